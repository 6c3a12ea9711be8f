"""The scene model: the data classes a validated scene is made of (``Scene``, ``Camera``,
``Light``, ``RenderSettings``, ``SceneObject``; ``Environment`` is in ``viewer.scene.environment``)
and the scene file's vocabulary: its sections, keys and allowed values."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from viewer.scene.environment import Environment
from viewer.scene.equality import equal

SCENE_VERSION = 1

TOP_KEYS = ("version", "camera", "environment", "render", "lights", "objects", "materials")
CAMERA_KEYS = ("position", "target", "up", "fov_y", "width", "height")
ENV_KEYS = ("constant", "map", "intensity", "rotation_deg")
RENDER_KEYS = ("ibl", "ssr", "shadows", "msaa", "exposure", "tonemap", "ms_compensation", "raytrace", "raytrace_depth",
               "raytrace_occlusion")
LIGHT_TYPES = ("point", "directional")
POINT_KEYS = ("type", "position", "intensity")
DIRECTIONAL_KEYS = ("type", "direction", "irradiance")
OBJECT_KEYS = ("mesh", "material", "translate", "scale", "rotate_y_deg")

IBL_MODES = ("split_sum", "fis", "brute_force", "off")
TONEMAPS = ("none", "aces", "filmic", "reinhard")
MSAA_SAMPLES = (0, 1, 2, 4, 8)
MAX_SIZE = 16384
SIZE_ALLOWED = f"an integer of pixels in [1, {MAX_SIZE}]"  # camera.width, camera.height
# The most objects and triangles (over all objects, each counting its mesh's) a scene may hold
# (docs/scene-format.md, [[objects]]): beyond them software OpenGL takes minutes a frame and the
# reference's world-space triangles (72 bytes each) outgrow memory. 1,000 built-in spheres are
# 20 million triangles; 10,000 cubes 120,000.
MAX_OBJECTS = 100_000
MAX_TRIANGLES = 30_000_000
# The most lights a scene may hold (docs/scene-format.md, [[lights]]): the rasterizer's and the
# GPU engine's uniform arrays are this long; the rasterizer shadow-maps the first 4 of them.
MAX_LIGHTS = 16
LARGE_SCENE_OBJECTS = 1_000   # from here on, loading says how large the scene is (Scene.size_note)
EXPOSURE_RANGE = (-20.0, 20.0)
# Both renderers store scene numbers as float32 (GPU uniforms, Embree vertices, float32 images):
# a finite float64 beyond this would turn into inf there.
FLOAT32_MAX = float(np.finfo(np.float32).max)
#: m: the largest |coordinate| of a camera, a light or an object's translation (a camera 1e17 m
#: away has near = far in float64: its projection divides by zero; the renderers compute in float32)
MAX_COORD = 1e6
#: the range of an object's scale (each component): within it a unit mesh stays inside MAX_COORD
MIN_SCALE, MAX_SCALE = 1e-6, 1e6
MIN_VIEW_DISTANCE = 1e-6  # m, between camera.position and camera.target (viewer.scene.camera clamps there)


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
        return equal(self, other)


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
        return equal(self, other)


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
    # with raytrace: the diffuse environment term traces its occlusion in the same triangles
    # (16 cosine rays a pixel, 4 at a chain's hits); off by default, since it multiplies a traced
    # frame's cost 3-30x on a software rasterizer and shows grain in one frame
    raytrace_occlusion: bool = False

    def __eq__(self, other):
        return equal(self, other)


@dataclass(eq=False)
class SceneObject:
    """One mesh instance. ``mesh`` is the reference as written in the file (a built-in name or
    a path relative to the scene file); ``mesh_data`` is the loaded ``viewer.scene.mesh.MeshData``
    (None when the scene was parsed with ``load_meshes=False``). ``scale`` is a float or a
    (3,) array of positive numbers."""

    mesh: str
    material: str
    translate: np.ndarray = field(default_factory=lambda: np.zeros(3))
    scale: float | np.ndarray = 1.0
    rotate_y_deg: float = 0.0
    mesh_data: Any = field(default=None, repr=False)
    #: what ``equal`` leaves out of an object, also inside a Scene's list: a scene loaded with
    #: meshes equals the same scene parsed with ``load_meshes=False``
    EQ_SKIP = ("mesh_data",)

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

    def y_range(self) -> tuple[float, float]:
        """(lowest, highest) world y of the mesh: the height over which a thin film's thickness
        varies (``thin_film.thickness_top_nm``). The rotation is about y, so only the scale and
        translation matter."""
        y = np.asarray(self.mesh_data.positions, dtype=np.float64).reshape(-1, 3)[:, 1]
        if y.size == 0:
            return 0.0, 0.0
        sy = float(np.broadcast_to(np.asarray(self.scale, dtype=np.float64), (3,))[1])
        ty = float(np.asarray(self.translate, dtype=np.float64)[1])
        return sy * float(y.min()) + ty, sy * float(y.max()) + ty

    def __eq__(self, other):
        return equal(self, other, skip=self.EQ_SKIP)


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
        local: dict = {}   # (mesh, rotation, scale) -> the box of the turned and scaled vertices
        for obj in self.objects:
            if obj.mesh_data is None:
                continue
            k = (id(obj.mesh_data), float(obj.rotate_y_deg), np.asarray(obj.scale, np.float64).tobytes())
            box = local.get(k)
            if box is None:
                p = np.asarray(obj.mesh_data.positions, dtype=np.float64).reshape(-1, 3)
                if not len(p):
                    continue
                p = p @ obj.model_matrix()[:3, :3].T
                box = local[k] = (p.min(axis=0), p.max(axis=0))
            # rounding is monotonic, so min(p + t) = min(p) + t exactly: world_positions' box
            t = np.asarray(obj.translate, np.float64)
            lo = np.minimum(lo, box[0] + t)
            hi = np.maximum(hi, box[1] + t)
        if not np.all(np.isfinite(lo)):
            return np.zeros(3), np.zeros(3)
        return lo, hi

    def size_note(self) -> str | None:
        """"N objects, T triangles" for a scene of ``LARGE_SCENE_OBJECTS`` objects or more (the
        CLI prints it on stderr, the window in its status line: such a load takes seconds), else
        None."""
        if len(self.objects) < LARGE_SCENE_OBJECTS:
            return None
        tris = sum(len(o.mesh_data.indices) for o in self.objects if o.mesh_data is not None)
        return f"{len(self.objects):,} objects, {tris:,} triangles"

    def __eq__(self, other):
        return equal(self, other, skip=("data", "label", "base_dir"))
