"""What only the cpu engine renders, in one place: the tests, the one-line refusal of
``--engine gpu`` and the reason ``auto`` prints for taking the cpu engine. ``cpu_only(scene)``
is the first limit a scene meets (None: the gpu engine renders it); the engine selection
(``viewer/reference_common/select.py``) and the gpu engine itself (``viewer/gpupt/engine.py``: several measured
tables) read them here."""

from __future__ import annotations

from typing import NamedTuple


def needs_spectral(scene, spectral: bool | None = None) -> bool:
    """Whether a reference of ``scene`` traces wavelengths: ``spectral`` where given, else
    whether a material it uses is dispersive."""
    if spectral is not None:
        return bool(spectral)
    from viewer.scene.materials import scene_is_dispersive

    return scene_is_dispersive(scene)


def uses_measured(scene) -> bool:
    """Whether a material of ``scene`` is (or nests) a measured BRDF table (MERL or MIT)."""
    from viewer import brdf

    return any(brdf.is_measured(m) for m in scene.materials.values())


def measured_tables(scene) -> dict:
    """{table key: the measured Params that reads it} of the materials of ``scene`` (a nested
    base too): the gpu engine binds one table for the whole pass, so it renders scenes whose
    measured materials share one file."""
    from viewer.gl.measured_tex import measured_params

    out = {}
    for m in scene.materials.values():
        p = measured_params(m)
        if p is not None:
            out.setdefault((p.file or "", p.file.lower().endswith(".dat") if p.file else False), p)
    return out


def several_measured_tables(scene) -> bool:
    return len(measured_tables(scene)) > 1


MEASURED_REFUSAL = ("--engine gpu binds one measured table per scene, and this scene's measured materials "
                    "read several files; use --engine cpu or auto (auto takes the cpu engine for them)")


def uses_random_walk(scene) -> bool:
    """Whether a material some object uses (or its nested base) has the microfacet model's
    multiple-scattering random walk, which only the cpu engine traces."""
    from viewer import brdf
    from viewer.scene.materials import uses

    return uses(scene, brdf.walks)


RANDOM_WALK_REASON = ("a material has a random walk (microfacet multiple_scattering, or layered "
                      "reference = \"random_walk\"): only the cpu engine has it")


def uses_thin_film(scene) -> bool:
    """Whether a material some object uses has a thin film (its own, or a layered coating's)."""
    from viewer import brdf
    from viewer.scene.materials import uses

    return uses(scene, brdf.has_film)


def uses_film_over_height(scene) -> bool:
    """Whether a material some object uses has a thin film whose thickness changes with height
    (``thickness_top_nm``): the gpu engine evaluates materials without the hit's height (at the
    film's bottom thickness), while the rasterizer and the cpu engine follow it per point."""
    from viewer import brdf
    from viewer.brdf import thin_film
    from viewer.scene.materials import uses

    return uses(scene, lambda p: brdf.has_film(p) and thin_film.varies(p))


FILM_HEIGHT_REFUSAL = ("--engine gpu draws a thin film over height (thickness_top_nm) at its bottom thickness; "
                       "use --engine cpu or auto (auto takes the cpu engine for it)")


FILM_SPECTRAL_REFUSAL = ("--engine gpu does not trace thin films per wavelength (its spectral pass would "
                         "evaluate them in RGB); use --engine cpu or auto (auto takes the cpu engine for them)")


RANDOM_WALK_REFUSAL = ("--engine gpu has no random walk (a microfacet material has multiple_scattering "
                       "= true, or a layered one reference = \"random_walk\"); use --engine cpu or auto")


class Limit(NamedTuple):
    """One thing only the cpu engine renders."""
    applies: object   # applies(scene, spectral) -> bool
    refusal: str      # what --engine gpu says (one line)
    reason: str       # why auto takes the cpu engine


LIMITS = (
    Limit(lambda scene, spectral: several_measured_tables(scene), MEASURED_REFUSAL,
          "the scene's measured materials read several tables: only the cpu engine renders them"),
    Limit(lambda scene, spectral: uses_random_walk(scene), RANDOM_WALK_REFUSAL, RANDOM_WALK_REASON),
    Limit(lambda scene, spectral: uses_thin_film(scene) and needs_spectral(scene, spectral), FILM_SPECTRAL_REFUSAL,
          "a thin film traced per wavelength: only the cpu engine does it"),
    Limit(lambda scene, spectral: uses_film_over_height(scene), FILM_HEIGHT_REFUSAL,
          "a thin film over height (thickness_top_nm): only the cpu engine follows it per hit"),
)


def cpu_only(scene, spectral: bool | None = None) -> Limit | None:
    """The first of ``LIMITS`` that ``scene`` meets (``spectral`` as ``needs_spectral``), or None."""
    return next((lim for lim in LIMITS if lim.applies(scene, spectral)), None)
