"""The web handout's cost: build the lecture's handout and open it in headless Chromium from disk.

    python benchmarks/handout.py [--out DIR] [--steps 1-15] [--spp 64] [--engine auto]
                                 [--cache DIR] [--screenshots DIR] [--page 3 --page 11]

Builds ``brdf-viewer handout`` at the default size (480 x 270) into ``--out`` (default: a fresh
temporary folder) and prints the build time, how many references were rendered or found in the
reference cache (``--cache``: the cache folder to use, e.g. an empty one for a cold build;
default the user's), the folder's size in MB against the 25 MB a course site should not
exceed, and the first contentful paint (the browser's ``first-contentful-paint`` entry,
``performance`` paint timing) of ``index.html`` and of the ``--page`` steps, opened from file://
in headless Chromium (/usr/bin/chromium) at 1280 x 800, each in a fresh browser context, the
median of 5 loads. ``--screenshots DIR`` also saves full-page screenshots of the index and those
steps at 1280 x 800 and on a 390 x 844 phone."""

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

FCP_JS = """() => new Promise(done => {
  const seen = performance.getEntriesByName('first-contentful-paint');
  if (seen.length) return done(seen[0].startTime);
  new PerformanceObserver(list => {
    const e = list.getEntriesByName('first-contentful-paint');
    if (e.length) done(e[0].startTime);
  }).observe({type: 'paint', buffered: true});
})"""
LAUNCH_ARGS = ["--enable-unsafe-swiftshader", "--use-angle=swiftshader"]


def build(args) -> tuple[float, str]:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    if args.cache:
        env["BRDF_VIEWER_CACHE"] = str(Path(args.cache).resolve())
    cmd = [sys.executable, "-m", "viewer", "handout", str(args.out), "--steps", args.steps, "--spp", str(args.spp),
           "--engine", args.engine]
    t0 = time.perf_counter()
    r = subprocess.run(cmd, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if r.returncode != 0:
        sys.exit(f"handout failed ({r.returncode}): {r.stderr.strip()[-2000:]}")
    return wall, r.stdout


def first_paints(out: Path, pages: list[str], repeat: int = 5) -> dict[str, list[float]]:
    from playwright.sync_api import sync_playwright

    times = {p: [] for p in pages}
    with sync_playwright() as pw:
        b = pw.chromium.launch(executable_path="/usr/bin/chromium", args=LAUNCH_ARGS)
        for _ in range(repeat):
            for name in pages:
                ctx = b.new_context(viewport={"width": 1280, "height": 800})
                page = ctx.new_page()
                page.goto((out / name).as_uri(), wait_until="load")
                times[name].append(float(page.evaluate(FCP_JS)))
                ctx.close()
        b.close()
    return times


def screenshots(out: Path, pages: list[str], folder: Path) -> list[Path]:
    from playwright.sync_api import sync_playwright

    folder.mkdir(parents=True, exist_ok=True)
    saved = []
    with sync_playwright() as pw:
        b = pw.chromium.launch(executable_path="/usr/bin/chromium", args=LAUNCH_ARGS)
        for (w, h, tag, mobile) in ((1280, 800, "desktop", False), (390, 844, "phone", True)):
            ctx = b.new_context(viewport={"width": w, "height": h}, is_mobile=mobile, has_touch=mobile)
            page = ctx.new_page()
            for name in pages:
                page.goto((out / name).as_uri(), wait_until="load")
                page.wait_for_timeout(2000)   # the live view's first frames
                scroll = page.evaluate("[document.documentElement.scrollWidth, window.innerWidth]")
                path = folder / f"{tag}-{Path(name).stem}.png"
                page.screenshot(path=str(path), full_page=True)
                saved.append(path)
                print(f"screenshot {path} (page {scroll[0]} px wide in a {scroll[1]} px viewport)")
            ctx.close()
        b.close()
    return saved


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=None, help="the handout folder (default: a new temporary one)")
    ap.add_argument("--steps", default="1-15")
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--engine", default="auto")
    ap.add_argument("--cache", default=None, help="reference cache folder (default: the user's)")
    ap.add_argument("--page", type=int, action="append", default=None,
                    help="a step whose page is timed and shot (repeatable; default 3 and 11)")
    ap.add_argument("--screenshots", type=Path, default=None, help="save screenshots here")
    args = ap.parse_args()
    args.out = args.out or Path(tempfile.mkdtemp(prefix="handout-")) / "site"
    steps = args.page or [3, 11]
    print(f"load: {os.getloadavg()[0]:.1f} {os.getloadavg()[1]:.1f} {os.getloadavg()[2]:.1f} on {os.cpu_count()} cores")
    wall, stdout = build(args)
    lines = stdout.strip().splitlines()
    rendered = sum(1 for ln in lines if ln.startswith("step ") and "rendered in" in ln)
    cached = sum(1 for ln in lines if ln.startswith("step ") and "(cached)" in ln)
    size = sum(f.stat().st_size for f in args.out.rglob("*") if f.is_file())
    files = sum(1 for f in args.out.rglob("*") if f.is_file())
    print(lines[-1])
    print(f"build: {wall:.1f} s for {rendered + cached} steps ({rendered} references rendered, {cached} from the cache)")
    print(f"size: {size / 1e6:.2f} MB in {files} files (limit 25 MB: {'within' if size <= 25e6 else 'OVER'})")
    pages = ["index.html"] + [f"step-{n:02d}.html" for n in steps]
    for name, ts in first_paints(args.out, pages).items():
        print(f"first contentful paint {name}: median {statistics.median(ts):.0f} ms "
              f"(min {min(ts):.0f}, max {max(ts):.0f}, {len(ts)} loads, file://, 1280x800)")
    if args.screenshots:
        screenshots(args.out, pages, args.screenshots)
    print(f"handout: {args.out}")


if __name__ == "__main__":
    main()
