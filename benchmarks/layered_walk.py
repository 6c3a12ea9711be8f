"""How far the layered model's closed form (both twins) is from the stochastic layered random walk
(viewer/brdf/layered_walk.py, the CPU reference's ``reference = "random_walk"``): directional
albedo over angles for Lambert and glossy bases and smooth and rough coats. One command:

    python benchmarks/layered_walk.py [--n 40000]

Prints, per case and cos(theta_o): the closed form's albedo (its own sampler, 48 x 48 stratified
samples), the walk's (the closed form's directions, weighted by the walk's f; +- 1 standard error)
and their difference. The walk's coat scatters multiply on its microsurface (Heitz et al. 2016's
dielectric walk), so a lossless coat over a white base returns 1 at every roughness.
"""

import argparse

import numpy as np

from viewer import brdf
from viewer.brdf import layered_walk
from viewer.brdf.albedo import directional_albedo

M = brdf.get("layered")
CASES = [
    ("white lambert, smooth coat 1.5", dict(ior=1.5, alpha=0.001), dict(model="lambert", albedo=[1, 1, 1])),
    ("white lambert, coat 1.5 alpha 0.1", dict(ior=1.5, alpha=0.1), dict(model="lambert", albedo=[1, 1, 1])),
    ("white lambert, coat 1.5 alpha 0.3", dict(ior=1.5, alpha=0.3), dict(model="lambert", albedo=[1, 1, 1])),
    ("white lambert, coat 1.5 alpha 0.6", dict(ior=1.5, alpha=0.6), dict(model="lambert", albedo=[1, 1, 1])),
    ("lambert 0.8, smooth coat 2.0, tau 0.1", dict(ior=2.0, alpha=0.001, thickness=10.0, sigma_a=[0.01] * 3),
     dict(model="lambert", albedo=[0.8] * 3)),
    ("gold microfacet a0.3, smooth coat 1.5", dict(ior=1.5, alpha=0.001),
     dict(model="microfacet", alpha=0.3, fresnel="conductor", eta=[0.18, 0.42, 1.37], k=[3.42, 2.35, 1.77])),
    ("F=1-ish silver microfacet a0.1, smooth coat 1.5", dict(ior=1.5, alpha=0.001),
     dict(model="microfacet", alpha=0.1, fresnel="conductor", eta=[0.05, 0.06, 0.05], k=[4.3, 3.6, 2.7])),
    ("white oren-nayar s0.5, smooth coat 1.5", dict(ior=1.5, alpha=0.001),
     dict(model="oren_nayar", albedo=[1, 1, 1], sigma=0.5)),
    ("white lambert, smooth coat 1.5 + film 300 nm", dict(ior=1.5, alpha=0.001, thin_film={"ior": 1.33, "thickness_nm": 300.0}),
     dict(model="lambert", albedo=[1, 1, 1])),
]


def walk_albedo(p, mu, n, seed=0):
    rng = np.random.default_rng(seed)
    wo = np.tile([np.sqrt(1 - mu * mu), 0.0, mu], (n, 1))
    wi, _, pdf = M.sample(p, wo, rng.random((n, 2)))
    f = layered_walk.eval_walk(p, wi, wo, rng)
    ok = pdf > 0
    w = np.where(ok[:, None], f * (wi[:, 2] / np.where(ok, pdf, 1.0))[:, None], 0.0)
    return w.mean(axis=0), w.std(axis=0) / np.sqrt(n)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=40000)
    a = ap.parse_args()
    mus = np.array([0.2, 0.5, 1.0])
    for label, coat, base in CASES:
        p = M.params(coating=coat, base=base)
        cf = directional_albedo(M, p, mus, n_side=48)
        print(label)
        for k, mu in enumerate(mus):
            w, se = walk_albedo(p, float(mu), a.n, seed=k)
            print(f"  cos {mu:.1f}: closed {np.round(cf[k], 4)}  walk {np.round(w, 4)} +- {np.round(se, 4)}"
                  f"  closed - walk {np.round(cf[k] - w, 4)}")


if __name__ == "__main__":
    main()
