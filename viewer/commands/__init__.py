"""The commands: each parses its arguments, calls the layers below and says what it did."""
