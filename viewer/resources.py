"""Resolve the product's resources (shaders, built-in models, scenes) through the package,
never through the working directory."""

from __future__ import annotations

from pathlib import Path

PACKAGE_DIR = Path(__file__).resolve().parent
ROOT = PACKAGE_DIR.parent
SHADER_DIR = ROOT / "shaders"
MODEL_DIR = ROOT / "models"
SCENE_DIR = PACKAGE_DIR / "scenes"


def shader_path(rel: str) -> Path:
    return SHADER_DIR / rel
