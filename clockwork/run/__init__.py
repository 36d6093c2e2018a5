"""Run: a scene's points through the analyses into results.

``catalog.load_scene`` validates a scene against every registered analysis
and plot kind; ``points`` runs one point; ``scene_run.run_scene`` runs them
all (here, in a local process pool from ``pool``, or on Dask from
``dask``) and writes the results; ``gallery`` runs every scene.
"""

from .catalog import load_scene
from .points import point_key, run_point
from .scene_run import run_scene

__all__ = ["load_scene", "point_key", "run_point", "run_scene"]
