"""BRDF plots: the data (pure numpy, computed with the registry's Python twins) and a headless
drawing of them with Pillow.

The GUI (``viewer.app.plots_panel``) and ``brdf-viewer plot`` both call the data functions below,
so what is plotted is exactly what ``viewer.brdf`` computes:

* ``polar_lobe``: f(wi, wo) and f(wi, wo) cos(theta_o) in the plane of incidence (BRDF Explorer's
  polar plot). The plane is the one through the normal at azimuth ``phi`` (0 = the x-z plane
  that holds the tangent, 90 = the y-z plane that holds the bitangent: the two planes of an
  anisotropic model). wi = (sin t_i cos phi, sin t_i sin phi, cos t_i) and
  wo = (-sin t_o cos phi, -sin t_o sin phi, cos t_o) for t_o in [-90, 90] degrees: t_o > 0 lies
  on the mirror side (the mirror direction is t_o = theta_i), t_o < 0 on the side of the light
  (t_o = -theta_i is the retro-reflection direction). The integral of f cos(t_o) over the
  hemisphere of wo is the directional albedo.
* ``lobe_3d``: f cos(theta_o) over the hemisphere of wo as a surface (radius = value).
* ``albedo_curve``: directional albedo vs angle (the furnace curve), ``viewer.brdf.albedo``.
* ``fresnel_curves``: R_s, R_p and R vs the angle of incidence from ``viewer.brdf.fresnel``, with
  Brewster's angle atan(n2/n1) and, leaving the denser medium, the critical angle asin(n2/n1).
* ``bouguer_curve``: Bouguer's (Beer-Lambert) law T(d) = exp(-sigma_a d).
* ``sampling_histogram``: the model's importance sampler at a fixed direction: the histogram of
  sampled directions in (cos theta, phi) cells beside the pdf integrated over the same cells,
  their difference in standard deviations and the chi-square p-value, all from
  ``viewer.brdf.chi2`` (the test suite's chi-square test), plus a point cloud of samples.

``figure`` turns one of them into a ``Figure`` (labelled curves and marks), ``render_figure``
draws it as an RGB image and ``figure_json`` gives the plotted numbers (the PNG's
``brdf-viewer:plot`` text chunk).

The package: ``kinds`` (which plots apply to a material, the checks of a kind and a channel),
``data`` (the curves above), ``figure_types`` (``Figure``, ``Curve``, ``Mark``), ``figures``
(``figure``: curves, marks, notes of one kind),
``canvas`` (the Pillow drawing library: canvas, ticks, fonts, colour map, legend and label
placement), ``draw`` (each kind drawn; ``render_figure``), ``png`` (the PNG with its JSON),
``spectral`` (n, k and R(theta, lambda) of a spectral table) and ``measured`` (the Rusinkiewicz
slice of a measured BRDF).
"""

from viewer.plots.canvas import CHANNEL_COLOURS, CHANNEL_NAMES, colormap, nice_ceil, nice_ticks, tick_label
from viewer.plots.data import (SAMPLING_COLS, SAMPLING_ROWS, albedo_curve, bouguer_curve, direction, fresnel_curves,
                               lobe_3d, plane_directions, polar_lobe, sampling_histogram)
from viewer.plots.draw import render_figure
from viewer.plots.figure_types import Curve, Figure, Mark
from viewer.plots.figures import figure, params_summary
from viewer.plots.kinds import (CHANNELS, KINDS, LUMINANCE, absorption_source, applicable_kinds, as_params,
                                check_channel, check_kind, check_kind_name, fresnel_source, reduce_channel,
                                sampling_delta, spectral_source)
from viewer.plots.png import PNG_KEY, figure_json, read_plot_data, write_plot

__all__ = [
    "CHANNELS", "CHANNEL_COLOURS", "CHANNEL_NAMES", "KINDS", "LUMINANCE", "PNG_KEY", "SAMPLING_COLS", "SAMPLING_ROWS",
    "Curve", "Figure", "Mark", "absorption_source", "albedo_curve", "applicable_kinds", "as_params",
    "bouguer_curve", "check_channel", "check_kind", "check_kind_name", "colormap", "direction", "figure",
    "figure_json", "fresnel_curves", "fresnel_source", "lobe_3d", "nice_ceil", "nice_ticks", "params_summary",
    "plane_directions", "polar_lobe", "read_plot_data", "reduce_channel", "render_figure", "sampling_delta",
    "sampling_histogram", "spectral_source", "tick_label", "write_plot",
]
