"""The raster's GLSL 4.10 programs converted mechanically to GLSL ES 3.00 (WebGL2), at build time.

The input is what ``viewer.gl.shaders.program_sources`` assembles for the window (includes
inlined with ``#line`` directives, ``#define``s after ``#version``); nothing is ported by hand.
The conversion, line by line:

- ``#version 410 core`` becomes ``#version 300 es`` followed by ``highp`` default precision for
  ``float``, ``int`` and every sampler type (GLSL ES gives fragment floats no default, and
  ``sampler3D``, ``sampler2DArray``, ``sampler2DShadow`` none at all);
- the preprocessor conditionals are evaluated with the program's ``#define``s (``#ifdef``,
  ``#ifndef``, ``#if`` / ``#elif`` over ``defined``, ``!``, ``&&``, ``||``, integer comparisons), and
  the lines of inactive branches are blanked (the directives stay, so the ES compiler takes the
  same branches and the line numbers stay those of the files);
- active code is checked for what GLSL ES 3.00 lacks (geometry stages, doubles, 1D and buffer
  samplers, ``textureGather``, ``fma``, the bit-field functions, ``noperspective``, dual-source
  ``index =`` outputs, uniform initializers, ...): any such construct raises ``ConversionError``
  naming it, with the file and line it came from (``FILE:LINE: ...``);
- a geometry stage that only passes its triangle through and adds values computed from the whole
  triangle (``passes/forward.geom``: the flat geometric normal) has no ES counterpart: the
  vertex stage's outputs it forwards are renamed to the geometry stage's output names, and each
  value the stage computes becomes a vertex attribute ``in_<name>`` that the host fills per
  triangle corner (``geometry_attributes``); the host's formula is the stage's (the live view's
  runtime computes the same cross product of the triangle's world positions).

- a ``.brdf`` file's own shader lines (BRDF Explorer's dialect, which leans on desktop GLSL's
  implicit int-to-float conversions) get their integer literals written as float literals where
  no integer variable is in the statement (``float_literals``).

What this does not check: other implicit int-to-float conversions (an int variable where a float
is needed), which need types; the ES compiler reports them (the browser test compiles every
program). The viewer's own shaders use none.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

from viewer import ViewerError

ES_VERSION = "#version 300 es"
#: default precision of every type the raster's programs use (highp: the desktop's float32)
PRECISION = ("precision highp float;", "precision highp int;", "precision highp sampler2D;",
             "precision highp sampler3D;", "precision highp sampler2DArray;", "precision highp sampler2DShadow;",
             "precision highp samplerCube;", "precision highp isampler2D;", "precision highp usampler2D;")

#: constructs of GLSL 4.10 that GLSL ES 3.00 lacks: (regex over a comment-free active line, name)
UNSUPPORTED = [
    (r"\bdouble\b|\bdvec[234]\b|\bdmat[234]\b", "double precision (double, dvec, dmat)"),
    (r"\b[iu]?sampler1D\w*\b", "1D samplers"),
    (r"\b[iu]?samplerBuffer\b", "buffer samplers"),
    (r"\b[iu]?samplerCubeArray\w*\b", "cube map array samplers"),
    (r"\b[iu]?sampler2DMS\w*\b", "multisample samplers"),
    (r"\b[iu]?sampler2DRect\w*\b", "rectangle samplers"),
    (r"\btextureGather\w*\b", "textureGather"),
    (r"\btextureQueryL\w+\b", "textureQueryLod / textureQueryLevels"),
    (r"\bfma\s*\(", "fma()"),
    (r"\bfrexp\s*\(|\bldexp\s*\(", "frexp() / ldexp()"),
    (r"\bbitfield(Extract|Insert|Reverse)\s*\(", "bitfieldExtract / Insert / Reverse"),
    (r"\bbitCount\s*\(|\bfind[LM]SB\s*\(", "bitCount / findLSB / findMSB"),
    (r"\buaddCarry\s*\(|\busubBorrow\s*\(|\b[ui]mulExtended\s*\(", "extended integer arithmetic"),
    (r"\b(pack|unpack)(Unorm|Snorm)4x8\s*\(", "packUnorm4x8 and relatives"),
    (r"\binterpolateAt\w+\s*\(", "interpolateAt* functions"),
    (r"\bEmitVertex\s*\(|\bEndPrimitive\s*\(|\bgl_in\b", "geometry shader built-ins"),
    (r"\bgl_PrimitiveID\b|\bgl_Layer\b|\bgl_ViewportIndex\b|\bgl_ClipDistance\b|\bgl_SampleID\b",
     "built-ins GLSL ES 3.00 lacks (gl_PrimitiveID, gl_Layer, gl_ClipDistance, gl_SampleID...)"),
    (r"\bnoperspective\b", "the noperspective qualifier"),
    (r"\bsubroutine\b", "subroutines"),
    (r"\bprecise\b", "the precise qualifier"),
    (r"\bpatch\b", "tessellation patches"),
    (r"\bimage[123]D\w*\b|\bimage(Load|Store)\s*\(|\batomic\w*\s*\(", "images and atomics"),
    (r"layout\s*\([^)]*\bindex\s*=", "dual-source outputs (layout index =)"),
    (r"^\s*(layout\s*\([^)]*\)\s*)?uniform\b[^;=]*=", "uniform initializers"),
    (r"\b(in|out)\s+\w+\s+\w+\s*\[\s*\]\s*;", "unsized stage arrays (geometry or tessellation interfaces)"),
]
_UNSUPPORTED = [(re.compile(p), name) for p, name in UNSUPPORTED]

_LINE = re.compile(r"^\s*#\s*line\s+(\d+)(?:\s+(\d+))?\s*$")
_DIRECTIVE = re.compile(r"^\s*#\s*(\w+)\s*(.*?)\s*$")
LINE_BASE = 100000  # viewer.gl.shaders.LINE_BASE: line k * LINE_BASE + n is line n of file k


class ConversionError(ViewerError):
    """A construct of the desktop GLSL that GLSL ES 3.00 cannot express; the message names it and
    the file and line it came from."""


@dataclass
class EsProgram:
    """A program converted to GLSL ES 3.00: the two stage sources and the vertex attributes the
    host fills per triangle corner in place of the desktop's geometry stage (name -> GLSL type)."""

    vertex: str
    fragment: str
    geometry_attributes: dict[str, str] = field(default_factory=dict)


# ------------------------------------------------------------------ comments and locations
def strip_comments(lines: list[str]) -> list[str]:
    """The lines with // and /* */ comments replaced by spaces (line count kept)."""
    out, in_block = [], False
    for line in lines:
        res, i = [], 0
        while i < len(line):
            if in_block:
                j = line.find("*/", i)
                if j < 0:
                    i = len(line)
                    break
                i, in_block = j + 2, False
                res.append(" ")
                continue
            if line.startswith("//", i):
                break
            if line.startswith("/*", i):
                in_block, i = True, i + 2
                continue
            res.append(line[i])
            i += 1
        out.append("".join(res))
    return out


def line_files(lines: list[str]) -> list[int]:
    """Per line of a preprocessed source, the index of the file it came from (its ``#line``
    directives; a directive line counts as the file it names)."""
    out, idx = [], 0
    for line in lines:
        m = _LINE.match(line)
        if m:
            n = int(m.group(1))
            idx = int(m.group(2)) if m.group(2) is not None else idx
            if n >= LINE_BASE:
                idx = n // LINE_BASE
        out.append(idx)
    return out


# ------------------------------------------------------------------ .brdf files' literals
#: an integer literal (not part of a float, hex or unsigned literal, nor of a name)
_INT_LITERAL = re.compile(r"(?<![\w.])(?<![eE][+-])(\d+)(?![\w.])")
_INT_DECL = re.compile(r"\b(?:int|uint|ivec[234]|uvec[234])\s+(\w+)")


def float_literals(code: list[str]) -> list[str]:
    """Lines of a ``.brdf`` file's shader (BRDF Explorer's dialect: desktop GLSL, which turns an
    int into a float where a float is needed; GLSL ES does not) with each integer literal written
    as a float literal (``1 - c`` -> ``1.0 - c``, ``min(1, x)`` -> ``min(1.0, x)``), except inside
    ``[...]``, in preprocessor lines, in ``case`` labels and in any statement that names an integer
    variable of the file or declares one (there the literal may be an int; what is left the ES
    compiler reports)."""
    ints = set()
    for line in code:
        ints.update(_INT_DECL.findall(line))
    int_word = re.compile(r"\b(" + "|".join(map(re.escape, sorted(ints))) + r")\b") if ints else None
    out = []
    for line in code:
        if line.lstrip().startswith("#") or re.match(r"\s*case\b", line):
            out.append(line)
            continue
        pieces, depth = [], 0
        # statements: split at ; { } so one with an int variable keeps its literals
        for part in re.split(r"([;{}])", line):
            if part in (";", "{", "}") or (int_word is not None and int_word.search(part)) or _INT_DECL.search(part) \
                    or re.search(r"\bfor\s*\(\s*(int|uint)\b", part):
                pieces.append(part)
                depth += part.count("[") - part.count("]")
                continue
            res, i = [], 0
            for m in _INT_LITERAL.finditer(part):
                seg = part[i:m.start()]
                depth += seg.count("[") - seg.count("]")
                res.append(seg)
                res.append(m.group(1) if depth > 0 else m.group(1) + ".0")
                i = m.end()
            tail = part[i:]
            depth += tail.count("[") - tail.count("]")
            res.append(tail)
            pieces.append("".join(res))
        out.append("".join(pieces))
    return out


def _locator(files: list[str] | None):
    """A function index -> 'FILE:LINE' of a preprocessed source's line (from its #line directives)."""
    def where(lines: list[str], index: int) -> str:
        file_idx, line_no = 0, 1
        for k in range(index):
            m = _LINE.match(lines[k])
            if m:
                n = int(m.group(1))
                idx = int(m.group(2)) if m.group(2) is not None else file_idx
                if n >= LINE_BASE:
                    idx, n = divmod(n, LINE_BASE)
                file_idx, line_no = idx, n
            else:
                line_no += 1
        name = files[file_idx] if files and 0 <= file_idx < len(files) else f"<source {file_idx}>"
        return f"{name}:{line_no}"
    return where


# ------------------------------------------------------------------ the conditionals
_TOKEN = re.compile(r"\s*(defined|\d+|[A-Za-z_]\w*|&&|\|\||==|!=|<=|>=|[()!<>])")


def _eval_condition(expr: str, macros: dict[str, str], where: str) -> bool:
    """The value of an ``#if`` expression: defined(X), defined X, !, &&, ||, (), integer
    literals and object-like macros with integer values, ==, !=, <, >, <=, >=."""
    toks, pos = [], 0
    expr = expr.strip()
    while pos < len(expr):
        m = _TOKEN.match(expr, pos)
        if not m:
            raise ConversionError(f"{where}: cannot evaluate the preprocessor condition {expr!r} "
                                  f"(at {expr[pos:]!r}); GLSL ES conversion knows defined, !, &&, ||, "
                                  "comparisons of integers")
        toks.append(m.group(1))
        pos = m.end()
    k = [0]

    def peek():
        return toks[k[0]] if k[0] < len(toks) else None

    def take(t=None):
        tok = peek()
        if tok is None or (t is not None and tok != t):
            raise ConversionError(f"{where}: cannot evaluate the preprocessor condition {expr!r}")
        k[0] += 1
        return tok

    def value(name: str, depth: int = 0) -> int:
        if name.isdigit():
            return int(name)
        v = macros.get(name)
        if v is None:
            return 0  # the C preprocessor's rule: an undefined identifier is 0
        v = v.strip()
        if re.fullmatch(r"\d+", v):
            return int(v)
        if depth < 8 and re.fullmatch(r"[A-Za-z_]\w*", v):
            return value(v, depth + 1)
        raise ConversionError(f"{where}: the macro {name} = {v!r} in {expr!r} is not an integer")

    def primary():
        tok = take()
        if tok == "!":
            return not primary()
        if tok == "(":
            v = disjunction()
            take(")")
            return v
        if tok == "defined":
            if peek() == "(":
                take("(")
                name = take()
                take(")")
            else:
                name = take()
            return name in macros
        return value(tok)

    def comparison():
        a = primary()
        while peek() in ("==", "!=", "<", ">", "<=", ">="):
            op, b = take(), primary()
            a = {"==": a == b, "!=": a != b, "<": a < b, ">": a > b, "<=": a <= b, ">=": a >= b}[op]
        return a

    def conjunction():
        v = comparison()
        while peek() == "&&":
            take()
            v = comparison() and v
        return v

    def disjunction():
        v = conjunction()
        while peek() == "||":
            take()
            v = conjunction() or v
        return v

    result = disjunction()
    if peek() is not None:
        raise ConversionError(f"{where}: cannot evaluate the preprocessor condition {expr!r}")
    return bool(result)


def active_lines(lines: list[str], where) -> list[bool]:
    """Per line, whether it is compiled (outside every inactive branch); directives count as
    active. Tracks ``#define`` / ``#undef`` of active lines."""
    macros: dict[str, str] = {}
    stack: list[list[bool]] = []  # [this branch active, some branch taken, parent active]
    out = []
    code = strip_comments(lines)
    for i, line in enumerate(code):
        on = all(s[0] for s in stack)
        m = _DIRECTIVE.match(line)
        if not m:
            out.append(on)
            continue
        d, rest = m.group(1), m.group(2)
        parent = on
        if d in ("ifdef", "ifndef", "if"):
            if d == "if":
                cond = _eval_condition(rest, macros, where(lines, i)) if parent else False
            else:
                cond = (rest.split()[0] in macros) == (d == "ifdef") if rest else False
            stack.append([cond, cond, parent])
        elif d == "elif":
            if not stack:
                raise ConversionError(f"{where(lines, i)}: #elif without #if")
            top = stack[-1]
            cond = (not top[1]) and top[2] and _eval_condition(rest, macros, where(lines, i))
            top[0] = cond
            top[1] = top[1] or cond
        elif d == "else":
            if not stack:
                raise ConversionError(f"{where(lines, i)}: #else without #if")
            top = stack[-1]
            top[0] = not top[1]
            top[1] = True
        elif d == "endif":
            if not stack:
                raise ConversionError(f"{where(lines, i)}: #endif without #if")
            stack.pop()
        elif on and d == "define":
            dm = re.match(r"([A-Za-z_]\w*)(\([^)]*\))?\s*(.*)$", rest)
            if dm:
                macros[dm.group(1)] = dm.group(3) if dm.group(2) is None else "<function-like>"
        elif on and d == "undef":
            macros.pop(rest.split()[0] if rest else "", None)
        out.append(True)
    if stack:
        raise ConversionError(f"{where(lines, len(lines) - 1)}: #if without #endif")
    return out


# ------------------------------------------------------------------ one stage
def convert_stage(text: str, files: list[str] | None = None, stage: str = "fragment",
                  renames: dict[str, str] | None = None, extra_decls: list[str] | None = None) -> str:
    """One preprocessed stage source (``viewer.gl.shaders.Source.text``; ``files`` its
    ``Source.files``) in GLSL ES 3.00. ``renames``: identifiers to rename in active code (whole
    words); ``extra_decls``: declarations added after the precision statements."""
    lines = text.splitlines()
    where = _locator(files)
    if not lines or not re.match(r"^\s*#\s*version\s+(\d+)", lines[0]):
        raise ConversionError(f"{(files or ['<source>'])[0]}:1: the {stage} stage does not start with a "
                              "#version line; GLSL ES conversion needs one")
    version = int(re.match(r"^\s*#\s*version\s+(\d+)", lines[0]).group(1))
    if version > 410:
        raise ConversionError(f"{(files or ['<source>'])[0]}:1: #version {version}: GLSL ES conversion "
                              "takes desktop GLSL up to 4.10")
    active = active_lines(lines, where)
    code = strip_comments(lines)
    if files and any(f.endswith(".brdf") for f in files):
        # a .brdf file's own lines: its integer literals as floats (see float_literals)
        owner = line_files(lines)
        mine = [i for i in range(len(lines)) if files[owner[i]].endswith(".brdf") and not _LINE.match(lines[i])]
        fixed = float_literals([code[i] for i in mine])
        for i, text in zip(mine, fixed):
            if text != code[i]:
                lines[i] = code[i] = text   # (its comments go: they were only comments)
    out = [ES_VERSION, *PRECISION, *(extra_decls or [])]
    rename = re.compile(r"\b(" + "|".join(map(re.escape, renames)) + r")\b") if renames else None
    for i in range(1, len(lines)):
        line, bare = lines[i], code[i]
        if not active[i]:
            out.append("")
            continue
        if _DIRECTIVE.match(bare):
            d = _DIRECTIVE.match(bare).group(1)
            if d == "extension":
                raise ConversionError(f"{where(lines, i)}: #extension {bare.split()[1:2]}: "
                                      "GLSL ES conversion takes no desktop extensions")
            out.append(line if rename is None else rename.sub(lambda m: renames[m.group(1)], line))
            continue
        for pat, name in _UNSUPPORTED:
            if pat.search(bare):
                raise ConversionError(f"{where(lines, i)}: {name} in the {stage} stage: GLSL ES 3.00 has no "
                                      f"counterpart ({bare.strip()[:80]!r})")
        if rename is not None:
            line = rename.sub(lambda m: renames[m.group(1)], line)
        out.append(line)
    # the precision statements and extra declarations moved every line after #version down: say
    # where line 2 is again, so the compiler's line numbers stay those of the files
    first = out[1 + len(PRECISION) + len(extra_decls or []):]
    head = out[:1 + len(PRECISION) + len(extra_decls or [])]
    return "\n".join(head + ["#line 2 0"] + first) + "\n"


# ------------------------------------------------------------------ the geometry stage
_GS_IN = re.compile(r"^\s*in\s+(\w+)\s+(\w+)\s*\[\s*\]\s*;")
_GS_OUT = re.compile(r"^\s*((?:flat|smooth)\s+)?out\s+(\w+)\s+(\w+)\s*;")
_GS_FORWARD = re.compile(r"^\s*(\w+)\s*=\s*(\w+)\s*\[\s*\w+\s*\]\s*;")
#: values a geometry stage may compute per triangle that the host can fill as an attribute (the
#: live view's runtime computes them with the same formula): name -> what it is
HOST_VALUES = {"v_geometric_normal": "the triangle's unit world-space normal from its winding"}


def fold_geometry(gs_text: str, gs_files: list[str] | None = None) -> tuple[dict[str, str], dict[str, str]]:
    """(renames for the vertex stage: its output -> the geometry stage's output it becomes,
    attributes: name -> type of each value the host fills in place of the stage). A geometry
    stage that does more than forward its inputs and add the values of ``HOST_VALUES`` is a
    ConversionError."""
    lines = gs_text.splitlines()
    code = strip_comments(lines)
    where = _locator(gs_files)
    ins, outs, renames = {}, {}, {}
    for i, line in enumerate(code):
        m = _GS_IN.match(line)
        if m:
            ins[m.group(2)] = m.group(1)
        m = _GS_OUT.match(line)
        if m:
            outs[m.group(3)] = (m.group(2), i)
        m = _GS_FORWARD.match(line)
        if m and m.group(2) in ins:
            renames[m.group(2)] = m.group(1)
    attrs = {}
    for name, (typ, i) in outs.items():
        if name in renames.values():
            continue
        if name not in HOST_VALUES:
            raise ConversionError(f"{where(lines, i)}: the geometry stage computes {name!r}; GLSL ES has no "
                                  f"geometry stage and the host fills only {', '.join(HOST_VALUES)}")
        attrs[name] = typ
    if set(renames) != set(ins):
        missing = sorted(set(ins) - set(renames))
        raise ConversionError(f"{(gs_files or ['<geometry>'])[0]}: the geometry stage does not simply forward "
                              f"{', '.join(missing)}; GLSL ES has no geometry stage")
    return renames, attrs


def attribute_name(varying: str) -> str:
    """The vertex attribute that carries a host value to the varying ``varying`` (v_x -> in_x)."""
    return "in_" + (varying[2:] if varying.startswith("v_") else varying)


def convert_program(vs, fs, gs=None) -> EsProgram:
    """Sources (``viewer.gl.shaders.Source``, as ``program_sources`` returns them) -> EsProgram."""
    renames, attrs = ({}, {}) if gs is None else fold_geometry(gs.text, gs.files)
    extra = []
    for name, typ in attrs.items():
        extra.append(f"in {typ} {attribute_name(name)};")
        extra.append(f"flat out {typ} {name};")
    vert = convert_stage(vs.text, vs.files, "vertex", renames=renames, extra_decls=extra)
    if attrs:
        # the vertex stage hands each host value on unchanged (flat: every corner of a triangle
        # carries the same one, so the provoking vertex does not matter)
        body = " ".join(f"{n} = {attribute_name(n)};" for n in attrs)
        vert = _append_to_main(vert, body, vs.files)
    frag = convert_stage(fs.text, fs.files, "fragment")
    return EsProgram(vert, frag, dict(attrs))


def _append_to_main(text: str, body: str, files) -> str:
    """``text`` with ``body`` inserted at the start of ``void main() {``, on its line (the line
    numbers after it stay those of the file)."""
    m = re.search(r"\bvoid\s+main\s*\(\s*(void)?\s*\)\s*\{", text)
    if not m:
        raise ConversionError(f"{(files or ['<vertex>'])[0]}: no main() to hand the host values on in")
    return text[:m.end()] + " " + body + text[m.end():]
