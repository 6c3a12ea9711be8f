"""One rasterizer frame as a sequence of named steps (``FramePasses.run``): the frame's targets and
switches (``begin``), the shadow pass (viewer/gl/shadow.py), the environment (the thickness of
absorbers: viewer/gl/targets.py, the IBL textures: viewer/gl/ibl.py, the materials' tables:
``MaterialUniforms.prepare``), the background, the per-frame uniforms, the traced chains' scene
data (viewer/gl/raytrace.py), the objects' draws (viewer/gl/object_draws.py), and the SSR pass
(viewer/gl/ssr.py) or the MSAA resolve. ``FramePasses`` holds the passes the steps use, the
IBL, SSR and traced-chain state made on first use."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from viewer.scene.camera import OrbitCamera, gl_bytes
from viewer.gl import texture_units
from viewer.gl.unit_fill import UnitFill
from viewer.gl.constants import IBL_MODES, LIGHT_TYPES, MAX_LIGHTS, SSR_VIEW_BASE
from viewer.gl.program_set import BACKGROUND, SHADOW_GLASS, THICKNESS, absorbing, frame_switches, scene_traces
from viewer.gl.raytrace import chain_traces, dispersive
from viewer.gl.shaders import set_uniform as _set
from viewer.gl.shadow import ShadowMaps, casts_shadows, glass_shadows
from viewer.gl.targets import ThicknessPass


class Frame(NamedTuple):
    """What one frame renders with: size, camera, targets and the switches the steps share."""

    w: int
    h: int
    cam: OrbitCamera
    targets: object      # viewer.gl.targets.FrameTargets (the HDR targets or the SSR pass's)
    view_mode: int      # the forward pass's (0 when the SSR pass shows a debug view)
    ssr_on: bool
    ssr_debug: int      # the SSR pass's output (0: the composite)
    lights: list
    shadows: bool
    env_rad: np.ndarray  # the constant environment's radiance (intensity applied)
    env_map: object      # the radiance map, or None
    env_on: bool         # the environment lights the scene (IBL not off, not black)
    raytrace: bool       # traced chains on (the scene's ``raytrace`` unless the call overrides it)
    region: tuple | None  # (x, y, w, h) scissor of the background and forward draws, else None
    cull: bool = True    # objects that cannot reach the region are not drawn (object_draws.in_region)
    only: frozenset | None = None  # the materials whose objects are drawn (None: all)


class FramePasses:
    """The steps of a frame, with the renderer's other parts: ``program_set`` (programs),
    ``meshes`` (buffers), ``materials`` (``MaterialUniforms``), ``draws`` (``ObjectDraws``) and
    ``output`` (``FrameOutput``: the targets)."""

    def __init__(self, ctx, program_set, meshes, materials, draws, output):
        self.ctx = ctx
        self.program_set = program_set
        self.meshes = meshes
        self.materials = materials
        self.draws = draws
        self.output = output
        self.shadows = ShadowMaps(ctx)
        self.unit_fill = UnitFill(ctx)  # what the optional units hold when the frame fills none
        self.thickness = ThicknessPass(ctx)
        self.ssr_back = ThicknessPass(ctx)  # the nearest back face of every object, for SSR hits
        self._ibl = None
        self._ssr = None
        self._rt = None

    # ---------------------------------------------------------------- passes made on first use
    def ibl(self):
        """The image-based lighting state (prefiltered environment), created on first use."""
        if self._ibl is None:
            from viewer.gl.ibl import IBL

            self._ibl = IBL(self.ctx)
        return self._ibl

    def ssr(self):
        """The screen-space reflection pass (viewer/gl/ssr.py), created on first use."""
        if self._ssr is None:
            from viewer.gl.ssr import SSR

            self._ssr = SSR(self.ctx)
        return self._ssr

    def raytrace_state(self):
        """The scene's BVH and material textures for traced chains (viewer/gl/raytrace.py)."""
        if self._rt is None:
            from viewer.gl.raytrace import RayTrace

            self._rt = RayTrace(self.ctx)
        return self._rt

    def reloadable(self) -> dict:
        """The passes made so far that own programs ({prefix: pass or None}), for hot reload."""
        return {"ssr": self._ssr, "ibl": self._ibl}

    # ---------------------------------------------------------------- the frame
    def run(self, scene, camera, width, height, view_mode, msaa, frame_index, raytrace=None, region=None, cull=True,
            only=None):
        """Render a frame into the linear HDR target; returns the resolved float texture."""
        f = self.begin(scene, camera, width, height, view_mode, msaa, raytrace, region)._replace(
            cull=cull, only=None if only is None else frozenset(only))
        if f.shadows:
            self.shadow_pass(scene)
        thickness = self.environment(scene, f)
        self.unit_fill.bind()  # before the frame's own textures, which are bound over them
        if f.region is not None:  # applied by every use() of the frame's colour target
            f.targets.draw_fbo.scissor = f.region
        try:
            self.background(scene, f)
            uniforms = self.frame_uniforms(scene, f, frame_index)
            rt = self.raytrace_setup(scene, f)
            self.draws.draw(scene, f, uniforms, rt, thickness, self._ibl)
        finally:
            if f.region is not None:
                f.targets.draw_fbo.scissor = None
                f.targets.draw_fbo.use()
        return self.finish(scene, f, frame_index)

    def shadow_pass(self, scene) -> None:
        """The shadow atlas of ``scene`` (drawn unless it holds the scene already)."""
        glass = self.program_set.get("shadow_glass", SHADOW_GLASS) if glass_shadows(scene) else None
        self.shadows.update(scene, self.program_set.programs["shadow"], self.meshes.draw_objects, glass)

    def shadows_ready(self, scene) -> bool:
        """A frame of ``scene`` would not draw its shadow atlas (none, or it holds the scene)."""
        return not casts_shadows(scene) or self.shadows.holds(scene)

    def begin(self, scene, camera, width, height, view_mode, msaa, raytrace=None, region=None) -> Frame:
        """The frame's size, camera, colour targets (the SSR pass's with SSR) and switches."""
        w = int(width or scene.camera.width)
        h = int(height or scene.camera.height)
        ssr_on = bool(scene.render.ssr)
        targets = self.output.ensure(w, h, scene.render.msaa if msaa is None else msaa)
        if ssr_on:  # the same sample count, with the SSR pass's three attachments
            targets = self.ssr().targets(w, h, targets.samples)
        ssr_debug = view_mode - SSR_VIEW_BASE if view_mode > SSR_VIEW_BASE else 0
        if ssr_debug:
            view_mode = 0  # the forward pass shades; the SSR pass shows its debug output
        lights = scene.lights[:MAX_LIGHTS]   # all of them (the validator refuses more); 4 shadowed
        env = scene.environment
        env_rad = np.zeros(3) if env.constant is None else np.asarray(env.constant, float) * env.intensity
        env_map = env.radiance_map() if env.map is not None else None
        env_on = frame_switches(scene, raytrace)[1]
        self.output.begin(targets)
        rt_on = bool(scene.render.raytrace) if raytrace is None else bool(raytrace)
        if region is not None:
            x, y, rw, rh = (int(v) for v in region)
            x0, y0 = max(0, x), max(0, y)
            region = (x0, y0, max(0, min(w, x + rw) - x0), max(0, min(h, y + rh) - y0))
        return Frame(w, h, camera or OrbitCamera.from_scene(scene), targets, view_mode, ssr_on, ssr_debug,
                     lights, casts_shadows(scene), env_rad, env_map, env_on,
                     rt_on, region)

    def environment(self, scene, f: Frame):
        """The thickness of absorbing objects (or None), the IBL textures of the environment, and
        the tables of every material (before the forward pass: a GPU table build binds its own
        targets)."""
        thickness = None
        absorbers = [o for o in scene.objects if absorbing(scene.materials[o.material])
                     and not (f.raytrace and chain_traces(scene.materials[o.material]))]
        if absorbers and f.env_on:
            thickness = self.thickness.render(absorbers, f.cam, f.w, f.h,
                                              self.program_set.get("thickness", THICKNESS), self.meshes.draw_objects)
        self.ibl().set_environment(f.env_map, constant=None if f.env_map is not None else f.env_rad)
        self.materials.prepare(scene, env_tables=f.ssr_on or f.env_on)
        return thickness

    def background(self, scene, f: Frame):
        """Clear the colour target to the constant environment and draw the map behind the scene."""
        ctx = self.ctx
        fbo = f.targets.draw_fbo
        fbo.use()
        fbo.viewport = (0, 0, f.w, f.h)
        fbo.clear(*[float(x) for x in f.env_rad], 1.0, depth=1.0)
        env = scene.environment
        if f.ssr_on:
            self._ssr.background(self._ibl, f.cam, f.w, f.h, f.env_map is not None, f.env_rad, env.rotation_deg)
        elif f.env_map is not None:  # draw the environment behind the scene
            bg = self.program_set.get("background", BACKGROUND)
            ctx.disable(ctx.DEPTH_TEST)
            _set(bg, "u_inv_view_proj", gl_bytes(np.linalg.inv(f.cam.projection(f.w / f.h) @ f.cam.view())))
            _set(bg, "u_camera_pos", tuple(float(x) for x in f.cam.position))
            self._ibl.bind(bg, env.rotation_deg)
            self.program_set.fullscreen_vao(bg).render(vertices=3)
        ctx.enable(ctx.DEPTH_TEST)
        ctx.disable(ctx.CULL_FACE)

    def frame_uniforms(self, scene, f: Frame, frame_index: int) -> dict:
        """The uniforms every forward program of the frame gets (camera, lights, environment,
        view mode, the shadow atlas, bound to its unit here)."""
        types = np.zeros(MAX_LIGHTS, "i4")
        pos = np.zeros((MAX_LIGHTS, 3), "f4")
        val = np.zeros((MAX_LIGHTS, 3), "f4")
        for i, l in enumerate(f.lights):
            types[i] = LIGHT_TYPES[l.type]
            pos[i] = l.position if l.type == "point" else l.direction
            val[i] = l.intensity if l.type == "point" else l.irradiance
        uniforms = {
            "u_view_proj": gl_bytes(f.cam.projection(f.w / f.h) @ f.cam.view()),
            "u_camera_pos": tuple(float(x) for x in f.cam.position),
            "u_num_lights": len(f.lights),
            "u_light_type": types.tobytes(),
            "u_light_pos": pos.tobytes(),
            "u_light_value": val.tobytes(),
            "u_env_on": int(f.env_on),
            "u_env_constant": tuple(float(x) for x in f.env_rad),
            "u_ibl_mode": IBL_MODES.get(scene.render.ibl, 1),
            "u_frame_index": int(frame_index),
            "u_ms_on": int(bool(getattr(scene.render, "ms_compensation", False))),
            "u_view_mode": int(f.view_mode),
            "u_shadows_on": int(f.shadows),
        }
        if f.ssr_on:
            uniforms["u_view"] = gl_bytes(f.cam.view())
        if f.shadows:
            uniforms.update(self.shadows.bind(unit=texture_units.SHADOW_ATLAS))
        return uniforms

    def raytrace_setup(self, scene, f: Frame):
        """(RayTrace state, the scene's materials, dispersion) when a traced chain starts at a
        mirror or smooth glass of the scene, else None."""
        if not (f.raytrace and scene_traces(scene)):
            return None
        rt = self.raytrace_state()
        rt.update(scene, self.materials.tables.albedo_tables)
        return rt, list(scene.materials.values()), dispersive(scene)

    def finish(self, scene, f: Frame, frame_index: int):
        """The SSR pass (which resolves and traces), or the MSAA resolve; the linear HDR texture."""
        if f.ssr_on:
            # what lies behind each visible surface: the distance to the nearest back face (0 where
            # none, e.g. a one-sided floor), so a reflected ray passing behind a closed object's
            # front within the object hits it and one passing behind the object does not
            back = self.ssr_back.render(scene.objects, f.cam, f.w, f.h, self.program_set.get("thickness", THICKNESS),
                                        self.meshes.draw_objects)
            return self._ssr.resolve_and_trace(self._ibl, f.cam, f.w, f.h, f.env_on, scene.environment.rotation_deg,
                                               f.ssr_debug, frame_index, back=back)
        return self.output.resolve(f.targets, f.region)

    def release(self):
        self.shadows.release()
        self.unit_fill.release()
        for part in (self.thickness, self.ssr_back, self._ibl, self._ssr, self._rt):
            if part is not None:
                part.release()
        self._ibl = self._ssr = self._rt = None
