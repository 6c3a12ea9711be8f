""".brdf file BRDFs, the figures of docs/write-your-own-brdf.md:

    python benchmarks/brdf_files.py [--published FOLDER]

1. compile: a file's evaluation program (first, with Mesa's shader cache off, and from the
   in-process cache) and the first raster frame of a scene with it against the second;
2. a slider move on a file BRDF to the new frame (the raster, parameters in the material block:
   no compile), against the same move on the built-in microfacet;
3. the GPU engine's samples/second on a file Lambert against the built-in Lambert;
4. the variance of the generic sampler (cosine mixed with the tabulated half vectors) against the built-in GGX sampler (visible
   normals) on a GGX written as a .brdf (benchmarks/scenes/ggx.brdf), at equal samples, BSDF
   sampling only, under a constant environment: the ratio of the per-pixel variances over seeds;
   and per sample at fixed views: the variance of f cos / pdf of the generic sampler (its numpy
   twin, viewer.brdf.file_sampler, the GPU engine's table) over the built-in's, per alpha (0.1,
   0.3, 0.6) and view (0, 45, 75 degrees);
5. with --published: how many of a folder of .brdf files load, get a report card and render.
"""

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("MESA_SHADER_CACHE_DISABLE", "true")  # "first" compiles are first
import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
HERE = Path(__file__).resolve().parent

SCENE = """
[camera]
position = [0.0, 0.0, 4.0]
target = [0.0, 0.0, 0.0]
fov_y = 40.0
width = {w}
height = {h}

{env}

[[objects]]
mesh = "sphere"
material = "ball"

[materials.ball]
{mat}
"""
POINT = '[[lights]]\ntype = "point"\nposition = [2.0, 3.0, 2.0]\nintensity = [10.0, 10.0, 10.0]'
CONST = '[environment]\nconstant = [1.0, 1.0, 1.0]\n[render]\nibl = "fis"'


def scene(folder, mat, env=POINT, w=256, h=256):
    p = Path(folder) / f"s{abs(hash((mat, env, w, h)))}.toml"
    p.write_text(SCENE.format(w=w, h=h, env=env, mat=mat))
    return p


def compile_times(folder):
    from viewer import brdf
    from viewer.gl.file_brdf import FileEvaluator

    f = brdf.load(ROOT / "viewer" / "brdfs" / "cooktorrance.brdf").bfile
    ev = FileEvaluator()
    t = time.perf_counter()
    ev.check(f)
    first = time.perf_counter() - t
    t = time.perf_counter()
    ev.check(f)
    cached = time.perf_counter() - t
    print(f"compile: evaluation program {first * 1e3:.0f} ms first, {cached * 1e3:.3f} ms cached (in-process)")


def raster_frames(folder):
    from viewer.scene.camera import OrbitCamera
    from viewer.gl.context import create_offscreen_context
    from viewer.gl.renderer import Renderer
    from viewer.scene import load_scene

    ctx = create_offscreen_context()
    r = Renderer(ctx)
    shutil_src = ROOT / "viewer" / "brdfs" / "cooktorrance.brdf"
    out = {}
    for label, mat, key, values in (
            ("file Cook-Torrance", f'model = "custom"\nfile = "{shutil_src}"', "m", (0.3, 0.31)),
            ("built-in microfacet", 'model = "microfacet"\ndistribution = "beckmann"\nshadowing = "v_cavity"\n'
                                    'fresnel = "dielectric"\nkd = [0.0, 0.0, 0.0]', "alpha_x", (0.3, 0.31))):
        sc = load_scene(scene(folder, mat, POINT + "\n" + CONST))
        cam = OrbitCamera.from_scene(sc)
        t = time.perf_counter()
        r.render_arrays(sc, cam)
        first = time.perf_counter() - t
        t = time.perf_counter()
        r.render_arrays(sc, cam)
        second = time.perf_counter() - t
        moves = []
        for k in range(10):
            p = sc.materials["ball"]
            sc.materials["ball"] = p.replace(**{key: values[k % 2] + 1e-4 * k})
            t = time.perf_counter()
            r.render_arrays(sc, cam)
            moves.append(time.perf_counter() - t)
        out[label] = statistics.median(moves)
        print(f"raster {label}: first frame {first * 1e3:.0f} ms (compiles), next {second * 1e3:.0f} ms, "
              f"slider move to frame {statistics.median(moves) * 1e3:.0f} ms (median of 10, 256x256)")
    return out


def engine_rate(folder):
    from viewer.scene.camera import OrbitCamera
    from viewer.reference_common.select import make_renderer
    from viewer.scene import load_scene

    lam = ROOT / "tests" / "brdfs" / "lambert_twin.brdf"
    for label, mat in (("file Lambert", f'model = "custom"\nfile = "{lam}"\ngain = 0.8'),
                       ("built-in Lambert", 'model = "lambert"\nalbedo = [0.64, 0.48, 0.32]')):
        sc = load_scene(scene(folder, mat, POINT + "\n" + CONST, 128, 128))
        rr = make_renderer("gpu", sc, OrbitCamera.from_scene(sc), max_depth=3, seed=1)
        try:
            rr.step(2)
            t = time.perf_counter()
            rr.step(32)
            dt = time.perf_counter() - t
        finally:
            rr.close()
        print(f"gpu engine {label}: {32 * 128 * 128 / dt:,.0f} samples/s (128x128, 32 spp, depth 3)")


def variance_ratio(folder, seeds=12, spp=4):
    from viewer.scene.camera import OrbitCamera
    from viewer.reference_common.select import make_renderer
    from viewer.scene import load_scene

    ggx = HERE / "scenes" / "ggx.brdf"
    res = {}
    for label, mat in (("generic on the .brdf", f'model = "custom"\nfile = "{ggx}"\nalpha = 0.3\nf0 = 0.9'),
                       ("built-in (VNDF)", 'model = "microfacet"\ndistribution = "ggx"\nfresnel = "schlick"\n'
                                           'f0 = [0.9, 0.9, 0.9]\nalpha = 0.3\nkd = [0.0, 0.0, 0.0]')):
        sc = load_scene(scene(folder, mat, CONST, 64, 64))
        imgs = []
        for s in range(seeds):
            rr = make_renderer("gpu", sc, OrbitCamera.from_scene(sc), max_depth=1, seed=100 + s, strategy="bsdf")
            try:
                rr.step(spp)
                imgs.append(rr.mean().copy())
            finally:
                rr.close()
        a = np.stack(imgs)
        mask = a.mean(axis=0).sum(axis=2) > 0
        res[label] = (float(a.var(axis=0, ddof=1)[mask].mean()), float(a.mean(axis=0)[mask].mean()))
    g, b = res["generic on the .brdf"], res["built-in (VNDF)"]
    print(f"variance at equal samples ({spp} spp x {seeds} seeds, bsdf sampling, constant environment): "
          f"generic {g[0]:.3g}, built-in {b[0]:.3g}, ratio {g[0] / b[0]:.2f}x (means {g[1]:.4f} / {b[1]:.4f})")


def variance_ratio_per_view(n=400_000):
    from viewer import brdf
    from viewer.brdf import file_sampler
    from viewer.gl.brdf_glsl import sampler_table

    m = brdf.load(HERE / "scenes" / "ggx.brdf")
    built = brdf.get("microfacet")
    print(f"variance of f cos / pdf per sample, generic sampler (table {file_sampler.FULL} = "
          f"{file_sampler.size(file_sampler.FULL)} floats) over the built-in GGX (VNDF), {n:,} samples each:")
    for alpha in (0.1, 0.3, 0.6):
        p = m.params(alpha=alpha, f0=0.9)
        table = sampler_table(p, None)
        q = built.params().replace(distribution="ggx", fresnel="schlick", f0=np.full(3, 0.9), alpha_x=alpha,
                                   alpha_y=alpha, kd=np.zeros(3))
        out = []
        for tv in (0.0, 45.0, 75.0):
            rng = np.random.default_rng(int(alpha * 1000 + tv))
            t = np.radians(tv)
            wo = np.broadcast_to(np.array([np.sin(t) * np.cos(0.37), np.sin(t) * np.sin(0.37), np.cos(t)]),
                                 (n, 3)).copy()
            wi, pdf = file_sampler.sample(table, wo, rng.random((n, 3)))
            ok = pdf > 0
            f = np.zeros(n)
            f[ok] = m.eval(p, wi[ok], wo[ok])[:, 1]
            w = np.where(ok, f * np.maximum(wi[:, 2], 0.0) / np.where(ok, pdf, 1.0), 0.0)
            _, wb, _ = built.sample(q, wo, rng.random((n, 2)))
            out.append(f"{tv:.0f} deg {np.var(w) / np.var(wb[:, 1]):.2f}x")
        print(f"  alpha {alpha}: " + ", ".join(out))


def published(folder, out):
    from viewer import brdf, file_brdf_evaluator
    from viewer.brdf.report_card import report

    files = sorted(Path(folder).glob("*.brdf"))
    loaded = carded = passed = rendered = finite = 0
    import viewer

    for f in files:
        try:
            m = brdf.load(f)
            file_brdf_evaluator().check(m.bfile)
            loaded += 1
            rep = report(m, m.params(), f.name)
            carded += 1
            passed += bool(rep["pass"])
            img = viewer.render(scene(out, f'model = "custom"\nfile = "{f}"', POINT + "\n" + CONST, 48, 48))
            rendered += 1
            finite += bool(np.all(np.isfinite(img)))
        except Exception as e:  # noqa: BLE001 - counted, and named
            print(f"  {f.name}: {str(e).splitlines()[0]}")
    print(f"published files: {len(files)}; load and compile {loaded}; report card {carded} "
          f"({passed} pass every check); render {rendered} ({finite} with every pixel finite)")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--published", help="a folder of BRDF Explorer .brdf files")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as d:
        compile_times(d)
        raster_frames(d)
        engine_rate(d)
        variance_ratio(d)
        variance_ratio_per_view()
        if args.published:
            published(args.published, d)


if __name__ == "__main__":
    main()
