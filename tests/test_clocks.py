"""FMI 3.0 clocks: Co-Simulation in Event Mode and Scheduled Execution.

The FMUs are tests/data/fmi3/clocked.c (CMake builds them, tests/CMakeLists.txt;
descriptions in tests/fmi3_clocked.py); each refuses a wrong call sequence or a tick at a wrong time, so a
run that ends at all had its ticks where they belong. Ticker has an output
clock ticking every `period` s; Counter a triggered input clock that adds
its clocked input to its clocked count; Sampler a constant clock (0.1 s,
shift 0.05 s), a countdown clock set at the third sample and a changing
clock; Partitions is Scheduled Execution with two periodic partitions of
different priority, an output clock and a countdown clock set through
clockUpdate. Each runs on both engines, and the two give the same bits
(test_both_engines_give_the_same_bits).
"""

from __future__ import annotations

import math

import pytest

from clockwork.engine import MasterSettings, System
from clockwork.engine.samples import Samples, Signal
from clockwork.errors import SceneError, UsageError
from cwtest import test_fmu


@pytest.fixture(scope="module")
def fmus():
    return {n: str(test_fmu(f"fmi3/{n}")) for n in ("Ticker", "EarlyTicker", "Counter", "Sampler", "Partitions")}


def close(a, b):
    return len(a) == len(b) and all(math.isclose(x, y, rel_tol=1e-12, abs_tol=1e-12) for x, y in zip(a, b))


ENGINES = ["python", "compiled"]


@pytest.fixture(params=ENGINES)
def engine(request):
    return request.param


@pytest.mark.parametrize("step", [0.1, 0.25, 0.03])
def test_output_clock_drives_a_counter(fmus, step, engine):
    """Ticker's output clock ticks Counter's input clock in the same event;
    the clocked n reaches the clocked step_by at each tick only."""
    with System({"tk": (fmus["Ticker"], {}), "ct": (fmus["Counter"], {})},
                ["tk.tick -> ct.tooth", "tk.n -> ct.step_by"], MasterSettings(step=step, engine=engine)) as s:
        m = s.master
        m.run_until(1.0)
        times = [0.1 * k for k in range(1, 11)]
        assert close(m.clock_ticks["tk.tick"], times)
        assert close(m.clock_ticks["ct.tooth"], times)
        assert [x for _, x in m.clocked_values["tk.n"]] == list(range(1, 11))
        assert [x for _, x in m.clocked_values["ct.count"]] == [k * (k + 1) // 2 for k in range(1, 11)]
        assert close([x for _, x in m.clocked_values["ct.last"]], times)
        # The unclocked total follows the count after each event.
        assert s.instances["ct"].get_values(["total"])[0] == 55


def test_a_tick_inside_a_step_reaches_the_clocks_at_its_end(fmus, engine):
    """An output clock the FMU does not announce (EarlyTicker: announce = 0)
    ticks inside a step, where the FMU returns early: its own record has the
    tick's time; the connected clock ticks at the communication point that
    ends the step, said once in a note."""
    with System({"tk": (fmus["EarlyTicker"], {"announce": 0}), "ct": (fmus["Counter"], {})},
                ["tk.tick -> ct.tooth"], MasterSettings(step=0.25, engine=engine)) as s:
        m = s.master
        m.run_until(1.0)
        assert close(m.clock_ticks["tk.tick"], [0.1 * k for k in range(1, 11)])
        assert close(m.clock_ticks["ct.tooth"], [0.25, 0.5, 0.75, 1.0])
        assert [x for _, x in m.clocked_values["ct.count"]] == [1, 2, 3, 4]
        # Two ticks inside the first step reach the counter as one, at its end.
        assert [n for n in m.notes if "tk.tick ticked inside a step at t = 0.1 s" in n and "t = 0.25 s" in n]


def test_periodic_countdown_and_changing_clocks(fmus, engine):
    with System({"sp": (fmus["Sampler"], {})}, [], MasterSettings(step=0.1, engine=engine)) as s:
        m = s.master
        m.run_until(1.0)
        assert close(m.clock_ticks["sp.sample"], [0.05 + 0.1 * k for k in range(10)])
        assert close(m.clock_ticks["sp.alarm"], [0.25 + 0.025])
        assert close([x for _, x in m.clocked_values["sp.alarm_time"]], [0.275])
        assert close(m.clock_ticks["sp.beat"], [0.0, 0.2, 0.5, 0.9])
        assert [x for _, x in m.clocked_values["sp.beats"]] == [1, 2, 3, 4]
        assert [x for _, x in m.clocked_values["sp.samples"]] == list(range(1, 11))


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
def test_scheduled_execution_partitions_by_priority(fmus, step, engine):
    with System({"se": (fmus["Partitions"], {})}, [], MasterSettings(step=step, engine=engine)) as s:
        m = s.master
        m.run_until(1.0)
        assert close(m.clock_ticks["se.fast"], [0.1 * k for k in range(11)])
        assert close(m.clock_ticks["se.slow"], [0.3 * k for k in range(4)])
        assert close(m.clock_ticks["se.every3"], [0.2, 0.5, 0.8])
        assert close(m.clock_ticks["se.later"], [0.25, 0.55, 0.85])
        assert [x for _, x in m.clocked_values["se.later_n"]] == [1, 2, 3]
        assert s.instances["se"].get_values(["order"])[0] == expected_order(1.0)


def test_scheduled_output_clock_drives_a_counter(fmus, engine):
    with System({"se": (fmus["Partitions"], {}), "ct": (fmus["Counter"], {})}, ["se.every3 -> ct.tooth"],
                MasterSettings(step=0.1, engine=engine)) as s:
        s.master.run_until(1.0)
        assert close(s.master.clock_ticks["ct.tooth"], [0.2, 0.5, 0.8])
        assert [x for _, x in s.master.clocked_values["ct.count"]] == [1, 2, 3]


def test_input_file_ticks_a_triggered_clock(fmus, engine):
    samples = Samples([0.0, 0.3, 0.35, 0.7, 0.9], [Signal("ct", "tooth", (0, 1, 0, 2, 0), False)])
    with System({"ct": (fmus["Counter"], {})}, [], MasterSettings(step=0.25, engine=engine), inputs=samples) as s:
        s.master.run_until(1.0)
        assert close(s.master.clock_ticks["ct.tooth"], [0.3, 0.7])
        assert close([x for _, x in s.master.clocked_values["ct.last"]], [0.3, 0.7])


def test_the_compiled_engine_runs_clocks(fmus):
    from clockwork.engine.clocks import ClockedMaster

    for engine in ("auto", "compiled"):
        with System({"sp": (fmus["Sampler"], {})}, [], MasterSettings(step=0.1, engine=engine)) as s:
            assert s.master.engine == "compiled" and isinstance(s.master, ClockedMaster)
            assert s.master.engine_reason is None
    # What the core does not do falls back as for any scene, clocks or not.
    with System({"sp": (fmus["Sampler"], {})}, [], MasterSettings(step=0.1, richardson=True)) as s:
        assert s.master.engine == "python" and "step doubling" in s.master.engine_reason


def _bits(m, rec):
    """Everything a run gives, exactly: the ticks, the clocked values, the
    communication points' series, the notes, the counts."""
    return (m.t, m.clock_ticks, {k: [(t, repr(x)) for t, x in v] for k, v in m.clocked_values.items()},
            {k: list(v) for k, v in rec.columns.items()}, [n for n in m.notes if not n.startswith("master.threads")],
            m.stats.steps, m.stats.events)


def _run(components, links, engine, stop, inputs=None, restart=None, **settings):
    from clockwork.engine.recording import Recorder

    with System(components, [], MasterSettings(engine="python")) as s:  # the unclocked Real outputs
        outputs = [(n, v) for n, inst in s.instances.items() for v, var in inst.variables.items()
                   if var.causality == "output" and var.type == "Real" and v not in inst.clock_table().clocked]
    record = {n: [v for i, v in outputs if i == n] for n in components}
    with System(components, links, MasterSettings(engine=engine, **settings), inputs=inputs, record=record) as s:
        m = s.master
        assert m.engine == engine
        rec = Recorder(m, outputs)
        rec.start()
        m.run_until(stop / 2, rec)
        if restart is not None:
            s.restart(restart)
            rec = Recorder(m, outputs)
            rec.start()
        m.run_until(stop, rec)
        return _bits(m, rec)


BOTH = {
    "ticker-counter": (lambda f: ({"tk": (f["Ticker"], {}), "ct": (f["Counter"], {})},
                                  ["tk.tick -> ct.tooth", "tk.n -> ct.step_by"]), {"step": 0.03}),
    "early-return": (lambda f: ({"tk": (f["EarlyTicker"], {"announce": 0}), "ct": (f["Counter"], {})},
                                ["tk.tick -> ct.tooth"]), {"step": 0.25}),
    "threads": (lambda f: ({"tk": (f["EarlyTicker"], {"announce": 0}), "ct": (f["Counter"], {}),
                            "sp": (f["Sampler"], {})}, ["tk.tick -> ct.tooth", "tk.n -> ct.step_by"]),
                {"step": 0.07, "threads": 2}),
    "sampler": (lambda f: ({"sp": (f["Sampler"], {})}, []), {"step": 0.07}),
    "partitions": (lambda f: ({"se": (f["Partitions"], {})}, []), {"step": 0.07}),
    "partitions-counter": (lambda f: ({"se": (f["Partitions"], {}), "ct": (f["Counter"], {})},
                                      ["se.every3 -> ct.tooth"]), {"step": 0.1}),
    "restart": (lambda f: ({"tk": (f["Ticker"], {}), "ct": (f["Counter"], {}), "se": (f["Partitions"], {})},
                           ["tk.tick -> ct.tooth", "tk.n -> ct.step_by"]), {"step": 0.1}),
}


@pytest.mark.parametrize("scene", list(BOTH))
def test_both_engines_give_the_same_bits(fmus, scene):
    make, settings = BOTH[scene]
    components, links = make(fmus)
    restart = {"tk": {"period": 0.25}} if scene == "restart" else None
    python = _run(components, links, "python", 1.0, restart=restart, **settings)
    assert python == _run(components, links, "compiled", 1.0, restart=restart, **settings)
    assert python[1] and any(python[1].values())  # clocks ticked


@pytest.mark.parametrize("engine", ENGINES)
def test_an_error_in_an_event_inside_a_step_is_raised_as_on_python(fmus, engine):
    """The handler of an event an FMU signals inside its step runs under the
    core's fmi3DoStep (a callback): its error reaches the caller as such."""
    from clockwork.errors import SimulationError

    with System({"tk": (fmus["EarlyTicker"], {"announce": 0}), "ct": (fmus["Counter"], {})},
                ["tk.tick -> ct.tooth"], MasterSettings(step=0.25, engine=engine)) as s:
        m = s.master
        assert m.engine == engine
        read = m._read_clocked_outputs

        def failing(n, clocks, t):
            if t > 0.5:
                raise SimulationError(f"{n}: refused at t = {t!r} s", time=t, instance=n)
            read(n, clocks, t)

        m._read_clocked_outputs = failing
        with pytest.raises(SimulationError, match=r"tk: refused at t = 0\.6"):
            m.run_until(1.0)
        assert close(m.clock_ticks["ct.tooth"], [0.25, 0.5])


def test_a_run_to_marks_ticks_the_clocks_on_both_engines(fmus):
    """run_marks with clocks (the compiled engine loops in Python over the core's steps)."""
    from clockwork.engine import Marks

    runs = []
    for engine in ENGINES:
        with System({"tk": (fmus["Ticker"], {}), "ct": (fmus["Counter"], {})},
                    ["tk.tick -> ct.tooth", "tk.n -> ct.step_by"], MasterSettings(step=0.07, engine=engine),
                    record={"ct": ["total"]}) as s:
            port = s.master.ports["ct"]
            total = (port, port.out_names.index("total"))
            marks = Marks([0.33, 0.61], outputs=[total], watched=[total], max_step=0.07)
            s.master.run_marks(1.0, marks)
            runs.append((marks.rows, s.master.clock_ticks, s.master.t))
    assert runs[0] == runs[1]
    assert close(runs[0][1]["ct.tooth"], [0.1 * k for k in range(1, 11)]) and runs[0][0][-1][1] == 55


def test_both_engines_tick_from_an_input_file_alike(fmus):
    samples = Samples([0.0, 0.3, 0.35, 0.7, 0.9], [Signal("ct", "tooth", (0, 1, 0, 2, 0), False)])
    runs = [_run({"ct": (fmus["Counter"], {})}, [], e, 1.0, inputs=samples, step=0.25) for e in ENGINES]
    assert runs[0] == runs[1] and close(runs[0][1]["ct.tooth"], [0.3, 0.7])


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


def cli(*args, cwd=None):
    import os
    import subprocess
    import sys

    return subprocess.run([sys.executable, "-m", "clockwork", *args], capture_output=True, text=True, cwd=cwd,
                          env={**os.environ, "CLOCKWORK_CACHE": "off"})


def scene_file(tmp_path, fmus, extra=""):
    path = tmp_path / "s.toml"
    path.write_text('connections = ["tk.tick -> ct.tooth", "tk.n -> ct.step_by"]\n[scene]\ntitle = "t"\n'
                    f'[components.tk]\nfmu = "{fmus["Ticker"]}"\n[components.ct]\nfmu = "{fmus["Counter"]}"\n'
                    f'[experiment]\nstop = 1\n[master]\nstep = 0.25\n{extra}')
    return path


def test_validate_and_info_list_the_clocks(fmus, tmp_path):
    p = cli("validate", str(scene_file(tmp_path, fmus)))
    assert p.returncode == 0, p.stderr
    assert "tk.tick (output, triggered)" in p.stdout and "ticks ct.tooth" in p.stdout
    assert "ct.tooth (input, triggered)" in p.stdout and "ticked here by tk.tick" in p.stdout
    p = cli("info", fmus["Partitions"])
    assert p.returncode == 0, p.stderr
    assert "clocks (Scheduled Execution" in p.stdout
    assert "fast (input, constant, priority 1): every 0.1 s from the start + 0 s" in p.stdout
    assert "later (input, countdown, priority 3)" in p.stdout


@pytest.mark.parametrize("engine", ENGINES)
def test_run_writes_the_ticks_and_the_clocked_values(fmus, tmp_path, engine):
    import json

    out = tmp_path / "out"
    p = cli("run", str(scene_file(tmp_path, fmus, f'engine = "{engine}"\n')), "--out", str(out), "--no-progress")
    assert p.returncode == 0, p.stderr
    summary = json.loads((out / "summary.json").read_text())
    r = summary["result"]
    assert r["engine"] == engine and not r.get("engine_reason")
    assert close(r["clock_ticks"]["ct.tooth"], [0.1 * k for k in range(1, 11)])
    assert r["clocked"]["ct.count"]["value"] == [k * (k + 1) // 2 for k in range(1, 11)]
    # The communication points' series has no clock and no clocked variable; total follows the count.
    rows = (out / "timeseries.csv").read_text().splitlines()
    assert rows[0] == "time,tk.x,ct.total" and rows[-1] == "1.0,1.0,55.0"


def test_a_clocked_variable_is_not_a_column(fmus, tmp_path):
    p = cli("validate", str(scene_file(tmp_path, fmus, '[record]\noutputs = ["ct.count"]\n')))
    assert p.returncode == 2
    assert len(p.stderr.splitlines()) == 1 and "record.outputs[0]: ct.count is clocked" in p.stderr


def test_an_input_file_ticks_the_fmu_alone(fmus, tmp_path):
    import json

    (tmp_path / "in.csv").write_text("time,tooth\n0,0\n0.3,1\n0.35,0\n0.7,1\n0.9,0\n")
    out = tmp_path / "out"
    p = cli("run", fmus["Counter"], "--input", str(tmp_path / "in.csv"), "--out", str(out), "--no-progress")
    assert p.returncode == 0, p.stderr
    r = json.loads((out / "summary.json").read_text())["result"]
    assert close(r["clock_ticks"]["Counter.tooth"], [0.3, 0.7])
    assert r["clocked"]["Counter.count"]["value"] == [1, 2]


# -- the clock itself: the escapement's switch as an output clock ---------------

CLOCK_LINKS = ["pendulum.phi -> escapement.phi", "pendulum.w -> escapement.w",
               "escapement.tau -> pendulum.tau_escapement"]
PENDULUM = {"L": 1.0, "m": 1.0, "g": 9.81, "Q": 1000, "phi_start": math.radians(6), "rtol": 1e-11, "atol": 1e-13}
ESCAPEMENT = {"torque": 0.004, "phi_r": math.radians(2)}


def clock_run(escapement_fmu, extra=None, links=(), stop=20.0, engine="python"):
    """The core clock (scenarios/core_grasshopper.toml) on FMI 3.0 builds:
    the communication points where the escapement's mode changed, the
    pendulum's ticks (its own tick detection), the angle at every point."""
    from clockwork.engine.recording import Recorder
    from cwtest import FMU_DIR

    components = {"pendulum": (str(FMU_DIR / "fmi3" / "Pendulum.fmu"), PENDULUM),
                  "escapement": (str(escapement_fmu), ESCAPEMENT), **(extra or {})}
    settings = MasterSettings(step=0.01, event_location=True, engine=engine)
    with System(components, CLOCK_LINKS + list(links), settings,
                record={"escapement": ["mode"], "pendulum": ["phi", "tick_time"]}) as s:
        rec = Recorder(s.master, [("escapement", "mode"), ("pendulum", "phi")], ticks_of="pendulum")
        rec.start()
        s.master.run_until(stop, rec)
        t, mode, phi = rec.columns["time"], rec.columns["escapement.mode"], rec.columns["pendulum.phi"]
        switches = [t[k] for k in range(1, len(t)) if mode[k] != mode[k - 1]]
        return s.master, switches, list(rec.ticks), dict(zip(t, phi)), list(phi)


def test_the_escapements_switch_ticks_a_going_train(fmus, engine):
    """TestClockedEscapement (the GrasshopperEscapement's own code with its
    switch as the output clock escape) drives the counter: each tick is a
    switch the master located on the escapement's indicator, at the same
    time, to the bit, as the switches of the bundled escapement without
    clocks; two per period of the pendulum's own ticks."""
    from cwtest import FMU_DIR, test_fmu

    master, switches, ticks, _, _ = clock_run(FMU_DIR / "fmi3" / "GrasshopperEscapement.fmu", engine=engine)
    clocked, clocked_switches, clocked_ticks, phi, _ = clock_run(
        test_fmu("fmi3/TestClockedEscapement"), {"train": (fmus["Counter"], {})}, ["escapement.escape -> train.tooth"],
        engine=engine)
    escapes = clocked.clock_ticks["escapement.escape"]
    assert len(switches) >= 18  # two a period of about 2 s
    assert escapes == switches == clocked_switches  # the same times, to the bit
    assert clocked_ticks == ticks  # the pendulum runs as without the clock
    assert clocked.clock_ticks["train.tooth"] == escapes
    assert [x for _, x in clocked.clocked_values["train.count"]] == list(range(1, len(escapes) + 1))
    # Each switch lies just past phi = +-phi_r (located to the event tolerance), two per period.
    phi_r = ESCAPEMENT["phi_r"]
    assert all(abs(abs(phi[t]) - phi_r) < 1e-6 for t in escapes)
    for a, b in zip(ticks, ticks[1:]):
        assert sum(a < t <= b for t in escapes) == 2


def test_the_clocked_clock_gives_the_same_bits_on_both_engines(fmus):
    from cwtest import test_fmu

    runs = []
    for engine in ENGINES:
        m, switches, ticks, _, phi = clock_run(test_fmu("fmi3/TestClockedEscapement"), {"train": (fmus["Counter"], {})},
                                               ["escapement.escape -> train.tooth"], stop=6.0, engine=engine)
        assert m.engine == engine
        runs.append((switches, ticks, phi, m.clock_ticks, m.clocked_values, m.stats.steps, m.stats.events))
    assert runs[0] == runs[1] and runs[0][3]["train.tooth"]


def test_an_ssp_connects_clock_connectors(fmus, tmp_path):
    """SSP 2.0's ssc:Clock connectors: the clock connection of an SSD runs as a scene's."""
    import json
    import shutil

    res = tmp_path / "resources"
    res.mkdir()
    shutil.copy(fmus["Ticker"], res / "Ticker.fmu")
    shutil.copy(fmus["Counter"], res / "Counter.fmu")
    ssd = tmp_path / "SystemStructure.ssd"
    ssd.write_text("""<?xml version="1.0" encoding="UTF-8"?>
<ssd:SystemStructureDescription version="2.0" name="clocked"
    xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription"
    xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon">
  <ssd:System name="root">
    <ssd:Elements>
      <ssd:Component name="tk" source="resources/Ticker.fmu">
        <ssd:Connectors><ssd:Connector name="tick" kind="output"><ssc:Clock/></ssd:Connector></ssd:Connectors>
      </ssd:Component>
      <ssd:Component name="ct" source="resources/Counter.fmu">
        <ssd:Connectors><ssd:Connector name="tooth" kind="input"><ssc:Clock/></ssd:Connector></ssd:Connectors>
      </ssd:Component>
    </ssd:Elements>
    <ssd:Connections>
      <ssd:Connection startElement="tk" startConnector="tick" endElement="ct" endConnector="tooth"/>
    </ssd:Connections>
  </ssd:System>
  <ssd:DefaultExperiment startTime="0" stopTime="0.5"/>
</ssd:SystemStructureDescription>
""")
    out = tmp_path / "out"
    p = cli("run", str(ssd), "--out", str(out), "--no-progress", "--set", "master.step=0.1")
    assert p.returncode == 0, p.stderr
    r = json.loads((out / "summary.json").read_text())["result"]
    assert close(r["clock_ticks"]["ct.tooth"], [0.1, 0.2, 0.3, 0.4, 0.5])
    assert r["clocked"]["ct.count"]["value"] == [1, 2, 3, 4, 5]


def test_a_restart_starts_the_clocks_again(fmus, engine):
    """System.restart (a sweep's next point on the same instances): the
    schedule and the records start again, from the new parameters."""
    with System({"tk": (fmus["Ticker"], {}), "ct": (fmus["Counter"], {}), "se": (fmus["Partitions"], {})},
                ["tk.tick -> ct.tooth", "tk.n -> ct.step_by"], MasterSettings(step=0.1, engine=engine)) as s:
        s.master.run_until(0.5)
        s.restart({"tk": {"period": 0.25}})
        s.master.run_until(1.0)
        assert close(s.master.clock_ticks["ct.tooth"], [0.25, 0.5, 0.75, 1.0])
        assert [x for _, x in s.master.clocked_values["ct.count"]] == [1, 3, 6, 10]
        assert close(s.master.clock_ticks["se.slow"], [0.0, 0.3, 0.6, 0.9])


def _description_only(tmp_path, name, clocks, cs='<CoSimulation modelIdentifier="M" hasEventMode="true"/>'):
    import zipfile

    xml = f"""<?xml version="1.0"?>
<fmiModelDescription fmiVersion="3.0" modelName="{name}" instantiationToken="x">
  {cs}
  <ModelVariables>{clocks}</ModelVariables>
  <ModelStructure/>
</fmiModelDescription>"""
    path = tmp_path / f"{name}.fmu"
    with zipfile.ZipFile(path, "w") as z:
        z.writestr("modelDescription.xml", xml)
    return path


@pytest.mark.parametrize("clock, needle", [
    ('<Clock name="c" valueReference="1" causality="input" intervalVariability="constant" intervalDecimal="fast"/>',
     "Clock c: intervalDecimal='fast': expected a number"),
    ('<Clock name="c" valueReference="1" causality="input" intervalVariability="constant" intervalDecimal="0"/>',
     "clock c: a constant clock needs intervalDecimal > 0"),
    ('<Clock name="c" valueReference="1" causality="input" intervalVariability="constant" intervalDecimal="1" '
     'shiftDecimal="1_0"/>', "Clock c: shiftDecimal='1_0': expected a number"),
    ('<Clock name="c" valueReference="1" causality="input" intervalVariability="triggered" priority="-1"/>',
     "Clock c: priority='-1': expected a whole number >= 0"),
    ('<Clock name="c" valueReference="1" causality="local" intervalVariability="triggered"/>',
     "clock c: expected causality input or output, found local"),
])
def test_a_bad_clock_is_refused_in_one_line(tmp_path, clock, needle):
    from clockwork.fmi.description import FmuError, read_fmu

    path = _description_only(tmp_path, "Bad", clock)
    with pytest.raises(FmuError, match="Bad"):
        read_fmu(path, need_binary=False)
    p = cli("info", str(path))
    assert p.returncode == 2 and len(p.stderr.splitlines()) == 1 and needle in p.stderr, p.stderr


def test_validate_says_a_triggered_clock_never_ticks(fmus, tmp_path):
    scene = tmp_path / "s.toml"
    scene.write_text(f'[scene]\ntitle = "t"\n[components.ct]\nfmu = "{fmus["Counter"]}"\n[experiment]\nstop = 1\n')
    p = cli("validate", str(scene))
    assert p.returncode == 0 and "ct.tooth" in p.stdout and "ticked here by nothing: it never ticks" in p.stdout


def test_export_ssp_keeps_the_clock_connections(fmus, tmp_path):
    import json

    ssp = tmp_path / "s.ssp"
    p = cli("export-ssp", str(scene_file(tmp_path, fmus)), "--out", str(ssp))
    assert p.returncode == 0, p.stderr
    out = tmp_path / "out"
    p = cli("run", str(ssp), "--out", str(out), "--no-progress")
    assert p.returncode == 0, p.stderr
    r = json.loads((out / "summary.json").read_text())["result"]
    assert r["clocked"]["ct.count"]["value"] == [k * (k + 1) // 2 for k in range(1, 11)]
