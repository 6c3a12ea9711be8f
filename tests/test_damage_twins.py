"""A ``.brdf`` file's numpy twin is code from the file's author: it runs only when the user has
trusted it (``--trust-twin PATH``, ``BRDF_VIEWER_TRUST_TWINS``, the window's question), never
because a scene, a screenshot's embedded scene or a folder names it; and a trusted twin that
misbehaves (exits, raises, returns the wrong shape, None or NaN, sleeps) is one line naming it and
a non-zero exit, never a traceback, a hang or a silent exit 0.

The hostile twin writes a marker file when it is imported: no marker, no code ran."""

import os
import shutil
from pathlib import Path

import numpy as np
import pytest

from gui_harness import HAVE_X, run_py

from viewer import ViewerError, brdf
from viewer.brdf import file_model, twin_trust

DATA = Path(__file__).parent / "brdfs"

SCENE = """
[camera]
position = [0.0, 0.0, 3.0]
target = [0.0, 0.0, 0.0]
fov_y = 40.0
width = 16
height = 16

[[lights]]
type = "point"
position = [2.0, 3.0, 2.0]
intensity = [10.0, 10.0, 10.0]

[[objects]]
mesh = "sphere"
material = "ball"

[materials.ball]
model = "custom"
file = "hostile.brdf"
"""

EVAL = """
def eval(p, wi, wo):
    return np.broadcast_to(p.gain * np.asarray(p.albedo) / np.pi, (len(wi), 3))
"""


def _hostile(folder: Path, marker: Path, name="hostile") -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    shutil.copy(DATA / "lambert_twin.brdf", folder / f"{name}.brdf")
    (folder / f"{name}.py").write_text(
        "import multiprocessing\nimport numpy as np\n"
        f"open({str(marker)!r}, 'a').write(multiprocessing.current_process().name + '\\n')\n" + EVAL)
    return folder / f"{name}.brdf"


@pytest.fixture(autouse=True)
def _no_trust(monkeypatch):
    monkeypatch.delenv(twin_trust.TRUST_ENV, raising=False)
    twin_trust.forget()
    yield
    twin_trust.forget()


@pytest.fixture
def hostile(tmp_path):
    marker = tmp_path / "MARKER"
    path = _hostile(tmp_path / "student", marker)
    scene = tmp_path / "student" / "scene.toml"
    scene.write_text(SCENE)
    return path, scene, marker


def _main(capsys, *argv):
    from viewer.commands.cli import main

    rc = main([str(a) for a in argv])
    out = capsys.readouterr()
    return rc, out.out, out.err


# ----------------------------------------------------------------------------- consent


def test_no_command_runs_an_untrusted_twin(hostile, tmp_path, capsys):
    """Opening, models, check, plot, render, reference on both engines and bake: the file works
    (without its twin) and one line says the twin was not run; the twin never ran."""
    path, scene, marker = hostile
    m = brdf.load(path)
    assert m.twin is None and m.twin_not_run.startswith("hostile.brdf: its numpy twin hostile.py was not run")
    assert "--trust-twin" in m.twin_not_run
    capsys.readouterr()
    rc, out, err = _main(capsys, "models", path)
    assert rc == 0 and "numpy twin: not run (not trusted" in out
    file_model.clear_cache()   # each command below loads it afresh, as a new process would
    rc, out, err = _main(capsys, "check", path)
    assert rc == 0 and out.startswith(f"{path}: PASS") and " twin " not in out
    assert err.count("\n") == 1 and "hostile.py was not run (not trusted)" in err
    rc, out, err = _main(capsys, "plot", path, "--kind", "polar", "--out", tmp_path / "p.png", "--width", 200,
                         "--height", 150)
    assert rc == 0 and (tmp_path / "p.png").is_file()
    rc, out, err = _main(capsys, "render", scene, "--out", tmp_path / "r.png")
    assert rc == 0 and (tmp_path / "r.png").is_file()
    rc, out, err = _main(capsys, "reference", scene, "--spp", 1, "--engine", "cpu", "--workers", 0,
                         "--out", tmp_path / "c.png")
    assert rc == 2 and err.count("\n") == 1 and "hostile.py was not run (not trusted)" in err
    assert "--engine gpu" in err and not (tmp_path / "c.png").exists()
    rc, out, err = _main(capsys, "reference", scene, "--spp", 1, "--out", tmp_path / "g.png")
    assert rc == 0 and "engine: gpu" in out and (tmp_path / "g.png").is_file()
    rc, out, err = _main(capsys, "bake", scene, "--spp", 1)
    assert rc == 0 and "1 spp" in out
    rc, out, err = _main(capsys, "compare", scene, "--spp", 1, "--supersample", 1, "--out", tmp_path / "cmp")
    assert rc == 0 and (tmp_path / "cmp" / "metrics.json").is_file()
    assert not marker.exists()


def test_a_screenshot_naming_the_file_does_not_run_its_twin(hostile, tmp_path, capsys):
    from viewer.base.io import write_png
    from viewer.scene import load_scene
    from viewer.scene.screenshot import png_text

    path, scene, marker = hostile
    shot = tmp_path / "shot.png"
    write_png(shot, np.zeros((16, 16, 3), np.uint8), png_text(load_scene(scene)))
    assert "hostile.brdf" in png_text(load_scene(scene))["brdf-viewer:scene"]
    file_model.clear_cache()
    rc, out, err = _main(capsys, "render", shot, "--out", tmp_path / "again.png")
    assert rc == 0 and (tmp_path / "again.png").is_file() and "was not run (not trusted)" in err
    assert not marker.exists()


def test_trust_twin_runs_it_on_every_command_that_needs_it(hostile, tmp_path, capsys):
    path, scene, marker = hostile
    rc, out, err = _main(capsys, "check", path, "--trust-twin", path.parent)
    assert rc == 0 and " twin " in out and "not run" not in err
    assert marker.is_file()
    # the cpu reference: the parent's trust reaches its spawned worker, which imports the twin too
    marker.unlink()
    twin_trust.forget()
    rc, out, err = _main(capsys, "reference", scene, "--spp", 1, "--engine", "cpu", "--workers", 1,
                         "--trust-twin", path, "--out", tmp_path / "c.png")
    assert rc == 0 and (tmp_path / "c.png").is_file(), err
    # the spawned worker ran it (after its own probe): the parent's trust reached it
    assert any(line.startswith("SpawnProcess") for line in marker.read_text().splitlines()), marker.read_text()


def test_the_environment_trusts_paths_joined_by_colons(hostile, tmp_path, monkeypatch):
    path, _, marker = hostile
    monkeypatch.setenv(twin_trust.TRUST_ENV, f"{tmp_path / 'elsewhere'}:{path.parent}")
    assert brdf.load(path).twin is not None and marker.is_file()


def test_trust_is_of_the_real_path(tmp_path):
    """A symlink in a trusted folder to a twin outside it, or ``..`` out of it, is not trusted;
    the program's own examples are."""
    marker = tmp_path / "MARKER"
    evil = _hostile(tmp_path / "evil", marker)
    trusted = tmp_path / "trusted"
    trusted.mkdir()
    shutil.copy(evil, trusted / "hostile.brdf")
    os.symlink(evil.with_suffix(".py"), trusted / "hostile.py")
    twin_trust.trust(trusted)
    assert not twin_trust.is_trusted(trusted / "hostile.py")
    assert not twin_trust.is_trusted(trusted / ".." / "evil" / "hostile.py")
    assert brdf.load(trusted / "hostile.brdf").twin is None and not marker.exists()
    # a .brdf symlinked into the trusted folder is the file it points to, with that folder's twin
    os.symlink(evil, trusted / "linked.brdf")
    assert brdf.load(trusted / "linked.brdf").twin is None and not marker.exists()
    assert twin_trust.is_trusted(twin_trust.BUILT_IN / "cooktorrance.py")
    with pytest.raises(ViewerError, match="no such file or folder"):
        twin_trust.trust(tmp_path / "nothing")


def test_a_worker_takes_the_parents_decision_not_its_environment(hostile, monkeypatch):
    path, _, _ = hostile
    monkeypatch.setenv(twin_trust.TRUST_ENV, str(path.parent))
    twin = path.with_suffix(".py")
    assert twin_trust.trusted_twins([path]) == [str(twin.resolve())]
    try:
        twin_trust.decide([])
        assert not twin_trust.is_trusted(twin)
        twin_trust.decide([str(twin.resolve())])
        assert twin_trust.is_trusted(twin)
    finally:
        twin_trust.decide(None)


def test_the_setup_the_workers_receive_carries_the_trusted_twins(hostile, trust_twins):
    from viewer.reference_common.setup import RenderSetup
    from viewer.scene import load_scene

    path, scene, _ = hostile
    assert RenderSetup.from_scene(load_scene(scene)).extra["trusted_twins"] == []
    trust_twins(path.parent)
    assert RenderSetup.from_scene(load_scene(scene)).extra["trusted_twins"] == [str(path.with_suffix(".py").resolve())]


def test_the_cli_names_an_unknown_trust_path_in_one_line(capsys, tmp_path):
    rc, out, err = _main(capsys, "models", "--trust-twin", tmp_path / "nope")
    assert rc == 2 and err.count("\n") == 1 and "--trust-twin" in err and "no such file or folder" in err


# ----------------------------------------------------------------------------- misbehaviour

BAD = {
    "exit_at_import": "import sys\nsys.exit(0)\n" + EVAL,
    "exit_in_eval": "def eval(p, wi, wo):\n    import sys\n    sys.exit(0)\n",
    "raise_in_eval": "def eval(p, wi, wo):\n    raise RuntimeError('boom')\n",
    "wrong_shape": "def eval(p, wi, wo):\n    return np.ones((len(wi), 2))\n",
    "none": "def eval(p, wi, wo):\n    return None\n",
    "nan": "def eval(p, wi, wo):\n    return np.full((len(wi), 3), np.nan)\n",
    "sleep_at_import": "import time\ntime.sleep(600)\n" + EVAL,
    "sleep_in_eval": "import time\ndef eval(p, wi, wo):\n    time.sleep(600)\n",
    # well-behaved in the probe's child (its arguments: this twin and its file), asleep in the
    # command's own calls
    "sleep_later": ("import sys, time\ndef eval(p, wi, wo):\n"
                    "    if not (len(sys.argv) == 3 and sys.argv[1].endswith('sleep_later.py')):\n"
                    "        time.sleep(600)\n    return np.full((len(wi), 3), 0.5 / np.pi)\n"),
}
SAYS = {"exit_at_import": "sys.exit(0)", "exit_in_eval": "sys.exit(0)", "raise_in_eval": "RuntimeError: boom",
        "wrong_shape": "shape (4, 2)", "none": "returned None", "nan": "NaN",
        "sleep_at_import": "time limit", "sleep_in_eval": "time limit", "sleep_later": "did not return within 1.5 s"}


def _bad_twin(tmp_path, case) -> Path:
    shutil.copy(DATA / "lambert_twin.brdf", tmp_path / f"{case}.brdf")
    (tmp_path / f"{case}.py").write_text("import numpy as np\n" + BAD[case])
    return tmp_path / f"{case}.brdf"


@pytest.mark.parametrize("case", sorted(BAD))
def test_a_misbehaving_twin_is_one_line_naming_it_and_exit_2(case, tmp_path, capsys, monkeypatch):
    if case.startswith("sleep"):
        monkeypatch.setenv(twin_trust.TIME_LIMIT_ENV, "1.5")
    path = _bad_twin(tmp_path, case)
    rc, out, err = _main(capsys, "check", path, "--trust-twin", tmp_path)
    assert rc == 2 and out == "" and err.count("\n") == 1 and "Traceback" not in err, (out, err)
    assert err.startswith(f"brdf-viewer: error: {case}.py") and SAYS[case] in err, err


@pytest.mark.parametrize("case", ["exit_at_import", "sleep_at_import"])
def test_render_with_a_misbehaving_twin_exits_2_with_one_line(case, tmp_path, capsys, monkeypatch):
    monkeypatch.setenv(twin_trust.TIME_LIMIT_ENV, "1.5")
    _bad_twin(tmp_path, case)
    (tmp_path / "s.toml").write_text(SCENE.replace("hostile.brdf", f"{case}.brdf"))
    rc, out, err = _main(capsys, "render", tmp_path / "s.toml", "--out", tmp_path / "r.png", "--trust-twin", tmp_path)
    assert rc == 2 and err.count("\n") == 1 and f"{case}.py" in err and not (tmp_path / "r.png").exists()


class _Twin:
    """A twin module that passes the probe and misbehaves afterwards (what the wrappers catch)."""

    def __init__(self, result):
        self.result = result

    def eval(self, p, wi, wo):
        if isinstance(self.result, BaseException):
            raise self.result
        return self.result


@pytest.mark.parametrize("result, says", [(SystemExit(0), "called sys.exit(0) in eval"),
                                          (ValueError("bad"), "raised ValueError: bad in eval"),
                                          (None, "returned None"), (np.ones((5, 3)), "shape (5, 3)"),
                                          ("text", "not numbers"), (np.full((4, 3), np.inf), "NaN or Inf")])
def test_every_call_of_a_twin_is_checked(result, says):
    ev, sample, pdf = twin_trust.guarded(Path("t.py"), _Twin(result))
    wi = np.tile([0.0, 0.0, 1.0], (4, 1))
    with pytest.raises(ViewerError) as e:
        ev(None, wi, wi)
    assert str(e.value).startswith("t.py") and says in str(e.value) and "\n" not in str(e.value)
    assert sample is None and pdf is None


def test_a_twin_may_return_one_value_per_pair_and_nan_below_the_horizon():
    ev, _, _ = twin_trust.guarded(Path("t.py"), _Twin(np.array([1.0, 2.0, np.nan])))
    wi = np.array([[0.0, 0.0, 1.0], [0.0, 0.6, 0.8], [0.0, 0.6, -0.8]])
    np.testing.assert_array_equal(ev(None, wi, wi), [[1.0] * 3, [2.0] * 3, [0.0] * 3])


def test_keyboard_interrupt_is_the_users():
    ev, _, _ = twin_trust.guarded(Path("t.py"), _Twin(KeyboardInterrupt()))
    with pytest.raises(KeyboardInterrupt):
        ev(None, np.tile([0.0, 0.0, 1.0], (2, 1)), np.tile([0.0, 0.0, 1.0], (2, 1)))


def test_the_time_limit_is_a_named_constant_the_environment_overrides(monkeypatch):
    monkeypatch.delenv(twin_trust.TIME_LIMIT_ENV, raising=False)
    assert twin_trust.time_limit() == twin_trust.TIME_LIMIT_S
    monkeypatch.setenv(twin_trust.TIME_LIMIT_ENV, "2.5")
    assert twin_trust.time_limit() == 2.5
    monkeypatch.setenv(twin_trust.TIME_LIMIT_ENV, "soon")
    with pytest.raises(ViewerError, match="not a number"):
        twin_trust.time_limit()


def test_a_twin_that_ends_its_process_is_one_line(tmp_path, trust_twins):
    shutil.copy(DATA / "lambert_twin.brdf", tmp_path / "gone.brdf")
    (tmp_path / "gone.py").write_text("import os\nos._exit(3)\n")
    trust_twins(tmp_path)
    with pytest.raises(ViewerError) as e:
        brdf.load(tmp_path / "gone.brdf")
    assert str(e.value).startswith("gone.py: ") and "exit status 3" in str(e.value)


# ----------------------------------------------------------------------------- the window's question


@pytest.fixture
def twin_session(gl_ctx, renderer):
    from viewer.app.session import Session

    made = []

    def make(scene=None, state=None):
        from viewer.scene import load_scene

        s = Session(gl_ctx, "default", scene=load_scene(scene) if scene else None, renderer=renderer,
                    prefetch=False, state=state)
        s.warm = []
        made.append(s)
        return s

    yield make
    for s in made:
        s.release()


def test_the_window_asks_before_running_a_twin_and_not_now_keeps_it_off(hostile, twin_session):
    path, scene, marker = hostile
    s = twin_session(scene)   # a scene file naming the .brdf grants nothing: it asks
    brdf_path, twin = s.twins.current
    assert brdf_path.name == "hostile.brdf" and twin.name == "hostile.py"
    assert str(twin.resolve()) in s.twins.question() and "hostile.brdf" in s.twins.question()
    s.twins.answer(False)
    assert s.twins.current is None and "not now" in s.status and not marker.exists()
    assert "trusted_twin_folders" not in s.state
    s.open_files([str(path)])   # a drop of the same folder's file: not asked again this session
    assert s.twins.current is None and not marker.exists()
    s.render_view((16, 12))     # the file draws without its twin
    assert not marker.exists()


def test_running_the_twin_trusts_its_folder_remembered_in_the_state_file(hostile, tmp_path, twin_session):
    from viewer.app import state as state_mod

    path, scene, marker = hostile
    s = twin_session()
    s.open_files([str(path.parent)])   # a dropped folder grants nothing either
    assert s.twins.current is None and not marker.exists() and not twin_trust.is_trusted(path.with_suffix(".py"))
    s.open_files([str(path)])          # a dropped file: the question names it
    assert s.twins.current[1].name == "hostile.py" and not marker.exists()
    s.twins.answer(True)
    assert s.twins.current is None and twin_trust.is_trusted(path.with_suffix(".py"))
    assert brdf.load(path).twin is not None and marker.is_file()
    folder = str(path.parent.resolve())
    assert s.state["trusted_twin_folders"] == [folder]
    assert s.save_state(path=tmp_path / "state.toml")
    saved = state_mod.load_state(tmp_path / "state.toml")
    assert saved["trusted_twin_folders"] == [folder]
    # the next session trusts the remembered folder without asking
    twin_trust.forget()
    assert not twin_trust.is_trusted(path.with_suffix(".py"))
    s2 = twin_session(scene, state=saved)
    assert s2.twins.current is None and twin_trust.is_trusted(path.with_suffix(".py"))


def test_a_twin_that_misbehaves_once_trusted_in_the_window_is_one_error(tmp_path, twin_session):
    path = _bad_twin(tmp_path, "raise_in_eval")
    s = twin_session()
    s.open_files([str(path)])
    assert s.twins.current[1].name == "raise_in_eval.py"
    s.twins.answer(True)
    assert s.messages[-1].error and s.status.startswith("raise_in_eval.py:3: ") and "RuntimeError: boom" in s.status


def test_a_damaged_trusted_folder_list_in_the_state_file_is_ignored(tmp_path, capsys):
    from viewer.app import state as state_mod

    (tmp_path / "state.toml").write_text('trusted_twin_folders = [1, 2]\nui_scale = 1.5\n')
    st = state_mod.load_state(tmp_path / "state.toml")
    assert st == {"ui_scale": 1.5} and "trusted_twin_folders: ignored" in capsys.readouterr().err


@pytest.mark.skipif(not HAVE_X, reason="needs Xvfb (apt-get install xvfb) or a display")
def test_the_window_draws_the_question_as_a_modal_naming_the_file(display, hostile):
    path, scene, marker = hostile
    r = run_py(f"""
        from viewer.app.main import App
        from viewer.app.panels import twin_dialog
        shown = []
        draw = twin_dialog.draw
        twin_dialog.draw = lambda imgui, q: shown.append((draw(imgui, q), q.question())) or shown[-1][0]
        app = App({str(scene)!r}, size=(640, 400), restore_state=False)
        app.session.warm = []
        for _ in range(3):
            app.frame(wait=False)
        print("SHOWN", shown[-1][0], "hostile.py" in shown[-1][1])
        app.session.twins.answer(False)
        app.frame(wait=False)
        print("AFTER", shown[-1][0])
        app.close()
        """, display)
    assert r.returncode == 0, r.stderr[-3000:]
    assert "SHOWN True True" in r.stdout and "AFTER False" in r.stdout, r.stdout
    assert not marker.exists()


@pytest.mark.skipif(not HAVE_X, reason="needs Xvfb (apt-get install xvfb) or a display")
def test_the_window_with_a_trusted_twin_that_exits_exits_2_with_one_line(display, tmp_path):
    _bad_twin(tmp_path, "exit_at_import")
    (tmp_path / "s.toml").write_text(SCENE.replace("hostile.brdf", "exit_at_import.brdf"))
    r = run_py(f"""
        import sys
        from viewer.commands.cli import main
        sys.exit(main([{str(tmp_path / 's.toml')!r}, "--frames", "2", "--trust-twin", {str(tmp_path)!r}]))
        """, display)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "Traceback" not in r.stderr, r.stderr[-2000:]
    assert r.stderr.startswith("brdf-viewer: error: exit_at_import.py: the numpy twin called sys.exit(0)")


@pytest.mark.parametrize("command", ["render", "reference", "compare", "bake", "plot", "models", "check", None])
def test_every_command_that_opens_materials_takes_trust_twin(command, capsys):
    from viewer.commands.cli import main

    with pytest.raises(SystemExit) as e:
        main(([command] if command else []) + ["--help"])
    assert e.value.code == 0 and "--trust-twin PATH" in capsys.readouterr().out
