"""clockwork's accurate run of the core scenes, the yardstick of the tool
tests' second check, against the monolithic scipy solution
(clockwork.physics.reference: DOP853 with every switch located).

Its own error must be negligible next to the fixed-step errors it
measures (0.007 to 0.024 s on the 100th tick): at most 1e-4 s on every
one of the first 100 tick times.
"""

import math

import numpy as np
import pytest

import prediction
from interop_common import PERIODS, SCENES, scene

from clockwork.physics import reference


def _value(sc, inst, name):
    return prediction._value(sc, inst, name)


@pytest.mark.parametrize("name", SCENES)
def test_accurate_run_matches_monolithic_reference(name):
    sc = scene(name)
    stop = sc.experiment.stop
    vib = None
    if "vibration" in sc.components:
        vib = reference.Vibration(**{k: _value(sc, "vibration", k) for k in
                                     ("gamma2", "omega02", "kappa", "C1", "C2", "a2_start", "a2dot_start")})
        assert math.isclose(_value(sc, "vibration", "inertia"), _value(sc, "pendulum", "m") * _value(sc, "pendulum", "L") ** 2)
    drag = {k: _value(sc, "drag", k) for k in ("c1", "c2")} if "drag" in sc.components else {}
    params = reference.ClockParams(
        L=_value(sc, "pendulum", "L"), m=_value(sc, "pendulum", "m"), g=_value(sc, "pendulum", "g"),
        Q=_value(sc, "pendulum", "Q"), escapement="grasshopper", torque=_value(sc, "escapement", "torque"),
        phi_r=_value(sc, "escapement", "phi_r"), vibration=vib, **drag)
    ref = reference.simulate(params, _value(sc, "pendulum", "phi_start"), _value(sc, "pendulum", "w_start"), stop)
    ours = prediction.accurate_run(sc, stop)
    assert len(ref.ticks) >= PERIODS and len(ours.ticks) >= PERIODS
    d = np.abs(ours.ticks[:PERIODS] - ref.ticks[:PERIODS])
    print(f"{name}: accurate run vs monolithic reference: max tick difference {d.max():.3g} s "
          f"(tick {PERIODS}: {d[-1]:.3g} s)")
    assert d.max() <= 1e-4
