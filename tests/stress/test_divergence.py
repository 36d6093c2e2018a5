"""Divergence past the stability limit is reported cleanly.

The diverging case is inside the swept range of test_stability_limits:
Jacobi order, quadratic extrapolation, step 1.28 s, kappa = 0, C2 = 5 (the
pendulum is pumped until it spins; |phi| passes the master's divergence
limit of 1e8 after about 440 s).
"""

import json
import math
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from stress_support import FMU_DIR, ROOT, fmus  # noqa: F401 (first: puts benchmarks/ on sys.path)
import stability as st  # noqa: E402
from clockwork.errors import SimulationError

DIVERGING = dict(coupling=st.Coupling(0.0, 5.0), config=st.Config("jacobi", 2), step=1.28)
STOP_S = 1000.0


def test_master_names_time_instance_and_variable():
    samples = []
    with st.vibration_system(DIVERGING["coupling"], DIVERGING["config"].settings(DIVERGING["step"])) as s:
        m = s.master
        names = [(n, p.out_names) for n, p in m.ports.items()]
        with pytest.raises(SimulationError) as e:
            m.run_until(STOP_S, lambda master: samples.append([x for _, p in master.ports.items() for x in p.out]))
        t_fail = m.t
    err = e.value
    assert err.time is not None and 0.0 < err.time < STOP_S
    assert err.instance in ("pendulum", "vibration")
    assert err.variable in dict(names)[err.instance]
    assert f"{err.instance}.{err.variable}" in str(err) and "t = " in str(err)
    assert "\n" not in str(err)
    # Nothing past the limit reached the caller: every sampled value is finite and below it.
    assert samples and np.all(np.isfinite(samples)) and np.max(np.abs(samples)) < 1e8
    assert t_fail == pytest.approx(err.time)


SCENE = textwrap.dedent("""\
    connections = [
      "pendulum.phi -> vibration.a1",
      "vibration.tau -> pendulum.tau_coupling",
    ]

    [scene]
    title = "Pendulum and mechanism vibration past the stability limit"

    [components.pendulum]
    fmu = "Pendulum"
    parameters = {{ Q = 0, phi_start = "5 deg", rtol = 1e-11, atol = 1e-13 }}

    [components.vibration]
    fmu = "MechanismVibration"
    parameters = {{ kappa = 0.0, C1 = 1.0, C2 = 5.0, a2_start = 1e-3, rtol = 1e-11, atol = 1e-13 }}

    [experiment]
    stop = "{stop} s"

    [master]
    step = "1.28 s"
    order = "jacobi"
    extrapolation = 2

    [record]
    outputs = ["pendulum.phi", "vibration.a2"]

    [analysis]
    kind = "time_series"
    {sweep}
    [[plot]]
    kind = "{plot}"
    x = "{x}"
    y = ["{y}"]
    title = "a2"
    file = "a2.png"
    """)


def _clockwork(tmp_path, sweep: bool):
    text = SCENE.format(stop=STOP_S, sweep=(
        '\n[sweep]\naxes = [ { parameter = "master.step", values = ["0.64 s", "1.28 s"] } ]\n' if sweep else ""),
        plot="sweep" if sweep else "time_series", x="master.step" if sweep else "time",
        y="t_end_s" if sweep else "vibration.a2")
    scene = tmp_path / "diverging.toml"
    scene.write_text(text)
    out = tmp_path / "out"
    env = dict(os.environ, CLOCKWORK_FMU_DIR=str(FMU_DIR), PYTHONPATH=str(ROOT))
    proc = subprocess.run([sys.executable, "-m", "clockwork", "run", str(scene), "--out", str(out), "--no-progress"],
                          capture_output=True, text=True, env=env, timeout=300)
    return proc, out


def test_clockwork_run_of_a_diverging_scene(tmp_path):
    proc, out = _clockwork(tmp_path, sweep=False)
    assert proc.returncode == 1, (proc.stdout, proc.stderr)
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith("clockwork: error: t = ")
    assert "exceeds the divergence limit" in lines[0]
    assert "pendulum." in lines[0] or "vibration." in lines[0]
    # The history up to the last good communication point is kept (issue 26): every row finite,
    # and the summary says failed, when, where and why.
    failed = json.loads((out / "summary.json").read_text())["result"]["failed"]
    assert failed["instance"] in ("pendulum", "vibration") and "exceeds the divergence limit" in failed["message"]
    assert failed["last_point_s"] < failed["time_s"] and f"t = {failed['time_s']!r} s" in lines[0]
    rows = np.genfromtxt(out / "timeseries.csv", delimiter=",", names=True)
    assert len(rows) > 1 and np.all(np.isfinite(rows.view((float, len(rows.dtype.names)))))
    assert rows["time"][-1] == failed["last_point_s"]


@pytest.fixture(scope="module")
def diverging_sweep(tmp_path_factory):
    return _clockwork(tmp_path_factory.mktemp("sweep"), sweep=True)


def test_sweep_with_a_diverging_point_records_the_failure(diverging_sweep):
    """The finished point is written, the failed one carries its error; no
    number of the failed point pretends to be a result."""
    proc, out = diverging_sweep
    summary = json.loads((out / "summary.json").read_text())
    assert summary["points_failed"] == 1
    failed = [p for p in summary["points"] if "error" in p]
    assert len(failed) == 1 and failed[0]["point"]["master.step"] == 1.28
    assert "exceeds the divergence limit" in failed[0]["error"]
    assert set(failed[0]) == {"point", "error", "failed"}
    assert failed[0]["failed"]["time_s"] > failed[0]["failed"]["last_point_s"]
    rows = np.genfromtxt(out / "sweep.csv", delimiter=",", names=True)
    bad = rows[rows["masterstep"] == 1.28]
    assert len(bad) == 1 and not any(math.isfinite(bad[0][n]) for n in rows.dtype.names[1:])


def test_sweep_with_a_diverging_point_is_not_silent(diverging_sweep):
    proc, out = diverging_sweep
    assert proc.returncode != 0 or "diverg" in proc.stderr or "failed" in proc.stderr, (proc.returncode, proc.stderr)
