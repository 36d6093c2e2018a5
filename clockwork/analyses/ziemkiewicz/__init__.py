"""Ziemkiewicz, Phys. Rev. E 103, 062208 (2021), by figure.

``free_period`` Fig. 1; ``escapement`` Figs. 2-6; ``disturbance`` Fig. 7;
``limit_cycle`` Fig. 8(a); ``vibration`` Figs. 8(b), 9; ``rate_error``
Fig. 10(a); ``lyapunov`` Fig. 10(b); ``step_accuracy`` Fig. 11. ``clock``
and ``parts`` hold what they share.
"""

from . import disturbance, escapement, free_period, limit_cycle, rate_error  # noqa: F401  (they register)
from .clock import Clock
from .lyapunov import running_exponent
from .step_accuracy import euler_a1_period
from .vibration import section_statistics

__all__ = ["Clock", "euler_a1_period", "running_exponent", "section_statistics"]
