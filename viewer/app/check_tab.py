"""The plots window's *Check* tab: the report card (``viewer.brdf.report_card``, the checks of
``brdf-viewer check``) of one shown material, built-in or a ``.brdf`` file: each check's result
and number, and the directional albedo against the incident angle. The card is computed when the
material (or a parameter) changes and kept until then; it takes 0.3 to 2 s, computed in the
plots panel's worker thread in the window (the tab says so meanwhile)."""

from __future__ import annotations

import json

_FIELDS = ("min", "max_rel_error", "max_albedo", "p_value", "count")


def card(p) -> dict:
    """The report card of material parameters ``p``."""
    from viewer import brdf
    from viewer.brdf.report_card import report

    model = brdf.get(p.model)
    if brdf.is_file(p):
        model = model.of(p)
    return report(model, p, model.bfile.path.name if brdf.is_file(p) else p.model)


def card_or_error(p) -> tuple:
    """(card, "") or (None, the error's first line)."""
    from viewer import ViewerError

    try:
        return card(p), ""
    except ViewerError as e:
        return None, str(e).splitlines()[0]


_RGB = ((0.9, 0.3, 0.3), (0.35, 0.8, 0.35), (0.35, 0.55, 0.95))   # the albedo's channels
_BOUND, _ALLOWED = (0.85, 0.85, 0.85), (0.95, 0.65, 0.2)


class CheckTab:
    """``draw(names, materials)`` inside the plots window's tab."""

    def __init__(self):
        self.material = None
        self._key = None
        self._card = None
        self._error = ""
        self._want = None   # the card to show: (material, parameters, how many times checked again)
        self._round = 0

    def draw(self, names, materials, panel=None) -> None:
        """``panel``: the plots panel, whose ``cached(key, fn)`` computes the card in its worker
        (None while it does) and whose legend goes under the plot; without one the card is
        computed here and the plot keeps implot's own legend."""
        from imgui_bundle import imgui, implot

        cached = panel.cached if panel is not None else None

        if self.material not in names:
            self.material = names[0]
        ch, i = imgui.combo("material##check", names.index(self.material), list(names))
        if ch:
            self.material = names[i]
        p = materials[self.material]
        key = (self.material, json.dumps(p.to_plain(), sort_keys=True))
        again = imgui.button("check again##check")
        if (key != self._key or again) and not imgui.is_any_item_active():
            self._key = key
            self._round += bool(again)
            self._want = key + (self._round,)
            if cached is None:
                self._card, self._error = card_or_error(p)
        if cached is not None and self._want is not None:
            got = cached(("check",) + self._want, lambda p=p: card_or_error(p))
            if got is None:
                imgui.text_wrapped(f"computing the report card of {self._want[0]} ...")
                return
            self._card, self._error = got
        if self._error:
            imgui.text_colored(imgui.ImVec4(1.0, 0.35, 0.3, 1.0), self._error)
            return
        c = self._card
        if c is None:
            return
        imgui.text(f"{c['file']}: {'PASS' if c['pass'] else 'FAIL'}  (brdf-viewer check, see docs/write-your-own-brdf.md)")
        if imgui.begin_table("##checks", 3, imgui.TableFlags_.borders | imgui.TableFlags_.sizing_stretch_prop):
            for name, r in c["checks"].items():
                imgui.table_next_row()
                imgui.table_next_column()
                imgui.text(name)
                imgui.table_next_column()
                col = imgui.ImVec4(0.3, 0.85, 0.4, 1.0) if r["pass"] else imgui.ImVec4(1.0, 0.35, 0.3, 1.0)
                imgui.text_colored(col, "pass" if r["pass"] else "FAIL")
                imgui.table_next_column()
                imgui.text(", ".join(f"{k} {r[k]:.4g}" if isinstance(r[k], float) else f"{k} {r[k]}"
                                     for k in _FIELDS if k in r))
            imgui.end_table()
        e = c["checks"]["energy"]
        import numpy as np

        th = np.asarray(e["theta_deg"], dtype=np.float64)
        alb = np.asarray(e["albedo"], dtype=np.float64)
        bound = float(e["bound"])
        # what the check allows above the bound at each angle (a few standard errors of the
        # estimate's own noise): an albedo curve above this line fails the energy check
        allowed = bound + np.asarray(e["tolerance"], dtype=np.float64).min(axis=1)
        noise = float(np.max(e["noise"]))
        imgui.text_wrapped(f"energy: largest noise (1 s.e.) {noise:.2g}, allowed above {bound:g} "
                           f"up to {allowed.max() - bound:.2g}")
        lines = [(f"albedo {c}", th, alb[:, k], col) for k, (c, col) in enumerate(zip("rgb", _RGB))]
        lines += [(f"{bound:g} (energy bound)", np.array([0.0, 90.0]), np.array([bound, bound]), _BOUND),
                  ("allowed (bound + tolerance)", th, allowed, _ALLOWED)]
        size = panel.plot_size() if panel is not None else imgui.ImVec2(-1, -1)
        if panel is not None:
            panel.begin_frame_rect(size)
        flags = implot.Flags_.no_legend if panel is not None else 0
        if implot.begin_plot("directional albedo##check", size, flags):
            implot.setup_axes("theta (deg)", "albedo")
            # the whole of every line in view, the bound and the allowed line included
            implot.setup_axes_limits(0.0, 90.0, 0.0, 1.05 * max(float(alb.max()), float(allowed.max())),
                                     implot.Cond_.always)
            for label, x, y, col in lines:
                implot.plot_line(label, x, np.ascontiguousarray(y, dtype=np.float64),
                                 implot.Spec(line_color=imgui.ImVec4(*col, 1.0), line_weight=2.0))
                if panel is not None:
                    panel.key(label, col)
            implot.end_plot()
