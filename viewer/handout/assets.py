"""One lecture step's pictures and numbers for the handout, written under ``OUT/step-NN/``:

* ``raster.png``: ``viewer.render`` (the window's rasterizer) at the handout's size, after the
  step's exposure and tone mapping;
* ``reference.png``: the reference path tracer's image from the reference cache, rendered (and
  stored there) as ``brdf-viewer bake`` renders it when the cache lacks it or holds fewer samples
  than asked for; a cached entry with more samples is used as it is. The cache key is bake's and
  the window's (the same setup at the same size), so a lecture baked at the handout's size is
  not rendered again;
* ``difference.png``: ``viewer.image.compare.heat_map`` (|raster - reference| averaged over the
  channels, with its colour bar and scale below it), the difference map of ``brdf-viewer compare``;
* ``plot-MATERIAL.png`` and ``plot-MATERIAL.json``: the step's plot (the kind the window's plots
  panel shows for the step) for each of the step's materials but the floor, drawn by
  ``viewer.plots`` with its plotted numbers beside it;
* ``thumbnail.png`` (the raster, small, for the index) and ``step.json`` (what the page states:
  sizes, spp, engine, error metrics, the plots).
"""

from __future__ import annotations

import json
import re
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

PLOT_SIZE = (720, 480)      # the plots' pixels: the window's plot panel at UI scale 1 is about this size
THUMB_WIDTH = 320           # the index's thumbnails


@dataclass
class ReferenceSettings:
    """How the references are made when the cache lacks them (bake's options)."""
    spp: int = 64
    engine: str = "auto"
    max_depth: int = 8
    seed: int = 0
    workers: int | None = None


@dataclass
class PlotFile:
    material: str
    kind: str
    title: str
    png: str    # relative to OUT
    json: str   # relative to OUT


@dataclass
class StepAssets:
    """What was written for one step (paths relative to OUT) and the numbers its page states."""
    number: int                 # 1-based
    key: str
    title: str
    caption: str
    width: int
    height: int
    raster: str
    reference: str
    difference: str
    thumbnail: str
    data: str
    spp: int
    engine: str
    cached: bool                # the reference came from the cache as it was
    reference_seconds: float    # time spent rendering it now (0 when cached)
    diff_scale: float
    rmse: float
    relative_mse: float
    plot_kind: str
    plots: list[PlotFile] = field(default_factory=list)
    plot_notes: list[str] = field(default_factory=list)


def step_folder(number: int) -> str:
    """``step-NN``: the folder of step ``number`` (1-based); its page is ``step-NN.html``."""
    return f"step-{number:02d}"


def file_stem(name: str) -> str:
    """A material name as part of a file name (letters, digits, ``-`` and ``_``)."""
    return re.sub(r"[^A-Za-z0-9_-]", "_", name) or "_"


def reference_image(scene, width: int, height: int, settings: ReferenceSettings, progress=None):
    """``(linear, spp, engine, cached, seconds)``: the reference of ``scene`` at width x height
    from the reference cache, rendered there first as ``bake`` does when the cache holds fewer
    than ``settings.spp`` samples (resumed from what it holds). ``progress(label)`` gives a
    progress bar (called with the fraction done, ``end()`` at the end)."""
    from viewer.reference_common import cache
    from viewer.reference_common.select import choose_for_scenes, make_renderer, needs_spectral
    from viewer.reference_common.setup import RenderSetup
    from viewer.scene.camera import OrbitCamera

    camera = OrbitCamera.from_scene(scene)
    setup = RenderSetup.from_scene(scene, camera, width, height, settings.max_depth)
    setup.extra["spectral"] = needs_spectral(scene)   # as both engines key it (dispersive: wavelengths)
    key = cache.setup_key(setup)
    old = cache.load(key, shape=(height, width, 3))   # a damaged entry: set aside with one line
    have = old.spp if old is not None else 0
    if old is not None and have >= settings.spp:
        return old.mean(), old.spp, old.engine, True, 0.0
    engine, _ = choose_for_scenes(settings.engine, [scene])
    start = time.perf_counter()
    bar = progress(f"reference {width}x{height} {settings.spp} spp ({engine})") if progress else None
    with make_renderer(engine, scene, camera, width, height, max_depth=settings.max_depth, seed=settings.seed,
                       workers=settings.workers) as r:
        if old is not None:
            r.resume(old.sum, old.sum2, old.spp)
        try:
            if bar is not None:
                bar(0.0)
            r.step(settings.spp - have, progress=bar)
        finally:
            if bar is not None:
                bar.end()
        total, total2, spp = r.state()
    cache.store(key, cache.Entry(total, total2, spp, engine, settings.seed))   # CacheError: one line, exit 1
    return (total / max(spp, 1)).astype(np.float32), spp, engine, False, time.perf_counter() - start


def step_plots(scene, step, out_dir: Path, folder: str) -> tuple[list[PlotFile], list[str]]:
    """The step's plot (``step.plot``) of each of its materials but the floor, as PNG + JSON in
    ``out_dir/folder``; notes for the materials the kind does not apply to. The Fresnel plot of
    the total internal reflection step is drawn from inside the glass (the window's choice)."""
    from viewer import plots
    from viewer.base.io import atomic_write_bytes, write_png
    from viewer.plots.png import figure_json

    if not step.plot:
        return [], ["this step has no plot"]
    out, notes = [], []
    for name, p in scene.materials.items():
        if name == "floor":
            continue
        if step.plot not in plots.applicable_kinds(p):
            notes.append(f"{name}: no {step.plot} plot (it does not apply to this material)")
            continue
        fig = plots.figure(p, step.plot, name=name, inside=step.key == "tir")
        stem = f"{folder}/plot-{file_stem(name)}"
        data = figure_json(fig)   # the numbers beside the PNG, not also in it (plot --data's JSON)
        if isinstance(data.get("params"), dict) and isinstance(data["params"].get("file"), str):
            data["params"]["file"] = Path(data["params"]["file"]).name   # not the build machine's path
        write_png(out_dir / f"{stem}.png", plots.render_figure(fig, *PLOT_SIZE))
        atomic_write_bytes(out_dir / f"{stem}.json", (json.dumps(data, separators=(",", ":")) + "\n").encode())
        out.append(PlotFile(name, step.plot, data["title"], f"{stem}.png", f"{stem}.json"))
    return out, notes


def write_palette_png(path: Path, srgb: np.ndarray) -> None:
    """A heat map as a 256-colour PNG: a third of the RGB file's bytes (3.0 MB -> 1.0 MB for the 15
    lecture steps at 480x270, whose noisy maps compress badly), at most 3 levels of 255 off per
    channel (Pillow's max-coverage palette, no dithering: measured on those maps)."""
    import io

    from PIL import Image

    from viewer.base.io import atomic_write_bytes

    im = Image.fromarray(np.ascontiguousarray(srgb, dtype=np.uint8)).quantize(
        256, method=Image.Quantize.MAXCOVERAGE, dither=Image.Dither.NONE)
    buf = io.BytesIO()
    im.save(buf, format="PNG", optimize=True)
    atomic_write_bytes(path, buf.getvalue())


def write_thumbnail(path: Path, srgb: np.ndarray) -> None:
    from PIL import Image

    from viewer.base.io import write_png

    h, w = srgb.shape[:2]
    tw = min(THUMB_WIDTH, w)
    th = max(1, round(h * tw / w))
    im = Image.fromarray(np.ascontiguousarray(srgb)).resize((tw, th), Image.LANCZOS)
    write_png(path, np.asarray(im))


def write_step_assets(index: int, scene, out_dir: Path, width: int, height: int, settings: ReferenceSettings,
                      progress=None) -> StepAssets:
    """Write step ``index``'s (0-based) files under ``out_dir/step-NN/`` (see the module) for
    ``scene`` (the step's scene at width x height) and return what was written."""
    import viewer
    from viewer.base.io import atomic_write_bytes, write_png
    from viewer.image.colour import to_srgb8
    from viewer.image.compare import heat_map, metrics
    from viewer.scene.lecture import TOUR

    step = TOUR[index]
    number = index + 1
    folder = step_folder(number)
    (out_dir / folder).mkdir(exist_ok=True)
    exp, tm = scene.render.exposure, scene.render.tonemap
    raster = viewer.render(scene)
    reference, spp, engine, cached, seconds = reference_image(scene, width, height, settings, progress)
    raster_srgb = to_srgb8(raster, exp, tm)
    write_png(out_dir / folder / "raster.png", raster_srgb)
    write_png(out_dir / folder / "reference.png", to_srgb8(reference, exp, tm))
    diff, scale = heat_map(raster, reference)
    write_palette_png(out_dir / folder / "difference.png", diff)
    write_thumbnail(out_dir / folder / "thumbnail.png", raster_srgb)
    m = metrics(raster, reference)
    plot_files, notes = step_plots(scene, step, out_dir, folder)
    a = StepAssets(number, step.key, step.title, step.caption, width, height, f"{folder}/raster.png",
                   f"{folder}/reference.png", f"{folder}/difference.png", f"{folder}/thumbnail.png",
                   f"{folder}/step.json", int(spp), engine, cached, seconds, float(scale), m["rmse"],
                   m["relative_mse"], step.plot, plot_files, notes)
    data = asdict(a)
    data["metrics"] = m
    atomic_write_bytes(out_dir / a.data, (json.dumps(data, indent=1) + "\n").encode())
    return a
