"""The caustic photon map both reference engines share (no GL, no ray kernel here): the
integrators' names, the progressive radius schedule, photon emission from the setup's lights
and environment, the choice of integrator, and a uniform hash grid of photons that the CPU
engine queries in numpy and the GPU engine uploads as textures.

Estimator (``photon``: path tracing plus a progressive caustic photon map)
------------------------------------------------------------------------
Path space is partitioned, so nothing is counted twice. A *caustic path* reaches its light end
from its last non-delta vertex x_j through one or more delta vertices (a mirror, smooth glass, a
delta lobe of a layered material); the photon map alone estimates those, the path tracer alone
every other path. Under ``photon`` the path tracer therefore drops light that arrives through a
delta chain after a non-delta vertex (the environment, including a sky's sun, reached by a ray
from a delta lobe when the path has scattered off a smooth lobe before), and at every non-delta
vertex of the eye path adds the photon estimate

    throughput * sum_p f(x, wo, wi_p) Phi_p / (pi r^2)     over photons |x - x_p| < r,

with the uniform (box) kernel 1 / (pi r^2) over the disk of radius r (Knaus & Zwicker's
kernel) and a normal test |n_p . n_g(x)| >= ``NORMAL_COS``; f is the material's BRDF (its numpy
twin), the cosine at x is inside Phi_p. A path with no non-delta vertex (camera -> mirror ->
environment) stays with the path tracer.

Photons: each pass emits N photons from all lights in proportion to their power
(``emit_photons``), traces them only while they hit delta surfaces (Russian roulette allowed)
and stores a photon at its first non-delta hit when it passed at least one delta vertex; one
whose first hit is non-delta is dropped (that light is direct light, the path tracer's).

Progressive and consistent (Knaus & Zwicker 2011, "Progressive photon mapping: a probabilistic
approach", ACM TOG 30(3)): pass i (1-based) gathers with radius r_i, r_{i+1}^2 = r_i^2 (i + alpha)
/ (i + 1), alpha = 2/3, so r_i^2 = r_1^2 Gamma(i + alpha) / (Gamma(1 + alpha) Gamma(i + 1)) ~ i^(alpha-1);
the image is the mean of the passes. Each pass is an independent estimate whose bias (the blur of
the caustic over the disk, O(r_i^2) where the caustic is smooth) and variance (O(1 / (N r_i^2)))
both vanish as i grows, so the mean converges to the caustic (bias -> 0 as r -> 0; at low pass
counts caustics look blurred over about r_1).

r_1 (``initial_radius``): the radius of a disk that would hold ``NEIGHBOURS`` photons if the N
photons of a pass were spread evenly over the disk of the scene's bounding radius R:
r_1 = R sqrt(NEIGHBOURS / N). Caustic photons concentrate, so focused caustics hold far more.
"""

from __future__ import annotations

import math

import numpy as np

from viewer.reference_common.estimator import INTEGRATORS  # ("path", "photon"): the estimator's options check them

INTEGRATOR_LABELS = {"path": "path tracing", "photon": "path tracing + caustic photon map"}
ALPHA = 2.0 / 3.0            # Knaus & Zwicker's alpha: the share of photons a pass's radius keeps
NEIGHBOURS = 25              # photons a pass's first gather disk holds if spread evenly (r_1)
NORMAL_COS = 0.9             # a photon counts where |n_p . n_g(x)| >= this (same surface, not a wall behind)
MAX_PHOTON_BOUNCES = 16      # delta vertices a photon may pass before it is dropped
PHOTON_RR_START = 4          # Russian roulette on photons from their 4th delta vertex on
MIN_PHOTONS, MAX_PHOTONS = 1 << 14, 1 << 18
#: the random stream of pass i's photons: philox(seed, PHOTON_STREAM, i) (a block id no image uses)
PHOTON_STREAM = 0x7F0000000000

# hash of a cell (Teschner et al. 2003, "Optimized spatial hashing for collision detection"), on
# unsigned 32-bit integers (the GPU engine computes the same in GLSL's uint arithmetic)
HASH_PRIMES = (73856093, 19349663, 83492791)


def check_integrator(name: str) -> str:
    """``name`` when it is an integrator, else a one-line ViewerError."""
    if name not in INTEGRATORS:
        from viewer import ViewerError

        raise ViewerError(f"integrator: {name!r} is not an integrator; allowed: {', '.join(INTEGRATORS)}")
    return name


# ----------------------------------------------------------------------------- radius schedule

def radius_sq(r1: float, i) -> np.ndarray:
    """r_i^2 of pass ``i`` (1-based; a number or an array): r_1^2 prod_{k<i} (k + alpha) / (k + 1)
    = r_1^2 Gamma(i + alpha) / (Gamma(1 + alpha) Gamma(i + 1)) (Knaus & Zwicker 2011, eq. 15)."""
    i = np.asarray(i, dtype=np.float64)
    if np.any(i < 1):
        raise ValueError("pass indices start at 1")
    lg = np.vectorize(math.lgamma)
    return float(r1) ** 2 * np.exp(lg(i + ALPHA) - math.lgamma(1.0 + ALPHA) - lg(i + 1.0))


def pass_radius(r1: float, i: int) -> float:
    """r_i of pass ``i`` (1-based)."""
    return float(np.sqrt(radius_sq(r1, int(i))))


def photons_per_pass(width: int, height: int) -> int:
    """Photons per pass: one per pixel (a pass is one sample per pixel), clamped to
    [MIN_PHOTONS, MAX_PHOTONS], so the photon tracing costs about what the pass's eye paths do."""
    return int(np.clip(int(width) * int(height), MIN_PHOTONS, MAX_PHOTONS))


def scene_bounds(setup) -> tuple[np.ndarray, float]:
    """(centre, radius) of the sphere around the scene's triangles' bounding box."""
    tri = setup.geometry.triangles
    if tri.size == 0:
        return np.zeros(3), 1.0
    pts = tri.reshape(-1, 3)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    return 0.5 * (lo + hi), max(0.5 * float(np.linalg.norm(hi - lo)), 1e-6)


def initial_radius(scene_radius: float, n_photons: int) -> float:
    """r_1 = R sqrt(NEIGHBOURS / N) (see the module docstring)."""
    return float(scene_radius) * math.sqrt(NEIGHBOURS / max(int(n_photons), 1))


# ----------------------------------------------------------------------------- emission

def _luminance(rgb) -> float:
    from viewer.brdf.sampling import LUMINANCE_REC709

    return float(np.abs(np.asarray(rgb, dtype=np.float64)) @ LUMINANCE_REC709)


def texel_solid_angles(h: int, w: int) -> np.ndarray:
    """(h,) the exact solid angle of a texel of each row of an (h, w) lat-long map:
    (2 pi / w) (cos theta_top - cos theta_bottom)."""
    edges = np.cos(math.pi * np.arange(h + 1) / h)
    return (2.0 * math.pi / w) * (edges[:-1] - edges[1:])


def environment_power(env) -> np.ndarray:
    """The integral of the environment's radiance over the sphere, int L(w) dw (RGB): 4 pi L for a
    constant, each texel's radiance times its solid angle for a map (the map is piecewise
    constant, so this is exact, and it is what its importance sampling estimates)."""
    if env.is_black:
        return np.zeros(3)
    if not env.is_map:
        return 4.0 * math.pi * np.asarray(env.constant, dtype=np.float64)
    h, w, _ = env.image.shape
    return np.einsum("hwc,h->c", env.image, texel_solid_angles(h, w))


def light_powers(setup, radius: float) -> list[tuple[str, int, np.ndarray]]:
    """[(kind, index, RGB power)]: every emitter's power into the scene: a point light 4 pi I, a
    directional light E pi R^2, the environment pi R^2 int L dw (``kind`` "point",
    "directional", "environment"; ``index`` into ``setup.lights``, -1 for the environment)."""
    disk = math.pi * radius * radius
    out = []
    for k, (kind, _a, val) in enumerate(setup.lights):
        val = np.asarray(val, dtype=np.float64)
        out.append((kind, k, 4.0 * math.pi * val if kind == "point" else disk * val))
    if not setup.env.is_black:
        out.append(("environment", -1, disk * environment_power(setup.env)))
    return out


def _generator(rng_or_seed) -> np.random.Generator:
    if isinstance(rng_or_seed, np.random.Generator):
        return rng_or_seed
    return np.random.Generator(np.random.Philox(key=int(rng_or_seed) & 0xFFFFFFFFFFFFFFFF))


def sample_environment(env, u):
    """Directions toward the environment for photons: (w (N, 3), radiance (N, 3), pdf (N,) per solid
    angle) from uniforms u (N, 2). A map: a texel with its probability (the map's importance
    sampling tables, ``EnvironmentLight.distribution``), drawn from the CDF of all texels at
    once, then a uniform point inside it (u, v), the density the map's own ``sample`` has,
    p = p_texel W H / (2 pi^2 sin theta); a constant: uniform on the sphere."""
    n = u.shape[0]
    dist = env.distribution()
    if dist is None:
        return env.sample(u, np.broadcast_to([0.0, 0.0, 1.0], (n, 3)), np.ones(n, dtype=bool))
    from viewer.environment.latlong import uv_to_dir

    texel_p, _row_cdf, _col_cdf, to_map = dist
    h, w = texel_p.shape
    cdf = np.cumsum(texel_p.ravel())
    k = np.minimum(np.searchsorted(cdf, u[:, 0] * cdf[-1], side="right"), h * w - 1)
    while np.any(texel_p.ravel()[k] <= 0):          # (only where u hit a zero-width step exactly)
        bad = texel_p.ravel()[k] <= 0
        k[bad] = np.minimum(k[bad] + 1, h * w - 1)
    row, col = k // w, k % w
    # the second uniform, and the first's place within its texel's step, place the point
    lo = cdf[k] - texel_p.ravel()[k]
    fu = np.clip((u[:, 0] * cdf[-1] - lo) / texel_p.ravel()[k], 0.0, 1.0 - 1e-12)
    vv = (row + np.clip(u[:, 1], 0.0, 1.0 - 1e-12)) / h
    uu = (col + fu) / w
    d = uv_to_dir(uu, vv) @ to_map                   # map -> world (to_map is a rotation)
    sin_t = np.sin(math.pi * vv)
    pdf = np.where(sin_t > 0, texel_p[row, col] * (w * h) / (2.0 * math.pi * math.pi * np.maximum(sin_t, 1e-300)), 0.0)
    return d, env.image[row, col], pdf


def _disk_points(u, centre, axis, radius):
    """Uniform points on the disk of ``radius`` about ``centre`` perpendicular to unit ``axis``
    (N, 3) or (3,), from uniforms u (N, 2)."""
    from viewer.brdf.sampling import frame_from_z

    axis = np.broadcast_to(np.asarray(axis, dtype=np.float64), (u.shape[0], 3))
    tx, ty = frame_from_z(axis)
    r = radius * np.sqrt(u[:, 0])
    phi = 2.0 * math.pi * u[:, 1]
    return centre + (r * np.cos(phi))[:, None] * tx + (r * np.sin(phi))[:, None] * ty


def emit_photons(setup, n: int, rng_or_seed):
    """``n`` photons from the setup's lights and environment: (origins (M, 3), directions
    (M, 3) unit, powers (M, 3) RGB flux per photon), M about n. Each emitter gets photons in
    proportion to its luminous power (at least one if it has any); its photons share its power.

    * point light (position, intensity I): directions uniform on the sphere, flux 4 pi I / n_k;
    * directional light (direction d, irradiance E): direction d, origins uniform on the disk of
      the scene's bounding radius R perpendicular to d, R behind the centre; flux E pi R^2 / n_k;
    * environment (a map or a constant; a sky's sun is in its map): direction -w with w drawn
      by the environment's importance sampling (a constant: uniform on the sphere), origin on
      the same disk perpendicular to w, flux L(w) pi R^2 / (p(w) n_k).
    """
    rng = _generator(rng_or_seed)
    centre, R = scene_bounds(setup)
    powers = light_powers(setup, R)
    lum = np.array([_luminance(p) for _k, _i, p in powers])
    total = lum.sum()
    empty = np.zeros((0, 3))
    if n <= 0 or total <= 0:
        return empty, empty.copy(), empty.copy()
    counts = [max(1, int(round(n * l / total))) if l > 0 else 0 for l in lum]
    origins, dirs, flux = [], [], []
    for (kind, k, power), nk in zip(powers, counts):
        if nk == 0:
            continue
        if kind == "point":
            u = rng.random((nk, 2))
            z = 1.0 - 2.0 * u[:, 0]
            s = np.sqrt(np.maximum(0.0, 1.0 - z * z))
            phi = 2.0 * math.pi * u[:, 1]
            d = np.stack([s * np.cos(phi), s * np.sin(phi), z], axis=1)
            o = np.broadcast_to(np.asarray(setup.lights[k][1], dtype=np.float64), (nk, 3)).copy()
            f = np.broadcast_to(power / nk, (nk, 3)).copy()
        elif kind == "directional":
            a = np.asarray(setup.lights[k][1], dtype=np.float64)
            a = a / np.linalg.norm(a)
            o = _disk_points(rng.random((nk, 2)), centre - R * a, a, R)
            d = np.broadcast_to(a, (nk, 3)).copy()
            f = np.broadcast_to(power / nk, (nk, 3)).copy()
        else:
            u = rng.random((nk, 4))
            w, L, pdf = sample_environment(setup.env, u[:, :2])
            ok = pdf > 0
            w, L, pdf, u = w[ok], L[ok], pdf[ok], u[ok]
            o = _disk_points(u[:, 2:4], centre + R * w, w, R)
            d = -w
            f = L * (math.pi * R * R) / (pdf[:, None] * nk)
        origins.append(o)
        dirs.append(d)
        flux.append(f)
    return np.concatenate(origins), np.concatenate(dirs), np.concatenate(flux)


# ----------------------------------------------------------------------------- wavelengths

def spectral_photons(setup) -> bool:
    """Whether a pass's photons carry one wavelength each: where the spectral estimator runs
    (``setup.extra["spectral"]``) and a surface a photon passes (one with a delta lobe) has
    values that depend on the wavelength (a dispersive dielectric: n(lambda) bends each
    wavelength its own way, so a prism's caustic splits into colours; a spectral mirror).
    Elsewhere photons carry RGB power, as the RGB estimator's do."""
    if not setup.extra.get("spectral"):
        return False
    from viewer import brdf

    return any(m.lobes.has_delta and brdf.uses_spectral(m.params) for m in setup.materials)


def photon_bins(gen: np.random.Generator, n: int) -> np.ndarray:
    """(n,) wavelength bins (0 .. N_BINS - 1 of ``viewer.reference_common.wavelengths``),
    uniform: probability 1 / N_BINS each."""
    from viewer.reference_common.wavelengths import N_BINS

    return np.minimum((gen.random(n) * N_BINS).astype(np.int64), N_BINS - 1)


def spectral_flux(flux_rgb, bins) -> np.ndarray:
    """(n,) the spectral flux at ``bins`` of RGB fluxes (n, 3): the Mallett & Yuksel (2019)
    upsampling both engines use for RGB quantities, sum_c x_c b_c(lambda)."""
    from viewer import spectral
    from viewer.reference_common.wavelengths import bin_wavelengths

    basis = spectral.upsampling.basis_at(bin_wavelengths())
    return np.einsum("nc,nc->n", basis[np.asarray(bins)], np.asarray(flux_rgb, dtype=np.float64))


def flux_to_rgb(phi, bins) -> np.ndarray:
    """(n, 3) the RGB a photon of spectral flux ``phi`` (n,) at wavelength bins ``bins`` stores:
    N_BINS phi W(lambda) with W the bins' CIE RGB weights (sum W = 1), the one-sample estimate
    of sum_lambda W(lambda) Phi(lambda) for a bin drawn with probability 1 / N_BINS, so a
    photon's expected RGB is the RGB of its spectrum (some bins' W has a negative channel, as a
    pure wavelength lies outside the Rec. 709 gamut: single photons may store one)."""
    from viewer.reference_common.wavelengths import N_BINS, bin_weights

    return N_BINS * np.asarray(phi, dtype=np.float64)[:, None] * bin_weights()[np.asarray(bins)]


# ----------------------------------------------------------------------------- the hash grid

def hash_cells(cells: np.ndarray, table_size: int) -> np.ndarray:
    """The bucket of integer cells (N, 3): (x p1 ^ y p2 ^ z p3) mod table_size on unsigned
    32-bit integers (the cell coordinates wrap to uint32 first; table_size a power of two)."""
    c = np.asarray(cells, dtype=np.int64).astype(np.uint32)
    with np.errstate(over="ignore"):
        h = (c[..., 0] * np.uint32(HASH_PRIMES[0])) ^ (c[..., 1] * np.uint32(HASH_PRIMES[1])) \
            ^ (c[..., 2] * np.uint32(HASH_PRIMES[2]))
    return (h & np.uint32(table_size - 1)).astype(np.int64)


class PhotonGrid:
    """A uniform hash grid of photons (cell size = the gather radius): photons sorted by bucket
    (``order`` into the photons given, ``positions``, ``directions``, ``powers``, ``normals``
    in that order), and per bucket ``start`` and ``count`` (int32, ``table_size`` entries, a
    power of two >= 2 N): the photons of bucket b are sorted rows start[b] .. start[b] +
    count[b] - 1. A lookup visits the 27 cells around the query's cell (cell size >= r covers
    the ball of radius r), each bucket once (two cells may share a bucket), and keeps photons
    within r. Empty grid: no photons, every count 0."""

    def __init__(self, positions, directions, powers, normals, radius: float):
        pos = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
        n = pos.shape[0]
        self.radius = float(radius)
        self.cell = self.radius
        self.table_size = 1 << max(4, int(math.ceil(math.log2(max(2 * n, 2)))))
        bucket = hash_cells(np.floor(pos / self.cell), self.table_size) if n else np.zeros(0, np.int64)
        self.order = np.argsort(bucket, kind="stable")
        self.positions = pos[self.order]
        self.directions = np.asarray(directions, dtype=np.float64).reshape(-1, 3)[self.order]
        self.powers = np.asarray(powers, dtype=np.float64).reshape(n, -1)[self.order] if n else np.zeros((0, 3))
        self.normals = np.asarray(normals, dtype=np.float64).reshape(-1, 3)[self.order]
        counts = np.bincount(bucket, minlength=self.table_size).astype(np.int32)
        self.count = counts
        self.start = (np.cumsum(counts) - counts).astype(np.int32)

    def __len__(self) -> int:
        return int(self.positions.shape[0])

    OFFSETS = np.array([(i, j, k) for i in (-1, 0, 1) for j in (-1, 0, 1) for k in (-1, 0, 1)], dtype=np.int64)

    def query(self, points) -> tuple[np.ndarray, np.ndarray]:
        """Pairs (query index, sorted photon row) of photons within the radius of ``points``
        (M, 3), the pairs of each query together."""
        q = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        m = q.shape[0]
        if m == 0 or len(self) == 0:
            return np.zeros(0, np.int64), np.zeros(0, np.int64)
        base = np.floor(q / self.cell).astype(np.int64)
        b = hash_cells(base[:, None, :] + self.OFFSETS[None, :, :], self.table_size)   # (M, 27)
        b = np.sort(b, axis=1)
        first = np.ones_like(b, dtype=bool)
        first[:, 1:] = b[:, 1:] != b[:, :-1]                 # each bucket once per query
        cnt = np.where(first, self.count[b], 0).ravel().astype(np.int64)
        st = self.start[b].ravel().astype(np.int64)
        total = int(cnt.sum())
        if total == 0:
            return np.zeros(0, np.int64), np.zeros(0, np.int64)
        qi = np.repeat(np.repeat(np.arange(m), 27), cnt)
        run0 = np.cumsum(cnt) - cnt
        rows = np.repeat(st - run0, cnt) + np.arange(total)
        d = self.positions[rows] - q[qi]
        near = np.einsum("ij,ij->i", d, d) < self.radius * self.radius
        return qi[near], rows[near]


def build_grid(positions, directions, powers, normals, radius: float) -> PhotonGrid:
    """A ``PhotonGrid`` of the photons for gathers of ``radius``."""
    return PhotonGrid(positions, directions, powers, normals, radius)


# ----------------------------------------------------------------------------- the choice

#: an environment is "peaked" (a sun, a lamp in a map) where its brightest texels covering
#: PEAK_SOLID_ANGLE of the sphere hold at least PEAK_POWER_SHARE of its power: a source that
#: small is found by a BSDF-sampled ray through glass about PEAK_SOLID_ANGLE of the time
PEAK_SOLID_ANGLE = 0.01
PEAK_POWER_SHARE = 0.25


def environment_is_peaked(env) -> bool:
    """Whether the environment light holds a small, bright source (see PEAK_*)."""
    if env.is_black or not env.is_map:
        return False
    h, w, _ = env.image.shape
    from viewer.brdf.sampling import LUMINANCE_REC709

    d_omega = np.broadcast_to(texel_solid_angles(h, w)[:, None], (h, w)).ravel()
    power = (np.abs(env.image @ LUMINANCE_REC709)).ravel() * d_omega
    radiance = power / np.maximum(d_omega, 1e-300)
    order = np.argsort(-radiance, kind="stable")
    omega = np.cumsum(d_omega[order]) / (4.0 * math.pi)
    share = np.cumsum(power[order]) / max(power.sum(), 1e-300)
    k = int(np.searchsorted(omega, PEAK_SOLID_ANGLE, side="right"))
    return k > 0 and float(share[k - 1]) >= PEAK_POWER_SHARE


def choose_integrator(setup_or_scene) -> tuple[str, str]:
    """(name, reason): ``photon`` for a scene with smooth (delta) surfaces lit by a point or
    directional light or a peaked environment (a sky's sun), else ``path``; ``reason`` is one
    short clause for the line that says which was picked."""
    if hasattr(setup_or_scene, "geometry"):       # a RenderSetup (a scene has no triangle soup)
        lobes = [(m.name, m.lobes) for m in setup_or_scene.materials]
        kinds = [k for k, _a, _v in setup_or_scene.lights]
        env = setup_or_scene.env
    else:
        from viewer import brdf
        from viewer.reference_common.envmap import EnvironmentLight

        sc = setup_or_scene
        used = {o.material for o in sc.objects}
        lobes = [(n, brdf.get(p.model).lobes(p)) for n, p in sc.materials.items() if n in used]
        kinds = [lt.type for lt in sc.lights]
        e = sc.environment
        img = e.radiance_map(256, 128) if e.map is not None else None
        env = EnvironmentLight(image=img, intensity=1.0) if img is not None else EnvironmentLight.from_scene(sc)
    delta = [name for name, lobe in lobes if lobe.has_delta]
    if not delta:
        return "path", "no smooth (delta) surface, so no caustic"
    what = ", ".join(repr(d) for d in delta[:3]) + (" ..." if len(delta) > 3 else "")
    small = [f"a {k} light" for k in dict.fromkeys(kinds)]
    if environment_is_peaked(env):
        small.append("a small bright source in the environment (a sun)")
    if not small:
        return "path", f"smooth (delta) surfaces ({what}) but only broad light, which path tracing finds"
    return "photon", f"smooth (delta) surfaces ({what}) lit by {' and '.join(small)}: caustics"
