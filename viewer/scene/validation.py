"""The validator's vocabulary: ``Checker`` builds the one-line messages
``<label>: <field>: <problem>; allowed: <what is allowed>`` and checks single values; TOML text is
read here (``loads_toml``) and refused when nested too deeply (``check_nesting``)."""

from __future__ import annotations

import math
import re
from typing import Sequence

import numpy as np

from viewer import ViewerError
from viewer.base.io import one_line
from viewer.scene.model import FLOAT32_MAX

try:  # Python >= 3.11
    import tomllib
except ModuleNotFoundError:  # pragma: no cover - Python 3.10
    import tomli as tomllib


def describe(v) -> str:
    if isinstance(v, bool):
        return f"{str(v).lower()} (a boolean)"
    if isinstance(v, str):
        return f"{short(v)!r} (a string)"
    if isinstance(v, dict):
        return "a table"
    if isinstance(v, list):
        return f"a list of {len(v)}"
    if isinstance(v, int) and abs(v) >= 10 ** 15:
        return "%.3g" % v if abs(v) < 10 ** 300 else "a huge integer"
    if isinstance(v, (int, float)):
        return f"{v!r}"
    return f"{v!r} (a {type(v).__name__})"


def short(text: str, n: int = 60) -> str:
    """``text`` cut to ``n`` characters for a message (a scene may hold a megabyte string)."""
    return text if len(text) <= n else text[: n - 3] + "..."


def _is_num(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _g(v: float) -> str:
    return f"{v:g}"


class Checker:
    """Builds the one-line messages: ``<label>: <field>: <problem>; allowed: <allowed>``."""

    def __init__(self, label: str):
        self.label = label

    def fail(self, fld: str, problem: str, allowed: str):
        # each part shortened: a problem quotes at most a short prefix of a 100 KB value or name
        raise ViewerError(one_line(f"{short(self.label, 200)}: {short(fld, 120)}: {short(problem, 200)}; "
                                   f"allowed: {allowed}"))

    def table(self, value, fld: str, keys: Sequence[str], what: str = "key") -> dict:
        if not isinstance(value, dict):
            self.fail(fld, f"expected a table, got {describe(value)}",
                      f"a table [{fld}] with keys " + ", ".join(keys))
        for k in value:
            if k not in keys:
                k = short(k, 40)
                self.fail(f"{fld}.{k}" if fld else k, f"unknown {what}", ", ".join(keys))
        return value

    def number(self, value, fld, allowed, lo=None, hi=None, lo_open=False, hi_open=False) -> float:
        if not _is_num(value):
            self.fail(fld, f"expected a number, got {describe(value)}", allowed)
        v = _to_float(value)
        if not math.isfinite(v):
            self.fail(fld, f"{describe(value)} is not a finite number", allowed)
        if abs(v) > FLOAT32_MAX:
            self.fail(fld, f"{_g(v)} is beyond the float32 range the renderers compute in (|x| <= 3.4e38)", allowed)
        if lo is not None and (v < lo or (lo_open and v == lo)):
            self.fail(fld, f"{_g(v)} is out of range", allowed)
        if hi is not None and (v > hi or (hi_open and v == hi)):
            self.fail(fld, f"{_g(v)} is out of range", allowed)
        return v

    def integer(self, value, fld, allowed, lo=None, hi=None, choices=None) -> int:
        if not isinstance(value, int) or isinstance(value, bool):
            self.fail(fld, f"expected an integer, got {describe(value)}", allowed)
        if (lo is not None and value < lo) or (hi is not None and value > hi) or (
                choices is not None and value not in choices):
            self.fail(fld, f"{describe(value)} is out of range", allowed)
        return int(value)

    def boolean(self, value, fld) -> bool:
        if not isinstance(value, bool):
            self.fail(fld, f"expected true or false, got {describe(value)}", "true, false")
        return value

    def choice(self, value, fld, choices) -> str:
        allowed = ", ".join(f'"{c}"' for c in choices)
        if not isinstance(value, str):
            self.fail(fld, f"expected a string, got {describe(value)}", allowed)
        if value not in choices:
            self.fail(fld, f"{value!r} is not allowed", allowed)
        return value

    def string(self, value, fld, allowed) -> str:
        if not isinstance(value, str):
            self.fail(fld, f"expected a string, got {describe(value)}", allowed)
        if not value.strip():
            self.fail(fld, "is empty", allowed)
        return value

    def vec3(self, value, fld, allowed, grey=False, nonneg=False, positive=False, nonzero=False) -> np.ndarray:
        if grey and _is_num(value):
            value = [value] * 3
        if not isinstance(value, list):
            self.fail(fld, f"expected 3 numbers, got {describe(value)}", allowed)
        if len(value) != 3:
            self.fail(fld, f"expected 3 numbers, got {len(value)}", allowed)
        for i, x in enumerate(value):
            if not _is_num(x):
                self.fail(f"{fld}[{i}]", f"expected a number, got {describe(x)}", allowed)
        with np.errstate(over="ignore"):
            arr = np.array([_to_float(x) for x in value], dtype=np.float64)
        if not np.all(np.isfinite(arr)):
            self.fail(fld, f"{[float(x) for x in arr]} is not finite", allowed)
        if np.any(np.abs(arr) > FLOAT32_MAX):
            self.fail(fld, f"{[_num(x) for x in arr]} is beyond the float32 range the renderers compute in "
                           "(|x| <= 3.4e38)", allowed)
        if nonneg and np.any(arr < 0):
            self.fail(fld, f"{[_num(x) for x in arr]} has a negative component", allowed)
        if positive and np.any(arr <= 0):
            self.fail(fld, f"{[_num(x) for x in arr]} has a component <= 0", allowed)
        if nonzero and not np.any(arr != 0):
            self.fail(fld, "is the zero vector", allowed)
        return arr


def _to_float(x) -> float:
    try:
        return float(x)
    except OverflowError:  # a TOML integer beyond any float
        return math.inf if x > 0 else -math.inf


def _num(x: float):
    return int(x) if float(x).is_integer() and abs(x) < 1e15 else float(x)


MAX_NESTING = 32  # tables and arrays inside each other; a scene needs 5


def loads_toml(text: str, label: str) -> dict:
    from viewer.base.input_bounds import toml_problem

    syntax = "TOML syntax (key = value, [table], [[array]], strings in double quotes)"
    problem = toml_problem(text)  # before the reader spends memory on it
    if problem:
        m = re.match(r"line \d+", problem)
        Checker(label).fail(m.group(0) if m else "TOML", problem[m.end() + 2:] if m else problem,
                            "a scene as in docs/scene-format.md")
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        msg = str(e).splitlines()[0] if str(e) else "invalid TOML"
        m = re.search(r"line (\d+)", msg)
        where = f"line {m.group(1)}" if m else "TOML"
        Checker(label).fail(where, f"TOML syntax error: {msg}", syntax)
    except RecursionError:  # the parser recurses once per nested [ or {
        Checker(label).fail("TOML", "arrays or inline tables nested too deeply to read", syntax)
    except ValueError as e:  # e.g. an integer of more than 4300 digits (int() refuses it)
        Checker(label).fail("TOML", f"a value cannot be read ({short(str(e).splitlines()[0], 80)})", syntax)
    return data


def check_nesting(data, label: str) -> None:
    """Refuse data nested deeper than MAX_NESTING (copying or walking it would recurse)."""
    stack = [(data, 0)]
    while stack:
        v, depth = stack.pop()
        if depth > MAX_NESTING:
            Checker(label).fail("TOML", f"tables or arrays nested more than {MAX_NESTING} deep",
                                 "a scene as in docs/scene-format.md (at most a few levels deep)")
        if isinstance(v, dict):
            stack.extend((x, depth + 1) for x in v.values())
        elif isinstance(v, list):
            stack.extend((x, depth + 1) for x in v)
