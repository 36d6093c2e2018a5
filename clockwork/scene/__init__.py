"""The scene: the file format that says what to simulate and how.

``load``: loading, ``--set`` overrides and strict validation; ``model``:
the frozen, validated ``Scene``; ``units``: quantities with units;
``sweep``: the sweep specification; ``kinds``: what the analysis and plot
tables may hold; ``ssp``: the same scene written as an SSP 1.0 archive for
other FMI tools. The format is documented in docs/scenes.md.
"""

from .kinds import NO_KINDS, Invalid, Kinds
from .load import load_scene, parse_override
from .model import Component, Connection, Experiment, MasterConfig, Record, Scene, Sweep, SweepAxis

__all__ = ["NO_KINDS", "Invalid", "Kinds", "load_scene", "parse_override", "Component", "Connection",
           "Experiment", "MasterConfig", "Record", "Scene", "Sweep", "SweepAxis"]
