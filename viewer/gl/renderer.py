"""The rasterizer: shadow maps, a forward pass into a linear HDR float target with MSAA, and a
tone-mapping pass to the screen or an 8-bit sRGB image. The window and the offscreen path both
call ``Renderer.render``; only the owner of the final framebuffer differs.

``Renderer`` is the facade the window, the notebook, the commands and the tests use; each of its
jobs is a part it holds (docs/architecture.md, *The rasterizer*):

- ``meshes`` (``viewer/gl/meshes.py``, ``MeshCache``): the meshes' GPU buffers, instanced draws;
- ``program_set`` (``viewer/gl/program_set.py``, ``ProgramSet``): the programs, which variant a
  material is drawn with, hot reload and the programs' errors;
- ``output`` (``viewer/gl/frame_output.py``, ``FrameOutput``): the HDR targets, the MSAA resolve,
  tone mapping and read-back;
- ``tables`` (``viewer/gl/material_tables.py``, ``MaterialTables``) and ``material_uniforms``
  (``viewer/gl/material_uniforms.py``, ``MaterialUniforms``): a material's tables and uniforms;
- ``draws`` (``viewer/gl/object_draws.py``, ``ObjectDraws``): the objects' and thin shells' draws
  and the traced mask;
- ``passes`` (``viewer/gl/frame_passes.py``, ``FramePasses``): a frame's named steps and the passes
  they use (shadow maps, thickness, IBL, SSR, traced chains)."""

from __future__ import annotations

import numpy as np

from viewer.scene.camera import OrbitCamera
from viewer.gl.constants import IBL_MODES, MAX_LIGHTS, SSR_VIEW_BASE, TONEMAPS, VIEW_MODES
from viewer.gl.frame_output import FrameOutput
from viewer.gl.frame_passes import FramePasses
from viewer.gl.material_tables import MaterialTables
from viewer.gl.material_uniforms import MaterialUniforms
from viewer.gl.meshes import GpuMesh, MeshCache
from viewer.gl.object_draws import ObjectDraws
from viewer.gl.program_set import ProgramSet, scene_traces
from viewer.gl.shaders import ShaderError
from viewer.gl.shadow import SHADOW_TILE

__all__ = ["Renderer", "GpuMesh", "MAX_LIGHTS", "SHADOW_TILE", "TONEMAPS", "IBL_MODES", "VIEW_MODES",
           "SSR_VIEW_BASE"]


class Renderer:
    # No per-sample shading (GLSL 'sample' inputs): on Mesa llvmpipe 22.3 it gave wrong shadow
    # visibility on fully covered pixels near silhouettes (measured against the reference). For
    # an exact box filter use render_arrays(..., supersample=k) instead.

    def __init__(self, ctx):
        self.ctx = ctx
        self.meshes = MeshCache(ctx)
        self.program_set = ProgramSet(ctx, vao_tables=self.meshes.vao_tables)
        self.output = FrameOutput(ctx, self.program_set)
        self.tables = MaterialTables(ctx)
        self.material_uniforms = MaterialUniforms(ctx, self.tables)
        self.draws = ObjectDraws(ctx, self.program_set, self.meshes, self.material_uniforms)
        self.passes = FramePasses(ctx, self.program_set, self.meshes, self.material_uniforms, self.draws,
                                  self.output)

    # ---------------------------------------------------------------- programs
    @property
    def programs(self) -> dict:
        """The programs built so far, by key (``forward:<models>:<variant>``, ``shadow``, ...)."""
        return self.program_set.programs

    #: set by hot reload (viewer/gl/hot_reload.py): a program that fails to compile is reported
    #: in ``shader_errors`` instead of raised from ``render`` (objects whose forward program has
    #: no good version yet are left out of the image), and is retried when a shader file changes.
    @property
    def hot_reload(self) -> bool:
        return self.program_set.hot_reload

    @hot_reload.setter
    def hot_reload(self, on: bool):
        self.program_set.hot_reload = bool(on)

    @property
    def last_reloaded(self) -> list[str]:
        """The keys of the programs the last ``reload_shaders`` replaced."""
        return self.program_set.last_reloaded

    def build_programs(self):
        """(Re)compile the fixed passes. Raises ShaderError; on failure the old programs stay.

        The forward pass is compiled per set of material models (``forward_program``), on
        first use, and cached: a slider move is a uniform upload, a model switch compiles at
        most once. ``reload_shaders`` rebuilds every program from the files."""
        self.program_set.build_fixed()

    @property
    def shader_errors(self) -> list[ShaderError]:
        """The programs that do not compile from the current files (each error once; a program
        that failed keeps rendering with its last good version). Empty when all compile."""
        return self.program_set.errors()

    def file_brdfs(self) -> set[str]:
        """The paths of the ``.brdf`` files of the programs in use (hot reload watches them)."""
        return self.program_set.file_brdfs()

    def reload_shaders(self, changed=None) -> list[ShaderError]:
        """Rebuild programs from the shader files as they are now and return ``shader_errors``.

        ``changed``: paths relative to shader_root() that changed (as ShaderWatcher reports
        them), or None for all. A program is compiled again only if its preprocessed sources
        differ from those of the program in use (or, for the SSR and IBL passes' programs, if
        it includes a changed file), or if it failed before and its sources changed since.
        A program that compiles replaces the old one, which is released only then; one that
        fails keeps the old one in use. Never raises ShaderError. ``last_reloaded`` lists the
        keys of the programs replaced."""
        changed = None if changed is None else {str(c).replace("\\", "/") for c in changed}
        if changed is None or any(c.startswith(("brdf/", "common/")) or c.endswith(".brdf") for c in changed):
            self.tables.shaders_changed()  # the albedo tables come from the GLSL samplers
        return self.program_set.reload(changed, passes=self.passes.reloadable())

    def program_keys(self) -> list[str]:
        """The keys of every program built so far, but the passes' own (IBL, SSR: a pass given a
        new program redoes its work, such as the environment's prefilter)."""
        return self.program_set.cache.keys()

    def relink_programs(self, keys=None) -> list[str]:
        """Link programs again, now from the driver's cache of linked programs
        (``ProgramCache.relink``): ``keys`` (``program_keys``'), or all of those. The keys
        relinked."""
        return self.program_set.cache.relink(keys)

    def forward_program(self, params, ssr: bool = False,
                        ibl_sampled: bool = False, env_light: bool = True, env_constant: bool = False,
                        traced=None, dispersion: bool = False, shell: bool = False, glass_shadow: bool = False,
                        env_occlusion: bool = False):
        """The forward program for a material (its model, and a nested base model if any); the
        variants are ``programs.forward_variant``'s (``traced``: the scene's materials, for a
        mirror or smooth glass whose specular chain is traced; ``shell``: a thin shell's)."""
        return self.program_set.forward_program(params, ssr=ssr, ibl_sampled=ibl_sampled, env_light=env_light,
                                                env_constant=env_constant, traced=traced, dispersion=dispersion,
                                                shell=shell, glass_shadow=glass_shadow, env_occlusion=env_occlusion)

    def forward_keys(self, scene, raytrace: bool | None = None) -> dict[str, str]:
        """material name -> the key of the forward program a frame of ``scene`` draws its
        objects with (``programs`` holds it once built): what a preset or model change must
        compile before the frame can show it."""
        return self.program_set.forward_keys(scene, raytrace)

    # ---------------------------------------------------------------- resources
    def draw_objects(self, objects, prog):
        """Draw ``objects`` with ``prog``: one instanced draw per mesh they use, in order of
        first appearance (the shadow and thickness passes)."""
        self.meshes.draw_objects(objects, prog)

    def forget_meshes(self, keep=()):
        """Release GPU buffers of meshes not in ``keep`` (called when a scene is replaced)."""
        self.meshes.forget(keep)

    # ---------------------------------------------------------------- material tables
    @property
    def gpu_albedo(self) -> bool:
        """Albedo tables with the GLSL samplers (False: the numpy builder)."""
        return self.tables.gpu

    @gpu_albedo.setter
    def gpu_albedo(self, on: bool):
        self.tables.gpu = bool(on)

    @property
    def albedo_gpu_error(self) -> ShaderError | None:
        """Why the GPU albedo builder last failed (the tables then came from numpy), or None."""
        return self.tables.gpu_error

    def albedo_tables(self, params) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, np.ndarray]:
        """A material's environment-lighting data, cached by its parameter values (see
        ``MaterialTables.albedo_tables``)."""
        return self.tables.albedo_tables(params)

    def ms_f0(self, params) -> np.ndarray:
        """The normal-incidence Fresnel of a material's specular part (``MaterialTables.ms_f0``)."""
        return self.tables.ms_f0(params)

    # ---------------------------------------------------------------- passes
    def ibl(self):
        """The image-based lighting state (prefiltered environment), created on first use."""
        return self.passes.ibl()

    def raytrace_state(self):
        """The scene's BVH and material textures for traced chains (viewer/gl/raytrace.py)."""
        return self.passes.raytrace_state()

    def ssr(self):
        """The screen-space reflection pass (viewer/gl/ssr.py), created on first use."""
        return self.passes.ssr()

    def shadows_ready(self, scene) -> bool:
        """A frame of ``scene`` would not draw its shadow atlas (no shadows, or the atlas holds
        the scene's lights and objects as they are)."""
        return self.passes.shadows_ready(scene)

    def draw_shadows(self, scene) -> None:
        """The shadow atlas of ``scene`` drawn now (a frame of its own in the window's view
        preparation: the gallery's 205k triangles from each light took 0.28 s)."""
        self.passes.shadow_pass(scene)

    # ---------------------------------------------------------------- the frame
    def render(self, scene, camera: OrbitCamera | None = None, width: int | None = None,
               height: int | None = None, view_mode: int = 0, msaa: int | None = None, frame_index: int = 0,
               raytrace: bool | None = None, region: tuple | None = None, cull: bool = True,
               only=None):
        """Render the scene into the linear HDR target; returns the resolved float texture.

        ``raytrace``: False draws mirrors and smooth glass with the untraced approximation even
        when the scene says ``raytrace = true`` (the window's preview frames), None follows the
        scene. ``region`` = (x, y, w, h) in pixels from the bottom left: only those pixels are
        drawn (a scissor on the background and forward draws; shadow maps and the other passes
        are whole), each exactly as in a whole frame (the window's progressive trace,
        ``viewer.gl.raytrace.ProgressiveTrace``); the rest of the target is left undefined. An
        object that cannot reach the region is not drawn at all (``object_draws.in_region``)
        unless ``cull`` is False (a trial draw that is to make every object's program). ``only``:
        the names of the materials whose objects are drawn (the others still count for what the
        whole scene switches, e.g. the glass shadows every program receives); None: all.

        Raises ShaderError when a program it needs does not compile, except in hot-reload mode
        (``hot_reload``): there the error goes to ``shader_errors``, an object whose forward
        program never compiled is left out, and a pass that cannot be built gives back the
        colour target as it is (normally the previous frame)."""
        self.program_set.keep_files(scene.materials.values())  # a file the scene let go: no stale error
        if not self.hot_reload:
            return self.passes.run(scene, camera, width, height, view_mode, msaa, frame_index, raytrace, region, cull, only)
        try:
            hdr = self.passes.run(scene, camera, width, height, view_mode, msaa, frame_index, raytrace, region, cull, only)
        except ShaderError as e:
            self.program_set.render_error = e
            w = int(width or scene.camera.width)
            h = int(height or scene.camera.height)
            return self.output.ensure(w, h, scene.render.msaa if msaa is None else msaa).resolved
        self.program_set.render_error = None
        return hdr

    def resolved_framebuffer(self, hdr):
        """The framebuffer of ``hdr``, a texture ``render`` returned (to read or copy from)."""
        return self.output.resolved_framebuffer(hdr)

    def traces(self, scene) -> bool:
        """Whether a render of ``scene`` traces specular chains (``raytrace`` on and a mirror or
        smooth glass in the scene)."""
        return scene_traces(scene)

    def traced_mask(self, scene, camera: OrbitCamera | None = None, width: int | None = None,
                    height: int | None = None, raytrace: bool | None = None) -> np.ndarray:
        """(H, W) bool in the texture's row order (row 0 = bottom): the pixels whose front-most
        surface at the pixel centre is an object drawn with a traced chain, i.e. the pixels where
        a traced frame without MSAA differs from an untraced one (every other object keeps its
        program). The objects are drawn as the forward pass draws them (same vertex stage, order
        and depth test), so the coverage is the forward pass's without MSAA."""
        return self.draws.traced_mask(scene, camera, width, height, raytrace)

    # ---------------------------------------------------------------- tone map and read-back
    def tonemap_to(self, fbo, hdr, exposure: float = 0.0, tonemap: str = "none", viewport=None):
        """Exposure, tone mapping and sRGB encoding of ``hdr`` into ``fbo`` (e.g. ctx.screen)."""
        self.output.tonemap_to(fbo, hdr, exposure, tonemap, viewport)

    def read_linear(self, hdr) -> np.ndarray:
        """(H, W, 3) float32 radiance, row 0 = top (docs/conventions.md)."""
        return self.output.read_linear(hdr)

    def read_srgb(self, hdr, exposure=0.0, tonemap="none") -> np.ndarray:
        """(H, W, 3) uint8 sRGB after exposure and tone mapping, row 0 = top."""
        return self.output.read_srgb(hdr, exposure, tonemap)

    def render_arrays(self, scene, camera=None, width=None, height=None, view_mode=0, supersample: int = 1,
                      frames: int | None = None):
        """(linear float32, sRGB uint8) images, (H, W, 3), row 0 = top.

        ``supersample`` k > 1 renders k x k shading points per pixel on a regular grid (no MSAA)
        and averages them: the box filter of docs/conventions.md up to 1/k^2 of the error of
        shading at the pixel centre (what MSAA does), at k^2 times the cost. ``frames``: the mean
        of that many frames with new sample sets; None: the frames a still window view averages
        before it rests (``viewer.gl.file_env.settle_frames``: a file material's sampled
        environment light settles over 64, every other scene is one frame)."""
        if frames is None:
            from viewer.gl.file_env import settle_frames

            frames = settle_frames(scene) if view_mode == 0 else 1
        if supersample <= 1 and frames <= 1:
            hdr = self.render(scene, camera, width, height, view_mode)
            return (self.read_linear(hdr),
                    self.read_srgb(hdr, scene.render.exposure, scene.render.tonemap))
        from viewer.image.colour import to_srgb8

        k = max(int(supersample), 1)
        w = int(width or scene.camera.width)
        h = int(height or scene.camera.height)
        acc = None
        for f in range(max(int(frames), 1)):  # progressive: frames with new sample sets
            if k == 1:
                img = self.read_linear(self.render(scene, camera, width, height, view_mode, frame_index=f))
            else:
                big = self.read_linear(self.render(scene, camera, w * k, h * k, view_mode, msaa=0, frame_index=f))
                img = big.reshape(h, k, w, k, 3).mean(axis=(1, 3), dtype=np.float64)
            acc = img.astype(np.float64) if acc is None else acc + img
        linear = (acc / max(int(frames), 1)).astype(np.float32)
        return linear, to_srgb8(linear, scene.render.exposure, scene.render.tonemap)

    def release(self):
        for part in (self.output, self.meshes, self.passes, self.draws, self.tables, self.material_uniforms,
                     self.program_set):
            part.release()
