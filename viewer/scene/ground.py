"""The ground an untraced thin shell reflects: the scene's floor as an analytic plane.

An untraced soap bubble (a dielectric of ior 1, drawn over the frame by the rasterizer's shell
pass) reflects what its faces see. The environment map alone has no floor: the studio map is dark
below the horizon, so the far face of a bubble, a concave mirror whose upper half looks down at
the floor, reflected almost nothing there, and the bubble's upper half was the dark wall behind
it where the traced bubble and the reference show the lit floor in the film. The shell pass
therefore meets its reflected rays with this plane first: where a ray going down lands on it,
the face reflects the floor's radiance there (its Lambert albedo over pi times the irradiance of
the lights, with their shadow maps, and of the environment from the upper hemisphere, the way
the rasterizer shades the floor itself); elsewhere it reflects the environment as before.

The ground is the largest ``plane`` mesh with a Lambert material (a plane mesh stays horizontal:
objects turn about +y only). None when the scene has none; then shells reflect the environment
only."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from viewer import brdf


@dataclass(frozen=True)
class Ground:
    """A horizontal rectangle at height ``origin[1]``: world point (x, y, z) lies on it when
    ``to_local @ (x - origin[0], z - origin[2])`` is in [-1, 1]^2 (the plane mesh's own
    coordinates). ``albedo``: its Lambert albedo (linear RGB)."""

    origin: np.ndarray    # (3,) the plane's centre
    to_local: np.ndarray  # (2, 2) world (dx, dz) -> the mesh's (x, z)
    albedo: np.ndarray    # (3,)

    def contains(self, x, z) -> np.ndarray:
        """Whether world points (x, z) (arrays) lie over the rectangle."""
        d = np.stack([np.asarray(x, float) - self.origin[0], np.asarray(z, float) - self.origin[2]])
        u = np.tensordot(self.to_local, d, axes=1)
        return (np.abs(u[0]) <= 1.0) & (np.abs(u[1]) <= 1.0)


def ground_plane(scene) -> Ground | None:
    """The scene's ground for the shells' reflections (see the module), or None."""
    best, best_area = None, 0.0
    for obj in scene.objects:
        params = scene.materials.get(obj.material)
        if obj.mesh != "plane" or params is None or brdf.lambertian_albedo(params) is None:
            continue
        s = np.broadcast_to(np.asarray(obj.scale, dtype=np.float64), (3,))
        area = float(s[0] * s[2])
        if area > best_area:
            best, best_area = (obj, params, s), area
    if best is None:
        return None
    obj, params, s = best
    a = math.radians(obj.rotate_y_deg)
    c, sn = math.cos(a), math.sin(a)
    # the model matrix maps the mesh's (x, z) to world (c s_x x + sn s_z z, -sn s_x x + c s_z z)
    # (SceneObject.model_matrix: T R_y S); its inverse: R_y transposed, then 1 / scale
    to_local = np.array([[c / s[0], -sn / s[0]], [sn / s[2], c / s[2]]])
    albedo = brdf.lambertian_albedo(params)
    return Ground(origin=np.asarray(obj.translate, dtype=np.float64).copy(), to_local=to_local, albedo=albedo)

