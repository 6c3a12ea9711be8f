"""Memory taken again and again (the CPU reference's chunks, the window's readbacks), kept instead of
faulted in anew.

A chunk allocates and frees the same few dozen arrays of 0.1-10 MB per bounce (numpy
temporaries of 32,768 paths). Two defaults make each of those allocations cost kernel time:

- glibc serves blocks above its mmap threshold (128 KB at first, raised only by frees of such
  blocks) with fresh ``mmap`` pages and gives free heap tops back (``trim``), so the next chunk
  takes the same memory again as page faults;
- numpy advises the kernel to back arrays of 4 MB and more with huge pages (``madvise``); where
  the kernel's huge-page ``defrag`` setting is ``madvise`` (Debian's default), such a fault may
  compact memory on the spot.

A 1280x720, 4-spp render of ``benchmarks/scenes/bench.toml`` (two threads, load 5-9) spent
1.0-1.6 s of system time of its 5 CPU s; without the huge-page advice 0.5 s (213,000 page
faults), and with the heap thresholds below as well 0.2 s (82,000). ``keep_freed_memory`` sets
both for the process, once: blocks up to 64 MB come from the heap, up to 256 MB of free heap is
kept, and numpy's huge-page advice is off (numpy reads ``NUMPY_MADVISE_HUGEPAGE`` only when it is
imported; afterwards its own setter, the one its import calls, is the way). Only where the C
library is glibc (``mallopt``) and numpy has that setter; elsewhere nothing changes.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import threading

M_TRIM_THRESHOLD, M_TOP_PAD, M_MMAP_THRESHOLD = -1, -2, -3   # glibc's <malloc.h> parameter numbers
MMAP_THRESHOLD = 64 << 20   # bytes: a block below this comes from the heap (glibc's ceiling is 32 MB by default)
TRIM_THRESHOLD = 256 << 20  # bytes of free heap top kept before any is returned
TOP_PAD = 16 << 20          # bytes asked for beyond each request when the heap grows

_lock = threading.Lock()
_done: dict | None = None


def _set_heap_thresholds() -> bool:
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        mallopt = libc.mallopt
    except (OSError, AttributeError):   # not glibc: its own allocator's defaults stay
        return False
    mallopt.argtypes, mallopt.restype = [ctypes.c_int, ctypes.c_int], ctypes.c_int
    return all(mallopt(k, v) == 1 for k, v in ((M_MMAP_THRESHOLD, MMAP_THRESHOLD),
                                                (M_TRIM_THRESHOLD, TRIM_THRESHOLD), (M_TOP_PAD, TOP_PAD)))


def _no_huge_page_advice() -> bool:
    import numpy as np

    setter = getattr(getattr(getattr(np, "_core", None), "multiarray", None), "_set_madvise_hugepage", None)
    if setter is None:
        return False
    setter(False)
    return True


def keep_freed_memory() -> dict:
    """Set both for this process (once). Returns which took: {"heap": bool, "numpy": bool}."""
    global _done
    with _lock:
        if _done is None:
            _done = {"heap": _set_heap_thresholds(), "numpy": _no_huge_page_advice()}
        return dict(_done)
