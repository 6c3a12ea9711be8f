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
