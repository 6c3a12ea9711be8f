"""Light from infinitely far away for the reference engines (both build their environment from it): a constant radiance or a
lat-long radiance map, with the light-sampling strategies the integrator combines with BSDF
sampling by multiple importance sampling (Veach 1997, ch. 9).

Orientation (docs/conventions.md; the mapping is ``viewer.environment.latlong``'s): a world
direction d looks up the map at ``u = 0.5 + atan2(d.x, -d.z) / (2 pi)``, ``v = acos(d.y) / pi``
(v = 0 at the zenith = row 0), after the scene's rotation: ``L(d) = intensity * map(R_y(-rotation_deg) d)``.

Sampling
--------
* Constant environment: cosine-weighted hemisphere about the shading normal (pdf cos / pi) for
  reflection-only surfaces, uniform sphere (pdf 1 / (4 pi)) for transmissive ones, whose
  integrand covers both hemispheres.
* Map: the texels are piecewise constant (nearest lookup, so the sampled density and the
  radiance agree exactly). A texel's weight is its luminance times sin(theta) at its row
  centre (its solid angle up to a constant); a row is picked from the marginal distribution,
  a column from the row's conditional one, then a uniform point inside the texel (pbrt-v3
  14.2.4, "Infinite area lights"). The density in (u, v) is ``w / sum(w) * W * H``, and per
  solid angle ``p(omega) = p(u, v) / (2 pi^2 sin(theta))`` (the Jacobian of
  (u, v) -> (theta = pi v, phi = 2 pi u)).
"""

from __future__ import annotations

import math

import numpy as np

from viewer import ViewerError
from viewer.brdf.sampling import LUMINANCE_REC709, cosine_hemisphere
from viewer.environment.latlong import dir_to_uv, rotation_y, uv_to_dir

INV_4PI = 1.0 / (4.0 * math.pi)


class EnvironmentLight:
    """``constant`` (RGB radiance) or ``image`` ((H, W, 3) radiance, row 0 = zenith), both
    times ``intensity``; ``rotation_deg`` turns the map about +y (scene convention)."""

    def __init__(self, constant=None, image=None, intensity: float = 1.0, rotation_deg: float = 0.0):
        self.intensity = float(intensity)
        self.image = None
        self.constant = np.zeros(3)
        if image is not None:
            img = np.asarray(image, dtype=np.float64)
            if img.ndim != 3 or img.shape[2] < 3 or img.shape[0] < 1 or img.shape[1] < 1:
                raise ViewerError(f"environment map: expected an (H, W, 3) radiance array, got shape {img.shape}")
            img = img[:, :, :3]
            if not np.all(np.isfinite(img)) or np.any(img < 0):
                raise ViewerError("environment map: radiance must be finite and >= 0")
            self.image = np.ascontiguousarray(img * self.intensity)
            self._build_distribution()
        elif constant is not None:
            self.constant = np.asarray(constant, dtype=np.float64).reshape(3) * self.intensity
        self.rotation_deg = float(rotation_deg)
        self._to_map = rotation_y(-self.rotation_deg)    # world -> map direction
        self._to_world = rotation_y(self.rotation_deg)

    @classmethod
    def from_scene(cls, scene, image=None) -> "EnvironmentLight":
        env = scene.environment
        if image is not None:
            return cls(image=image, intensity=env.intensity, rotation_deg=env.rotation_deg)
        if env.map is not None:
            # intensity is already applied by radiance_map(); the rotation is applied at lookup
            return cls(image=env.radiance_map(), intensity=1.0, rotation_deg=env.rotation_deg)
        if env.constant is None:
            return cls()
        return cls(constant=env.constant, intensity=env.intensity)

    # ------------------------------------------------------------------ properties
    @property
    def is_map(self) -> bool:
        return self.image is not None

    @property
    def is_black(self) -> bool:
        if self.image is not None:
            return not np.any(self.image > 0)
        return not np.any(self.constant > 0)

    # ------------------------------------------------------------------ map distribution
    def _build_distribution(self):
        h, w, _ = self.image.shape
        lum = np.abs(self.image @ LUMINANCE_REC709)
        sin_t = np.sin(math.pi * (np.arange(h) + 0.5) / h)
        wgt = lum * sin_t[:, None]
        row_sum = wgt.sum(axis=1)
        total = row_sum.sum()
        if total <= 0:
            wgt = np.ones((h, w)) * sin_t[:, None]
            row_sum = wgt.sum(axis=1)
            total = row_sum.sum()
        self._texel_p = wgt / total                        # probability of each texel
        self._row_cdf = np.concatenate([[0.0], np.cumsum(row_sum) / total])
        cond = np.cumsum(wgt, axis=1) / np.where(row_sum > 0, row_sum, 1.0)[:, None]
        self._col_cdf = np.concatenate([np.zeros((h, 1)), cond], axis=1)
        self._row_cdf[-1] = 1.0
        self._col_cdf[:, -1] = 1.0

    def distribution(self):
        """The map's sampling tables for other engines (the GPU's textures): ``(texel_p (H, W),
        row_cdf (H + 1,), col_cdf (H, W + 1), to_map (3, 3))``: the probability of each texel,
        the marginal CDF over rows, each row's conditional CDF over columns (both start at 0
        and end at exactly 1) and the world -> map rotation. None for a constant environment."""
        if self.image is None:
            return None
        return self._texel_p, self._row_cdf, self._col_cdf, self._to_map

    def _texel(self, u, v):
        h, w, _ = self.image.shape
        col = np.floor(u * w).astype(np.int64) % w
        row = np.clip(np.floor(v * h).astype(np.int64), 0, h - 1)
        return row, col

    # ------------------------------------------------------------------ radiance and sampling
    def eval(self, d: np.ndarray) -> np.ndarray:
        """Radiance (N, 3) arriving from world directions d (N, 3) (unit)."""
        if self.image is None:
            return np.broadcast_to(self.constant, d.shape).copy()
        dm = d @ self._to_map.T
        u, v = dir_to_uv(dm)
        row, col = self._texel(u, v)
        return self.image[row, col]

    def sample(self, u: np.ndarray, normals: np.ndarray, two_sided: np.ndarray):
        """Directions for next-event estimation: (wi (N, 3), radiance (N, 3), pdf (N,) per
        solid angle). ``normals`` (N, 3) shading normals, ``two_sided`` (N,) bool (transmissive
        surfaces) choose the strategy of the constant environment; the map ignores them."""
        n = u.shape[0]
        if self.image is None:
            from viewer.brdf.sampling import frame_from_z

            local = cosine_hemisphere(u)
            tx, ty = frame_from_z(normals)
            wi = local[:, :1] * tx + local[:, 1:2] * ty + local[:, 2:3] * normals
            pdf = local[:, 2] / math.pi
            if np.any(two_sided):
                z = 1.0 - 2.0 * u[:, 0]
                r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
                phi = 2.0 * math.pi * u[:, 1]
                sph = np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=-1)
                wi = np.where(two_sided[:, None], sph, wi)
                pdf = np.where(two_sided, INV_4PI, pdf)
            return wi, np.broadcast_to(self.constant, (n, 3)).copy(), pdf
        h, w, _ = self.image.shape
        row = np.clip(np.searchsorted(self._row_cdf, u[:, 1], side="right") - 1, 0, h - 1)
        # second uniform re-used inside the row: rescale u1 within the picked row's interval
        lo, hi = self._row_cdf[row], self._row_cdf[row + 1]
        fv = np.clip((u[:, 1] - lo) / np.where(hi > lo, hi - lo, 1.0), 0.0, 1.0 - 1e-12)
        cdf_rows = self._col_cdf[row]
        col = np.clip((cdf_rows < u[:, 0][:, None]).sum(axis=1) - 1, 0, w - 1)
        clo = cdf_rows[np.arange(n), col]
        chi = cdf_rows[np.arange(n), col + 1]
        fu = np.clip((u[:, 0] - clo) / np.where(chi > clo, chi - clo, 1.0), 0.0, 1.0 - 1e-12)
        uu = (col + fu) / w
        vv = (row + fv) / h
        dm = uv_to_dir(uu, vv)
        wi = dm @ self._to_world.T
        sin_t = np.sin(math.pi * vv)
        p_uv = self._texel_p[row, col] * (w * h)
        pdf = np.where(sin_t > 0, p_uv / (2.0 * math.pi * math.pi * np.maximum(sin_t, 1e-300)), 0.0)
        return wi, self.image[row, col], pdf

    def pdf(self, d: np.ndarray, normals: np.ndarray, two_sided: np.ndarray) -> np.ndarray:
        """The solid-angle density with which ``sample`` picks world directions d."""
        if self.image is None:
            cos = np.sum(d * normals, axis=-1)
            return np.where(two_sided, INV_4PI, np.maximum(cos, 0.0) / math.pi)
        h, w, _ = self.image.shape
        dm = d @ self._to_map.T
        u, v = dir_to_uv(dm)
        row, col = self._texel(u, v)
        sin_t = np.sin(math.pi * np.clip(v, 0.0, 1.0))
        p_uv = self._texel_p[row, col] * (w * h)
        return np.where(sin_t > 0, p_uv / (2.0 * math.pi * math.pi * np.maximum(sin_t, 1e-300)), 0.0)
