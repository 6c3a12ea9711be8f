"""brdf-viewer: an OpenGL teaching viewer for reflectance models.

The package's layers (docs/architecture.md): ``scene`` (files and validation), ``mesh``
(trimesh loading and the built-in shapes), ``brdf`` (the registry and the numpy twins of
every GLSL BRDF), ``pathtracer`` (the CPU reference), ``gl`` (contexts, shader loading and the
renderer), ``app`` (the window).

For scripts and notebooks (docs/python-api.md)::

    import viewer
    img = viewer.render("default", width=320, height=180)        # (H, W, 3) float32 radiance
    ref = viewer.reference("default", spp=16, width=320, height=180)

Importing ``viewer`` is cheap: ``render``, ``reference`` and ``__version__`` load what they need
on first use.
"""

from __future__ import annotations


class ViewerError(Exception):
    """A problem with user input (file, field, value) that the CLI reports in one line, exit 2."""


class OutputError(ViewerError, OSError):
    """A file that could not be written (a full disk, an unwritable folder, a reference cache
    that cannot store): one line naming the file and why, exit 1, nothing partial left. Also an
    ``OSError`` (with the original ``errno``), so code that handles write failures keeps doing so."""


def _read_version() -> str:
    """The version, kept in one place: pyproject.toml. A source checkout reads that file (so a
    checkout on ``PYTHONPATH`` never reports another install's version); an installed package
    reads its distribution metadata, which the build copied from it."""
    from pathlib import Path

    pyproject = Path(__file__).resolve().parent.parent / "pyproject.toml"
    if pyproject.is_file():
        try:
            import tomllib
        except ModuleNotFoundError:  # Python 3.10
            import tomli as tomllib
        try:
            project = tomllib.loads(pyproject.read_text(encoding="utf-8")).get("project", {})
            if project.get("name") == "brdf-viewer" and "version" in project:
                return str(project["version"])
        except (OSError, ValueError):
            pass
    from importlib import metadata

    try:
        return metadata.version("brdf-viewer")
    except metadata.PackageNotFoundError:
        return "unknown"


def file_brdf_evaluator():
    """The object that runs a ``.brdf`` file's GLSL on an offscreen context (``viewer.gl.file_brdf``):
    the wiring between ``viewer.brdf``, which imports no GL, and the GL side."""
    from viewer.gl.file_brdf import shared_evaluator

    return shared_evaluator()


def file_brdf_probe():
    """The function that vets a ``.brdf`` file's GLSL in a child process with a time and a memory
    limit before it is used (``viewer.gl.file_probe.probe``): the same wiring."""
    from viewer.gl.file_probe import probe

    return probe


def render(scene, width=None, height=None, overrides=()):
    """Rasterize ``scene`` offscreen; (H, W, 3) float32 linear radiance (see viewer.api.render)."""
    from viewer.api import render as _render

    return _render(scene, width=width, height=height, overrides=overrides)


def reference(scene, spp=64, engine="auto", width=None, height=None, overrides=(), *, seed=0,
              max_depth=8, workers=None):
    """Reference path tracing of ``scene``; (H, W, 3) float32 (see viewer.api.reference)."""
    from viewer.api import reference as _reference

    return _reference(scene, spp=spp, engine=engine, width=width, height=height, overrides=overrides,
                      seed=seed, max_depth=max_depth, workers=workers)


def bparam_overrides(material, path):
    """The assignments that set a scene material's values from a .bparam file (see
    viewer.api.bparam_overrides), for ``overrides``."""
    from viewer.api import bparam_overrides as _bparam_overrides

    return _bparam_overrides(material, path)


def __getattr__(name):
    if name == "__version__":
        value = _read_version()
        globals()["__version__"] = value
        return value
    raise AttributeError(f"module 'viewer' has no attribute {name!r}")
