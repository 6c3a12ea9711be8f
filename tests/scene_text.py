"""Scene files for tests and benchmarks, written from parts (numpy-free; no viewer import), so
the scenes several of them render are defined once.

``scene(camera(...), environment(...), point_light(...), sphere_on_floor(...), material(...))``
joins TOML tables; values are Python values (lists, floats, ints, strings, bools, dicts). The
benchmarks import this module too (they put ``tests/`` on the path).
"""

from __future__ import annotations

import json


def toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, dict):
        return "{" + ", ".join(f"{k} = {toml_value(x)}" for k, x in v.items()) + "}"
    return "[" + ", ".join(toml_value(x) for x in v) + "]"


def table(header: str, **values) -> str:
    """``[header]`` (``[[header]]`` when it starts with ``[``) and its ``key = value`` lines;
    None values are left out."""
    lines = [f"[{header}]"] + [f"{k} = {toml_value(v)}" for k, v in values.items() if v is not None]
    return "\n".join(lines) + "\n"


def scene(*parts: str) -> str:
    return "\n".join(parts)


def camera(position, target, fov_y, width=None, height=None, up=None) -> str:
    return table("camera", position=list(position), target=list(target),
                 up=None if up is None else list(up), fov_y=fov_y, width=width, height=height)


def environment(**values) -> str:
    return table("environment", **values)


def render(**values) -> str:
    return table("render", **values)


def point_light(position, intensity) -> str:
    return table("[lights]", type="point", position=list(position), intensity=list(intensity))


def obj(mesh: str, material: str, **placement) -> str:
    """One ``[[objects]]`` entry: ``translate``, ``scale``, ``rotate_y_deg`` ... as given."""
    return table("[objects]", mesh=mesh, material=material, **placement)


def material(name: str, **params) -> str:
    return table(f"materials.{name}", **params)


def sphere_on_floor(ball: str = "ball", floor: str = "floor", height: float = 0.5, radius: float = 0.5,
                    floor_scale: float = 3.0) -> str:
    """A sphere of ``radius`` centred ``height`` above a ``floor_scale`` plane at y = 0."""
    return scene(obj("sphere", ball, translate=[0.0, height, 0.0], scale=radius),
                 obj("plane", floor, scale=floor_scale))


LAMBERT_RED = dict(model="lambert", albedo=[0.7, 0.2, 0.15])
MIRROR_NO_FRESNEL = dict(model="mirror", fresnel="none")


def mirror_floor(width=None, height=None, ssr=None) -> str:
    """A red Lambert sphere over a mirror floor (no Fresnel), one point light and a constant sky:
    the traced chains' mirror case (tests/test_raytrace.py, benchmarks/raytrace.py)."""
    return scene(
        camera([0.0, 1.2, 3.2], [0.0, 0.4, 0.0], 40.0, width, height, up=[0.0, 1.0, 0.0]),
        environment(constant=[0.2, 0.25, 0.3]),
        render(ibl="split_sum", ssr=ssr, shadows=True),
        point_light([-2.0, 4.0, 2.5], [30.0, 30.0, 30.0]),
        sphere_on_floor(height=0.6),
        material("ball", **LAMBERT_RED),
        material("floor", **MIRROR_NO_FRESNEL))


def lone_sphere(material_params: dict, width: int, height: int, constant=(1.0, 1.0, 1.0),
                name: str = "m") -> str:
    """A unit sphere at the origin seen from (0, 0, 4) (fov 40 degrees) in a constant
    environment: the furnace and albedo oracles' scene."""
    return scene(camera([0.0, 0.0, 4.0], [0.0, 0.0, 0.0], 40.0, width, height),
                 environment(constant=list(constant)),
                 obj("sphere", name),
                 material(name, **material_params))


def glass_ball(width=None, height=None) -> str:
    """A smooth glass ball (the lecture's air-glass preset) alone under the studio map: every
    traced chain ends in the environment (tests/test_raytrace.py, benchmarks/raytrace.py)."""
    return scene(camera([0.0, 0.3, 3.0], [0.0, 0.0, 0.0], 30.0, width, height, up=[0.0, 1.0, 0.0]),
                 environment(map="studio"),
                 render(ibl="split_sum"),
                 obj("sphere", "glass", scale=0.6),
                 material("glass", preset="lecture_air_glass"))
