"""Systems of many FMUs: loading in linear time, and stepping on threads
(master.threads) with the bits of one thread.

Work is counted, not timed: the number of variable indexes built, of
lookups and of port updates as the system grows.
"""

from __future__ import annotations

import textwrap
import weakref
from pathlib import Path

import pytest
from fmpy import read_model_description

from clockwork.engine import MasterSettings, System
from clockwork.engine import parallel
from clockwork.fmi import description
from clockwork.engine.instances import make_instance
from clockwork.engine.ports import Port
from clockwork.engine.recording import Recorder
from clockwork.errors import SceneError, SimulationError
from clockwork.scene import load_scene
from cwtest import fmu_file, test_fmu

H = 0.125  # s


def _chain_scene(tmp_path, n: int) -> object:
    """A TestDecay feeding n - 1 TestSums in a row."""
    decay, total = test_fmu("TestDecay"), test_fmu("TestSum")
    lines = ['connections = [' + ", ".join(
        f'"{"d" if i == 1 else f"s{i - 1}"}.{"x" if i == 1 else "y"} -> s{i}.u1"' for i in range(1, n)) + "]",
        "[scene]", 'title = "chain"', "[experiment]", "stop = 1.0", "[master]", "step = 0.1",
        "[components.d]", f'fmu = "{decay}"']
    for i in range(1, n):
        lines += [f"[components.s{i}]", f'fmu = "{total}"']
    path = tmp_path / f"chain{n}.toml"
    path.write_text("\n".join(lines) + "\n")
    return path


class _Counting(weakref.WeakKeyDictionary):
    built = 0

    def __setitem__(self, key, value):
        type(self).built += 1
        super().__setitem__(key, value)


def test_the_variable_index_is_built_once_per_fmu_file(tmp_path, monkeypatch):
    monkeypatch.setattr(description, "_VARIABLES", _Counting())
    _Counting.built = 0
    scene = load_scene(_chain_scene(tmp_path, 60))
    assert _Counting.built == 2  # TestDecay and TestSum, not one per component or connection end
    md = scene.components["s1"].model_description
    assert description.variables(md) is description.variables(md)
    assert scene.components["s1"].model_description is scene.components["s59"].model_description


def _count_lookups(monkeypatch) -> dict:
    """Count every lookup of an FMU's variables (fmi.description.variables,
    under each name the loaders import it as): {"n": calls so far}."""
    calls = {"n": 0}
    real = description.variables

    def counted(md):
        calls["n"] += 1
        return real(md)

    monkeypatch.setattr("clockwork.fmi.description.variables", counted)
    for module in ("scene.load", "scene.checks", "scene.model", "scene.ssp.structure", "scene.ssp.flatten",
                   "scene.ssp.parameters", "scene.ssp.sections"):
        monkeypatch.setattr(f"clockwork.{module}.variables_of", counted)
    return calls


def _linear(work: dict) -> bool:
    """Work at 50, 100, 200 components that doubles (at most) with them."""
    return work[50] > 0 and work[200] <= 2.1 * work[100] and work[100] <= 2.1 * work[50]


def test_loading_does_work_linear_in_the_components(tmp_path, monkeypatch):
    """Lookups of an FMU's variables while a chain loads: proportional to
    its length (a map over all components per connection end made them
    grow with its square)."""
    calls = _count_lookups(monkeypatch)
    work = {}
    for n in (50, 100, 200):
        calls["n"] = 0
        load_scene(_chain_scene(tmp_path, n))
        work[n] = calls["n"]
    assert _linear(work), work


def test_reading_an_ssp_does_work_linear_in_the_components(tmp_path, monkeypatch):
    """The same for an SSP archive (the SSP reader, then the scene's load
    and checks): lookups of an FMU's variables proportional to the chain's
    length, one variable index per FMU file."""
    from clockwork.run.catalog import load_scene as load_any
    from clockwork.scene.ssp import export_ssp

    archives = {n: export_ssp(load_scene(_chain_scene(tmp_path, n)), tmp_path / f"chain{n}.ssp")
                for n in (50, 100, 200)}
    calls = _count_lookups(monkeypatch)
    monkeypatch.setattr(description, "_VARIABLES", _Counting())
    work = {}
    _Counting.built = 0
    for n, archive in archives.items():
        calls["n"] = 0
        scene = load_any(archive)
        assert len(scene.components) == n
        work[n] = calls["n"]
    assert _Counting.built == 2  # TestDecay and TestSum, whose descriptions the three archives share
    assert _linear(work), work


def test_instances_of_one_fmu_share_its_table_and_its_library():
    path = test_fmu("TestSum")
    a, b = make_instance("a", path), make_instance("b", path)
    try:
        a.instantiate()
        b.instantiate()
        assert a.variables is b.variables
        assert a._slave.dll is b._slave.dll
        assert a.component != b.component  # two instances all the same
        a.setup(0.0, {"k1": 2.0})
        b.setup(0.0, {})
        assert a.get_real(["k1"]) == [2.0] and b.get_real(["k1"]) == [1.0]
        assert b._slave.instanceName == "b"
        with pytest.raises(TypeError):
            a.variables["k1"] = None  # shared: read-only
    finally:
        a.free()
        b.free()


# -- stepping on threads ---------------------------------------------------------------------


def _clocks(k: int) -> tuple[dict, list[str]]:
    """k grasshopper clocks side by side (each pendulum dynamic, each escapement feedthrough-only)."""
    comps, links = {}, []
    for i in range(k):
        comps[f"p{i}"] = (str(fmu_file("Pendulum")), {"Q": 1000.0, "phi_start": 0.1 + 0.002 * i})
        comps[f"e{i}"] = (str(fmu_file("GrasshopperEscapement")), {"torque": 0.004, "phi_r": 0.035})
        links += [f"p{i}.phi -> e{i}.phi", f"p{i}.w -> e{i}.w", f"e{i}.tau -> p{i}.tau_escapement"]
    return comps, links


def _mixed() -> tuple[dict, list[str]]:
    """Dynamic instances that depend on each other through feedthrough-only
    ones (d0 -> t0 -> d2, d3 -> t3 -> d1), beside independent ones."""
    decay, total = str(test_fmu("TestDecay")), str(test_fmu("TestSum"))
    comps = {f"d{i}": (decay, {"k": 0.5 + 0.1 * i, "x0": 1.0 + i}) for i in range(6)}
    comps.update({"t0": (total, {"k1": 2.0}), "t3": (total, {"k1": -1.0}), "t5": (total, {})})
    links = ["d0.x -> t0.u1", "t0.y -> d2.v", "d3.x -> t3.u1", "t3.y -> d1.v", "d4.x -> d5.v", "d5.x -> t5.u1",
             "d1.x -> t5.u2"]
    return comps, links


def _loop_beside() -> tuple[dict, list[str]]:
    """An algebraic loop among feedthrough-only instances (add <-> gain), fed
    by one dynamic instance and feeding another, beside independent ones."""
    decay, total = str(test_fmu("TestDecay")), str(test_fmu("TestSum"))
    comps = {f"d{i}": (decay, {"k": 0.5 + 0.1 * i, "x0": 1.0 + i}) for i in range(4)}
    comps.update({"add": (total, {"c": 1.0}), "gain": (total, {"k1": 0.5, "k2": 0.0})})
    return comps, ["add.y -> gain.u1", "gain.y -> add.u2", "d0.x -> add.u1", "add.y -> d2.v"]


def _faces() -> tuple[dict, list[str]]:
    """Model Exchange instances (FMI 2.0 and 3.0, the core's solvers) beside
    FMI 1.0 and FMI 3.0 Co-Simulation ones, coupled in a row and side by side."""
    comps = {"b2": (str(test_fmu("MeBall")), {}), "b3": (str(test_fmu("fmi3/MeBall")), {}),
             "osc": (str(test_fmu("MeOscillator")), {}), "lag": (str(test_fmu("MeLag")), {}),
             "d1": (str(test_fmu("fmi1/TestDecay")), {"k": 0.3}), "d3": (str(test_fmu("fmi3/TestDecay")), {}),
             "s3": (str(test_fmu("fmi3/TestSum")), {"k1": 2.0})}
    return comps, ["osc.x -> lag.u", "lag.y -> d1.v", "b2.h -> s3.u1", "s3.y -> d3.v"]


def _lags() -> tuple[dict, list[str]]:
    """Dynamic instances whose outputs depend on their sampled inputs
    (MeLag's e = u - y), read after the step."""
    lag = str(test_fmu("MeLag"))
    return {f"l{i}": (lag, {"T": 0.2 + 0.1 * i}) for i in range(4)}, ["l0.y -> l3.u"]


def _lag_samples():
    from clockwork.engine.samples import Samples, Signal

    times = [0.0, 0.3, 0.6, 0.6, 1.0, 2.0]
    return Samples(times, [Signal(f"l{i}", "u", tuple((1 + i) * t * t for t in times), True) for i in range(3)])


SYSTEMS = {"clocks": lambda: _clocks(6), "mixed": _mixed, "loop": _loop_beside, "faces": _faces,
           "lags": _lags}


def _run(system: tuple[dict, list[str]], steps: int, inputs=None, **settings):
    comps, links = system
    # Model Exchange instances stepped alone, as the core schedules them (a
    # group of connected ones is one instance to the core: tests/test_me_group.py).
    settings.setdefault("me_groups", False)
    # Every Real output, connected or not (an unconnected one is read after the step too).
    record = {n: [v.name for v in read_model_description(path).modelVariables
                  if v.causality == "output" and v.type in ("Real", "Float64")] for n, (path, _) in comps.items()}
    with System(comps, links, MasterSettings(**settings), record=record, inputs=inputs) as s:
        m = s.master
        outputs = [(n, name) for n, names in record.items() for name in names]
        rec = Recorder(m, outputs)
        rec.start()
        m.run_until(steps * settings["step"], rec)
        assert len(rec.columns) == len(outputs) + 1 and len(rec.columns["time"]) >= steps + 1  # events add points
        return rec.columns, vars(m.stats), m.engine, list(m.notes)


@pytest.mark.parametrize("order", ["gauss-seidel", "jacobi"])
@pytest.mark.parametrize("system, step, steps", [("clocks", 0.01, 300), ("mixed", H, 40), ("loop", H, 24),
                                                 ("faces", 0.05, 40), ("faces-cvode", 0.05, 40),
                                                 ("lags", H, 24)])
def test_threads_give_the_bits_of_one_thread(system, step, steps, order):
    build = SYSTEMS[system.removesuffix("-cvode")]
    inputs = _lag_samples() if system == "lags" else None
    settings = {"step": step, "order": order, "me_solver": "cvode" if system.endswith("-cvode") else "auto"}
    one = _run(build(), steps, inputs, engine="compiled", **settings)
    assert one[2] == "compiled", one[3]
    for threads in (2, 3, 16):
        many = _run(build(), steps, inputs, engine="compiled", threads=threads, **settings)
        assert many[:3] == one[:3], threads
    python = _run(build(), steps, inputs, engine="python", threads=2, **settings)
    assert python[:2] == one[:2]
    assert any("master.threads = 2: the Python engine steps one instance at a time" in n for n in python[3])
    if system == "clocks":
        assert one[1]["events"] > 0 and one[1]["rollbacks"] > 0  # the threads stepped rollbacks and replays too


@pytest.mark.parametrize("order", ["gauss-seidel", "jacobi"])
def test_strong_coupling_with_threads_steps_one_after_the_other(order):
    """master.iterations on the compiled core with threads: each iterate
    sets the inputs from its own line, so the instances step one after the
    other there, with the bits of one thread and of the Python engine."""
    settings = {"step": H, "order": order, "iterations": 2}
    one = _run(_mixed(), 40, engine="compiled", **settings)
    assert one[2] == "compiled" and one[1]["coupling_iterations"] > 0
    assert _run(_mixed(), 40, engine="compiled", threads=2, **settings)[:3] == one[:3]
    assert _run(_mixed(), 40, engine="python", **settings)[:2] == one[:2]


def test_the_runs_that_step_at_once():
    comps, links = _mixed()
    with System(comps, links, MasterSettings(step=H, engine="python")) as s:
        ports = s.master.ports
        names = [p.inst.name for p in ports.dynamic]
        ends = parallel.group_ends(ports, jacobi=False)
        runs, a = [], 0
        while a < len(ends):
            runs.append(names[a:ends[a]])
            a = ends[a]
        # d1 reads t3 (a feedthrough-only instance: not in the first run), d2 reads t0,
        # which depends on d0 in the run before it; d5 reads d4 in its own run.
        assert names == [f"d{i}" for i in range(6)]
        assert runs == [["d0"], ["d1", "d2", "d3", "d4"], ["d5"]]
        assert parallel.group_ends(ports, jacobi=True) == [6] * 6
        after = parallel.updates_after(ports)
        assert after[0] == ports.first_in_order
        assert [[p.inst.name for p in x] for x in after[1:]] == [["t5"], [], ["t3"], [], ["t5"]]


def test_port_updates_per_step_grow_linearly_with_the_clocks(monkeypatch):
    """Each pendulum's step updates its own escapement, not every one (a
    system of k clocks made k x k updates per step)."""
    pulls = {"n": 0}
    real = Port.pull

    def counted(self, t, read=True):
        pulls["n"] += 1
        return real(self, t, read)

    monkeypatch.setattr(Port, "pull", counted)
    work = {}
    for k in (4, 8):
        comps, links = _clocks(k)
        with System(comps, links, MasterSettings(step=0.01, engine="python", event_location=False)) as s:
            pulls["n"] = 0
            s.master.run_until(0.1)
            work[k] = pulls["n"]
    assert work[8] <= 2 * work[4] + 20, work


def test_a_failed_step_on_threads_names_the_instance_one_thread_names():
    stair = str(test_fmu("TestStair"))
    comps = {"a": (stair, {"end_time": 0.5, "terminate": False}),
             "b": (stair, {"end_time": 0.25, "terminate": False}),
             "c": (stair, {"end_time": 0.25, "terminate": False})}
    errors = []
    for threads in (1, 2):
        with System(comps, [], MasterSettings(step=H, engine="compiled", threads=threads)) as s:
            with pytest.raises(SimulationError) as e:
                s.master.run_until(1.0)
            errors.append((str(e.value), e.value.instance))
    assert errors[0] == errors[1]
    assert errors[0][1] == "b"  # b and c fail in the same step: b comes first


@pytest.mark.parametrize("value", [0, -1, 257, 1.5, True, "2"])
def test_a_bad_thread_count_is_refused(tmp_path, value):
    with pytest.raises(SceneError, match="master.threads"):
        MasterSettings(threads=value)
    scene = tmp_path / "s.toml"
    scene.write_text(textwrap.dedent(f"""\
        [scene]
        title = "t"
        [components.d]
        fmu = "{test_fmu('TestDecay')}"
        [experiment]
        stop = 1.0
        [master]
        threads = {value!r}
        """).replace("'", '"').replace("True", "true"))
    with pytest.raises(SceneError, match="master.threads") as e:
        load_scene(scene)
    assert "\n" not in str(e.value)


def test_threads_reach_the_scene_and_its_ssp_and_leave_the_point_key(tmp_path):
    from clockwork.run.catalog import load_scene as load_with_kinds
    from clockwork.run.points import point_key
    from clockwork.scene.ssp import export_ssp

    path = _chain_scene(tmp_path, 3)
    one, two = load_scene(path), load_scene(path, ["master.threads=2"])
    assert (one.master.threads, two.master.threads) == (1, 2)
    assert point_key(one, {}) == point_key(two, {})  # the same bits on any number of threads
    assert point_key(one, {}) != point_key(load_scene(path, ["master.order=jacobi"]), {})
    export_ssp(two, tmp_path / "x.ssp")
    assert load_with_kinds(tmp_path / "x.ssp").master.threads == 2


def test_the_scaling_benchmark_runs_its_reduced_form_and_agrees_with_an_fmpy_loop(tmp_path):
    """benchmarks/bench_scale.py on the project's stand-ins: clockwork (one
    thread and two) gives the bits of a hand-written Gauss-Seidel loop over
    fmpy, on the chain and on the wide system."""
    import json
    import os
    import subprocess
    import sys

    from cwtest import ROOT, TEST_FMU_DIR

    out = tmp_path / "bench.json"
    proc = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "bench_scale.py"), "--sizes", "3", "6",
                           "--rounds", "1", "--tools", "clockwork", "clockwork-threads", "fmpy",
                           "--work", str(tmp_path / "work"), "--json", str(out)],
                          capture_output=True, text=True, env={**os.environ, "CW_TEST_FMU_DIR": str(TEST_FMU_DIR)})
    assert proc.returncode == 0, proc.stderr[-2000:]
    results = json.loads(out.read_text())
    assert len(results) == 2 * 2 * 3
    assert all(r["max_diff"] == 0 and r["lag_steps"] == 0 for r in results.values()), results


@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="counts the process's threads in /proc")
def test_freeing_a_system_stops_its_threads():
    def threads_now() -> int:  # the core's pthreads, which Python's threading module does not see
        return len(list(Path("/proc/self/task").iterdir()))

    start = threads_now()
    comps, links = _clocks(2)
    s = System(comps, links, MasterSettings(step=0.01, engine="compiled", threads=3))
    assert threads_now() == start + 2  # and the calling thread
    s.master.run_until(0.05)
    s.free()
    assert threads_now() == start


def test_a_run_without_plots_draws_none_and_plot_draws_them_later(tmp_path, capsys):
    """clockwork run --no-plot: no plot process, no plot file (the default
    plot a time series gets included); clockwork plot DIR draws it after."""
    import json

    from cwtest import run_cli

    scene = _chain_scene(tmp_path, 3)
    rc, out, err = run_cli(capsys, ["run", scene, "--out", tmp_path / "run", "--no-progress", "--no-plot"])
    assert rc == 0, err
    assert sorted(p.name for p in (tmp_path / "run").iterdir()) == ["summary.json", "timeseries.csv"]
    assert json.loads((tmp_path / "run" / "summary.json").read_text())["files"] == ["timeseries.csv", "summary.json"]
    rc, out, err = run_cli(capsys, ["plot", tmp_path / "run"])
    assert rc == 0 and (tmp_path / "run" / "outputs.png").is_file(), err


# -- many outputs ------------------------------------------------------------------------------


class _Name(str):
    """An output name that counts the comparisons made with it: a search of a
    list compares it with each entry, a dict or set lookup about once."""

    compared = 0

    def __eq__(self, other):
        type(self).compared += 1
        return str.__eq__(self, other)

    def __ne__(self, other):
        type(self).compared += 1
        return str.__ne__(self, other)

    __hash__ = str.__hash__


def _wide_run_work(tmp_path, n: int, engine: str) -> int:
    """Comparisons of output names while a System of one FMU with n outputs
    is built, recorded and stepped twice."""
    from wide_fmu import wide_fmu

    fmu = wide_fmu(test_fmu("TestSink"), n, tmp_path / f"wide{n}.fmu")
    names = [_Name(f"w[{k}]") for k in range(1, n + 1)]
    _Name.compared = 0
    with System({"w": (str(fmu), {})}, [], MasterSettings(step=0.1, engine=engine), record={"w": names}) as s:
        rec = Recorder(s.master, [("w", x) for x in names])
        rec.start()
        s.master.run_until(0.2, rec)
        assert len(rec.columns) == n + 1 and len(rec.columns["time"]) == 3
    return _Name.compared


@pytest.mark.parametrize("engine", ["python", "compiled"])
def test_recording_many_outputs_does_work_linear_in_them(tmp_path, engine):
    """100,000 outputs never finished: the ports and the recorder searched
    lists of output names for each output (n^2 / 2 comparisons)."""
    work = {n: _wide_run_work(tmp_path, n, engine) for n in (1000, 2000, 4000)}
    assert work[4000] <= 2.1 * work[2000] and work[2000] <= 2.1 * work[1000], work
    assert work[4000] < 10 * 4000, work  # a few per output, not one per pair


def test_the_compiled_recording_buffer_is_bounded_whatever_the_width(tmp_path):
    """The compiled core's buffer of recorded rows held 4096 rows of every
    column: 3.3 GB for 100,000 outputs before a step was taken."""
    import ctypes

    from wide_fmu import wide_fmu

    fmu = wide_fmu(test_fmu("TestSink"), 4000, tmp_path / "wide.fmu")
    names = [f"w[{k}]" for k in range(1, 4001)]
    with System({"w": (str(fmu), {})}, [], MasterSettings(step=0.1, engine="compiled"), record={"w": names}) as s:
        rec = Recorder(s.master, [("w", x) for x in names])
        native, _ = s.master._make_native(rec)
        rows, _ = native._buffers
        assert ctypes.sizeof(rows) <= 8 * (1 << 22) + 8 * 16 * 4001
        assert native.capacity >= 16
