"""The GLSL text of a ``.brdf`` file's parameters: its declarations as the flat floats of
``u_p`` (a bool as 0 or 1, a colour as three floats, declaration order), the statements that copy
them into the file's globals, and the file as a virtual include. Below both the generated
dispatch (``brdf_glsl``) and the file's evaluation programs (``file_brdf``); compiles nothing."""

from __future__ import annotations

import re
import zlib

import numpy as np

from viewer.brdf.brdffile import PREFIX, BrdfFile

MAX_PARAMS = 64  # floats of u_p


def param_floats(bfile: BrdfFile, p) -> np.ndarray:
    """The parameter values of ``p`` as the flat floats of ``u_p`` (declaration order)."""
    out = []
    for d in bfile.declarations:
        v = p[d.name] if p is not None and d.name in p else d.default
        if not _of_kind(d.kind, v):  # a value of a parameter the file since retyped
            v = d.default
        if d.kind == "color":
            out.extend(float(x) for x in np.ravel(v)[:3])
        elif d.kind == "bool":
            out.append(1.0 if v else 0.0)
        else:
            out.append(float(v))
    return np.array(out + [0.0] * max(1, MAX_PARAMS - len(out)), dtype="f4")[:max(MAX_PARAMS, len(out))]


def _of_kind(kind: str, v) -> bool:
    if kind == "color":
        return not isinstance(v, (str, bytes)) and np.size(v) == 3
    if kind == "bool":
        return isinstance(v, (bool, np.bool_))
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, (bool, np.bool_))


def set_params_glsl(bfile: BrdfFile, read=lambda k: f"u_p[{k}]", prefix: str = PREFIX) -> str:
    """GLSL statements copying the parameter floats (``read(k)``: the GLSL expression of float k,
    declaration order) into the file's globals (named with ``prefix``)."""
    lines, k = [], 0
    for d in bfile.declarations:
        g = prefix + d.name
        if d.kind == "color":
            lines.append(f"{g} = vec3({read(k)}, {read(k + 1)}, {read(k + 2)});")
            k += 3
        elif d.kind == "bool":
            lines.append(f"{g} = {read(k)} > 0.5;")
            k += 1
        else:
            lines.append(f"{g} = {read(k)};")
            k += 1
    return "\n    ".join(lines)


def n_floats(bfile: BrdfFile) -> int:
    return sum(3 if d.kind == "color" else 1 for d in bfile.declarations)


_UNSAFE = re.compile(r"[^A-Za-z0-9_.+/-]")


def include_name(name: str) -> str:
    """The name a file (or path) is included under in GLSL: itself when it holds only letters,
    digits and ``_ . + - /``; else those characters kept, the others as ``_``, and a hash of the
    whole name, so a quote, a backslash, a newline or a non-ASCII letter never reaches an
    ``#include "..."`` line and two such names never meet."""
    if not _UNSAFE.search(name):
        return name
    stem, dot, ext = name.rpartition(".") if "." in name else (name, "", "")
    return f"{_UNSAFE.sub('_', stem)}-{zlib.crc32(name.encode('utf-8', 'surrogatepass')):08x}{dot}{_UNSAFE.sub('_', ext)}"


def virtual_files(bfile: BrdfFile, prefix: str = PREFIX, name: str | None = None) -> dict[str, str]:
    """The file as a virtual include, under ``name`` (default: the file's ``include_name``)."""
    return {name or include_name(bfile.path.name): bfile.glsl_block(prefix=prefix)}
