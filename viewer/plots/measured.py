"""The Rusinkiewicz image slice of a BRDF (``brdf-viewer plot ... --kind slice``): f at phi_d =
90 degrees with theta_h across (columns: the MERL table's theta_h bins, the square-root mapping,
so the specular peak near theta_h = 0 gets half of the width) and theta_d down, the view of
measured BRDFs that Burley's BRDF Explorer made common. With a second material (``--overlay``,
e.g. a fitted model) it also draws the cosine-weighted residual (model - first) cos theta_i, red
where the model reflects too much, blue too little: where an analytic model fails."""

from __future__ import annotations

import numpy as np

from viewer.brdf import merl
from viewer.plots.figure_types import Figure
from viewer.plots.kinds import LUMINANCE

PHI_D = 0.5 * np.pi


def slice_data(p, overlay=None, n_d: int = 90, phi_d: float = 90.0, cos: bool = False) -> dict:
    """f (n_d, 90, 3) at (theta_h bin angles, theta_d rows, phi_d, default 90 deg), the
    directions' cos theta_i, and the overlay's residual if one is given; with ``cos`` f is
    multiplied by cos theta_i of the light (BRDF Explorer's N.L option)."""
    import math

    from viewer import ViewerError, brdf

    phi_d = float(phi_d)
    if not (math.isfinite(phi_d) and 0.0 <= phi_d <= 180.0):
        raise ViewerError(f"--phi-d: {phi_d:g} is out of range; allowed: degrees in [0, 180]")
    th, _, _ = merl.grid_angles()
    td = (np.arange(n_d) + 0.5) / n_d * merl.HALF_PI
    TD, TH = np.meshgrid(td, th, indexing="ij")
    wi, wo = merl.from_half_diff(TH.ravel(), TD.ravel(), np.full(TH.size, math.radians(phi_d)))
    ok = (wi[:, 2] > 0) & (wo[:, 2] > 0)
    f = np.zeros((TH.size, 3))
    f[ok] = brdf.get(p.model).eval(p, wi[ok], wo[ok])
    raw = f.reshape(n_d, merl.N_TH, 3)
    if cos:
        f = f * np.maximum(wi[:, 2], 0.0)[:, None]
    out = {"theta_h": np.degrees(th), "theta_d": np.degrees(td), "f": f.reshape(n_d, merl.N_TH, 3),
           "valid": ok.reshape(n_d, merl.N_TH), "cos_i": np.maximum(wi[:, 2], 0).reshape(n_d, merl.N_TH),
           "phi_d": phi_d, "cos": bool(cos)}
    if overlay is not None:
        g = np.zeros((TH.size, 3))
        g[ok] = brdf.get(overlay.model).eval(overlay, wi[ok], wo[ok])
        g = g.reshape(n_d, merl.N_TH, 3)
        out["overlay"] = g
        out["residual"] = (g - raw) * out["cos_i"][..., None]
    return out


def slice_figure(p, label: str, sub: str, overlay=None, phi_d: float = 90.0, cos: bool = False):
    d = slice_data(p, overlay, phi_d=phi_d, cos=cos)
    lum = d["f"] @ LUMINANCE
    what = "f cos theta_i" if cos else "f"
    notes = [f"phi_d = {d['phi_d']:g} deg; columns: the MERL theta_h bins (sqrt mapping), rows: theta_d; "
             f"max {what} = {float(lum.max()):.4g} /sr (luminance); colour: RGB of log(1 + f) / log(1 + max f)"]
    info = {"theta_h": d["theta_h"], "theta_d": d["theta_d"], "f": d["f"], "valid": d["valid"]}
    if overlay is not None:
        r = d["residual"] @ LUMINANCE
        rms = float(np.sqrt(np.mean(r[d["valid"]] ** 2)))
        notes.append(f"right: residual ({overlay.model} - {p.model}) cos theta_i (luminance), RMS {rms:.3g}; "
                     f"red: the model reflects more, blue: less")
        info.update(residual=d["residual"], overlay_model=overlay.model, overlay_params=overlay.to_plain(),
                    residual_rms=rms)
    return Figure("slice", p.model, p, f"{label}: Rusinkiewicz slice f(theta_h, theta_d)",
                  "theta_h (deg)", "theta_d (deg)", [], [], (0.0, 90.0), (0.0, 90.0), sub, notes, info)


def _image(cv, box, rgb):
    from PIL import Image

    x0, y0, x1, y1 = (int(v) for v in box)
    im = Image.fromarray(np.clip(rgb * 255 + 0.5, 0, 255).astype(np.uint8)).resize((x1 - x0, y1 - y0), Image.NEAREST)
    cv.im.paste(im, (x0, y0))
    cv.draw.rectangle([x0, y0, x1, y1], outline=(60, 60, 60), width=cv.s(1))


def _ticks(cv, box, title):
    x0, y0, x1, y1 = box
    for deg in (0, 2, 10, 22.5, 45, 90):  # theta_h ticks at their sqrt-mapped positions
        x = x0 + np.sqrt(deg / 90.0) * (x1 - x0)
        cv.draw.line([(x, y1), (x, y1 + cv.s(4))], fill=(60, 60, 60), width=cv.s(1))
        cv.text((x, y1 + cv.s(6)), f"{deg:g}", px=11, anchor="ma")
    for deg in (0, 30, 60, 90):
        y = y0 + deg / 90.0 * (y1 - y0)
        cv.draw.line([(x0 - cv.s(4), y), (x0, y)], fill=(60, 60, 60), width=cv.s(1))
        cv.text((x0 - cv.s(6), y), f"{deg:g}", px=11, anchor="rm")
    cv.text(((x0 + x1) / 2, y1 + cv.s(22)), "theta_h (deg)", px=12, anchor="ma")
    cv.text((x0, y0 - cv.s(16)), title, px=12, anchor="la")


def draw_slice(cv, fig, width, height):
    info = fig.info
    f = np.asarray(info["f"])
    top = 58 + 14 * len(fig.notes) + 24
    two = "residual" in info
    right = width * (0.5 if two else 1.0)
    box = (cv.s(60), cv.s(top), cv.s(right - 24), cv.s(height - 44))
    vmax = max(float(f.max()), 1e-12)
    rgb = np.log1p(np.maximum(f, 0.0)) / np.log1p(vmax)
    rgb = np.where(np.asarray(info["valid"])[..., None], rgb, 0.85)
    _image(cv, box, rgb)
    _ticks(cv, box, f"{fig.model}: f (theta_d down)")
    cv.vtext((cv.s(18), (box[1] + box[3]) / 2), "theta_d (deg)", px=12)
    if two:
        r = np.asarray(info["residual"]) @ LUMINANCE
        vm = max(float(np.abs(r).max()), 1e-12)
        t = np.clip(r / vm, -1.0, 1.0)
        img = np.stack([1 - np.clip(-t, 0, 1), 1 - np.abs(t), 1 - np.clip(t, 0, 1)], axis=-1)
        img = np.where(np.asarray(info["valid"])[..., None], img, 0.85)
        box2 = (cv.s(right + 40), cv.s(top), cv.s(width - 24), cv.s(height - 44))
        _image(cv, box2, img)
        _ticks(cv, box2, f"residual, +-{vm:.3g} (red: {info['overlay_model']} higher)")
