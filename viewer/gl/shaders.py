"""Shader loading: ``#include "file"`` resolution (each file at most once), error lines mapped
back to the file they came from, and generated virtual files (``brdf/dispatch.glsl``, and
``generated/constants.glsl`` in every program: the values of ``viewer.gl.constants``).

Files are read from disk on every build (there is no source cache), from ``shader_root()``:
the package's ``shaders/`` unless ``set_shader_root`` or the environment variable
``BRDF_VIEWER_SHADERS`` names another folder (tests point it at a temporary copy; hot reload
in ``viewer/gl/hot_reload.py`` rebuilds programs when files there change). The folder and
``ShaderError`` live in ``viewer/gl/shader_folder.py``, below this module and the generated
dispatch (``viewer/gl/brdf_glsl.py``), which both use them.

``python -m viewer.gl.shaders --check`` compiles every BRDF family's GLSL."""

from __future__ import annotations

import os
import re
from dataclasses import dataclass, field
from pathlib import Path

from viewer.gl.shader_folder import SHADER_ROOT_ENV, ShaderError, set_shader_root, shader_root  # public here too

_INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"\s*$')
# Line numbers of included file k start at k * LINE_BASE (``#line``), so a compiler message
# names the file through its line number alone: Mesa 22 reports source string 0 for some errors
# in included code (undeclared identifiers in expressions) although it keeps the line right.
LINE_BASE = 100000
# Mesa: "0:12(5): error: ..."; NVIDIA: "0(12) : error ..."; Apple/AMD: "ERROR: 0:12: ..."
_ERR = [re.compile(r"(?P<file>\d+):(?P<line>\d+)\(\d+\)"),
        re.compile(r"(?P<file>\d+)\((?P<line>\d+)\)"),
        re.compile(r"ERROR:\s*(?P<file>\d+):(?P<line>\d+)")]


#: the generated include of the constants both sides share (viewer/gl/constants.py)
GENERATED_CONSTANTS = "generated/constants.glsl"

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
                    if ln >= LINE_BASE:  # the line number says which file: trust it over idx
                        idx, ln = divmod(ln, LINE_BASE)
                    name = self.files[idx] if 0 <= idx < len(self.files) else f"<source {idx}>"
                    line = raw[: m.start()] + f"{name}:{ln}" + raw[m.end():]
                    if first_file is None and "error" in raw.lower():
                        first_file, first_line = name, ln
                    break
            if line.strip():
                out.append(line.strip())
        return "\n".join(out), out, first_file, first_line


def preprocess(text: str, name: str, virtual: dict[str, str] | None = None,
               root: Path | None = None, defines: dict[str, str] | None = None) -> Source:
    """Inline includes, emitting ``#line`` directives so compiler messages map back to files;
    ``defines`` become ``#define`` lines right after ``#version``. ``root``: shader_root()."""
    root = shader_root() if root is None else Path(root)
    virtual = dict(virtual or {})
    src = Source("", [name])
    included = {name}
    out: list[str] = []

    def read(rel: str, file: str, line: int) -> str:
        if rel in virtual:
            return virtual[rel]
        if rel == GENERATED_CONSTANTS:  # made from the Python side's values, never a file
            from viewer.gl.constants import glsl_header

            return glsl_header()
        path = root / rel
        try:
            return path.read_text()
        except OSError as e:
            why = f"cannot include {rel!r}: {e.strerror}"
            raise ShaderError(f"{file}:{line}: {why}", file, line, detail=why) from None

    def emit(body: str, idx: int):
        for n, line in enumerate(body.splitlines(), start=1):
            m = _INCLUDE.match(line)
            if m:
                rel = m.group(1)
                if rel not in included:
                    included.add(rel)
                    src.files.append(rel)
                    child = len(src.files) - 1
                    out.append(f"#line {child * LINE_BASE + 1} {child}")
                    emit(read(rel, src.files[idx], n), child)
                    out.append(f"#line {idx * LINE_BASE + n + 1} {idx}")
                else:
                    out.append("")
                continue
            out.append(line)
            if n == 1 and line.lstrip().startswith("#version"):
                if idx == 0:
                    out.extend(f"#define {k} {v}" for k, v in (defines or {}).items())
                out.append(f"#line {idx * LINE_BASE + 2} {idx}")

    emit(text, 0)
    src.text = "\n".join(out) + "\n"
    return src


def load(rel: str, virtual: dict[str, str] | None = None, defines: dict[str, str] | None = None) -> Source:
    root = shader_root()
    try:
        text = (root / rel).read_text()
    except OSError as e:
        raise ShaderError(f"{rel}: cannot read shader: {e.strerror}", rel, detail=f"cannot read shader: {e.strerror}") \
            from None
    return preprocess(text, rel, virtual, root=root, defines=defines)


def default_virtual(only: tuple[str, ...] | None = None) -> dict[str, str]:
    from viewer.gl.brdf_glsl import custom_virtual, generate_dispatch

    return {"brdf/dispatch.glsl": generate_dispatch(only), **custom_virtual(only)}


def program_sources(vertex: str | None = None, fragment: str | None = None, *, geometry: str | None = None,
                    vertex_source: str | None = None, fragment_source: str | None = None,
                    virtual: dict[str, str] | None = None, defines: dict[str, str] | None = None):
    """The preprocessed (vertex, fragment, geometry or None) sources of a program, read from
    disk now; ``virtual`` None = every model's dispatch. Raises ShaderError (unreadable file)."""
    if virtual is None:
        virtual = default_virtual()
    vs = load(vertex, virtual, defines) if vertex else preprocess(vertex_source, "<vertex>", virtual, defines=defines)
    fs = load(fragment, virtual, defines) if fragment else preprocess(fragment_source, "<fragment>", virtual,
                                                                      defines=defines)
    gs = load(geometry, virtual, defines) if geometry else None
    return vs, fs, gs


def compile_sources(ctx, vs: Source, fs: Source, gs: Source | None = None):
    """Compile and link preprocessed sources; a failure raises ShaderError located in the file
    (of the includes) the first error is in."""
    import moderngl

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
        detail = head
        if f is not None and ln is not None and detail.startswith(f"{f}:{ln}"):
            detail = detail[len(f"{f}:{ln}"):].lstrip(":( 0123456789)").strip() or head
        raise ShaderError(f"shader compile failed: {head}" + ("\n" + text if len(first) > 1 else ""), f, ln,
                          detail=detail) from None


def build_program(ctx, vertex: str | None = None, fragment: str | None = None, *, geometry: str | None = None,
                  vertex_source: str | None = None, fragment_source: str | None = None,
                  virtual: dict[str, str] | None = None, defines: dict[str, str] | None = None):
    """Compile and link a program from files under shader_root() (or given sources)."""
    return compile_sources(ctx, *program_sources(vertex, fragment, geometry=geometry, vertex_source=vertex_source,
                                                 fragment_source=fragment_source, virtual=virtual,
                                                 defines=defines))


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


def _check() -> int:
    """Compile every family (``python -m viewer.gl.shaders --check``)."""
    from viewer import brdf
    from viewer.gl.context import create_offscreen_context

    ctx = create_offscreen_context()
    frag = ('#version 410 core\n#include "brdf/dispatch.glsl"\nuniform int u_model;\nin vec2 v_uv;\n'
            "out vec4 color;\nvoid main() { vec3 wi = normalize(vec3(v_uv, 1.0)); vec3 wo = vec3(0.0, 0.0, 1.0);\n"
            "    color = vec4(brdf_eval(u_model, 0, wi, wo) + brdf_terms(u_model, 0, wi, wo), 1.0); }\n")
    vert = ("#version 410 core\nin vec2 in_pos; out vec2 v_uv;\n"
            "void main() { v_uv = in_pos; gl_Position = vec4(in_pos, 0.0, 1.0); }\n")
    try:
        build_program(ctx, vertex_source=vert, fragment_source=frag)
    except ShaderError as e:
        print(e)
        return 1
    print("all BRDF families compile:", ", ".join(brdf.names()))
    return 0


if __name__ == "__main__":
    import sys

    if "--check" in sys.argv:
        sys.exit(_check())
