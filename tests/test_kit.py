"""The regression kit: export-suite's cases, fmpy's cross-check validation of
the single-FMU part, and compare's verdicts on good, perturbed and bad results."""

import json
from pathlib import Path

import numpy as np
import pytest

from cwtest import FMU_DIR, assert_one_line_error, fmu_file, run_cli
from clockwork import __version__, cli
from clockwork.kit import events
from clockwork.kit.cases import CASES
from clockwork.kit.csvio import read_result, write_csv
from clockwork.kit.runners import run_clockwork


@pytest.fixture(autouse=True)
def _fmu_dir(monkeypatch):
    fmu_file("Pendulum")
    monkeypatch.setenv("CLOCKWORK_FMU_DIR", str(FMU_DIR))


run = run_cli


@pytest.fixture(scope="module")
def suite(tmp_path_factory):
    import os

    os.environ["CLOCKWORK_FMU_DIR"] = str(FMU_DIR)
    d = tmp_path_factory.mktemp("kit") / "suite"
    assert cli.main(["export-suite", str(d)]) == 0
    return d


@pytest.fixture(scope="module")
def own_result(tmp_path_factory, suite):
    out = tmp_path_factory.mktemp("runs") / "grasshopper.csv"
    run_clockwork(CASES["GrasshopperClock"], out)
    return out


def _case_dir(suite, name):
    c = CASES[name]
    if c.kind == "fmu":
        return suite / "fmus" / "2.0" / "cs" / "linux64" / "clockwork" / __version__ / name
    return suite / "ssp" / name


def test_export_suite_writes_every_case(suite):
    assert len(CASES) >= 6
    index = json.loads((suite / "suite.json").read_text())
    assert [c["name"] for c in index["cases"]] == list(CASES)
    for name, c in CASES.items():
        d = _case_dir(suite, name)
        model = d / (f"{name}.fmu" if c.kind == "fmu" else f"{name}.ssp")
        for f in (model, d / f"{name}_ref.csv", d / f"{name}_ref.opt", d / f"{name}_case.json",
                  d / f"{name}_events.csv", d / "README.md"):
            assert f.is_file(), f
        meta = json.loads((d / f"{name}_case.json").read_text())
        assert meta["events"]["count"]["ticks"] >= 8
        if c.switch_signal:
            assert meta["events"]["count"]["switches"] >= 16
        assert set(meta["tolerances"]["tube"]) == set(c.tube_signals)
        assert (d / f"{name}_in.csv").is_file() == (c.jump is not None)
    assert not list(suite.rglob("*.part"))


def test_reference_results_in_the_fmi_ls_ref_layout(suite):
    """Every case's reference files are described by an FMI-LS-REF manifest
    (extra/org.fmi-standard.fmi-ls-ref/fmi-ls-manifest.xml): inside the FMU
    for a single-FMU case, with the files beside it; in the case directory
    for a coupled case, pointing at the files there. Each source resolves to
    the same bytes as the case's own file, and the reference has role result."""
    import posixpath
    import xml.etree.ElementTree as ET
    import zipfile

    ls = "extra/org.fmi-standard.fmi-ls-ref"
    ns = "{http://fmi-standard.org/fmi-ls-manifest}"
    for name, c in CASES.items():
        d = _case_dir(suite, name)
        if c.kind == "fmu":
            z = zipfile.ZipFile(d / f"{name}.fmu")
            manifest = z.read(f"{ls}/fmi-ls-manifest.xml")

            def read(source):
                return z.read(posixpath.normpath(f"{ls}/{source}"))
            assert b"fmi-ls-ref" in z.read("documentation/fmi-ls-ref.txt")
        else:
            manifest = (d / ls / "fmi-ls-manifest.xml").read_bytes()

            def read(source):
                return (d / ls / source).resolve().read_bytes()
        root = ET.fromstring(manifest)
        assert root.tag == "fmiReferences" and root.get(f"{ns}fmi-ls-name") == "org.fmi-standard.fmi-ls-ref"
        related = {Path(r.get("source")).name: r for r in root.iter("Related")}
        assert related[f"{name}_ref.csv"].get("role") == "result"
        assert related[f"{name}_ref.csv"].get("type") == "text/csv"
        assert {f"{name}_events.csv", f"{name}_case.json", "README.md"} <= set(related)
        assert (f"{name}_in.csv" in related) == (c.jump is not None)
        for base, r in related.items():
            assert read(r.get("source")) == (d / base).read_bytes(), (name, base)


def test_single_fmu_part_passes_fmpy_cross_check_validation(suite):
    from fmpy.cross_check.validate_vendor_repo import validate_repo

    fmus, results, problems = validate_repo(str(suite))
    assert fmus == sum(c.kind == "fmu" for c in CASES.values()) and problems == []


def test_compare_passes_clockworks_own_result(capsys, suite, own_result):
    rc, out, err = run(capsys, ["compare", own_result, _case_dir(suite, "GrasshopperClock")])
    assert rc == 0 and err == "", out
    assert out.strip().endswith("verdict: PASS")
    assert "switches (100)" in out and "ticks (50)" in out


def test_compare_fails_a_result_outside_the_tube(capsys, tmp_path, suite, own_result):
    r = read_result(own_result)
    names = ["time"] + list(r.columns)
    data = np.column_stack([r.time] + [r.columns[n] for n in r.columns])
    tol = CASES["GrasshopperClock"].tolerances.tube["pendulum.phi"]
    data[:, names.index("pendulum.phi")] += 3 * tol * np.sin(r.time)  # 3x the tube, no event moved much
    bad = write_csv(tmp_path / "perturbed.csv", names, data)
    rc, out, _ = run(capsys, ["compare", bad, _case_dir(suite, "GrasshopperClock")])
    assert rc == 1, out
    assert "tube pendulum.phi" in out and "FAIL" in out and out.strip().endswith("verdict: FAIL")


def test_compare_fails_a_shifted_switch(capsys, tmp_path, suite, own_result):
    """The escapement torque changes sign three rows late at one switch: the
    tube and ticks still pass, the switch check does not."""
    r = read_result(own_result)
    tau = r.columns["escapement.tau"].copy()
    j = int(np.nonzero(np.sign(tau[1:]) != np.sign(tau[:-1]))[0][5]) + 1
    tau[j:j + 3] = tau[j - 1]
    cols = dict(r.columns, **{"escapement.tau": tau})
    bad = write_csv(tmp_path / "late.csv", ["time"] + list(cols), np.column_stack([r.time] + list(cols.values())))
    rc, out, _ = run(capsys, ["compare", bad, "GrasshopperClock"])
    assert rc == 1
    lines = {ln.split()[0] + " " + ln.split()[1]: ln for ln in out.splitlines()[2:-1]}
    assert lines["tube pendulum.phi"].endswith("pass")
    assert "FAIL" in lines["switches (100)"]


def test_compare_reads_other_tools_layouts(capsys, tmp_path, suite, own_result):
    r = read_result(own_result)
    # OMSimulator: model.root.<comp>.<var>; an extra column it cannot match
    oms = ["time"] + [f"model.root.{n}" for n in r.columns] + ["model.root.pendulum.energy"]
    data = np.column_stack([r.time] + list(r.columns.values()) + [np.zeros_like(r.time)])
    f = write_csv(tmp_path / "oms.csv", oms, data)
    rc, out, _ = run(capsys, ["compare", f, _case_dir(suite, "GrasshopperClock")])
    assert rc == 0, out
    assert "unmatched column: model.root.pendulum.energy" in out
    # ecos's CSV writer: iterations, time, <inst>::<var>[REAL]
    lines = ["iterations, time, " + ", ".join(n.replace(".", "::") + "[REAL]" for n in r.columns)]
    for k, t in enumerate(r.time):
        lines.append(f"{k}, {float(t)!r}, " + ", ".join(repr(float(v[k])) for v in r.columns.values()))
    (tmp_path / "ecos.csv").write_text("\n".join(lines) + "\n")
    rc, out, _ = run(capsys, ["compare", tmp_path / "ecos.csv", "GrasshopperClock"])
    assert rc == 0, out
    # libcosim's file observer: one CSV per slave, "<var> [<ref> <type> <causality>]"
    d = tmp_path / "libcosim"
    d.mkdir()
    for slave in ("pendulum", "escapement"):
        mine = {n.split(".")[1]: v for n, v in r.columns.items() if n.startswith(slave + ".")}
        head = ["Time", "StepCount"] + [f"{v} [{k} Real OUT]" for k, v in enumerate(mine)]
        write_csv(d / f"{slave}_20260101_120000_000001.csv", head,
                  np.column_stack([r.time, np.arange(len(r.time))] + list(mine.values())))
    rc, out, _ = run(capsys, ["compare", d, _case_dir(suite, "GrasshopperClock")])
    assert rc == 0, out


def test_compare_names_a_missing_signal(capsys, tmp_path, own_result):
    r = read_result(own_result)
    f = write_csv(tmp_path / "no_w.csv", ["time", "pendulum.phi"], np.column_stack([r.time, r.columns["pendulum.phi"]]))
    rc, out, _ = run(capsys, ["compare", f, "GrasshopperClock"])
    assert rc == 1
    assert "missing signal: pendulum.w (no column ends with 'pendulum.w')" in out


@pytest.mark.parametrize("content, needle", [
    (None, "no such file"),
    ("just text\n", "expected a header line"),
    ("time,pendulum.phi\n0,abc\n", "line 2: not a number"),
    ("phi,time\n0,0\n1,1\n", "first column must be the time"),
    ("time,pendulum.phi\n1,0\n0,0\n", "non-decreasing"),
])
def test_compare_bad_csv_exits_2_with_one_line(capsys, tmp_path, content, needle):
    f = tmp_path / "r.csv"
    if content is not None:
        f.write_text(content)
    rc, _, err = run(capsys, ["compare", f, "GrasshopperClock"])
    assert_one_line_error(rc, err, needle)


def test_compare_unknown_case_exits_2(capsys, own_result, tmp_path):
    rc, _, err = run(capsys, ["compare", own_result, "NoSuchCase"])
    assert_one_line_error(rc, err, "unknown case 'NoSuchCase'")
    rc, _, err = run(capsys, ["compare", own_result, tmp_path])
    assert_one_line_error(rc, err, "not a case directory")


def test_export_suite_unknown_case_exits_2(capsys, tmp_path):
    rc, _, err = run(capsys, ["export-suite", tmp_path / "s", "--only", "Nope"])
    assert_one_line_error(rc, err, "--only Nope: unknown case")


def test_kink_locator_places_a_switch_between_rows():
    """A slope jump of w between rows of a 0.01 s grid, found to < 1e-8 s."""
    t = np.arange(0.0, 0.4, 0.01)
    ts = 0.2037
    w = 0.3 * np.cos(3.1 * t) + 0.008 * np.maximum(t - ts, 0.0) - 0.04 * np.maximum(t - ts, 0.0) ** 3 / 6
    tau = np.where(t < ts, -1.0, 1.0)
    found, _ = events.switches(t, tau, w)
    assert len(found) == 1 and abs(found[0] - ts) < 1e-8


@pytest.mark.parametrize("name", list(CASES))
def test_clockworks_master_passes_every_case_and_fails_without_event_location(tmp_path, suite, name):
    from clockwork.kit.grade import compare

    good = run_clockwork(CASES[name], tmp_path / "good.csv")
    assert compare(good, _case_dir(suite, name)).passed
    if CASES[name].switch_signal:
        late = run_clockwork(CASES[name], tmp_path / "late.csv", event_location=False)
        g = compare(late, _case_dir(suite, name))
        assert not g.passed and not next(c for c in g.checks if c.what.startswith("switches")).ok


def test_fmpy_result_of_the_single_fmu_case_passes_and_json_is_strict(capsys, tmp_path, suite):
    from fmpy import simulate_fmu
    from fmpy.util import write_csv as fmpy_write_csv

    d = _case_dir(suite, "Pendulum")
    res = simulate_fmu(str(d / "Pendulum.fmu"), stop_time=20.0, step_size=0.01, output_interval=0.01,
                       output=["phi", "w"])
    out = tmp_path / "Pendulum_out.csv"
    fmpy_write_csv(str(out), res)
    rc, text, _ = run(capsys, ["compare", out, d, "--json", tmp_path / "grade.json"])
    assert rc == 0, text
    grade = json.loads((tmp_path / "grade.json").read_text(), parse_constant=lambda c: pytest.fail(c))
    assert grade["passed"] and grade["case"] == "Pendulum"
    assert not list(tmp_path.glob(".*.part"))


def test_kit_imports_only_layers_below_it():
    """kit/ sits beside bench/ above run/: it never imports the cli or the bench."""
    import ast

    kit = Path(__file__).resolve().parents[1] / "clockwork" / "kit"
    for f in kit.glob("*.py"):
        for node in ast.walk(ast.parse(f.read_text())):
            if isinstance(node, ast.ImportFrom) and node.level:
                mod = node.module or ""
                assert not (node.level >= 2 and mod.split(".")[0] in ("cli", "bench")), (f.name, mod)


def test_fmpy_ssp_run_with_the_torque_jump_input_is_graded(tmp_path, suite):
    """fmpy's SSP runner on the torque-jump case (input through a system
    connector of a copy of the archive): a fixed-step result, so it fails,
    on its switches among others, and leaves no temporary files."""
    import subprocess
    import sys
    import tempfile

    from clockwork.kit.grade import compare

    before = set(Path(tempfile.gettempdir()).glob("clockwork-kit-fmpy-*"))
    out = tmp_path / "hoyng.fmpy.csv"
    p = subprocess.run([sys.executable, "-m", "clockwork.kit.tools", "fmpy", str(_case_dir(suite, "HoyngTorqueJump")),
                        "--step", "0.02", "--out", str(out)], capture_output=True, text=True, timeout=600,
                       cwd=Path(__file__).resolve().parents[1])
    assert p.returncode == 0, p.stderr[-2000:]
    g = compare(out, _case_dir(suite, "HoyngTorqueJump"))
    assert not g.passed and not g.missing
    checks = {c.what.split(" (")[0]: c for c in g.checks}
    assert not checks["switches"].ok and checks["switches"].worst > 0.02  # one to two steps late
    assert set(Path(tempfile.gettempdir()).glob("clockwork-kit-fmpy-*")) == before


def test_signals_of_dotted_instances_are_split_by_the_names_resolver(tmp_path):
    """Instances "clock" and "clock.pendulum": clock.pendulum.phi is phi of
    clock.pendulum, clock.vibration_velocity an input of clock (a split at
    the first dot would look for pendulum.phi in clock). The run gives the
    plain case's numbers."""
    import dataclasses

    from clockwork.kit.cases import SCENES

    plain = CASES["HoyngTorqueJump"]
    text = (SCENES / "hoyng_jump.toml").read_text()
    text = text.replace('"escapement.', '"clock.').replace('"pendulum.', '"clock.pendulum.')
    text = text.replace("-> escapement.", "-> clock.").replace("-> pendulum.", "-> clock.pendulum.")
    text = text.replace("[components.pendulum]", '[components."clock.pendulum"]')
    text = text.replace("[components.escapement]", "[components.clock]")
    (tmp_path / "dotted.toml").write_text(text)
    short = plain.overrides[0], "experiment.stop=3.0"
    a = read_result(run_clockwork(dataclasses.replace(plain, stop=3.0, overrides=short, jump=(1.5, *plain.jump[1:])),
                                  tmp_path / "plain.csv"))
    dotted = dataclasses.replace(
        plain, scene=str(tmp_path / "dotted.toml"), stop=3.0, overrides=("clock." + short[0], short[1]),
        tube_signals=("clock.pendulum.phi", "clock.pendulum.w"), switch_signal="clock.tau",
        jump=(1.5, "clock.vibration_velocity", 0.0, 1.0))
    b = read_result(run_clockwork(dotted, tmp_path / "dotted.csv"))
    assert len(a.time) > 100 and np.array_equal(a.time, b.time)
    for x, y in (("pendulum.phi", "clock.pendulum.phi"), ("pendulum.w", "clock.pendulum.w"),
                 ("escapement.tau", "clock.tau")):
        assert np.array_equal(a.columns[x], b.columns[y]), x
