"""Portability of the GLSL: no double precision anywhere (Apple's OpenGL 4.1 on Apple silicon has
no fp64 hardware, and many GPUs run it at 1/32 of the float rate). The check reads every shader
file with comments removed, so prose that says "double" does not count."""

import re

from viewer.base.resources import SHADER_DIR

FP64 = re.compile(r"\b(double|dvec[234]|dmat[234](x[234])?)\b|\d(\.\d*)?(e[+-]?\d+)?lf\b", re.IGNORECASE)


def _code(text: str) -> str:
    text = re.sub(r"/\*.*?\*/", lambda m: "\n" * m.group(0).count("\n"), text, flags=re.S)  # keep line numbers
    return re.sub(r"//[^\n]*", "", text)


def test_no_shader_uses_double_precision():
    files = sorted(p for p in SHADER_DIR.rglob("*") if p.suffix in (".glsl", ".vert", ".frag", ".geom"))
    assert len(files) > 10, f"shaders not found under {SHADER_DIR}"
    bad = []
    for f in files:
        for n, line in enumerate(_code(f.read_text(encoding="utf-8")).splitlines(), 1):
            if FP64.search(line):
                bad.append(f"{f.relative_to(SHADER_DIR)}:{n}: {line.strip()}")
    assert not bad, "double precision in GLSL:\n" + "\n".join(bad)


def test_the_check_sees_double_precision():
    """The pattern catches each fp64 form (so the test above can fail)."""
    for code in ("double x = 1.0;", "dvec3 h;", "dmat4 m;", "float y = 1.0LF;", "x = 2lf;"):
        assert FP64.search(_code(code)), code
    for code in ("float x; // double precision", "vec3 h; /* dvec3 */", "float doubled = 2.0;"):
        assert not FP64.search(_code(code)), code
