"""The Check tab: the report card of one material (``viewer.app.check_tab.CheckTab``: finite,
non-negative, reciprocal, energy, the numpy twin and the sampler, as ``brdf-viewer check``)."""

from __future__ import annotations


def draw(panel, names, materials):
    if panel.check_tab is None:  # made when the tab is first shown
        from viewer.app.check_tab import CheckTab

        panel.check_tab = CheckTab()
    panel.check_tab.draw(names, materials, panel)
