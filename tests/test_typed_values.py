"""Numbers typed into the window's widgets: a value the widget cannot take is refused in one
line naming the widget the student used (the roughness slider, not alpha_x; the light's
intensity) and its range; the old value stays."""

import numpy as np
import pytest

from viewer.app.panels import lights
from viewer.app.ui import ROUGHNESS_LABEL, out_of_range, roughness_alpha


def test_roughness_refusal_names_the_slider_and_its_range():
    a, msg = roughness_alpha(0.0, 1e-4, 1.0)  # microfacet: alpha_x in [1e-4, 1]
    assert a is None and msg.startswith(f"{ROUGHNESS_LABEL}: 0 is out of range; allowed: 0.01 to 1")
    assert "alpha_x" not in msg and "alpha = r^2 in [0.0001, 1]" in msg and "\n" not in msg
    assert roughness_alpha(0.5, 1e-4, 1.0) == (0.25, "")
    assert roughness_alpha(0.0, 0.0, 1.0) == (0.0, "")  # smooth glass: alpha 0 is allowed
    assert roughness_alpha(float("nan"), 1e-4, 1.0)[0] is None


@pytest.mark.parametrize("typed", [-5.0, 1e9, 1e30, float("inf"), float("nan")])
def test_out_of_range_is_one_line_naming_the_field(typed):
    msg = out_of_range("intensity W/sr", [typed, 1.0, 1.0], 0.0, 1e6)
    assert msg.startswith("intensity W/sr: ") and "allowed: 0 to 1e+06" in msg and "\n" not in msg
    assert out_of_range("intensity W/sr", [0.0, 5.0, 1e6], 0.0, 1e6) == ""


@pytest.fixture
def session(gl_ctx, renderer):
    from viewer.app.session import Session

    s = Session(gl_ctx, "default", renderer=renderer, prefetch=False)
    yield s
    s.release()


@pytest.mark.parametrize("typed", [-5.0, 1e9, 1e30])
def test_a_light_refuses_a_typed_intensity_and_keeps_its_own(session, typed):
    before = np.array(session.scene.lights[0].intensity)
    n0 = len(session.messages)
    assert not lights.set_value(session, 0, "intensity", [typed] * 3)
    msgs = session.messages[n0:]
    assert len(msgs) == 1 and msgs[0].error and "intensity W/sr" in msgs[0].text and "0 to 1e+06" in msgs[0].text
    assert np.array_equal(session.scene.lights[0].intensity, before)
    assert lights.set_value(session, 0, "intensity", [10.0, 20.0, 30.0])
    assert np.array_equal(session.scene.lights[0].intensity, [10.0, 20.0, 30.0])
