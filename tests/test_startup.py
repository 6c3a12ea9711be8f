"""What the window's first frame does not need stays out of the start-up: the built-in meshes are
read without trimesh (and its scipy), Beckmann's scipy functions load on first use, and the
multiple-scattering DFG table is made only for a compensated specular material."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from viewer.scene import meshgen
from viewer.scene.mesh import read_own_ply, write_ply
from viewer.base.resources import MODEL_DIR

ROOT = Path(__file__).resolve().parent.parent


@pytest.mark.parametrize("name", sorted(meshgen.GENERATORS))
def test_own_ply_reader_agrees_with_trimesh(name):
    from viewer.scene.mesh import load_mesh  # noqa: F401  (trimesh comes through viewer.base.optional)
    import trimesh

    path = MODEL_DIR / f"{name}.ply"
    pos, nrm, uvs, faces = read_own_ply(path)
    ref = trimesh.load(str(path), process=False, fix_texture=False)
    np.testing.assert_array_equal(pos, np.asarray(ref.vertices))
    np.testing.assert_array_equal(faces, np.asarray(ref.faces))
    np.testing.assert_array_equal(nrm, np.asarray(ref.vertex_normals))
    # uvs: what the generator wrote (trimesh's PLY reader alters a few pole uvs of shader_ball)
    shape = meshgen.generate(name)
    if shape.uvs is None:
        assert uvs is None
    else:
        np.testing.assert_array_equal(uvs, np.asarray(shape.uvs, dtype=np.float32))


def test_own_ply_reader_declines_other_files(tmp_path):
    f = tmp_path / "a.ply"
    write_ply(f, [[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 0, 1]] * 3, [[0, 1, 2]])
    assert read_own_ply(f) is not None
    data = f.read_bytes()
    (tmp_path / "b.ply").write_bytes(data.replace(b"comment brdf-viewer", b"comment somebody-else"))
    assert read_own_ply(tmp_path / "b.ply") is None
    (tmp_path / "c.ply").write_bytes(data[:-1])  # truncated
    assert read_own_ply(tmp_path / "c.ply") is None
    (tmp_path / "d.ply").write_bytes(b"ply\nformat ascii 1.0\nend_header\n")
    assert read_own_ply(tmp_path / "d.ply") is None


def test_default_scene_loads_without_trimesh_or_scipy():
    code = ("import sys, viewer.scene as s; sc = s.load_scene('default'); "
            "from viewer.gl.renderer import Renderer; import viewer.app.main; "
            "print(sorted(m for m in ('trimesh', 'scipy', 'scipy.special') if m in sys.modules))")
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    r = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "[]", r.stdout


def test_first_frame_of_the_default_scene_makes_no_dfg_table(gl_ctx, monkeypatch):
    """The CPU DFG table (seconds of numpy) serves only the multiple-scattering compensation of a
    specular material; the default scene (Lambert, no compensation) must not make it."""
    from viewer.scene.camera import OrbitCamera
    from viewer.environment import dfg
    from viewer.gl.renderer import Renderer
    from viewer.scene import load_scene

    def refuse(*a, **k):
        raise AssertionError("dfg_table was computed")

    monkeypatch.setattr(dfg, "dfg_table", refuse)
    monkeypatch.setattr(dfg, "stored_dfg_table", refuse)  # nor read it from the disk cache
    # the renderer keeps the table once made (an earlier test in the session may have made it)
    from viewer.brdf import ms_compensation
    monkeypatch.setattr(ms_compensation, "_DFG", None)
    scene = load_scene("default", ["camera.width=32", "camera.height=18"])
    r = Renderer(gl_ctx)
    try:
        lin, _ = r.render_arrays(scene, OrbitCamera.from_scene(scene))
        assert np.isfinite(lin).all() and lin.mean() > 0
        # a compensated microfacet lobe does not either (its E_ss is its own F = 1 albedo table)...
        settings = ["camera.width=16", "camera.height=16", "render.ms_compensation=true",
                    "render.ibl=\"split_sum\"", "environment.constant=[0.5,0.5,0.5]"]
        micro = load_scene("sphere", settings + ['materials.ball={model="microfacet", alpha=0.5}'])
        assert np.isfinite(r.render_arrays(micro, OrbitCamera.from_scene(micro))[0]).all()
        # ...but a compensated lobe without a Fresnel factor does (so the refusal above can fire)
        glossy = load_scene("sphere", settings + ['materials.ball={model="phong", shininess=50}'])
        with pytest.raises(AssertionError, match="dfg_table was computed"):
            r.render_arrays(glossy, OrbitCamera.from_scene(glossy))
    finally:
        r.release()
