"""Shader hot reload: notice edited files under the shader folder by polling their stat
signatures (no file-system notification library: a scan of ~35 files costs well under a
millisecond), so the app can rebuild its programs with ``Renderer.reload_shaders``.

The app calls ``ShaderWatcher.poll()`` once per frame; the scan itself runs at most every
``interval`` seconds. A file counts as changed when its modification time (ns), size or inode
differ from the last scan (size and inode catch edits inside a coarse mtime tick and editors
that save by renaming a new file over the old one), or when it appears or disappears."""

from __future__ import annotations

import os
import time
from pathlib import Path

#: file name endings taken as shader sources (editor swap and backup files are not)
SHADER_SUFFIXES = (".glsl", ".vert", ".frag", ".geom", ".comp", ".tesc", ".tese", ".inc")


def scan(root: str | os.PathLike) -> dict[str, tuple[int, int, int]]:
    """{path relative to root with '/' separators: (mtime_ns, size, inode)} of every shader
    file below ``root`` (hidden files and folders skipped). A missing root scans as empty."""
    root = os.fspath(root)
    out: dict[str, tuple[int, int, int]] = {}
    stack = [("", root)]
    while stack:
        prefix, folder = stack.pop()
        try:
            entries = list(os.scandir(folder))
        except OSError:
            continue
        for e in entries:
            if e.name.startswith("."):
                continue
            rel = prefix + e.name
            try:
                if e.is_dir():
                    stack.append((rel + "/", e.path))
                elif e.name.endswith(SHADER_SUFFIXES) and e.is_file():
                    st = e.stat()
                    out[rel] = (st.st_mtime_ns, st.st_size, st.st_ino)
            except OSError:  # removed between listing and stat: the next scan sees it gone
                continue
    return out


class ShaderWatcher:
    """Reports shader files that changed since the previous scan."""

    def __init__(self, root: str | os.PathLike | None = None, interval: float = 0.25):
        if root is None:
            from viewer.gl.shaders import shader_root

            root = shader_root()
        self.root = Path(root)
        self.interval = float(interval)
        self.last_scan_ms = 0.0
        self._stats = scan(self.root)
        self._last = time.monotonic()

    def poll(self, force: bool = False) -> list[str]:
        """Sorted relative paths of files modified, added or removed since the last scan; [] if
        none, or if less than ``interval`` seconds passed since the last scan (unless ``force``)."""
        now = time.monotonic()
        if not force and now - self._last < self.interval:
            return []
        self._last = now
        t0 = time.perf_counter()
        stats = scan(self.root)
        self.last_scan_ms = 1000 * (time.perf_counter() - t0)
        old, self._stats = self._stats, stats
        if stats == old:
            return []
        return sorted(k for k in old.keys() | stats.keys() if old.get(k) != stats.get(k))
