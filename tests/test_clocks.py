"""FMI 3.0 clocks: Co-Simulation in Event Mode and Scheduled Execution.

The FMUs are tests/data/fmi3/clocked.c (tests/fmi3_clocked.py builds
them); each refuses a wrong call sequence or a tick at a wrong time, so a
run that ends at all had its ticks where they belong. Ticker has an output
clock ticking every `period` s; Counter a triggered input clock that adds
its clocked input to its clocked count; Sampler a constant clock (0.1 s,
shift 0.05 s), a countdown clock set at the third sample and a changing
clock; Partitions is Scheduled Execution with two periodic partitions of
different priority, an output clock and a countdown clock set through
clockUpdate.
"""

from __future__ import annotations

import math

import pytest

from clockwork.engine import MasterSettings, System
from clockwork.engine.samples import Samples, Signal
from clockwork.errors import SceneError, UsageError
import fmi3_clocked


@pytest.fixture(scope="module")
def fmus(tmp_path_factory):
    d = tmp_path_factory.mktemp("clocked")
    return {n: str(fmi3_clocked.build(d, n)) for n in ("Ticker", "Counter", "Sampler", "Partitions")}


def close(a, b):
    return len(a) == len(b) and all(math.isclose(x, y, rel_tol=1e-12, abs_tol=1e-12) for x, y in zip(a, b))


@pytest.mark.parametrize("step", [0.1, 0.25, 0.03])
def test_output_clock_drives_a_counter(fmus, step):
    """Ticker's output clock ticks Counter's input clock in the same event;
    the clocked n reaches the clocked step_by at each tick only."""
    with System({"tk": (fmus["Ticker"], {}), "ct": (fmus["Counter"], {})},
                ["tk.tick -> ct.tooth", "tk.n -> ct.step_by"], MasterSettings(step=step)) as s:
        m = s.master
        m.run_until(1.0)
        times = [0.1 * k for k in range(1, 11)]
        assert close(m.ticks["tk.tick"], times)
        assert close(m.ticks["ct.tooth"], times)
        assert [x for _, x in m.clocked["tk.n"]] == list(range(1, 11))
        assert [x for _, x in m.clocked["ct.count"]] == [k * (k + 1) // 2 for k in range(1, 11)]
        assert close([x for _, x in m.clocked["ct.last"]], times)
        # The unclocked total follows the count after each event.
        assert s.instances["ct"].get_values(["total"])[0] == 55


def test_periodic_countdown_and_changing_clocks(fmus):
    with System({"sp": (fmus["Sampler"], {})}, [], MasterSettings(step=0.1)) as s:
        m = s.master
        m.run_until(1.0)
        assert close(m.ticks["sp.sample"], [0.05 + 0.1 * k for k in range(10)])
        assert close(m.ticks["sp.alarm"], [0.25 + 0.025])
        assert close([x for _, x in m.clocked["sp.alarm_time"]], [0.275])
        assert close(m.ticks["sp.beat"], [0.0, 0.2, 0.5, 0.9])
        assert [x for _, x in m.clocked["sp.beats"]] == [1, 2, 3, 4]
        assert [x for _, x in m.clocked["sp.samples"]] == list(range(1, 11))


def expected_order(stop):
    """The activation sequence of Partitions with priorities obeyed (fast 1, slow 2, later 3)."""
    ticks = []
    for k in range(int(stop / 0.1 + 1e-9) + 1):
        ticks.append((round(0.1 * k, 9), 1, 1))
        if (k + 1) % 3 == 0:
            ticks.append((round(0.1 * k + 0.05, 9), 3, 3))
    for k in range(int(stop / 0.3 + 1e-9) + 1):
        ticks.append((round(0.3 * k, 9), 2, 2))
    order = 0
    for _, _, p in sorted(ticks):
        order = (order * 10 + p) % 100000000
    return order


@pytest.mark.parametrize("step", [0.1, 0.07])
def test_scheduled_execution_partitions_by_priority(fmus, step):
    with System({"se": (fmus["Partitions"], {})}, [], MasterSettings(step=step)) as s:
        m = s.master
        m.run_until(1.0)
        assert close(m.ticks["se.fast"], [0.1 * k for k in range(11)])
        assert close(m.ticks["se.slow"], [0.3 * k for k in range(4)])
        assert close(m.ticks["se.every3"], [0.2, 0.5, 0.8])
        assert close(m.ticks["se.later"], [0.25, 0.55, 0.85])
        assert [x for _, x in m.clocked["se.later_n"]] == [1, 2, 3]
        assert s.instances["se"].get_values(["order"])[0] == expected_order(1.0)


def test_scheduled_output_clock_drives_a_counter(fmus):
    with System({"se": (fmus["Partitions"], {}), "ct": (fmus["Counter"], {})}, ["se.every3 -> ct.tooth"],
                MasterSettings(step=0.1)) as s:
        s.master.run_until(1.0)
        assert close(s.master.ticks["ct.tooth"], [0.2, 0.5, 0.8])
        assert [x for _, x in s.master.clocked["ct.count"]] == [1, 2, 3]


def test_input_file_ticks_a_triggered_clock(fmus):
    samples = Samples([0.0, 0.3, 0.35, 0.7, 0.9], [Signal("ct", "tooth", (0, 1, 0, 2, 0), False)])
    with System({"ct": (fmus["Counter"], {})}, [], MasterSettings(step=0.25), inputs=samples) as s:
        s.master.run_until(1.0)
        assert close(s.master.ticks["ct.tooth"], [0.3, 0.7])
        assert close([x for _, x in s.master.clocked["ct.last"]], [0.3, 0.7])


def test_the_compiled_engine_hands_clocks_to_python(fmus):
    with System({"sp": (fmus["Sampler"], {})}, [], MasterSettings(step=0.1, engine="auto")) as s:
        assert s.master.engine == "python"
        assert "does not run FMI 3.0 clocks" in s.master.engine_reason
    with pytest.raises(SceneError, match="does not run FMI 3.0 clocks"):
        System({"sp": (fmus["Sampler"], {})}, [], MasterSettings(step=0.1, engine="compiled"))


def test_a_scene_without_clocks_keeps_the_plain_master(fmus):
    from clockwork.engine.clocks import ClockedMaster
    from cwtest import FMU_DIR

    with System({"p": (str(FMU_DIR / "Pendulum.fmu"), {})}, [], MasterSettings(step=0.01, engine="python")) as s:
        assert not isinstance(s.master, ClockedMaster)


@pytest.mark.parametrize("link, message", [
    ("tk.tick -> sp.sample", "ticks a triggered input clock only"),
    ("tk.x -> ct.tooth", "a clock connects to a clock only"),
])
def test_bad_clock_connections(fmus, link, message):
    with pytest.raises(SceneError, match=message):
        System({"tk": (fmus["Ticker"], {}), "ct": (fmus["Counter"], {}), "sp": (fmus["Sampler"], {})}, [link],
               MasterSettings(step=0.1))


def test_an_input_file_column_ticks_only_a_triggered_clock(fmus):
    samples = Samples([0.0, 0.5], [Signal("sp", "sample", (0, 1), False)])
    with pytest.raises(UsageError, match="ticks a triggered input clock"):
        System({"sp": (fmus["Sampler"], {})}, [], MasterSettings(step=0.1), inputs=samples)
