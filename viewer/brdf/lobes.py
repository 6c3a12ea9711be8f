"""The one vocabulary for a material's lobes: ``Lobe``, a set of flags that says on which side
a lobe scatters (REFLECTION, TRANSMISSION) and how (DIFFUSE, GLOSSY, DELTA).

A model computes the lobes of its parameters (``Model.lobes(p)``, the ``lobes`` hook of
``viewer.brdf.spec.HOOKS``): the union of every lobe it may draw. Its sampler says which lobe
each sample drew (``Model.sample_lobe``, and the GLSL ``<name>_sample``'s ``out uint lobe``):
one side and one kind. The GLSL side has the same numbers as ``LOBE_<NAME>``
(``generated/constants.glsl``, from this class) and the predicates below as functions of
``shaders/common/lobes.glsl``.

The idea and the bit values are those of pbrt-v4's ``BxDFFlags`` (Pharr, Jakob, Humphreys,
"Physically Based Rendering", 4th ed., section 9.1.2: Reflection 1, Transmission 2, Diffuse 4,
Glossy 8, Specular 16) and Mitsuba 3's ``BSDFFlags``; DELTA is pbrt's Specular (a direction
drawn with a discrete probability, no density: mirror, smooth glass).
"""

from __future__ import annotations

import enum

import numpy as np


class Lobe(enum.IntFlag):
    """A set of lobes; one sample's lobe has one side bit and one kind bit."""

    NONE = 0
    REFLECTION = 1
    TRANSMISSION = 2
    DIFFUSE = 4
    GLOSSY = 8
    DELTA = 16

    @property
    def is_delta(self) -> bool:
        """Every lobe is a delta lobe (and there is one): every sample is discrete, there is
        nothing for light sampling to find."""
        return bool(self & Lobe.DELTA) and not self & SMOOTH

    @property
    def has_delta(self) -> bool:
        """Some lobe is a delta lobe."""
        return bool(self & Lobe.DELTA)

    @property
    def is_smooth(self) -> bool:
        """No lobe is a delta lobe: every sample has a density (light sampling and MIS apply)."""
        return not self & Lobe.DELTA

    @property
    def has_smooth(self) -> bool:
        """Some lobe has a density (diffuse or glossy)."""
        return bool(self & SMOOTH)

    @property
    def is_mixed(self) -> bool:
        """Delta and smooth lobes both (a coat over a mirror): which one a sample drew is the
        sampler's to say."""
        return self.has_delta and self.has_smooth

    @property
    def transmits(self) -> bool:
        """Some lobe scatters to the other side of the surface."""
        return bool(self & Lobe.TRANSMISSION)


SMOOTH = Lobe.DIFFUSE | Lobe.GLOSSY
SIDES = Lobe.REFLECTION | Lobe.TRANSMISSION
KINDS = Lobe.DIFFUSE | Lobe.GLOSSY | Lobe.DELTA

#: the dtype of the per-sample lobe arrays ``sample_lobe`` returns
DTYPE = np.uint8


def drew_delta(lobes) -> np.ndarray:
    """(N,) bool: which samples of a per-sample lobe array drew a delta lobe."""
    return (np.asarray(lobes, dtype=DTYPE) & DTYPE(Lobe.DELTA)) != 0


def by_side(kind: Lobe, wi, wo) -> np.ndarray:
    """(N,) per-sample lobes: ``kind``'s kind bits with the side each pair (wi, wo) is on
    (reflection where wi and wo are on the same side of the surface, else transmission)."""
    same = np.asarray(wi)[..., 2] * np.asarray(wo)[..., 2] >= 0.0
    k = DTYPE(Lobe(kind) & KINDS)
    return np.where(same, k | DTYPE(Lobe.REFLECTION), k | DTYPE(Lobe.TRANSMISSION)).astype(DTYPE)


def declared(delta: bool, transmissive: bool) -> Lobe:
    """The lobes a model without a ``lobes`` hook has, from its spec's ``delta`` and
    ``transmissive``: delta or else glossy, on the reflection side and (transmissive) the other."""
    side = Lobe.REFLECTION | (Lobe.TRANSMISSION if transmissive else Lobe.NONE)
    return side | (Lobe.DELTA if delta else Lobe.GLOSSY)


def glsl_defines() -> dict[str, str]:
    """{GLSL name: literal} of every flag (``LOBE_REFLECTION`` -> ``1u``; unsigned, as the GLSL
    lobes are ``uint``)."""
    out = {"LOBE_NONE": "0u"} | {f"LOBE_{f.name}": f"{int(f)}u" for f in Lobe}  # (iteration skips NONE)
    out.update(LOBE_SMOOTH=f"{int(SMOOTH)}u", LOBE_SIDES=f"{int(SIDES)}u", LOBE_KINDS=f"{int(KINDS)}u")
    return out
