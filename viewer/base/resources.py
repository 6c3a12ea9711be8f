"""Resolve the product's resources (shaders, built-in models, scenes) through the package,
never through the working directory.

Two layouts hold them:

* an installed package (wheel, ``pip install .``): the build copies the repository's top-level
  ``shaders/`` and ``models/`` folders into the package as ``viewer/shaders`` and
  ``viewer/models`` (see setup.py);
* a source checkout (``pip install -e .``, or ``PYTHONPATH`` at the checkout): the top-level
  ``shaders/`` and ``models/`` folders next to ``viewer/``, so an edit there is what runs (shader
  hot reload watches the files the viewer really reads).

The package's own copy wins when it exists. ``BRDF_VIEWER_SHADERS`` (read by
``viewer.gl.shaders.shader_root``) points the shader loader at another folder in either layout.
Built-in scenes are ordinary package data (``viewer/scenes``) in both.
"""

from __future__ import annotations

from pathlib import Path

PACKAGE_DIR = Path(__file__).resolve().parent.parent  # viewer/ (this file is viewer/base/resources.py)
ROOT = PACKAGE_DIR.parent


def _resource_dir(name: str, probe: str) -> Path:
    """``viewer/<name>`` in an installed package, else ``<checkout>/<name>``; ``probe`` is a file
    that every complete copy holds (a half-built or foreign folder of the same name is skipped)."""
    for folder in (PACKAGE_DIR / name, ROOT / name):
        if (folder / probe).is_file():
            return folder
    return PACKAGE_DIR / name  # neither: the loaders name the missing file in their message


SHADER_DIR = _resource_dir("shaders", "passes/forward.frag")
MODEL_DIR = _resource_dir("models", "sphere.ply")
SCENE_DIR = PACKAGE_DIR / "scenes"
