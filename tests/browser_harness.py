"""A headless Chromium for tests of the web handout, through Playwright's Python API.

The system's browser is used (``/usr/bin/chromium``, Debian's package, which ``.ci/run``
installs; never a browser download), with WebGL2 on SwiftShader (``--use-angle=swiftshader``:
no GPU needed). ``browser`` is a session fixture; a test module makes it available with
``from browser_harness import browser  # noqa: F401``. Without Chromium or Playwright the tests
that use it skip with one line naming what is missing.

``open_page(browser, url_or_html, viewport)`` returns (page, messages): every console message
and page error, so a test can assert that none is an error (``errors(messages)``)."""

from __future__ import annotations

import os
import shutil

import pytest

CHROMIUM = os.environ.get("BRDF_VIEWER_CHROMIUM", "/usr/bin/chromium")
#: WebGL2 on SwiftShader in a headless Chromium (the flags ANGLE needs for its software backend)
ARGS = ["--use-gl=angle", "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--ignore-gpu-blocklist",
        "--disable-gpu-driver-bug-workarounds"]


def chromium_path() -> str | None:
    """The Chromium executable, or None when there is none."""
    path = CHROMIUM if os.path.isfile(CHROMIUM) else shutil.which("chromium") or shutil.which("chromium-browser")
    return path if path and os.access(path, os.X_OK) else None


def missing() -> str | None:
    """Why the browser tests cannot run (one line), or None."""
    try:
        import playwright.sync_api  # noqa: F401
    except ImportError:
        return "playwright is not installed (pip install playwright; the [test] extra has it)"
    if chromium_path() is None:
        return f"no Chromium at {CHROMIUM} (apt-get install chromium)"
    return None


_STARTED: list = []  # [(playwright, browser)]: one Chromium per process, whichever module asks first


def _shared_browser():
    """The process's Chromium, started on first use and closed when the process exits: test
    modules that import ``browser`` get fixture instances of their own, and Playwright's sync
    API allows one instance per thread."""
    if _STARTED and _STARTED[0][1].is_connected():
        return _STARTED[0][1]
    import atexit

    from playwright.sync_api import sync_playwright

    if _STARTED:
        _close()
    pw = sync_playwright().start()
    try:
        b = pw.chromium.launch(executable_path=chromium_path(), args=ARGS, headless=True)
    except Exception as e:  # noqa: BLE001 - a browser that does not start: the tests cannot run
        pw.stop()
        pytest.skip(f"Chromium at {chromium_path()} does not start: {str(e).splitlines()[0]}")
    _STARTED.append((pw, b))
    atexit.register(_close)
    return b


def _close():
    while _STARTED:
        pw, b = _STARTED.pop()
        try:
            b.close()
        finally:
            pw.stop()


@pytest.fixture(scope="session")
def browser():
    """One headless Chromium with WebGL2 for the session (shared by every module that uses it)."""
    why = missing()
    if why:
        pytest.skip(why)
    yield _shared_browser()


def open_page(browser, url: str | None = None, html: str | None = None, viewport=(1280, 800)):
    """A new page (``url``, e.g. ``file:///...``, or ``html`` content) and the list its console
    messages and page errors are collected in: (type, text) pairs."""
    page = browser.new_page(viewport={"width": int(viewport[0]), "height": int(viewport[1])})
    messages: list[tuple[str, str]] = []
    page.on("console", lambda m: messages.append((m.type, m.text)))
    page.on("pageerror", lambda e: messages.append(("pageerror", str(e))))
    if url is not None:
        page.goto(url)
    elif html is not None:
        page.set_content(html)
    return page, messages


def errors(messages) -> list[str]:
    """The console errors and page errors among ``messages``."""
    return [f"{t}: {text}" for t, text in messages if t in ("error", "pageerror")]


def webgl2_available(page) -> bool:
    return bool(page.evaluate("() => !!document.createElement('canvas').getContext('webgl2')"))
