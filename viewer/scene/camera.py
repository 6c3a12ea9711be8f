"""Orbit camera (three.js OrbitControls conventions: left rotate, right/middle pan, wheel dolly).

Matrices are numpy 4x4 in the column-vector convention (clip = P @ V @ [x, y, z, 1]); pyrr
builds them in its row-vector convention and we transpose once, here. ``gl_bytes`` writes a
column-convention matrix so GLSL's ``M * v`` means the same thing.
"""

from __future__ import annotations

import math

import numpy as np
from pyrr import matrix44

PITCH_LIMIT = math.radians(89.0)  # just short of the poles, so up never flips


def gl_bytes(m: np.ndarray) -> bytes:
    """Bytes of a column-convention matrix for a GLSL mat4/mat3 uniform (GLSL is column-major)."""
    return np.ascontiguousarray(np.asarray(m, dtype=np.float32).T).tobytes()


def look_at(eye, target, up) -> np.ndarray:
    return matrix44.create_look_at(np.asarray(eye, float), np.asarray(target, float),
                                   np.asarray(up, float), dtype=np.float64).T


def perspective(fov_y_deg: float, aspect: float, near: float, far: float) -> np.ndarray:
    return matrix44.create_perspective_projection(fov_y_deg, aspect, near, far, dtype=np.float64).T


def orthographic(half_w: float, half_h: float, near: float, far: float) -> np.ndarray:
    return matrix44.create_orthogonal_projection(-half_w, half_w, -half_h, half_h, near, far,
                                                 dtype=np.float64).T


class OrbitCamera:
    """Position given by target, distance, yaw and pitch around the world +y axis."""

    def __init__(self, position, target, fov_y: float = 40.0, up=(0.0, 1.0, 0.0)):
        self.fov_y = float(fov_y)
        self.up = np.asarray(up, dtype=np.float64)
        self._set_from(np.asarray(position, float), np.asarray(target, float))
        self._home = (self.target.copy(), self.distance, self.yaw, self.pitch, self.fov_y)
        self.near_far = None  # (near, far) set by fit(); otherwise derived from the distance

    @classmethod
    def from_scene(cls, scene) -> "OrbitCamera":
        c = scene.camera
        cam = cls(c.position, c.target, c.fov_y, c.up)
        lo, hi = scene.bounds()
        given = isinstance(getattr(scene, "data", None), dict) and "position" in scene.data.get("camera", {})
        if given:
            cam.set_clip_from_bounds(lo, hi)
        else:  # no camera in the file: frame the whole scene from the default direction
            cam.fit(lo, hi)
        cam._home = (cam.target.copy(), cam.distance, cam.yaw, cam.pitch, cam.fov_y)
        return cam

    def _set_from(self, position, target):
        self.target = target.astype(np.float64)
        d = position - target
        self.distance = max(float(np.linalg.norm(d)), 1e-6)
        d = d / self.distance
        self.pitch = math.asin(max(-1.0, min(1.0, d[1])))
        self.yaw = math.atan2(d[0], d[2])

    @property
    def position(self) -> np.ndarray:
        cp = math.cos(self.pitch)
        d = np.array([cp * math.sin(self.yaw), math.sin(self.pitch), cp * math.cos(self.yaw)])
        return self.target + self.distance * d

    def view(self) -> np.ndarray:
        return look_at(self.position, self.target, self.up)

    def set_clip_from_bounds(self, lo, hi):
        self._bounds = (np.asarray(lo, float), np.asarray(hi, float))

    def clip_planes(self) -> tuple[float, float]:
        """Near/far from the scene bounds so depth precision is spent on the scene."""
        if getattr(self, "_bounds", None) is None:
            return 0.01 * self.distance, 100.0 * self.distance
        lo, hi = self._bounds
        center = 0.5 * (lo + hi)
        radius = 0.5 * float(np.linalg.norm(hi - lo)) + 1e-3
        dist = float(np.linalg.norm(self.position - center))
        far = dist + radius * 1.05
        near = max(dist - radius * 1.05, far * 1e-4, 1e-3)
        return near, far

    def projection(self, aspect: float) -> np.ndarray:
        near, far = self.clip_planes()
        return perspective(self.fov_y, aspect, near, far)

    # ------------------------------------------------------------ interaction
    def orbit(self, dx_px: float, dy_px: float, viewport_h: float):
        k = math.pi / max(viewport_h, 1.0)  # a drag over the viewport height turns by 180 deg
        self.yaw -= dx_px * k
        self.pitch = max(-PITCH_LIMIT, min(PITCH_LIMIT, self.pitch + dy_px * k))

    def pan(self, dx_px: float, dy_px: float, viewport_h: float):
        v = self.view()
        right, up = v[0, :3], v[1, :3]
        world_per_px = 2.0 * self.distance * math.tan(math.radians(self.fov_y) / 2) / max(viewport_h, 1.0)
        self.target = self.target - right * dx_px * world_per_px + up * dy_px * world_per_px

    def dolly(self, steps: float):
        self.distance = max(1e-3, self.distance * (0.9 ** steps))

    def reset(self):
        t, self.distance, self.yaw, self.pitch, self.fov_y = self._home
        self.target = t.copy()

    def fit(self, lo, hi):
        """Frame the bounding sphere of (lo, hi), keeping the view direction."""
        lo, hi = np.asarray(lo, float), np.asarray(hi, float)
        self.target = 0.5 * (lo + hi)
        radius = max(0.5 * float(np.linalg.norm(hi - lo)), 1e-3)
        self.distance = radius / math.sin(math.radians(self.fov_y) / 2) * 1.05
        self.set_clip_from_bounds(lo, hi)


def screen_boxes(camera: OrbitCamera, w: int, h: int, objects) -> list:
    """Per object of ``objects`` (scene objects: a mesh's bounds under a model matrix), the
    pixels (x0, y0, x1, y1), from the bottom left of a w x h frame, that its box covers when
    projected; None where the box crosses the camera's plane (then it may cover any pixel)."""
    vp = camera.projection(w / h) @ camera.view()
    out = []
    for obj in objects:
        lo, hi = obj.mesh_data.bounds()
        corners = np.array([[x, y, z, 1.0] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
        clip = corners @ (vp @ obj.model_matrix()).T
        cw = clip[:, 3]
        if not np.all(cw > 1e-6):
            out.append(None)
            continue
        px = (clip[:, 0] / cw + 1.0) * 0.5 * w
        py = (clip[:, 1] / cw + 1.0) * 0.5 * h
        out.append((float(px.min()), float(py.min()), float(px.max()), float(py.max())))
    return out
