"""The plots window's Check tab computes the report card of the chosen material (built-in or a
.brdf file) once per parameter set; drawn in the panel test of test_plots.py."""

from pathlib import Path

from viewer import brdf
from viewer.app.check_tab import card

DATA = Path(__file__).parent / "brdfs"


def test_the_card_of_a_file_and_of_a_built_in_material():
    c = card(brdf.load(DATA / "too_bright.brdf").params())
    assert c["file"] == "too_bright.brdf" and not c["pass"] and not c["checks"]["energy"]["pass"]
    c = card(brdf.get("lambert").params(albedo=0.5))
    assert c["file"] == "lambert" and c["pass"] and abs(c["checks"]["energy"]["max_albedo"] - 0.5) < 1e-3
