"""The plots panel's data (``PlotsPanel.store``, viewer/app/plots_panel.py): each tab's curves
cached per (kind, material parameters, angles) and recomputed only when those change; in the
window (``background``) computed in one worker thread beside the frames (numpy releases the
interpreter for most of the work), so switching tabs or opening a step whose plot needs seconds
of numpy never freezes a frame; the last data of a kind and material are drawn meanwhile
(``updating``); the albedo curve (tens of ms per material) waits while a slider is held
(``albedo_stale``) and is recomputed when it is released. No drawing."""

from __future__ import annotations

from viewer import plots
from viewer.app.plot_tabs.common import params_key

CACHE_MAX = 256


class PlotData:
    """The tabs' data: ``cached`` (any key), ``data`` (per kind and material), ``albedo``;
    ``background``: computed in a worker thread (None until it has them), ``wake`` called from
    it when a result is ready (the window's loop)."""

    def __init__(self):
        self.background = False  # True (the window): data computed in a worker thread
        self.wake = None         # called from the worker when a result is ready
        self.updating: set[str] = set()  # materials drawn with their last data this frame
        self.albedo_stale: set[str] = set()  # materials whose albedo curve waits for a slider
        self._cache: dict = {}
        self._jobs: dict = {}    # key -> Future of data being computed
        self._pool = None
        self._last: dict = {}    # (kind, material) -> the data drawn last
        self._albedo_shown: dict[str, tuple] = {}

    @property
    def computing(self) -> bool:
        """Data for a tab drawn are being computed in the worker thread."""
        return any(not f.done() for f in self._jobs.values())

    def shutdown(self) -> None:
        """The worker thread stops after the job it runs; the jobs queued are dropped."""
        if self._pool is not None:
            self._pool.shutdown(wait=False, cancel_futures=True)
            self._pool = None

    def cached(self, key, fn):
        """``fn()`` once per ``key``; with ``background``, None until the worker thread has it."""
        if key in self._cache:
            return self._cache[key]
        if self.background:
            job = self._jobs.get(key)
            if job is None:
                self._submit(key, fn)
                return None
            if not job.done():
                return None
            del self._jobs[key]
            value = job.result()  # an exception raised there is raised here, as computed here
        else:
            value = fn()
        if len(self._cache) > CACHE_MAX:
            self._cache.clear()
        self._cache[key] = value
        return value

    def _submit(self, key, fn):
        from concurrent.futures import ThreadPoolExecutor

        if self._pool is None:
            self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="plots")
        for k in [k for k, f in self._jobs.items() if not f.running() and f.cancel()]:
            del self._jobs[k]  # queued for a tab or angle no longer drawn: the newest asks first
        job = self._pool.submit(fn)
        job.add_done_callback(lambda _: self.wake and self.wake())
        self._jobs[key] = job

    def data(self, kind, name, p, *args, fn):
        """``fn()`` cached per (kind, material, its parameters, ``args``). While the worker
        computes it, the last data of this kind and material are returned (a slider dragged,
        another angle; the tab says they are being updated), or None when there are none."""
        d = self.cached((kind, name, params_key(p)) + args, fn)
        if d is not None:
            self._last[(kind, name)] = d
            return d
        last = self._last.get((kind, name))
        if last is not None:
            self.updating.add(name)
        return last

    def albedo(self, name, p, held: bool | None = None):
        """The albedo curve of ``p``; while a slider is held (``held``, by default imgui's
        any item active), the last one shown (marked stale)."""
        if held is None:
            from imgui_bundle import imgui

            held = imgui.is_any_item_active()
        key = ("albedo", name, params_key(p))
        if key not in self._cache and held and name in self._albedo_shown:
            self.albedo_stale.add(name)  # a slider is held: keep the old curve until it is released
            return self._albedo_shown[name]
        self.albedo_stale.discard(name)
        d = self.cached(key, lambda: plots.albedo_curve(p))
        if d is not None:
            self._albedo_shown[name] = d
        return d
