"""Measured BRDFs: an isotropic MERL table (Matusik et al. 2003, ``.binary``) looked up with
trilinear interpolation on the index grid, or an anisotropic MIT table (Ngan et al. 2005,
``.dat``, as BRDF Explorer opens them) looked up with quadrilinear interpolation, both importance
sampled by a cosine + tabulated half-vector mixture; the formats, the mappings and the sampler
are described in ``viewer.brdf.merl`` and ``viewer.brdf.mit_aniso``. The file's suffix tells the
format (``is_aniso``); the GLSL twin compiles the anisotropic lookup with ``MEASURED_ANISO``.

``file = ""`` (the default) is a built-in example table, tabulated at first use from a closed
form (``example_brdf``: GGX alpha 0.25, Schlick F0 (0.9, 0.7, 0.45), Smith G over a Lambert base
(0.12, 0.1, 0.08)), so the model works without a download; real measurements come from the MERL
BRDF database (see README).
"""

from __future__ import annotations

import numpy as np

from viewer import ViewerError
from viewer.brdf import merl, mit_aniso
from viewer.brdf.sampling import cosine_hemisphere, cosine_hemisphere_pdf, normalize, sample_weight
from viewer.brdf.spec import ModelSpec, Param

EXAMPLE = dict(kd=(0.12, 0.1, 0.08), alpha=0.25, f0=(0.9, 0.7, 0.45))
_EXAMPLE: list = []


def example_brdf(wi, wo, kd=EXAMPLE["kd"], alpha=EXAMPLE["alpha"], f0=EXAMPLE["f0"]):
    """The built-in example's closed form: kd / pi + F D G / (4 cos_i cos_o) with GGX D
    (Walter et al. 2007), Schlick's F (1994) and the height-correlated Smith G (Heitz 2014)."""
    h = normalize(wi + wo)
    ci, co, ch = wi[:, 2], wo[:, 2], h[:, 2]
    cd = np.sum(wi * h, axis=1)
    a2 = alpha * alpha
    d = a2 / (np.pi * (ch * ch * (a2 - 1.0) + 1.0) ** 2)

    def lam(c):
        c = np.clip(c, 1e-9, 1.0)
        return 0.5 * (np.sqrt(1.0 + a2 * (1.0 - c * c) / (c * c)) - 1.0)

    g = 1.0 / (1.0 + lam(ci) + lam(co))
    f = np.asarray(f0)[None, :] + (1.0 - np.asarray(f0)[None, :]) * ((1.0 - np.clip(cd, 0, 1)) ** 5)[:, None]
    spec = f * (d * g / (4.0 * np.maximum(ci * co, 1e-12)))[:, None]
    return np.asarray(kd)[None, :] / np.pi + spec


def example() -> "merl.Measured":
    """The built-in example table (``file = ""``)."""
    if not _EXAMPLE:
        _EXAMPLE.append(merl.Measured(merl.tabulate(example_brdf), "<built-in example>"))
    return _EXAMPLE[0]


def is_aniso(p) -> bool:
    """Whether a measured material's file is an anisotropic MIT table (``.dat``)."""
    return bool(p.file) and mit_aniso.is_mit_file(p.file)


def load_file(path):
    """The loaded table of a measured file by its format: MIT ``.dat`` or MERL (``.binary``)."""
    return mit_aniso.load(path) if mit_aniso.is_mit_file(path) else merl.load(path)


def data(p) -> "merl.HalfVectorSampler":
    """The material's loaded table (``merl.Measured`` or ``mit_aniso.AnisoMeasured``)."""
    return load_file(p.file) if p.file else example()


def _check_file(value, where):
    if value:
        try:
            load_file(value)
        except ViewerError as e:
            raise ViewerError(f"{where}: {e}") from None


# The GLSL twin agrees to 1e-3 relative, not 1e-4: its continuous table coordinates carry the
# float32 rounding of the angles (about 90 x 6e-8 = 5e-6 of a cell), and trilinear weights multiply
# that by the difference between neighbouring entries, which near grazing theta_d (f ~ 1 / cos)
# and at sharp peaks is up to ~100 times the value (measured: 6e-4 at most over 4000 pairs with
# entries at their bins' lower edges; 1.04e-3 at a pair 1.4 / 3 deg above the horizon with entries
# at the centres, which put the last theta_h entry at 89.0 deg, where f ~ 1 / cos is steepest).
GLSL_RTOL = 2e-3

SPEC = ModelSpec(
    name="measured",
    title="Measured (MERL, MIT)",
    params=(
        Param("file", "path", "", "a MERL .binary (isotropic) or MIT .dat (anisotropic) BRDF file "
              "(\"\": the built-in example)", check=_check_file),
        Param("scale", "float", 1.0, "factor on the measured values (at most 1: dims a measurement)", lo=0.0, hi=1.0),
    ),
    source="Matusik, Pfister, Brand, McMillan 2003, A Data-Driven Reflectance Model (MERL BRDF database); "
           "Rusinkiewicz 1998 half/difference coordinates; Ngan, Durand, Matusik 2005, Experimental "
           "Analysis of BRDF Models (MIT anisotropic data)",
)


def is_measured(p):
    """A measured table: always."""
    return True


def eval(p, wi, wo):
    ok = (wi[:, 2] > 0) & (wo[:, 2] > 0)
    f = data(p).value(wi, wo) * p.scale
    return np.where(ok[:, None], f, 0.0)


def _h_pdf(d, h):
    """The tabulated density of half vectors h (N, 3) per solid angle."""
    th = np.arctan2(np.hypot(h[:, 0], h[:, 1]), h[:, 2])
    i = np.clip(np.floor(np.sqrt(np.clip(th, 0.0, merl.HALF_PI) / merl.HALF_PI) * merl.N_TH), 0, merl.N_TH - 1)
    return np.where(h[:, 2] > 0, d.bin_pdf[i.astype(int)], 0.0)


def pdf(p, wi, wo):
    d = data(p)
    ok = (wi[:, 2] > 0) & (wo[:, 2] > 0)
    h = normalize(wi + wo)
    cos_oh = np.sum(wo * h, axis=1)
    ph = np.where(cos_oh > 0, _h_pdf(d, h) / (4.0 * np.where(cos_oh > 0, cos_oh, 1.0)), 0.0)
    mix = d.w_cos * cosine_hemisphere_pdf(wi) + (1.0 - d.w_cos) * ph
    return np.where(ok, mix, 0.0)


def sample_half(d, u):
    """Half vectors (N, 3) from the tabulated density: a theta_h bin by its CDF, then a direction
    uniform in solid angle within the bin (1 - cos theta linear in the rescaled uniform)."""
    u0 = np.clip(u[:, 0], 0.0, np.nextafter(1.0, 0.0))
    i = np.minimum(np.searchsorted(d.cdf, u0, side="right"), merl.N_TH - 1)
    lo = np.where(i > 0, d.cdf[np.maximum(i - 1, 0)], 0.0)
    width = d.cdf[i] - lo
    t = np.clip((u0 - lo) / np.where(width > 0, width, 1.0), 0.0, 1.0)
    a = 2.0 * np.sin(0.5 * d.edges[i]) ** 2  # 1 - cos at the bin's edges, without cancellation
    b = 2.0 * np.sin(0.5 * d.edges[i + 1]) ** 2
    x = a + t * (b - a)
    cos_t = 1.0 - x
    sin_t = np.sqrt(np.maximum(x * (2.0 - x), 0.0))
    phi = 2.0 * np.pi * u[:, 1]
    return np.stack([sin_t * np.cos(phi), sin_t * np.sin(phi), cos_t], axis=1)


def sample(p, wo, u):
    d = data(p)
    w = d.w_cos
    use_cos = u[:, 0] < w
    uc = np.where(use_cos, u[:, 0] / w, (u[:, 0] - w) / (1.0 - w))
    uu = np.stack([np.clip(uc, 0.0, np.nextafter(1.0, 0.0)), u[:, 1]], axis=1)
    wi_c = cosine_hemisphere(uu)
    h = sample_half(d, uu)
    wi_h = 2.0 * np.sum(wo * h, axis=1, keepdims=True) * h - wo
    wi = np.where(use_cos[:, None], wi_c, wi_h)
    pdf_ = pdf(p, wi, wo)
    f = eval(p, wi, wo)
    weight, pdf_ = sample_weight(f, wi, pdf_)
    return wi, weight, pdf_


def ibl_split(p):
    """Image-based lighting (split sum): the table less its diffuse floor, as a lobe of width
    alpha (``merl.Measured.split_sum_fit``); the third value is the diffuse albedo that the
    renderer subtracts from the table's albedo to leave the specular part."""
    kd, alpha = data(p).split_sum_fit()
    return p, alpha, kd * p.scale
