"""``brdf-viewer handout OUT``: a small handout (three lecture steps at 96 x 54, references of 4
spp from a cache of its own), built once per module by the command line, then read as files
(pages, titles, captions, the live view's canvas and sliders, no URL outside OUT, every named
file present) and opened from disk in headless Chromium (no console error, no horizontal
scrolling on a 390 x 844 phone, every image loaded). The 15-step build at the default size is
``benchmarks/handout.py``."""

from __future__ import annotations

import html
import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
from browser_harness import browser, errors  # noqa: F401  (browser: the session's headless Chromium)

from viewer.scene.lecture import TOUR, tour_scene

ROOT = Path(__file__).resolve().parents[1]
STEPS = (1, 6)   # 1-based: lit by a constant environment only (no map to prefilter, no traced chains), 3 materials
SIZE = (96, 54)

# a URL that leaves the folder: a scheme's (http:, https:, ftp:, ws:, wss:) anywhere in the text, or
# a network-path reference ("//host/...") where a file names another file: an HTML attribute, a CSS
# url() or @import, a JavaScript import / fetch of a string literal
OUTSIDE_URL = re.compile(
    r"""(?ix)\b(?:https?|ftp|wss?):
        | (?:src|href|action|poster|data|srcset)\s*=\s*["']?\s*//
        | url\(\s*["']?\s*//
        | @import\s+["']?\s*//
        | (?:import|from|fetch\(|import\()\s*["']\s*//""")
LOCAL_REF = re.compile(r"""(?i)(?:src|href)\s*=\s*["']([^"'#?]+)|url\(\s*["']?([^"')#?]+)""")


def outside_urls(text: str) -> list[str]:
    return [m.group(0) for m in OUTSIDE_URL.finditer(text)]


def local_references(text: str) -> list[str]:
    """The files an HTML or CSS text names by relative path (not data: URLs)."""
    refs = [a or b for a, b in LOCAL_REF.findall(text)]
    return [r.strip() for r in refs if r.strip() and not r.strip().lower().startswith("data:")]


@pytest.fixture(scope="module")
def handout(tmp_path_factory):
    out = tmp_path_factory.mktemp("handout") / "site"
    env = dict(os.environ, PYTHONPATH=str(ROOT), BRDF_VIEWER_CACHE=str(tmp_path_factory.mktemp("cache")))
    r = subprocess.run([sys.executable, "-m", "viewer", "handout", str(out), "--steps", ",".join(map(str, STEPS)),
                        "--width", str(SIZE[0]), "--height", str(SIZE[1]), "--spp", "4", "--engine", "cpu",
                        "--workers", "0"], capture_output=True, text=True, env=env, timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    return out, r.stdout


def _page(out: Path, n: int) -> str:
    return (out / f"step-{n:02d}.html").read_text(encoding="utf-8")


def test_the_command_says_what_it_wrote(handout):
    out, stdout = handout
    lines = stdout.strip().splitlines()
    assert len([ln for ln in lines if ln.startswith("step ")]) == len(STEPS)
    last = lines[-1]
    assert last.startswith(f"wrote {out}/: index.html and 2 step pages (step-01.html, step-06.html)")
    size = sum(f.stat().st_size for f in out.rglob("*") if f.is_file())
    assert f"{size / 1e6:.1f} MB" in last
    for n in STEPS:   # each step's reference: its samples and engine, as its page states them
        assert f"{n}: 4 spp cpu" in last
        data = json.loads((out / f"step-{n:02d}" / "step.json").read_text())
        assert data["spp"] == 4 and data["engine"] == "cpu" and data["width"] == SIZE[0]
        assert "4 samples per pixel, cpu engine" in _page(out, n)


def test_every_page_has_its_title_caption_and_navigation(handout):
    out, _ = handout
    index = (out / "index.html").read_text(encoding="utf-8")
    for k, n in enumerate(STEPS):
        step = TOUR[n - 1]
        page = _page(out, n)
        assert f"<h1>{n}. {html.escape(step.title)}</h1>" in page
        assert html.escape(step.caption) in page and html.escape(step.caption) in index
        assert f'href="step-{n:02d}.html"' in index and f'src="step-{n:02d}/thumbnail.png"' in index
        prev_link = re.search(r'href="([^"]+)" rel="prev"', page)
        next_link = re.search(r'href="([^"]+)" rel="next"', page)
        assert (prev_link and prev_link.group(1)) == (f"step-{STEPS[k - 1]:02d}.html" if k > 0 else None)
        assert (next_link and next_link.group(1)) == (f"step-{STEPS[k + 1]:02d}.html" if k + 1 < len(STEPS) else None)
        for name in ("raster.png", "reference.png", "difference.png"):
            assert f'src="step-{n:02d}/{name}"' in page


def test_each_step_has_its_plots_with_their_numbers(handout):
    from viewer import plots

    out, _ = handout
    for n in STEPS:
        step, scene = TOUR[n - 1], tour_scene(n - 1, load_meshes=False)
        subjects = [m for m, p in scene.materials.items() if m != "floor" and step.plot in plots.applicable_kinds(p)]
        assert subjects
        for m in subjects:
            data = json.loads((out / f"step-{n:02d}" / f"plot-{m}.json").read_text())
            assert data["kind"] == step.plot and (data["curves"] or data["info"].get("value"))
            assert f'src="step-{n:02d}/plot-{m}.png"' in _page(out, n)


def test_each_step_has_the_live_canvas_and_a_slider_per_parameter(handout):
    from viewer import brdf

    out, _ = handout
    for n in STEPS:
        page = _page(out, n)
        assert re.search(rf'<canvas[^>]*\bdata-step="{n:02d}"', page), n
        sliders = set(re.findall(r'<input[^>]*type="range"[^>]*data-param="([^"]+)"', page)
                      + re.findall(r'<input[^>]*data-param="([^"]+)"[^>]*type="range"', page))
        scene = tour_scene(n - 1, load_meshes=False)
        for name, p in scene.materials.items():
            for spec in brdf.get(p.model).spec.params:
                key = f"materials.{name}.{spec.name}"
                if spec.kind == "float":
                    assert key in sliders, (n, name, spec.name)
                elif spec.kind == "rgb":   # a colour picker or three range inputs
                    assert f'data-param="{key}"' in page, (n, name, spec.name)


def test_no_file_names_a_url_outside_the_folder(handout):
    out, _ = handout
    texts = [f for f in out.rglob("*") if f.is_file() and f.suffix.lower() in (".html", ".css", ".js", ".json",
                                                                                  ".glsl", ".txt", ".svg", ".mjs")]
    assert {f.suffix for f in texts} >= {".html", ".css", ".json"}
    for f in texts:
        assert outside_urls(f.read_text(encoding="utf-8")) == [], f


def test_the_url_check_can_fail():
    bad = ['<script src="https://cdn.example/x.js">', "<link href='//fonts.example/f.css'>",
           "@import url(//x/y.css);", 'fetch("//host/a")', "see http://example.org", "import m from '//x/m.js'"]
    assert all(outside_urls(t) for t in bad)
    fine = ['<img src="step-01/raster.png">', "// a comment in a script", "a = b // c", '<link href="data:,">']
    assert not any(outside_urls(t) for t in fine)


def test_every_named_file_is_inside_the_folder(handout):
    out, _ = handout
    for f in list(out.glob("*.html")) + list(out.rglob("*.css")):
        refs = local_references(f.read_text(encoding="utf-8"))
        assert refs or f.suffix == ".css", f
        for ref in refs:
            target = (f.parent / ref).resolve()
            assert target.is_file(), f"{f.name} names {ref}, which is missing"
            assert out.resolve() in target.parents, f"{f.name} names {ref}, outside the folder"


def test_a_file_or_an_unwritable_place_as_out_is_one_line(tmp_path, capsys):
    from viewer.commands.cli import main

    f = tmp_path / "a file"
    f.write_text("x")
    assert main(["handout", str(f), "--steps", "1"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "exists and is not a folder" in err and str(f) in err
    assert main(["handout", str(f / "sub"), "--steps", "1"]) == 1   # a folder that cannot be made
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "cannot be written" in err
    assert main(["handout", str(tmp_path / "x"), "--steps", "16"]) == 2
    assert "out of range" in capsys.readouterr().err and not (tmp_path / "x").exists()


def test_the_reference_is_bakes_cache_entry_used_or_refined(tmp_path, monkeypatch, capsys):
    """A reference bake stored is found at the same size (the same key); one with fewer samples
    than asked for is resumed to the count and stored; one with more is used as it is."""
    from viewer.commands.cli import main
    from viewer.handout.assets import ReferenceSettings, reference_image

    monkeypatch.setenv("BRDF_VIEWER_CACHE", str(tmp_path / "cache"))
    assert main(["bake", "lecture:1", "--spp", "2", "--width", "16", "--height", "9",
                 "--engine", "cpu", "--workers", "0"]) == 0
    capsys.readouterr()
    scene = tour_scene(0, overrides=["camera.width=16", "camera.height=9"])
    img, spp, engine, cached, _ = reference_image(scene, 16, 9, ReferenceSettings(1, "cpu", workers=0))
    assert (spp, engine, cached, img.shape) == (2, "cpu", True, (9, 16, 3))
    _, spp, _, cached, _ = reference_image(scene, 16, 9, ReferenceSettings(3, "cpu", workers=0))
    assert (spp, cached) == (3, False)
    again, spp, _, cached, _ = reference_image(scene, 16, 9, ReferenceSettings(3, "cpu", workers=0))
    assert (spp, cached) == (3, True) and float(again.mean()) > 0


# ----------------------------------------------------------------------------- in a browser

def test_pages_open_from_disk_without_errors_and_fit_a_phone(handout, browser):
    out, _ = handout
    page = browser.new_page(viewport={"width": 390, "height": 844}, device_scale_factor=1, is_mobile=True,
                            has_touch=True)
    messages, failed = [], []
    page.on("console", lambda m: messages.append((m.type, m.text)))
    page.on("pageerror", lambda e: messages.append(("pageerror", str(e))))
    page.on("requestfailed", lambda r: failed.append(r.url))
    try:
        for name in ["index.html"] + [f"step-{n:02d}.html" for n in STEPS]:
            page.goto((out / name).as_uri(), wait_until="load")
            page.wait_for_timeout(300)   # the live view's first frames
            widths = page.evaluate("[document.documentElement.scrollWidth, window.innerWidth]")
            assert widths[0] <= widths[1], (name, widths)
            broken = page.evaluate("[...document.images].filter(i => !(i.complete && i.naturalWidth > 0))"
                                   ".map(i => i.getAttribute('src'))")
            assert broken == [], (name, broken)
            assert page.evaluate("document.images.length") >= (len(STEPS) if name == "index.html" else 4)
            assert errors(messages) == [] and failed == [], (name, errors(messages), failed)
    finally:
        page.close()
