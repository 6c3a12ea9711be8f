"""The ``spectral`` plot: n(lambda), k(lambda) of a material's table, R(theta, lambda) as an image
with the resulting RGB colour per angle, and how far two RGB shortcuts are from that colour:
Schlick's approximation with the spectral f0, and the three-wavelength approximation (exact
Fresnel of n + i k sampled at 650 / 550 / 450 nm, what RGB renderers usually do).

A material with a thin film (``thin_film``, or a layered model's ``coating.thin_film``): R(theta,
lambda) is the film's (``fresnel_thin_film`` over the base's n(lambda): its spectral table, else
its ior, or a conductor's RGB eta, k interpolated in wavelength as viewer/brdf/thin_film.py does),
and the shortcuts are the RGB renderers' 32-wavelength integration and the film evaluated at the
three wavelengths 650 / 550 / 450 nm.

Data: ``spectral_data(p)``; the figure: ``spectral_figure``; drawing: ``draw_spectral`` (Pillow,
through ``viewer.plots.canvas``).
"""

from __future__ import annotations

import numpy as np

from viewer import ViewerError, spectral
from viewer.plots.canvas import CHANNEL_COLOURS, colormap, nice_ceil, nice_ticks, tick_label
from viewer.plots.figure_types import Curve, Figure
from viewer.plots.kinds import film_owner, fresnel_source, spectral_name

WAVELENGTHS_NM = np.arange(360.0, 781.0, 5.0)
THETA_DEG = np.linspace(0.0, 90.0, 91)


def _film_data(p, owner) -> dict:
    from viewer.brdf import thin_film
    from viewer.brdf.fresnel import fresnel_thin_film

    lam = WAVELENGTHS_NM
    src = fresnel_source(p)
    name = spectral_name(p)
    if name is not None:
        n2 = spectral.ior(name, lam)
        base = f"{name} ({spectral.describe(name)})"
    elif src["type"] == "conductor":
        rgb_nm = np.array(thin_film.RGB_NM[::-1])
        n2 = np.interp(lam, rgb_nm, src["eta"][::-1]) + 1j * np.interp(lam, rgb_nm, src["k"][::-1])
        base = "conductor eta + i k = " + ", ".join(f"{e:.3g}+{k:.3g}i" for e, k in zip(src["eta"], src["k"]))
    else:
        n2 = np.full(lam.shape, float(src["ior"]), dtype=np.complex128)
        base = f"dielectric n = {src['ior']:.4g}"
    tf = owner.thin_film
    cos = np.cos(np.radians(THETA_DEG))
    R = fresnel_thin_film(cos[:, None], lam[None, :], tf.ior, tf.thickness_nm, n2[None, :])
    rgb = np.clip(spectral.to_rgb(R, lam), 0.0, 1.0)
    if src["type"] == "conductor":
        renderer = thin_film.reflectance_rgb(owner, cos, src["eta"], src["k"])
    else:
        renderer = thin_film.reflectance_rgb(owner, cos, float(src["ior"]))
    lam3 = np.array(thin_film.RGB_NM)
    n3 = np.interp(lam3, lam, n2.real) + 1j * np.interp(lam3, lam, n2.imag)
    three = fresnel_thin_film(cos[:, None], lam3[None, :], tf.ior, tf.thickness_nm, n3[None, :])
    label = f"n = {tf.ior:.4g}, {tf.thickness_nm:g} nm on {base}"
    return {"name": "thin film", "description": label,
            "source": "Airy summation (Born & Wolf sec. 7.6.1), both polarizations averaged",
            "wavelength_nm": lam, "n": n2.real, "k": n2.imag, "theta": THETA_DEG, "R": R, "rgb": rgb,
            "schlick": renderer, "three_wavelength": three,
            "err_schlick": renderer - rgb, "err_three": three - rgb,
            "max_err_schlick": float(np.abs(renderer - rgb).max()),
            "max_err_three": float(np.abs(three - rgb).max()),
            "conductor": src["type"] == "conductor", "film": True,
            "labels": ("32 wavelengths (renderers) - spectral", "3 wavelengths (650/550/450 nm) - spectral")}


def spectral_data(p_or_name) -> dict:
    """n, k over WAVELENGTHS_NM; R (91 angles x wavelengths); its RGB per angle; Schlick and the
    three-wavelength approximation and their errors against it. A material with a thin film:
    the film's R (see the module docstring); n, k are then the base's."""
    from viewer.brdf import spectral_fresnel as sf
    from viewer.brdf.fresnel import fresnel_conductor, fresnel_schlick

    owner = film_owner(p_or_name)
    if owner is not None:
        return _film_data(p_or_name, owner)
    name = p_or_name if isinstance(p_or_name, str) else spectral_name(p_or_name)
    if name is None:
        raise ViewerError("spectral plot: the material names no spectral table (spectral = \"NAME\")")
    lam = WAVELENGTHS_NM
    n = spectral.ior(name, lam)
    cos = np.cos(np.radians(THETA_DEG))
    R = sf.spectral_reflectance(name, cos, lam)                     # (91, L)
    rgb = spectral.to_rgb(R, lam)                                   # (91, 3) the spectral integral
    f0 = rgb[0]
    schlick = fresnel_schlick(cos[:, None], f0[None, :])
    n3 = spectral.ior(name, np.array(sf.RGB_WAVELENGTHS_NM))
    three = fresnel_conductor(cos[:, None], n3.real[None, :], n3.imag[None, :])
    return {"name": name, "description": spectral.describe(name), "source": spectral.source(name),
            "wavelength_nm": lam, "n": n.real, "k": n.imag, "theta": THETA_DEG, "R": R, "rgb": rgb,
            "schlick": schlick, "three_wavelength": three,
            "err_schlick": schlick - rgb, "err_three": three - rgb,
            "max_err_schlick": float(np.abs(schlick - rgb).max()),
            "max_err_three": float(np.abs(three - rgb).max()),
            "conductor": spectral.is_conductor(name), "film": False,
            "labels": ("Schlick - spectral", "3 wavelengths - spectral")}


def rgb_over_one(rgb) -> str:
    """A note for a linear-sRGB reflectance with a channel over 1 ("" when none is): every
    wavelength's reflectance is at most 1, but the sRGB cube does not hold every object colour
    (gold's saturated yellow needs red above 1 at its luminance), so the channel is not light made."""
    over = [c for c, v in zip("RGB", np.asarray(rgb, float)) if v > 1.0]
    if not over:
        return ""
    return (f" ({', '.join(over)} over 1: the colour lies outside the sRGB cube; every wavelength's "
            f"reflectance is at most 1)")


def spectral_figure(p, label: str, sub: str):
    d = spectral_data(p)
    curves = []
    for lab, arr, style in ((d["labels"][0], d["err_schlick"], "solid"),
                            (d["labels"][1], d["err_three"], "dashed")):
        for c in range(3):
            curves.append(Curve(f"{lab} ({'rgb'[c]})", d["theta"], arr[:, c], CHANNEL_COLOURS[c], style))
    first = "32 wavelengths (the RGB renderers)" if d["film"] else "Schlick"
    notes = [f"{d['name']} ({d['description']}): {d['source'][:110]}",
             f"max |error| over angles and channels: {first} {d['max_err_schlick']:.3f}, "
             f"3 wavelengths (650/550/450 nm) {d['max_err_three']:.3f}; "
             f"normal incidence RGB {np.round(d['rgb'][0], 3).tolist()}{rgb_over_one(d['rgb'][0])}"]
    emax = max(d["max_err_schlick"], d["max_err_three"], 1e-3)
    return Figure("spectral", p.model, p, f"{label}: spectral Fresnel reflectance of {d['name']}",
                  "angle of incidence (deg)", "RGB error", curves, [], (0.0, 90.0),
                  (-emax * 1.1, emax * 1.1), sub, notes,
                  {k: d[k] for k in ("name", "wavelength_nm", "n", "k", "theta", "R", "rgb",
                                     "max_err_schlick", "max_err_three", "conductor", "film")})


def _srgb(rgb):
    from viewer.image.colour import to_srgb8

    return to_srgb8(np.clip(np.asarray(rgb, dtype=np.float32), 0.0, 1.0))


def _axes(cv, box, xr, yr, xlabel, ylabel, title):
    x0, y0, x1, y1 = box
    d = cv.draw

    def to_px(x, y):
        return (x0 + (np.asarray(x) - xr[0]) / (xr[1] - xr[0]) * (x1 - x0),
                y1 - (np.asarray(y) - yr[0]) / (yr[1] - yr[0]) * (y1 - y0))

    xt, yt = nice_ticks(xr[0], xr[1], 5), nice_ticks(yr[0], yr[1], 4)
    for v in xt:
        px, _ = to_px(v, yr[0])
        d.line([(px, y1), (px, y1 + cv.s(4))], fill=(60, 60, 60), width=cv.s(1))
        cv.text((px, y1 + cv.s(6)), tick_label(v, xt), px=11, anchor="ma")
    for v in yt:
        _, py = to_px(xr[0], v)
        d.line([(x0, py), (x1, py)], fill=(235, 235, 235), width=cv.s(1))
        cv.text((x0 - cv.s(6), py), tick_label(v, yt), px=11, anchor="rm")
    d.rectangle([x0, y0, x1, y1], outline=(60, 60, 60), width=cv.s(1))
    cv.text(((x0 + x1) / 2, y1 + cv.s(22)), xlabel, px=12, anchor="ma")
    cv.text((x0, y0 - cv.s(16)), f"{title}   ({ylabel})", px=12, anchor="la")
    return to_px


def draw_spectral(cv, fig, width, height):
    """Three panels: n, k vs lambda (top left), R(theta, lambda) with the RGB swatch (top
    right), the errors of the RGB shortcuts vs theta (bottom)."""
    from PIL import Image

    info = fig.info
    lam, n, k = np.asarray(info["wavelength_nm"]), np.asarray(info["n"]), np.asarray(info["k"])
    top = 58 + 14 * len(fig.notes) + 20
    mid = top + (height - top) * 0.52
    # n, k
    box = (cv.s(60), cv.s(top), cv.s(width * 0.45), cv.s(mid - 34))
    vmax = nice_ceil(max(float(n.max()), float(k.max()), 1.0) * 1.05)
    to_px = _axes(cv, box, (lam[0], lam[-1]), (0.0, vmax), "wavelength (nm)", "n solid, k dashed",
                  "index of refraction")
    for arr, style in ((n, "solid"), (k, "dashed")):
        px, py = to_px(lam, arr)
        cv.polyline(list(zip(px, py)), (40, 40, 40), 2.0, style)
    # R(theta, lambda) image: lambda across, theta down; swatch column on the right
    x0, y0, x1, y1 = cv.s(width * 0.55), cv.s(top), cv.s(width - 90), cv.s(mid - 34)
    R = np.asarray(info["R"])
    img = np.clip(colormap(R[::-1]), 0, 255).astype(np.uint8)       # row 0 = 90 degrees
    im = Image.fromarray(img).resize((int(x1 - x0), int(y1 - y0)), Image.NEAREST)
    cv.im.paste(im, (int(x0), int(y0)))
    _axes(cv, (x0, y0, x1, y1), (lam[0], lam[-1]), (0.0, 90.0), "wavelength (nm)",
          "theta up; R 0 purple .. 1 yellow", "R(theta, lambda)")
    sw = _srgb(np.asarray(info["rgb"])[::-1])[:, None, :]
    swim = Image.fromarray(np.repeat(sw, 4, axis=1)).resize((int(cv.s(40)), int(y1 - y0)), Image.NEAREST)
    cv.im.paste(swim, (int(x1 + cv.s(12)), int(y0)))
    cv.text((x1 + cv.s(32), y0 - cv.s(16)), "RGB", px=12, anchor="ma")
    # errors
    box = (cv.s(60), cv.s(mid + 16), cv.s(width - 24), cv.s(height - 40))
    ya, yb = fig.y_range
    to_px = _axes(cv, box, (0.0, 90.0), (ya, yb), fig.x_label, "shortcut - spectral integral",
                  "RGB error: 32 wavelengths (solid), three wavelengths (dashed)" if info.get("film")
                  else "RGB error: Schlick (solid), three wavelengths (dashed)")
    zx, zy = to_px(np.array([0.0, 90.0]), np.array([0.0, 0.0]))
    cv.draw.line([(zx[0], zy[0]), (zx[1], zy[1])], fill=(120, 120, 120), width=cv.s(1))
    for c in fig.curves:
        px, py = to_px(c.x, c.y)
        cv.polyline(list(zip(px, py)), tuple(c.color), 2.0, c.style)
