"""Fuzzed inputs for the hardening tests (tests/test_fuzz.py) and benchmarks/hardening.py.

Every generator is driven by a ``numpy.random.Generator`` so a seed gives the same cases. A
case is fed to a loader (``viewer.scene.load_scene``, ``viewer.scene.mesh.load_mesh``,
``viewer.environment.io.load_environment``); the loader must either succeed with sane output
or raise exactly one ``ViewerError`` whose message is one line. ``check_*`` return "ok" or
"error" and raise ``FuzzFailure`` (with the case's description) for anything else: another
exception type, a multi-line or empty message, or a "successful" result that is not sane
(NaN in a mesh, a scene that does not save and load back the same).
"""

from __future__ import annotations

import copy
import datetime
import math
import struct
import traceback
from pathlib import Path

import numpy as np

from viewer import ViewerError

try:  # Python >= 3.11
    import tomllib
except ModuleNotFoundError:  # pragma: no cover
    import tomli as tomllib

import tomli_w


class FuzzFailure(AssertionError):
    pass


SPECIAL_NUMBERS = (math.nan, math.inf, -math.inf, -1, -1.0, -1e-300, 0, 0.0, -0.0, 5e-324, 1e-320,
                   1e-30, 0.5, 1, 1.0, 3, 255, 65536, 1e6, 1e18, 1e30, 1e38, 3.5e38, 1e300, 1e308,
                   -1e308, 2 ** 31, 2 ** 63 - 1, -2 ** 63, 2 ** 64, 10 ** 30)
OTHER_VALUES = ("", " ", "x", "nan", "sphere", "ggx", "../../etc/passwd", "\u00e9\u6f22", "a" * 300,
                "a\x00.obj", "~nobody_xyz_/a.ply", "x" * 300 + ".obj", "y" * 300 + ".hdr", "/dev/zero",
                "/dev/null.exr", "/", ".", "sky", "studio", "cube.ply", "line\nbreak.obj",
                True, False, [], [1], [1, 2], [1, 2, 3, 4], [[1, 2, 3]], ["a", "b", "c"],
                [True, 1.0, 2.0], [math.nan, 0.0, 1.0], {}, {"a": 1}, {"model": "lambert"},
                datetime.date(2024, 1, 2), datetime.time(12, 0), datetime.datetime(2024, 1, 2, 3, 4, 5))
GARBAGE = (b"\x00", b"\xff\xfe", b"\x80\x81", b"[[", b"]]", b"[", b"=", b"\"", b"'''", b"\n[camera]\n",
           b"\n[[objects]]\n", b"{", b"}", b"\\", b"#", b"\r", b"\t", b"\xc3", b"nan", b"= = =")


def builtin_scene_texts() -> dict[str, str]:
    from viewer.base.resources import SCENE_DIR

    return {p.stem: p.read_text(encoding="utf-8") for p in sorted(SCENE_DIR.glob("*.toml"))}


# ----------------------------------------------------------------------------- scenes

def _paths(data, prefix=()):
    """Every (path, value) in nested dicts / lists, containers included."""
    out = []
    if isinstance(data, dict):
        for k, v in data.items():
            out.append((prefix + (k,), v))
            out.extend(_paths(v, prefix + (k,)))
    elif isinstance(data, list):
        for i, v in enumerate(data):
            out.append((prefix + (i,), v))
            out.extend(_paths(v, prefix + (i,)))
    return out


def _get_parent(data, path):
    cur = data
    for p in path[:-1]:
        cur = cur[p]
    return cur


def _pick(rng, seq):
    return seq[int(rng.integers(len(seq)))]


def _random_number(rng):
    r = rng.random()
    if r < 0.6:
        return _pick(rng, SPECIAL_NUMBERS)
    if r < 0.8:
        return float(rng.uniform(-10, 10))
    return int(rng.integers(-5, 20))


def _random_value(rng):
    return _random_number(rng) if rng.random() < 0.5 else copy.deepcopy(_pick(rng, OTHER_VALUES))


SCENE_KINDS = ("delete", "duplicate", "swap_type", "number", "list_length", "unknown_key",
               "truncate", "garbage", "override", "combo")


def mutate_scene(rng, text: str, kind: str):
    """(description, file bytes, overrides) for one mutation of a valid scene text."""
    data = tomllib.loads(text)
    paths = _paths(data)
    desc = kind
    overrides: list[str] = []
    raw: bytes | None = None
    if kind == "delete":
        path, _ = _pick(rng, paths)
        del _get_parent(data, path)[path[-1]]
        desc += f" {path}"
    elif kind == "duplicate":
        lines = text.splitlines(keepends=True)
        idx = [i for i, ln in enumerate(lines) if ln.strip() and not ln.lstrip().startswith("#")]
        i = _pick(rng, idx)
        j = int(rng.integers(len(lines) + 1))
        lines.insert(j, lines[i])
        raw = "".join(lines).encode()
        desc += f" line {i} -> {j}"
    elif kind == "swap_type":
        path, _ = _pick(rng, paths)
        v = _random_value(rng)
        _get_parent(data, path)[path[-1]] = v
        desc += f" {path} = {v!r}"
    elif kind == "number":
        leaves = [(p, v) for p, v in paths if isinstance(v, (int, float)) and not isinstance(v, bool)]
        path, _ = _pick(rng, leaves) if leaves else _pick(rng, paths)
        v = _random_number(rng)
        _get_parent(data, path)[path[-1]] = v
        desc += f" {path} = {v!r}"
    elif kind == "list_length":
        lists = [(p, v) for p, v in paths if isinstance(v, list) and v]
        path, v = _pick(rng, lists)
        if rng.random() < 0.5:
            v.pop(int(rng.integers(len(v))))
        else:
            v.append(copy.deepcopy(v[int(rng.integers(len(v)))]))
        desc += f" {path} -> {len(v)} items"
    elif kind == "unknown_key":
        tables = [data] + [v for _, v in paths if isinstance(v, dict)]
        t = _pick(rng, tables)
        key = _pick(rng, ("colour", "alpha", "model", "type", "Position", "x y", "\u00e9", "", "a\nb",
                          "c\rd", "e\u2028f", "g\x85h", "k" * 5000))
        t[key] = _random_value(rng)
        desc += f" {key!r}"
    elif kind == "truncate":
        b = text.encode()
        n = int(rng.integers(len(b)))
        raw = b[:n]
        desc += f" at byte {n}/{len(b)}"
    elif kind == "garbage":
        b = bytearray(text.encode())
        for _ in range(int(rng.integers(1, 4))):
            pos = int(rng.integers(len(b) + 1))
            if rng.random() < 0.5:
                junk = _pick(rng, GARBAGE)
            else:
                junk = bytes(rng.integers(0, 256, int(rng.integers(1, 8)), dtype=np.uint8))
            if rng.random() < 0.5:
                b[pos:pos + len(junk)] = junk
            else:
                b[pos:pos] = junk
        raw = bytes(b)
        desc += f" {len(raw) - len(text.encode()):+d} bytes"
    elif kind == "override":
        leaf_paths = [p for p, v in paths if not isinstance(v, (dict, list)) or rng.random() < 0.3]
        path = _pick(rng, leaf_paths)
        key = ".".join(str(p) for p in path)
        if rng.random() < 0.2:
            key = _pick(rng, ("", ".", "camera..fov_y", "lights.9.position", "objects[99].mesh",
                              "materials.nope.alpha", "camera.fov_y.x", "nope.x", "lights.-1.type"))
        val = _pick(rng, ("nan", "inf", "-inf", "-1", "1e400", "0", "[1,2]", "[nan,0,0]", "true",
                          "\"\"", "{a=1}", "ggx", "[[1]]", "1e308", "'x'", "[", "= 3", "9" * 40))
        overrides = [f"{key}={val}" if rng.random() < 0.95 else key]
        desc += f" {overrides}"
    elif kind == "combo":
        for _ in range(int(rng.integers(2, 5))):
            k = _pick(rng, ("delete", "swap_type", "number", "list_length", "unknown_key"))
            try:
                text2 = tomli_w.dumps(data)
                d2, raw2, _ = mutate_scene(rng, text2, k)
                data = tomllib.loads(raw2.decode())
                desc += f" [{d2}]"
            except Exception:  # the mutation could not be serialized: keep the last data
                continue
    else:  # pragma: no cover
        raise ValueError(kind)
    if raw is None:
        try:
            raw = tomli_w.dumps(data).encode()
        except Exception:  # tomli_w refuses e.g. an empty key in a table header: write by hand
            raw = text.encode()
            desc += " (unserializable, original)"
    return desc, raw, overrides


def check_one_line(e: BaseException, desc: str):
    msg = str(e)
    if not isinstance(e, ViewerError):
        tb = "".join(traceback.format_exception(e)).strip()
        raise FuzzFailure(f"{desc}: {type(e).__name__} instead of ViewerError:\n{tb}")
    if not msg or len(msg.splitlines()) != 1:
        raise FuzzFailure(f"{desc}: ViewerError message is not one line: {msg!r}")
    if "Traceback" in msg:
        raise FuzzFailure(f"{desc}: message carries a traceback: {msg!r}")
    if len(msg) > 2000:
        raise FuzzFailure(f"{desc}: message is {len(msg)} characters long")


def check_scene_file(path: Path, overrides=(), desc: str = "", load_meshes: bool = True) -> str:
    """Load a scene file; "error" for a clean ViewerError, "ok" for a scene that also saves and
    loads back equal; FuzzFailure otherwise."""
    from viewer.scene import load_scene, parse_scene, scene_to_toml

    try:
        scene = load_scene(str(path), list(overrides), load_meshes=load_meshes)
    except Exception as e:  # noqa: BLE001 - the point of the check
        check_one_line(e, desc)
        return "error"
    try:
        check_scene_sane(scene)
        text = scene_to_toml(scene)
        again = parse_scene(tomllib.loads(text), scene.path, label=scene.label, base_dir=scene.base_dir,
                            load_meshes=False)
    except Exception as e:  # noqa: BLE001
        tb = "".join(traceback.format_exception(e)).strip()
        raise FuzzFailure(f"{desc}: accepted scene does not save and load back:\n{tb}") from None
    if again != scene:
        raise FuzzFailure(f"{desc}: saved scene loads back different")
    return "ok"


def check_scene_sane(scene):
    cam = scene.camera
    for v in (cam.position, cam.target, cam.up):
        assert np.all(np.isfinite(v)), "camera vector not finite"
    view = cam.target - cam.position
    n = np.linalg.norm(view)
    assert np.isfinite(n) and n > 0, f"viewing direction length {n}"
    assert 0 < cam.fov_y < 180
    for light in scene.lights:
        for v in (light.position, light.intensity, light.direction, light.irradiance):
            assert np.all(np.isfinite(v))
    for obj in scene.objects:
        m = obj.model_matrix()
        assert np.all(np.isfinite(m)), "model matrix not finite"
        if obj.mesh_data is not None:
            assert np.all(np.isfinite(obj.world_positions())), "world positions not finite"


# ----------------------------------------------------------------------------- meshes

MESH_KINDS = ("truncate", "empty", "nan_coords", "inf_coords", "huge_coords", "zero_area",
              "non_manifold", "index_out_of_range", "negative_index", "garbage", "flip_bytes",
              "no_faces", "nan_normals", "zero_normals", "quads_and_polygons", "header_lies")
MESH_EXTS = (".ply", ".obj", ".stl", ".off")


def _tri_soup(rng, n_tri=12):
    """A small random mesh: V positions, normals, faces."""
    p = rng.normal(size=(n_tri + 2, 3))
    f = np.stack([np.zeros(n_tri, int), np.arange(1, n_tri + 1), np.arange(2, n_tri + 2)], axis=1)
    n = rng.normal(size=p.shape)
    return p, n, f


def _write_obj(path, P, F, N=None, extra=""):
    lines = [f"v {x!r} {y!r} {z!r}" for x, y, z in np.asarray(P, dtype=float).tolist()]
    if N is not None:
        lines += [f"vn {x!r} {y!r} {z!r}" for x, y, z in np.asarray(N, dtype=float).tolist()]
        lines += ["f " + " ".join(f"{i + 1}//{i + 1}" for i in tri) for tri in np.asarray(F).tolist()]
    else:
        lines += ["f " + " ".join(str(i + 1) for i in tri) for tri in np.asarray(F).tolist()]
    Path(path).write_text("\n".join(lines) + "\n" + extra)


def _write_off(path, P, F):
    lines = ["OFF", f"{len(P)} {len(F)} 0"]
    lines += [f"{x!r} {y!r} {z!r}" for x, y, z in np.asarray(P, dtype=float).tolist()]
    lines += ["3 " + " ".join(str(i) for i in tri) for tri in np.asarray(F).tolist()]
    Path(path).write_text("\n".join(lines) + "\n")


def _write_stl(path, P, F):
    with np.errstate(over="ignore"):  # huge_coords: 1e300 is written as inf, as a float32 file would
        P = np.asarray(P, dtype="<f4")
    F = np.asarray(F)
    tris = P[F] if len(F) else np.zeros((0, 3, 3), "<f4")
    rec = np.zeros(len(tris), dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])
    rec["v"] = tris
    Path(path).write_bytes(b"\0" * 80 + struct.pack("<I", len(tris)) + rec.tobytes())


def write_mesh(path: Path, P, F, N=None):
    from viewer.scene.mesh import write_ply

    ext = path.suffix
    if ext == ".ply":
        write_ply(path, P, np.zeros_like(P) if N is None else N, F)
    elif ext == ".obj":
        _write_obj(path, P, F, N)
    elif ext == ".off":
        _write_off(path, P, F)
    elif ext == ".stl":
        _write_stl(path, P, F)
    else:  # pragma: no cover
        raise ValueError(ext)


def make_mesh_case(rng, folder: Path, kind: str, index: int) -> tuple[str, Path]:
    ext = _pick(rng, MESH_EXTS)
    path = Path(folder) / f"m{index}{ext}"
    P, N, F = _tri_soup(rng, int(rng.integers(1, 40)))
    desc = f"{kind} {ext}"
    if kind == "truncate":
        write_mesh(path, P, F, N)
        b = path.read_bytes()
        cut = int(rng.integers(len(b)))
        path.write_bytes(b[:cut])
        desc += f" at {cut}/{len(b)}"
    elif kind == "empty":
        path.write_bytes(b"")
    elif kind in ("nan_coords", "inf_coords", "huge_coords"):
        val = {"nan_coords": math.nan, "inf_coords": _pick(rng, (math.inf, -math.inf)),
               "huge_coords": _pick(rng, (1e38, -3e38, 1e30, 1e300))}[kind]
        P = P.copy()
        P[int(rng.integers(len(P))), int(rng.integers(3))] = val
        with np.errstate(over="ignore"):  # 1e300 becomes inf in a float32 file, as intended
            write_mesh(path, P, F, N)
    elif kind == "zero_area":
        P = P.copy()
        r = rng.random()
        if r < 0.3:
            P[:] = P[0]                        # every face collapses
        elif r < 0.6:
            P[:, 2] = 0.0
            P[:, 1] = 2.0 * P[:, 0]            # collinear: every face a sliver
        else:
            P[F[0, 1]] = P[F[0, 0]]            # one face degenerate, the rest fine
        write_mesh(path, P, F, N)
    elif kind == "non_manifold":
        # three or more faces on one edge, a bowtie vertex, duplicated and flipped faces
        F2 = np.concatenate([F, F[:1], F[:1, ::-1], [[0, 1, len(P) - 1]]])
        write_mesh(path, P, F2, N)
    elif kind in ("index_out_of_range", "negative_index"):
        F2 = F.copy()
        F2[int(rng.integers(len(F2))), int(rng.integers(3))] = (
            len(P) + int(rng.integers(0, 1000)) if kind == "index_out_of_range" else -int(rng.integers(1, 5)))
        if ext == ".stl":  # an STL has no indices: write a PLY instead
            path = path.with_suffix(".ply")
            desc = f"{kind} .ply"
        if path.suffix == ".ply":
            from viewer.scene.mesh import write_ply

            Fu = F2.astype(np.int64) & 0xFFFFFFFF      # negative -> huge unsigned
            write_ply(path, P, N, Fu)
        elif path.suffix == ".obj":
            _write_obj(path, P, F2)
        else:
            _write_off(path, P, F2)
    elif kind == "garbage":
        n = int(rng.integers(1, 4096))
        path.write_bytes(bytes(rng.integers(0, 256, n, dtype=np.uint8)))
    elif kind == "flip_bytes":
        write_mesh(path, P, F, N)
        b = bytearray(path.read_bytes())
        for _ in range(int(rng.integers(1, 20))):
            b[int(rng.integers(len(b)))] = int(rng.integers(256))
        path.write_bytes(bytes(b))
    elif kind == "no_faces":
        write_mesh(path, P, np.zeros((0, 3), int), N)
    elif kind in ("nan_normals", "zero_normals"):
        N = N.copy()
        N[: max(1, len(N) // 2)] = math.nan if kind == "nan_normals" else 0.0
        if ext in (".stl", ".off"):
            path = path.with_suffix(_pick(rng, (".ply", ".obj")))
            desc = f"{kind} {path.suffix}"
        write_mesh(path, P, F, N)
    elif kind == "quads_and_polygons":
        path = path.with_suffix(".obj")
        desc = f"{kind} .obj"
        lines = [f"v {x!r} {y!r} {z!r}" for x, y, z in P.tolist()]
        lines += ["f 1 2 3 4", "f 1 2", "f 1", "f 1 2 3 4 5 6", "l 1 2", "p 1"]
        path.write_text("\n".join(lines) + "\n")
    elif kind == "header_lies":
        path = path.with_suffix(_pick(rng, (".ply", ".off")))
        desc = f"{kind} {path.suffix}"
        if path.suffix == ".ply":
            from viewer.scene.mesh import write_ply

            write_ply(path, P, N, F)
            b = path.read_bytes()
            which = _pick(rng, (b"element vertex", b"element face"))
            i = b.index(which) + len(which) + 1
            j = b.index(b"\n", i)
            lie = _pick(rng, (b"0", b"1", b"99999999", b"-3", b"x", str(len(P) * 2).encode(), b"4294967295"))
            path.write_bytes(b[:i] + lie + b[j:])
            desc += f" {which.decode()} {lie.decode()}"
        else:
            _write_off(path, P, F)
            t = path.read_text().splitlines()
            t[1] = _pick(rng, (f"{len(P) * 3} {len(F)} 0", f"{len(P)} {len(F) * 5} 0", "-1 -1 0", "a b c", ""))
            path.write_text("\n".join(t) + "\n")
            desc += f" counts {t[1]!r}"
    else:  # pragma: no cover
        raise ValueError(kind)
    return desc, path


def check_mesh_file(path: Path, desc: str = "") -> str:
    from viewer.scene.mesh import clear_cache, load_mesh

    clear_cache()
    try:
        m = load_mesh(str(path), where="fuzz")
    except Exception as e:  # noqa: BLE001
        check_one_line(e, desc)
        return "error"
    check_mesh_sane(m, desc)
    return "ok"


def check_mesh_sane(m, desc=""):
    try:
        V = len(m.positions)
        assert V > 0 and len(m.indices) > 0, "empty mesh accepted"
        assert m.positions.dtype == np.float32 and m.positions.shape == (V, 3)
        for a in (m.positions, m.normals, m.tangents, m.uvs):
            assert np.all(np.isfinite(a)), "non-finite vertex data"
        assert np.allclose(np.linalg.norm(m.normals, axis=1), 1.0, atol=1e-4), "normals not unit"
        assert np.allclose(np.linalg.norm(m.tangents[:, :3], axis=1), 1.0, atol=1e-4), "tangents not unit"
        assert m.indices.dtype == np.uint32 and m.indices.max() < V, "index out of range"
    except AssertionError as e:
        raise FuzzFailure(f"{desc}: accepted mesh is not sane: {e}") from None


# ----------------------------------------------------------------------------- environment maps

ENV_KINDS = ("truncate", "empty", "garbage", "flip_bytes", "bad_resolution", "bad_header",
             "wrong_magic", "nan_texels", "inf_texels", "negative_texels", "tiny", "odd_aspect",
             "exposure")


def make_env_case(rng, folder: Path, kind: str, index: int) -> tuple[str, Path]:
    from viewer.environment.io import save_environment

    ext = _pick(rng, (".hdr", ".exr"))
    path = Path(folder) / f"e{index}{ext}"
    h = int(rng.integers(1, 9))
    w = 2 * h if rng.random() < 0.8 else int(rng.integers(1, 20))
    img = rng.uniform(0, 4, size=(h, w, 3)).astype(np.float32)
    desc = f"{kind} {ext} {w}x{h}"
    if kind in ("nan_texels", "inf_texels", "negative_texels"):
        # RGBE cannot hold these: only OpenEXR can carry them
        path = path.with_suffix(".exr")
        desc = f"{kind} .exr {w}x{h}"
        val = {"nan_texels": math.nan, "inf_texels": _pick(rng, (math.inf, -math.inf)),
               "negative_texels": -float(rng.uniform(1e-6, 10))}[kind]
        mask = rng.random(img.shape) < 0.3
        mask.flat[int(rng.integers(mask.size))] = True
        img[mask] = val
        save_environment(path, img)
        return desc, path
    if kind == "tiny":
        img = img[:1, :1]
        desc = f"tiny {ext} 1x1"
        save_environment(path, img)
        return desc, path
    save_environment(path, img)
    b = path.read_bytes()
    if kind == "truncate":
        cut = int(rng.integers(len(b)))
        path.write_bytes(b[:cut])
        desc += f" at {cut}/{len(b)}"
    elif kind == "empty":
        path.write_bytes(b"")
    elif kind == "garbage":
        magic = b"#?RADIANCE\n" if ext == ".hdr" else b"\x76\x2f\x31\x01"
        n = int(rng.integers(0, 2048))
        path.write_bytes(magic + bytes(rng.integers(0, 256, n, dtype=np.uint8)))
    elif kind == "flip_bytes":
        bb = bytearray(b)
        for _ in range(int(rng.integers(1, 10))):
            bb[int(rng.integers(len(bb)))] = int(rng.integers(256))
        path.write_bytes(bytes(bb))
    elif kind == "bad_resolution":
        if ext == ".hdr":
            end = b.index(b"\n\n") + 2
            nl = b.index(b"\n", end)
            res = _pick(rng, (f"-Y {h} +X {w + 3}", f"-Y {h + 5} +X {w}", f"-Y 0 +X {w}", f"-Y {h} +X 0",
                              f"+Y {h} +X {w}", f"-Y {h} -X {w}", f"+X {w} -Y {h}", "-Y 99999 +X 99999",
                              f"-Y {h} +X {w} extra", "garbage", f"-Y -{h} +X {w}",
                              f"-Y {h} +X {2 ** 40}"))
            path.write_bytes(b[:end] + res.encode() + b[nl:])
            desc += f" {res!r}"
        else:
            # the dataWindow box: 4 int32 after its name and type
            i = b.find(b"dataWindow\0box2i\0")
            if i < 0:
                path.write_bytes(b[:len(b) // 2])
            else:
                j = i + len(b"dataWindow\0box2i\0") + 4
                vals = list(struct.unpack("<4i", b[j:j + 16]))
                k = int(rng.integers(4))
                vals[k] = _pick(rng, (-1, 0, 1, vals[k] + 7, -(2 ** 31), 2 ** 31 - 1, 100000))
                path.write_bytes(b[:j] + struct.pack("<4i", *vals) + b[j + 16:])
                desc += f" dataWindow {vals}"
    elif kind == "bad_header":
        if ext == ".hdr":
            line = _pick(rng, (b"FORMAT=32-bit_rle_xyze\n", b"EXPOSURE=abc\n", b"EXPOSURE=0\n",
                               b"EXPOSURE=-2\n", b"EXPOSURE=nan\n", b"EXPOSURE=inf\n", b"EXPOSURE=1e-320\n",
                               b"\0\0\0\n", b"X" * 70000 + b"\n"))
            i = b.index(b"\n") + 1
            path.write_bytes(b[:i] + line + b[i:])
            desc += f" {line[:40]!r}"
        else:
            i = b.find(b"channels\0chlist\0")
            path.write_bytes(b[:i + 3] + b"\xff" * 8 + b[i + 11:] if i >= 0 else b[:8])
    elif kind == "wrong_magic":
        other = _pick(rng, (b"\x89PNG\r\n\x1a\n", b"\xff\xd8\xff", b"#?RADIANC", b"\x76\x2f\x31\x02", b"GIF8"))
        path.write_bytes(other + b[len(other):])
        desc += f" {other!r}"
    elif kind == "odd_aspect":
        img = rng.uniform(0, 1, size=(int(rng.integers(1, 6)), int(rng.integers(2, 30)), 3)).astype(np.float32)
        save_environment(path, img)
        desc = f"odd_aspect {ext} {img.shape[1]}x{img.shape[0]}"
    elif kind == "exposure":
        if ext == ".hdr":
            i = b.index(b"\n") + 1
            e = _pick(rng, (b"0.5", b"2", b"1e-30", b"1e30", b"1e300"))
            path.write_bytes(b[:i] + b"EXPOSURE=" + e + b"\n" + b[i:])
            desc += f" EXPOSURE={e.decode()}"
    else:  # pragma: no cover
        raise ValueError(kind)
    return desc, path


def check_env_file(path: Path, desc: str = "") -> str:
    from viewer.environment.io import load_environment

    try:
        img = load_environment(path)
    except Exception as e:  # noqa: BLE001
        check_one_line(e, desc)
        return "error"
    if not (img.dtype == np.float32 and img.ndim == 3 and img.shape[2] == 3 and img.shape[0] >= 1
            and img.shape[1] >= 2):
        raise FuzzFailure(f"{desc}: accepted map has shape {img.shape} {img.dtype}")
    if not np.all(np.isfinite(img)) or np.any(img < 0):
        raise FuzzFailure(f"{desc}: accepted map has NaN, infinite or negative texels")
    return "ok"


# ----------------------------------------------------------------------------- runners

def run_fuzz(which: str, n: int, seed: int, folder: Path, max_failures: int = 20):
    """Run ``n`` cases of ``which`` ("scene", "mesh", "env"); returns (counts, failures) with
    counts[(kind, outcome)] for outcome "ok" / "error" / "FAIL" and the first failures' texts.
    Cases cycle through the kinds (and, for scenes, the built-in scenes) so each is tried."""
    import collections
    import logging

    rng = np.random.default_rng(seed)
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    counts: collections.Counter = collections.Counter()
    failures: list[str] = []
    texts = builtin_scene_texts() if which == "scene" else {}
    names = list(texts)
    env_log = logging.getLogger("viewer.environment")
    old_level = env_log.level
    env_log.setLevel(logging.ERROR)  # the sanitize / aspect warnings are expected here
    try:
        for i in range(n):
            if which == "scene":
                name = names[i % len(names)]
                kind = SCENE_KINDS[(i // len(names)) % len(SCENE_KINDS)]
                desc, raw, overrides = mutate_scene(rng, texts[name], kind)
                desc = f"scene {name} {desc}"
                path = folder / f"s{i}.toml"
                path.write_bytes(raw)
                check = lambda: check_scene_file(path, overrides, desc)  # noqa: E731
            elif which == "mesh":
                kind = MESH_KINDS[i % len(MESH_KINDS)]
                desc, path = make_mesh_case(rng, folder, kind, i)
                desc = f"mesh {desc}"
                check = lambda: check_mesh_file(path, desc)  # noqa: E731
            elif which == "env":
                kind = ENV_KINDS[i % len(ENV_KINDS)]
                desc, path = make_env_case(rng, folder, kind, i)
                desc = f"map {desc}"
                check = lambda: check_env_file(path, desc)  # noqa: E731
            else:  # pragma: no cover
                raise ValueError(which)
            try:
                counts[(kind, check())] += 1
            except FuzzFailure as e:
                counts[(kind, "FAIL")] += 1
                if len(failures) < max_failures:
                    failures.append(str(e))
            try:
                path.unlink()
            except OSError:
                pass
    finally:
        env_log.setLevel(old_level)
    return counts, failures


def format_counts(which: str, counts) -> str:
    kinds = sorted({k for k, _ in counts})
    lines = [f"{which}: {sum(counts.values())} cases, "
             f"{sum(v for (k, o), v in counts.items() if o == 'FAIL')} failures"]
    for k in kinds:
        lines.append(f"  {k:20s} ok {counts[(k, 'ok')]:6d}  clean error {counts[(k, 'error')]:6d}"
                     f"  FAIL {counts[(k, 'FAIL')]:4d}")
    return "\n".join(lines)
