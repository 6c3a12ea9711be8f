"""Every built-in scene and lecture step: the raster as the window shows it once the view is still
(a traced frame where the scene says ``raytrace = true``, its MSAA, SSR in one frame) against the
CPU reference (max depth 8, the window's), at 64 x 48 and 16 spp; ``-m slow`` repeats it at
160 x 96 and 128 spp. Figures (``viewer.image.compare.agreement``): the image's mean relative
difference and the 90th percentile of the 8 x 8 blocks' relative differences.

Each scene's tolerance stands beside it with its reason: what the rasterizer does not do
(light between objects, occlusion of the environment) and by how much, measured; the
reference's own noise at 16 spp is about 3% per block on diffuse scenes and more where a
small bright source is seen through glass. The reference is deterministic for a seed, so the
figures do not move between runs. ``benchmarks/scenes_vs_reference.py`` prints the same table.

Where a scene shows the sun through smooth glass (``SUN_GLINTS``) the pixels the reference has not
resolved (its estimate rests on about one sample) are named, counted and left out of the figures."""

import numpy as np
import pytest

from viewer.scene.camera import OrbitCamera
from viewer.image.compare import agreement
from viewer.scene import load_scene

pathtracer = pytest.importorskip("viewer.pathtracer")

SMALL = (64, 48, 16)
LARGE = (160, 96, 128)

# name: (mean rel, block p90, why the raster differs); measured at 64 x 48 / 16 spp in brackets
TOLERANCE = {
    "sphere": (0.02, 0.06, "one Lambert-ish ball in a constant sky, direct light and split sum: the "
               "reference's noise only [0.008 / 0.026]"),
    "default": (0.08, 0.30, "no light bounced from the floor onto the objects and no occlusion of the "
                "environment under them [0.050 / 0.201]"),
    "gallery": (0.08, 0.30, "as default, over several objects; its mirror and glass traced (the "
                "scene opens traced) [0.018 / 0.072; 0.047 / 0.196 when it opened untraced]"),
    "cornell": (0.45, 0.90, "a closed box: light bounced between the walls is about 40% of the image, "
                "which the raster leaves out (it keeps the direct light and the constant ambient) "
                "[0.394 / 0.826]"),
    "cornell_glossy": (0.45, 0.90, "as cornell; SSR shows the glossy walls' reflections of what is on "
                       "screen [0.372 / 0.831; 0.422 / 0.816 at 160 x 96]"),
    "reflective_floor": (0.12, 0.65, "the studio's bright panels mirrored by the floor: 16 spp of them "
                         "are noisy blocks; SSR reflects only what is on screen (the objects' backs "
                         "and the floor under them are missing), no light between objects "
                         "[0.093 / 0.550]"),
    "soap_bubble": (0.06, 0.25, "traced ior-1 shells with the film's RGB R on both faces (the floor "
                    "seen through with 1 - R): the floor is shaded the raster's way (no occlusion of "
                    "the environment), 16 spp of the studio's panels in the films [0.040 / 0.183; "
                    "0.178 / 0.605 untraced, opaque shells]"),
    "soap_bubble/untraced": (0.06, 0.27, "the same shells drawn over the frame with dual-source "
                             "blending (1 - R of what lies behind, plus R of what each face's mirror "
                             "ray meets: the floor, as an analytic plane shaded the raster's way, or "
                             "the environment); no second pass through the shell for a far face's "
                             "reflection, 16 spp of the studio's panels [0.042 / 0.202; 0.074 / 0.378 "
                             "when the faces reflected the environment's dark floor in place of the "
                             "scene's, 0.178 / 0.605 when the shells were opaque]"),
    "lecture:1": (0.07, 0.15, "no light from the floor onto the ball, no occlusion of the dim "
                  "environment at the contact [0.041 / 0.086]"),
    "lecture:2": (0.06, 0.25, "traced glass: the floor's light seen through and in the glass is the "
                  "raster's diffuse floor shading; 16 spp of refracted sky [0.031 / 0.164]"),
    "lecture:3": (0.05, 0.25, "traced glass cube, as step 2 [0.020 / 0.159]"),
    "lecture:4": (0.05, 0.12, "as step 1 [0.022 / 0.057]"),
    "lecture:5": (0.07, 0.25, "as step 1, two balls that light each other in the reference [0.043 / 0.157]"),
    "lecture:6": (0.12, 0.25, "a light behind the camera: the floor and the two balls light each other "
                  "strongly in the reference [0.087 / 0.169]"),
    "lecture:7": (0.10, 0.22, "a light behind the camera, as step 6: the floor and the two balls light "
                  "each other in the reference [0.064 / 0.122]"),
    "lecture:8": (0.04, 0.10, "as step 1 [0.016 / 0.040]"),
    "lecture:9": (0.03, 0.20, "split-sum coat over a glossy base under the studio map: the prefiltered "
                  "environment against the exact lobe [0.000 / 0.118]"),
    "lecture:10": (0.06, 0.30, "traced absorbing glass, as step 2 [0.030 / 0.217]"),
    "lecture:11": (0.13, 0.15, "traced metals: the floor they mirror is shaded the raster's way (no "
                   "light bounced from the balls onto it) [0.066 / 0.083; 0.11 / 0.09 at 160 x 96]"),
    "lecture:12": (0.05, 0.25, "traced dispersion with one index per channel against the spectral "
                   "reference; lit from behind, so no bar seen through the prism lies in its shadow, "
                   "which the raster draws where the straight ray lands, not where the prism bends "
                   "the light [0.022 / 0.178; 0.087 / 0.200 with the light in front; 0.027 / 0.205 at "
                   "160 x 96 with the sun's glints left out (SUN_GLINTS), 0.082 / 0.193 with them]"),
    "lecture:13": (0.06, 0.25, "traced soap bubbles, as soap_bubble [0.044 / 0.178]"),
    "lecture:13/untraced": (0.07, 0.20, "untraced soap bubbles, as soap_bubble/untraced [0.050 / 0.142; "
                            "0.076 / 0.220 with the environment's dark floor reflected, the bubbles' "
                            "upper halves dark; 0.175 / 0.615 in an earlier record, from before the shell pass]"),
    "lecture:14": (0.10, 0.45, "glossy gold (alpha 0.15) under the studio map: the split sum's "
                   "prefiltered lights against the lobe's exact reflection of them [0.064 / 0.369]"),
    "lecture:15": (0.05, 0.25, "a .brdf file beside the built-in microfacet, one point light and no "
                   "environment: the floor's light on the balls' undersides and the soft contact "
                   "shadows, which the raster leaves out, and 16 spp on the lit floor [0.025 / 0.158]"),
}

# Scenes whose reference sees the sun (0.53 deg, 1e6 times the sky) through a smooth dielectric over a
# small part of a pixel: a glint the raster, which shades pixel centres, does not draw, and which a
# few hundred samples of the pixel see 0 or 1 times, so the one pixel's estimate is off by many times
# its value. Those pixels (relative standard error of the reference's mean at least
# UNRESOLVED_REL_ERR: about one sample carries the pixel) at least MIN_TIMES_MEAN times the
# image's mean are left out of both images, at most MAX_UNRESOLVED of them; the rest of the scene
# keeps its tolerance.
SUN_GLINTS = {
    "lecture:12": "at 160 x 96 the sun is seen in the diamond ball over 3% of pixel (row 44, col 103): "
                  "7.8 (mean of RGB) traced analytically on a 1000 x 1000 grid of the pixel (one index "
                  "per channel, Fresnel at every face), 7.2 from 204,800 reference samples of it, 0.047 "
                  "without the sun (the raster: 0.047), 1.3% of the image's sum. Seed 1's 128 samples "
                  "put one on it: 62.3, 10% of the image's sum (mean rel 0.082 with it, 0.027 without). "
                  "Pixel (row 70, col 122), the black floor right of the ball: a path from the floor "
                  "through the ball to the sun (its caustic), 1.4 from one sample of 128, 0.003 from "
                  "102,400 samples of the pixel",
}
UNRESOLVED_REL_ERR = 0.9   # one sample of k carrying a pixel: 1 / sqrt(k) (1.0 for k = 1, 0.71 for 2)
MAX_UNRESOLVED = 4         # more is not a glint: a broken region the test must see
MIN_TIMES_MEAN = 20.0      # unresolved pixels under 20 times the image's mean stay in: at 16 spp the
                           # bars seen through the prism, one wavelength a sample, are 1-6 times it

# The default suite runs these (what they guard: traced glass under MSAA on step 2, block p90
# 0.299 before its fix; the single-lobe steps' lighting on 1 and 4; SSR on reflective_floor,
# though at this size the old SSR is within its noise: tests/test_ssr.py's ball on a mirror
# floor is SSR's own check); the rest cost 10-70 s each,
# mostly compiling their programs, and run with -m slow.
# (soap_bubble/untraced and lecture:13/untraced run with -m slow: tests/test_thin_shell.py checks
# the untraced shells against analytic truths in the default run)
FAST = ("sphere", "lecture:1", "lecture:2", "lecture:4", "reflective_floor")
SCENES = tuple(TOLERANCE)
# "scene/variant": the scene with a switch the window offers turned the other way
VARIANTS = {"untraced": ("render.raytrace=false",)}


def _marks(name, slow):
    marks = []
    if slow:
        marks.append(pytest.mark.slow)
    return marks


def _compare(renderer, name, size):
    w, h, spp = size
    base, _, variant = name.partition("/")
    scene = load_scene(base, overrides=VARIANTS[variant] if variant else ())
    raster = renderer.render_arrays(scene, width=w, height=h)[0]
    ref = pathtracer.ReferenceRenderer(scene, camera=OrbitCamera.from_scene(scene), width=w, height=h,
                                       max_depth=8, seed=1, workers=2)
    try:
        ref.step(spp)
        mean = ref.mean()
        variance = ref.variance()
    finally:
        ref.close()
    if base in SUN_GLINTS:
        mean = _without_unresolved(name, raster, mean, variance)
    g = agreement(raster, mean)
    tol_mean, tol_p90, why = TOLERANCE[name]
    print(f"{name} {w}x{h} {spp} spp: mean rel {g['mean_rel']:.3f} (< {tol_mean}), block p90 "
          f"{g['block_p90']:.3f} (< {tol_p90}): {why}")
    return g, tol_mean, tol_p90


def _without_unresolved(name, raster, mean, variance):
    """The reference with its unresolved pixels that matter (see ``SUN_GLINTS``) replaced by the
    raster's, so that they count in neither image; prints each one and asserts there are few."""
    # the RGB vector's relative standard error: exactly 1 for a pixel one sample carries, whatever
    # its colour (a single wavelength's RGB has negative channels)
    norm = np.sqrt((np.asarray(mean, np.float64) ** 2).sum(axis=-1))
    rel = np.sqrt(np.maximum(variance, 0.0).sum(axis=-1)) / np.maximum(norm, 1e-12)
    lum = mean.mean(axis=-1)
    share = lum / max(float(lum.sum()), 1e-12)
    out = (rel >= UNRESOLVED_REL_ERR) & (lum >= MIN_TIMES_MEAN * float(lum.mean()))
    print(f"{name}: {SUN_GLINTS[name.partition('/')[0]]}")
    for r, c in np.argwhere(out):
        print(f"  pixel (row {r}, col {c}) left out: reference {mean[r, c].mean():.3f} (rel. std. error "
              f"{rel[r, c]:.2f}, {share[r, c]:.1%} of the image's sum), raster {raster[r, c].mean():.3f}")
    assert out.sum() <= MAX_UNRESOLVED, f"{name}: {int(out.sum())} pixels unresolved in the reference"
    return np.where(out[..., None], raster, mean)


@pytest.mark.parametrize("name", [pytest.param(n, marks=_marks(n, n not in FAST)) for n in SCENES])
def test_scene_agrees_with_reference(renderer, name):
    g, tol_mean, tol_p90 = _compare(renderer, name, SMALL)
    assert g["mean_rel"] < tol_mean
    assert g["block_p90"] < tol_p90


@pytest.mark.slow  # 160 x 96 at 128 spp: minutes per traced or spectral scene on two cores
@pytest.mark.parametrize("name", [pytest.param(n, marks=_marks(n, False)) for n in SCENES])
def test_scene_agrees_with_reference_large(renderer, name):
    g, tol_mean, tol_p90 = _compare(renderer, name, LARGE)
    assert g["mean_rel"] < tol_mean
    assert g["block_p90"] < tol_p90


def test_every_built_in_scene_and_lecture_step_has_a_tolerance():
    """A new scene or step joins the comparison (a regression hides between the scenes)."""
    from viewer.scene import builtin_scene_names, lecture_scene_names

    assert set(builtin_scene_names()) | set(lecture_scene_names()) <= set(TOLERANCE)



def test_unresolved_pixels_left_out_are_one_sample_glints_only():
    """The exclusion takes a bright pixel one sample carries, keeps a converged bright one and a dim
    one-sample one, and refuses a row of them (synthetic sums of 128 samples, 64 x 48)."""
    n = 128
    mean = np.full((48, 64, 3), 0.05)
    variance = (0.05 * 0.2) ** 2 / n * np.ones((48, 64, 3))   # a converged image: 2% error
    mean[1, 2], variance[1, 2] = 60.0, 60.0 ** 2              # one sample of 128 at 7680
    mean[3, 3], variance[3, 3] = 60.0, (60.0 * 0.1) ** 2      # as bright, resolved: 10% error
    mean[5, 5], variance[5, 5] = 0.5, 0.5 ** 2                # one sample, too dim to matter
    raster = np.full((48, 64, 3), 0.04)
    out = _without_unresolved("lecture:12", raster, mean, variance)
    assert np.argwhere(out.mean(axis=-1) != mean.mean(axis=-1)).tolist() == [[1, 2]]
    assert out[1, 2].tolist() == raster[1, 2].tolist()
    mean[6, :5], variance[6, :5] = 60.0, 60.0 ** 2
    with pytest.raises(AssertionError, match="unresolved"):
        _without_unresolved("lecture:12", raster, mean, variance)
