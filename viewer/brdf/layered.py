"""Layered BRDF: a rough dielectric coating over any base material (Weidlich & Wilkie 2007,
'Arbitrarily layered micro-facet surfaces', GRAPHITE 2007; lecture: 'The layered model').

  f(wi, wo) = f_coat(wi, wo)
            + T(cos_i) T(cos_o) a(wi', wo') f_base(wi', wo') / eta^2

* f_coat: GGX microfacet reflection of the coating's surface, F(wi.h) with exact dielectric
  Fresnel, height-correlated Smith G2 (Walter et al. 2007 eq. 20, Heitz 2014 eq. 99); this is
  Weidlich-Wilkie's top-layer term.
* wi', wo': wi and wo refracted through the (mean) coating surface into the layer, pointing up
  toward the interface: w' = (w.x / eta, w.y / eta, cos_t) (Weidlich-Wilkie sec. 4, 'the
  second layer is evaluated with the refracted directions').
* T = 1 - E(cos): the transmittance into and out of the layer at the macro-surface angles, E the
  coat's own directional albedo (tabulated per ior and alpha, see ``coat_albedo_table``): what the
  coat does not reflect enters. For a smooth coat E = F and T is Weidlich-Wilkie's T12 = T21 =
  1 - F; for a rough one 1 - F(cos) would drop the light that the rough surface neither reflects
  nor lets through at the macro angle (a white furnace of 0.3 at grazing angles for alpha = 1).
* a = exp(-sigma_a * thickness * (1/cos_ti' + 1/cos_to')): Bouguer absorption along the two
  refracted paths through the layer (Weidlich-Wilkie's absorption term; lecture 'Transmitted
  radiance').
* 1 / eta^2: the radiance leaving the layer is the radiance inside divided by eta^2 (L / n^2 is
  invariant across a refraction, the lecture's 'Transmitted radiance'), while the irradiance the
  base receives is the transmitted flux T_i E, whatever the solid angle it arrives in; so
  f = T_i T_o f_base / eta^2. (It is not there to keep the albedo below 1: with it a white
  Lambert base under a smooth clear coat returns R_o + T_o (1 - r_e) / eta^2 after one bounce,
  about 0.43 at ior 1.5; the rest is light the coat reflects back down.)
* Interreflections between coat and base: light leaving a Lambertian base of albedo rho is
  diffuse inside the layer; at cosine mu the coat reflects the fraction F_int(mu) back down (1
  beyond the critical angle), after absorption exp(-2 tau / mu) (tau = sigma_a * thickness) on
  the way up and down, and the base reflects it again, diffusely. So each bounce multiplies the
  base's radiance by rho K, K = integral_0^1 F_int(mu) exp(-2 tau / mu) 2 mu dmu (the coat's
  internal diffuse reflectance; 1 - (1 - r_e) / eta^2 without absorption, r_e the external one),
  and the geometric series sums to the factor 1 / (1 - rho K) on the base term. For a smooth coat
  and a white, non-absorbing layer the albedo is then exactly R_o + T_o = 1. K is a 16 + 16 point
  Gauss-Legendre quadrature (the total-internal-reflection cone, and the transmitting cone in the
  outside cosine, where F_int(mu) = F_ext(mu') is smooth).
  Every other non-delta base (Oren-Nayar, microfacet, ...) gets the same series with its own
  albedos (``base_bounce_tables``): the first bounce is f_base itself; of the light it sends up
  from mu, the coat returns A_b(mu) = integral f_b(mu, v) cos v R_int(v) dv, taken as diffuse, which
  the base reflects toward mu_o with its directional albedo E_b(mu_o) and returns again with
  rho_K = integral A_b 2 mu dmu; so the later orders add (A_b(mu_i) E_b(mu_o) + E_b(mu_i) A_b(mu_o))
  / (2 pi (1 - rho_K)) (symmetric: reciprocal). For Lambert this is exactly the series above. Both
  twins interpolate the same tables, computed once per material. Against the stochastic layered
  random walk (viewer/brdf/layered_walk.py, the reference's ``reference = "random_walk"``;
  benchmarks/layered_walk.py; tests/test_layered_walk.py), directional albedo at cos 1 / 0.5 /
  0.15: a white Oren-Nayar base (sigma 30 deg) under an alpha 0.05 coat 0.786 / 0.804 / 0.865
  against 0.812 / 0.818 / 0.867 (0.381 / 0.416 / 0.592 with one bounce), a gold GGX base (alpha
  0.3, red) 0.755 / 0.661 / 0.742 against 0.716 / 0.652 / 0.741 (one bounce 0.563 / 0.449 /
  0.587). What remains is the diffuse assumption: a glossy base's returned light stays near its
  mirror direction, an Oren-Nayar base's is not quite Lambertian. A delta base (mirror) keeps one
  bounce (it is sampled as a discrete lobe; its interreflections are lost).
  For a rough coat F_ext is replaced by E in K (an approximation: the internal reflection of a
  rough interface is taken as the outside albedo at the matching angle), which keeps the white
  furnace at 1 within the albedo table's error.
* A thin film on the coating (``coating.thin_film = {ior, thickness_nm, thickness_top_nm}``,
  viewer/brdf/thin_film.py: soap on a varnish, an oil film on a lacquer): the coat's Fresnel
  F(wi.h) becomes the film's RGB reflectance over the coat's ior; its albedo E + R_film - F; and
  the internal reflectance K takes the same coloured E (a lossless film stack reflects the same
  fraction from either side at angles related by Snell's law, so F_int(mu) = R_film(mu')).
  ``thickness_nm = 0`` is no film: the plain model, bit for bit. R_film is not summed over
  wavelengths per shading point: ``film_table`` holds its RGB at 32 cosines (linear in sqrt(cos)),
  computed once per material and packed after the coat's albedo table (``derived``); both twins
  interpolate it (within 1.8e-3 of the exact Airy sum for a 400 nm water film on a 1.5 coat, 0.019
  at worst), so the GLSL, whose coat Fresnel is called in the lobe, in E, 16 times in K and in
  the sampler, compiles as fast as without a film. The spectral reference evaluates the film
  exactly at its wavelengths. A film over height (``thickness_top_nm``): the rasterizer takes
  the bottom thickness (one table per material); the CPU reference follows the height per hit.
Units: thickness in micrometres, sigma_a in 1/micrometre (only the optical depth
sigma_a * thickness matters).

Reciprocal: yes. T(cos_i) T(cos_o), the absorption, the 1 / eta^2 and f_coat are symmetric in
(wi, wo), and f_base is evaluated at the symmetric pair (wi', wo'); so f is reciprocal when the
base is.

Sampling: the coat lobe (GGX visible normals) with probability P_c = F(cos_o), else the base
(its own ``sample`` with wo', the result refracted out; pdf converted by the solid-angle
Jacobian cos_i / (eta^2 cos_i')). pdf is the matching mixture; weight = f cos / pdf. A delta
base (mirror) is a discrete lobe: its sample has pdf (1 - P_c) pdf_base and its throughput.
"""

from __future__ import annotations

import functools

import numpy as np

from viewer.brdf import spectral_fresnel, thin_film
from viewer.brdf.fresnel import fresnel_dielectric
from viewer.brdf.microfacet_dist import Distribution
from viewer.brdf.sampling import dot, normalize, ratio_capped, reflect, split_uniform
from viewer.brdf import lobes as lobe_flags
from viewer.brdf.lobes import Lobe
from viewer.brdf.spec import ModelSpec, Param

SPEC = ModelSpec(
    name="layered",
    title="Layered (Weidlich-Wilkie coating over a base)",
    params=(
        Param("coating", "table", {}, "the dielectric coating", fields=(
            Param("ior", "float", 1.5, "index of refraction of the coating", lo=1.0, hi=3.0),
            Param("alpha", "float", 0.1, "GGX roughness of the coating surface", lo=0.001, hi=1.0,
                  log=True),
            Param("thickness", "float", 10.0, "coating thickness", unit="um", lo=0.0, hi=1000.0),
            Param("sigma_a", "rgb", [0.0, 0.0, 0.0], "absorption coefficient in the coating",
                  unit="1/um", lo=0.0, hi=10.0),
            spectral_fresnel.param(dielectric_only=True),
            thin_film.param(),
        )),
        Param("base", "material", {"model": "lambert", "albedo": [0.5, 0.1, 0.1]},
              "the material under the coating (any non-layered model)"),
        Param("reference", "choice", "closed_form",
              "how the CPU reference evaluates it: the twins' closed form, or the stochastic layered "
              "random walk (Guo et al. 2018; viewer/brdf/layered_walk.py), the truth for coat-base "
              "interreflections; the rasterizer always draws the closed form",
              choices=("closed_form", "random_walk")),
    ),
    source="Weidlich & Wilkie 2007 (layered micro-facet surfaces); Walter et al. 2007 eq. 20; "
           "Heitz 2014 eq. 99; Bouguer's law; coat-base interreflections as a geometric series",
    derived=lambda p: derived(p),
    # COAT_TABLE, 3 FILM_TABLE, 3 BASE_TABLE E_b, 3 BASE_TABLE A_b, rho_K (see ``derived``)
    derived_size=24 + 3 * 32 + 2 * 3 * 4 + 3,
    derived_copy=24 + 1,           # the coat table and the film flag (the film table's first entry);
                                   # the rest is read from the material block (p.derived_at)
)


def _base(p):
    from viewer import brdf

    return brdf.get(p.base.model)


def refract_in(w, eta):
    """w refracted into the layer through the mean surface, pointing up (z > 0): Snell's law
    in vector form for the normal +z. Incident from outside, so no total internal reflection."""
    out = np.empty((len(w), 3))
    xy = np.divide(w[:, :2], eta, out=out[:, :2])
    out[:, 2] = np.sqrt(np.maximum(0.0, 1.0 - dot(xy, xy)))
    return out


def refract_out(w, eta):
    """A direction inside the layer (z > 0) refracted out; ok = False under total internal
    reflection."""
    out = np.empty((len(w), 3))
    xy = np.multiply(w[:, :2], eta, out=out[:, :2])
    s2 = dot(xy, xy)
    ok = s2 < 1.0
    out[:, 2] = np.sqrt(np.maximum(0.0, 1.0 - s2))
    return out, ok


def _dist(p):
    return Distribution("ggx", p.coating.alpha, p.coating.alpha)


FILM_TABLE = 32  # the coat film's RGB R at cos = (k / 31)^2, k = 0..31: linear in sqrt(cos)
BASE_TABLE = 4  # the base's E_b and A_b where the outside cosine is (k / 3)^2: linear in its sqrt
BASE_TABLES_AT = 24 + 3 * FILM_TABLE  # their offset in the derived block (after the film table)


@functools.lru_cache(maxsize=1024)
def _film_table_cached(film_ior: float, thickness_nm: float, coat_ior: float) -> np.ndarray:
    from viewer.brdf.spec import Params

    film = Params("", {"thin_film": Params("", {"ior": film_ior, "thickness_nm": thickness_nm})})
    x = (np.arange(FILM_TABLE) / (FILM_TABLE - 1)) ** 2
    t = thin_film.reflectance_rgb(film, x, coat_ior)
    t.setflags(write=False)
    return t


def film_table(p) -> np.ndarray:
    """(FILM_TABLE, 3) the coat film's RGB reflectance (Airy summation over 32 wavelengths,
    viewer/brdf/thin_film.py) at cos = (k / 31)^2 over the coat's ior, at the film's (bottom)
    thickness: computed once per material, so neither twin sums wavelengths per shading point.
    Linear interpolation in sqrt(cos) (where R rises steeply toward grazing) is within 1.8e-3 of
    the exact sum for a 400 nm water film on a 1.5 coat, 0.019 at worst over film ior 1.2-3,
    50-1000 nm, coat ior 1-3 (tests/test_layered_film.py)."""
    tf = p.coating.thin_film
    return _film_table_cached(float(tf.ior), float(tf.thickness_nm), float(p.coating.ior))


def film_table_rgb(p, cos) -> np.ndarray:
    """(N, 3) the coat film's RGB reflectance at cos, interpolated in ``film_table`` (the GLSL
    twin does the same)."""
    t = film_table(p)
    x = np.sqrt(np.clip(np.asarray(cos, dtype=np.float64).reshape(-1), 0.0, 1.0)) * (FILM_TABLE - 1)
    i = np.minimum(np.floor(x).astype(int), FILM_TABLE - 2)
    f = (x - i)[:, None]
    return (1.0 - f) * np.take(t, i, axis=0) + f * np.take(t, i + 1, axis=0)  # t[i], t[i + 1]


def derived(p) -> np.ndarray:
    """The layered material's derived block (147 floats: with a spectral microfacet base, the
    largest, the material fills the 256 floats of the rasterizer's block exactly): the coat's
    albedo table (COAT_TABLE); with a coat film its reflectance table (FILM_TABLE x RGB), zeros
    without one (its first entry, R at grazing = 1, is the film flag both twins test); then
    the base's interreflection tables (``base_bounce_tables``): E_b and A_b (BASE_TABLE x RGB
    each) and rho_K (RGB)."""
    out = np.zeros(COAT_TABLE + 3 * FILM_TABLE + 2 * 3 * BASE_TABLE + 3)
    out[:COAT_TABLE] = coat_albedo_table(p.coating.ior, p.coating.alpha)
    if thin_film.at_point(p.coating):
        t = film_table(p).reshape(-1)
        assert t[0] > 0.5  # R = 1 at grazing incidence: the flag
        out[COAT_TABLE:COAT_TABLE + 3 * FILM_TABLE] = t
    E, A, rk = base_bounce_tables(p)
    o = BASE_TABLES_AT
    out[o:o + 3 * BASE_TABLE] = E.reshape(-1)
    out[o + 3 * BASE_TABLE:o + 6 * BASE_TABLE] = A.reshape(-1)
    out[o + 6 * BASE_TABLE:] = rk
    return out


def coat_fresnel(p, cos) -> np.ndarray:
    """(N, 3) reflectance of the coat's surface at cos (from outside): the dielectric F, or with a
    thin film on the coating the film's RGB reflectance over the coat's ior (``film_table_rgb``;
    in the spectral reference, whose film carries its wavelengths, the exact Airy sum there)."""
    c = np.clip(np.asarray(cos, dtype=np.float64).reshape(-1), 0.0, 1.0)
    if thin_film.at_point(p.coating):
        if p.coating.thin_film.get("lambda_nm") is not None:
            return thin_film.reflectance_rgb(p.coating, c, p.coating.ior)
        return film_table_rgb(p, c)
    return np.repeat(fresnel_dielectric(c, p.coating.ior)[:, None], 3, axis=1)


def eval_coat(p, wi, wo):
    """(N, 3) the coat's GGX reflection (RGB with a thin film)."""
    ci, co = wi[:, 2], wo[:, 2]
    ok = (ci > 0) & (co > 0)
    h = normalize(wi + wo)
    d = _dist(p)
    # Walter et al. 2007 eq. 20 with the dielectric F (Fresnel at the microfacet)
    F = coat_fresnel(p, dot(wi, h))
    val = F * ratio_capped(d.G2(wi, wo, h) * d.D(h), 4.0 * np.where(ok, ci * co, 1.0))[:, None]
    return np.where(ok[:, None], val, 0.0)


COAT_TABLE = 24  # E_coat at cos = k / 23, k = 0..23 (cos 0 evaluated at 1e-3)


@functools.lru_cache(maxsize=256)
def _coat_albedo_cached(ior: float, alpha: float) -> tuple:
    from viewer.brdf.albedo import stratified_u

    mu = np.maximum(np.arange(COAT_TABLE) / (COAT_TABLE - 1), 1e-3)
    u = stratified_u(32, seed=7)
    wo = np.stack([np.sqrt(1.0 - mu * mu), np.zeros_like(mu), mu], axis=-1)
    wo_r = np.repeat(wo, len(u), axis=0)
    u_r = np.tile(u, (mu.size, 1))
    d = Distribution("ggx", alpha, alpha)
    m = d.sample_m(wo_r, u_r)
    wi = reflect(wo_r, m)
    om = np.clip(dot(wo_r, m), 0.0, 1.0)
    # VNDF sampling of the coat lobe: weight f cos / pdf = F(o.m) G2 / G1(wo) (Heitz 2018 sec. 2)
    g1 = d.G1(wo_r, m)
    ok = (wi[:, 2] > 0) & (g1 > 0)
    w = np.where(ok, fresnel_dielectric(om, ior) * d.G2(wi, wo_r, m) / np.where(ok, g1, 1.0), 0.0)
    return tuple(np.clip(w.reshape(mu.size, len(u)).mean(axis=1), 0.0, 1.0))


def coat_albedo_table(ior, alpha) -> np.ndarray:
    """(24,) directional albedo E(mu) of the coat's own reflection (GGX, dielectric F) at
    cos = k / 23: estimated once per (ior, alpha) with 1,024 multi-jittered visible-normal samples
    (error ~1e-3); the GLSL twin gets the same numbers through the material block."""
    return np.array(_coat_albedo_cached(float(ior), float(alpha)))


def coat_albedo(p, cos):
    """E(cos) interpolated linearly in the table (the twin does the same)."""
    t = coat_albedo_table(p.coating.ior, p.coating.alpha)
    x = np.clip(np.asarray(cos, dtype=np.float64), 0.0, 1.0) * (COAT_TABLE - 1)
    i = np.minimum(np.floor(x).astype(int), COAT_TABLE - 2)
    f = x - i
    return (1.0 - f) * t[i] + f * t[i + 1]


def coat_albedo_rgb(p, cos) -> np.ndarray:
    """(N, 3) the coat's albedo E(cos) per channel. With a thin film on the coating: the table's E
    plus the film's change of the reflectance at the macro angle, E + R_film - F (exact for a
    smooth coat, where E = F; for a rough one an approximation), clipped to [0, 1]."""
    c = np.clip(np.asarray(cos, dtype=np.float64).reshape(-1), 0.0, 1.0)
    E = np.repeat(coat_albedo(p, c)[:, None], 3, axis=1)
    if thin_film.at_point(p.coating):
        E = np.clip(E + coat_fresnel(p, c) - fresnel_dielectric(c, p.coating.ior)[:, None], 0.0, 1.0)
    return E


def _through(p, wi, wo):
    """(wi', wo', factor (N,3)) of the base term: T_i T_o a / eta^2, T = 1 - E(cos) (the coat's
    albedo: what the rough coat does not reflect enters the layer)."""
    eta = p.coating.ior
    wi_t = refract_in(wi, eta)
    wo_t = refract_in(wo, eta)
    Ti = 1.0 - coat_albedo_rgb(p, wi[:, 2])
    To = 1.0 - coat_albedo_rgb(p, wo[:, 2])
    # Bouguer absorption along both refracted paths (cos_t >= sqrt(1 - 1/eta^2) > 0 unless eta = 1
    # at grazing; guarded)
    path = 1.0 / np.maximum(wi_t[:, 2], 1e-12) + 1.0 / np.maximum(wo_t[:, 2], 1e-12)
    a = np.exp(-p.coating.sigma_a[None, :] * p.coating.thickness * path[:, None])
    return wi_t, wo_t, (Ti * To / (eta * eta)) * a


# 16-point Gauss-Legendre nodes and weights on [0, 1] (numpy.polynomial.legendre.leggauss(16),
# mapped); the GLSL twin holds the same numbers
GL16_X, GL16_W = np.polynomial.legendre.leggauss(16)
GL16_X, GL16_W = 0.5 * (GL16_X + 1.0), 0.5 * GL16_W


def internal_reflectance(p):
    """K = integral_0^1 F_int(mu) exp(-2 tau / mu) 2 mu dmu: the fraction of diffuse light inside
    the layer (cosine mu at the base) that the coat returns to the base, with absorption over the
    path up and down; tau (3,) = sigma_a * thickness. Split at the critical cosine
    mu_c = sqrt(1 - 1 / eta^2): below it F_int = 1; above it, in the outside cosine mu'
    (mu^2 = 1 - (1 - mu'^2) / eta^2, 2 mu dmu = 2 mu' dmu' / eta^2), F_int(mu) = E(mu'), the coat's
    albedo from outside (the smooth F_ext(mu') when alpha -> 0). Without absorption
    K = 1 - (1 - E_avg) / eta^2, E_avg = integral E(mu') 2 mu' dmu', so that with T = 1 - E the
    white furnace of a white Lambert base gives E(mu_o) + T_o = 1.)"""
    return internal_weighted(p, None)


def internal_nodes(p) -> np.ndarray:
    """(32,) the inside cosines of ``internal_reflectance``'s quadrature: 16 in the total-internal-
    reflection cone, 16 refracted from the outside cosines of the transmitting cone."""
    eta = float(p.coating.ior)
    mu_c = np.sqrt(max(0.0, 1.0 - 1.0 / (eta * eta)))
    return np.concatenate([mu_c * GL16_X, np.sqrt(1.0 - (1.0 - GL16_X * GL16_X) / (eta * eta))])


def internal_weighted(p, weight):
    """integral_0^1 w(mu) F_int(mu) exp(-2 tau / mu) 2 mu dmu with w (32, 3) given at
    ``internal_nodes`` (None: 1, which is K)."""
    eta = float(p.coating.ior)
    tau = np.asarray(p.coating.sigma_a * p.coating.thickness, dtype=np.float64)[..., None]
    w = np.ones((32, 3)) if weight is None else np.asarray(weight, dtype=np.float64)
    mu_c = np.sqrt(max(0.0, 1.0 - 1.0 / (eta * eta)))
    mu = mu_c * GL16_X
    tir = mu_c * np.sum(GL16_W * 2.0 * mu * np.exp(-2.0 * tau / np.maximum(mu, 1e-30)) * w[:16].T, axis=-1)
    mu_in = internal_nodes(p)[16:]
    F = coat_albedo_rgb(p, GL16_X).T                   # (3, 16): a thin film colours it
    trans = np.sum(GL16_W * F * 2.0 * GL16_X * np.exp(-2.0 * tau / mu_in) * w[16:].T, axis=-1) / (eta * eta)
    return tir + trans


def internal_return(p, mu):
    """(N, 3) R_int(mu) exp(-2 tau / mu): the fraction of light going up inside the layer at
    cosine mu that the coat sends back down to the base, with the absorption up and down
    (1 under total internal reflection; else the coat's albedo at the matching outside cosine,
    as in ``internal_reflectance``, whose integrand this is)."""
    mu = np.clip(np.asarray(mu, dtype=np.float64).reshape(-1), 0.0, 1.0)
    eta = float(p.coating.ior)
    s2 = eta * eta * (1.0 - mu * mu)
    out = np.ones((mu.size, 3))
    t = s2 < 1.0
    if np.any(t):
        out[t] = coat_albedo_rgb(p, np.sqrt(1.0 - s2[t]))
    tau = np.asarray(p.coating.sigma_a * p.coating.thickness, dtype=np.float64)
    with np.errstate(divide="ignore", over="ignore"):
        return out * np.exp(-2.0 * tau[None, :] / np.maximum(mu, 1e-12)[:, None])


def _key(params) -> str:
    return params.model + repr(sorted((k, repr(v)) for k, v in dict(params).items()))


_BOUNCE_CACHE: dict = {}


def _bounce_tables_cached(p) -> tuple:
    key = (_key(p.base), _key(p.coating))
    hit = _BOUNCE_CACHE.get(key)
    if hit is None:
        if len(_BOUNCE_CACHE) >= 256:
            _BOUNCE_CACHE.clear()
        hit = _BOUNCE_CACHE[key] = _bounce_tables(p)
    return hit


def _base_albedos(p, mu):
    """(E_b, A_b), each (len(mu), 3), at the inside cosines mu: the base's sampler, 2 azimuths
    (anisotropic bases: along the tangent and the bitangent) x 256 stratified samples (error
    ~3e-3; a table costs ~50 ms, once per material: the window rebuilds it when a slider moves)."""
    from viewer.brdf.albedo import stratified_u

    base = _base(p)
    mu = np.maximum(np.asarray(mu, dtype=np.float64), 1e-3)
    E = np.zeros((mu.size, 3))
    A = np.zeros((mu.size, 3))
    phis = (0.0, 0.5 * np.pi)
    for seed, phi in enumerate(phis):
        u = stratified_u(16, seed=11 + seed)
        s = np.sqrt(1.0 - mu * mu)
        wo = np.stack([s * np.cos(phi), s * np.sin(phi), mu], axis=-1)
        wi, w, pdf = base.sample(p.base, np.repeat(wo, len(u), axis=0), np.tile(u, (mu.size, 1)))
        ok = (pdf > 0) & (wi[:, 2] > 0) & np.all(np.isfinite(w), axis=1)
        w = np.where(ok[:, None], w, 0.0)
        E += w.reshape(mu.size, len(u), 3).mean(axis=1)
        A += (w * internal_return(p, wi[:, 2])).reshape(mu.size, len(u), 3).mean(axis=1)
    return E / len(phis), A / len(phis)


def table_cosines(p) -> np.ndarray:
    """(BASE_TABLE,) the inside cosines of the base tables' entries: refracted from the outside
    cosines (k / 3)^2 (the only ones the closed form evaluates the base at)."""
    x = (np.arange(BASE_TABLE) / (BASE_TABLE - 1)) ** 2
    eta = float(p.coating.ior)
    return np.sqrt(1.0 - (1.0 - x * x) / (eta * eta))


def _bounce_tables(p) -> tuple:
    E, A = _base_albedos(p, table_cosines(p))
    # rho_K = integral A_b 2 mu dmu = integral E_b(mu) R_int(mu) 2 mu dmu (reciprocity of the
    # base): K's quadrature weighted by the smooth E_b, split at the critical angle where R_int
    # has its kink (sampling R_int inside A_b's integral instead is 1.5% off with 256 samples)
    E_k, _ = _base_albedos(p, internal_nodes(p))
    return E, A, internal_weighted(p, E_k)


def base_bounce_tables(p):
    """(E_b, A_b, rho_K): the coat-base interreflections of the base, BASE_TABLE x RGB at the
    inside cosines ``table_cosines``, and RGB.

    E_b(mu): the base's directional albedo; A_b(mu) = integral f_b(mu, v) cos v R_int(v) dv, the
    part of the light the base reflects from mu that the coat returns (``internal_return``);
    rho_K = integral A_b(mu) 2 mu dmu, the round trip of light that reaches the base diffusely.
    Light the coat returns is taken as diffuse (the assumption of the Lambert series), so the
    orders after the first sum to (A_b(mu_i) E_b(mu_o) + E_b(mu_i) A_b(mu_o)) / (2 pi (1 - rho_K))
    (the symmetric form keeps f reciprocal). A Lambert base (albedo rho) has E_b = rho and
    A_b = rho_K = rho K exactly, and the sum is the geometric series 1 / (1 - rho K) of its
    albedo; other bases are estimated with their own sampler (``_base_albedos``; error ~3e-3).
    Four entries linear in sqrt(outside cosine) are within 0.5% of the layer's albedo with 16
    (a white Oren-Nayar, gold and silver GGX bases). Albedos are capped at 1 and rho_K at 0.99
    (bases that create energy have no convergent series). A delta base has none (zeros): its
    interreflections are left out (it is sampled as a discrete lobe)."""
    if p.base.model == "lambert":
        rho = np.asarray(p.base.albedo, dtype=np.float64)
        K = internal_reflectance(p)
        E = np.tile(rho, (BASE_TABLE, 1))
        return E, np.tile(rho * K, (BASE_TABLE, 1)), rho * K
    if _base_is_delta(p):
        z = np.zeros((BASE_TABLE, 3))
        return z, z, np.zeros(3)
    E, A, rk = _bounce_tables_cached(p)
    # the series is that of an energy-conserving base: a base that reflects more than it receives
    # (a Lafortune lobe with large coefficients: E_b ~ 1e32 at n = 5000, cz = 10) has none, so its
    # albedos are capped at 1 and rho_K at 0.99 (finite in float32; the walk diverges there too)
    return np.clip(E, 0.0, 1.0), np.clip(A, 0.0, 1.0), np.clip(rk, 0.0, 0.99)


def _table_rgb(t, cos_out):
    x = np.sqrt(np.clip(np.asarray(cos_out, dtype=np.float64), 0.0, 1.0)) * (BASE_TABLE - 1)
    i = np.minimum(np.floor(x).astype(int), BASE_TABLE - 2)
    f = (x - i)[:, None]
    return (1.0 - f) * np.take(t, i, axis=0) + f * np.take(t, i + 1, axis=0)  # t[i], t[i + 1]


def base_interreflections(p, wi, wo):
    """(N, 3) the orders after the first of the coat-base interreflections, added to f_base at
    the refracted pair, looked up at the outside cosines of wi and wo (``base_bounce_tables``;
    the GLSL twin interpolates the same tables)."""
    E, A, rk = base_bounce_tables(p)
    ci, co = wi[:, 2], wo[:, 2]
    num = _table_rgb(A, ci) * _table_rgb(E, co) + _table_rgb(E, ci) * _table_rgb(A, co)
    return num / (2.0 * np.pi * np.maximum(1.0 - rk, 1e-6))[None, :]


def eval(p, wi, wo):
    ok = (wi[:, 2] > 0) & (wo[:, 2] > 0)
    f = eval_coat(p, wi, wo)
    # (a delta base evaluates to 0 here; it is reached through ``sample`` only)
    wi_t, wo_t, k = _through(p, wi, wo)
    f = f + k * (_base(p).module.eval(p.base, wi_t, wo_t) + base_interreflections(p, wi, wo))
    return np.where(ok[:, None], f, 0.0)


def _p_coat(p, wo):
    return fresnel_dielectric(np.clip(wo[:, 2], 0.0, 1.0), p.coating.ior)


def _pdf_coat(p, wi, wo):
    h = normalize(wi + wo)
    oh = dot(wo, h)
    ok = (wi[:, 2] > 0) & (wo[:, 2] > 0) & (oh > 0)
    return np.where(ok, _dist(p).D_visible(wo, h) / (4.0 * np.where(ok, oh, 1.0)), 0.0)


def _pdf_base(p, wi, wo):
    eta = p.coating.ior
    wi_t = refract_in(wi, eta)
    wo_t = refract_in(wo, eta)
    pb = _base(p).module.pdf(p.base, wi_t, wo_t)
    # solid-angle Jacobian of refraction: dw' / dw = cos_i / (eta^2 cos_i')
    jac = np.maximum(wi[:, 2], 0.0) / (eta * eta * np.maximum(wi_t[:, 2], 1e-300))
    return pb * jac


def pdf(p, wi, wo):
    ok = (wi[:, 2] > 0) & (wo[:, 2] > 0)
    pc = _p_coat(p, wo)
    out = pc * _pdf_coat(p, wi, wo) + (1.0 - pc) * _pdf_base(p, wi, wo)
    return np.where(ok, out, 0.0)


def sample(p, wo, u):
    return sample_lobe(p, wo, u)[:3]


def lobes(p):
    """The coat's glossy reflection and the kinds of the base's lobes, seen from above (what
    the base transmits stays in the layer): a delta base makes the layer delta and smooth."""
    return Lobe.REFLECTION | Lobe.GLOSSY | (_base(p).lobes(p.base) & lobe_flags.KINDS)


def sample_lobe(p, wo, u):
    """``sample`` plus, per sample, the lobe it drew: the coat's (glossy reflection) or the
    base's kind, reflected (a smooth mirror or glass base under the coat: a discrete
    direction, DELTA)."""
    n = wo.shape[0]
    up = wo[:, 2] > 0
    wo_s = np.where(up[:, None], wo, np.array([0.0, 0.0, 1.0]))
    pc = _p_coat(p, wo_s)
    uc, u0 = split_uniform(u[:, 0])
    uu = np.stack([u0, u[:, 1]], axis=-1)
    coat = uc < pc
    wi = np.zeros((n, 3))
    lobe = np.full(n, Lobe.REFLECTION | Lobe.GLOSSY, dtype=lobe_flags.DTYPE)
    if np.any(coat):
        m = _dist(p).sample_m(wo_s[coat], uu[coat])
        wi[coat] = reflect(wo_s[coat], m)
    base = _base(p)
    eta = p.coating.ior
    ok_b = np.ones(n, dtype=bool)
    w_delta = None
    if np.any(~coat):
        sel = ~coat
        wo_t = refract_in(wo_s[sel], eta)
        wi_t, w_b, pdf_b, lobe_b = base.sample_lobe(p.base, wo_t, uu[sel])
        wi_out, ok_out = refract_out(wi_t, eta)
        wi[sel] = wi_out
        ok_b[sel] = ok_out & (pdf_b > 0) & (wi_t[:, 2] > 0)
        lobe[sel] = (lobe_b & lobe_flags.DTYPE(lobe_flags.KINDS)) | lobe_flags.DTYPE(Lobe.REFLECTION)
        if _base_is_delta(p):
            # discrete base lobe: throughput T_i T_o a w_b (the eta^2 factors cancel for a delta
            # lobe: radiance times eta^2 going in, divided by eta^2 going out)
            _, _, k = _through(p, wi_out, wo_s[sel])
            w_delta = (sel, k * eta * eta * w_b / np.maximum(1.0 - pc[sel], 1e-300)[:, None],
                       (1.0 - pc[sel]) * pdf_b)
    pdf_ = pdf(p, wi, wo)
    ok = up & (wi[:, 2] > 0) & ok_b
    if w_delta is not None:
        sel, wd, pd = w_delta
        pdf_[sel] = pd
    ok &= pdf_ > 0
    f = eval(p, wi, wo)
    weight = f * (wi[:, 2] / np.where(ok, pdf_, 1.0))[:, None]
    if w_delta is not None:
        sel, wd, pd = w_delta
        weight[sel] = wd
    weight = np.where(ok[:, None], weight, 0.0)
    return wi, weight, np.where(ok, pdf_, 0.0), lobe


def _base_is_delta(p):
    return _base(p).is_delta(p.base)


def fresnel_source(p):
    return {"type": "dielectric", "ior": float(p.coating.ior), "field": "coating.ior"}


def is_dispersive(p):
    """A coat of a spectral dielectric (``coating.spectral``): its n(lambda_hero) refracts (the base
    is asked through its own model)."""
    return p.coating.get("spectral", spectral_fresnel.NONE) != spectral_fresnel.NONE


def walks(p):
    """The CPU reference's layered random walk (``reference = "random_walk"``)."""
    return p.get("reference") == "random_walk"


def reference_model(model, p):
    """The random walk (viewer/brdf/layered_walk.py) for ``reference = "random_walk"`` over a
    non-delta base (a delta base keeps the closed form, which is exact for it), else ``model``."""
    if walks(p) and not _base_is_delta(p):
        from viewer.brdf.layered_walk import WalkModel

        return WalkModel(model)
    return model


def ibl_split(p):
    """Image-based lighting proxy: the coating alone (a black base) and the coating's alpha."""
    from viewer import brdf

    return p.replace(base=brdf.get("lambert").params(albedo=[0.0, 0.0, 0.0])), float(p.coating["alpha"])


def splits_u(p):
    """The sample splits u[:, 0] into the coat-or-base choice and the direction
    (``split_uniform``); the GLSL twin takes those as u.z and u.x (viewer.gl.brdf_glsl.glsl_u)."""
    return True
