"""BRDF Explorer's parameter files (.bparam): a file written by hand in BRDF Explorer's format
loads onto a .brdf file's material (by name and kind, unknown names in one note, values
validated), saving writes that format atomically and reads back, bad files give one line."""

from pathlib import Path

import numpy as np
import pytest

from viewer import ViewerError, brdf
from viewer.brdf import bparam

DATA = Path(__file__).parent / "brdfs"
FILE = DATA / "every_declaration.brdf"

# as BRDF Explorer's saveParamsFile writes it (%f numbers), plus a name the file lacks and a
# colour named like a float parameter (kind differs: left out)
HAND = f"""bparam {FILE}

::begin parameters
float n 1.000000 1000.000000 120.500000
float f0 0.000000 1.000000 0.250000
float gone 0.000000 1.000000 0.500000
bool use_fresnel 0
bool halve 1
color tint 0.200000 0.400000 0.600000
color n 1.0 1.0 1.0
::end parameters
"""


def test_hand_written_file_loads(tmp_path):
    path = tmp_path / "mine.bparam"
    path.write_text(HAND)
    bp = bparam.parse(path)
    assert bp.brdf_path() == FILE
    m = brdf.load(bp.brdf_path())
    p, note = bparam.apply(m, m.params(), bp)
    assert p["n"] == 120.5 and p["f0"] == 0.25 and p["use_fresnel"] is False and p["halve"] is True
    np.testing.assert_allclose(p["tint"], [0.2, 0.4, 0.6])
    assert "\n" not in note and "float gone" in note and "color n" in note and "2 parameters" in note


def test_round_trip(tmp_path):
    m = brdf.load(FILE)
    p = m.params(n=7.25, f0=0.123456789, halve=True, use_fresnel=False, tint=[0.1, 0.2, 0.3])
    path = bparam.save(tmp_path / "out.bparam", m, p)
    text = path.read_text()
    assert text.startswith(f"bparam {FILE.resolve()}\n\n::begin parameters\n") and text.endswith("::end parameters\n")
    assert "float n 1.0 1000.0 7.25\n" in text and "bool halve 1\n" in text and "color tint 0.1 0.2 0.3\n" in text
    q, note = bparam.apply(m, m.params(), bparam.parse(path))
    assert note == "" and q.to_plain() == p.to_plain()
    assert not [f for f in tmp_path.iterdir() if f.name != "out.bparam"]  # no temporary left


def test_bad_files_give_one_line(tmp_path):
    m = brdf.load(FILE)
    cases = {
        "first.bparam": ("analytic\n", "first line"),
        "kind.bparam": (f"bparam {FILE}\n::begin parameters\nint n 3\n::end parameters\n", "not a parameter kind"),
        "words.bparam": (f"bparam {FILE}\n::begin parameters\nfloat n 1 2\n::end parameters\n", "has 5 words"),
        "num.bparam": (f"bparam {FILE}\n::begin parameters\nfloat n 1 1000 x\n::end parameters\n", "not a number"),
        "bool.bparam": (f"bparam {FILE}\n::begin parameters\nbool halve yes\n::end parameters\n", "0 or 1"),
        "open.bparam": (f"bparam {FILE}\n::begin parameters\nbool halve 1\n", "not closed"),
        "nest.bparam": (f"bparam {FILE}\n::begin parameters\n::begin x\n", "do not nest"),
    }
    for name, (text, words) in cases.items():
        (tmp_path / name).write_text(text)
        with pytest.raises(ViewerError) as e:
            bparam.parse(tmp_path / name)
        msg = str(e.value)
        assert "\n" not in msg and name in msg and words in msg, (name, msg)
    (tmp_path / "bin.bparam").write_bytes(b"bparam x\n\xff\xfe")
    with pytest.raises(ViewerError, match="not a text file"):
        bparam.parse(tmp_path / "bin.bparam")
    with pytest.raises(ViewerError, match="file not found"):
        bparam.parse(tmp_path / "none.bparam")
    # a value outside the .brdf file's declared range: the scene's validation, naming both files
    (tmp_path / "range.bparam").write_text(f"bparam {FILE}\n::begin parameters\nfloat n 1 5000 4000\n::end parameters\n")
    with pytest.raises(ViewerError) as e:
        bparam.apply(m, m.params(), bparam.parse(tmp_path / "range.bparam"))
    assert "\n" not in str(e.value) and "range.bparam" in str(e.value) and "n" in str(e.value)


def test_window_loads_and_saves_parameters_and_measured_drops(gl_ctx, renderer, tmp_path):
    """The window's paths (the Files panel's Load / Save parameters, drops): a .bparam dropped on
    the selected object's file material sets its values, saving writes them back, a bad file is
    one error and keeps the material, a dropped MIT .dat table becomes the measured material."""
    from viewer.app.session import Session
    from viewer.brdf import mit_aniso

    s = Session(gl_ctx, "default", renderer=renderer, prefetch=False)
    s.warm = []
    try:
        name = s.scene.objects[s.mesh_target].material
        m = brdf.load(FILE)
        s.set_material(name, m.params())
        (tmp_path / "mine.bparam").write_text(HAND)
        n0 = len(s.messages)
        s.open_files([str(tmp_path / "mine.bparam")])
        msgs = s.messages[n0:]
        assert len(msgs) == 1 and not msgs[0].error and "float gone" in msgs[0].text, msgs
        assert s.scene.materials[name]["n"] == 120.5
        assert s.file_action("save_bparam", str(tmp_path / "saved"))
        q, _ = bparam.apply(m, m.params(), bparam.parse(tmp_path / "saved.bparam"))
        assert q.to_plain() == s.scene.materials[name].to_plain()
        (tmp_path / "bad.bparam").write_text("nope\n")
        n0 = len(s.messages)
        s.open_files([str(tmp_path / "bad.bparam")])
        msgs = s.messages[n0:]
        assert len(msgs) == 1 and msgs[0].error and "bad.bparam" in msgs[0].text
        assert s.scene.materials[name]["n"] == 120.5
        mit_aniso.write(tmp_path / "t.dat", np.full((2, 2, 4, 4, 3), 0.1))
        s.open_files([str(tmp_path / "t.dat")])
        assert s.scene.materials[name].model == "measured" and s.scene.materials[name]["file"].endswith("t.dat")
    finally:
        s.release()


def test_cli_bparam(tmp_path, capsys):
    """``plot FILE.bparam`` plots the .brdf file it names with its values (--set wins), the scene
    commands take ``--bparam MATERIAL=FILE``; what the file's BRDF lacks is one note, a bad
    argument or file one error line (exit status 2)."""
    from viewer.commands import cli
    from viewer.scene import material_from_name

    (tmp_path / "mine.bparam").write_text(HAND)
    p = material_from_name(str(tmp_path / "mine.bparam"), ["f0=0.5"])
    assert p["n"] == 120.5 and p["f0"] == 0.5
    assert "float gone" in capsys.readouterr().err
    scene = tmp_path / "s.toml"
    from viewer.scene import SCENE_DIR

    scene.write_text((SCENE_DIR / "sphere.toml").read_text().split("[materials.ball]")[0]
                     + f'[materials.ball]\nmodel = "custom"\nfile = "{FILE}"\n')
    lines, note = bparam.overrides(tmp_path / "mine.bparam", prefix="materials.ball.")
    assert "materials.ball.n=120.5" in lines and not any("gone" in x for x in lines) and "float gone" in note
    import viewer

    assert viewer.bparam_overrides("ball", tmp_path / "mine.bparam") == lines  # the Python API
    assert cli.main(["render", str(scene), "--out", str(tmp_path / "ok.png"), "--width", "16", "--height", "16",
                     "--bparam", f"ball={tmp_path / 'mine.bparam'}", "--set", "materials.ball.f0=0.5"]) == 0
    assert "float gone" in capsys.readouterr().err and (tmp_path / "ok.png").exists()
    assert cli.main(["render", str(scene), "--out", str(tmp_path / "x.png"), "--bparam", "ball"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "MATERIAL=FILE.bparam" in err
    (tmp_path / "bad.bparam").write_text("bparam x\n::begin parameters\nfloat n\n")
    assert cli.main(["render", str(scene), "--out", str(tmp_path / "x.png"), "--bparam",
                     f"ball={tmp_path / 'bad.bparam'}"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "bad.bparam:3" in err and not (tmp_path / "x.png").exists()
