"""Orbit camera behaviour and the one-line message when no OpenGL 4.1 context can be had."""

import math

import numpy as np
import pytest

from viewer import ViewerError
from viewer.scene.camera import OrbitCamera


def test_camera_from_look_at_round_trips():
    cam = OrbitCamera([1.0, 2.0, 3.0], [0.5, 0.0, -1.0], 40.0)
    assert np.allclose(cam.position, [1.0, 2.0, 3.0])
    v = cam.view()
    # the target lies straight ahead (-z in view space), the eye at the origin
    t = v @ np.array([0.5, 0.0, -1.0, 1.0])
    assert abs(t[0]) < 1e-9 and abs(t[1]) < 1e-9 and t[2] < 0
    assert np.allclose(v @ np.array([1.0, 2.0, 3.0, 1.0]), [0, 0, 0, 1])


def test_orbit_keeps_distance_and_clamps_pitch():
    cam = OrbitCamera([0.0, 0.0, 4.0], [0.0, 0.0, 0.0], 40.0)
    cam.orbit(300.0, 0.0, 600.0)
    assert math.isclose(np.linalg.norm(cam.position), 4.0)
    assert cam.position[0] < 0  # dragging right turns the camera around to the left (-x)
    cam.orbit(0.0, 10000.0, 600.0)  # far past the pole
    assert cam.pitch <= math.radians(89.0) + 1e-12
    assert np.all(np.isfinite(cam.view()))


def test_pan_dolly_reset_fit():
    cam = OrbitCamera([0.0, 0.0, 4.0], [0.0, 0.0, 0.0], 40.0)
    cam.pan(100.0, 0.0, 500.0)
    assert cam.target[0] < 0  # dragging right moves the scene right, i.e. the target left
    cam.dolly(2.0)
    assert cam.distance < 4.0
    cam.reset()
    assert np.allclose(cam.position, [0, 0, 4]) and np.allclose(cam.target, 0)
    cam.fit([-3, -1, -2], [3, 1, 2])
    radius = 0.5 * np.linalg.norm([6, 2, 4])
    # the bounding sphere fits in the vertical field of view
    assert cam.distance * math.sin(math.radians(20)) >= radius


def test_projection_maps_fov_edge_to_ndc_edge():
    cam = OrbitCamera([0.0, 0.0, 4.0], [0.0, 0.0, 0.0], 40.0)
    p = cam.projection(1.5) @ cam.view()
    y = 4.0 * math.tan(math.radians(20))  # a point on the upper edge of the view at z = 0
    clip = p @ np.array([0.0, y, 0.0, 1.0])
    assert math.isclose(clip[1] / clip[3], 1.0, rel_tol=1e-9)
    x = y * 1.5
    clip = p @ np.array([x, 0.0, 0.0, 1.0])
    assert math.isclose(clip[0] / clip[3], 1.0, rel_tol=1e-9)


def test_no_gl41_gives_one_clear_line(monkeypatch):
    import moderngl

    from viewer.gl import context

    def fail(*a, **k):
        raise Exception("requested OpenGL 4.1 but got 3.3")

    monkeypatch.setattr(moderngl, "create_standalone_context", fail)
    with pytest.raises(ViewerError) as e:
        context.create_offscreen_context()
    msg = str(e.value)
    assert "\n" not in msg and "OpenGL 4.1" in msg and "EGL" in msg and "apt-get install" in msg
