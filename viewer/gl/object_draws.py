"""The forward pass's draws of a frame's objects: one instanced draw per mesh and material with the
forward-program variant of its material, then the untraced thin shells over the opaque frame,
back to front with dual-source blending; and the traced mask, the pixels whose front-most surface
is drawn with a traced chain or a traced environment occlusion (the window's progressive trace)."""

from __future__ import annotations

import numpy as np

from viewer.brdf import thin_film
from viewer.scene.camera import OrbitCamera, gl_bytes, screen_boxes
from viewer.gl import texture_units
from viewer.gl.constants import IBL_MODES, MAT_FLOATS
from viewer.gl.context import release_gl
from viewer.gl.meshes import group_by, instance_data
from viewer.gl.program_set import TRACED_MASK, env_occluded, forward_args, frame_switches, scene_traces, thin_shell
from viewer.gl.raytrace import MAX_SEGMENTS as RT_MAX_SEGMENTS
from viewer.gl.raytrace import chain_traces
from viewer.gl.shaders import ShaderError
from viewer.gl.shaders import set_uniform as _set

GL_SRC1_COLOR = 0x88F9  # dual-source blending (core since OpenGL 3.3); moderngl names no constant


def in_region(objects, f) -> list:
    """[(index, object)] of ``objects`` that may cover a pixel of the frame's region (all of them
    without one). A tile's draws are scissored, but the vertex work of every object is done
    whatever the scissor (28 ms a tile for the gallery's 11 objects on software OpenGL): an
    object whose box, projected, lies wholly outside the region (by 2 pixels) writes nothing
    there and is left out, so the tile's pixels are the whole frame's exactly. A box crossing
    the camera's plane is kept. ``f.only``: only the objects of those materials (a trial draw)."""
    pairs = [(i, o) for i, o in enumerate(objects) if f.only is None or o.material in f.only]
    if f.region is None or not f.cull or not pairs:
        return pairs
    x0, y0, rw, rh = f.region
    boxes = screen_boxes(f.cam, f.w, f.h, [o for _, o in pairs])
    return [pair for pair, box in zip(pairs, boxes)
            if box is None or not (box[2] + 2 < x0 or box[0] - 2 > x0 + rw or box[3] + 2 < y0 or box[1] - 2 > y0 + rh)]


class ObjectDraws:
    """The objects' draws, with the programs of ``program_set`` (a ``ProgramSet``), the buffers
    of ``meshes`` (a ``MeshCache``) and the per-material uniforms of ``materials`` (a
    ``MaterialUniforms``). ``f`` is the frame (``viewer.gl.frame_passes.Frame``)."""

    def __init__(self, ctx, program_set, meshes, materials):
        self.ctx = ctx
        self.program_set = program_set
        self.meshes = meshes
        self.materials = materials
        self._mask_target = None    # (size, texture, depth, framebuffer) of traced_mask

    def draw(self, scene, f, uniforms: dict, rt, thickness, ibl):
        """One instanced draw per mesh and material (per object where a thin film varies over
        the object's height) with the forward-program variant of its material; the frame's
        uniforms are set once per program. ``rt``: (RayTrace, ...) when the frame traces chains,
        else None; ``ibl``: the IBL state, bound to every program."""
        ready = set()

        own = {name: thin_film.varies(p) for name, p in scene.materials.items()}   # u_film_y: the object's own

        def group_key(i_obj):
            i, obj = i_obj
            return (obj.material, id(obj.mesh_data), i if own[obj.material] else -1)

        shells = []  # untraced thin shells: drawn after everything opaque, back to front
        for group in group_by(in_region(scene.objects, f), group_key):
            obj = group[0][1]
            params = scene.materials[obj.material]
            traced = rt is not None and chain_traces(params)
            if not traced and thin_shell(params):
                shells += [o for _, o in group]
                continue
            args = forward_args(scene, params, f.ssr_on, f.env_on, f.env_map is None, rt is not None)
            # sampled in split_sum mode: a file BRDF's environment light (forward_args)
            custom_fis = args["ibl_sampled"] and scene.render.ibl == "split_sum"
            try:
                prog = self.program_set.forward_program(params, **args)
            except ShaderError:
                if not self.program_set.hot_reload:
                    raise
                continue  # never compiled (see shader_errors): leave the objects out, draw the rest
            if id(prog) not in ready:
                for k, v in uniforms.items():
                    _set(prog, k, v)
                # always: unbound samplers default to unit 0, where the shadow atlas (a different
                # sampler type) is, and that makes the draw call invalid
                ibl.bind(prog, scene.environment.rotation_deg)
                if custom_fis:
                    _set(prog, "u_ibl_mode", IBL_MODES["fis"])
                ready.add(id(prog))
            if traced or args["env_occlusion"]:  # every frame: the shadow atlas and IBL share no units with these
                rt[0].bind(prog, first_unit=texture_units.TRACED)
                row = rt[0].rows[obj.material]
                _set(prog, "u_rt_row", row)
                _set(prog, "u_mat_base", row * MAT_FLOATS)
                _set(prog, "u_rt_depth", int(scene.render.raytrace_depth))
                _set(prog, "u_rt_max_segments", RT_MAX_SEGMENTS)
            self.materials.set(prog, obj, params, bool(uniforms["u_ms_on"]), thickness, env=f.env_on or f.ssr_on)
            if args["ibl_sampled"]:
                self.materials.sampled_env(prog, params, scene)
            self.meshes.get(obj.mesh_data).draw(prog, instance_data([o for _, o in group]))
        if shells:
            self._draw_shells(scene, f, uniforms, thickness, shells, ibl)

    def _draw_shells(self, scene, f, uniforms: dict, thickness, shells, ibl):
        """Thin shells over the opaque frame, farthest first, each in two draws (its far faces,
        then its near ones) with dual-source blending: destination x transmittance + reflected
        radiance, i.e. each face lets its transmitted fraction of what lies behind it through
        and adds what it reflects (forward.frag, THIN_SHELL). No depth writes: what a shell
        covers stays the depth and, with SSR, the geometry of what lies behind it."""
        ctx = self.ctx
        fbo = f.targets.shell_fbo
        own_scissor = f.region is not None and fbo is not f.targets.draw_fbo
        if own_scissor:
            fbo.scissor = f.region
        fbo.use()
        eye = np.asarray(f.cam.position, float)
        shells = sorted(shells, key=lambda o: -float(np.linalg.norm(np.asarray(o.translate, float) - eye)))
        ctx.enable(ctx.BLEND | ctx.CULL_FACE | ctx.DEPTH_TEST)
        ctx.blend_func = (ctx.ONE, GL_SRC1_COLOR)
        fbo.depth_mask = False
        try:
            for obj in shells:
                params = scene.materials[obj.material]
                try:
                    prog = self.program_set.forward_program(
                        params, **forward_args(scene, params, f.ssr_on, f.env_on, f.env_map is None, False))
                except ShaderError:
                    if not self.program_set.hot_reload:
                        raise
                    continue
                for k, v in uniforms.items():
                    _set(prog, k, v)
                ibl.bind(prog, scene.environment.rotation_deg)
                # always: the transmittance comes from the material's albedo tables
                self.materials.set(prog, obj, params, bool(uniforms["u_ms_on"]), thickness, env=True)
                self.materials.ground(prog, scene)  # the floor its reflections meet
                mesh = self.meshes.get(obj.mesh_data)
                for side in ("front", "back"):  # culled: far faces first, then near ones
                    ctx.cull_face = side
                    mesh.draw(prog, instance_data([obj]))
        finally:
            fbo.depth_mask = True
            ctx.cull_face = "back"
            ctx.disable(ctx.BLEND | ctx.CULL_FACE)
            ctx.blend_func = ctx.DEFAULT_BLENDING
            if own_scissor:
                fbo.scissor = None
            f.targets.draw_fbo.use()

    def traced_mask(self, scene, camera: OrbitCamera | None = None, width: int | None = None,
                    height: int | None = None, raytrace: bool | None = None) -> np.ndarray:
        """(H, W) bool, row 0 = bottom: the pixels whose front-most surface at the pixel centre
        is drawn with a traced chain (``Renderer.traced_mask``)."""
        ctx = self.ctx
        w = int(width or scene.camera.width)
        h = int(height or scene.camera.height)
        on = bool(scene.render.raytrace) if raytrace is None else bool(raytrace)
        if not (on and scene_traces(scene)):
            return np.zeros((h, w), bool)
        if self._mask_target is None or self._mask_target[0] != (w, h):
            self._release_mask()
            tex = ctx.texture((w, h), 1, dtype="f1")
            depth = ctx.depth_renderbuffer((w, h))
            self._mask_target = ((w, h), tex, depth, ctx.framebuffer(color_attachments=[tex], depth_attachment=depth))
        _, tex, _, fbo = self._mask_target
        cam = camera or OrbitCamera.from_scene(scene)
        prog = self.program_set.get("traced_mask", TRACED_MASK)
        fbo.use()
        fbo.viewport = (0, 0, w, h)
        fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        ctx.enable(ctx.DEPTH_TEST)
        ctx.disable(ctx.CULL_FACE)
        _set(prog, "u_view_proj", gl_bytes(cam.projection(w / h) @ cam.view()))
        env_on = frame_switches(scene, raytrace)[1]
        for obj in scene.objects:  # one draw each, in the forward pass's order (u_traced per object)
            params = scene.materials[obj.material]
            # a chain, or the environment's occlusion traced in the BVH (program_set.env_occluded)
            _set(prog, "u_traced", float(chain_traces(params) or env_occluded(scene, params, env_on, True)))
            self.meshes.get(obj.mesh_data).draw(prog, instance_data([obj]))
        return np.frombuffer(tex.read(alignment=1), np.uint8).reshape(h, w) > 127

    def _release_mask(self):
        if self._mask_target is not None:
            release_gl(*self._mask_target[1:])
            self._mask_target = None

    def release(self):
        self._release_mask()
