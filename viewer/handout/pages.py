"""The handout's pages: ``build_handout`` writes ``OUT/index.html`` (the steps with thumbnails),
``OUT/step-NN.html`` per lecture step (title, caption, the live view of ``viewer.handout.live``,
raster, reference, difference map, the step's plots with their numbers) and ``OUT/handout.css``.

Every file a page names lies inside OUT and is named by a relative path, so the folder opens
from disk (file://) and from any static host with no server, no network and no build step. The
layout is one column on a phone (390 px wide: no horizontal scrolling, pictures at most the
page's width) and a grid of figures on a wider screen; the fonts are the system's."""

from __future__ import annotations

import html
import os
import time
from dataclasses import dataclass, field
from pathlib import Path

from viewer import OutputError, ViewerError
from viewer.handout.assets import ReferenceSettings, StepAssets, step_folder, write_step_assets

STYLE_FILE = "handout.css"
DEFAULT_SIZE = (480, 270)   # half the lecture camera: the window's reference view, bake's default size

STYLE = """\
*, *::before, *::after { box-sizing: border-box; }
html { -webkit-text-size-adjust: 100%; text-size-adjust: 100%; }
body { margin: 0 auto; max-width: 1280px; padding: 0 1rem 2rem; color: #1d1d1f; background: #fbfbfa;
       font: 16px/1.5 system-ui, -apple-system, "Segoe UI", Roboto, "Helvetica Neue", Arial, sans-serif; }
img, canvas, video, svg { max-width: 100%; height: auto; }
img { display: block; }
input, select, button, textarea { max-width: 100%; }
h1 { font-size: clamp(1.4rem, 5vw, 2.2rem); line-height: 1.2; margin: 1rem 0 .5rem; overflow-wrap: anywhere; }
h2 { font-size: 1.25rem; margin: 2rem 0 .5rem; }
p, li, figcaption, h1, h2, h3 { overflow-wrap: anywhere; }
code { font-size: .92em; }
a { color: #0b57b0; }
.caption { font-size: 1.1rem; max-width: 72ch; }
nav.steps { display: flex; flex-wrap: wrap; gap: .5rem 1.25rem; align-items: baseline;
            padding: .75rem 0; border-bottom: 1px solid #ddd; }
nav.steps.bottom { border-bottom: 0; border-top: 1px solid #ddd; margin-top: 2rem; }
nav.steps .here { color: #555; margin-left: auto; }
nav.steps a { text-decoration: none; padding: .35rem 0; }
nav.steps a:hover, nav.steps a:focus { text-decoration: underline; }
section.live { min-width: 0; }
section.live > * { max-width: 100%; }
.note { color: #555; font-size: .9rem; max-width: 72ch; }
.figures { display: grid; gap: 1.25rem; grid-template-columns: repeat(auto-fit, minmax(min(100%, 300px), 1fr)); }
.plots { display: grid; gap: 1.25rem; grid-template-columns: repeat(auto-fit, minmax(min(100%, 420px), 1fr)); }
figure { margin: 0; min-width: 0; }
figure img { width: 100%; border: 1px solid #e2e2e2; background: #fff; }
figcaption { font-size: .9rem; color: #444; margin-top: .35rem; }
ol.cards { list-style: none; padding: 0; margin: 1rem 0; display: grid; gap: 1.25rem;
           grid-template-columns: repeat(auto-fill, minmax(min(100%, 260px), 1fr)); }
ol.cards li { min-width: 0; }
ol.cards a { display: block; color: inherit; text-decoration: none; }
ol.cards a:hover h2, ol.cards a:focus h2 { text-decoration: underline; }
ol.cards img { width: 100%; border: 1px solid #e2e2e2; }
ol.cards h2 { font-size: 1.05rem; margin: .5rem 0 .25rem; color: #0b57b0; }
ol.cards p { margin: 0; font-size: .9rem; color: #444; }
footer { color: #666; font-size: .85rem; margin-top: 2rem; }
"""


@dataclass
class HandoutResult:
    """What ``build_handout`` wrote."""
    out: Path
    steps: list[StepAssets]
    pages: list[str] = field(default_factory=list)   # relative to out
    size_bytes: int = 0                              # every file under out
    seconds: float = 0.0


def check_out_folder(out) -> Path:
    """OUT as a folder this build can write: created when missing; ``ViewerError`` (exit 2) when
    it is a file, ``OutputError`` (exit 1) when it cannot be created or written."""
    import tempfile

    from viewer.base.io import one_line

    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ViewerError(one_line(f"handout {out}: exists and is not a folder; name a folder (created when missing)"))
    try:
        out.mkdir(parents=True, exist_ok=True)
        fd, probe = tempfile.mkstemp(prefix=".probe.", suffix=".part", dir=out)
        os.close(fd)
        os.unlink(probe)
    except OSError as e:
        raise OutputError(one_line(f"handout {out}: the folder cannot be written ({e.strerror or e})")) from None
    return out


def _esc(text) -> str:
    return html.escape(str(text), quote=True)


def _head(title: str, styles: list[str]) -> str:
    links = "".join(f'<link rel="stylesheet" href="{_esc(s)}">\n' for s in [STYLE_FILE, *styles])
    # the empty data: icon keeps a browser from asking the host (or the disk) for /favicon.ico
    return ("<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
            "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n"
            f"<title>{_esc(title)}</title>\n<link rel=\"icon\" href=\"data:,\">\n{links}</head>\n")


def _nav(steps: list[StepAssets], i: int, where: str) -> str:
    parts = ['<a href="index.html">All steps</a>']
    if i > 0:
        p = steps[i - 1]
        parts.append(f'<a href="{step_folder(p.number)}.html" rel="prev">&larr; {p.number}. {_esc(p.title)}</a>')
    if i + 1 < len(steps):
        n = steps[i + 1]
        parts.append(f'<a href="{step_folder(n.number)}.html" rel="next">{n.number}. {_esc(n.title)} &rarr;</a>')
    parts.append(f'<span class="here">step {steps[i].number} of the lecture\'s {_tour_len()}</span>')
    return f'<nav class="steps {where}" aria-label="steps">' + "".join(parts) + "</nav>\n"


def _tour_len() -> int:
    from viewer.scene.lecture import TOUR

    return len(TOUR)


def _img(src: str, alt: str, w: int, h: int, link: bool = True) -> str:
    """An image at its size (the page keeps its room while it loads); ``link``: a tap or click
    opens it alone, at full size (a plot's small print on a phone)."""
    img = f'<img src="{_esc(src)}" alt="{_esc(alt)}" width="{w}" height="{h}">'
    return f'<a href="{_esc(src)}">{img}</a>' if link else img


def _reference_text(a: StepAssets) -> str:
    # whether it came from the cache is the build's business (the command's output, step.json)
    return (f"Reference: the path tracer, {a.spp} samples per pixel, {a.engine} engine; the same meshes, "
            "camera, lights and exposure as the raster.")


def step_page(steps: list[StepAssets], i: int, live) -> str:
    """The page of ``steps[i]`` (``live``: its ``LiveView``)."""
    from viewer.handout.assets import PLOT_SIZE

    a = steps[i]
    w, h = a.width, a.height
    out = [_head(f"{a.number}. {a.title} - BRDF lecture handout", list(live.styles)), "<body>\n",
           _nav(steps, i, "top"), "<main>\n",
           f'<h1>{a.number}. {_esc(a.title)}</h1>\n<p class="caption">{_esc(a.caption)}</p>\n',
           '<section class="live" aria-label="live view">\n<h2>Live view</h2>\n', live.html, "\n</section>\n",
           "<h2>Raster, reference and their difference</h2>\n<div class=\"figures\">\n",
           f"<figure>{_img(a.raster, f'raster image of step {a.number}', w, h)}<figcaption>Raster: the viewer's "
           f"rasterizer (<code>viewer.render</code>), {w}&times;{h}.</figcaption></figure>\n",
           f"<figure>{_img(a.reference, f'reference image of step {a.number}', w, h)}"
           f"<figcaption>{_esc(_reference_text(a))}</figcaption></figure>\n",
           f"<figure>{_img(a.difference, f'difference map of step {a.number}', w, h + 2 + max(8, h // 16))}"
           f"<figcaption>Difference |raster &minus; reference|, averaged over the colour channels; the colour bar "
           f"under it runs from 0 (black) to {a.diff_scale:.3g} (white, the 99th percentile). RMSE {a.rmse:.3g}, "
           f"relative MSE {a.relative_mse:.3g}.</figcaption></figure>\n</div>\n"]
    if a.plots or a.plot_notes:
        out.append(f"<h2>Plot: {_esc(a.plot_kind)}</h2>\n<div class=\"plots\">\n")
        for p in a.plots:
            out.append(f"<figure>{_img(p.png, p.title, *PLOT_SIZE)}<figcaption>{_esc(p.material)}: "
                       f'the plotted numbers as JSON, <a href="{_esc(p.json)}">{_esc(Path(p.json).name)}</a>.'
                       "</figcaption></figure>\n")
        out.append("</div>\n")
        out += [f'<p class="note">{_esc(n)}</p>\n' for n in a.plot_notes]
    out.append(f'<p class="note">This page\'s numbers: <a href="{_esc(a.data)}">{_esc(a.data)}</a>.</p>\n')
    out += ["</main>\n", _nav(steps, i, "bottom")]
    out += [f'<script src="{_esc(s)}"></script>\n' for s in live.scripts]
    out.append("</body>\n</html>\n")
    return "".join(out)


def index_page(steps: list[StepAssets], command: str) -> str:
    """The index: every step with its thumbnail, title and caption."""
    import viewer

    out = [_head("BRDF lecture handout", []), "<body>\n<main>\n<h1>BRDF lecture handout</h1>\n",
           '<p class="caption">BRDFs, Fresnel reflectance and absorption, one example per page: the '
           "scene live in your browser with its sliders, the viewer's raster image beside a path-traced "
           "reference and their difference, and the plot that goes with it.</p>\n<ol class=\"cards\">\n"]
    for a in steps:
        out.append(f'<li><a href="{step_folder(a.number)}.html">'
                   f"{_img(a.thumbnail, f'step {a.number}: {a.title}', *_thumb_size(a), link=False)}"
                   f"<h2>{a.number}. {_esc(a.title)}</h2><p>{_esc(a.caption)}</p></a></li>\n")
    out.append("</ol>\n</main>\n")
    out.append(f"<footer>Made with brdf-viewer {_esc(viewer.__version__)}: <code>{_esc(command)}</code>. "
               "Every file lies in this folder: it opens from disk or from any static web host.</footer>\n")
    out.append("</body>\n</html>\n")
    return "".join(out)


def _thumb_size(a: StepAssets) -> tuple[int, int]:
    from viewer.handout.assets import THUMB_WIDTH

    tw = min(THUMB_WIDTH, a.width)
    return tw, max(1, round(a.height * tw / a.width))


def folder_size(out: Path) -> int:
    return sum(f.stat().st_size for f in out.rglob("*") if f.is_file())


def build_handout(out, steps: list[int], width: int, height: int, settings: ReferenceSettings | None = None,
                  report=print, progress=None, command: str = "brdf-viewer handout") -> HandoutResult:
    """Write the handout of the lecture ``steps`` (0-based) into the folder ``out`` at width x
    height (see the module). ``report(line)`` is told each step as it is done; ``progress(label)``
    makes the reference's progress bar; ``command`` is named in the index's footer."""
    from viewer.base.io import atomic_write_bytes
    from viewer.handout.live import write_live
    from viewer.reference_common import cache
    from viewer.scene.lecture import TOUR, tour_scene

    settings = settings or ReferenceSettings()
    t0 = time.perf_counter()
    out = check_out_folder(out)
    size = [f"camera.width={width}", f"camera.height={height}"]
    scenes = [tour_scene(i, overrides=size) for i in steps]   # every scene loads before any rendering
    cache.check_writable()                                    # a cache that cannot store: said before rendering
    done: list[StepAssets] = []
    lives = []
    for k, (i, scene) in enumerate(zip(steps, scenes)):
        ts = time.perf_counter()
        a = write_step_assets(i, scene, out, width, height, settings, progress)
        lives.append(write_live(scene, out, a.number))
        done.append(a)
        ref = "cached" if a.cached else f"rendered in {a.reference_seconds:.1f} s"
        report(f"step {a.number} ({k + 1}/{len(steps)}) {TOUR[i].key}: raster and reference {width}x{height}, "
               f"reference {a.spp} spp {a.engine} ({ref}), {len(a.plots)} {a.plot_kind} plot"
               f"{'' if len(a.plots) == 1 else 's'}, live view; {time.perf_counter() - ts:.1f} s")
    result = HandoutResult(out, done)
    atomic_write_bytes(out / STYLE_FILE, STYLE.encode())
    for k, a in enumerate(done):
        name = f"{step_folder(a.number)}.html"
        atomic_write_bytes(out / name, step_page(done, k, lives[k]).encode())
        result.pages.append(name)
    atomic_write_bytes(out / "index.html", index_page(done, command).encode())
    result.pages.insert(0, "index.html")
    result.size_bytes = folder_size(out)
    result.seconds = time.perf_counter() - t0
    return result
