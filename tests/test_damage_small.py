"""Small damages: ``bake --lecture`` into a full or unwritable cache exits 1 with the reason (an
output problem, docs/commands.md); both caches set aside entries of finite garbage (3e38
everywhere), not only unreadable ones; a BRDF that returns Inf is named as the culprit, not the
renderer."""

from __future__ import annotations

import errno
import os

import numpy as np
import pytest

from viewer.commands import cli
ENOSPC = os.strerror(errno.ENOSPC)   # "No space left on device"


def run_main(args, capsys):
    rc = cli.main(list(args))
    out = capsys.readouterr()
    return rc, out.out, out.err


def _full_disk(monkeypatch, spare=lambda path: False):
    """Every atomic write fails as on a full disk (viewer.base.io's own error for ENOSPC), except
    those ``spare(path)`` lets through."""
    import viewer.base.io as vio

    real = vio.atomic_write_bytes

    def write(path, data):
        if spare(path):
            return real(path, data)
        raise vio.write_error(path, OSError(errno.ENOSPC, ENOSPC))

    monkeypatch.setattr(vio, "atomic_write_bytes", write)


# ----------------------------------------------------------------------------- bake --lecture

def test_bake_lecture_into_a_full_cache_exits_1_with_the_reason(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("BRDF_VIEWER_CACHE", str(tmp_path))
    _full_disk(monkeypatch)
    rc, out, err = run_main(["bake", "--lecture", "--width", "8", "--height", "8"], capsys)
    assert rc == 1, err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert "traced-frame cache" in err and ENOSPC in err and str(tmp_path / "traced") in err, err


def test_bake_lecture_that_cannot_store_a_step_exits_1_with_the_reason(tmp_path, monkeypatch, capsys):
    # the probe write passes, the entry's write finds the disk full
    import viewer.app.lecture_prep as prep_mod
    from viewer.scene.lecture import TOUR

    step = [s.key for s in TOUR].index("tir")
    monkeypatch.setattr(prep_mod, "traced_steps", lambda: [step])
    monkeypatch.setenv("BRDF_VIEWER_CACHE", str(tmp_path))
    _full_disk(monkeypatch, spare=lambda path: os.path.basename(str(path)).startswith(".probe-"))
    rc, out, err = run_main(["bake", "--lecture", "--width", "16", "--height", "12"], capsys)
    assert rc == 1, err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert f"lecture step {step + 1} traced but not stored" in err and ENOSPC in err, err
    assert not list((tmp_path / "traced").glob("*.npz"))


def test_bake_lecture_into_an_unwritable_cache_exits_1_with_the_reason(tmp_path, monkeypatch, capsys):
    # tests run as root, where a folder's mode does not stop a write: the cache's parent is a file
    blocker = tmp_path / "file"
    blocker.write_text("")
    monkeypatch.setenv("BRDF_VIEWER_CACHE", str(blocker / "cache"))
    rc, out, err = run_main(["bake", "--lecture", "--width", "8", "--height", "8"], capsys)
    assert rc == 1, err
    assert err.count("\n") == 1 and os.strerror(errno.ENOTDIR) in err, err


def test_bake_reference_into_a_full_cache_exits_1_with_the_reason(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("BRDF_VIEWER_CACHE", str(tmp_path))
    _full_disk(monkeypatch)
    rc, out, err = run_main(["bake", "sphere", "--spp", "1", "--width", "8", "--height", "6",
                             "--engine", "cpu", "--workers", "0"], capsys)
    assert rc == 1, err
    lines = [l for l in err.splitlines() if l.startswith("brdf-viewer:")]
    assert len(lines) == 1 and "reference cache" in lines[0] and ENOSPC in lines[0], err
    assert not list((tmp_path / "references").glob("*.npz"))


# ----------------------------------------------------------------------------- cache plausibility

SHAPE = (6, 8)


@pytest.mark.parametrize("damage, said", [("huge", "radiance of 3e+38"), ("negative", "negative radiance"),
                                          ("float64", "float64 values"), ("inf", "not finite")])
def test_traced_cache_sets_aside_implausible_entries(tmp_path, damage, said):
    from viewer.gl import trace_cache

    key = "k" * 64
    good = np.random.default_rng(0).uniform(0.0, 5.0, SHAPE + (4,)).astype(np.float32)
    assert trace_cache.store(key, good, tmp_path) is not None
    image, why = trace_cache.load(key, SHAPE, tmp_path)
    assert why == "" and np.array_equal(image, good)         # a plausible entry is a hit
    bad = {"huge": np.full(SHAPE + (4,), 3e38, np.float32),
           "negative": np.where(good > 4.0, -2.0, good).astype(np.float32),
           "float64": good.astype(np.float64),
           "inf": np.where(good > 4.0, np.inf, good).astype(np.float32)}[damage]
    if damage == "float64":   # store() writes float32: write the other dtype as a writer of old might
        import io
        import zipfile

        buf = io.BytesIO()
        np.save(buf, bad)
        with zipfile.ZipFile(trace_cache.path_for(key, tmp_path), "w") as z:
            z.writestr("image.npy", buf.getvalue())
    else:
        assert trace_cache.store(key, bad, tmp_path) is not None
    image, why = trace_cache.load(key, SHAPE, tmp_path)
    assert image is None and "set aside" in why and said in why and "\n" not in why, why
    assert trace_cache.path_for(key, tmp_path).with_suffix(".npz.damaged").is_file()
    assert trace_cache.load(key, SHAPE, tmp_path) == (None, "")   # gone: traced afresh


@pytest.mark.parametrize("damage, said", [("huge", "mean radiance of 3.75e+37; plausible: at most 1e+09"), ("ints", "not floats")])
def test_reference_cache_sets_aside_implausible_entries(tmp_path, damage, said):
    from viewer.reference_common import cache

    key = "r" * 64
    rng = np.random.default_rng(1)
    s = rng.uniform(0.0, 4.0, SHAPE + (3,))
    good = cache.Entry(s, s * s, 4, "cpu", 0)
    said_lines = []
    assert cache.store(key, good, tmp_path, report=said_lines.append)
    back = cache.load(key, tmp_path, SHAPE + (3,), report=said_lines.append)
    assert back is not None and back.spp == 4 and np.allclose(back.sum, s, rtol=1e-6) and said_lines == []
    path = cache.path_for(key, tmp_path)
    if damage == "huge":
        huge = np.full(SHAPE + (3,), 3e38)
        with np.errstate(over="ignore"):
            assert cache.store(key, cache.Entry(huge, huge * huge, 8, "cpu", 0), tmp_path)
    else:
        np.savez(path, sum=np.ones(SHAPE + (3,), np.int32), sum2=np.ones(SHAPE + (3,), np.int32),
                 spp=np.int64(8), engine=np.str_("cpu"), seed=np.int64(0))
    assert cache.load(key, tmp_path, SHAPE + (3,), report=said_lines.append) is None
    assert len(said_lines) == 1 and "damaged" in said_lines[0] and said in said_lines[0], said_lines
    assert path.with_name(path.name + ".damaged").is_file() and not path.exists()


def test_the_bound_is_far_above_a_bright_plausible_image(tmp_path):
    # a sharp highlight of 1e7 in one pixel is an image, not garbage
    from viewer.gl import trace_cache
    from viewer.base.io import MAX_CACHED_RADIANCE
    from viewer.reference_common import cache

    assert MAX_CACHED_RADIANCE == 1e9
    img = np.zeros(SHAPE + (4,), np.float32)
    img[2, 3] = 1e7
    trace_cache.store("b" * 64, img, tmp_path)
    assert trace_cache.load("b" * 64, SHAPE, tmp_path)[1] == ""
    s = np.zeros(SHAPE + (3,))
    s[1, 1] = 4e7   # 1e7 at 4 spp
    assert cache.entry_problem(cache.Entry(s, s * s, 4, "cpu", 0), SHAPE + (3,)) is None
    s[1, 1] = 4e9 + 1e9
    assert "mean radiance" in cache.entry_problem(cache.Entry(s, s * s, 4, "cpu", 0), SHAPE + (3,))


# ----------------------------------------------------------------------------- a BRDF returning Inf

INF_BRDF = """analytic
# returns Inf everywhere: 1 / 0
::begin parameters
float k 0 1 0.5
::end parameters
::begin shader
vec3 BRDF(vec3 L, vec3 V, vec3 N, vec3 X, vec3 Y)
{
    return vec3(1.0 / (k - k));
}
::end shader
"""

INF_SCENE = """[camera]
position = [0.0, 0.0, 4.0]
target = [0.0, 0.0, 0.0]
width = 32
height = 24

[[lights]]
position = [2.0, 3.0, 4.0]
intensity = [10.0, 10.0, 10.0]

[[objects]]
mesh = "sphere"
material = "ball"

[materials.ball]
model = "custom"
file = "inf.brdf"
"""


def test_a_brdf_returning_inf_is_named_not_the_renderer(tmp_path, capsys):
    (tmp_path / "inf.brdf").write_text(INF_BRDF)
    (tmp_path / "s.toml").write_text(INF_SCENE)
    rc, out, err = run_main(["render", str(tmp_path / "s.toml"), "--out", str(tmp_path / "o.png")], capsys)
    assert rc == 3
    assert err.count("\n") == 1, err
    assert "the BRDF of material 'ball' (custom inf.brdf)" in err and "not the renderer's" in err, err


def test_a_renderer_fault_is_not_blamed_on_the_brdf(tmp_path, monkeypatch, capsys):
    # every image with an object poisoned (the material does not matter): the object is named, no BRDF
    from viewer.gl import renderer as R

    real = R.Renderer.render_arrays

    def poisoned(self, scene, *a, **k):
        lin, srgb = real(self, scene, *a, **k)
        if scene.objects:
            lin = lin.copy()
            lin[0, :4] = np.inf
        return lin, srgb

    monkeypatch.setattr(R.Renderer, "render_arrays", poisoned)
    rc, out, err = run_main(["render", "sphere", "--out", str(tmp_path / "a.png"), "--width", "24",
                             "--height", "16", "--set", "materials.ball.preset=gold"], capsys)
    assert rc == 3
    assert err.count("\n") == 1 and "with material 'ball' (microfacet)" in err and "BRDF" not in err, err
