"""The lecture tour: the examples of the course (Frisvad, "BRDF, Fresnel Reflectance, and
Absorption"), one scene each with a one-line caption saying what to notice.

The window steps through them with the number and arrow keys (lecture mode); ``tour_scene(i)``
builds the same scenes anywhere (tests render every step offscreen). Each step is a complete
scene in the scene-file TOML format, built from the lecture presets of ``viewer.brdf.presets``,
so what the tour shows is exactly what a student gets by loading that TOML.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Step:
    key: str          # short id, e.g. "fresnel"
    title: str        # shown large
    caption: str      # one line: what to notice
    toml: str         # the scene
    plot: str = ""    # the plot kind that goes with it ("fresnel", "polar", ...), may be empty
    image: str = ""   # the image mode the window switches to ("reference", ...), may be empty


def _camera(pos=(0.0, 0.9, 4.2), target=(0.0, 0.6, 0.0), fov=36.0) -> str:
    return (f"[camera]\nposition = {list(pos)}\ntarget = {list(target)}\nup = [0.0, 1.0, 0.0]\n"
            f"fov_y = {fov}\nwidth = 960\nheight = 540\n")


_FLOOR = '[[objects]]\nmesh = "plane"\nmaterial = "floor"\nscale = 6.0\n'
# 80 m across: what a clear shell shows through and mirrors below the horizon is this floor, not the
# studio map's dark floor beyond the edge of a 12 m one (a dark band across each bubble's middle)
_WIDE_FLOOR = '[[objects]]\nmesh = "plane"\nmaterial = "floor"\nscale = 40.0\n'
_FLOOR_MAT = '[materials.floor]\nmodel = "lambert"\nalbedo = [0.5, 0.5, 0.5]\n'
# under the studio map and the key light together a 0.5 floor reads 0.86-0.97 (near white, where
# the caption lies over it): a darker grey keeps it well under white
_GREY_FLOOR_MAT = '[materials.floor]\nmodel = "lambert"\nalbedo = [0.25, 0.25, 0.25]\n'
# under the bright lights of the highlight steps: a dark floor, so the ball is the brightest thing
_DARK_FLOOR_MAT = '[materials.floor]\nmodel = "lambert"\nalbedo = [0.06, 0.06, 0.06]\n'
_KEY_LIGHT = '[[lights]]\ntype = "point"\nposition = [-2.0, 4.0, 3.0]\nintensity = [30.0, 30.0, 30.0]\n'
# the prism narrowed to a 30 degree apex (a 60 degree SF11 prism totally reflects a level view at
# its back face): it bends the view about 27 degrees down, red and blue 2.4 degrees apart, onto
# the floor behind it, where these white bars lie across a black floor (edges of high contrast);
# 2 m long, reaching left past where the bent view through the prism's upper left lands (x = -1.67;
# with bars 1.6 m long a wedge of its face saw the bare floor beside them), no farther (the diamond
# shows what lies around it, the more bars the more coloured glints there)
# step 12's light: above and behind the prism, so its shadow falls in front of it, on the bare
# floor, and no bar seen through it lies in it. Under the key light (in front, left) the shadow
# covered the bars behind the prism's right half: the reference showed them dark there (the light
# the prism bends lands elsewhere; with the photon integrator's caustics too) while the raster's
# glass shadow, drawn where the straight ray meets the floor, lit them: mean 0.087 apart at 64 x 48.
# Half the key light's intensity: nearer the bars and more overhead, 30 W/sr put 1.95 times the
# irradiance on them, and 5% of the frame clipped at white
_PRISM_LIGHT = '[[lights]]\ntype = "point"\nposition = [-2.0, 4.0, -3.0]\nintensity = [15.0, 15.0, 15.0]\n'
_BLACK_FLOOR_MAT = '[materials.floor]\nmodel = "lambert"\nalbedo = [0.02, 0.02, 0.02]\n'
_BARS = "".join(f'[[objects]]\nmesh = "cube"\nmaterial = "bar"\nscale = [1.0, 0.005, 0.025]\n'
                f"translate = [-0.8, 0.005, {-0.35 - 0.15 * k:.2f}]\n" for k in range(10))
# just above and left of the camera: the mirror direction lands on the ball's front, so the
# highlight sits where the audience looks
_HIGHLIGHT_LIGHT = '[[lights]]\ntype = "point"\nposition = [-0.8, 2.2, 4.0]\nintensity = [120.0, 120.0, 120.0]\n'
# behind the camera, between the two balls: both highlights face the viewer at the same angle
_RETRO_LIGHT = '[[lights]]\ntype = "point"\nposition = [0.0, 1.6, 5.6]\nintensity = [70.0, 70.0, 70.0]\n'
_TAIL_LIGHT = '[[lights]]\ntype = "point"\nposition = [0.0, 1.4, 5.0]\nintensity = [400.0, 400.0, 400.0]\n'


def _sphere(material: str, x: float = 0.0, r: float = 0.6, y: float | None = None) -> str:
    y = r if y is None else y
    return (f'[[objects]]\nmesh = "sphere"\nmaterial = "{material}"\nscale = {r}\n'
            f"translate = [{x}, {y}, 0.0]\n")


def _env(spec: str) -> str:
    return f"[environment]\n{spec}\n"


def _render(ibl: str = "split_sum", ssr: bool = False, raytrace: bool = False, exposure: float = 0.0,
            tonemap: str = "none") -> str:
    rt = "raytrace = true\n" if raytrace else ""
    tm = f'exposure = {exposure}\ntonemap = "{tonemap}"\n' if exposure or tonemap != "none" else ""
    return f'[render]\nibl = "{ibl}"\nssr = {str(ssr).lower()}\nshadows = true\nmsaa = 4\n{rt}{tm}'


def _mat(name: str, preset: str, **extra) -> str:
    lines = [f"[materials.{name}]", f'preset = "{preset}"']
    for k, v in extra.items():
        lines.append(f"{k} = {v!r}".replace("'", '"'))
    return "\n".join(lines) + "\n"


def _scene(*parts: str) -> str:
    return "\n".join(parts)


_DIM = _env("constant = [0.08, 0.08, 0.09]")
_STUDIO = _env('map = "studio"\nintensity = 1.0')
# the sky model is in cd/m^2 (thousands): scaled so the horizon reads about 0.3 (EV 0)
_SKY = _env('map = "sky"\nintensity = 0.006')
# the steps lit by that sky alone (no lamp): +3 EV, so on a projector the brightest sky and glass
# read near 200/255 (at EV 0 they read 77); nothing in them reaches white at that exposure, so
# no tone map is needed and the image stays linear (4% against 100% stays 1:25)
_SKY_EV = 3.0


# what the raster leaves out where smooth surfaces bend or mirror light onto others (steps 2, 3, 10,
# 11, 13): its shadows let light through glass (Fresnel and Bouguer) but do not focus it
_NO_CAUSTICS = " Raster: no caustics (light focused by smooth surfaces; reference only)."


def _one_ball(preset: str) -> str:
    """One sphere of ``preset`` on the floor under the key light and dim surroundings (a constant
    0.08 that lights the raster too, as it lights the reference): the setting of the single-lobe
    steps."""
    return _scene(_camera(), _DIM, _render("split_sum"), _KEY_LIGHT, _FLOOR, _sphere("ball"), _FLOOR_MAT,
                  _mat("ball", preset))


TOUR: tuple[Step, ...] = (
    Step("lambert", "Lambert",
         "Perfectly diffuse: the same radiance toward every viewer; shading follows cos(theta_i) alone.",
         _one_ball("lecture_lambert"), "polar"),
    Step("fresnel", "Mirror and glass with Fresnel",
         "Air-glass n = 1.5: 4% reflected head-on, 100% at grazing angles (the black glass's rims). "
         "The clear ball refracts what lies behind it: floor and sky upside down."
         + _NO_CAUSTICS,
         _scene(_camera(), _SKY, _render("split_sum", raytrace=True, exposure=_SKY_EV), _FLOOR,
                _sphere("black_glass", -0.75),
                _sphere("glass", 0.75), _FLOOR_MAT,
                '[materials.black_glass]\nmodel = "mirror"\nfresnel = "dielectric"\nior = 1.5\n',
                _mat("glass", "lecture_air_glass")), "fresnel"),
    Step("tir", "Total internal reflection",
         "Inside glass past the critical angle asin(1/1.5) = 41.8 deg all light reflects: the bottom "
         "turns into a mirror, the near faces' lower half showing the sky."
         + _NO_CAUSTICS,
         _scene(_camera((0.0, 1.9, 3.2), (0.0, 0.45, 0.0)), _SKY,
                _render("split_sum", raytrace=True, exposure=_SKY_EV), _FLOOR,
                '[[objects]]\nmesh = "cube"\nmaterial = "glass"\nscale = 0.55\n'
                'translate = [0.0, 0.56, 0.0]\nrotate_y_deg = 35.0\n',
                _FLOOR_MAT, _mat("glass", "lecture_air_glass")), "fresnel"),
    Step("torrance_sparrow", "Torrance-Sparrow with a Blinn-Phong distribution",
         "Microfacets: D (Blinn-Phong), V-cavity shadowing G and Fresnel F shape the white highlight; "
         "the dark blue is the diffuse base under it.",
         _scene(_camera(), _DIM, _render("split_sum"), _HIGHLIGHT_LIGHT, _FLOOR, _sphere("ball"), _DARK_FLOOR_MAT,
                _mat("ball", "lecture_torrance_sparrow_blinn", kd=[0.04, 0.06, 0.14])), "polar"),
    Step("beckmann_ggx", "Beckmann (left) against GGX (right)",
         "Same alpha = 0.2, black base so only the lobe shows: GGX's long tail spreads a glow far around "
         "its highlight; Beckmann's falls off to black within a few degrees.",
         _scene(_camera(), _env("constant = [0.02, 0.02, 0.025]"), _render("split_sum", exposure=1.5, tonemap="reinhard"),
                _TAIL_LIGHT, _FLOOR,
                _sphere("beckmann", -0.75), _sphere("ggx", 0.75), _DARK_FLOOR_MAT,
                _mat("beckmann", "lecture_beckmann", kd=[0.0, 0.0, 0.0]),
                _mat("ggx", "lecture_ggx", kd=[0.0, 0.0, 0.0])), "polar"),
    Step("oren_nayar", "Oren-Nayar (left) against Lambert (right)",
         "Lit from behind the viewer, rough clay looks flat (backscatter); Lambert darkens toward the rim.",
         _scene(_camera(), _DIM, _render("split_sum"),
                '[[lights]]\ntype = "point"\nposition = [0.0, 1.2, 6.0]\nintensity = [60.0, 60.0, 60.0]\n',
                _FLOOR, _sphere("oren_nayar", -0.75), _sphere("lambert", 0.75), _FLOOR_MAT,
                _mat("oren_nayar", "lecture_oren_nayar"), _mat("lambert", "lecture_lambert")), "polar"),
    # the lamp just behind and above the camera: light returns toward it, so the retro lobe
    # (C = 0.7, n = 5: 0.7^5 = 0.17 /sr back along wi) adds more than the base's kd / pi =
    # 0.13 /sr to every pixel of the left ball; the forward lobe's highlight lands near its centre
    Step("lafortune", "Lafortune's generalized cosine lobes (left) against their diffuse base (right)",
         "Lit from behind the viewer: the retro-reflective lobe sends the light back, so the left ball "
         "is over twice as bright as its diffuse base alone (right, Lambert, same kd), out to the rim; "
         "the forward lobe adds the highlight.",
         _scene(_camera(), _DIM, _render("split_sum"), _RETRO_LIGHT, _FLOOR,
                _sphere("lafortune", -0.75), _sphere("lambert", 0.75), _FLOOR_MAT,
                _mat("lafortune", "lecture_lafortune"),
                '[materials.lambert]\nmodel = "lambert"\nalbedo = [0.4, 0.3, 0.2]\n'), "polar"),
    Step("ashikhmin_shirley", "Ashikhmin-Shirley anisotropy",
         "n_u = 10, n_v = 1000: the highlight stretches across the tangent direction, as on brushed metal.",
         _one_ball("lecture_ashikhmin_shirley"), "lobe"),
    Step("layered", "Weidlich-Wilkie layered coat",
         "A clear coat over a coloured base: a sharp Fresnel reflection on top of a glossy, tinted layer.",
         _scene(_camera(), _STUDIO, _render("split_sum"), _KEY_LIGHT, _FLOOR, _sphere("ball"), _GREY_FLOOR_MAT,
                _mat("ball", "lecture_layered")), "albedo"),
    Step("absorbing_glass", "Absorbing glass (Bouguer / Beer-Lambert)",
         "Transmittance exp(-sigma_a d) over each traced path: the floor and sky through the big sphere "
         "come out a deeper green than through the small one."
         + _NO_CAUSTICS,
         _scene(_camera(), _SKY, _render("split_sum", raytrace=True, exposure=_SKY_EV), _FLOOR,
                _sphere("glass_big", -0.6, 0.7),
                _sphere("glass_small", 0.9, 0.3), _FLOOR_MAT, _mat("glass_big", "lecture_absorbing_glass"),
                _mat("glass_small", "lecture_absorbing_glass")), "bouguer"),
    Step("complex_ior", "Complex IOR: gold, silver, copper",
         "n + i k per wavelength (Johnson & Christy 1972): gold and copper absorb the blue end, silver "
         "reflects all; their colours show in the white floor each one mirrors." + _NO_CAUSTICS,
         _scene(_camera(fov=40.0), _SKY, _render("split_sum", raytrace=True), _KEY_LIGHT, _FLOOR,
                _sphere("gold", -1.3, 0.55), _sphere("silver", 0.0, 0.55), _sphere("copper", 1.3, 0.55),
                '[materials.floor]\nmodel = "lambert"\nalbedo = [0.8, 0.8, 0.8]\n',
                _mat("gold", "polished_gold"), _mat("silver", "polished_silver"),
                _mat("copper", "polished_copper")), "spectral"),
    Step("dispersion", "Dispersion: a flint prism and a diamond",
         "n(lambda) falls with wavelength (SF11: 1.83 at 420 nm, 1.77 at 680 nm): blue bends most. "
         "Through the prism the white bars on the black floor behind it split into rainbow bands; "
         "the raster traces each colour channel with its own n.",
         _scene(_camera((0.0, 0.8, 3.6), (0.0, 0.5, 0.0), 36.0), _SKY,
                # +1.5 EV: the black floor leaves the bars and the sky the brightest things
                _render("split_sum", raytrace=True, exposure=1.5),
                _PRISM_LIGHT, _FLOOR,
                # 1 cm above the floor, as the TIR cube: a base face in the floor's plane made every
                # ray leaving through it hit the prism or the floor at the same distance, a band of
                # speckle in both renderers
                '[[objects]]\nmesh = "prism"\nmaterial = "flint"\nscale = [0.28, 0.6, 0.5]\n'
                'translate = [-0.6, 0.31, 0.0]\nrotate_y_deg = 90.0\n',
                _BARS, _sphere("diamond", 0.7, 0.45), _BLACK_FLOOR_MAT,
                '[materials.bar]\nmodel = "lambert"\nalbedo = [0.9, 0.9, 0.9]\n',
                '[materials.flint]\nmodel = "dielectric"\nspectral = "SF11"\n',
                '[materials.diamond]\nmodel = "dielectric"\nspectral = "diamond"\n'), "spectral"),
    Step("soap_bubble", "Soap bubbles: thin-film interference",
         "Water films in air: light reflected at a film's two faces interferes, the colour shifting with "
         "angle. Clear shells (ior 1, no refraction): the floor shows through."
         + _NO_CAUSTICS,
         _scene(_camera(), _STUDIO, _render("split_sum", raytrace=True), _WIDE_FLOOR, _sphere("bubble", -0.75, 0.6, 0.8),
                _sphere("thin", 0.75, 0.6, 0.8), _FLOOR_MAT, _mat("bubble", "lecture_soap_bubble"),
                _mat("thin", "lecture_soap_bubble") + "thin_film = { ior = 1.33, thickness_nm = 250.0 }\n"), "fresnel"),
    # The variances in the caption: per-sample variance averaged over the image at 256 spp
    # (test_strategies measures the same scene and checks them): MIS 1.27, BSDF alone 3.51,
    # light alone 4.35.
    Step("importance_sampling", "Importance sampling: BSDF, light and MIS",
         "Glossy gold under the studio map, raster left, reference right. Press S to switch the reference "
         "between MIS, BSDF sampling alone (2.8x the variance of MIS) and light sampling alone (3.4x): "
         "watch the speckle.",
         _scene(_camera((0.0, 0.0, 3.2), (0.0, 0.0, 0.0), 40.0), _STUDIO, _render("split_sum"),
                '[[objects]]\nmesh = "sphere"\nmaterial = "ball"\n',
                _mat("ball", "gold", alpha=0.15)), "sampling", "split"),
    # A BRDF Explorer file beside the built-in model it writes out: viewer/brdfs/cooktorrance.brdf
    # (relative to the built-in scenes' folder, where lecture steps resolve their files)
    Step("brdf_file", "Your own BRDF: a .brdf file",
         "Left: a textbook Cook-Torrance in one text file, opened at run time (Beckmann D, V-cavity G, Fresnel "
         "for ior 1.5). Right: the built-in microfacet with the same choices, the same ball. brdf-viewer check grades it.",
         # no environment (a file BRDF's environment light is importance sampled, noisy in one
         # frame), so the raster and the reference see the same light: the point light alone; seen
         # from above, the balls stand against the lit floor
         _scene(_camera((0.0, 2.6, 3.6), (0.0, 0.45, 0.0)), _env("constant = [0.0, 0.0, 0.0]"), _render("off", tonemap="reinhard"),
                '[[lights]]\ntype = "point"\nposition = [0.0, 5.0, 3.0]\nintensity = [250.0, 250.0, 250.0]\n', _FLOOR,
                _sphere("file", -0.75), _sphere("builtin", 0.75),
                _FLOOR_MAT,
                '[materials.file]\nmodel = "custom"\nfile = "../brdfs/cooktorrance.brdf"\nm = 0.3\nior = 1.5\n',
                '[materials.builtin]\nmodel = "microfacet"\ndistribution = "beckmann"\nshadowing = "v_cavity"\n'
                'fresnel = "dielectric"\nior = 1.5\nalpha = 0.3\nkd = [0.0, 0.0, 0.0]\n'), "polar", "raster"),
)


def step_label(index: int) -> str:
    """How step ``index`` (0-based) is named in messages: ``<lecture 3: tir>``."""
    i = index % len(TOUR)
    return f"<lecture {i + 1}: {TOUR[i].key}>"


def tour_scene(index: int, load_meshes: bool = True, overrides=()):
    """The tour's step ``index`` (0-based) as a validated ``Scene``, ``overrides`` (``--set``)
    applied; the built-in scene name ``lecture:{index + 1}`` (``viewer.scene.load_scene``) is
    this scene."""
    from viewer.base.resources import SCENE_DIR
    from viewer.scene.parse import parse_scene
    from viewer.scene.validation import loads_toml

    i = index % len(TOUR)
    data = loads_toml(TOUR[i].toml, step_label(i))
    return parse_scene(data, None, overrides, label=step_label(i), base_dir=SCENE_DIR, load_meshes=load_meshes)
