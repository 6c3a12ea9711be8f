"""Shared helpers for the classroom tests: every built-in scene and lecture step under every
combination of the rasterizer's switches (the shader variants a lecturer can reach)."""

from __future__ import annotations

import itertools

import numpy as np

IBL_MODES = ("split_sum", "fis", "brute_force", "off")
SWEEP_SIZE = (48, 32)  # small: the check is about every pixel being a number, not about detail


def all_scene_names() -> list[str]:
    from viewer.scene import builtin_scene_names, lecture_scene_names

    return builtin_scene_names() + lecture_scene_names()


def switch_overrides(ssr: bool, ibl: str, env: str) -> list[str]:
    """--set assignments for one combination. ``env``: "scene" keeps the scene's environment
    (a constant grey where the scene has none, so the environment really lights it), "none"
    replaces it with no light at all."""
    out = [f"render.ssr={str(ssr).lower()}", f'render.ibl="{ibl}"', "render.msaa=0"]
    if env == "none":
        out.append("environment={constant = [0.0, 0.0, 0.0]}")
    return out


def scene_with_switches(name: str, ssr: bool, ibl: str, env: str):
    from viewer.scene import load_scene

    scene = load_scene(name, switch_overrides(ssr, ibl, env))
    if env == "scene" and scene.environment.map is None and not np.any(
            np.asarray(scene.environment.constant) * scene.environment.intensity > 0):
        scene = load_scene(name, switch_overrides(ssr, ibl, env) + ["environment={constant = [0.3, 0.3, 0.3]}"])
    return scene


def switch_combinations():
    return list(itertools.product((False, True), IBL_MODES, ("scene", "none")))
