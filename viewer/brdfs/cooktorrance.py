"""The numpy twin of cooktorrance.brdf (shading frame: z = normal; wi toward the light)."""

import numpy as np


def eval(p, wi, wo):
    h = wi + wo
    h = h / np.maximum(np.linalg.norm(h, axis=1, keepdims=True), 1e-300)
    nh, nl, nv, vh = h[:, 2], wi[:, 2], wo[:, 2], np.sum(wo * h, axis=1)
    c2 = np.maximum(nh * nh, 1e-300)
    d = np.exp(-(1 - c2) / c2 / p.m ** 2) / (np.pi * p.m ** 2 * c2 * c2)
    g = np.minimum(1.0, np.minimum(2 * nh * nv / vh, 2 * nh * nl / vh))
    gg = np.sqrt(p.ior ** 2 - 1 + vh * vh)
    a = (gg - vh) / (gg + vh)
    b = (vh * (gg + vh) - 1) / (vh * (gg - vh) + 1)
    f = 0.5 * a * a * (1 + b * b)
    val = np.where(nh > 0, d * f * g / (4 * nl * nv), 0.0)
    return np.asarray(p.tint)[None, :] * val[:, None]
