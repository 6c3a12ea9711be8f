"""Hardening runs, big versions of the tests (prints counts and figures, asserts nothing;
exit status 1 when any case failed): `python benchmarks/hardening.py [--quick] [--only NAMES]`.

Sections (``--only fuzz,cli,bigmesh,nan,files,lifecycle,deps``):

* fuzz       mutated scene files, broken meshes, broken HDR / EXR maps over several seeds
             (tests/fuzz_cases.py): each must load or fail with exactly one one-line ViewerError;
             then the accepted mutated scenes are rendered by the reference (tiny image) and must
             give finite, non-negative pixels.
* cli        fuzzed scene files through `python -m viewer render`: exit status 0 or 2, on 2 one
             line on stderr and no output file.
* bigmesh    a 5,000,000-triangle PLY: load time and peak memory; the same file truncated and with
             a NaN coordinate must fail with one line.
* nan        the NaN sweep (tests/nan_sweep_cases.py) with many parameter corners: numpy twins,
             GLSL twins, rasterized renders, reference renders.
* files      SIGKILL a process writing through viewer.base.io at random moments (npy, png, json);
             the destination must be absent or a complete version; a naive writer (open + write)
             under the same kills as the control.
* lifecycle  1,000 restarts of the window's reference view (with and without worker processes),
             threads / processes / memory before and after; renderer create-close cycles.
* deps       which optional packages are installed, and the message a missing one gives.

Run from the repository root; the default run takes about 10 minutes on 2 cores, --quick about 2.
"""

from __future__ import annotations

import argparse
import collections
import os
import random
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

FAILURES: list[str] = []


def section(title):
    print(f"\n== {title} ==", flush=True)


def fail(text):
    FAILURES.append(text)
    print("   FAIL:", text.splitlines()[0][:300], flush=True)


def peak_rss_mb():
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


# ----------------------------------------------------------------------------- fuzz

def run_fuzz(quick):
    import fuzz_cases as fc

    section("fuzzed inputs (each case: loads, or exactly one one-line ViewerError)")
    counts_total = {"scene": 20000, "mesh": 8000, "env": 8000}
    if quick:
        counts_total = {"scene": 3000, "mesh": 1600, "env": 1300}
    seeds = (1, 2, 3, 4)
    for which, n in counts_total.items():
        t0 = time.perf_counter()
        total = collections.Counter()
        with tempfile.TemporaryDirectory() as tmp:
            for seed in seeds:
                counts, failures = fc.run_fuzz(which, n // len(seeds), seed, Path(tmp) / str(seed))
                total.update(counts)
                for f in failures:
                    fail(f)
        print(fc.format_counts(which, total))
        print(f"   {time.perf_counter() - t0:.1f} s")
    deep_render(quick)


def deep_render(quick):
    """Accepted mutated scenes through the reference (6 x 4 pixels, 1 spp, depth 3)."""
    import numpy as np

    import fuzz_cases as fc
    from viewer.pathtracer import ReferenceRenderer
    from viewer.scene import load_scene

    n = 300 if quick else 1500
    rng = np.random.default_rng(11)
    texts = fc.builtin_scene_texts()
    names = list(texts)
    kinds = ("number", "swap_type", "delete", "list_length", "combo")
    accepted = bad = 0
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        p = Path(tmp) / "s.toml"
        for i in range(n):
            desc, raw, ov = fc.mutate_scene(rng, texts[names[i % len(names)]], kinds[i % len(kinds)])
            p.write_bytes(raw)
            try:
                scene = load_scene(str(p), ov + ["camera.width=6", "camera.height=4"])
            except Exception:  # noqa: BLE001 - refused cases were checked above
                continue
            accepted += 1
            try:
                with ReferenceRenderer(scene, workers=0, max_depth=3, seed=i) as r:
                    r.step(1)
                    img = r.mean()
                if not np.all(np.isfinite(img)) or img.min() < 0:
                    bad += 1
                    fail(f"reference of accepted scene {names[i % len(names)]} {desc}: non-finite or negative")
            except Exception as e:  # noqa: BLE001
                bad += 1
                fail(f"reference of accepted scene {names[i % len(names)]} {desc}: {type(e).__name__}: {e}")
    print(f"accepted mutated scenes rendered by the reference: {accepted} of {n} mutations, {bad} failures "
          f"({time.perf_counter() - t0:.1f} s)")


# ----------------------------------------------------------------------------- cli

def run_cli(quick):
    import numpy as np

    import fuzz_cases as fc

    section("fuzzed scene files through `python -m viewer render` (exit 0, or 2 + one line + no file)")
    n = 12 if quick else 60
    rng = np.random.default_rng(5)
    texts = fc.builtin_scene_texts()
    names = list(texts)
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    outcome = collections.Counter()
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(n):
            kind = fc.SCENE_KINDS[i % len(fc.SCENE_KINDS)]
            desc, raw, ov = fc.mutate_scene(rng, texts[names[i % len(names)]], kind)
            scene = Path(tmp) / f"s{i}.toml"
            scene.write_bytes(raw)
            out = Path(tmp) / f"o{i}.png"
            args = [sys.executable, "-m", "viewer", "render", str(scene), "--out", str(out), "--width", "16",
                    "--height", "12"] + [x for o in ov for x in ("--set", o)]
            r = subprocess.run(args, capture_output=True, text=True, env=env, timeout=300)
            lines = r.stderr.strip().splitlines()
            if r.returncode == 0:
                ok = out.exists()
            else:
                ok = (r.returncode == 2 and len(lines) == 1 and lines[0].startswith("brdf-viewer: error: ")
                      and not out.exists())
            outcome[(kind, "exit 0" if r.returncode == 0 else f"exit {r.returncode}", ok)] += 1
            if not ok:
                fail(f"cli {desc}: exit {r.returncode}, stderr {r.stderr[-500:]!r}")
    for (kind, code, ok), c in sorted(outcome.items()):
        print(f"   {kind:12s} {code}: {c}{'' if ok else '  (FAILED)'}")
    print(f"{n} command lines, {sum(c for (k, _, ok), c in outcome.items() if not ok)} failures "
          f"({time.perf_counter() - t0:.1f} s)")


# ----------------------------------------------------------------------------- big mesh

BIG_MESH_CHILD = r"""
import json, resource, sys, time
from viewer import ViewerError
from viewer.scene.mesh import load_mesh
t = time.perf_counter()
try:
    m = load_mesh(sys.argv[1])
    out = {"ok": True, "triangles": int(len(m.indices)), "vertices": int(len(m.positions))}
except ViewerError as e:
    out = {"ok": False, "message": str(e)}
out["seconds"] = time.perf_counter() - t
out["peak_rss_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
print(json.dumps(out))
"""


def run_bigmesh(quick):
    import json

    import numpy as np

    from viewer.scene.mesh import write_ply

    n = 700 if quick else 1582  # an n x n grid on a sphere: 2 n^2 triangles (1582: 5,005,448)
    section(f"a {2 * n * n:,}-triangle mesh (binary PLY)")
    with tempfile.TemporaryDirectory() as tmp:
        u = np.linspace(0.0, 2.0 * np.pi, n + 1)
        v = np.linspace(0.01, np.pi - 0.01, n + 1)
        U, V = np.meshgrid(u, v)
        P = np.stack([np.sin(V) * np.cos(U), np.cos(V), np.sin(V) * np.sin(U)], -1).reshape(-1, 3)
        idx = np.arange((n + 1) * (n + 1)).reshape(n + 1, n + 1)
        a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel()
        F = np.concatenate([np.stack([a, c, b], 1), np.stack([b, c, d], 1)])
        path = Path(tmp) / "big.ply"
        t = time.perf_counter()
        write_ply(path, P, np.full_like(P, np.nan), F)
        size = path.stat().st_size
        print(f"written {size / 2 ** 20:.0f} MB in {time.perf_counter() - t:.1f} s")
        data = path.read_bytes()
        (Path(tmp) / "cut.ply").write_bytes(data[: int(len(data) * 0.6)])
        header_end = data.index(b"end_header\n") + len(b"end_header\n")
        nan_at = header_end + 24 * (len(P) // 2)  # x of the middle vertex
        (Path(tmp) / "nan.ply").write_bytes(data[:nan_at] + np.float32(np.nan).tobytes() + data[nan_at + 4:])
        del data
        env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
        for name, expect_ok in (("big.ply", True), ("cut.ply", False), ("nan.ply", False)):
            r = subprocess.run([sys.executable, "-c", BIG_MESH_CHILD, str(Path(tmp) / name)], capture_output=True,
                               text=True, env=env, timeout=900)
            try:
                res = json.loads(r.stdout.strip().splitlines()[-1])
            except (IndexError, ValueError):
                fail(f"big mesh {name}: child failed: {r.stderr[-400:]}")
                continue
            what = (f"{res['triangles']:,} triangles, {res['vertices']:,} vertices" if res["ok"]
                    else f"error: {res['message'][:160]}")
            print(f"   {name:8s} {res['seconds']:6.1f} s, peak RSS {res['peak_rss_mb']:7.0f} MB: {what}")
            if res["ok"] != expect_ok or (not res["ok"] and len(res["message"].splitlines()) != 1):
                fail(f"big mesh {name}: {res}")


# ----------------------------------------------------------------------------- NaN sweep

def run_nan(quick):
    import numpy as np

    import nan_sweep_cases as nc
    from brdf_harness import param_grid
    from viewer import brdf

    section("NaN sweep: parameter corners x special direction pairs, both renderers")
    n_twin = 60 if quick else 400
    n_render = 3 if quick else 12
    n_ref = 6 if quick else 30
    rng = np.random.default_rng(3)
    wi, wo = nc.direction_pairs(rng)
    print(f"{len(wi)} direction pairs; per model {n_twin} corner sets + the harness grid for the twins, "
          f"{n_render} corners x 3 IBL modes for raster renders, {n_ref} corners for reference renders")
    from glsl_eval import GLSLEvaluator
    from viewer.scene.camera import OrbitCamera
    from viewer.gl.context import create_offscreen_context
    from viewer.gl.renderer import Renderer
    from viewer.pathtracer import ReferenceRenderer

    ctx = create_offscreen_context()
    ev = GLSLEvaluator(ctx)
    renderer = Renderer(ctx)
    wi32, wo32 = wi.astype(np.float32).astype(np.float64), wo.astype(np.float32).astype(np.float64)
    print(f"   {'model':18s} {'sets':>5s} {'numpy bad':>9s} {'GLSL bad':>9s} {'renders':>7s} {'bad':>4s} "
          f"{'reference':>9s} {'bad':>4s} {'s':>6s}")
    for name in brdf.names():
        t0 = time.perf_counter()
        sets = param_grid(brdf.get(name)) + nc.corner_sets(name, n_twin, 1001)
        py_bad = gl_bad = 0
        for p in sets:
            problems = nc.check_python(name, p, wi, wo, rng)
            if problems:
                py_bad += 1
                fail(f"numpy {name} {p.to_plain()}: {problems[:2]}")
            for what in (0, 1):
                f = ev.eval(p, wi32, wo32, what)
                if not np.all(np.isfinite(f)) or (what == 0 and f.min() < 0):
                    gl_bad += 1
                    fail(f"GLSL {'eval' if what == 0 else 'terms'} {name} {p.to_plain()}")
        r_n = r_bad = 0
        for ibl, ssr in (("split_sum", True), ("fis", False), ("brute_force", False)):
            scene = nc.sweep_scene(24, 24, ibl, ssr)
            cam = OrbitCamera.from_scene(scene)
            for p in nc.corner_sets(name, n_render, 2002):
                scene.materials["ball"] = p
                linear, _ = renderer.render_arrays(scene, cam)
                r_n += 1
                if not np.all(np.isfinite(linear)) or linear.min() < 0:
                    r_bad += 1
                    fail(f"raster {name} {ibl} {p.to_plain()}")
        f_n = f_bad = 0
        scene = nc.sweep_scene(10, 8)
        for k, p in enumerate(nc.corner_sets(name, n_ref, 3003)):
            scene.materials["ball"] = p
            with ReferenceRenderer(scene, max_depth=4, seed=k, workers=0) as ref:
                ref.step(2)
                img = ref.mean()
            f_n += 1
            if ref.bad_values or not np.all(np.isfinite(img)) or img.min() < 0:
                f_bad += 1
                fail(f"reference {name} {p.to_plain()}: bad_values {ref.bad_values}")
        print(f"   {name:18s} {len(sets):5d} {py_bad:9d} {gl_bad:9d} {r_n:7d} {r_bad:4d} {f_n:9d} {f_bad:4d} "
              f"{time.perf_counter() - t0:6.1f}", flush=True)
    renderer.release()


# ----------------------------------------------------------------------------- files

NAIVE_WRITER = r"""
import sys, numpy as np
dst, size = sys.argv[1], int(sys.argv[2])
print("ready", flush=True)
i = 0
while True:
    i += 1
    data = np.full((size, size, 3), float(i), np.float32)
    with open(dst, "wb") as f:       # not atomic: truncate, then write in pieces
        np.save(f, data)
"""


def run_files(quick):
    from test_atomic_files import check_complete, kill_writers  # the test's writer and checks

    section("SIGKILL during writes: the destination is absent or one complete version")
    kills = 20 if quick else 100
    t0 = time.perf_counter()
    for kind, size in (("npy", 512), ("png", 384), ("json", 1024)):
        with tempfile.TemporaryDirectory() as tmp:
            try:
                versions, mid = kill_writers(Path(tmp), kind, kills, size, seed=len(kind) + 7)
                print(f"   {kind:5s}: {kills} kills, {mid} while a temporary file was open, 0 partial files; "
                      f"versions found: {len(set(versions))} different")
            except AssertionError as e:
                fail(f"{kind}: partial file after a kill: {e}")
    # the control: the same kills against a plain open() + write
    partial = 0
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    rng = random.Random(9)
    with tempfile.TemporaryDirectory() as tmp:
        dst = Path(tmp) / "naive.npy"
        for _ in range(kills // 2):
            p = subprocess.Popen([sys.executable, "-c", NAIVE_WRITER, str(dst), "512"], stdout=subprocess.PIPE,
                                 env=env)
            p.stdout.readline()
            time.sleep(rng.random() * 0.25)
            os.kill(p.pid, 9)
            p.wait()
            p.stdout.close()
            try:
                check_complete("npy", dst, 512)
            except Exception:  # noqa: BLE001 - a partial file: what the atomic writer prevents
                partial += 1
    print(f"   control, naive open + write: {partial} partial files in {kills // 2} kills "
          f"({time.perf_counter() - t0:.1f} s in all)")


# ----------------------------------------------------------------------------- lifecycle

def run_lifecycle(quick):
    import lifecycle

    section("reference lifecycle: restart the window's reference view over and over")
    n = 200 if quick else 1000
    old = tempfile.tempdir
    with tempfile.TemporaryDirectory() as tmp:
        tempfile.tempdir = tmp  # the renderer's setup files: only ours in this folder
        try:
            for workers in (2, 0):
                r = lifecycle.restart_storm(n, workers=workers, seed=workers, max_pause_s=0.02)
                print(f"   workers={workers}: {r.summary()}")
                if r.errors:
                    fail(f"lifecycle workers={workers}: {r.errors[:2]}")
                if r.after_close_workers or r.after_close_tasks > r.baseline_tasks or r.after_close_setup_files:
                    fail(f"lifecycle workers={workers}: left behind {r.after_close_workers}, "
                         f"{r.after_close_tasks} threads, {r.after_close_setup_files}")
                if r.drift_mb >= 16.0:
                    fail(f"lifecycle workers={workers}: RSS drift {r.drift_mb:.1f} MB")
            from viewer.pathtracer import ReferenceRenderer
            from viewer.scene import load_scene

            scene = load_scene("sphere", ["camera.width=16", "camera.height=12"])
            cycles = 5 if quick else 20
            before_tasks = lifecycle.task_count()
            rss0 = lifecycle.rss_bytes()
            t0 = time.perf_counter()
            for _ in range(cycles):
                with ReferenceRenderer(scene, max_depth=2, workers=2) as rr:
                    rr.step(1)
            time.sleep(0.5)
            print(f"   ReferenceRenderer(workers=2) create / step / close x{cycles}: "
                  f"{(time.perf_counter() - t0) / cycles:.2f} s each; worker processes after: "
                  f"{len(lifecycle.worker_children())}; threads {before_tasks} -> {lifecycle.task_count()}; "
                  f"RSS {rss0 / 2 ** 20:.1f} -> {lifecycle.rss_bytes() / 2 ** 20:.1f} MB")
            if lifecycle.worker_children():
                fail("renderer cycles left worker processes")
        finally:
            tempfile.tempdir = old


# ----------------------------------------------------------------------------- deps

def run_deps(quick):
    from viewer import ViewerError
    from viewer.base.optional import PACKAGES, available, require

    section("optional packages")
    for name in sorted(PACKAGES):
        state = "installed" if available(name) else "MISSING"
        saved = sys.modules.get(name, "absent")
        sys.modules[name] = None  # what its absence looks like
        try:
            require(name)
            msg = "(no error!)"
            fail(f"require({name}) did not fail when hidden")
        except ViewerError as e:
            msg = str(e)
        finally:
            if saved == "absent":
                del sys.modules[name]
            else:
                sys.modules[name] = saved
        print(f"   {name:8s} {state:9s} when missing: {msg}")


SECTIONS = {"fuzz": run_fuzz, "cli": run_cli, "bigmesh": run_bigmesh, "nan": run_nan, "files": run_files,
            "lifecycle": run_lifecycle, "deps": run_deps}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="smaller counts (about 2 minutes)")
    ap.add_argument("--only", default=",".join(SECTIONS), help="comma-separated sections: " + ", ".join(SECTIONS))
    args = ap.parse_args()
    t0 = time.perf_counter()
    print(f"brdf-viewer hardening runs; {os.cpu_count()} CPUs; python {sys.version.split()[0]}"
          + ("; quick" if args.quick else ""))
    for name in args.only.split(","):
        SECTIONS[name.strip()](args.quick)
    print(f"\n{len(FAILURES)} failures; {time.perf_counter() - t0:.0f} s; peak RSS of this process "
          f"{peak_rss_mb():.0f} MB")
    return 1 if FAILURES else 0


if __name__ == "__main__":
    sys.exit(main())
