"""The texture units of the rasterizer's programs, in one table, so that no two textures one
program reads share a unit (``tests/test_texture_units.py``). OpenGL 4.1 guarantees 16 units a
stage (0 .. 15). A sampler left unset reads unit 0, so every program sets all of its samplers.

Passes whose programs read none of these textures count their units from 0 (``SOURCE``,
``SECOND_SOURCE``: the IBL's downsampling, prefilter, DFG and cube map passes, the albedo
tables' reduction, the Hi-Z build, the tone map) or from their own first unit (the GPU
reference engine) and are not in the table. No other module writes a unit as a number
(``tests/test_texture_units.py``).
"""

from __future__ import annotations

MAX_UNITS = 16   # GL_MAX_TEXTURE_IMAGE_UNITS is at least 16 in OpenGL 4.1

SHADOW_ATLAS = 0   # the shadow maps' atlas (viewer/gl/shadow.py)
THICKNESS = 1      # the thickness of absorbing objects (viewer/gl/targets.py)
GLASS_SHADOW = 2   # the glass casters' optical depth, beside the shadow atlas (viewer/gl/shadow.py)
SSR_INPUTS = 0     # the SSR pass: colour mips, specular, geometry (0 .. 2) and the Hi-Z pyramid (3)
SSR_HIZ = SSR_INPUTS + 3
IBL = 4            # map, prefiltered, DFG table, cube map: IBL .. IBL + 3 (viewer/gl/ibl.py)
IBL_COUNT = 4
TRACED = 8         # BVH nodes, triangles, shading, material rows: TRACED .. TRACED + 3 (viewer/gl/raytrace.py)
TRACED_COUNT = 4
MEASURED = 15      # a measured material's 3D table (viewer/gl/measured_tex.py)
ALBEDO_PATTERN = 0  # the albedo tables' sample pattern (viewer/gl/albedo_gpu.py)
SSR_BACK = 12      # the SSR pass's background (what lies behind the surfaces), above the IBL's units
SOURCE = 0         # the one input of a pass that reads only its own textures (first of two)
SECOND_SOURCE = 1  # ... its second input (the albedo tables' reduction: transmission)

#: program -> {what it reads: (first unit, how many)}
PROGRAMS = {
    "forward": {"shadow atlas": (SHADOW_ATLAS, 1), "thickness": (THICKNESS, 1), "glass shadow": (GLASS_SHADOW, 1), "environment": (IBL, IBL_COUNT),
                "traced chains": (TRACED, TRACED_COUNT), "measured table": (MEASURED, 1)},
    "background": {"environment": (IBL, IBL_COUNT)},
    "ssr trace": {"ssr inputs": (SSR_INPUTS, 4), "environment": (IBL, IBL_COUNT), "background": (SSR_BACK, 1)},
    "albedo tables": {"sample pattern": (ALBEDO_PATTERN, 1), "measured table": (MEASURED, 1)},
}


def collisions(programs: dict = PROGRAMS, max_units: int = MAX_UNITS) -> list[str]:
    """'program: a and b share unit u' and 'program: a reaches past unit max_units - 1', for
    every clash in ``programs``."""
    out = []
    for prog, uses in programs.items():
        owner: dict[int, str] = {}
        for what, (first, count) in uses.items():
            for u in range(first, first + count):
                if not 0 <= u < max_units:
                    out.append(f"{prog}: {what} reaches unit {u}, past the {max_units} units")
                elif u in owner:
                    out.append(f"{prog}: {owner[u]} and {what} share unit {u}")
                else:
                    owner[u] = what
    return out
