"""Plots: PNG files of a scene's results. ``registry`` holds the kinds;
``basic``, ``outputs`` (the default plot of a time series), ``ziemkiewicz``,
``chaos``, ``hoyng`` and ``stability`` define them;
``background`` draws them in a second process. Importing this package
registers every kind."""

from . import basic, chaos, hoyng, outputs, stability, ziemkiewicz  # noqa: F401  (each registers its kinds)
from .background import Plotter
from .registry import PLOTS, make_plots, register

__all__ = ["PLOTS", "Plotter", "make_plots", "register"]
