"""Figures: one plot kind of one material as labelled curves, marks and notes (``figure``), the
data of ``viewer.plots.data`` in the form the drawing (``viewer.plots.draw``) and the JSON of the
PNG (``viewer.plots.png``) use."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from viewer.brdf import thin_film

from viewer.plots.canvas import CHANNEL_COLOURS, CHANNEL_NAMES, NEUTRAL, nice_ceil
from viewer.plots.figure_types import Curve, Figure, Mark, fmt_value
from viewer.plots.data import albedo_curve, bouguer_curve, fresnel_curves, lobe_3d, polar_lobe, sampling_histogram
from viewer.plots.kinds import as_params, check_channel, check_kind, reduce_channel

def _channel_groups(same) -> list[list[int]]:
    """The channels 0..2 grouped so that ``same(first of the group, c)`` holds for each member."""
    groups = []
    for c in range(3):
        for g in groups:
            if same(g[0], c):
                g.append(c)
                break
        else:
            groups.append([c])
    return groups


def _rgb_curves(x, rgb, label, channel, style="solid", color=None, extra=None) -> list:
    """Curves of one RGB quantity: one per channel for 'rgb' (one only when the channels are
    equal), or the chosen channel / luminance."""
    rgb = np.asarray(rgb, dtype=np.float64)
    extra = extra or {}
    if channel == "rgb":
        if np.allclose(rgb, rgb[:, :1], rtol=0, atol=1e-12):
            return [Curve(label, x, rgb[:, 0], color or NEUTRAL, style, {k: v[:, 0] for k, v in extra.items()})]
        # channels with identical values share one curve ("green, blue")
        groups = _channel_groups(lambda a, c: np.allclose(rgb[:, a], rgb[:, c], rtol=0, atol=1e-12))
        return [Curve(f"{label} ({', '.join(CHANNEL_NAMES[c] for c in g)})", x, rgb[:, g[0]],
                      CHANNEL_COLOURS[g[0]], style, {k: v[:, g[0]] for k, v in extra.items()}) for g in groups]
    col = color or (NEUTRAL if channel == "lum" else CHANNEL_COLOURS["rgb".index(channel)])
    name = "luminance" if channel == "lum" else CHANNEL_NAMES["rgb".index(channel)]
    return [Curve(f"{label} ({name})", x, reduce_channel(rgb, channel), col, style,
                  {k: reduce_channel(v, channel) for k, v in extra.items()})]


def params_summary(p, limit: int = 110) -> str:
    parts = []
    for k, v in p.items():
        if hasattr(v, "model") and v.model:
            parts.append(f"{k}={v.model}")
        else:
            parts.append(f"{k}={fmt_value(v)}")
    s = ", ".join(parts)
    return s if len(s) <= limit else s[: limit - 3] + "..."


@dataclass
class _Request:
    """What one figure is asked for: the material (validated), an overlay, the label, the
    subtitle and the options of ``figure``."""
    p: object
    overlay: object
    label: str
    sub: str
    theta_i: float
    phi: float
    channel: str
    inside: bool
    log: bool
    samples: int
    seed: int
    theta_d: float = 0.0
    theta_h: float = 0.0
    phi_v: float | None = None
    phi_d: float = 90.0
    cos: bool = False
    kind: str = ""

    def shown(self, y) -> np.ndarray:
        """y as plotted: log10(1 + y) with ``log``."""
        return np.log10(1.0 + np.asarray(y)) if self.log else np.asarray(y)

    @property
    def y_format(self) -> str:
        return "log10(1 + {})" if self.log else "{}"

    @property
    def transform(self) -> str:
        return "log10(1+y)" if self.log else ""


def figure(p, kind: str, *, theta_i: float = 45.0, phi: float = 0.0, channel: str = "rgb",
           inside: bool = False, log: bool = False, name: str | None = None, samples: int = 200_000,
           seed: int = 0, overlay=None, theta_d: float = 0.0, theta_h: float = 0.0, phi_v: float | None = None,
           phi_d: float = 90.0, cos: bool = False) -> Figure:
    """The figure of one plot kind for one material (what ``brdf-viewer plot`` draws);
    ``samples`` and ``seed`` are the sampling plot's. ``overlay``: a second material drawn dashed
    over the polar, albedo and theta plots (e.g. an analytic model over a measured one) and, for
    the slice, the residual image. ``theta_d`` (theta_h plot), ``theta_h`` (theta_d plot),
    ``phi_v`` (theta_v plot, default ``phi``), ``phi_d`` (slice) hold the other angles (degrees);
    ``cos``: f times cos theta_i of the light (theta plots, slice)."""
    p = as_params(p)
    overlay = None if overlay is None else as_params(overlay)
    check_kind(p, kind)
    check_channel(channel)
    r = _Request(p, overlay, name or p.model, f"{p.model}: {params_summary(p)}", theta_i, phi, channel,
                 inside, log, samples, seed, theta_d, theta_h, phi_v, phi_d, cos, kind)
    return _FIGURES[kind](r)


def _polar_figure(r: _Request) -> Figure:
    p, channel, theta_i, phi = r.p, r.channel, r.theta_i, r.phi
    d = polar_lobe(p, theta_i, phi)
    curves = _rgb_curves(d["theta_o"], r.shown(d["fcos"]), "f cos", channel, extra={"f": d["f"]})
    if r.overlay is not None:
        d2 = polar_lobe(r.overlay, theta_i, phi)
        curves += _rgb_curves(d2["theta_o"], r.shown(d2["fcos"]), f"{r.overlay.model} f cos", channel, "dashed",
                              extra={"f": d2["f"]})
    vmax = max([float(np.max(c.y)) for c in curves] + [float(np.max(r.shown(x["reflectance"])))
                                                     for x in d["delta"]] + [0.0])
    plane = "x-z (tangent)" if phi % 180 == 0 else ("y-z (bitangent)" if phi % 180 == 90 else f"phi = {phi:g} deg")
    notes = [f"wi at theta_i = {theta_i:g} deg; theta_o > 0: mirror side"]
    for x in d["delta"]:
        notes.append("delta lobe (mirror direction): R = " + fmt_value(x["reflectance"]))
    return Figure("polar", p.model, p, f"{r.label}: lobe in the plane of incidence ({plane})",
                  "theta_o (deg)", r.y_format.format("f cos(theta_o) [1/sr]"), curves, [],
                  (-90.0, 90.0), (0.0, nice_ceil(vmax * 1.05)), r.sub, notes,
                  {"theta_i": theta_i, "phi": phi, "delta": d["delta"], "channel": channel,
                   "transform": r.transform, "wi": d["wi"]})


def _lobe_figure(r: _Request) -> Figure:
    p, theta_i, phi = r.p, r.theta_i, r.phi
    ch = "lum" if r.channel == "rgb" else r.channel
    d = lobe_3d(p, theta_i, phi, channel=ch)
    value = r.shown(d["value"])
    x, y, z = (value * d["wo"][..., i] for i in range(3))
    chn = "luminance" if ch == "lum" else CHANNEL_NAMES["rgb".index(ch)]
    notes = [f"wi at theta_i = {theta_i:g} deg, phi_i = {phi:g} deg; radius = f cos ({chn})"]
    for dl in d["delta"]:
        notes.append("delta lobe (mirror direction): R = " + fmt_value(dl["reflectance"]))
    vmax = max([float(np.max(value)) if value.size else 0.0]
               + [float(np.max(r.shown(dl["reflectance"]))) for dl in d["delta"]])
    return Figure("lobe", p.model, p, f"{r.label}: 3D lobe f cos(theta_o)", "x (tangent)", "z (normal)",
                  [], [], (-1, 1), (0.0, nice_ceil(vmax * 1.05) if vmax > 0 else 1.0), r.sub, notes,
                  {"theta_i": theta_i, "phi": phi, "channel": ch, "theta": d["theta"], "phi_grid": d["phi"],
                   "x": x, "y": y, "z": z, "value": value, "wi": d["wi"], "delta": d["delta"],
                   "transform": r.transform})


def _albedo_figure(r: _Request) -> Figure:
    p, channel = r.p, r.channel
    d = albedo_curve(p)
    curves = _rgb_curves(d["theta"], d["albedo"], "albedo", channel)
    from viewer.brdf import ms_compensation
    if ms_compensation.applies(p):  # single scattering, the raster's compensation, the random walk
        from viewer import brdf

        ms = ms_compensation.albedos(p, np.cos(np.radians(d["theta"])), known={
            "walk" if brdf.walks(p) else "single": d["albedo"]})
        curves = _rgb_curves(d["theta"], ms["single"], "single scattering", channel, "dotted")
        curves += _rgb_curves(d["theta"], ms["compensated"], "compensated, environment (raster)", channel, "dashed")
        curves += _rgb_curves(d["theta"], ms["kulla_conty"], "compensated, lights (raster)", channel, "dashdot")
        curves += _rgb_curves(d["theta"], ms["walk"], "random walk (reference)", channel)
    if r.overlay is not None:
        d2 = albedo_curve(r.overlay)
        curves += _rgb_curves(d2["theta"], d2["albedo"], f"{r.overlay.model} albedo", channel, "dashed")
    if d["transmissive"]:
        curves += _rgb_curves(d["theta"], d["reflected"], "reflected", channel, "dashed")
        curves += _rgb_curves(d["theta"], d["transmitted"], "transmitted", channel, "dotted")
    vmax = max(float(np.max(c.y)) for c in curves)
    return Figure("albedo", p.model, p, f"{r.label}: directional albedo (furnace test)",
                  "theta (deg) of wo", "albedo rho(theta)", curves, [], (0.0, 90.0),
                  (0.0, 1.05 if vmax <= 1.03 else nice_ceil(vmax * 1.02)), r.sub,
                  ["white furnace: radiance 1 from every direction reflects rho"], {"channel": channel})


_FRESNEL_COLOURS = {"R_s": (31, 119, 180), "R_p": (255, 127, 14), "R": NEUTRAL, "Schlick": (148, 103, 189)}
_FRESNEL_STYLES = {"R_s": "dashed", "R_p": "dotted", "R": "solid", "Schlick": "solid"}


def _fresnel_curve_list(d, ch: str, single: bool) -> list:
    """R_s, R_p, R (and Schlick), per channel or of one channel, and a thin film's RGB R."""
    curves = []
    series = [("R_s", d["Rs"]), ("R_p", d["Rp"]), ("R", d["R"])]
    if "schlick" in d:
        series.append(("Schlick", d["schlick"]))
    for lab, arr in series:
        if ch == "rgb" and not single:
            curves += _rgb_curves(d["theta"], arr, lab, "rgb", _FRESNEL_STYLES[lab])
        else:
            c = ch if ch != "rgb" else "r"
            idx = "rgb".index(c)
            suffix = "" if single else f" ({CHANNEL_NAMES[idx]})"
            curves.append(Curve(lab + suffix, d["theta"], arr[:, idx], _FRESNEL_COLOURS[lab], _FRESNEL_STYLES[lab]))
    if "thin_film" in d:  # the film's interference reflectance, one curve per channel
        curves += _rgb_curves(d["theta"], d["thin_film"], "thin film R", "rgb" if ch in ("rgb", "lum") else ch)
    return curves


def _fresnel_marks(d, ch: str, single: bool) -> list:
    """Brewster's (or the pseudo-Brewster) angle and the critical angle, once per group of
    channels with the same index."""
    marks = []
    if ch == "rgb" and not single:
        # channels with the same index share their marks
        groups = _channel_groups(lambda a, c: d["eta"][a] == d["eta"][c] and d["k"][a] == d["k"][c])
    else:
        groups = [["rgb".index(ch if ch != "rgb" else "r")]]
    for g in groups:
        c = g[0]
        many = len(groups) > 1
        colour = CHANNEL_COLOURS[c] if many else (60, 60, 60)
        suffix = f" ({', '.join(CHANNEL_NAMES[i] for i in g)})" if many else ""
        marks.append(Mark(f"{d['brewster_label']} {d['brewster'][c]:.1f}°{suffix}", float(d["brewster"][c]), colour))
        if np.isfinite(d["critical"][c]):
            marks.append(Mark(f"critical {d['critical'][c]:.1f}°{suffix}", float(d["critical"][c]),
                              colour if many else (200, 30, 30)))
    return marks


def _fresnel_medium(p, d, inside: bool) -> str:
    """The note that names the interface: conductor n + ik, Schlick's f0, or the dielectric's n."""
    if d["type"] == "conductor":
        medium = ("conductor n + ik = " + ", ".join(f"{e:.3g}+{kk:.3g}i" for e, kk in zip(d["eta"], d["k"]))
                  + "; pseudo-Brewster = angle of minimal R_p")
    elif d["type"] == "schlick":
        medium = f"Schlick f0 = {fmt_value(p[d['field']] if d['field'] in p else d['eta'])}; exact " \
                 f"curves of the dielectric with that f0, n = {fmt_value(d['eta'])}"
    else:
        n = 1.0 / d["eta"][0] if inside else d["eta"][0]
        medium = (f"from inside n = {n:.4g} to air (n2/n1 = {d['eta'][0]:.4g})" if inside
                  else f"from air to n = {n:.4g}")
    if "thin_film" in d:
        tf = thin_film.film_of(p)
        medium += (f"; thin film n = {tf.ior:.4g}, {tf.thickness_nm:g} nm "
                   "(Airy summation, RGB from 32 wavelengths); R_s, R_p, R: without the film")
    return medium


def _fresnel_figure(r: _Request) -> Figure:
    p, inside = r.p, r.inside
    d = fresnel_curves(p, inside=inside)
    single = np.allclose(d["eta"], d["eta"][0]) and np.allclose(d["k"], d["k"][0])
    ch = r.channel
    if ch == "lum":
        ch = "rgb" if single else "g"  # R of a luminance is no Fresnel curve: use green
    return Figure("fresnel", p.model, p, f"{r.label}: Fresnel reflectance ({d['field']})",
                  "angle of incidence (deg)", "reflectance", _fresnel_curve_list(d, ch, single),
                  _fresnel_marks(d, ch, single), (0.0, 90.0), (0.0, 1.04), r.sub, [_fresnel_medium(p, d, inside)],
                  {"channel": ch, "inside": bool(inside), "type": d["type"],
                   "brewster": d["brewster"], "critical": d["critical"], "eta": d["eta"], "k": d["k"]})


def _slice_figure(r: _Request) -> Figure:
    from viewer.plots.measured import slice_figure

    return slice_figure(r.p, r.label, r.sub, r.overlay, phi_d=r.phi_d, cos=r.cos)


def _theta_data(r: _Request, p):
    from viewer.plots import theta

    if r.kind == "theta_h":
        return theta.theta_h_curve(p, r.theta_d, cos=r.cos)
    if r.kind == "theta_d":
        return theta.theta_d_curve(p, r.theta_h, cos=r.cos)
    return theta.theta_v_curve(p, r.theta_i, r.phi, r.phi_v, cos=r.cos)


def _theta_figure(r: _Request) -> Figure:
    """BRDF Explorer's theta_h, theta_d and theta_v plots (``viewer.plots.theta``)."""
    d = _theta_data(r, r.p)
    what = "f cos(theta_i)" if r.cos else "f"
    curves = _rgb_curves(d["x"], r.shown(d["y"]), what, r.channel)
    if r.overlay is not None:
        d2 = _theta_data(r, r.overlay)
        curves += _rgb_curves(d2["x"], r.shown(d2["y"]), f"{r.overlay.model} {what}", r.channel, "dashed")
    from viewer.plots.theta import axis_top

    top, peak = axis_top(d["x"], [c.y for c in curves])
    held, x_label, x_range = {
        "theta_h": (f"theta_d = {d.get('theta_d', 0):g} deg, phi_d = 90 deg, phi_h = 0 (h in the x-z plane)",
                    "theta_h (deg)", (-90.0, 90.0)),
        "theta_d": (f"theta_h = {d.get('theta_h', 0):g} deg, phi_d = 90 deg, phi_h = 0", "theta_d (deg)",
                    (0.0, 90.0)),
        "theta_v": (f"light at theta_i = {d.get('theta_i', 0):g} deg, phi_i = {d.get('phi_i', 0):g} deg; view "
                    f"in the plane phi_v = {d.get('phi_v', 0):g} deg, theta_v > 0: mirror side",
                    "theta_v (deg)", (-90.0, 90.0)),
    }[r.kind]
    unit = " [1/sr]"
    notes = [held + ("; times cos theta_i of the light (N.L)" if r.cos else "")]
    if peak is not None:
        notes.append(f"toward grazing the curve runs off the axis, up to {peak:.4g} (the axis is set by "
                     f"|{x_label.split()[0]}| <= 80 deg)")
        for c in curves:  # drawn to just past the axis' top (the JSON's "f" keeps every value)
            c.extra.setdefault("unclipped", c.y)
            c.y = np.minimum(c.y, 2.0 * top)
    info = {"channel": r.channel, "transform": r.transform, "cos": r.cos,
            **{k: d[k] for k in ("theta_d", "theta_h", "theta_i", "phi_i", "phi_v", "phi_d") if k in d}}
    return Figure(r.kind, r.p.model, r.p, f"{r.label}: f against {x_label.split()[0]}", x_label,
                  r.y_format.format(what + unit), curves, [], x_range,
                  (0.0, nice_ceil(top * 1.05)), r.sub, notes, info)


_TERM_STYLE = {"D": ((31, 119, 180), "solid"), "G": ((44, 160, 44), "dashdot"),
               "1/(4 cos cos)": ((148, 103, 189), "dotted"), "product": (NEUTRAL, "solid")}
LOG_FLOOR = 1e-4  # the term view's log axis starts here (F, G and D's tails reach below it)


def _terms_figure(r: _Request) -> Figure:
    """The microfacet term view: D, F, G, 1 / (4 cos cos), their product and f (dashed)."""
    from viewer.plots.theta import term_curves

    d = term_curves(r.p, r.theta_i, r.phi)
    x = d["x"]

    def shown(y):
        return np.log10(np.maximum(y, LOG_FLOOR)) if r.log else np.asarray(y)

    ch = "lum" if r.channel == "rgb" else r.channel
    curves = [Curve("D", x, shown(d["D"]), *_TERM_STYLE["D"])]
    curves += _rgb_curves(x, shown(d["F"]), "F", ch, "dashed", color=(214, 120, 20))
    curves.append(Curve("G", x, shown(d["G"]), *_TERM_STYLE["G"]))
    curves.append(Curve("1/(4 cos cos)", x, shown(d["1/(4 cos cos)"]), *_TERM_STYLE["1/(4 cos cos)"]))
    curves += _rgb_curves(x, shown(d["product"]), "D F G / (4 cos cos)", ch, color=NEUTRAL)
    curves += _rgb_curves(x, shown(d["f"]), "f (the model)", ch, "dashed", color=(214, 39, 40))
    if "other" in d:
        curves += _rgb_curves(x, shown(d["other"]), "f - D F G / (4 cos cos)", ch, "dotted", color=(140, 86, 75))
    # the 1 / (4 cos cos) factor grows without bound at grazing angles: the axis ends where the
    # other terms do (its curve leaves the plot there)
    ys = np.concatenate([c.y for c in curves])
    rest = np.concatenate([c.y for c in curves if c.label != "1/(4 cos cos)"])
    if r.log:
        lo, hi = math.floor(float(ys.min())), math.ceil(float(rest.max()) + 1e-9)
        y_range, y_label = (float(lo), float(max(hi, lo + 1))), "log10 of the term"
    else:
        y_range, y_label = (0.0, nice_ceil(max(float(rest.max()), 1.0) * 1.05)), "term value"
    span = y_range[1] - y_range[0]
    for c in curves:  # a curve far off the axes is drawn to just past its edge (dashes of a 1e15 line never end)
        c.y = np.clip(c.y, y_range[0] - span, y_range[1] + span)
    notes = [f"view wo at theta_v = {d['theta_v']:g} deg; light wi in the plane phi = {d['phi']:g} deg, "
             f"theta_l > 0: mirror side; h = normalize(wi + wo)"]
    return Figure("terms", r.p.model, r.p, f"{r.label}: microfacet terms D, F, G", "theta_l (deg) of the light",
                  y_label, curves, [], (-90.0, 90.0), y_range, r.sub, notes,
                  {"channel": ch, "theta_v": d["theta_v"], "phi": d["phi"], "log": bool(r.log),
                   "log_floor": LOG_FLOOR if r.log else None})


def _spectral_figure(r: _Request) -> Figure:
    from viewer.plots.spectral import spectral_figure

    return spectral_figure(r.p, r.label, r.sub)


def _bouguer_figure(r: _Request) -> Figure:
    p = r.p
    d = bouguer_curve(p)
    curves = _rgb_curves(d["d"], d["T"], "T", r.channel)
    marks = []
    if d["thickness"]:
        marks.append(Mark(f"layer thickness {d['thickness']:g} {d['unit']}", d["thickness"]))
    unit = d["unit"]
    return Figure("bouguer", p.model, p, f"{r.label}: Bouguer's law T(d) = exp(-sigma_a d)",
                  f"distance d ({unit})", "transmittance T", curves, marks, (0.0, float(d["d"][-1])),
                  (0.0, 1.0), r.sub, [f"sigma_a = {fmt_value(d['sigma_a'])} 1/{unit} ({d['field']})"],
                  {"channel": r.channel, "sigma_a": d["sigma_a"], "unit": unit})


def _sampling_figure(r: _Request) -> Figure:
    p, theta_i, phi, seed = r.p, r.theta_i, r.phi, r.seed
    d = sampling_histogram(p, theta_i, phi, samples=r.samples, seed=seed)
    span = "cos theta from 1 (top) to -1" if d["sphere"] else "cos theta from 1 (top) to 0"
    notes = [f"wo at theta = {theta_i:g} deg, phi = {phi:g} deg; {d['samples']} samples (seed {seed}); cells: "
             f"{d['rows']} rows ({span}) x {d['cols']} columns of phi",
             f"chi-square {d['chi2']:.1f}, {d['dof']} dof: p = {d['p_value']:.3g}; failed samples {d['failed']}"]
    return Figure("sampling", p.model, p, f"{r.label}: importance sampling against the pdf",
                  "phi (deg)", span, [], [], (0.0, 360.0), (0.0, 1.0), r.sub, notes, d)


_FIGURES = {"polar": _polar_figure, "lobe": _lobe_figure, "albedo": _albedo_figure, "fresnel": _fresnel_figure,
            "bouguer": _bouguer_figure, "spectral": _spectral_figure, "sampling": _sampling_figure,
            "slice": _slice_figure, "theta_h": _theta_figure, "theta_d": _theta_figure, "theta_v": _theta_figure,
            "terms": _terms_figure}
