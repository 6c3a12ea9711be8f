"""The BRDF registry: every model of the course, as a spec plus numpy eval / sample / pdf.

Each family is one module of this package that defines ``SPEC`` (a ``ModelSpec``) and the
functions ``eval(p, wi, wo)``, ``sample(p, wo, u)`` and ``pdf(p, wi, wo)`` over (N, 3) arrays
in the shading frame (z = normal; wi toward the light, wo toward the viewer; no cosine in f).
Its GLSL twin is ``shaders/brdf/<name>.glsl``. Modules are discovered, so adding a model is
one Python file plus one GLSL file.
"""

from __future__ import annotations

import importlib
import pkgutil

import numpy as np

from viewer import ViewerError
from viewer.brdf.spec import ModelSpec, Param, Params, validate_params

# The course's order (the lecture's order of families); discovered extras follow alphabetically.
ORDER = ("lambert", "phong", "blinn_phong", "microfacet", "oren_nayar", "lafortune",
         "ashikhmin_shirley", "layered", "mirror", "dielectric")

_HELPERS = {"spec", "fresnel", "microfacet_dist", "microfacet_walk", "sampling", "presets", "albedo",
            "spectral_fresnel", "thin_film", "merl", "fit", "chi2"}
_REGISTRY: dict[str, "Model"] | None = None


class Model:
    """A registered model: its spec and vectorized numpy functions (docs/architecture.md)."""

    def __init__(self, module):
        self.module = module
        self.spec: ModelSpec = module.SPEC
        self.name = self.spec.name

    def __repr__(self):
        return f"<brdf model {self.name}>"

    def params(self, **values) -> Params:
        """Defaults of every parameter, overridden by ``values`` (validated)."""
        return validate_params(self.spec, values, self.name, lookup_spec)

    def _p(self, p):
        if p is None:
            return self.params()
        if isinstance(p, Params):
            return p
        return self.params(**p)

    def eval(self, p, wi, wo):
        wi, wo, single = _dirs(wi, wo)
        f = self.module.eval(self._p(p), wi, wo)
        return f[0] if single else f

    def pdf(self, p, wi, wo):
        wi, wo, single = _dirs(wi, wo)
        pdf = self.module.pdf(self._p(p), wi, wo)
        return float(pdf[0]) if single else pdf

    def sample(self, p, wo, u):
        wo = np.asarray(wo, dtype=np.float64)
        u = np.asarray(u, dtype=np.float64)
        single = wo.ndim == 1 and u.ndim == 1
        n = max(np.atleast_2d(wo).shape[0], np.atleast_2d(u).shape[0])
        wo2 = np.broadcast_to(np.atleast_2d(wo), (n, 3)).copy()
        u2 = np.broadcast_to(np.atleast_2d(u), (n, 2)).copy()
        wi, weight, pdf = self.module.sample(self._p(p), wo2, u2)
        if single:
            return wi[0], weight[0], float(pdf[0])
        return wi, weight, pdf


def _dirs(wi, wo):
    wi = np.asarray(wi, dtype=np.float64)
    wo = np.asarray(wo, dtype=np.float64)
    single = wi.ndim == 1 and wo.ndim == 1
    wi, wo = np.broadcast_arrays(np.atleast_2d(wi), np.atleast_2d(wo))
    return np.ascontiguousarray(wi), np.ascontiguousarray(wo), single


def _registry() -> dict[str, Model]:
    global _REGISTRY
    if _REGISTRY is None:
        found = {}
        for info in pkgutil.iter_modules(__path__):
            if info.name in _HELPERS or info.name.startswith("_"):
                continue
            mod = importlib.import_module(f"{__name__}.{info.name}")
            if hasattr(mod, "SPEC"):
                found[mod.SPEC.name] = Model(mod)
        ordered = [n for n in ORDER if n in found] + sorted(n for n in found if n not in ORDER)
        _REGISTRY = {n: found[n] for n in ordered}
    return _REGISTRY


def names() -> list[str]:
    """Every registry name, in the course's order."""
    return list(_registry())


def get(name: str) -> Model:
    try:
        return _registry()[name]
    except KeyError:
        raise ViewerError(f"unknown BRDF model {name!r}; allowed: {', '.join(names())}") from None


def lookup_spec(name, where: str = "model") -> ModelSpec:
    """The spec of ``name`` or a ViewerError naming ``where`` and the allowed names."""
    reg = _registry()
    if name not in reg:
        raise ViewerError(f"{where}: unknown model {name!r}; allowed: {', '.join(reg)}")
    return reg[name].spec


def __getattr__(attr):
    # The Fresnel functions live apart from the models that call them (pbrt's layout).
    if attr.startswith("fresnel_"):
        from viewer.brdf import fresnel

        return getattr(fresnel, attr)
    raise AttributeError(attr)


__all__ = ["Model", "ModelSpec", "Param", "Params", "get", "names", "lookup_spec"]
