"""The cost of a slider move's albedo tables, numpy builder against the GPU one:

    python benchmarks/albedo_tables.py [--repeat 7]

For each material of the gallery scene (one per BRDF family, the lecture's presets) a slider
move is simulated by nudging one float parameter, and the renderer's table work is timed: the
(reflected, transmitted) tables plus, for models with a specular proxy (``ibl_split``), the
specular part's table, i.e. what ``Renderer.albedo_tables`` computes on a cache miss. Prints
the first GPU build (compiles the sampling program), then the median of the slider moves."""

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def _nudge(params, k):
    """The parameters after the k-th slider step: the first float parameter scaled by 1 +- 1%."""
    from viewer import brdf

    spec = brdf.get(params.model).spec
    for prm in spec.params:
        if prm.kind == "float":
            v = float(params[prm.name]) * (1.0 + 0.01 * ((k % 2) * 2 - 1))
            v = min(max(v, prm.lo if prm.lo is not None else v), prm.hi if prm.hi is not None else v)
            return params.replace(**{prm.name: v})
        if prm.kind == "rgb":
            v = np.clip(params[prm.name] * (1.0 + 0.01 * ((k % 2) * 2 - 1)), prm.lo, prm.hi)
            return params.replace(**{prm.name: v})
    return params


def _work(builder, model, params):
    r, t = builder(model, params)
    split = getattr(model.module, "ibl_split", None)
    if split is not None:
        sp, _ = split(params)
        if sp is not params:
            builder(model, sp)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=7)
    args = ap.parse_args()
    from viewer import brdf
    from viewer.brdf.albedo import albedo_tables
    from viewer.gl.albedo_gpu import GPUAlbedoTables
    from viewer.gl.context import create_offscreen_context
    from viewer.scene import load_scene

    ctx = create_offscreen_context()
    gpu = GPUAlbedoTables(ctx)
    scene = load_scene("gallery")
    print(f"renderer: {ctx.info['GL_RENDERER']}")
    print(f"{'material':22s} {'model':18s} {'numpy ms':>9s} {'gpu first ms':>13s} {'gpu ms':>8s}")
    all_np, all_gpu = [], []
    for name, p in scene.materials.items():
        model = brdf.get(p.model)
        t = time.perf_counter()
        _work(lambda m, q: gpu.tables(q), model, p)
        first = (time.perf_counter() - t) * 1e3
        tn, tg = [], []
        for k in range(args.repeat):
            q = _nudge(p, k + 1)
            t = time.perf_counter()
            _work(albedo_tables, model, q)
            tn.append((time.perf_counter() - t) * 1e3)
            t = time.perf_counter()
            _work(lambda m, qq: gpu.tables(qq), model, q)
            tg.append((time.perf_counter() - t) * 1e3)
        mn, mg = statistics.median(tn), statistics.median(tg)
        all_np.append(mn)
        all_gpu.append(mg)
        print(f"{name:22s} {p.model:18s} {mn:9.1f} {first:13.1f} {mg:8.1f}")
    print(f"median over materials: numpy {statistics.median(all_np):.1f} ms, gpu {statistics.median(all_gpu):.1f} ms; "
          f"max: numpy {max(all_np):.1f} ms, gpu {max(all_gpu):.1f} ms")
    gpu.release()


if __name__ == "__main__":
    main()
