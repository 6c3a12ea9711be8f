"""A program drawn again compiles nothing: llvmpipe makes a program's machine code at its first
draw for the state in use, which includes the kind of texture at every unit its samplers name
(viewer/gl/unit_fill.py). The forward pass's optional units (a frame without shadows still names
the shadow atlas's unit) must hold the same kind of texture whatever an earlier pass or lecture
step left there. Checked on state: the kind of texture (format, filter, wrap, comparison) at each
sampler's unit at every draw, read from GL, and the programs linked; no timing."""

import ctypes

import moderngl
import pytest

_GL = None
# the binding queries and targets of the sampler types the shaders declare
_TARGETS = {0x8B5E: (0x8069, 0x0DE1), 0x8B62: (0x8069, 0x0DE1),   # sampler2D, sampler2DShadow
            0x8DC1: (0x8C1D, 0x8C1A), 0x8B5F: (0x806A, 0x806F)}   # sampler2DArray, sampler3D


def _gl():
    global _GL
    if _GL is None:
        _GL = ctypes.CDLL("libGL.so.1")  # GLVND dispatches to the current (EGL) context
    return _GL


def _geti(pname) -> int:
    v = ctypes.c_int()
    _gl().glGetIntegerv(pname, ctypes.byref(v))
    return v.value


def _sampler_units(glo: int) -> tuple:
    """(name, GL type, unit) of every sampler of program ``glo``."""
    gl, out = _gl(), []
    n = ctypes.c_int()
    gl.glGetProgramiv(glo, 0x8B86, ctypes.byref(n))  # GL_ACTIVE_UNIFORMS
    for i in range(n.value):
        name, length, size, kind = ctypes.create_string_buffer(256), ctypes.c_int(), ctypes.c_int(), ctypes.c_uint()
        gl.glGetActiveUniform(glo, i, 256, ctypes.byref(length), ctypes.byref(size), ctypes.byref(kind), name)
        if kind.value in _TARGETS:
            unit = ctypes.c_int()
            gl.glGetUniformiv(glo, gl.glGetUniformLocation(glo, name.value), ctypes.byref(unit))
            out.append((name.value.decode(), kind.value, unit.value))
    return tuple(out)


def _kinds(glo: int) -> tuple:
    """What each sampler of program ``glo`` reads now: (name, internal format, min filter,
    wrap s, compare mode) of the texture bound at its unit, or None for no texture."""
    gl, out = _gl(), []
    active = _geti(0x84E0)  # GL_ACTIVE_TEXTURE
    for name, kind, unit in _sampler_units(glo):
        query, target = _TARGETS[kind]
        gl.glActiveTexture(0x84C0 + unit)
        if not _geti(query):
            out.append((name, None))
            continue
        fmt, mn, wrap, cmp = (ctypes.c_int() for _ in range(4))
        gl.glGetTexLevelParameteriv(target, 0, 0x1003, ctypes.byref(fmt))  # GL_TEXTURE_INTERNAL_FORMAT
        gl.glGetTexParameteriv(target, 0x2801, ctypes.byref(mn))   # GL_TEXTURE_MIN_FILTER
        gl.glGetTexParameteriv(target, 0x2802, ctypes.byref(wrap))  # GL_TEXTURE_WRAP_S
        gl.glGetTexParameteriv(target, 0x884C, ctypes.byref(cmp))   # GL_TEXTURE_COMPARE_MODE
        out.append((name, fmt.value, mn.value, wrap.value, cmp.value))
    gl.glActiveTexture(active)
    return tuple(out)


class _Recorder:
    """Records (program, what its samplers read) at every draw, and the programs linked."""

    def __init__(self, ctx, monkeypatch):
        self.draws: list = []
        self.links = 0
        render, program = moderngl.VertexArray.render, ctx.program

        def recorded(vao, *args, **kwargs):
            self.draws.append((vao.program.glo, _kinds(vao.program.glo)))
            return render(vao, *args, **kwargs)

        def linked(*args, **kwargs):
            self.links += 1
            return program(*args, **kwargs)

        monkeypatch.setattr(moderngl.VertexArray, "render", recorded)
        monkeypatch.setattr(ctx, "program", linked)

    def take(self):
        draws, links = set(self.draws), self.links
        self.draws, self.links = [], 0
        return draws, links


def _leave(ctx, components: int, dtype: str, mipmaps: bool):
    """Bind a texture of another kind to every unit, as an earlier pass may leave one there."""
    tex = ctx.texture((4, 4), components, bytes(16 * components * (4 if dtype == "f4" else 1)), dtype=dtype)
    if mipmaps:
        tex.build_mipmaps()
    for unit in range(16):
        tex.use(location=unit)
    return tex


def test_what_an_earlier_pass_left_on_a_unit_does_not_change_what_a_program_reads(gl_ctx, monkeypatch):
    from viewer.gl.renderer import Renderer
    from viewer.scene import load_scene

    scene = load_scene("sphere", ["render.shadows=false"])  # its programs name the shadow atlas all the same
    r = Renderer(gl_ctx)
    rec = _Recorder(gl_ctx, monkeypatch)
    left = []
    try:
        r.render(scene, None, 24, 16, msaa=0)  # its maps, tables and programs made
        rec.take()
        seen = []
        for components, dtype, mipmaps in ((4, "f4", False), (3, "f4", True), (4, "f1", False)):
            left.append(_leave(gl_ctx, components, dtype, mipmaps))
            r.render(scene, None, 24, 16, msaa=0)
            seen.append(rec.take()[0])
        forward = {glo for glo, kinds in seen[0] if any(k[0] == "u_shadow_atlas" for k in kinds)}
        assert forward  # the forward programs name the shadow atlas's unit (shadows off or on)
        assert seen[1] == seen[0] and seen[2] == seen[0], sorted(seen[1] ^ seen[0], key=str)[:4]
    finally:
        r.release()
        for t in left:
            t.release()


@pytest.mark.slow  # the 15 lecture steps drawn twice in a session, tiles and traced strips: minutes on 2 loaded cores
def test_every_lecture_step_drawn_again_compiles_nothing(gl_ctx, monkeypatch):
    from viewer.app.session import Session
    from viewer.gl.renderer import Renderer
    from viewer.scene.lecture import TOUR, tour_scene

    r = Renderer(gl_ctx)
    s = Session(gl_ctx, "default", renderer=r, prefetch=False, compile_ahead=False, tiled_frames=True)
    size = (96, 64)

    def settle(limit=400):
        for _ in range(limit):
            s.render_view(size)
            if not [w for w in s.pending_work() if w != "warm-up"]:  # no child: warm-up never ends
                return
        raise AssertionError("the view did not settle")

    try:
        settle()
        rec = _Recorder(gl_ctx, monkeypatch)
        first: set = set()
        n = len(TOUR)
        for i in range(n):
            s.scene = tour_scene(i)
            s.changed()
            settle()
            first |= rec.take()[0]
        traced = 0
        for i in reversed(range(n)):  # each step after another step than the first time
            s.scene = tour_scene(i)
            s.changed()
            settle()
            draws, links = rec.take()
            assert links == 0, f"step {i + 1} linked {links} programs again"
            assert draws <= first, f"step {i + 1}: {sorted(draws - first, key=str)[:2]}"
            traced += any(k[0] == "u_bvh_nodes" for _, kinds in draws for k in kinds)
        assert traced >= 5  # the traced steps drew their traced programs
    finally:
        s.release()
        r.release()
