"""Compiled (numba) stand-ins for the hot steps of a bounce, each checked against its numpy twin.

The wavefront integrator (``integrator.py``) spends most of a bounce in numpy's per-call cost
and temporaries on arrays of a few thousand paths. These steps are compiled here, each as a
function of one path (``*1``: scalars in, a tuple out) and a loop over arrays that calls it;
the fused bounce (``fused.py``) calls the same per-path functions from its one loop:

* ``hit_shading`` (``shade_hit1``): the surface points of a bounce's hits in the rasterizer's
  conventions (``integrator._Hits``): hit points, interpolated shading normals and tangents
  (``viewer.geometry.soup.hit_points`` / ``interpolate_shading``), the back-face flip, the
  geometric normal on the shading normal's side, the tangent frame (``soup.shading_frame``),
  ``wo`` in it and the ray offset. ``hit_shading_numpy`` is the same computed with the numpy
  functions of ``viewer.geometry.soup``: the twin the compiled loop is tested against.
* ``CompiledMicrofacet`` (``microfacet_eval1``, ``microfacet_pdf1``, ``microfacet_sample1``):
  the microfacet model (``viewer.brdf.microfacet``) for what the reference meets most, GGX
  with height-correlated Smith G, conductor or dielectric Fresnel (RGB eta, k, an ior, or a
  spectral table), with or without its diffuse base, no film or random walk: ``eval``, ``pdf``
  and ``sample_lobe`` with the twin's
  interface, arguments and random numbers, so the estimator and its random streams are
  unchanged. ``CompiledLambert`` (``lambert_*1``): ``viewer.brdf.lambert`` the same way. Both
  are ``CompiledStandIn``s: the interface's wrappers are written once there, and each stand-in
  states only its baked-in data and the compiled loops that take them.
  ``compiled_model`` says which materials they take (any other is evaluated by its numpy twin).
* ``constant_env_sample`` (``constant_env_sample1``, ``constant_env_pdf1``): light sampling of
  a constant environment (``viewer.reference_common.envmap.EnvironmentLight.sample`` / ``pdf``:
  cosine-weighted about the shading normal, the uniform sphere for transmissive surfaces).
* ``nee_candidates`` (``nee_test1``, ``nee_term1``): one next-event direction at a material
  group's hits (the light test, the contribution, the shadow ray's origin).
* ``embree_rays``, ``embree_hits`` (``embree_ray1``): the float32 rays
  ``kernel_embree.EmbreeKernel`` hands Embree, and its hits in float64; ``embree_intersect``,
  ``embree_occluded`` (``embree_intersect1``, ``embree_occluded1``): the same rays handed to
  Embree's C functions one by one (``kernel_embree.DirectScene``; the function and the
  RTCRayHit are passed as addresses, so the compiled code holds none and stays cacheable).
* ``draw_paths`` (``philox_uniform1``): the numbers numpy's ``Philox`` stream of a path holds
  for it at any bounce, computed for the live paths only (Philox4x64-10, Salmon et al. 2011).

The formulas are the twin's (``microfacet.eval_specular`` / ``pdf`` / ``sample``,
``microfacet_dist`` GGX ``D``, ``Lambda``, visible-normal sampling, ``fresnel.fresnel_conductor``,
``spectral_fresnel.lookup``, ``sampling.ratio_capped``, ``sampling.cosine_hemisphere``), step
by step in the same order, so results agree with the twin to a few float64 roundings;
tests/test_compiled_kernels.py and tests/test_fused_bounce.py check that on many random inputs
(below the horizon, grazing, and at the edges of the interpolation tables included).

Without numba every step runs its numpy twin. Compiled with ``cache=True``: the first process
in a fresh environment compiles what it calls (about 12 CPU seconds for the fused bounce, 5 for
the rest), later ones load numba's cache (about 0.3 CPU seconds, nearly all numba's own start; scipy's
linear algebra, which numba would import for nothing, is kept out: ``_load_numba_math_without_scipy``);
a worker does either at its start (``Integrator.warm``).
"""

from __future__ import annotations

import cmath
import math
import sys
import threading

import numpy as np


class _NoScipyLinalgInThisThread:
    """A finder on ``sys.meta_path`` that refuses ``scipy.linalg`` to the thread that made it
    and says nothing to any other (another thread's import of scipy goes on as ever)."""

    def __init__(self):
        self.thread = threading.get_ident()

    def find_spec(self, name, path=None, target=None):
        if name == "scipy.linalg" and threading.get_ident() == self.thread:
            raise ImportError("scipy.linalg is not loaded for numba's array math (viewer.pathtracer.compiled)")
        return None


def _load_numba_math_without_scipy():
    """Import ``numba.np.arraymath`` (numba loads it with its CPU target, at the first compile
    or cache load) while ``scipy.linalg`` cannot be imported in this thread. Its module body
    imports ``scipy.linalg`` only to pick the inner product of ``np.correlate`` /
    ``np.convolve`` (BLAS or a loop): about 0.2 CPU seconds in every worker process, and
    scipy's own OpenBLAS starts a thread pool that lasts as long as the process. Our kernels
    call neither function, so numba's loop is chosen and nothing else changes: a function that
    needs BLAS (``np.dot``, ``np.linalg``) still imports scipy when it is compiled
    (``numba.np.linalg.ensure_blas``)."""
    if "scipy.linalg" in sys.modules or "numba.np.arraymath" in sys.modules:
        return   # already paid for (or already decided): nothing to save
    finder = _NoScipyLinalgInThisThread()
    sys.meta_path.insert(0, finder)
    try:
        import numba.np.arraymath  # noqa: F401
    finally:
        sys.meta_path.remove(finder)


try:
    _load_numba_math_without_scipy()
    from llvmlite import ir as llvm_ir
    from numba import njit, types as nb_types
    from numba.extending import intrinsic
    HAVE_NUMBA = True
except ImportError:  # numba missing: every step runs its numpy twin (slower, the same values)
    HAVE_NUMBA = False

    def njit(*args, **kwargs):
        return lambda f: f

    def intrinsic(f):
        return f

from viewer.brdf import lobes as lobes_mod
from viewer.brdf import lambert, microfacet, spectral_fresnel, thin_film
from viewer.brdf.lobes import Lobe
from viewer.brdf.sampling import F_MAX, INV_PI
from viewer.geometry.soup import EPS_REL, hit_points, interpolate_shading, shading_frame

__all__ = ["hit_shading", "hit_shading_numpy", "CompiledStandIn", "CompiledMicrofacet", "CompiledLambert",
           "compiled_model", "constant_env_sample",
           "embree_rays", "embree_rays_numpy", "embree_hits", "embree_hits_numpy", "nee_candidates", "nee_candidates_numpy",
           "embree_intersect", "embree_occluded", "draw_paths", "philox_uniform1"]

_PI = np.pi
_INV_PI = 1.0 / np.pi
_INV_4PI = 1.0 / (4.0 * math.pi)


# ----------------------------------------------------------------------------- hit shading

@njit(cache=True, error_model="numpy", inline="always")
def shade_hit1(k, u, v, d0, d1, d2, tris, vnorm, vtan, gnorm, mat_index, trans_table):
    """The shading of one hit (triangle ``k`` at barycentrics (u, v) of a ray along d) as
    ``hit_shading`` defines it, as scalars: (p0, p1, p2, eps, winding normal g0..g2, shading
    normal n0..n2, geometric normal on its side ng0..ng2, tangent a0..a2, bitangent b0..b2,
    local wo0..wo2, material, transmissive). The one loop body of ``hit_shading`` and of the
    fused bounce (``viewer.pathtracer.fused``)."""
    w = 1.0 - u - v
    p0 = w * tris[k, 0, 0] + u * tris[k, 1, 0] + v * tris[k, 2, 0]
    p1 = w * tris[k, 0, 1] + u * tris[k, 1, 1] + v * tris[k, 2, 1]
    p2 = w * tris[k, 0, 2] + u * tris[k, 1, 2] + v * tris[k, 2, 2]
    pmax = 0.0
    if abs(p0) > pmax:
        pmax = abs(p0)
    if abs(p1) > pmax:
        pmax = abs(p1)
    if abs(p2) > pmax:
        pmax = abs(p2)
    eps = EPS_REL * (1.0 + pmax)
    # interpolated shading normal, normalized (the winding normal where it vanishes)
    n0 = w * vnorm[k, 0, 0] + u * vnorm[k, 1, 0] + v * vnorm[k, 2, 0]
    n1 = w * vnorm[k, 0, 1] + u * vnorm[k, 1, 1] + v * vnorm[k, 2, 1]
    n2 = w * vnorm[k, 0, 2] + u * vnorm[k, 1, 2] + v * vnorm[k, 2, 2]
    ln = math.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
    g0 = gnorm[k, 0]
    g1 = gnorm[k, 1]
    g2 = gnorm[k, 2]
    if ln > 1e-300:
        n0 /= ln
        n1 /= ln
        n2 /= ln
    else:
        n0, n1, n2 = g0, g1, g2
    t0 = w * vtan[k, 0, 0] + u * vtan[k, 1, 0] + v * vtan[k, 2, 0]
    t1 = w * vtan[k, 0, 1] + u * vtan[k, 1, 1] + v * vtan[k, 2, 1]
    t2 = w * vtan[k, 0, 2] + u * vtan[k, 1, 2] + v * vtan[k, 2, 2]
    t3 = w * vtan[k, 0, 3] + u * vtan[k, 1, 3] + v * vtan[k, 2, 3]
    m = mat_index[k]
    tr = trans_table[m]
    # a back-face hit flips the shading normal (not for transmissive materials)
    if (d0 * g0 + d1 * g1 + d2 * g2) > 0 and not tr:
        n0, n1, n2 = -n0, -n1, -n2
    s = -1.0 if (g0 * n0 + g1 * n1 + g2 * n2) < 0 else 1.0
    # tangent frame: t = tangent - n (n . tangent) normalized, b = cross(n, t) sign(w)
    dt = n0 * t0 + n1 * t1 + n2 * t2
    a0 = t0 - n0 * dt
    a1 = t1 - n1 * dt
    a2 = t2 - n2 * dt
    l2 = a0 * a0 + a1 * a1 + a2 * a2
    if not (l2 > 1e-12):
        if abs(n0) < 0.9:      # cross(n, x)
            a0, a1, a2 = 0.0, n2, -n1
        else:                  # cross(n, y)
            a0, a1, a2 = -n2, 0.0, n0
        lf = math.sqrt(a0 * a0 + a1 * a1 + a2 * a2)
        a0 /= lf
        a1 /= lf
        a2 /= lf
        l2 = 1.0
    sl = math.sqrt(l2)
    a0 /= sl
    a1 /= sl
    a2 /= sl
    sg = -1.0 if t3 < 0.0 else 1.0
    b0 = (n1 * a2 - n2 * a1) * sg
    b1 = (n2 * a0 - n0 * a2) * sg
    b2 = (n0 * a1 - n1 * a0) * sg
    o0, o1, o2 = -d0, -d1, -d2
    wo0 = o0 * a0 + o1 * a1 + o2 * a2
    wo1 = o0 * b0 + o1 * b1 + o2 * b2
    wo2 = o0 * n0 + o1 * n1 + o2 * n2
    return (p0, p1, p2, eps, g0, g1, g2, n0, n1, n2, g0 * s, g1 * s, g2 * s,
            a0, a1, a2, b0, b1, b2, wo0, wo1, wo2, m, tr)


@njit(cache=True, error_model="numpy", nogil=True)
def _hit_shading(tris, vnorm, vtan, gnorm, mat_index, trans_table, d, prim, bu, bv,
                 p, ng_raw, n, ng, tx, ty, wo_l, eps, mat, trans):
    for i in range(prim.shape[0]):
        (p[i, 0], p[i, 1], p[i, 2], eps[i], ng_raw[i, 0], ng_raw[i, 1], ng_raw[i, 2], n[i, 0], n[i, 1], n[i, 2],
         ng[i, 0], ng[i, 1], ng[i, 2], tx[i, 0], tx[i, 1], tx[i, 2], ty[i, 0], ty[i, 1], ty[i, 2],
         wo_l[i, 0], wo_l[i, 1], wo_l[i, 2], mat[i], trans[i]) = shade_hit1(
            prim[i], bu[i], bv[i], d[i, 0], d[i, 1], d[i, 2], tris, vnorm, vtan, gnorm, mat_index, trans_table)


def hit_shading(geom, trans_table, d, prim, bu, bv) -> dict:
    """The shading of hits (prim, bu, bv) of rays ``d`` on ``geom`` (a ``SceneGeometry``):
    a dict of p, ng_raw, n, ng, tx, ty, wo_l (each (M, 3)), eps (M,), mat (M,) and trans (M,)
    as ``integrator._Hits`` defines them (compiled; the twin is ``hit_shading_numpy``)."""
    if not HAVE_NUMBA:
        return hit_shading_numpy(geom, trans_table, d, prim, bu, bv)
    m = prim.shape[0]
    out = {k: np.empty((m, 3)) for k in ("p", "ng_raw", "n", "ng", "tx", "ty", "wo_l")}
    out["eps"] = np.empty(m)
    out["mat"] = np.empty(m, dtype=geom.material_index.dtype)
    out["trans"] = np.empty(m, dtype=bool)
    _hit_shading(geom.triangles, geom.normals, geom.tangents, geom.geo_normals, geom.material_index,
                 trans_table, np.ascontiguousarray(d, dtype=np.float64), np.ascontiguousarray(prim),
                 np.ascontiguousarray(bu, dtype=np.float64), np.ascontiguousarray(bv, dtype=np.float64),
                 out["p"], out["ng_raw"], out["n"], out["ng"], out["tx"], out["ty"], out["wo_l"],
                 out["eps"], out["mat"], out["trans"])
    return out


def hit_shading_numpy(geom, trans_table, d, prim, bu, bv) -> dict:
    """``hit_shading`` in numpy with ``viewer.geometry.soup``'s functions (the twin)."""
    p = hit_points(geom, prim, bu, bv)
    ng_raw = geom.geo_normals[prim]
    n, tan = interpolate_shading(geom, prim, bu, bv)
    mat = geom.material_index[prim]
    trans = trans_table[mat]
    flip = (np.sum(d * ng_raw, axis=1) > 0) & ~trans
    n = np.where(flip[:, None], -n, n)
    ng = ng_raw * np.where(np.sum(ng_raw * n, axis=1) < 0, -1.0, 1.0)[:, None]
    tx, ty = shading_frame(n, tan)
    wo = -d
    wo_l = np.stack([np.sum(wo * tx, axis=1), np.sum(wo * ty, axis=1), np.sum(wo * n, axis=1)], axis=1)
    eps = EPS_REL * (1.0 + np.abs(p).max(axis=1))
    return {"p": p, "ng_raw": ng_raw, "n": n, "ng": ng, "tx": tx, "ty": ty, "wo_l": wo_l, "eps": eps,
            "mat": mat, "trans": trans}


# ----------------------------------------------------------------------------- microfacet

@njit(cache=True, error_model="numpy", inline="always")
def _abs2(z):
    """|z|^2 as re^2 + im^2 (the twin squares np.abs, a hypot: the two differ in the last place)."""
    return z.real * z.real + z.imag * z.imag


# Not inlined by numba: its three calls per model evaluation, inlined into the fused bounce
# (``fused._shade``) with every caller, made that kernel take 110 CPU s to compile on a fresh
# cache; as a call it takes 21 s, and the bounce is as fast (8 spp of the default scene at
# 256 x 256: 0.41 CPU s either way) with bit-identical images.
@njit(cache=True, error_model="numpy")
def _fresnel(c, ch, md, m):
    """Channel ``ch`` of ``microfacet.fresnel_rgb`` at cos ``c`` for row ``m`` of the material
    data ``md`` (``material_rows``): the spectral table's lookup (``spectral_fresnel.lookup``)
    when the row has a table, else ``fresnel.fresnel_conductor`` of its eta, k, or, where k is
    negative (the mark of a dielectric), ``fresnel.fresnel_dielectric`` of index eta."""
    nt = int(md[m, MD_NROWS])
    if nt > 0:
        cc = min(max(c, 0.0), 1.0)
        x = math.sqrt(cc) * (nt - 1)
        i = min(int(math.floor(x)), nt - 2)
        f = x - i
        return md[m, MD_TABLE + 3 * i + ch] * (1.0 - f) + md[m, MD_TABLE + 3 * (i + 1) + ch] * f
    cc = min(max(c, 0.0), 1.0)
    if md[m, MD_K + ch] < 0:   # fresnel_dielectric_polarized (cos >= 0: light from outside, n_i = 1, n_t = eta)
        e = md[m, MD_ETA + ch]
        sin2_t = max(0.0, 1.0 - cc * cc) / (e * e)
        if sin2_t >= 1.0:
            return 1.0
        cos_t = math.sqrt(max(0.0, 1.0 - sin2_t))
        den_s = cc + e * cos_t
        den_p = e * cc + cos_t
        rs = (cc - e * cos_t) / den_s if den_s > 0 else 1.0
        rp = (e * cc - cos_t) / den_p if den_p > 0 else 1.0
        return 0.5 * (rs * rs + rp * rp)
    nc = complex(md[m, MD_ETA + ch], md[m, MD_K + ch])
    sin2 = complex(1.0 - cc * cc, 0.0)
    n2 = nc * nc
    w = cmath.sqrt(n2 - sin2)
    a = n2 * cc
    den_s = _abs2(cc + w)
    den_p = _abs2(a + w)
    rs = _abs2(cc - w) / den_s if den_s > 0 else 1.0
    rp = _abs2(a - w) / den_p if den_p > 0 else 1.0
    return 0.5 * (min(rs, 1.0) + min(rp, 1.0))


@njit(cache=True, error_model="numpy", inline="always")
def _lambda_ggx(wx, wy, wz, ax, ay):
    """microfacet_dist.lambda_ggx of one direction."""
    wz2 = wz * wz
    if not (wz2 > 0):
        return np.inf
    s = ((ax * wx) ** 2 + (ay * wy) ** 2) / wz2
    if s == np.inf:
        return np.inf
    return s / (2.0 * (1.0 + math.sqrt(1.0 + s)))


@njit(cache=True, error_model="numpy", inline="always")
def _d_ggx(mx, my, mz, ax, ay):
    """microfacet_dist.D_ggx of one normal."""
    t = (mx / ax) ** 2 + (my / ay) ** 2 + mz * mz
    if mz > 0 and t > 0:
        return 1.0 / (_PI * ax * ay * (t * t))
    return 0.0


@njit(cache=True, error_model="numpy", inline="always")
def _half(ix, iy, iz, ox, oy, oz):
    hx = ix + ox
    hy = iy + oy
    hz = iz + oz
    ln = math.sqrt(hx * hx + hy * hy + hz * hz)
    if not (ln > 0):
        ln = 1.0
    return hx / ln, hy / ln, hz / ln


@njit(cache=True, error_model="numpy", inline="always")
def _p_diffuse1(co, md, m):
    """microfacet._p_diffuse of one wo (cos ``co``): the probability of sampling the diffuse
    base, mean(kd (1 - F(co))) / (mean(kd (1 - F(co))) + mean(F(co))); 0 without a base."""
    kd0, kd1, kd2 = md[m, MD_KD], md[m, MD_KD + 1], md[m, MD_KD + 2]
    if not (kd0 > 0 or kd1 > 0 or kd2 > 0):
        return 0.0
    f0 = _fresnel(co, 0, md, m)
    f1 = _fresnel(co, 1, md, m)
    f2 = _fresnel(co, 2, md, m)
    wd = (kd0 * max(1.0 - f0, 0.0) + kd1 * max(1.0 - f1, 0.0) + kd2 * max(1.0 - f2, 0.0)) / 3.0
    ws = (f0 + f1 + f2) / 3.0
    tot = wd + ws
    return wd / tot if tot > 0 else 0.0


@njit(cache=True, error_model="numpy", inline="always")
def microfacet_eval1(ix, iy, iz, ox, oy, oz, ax, ay, md, m):
    """microfacet.eval of one pair: (f_r, f_g, f_b), ``eval_specular`` plus, where material row
    ``m`` has one, ``eval_diffuse`` (the Fresnel of row ``m``: ``_fresnel``)."""
    ok = iz > 0 and oz > 0
    if not ok:
        return 0.0, 0.0, 0.0
    hx, hy, hz = _half(ix, iy, iz, ox, oy, oz)
    D = _d_ggx(hx, hy, hz, ax, ay)
    ih = ix * hx + iy * hy + iz * hz
    oh = ox * hx + oy * hy + oz * hz
    if ih * iz > 0 and oh * oz > 0:
        G = 1.0 / (1.0 + _lambda_ggx(ix, iy, iz, ax, ay) + _lambda_ggx(ox, oy, oz, ax, ay))
    else:
        G = 0.0
    a = D * G
    b = 4.0 * (iz * oz)
    if a > 0:
        r = min(a / b, F_MAX) if b > 0 else F_MAX
    else:
        r = 0.0
    f0 = _fresnel(ih, 0, md, m) * r
    f1 = _fresnel(ih, 1, md, m) * r
    f2 = _fresnel(ih, 2, md, m) * r
    kd0, kd1, kd2 = md[m, MD_KD], md[m, MD_KD + 1], md[m, MD_KD + 2]
    if kd0 > 0 or kd1 > 0 or kd2 > 0:   # eval_diffuse: kd / pi (1 - F(ci)) (1 - F(co))
        f0 = f0 + kd0 * INV_PI * max(1.0 - _fresnel(iz, 0, md, m), 0.0) * max(
            1.0 - _fresnel(oz, 0, md, m), 0.0)
        f1 = f1 + kd1 * INV_PI * max(1.0 - _fresnel(iz, 1, md, m), 0.0) * max(
            1.0 - _fresnel(oz, 1, md, m), 0.0)
        f2 = f2 + kd2 * INV_PI * max(1.0 - _fresnel(iz, 2, md, m), 0.0) * max(
            1.0 - _fresnel(oz, 2, md, m), 0.0)
    return f0, f1, f2


@njit(cache=True, error_model="numpy", inline="always")
def _pdf_specular1(ix, iy, iz, ox, oy, oz, ax, ay):
    """microfacet._pdf_specular of one pair: the visible-normal density, reflected."""
    hx, hy, hz = _half(ix, iy, iz, ox, oy, oz)
    oh = ox * hx + oy * hy + oz * hz
    if not (oh > 0):
        return 0.0
    g1 = 1.0 / (1.0 + _lambda_ggx(ox, oy, oz, ax, ay)) if oh * oz > 0 else 0.0
    pm = g1 * max(0.0, oh) * _d_ggx(hx, hy, hz, ax, ay) / oz
    return pm / (4.0 * oh)


@njit(cache=True, error_model="numpy", inline="always")
def microfacet_pdf1(ix, iy, iz, ox, oy, oz, ax, ay, md, m):
    """microfacet.pdf of one pair (no walk): the specular density and, where material row ``m``
    has a diffuse base, the mixture with the cosine lobe by ``_p_diffuse1``."""
    if not (iz > 0 and oz > 0):
        return 0.0
    pd = _p_diffuse1(oz, md, m)
    ps = _pdf_specular1(ix, iy, iz, ox, oy, oz, ax, ay)
    return (1.0 - pd) * ps + pd * max(iz, 0.0) * INV_PI


@njit(cache=True, error_model="numpy", inline="always")
def _vndf_reflect1(sx, sy, sz, u0, u1, ax, ay):
    """microfacet_dist.sample_vndf_ggx of the upper-hemisphere direction s (Heitz 2018,
    listing 1: stretch, an orthonormal basis about it, a point on the warped disk, unstretch),
    then s mirrored about that normal (``sampling.reflect``)."""
    vx, vy, vz = ax * sx, ay * sy, sz
    lv = math.sqrt(vx * vx + vy * vy + vz * vz)
    if lv > 0:
        vx, vy, vz = vx / lv, vy / lv, vz / lv
    lensq = vx * vx + vy * vy
    if lensq > 0:
        inv = 1.0 / math.sqrt(lensq)
        t1x, t1y, t1z = -vy * inv, vx * inv, 0.0 * inv
    else:
        t1x, t1y, t1z = 1.0, 0.0, 0.0
    t2x = vy * t1z - vz * t1y
    t2y = vz * t1x - vx * t1z
    t2z = vx * t1y - vy * t1x
    rr = math.sqrt(u0)
    phi = 2.0 * _PI * u1
    p1 = rr * math.cos(phi)
    p2 = rr * math.sin(phi)
    s = 0.5 * (1.0 + vz)
    p2 = (1.0 - s) * math.sqrt(max(0.0, 1.0 - p1 * p1)) + s * p2
    q = math.sqrt(max(0.0, 1.0 - p1 * p1 - p2 * p2))
    nx = p1 * t1x + p2 * t2x + q * vx
    ny = p1 * t1y + p2 * t2y + q * vy
    nz = p1 * t1z + p2 * t2z + q * vz
    mx, my, mz = ax * nx, ay * ny, max(1e-12, nz)
    lm = math.sqrt(mx * mx + my * my + mz * mz)
    if lm > 0:
        mx, my, mz = mx / lm, my / lm, mz / lm
    dm = sx * mx + sy * my + sz * mz
    return 2.0 * dm * mx - sx, 2.0 * dm * my - sy, 2.0 * dm * mz - sz


@njit(cache=True, error_model="numpy", inline="always")
def microfacet_sample1(ox, oy, oz, u0, u1, ax, ay, md, m):
    """microfacet.sample (no walk) of one wo: the diffuse base with probability
    ``_p_diffuse1`` (u0 rescaled within its choice) by the cosine lobe, else visible-normal
    sampling of wo (the pole for wo below the horizon), mirrored; (wi x, y, z, weight f cos /
    pdf r, g, b, pdf) with the whole model's f and pdf."""
    up = oz > 0
    sx, sy, sz = (ox, oy, oz) if up else (0.0, 0.0, 1.0)
    pdif = _p_diffuse1(sz, md, m)
    diffuse = u0 < pdif
    if diffuse:
        uu = u0 / (pdif if pdif > 0 else 1.0)
    else:
        uu = (u0 - pdif) / ((1.0 - pdif) if pdif < 1 else 1.0)
    uu = min(max(uu, 0.0), 1.0 - 1e-16)
    if diffuse:
        ix, iy, iz = cosine_hemisphere1(uu, u1)
    else:
        ix, iy, iz = _vndf_reflect1(sx, sy, sz, uu, u1, ax, ay)
    pd = microfacet_pdf1(ix, iy, iz, ox, oy, oz, ax, ay, md, m)
    if up and iz > 0 and pd > 0:
        f0, f1, f2 = microfacet_eval1(ix, iy, iz, ox, oy, oz, ax, ay, md, m)
        sc = iz / pd
        return ix, iy, iz, f0 * sc, f1 * sc, f2 * sc, pd
    return ix, iy, iz, 0.0, 0.0, 0.0, 0.0


@njit(cache=True, error_model="numpy", nogil=True)
def _mf_eval(wi, wo, ax, ay, md, out):
    r = wo.shape[0]
    for j in range(wi.shape[0]):
        i = j % r
        out[j, 0], out[j, 1], out[j, 2] = microfacet_eval1(wi[j, 0], wi[j, 1], wi[j, 2], wo[i, 0], wo[i, 1],
                                                           wo[i, 2], ax, ay, md, 0)


@njit(cache=True, error_model="numpy", nogil=True)
def _mf_pdf(wi, wo, ax, ay, md, out):
    for j in range(wi.shape[0]):
        out[j] = microfacet_pdf1(wi[j, 0], wi[j, 1], wi[j, 2], wo[j, 0], wo[j, 1], wo[j, 2], ax, ay, md, 0)


@njit(cache=True, error_model="numpy", nogil=True)
def _mf_sample(wo, u, ax, ay, md, wi, weight, pdf):
    for j in range(wo.shape[0]):
        (wi[j, 0], wi[j, 1], wi[j, 2], weight[j, 0], weight[j, 1], weight[j, 2],
         pdf[j]) = microfacet_sample1(wo[j, 0], wo[j, 1], wo[j, 2], u[j, 0], u[j, 1], ax, ay, md, 0)


MD_ETA, MD_K, MD_KD, MD_NROWS, MD_TABLE = 0, 3, 6, 9, 10


def material_rows(models) -> np.ndarray:
    """The data of microfacet models (``CompiledMicrofacet``; other entries None) as one float64
    row each, what ``_fresnel`` and the microfacet functions read: eta (3), k (3; -1 marks a
    dielectric of index eta), kd (3), the spectral table's rows, the table (rows x 3,
    flattened). One array, not five: every array handed down a chain of inlined functions
    costs atomic reference counts in the loop."""
    rows = max([m.table.shape[0] for m in models if m is not None] + [0])
    md = np.zeros((len(models), MD_TABLE + 3 * rows))
    for i, m in enumerate(models):
        if m is not None:
            md[i, MD_ETA:MD_ETA + 3], md[i, MD_K:MD_K + 3], md[i, MD_KD:MD_KD + 3] = m.eta, m.k, m.kd
            md[i, MD_NROWS] = m.table.shape[0]
            md[i, MD_TABLE:MD_TABLE + m.table.size] = m.table.reshape(-1)
    return md


def _f64(a):
    return np.ascontiguousarray(a, dtype=np.float64)


class CompiledStandIn:
    """What the compiled stand-ins of a material's model share: the interface the integrator
    uses of a ``viewer.brdf.Model`` (``lobes``, and ``eval``, ``pdf``, ``sample_lobe`` on (N, 3)
    local directions; ``p`` is accepted and must be the material's parameters: a stand-in bakes
    them in; ``eval`` takes ``wi`` as r stacked sets of the N ``wo``, ``wo`` given once or
    tiled), the inputs made contiguous float64 and the outputs allocated here. A subclass bakes
    in its material's data (``__init__``, after this one's) and states how its compiled loops
    take them: ``_eval_into(wi, wo, out)``, ``_pdf_into(wi, wo, out)`` and ``_sample_into(wo, u,
    wi, weight, pdf)``, each filling the arrays it is given."""

    def __init__(self, p, twin):
        self.twin = twin
        own = twin.lobes(p)
        # what sample_lobe reports of every sample: delta where the model is, else its smooth lobes, reflected
        self.lobe = np.uint8((Lobe.DELTA if own.is_delta else own & lobes_mod.SMOOTH) | Lobe.REFLECTION)

    def lobes(self, p=None):
        return self.twin.lobes(p)

    def eval(self, p, wi, wo):
        wi, wo = _f64(wi), _f64(wo)
        out = np.empty((wi.shape[0], 3))
        self._eval_into(wi, wo, out)
        return out

    def pdf(self, p, wi, wo):
        wi, wo = _f64(wi), _f64(wo)
        out = np.empty(wi.shape[0])
        self._pdf_into(wi, wo, out)
        return out

    def sample_lobe(self, p, wo, u):
        wo, u = _f64(wo), _f64(u)
        n = wo.shape[0]
        wi, weight, pdf = np.empty((n, 3)), np.empty((n, 3)), np.empty(n)
        self._sample_into(wo, u, wi, weight, pdf)
        return wi, weight, pdf, np.full(n, self.lobe, dtype=lobes_mod.DTYPE)


class CompiledMicrofacet(CompiledStandIn):
    """The microfacet model of one material (see ``compiled_model``); its alphas, Fresnel data
    and diffuse base are baked in (``material_rows``)."""

    def __init__(self, p, twin):
        super().__init__(p, twin)
        self.ax = float(p.alpha_x)
        self.ay = float(p.alpha_y)
        if p.fresnel == "conductor":
            self.eta = np.ascontiguousarray(np.asarray(p.eta, dtype=np.float64).reshape(3))
            self.k = np.ascontiguousarray(np.asarray(p.k, dtype=np.float64).reshape(3))
        else:   # a dielectric of index ior, marked by k = -1 (``_fresnel``)
            self.eta, self.k = np.full(3, float(p.ior)), np.full(3, -1.0)
        self.kd = np.ascontiguousarray(np.asarray(p.kd, dtype=np.float64).reshape(3))
        if p.spectral != spectral_fresnel.NONE:
            self.table = np.array(spectral_fresnel.table(p.spectral), dtype=np.float64, order="C")  # writable: one compiled signature
        else:
            self.table = np.zeros((0, 3))
        self.md = material_rows([self])   # the data as the per-path functions read it

    def _eval_into(self, wi, wo, out):
        _mf_eval(wi, wo, self.ax, self.ay, self.md, out)

    def _pdf_into(self, wi, wo, out):
        _mf_pdf(wi, wo, self.ax, self.ay, self.md, out)

    def _sample_into(self, wo, u, wi, weight, pdf):
        _mf_sample(wo, u, self.ax, self.ay, self.md, wi, weight, pdf)


# ----------------------------------------------------------------------------- Lambert

@njit(cache=True, error_model="numpy", inline="always")
def lambert_eval1(iz, oz, r, g, b):
    """lambert.eval of one pair with albedo (r, g, b)."""
    if iz > 0 and oz > 0:
        return r * INV_PI, g * INV_PI, b * INV_PI
    return 0.0, 0.0, 0.0


@njit(cache=True, error_model="numpy", inline="always")
def lambert_pdf1(iz, oz):
    """lambert.pdf of one pair: cos / pi above the horizon (``sampling.cosine_hemisphere_pdf``)."""
    return max(iz, 0.0) * INV_PI if oz > 0 else 0.0


@njit(cache=True, error_model="numpy", inline="always")
def lambert_sample1(oz, u0, u1, r, g, b):
    """lambert.sample of one wo: (wi x, y, z, weight = albedo where the pdf is positive, pdf)."""
    x, y, z = cosine_hemisphere1(u0, u1)
    pd = lambert_pdf1(z, oz)
    if pd > 0:
        return x, y, z, r, g, b, pd
    return x, y, z, 0.0, 0.0, 0.0, pd


@njit(cache=True, error_model="numpy", nogil=True)
def _lambert_eval(wi, wo, alb, out):
    r = wo.shape[0]
    for j in range(wi.shape[0]):
        out[j, 0], out[j, 1], out[j, 2] = lambert_eval1(wi[j, 2], wo[j % r, 2], alb[0], alb[1], alb[2])


@njit(cache=True, error_model="numpy", nogil=True)
def _lambert_pdf(wi, wo, out):
    for j in range(wi.shape[0]):
        out[j] = lambert_pdf1(wi[j, 2], wo[j, 2])


@njit(cache=True, error_model="numpy", nogil=True)
def _lambert_sample(wo, u, alb, wi, weight, pdf):
    for j in range(wo.shape[0]):
        (wi[j, 0], wi[j, 1], wi[j, 2], weight[j, 0], weight[j, 1], weight[j, 2],
         pdf[j]) = lambert_sample1(wo[j, 2], u[j, 0], u[j, 1], alb[0], alb[1], alb[2])


class CompiledLambert(CompiledStandIn):
    """The Lambert model of one material (``viewer.brdf.lambert``); the albedo is baked in."""

    def __init__(self, p, twin):
        super().__init__(p, twin)
        self.albedo = np.ascontiguousarray(np.asarray(p.albedo, dtype=np.float64).reshape(3))

    def _eval_into(self, wi, wo, out):
        _lambert_eval(wi, wo, self.albedo, out)

    def _pdf_into(self, wi, wo, out):
        _lambert_pdf(wi, wo, out)

    def _sample_into(self, wo, u, wi, weight, pdf):
        _lambert_sample(wo, u, self.albedo, wi, weight, pdf)


def compiled_model(p, twin):
    """A compiled stand-in for ``twin`` (the registry model of material parameters ``p``), or
    None where none applies: ``twin`` runs ``viewer.brdf.lambert``, or ``viewer.brdf.microfacet``
    (the module these kernels repeat) with GGX, Smith G, conductor or dielectric Fresnel (RGB or
    a spectral table), with or without a diffuse base, no thin film, no multiple scattering."""
    module = getattr(twin, "module", None)
    if not HAVE_NUMBA or module not in (microfacet, lambert):
        return None
    if twin.hook("sample_lobe") is not None or twin.hook("reference_model") is not None:
        return None
    if module is lambert:
        return CompiledLambert(p, twin)
    ok = (p.distribution == "ggx" and p.shadowing == "smith" and p.fresnel in ("conductor", "dielectric")
          and not bool(p.get("multiple_scattering", False))
          and not twin.has_film(p) and not thin_film.at_point(p) and not thin_film.varies(p))
    return CompiledMicrofacet(p, twin) if ok else None


# ----------------------------------------------------------------------------- constant environment

@njit(cache=True, error_model="numpy", inline="always")
def cosine_hemisphere1(u0, u1):
    """``sampling.cosine_hemisphere`` of one pair: Malley's method on the concentric disk
    (Shirley-Chiu 1997); (x, y, z)."""
    a = 2.0 * u0 - 1.0
    b = 2.0 * u1 - 1.0
    if abs(a) > abs(b):
        rr = a
        phi = (_PI / 4) * (b / (1.0 if a == 0 else a))
    else:
        rr = b
        phi = (_PI / 2) - (_PI / 4) * (a / (1.0 if b == 0 else b))
    if a == 0 and b == 0:
        rr = 0.0
    lx = rr * math.cos(phi)
    ly = rr * math.sin(phi)
    return lx, ly, math.sqrt(max(0.0, 1.0 - lx * lx - ly * ly))


@njit(cache=True, error_model="numpy", inline="always")
def constant_env_sample1(u0, u1, n0, n1, n2, two_sided):
    """EnvironmentLight.sample of a constant environment at one hit: Malley's method in the
    frame of ``sampling.frame_from_z`` about the shading normal, pdf cos / pi; a uniform
    sphere, pdf 1 / (4 pi), where ``two_sided``. (wi x, y, z, pdf)."""
    if two_sided:
        z = 1.0 - 2.0 * u0
        r = math.sqrt(max(0.0, 1.0 - z * z))
        phi = 2.0 * math.pi * u1
        return r * math.cos(phi), r * math.sin(phi), z, _INV_4PI
    lx, ly, lz = cosine_hemisphere1(u0, u1)
    sign = 1.0 if n2 >= 0.0 else -1.0
    aa = -1.0 / (sign + n2)
    bb = n0 * n1 * aa
    x0, x1, x2 = 1.0 + sign * n0 ** 2 * aa, sign * bb, -sign * n0
    y0, y1, y2 = bb, sign + n1 ** 2 * aa, -n1
    return (lx * x0 + ly * y0 + lz * n0, lx * x1 + ly * y1 + lz * n1, lx * x2 + ly * y2 + lz * n2,
            lz / math.pi)


@njit(cache=True, error_model="numpy", inline="always")
def constant_env_pdf1(d0, d1, d2, n0, n1, n2, two_sided):
    """EnvironmentLight.pdf of a constant environment for one direction."""
    if two_sided:
        return _INV_4PI
    return max(d0 * n0 + d1 * n1 + d2 * n2, 0.0) / math.pi


@njit(cache=True, error_model="numpy", nogil=True)
def _constant_env_sample(u, nrm, two_sided, wi, pdf):
    for i in range(u.shape[0]):
        wi[i, 0], wi[i, 1], wi[i, 2], pdf[i] = constant_env_sample1(u[i, 0], u[i, 1], nrm[i, 0], nrm[i, 1], nrm[i, 2],
                                                                    two_sided[i])


def constant_env_sample(env, u, normals, two_sided):
    """``env.sample(u, normals, two_sided)`` of a constant ``EnvironmentLight`` (compiled; the
    twin is ``viewer.reference_common.envmap.EnvironmentLight.sample``)."""
    if not HAVE_NUMBA:
        return env.sample(u, normals, two_sided)
    n = u.shape[0]
    wi, pdf = np.empty((n, 3)), np.empty(n)
    _constant_env_sample(np.ascontiguousarray(u, dtype=np.float64), np.ascontiguousarray(normals, dtype=np.float64),
                         np.ascontiguousarray(two_sided, dtype=np.bool_), wi, pdf)
    return wi, np.broadcast_to(env.constant, (n, 3)).copy(), pdf


# ----------------------------------------------------------------------------- Embree rays

@njit(cache=True, error_model="numpy", inline="always")
def embree_ray1(o0, o1, o2, d0, d1, d2, centre, tmin, tmax, big):
    """One float32 ray as ``embree_rays`` makes it: (origin x, y, z, direction x, y, z, far,
    whether far is positive)."""
    far = min(tmax - tmin, big)
    return (np.float32((o0 - centre[0]) + tmin * d0), np.float32((o1 - centre[1]) + tmin * d1),
            np.float32((o2 - centre[2]) + tmin * d2), np.float32(d0), np.float32(d1), np.float32(d2),
            np.float32(far if far > 0 else 0.0), far > 0)


@njit(cache=True, error_model="numpy", nogil=True)
def _embree_rays(o, d, centre, tmin, tmax, big, o32, d32, far32, live):
    for i in range(o.shape[0]):
        (o32[i, 0], o32[i, 1], o32[i, 2], d32[i, 0], d32[i, 1], d32[i, 2], far32[i],
         live[i]) = embree_ray1(o[i, 0], o[i, 1], o[i, 2], d[i, 0], d[i, 1], d[i, 2], centre, tmin, tmax[i], big)


def embree_rays(o, d, centre, tmin, tmax, big):
    """The float32 rays ``kernel_embree.EmbreeKernel`` hands Embree: origins shifted by
    ``-centre`` and moved to ``tmin`` along ``d``, directions, far distances ``min(tmax - tmin,
    big)`` (0 where not positive), and whether that is positive (compiled; the twin is
    ``embree_rays_numpy``)."""
    if not HAVE_NUMBA:
        return embree_rays_numpy(o, d, centre, tmin, tmax, big)
    n = o.shape[0]
    o32, d32 = np.empty((n, 3), np.float32), np.empty((n, 3), np.float32)
    far32, live = np.empty(n, np.float32), np.empty(n, np.bool_)
    _embree_rays(np.ascontiguousarray(o, dtype=np.float64), np.ascontiguousarray(d, dtype=np.float64),
                 np.ascontiguousarray(centre, dtype=np.float64), float(tmin),
                 np.ascontiguousarray(tmax, dtype=np.float64), float(big), o32, d32, far32, live)
    return o32, d32, far32, live


@njit(cache=True, error_model="numpy", nogil=True)
def _embree_hits(prim_id, tfar, u32, v32, live, tmin, t, prim, u, v):
    for i in range(prim_id.shape[0]):
        k = prim_id[i]
        if k >= 0 and live[i]:
            prim[i] = k
            t[i] = np.float64(tfar[i]) + tmin
            u[i] = u32[i]
            v[i] = v32[i]
        else:
            prim[i] = -1
            t[i] = np.inf
            u[i] = 0.0
            v[i] = 0.0


def embree_hits(res, live, tmin):
    """(t, prim, u, v) in float64 / int64 from Embree's closest-hit results ``res`` (a miss, or
    a ray whose interval was empty: prim -1, t inf, u = v = 0; t shifted back by ``tmin``).
    Compiled; the twin is ``embree_hits_numpy``."""
    if not HAVE_NUMBA:
        return embree_hits_numpy(res, live, tmin)
    n = live.shape[0]
    t, prim, u, v = np.empty(n), np.empty(n, np.int64), np.empty(n), np.empty(n)
    _embree_hits(np.ascontiguousarray(res["primID"]), np.ascontiguousarray(res["tfar"]),
                 np.ascontiguousarray(res["u"]), np.ascontiguousarray(res["v"]), live, float(tmin), t, prim, u, v)
    return t, prim, u, v


def embree_hits_numpy(res, live, tmin):
    """``embree_hits`` in numpy."""
    n = live.shape[0]
    t, prim, u, v = np.full(n, np.inf), np.full(n, -1, dtype=np.int64), np.zeros(n), np.zeros(n)
    p = res["primID"].astype(np.int64)
    hit = (p >= 0) & live
    prim[hit] = p[hit]
    t[hit] = res["tfar"][hit].astype(np.float64) + tmin
    u[hit] = res["u"][hit]
    v[hit] = res["v"][hit]
    return t, prim, u, v


def embree_rays_numpy(o, d, centre, tmin, tmax, big):
    """``embree_rays`` in numpy."""
    o32 = np.ascontiguousarray((o - centre + tmin * d).astype(np.float32))
    d32 = np.ascontiguousarray(d.astype(np.float32))
    far = np.minimum(tmax - tmin, big)
    far32 = np.ascontiguousarray(np.where(far > 0, far, 0.0).astype(np.float32))
    return o32, d32, far32, far > 0


# ----------------------------------------------------------------------------- Embree, ray by ray

@intrinsic
def _c_call3(typingctx, fn, a, b, c):
    """Call the C function at address ``fn`` (void f(void *, void *, void *)) with three
    addresses. An address taken as an argument, not baked into the code: the compiled
    functions stay cacheable across processes."""
    u64 = nb_types.uint64
    sig = nb_types.void(u64, u64, u64, u64)

    def codegen(context, builder, signature, args):
        i8p = llvm_ir.IntType(8).as_pointer()
        fnty = llvm_ir.FunctionType(llvm_ir.VoidType(), [i8p, i8p, i8p])
        fptr = builder.inttoptr(args[0], fnty.as_pointer())
        builder.call(fptr, [builder.inttoptr(x, i8p) for x in args[1:]])
        return context.get_dummy_value()

    return sig, codegen


def _mem_intrinsic(kind, store):
    """An intrinsic that loads (``store`` False: (addr, index) -> value) or stores ((addr,
    index, value)) element ``index`` of the float32 / uint32 array at address ``addr``: the
    RTCRayHit is reached through its address, so no array (and no reference count) travels
    through the per-ray functions."""
    u64, i64 = nb_types.uint64, nb_types.int64
    val = nb_types.float32 if kind == "f32" else nb_types.uint32

    def impl(typingctx, addr, index, value=None):
        def codegen(context, builder, signature, args):
            lty = llvm_ir.FloatType() if kind == "f32" else llvm_ir.IntType(32)
            ptr = builder.gep(builder.inttoptr(args[0], lty.as_pointer()), [args[1]])
            if store:
                builder.store(args[2], ptr)
                return context.get_dummy_value()
            return builder.load(ptr)

        sig = nb_types.void(u64, i64, val) if store else val(u64, i64)
        return sig, codegen

    if store:
        def typer(typingctx, addr, index, value):
            return impl(typingctx, addr, index, value)
    else:
        def typer(typingctx, addr, index):
            return impl(typingctx, addr, index)
    typer.__name__ = f"_{'st' if store else 'ld'}_{kind}"
    return intrinsic(typer)


_ld_f32 = _mem_intrinsic("f32", False)
_st_f32 = _mem_intrinsic("f32", True)
_ld_u32 = _mem_intrinsic("u32", False)
_st_u32 = _mem_intrinsic("u32", True)
_INVALID_ID = 0xFFFFFFFF


@njit(cache=True, error_model="numpy", inline="always")
def _ray_into(rh, ox, oy, oz, dx, dy, dz, far):
    """Fill the RTCRayHit at address ``rh`` (uint32 words: the ray's 12, then the hit's) with a
    float32 ray from tnear 0 to ``far``, every mask bit, no hit."""
    _st_f32(rh, 0, ox)
    _st_f32(rh, 1, oy)
    _st_f32(rh, 2, oz)
    _st_f32(rh, 3, np.float32(0.0))
    _st_f32(rh, 4, dx)
    _st_f32(rh, 5, dy)
    _st_f32(rh, 6, dz)
    _st_f32(rh, 7, np.float32(0.0))
    _st_f32(rh, 8, far)
    _st_u32(rh, 9, np.uint32(_INVALID_ID))    # mask
    _st_u32(rh, 10, np.uint32(0))             # id
    _st_u32(rh, 11, np.uint32(0))             # flags
    _st_u32(rh, 18, np.uint32(_INVALID_ID))   # geomID
    _st_u32(rh, 19, np.uint32(_INVALID_ID))   # instID[0]


@njit(cache=True, error_model="numpy", inline="always")
def embree_intersect1(scene, fn, rh, ox, oy, oz, dx, dy, dz, far, live, tmin):
    """``rtcIntersect1`` of one float32 ray (``compiled.embree_rays``'s conventions) with the
    RTCRayHit at address ``rh`` (16-byte aligned, 80 bytes or more): (prim, t, u, v) as
    ``embree_hits`` gives them (a miss or a dead ray: -1, inf, 0, 0)."""
    if not live:
        return -1, np.inf, 0.0, 0.0
    _ray_into(rh, ox, oy, oz, dx, dy, dz, far)
    _c_call3(fn, scene, rh, np.uint64(0))
    if _ld_u32(rh, 18) == _INVALID_ID:
        return -1, np.inf, 0.0, 0.0
    return (np.int64(_ld_u32(rh, 17)), np.float64(_ld_f32(rh, 8)) + tmin, np.float64(_ld_f32(rh, 15)),
            np.float64(_ld_f32(rh, 16)))


@njit(cache=True, error_model="numpy", inline="always")
def embree_occluded1(scene, fn, rh, ox, oy, oz, dx, dy, dz, far, live):
    """``rtcOccluded1`` of one float32 ray: whether something lies between tnear and ``far``
    (Embree sets tfar to -inf when it finds a hit)."""
    if not live:
        return False
    _ray_into(rh, ox, oy, oz, dx, dy, dz, far)
    _c_call3(fn, scene, rh, np.uint64(0))
    return _ld_f32(rh, 8) == -np.inf


@njit(cache=True, error_model="numpy", nogil=True)
def _embree_intersect(scene, fn, rh, o32, d32, far32, live, tmin, t, prim, u, v):
    for i in range(o32.shape[0]):
        prim[i], t[i], u[i], v[i] = embree_intersect1(scene, fn, rh, o32[i, 0], o32[i, 1], o32[i, 2], d32[i, 0],
                                                      d32[i, 1], d32[i, 2], far32[i], live[i], tmin)


@njit(cache=True, error_model="numpy", nogil=True)
def _embree_occluded(scene, fn, rh, o32, d32, far32, live, out):
    for i in range(o32.shape[0]):
        out[i] = embree_occluded1(scene, fn, rh, o32[i, 0], o32[i, 1], o32[i, 2], d32[i, 0], d32[i, 1], d32[i, 2],
                                  far32[i], live[i])


def embree_intersect(direct, o32, d32, far32, live, tmin):
    """(t, prim, u, v) of the float32 rays (``embree_rays``) in ``direct`` (a
    ``kernel_embree.DirectScene``), ray by ray; what ``embree_hits`` makes of Embree's batch."""
    n = o32.shape[0]
    t, prim, u, v = np.empty(n), np.empty(n, np.int64), np.empty(n), np.empty(n)
    _embree_intersect(np.uint64(direct.scene), np.uint64(direct.intersect1), np.uint64(direct.rayhit_address), o32,
                      d32, far32, live, float(tmin), t, prim, u, v)
    return t, prim, u, v


def embree_occluded(direct, o32, d32, far32, live):
    """(N,) bool: which float32 rays (``embree_rays``) something in ``direct`` blocks."""
    out = np.empty(o32.shape[0], np.bool_)
    _embree_occluded(np.uint64(direct.scene), np.uint64(direct.occluded1), np.uint64(direct.rayhit_address), o32,
                     d32, far32, live, out)
    return out


# ----------------------------------------------------------------------------- Philox, number by number

@intrinsic
def _mulhilo64(typingctx, a, b):
    """(high, low) 64-bit words of the 128-bit product of two uint64 (Random123's mulhilo64)."""
    u64 = nb_types.uint64
    sig = nb_types.UniTuple(u64, 2)(u64, u64)

    def codegen(context, builder, signature, args):
        i128, i64 = llvm_ir.IntType(128), llvm_ir.IntType(64)
        prod = builder.mul(builder.zext(args[0], i128), builder.zext(args[1], i128))
        hi = builder.trunc(builder.lshr(prod, llvm_ir.Constant(i128, 64)), i64)
        return context.make_tuple(builder, signature.return_type, [hi, builder.trunc(prod, i64)])

    return sig, codegen


_PHILOX_M0 = np.uint64(0xD2E7470EE14C6C93)
_PHILOX_M1 = np.uint64(0xCA5A826395121157)
_PHILOX_W0 = np.uint64(0x9E3779B97F4A7C15)
_PHILOX_W1 = np.uint64(0xBB67AE8584CAA73B)
_DOUBLE_UNIT = 1.0 / 9007199254740992.0   # 2^-53


@njit(cache=True, error_model="numpy", inline="always")
def philox4x64_10(c0, c1, c2, c3, k0, k1):
    """Philox4x64 with 10 rounds of counter (c0..c3) and key (k0, k1) (Salmon et al. 2011;
    Random123's philox4x64_R, the function numpy's ``Philox`` runs): four uint64."""
    for r in range(10):
        if r > 0:
            k0 += _PHILOX_W0
            k1 += _PHILOX_W1
        hi0, lo0 = _mulhilo64(_PHILOX_M0, c0)
        hi1, lo1 = _mulhilo64(_PHILOX_M1, c2)
        c0, c1, c2, c3 = hi1 ^ c1 ^ k0, lo1, hi0 ^ c3 ^ k1, lo0
    return c0, c1, c2, c3


@njit(cache=True, error_model="numpy", inline="always")
def philox_uniform1(k0, k1, c2, c3, q):
    """The ``q``-th double (from 0) that ``Generator(Philox(key=(k0, k1), counter=(0, 0, c2,
    c3))).random()`` returns: numpy's Philox raises the counter's low word before each block of
    four uint64 (the first block is counter + 1), and a double is the top 53 bits of one uint64
    times 2^-53."""
    blk = q // np.uint64(4)
    w = philox4x64_10(blk + np.uint64(1), np.uint64(0), c2, c3, k0, k1)
    lane = q % np.uint64(4)
    x = w[0] if lane == 0 else (w[1] if lane == 1 else (w[2] if lane == 2 else w[3]))
    return np.float64(x >> np.uint64(11)) * _DOUBLE_UNIT


@njit(cache=True, error_model="numpy", nogil=True)
def _draw_paths(act, m, k0, k1, stream, pix, c2, c3, first, width, rnd):
    """Row ``act[i]`` of ``rnd`` (N, width) for the i < m paths ``act``: numbers first[s] +
    width * pix .. + width - 1 of the path's stream s = ``stream[a]`` (counter (0, 0, c2[s],
    c3[s])), each Philox block computed once for the numbers it holds."""
    for i in range(m):
        a = act[i]
        s = stream[a]
        q = first[s] + np.uint64(width) * np.uint64(pix[a])
        blk = q // np.uint64(4)
        w = philox4x64_10(blk + np.uint64(1), np.uint64(0), c2[s], c3[s], k0, k1)
        for k in range(width):
            qk = q + np.uint64(k)
            if qk // np.uint64(4) != blk:
                blk = qk // np.uint64(4)
                w = philox4x64_10(blk + np.uint64(1), np.uint64(0), c2[s], c3[s], k0, k1)
            lane = qk % np.uint64(4)
            x = w[0] if lane == 0 else (w[1] if lane == 1 else (w[2] if lane == 2 else w[3]))
            rnd[a, k] = np.float64(x >> np.uint64(11)) * _DOUBLE_UNIT


def draw_paths(act, k0, k1, stream, pix, c2, c3, first, rnd):
    """Fill the rows ``act`` of ``rnd`` (N, width) with the numbers the paths' Philox streams
    (see ``_draw_paths``; ``first`` per stream, uint64) hold for them (compiled)."""
    _draw_paths(np.ascontiguousarray(act, np.int64), int(act.shape[0]), np.uint64(k0), np.uint64(k1),
                stream, pix, c2, c3, first, int(rnd.shape[1]), rnd)


# ----------------------------------------------------------------------------- next-event candidates

@njit(cache=True, error_model="numpy", inline="always")
def nee_test1(wl2, ww0, ww1, ww2, ng0, ng1, ng2, p0, p1, p2, eps, share, extra_ok, transmissive):
    """One next-event direction at one hit as ``nee_candidates`` defines it, but its
    contribution: (whether it passes the light test and ``extra_ok``, the factor ``|cos|
    share``, the shadow ray's origin: the hit point ``p`` offset by ``eps`` along ``ng`` to the
    side ``ww`` leaves)."""
    gcos = ng0 * ww0 + ng1 * ww1 + ng2 * ww2
    z = wl2
    good = z * gcos > 0 if transmissive else (z > 0 and gcos > 0)
    good = good and extra_ok
    cs = abs(z) * share
    side = -1.0 if gcos < 0 else 1.0
    e = eps * side
    return good, cs, p0 + e * ng0, p1 + e * ng1, p2 + e * ng2


@njit(cache=True, error_model="numpy", inline="always")
def nee_term1(t, f, cs, fac):
    """One channel of a next-event contribution: throughput, BSDF, cosine (and share), light."""
    return t * f * cs * fac


@njit(cache=True, error_model="numpy", nogil=True)
def _nee_candidates(wl, ww, ng, sel, p, eps, T, f, fac, share, extra_ok, transmissive, ok, c, o):
    for i in range(wl.shape[0]):
        j = sel[i]
        good, cs, o[i, 0], o[i, 1], o[i, 2] = nee_test1(
            wl[i, 2], ww[i, 0], ww[i, 1], ww[i, 2], ng[i, 0], ng[i, 1], ng[i, 2], p[j, 0], p[j, 1], p[j, 2], eps[j],
            1.0 if share.shape[0] == 0 else share[i], True if extra_ok.shape[0] == 0 else extra_ok[i], transmissive)
        pos = False
        for k in range(T.shape[1]):
            v = nee_term1(T[i, k], f[i, k], cs, fac[i, k])
            c[i, k] = v
            pos = pos or v > 0
        ok[i] = good and pos


def nee_candidates(wl, ww, ng, sel, p, eps, T, f, fac, share, extra_ok, transmissive):
    """One next-event direction at a material group's hits: (ok, contribution, shadow-ray
    origin) as ``integrator._next_event`` defines them: the rasterizer's light test (shading
    cosine ``wl.z`` and geometric ``ng . ww`` on the same side, both positive unless
    ``transmissive``) and ``extra_ok`` (None: all), contribution ``T f |cos| share fac`` (``share``
    None: 1) with a positive channel, origin ``p + eps n_g`` on the side ``ww`` leaves (``p``,
    ``eps`` indexed by ``sel``). Compiled; the twin is ``nee_candidates_numpy``."""
    if not HAVE_NUMBA:
        return nee_candidates_numpy(wl, ww, ng, sel, p, eps, T, f, fac, share, extra_ok, transmissive)
    k, ch = T.shape
    ok, c, o = np.empty(k, np.bool_), np.empty((k, ch)), np.empty((k, 3))
    f64 = np.float64
    _nee_candidates(np.ascontiguousarray(wl, dtype=f64), np.ascontiguousarray(ww, dtype=f64),
                    np.ascontiguousarray(ng, dtype=f64), np.ascontiguousarray(sel, dtype=np.int64), p, eps,
                    np.ascontiguousarray(T, dtype=f64), np.ascontiguousarray(f, dtype=f64),
                    np.ascontiguousarray(fac, dtype=f64),
                    np.zeros(0) if share is None else np.ascontiguousarray(share, dtype=f64),
                    np.zeros(0, np.bool_) if extra_ok is None else np.ascontiguousarray(extra_ok, dtype=np.bool_),
                    bool(transmissive), ok, c, o)
    return ok, c, o


def nee_candidates_numpy(wl, ww, ng, sel, p, eps, T, f, fac, share, extra_ok, transmissive):
    """``nee_candidates`` in numpy (the integrator's steps before it was compiled)."""
    g = np.sum(ng * ww, axis=1)
    ok = wl[:, 2] * g > 0 if transmissive else (wl[:, 2] > 0) & (g > 0)
    if extra_ok is not None:
        ok &= extra_ok
    cos = np.abs(wl[:, 2]) if share is None else np.abs(wl[:, 2]) * share
    c = T * f * cos[:, None] * fac
    ok &= np.any(c > 0, axis=1)
    side = np.where(g < 0, -1.0, 1.0)
    return ok, c, p[sel] + (eps[sel] * side)[:, None] * ng


# ----------------------------------------------------------------------------- a path's numbers, inline

@njit(cache=True, error_model="numpy", inline="always")
def _word8(w, v, j):
    """Word ``j`` (0..7) of two Philox blocks ``w`` then ``v`` as a double in [0, 1) (the top
    53 bits times 2^-53, numpy's ``random``)."""
    if j < 4:
        x = w[0] if j == 0 else (w[1] if j == 1 else (w[2] if j == 2 else w[3]))
    else:
        x = v[0] if j == 4 else (v[1] if j == 5 else (v[2] if j == 6 else v[3]))
    return np.float64(x >> np.uint64(11)) * _DOUBLE_UNIT


@njit(cache=True, error_model="numpy", inline="always")
def stream_numbers5(q, c2, c3, k0, k1, cached_blk, cached):
    """Numbers ``q`` .. ``q + 4`` (from 0) of the Philox stream with counter (0, 0, c2, c3) and
    key (k0, k1), as ``philox_uniform1`` gives them one by one: five numbers always span two
    blocks, q // 4 and the next. ``cached``: the words of block ``cached_blk`` (a path's
    neighbour in the same stream computed it: its last block is this path's first), reused
    instead of computed again. Returns the five numbers and (index, words) of the last block."""
    four = np.uint64(4)
    b0 = q // four
    if b0 == cached_blk:
        w = cached
    else:
        w = philox4x64_10(b0 + np.uint64(1), np.uint64(0), c2, c3, k0, k1)
    v = philox4x64_10(b0 + np.uint64(2), np.uint64(0), c2, c3, k0, k1)
    lane = np.int64(q % four)
    return (_word8(w, v, lane), _word8(w, v, lane + 1), _word8(w, v, lane + 2), _word8(w, v, lane + 3),
            _word8(w, v, lane + 4), b0 + np.uint64(1), v)


@njit(cache=True, error_model="numpy", inline="always")
def stream_numbers2(q, c2, c3, k0, k1, cached_blk, cached):
    """Numbers ``q`` and ``q + 1`` (``q`` even: one block) of a Philox stream (see
    ``stream_numbers5``); returns them and (index, words) of their block."""
    b0 = q // np.uint64(4)
    if b0 == cached_blk:
        w = cached
    else:
        w = philox4x64_10(b0 + np.uint64(1), np.uint64(0), c2, c3, k0, k1)
    lane = np.int64(q % np.uint64(4))
    return _word8(w, w, lane), _word8(w, w, lane + 1), b0, w
