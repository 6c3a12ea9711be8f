"""What a screenshot carries: the scene and every parameter, as PNG text chunks, so a
screenshot can be reopened as a scene."""

from __future__ import annotations

import copy
import dataclasses
import json

import viewer


def png_text(scene, camera=None, extra: dict | None = None) -> dict[str, str]:
    from viewer.scene import scene_to_toml

    if camera is not None:
        # the scene as seen: the camera where the user left it
        scene = copy.copy(scene)
        scene.camera = dataclasses.replace(scene.camera, position=camera.position.copy(),
                                           target=camera.target.copy(), fov_y=float(camera.fov_y))
    text = {
        "Software": f"brdf-viewer {viewer.__version__}",
        "brdf-viewer:scene": scene_to_toml(scene),
    }
    state = {}
    if camera is not None:
        state["camera"] = {"position": [float(x) for x in camera.position],
                           "target": [float(x) for x in camera.target], "fov_y": camera.fov_y}
    if extra:
        state.update(extra)
    if state:
        text["brdf-viewer:state"] = json.dumps(state, sort_keys=True)
    return text
