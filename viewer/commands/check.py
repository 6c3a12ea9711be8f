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


def _format(rep: dict) -> str:
    lines = [f"{rep['file']}: {'PASS' if rep['pass'] else 'FAIL'}"]
    for name, c in rep["checks"].items():
        detail = ", ".join(f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}"
                           for k, v in c.items() if k in ("min", "max_rel_error", "max_albedo", "p_value", "count"))
        lines.append(f"    {name:13s} {'pass' if c['pass'] else 'FAIL'}" + (f"  ({detail})" if detail else ""))
        if name == "energy" and not c["pass"]:
            worst = max(range(len(c["albedo"])), key=lambda i: max(c["albedo"][i]))
            lines.append(f"        albedo {max(c['albedo'][worst]):.4g} > 1 at theta {c['theta_deg'][worst]} deg")
    return "\n".join(lines)


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
