"""The reference path tracer (viewer/pathtracer): analytic oracles (furnace, GGX albedo, glass
slab, total internal reflection), determinism, robustness over the registry, cancellation
and the ``reference`` command. Images are small; the oracles set the sample counts."""

from __future__ import annotations

import math
import multiprocessing as mp
import subprocess
import sys
import textwrap
import threading
import time

import numpy as np
import pytest

from viewer import brdf
from viewer.pathtracer import ReferenceRenderer
from viewer.pathtracer.integrator import Integrator
from viewer.reference_common.setup import RenderSetup
from viewer.pathtracer.kernel_embree import EmbreeKernel
from viewer.scene import load_scene

from brdf_harness import param_grid
from scene_text import camera, environment, lone_sphere, material, point_light, scene, sphere_on_floor


def scene_from(tmp_path, text, name="s.toml"):
    p = tmp_path / name
    p.write_text(textwrap.dedent(text))
    return load_scene(p)


def pixel_corner_rays(w, h, fov_y=40.0, dist=4.0):
    """Camera at (0, 0, dist) looking at -z: ray directions through every pixel's 4 corners and
    its centre, shape (h, w, 5, 3)."""
    th = math.tan(math.radians(fov_y) / 2)
    offs = [(0, 0), (1, 0), (0, 1), (1, 1), (0.5, 0.5)]
    out = np.zeros((h, w, 5, 3))
    i, j = np.meshgrid(np.arange(h), np.arange(w), indexing="ij")
    for k, (dx, dy) in enumerate(offs):
        x = (2 * (j + dx) / w - 1) * th * w / h
        y = (1 - 2 * (i + dy) / h) * th
        d = np.stack([x, y, -np.ones_like(x)], axis=-1)
        out[:, :, k] = d / np.linalg.norm(d, axis=-1, keepdims=True)
    return out


def sphere_hit(d, radius, dist=4.0):
    """Unit-speed rays from (0, 0, dist): (hit?, normal at the hit) against a centred sphere."""
    o = np.array([0.0, 0.0, dist])
    b = d @ o
    c = o @ o - radius * radius
    disc = b * b - c
    hit = disc > 0
    t = -b - np.sqrt(np.maximum(disc, 0))
    p = o + t[..., None] * d
    return hit, p / radius


# ----------------------------------------------------------------------------- ray kernel

def test_embree_kernel_interface():
    tri = np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 0, 2], [1, 0, 2], [0, 1, 2]]], float)
    k = EmbreeKernel(tri)
    o = np.array([[0.2, 0.3, -1.0], [0.2, 0.3, 1.0], [5, 5, -1]])
    d = np.array([[0, 0, 1.0]] * 3)
    t, prim, u, v = k.intersect(o, d, 0.0, np.inf)
    assert list(prim) == [0, 1, -1]
    assert np.allclose(t[:2], [1.0, 1.0]) and t[2] == np.inf
    p = (1 - u - v)[:2, None] * tri[prim[:2], 0] + u[:2, None] * tri[prim[:2], 1] + v[:2, None] * tri[prim[:2], 2]
    assert np.allclose(p, o[:2] + t[:2, None] * d[:2], atol=1e-6)
    # tmin skips the first triangle, tmax stops short of it
    t2, prim2, _, _ = k.intersect(o[:1], d[:1], 1.5, np.inf)
    assert prim2[0] == 1 and abs(t2[0] - 3.0) < 1e-5
    assert list(k.occluded(o, d, 0.0, np.array([0.5, 10.0, 10.0]))) == [False, True, False]
    assert not EmbreeKernel(np.zeros((0, 3, 3))).occluded(o, d, 0.0, np.inf).any()


# ----------------------------------------------------------------------------- oracles

@pytest.mark.parametrize("max_depth,env", [(1, "constant"), (8, "constant"), (8, "map")])
def test_furnace_lambert_sphere(tmp_path, max_depth, env):
    sc = scene_from(tmp_path, lone_sphere(dict(model="lambert", albedo=[0.5, 0.5, 0.5]), 32, 32))
    # "map": the same white environment as a lat-long array, so the map's importance sampling
    # (luminance x sin theta, pdf per solid angle with the Jacobian) and its MIS weights are used
    image = np.ones((8, 16, 3)) if env == "map" else None
    r = ReferenceRenderer(sc, width=32, height=32, max_depth=max_depth, seed=1, workers=0, env_image=image)
    r.step(8 if env == "constant" else 32)
    m, var = r.mean(), r.variance()
    r.close()
    assert r.bad_values == 0
    rays = pixel_corner_rays(32, 32)
    inner = sphere_hit(rays, 0.97)[0].all(axis=-1)
    outer = ~sphere_hit(rays, 1.03)[0].any(axis=-1)
    assert inner.sum() > 100 and outer.sum() > 300
    se = np.sqrt(var)
    # A convex object sees only the environment: exactly albedo * L = 0.5 at every depth >= 1.
    # Tolerance: 4 standard errors of the mean (the estimate's own variance; cosine env sampling
    # and cosine BSDF sampling are both exact for Lambert, so it is nearly 0) plus 2e-3 for the
    # tessellation: directions above the interpolated normal but below the flat triangle are
    # cut (rasterizer convention), a cosine-weighted fraction ~ (normal deviation)^2.
    err = np.abs(m[inner] - 0.5)
    assert np.all(err <= 4 * se[inner] + 2e-3), err.max()
    assert np.all(np.abs(m[outer] - 1.0) <= 1e-6)


def _albedo_table(model, p, cos_o, n_theta=160, n_phi=160):
    """Directional albedo integral of f cos over the hemisphere by Gauss-Legendre in cos(theta_i)
    and the midpoint rule in phi (the BRDF is isotropic and smooth for alpha = 0.5)."""
    x, w = np.polynomial.legendre.leggauss(n_theta)
    mu = 0.5 * (x + 1)                       # cos(theta_i) in (0, 1)
    wmu = 0.5 * w
    phi = (np.arange(n_phi) + 0.5) * 2 * np.pi / n_phi
    MU, PHI = np.meshgrid(mu, phi, indexing="ij")
    st = np.sqrt(1 - MU ** 2)
    wi = np.stack([st * np.cos(PHI), st * np.sin(PHI), MU], axis=-1).reshape(-1, 3)
    weights = (wmu[:, None] * np.full(n_phi, 2 * np.pi / n_phi)[None, :]).reshape(-1)
    out = []
    for c in cos_o:
        wo = np.array([math.sqrt(max(0.0, 1 - c * c)), 0.0, c])
        f = model.eval(p, wi, np.broadcast_to(wo, wi.shape))
        out.append((f[:, 0] * wi[:, 2] * weights).sum())
    return np.array(out)


def test_ggx_sphere_albedo(tmp_path):
    sc = scene_from(tmp_path, lone_sphere(dict(model="microfacet", distribution="ggx", fresnel="schlick",
                                               f0=[1.0, 1.0, 1.0], alpha=0.5), 32, 32))
    r = ReferenceRenderer(sc, width=32, height=32, max_depth=16, seed=2, workers=0)
    r.step(32)
    m, var = r.mean(), r.variance()
    r.close()
    assert r.bad_values == 0
    model = brdf.get("microfacet")
    p = sc.materials["m"]
    grid = np.linspace(0.0, 1.0, 65)
    table = _albedo_table(model, p, grid)
    rays = pixel_corner_rays(32, 32)
    hit, nrm = sphere_hit(rays, 1.0)
    inner = sphere_hit(rays, 0.97)[0].all(axis=-1)
    cos = np.clip(np.sum(nrm * -rays, axis=-1), 0, 1)        # cos_o at corners and centre
    inner &= cos.min(axis=-1) > 0.25                          # away from grazing (tessellation)
    a = np.interp(cos, grid, table)
    centre = a[..., 4]
    footprint = a.max(axis=-1) - a.min(axis=-1)
    # The pixel mean is the albedo averaged over the pixel's footprint, which lies between the
    # albedos at its corners and centre: tolerance = 4 SE (own variance estimate) + that
    # spread + 3e-3 for the tessellated sphere's normals and the cut below the flat triangles.
    err = np.abs(m[..., 0] - centre)
    tol = 4 * np.sqrt(var[..., 0]) + footprint + 3e-3
    assert inner.sum() > 100
    assert np.all(err[inner] <= tol[inner]), (err - tol)[inner].max()
    # over all inner pixels together: 4 SE of the average plus 2e-3 (footprint averaging and
    # tessellation, both far below that at 32x32)
    signed = (m[..., 0] - centre)[inner]
    se_all = math.sqrt(float(var[..., 0][inner].sum())) / inner.sum()
    assert abs(signed.mean()) <= 4 * se_all + 2e-3, (signed.mean(), se_all)


def test_glass_slab_transmittance(tmp_path):
    d, sigma, ior = 0.2, 2.0, 1.5
    sc = scene_from(tmp_path, f"""
        [camera]
        position = [0.0, 3.0, 0.0]
        target = [0.0, 0.0, 0.0]
        up = [0.0, 0.0, -1.0]
        fov_y = 4.0
        width = 8
        height = 8
        [[objects]]
        mesh = "cube"
        material = "glass"
        scale = [20.0, {d / 2}, 20.0]
        [materials.glass]
        model = "dielectric"
        ior = {ior}
        sigma_a = [{sigma}, {sigma}, {sigma}]
        """)
    # Environment: radiance 1 from the lower hemisphere (y < 0), black above. The camera looks
    # straight down: every reflection (off the top, or leaving through the top after internal
    # bounces) sees black, every path that leaves through the bottom sees 1, so the pixel is
    # exactly the slab's total transmittance. (Lat-long row 0 = zenith.)
    env = np.zeros((2, 4, 3))
    env[1] = 1.0
    r = ReferenceRenderer(sc, max_depth=32, seed=3, workers=0, env_image=env)
    r.step(256)
    m, var = r.mean(), r.variance()
    r.close()
    R = ((ior - 1) / (ior + 1)) ** 2
    a = math.exp(-sigma * d)
    T = (1 - R) ** 2 * a / (1 - R * R * a * a)   # incoherent sum over internal reflections
    c = m[2:6, 2:6, 1]
    se = math.sqrt(float(var[2:6, 2:6, 1].mean()) / c.size)
    # 4 standard errors of the mean over the 16 centre pixels; the view angle is <= 2 degrees
    # off normal, which changes R and the path length by < 1e-3 relative.
    assert abs(float(c.mean()) - T) <= 4 * se + 1e-3 * T, (c.mean(), T, se)
    assert se < 0.02 * T   # the test has teeth: no absorption (T = 0.92) would be 20 SE away
    print("slab", float(c.mean()), T, se)
    assert r.bad_values == 0


def test_total_internal_reflection_inside_sphere(tmp_path):
    sc = scene_from(tmp_path, lone_sphere(dict(model="dielectric", ior=1.5), 32, 32, name="glass"))
    it = Integrator(RenderSetup.from_scene(sc, width=4, height=4, max_depth=12))
    rng = np.random.default_rng(0)
    n = 2000
    # From (0, h, 0) along +x the ray meets the unit sphere at an angle of incidence asin(h).
    # Critical angle asin(1/1.5) = 41.8 deg: h = 0.9 (64 deg) is totally reflected at every
    # bounce (a sphere keeps the angle), so the path never leaves and sees no environment.
    for h, escapes in [(0.9, False), (0.2, True)]:
        o = np.tile([0.0, h, 0.0], (n, 1))
        d = np.tile([1.0, 0.0, 0.0], (n, 1))
        L = it.trace(o, d, lambda: rng.random((n, 5)))
        if escapes:
            assert L.mean() > 0.5
        else:
            assert np.all(L == 0.0)
    assert it.bad_values == 0


# ----------------------------------------------------------------------------- determinism

def small_scene(width=32, height=24):
    """A gold sphere on a grey floor, a point light and a constant sky."""
    return scene(camera([0.0, 1.2, 3.5], [0.0, 0.4, 0.0], 45.0, width, height),
                 environment(constant=[0.3, 0.35, 0.4]),
                 point_light([2.0, 3.0, 2.0], [20.0, 20.0, 20.0]),
                 sphere_on_floor(height=0.5),
                 material("ball", preset="gold", alpha=0.3),
                 material("floor", model="lambert", albedo=[0.5, 0.5, 0.5]))


SMALL_SCENE = small_scene()


def test_determinism_and_seed_statistics(tmp_path):
    sc = scene_from(tmp_path, SMALL_SCENE)
    spp = 32
    a = ReferenceRenderer(sc, seed=7, workers=0)
    a.step(spp)
    b = ReferenceRenderer(sc, seed=7, workers=2, pool="processes")
    b.step(spp)
    c = ReferenceRenderer(sc, seed=8, workers=0)
    c.step(spp)
    d = ReferenceRenderer(sc, seed=7, workers=2)   # "auto": this scene's bounce is compiled, so threads
    d.step(spp)
    try:
        assert d.pool_kind == "threads" and b.pool_kind == "processes"
        for other in (b, d):   # the same chunks, streams and order of sums, whatever renders them
            assert np.array_equal(a.mean(), other.mean())
            assert np.array_equal(a.variance(), other.variance())
        assert a.mean().shape == (24, 32, 3) and a.mean().dtype == np.float32
        # different seeds: (a - b)^2 / (var_a + var_b) has mean (n - 1) / (n - 3) for normal
        # sample means with variances estimated from n samples (E[1 / chi^2_{n-1}] scaling);
        # its own standard error over the pixels sets the tolerance (4 SE + 0.05 for
        # non-normal tails of few-sample means).
        ma, mc = a.mean().astype(np.float64), c.mean().astype(np.float64)
        vs = a.variance().astype(np.float64) + c.variance().astype(np.float64)
        sel = vs > 1e-12
        ratio = ((ma - mc) ** 2)[sel] / vs[sel]
        expect = (spp - 1) / (spp - 3)
        se = ratio.std() / math.sqrt(ratio.size)
        assert ratio.size > 500
        assert abs(ratio.mean() - expect) < 4 * se + 0.05, (ratio.mean(), expect, se)
        print("seed ratio", ratio.mean(), expect, se)
        assert not np.array_equal(ma, mc)
        # workers never import GL, the window's layer or the GPU tracer; nor PIL, trimesh or
        # scipy's linear algebra, which a render does not use (numba would import the latter
        # for nothing: viewer.pathtracer.compiled keeps it out, a thread pool and 0.2 CPU s less)
        mods = b.worker_modules()
        assert mods and not any(m.split(".")[0] in ("moderngl", "glfw", "OpenGL", "imgui_bundle", "PIL", "trimesh")
                                or m.startswith(("viewer.app", "viewer.gpupt", "scipy.linalg")) for m in mods), \
            [m for m in mods if m.startswith(("viewer.app", "viewer.gpupt", "scipy.linalg", "PIL", "trimesh"))]
    finally:
        for r in (a, b, c, d):
            r.close()


def _grid_subset(model, k=6):
    grid = param_grid(model)
    if len(grid) <= k:
        return grid
    idx = np.unique(np.linspace(0, len(grid) - 1, k).round().astype(int))
    return [grid[i] for i in idx]


@pytest.mark.parametrize("name", brdf.names())
def test_no_nan_inf_negative_at_parameter_extremes(tmp_path, name):
    sc = scene_from(tmp_path, small_scene(16, 12))
    model = brdf.get(name)
    for p in _grid_subset(model):
        sc.materials["ball"] = p
        r = ReferenceRenderer(sc, max_depth=6, seed=0, workers=0)
        r.step(2)
        img = r.mean()
        r.close()
        assert r.bad_values == 0, (name, dict(p))
        assert np.all(np.isfinite(img)), (name, dict(p))
        if r.is_spectral:  # Rec.709 of a spectral estimate is negative outside the gamut, its XYZ is not
            from viewer.spectral.colorimetry import rgb_to_xyz

            assert rgb_to_xyz(img).min() >= -1e-6 * max(1.0, float(np.abs(img).max())), (name, dict(p))
        else:
            assert np.all(img >= 0), (name, dict(p))


# ----------------------------------------------------------------------------- cancellation

CANCEL_BOUND_S = 30.0   # a loaded machine meets it; the latency itself: benchmarks/cancel.py


@pytest.mark.parametrize("pool", ["processes", "threads"])
def test_cancel_discards_the_pass_and_leaves_no_processes(tmp_path, pool):
    """A cancelled ``step`` returns False soon, adds nothing, leaves the renderer usable, and
    ``close`` ends exactly the worker processes this renderer started (threads: none)."""
    sc = scene_from(tmp_path, small_scene(64, 64))
    r = ReferenceRenderer(sc, seed=0, workers=2, pool=pool)
    assert r.pool_kind == pool
    r.step(1)
    ref = r.mean().copy()
    cancel, running = threading.Event(), threading.Event()
    out = {}

    def work():
        out["ok"] = r.step(10_000, cancel=cancel, progress=lambda f: running.set())

    th = threading.Thread(target=work)
    th.start()
    assert running.wait(120), "no chunk of the pass finished"   # the pass is under way
    cancel.set()
    th.join(CANCEL_BOUND_S)
    assert not th.is_alive(), "step did not return after the cancel"
    assert out["ok"] is False
    # the cancelled pass is discarded
    assert r.spp == 1 and np.array_equal(r.mean(), ref)
    # still usable after a cancel
    assert r.step(1) and r.spp == 2
    pids = r.worker_pids()
    assert bool(pids) == (pool == "processes")
    r.close()   # waits for its workers
    assert not set(pids) & {p.pid for p in mp.active_children()}
    if pool == "threads":
        assert not [t for t in threading.enumerate() if t.name.startswith("reference")]


# ----------------------------------------------------------------------------- CLI

def run_cli(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "viewer", *map(str, args)], capture_output=True,
                          text=True, timeout=300, cwd=cwd)


def test_reference_cli(tmp_path):
    scene = tmp_path / "s.toml"
    scene.write_text(SMALL_SCENE)
    out, lin = tmp_path / "r.png", tmp_path / "r.npy"
    res = run_cli("reference", scene, "--spp", 2, "--out", out, "--linear", lin, "--width", 16,
                  "--height", 12, "--seed", 3, "--max-depth", 3)
    assert res.returncode == 0, res.stderr
    assert "samples/second" in res.stdout
    img = np.load(lin)
    assert img.shape == (12, 16, 3) and img.dtype == np.float32 and np.all(np.isfinite(img))
    from PIL import Image

    with Image.open(out) as im:
        assert im.size == (16, 12)
    # same image as the API with the same seed and depth
    sc = load_scene(scene, ["camera.width=16", "camera.height=12"])
    r = ReferenceRenderer(sc, max_depth=3, seed=3, workers=0)
    r.step(2)
    r.close()
    assert np.array_equal(r.mean(), img)
    # bad input: exit 2, one line, no output files
    for args in (["--spp", 0], ["--spp", 2, "--max-depth", 0], ["--spp", 2, "--set", "camera.fov_y=500"]):
        bad_out = tmp_path / "bad.png"
        res = run_cli("reference", scene, "--out", bad_out, "--linear", tmp_path / "bad.npy", *args)
        assert res.returncode == 2, res.stderr
        assert len(res.stderr.strip().splitlines()) == 1
        assert not bad_out.exists() and not (tmp_path / "bad.npy").exists()
    res = run_cli("reference", tmp_path / "missing.toml", "--spp", 1, "--out", tmp_path / "m.png")
    assert res.returncode == 2 and not (tmp_path / "m.png").exists()


# ----------------------------------------------------------------------------- environment map

def test_envmap_orientation_and_importance_sampling():
    from viewer.environment.latlong import dir_to_uv as direction_to_uv, uv_to_dir as uv_to_direction
    from viewer.reference_common.envmap import EnvironmentLight

    u, v = direction_to_uv(np.array([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]]))
    assert np.allclose(u[[0, 2]], [0.5, 0.75]) and np.allclose(v, [0.5, 0.0, 0.5])  # u is arbitrary at the pole
    d = uv_to_direction(np.array([0.1, 0.7]), np.array([0.3, 0.9]))
    assert np.allclose(np.stack(direction_to_uv(d), 1), [[0.1, 0.3], [0.7, 0.9]])
    rng = np.random.default_rng(5)
    img = rng.random((16, 32, 3)) ** 4 * 10
    img[3, 7] = 500.0                              # a small bright "sun"
    env = EnvironmentLight(image=img, intensity=2.0, rotation_deg=30.0)
    n = 200_000
    wi, L, pdf = env.sample(rng.random((n, 2)), np.zeros((n, 3)), np.zeros(n, bool))
    assert np.allclose(np.linalg.norm(wi, axis=1), 1.0)
    assert np.allclose(env.eval(wi), L)
    assert np.allclose(env.pdf(wi, np.zeros((n, 3)), np.zeros(n, bool)), pdf, rtol=1e-6)
    # E[L / pdf] = integral of L over the sphere = sum of texel radiance x texel solid angle
    h, w = img.shape[:2]
    rows = np.arange(h)
    solid = (2 * np.pi / w) * (np.cos(np.pi * rows / h) - np.cos(np.pi * (rows + 1) / h))
    exact = 2.0 * (img * solid[:, None, None]).sum(axis=(0, 1))
    est = L / pdf[:, None]
    se = est.std(axis=0) / math.sqrt(n)
    assert np.all(np.abs(est.mean(axis=0) - exact) <= 4 * se), (est.mean(axis=0), exact, se)
    # proportional to luminance x sin(theta): far lower variance than uniform sampling
    assert np.all(se / exact < 0.01)


def test_reset_reuses_workers_and_matches_a_fresh_renderer(tmp_path):
    """reset() re-targets the same worker processes; the result equals a new renderer's."""
    import textwrap

    from viewer.pathtracer import ReferenceRenderer
    from viewer.scene import load_scene

    body = textwrap.dedent("""
        [camera]
        position = [0.0, 0.0, 4.0]
        width = 24
        height = 16
        [environment]
        constant = [1.0, 1.0, 1.0]
        [[objects]]
        mesh = "sphere"
        material = "m"
        [materials.m]
        model = "lambert"
        albedo = [{a}, {a}, {a}]
        """)
    (tmp_path / "a.toml").write_text(body.format(a=0.5))
    (tmp_path / "b.toml").write_text(body.format(a=0.2))
    a, b = load_scene(tmp_path / "a.toml"), load_scene(tmp_path / "b.toml")
    with ReferenceRenderer(a, max_depth=2, seed=3, workers=2, pool="processes") as r:
        r.step(2)
        pids = set(r.worker_pids())
        r.reset(b)
        assert r.spp == 0
        r.step(2)
        assert set(r.worker_pids()) == pids
        got = r.mean()
    with ReferenceRenderer(b, max_depth=2, seed=3, workers=0) as fresh:
        fresh.step(2)
        assert np.array_equal(got, fresh.mean())


def test_scene_environment_map_is_used(tmp_path):
    """A scene naming a map (here a saved .hdr file) lights the reference: a Lambert sphere of
    albedo a under a map of constant radiance 0.75 shows a * 0.75 (furnace with a map file)."""
    from viewer.environment.io import save_environment
    from viewer.pathtracer import ReferenceRenderer
    from viewer.scene import load_scene

    save_environment(tmp_path / "flat.hdr", np.full((16, 32, 3), 0.75, dtype=np.float32))
    (tmp_path / "s.toml").write_text(textwrap.dedent("""
        [camera]
        position = [0.0, 0.0, 4.0]
        width = 16
        height = 16
        [environment]
        map = "flat.hdr"
        intensity = 2.0
        [[objects]]
        mesh = "sphere"
        material = "m"
        [materials.m]
        model = "lambert"
        albedo = [0.5, 0.5, 0.5]
        """))
    scene = load_scene(tmp_path / "s.toml")
    with ReferenceRenderer(scene, max_depth=3, seed=1, workers=0) as r:
        r.step(8)
        img, var = r.mean(), r.variance()
    # background: the map itself (1.5); centre of the sphere: 0.5 * 1.5. RGBE stores 0.75
    # exactly (a power-of-two mantissa), so the only error is Monte Carlo noise (4 SE).
    assert np.allclose(img[0, 0], 1.5, atol=1e-6)
    c = img[7:9, 7:9].reshape(-1, 3)
    se = np.sqrt(var[7:9, 7:9].reshape(-1, 3))
    assert np.all(np.abs(c - 0.75) <= 4 * se + 1e-6), (c, se)


def test_auto_pool_follows_the_scene_across_resets(tmp_path):
    """``pool="auto"``: threads where every bounce is compiled (the compiled loop releases the GIL),
    worker processes for the photon integrator's numpy steps, switched on ``reset``; each image
    equals a fresh in-process renderer's, bit for bit. An unknown pool is refused by name."""
    sc = scene_from(tmp_path, small_scene(16, 12))
    with pytest.raises(ValueError, match="pool: 'fork'"):
        ReferenceRenderer(sc, workers=2, pool="fork")
    with ReferenceRenderer(sc, max_depth=3, seed=5, workers=2) as r:
        seen = []
        for integrator in ("path", "photon", "path"):
            if seen:
                r.reset(sc, integrator=integrator)
            r.step(2)
            with ReferenceRenderer(sc, max_depth=3, seed=5, workers=0, integrator=integrator) as fresh:
                fresh.step(2)
                assert np.array_equal(r.mean(), fresh.mean()), integrator
            seen.append((r.pool_kind, bool(r.worker_pids())))
        assert seen == [("threads", False), ("processes", True), ("threads", False)]


def test_a_rendering_process_keeps_its_freed_memory(tmp_path):
    """Where this process renders (threads or ``workers=0``), glibc's heap keeps freed chunk arrays
    and numpy stops advising huge pages (``viewer.base.heap``: each cost a page fault or a
    memory compaction per chunk)."""
    from viewer.base import heap

    with ReferenceRenderer(scene_from(tmp_path, small_scene(8, 6)), workers=0) as r:
        r.step(1)
    assert heap.keep_freed_memory() == {"heap": sys.platform.startswith("linux"), "numpy": True}
