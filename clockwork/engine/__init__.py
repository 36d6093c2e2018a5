"""The engine: co-simulation of FMUs: FMI 1.0, 2.0 and 3.0 Co-Simulation, FMI 2.0
and 3.0 Model Exchange (each with an integrator of the engine's own).

It makes instances of FMUs through one factory (``instances``; the
faces, one per FMI version and interface, are in ``clockwork.fmi`` behind
the instance contract ``fmi/contract.py``; ``model_exchange``,
``me_step``, ``rk``, ``cvode``: a Model Exchange face composed with an
integrator, stepped as a Co-Simulation instance),
wires them (``wiring``, ``ports``, ``loops``: algebraic loops), steps them (``master``: the loop; ``coupling``, ``location``,
``checkpoints``, ``richardson``: what makes a step accurate; ``recording``:
what is kept of a run) and shoots for periodic orbits (``shooting``). It
knows nothing of scene files, papers, plots or result files.
"""

from typing import TYPE_CHECKING

__all__ = ["Marks", "Master", "MasterSettings", "Statistics", "System"]

if TYPE_CHECKING:  # what __getattr__ gives, for readers, type checkers and the API docs
    from .marks import Marks
    from .master import Master
    from .settings import MasterSettings, Statistics
    from .system import System


def __getattr__(name: str):
    # Imported on first use: a module of the engine (names, description)
    # imports without the master and fmpy's simulation (the plot process's
    # start-up time; clockwork.results.plots.background).
    if name == "Master":
        from . import master as home
    elif name == "Marks":
        from . import marks as home
    elif name in ("MasterSettings", "Statistics"):
        from . import settings as home
    elif name == "System":
        from . import system as home
    else:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(home, name)
