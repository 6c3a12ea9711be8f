"""brdf-viewer: an OpenGL teaching viewer for reflectance models.

The package is split as DESIGN.md describes: ``scene`` (files and validation), ``mesh``
(trimesh loading and the built-in shapes), ``brdf`` (the registry and the numpy twins of
every GLSL BRDF), ``gl`` (contexts, shader loading and the renderer), ``app`` (the window).
"""

__version__ = "0.1.0"


class ViewerError(Exception):
    """A problem with user input (file, field, value) that the CLI reports in one line, exit 2."""
