"""Scene files checked against every analysis and plot kind there is.

``load_scene`` is clockwork.scene.load_scene with the kinds that the
analyses and the plots register (importing them registers them all).
"""

from __future__ import annotations

import os

from ..analyses import registry as analyses
from ..results.plots import registry as plots
from ..scene import Kinds
from ..scene import load_scene as _load_scene


def kinds() -> Kinds:
    return Kinds(analyses.ANALYSIS_KEYS, analyses._ANALYSIS_CONVERT, plots.PLOT_KEYS, plots._PLOT_CONVERT)


def load_scene(path: str | os.PathLike, overrides=()):
    """Load, override and validate a scene file; raises SceneError."""
    return _load_scene(path, overrides, kinds())
