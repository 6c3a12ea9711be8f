"""Traced specular chains in the rasterizer ([render] raytrace = true; viewer/gl/raytrace.py,
shaders/common/specular_chain.glsl), against the CPU reference path tracer and analytic values.

The reference follows the same delta chains exactly (its max_depth = the chain's depth, 8), so
where a chain ends in the environment the two differ only by the pixel filter (both box-filter:
the raster supersamples 4 x 4, the reference jitters its samples) and its Monte Carlo noise.
Where a chain ends on a diffuse surface the raster shades it the rasterizer's way (split-sum
environment without occlusion, shadow maps), the reference with full global illumination: the
tolerances below leave room for that and say so.
"""

import textwrap

import numpy as np
import pytest

from viewer.scene.camera import OrbitCamera
from viewer import ViewerError as SceneError
from viewer.scene import load_scene, parse_scene

from scene_text import camera, environment, glass_ball, material, mirror_floor, obj, render, scene

W = H = 64
SS = 4


def _scene(tmp_path, name, text):
    p = tmp_path / f"{name}.toml"
    p.write_text(textwrap.dedent(text))
    return load_scene(str(p))


def _reference(scene, spp, seed=1):
    pathtracer = pytest.importorskip("viewer.pathtracer")
    ref = pathtracer.ReferenceRenderer(scene, camera=OrbitCamera.from_scene(scene), width=W, height=H,
                                       max_depth=8, seed=seed, workers=2)
    try:
        ref.step(spp)
        return ref.mean()
    finally:
        ref.close()


def _object_mask(gl_ctx, scene, index, erode=1):
    """Pixels whose centre ray first hits object ``index`` (the BVH on the GPU), eroded by
    ``erode`` pixels so silhouettes (partly covered pixels) are left out."""
    from render_util import camera_rays

    from viewer.gl.scene_textures import RayQuery, SceneTextures
    from viewer.geometry.soup import build_geometry

    c = scene.camera
    d = camera_rays(c.position, c.target, c.up, c.fov_y, W, H).reshape(-1, 3)
    geom = build_geometry(scene)
    q = RayQuery(gl_ctx)
    with SceneTextures(gl_ctx, geom) as st:
        _, prim, _, _ = q.intersect(st, np.broadcast_to(c.position, d.shape), d)
    q.release()
    obj = np.where(prim >= 0, geom.object_index[np.maximum(prim, 0)], -1).reshape(H, W)
    m = obj == index
    for _ in range(erode):
        e = m.copy()
        e[1:-1, 1:-1] = m[1:-1, 1:-1] & m[:-2, 1:-1] & m[2:, 1:-1] & m[1:-1, :-2] & m[1:-1, 2:]
        e[0, :] = e[-1, :] = e[:, 0] = e[:, -1] = False
        m = e
    return m


def _rel_mean_error(img, ref, mask):
    """The error of the mean radiance over the mask, relative: |mean raster - mean reference| /
    mean reference, summed over the channels (the per-pixel error of sharp refracted panels at
    64 samples per pixel is mostly the reference's noise: 16% at 64 spp, 5% at 512 on the ball;
    the 4x4-block errors below catch local differences)."""
    a, b = img[mask].mean(axis=0), ref[mask].mean(axis=0)
    return float(np.abs(a - b).sum() / b.sum())


def _block_errors(img, ref, mask, k=4):
    """Relative error of the mean over each k x k block lying fully inside the mask."""
    out = []
    for i in range(0, H - k + 1, k):
        for j in range(0, W - k + 1, k):
            if mask[i:i + k, j:j + k].all():
                a = img[i:i + k, j:j + k].mean(axis=(0, 1))
                b = ref[i:i + k, j:j + k].mean(axis=(0, 1))
                out.append(float(np.abs(a - b).sum() / max(b.sum(), 1e-6)))
    return np.array(out)


def _raster(renderer, scene, raytrace):
    scene.render.raytrace = raytrace
    return renderer.render_arrays(scene, width=W, height=H, supersample=SS)[0]


GLASS_BALL = glass_ball(W, H)


def test_scene_key_is_validated(tmp_path):
    s = _scene(tmp_path, "ok", GLASS_BALL + "\n")
    assert s.render.raytrace is False and s.render.raytrace_depth == 8
    import tomllib

    data = tomllib.loads(textwrap.dedent(GLASS_BALL))
    data["render"]["raytrace"] = True
    data["render"]["raytrace_depth"] = 5
    s = parse_scene(data, None)
    assert s.render.raytrace is True and s.render.raytrace_depth == 5
    for key, bad, what in (("raytrace", "yes", "expected true or false"), ("raytrace_depth", 0, "out of range"),
                           ("raytrace_depth", 2.5, "expected an integer")):
        d = tomllib.loads(textwrap.dedent(GLASS_BALL))
        d["render"][key] = bad
        with pytest.raises(SceneError, match=f"render.{key}.*{what}"):
            parse_scene(d, None)


@pytest.mark.slow  # the block errors need a converged reference: 512 spp (~50 s on 2 cores)
def test_glass_ball_under_studio_map(tmp_path, renderer, gl_ctx):
    # Every chain ends in the environment (nothing else in the scene), so raster and reference
    # integrate the same function over each pixel. Tolerances: mean < 3% and p90 of 4x4 blocks
    # < 20% (the bounds); what remains is the sphere's tessellation (the reference
    # traces the same triangles and normals, so only the box filters' sampling differs), the
    # reference's noise at 64 spp (~1% per block on this map) and float32 rounding near TIR.
    scene = _scene(tmp_path, "ball", GLASS_BALL)
    mask = _object_mask(gl_ctx, scene, 0)
    ref = _reference(scene, 512, seed=3)
    errs = {}
    for rt in (False, True):
        img = _raster(renderer, scene, rt)
        errs[rt] = (_rel_mean_error(img, ref, mask), float(np.percentile(_block_errors(img, ref, mask), 90)))
    print(f"glass ball ({mask.sum()} px): raytrace off mean {errs[False][0]:.4f} p90 {errs[False][1]:.4f}; "
          f"on mean {errs[True][0]:.4f} p90 {errs[True][1]:.4f}")
    assert errs[True][0] < 0.03
    assert errs[True][1] < 0.20


def test_glass_ball_with_msaa_is_traced_from_the_surface(tmp_path, renderer, gl_ctx):
    # The window renders with MSAA (the scene's 4 samples), not supersampled: a pixel a triangle
    # covers only partly is shaded at its centre, past the triangle's edge. Away from the ball's
    # silhouette every pixel's centre lies on the surface either way, so the traced image with
    # MSAA equals the one without it there (float rounding of the re-found hit: 1e-4), and the
    # ball's mean is the supersampled one's within 3% (measured 1.6% here, 0.5% at 128 x 128:
    # MSAA shades a silhouette pixel at one point, where the rim's Fresnel rises steeply across
    # it; the box filter averages it). Before
    # the chain re-found its start in the BVH, 8% of the inner pixels were off (a refracted ray
    # started outside the mesh entered twice) and the ball's mean was 16% low here.
    scene = _scene(tmp_path, "ball", GLASS_BALL)
    scene.render.raytrace = True
    mask = _object_mask(gl_ctx, scene, 0)
    inner = mask.copy()
    for _ in range(2):  # two pixels in from the silhouette
        inner[1:-1, 1:-1] &= inner[:-2, 1:-1] & inner[2:, 1:-1] & inner[1:-1, :-2] & inner[1:-1, 2:]
    msaa = renderer.read_linear(renderer.render(scene, width=W, height=H, msaa=4))
    plain = renderer.read_linear(renderer.render(scene, width=W, height=H, msaa=0))
    boxed = renderer.render_arrays(scene, width=W, height=H, supersample=SS)[0]
    off = np.abs(msaa - plain).max(axis=-1) > 1e-4 * (1.0 + plain.max(axis=-1))
    rel = abs(float(msaa[mask].mean()) / float(boxed[mask].mean()) - 1.0)
    print(f"traced glass with MSAA: {off[inner].mean():.4f} of {inner.sum()} inner px differ from msaa 0; "
          f"ball mean {msaa[mask].mean():.4f} vs supersampled {boxed[mask].mean():.4f} ({rel:.4f})")
    assert off[inner].mean() == 0.0
    assert rel < 0.03


@pytest.mark.slow  # 512 spp: at 64 the reference's fireflies alone move the cube's mean by 3.5%
def test_tir_glass_cube_lecture_step(renderer, gl_ctx):
    # The lecture's total-internal-reflection step (a glass cube turned 35 degrees on a Lambert
    # floor under the sky). Chains that end on the floor see it shaded the rasterizer's way
    # (split-sum sky light without occlusion, no indirect light), the reference with global
    # illumination: hence 8% (the bound) rather than the 3% of the lone ball.
    from viewer.scene.lecture import TOUR, tour_scene

    i = [s.key for s in TOUR].index("tir")
    scene = tour_scene(i)
    scene.camera.width, scene.camera.height = W, H
    cube = [k for k, o in enumerate(scene.objects) if o.material == "glass"][0]
    mask = _object_mask(gl_ctx, scene, cube)
    ref = _reference(scene, 512, seed=5)
    e = {rt: _rel_mean_error(_raster(renderer, scene, rt), ref, mask) for rt in (False, True)}
    print(f"TIR cube ({mask.sum()} px): mean error raytrace off {e[False]:.4f}, on {e[True]:.4f}")
    assert e[True] < 0.08


def _reflected_region(scene):
    """Floor pixels whose mirrored centre ray meets the sphere (analytic, numpy)."""
    from render_util import camera_rays, hit_plane_y, hit_sphere

    c = scene.camera
    d = camera_rays(c.position, c.target, c.up, c.fov_y, W, H)
    t = hit_plane_y(c.position, d, 0.0)
    p = np.asarray(c.position) + d * np.where(np.isfinite(t), t, 0.0)[..., None]
    floor = np.isfinite(t) & (np.abs(p[..., 0]) < 2.9) & (np.abs(p[..., 2]) < 2.9)
    floor &= ~np.isfinite(hit_sphere(c.position, d, (0.0, 0.6, 0.0), 0.5))
    r = d * np.array([1.0, -1.0, 1.0])
    hits = np.zeros((H, W), bool)
    for i, j in zip(*np.nonzero(floor)):
        hits[i, j] = np.isfinite(hit_sphere(p[i, j], r[i, j][None], (0.0, 0.6, 0.0), 0.5)[0])
    m = floor & hits
    e = m.copy()
    e[1:-1, 1:-1] = m[1:-1, 1:-1] & m[:-2, 1:-1] & m[2:, 1:-1] & m[1:-1, :-2] & m[1:-1, 2:]
    return e


def test_sphere_over_mirror_floor(tmp_path, renderer):
    # In the reflected region the chain is camera -> mirror -> Lambert sphere, shaded by the
    # point light with its shadow map and the constant environment's irradiance (no occlusion:
    # the reference's sphere underside also sees the floor's mirror image, which the raster's
    # split sum takes as sky; that is the remaining error). Bound: 0.15 x the RMSE without any
    # reflection of the scene (the bound).
    scene = _scene(tmp_path, "mirror", mirror_floor(W, H, ssr=False))
    region = _reflected_region(scene)
    assert region.sum() > 40
    ref = _reference(scene, 64)
    out = {}
    for name, rt, ssr in (("none", False, False), ("ssr", False, True), ("raytrace", True, False)):
        scene.render.ssr = ssr
        img = _raster(renderer, scene, rt)
        out[name] = float(np.sqrt(np.mean((img[region] - ref[region]) ** 2)))
    scene.render.ssr = False
    # the sphere's underside: with raytrace_occlusion its diffuse environment term traces the
    # floor (a mirror: the sky it reflects, less the sphere's own image), which closes most of
    # what is left
    scene.render.raytrace_occlusion = True
    img = _raster(renderer, scene, True)
    out["occlusion"] = float(np.sqrt(np.mean((img[region] - ref[region]) ** 2)))
    scene.render.raytrace_occlusion = False
    print(f"mirror floor reflected region ({region.sum()} px) RMSE: no reflection {out['none']:.4f}, "
          f"SSR {out['ssr']:.4f}, ray traced {out['raytrace']:.4f}, with occlusion {out['occlusion']:.4f}")
    assert out["raytrace"] < 0.15 * out["none"]
    assert out["occlusion"] < out["raytrace"]


def absorbing_ball(radius, constant=(1.0, 1.0, 1.0)):
    """An absorbing glass ball of ``radius`` (sigma_a 0.5, 1.5, 3.0 per unit length) in a
    constant environment (white: a furnace)."""
    return scene(camera([0.0, 0.0, 4.0], [0.0, 0.0, 0.0], 30.0, W, H, up=[0.0, 1.0, 0.0]),
                 environment(constant=list(constant)),
                 render(ibl="split_sum"),
                 obj("sphere", "glass", scale=radius),
                 material("glass", model="dielectric", ior=1.5, sigma_a=[0.5, 1.5, 3.0]))


@pytest.mark.parametrize("radius", [0.3, 0.9])
def test_absorbing_glass_follows_bouguer(tmp_path, renderer, gl_ctx, radius):
    # (a) The central pixels, analytically: under a constant environment L the ray through the
    # centre runs along the diameter d = 2r and every internal reflection sends it back along
    # it; each arrival at the surface lets (1 - R) out into the environment, so
    # L_centre / L = R + (1 - R)^2 a / (1 - R a) with a = exp(-sigma_a d) and R the normal-
    # incidence Fresnel reflectance (0.04), a geometric series (sigma_a = 0 gives 1: glass in a
    # furnace is invisible; the chain's depth 8 cuts it after 6 traversals, < 1e-7 here). 0.5%
    # covers the 2 x 2 pixels' rays being up to 1.5 pixels off the axis (shorter chords).
    # (b) Over the whole sphere against the reference (two sizes: the colour deepens with the
    # path length): mean error < 3% per channel; both follow the chain exactly here.
    scene = _scene(tmp_path, f"abs{radius}", absorbing_ball(radius))
    img = _raster(renderer, scene, True)
    sigma = np.array([0.5, 1.5, 3.0])
    R = ((1.5 - 1.0) / (1.5 + 1.0)) ** 2
    a = np.exp(-sigma * 2.0 * radius)
    expect = R + (1 - R) ** 2 * a / (1 - R * a)
    centre = img[H // 2 - 1:H // 2 + 1, W // 2 - 1:W // 2 + 1].mean(axis=(0, 1))
    print(f"r = {radius}: centre {centre}, Bouguer series {expect}")
    np.testing.assert_allclose(centre, expect, rtol=5e-3)
    mask = _object_mask(gl_ctx, scene, 0)
    ref = _reference(scene, 32)
    err = np.abs(img[mask].mean(axis=0) - ref[mask].mean(axis=0)) / ref[mask].mean(axis=0)
    print(f"r = {radius}: per-channel error of the mean over the sphere {err}")
    assert np.all(err < 0.03)


@pytest.mark.parametrize("step", ["fresnel", "tir", "absorbing_glass"])
def test_raytrace_false_is_bit_identical(renderer, gl_ctx, step):
    # raytrace = false compiles no traced program and binds nothing new: the image equals a
    # renderer that never traced, bit for bit (also after traced frames on the same renderer).
    from viewer.gl.renderer import Renderer
    from viewer.scene.lecture import TOUR, tour_scene

    scene = tour_scene([s.key for s in TOUR].index(step))
    assert scene.render.raytrace  # these steps trace their glass; the test turns it off first
    scene.render.raytrace = False
    fresh = Renderer(gl_ctx)
    try:
        before = fresh.render_arrays(scene, width=48, height=32)[0]
    finally:
        fresh.release()
    scene.render.raytrace = True
    traced = renderer.render_arrays(scene, width=48, height=32)[0]
    scene.render.raytrace = False
    after = renderer.render_arrays(scene, width=48, height=32)[0]
    assert np.array_equal(before, after)
    assert not np.array_equal(traced, after)


def test_dispersion_traces_each_channel(tmp_path, renderer, monkeypatch):
    # One index per colour channel: each channel of the dispersive render equals that channel
    # of a render whose single index is that channel's (the chain traced per channel).
    import viewer.gl.raytrace as rtmod

    scene = _scene(tmp_path, "disp", absorbing_ball(0.6, constant=[0.3, 0.5, 0.8]))
    scene.render.raytrace = True
    single = {}
    for ior in (1.4, 1.5, 1.7):
        scene.materials["glass"]["ior"] = ior
        single[ior] = renderer.render_arrays(scene, width=32, height=32)[0]
    monkeypatch.setattr(rtmod, "chain_eta", lambda p: np.array([1.4, 1.5, 1.7]))
    from viewer.gl import program_set

    monkeypatch.setattr(program_set, "dispersive", lambda s: True)  # the forward variant's dispersion switch
    renderer.raytrace_state().invalidate_materials()  # rebuild the material rows with the new indices
    disp = renderer.render_arrays(scene, width=32, height=32)[0]
    for c, ior in enumerate((1.4, 1.5, 1.7)):
        np.testing.assert_allclose(disp[..., c], single[ior][..., c], atol=1e-5)
    assert not np.allclose(single[1.4], single[1.7])


@pytest.mark.parametrize("step, msaa", [("tir", 4), ("absorbing_glass", 0)])
def test_progressive_trace_equals_one_shot(renderer, gl_ctx, step, msaa):
    # The window's progressive trace ends with the untraced view (the view's MSAA) where no
    # traced chain starts and one traced frame without MSAA where one does (the mask), bit for
    # bit: each tile is a scissored traced frame (the scissor only discards pixels outside) and
    # the copy is of float32 texels. Before it is done every pixel shows the untraced view, its
    # half-resolution trace or its full trace: never a hole.
    from viewer.gl.raytrace import ProgressiveTrace
    from viewer.scene.lecture import TOUR, tour_scene

    scene = tour_scene([s.key for s in TOUR].index(step))
    assert renderer.traces(scene)
    w, h = 40, 30
    one_shot = renderer.read_linear(renderer.render(scene, None, w, h, msaa=0)).copy()
    plain0 = renderer.read_linear(renderer.render(scene, None, w, h, msaa=0, raytrace=False)).copy()
    untraced = renderer.read_linear(renderer.render(scene, None, w, h, msaa=msaa, raytrace=False)).copy()
    coarse = renderer.read_linear(renderer.render(scene, None, w // 2, h // 2, msaa=0)).copy()
    mask = renderer.traced_mask(scene, None, w, h)[::-1]  # row 0 = top, as read_linear
    # the mask is where tracing changes a frame: nowhere outside it, and at most pixels inside
    assert 0 < mask.sum() < mask.size
    assert np.array_equal(one_shot[~mask], plain0[~mask])
    assert np.mean(np.any(one_shot[mask] != plain0[mask], axis=-1)) > 0.5
    expected = np.where(mask[..., None], one_shot, untraced)
    coarse_up = np.repeat(np.repeat(coarse, 2, axis=0), 2, axis=1)
    lum = lambda a: a @ np.array([0.2126, 0.7152, 0.0722], np.float32)  # noqa: E731
    pt = ProgressiveTrace(gl_ctx)
    try:
        # tiles of a row at most (the trace grows its tiles from a 16-pixel probe)
        tex = pt.start(renderer, scene, None, w, h, msaa=msaa, rows=1, max_pixels=w)
        assert np.array_equal(renderer.read_linear(tex), untraced) and not pt.done
        seen_coarse = seen_partial = 0
        while not pt.done:
            pt.step(budget_s=1e-9)  # one tile at a time: tile edges everywhere
            img = pt.image()
            # every pixel is the untraced view, its half-resolution trace or its trace
            ok = (np.all(img == untraced, axis=-1) | np.all(img == one_shot, axis=-1)
                  | np.all(img == coarse_up, axis=-1))
            assert ok.all(), np.argwhere(~ok)[:5]
            # never black where neither the untraced nor the traced view is
            dark = lum(img) < 1e-4
            assert not np.any(dark & (lum(untraced) >= 1e-4) & (lum(one_shot) >= 1e-4))
            assert lum(img).min() >= min(lum(untraced).min(), lum(one_shot).min(), lum(coarse_up).min())
            seen_coarse += pt.coarse
            seen_partial += not pt.done
        assert seen_coarse > 0 and seen_partial > 4 and pt.steps > 5 and pt.progress == 1.0
        assert np.array_equal(pt.image(), expected)
        assert pt.elapsed_s >= pt.trace_s > 0
        pt.start(renderer, scene, None, w, h, msaa=msaa, coarse=False)
        pt.step(budget_s=1e9)  # tiles until done, in one step
        assert pt.done and np.array_equal(pt.image(), expected)
        pt.start(renderer, scene, None, w, h, msaa=msaa, coarse=False, max_pixels=1 << 22)
        pt.finish()  # the bake's way: a tile per run of blocks with traced pixels
        assert pt.steps <= 3 and np.array_equal(pt.image(), expected)
    finally:
        pt.release()


def test_raytrace_override_false_equals_raytrace_off(renderer):
    # render(raytrace=False), the window's preview while the view moves, is the untraced render
    from viewer.scene.lecture import TOUR, tour_scene

    scene = tour_scene([s.key for s in TOUR].index("fresnel"))
    forced = renderer.read_linear(renderer.render(scene, None, 32, 24, msaa=0, raytrace=False)).copy()
    scene.render.raytrace = False
    off = renderer.read_linear(renderer.render(scene, None, 32, 24, msaa=0))
    assert np.array_equal(forced, off)


def _bubble_over_bars(tmp_path, film_nm):
    """A soap bubble (ior 1, water film) over a black floor crossed by white bars, under a
    constant sky (seen in the film against the dark floor behind): film_nm 0 leaves an ior-1 shell, which lets everything through unchanged."""
    bars = "".join(obj("cube", "bar", scale=[1.6, 0.005, 0.1], translate=[0.0, 0.005, -0.6 + 0.32 * k])
                   for k in range(5))
    text = scene(camera([0.0, 1.4, 2.6], [0.0, 0.3, 0.0], 34.0, W, H, up=[0.0, 1.0, 0.0]),
                 environment(constant=[1.0, 1.0, 1.0]),
                 render(ibl="split_sum", raytrace=True),
                 obj("sphere", "bubble", scale=0.55, translate=[0.0, 0.6, 0.0]),
                 obj("plane", "floor", scale=4.0), bars,
                 material("bubble", preset="soap_bubble", thin_film={"ior": 1.33, "thickness_nm": film_nm}),
                 material("floor", model="lambert", albedo=[0.02, 0.02, 0.02]),
                 material("bar", model="lambert", albedo=[0.9, 0.9, 0.9]))
    return _scene(tmp_path, f"bubble{film_nm:g}", text)


def _chroma(v):
    v = np.asarray(v, np.float64)
    return v / v.sum()


def test_soap_bubble_shows_the_floor_through_and_the_film_colours(tmp_path, renderer, gl_ctx):
    # Traced, each face of the ior-1 shell reflects the film's RGB R and passes 1 - R straight on
    # (the dielectric's sampler and the reference do the same): inside the silhouette the bars
    # behind must show (correlation with the reference), dimmed by about (1 - R)^2 against the
    # bubble-less render, and the rim, where R rises, must carry the film's colour.
    scene = _bubble_over_bars(tmp_path, 400.0)
    mask = _object_mask(gl_ctx, scene, 0, erode=1)
    inner = _object_mask(gl_ctx, scene, 0, erode=5)
    rim = mask & ~inner
    ref = _reference(scene, 32)
    img = _raster(renderer, scene, True)
    bare = _raster(renderer, _bubble_over_bars(tmp_path, 0.0), True)
    lum = lambda a: a[..., :3] @ np.array([0.2126, 0.7152, 0.0722])  # noqa: E731
    corr = float(np.corrcoef(lum(img)[inner], lum(ref)[inner])[0, 1])
    corr_bare = float(np.corrcoef(lum(bare)[inner], lum(ref)[inner])[0, 1])
    mean_err = _rel_mean_error(img, ref, mask)
    ratio = float(lum(img)[inner].mean() / lum(bare)[inner].mean())
    ratio_ref = float(lum(ref)[inner].mean() / lum(bare)[inner].mean())
    c_img, c_ref, c_bare = (_chroma(a[rim].mean(axis=0)[:3]) for a in (img, ref, bare))
    print(f"bubble ({mask.sum()} px, rim {rim.sum()}): corr {corr:.3f} (bare shell {corr_bare:.3f}), mean err "
          f"{mean_err:.3f}, inside / bubble-less {ratio:.3f} (reference {ratio_ref:.3f}); rim chroma "
          f"{np.round(c_img, 4)} ref {np.round(c_ref, 4)} bare {np.round(c_bare, 4)}")
    # measured: corr 0.990, mean err 0.018, ratio 1.131 / 1.118, rim chroma within 0.0016 of the
    # reference's, which departs 0.012 from grey (an invisible shell: grey; an opaque one: no bars)
    assert corr > 0.95  # the bars behind; the reference's noise at 32 spp lowers it a little
    assert mean_err < 0.05  # the floor is shaded the raster's way (no occlusion of the sky)
    assert abs(ratio - ratio_ref) < 0.03
    assert np.abs(c_ref - 1.0 / 3.0).max() > 0.008  # the scene does show the film's colour
    assert np.abs(c_img - c_ref).max() < 0.004  # a third of that departure


def test_a_scenes_bvh_is_built_once_then_read_from_the_disk_cache(monkeypatch):
    """The flattened BVH (what ``SceneTextures`` uploads) is read back from the disk cache for
    the same triangles, equal to the build that stored it; other triangles are built anew."""
    import dataclasses as dc

    import viewer.geometry.bvh_flat as bvh_flat
    from viewer.geometry.soup import build_geometry
    from viewer.gl.raytrace import cached_flat_scene
    from viewer.scene import load_scene

    full = build_geometry(load_scene("default"))
    n = 1500  # a part of it: quick to build; moved so that no other test's entry matches
    geom = dc.replace(full, **{f: getattr(full, f)[:n] for f in ("triangles", "geo_normals", "normals", "tangents",
                                                                   "object_index", "material_index")})
    geom = dc.replace(geom, triangles=geom.triangles + 0.123)
    built = []
    real = bvh_flat.flatten_scene
    monkeypatch.setattr(bvh_flat, "flatten_scene", lambda g: built.append(1) or real(g))
    first = cached_flat_scene(geom)
    again = cached_flat_scene(geom)
    assert built == [1]  # built once, then read
    for name in ("nodes", "tris", "shading", "prim_id"):
        assert np.array_equal(getattr(again, name), getattr(first, name)), name
    assert (again.n_nodes, again.n_triangles, again.depth) == (first.n_nodes, first.n_triangles, first.depth)
    cached_flat_scene(dc.replace(geom, triangles=geom.triangles + 0.5))
    assert built == [1, 1]  # other triangles: built
