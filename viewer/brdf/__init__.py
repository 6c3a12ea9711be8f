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
from viewer.brdf import lobes, thin_film, wavelengths
from viewer.brdf.lobes import Lobe
from viewer.brdf.spec import HOOKS, ModelSpec, Param, Params, check_module, validate_params

# The course's order (the lecture's order of families); discovered extras follow alphabetically.
ORDER = ("lambert", "phong", "blinn_phong", "microfacet", "oren_nayar", "lafortune",
         "ashikhmin_shirley", "layered", "mirror", "dielectric")

_HELPERS = {"spec", "lobes", "mit_aniso", "bparam", "brdffile", "file_model", "report_card", "fresnel", "microfacet_dist",
            "microfacet_walk", "sampling", "presets", "albedo", "spectral_fresnel", "thin_film", "merl", "fit", "chi2",
            "wavelengths", "layered_walk", "file_sampler", "ms_compensation"}
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

    # -- the material predicates (viewer.brdf.spec.HOOKS): the hook answers for p's own values,
    #    a nested material (a layered base) is asked through its own model
    def _nested(self, p):
        return [p[prm.name] for prm in self.spec.params if prm.kind == "material" and p.get(prm.name) is not None]

    def _ask(self, name, p, default=False) -> bool:
        p = self._p(p)
        fn = self.hook(name)
        if bool(fn(p)) if fn is not None else default:
            return True
        return any(getattr(get(v.model), name)(v) for v in self._nested(p))

    def has_film(self, p=None) -> bool:
        """``p`` carries an active thin film: its own or its coating's, thicker than 0 at the
        object's bottom or top (``thin_film.active``, the one definition)."""
        p = self._p(p)
        fn = self.hook("has_film")
        return bool(fn(p)) if fn is not None else thin_film.active(p)

    def is_dispersive(self, p=None) -> bool:
        """Light refracts through ``p`` by n(lambda) (a spectral dielectric or coat, or base)."""
        return self._ask("is_dispersive", p)

    def uses_spectral(self, p=None) -> bool:
        """``p``'s values depend on the wavelength (a spectral table, a thin film), here or in a
        nested material: the spectral reference evaluates it at each path's wavelengths."""
        p = self._p(p)
        fn = self.hook("uses_spectral")
        own = bool(fn(p)) if fn is not None else wavelengths.uses_spectral_by_names(p) or self.has_film(p)
        return own or any(get(v.model).uses_spectral(v) for v in self._nested(p))

    def walks(self, p=None) -> bool:
        """The CPU reference evaluates ``p`` (or its nested base) by a stochastic random walk."""
        return self._ask("walks", p)

    def is_measured(self, p=None) -> bool:
        """``p`` is (or nests) a measured table."""
        return self._ask("is_measured", p)

    def reference_model(self, p=None):
        """The model the CPU reference evaluates ``p`` with (the hook's stand-in, else self)."""
        fn = self.hook("reference_model")
        return fn(self, self._p(p)) if fn is not None else self

    def params_at(self, p, lam3) -> Params:
        """``p`` at three wavelengths ``lam3`` (nm) as its three channels (the hook, else by
        parameter names: ``viewer.brdf.wavelengths.params_at``)."""
        p = self._p(p)
        fn = self.hook("params_at")
        if fn is not None:
            return fn(p, lam3)
        return wavelengths.params_at(p, lam3, nested=lambda v, lam: get(v.model).params_at(v, lam))

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

    def terms(self, p, wi, wo) -> dict | None:
        """The factors of ``p``'s microfacet lobe at (N, 3) ``wi``, ``wo`` (the ``terms`` hook:
        D, F, G, 1/(4 cos cos) and what f adds to their product), or None where it has none."""
        fn = self.hook("terms")
        if fn is None:
            return None
        wi, wo, _ = _dirs(wi, wo)
        return fn(self._p(p), wi, wo)

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

    def terms(self, p, wi, wo):
        return self.of(p).terms(p, wi, wo)


class _CustomModule:
    def __init__(self, **kw):
        self.__dict__.update(kw)


_CUSTOM: CustomModel | None = None


def is_file(params) -> bool:
    """``params`` is a material drawn from a ``.brdf`` file (the one question about a material
    that the rest of the program asks by model, answered here)."""
    from viewer.brdf.file_model import CUSTOM

    return params is not None and getattr(params, "model", None) == CUSTOM


def is_file_model(name) -> bool:
    """``name`` (a material table's ``model`` as written) is the model of ``.brdf`` files."""
    from viewer.brdf.file_model import CUSTOM

    return name == CUSTOM


def path_params(name) -> tuple[str, ...]:
    """The file parameters (kind ``path``) of the registry model ``name`` as written in a
    material table, which a scene resolves against its folder; () for a ``.brdf`` file's model
    (its ``file`` is resolved when the file is loaded) or an unknown name."""
    if not isinstance(name, str) or is_file_model(name) or name not in _registry():
        return ()
    return tuple(p.name for p in _registry()[name].spec.params if p.kind == "path")


def model_of(params) -> Model:
    """The model of a material's parameters (``get(params.model)``)."""
    return get(params.model)


def is_delta(params) -> bool:
    """Every lobe of the material is a delta lobe (what a traced chain follows)."""
    return get(params.model).is_delta(params)


def has_film(params) -> bool:
    """The material carries an active thin film (its own or its coating's, at the object's
    bottom or top): its model's ``has_film``."""
    return get(params.model).has_film(params)


def is_dispersive(params) -> bool:
    """Light refracts through the material by n(lambda): its model's ``is_dispersive``."""
    return get(params.model).is_dispersive(params)


def uses_spectral(params) -> bool:
    """The material's values depend on the wavelength: its model's ``uses_spectral``."""
    return get(params.model).uses_spectral(params)


def walks(params) -> bool:
    """The CPU reference evaluates the material by a random walk: its model's ``walks``."""
    return get(params.model).walks(params)


def is_measured(params) -> bool:
    """The material is (or nests) a measured table: its model's ``is_measured``."""
    return get(params.model).is_measured(params)


def lambertian_albedo(params):
    """The RGB albedo where the material reflects as a Lambert surface, else None: its model's
    ``lambertian_albedo`` hook."""
    fn = get(params.model).hook("lambertian_albedo")
    return None if fn is None else fn(params)


def params_at(params, lam3) -> Params:
    """The material at three wavelengths ``lam3`` (nm): its model's ``params_at``."""
    return get(params.model).params_at(params, lam3)


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


__all__ = ["spec_of", "has_film", "is_dispersive", "uses_spectral", "walks", "is_measured", "params_at",
           "is_delta", "is_file", "is_file_model", "path_params", "model_of",
           "CustomModel", "FileModel", "load", "Model", "ModelSpec", "Param", "Params", "get", "names", "lookup_spec"]
