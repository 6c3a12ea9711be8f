"""The notebook widget's costs in JupyterLab (docs/notebook.md, "Front ends"):

    python benchmarks/notebook_lab.py [--size 480x270] [--workers N] [--repeat 10] [--nbclient]

A JupyterLab server on 127.0.0.1 and headless Chromium (tests/test_notebook_lab.py's
``LabSession``) on a copy of examples/explore.ipynb at ``--size`` (default the notebook's own,
480x270, its reference on every core): the server's start, the notebook's opening, *Run All
Cells*, the first widget's first frame once scrolled into view; then, timed in the page (the
moment a key goes down to the moment the new frame's <img> changes), a roughness slider step by
the keyboard; the frames and bytes per frame of a left drag (JPEG while interacting, PNG once
still); the reference's first image and its spp after 20 s. ``--nbclient`` also runs the same
notebook with nbclient in this process, as a peer for the *Run All* time."""

import argparse
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

# the page's clock when a key goes down on the slider (set by the listener below)
KEY_CLOCK = """() => { window.keyDownAt = null;
  document.addEventListener('keydown', () => { window.keyDownAt = performance.now(); }, true); }"""


def nbclient_time(size, workers):
    import nbclient
    import nbformat

    nb = nbformat.read(ROOT / "examples" / "explore.ipynb", as_version=4)
    cell = next(c for c in nb.cells if c.cell_type == "code" and "SIZE = " in c.source)
    cell.source = f"SIZE = {tuple(size)!r}\nWORKERS = {workers!r}\n"
    t = time.perf_counter()
    nbclient.NotebookClient(nb, timeout=1200, kernel_name="python3",
                            resources={"metadata": {"path": str(ROOT)}}).execute()
    return time.perf_counter() - t


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", default="480x270", help="the widget's CSS size, WxH")
    ap.add_argument("--workers", type=int, default=None, help="the reference's workers (default: every core)")
    ap.add_argument("--repeat", type=int, default=10, help="slider steps timed")
    ap.add_argument("--nbclient", action="store_true", help="also run the notebook with nbclient (a peer)")
    ap.add_argument("--shots", type=Path, default=None, help="save the page's screenshots in this folder")
    a = ap.parse_args(argv)
    import os
    import tempfile

    from test_notebook_lab import LabSession, missing, reference_numbers

    reason = missing()
    if reason:
        print(f"skipped: {reason}")
        return
    size = tuple(int(v) for v in a.size.lower().split("x"))
    # the kernel's reference cache and state file in a throwaway folder, never the user's
    scratch = tempfile.mkdtemp(prefix="brdf-viewer-bench-")
    os.environ["BRDF_VIEWER_CACHE"] = os.path.join(scratch, "cache")
    os.environ["BRDF_VIEWER_STATE"] = os.path.join(scratch, "state.toml")
    with open("/proc/loadavg") as f:
        print(f"load average at the start: {' '.join(f.read().split()[:3])}")
    with LabSession(size=size, workers=a.workers) as lab:
        page = lab.page
        errors = lab.run_all(timeout_s=1800)
        if errors:
            print("a cell failed:", errors[0][-600:])
            return
        panel, img = lab.widget(0)
        lab.watch(img)
        t = time.perf_counter()
        lab.show(img)
        first = time.perf_counter() - t
        for k, v in lab.times.items():
            print(f"{k}: {v:.1f} s")
        print(f"first widget's frame once scrolled into view (frames settled): {first:.1f} s")
        lab.toggle(panel, "raster")
        lab.settle(img)
        if a.shots:
            a.shots.mkdir(parents=True, exist_ok=True)
            panel.screenshot(path=str(a.shots / "raster.png"))

        # a slider step by the keyboard: keydown -> the new frame in the <img>
        handle = lab.slider(panel, "roughness r").locator(".noUi-handle")
        handle.scroll_into_view_if_needed()
        page.evaluate(KEY_CLOCK)
        lat, kinds = [], []
        for k in range(a.repeat):
            handle.focus()
            n = len(lab.frames())
            page.keyboard.press("ArrowRight" if k % 2 == 0 else "ArrowLeft")
            try:
                f = lab.wait_new_frame(n, timeout_s=60)
            except Exception:   # noqa: BLE001 - no frame: the step changed nothing visible
                print("slider step: no new frame within 60 s")
                break
            lat.append(f["t"] - page.evaluate("window.keyDownAt"))
            kinds.append(f)
            lab.settle(img, quiet_s=0.6)
        if lat:
            sizes = [f["size"] for f in kinds if f["size"] > 0]
            print(f"slider step -> frame in the page: median {statistics.median(lat):.0f} ms "
                  f"(min {min(lat):.0f}, max {max(lat):.0f}, {len(lat)} steps); first frame "
                  f"{kinds[0]['type']}, median {statistics.median(sizes) / 1024:.1f} KiB")

        # a left drag of 2 s: frames and bytes per frame
        n = len(lab.frames())
        t = time.perf_counter()
        # a turn about the vertical axis (a vertical drag soon looks from below the floor)
        lab.drag(img, 160, 0, steps=50, step_ms=40)
        dt = time.perf_counter() - t
        lab.settle(img)
        got = lab.frames()[n:]
        jpeg = [f["size"] for f in got if f["type"] == "image/jpeg" and f["size"] > 0]
        png = [f["size"] for f in got if f["type"] == "image/png" and f["size"] > 0]
        print(f"drag: {len(got)} frames in {dt:.1f} s of dragging and settling ({len(jpeg)} JPEG, "
              f"median {statistics.median(jpeg) / 1024 if jpeg else 0:.1f} KiB; {len(png)} PNG, "
              f"median {statistics.median(png) / 1024 if png else 0:.1f} KiB)")
        if a.shots:
            panel.screenshot(path=str(a.shots / "orbit.png"))

        # the reference: its first image and its spp after 20 s
        n = len(lab.frames())
        t = time.perf_counter()
        lab.toggle(panel, "reference")
        first_ref = None
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline:
            spp, rmse = reference_numbers(lab.status(panel))
            if first_ref is None and spp:
                first_ref = time.perf_counter() - t
            time.sleep(0.25)
        spp, rmse = reference_numbers(lab.status(panel))
        print(f"reference: first image after {first_ref if first_ref is not None else float('nan'):.1f} s, "
              f"{spp} spp after 20 s (rmse est. {rmse}), {len(lab.frames()) - n} frames sent")
        if a.shots:
            panel.screenshot(path=str(a.shots / "reference.png"))
        lab.toggle(panel, "raster")
    if a.nbclient:
        os.environ["PYTHONPATH"] = os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])
        print(f"the same notebook with nbclient: {nbclient_time(size, a.workers):.1f} s")
    with open("/proc/loadavg") as f:
        print(f"load average at the end: {' '.join(f.read().split()[:3])}")


if __name__ == "__main__":
    main()
