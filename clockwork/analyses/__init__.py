"""Analyses: what a scene measures at each sweep point.

``registry`` (the bottom of the layer) holds the kinds; ``context`` gives an
analysis the scene at its point (effective parameters, the wired system);
``keys`` checks analysis-table values. The kinds, by figure family:
``time_series`` (time_series, ticks), ``steady_state``, ``ziemkiewicz``
(Figs. 1-11 of Ziemkiewicz), ``hoyng`` (Figs. 3-6, App. C of Hoyng) and
``environment`` (the clock in air: barometric and thermal coefficients, a
year of weather).
Importing this package registers every kind.
"""

from . import environment, hoyng, steady_state, time_series, ziemkiewicz  # noqa: F401  (each registers its kinds)
from .registry import ANALYSES, register, register_analysis, run_analysis

__all__ = ["ANALYSES", "register", "register_analysis", "run_analysis"]
