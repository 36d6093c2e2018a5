"""clockwork design: an escapement whose rate ignores its drive (and the
barometer), found by SciPy on steady states; and its bad input."""

import json

import pytest

from cwtest import FMU_DIR, assert_one_line_error, run_cli


@pytest.fixture(autouse=True)
def _fmu_dir(monkeypatch):
    monkeypatch.setenv("CLOCKWORK_FMU_DIR", str(FMU_DIR))


def _fig4a_amplitude() -> float:
    """The bundled Fig. 4(a) design's amplitude (deg) at its operating torque, 0.4 N.cm."""
    import dataclasses

    from clockwork.run.catalog import load_scene
    from clockwork.run.points import run_point

    scene = load_scene("ziemkiewicz_fig4a")
    scene = dataclasses.replace(scene, sweep=None, plots=(), analysis={"kind": "steady_state",
                                                                       "tolerance_s_per_day": 1e-6})
    return run_point(scene, {})["result"]["amplitude_deg"]


DRIVE = "d(E_T_s_per_day)/d(escapement.torque [N.cm])"
PRESSURE = "d(E_T_s_per_day)/d(air.pressure [hPa])"


@pytest.mark.slow
def test_grasshopper_design_ignores_its_drive(tmp_path, capsys):
    """At the bundled design's own amplitude, a recoil angle is found whose
    drive sensitivity is at least 10x smaller, and the forward check (the
    steady rate at the torque -10 % and +10 %) confirms it."""
    amplitude = _fig4a_amplitude()
    rc, out, err = run_cli(capsys, ["design", "ziemkiewicz_fig4a", "--vary", "escapement.phi_r=1deg..5deg",
                                    "--amplitude", repr(amplitude), "--goal", DRIVE, "--out", tmp_path / "d"])
    assert rc == 0, err
    d = json.loads((tmp_path / "d" / "summary.json").read_text())["design"]
    (s,) = d["sensitivities"]
    assert abs(s["after"]) * 10 <= abs(s["before"]), s
    # the same amplitude before and after, the bundled torque before
    for when in ("before", "after"):
        assert abs(d["operating_point"][when]["amplitude_deg"] / amplitude - 1) < 1e-6
    assert abs(d["parameters"]["escapement.torque"]["before"] / 0.004 - 1) < 1e-5
    f = d["forward_check"]
    for check in (f, {k: f[k]["time_domain"] for k in ("before", "after")}):  # shooting, then plain runs
        assert abs(check["after"]["rate_change_s_per_day_over_pm10_percent"]) * 10 <= \
            abs(check["before"]["rate_change_s_per_day_over_pm10_percent"]), f
    # the plain forward runs (no shooting) agree with the steady states to the scene's own rate tolerance
    for when in ("before", "after"):
        for steady, timed in zip(f[when]["E_T_s_per_day"], f[when]["time_domain"]["E_T_s_per_day"]):
            assert abs(steady - timed) < 1e-3, f
    assert d["goal"]["after"] < d["goal"]["before"]
    assert sorted(json.loads((tmp_path / "d" / "summary.json").read_text())["files"]) == \
        ["design.csv", "design_goal.png", "summary.json"]


@pytest.mark.slow
def test_pressure_weight_trades_drive_for_barometer(tmp_path, capsys):
    """The clock in air: with the pressure's weight raised, the design's
    pressure sensitivity falls and its drive sensitivity rises."""
    after = {}
    for w in (1.0, 1e4):
        rc, _, err = run_cli(capsys, ["design", "air_barometric_ziemkiewicz", "--vary",
                                      "escapement.phi_r=1deg..5deg", "--amplitude", "7",
                                      "--goal", f"{DRIVE} + {w!r}*{PRESSURE}", "--out", tmp_path / f"w{w:g}"])
        assert rc == 0, err
        d = json.loads((tmp_path / f"w{w:g}" / "summary.json").read_text())["design"]
        drive, pressure = d["sensitivities"]
        assert drive["term"] == DRIVE and pressure["term"] == PRESSURE and pressure["weight"] == w
        after[w] = (abs(drive["after"]), abs(pressure["after"]))
    assert after[1e4][1] < after[1.0][1], after
    assert after[1e4][0] > after[1.0][0], after


@pytest.mark.parametrize("args, needles", [
    (["--vary", "escapement.phi_r=1deg..5deg", "--goal", "d(E_X)/d(escapement.torque)"],
     ["--goal", "E_X", "no result column", "E_T_s_per_day"]),
    (["--vary", "escapement.phi_r=1deg..5deg", "--goal", "E_T_s_per_day"], ["--goal", "expected"]),
    (["--vary", "escapement.phi_r=1deg..5deg", "--goal", f"{DRIVE} +"], ["--goal", "character"]),
    (["--vary", "escapement.phi_r=1deg..5deg", "--goal", f"0*{DRIVE}"], ["--goal", "weight > 0"]),
    (["--vary", "escapement.phi_r=1deg..5deg", "--goal", "d(E_T_s_per_day)/d(pendulum.nope)"],
     ["--goal", "no variable nope"]),
    (["--vary", "escapement.phi_r=1deg..5deg", "--goal", "d(E_T_s_per_day)/d(escapement.torque [hPa])"],
     ["--goal", "[hPa]"]),
    (["--vary", "escapement.nope=1..2", "--goal", DRIVE], ["--vary escapement.nope=1..2", "no variable nope"]),
    (["--vary", "escapement.phi_r", "--goal", DRIVE], ["--vary escapement.phi_r", "LOW..HIGH"]),
    (["--vary", "escapement.phi_r=", "--goal", DRIVE], ["--vary escapement.phi_r", "LOW..HIGH"]),
    (["--vary", "escapement.phi_r=3deg..2deg", "--goal", DRIVE], ["--vary", "LOW < HIGH"]),
    (["--vary", "escapement.phi_r=2deg..2deg", "--goal", DRIVE], ["--vary", "LOW < HIGH"]),
    (["--vary", "escapement.phi_r=1 kg..2 kg", "--goal", DRIVE], ["--vary", "a unit of rad"]),
    (["--vary", "escapement.phi_r=1deg..5deg", "--vary", "escapement.phi_r=2deg..3deg", "--goal", DRIVE],
     ["--vary", "twice"]),
    (["--vary", "escapement.torque=0.1N.cm..1N.cm", "--amplitude", "7", "--goal", DRIVE],
     ["--vary", "amplitude"]),
    (["--goal", DRIVE], ["--vary"]),
    (["--vary", "escapement.phi_r=1deg..5deg", "--goal", DRIVE, "--step", "0"], ["--step"]),
], ids=["column", "no-derivative", "dangling-plus", "zero-weight", "unknown-goal-param", "goal-unit",
        "unknown-vary", "no-range", "empty-range", "low-above-high", "low-equals-high", "vary-unit", "twice",
        "drive-and-amplitude", "no-vary", "step"])
def test_bad_input_is_one_line(tmp_path, capsys, args, needles):
    out = tmp_path / "d"
    rc, _, err = run_cli(capsys, ["design", "ziemkiewicz_fig4a", *args, "--out", out])
    assert_one_line_error(rc, err, *needles)
    assert not out.exists() or not any(out.iterdir())


def test_a_scene_without_steady_states_is_refused(tmp_path, capsys):
    out = tmp_path / "d"
    rc, _, err = run_cli(capsys, ["design", "hoyng_fig5", "--vary", "escapement.phi_r=0.02..0.04",
                                  "--goal", "d(E_T_s_per_day)/d(escapement.torque)", "--out", out])
    assert_one_line_error(rc, err, "hoyng_fig5.toml", "analysis.kind", "steady-state")
    assert not out.exists()


def test_an_optimiser_that_fails_is_exit_1_and_writes_nothing(tmp_path, capsys):
    """Every design stalls (a torque far too weak to swing past phi_r): no
    goal anywhere, the optimiser fails, nothing is written."""
    out = tmp_path / "d"
    rc, _, err = run_cli(capsys, ["design", "ziemkiewicz_fig4a", "--vary", "escapement.torque=1e-9..2e-9",
                                  "--goal", "d(E_T_s_per_day)/d(escapement.phi_r)", "--out", out])
    assert_one_line_error(rc, err, "optimiser", code=1)
    assert not out.exists() or not any(p for p in out.iterdir() if not p.name.startswith("."))


@pytest.mark.slow
def test_drive_pressure_and_temperature_in_one_goal(tmp_path, capsys):
    """The three sensitivities the horologist asks about, weighted in one
    goal, each reported before and after in its unit."""
    goal = f"{DRIVE} + 100*d(E_T_s_per_day)/d(air.temperature [K]) + 1e3*{PRESSURE}"
    rc, _, err = run_cli(capsys, ["design", "air_thermal", "--vary", "escapement.phi_r=1deg..5deg", "--amplitude", "7",
                                  "--goal", goal, "--out", tmp_path / "d"])
    assert rc == 0, err
    d = json.loads((tmp_path / "d" / "summary.json").read_text())["design"]
    assert [s["unit"] for s in d["sensitivities"]] == ["s/day per N.cm", "s/day per K", "s/day per hPa"]
    assert [s["weight"] for s in d["sensitivities"]] == [1.0, 100.0, 1e3]
    assert all(isinstance(s[k], float) for s in d["sensitivities"] for k in ("before", "after"))
    assert d["goal"]["after"] < d["goal"]["before"]
    assert d["goal"]["after"] == pytest.approx(sum((s["weight"] * s["after"]) ** 2 for s in d["sensitivities"]))
