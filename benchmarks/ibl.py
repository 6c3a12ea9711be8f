"""IBL prefiltering figures: `python benchmarks/ibl.py [--map sky|studio] [--width 1024]`
(prints numbers, asserts nothing).

For a built-in map (1024 x 512 by default): ``IBL.set_environment`` cold (empty disk cache: mip
chain, GGX prefilter of every level, SH projection, DFG table) and cached (a new ``IBL`` in this
process, and a new process, both reading the disk cache), with the parts of each. The cache is a
temporary folder (``BRDF_VIEWER_CACHE``), removed at the end.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

_CHILD = r"""
import json, sys, time
t0 = time.perf_counter()
from viewer.environment import procedural
from viewer.gl.context import create_offscreen_context
from viewer.gl.ibl import IBL
img = procedural.generate(sys.argv[1], int(sys.argv[2]), int(sys.argv[2]) // 2)
ctx = create_offscreen_context()
ibl = IBL(ctx)
t = time.perf_counter()
ibl.set_environment(img)
s = dict(ibl.stats, wall_s=time.perf_counter() - t)
print(json.dumps({k: v for k, v in s.items() if isinstance(v, (int, float, bool))}))
"""


def _fmt(stats: dict) -> str:
    keys = ("total_s", "prefilter_s", "map_s", "sh_s", "hash_s", "upload_s", "dfg_s", "compile_s")
    return "  ".join(f"{k[:-2]} {stats[k] * 1000:.0f} ms" for k in keys if k in stats)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--map", default="sky", choices=("sky", "studio"))
    ap.add_argument("--width", type=int, default=1024)
    ap.add_argument("--repeat", type=int, default=3, help="cold runs (best and median reported)")
    args = ap.parse_args(argv)

    with tempfile.TemporaryDirectory(prefix="brdf-viewer-ibl-bench-") as tmp:
        os.environ["BRDF_VIEWER_CACHE"] = tmp
        from viewer.environment import procedural
        from viewer.gl.context import create_offscreen_context
        from viewer.gl.ibl import IBL

        ctx = create_offscreen_context()
        print(f"renderer: {ctx.info['GL_RENDERER']}, CPUs: {os.cpu_count()}")
        img = procedural.generate(args.map, args.width, args.width // 2)
        print(f"map: {args.map} {args.width}x{args.width // 2}")

        colds = []
        for i in range(args.repeat):
            ibl = IBL(ctx, use_cache=False)
            ibl.set_environment(img)
            colds.append(ibl.stats["total_s"])
            if i == 0:
                s = ibl.stats
                print(f"levels {s['levels']}: alphas {s['alphas']}, samples/texel {s['samples']}, "
                      f"layers {s['layer_size'][0]}x{s['layer_size'][1]}")
            print(f"cold #{i + 1}:      {_fmt(ibl.stats)}")
            ibl.release()
        colds.sort()
        print(f"cold: best {colds[0]:.2f} s, median {colds[len(colds) // 2]:.2f} s")

        ibl = IBL(ctx)  # fills the disk cache
        ibl.set_environment(img)
        ibl.release()
        ibl = IBL(ctx)
        t = time.perf_counter()
        ibl.set_environment(img)
        print(f"cached (same process, new IBL): {_fmt(ibl.stats)}  cached={ibl.stats['cached']}")
        t = time.perf_counter()
        ibl.set_environment(img)
        print(f"unchanged (same IBL, same map): {(time.perf_counter() - t) * 1000:.1f} ms (content hash only)")
        ibl.release()

        out = subprocess.run([sys.executable, "-c", _CHILD, args.map, str(args.width)],
                             env=dict(os.environ), capture_output=True, text=True)
        if out.returncode == 0:
            s = json.loads(out.stdout.strip().splitlines()[-1])
            print(f"cached (new process):           {_fmt(s)}  cached={s['cached']} "
                  f"prefilter passes={s['prefilter_passes']}")
        else:
            print("cached (new process): failed\n" + out.stderr)
        ctx.release()


if __name__ == "__main__":
    main()
