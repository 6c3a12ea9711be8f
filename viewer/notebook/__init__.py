"""The viewer in a Jupyter notebook (docs/notebook.md): ``Viewer``, a ``jupyter_rfb`` widget with
the raster view, orbit and dolly, the material editors, the progressive reference and the BRDF
plots. Needs the ``[notebook]`` extra (jupyter_rfb, ipywidgets): without it, importing this
package raises one ``ViewerError`` line saying what to install."""

from viewer.base.optional import require

require("ipywidgets")
require("jupyter_rfb")

from viewer.notebook.view import NotebookView, load_view_scene  # noqa: E402
from viewer.notebook.widget import Viewer  # noqa: E402

__all__ = ["NotebookView", "Viewer", "load_view_scene"]
