"""What every layer may stand on: atomic files, optional dependencies, where resources are, input bounds."""
