"""What a screenshot carries: the scene and every parameter, as PNG text chunks, so a
screenshot can be reopened as a scene."""

from __future__ import annotations

import copy
import dataclasses
import json

import viewer


def scene_with_camera(scene, camera=None, size=None):
    """A shallow copy of ``scene`` whose [camera] is the orbit camera where the user left it
    (and the image size ``size`` = (w, h) when given)."""
    if camera is None and size is None:
        return scene
    scene = copy.copy(scene)
    cam = scene.camera
    if camera is not None:
        cam = dataclasses.replace(cam, position=camera.position.copy(), target=camera.target.copy(),
                                  fov_y=float(camera.fov_y))
    if size is not None:
        cam = dataclasses.replace(cam, width=int(size[0]), height=int(size[1]))
    scene.camera = cam
    return scene


def png_text(scene, camera=None, extra: dict | None = None) -> dict[str, str]:
    from viewer.scene import scene_to_toml

    scene = scene_with_camera(scene, camera)  # the scene as seen
    text = {
        "Software": f"brdf-viewer {viewer.__version__}",
        # absolute mesh and map paths: the PNG reopens from any folder (viewer.scene.load falls
        # back to a file of the same name beside the PNG when the PNG travelled with its files)
        "brdf-viewer:scene": scene_to_toml(scene, absolute_paths=True),
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
