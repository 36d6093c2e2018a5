"""clockwork fit: a clock's parameters recovered from measurements it did not make.

The measurements come from a hidden parameter set through the project's
independent integration of the same equations with scipy
(clockwork.physics.reference: DOP853 with its own event location, the
return map solved by brentq), never from the FMUs, with seeded Gaussian
noise; the fit (the FMUs, shot for their periodic orbits) must find the
hidden values within 3 sigma, with sigmas of a few percent at most.
"""

from __future__ import annotations

import math
import os

import numpy as np
import pytest

from cwtest import FMU_DIR, assert_one_line_error, fmu_file, run_cli
from clockwork.numbers import parse_json

# The hidden clock: Ziemkiewicz Fig. 4(a)'s (L = 1 m, m = 1 kg) with another Q and recoil angle.
TRUE_Q = 850.0
TRUE_PHI_R = math.radians(2.3)
TORQUES_NCM = (0.1, 0.2, 0.4, 0.7, 1.0)
SIGMA_AMPLITUDE_DEG = 0.05  # a timer's amplitude, to a twentieth of a degree
SIGMA_RATE = 0.2  # s/day


@pytest.fixture(autouse=True)
def _fmu_dir(monkeypatch):
    fmu_file("Pendulum")
    monkeypatch.setenv("CLOCKWORK_FMU_DIR", str(FMU_DIR))


@pytest.fixture(scope="module")
def truth():
    """(torque N.cm, amplitude deg, E_T s/day) of the hidden clock, noise-free and measured."""
    from clockwork.physics.reference import ClockParams, steady_state

    rng = np.random.default_rng(20261202)
    rows = []
    for t in TORQUES_NCM:
        s = steady_state(ClockParams(L=1.0, m=1.0, g=9.81, Q=TRUE_Q, torque=t / 100.0, phi_r=TRUE_PHI_R))
        amplitude = math.degrees(0.5 * (s.amplitude + s.amplitude_left))  # the analysis' mean of both turns
        rate = s.E_T * 86400.0
        rows.append((t, amplitude + rng.normal(0.0, SIGMA_AMPLITUDE_DEG), rate + rng.normal(0.0, SIGMA_RATE)))
    return rows


def _write(path, header, rows):
    path.write_text(",".join(header) + "\n" + "".join(",".join(f"{x!r}" if isinstance(x, float) else str(x)
                                                                 for x in r) + "\n" for r in rows))
    return path


def _summary(out):
    return parse_json((out / "summary.json").read_text())


def test_fit_recovers_the_hidden_clock(tmp_path, capsys, truth):
    data = _write(tmp_path / "timer.csv",
                  ["escapement.torque [N.cm]", "amplitude_deg", "sigma_amplitude_deg", "E_T_s_per_day",
                   "sigma_E_T_s_per_day"],
                  [(t, a, SIGMA_AMPLITUDE_DEG, r, SIGMA_RATE) for t, a, r in truth])
    out = tmp_path / "fit"
    rc, stdout, err = run_cli(capsys, ["fit", "ziemkiewicz_fig4a", "--data", data, "--free", "pendulum.Q=1000",
                                       "--free", "escapement.phi_r=2 deg", "--out", out])
    assert rc == 0, err
    s = _summary(out)  # strict JSON
    fit = s["fit"]
    for name, true in (("pendulum.Q", TRUE_Q), ("escapement.phi_r", TRUE_PHI_R)):
        p = fit["parameters"][name]
        assert p["identifiable"] and p["sigma"] > 0
        assert abs(p["value"] - true) < 3 * p["sigma"], (name, p, true)
        assert p["sigma"] < 0.05 * true, (name, p)  # useful: a few percent at most
    assert fit["parameters"]["escapement.phi_r"]["unit"] == "rad" and fit["parameters"]["pendulum.Q"]["unit"] is None
    corr = fit["correlation"]
    assert corr["pendulum.Q"]["pendulum.Q"] == pytest.approx(1.0)
    assert corr["pendulum.Q"]["escapement.phi_r"] == pytest.approx(corr["escapement.phi_r"]["pendulum.Q"])
    assert abs(corr["pendulum.Q"]["escapement.phi_r"]) < 1.0
    assert fit["dof"] == 2 * len(TORQUES_NCM) - 2
    assert fit["chi2"] == pytest.approx(sum(c["normalized"] ** 2 for r in fit["residuals"]
                                            for c in (r["amplitude_deg"], r["E_T_s_per_day"])))
    assert fit["chi2"] / fit["dof"] < 3.0  # the noise the data were given, not more
    assert len(fit["residuals"]) == len(TORQUES_NCM)
    first = fit["residuals"][0]
    assert first["parameters"] == {"escapement.torque": pytest.approx(TORQUES_NCM[0] / 100.0)}
    assert first["E_T_s_per_day"]["residual"] == pytest.approx(first["E_T_s_per_day"]["measured"]
                                                               - first["E_T_s_per_day"]["fitted"])
    assert not fit["sigma_scaled_by_residuals"]
    assert sorted(s["files"]) == ["fit.csv", "fit.png", "summary.json"]
    assert (out / "fit.png").stat().st_size > 10_000
    assert (out / "fit.csv").read_text().splitlines()[0].startswith("line,escapement.torque,amplitude_deg,")
    assert "pendulum.Q = " in stdout and "note" not in err


def test_timer_layout_without_sigmas(tmp_path, capsys, truth):
    """A timer's export: a time column, rate (s/day, positive when the clock gains) and amplitude; no
    uncertainties, so equal weights and the scale from the residuals."""
    data = _write(tmp_path / "microset.csv", ["Time", "escapement.torque [N.cm]", "Rate [s/day]", "Amplitude"],
                  [(f"2026-12-0{i + 1}T12:00", t, -r, a) for i, (t, a, r) in enumerate(truth)])
    out = tmp_path / "fit"
    rc, _, err = run_cli(capsys, ["fit", "ziemkiewicz_fig4a", "--data", data, "--free", "escapement.phi_r=2 deg",
                                  "--set", f"pendulum.Q={TRUE_Q}", "--out", out])
    assert rc == 0, err
    fit = _summary(out)["fit"]
    p = fit["parameters"]["escapement.phi_r"]
    assert fit["sigma_scaled_by_residuals"]
    assert abs(p["value"] - TRUE_PHI_R) < 3 * p["sigma"] and p["sigma"] < 0.05 * TRUE_PHI_R, p
    row = fit["residuals"][0]
    assert row["label"] == "2026-12-01T12:00"
    assert row["E_T_s_per_day"]["measured"] == pytest.approx(truth[0][2])  # the rate's sign turned into E_T's
    assert row["E_T_s_per_day"]["sigma"] is None


def test_a_parameter_the_data_cannot_see_is_named_not_fitted(tmp_path, capsys, truth):
    """The steady state depends on the bob's mass and the pendulum's length only through
    torque / (m g L): m and L together are not identifiable."""
    data = _write(tmp_path / "d.csv", ["escapement.torque [N.cm]", "amplitude_deg", "E_T_s_per_day"], truth)
    out = tmp_path / "fit"
    rc, stdout, err = run_cli(capsys, ["fit", "ziemkiewicz_fig4a", "--data", data, "--free", "pendulum.m",
                                       "--free", "pendulum.L", "--set", f"pendulum.Q={TRUE_Q}",
                                       "--set", f"escapement.phi_r={TRUE_PHI_R}", "--out", out])
    assert rc == 0, err
    notes = [ln for ln in err.splitlines() if ln.startswith("clockwork: note: ")]
    assert len(notes) == 1 and "pendulum.m" in notes[0] and "pendulum.L" in notes[0], err
    raw = (out / "summary.json").read_text()
    assert "Infinity" not in raw and "NaN" not in raw
    fit = parse_json(raw)["fit"]
    for name in ("pendulum.m", "pendulum.L"):
        assert fit["parameters"][name]["identifiable"] is False
        assert fit["parameters"][name]["sigma"] is None  # infinite: strict JSON writes it as null
    assert fit["correlation"]["pendulum.m"]["pendulum.L"] is None
    assert "not identifiable" in stdout


def test_identify_names_the_parameters_of_a_singular_direction():
    from clockwork.run.fit import identify

    rng = np.random.default_rng(3)
    a, c = rng.normal(size=8), rng.normal(size=8)
    jac = np.stack([a, 2.0 * a, c], axis=1)  # the first two move the residuals only together
    cov, unidentified, relative = identify(jac, np.ones(3))
    assert unidentified == [0, 1]
    assert relative[-1] < 1e-12 and relative[0] == 1.0
    reduced = np.stack([a, c], axis=1)  # the problem in the combination the data see, and the third
    assert cov[2, 2] == pytest.approx(np.linalg.inv(reduced.T @ reduced)[1, 1], rel=1e-9)
    assert np.isnan(cov[0, 0]) and np.isnan(cov[0, 2])
    cov, unidentified, _ = identify(np.stack([a, np.zeros(8)], axis=1), np.ones(2))
    assert unidentified == [1]  # a parameter that moves nothing


def test_timer_pressure_and_temperature_set_the_air(tmp_path):
    from clockwork.run.catalog import load_scene
    from clockwork.run.fit_data import read_data

    scene = load_scene("air_barometric_ziemkiewicz")
    data = read_data(scene, _write(tmp_path / "t.csv", ["date", "pressure", "temperature [K]", "rate"],
                                   [("d1", 1013.25, 293.15, 1.5), ("d2", 990.5, 300.0, "")]))
    assert data.settings[0][("air", "pressure")] == pytest.approx(101325.0)  # hPa, a barometer's unit
    assert data.settings[1][("air", "temperature")] == 300.0
    assert data.settings[1][("pendulum", "temperature")] == 300.0  # the room's: the rod's too, where unconnected
    assert data.measured["E_T_s_per_day"][0] == -1.5  # a timer's rate is positive when the clock gains
    assert math.isnan(data.measured["E_T_s_per_day"][1])  # not measured that day
    assert data.labels == ["d1", "d2"]
    data = read_data(scene, _write(tmp_path / "c.csv", ["temperature", "E_T_s_per_day"], [(20.0, 1.0)]))
    assert data.settings[0][("air", "temperature")] == pytest.approx(293.15)  # degC without a bracket


BAD_DATA = [
    ("escapement.torque [N.cm],amplitude_deg,bogus\n0.1,3.8,1\n", "column bogus", "names no settable parameter"),
    ("escapement.torque [N.cm],amplitude_deg\n0.1,abc\n", "line 2, column amplitude_deg", "expected a number"),
    ("escapement.torque [N.cm],amplitude_deg\n0.1,nan\n", "line 2, column amplitude_deg", "expected a number"),
    ("escapement.torque [N.cm],amplitude_deg\n", "", "no data rows"),
    ("", "", "empty"),
    ("escapement.torque [furlong],amplitude_deg\n0.1,3\n", "column escapement.torque [furlong]", "a unit of N.m"),
    ("escapement.torque [N.cm],amplitude_deg\n5e6,3\n", "line 2, column escapement.torque", "in its range"),
    ("escapement.torque [N.cm],amplitude_deg,sigma_E_T_s_per_day\n0.1,3,1\n", "column sigma_E_T_s_per_day",
     "which no column of this file measures"),
    ("escapement.torque [N.cm],amplitude_deg,sigma_amplitude_deg\n0.1,3,0\n", "column sigma_amplitude_deg", "> 0"),
    ("escapement.torque [N.cm],amplitude_deg,E_T_s_per_day,sigma_amplitude_deg\n0.1,3,1,1\n",
     "column E_T_s_per_day", "has no sigma_ column"),
    ("escapement.torque [N.cm],amplitude_deg\n0.1,3,4\n", "line 2", "3 values for 2 columns"),
    ("escapement.torque,escapement.phi_r\n0.1,3\n", "", "no measured column"),
    ("pendulum.phi,amplitude_deg\n0.1,3\n", "column pendulum.phi", "an output, not a parameter"),
    ("pendulum.tau_escapement,amplitude_deg\n0.1,3\n", "column pendulum.tau_escapement", "connected input"),
    ("escapement.torque [N.cm],amplitude_deg [furlong]\n0.1,3\n", "column amplitude_deg [furlong]", "unit of"),
    ("escapement.torque,amplitude_deg,amplitude_deg\n0.1,3,3\n", "column amplitude_deg", "given twice"),
    ("escapement.torque [N.cm],amplitude_deg\n0.1,\n", "", "no measured value"),
    ("escapement.torque [N.cm],amplitude_deg\n,3\n", "line 2, column escapement.torque", "expected a number"),
    ("pressure,amplitude_deg\n1000,3\n", "column pressure", "no settable pressure"),
]


@pytest.mark.parametrize("text,where,what", BAD_DATA)
def test_bad_data_is_one_line_and_writes_nothing(tmp_path, capsys, text, where, what):
    data = tmp_path / "bad.csv"
    data.write_text(text)
    out = tmp_path / "fit"
    rc, _, err = run_cli(capsys, ["fit", "ziemkiewicz_fig4a", "--data", data, "--free", "pendulum.Q", "--out", out])
    assert_one_line_error(rc, err, str(data), where, what)
    assert not out.exists()


@pytest.mark.parametrize("free,what", [
    (["pendulum.QQ"], "names no Real parameter of the scene (did you mean pendulum.Q?)"),
    (["pendulum.tau_external"], "declares no range"),
    (["escapement.noise_start"], "declares no range"),
    (["escapement.torque"], "set row by row by the data file's column"),
    (["pendulum.Q=-5"], "outside pendulum.Q's range"),
    (["pendulum.Q=abc"], "expected a guess"),
    (["escapement.phi_r=2 furlong"], "a unit of rad"),
    (["pendulum.Q", "pendulum.Q"], "freed twice"),
    (["escapement.profile"], "only Real parameters"),
    ([], "expected at least one --free"),
])
def test_bad_free_parameters(tmp_path, capsys, free, what):
    data = _write(tmp_path / "d.csv", ["escapement.torque [N.cm]", "amplitude_deg"], [(0.1, 3.8), (0.4, 7.6)])
    out = tmp_path / "fit"
    argv = ["fit", "ziemkiewicz_fig4a", "--data", data, "--out", out]
    for f in free:
        argv += ["--free", f]
    rc, _, err = run_cli(capsys, argv)
    assert_one_line_error(rc, err, what)
    if free:
        assert f"--free {free[-1 if 'twice' in what else 0]}" in err
    assert not out.exists()


def test_too_few_measurements_for_the_free_parameters(tmp_path, capsys):
    data = _write(tmp_path / "d.csv", ["escapement.torque [N.cm]", "amplitude_deg"], [(0.4, 7.6)])
    rc, _, err = run_cli(capsys, ["fit", "ziemkiewicz_fig4a", "--data", data, "--free", "pendulum.Q",
                                  "--out", tmp_path / "fit"])
    assert_one_line_error(rc, err, str(data), "1 measured value for 1 free parameter")
    assert not (tmp_path / "fit").exists()


def test_a_time_series_scene_offers_its_own_result_columns(tmp_path, capsys):
    data = _write(tmp_path / "d.csv", ["pendulum.Q", "amplitude_deg"], [(500, 3.0), (600, 3.1)])
    rc, _, err = run_cli(capsys, ["fit", "core_grasshopper", "--data", data, "--free", "pendulum.L",
                                  "--out", tmp_path / "fit"])
    assert_one_line_error(rc, err, "column amplitude_deg", "names no settable parameter", "last_amplitude_deg")


def test_a_fit_that_does_not_converge_fails_with_one_line(tmp_path, capsys, monkeypatch, truth):
    from clockwork.run import fit

    monkeypatch.setattr(fit, "MAX_EVALUATIONS_PER_PARAMETER", 1)
    data = _write(tmp_path / "d.csv", ["escapement.torque [N.cm]", "amplitude_deg"], [(t, a) for t, a, _ in truth])
    out = tmp_path / "fit"
    out.mkdir()
    rc, _, err = run_cli(capsys, ["fit", "ziemkiewicz_fig4a", "--data", data, "--free", "pendulum.Q=300",
                                  "--out", out])
    assert_one_line_error(rc, err, "the fit did not converge", "pendulum.Q = ", code=1)
    assert os.listdir(out) == []  # nothing half-written, no staging folder left


def test_a_data_file_that_is_no_regular_file_is_refused_unread(tmp_path, capsys):
    fifo = tmp_path / "log.csv"
    os.mkfifo(fifo)  # no writer: an open() without O_NONBLOCK would wait for ever
    rc, _, err = run_cli(capsys, ["fit", "ziemkiewicz_fig4a", "--data", fifo, "--free", "pendulum.Q",
                                  "--out", tmp_path / "fit"])
    assert_one_line_error(rc, err, str(fifo), "is a FIFO (named pipe), expected a CSV data file")


def test_a_cached_point_of_the_same_parameters_under_another_label_is_reused(tmp_path, capsys, monkeypatch):
    """The cache's key hashes the effective parameters: a row that sets escapement.torque to the scene's own
    value is the point a run that leaves it alone stored. It is reused, without a warning about its label."""
    from clockwork.run import batch
    from clockwork.run.catalog import load_scene

    monkeypatch.setenv("CLOCKWORK_CACHE", str(tmp_path / "cache"))
    scene = load_scene("ziemkiewicz_fig4a")
    first = batch.run_points(scene, [{("pendulum", "Q"): 1000.0}])[0]
    calls = []
    monkeypatch.setattr(batch, "run_point", lambda *a, **k: calls.append(a) or {})
    again = batch.run_points(scene, [{("escapement", "torque"): 0.004}])[0]
    assert calls == [] and capsys.readouterr().err == ""
    assert again["point"] == {"escapement.torque": 0.004}
    assert again["result"] == first["result"]


def test_units_in_brackets_are_converted(tmp_path):
    from clockwork.run.catalog import load_scene
    from clockwork.run.fit_data import read_data

    scene = load_scene("ziemkiewicz_fig4a")
    data = read_data(scene, _write(tmp_path / "u.csv", ["\ufeffescapement.torque [N.mm]", "escapement.phi_r [deg]",
                                                        "amplitude_deg [rad]", "sigma_amplitude_deg [mrad]",
                                                        "E_T_s_per_day", "sigma_E_T_s_per_day"],
                                   [(4.0, 2.5, 0.1, 1.0, -3.0, 0.5)]))
    assert data.settings[0] == {("escapement", "torque"): pytest.approx(0.004),
                                ("escapement", "phi_r"): pytest.approx(math.radians(2.5))}
    assert data.measured["amplitude_deg"][0] == pytest.approx(math.degrees(0.1))
    assert data.sigma["amplitude_deg"][0] == pytest.approx(math.degrees(1e-3))
    assert data.measured["E_T_s_per_day"][0] == -3.0 and data.sigma["E_T_s_per_day"][0] == 0.5
