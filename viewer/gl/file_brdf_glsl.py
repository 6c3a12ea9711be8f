"""The GLSL text of a ``.brdf`` file's parameters: its declarations as the flat floats of
``u_p`` (a bool as 0 or 1, a colour as three floats, declaration order), the statements that copy
them into the file's globals, and the file as a virtual include. Below both the generated
dispatch (``brdf_glsl``) and the file's evaluation programs (``file_brdf``); compiles nothing."""

from __future__ import annotations

import numpy as np

from viewer.brdf.brdffile import PREFIX, BrdfFile

MAX_PARAMS = 64  # floats of u_p


def param_floats(bfile: BrdfFile, p) -> np.ndarray:
    """The parameter values of ``p`` as the flat floats of ``u_p`` (declaration order)."""
    out = []
    for d in bfile.declarations:
        v = p[d.name] if p is not None and d.name in p else d.default
        if d.kind == "color":
            out.extend(float(x) for x in np.ravel(v)[:3])
        elif d.kind == "bool":
            out.append(1.0 if v else 0.0)
        else:
            out.append(float(v))
    return np.array(out + [0.0] * max(1, MAX_PARAMS - len(out)), dtype="f4")[:max(MAX_PARAMS, len(out))]


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


def virtual_files(bfile: BrdfFile, prefix: str = PREFIX, name: str | None = None) -> dict[str, str]:
    """The file as a virtual include, under ``name`` (default: the file's name)."""
    return {name or bfile.path.name: bfile.glsl_block(prefix=prefix)}
