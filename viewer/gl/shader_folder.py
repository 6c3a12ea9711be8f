"""Where shader files are read from (``shader_root``) and the error a shader reports
(``ShaderError``): what the shader loader (``viewer/gl/shaders.py``) and the generated BRDF
dispatch (``viewer/gl/brdf_glsl.py``) share, so neither imports the other for them."""

from __future__ import annotations

import os
from pathlib import Path

from viewer import ViewerError
from viewer.base.resources import SHADER_DIR

#: environment variable naming another shader folder (default: the package's shaders/)
SHADER_ROOT_ENV = "BRDF_VIEWER_SHADERS"
_root_override: Path | None = None


def set_shader_root(path: str | os.PathLike | None) -> Path | None:
    """Read shaders from ``path`` from now on (None: back to the environment variable or the
    package's shaders/). Programs already built are not affected until they are rebuilt.
    Returns the previous setting (None when there was none), to restore it with."""
    global _root_override
    previous = _root_override
    _root_override = None if path is None else Path(path).resolve()
    return previous


def shader_root() -> Path:
    """The folder shader files are read from: ``set_shader_root``'s, else $BRDF_VIEWER_SHADERS,
    else the package's shaders/ (never the working folder)."""
    if _root_override is not None:
        return _root_override
    env = os.environ.get(SHADER_ROOT_ENV)
    return Path(env).resolve() if env else SHADER_DIR


class ShaderError(ViewerError):
    """A shader failed to compile or link; ``.file`` and ``.line`` locate the first error (the
    included file it is really in, not the pass that included it; None for link errors).
    ``.detail`` is that error's message without its location; ``.program`` names the program
    when the renderer knows it (e.g. ``shadow``, ``forward:lambert:env``)."""

    def __init__(self, message: str, file: str | None = None, line: int | None = None,
                 detail: str | None = None, program: str | None = None):
        super().__init__(message)
        self.file = file
        self.line = line
        self.detail = detail if detail is not None else message.splitlines()[0] if message else ""
        self.program = program

    def summary(self) -> str:
        """One line: ``file:line: message`` (``program: message`` when no file is known)."""
        if self.file is not None:
            where = f"{self.file}:{self.line}" if self.line is not None else self.file
        else:
            where = self.program or "link"
        return f"{where}: {self.detail}"
