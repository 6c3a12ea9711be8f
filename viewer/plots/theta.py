"""BRDF Explorer's cartesian slices (Burley's BRDF Explorer, its "Theta H", "Theta D" and
"Theta V" plots) and the microfacet term view: f along one angle with the others held, for any
model through its ``eval`` (built-in, ``.brdf`` file, measured).

* ``theta_h_curve``: f against theta_h (signed, -90..90 degrees; negative: the half vector
  tilted toward -x) at a fixed theta_d, with phi_d = 90 degrees (the difference vector across the
  plane of the normal and h) and phi_h = 0 (h in the x-z plane): the specular peak's shape.
* ``theta_d_curve``: f against theta_d (0..90) at a fixed theta_h, same phi_d and phi_h: the
  Fresnel rise toward grazing at a fixed microfacet.
* ``theta_v_curve``: f against the view angle theta_v (signed, -90..90; > 0: the mirror side)
  in the plane at azimuth phi_v (default: the light's azimuth, BRDF Explorer's "Lock") for the
  light fixed at (theta_i, phi_i).
* ``term_curves``: the factors D, F, G and 1 / (4 cos_i cos_o) of a microfacet lobe (the model's
  ``terms`` hook) and their product, against the light's signed angle theta_l in the plane of
  incidence at the view direction (theta_v, phi) (> 0: the mirror side), with f beside them.

The directions of the theta_h and theta_d plots are the Rusinkiewicz pair
(``viewer.brdf.merl.from_half_diff``): wi = the difference vector d rotated by theta_h about y,
wo = wi mirrored about h. BRDF Explorer's cosine option multiplies f by N.L = cos theta_i of the
light (``cos``): on the theta_v plot that is one constant, the light being fixed.
"""

from __future__ import annotations

import math

import numpy as np

from viewer import ViewerError
from viewer.brdf import merl
from viewer.plots.data import direction, plane_directions
from viewer.plots.kinds import as_params, model_of

PHI_D = 90.0  # degrees: the theta_h / theta_d plots' phi_d (BRDF Explorer's)
# the signed angles stop short of 90 degrees, where cos_i cos_o = 0 and f = F D G / (4 cos_i cos_o)
# is 0 / 0 (BRDF Explorer's grid, at the centres of its segments, never reaches 90 either)
EDGE = 89.5
TERM_KEYS = ("D", "F", "G", "1/(4 cos cos)")


def _angle(value, name: str, lo: float, hi: float) -> float:
    v = float(value)
    if not (math.isfinite(v) and lo <= v <= hi):
        raise ViewerError(f"--{name}: {v:g} is out of range; allowed: degrees in [{lo:g}, {hi:g}]")
    return v


def _f(p, wi, wo) -> np.ndarray:
    """f for a plot (a stochastic eval averaged, as ``viewer.plots.data``'s lobes)."""
    model = model_of(p)
    fn = model.hook("eval_mean")
    wi, wo = np.ascontiguousarray(wi, dtype=np.float64), np.ascontiguousarray(wo, dtype=np.float64)
    f = model.eval(p, wi, wo) if fn is None else fn(p, wi, wo)
    return np.asarray(f, dtype=np.float64)


def _result(x, wi, wo, f, cos: bool, **info) -> dict:
    cos_i = np.maximum(wi[:, 2], 0.0)
    y = f * cos_i[:, None] if cos else f
    return {"x": x, "wi": wi, "wo": wo, "f": f, "y": y, "cos_i": cos_i, "cos": bool(cos), **info}


CENTRAL = 80.0  # degrees: the part of a slice that sets its axis (see ``axis_top``)


def axis_top(x, ys) -> tuple[float, float | None]:
    """The top of a slice's y axis for curves ``ys`` (arrays over ``x``): the largest value
    within |x| <= CENTRAL, plus a quarter, when f beyond it runs off (f of a rough metal grows
    as 1 / cos toward grazing, to hundreds at theta_d = 89.5, and would flatten every other
    curve); else the largest value. Returns (top, the largest value when it is above top, else
    None)."""
    x = np.abs(np.asarray(x, dtype=np.float64))
    peak = max([float(np.max(y)) for y in ys] + [0.0])
    inner = max([float(np.max(np.asarray(y)[x <= CENTRAL])) for y in ys] + [0.0])
    if inner > 0 and peak > 1.25 * inner:
        return 1.25 * inner, peak
    return max(peak, 1e-6), None


def half_angle_grid(n: int = 361) -> np.ndarray:
    """Signed theta_h (degrees) from -EDGE to EDGE, squared spacing (denser near theta_h = 0, where
    the specular peak is, as BRDF Explorer samples it)."""
    s = np.linspace(-1.0, 1.0, int(n))
    return np.sign(s) * s * s * EDGE


def theta_h_curve(p, theta_d: float = 0.0, n: int = 361, cos: bool = False) -> dict:
    """f against signed theta_h at theta_d (degrees), phi_d = 90, phi_h = 0. Returns x (theta_h
    in degrees), wi, wo, f (m, 3), y (f or f cos theta_i), cos_i, theta_d."""
    p = as_params(p)
    td = _angle(theta_d, "theta-d", 0.0, 89.9)
    x = half_angle_grid(n)
    wi, wo = merl.from_half_diff(np.radians(x), math.radians(td), math.radians(PHI_D))
    return _result(x, wi, wo, _f(p, wi, wo), cos, theta_d=td, phi_d=PHI_D)


def theta_d_curve(p, theta_h: float = 0.0, n: int = 181, cos: bool = False) -> dict:
    """f against theta_d (0..EDGE degrees) at theta_h (degrees), phi_d = 90, phi_h = 0; 0 where a
    direction passes below the horizon."""
    p = as_params(p)
    th = _angle(theta_h, "theta-h", 0.0, 89.9)
    x = np.linspace(0.0, EDGE, int(n))
    wi, wo = merl.from_half_diff(math.radians(th), np.radians(x), math.radians(PHI_D))
    return _result(x, wi, wo, _f(p, wi, wo), cos, theta_h=th, phi_d=PHI_D)


def theta_v_curve(p, theta_i: float = 45.0, phi_i: float = 0.0, phi_v: float | None = None, n: int = 361,
                  cos: bool = False) -> dict:
    """f against the signed view angle theta_v (degrees; > 0 the mirror side of the plane at
    azimuth phi_v, default phi_i) for the light at (theta_i, phi_i)."""
    p = as_params(p)
    ti = _angle(theta_i, "theta-i", 0.0, 89.9)
    pi_ = _angle(phi_i, "phi", -360.0, 360.0)
    pv = pi_ if phi_v is None else _angle(phi_v, "phi-v", -360.0, 360.0)
    x = np.linspace(-EDGE, EDGE, int(n))
    wo = plane_directions(x, pv)
    wi = np.broadcast_to(direction(ti, pi_), wo.shape).copy()
    return _result(x, wi, wo, _f(p, wi, wo), cos, theta_i=ti, phi_i=pi_, phi_v=pv)


def term_curves(p, theta_v: float = 45.0, phi: float = 0.0, n: int = 361) -> dict:
    """The term view: D, F (RGB), G and 1 / (4 cos_i cos_o) of the model's ``terms`` hook and
    their product, with f, against the light's signed angle theta_l (degrees, -90..90; > 0: the
    mirror side) in the plane of incidence at azimuth ``phi``, the view fixed at theta_v.
    Returns x, wi, wo, the terms, product (m, 3), f (m, 3) and other (m, 3) where the model says
    what f adds to the product."""
    p = as_params(p)
    tv = _angle(theta_v, "theta-i", 0.0, 89.9)
    ph = _angle(phi, "phi", -360.0, 360.0)
    x = np.linspace(-EDGE, EDGE, int(n))
    wi = plane_directions(x, ph)
    wo = np.broadcast_to(direction(tv, ph), wi.shape).copy()
    t = model_of(p).terms(p, wi, wo)
    if t is None:
        raise ViewerError(f"terms plot: model {p.model!r} has no D, F, G decomposition (a microfacet model or a "
                          ".brdf file defining float D, F and G(vec3 L, vec3 V, vec3 N, vec3 X, vec3 Y))")
    D, F, G, inv = (np.asarray(t[k], dtype=np.float64) for k in TERM_KEYS)
    F = np.broadcast_to(F.reshape(len(x), -1), (len(x), 3))
    product = D[:, None] * F * G[:, None] * inv[:, None]
    out = {"x": x, "wi": wi, "wo": wo, "D": D, "F": F, "G": G, "1/(4 cos cos)": inv, "product": product,
           "f": _f(p, wi, wo), "theta_v": tv, "phi": ph}
    if "other" in t:
        out["other"] = np.asarray(t["other"], dtype=np.float64)
    return out
