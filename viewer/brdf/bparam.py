"""BRDF Explorer's parameter files (``.bparam``): a material's values, saved and loaded.

The format (as BRDF Explorer writes it, ``BRDFBase::saveParamsFile``, and reads it,
``BRDFBase::loadBRDF`` / ``processParameterLine``)::

    bparam PATH-OF-THE-BRDF-FILE

    ::begin parameters
    float NAME MIN MAX VALUE
    bool NAME 0|1
    color NAME R G B
    ::end parameters

The first line names the BRDF the values belong to (BRDF Explorer opens that file and copies
the values whose name matches one of its parameters, per kind: ``syncParametersIntoBRDF``).
Blank lines and lines starting with ``#`` are skipped; sections other than ``parameters`` are
ignored (BRDF Explorer warns about them); a float's MIN and MAX are the slider's range, only its
VALUE is a value. Here the values go through the material's own validation (a float out of the
file's declared range is one error naming the parameter), names the material lacks or whose kind
differs are reported in one line and left out.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from viewer import ViewerError
from viewer.base.io import atomic_write_bytes, one_line, stat_file

SUFFIX = ".bparam"
#: the most bytes of a .bparam file (one written for a file of 100 parameters is about 4 KB)
MAX_BYTES = 1024 * 1024
_KINDS = {"float": (1, "float"), "bool": (1, "bool"), "color": (3, "rgb")}


@dataclass
class Entry:
    kind: str          # "float", "bool" or "color" (the file's words)
    name: str
    value: object      # float, bool or a list of 3 floats
    line: int
    range: tuple | None = None  # a float's (min, max) as written


@dataclass
class BparamFile:
    path: Path
    brdf: str                    # the first line's file name, as written
    entries: list[Entry] = field(default_factory=list)

    def brdf_path(self) -> Path:
        """The BRDF file the values belong to; a relative name is taken beside the .bparam file."""
        p = Path(self.brdf).expanduser()
        return p if p.is_absolute() else self.path.parent / p


def _number(word: str, where: str, what: str) -> float:
    try:
        v = float(word)
    except ValueError:
        raise ViewerError(one_line(f"{where}: {what} {word!r} is not a number")) from None
    if not np.isfinite(v):
        raise ViewerError(one_line(f"{where}: {what} {word!r} is not a finite number"))
    return v


def parse(path, text: str | None = None) -> BparamFile:
    """Read a .bparam file; one-line ViewerError naming ``FILE:LINE`` for anything outside the
    format (no ``bparam`` first line, a parameter line of another kind or with missing or bad
    numbers, an unclosed or nested section, a file too large or not UTF-8 text)."""
    path = Path(path)
    if text is None:
        st, problem = stat_file(path)
        if problem:
            raise ViewerError(one_line(f"{path}: {problem}; allowed: a BRDF Explorer parameter file (.bparam)"))
        if st.st_size > MAX_BYTES:
            raise ViewerError(one_line(f"{path}: {st.st_size} bytes; a .bparam file holds at most {MAX_BYTES}"))
        try:
            text = path.read_bytes().decode("utf-8")
        except UnicodeDecodeError as e:
            raise ViewerError(one_line(f"{path}: not a text file (byte {e.start} is not UTF-8)")) from None
        except OSError as e:
            raise ViewerError(one_line(f"{path}: cannot be read ({e.strerror or e})")) from None
    lines = text.splitlines()
    first = lines[0].strip() if lines else ""
    words = first.split(None, 1)
    if not words or words[0] != "bparam":
        raise ViewerError(one_line(f"{path}:1: not a BRDF Explorer parameter file: the first line is {first[:60]!r}; "
                                   f"allowed: 'bparam FILE' (the BRDF the values belong to)"))
    out = BparamFile(path, words[1].strip() if len(words) > 1 else "")
    section = ""
    for k, raw in enumerate(lines[1:], start=2):
        line = raw.strip()
        where = f"{path}:{k}"
        if not line or line.startswith("#"):
            continue
        w = line.split()
        if w[0] == "::begin":
            if section:
                raise ViewerError(one_line(f"{where}: '::begin' inside the section {section!r}; sections do not nest"))
            section = w[1] if len(w) > 1 else ""
            continue
        if w[0] == "::end":
            if (w[1] if len(w) > 1 else "") != section or not section:
                raise ViewerError(one_line(f"{where}: {line!r} does not close the open section {section or '(none)'!r}"))
            section = ""
            continue
        if section != "parameters":
            continue  # another section (BRDF Explorer warns and skips it), or text outside one
        if w[0] not in _KINDS:
            raise ViewerError(one_line(f"{where}: {w[0]!r} is not a parameter kind; allowed: float NAME MIN MAX "
                                       f"VALUE, bool NAME 0|1, color NAME R G B"))
        need = {"float": 5, "bool": 3, "color": 5}[w[0]]
        if len(w) != need:
            raise ViewerError(one_line(f"{where}: a {w[0]} line has {need} words ({line!r} has {len(w)})"))
        kind, name = w[0], w[1]
        if kind == "float":
            lo, hi, v = (_number(x, where, f"{name}'s {what}") for x, what in zip(w[2:], ("min", "max", "value")))
            out.entries.append(Entry(kind, name, v, k, (lo, hi)))
        elif kind == "bool":
            if w[2] not in ("0", "1"):
                raise ViewerError(one_line(f"{where}: bool {name} is {w[2]!r}; allowed: 0 or 1"))
            out.entries.append(Entry(kind, name, w[2] == "1", k))
        else:
            out.entries.append(Entry(kind, name, [_number(x, where, f"{name}'s colour") for x in w[2:]], k))
    if section:
        raise ViewerError(one_line(f"{path}: the section {section!r} is not closed ('::end {section}')"))
    return out


def assignments(spec, bp: BparamFile) -> tuple[dict, list[str]]:
    """({parameter: value} of the entries that match a parameter of ``spec`` by name and kind,
    [the entries left out, as 'kind name']). A later entry of a name wins."""
    known = {p.name: p for p in spec.params}
    values, left = {}, []
    for e in bp.entries:
        p = known.get(e.name)
        if p is None or p.kind != _KINDS[e.kind][1]:
            left.append(f"{e.kind} {e.name}")
            continue
        values[e.name] = e.value
    return values, left


def apply(model, params, bp: BparamFile):
    """``params`` (of ``model``, a registry model or a file model) with the file's values set,
    validated as a scene's values, and the one-line note of what was left out (or "")."""
    values, left = assignments(model.spec, bp)
    raw = params.to_plain()
    raw.pop("model", None)
    raw.update(values)
    try:
        new = model.params(**raw)
    except ViewerError as e:
        raise ViewerError(one_line(f"{bp.path}: {e}")) from None
    note = ""
    if left:
        note = one_line(f"{bp.path}: {len(left)} parameters not in {model.name!r} left out: {', '.join(left)}")
    return new, note


def _fmt(v: float) -> str:
    return repr(float(v))  # shortest exact decimal (BRDF Explorer writes %f and reads any)


def text_of(model, params, brdf_name: str) -> str:
    """The .bparam text of ``params``: floats (with their range), bools, then colours, as BRDF
    Explorer writes them; parameters of other kinds (a path, a choice) have no line."""
    lines = [f"bparam {brdf_name}", "", "::begin parameters"]
    floats = [p for p in model.spec.params if p.kind == "float"]
    bools = [p for p in model.spec.params if p.kind == "bool"]
    colours = [p for p in model.spec.params if p.kind == "rgb"]
    for p in floats:
        v = float(params[p.name])
        lo = p.lo if p.lo is not None else min(v, 0.0)
        hi = p.hi if p.hi is not None else max(v, 1.0)
        lines.append(f"float {p.name} {_fmt(lo)} {_fmt(hi)} {_fmt(v)}")
    for p in bools:
        lines.append(f"bool {p.name} {1 if params[p.name] else 0}")
    for p in colours:
        r, g, b = (float(x) for x in np.asarray(params[p.name], dtype=float).reshape(-1)[:3])
        lines.append(f"color {p.name} {_fmt(r)} {_fmt(g)} {_fmt(b)}")
    lines.append("::end parameters")
    return "\n".join(lines) + "\n"


def save(path, model, params, brdf_name: str | None = None) -> Path:
    """Write ``params`` as a .bparam file, atomically; the first line names ``brdf_name``
    (default: the material's ``file``, absolute, so BRDF Explorer finds it from anywhere)."""
    if brdf_name is None:
        f = params.get("file") if "file" in model.spec.names else None
        brdf_name = os.path.abspath(os.fspath(f)) if f else model.name
    return atomic_write_bytes(path, text_of(model, params, brdf_name).encode("utf-8"))


def overrides(path, prefix: str = "") -> tuple[list[str], str]:
    """The ``--set`` assignments (``PREFIX + NAME=VALUE``) of a .bparam file's values that match the
    parameters of the BRDF file it names (by name and kind), and the one-line note of those left
    out (or ""); the CLI puts them before the user's own ``--set``, which win."""
    import json

    from viewer import brdf

    bp = parse(path)
    target = bp.brdf_path()
    if not bp.brdf:
        raise ViewerError(one_line(f"{bp.path}:1: the first line names no BRDF file ('bparam FILE')"))
    model = brdf.load(target)
    values, left = assignments(model.spec, bp)
    lines = [f"{prefix}{k}={json.dumps(v)}" for k, v in values.items()]
    note = one_line(f"{bp.path}: {len(left)} parameters not in {target.name} left out: {', '.join(left)}") if left else ""
    return lines, note
