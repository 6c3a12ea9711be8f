"""Packages imported only where they are needed: import one, or say in one line which package is
missing, what needs it and how to install it (a ``ViewerError``, so the command line exits with
status 2 and that line instead of a traceback)."""

from __future__ import annotations

import importlib
import importlib.util
from types import ModuleType

from viewer import ViewerError

# import name -> (what needs it, how to install it)
PACKAGES = {
    "numba": ("the numba ray kernel (kernel='numba')", "pip install numba (or: pip install -e '.[test]')"),
    "mitsuba": ("the Mitsuba 3 comparison of benchmarks/pathtracer.py",
                "pip install mitsuba (or: pip install -e '.[bench]')"),
    "embreex": ("the reference path tracer's Embree ray kernel", "pip install embreex"),
    "cv2": ("reading and writing Radiance .hdr maps", "pip install opencv-python-headless"),
    "OpenEXR": ("reading and writing OpenEXR .exr maps", "pip install OpenEXR"),
    "trimesh": ("reading mesh files (OBJ, PLY, STL, OFF, glTF)", "pip install trimesh"),
    "jupyter_rfb": ("the notebook widget viewer.notebook.Viewer", "pip install -e '.[notebook]'"),
    "ipywidgets": ("the notebook widget viewer.notebook.Viewer", "pip install -e '.[notebook]'"),
}
DISTRIBUTIONS = {"cv2": "opencv-python-headless"}  # where the pip name differs from the import name


def require(name: str, purpose: str | None = None, load: bool = True) -> ModuleType | None:
    """``importlib.import_module(name)``, or a ``ViewerError`` naming the package: e.g.
    "numba is not installed; it is needed for the numba ray kernel (kernel='numba'); install it
    with: pip install numba (or: pip install -e '.[test]')". A package that is installed but
    fails to import (one of its own dependencies missing, a broken build) is named with the
    reason. ``load=False`` only checks that the package is installed (``find_spec``, no import:
    numba takes a second to import, and a process that merely starts workers need not load it)."""
    try:
        if not load:
            if importlib.util.find_spec(name) is None:
                raise ModuleNotFoundError(f"No module named {name!r}", name=name)
            return None
        return importlib.import_module(name)
    except ImportError as e:
        raise ViewerError(explain(e, name, purpose)) from None


def explain(error: ImportError, name: str | None = None, purpose: str | None = None) -> str:
    """One line about an ImportError: which package is missing (``name``, else the module the
    error names), what needs it and how to install it."""
    missing = getattr(error, "name", None)
    name = name or (missing.split(".")[0] if missing else None) or "a package"
    what, install = PACKAGES.get(name, (None, f"pip install {DISTRIBUTIONS.get(name, name)}"))
    what = purpose or what or "this feature"
    label = name if name not in DISTRIBUTIONS else f"{name} ({DISTRIBUTIONS[name]})"
    if missing is None or missing.split(".")[0] == name:
        return f"{label} is not installed; it is needed for {what}; install it with: {install}"
    reason = " ".join(str(error).split())
    return f"{label} cannot be imported ({reason}); it is needed for {what}"


def available(name: str) -> bool:
    """True when ``name`` imports."""
    try:
        importlib.import_module(name)
        return True
    except ImportError:
        return False
