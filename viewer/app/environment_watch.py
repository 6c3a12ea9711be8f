"""The environment light's background prefilter: a map the disk cache lacks is drawn at once
with a quick prefilter (``viewer.gl.ibl.IBL.defer``), its full prefilter in a child process
(``viewer.app.prefetch.MapPrefilter``), never on the window's thread; once the disk cache holds
it, the view is drawn again with it. ``EnvironmentWatch`` is held by
``viewer.app.session.Session`` as ``session.env``. No imgui, no glfw."""

from __future__ import annotations

import time


class EnvironmentWatch:
    """The background prefilter of ``session``'s environment map."""

    def __init__(self, session):
        self.session = session
        self._job = None
        self._failed: set[str] = set()

    def release(self) -> None:
        """Stop the prefilter's child."""
        if self._job is not None:
            self._job.stop()
            self._job = None

    @property
    def provisional(self) -> bool:
        """The environment light is drawn with a quick prefilter while the full one runs in the
        background (or failed there)."""
        ibl = self.session.renderer.ibl()
        return ibl.defer and ibl.provisional is not None

    def watch(self):
        """A map drawn with a quick prefilter (``viewer.gl.ibl.IBL.defer``): its full prefilter
        in a child process; once the disk cache holds it, the view is drawn again with it."""
        s = self.session
        ibl = s.renderer.ibl()
        job = self._job
        if job is not None:
            if job.key != ibl.provisional:  # another map now (or the full one is read): not needed
                job.stop(wait=False)  # reaped on a thread: no frame waits for the child to exit
                self._job = job = None
            elif job.ready:
                self._job = None
                s.dirty = True  # the next frame reads it from the disk cache
                s.notify(f"environment light: fully prefiltered in the background "
                         f"({time.perf_counter() - job.started:.1f} s)")
                return
            elif job.finished:
                self._job = None
                self._failed.add(job.key)
                s.notify(f"environment light stays a quick prefilter: {job.error}", error=True)
                return
        if ibl.defer and ibl.provisional is not None and job is None and ibl.provisional not in self._failed:
            from viewer.app.prefetch import MapPrefilter

            self._job = MapPrefilter(ibl.provisional, ibl.pending_map)
            if self._job.error:
                self._failed.add(ibl.provisional)
                s.notify(self._job.error, error=True)
                self._job = None
            else:
                s.notify("environment light: a quick low-resolution prefilter until the full one, "
                         "prefiltered in the background, is ready")
