"""A ``.brdf`` file's GLSL on the GPU: the block of ``viewer.brdf.brdffile`` compiled into an
evaluation program (directions in float textures, f or the file's sampler out of float32
targets), the evaluator ``viewer.brdf.load``'s models run their ``eval`` with.

The file goes in as a virtual include named after it (``NAME.brdf``), one GLSL line per file
line, so a compiler message reads ``NAME.brdf:LINE: message`` (``FileBrdfError``). Programs are
cached by their source text; a changed file compiles anew. Parameters go in as one float array
``u_p`` in declaration order (a bool as 0 or 1, a colour as three floats) and are copied into the
file's globals before its ``BRDF`` runs.
"""

from __future__ import annotations

import re

import numpy as np

from viewer import ViewerError
from viewer.brdf.brdffile import PREFIX, PREFIX_RE, TERM_NAMES, BrdfFile, sampler_takes_view, term_functions
from viewer.brdf.glsl_guard import over_budget_glsl, over_budget_message
from viewer.gl.context import release_gl
from viewer.gl.file_brdf_glsl import MAX_PARAMS, include_name, n_floats, param_floats, set_params_glsl, virtual_files  # noqa: F401
from viewer.gl.shaders import ShaderError, build_program

WIDTH = 256      # texels per row of the direction textures

_VERT = """#version 410 core
void main() {
    vec2 p = vec2((gl_VertexID << 1) & 2, gl_VertexID & 2);
    gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0);
}
"""


class FileBrdfError(ShaderError):
    """A ``.brdf`` file's GLSL does not compile: ``str()`` is one line ``NAME.brdf:LINE: message``."""


def _eval_fragment(bfile: BrdfFile) -> str:
    return f"""#version 410 core
#include "{include_name(bfile.path.name)}"
uniform sampler2D u_wi;
uniform sampler2D u_wo;
uniform float u_p[{max(MAX_PARAMS, n_floats(bfile))}];
out vec4 color;
void main() {{
    {set_params_glsl(bfile)}
    ivec2 px = ivec2(gl_FragCoord.xy);
    vec3 wi = texelFetch(u_wi, px, 0).xyz;
    vec3 wo = texelFetch(u_wo, px, 0).xyz;
    vec3 f = vec3({PREFIX}BRDF(wi, wo, vec3(0.0, 0.0, 1.0), vec3(1.0, 0.0, 0.0), vec3(0.0, 1.0, 0.0)));
    color = vec4(f, {over_budget_glsl(PREFIX)} ? -1.0 : 1.0);
}}
"""


def _sample_fragment(bfile: BrdfFile) -> str:
    view = "wo, " if sampler_takes_view(bfile) else ""
    return f"""#version 410 core
#include "{include_name(bfile.path.name)}"
uniform sampler2D u_wo;
uniform sampler2D u_u;
uniform float u_p[{max(MAX_PARAMS, n_floats(bfile))}];
layout(location = 0) out vec4 out_wi_pdf;
layout(location = 1) out vec4 out_weight;
void main() {{
    {set_params_glsl(bfile)}
    ivec2 px = ivec2(gl_FragCoord.xy);
    vec3 wo = texelFetch(u_wo, px, 0).xyz;
    vec2 u = texelFetch(u_u, px, 0).xy;
    vec3 wi = vec3(0.0, 0.0, 1.0);
    float pdf = 0.0;
    vec3 w = vec3({PREFIX}sampleBRDF({view}u.x, u.y, vec3(0.0, 0.0, 1.0), vec3(1.0, 0.0, 0.0), vec3(0.0, 1.0, 0.0),
                                     wi, pdf));
    out_wi_pdf = vec4(wi, pdf);
    out_weight = vec4(w, {over_budget_glsl(PREFIX)} ? -1.0 : 1.0);
}}
"""


def _terms_fragment(bfile: BrdfFile) -> str:
    """The file's D, F and G (``brdffile.term_functions``) at each direction pair, one target
    each (alpha -1 where that call reached the loop budget)."""
    calls = []
    for k, name in enumerate(TERM_NAMES):
        calls.append(f"{PREFIX}0steps = 0; out_{name} = vec4(vec3({PREFIX}{name}(wi, wo, vec3(0.0, 0.0, 1.0), "
                     f"vec3(1.0, 0.0, 0.0), vec3(0.0, 1.0, 0.0))), {over_budget_glsl(PREFIX)} ? -1.0 : 1.0);")
    outs = "\n".join(f"layout(location = {k}) out vec4 out_{n};" for k, n in enumerate(TERM_NAMES))
    body = "\n    ".join(calls)
    return f"""#version 410 core
#include "{include_name(bfile.path.name)}"
uniform sampler2D u_wi;
uniform sampler2D u_wo;
uniform float u_p[{max(MAX_PARAMS, n_floats(bfile))}];
{outs}
void main() {{
    {set_params_glsl(bfile)}
    ivec2 px = ivec2(gl_FragCoord.xy);
    vec3 wi = texelFetch(u_wi, px, 0).xyz;
    vec3 wo = texelFetch(u_wo, px, 0).xyz;
    {body}
}}
"""


def _first_error(log: str, name: str):
    """(line or None, message) of the first compiler error in a located log (``name:LINE: ...``),
    with the file's own names (the viewer's prefix taken away)."""
    pat = re.compile(r"(?P<file>[^\s:]+):(?P<line>\d+):\s*(?P<msg>.*)")
    first = None
    for raw in log.splitlines():
        m = pat.search(raw)
        if m and "error" in m.group("msg").lower():
            first = (m.group("file"), int(m.group("line")), m.group("msg"))
            if first[0] == name:
                break
    if first is None:
        return None, None
    msg = re.sub(PREFIX_RE + r"(\w+)", r"\1", first[2]).strip()
    return (first[1] if first[0] == name else None), msg


def compile_program(ctx, bfile: BrdfFile, fragment: str):
    """Compile an evaluation program of ``bfile``; FileBrdfError naming ``NAME.brdf:LINE``."""
    name = bfile.path.name
    try:
        return build_program(ctx, vertex_source=_VERT, fragment_source=fragment, virtual=virtual_files(bfile))
    except ShaderError as e:
        line, msg = _first_error(str(e), include_name(name))
        if msg is None:
            msg = re.sub(PREFIX_RE + r"(\w+)", r"\1", e.detail)
        if line is None:  # outside the file's lines: the viewer's call of BRDF / sampleBRDF
            line = (bfile.sampler if "sampleBRDF" in fragment else bfile.shader)[0]
        raise FileBrdfError(f"{name}:{line}: {msg}", name, line, detail=msg) from None


def _within_budget(bfile: BrdfFile, flags) -> None:
    """Refuse the results of a call that reached the loop budget (flag -1 at some pair)."""
    if np.any(np.asarray(flags) < 0):
        raise ViewerError(over_budget_message(bfile.path.name))


class FileEvaluator:
    """Runs files' GLSL. Without ``ctx`` it makes a headless context of its own on a thread of its
    own and does all its GL work there: a thread's current context is its own, so the caller's
    (a window's, a renderer's) is never touched. With ``ctx`` it works on that context, on the
    caller's thread."""

    def __init__(self, ctx=None):
        self._pool = None
        if ctx is None:
            from concurrent.futures import ThreadPoolExecutor

            from viewer.gl.context import create_offscreen_context

            self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="brdf-file-gl")
            ctx = self._pool.submit(create_offscreen_context).result()
        self.ctx = ctx
        self._programs: dict = {}
        self.compiles = 0

    def _on_gl(self, fn, *args):
        return fn(*args) if self._pool is None else self._pool.submit(fn, *args).result()

    def program(self, bfile: BrdfFile, kind: str = "eval"):
        frag = {"eval": _eval_fragment, "sample": _sample_fragment, "terms": _terms_fragment}[kind](bfile)
        key = (frag, bfile.glsl_block())
        hit = self._programs.get(key)
        if hit is None:
            prog = compile_program(self.ctx, bfile, frag)
            hit = (prog, self.ctx.vertex_array(prog, []))
            self.compiles += 1
            if len(self._programs) > 32:
                self._programs.clear()
            self._programs[key] = hit
        return hit

    def check(self, bfile: BrdfFile) -> None:
        """Compile the file's programs (FileBrdfError on a problem)."""
        def work():
            self.program(bfile, "eval")
            if bfile.has_sampler:
                self.program(bfile, "sample")

        self._on_gl(work)

    def _tex(self, a, w, h):
        data = np.zeros((h * w, 4), dtype="f4")
        data[: len(a), : a.shape[1]] = a
        t = self.ctx.texture((w, h), 4, data.tobytes(), dtype="f4")
        t.filter = (self.ctx.NEAREST, self.ctx.NEAREST)
        return t

    def _run(self, prog, vao, inputs: dict, n: int, n_out: int, p_floats):
        w = min(WIDTH, max(n, 1))
        h = (n + w - 1) // w
        texs = [self._tex(a, w, h) for a in inputs.values()]
        outs = [self.ctx.texture((w, h), 4, dtype="f4") for _ in range(n_out)]
        fbo = self.ctx.framebuffer(color_attachments=outs)
        try:
            for unit, (name, t) in enumerate(zip(inputs, texs)):
                t.use(unit)
                if name in prog:
                    prog[name].value = unit
            if "u_p" in prog:
                u = prog["u_p"]
                u.write(np.asarray(p_floats, "f4")[: u.array_length].tobytes())
            fbo.use()
            fbo.viewport = (0, 0, w, h)
            self.ctx.disable(self.ctx.BLEND | self.ctx.DEPTH_TEST)
            vao.render(mode=self.ctx.TRIANGLES, vertices=3)
            res = [np.frombuffer(o.read(), dtype="f4").reshape(-1, 4)[:n].astype(np.float64) for o in outs]
        finally:
            release_gl(*texs, *outs, fbo)
        return res

    def eval(self, bfile: BrdfFile, p, wi, wo) -> np.ndarray:
        """(N, 3) f of the file's BRDF for (N, 3) wi, wo (float32-rounded) in the shading frame."""
        wi = np.asarray(wi, np.float64)
        wo = np.asarray(wo, np.float64)
        n = len(wi)
        if n == 0:
            return np.zeros((0, 3))
        def work():
            prog, vao = self.program(bfile, "eval")
            return self._run(prog, vao, {"u_wi": wi, "u_wo": wo}, n, 1, param_floats(bfile, p))[0]

        out = self._on_gl(work)
        _within_budget(bfile, out[:, 3])
        return out[:, :3]

    def terms(self, bfile: BrdfFile, p, wi, wo) -> dict:
        """The file's term functions D, F, G (``brdffile.term_functions``; all three defined) at
        (N, 3) wi, wo: {"D": (N,), "F": (N, 3), "G": (N,)}, D and G from the first channel."""
        have = term_functions(bfile)
        missing = [n for n in TERM_NAMES if n not in have]
        if missing:
            raise ViewerError(f"{bfile.path.name}: no term function {', '.join(missing)} (the term view calls "
                              f"float D(vec3 L, vec3 V, vec3 N, vec3 X, vec3 Y), and F and G alike)")
        wi = np.asarray(wi, np.float64)
        wo = np.asarray(wo, np.float64)
        n = len(wi)
        if n == 0:
            return {"D": np.zeros(0), "F": np.zeros((0, 3)), "G": np.zeros(0)}

        def work():
            prog, vao = self.program(bfile, "terms")
            return self._run(prog, vao, {"u_wi": wi, "u_wo": wo}, n, len(TERM_NAMES), param_floats(bfile, p))

        d, f, g = self._on_gl(work)
        for out in (d, f, g):
            _within_budget(bfile, out[:, 3])
        return {"D": d[:, 0], "F": f[:, :3], "G": g[:, 0]}

    def sample(self, bfile: BrdfFile, p, wo, u):
        """The file's isFunc sampler: (wi, weight, pdf) for (N, 3) wo and (N, 2) u."""
        wo = np.asarray(wo, np.float64)
        u = np.asarray(u, np.float64)
        n = len(wo)
        def work():
            prog, vao = self.program(bfile, "sample")
            return self._run(prog, vao, {"u_wo": wo, "u_u": u}, n, 2, param_floats(bfile, p))

        a, b = self._on_gl(work)
        _within_budget(bfile, b[:, 3])
        return a[:, :3], b[:, :3], a[:, 3]


_SHARED: FileEvaluator | None = None


def shared_evaluator() -> FileEvaluator:
    """The process's evaluator (its own headless context on its own thread, made on first use)."""
    global _SHARED
    if _SHARED is None:
        _SHARED = FileEvaluator()
    return _SHARED
