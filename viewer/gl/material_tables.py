"""The per-material data of environment lighting, cached by parameter values: directional-albedo
tables (reflected, transmitted, and the specular part's alone, the model's ``ibl_split`` hook),
that part's lobe width, and for the multiple-scattering compensation the lobe's single-scattering
albedo with F = 1 (E_ss) and its normal-incidence Fresnel (the rule of ``viewer.brdf.ms_compensation``). Tables come from the GLSL samplers on the GPU (``viewer/gl/albedo_gpu.py``: the
numpy estimator's points) or from numpy (``viewer.brdf.albedo``: the oracle and the fallback)."""

from __future__ import annotations

import json

import numpy as np

from viewer.brdf.albedo import TABLE_SIZE, albedo_tables
from viewer.gl.shaders import ShaderError

class MaterialTables:
    """``gpu``: build tables with the GLSL samplers (False: the numpy builder); ``gpu_error``:
    why the GPU builder last failed (a family file being edited), the tables then came from numpy."""

    def __init__(self, ctx):
        self.ctx = ctx
        self.gpu = True
        self.gpu_error: ShaderError | None = None
        self.gpu_builder = None  # the GPUAlbedoTables, made on first use
        self._cache: dict[str, tuple] = {}
        self._ms_cache: dict[str, tuple] = {}

    def albedo_tables(self, params) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, np.ndarray]:
        """float32 (32, 3) tables of the reflected albedo, the transmitted albedo and the
        reflected albedo of the specular part alone (none for diffuse models), that part's lobe
        width alpha, and its normal-incidence Fresnel (``ms_f0``)."""
        return self.tables(params) + (self.ms_f0(params),)

    def ms_f0(self, params) -> np.ndarray:
        """The normal-incidence Fresnel of a material's specular part for the multiple-scattering
        compensation (``ms_terms``)."""
        return self.ms_terms(params)[1]

    def ms_terms(self, params) -> tuple[np.ndarray, np.ndarray]:
        """The multiple-scattering compensation's data (computed on first use: only scenes with
        ``ms_compensation`` need it): float32 (32,) E_ss, the specular lobe's single-scattering
        albedo with F = 1 (``viewer.brdf.ms_compensation.white_lobe``, built like the other tables; the
        GGX DFG table's A + B for lobes without one), and F0 = the specular albedo over E_ss at
        the table's normal-incidence node (``viewer.brdf.ms_compensation.ms_f0``)."""
        from viewer.brdf import ms_compensation
        key = json.dumps(params.to_plain(), sort_keys=True)
        terms = self._ms_cache.get(key)
        if terms is None:
            _, _, spec, alpha = self.tables(params)
            if not np.any(spec[-1] > 0):  # no specular part (diffuse models): no term
                terms = (np.ones(TABLE_SIZE, "f4"), np.zeros(3))
            else:
                from viewer import brdf

                split = brdf.get(params.model).hook("ibl_split")
                white = ms_compensation.white_lobe(split(params)[0]) if split is not None else None
                if white is not None:
                    e_ss = self._albedo_pair(brdf.get(white.model), white)[0].mean(axis=1)
                else:  # about a second of numpy the first time: the DFG table
                    e_ss = ms_compensation.ess_ggx((np.arange(TABLE_SIZE) + 0.5) / TABLE_SIZE, alpha)
                terms = (np.clip(e_ss, 0.0, 1.0).astype("f4"), ms_compensation.ms_f0(spec[-1], e_ss[-1]))
            if len(self._ms_cache) > 256:
                self._ms_cache.clear()
            self._ms_cache[key] = terms
        return terms

    def tables(self, params) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
        """(reflected, transmitted, specular part, alpha), cached by the parameter values."""
        key = json.dumps(params.to_plain(), sort_keys=True)
        tables = self._cache.get(key)
        if tables is None:
            from viewer import brdf

            model = brdf.get(params.model)
            r, t = self._albedo_pair(model, params)
            split = model.hook("ibl_split")
            if split is None:
                spec, alpha = np.zeros_like(r), 1.0
            else:
                # (specular params, alpha[, diffuse albedo to take away from their albedo])
                spec_params, alpha, *diffuse = split(params)
                spec = r if spec_params is params else self._albedo_pair(model, spec_params)[0]
                if diffuse:
                    spec = np.maximum(spec - np.asarray(diffuse[0])[None, :], 0.0)
            spec = np.minimum(spec, r)
            tables = (r.astype("f4"), t.astype("f4"), spec.astype("f4"), float(alpha))
            if len(self._cache) > 256:
                self._cache.clear()
            self._cache[key] = tables
        return tables

    def _albedo_pair(self, model, params):
        """(reflected, transmitted) albedo tables: on the GPU with the GLSL samplers, or with
        numpy where ``gpu`` is off or the sampling program fails to compile."""
        if self.gpu:
            try:
                if self.gpu_builder is None:
                    from viewer.gl.albedo_gpu import GPUAlbedoTables

                    self.gpu_builder = GPUAlbedoTables(self.ctx)
                return self.gpu_builder.tables(params)
            except ShaderError as e:  # e.g. a family file being edited: numpy still knows the model
                self.gpu_error = e
        if params.get("multiple_scattering", False):
            # the GLSL samplers have no random walk: nor has the fallback (the raster adds the
            # walk's light as its compensation, which must not come on top of the walk's albedo)
            params = params.replace(multiple_scattering=False)
        return albedo_tables(model, params)

    def built(self, params, ms: bool = False) -> bool:
        """Whether the tables of ``params`` (``ms``: and its compensation's terms) are built:
        asking for them costs nothing."""
        key = json.dumps(params.to_plain(), sort_keys=True)
        return key in self._cache and (not ms or key in self._ms_cache)

    def ready(self, params) -> bool:
        """Whether the tables of ``params`` come without compiling a program: cached, built with
        numpy, or the GPU builder has the sampling programs of the material, its specular part
        and that part's white lobe (a slider move; a new model or choice compiles one)."""
        key = json.dumps(params.to_plain(), sort_keys=True)
        if (key in self._cache and key in self._ms_cache) or not self.gpu:
            return True
        if self.gpu_builder is None:
            return False
        from viewer import brdf
        from viewer.brdf import ms_compensation
        sampled = [params]
        split = brdf.get(params.model).hook("ibl_split")
        if split is not None:
            spec_params = split(params)[0]
            white = ms_compensation.white_lobe(spec_params)
            sampled += [spec_params] + ([white] if white is not None else [])
        return all(self.gpu_builder.has_program(p) for p in sampled)

    def export(self, params) -> dict:
        """A material's tables and multiple-scattering terms as plain lists (built now where
        missing), for ``adopt`` in another process: the compile-ahead worker builds them
        beside the window (viewer/app/compile_ahead.py)."""
        r, t, spec, alpha = self.tables(params)
        ess, f0 = self.ms_terms(params)
        return {"r": r.tolist(), "t": t.tolist(), "spec": spec.tolist(), "alpha": float(alpha),
                "ess": np.asarray(ess).tolist(), "f0": np.asarray(f0, float).tolist()}

    def adopt(self, params, data: dict) -> None:
        """Take the tables ``export`` gave for the same parameter values (the same estimator,
        run elsewhere): the next ``tables`` / ``ms_terms`` of ``params`` read them."""
        key = json.dumps(params.to_plain(), sort_keys=True)
        self._cache[key] = (np.asarray(data["r"], "f4"), np.asarray(data["t"], "f4"),
                            np.asarray(data["spec"], "f4"), float(data["alpha"]))
        self._ms_cache[key] = (np.asarray(data["ess"], "f4"), np.asarray(data["f0"], float))

    def clear(self):
        """Forget the cached tables (they are built again on the next use)."""
        self._cache.clear()
        self._ms_cache.clear()

    def shaders_changed(self):
        """The GLSL samplers changed: rebuild the GPU builder and the tables from the new files."""
        self.release()
        self._cache.clear()
        self._ms_cache.clear()
        self.gpu_error = None

    def release(self):
        if self.gpu_builder is not None:
            self.gpu_builder.release()
            self.gpu_builder = None
