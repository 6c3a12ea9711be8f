"""``brdf-viewer check MODEL_OR_FILE [--set NAME=VALUE ...] [--json]``: the report card
(``viewer.brdf.report_card``) of a ``.brdf`` file or a built-in model or preset.

Exit status: 0 when every check passes, 1 when one fails, 2 when the file cannot be read or
compiled (one line naming ``FILE:LINE``), is over a size limit, or its GLSL is refused by the
loop budget or the test render (``viewer.brdf.glsl_guard``, ``viewer.gl.file_probe``), or an
argument is wrong; 130 after Ctrl-C, 143 after SIGTERM (at once, the test render's child killed)."""

from __future__ import annotations

import argparse
import json
import os
import signal
import sys
import threading

from viewer.commands.names import add_trust_option


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="brdf-viewer check",
                                description="The report card of a BRDF: finite, non-negative, reciprocal, "
                                            "energy (directional albedo), the numpy twin and the sampler.")
    p.add_argument("target", metavar="MODEL_OR_FILE", help="a .brdf file, a built-in model or a preset")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="NAME=VALUE",
                   help="a parameter value (repeatable), e.g. --set alpha=0.3")
    p.add_argument("--json", action="store_true", help="print the report as one JSON object")
    return add_trust_option(p)


def model_and_params(target: str, assignments):
    from viewer import brdf

    from viewer.scene import file_material, material_from_name

    if target.lower().endswith(".brdf"):
        model = brdf.load(target)
        return model, file_material(model, assignments)
    p = material_from_name(target, assignments)
    return brdf.get(p.model), p


def compile_check(model) -> None:
    """Compile a file model's GLSL now (a FileBrdfError, exit 2, names FILE.brdf:LINE)."""
    from viewer.brdf import FileModel

    if isinstance(model, FileModel):
        from viewer import file_brdf_evaluator

        file_brdf_evaluator().check(model.bfile)


#: the usual cause of a NaN in a .brdf file, printed under a failing ``finite``
NAN_HINT = ("the usual cause: pow(1 - VdotH, 5) with VdotH a hair above 1 (float32 rounding of",
            "dot(V, normalize(L + V)) where L = V) is pow of a negative number, a NaN on most GPUs;",
            "write pow(max(1 - VdotH, 0), 5) (and clamp what goes into sqrt, acos and pow alike)")


def _vec(v) -> str:
    return "(" + ", ".join(f"{x:.4g}" for x in v) + ")"


def _rgb(v, fmt) -> str:
    return " ".join(format(x, fmt) for x in v)


def _format(rep: dict) -> str:
    """The report card as text: one line per check, then the example pair of a failing finite
    or reciprocity check and the energy check's estimate, noise and tolerance at every angle."""
    lines = [f"{rep['file']}: {'PASS' if rep['pass'] else 'FAIL'}"]
    for name, c in rep["checks"].items():
        detail = ", ".join(f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}"
                           for k, v in c.items()
                           if k in ("min", "max_rel_error", "tolerance", "rounding", "max_albedo", "bound",
                                    "p_value", "count") and not isinstance(v, list))
        lines.append(f"    {name:13s} {'pass' if c['pass'] else 'FAIL'}" + (f"  ({detail})" if detail else ""))
        if name == "finite" and not c["pass"] and "example" in c:
            e = c["example"]
            lines.append(f"        f is NaN or Inf at wi {_vec(e['wi'])}, wo {_vec(e['wo'])}")
            if str(rep["file"]).lower().endswith(".brdf"):
                lines.extend(f"        {h}" for h in NAN_HINT)
        if name == "reciprocity" and not c["pass"] and "example" in c:
            e = c["example"]
            lines.append(f"        f(wi, wo) = {_rgb(e['f'], '.5g')} but f(wo, wi) = {_rgb(e['f_exchanged'], '.5g')} "
                         f"at wi {_vec(e['wi'])}, wo {_vec(e['wo'])}")
        if name == "energy" and "noise" in c:
            lines.extend(_energy_rows(c))
    return "\n".join(lines)


def _energy_rows(c: dict) -> list[str]:
    bound = c.get("bound", 1.0)
    rows = [f"        {'theta':>5}  {'albedo (R G B)':26s}  {'noise, 1 s.e. (R G B)':26s}  allowed above {bound:g}"]
    for t, a, n, tol in zip(c["theta_deg"], c["albedo"], c["noise"], c["tolerance"]):
        over = any(x - bound > y for x, y in zip(a, tol))
        rows.append(f"        {t:>5}  {_rgb(a, '8.5g'):26s}  {_rgb(n, '8.2g'):26s}  {_rgb(tol, '8.2g')}"
                    + ("  over" if over else ""))
    return rows


def _stop_now(signum, _frame):
    """Ctrl-C or SIGTERM: end at once, whatever GL work runs (a file's test render in its child,
    which is killed, or the card's evaluation on the evaluator's thread, which is not waited for)."""
    from viewer.gl.file_probe import cancel_all

    cancel_all()
    for f in (sys.stdout, sys.stderr):
        try:
            f.flush()
        except (OSError, ValueError):
            pass
    os._exit(128 + signum)


def cmd_check(args) -> int:
    old = {}
    if threading.current_thread() is threading.main_thread():
        for sig in (signal.SIGINT, signal.SIGTERM):
            old[sig] = signal.signal(sig, _stop_now)
    try:
        return _check(args)
    finally:
        for sig, handler in old.items():
            signal.signal(sig, handler)


def _check(args) -> int:
    from viewer.brdf.report_card import report

    model, p = model_and_params(args.target, args.overrides)
    compile_check(model)
    rep = report(model, p, args.target)
    if args.json:
        print(json.dumps(rep))
    else:
        print(_format(rep))
    sys.stdout.flush()
    return 0 if rep["pass"] else 1
