"""The reference loop in clockwork's configuration is clockwork's master.

clockwork's master with MasterSettings(order="jacobi", extrapolation=0,
event_location=False) and reference_loop.run(..., time="grid",
sampling="fresh", start="consistent") must give the same numbers: the tool
tests compare each tool with the same loop switched to the tool's
conventions, so this test is what ties the tools to clockwork's master.
"""

import numpy as np
import pytest

import reference_loop
from interop_common import RELATIVE_TOLERANCE, SCENES, compared, relative_difference, scene, steps

from clockwork.analyses.context import build_system

JACOBI_ZOH = {("master", "order"): "jacobi", ("master", "extrapolation"): 0, ("master", "event_location"): False}


def master_run(sc, n: int, names: list[str]) -> dict:
    record: dict[str, list[str]] = {}
    for name in names:
        inst, var = name.split(".")
        record.setdefault(inst, []).append(var)
    times, values = [], {n_: [] for n_ in names}
    with build_system(sc, JACOBI_ZOH, record=record) as sysm:
        def on_point(m):
            times.append(m.t)
            for name in names:
                inst, var = name.split(".")
                values[name].append(sysm.output(inst, var))

        sysm.master.run_until(sc.experiment.start + n * sc.master.step, on_point)
    return {"time": np.array(times), **{k: np.array(v) for k, v in values.items()}}


@pytest.mark.parametrize("name", SCENES)
def test_loop_in_clockwork_configuration_equals_master(name):
    sc = scene(name)
    n = steps(sc)
    names = compared(sc)
    master = master_run(sc, n, names)
    loop = reference_loop.run_as("clockwork", sc, n, names)
    assert len(master["time"]) == n
    assert np.array_equal(master["time"], loop["time"])
    for var in names:
        d = relative_difference(loop[var], master[var])
        print(f"{name}: {var}: loop(clockwork) vs master, relative {d:.3g}")
        assert d <= RELATIVE_TOLERANCE, (var, d)
    # The tools' convention (feedthrough outputs one step late) is a
    # different algorithm: the comparison above can tell them apart.
    held = reference_loop.run(sc, n, names[:1], time="grid", sampling="held", start="consistent")
    d = relative_difference(held[names[0]], master[names[0]])
    print(f"{name}: held sampling vs master, relative {d:.3g}")
    assert d > 1e3 * RELATIVE_TOLERANCE
