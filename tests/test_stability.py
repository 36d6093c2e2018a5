"""clockwork stability: the Allan and time deviations of ticks (allantools),
their slopes for the power-law noises theory names, tick logs and bad input."""

import json
import math

import numpy as np
import pytest

from cwtest import FMU_DIR, assert_one_line_error, run_cli
from clockwork.analyses import stability as st

PERIOD = 2.0  # s
N_TICKS = 1 << 14


def _ticks_white_phase(rng) -> np.ndarray:
    """Ticks of an ideal clock read with white timing noise (1 ms rms)."""
    return PERIOD * np.arange(N_TICKS) + 1e-3 * rng.standard_normal(N_TICKS)


def _ticks_white_frequency(rng) -> np.ndarray:
    """Ticks whose periods are independent: white frequency noise (1e-4 relative rms)."""
    periods = PERIOD * (1.0 + 1e-4 * rng.standard_normal(N_TICKS - 1))
    return np.concatenate([[0.0], np.cumsum(periods)])


# The tau range of the slope fit: from 4 tau0 (past the first points, where a
# discrete series departs from the power law's asymptote) to 256 tau0 (N/64:
# still 64 spans of the longest tau).
TAU_RANGE = (4 * PERIOD, 256 * PERIOD)


@pytest.mark.parametrize("make, theory, tdev_theory, alpha", [(_ticks_white_phase, -1.0, -0.5, 2),
                                                              (_ticks_white_frequency, -0.5, 0.5, 0)],
                         ids=["white-phase", "white-frequency"])
def test_slopes_of_power_law_noises(make, theory, tdev_theory, alpha):
    r = st.allan(make(np.random.default_rng(20260412)))
    c = r["columns"]
    slope, se = st.log_slope(c["tau_s"], c["oadev"], c["oadev_lo"], c["oadev_hi"], TAU_RANGE)
    # three standard errors of the slope, from the estimator's own one-sigma intervals at the ends
    assert abs(slope - theory) < 3 * se, (slope, se)
    assert se < 0.1  # and the test has power: the intervals are narrow enough to tell -1 from -1/2
    # the time deviation, tau MDEV / sqrt(3): MDEV falls as tau^-3/2 for white phase noise and as
    # tau^-1/2 for white frequency noise, so TDEV goes as tau^-1/2 and tau^+1/2
    t_slope, t_se = st.log_slope(c["tau_s"], c["tdev_s"], c["tdev_lo_s"], c["tdev_hi_s"], TAU_RANGE)
    assert abs(t_slope - tdev_theory) < 3 * t_se, (t_slope, t_se)
    # the noise type identified where enough data remain
    assert c["noise_alpha"][2] == alpha
    for k in range(len(c["tau_s"])):
        assert c["oadev_lo"][k] < c["oadev"][k] < c["oadev_hi"][k]
        assert c["tdev_lo_s"][k] < c["tdev_s"][k] < c["tdev_hi_s"][k]


def test_white_frequency_level():
    """The level too: white frequency noise of relative rms s has ADEV(tau0) = s."""
    c = st.allan(_ticks_white_frequency(np.random.default_rng(7)))["columns"]
    a, lo, hi = c["oadev"][0], c["oadev_lo"][0], c["oadev_hi"][0]
    assert abs(a / 1e-4 - 1) < 3 * 0.5 * (hi - lo) / a  # three of its one-sigma half-widths


def test_a_constant_rate_drops_out():
    """A clock that runs fast by a constant amount has the same deviations."""
    rng = np.random.default_rng(3)
    t = _ticks_white_frequency(rng)
    a = st.allan(t)["columns"]["oadev"]
    b = st.allan(t * (1 + 1e-3))["columns"]["oadev"]
    np.testing.assert_allclose(a, b, rtol=2e-3)


def _write_log(path, text):
    path.write_text(text)
    return path


def test_tick_log_to_files(tmp_path, capsys):
    rng = np.random.default_rng(11)
    t = _ticks_white_frequency(rng)[:2000]
    log = _write_log(tmp_path / "log.csv", "# a timer's export\nn;time [ms];note\n" +
                     "".join(f"{i};{float(x) * 1000!r};ok\n" for i, x in enumerate(t)))
    rc, out, err = run_cli(capsys, ["stability", "--data", log, "--out", tmp_path / "o"])
    assert rc == 0, err
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert s["stability"]["ticks"] == 2000
    assert abs(s["stability"]["mean_period_s"] - PERIOD) < 1e-3
    assert sorted(s["files"]) == ["stability.csv", "stability.png", "summary.json"]
    head = (tmp_path / "o" / "stability.csv").read_text().splitlines()[0]
    assert head.startswith("tau_s,m,oadev,oadev_lo,oadev_hi,tdev_s")
    # the same from a header-less file in seconds
    log2 = _write_log(tmp_path / "bare.csv", "".join(f"{float(x)!r}\n" for x in t))
    rc, _, err = run_cli(capsys, ["stability", "--data", log2, "--out", tmp_path / "o2"])
    assert rc == 0, err
    s2 = json.loads((tmp_path / "o2" / "summary.json").read_text())
    np.testing.assert_allclose(s2["stability"]["columns"]["oadev"], s["stability"]["columns"]["oadev"], rtol=1e-9)


@pytest.mark.parametrize("text, needles", [
    ("time\n" + "".join(f"{i}\n" for i in range(30)) + "29\n", ["line 32", "increase"]),
    ("time\n" + "".join(f"{i}\n" for i in range(30, 0, -1)), ["line 3", "increase"]),
    ("time\n" + "".join(f"{i}\n" for i in range(5)), ["5 ticks", f"at least {st.MIN_TICKS}"]),
    ("time\n" + "".join(f"{i}\n" for i in range(10)) + "ten\n", ["line 12", "column time", "'ten'"]),
    ("time\n" + "".join(f"{i}\n" for i in range(20)) + "nan\n", ["line 22", "number"]),
    ("a,b\n1,2\n", ["no tick-time column", "a, b"]),
    ("time [fortnights]\n1\n", ["time unit"]),
    ("", ["no ticks"]),
], ids=["repeated", "decreasing", "too-few", "text", "nan", "no-column", "unit", "empty"])
def test_bad_tick_logs(tmp_path, capsys, text, needles):
    log = _write_log(tmp_path / "log.csv", text)
    out = tmp_path / "o"
    rc, _, err = run_cli(capsys, ["stability", "--data", log, "--out", out])
    assert_one_line_error(rc, err, str(log), *needles)
    assert not out.exists() or not any(out.iterdir())


def test_bad_sources(tmp_path, capsys):
    rc, _, err = run_cli(capsys, ["stability", "--out", tmp_path / "o"])
    assert_one_line_error(rc, err, "one of them")
    (tmp_path / "run").mkdir()
    rc, _, err = run_cli(capsys, ["stability", tmp_path / "run", "--out", tmp_path / "o"])
    assert_one_line_error(rc, err, "no ticks.csv")
    rc, _, err = run_cli(capsys, ["stability", "--data", tmp_path / "nothing.csv", "--out", tmp_path / "o"])
    assert_one_line_error(rc, err, "nothing.csv", "no such file")
    rc, _, err = run_cli(capsys, ["stability", "--data", tmp_path, "--out", tmp_path / "o"])
    assert_one_line_error(rc, err, "directory")


def test_hoyng_noisy_clock_gives_a_curve(tmp_path, capsys, monkeypatch):
    """Hoyng's clock with torque noise from the start (Fig. 6's, shortened):
    a scene's ticks, run here, give an Allan curve with intervals."""
    monkeypatch.setenv("CLOCKWORK_FMU_DIR", str(FMU_DIR))
    periods = 600
    stop = periods * 2 * math.pi
    rc, out, err = run_cli(capsys, ["stability", "hoyng_fig6", "--out", tmp_path / "o",
                                    "--set", f"experiment.stop={stop!r}", "--set", "escapement.noise_start=0"])
    assert rc == 0, err
    s = json.loads((tmp_path / "o" / "summary.json").read_text())["stability"]
    assert s["ticks"] >= periods - 2
    c = s["columns"]
    assert len(c["tau_s"]) >= 5 and all(x > 0 for x in c["oadev"])
    assert all(lo < a < hi for lo, a, hi in zip(c["oadev_lo"], c["oadev"], c["oadev_hi"]))


@pytest.mark.parametrize("stop, drawn", [(40, True), (10, False)], ids=["enough-ticks", "too-few"])
def test_a_run_that_asks_for_the_stability_plot(tmp_path, capsys, monkeypatch, stop, drawn):
    """A scene's run that records ticks and lists [[plot]] kind = "stability"
    writes stability.csv, summary.json's stability and the plot; with too
    few ticks, a note instead, and the plot is not drawn."""
    from cwtest import CLOCK_SCENE

    monkeypatch.setenv("CLOCKWORK_FMU_DIR", str(FMU_DIR))
    scene = tmp_path / "s.toml"
    scene.write_text(CLOCK_SCENE.format(stop=stop, sweep='[[plot]]\nkind = "stability"\nfile = "allan.png"\n'))
    rc, _, err = run_cli(capsys, ["run", scene, "--out", tmp_path / "o", "--no-progress"])
    assert rc == 0, err
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert sorted(p.name for p in (tmp_path / "o").iterdir()) == sorted(s["files"])
    if drawn:
        assert {"stability.csv", "allan.png", "ticks.csv"} <= set(s["files"])
        assert s["stability"]["ticks"] == s["result"]["ticks"] >= st.MIN_TICKS
        assert len(s["stability"]["columns"]["oadev"]) >= 2
        # the run's directory as a source gives the same numbers from its ticks.csv
        rc, _, err = run_cli(capsys, ["stability", tmp_path / "o", "--out", tmp_path / "o2"])
        assert rc == 0, err
        again = json.loads((tmp_path / "o2" / "summary.json").read_text())["stability"]
        np.testing.assert_allclose(again["columns"]["oadev"], s["stability"]["columns"]["oadev"], rtol=1e-9)
    else:
        assert "stability.csv" not in s["files"] and "allan.png" not in s["files"]
        assert "fewer than" in s["stability"]["note"]
