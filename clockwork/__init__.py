"""clockwork: pendulum-clock FMUs and a co-simulation master on fmpy."""

from .version import __version__

__all__ = ["__version__", "load", "simulate"]


def __getattr__(name: str):
    # Imported on first use: `clockwork` (the command) starts without NumPy and the engine.
    if name == "simulate":
        from .api import simulate

        return simulate
    if name == "load":
        from .results.load import load

        return load
    raise AttributeError(f"module 'clockwork' has no attribute {name!r}")
