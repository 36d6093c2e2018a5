"""Hoyng, Am. J. Phys. 82, 1053 (2014), by figure.

``stationary`` Fig. 3 and App. C; ``torque_jump`` Figs. 4, 5;
``long_run`` Fig. 6 (co-simulated); ``averaged_run`` Fig. 6 (model
equations). ``common`` holds what they share.
"""

from . import averaged_run, long_run, stationary, torque_jump  # noqa: F401  (they register)
from .common import escapement_noise

__all__ = ["escapement_noise"]
