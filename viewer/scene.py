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
(never the working directory); a mesh may also be a built-in name (``viewer.mesh``).
"""

from __future__ import annotations

import copy
import math
import os
import re
from dataclasses import dataclass, field, fields, is_dataclass
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from viewer import ViewerError
from viewer.io import expand_user, one_line, one_line_errors, path_problem
from viewer.resources import SCENE_DIR

try:  # Python >= 3.11
    import tomllib
except ModuleNotFoundError:  # pragma: no cover - Python 3.10
    import tomli as tomllib

import tomli_w

SCENE_VERSION = 1

TOP_KEYS = ("version", "camera", "environment", "render", "lights", "objects", "materials")
CAMERA_KEYS = ("position", "target", "up", "fov_y", "width", "height")
ENV_KEYS = ("constant", "map", "intensity", "rotation_deg")
RENDER_KEYS = ("ibl", "ssr", "shadows", "msaa", "exposure", "tonemap", "ms_compensation", "raytrace", "raytrace_depth")
LIGHT_TYPES = ("point", "directional")
POINT_KEYS = ("type", "position", "intensity")
DIRECTIONAL_KEYS = ("type", "direction", "irradiance")
OBJECT_KEYS = ("mesh", "material", "translate", "scale", "rotate_y_deg")

IBL_MODES = ("split_sum", "fis", "brute_force", "off")
TONEMAPS = ("none", "aces", "filmic", "reinhard")
MSAA_SAMPLES = (0, 1, 2, 4, 8)
MAX_SIZE = 16384
EXPOSURE_RANGE = (-20.0, 20.0)
# Both renderers store scene numbers as float32 (GPU uniforms, Embree vertices, float32 images):
# a finite float64 beyond this would turn into inf there.
FLOAT32_MAX = float(np.finfo(np.float32).max)
MIN_VIEW_DISTANCE = 1e-6  # m, between camera.position and camera.target (viewer.camera clamps there)


# ----------------------------------------------------------------------------- data classes

def _v3(x) -> np.ndarray:
    return np.array(x, dtype=np.float64).reshape(3)


@dataclass(eq=False)
class Camera:
    """A pinhole camera looking from ``position`` at ``target``; ``fov_y`` is the full vertical
    field of view in degrees; ``width`` x ``height`` pixels. ``up`` is stored unit length."""

    position: np.ndarray = field(default_factory=lambda: _v3([0.0, 0.0, 4.0]))
    target: np.ndarray = field(default_factory=lambda: _v3([0.0, 0.0, 0.0]))
    up: np.ndarray = field(default_factory=lambda: _v3([0.0, 1.0, 0.0]))
    fov_y: float = 40.0
    width: int = 256
    height: int = 256

    @property
    def aspect(self) -> float:
        return self.width / self.height

    def __eq__(self, other):
        return _equal(self, other)


@dataclass(eq=False)
class Light:
    """A point light (``position`` m, ``intensity`` W/sr) or a directional light (``direction``:
    unit vector the light travels along, from the light toward the scene; ``irradiance`` W/m^2).
    The fields of the other type are zero."""

    type: str = "point"
    position: np.ndarray = field(default_factory=lambda: np.zeros(3))
    intensity: np.ndarray = field(default_factory=lambda: np.zeros(3))
    direction: np.ndarray = field(default_factory=lambda: np.zeros(3))
    irradiance: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def __eq__(self, other):
        return _equal(self, other)


LUMINANCE = np.array([0.2126, 0.7152, 0.0722])  # Rec.709 luminance of linear RGB
MID_GREY = 0.18


@dataclass(eq=False)
class Environment:
    """Light from infinitely far away: ``intensity * constant`` (RGB radiance from every
    direction) or ``intensity * map(R_y(-rotation_deg) d)`` with ``map`` a lat-long image
    (docs/conventions.md gives the mapping). Exactly one of ``constant`` and ``map`` is set.

    ``map`` is a ``Path`` (a Radiance .hdr or OpenEXR .exr file) or a ``str``, the name of a
    built-in map generated by ``viewer.environment.procedural`` ("sky", "studio").
    ``radiance_map()`` decodes or generates the image once (cached on this object) and
    ``lookup(dirs)`` gives the radiance for world directions."""

    constant: np.ndarray | None = field(default_factory=lambda: np.zeros(3))
    map: Path | str | None = None
    intensity: float = 1.0
    rotation_deg: float = 0.0

    @property
    def is_black(self) -> bool:
        return self.map is None and (self.constant is None or not np.any(self.constant * self.intensity > 0))

    @property
    def is_builtin(self) -> bool:
        """True when ``map`` names a built-in (generated) map rather than a file."""
        from viewer.environment.procedural import builtin_names

        return isinstance(self.map, str) and self.map in builtin_names()

    def radiance_map(self, width: int = 1024, height: int = 512) -> np.ndarray | None:
        """float32 (H, W, 3) lat-long radiance with ``intensity`` applied and the rotation *not*
        applied (``lookup`` and the GPU apply it when they look up); None for a constant
        environment. Built-in maps are generated at ``width`` x ``height``; files keep their own
        size. Decoded once and cached (the cache follows edits of ``map`` and ``intensity``);
        the array is read-only. A bad file raises ``ViewerError`` naming the scene, the field and
        the file."""
        if self.map is None:
            return None
        cache = self.__dict__.setdefault("_map_cache", {})
        key_raw = (str(self.map), type(self.map).__name__) + ((width, height) if self.is_builtin else ())
        key = key_raw + (float(self.intensity),)
        if key in cache:
            return cache[key]
        raw = cache.get(key_raw)
        if raw is None:
            raw = self._load_map(width, height)
            cache.clear()
            cache[key_raw] = raw
        img = raw * np.float32(self.intensity) if self.intensity != 1.0 else raw.copy()
        img.setflags(write=False)
        cache[key] = img
        return img

    def mean_luminance(self) -> float:
        """The solid-angle mean of the Rec.709 luminance over the sphere of directions, before
        ``intensity``: the radiance a white Lambert surface facing a uniform environment of the
        same average shows (exact for a constant environment). Lat-long rows weigh sin(theta)."""
        if self.map is None:
            c = np.zeros(3) if self.constant is None else np.asarray(self.constant, float)
            return float(c @ LUMINANCE)
        cache = self.__dict__.setdefault("_map_cache", {})
        key = ("mean_luminance", str(self.map))
        if key not in cache:
            img = self.radiance_map()
            lum = np.asarray(img, np.float64) @ LUMINANCE
            h = lum.shape[0]
            w = np.sin((np.arange(h) + 0.5) / h * np.pi)
            mean = float((lum.mean(axis=1) * w).sum() / w.sum())
            cache[key] = mean / self.intensity if self.intensity > 0 else 0.0
        return cache[key]

    def mid_grey_intensity(self) -> float | None:
        """The ``intensity`` that puts the mean luminance at mid-grey (``MID_GREY`` = 0.18, the
        photographic key of Reinhard et al. 2002) at exposure 0, so a diffuse white object under
        the map reads about mid-grey. The mean rather than the median: the built-in studio is a
        dark room (median 0.021) lit by small panels, and its median at mid-grey would put those
        at ~170, a white screen; the sky's mean (12.2 kcd/m^2) gives 0.0148. None for a black
        environment."""
        m = self.mean_luminance()
        return MID_GREY / m if m > 0 and np.isfinite(m) else None

    def _load_map(self, width: int, height: int) -> np.ndarray:
        from viewer.environment import procedural
        from viewer.environment.io import load_environment

        if self.is_builtin:
            return procedural.generate(self.map, width, height)
        where = self.__dict__.get("_where", "<scene>")
        try:
            return load_environment(Path(self.map))
        except ViewerError as e:
            raise ViewerError(f"{where}: environment.map: {e}; allowed: {_MAP_ALLOWED}") from None

    def lookup(self, dirs) -> np.ndarray:
        """(N, 3) radiance arriving from world directions ``dirs`` (N, 3) (unit or not):
        ``intensity * constant``, or the bilinear map value with intensity and rotation applied
        (at the default generation size 1024 x 512 for built-in maps)."""
        d = np.asarray(dirs, dtype=np.float64)
        if self.map is None:
            c = np.zeros(3) if self.constant is None else np.asarray(self.constant, dtype=np.float64)
            return np.broadcast_to(c * self.intensity, d.shape[:-1] + (3,)).copy()
        from viewer.environment.latlong import lookup

        return lookup(self.radiance_map(), d, self.rotation_deg)

    def __eq__(self, other):
        return _equal(self, other)


@dataclass(eq=False)
class RenderSettings:
    """The rasterizer's switches (the reference path tracer ignores them)."""

    ibl: str = "split_sum"
    ssr: bool = False
    shadows: bool = True
    msaa: int = 4
    exposure: float = 0.0
    tonemap: str = "none"
    # multiple-scattering energy compensation of glossy lobes under environment light
    # (Fdez-Aguera 2019; Kulla & Conty 2017): the energy single scattering loses, put back
    ms_compensation: bool = False
    # specular chains (mirror and smooth-glass bounces) traced through the scene's triangles on
    # the GPU instead of the environment looked up as through a sphere; raytrace_depth = the most
    # scattering events along a chain, the camera's hit included (the reference's max_depth)
    raytrace: bool = False
    raytrace_depth: int = 8

    def __eq__(self, other):
        return _equal(self, other)


@dataclass(eq=False)
class SceneObject:
    """One mesh instance. ``mesh`` is the reference as written in the file (a built-in name or
    a path relative to the scene file); ``mesh_data`` is the loaded ``viewer.mesh.MeshData``
    (None when the scene was parsed with ``load_meshes=False``). ``scale`` is a float or a
    (3,) array of positive numbers."""

    mesh: str
    material: str
    translate: np.ndarray = field(default_factory=lambda: np.zeros(3))
    scale: float | np.ndarray = 1.0
    rotate_y_deg: float = 0.0
    mesh_data: Any = field(default=None, repr=False)

    def model_matrix(self) -> np.ndarray:
        """4x4 float64 object-to-world matrix for column vectors (``M @ [x, y, z, 1]``):
        ``T(translate) @ R_y(rotate_y_deg) @ S(scale)``. Transpose it for pyrr's row-major
        (vector-on-the-left) convention."""
        s = np.broadcast_to(np.asarray(self.scale, dtype=np.float64), (3,))
        a = math.radians(self.rotate_y_deg)
        c, sn = math.cos(a), math.sin(a)
        # Right-handed rotation about +y: x goes to -z for +90 degrees.
        rot = np.array([[c, 0.0, sn], [0.0, 1.0, 0.0], [-sn, 0.0, c]])
        m = np.eye(4)
        m[:3, :3] = rot * s[None, :]
        m[:3, 3] = self.translate
        return m

    def normal_matrix(self) -> np.ndarray:
        """3x3 matrix that transforms normals to world space (inverse transpose of the
        upper-left 3x3 of the model matrix); renormalize after use."""
        return np.linalg.inv(self.model_matrix()[:3, :3]).T

    def world_positions(self) -> np.ndarray:
        """(V, 3) float64 vertex positions in world space."""
        p = np.asarray(self.mesh_data.positions, dtype=np.float64).reshape(-1, 3)
        m = self.model_matrix()
        return p @ m[:3, :3].T + m[:3, 3]

    def __eq__(self, other):
        return _equal(self, other, skip=("mesh_data",))


@dataclass(eq=False)
class Scene:
    """A validated scene. ``data`` is the TOML data after ``--set`` overrides, as read (before
    normalization); ``scene_to_toml(scene)`` writes the current field values instead, so edits
    made to a Scene (e.g. by the GUI) are what gets saved. ``label`` names the scene in messages
    (the file name, or ``<built-in default>``); ``base_dir`` is where relative paths resolve."""

    path: Path | None
    camera: Camera
    environment: Environment
    render: RenderSettings
    lights: list
    objects: list
    materials: dict
    data: dict = field(default_factory=dict)
    label: str = "<scene>"
    base_dir: Path | None = None

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(min, max) float64 (3,) corners of the world-space box around every object."""
        lo = np.full(3, np.inf)
        hi = np.full(3, -np.inf)
        for obj in self.objects:
            if obj.mesh_data is None:
                continue
            p = obj.world_positions()
            if len(p):
                lo = np.minimum(lo, p.min(axis=0))
                hi = np.maximum(hi, p.max(axis=0))
        if not np.all(np.isfinite(lo)):
            return np.zeros(3), np.zeros(3)
        return lo, hi

    def material_of(self, obj: SceneObject):
        return self.materials[obj.material]

    def __eq__(self, other):
        return _equal(self, other, skip=("data", "label", "base_dir"))


_EQ_SKIP = {SceneObject: ("mesh_data",)}


def _equal(a, b, skip=()) -> bool:
    """Structural equality that understands numpy arrays, Params and dataclasses.
    Float arrays compare with a relative tolerance of 1e-12 (a normalized direction that is
    normalized again may move by an ulp)."""
    if type(a) is not type(b):
        if not (isinstance(a, (int, float)) and isinstance(b, (int, float))
                and not isinstance(a, bool) and not isinstance(b, bool)):
            return False
    if is_dataclass(a):
        # A SceneObject inside a Scene's list skips mesh_data as it does on its own, so a scene
        # loaded with meshes equals the same scene parsed with load_meshes=False.
        skip = skip or _EQ_SKIP.get(type(a), ())
        return all(_equal(getattr(a, f.name), getattr(b, f.name)) for f in fields(a) if f.name not in skip)
    if isinstance(a, np.ndarray):
        return a.shape == b.shape and bool(np.allclose(a, b, rtol=1e-12, atol=1e-15))
    if isinstance(a, dict):
        if getattr(a, "model", None) != getattr(b, "model", None):
            return False
        return a.keys() == b.keys() and all(_equal(a[k], b[k]) for k in a)
    if isinstance(a, (list, tuple)):
        return len(a) == len(b) and all(_equal(x, y) for x, y in zip(a, b))
    return a == b


# ----------------------------------------------------------------------------- validation

def _describe(v) -> str:
    if isinstance(v, bool):
        return f"{str(v).lower()} (a boolean)"
    if isinstance(v, str):
        return f"{_short(v)!r} (a string)"
    if isinstance(v, dict):
        return "a table"
    if isinstance(v, list):
        return f"a list of {len(v)}"
    if isinstance(v, int) and abs(v) >= 10 ** 15:
        return "%.3g" % v if abs(v) < 10 ** 300 else "a huge integer"
    if isinstance(v, (int, float)):
        return f"{v!r}"
    return f"{v!r} (a {type(v).__name__})"


def _short(text: str, n: int = 60) -> str:
    """``text`` cut to ``n`` characters for a message (a scene may hold a megabyte string)."""
    return text if len(text) <= n else text[: n - 3] + "..."


def _is_num(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _g(v: float) -> str:
    return f"{v:g}"


class _Checker:
    """Builds the one-line messages: ``<label>: <field>: <problem>; allowed: <allowed>``."""

    def __init__(self, label: str):
        self.label = label

    def fail(self, fld: str, problem: str, allowed: str):
        raise ViewerError(one_line(f"{self.label}: {fld}: {problem}; allowed: {allowed}"))

    def table(self, value, fld: str, keys: Sequence[str], what: str = "key") -> dict:
        if not isinstance(value, dict):
            self.fail(fld, f"expected a table, got {_describe(value)}",
                      f"a table [{fld}] with keys " + ", ".join(keys))
        for k in value:
            if k not in keys:
                k = _short(k, 40)
                self.fail(f"{fld}.{k}" if fld else k, f"unknown {what}", ", ".join(keys))
        return value

    def number(self, value, fld, allowed, lo=None, hi=None, lo_open=False, hi_open=False) -> float:
        if not _is_num(value):
            self.fail(fld, f"expected a number, got {_describe(value)}", allowed)
        v = _to_float(value)
        if not math.isfinite(v):
            self.fail(fld, f"{_describe(value)} is not a finite number", allowed)
        if abs(v) > FLOAT32_MAX:
            self.fail(fld, f"{_g(v)} is beyond the float32 range the renderers compute in (|x| <= 3.4e38)", allowed)
        if lo is not None and (v < lo or (lo_open and v == lo)):
            self.fail(fld, f"{_g(v)} is out of range", allowed)
        if hi is not None and (v > hi or (hi_open and v == hi)):
            self.fail(fld, f"{_g(v)} is out of range", allowed)
        return v

    def integer(self, value, fld, allowed, lo=None, hi=None, choices=None) -> int:
        if not isinstance(value, int) or isinstance(value, bool):
            self.fail(fld, f"expected an integer, got {_describe(value)}", allowed)
        if (lo is not None and value < lo) or (hi is not None and value > hi) or (
                choices is not None and value not in choices):
            self.fail(fld, f"{_describe(value)} is out of range", allowed)
        return int(value)

    def boolean(self, value, fld) -> bool:
        if not isinstance(value, bool):
            self.fail(fld, f"expected true or false, got {_describe(value)}", "true, false")
        return value

    def choice(self, value, fld, choices) -> str:
        allowed = ", ".join(f'"{c}"' for c in choices)
        if not isinstance(value, str):
            self.fail(fld, f"expected a string, got {_describe(value)}", allowed)
        if value not in choices:
            self.fail(fld, f"{value!r} is not allowed", allowed)
        return value

    def string(self, value, fld, allowed) -> str:
        if not isinstance(value, str):
            self.fail(fld, f"expected a string, got {_describe(value)}", allowed)
        if not value.strip():
            self.fail(fld, "is empty", allowed)
        return value

    def vec3(self, value, fld, allowed, grey=False, nonneg=False, positive=False, nonzero=False) -> np.ndarray:
        if grey and _is_num(value):
            value = [value] * 3
        if not isinstance(value, list):
            self.fail(fld, f"expected 3 numbers, got {_describe(value)}", allowed)
        if len(value) != 3:
            self.fail(fld, f"expected 3 numbers, got {len(value)}", allowed)
        for i, x in enumerate(value):
            if not _is_num(x):
                self.fail(f"{fld}[{i}]", f"expected a number, got {_describe(x)}", allowed)
        with np.errstate(over="ignore"):
            arr = np.array([_to_float(x) for x in value], dtype=np.float64)
        if not np.all(np.isfinite(arr)):
            self.fail(fld, f"{[float(x) for x in arr]} is not finite", allowed)
        if np.any(np.abs(arr) > FLOAT32_MAX):
            self.fail(fld, f"{[_num(x) for x in arr]} is beyond the float32 range the renderers compute in "
                           "(|x| <= 3.4e38)", allowed)
        if nonneg and np.any(arr < 0):
            self.fail(fld, f"{[_num(x) for x in arr]} has a negative component", allowed)
        if positive and np.any(arr <= 0):
            self.fail(fld, f"{[_num(x) for x in arr]} has a component <= 0", allowed)
        if nonzero and not np.any(arr != 0):
            self.fail(fld, "is the zero vector", allowed)
        return arr


def _to_float(x) -> float:
    try:
        return float(x)
    except OverflowError:  # a TOML integer beyond any float
        return math.inf if x > 0 else -math.inf


def _num(x: float):
    return int(x) if float(x).is_integer() and abs(x) < 1e15 else float(x)


# ----------------------------------------------------------------------------- public API

def builtin_scene_names() -> list[str]:
    """Names of the scenes shipped in ``viewer/scenes`` (``default`` first)."""
    names = sorted(p.stem for p in SCENE_DIR.glob("*.toml"))
    if "default" in names:
        names.remove("default")
        names.insert(0, "default")
    return names


LECTURE_NAME = re.compile(r"lecture:(\S*)")  # lecture:N, N = 1 .. the number of lecture steps


def lecture_scene_names() -> list[str]:
    """``lecture:1`` .. ``lecture:N``: the lecture tour's steps as built-in scene names."""
    from viewer.lecture import TOUR

    return [f"lecture:{i + 1}" for i in range(len(TOUR))]


def _lecture_scene(m, overrides, load_meshes: bool) -> "Scene":
    from viewer.lecture import TOUR, step_label

    n = len(TOUR)
    text = m.group(0)
    allowed = f"lecture:1 .. lecture:{n} (the lecture tour's steps, 1-based)"
    if not m.group(1).isdigit():
        _Checker(text).fail("scene", f"{m.group(1)!r} is not a step number", allowed)
    i = int(m.group(1))
    if not 1 <= i <= n:
        _Checker(text).fail("scene", f"step {i} is out of range", allowed)
    data = _loads(TOUR[i - 1].toml, step_label(i - 1))
    return parse_scene(data, None, overrides, label=step_label(i - 1), base_dir=SCENE_DIR, load_meshes=load_meshes)


def _builtin_label(name: str) -> str:
    return f"<built-in {name}>"


@one_line_errors
def load_scene(ref: str | Path | None = None, overrides: Sequence[str] = (), *,
               load_meshes: bool = True) -> "Scene":
    """Load and validate a scene.

    ``ref`` None loads the built-in ``default``; a string without a path separator and without
    a ``.toml`` suffix that names a built-in scene (``builtin_scene_names()``) loads that one;
    ``lecture:N`` loads the lecture tour's step N (1-based; ``lecture_scene_names()``);
    anything else is a file path. ``overrides`` are ``KEY=VALUE`` assignments (``--set``)
    applied before validation. Raises ``ViewerError`` (one line) on any problem.
    """
    if ref is None:
        ref = "default"
    text = str(ref)
    seps = {"/", os.sep} | ({os.altsep} if os.altsep else set())
    is_bare = isinstance(ref, str) and not any(s in text for s in seps) and not text.endswith(".toml")
    builtins = builtin_scene_names()
    m = LECTURE_NAME.fullmatch(text) if is_bare else None
    if m is not None:
        return _lecture_scene(m, overrides, load_meshes)
    if is_bare and text in builtins:
        file = SCENE_DIR / f"{text}.toml"
        label = _builtin_label(text)
        data = _read_toml(file, label)
        return parse_scene(data, None, overrides, label=label, base_dir=SCENE_DIR, load_meshes=load_meshes)
    path = Path(ref)
    label = text
    problem = path_problem(path)
    if problem == "file not found":
        hint = ("a scene file path (.toml) or a built-in scene name: " + ", ".join(builtins)
                + ", lecture:1 .. lecture:" + str(len(lecture_scene_names())))
        if is_bare:
            _Checker(label).fail("scene", "no such built-in scene or file", hint)
        _Checker(label).fail("file", "not found", hint)
    if problem == "is a folder, not a file":
        _Checker(label).fail("file", "is a folder, not a scene file", "a scene file path (.toml)")
    if problem is not None:  # a pipe would block the read; a name too long, a NUL character
        _Checker(label).fail("file", problem, "a scene file path (.toml)")
    if path.suffix.lower() == ".png":
        # a screenshot: its text chunk holds the whole scene (viewer.screenshot.png_text)
        data = _read_screenshot(path, label)
        return parse_scene(data, path, overrides, label=label, load_meshes=load_meshes)
    data = _read_toml(path, label)
    return parse_scene(data, path, overrides, label=label, load_meshes=load_meshes)


def load_scene_text(text: str, overrides: Sequence[str] = (), *, base_dir: str | Path | None = None,
                    label: str = "<scene text>", load_meshes: bool = True) -> "Scene":
    """Load and validate a scene given as TOML text (the Python API's third kind of scene).
    Relative mesh and map paths resolve against ``base_dir`` (default: the working folder).
    Raises ``ViewerError`` (one line) on any problem, as ``load_scene`` does."""
    data = _loads(str(text), label)
    return parse_scene(data, None, overrides, label=label, base_dir=base_dir, load_meshes=load_meshes)


SCREENSHOT_KEY = "brdf-viewer:scene"


def _read_screenshot(path: Path, label: str) -> dict:
    """The scene stored in a screenshot's PNG text chunk. Mesh and map paths in it resolve
    against the screenshot's folder; built-in names work anywhere."""
    try:
        from viewer.io import read_png_text

        text = read_png_text(path)
    except Exception as e:  # noqa: BLE001 - Pillow raises many kinds for a broken PNG
        _Checker(label).fail("file", f"cannot be read as PNG ({type(e).__name__}: {e})",
                             "a brdf-viewer screenshot (.png) or a scene file (.toml)")
    if SCREENSHOT_KEY not in text:
        _Checker(label).fail(SCREENSHOT_KEY, "this PNG holds no scene",
                             "a screenshot saved by brdf-viewer (F12 or render)")
    return _loads(text[SCREENSHOT_KEY], label)


def _read_toml(path: Path, label: str) -> dict:
    try:
        raw = path.read_bytes()
    except OSError as e:
        _Checker(label).fail("file", f"cannot be read ({e.strerror or e})", "a readable scene file (.toml)")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as e:
        _Checker(label).fail("file", f"is not UTF-8 text (byte {e.start})", "a UTF-8 TOML text file")
    return _loads(text, label)


MAX_NESTING = 32  # tables and arrays inside each other; a scene needs 5


def _loads(text: str, label: str) -> dict:
    syntax = "TOML syntax (key = value, [table], [[array]], strings in double quotes)"
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        msg = str(e).splitlines()[0] if str(e) else "invalid TOML"
        m = re.search(r"line (\d+)", msg)
        where = f"line {m.group(1)}" if m else "TOML"
        _Checker(label).fail(where, f"TOML syntax error: {msg}", syntax)
    except RecursionError:  # the parser recurses once per nested [ or {
        _Checker(label).fail("TOML", "arrays or inline tables nested too deeply to read", syntax)
    except ValueError as e:  # e.g. an integer of more than 4300 digits (int() refuses it)
        _Checker(label).fail("TOML", f"a value cannot be read ({_short(str(e).splitlines()[0], 80)})", syntax)
    return data


def _check_nesting(data, label: str) -> None:
    """Refuse data nested deeper than MAX_NESTING (copying or walking it would recurse)."""
    stack = [(data, 0)]
    while stack:
        v, depth = stack.pop()
        if depth > MAX_NESTING:
            _Checker(label).fail("TOML", f"tables or arrays nested more than {MAX_NESTING} deep",
                                 "a scene as in docs/scene-format.md (at most a few levels deep)")
        if isinstance(v, dict):
            stack.extend((x, depth + 1) for x in v.values())
        elif isinstance(v, list):
            stack.extend((x, depth + 1) for x in v)


@one_line_errors
def parse_scene(data: dict, path: Path | None, overrides: Sequence[str] = (), *,
                label: str | None = None, base_dir: Path | None = None,
                load_meshes: bool = True) -> "Scene":
    """Validate parsed TOML ``data`` (not modified) and build a ``Scene``.

    ``path`` names the file in messages and is where relative mesh and map paths resolve
    (``base_dir`` overrides that; without either they resolve against the working folder).
    ``overrides`` are ``--set`` assignments applied to a copy of ``data`` first.
    """
    path = Path(path) if path is not None else None
    if label is None:
        label = str(path) if path is not None else "<scene>"
    if base_dir is None:
        base_dir = path.parent if path is not None else Path.cwd()
    base_dir = Path(base_dir).absolute()
    _check_nesting(data, label)  # before deepcopy, which recurses (a --set value is checked as parsed)
    data = copy.deepcopy(data)
    # a material's model or preset set by --set starts that material afresh (the model's defaults,
    # the preset's values); the other assignments apply after it, whatever their order
    firsts = [a for a in overrides if _is_material_switch(a)]
    for a in firsts:
        _switch_material(data, a)
    for a in overrides:
        if a not in firsts:
            apply_override(data, a)
    ck = _Checker(label)
    ck.table(data, "", TOP_KEYS, what="section")

    if "version" in data:
        ck.integer(data["version"], "version", f"{SCENE_VERSION}", SCENE_VERSION, SCENE_VERSION)
    camera = _parse_camera(ck, data.get("camera", {}))
    environment = _parse_environment(ck, data.get("environment"), base_dir)
    render = _parse_render(ck, data.get("render", {}))
    materials = _parse_materials(ck, data.get("materials", {}), base_dir)
    lights = _parse_lights(ck, data.get("lights", []))
    objects = _parse_objects(ck, data.get("objects"), materials)

    if load_meshes:
        from viewer.mesh import load_mesh

        cache: dict[str, Any] = {}
        for i, obj in enumerate(objects):
            if obj.mesh not in cache:
                cache[obj.mesh] = load_mesh(obj.mesh, base_dir, where=f"{label}: objects[{i}].mesh")
            obj.mesh_data = cache[obj.mesh]

    return Scene(path=path, camera=camera, environment=environment, render=render, lights=lights,
                 objects=objects, materials=materials, data=data, label=label, base_dir=base_dir)


def _parse_camera(ck: _Checker, t) -> Camera:
    ck.table(t, "camera", CAMERA_KEYS)
    cam = Camera()
    pos_allowed = "3 finite numbers [x, y, z] in metres"
    if "position" in t:
        cam.position = ck.vec3(t["position"], "camera.position", pos_allowed)
    if "target" in t:
        cam.target = ck.vec3(t["target"], "camera.target", pos_allowed)
    if "up" in t:
        cam.up = ck.vec3(t["up"], "camera.up", "3 finite numbers, not all zero", nonzero=True)
    if "fov_y" in t:
        cam.fov_y = ck.number(t["fov_y"], "camera.fov_y", "a number of degrees in (0, 180), the full vertical field of view",
                              0.0, 180.0, lo_open=True, hi_open=True)
    for k in ("width", "height"):
        if k in t:
            setattr(cam, k, ck.integer(t[k], f"camera.{k}", f"an integer of pixels in [1, {MAX_SIZE}]", 1, MAX_SIZE))
    view = cam.target - cam.position
    if not np.any(view != 0):
        ck.fail("camera.target", "equals camera.position, so there is no viewing direction",
                "a target different from the position")
    dist = float(np.linalg.norm(view))
    if dist < MIN_VIEW_DISTANCE:  # the orbit camera clamps its distance there; 1e-300 would not normalize
        ck.fail("camera.target", f"is only {dist:.3g} m from camera.position",
                f"a target at least {MIN_VIEW_DISTANCE:g} m from the position")
    up = cam.up / np.max(np.abs(cam.up))  # scaled first: the norm of [0, 1e-200, 0] underflows
    cam.up = up / np.linalg.norm(up)      # stored unit length, as a light's direction
    if np.linalg.norm(np.cross(view / dist, cam.up)) < 1e-6:
        ck.fail("camera.up", "is parallel to the viewing direction (target - position)",
                "a vector not parallel to the viewing direction, e.g. [0, 1, 0]")
    return cam


_MAP_ALLOWED = ("a built-in name (sky, studio) or a lat-long image file (Radiance .hdr, OpenEXR .exr) "
                "relative to the scene file")


def _parse_environment(ck: _Checker, t, base_dir: Path) -> Environment:
    from viewer.environment.io import check_environment_file
    from viewer.environment.procedural import builtin_names

    env = Environment()
    env.__dict__["_where"] = ck.label
    if t is None:
        return env
    ck.table(t, "environment", ENV_KEYS)
    if "constant" in t and "map" in t:
        ck.fail("environment.map", "given together with environment.constant",
                "either constant = [r, g, b] or map = \"file.hdr\", not both")
    if "constant" in t:
        env.constant = ck.vec3(t["constant"], "environment.constant",
                               "3 numbers >= 0 (radiance, linear RGB), or one number for grey",
                               grey=True, nonneg=True)
    if "map" in t:
        env.constant = None
        name = ck.string(t["map"], "environment.map", _MAP_ALLOWED)
        if name in builtin_names():  # a bare built-in name; files have a suffix
            env.map = name
        else:
            env.map = _check_file(ck, name, "environment.map", base_dir, _MAP_ALLOWED)
            try:  # the file's signature only; it is decoded when first used (radiance_map)
                check_environment_file(env.map)
            except ViewerError as e:
                ck.fail("environment.map", str(e), _MAP_ALLOWED)
    if "intensity" in t:
        env.intensity = ck.number(t["intensity"], "environment.intensity", "a number >= 0 (a scale factor)", 0.0)
    if "rotation_deg" in t:
        env.rotation_deg = ck.number(t["rotation_deg"], "environment.rotation_deg",
                                     "a finite number of degrees (rotation about +y)")
    return env


def _check_file(ck: _Checker, value, fld: str, base_dir: Path, allowed: str) -> Path:
    ref = ck.string(value, fld, allowed)
    p = expand_user(ref)
    if not p.is_absolute():
        p = base_dir / p
    problem = path_problem(p)
    if problem == "file not found":
        ck.fail(fld, f"file not found: {p}", allowed)
    if problem is not None:
        ck.fail(fld, f"not a file: {p} ({problem})", allowed)
    try:
        with open(p, "rb") as fh:
            fh.read(1)
    except OSError as e:
        ck.fail(fld, f"cannot be read: {p} ({e.strerror or e})", allowed)
    return p


def _parse_render(ck: _Checker, t) -> RenderSettings:
    ck.table(t, "render", RENDER_KEYS)
    r = RenderSettings()
    if "ibl" in t:
        r.ibl = ck.choice(t["ibl"], "render.ibl", IBL_MODES)
    if "ssr" in t:
        r.ssr = ck.boolean(t["ssr"], "render.ssr")
    if "shadows" in t:
        r.shadows = ck.boolean(t["shadows"], "render.shadows")
    if "msaa" in t:
        r.msaa = ck.integer(t["msaa"], "render.msaa", "one of " + ", ".join(map(str, MSAA_SAMPLES)),
                            choices=MSAA_SAMPLES)
    if "exposure" in t:
        lo, hi = EXPOSURE_RANGE
        r.exposure = ck.number(t["exposure"], "render.exposure", f"a number of EV in [{lo:g}, {hi:g}]", lo, hi)
    if "tonemap" in t:
        r.tonemap = ck.choice(t["tonemap"], "render.tonemap", TONEMAPS)
    if "ms_compensation" in t:
        r.ms_compensation = ck.boolean(t["ms_compensation"], "render.ms_compensation")
    if "raytrace" in t:
        r.raytrace = ck.boolean(t["raytrace"], "render.raytrace")
    if "raytrace_depth" in t:
        r.raytrace_depth = ck.integer(t["raytrace_depth"], "render.raytrace_depth",
                                      "an integer 1..16, the most scattering events along a traced chain", 1, 16)
    return r


def _parse_lights(ck: _Checker, lst) -> list[Light]:
    if isinstance(lst, dict):
        ck.fail("lights", "is a single table", "an array of tables: write [[lights]] for each light")
    if not isinstance(lst, list):
        ck.fail("lights", f"expected an array of tables, got {_describe(lst)}", "[[lights]] tables")
    out = []
    for i, t in enumerate(lst):
        fld = f"lights[{i}]"
        if not isinstance(t, dict):
            ck.fail(fld, f"expected a table, got {_describe(t)}", "a [[lights]] table")
        kind = ck.choice(t.get("type", "point"), f"{fld}.type", LIGHT_TYPES)
        if kind == "point":
            ck.table(t, fld, POINT_KEYS, what="key for a point light")
            if "position" not in t:
                ck.fail(f"{fld}.position", "missing (a point light needs a position)", "3 finite numbers [x, y, z] in metres")
            light = Light("point")
            light.position = ck.vec3(t["position"], f"{fld}.position", "3 finite numbers [x, y, z] in metres")
            light.intensity = ck.vec3(t.get("intensity", [1.0, 1.0, 1.0]), f"{fld}.intensity",
                                      "3 numbers >= 0 (radiant intensity, W/sr), or one number for grey",
                                      grey=True, nonneg=True)
        else:
            ck.table(t, fld, DIRECTIONAL_KEYS, what="key for a directional light")
            allowed = "3 finite numbers, not all zero: the direction the light travels (from the light toward the scene)"
            if "direction" not in t:
                ck.fail(f"{fld}.direction", "missing (a directional light needs a direction)", allowed)
            light = Light("directional")
            d = ck.vec3(t["direction"], f"{fld}.direction", allowed, nonzero=True)
            d = d / np.max(np.abs(d))  # scaled first: the norm of [1e-200, -1e-200, 0] underflows
            light.direction = d / np.linalg.norm(d)
            light.irradiance = ck.vec3(t.get("irradiance", [1.0, 1.0, 1.0]), f"{fld}.irradiance",
                                       "3 numbers >= 0 (irradiance, W/m^2), or one number for grey",
                                       grey=True, nonneg=True)
        out.append(light)
    return out


def _mesh_allowed() -> str:
    try:
        from viewer.mesh import builtin_names

        names = ", ".join(builtin_names())
    except Exception:  # mesh module absent or broken: still give a useful hint
        names = "sphere, plane, ..."
    return f"a built-in mesh name ({names}) or a mesh file path relative to the scene file"


def _parse_objects(ck: _Checker, lst, materials: dict) -> list[SceneObject]:
    need = "one or more [[objects]] tables, each with mesh and material"
    if lst is None:
        ck.fail("objects", "missing (a scene needs at least one object)", need)
    if isinstance(lst, dict):
        ck.fail("objects", "is a single table", "an array of tables: write [[objects]] for each object")
    if not isinstance(lst, list):
        ck.fail("objects", f"expected an array of tables, got {_describe(lst)}", need)
    if not lst:
        ck.fail("objects", "is empty (a scene needs at least one object)", need)
    mat_allowed = ", ".join(materials) if materials else "none defined yet: add a [materials.NAME] table"
    out = []
    for i, t in enumerate(lst):
        fld = f"objects[{i}]"
        ck.table(t, fld, OBJECT_KEYS)
        if "mesh" not in t:
            ck.fail(f"{fld}.mesh", "missing", _mesh_allowed())
        mesh = ck.string(t["mesh"], f"{fld}.mesh", _mesh_allowed())
        if "material" not in t:
            ck.fail(f"{fld}.material", "missing", "the name of a [materials.NAME] table: " + mat_allowed)
        mat = ck.string(t["material"], f"{fld}.material", "a material name: " + mat_allowed)
        if mat not in materials:
            ck.fail(f"{fld}.material", f"unknown material {mat!r}", mat_allowed)
        obj = SceneObject(mesh=mesh, material=mat)
        if "translate" in t:
            obj.translate = ck.vec3(t["translate"], f"{fld}.translate", "3 finite numbers [x, y, z] in metres")
        if "scale" in t:
            s = t["scale"]
            allowed = "a number > 0, or 3 numbers > 0 [sx, sy, sz]"
            if isinstance(s, list):
                obj.scale = ck.vec3(s, f"{fld}.scale", allowed, positive=True)
            else:
                obj.scale = ck.number(s, f"{fld}.scale", allowed, 0.0, lo_open=True)
        if "rotate_y_deg" in t:
            obj.rotate_y_deg = ck.number(t["rotate_y_deg"], f"{fld}.rotate_y_deg",
                                         "a finite number of degrees (rotation about +y)")
        out.append(obj)
    return out


def _parse_materials(ck: _Checker, t, base_dir: Path | None = None) -> dict:
    from viewer import brdf
    from viewer.brdf.presets import PRESETS
    from viewer.brdf.spec import validate_params

    if not isinstance(t, dict):
        ck.fail("materials", f"expected a table, got {_describe(t)}", "[materials.NAME] tables")
    out = {}
    for name, raw in t.items():
        fld = f"materials.{_short(name, 40)}"
        if not isinstance(raw, dict):
            ck.fail(fld, f"expected a table, got {_describe(raw)}",
                    f"a [{fld}] table with model = one of {', '.join(brdf.names())} (or preset = ...)")
        raw = dict(raw)
        if "preset" in raw:
            pname = raw.pop("preset")
            allowed = ", ".join(PRESETS) or "none defined"
            if not isinstance(pname, str):
                ck.fail(f"{fld}.preset", f"expected a string, got {_describe(pname)}", allowed)
            if pname not in PRESETS:
                ck.fail(f"{fld}.preset", f"unknown preset {pname!r}", allowed)
            merged = copy.deepcopy(PRESETS[pname])
            if "model" in raw and raw["model"] != merged.get("model"):
                # The table picks another model: keep only the preset's parameters it knows.
                other = brdf.lookup_spec(raw["model"], f"{ck.label}: {fld}.model") if isinstance(
                    raw["model"], str) else None
                known = set(other.names) | set(other.aliases) if other else set()
                merged = {k: v for k, v in merged.items() if k in known}
            merged.update(raw)
            raw = merged
        if "model" not in raw:
            ck.fail(f"{fld}.model", "missing", ", ".join(brdf.names()) + " (or give preset = one of "
                    + (", ".join(PRESETS) or "none") + ")")
        model = raw.pop("model")
        if not isinstance(model, str):
            ck.fail(f"{fld}.model", f"expected a string, got {_describe(model)}", ", ".join(brdf.names()))
        spec = brdf.lookup_spec(model, f"{ck.label}: {fld}.model")
        if model == "measured" and isinstance(raw.get("file"), str) and raw["file"] and base_dir is not None:
            raw["file"] = str(Path(base_dir) / Path(raw["file"]).expanduser())  # relative to the scene file
        out[name] = validate_params(spec, raw, f"{ck.label}: {fld}", brdf.lookup_spec)
    return out


# ----------------------------------------------------------------------------- overrides

_INDEX = re.compile(r"\[(\d+)\]")


def _parse_value(text: str):
    """A TOML value (number, bool, array, inline table, quoted string); else the bare text."""
    text = text.strip()
    try:
        value = tomllib.loads(f"v = {text}")["v"]
    except (ValueError, RecursionError):  # TOMLDecodeError is a ValueError; so is a 5000-digit integer
        return text
    _check_nesting(value, f"--set value {_short(text)}")
    return value


def _override_parts(assignment: str) -> list[str]:
    key = assignment.split("=", 1)[0] if "=" in assignment else ""
    return _INDEX.sub(r".\1", key.strip()).split(".")


def _is_material_switch(assignment: str) -> bool:
    """``materials.NAME.model=...`` or ``materials.NAME.preset=...`` (also a nested material's,
    ``materials.NAME.base.model=...``)."""
    parts = _override_parts(assignment)
    return len(parts) >= 3 and parts[0] == "materials" and parts[-1] in ("model", "preset") and all(parts)


def _switch_material(data: dict, assignment: str) -> None:
    """Apply a model / preset assignment and drop every other value of that material table, so
    the material becomes the model's defaults or the preset."""
    parts = _override_parts(assignment)
    apply_override(data, assignment)  # checks the path, sets the value
    cur: Any = data
    for p in parts[:-1]:
        cur = cur[int(p)] if isinstance(cur, list) else cur[p]
    if isinstance(cur, dict):
        value = cur[parts[-1]]
        cur.clear()
        cur[parts[-1]] = value


def apply_override(data: dict, assignment: str, where: str = "--set") -> None:
    """Apply one ``KEY=VALUE`` assignment to ``data`` in place.

    KEY is a dotted path (``materials.ball.alpha``, ``camera.fov_y``); list items are addressed
    by index (``lights.0.intensity`` or ``lights[0].intensity``). VALUE is parsed as a TOML
    value (``0.2``, ``[1, 2, 3]``, ``true``, ``"text"``); a bare word that is not TOML is taken
    as a string (``model=ggx``). Missing top-level sections (camera, environment, render,
    materials) are created; any other missing part of the path is an error naming it. The
    value itself is checked later, by ``parse_scene``.
    """
    ck = _Checker(f"{where} {assignment}")
    if "=" not in assignment:
        ck.fail("KEY=VALUE", "no '=' in the assignment", "KEY=VALUE with a dotted KEY, e.g. materials.ball.alpha=0.2")
    key, text = assignment.split("=", 1)
    key = _INDEX.sub(r".\1", key.strip())
    parts = key.split(".")
    if not key or any(not p for p in parts):
        ck.fail(key or "KEY", "empty part in the dotted path",
                "a dotted path like materials.ball.alpha or lights.0.intensity")
    value = _parse_value(text)
    cur: Any = data
    for depth, part in enumerate(parts):
        here = ".".join(parts[:depth + 1])
        last = depth == len(parts) - 1
        if isinstance(cur, list):
            if not part.isdigit() or int(part) >= len(cur):
                allowed = (f"an index 0..{len(cur) - 1}" if cur else "nothing: the list is empty")
                ck.fail(here, f"no item {part!r} in {'.'.join(parts[:depth]) or 'the list'}", allowed)
            idx = int(part)
            if last:
                cur[idx] = value
            else:
                cur = cur[idx]
        elif isinstance(cur, dict):
            if last:
                cur[part] = value
            elif part in cur:
                cur = cur[part]
            elif depth == 0 and part in ("camera", "environment", "render", "materials"):
                cur[part] = {}
                cur = cur[part]
            else:
                allowed = ", ".join(map(str, cur)) if cur else "nothing here yet"
                if depth == 0:
                    allowed = ", ".join(TOP_KEYS)
                ck.fail(here, f"no {part!r} in {'.'.join(parts[:depth]) or 'the scene'}", allowed)
        else:
            ck.fail(here, f"{'.'.join(parts[:depth])} is a value ({_describe(cur)}), not a table or list",
                    "a path that ends at " + ".".join(parts[:depth]))


# ----------------------------------------------------------------------------- saving

def scene_to_data(scene: Scene) -> dict:
    """The scene's current values as plain TOML data (every value explicit, presets expanded).
    Relative paths are written relative to the scene's folder."""
    cam = scene.camera
    d: dict[str, Any] = {"version": SCENE_VERSION}
    d["camera"] = {"position": _list(cam.position), "target": _list(cam.target), "up": _list(cam.up),
                   "fov_y": float(cam.fov_y), "width": int(cam.width), "height": int(cam.height)}
    env = scene.environment
    e: dict[str, Any] = {}
    if env.map is not None:
        e["map"] = env.map if isinstance(env.map, str) else _rel(env.map, scene)
    else:
        e["constant"] = _list(env.constant if env.constant is not None else np.zeros(3))
    e["intensity"] = float(env.intensity)
    e["rotation_deg"] = float(env.rotation_deg)
    d["environment"] = e
    r = scene.render
    d["render"] = {"ibl": r.ibl, "ssr": bool(r.ssr), "shadows": bool(r.shadows), "msaa": int(r.msaa),
                   "exposure": float(r.exposure), "tonemap": r.tonemap,
                   "ms_compensation": bool(r.ms_compensation)}
    if r.raytrace or r.raytrace_depth != 8:
        d["render"].update(raytrace=bool(r.raytrace), raytrace_depth=int(r.raytrace_depth))
    lights = []
    for light in scene.lights:
        if light.type == "point":
            lights.append({"type": "point", "position": _list(light.position), "intensity": _list(light.intensity)})
        else:
            lights.append({"type": light.type, "direction": _list(light.direction),
                           "irradiance": _list(light.irradiance)})
    if lights:
        d["lights"] = lights
    objs = []
    for o in scene.objects:
        s = o.scale
        scale = _list(s) if np.ndim(s) else float(s)
        objs.append({"mesh": o.mesh, "material": o.material, "translate": _list(o.translate),
                     "scale": scale, "rotate_y_deg": float(o.rotate_y_deg)})
    d["objects"] = objs
    d["materials"] = {name: _plain(p.to_plain()) for name, p in scene.materials.items()}
    return d


def _list(a) -> list:
    return [float(x) for x in np.asarray(a, dtype=np.float64).reshape(-1)]


def _plain(v):
    if isinstance(v, dict):
        return {k: _plain(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_plain(x) for x in v]
    if isinstance(v, np.ndarray):
        return _list(v)
    if isinstance(v, np.generic):
        return v.item()
    return v


def _rel(p: Path, scene: Scene) -> str:
    base = scene.base_dir or (scene.path.parent if scene.path else Path.cwd())
    p = Path(p)
    try:
        return Path(os.path.relpath(p, Path(base).absolute())).as_posix()
    except ValueError:  # another drive on Windows
        return str(p)


def scene_to_toml(scene_or_data) -> str:
    """TOML text for a ``Scene`` (its current values, see ``scene_to_data``) or for plain data.
    ``parse_scene(tomllib.loads(scene_to_toml(s)), s.path) == s``."""
    data = scene_to_data(scene_or_data) if isinstance(scene_or_data, Scene) else _plain(scene_or_data)
    lines: list[str] = []
    _emit_table(lines, [], data, header=None)
    text = "\n".join(lines).strip("\n") + "\n"
    # tomli_w is the reference writer: fall back to it should our layout ever fail to parse back.
    try:
        if tomllib.loads(text) != data:
            raise ValueError
    except (tomllib.TOMLDecodeError, ValueError):
        text = tomli_w.dumps(data)
    return text


_BARE_KEY = re.compile(r"^[A-Za-z0-9_-]+$")


def _key(k: str) -> str:
    return k if _BARE_KEY.match(k) else _string(k)


def _string(s: str) -> str:
    return tomli_w.dumps({"v": s})[4:].strip()


def _is_aot(v) -> bool:
    return isinstance(v, list) and bool(v) and all(isinstance(x, dict) for x in v)


def _value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return _string(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{_key(k)} = {_value(x)}" for k, x in v.items()) + " }"
    return tomli_w.dumps({"v": v})[4:].strip()


def _emit_table(lines: list, prefix: list, tbl: dict, header: str | None):
    """Readable TOML: scalars and number arrays inline, tables as [a.b], arrays of tables as
    [[a.b]]. ``header`` is "[]" or "[[]]" for the kind of header this table gets (None: root)."""
    simple = [(k, v) for k, v in tbl.items() if not isinstance(v, dict) and not _is_aot(v)]
    nested = [(k, v) for k, v in tbl.items() if isinstance(v, dict) or _is_aot(v)]
    name = ".".join(_key(p) for p in prefix)
    if header == "[[]]" or (header == "[]" and (simple or not nested)):
        if lines:
            lines.append("")
        lines.append(f"[[{name}]]" if header == "[[]]" else f"[{name}]")
    for k, v in simple:
        lines.append(f"{_key(k)} = {_value(v)}")
    for k, v in nested:
        if isinstance(v, dict):
            _emit_table(lines, prefix + [k], v, "[]")
        else:
            for item in v:
                _emit_table(lines, prefix + [k], item, "[[]]")


def material_to_toml(name: str, params) -> str:
    """One material as a ``[materials.NAME]`` table, the scene file's format (a material file)."""
    return scene_to_toml({"materials": {name: _plain(params.to_plain())}})


def load_material_file(path) -> tuple[str, Any]:
    """(name, Params) of the first ``[materials.NAME]`` table of a TOML file (a material file or
    a whole scene), validated like a scene's materials. Raises ViewerError (one line)."""
    path = Path(path).expanduser()
    label = str(path)
    data = _read_toml(path, label)
    mats = data.get("materials")
    if not isinstance(mats, dict) or not mats:
        _Checker(label).fail("materials", "no [materials.NAME] table in the file",
                             "a file with [materials.NAME] and model = ... (or preset = ...)")
    name = next(iter(mats))
    return name, _parse_materials(_Checker(label), {name: mats[name]}, path.parent.absolute())[name]
