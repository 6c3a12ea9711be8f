"""The rasterizer's multiple-scattering compensation (Fdez-Aguera 2019) against the reference's
random walk on the microsurface (Heitz et al. 2016), as directional albedo in a white furnace:

    python benchmarks/ms_compensation.py [--n-side 24]

For GGX and Beckmann, a white conductor (F = 1), gold (conductor Fresnel) and a dielectric
(ior 1.5), per alpha: the albedo at normal incidence of single scattering, compensation and walk,
and the compensation's largest and mean absolute error against the walk over theta_o = 0..85
degrees (mean over the RGB channels), for the rasterizer's rule (E_ss = the lobe's own albedo
with F = 1) and, as "GGX table", the former rule (E_ss = A + B of the GGX DFG table for every
distribution).
These are the furnace sphere's values: a convex object in a constant environment shows
L_env times the albedo at each pixel's view angle, in both renderers."""

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n-side", type=int, default=24, help="sqrt of the samples per angle and azimuth")
    args = ap.parse_args(argv)
    from viewer import brdf
    from viewer.brdf import ms_compensation
    mf = brdf.get("microfacet")
    theta = np.radians(np.arange(0.0, 86.0, 5.0))
    cos_o = np.cos(theta)
    materials = {"white F=1": dict(fresnel="schlick", f0=1.0), "gold": dict(fresnel="conductor"),
                 "ior 1.5": dict(fresnel="dielectric", ior=1.5)}
    print(f"{'distribution':12s} {'material':10s} {'alpha':>5s} | normal incidence: {'single':>6s} {'comp.':>6s} "
          f"{'walk':>6s} | |comp. - walk|: {'max':>6s} {'mean':>6s} | GGX table: {'max':>6s} {'mean':>6s}")
    for dist in ("ggx", "beckmann"):
        for label, kw in materials.items():
            for alpha in (0.1, 0.25, 0.5, 0.75, 1.0):
                p = mf.params(distribution=dist, alpha=alpha, **kw)
                a = ms_compensation.albedos(p, cos_o, n_side=args.n_side)
                old = ms_compensation.albedos(p, cos_o, n_side=args.n_side, rule="ggx",
                                         known={"single": a["single"], "walk": a["walk"]})
                s, c, w = (a[k].mean(axis=1) for k in ("single", "compensated", "walk"))
                err = np.abs(a["compensated"] - a["walk"]).mean(axis=1)
                err_old = np.abs(old["compensated"] - a["walk"]).mean(axis=1)
                print(f"{dist:12s} {label:10s} {alpha:5.2f} | {'':17s} {s[0]:6.3f} {c[0]:6.3f} {w[0]:6.3f} | "
                      f"{'':15s} {err.max():6.3f} {err.mean():6.3f} | {'':11s} {err_old.max():6.3f} "
                      f"{err_old.mean():6.3f}")


if __name__ == "__main__":
    main()
