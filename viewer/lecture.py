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
_FLOOR_MAT = '[materials.floor]\nmodel = "lambert"\nalbedo = [0.5, 0.5, 0.5]\n'
_KEY_LIGHT = '[[lights]]\ntype = "point"\nposition = [-2.0, 4.0, 3.0]\nintensity = [30.0, 30.0, 30.0]\n'


def _sphere(material: str, x: float = 0.0, r: float = 0.6, y: float | None = None) -> str:
    y = r if y is None else y
    return (f'[[objects]]\nmesh = "sphere"\nmaterial = "{material}"\nscale = {r}\n'
            f"translate = [{x}, {y}, 0.0]\n")


def _env(spec: str) -> str:
    return f"[environment]\n{spec}\n"


def _render(ibl: str = "split_sum", ssr: bool = False, raytrace: bool = False) -> str:
    rt = "raytrace = true\n" if raytrace else ""
    return f'[render]\nibl = "{ibl}"\nssr = {str(ssr).lower()}\nshadows = true\nmsaa = 4\n{rt}'


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


def _one_ball(preset: str) -> str:
    """One sphere of ``preset`` on the floor under the key light, dim surroundings, no IBL: the
    setting of the single-lobe steps."""
    return _scene(_camera(), _DIM, _render("off"), _KEY_LIGHT, _FLOOR, _sphere("ball"), _FLOOR_MAT,
                  _mat("ball", preset))


TOUR: tuple[Step, ...] = (
    Step("lambert", "Lambert",
         "Perfectly diffuse: the same radiance toward every viewer; shading follows cos(theta_i) alone.",
         _one_ball("lecture_lambert"), "polar"),
    Step("fresnel", "Mirror and glass with Fresnel",
         "Air-glass n = 1.5: 4% reflected head-on, rising to 100% at grazing angles (the black glass's "
         "rims). The clear ball refracts what lies behind it: "
         "floor and sky upside down.",
         _scene(_camera(), _SKY, _render("split_sum", raytrace=True), _FLOOR, _sphere("black_glass", -0.75),
                _sphere("glass", 0.75), _FLOOR_MAT,
                '[materials.black_glass]\nmodel = "mirror"\nfresnel = "dielectric"\nior = 1.5\n',
                _mat("glass", "lecture_air_glass")), "fresnel"),
    Step("tir", "Total internal reflection",
         "Inside glass beyond the critical angle asin(1/1.5) = 41.8 deg all light reflects: the bottom "
         "turns into a mirror, so the near faces' lower half shows the sky, not the floor.",
         _scene(_camera((0.0, 1.9, 3.2), (0.0, 0.45, 0.0)), _SKY, _render("split_sum", raytrace=True), _FLOOR,
                '[[objects]]\nmesh = "cube"\nmaterial = "glass"\nscale = 0.55\n'
                'translate = [0.0, 0.56, 0.0]\nrotate_y_deg = 35.0\n',
                _FLOOR_MAT, _mat("glass", "lecture_air_glass")), "fresnel"),
    Step("torrance_sparrow", "Torrance-Sparrow with a Blinn-Phong distribution",
         "Microfacets: D (Blinn-Phong), V-cavity shadowing G and Fresnel F shape one highlight over a diffuse base.",
         _one_ball("lecture_torrance_sparrow_blinn"), "polar"),
    Step("beckmann_ggx", "Beckmann (left) against GGX (right)",
         "Same alpha = 0.2: GGX's long tail leaves a glow around the highlight; Beckmann falls off quickly.",
         _scene(_camera(), _DIM, _render("off"), _KEY_LIGHT, _FLOOR, _sphere("beckmann", -0.75),
                _sphere("ggx", 0.75), _FLOOR_MAT, _mat("beckmann", "lecture_beckmann"),
                _mat("ggx", "lecture_ggx")), "polar"),
    Step("oren_nayar", "Oren-Nayar (left) against Lambert (right)",
         "Lit from behind the viewer, rough clay looks flat (backscatter); Lambert darkens toward the rim.",
         _scene(_camera(), _DIM, _render("off"),
                '[[lights]]\ntype = "point"\nposition = [0.0, 1.2, 6.0]\nintensity = [60.0, 60.0, 60.0]\n',
                _FLOOR, _sphere("oren_nayar", -0.75), _sphere("lambert", 0.75), _FLOOR_MAT,
                _mat("oren_nayar", "lecture_oren_nayar"), _mat("lambert", "lecture_lambert")), "polar"),
    Step("lafortune", "Lafortune's generalized cosine lobes",
         "A forward lobe about the mirror direction plus a retro-reflective lobe, over a diffuse base.",
         _one_ball("lecture_lafortune"), "polar"),
    Step("ashikhmin_shirley", "Ashikhmin-Shirley anisotropy",
         "n_u = 10, n_v = 1000: the highlight stretches across the tangent direction, as on brushed metal.",
         _one_ball("lecture_ashikhmin_shirley"), "lobe"),
    Step("layered", "Weidlich-Wilkie layered coat",
         "A clear coat over a coloured base: a sharp Fresnel reflection on top of a glossy, tinted layer.",
         _scene(_camera(), _STUDIO, _render("split_sum"), _KEY_LIGHT, _FLOOR, _sphere("ball"), _FLOOR_MAT,
                _mat("ball", "lecture_layered")), "albedo"),
    Step("absorbing_glass", "Absorbing glass (Bouguer / Beer-Lambert)",
         "Transmittance exp(-sigma_a d) over each traced path: the floor and sky seen through the big "
         "sphere come out a deeper green than through the small one, darkest where the path is longest.",
         _scene(_camera(), _SKY, _render("split_sum", raytrace=True), _FLOOR, _sphere("glass_big", -0.6, 0.7),
                _sphere("glass_small", 0.9, 0.3), _FLOOR_MAT, _mat("glass_big", "lecture_absorbing_glass"),
                _mat("glass_small", "lecture_absorbing_glass")), "bouguer"),
    Step("complex_ior", "Complex IOR: gold, silver, copper",
         "n + i k measured per wavelength (Johnson & Christy 1972): gold and copper absorb the blue end "
         "(n rises, k falls below 500-600 nm), silver reflects all; their colours show in the white floor "
         "each one mirrors (traced reflections).",
         _scene(_camera(fov=40.0), _SKY, _render("split_sum", raytrace=True), _KEY_LIGHT, _FLOOR,
                _sphere("gold", -1.3, 0.55), _sphere("silver", 0.0, 0.55), _sphere("copper", 1.3, 0.55),
                '[materials.floor]\nmodel = "lambert"\nalbedo = [0.8, 0.8, 0.8]\n',
                _mat("gold", "polished_gold"), _mat("silver", "polished_silver"),
                _mat("copper", "polished_copper")), "spectral"),
    Step("dispersion", "Dispersion: a flint prism and a diamond",
         "n(lambda) falls with wavelength (SF11: 1.83 at 420 nm, 1.77 at 680 nm): blue bends most. "
         "The raster traces each colour channel with its own n: red and blue part at the edges.",
         _scene(_camera((0.0, 0.8, 3.6), (0.0, 0.5, 0.0), 36.0), _SKY, _render("split_sum", raytrace=True), _FLOOR,
                '[[objects]]\nmesh = "prism"\nmaterial = "flint"\nscale = 0.5\n'
                'translate = [-0.6, 0.6, 0.0]\nrotate_y_deg = 90.0\n',
                _sphere("diamond", 0.7, 0.45), _FLOOR_MAT,
                '[materials.flint]\nmodel = "dielectric"\nspectral = "SF11"\n',
                '[materials.diamond]\nmodel = "dielectric"\nspectral = "diamond"\n'), "spectral"),
    Step("soap_bubble", "Soap bubbles: thin-film interference",
         "A 400 nm water film in air: the waves reflected at its two faces interfere, so the colour changes with the viewing angle (Fresnel with a phase).",
         _scene(_camera(), _STUDIO, _render("split_sum"), _FLOOR, _sphere("bubble", -0.75, 0.6, 0.8),
                _sphere("thin", 0.75, 0.6, 0.8), _FLOOR_MAT, _mat("bubble", "lecture_soap_bubble"),
                _mat("thin", "lecture_soap_bubble") + "thin_film = { ior = 1.33, thickness_nm = 250.0 }\n"), "fresnel"),
    # The variances in the caption: per-sample variance averaged over the image at 256 spp
    # (test_strategies measures the same scene and checks them): MIS 1.27, BSDF alone 3.51,
    # light alone 4.35.
    Step("importance_sampling", "Importance sampling: BSDF, light and MIS",
         "Glossy gold under the studio map. Reference > strategy: BSDF sampling alone has 2.8x, light "
         "sampling alone 3.4x the variance of MIS (power heuristic); error view shows where.",
         _scene(_camera((0.0, 0.0, 3.2), (0.0, 0.0, 0.0), 40.0), _STUDIO, _render("split_sum"),
                '[[objects]]\nmesh = "sphere"\nmaterial = "ball"\n',
                _mat("ball", "gold", alpha=0.15)), "sampling", "reference"),
    # A BRDF Explorer file beside the built-in model it writes out: viewer/brdfs/cooktorrance.brdf
    # (relative to the built-in scenes' folder, where lecture steps resolve their files)
    Step("brdf_file", "Your own BRDF: a .brdf file",
         "Left: a textbook Cook-Torrance in one text file, opened at run time (Beckmann D, V-cavity G, Fresnel "
         "for ior 1.5). Right: the built-in microfacet with the same choices, the same ball. brdf-viewer check grades it.",
         _scene(_camera(), _DIM, _render("off"), _KEY_LIGHT, _FLOOR, _sphere("file", -0.75), _sphere("builtin", 0.75),
                _FLOOR_MAT,
                '[materials.file]\nmodel = "custom"\nfile = "../brdfs/cooktorrance.brdf"\nm = 0.3\nior = 1.5\n',
                '[materials.builtin]\nmodel = "microfacet"\ndistribution = "beckmann"\nshadowing = "v_cavity"\n'
                'fresnel = "dielectric"\nior = 1.5\nalpha = 0.3\nkd = [0.0, 0.0, 0.0]\n'), "polar", "raster"),
)


def step_label(index: int) -> str:
    """How step ``index`` (0-based) is named in messages: ``<lecture 3: tir>``."""
    i = index % len(TOUR)
    return f"<lecture {i + 1}: {TOUR[i].key}>"


def tour_scene(index: int, load_meshes: bool = True):
    """The tour's step ``index`` (0-based) as a validated ``Scene``; the same as the built-in
    scene name ``lecture:{index + 1}`` (``viewer.scene.load_scene``)."""
    from viewer.scene import load_scene

    return load_scene(f"lecture:{index % len(TOUR) + 1}", load_meshes=load_meshes)
