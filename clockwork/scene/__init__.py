"""The scene: the file format that says what to simulate and how.

``load``: loading, ``--set`` overrides and strict validation; ``model``:
the frozen, validated ``Scene``; ``units``: quantities with units;
``sweep``: the sweep specification; ``kinds``: what the analysis and plot
tables may hold; ``ssp``: the same scene written as an SSP 1.0 archive for
other FMI tools. The format is documented in docs/scenes.md.
"""

from typing import TYPE_CHECKING

__all__ = ["NO_KINDS", "Invalid", "Kinds", "load_scene", "parse_override", "Component", "Connection",
           "Experiment", "Record", "Scene", "Sweep", "SweepAxis"]

if TYPE_CHECKING:  # what __getattr__ gives, for readers, type checkers and the API docs
    from .kinds import NO_KINDS, Invalid, Kinds
    from .load import load_scene, parse_override
    from .model import Component, Connection, Experiment, Record, Scene, Sweep, SweepAxis


def __getattr__(name: str):
    # Imported on first use: scene.kinds imports without the loader, the
    # engine and fmpy (the plot process's start-up time;
    # clockwork.results.plots.background).
    if name in ("NO_KINDS", "Invalid", "Kinds"):
        from . import kinds as home
    elif name in ("load_scene", "parse_override"):
        from . import load as home
    elif name in __all__:
        from . import model as home
    else:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(home, name)
