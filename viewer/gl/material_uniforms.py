"""A material's uniforms in a forward program: its parameter block, its measured tables, the
multiple-scattering compensation, its environment lighting (albedo tables, lobe width,
transmission and absorption) and, for a sampled environment, its sampler's settings.

``MaterialUniforms`` sets them from the renderer's ``MaterialTables`` (viewer/gl/material_tables.py)
and holds the measured BRDFs' 3D textures (viewer/gl/measured_tex.py), made on first use."""

from __future__ import annotations

import numpy as np

from viewer import brdf
from viewer.brdf import thin_film
from viewer.gl import texture_units
from viewer.gl.brdf_glsl import uniform_block
from viewer.gl.program_set import brdf_spec
from viewer.gl.shaders import set_uniform as _set
from viewer.scene.ground import ground_plane


class MaterialUniforms:
    """The per-material uniforms of the forward pass, from ``tables`` (a ``MaterialTables``)."""

    def __init__(self, ctx, tables):
        self.ctx = ctx
        self.tables = tables
        self._measured = None

    def prepare(self, scene, env_tables: bool):
        """Build the tables the frame's materials need before the forward pass (a GPU table
        build binds its own targets): the albedo tables when the environment or SSR lights them
        (``env_tables``), the compensation's terms where it is on."""
        ms_scene = bool(getattr(scene.render, "ms_compensation", False))
        for name in dict.fromkeys(o.material for o in scene.objects):   # each material once
            params = scene.materials[name]
            if env_tables:
                self.tables.albedo_tables(params)
            if ms_scene or bool(params.get("multiple_scattering", False)):
                self.tables.ms_terms(params)  # point and directional lights use them too

    def prepared(self, scene, env_tables: bool) -> bool:
        """Whether ``prepare(scene, env_tables)`` has nothing left to build."""
        ms_scene = bool(getattr(scene.render, "ms_compensation", False))
        for name in dict.fromkeys(o.material for o in scene.objects):
            params = scene.materials[name]
            # albedo_tables brings the compensation's terms too (its ms_f0)
            ms = env_tables or ms_scene or bool(params.get("multiple_scattering", False))
            if ms and not self.tables.built(params, ms):
                return False
        return True

    def measured_textures(self):
        """The 3D textures of measured BRDF tables (viewer/gl/measured_tex.py), made on first use."""
        if self._measured is None:
            from viewer.gl.measured_tex import MeasuredTextures

            self._measured = MeasuredTextures(self.ctx)
        return self._measured

    def set(self, prog, obj, params, ms_scene: bool, thickness, env: bool):
        """The uniforms of ``params`` drawn on ``obj`` (``ms_scene``: the scene's compensation
        switch; ``thickness``: the thickness texture or None; ``env``: set the environment
        lighting's too)."""
        idx, block = uniform_block(params)
        _set(prog, "u_model_id", idx)
        # the object's world y range: a film over height (thickness_top_nm); (0, 0) a uniform one
        _set(prog, "u_film_y", obj.y_range() if thin_film.varies(params) else (0.0, 0.0))
        _set(prog, "u_mat", block.tobytes())
        if "u_measured" in prog:
            self.measured_textures().bind(prog, params)
        self._ms(prog, params, ms_scene)
        if env:
            self._environment(prog, params, thickness)

    def ground(self, prog, scene):
        """A thin shell's ground (viewer/scene/ground.py): the plane its reflected rays meet
        before the environment, or none (u_ground_on 0)."""
        g = ground_plane(scene)
        _set(prog, "u_ground_on", int(g is not None))
        if g is not None:
            m = g.to_local
            _set(prog, "u_ground_origin", tuple(float(v) for v in g.origin))
            _set(prog, "u_ground_to_local", (float(m[0, 0]), float(m[0, 1]), float(m[1, 0]), float(m[1, 1])))
            _set(prog, "u_ground_albedo", tuple(float(v) for v in g.albedo))

    def sampled_env(self, prog, params, scene):
        """A file material samples its environment light with its own sampler, its lookups
        filtered for all the samples of the frames a still view averages, and in split-sum mode
        lights its constant part with the irradiance (``viewer.gl.file_env``); the built-in
        models sample with the proxy lobe."""
        from viewer.gl.file_env import FRAME_SAMPLES, constant_part, settle_frames

        own = brdf.is_file(params)
        _set(prog, "u_ibl_own", int(own))
        floor = constant_part(params) if own and scene.render.ibl == "split_sum" else np.zeros(3)
        _set(prog, "u_env_floor", tuple(float(x) for x in floor))
        _set(prog, "u_fis_samples", FRAME_SAMPLES * (settle_frames(scene) if own else 1))

    def _ms(self, prog, params, ms_scene: bool):
        """The multiple-scattering compensation of a material (environment light: Fdez-Aguera;
        point and directional lights: Kulla-Conty; viewer/brdf/ms_compensation.py): for the whole scene, or
        for a material whose reference has the multiple-scattering random walk (the raster's
        approximation of the same light)."""
        from viewer.brdf import ms_compensation
        ms_on = ms_scene or bool(params.get("multiple_scattering", False))
        _set(prog, "u_ms_on", int(ms_on))
        if ms_on:  # the shader reads u_ms_f0, u_ms_ess and u_ms_eavg only then
            ms_ess, ms_f0 = self.tables.ms_terms(params)
            _set(prog, "u_ms_f0", tuple(float(x) for x in ms_f0))
            _set(prog, "u_ms_ess", ms_ess.tobytes())
            _set(prog, "u_ms_eavg", ms_compensation.e_avg(ms_ess))

    def _environment(self, prog, params, thickness):
        """A material's environment-lighting uniforms: its albedo tables, lobe width,
        transmission and absorption."""
        refl, trans, spec, alpha = self.tables.tables(params)
        _set(prog, "u_albedo", refl.tobytes())
        _set(prog, "u_albedo_t", trans.tobytes())
        _set(prog, "u_albedo_s", spec.tobytes())
        _set(prog, "u_ibl_alpha", alpha)
        _set(prog, "u_ibl_delta", int(brdf_spec(params).delta and alpha == 0.0))
        absorbing = "sigma_a" in params and brdf_spec(params).transmissive
        _set(prog, "u_transmit_on", int(bool(np.any(trans > 0))))
        _set(prog, "u_sigma_a", tuple(float(x) for x in (params.sigma_a if absorbing else np.zeros(3))))
        _set(prog, "u_ior", float(params.get("ior", 1.0)))
        if thickness is not None:
            thickness.use(location=texture_units.THICKNESS)
        # always: left at unit 0 it would share the shadow atlas's unit (another sampler type)
        _set(prog, "u_thickness", texture_units.THICKNESS)

    def release(self):
        if self._measured is not None:
            self._measured.release()
            self._measured = None
