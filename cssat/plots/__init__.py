"""Figures of the experiments and sweeps, as matplotlib ``Figure`` objects.

Every function returns a :class:`matplotlib.figure.Figure` built without pyplot, so nothing here
switches matplotlib's backend or touches a notebook's open figures: show one in a notebook by
leaving it as a cell's value, save it with :func:`save_figure` (atomic) or ``fig.savefig``.

Modules: :mod:`~cssat.plots.base` (saving, image panels), :mod:`~cssat.plots.paper` (the paper's
Fig. 9–14), :mod:`~cssat.plots.scene` (Fig. 4–5), :mod:`~cssat.plots.grids` (sweeps and grids).
"""

from cssat.plots.base import FIGURE_FORMATS, error_panels, image_panels, light_curve_image, save_figure
from cssat.plots.grids import WORDS, grid_curves_figure, grid_images_figure, grid_maps_figure, sweep_figure
from cssat.plots.paper import sim1_figure, sim2_figure, sim3_figures
from cssat.plots.scene import atmosphere_figure, lightcurve_figure, observations_figure

__all__ = ["image_panels", "error_panels", "FIGURE_FORMATS", "sim1_figure", "sim2_figure", "sim3_figures",
           "grid_images_figure", "grid_maps_figure", "grid_curves_figure", "lightcurve_figure",
           "atmosphere_figure", "observations_figure", "sweep_figure", "light_curve_image", "save_figure", "WORDS"]
