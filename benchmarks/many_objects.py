"""Scenes of many objects: `python benchmarks/many_objects.py [--sizes 1000,10000] [--width W]`
(prints numbers, asserts nothing).

For each count N (default 1,000 and 10,000) a grid of N small objects (built-in cubes by
default, ``--mesh sphere`` for spheres; two materials, a directional light with shadows) is
written as a scene file and, in the same run, timed as whole processes:

- ``brdf-viewer render`` (the rasterizer: load, one instanced draw per mesh and material, the
  PNG with its embedded scene);
- ``brdf-viewer reference --spp 1 --engine cpu`` (the CPU reference: load, triangles and BVH,
  one sample per pixel).

Each line gives the seconds and the ratio render / reference. The rasterizer used to draw each
object on its own (28 s for 10,000 cubes against 3.3 s for the reference); the counts and
triangles a scene may hold are in docs/scene-format.md (``[[objects]]``).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def grid_scene(n: int, mesh: str, width: int, height: int) -> str:
    k = max(1, round(n ** 0.5))
    lines = ["version = 1", "[camera]", "position = [0, 30, 60]", "target = [0, 0, 0]", f"width = {width}",
             f"height = {height}", "[[lights]]", 'type = "directional"', "direction = [-0.3, -1, -0.2]",
             "irradiance = [3, 3, 3]", "[materials.a]", 'model = "lambert"', "albedo = [0.7, 0.3, 0.2]",
             "[materials.b]", 'model = "microfacet"', "alpha = 0.3"]
    for i in range(n):
        x, z = (i % k - k / 2) * 0.6, (i // k - k / 2) * 0.6
        lines += ["[[objects]]", f'mesh = "{mesh}"', f'material = "{"ab"[i % 2]}"',
                  f"translate = [{x:.3f}, 0, {z:.3f}]", "scale = 0.25"]
    return "\n".join(lines) + "\n"


def timed(args: list[str]) -> tuple[float, str]:
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    t0 = time.perf_counter()
    # cwd: not a checkout (``-m`` puts the working folder first on the path, before PYTHONPATH)
    r = subprocess.run([sys.executable, "-m", "viewer", *args], capture_output=True, text=True, env=env,
                       cwd=tempfile.gettempdir())
    wall = time.perf_counter() - t0
    return wall, ("" if r.returncode == 0 else f" (exit {r.returncode}: {r.stderr.strip().splitlines()[-1]})")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="1000,10000", help="object counts, comma-separated")
    ap.add_argument("--mesh", default="cube", help="built-in mesh of every object (default cube)")
    ap.add_argument("--width", type=int, default=256)
    ap.add_argument("--height", type=int, default=192)
    ap.add_argument("--workers", type=int, default=2, help="the reference's worker processes")
    a = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="brdf-viewer-many-") as tmp:
        for n in (int(x) for x in a.sizes.split(",")):
            scene = Path(tmp) / f"{a.mesh}{n}.toml"
            scene.write_text(grid_scene(n, a.mesh, a.width, a.height))
            raster, why_r = timed(["render", str(scene), "--out", str(Path(tmp) / "r.png")])
            ref, why_p = timed(["reference", str(scene), "--spp", "1", "--engine", "cpu", "--workers",
                                str(a.workers), "--out", str(Path(tmp) / "p.png")])
            print(f"{n:>7,} {a.mesh}s at {a.width}x{a.height}: render {raster:6.2f} s{why_r}, "
                  f"reference (1 spp, cpu, {a.workers} workers) {ref:6.2f} s{why_p}, "
                  f"render / reference {raster / ref:.2f}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
