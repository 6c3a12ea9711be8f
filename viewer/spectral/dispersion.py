"""Dielectrics by their dispersion formulas (wavelength in micrometres inside the formulas).

Sellmeier, as refractiveindex.info writes them:
  form 1: n^2 - 1 = sum_i B_i l^2 / (l^2 - C_i^2)
  form 2: n^2 - 1 = sum_i B_i l^2 / (l^2 - C_i)
Coefficients and ranges as published (via the refractiveindex.info database, CC0):
"""

from __future__ import annotations

import numpy as np

# name -> (form, [(B, C), ...], valid range nm, description, reference)
FORMULAS: dict[str, tuple[int, list[tuple[float, float]], tuple[float, float], str, str]] = {
    "BK7": (2, [(1.03961212, 0.00600069867), (0.231792344, 0.0200179144), (1.01046945, 103.560653)],
            (300.0, 2500.0), "Schott N-BK7 borosilicate crown glass",
            "SCHOTT optical glass catalogue (Zemax catalogue 2017-01-20b), N-BK7"),
    "F2": (2, [(1.34533359, 0.00997743871), (0.209073176, 0.0470450767), (0.937357162, 111.886764)],
           (320.0, 2500.0), "Schott F2 flint glass",
           "SCHOTT optical glass catalogue (Zemax catalogue 2017-01-20b), F2"),
    "SF11": (2, [(1.73848403, 0.0136068604), (0.311168974, 0.0615960463), (1.17490871, 121.922711)],
             (390.0, 2500.0), "Schott SF11 dense flint glass (high dispersion)",
             "SCHOTT optical glass catalogue (Zemax catalogue 2017-01-20b), SF11"),
    "SiO2": (1, [(0.6961663, 0.0684043), (0.4079426, 0.1162414), (0.8974794, 9.896161)],
             (210.0, 6700.0), "fused silica, 20 C",
             "I. H. Malitson, Interspecimen comparison of the refractive index of fused silica, "
             "J. Opt. Soc. Am. 55, 1205-1208 (1965)"),
    "H2O": (2, [(5.684027565e-1, 5.101829712e-3), (1.726177391e-1, 1.821153936e-2),
                (2.086189578e-2, 2.620722293e-2), (1.130748688e-1, 1.069792721e1)],
            (182.0, 1129.0), "distilled water, 20 C",
            "M. Daimon and A. Masumura, Measurement of the refractive index of distilled water from "
            "the near-infrared region to the ultraviolet region, Appl. Opt. 46, 3811-3820 (2007)"),
    "diamond": (1, [(0.3306, 0.1750), (4.3356, 0.1060)], (226.0, 760.0), "diamond (cubic carbon)",
                "F. Peter, Ueber Brechungsindizes und Absorptionskonstanten des Diamanten zwischen "
                "644 und 226 mu, Z. Phys. 15, 358-368 (1923)"),
    "sapphire": (1, [(1.4313493, 0.0726631), (0.65054713, 0.1193242), (5.3414021, 18.028251)],
                 (200.0, 5000.0), "synthetic sapphire (Al2O3), ordinary ray, 20 C",
                 "I. H. Malitson and M. J. Dodge, Refractive index and birefringence of synthetic "
                 "sapphire, J. Opt. Soc. Am. 62, 1405 (1972); M. J. Dodge, Handbook of Laser Science "
                 "and Technology IV, CRC Press (1986), p. 30"),
}


def sellmeier(name: str, wavelength_nm) -> np.ndarray:
    """Real n(lambda) of a dielectric in ``FORMULAS``."""
    form, terms, _, _, _ = FORMULAS[name]
    l2 = (np.asarray(wavelength_nm, dtype=np.float64) * 1e-3) ** 2
    n2 = np.ones_like(l2)
    for b, c in terms:
        n2 = n2 + b * l2 / (l2 - (c * c if form == 1 else c))
    return np.sqrt(n2)
