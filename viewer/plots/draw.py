"""The figures drawn (Pillow, through ``viewer.plots.canvas``): cartesian curves with marks, the
polar lobe, the shaded 3D lobe, the sampling panels; the spectral and slice figures are drawn by
their own modules. ``render_figure`` picks the drawing of a figure's kind."""

from __future__ import annotations

import math

import numpy as np

from viewer import ViewerError
from viewer.plots.canvas import (Canvas, arrow, clipped_layer, colormap, curve_pixels, draw_grid, draw_header,
                                 draw_legend, legend_beside_or_below, nice_ticks, paste_clipped, place_labels,
                                 tick_label)
from viewer.plots.figure_types import Figure, fmt_value

def _items(fig):
    return [(c.label, c.color, c.style) for c in fig.curves]


def cartesian_frame(cv, fig, width, height):
    """The axes' data rect (canvas pixels) of a cartesian figure and its legend outside it:
    (box, legend plan or None, legend's top left corner). Beside the axes on the right when it
    fits there in one column, else under the x axis' label."""
    left, right, top, bottom = 78, 24, 58 + 14 * len(fig.notes), 56
    where, plan = legend_beside_or_below(cv, _items(fig), width, height - top - bottom)
    if where == "beside":
        right += plan.w / cv.ss + 14
    elif where == "below":
        bottom += plan.h / cv.ss + 8
    x0, y0, x1, y1 = cv.s(left), cv.s(top), cv.s(width - right), cv.s(height - bottom)
    corner = (x1 + cv.s(14), y0) if where == "beside" else (x0, y1 + cv.s(52))
    return (x0, y0, x1, y1), plan, corner


def _draw_cartesian(cv, fig, width, height):
    box, plan, corner = cartesian_frame(cv, fig, width, height)
    x0, y0, x1, y1 = box
    (xa, xb), (ya, yb) = fig.x_range, fig.y_range

    def to_px(x, y):
        return x0 + (np.asarray(x) - xa) / (xb - xa) * (x1 - x0), y1 - (np.asarray(y) - ya) / (yb - ya) * (y1 - y0)

    d = cv.draw
    xt, yt = nice_ticks(xa, xb, 9), nice_ticks(ya, yb, 5)
    for v in xt:
        px, _ = to_px(v, ya)
        d.line([(px, y0), (px, y1)], fill=(232, 232, 232), width=cv.s(1))
        d.line([(px, y1), (px, y1 + cv.s(5))], fill=(60, 60, 60), width=cv.s(1))
        cv.text((px, y1 + cv.s(8)), tick_label(v, xt), px=12, anchor="ma")
    for v in yt:
        _, py = to_px(xa, v)
        d.line([(x0, py), (x1, py)], fill=(232, 232, 232), width=cv.s(1))
        d.line([(x0 - cv.s(5), py), (x0, py)], fill=(60, 60, 60), width=cv.s(1))
        cv.text((x0 - cv.s(8), py), tick_label(v, yt), px=12, anchor="rm")
    d.rectangle([x0, y0, x1, y1], outline=(60, 60, 60), width=cv.s(1))
    cv.text(((x0 + x1) / 2, y1 + cv.s(28)), fig.x_label, px=14, anchor="ma")
    cv.vtext((cv.s(16), (y0 + y1) / 2), fig.y_label, px=14)
    layer, ld = clipped_layer(cv)
    # marks: dashed vertical lines, labels staggered from the top
    for i, m in enumerate(fig.marks):
        px, _ = to_px(m.x, ya)
        cv.polyline([(px, y0), (px, y1)], m.color + (255,), 1.5, "dashed", draw=ld)
    for c in fig.curves:
        px, py = to_px(c.x, c.y)
        cv.polyline(list(zip(px, py)), tuple(c.color) + (255,), 2.2, c.style, draw=ld)
    paste_clipped(cv, layer, box)
    legend = draw_legend(cv, plan, *corner)
    pts = curve_pixels(fig, to_px, cv.s(2))
    spots = place_labels(cv, [(float(to_px(m.x, ya)[0]), m.label) for m in fig.marks], box, *pts, [legend])
    for m, (tx, ty, tw, th, _) in zip(fig.marks, spots):
        cv.draw.rectangle([tx - cv.s(2), ty - cv.s(2), tx + tw + cv.s(2), ty + th], fill=(255, 255, 255))
        cv.text((tx, ty), m.label, px=12, fill=m.color, anchor="lt")


def _shown(fig, v) -> float:
    """A value as the figure plots it (log10(1 + v) with --log)."""
    return float(np.log10(1.0 + v)) if fig.info.get("transform") else float(v)


def polar_frame(cv, fig, width, height):
    """The polar figure's semicircle (centre x, y and radius R, canvas pixels) and its legend
    outside it: (cx, cy, R, legend plan or None, legend's top left corner). Beside the
    semicircle's right end when it fits there in one column, else under the radius' label."""
    top = 58 + 14 * len(fig.notes)
    where, plan = legend_beside_or_below(cv, _items(fig), width, height - top - 70)
    room_w = width - (plan.w / cv.ss + 12 if where == "beside" else 0)
    room_h = height - top - 70 - (plan.h / cv.ss + 10 if where == "below" else 0)
    radius_px = max(20.0, min((room_w - 120) / 2, room_h))
    cx, cy = cv.s(room_w / 2), cv.s(top + 24 + radius_px)
    corner = (cv.s(room_w), cv.s(top + 24)) if where == "beside" else (cv.s(width / 2) - (plan.w / 2 if plan else 0),
                                                                       cy + cv.s(44))
    return cx, cy, cv.s(radius_px), plan, corner


def _draw_polar(cv, fig, width, height):
    cx, cy, R, plan, corner = polar_frame(cv, fig, width, height)
    rmax = fig.y_range[1]
    d = cv.draw
    # rings and spokes
    rt = [v for v in nice_ticks(0.0, rmax, 4) if v > 0]
    for v in rt:
        rr = R * v / rmax
        d.arc([cx - rr, cy - rr, cx + rr, cy + rr], 180, 360, fill=(215, 215, 215), width=cv.s(1))
        cv.text((cx + rr + cv.s(2), cy + cv.s(4)), tick_label(v, rt), px=11, fill=(110, 110, 110), anchor="ma")
    for a in range(-90, 91, 15):
        t = math.radians(a)
        ex, ey = cx + R * math.sin(t), cy - R * math.cos(t)
        d.line([(cx, cy), (ex, ey)], fill=(225, 225, 225), width=cv.s(1))
        lx, ly = cx + (R + cv.s(16)) * math.sin(t), cy - (R + cv.s(14)) * math.cos(t)
        cv.text((lx, ly), f"{a}°", px=11, fill=(90, 90, 90), anchor="mm")
    d.arc([cx - R, cy - R, cx + R, cy + R], 180, 360, fill=(120, 120, 120), width=cv.s(1))
    d.line([(cx - R - cv.s(20), cy), (cx + R + cv.s(20), cy)], fill=(60, 60, 60), width=cv.s(2))
    cv.text((cx - R + cv.s(4), cy + cv.s(4)), "surface", px=11, fill=(90, 90, 90), anchor="la")
    cv.text((cx, cy + cv.s(22)), f"radius: {fig.y_label}", px=12, fill=(50, 50, 50), anchor="ma")
    # incident and mirror directions
    ti = math.radians(fig.info["theta_i"])
    far = (cx - R * 1.0 * math.sin(ti), cy - R * 1.0 * math.cos(ti))
    arrow(cv, far, (cx - cv.s(6) * math.sin(ti), cy - cv.s(6) * math.cos(ti)), (230, 120, 0), 2.0, 12)
    mid = (cx - 0.72 * R * math.sin(ti), cy - 0.72 * R * math.cos(ti))
    cv.text((mid[0] - cv.s(8) * math.cos(ti), mid[1] + cv.s(8) * math.sin(ti)),
            f"light (wi), theta_i = {fig.info['theta_i']:g}°", px=12, fill=(200, 100, 0),
            anchor="rt" if ti > math.radians(12) else "lm")
    mirror = (cx + R * math.sin(ti), cy - R * math.cos(ti))
    cv.polyline([(cx, cy), mirror], (150, 150, 150), 1.2, "dotted")
    if not fig.info.get("delta"):
        mm = (cx + 0.93 * R * math.sin(ti), cy - 0.93 * R * math.cos(ti))
        cv.text((mm[0] + cv.s(6) * math.cos(ti), mm[1] + cv.s(6) * math.sin(ti)), "mirror", px=11,
                fill=(120, 120, 120), anchor="lt")
    # lobe curves
    layer, ld = clipped_layer(cv)
    lines = []
    for c in fig.curves:  # every fill first: a fill drawn later would overwrite the lines it covers
        t = np.radians(np.asarray(c.x))
        r = R * np.clip(np.asarray(c.y), 0, None) / rmax
        pts = list(zip(cx + r * np.sin(t), cy - r * np.cos(t)))
        ld.polygon(pts, fill=tuple(c.color) + (28,))
        lines.append((pts, c))
    for pts, c in lines:
        cv.polyline(pts, tuple(c.color) + (255,), 2.2, c.style, draw=ld)
    paste_clipped(cv, layer, (0, 0, cv.w, cy + 1))
    for dl in fig.info.get("delta", []):
        refl = np.asarray(dl["reflectance"], float)
        rr = R * min(1.0, _shown(fig, np.max(refl)) / rmax)
        t = math.radians(dl["theta_o"])
        tip = (cx + rr * math.sin(t), cy - rr * math.cos(t))
        arrow(cv, (cx, cy), tip, (120, 40, 160), 3.0, 14)
        mid = (cx + 0.55 * rr * math.sin(t), cy - 0.55 * rr * math.cos(t))
        cv.text((mid[0] + cv.s(10) * math.cos(t), mid[1] + cv.s(10) * math.sin(t)),
                "delta lobe, R = " + fmt_value(refl), px=12, fill=(120, 40, 160), anchor="lt")
    draw_legend(cv, plan, *corner)


def _view_basis(elevation: float, azimuth: float):
    """(view, right, up) of an oblique view of the hemisphere: ``view`` points toward the viewer."""
    el, az = math.radians(elevation), math.radians(azimuth)
    view = np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])  # toward viewer
    right = np.array([-math.sin(az), math.cos(az), 0.0])
    return view, right, np.cross(view, right)


def _draw_lobe(cv, fig, width, height, elevation=25.0, azimuth=-75.0):
    top = 58 + 14 * len(fig.notes)
    view, right, up = _view_basis(elevation, azimuth)
    x, y, z = (np.asarray(fig.info[k], float) for k in "xyz")
    value = np.asarray(fig.info["value"], float)
    rmax = fig.y_range[1]
    P = np.stack([x, y, z], axis=-1) / rmax  # unit-ish
    scale = cv.s(min((width - 200) / 2.4, (height - top - 40) / 1.6))
    cx, cy = cv.s((width - 90) / 2), cv.s(top + 20) + scale * 1.1

    def proj(q):
        q = np.asarray(q, float)
        return cx + scale * (q @ right), cy - scale * (q @ up)

    _lobe_ground(cv, proj)
    vmax = float(value.max()) if value.size else 0.0
    _lobe_surface(cv, proj, P, value, view, vmax)
    _lobe_arrows(cv, fig, proj, rmax)
    _lobe_colour_bar(cv, fig, width, height, top, vmax)


def _lobe_ground(cv, proj):
    """The ground disc and the x, y, z axes."""
    ring = np.stack([np.cos(np.linspace(0, 2 * np.pi, 181)), np.sin(np.linspace(0, 2 * np.pi, 181)),
                     np.zeros(181)], -1)
    gx, gy = proj(ring)
    cv.draw.polygon(list(zip(gx, gy)), fill=(240, 240, 240), outline=(170, 170, 170))
    for lab, vec in (("x (tangent)", [1.15, 0, 0]), ("y", [0, 1.15, 0]), ("z (normal)", [0, 0, 1.15])):
        a, b = proj(np.zeros(3)), proj(np.array(vec, float))
        arrow(cv, (a[0], a[1]), (b[0], b[1]), (110, 110, 110), 1.2, 8)
        cv.text((b[0] + cv.s(4), b[1]), lab, px=11, fill=(90, 90, 90), anchor="lm")


def _lobe_surface(cv, proj, P, value, view, vmax):
    """The lobe's shaded quads, far to near (painter's algorithm), coloured by value."""
    quads = np.stack([P[:-1, :-1], P[1:, :-1], P[1:, 1:], P[:-1, 1:]], axis=2)  # (nt-1, np-1, 4, 3)
    qv = (value[:-1, :-1] + value[1:, :-1] + value[1:, 1:] + value[:-1, 1:]) / 4
    qf = quads.reshape(-1, 4, 3)
    qv = qv.ravel()
    depth = qf.mean(axis=1) @ view
    n = np.cross(qf[:, 2] - qf[:, 0], qf[:, 3] - qf[:, 1])
    nn = np.linalg.norm(n, axis=-1)
    light = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    shade = np.where(nn > 0, np.abs(n @ light) / np.maximum(nn, 1e-30), 0.6)
    colours = colormap(qv / vmax if vmax > 0 else qv) * (0.55 + 0.45 * shade)[:, None]
    layer, ld = clipped_layer(cv)
    for i in np.argsort(depth):
        if qv[i] <= 0 and vmax > 0 and np.allclose(qf[i], 0):
            continue
        px, py = proj(qf[i])
        col = tuple(int(c) for c in colours[i])
        ld.polygon(list(zip(px, py)), fill=col + (235,), outline=tuple(int(c * 0.75) for c in col) + (255,))
    paste_clipped(cv, layer, (0, 0, cv.w, cv.h))


def _lobe_arrows(cv, fig, proj, rmax):
    """The incident direction (toward the light) and the delta lobes."""
    wi = np.asarray(fig.info["wi"], float)
    a, b = proj(wi * 1.08), proj(wi * 0.05)
    arrow(cv, (a[0], a[1]), (b[0], b[1]), (230, 120, 0), 2.0, 12)
    cv.text((a[0], a[1] + cv.s(6)), f"light (wi), theta_i = {fig.info['theta_i']:g}°", px=12,
            fill=(200, 100, 0), anchor="ma")
    for dl in fig.info.get("delta", []):
        tip = proj(np.asarray(dl["wo"], float) * min(1.0, _shown(fig, np.max(dl["reflectance"])) / rmax))
        o = proj(np.zeros(3))
        arrow(cv, (o[0], o[1]), (tip[0], tip[1]), (120, 40, 160), 3.0, 14)
        cv.text((tip[0] + cv.s(6), tip[1]), "delta lobe, R = " + fmt_value(np.asarray(dl["reflectance"])), px=12,
                fill=(120, 40, 160), anchor="lm")


def _lobe_colour_bar(cv, fig, width, height, top, vmax):
    d = cv.draw
    bx0, bx1 = cv.s(width - 70), cv.s(width - 52)
    by0, by1 = cv.s(top + 30), cv.s(height - 50)
    for j in range(int(by1 - by0)):
        t = 1 - j / max(1, by1 - by0 - 1)
        d.line([(bx0, by0 + j), (bx1, by0 + j)], fill=tuple(int(c) for c in colormap(t)))
    d.rectangle([bx0, by0, bx1, by1], outline=(90, 90, 90), width=cv.s(1))
    for v in nice_ticks(0.0, vmax if vmax > 0 else 1.0, 4):
        yy = by1 - (by1 - by0) * v / (vmax if vmax > 0 else 1.0)
        d.line([(bx1, yy), (bx1 + cv.s(4), yy)], fill=(60, 60, 60), width=cv.s(1))
        cv.text((bx1 + cv.s(6), yy), f"{v:.3g}", px=11, anchor="lm")
    cv.vtext((cv.s(width - 84), (by0 + by1) / 2), "f cos(theta_o)" + (" (log10(1+y))" if fig.info.get("transform") else ""),
             px=12)


def _draw_sampling(cv, fig, width, height):
    """Two by two: histogram | integrated pdf, difference | point cloud."""
    d = fig.info
    top = cv.s(62 + 14 * len(fig.notes))
    gap_x, gap_y = cv.s(36), cv.s(44)
    left = cv.s(40)
    gw = (cv.s(width) - left - cv.s(16) - gap_x) / 2
    gh = (cv.s(height) - top - cv.s(16) - gap_y - cv.s(30)) / 2
    vmax = max(float(np.max(d["observed"])), float(np.max(d["expected"])), 1e-12)
    panels = (("histogram of samples", d["observed"], False, vmax),
              ("integrated pdf x samples", d["expected"], False, vmax),
              ("difference (o - e) / sqrt(e)", d["difference"], True, max(3.0, float(np.abs(d["difference"]).max()))))
    for i, (title, a, signed, vm) in enumerate(panels):
        x0 = left + (i % 2) * (gw + gap_x)
        y0 = top + cv.s(16) + (i // 2) * (gh + gap_y)
        box = (x0, y0, x0 + gw, y0 + gh)
        draw_grid(cv, np.asarray(a, float), box, signed, vm)
        cv.text((x0 + gw / 2, y0 - cv.s(15)), title, px=12, anchor="la" if False else "ma")
        scale = f"white 0 .. black {vm:.3g} samples" if not signed else f"blue -{vm:.3g} .. red +{vm:.3g} sigma"
        cv.text((x0 + gw / 2, box[3] + cv.s(4)), scale + "; phi 0 .. 360 deg across", px=10, fill=(80, 80, 80),
                anchor="ma")
        if i % 2 == 0:
            cv.vtext((x0 - cv.s(14), y0 + gh / 2), fig.y_label, px=10)
    # point cloud: the hemisphere (sphere) seen obliquely, as the 3D lobe
    x0 = left + gw + gap_x
    y0 = top + cv.s(16) + gh + gap_y
    view, right, up = _view_basis(25.0, -75.0)
    scale = min(gw / 2.3, gh / (2.2 if d["sphere"] else 1.45))
    cx, cy = x0 + gw / 2, y0 + (gh / 2 if d["sphere"] else gh * 0.68)

    def proj(q):
        q = np.asarray(q, float)
        return cx + scale * (q @ right), cy - scale * (q @ up)

    ang = np.linspace(0, 2 * np.pi, 181)
    ring = np.stack([np.cos(ang), np.sin(ang), np.zeros_like(ang)], -1)
    gx, gy = proj(ring)
    cv.draw.polygon(list(zip(gx, gy)), fill=(242, 242, 242), outline=(170, 170, 170))
    pts = np.asarray(d["points"], float).reshape(-1, 3)
    depth = pts @ view
    px, py = proj(pts)
    r = cv.s(1.5)
    near = (depth - depth.min()) / max(float(np.ptp(depth)), 1e-12) if len(pts) else depth
    for j in np.argsort(depth):
        base = np.array((31, 119, 180) if pts[j, 2] >= 0 else (214, 39, 40), float)
        col = tuple(int(c) for c in base * (0.55 + 0.45 * near[j]) + 255 * 0.0)
        cv.draw.ellipse([px[j] - r, py[j] - r, px[j] + r, py[j] + r], fill=col)
    wo = np.asarray(d["wo"], float)
    a, b = proj(wo * 1.15), proj(np.zeros(3))
    arrow(cv, (a[0], a[1]), (b[0], b[1]), (230, 120, 0), 2.0, 12)
    cv.text((a[0], a[1] - cv.s(4)), "wo", px=12, fill=(200, 100, 0), anchor="md")
    cv.text((x0 + gw / 2, y0 - cv.s(15)), f"{len(pts)} sampled directions wi"
            + (" (red: transmitted)" if d["sphere"] else ""), px=12, anchor="ma")


def render_figure(fig: Figure, width: int = 900, height: int = 600, ss: int = 3) -> np.ndarray:
    """The figure drawn with Pillow as (height, width, 3) uint8 sRGB, anti-aliased by drawing at
    ``ss`` x the size and box-filtering down."""
    if not (200 <= width <= 4000 and 150 <= height <= 4000):
        raise ViewerError(f"--width/--height: {width}x{height} is out of range; allowed: width 200..4000, "
                          "height 150..4000")
    cv = Canvas(width, height, ss)
    draw_header(cv, fig, width)
    if fig.kind == "polar":
        _draw_polar(cv, fig, width, height)
    elif fig.kind == "lobe":
        _draw_lobe(cv, fig, width, height)
    elif fig.kind == "spectral":
        from viewer.plots.spectral import draw_spectral

        draw_spectral(cv, fig, width, height)
    elif fig.kind == "sampling":
        _draw_sampling(cv, fig, width, height)
    elif fig.kind == "slice":
        from viewer.plots.measured import draw_slice

        draw_slice(cv, fig, width, height)
    else:
        _draw_cartesian(cv, fig, width, height)
    return cv.image()
