"""An environment map the disk cache lacks never freezes the window: the frame draws it with a
quick low-resolution prefilter (``viewer.gl.ibl.IBL.defer``), the full prefilter runs in a child
process (``viewer.app.prefetch.MapPrefilter``) into the disk cache, and the view is drawn again
with it once it is there; the meantime is labelled and never stored as a prepared trace."""

import numpy as np
import pytest


def _map(seed=0, w=64, h=32):
    rng = np.random.default_rng(seed)
    img = rng.uniform(0.0, 2.0, (h, w, 3)).astype(np.float32)
    img[:4, :8] = 40.0  # a bright patch: the prefilter has something to blur
    return img


@pytest.fixture
def cache_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("BRDF_VIEWER_CACHE", str(tmp_path / "cache"))
    return tmp_path / "cache"


def test_a_cache_miss_is_a_quick_provisional_prefilter(gl_ctx, cache_dir):
    from viewer.app.prefetch import prefilter_file
    from viewer.environment import cache
    from viewer.gl import ibl as ibl_mod

    ibl = ibl_mod.IBL(gl_ctx)
    try:
        ibl.defer = True
        img = _map()
        ibl.set_environment(img)
        # the quick prefilter: small layers, few samples, nothing written to the disk cache
        assert ibl.stats["provisional"] and ibl.provisional is not None
        assert ibl.layer_size == (ibl_mod.QUICK_LAYER_WIDTH, ibl_mod.QUICK_LAYER_WIDTH // 2)
        assert ibl.stats["prefilter_passes"] == 1 and max(ibl.stats["samples"]) == ibl_mod.QUICK_SAMPLES
        assert not cache.path_for(ibl.provisional).exists()
        assert np.array_equal(ibl.pending_map, img)
        key = ibl.provisional
        ibl.set_environment(img)  # the next frame: unchanged (the cache does not hold it yet)
        assert ibl.stats["unchanged"] and ibl.provisional == key
        # the full prefilter elsewhere (as the background child runs it), then the next frame reads it
        path = cache_dir / "pending.npy"
        cache_dir.mkdir(parents=True, exist_ok=True)
        np.save(path, ibl.pending_map)
        assert prefilter_file(path) == 0
        assert cache.path_for(key).is_file()
        ibl.set_environment(img)
        assert ibl.stats["cached"] and not ibl.stats["provisional"] and ibl.provisional is None
        assert ibl.stats["prefilter_passes"] == 0  # read, not prefiltered here
        assert ibl.layer_size == (min(ibl_mod.LAYER_WIDTH, 64), min(ibl_mod.LAYER_WIDTH // 2, 32))
        # the same levels a synchronous prefilter gives
        sync = ibl_mod.IBL(gl_ctx, use_cache=False)
        try:
            sync.set_environment(img)
            assert np.allclose(sync.prefiltered_data, ibl.prefiltered_data, rtol=1e-5, atol=1e-6)
        finally:
            sync.release()
    finally:
        ibl.release()


def test_without_defer_a_miss_prefilters_at_once(gl_ctx, cache_dir):
    from viewer.environment import cache
    from viewer.gl.ibl import IBL

    ibl = IBL(gl_ctx)
    try:
        ibl.set_environment(_map(1))
        assert not ibl.stats["provisional"] and ibl.provisional is None and ibl.stats["prefilter_passes"] == 1
        assert cache.path_for(cache.content_key(_map(1), ibl_settings(ibl))).is_file()
    finally:
        ibl.release()


def ibl_settings(ibl):
    return {"alphas": ibl.alphas, "samples": ibl.samples, "layer_width": ibl.layer_width,
            "fis_bias": ibl.fis_bias, "estimator": "ggx-dcos-n=v=r-nol-weighted-fis"}


def test_the_window_never_prefilters_a_new_map_on_its_thread(gl_ctx, cache_dir, tmp_path, monkeypatch):
    import time

    from viewer.app.session import DEFER_ENV, Session
    from viewer.gl.renderer import Renderer

    # a renderer of its own: the shared one's IBL may bypass the disk cache after a hot-reload test
    renderer = Renderer(gl_ctx)
    from viewer.environment.io import save_environment

    monkeypatch.setenv(DEFER_ENV, "1")  # the window's default (the suite turns it off)
    env = tmp_path / "env.hdr"
    save_environment(env, _map(2))
    s = Session(gl_ctx, "sphere", [f"environment.map={env}"], renderer=renderer, prefetch=True)
    try:
        s.warm = []
        s.render_view((32, 24))
        assert s.environment_provisional and s.quality == "full"
        assert "quick low-resolution prefilter" in s.status
        deadline = time.monotonic() + 240
        while s.environment_provisional and time.monotonic() < deadline:  # waits for the child
            time.sleep(0.05)
            s.render_view((32, 24))
        assert not s.environment_provisional, s.status
        assert "fully prefiltered in the background" in " ".join(m.text for m in s.messages)
        assert s.renderer.ibl().stats.get("cached")
    finally:
        s.release()
        renderer.release()


def test_a_small_or_constant_map_is_prefiltered_at_once(gl_ctx, cache_dir):
    # nothing to gain from the quick prefilter where the full one is as small
    from viewer.gl import ibl as ibl_mod

    ibl = ibl_mod.IBL(gl_ctx)
    try:
        ibl.defer = True
        ibl.set_environment(None, constant=(0.3, 0.3, 0.3))
        assert ibl.provisional is None and not ibl.stats["provisional"]
        ibl.set_environment(_map(3, w=ibl_mod.QUICK_LAYER_WIDTH, h=ibl_mod.QUICK_LAYER_WIDTH // 2))
        assert ibl.provisional is None and ibl.stats["prefilter_passes"] == 1
    finally:
        ibl.release()


def test_built_in_maps_are_kept_in_the_disk_cache(cache_dir):
    # the sky is generated once (numpy, up to seconds on a loaded machine), then read back: the
    # same texels either way
    from viewer.environment import cache, procedural

    for name in procedural.builtin_names():
        fresh = procedural.generate(name, 64, 32, cache=False)
        first = procedural.generate(name, 64, 32)
        assert list(cache_dir.glob("procedural-*.npz"))
        again = procedural.generate(name, 64, 32)
        assert np.array_equal(fresh, first) and np.array_equal(first, again) and again.dtype == np.float32
    key = cache.content_key(None, {"name": "sky", "width": 64, "height": 32,
                                   "version": procedural.GENERATOR_VERSION}, kind="procedural")
    path = cache.path_for(key, kind="procedural")
    path.write_bytes(b"damaged")  # a damaged entry reads as a miss and is generated again
    assert np.array_equal(procedural.generate("sky", 64, 32), procedural.generate("sky", 64, 32, cache=False))


def test_a_prefilter_no_longer_needed_is_stopped_without_waiting_for_its_child(cache_dir, monkeypatch):
    """Another map shown: the old map's prefilter child is signalled and reaped on a thread of its
    own (the window's frame waited 0.5 s for it beside two busy processes), and a new prefilter
    of the same map has a file of its own, which the old one's clean-up cannot remove."""
    import threading

    from viewer.app import prefetch

    real, gate, order = prefetch.stop_child, threading.Event(), []

    def held(proc, timeout=10.0):
        assert gate.wait(5)
        order.append("reaped")
        real(proc, timeout)

    monkeypatch.setattr(prefetch, "stop_child", held)
    img = _map(3)
    old = prefetch.MapPrefilter("k", img)
    new = prefetch.MapPrefilter("k", img)   # the same map again: its own file
    assert not old.error and not new.error
    assert len(list(cache_dir.glob("pending-k-*.npy"))) == 2
    old.stop(wait=False)
    order.append("returned")   # before the child was reaped: the caller did not wait
    gate.set()
    for t in threading.enumerate():
        if t.name == "brdf-viewer-prefilter-stop":
            t.join(30)
    assert order == ["returned", "reaped"] and old.finished
    assert len(list(cache_dir.glob("pending-k-*.npy"))) == 1   # the new job's file is still there
    monkeypatch.setattr(prefetch, "stop_child", real)
    new.stop()
    assert new.finished and not list(cache_dir.glob("pending-k-*.npy"))
