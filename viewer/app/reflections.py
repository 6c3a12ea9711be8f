"""The Display panel's *reflections / refraction* choice and the scene keys it stands for.

    off         ssr = false, raytrace = false: every specular lobe sees the prefiltered
                environment (glass is looked up as through a sphere, one bounce)
    SSR         ssr = true,  raytrace = false: reflections of what is on screen (Hi-Z traced
                in screen space), the environment beyond
    ray traced  raytrace = true: mirrors and smooth glass follow their chain of delta bounces
                through the scene's triangles (refraction, total internal reflection, Bouguer
                absorption); ``ssr`` keeps its value (the "+ SSR on glossy lobes" box), since
                rough lobes are never traced

The window keeps no state of its own: the choice is read from and written to the scene's
``[render]`` table, so what the panel shows is what a saved scene file says.
"""

from __future__ import annotations

MODES = ("off", "SSR", "ray traced")

TOOLTIPS = {
    "off": "specular lobes reflect the prefiltered environment only; glass refracts it as "
           "through a sphere (one bounce)",
    "SSR": "screen-space reflections: what is on screen reflects in glossy and mirror surfaces; "
           "the environment where the ray leaves the screen",
    "ray traced": "mirrors and smooth glass trace their chain of bounces through the scene's "
                  "triangles: refraction, total internal reflection, absorption over the true "
                  "path; rough lobes keep the environment (or SSR)",
}


def reflection_mode(render) -> str:
    """The choice a scene's render settings stand for."""
    if render.raytrace:
        return "ray traced"
    return "SSR" if render.ssr else "off"


def set_reflection_mode(render, mode: str, ssr_on_glossy: bool | None = None) -> bool:
    """Set ``render.ssr`` / ``render.raytrace`` for ``mode``; returns whether anything changed.
    ``ssr_on_glossy`` (ray traced only): SSR for the lobes the chain does not trace; None keeps
    it off when coming from another mode and as it is when already ray traced."""
    if mode not in MODES:
        raise ValueError(f"reflections: unknown mode {mode!r}; one of {', '.join(MODES)}")
    before = (bool(render.ssr), bool(render.raytrace))
    if mode == "off":
        render.ssr, render.raytrace = False, False
    elif mode == "SSR":
        render.ssr, render.raytrace = True, False
    else:
        if ssr_on_glossy is None:
            ssr_on_glossy = bool(render.ssr) if render.raytrace else False
        render.ssr, render.raytrace = bool(ssr_on_glossy), True
    return (bool(render.ssr), bool(render.raytrace)) != before


def delta_materials(scene) -> list[str]:
    """The scene's materials whose every lobe is a delta lobe (a mirror, smooth glass, a soap
    film; the model's ``is_delta``): what they reflect and refract shows only in traced reflections
    (or SSR, for what is on screen), since the traced chains follow exactly these
    (``viewer.gl.raytrace.chain_traces``). A coat over a mirror is not one: its coat is a smooth lobe,
    the chains shade it as any rough surface, and ray tracing would not change what it shows."""
    from viewer import brdf

    return [name for name, p in scene.materials.items() if brdf.is_delta(p)]


def traced_hint(scene) -> str:
    """"" unless reflections are not traced and a material has a delta lobe: then the line
    saying that ray tracing shows them (the Display panel's choice)."""
    if reflection_mode(scene.render) == "ray traced":
        return ""
    names = delta_materials(scene)
    if not names:
        return ""
    what = ", ".join(names)
    return (f"{what}: a mirror or smooth glass shows the scene around it only when ray traced "
            "(Display > reflections / refraction: ray traced)")
