"""clockwork: pendulum-clock FMUs and a co-simulation master on fmpy."""

__version__ = "0.1.0"
