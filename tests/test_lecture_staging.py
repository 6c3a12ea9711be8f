"""The lecture's steps show what their captions say, measured on the raster image (offscreen,
the window's renderer) with pixel masks from independent camera rays (render_util): step 4's
Torrance-Sparrow highlight stands out of its diffuse base; step 5's GGX tail carries several
times the energy of Beckmann's at the same alpha; the glass steps are exposed for a projector
(their brightest percent near white, in the raster and the reference alike); step 7's
retro-reflection shows on the ball; step 9's floor stays under white where the caption lies."""

import numpy as np
import pytest

from render_util import camera_rays, hit_plane_y, hit_sphere
from viewer.scene.lecture import TOUR

W, H = 480, 270
LUM = np.array([0.2126, 0.7152, 0.0722])


def _step(key):
    return next(i for i, s in enumerate(TOUR) if s.key == key)


def _render(key):
    from viewer import api
    from viewer.scene import load_scene

    ref = f"lecture:{_step(key) + 1}"
    sc = load_scene(ref, [f"camera.width={W}", f"camera.height={H}"])
    return sc, api.render(ref, W, H) @ LUM


def _ball_mask(sc, material):
    """Pixels whose centre ray hits the sphere made of ``material`` (radius = its scale), shrunk
    by a few percent of the radius so the silhouette's antialiased edge is left out."""
    c = sc.camera
    d = camera_rays(c.position, c.target, c.up, c.fov_y, W, H)
    (o,) = [o for o in sc.objects if o.material == material and o.mesh == "sphere"]
    r = float(np.max(o.scale))
    return np.isfinite(hit_sphere(c.position, d, o.translate, 0.93 * r))


def highlight_contrast(sc, lum, obj="ball"):
    """The brightest pixel of the ball over the median of its pixels."""
    v = lum[_ball_mask(sc, obj)]
    return float(v.max() / np.median(v))


def tail_energy(sc, lum, obj):
    """Light the ball sends outside its highlight's core: the sum of its pixels darker than a
    tenth of its peak (linear luminance). With a black base (kd = 0) that is the lobe's tail:
    GGX's D falls as tan(theta_h)^-4, Beckmann's as exp(-tan^2 / alpha^2)."""
    v = lum[_ball_mask(sc, obj)]
    return float(v[v < 0.1 * v.max()].sum())


def test_torrance_sparrow_highlight_stands_out():
    sc, lum = _render("torrance_sparrow")
    c = highlight_contrast(sc, lum)
    print(f"step 4 highlight contrast (max / median of the ball) {c:.2f}")
    # a bump on a diffuse ball is ~1.3; the highlight is at least 3x the ball's typical pixel
    assert c > 3.0, c


def test_ggx_tail_glows_against_beckmann():
    sc, lum = _render("beckmann_ggx")
    b, g = tail_energy(sc, lum, "beckmann"), tail_energy(sc, lum, "ggx")
    peaks = [float(lum[_ball_mask(sc, m)].max()) for m in ("beckmann", "ggx")]
    print(f"step 5 tail energy GGX / Beckmann {g / b:.2f}; peaks {peaks}")
    # the same alpha: the peaks are alike (D(0) = 1 / (pi alpha^2) for both), the tails are not
    # measured 3.7; a diffuse base under both (kd = 0.5, as the presets have) brings it near 1
    assert g / b > 2.5, (g, b)
    assert 0.5 < peaks[1] / peaks[0] < 2.0, peaks


def _prism_mask(sc, w, h):
    """Pixels whose centre ray meets the prism's bounding box (its triangle's extent in y and
    z, its length along x after the quarter turn), as an independent screen region."""
    c = sc.camera
    d = camera_rays(c.position, c.target, c.up, c.fov_y, w, h)
    (o,) = [o for o in sc.objects if o.mesh == "prism"]
    sx, sy, sz = np.broadcast_to(np.asarray(o.scale, float), (3,))
    # local x (the triangle's half-width 0.866) becomes world z, local z (the length) world x
    lo = np.asarray(o.translate) + np.array([-sz, -0.5 * sy, -0.866 * sx])
    hi = np.asarray(o.translate) + np.array([sz, sy, 0.866 * sx])
    org = np.asarray(c.position, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        t0, t1 = (lo - org) / d, (hi - org) / d
    near = np.max(np.minimum(t0, t1), axis=-1)
    far = np.min(np.maximum(t0, t1), axis=-1)
    return far > np.maximum(near, 0.0)


@pytest.mark.slow  # one traced frame of glass on software OpenGL: about 70 s at 320 x 180
def test_dispersion_shows_rainbow_bands_through_the_prism():
    from viewer import api
    from viewer.image.colour import to_srgb8
    from viewer.scene import load_scene

    w, h = 320, 180
    ref = f"lecture:{_step('dispersion') + 1}"
    sc = load_scene(ref)
    s8 = to_srgb8(api.render(ref, w, h), sc.render.exposure, sc.render.tonemap).astype(int)
    rb = s8[..., 0] - s8[..., 2]
    warm, cool = rb > 40, rb < -40
    inside = _prism_mask(sc, w, h)
    n = {k: (int((m & inside).sum()), int((m & ~inside).sum())) for k, m in (("warm", warm), ("cool", cool))}
    print(f"step 12 fringe pixels R - B > 40/255 {n['warm'][0]} through the prism, {n['warm'][1]} elsewhere; "
          f"B - R > 40/255 {n['cool'][0]} through it, {n['cool'][1]} elsewhere ({w} x {h})")
    # a dispersed white bar has a red edge and a blue edge: through the prism warm and cool
    # fringes come in about equal numbers (measured 1422 and 1399 of its 6076 pixels; a quarter
    # of its pixels coloured is a band pattern no glint makes). Elsewhere the blue sky, seen
    # through the diamond's lower half at +1.5 EV, is cool by 41-45/255 (622 pixels), so the
    # warm fringes alone tell the prism's bands from the rest: 34 elsewhere, the diamond's glints
    # (the staging before the bars: 6 at 480 x 270, sun glints)
    assert n["warm"][0] + n["cool"][0] > 0.25 * inside.sum(), (n, int(inside.sum()))
    assert min(n["warm"][0], n["cool"][0]) > 0.1 * inside.sum(), (n, int(inside.sum()))
    assert n["warm"][0] > 5 * n["warm"][1], n


def test_importance_sampling_step_strategies_differ_in_noise():
    """Step 14 on its own scene (at 32 x 18): the per-sample variance of BSDF sampling alone and
    of light sampling alone, over that of MIS, as the caption states them (2.8x and 3.4x at
    256 spp on the full image)."""
    from viewer.pathtracer import ReferenceRenderer
    from viewer.scene import load_scene

    step = _step("importance_sampling")
    assert TOUR[step].image == "split"  # opens on the raster beside the converging reference
    sc = load_scene(f"lecture:{step + 1}", ["camera.width=32", "camera.height=18"])
    var = {}
    for i, strategy in enumerate(("mis", "bsdf", "light")):
        with ReferenceRenderer(sc, workers=0, seed=20 + i, max_depth=8, strategy=strategy) as r:
            r.step(64)
            var[strategy] = float(r.variance().astype(np.float64).mean())
    ratios = {k: var[k] / var["mis"] for k in ("bsdf", "light")}
    print(f"step 14 variance over MIS: BSDF {ratios['bsdf']:.2f}, light {ratios['light']:.2f} ({var})")
    # the caption's 2.8x and 3.4x, with room for the noise of a variance estimate from 64 spp
    # over 576 pixels (light sampling's heavy tail makes it the least certain)
    assert ratios["bsdf"] > 1.8 and ratios["light"] > 1.8, ratios


CAPTIONS = r'''
from viewer.app.main import App
from viewer.app.panels.overlays import measure, wrap_lines
from viewer.scene.lecture import TOUR
app = App("sphere", size=(1920, 1080), restore_state=False)
app.session.warm = []
app.set_ui_scale(1.5)
bad = []
for i in range(len(TOUR)):
    app.session.lecture(i)
    app.session.scene.render.raytrace = False  # the caption is what is measured, not the trace
    app.session.compare.mode = "raster"
    app.frame()
    lay, t = app.overlay_plan()
    rr, px = lay["caption_text"], lay["caption_px"]
    m = measure()
    lines = wrap_lines(t["caption"], rr.w, lambda s: m(s, px.y)[0])
    h = sum(m(line, px.y)[1] for line in lines)
    if h > rr.h + 0.5 or any(m(line, px.y)[0] > rr.w + 0.5 for line in lines):
        bad.append((i + 1, h, rr.h))
print("BAD", bad)
app.close()
'''


@pytest.mark.slow  # loads all 14 steps in a window (their maps prefiltered): about 150 s on 2 cores
@pytest.mark.skipif(__import__("shutil").which("Xvfb") is None, reason="needs Xvfb")
def test_every_caption_fits_its_box_at_projector_scale(display):
    """At 1920 x 1080 and UI 1.5 every step's caption, broken into the lines drawn, is no wider
    and no taller than its box (a word used to run past the right edge)."""
    from gui_harness import run_py

    r = run_py(CAPTIONS, display, timeout=600)
    assert r.returncode == 0 and "BAD []" in r.stdout, r.stdout + r.stderr[-2000:]


def _srgb8(key, w, h):
    from viewer import api
    from viewer.image.colour import to_srgb8
    from viewer.scene import load_scene

    ref = f"lecture:{_step(key) + 1}"
    sc = load_scene(ref, [f"camera.width={w}", f"camera.height={h}"])
    return sc, to_srgb8(api.render(ref, w, h), sc.render.exposure, sc.render.tonemap)


# the glass steps: every one traces its specular chains (a few seconds a step at 160 x 90, the
# dispersion and soap-bubble steps about ten)
GLASS = ("fresnel", "tir", "absorbing_glass", "complex_ior")
GLASS_SLOW = ("dispersion", "soap_bubble")


def _glass_p99(key):
    sc, s8 = _srgb8(key, 160, 90)
    assert sc.render.raytrace
    p99 = float(np.percentile(s8, 99))
    print(f"step {_step(key) + 1} ({key}): 99th percentile {p99:.0f}/255 at EV {sc.render.exposure:g}, "
          f"tone map {sc.render.tonemap}")
    return p99


@pytest.mark.parametrize("key", GLASS)
def test_glass_step_is_exposed_for_a_projector(key):
    """The brightest percent of the 8-bit image reads at least 180/255 (steps 2, 3 and 10, lit
    by the sky alone, read 77, 78 and 76 before they had an exposure of their own)."""
    assert _glass_p99(key) >= 180


@pytest.mark.slow  # about ten seconds each at 160 x 90
@pytest.mark.parametrize("key", GLASS_SLOW)
def test_slow_glass_step_is_exposed_for_a_projector(key):
    assert _glass_p99(key) >= 180  # step 12 read 136 at EV 0


def test_glass_step_reference_follows_the_scene_exposure():
    """The exposure is the scene's, so the reference's image is exposed as the raster's: step 2
    path-traced at 48 x 27, 4 spp, written as ``brdf-viewer reference`` writes it."""
    from viewer import api
    from viewer.image.colour import to_srgb8
    from viewer.scene import load_scene

    ref = f"lecture:{_step('fresnel') + 1}"
    sc = load_scene(ref)
    assert sc.render.exposure > 0
    lin = api.reference(ref, spp=4, engine="cpu", width=48, height=27, workers=0)
    p99 = float(np.percentile(to_srgb8(lin, sc.render.exposure, sc.render.tonemap), 99))
    at_ev0 = float(np.percentile(to_srgb8(lin), 99))
    print(f"step 2 reference: 99th percentile {p99:.0f}/255 (at EV 0: {at_ev0:.0f})")
    assert p99 >= 180 > at_ev0


def _ball_cos(sc, material, w, h):
    """cos(angle between the sphere's normal and the view ray) per pixel of the sphere made of
    ``material`` (NaN off it)."""
    c = sc.camera
    d = camera_rays(c.position, c.target, c.up, c.fov_y, w, h)
    (o,) = [o for o in sc.objects if o.material == material and o.mesh == "sphere"]
    r, centre = float(np.max(o.scale)), np.asarray(o.translate, float)
    t = hit_sphere(c.position, d, centre, r)
    hit = np.isfinite(t)
    n = (np.asarray(c.position) + np.where(hit, t, 0.0)[..., None] * d - centre) / r
    return np.where(hit, -np.sum(n * d, axis=-1), np.nan)


def test_lafortune_step_shows_its_retro_reflection_on_the_ball():
    """Step 7 lit from behind the viewer: wherever the forward lobe is out of the way (toward the
    rim, cos theta 0.25 .. 0.6), the Lafortune ball is much brighter than the Lambert ball of its
    diffuse base beside it. Expected from the model in luminance: (kd / pi + 0.7^5) / (kd / pi)
    = (0.096 + 0.168) / 0.096 = 2.8 with the light on the view ray; the lamp 1.4 m off it and the
    dim ambient bring it a little lower. Under the former key light (50 degrees off the view) the
    retro lobe added 15%."""
    w, h = 480, 270
    sc, lum = _render("lafortune")
    lum = lum.astype(np.float64)
    rings = {}
    for m in ("lafortune", "lambert"):
        cos = _ball_cos(sc, m, w, h)
        rim, centre = (cos > 0.25) & (cos < 0.6), cos > 0.95
        rings[m] = (float(lum[rim].mean()), float(lum[centre].mean()))
    gain = rings["lafortune"][0] / rings["lambert"][0]
    ratios = {m: round(r / c, 3) for m, (r, c) in rings.items()}
    print(f"step 7 rim gain Lafortune / Lambert {gain:.2f}; rim / centre {ratios}")
    assert gain > 2.0, rings


def test_layered_step_floor_is_not_blown_out_under_the_caption():
    """Step 9 (studio map and key light together): the floor pixels in the bottom 35% of the view,
    where the caption's box lies, stay under white. With a 0.5 floor they read 239/255 at the
    median, 46% of them at 240 or above."""
    w, h = 320, 180
    sc, s8 = _srgb8("layered", w, h)
    c = sc.camera
    d = camera_rays(c.position, c.target, c.up, c.fov_y, w, h)
    (ball,) = [o for o in sc.objects if o.mesh == "sphere"]
    floor = np.isfinite(hit_plane_y(c.position, d, 0.0)) & ~np.isfinite(
        hit_sphere(c.position, d, ball.translate, 1.05 * float(np.max(ball.scale))))
    floor[: int(0.65 * h)] = False
    v = s8.max(axis=-1)[floor]
    assert v.size > 0.2 * w * h
    hot, white = float(np.mean(v >= 240)), float(np.mean(v == 255))
    print(f"step 9 floor under the caption: median {np.median(v):.0f}/255, {hot:.1%} at >= 240, {white:.1%} at 255")
    assert white == 0.0 and hot < 0.05, (hot, white)


def _floor_misses(key, w=240, h=135, horizon_deg=2.0):
    """Of the rays leaving the bubbles of step ``key`` downward more steeply than ``horizon_deg``
    (straight through an ior-1 shell, and mirrored at its front face), the fraction that passes
    the floor's edge (the plane mesh spans [-1, 1] times its scale) and sees the studio's dark
    floor band at the horizon instead."""
    from viewer.scene import load_scene

    sc = load_scene(f"lecture:{_step(key) + 1}", load_meshes=False)
    c = sc.camera
    d = camera_rays(c.position, c.target, c.up, c.fov_y, w, h)
    (floor,) = [o for o in sc.objects if o.mesh == "plane"]
    half = float(np.max(floor.scale))
    out = []
    for o in sc.objects:
        if o.mesh != "sphere":
            continue
        centre, r = np.asarray(o.translate, float), float(np.max(o.scale))
        t = hit_sphere(c.position, d, centre, r)
        hit = np.isfinite(t)
        p = np.asarray(c.position) + t[hit][:, None] * d[hit]
        n = (p - centre) / r
        straight = d[hit]
        mirrored = straight - 2.0 * np.sum(straight * n, axis=-1, keepdims=True) * n
        for start, ray in ((p, straight), (p, mirrored)):
            down = ray[:, 1] < -np.sin(np.radians(horizon_deg))
            q = start[down] + (-start[down, 1] / ray[down, 1])[:, None] * ray[down]
            out.append(np.maximum(np.abs(q[:, 0]), np.abs(q[:, 2])) > half)
    out = np.concatenate(out)
    return float(out.mean()), out.size


def test_soap_bubble_step_shows_no_dark_horizon_band():
    """Step 13: every ray that leaves a bubble downward (beyond two degrees below the horizon),
    seen through it or mirrored in it, lands on the floor. With a floor 12 m across, 28% of
    them passed its edge onto the studio map's dark floor (0.02-0.06): a dark band across each
    bubble's middle, in the reference too."""
    miss, n = _floor_misses("soap_bubble")
    print(f"step 13: {miss:.2%} of {n} downward rays pass the floor's edge")
    assert n > 1000 and miss == 0.0


def _first_hits(o, d, tris):
    """Distance to the nearest of ``tris`` (T, 3, 3) along rays from ``o`` (N, 3) in ``d`` (N, 3),
    and that triangle's index; inf / -1 where none is hit (Moller-Trumbore)."""
    a, e1, e2 = tris[:, 0], tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]
    p = np.cross(d[:, None, :], e2[None])
    det = np.sum(p * e1[None], axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / det
        s = o[:, None, :] - a[None]
        u = np.sum(s * p, axis=-1) * inv
        q = np.cross(s, e1[None])
        v = np.sum(d[:, None, :] * q, axis=-1) * inv
        t = np.sum(q * e2[None], axis=-1) * inv
    ok = (np.abs(det) > 1e-12) & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 1e-6)
    t = np.where(ok, t, np.inf)
    k = np.argmin(t, axis=1)
    best = t[np.arange(len(t)), k]
    return best, np.where(np.isfinite(best), k, -1)


def _refract(d, n, eta):
    """``d`` refracted into a medium ``eta`` times denser across a face of normal ``n`` (any
    side); NaN where it is totally reflected."""
    n = np.where(np.sum(d * n, axis=-1, keepdims=True) > 0, -n, n)
    c = -np.sum(d * n, axis=-1, keepdims=True)
    k = 1.0 - (1.0 - c * c) / (eta * eta)
    out = d / eta + (c / eta - np.sqrt(np.maximum(k, 0.0))) * n
    return np.where(k >= 0, out, np.nan)


def test_dispersion_step_prism_shows_the_bars_over_its_whole_face():
    """Step 12: the view through the prism (SF11, n 1.77-1.83) lands on the bars' rows over the
    whole face: every ray that passes the prism (entering its front face, leaving its back one)
    and reaches the floor among the rows lands within the bars' length. With bars 1.6 m long a
    wedge of the face's upper left saw the bare black floor beside them (traced and in the
    reference: the bent view spreads sideways with distance)."""
    from viewer.scene import load_scene

    sc = load_scene(f"lecture:{_step('dispersion') + 1}")
    c = sc.camera
    w, h = 320, 180
    d = camera_rays(c.position, c.target, c.up, c.fov_y, w, h).reshape(-1, 3)
    (prism,) = [o for o in sc.objects if o.mesh == "prism"]
    tris = prism.world_positions()[np.asarray(prism.mesh_data.indices).reshape(-1, 3)]
    normals = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    normals /= np.linalg.norm(normals, axis=-1, keepdims=True)
    bars = [o for o in sc.objects if o.material == "bar"]
    xs = [(o.translate[0] - o.scale[0], o.translate[0] + o.scale[0]) for o in bars]
    zs = sorted(o.translate[2] for o in bars)
    counted = 0
    for n_glass in (1.77, 1.83):  # the red and the blue end of SF11's index
        o = np.broadcast_to(np.asarray(c.position, float), d.shape)
        t, k = _first_hits(o, d, tris)
        inside = np.isfinite(t)
        p = o[inside] + t[inside, None] * d[inside]
        r = _refract(d[inside], normals[k[inside]], n_glass)
        t2, k2 = _first_hits(p + 1e-6 * r, np.nan_to_num(r), tris)
        ok = np.isfinite(t2) & ~np.isnan(r[:, 0])
        p2 = p[ok] + t2[ok, None] * r[ok]
        out = _refract(r[ok], normals[k2[ok]], 1.0 / n_glass)
        down = ~np.isnan(out[:, 0]) & (out[:, 1] < 0)
        q = p2[down] + (-p2[down, 1] / out[down, 1])[:, None] * out[down]
        among = (q[:, 2] <= zs[-1]) & (q[:, 2] >= zs[0])  # between the first row and the last
        beside = (q[:, 0] < min(a for a, _ in xs)) | (q[:, 0] > max(b for _, b in xs))
        counted += int(among.sum())
        print(f"n {n_glass}: {inside.sum()} rays into the prism, {among.sum()} land among the rows, "
              f"{(among & beside).sum()} beside the bars")
        assert not np.any(among & beside)
    assert counted > 2000
