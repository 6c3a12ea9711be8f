"""BRDF files: Disney BRDF Explorer's ``.brdf`` format (type ``analytic``), read as published.

The format (BRDF Explorer's ``BRDFBase::loadBRDF`` and ``BRDFAnalytic``, and the files it ships):

* the first line names the type; only ``analytic`` is a BRDF with a shader;
* blank lines, and lines whose first non-blank character is ``#``, are skipped everywhere, inside
  a shader section too (so a ``.brdf`` shader cannot use the GLSL preprocessor);
* sections ``::begin NAME`` ... ``::end NAME``, not nested: ``parameters``, ``shader`` (GLSL
  defining ``vec3 BRDF(vec3 L, vec3 V, vec3 N, vec3 X, vec3 Y)``: toward the light, toward the
  viewer, normal, tangent, bitangent; f without the cosine) and ``isFunc`` (GLSL defining the
  optional sampler); other sections are ignored;
* parameter lines ``float NAME MIN MAX DEFAULT``, ``bool NAME DEFAULT`` (0 or 1) and
  ``color NAME R G B``; each becomes a uniform of that name (``float``, ``bool``, ``vec3``)
  that the shader reads.

The sampler, as BRDF Explorer declares it: ``vec3 sampleBRDF(float u, float v, vec3 N, vec3 X,
vec3 Y, out vec3 wi, out float pdf)``; this viewer also passes the view direction first where a
file declares ``vec3 sampleBRDF(vec3 V, float u, float v, vec3 N, vec3 X, vec3 Y, out vec3 wi,
out float pdf)``, and takes the return value as the weight f cos / pdf.

This module has no GL: it parses, validates and turns the file's GLSL into a block for this
viewer's programs (``glsl_block``): every name the file declares at the top level (its
parameters, functions, constants) gets the prefix ``PREFIX``, so it cannot meet a name of the
viewer's shaders, and the block keeps the file's line numbers, so a compiler message names
``FILE.brdf:LINE``. The GL side (``viewer.gl.file_brdf``) compiles it.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path

from viewer import ViewerError
from viewer.brdf.glsl_guard import check_code, check_file_size, check_sizes, guard_globals, guard_loops

#: the prefix of every top-level name of a file's GLSL in this viewer's programs (the file in a
#: program's slot k > 0 gets ``prefix_for(k)``, so several files can share one program)
PREFIX = "bxf_"
#: any slot's prefix, for taking it out of compiler messages
PREFIX_RE = r"\bbxf\d*_"


#: the parameter floats a file may declare (a colour is three): the renderer's material block holds
#: 256 floats (``viewer.gl.constants.MAT_FLOATS``), at least 32 of them the generic sampler's table
#: (``viewer.brdf.file_sampler``: its smallest size, 29 floats, where a file fills the rest; a
#: larger one in what a smaller file leaves); ``tests/test_damage_inputs.py`` checks the sum
MAX_PARAM_FLOATS = 224


def prefix_for(slot: int) -> str:
    """The prefix of the file BRDF in slot ``slot`` of a program (``PREFIX`` for the first)."""
    return PREFIX if slot == 0 else f"bxf{slot}_"
SECTIONS = ("parameters", "shader", "isFunc")
_IDENT = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_TOKEN = re.compile(r"[A-Za-z_][A-Za-z0-9_]*|\d+\.?\d*(?:[eE][+-]?\d+)?|\.\d+(?:[eE][+-]?\d+)?|\S")
_GLSL_KEYWORDS = {
    "attribute", "const", "uniform", "varying", "buffer", "shared", "layout", "centroid", "flat", "smooth",
    "noperspective", "patch", "sample", "break", "continue", "do", "for", "while", "switch", "case", "default",
    "if", "else", "subroutine", "in", "out", "inout", "float", "double", "int", "void", "bool", "true", "false",
    "invariant", "precise", "discard", "return", "struct", "precision", "highp", "mediump", "lowp", "uint",
}


@dataclass(frozen=True)
class Declaration:
    """One parameter line: kind ``float`` | ``bool`` | ``color``, its name and 1-based line;
    ``lo``, ``hi`` for floats; ``default`` a float, a bool or an (r, g, b) tuple."""

    kind: str
    name: str
    line: int
    default: object
    lo: float | None = None
    hi: float | None = None


@dataclass
class BrdfFile:
    """A parsed ``.brdf`` file. ``lines`` is the file's text split into lines; ``shader`` and
    ``sampler`` are the 1-based line numbers of each section's code lines."""

    path: Path
    kind: str
    declarations: list[Declaration]
    lines: list[str]
    shader: list[int]
    sampler: list[int] = field(default_factory=list)

    @property
    def name(self) -> str:
        return self.path.stem

    @property
    def has_sampler(self) -> bool:
        return bool(self.sampler)

    def where(self, line: int | None = None) -> str:
        return f"{self.path.name}:{line}" if line is not None else self.path.name

    def declaration(self, name: str) -> Declaration:
        for d in self.declarations:
            if d.name == name:
                return d
        raise KeyError(name)

    def top_level_names(self) -> list[str]:
        """Every name the file's GLSL declares at the top level (functions, constants, globals,
        structs) and its parameters."""
        names = [d.name for d in self.declarations]
        for line_set in (self.shader, self.sampler):
            for n in _declared(self._code(line_set)):
                if n not in names:
                    names.append(n)
        return names

    def _code(self, line_set) -> str:
        return "\n".join(_strip_comments_line(self.lines[i - 1]) for i in line_set)

    def glsl_block(self, sampler_wrapper: bool = True, prefix: str = PREFIX) -> str:
        """The file as GLSL for this viewer: one output line per file line (the file's line
        numbers survive, for messages), parameters as globals ``prefix + name`` on their own
        lines, the shader and sampler with their top-level names prefixed, everything else blank."""
        rename = {n: prefix + n for n in self.top_level_names()}
        # the entry points run under the loop budget (viewer.brdf.glsl_guard): the file's own
        # BRDF / sampleBRDF become prefix + "0BRDF" / "0sampleBRDF", called by wrappers that set
        # the budget's counter to 0
        rename.update(BRDF=prefix + "0BRDF", sampleBRDF=prefix + "0sampleBRDF")
        out = [""] * len(self.lines)
        glsl_type = {"float": "float", "bool": "bool", "color": "vec3"}
        for d in self.declarations:
            out[d.line - 1] = f"{glsl_type[d.kind]} {prefix}{d.name};"
        code_lines = self.shader + (self.sampler if sampler_wrapper else [])
        guarded = guard_loops({i: self.lines[i - 1] for i in code_lines}, prefix + "0step")
        for i in code_lines:
            out[i - 1] = rename_names(guarded[i], rename)
        # the budget before the file's code (on its type line, blank otherwise), each wrapper
        # after its section's last line (a line of the section's end, blank otherwise)
        out[self.type_line - 1] = guard_globals(prefix)
        c = f"{prefix}0steps = 0;"
        out[self.shader[-1]] = (f"vec3 {prefix}BRDF(vec3 L, vec3 V, vec3 N, vec3 X, vec3 Y) {{ {c} "
                                f"return vec3({prefix}0BRDF(L, V, N, X, Y)); }}")
        if self.sampler and sampler_wrapper:
            v, vc = ("vec3 V, ", "V, ") if sampler_takes_view(self) else ("", "")
            out[self.sampler[-1]] = (f"vec3 {prefix}sampleBRDF({v}float u, float v, vec3 N, vec3 X, vec3 Y, "
                                     f"out vec3 wi, out float pdf) {{ {c} return vec3({prefix}0sampleBRDF("
                                     f"{vc}u, v, N, X, Y, wi, pdf)); }}")
        return "\n".join(out) + "\n"

    @property
    def type_line(self) -> int:
        """The 1-based line naming the type (the first line that is not blank)."""
        return next(i + 1 for i, t in enumerate(self.lines) if t.strip())


def _strip_comments_line(text: str) -> str:
    i = text.find("//")
    return text if i < 0 else text[:i]


def _strip_block_comments(code: str) -> str:
    return re.sub(r"/\*.*?\*/", lambda m: "\n" * m.group(0).count("\n"), code, flags=re.S)


def _declared(code: str) -> list[str]:
    """Names declared at the top level of GLSL ``code``: at brace and parenthesis depth 0, an
    identifier after a type (an identifier) and before ``(``, ``=``, ``;``, ``,`` or ``[``; and
    struct names."""
    code = _strip_block_comments(code)
    toks = _TOKEN.findall(code)
    out: list[str] = []
    brace = paren = 0
    prev = None
    for j, t in enumerate(toks):
        nxt = toks[j + 1] if j + 1 < len(toks) else ""
        if t == "{":
            brace += 1
        elif t == "}":
            brace = max(brace - 1, 0)
        elif t == "(":
            paren += 1
        elif t == ")":
            paren = max(paren - 1, 0)
        elif brace == 0 and _IDENT.fullmatch(t) and t not in _GLSL_KEYWORDS:
            if prev == "struct" or (
                    paren == 0 and prev is not None and (_IDENT.fullmatch(prev) or prev == "]")
                    and prev not in ("return",) and nxt in ("(", "=", ";", ",", "[")):
                if t not in out:
                    out.append(t)
        prev = t
    return out


def rename_names(line: str, rename: dict[str, str]) -> str:
    """``line`` with whole-word identifiers renamed, outside // comments (a /* */ comment on one
    line is renamed too: harmless)."""
    code, sep, comment = line.partition("//")

    def sub(m):
        w = m.group(0)
        return rename.get(w, w)

    # identifiers only: not the digits of a number (1e5), not a member after a dot (v.x stays)
    renamed = re.sub(r"(?<![A-Za-z0-9_.])[A-Za-z_][A-Za-z0-9_]*", sub, code)
    return renamed + sep + comment


def _number(text: str, where: str, what: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise ViewerError(f"{where}: {what}: {text!r} is not a number") from None
    if not math.isfinite(v):
        raise ViewerError(f"{where}: {what}: {text!r} is not a finite number")
    return v


def _parameter(text: str, line: int, where: str, seen: set) -> Declaration:
    parts = text.split()
    kind = parts[0]
    if kind not in ("float", "bool", "color"):
        raise ViewerError(f"{where}: unknown parameter type {kind!r}; allowed: float NAME MIN MAX DEFAULT, "
                          f"bool NAME DEFAULT, color NAME R G B")
    need = {"float": 5, "bool": 3, "color": 5}[kind]
    form = {"float": "float NAME MIN MAX DEFAULT", "bool": "bool NAME DEFAULT", "color": "color NAME R G B"}[kind]
    if len(parts) < need:
        raise ViewerError(f"{where}: expected {form}, got {text.strip()!r}")
    name = parts[1]
    if not _IDENT.fullmatch(name) or name in _GLSL_KEYWORDS or name.startswith("gl_") or "__" in name:
        raise ViewerError(f"{where}: {name!r} is not a usable GLSL name for a parameter")
    if name in seen or name in ("file", "model"):
        raise ViewerError(f"{where}: parameter {name!r} is declared twice" if name in seen
                          else f"{where}: {name!r} is reserved in a material table; rename the parameter")
    seen.add(name)
    if kind == "float":
        lo, hi, dv = (_number(parts[i], where, n) for i, n in ((2, "MIN"), (3, "MAX"), (4, "DEFAULT")))
        if not lo <= hi:
            raise ViewerError(f"{where}: float {name}: MIN {lo:g} is above MAX {hi:g}")
        if not lo <= dv <= hi:
            raise ViewerError(f"{where}: float {name}: DEFAULT {dv:g} is outside [{lo:g}, {hi:g}]")
        return Declaration("float", name, line, dv, lo, hi)
    if kind == "bool":
        # BRDF Explorer reads the value with iostream's >> into a bool: 0 or 1
        if parts[2] not in ("0", "1", "true", "false"):
            raise ViewerError(f"{where}: bool {name}: DEFAULT must be 0 or 1, got {parts[2]!r}")
        return Declaration("bool", name, line, parts[2] in ("1", "true"))
    rgb = tuple(_number(parts[i], where, c) for i, c in ((2, "R"), (3, "G"), (4, "B")))
    return Declaration("color", name, line, rgb, 0.0, None)


def parse(path, text: str | None = None) -> BrdfFile:
    """Parse a ``.brdf`` file (``text`` instead of reading ``path``); one-line ViewerError naming
    ``FILE.brdf:LINE`` on a problem."""
    path = Path(path)
    name = path.name
    if text is None:
        try:
            check_file_size(name, path.stat().st_size)  # a huge file is never read
            text = path.read_text(encoding="utf-8", errors="replace")
        except OSError as e:
            raise ViewerError(f"{path}: cannot read BRDF file: {e.strerror or e}") from None
    check_sizes(name, text)
    lines = text.splitlines()
    first = next((i for i, l in enumerate(lines) if l.strip()), None)
    if first is None:
        raise ViewerError(f"{name}:1: empty BRDF file; the first line names the type ('analytic')")
    kind = lines[first].split()[0]
    if kind != "analytic":
        raise ViewerError(f"{name}:{first + 1}: BRDF type {kind!r} is not supported; allowed: 'analytic' "
                          f"(the first line names the type)")
    decls: list[Declaration] = []
    seen: set = set()
    sections: dict[str, list[int]] = {"shader": [], "isFunc": []}
    current, begun = None, 0
    for i in range(first + 1, len(lines)):
        ln = i + 1
        raw = lines[i]
        t = raw.strip()
        if not t or t.startswith("#"):
            continue
        tok = t.split()
        if tok[0] in ("::begin", "::end"):
            what = tok[1] if len(tok) > 1 else ""
            if tok[0] == "::begin":
                if current is not None:
                    raise ViewerError(f"{name}:{ln}: '::begin {what}' inside section {current!r} (begun on line "
                                      f"{begun}); close it with '::end {current}' first")
                if not what:
                    raise ViewerError(f"{name}:{ln}: '::begin' needs a section name: "
                                      + ", ".join(SECTIONS))
                current, begun = what, ln
            else:
                if what != current:
                    raise ViewerError(f"{name}:{ln}: '::end {what}' does not close "
                                      + (f"section {current!r} (begun on line {begun})" if current else
                                         "any section"))
                current = None
            continue
        if current == "parameters":
            decls.append(_parameter(t, ln, f"{name}:{ln}", seen))
        elif current in sections:
            sections[current].append(ln)
        # lines outside a section and in unknown sections are ignored, as BRDF Explorer does
    if current is not None:
        raise ViewerError(f"{name}:{begun}: section {current!r} is never closed ('::end {current}' missing)")
    floats = sum(3 if d.kind == "color" else 1 for d in decls)
    if floats > MAX_PARAM_FLOATS:
        raise ViewerError(f"{name}: its parameters are {floats} floats (a color is 3); a .brdf file may declare at "
                          f"most {MAX_PARAM_FLOATS}")
    if not sections["shader"]:
        raise ViewerError(f"{name}: no '::begin shader' section with a vec3 BRDF(vec3 L, vec3 V, vec3 N, "
                          f"vec3 X, vec3 Y) function")
    f = BrdfFile(path, kind, decls, lines, sections["shader"], sections["isFunc"])
    check_code(name, {ln: _strip_comments_line(lines[ln - 1]) for ln in f.shader + f.sampler})
    code = f._code(f.shader)
    if not re.search(r"\bBRDF\s*\(", code):
        raise ViewerError(f"{name}:{f.shader[0]}: the shader section defines no function "
                          f"'vec3 BRDF(vec3 L, vec3 V, vec3 N, vec3 X, vec3 Y)'")
    if f.sampler and not re.search(r"\bsampleBRDF\s*\(", f._code(f.sampler)):
        raise ViewerError(f"{name}:{f.sampler[0]}: the isFunc section defines no function 'sampleBRDF'")
    return f


#: the term view's functions a file may define (D, F, G of a microfacet lobe)
TERM_NAMES = ("D", "F", "G")
_TERM_DEF = re.compile(r"\b(float|vec3)\s+([DFG])\s*\(([^()]*)\)\s*\{")


def term_functions(f: BrdfFile) -> dict[str, str]:
    """The term functions the file's shader defines: {name: return type} for each of ``D``,
    ``F`` and ``G`` defined as ``float NAME(vec3 L, vec3 V, vec3 N, vec3 X, vec3 Y)`` (or
    returning ``vec3``), BRDF's own arguments; a function of those names with other arguments
    is not a term function."""
    out: dict[str, str] = {}
    for m in _TERM_DEF.finditer(_strip_block_comments(f._code(f.shader))):
        args = [a.split() for a in m.group(3).split(",")]
        if len(args) == 5 and all(len(a) >= 2 and a[-2] == "vec3" for a in args):
            out[m.group(2)] = m.group(1)
    return out


def sampler_takes_view(f: BrdfFile) -> bool:
    """The file's sampleBRDF takes the view direction first (this viewer's extension)."""
    m = re.search(r"\bsampleBRDF\s*\(\s*(?:in\s+)?(\w+)", f._code(f.sampler))
    return bool(m and m.group(1) == "vec3")
