"""What the view draws and how: the raster frame of the still view, whole or in tiles over the
view as it was (``tiled_frames``), the progressive trace of a scene with traced chains (strips
over its untraced frame), the running mean of frames with new sample sets (brute-force IBL, the
sampled environment light of file materials: ``viewer.app.frame_mean``), and the record of what each frame was
drawn from (``FrameSource``). ``ViewFrames`` is held by ``viewer.app.session.Session`` as
``session.frames``; it asks the session's other parts what to draw while programs compile
(``session.compiles``) and tells the lecture when a step's first frame is drawn
(``session.tour``). No imgui, no glfw."""

from __future__ import annotations

import dataclasses
import sys
import time

import numpy as np

from viewer import ViewerError
from viewer.app.compile_control import KEEP_IMAGE, UNTRACED
from viewer.app.view_prep import PREPARING, ViewPrep
from viewer.app.frame_mean import BF_FRAMES, FrameMean, frames_wanted  # noqa: F401 (BF_FRAMES: the window's)
from viewer.gl.context import release_gl

TRACE_BUDGET_S = 0.12  # traced chains: the time one refining frame's strip of rows aims at
# tiled frames: a still view whose whole frame took longer than this is drawn in tiles of about
# this much time per frame, over the view as it was or its half-resolution preview (the window
# then answers input within a frame's budget on software OpenGL, where one frame at 1280 x 720
# with MSAA takes 0.3 s); less where the rest of the window's frame leaves less of FRAME_GOAL_S
TILE_BUDGET_S = 0.07
FRAME_GOAL_S = 0.12


#: what the view says of a frame drawn while the scene's own programs compile beside
FORM_WORDS = {"stand-in": "drawn with grey stand-ins", "untraced": "drawn untraced", "held": "drawn as before"}
#: what the pixels a tiled frame's tiles have not reached yet show, by the form drawn before
#: ("preview": a preview of the frame drawn, at a quarter or half of its resolution)
UNDER_WORDS = {"stand-in": "grey stand-ins", "untraced": "untraced", "held": "as before", "own": "as it was",
               "preview": "a preview"}


@dataclasses.dataclass(frozen=True)
class FrameSource:
    """What the raster image shown was drawn from: ``scene`` (the session's scene object then),
    its materials (``materials``: name -> params as drawn), and ``form``: "own" (every material
    with its own programs), "held" (the same scene with the edited materials as they were),
    "untraced" (the scene without its traced chains), "stand-in" (its objects, the materials not
    ready drawn as grey Lambert stand-ins) or "preparing" (no image: the parts of the scene's
    first frame are made, ``viewer.app.view_prep``). ``under``: where the frame is drawn in tiles, the
    scene of the image the tiles not drawn yet show (the same scene, always)."""
    scene: object
    materials: dict
    form: str
    under: object = None


def _same_framing(size, other) -> bool:
    """Two sizes of one view's framing: the same aspect to within a pixel (the compare views draw
    the raster letterboxed into half the view, ``layout.fit_rect``)."""
    (w0, h0), (w1, h1) = size, other
    return w0 > 0 and h0 > 0 and abs(w0 * h1 / h0 - w1) <= 1.0 and abs(h0 * w1 / w0 - h1) <= 1.0


class ViewFrames:
    """The raster frames of ``session``'s view (``tiled_frames``: a still view whose whole frame
    takes longer than ``TILE_BUDGET_S`` is drawn in tiles over the next frames, ``quality``
    "refining" meanwhile)."""

    def __init__(self, session, tiled_frames: bool = False, prepare_frames: bool = False):
        self.session = session
        self.prep = ViewPrep(session, prepare_frames)  # a new scene's first frame, made over frames
        self.hdr = None            # the raster image shown (a texture), None before the first
        self.hdr_for = None        # the view size (w, h) the image shown was drawn for
        self.raster_version = 0
        self.render_ms = 0.0
        self.frame_rest_s = 0.0    # what the window's frame costs beside render_view (the window sets it)
        self.quality = "full"      # "preview" after an interactive (half-resolution) frame
        self.nonfinite = None      # the last check's message about NaN / Inf pixels, else None
        self.frame_source = None   # what the raster image shown was drawn from (FrameSource)
        self.drawn_materials = None  # (scene, {material name: params}) last drawn with their own programs
        self._tiles_under = None   # the scene of the image under a tiled frame's tiles
        self._tiles_under_form = "preview"  # and what it shows (UNDER_WORDS)
        self._mean = FrameMean()   # brute-force IBL, file materials' environment light
        self._nonfinite_said = None
        self._trace = None         # the progressive trace of a still view (viewer.gl.raytrace)
        self._tiles_on = tiled_frames
        self._tiles = None         # the still raster frame drawn in tiles (a ProgressiveTrace, traced=False)
        self._whole_s = None       # ((w, h), seconds, scene's objects): what the last whole full-quality frame cost
        self._untraced_tiles = False  # a traced view's untraced frame is being drawn in tiles first
        self._drawn_view = None    # the camera and view mode of the frame shown (_view_key)
        self._shown = None         # (texture, framebuffer): the view kept while the preparation renders

    def release(self) -> None:
        """Free the textures and traces this part made."""
        self._mean.release()
        for t in (self._trace, self._tiles):
            if t is not None:
                t.release()
        self._trace = self._tiles = None
        if self._shown is not None:
            release_gl(self._shown[1], self._shown[0])
            self._shown = None

    @property
    def bf_count(self) -> int:
        """Frames in the running mean (brute-force IBL, file materials' environment light)."""
        return self._mean.count

    @property
    def frames_wanted(self) -> int:
        """The frames the still view's running mean averages (``frame_mean.frames_wanted``; 1 for
        a view traced in strips, which refines its own way)."""
        return 1 if self._progressive() else frames_wanted(self.session.scene)

    @property
    def averaging(self) -> bool:
        """The still view's running mean has frames to come."""
        n = self.frames_wanted
        return n > 1 and self._mean.count < n

    @property
    def refining(self) -> bool:
        """Frames should follow without waiting for input (the running mean still averaging, or
        the traced chains still refining)."""
        return self.averaging or self.tracing or self.tiling

    @property
    def tiling(self) -> bool:
        """The still view's raster frame is being drawn in tiles (``tiled_frames``)."""
        return self._tiles is not None and self._tiles.active and not self._tiles.done

    @property
    def under_form(self):
        """What the tiles have not reached yet shows (``UNDER_WORDS``' key); None: the view is whole."""
        return self._tiles_under_form if self.tiling else None

    @property
    def trace(self):
        """The progressive trace of the still view (``viewer.gl.raytrace.ProgressiveTrace``), or
        None before the first traced view."""
        return self._trace

    @property
    def tracing(self) -> bool:
        """The traced image of the still view is being built, strip by strip."""
        return self._trace is not None and self._trace.active and not self._trace.done

    @property
    def trace_status(self) -> str:
        """What the view says while the traced image refines, or while it stands in for a scene
        whose programs compile beside ("" otherwise)."""
        s = self.session
        src = self.frame_source
        if self.prep.active:
            return self.prep.label()
        rest = UNDER_WORDS.get(self._tiles_under_form, "as it was")
        if s.pending and src is not None and src.scene is s.scene and src.form in FORM_WORDS:
            text = f"compiling {', '.join(s.pending)} in the background: {FORM_WORDS[src.form]} until ready"
            if self.tiling and self._tiles_under_form != src.form:  # the tiles not there yet show another form
                text += f" (in tiles: {100 * self._tiles.progress:.0f}%, the rest {rest})"
            return text
        if self.tiling:
            return f"drawing the view in tiles: {100 * self._tiles.progress:.0f}% (the rest {rest})"
        n = self.frames_wanted
        if s.scene.render.ibl != "brute_force" and self.averaging and self._mean.count > 0:
            return f"environment light of file materials: converging {self._mean.count}/{n} frames"
        if not self.tracing:
            s = self.session
            return s.prep.progress_text() if s.preparing else ""
        t = self._trace
        stage = "half resolution first" if t.coarse else "full resolution"
        return (f"ray tracing: {100 * t.progress:.0f}%, {stage}, {time.perf_counter() - t.started:.0f} s "
                "(what is not traced yet is drawn untraced)")

    def _progressive(self) -> bool:
        """Traced chains drawn untraced while the view moves and traced in strips once it is
        still: a scene that traces, without SSR (its pass reads the whole frame) and brute-force
        IBL (which averages whole frames); those trace every full frame at once."""
        s = self.session
        r = s.scene.render
        return s.renderer.traces(s.scene) and not r.ssr and r.ibl != "brute_force"

    def draw(self, size, interacting: bool = False) -> None:
        """Render the raster image for a view of ``size`` = (w, h) pixels if anything changed:
        at half resolution without MSAA while the user drags (software GL is slow), at full
        quality once the interaction pauses; brute-force IBL keeps averaging frames."""
        s = self.session
        rw_full, rh_full = size
        if s.compare.mode == "reference":
            s.dirty = False  # no raster image is shown; the reference restarts on its own key
            return
        if rw_full <= 0 or rh_full <= 0:
            return
        scale = 0.5 if interacting else 1.0
        rw, rh = max(1, int(rw_full * scale)), max(1, int(rh_full * scale))
        want_full = not interacting and self.quality == "preview"
        progressive = (self.tracing or self.tiling or self.averaging) and not interacting
        stale = self.hdr is None or self.hdr_for != (rw_full, rh_full)
        s.compiles.poll()  # the programs the view waits for are ready: draw the material as it now is
        if s.preparing:
            s.tour.prepare_step()
        s.env.watch()
        if not (s.dirty or want_full or stale or progressive):
            return
        t1 = time.perf_counter()
        restart = s.dirty or want_full or stale
        whole_from = None
        if restart:
            self._mean.reset()
        traced = self._progressive()
        quality = "preview" if interacting else "full"
        # a prepared traced view (a lecture step baked) opens from the traced-frame cache at once,
        # needing no program: nothing held back or prepared (looked up once its map is read)
        cached = trace_cached(s, rw, rh) if traced and not interacting and restart \
            and s.scene.environment.map_read() else None
        if prepared := bool(cached):
            s.compiles.nothing_awaited()
            self.prep.finish()
        held = s.compiles.held_back(False if traced and interacting else None, False if traced else None, stale) \
            if s.compiles.on and not prepared else None
        as_drawn = s.scene if held is None or held is UNTRACED else held  # the scene as this frame draws it
        if not prepared and held is not KEEP_IMAGE and self.prep.needed(self.frame_source, None if interacting else as_drawn,
                                                       False if traced else None) \
                and self._prepare(as_drawn, traced, rw, rh):
            return  # the placeholder (or the image kept): still dirty, so the next frame follows at once
        source = None
        try:
            if held is KEEP_IMAGE:
                quality = self.quality
            elif traced and not interacting and held is None:  # still: untraced, then traced in strips
                quality = self._trace_step(rw, rh, restart, cached)
                source = FrameSource(s.scene, dict(s.scene.materials), "own")
            else:
                if self._trace is not None:
                    self._trace.cancel()
                # held: a changed material's programs compile beside, so it is drawn as it was
                # (not "preview" when still: that would draw it again each frame until the
                # answer comes, which marks the view dirty by itself)
                drawn = as_drawn
                form = ("own" if held is None else "untraced" if held is UNTRACED
                        else "stand-in" if getattr(held, "stand_in", False) else "held")
                source = FrameSource(s.scene, dict(drawn.materials), form)
                if not interacting and self._tiled(drawn, rw, rh):
                    quality = self._tile_step(drawn, rw, rh, restart)
                    source = dataclasses.replace(source, under=self._tiles_under)
                else:
                    if self._tiles is not None:
                        self._tiles.cancel()
                    t2 = time.perf_counter()
                    self.hdr = s.renderer.render(drawn, s.camera, rw, rh, s.view_mode,
                                                 msaa=0 if interacting else None, frame_index=self.bf_count,
                                                 raytrace=False if traced else None)
                    if frames_wanted(drawn) > 1 and not interacting:
                        self.hdr = self._mean.add(s.renderer, s.ctx, self.hdr)
                    elif not interacting:
                        whole_from = t2  # a whole still frame: its cost, once finished below
            if held is None:  # what a held frame may show of these materials while others compile
                self.drawn_materials = (s.scene, dict(s.scene.materials))
            if held is not KEEP_IMAGE:
                self._drawn_view = self._view_key()
                self.frame_source = source
        except ViewerError as e:  # e.g. a shader that never compiled: keep the last image
            s.notify(str(e), error=True)
        s.ctx.finish()
        if whole_from is not None:
            self._whole_s = ((rw, rh), time.perf_counter() - whole_from, drawn.objects)
        if quality == "full" and self.hdr is not None:
            self._check_finite(self.hdr)
        self.raster_version += 1
        self.render_ms = 1000 * (time.perf_counter() - t1)
        self.hdr_for = (rw_full, rh_full)
        self.quality = quality
        s.dirty = False
        s.env.watch()
        if s.tour.step_timer is not None and not interacting and held is not KEEP_IMAGE:
            s.tour.step_shown()

    def _prepare(self, drawn, traced: bool, w: int, h: int) -> bool:
        """One frame of the preparation of a scene the view has not drawn yet
        (``viewer.app.view_prep``): True when the view shows the placeholder this frame (no
        image: never the last scene's frame, and its form "preparing" makes no note about a
        frame drawn otherwise true), False when the frame itself is drawn now."""
        s = self.session
        # the same scene in another form (untraced after its stand-ins, a material edited): the
        # view keeps its image (of this scene) while the new form's programs are made
        src = self.frame_source
        keep = src is not None and src.scene is s.scene and src.form != PREPARING and self.hdr is not None
        try:
            if not self.prep.step(drawn, (w, h), s.view_mode, False if traced else None):
                return False
        except ViewerError as e:  # a program that does not compile: the frame reports it as always
            self.prep.finish()
            s.notify(str(e), error=True)
            return False
        self.prep.kept = FORM_WORDS.get(src.form, "the view as it was") if keep else None
        if not keep:
            self.hdr = None
            self.frame_source = FrameSource(s.scene, dict(drawn.materials), PREPARING)
        return True

    def _tiled(self, scene, w, h) -> bool:
        """Whether the still view of ``scene`` is drawn in tiles: ``tiled_frames`` on, its last
        whole frame (or tiled one) over ``TILE_BUDGET_S`` (at another size, scaled by the pixels),
        or another scene or the view's first frame (its cost not known yet: a lecture step's soap
        bubbles cost 30 times the step before), a frame that tiles (not SSR, whose pass reads the whole frame, nor brute-force
        IBL or a file material's sampled environment light, whose means average whole frames)."""
        if not self._tiles_on or scene.render.ssr or frames_wanted(scene) > 1:
            return False
        if self.tiling:
            return True
        if self._whole_s is None:  # the view's first frame: its cost is not known (the default
            return True            # scene's whole first frame took 0.6 s on software OpenGL)
        (w0, h0), cost, objects = self._whole_s
        # another size (side by side, a resize, lecture mode's strip): the cost scaled by the pixels
        return objects is not scene.objects or cost * (w * h) / max(w0 * h0, 1) > self.tile_budget_s

    def _new_scene(self, scene) -> bool:
        """No frame of ``scene`` was drawn whole yet (another scene was, or none)."""
        return self._whole_s is None or self._whole_s[2] is not scene.objects

    @property
    def tile_budget_s(self) -> float:
        """A tiled frame's time per frame: ``TILE_BUDGET_S``, or less where the rest of the
        window's frame (``frame_rest_s``: the interface, the view's tone mapping) leaves less of
        ``FRAME_GOAL_S``, though not under 30 ms."""
        return min(TILE_BUDGET_S, max(0.03, FRAME_GOAL_S - self.frame_rest_s))

    def _view_key(self):
        s = self.session
        return (s.view_mode, s.camera.fov_y, tuple(s.camera.position), tuple(s.camera.target))

    def _tile_step(self, scene, w, h, restart: bool) -> str:
        """The tiled raster frame: (re)start it, or draw its next tiles; "refining" until it is
        whole. Meanwhile the view shows what it showed (materials edited in the same scene at
        the same size, or the same scene drawn with stand-ins or untraced while its programs
        compiled: the new look replaces the old from the top) or its preview (the
        half-resolution frame just drawn while the view moved, else one drawn now)."""
        from viewer.gl.raytrace import ProgressiveTrace

        s = self.session
        if self._tiles is None:
            self._tiles = ProgressiveTrace(s.ctx)
        t = self._tiles
        t.msaa_made = self.prep.on  # the preparation drew each program at the view's MSAA
        if restart or not t.active:
            under = None
            same = (self.drawn_materials is not None and self.drawn_materials[0] is s.scene
                    and self._drawn_view == self._view_key())  # the same scene seen the same way
            # the preview of this scene just drawn while the view moved, or this scene seen the
            # same way in another form (its grey stand-ins, untraced: the view keeps its full
            # resolution and MSAA under the tiles), never another scene's
            ours = self.frame_source is not None and self.frame_source.scene is s.scene
            seen = ours and self._drawn_view == self._view_key()
            if self.hdr is not None and ours and (self.quality == "preview" or (seen and _same_framing(self.hdr.size, (w, h)))):
                # read before any tile draws over the renderer's target; at another size of the
                # same framing (a compare view's half and the whole view) resampled on the GPU
                under = self.hdr
            self._tiles_under = self.frame_source.scene if under is not None else s.scene
            self._tiles_under_form = ("preview" if under is None or self.quality == "preview"
                                      else self.frame_source.form)
            # the first tile: a 32nd of the view (the cost per pixel of a changed material is
            # not known yet); the next follow the time of the last
            self.hdr = t.start(s.renderer, scene, s.camera, w, h, s.view_mode, traced=False,
                               under=under, like_last=same, rows=max(4, h // 32), max_pixels=w * h,
                               preview_scale=t.preview_scale(scene, w, h, 4 if self._new_scene(scene) else 2, FRAME_GOAL_S))
            if under is None:  # this frame drew the preview
                return "refining"
        self.hdr = t.step(self.tile_budget_s)
        if not t.done:
            return "refining"
        self._tiles_under = s.scene
        self._whole_s = ((w, h), t.trace_s, scene.objects)
        return "full"

    def _trace_step(self, w, h, restart: bool, cached: bool | None = None) -> str:
        """The progressive trace: (re)start it with the untraced view, or trace its next strip;
        "tracing" until the traced image is complete, then "full". Where the untraced frame
        itself is over the tile budget (or its cost is not known: another scene, ray tracing
        just turned on) and the traced-frame cache does not hold the view, the untraced frame is
        drawn in tiles first (``_tile_step``), then traced from it. ``cached``: whether that
        cache holds the view, where this frame looked it up already."""
        from viewer.gl.raytrace import ProgressiveTrace

        s = self.session
        if self._trace is None:
            self._trace = ProgressiveTrace(s.ctx)
        t = self._trace
        if restart:
            self._untraced_tiles = False
        if (restart or not t.active) and not self._untraced_tiles:
            if self._tiled(s.scene, w, h) and not (trace_cached(s, w, h) if cached is None else cached):
                self._untraced_tiles = True
                t.cancel()
        if self._untraced_tiles:
            if self._tile_step(s.scene, w, h, restart) != "full":
                return "tracing"
            self._untraced_tiles = False
            self.hdr = t.start(s.renderer, s.scene, s.camera, w, h, s.view_mode,
                               store=s.lecture_step >= 0, untraced=self.hdr)
            return "tracing" if not t.done else "full"
        if restart or not t.active:
            self.hdr = t.start(s.renderer, s.scene, s.camera, w, h, s.view_mode, cache=True,
                               store=s.lecture_step >= 0)
            if s.environment_provisional:  # a quick prefilter lights it: not for the cache
                t.keep_out_of_cache()
            if t.cache_message:
                s.notify(t.cache_message)
            if not t.from_cache:
                return "tracing"
            s.notify(f"ray traced view from the prepared cache ({t.elapsed_s:.2f} s)")
            return "full"
        if self.prep.on and not s.renderer.raytrace_state().ready(s.scene):
            return "tracing"  # its BVH is made beside: the untraced frame stays meanwhile
        if self.prep.on and self.prep.trace_part(s.scene, t.pass_size, s.view_mode):
            return "tracing"  # one program drawn in the tiles' state this frame (``ViewPrep.trace_part``)
        self.hdr = t.step(TRACE_BUDGET_S)
        if not t.done:
            return "tracing"
        # the true time: from the still view's first frame to the last tile, frames between included
        s.notify(f"ray traced in {t.elapsed_s:.1f} s ({t.steps} tiles, {t.trace_s:.1f} s of them tracing)")
        return "full"

    def _keep_view(self):
        """Copy the view's image into a texture of the session's own unless it has one already
        (the trace's, the brute-force mean's, this copy)."""
        s = self.session
        own = [x for x in (self._trace and self._trace.texture, self._mean.texture, self._shown and self._shown[0]) if x]
        if self.hdr is None or any(self.hdr is x for x in own):
            return
        size = self.hdr.size
        if self._shown is None or self._shown[0].size != size:
            if self._shown is not None:
                release_gl(self._shown[1], self._shown[0])
            tex = s.ctx.texture(size, 4, dtype="f4")
            tex.filter = (s.ctx.NEAREST, s.ctx.NEAREST)
            self._shown = (tex, s.ctx.framebuffer(color_attachments=[tex]))
        src = s.ctx.framebuffer(color_attachments=[self.hdr])
        try:
            s.ctx.copy_framebuffer(self._shown[1], src)
        finally:
            release_gl(src)
        self.hdr = self._shown[0]

    def _check_finite(self, hdr):
        """Say in one line (a notification and stderr, once per distinct message) when the view
        holds NaN or Inf pixels: a renderer bug the class would see as holes. The texels are
        tested as read (no flipped copy, no mask: a frame at 1456x1080 costs a quarter of that);
        only a frame with such pixels is read again to name them."""
        from viewer.image.finite import nonfinite_message, render_switches

        s = self.session
        try:
            msg = None
            if not np.isfinite(np.frombuffer(hdr.read(), dtype="f4")).all():  # alpha too: then looked at closely
                msg = nonfinite_message(s.renderer.read_linear(hdr), f"view of {s.scene.label}", (),
                                        render_switches(s.scene))
        except Exception:  # noqa: BLE001 - a lost target is no reason to stop drawing
            return
        self.nonfinite = msg
        if msg and msg != self._nonfinite_said:
            s.notify(msg, error=True)
            print("brdf-viewer: " + msg, file=sys.stderr, flush=True)
        self._nonfinite_said = msg


def trace_cached(session, w, h) -> bool:
    """The traced-frame cache holds ``session``'s still view at (w, h)."""
    from viewer.gl import trace_cache

    key = trace_cache.frame_key(session.scene, session.camera, w, h, session.view_mode, None,
                                session.ctx.info.get("GL_RENDERER", ""))
    return trace_cache.path_for(key).exists()

