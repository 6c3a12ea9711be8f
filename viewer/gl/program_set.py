"""The rasterizer's programs: which forward-program variant a frame draws each material with
(``frame_switches``, ``forward_args``), the fixed passes' programs, and hot reload.

``ProgramSet`` holds them in a ``ProgramCache`` (viewer/gl/programs.py): the fixed passes
(shadow, tone map, the forward pass's Lambert stand-in) built at once, the forward variants and
the other passes' programs (background, thickness, traced mask) on first use, and what went
wrong (a program that fails to compile, the last frame's error in hot-reload mode)."""

from __future__ import annotations

import numpy as np

from viewer import brdf
from viewer.gl.programs import FORWARD_STAGES, ProgramCache, Recipe, forward_variant
from viewer.gl.raytrace import chain_traces, dispersive
from viewer.gl.shaders import ShaderError
from viewer.gl.shadow import glass_shadows

FIXED = {
    "forward:lambert": Recipe(*FORWARD_STAGES),
    "shadow": Recipe("passes/shadow.vert", "passes/shadow.frag"),
    "tonemap": Recipe("passes/fullscreen.vert", "passes/tonemap.frag"),
}
# programs built on first use
BACKGROUND = Recipe("passes/fullscreen.vert", "passes/background.frag")
ENLARGE = Recipe("passes/fullscreen.vert", "passes/enlarge.frag")   # a preview enlarged (raytrace.ProgressiveTrace)
THICKNESS = Recipe("passes/forward.vert", "passes/thickness.frag")
TRACED_MASK = Recipe("passes/forward.vert", "passes/traced_mask.frag")
SHADOW_GLASS = Recipe("passes/shadow_glass.vert", "passes/shadow_glass.frag")


def brdf_spec(params):
    return brdf.get(params.model).spec


def thin_shell(params) -> bool:
    """A dielectric of ior 1 (air on both sides, e.g. a soap film's bubble): light crosses it
    without bending, so the rasterizer blends what lies behind it through its transmittance
    instead of looking the refracted ray up in the environment."""
    return brdf_spec(params).transmissive and float(params.get("ior", 1.5)) == 1.0


def absorbing(params) -> bool:
    """A transmissive material with a positive absorption coefficient (the thickness pass)."""
    return brdf_spec(params).transmissive and "sigma_a" in params and bool(np.any(np.asarray(params.sigma_a) > 0))


def scene_traces(scene) -> bool:
    """Whether a render of ``scene`` traces specular chains (``raytrace`` on and a mirror or
    smooth glass in the scene)."""
    return bool(scene.render.raytrace) and any(chain_traces(scene.materials[o.material]) for o in scene.objects)


def frame_switches(scene, raytrace: bool | None = None) -> tuple[bool, bool, bool, bool]:
    """(SSR on, the environment lights the scene, it is a constant one, traced chains drawn) of
    a frame of ``scene`` (``raytrace`` overrides the scene's), as ``Renderer.render`` decides
    them, without loading a map."""
    env = scene.environment
    constant = env.map is None
    lit = constant and env.constant is not None and bool(np.any(np.asarray(env.constant, float) * env.intensity > 0))
    env_on = scene.render.ibl != "off" and (not constant or lit)
    rt_on = bool(scene.render.raytrace) if raytrace is None else bool(raytrace)
    # as the frame's traced-chain setup (FramePasses): the call's switch on, and the scene's
    traced = rt_on and scene_traces(scene)
    return bool(scene.render.ssr), env_on, constant, traced


def forward_args(scene, params, ssr_on: bool, env_on: bool, env_constant: bool, traced_frame: bool) -> dict:
    """The ``Renderer.forward_program`` arguments of the program that draws ``params`` in a frame
    of ``scene`` with these switches (``traced_frame``: the frame traces specular chains)."""
    traced = traced_frame and chain_traces(params)
    shell = not traced and thin_shell(params)
    occlusion = env_occluded(scene, params, env_on, traced_frame)
    # a file BRDF's lobe is unknown: no split sum can be pre-integrated for it, so its
    # environment light is importance sampled (fis, or brute force when asked for)
    custom_fis = brdf.is_file(params) and env_on and scene.render.ibl == "split_sum"
    ibl_sampled = env_on and scene.render.ibl in ("fis", "brute_force")
    return {"ssr": ssr_on and not shell, "ibl_sampled": ibl_sampled or custom_fis, "env_light": env_on,
            "env_constant": env_constant, "traced": list(scene.materials.values()) if traced or occlusion else None,
            "dispersion": traced and dispersive(scene), "shell": shell, "glass_shadow": glass_shadows(scene),
            "env_occlusion": occlusion}


def env_occluded(scene, params, env_on: bool, traced_frame: bool) -> bool:
    """Whether a traced frame traces the environment's occlusion in the scene's BVH for
    ``params`` (its diffuse environment term, and that of the surfaces its chains meet): with the
    scene's ``raytrace_occlusion`` on, every material the environment lights in a traced frame but
    an untraced thin shell."""
    return (bool(scene.render.raytrace_occlusion) and traced_frame and env_on
            and (chain_traces(params) or not thin_shell(params)))


class ProgramSet:
    """The rasterizer's programs by key (``forward:<models>:<variant>``, ``shadow``, ...) and
    their errors. ``vao_tables()``: the vertex-array tables of everyone who drew with them
    (``MeshCache.vao_tables``). ``render_error``: the error of the last frame in hot-reload mode
    (``Renderer.render``), reported with the programs' own."""

    def __init__(self, ctx, vao_tables):
        self.ctx = ctx
        self.cache = ProgramCache(ctx, vao_tables=vao_tables)
        self.render_error: ShaderError | None = None
        self.build_fixed()

    @property
    def programs(self) -> dict:
        return self.cache.programs

    @property
    def hot_reload(self) -> bool:
        return self.cache.hot_reload

    @hot_reload.setter
    def hot_reload(self, on: bool):
        self.cache.hot_reload = bool(on)

    @property
    def last_reloaded(self) -> list[str]:
        return self.cache.last_reloaded

    def build_fixed(self):
        """(Re)compile the fixed passes. Raises ShaderError; on failure the old programs stay."""
        self.cache.build_all(FIXED)

    def get(self, key: str, recipe: Recipe):
        """The program ``key``, built from ``recipe`` on first use (raises ShaderError)."""
        return self.cache.get(key, recipe)

    def enlarge(self):
        """The program that enlarges a preview (shaders/passes/enlarge.frag), made on first use."""
        return self.get("enlarge", ENLARGE)

    def fullscreen_vao(self, prog):
        return self.cache.fullscreen_vao(prog)

    def errors(self) -> list[ShaderError]:
        """The programs that do not compile from the current files and the last frame's error,
        each once."""
        return self.cache.errors([] if self.render_error is None else [self.render_error])

    def file_brdfs(self) -> set[str]:
        return self.cache.file_brdfs()

    def keep_files(self, materials) -> None:
        self.cache.keep_files(materials)

    def reload(self, changed, passes: dict) -> list[ShaderError]:
        """Rebuild the programs whose sources changed (``ProgramCache.reload``; ``changed``:
        normalised paths or None), the next frame tries again; returns ``errors()``."""
        self.render_error = None  # the next render tries again
        self.cache.reload(changed, passes=passes)
        return self.errors()

    def forward_program(self, params, ssr: bool = False,
                        ibl_sampled: bool = False, env_light: bool = True, env_constant: bool = False,
                        traced=None, dispersion: bool = False, shell: bool = False, glass_shadow: bool = False,
                        env_occlusion: bool = False):
        """The forward program of a material and variant (``Renderer.forward_program``)."""
        key, models, defines = forward_variant(params, ssr=ssr, ibl_sampled=ibl_sampled,
                                               env_light=env_light, env_constant=env_constant, traced=traced,
                                               dispersion=dispersion, shell=shell, glass_shadow=glass_shadow,
                                               env_occlusion=env_occlusion)
        prog = self.programs.get(key)  # the per-frame path: no recipe built when cached
        if prog is not None:
            return prog
        return self.cache.get(key, Recipe(*FORWARD_STAGES, models=tuple(models),
                                          defines=tuple(defines.items())))

    def forward_keys(self, scene, raytrace: bool | None = None) -> dict[str, str]:
        """material name -> the key of the forward program a frame of ``scene`` draws it with."""
        sw = frame_switches(scene, raytrace)
        out = {}
        for name in dict.fromkeys(o.material for o in scene.objects):
            params = scene.materials[name]
            out[name] = forward_variant(params, **forward_args(scene, params, *sw))[0]
        return out

    def release(self):
        self.cache.release()
