"""Lambert: the perfectly diffuse BRDF f = rho_d / pi (lecture: 'The BRDF of perfectly diffuse
materials'; Lambert 1760)."""

from __future__ import annotations

import numpy as np

from viewer.brdf.sampling import INV_PI, cosine_hemisphere, cosine_hemisphere_pdf
from viewer.brdf.lobes import Lobe
from viewer.brdf.spec import ModelSpec, Param

SPEC = ModelSpec(
    name="lambert",
    title="Lambert",
    params=(
        Param("albedo", "rgb", [0.8, 0.8, 0.8], "diffuse reflectance rho_d", lo=0.0, hi=1.0),
    ),
    source="Lambert 1760; lecture eq. f_r,d = rho_d / pi",
)


def eval(p, wi, wo):
    ok = (wi[:, 2] > 0) & (wo[:, 2] > 0)
    return np.where(ok[:, None], p.albedo[None, :] * INV_PI, 0.0)


def pdf(p, wi, wo):
    return np.where(wo[:, 2] > 0, cosine_hemisphere_pdf(wi), 0.0)


def sample(p, wo, u):
    wi = cosine_hemisphere(u)
    pdf_ = np.where(wo[:, 2] > 0, cosine_hemisphere_pdf(wi), 0.0)
    ok = pdf_ > 0
    # f cos / pdf = (albedo / pi) cos / (cos / pi) = albedo
    weight = np.where(ok[:, None], p.albedo[None, :], 0.0)
    return wi, weight, pdf_


def lobes(p):
    return Lobe.REFLECTION | Lobe.DIFFUSE


def lambertian_albedo(p):
    """The albedo: a Lambert surface everywhere (the model hook)."""
    return np.broadcast_to(np.asarray(p["albedo"], dtype=np.float64), (3,)).copy()
