"""Figures of sweep results and traces, one module per family of figures.

Every ``plot_*`` function returns a matplotlib Figure (drawn in a notebook, saved with
:func:`save_figure`); those with one panel draw on a given ``ax=`` instead. Figures are
made without pyplot, so nothing here selects a backend or keeps figures open;
matplotlib is imported on first use, so importing the package stays light.

``maps`` (phase diagrams, maps of a variable, refined results and their boundaries),
``bifurcation`` (bifurcation and orbit diagrams), ``trace`` (time series),
``catalogue`` (a run's slip events), ``floquet`` (how stable each cycle is), ``kicks``
(the critical kick), ``basins`` (basin fractions), ``nblock`` (the N-block figure);
``common``: what they share (colours, labels, titles, saving).
"""

from .basins import plot_basin_fractions
from .bifurcation import plot_bifurcation, plot_orbit_diagram
from .catalogue import plot_catalogue, plot_threshold_sensitivity
from .common import save_figure
from .floquet import plot_floquet
from .kicks import plot_critical_kick
from .maps import plot_refined, plot_result, plot_variable, plottable
from .nblock import plot_nblock
from .trace import draw_trace, plot_trace

__all__ = [
    "draw_trace",
    "plot_basin_fractions",
    "plot_bifurcation",
    "plot_catalogue",
    "plot_critical_kick",
    "plot_floquet",
    "plot_nblock",
    "plot_orbit_diagram",
    "plot_refined",
    "plot_result",
    "plot_threshold_sensitivity",
    "plot_trace",
    "plot_variable",
    "plottable",
    "save_figure",
]
