"""The window's Monte Carlo views under Xvfb: the reference's strategy from the *Reference*
settings reaches the renderer, the error views are the running variance's maps (drawn with a
colour bar), the convergence curve grows and is stored for comparison, and the plots window's
Sampling tab draws."""

import textwrap
import subprocess
import sys

from gui_harness import HANG_S, window_env

import pytest

pytestmark = pytest.mark.skipif(__import__("shutil").which("Xvfb") is None
                                and not __import__("os").environ.get("DISPLAY"), reason="needs Xvfb")


def test_error_views_convergence_and_sampling_tab(display, tmp_path):
    from reference_harness import GLOSSY_STUDIO

    scene = tmp_path / "glossy.toml"
    scene.write_text(GLOSSY_STUDIO)
    code = f"""
        import time
        import numpy as np
        from viewer.app.main import App
        from viewer.image.variance import standard_error, relative_error, samples_needed
        app = App({str(scene)!r}, size=(480, 300))
        app.frame()
        raster = app.capture_window()
        rv = app.session.reference_view()
        app.session.monte_carlo.set_options(rv, strategy="bsdf")
        app.session.monte_carlo.view = "standard error"
        app.session.monte_carlo.show_convergence = True
        app.plots.visible = True
        app.plots.select_tab("Sampling")
        t0 = time.time()
        # at least 4 spp and two passes on the convergence curve (a pass may add several spp:
        # waiting for the spp alone left one point where the reference ran slower)
        while (rv.snapshot() is None or rv.spp < 4 or len(rv.curve) < 2) and time.time() - t0 < 600:
            app.frame()
        assert rv.spp >= 4 and len(rv.curve) >= 2, rv.error
        assert rv.setup.strategy == "bsdf"
        app.frame()
        # one snapshot for both sides: the reference keeps adding passes meanwhile
        snap = rv.snapshot()
        mean, var, spp = snap.mean, snap.variance, snap.spp
        for view, expect in (("standard error", standard_error(var)), ("relative error", relative_error(mean, var)),
                             ("samples needed", samples_needed(mean, var, spp, app.session.monte_carlo.target))):
            app.session.monte_carlo.view = view
            err, rgb = app.session.monte_carlo.heat_map(snap)
            np.testing.assert_allclose(err, np.where(np.isfinite(expect), expect, 0.0), rtol=1e-12)
        app.session.monte_carlo.view = "relative error"
        times = []
        for _ in range(4):
            app.session.monte_carlo.invalidate()  # force a recompute, to time it
            app.frame()
            times.append(app.session.monte_carlo.view_ms)
        shot = app.capture_window()
        assert np.abs(shot.astype(float) - raster).mean() > 1.0
        from PIL import Image
        Image.fromarray(shot).save({str(tmp_path / 'mc.png')!r})
        n = len(rv.curve)
        assert n >= 2 and rv.curve.label == "bsdf"
        assert app.session.monte_carlo.store_curve(rv) and app.session.monte_carlo.stored.label.startswith("BSDF sampling")
        app.session.monte_carlo.set_options(rv, strategy="mis")
        app.frame()
        assert rv.curve.label == "mis" and len(app.session.monte_carlo.stored) == n
        t0 = time.time()
        while len(rv.curve) < 2 and time.time() - t0 < 600:
            app.frame()
        assert rv.setup.strategy == "mis"
        app.frame()
        Image.fromarray(app.capture_window()).save({str(tmp_path / 'mc2.png')!r})
        print("VIEW_MS", " ".join(f"{{t:.2f}}" for t in times), "size", mean.shape)
        app.glfw.set_window_should_close(app.window, True)
        app.run()
        print("MC OK")
    """
    r = subprocess.run([sys.executable, "-c", textwrap.dedent(code)], env=window_env(display), capture_output=True,
                       text=True, timeout=HANG_S)
    assert r.returncode == 0, r.stderr[-3000:] + r.stdout
    assert "MC OK" in r.stdout
    print(r.stdout)
