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
from viewer.brdf import lobes
from viewer.brdf.lobes import Lobe
from viewer.brdf.spec import HOOKS, ModelSpec, Param, Params, check_module, validate_params

# The course's order (the lecture's order of families); discovered extras follow alphabetically.
ORDER = ("lambert", "phong", "blinn_phong", "microfacet", "oren_nayar", "lafortune",
         "ashikhmin_shirley", "layered", "mirror", "dielectric")

_HELPERS = {"spec", "lobes", "brdffile", "file_model", "report_card", "fresnel", "microfacet_dist", "microfacet_walk", "sampling", "presets", "albedo",
            "spectral_fresnel", "thin_film", "merl", "fit", "chi2"}
_REGISTRY: dict[str, "Model"] | None = None


class Model:
    """A registered model: its spec and vectorized numpy functions (docs/architecture.md), and
    the optional hooks of the model protocol (``viewer.brdf.spec.HOOKS``) with their defaults."""

    def __init__(self, module, where: str | None = None):
        check_module(module, where)
        self.module = module
        self.spec: ModelSpec = module.SPEC
        self.name = self.spec.name

    def hook(self, name: str, default=None):
        """The module's hook ``name`` (one of ``spec.HOOKS``), or ``default`` when it has none."""
        if name not in HOOKS:
            raise KeyError(f"{name!r} is not a hook of the model protocol")
        return getattr(self.module, name, default)

    def lobes(self, p=None) -> Lobe:
        """The lobes of ``p`` (``viewer.brdf.lobes.Lobe``): every lobe its sampler may draw. The
        ``lobes`` hook, else the spec's ``delta`` / ``transmissive`` (``lobes.declared``) with the
        kinds of any material ``p`` nests (a base under a coat, seen from above: reflection)."""
        p = self._p(p)
        fn = self.hook("lobes")
        if fn is not None:
            return Lobe(int(fn(p)))
        out = lobes.declared(self.spec.delta, self.spec.transmissive)
        for prm in self.spec.params:
            if prm.kind == "material":
                out |= (get(p[prm.name].model).lobes(p[prm.name]) & lobes.KINDS) | Lobe.REFLECTION
        return out

    def is_delta(self, p=None) -> bool:
        """Every lobe of ``p`` is a delta lobe (mirror, smooth glass): ``lobes(p).is_delta``."""
        return self.lobes(p).is_delta

    def has_delta(self, p=None) -> bool:
        """Some lobe of ``p`` is a delta lobe (``p`` is delta, or a coat over a delta base)."""
        return self.lobes(p).has_delta

    def sample_lobe(self, p, wo, u):
        """``sample`` plus, per sample, the lobe it drew: (wi, weight, pdf, lobe), lobe a uint8
        array of ``Lobe`` values (a ``Lobe`` for one sample). The ``sample_lobe`` hook, else
        the model's kind (delta when it is delta, else its smooth kinds) on the side each sample
        went to (``lobes.by_side``; reflection for a model that does not transmit). A failed
        sample (pdf 0) carries the lobe it tried."""
        p = self._p(p)
        fn = self.hook("sample_lobe")
        wo2, u2, single = _sample_args(wo, u)
        if fn is not None:
            wi, weight, pdf, lobe = fn(p, wo2, u2)
        else:
            wi, weight, pdf = self.module.sample(p, wo2, u2)
            own = self.lobes(p)
            kind = Lobe.DELTA if own.is_delta else own & lobes.SMOOTH
            lobe = (lobes.by_side(kind, wi, wo2) if own.transmits
                    else np.full(len(pdf), kind | Lobe.REFLECTION, dtype=lobes.DTYPE))
        lobe = np.asarray(lobe, dtype=lobes.DTYPE)
        if single:
            return wi[0], weight[0], float(pdf[0]), Lobe(int(lobe[0]))
        return wi, weight, pdf, lobe

    def fresnel_source(self, p=None) -> dict | None:
        """How ``p``'s Fresnel reflectance is given (the hook, else by parameter names)."""
        p = self._p(p)
        fn = self.hook("fresnel_source")
        return fn(p) if fn is not None else fresnel_source_by_names(p)

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
        wo2, u2, single = _sample_args(wo, u)
        wi, weight, pdf = self.module.sample(self._p(p), wo2, u2)
        if single:
            return wi[0], weight[0], float(pdf[0])
        return wi, weight, pdf


class FileModel(Model):
    """The model of one ``.brdf`` file (``load``): the registry's interface, with ``eval`` running
    the file's GLSL; ``bfile`` is the parsed file, ``twin`` its numpy twin module or None."""

    @property
    def bfile(self):
        return self.module.source_file

    @property
    def twin(self):
        return self.module.numpy_twin

    @property
    def twin_not_run(self) -> str | None:
        """The line saying that the file's twin exists but was not run (the user has not trusted
        it: ``viewer.brdf.twin_trust``), else None."""
        return self.module.twin_not_run

    @property
    def sampled_by(self) -> str | None:
        """"numpy twin", "isFunc" or None (the generic cosine-weighted sampler)."""
        return self.module.sampled_by

    def __repr__(self):
        return f"<brdf file {self.bfile.path.name}>"

    def params(self, **values) -> Params:
        values.setdefault("file", str(self.bfile.path))
        return super().params(**values)

    def numpy_model(self) -> Model:
        """The model the CPU reference evaluates: the numpy twin (its sampler, or cosine-weighted
        sampling); a one-line ViewerError when the file has no twin."""
        if self.module.numpy_module is None:
            if self.module.twin_not_run:
                twin = self.bfile.path.with_suffix(".py")
                raise ViewerError(f"{self.bfile.path.name}: the cpu engine evaluates numpy twins and {twin.name} was "
                                  f"not run (not trusted); use --engine gpu or auto, or --trust-twin {twin}")
            raise ViewerError(f"{self.bfile.path.name}: the cpu engine evaluates numpy twins and this file has none "
                              f"({self.bfile.path.with_suffix('.py').name} beside it); use --engine gpu or auto")
        return Model(self.module.numpy_module, where=self.bfile.path.with_suffix(".py").name)

    def twin_eval(self, p, wi, wo):
        """f from the numpy twin (a ViewerError when the file has none)."""
        if self.module.twin_eval is None:
            if self.module.twin_not_run:
                raise ViewerError(self.module.twin_not_run)
            raise ViewerError(f"{self.bfile.path.name}: no numpy twin {self.bfile.path.with_suffix('.py').name} "
                              f"beside it")
        wi, wo, single = _dirs(wi, wo)
        f = self.module.twin_eval(self._p(p), wi, wo)
        return f[0] if single else f


def load(path) -> FileModel:
    """The model of a BRDF Explorer ``.brdf`` file (and its numpy twin ``NAME.py`` beside it)."""
    from viewer.brdf import file_model

    return file_model.load(path, FileModel)


def _sample_args(wo, u):
    wo = np.asarray(wo, dtype=np.float64)
    u = np.asarray(u, dtype=np.float64)
    single = wo.ndim == 1 and u.ndim == 1
    n = max(np.atleast_2d(wo).shape[0], np.atleast_2d(u).shape[0])
    wo2 = np.broadcast_to(np.atleast_2d(wo), (n, 3)).copy()
    u2 = np.broadcast_to(np.atleast_2d(u), (n, 2)).copy()
    return wo2, u2, single


def fresnel_source_by_names(p) -> dict | None:
    """The default ``fresnel_source``: a scalar ``ior`` (dielectric), or ``eta`` and ``k``
    (conductor), else None."""
    if "ior" in p and np.ndim(p["ior"]) == 0:
        return {"type": "dielectric", "ior": float(p["ior"]), "field": "ior"}
    if "eta" in p and "k" in p:
        return {"type": "conductor", "eta": np.asarray(p["eta"], float), "k": np.asarray(p["k"], float),
                "field": "eta, k"}
    return None


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


class CustomModel(Model):
    """``get("custom")``: the scene files' model of file BRDFs. Its functions take the file from
    the parameters (``p.file``, an absolute path once validated) and run that file's model."""

    def __init__(self):
        from viewer.brdf.file_model import CUSTOM_SPEC

        spec = CUSTOM_SPEC
        super().__init__(_CustomModule(SPEC=spec, eval=lambda p, wi, wo: self.of(p).module.eval(p, wi, wo),
                                       sample=lambda p, wo, u: self.of(p).module.sample(p, wo, u),
                                       pdf=lambda p, wi, wo: self.of(p).module.pdf(p, wi, wo)), where="custom")

    @staticmethod
    def of(p) -> FileModel:
        """The file model of parameters ``p`` (with a ``file``)."""
        if p is None or not p.get("file"):
            raise ViewerError("model 'custom': give file = \"NAME.brdf\" (a BRDF Explorer file)")
        from viewer.brdf import file_model

        return file_model.load_or_last_good(p["file"], FileModel)

    def params(self, **values) -> Params:
        return self.of(values).params(**values)

    def lobes(self, p=None) -> Lobe:
        if p is None or not p.get("file"):  # no file yet: a file BRDF reflects, smoothly
            return lobes.declared(False, False)
        return self.of(p).lobes(p)

    def fresnel_source(self, p=None):
        return self.of(p).fresnel_source(p)

    def sample_lobe(self, p, wo, u):
        return self.of(p).sample_lobe(p, wo, u)


class _CustomModule:
    def __init__(self, **kw):
        self.__dict__.update(kw)


_CUSTOM: CustomModel | None = None


def is_file(params) -> bool:
    """``params`` is a material drawn from a ``.brdf`` file (the one question about a material
    that the rest of the program asks by model, answered here)."""
    from viewer.brdf.file_model import CUSTOM

    return params is not None and getattr(params, "model", None) == CUSTOM


def get(name: str) -> Model:
    global _CUSTOM
    if name == "custom":
        if _CUSTOM is None:
            _CUSTOM = CustomModel()
        return _CUSTOM
    try:
        return _registry()[name]
    except KeyError:
        shown = repr(name) if len(repr(name)) <= 60 else repr(name)[:57] + "..."
        raise ViewerError(f"unknown BRDF model {shown}; allowed: {', '.join(names())}") from None


def spec_of(p) -> ModelSpec:
    """The spec of a material's parameters: its model's, or for a file BRDF (``custom``) the
    file's (its declarations and ``file``)."""
    if p.model == "custom":
        return CustomModel.of(p).spec
    return get(p.model).spec


def lookup_spec(name, where: str = "model") -> ModelSpec:
    """The spec of ``name`` or a ViewerError naming ``where`` and the allowed names."""
    reg = _registry()
    if name == "custom":
        raise ViewerError(f"{where}: model 'custom' (a .brdf file) is a material of its own; it cannot be "
                          f"nested in another material")
    if name not in reg:
        shown = repr(name) if len(repr(name)) <= 60 else repr(name)[:57] + "..."   # never a 100 KB name whole
        raise ViewerError(f"{where}: unknown model {shown}; allowed: {', '.join(reg)}")
    return reg[name].spec


def __getattr__(attr):
    # The Fresnel functions live apart from the models that call them (pbrt's layout).
    if attr.startswith("fresnel_"):
        from viewer.brdf import fresnel

        return getattr(fresnel, attr)
    raise AttributeError(attr)


__all__ = ["spec_of", "CustomModel", "FileModel", "load", "Model", "ModelSpec", "Param", "Params", "get", "names", "lookup_spec"]
