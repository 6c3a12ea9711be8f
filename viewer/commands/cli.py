"""Command line: the commands of README.md, each a parser (``_parser_<command>``) and a
``cmd_<command>`` that checks the arguments, calls the layers below (scene loading, the
renderer, the reference engines, the plots), writes the files and prints what it did; ``fit``
lives in ``viewer/commands/measured.py``, the command names in ``viewer/commands/names.py``."""

from __future__ import annotations

import argparse
import sys
import time

import viewer
from viewer import OutputError, ViewerError
from viewer.commands.names import COMMANDS, HEADLESS_HINT, add_trust_option

ENGINE_HELP = ("reference engine: cpu (numpy + Embree), gpu (GLSL path tracer) or auto (default: a hardware "
               "GPU, else whichever measured faster here; the choice is printed)")


def _trust(args) -> None:
    from viewer.brdf import twin_trust

    for path in getattr(args, "trust_twin", None) or []:
        twin_trust.trust(path)


def _engine(args, ctx=None, scenes=()):
    """The engine for --engine, printed with the reason (auto's choice). ``scenes``: those it will
    render; auto takes the cpu engine where one needs wavelengths (only it traces them)."""
    from viewer.reference_common.select import choose_for_scenes

    engine, why = choose_for_scenes(args.engine, scenes, spectral=getattr(args, "spectral", None), ctx=ctx)
    print(f"engine: {engine} ({why})")
    return engine


def _parser_window() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="brdf-viewer", description=(
        "OpenGL teaching viewer for BRDFs. With no command: open the window on SCENE (a scene "
        "file or a built-in scene name; the built-in default scene when omitted). Commands: "
        + ", ".join(COMMANDS) + " (brdf-viewer COMMAND --help)."))
    from viewer.scene.lecture import TOUR

    n = len(TOUR)
    p.add_argument("scene", nargs="?", help=(
        f"scene file (.toml) or built-in scene name; lecture:1 .. lecture:{n} open the lecture tour's "
        f"{n} steps in lecture mode (keys there: 1-9 and 0 for steps 1-10, Shift 1-{n - 10} for 11-{n}, "
        "the arrows and page keys for every step)"))
    p.add_argument("--version", action="version", version=f"brdf-viewer {viewer.__version__}",
                   help="print the version and exit")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a scene value by dotted path, e.g. materials.ball.albedo=[1,0,0]")
    p.add_argument("--width", type=int, help="window width in pixels (default: the last session's, else 1280)")
    p.add_argument("--height", type=int, help="window height in pixels (default: the last session's, else 720)")
    p.add_argument("--frames", type=int, default=0, help="quit after this many frames (0 = run until closed)")
    p.add_argument("--screenshot", metavar="PNG", help="with --frames N: after N frames, save a screenshot once the view is finished "
                        "(no tiles or compile in progress; a reference pass where the view shows it)")
    p.add_argument("--no-compile-ahead", dest="compile_ahead", action="store_false", default=None,
                   help="compile shader programs on the window's thread instead of in a background process "
                        "(a preset or model change then stops the frames while it compiles)")
    add_trust_option(p)
    return p


def _parser_render() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="brdf-viewer render",
                                description="Rasterize a scene offscreen (EGL) with the window's renderer.")
    p.add_argument("scene", help="scene file (.toml) or built-in scene name")
    p.add_argument("--out", required=True, help="output PNG (sRGB, after exposure and tone mapping)")
    p.add_argument("--linear", help="also write the linear radiance as float32 .npy (H, W, 3), row 0 = top")
    p.add_argument("--width", type=int, help="image width (overrides camera.width)")
    p.add_argument("--height", type=int, help="image height (overrides camera.height)")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a scene value by dotted path (repeatable)")
    p.add_argument("--bparam", dest="bparams", action="append", default=[], metavar="MATERIAL=FILE",
                   help="set a material's values from a BRDF Explorer .bparam file (repeatable; --set wins)")
    p.add_argument("--view", default="shaded", help="shaded | F | D | G | N.L | \"f cos\" | shadow (term views) | \"ssr hit\" | \"ssr steps\" | \"ssr uv\" | \"ssr only\" (SSR debug)")
    p.add_argument("--supersample", type=int, default=1, metavar="K",
                   help="K x K shading points per pixel, averaged (an exact box filter, as the reference "
                        "computes pixels); default 1 = the scene's MSAA, shading once per pixel")
    add_trust_option(p)
    return p


def _parser_reference() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="brdf-viewer reference",
                                description="Render a scene with the reference path tracer (same meshes, "
                                            "same camera as render). Prints progress and samples/second.")
    p.add_argument("scene", help="scene file (.toml) or built-in scene name")
    p.add_argument("--spp", type=int, required=True, help="samples per pixel (>= 1)")
    p.add_argument("--out", required=True, help="output PNG (sRGB, after exposure and tone mapping)")
    p.add_argument("--linear", help="also write the linear radiance as float32 .npy (H, W, 3), row 0 = top")
    p.add_argument("--seed", type=int, default=0, help="random seed (same seed, same image)")
    p.add_argument("--max-depth", type=int, default=8, dest="max_depth",
                   help="scattering events per path (1 = direct light only)")
    p.add_argument("--width", type=int, help="image width (overrides camera.width)")
    p.add_argument("--height", type=int, help="image height (overrides camera.height)")
    p.add_argument("--workers", type=int, help="worker processes of the cpu engine (default: every core)")
    p.add_argument("--engine", default="auto", help=ENGINE_HELP)
    p.add_argument("--spectral", action="store_true", default=None,
                   help="trace wavelengths (hero-wavelength sampling, cpu engine; default when a material "
                        "is dispersive)")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a scene value by dotted path (repeatable)")
    p.add_argument("--bparam", dest="bparams", action="append", default=[], metavar="MATERIAL=FILE",
                   help="set a material's values from a BRDF Explorer .bparam file (repeatable; --set wins)")
    _add_estimator_options(p)
    add_trust_option(p)
    return p


def _add_estimator_options(p: argparse.ArgumentParser) -> None:
    """The reference estimator's options (reference and compare)."""
    p.add_argument("--strategy", default="mis", choices=("mis", "bsdf", "light"),
                   help="how the environment is reached: BSDF sampling only, light (environment) sampling "
                        "only, or both with multiple importance sampling (default); point and directional "
                        "lights are always next-event estimated")
    p.add_argument("--mis-heuristic", dest="mis_heuristic", default="power", choices=("power", "balance"),
                   help="MIS weights: power (beta = 2, default) or balance heuristic")
    p.add_argument("--no-roulette", dest="russian_roulette", action="store_false",
                   help="trace every path to --max-depth (no Russian roulette)")
    _add_integrator_option(p)


def _add_integrator_option(p: argparse.ArgumentParser) -> None:
    from viewer.reference_common.caustics import INTEGRATORS

    p.add_argument("--integrator", default=None, choices=INTEGRATORS,
                   help="path: path tracing; photon: path tracing plus a progressive caustic photon map, "
                        "for light reaching diffuse surfaces through mirrors and glass (default: photon where "
                        "the scene has smooth surfaces lit by point, directional or small lights, else path; "
                        "one line says which)")


def _estimator(args) -> dict:
    return {"strategy": args.strategy, "mis_heuristic": args.mis_heuristic,
            "russian_roulette": args.russian_roulette, "integrator": getattr(args, "integrator", None) or "auto"}


def _say_integrator(renderer) -> str:
    """Print which integrator the renderer runs and why (one line); returns its name."""
    setup = renderer.setup
    print(f"integrator: {setup.integrator} ({setup.integrator_reason})")
    return setup.integrator


def _parser_plot() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="brdf-viewer plot", description=(
        "The BRDF plots of the window, headless: a PNG drawn with Pillow whose text chunk "
        "'brdf-viewer:plot' holds the plotted numbers as JSON."))
    p.add_argument("model", help="a BRDF model (brdf-viewer models), a material preset (e.g. lecture_air_glass), a "
                   "material .toml, a measured .binary / .dat file or a BRDF Explorer .brdf / .bparam file")
    p.add_argument("--kind", required=True, help="polar | lobe | albedo | fresnel | bouguer | spectral | sampling | "
                   "slice | theta_h | theta_d | theta_v | terms")
    p.add_argument("--overlay", metavar="MODEL", help="polar, albedo, slice, theta_*: a second material drawn over it (a model, "
                   "preset, .binary / .dat measured file or material .toml, e.g. one written by brdf-viewer fit)")
    p.add_argument("--out", required=True, help="output PNG")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="set a material parameter, e.g. alpha=0.2, eta=[0.2,0.9,1.1], coating.ior=1.3 (repeatable)")
    p.add_argument("--theta-i", dest="theta_i", type=float, default=45.0, metavar="DEG",
                   help="incident angle from the normal, [0, 90) (polar, lobe); default 45")
    p.add_argument("--phi", type=float, default=0.0, metavar="DEG",
                   help="azimuth of the plane of incidence: 0 = tangent (x-z), 90 = bitangent (y-z) (polar, lobe)")
    p.add_argument("--channel", default="rgb",
                   help="rgb (one curve per distinct channel) | lum (Rec.709 luminance) | r | g | b")
    p.add_argument("--inside", action="store_true",
                   help="fresnel: light inside the denser medium (eta = 1/ior): critical angle, total internal reflection")
    p.add_argument("--log", action="store_true", help="polar, lobe, theta_*: plot log10(1 + y); terms: a log10 axis")
    p.add_argument("--theta-d", dest="theta_d", type=float, default=0.0, metavar="DEG",
                   help="theta_h plot: the held difference angle theta_d, [0, 90) (default 0)")
    p.add_argument("--theta-h", dest="theta_h", type=float, default=0.0, metavar="DEG",
                   help="theta_d plot: the held half angle theta_h, [0, 90) (default 0)")
    p.add_argument("--phi-v", dest="phi_v", type=float, default=None, metavar="DEG",
                   help="theta_v plot: azimuth of the view's plane (default --phi, the light's)")
    p.add_argument("--phi-d", dest="phi_d", type=float, default=90.0, metavar="DEG",
                   help="slice: the held difference azimuth phi_d, [0, 180] (default 90)")
    p.add_argument("--cos", action="store_true",
                   help="theta_*, slice: f times cos theta_i of the light (BRDF Explorer's N.L)")
    p.add_argument("--samples", type=int, default=200_000,
                   help="sampling: directions drawn from the sampler for the histogram (default 200000)")
    p.add_argument("--seed", type=int, default=0, help="sampling: random seed (default 0)")
    p.add_argument("--data", metavar="JSON", help="also write the plotted numbers as JSON")
    p.add_argument("--width", type=int, default=900, help="image width (default 900)")
    p.add_argument("--height", type=int, default=600, help="image height (default 600)")
    add_trust_option(p)
    return p


def cmd_plot(args) -> int:
    from viewer import plots
    from viewer.base.io import check_output_path
    from viewer.scene import material_from_name

    out = check_output_path(args.out, (".png",), "--out")
    data = check_output_path(args.data, (".json",), "--data") if args.data else None
    plots.check_kind_name(args.kind)
    plots.check_channel(args.channel)
    p = material_from_name(args.model, args.overrides)
    overlay = material_from_name(args.overlay, []) if args.overlay else None
    fig = plots.figure(p, args.kind, theta_i=args.theta_i, phi=args.phi, channel=args.channel,
                       inside=args.inside, log=args.log, name=args.model, samples=args.samples, seed=args.seed,
                       overlay=overlay, theta_d=args.theta_d, theta_h=args.theta_h, phi_v=args.phi_v,
                       phi_d=args.phi_d, cos=args.cos)
    plots.write_plot(fig, out, data, args.width, args.height)
    print(f"wrote {out} ({args.kind} plot of {args.model})" + (f" and {data}" if data else ""))
    return 0


class ProgressBar:
    """A progress line on stderr: redrawn in place on a terminal; elsewhere (a log file, a CI
    job) one plain line every ``every_s`` seconds and at 100%, so logs do not fill with
    carriage-return redraws."""

    def __init__(self, label: str, start: float, stream=None, every_s: float = 5.0):
        self.label, self.start, self.every_s = label, start, every_s
        self.stream = stream if stream is not None else sys.stderr
        isatty = getattr(self.stream, "isatty", None)
        self.tty = bool(isatty and isatty())
        self._last = None
        self._wrote = False

    def __call__(self, frac: float):
        now = time.perf_counter()
        n = int(30 * frac)
        text = f"{self.label} [{'#' * n}{'.' * (30 - n)}] {100 * frac:5.1f}% {now - self.start:6.1f} s"
        if self.tty:
            self.stream.write("\r" + text)
            self._wrote = True
        elif self._last is None or now - self._last >= self.every_s or frac >= 1.0:
            if frac >= 1.0 and self._last is not None and self._done:
                return
            self.stream.write(text + "\n")
            self._last = now
            self._done = frac >= 1.0
        self.stream.flush()

    _done = False

    def end(self):
        if self.tty and self._wrote:
            self.stream.write("\n")
            self.stream.flush()


def _parser_models() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="brdf-viewer models",
                                description="List every BRDF model with its parameters, ranges and defaults.")
    p.add_argument("files", nargs="*", metavar="FILE.brdf", help="list these .brdf files' parameters instead")
    add_trust_option(p)
    return p


def _bparam_overrides(args) -> list[str]:
    """``--bparam MATERIAL=FILE.bparam``: the file's values as ``materials.MATERIAL.NAME=VALUE``
    assignments (before the ``--set`` ones, which win); names the file's BRDF lacks: one note."""
    from viewer.brdf import bparam

    out = []
    for a in getattr(args, "bparams", None) or []:
        mat, sep, path = a.partition("=")
        if not sep or not mat or not path:
            raise ViewerError(f"--bparam {a}: expected MATERIAL=FILE.bparam, e.g. --bparam ball=shiny.bparam")
        lines, note = bparam.overrides(path, prefix=f"materials.{mat}.")
        if note:
            print(f"brdf-viewer: {note}", file=sys.stderr)
        out += lines
    return out


def _overrides(args) -> list[str]:
    """--set assignments plus --width / --height as camera overrides."""
    from viewer.scene import check_replaced

    out = _bparam_overrides(args) + list(args.overrides)
    check_replaced(out, {f"camera.{k}": f"--{k}" for k in ("width", "height") if getattr(args, k) is not None})
    for key, val in (("width", args.width), ("height", args.height)):
        if val is not None:
            out.append(f"camera.{key}={val}")
    return out


def _load(ref, overrides):
    """``load_scene`` and, for a large scene, one line on stderr saying how large and how long
    the load took, before the rendering starts (``Scene.size_note``)."""
    from viewer.scene import load_scene
    from viewer.scene.model import LARGE_SCENE_OBJECTS

    t0 = time.perf_counter()
    expected = _objects_in_file(ref)
    if expected >= LARGE_SCENE_OBJECTS:  # a long load: say so before it starts, not only after
        print(f"brdf-viewer: {ref}: loading about {expected:,} objects", file=sys.stderr, flush=True)
    scene = load_scene(ref, overrides)
    note = scene.size_note()
    if note:
        print(f"brdf-viewer: {scene.label}: {note}, loaded in {time.perf_counter() - t0:.1f} s; rendering",
              file=sys.stderr, flush=True)
    return scene


def _raster_note(scene) -> None:
    """One line on stderr for a scene whose lights outnumber the raster's shadow maps."""
    from viewer.gl.shadow import unshadowed_note

    note = unshadowed_note(scene)
    if note:
        print(f"brdf-viewer: {scene.label}: {note}", file=sys.stderr, flush=True)


def _objects_in_file(ref) -> int:
    """How many ``[[objects]]`` tables a scene file holds, counted in its text without parsing
    it (0 for a built-in name, a PNG or a file that cannot be read: the load names the problem)."""
    import os

    try:
        if not str(ref).endswith(".toml") or os.path.getsize(ref) > (256 << 20):
            return 0
        with open(ref, "rb") as f:
            return f.read().count(b"[[objects]]")
    except (OSError, TypeError, ValueError):
        return 0


def _write_all(outputs) -> None:
    """Write a command's outputs ((path or None, write) pairs, each write atomic): when one fails
    (a full disk), the ones this command already wrote are removed again, so a failed command
    leaves no file of its own behind (an older file under a name is replaced only on success)."""
    import os

    done = []
    try:
        for path, write in outputs:
            if path is None:
                continue
            existed = os.path.lexists(path)
            write()
            if not existed:
                done.append(path)
    except BaseException:
        for path in done:
            try:
                os.unlink(path)
            except OSError:
                pass
        raise


def _screenshot_size(args) -> list[str]:
    """A screenshot named as the scene renders at the screenshot's size (camera overrides, before
    --width / --height and --set, which win)."""
    from pathlib import Path

    path = Path(str(args.scene))
    if path.suffix.lower() != ".png" or not path.is_file():
        return []
    try:
        from PIL import Image

        with Image.open(path) as im:
            w, h = im.size
    except Exception:  # noqa: BLE001 - Pillow raises many kinds for a broken PNG; load_scene names it
        return []
    return [f"camera.width={w}", f"camera.height={h}"]


def cmd_render(args) -> int:
    from viewer.gl.context import create_offscreen_context
    from viewer.gl.renderer import VIEW_MODES, Renderer
    from viewer.base.io import check_output_path, write_npy, write_png
    from viewer.scene.screenshot import png_text

    out = check_output_path(args.out, (".png",), "--out")
    lin_path = check_output_path(args.linear, (".npy",), "--linear") if args.linear else None
    if args.view not in VIEW_MODES:
        raise ViewerError(f"--view: {args.view!r} is not a view; allowed: {', '.join(VIEW_MODES)}")
    scene = _load(args.scene, _screenshot_size(args) + _overrides(args))
    _raster_note(scene)
    ctx = create_offscreen_context()
    renderer = Renderer(ctx)
    from viewer.scene.camera import OrbitCamera

    camera = OrbitCamera.from_scene(scene)
    if not 1 <= args.supersample <= 8:
        raise ViewerError(f"--supersample: {args.supersample} is out of range; allowed: 1 to 8")
    linear, srgb = renderer.render_arrays(scene, camera, view_mode=VIEW_MODES[args.view],
                                          supersample=args.supersample)
    from viewer.image import term_scales
    if args.view in term_scales.SCALES:  # false colour: no exposure or tone mapping, a colour bar below
        from viewer.image.colour import to_srgb8

        srgb = term_scales.with_colour_bar(to_srgb8(linear, 0.0, "none"), args.view)
    _write_all([(lin_path, lambda: write_npy(lin_path, linear)),
                (out, lambda: write_png(out, srgb, png_text(scene, camera)))])
    print(f"wrote {out} ({srgb.shape[1]}x{srgb.shape[0]})" + (f" and {lin_path}" if lin_path else ""))
    from viewer.image.finite import culprits, nonfinite_count, nonfinite_message, render_switches

    if nonfinite_count(linear):  # a renderer bug: say where it came from and fail
        found = culprits(scene, lambda s: renderer.render_arrays(s, camera, view_mode=VIEW_MODES[args.view],
                                                                 supersample=args.supersample)[0])
        print("brdf-viewer: error: " + nonfinite_message(linear, f"render {args.scene}", found,
                                                         render_switches(scene)), file=sys.stderr)
        return 3
    return 0


def cmd_reference(args) -> int:
    from viewer.scene.camera import OrbitCamera
    from viewer.image.colour import to_srgb8
    from viewer.base.io import check_output_path, write_npy, write_png
    from viewer.scene.screenshot import png_text

    out = check_output_path(args.out, (".png",), "--out")
    lin_path = check_output_path(args.linear, (".npy",), "--linear") if args.linear else None
    if args.spp < 1:
        raise ViewerError(f"--spp: {args.spp} is out of range; allowed: an integer >= 1")
    if args.max_depth < 1:
        raise ViewerError(f"--max-depth: {args.max_depth} is out of range; allowed: an integer >= 1 "
                          "(1 = direct light only)")
    if args.workers is not None and args.workers < 0:
        raise ViewerError(f"--workers: {args.workers} is out of range; allowed: an integer >= 0 (0 = no pool)")
    scene = _load(args.scene, _overrides(args))
    camera = OrbitCamera.from_scene(scene)
    from viewer.reference_common.select import make_renderer

    w, h = scene.camera.width, scene.camera.height
    engine = _engine(args, scenes=[scene])
    t0 = time.perf_counter()
    renderer = make_renderer(engine, scene, camera, max_depth=args.max_depth, seed=args.seed, workers=args.workers,
                             spectral=args.spectral, **_estimator(args))
    integrator = _say_integrator(renderer)
    try:
        renderer.warm_up()
        start = time.perf_counter()

        bar = ProgressBar(f"reference {w}x{h} {args.spp} spp", start)
        bar(0.0)
        try:
            renderer.step(args.spp, progress=bar)
        finally:  # an error message starts on its own line, not after the bar
            bar.end()
        wall = time.perf_counter() - start
        linear = renderer.mean()
        bad = renderer.bad_values
    finally:
        renderer.close()
    srgb = to_srgb8(linear, scene.render.exposure, scene.render.tonemap)
    text = png_text(scene, camera, {"reference": {"spp": args.spp, "seed": args.seed, "max_depth": args.max_depth,
                                                  "engine": engine, **_estimator(args), "integrator": integrator}})
    _write_all([(lin_path, lambda: write_npy(lin_path, linear)), (out, lambda: write_png(out, srgb, text))])
    samples = w * h * args.spp
    print(f"wrote {out} ({w}x{h}, {args.spp} spp" + (", spectral" if renderer.is_spectral else "") + ")"
          + (f" and {lin_path}" if lin_path else ""))
    print(f"{samples / max(wall, 1e-9):.0f} samples/second ({samples} camera samples in {wall:.2f} s; "
          f"{time.perf_counter() - t0 - wall:.2f} s setup)")
    if bad:
        print(f"warning: {bad} NaN/Inf/negative values from the BRDF models were replaced by 0", file=sys.stderr)
    return 0


def _parser_compare() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="brdf-viewer compare",
                                description="Raster vs reference: both images, difference heat maps and metrics.json.")
    p.add_argument("scene", help="scene file (.toml), screenshot (.png) or built-in scene name")
    p.add_argument("--spp", type=int, required=True, help="reference samples per pixel")
    p.add_argument("--out", required=True, help="output folder (created if missing)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--max-depth", type=int, default=8, help="reference path length (1 = direct light)")
    p.add_argument("--supersample", type=int, default=4,
                   help="raster K x K shading points per pixel (box filter, as the reference); default 4")
    p.add_argument("--width", type=int)
    p.add_argument("--height", type=int)
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")
    p.add_argument("--bparam", dest="bparams", action="append", default=[], metavar="MATERIAL=FILE",
                   help="set a material's values from a BRDF Explorer .bparam file (repeatable; --set wins)")
    p.add_argument("--workers", type=int, default=None)
    p.add_argument("--engine", default="auto", help=ENGINE_HELP)
    _add_estimator_options(p)
    add_trust_option(p)
    return p


def cmd_compare(args) -> int:
    """Writes raster.png/.npy, reference.png/.npy, diff_abs.png, diff_rel.png, metrics.json."""
    import json
    from pathlib import Path

    from viewer.scene.camera import OrbitCamera
    from viewer.image.colour import to_srgb8
    from viewer.image.compare import heat_map, metrics
    from viewer.gl.context import create_offscreen_context
    from viewer.gl.renderer import Renderer
    from viewer.reference_common.select import make_renderer
    from viewer.base.io import atomic_write_bytes, write_npy, write_png
    from viewer.scene import load_scene

    if args.spp < 1:
        raise ViewerError(f"--spp: {args.spp} is out of range; allowed: an integer >= 1")
    if args.max_depth < 1:
        raise ViewerError(f"--max-depth: {args.max_depth} is out of range; allowed: an integer >= 1")
    if not 1 <= args.supersample <= 8:
        raise ViewerError(f"--supersample: {args.supersample} is out of range; allowed: 1 to 8")
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise ViewerError(f"--out {out}: exists and is not a folder")
    scene = load_scene(args.scene, _overrides(args))
    _raster_note(scene)
    camera = OrbitCamera.from_scene(scene)
    ctx = create_offscreen_context()
    raster = Renderer(ctx).render_arrays(scene, camera, supersample=args.supersample)[0]
    engine = _engine(args, ctx, scenes=[scene])
    t0 = time.perf_counter()
    with make_renderer(engine, scene, camera, max_depth=args.max_depth, seed=args.seed, workers=args.workers,
                       ctx=ctx, **_estimator(args)) as ref:
        integrator = _say_integrator(ref)
        ref.step(args.spp)
        reference, variance = ref.mean(), ref.variance()
    wall = time.perf_counter() - t0
    m = metrics(raster, reference)
    m.update({"scene": str(args.scene), "spp": args.spp, "seed": args.seed, "max_depth": args.max_depth,
              **_estimator(args), "integrator": integrator,
              "raster_supersample": args.supersample, "reference_seconds": wall, "engine": engine,
              "reference_mean_variance_of_mean": float(variance.mean())})
    abs_png, abs_scale = heat_map(raster, reference)
    rel_png, rel_scale = heat_map(raster, reference, relative=True)
    m["heat_map_scale_abs"], m["heat_map_scale_rel"] = abs_scale, rel_scale
    out.mkdir(parents=True, exist_ok=True)
    exp, tm = scene.render.exposure, scene.render.tonemap
    write_npy(out / "raster.npy", raster)
    write_npy(out / "reference.npy", reference)
    write_png(out / "raster.png", to_srgb8(raster, exp, tm))
    write_png(out / "reference.png", to_srgb8(reference, exp, tm))
    write_png(out / "diff_abs.png", abs_png)
    write_png(out / "diff_rel.png", rel_png)
    atomic_write_bytes(out / "metrics.json", (json.dumps(m, indent=2) + "\n").encode())
    print(f"wrote {out}/: raster, reference, diff_abs (scale {abs_scale:.3g}), diff_rel (scale {rel_scale:.3g}), "
          f"metrics.json; RMSE {m['rmse']:.4g}, relative MSE {m['relative_mse']:.4g}")
    return 0


def cmd_models(args) -> int:
    from viewer import brdf

    if getattr(args, "files", None):
        for f in args.files:
            model = brdf.load(f)
            print(f"{f}: model = \"custom\", file = {f!r}; sampler: {model.sampled_by or 'cosine-weighted (generic)'}"
                  f"; numpy twin: {_twin_state(model)}")
            for p in model.spec.params[1:]:
                print(f"    {_describe_param(p)}")
        return 0
    for name in brdf.names():
        spec = brdf.get(name).spec
        print(f"{name}: {spec.title}  [{spec.source}]")
        for p in spec.params:
            print(f"    {_describe_param(p)}")
        if not spec.reciprocal:
            print(f"    (not reciprocal: {spec.reciprocal_why})")
    from viewer.brdf.presets import PRESETS

    print("\npresets (scene files: preset = \"NAME\", any parameter may be overridden beside it):")
    for name in sorted(PRESETS):
        print(f"    {name}: {PRESETS[name]['model']}")
    return 0


def _twin_state(model) -> str:
    if model.twin is not None:
        return "yes"
    return "not run (not trusted: --trust-twin PATH)" if model.twin_not_run else "no"


def _describe_param(p, indent="    ") -> str:
    from viewer.brdf import lookup_spec
    from viewer.brdf.spec import default_value

    d = default_value(p, lookup_spec)
    if p.kind == "rgb":
        dv = "[" + ", ".join(f"{x:g}" for x in d) + "]"
    elif p.kind in ("table", "lobes", "material"):
        dv = "see below" if p.kind != "material" else d.model
    elif p.kind == "bool":
        dv = "true" if d else "false"
    else:
        dv = repr(d) if isinstance(d, str) else f"{d:g}"
    unit = f" {p.unit}" if p.unit else ""
    line = f"{p.name} ({p.kind}) default {dv}{unit}; {p.allowed()}" + (f" - {p.doc}" if p.doc else "")
    if p.kind in ("table", "lobes"):
        line += "".join("\n" + indent + "    " + _describe_param(f, indent + "    ") for f in p.fields)
    return line


def _parser_bake() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="brdf-viewer bake",
                                description="Fill the reference cache in advance (the window shows a cached "
                                            "reference at once and keeps refining it); with --lecture also the "
                                            "traced-frame cache: every lecture step with traced glass or mirrors, "
                                            "traced for a window of --width x --height (default: the size of the "
                                            "window the last session used), opens fully traced in every layout of "
                                            "that window (the window's Prepare lecture does the same for its size).")
    p.add_argument("scenes", nargs="*", metavar="SCENE", help="scene files or built-in scene names")
    p.add_argument("--lecture", action="store_true", help="also every lecture step")
    p.add_argument("--steps", default=None, metavar="LIST",
                   help="with --lecture: only these steps (1-based, e.g. 2,3,10-13)")
    p.add_argument("--spp", type=int, help="samples per pixel each reference should reach (required unless "
                                           "only the lecture's traced frames are wanted)")
    p.add_argument("--width", type=int, help="reference width (default: half the scene camera's width, "
                                             "as the window's reference view renders); with --lecture also "
                                             "the width of the window the traced frames are for")
    p.add_argument("--height", type=int, help="reference height (default: half the scene camera's height); "
                                              "with --lecture also the traced frames' window height")
    p.add_argument("--max-depth", type=int, default=8, dest="max_depth")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--workers", type=int, default=None)
    p.add_argument("--engine", default="auto", help=ENGINE_HELP)
    _add_integrator_option(p)
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")
    p.add_argument("--bparam", dest="bparams", action="append", default=[], metavar="MATERIAL=FILE",
                   help="set a material's values from a BRDF Explorer .bparam file (repeatable; --set wins)")
    add_trust_option(p)
    return p


def cmd_bake(args) -> int:
    from viewer.scene.camera import OrbitCamera
    from viewer.reference_common.select import make_renderer, needs_spectral
    from viewer.reference_common import cache
    from viewer.reference_common.setup import RenderSetup

    for name in ("width", "height"):
        v = getattr(args, name)
        if v is not None and not 1 <= v <= 16384:
            raise ViewerError(f"--{name}: {v} is out of range; allowed: an integer from 1 to 16384")
    if args.lecture and (args.width is None) != (args.height is None):
        raise ViewerError("bake --lecture: give both --width and --height (the window size the traced frames are "
                          "for) or neither (the last session's window)")
    steps = _lecture_steps(args.steps) if args.steps is not None else None
    if steps is not None and not args.lecture:
        raise ViewerError("bake: --steps goes with --lecture")
    if args.spp is None:
        if not args.lecture:
            raise ViewerError("bake: --spp N is required (or --lecture for the lecture's traced frames alone)")
        if args.scenes:
            raise ViewerError("bake: scenes other than the lecture's need --spp N (their references)")
        return _bake_traced(*_lecture_window(args), steps)
    if args.spp < 1:
        raise ViewerError(f"--spp: {args.spp} is out of range; allowed: an integer >= 1")
    if args.max_depth < 1:
        raise ViewerError(f"--max-depth: {args.max_depth} is out of range; allowed: an integer >= 1")
    jobs = [(str(s), lambda s=s: _load(s, _overrides(args))) for s in args.scenes]
    if args.lecture:
        from viewer.scene.lecture import TOUR, tour_scene

        jobs += [(f"lecture step {i + 1}", lambda i=i: tour_scene(i)) for i in range(len(TOUR))
                 if steps is None or i in steps]
    if not jobs:
        raise ViewerError("bake: name at least one SCENE, or --lecture")
    scenes = [(label, make()) for label, make in jobs]   # every scene loads before any rendering
    cache.check_writable()                                 # a cache that cannot store: say so before rendering
    engine = _engine(args, scenes=[s for _, s in scenes])
    for label, scene in scenes:
        camera = OrbitCamera.from_scene(scene)
        w = args.width or max(1, scene.camera.width // 2)
        h = args.height or max(1, scene.camera.height // 2)
        setup = RenderSetup.from_scene(scene, camera, w, h, args.max_depth, integrator=args.integrator or "auto")
        print(f"{label}: integrator: {setup.integrator} ({setup.integrator_reason})")
        setup.extra["spectral"] = needs_spectral(scene)   # as both engines key it (dispersive: wavelengths)
        key = cache.setup_key(setup)
        old = cache.load(key, shape=(h, w, 3))   # a damaged entry: set aside with one line, rendered afresh
        have = old.spp if old is not None else 0
        if have >= args.spp:
            print(f"{label}: {w}x{h} already cached at {have} spp ({key[:12]})")
            continue
        start = time.perf_counter()
        with make_renderer(engine, scene, camera, w, h, max_depth=args.max_depth, seed=args.seed,
                           workers=args.workers, integrator=setup.integrator) as r:
            if old is not None:
                r.resume(old.sum, old.sum2, old.spp)

            def bar(frac):
                n = int(30 * frac)
                sys.stderr.write(f"\rbake {label} [{'#' * n}{'.' * (30 - n)}] {100 * frac:5.1f}% {w}x{h} "
                                 f"{args.spp} spp {time.perf_counter() - start:6.1f} s")
                sys.stderr.flush()

            bar(0.0)
            try:
                r.step(args.spp - have, progress=bar)
            finally:
                sys.stderr.write("\n")
            total, total2, spp = r.state()
        cache.store(key, cache.Entry(total, total2, spp, engine, args.seed))  # CacheError: one line, exit 1
        print(f"{label}: {w}x{h} {spp} spp in {time.perf_counter() - start:.1f} s -> {cache.path_for(key)}")
    return _bake_traced(*_lecture_window(args), steps) if args.lecture else 0


def _parser_handout() -> argparse.ArgumentParser:
    from viewer.handout.pages import DEFAULT_SIZE

    p = argparse.ArgumentParser(prog="brdf-viewer handout",
                                description="Write the lecture as a static web handout: OUT/index.html and one page "
                                            "per step, OUT/step-NN.html (title, caption, the live WebGL2 view with "
                                            "its sliders, raster, reference, difference map, the step's plots with "
                                            "their numbers as JSON). Every file lies inside OUT: copy the folder to "
                                            "any static host, or open index.html from disk.")
    p.add_argument("out", metavar="OUT", help="the handout's folder (created when missing)")
    p.add_argument("--steps", default=None, metavar="LIST",
                   help="only these lecture steps (1-based, e.g. 1-15 or 2,3,10-13; default every step)")
    p.add_argument("--width", type=int, default=None,
                   help="raster, reference and difference images' width (default %d, with --height %d: the "
                        "window's reference size, which bake fills the reference cache at)" % DEFAULT_SIZE)
    p.add_argument("--height", type=int, default=None, help="their height (default %d)" % DEFAULT_SIZE[1])
    p.add_argument("--spp", type=int, default=64,
                   help="samples per pixel of a reference the cache lacks (rendered and stored as bake does; "
                        "a cached one with more samples is used as it is); default 64")
    p.add_argument("--engine", default="auto", help=ENGINE_HELP)
    p.add_argument("--workers", type=int, default=None, help="worker processes of the cpu engine (default: every core)")
    add_trust_option(p)
    return p


def cmd_handout(args) -> int:
    from viewer.handout.assets import ReferenceSettings
    from viewer.handout.pages import DEFAULT_SIZE, build_handout

    w = args.width if args.width is not None else DEFAULT_SIZE[0]
    h = args.height if args.height is not None else DEFAULT_SIZE[1]
    for name, v in (("width", w), ("height", h)):
        if not 16 <= v <= 4096:
            raise ViewerError(f"--{name}: {v} is out of range; allowed: an integer from 16 to 4096")
    if args.spp < 1:
        raise ViewerError(f"--spp: {args.spp} is out of range; allowed: an integer >= 1")
    if args.workers is not None and args.workers < 0:
        raise ViewerError(f"--workers: {args.workers} is out of range; allowed: an integer >= 0 (0 = no pool)")
    from viewer.reference_common.select import ENGINES

    if args.engine not in ENGINES:
        raise ViewerError(f"--engine: {args.engine!r} is not a reference engine; allowed: {', '.join(ENGINES)}")
    from viewer.scene.lecture import TOUR

    steps = _lecture_steps(args.steps) if args.steps is not None else list(range(len(TOUR)))
    from pathlib import Path

    command = f"brdf-viewer handout {Path(args.out).name or 'OUT'}" + (f" --steps {args.steps}" if args.steps else "") + f" --width {w} --height {h}"
    r = build_handout(args.out, steps, w, h, ReferenceSettings(args.spp, args.engine, workers=args.workers),
                      report=lambda line: print(line, flush=True),
                      progress=lambda label: ProgressBar(label, time.perf_counter()), command=command)
    names = r.pages[1:]
    refs = ", ".join(f"{a.number}: {a.spp} spp {a.engine}{' (cached)' if a.cached else ''}" for a in r.steps)
    print(f"wrote {r.out}/: index.html and {len(r.steps)} step page{'s' if len(r.steps) != 1 else ''} "
          f"({', '.join(names) if len(names) <= 3 else names[0] + ' .. ' + names[-1]}), {r.size_bytes / 1e6:.1f} MB "
          f"in {r.seconds:.0f} s; references per step: {refs}")
    return 0


def _lecture_steps(text: str) -> list[int]:
    """``--steps 2,3,10-13`` as 0-based lecture steps, in the tour's order."""
    from viewer.scene.lecture import TOUR

    out: set[int] = set()
    for part in str(text).split(","):
        part = part.strip()
        lo, _, hi = part.partition("-")
        try:
            a, b = int(lo), int(hi or lo)
        except ValueError:
            raise ViewerError(f"--steps: {part!r} is not a step or a range (e.g. 2,3,10-13)") from None
        if not (1 <= a <= b <= len(TOUR)):
            raise ViewerError(f"--steps: {part!r} is out of range; the lecture has steps 1 to {len(TOUR)}")
        out.update(range(a - 1, b))
    return sorted(out)


def _lecture_window(args) -> tuple[int, int]:
    """The window size the lecture's traced frames are for: --width and --height, else the
    framebuffer the last session drew into (its state file: full screen, or a HiDPI screen's
    pixels, as the window's Prepare lecture prepares), else that session's window size, else
    the window's default size."""
    if args.width is not None:
        return args.width, args.height
    from viewer.app.state import DEFAULT_WINDOW, load_state

    st = load_state()
    for w, h in (("framebuffer_width", "framebuffer_height"), ("window_width", "window_height")):
        if w in st and h in st:
            return st[w], st[h]
    return DEFAULT_WINDOW


def _bake_traced(w: int, h: int, steps=None) -> int:
    """The traced-frame cache for a w x h window: every lecture step with traced chains
    (``viewer.app.lecture_prep``; ``steps``: only those of them), one line per step and one at
    the end."""
    import os

    from viewer.app.lecture_prep import PARENT_ENV, LecturePrep, prepared_text, traced_steps, view_size
    from viewer.gl import trace_cache
    from viewer.gl.context import create_offscreen_context
    from viewer.gl.renderer import Renderer

    from viewer.base.io import atomic_write_bytes

    folder = trace_cache.cache_folder()
    try:
        folder.mkdir(parents=True, exist_ok=True)
        probe = atomic_write_bytes(folder / f".probe-{os.getpid()}", b"")
        probe.unlink()
    except OSError as e:   # a full disk or an unwritable folder: an output problem, exit 1
        why = e.strerror or (os.strerror(e.errno) if e.errno else str(e))   # viewer.base.io keeps the errno
        raise OutputError(f"bake --lecture: the traced-frame cache {folder} cannot be written ({why})") from None
    parent = os.environ.get(PARENT_ENV, "")
    if parent.isdigit():  # run by the window's Prepare lecture: it ends when the window does
        from viewer.pathtracer.progressive import watch_parent

        watch_parent(int(parent))
    steps = [i for i in traced_steps() if steps is None or i in steps]
    vw, vh = view_size((w, h))
    print(f"preparing lecture for {prepared_text((w, h))}: {len(steps)} traced steps", flush=True)
    ctx = create_offscreen_context()
    renderer = Renderer(ctx)
    try:
        prep = LecturePrep(ctx, renderer, (w, h), steps)

        def said(r):
            for msg in prep.messages:
                print(msg, flush=True)
            prep.messages.clear()
            if r.cached:
                print(f"lecture step {r.step + 1}: {vw}x{vh} already prepared", flush=True)
            elif r.stored is None:
                why = trace_cache.store_failure() or "the cache folder could not be written"
                raise OutputError(f"bake --lecture: lecture step {r.step + 1} traced but not stored in {folder}: {why}")
            else:
                print(f"lecture step {r.step + 1}: traced {vw}x{vh} in {r.seconds:.1f} s -> {r.stored}", flush=True)

        prep.run(said)
        print(f"lecture prepared for {prepared_text((w, h))}: {len(steps)} traced steps in {prep.elapsed_s:.1f} s")
    finally:
        renderer.release()
    return 0


def cmd_window(args) -> int:
    from viewer.gl.context import have_display

    if not have_display():
        raise ViewerError(f"no display found (DISPLAY is not set); {HEADLESS_HINT}")
    from viewer.app.main import run_app

    from viewer.app.state import DEFAULT_WINDOW

    size = None if args.width is None and args.height is None else (args.width or DEFAULT_WINDOW[0], args.height or DEFAULT_WINDOW[1])
    return run_app(args.scene, args.overrides, size=size, frames=args.frames,
                   screenshot=args.screenshot, compile_ahead=args.compile_ahead)


def _first_line(e: Exception) -> str:
    """The message's first line, at most 1,000 characters (the messages quote at most a short
    prefix of a value; this is the last guard against one that quotes a 100 KB value whole)."""
    from viewer.scene.validation import short

    text = str(e)
    return short(text.splitlines()[0] if text else type(e).__name__, 1000)


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        if argv and argv[0] in COMMANDS:
            cmd, rest = argv[0], argv[1:]
            from viewer.commands import check as check_cli
            from viewer.commands import measured as measured_cli
            parser = {"render": _parser_render, "reference": _parser_reference, "compare": _parser_compare,
                      "bake": _parser_bake, "plot": _parser_plot, "models": _parser_models,
                      "fit": measured_cli.parser, "check": check_cli.parser, "handout": _parser_handout}[cmd]()
            args = parser.parse_args(rest)
            _trust(args)
            return {"render": cmd_render, "reference": cmd_reference, "compare": cmd_compare,
                    "bake": cmd_bake, "plot": cmd_plot, "models": cmd_models, "fit": measured_cli.cmd_fit,
                    "check": check_cli.cmd_check, "handout": cmd_handout}[cmd](args)
        args = _parser_window().parse_args(argv)
        _trust(args)
        return cmd_window(args)
    except OutputError as e:   # a file that could not be written: exit 1
        print(f"brdf-viewer: error: {_first_line(e)}", file=sys.stderr)
        return 1
    except ViewerError as e:
        print(f"brdf-viewer: error: {_first_line(e)}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
