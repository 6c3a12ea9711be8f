"""*Prepare lecture*: trace every lecture step that has traced chains at one view size into the
traced-frame cache (``viewer.gl.trace_cache``), so that in class each such step opens fully
traced. The window runs it a slice per frame (``step``), between its own frames;
``brdf-viewer bake --lecture --width W --height H`` runs it to the end (``run``). Both trace the
way the window's progressive trace does (``viewer.gl.raytrace.ProgressiveTrace``, full
resolution only), so the entry is what the window would have traced live."""

from __future__ import annotations

import dataclasses
import time

#: the largest tile when nobody waits for a frame (the bake): a whole frame of 1920 x 1080
BAKE_TILE_PIXELS = 1 << 22


@dataclasses.dataclass
class StepResult:
    step: int          # 0-based lecture step
    seconds: float     # wall-clock time to trace it (0 when it was cached already)
    cached: bool       # the cache held it already
    stored: object     # the entry's path, or None (the cache folder could not be written)


def traced_steps() -> list[int]:
    """The 0-based lecture steps whose scenes trace specular chains."""
    from viewer.gl.raytrace import KIND_SHADED, chain_kind
    from viewer.lecture import TOUR, tour_scene

    out = []
    for i in range(len(TOUR)):
        scene = tour_scene(i)
        if scene.render.raytrace and any(chain_kind(scene.materials[o.material]) != KIND_SHADED
                                         for o in scene.objects):
            out.append(i)
    return out


class LecturePrep:
    """Traces ``steps`` (default: every traced step) at ``size`` = (w, h) with ``renderer``."""

    def __init__(self, ctx, renderer, size, steps=None, view_mode: int = 0):
        self.ctx = ctx
        self.renderer = renderer
        self.size = (int(size[0]), int(size[1]))
        if self.size[0] <= 0 or self.size[1] <= 0:
            raise ValueError(f"view size {self.size[0]}x{self.size[1]}: both must be >= 1")
        self.steps = list(traced_steps() if steps is None else steps)
        self.view_mode = int(view_mode)
        self.results: list[StepResult] = []
        self.messages: list[str] = []   # entries set aside
        self.started = time.perf_counter()
        self.elapsed_s = 0.0
        self._trace = None
        self._index = 0

    @property
    def done(self) -> bool:
        return self._index >= len(self.steps)

    @property
    def current(self) -> int | None:
        return None if self.done else self.steps[self._index]

    def progress_text(self) -> str:
        if self.done:
            return f"lecture prepared for a {self.size[0]}x{self.size[1]} view in {self.elapsed_s:.1f} s"
        frac = self._trace.progress if self._trace is not None else 0.0
        return (f"preparing lecture for a {self.size[0]}x{self.size[1]} view: step {self.current + 1} "
                f"({self._index + 1}/{len(self.steps)}) {100 * frac:.0f}%, "
                f"{time.perf_counter() - self.started:.0f} s")

    def _begin(self):
        from viewer.camera import OrbitCamera
        from viewer.gl.raytrace import ProgressiveTrace
        from viewer.lecture import tour_scene

        scene = tour_scene(self.current)
        self._trace = ProgressiveTrace(self.ctx)
        w, h = self.size
        self._trace.start(self.renderer, scene, OrbitCamera.from_scene(scene), w, h, self.view_mode,
                          coarse=False, cache=True, store=True, max_pixels=BAKE_TILE_PIXELS)
        if self._trace.cache_message:
            self.messages.append(self._trace.cache_message)

    def _end(self):
        t = self._trace
        self.results.append(StepResult(self.current, 0.0 if t.from_cache else t.elapsed_s, t.from_cache,
                                       t.stored))
        t.release()
        self._trace = None
        self._index += 1
        if self.done:
            self.elapsed_s = time.perf_counter() - self.started

    def step(self, budget_s: float = 0.2) -> StepResult | None:
        """About ``budget_s`` of work (a step's untraced frame, or tiles); the step's result when
        one finished, else None."""
        if self.done:
            return None
        if self._trace is None:
            self._begin()
        else:
            self._trace.step(budget_s)
        if self._trace.done:
            self._end()
            return self.results[-1]
        return None

    def run(self, on_result=None) -> list[StepResult]:
        """Everything left, in large tiles; ``on_result(result)`` after each step."""
        while not self.done:
            if self._trace is None:
                self._begin()
            self._trace.finish()
            self._end()
            if on_result is not None:
                on_result(self.results[-1])
        return self.results

    def cancel(self):
        if self._trace is not None:
            self._trace.release()
            self._trace = None
        self._index = len(self.steps)
