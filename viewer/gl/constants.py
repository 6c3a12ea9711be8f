"""Numbers the Python side and the GLSL side must agree on, kept here once and emitted into the
shaders as the generated include ``generated/constants.glsl`` (``glsl_header``), which the
shader loader (``viewer.gl.shaders``) provides to every program: sizes, the ids of the render
modes, the lobe flags (``LOBE_<FLAG>``, unsigned: viewer/brdf/lobes.py's ``Lobe``), and the id of
every choice of every BRDF parameter (from the model's spec, the one place its choice list
lives: ``<MODEL>_<PARAM>_<CHOICE>``, e.g. ``MICROFACET_FRESNEL_DIELECTRIC``).
No shader compares a mode or a choice against a bare number (``tests/test_glsl_constants.py``)."""

from __future__ import annotations

import re

from viewer.brdf import lobes
from viewer.brdf.albedo import TABLE_SIZE
from viewer.brdf.layered import BASE_TABLE, BASE_TABLES_AT, COAT_TABLE, FILM_TABLE
from viewer.brdf.spectral_fresnel import TABLE_N
from viewer.geometry.bvh_flat import STACK_SIZE
from viewer.geometry.soup import EPS_REL
from viewer.reference_common.caustics import HASH_PRIMES, MAX_PHOTON_BOUNCES, NORMAL_COS, PHOTON_RR_START
from viewer.reference_common.estimator import RR_MAX, RR_MIN, RR_START_DEPTH
from viewer.reference_common.wavelengths import HERO, N_BINS, STRIDE
from viewer.scene.model import MAX_LIGHTS
from viewer.image.term_scales import NOT_APPLICABLE, SCALES

# MAX_LIGHTS (viewer/scene/model.py): the point and directional lights a scene may hold, the length
# of the rasterizer's light arrays; the first SHADOW_LIGHTS of them have shadow maps, the rest are
# drawn without shadows
SHADOW_LIGHTS = 4
ALBEDO_TABLE = TABLE_SIZE  # entries of a directional-albedo table: cos(theta_o) = (k + 0.5) / size
IBL_MAX_LEVELS = 8        # prefiltered environment levels at most (level 0 is the map itself)
MAX_MATERIALS = 64        # materials the GPU reference engine holds
LAYERED_COAT_TABLE = COAT_TABLE  # the layered coat's albedo table entries (viewer/brdf/layered.py)
LAYERED_FILM_TABLE = FILM_TABLE  # the layered coat film's RGB reflectance table entries
LAYERED_BASE_TABLE = BASE_TABLE  # the layered base's interreflection tables' entries
LAYERED_BASE_TABLES_AT = BASE_TABLES_AT  # their offset in the layered derived block
SPECTRAL_TABLE_N = TABLE_N  # samples of a spectral material's RGB Fresnel table (viewer/brdf/spectral_fresnel.py)
BVH_STACK = STACK_SIZE    # the BVH traversal's stack (viewer/geometry/bvh_flat.py refuses deeper trees)
MAT_VEC4 = 64             # the material block u_mat in vec4s (viewer/gl/brdf_glsl.py)
MAT_FLOATS = 4 * MAT_VEC4  # ... in floats: material r of a texture of blocks starts at float MAT_FLOATS * r
EMPTY_DEPTH = 1e30        # the SSR depth pyramid where there is no surface (viewer/gl/ssr.py)
# RR_START_DEPTH: Russian roulette from this scattering event on (viewer/reference_common/estimator.py)
SPEC_STRIDE = STRIDE      # bins between a spectral path's wavelengths (viewer/reference_common/wavelengths.py)
# the caustic photon map (viewer/reference_common/caustics.py): delta vertices a photon may pass, the
# one from which Russian roulette plays; the hash grid's primes are written unsigned (PHOTON_HASH_P*)
PHOTON_MAX_BOUNCES = MAX_PHOTON_BOUNCES
PHOTON_RR_START = PHOTON_RR_START

LIGHT_TYPES = {"point": 0, "directional": 1}
TONEMAPS = {"none": 0, "reinhard": 1, "aces": 2, "filmic": 3}
IBL_MODES = {"off": 0, "split_sum": 1, "fis": 2, "brute_force": 3}
VIEW_MODES = {"shaded": 0, "F": 1, "D": 2, "G": 3, "N.L": 4, "f cos": 5, "shadow": 6,
              # screen-space reflections (viewer/gl/ssr.py; only with [render] ssr = true):
              "ssr hit": 7, "ssr steps": 8, "ssr uv": 9, "ssr only": 10}
SSR_VIEW_BASE = 6  # view mode 7.. = SSR debug output 1..
#: the SSR pass's output (u_debug): the composite or one of its debug views
SSR_DEBUG = {"composite": 0, "hit": 1, "steps": 2, "uv": 3, "only": 4}
#: a material row of the traced chains' texture (viewer/gl/raytrace.py): where each part starts,
#: in texels; the u_mat block (64 texels) is first
CHAIN_TEXELS = {"albedo": 64, "spec": 96, "trans": 128, "info": 160, "sigma": 161, "eta": 162, "k": 163,
                "film": 164, "film_y": 165}
CHAIN_ROW_TEXELS = 166
#: the GPU engine's estimator strategies (the STRATEGY define)
STRATEGIES = {"mis": 0, "bsdf": 1, "light": 2}
#: the GPU engine's environment kinds (the ENV_MODE define)
ENV_MODES = {"black": 0, "constant": 1, "map": 2}

# name prefix in GLSL of each id table above
_TABLES = (("LIGHT", LIGHT_TYPES), ("TONEMAP", TONEMAPS), ("IBL_MODE", IBL_MODES), ("VIEW_MODE", VIEW_MODES),
           ("SSR_DEBUG", SSR_DEBUG), ("RT_T", CHAIN_TEXELS), ("STRATEGY", STRATEGIES),
           ("ENV_MODE", ENV_MODES))
_SIZES = ("MAX_LIGHTS", "SHADOW_LIGHTS", "ALBEDO_TABLE", "IBL_MAX_LEVELS", "MAX_MATERIALS", "CHAIN_ROW_TEXELS",
          "LAYERED_COAT_TABLE", "LAYERED_FILM_TABLE", "LAYERED_BASE_TABLE", "LAYERED_BASE_TABLES_AT",
          "SPECTRAL_TABLE_N", "BVH_STACK", "MAT_VEC4", "MAT_FLOATS",
          "RR_START_DEPTH", "SPEC_STRIDE", "PHOTON_MAX_BOUNCES", "PHOTON_RR_START")


def float_values() -> dict[str, float]:
    """{GLSL name: value} of the header's float constants: the empty depth, the reference
    estimator's Russian roulette bounds (``RR_MIN``, ``RR_MAX``: viewer/reference_common/estimator.py),
    its wavelength bins and a hero-only path's weight (``SPEC_N_BINS``, ``SPEC_HERO``:
    viewer/reference_common/wavelengths.py), the photon map's normal test (``PHOTON_NORMAL_COS``:
    viewer/reference_common/caustics.py),
    the relative ray offset (``EPS_REL``: viewer/geometry/soup.py), and the term views'
    scales (viewer/image/term_scales.py): ``TERM_<VIEW>_K`` and ``TERM_<VIEW>_MAX`` of t = log(1 + k v) /
    log(1 + k v_max) (k = 0: t = v / v_max), ``TERM_NOT_APPLICABLE`` the grey of "no such term"."""
    out = {"EMPTY_DEPTH": float(EMPTY_DEPTH), "TERM_NOT_APPLICABLE": float(NOT_APPLICABLE),
           "RR_MIN": float(RR_MIN), "RR_MAX": float(RR_MAX), "EPS_REL": float(EPS_REL),
           "SPEC_N_BINS": float(N_BINS), "SPEC_HERO": float(HERO), "PHOTON_NORMAL_COS": float(NORMAL_COS)}
    for view, (_, k, vmax) in SCALES.items():
        out[glsl_name("TERM", view, "K")] = float(k)
        out[glsl_name("TERM", view, "MAX")] = float(vmax)
    return out


def glsl_name(*parts: str) -> str:
    """``("microfacet", "fresnel", "dielectric")`` -> ``MICROFACET_FRESNEL_DIELECTRIC``."""
    return "_".join(re.sub(r"[^A-Za-z0-9]+", "_", p).strip("_").upper() for p in parts)


def choice_ids() -> dict[str, int]:
    """{GLSL name: index} of every choice of every choice parameter of every registered model
    (nested tables included: ``LAYERED_COATING_SPECTRAL_BK7``)."""
    from viewer import brdf

    out: dict[str, int] = {}

    def walk(prefix, params):
        for p in params:
            if p.kind == "choice":
                for i, c in enumerate(p.choices):
                    out[glsl_name(*prefix, p.name, c)] = i
            elif p.kind in ("table", "lobes"):
                walk(prefix + (p.name,), p.fields)

    for name in brdf.names():
        walk((name,), brdf.get(name).spec.params)
    return out


def values() -> dict[str, int]:
    """{GLSL name: value} of everything the header defines."""
    pairs = [(name, int(globals()[name])) for name in _SIZES]
    for prefix, table in _TABLES:
        pairs += [(glsl_name(prefix, k), v) for k, v in table.items()]
    pairs += list(choice_ids().items())
    out = dict(pairs)
    assert len(out) == len(pairs), "two constants share a GLSL name"
    return out


def lobe_values() -> dict[str, int]:
    """{GLSL name: value} of the lobe flags (``LOBE_<FLAG>``, viewer/brdf/lobes.py's ``Lobe``, and
    its unions LOBE_SMOOTH, LOBE_SIDES, LOBE_KINDS); the header writes them unsigned (``16u``)."""
    return {k: int(v.rstrip("u")) for k, v in lobes.glsl_defines().items()}


def glsl_header() -> str:
    """The source of ``generated/constants.glsl``."""
    lines = ["// Generated by viewer/gl/constants.py (the values the Python side uses). Do not edit."]
    lines += [f"#define {k} {v}" for k, v in values().items()]
    lines += [f"#define {k} {v}u" for k, v in lobe_values().items()]
    lines += [f"#define PHOTON_HASH_P{j + 1} {int(v)}u" for j, v in enumerate(HASH_PRIMES)]
    lines += [f"#define {k} {v!r}" for k, v in float_values().items()]
    return "\n".join(lines) + "\n"
