"""``brdf-viewer fit MEASURED_FILE --model MODEL``: fit an analytic model to a measured BRDF
(viewer/brdf/fit.py), print the parameters and the error, write the material table (atomically)
and, optionally, the residual slice (viewer/plots/measured.py)."""

from __future__ import annotations

import argparse

from viewer import ViewerError


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="brdf-viewer fit", description=(
        "Fit an analytic BRDF model to a measured one (a MERL .binary file) by least squares on "
        "cosine-weighted values; print the parameters and the error, write a material table."))
    p.add_argument("file", help="a MERL .binary BRDF file")
    p.add_argument("--model", required=True, help="the model to fit, e.g. microfacet, lambert, blinn_phong")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="the model's start values and choices, e.g. distribution=beckmann, fresnel=schlick")
    p.add_argument("--fix", action="append", default=[], metavar="NAME",
                   help="keep this parameter at its start value (repeatable), e.g. --fix kd")
    p.add_argument("--out", default="fitted.toml", help="material file to write (default fitted.toml)")
    p.add_argument("--name", default="fitted", help="the material's name in the file (default fitted)")
    p.add_argument("--residual", metavar="PNG", help="also write the residual slice as a PNG")
    return p


def cmd_fit(args) -> int:
    from viewer import brdf, plots
    from viewer.brdf import fit, merl
    from viewer.base.io import check_output_path
    from viewer.scene import material_from_name, save_material

    out = check_output_path(args.out, (".toml",), "--out")
    res_png = check_output_path(args.residual, (".png",), "--residual") if args.residual else None
    if str(args.file).lower().endswith(".dat"):
        raise ViewerError(f"{args.file}: an MIT anisotropic table; fit reads isotropic MERL .binary files "
                          f"(the fitted models' isotropic lobes)")
    table = merl.read(args.file)
    start = material_from_name(args.model, args.overrides)
    spec = brdf.get(start.model).spec
    for name in args.fix:
        if name not in spec.names:
            raise ViewerError(f"--fix {name}: not a parameter of {start.model!r}; allowed: {', '.join(spec.names)}")
    r = fit.fit(table, start.model, start=start, fixed=tuple(args.fix))
    save_material(args.name, r.params, out)
    shown = ", ".join(f"{k} = {_fmt(r.params[k])}" for k in r.fitted)
    print(f"fitted {start.model} to {args.file} ({r.n_points} entries x 3 channels): {shown}")
    print(f"RMS of (f_model - f_measured) cos theta_i: {r.rms:.4g} /sr (start {r.rms_start:.4g}), "
          f"{100 * r.rel:.2f}% of the RMS of f cos theta_i")
    print(f"wrote {out} ([materials.{args.name}])")
    if res_png is not None:
        p = brdf.get("measured").params(file=str(args.file))
        fig = plots.figure(p, "slice", name=str(args.file), overlay=r.params)
        plots.write_plot(fig, res_png)
        print(f"wrote {res_png} (residual slice)")
    return 0


def _fmt(v) -> str:
    import numpy as np

    if isinstance(v, np.ndarray):
        return "[" + ", ".join(f"{x:.4g}" for x in v) + "]"
    return f"{v:.4g}" if isinstance(v, float) else str(v)
