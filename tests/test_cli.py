"""The command line (README.md, "Commands"): outputs, exit status, one-line errors and no partial
files on bad input."""

import subprocess
import sys
import textwrap

import numpy as np
import pytest

from viewer import brdf


def run(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "viewer", *map(str, args)], capture_output=True,
                          text=True, timeout=300, cwd=cwd)


def test_render_png_and_linear(tmp_path):
    out, lin = tmp_path / "a.png", tmp_path / "a.npy"
    r = run("render", "sphere", "--out", out, "--linear", lin, "--width", 96, "--height", 64)
    assert r.returncode == 0, r.stderr
    from PIL import Image

    img = Image.open(out)
    assert img.size == (96, 64) and img.mode == "RGB"
    a = np.load(lin)
    assert a.shape == (64, 96, 3) and a.dtype == np.float32
    assert np.isfinite(a).all() and a.max() > 0
    # PNG = sRGB encoding of the linear image (exposure 0, no tone mapping): check the curve
    srgb = np.asarray(img).astype(float) / 255
    lin_c = np.clip(a, 0, 1)
    enc = np.where(lin_c <= 0.0031308, 12.92 * lin_c, 1.055 * lin_c ** (1 / 2.4) - 0.055)
    assert np.abs(srgb - enc).max() <= 1.0 / 255 + 1e-6


def test_render_set_override_changes_image(tmp_path):
    a, b = tmp_path / "a.npy", tmp_path / "b.npy"
    assert run("render", "sphere", "--out", tmp_path / "a.png", "--linear", a, "--width", 32, "--height", 32).returncode == 0
    r = run("render", "sphere", "--out", tmp_path / "b.png", "--linear", b, "--width", 32, "--height", 32,
            "--set", "materials.ball.albedo=[0.1, 0.1, 0.1]")
    assert r.returncode == 0, r.stderr
    assert np.load(b).sum() < np.load(a).sum()


BAD = {
    "typo_key": ("[camera]\nfov = 40.0\n", "camera.fov"),
    "bad_type": ("[camera]\nfov_y = \"wide\"\n", "camera.fov_y"),
    "out_of_range": ("[camera]\nfov_y = 200.0\n", "camera.fov_y"),
    "unknown_model": ("[materials.m]\nmodel = \"lambertt\"\n", "materials.m.model"),
    "unknown_material": ("", "objects[0].material"),
    "missing_mesh_file": ("", "objects[0].mesh"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_scene_exit_2_one_line_no_output(tmp_path, case):
    extra, field = BAD[case]
    mesh = "nothere.obj" if case == "missing_mesh_file" else "sphere"
    material = "nope" if case == "unknown_material" else "m"
    body = extra + textwrap.dedent(f"""
        [[objects]]
        mesh = "{mesh}"
        material = "{material}"
        """)
    if "[materials.m]" not in body:
        body += '\n[materials.m]\nmodel = "lambert"\n'
    scene = tmp_path / "bad.toml"
    scene.write_text(body)
    out = tmp_path / "out.png"
    r = run("render", scene, "--out", out)
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1, r.stderr
    assert "bad.toml" in lines[0] and field in lines[0], lines[0]
    assert "Traceback" not in r.stderr
    assert not out.exists()
    assert list(tmp_path.iterdir()) == [scene]  # no partial or temporary file either


def test_broken_mesh_file_gives_message(tmp_path):
    (tmp_path / "broken.ply").write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 100\n")
    (tmp_path / "s.toml").write_text('[[objects]]\nmesh = "broken.ply"\nmaterial = "m"\n[materials.m]\nmodel = "lambert"\n')
    r = run("render", tmp_path / "s.toml", "--out", tmp_path / "o.png")
    assert r.returncode == 2
    assert "broken.ply" in r.stderr and "Traceback" not in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1


def test_bad_set_and_bad_output_path(tmp_path):
    r = run("render", "sphere", "--out", tmp_path / "o.png", "--set", "materials.ball.albdo=0.5")
    assert r.returncode == 2 and "albdo" in r.stderr
    r = run("render", "sphere", "--out", tmp_path / "o.jpg")
    assert r.returncode == 2 and ".png" in r.stderr
    r = run("render", "sphere", "--out", tmp_path / "missing_dir" / "o.png")
    assert r.returncode == 2 and "does not exist" in r.stderr
    assert not any(tmp_path.iterdir())


def test_models_lists_registry():
    r = run("models")
    assert r.returncode == 0
    for name in brdf.names():
        assert f"{name}:" in r.stdout
    assert "albedo (rgb) default" in r.stdout


def test_truncated_hdr_environment_exit_2(tmp_path):
    from viewer.environment.io import save_environment

    good = tmp_path / "good.hdr"
    save_environment(good, np.random.default_rng(0).random((32, 64, 3)).astype(np.float32))
    (tmp_path / "cut.hdr").write_bytes(good.read_bytes()[: len(good.read_bytes()) // 2])
    (tmp_path / "s.toml").write_text('[environment]\nmap = "cut.hdr"\n[[objects]]\nmesh = "sphere"\n'
                                     'material = "m"\n[materials.m]\nmodel = "lambert"\n')
    out = tmp_path / "o.png"
    for cmd in ("render", "reference"):
        extra = ["--spp", "1"] if cmd == "reference" else []
        r = run(cmd, tmp_path / "s.toml", "--out", out, *extra)
        assert r.returncode == 2, (cmd, r.stderr)
        lines = [l for l in r.stderr.strip().splitlines() if l.startswith("brdf-viewer")]
        assert len(lines) == 1 and "cut.hdr" in lines[0], r.stderr
        assert "Traceback" not in r.stderr and not out.exists()


def test_screenshot_reopens_as_the_same_scene(tmp_path):
    """A PNG written by render holds its scene: rendering the PNG gives the identical image."""
    a, b = tmp_path / "a.png", tmp_path / "b.png"
    assert run("render", "gallery", "--out", a, "--linear", tmp_path / "a.npy", "--width", 96, "--height", 54,
               "--set", 'materials.gold.alpha=0.4').returncode == 0
    r = run("render", a, "--out", b, "--linear", tmp_path / "b.npy")
    assert r.returncode == 0, r.stderr
    assert np.array_equal(np.load(tmp_path / "a.npy"), np.load(tmp_path / "b.npy"))
    from PIL import Image

    Image.new("RGB", (4, 4)).save(tmp_path / "plain.png")
    r = run("render", tmp_path / "plain.png", "--out", tmp_path / "c.png")
    assert r.returncode == 2 and "holds no scene" in r.stderr


def test_compare_writes_images_and_consistent_metrics(tmp_path):
    import json

    out = tmp_path / "cmp"
    r = run("compare", "sphere", "--spp", 8, "--out", out, "--width", 40, "--height", 40, "--max-depth", 1)
    assert r.returncode == 0, r.stderr
    for name in ("raster.png", "reference.png", "diff_abs.png", "diff_rel.png", "raster.npy", "reference.npy",
                 "metrics.json"):
        assert (out / name).is_file(), name
    m = json.loads((out / "metrics.json").read_text())
    a, b = np.load(out / "raster.npy"), np.load(out / "reference.npy")
    d2 = (a.astype(float) - b) ** 2
    assert np.isclose(m["rmse"], np.sqrt(d2.mean()))
    assert np.isclose(m["relative_mse"], (d2 / (b.astype(float) ** 2 + 1e-2)).mean())
    assert np.allclose(m["mean_reference_per_channel"], b.mean(axis=(0, 1)), rtol=1e-6)
    # direct light from one point light on a Lambert sphere: raster and reference agree closely
    assert m["rmse"] < 0.02
    r = run("compare", "sphere", "--spp", 0, "--out", tmp_path / "x")
    assert r.returncode == 2 and "--spp" in r.stderr and not (tmp_path / "x").exists()
