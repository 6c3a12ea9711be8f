"""The plotted numbers, pure numpy from the registry's Python twins: the lobe in the plane of
incidence, the 3D lobe, directional albedo, Fresnel curves, Bouguer's law and the sampler's
histogram against its pdf (the angles are described in ``viewer.plots``)."""

from __future__ import annotations

import math

import numpy as np

from viewer import ViewerError
from viewer.brdf.sampling import reflect_z
from viewer.plots.kinds import (absorption_source, as_params, check_channel, check_kind, fresnel_source, model_of,
                                reduce_channel)

def direction(theta_deg, phi_deg=0.0) -> np.ndarray:
    """Unit vector(s) at polar angle theta from +z (the normal) and azimuth phi from +x."""
    t = np.radians(np.asarray(theta_deg, dtype=np.float64))
    ph = np.radians(np.asarray(phi_deg, dtype=np.float64))
    t, ph = np.broadcast_arrays(t, ph)
    return np.stack([np.sin(t) * np.cos(ph), np.sin(t) * np.sin(ph), np.cos(t)], axis=-1)


def plane_directions(theta_o_deg, phi_deg=0.0) -> np.ndarray:
    """wo in the plane of incidence at signed angle theta_o (> 0: the mirror side, i.e. azimuth
    phi + 180)."""
    return direction(-np.asarray(theta_o_deg, dtype=np.float64), float(phi_deg))


def _check_theta_i(theta_i: float) -> float:
    theta_i = float(theta_i)
    if not (math.isfinite(theta_i) and 0.0 <= theta_i < 90.0):
        raise ViewerError(f"--theta-i: {theta_i:g} is out of range; allowed: degrees in [0, 90)")
    return theta_i


def _check_phi(phi: float) -> float:
    phi = float(phi)
    if not (math.isfinite(phi) and -360.0 <= phi <= 360.0):
        raise ViewerError(f"--phi: {phi:g} is out of range; allowed: degrees in [-360, 360]")
    return phi


def _delta_reflectance(p, cos_i: float) -> np.ndarray:
    """RGB reflectance of a delta mirror lobe at cos_i (the Fresnel term of the material)."""
    from viewer.brdf.fresnel import fresnel_conductor, fresnel_dielectric, fresnel_schlick

    src = fresnel_source(p)
    if src is None:
        return np.ones(3)
    film = _thin_film_curve(p, src, np.array([cos_i]), False)
    if film is not None:  # a coated interface: the film's interference decides, not the bare one
        return np.asarray(film, float).reshape(-1, 3)[0]
    if src["type"] == "dielectric":
        return np.full(3, fresnel_dielectric(cos_i, src["ior"]))
    if src["type"] == "conductor":
        return np.asarray(fresnel_conductor(cos_i, src["eta"], src["k"]), float)
    return np.asarray(fresnel_schlick(cos_i, src["f0"]), float)


def _eval(model, p, wi, wo):
    """f for a plot: a model's ``eval_mean`` where it has one (a stochastic eval averaged), else eval."""
    fn = model.hook("eval_mean")
    return model.eval(p, wi, wo) if fn is None else fn(p, np.ascontiguousarray(wi), np.ascontiguousarray(wo))


def polar_lobe(p, theta_i: float = 45.0, phi: float = 0.0, n: int = 721) -> dict:
    """The lobe in the plane of incidence (see the module docstring for the angles).

    Returns theta_o (degrees, sorted: a uniform grid of n points over [-90, 90] plus a dense one
    within 4 degrees of the mirror direction, so sharp peaks are resolved), wi (3,), wo (m, 3),
    f (m, 3), fcos (m, 3) = f cos(theta_o), delta: a list of {theta_o, reflectance (3,)} for
    the delta lobes of a mirror or smooth dielectric (whose f is 0 as a function; a thin film's
    reflectance where the material has one), and refracted: for a smooth dielectric, a list of
    {theta_t (degrees below the surface, on the far side of the normal), transmittance (3,) =
    1 - R} (empty beyond total internal reflection)."""
    p = as_params(p)
    theta_i, phi = _check_theta_i(theta_i), _check_phi(phi)
    model = model_of(p)
    grid = np.linspace(-90.0, 90.0, int(n))
    dense = theta_i + np.linspace(-4.0, 4.0, 161)
    theta_o = np.unique(np.concatenate([grid, dense[(dense > -90.0) & (dense < 90.0)]]))
    wi = direction(theta_i, phi)
    wo = plane_directions(theta_o, phi)
    f = np.asarray(_eval(model, p, np.broadcast_to(wi, wo.shape), wo), dtype=np.float64)
    cos_o = np.maximum(np.cos(np.radians(theta_o)), 0.0)
    fcos = f * cos_o[:, None]
    delta, refracted = [], []
    lobes = model.lobes(p)
    if lobes.is_delta and not np.any(f > 0):
        r = _delta_reflectance(p, math.cos(math.radians(theta_i)))
        delta.append({"theta_o": theta_i, "reflectance": r})
        src = fresnel_source(p)
        if lobes.transmits and src is not None and src["type"] == "dielectric":
            # Snell: sin theta_t = sin theta_i / n; the rest of the energy goes through
            s = math.sin(math.radians(theta_i)) / src["ior"]
            if s < 1.0:
                refracted.append({"theta_t": math.degrees(math.asin(s)), "transmittance": 1.0 - r})
    return {"theta_o": theta_o, "wi": wi, "wo": wo, "f": f, "fcos": fcos, "delta": delta,
            "refracted": refracted, "theta_i": theta_i, "phi": phi}


def lobe_3d(p, theta_i: float = 45.0, phi_i: float = 0.0, n_theta: int = 46, n_phi: int = 97,
            channel: str = "lum") -> dict:
    """f(wi, wo) cos(theta_o) over the hemisphere of wo on an (n_theta, n_phi) grid
    (theta_o 0..90, phi_o 0..360 with the first column repeated last, so the surface closes).

    Returns theta, phi (degrees), wi, f and fcos (n_theta, n_phi, 3), value (n_theta, n_phi) =
    the chosen channel of fcos ('rgb' = luminance) and the surface x, y, z = value * wo."""
    p = as_params(p)
    theta_i, phi_i = _check_theta_i(theta_i), _check_phi(phi_i)
    check_channel(channel)
    model = model_of(p)
    theta = np.linspace(0.0, 90.0, int(n_theta))
    phi = np.linspace(0.0, 360.0, int(n_phi))
    T, P = np.meshgrid(theta, phi, indexing="ij")
    wo = direction(T, P)
    wi = direction(theta_i, phi_i)
    flat = wo.reshape(-1, 3)
    f = np.asarray(_eval(model, p, np.broadcast_to(wi, flat.shape), flat), dtype=np.float64).reshape(T.shape + (3,))
    fcos = f * np.maximum(wo[..., 2], 0.0)[..., None]
    value = reduce_channel(fcos, channel)
    x, y, z = (value * wo[..., i] for i in range(3))
    delta = []
    if model.lobes(p).is_delta and not np.any(f > 0):
        delta.append({"wo": reflect_z(wi),
                      "reflectance": _delta_reflectance(p, float(wi[2]))})
    return {"theta": theta, "phi": phi, "wi": wi, "wo": wo, "f": f, "fcos": fcos, "value": value,
            "x": x, "y": y, "z": z, "delta": delta, "theta_i": theta_i, "phi_i": phi_i, "channel": channel}


def albedo_curve(p, n: int = 46, n_side: int = 24, theta_max: float = 89.5) -> dict:
    """Directional albedo rho(theta) = integral of f cos over the hemisphere (the furnace test:
    a white environment of radiance 1 seen at angle theta reflects rho), from
    ``viewer.brdf.albedo.directional_albedo`` (the model's own sampler on a fixed stratified
    pattern: deterministic). theta is the angle of wo; for a reciprocal model it is also the
    albedo of light incident at theta. Returns theta (degrees), albedo, reflected and
    transmitted (each (n, 3))."""
    from viewer.brdf.albedo import directional_albedo

    p = as_params(p)
    theta = np.linspace(0.0, float(theta_max), int(n))
    refl, trans = directional_albedo(model_of(p), p, np.cos(np.radians(theta)), n_side=int(n_side), split=True)
    return {"theta": theta, "albedo": refl + trans, "reflected": refl, "transmitted": trans,
            "transmissive": bool(model_of(p).spec.transmissive)}


def _pseudo_brewster(eta, k) -> np.ndarray:
    """Angle (degrees) of minimal R_p of a conductor, per channel (0.01 degree grid)."""
    from viewer.brdf.fresnel import fresnel_conductor_polarized

    t = np.linspace(0.0, 90.0, 9001)
    _, rp = fresnel_conductor_polarized(np.cos(np.radians(t))[:, None], eta[None, :], k[None, :])
    return t[np.argmin(rp, axis=0)]


def _thin_film_curve(p, src, cos, inside):
    """(n, 3) RGB reflectance of the material's thin film (viewer/brdf/thin_film.py) against the
    angle, or None when it has none."""
    from viewer.brdf import thin_film

    owner = p if "thin_film" in p else p.get("coating")  # a layered model's film is its coating's
    if owner is None or not thin_film.at_point(owner) or src["type"] == "schlick":
        return None
    if src["type"] == "conductor":
        return thin_film.reflectance_rgb(owner, cos, src["eta"], src["k"])
    ior = src["ior"]
    return thin_film.dielectric_reflectance_rgb(owner, cos, 1.0 / ior if inside else ior)


def fresnel_curves(p, inside: bool = False, n: int = 181) -> dict:
    """R_s, R_p and R = (R_s + R_p) / 2 vs the angle of incidence theta (0..90 degrees, n points),
    each (n, 3), from ``viewer.brdf.fresnel``.

    Dielectric (n = ior): light from air (eta = n2/n1 = ior) or, with ``inside``, from inside
    the denser medium (eta = 1/ior): total internal reflection beyond the critical angle
    asin(n2/n1). Brewster's angle atan(n2/n1) has R_p = 0. Conductor (n + i k, from air): the
    pseudo-Brewster angle (minimal R_p). Schlick (f0): the Schlick curve plus the exact curves of
    the dielectric with the same f0, n = (1 + sqrt f0) / (1 - sqrt f0).
    Returns theta, Rs, Rp, R, (schlick), type, eta (3,) (relative index n2/n1), k (3,),
    brewster (3,), critical (3,) (NaN where none), brewster_label, field, inside."""
    from viewer.brdf.fresnel import (fresnel_conductor, fresnel_conductor_polarized, fresnel_dielectric,
                                     fresnel_dielectric_polarized, fresnel_schlick)

    p = as_params(p)
    check_kind(p, "fresnel")
    src = fresnel_source(p)
    theta = np.linspace(0.0, 90.0, int(n))
    if inside and src["type"] == "dielectric" and src["ior"] > 1.0:
        # R rises steeply just below the critical angle: sample it densely there
        crit = math.degrees(math.asin(1.0 / src["ior"]))
        theta = np.unique(np.concatenate([theta, crit - np.geomspace(1e-4, 2.0, 60), [crit]]))
    cos = np.cos(np.radians(theta))[:, None]
    out = {"theta": theta, "type": src["type"], "field": src["field"], "inside": bool(inside)}
    film = _thin_film_curve(p, src, cos[:, 0], inside)
    if film is not None:
        out["thin_film"] = film
    if src["type"] == "conductor":
        if inside:
            raise ViewerError(f"--inside: model {p.model!r} has a conductor Fresnel term (eta + i k, seen "
                              "from air); allowed: a dielectric interface (ior)")
        eta, k = src["eta"], src["k"]
        Rs, Rp = fresnel_conductor_polarized(cos, eta[None, :], k[None, :])
        out.update(Rs=Rs, Rp=Rp, R=fresnel_conductor(cos, eta[None, :], k[None, :]), eta=eta, k=k,
                   brewster=_pseudo_brewster(eta, k), critical=np.full(3, np.nan),
                   brewster_label="pseudo-Brewster")
        return out
    if src["type"] == "schlick":
        if inside:
            raise ViewerError(f"--inside: model {p.model!r} has a Schlick Fresnel term (f0, seen from "
                              "air); allowed: a dielectric interface (ior)")
        f0 = np.clip(src["f0"], 0.0, 0.999999)
        eta = (1.0 + np.sqrt(f0)) / (1.0 - np.sqrt(f0))
        out["schlick"] = fresnel_schlick(cos, src["f0"][None, :])
    else:
        eta = np.full(3, src["ior"])
        if inside:
            eta = 1.0 / eta
    Rs, Rp = fresnel_dielectric_polarized(cos, eta[None, :])
    critical = np.where(eta < 1.0, np.degrees(np.arcsin(np.minimum(eta, 1.0))), np.nan)
    out.update(Rs=Rs, Rp=Rp, R=fresnel_dielectric(cos, eta[None, :]), eta=eta, k=np.zeros(3),
               brewster=np.degrees(np.arctan(eta)), critical=critical, brewster_label="Brewster")
    return out


def bouguer_curve(p, d_max: float | None = None, n: int = 201) -> dict:
    """Bouguer's law T(d) = exp(-sigma_a d) per channel over d in [0, d_max] (n points).
    d_max defaults to 3 / (the smallest positive sigma_a), where every absorbing channel is
    below e^-3 = 5 %, and covers twice a layer's thickness. Returns d, T (n, 3), sigma_a,
    unit (of d), thickness (layered) or None."""
    p = as_params(p)
    check_kind(p, "bouguer")
    src = absorption_source(p)
    sigma = src["sigma_a"]
    if d_max is None:
        pos = sigma[sigma > 0]
        d_max = 3.0 / pos.min() if pos.size else 1.0
        if src["thickness"]:
            d_max = max(d_max, 2.0 * src["thickness"])
    d_max = float(d_max)
    if not (math.isfinite(d_max) and d_max > 0):
        raise ViewerError(f"d_max: {d_max:g} is out of range; allowed: a positive distance")
    d = np.linspace(0.0, d_max, int(n))
    return {"d": d, "T": np.exp(-sigma[None, :] * d[:, None]), "sigma_a": sigma, "unit": src["unit"],
            "thickness": src["thickness"], "field": src["field"]}


SAMPLING_ROWS, SAMPLING_COLS = 25, 50     # the chi-square test's cells (cos theta rows, phi columns)


def sampling_histogram(p, theta_i: float = 45.0, phi: float = 0.0, samples: int = 200_000, seed: int = 0,
                       points: int = 1500, rows: int = SAMPLING_ROWS, cols: int = SAMPLING_COLS) -> dict:
    """The sampler of ``p`` at the fixed direction ``wo`` = (theta_i, phi) against its pdf, with
    the test suite's chi-square functions (``viewer.brdf.chi2``) and the same cells: rows of
    cos theta (top row cos = 1; on the sphere for transmissive models, 2 rows + 1 from cos = 1
    down to -1) by columns of phi in [0, 360). Returns observed counts, expected counts (samples
    x the integrated pdf), their difference in standard deviations (o - e) / sqrt(max(e, 1)),
    the chi-square statistic, degrees of freedom and p-value, failed samples (pdf = 0), and
    ``points`` sampled directions (a second stream) for the point cloud. The histogram and pdf
    are what ``chi2_test(model, p, wo, samples, default_rng(seed), ...)`` computes."""
    from viewer import brdf
    from viewer.brdf.chi2 import chi2_from_counts, histogram, integrate_pdf

    p = as_params(p)
    theta_i, phi = _check_theta_i(theta_i), _check_phi(phi)
    samples, points = int(samples), int(points)
    if not 1000 <= samples <= 50_000_000:
        raise ViewerError(f"--samples: {samples} is out of range; allowed: 1000 to 50000000")
    model = brdf.get(p.model)
    sphere = bool(model.spec.transmissive)
    wo = direction(theta_i, phi)
    rng = np.random.default_rng(seed)
    r = 2 * rows + 1 if sphere else rows
    observed, failed, problems = histogram(model, p, wo, samples, rng, r, cols, sphere)
    expected = samples * integrate_pdf(model, p, wo, r, cols, sphere, n_samples=samples)
    res = chi2_from_counts(observed, failed, problems, expected, samples, alpha=0.0)
    o = observed.astype(np.float64)
    wi, _, pdf = model.sample(p, np.broadcast_to(wo, (points, 3)), np.random.default_rng([seed, 1]).random((points, 2)))
    cloud = wi[pdf > 0]
    # row 0 of the chi-square cells is cos theta = c0 (bottom): flip so row 0 = the pole
    return {"wo": wo, "theta_i": theta_i, "phi": phi, "sphere": sphere, "samples": samples, "seed": int(seed),
            "rows": r, "cols": cols, "observed": o[::-1], "expected": expected[::-1],
            "difference": ((o - expected) / np.sqrt(np.maximum(expected, 1.0)))[::-1],
            "chi2": res.stat, "dof": res.dof, "p_value": res.p_value, "failed": int(failed),
            "message": res.message, "points": cloud}
