"""BRDF specs: the single description of a model's parameters.

A spec drives the GUI sliders, scene-file validation, ``brdf-viewer models``, plot axes and the
GLSL parameter block (see ``viewer.gl.brdf_glsl``). Every family module in this package defines
``SPEC`` plus numpy ``eval(p, wi, wo)``, ``sample(p, wo, u)`` and ``pdf(p, wi, wo)``; the
GLSL twin lives in ``shaders/brdf/<name>.glsl``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from viewer import ViewerError

KINDS = ("rgb", "float", "choice", "lobes", "table", "material", "path", "bool")


@dataclass(frozen=True)
class Param:
    """One parameter of a model.

    kind:
      rgb      3 floats (linear RGB); a scalar in a scene file means grey
      float    1 float
      choice   one of ``choices`` (strings); the GLSL side gets its index as an int
      bool     true or false, or 1 or 0 as a .brdf file writes them (the GLSL side gets a bool)
      lobes    a list of up to ``max_items`` tables whose fields are ``fields``
      table    a sub-table whose fields are ``fields`` (e.g. the layered model's coating)
      material another material table (any model except those with a ``material`` param)
      path     a file name (a string; no GLSL field: the renderer binds what the file holds)
    lo, hi: the allowed range (inclusive) of a float and of each rgb component.
    ui_lo, ui_hi: the slider range when narrower than the allowed range; log: log-scale slider.
    """

    name: str
    kind: str
    default: Any
    doc: str = ""
    unit: str = ""
    lo: float | None = None
    hi: float | None = None
    choices: tuple[str, ...] = ()
    fields: tuple["Param", ...] = ()
    max_items: int = 4
    ui_lo: float | None = None
    ui_hi: float | None = None
    log: bool = False
    # a choice of viewer.spectral material whose RGB Fresnel table the GLSL block carries
    spectral_table: bool = False
    # path: check(value, where) raises ViewerError when the file is unusable
    check: object = None
    # fills(value) -> {name: value}: the parameters beside it that its value implies where the
    # file does not give them (a spectral table's ior, eta and k: viewer/brdf/spectral_fresnel.py)
    fills: object = None

    def __post_init__(self):
        assert self.kind in KINDS, self.kind

    @property
    def slider_range(self) -> tuple[float, float]:
        lo = self.ui_lo if self.ui_lo is not None else self.lo
        hi = self.ui_hi if self.ui_hi is not None else self.hi
        return (0.0 if lo is None else lo, 1.0 if hi is None else hi)

    def allowed(self) -> str:
        """Human-readable description of what this parameter accepts."""
        if self.kind == "choice":
            return "one of " + ", ".join(repr(c) for c in self.choices)
        if self.kind in ("float", "rgb"):
            rng = f"in [{_fmt(self.lo)}, {_fmt(self.hi)}]"
            return ("a number " if self.kind == "float" else "3 numbers (or one for grey) each ") + rng
        if self.kind == "lobes":
            return f"a list of up to {self.max_items} tables with keys " + ", ".join(f.name for f in self.fields)
        if self.kind == "table":
            return "a table with keys " + ", ".join(f.name for f in self.fields)
        if self.kind == "path":
            return "a file name (a string)"
        if self.kind == "bool":
            return "true or false"
        return "a material table with a 'model' key"


def _fmt(v):
    if v is None:
        return "-inf"
    return f"{v:g}"


@dataclass(frozen=True)
class ModelSpec:
    name: str
    title: str
    params: tuple[Param, ...]
    source: str  # the paper(s) and equation(s) implemented
    doc: str = ""
    reciprocal: bool = True
    reciprocal_why: str = ""  # why not, when reciprocal is False
    # delta lobes (perfect mirror / smooth glass) and transmission, as declared: the default of
    # the ``lobes`` hook (viewer/brdf/lobes.py), which a model computes from its parameters
    delta: bool = False
    transmissive: bool = False
    # aliases: a key a user may write that sets several parameters, e.g. alpha -> alpha_x, alpha_y
    aliases: dict = field(default_factory=dict)
    # values derived from the parameters that the GLSL twin reads as ``float derived[N]`` after
    # the parameters (e.g. a table precomputed in numpy): derived(params) -> N floats
    derived: object = None
    derived_size: int = 0
    # how many of them the struct copies (None: all); the GLSL reads the rest from the material
    # block at ``p.derived_at + i`` (software GL turns every dynamic index into a local array into a
    # chain over all its elements, so a long table is read from the uniforms instead)
    derived_copy: int | None = None

    def param(self, name: str) -> Param:
        for p in self.params:
            if p.name == name:
                return p
        raise KeyError(name)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.params)

    @property
    def nests_material(self) -> bool:
        return any(p.kind == "material" for p in self.params)


class Params(dict):
    """Validated parameter values of one model; attribute access (``p.alpha``) and ``p.model``.

    rgb values are float64 arrays of shape (3,); floats are Python floats; choices are strings;
    lobes are lists of Params; tables are Params; materials are Params with their own ``model``.
    """

    def __init__(self, model: str, values: dict):
        super().__init__(values)
        object.__setattr__(self, "model", model)

    def __getattr__(self, key):
        try:
            return self[key]
        except KeyError:
            raise AttributeError(key) from None

    def __setattr__(self, key, value):
        self[key] = value

    def replace(self, **kw) -> "Params":
        d = dict(self)
        d.update(kw)
        return Params(self.model, d)

    def to_plain(self) -> dict:
        """JSON/TOML-friendly copy (lists instead of arrays), including the model name."""
        out = {"model": self.model}
        out.update({k: _plain(v) for k, v in self.items()})
        return out


def _plain(v):
    if isinstance(v, Params):
        d = v.to_plain()
        if v.model in ("", None):
            d.pop("model")
        return d
    if isinstance(v, np.ndarray):
        return [float(x) for x in v]
    if isinstance(v, list):
        return [_plain(x) for x in v]
    return v


def _is_number(x) -> bool:
    return isinstance(x, (int, float, np.integer, np.floating)) and not isinstance(x, bool)


def _show(value, n: int = 60) -> str:
    """A value for a message, cut to ``n`` characters (a scene may hold huge values)."""
    if isinstance(value, int) and not isinstance(value, bool) and abs(value) >= 10 ** 15:
        return "%.3g" % value if abs(value) < 10 ** 300 else "a huge integer"
    try:
        text = repr(value)
    except ValueError:  # e.g. an integer of more than 4300 digits inside a list
        text = f"a {type(value).__name__}"
    return text if len(text) <= n else text[: n - 3] + "..."


def _float(x) -> float:
    try:
        return float(x)
    except OverflowError:  # an integer beyond any float: out of every range
        return math.inf if x > 0 else -math.inf


def validate_value(param: Param, value, where: str, lookup_spec=None):
    """Check one value against its Param; return the normalized value or raise ViewerError.

    ``where`` names the field for the message (e.g. ``scene.toml: materials.ball.alpha``).
    """
    k = param.kind
    if k == "float":
        if not _is_number(value):
            raise ViewerError(f"{where}: expected {param.allowed()}, got {_show(value)}")
        v = _float(value)
        if not math.isfinite(v) or (param.lo is not None and v < param.lo) or (param.hi is not None and v > param.hi):
            raise ViewerError(f"{where}: {v:g} is out of range; allowed: {param.allowed()}")
        return v
    if k == "rgb":
        if _is_number(value):
            value = [value] * 3
        if isinstance(value, np.ndarray):
            value = value.tolist()
        if not isinstance(value, (list, tuple)) or len(value) != 3 or not all(_is_number(x) for x in value):
            raise ViewerError(f"{where}: expected {param.allowed()}, got {_show(value)}")
        arr = np.array([_float(x) for x in value], dtype=np.float64)
        bad = (~np.isfinite(arr)) | ((arr < param.lo) if param.lo is not None else False) | (
            (arr > param.hi) if param.hi is not None else False)
        if np.any(bad):
            shown = ", ".join(f"{float(x):g}" for x in np.ravel(arr))
            raise ViewerError(f"{where}: [{shown}] is out of range; allowed: {param.allowed()}")
        return arr
    if k == "path":
        if not isinstance(value, str):
            raise ViewerError(f"{where}: expected {param.allowed()}, got {_show(value)}")
        if param.check is not None:
            param.check(value, where)
        return value
    if k == "bool":
        if isinstance(value, (int, np.integer)) and not isinstance(value, bool) and value in (0, 1):
            return bool(value)  # 0 / 1, as a .brdf file writes its bools (and --set use_diffuse=0)
        if not isinstance(value, (bool, np.bool_)):
            raise ViewerError(f"{where}: expected {param.allowed()}, got {_show(value)}")
        return bool(value)
    if k == "choice":
        if value not in param.choices:
            raise ViewerError(f"{where}: {_show(value)} is not allowed; allowed: {param.allowed()}")
        return str(value)
    if k == "table":
        if not isinstance(value, dict):
            raise ViewerError(f"{where}: expected {param.allowed()}, got {_show(value)}")
        return validate_fields(param.fields, value, where, model="")
    if k == "lobes":
        if not isinstance(value, (list, tuple)) or not (1 <= len(value) <= param.max_items):
            raise ViewerError(f"{where}: expected {param.allowed()}, got {_show(value)}")
        out = []
        for i, item in enumerate(value):
            if not isinstance(item, dict):
                raise ViewerError(f"{where}[{i}]: expected a table with keys "
                                  + ", ".join(f.name for f in param.fields))
            out.append(validate_fields(param.fields, item, f"{where}[{i}]", model=""))
        return out
    if k == "material":
        if isinstance(value, Params):
            return value
        if not isinstance(value, dict) or "model" not in value:
            raise ViewerError(f"{where}: expected {param.allowed()}, got {_show(value)}")
        if lookup_spec is None:
            raise ViewerError(f"{where}: nested materials need the registry")
        sub = dict(value)
        name = sub.pop("model")
        spec = lookup_spec(name, f"{where}.model")
        if spec.nests_material:
            raise ViewerError(f"{where}.model: {name!r} cannot be nested inside another layered material")
        out = validate_params(spec, sub, where, lookup_spec)
        if film_table_active(out.get("thin_film")):
            # the film's wavelength loop, inlined at each of the coat model's calls of its base,
            # takes software GL minutes to compile (measured: 379 s); films go on outer surfaces
            raise ViewerError(f"{where}.thin_film: a thin film on a nested base material is not supported; "
                              f"set thickness_nm = 0 (and thickness_top_nm = -1) there (films go on the outer surface)")
        return out
    raise AssertionError(k)


def film_table_active(tf) -> bool:
    """Whether a ``thin_film`` table (viewer/brdf/thin_film.py) is thicker than 0 at the object's
    bottom (``thickness_nm``) or top (``thickness_top_nm``): the one test of an active film, which
    ``thin_film.active`` (a material's own film or its coating's) applies; here, below the models,
    since validation refuses a film on a nested material by it."""
    return tf is not None and max(float(tf.get("thickness_nm", 0.0)), float(tf.get("thickness_top_nm", -1.0))) > 0.0


def validate_fields(fields, raw: dict, where: str, model: str, aliases=None, lookup_spec=None) -> Params:
    names = [f.name for f in fields]
    raw = dict(raw)
    for alias, targets in (aliases or {}).items():
        if alias in raw:
            v = raw.pop(alias)
            for t in targets:
                if t in raw:
                    raise ViewerError(f"{where}.{alias}: give either {alias!r} or {'/'.join(targets)}, not both")
                raw[t] = v
    for key in raw:
        if key not in names:
            allowed = names + list((aliases or {}).keys())
            what = f"model {model!r}" if model else "this table"
            key = key if len(key) <= 40 else key[:37] + "..."
            raise ViewerError(f"{where}.{key}: unknown parameter of {what}; allowed: {', '.join(allowed)}")
    out = {}
    for f in fields:
        if f.name in raw:
            out[f.name] = validate_value(f, raw[f.name], f"{where}.{f.name}", lookup_spec)
        else:
            out[f.name] = default_value(f, lookup_spec)
    for f in fields:
        if f.fills is not None:
            for key, value in f.fills(out[f.name]).items():
                if key in names and key not in raw:
                    out[key] = value
    return Params(model, out)


def default_value(f: Param, lookup_spec=None):
    """The validated default of one parameter (an array for rgb, tables validated)."""
    d = f.default
    if f.kind == "rgb":
        return np.array(d if isinstance(d, (list, tuple)) else [d] * 3, dtype=np.float64)
    if f.kind == "table":
        return validate_fields(f.fields, dict(d or {}), f.name, "")
    if f.kind == "lobes":
        return [validate_fields(f.fields, dict(x), f.name, "") for x in d]
    if f.kind == "material":  # needs the registry's lookup_spec (viewer.brdf.lookup_spec)
        return validate_value(f, dict(d), f.name, lookup_spec)
    return d


def validate_params(spec: ModelSpec, raw: dict, where: str, lookup_spec=None) -> Params:
    """Validate a material table (without its 'model' key) against a spec; fill defaults."""
    return validate_fields(spec.params, raw, where, spec.name, spec.aliases, lookup_spec)


# ----------------------------------------------------------------------------- the model protocol


class BRDFModule(Protocol):
    """What a model module (a family of this package, or a ``.brdf`` file's model) provides.

    Required: ``SPEC`` (a ``ModelSpec``) and numpy ``eval(p, wi, wo)``, ``sample(p, wo, u)``,
    ``pdf(p, wi, wo)`` over (N, 3) direction arrays in the shading frame (z = normal; wi toward
    the light, wo toward the viewer; f without the cosine; u (N, 2) uniform). ``sample`` returns
    ``(wi, weight, pdf)`` with weight = f cos / pdf (0 where it fails). Every optional hook of
    ``HOOKS`` may be defined beside them; ``check_module`` rejects a misspelled one.
    """

    SPEC: ModelSpec

    def eval(self, p: Params, wi: np.ndarray, wo: np.ndarray) -> np.ndarray: ...

    def sample(self, p: Params, wo: np.ndarray, u: np.ndarray) -> tuple: ...

    def pdf(self, p: Params, wi: np.ndarray, wo: np.ndarray) -> np.ndarray: ...


@dataclass(frozen=True)
class Hook:
    """One optional hook of a model module: a function (``args`` names its arguments) or a value,
    and what the registry does when the module leaves it out (``default``)."""

    name: str
    kind: str  # "function" | "value"
    args: tuple[str, ...]
    default: str
    doc: str


REQUIRED = {"eval": ("p", "wi", "wo"), "sample": ("p", "wo", "u"), "pdf": ("p", "wi", "wo")}

HOOKS = {h.name: h for h in (
    Hook("lobes", "function", ("p",), "SPEC.delta (else glossy), reflection and, when SPEC.transmissive, "
         "transmission (viewer.brdf.lobes.declared), with the kinds of a nested material",
         "the Lobe flags of p (viewer/brdf/lobes.py): every lobe the sampler may draw, computed from p"),
    Hook("has_film", "function", ("p",), "thin_film.active: its own thin_film or its coating's, thicker than 0 "
         "at the object's bottom or top",
         "True when p carries an active thin film (its own or a table parameter's, e.g. a layered coating's): "
         "the film the renderers trace somewhere on the object (at a point its local thickness applies)"),
    Hook("is_dispersive", "function", ("p",), "False (nested materials are asked through their own model)",
         "True when light refracts through p by n(lambda) (a spectral dielectric, a spectral coat): "
         "a spectral reference traces one wavelength per path there"),
    Hook("uses_spectral", "function", ("p",), "by parameter names: spectral != 'none' in p or a table of it, "
         "or has_film(p) (nested materials through their own model)",
         "True when p's values depend on the wavelength (a spectral table, a thin film): the spectral "
         "reference evaluates it at each path's wavelengths"),
    Hook("walks", "function", ("p",), "False (nested materials through their own model)",
         "True when the CPU reference evaluates p by a stochastic random walk (microfacet multiple "
         "scattering, the layered random walk), which only the cpu engine has"),
    Hook("reference_model", "function", ("model", "p"), "model",
         "the model the CPU reference evaluates p with: a stochastic stand-in (the layered random walk) "
         "for the registry's model, else that model"),
    Hook("is_measured", "function", ("p",), "False (nested materials through their own model)",
         "True when p is a measured table (MERL), which only the cpu engine renders"),
    Hook("params_at", "function", ("p", "lam3"), "by parameter names (viewer.brdf.wavelengths.params_at)",
         "p at three wavelengths lam3 (nm) as its three channels: spectral tables give eta, k = n, k "
         "there (ior = n(lam3[0])), a thin film evaluates there, RGB values are upsampled"),
    Hook("sample_lobe", "function", ("p", "wo", "u"), "sample(p, wo, u) plus lobes.by_side: the model's "
         "kind (delta when lobes(p) is delta, else its smooth kinds) on the side each sample went to",
         "(wi, weight, pdf, lobe): sample's result and, per sample, the Lobe it drew (a delta one gets "
         "no light sampling, no MIS); needed by models that mix delta and smooth lobes"),
    Hook("fresnel_source", "function", ("p",), "by parameter names: ior, or eta and k, else None",
         "how p's Fresnel reflectance is given, for the Fresnel plot: {'type': 'dielectric', 'ior', "
         "'field'} | {'type': 'conductor', 'eta', 'k', 'field'} | {'type': 'schlick', 'f0', 'field'} | None"),
    Hook("ibl_split", "function", ("p",), "None (no specular part: diffuse image-based lighting)",
         "(specular params, alpha[, diffuse albedo]): the part the split-sum prefilter serves and its width"),
    Hook("lambertian_albedo", "function", ("p",), "None (not a Lambert reflector)",
         "the RGB albedo where p reflects as a Lambert surface (f = albedo / pi everywhere), else None: "
         "what the raster's thin shells see of a floor in their reflections"),
    Hook("splits_u", "function", ("p",), "False",
         "True when sample splits u[:, 0] into a lobe choice and a continuous part (split_uniform)"),
    Hook("eval_mean", "function", ("p", "wi", "wo"), "eval",
         "the mean of a stochastic eval, for the plots"),
    Hook("energy_conserving", "function", ("p",), "p unchanged",
         "p moved into the range where the model conserves energy (the tests' plausible sets)"),
    Hook("TEST_PARAMS", "value", (), "the defaults plus a rough and a sharp set by parameter names",
         "{label: parameter dict}: the sets the chi-square and furnace tests use"),
    Hook("GLSL_RTOL", "value", (), "1e-4", "the relative tolerance of the GLSL twin against numpy"),
    Hook("ALBEDO_BOUND", "value", (), "1.0", "the largest directional albedo the model may reach"),
    Hook("ALBEDO_BOUND_WHY", "value", (), "''", "why ALBEDO_BOUND exceeds 1 (required when it does)"),
    Hook("terms", "function", ("p", "wi", "wo"), "None (no term decomposition)",
         "the factors of a microfacet lobe, for the term view: {'D': (N,), 'F': (N, 3), 'G': (N,), "
         "'1/(4 cos cos)': (N,)} whose product is the lobe (and 'other': (N, 3), what f adds to it, "
         "e.g. a diffuse base), or None where p has no such decomposition"),
)}


def _public_names(module) -> dict:
    """The module's own public names (not imported ones, not submodules)."""
    import types

    own = getattr(module, "__name__", None)
    out = {}
    for key, value in vars(module).items():
        if key.startswith("_") or isinstance(value, types.ModuleType):
            continue
        if callable(value) and getattr(value, "__module__", own) != own:
            continue  # imported
        out[key] = value
    return out


def check_module(module, where: str | None = None) -> None:
    """Check a model module against the protocol: SPEC, eval / sample / pdf with their arguments,
    and every hook's kind and arguments; a public name within a letter or two of a hook's (or a
    required function's) name is a misspelled hook. Raises ViewerError naming the module."""
    import difflib
    import inspect

    where = where or getattr(module, "__name__", "model")
    if not isinstance(getattr(module, "SPEC", None), ModelSpec):
        raise ViewerError(f"{where}: a model module needs SPEC = ModelSpec(...)")

    def check_args(name, fn, args):
        if not callable(fn):
            raise ViewerError(f"{where}: {name} must be a function of ({', '.join(args)})")
        try:
            sig = inspect.signature(fn)
        except (TypeError, ValueError):
            return
        try:
            sig.bind(*args)
        except TypeError:
            raise ViewerError(f"{where}: {name}{sig} must take ({', '.join(args)})") from None

    for name, args in REQUIRED.items():
        if not hasattr(module, name):
            raise ViewerError(f"{where}: a model module needs {name}({', '.join(args)})")
        check_args(name, getattr(module, name), args)
    known = set(HOOKS) | set(REQUIRED) | {"SPEC"}
    for name, value in _public_names(module).items():
        if name in HOOKS:
            hook = HOOKS[name]
            if hook.kind == "function":
                check_args(name, value, hook.args)
            elif callable(value):
                raise ViewerError(f"{where}: {name} is a value ({hook.doc}), not a function")
            continue
        if name in known:
            continue
        close = difflib.get_close_matches(name.lower(), [k.lower() for k in known], n=1, cutoff=0.84)
        if close:
            real = next(k for k in known if k.lower() == close[0])
            raise ViewerError(f"{where}: {name!r} is not a hook of the model protocol; did you mean {real!r}? "
                              f"(hooks: {', '.join(sorted(HOOKS))})")
