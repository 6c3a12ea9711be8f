"""Multiple scattering of a microfacet material three ways, as directional albedo (white furnace):

* ``single``: the single-scattering lobe alone (``multiple_scattering = false``);
* ``compensated``: what the rasterizer shows with ``render.ms_compensation`` in a constant
  environment: the single-scattering albedo plus Fdez-Aguera 2019's term F_ms E_ms, with
  E_ms = 1 - E_ss, E_ss the specular lobe's own single-scattering albedo with F = 1
  (``white_lobe``; the GGX DFG table's A + B only for lobes without a Fresnel factor to set to 1),
  and the material's F0 derived as the renderer does (``ms_f0``: its normal-incidence specular
  albedo over E_ss there, clamped to 1);
* ``kulla_conty``: what the rasterizer adds for point and directional lights with
  ``render.ms_compensation``: Kulla & Conty 2017's energy term, a lobe
  f_ms = (1 - E_ss(mu_i)) (1 - E_ss(mu_o)) / (pi (1 - E_avg)) tinted by
  F_avg^2 E_avg / (1 - F_avg (1 - E_avg)), with the same E_ss and F0 (E_avg its hemispherical
  average, ``e_avg``); its albedo is single + (1 - E_ss(mu_o)) F_add. Rough gold at alpha 1:
  blue 0.176 / 0.221 against the walk's 0.186 / 0.244 at cos 1 / 0.5, where Fdez-Aguera's form
  gives 0.160 / 0.222 (its single bounce colour F_avg per order is a limit there);
* ``walk``: the reference's random walk (Heitz et al. 2016; ``multiple_scattering = true``).

All three from the model's own samplers on the same stratified pattern
(``viewer.brdf.albedo.directional_albedo``); ``benchmarks/ms_compensation.py`` prints the
compensation's error against the walk per alpha. The rule for E_ss and F0 lives here once: the
rasterizer's tables (``viewer/gl/material_tables.py``) call ``white_lobe``, ``ess_ggx`` and
``ms_f0``."""

from __future__ import annotations

import numpy as np

from viewer import brdf
from viewer.brdf import spectral_fresnel
from viewer.brdf.albedo import TABLE_SIZE, directional_albedo

_DFG = None


def applies(p) -> bool:
    """Whether the comparison exists for a material: one whose ``multiple_scattering`` switch turns
    on the reference's random walk (microfacet with a Smith GGX or Beckmann lobe; the model's
    ``walks``)."""
    return "multiple_scattering" in p and brdf.walks(p.replace(multiple_scattering=True))


def _dfg(nov, alpha):
    global _DFG
    from viewer.environment.dfg import lookup_dfg, stored_dfg_table

    if _DFG is None:
        _DFG = stored_dfg_table()
    return lookup_dfg(_DFG, nov, max(float(alpha), 1e-3))


def white_lobe(spec_p):
    """The specular lobe ``spec_p`` (a model's ``ibl_split`` params) with F = 1, single scattering
    only: its directional albedo is the E_ss of the compensation. Microfacet lobes (every D and G):
    Schlick with f0 = 1 is F = 1 exactly (no film, no spectral table, no walk, no diffuse base).
    None for the other models (no Fresnel factor to set to 1); ``ess_ggx`` stands in for them."""
    if not _schlick_lobe(spec_p):
        return None
    kw = {"spectral": spectral_fresnel.NONE} if "spectral" in spec_p else {}
    kw.update({k: v for k, v in (("kd", np.zeros(3)), ("multiple_scattering", False)) if k in spec_p})
    return spec_p.replace(fresnel="schlick", f0=np.ones(3), **kw)


def _schlick_lobe(p) -> bool:
    """A lobe whose Fresnel may be Schlick's with ``f0`` (then f0 = 1 is F = 1): by its spec."""
    if not hasattr(p, "model") or not p.model:
        return False
    spec = brdf.spec_of(p)
    return "f0" in spec.names and "fresnel" in spec.names and "schlick" in spec.param("fresnel").choices


def ess_ggx(cos_o, alpha) -> np.ndarray:
    """E_ss = A + B of the GGX DFG table at the lobe width ``alpha`` (the rule for lobes without
    ``white_lobe``, and the one used for every lobe before: wrong for Beckmann and Blinn-Phong)."""
    a, b = _dfg(np.asarray(cos_o, dtype=np.float64), alpha)
    return np.clip(np.asarray(a + b, dtype=np.float64), 0.0, 1.0)


def ms_f0(spec_normal, ess_normal) -> np.ndarray:
    """The specular lobe's Fresnel at normal incidence for F_avg: its albedo there over E_ss there
    (exact for a constant F), clamped to [0, 1]; 0 for a material without a specular part."""
    spec_normal = np.asarray(spec_normal, dtype=np.float64)
    if not np.any(spec_normal > 0):
        return np.zeros(3)
    return np.clip(spec_normal / max(float(ess_normal), 1e-6), 0.0, 1.0)


def compensated(single, spec_single, e_ss, f0) -> np.ndarray:
    """Fdez-Aguera 2019 sec. 3-4 (``viewer.environment.dfg.ms_compensation``'s formula) with the
    lobe's own single-scattering albedo as FssEss, as shaders/passes/forward.frag adds it:
    single + F_ms E_ms, E_ms = 1 - E_ss, F_avg = F0 + (1 - F0) / 21,
    F_ms = FssEss F_avg / (1 - E_ms F_avg)."""
    e_ms = np.clip(1.0 - np.asarray(e_ss, dtype=np.float64), 0.0, 1.0)[:, None]
    f_avg = np.asarray(f0) + (1.0 - np.asarray(f0)) / 21.0
    f_ms = spec_single * f_avg / (1.0 - e_ms * f_avg)
    return single + f_ms * e_ms


def e_avg(e_ss_table) -> float:
    """E_avg = integral E_ss(mu) 2 mu dmu of a table at cos = (k + 0.5) / size (midpoint rule):
    the hemispherical average of the single-scattering albedo with F = 1."""
    e = np.clip(np.asarray(e_ss_table, dtype=np.float64).reshape(-1), 0.0, 1.0)
    mu = (np.arange(e.size) + 0.5) / e.size
    return float(np.clip(np.sum(e * 2.0 * mu) / e.size, 0.0, 1.0))


def kulla_conty_fadd(f0, e_avg_) -> np.ndarray:
    """Kulla & Conty 2017 ("Revisiting physically based shading at Imageworks", SIGGRAPH course):
    the Fresnel tint of the multiple-scattering lobe, F_avg^2 E_avg / (1 - F_avg (1 - E_avg)),
    F_avg = F0 + (1 - F0) / 21 (Schlick's hemispherical average; 0 without a specular lobe)."""
    f0 = np.asarray(f0, dtype=np.float64)
    if not np.any(f0 > 0):
        return np.zeros(3)
    f_avg = f0 + (1.0 - f0) / 21.0
    return f_avg * f_avg * e_avg_ / (1.0 - f_avg * (1.0 - e_avg_))


def kulla_conty_eval(e_i, e_o, e_avg_, f0) -> np.ndarray:
    """(N, 3) Kulla & Conty's energy term for a light from wi: f_ms = (1 - E_ss(mu_i))
    (1 - E_ss(mu_o)) / (pi (1 - E_avg)) times ``kulla_conty_fadd``; its directional albedo is
    (1 - E_ss(mu_o)) F_add (what shaders/passes/forward.frag adds for point and directional
    lights)."""
    lobe = (1.0 - np.asarray(e_i)) * (1.0 - np.asarray(e_o)) / (np.pi * max(1.0 - e_avg_, 1e-6))
    return lobe[:, None] * kulla_conty_fadd(f0, e_avg_)[None, :]


def kulla_conty(single, e_ss, e_avg_, f0) -> np.ndarray:
    """Directional albedo with Kulla & Conty's term: single + (1 - E_ss(mu_o)) F_add."""
    e_ms = np.clip(1.0 - np.asarray(e_ss, dtype=np.float64), 0.0, 1.0)[:, None]
    return single + e_ms * kulla_conty_fadd(f0, e_avg_)[None, :]


def albedos(p, cos_o, n_side: int = 24, known: dict | None = None, rule: str = "lobe") -> dict:
    """{"single", "compensated", "kulla_conty", "walk"}: (len(cos_o), 3) directional albedos of
    ``p``: single scattering, Fdez-Aguera's compensation (the raster's environment light),
    Kulla & Conty's energy term (the raster's point and directional lights), the random walk.
    ``known``: any of "single" / "walk" already computed at these cos_o with this n_side.
    ``rule``: "lobe" (E_ss of ``white_lobe``, what the rasterizer does) or "ggx" (the GGX DFG
    table for every lobe: the former rule, kept for the benchmark's before/after)."""
    model = brdf.get("microfacet")
    cos_o = np.asarray(cos_o, dtype=np.float64)
    known = known or {}
    off = p.replace(multiple_scattering=False)
    on = p.replace(multiple_scattering=True)
    single = known.get("single")
    if single is None:
        single = directional_albedo(model, off, cos_o, n_side=n_side)
    walk = known.get("walk")
    if walk is None:
        walk = directional_albedo(model, on, cos_o, n_side=n_side)
    spec_p, alpha = model.hook("ibl_split")(off)
    nov_n = (TABLE_SIZE - 0.5) / TABLE_SIZE
    has_kd = bool(np.any(np.asarray(p.kd) > 0))
    spec_single = directional_albedo(model, spec_p, cos_o, n_side=n_side) if has_kd else single
    spec_normal = directional_albedo(model, spec_p, np.array([nov_n]), n_side=n_side)[0]
    white = white_lobe(spec_p) if rule == "lobe" else None
    mu_t = (np.arange(TABLE_SIZE) + 0.5) / TABLE_SIZE   # the raster's table (material_tables)
    if white is not None:
        cos_n = np.concatenate([cos_o, mu_t])
        e = directional_albedo(model, white, cos_n, n_side=n_side).mean(axis=1)
        e_ss, e_tab = e[:cos_o.size], e[cos_o.size:]
    else:
        e_ss, e_tab = ess_ggx(cos_o, alpha), ess_ggx(mu_t, alpha)
    f0 = ms_f0(spec_normal, float(e_tab[-1]))
    return {"single": single, "compensated": compensated(single, spec_single, e_ss, f0),
            "kulla_conty": kulla_conty(single, e_ss, e_avg(e_tab), f0),
            "walk": walk}
