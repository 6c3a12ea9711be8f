"""Programs built from shader files, kept so that hot reload can build them again.

``Recipe`` says how one program is built (stage files, the BRDF models of the generated
``brdf/dispatch.glsl``, ``#define``s). ``ProgramCache`` holds the renderer's programs by key,
remembers the source texts of each program in use and the errors of those that failed, and
rebuilds them from the files (``reload``), together with the programs a pass owns (IBL, SSR),
which it reaches only through the pass's ``program_recipes()`` and ``replace_program()``."""

from __future__ import annotations

from typing import NamedTuple

from viewer.gl.shaders import ShaderError, compile_sources, default_virtual, program_sources


class Recipe(NamedTuple):
    """How to build one program from the files under shader_root(): stage files, the BRDF
    models of the generated ``brdf/dispatch.glsl`` (None: no virtual files) and ``#define``s."""

    vertex: str
    fragment: str
    geometry: str | None = None
    models: tuple[str, ...] | None = ("lambert",)
    defines: tuple[tuple[str, str], ...] = ()

    def sources(self):
        virtual = {} if self.models is None else default_virtual(self.models)
        return program_sources(self.vertex, self.fragment, geometry=self.geometry, virtual=virtual,
                               defines=dict(self.defines) or None)

    def build(self, ctx):
        """Compile and link the program now (raises ShaderError)."""
        return compile_sources(ctx, *self.sources())


def texts(sources) -> tuple:
    return tuple(None if s is None else s.text for s in sources)


def files(sources) -> set[str]:
    return {f for s in sources if s is not None for f in s.files}


class ProgramCache:
    """Programs by key, built from their recipes on first use.

    ``vao_tables()`` gives the dicts (id(program) -> vertex array) of everyone who made vertex
    arrays for these programs; a program that is replaced or released takes its vertex arrays
    with it. ``hot_reload``: a build that failed is not tried again until a shader file changes."""

    def __init__(self, ctx, vao_tables=lambda: ()):
        self.ctx = ctx
        self.programs: dict[str, object] = {}
        self.hot_reload = False
        self.last_reloaded: list[str] = []
        self._vao_tables = vao_tables
        self._recipes: dict[str, Recipe] = {}  # how each program in self.programs was built
        self._good: dict[str, tuple] = {}  # the source texts of the program in use, per key
        self._failed: dict[str, tuple] = {}  # key -> (source texts or None, ShaderError)
        self._fullscreen_vaos: dict[int, object] = {}  # id(program) -> its attribute-less vertex array

    # ---------------------------------------------------------------- building
    def build_all(self, recipes: dict[str, Recipe]):
        """(Re)compile ``recipes`` now, all or none: on failure the old programs stay and the
        ShaderError is raised."""
        new = {}
        try:
            for key, recipe in recipes.items():
                new[key] = self._compile(key, recipe)
        except ShaderError:
            for p, _ in new.values():
                p.release()
            raise
        for key, (prog, text) in new.items():
            self._recipes[key] = recipes[key]
            self._install(key, prog, text)

    def _sources(self, key: str, recipe: Recipe):
        """``recipe``'s preprocessed sources, read from disk now; a failure (unreadable file)
        is remembered (``errors``) and raised."""
        try:
            return recipe.sources()
        except ShaderError as e:
            e.program = key
            self._failed[key] = (None, e)
            raise

    def _link(self, key: str, sources, text: tuple):
        """Compile ``sources`` (whose texts are ``text``); a failure is remembered and raised."""
        try:
            prog = compile_sources(self.ctx, *sources)
        except ShaderError as e:
            e.program = key
            self._failed[key] = (text, e)
            raise
        self._failed.pop(key, None)
        return prog

    def _compile(self, key: str, recipe: Recipe):
        """(program, its source texts); a failure is remembered and raised."""
        sources = self._sources(key, recipe)
        text = texts(sources)
        return self._link(key, sources, text), text

    def fullscreen_vao(self, prog):
        """The attribute-less vertex array of a fullscreen program, made on first use."""
        vao = self._fullscreen_vaos.get(id(prog))
        if vao is None:
            vao = self._fullscreen_vaos[id(prog)] = self.ctx.vertex_array(prog, [])
        return vao

    def _drop_program(self, prog):
        """Release a program and every vertex array made for it (all are keyed by its id)."""
        vaos = [self._fullscreen_vaos.pop(id(prog), None)] + [t.pop(id(prog), None) for t in self._vao_tables()]
        for v in vaos:
            if v is not None:
                v.release()
        prog.release()

    def _install(self, key: str, prog, text: tuple):
        """Put ``prog`` (built from sources ``text``) in use under ``key``; the program it
        replaces is released only now."""
        old = self.programs.get(key)
        self.programs[key] = prog
        self._good[key] = text
        if old is not None and old is not prog:
            self._drop_program(old)

    def get(self, key: str, recipe: Recipe):
        """The cached program ``key``, built from ``recipe`` on first use. In hot-reload mode a
        build that failed is not tried again until a shader file changes (``reload``)."""
        prog = self.programs.get(key)
        if prog is not None:
            return prog
        self._recipes[key] = recipe
        failed = self._failed.get(key)
        if failed is not None and self.hot_reload:
            raise failed[1]
        prog, text = self._compile(key, recipe)
        self._install(key, prog, text)
        return prog

    # ---------------------------------------------------------------- hot reload
    def errors(self, extra=()) -> list[ShaderError]:
        """The programs that do not compile from the current files, and ``extra`` errors, each
        error once."""
        out, seen = [], set()
        for e in [e for _, e in self._failed.values()] + list(extra):
            k = (e.file, e.line, e.detail)
            if k not in seen:
                seen.add(k)
                out.append(e)
        return out

    def _slots(self, passes: dict):
        """(key, recipe, install) of every program that can be rebuilt: this cache's, and those
        of ``passes`` ({prefix: a pass with program_recipes() / replace_program(name, prog)})."""
        slots = [(k, r, lambda p, t, k=k: self._install(k, p, t)) for k, r in list(self._recipes.items())]
        for prefix, owner in passes.items():
            if owner is None:
                continue
            for name, recipe in owner.program_recipes().items():
                slots.append((f"{prefix}:{name}", recipe, lambda p, t, o=owner, n=name: o.replace_program(n, p)))
        return slots

    def reload(self, changed=None, passes: dict | None = None) -> None:
        """Rebuild programs from the shader files as they are now.

        ``changed``: paths relative to shader_root() that changed, or None for all. A program
        is compiled again only if its preprocessed sources differ from those of the program in
        use (or, for the passes' programs, if it includes a changed file), or if it failed
        before and its sources changed since. A program that compiles replaces the old one,
        which is released only then; one that fails keeps the old one in use. Never raises
        ShaderError. ``last_reloaded`` lists the keys of the programs replaced."""
        self.last_reloaded = []
        for key, recipe, install in self._slots(passes or {}):
            failed = self._failed.get(key)
            good = self._good.get(key)
            try:
                sources = self._sources(key, recipe)
            except ShaderError:
                continue
            text = texts(sources)
            if failed is not None and failed[0] == text:
                continue  # the same sources as the failed attempt: the same error
            if text == good:
                self._failed.pop(key, None)  # back to the sources of the program in use
                continue
            if failed is None and good is None and changed is not None and not (files(sources) & changed):
                continue
            try:
                prog = self._link(key, sources, text)
            except ShaderError:
                continue
            self._good[key] = text
            install(prog, text)
            self.last_reloaded.append(key)

    def keys(self) -> list[str]:
        """The keys of this cache's programs (not the passes' own, which ``reload`` also reaches)."""
        return list(self._recipes)

    def relink(self, keys=None) -> list[str]:
        """Link this cache's programs again from the same sources: ``keys`` (None: all). Where
        the driver keeps a cache of linked programs (Mesa's, on disk), each is then linked from
        it, as every process that links it later does, with no machine code of its own yet:
        llvmpipe keys the code a program makes for a new state by whether its earlier code was
        made in this process or read from the disk cache, so only a program whose code so far
        was all read finds the code another process (the compile-ahead child) made for the next
        state. Each program that links
        replaces the old one (and its vertex arrays); one that fails, or whose files changed
        since (hot reload's to build and report), keeps the old one. Never raises ShaderError.
        Returns the keys relinked."""
        out = []
        for key in self.keys() if keys is None else [k for k in keys if k in self._recipes]:
            try:
                sources = self._sources(key, self._recipes[key])
                text = texts(sources)
                if text != self._good.get(key):
                    continue
                prog = self._link(key, sources, text)
            except ShaderError:
                continue
            self._install(key, prog, text)
            out.append(key)
        return out

    def file_brdfs(self) -> set[str]:
        """The paths of the ``.brdf`` files the programs hold (their models ``custom:PATH``)."""
        from viewer.gl.brdf_glsl import CUSTOM_PREFIX, is_custom

        out = set()
        for r in self._recipes.values():
            out.update(m[len(CUSTOM_PREFIX):] for m in (r.models or ()) if is_custom(m))
        return out

    def keep_files(self, materials) -> None:
        """Drop the programs holding a ``.brdf`` file that none of ``materials`` (the scene a
        frame draws) uses: the program, its recipe and its error. A file the scene no longer
        holds is then neither reported (``errors``: its last compile's error would stand beside
        the file now in use) nor watched or rebuilt by hot reload; a material that takes the
        file again compiles it again (its verdicts and the driver's cache are per content)."""
        held = self.file_brdfs()
        if not held:
            return  # the per-frame path of a scene without file materials
        from viewer.gl.brdf_glsl import CUSTOM_PREFIX, is_custom, models_used

        used = {m[len(CUSTOM_PREFIX):] for p in materials for m in models_used(p) if is_custom(m)}
        if held <= used:
            return
        for key in [k for k, r in self._recipes.items()
                    if any(is_custom(m) and m[len(CUSTOM_PREFIX):] not in used for m in (r.models or ()))]:
            self._recipes.pop(key)
            self._good.pop(key, None)
            self._failed.pop(key, None)
            prog = self.programs.pop(key, None)
            if prog is not None:
                self._drop_program(prog)

    def release(self):
        for v in self._fullscreen_vaos.values():
            v.release()
        self._fullscreen_vaos.clear()
        for p in self.programs.values():
            p.release()
        self.programs.clear()


FORWARD_STAGES = ("passes/forward.vert", "passes/forward.frag", "passes/forward.geom")


def forward_variant(params, *, ssr: bool = False, ibl_sampled: bool = False,
                    env_light: bool = True, env_constant: bool = False, traced=None,
                    dispersion: bool = False, shell: bool = False, glass_shadow: bool = False,
                    env_occlusion: bool = False) -> tuple[str, tuple[str, ...], dict[str, str]]:
    """(cache key, BRDF models, ``#define``s) of the forward program that draws a material.

    Its models are the material's (and a nested base's); ``traced``: the scene's materials
    when the material's specular chain is traced (viewer/gl/raytrace.py; the chain may hit any
    of them), ``dispersion`` traces each colour channel's chain apart. ``ibl_sampled`` compiles
    in the per-pixel environment sampling of the fis and brute_force modes (software GL pays
    for untaken loops). ``shell``: a thin shell (a dielectric of ior 1), drawn after the opaque
    objects with dual-source blending (its transmittance multiplies what lies behind it; never
    with SSR's extra outputs). ``glass_shadow``: the lights pass through the glass casters' atlas
    (viewer/gl/shadow.py; a scene with glass and shadows). ``env_occlusion``: the diffuse
    environment term is traced for occlusion in the scene's BVH (a traced frame; it makes the
    program read the scene's textures as ``traced`` does). The materials' own variants come from
    ``program_defines``."""
    from viewer.gl.brdf_glsl import models_used, program_defines
    from viewer.gl.raytrace import chain_traces

    if shell and ssr:
        raise ValueError("a thin shell's program has no SSR outputs (it blends into the radiance alone)")
    used = models_used(params)
    materials = [params]
    if traced is not None:
        traced = list(traced)
    elif env_occlusion:
        raise ValueError("environment occlusion traces the scene: pass its materials as traced")
    if traced is not None:
        scene_models = sorted(dict.fromkeys(m for p in traced for m in models_used(p)))
        used = tuple(dict.fromkeys(used + tuple(scene_models)))
        materials += traced
    flags = {"SSR": ssr, "IBL_SAMPLED": ibl_sampled, "ENV_LIGHT": env_light,
             "ENV_CONSTANT": env_constant, "RAYTRACE": traced is not None and chain_traces(params),
             "MAT_TEXTURE": traced is not None,
             "RT_DISPERSION": traced is not None and dispersion, "THIN_SHELL": shell,
             "GLASS_SHADOW": glass_shadow, "ENV_OCCLUSION": env_occlusion}
    defines = {k: "1" for k, on in flags.items() if on}
    defines.update(program_defines(materials))
    key = ("forward:" + "+".join(used) + (":ssr" if ssr else "")
           + (":iblsampled" if ibl_sampled else "") + (":env" if env_light else "")
           + (":const" if env_constant else "") + (":rt" if traced is not None else "")
           + (":disp" if traced is not None and dispersion else "") + (":film" if "THIN_FILM" in defines else "")
           + (":coatfilm" if "COAT_FILM" in defines else "")
           + (":aniso" if "MEASURED_ANISO" in defines else "") + (":shell" if "THIN_SHELL" in defines else "")
           + (":gshadow" if glass_shadow else "") + (":envocc" if env_occlusion else ""))
    return key, used, defines
