"""Independent camera rays and analytic shading for the renderer tests (numpy only; no pyrr,
no renderer code), so a wrong projection or orientation in the renderer is caught."""

import math

import numpy as np


def camera_rays(position, target, up, fov_y, width, height, offset=(0.5, 0.5)):
    """Unit ray directions (H, W, 3) through each pixel's point ``offset`` (0.5 = centre).
    Row 0 is the top of the image, +x of the camera is to the right."""
    pos = np.asarray(position, float)
    fwd = np.asarray(target, float) - pos
    fwd /= np.linalg.norm(fwd)
    right = np.cross(fwd, np.asarray(up, float))
    right /= np.linalg.norm(right)
    upv = np.cross(right, fwd)
    t = math.tan(math.radians(fov_y) / 2)
    aspect = width / height
    j = (np.arange(width) + offset[0]) / width * 2 - 1
    i = 1 - (np.arange(height) + offset[1]) / height * 2
    x = j[None, :] * t * aspect
    y = i[:, None] * t
    d = fwd[None, None, :] + x[..., None] * right[None, None, :] + y[..., None] * upv[None, None, :]
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def hit_sphere(origin, dirs, center, radius):
    """Distance along each ray to the first hit of a sphere, inf where it misses."""
    oc = np.asarray(origin, float) - np.asarray(center, float)
    b = np.sum(dirs * oc, axis=-1)
    c = np.dot(oc, oc) - radius * radius
    disc = b * b - c
    t = -b - np.sqrt(np.maximum(disc, 0.0))
    return np.where((disc > 0) & (t > 0), t, np.inf)


def hit_plane_y(origin, dirs, y0):
    o = np.asarray(origin, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (y0 - o[1]) / dirs[..., 1]
    return np.where(np.isfinite(t) & (t > 0), t, np.inf)


def lambert_point(albedo, intensity, light_pos, p, n):
    """albedo/pi * I * max(0, n.l) / r^2 (docs/conventions.md), per pixel (H, W, 3)."""
    d = np.asarray(light_pos, float) - p
    r2 = np.sum(d * d, axis=-1, keepdims=True)
    l = d / np.sqrt(r2)
    cos = np.maximum(np.sum(n * l, axis=-1, keepdims=True), 0.0)
    return np.asarray(albedo) / np.pi * np.asarray(intensity) * cos / r2


def sphere_interior(cam, center=(0, 0, 0), radius=1.0, light=(2.0, 3.0, 3.0), margin=1):
    """Pixels whose four corners all see the sphere, with the terminator band removed (there
    the raster's value at the pixel centre and the reference's pixel average differ by more
    than curvature: n.l changes sign inside the pixel)."""
    inside = np.ones((cam.height, cam.width), bool)
    sign = []
    for off in ((0, 0), (1, 0), (0, 1), (1, 1)):
        d = camera_rays(cam.position, cam.target, cam.up, cam.fov_y, cam.width, cam.height, off)
        t = hit_sphere(cam.position, d, center, radius)
        inside &= np.isfinite(t)
        p = cam.position + d * np.where(np.isfinite(t), t, 0)[..., None]
        n = p - np.asarray(center)
        l = np.asarray(light) - p
        sign.append(np.sum(n * l, axis=-1) > 0)
    same = np.all(sign, axis=0) | ~np.any(sign, axis=0)
    m = inside & same
    for _ in range(margin):
        m[1:, :] &= m[:-1, :]
        m[:-1, :] &= m[1:, :]
        m[:, 1:] &= m[:, :-1]
        m[:, :-1] &= m[:, 1:]
    return m
