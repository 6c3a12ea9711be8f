"""Environment lighting, CPU side: map files, orientation, rotation, solid angles, cube maps,
SH irradiance, the DFG table, the built-in maps and the scene's [environment] section."""

from __future__ import annotations

import logging
import math
import os

import numpy as np
import pytest

from viewer import ViewerError
from viewer.environment import dfg, latlong, procedural, sh
from viewer.environment.io import load_environment, read_environment, save_environment
from viewer.scene import load_scene, scene_to_toml

D45 = np.array([0.0, math.cos(math.pi / 4), -math.sin(math.pi / 4)])  # u = 0.5, v = 0.25


def _rand_map(h=16, w=32, seed=0):
    rng = np.random.default_rng(seed)
    return (rng.random((h, w, 3)) * 50.0 + 0.01).astype(np.float32)


# ----------------------------------------------------------------------------- files

@pytest.mark.parametrize("suffix", [".hdr", ".exr"])
def test_file_round_trip(tmp_path, suffix):
    a = _rand_map()
    a[0, 0] = [1e4, 2e-3, 0.5]  # wide range in one texel
    p = tmp_path / f"env{suffix}"
    save_environment(p, a)
    assert sorted(os.listdir(tmp_path)) == [p.name]  # atomic: no temporary left behind
    b = load_environment(p)
    assert b.dtype == np.float32 and b.shape == a.shape
    if suffix == ".exr":
        np.testing.assert_array_equal(a, b)
    else:  # RGBE: 8-bit mantissas sharing the exponent of the texel's largest channel
        err = np.abs(a - b) / a.max(axis=-1, keepdims=True)
        assert err.max() < 1.0 / 128


def test_exr_grey_and_rgba_channels(tmp_path):
    import OpenEXR

    y = np.linspace(0.0, 3.0, 32, dtype=np.float32).reshape(4, 8)
    with OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION}, {"Y": y}) as f:
        f.write(str(tmp_path / "grey.exr"))
    g = load_environment(tmp_path / "grey.exr")
    assert g.shape == (4, 8, 3) and np.array_equal(g[..., 1], y) and np.array_equal(g[..., 0], g[..., 2])
    rgba = np.dstack([_rand_map(4, 8), np.ones((4, 8, 1), np.float32)]).astype(np.float16)
    with OpenEXR.File({"compression": OpenEXR.PIZ_COMPRESSION}, {"RGBA": rgba}) as f:
        f.write(str(tmp_path / "rgba.exr"))
    np.testing.assert_array_equal(load_environment(tmp_path / "rgba.exr"), rgba[..., :3].astype(np.float32))


def test_hdr_exposure_header_is_honoured(tmp_path):
    p = tmp_path / "exp.hdr"
    save_environment(p, _rand_map(4, 8))
    plain = load_environment(p)
    data = p.read_bytes()
    first = data.index(b"\n") + 1
    p.write_bytes(data[:first] + b"EXPOSURE=2.0\n" + data[first:])
    np.testing.assert_allclose(load_environment(p), plain / 2.0, rtol=1e-6)


def _expect(path, *words):
    with pytest.raises(ViewerError) as e:
        load_environment(path)
    msg = str(e.value)
    assert "\n" not in msg and path.name in msg, msg
    for w in words:
        assert w in msg, msg
    return msg


def test_file_errors_name_the_file(tmp_path):
    _expect(tmp_path / "missing.hdr", "not found")
    (tmp_path / "folder.exr").mkdir()
    _expect(tmp_path / "folder.exr", "not a file")
    (tmp_path / "empty.hdr").write_bytes(b"")
    _expect(tmp_path / "empty.hdr", "not a Radiance", "empty")
    from PIL import Image

    Image.new("RGB", (8, 4)).save(tmp_path / "pic.png")
    os.replace(tmp_path / "pic.png", tmp_path / "renamed.hdr")
    _expect(tmp_path / "renamed.hdr", "not a Radiance", "PNG")
    for suffix in (".hdr", ".exr"):
        p = tmp_path / f"cut{suffix}"
        save_environment(p, _rand_map(32, 64))
        data = p.read_bytes()
        p.write_bytes(data[: len(data) // 2])
        _expect(p, "truncated")
    save_environment(tmp_path / "thin.hdr", _rand_map(4, 1))
    _expect(tmp_path / "thin.hdr", "width >= 2")
    with pytest.raises(ViewerError, match="allowed: .hdr, .exr"):
        save_environment(tmp_path / "x.png", _rand_map())


def test_unreadable_file(tmp_path, monkeypatch):
    import viewer.environment.io as env_io

    p = tmp_path / "locked.exr"
    save_environment(p, _rand_map())

    def denied(*args, **kwargs):  # what open() raises without read permission (root ignores chmod)
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(env_io, "open", denied, raising=False)
    _expect(p, "cannot be read", "Permission denied")


def test_odd_aspect_accepted_and_bad_texels_sanitized(tmp_path, caplog):
    import OpenEXR

    a = _rand_map(8, 8)
    a[1, 2, 0] = np.nan
    a[3, 3] = -1.0
    a[5, 6, 2] = np.inf
    with OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION}, {"RGB": a}) as f:
        f.write(str(tmp_path / "bad.exr"))
    with caplog.at_level(logging.WARNING, logger="viewer.environment"):
        img = read_environment(tmp_path / "bad.exr")
    assert img.pixels.shape == (8, 8, 3) and img.sanitized == 3
    assert np.all(np.isfinite(img.pixels)) and img.pixels.min() >= 0.0
    assert img.pixels[1, 2, 0] == 0 and np.all(img.pixels[3, 3] == 0) and img.pixels[1, 2, 1] == a[1, 2, 1]
    text = caplog.text
    assert "bad.exr" in text and "3 texels" in text and "not 2:1" in text


# ----------------------------------------------------------------------------- lat-long geometry

def test_orientation_of_the_contract():
    u, v = latlong.dir_to_uv(np.array([D45, [0, 0, -1], [1, 0, 0], [-1, 0, 0], [0, 1, 0]]))
    np.testing.assert_allclose(u[:4], [0.5, 0.5, 0.75, 0.25], atol=1e-12)
    np.testing.assert_allclose(v, [0.25, 0.5, 0.5, 0.5, 0.0], atol=1e-12)
    rng = np.random.default_rng(1)
    d = rng.normal(size=(100, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    np.testing.assert_allclose(latlong.uv_to_dir(*latlong.dir_to_uv(d)), d, atol=1e-12)
    # A map bright only around (u, v) = (0.5, 0.25) is brightest for d = (0, cos 45, -sin 45).
    h, w = 64, 128
    uu, vv = latlong.texel_centers(h, w)
    img = np.exp(-((uu - 0.5) ** 2 + (vv - 0.25) ** 2) / 0.002)[..., None].repeat(3, -1)
    dirs = latlong.texel_directions(4 * h, 4 * w).reshape(-1, 3)
    vals = latlong.lookup(img, dirs)[:, 0]
    best = dirs[np.argmax(vals)]
    assert np.degrees(np.arccos(best @ D45)) < 360.0 / w  # within a texel (bilinear has a flat top)
    assert latlong.lookup(img, D45[None])[0, 0] > 0.98 * vals.max()
    row, col = latlong.pixel_of(np.array([0.0, 1.0, 0.0]), h, w)
    assert row == 0  # the zenith is the top row


_LATLONG_FRAG = """#version 410 core
#include "common/latlong.glsl"
uniform sampler2D u_d;
uniform sampler2D u_uv;
layout(location = 0) out vec4 out_uv;
layout(location = 1) out vec4 out_dir;
void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    out_uv = vec4(env_dir_to_uv(texelFetch(u_d, px, 0).xyz), 0.0, 1.0);
    out_dir = vec4(env_uv_to_dir(texelFetch(u_uv, px, 0).xy), 1.0);
}
"""


def test_the_glsl_latlong_mapping_is_the_numpy_one(gl_ctx):
    """common/latlong.glsl, the one GLSL mapping (the rasterizer's IBL and the GPU engine's
    environment include it), against viewer/environment/latlong.py both ways: random directions
    of any length (the mapping normalizes), the axes, the poles (where GLSL's atan(0, 0) is
    undefined: u = 0.5 there, any u being the same point) and the u = 0 / 1 seam."""
    from viewer.gl.shaders import build_program

    rng = np.random.default_rng(3)
    d = rng.normal(size=(250, 3)) * rng.uniform(0.01, 100.0, size=(250, 1))
    d = np.concatenate([d, np.eye(3), -np.eye(3), [[0.0, 2.0, 0.0], [0.0, -0.5, 0.0], [1e-3, 0.0, 1.0]]])
    uv = rng.uniform(0.0, 1.0, size=(len(d), 2))
    n, w = len(d), 16
    h = (n + w - 1) // w

    def tex(a):
        data = np.zeros((w * h, 4), "f4")
        data[:n, : a.shape[1]] = a
        t = gl_ctx.texture((w, h), 4, data.tobytes(), dtype="f4")
        t.filter = (gl_ctx.NEAREST, gl_ctx.NEAREST)
        return t

    vert = ("#version 410 core\nvoid main() { vec2 p = vec2((gl_VertexID << 1) & 2, gl_VertexID & 2);"
            " gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0); }\n")
    prog = build_program(gl_ctx, vertex_source=vert, fragment_source=_LATLONG_FRAG)
    td, tuv = tex(d), tex(uv)
    outs = [gl_ctx.texture((w, h), 4, dtype="f4") for _ in range(2)]
    fbo = gl_ctx.framebuffer(color_attachments=outs)
    vao = gl_ctx.vertex_array(prog, [])
    try:
        td.use(0)
        tuv.use(1)
        prog["u_d"].value, prog["u_uv"].value = 0, 1
        fbo.use()
        fbo.viewport = (0, 0, w, h)
        vao.render(vertices=3)
        g_uv, g_dir = (np.frombuffer(o.read(), "f4").reshape(-1, 4)[:n] for o in outs)
    finally:
        for x in (fbo, vao, prog, td, tuv, *outs):
            x.release()
    u, v = latlong.dir_to_uv(d)
    pole = (d[:, 0] == 0.0) & (d[:, 2] == 0.0)
    assert pole.sum() == 4
    # GLSL's atan and acos are approximations of implementation-defined precision (Mesa llvmpipe:
    # up to 5e-5 off in u and v, measured); 2e-4 is under half a texel of a 4096 x 2048 map, and
    # an unnormalized y (the length ignored) or another orientation is off by far more. u is
    # compared around the seam (u = 0 and 1 are one line).
    du = np.abs(g_uv[:, 0] - u)
    np.testing.assert_array_less(np.minimum(du, 1.0 - du)[~pole], 2e-4)
    np.testing.assert_array_equal(g_uv[pole, 0], 0.5)
    np.testing.assert_allclose(g_uv[:, 1], v, atol=2e-4)
    np.testing.assert_allclose(g_dir[:, :3], latlong.uv_to_dir(uv[:, 0], uv[:, 1]), atol=1e-5)


def test_rotation_is_right_handed_about_y():
    h, w = 64, 128
    uu, vv = latlong.texel_centers(h, w)
    img = np.exp(-((uu - 0.5) ** 2 + (vv - 0.25) ** 2) / 0.002)[..., None].repeat(3, -1)
    peak = latlong.lookup(img, D45[None])[0, 0]
    # Turning the map by +90 deg about +y carries -z to -x: the bright spot moves to
    # R_y(90) (0, c, -s) = (-s, c, 0).
    moved = np.array([-math.sin(math.pi / 4), math.cos(math.pi / 4), 0.0])
    np.testing.assert_allclose(latlong.rotation_y(90.0) @ D45, moved, atol=1e-12)
    assert latlong.lookup(img, moved[None], rotation_deg=90.0)[0, 0] == pytest.approx(peak, rel=1e-6)
    assert latlong.lookup(img, D45[None], rotation_deg=90.0)[0, 0] < 1e-3 * peak
    rng = np.random.default_rng(2)
    d = rng.normal(size=(50, 3))
    np.testing.assert_allclose(latlong.lookup(img, d @ latlong.rotation_y(37.0).T, 37.0), latlong.lookup(img, d),
                               atol=1e-9)


def test_solid_angles_sum_to_4pi():
    for h, w in ((1, 2), (7, 13), (256, 512)):
        om = latlong.solid_angles(h, w)
        assert om.sum() == pytest.approx(4.0 * math.pi, rel=1e-12)
        assert np.all(om > 0)
    h, w = 256, 512
    theta = (np.arange(h) + 0.5) / h * np.pi  # the sin(theta) dtheta dphi approximation
    np.testing.assert_allclose(latlong.row_solid_angles(h, w), np.sin(theta) * (np.pi / h) * (2 * np.pi / w),
                               rtol=1e-4)


def test_cubemap_faces_where_gl_expects():
    h, w = 256, 512
    coded = latlong.texel_directions(h, w).astype(np.float32)  # radiance = its own direction
    size = 16
    cube = latlong.to_cubemap(coded, size)
    assert cube.shape == (6, size, size, 3) and cube.dtype == np.float32
    for f in range(6):
        d = latlong.cube_face_directions(f, size)
        assert np.abs(cube[f] - d).max() < 0.02
        # the forward rule of the GL spec's selection table (sec. 8.13) sends each texel back to itself
        face, s, t = latlong.cube_direction_to_face(d)
        assert np.all(face == f)
        np.testing.assert_allclose(s, np.broadcast_to((np.arange(size) + 0.5) / size, (size, size)), atol=1e-12)
        np.testing.assert_allclose(t, np.broadcast_to(((np.arange(size) + 0.5) / size)[:, None], (size, size)),
                                   atol=1e-12)
    axes = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
    even = latlong.to_cubemap(coded, 2)  # the 4 centre-adjacent texels average to the face centre
    for f in range(6):
        centre = even[f].mean(axis=(0, 1))
        assert centre @ axes[f] > 0.8  # +Y face = zenith, +X face looks along +x, ...
    odd = latlong.to_cubemap(coded, 5)
    for f in range(6):  # a face's centre texel is the lat-long value of its axis (u is arbitrary at the poles)
        np.testing.assert_allclose(odd[f, 2, 2], latlong.lookup(coded, axes[f][None])[0], atol=1e-6 if f not in (2, 3)
                                   else 0.02)
    # side faces: row 0 (t = 0) is up; +Y face: row 0 looks toward -z (tc = rz)
    assert latlong.cube_face_directions(4, 4)[0, 1:3, 1].min() > 0.3
    assert latlong.cube_face_directions(2, 4)[0, 1:3, 2].max() < -0.3


# ----------------------------------------------------------------------------- SH

def test_sh_constant_environment_gives_pi_l():
    L = np.array([0.7, 1.3, 0.05])
    c = sh.project_latlong(np.broadcast_to(L, (32, 64, 3)))
    rng = np.random.default_rng(3)
    n = rng.normal(size=(200, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    np.testing.assert_allclose(sh.irradiance(c, n), np.broadcast_to(np.pi * L, (200, 3)), rtol=1e-12)
    np.testing.assert_allclose(sh.lambert_radiance(c, n, [0.5, 0.5, 0.5]), np.broadcast_to(0.5 * L, (200, 3)),
                               rtol=1e-12)


def test_sh_basis_is_orthonormal():
    h, w = 128, 256
    B = sh.basis(latlong.texel_directions(h, w))
    G = np.einsum("ijk,ijl,ij->kl", B, B, latlong.solid_angles(h, w))
    np.testing.assert_allclose(G, np.eye(9), atol=1e-4)


def test_cosine_lobe_closed_form():
    # against a direct texel sum of the defining integral
    h, w = 512, 1024
    d = latlong.texel_directions(h, w).reshape(-1, 3)
    om = latlong.solid_angles(h, w).ravel()
    L = np.maximum(d[:, 1], 0.0)
    for beta in (0.0, 0.6, math.pi / 2, 2.4):
        n = np.array([math.sin(beta), math.cos(beta), 0.0])
        direct = np.sum(L * np.maximum(d @ n, 0.0) * om)
        assert sh.cosine_lobe_irradiance(math.cos(beta)) == pytest.approx(direct, abs=2e-4)


@pytest.mark.parametrize("axis", [(0.0, 1.0, 0.0), (1.0, 2.0, -0.5)])
def test_sh_irradiance_of_cosine_lobe_within_order2_bound(axis):
    """L(d) = max(0, d.a). The order-2 error is the tail sum_{l>=4} A_l^2 (2l+1)/(4 pi) P_l(cos b),
    at most 0.016362 (beta = 0 or pi); see viewer.environment.sh."""
    a = np.asarray(axis) / np.linalg.norm(axis)
    c = sh.project_function(lambda d: np.maximum(d @ a, 0.0)[:, None], n=256)
    b = np.linspace(0.0, np.pi, 91)
    # normals in a plane containing a
    e = np.cross(a, [0.3, 0.1, 0.9])
    e /= np.linalg.norm(e)
    normals = np.cos(b)[:, None] * a + np.sin(b)[:, None] * e
    err = sh.irradiance(c, normals)[:, 1] - sh.cosine_lobe_irradiance(np.cos(b))
    tail_at_0 = 0.016362  # the analytic bound
    assert np.abs(err).max() <= tail_at_0 + 2e-4
    assert abs(err[0]) == pytest.approx(tail_at_0, abs=2e-4)  # and it is reached where predicted
    assert abs(err[45]) == pytest.approx(0.003987, abs=2e-4)  # beta = pi/2


# ----------------------------------------------------------------------------- DFG

@pytest.fixture(scope="module")
def table():
    return dfg.dfg_table(32, 4096)


def test_dfg_table_convention(table):
    assert table.shape == (32, 32, 2) and table.dtype == np.float32
    c = dfg.table_coords(32)
    # axis 0 = NoV, axis 1 = alpha, channel 0 = A (scale on F0), channel 1 = B (bias)
    a, b = dfg.dfg_ab(np.array([c[3]]), np.array([c[20]]))
    np.testing.assert_allclose(table[3, 20], [a[0], b[0]], rtol=1e-6)
    A, B = dfg.lookup_dfg(table, c[3], c[20])
    np.testing.assert_allclose([A, B], table[3, 20], rtol=1e-6)


def test_dfg_table_matches_reference(table):
    c = dfg.table_coords(32)
    for i, j in [(0, 0), (0, 31), (1, 1), (5, 2), (15, 7), (31, 1), (31, 7), (31, 31), (20, 15), (8, 26)]:
        ref = dfg.dfg_reference(c[i], c[j], 512)
        np.testing.assert_allclose(table[i, j], ref, atol=1e-3, err_msg=f"NoV={c[i]}, alpha={c[j]}")


def test_dfg_limits(table):
    s = table.sum(axis=-1)
    assert np.all(table >= 0) and s.max() <= 1.0 + 1e-6
    assert table[-1, 0, 0] > 0.999 and table[-1, 0, 1] < 1e-5  # smooth, normal incidence: (1, 0)
    assert table[0, 0, 1] > 0.5  # grazing: Fresnel -> 1, the bias dominates
    assert np.all(np.diff(s[16], axis=0) < 0)  # rougher loses more energy (single scattering)


def test_ms_compensation_white_furnace(table):
    A, B = table[..., 0], table[..., 1]
    fss, fms = dfg.ms_compensation(A, B, 1.0)
    np.testing.assert_allclose(fss + fms, 1.0, atol=1e-6)
    fss, fms = dfg.ms_compensation(A[..., None], B[..., None], np.array([0.04, 0.5, 0.9]))
    assert fss.shape == (32, 32, 3) and np.all(fms >= 0) and np.all(fss + fms <= 1.0 + 1e-6)
    assert np.all(fss + fms >= fss)


# ----------------------------------------------------------------------------- built-in maps

def test_sky():
    h, w = 256, 512
    img = procedural.sky(w, h)
    assert img.shape == (h, w, 3) and img.dtype == np.float32
    assert np.all(np.isfinite(img)) and img.min() >= 0
    sun = procedural.direction(-135.0, 35.0)
    assert sun[0] < 0 and sun[2] > 0  # front-left of the default camera (it looks along -z)
    r, c = np.unravel_index(np.argmax(img.sum(-1)), (h, w))
    rs, cs = latlong.pixel_of(sun, h, w)
    assert abs(int(r) - int(rs)) <= 1 and min(abs(int(c) - int(cs)), w - abs(int(c) - int(cs))) <= 1
    # the disk's energy is L_sun * Omega_sun whatever the resolution
    om = latlong.solid_angles(h, w)[..., None]
    l_sun = procedural.sun_radiance(35.0)
    omega = 2 * math.pi * (1 - math.cos(math.radians(0.53 / 2)))
    sky_only = procedural.sky(w, h, sun_diameter_deg=1e-6)
    near = slice(int(rs) - 3, int(rs) + 4)
    np.testing.assert_allclose(((img - sky_only) * om)[near].sum(axis=(0, 1)), l_sun * omega, rtol=1e-3)
    assert 0.8e6 < procedural.REC709_LUMA @ l_sun < 1.6e6  # kcd/m^2
    # ground: one grey-brown constant below the horizon
    ground = img[h // 2 + 1:]
    assert np.ptp(ground.reshape(-1, 3), axis=0).max() == 0
    g = ground[0, 0]
    assert g[0] > g[1] > g[2] and g.max() < img[h // 2 - 1].mean(axis=0).max()
    # sky: bluer at the zenith than at the horizon
    assert img[0, 0, 2] > img[0, 0, 0]


def test_studio():
    h, w = 256, 512
    img = procedural.studio(w, h)
    assert np.all(np.isfinite(img)) and img.min() >= 0.02 - 1e-6
    for name, az, el, _pw, _ph, rgb in procedural.STUDIO_PANELS:
        d = procedural.direction(az, el)
        np.testing.assert_allclose(latlong.lookup(img, d[None])[0], rgb, rtol=1e-4, err_msg=name)
    assert latlong.lookup(img, procedural.direction(0.0, 10.0)[None])[0] == pytest.approx([0.02] * 3, abs=1e-6)
    assert latlong.lookup(img, np.array([[0.0, -1.0, 0.0]]))[0] == pytest.approx([0.06] * 3, abs=1e-3)


# ----------------------------------------------------------------------------- scene

SCENE = """
[camera]
position = [0.0, 0.0, 4.0]
[[objects]]
mesh = "sphere"
material = "m"
[materials.m]
model = "lambert"
albedo = 0.5
[environment]
"""


def _scene(tmp_path, env_text, name="s.toml"):
    p = tmp_path / name
    p.write_text(SCENE + env_text)
    return load_scene(str(p), load_meshes=False)


def test_scene_builtin_map(tmp_path):
    s = _scene(tmp_path, 'map = "studio"\nintensity = 2.0\nrotation_deg = 90.0\n')
    env = s.environment
    assert env.map == "studio" and env.constant is None and env.is_builtin
    m = env.radiance_map()
    assert m.shape == (512, 1024, 3) and not m.flags.writeable
    assert env.radiance_map() is m  # cached
    np.testing.assert_allclose(m, 2.0 * procedural.studio(1024, 512), rtol=1e-6)
    key = procedural.direction(-135.0, 35.0)
    # rotation applied at lookup: the key light now appears turned by +90 deg about +y
    np.testing.assert_allclose(env.lookup(latlong.rotation_y(90.0) @ key)[None][0],
                               2.0 * np.array(procedural.STUDIO_PANELS[0][5]), rtol=1e-3)
    assert 'map = "studio"' in scene_to_toml(s)


def test_scene_map_file_lookup(tmp_path):
    a = _rand_map(16, 32)
    (tmp_path / "maps").mkdir()
    save_environment(tmp_path / "maps" / "e.exr", a)
    s = _scene(tmp_path, 'map = "maps/e.exr"\nintensity = 0.5\n')
    d = latlong.texel_directions(16, 32)[5, 7]
    np.testing.assert_allclose(s.environment.lookup(d[None])[0], 0.5 * a[5, 7], rtol=1e-6)
    c = _scene(tmp_path, "constant = [1, 2, 3]\nintensity = 2.0\n", "c.toml")
    assert c.environment.radiance_map() is None
    np.testing.assert_allclose(c.environment.lookup(np.ones((4, 3))), [[2, 4, 6]] * 4)


def test_scene_bad_map_files(tmp_path):
    (tmp_path / "pic.hdr").write_bytes(b"\x89PNG\r\n\x1a\n" + b"\0" * 32)
    with pytest.raises(ViewerError) as e:
        _scene(tmp_path, 'map = "pic.hdr"\n')
    assert "s.toml: environment.map:" in str(e.value) and "pic.hdr" in str(e.value) and "PNG" in str(e.value)
    save_environment(tmp_path / "cut.exr", _rand_map(32, 64))
    data = (tmp_path / "cut.exr").read_bytes()
    (tmp_path / "cut.exr").write_bytes(data[: len(data) // 2])
    s = _scene(tmp_path, 'map = "cut.exr"\n')  # the signature is fine: decoded when first used
    with pytest.raises(ViewerError) as e:
        s.environment.radiance_map()
    msg = str(e.value)
    assert "\n" not in msg and "environment.map" in msg and "cut.exr" in msg and "truncated" in msg


def test_cli_exits_2_on_a_bad_map(tmp_path, capsys):
    from viewer.commands.cli import main

    (tmp_path / "pic.hdr").write_bytes(b"\x89PNG\r\n\x1a\n" + b"\0" * 32)
    p = tmp_path / "s.toml"
    p.write_text(SCENE + 'map = "pic.hdr"\n')
    out = tmp_path / "out.png"
    assert main(["render", str(p), "--out", str(out)]) == 2
    assert "pic.hdr" in capsys.readouterr().err and not out.exists()


def test_stored_dfg_table_is_the_computed_one(tmp_path, monkeypatch):
    """The DFG table kept in the disk cache reads back as computed, and a damaged entry is
    computed again (the multiple-scattering terms take it from there in every process)."""
    from viewer.environment.dfg import dfg_table, stored_dfg_table

    monkeypatch.setenv("BRDF_VIEWER_CACHE", str(tmp_path))
    want = dfg_table(8, 64)
    first = stored_dfg_table(8, 64)
    files = list(tmp_path.glob("dfg-*.npz"))
    assert len(files) == 1
    assert np.array_equal(first, want)
    with monkeypatch.context() as m:  # read from the file: nothing is computed
        m.setattr(dfg, "dfg_table", lambda *a: pytest.fail("computed again"))
        assert np.array_equal(stored_dfg_table(8, 64), want)
    files[0].write_bytes(b"not an npz")
    assert np.array_equal(stored_dfg_table(8, 64), want)


def test_built_in_maps_warmed_on_a_thread_are_generated_once_and_read_by_the_frame(monkeypatch):
    """``warm_builtin`` generates the maps into the disk cache beside the window's frames; a
    frame asking for one meanwhile waits for that generation rather than starting another, and
    later reads it from the cache (the window's thread never generates a warmed map)."""
    import threading

    from viewer.environment import procedural

    calls = []
    release = threading.Event()
    real = procedural.BUILTIN_MAPS["sky"]

    def counted(w, h):
        calls.append(threading.current_thread().name)
        release.wait(60)  # the frame below asks while this generation is under way
        return real(w, h)

    monkeypatch.setitem(procedural.BUILTIN_MAPS, "sky", counted)
    th = procedural.warm_builtin(lambda: ["sky"], width=64, height=32)
    while not calls:
        th.join(0.01)
    got = []
    frame = threading.Thread(target=lambda: got.append(procedural.generate("sky", 64, 32)))
    frame.start()
    release.set()
    th.join(60)
    frame.join(60)
    assert calls == ["brdf-viewer-builtin-maps"]  # generated once, on the warm-up thread
    assert np.array_equal(got[0], real(64, 32).astype(np.float32))
    assert np.array_equal(procedural.generate("sky", 64, 32), got[0]) and len(calls) == 1  # read back
