"""Shader loading: ``#include "file"`` resolution (each file at most once), error lines mapped
back to the file they came from, and generated virtual files (``brdf/dispatch.glsl``)."""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

from viewer import ViewerError
from viewer.resources import SHADER_DIR

_INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"\s*$')
# Mesa: "0:12(5): error: ..."; NVIDIA: "0(12) : error ..."; Apple/AMD: "ERROR: 0:12: ..."
_ERR = [re.compile(r"(?P<file>\d+):(?P<line>\d+)\(\d+\)"),
        re.compile(r"(?P<file>\d+)\((?P<line>\d+)\)"),
        re.compile(r"ERROR:\s*(?P<file>\d+):(?P<line>\d+)")]


class ShaderError(ViewerError):
    """A shader failed to compile or link; ``.file`` and ``.line`` locate the first error."""

    def __init__(self, message: str, file: str | None = None, line: int | None = None):
        super().__init__(message)
        self.file = file
        self.line = line


@dataclass
class Source:
    text: str
    files: list[str] = field(default_factory=list)  # index = GLSL source-string number in #line

    def locate(self, log: str) -> tuple[str, list[str], str | None, int | None]:
        """Rewrite a compiler log so every 'N:L' names the file; return (text, lines, file, line)."""
        out, first_file, first_line = [], None, None
        for raw in log.splitlines():
            line = raw
            for pat in _ERR:
                m = pat.search(raw)
                if m:
                    idx, ln = int(m.group("file")), int(m.group("line"))
                    name = self.files[idx] if 0 <= idx < len(self.files) else f"<source {idx}>"
                    line = raw[: m.start()] + f"{name}:{ln}" + raw[m.end():]
                    if first_file is None and "error" in raw.lower():
                        first_file, first_line = name, ln
                    break
            if line.strip():
                out.append(line.strip())
        return "\n".join(out), out, first_file, first_line


def preprocess(text: str, name: str, virtual: dict[str, str] | None = None,
               root: Path = SHADER_DIR, defines: dict[str, str] | None = None) -> Source:
    """Inline includes, emitting ``#line`` directives so compiler messages map back to files;
    ``defines`` become ``#define`` lines right after ``#version``."""
    virtual = dict(virtual or {})
    src = Source("", [name])
    included = {name}
    out: list[str] = []

    def read(rel: str, where: str) -> str:
        if rel in virtual:
            return virtual[rel]
        path = root / rel
        try:
            return path.read_text()
        except OSError as e:
            raise ShaderError(f"{where}: cannot include {rel!r}: {e.strerror}", where) from None

    def emit(body: str, idx: int):
        for n, line in enumerate(body.splitlines(), start=1):
            m = _INCLUDE.match(line)
            if m:
                rel = m.group(1)
                if rel not in included:
                    included.add(rel)
                    src.files.append(rel)
                    child = len(src.files) - 1
                    out.append(f"#line 1 {child}")
                    emit(read(rel, f"{src.files[idx]}:{n}"), child)
                    out.append(f"#line {n + 1} {idx}")
                else:
                    out.append("")
                continue
            out.append(line)
            if n == 1 and line.lstrip().startswith("#version"):
                if idx == 0:
                    out.extend(f"#define {k} {v}" for k, v in (defines or {}).items())
                out.append(f"#line 2 {idx}")

    emit(text, 0)
    src.text = "\n".join(out) + "\n"
    return src


def load(rel: str, virtual: dict[str, str] | None = None, defines: dict[str, str] | None = None) -> Source:
    path = SHADER_DIR / rel
    try:
        text = path.read_text()
    except OSError as e:
        raise ShaderError(f"{rel}: cannot read shader: {e.strerror}", rel) from None
    return preprocess(text, rel, virtual, defines=defines)


def default_virtual(only: tuple[str, ...] | None = None) -> dict[str, str]:
    from viewer.brdf.glsl import generate_dispatch

    return {"brdf/dispatch.glsl": generate_dispatch(only)}


def build_program(ctx, vertex: str | None = None, fragment: str | None = None, *, geometry: str | None = None,
                  vertex_source: str | None = None, fragment_source: str | None = None,
                  virtual: dict[str, str] | None = None, defines: dict[str, str] | None = None):
    """Compile and link a program from files under shaders/ (or given sources)."""
    import moderngl

    if virtual is None:
        virtual = default_virtual()
    vs = load(vertex, virtual, defines) if vertex else preprocess(vertex_source, "<vertex>", virtual, defines=defines)
    fs = load(fragment, virtual, defines) if fragment else preprocess(fragment_source, "<fragment>", virtual,
                                                                      defines=defines)
    gs = load(geometry, virtual, defines) if geometry else None
    try:
        return ctx.program(vertex_shader=vs.text, fragment_shader=fs.text,
                           geometry_shader=gs.text if gs else None)
    except moderngl.Error as e:
        log = str(e)
        # moderngl names the failing stage in its message
        head = log.lower()[:200]
        which = fs if "fragment" in head else (gs if gs is not None and "geometry" in head else vs)
        text, _, f, ln = which.locate(log)
        first = text.splitlines()
        head = next((l for l in first if "error" in l.lower()), first[0] if first else "compile error")
        raise ShaderError(f"shader compile failed: {head}" + ("\n" + text if len(first) > 1 else ""), f, ln) from None


def set_uniform(prog, name, value):
    """Set a uniform if the compiler kept it (unused uniforms are optimized away). Bytes are
    cut to what the program kept: the compiler may shorten an array to the highest index it sees
    used (u_mat with a constant offset)."""
    try:
        u = prog[name]
    except KeyError:
        return
    if isinstance(value, (bytes, bytearray)):
        u.write(bytes(value[: u.array_length * u.dimension * 4]))
    else:
        u.value = value
