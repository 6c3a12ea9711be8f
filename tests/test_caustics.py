"""The ``photon`` integrator (path tracing plus a progressive caustic photon map;
viewer/reference_common/caustics.py, viewer/pathtracer/photons.py) against closed forms:

1. a point light above a mirror floor lighting a Lambert wall: the wall's irradiance is the
   light's plus its mirror image's, the image's times the mirror's R at each angle (R = 1 for a
   perfect mirror, the lecture's Fresnel R for a dielectric one);
2. a glass slab between a distant light and a Lambert floor: two interfaces, every internal
   reflection and Bouguer's absorption, T = (1 - R)^2 a / (1 - R^2 a^2), a = exp(-sigma d / cos t);
3. a glass sphere under a distant light: paraxial rays cross the axis n R / (2 (n - 1)) from the
   centre, and the power in the caustic is the light the sphere intercepts times its
   transmittance (every ray traced through the sphere in closed form, all internal reflections);
4. where the path tracer converges (a broad light), ``photon`` equals ``path`` within noise.

Each estimate is the mean of independent passes (a pass: its own photon map and eye samples), so
its standard error comes from the spread of the passes; a tolerance is that many standard errors
plus the kernel's bias where the irradiance is not flat (r^2 / 8 times its Laplacian, the mean
of a smooth field over a disk of radius r), named beside each check.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from viewer import ViewerError
from viewer.pathtracer.integrator import DIMS_PER_BOUNCE, Integrator
from viewer.pathtracer.photons import trace_photons
from viewer.reference_common import caustics
from viewer.reference_common.estimator import EstimatorOptions
from viewer.reference_common.setup import RenderSetup
from viewer.scene import load_scene_text

from scene_text import camera, environment, material, obj, point_light, scene, table

N_GLASS = 1.5


def fresnel(cos_i, n):
    """The lecture's unpolarized R = (|r_perp|^2 + |r_par|^2) / 2 from outside (n_i = 1, n_t = n)."""
    cos_i = np.asarray(cos_i, dtype=np.float64)
    cos_t = np.sqrt(np.maximum(1.0 - (1.0 - cos_i * cos_i) / (n * n), 0.0))
    rs = (cos_i - n * cos_t) / (cos_i + n * cos_t)
    rp = (n * cos_i - cos_t) / (n * cos_i + cos_t)
    return 0.5 * (rs * rs + rp * rp), cos_t


def directional(direction, e):
    return table("[lights]", type="directional", direction=list(direction), irradiance=[e, e, e])


def integrator(text, max_depth=8, photons=None, name="photon"):
    setup = RenderSetup.from_scene(load_scene_text(text), width=64, height=48, max_depth=max_depth,
                                   integrator=name)
    if photons:
        setup.extra["photons_per_pass"] = photons
    return Integrator(setup)


def passes(it, o, d, n_pass, seed=1, spp=1):
    """(n_pass, M, 3): radiance along rays (o, d) (M of them), one mean of ``spp`` samples per
    pass; pass i gathers from its own photon map with radius r_{i+1}."""
    rng = np.random.default_rng(seed)
    big_o, big_d = np.tile(o, (spp, 1)), np.tile(d, (spp, 1))
    out = []
    for i in range(n_pass):
        it.pass_of_path = np.full(big_o.shape[0], i)
        it.block_seed = seed
        L = it.trace(big_o, big_d, lambda: rng.random((big_o.shape[0], DIMS_PER_BOUNCE)))
        out.append(L.reshape(spp, o.shape[0], 3).mean(axis=0))
    return np.array(out)


def mean_and_error(per_pass):
    """Mean over passes and its standard error (passes are independent)."""
    v = np.asarray(per_pass, dtype=np.float64)
    return v.mean(axis=0), v.std(axis=0, ddof=1) / math.sqrt(v.shape[0])


def kernel_bias(field, pts, r2, h=1e-3):
    """r^2 / 8 * Laplacian of ``field`` in the plane of ``pts`` (central differences along the
    two in-plane axes given as pts' columns 1 and 2): the box kernel's leading bias."""
    lap = 0.0
    for ax in (1, 2):
        e = np.zeros(3)
        e[ax] = h
        lap = lap + (field(pts + e) - 2 * field(pts) + field(pts - e)) / (h * h)
    return r2 / 8.0 * lap


# ----------------------------------------------------------------------------- the shared module

def test_radius_schedule_is_knaus_zwicker():
    r2 = [1.0]
    for i in range(1, 200):
        r2.append(r2[-1] * (i + caustics.ALPHA) / (i + 1))
    assert np.allclose(caustics.radius_sq(1.0, np.arange(1, 201)), r2, rtol=1e-12)
    assert caustics.pass_radius(0.3, 1) == pytest.approx(0.3)
    # r_i^2 ~ i^(alpha - 1): the radius shrinks, slowly enough that photons per disk grow as i^alpha
    assert caustics.radius_sq(1.0, 10_000) * 10_000 ** (1 - caustics.ALPHA) == pytest.approx(
        1.0 / math.gamma(1 + caustics.ALPHA), rel=1e-3)
    with pytest.raises(ValueError):
        caustics.radius_sq(1.0, 0)


def test_initial_radius_and_photon_count():
    assert caustics.initial_radius(2.0, 10_000) == pytest.approx(2.0 * math.sqrt(caustics.NEIGHBOURS / 10_000))
    assert caustics.photons_per_pass(320, 240) == 320 * 240
    assert caustics.photons_per_pass(8, 8) == caustics.MIN_PHOTONS
    assert caustics.photons_per_pass(4000, 4000) == caustics.MAX_PHOTONS


def test_grid_finds_exactly_the_photons_within_the_radius():
    rng = np.random.default_rng(3)
    pos = rng.random((3000, 3)) * [4.0, 0.5, 4.0] - 2.0         # negative cells too
    q = rng.random((400, 3)) * [4.0, 0.5, 4.0] - 2.0
    for radius in (0.03, 0.2, 1.5):                              # 1.5: few cells, many shared buckets
        g = caustics.build_grid(pos, pos, np.ones((3000, 3)), pos, radius)
        assert g.table_size & (g.table_size - 1) == 0 and g.table_size >= 6000
        assert int(g.count.sum()) == 3000
        qi, rows = g.query(q)
        got = sorted(zip(qi.tolist(), g.order[rows].tolist()))
        d2 = ((q[:, None, :] - pos[None, :, :]) ** 2).sum(-1)
        want = sorted(zip(*np.nonzero(d2 < radius * radius)))
        assert got == [(int(a), int(b)) for a, b in want]
    empty = caustics.build_grid(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3)), 0.1)
    assert len(empty) == 0 and empty.query(q)[0].size == 0


POINT_SCENE = scene(camera([0, 1, 4], [0, 0, 0], 40.0), environment(constant=[0.0, 0.0, 0.0]),
                    point_light([0, 2, 0], [3.0, 2.0, 1.0]), directional([0.3, -1.0, 0.2], 1.5),
                    obj("plane", "floor", scale=2.0), material("floor", model="lambert"))


def test_emission_carries_each_lights_power():
    setup = RenderSetup.from_scene(load_scene_text(POINT_SCENE))
    o, d, f = caustics.emit_photons(setup, 20_000, 5)
    _c, R = caustics.scene_bounds(setup)
    assert np.allclose(np.linalg.norm(d, axis=1), 1.0)
    at_point = np.all(np.isclose(o, [0, 2, 0]), axis=1)
    # every photon of a light shares its power: the sums are exact
    assert np.allclose(f[at_point].sum(0), 4 * math.pi * np.array([3.0, 2.0, 1.0]))
    assert np.allclose(f[~at_point].sum(0), 1.5 * math.pi * R * R)
    a = np.array([0.3, -1.0, 0.2]) / np.linalg.norm([0.3, -1.0, 0.2])
    assert np.allclose(d[~at_point], a)
    # the directional light's origins cover the disk of radius R perpendicular to it
    rel = o[~at_point] - (_c - R * a)
    assert np.allclose(rel @ a, 0.0, atol=1e-9) and np.linalg.norm(rel, axis=1).max() <= R + 1e-9
    # power shares: photons in proportion to luminous power
    lum = lambda rgb: float(np.asarray(rgb) @ [0.2126, 0.7152, 0.0722])
    share = lum(4 * math.pi * np.array([3.0, 2.0, 1.0])) / (lum(4 * math.pi * np.array([3.0, 2.0, 1.0]))
                                                            + lum([1.5 * math.pi * R * R] * 3))
    assert at_point.mean() == pytest.approx(share, abs=1e-3)


def test_environment_photons_carry_its_power():
    sky = scene(camera([0, 1, 4], [0, 0, 0], 40.0), environment(map="sky", intensity=0.006),
                obj("plane", "floor", scale=2.0), material("floor", model="lambert"))
    setup = RenderSetup.from_scene(load_scene_text(sky))
    _c, R = caustics.scene_bounds(setup)
    want = math.pi * R * R * caustics.environment_power(setup.env)
    # the photons' directions have the map's own density and radiance (rotated as the map is)
    setup.env = type(setup.env)(image=setup.env.image, rotation_deg=30.0)
    w, L, pdf = caustics.sample_environment(setup.env, np.random.default_rng(2).random((4000, 2)))
    n4 = np.broadcast_to([0.0, 0.0, 1.0], (4000, 3))
    assert np.allclose(L, setup.env.eval(w)) and np.allclose(pdf, setup.env.pdf(w, n4, np.ones(4000, bool)))
    f = np.concatenate([caustics.emit_photons(setup, 20_000, s)[2] for s in range(4)])
    # the photons are independent: the sum of each pass estimates the power, their mean has the
    # standard error of the photons' spread (unbiased: importance sampled, the map piecewise constant)
    m, se = 20_000 * f.mean(0), 20_000 * f.std(0, ddof=1) / math.sqrt(f.shape[0])
    assert np.all(np.abs(m - want) < 4 * se), (m / want - 1, se / want)
    const = scene(camera([0, 1, 4], [0, 0, 0], 40.0), environment(constant=[0.5, 0.4, 0.3]),
                  obj("plane", "floor", scale=2.0), material("floor", model="lambert"))
    setup = RenderSetup.from_scene(load_scene_text(const))
    _c, R = caustics.scene_bounds(setup)
    f = caustics.emit_photons(setup, 5000, 1)[2]    # uniform sphere: every photon the same, exact
    assert np.allclose(f.sum(0), math.pi * R * R * 4 * math.pi * np.array([0.5, 0.4, 0.3]))


@pytest.mark.parametrize("lights, mat, want", [
    (point_light([0, 2, 0], [5, 5, 5]), dict(model="lambert"), "path"),
    (point_light([0, 2, 0], [5, 5, 5]), dict(model="mirror"), "photon"),
    (directional([0, -1, 0], 2.0), dict(model="dielectric"), "photon"),
    ("", dict(model="dielectric"), "path"),                       # a constant environment alone
    (point_light([0, 2, 0], [5, 5, 5]), dict(model="dielectric", alpha=0.3), "path"),   # rough glass
])
def test_choose_integrator(lights, mat, want):
    text = scene(camera([0, 1, 4], [0, 0, 0], 40.0), environment(constant=[0.2, 0.2, 0.2]), lights,
                 obj("sphere", "ball"), obj("plane", "floor", scale=2.0, translate=[0, -1, 0]),
                 material("ball", **mat), material("floor", model="lambert"))
    sc = load_scene_text(text)
    name, why = caustics.choose_integrator(sc)
    assert name == want and why
    assert caustics.choose_integrator(RenderSetup.from_scene(sc))[0] == want
    assert RenderSetup.from_scene(sc, integrator="auto").integrator == want


def test_a_sun_in_the_sky_is_peaked_and_a_constant_is_not():
    text = scene(camera([0, 1, 4], [0, 0, 0], 40.0), environment(map="sky", intensity=0.006),
                 obj("sphere", "ball"), material("ball", model="dielectric"))
    assert caustics.choose_integrator(load_scene_text(text))[0] == "photon"


def test_unknown_integrator_is_one_line():
    with pytest.raises(ViewerError, match="integrator: 'bdpt' is not an integrator; allowed: path, photon"):
        EstimatorOptions(integrator="bdpt")
    assert EstimatorOptions(integrator="auto").updated(integrator="photon").integrator == "photon"


# ----------------------------------------------------------------------------- oracle 1: mirror floor

LIGHT_H, WALL_X, INTENSITY, WALL_RHO = 1.0, 2.0, 10.0, 0.8


def mirror_wall(mirror: dict) -> str:
    return scene(camera([0.5, 1.2, 0], [2, 1.2, 0], 40.0), environment(constant=[0.0, 0.0, 0.0]),
                 point_light([0, LIGHT_H, 0], [INTENSITY] * 3),
                 obj("plane", "mirror", scale=3.0),
                 obj("cube", "wall", translate=[WALL_X + 0.05, 1.5, 0.0], scale=[0.05, 1.5, 1.5]),
                 material("mirror", **mirror), material("wall", model="lambert", albedo=[WALL_RHO] * 3))


def wall_points():
    ys, zs = np.meshgrid(np.linspace(0.3, 2.5, 10), np.linspace(-1.0, 1.0, 7))
    return np.stack([np.full(ys.size, WALL_X), ys.ravel(), zs.ravel()], axis=1)


def wall_radiance(q, ior=None):
    """Lambert radiance of the wall at q: rho / pi (E_direct + R E_image), the image light at -h.
    R at the mirror's incidence angle (1 without Fresnel)."""
    def irradiance(src):
        v = src - q
        r2 = (v * v).sum(1)
        return INTENSITY * (q[:, 0] - src[0]) / np.sqrt(r2) / r2   # wall normal -x
    image = np.array([0.0, -LIGHT_H, 0.0])
    refl = 1.0
    if ior is not None:
        v = q - image
        refl = fresnel(np.abs(v[:, 1]) / np.linalg.norm(v, axis=1), ior)[0]
    return WALL_RHO / math.pi * (irradiance(np.array([0.0, LIGHT_H, 0.0])) + refl * irradiance(image))


def eye_rays_to(q, eye):
    d = q - eye
    return np.broadcast_to(eye, q.shape).copy(), d / np.linalg.norm(d, axis=1, keepdims=True)


@pytest.mark.parametrize("mirror, ior", [(dict(model="mirror", fresnel="none"), None),
                                         (dict(model="mirror", fresnel="dielectric", ior=1.5), 1.5)])
def test_mirror_floor_lights_the_wall_with_the_image_light(mirror, ior):
    q = wall_points()
    o, d = eye_rays_to(q, np.array([0.5, 1.2, 0.0]))
    want = wall_radiance(q, ior)
    it = integrator(mirror_wall(mirror), photons=1 << 15)
    per_pass = passes(it, o, d, 12, spp=2)[:, :, 0]
    got, se = mean_and_error(per_pass.mean(1))
    r2 = float(np.mean(caustics.radius_sq(it.caustics.r1, np.arange(1, 13))))
    bias = abs(float(np.mean(kernel_bias(lambda p: wall_radiance(p, ior), q, r2))))
    err = got / want.mean() - 1
    # 4 standard errors of the pass means plus the kernel's blur of the curved irradiance
    assert abs(got - want.mean()) < 4 * se + bias, (err, se / want.mean(), bias / want.mean())
    # the path tracer alone misses the mirrored light exactly: NEE finds the direct light only
    path = passes(integrator(mirror_wall(mirror), name="path"), o, d, 1)[0, :, 0]
    direct = WALL_RHO / math.pi * INTENSITY * q[:, 0] / np.linalg.norm(q - [0, LIGHT_H, 0], axis=1) ** 3
    assert np.allclose(path, direct, rtol=1e-5)   # hit points in float32 (the ray kernel)
    if ior is None:
        assert path.mean() < 0.8 * want.mean()     # the perfect mirror's image light: 27% of the wall's


# ----------------------------------------------------------------------------- oracle 2: glass slab

SLAB_D, SLAB_SIGMA, SLAB_E = 0.2, (0.5, 1.0, 2.0), 3.0


def slab_scene(theta_deg):
    th = math.radians(theta_deg)
    return scene(camera([0, 3, 3], [0, 0, 0], 40.0), environment(constant=[0.0, 0.0, 0.0]),
                 directional([math.sin(th), -math.cos(th), 0.0], SLAB_E),
                 obj("plane", "floor", scale=2.5),
                 obj("cube", "glass", translate=[0, 1.0, 0], scale=[2.5, SLAB_D / 2, 2.5]),
                 material("floor", model="lambert", albedo=[0.5, 0.5, 0.5]),
                 material("glass", model="dielectric", ior=N_GLASS, sigma_a=list(SLAB_SIGMA)))


def slab_transmittance(theta_deg):
    """(1 - R)^2 a / (1 - R^2 a^2), a = exp(-sigma d / cos theta_t): the geometric series of the
    internal reflections (R the same at both faces: the inner angle is the refracted one)."""
    R, cos_t = fresnel(math.cos(math.radians(theta_deg)), N_GLASS)
    a = np.exp(-np.asarray(SLAB_SIGMA) * SLAB_D / cos_t)
    return (1 - R) ** 2 * a / (1 - R * R * a * a)


def slab_floor(theta_deg, n_pass, photons, seed=1):
    xs, zs = np.meshgrid(np.linspace(-0.6, 0.6, 7), np.linspace(-0.6, 0.6, 7))
    o = np.stack([xs.ravel(), np.full(xs.size, 0.05), zs.ravel()], axis=1)
    d = np.broadcast_to([0.0, -1.0, 0.0], o.shape).copy()
    # max_depth 1: the floor's own light only (no floor -> slab -> floor interreflection)
    it = integrator(slab_scene(theta_deg), max_depth=1, photons=photons)
    per_pass = passes(it, o, d, n_pass, seed=seed).mean(axis=1)           # (P, 3)
    want = 0.5 / math.pi * SLAB_E * math.cos(math.radians(theta_deg)) * slab_transmittance(theta_deg)
    return per_pass, want


@pytest.mark.parametrize("theta", [0.0, 40.0])
def test_glass_slab_transmits_with_internal_reflections_and_absorption(theta):
    per_pass, want = slab_floor(theta, 10, 1 << 15)
    got, se = mean_and_error(per_pass)
    # a flat field: the kernel has no bias, only noise (4 standard errors)
    assert np.all(np.abs(got - want) < 4 * se), (got / want - 1, se / want)
    # without the photon map the slab's shadow is black: the light only reaches it through glass
    o = np.array([[0.0, 0.05, 0.0]])
    assert passes(integrator(slab_scene(theta), max_depth=1, name="path"), o, np.array([[0.0, -1.0, 0.0]]),
                  1).max() == 0.0


# ----------------------------------------------------------------------------- oracle 3: glass sphere

SPHERE_R, SPHERE_Y, SPHERE_E = 0.5, 0.75, 2.0   # the floor (y = 0) at the paraxial focus: 1.5 R below


def sphere_scene():
    return scene(camera([0, 3, 3], [0, 0, 0], 40.0), environment(constant=[0.0, 0.0, 0.0]),
                 directional([0.0, -1.0, 0.0], SPHERE_E),
                 obj("plane", "floor", scale=2.0), obj("sphere", "glass", translate=[0, SPHERE_Y, 0], scale=SPHERE_R),
                 material("floor", model="lambert", albedo=[0.5, 0.5, 0.5]),
                 material("glass", model="dielectric", ior=N_GLASS))


def test_glass_sphere_focuses_paraxial_rays_at_n_r_over_2_n_minus_1():
    it = integrator(sphere_scene(), max_depth=1)
    rng = np.random.default_rng(0)
    m = 2000
    b = 0.02 * SPHERE_R * np.sqrt(rng.random(m))
    phi = 2 * math.pi * rng.random(m)
    o = np.stack([b * np.cos(phi), np.full(m, 2.0), b * np.sin(phi)], axis=1)
    p, wi, _f, _n = trace_photons(it, o, np.broadcast_to([0.0, -1.0, 0.0], o.shape).copy(), np.ones((m, 3)), rng)
    on_floor = p[:, 1] < 1e-3
    p, wi = p[on_floor], wi[on_floor]
    assert on_floor.sum() > 0.85 * m     # 2 x 4% reflected at normal incidence, the rest reaches the floor
    t = -(p[:, 0] * wi[:, 0] + p[:, 2] * wi[:, 2]) / (wi[:, 0] ** 2 + wi[:, 2] ** 2)
    focus = SPHERE_Y - np.median(p[:, 1] + t * wi[:, 1])
    want = N_GLASS * SPHERE_R / (2 * (N_GLASS - 1))
    # b <= 0.02 R: spherical aberration (b / R)^2 R ~ 2e-4 R; the mesh's facets about as much
    assert focus == pytest.approx(want, rel=2e-3)


def disk_share(d, r, rho):
    """The share of a disk of radius r centred d from the origin inside the disk of radius rho
    (the two circles' lens area over pi r^2)."""
    d = np.maximum(np.asarray(d, dtype=np.float64), 1e-12)
    a = np.clip((d * d + r * r - rho * rho) / (2 * d * r), -1.0, 1.0)
    b = np.clip((d * d + rho * rho - r * r) / (2 * d * rho), -1.0, 1.0)
    k = np.maximum((-d + r + rho) * (d + r - rho) * (d - r + rho) * (d + r + rho), 0.0)
    lens = r * r * np.arccos(a) + rho * rho * np.arccos(b) - 0.5 * np.sqrt(k)
    return np.where(d <= rho - r, 1.0, np.where(d >= rho + r, 0.0, lens / (math.pi * r * r)))


def sphere_caustic_power(rho, kmax=8, nb=20000, radii=None):
    """Power reaching the floor (y = 0) within radius ``rho`` through the sphere: E times the sum
    over k internal reflections of int 2 pi b (1 - R)^2 R^k db over the impact parameters b whose
    exit ray goes down and lands within rho. Rays traced exactly in the meridional plane.
    ``radii``: the passes' gather radii; then the power the estimator gathers over the disk in
    expectation, each ray's landing point counted with the share of its gather disk inside rho
    (the uniform kernel's blur across the disk's rim, averaged over the passes)."""
    R0, n = SPHERE_R, N_GLASS
    b = (np.arange(nb) + 0.5) / nb * R0
    Rf = fresnel(np.sqrt(1 - (b / R0) ** 2), n)[0]
    c0 = np.array([0.0, SPHERE_Y])
    p = np.stack([b, SPHERE_Y + np.sqrt(R0 * R0 - b * b)], axis=1)
    nrm = (p - c0) / R0
    v = np.tile([0.0, -1.0], (nb, 1))
    c = -(v * nrm).sum(1)
    v = v / n + (c / n - np.sqrt(1 - (1 - c * c) / n ** 2))[:, None] * nrm      # refract in
    total = 0.0
    for k in range(kmax + 1):
        p = p + (-2 * ((p - c0) * v).sum(1))[:, None] * v                       # the next chord's end
        nrm = (p - c0) / R0
        c = (v * nrm).sum(1)
        out = n * v + (np.sqrt(1 - n * n * (1 - c * c)) - n * c)[:, None] * nrm  # refract out
        down = out[:, 1] < 0
        x = p[:, 0] - out[:, 0] * p[:, 1] / np.where(down, out[:, 1], -1.0)
        if radii is None:
            inside = np.abs(x) < rho
        else:
            inside = np.mean([disk_share(np.abs(x), r, rho) for r in radii], axis=0)
        total += float((2 * math.pi * b * (1 - Rf) ** 2 * Rf ** k * down * inside).sum() * R0 / nb)
        v = v - 2 * c[:, None] * nrm                                              # reflect inside
    return SPHERE_E * total


def sphere_floor_power(rho, n_pass, photons, h=0.015, seed=1):
    """(per-pass gathered power over the disk of radius rho, the passes' gather radii). Each pass
    integrates the floor's irradiance over the disk on a grid of spacing h shifted by a uniform
    random offset (unbiased: a fixed grid under a caustic's focus would weigh the focus by the
    number of grid points in a gather disk, which moves with r)."""
    it = integrator(sphere_scene(), max_depth=1, photons=photons)
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n_pass):
        xs = np.arange(-rho - h, rho + h, h) + rng.random() * h
        zs = np.arange(-rho - h, rho + h, h) + rng.random() * h
        X, Z = np.meshgrid(xs, zs)
        inside = X ** 2 + Z ** 2 < rho * rho
        o = np.stack([X[inside], np.full(inside.sum(), 0.01), Z[inside]], axis=1)
        d = np.broadcast_to([0.0, -1.0, 0.0], o.shape).copy()
        it.pass_of_path, it.block_seed = np.full(o.shape[0], i), seed
        L = it.trace(o, d, lambda: rng.random((o.shape[0], DIMS_PER_BOUNCE)))[:, 0]
        out.append((L * math.pi / 0.5).sum() * h * h)      # irradiance = pi L / rho_floor, times h^2
    radii = [caustics.pass_radius(it.caustics.r1, i) for i in range(1, n_pass + 1)]
    return np.array(out), radii


def test_glass_sphere_caustic_holds_the_intercepted_light_times_transmittance():
    rho = 0.45   # inside the sphere's shadow (radius R): no direct light, all of it caustic
    want = sphere_caustic_power(rho)
    assert want == pytest.approx(sphere_caustic_power(rho, nb=40000), rel=1e-4)   # quadrature converged
    assert 0.75 < want / (SPHERE_E * math.pi * SPHERE_R ** 2) < 0.85   # the rim's rays miss the disk
    per_pass, radii = sphere_floor_power(rho, 8, 1 << 15)
    got, se = mean_and_error(per_pass)
    # the marginal rays land in a bright ring near the shadow's edge, just outside rho: the kernel
    # blurs part of it in (a bias of a few percent at these radii, vanishing as r -> 0), which the
    # closed form takes into account exactly (``radii``); then 4 standard errors, and 0.5% for the
    # mesh's facets (20 k triangles) against the true sphere
    blurred = sphere_caustic_power(rho, radii=radii)
    assert abs(got - blurred) < 4 * se + 0.005 * blurred, (got / blurred - 1, se / blurred, blurred / want - 1)


# ----------------------------------------------------------------------------- 4: agreement with path

def broad_light_scene():
    """A Lambert ball over a mirror floor under a constant sky: the ball's underside is lit
    through the mirror by a light so large that path tracing finds it easily."""
    return scene(camera([0, 0.9, 3.0], [0, 0.4, 0], 40.0), environment(constant=[1.0, 0.9, 0.8]),
                 obj("plane", "mirror", scale=2.0), obj("sphere", "ball", translate=[0, 0.6, 0], scale=0.5),
                 material("mirror", model="mirror", fresnel="none"),
                 material("ball", model="lambert", albedo=[0.7, 0.5, 0.3]))


def block_means(name, seeds, w=24, h=18, spp=2):
    setup = RenderSetup.from_scene(load_scene_text(broad_light_scene()), width=w, height=h, max_depth=4,
                                   integrator=name)
    setup.extra["photons_per_pass"] = 1 << 14
    it = Integrator(setup)
    out = []
    for s in seeds:
        total, _sq = it.render_block(0, h, range(spp), s, 0)
        img = total[:, :, 1] / spp
        out.append(img.reshape(3, h // 3, 4, w // 4).mean(axis=(1, 3)).ravel())
    return np.array(out)


def test_photon_equals_path_where_path_converges():
    seeds = range(6)
    a, b = block_means("path", seeds), block_means("photon", seeds)
    ma, sa = mean_and_error(a)
    mb, sb = mean_and_error(b)
    z = (mb - ma) / np.sqrt(sa ** 2 + sb ** 2 + 1e-12)
    # 12 blocks, each within 4.5 standard errors (a 1-in-10^5 event each when they agree); the
    # photon kernel's blur of the smooth underside lighting is far below the noise
    assert np.all(np.abs(z) < 4.5), (z, mb / np.maximum(ma, 1e-9) - 1)


# ----------------------------------------------------------------------------- longer convergence

@pytest.mark.slow   # 100 passes of 2^16 photons: about a minute; the quick versions above take 10 passes
@pytest.mark.parametrize("theta", [0.0, 40.0])
def test_glass_slab_converges(theta):
    per_pass, want = slab_floor(theta, 100, 1 << 16, seed=5)
    got, se = mean_and_error(per_pass)
    assert np.all(np.abs(got - want) < 4 * se) and np.all(np.abs(got / want - 1) < 0.01), (got / want - 1, se / want)


@pytest.mark.slow   # 60 passes over 2800 floor points: about a minute
def test_glass_sphere_caustic_power_converges():
    per_pass, radii = sphere_floor_power(0.45, 60, 1 << 16, seed=3)
    got, se = mean_and_error(per_pass)
    blurred = sphere_caustic_power(0.45, radii=radii)
    assert abs(got - blurred) < 4 * se + 0.005 * blurred, (got / blurred - 1, se / blurred)


# ----------------------------------------------------------------------------- the command line

def test_reference_command_says_which_integrator_and_why(tmp_path, capsys):
    from viewer.commands.cli import main

    scene_file = tmp_path / "mirror.toml"
    scene_file.write_text(mirror_wall(dict(model="mirror", fresnel="none")).replace(
        "fov_y = 40.0", "fov_y = 40.0\nwidth = 16\nheight = 12"))
    out = tmp_path / "r.png"
    assert main(["reference", str(scene_file), "--spp", "1", "--workers", "0", "--engine", "cpu",
                 "--out", str(out)]) == 0
    said = capsys.readouterr().out
    assert "integrator: photon (smooth (delta) surfaces ('mirror') lit by a point light: caustics)" in said
    assert main(["reference", str(scene_file), "--spp", "1", "--workers", "0", "--engine", "cpu",
                 "--integrator", "path", "--out", str(out)]) == 0
    assert "integrator: path (asked for)" in capsys.readouterr().out
    with pytest.raises(SystemExit) as e:
        main(["reference", str(scene_file), "--integrator", "bdpt", "--out", str(out)])
    assert e.value.code == 2 and "argument --integrator: invalid choice: 'bdpt'" in capsys.readouterr().err
