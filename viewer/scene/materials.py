"""Questions about a scene's materials, asked of their models (``viewer.brdf``'s predicates):
whether some material an object uses has a property. The scene model is the home of these,
since ``viewer/brdf`` knows no scene."""

from __future__ import annotations

from viewer import brdf


def used_materials(scene) -> list:
    """The parameters of the materials some object uses, in the scene's order."""
    used = {o.material for o in scene.objects}
    return [p for name, p in scene.materials.items() if name in used]


def uses(scene, predicate) -> bool:
    """Whether ``predicate(params)`` holds for a material some object uses (e.g.
    ``uses(scene, brdf.has_film)``)."""
    return any(predicate(p) for p in used_materials(scene))


def scene_is_dispersive(scene) -> bool:
    """Whether a material some object uses is dispersive (``brdf.is_dispersive``): a reference of
    the scene traces wavelengths."""
    return uses(scene, brdf.is_dispersive)
