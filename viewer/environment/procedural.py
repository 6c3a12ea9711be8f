"""Built-in environment maps, generated (no downloads): ``sky``, ``studio`` and ``constant``.

Each generator is ``f(width, height, **params) -> float32 (H, W, 3)`` linear Rec.709 radiance
in the lat-long orientation of ``viewer.environment.latlong`` (row 0 = zenith, u = 0.5 looks
along -z). Scene files name them by ``[environment] map = "sky"`` or ``map = "studio"``
(their defaults); ``generate(name, width, height)`` is the dispatch.

Azimuths here are the lat-long's phi = atan2(d.x, -d.z) in degrees: 0 = -z (straight ahead of
the default camera, which looks along -z), +90 = +x (right), -90 = -x (left), 180 = +z (behind
the camera). Elevations are degrees above the horizon.
"""

from __future__ import annotations

import math
import threading

import numpy as np

from viewer.environment.latlong import dir_to_uv, row_solid_angles, texel_directions, uv_to_dir
from viewer.spectral.colorimetry import LUMINANCE_REC709

# CIE XYZ -> linear Rec.709 RGB (IEC 61966-2-1 sRGB, D65 white).
XYZ_TO_REC709 = np.array([[3.2404542, -1.5371385, -0.4985314],
                          [-0.9692660, 1.8760108, 0.0415560],
                          [0.0556434, -0.2040259, 1.0572252]])
REC709_LUMA = LUMINANCE_REC709


def direction(azimuth_deg: float, elevation_deg: float) -> np.ndarray:
    """Unit direction of an azimuth (phi = atan2(d.x, -d.z)) and an elevation, in degrees."""
    phi, el = math.radians(azimuth_deg), math.radians(elevation_deg)
    return np.array([math.cos(el) * math.sin(phi), math.sin(el), -math.cos(el) * math.cos(phi)])


def constant(width: int, height: int, rgb=(1.0, 1.0, 1.0)) -> np.ndarray:
    """A map of one radiance ``rgb`` everywhere."""
    rgb = np.broadcast_to(np.asarray(rgb, dtype=np.float32), (3,))
    return np.broadcast_to(rgb, (height, width, 3)).astype(np.float32)


# ----------------------------------------------------------------------------- sky

# Preetham, Shirley & Smits 1999, "A Practical Analytic Model for Daylight", appendix A.2:
# the Perez coefficients (A, B, C, D, E) as linear functions of the turbidity T, rows = (Y, x, y),
# each entry (slope on T, offset).
PEREZ_COEFFS = np.array([
    # A                 B                  C                  D                  E
    [[0.1787, -1.4630], [-0.3554, 0.4275], [-0.0227, 5.3251], [0.1206, -2.5771], [-0.0670, 0.3703]],  # Y
    [[-0.0193, -0.2592], [-0.0665, 0.0008], [-0.0004, 0.2125], [-0.0641, -0.8989], [-0.0033, 0.0452]],  # x
    [[-0.0167, -0.2608], [-0.0950, 0.0092], [-0.0079, 0.2102], [-0.0441, -1.6537], [-0.0109, 0.0529]],  # y
])
# Appendix A.2: zenith chromaticity x_z, y_z = [T^2, T, 1] M [theta_s^3, theta_s^2, theta_s, 1]^T.
ZENITH_X = np.array([[0.00166, -0.00375, 0.00209, 0.0],
                     [-0.02903, 0.06377, -0.03202, 0.00394],
                     [0.11693, -0.21196, 0.06052, 0.25886]])
ZENITH_Y = np.array([[0.00275, -0.00610, 0.00317, 0.0],
                     [-0.04214, 0.08970, -0.04153, 0.00516],
                     [0.15346, -0.26756, 0.06670, 0.26688]])

SUN_DIAMETER_DEG = 0.53
# Luminance of the sun's disk above the atmosphere: 128 klx (the solar illuminance at the top of
# the atmosphere) over the disk's solid angle 6.72e-5 sr = 1.9e9 cd/m^2, here in kcd/m^2.
SUN_LUMINANCE_TOA = 1.9e6
# Wavelengths (micrometres) standing for the R, G, B channels in the sun's attenuation.
RGB_WAVELENGTHS_UM = np.array([0.61, 0.55, 0.465])
GROUND_ALBEDO = np.array([0.11, 0.095, 0.075])  # a dim grey-brown


def perez(theta, gamma, coeffs) -> np.ndarray:
    """Perez et al. 1993 all-weather model as used by Preetham et al. 1999, eq. 3:
    F(theta, gamma) = (1 + A exp(B / cos theta)) (1 + C exp(D gamma) + E cos^2 gamma), with theta
    the view direction's zenith angle and gamma its angle to the sun. cos(theta) is clamped
    to 1e-3 at the horizon (B < 0, so the exponential goes smoothly to 0 there)."""
    a, b, c, d, e = coeffs
    cos_t = np.maximum(np.cos(theta), 1e-3)
    return (1.0 + a * np.exp(b / cos_t)) * (1.0 + c * np.exp(d * gamma) + e * np.cos(gamma) ** 2)


def preetham_sky(dirs, sun_dir, turbidity: float = 2.5) -> np.ndarray:
    """(N, 3) linear Rec.709 sky radiance for unit directions with d.y >= 0 (kcd/m^2: the
    luminance of the result is the model's Y). Preetham et al. 1999: Y, x, y each follow
    value = value_zenith * F(theta, gamma) / F(0, theta_s) (eq. 4); zenith luminance
    Y_z = (4.0453 T - 4.9710) tan(chi) - 0.2155 T + 2.4192 kcd/m^2 with
    chi = (4/9 - T/120)(pi - 2 theta_s) (appendix A.2); zenith chromaticity from the
    matrices above. (x, y, Y) -> XYZ -> Rec.709 by the sRGB matrix; tiny negative components
    (out of the Rec.709 gamut) are clipped to 0."""
    t = float(turbidity)
    theta_s = math.acos(min(1.0, max(-1.0, float(sun_dir[1]))))
    coeffs = PEREZ_COEFFS[..., 0] * t + PEREZ_COEFFS[..., 1]  # (3 rows Y x y, 5)
    chi = (4.0 / 9.0 - t / 120.0) * (math.pi - 2.0 * theta_s)
    yz = (4.0453 * t - 4.9710) * math.tan(chi) - 0.2155 * t + 2.4192
    tv = np.array([t * t, t, 1.0])
    sv = np.array([theta_s ** 3, theta_s ** 2, theta_s, 1.0])
    zen = np.array([yz, tv @ ZENITH_X @ sv, tv @ ZENITH_Y @ sv])
    theta = np.arccos(np.clip(dirs[:, 1], -1.0, 1.0))
    gamma = np.arccos(np.clip(dirs @ sun_dir, -1.0, 1.0))
    vals = [zen[k] * perez(theta, gamma, coeffs[k]) / perez(0.0, theta_s, coeffs[k]) for k in range(3)]
    lum, x, y = vals
    y = np.maximum(y, 1e-6)
    xyz = np.stack([x * lum / y, lum, (1.0 - x - y) * lum / y], axis=-1)
    return np.maximum(xyz @ XYZ_TO_REC709.T, 0.0)


def sun_radiance(elevation_deg: float, turbidity: float = 2.5) -> np.ndarray:
    """RGB radiance of the sun's disk at the ground (kcd/m^2 luminance units): SUN_LUMINANCE_TOA
    (white) times the transmittance of Rayleigh and aerosol scattering, the two attenuations of
    Preetham et al. 1999, appendix A.3 (ozone, mixed gases and water vapour are left out):
    tau_R = exp(-0.008735 lambda^-4.08 m), tau_a = exp(-beta lambda^-alpha m) with
    beta = 0.04608 T - 0.04586, alpha = 1.3, lambda in micrometres, and the relative optical
    mass m = 1 / (cos theta_s + 0.15 (93.885 - theta_s[deg])^-1.253) (Kasten 1966)."""
    theta_s = 90.0 - float(elevation_deg)
    m = 1.0 / (math.cos(math.radians(theta_s)) + 0.15 * (93.885 - theta_s) ** -1.253)
    lam = RGB_WAVELENGTHS_UM
    beta = 0.04608 * turbidity - 0.04586
    tau = np.exp(-0.008735 * lam ** -4.08 * m) * np.exp(-beta * lam ** -1.3 * m)
    return SUN_LUMINANCE_TOA * tau


def _disk_coverage(height: int, width: int, center: np.ndarray, radius: float, n: int = 8):
    """(rows, cols, coverage) of the texels a small disk of angular ``radius`` touches: the
    fraction of n x n sub-points of each texel (uniform in u, v) inside the disk."""
    u0, v0 = dir_to_uv(center)
    sin_t = max(math.sin(math.pi * v0), 1e-6)
    half_rows = int(math.ceil(radius / math.pi * height)) + 2
    half_cols = min(width // 2, int(math.ceil(radius / (2 * math.pi * sin_t) * width)) + 2)
    r0 = int(v0 * height)
    c0 = int(u0 * width)
    rows = np.arange(max(0, r0 - half_rows), min(height, r0 + half_rows + 1))
    cols = np.arange(c0 - half_cols, c0 + half_cols + 1)
    sub = (np.arange(n) + 0.5) / n
    vv = (rows[:, None] + sub[None, :]) / height  # (R, n)
    uu = (cols[:, None] + sub[None, :]) / width   # (C, n)
    V = vv[:, None, :, None]
    U = uu[None, :, None, :]
    d = uv_to_dir(np.broadcast_to(U, (len(rows), len(cols), n, n)), np.broadcast_to(V, (len(rows), len(cols), n, n)))
    inside = (d @ center) >= math.cos(radius)
    return rows, cols % width, inside.mean(axis=(2, 3))


def sky(width: int = 1024, height: int = 512, sun_elevation_deg: float = 35.0,
        sun_azimuth_deg: float = -135.0, turbidity: float = 2.5,
        sun_diameter_deg: float = SUN_DIAMETER_DEG) -> np.ndarray:
    """A clear sky with a sun, in kcd/m^2 (the Rec.709 luminance of a texel is its luminance in
    kcd/m^2; multiply by 1000 for cd/m^2). Scenes usually want ``intensity`` ~ 0.01-0.05 or a
    negative exposure: with the defaults the horizontal illuminance is E_sky ~ 24 plus E_sun ~ 48 klx,
    so a white Lambertian surface facing up reflects (E_sky + E_sun) / pi ~ 23 kcd/m^2.

    * Sky (d.y >= 0): Preetham et al. 1999 with ``turbidity`` (2 = very clear, 10 = hazy);
      with the defaults the zenith is about 5 kcd/m^2 and the horizon 9-20.
    * Sun: a disk of ``sun_diameter_deg`` (0.53 deg, solid angle 6.7e-5 sr) at
      ``sun_elevation_deg`` above the horizon and ``sun_azimuth_deg`` (default -135: front-left
      of the default camera, so the light travels toward +x/-z), radiance ``sun_radiance``:
      about 1.2e6 kcd/m^2 at 35 deg (illuminance at normal incidence ~ 83 klx), warmer low
      down. Texels the disk covers in part get their share (8 x 8 sub-samples), and the total
      is scaled so that sum(L dOmega) over the disk is exactly L_sun * Omega_sun at any size.
    * Ground (d.y < 0): a constant GROUND_ALBEDO / pi * E_horizontal, the radiance of a dim
      grey-brown Lambertian ground lit by this sky and sun (E computed from the map itself).
    """
    if not 0.0 < sun_elevation_deg <= 90.0:
        raise ValueError("sun_elevation_deg must be in (0, 90] (the Preetham model is for a sun above the horizon)")
    sun = direction(sun_azimuth_deg, sun_elevation_deg)
    dirs = texel_directions(height, width).reshape(-1, 3)
    up = dirs[:, 1] >= 0.0
    img = np.zeros((height * width, 3))
    img[up] = preetham_sky(dirs[up], sun, turbidity)
    img = img.reshape(height, width, 3)
    # Horizontal irradiance from the sky part of the map, then the sun.
    d_omega = row_solid_angles(height, width)[:, None, None]
    cos_up = np.maximum(dirs[:, 1], 0.0).reshape(height, width, 1)
    e_sky = (img * cos_up * d_omega).sum(axis=(0, 1))
    l_sun = sun_radiance(sun_elevation_deg, turbidity)
    r = math.radians(sun_diameter_deg) / 2.0
    omega_sun = 2.0 * math.pi * (1.0 - math.cos(r))
    e_sun = l_sun * omega_sun * sun[1]
    img[~up.reshape(height, width)] = GROUND_ALBEDO / math.pi * (e_sky + e_sun)
    # The sun disk, energy-exact.
    rows, cols, cov = _disk_coverage(height, width, sun, r)
    w = cov * row_solid_angles(height, width)[rows][:, None]
    if w.sum() > 0:
        add = (l_sun * omega_sun)[None, None, :] * (cov / w.sum())[..., None]
        np.add.at(img, (rows[:, None], cols[None, :]), add)
    return img.astype(np.float32)


# ----------------------------------------------------------------------------- studio

# (name, azimuth deg, elevation deg, width deg (azimuth), height deg (elevation), radiance RGB)
STUDIO_PANELS = (
    ("key", -135.0, 35.0, 40.0, 28.0, (20.0, 19.4, 18.6)),   # front-left, high, slightly warm
    ("fill", 125.0, 15.0, 36.0, 24.0, (7.6, 8.0, 8.4)),      # front-right, low, slightly cool
    ("rim", 25.0, 40.0, 16.0, 40.0, (12.0, 12.0, 12.0)),     # behind the objects, right, a tall strip
)
STUDIO_BACKGROUND = 0.02
STUDIO_FLOOR = 0.06  # at the nadir; the floor brightens from 0.02 at the horizon to this
STUDIO_EDGE_DEG = 1.5  # soft edges: ~4 texels of a 1024-wide map


def _smooth_box(x, half, edge):
    """1 inside |x| < half - edge/2, 0 outside half + edge/2, a smoothstep between."""
    t = np.clip((half + edge / 2.0 - np.abs(x)) / edge, 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def studio(width: int = 1024, height: int = 512, panels=STUDIO_PANELS,
           background: float = STUDIO_BACKGROUND, floor: float = STUDIO_FLOOR,
           edge_deg: float = STUDIO_EDGE_DEG) -> np.ndarray:
    """A photo studio: a dark background (radiance 0.02), three bright rectangular area lights
    (key 20, fill 8, rim 12; ``STUDIO_PANELS`` gives where) whose edges fade over ``edge_deg``
    degrees, and a floor that brightens from 0.02 at the horizon to 0.06 straight down. The
    panels are rectangles in (azimuth, elevation), i.e. bounded by meridians and parallels."""
    dirs = texel_directions(height, width)
    az = np.degrees(np.arctan2(dirs[..., 0], -dirs[..., 2]))
    el = np.degrees(np.arcsin(np.clip(dirs[..., 1], -1.0, 1.0)))
    img = np.full((height, width, 3), background, dtype=np.float64)
    down = np.clip(-dirs[..., 1], 0.0, 1.0)
    img += ((floor - background) * down * down * (3.0 - 2.0 * down))[..., None]
    for _name, p_az, p_el, p_w, p_h, rgb in panels:
        daz = (az - p_az + 180.0) % 360.0 - 180.0
        mask = _smooth_box(daz, p_w / 2.0, edge_deg) * _smooth_box(el - p_el, p_h / 2.0, edge_deg)
        img += mask[..., None] * (np.asarray(rgb, dtype=np.float64) - background)[None, None, :]
    return img.astype(np.float32)


BUILTIN_MAPS = {"sky": sky, "studio": studio}


def builtin_names() -> tuple[str, ...]:
    return tuple(BUILTIN_MAPS)


#: bump when a built-in map's formula changes (its disk-cache entries are then not read)
GENERATOR_VERSION = 1


_GENERATING: dict = {}  # (name, width, height) -> the lock held while one thread generates it
_GENERATING_LOCK = threading.Lock()


def generate(name: str, width: int = 1024, height: int = 512, cache: bool = True) -> np.ndarray:
    """The built-in map ``name`` (``builtin_names()``) at its default parameters. ``cache``:
    kept in the disk cache (``viewer.environment.cache``, kind "procedural"), since generating
    the sky takes 0.5-1.5 s of numpy on a loaded machine and reading it back a few ms, which the
    window's frame would otherwise wait for on each step with the map."""
    if name not in BUILTIN_MAPS:
        raise KeyError(f"no built-in environment {name!r}; allowed: {', '.join(BUILTIN_MAPS)}")
    if not cache:
        return BUILTIN_MAPS[name](width, height)
    from viewer.environment import cache as disk

    key = disk.content_key(None, {"name": name, "width": int(width), "height": int(height),
                                  "version": GENERATOR_VERSION}, kind="procedural")
    with _GENERATING_LOCK:
        lock = _GENERATING.setdefault((name, int(width), int(height)), threading.Lock())
    # one thread generates a map at a time (the window's background warm-up, ``warm_builtin``,
    # and its frame): the second reads what the first stored, never starts over
    with lock:
        hit = disk.load(key, kind="procedural", expect={"map": (int(height), int(width), 3)})
        if hit is not None and hit["map"].dtype == np.float32:
            return hit["map"]
        img = np.ascontiguousarray(BUILTIN_MAPS[name](width, height), dtype=np.float32)
        disk.store(key, {"map": img}, kind="procedural")
        return img


def warm_builtin(names, width: int = 1024, height: int = 512) -> threading.Thread:
    """Generate the built-in maps ``names`` (a list, or a function returning it, called on the
    thread) into the disk cache on a background thread (numpy lets the window's thread run
    between its array operations), so that the frame that first shows one reads it in
    milliseconds instead of generating it (the sky: 0.3-1.5 s)."""
    def run():
        try:
            todo = names() if callable(names) else names
        except Exception:  # noqa: BLE001 - nothing warmed; each frame generates its own map
            return
        for name in todo:
            try:
                generate(name, width, height)
            except Exception:  # noqa: BLE001 - the frame that needs it generates it and reports
                pass
    th = threading.Thread(target=run, name="brdf-viewer-builtin-maps", daemon=True)
    th.start()
    return th
