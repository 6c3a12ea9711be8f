"""Least-squares fit of an analytic BRDF model to a measured (MERL) table.

The data: the table's entries on a sub-grid (every theta_h bin, every ``step_d``-th theta_d and
``step_p``-th phi_d entry), both directions above the horizon and the entry measured (> 0). The
residual of one entry and channel is (f_model - f_measured) cos theta_i, the cosine-weighted
value (what a light of unit irradiance reflects: grazing entries, where measurements are least
reliable and f is largest, weigh little). scipy's trust-region reflective least squares keeps
every parameter in its range (Branch, Coleman and Li 1999; ``scipy.optimize.least_squares``).

Fitted: the float and rgb parameters of the model (choices stay as given) that change its
values on these directions (a parameter the chosen Fresnel form does not read, e.g. ``ior``
under ``fresnel = "schlick"``, is left out).
"""

from __future__ import annotations

import numpy as np

from viewer import ViewerError
from viewer.brdf import merl


def fit_points(table: np.ndarray, step_d: int = 6, step_p: int = 12):
    """(wi, wo, f) of the measured entries the fit uses."""
    th, td, pd = merl.grid_angles()
    ih, idd, ip = np.meshgrid(np.arange(merl.N_TH), np.arange(0, merl.N_TD, step_d),
                              np.arange(0, merl.N_PD, step_p), indexing="ij")
    ih, idd, ip = ih.ravel(), idd.ravel(), ip.ravel()
    wi, wo = merl.from_half_diff(th[ih], td[idd], pd[ip])
    f = table[ih, idd, ip]
    ok = (wi[:, 2] > 1e-3) & (wo[:, 2] > 1e-3) & np.all(f > 0, axis=1)
    return wi[ok], wo[ok], f[ok]


def _free(spec, p, fixed=()):
    """(name, kind, lo, hi) of the parameters to fit."""
    out = []
    for prm in spec.params:
        if prm.kind in ("float", "rgb") and prm.name not in fixed:
            out.append(prm)
    return out


def _pack(free, p):
    x, lo, hi = [], [], []
    for prm in free:
        v = np.atleast_1d(np.asarray(p[prm.name], dtype=np.float64))
        a = -np.inf if prm.lo is None else prm.lo
        b = np.inf if prm.hi is None else prm.hi
        x.extend(v.tolist())
        lo.extend([a] * v.size)
        hi.extend([b] * v.size)
    return np.array(x), np.array(lo), np.array(hi)


def _unpack(free, p, x):
    vals, i = {}, 0
    for prm in free:
        if prm.kind == "rgb":
            vals[prm.name] = np.array(x[i:i + 3])
            i += 3
        else:
            vals[prm.name] = float(x[i])
            i += 1
    return p.replace(**vals)


class FitResult:
    def __init__(self, params, rms, rel, fitted, n_points, residual_rms_start):
        self.params, self.rms, self.rel, self.fitted = params, rms, rel, fitted
        self.n_points, self.rms_start = n_points, residual_rms_start


def fit(table: np.ndarray, model_name: str, start=None, fixed=(), max_nfev: int = 60) -> FitResult:
    """Fit ``model_name`` (starting from ``start`` Params, default its defaults) to ``table``."""
    from scipy.optimize import least_squares

    from viewer import brdf

    model = brdf.get(model_name)
    spec = model.spec
    if spec.delta or spec.transmissive or spec.nests_material or model_name == "measured":
        raise ViewerError(f"--model: {model_name!r} cannot be fitted to a measured BRDF; allowed: a reflective "
                          f"model without a delta lobe or nested material, e.g. microfacet, lambert, "
                          f"blinn_phong, oren_nayar, lafortune, ashikhmin_shirley")
    p0 = start if start is not None else model.params()
    wi, wo, f = fit_points(table)
    if len(f) < 100:
        raise ViewerError("the measured table has fewer than 100 measured entries above the horizon; "
                          "nothing to fit")
    cos_i = wi[:, 2:3]
    free = _free(spec, p0, fixed)
    x0, lo, hi = _pack(free, p0)
    x0 = np.clip(x0, lo, hi)
    # leave out what does not change the model here (e.g. ior under Schlick's Fresnel)
    base = model.eval(p0, wi[::7], wo[::7])
    keep = []
    for prm in free:
        v = np.atleast_1d(np.asarray(p0[prm.name], dtype=np.float64))
        a = -np.inf if prm.lo is None else prm.lo
        b = np.inf if prm.hi is None else prm.hi
        step = 0.05 * max(1.0, float(np.max(np.abs(v))))
        trial = np.where(v + step <= b, v + step, v - step)
        trial = np.clip(trial, a, b)
        q = p0.replace(**{prm.name: trial if prm.kind == "rgb" else float(trial[0])})
        if np.any(np.abs(model.eval(q, wi[::7], wo[::7]) - base) > 1e-9 * (1.0 + np.abs(base))):
            keep.append(prm)
    free = keep
    if not free:
        raise ViewerError(f"--model: {model_name!r} has no parameter that changes its values here")
    x0, lo, hi = _pack(free, p0)
    x0 = np.clip(x0, lo, hi)

    def residual(x):
        q = _unpack(free, p0, x)
        return ((model.eval(q, wi, wo) - f) * cos_i).ravel()

    r0 = residual(x0)
    res = least_squares(residual, x0, bounds=(lo, hi), max_nfev=max_nfev, x_scale="jac")
    p = _unpack(free, p0, res.x)
    r = res.fun
    rms = float(np.sqrt(np.mean(r * r)))
    scale = float(np.sqrt(np.mean((f * cos_i) ** 2)))
    return FitResult(brdf.get(model_name).params(**{k: v for k, v in p.items()}), rms, rms / scale if scale > 0 else 0.0,
                     [prm.name for prm in free], len(f), float(np.sqrt(np.mean(r0 * r0))))
