#version 410 core
// depth only
void main() {}
