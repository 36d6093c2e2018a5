"""Every command on every kind of FMU, alone and in a scene, on both engines.

The kinds: FMI 1.0, 2.0 and 3.0 Co-Simulation, FMI 2.0 and 3.0 Model
Exchange, FMI 3.0 with arrays; each with test FMUs built by CMake
(build/test-fmus) whose results have a closed form:

- Co-Simulation: TestDecay, dx/dt = -k x by explicit Euler steps as long as
  the tolerance the FMU is given (1e-2 without one: FMI 1.0 has none;
  DefaultExperiment's 1e-3 else), in a scene feeding TestSum
  (y = k1 u1 + c);
- Model Exchange: MeOscillator (a damped oscillator), in a scene feeding
  MeLag (dy/dt = (k u - y) / T): one linear system, solved by its matrix
  exponential;
- arrays: Linear (dx/dt = A x + B u, diagonal A, RK4 inside), in a scene
  where one's y drives the other's u (an array connection).

The commands: `clockwork run` (the FMU alone, the scene file), `validate`,
`info`, `export-scene` (the FMU alone as a scene, run again) and
`export-ssp` (the scene as an SSP, run again), `plot`, and
`clockwork.simulate`. Each run is made once per module (module fixtures)
and every cell checks its own claim on it: exit code 0, the result's
columns, the end value against the closed form, the two engines' bits
equal, an exported scene's bits equal to the original's, `plot --only` by
an output's recorded name, simulate with fmpy's `fmi_type` of the
interface the FMU runs through. The kinds clockwork refuses (FMI 1.0
Model Exchange, FMI 3.0 Model Exchange with arrays) are one line from
every command.
"""

from __future__ import annotations

import contextlib
import csv
import io
import math
import re
import zipfile
from dataclasses import dataclass
from pathlib import Path

import pytest

from cwtest import assert_one_line_error, test_fmu

ENGINES = ("python", "compiled")
MODES = ("alone", "scene")
# SSP 1.0 cannot describe FMI 3.0 arrays: export-ssp refuses such a scene (one line, exit 2).
NO_SSP = {"arrays"}


def _euler_decay(t: float, dt: float, step: float, k: float = 1.0, x0: float = 1.0) -> float:
    """TestDecay's x(t) (v = 0): each communication step of `step` s in
    explicit Euler steps of dt, the last one shorter."""
    m = math.floor(step / dt + 1e-9)
    per_step = (1 - k * dt) ** m * (1 - k * (step - m * dt))
    return x0 * per_step ** round(t / step)


OMEGA, ZETA = 2 * math.pi, 0.05  # MeOscillator's defaults (x0 = 1, v0 = 0)
LAG_K, LAG_T = 1.0, 0.5  # MeLag's defaults (y0 = 0)


def _oscillator(t: float) -> float:
    """MeOscillator's x(t), exactly."""
    wd = OMEGA * math.sqrt(1 - ZETA ** 2)
    return math.exp(-ZETA * OMEGA * t) * (math.cos(wd * t) + ZETA * OMEGA / wd * math.sin(wd * t))


def _lag_of(source, t: float, step: float, rate: float, gain: float = 1.0) -> float:
    """dy/dt = rate (gain u - y), y(0) = 0, with u = source(t_k+1) held over
    each communication step [t_k, t_k+1]: the master's Gauss-Seidel order (the
    source steps first, and its new output is the input held over the step)."""
    y, decay = 0.0, math.exp(-rate * step)
    for k in range(round(t / step)):
        y = decay * y + (1 - decay) * gain * source((k + 1) * step)
    return y


@dataclass(frozen=True)
class Kind:
    name: str
    fmu: str  # cwtest.test_fmu's name
    partner: str  # the second component of the scene
    interface: str  # as `clockwork info` names it
    fmi: str  # the FMI version, as `clockwork info` names it
    scene_body: str  # [components...], connections, parameters
    scene_stop: float
    scene_step: float


KINDS = {
    k.name: k for k in (
        Kind("cs1", "fmi1/TestDecay", "fmi1/TestSum", "Co-Simulation", "1.0",
             'connections = ["decay.x -> sum.u1"]\n'
             '[components.decay]\nfmu = "{fmu}"\n'
             '[components.sum]\nfmu = "{partner}"\nparameters = {{ k1 = 2, c = 0.5 }}\n', 1.0, 0.1),
        Kind("cs2", "TestDecay", "TestSum", "Co-Simulation", "2.0",
             'connections = ["decay.x -> sum.u1"]\n'
             '[components.decay]\nfmu = "{fmu}"\n'
             '[components.sum]\nfmu = "{partner}"\nparameters = {{ k1 = 2, c = 0.5 }}\n', 1.0, 0.1),
        Kind("cs3", "fmi3/TestDecay", "fmi3/TestSum", "Co-Simulation", "3.0",
             'connections = ["decay.x -> sum.u1"]\n'
             '[components.decay]\nfmu = "{fmu}"\n'
             '[components.sum]\nfmu = "{partner}"\nparameters = {{ k1 = 2, c = 0.5 }}\n', 1.0, 0.1),
        Kind("me2", "MeOscillator", "MeLag", "Model Exchange", "2.0",
             'connections = ["osc.x -> lag.u"]\n'
             '[components.osc]\nfmu = "{fmu}"\n[components.lag]\nfmu = "{partner}"\n', 2.0, 0.01),
        Kind("me3", "fmi3/MeOscillator", "fmi3/MeLag", "Model Exchange", "3.0",
             'connections = ["osc.x -> lag.u"]\n'
             '[components.osc]\nfmu = "{fmu}"\n[components.lag]\nfmu = "{partner}"\n', 2.0, 0.01),
        Kind("arrays", "fmi3/Linear", "fmi3/Linear", "Co-Simulation", "3.0",
             'connections = ["a.y -> b.u"]\n'
             '[components.a]\nfmu = "{fmu}"\n[components.b]\nfmu = "{partner}"\n', 2.0, 0.1),
    )
}

# The columns a run records (beside time): alone, every output of the FMU;
# in a scene, the [record] outputs below.
ALONE_COLUMNS = {
    "cs1": ["x"], "cs2": ["x"], "cs3": ["x"],
    "me2": ["x", "v"], "me3": ["x", "v"],
    "arrays": ["y[0]", "y[1]", "x[0]", "x[1]", "x[2]", "s", "kk[0]", "kk[1]", "kk[2]"],
}
SCENE_RECORD = {
    "cs1": ["decay.x", "sum.y"], "cs2": ["decay.x", "sum.y"], "cs3": ["decay.x", "sum.y"],
    "me2": ["osc.x", "lag.y"], "me3": ["osc.x", "lag.y"],
    "arrays": ["a.y", "b.x"],
}
SCENE_COLUMNS = {**SCENE_RECORD, "arrays": ["a.y[0]", "a.y[1]", "b.x[0]", "b.x[1]", "b.x[2]"]}


def expected_alone(kind: str, t: float) -> dict[str, tuple[float, float]]:
    """{column: (value, relative tolerance)} at the run's end t."""
    if kind in ("cs1", "cs2", "cs3"):
        # FMI 1.0 passes no tolerance (the FMU's 1e-2); 2.0 and 3.0 the DefaultExperiment's 1e-3.
        # `clockwork run X.fmu`'s step: the DefaultExperiment's (0.1 s), else fmpy's (stop / 500: FMI 1.0)
        dt, step = (1e-2, 2e-3) if kind == "cs1" else (1e-3, 0.1)
        return {"x": (_euler_decay(t, dt, step), 1e-12)}
    if kind in ("me2", "me3"):
        # the exact solution; the wrapper's integrator at the master's default tolerance (1e-6 relative)
        return {"x": (_oscillator(t), 1e-4)}
    x = [math.exp(-(i + 1) * t) for i in range(3)]  # A = diag(-1, -2, -3), x0 = 1, u = 0
    # RK4 in steps of 0.01: a global error of order 1e-8
    return {**{f"x[{i}]": (x[i], 1e-6) for i in range(3)}, "y[0]": (x[0], 1e-6), "y[1]": (x[1], 1e-6),
            "s": (sum(x), 1e-6)}


def expected_scene(kind: str, t: float) -> dict[str, tuple[float, float]]:
    step = KINDS[kind].scene_step
    if kind in ("cs1", "cs2", "cs3"):
        x = _euler_decay(t, 1e-2 if kind == "cs1" else 1e-3, step)
        return {"decay.x": (x, 1e-12), "sum.y": (2 * x + 0.5, 1e-12)}  # y = k1 x + c at the last point
    if kind in ("me2", "me3"):
        # MeLag: dy/dt = (k u - y) / T; the integrators' error at the default tolerance
        return {"osc.x": (_oscillator(t), 1e-4),
                "lag.y": (_lag_of(_oscillator, t, step, 1 / LAG_T, LAG_K), 1e-4)}
    # a alone: x_i = e^-(i+1)t (RK4 inside); b: dx_i/dt = -(i+1) x_i + u_i, x_i(0) = 1, u = a.y held
    # over each step as the master gives it, b.x[2] = e^-3t (no input)
    def b(i):
        return math.exp(-(i + 1) * t) + _lag_of(lambda s: math.exp(-(i + 1) * s), t, step, i + 1, 1 / (i + 1))
    return {"a.y[0]": (math.exp(-t), 1e-6), "a.y[1]": (math.exp(-2 * t), 1e-6),
            "b.x[0]": (b(0), 1e-6), "b.x[1]": (b(1), 1e-6), "b.x[2]": (math.exp(-3 * t), 1e-6)}


def cli(*argv) -> tuple[int, str, str]:
    """clockwork's CLI in this process: (exit code, stdout, stderr)."""
    from clockwork import cli as cw_cli

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = cw_cli.main([str(a) for a in argv])
    return rc, out.getvalue(), err.getvalue()


def read_series(folder: Path) -> tuple[list[str], list[list[str]]]:
    """timeseries.csv of a run: (header, rows as text: the bits as written)."""
    with open(folder / "timeseries.csv", newline="") as f:
        rows = list(csv.reader(f))
    return rows[0], rows[1:]


class Lab:
    """The matrix's files and runs, each made once (a module fixture)."""

    def __init__(self, root: Path):
        self.root = root
        self.runs: dict = {}
        self.sources: dict = {}

    def source(self, kind: str, mode: str) -> Path:
        """The FMU alone, or the scene file of the kind."""
        key = (kind, mode)
        if key not in self.sources:
            k = KINDS[kind]
            if mode == "alone":
                self.sources[key] = test_fmu(k.fmu)
            else:
                f = self.root / f"{kind}.toml"
                outputs = ", ".join(f'"{o}"' for o in SCENE_RECORD[kind])
                f.write_text(k.scene_body.format(fmu=test_fmu(k.fmu), partner=test_fmu(k.partner))
                             + f'[scene]\ntitle = "{kind}"\n'
                             f'[experiment]\nstop = "{k.scene_stop} s"\n'
                             f'[master]\nstep = "{k.scene_step} s"\n'
                             f"[record]\noutputs = [{outputs}]\n")
                self.sources[key] = f
        return self.sources[key]

    def exported(self, kind: str, mode: str) -> tuple[int, str, Path]:
        """export-scene of the FMU alone (a scene file), export-ssp of the scene (an SSP)."""
        key = ("export", kind, mode)
        if key not in self.runs:
            src = self.source(kind, mode)
            if mode == "alone":
                out = self.root / f"{kind}_exported.toml"
                rc, _, err = cli("export-scene", src, "--out", out)
            else:
                out = self.root / f"{kind}.ssp"
                rc, _, err = cli("export-ssp", src, "--out", out)
            self.runs[key] = (rc, err, out)
        return self.runs[key]

    def run(self, kind: str, mode: str, engine: str, exported: bool = False) -> tuple[int, str, Path]:
        """`clockwork run` of the source (or of what export made of it): (exit code, stderr, --out)."""
        key = ("run", kind, mode, engine, exported)
        if key not in self.runs:
            if exported:
                rc, err, src = self.exported(kind, mode)
                assert rc == 0, err
            else:
                src = self.source(kind, mode)
            out = self.root / f"{kind}_{mode}_{engine}{'_exported' if exported else ''}"
            # the Python engine's first run draws the default plot too (test_plot)
            plot = () if engine == "python" and not exported else ("--no-plot",)
            rc, _, err = cli("run", src, "--out", out, "--no-progress", *plot, "--set", f"master.engine={engine}")
            self.runs[key] = (rc, err, out)
        return self.runs[key]

    def simulate(self, kind: str, mode: str, engine: str):
        key = ("simulate", kind, mode, engine)
        if key not in self.runs:
            import clockwork

            self.runs[key] = clockwork.simulate(str(self.source(kind, mode)), master={"engine": engine})
        return self.runs[key]


@pytest.fixture(scope="module")
def lab(tmp_path_factory):
    return Lab(tmp_path_factory.mktemp("matrix"))


def _model(kind: str) -> str:
    """The instance `clockwork run X.fmu` makes: named after the model."""
    return Path(KINDS[kind].fmu).name


def _columns(kind: str, mode: str) -> list[str]:
    if mode == "alone":
        return ["time", *(f"{_model(kind)}.{c}" for c in ALONE_COLUMNS[kind])]
    return ["time", *SCENE_COLUMNS[kind]]


def _stop(kind: str, mode: str) -> float:
    if mode == "scene":
        return KINDS[kind].scene_stop
    return {"me2": 10.0, "me3": 10.0, "arrays": 2.0}.get(kind, 1.0)  # the FMUs' DefaultExperiment


def _check_end(kind: str, mode: str, header: list[str], last: list[float]) -> None:
    t = last[0]
    assert t == pytest.approx(_stop(kind, mode), abs=1e-12)
    expected = (expected_alone if mode == "alone" else expected_scene)(kind, t)
    got = dict(zip(header, last))
    if mode == "alone":
        expected = {f"{_model(kind)}.{c}": v for c, v in expected.items()}
    for column, (value, rel) in expected.items():
        assert got[column] == pytest.approx(value, rel=rel, abs=rel * 1e-3), (column, got[column], value)


CELLS = [(k, m) for k in KINDS for m in MODES]
IDS = [f"{k}-{m}" for k, m in CELLS]


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("kind, mode", CELLS, ids=IDS)
def test_run(lab, kind, mode, engine):
    """`clockwork run`: exit 0, the columns, the end value of each output against its closed form."""
    rc, err, out = lab.run(kind, mode, engine)
    assert rc == 0, err
    header, rows = read_series(out)
    assert header == _columns(kind, mode)
    _check_end(kind, mode, header, [float(v) for v in rows[-1]])


@pytest.mark.parametrize("kind, mode", CELLS, ids=IDS)
def test_the_two_engines_give_the_same_bits(lab, kind, mode):
    series = []
    for engine in ENGINES:
        rc, err, out = lab.run(kind, mode, engine)
        assert rc == 0, err
        series.append(read_series(out))
    assert series[0] == series[1]


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("kind, mode", CELLS, ids=IDS)
def test_validate(lab, kind, mode, engine):
    """`clockwork validate` passes where the run does (it crashed on a Model-Exchange-only FMU once)."""
    rc, out, err = cli("validate", lab.source(kind, mode), "--set", f"master.engine={engine}")
    assert rc == 0, err
    assert "Traceback" not in err and out.strip()


@pytest.mark.parametrize("kind, mode", CELLS, ids=IDS)
def test_info(lab, kind, mode):
    """`clockwork info`: the FMU (its version, interface and outputs), or the SSP the scene exports to
    (both instances); the scene file itself is one line naming it (before: "expected a model name (e.g.
    "Pendulum") or a path ending .fmu", no file named)."""
    if mode == "alone":
        rc, out, err = cli("info", lab.source(kind, mode))
        assert rc == 0, err
        assert f"(FMI {KINDS[kind].fmi} {KINDS[kind].interface})" in out.splitlines()[0], out
        for column in ALONE_COLUMNS[kind]:
            assert column.split("[")[0] in out, (column, out)
        return
    rc, _, err = cli("info", lab.source(kind, mode))
    assert_one_line_error(rc, err, f"{lab.source(kind, mode)}: expected an FMU", "clockwork validate")
    if kind in NO_SSP:  # each component's FMU
        for fmu in {KINDS[kind].fmu, KINDS[kind].partner}:
            rc, out, err = cli("info", test_fmu(fmu))
            assert rc == 0, err
            assert f"(FMI {KINDS[kind].fmi} {KINDS[kind].interface})" in out.splitlines()[0], out
    else:
        rc, err, ssp = lab.exported(kind, mode)
        assert rc == 0, err
        rc, out, err = cli("info", ssp)
        assert rc == 0, err
        for column in SCENE_RECORD[kind]:
            assert column.split(".")[0] in out, (column, out)


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("kind, mode", CELLS, ids=IDS)
def test_exported_runs_give_the_same_bits(lab, kind, mode, engine):
    """export-scene (the FMU alone) or export-ssp (the scene): validate passes, and its run gives the
    original's bits; a scene SSP 1.0 cannot describe is refused with one line."""
    rc, err, exported = lab.exported(kind, mode)
    if mode == "scene" and kind in NO_SSP:
        assert_one_line_error(rc, err, "array variables", "SSP 1.0")
        assert not exported.exists()
        return
    assert rc == 0, err
    rc, _, err = cli("validate", exported, "--set", f"master.engine={engine}")
    assert rc == 0, err
    rc, err, out = lab.run(kind, mode, engine, exported=True)
    assert rc == 0, err
    rc0, err0, out0 = lab.run(kind, mode, engine)
    assert rc0 == 0, err0
    assert read_series(out) == read_series(out0)


@pytest.mark.parametrize("kind, mode", CELLS, ids=IDS)
def test_plot(lab, kind, mode):
    """`clockwork run` draws its default plot, and `clockwork plot` a finished run's outputs."""
    rc, err, run = lab.run(kind, mode, "python")
    assert rc == 0, err
    assert (run / "outputs.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    png = run.parent / f"{kind}_{mode}.png"
    rc, _, err = cli("plot", run, "--out", png)
    assert rc == 0, err
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # --only an output by the name [record] and simulate take (an array's: every element; before, no
    # column matched it)
    name = ALONE_COLUMNS[kind][0].split("[")[0] if mode == "alone" else SCENE_RECORD[kind][-1]
    rc, _, err = cli("plot", run, "--only", name, "--out", png.with_name(f"only_{png.name}"))
    assert rc == 0, err
    assert png.with_name(f"only_{png.name}").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("kind, mode", CELLS, ids=IDS)
def test_simulate(lab, kind, mode, engine):
    """clockwork.simulate: the fields of the run's columns (an array a field of its shape), the CLI
    run's numbers."""
    got = lab.simulate(kind, mode, engine)
    rc, err, out = lab.run(kind, mode, engine)
    assert rc == 0, err
    header, rows = read_series(out)
    flat = {"time": got["time"]}
    for name in got.dtype.names[1:]:
        values = got[name]
        if values.ndim == 1:
            flat[name] = values
        else:
            for i in range(values.shape[1]):
                flat[f"{name}[{i}]"] = values[:, i]
    if mode == "alone":  # fmpy's names: the variable's alone
        header = ["time", *(c.split(".", 1)[1] for c in header[1:])]
    assert sorted(flat) == sorted(header)
    assert len(got) == len(rows)
    for j, column in enumerate(header):
        assert [float(r[j]) for r in rows] == flat[column].astype(float).tolist(), column


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("kind, mode", CELLS, ids=IDS)
def test_simulate_takes_fmpys_fmi_type_of_the_interface_it_runs(lab, kind, mode, engine):
    """fmpy's fmi_type naming the interface the FMU runs through (Model Exchange for a Model-Exchange-only
    FMU, as an fmpy user writes it) gives the same result; the other interface is one line naming fmi_type
    (before: 'ModelExchange' was refused for every FMU, 'CoSimulation' ran a Model-Exchange-only FMU)."""
    import clockwork
    from clockwork.errors import UsageError

    runs, other = ("ModelExchange", "CoSimulation") if kind.startswith("me") else ("CoSimulation", "ModelExchange")
    got = clockwork.simulate(str(lab.source(kind, mode)), master={"engine": engine}, fmi_type=runs)
    assert got.dtype == lab.simulate(kind, mode, engine).dtype
    assert got.tobytes() == lab.simulate(kind, mode, engine).tobytes()
    with pytest.raises(UsageError) as e:
        clockwork.simulate(str(lab.source(kind, mode)), master={"engine": engine}, fmi_type=other)
    assert str(e.value).startswith(f"simulate(fmi_type={other!r}): ") and "\n" not in str(e.value)


# Kinds clockwork refuses: FMI 1.0 Model Exchange (TestDecay's FMI 1.0 description without <Implementation>)
# and FMI 3.0 Model Exchange with arrays (Linear's description declaring <ModelExchange>); copies of the
# built archives with the description edited.
REFUSED = {
    "fmi1-me": ("fmi1/TestDecay", lambda xml: re.sub(r"<Implementation>.*?</Implementation>", "", xml, flags=re.S),
                "FMI 1.0 Model Exchange is not supported"),
    "fmi3-me-arrays": ("fmi3/Linear",
                       lambda xml: re.sub(r"<CoSimulation [^>]*/>", '<ModelExchange modelIdentifier="Linear"/>', xml),
                       "Model Exchange with FMI 3.0 array variables is not supported"),
}


@pytest.fixture(scope="module")
def refused(tmp_path_factory):
    """{kind: (the FMU, a scene with it beside TestSum)}."""
    folder = tmp_path_factory.mktemp("refused")
    out = {}
    for kind, (name, edit, _) in REFUSED.items():
        fmu = folder / f"{kind}.fmu"
        with zipfile.ZipFile(test_fmu(name)) as zin, zipfile.ZipFile(fmu, "w") as zout:
            for item in zin.infolist():
                data = zin.read(item)
                if item.filename == "modelDescription.xml":
                    data = edit(data.decode()).encode()
                    assert data != zin.read(item)
                zout.writestr(item, data)
        scene = folder / f"{kind}.toml"
        scene.write_text(f'[scene]\ntitle = "{kind}"\n[components.a]\nfmu = "{fmu}"\n'
                         f'[components.sum]\nfmu = "{test_fmu("TestSum")}"\n[experiment]\nstop = "1 s"\n')
        out[kind] = (fmu, scene)
    return out


# info and export-scene take an FMU, not a scene file
REFUSED_CELLS = [(k, m, c) for k in REFUSED for m in MODES
                 for c in ("validate", "run python", "run compiled", "export-scene", "info", "simulate")
                 if m == "alone" or c not in ("info", "export-scene")]


@pytest.mark.parametrize("kind, mode, command", REFUSED_CELLS, ids=["-".join(c) for c in REFUSED_CELLS])
def test_a_kind_clockwork_cannot_run_is_one_line_from_every_command(refused, tmp_path, kind, mode, command):
    """Exit 2 and one line saying what is not supported, nothing written; `info` describes what it can."""
    import clockwork
    from clockwork.errors import SceneError

    fmu, scene = refused[kind]
    src, why = (fmu if mode == "alone" else scene), REFUSED[kind][2]
    out = tmp_path / "out"
    if command == "simulate":
        with pytest.raises(SceneError) as e:
            clockwork.simulate(str(src))
        assert why in str(e.value) and "\n" not in str(e.value)
        return
    if command == "info":
        rc, got, err = cli("info", src)
        if kind == "fmi3-me-arrays":  # described, though not run
            assert rc == 0 and got.startswith("Linear (FMI 3.0 Model Exchange)"), err
        else:
            assert_one_line_error(rc, err, why)
        return
    if command == "export-scene":
        out = tmp_path / "out.toml"
    argv = {"validate": ["validate", src], "export-scene": ["export-scene", src, "--out", out],
            "run python": ["run", src, "--out", out, "--no-progress", "--set", "master.engine=python"],
            "run compiled": ["run", src, "--out", out, "--no-progress", "--set", "master.engine=compiled"]}[command]
    rc, _, err = cli(*argv)
    assert_one_line_error(rc, err, why)
    assert not out.exists()
