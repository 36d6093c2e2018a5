"""The compiled stepping core against the Python master: the same bits.

master.engine = "compiled" runs the stepping loop in C (src_c/master/,
cw_step.c and its parts); "python" is the reference loop. Where the algorithm is the
same, every output, every statistic and every located event agree bit for
bit: on the core scenes, on located events with replays and hidden
crossings, on input extrapolation, on Jacobi and Gauss-Seidel, on shooting
(reinitialization) and on the tick-point loop of Hoyng's long run.
"""

from __future__ import annotations

import json
import math
import threading

import pytest

from clockwork.engine import MasterSettings, System
from clockwork.engine import compiled
from clockwork.engine.compiled import CompiledMaster
from clockwork.engine.marks import Marks
from clockwork.engine.master import Master
from clockwork.engine.recording import Recorder
from clockwork.errors import SceneError, SimulationError
from cwtest import assert_one_line_error, run_cli, test_fmu

CLOCK = {"pendulum": ("Pendulum", dict(Q=1000.0, phi_start=math.radians(6))),
         "escapement": ("GrasshopperEscapement", dict(torque=4e-3, phi_r=math.radians(2))),
         "drag": ("Drag", dict(c1=2e-5, c2=2e-4))}
LINKS = ["pendulum.phi -> escapement.phi", "pendulum.w -> escapement.w",
         "escapement.tau -> pendulum.tau_escapement", "pendulum.w -> drag.w", "drag.tau -> pendulum.tau_drag"]


def _pair(components, links, **settings):
    """The same system on both engines."""
    out = {}
    for engine in ("python", "compiled"):
        out[engine] = System(components, links, MasterSettings(engine=engine, **settings),
                             record={"pendulum": ["tick_time", "amplitude"]})
    assert type(out["python"].master) is Master
    assert type(out["compiled"].master) is CompiledMaster
    return out["python"], out["compiled"]


def _same_state(p, c):
    mp, mc = p.master, c.master
    assert mp.t == mc.t
    assert list(mp.ports.buffer) == list(mc.ports.buffer)
    assert mp.stats == mc.stats


@pytest.mark.parametrize("settings", [
    dict(step=0.01),
    dict(step=0.01, order="jacobi"),
    dict(step=0.013, extrapolation=1),
    dict(step=0.02, extrapolation=2),
    dict(step=0.02, extrapolation=2, order="jacobi"),
    dict(step=0.05, event_location=False),
    dict(step=0.1),  # long steps: hidden crossings, replays, the sources' step cap
    dict(step=0.03, event_time_tolerance=1e-6, event_indicator_tolerance=1e-8),
    dict(step=0.01, iterations=2),  # strong coupling
    dict(step=0.02, iterations=1, order="jacobi", event_prediction=False),
])
def test_every_step_is_the_same_bits(settings):
    p, c = _pair(CLOCK, LINKS, **settings)
    with p, c:
        _same_state(p, c)
        for k in range(400):
            h = settings["step"] * (1.0 if k % 7 else 0.37)  # off-grid steps too
            assert p.master.step(h) == c.master.step(h)
            _same_state(p, c)
        st = c.master.stats
        if settings.get("event_location", True):
            assert st.events > 0 and (st.predicted_landings > 0) == settings.get("event_prediction", True)
        assert (st.coupling_iterations > 0) == ("iterations" in settings)


@pytest.mark.parametrize("derivative_error", [0.0, 0.3])
def test_predicted_landings_and_missed_predictions_are_the_same_bits(derivative_error):
    # Exact derivatives: every switch landed on by prediction; 30 % wrong
    # ones: predictions miss, and the miss is replayed and located.
    comps = {"osc": (str(test_fmu("TestOscillator")), dict(amplitude=0.1, omega=3.0,
                                                          derivative_error=derivative_error)),
             "escapement": ("GrasshopperEscapement", dict(torque=1e-3, phi_r=0.05))}
    out = {}
    for engine in ("python", "compiled"):
        out[engine] = System(comps, ["osc.x -> escapement.phi", "osc.v -> escapement.w"],
                             MasterSettings(step=0.3, engine=engine))
    p, c = out["python"], out["compiled"]
    with p, c:
        for k in range(150):
            assert p.master.step(0.3) == c.master.step(0.3)
            _same_state(p, c)
        st = c.master.stats
        if derivative_error:
            assert st.mispredicted > 5 and st.replays > 5
        else:
            assert st.predicted_landings == st.events > 10 and st.rollbacks == 0


def test_replays_and_hidden_crossings_are_exercised_and_agree():
    # A long step over a fast swing: the step cap, hidden crossings and replays all happen.
    comps = {"pendulum": ("Pendulum", dict(L=0.05, Q=200.0, phi_start=math.radians(8))),
             "escapement": ("GrasshopperEscapement", dict(torque=2e-3, phi_r=math.radians(1)))}
    p, c = _pair(comps, LINKS[:3], step=0.2)
    with p, c:
        p.master.run_until(20.0)
        c.master.run_until(20.0)
        _same_state(p, c)
        st = c.master.stats
        assert st.events > 20 and st.rollbacks > 0 and st.event_iterations > 0


def test_run_until_records_the_same_rows_and_ticks():
    p, c = _pair(CLOCK, LINKS, step=0.01)
    with p, c:
        recs = []
        for s in (p, c):
            r = Recorder(s.master, [("pendulum", "phi"), ("escapement", "tau"), ("pendulum", "amplitude")],
                         interval=0.05, ticks_of="pendulum")
            r.start()
            s.master.run_until(3.0, r)
            s.master.run_until(7.0, r)  # resumed: the grid counter and the last tick carry over
            recs.append(r)
        assert recs[0].columns == recs[1].columns
        assert recs[0].ticks == recs[1].ticks and len(recs[0].ticks) >= 3
        assert len(recs[1].columns["time"]) == round(7.0 / 0.05) + 1
        _same_state(p, c)


def test_a_long_recording_crosses_the_buffer_boundary(monkeypatch):
    monkeypatch.setattr(compiled, "ROWS_PER_CALL", 16)
    p, c = _pair(CLOCK, LINKS, step=0.01)
    with p, c:
        recs = []
        for s in (p, c):
            r = Recorder(s.master, [("pendulum", "phi")], ticks_of="pendulum")
            r.start()
            s.master.run_until(2.0, r)
            recs.append(r)
        assert recs[0].columns == recs[1].columns and len(recs[0].columns["time"]) > 200
        assert recs[0].ticks == recs[1].ticks


def test_a_run_cut_into_slices_gives_the_same_bits(monkeypatch):
    """The core returns to Python after each slice of wall time (so that
    signals are handled) and is called again where it stopped: with a slice
    of 0 s it returns every 16 steps, and the bits do not change."""
    monkeypatch.setattr(CompiledMaster, "slice_s", 0.0)
    lib = compiled.load_core()
    returns = []
    for name in ("cw_run_until", "cw_run_marks"):
        def counted(*args, _call=getattr(lib, name)):
            rc = _call(*args)
            returns.append(rc)
            return rc
        monkeypatch.setattr(lib, name, counted)
    p, c = _pair(CLOCK, LINKS, step=0.01)
    with p, c:
        got = []
        for s in (p, c):
            m = s.master
            r = Recorder(m, [("pendulum", "phi"), ("escapement", "tau")], interval=0.05, ticks_of="pendulum")
            r.start()
            m.run_until(2.0, r)
            m.run_until(3.0)  # nothing recorded
            port = m.ports["pendulum"]
            watched, remember = [(port, port.out_names.index("tick_time"))], [(port, port.out_names.index("phi"))]
            marks = Marks([5.5], watched=watched, before=remember, margin=2e-3, stop_at_change=True)
            trace = [m.run_marks(6.0, marks), marks.rows, m.t]
            got.append((r.columns, r.ticks, trace))
        assert got[0] == got[1] and len(got[0][0]["time"]) == round(2.0 / 0.05) + 1
        _same_state(p, c)
    assert returns.count(compiled._SLICE_OVER) >= 300 // 16, returns  # 300 steps to t = 3 s, then the watch
    assert returns[-2:] == [compiled._SLICE_OVER, compiled._WATCHED], returns  # the watch was sliced too


def _outputs(m, *names):
    port = m.ports["pendulum"]
    return [(port, port.out_names.index(n)) for n in names]


def test_run_marks_stopping_at_each_change_is_the_same_on_both_engines():
    p, c = _pair(CLOCK, LINKS, step=0.05)
    with p, c:
        got = []
        for s in (p, c):
            m = s.master
            trace = []
            mark = 0.7
            while m.t < 6.0 - 1e-9:
                marks = Marks([mark], watched=_outputs(m, "tick_time"), outputs=_outputs(m, "phi"),
                              before=_outputs(m, "phi", "w"), margin=2e-3, stop_at_change=True)
                stopped = m.run_marks(6.0, marks)
                trace.append((stopped, m.t, marks.rows))
                mark = m.t + 0.9
            got.append(trace)
        assert got[0] == got[1] and len(got[0]) > 3 and got[0][0][0] and len(got[0][0][2]) == 1
        _same_state(p, c)


def test_run_marks_following_ticks_is_the_same_on_both_engines():
    """Marks moved by the ticks they follow, rows in batches of 4 (batch
    boundaries inside the run), called in two chunks: the same points, rows
    and state on both engines, and each tick seen within two margins."""
    p, c = _pair(CLOCK, LINKS, step=0.05)
    with p, c:
        got = []
        for s in (p, c):
            m = s.master
            marks = Marks([0.9], watched=_outputs(m, "tick_time"), outputs=_outputs(m, "tick_time", "phi"),
                          before=_outputs(m, "w"), follow=(0, 1.0), margin=1e-3)
            marks.rows_per_call = 4
            batches = []
            assert m.run_marks(17.0, marks, batches.append) is False
            m.run_marks(40.0, marks, batches.append)
            assert max(len(b) for b in batches) <= 4
            got.append([r for b in batches for r in b])
        assert got[0] == got[1]
        rows = got[0]
        assert len(rows) > 15
        assert all(0 < t - tt < 2e-3 + 1e-9 for t, tt, *_ in rows[2:])  # once the period is known
        _same_state(p, c)


def test_run_marks_on_a_schedule_is_the_same_on_both_engines():
    """Exact marks (tolerance 0, one step each): an unconnected input set at
    some, the outputs read at the others, two marks at one time, a mark
    where the master stands; the same bits on both engines."""
    comps = {"pendulum": ("Pendulum", dict(Q=1000.0, phi_start=math.radians(6)))}
    p, c = _pair(comps, [], step=0.05)
    times = [0.0, 0.3, 0.3, 0.71, 1.2, 1.2 + 1e-13, 2.0]
    sets = [False, True, False, False, True, False, False]
    values = [0.0, 1e-3, 0.0, 0.0, -2e-3, 0.0, 0.0]
    with p, c:
        got = []
        for s in (p, c):
            m = s.master
            inputs = [(s.instances["pendulum"], s.instances["pendulum"].variables["tau_escapement"].vr)]
            marks = Marks(times, sets=sets, values=values, record_at_marks=True, inputs=inputs,
                          outputs=_outputs(m, "amplitude", "tick_time"), max_step=math.inf, tolerance=0.0)
            m.run_marks(1.2, marks)
            m.run_marks(2.0, marks)
            got.append((marks.rows, m.stats.steps))
        assert got[0] == got[1]
        assert [r[0] for r in got[0][0]] == [0.0, 0.3, 0.71, 1.2 + 1e-13, 2.0] and got[0][1] == 5
        _same_state(p, c)


def test_shooting_reinitializes_the_same_way():
    p, c = _pair(CLOCK, LINKS, step=0.01)
    with p, c:
        for s in (p, c):
            s.master.run_until(1.3)
            s.master.reinitialize(s.parameters)
            s.master.run_until(2.0)
        _same_state(p, c)


def test_a_discontinuity_restarts_the_same_way():
    p, c = _pair(CLOCK, LINKS, step=0.02, extrapolation=2)
    with p, c:
        for s in (p, c):
            s.master.run_until(1.0)
            s.instances["escapement"].set_values({"torque": 6e-3})
            s.master.discontinuity()
            s.master.run_until(2.5)
        _same_state(p, c)


def test_masters_in_threads_do_not_share_state():
    """Any number of compiled masters at once: no global state in the core."""
    def run(out, k):
        with System(CLOCK, LINKS, MasterSettings(step=0.01, engine="compiled")) as s:
            s.master.run_until(3.0)
            out[k] = list(s.master.ports.buffer)

    out = {}
    threads = [threading.Thread(target=run, args=(out, k)) for k in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    alone = {}
    run(alone, 0)
    assert all(v == alone[0] for v in out.values()) and len(out) == 4


def test_divergence_is_named_as_by_the_python_master():
    # A swing pumped by a strong escapement until its speed passes the limit
    # (the start is below it: an output past it at the start fails there,
    # before the compiled core runs): the output that passes it is named.
    comps = {"pendulum": ("Pendulum", dict(Q=1000.0, phi_start=math.radians(5))),
             "escapement": ("GrasshopperEscapement", dict(torque=1.0))}
    messages = []
    for engine in ("python", "compiled"):
        with System(comps, LINKS[:3], MasterSettings(step=0.01, engine=engine, divergence_limit=3.0)) as s:
            with pytest.raises(SimulationError) as e:
                s.master.run_until(1e4)
            messages.append(str(e.value))
            assert e.value.time > 1.0
    assert messages[0] == messages[1] and "divergence limit" in messages[0]


def test_an_fmu_failure_is_reported_as_by_the_python_master():
    # Duffing with kappa < 0 runs away inside the vibration FMU's step: fmi2DoStep discards it.
    from test_master import VIB

    comps = {"pendulum": ("Pendulum", dict(Q=1000.0, phi_start=math.radians(10))),
             "vibration": ("MechanismVibration", dict(VIB, kappa=-1e15, a2_start=0.1))}
    links = ["pendulum.phi -> vibration.a1", "vibration.tau -> pendulum.tau_coupling"]
    errors = []
    for engine in ("python", "compiled"):
        with System(comps, links, MasterSettings(step=0.5, event_location=False, engine=engine)) as s:
            with pytest.raises(SimulationError) as e:
                s.master.run_until(10.0)
            errors.append((str(e.value), e.value.instance, e.value.time))
    assert errors[0] == errors[1]
    assert errors[0][1] == "vibration" and "discarded" in errors[0][0]


def test_auto_falls_back_to_python_where_the_core_does_not_reach():
    with System(CLOCK, LINKS, MasterSettings(step=0.01, richardson=True)) as s:
        assert type(s.master) is Master
    for settings in (dict(), dict(iterations=2)):  # strong coupling runs in the core too
        with System(CLOCK, LINKS, MasterSettings(step=0.01, **settings)) as s:
            assert type(s.master) is CompiledMaster
    with pytest.raises(SceneError, match="master.engine = 'compiled'"):
        System(CLOCK, LINKS, MasterSettings(step=0.01, engine="compiled", richardson=True))


def test_a_missing_core_library(monkeypatch, tmp_path):
    monkeypatch.setattr(compiled, "_lib", None)
    monkeypatch.setattr(compiled, "_lib_error", None)
    monkeypatch.setattr(compiled, "core_library", lambda: tmp_path / "libcw_master.so")
    with System(CLOCK, LINKS, MasterSettings(step=0.01)) as s:
        assert type(s.master) is Master  # auto: the Python master
    with pytest.raises(SceneError, match="cannot be loaded"):
        System(CLOCK, LINKS, MasterSettings(step=0.01, engine="compiled"))


@pytest.mark.parametrize("value, needle", [
    ('"fast"', '"auto", "python" or "compiled"'),
    ("1", '"auto", "python" or "compiled"'),
    ("true", '"auto", "python" or "compiled"'),
])
def test_a_bad_engine_is_bad_input(capsys, tmp_path, value, needle):
    rc, _, err = run_cli(capsys, ["run", "core_grasshopper", "--out", tmp_path / "o",
                                  "--set", f"master.engine={value}"])
    assert_one_line_error(rc, err, "master.engine", needle)
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("settings, needle", [
    (["master.richardson=true"], "does not do step doubling"),
])
def test_compiled_where_the_core_does_not_reach_is_bad_input(capsys, tmp_path, settings, needle):
    sets = [a for s in ["master.engine=compiled", *settings] for a in ("--set", s)]
    rc, _, err = run_cli(capsys, ["run", "core_grasshopper", "--out", tmp_path / "o", *sets])
    assert_one_line_error(rc, err, "core_grasshopper.toml", "master.engine", needle)
    assert not (tmp_path / "o").exists()


def test_compiled_without_the_core_library_is_bad_input_and_auto_runs(capsys, tmp_path, monkeypatch):
    monkeypatch.setattr(compiled, "_lib", None)
    monkeypatch.setattr(compiled, "_lib_error", None)
    monkeypatch.setenv("CLOCKWORK_CORE_LIB", str(tmp_path / "missing" / "libcw_master.so"))
    monkeypatch.setenv("CLOCKWORK_CACHE", "off")
    rc, _, err = run_cli(capsys, ["run", "core_grasshopper", "--out", tmp_path / "o",
                                  "--set", "master.engine=compiled"])
    assert_one_line_error(rc, err, "core_grasshopper.toml", "master.engine", "cannot be loaded",
                          "tools/setup.sh")
    rc, _, err = run_cli(capsys, ["run", "core_grasshopper", "--out", tmp_path / "auto", "--no-progress"])
    assert rc == 0, err
    assert (tmp_path / "auto" / "timeseries.csv").is_file()


def _summary(path):
    """summary.json without what depends on the clock on the wall or the engine's name."""
    def strip(x):
        if isinstance(x, dict):
            return {k: strip(v) for k, v in x.items()
                    if not any(w in k for w in ("wall", "cpu", "per_s", "note", "overrides", "engine"))}
        if isinstance(x, list):
            return [strip(v) for v in x]
        return x
    data = json.loads(path.read_text())
    data["headlines"] = [h for h in data.get("headlines", []) if "time" not in h.get("quantity", "").lower()
                         and "cpu" not in h.get("quantity", "").lower()]
    return strip(data)


@pytest.mark.parametrize("scene, extra", [
    ("core_grasshopper", []),
    ("core_grasshopper_drag", []),
    ("core_vibration", []),
    ("ziemkiewicz_fig4a", []),
    ("hoyng_fig6", ["--set", "experiment.stop=3000", "--set", "escapement.noise_start=1000",
                    "--set", "analysis.sample_every=5"]),
])
def test_scenes_give_the_same_files_on_both_engines(capsys, tmp_path, monkeypatch, scene, extra):
    monkeypatch.setenv("CLOCKWORK_CACHE", "off")
    outs = {}
    for engine in ("python", "compiled"):
        out = tmp_path / engine
        rc, _, err = run_cli(capsys, ["run", scene, "--out", out, "--no-progress",
                                      "--set", f"master.engine={engine}", *extra])
        assert rc == 0, err
        outs[engine] = out
    csvs = sorted(p.name for p in outs["python"].glob("*.csv"))
    assert csvs == sorted(p.name for p in outs["compiled"].glob("*.csv"))
    for name in csvs:
        assert (outs["python"] / name).read_bytes() == (outs["compiled"] / name).read_bytes(), name
    assert _summary(outs["python"] / "summary.json") == _summary(outs["compiled"] / "summary.json")
