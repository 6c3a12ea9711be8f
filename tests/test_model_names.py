"""The model-name rule, read from the source with ``ast`` (docs/architecture.md, *How to add a
BRDF*): no code under ``viewer/`` outside the model modules (``viewer/brdf``: the families, the
registry and the file model) compares a material's model name. What a caller needs to know of a
material (is it delta, does it carry a thin film, is it dispersive, spectral, a random walk,
measured, a ``.brdf`` file, ...) is a hook of the model protocol answered in ``viewer/brdf``
(``viewer.brdf.has_film(p)``, ``viewer.brdf.is_dispersive(p)``, ``model.is_delta(p)``, ...).

Flagged: a comparison (``==``, ``!=``, ``in``, ``not in``) one side of which names a model (an
attribute or subscript ``model`` / ``name`` / ``model_name``, ``.get("model")``, ``getattr(x,
"model")``, a plain name ``model`` / ``model_name``, or the list ``models_used(p)`` /
``scene_models(scene)`` of the names a material uses) and the other a string literal, or a
tuple, list or set of them, that is a registered model's name (``viewer.brdf.names()`` and ``custom``). A parameter's or an
object's name compared with a string that names no model (``p.name == "thin_film"``) is not a
model name and is not flagged. Nothing is allowed: ``ALLOWED`` is empty, and a staleness test
keeps any entry someone adds naming a current offender.
"""

from __future__ import annotations

import ast
import functools
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
NAMING = {"model", "name", "model_name"}     # attributes / subscripts that hold a model's name
PLAIN_NAMES = {"model", "model_name"}        # bare variables that hold one
MODEL_LISTS = {"models_used", "scene_models"}  # functions returning the model names a material uses
ALLOWED: set[str] = set()                    # "path:line" entries, each with its reason beside it


@functools.lru_cache(maxsize=None)
def model_names() -> frozenset[str]:
    from viewer import brdf

    return frozenset(brdf.names()) | {"custom"}


def _names_a_model(node: ast.expr) -> bool:
    if isinstance(node, ast.Attribute):
        return node.attr in NAMING
    if isinstance(node, ast.Subscript):
        s = node.slice
        return isinstance(s, ast.Constant) and s.value in NAMING
    if isinstance(node, ast.Name):
        return node.id in PLAIN_NAMES
    if isinstance(node, ast.Call):
        fn = node.func.attr if isinstance(node.func, ast.Attribute) else getattr(node.func, "id", None)
        if fn in MODEL_LISTS:
            return True
        args = node.args
        key = args[1] if fn == "getattr" and len(args) > 1 else args[0] if fn == "get" and args else None
        return isinstance(key, ast.Constant) and key.value in NAMING
    return False


def _literal_models(node: ast.expr, names) -> list[str]:
    if isinstance(node, ast.Constant) and isinstance(node.value, str):
        return [node.value] if node.value in names else []
    if isinstance(node, (ast.Tuple, ast.List, ast.Set)):
        return [e.value for e in node.elts if isinstance(e, ast.Constant) and e.value in names]
    return []


def comparisons(source: str, where: str, names) -> list[str]:
    """``where:line: text`` for each comparison of a model's name with a model name literal."""
    out = []
    for node in ast.walk(ast.parse(source, where)):
        if not isinstance(node, ast.Compare):
            continue
        sides = [node.left, *node.comparators]
        for op, (a, b) in zip(node.ops, zip(sides, sides[1:])):
            if not isinstance(op, (ast.Eq, ast.NotEq, ast.In, ast.NotIn)):
                continue
            for x, y in ((a, b), (b, a)):
                found = _literal_models(y, names)
                if found and _names_a_model(x):
                    out.append(f"{where}:{node.lineno}: {ast.unparse(node)} (model {', '.join(found)})")
                    break
    return out


@functools.lru_cache(maxsize=None)
def offenders(root: Path, names: frozenset) -> tuple[str, ...]:
    out = []
    for path in sorted((root / "viewer").rglob("*.py")):
        rel = path.relative_to(root).as_posix()
        if rel.startswith("viewer/brdf/"):
            continue  # the model modules and the registry: where the names belong
        out.extend(comparisons(path.read_text(encoding="utf-8"), rel, names))
    return tuple(out)


def test_no_model_name_comparisons_outside_the_models():
    found = [f for f in offenders(ROOT, model_names()) if f.split(": ")[0] not in ALLOWED]
    assert not found, "ask the model (a hook or a viewer.brdf predicate) instead:\n" + "\n".join(found)


def test_the_allowances_name_only_current_offenders():
    current = {f.split(": ")[0] for f in offenders(ROOT, model_names())}
    assert ALLOWED <= current, sorted(ALLOWED - current)


def test_the_model_name_rule_can_fail():
    names = {"mirror", "lambert", "custom", "dielectric"}
    bad = "\n".join([
        'if p.model == "mirror": pass',
        'x = "lambert" != mat.params.model',
        'y = params["model"] in ("dielectric", "phong")',
        'z = model == "custom"',
        'w = spec.name not in {"mirror"}',
        'v = p.get("model") == "lambert"',
        'u = getattr(p, "model", None) != "mirror"',
        't = "custom" in models_used(p)',
    ])
    found = comparisons(bad, "synthetic.py", names)
    assert [f.split(":")[1] for f in found] == ["1", "2", "3", "4", "5", "6", "7", "8"], found
    fine = "\n".join([
        'if p.name == "thin_film": pass',          # a parameter's name: no model is called that
        'if os.name == "nt": pass',
        'if kind == "mirror": pass',                 # not a model's name (a chain's kind)
        'if p.model == q.model: pass',               # two models compared, no literal
        'if p.fresnel == "conductor": pass',
    ])
    assert comparisons(fine, "fine.py", names) == []
