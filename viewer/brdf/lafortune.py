"""Lafortune: a diffuse term plus a sum of generalized cosine lobes.

Lafortune, Foo, Torrance & Greenberg 1997, "Non-linear approximation of reflectance functions"
(SIGGRAPH '97), Sec. 3: f = kd / pi + sum_j max(0, Cx,j wi.x wo.x + Cy,j wi.y wo.y + Cz,j wi.z wo.z)^n_j.
Each lobe is (C o wo) . wi raised to n, i.e. |v|^n cos^n(angle(wi, v)) with v = (Cx wo.x, Cy wo.y, Cz wo.z):
Cx = Cy = -Cz gives a Phong lobe about the mirror direction, Cx = Cy > 0 retro-reflection, Cx = Cy = 0
an off-specular lobe toward the normal, Cx != Cy anisotropy. The specular albedo is folded into C
(by convention): Cx = Cy = -C, Cz = C behaves like the normalized Phong lobe of ks = C^n 2 pi / (n + 2).

Energy: a lobe's directional albedo is at most max|C|^n 2 pi / (n + 1); with max(kd) plus the sum of
these bounds <= 1 the BRDF conserves energy. Other values are accepted (measured fits often are not
normalized); ``energy_conserving`` scales kd and the C's back. Lobe values above e^80 (reachable only far
outside that region, e.g. |C| = 2 with n = 1000) are clamped there so float32 shaders never overflow.
"""

from __future__ import annotations

import numpy as np

from viewer.brdf.sampling import INV_PI, cosine_hemisphere, cosine_hemisphere_pdf, dot, luminance, \
    normalize, phong_alpha, pick_lobe, power_cosine, sample_weight, to_world
from viewer.brdf.lobes import Lobe
from viewer.brdf.spec import ModelSpec, Param

LOG_CLAMP = 80.0  # lobe values are clamped at exp(80) ~ 5.5e34 (float32 max ~ 3.4e38)


TEST_PARAMS = {
    "default": {},
    # a broad retro-reflective lobe plus a Phong-like one (kd small)
    "rough": {"kd": [0.1, 0.1, 0.1], "lobes": [{"cx": 0.9, "cy": 0.9, "cz": 0.9, "n": 2.0},
                                                {"cx": -1.0, "cy": -1.0, "cz": 1.0, "n": 5.0}]},
    # a sharp specular lobe, an anisotropic one and an off-specular one toward the normal
    "sharp": {"kd": [0.05, 0.05, 0.05], "lobes": [{"cx": -1.01, "cy": -1.01, "cz": 1.01, "n": 500.0},
                                                   {"cx": -1.2, "cy": -0.6, "cz": 1.0, "n": 40.0},
                                                   {"cx": 0.0, "cy": 0.0, "cz": 1.05, "n": 20.0}]},
}

def _phong_like_c(ks, n):
    """C of a lobe Cx = Cy = -C, Cz = C that equals a normalized Phong lobe of albedo ks at normal incidence."""
    return float((ks * (n + 2.0) / (2.0 * np.pi)) ** (1.0 / n))


_C0 = round(_phong_like_c(0.4, 30.0), 6)  # 1.024004

LOBE_FIELDS = (
    Param("cx", "float", -_C0, "C_x: weight of wi.x wo.x (negative: toward the mirror direction)",
          lo=-10.0, hi=10.0, ui_lo=-1.5, ui_hi=1.5),
    Param("cy", "float", -_C0, "C_y: weight of wi.y wo.y", lo=-10.0, hi=10.0, ui_lo=-1.5, ui_hi=1.5),
    Param("cz", "float", _C0, "C_z: weight of wi.z wo.z", lo=-10.0, hi=10.0, ui_lo=-1.5, ui_hi=1.5),
    Param("n", "float", 30.0, "lobe exponent (0 = constant over the half-space d > 0)", lo=0.0, hi=10000.0,
          ui_lo=1.0, ui_hi=1000.0, log=True),
)

SPEC = ModelSpec(
    name="lafortune",
    title="Lafortune (generalized cosine lobes)",
    params=(
        Param("kd", "rgb", [0.5, 0.5, 0.5], "diffuse reflectance", lo=0.0, hi=1.0),
        Param("lobes", "lobes", [{"cx": -_C0, "cy": -_C0, "cz": _C0, "n": 30.0}],
              "generalized cosine lobes (ks folded into C)", fields=LOBE_FIELDS, max_items=4),
    ),
    source="Lafortune, Foo, Torrance & Greenberg 1997, Sec. 3 (generalized cosine lobes)",
    doc="f = kd/pi + sum_j max(0, Cx wi.x wo.x + Cy wi.y wo.y + Cz wi.z wo.z)^n. The default lobe "
        "(C = 1.024, n = 30) equals a normalized Phong lobe with ks = 0.4. Energy conserving when "
        "max(kd) + sum_j max|C_j|^n_j 2 pi / (n_j + 1) <= 1 (not enforced: see energy_conserving). "
        "Sampling: cosine for kd, a cos^n lobe about normalize(C o wo) for each lobe, picked in "
        "proportion to luminance(kd) and each lobe's estimated albedo.",
)


def lobe_albedo_bound_log(lobe):
    """log of max|C|^n 2 pi / (n + 1), an upper bound on the lobe's directional albedo."""
    cmax = max(abs(lobe.cx), abs(lobe.cy), abs(lobe.cz))
    if cmax == 0:
        return -np.inf
    return lobe.n * np.log(cmax) + np.log(2.0 * np.pi / (lobe.n + 1.0))


def energy_conserving(p):
    """Scale kd and the lobes so that max(kd) + sum of the lobe albedo bounds <= 1.

    A lobe with n = 0 cannot be scaled below the bound 2 pi by its C, so it is switched off (C = 0)."""
    # in the log domain: a random lobe (|C| = 3, n = 3000) has a bound of e^3000
    logs = [lobe_albedo_bound_log(l) for l in p.lobes]
    kmax = float(np.max(p.kd))
    terms = [np.log(kmax) if kmax > 0 else -np.inf] + logs
    top = max(terms)
    if top == -np.inf:
        return p
    log_total = top + np.log(sum(np.exp(b - top) for b in terms))
    if log_total <= 0.0:
        return p
    t = np.exp(-log_total)
    lobes = []
    for lobe in p.lobes:
        s = np.exp(-log_total / lobe.n) if lobe.n > 0 else 0.0
        lobes.append(lobe.replace(cx=lobe.cx * s, cy=lobe.cy * s, cz=lobe.cz * s))
    return p.replace(kd=p.kd * t, lobes=lobes)


def lobe_axis(lobe, wo):
    """v = (Cx wo.x, Cy wo.y, Cz wo.z): log|v| and the direction of v (the lobe's peak).

    log|v| = log(1 - L) / 2 with L = 1 - |v|^2 = sum_k wo_k^2 (1 - C_k)(1 + C_k) for unit wo: no cancellation
    when |C| ~ 1, where |v|^n with n = 5000 would turn one rounding of |v|^2 into 3e-4 relative
    (the float32 shader uses the same form; here wo is renormalized so the identity holds exactly).
    Where |v|^2 < 1/2 the plain log|v| is used instead (there L ~ 1 would cancel)."""
    w = normalize(wo)
    c = np.array([lobe.cx, lobe.cy, lobe.cz])
    v = w * c
    length = np.sqrt(dot(v, v))
    axis = v / np.where(length > 0, length, 1.0)[:, None]
    L = dot(w * w, (1.0 - c) * (1.0 + c))
    # the L form where |v| is near 1 (L <= 0.5); the plain log|v| where |v| is small (L ~ 1 cancels there)
    near_one = L <= 0.5
    log_len = np.where(near_one, 0.5 * np.log1p(-np.where(near_one, L, 0.0)),
                       np.log(np.where(length > 0, length, 1.0)))
    return np.where(length > 0, log_len, -np.inf), axis


def one_minus_cos(wi, axis):
    """1 - wi . axis = |wi - axis|^2 / 2, exact where wi ~ axis (sharp lobes)."""
    d = wi - axis
    return 0.5 * dot(d, d)


def _lobe_value(lobe, log_len, x):
    """max(0, (C o wo) . wi)^n from log|v| and x = 1 - cos(wi, v) (``lafortune_lobe``)."""
    on = (x < 1.0) & np.isfinite(log_len)
    log_val = lobe.n * (np.where(on, log_len, 0.0) + np.log1p(-np.where(on, x, 0.0)))
    return np.where(on, np.exp(np.minimum(log_val, LOG_CLAMP)), 0.0)


def lafortune_lobe(lobe, wi, wo):
    """Lafortune et al. 1997, Sec. 3: max(0, (C o wo) . wi)^n, evaluated as exp(n (log|v| + log1p(-x)))
    with x = 1 - cos(wi, v) so a sharp lobe keeps its precision (and n = 0 never meets pow(0, 0))."""
    log_len, axis = lobe_axis(lobe, wo)
    return _lobe_value(lobe, log_len, one_minus_cos(wi, axis))


def _axes(p, wo):
    """``lobe_axis`` of every lobe: computed once per call and shared by the lobe choice, the
    sampled directions, f and the pdf."""
    return [lobe_axis(lobe, wo) for lobe in p.lobes]


def _eval(p, wi, wo, axes, xs):
    """f from the lobes' axes and their x = 1 - cos(wi, axis) (``one_minus_cos``)."""
    ok = (wi[:, 2] > 0) & (wo[:, 2] > 0)
    spec = np.zeros(len(wi))
    for lobe, (log_len, _), x in zip(p.lobes, axes, xs):
        spec = spec + _lobe_value(lobe, log_len, x)
    f = p.kd[None, :] * INV_PI + spec[:, None]
    return np.where(ok[:, None], f, 0.0)


def eval(p, wi, wo):
    axes = _axes(p, wo)
    return _eval(p, wi, wo, axes, [one_minus_cos(wi, axis) for _, axis in axes])


def _probabilities(p, wo, axes):
    """(N, 1 + lobes) selection probabilities: luminance(kd) for the cosine part and, per lobe, its
    estimated albedo |v|^n 2 pi / (n + 1) times max(axis.z, 0.1) (the share of a sharp lobe above the horizon)."""
    w = np.empty((len(wo), 1 + len(p.lobes)))
    w[:, 0] = luminance(p.kd)
    for j, (lobe, (log_len, axis)) in enumerate(zip(p.lobes, axes)):
        on = np.isfinite(log_len)
        a = np.exp(np.minimum(lobe.n * np.where(on, log_len, 0.0), LOG_CLAMP)) * 2.0 * np.pi / (lobe.n + 1.0)
        w[:, j + 1] = np.where(on, a * np.clip(axis[:, 2], 0.1, 1.0), 0.0)
    total = w.sum(axis=1, keepdims=True)
    uniform = np.zeros_like(w)
    uniform[:, 0] = 1.0  # nothing reflects: sample the cosine part (f = 0 anyway)
    return np.where(total > 0, w / np.where(total > 0, total, 1.0), uniform)


def _pdf(p, wi, wo, probs, xs):
    val = probs[:, 0] * cosine_hemisphere_pdf(wi)
    for j, (lobe, x) in enumerate(zip(p.lobes, xs)):
        on = x < 1.0
        lobe_pdf = (lobe.n + 1.0) / (2.0 * np.pi) * np.where(
            on, np.exp(lobe.n * np.log1p(-np.where(on, x, 0.0))), 0.0)
        val = val + probs[:, j + 1] * lobe_pdf
    return np.where((wi[:, 2] > 0) & (wo[:, 2] > 0), val, 0.0)


def pdf(p, wi, wo):
    axes = _axes(p, wo)
    return _pdf(p, wi, wo, _probabilities(p, wo, axes), [one_minus_cos(wi, axis) for _, axis in axes])


def sample(p, wo, u):
    axes = _axes(p, wo)
    probs = _probabilities(p, wo, axes)
    k, u0 = pick_lobe(u[:, 0], probs)
    uu = np.empty((len(u), 2))
    uu[:, 0] = u0
    uu[:, 1] = u[:, 1]
    wi = np.empty((len(u), 3))
    diffuse = k == 0
    wi[diffuse] = cosine_hemisphere(uu[diffuse])
    for j, (lobe, (_, axis)) in enumerate(zip(p.lobes, axes)):
        sel = k == j + 1
        wi[sel] = to_world(power_cosine(uu[sel], lobe.n), axis[sel])
    xs = [one_minus_cos(wi, axis) for _, axis in axes]
    # f is clamped at e^80 (LOG_CLAMP) but the pdf is not: far out in a huge lobe (|C| = 10,
    # n = 10^4, u ~ 1e-300) f cos / pdf overflows; sample_weight fails that sample.
    weight, pdf_ = sample_weight(_eval(p, wi, wo, axes, xs), wi, _pdf(p, wi, wo, probs, xs))
    return wi, weight, pdf_


def ibl_split(p):
    """Image-based lighting proxy: the lobes alone (kd = 0), and the GGX alpha of the sharpest
    lobe's exponent (``phong_alpha``)."""
    n = max(float(l["n"]) for l in p.lobes)
    return p.replace(kd=np.zeros(3)), phong_alpha(n)


def lobes(p):
    """The diffuse kd lobe and the generalized cosine lobes."""
    return Lobe.REFLECTION | Lobe.DIFFUSE | Lobe.GLOSSY
