"""``--set KEY=VALUE`` overrides: applied to the TOML data before validation; a material's
``model`` or ``preset`` assignment starts that material afresh."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

from viewer.scene.model import MAX_SIZE, SIZE_ALLOWED, TOP_KEYS
from viewer.scene.validation import Checker, check_nesting, describe, short

try:  # Python >= 3.11
    import tomllib
except ModuleNotFoundError:  # pragma: no cover - Python 3.10
    import tomli as tomllib


_INDEX = re.compile(r"\[(\d+)\]")


def _parse_value(text: str):
    """A TOML value (number, bool, array, inline table, quoted string); else the bare text."""
    from viewer.base.input_bounds import toml_problem

    text = text.strip()
    problem = toml_problem(f"v = {text}")
    if problem:
        Checker(f"--set value {short(text)}").fail("value", problem.split(": ", 1)[-1], "a TOML value")
    try:
        value = tomllib.loads(f"v = {text}")["v"]
    except (ValueError, RecursionError):  # TOMLDecodeError is a ValueError; so is a 5000-digit integer
        return text
    check_nesting(value, f"--set value {short(text)}")
    return value


def dotted_key(key: str) -> str:
    """A ``--set`` KEY with list indices written as path parts: ``lobes[0].n`` -> ``lobes.0.n``."""
    return _INDEX.sub(r".\1", key.strip())


def _override_parts(assignment: str) -> list[str]:
    key = assignment.split("=", 1)[0] if "=" in assignment else ""
    return dotted_key(key).split(".")


def is_material_switch(assignment: str) -> bool:
    """``materials.NAME.model=...`` or ``materials.NAME.preset=...`` (also a nested material's,
    ``materials.NAME.base.model=...``)."""
    parts = _override_parts(assignment)
    if len(parts) == 3 and parts[0] == "materials" and parts[-1] == "file" and all(parts):
        return _is_brdf_file(assignment)  # a .brdf file: the material becomes that file's model
    return len(parts) >= 3 and parts[0] == "materials" and parts[-1] in ("model", "preset") and all(parts)


def _is_brdf_file(assignment: str) -> bool:
    text = assignment.split("=", 1)[1].strip().strip("\"'") if "=" in assignment else ""
    return text.lower().endswith(".brdf")


def switch_material(data: dict, assignment: str) -> None:
    """Apply a model / preset assignment and drop every other value of that material table, so
    the material becomes the model's defaults or the preset."""
    parts = _override_parts(assignment)
    apply_override(data, assignment)  # checks the path, sets the value
    cur: Any = data
    for p in parts[:-1]:
        cur = cur[int(p)] if isinstance(cur, list) else cur[p]
    if isinstance(cur, dict):
        value = cur[parts[-1]]
        cur.clear()
        cur[parts[-1]] = value
        if parts[-1] == "file":  # materials.NAME.file=NAME.brdf (found from the working folder too)
            cur["model"] = "custom"
            if isinstance(value, str) and not Path(value).is_absolute() and Path(value).is_file():
                cur["file"] = str(Path(value).absolute())


def apply_override(data: dict, assignment: str, where: str = "--set") -> None:
    """Apply one ``KEY=VALUE`` assignment to ``data`` in place.

    KEY is a dotted path (``materials.ball.alpha``, ``camera.fov_y``); list items are addressed
    by index (``lights.0.intensity`` or ``lights[0].intensity``). VALUE is parsed as a TOML
    value (``0.2``, ``[1, 2, 3]``, ``true``, ``"text"``); a bare word that is not TOML is taken
    as a string (``model=ggx``). Missing top-level sections (camera, environment, render,
    materials) are created; any other missing part of the path is an error naming it. The
    value itself is checked later, by ``parse_scene``.
    """
    ck = Checker(f"{where} {short(assignment)}")
    if "=" not in assignment:
        ck.fail("KEY=VALUE", "no '=' in the assignment", "KEY=VALUE with a dotted KEY, e.g. materials.ball.alpha=0.2")
    key, text = assignment.split("=", 1)
    key = dotted_key(key)
    parts = key.split(".")
    if not key or any(not p for p in parts):
        ck.fail(key or "KEY", "empty part in the dotted path",
                "a dotted path like materials.ball.alpha or lights.0.intensity")
    value = _parse_value(text)
    cur: Any = data
    for depth, part in enumerate(parts):
        here = ".".join(parts[:depth + 1])
        last = depth == len(parts) - 1
        if isinstance(cur, list):
            if not part.isdigit() or int(part) >= len(cur):
                allowed = (f"an index 0..{len(cur) - 1}" if cur else "nothing: the list is empty")
                ck.fail(here, f"no item {part!r} in {'.'.join(parts[:depth]) or 'the list'}", allowed)
            idx = int(part)
            if last:
                cur[idx] = value
            else:
                cur = cur[idx]
        elif isinstance(cur, dict):
            if last:
                cur[part] = value
            elif part in cur:
                cur = cur[part]
            elif depth == 0 and part in ("camera", "environment", "render", "materials"):
                cur[part] = {}
                cur = cur[part]
            else:
                allowed = ", ".join(map(str, cur)) if cur else "nothing here yet"
                if depth == 0:
                    allowed = ", ".join(TOP_KEYS)
                ck.fail(here, f"no {part!r} in {'.'.join(parts[:depth]) or 'the scene'}", allowed)
        else:
            ck.fail(here, f"{'.'.join(parts[:depth])} is a value ({describe(cur)}), not a table or list",
                    "a path that ends at " + ".".join(parts[:depth]))


def check_replaced(assignments, replaced: dict[str, str], where: str = "--set") -> None:
    """Check the ``camera.width`` / ``camera.height`` assignments among ``assignments`` that a
    command-line option replaces (``replaced``: key -> the option, e.g. ``--width``): a value
    that would be refused must not pass unseen because ``--width`` overwrites it. Raises
    ``ViewerError`` (one line)."""
    for a in assignments:
        if "=" not in a:
            continue
        key, text = a.split("=", 1)
        key = dotted_key(key)
        if key in replaced and key in ("camera.width", "camera.height"):
            ck = Checker(f"{where} {short(a)} (replaced by {replaced[key]})")
            ck.integer(_parse_value(text), key, SIZE_ALLOWED, 1, MAX_SIZE)
