"""The notebook widget's costs (docs/notebook.md):

    python benchmarks/notebook.py [--repeat 15] [--no-notebook]

For 480x270 and 960x540: the time from a roughness slider change to the frame (the value set
through the editor's slider, validated, the raster drawn and read back), the BRDF plot's redraw
that follows a resting slider, and the bytes jupyter_rfb sends per frame: JPEG (quality 80) while
interacting, PNG once still. Then the wall time of executing examples/explore.ipynb with nbclient
on a headless kernel (at the notebook's own size, 480x270, its reference on every core)."""

import argparse
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def slider_frames(size, repeat):
    from jupyter_rfb._utils import array2compressed   # what the widget sends, encoded the same way

    from viewer.notebook import NotebookView, load_view_scene
    from viewer.notebook.controls import MaterialEditor

    view = NotebookView(load_view_scene("default"), *size)
    editor = MaterialEditor(lambda: view.scene.materials["ball"], view.set, "materials.ball.")
    slider = editor.controls["roughness r"]
    view.frame()   # compiles the programs
    times, jpeg, png = [], [], []
    for k in range(repeat):
        t = time.perf_counter()
        slider.value = 0.3 + 0.02 * (k % 10)
        frame = view.frame()
        times.append(time.perf_counter() - t)
        jpeg.append(len(array2compressed(frame, 80)[1]))
        png.append(len(array2compressed(frame, 100)[1]))
    from viewer.plots import figure, render_figure

    plot = []
    for k in range(max(3, repeat // 3)):
        t = time.perf_counter()
        render_figure(figure(view.scene.materials["ball"], "polar", name="ball", samples=20_000), 420, 280, ss=2)
        plot.append(time.perf_counter() - t)
    view.close()
    return statistics.median(times), statistics.median(jpeg), statistics.median(png), statistics.median(plot)


def notebook_time():
    import nbclient
    import nbformat

    nb = nbformat.read(ROOT / "examples" / "explore.ipynb", as_version=4)
    t = time.perf_counter()
    nbclient.NotebookClient(nb, timeout=600, kernel_name="python3",
                            resources={"metadata": {"path": str(ROOT)}}).execute()
    return time.perf_counter() - t


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=15)
    ap.add_argument("--no-notebook", action="store_true", help="skip the nbclient run")
    a = ap.parse_args(argv)
    for size in ((480, 270), (960, 540)):
        ms, jpeg, png, plot = slider_frames(size, a.repeat)
        print(f"{size[0]}x{size[1]}: slider change -> frame {1000 * ms:.1f} ms (median of {a.repeat}); "
              f"sent per frame: JPEG {jpeg / 1024:.1f} KiB interacting, PNG {png / 1024:.1f} KiB still; "
              f"plot redraw {1000 * plot:.0f} ms")
    if not a.no_notebook:
        import os

        os.environ["PYTHONPATH"] = os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])
        print(f"examples/explore.ipynb with nbclient: {notebook_time():.1f} s")


if __name__ == "__main__":
    main()
