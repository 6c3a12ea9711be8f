"""What a reference engine renders from, the same for both engines: ``RenderSetup`` (the scene's
triangles and BVH from ``viewer.geometry``, its materials as ``MaterialInfo``, its lights, its
environment light (``viewer.reference_common.envmap``), the camera and the estimator's options), which
the CPU engine sends to its workers (picklable) and the GPU engine packs into textures. No GL."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from viewer import brdf
from viewer.brdf import twin_trust
from viewer.brdf.lobes import Lobe
from viewer.geometry.soup import SceneGeometry, build_geometry
from viewer.reference_common.envmap import EnvironmentLight
from viewer.reference_common.estimator import check_options


@dataclass
class MaterialInfo:
    name: str
    model_name: str
    params: object
    lobes: Lobe               # every lobe the material may draw (model.lobes(params))
    transmissive: bool
    sigma_a: np.ndarray       # (3,) absorption inside (transmissive), else zeros


def material_info(name: str, p) -> MaterialInfo:
    model = brdf.get(p.model)
    spec = model.spec
    lobes = model.lobes(p)
    sigma = np.zeros(3)
    if spec.transmissive and "sigma_a" in p:
        sigma = np.asarray(p["sigma_a"], dtype=np.float64).reshape(3).copy()
    return MaterialInfo(name, p.model, p, lobes, bool(spec.transmissive), sigma)


@dataclass
class RenderSetup:
    """Everything a worker needs (picklable): geometry, materials, lights, environment, camera."""

    geometry: SceneGeometry
    materials: list
    lights: list              # [("point", position, intensity) | ("directional", direction, irradiance)]
    env: EnvironmentLight
    cam_pos: np.ndarray
    cam_forward: np.ndarray
    cam_right: np.ndarray
    cam_up: np.ndarray
    tan_half_y: float
    width: int
    height: int
    max_depth: int = 8
    kernel: str = "embree"
    extra: dict = field(default_factory=dict)
    strategy: str = "mis"          # environment: "mis" | "bsdf" | "light" (every engine reads it)
    mis_heuristic: str = "power"   # "power" (beta = 2) | "balance"
    russian_roulette: bool = True
    integrator: str = "path"       # "path" | "photon" (viewer.reference_common.caustics), never "auto"
    integrator_reason: str = "asked for"

    @classmethod
    def from_scene(cls, scene, camera=None, width=None, height=None, max_depth: int = 8,
                   env_image=None, kernel: str = "embree", strategy: str = "mis",
                   mis_heuristic: str = "power", russian_roulette: bool = True,
                   integrator: str = "path") -> "RenderSetup":
        if camera is None:
            from viewer.scene.camera import OrbitCamera

            camera = OrbitCamera.from_scene(scene)
        width = int(width or scene.camera.width)
        height = int(height or scene.camera.height)
        pos = np.asarray(camera.position, dtype=np.float64)
        target = np.asarray(camera.target, dtype=np.float64)
        up = np.asarray(getattr(camera, "up", (0.0, 1.0, 0.0)), dtype=np.float64)
        fwd = target - pos
        fwd /= np.linalg.norm(fwd)
        right = np.cross(fwd, up)
        if np.linalg.norm(right) < 1e-12:  # looking along up: any perpendicular (as look_at would fail)
            right = np.cross(fwd, [1.0, 0.0, 0.0] if abs(fwd[0]) < 0.9 else [0.0, 0.0, 1.0])
        right /= np.linalg.norm(right)
        cam_up = np.cross(right, fwd)
        geom = build_geometry(scene)
        mats = [material_info(n, scene.materials[n]) for n in geom.material_names]
        lights = []
        for light in scene.lights:
            if light.type == "point":
                lights.append(("point", np.asarray(light.position, float), np.asarray(light.intensity, float)))
            else:
                d = np.asarray(light.direction, float)
                lights.append(("directional", d / np.linalg.norm(d), np.asarray(light.irradiance, float)))
        check_options(strategy, mis_heuristic, integrator)
        env = EnvironmentLight.from_scene(scene, env_image)
        setup = cls(geom, mats, lights, env, pos, fwd, right, cam_up,
                   math.tan(math.radians(float(camera.fov_y)) / 2.0), width, height, int(max_depth), kernel,
                   extra={"object_y": np.array([o.y_range() if o.mesh_data is not None else (0.0, 0.0)
                                                for o in scene.objects] or [(0.0, 0.0)]),
                          # the twins this process trusts: the workers take this decision as theirs
                          "trusted_twins": twin_trust.trusted_twins(
                              m.params["file"] for m in mats if brdf.is_file(m.params))},
                   strategy=strategy, mis_heuristic=mis_heuristic, russian_roulette=bool(russian_roulette))
        if integrator == "auto":   # the scene decides (one line says why)
            from viewer.reference_common.caustics import choose_integrator

            setup.integrator, setup.integrator_reason = choose_integrator(setup)
        else:
            setup.integrator = integrator
        return setup
