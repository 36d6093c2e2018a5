"""The engine: co-simulation of FMI 1.0, 2.0 and 3.0 Co-Simulation FMUs, and nothing else.

It loads FMUs (``description``; ``fmu``, ``fmu1``, ``fmu3``: an instance
of each version behind the same calls), wires them (``wiring``, ``ports``,
``loops``: algebraic loops),
steps them (``master``: the loop; ``coupling``, ``location``,
``checkpoints``, ``richardson``: what makes a step accurate; ``recording``:
what is kept of a run) and shoots for periodic orbits (``shooting``). It
knows nothing of scene files, papers, plots or result files.
"""

from .master import Master
from .settings import MasterSettings, Statistics
from .system import System

__all__ = ["Master", "MasterSettings", "Statistics", "System"]
