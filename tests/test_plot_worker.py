"""The plots panel's worker thread (PlotsPanel.background, the window's way): data not cached
yet are computed beside the frames, never in the frame that asks for them; the tab is told
(None, or the last data with the material marked as updating) until they arrive."""

import threading

import pytest

from viewer import plots
from viewer.app.plots_panel import PlotsPanel
from viewer.brdf.presets import get_preset


def _gold():
    return plots.as_params(get_preset("gold"))


def _wait(panel):
    for _ in range(500):
        if not panel.computing:
            return
        threading.Event().wait(0.01)
    raise AssertionError("the worker never finished")


def test_data_are_computed_in_the_worker_and_arrive_later():
    panel = PlotsPanel()
    panel.background = True
    gate, ran_on, woken = threading.Event(), [], []
    panel.wake = lambda: woken.append(1)

    def fn():
        ran_on.append(threading.get_ident())
        gate.wait(10)
        return {"x": 1}

    p = _gold()
    try:
        assert panel.data("polar", "ball", p, 45.0, fn=fn) is None  # nothing shown yet: the tab says computing
        assert panel.computing
        assert panel.data("polar", "ball", p, 45.0, fn=fn) is None  # asked again: not submitted twice
        gate.set()
        _wait(panel)
        assert panel.data("polar", "ball", p, 45.0, fn=fn) == {"x": 1}
        assert ran_on and ran_on[0] != threading.get_ident() and len(ran_on) == 1
        assert woken  # the window's loop is woken to draw the result
        assert not panel.computing
    finally:
        gate.set()
        panel.close()


def test_while_new_data_compute_the_last_are_drawn_and_marked_updating():
    panel = PlotsPanel()
    panel.background = True
    gate = threading.Event()
    p = _gold()
    try:
        panel.data("polar", "ball", p, 45.0, fn=lambda: "at 45")
        _wait(panel)
        assert panel.data("polar", "ball", p, 45.0, fn=lambda: "at 45") == "at 45"
        panel.updating = set()
        shown = panel.data("polar", "ball", p, 60.0, fn=lambda: gate.wait(10) and "at 60")
        assert shown == "at 45" and panel.updating == {"ball"}  # the slider moved: the old curve, labelled
        gate.set()
        _wait(panel)
        assert panel.data("polar", "ball", p, 60.0, fn=lambda: "unused") == "at 60"
    finally:
        gate.set()
        panel.close()


def test_an_error_in_the_worker_reaches_the_tab():
    panel = PlotsPanel()
    panel.background = True

    def bad():
        raise ValueError("no such curve")

    try:
        assert panel.cached(("k",), bad) is None
        _wait(panel)
        with pytest.raises(ValueError, match="no such curve"):
            panel.cached(("k",), bad)
    finally:
        panel.close()


def test_without_the_worker_data_are_computed_at_once():
    panel = PlotsPanel()
    assert panel.data("polar", "ball", _gold(), 45.0, fn=lambda: "now") == "now"
    assert not panel.computing
