"""The whole bounce in one compiled loop: the integrator's estimator (``integrator.py``) for the
scenes every step of which has a compiled stand-in.

``_shade`` runs, path by path, what ``Integrator.trace_paths`` and its steps do material group
by material group in numpy: the ray's closest hit, the environment reached by a ray that missed
(weighted against light sampling), the hit's shading (``compiled.shade_hit1``), next-event
estimation of every point and directional light and of the constant environment
(``compiled.constant_env_sample1``, the material's ``eval1`` and ``pdf1``, the MIS heuristic,
``compiled.nee_test1`` and ``nee_term1``) with its shadow rays, the BSDF sample (``sample1``),
light sampling's density in its direction, the new throughput, Russian roulette, and the next
ray. With Embree's ``DirectScene`` (``kernel_embree.py``) every ray and shadow ray goes to
Embree from inside the loop and an unoccluded contribution is added at once; with another ray
kernel (numba's, or Embree through ``embreex``) the closest hits come from one batched query
before the loop, the shadow rays are written out, and ``_add_unoccluded`` adds the unoccluded
ones' contributions after a batched occlusion query. The next wavefront (compacted, in path
order) goes into arrays allocated once per wavefront size.

``FusedBounce.render`` is ``Integrator.render_blocks``' wavefront: the camera rays
(``_camera_rays``) and every bounce's random numbers are computed here, each path's from its
Philox stream ``philox(seed, block, sample)`` (``compiled.stream_numbers5``: the two numbers
of the jitter, then five per bounce at the offsets numpy's draws would give them; a path
reuses the Philox block its neighbour in the stream ended in, and a ray that misses draws
nothing). ``FusedBounce.trace`` takes rays and a ``draw()`` from the caller
(``Integrator.trace``). (All of a chunk's bounces in one compiled call would save the Python
call of ``_shade`` per bounce, about 1.5% of a chunk's time, but LLVM inlines ``_shade`` into
that caller, so a fresh environment would compile it twice: 9 more CPU seconds.)

Nothing here is a formula of its own: the per-path steps are the functions of
``viewer.pathtracer.compiled`` (each tested against its numpy twin), called in the order of the
numpy steps and on the same random numbers (of a path's five a bounce: two the BSDF's, two the
environment's, one roulette's), so an image agrees with the numpy path to roundoff
(tests/test_fused_bounce.py), and a seed gives the same image every time.

Where it applies (``plan``): the RGB path tracer itself (not the spectral or photon
integrators, which override its steps), every material a ``CompiledLambert`` or
``CompiledMicrofacet``, none transmissive and none a film over height, a constant (or black)
environment, point and directional lights. Any other scene runs the numpy steps, unchanged.
"""

from __future__ import annotations

import numpy as np

from viewer.brdf.lobes import Lobe
from viewer.pathtracer import compiled
from viewer.pathtracer.compiled import (
    HAVE_NUMBA, CompiledLambert, CompiledMicrofacet, constant_env_pdf1, constant_env_sample1, embree_intersect1,
    embree_occluded1, embree_ray1, lambert_eval1, lambert_pdf1, lambert_sample1, microfacet_eval1, microfacet_pdf1,
    microfacet_sample1, nee_term1, nee_test1, shade_hit1, material_rows, stream_numbers2, stream_numbers5)
from viewer.pathtracer.kernel_embree import F32_MAX_T
from viewer.reference_common.estimator import RR_MAX, RR_MIN, RR_START_DEPTH

__all__ = ["FusedBounce", "plan"]

njit = compiled.njit
LAMBERT, MICROFACET = 0, 1
STRATEGY = {"mis": 0, "bsdf": 1, "light": 2}
POINT, DIRECTIONAL = 0, 1
DIMS = 5                     # numbers per path and bounce (integrator.DIMS_PER_BOUNCE; ``compiled.stream_numbers5``)
JITTER = 2                   # numbers per path drawn for the camera ray before the first bounce
NO_BLOCK = np.uint64(2**64 - 1)   # no Philox block cached


# ----------------------------------------------------------------------------- per path

@njit(cache=True, error_model="numpy", inline="always")
def _heuristic(a, b, power):
    """integrator._power (Veach 1997, eq. 9.13) or integrator._balance (eq. 9.10)."""
    if power:
        a2, b2 = a * a, b * b
        s = a2 + b2
        return a2 / s if s > 0 else 0.0
    s = a + b
    return a / s if s > 0 else 0.0


@njit(cache=True, error_model="numpy", inline="always")
def _clean(x):
    """Integrator._clean of one model output: (x, 0), or (0, 1) where x is NaN, Inf or negative."""
    if not (x >= 0.0) or x == np.inf:
        return 0.0, 1
    return x, 0


# ----------------------------------------------------------------------------- one bounce

@njit(cache=True, error_model="numpy", nogil=True)
def _shade(depth, scatter, m, act, o, d, prim, bu, bv, rnd, computed, k0, k1, stream, pix, ctr2, ctr3, first,
           direct, centre, scene, fn_hit, fn_occ, rh,
           tris, vnorm, vtan, gnorm, mat_index, trans_table,
           kinds, nee_on, delta, albedo, ax, ay, md,
           lkind, lpos, lval, env, env_on, env_by_light, env_by_bsdf, strategy, power, roulette,
           L, T, prev_pdf, prev_lpdf, prev_delta,
           act_out, o_out, d_out, s_idx, s_o, s_d, s_tmax, s_c, bad):
    """One bounce of the ``m`` rays (paths ``act``, origins ``o``, directions ``d``).
    ``direct``: each ray and shadow ray goes to Embree here (``scene``, the addresses of
    rtcIntersect1 / rtcOccluded1 and of an RTCRayHit ``rh``, the scene's ``centre``) and each
    unoccluded contribution is added at once; else their closest hits are (prim, bu, bv)
    (prim < 0: a miss) and the shadow rays are written out for a batched query. ``scatter``
    False: the rays after the last scattering event (only the environment they reach).
    Returns (next wavefront's size, shadow rays written out); ``bad[0]`` counts the model
    outputs cleaned (``Integrator.bad_values``)."""
    nl = lkind.shape[0]
    n_out = 0
    ns = 0
    nbad = 0
    c_st, c_blk = -1, NO_BLOCK   # the stream and Philox block the last path's numbers ended in
    c_w = (np.uint64(0), np.uint64(0), np.uint64(0), np.uint64(0))
    for i in range(m):
        a = act[i]
        if direct:
            x0, x1, x2, y0, y1, y2, far, live = embree_ray1(o[i, 0], o[i, 1], o[i, 2], d[i, 0], d[i, 1], d[i, 2],
                                                            centre, 0.0, np.inf, F32_MAX_T)
            k, _, hu, hv = embree_intersect1(scene, fn_hit, rh, x0, x1, x2, y0, y1, y2, far, live, 0.0)
        else:
            k, hu, hv = prim[i], bu[i], bv[i]
        if k < 0:
            # BSDF sampling's part of the environment (Integrator._bsdf_hits_environment)
            if env_on:
                if strategy == 0:
                    wm = 1.0 if prev_delta[a] else _heuristic(prev_pdf[a], prev_lpdf[a], power)
                elif strategy == 1:
                    wm = 1.0
                else:
                    wm = 1.0 if prev_delta[a] else 0.0
                for c in range(3):
                    L[a, c] += T[a, c] * env[c] * wm
            continue
        if not scatter:
            continue
        (p0, p1, p2, eps, gr0, gr1, gr2, n0, n1, n2, g0, g1, g2, t0, t1, t2, b0, b1, b2,
         o0, o1, o2, mt, tr) = shade_hit1(k, hu, hv, d[i, 0], d[i, 1], d[i, 2], tris, vnorm, vtan, gnorm,
                                          mat_index, trans_table)
        lam = kinds[mt] == LAMBERT
        tb0, tb1, tb2 = T[a, 0], T[a, 1], T[a, 2]
        # the path's five numbers of this bounce
        if computed:
            st = stream[a]
            q = first[st] + np.uint64(DIMS) * np.uint64(pix[a])
            u0, u1, u2, u3, u4, c_blk, c_w = stream_numbers5(q, ctr2[st], ctr3[st], k0, k1,
                                                             c_blk if st == c_st else NO_BLOCK, c_w)
            c_st = st
        else:
            u0, u1, u2, u3, u4 = rnd[a, 0], rnd[a, 1], rnd[a, 2], rnd[a, 3], rnd[a, 4]
        # light sampling of the environment (Integrator._light_sample_environment)
        e0, e1, e2, pe = 0.0, 0.0, 0.0, 0.0
        if env_by_light:
            e0, e1, e2, pe = constant_env_sample1(u2, u3, n0, n1, n2, tr)
            pe, nb = _clean(pe)
            nbad += nb
        # next-event estimation (Integrator._next_event): the delta lights, then the environment
        if nee_on[mt]:
            for j in range(nl + 1):
                if j < nl:
                    if lkind[j] == POINT:
                        dv0, dv1, dv2 = lpos[j, 0] - p0, lpos[j, 1] - p1, lpos[j, 2] - p2
                        r2 = max(dv0 * dv0 + dv1 * dv1 + dv2 * dv2, 1e-300)
                        r = np.sqrt(r2)
                        w0, w1, w2 = dv0 / r, dv1 / r, dv2 / r
                        fc0, fc1, fc2 = lval[j, 0] / r2, lval[j, 1] / r2, lval[j, 2] / r2
                        tmax = r - eps
                    else:
                        w0, w1, w2 = -lpos[j, 0], -lpos[j, 1], -lpos[j, 2]
                        fc0, fc1, fc2 = lval[j, 0], lval[j, 1], lval[j, 2]
                        tmax = np.inf
                elif env_by_light:
                    w0, w1, w2 = e0, e1, e2
                    tmax = np.inf
                else:
                    break
                l0 = w0 * t0 + w1 * t1 + w2 * t2
                l1 = w0 * b0 + w1 * b1 + w2 * b2
                l2 = w0 * n0 + w1 * n1 + w2 * n2
                if lam:
                    f0, f1, f2 = lambert_eval1(l2, o2, albedo[mt, 0], albedo[mt, 1], albedo[mt, 2])
                else:
                    f0, f1, f2 = microfacet_eval1(l0, l1, l2, o0, o1, o2, ax[mt], ay[mt], md, mt)
                f0, nb0 = _clean(f0)
                f1, nb1 = _clean(f1)
                f2, nb2 = _clean(f2)
                nbad += nb0 + nb1 + nb2
                extra = True
                if j == nl:   # the environment: MIS against BSDF sampling
                    extra = pe > 0
                    if strategy == 0:
                        if lam:
                            pb = lambert_pdf1(l2, o2)
                        else:
                            pb = microfacet_pdf1(l0, l1, l2, o0, o1, o2, ax[mt], ay[mt], md, mt)
                        pb, nb = _clean(pb)
                        nbad += nb
                        wmis = _heuristic(pe, pb, power) / (pe if pe > 0 else 1.0)
                    else:
                        wmis = 1.0 / (pe if pe > 0 else 1.0)
                    fc0, fc1, fc2 = env[0] * wmis, env[1] * wmis, env[2] * wmis
                good, cs, q0, q1, q2 = nee_test1(l2, w0, w1, w2, g0, g1, g2, p0, p1, p2, eps, 1.0, extra, tr)
                c0 = nee_term1(tb0, f0, cs, fc0)
                c1 = nee_term1(tb1, f1, cs, fc1)
                c2 = nee_term1(tb2, f2, cs, fc2)
                if not (good and (c0 > 0 or c1 > 0 or c2 > 0)):
                    continue
                if direct:   # the shadow ray now; Integrator._trace_shadows' sum
                    x0, x1, x2, y0, y1, y2, far, live = embree_ray1(q0, q1, q2, w0, w1, w2, centre, 0.0, tmax,
                                                                    F32_MAX_T)
                    if not embree_occluded1(scene, fn_occ, rh, x0, x1, x2, y0, y1, y2, far, live):
                        L[a, 0] += c0
                        L[a, 1] += c1
                        L[a, 2] += c2
                else:
                    s_idx[ns] = a
                    s_o[ns, 0], s_o[ns, 1], s_o[ns, 2] = q0, q1, q2
                    s_d[ns, 0], s_d[ns, 1], s_d[ns, 2] = w0, w1, w2
                    s_tmax[ns] = tmax
                    s_c[ns, 0], s_c[ns, 1], s_c[ns, 2] = c0, c1, c2
                    ns += 1
        # the BSDF sample (Integrator._sample_bsdf, _scatter)
        if lam:
            x, y, z, wt0, wt1, wt2, pdf_s = lambert_sample1(o2, u0, u1, albedo[mt, 0], albedo[mt, 1],
                                                            albedo[mt, 2])
        else:
            x, y, z, wt0, wt1, wt2, pdf_s = microfacet_sample1(o0, o1, o2, u0, u1, ax[mt], ay[mt], md,
                                                               mt)
        wt0, nb0 = _clean(wt0)
        wt1, nb1 = _clean(wt1)
        wt2, nb2 = _clean(wt2)
        pdf_s, nb3 = _clean(pdf_s)
        nbad += nb0 + nb1 + nb2 + nb3
        if not (np.isfinite(x) and np.isfinite(y) and np.isfinite(z)):
            nbad += 1
            x, y, z = 0.0, 0.0, 1.0
            wt0, wt1, wt2 = 0.0, 0.0, 0.0
        disc = delta[mt]
        q0 = x * t0 + y * b0 + z * n0
        q1 = x * t1 + y * b1 + z * n1
        q2 = x * t2 + y * b2 + z * n2
        gc = g0 * q0 + g1 * q1 + g2 * q2
        valid = z * gc > 0 if tr else (z > 0 and gc > 0)
        if not (valid and pdf_s > 0 and (wt0 > 0 or wt1 > 0 or wt2 > 0)):
            wt0, wt1, wt2 = 0.0, 0.0, 0.0
        lpdf = 0.0
        if env_by_light and env_by_bsdf:   # MIS: light sampling's density there
            lpdf = 0.0 if disc else constant_env_pdf1(q0, q1, q2, n0, n1, n2, tr)
        # the new throughput, roulette, the next ray (Integrator._continue, _roulette)
        tb0, tb1, tb2 = tb0 * wt0, tb1 * wt1, tb2 * wt2
        alive = tb0 > 0 or tb1 > 0 or tb2 > 0
        if roulette and depth >= RR_START_DEPTH:
            qs = min(max(max(tb0, max(tb1, tb2)), RR_MIN), RR_MAX)
            alive = alive and u4 < qs
            tb0, tb1, tb2 = tb0 / qs, tb1 / qs, tb2 / qs
        T[a, 0], T[a, 1], T[a, 2] = tb0, tb1, tb2
        prev_pdf[a] = pdf_s
        prev_lpdf[a] = lpdf
        prev_delta[a] = disc
        if alive:
            e = eps * (-1.0 if gc < 0 else 1.0)
            act_out[n_out] = a
            o_out[n_out, 0] = p0 + e * g0
            o_out[n_out, 1] = p1 + e * g1
            o_out[n_out, 2] = p2 + e * g2
            d_out[n_out, 0], d_out[n_out, 1], d_out[n_out, 2] = q0, q1, q2
            n_out += 1
    bad[0] += nbad
    return n_out, ns


@njit(cache=True, error_model="numpy", nogil=True)
def _add_unoccluded(L, s_idx, s_c, blocked, ns):
    """Integrator._trace_shadows' sum: the unoccluded shadow rays' contributions, in ray order."""
    for j in range(ns):
        if not blocked[j]:
            a = s_idx[j]
            for c in range(3):
                L[a, c] += s_c[j, c]


# ----------------------------------------------------------------------------- a chunk

@njit(cache=True, error_model="numpy", nogil=True)
def _camera_rays(counts, row0, width, height, tan_half_y, aspect, pos, fwd, right, up, k0, k1, c2, c3,
                 stream, pix, o, d):
    """``Integrator._block_streams`` and ``camera_rays`` for the streams ``(c2, c3)`` = (block,
    sample) of ``counts`` paths each (block rows from ``row0``): each path's stream index and
    pixel (``stream``, ``pix``), its jitter (numbers 2 pix and 2 pix + 1 of its stream) and its
    camera ray (o, d), in the same arithmetic as the numpy steps. Returns the paths' count."""
    a = 0
    for s in range(counts.shape[0]):
        cblk = NO_BLOCK
        cw = (np.uint64(0), np.uint64(0), np.uint64(0), np.uint64(0))
        for p in range(counts[s]):
            j0, j1, cblk, cw = stream_numbers2(np.uint64(JITTER) * np.uint64(p), c2[s], c3[s], k0, k1, cblk, cw)
            row, col = row0[s] + p // width, p % width
            x = (2.0 * (col + j0) / width - 1.0) * tan_half_y * aspect
            y = (1.0 - 2.0 * (row + j1) / height) * tan_half_y
            d0 = fwd[0] + x * right[0] + y * up[0]
            d1 = fwd[1] + x * right[1] + y * up[1]
            d2 = fwd[2] + x * right[2] + y * up[2]
            r = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
            d[a, 0], d[a, 1], d[a, 2] = d0 / r, d1 / r, d2 / r
            o[a, 0], o[a, 1], o[a, 2] = pos[0], pos[1], pos[2]
            stream[a], pix[a] = s, p
            a += 1
    return a


# ----------------------------------------------------------------------------- the integrator's side

def plan(it) -> "FusedBounce | None":
    """The fused bounce for integrator ``it`` (an ``Integrator``), or None where a step has no
    compiled stand-in (see the module docstring)."""
    s = it.s
    if not HAVE_NUMBA or it.CHANNELS != 3 or s.env.is_map or it.trans_table.any():
        return None
    if not all(isinstance(m, (CompiledLambert, CompiledMicrofacet)) for m in it.models) or not it.models:
        return None
    if any(kind not in ("point", "directional") for kind, _, _ in s.lights):
        return None
    return FusedBounce(it)


class FusedBounce:
    """``Integrator.trace_paths`` with every bounce one ``_shade`` call (see the module
    docstring); buffers are allocated once per wavefront size and reused."""

    def __init__(self, it):
        s = it.s
        models = it.models
        nm = len(models)
        self.kinds = np.array([LAMBERT if isinstance(m, CompiledLambert) else MICROFACET for m in models], np.int64)
        self.nee_on = np.array([not info.lobes.is_delta for info in s.materials], np.bool_)
        self.delta = np.array([bool(m.lobe & np.uint8(Lobe.DELTA)) for m in models], np.bool_)
        self.albedo = np.zeros((nm, 3))
        self.ax, self.ay = np.ones(nm), np.ones(nm)
        for i, m in enumerate(models):
            if isinstance(m, CompiledLambert):
                self.albedo[i] = m.albedo
            else:
                self.ax[i], self.ay[i] = m.ax, m.ay
        self.md = material_rows([m if isinstance(m, CompiledMicrofacet) else None for m in models])
        nl = len(s.lights)
        self.lkind = np.array([POINT if kind == "point" else DIRECTIONAL for kind, _, _ in s.lights], np.int64)
        self.lpos = np.array([a for _, a, _ in s.lights], np.float64).reshape(nl, 3)
        self.lval = np.array([v for _, _, v in s.lights], np.float64).reshape(nl, 3)
        self.env = np.ascontiguousarray(np.asarray(s.env.constant, np.float64).reshape(3))
        # Embree called from inside the loop where the kernel has a DirectScene (kernel_embree.py)
        self.direct = getattr(it.kernel, "direct", None)
        self.centre = np.ascontiguousarray(np.asarray(getattr(it.kernel, "centre", np.zeros(3)), np.float64))
        self._cap = -1

    def _buffers(self, n: int):
        """Wavefront buffers for ``n`` paths (two sets of (act, o, d) taking turns), the shadow
        rays a batched occlusion query takes, and each path's stream and pixel."""
        if n > self._cap:
            rows = 1 if self.direct is not None else n * (self.lkind.shape[0] + 1)
            self._act = [np.empty(n, np.int64), np.empty(n, np.int64)]
            self._o = [np.empty((n, 3)), np.empty((n, 3))]
            self._d = [np.empty((n, 3)), np.empty((n, 3))]
            self._s_idx = np.empty(rows, np.int64)
            self._s_o, self._s_d, self._s_c = np.empty((rows, 3)), np.empty((rows, 3)), np.empty((rows, 3))
            self._s_tmax = np.empty(rows)
            self._stream, self._pix = np.empty(n, np.int64), np.empty(n, np.int64)
            self._cap = n
        return self

    def _args(self, it):
        """The scene's, the materials', the lights' and the options' arguments of ``_shade``."""
        g = it.geom
        ds = self.direct
        if ds is not None:
            rays = (True, self.centre, np.uint64(ds.scene), np.uint64(ds.intersect1), np.uint64(ds.occluded1),
                    np.uint64(ds.rayhit_address))
        else:
            rays = (False, self.centre, np.uint64(0), np.uint64(0), np.uint64(0), np.uint64(0))
        return rays, (g.triangles, g.normals, g.tangents, g.geo_normals, g.material_index, it.trans_table,
                      self.kinds, self.nee_on, self.delta, self.albedo, self.ax, self.ay, self.md,
                      self.lkind, self.lpos, self.lval, self.env, bool(it.env_on), bool(it.env_by_light),
                      bool(it.env_by_bsdf), STRATEGY[it.strategy], it.mis_heuristic == "power",
                      bool(it.russian_roulette))

    def trace(self, it, paths, o, d, draw):
        """``Integrator.trace_paths`` of integrator ``it`` (the one this was planned for) for
        ``paths`` along the rays (o, d), ``draw()`` giving each bounce's numbers of every path:
        their radiance ``paths.L`` before the final check for NaN (the integrator's). (The
        integrator is an argument, not an attribute: no reference cycle keeps a dropped
        integrator's Embree scene alive until a garbage collection.)"""
        n = o.shape[0]
        self._buffers(n)
        o = np.ascontiguousarray(o, np.float64)
        d = np.ascontiguousarray(d, np.float64)
        return self._bounces(it, paths, np.arange(n, dtype=np.int64), o, d, None, draw)

    def camera_rays(self, it, blocks, samples, key):
        """The camera rays (o, d) of ``Integrator.render_blocks``' wavefront (blocks ``(row0,
        row1, block_id)``, block by block and sample by sample), computed: each path's jitter is
        the first two numbers of its pixel in the stream ``philox(seed, block, sample)`` (``key``:
        its Philox key, ``integrator.philox_key``), as ``Integrator._block_streams`` draws them,
        and the ray ``Integrator.camera_rays``' in the same arithmetic. Returns (o, d) (views of
        this object's buffers) and what the bounces' numbers are computed from: (key 0, key 1,
        each path's stream and pixel, the streams' counter words 2 and 3, their paths' counts)."""
        s = it.s
        W = s.width
        counts = np.array([(r1 - r0) * W for r0, r1, _ in blocks for _ in samples], np.int64)
        row0 = np.array([r0 for r0, _, _ in blocks for _ in samples], np.int64)
        c2 = np.array([int(b) & 0xFFFFFFFFFFFFFFFF for _, _, b in blocks for _ in samples], np.uint64)
        c3 = np.array([int(si) & 0xFFFFFFFFFFFFFFFF for _ in blocks for si in samples], np.uint64)
        n = int(counts.sum())
        self._buffers(n)
        key = (np.uint64(key[0]), np.uint64(key[1]))
        o, d = self._o[0][:n], self._d[0][:n]
        cam = [np.ascontiguousarray(v, np.float64) for v in (s.cam_pos, s.cam_forward, s.cam_right, s.cam_up)]
        _camera_rays(counts, row0, W, s.height, float(s.tan_half_y), s.width / s.height, *cam, *key, c2, c3,
                     self._stream, self._pix, o, d)
        return o, d, key + (self._stream, self._pix, c2, c3, counts)

    def render(self, it, paths, blocks, samples, key):
        """``Integrator.render_blocks``' radiance ``paths.L`` (``paths``: the state of its
        wavefront's N paths) before the final check for NaN: the camera rays (``camera_rays``)
        and every bounce's numbers computed from the paths' Philox streams (``DIMS`` numbers per
        path and bounce after the jitter, what ``Integrator._block_streams`` and ``BounceDraws``
        draw), so the image is the numpy steps' to roundoff."""
        o, d, numbers = self.camera_rays(it, blocks, samples, key)
        return self._bounces(it, paths, np.arange(o.shape[0], dtype=np.int64), o, d, 0, numbers)

    def _bounces(self, it, paths, act, o, d, held, rnd_of):
        """The bounces of the paths ``act`` along (o, d) (``held``: which of the two buffer sets
        holds them, None: neither), a ``_shade`` call each; ``rnd_of``: ``draw`` (each bounce's
        numbers of every path) or the key, streams and pixels the numbers are computed from."""
        s, kernel = it.s, it.kernel
        bad = np.zeros(1, np.int64)
        no_rnd, no_i, no_f, no_u = np.zeros((0, DIMS)), np.zeros(0, np.int64), np.zeros(0), np.zeros(0, np.uint64)
        rays, args = self._args(it)
        computed = not callable(rnd_of)
        if computed:
            k0, k1, stream, pix, c2, c3, counts = rnd_of
        else:
            k0, k1, stream, pix, c2, c3, counts = np.uint64(0), np.uint64(0), no_i, no_i, no_u, no_u, no_i
        first = np.empty(len(counts), np.uint64)
        ds = self.direct
        for depth in range(1, s.max_depth + 2):
            m = act.shape[0]
            if m == 0:
                break
            scatter = depth <= s.max_depth
            rnd = no_rnd
            if computed:
                first[:] = counts.astype(np.uint64) * np.uint64(JITTER + DIMS * (depth - 1))
            elif scatter:
                rnd = np.ascontiguousarray(rnd_of(), np.float64)
            if ds is None:
                _, prim, bu, bv = kernel.intersect(o, d, 0.0, np.inf)
                prim = np.ascontiguousarray(prim, np.int64)
                bu, bv = np.ascontiguousarray(bu, np.float64), np.ascontiguousarray(bv, np.float64)
            else:
                prim, bu, bv = no_i, no_f, no_f
            out = 1 if held == 0 else 0
            act_out, o_out, d_out = self._act[out], self._o[out], self._d[out]
            m_out, ns = _shade(depth, scatter, m, act, o, d, prim, bu, bv, rnd, computed, k0, k1, stream, pix, c2, c3,
                               first, *rays, *args, paths.L, paths.T, paths.prev_pdf, paths.prev_lpdf,
                               paths.prev_delta, act_out, o_out, d_out, self._s_idx, self._s_o, self._s_d,
                               self._s_tmax, self._s_c, bad)
            if not scatter:
                break
            if ns:
                blocked = kernel.occluded(self._s_o[:ns], self._s_d[:ns], 0.0, self._s_tmax[:ns])
                _add_unoccluded(paths.L, self._s_idx, self._s_c, np.ascontiguousarray(blocked, np.bool_), ns)
            act, o, d, held = act_out[:m_out], o_out[:m_out], d_out[:m_out], out
        it.bad_values += int(bad[0])
        return paths.L

