"""Multiple scattering of a microfacet material three ways, as directional albedo (white furnace):

* ``single``: the single-scattering lobe alone (``multiple_scattering = false``);
* ``compensated``: what the rasterizer shows with ``render.ms_compensation`` in a constant
  environment: the single-scattering albedo plus Fdez-Aguera 2019's term F_ms E_ms, with
  E_ms = 1 - (A + B) from the GGX DFG table and the material's F0 derived as the renderer does
  (its normal-incidence specular albedo over A + B, clamped to 1);
* ``walk``: the reference's random walk (Heitz et al. 2016; ``multiple_scattering = true``).

All three from the model's own samplers on the same stratified pattern
(``viewer.brdf.albedo.directional_albedo``); ``benchmarks/ms_compensation.py`` prints the
compensation's error against the walk per alpha."""

from __future__ import annotations

import numpy as np

from viewer import brdf
from viewer.brdf.albedo import TABLE_SIZE, directional_albedo

_DFG = None


def applies(p) -> bool:
    """Whether the comparison exists for a material: microfacet with a Smith GGX or Beckmann lobe."""
    return p.model == "microfacet" and p.distribution != "blinn_phong" and p.shadowing == "smith"


def _dfg(nov, alpha):
    global _DFG
    from viewer.environment.dfg import dfg_table, lookup_dfg

    if _DFG is None:
        _DFG = dfg_table()
    return lookup_dfg(_DFG, nov, max(float(alpha), 1e-3))


def albedos(p, cos_o, n_side: int = 24, known: dict | None = None) -> dict:
    """{"single", "compensated", "walk"}: (len(cos_o), 3) directional albedos of ``p``.
    ``known``: any of "single" / "walk" already computed at these cos_o with this n_side."""
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
    spec_p, alpha = model.module.ibl_split(off)
    nov_n = (TABLE_SIZE - 0.5) / TABLE_SIZE
    has_kd = bool(np.any(np.asarray(p.kd) > 0))
    spec_single = directional_albedo(model, spec_p, cos_o, n_side=n_side) if has_kd else single
    spec_normal = directional_albedo(model, spec_p, np.array([nov_n]), n_side=n_side)[0]
    a_n, b_n = _dfg(nov_n, alpha)
    f0 = np.clip(spec_normal / max(float(a_n + b_n), 1e-6), 0.0, 1.0)
    a, b = _dfg(cos_o, alpha)
    e_ms = np.clip(1.0 - (a + b), 0.0, 1.0)[:, None]
    f_avg = f0 + (1.0 - f0) / 21.0
    # viewer.environment.dfg.ms_compensation's formula, with the lobe's own single-scattering
    # albedo as FssEss (as shaders/passes/forward.frag uses its table rho_s)
    f_ms = spec_single * f_avg / (1.0 - e_ms * f_avg)
    return {"single": single, "compensated": single + f_ms * e_ms, "walk": walk}
