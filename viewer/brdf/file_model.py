"""A ``.brdf`` file as a model with the registry's interface (``viewer.brdf.load``).

The file's GLSL is the model: ``eval`` runs it (on an offscreen GL context, through the
evaluator the GL side provides: ``viewer.gl.file_brdf``; this package imports no GL, so the
evaluator is found through ``viewer.file_brdf_evaluator()``, the top-level package's wiring, or
set with ``set_glsl_evaluator``). A numpy twin ``NAME.py`` beside ``NAME.brdf`` with
``eval(p, wi, wo)`` (and optionally ``sample(p, wo, u)`` with ``pdf(p, wi, wo)``) in the shading
frame of the conventions is what the CPU reference evaluates, and the report card compares the
two; it is Python from the file's author and runs only once the user trusts it
(``viewer.brdf.twin_trust``, which also runs it guarded). Sampling: the twin's sampler when it has one, else the file's ``isFunc`` sampler (GLSL), else
cosine-weighted sampling (pdf cos / pi), which works for any BRDF.

Parameters: the file's declarations (``float`` a number in its range, ``bool``, ``color`` an RGB
value of 3 numbers >= 0) plus ``file`` (the path). ``Params.model`` is ``"custom"``, the scene
files' model name for file BRDFs.
"""

from __future__ import annotations

import types
from pathlib import Path

import numpy as np

from viewer import ViewerError
from viewer.brdf import twin_trust
from viewer.brdf.brdffile import TERM_NAMES, BrdfFile, parse, term_functions
from viewer.brdf.spec import ModelSpec, Param

#: the scene files' model name of a file BRDF
CUSTOM = "custom"
INV_PI = 1.0 / np.pi
_EVALUATOR = None
#: the spec of get("custom") before a file is known (a file's own spec adds its declarations)
CUSTOM_SPEC = ModelSpec(name=CUSTOM, title="a BRDF Explorer .brdf file",
                        params=(Param("file", "path", "", "the .brdf file (relative to the scene file)"),),
                        source="the file", doc="a BRDF Explorer .brdf file and its declared parameters")


def set_glsl_evaluator(evaluator) -> None:
    """Set the object that runs a file's GLSL: ``evaluator.eval(bfile, params, wi, wo)`` -> (N, 3)
    and ``evaluator.sample(bfile, params, wo, u)`` -> (wi, weight, pdf); None: back to the default
    (``viewer.file_brdf_evaluator()``)."""
    global _EVALUATOR
    _EVALUATOR = evaluator


_PROBE = None


def set_file_probe(probe) -> None:
    """Set the function that vets a parsed file before its model is made: ``probe(bfile)`` raises
    a one-line ViewerError to refuse it; None: back to the default (``viewer.file_brdf_probe()``,
    the compile and a tiny render in a child process with a time and a memory limit)."""
    global _PROBE
    _PROBE = probe


def file_probe():
    global _PROBE
    if _PROBE is None:
        from viewer import file_brdf_probe

        _PROBE = file_brdf_probe()
    return _PROBE


def glsl_evaluator():
    global _EVALUATOR
    if _EVALUATOR is None:
        from viewer import file_brdf_evaluator

        _EVALUATOR = file_brdf_evaluator()
    return _EVALUATOR


def _colour_hi(d) -> float:
    return max(1.0, *d.default)


def params_of(bfile: BrdfFile) -> tuple[Param, ...]:
    out = [Param("file", "path", str(bfile.path), "the .brdf file (relative to the scene file in a scene)")]
    for d in bfile.declarations:
        doc = f"declared on line {d.line} of {bfile.path.name}"
        if d.kind == "float":
            out.append(Param(d.name, "float", float(d.default), doc, lo=d.lo, hi=d.hi))
        elif d.kind == "bool":
            out.append(Param(d.name, "bool", bool(d.default), doc))
        else:
            out.append(Param(d.name, "rgb", list(d.default), doc, lo=0.0, hi=_colour_hi(d)))
    return tuple(out)


def load_twin(path: Path):
    """The numpy twin module ``NAME.py`` beside ``NAME.brdf``, or None when there is none or the
    user has not trusted it (``viewer.brdf.twin_trust``: then one line says it was not run). A
    trusted twin is first tried in a child process within a time limit; a twin that cannot be
    imported, misbehaves there or lacks ``eval(p, wi, wo)`` is a one-line ViewerError."""
    twin = twin_trust.twin_of(path)
    if not twin.is_file():
        return None
    if not twin_trust.is_trusted(twin):
        twin_trust.untrusted(path, twin)
        return None
    twin_trust.probe(twin, path)
    return twin_trust.import_twin(twin)


def _upper(wi, wo):
    return (wi[:, 2] > 0) & (wo[:, 2] > 0)


def cosine_sample(u):
    """Cosine-weighted directions (Malley's method) and their pdf cos / pi."""
    r = np.sqrt(u[:, 0])
    phi = 2.0 * np.pi * u[:, 1]
    z = np.sqrt(np.maximum(0.0, 1.0 - u[:, 0]))
    wi = np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)
    return wi, z * INV_PI


class FileModule(types.SimpleNamespace):
    """The protocol's module for one ``.brdf`` file (see ``viewer.brdf.spec.BRDFModule``)."""


def make_module(bfile: BrdfFile, twin=None) -> FileModule:
    spec = ModelSpec(name=CUSTOM, title=f"{bfile.name} ({bfile.path.name})", params=params_of(bfile),
                     source=f"the file {bfile.path}", doc="a BRDF Explorer .brdf file",
                     reciprocal=True)

    def glsl_eval(p, wi, wo):
        f = np.asarray(glsl_evaluator().eval(bfile, p, wi, wo), dtype=np.float64)
        return np.where(_upper(wi, wo)[:, None], f, 0.0)

    twin_path = twin_trust.twin_of(bfile.path)
    if twin is not None:  # every call checked: what it raises or returns wrong is one line naming it
        twin_eval, twin_sample, twin_pdf = twin_trust.guarded(twin_path, twin)

    if twin is not None and twin_sample is not None:
        sampler = "numpy twin"
        pdf, sample = twin_pdf, twin_sample
    elif bfile.has_sampler:
        sampler = "isFunc"

        def sample(p, wo, u):
            wi, w, pd = glsl_evaluator().sample(bfile, p, wo, u)
            ok = (pd > 0) & (wi[:, 2] > 0) & (wo[:, 2] > 0) & np.all(np.isfinite(w), axis=1)
            return wi, np.where(ok[:, None], w, 0.0), np.where(ok, pd, 0.0)

        def pdf(p, wi, wo):
            # the file's sampler gives its pdf only at the directions it draws
            raise ViewerError(f"{bfile.path.name}: the isFunc sampler gives no pdf for a given direction pair")
    else:
        sampler = None

        def pdf(p, wi, wo):
            return np.where(_upper(wi, wo), np.maximum(wi[:, 2], 0.0) * INV_PI, 0.0)

        def sample(p, wo, u):
            wi, pd = cosine_sample(u)
            ok = (wo[:, 2] > 0) & (pd > 0)
            f = glsl_eval(p, wi, wo)
            w = f * np.pi  # f cos / (cos / pi)
            return wi, np.where(ok[:, None], w, 0.0), np.where(ok, pd, 0.0)

    mod = FileModule(SPEC=spec, eval=glsl_eval, sample=sample, pdf=pdf)
    if all(n in term_functions(bfile) for n in TERM_NAMES):
        def terms(p, wi, wo):
            # the file's own D, F, G run as GLSL (viewer.gl.file_brdf), and 1 / (4 cos cos);
            # 'other' is what the file's BRDF adds to their product (a diffuse part, say)
            t = glsl_evaluator().terms(bfile, p, wi, wo)
            ok = _upper(wi, wo)
            out = {"D": np.where(ok, t["D"], 0.0), "F": np.where(ok[:, None], t["F"], 0.0),
                   "G": np.where(ok, t["G"], 0.0),
                   "1/(4 cos cos)": np.where(ok, 0.25 / np.where(ok, wi[:, 2] * wo[:, 2], 1.0), 0.0)}
            return out

        mod.terms = terms
    mod.numpy_module = None
    if twin is not None:  # the CPU reference's model: numpy only
        if sampler == "numpy twin":
            mod.numpy_module = FileModule(SPEC=spec, eval=twin_eval, sample=sample, pdf=pdf)
        else:
            def twin_pdf(p, wi, wo):
                return np.where(_upper(wi, wo), np.maximum(wi[:, 2], 0.0) * INV_PI, 0.0)

            def twin_sample(p, wo, u):
                wi, pd = cosine_sample(u)
                ok = (wo[:, 2] > 0) & (pd > 0)
                w = twin_eval(p, wi, wo) * np.pi
                return wi, np.where(ok[:, None], w, 0.0), np.where(ok, pd, 0.0)

            mod.numpy_module = FileModule(SPEC=spec, eval=twin_eval, sample=twin_sample, pdf=twin_pdf)
    mod.source_file = bfile
    mod.numpy_twin = twin
    mod.twin_not_run = None
    if twin is None and twin_path.is_file() and not twin_trust.is_trusted(twin_path):
        mod.twin_not_run = twin_trust.not_run_message(bfile.path, twin_path)
    mod.twin_eval = twin_eval if twin is not None else None
    mod.sampled_by = sampler  # "numpy twin" | "isFunc" | None (cosine-weighted)
    return mod


_CACHE: dict = {}


def _stamp(path: Path):
    """What the cached model depends on: both files' times and sizes, and whether the twin is
    trusted (a trust given later loads the twin)."""
    twin = twin_trust.twin_of(path)
    out = [twin.is_file() and twin_trust.is_trusted(twin)]
    for p in (path, path.with_suffix(".py")):
        try:
            st = p.stat()
            out.append((st.st_mtime_ns, st.st_size))
        except OSError:
            out.append(None)
    return tuple(out)


def load(path, make, where: str | None = None):
    """The model of the ``.brdf`` file ``path`` (cached until the file or its twin changes), made
    by ``make(module, where=NAME)`` (``viewer.brdf.FileModel``, which the package passes in: this
    module sits below the package and does not import it)."""

    path = Path(path).expanduser()
    if path.suffix.lower() != ".brdf":
        raise ViewerError(f"{where or path}: a BRDF file's name ends in .brdf")
    if not path.is_file():
        raise ViewerError(f"{where or path}: no such BRDF file" if where else f"{path}: no such BRDF file")
    path = path.resolve()
    key = str(path)
    stamp = _stamp(path)
    hit = _CACHE.get(key)
    if hit is not None and hit[0] == stamp:
        return hit[1]
    bfile = parse(path)
    file_probe()(bfile)  # before its GLSL reaches any context of this process
    model = make(make_module(bfile, load_twin(path)), where=path.name)
    if len(_CACHE) > 64:
        _CACHE.clear()
    _CACHE[key] = (stamp, model)
    _LAST_GOOD[key] = model
    return model


_LAST_GOOD: dict = {}


def clear_cache() -> None:
    """Forget every loaded model (the next ``load`` reads the files again)."""
    _CACHE.clear()


def load_or_last_good(path, make):
    """``load(path)``, or, when the file no longer parses (saved with a mistake while the window
    shows it), the model it last loaded as in this process: what is drawn keeps drawing while the
    hot reloader shows the error. A file never loaded raises as ``load`` does."""
    try:
        return load(path, make)
    except ViewerError:
        hit = _LAST_GOOD.get(str(Path(path).expanduser().resolve()))
        if hit is None:
            raise
        return hit
