"""Meshes: the built-in shapes, loading every format, cleaning, normals, tangents, errors."""

from __future__ import annotations

import os
import time

import numpy as np
import pytest
import trimesh

from viewer import ViewerError

from viewer.scene import meshgen
from viewer.scene.mesh import MeshData, build_mesh, builtin_names, clear_cache, load_mesh, write_ply
from viewer.base.resources import MODEL_DIR

BUILTINS = builtin_names()
CLOSED = ["sphere", "cube", "torus", "shader_ball", "cornell_short_block", "cornell_tall_block"]


# --------------------------------------------------------------------------- helpers

def welded(m: MeshData) -> trimesh.Trimesh:
    """The mesh with vertices at the same position merged (ignoring normal / uv splits)."""
    t = trimesh.Trimesh(m.positions.astype(np.float64), m.indices.astype(np.int64), process=False)
    t.merge_vertices(merge_tex=True, merge_norm=True)
    return t


def signed_volume(m: MeshData) -> float:
    P = m.positions.astype(np.float64)
    F = m.indices.astype(np.int64)
    return float(np.einsum("ij,ij->i", P[F[:, 0]], np.cross(P[F[:, 1]], P[F[:, 2]])).sum() / 6.0)


def face_normals(m: MeshData) -> np.ndarray:
    P = m.positions.astype(np.float64)
    F = m.indices.astype(np.int64)
    return np.cross(P[F[:, 1]] - P[F[:, 0]], P[F[:, 2]] - P[F[:, 0]])


def winding_number(P: np.ndarray, F: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Generalized winding number of the triangle mesh at the query points q (Q,3):
    the sum of the signed solid angles of its triangles (Van Oosterom & Strackee 1983) / 4 pi."""
    out = np.zeros(len(q))
    A, B, C = P[F[:, 0]], P[F[:, 1]], P[F[:, 2]]
    for i, x in enumerate(q):
        a, b, c = A - x, B - x, C - x
        la, lb, lc = (np.linalg.norm(v, axis=1) for v in (a, b, c))
        num = np.einsum("ij,ij->i", a, np.cross(b, c))
        den = (la * lb * lc + np.einsum("ij,ij->i", a, b) * lc
               + np.einsum("ij,ij->i", a, c) * lb + np.einsum("ij,ij->i", b, c) * la)
        out[i] = 2.0 * np.arctan2(num, den).sum() / (4.0 * np.pi)
    return out


def small_sphere() -> trimesh.Trimesh:
    return trimesh.creation.icosphere(subdivisions=2, radius=1.0)


# --------------------------------------------------------------------------- built-ins

@pytest.mark.parametrize("name", BUILTINS)
def test_builtin_loads_with_valid_arrays(name):
    m = load_mesh(name)
    V, F = len(m.positions), len(m.indices)
    assert m.name == name
    assert m.positions.dtype == np.float32 and m.positions.shape == (V, 3)
    assert m.normals.dtype == np.float32 and m.normals.shape == (V, 3)
    assert m.tangents.dtype == np.float32 and m.tangents.shape == (V, 4)
    assert m.uvs.dtype == np.float32 and m.uvs.shape == (V, 2)
    assert m.indices.dtype == np.uint32 and m.indices.shape == (F, 3) and F > 0
    assert m.indices.max() < V
    assert np.all(np.isfinite(m.positions)) and np.all(np.isfinite(m.tangents))
    np.testing.assert_allclose(np.linalg.norm(m.normals, axis=1), 1.0, atol=1e-5)
    t = m.tangents[:, :3].astype(np.float64)
    np.testing.assert_allclose(np.linalg.norm(t, axis=1), 1.0, atol=1e-5)
    assert np.abs(np.einsum("ij,ij->i", t, m.normals)).max() < 1e-5
    assert set(np.unique(m.tangents[:, 3])) <= {-1.0, 1.0}
    lo, hi = m.bounds()
    assert np.all(lo <= hi)
    # every face has a real area
    assert np.linalg.norm(face_normals(m), axis=1).min() > 0.0


@pytest.mark.parametrize("name", BUILTINS)
def test_builtin_faces_wind_like_their_normals(name):
    """Counter-clockwise around the vertex normals: the geometric normal of every face
    agrees with the normals at its corners."""
    m = load_mesh(name)
    fn = face_normals(m)
    vn = m.normals.astype(np.float64)[m.indices.astype(np.int64)].sum(axis=1)
    assert np.all(np.einsum("ij,ij->i", fn, vn) > 0.0)


@pytest.mark.parametrize("name", BUILTINS)
def test_builtin_normals_point_out_of_the_solid(name):
    """Crossing the surface along the normal, the winding number drops by one: the normal
    points from inside to outside (holds for open surfaces and for the teapot too)."""
    m = load_mesh(name)
    P = m.positions.astype(np.float64)
    F = m.indices.astype(np.int64)
    rng = np.random.default_rng(1)
    pick = rng.choice(len(F), size=min(40, len(F)), replace=False)
    centre = P[F[pick]].mean(axis=1)
    n = m.normals.astype(np.float64)[F[pick]].sum(axis=1)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    eps = 1e-4 * np.linalg.norm(P.max(0) - P.min(0))
    jump = winding_number(P, F, centre - eps * n) - winding_number(P, F, centre + eps * n)
    np.testing.assert_allclose(jump, 1.0, atol=0.05)


@pytest.mark.parametrize("name", CLOSED)
def test_closed_builtins_are_watertight_with_positive_volume(name):
    m = load_mesh(name)
    t = welded(m)
    assert t.is_watertight
    assert t.is_winding_consistent
    assert signed_volume(m) > 0.0


def test_sphere_is_a_level_5_icosphere_with_exact_normals():
    m = load_mesh("sphere")
    assert len(m.indices) == 20480
    np.testing.assert_allclose(np.linalg.norm(m.positions, axis=1), 1.0, atol=1e-6)
    np.testing.assert_allclose(m.normals, m.positions, atol=1e-6)
    assert abs(signed_volume(m) - 4.0 / 3.0 * np.pi) < 0.01


def test_shape_volumes_and_extents():
    assert abs(signed_volume(load_mesh("cube")) - 8.0) < 1e-5
    lo, hi = load_mesh("cube").bounds()
    np.testing.assert_allclose(lo, -1.0)
    np.testing.assert_allclose(hi, 1.0)
    torus = load_mesh("torus")
    exact = 2.0 * np.pi ** 2 * 0.7 * 0.3 ** 2
    assert abs(signed_volume(torus) - exact) / exact < 0.01
    lo, hi = torus.bounds()
    np.testing.assert_allclose([lo[1], hi[1]], [-0.3, 0.3], atol=1e-6)
    np.testing.assert_allclose([hi[0], hi[2]], [1.0, 1.0], atol=1e-3)
    plane = load_mesh("plane")
    assert np.all(plane.positions[:, 1] == 0.0)
    np.testing.assert_allclose(plane.normals, np.tile([0.0, 1.0, 0.0], (len(plane.normals), 1)))
    ball = load_mesh("shader_ball")
    assert ball.bounds()[0][1] == 0.0                    # stands on y = 0
    teapot = load_mesh("teapot")
    np.testing.assert_allclose(np.linalg.norm(teapot.positions, axis=1).max(), 1.0, atol=1e-6)
    lo, hi = teapot.bounds()
    assert abs(lo[1] + hi[1]) < 1e-6                     # centred in y
    assert hi[0] > -lo[0]                                 # spout on +x, handle on -x


def test_teapot_is_welded_and_has_only_the_classic_openings():
    """Patch seams and the poles are welded: the only open edges are the 8 classic
    boundary loops (rim inside, lid edge, spout tip and base, the handle's two ends)."""
    m = load_mesh("teapot")
    t = welded(m)
    assert len(t.vertices) == len(m.positions)           # nothing left to weld
    edges = np.sort(t.edges, axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    assert counts.max() == 2
    n = 16
    # rim inside and lid edge: 4 patches each; spout tip and base, handle ends: 2 each
    assert (counts == 1).sum() == 4 * n + 4 * n + 4 * (2 * n)
    # the lid's knob and the bottom: a single pole vertex each, normal straight up / down
    top = np.argmax(m.positions[:, 1])
    np.testing.assert_allclose(m.normals[top], [0.0, 1.0, 0.0], atol=1e-4)
    bottom = np.argmin(m.positions[:, 1] + 1e-3 * np.abs(m.positions[:, 0]) + 1e-3 * np.abs(m.positions[:, 2]))
    np.testing.assert_allclose(m.normals[bottom], [0.0, -1.0, 0.0], atol=1e-4)


def test_teapot_every_patch_points_out():
    """dP/du x dP/dv of each of Newell's 32 patches points out of the pot (the winding
    number drops by one across the surface at each patch's centre)."""
    ctrl, patches = meshgen.teapot_data()
    shape = meshgen.teapot(8)
    # data (z up, bottom at z = 0, knob top at z = 3.15) -> mesh: rotate to y up, shift, scale
    rot = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
    y_lo, y_hi = shape.positions[:, 1].min(), shape.positions[:, 1].max()
    scale = (y_hi - y_lo) / 3.15
    b, db = meshgen.bernstein(np.array([0.37]))
    C, N = [], []
    for patch in patches:
        G = ctrl[patch]
        p = np.einsum("ai,bj,ijk->k", b, b, G)
        n = np.cross(np.einsum("ai,bj,ijk->k", b, db, G), np.einsum("ai,bj,ijk->k", db, b, G))
        C.append((p @ rot.T) * scale + [0.0, y_lo, 0.0])
        N.append((n / np.linalg.norm(n)) @ rot.T)
    C, N = np.array(C), np.array(N)
    eps = 1e-3
    jump = winding_number(shape.positions, shape.indices, C - eps * N) - \
        winding_number(shape.positions, shape.indices, C + eps * N)
    np.testing.assert_allclose(jump, 1.0, atol=0.1)


def test_cornell_pieces_face_into_the_room():
    room = load_mesh("cornell_room")
    lo, hi = room.bounds()
    np.testing.assert_allclose(lo, [-1.0, 0.0, -1.0])
    np.testing.assert_allclose(hi, [1.0, 2.0, 1.0])
    centre = np.array([0.0, 1.0, 0.0])
    for name in ("cornell_room", "cornell_left", "cornell_right"):
        m = load_mesh(name)
        assert np.all(np.einsum("ij,ij->i", m.normals, centre - m.positions) > 0.0), name
    np.testing.assert_allclose(load_mesh("cornell_left").normals, np.tile([1, 0, 0], (4, 1)))
    np.testing.assert_allclose(load_mesh("cornell_right").normals, np.tile([-1, 0, 0], (4, 1)))
    light = load_mesh("cornell_light")
    np.testing.assert_allclose(light.normals, np.tile([0, -1, 0], (len(light.normals), 1)))
    assert 1.9 < light.positions[:, 1].min() < 2.0
    for name in ("cornell_short_block", "cornell_tall_block"):
        m = load_mesh(name)
        lo, hi = m.bounds()
        assert abs(lo[1]) < 1e-6 and np.all(lo >= -1.0) and np.all(hi <= [1.0, 2.0, 1.0])
        # flat normals: 6 distinct directions, one per side
        assert len(np.unique(np.round(m.normals, 4), axis=0)) == 6


def test_generated_models_match_the_generators():
    """models/<name>.ply (what ships) equals the in-memory generator's output."""
    for name in BUILTINS:
        path = MODEL_DIR / f"{name}.ply"
        assert path.is_file(), f"{path} missing: run python models/generate.py"
        from_file = load_mesh(name)
        shape = meshgen.generate(name)
        in_memory = build_mesh(name, shape.positions, shape.normals, shape.indices, shape.uvs)
        assert from_file.indices.shape == in_memory.indices.shape, name
        np.testing.assert_array_equal(from_file.indices, in_memory.indices)
        np.testing.assert_allclose(from_file.positions, in_memory.positions, atol=1e-6)
        np.testing.assert_allclose(from_file.normals, in_memory.normals, atol=1e-6)
        np.testing.assert_allclose(from_file.uvs, in_memory.uvs, atol=1e-6)
        np.testing.assert_allclose(from_file.tangents, in_memory.tangents, atol=1e-6)


def test_builtin_without_a_file_is_generated_in_memory(tmp_path, monkeypatch):
    import viewer.scene.mesh as vm
    reference = load_mesh("torus")
    monkeypatch.setattr(vm, "MODEL_DIR", tmp_path)         # no .ply there
    clear_cache()
    try:
        generated = load_mesh("torus")
    finally:
        clear_cache()
    np.testing.assert_array_equal(generated.indices, reference.indices)
    np.testing.assert_allclose(generated.positions, reference.positions, atol=1e-6)
    np.testing.assert_allclose(generated.normals, reference.normals, atol=1e-6)


def test_models_stay_small():
    total = sum(p.stat().st_size for p in MODEL_DIR.glob("*.ply"))
    assert total < 5 * 1024 * 1024


def test_ply_name_of_a_builtin_falls_back_to_it(tmp_path):
    m = load_mesh("sphere.ply", base_dir=tmp_path)
    assert len(m.indices) == 20480


# --------------------------------------------------------------------------- tangents

def test_tangents_follow_uvs_and_fallback_agrees():
    plane = load_mesh("plane")                            # u runs along +x
    np.testing.assert_allclose(plane.tangents, np.tile([1.0, 0.0, 0.0, 1.0], (len(plane.tangents), 1)), atol=1e-6)
    sphere = load_mesh("sphere")                          # no uvs: t = normalize(cross(y, n))
    n = sphere.normals.astype(np.float64)
    expect = np.cross([0.0, 1.0, 0.0], n)
    ok = np.linalg.norm(expect, axis=1) > 1e-3
    expect = expect[ok] / np.linalg.norm(expect[ok], axis=1, keepdims=True)
    np.testing.assert_allclose(sphere.tangents[ok, :3], expect, atol=1e-5)
    # the torus's uvs run around the y axis: on its outer half (normal pointing away from
    # the axis) that is the fallback's direction, on the inner half the opposite one
    torus = load_mesh("torus")
    n = torus.normals.astype(np.float64)
    fb = np.cross([0.0, 1.0, 0.0], n)
    ok = np.linalg.norm(fb, axis=1) > 1e-3
    fb = fb[ok] / np.linalg.norm(fb[ok], axis=1, keepdims=True)
    outward = np.einsum("ij,ij->i", n[ok][:, [0, 2]], torus.positions[ok][:, [0, 2]]) > 0.0
    dot = np.einsum("ij,ij->i", fb, torus.tangents[ok, :3])
    assert dot[outward].min() > 0.999 and dot[~outward].max() < -0.999


def test_tangent_fallback_at_the_poles_and_mirrored_uvs():
    P = np.array([[0, 0, 0], [1, 0, 0], [0, 0, -1]], dtype=np.float64)
    N = np.tile([0.0, 1.0, 0.0], (3, 1))
    m = build_mesh("tri", P, N, [[0, 1, 2]])            # no uvs, n parallel to y
    np.testing.assert_allclose(m.tangents, np.tile([1, 0, 0, 1], (3, 1)), atol=1e-6)
    m = build_mesh("tri", P, N, [[0, 1, 2]], uvs=[[0, 0], [1, 0], [0, 1]])
    np.testing.assert_allclose(m.tangents, np.tile([1, 0, 0, 1], (3, 1)), atol=1e-6)
    m = build_mesh("tri", P, N, [[0, 1, 2]], uvs=[[0, 0], [1, 0], [0, -1]])   # v mirrored
    np.testing.assert_allclose(m.tangents, np.tile([1, 0, 0, -1], (3, 1)), atol=1e-6)
    m = build_mesh("tri", P, N, [[0, 1, 2]], uvs=np.zeros((3, 2)))             # degenerate uvs
    np.testing.assert_allclose(m.tangents, np.tile([1, 0, 0, 1], (3, 1)), atol=1e-6)


# --------------------------------------------------------------------------- formats

@pytest.mark.parametrize("ext", ["obj", "ply", "stl", "off", "glb"])
def test_round_trip_each_format(tmp_path, ext):
    src = small_sphere()
    path = tmp_path / f"ball.{ext}"
    src.export(path)
    m = load_mesh(path.name, base_dir=tmp_path)
    assert m.name == "ball"
    assert len(m.indices) == len(src.faces)
    np.testing.assert_allclose(m.bounds()[0], src.bounds[0], atol=1e-5)
    np.testing.assert_allclose(m.bounds()[1], src.bounds[1], atol=1e-5)
    assert abs(welded(m).area - src.area) < 1e-4
    assert abs(signed_volume(m) - src.volume) < 1e-4
    # file normals or computed smooth ones: both close to the sphere's
    p = m.positions / np.linalg.norm(m.positions, axis=1, keepdims=True)
    assert np.einsum("ij,ij->i", p, m.normals).min() > 0.98
    assert welded(m).is_watertight


def test_gltf_scene_is_flattened_with_transforms(tmp_path):
    scene = trimesh.Scene()
    box = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    scene.add_geometry(box, node_name="a", transform=trimesh.transformations.translation_matrix([3.0, 0.0, 0.0]))
    mirror = np.diag([-1.0, 1.0, 1.0, 1.0])
    mirror[:3, 3] = [-3.0, 0.0, 0.0]
    scene.add_geometry(box.copy(), node_name="b", transform=mirror)
    scene.add_geometry(box.copy(), node_name="c", transform=trimesh.transformations.rotation_matrix(
        np.pi / 4, [0, 1, 0], point=[0, 0, 0]) @ trimesh.transformations.translation_matrix([0, 2.0, 0]))
    path = tmp_path / "scene.glb"
    scene.export(path)
    m = load_mesh(str(path))
    assert len(m.indices) == 3 * 12
    lo, hi = m.bounds()
    np.testing.assert_allclose([lo[0], hi[0]], [-3.5, 3.5], atol=1e-5)
    np.testing.assert_allclose(hi[1], 2.5, atol=1e-5)
    assert abs(signed_volume(m) - 3.0) < 1e-4               # mirrored part still outward
    fn = face_normals(m)
    vn = m.normals.astype(np.float64)[m.indices.astype(np.int64)].sum(axis=1)
    assert np.all(np.einsum("ij,ij->i", fn, vn) > 0.0)

    files = scene.export(file_type="gltf")                   # .gltf + external buffer
    for name, data in files.items():
        (tmp_path / name).write_bytes(data)
    m2 = load_mesh("model.gltf", base_dir=tmp_path)
    np.testing.assert_allclose(m2.bounds()[0], lo, atol=1e-5)
    np.testing.assert_allclose(m2.bounds()[1], hi, atol=1e-5)


def test_obj_split_normals_survive(tmp_path):
    """A flat-shaded OBJ (one vn per face) keeps its split normals: no vertex merging
    across different normals, and no smoothing."""
    lines = ["v -1 -1 -1", "v 1 -1 -1", "v 1 1 -1", "v -1 1 -1",
             "v -1 -1 1", "v 1 -1 1", "v 1 1 1", "v -1 1 1",
             "vn 0 0 -1", "vn 0 0 1", "vn -1 0 0", "vn 1 0 0", "vn 0 -1 0", "vn 0 1 0"]
    quads = [((1, 4, 3, 2), 1), ((5, 6, 7, 8), 2), ((1, 5, 8, 4), 3),
             ((2, 3, 7, 6), 4), ((1, 2, 6, 5), 5), ((4, 8, 7, 3), 6)]
    for q, n in quads:
        lines.append("f " + " ".join(f"{v}//{n}" for v in q))
    path = tmp_path / "flat.obj"
    path.write_text("\n".join(lines) + "\n")
    m = load_mesh(str(path))
    assert len(m.indices) == 12
    assert len(m.positions) == 24
    fn = face_normals(m)
    fn /= np.linalg.norm(fn, axis=1, keepdims=True)
    for k in range(3):                                   # every corner has its face's normal
        np.testing.assert_allclose(m.normals[m.indices[:, k]], fn, atol=1e-6)
    assert signed_volume(m) > 0


def test_obj_with_uvs_and_normals_keeps_both(tmp_path):
    path = tmp_path / "quad.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 1 0 -1\nv 0 0 -1\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
                    "vn 0.6 0.8 0\nf 1/1/1 2/2/1 3/3/1 4/4/1\n")
    m = load_mesh(str(path))
    np.testing.assert_allclose(m.normals, np.tile([0.6, 0.8, 0.0], (4, 1)), atol=1e-6)
    assert len(np.unique(m.uvs, axis=0)) == 4
    t = m.tangents[:, :3]
    assert np.abs(np.einsum("ij,ij->i", t, m.normals)).max() < 1e-6


def test_ply_file_normals_are_kept(tmp_path):
    """nx/ny/nz of a PLY are used as they are (here deliberately not the smooth ones),
    also when the file has uvs."""
    P = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [7, 7, 7]], dtype=np.float64)
    N = np.array([[0.0, 0.6, 0.8]] * 5)
    F = np.array([[0, 1, 2], [2, 1, 3]])
    path = tmp_path / "tilted.ply"
    write_ply(path, P, N, F, uvs=P[:, :2])
    m = load_mesh(str(path))
    assert len(m.positions) == 4                          # the unused vertex is gone
    np.testing.assert_allclose(m.normals, np.tile([0.0, 0.6, 0.8], (4, 1)), atol=1e-6)
    np.testing.assert_allclose(m.uvs, P[:4, :2], atol=1e-6)


def test_missing_normals_get_smooth_area_weighted_ones(tmp_path):
    src = small_sphere()
    path = tmp_path / "ball.off"                          # OFF has no normals
    src.export(path)
    m = load_mesh(str(path))
    expect = m.positions / np.linalg.norm(m.positions, axis=1, keepdims=True)
    assert np.einsum("ij,ij->i", expect, m.normals).min() > 0.99
    # a triangle soup (STL) is welded for smoothing: vertices are shared again
    path = tmp_path / "ball.stl"
    src.export(path)
    m = load_mesh(str(path))
    assert len(m.positions) == len(src.vertices)
    # area weighting: a vertex shared by a large and a small face leans to the large one
    P = np.array([[0, 0, 0], [4, 0, 0], [0, 0, -4], [0, -1, 0], [1, 0, 0]], dtype=np.float64)
    m = build_mesh("w", P, None, [[0, 1, 2], [0, 3, 4]])
    n0 = m.normals[0]
    big, small = np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0])
    assert n0 @ big > n0 @ small > 0.0


def test_degenerate_faces_are_dropped(tmp_path):
    path = tmp_path / "degenerate.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\nv 1e-12 1e-12 0\n"
                    "f 1 2 3\n"        # fine
                    "f 1 1 2\n"        # repeated index
                    "f 1 2 4\n"        # collinear: zero area
                    "f 1 5 2\n")       # near-zero area
    m = load_mesh(str(path))
    assert len(m.indices) == 1
    assert len(m.positions) == 3                          # unused vertices removed
    np.testing.assert_allclose(m.normals, np.tile([0.0, 0.0, 1.0], (3, 1)), atol=1e-6)


def test_loading_is_cached_and_sees_changes(tmp_path, monkeypatch):
    import viewer.scene.mesh as vm
    reads = []
    real = vm.read_mesh_file
    monkeypatch.setattr(vm, "read_mesh_file", lambda *a, **k: reads.append(a[0]) or real(*a, **k))
    path = tmp_path / "ball.ply"
    small_sphere().export(path)
    clear_cache()
    a = load_mesh(str(path))
    b = load_mesh("ball.ply", base_dir=tmp_path)          # same file, other spelling
    assert len(reads) == 1
    # one object for the same file: what is made per mesh (GPU buffers, shadows, the BVH's key)
    # is made once; its arrays are read-only, and a copy is the caller's own to edit
    assert a is b
    with pytest.raises(ValueError):
        a.positions[:] = 0.0
    mine = a.copy()
    mine.positions[:] = 0.0
    assert np.any(load_mesh(str(path)).positions != 0.0)
    assert len(reads) == 1
    trimesh.creation.box().export(path)                   # changed file: read again
    os.utime(path, ns=(time.time_ns(), time.time_ns() + 10**9))
    assert len(load_mesh(str(path)).indices) == 12
    assert len(reads) == 2


@pytest.mark.parametrize("ext", ["obj", "ply", "glb"])
def test_file_normals_survive_each_format(tmp_path, ext):
    """Normals stored in the file are used as they are, not recomputed (here: tilted
    normals that no smoothing would produce)."""
    src = small_sphere()
    tilted = src.vertices + np.array([0.0, 0.5, 0.0])
    tilted /= np.linalg.norm(tilted, axis=1, keepdims=True)
    mesh = trimesh.Trimesh(src.vertices, src.faces, vertex_normals=tilted, process=False)
    path = tmp_path / f"tilted.{ext}"
    mesh.export(path, **({"include_normals": True} if ext == "obj" else {}))
    m = load_mesh(str(path))
    # match loaded vertices to source vertices by position
    d = np.linalg.norm(m.positions[:, None, :] - src.vertices[None, :, :], axis=2)
    nearest = d.argmin(axis=1)
    assert d.min(axis=1).max() < 1e-5
    np.testing.assert_allclose(m.normals, tilted[nearest], atol=1e-4)


# --------------------------------------------------------------------------- errors

def expect_error(ref, *needles, **kw):
    with pytest.raises(ViewerError) as info:
        load_mesh(ref, **kw)
    msg = str(info.value)
    assert "\n" not in msg
    for needle in needles:
        assert needle in msg, msg
    return msg


def test_nan_coordinates_are_rejected(tmp_path):
    path = tmp_path / "nan.obj"
    path.write_text("v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    expect_error(str(path), "nan.obj", "NaN")
    path = tmp_path / "inf.ply"
    write_ply(path, [[np.inf, 0, 0], [1, 0, 0], [0, 1, 0]], np.zeros((3, 3)), [[0, 1, 2]])
    expect_error(str(path), "inf.ply", "infinite")


def test_empty_file_is_rejected(tmp_path):
    for name in ("empty.obj", "empty.ply", "empty.stl", "empty.glb"):
        (tmp_path / name).write_bytes(b"")
        expect_error(name, name, "empty", base_dir=tmp_path)


def test_file_without_faces_is_rejected(tmp_path):
    path = tmp_path / "points.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")
    expect_error(str(path), "points.obj", "empty mesh")
    path = tmp_path / "flat.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n")
    expect_error(str(path), "flat.obj", "no faces left")


def test_truncated_binary_ply_is_rejected(tmp_path):
    data = (MODEL_DIR / "torus.ply").read_bytes()
    path = tmp_path / "truncated.ply"
    path.write_bytes(data[: len(data) // 2])
    expect_error(str(path), "truncated.ply")


@pytest.mark.parametrize("ext", ["obj", "ply", "stl", "off", "glb", "gltf"])
def test_garbage_file_is_rejected(tmp_path, ext):
    rng = np.random.default_rng(7)
    path = tmp_path / f"garbage.{ext}"
    path.write_bytes(rng.integers(0, 256, 4096, dtype=np.uint8).tobytes())
    expect_error(str(path), f"garbage.{ext}")
    path.write_text("this is not a mesh\n" * 20)
    expect_error(str(path), f"garbage.{ext}")


def test_missing_file_is_rejected(tmp_path):
    msg = expect_error("nowhere.obj", "nowhere.obj", "not found", base_dir=tmp_path, where="scene.toml: objects[0].mesh")
    assert msg.startswith("scene.toml: objects[0].mesh: ")
    assert str(tmp_path) in msg


def test_unsupported_extension_is_rejected(tmp_path):
    path = tmp_path / "model.fbx"
    path.write_bytes(b"whatever")
    msg = expect_error(str(path), "model.fbx", "unsupported extension", ".obj", ".glb", "sphere")
    assert msg.startswith("mesh: ")
    expect_error("not_a_builtin", "not_a_builtin", "built-in", base_dir=tmp_path)


def test_out_of_range_indices_are_rejected(tmp_path):
    with pytest.raises(ViewerError, match="out of range"):
        build_mesh("bad", np.zeros((3, 3)), None, [[0, 1, 5]])


def test_a_scene_loaded_again_shares_its_meshes():
    """A scene opened again (a lecture step revisited, the default scene after the tour) gets the
    same mesh objects: the window's buffers, shadow atlas and BVH key, which follow a mesh
    object, are not made again for the same geometry."""
    from viewer.scene import load_scene

    first, again = load_scene("default"), load_scene("default")
    assert first is not again
    assert all(a.mesh_data is b.mesh_data for a, b in zip(first.objects, again.objects))
