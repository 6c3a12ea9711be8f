"""The per-material data of environment lighting, cached by parameter values: directional-albedo
tables (reflected, transmitted, and the specular part's alone, the model's ``ibl_split`` hook),
that part's lobe width, and its normal-incidence Fresnel for the multiple-scattering
compensation. Tables come from the GLSL samplers on the GPU (``viewer/gl/albedo_gpu.py``: the
numpy estimator's points) or from numpy (``viewer.brdf.albedo``: the oracle and the fallback)."""

from __future__ import annotations

import json

import numpy as np

from viewer.brdf.albedo import TABLE_SIZE, albedo_tables
from viewer.gl.shaders import ShaderError

_DFG = None


def _ms_f0(spec_albedo_normal, alpha: float, nov: float) -> np.ndarray:
    """The specular lobe's Fresnel at normal incidence for the multiple-scattering term: its
    albedo there divided by the GGX albedo with F = 1 (A + B of the DFG table), clamped to 1."""
    global _DFG
    from viewer.environment.dfg import dfg_table, lookup_dfg

    if not np.any(np.asarray(spec_albedo_normal, float) > 0):
        return np.zeros(3)  # no specular part (diffuse models): 0 whatever the table says
    if _DFG is None:  # about a second of numpy: made the first time a compensated specular needs it
        _DFG = dfg_table()
    a, b = lookup_dfg(_DFG, nov, max(alpha, 1e-3))
    return np.clip(np.asarray(spec_albedo_normal, float) / max(float(a + b), 1e-6), 0.0, 1.0)


class MaterialTables:
    """``gpu``: build tables with the GLSL samplers (False: the numpy builder); ``gpu_error``:
    why the GPU builder last failed (a family file being edited), the tables then came from numpy."""

    def __init__(self, ctx):
        self.ctx = ctx
        self.gpu = True
        self.gpu_error: ShaderError | None = None
        self.gpu_builder = None  # the GPUAlbedoTables, made on first use
        self._cache: dict[str, tuple] = {}
        self._ms_cache: dict[str, np.ndarray] = {}

    def albedo_tables(self, params) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, np.ndarray]:
        """float32 (32, 3) tables of the reflected albedo, the transmitted albedo and the
        reflected albedo of the specular part alone (none for diffuse models), that part's lobe
        width alpha, and its normal-incidence Fresnel (``ms_f0``)."""
        return self.tables(params) + (self.ms_f0(params),)

    def ms_f0(self, params) -> np.ndarray:
        """The normal-incidence Fresnel of a material's specular part for the multiple-scattering
        compensation (see ``_ms_f0``; computed on first use: only scenes with
        ``ms_compensation`` need it, and it needs the DFG table)."""
        key = json.dumps(params.to_plain(), sort_keys=True)
        f0 = self._ms_cache.get(key)
        if f0 is None:
            _, _, spec, alpha = self.tables(params)
            f0 = _ms_f0(spec[-1], alpha, (TABLE_SIZE - 0.5) / TABLE_SIZE)
            if len(self._ms_cache) > 256:
                self._ms_cache.clear()
            self._ms_cache[key] = f0
        return f0

    def tables(self, params) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
        """(reflected, transmitted, specular part, alpha), cached by the parameter values."""
        key = json.dumps(params.to_plain(), sort_keys=True)
        tables = self._cache.get(key)
        if tables is None:
            from viewer import brdf

            model = brdf.get(params.model)
            r, t = self._albedo_pair(model, params)
            split = getattr(model.module, "ibl_split", None)
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
        return albedo_tables(model, params)

    def clear(self):
        """Forget the cached tables (they are built again on the next use)."""
        self._cache.clear()

    def shaders_changed(self):
        """The GLSL samplers changed: rebuild the GPU builder and the tables from the new files."""
        self.release()
        self._cache.clear()
        self.gpu_error = None

    def release(self):
        if self.gpu_builder is not None:
            self.gpu_builder.release()
            self.gpu_builder = None
