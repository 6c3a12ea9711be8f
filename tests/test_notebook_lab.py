"""The notebook widget in JupyterLab (docs/notebook.md, "Front ends"): a JupyterLab server on
127.0.0.1 with a copy of ``examples/explore.ipynb``, headless Chromium (Playwright, Debian's
``/usr/bin/chromium``) running all of its cells from the *Run* menu, then the first widget used
as a person would: its frame shown is the renderer's image, a drag orbits and a double click
returns to the start view, the roughness slider changes the frame, and the *reference* toggle
shows a progressive image whose samples grow and whose estimated error falls.

``LabSession`` drives it; ``benchmarks/notebook_lab.py`` uses it for the timings."""

from __future__ import annotations

import json
import os
import re
import secrets
import shutil
import socket
import subprocess
import sys
import tempfile
import time
import urllib.request
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent
CHROMIUM = "/usr/bin/chromium"
SIZE = (240, 135)   # the test's widget size in CSS pixels (the notebook's settings cell is rewritten)

# What the page records of the first widget's <img>: each new frame's arrival time (ms, the page's
# clock), its size in bytes and its type (image/jpeg while interacting, image/png once still).
WATCH_FRAMES = """(img) => {
  window.rfbFrames = [];
  new MutationObserver(async () => {
    const entry = {t: performance.now(), size: -1, type: ''};
    window.rfbFrames.push(entry);
    try { const b = await (await fetch(img.src)).blob(); entry.size = b.size; entry.type = b.type; }
    catch (e) { }   // the next frame came first and revoked this one's URL
  }).observe(img, {attributes: true, attributeFilter: ['src']});
}"""


def missing() -> str | None:
    """Why the JupyterLab run cannot happen here (one line), or None."""
    import importlib.util

    for module, why in (("jupyterlab", "pip install jupyterlab"), ("playwright", "pip install playwright"),
                        ("jupyter_rfb", "pip install -e '.[notebook]'"), ("ipykernel", "pip install -e '.[test]'")):
        if importlib.util.find_spec(module) is None:
            return f"the JupyterLab check needs {module}: {why}"
    if not os.access(CHROMIUM, os.X_OK):
        return f"the JupyterLab check drives Chromium at {CHROMIUM} (Debian: apt install chromium)"
    return None


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def image_of(png: bytes) -> np.ndarray:
    import io

    from PIL import Image

    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB"))


def mean_diff(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.abs(a.astype(float) - b.astype(float)).mean())


class LabSession:
    """A JupyterLab server and a headless Chromium page on a copy of ``examples/explore.ipynb``
    with its settings cell set to ``size`` and ``workers``. Everything it writes (the notebook
    copy, Jupyter's config, runtime and data folders, the server log) is under one temporary
    folder; the kernel imports this checkout (``PYTHONPATH``)."""

    def __init__(self, size=SIZE, workers=0, viewport=(1400, 1100)):
        self.size, self.workers, self.viewport = size, workers, viewport
        self.folder = Path(tempfile.mkdtemp(prefix="brdf-viewer-lab-"))
        self.server = self.browser = self.playwright = self.page = None
        self.times: dict[str, float] = {}

    # ------------------------------------------------------------------ start and stop
    def __enter__(self):
        try:
            self.start()
        except BaseException:
            self.close()
            raise
        return self

    def __exit__(self, *exc):
        self.close()

    def start(self):
        nbdir = self.folder / "notebooks"
        nbdir.mkdir()
        nb = json.loads((ROOT / "examples" / "explore.ipynb").read_text(encoding="utf-8"))
        settings = [c for c in nb["cells"] if c["cell_type"] == "code" and "SIZE = " in "".join(c["source"])]
        assert len(settings) == 1
        settings[0]["source"] = [f"SIZE = {tuple(self.size)!r}\n", f"WORKERS = {self.workers!r}\n"]
        (nbdir / "explore.ipynb").write_text(json.dumps(nb), encoding="utf-8")
        config = self.folder / "config"
        (config / "labconfig").mkdir(parents=True)
        # no "get Jupyter news?" question over the page
        (config / "labconfig" / "page_config.json").write_text(json.dumps(
            {"disabledExtensions": {"@jupyterlab/apputils-extension:announcements": True}}))
        self.port, self.token = free_port(), secrets.token_hex(16)
        pythonpath = os.pathsep.join([str(ROOT)] + [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p])
        env = dict(os.environ, PYTHONPATH=pythonpath, JUPYTER_CONFIG_DIR=str(config),
                   JUPYTER_RUNTIME_DIR=str(self.folder / "runtime"), JUPYTER_DATA_DIR=str(self.folder / "data"),
                   IPYTHONDIR=str(self.folder / "ipython"))
        self.log = open(self.folder / "server.log", "w")
        t = time.perf_counter()
        self.server = subprocess.Popen(
            [sys.executable, "-m", "jupyterlab", "--no-browser", "--ip=127.0.0.1", f"--port={self.port}",
             f"--IdentityProvider.token={self.token}", f"--ServerApp.root_dir={nbdir}", "--allow-root"],
            stdout=self.log, stderr=subprocess.STDOUT, env=env)
        deadline = time.monotonic() + 120
        while True:
            try:
                urllib.request.urlopen(f"http://127.0.0.1:{self.port}/api/status?token={self.token}", timeout=2)
                break
            except OSError:
                if self.server.poll() is not None or time.monotonic() > deadline:
                    raise RuntimeError("the JupyterLab server did not start: " + self.server_log()[-2000:])
                time.sleep(0.3)
        self.times["server start"] = time.perf_counter() - t
        from playwright.sync_api import sync_playwright

        self.playwright = sync_playwright().start()
        self.browser = self.playwright.chromium.launch(executable_path=CHROMIUM, headless=True)
        self.page = self.browser.new_page(viewport={"width": self.viewport[0], "height": self.viewport[1]},
                                          device_scale_factor=1)
        self.console_errors = []
        self.page.on("console", lambda m: self.console_errors.append(m.text) if m.type == "error" else None)
        t = time.perf_counter()
        self.page.goto(f"http://127.0.0.1:{self.port}/lab/tree/explore.ipynb?token={self.token}")
        self.page.get_by_text("Python 3 (ipykernel) | Idle").wait_for(timeout=120_000)
        self.times["open notebook"] = time.perf_counter() - t

    def close(self):
        for step in (lambda: self.browser.close(), lambda: self.playwright.stop()):
            try:
                step()
            except Exception:   # noqa: BLE001 - closing what may be half started
                pass
        if self.server is not None and self.server.poll() is None:
            self.server.terminate()   # the server shuts its kernels down on SIGTERM
            try:
                self.server.wait(30)
            except subprocess.TimeoutExpired:
                self.server.kill()
                self.server.wait()
        if getattr(self, "log", None) is not None:
            self.log.close()
        shutil.rmtree(self.folder, ignore_errors=True)

    def server_log(self) -> str:
        try:
            return (self.folder / "server.log").read_text(errors="replace")
        except OSError:
            return ""

    # ------------------------------------------------------------------ the notebook
    def run_all(self, timeout_s=600):
        """Run > Run All Cells, and wait until no cell is queued or running and the kernel is idle.
        Returns the text of the error outputs (tracebacks), empty when every cell ran."""
        page = self.page
        t = time.perf_counter()
        page.click("div.lm-MenuBar-itemLabel:text-is('Run')")
        page.click("li.lm-Menu-item:has-text('Run All Cells')")
        page.wait_for_selector(".jp-InputPrompt:has-text('[*]')", timeout=30_000)
        page.wait_for_function(
            """() => ![...document.querySelectorAll('.jp-InputPrompt')].some(p => p.textContent.includes('*'))""",
            timeout=timeout_s * 1000, polling=500)
        page.get_by_text("Python 3 (ipykernel) | Idle").wait_for(timeout=60_000)
        self.times["run all cells"] = time.perf_counter() - t
        return [e.inner_text() for e in page.query_selector_all(".jp-OutputArea-output[data-mime-type="
                                                                  "'application/vnd.jupyter.stderr']")
                if "Error" in e.inner_text() or "Traceback" in e.inner_text()]

    # ------------------------------------------------------------------ the first widget
    def widget(self, index=0):
        """(the index-th widget's panel element, its frame <img>)."""
        img = self.page.locator(".renderview-wrapper img").nth(index)
        panel = img.locator("xpath=ancestor::div[contains(concat(' ', @class, ' '), ' widget-vbox ')][1]")
        return panel, img

    def watch(self, img):
        img.evaluate(WATCH_FRAMES)

    def frames(self) -> list[dict]:
        return self.page.evaluate("window.rfbFrames || []")

    def shot(self, img) -> np.ndarray:
        """What the <img> shows now, at its own pixel size (decoded by the browser, read back
        through a canvas: the frame as sent, without the page around it)."""
        img.scroll_into_view_if_needed()
        data = img.evaluate("""(img) => {
            const c = document.createElement('canvas');
            c.width = img.naturalWidth; c.height = img.naturalHeight;
            const g = c.getContext('2d');
            g.drawImage(img, 0, 0);
            return [c.width, c.height, Array.from(g.getImageData(0, 0, c.width, c.height).data)];
        }""")
        w, h, rgba = data
        return np.asarray(rgba, np.uint8).reshape(h, w, 4)[..., :3]

    def show(self, img, timeout_s=600.0) -> np.ndarray:
        """Scroll the widget into view (jupyter_rfb draws only a visible widget), wait for its
        first frame and for the frames to settle; the frame shown then."""
        img.scroll_into_view_if_needed()
        self.page.wait_for_function("(img) => img.naturalWidth > 1", arg=img.element_handle(),
                                    timeout=timeout_s * 1000, polling=100)
        return self.settle(img)

    def settle(self, img, quiet_s=1.2, timeout_s=60.0) -> np.ndarray:
        """The frame shown once no new frame has come for ``quiet_s`` (the still PNG has arrived)."""
        deadline = time.monotonic() + timeout_s
        n, since = len(self.frames()), time.monotonic()
        while time.monotonic() < deadline:
            time.sleep(0.2)
            m = len(self.frames())
            if m != n:
                n, since = m, time.monotonic()
            elif time.monotonic() - since >= quiet_s:
                break
        return self.shot(img)

    def wait_new_frame(self, count_before, timeout_s=30.0) -> dict:
        self.page.wait_for_function(f"(window.rfbFrames || []).length > {count_before}", timeout=timeout_s * 1000,
                                    polling=20)
        return self.frames()[count_before]

    def drag(self, img, dx, dy, steps=20, step_ms=30):
        box = img.bounding_box()
        x, y = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
        m = self.page.mouse
        m.move(x, y)
        m.down()
        for k in range(1, steps + 1):
            m.move(x + dx * k / steps, y + dy * k / steps)
            time.sleep(step_ms / 1000)
        m.up()

    def toggle(self, panel, name):
        panel.locator(".widget-toggle-buttons button", has_text=re.compile(rf"^\s*{name}\s*$")).first.click()

    def status(self, panel) -> str:
        return panel.locator(".widget-html-content", has_text="raster").first.inner_text()

    def slider(self, panel, label):
        return panel.locator(".widget-slider", has=self.page.locator(f"label:text-is('{label}')")).first


def reference_numbers(status: str):
    """(spp, rmse estimate or None) from the status line."""
    m = re.search(r"(\d+) spp(?:, rmse est\. ([0-9.eE+-]+))?", status)
    return (None, None) if m is None else (int(m.group(1)), None if m.group(2) is None else float(m.group(2)))


@pytest.fixture(scope="module")
def lab():
    reason = missing()
    if reason:
        pytest.skip(reason)
    with LabSession() as session:
        yield session


# slow: a JupyterLab server, Chromium and the whole notebook on a kernel (about 2-3 min on two loaded
# cores); the widget's rules themselves are checked without a browser in tests/test_notebook.py
@pytest.mark.slow
def test_explore_in_jupyterlab(lab, tmp_path):
    """All of explore.ipynb runs in JupyterLab; its first widget shows the renderer's image, orbits
    under a drag, returns to the start view on a double click, redraws for the roughness slider
    and shows a converging reference."""
    import viewer
    from viewer.image.colour import to_srgb8
    from viewer.scene import load_scene

    # a time limit against a hang, not a speed check: Run All took 250-350 s at load average 16-25
    errors = lab.run_all(timeout_s=1500)
    assert errors == [], errors[0][-2000:]
    panel, img = lab.widget(0)
    lab.watch(img)
    split = lab.show(img)
    (tmp_path / "lab-split.png").write_bytes(panel.screenshot())
    lab.toggle(panel, "raster")   # the notebook's last cell left the split view
    still = lab.settle(img)
    (tmp_path / "lab-raster.png").write_bytes(panel.screenshot())
    h, w = still.shape[:2]   # the <img>'s content box (the widget's CSS size less its border), ratio 1
    assert abs(w - lab.size[0]) <= 4 and abs(h - lab.size[1]) <= 4, still.shape
    assert still.std() > 10   # not blank: a lit ball on a floor
    assert mean_diff(split, still) > 1   # the split view's right half was the reference
    # the notebook set alpha 0.3 on the ball; the still frame is a PNG: the renderer's image exactly,
    # but the browser may convert colours on the way to the screenshot, so a step or two is allowed
    scene = load_scene("default")
    want = to_srgb8(viewer.render("default", w, h, overrides=["materials.ball.alpha=0.3"]), scene.render.exposure,
                    scene.render.tonemap)
    assert np.abs(still.astype(int) - want).max() <= 2, np.abs(still.astype(int) - want).max()

    # a drag orbits: the frame changes, several frames arrive during it (JPEG while interacting)
    n = len(lab.frames())
    lab.drag(img, 60, 0)   # a turn about the vertical axis
    orbited = lab.settle(img)
    during = lab.frames()[n:]
    (tmp_path / "lab-orbit.png").write_bytes(panel.screenshot())
    assert mean_diff(orbited, still) > 3, mean_diff(orbited, still)
    assert len(during) >= 2 and during[-1]["type"] == "image/png", during
    assert any(f["type"] == "image/jpeg" for f in during), during
    # a double click returns to the start view: the frame before the drag again
    box = img.bounding_box()
    lab.page.mouse.dblclick(box["x"] + 20, box["y"] + 20)
    back = lab.settle(img)
    assert np.abs(back.astype(int) - still).max() <= 2

    # the roughness slider (perceptual r = sqrt(alpha)) dragged to the right: a rougher ball
    slider = lab.slider(panel, "roughness r")
    handle = slider.locator(".noUi-handle")
    handle.scroll_into_view_if_needed()
    hb = handle.bounding_box()
    n = len(lab.frames())
    lab.page.mouse.move(hb["x"] + hb["width"] / 2, hb["y"] + hb["height"] / 2)
    lab.page.mouse.down()
    lab.page.mouse.move(hb["x"] + hb["width"] / 2 + 60, hb["y"] + hb["height"] / 2, steps=6)
    lab.page.mouse.up()
    r = float(slider.locator(".widget-readout").inner_text())
    rough = lab.settle(img)
    (tmp_path / "lab-slider.png").write_bytes(panel.screenshot())
    assert len(lab.frames()) > n
    assert r ** 2 > 0.3 + 0.02, r   # moved right of alpha 0.3
    # the frame is the render at the slider's value: much nearer to it than to the frame before
    # (the readout shows r to 3 decimals, so the alpha rendered here differs a little)
    at_r = to_srgb8(viewer.render("default", w, h, overrides=[f"materials.ball.alpha={r * r!r}"]),
                    scene.render.exposure, scene.render.tonemap)
    changed = np.abs(at_r.astype(int) - want).max(axis=2) > 6   # the pixels the new roughness changes
    assert changed.sum() > 50, changed.sum()
    near, far = (float(np.abs(rough[changed].astype(int) - x[changed]).mean()) for x in (at_r, want))
    assert near < 0.25 * far, (near, far)

    # the reference: its spp grows, its error estimate falls and the image settles
    lab.toggle(panel, "reference")
    seen, shots = [], []
    deadline = time.monotonic() + 90
    while time.monotonic() < deadline:
        spp, rmse = reference_numbers(lab.status(panel))
        if rmse is not None and (not seen or spp > seen[-1][0]):
            seen.append((spp, rmse))
            shots.append(lab.shot(img))
        if len(seen) >= 4 and seen[-1][0] >= 4 * seen[0][0]:
            break
        time.sleep(0.5)
    (tmp_path / "lab-reference.png").write_bytes(panel.screenshot())
    assert len(seen) >= 3, seen
    assert seen[-1][0] > seen[0][0] and seen[-1][1] < seen[0][1], seen
    assert all(s.std() > 10 for s in shots)
    # the reference is another image than the raster view (shadows, indirect light, noise)
    assert mean_diff(shots[-1], rough) > 1.0
    # converging: the change between the first two shown images is larger than between the last two
    assert mean_diff(shots[1], shots[0]) > mean_diff(shots[-1], shots[-2]), seen
    lab.toggle(panel, "raster")
    assert not [e for e in lab.console_errors if "renderview" in e or "jupyter_rfb" in e], lab.console_errors
