"""The generated header of the constants Python and GLSL share (viewer/gl/constants.py, included
as ``generated/constants.glsl``): its values are Python's, every shader that uses one of its
names includes it first, and no shader compares a parameter choice or a mode against a bare
number (a number whose meaning lives in Python's lists would silently go stale)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from viewer import brdf
from viewer.gl import constants
from viewer.gl.shaders import GENERATED_CONSTANTS, preprocess, shader_root

SHADERS = Path(__file__).resolve().parents[1] / "shaders"
INCLUDE = f'#include "{GENERATED_CONSTANTS}"'


def _header_values() -> dict[str, int]:
    """The header as the shader loader gives it to a program, parsed back."""
    text = preprocess(f"#version 410 core\n{INCLUDE}\n", "<test>").text
    return {m.group(1): int(m.group(2)) for m in re.finditer(r"^#define (\w+) (-?\d+)$", text, re.M)}


def _shader_files() -> list[Path]:
    files = sorted(p for p in SHADERS.rglob("*") if p.suffix in (".glsl", ".frag", ".vert", ".geom"))
    assert len(files) > 30
    return files


def test_lobe_flags_are_the_python_intflag():
    """LOBE_<FLAG> of the header, as a program sees it, is viewer/brdf/lobes.py's Lobe bit for bit
    (unsigned: the GLSL lobes are uint), the unions included; and the bits are pbrt-v4's
    BxDFFlags (Reflection 1, Transmission 2, Diffuse 4, Glossy 8, Specular 16)."""
    from viewer.brdf import lobes
    from viewer.brdf.lobes import Lobe

    text = preprocess(f"#version 410 core\n{INCLUDE}\n", "<test>").text
    got = {m.group(1): int(m.group(2)) for m in re.finditer(r"^#define (LOBE_\w+) (\d+)u$", text, re.M)}
    want = {f"LOBE_{f.name}": int(f) for f in Lobe} | {"LOBE_NONE": 0, "LOBE_SMOOTH": int(lobes.SMOOTH),
                                                       "LOBE_SIDES": int(lobes.SIDES), "LOBE_KINDS": int(lobes.KINDS)}
    assert got == want == constants.lobe_values()
    assert (got["LOBE_REFLECTION"], got["LOBE_TRANSMISSION"], got["LOBE_DIFFUSE"], got["LOBE_GLOSSY"],
            got["LOBE_DELTA"]) == (1, 2, 4, 8, 16)
    assert not re.search(r"^#define LOBE_\w+ \d+$", text, re.M)  # every one unsigned


def test_header_values_are_pythons():
    from viewer.brdf.albedo import TABLE_SIZE
    from viewer.gl import ibl, raytrace, renderer
    from viewer.gpupt import engine

    h = _header_values()
    # choice ids: the index in each spec's choice list, nested tables included
    n_choices = 0

    def walk(prefix, params):
        nonlocal n_choices
        for p in params:
            if p.kind == "choice":
                for i, c in enumerate(p.choices):
                    assert h[constants.glsl_name(*prefix, p.name, c)] == i, (prefix, p.name, c)
                    n_choices += 1
            elif p.kind in ("table", "lobes"):
                walk(prefix + (p.name,), p.fields)

    for name in brdf.names():
        walk((name,), brdf.get(name).spec.params)
    assert n_choices > 40
    assert h["MICROFACET_FRESNEL_DIELECTRIC"] == 0 and h["MIRROR_FRESNEL_CONDUCTOR"] == 0  # per model
    # sizes and modes, as the modules that use them see them
    assert h["MAX_LIGHTS"] == renderer.MAX_LIGHTS == 16
    assert h["SHADOW_LIGHTS"] == constants.SHADOW_LIGHTS == 4
    assert h["ALBEDO_TABLE"] == TABLE_SIZE
    assert h["IBL_MAX_LEVELS"] == ibl.MAX_LEVELS
    assert h["MAX_MATERIALS"] == engine.MAX_MATERIALS
    for prefix, table in (("TONEMAP", renderer.TONEMAPS), ("IBL_MODE", renderer.IBL_MODES),
                          ("VIEW_MODE", renderer.VIEW_MODES), ("STRATEGY", constants.STRATEGIES),
                          ("ENV_MODE", constants.ENV_MODES),
                          ("LIGHT", constants.LIGHT_TYPES), ("SSR_DEBUG", constants.SSR_DEBUG)):
        for k, v in table.items():
            assert h[constants.glsl_name(prefix, k)] == v, (prefix, k)
    assert h["VIEW_MODE_SSR_HIT"] - renderer.SSR_VIEW_BASE == h["SSR_DEBUG_HIT"]
    assert (h["RT_T_ALBEDO"], h["RT_T_INFO"], h["RT_T_K"], h["CHAIN_ROW_TEXELS"]) == (
        raytrace.T_ALBEDO, raytrace.T_INFO, raytrace.T_K, raytrace.ROW_TEXELS)
    from viewer.brdf import spectral_fresnel
    from viewer.geometry import bvh_flat
    from viewer.gl import brdf_glsl

    assert h["SPECTRAL_TABLE_N"] == spectral_fresnel.TABLE_N
    assert h["BVH_STACK"] == bvh_flat.STACK_SIZE
    assert h["MAT_FLOATS"] == 4 * brdf_glsl.MAT_VEC4 == len(brdf_glsl.uniform_block(brdf.get("lambert").params())[1])
    from viewer.pathtracer import integrator

    assert h["RR_START_DEPTH"] == integrator.RR_START_DEPTH == 4   # the CPU engine's, which the GPU engine's pass reads
    from viewer.pathtracer import spectral

    assert h["SPEC_STRIDE"] == spectral.STRIDE == 105
    assert h == constants.values()


def _header_floats() -> dict[str, float]:
    text = preprocess(f"#version 410 core\n{INCLUDE}\n", "<test>").text
    return {m.group(1): float(m.group(2))
            for m in re.finditer(r"^#define (\w+) (-?\d+\.\d*(?:e[+-]?\d+)?|-?\d+e[+-]?\d+)$", text, re.M)}


def test_header_floats_are_pythons():
    """The empty depth of the SSR pyramid, the reference estimator's roulette bounds and ray
    offset, and the term views' scales, as their modules see them."""
    from viewer.image import term_scales
    from viewer.gl import ssr
    from viewer.pathtracer import compiled, integrator

    f = _header_floats()
    assert f == constants.float_values() and len(f) == 8 + 2 * len(term_scales.SCALES)
    assert (f["RR_MIN"], f["RR_MAX"], f["EPS_REL"]) == (integrator.RR_MIN, integrator.RR_MAX, compiled.EPS_REL)
    assert (f["RR_MIN"], f["RR_MAX"], f["EPS_REL"]) == (0.05, 0.95, 1e-4)
    from viewer.pathtracer import spectral

    assert (f["SPEC_N_BINS"], f["SPEC_HERO"]) == (spectral.N_BINS, spectral.HERO) == (420, 4)
    assert f["EMPTY_DEPTH"] == ssr.EMPTY_DEPTH == 1e30
    assert f["TERM_NOT_APPLICABLE"] == term_scales.NOT_APPLICABLE
    from viewer.reference_common import caustics

    assert f["PHOTON_NORMAL_COS"] == caustics.NORMAL_COS
    for view, (_, k, vmax) in term_scales.SCALES.items():
        assert (f[constants.glsl_name("TERM", view, "K")], f[constants.glsl_name("TERM", view, "MAX")]) == (k, vmax)


def test_no_shader_defines_a_generated_name():
    """A value the header carries is not written again in a shader (``#define`` or ``const``)."""
    names = set(constants.values()) | set(constants.float_values())
    pat = re.compile(r"^\s*(?:#\s*define\s+(\w+)|const\s+\w+\s+(\w+)\s*=)")
    bad = [f"{f.relative_to(SHADERS)}:{n}: {m.group(1) or m.group(2)}"
           for f in _shader_files() for n, line in enumerate(f.read_text().splitlines(), start=1)
           if (m := pat.match(line)) and (m.group(1) or m.group(2)) in names]
    assert bad == []


def test_the_rec709_weights_are_written_once_a_side():
    """Python: ``viewer.spectral.colorimetry.LUMINANCE_REC709``; GLSL: ``luminance`` in
    common/math.glsl. Everything else calls them."""
    root = SHADERS.parent
    hits = sorted(str(f.relative_to(root)) for f in [*root.joinpath("viewer").rglob("*.py"), *_shader_files()]
                  if "0.7152" in f.read_text())
    assert hits == ["shaders/common/math.glsl", "viewer/spectral/colorimetry.py"]


def test_inv_pi_is_written_once_a_side():
    """GLSL: ``INV_PI`` in common/math.glsl, which the GLSL generated in Python (viewer/gl) uses
    too; Python: ``1 / np.pi``, never its digits."""
    root = SHADERS.parent
    hits = sorted(str(f.relative_to(root)) for f in [*root.joinpath("viewer").rglob("*.py"), *_shader_files()]
                  if "0.3183098" in f.read_text())
    assert hits == ["shaders/common/math.glsl"]


def ray_offsets(text: str) -> list[str]:
    """``line: code`` of every relative ray offset written as its number (``1e-4 * (1.0 + ...``)
    instead of ``EPS_REL`` (viewer/geometry/soup.py, in the header); comments are ignored."""
    pat = re.compile(r"(?<![\w.])(?:1(?:\.0*)?e-0*4|0?\.0001)\s*\*\s*\(\s*1(?:\.0*)?\s*\+")
    return [f"{n}: {line.strip()}" for n, line in enumerate(text.splitlines(), start=1)
            if pat.search(line.split("//")[0])]


def test_ray_offsets_are_eps_rel():
    """Both reference engines and the rasterizer's traced chains offset rays by ``EPS_REL``."""
    root = SHADERS.parent
    bad = [f"{f.relative_to(root)}:{hit}" for f in [*root.joinpath("viewer").rglob("*.py"), *_shader_files()]
           for hit in ray_offsets(f.read_text())]
    assert bad == []
    uses = {f.relative_to(SHADERS).as_posix() for f in _shader_files() if "EPS_REL * (1.0 +" in f.read_text()}
    assert uses == {"passes/pathtrace.frag", "pathtrace/spectral.glsl", "pathtrace/surface.glsl",
                    "common/specular_chain.glsl"}


@pytest.mark.parametrize("code", ["float eps = 1e-4 * (1.0 + max3(abs(p)));", "eps = 1e-4 * (1 + np.abs(p).max(1))",
                                  "float e = 0.0001*(1.0+m);"])
def test_the_ray_offset_scan_can_fail(code):
    assert ray_offsets("x\n" + code + "\n") == [f"2: {code}"]


def test_the_header_is_generated_wherever_shaders_are_read(tmp_path, monkeypatch):
    """Not a file: an empty shader folder (BRDF_VIEWER_SHADERS elsewhere, an installed copy)
    still gets it."""
    monkeypatch.setenv("BRDF_VIEWER_SHADERS", str(tmp_path))
    assert shader_root() == tmp_path.resolve()
    assert _header_values() == constants.values()


def test_files_include_the_header_before_using_it():
    """Each file that uses a generated name includes the header itself, above the first use
    (an include further down compiles only where another file happened to include it first)."""
    names = set(constants.values()) | set(constants.float_values())
    bad = []
    for f in _shader_files():
        lines = f.read_text().splitlines()
        inc = next((i for i, l in enumerate(lines) if l.strip() == INCLUDE), None)
        first = next((i for i, l in enumerate(lines)
                      if set(re.findall(r"\b[A-Z][A-Z0-9_]*\b", l.split("//")[0])) & names), None)
        if first is not None and (inc is None or inc > first):
            bad.append(f"{f.relative_to(SHADERS)}:{first + 1}")
    assert bad == []


# mode uniforms and the locals / defines that carry a mode or a choice id
MODE_NAMES = ("u_view_mode", "u_ibl_mode", "u_tonemap", "u_debug", "u_light_type", "mode", "dist", "kind",
              "hkind", "fr", "ENV_MODE", "STRATEGY")


def choice_fields() -> set[str]:
    out = set()

    def walk(params):
        for p in params:
            if p.kind == "choice":
                out.add(p.name)
            elif p.kind in ("table", "lobes"):
                walk(p.fields)

    for name in brdf.names():
        walk(brdf.get(name).spec.params)
    return out


def bare_id_comparisons(text: str, fields, modes=MODE_NAMES) -> list[str]:
    """``line: code`` of every comparison of a choice field (``x.field``) or a mode name with an
    integer literal, either way round; comments are ignored."""
    f = "|".join(sorted(map(re.escape, fields)))
    m = "|".join(sorted(map(re.escape, modes)))
    ident = rf"(?:\.\s*(?:{f})\b|(?<![\w.])(?:{m})\b(?:\s*\[[^\]]*\])?)"
    op = r"(?:==|!=|<=|>=|<|>)"
    num = r"-?\d+(?![\w.])"
    pats = [re.compile(rf"{ident}\s*{op}\s*{num}"), re.compile(rf"(?<![\w.]){num}\s*{op}\s*(?:\w+)?{ident}")]
    out = []
    for n, line in enumerate(text.splitlines(), start=1):
        code = line.split("//")[0]
        if any(p.search(code) for p in pats):
            out.append(f"{n}: {line.strip()}")
    return out


def test_no_shader_compares_a_choice_or_a_mode_with_a_bare_number():
    fields = choice_fields()
    assert {"fresnel", "distribution", "shadowing", "variant", "spectral"} <= fields
    bad = [f"{f.relative_to(SHADERS)}:{hit}" for f in _shader_files()
           for hit in bare_id_comparisons(f.read_text(), fields)]
    assert bad == []


@pytest.mark.parametrize("code", [
    "if (p.fresnel == 0) return x;", "return p.fresnel != 2 ? a : b;", "if (p.spectral > 0) f();",
    "bool b = 1 == p.distribution;", "if (u_view_mode <= 3) {", "bool pt = u_light_type[i] == 0;",
    "if (mode == 1) return c;", "#if ENV_MODE != 0", "if (p.thin_film.x > 0.0 && p . variant==1)",
])
def test_the_bare_number_scan_can_fail(code):
    assert bare_id_comparisons("// header\n" + code + "\n", choice_fields()) == [f"2: {code}"]


@pytest.mark.parametrize("code", [
    "if (p.fresnel == MIRROR_FRESNEL_NONE) return x;", "if (p.thin_film.thickness_nm > 0.0) f();",
    "if (u_view_mode == VIEW_MODE_D) {", "float x = p.alpha == 0.0 ? 1.0 : 2.0;",
    "if (u_num_lights == 0) return;  // p.fresnel == 0", "if (res == 2) break;", "int k = dist + 1;",
])
def test_the_bare_number_scan_passes_named_ids(code):
    assert bare_id_comparisons(code, choice_fields()) == []
