"""Caustic scenes with closed forms (the photon integrator's oracles; no test module imports
another, so the scenes and their exact answers live here).

``mirror_wall``: a point light (intensity I) at height h over a perfect mirror floor (fresnel
"none", R = 1) lights a Lambert wall (albedo rho) standing on the floor; the camera sees only the
wall. Irradiance at a wall point p: the light itself plus its mirror image at height -h (the
reflected ray meets the floor in front of the wall, inside the mirror),
    E(p) = I cos / d^2 + R I cos' / d'^2,   L = rho / pi E,
cos = (z_light - z_wall) / d (the wall faces +z). The image term is a caustic: under ``photon`` the
photon map's alone; the direct term is next-event estimation's.

``glass_slab``: a directional light of irradiance E straight down through a smooth glass slab
(ior n, thickness t, absorption sigma_a) onto a Lambert floor; the camera, below the slab, sees
only the floor. Under the slab, away from its edges, the floor's irradiance is E times the slab's
transmittance with every internal reflection (head-on Fresnel R = ((n - 1) / (n + 1))^2, Bouguer
a = exp(-sigma_a t)): T = (1 - R)^2 a / (1 - R^2 a^2); elsewhere E. max_depth 1: nothing after the
floor (no floor -> slab -> floor interreflection in the closed form).

``expected(...)``: the closed form per pixel (the camera's box filter by ``SUB`` x ``SUB``
sub-pixel rays), and its caustic term averaged over the gather disk of each pass's radius (what
the photon estimator's passes converge to in expectation at a finite number of passes: the
uniform kernel blurs the caustic over the disk |x - x_p| < r_i on the surface), and a mask of the
pixels whose disks lie wholly on one smooth part of the answer.
"""

from __future__ import annotations

import math
import tomllib

import numpy as np

from viewer.scene import SCENE_DIR, parse_scene

SUB = 6           # sub-pixel rays per axis for the camera's box filter
DISK_RINGS = 6    # the gather disk's quadrature: rings x spokes midpoint rule (exact for linear E)
DISK_SPOKES = 12

MIRROR_WALL = dict(I=6.0, h=0.5, rho=0.8, wall_z=-1.0)
GLASS_SLAB = dict(E=2.0, ior=1.5, t=0.2, y0=0.9, half=1.0, sigma_a=(0.2, 1.0, 3.0), rho=0.6, floor=2.0)


def mirror_wall_scene(size: int):
    c = MIRROR_WALL
    text = f"""
[camera]
position = [0.0, 1.3, 3.0]
target = [0.0, 1.3, -1.0]
up = [0.0, 1.0, 0.0]
fov_y = 30.0
width = {size}
height = {size}

[[lights]]
type = "point"
position = [0.0, {c['h']}, 0.0]
intensity = [{c['I']}, {c['I']}, {c['I']}]

[[objects]]
mesh = "plane"
material = "mirror"
scale = 3.0

[[objects]]
mesh = "cube"
material = "wall"
scale = [3.0, 3.0, 0.05]
translate = [0.0, 3.0, {c['wall_z'] - 0.05}]

[materials.mirror]
model = "mirror"
fresnel = "none"

[materials.wall]
model = "lambert"
albedo = [{c['rho']}, {c['rho']}, {c['rho']}]
"""
    return parse_scene(tomllib.loads(text), None, label="<mirror wall>", base_dir=SCENE_DIR)


def glass_slab_scene(size: int):
    c = GLASS_SLAB
    s = c["sigma_a"]
    text = f"""
[camera]
position = [0.0, 0.7, 2.2]
target = [0.0, 0.0, -0.3]
up = [0.0, 1.0, 0.0]
fov_y = 30.0
width = {size}
height = {size}

[[lights]]
type = "directional"
direction = [0.0, -1.0, 0.0]
irradiance = [{c['E']}, {c['E']}, {c['E']}]

[[objects]]
mesh = "plane"
material = "floor"
scale = {c['floor']}

[[objects]]
mesh = "cube"
material = "glass"
scale = [{c['half']}, {c['t'] / 2}, {c['half']}]
translate = [0.0, {c['y0'] + c['t'] / 2}, 0.0]

[materials.floor]
model = "lambert"
albedo = [{c['rho']}, {c['rho']}, {c['rho']}]

[materials.glass]
model = "dielectric"
ior = {c['ior']}
alpha = 0.0
sigma_a = [{s[0]}, {s[1]}, {s[2]}]
"""
    return parse_scene(tomllib.loads(text), None, label="<glass slab>", base_dir=SCENE_DIR)


def slab_transmittance() -> np.ndarray:
    c = GLASS_SLAB
    R = ((c["ior"] - 1.0) / (c["ior"] + 1.0)) ** 2
    a = np.exp(-np.asarray(c["sigma_a"]) * c["t"])
    return (1.0 - R) ** 2 * a / (1.0 - R * R * a * a)


def _camera_rays(scene, size):
    cam = scene.camera
    pos = np.asarray(cam.position, float)
    fwd = np.asarray(cam.target, float) - pos
    fwd /= np.linalg.norm(fwd)
    right = np.cross(fwd, np.asarray(cam.up, float))
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    th = math.tan(math.radians(cam.fov_y) / 2.0)
    s = (np.arange(SUB) + 0.5) / SUB
    px = np.arange(size)
    x = (2.0 * (px[None, :, None, None] + s[None, None, None, :]) / size - 1.0) * th
    y = (1.0 - 2.0 * (px[:, None, None, None] + s[None, None, :, None]) / size) * th
    x, y = np.broadcast_arrays(x, y)          # (rows, cols, SUB, SUB)
    d = fwd + x[..., None] * right + y[..., None] * up
    return pos, d / np.linalg.norm(d, axis=-1, keepdims=True)


def _disk(r):
    """Offsets (K, 2) and weights (K,) of the midpoint rule on the disk of radius r (equal areas)."""
    k = np.arange(DISK_RINGS)
    rho = r * np.sqrt((k + 0.5) / DISK_RINGS)
    phi = 2.0 * math.pi * (np.arange(DISK_SPOKES) + 0.5) / DISK_SPOKES
    off = np.stack([np.outer(rho, np.cos(phi)).ravel(), np.outer(rho, np.sin(phi)).ravel()], axis=1)
    return off, np.full(off.shape[0], 1.0 / off.shape[0])


def expected(name: str, size: int, radii=()):
    """(closed form (H, W, 3), its expectation with the caustic averaged over the disks of
    ``radii`` (one per pass; none: the closed form), mask (H, W) of pixels whose disks stay on one
    smooth part)."""
    if name == "mirror_wall":
        c = MIRROR_WALL
        sc = mirror_wall_scene(size)
        o, d = _camera_rays(sc, size)
        t = (c["wall_z"] - o[2]) / d[..., 2]
        p = o + t[..., None] * d                      # wall points (rows, cols, SUB, SUB, 3)
        light = np.array([0.0, c["h"], 0.0])
        image = np.array([0.0, -c["h"], 0.0])

        def irr(q, src):
            v = src - q
            dist = np.linalg.norm(v, axis=-1)
            return c["I"] * v[..., 2] / dist ** 3

        direct = irr(p, light)
        caustic = irr(p, image)
        blurred = caustic if not len(radii) else np.mean(
            [sum(w * irr(p + np.array([dx, dy, 0.0]), image) for (dx, dy), w in zip(*_disk(r))) for r in radii],
            axis=0)
        to_l = c["rho"] / math.pi
        exact = to_l * (direct + caustic).mean(axis=(2, 3))
        expect = to_l * (direct + blurred).mean(axis=(2, 3))
        mask = np.ones((size, size), bool)            # the caustic is smooth over the whole wall
        rgb = lambda a: np.repeat(a[..., None], 3, axis=-1)   # noqa: E731
        return rgb(exact), rgb(expect), mask
    c = GLASS_SLAB
    sc = glass_slab_scene(size)
    o, d = _camera_rays(sc, size)
    t = -o[1] / d[..., 1]
    p = o + t[..., None] * d
    hit = (t > 0) & (np.abs(p[..., 0]) <= c["floor"]) & (np.abs(p[..., 2]) <= c["floor"])
    T = slab_transmittance()

    def irr(px, pz):
        under = (np.abs(px) < c["half"]) & (np.abs(pz) < c["half"])
        return np.where(under[..., None], c["E"] * T, c["E"])

    exact_e = np.where(hit[..., None], irr(p[..., 0], p[..., 2]), 0.0)
    # the caustic part (under the slab) blurred over each pass's disk; the direct part is exact
    if len(radii):
        caus = []
        for r in radii:
            acc = 0.0
            for (dx, dz), w in zip(*_disk(r)):
                qx, qz = p[..., 0] + dx, p[..., 2] + dz
                under = (np.abs(qx) < c["half"]) & (np.abs(qz) < c["half"])
                acc = acc + w * np.where(under[..., None], c["E"] * T, 0.0)
            caus.append(acc)
        blur = np.mean(caus, axis=0)
        under = (np.abs(p[..., 0]) < c["half"]) & (np.abs(p[..., 2]) < c["half"])
        expect_e = np.where(hit[..., None], np.where(under[..., None], 0.0, c["E"]) + blur, 0.0)
    else:
        expect_e = exact_e
    to_l = c["rho"] / math.pi
    # the mask: the pixel's floor points all on one side of the slab's edges by more than the
    # first radius, and all on the floor
    rmax = max(radii) if len(radii) else 0.0
    m = np.maximum(np.abs(p[..., 0]), np.abs(p[..., 2]))
    edge = np.abs(m - c["half"]) > rmax + 1e-3
    mask = (edge & hit).all(axis=(2, 3))
    return to_l * exact_e.mean(axis=(2, 3)), to_l * expect_e.mean(axis=(2, 3)), mask


def slab_under_sky(size: int):
    """The glass slab scene lit by a constant sky alone: the floor under the slab sees the sky
    through the glass (caustic paths under ``photon``: the photon map's), around it directly;
    a broad light that path tracing also finds, so both integrators converge to one image."""
    sc = glass_slab_scene(size)
    sc.lights = []
    sc.environment.map = None
    sc.environment.constant = np.array([0.6, 0.65, 0.7])
    sc.environment.intensity = 1.0
    return sc


def coated_mirrors(size: int):
    """The mirror-wall scene with the floor and the wall both a glossy coat over a mirror (a
    material with a smooth and a delta lobe): photons are stored on the coat and go on through
    the mirror under it, so the photon pass's later rounds matter. No closed form: the engines
    are compared."""
    sc = mirror_wall_scene(size)
    coat = {"model": "layered", "coating": {"ior": 1.5, "alpha": 0.2, "thickness": 0.0, "sigma_a": [0.0, 0.0, 0.0]},
            "base": {"model": "mirror", "fresnel": "none"}}
    text = {"camera": {"position": list(sc.camera.position), "target": list(sc.camera.target),
                       "up": [0.0, 1.0, 0.0], "fov_y": float(sc.camera.fov_y), "width": size, "height": size},
            "lights": [{"type": "point", "position": [0.0, MIRROR_WALL["h"], 0.0],
                        "intensity": [MIRROR_WALL["I"]] * 3}],
            "objects": [{"mesh": "plane", "material": "floor", "scale": 3.0},
                        {"mesh": "cube", "material": "wall", "scale": [3.0, 3.0, 0.05],
                         "translate": [0.0, 3.0, MIRROR_WALL["wall_z"] - 0.05]}],
            "materials": {"floor": coat, "wall": dict(coat)}}
    return parse_scene(text, None, label="<coated mirrors>", base_dir=SCENE_DIR)
