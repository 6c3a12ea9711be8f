"""Texture units come from one table (viewer/gl/texture_units.py): no two textures a program
reads share a unit, none lies past the 16 units OpenGL 4.1 guarantees, and the programs a
traced, shadowed, environment-lit and screen-space-reflected frame builds point every sampler
at a unit of its own."""

from __future__ import annotations

from viewer.gl import texture_units
from viewer.gl.texture_units import PROGRAMS, collisions

# GL sampler types: 1D .. 2D_RECT_SHADOW, the array / buffer / integer samplers, multisample
_SAMPLER_TYPES = set(range(0x8B5D, 0x8B65)) | set(range(0x8DC0, 0x8DD9)) | set(range(0x9108, 0x910E))


def test_the_table_has_no_collisions():
    assert len(PROGRAMS["forward"]) >= 5
    assert collisions() == []


def test_the_collision_check_can_fail():
    bad = {"p": {"a": (0, 2), "b": (1, 1), "c": (15, 2)}, "q": {"a": (0, 1), "b": (1, 1)}}
    assert collisions(bad) == ["p: a and b share unit 1", "p: c reaches unit 16, past the 16 units"]


def test_the_units_a_pass_takes_are_the_table_s():
    """The passes start where the table says, and the traced chains take as many units."""
    import inspect

    from viewer.gl.ibl import IBL
    from viewer.gl.raytrace import RayTrace
    from viewer.gl.scene_textures import SAMPLERS
    from viewer.gl.shadow import ShadowMaps

    assert inspect.signature(IBL.bind).parameters["first_unit"].default == texture_units.IBL
    assert inspect.signature(RayTrace.bind).parameters["first_unit"].default == texture_units.TRACED
    assert inspect.signature(ShadowMaps.bind).parameters["unit"].default == texture_units.SHADOW_ATLAS
    assert len(SAMPLERS) + 1 == texture_units.TRACED_COUNT   # the BVH's textures and the material rows


def _samplers(prog) -> dict[str, int]:
    out = {}
    for name in prog:
        u = prog[name]
        if getattr(u, "gl_type", None) in _SAMPLER_TYPES:
            out[name] = int(u.value)
    return out


def test_a_full_frame_s_programs_read_each_unit_once(gl_ctx):
    from viewer.gl.renderer import Renderer
    from viewer.scene import load_scene

    scene = load_scene("gallery", ["render.raytrace=true", "render.ssr=true", "render.shadows=true"])
    r = Renderer(gl_ctx)
    try:
        r.render(scene, None, 48, 32, msaa=0)
        checked = 0
        for key, prog in r.programs.items():
            units = _samplers(prog)
            if len(units) < 2:
                continue
            checked += 1
            by_unit: dict[int, list[str]] = {}
            for name, u in units.items():
                by_unit.setdefault(u, []).append(name)
            assert all(len(v) == 1 for v in by_unit.values()), (key, by_unit)
        assert checked >= 2
    finally:
        r.release()


_ROOT = __import__("pathlib").Path(__file__).resolve().parents[1]
_SAMPLER_DECL = __import__("re").compile(r"uniform\s+\w*sampler\w*\s+(\w+)")


def sampler_names() -> set[str]:
    """Every sampler uniform declared in the shaders or in GLSL written in Python."""
    files = [p for p in (_ROOT / "shaders").rglob("*") if p.suffix in (".glsl", ".frag", ".vert", ".geom")]
    files += list((_ROOT / "viewer").rglob("*.py"))
    return {m for f in files for m in _SAMPLER_DECL.findall(f.read_text())}


def literal_units(source: str, samplers: set[str]) -> list[str]:
    """``line: what`` of every texture unit written as a number: ``tex.use(3)``,
    ``tex.use(location=3)``, ``_set(prog, "u_tex", 3)`` / ``set_uniform(...)`` and
    ``prog["u_tex"].value = 3`` for a sampler ``u_tex``."""
    import ast

    def is_int(n):
        return isinstance(n, ast.Constant) and type(n.value) is int

    out = []
    for n in ast.walk(ast.parse(source)):
        if isinstance(n, ast.Call):
            f = n.func
            name = f.attr if isinstance(f, ast.Attribute) else getattr(f, "id", None)
            if name == "use" and any(is_int(a) for a in [*n.args, *(k.value for k in n.keywords if k.arg == "location")]):
                out.append(f"{n.lineno}: use")
            elif (name in ("_set", "set_uniform") and len(n.args) >= 3 and isinstance(n.args[1], ast.Constant)
                  and n.args[1].value in samplers and is_int(n.args[2])):
                out.append(f"{n.lineno}: {n.args[1].value}")
        elif isinstance(n, ast.Assign) and len(n.targets) == 1:
            t = n.targets[0]
            if (isinstance(t, ast.Attribute) and t.attr == "value" and isinstance(t.value, ast.Subscript)
                    and isinstance(t.value.slice, ast.Constant) and t.value.slice.value in samplers and is_int(n.value)):
                out.append(f"{n.lineno}: {t.value.slice.value}")
    return sorted(out, key=lambda s: int(s.split(":")[0]))


def test_units_are_named_only_in_the_table():
    """No module of ours writes a texture unit as a number: each is a name in texture_units.py."""
    samplers = sampler_names()
    assert {"u_env_map", "u_hdr", "u_back", "u_refl", "u_src"} <= samplers
    texts = {f: f.read_text() for f in sorted((_ROOT / "viewer").rglob("*.py")) if f.name != "texture_units.py"}
    bad = [f"{f.relative_to(_ROOT)}:{hit}" for f, text in texts.items()
           if ".use(" in text or "].value" in text or "_set(" in text or "set_uniform(" in text
           for hit in literal_units(text, samplers)]
    assert bad == []


def test_the_literal_unit_scan_can_fail():
    src = ("def f(prog, tex, fbo, red, k):\n"
           "    tex.use(0)\n"
           "    tex.use(location=12)\n"
           "    _set(prog, 'u_back', 12)\n"
           "    red['u_refl'].value = 1\n"
           "    fbo.use()\n"                       # a framebuffer: no unit
           "    tex.use(location=texture_units.SSR_BACK)\n"
           "    _set(prog, 'u_level', 0)\n"        # not a sampler
           "    red['u_count'].value = k\n")
    assert literal_units(src, {"u_back", "u_refl"}) == ["2: use", "3: use", "4: u_back", "5: u_refl"]
