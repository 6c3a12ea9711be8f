"""Scene files: loading, validation, ``--set`` overrides and saving (docs/scene-format.md).

A scene is a TOML file with the sections ``camera``, ``environment``, ``render``,
``[[lights]]``, ``[[objects]]`` and ``[materials.NAME]`` (plus an optional ``version = 1``).
Everything is checked here, once, so the renderer, the path tracer and the GUI can trust a
``Scene``. Every problem is reported as a ``ViewerError`` with one line::

    <file>: <field path>: <problem>; allowed: <what is allowed>

e.g. ``cornell.toml: lights[0].intensity: -1 is negative; allowed: 3 numbers >= 0 (W/sr), or
one number for grey``. Field paths are dotted, list items indexed: ``camera.fov_y``,
``lights[1].intensity``, ``objects[0].material``, ``materials.ball.alpha``.

Conventions (docs/conventions.md): right-handed, +y up, metres; colours linear RGB.

* Point light: ``position`` (m) and ``intensity`` (W/sr, radiant intensity, RGB); it adds
  ``f * I * cos(theta_i) / r^2``.
* Directional light: ``direction`` is the direction the light *travels*, i.e. from the light
  toward the scene (a sun overhead has ``direction = [0, -1, 0]``); it is stored normalized.
  ``irradiance`` (W/m^2, RGB) is the irradiance on a surface facing the light.
* Environment: radiance ``L(d) = intensity * constant`` or ``intensity * map(R_y(-rotation_deg) d)``
  (the map is turned by ``rotation_deg`` about +y, right-handed). Absent section: black.
  ``map`` is a built-in name (``sky``, ``studio``: ``viewer.environment.procedural``) or a
  Radiance .hdr / OpenEXR .exr file; a file's signature is checked here, its pixels when first
  used (``Environment.radiance_map``), either failing with a one-line ``ViewerError`` naming the file.
* Object transform: ``M = T(translate) * R_y(rotate_y_deg) * S(scale)`` for column vectors.

Mesh references and environment-map paths are resolved against the scene file's folder
(never the working directory); a mesh may also be a built-in name (``viewer.scene.mesh``).

The package: ``model`` (the data classes and the file's keys and allowed values), ``environment``
(the environment light and its map), ``validation`` (the message builder ``Checker``, reading
TOML), ``parse`` (``parse_scene``: data to a validated ``Scene``), ``overrides`` (``--set``),
``load`` (built-in names, files, screenshots, text, material files, a material named on the
command line) and ``toml_writer`` (``scene_to_toml``, ``save_scene``; files are written
atomically). None of them imports GL or the window.
"""

from viewer.base.resources import SCENE_DIR
from viewer.scene.environment import LUMINANCE, MAP_ALLOWED, MID_GREY, Environment
from viewer.scene.load import (LECTURE_NAME, SCREENSHOT_KEY, builtin_scene_names, file_material, lecture_scene_names,
                               load_material_file, load_scene, load_scene_text, material_from_name)
from viewer.scene.model import (CAMERA_KEYS, DIRECTIONAL_KEYS, ENV_KEYS, EXPOSURE_RANGE, FLOAT32_MAX, IBL_MODES,
                                LIGHT_TYPES, MAX_SIZE, MIN_VIEW_DISTANCE, MSAA_SAMPLES, OBJECT_KEYS, POINT_KEYS,
                                RENDER_KEYS, SCENE_VERSION, TONEMAPS, TOP_KEYS, Camera, Light, RenderSettings, Scene,
                                SceneObject)
from viewer.scene.overrides import apply_override, check_replaced, dotted_key
from viewer.scene.parse import parse_scene
from viewer.scene.toml_writer import material_to_toml, save_material, save_scene, scene_to_data, scene_to_toml
from viewer.scene.validation import MAX_NESTING

__all__ = [
    "CAMERA_KEYS", "DIRECTIONAL_KEYS", "ENV_KEYS", "EXPOSURE_RANGE", "FLOAT32_MAX", "IBL_MODES", "LECTURE_NAME",
    "LIGHT_TYPES", "LUMINANCE", "MAP_ALLOWED", "MAX_NESTING", "MAX_SIZE", "MID_GREY", "MIN_VIEW_DISTANCE",
    "MSAA_SAMPLES", "OBJECT_KEYS", "POINT_KEYS", "RENDER_KEYS", "SCENE_DIR", "SCENE_VERSION", "SCREENSHOT_KEY",
    "TONEMAPS", "TOP_KEYS", "Camera", "Environment", "Light", "RenderSettings", "Scene", "SceneObject",
    "apply_override", "builtin_scene_names", "check_replaced", "dotted_key", "file_material", "lecture_scene_names",
    "load_material_file", "load_scene", "load_scene_text", "material_from_name", "material_to_toml",
    "parse_scene", "save_material", "save_scene", "scene_to_data", "scene_to_toml",
]
