"""The reference cache (viewer/reference_common/cache.py) and ``brdf-viewer bake``."""

import subprocess
import sys

import numpy as np
import pytest

from viewer.pathtracer import ReferenceRenderer
from viewer.reference_common import cache
from viewer.reference_common.setup import RenderSetup
from viewer.scene import load_scene


def key_of(scene, w=16, h=12, max_depth=8):
    return cache.setup_key(RenderSetup.from_scene(scene, None, w, h, max_depth))


def test_key_follows_everything_that_changes_the_image():
    base = key_of(load_scene("sphere"))
    assert key_of(load_scene("sphere")) == base                      # the same content, the same key
    changed = [
        key_of(load_scene("sphere", ["materials.ball.albedo=[0.8,0.8,0.7]"])),
        key_of(load_scene("sphere", ["camera.position=[0,0,4.5]"])),
        key_of(load_scene("sphere", ["lights.0.intensity=[10,10,11]"])),
        key_of(load_scene("sphere", ['environment={constant=[0.1,0.1,0.1]}'])),
        key_of(load_scene("sphere", ['objects.0.scale=1.01'])),
        key_of(load_scene("sphere"), w=17),
        key_of(load_scene("sphere"), max_depth=3),
    ]
    assert len(set(changed + [base])) == len(changed) + 1


def test_store_load_resume(tmp_path):
    sc = load_scene("sphere")
    with ReferenceRenderer(sc, width=16, height=12, max_depth=2, seed=3, workers=0) as r:
        r.step(4)
        full = r.mean()
    with ReferenceRenderer(sc, width=16, height=12, max_depth=2, seed=3, workers=0) as r:
        r.step(2)
        s, s2, spp = r.state()
    key = key_of(sc, max_depth=2)
    assert cache.store(key, cache.Entry(s, s2, spp, "cpu", 3), tmp_path)
    assert not cache.store(key, cache.Entry(s, s2, spp, "cpu", 3), tmp_path)   # no more samples: kept
    e = cache.load(key, tmp_path)
    assert e.spp == 2 and e.engine == "cpu"
    with ReferenceRenderer(sc, width=16, height=12, max_depth=2, seed=3, workers=0) as r:
        r.resume(e.sum, e.sum2, e.spp)
        r.step(2)              # samples 2 and 3: the same as the uninterrupted render
        assert r.spp == 4
        # float32 storage of the sums: 1e-6 relative
        assert np.allclose(r.mean(), full, rtol=1e-5, atol=1e-7)
    cache.path_for(key, tmp_path).write_bytes(b"broken")
    assert cache.load(key, tmp_path) is None                             # a damaged entry is ignored


def run_cli(*args, env=None):
    return subprocess.run([sys.executable, "-m", "viewer", *args], capture_output=True, text=True, env=env,
                          timeout=300)


def test_bake_cli(tmp_path):
    import os

    env = dict(os.environ, BRDF_VIEWER_CACHE=str(tmp_path))
    r = run_cli("bake", "sphere", "--spp", "2", "--width", "12", "--height", "8", "--engine", "cpu",
                "--workers", "0", env=env)
    assert r.returncode == 0, r.stderr
    assert "engine: cpu" in r.stdout and "2 spp" in r.stdout
    files = list((tmp_path / "references").glob("*.npz"))
    assert len(files) == 1 and not list((tmp_path / "references").glob("*.part"))
    r = run_cli("bake", "sphere", "--spp", "2", "--width", "12", "--height", "8", "--engine", "cpu",
                "--workers", "0", env=env)
    assert "already cached at 2 spp" in r.stdout
    r = run_cli("bake", "--spp", "2", env=env)
    assert r.returncode == 2 and "name at least one SCENE" in r.stderr
    r = run_cli("bake", "sphere", "--spp", "2", "--engine", "tpu", env=env)
    assert r.returncode == 2 and "--engine: 'tpu' is not an engine" in r.stderr


def test_bake_keys_a_dispersive_scene_as_the_renderers_do(tmp_path):
    """A dispersive scene's reference traces wavelengths; bake stores it under the key the
    window's renderer (which sets the spectral flag) looks up."""
    import os

    glass = 'materials.ball={model="dielectric", spectral="SF11"}'
    env = dict(os.environ, BRDF_VIEWER_CACHE=str(tmp_path))
    r = run_cli("bake", "sphere", "--spp", "1", "--width", "12", "--height", "8", "--engine", "cpu",
                "--workers", "0", "--max-depth", "3", "--set", glass, env=env)
    assert r.returncode == 0, r.stderr
    # integrator "auto", as the window's (smooth glass under the point light: the photon map)
    with ReferenceRenderer(load_scene("sphere", [glass]), width=12, height=8, max_depth=3, workers=0,
                           integrator="auto") as rr:
        assert rr.setup.extra["spectral"] and rr.setup.integrator == "photon"
        want = cache.path_for(cache.setup_key(rr.setup), tmp_path)
    assert [f.name for f in (tmp_path / "references").glob("*.npz")] == [want.name]
    with ReferenceRenderer(load_scene("sphere", [glass]), width=12, height=8, max_depth=3, workers=0,
                           integrator="path") as rr:   # another estimator: another entry
        assert cache.path_for(cache.setup_key(rr.setup), tmp_path) != want


def test_the_key_does_not_follow_numpys_print_options():
    """The key hashes numbers, not their repr under numpy's global print options (a library may
    set legacy="1.13", which writes np.float64(2.0) as 2.: the window then looked up another key)."""
    import numpy as np

    scene = load_scene("sphere")
    with ReferenceRenderer(scene, width=12, height=8, max_depth=3, workers=0) as rr:
        key = cache.setup_key(rr.setup)
        saved = np.get_printoptions()
        try:
            np.set_printoptions(legacy="1.13")
            assert cache.setup_key(rr.setup) == key
        finally:
            np.set_printoptions(**saved)

