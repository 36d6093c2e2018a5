"""Ziemkiewicz Figs. 1-7: the scenes at reduced size against the paper and theory.

Each test runs a few points of a scene in scenarios/ through the same
analysis code as `clockwork run`, and asserts a number of the paper (with
the tolerance and its reason next to it), an exact analytic value, or the
monolithic scipy reference (clockwork.physics.reference). Where our result
disagrees with the paper, the test pins our number and says so; the scene
descriptions explain why.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from cwtest import FMU_DIR, fmu_file
from clockwork.physics import analytic, reference
from clockwork.analyses import ziemkiewicz as z
from clockwork.results.plots import ziemkiewicz as zplots
from clockwork.results.headlines import HEADLINES, headlines_for
from clockwork.run import run_point
from clockwork.run import load_scene

SCENES = Path(__file__).resolve().parents[2] / "scenarios"
DAY = analytic.SECONDS_PER_DAY
DEG = math.pi / 180.0


@pytest.fixture(autouse=True)
def _fmus(monkeypatch):
    fmu_file("Pendulum")
    monkeypatch.setenv("CLOCKWORK_FMU_DIR", str(FMU_DIR))


def scene(stem: str, *overrides: str):
    return load_scene(SCENES / f"ziemkiewicz_{stem}.toml", list(overrides))


def run(sc, **values) -> dict:
    """One point: values as {"instance.variable": SI value}."""
    point = {tuple(k.split(".", 1)): v for k, v in values.items()}
    return run_point(sc, point)


ALL = ["fig1", "fig2a", "fig2b", "fig2c", "fig3", "fig4a", "fig4b", "fig4c", "fig5", "fig6", "fig7a", "fig7b",
       "fig7c"]


@pytest.mark.parametrize("stem", ALL)
def test_scene_loads_and_names_its_figure(stem):
    sc = scene(stem)
    fig = stem[3:]
    assert sc.reproduces == f"Ziemkiewicz Fig. {fig[0]}" + (f"({fig[1]})" if len(fig) > 1 else "")
    assert sc.path.stem in HEADLINES
    assert "DESCRIPTION" not in (sc.description or "")


# -- Fig. 1 ----------------------------------------------------------------------


def test_fig1_free_period_equals_agm():
    """Period from the FMU's ticks equals T0/AGM(1, cos(A/2)) to 1e-10 (the brief's goal;
    observed ~1e-13 with rtol = 1e-12), at small, medium and large amplitude."""
    sc = scene("fig1")
    results = [run(sc, **{"pendulum.phi_start": a * DEG}) for a in (2.0, 30.0, 90.0)]
    for r in results:
        res = r["result"]
        assert abs(res["rel_diff_agm"]) < 1e-10, res
        assert res["period_agm_s"] == analytic.exact_period(res["amplitude_deg"] * DEG, 1.0, 9.81)
    # Eq. (2) to first order falls below the AGM by ~(3/8)^2 k^4: visible at 90 deg.
    assert results[-1]["result"]["rel_diff_eq2_first_order"] < -0.04
    hl = headlines_for(sc, {}, results)
    assert hl[0]["ours"] < 1e-10


# -- Fig. 2 ----------------------------------------------------------------------


def test_fig2a_symmetric_window_escapement_error():
    """Window (-2, 2) deg: E_E is zero to first order. Paper: |E_E| ~ 0.01 s/day (its
    noise). Ours is deterministic: |E_E| < 0.01 s/day from A ~ 6 deg up, but
    -0.04 s/day at 2.65 deg, and the monolithic reference has the same E_T there
    to 1e-4 s/day, so it is the model's second-order physics, not numerics."""
    sc = scene("fig2a")
    big = run(sc, **{"escapement.torque": 0.006})["result"]  # A ~ 6.7 deg
    assert big["amplitude_deg"] > 6.0
    assert abs(big["E_E_s_per_day"]) < 0.01
    small = run(sc, **{"escapement.torque": 0.000944})["result"]  # A ~ 2.65 deg
    ref = reference.steady_state(reference.ClockParams(escapement="chronometer", torque=0.000944,
                                                       alpha_m1=-2 * DEG, alpha_m2=2 * DEG, Q=1000.0))
    assert abs(small["E_T_s_per_day"] - ref.E_T * DAY) < 1e-4
    assert -0.06 < small["E_E_s_per_day"] < -0.02  # the documented deviation from the paper's ~0.01
    # E_C at the right turning amplitude instead of the mean moves E_E by more than the effect.
    assert small["E_E_right_s_per_day"] < small["E_E_s_per_day"] - 0.01


def test_fig2b_and_2c_signs_minimum_and_stall():
    """Pushing before the lowest point speeds the clock (E_E < 0), after it slows
    it (E_E > 0, and E_T(A) has a minimum); |E_E| falls with A; below the
    threshold torque pi m g L alpha_m2 / Q = 0.1076 N.cm (from the energy balance
    at A = alpha_m2 = 2 deg) no orbit reaches beyond the window."""
    before, after = scene("fig2b"), scene("fig2c")
    torques = [0.0015, 0.002, 0.0025, 0.003, 0.004, 0.01]
    rb = [run(before, **{"escapement.torque": m})["result"] for m in torques]
    ra = [run(after, **{"escapement.torque": m})["result"] for m in torques]
    assert all(r["E_E_s_per_day"] < 0 for r in rb)
    assert all(r["E_E_s_per_day"] > 0 for r in ra)
    assert np.all(np.diff([abs(r["E_E_s_per_day"]) for r in rb]) < 0)
    assert np.all(np.diff([r["E_E_s_per_day"] for r in ra]) < 0)
    et_a = [r["E_T_s_per_day"] for r in ra]
    k = int(np.argmin(et_a))
    assert 0 < k < len(et_a) - 1  # an interior minimum
    et_b = [r["E_T_s_per_day"] for r in rb]
    assert np.all(np.diff(et_b) > 0)  # monotonic: no minimum
    threshold = math.pi * 9.81 * 2 * DEG / 1000.0
    stalled = run(after, **{"escapement.torque": 0.97 * threshold})["result"]
    assert stalled["stalled"] and stalled["omitted"]
    ok = run(after, **{"escapement.torque": 1.03 * threshold})["result"]
    assert not ok["stalled"] and ok["amplitude_deg"] > 2.0
    inside = run(before, **{"escapement.torque": 0.0005})["result"]
    assert inside["turns_inside_window"] and inside["omitted"]
    hl = headlines_for(after, {}, [{"result": r, "point": {}} for r in ra])
    assert hl[0]["ours"] == "positive" and hl[1]["ours"].startswith("A = ")


# -- Fig. 3 ----------------------------------------------------------------------


def test_fig3_steady_orbit_and_recoil():
    """Amplitude exactly 5 deg; recoil begins where |phi| = alpha_r = 4 deg (a located
    switch: 1e-7 deg); its share of the period is arccos(4/5)/pi = 0.2048 for a
    sinusoid, within 0.005 (two 5 ms samples per period round the recoil end);
    the torque within 1 % of Eq. (B6) (an energy balance over a sinusoidal swing)."""
    sc = scene("fig3")
    r = run(sc)
    res, s = r["result"], r["series"]
    assert abs(res["amplitude_deg"] - 5.0) < 1e-8
    assert res["orbit_closure_rad_per_s"] < 1e-9 and res["orbit_closure_phi_rad"] < 1e-9  # started on the orbit
    phi = np.degrees(np.asarray(s["pendulum.phi"]))
    rec = np.asarray(s["recoil"]) > 0.5
    starts = np.flatnonzero(rec[1:] & ~rec[:-1]) + 1
    assert len(starts) >= 3
    assert np.all(np.abs(np.abs(phi[starts]) - 4.0) < 1e-7)
    assert abs(res["recoil_fraction"] - math.acos(0.8) / math.pi) < 0.005
    b6 = analytic.grasshopper_torque_for_amplitude(5 * DEG, 4 * DEG, 1000.0, 1.0, 1.0, 9.81)
    assert abs(res["torque_Nm"] / b6 - 1) < 0.01
    # The torque opposes the motion exactly in the shaded phases.
    tau, w = np.asarray(s["escapement.tau"]), np.asarray(s["pendulum.w"])
    assert np.all((tau * w < 0) == rec)


# -- Fig. 4 ----------------------------------------------------------------------


@pytest.fixture(scope="module")
def fig4_clocks():
    return {p: scene(f"fig4{p}") for p in "abc"}


def _ee_at(sc, amplitude_deg):
    with z.Clock(sc, {}) as c:
        st = c.torque_for_amplitude(amplitude_deg * DEG)
    return st


def test_fig4_escapement_error_at_5_deg_and_ratios(fig4_clocks):
    """E_E(5 deg) in (a) = -100 s/day (paper, read off its figure: +-10 s/day).
    (a)/(c) = 2 (paper; Eq. B7 exactly): within 0.02, the Q-independence of the
    orbit shape beyond B7 being small. (a)/(b): paper ~3/2; ours lies between 3/2
    and B7's 3(A-2)/(2(A-3)) and tends to 3/2 as A grows (1.72, 1.57, 1.53)."""
    ea = {a: _ee_at(fig4_clocks["a"], a).E_E * DAY for a in (5.0, 8.0, 11.0)}
    eb = {a: _ee_at(fig4_clocks["b"], a).E_E * DAY for a in (5.0, 8.0, 11.0)}
    ec = {a: _ee_at(fig4_clocks["c"], a).E_E * DAY for a in (5.0, 11.0)}
    assert abs(ea[5.0] + 100.0) < 10.0
    for a, e in ec.items():
        assert abs(ea[a] / e - 2.0) < 0.02
    ratios = [ea[a] / eb[a] for a in (5.0, 8.0, 11.0)]
    for a, q in zip((5.0, 8.0, 11.0), ratios):
        assert 1.5 < q < 3 * (a - 2) / (2 * (a - 3))
    assert ratios[0] > ratios[1] > ratios[2]
    assert ratios[2] - 1.5 < 0.05


@pytest.mark.parametrize("panel,paper_deg", [("a", 7.0), ("b", 5.0), ("c", 4.0)])
def test_fig4_minimum_of_total_error(fig4_clocks, panel, paper_deg):
    """The E_T minimum is near 7, 5 and 4 deg (paper, '~': +-1 deg)."""
    with z.Clock(fig4_clocks[panel], {}) as c:
        st = c.optimal()
    assert abs(math.degrees(st.amplitude) - paper_deg) < 1.0


def test_fig4c_torque_insensitivity(fig4_clocks):
    """Paper: 0.04 to 0.06 N.cm give about 2 s/day of variation. Ours is 0.37 s/day
    (documented disagreement, see the scene): pinned below 1 s/day."""
    with z.Clock(fig4_clocks["c"], {}) as c:
        ets = []
        for M in (0.0004, 0.00047, 0.0005, 0.00055, 0.0006):
            c.set_torque(M)
            ets.append(c.steady().E_T * DAY)
    assert 0.2 < max(ets) - min(ets) < 1.0


def test_fig4c_matches_monolithic_reference(fig4_clocks):
    """The scenes' shooting agrees with scipy DOP853 shooting to 1e-3 s/day at Q = 2000."""
    res = run(fig4_clocks["c"], **{"escapement.torque": 0.0005})["result"]
    ref = reference.steady_state(reference.ClockParams(torque=0.0005, phi_r=2 * DEG, Q=2000.0))
    assert abs(res["E_T_s_per_day"] - ref.E_T * DAY) < 1e-3


def test_fig4a_overrides_reach_the_analysis():
    """`--set escapement.phi_r="2.5 deg" --set pendulum.Q=1500` on the 4(a) scene: B7
    beside each point uses the overridden values, and headlines say so."""
    sc = scene("fig4a", 'escapement.phi_r="2.5 deg"', "pendulum.Q=1500")
    r = run(sc, **{"escapement.torque": 0.003})
    res = r["result"]
    assert not res["stalled"]
    b7 = analytic.escapement_error_B7(res["amplitude_deg"] * DEG, 2.5 * DEG, 1500.0) * DAY
    assert res["E_E_B7_s_per_day"] == pytest.approx(b7, rel=1e-12)
    hl = headlines_for(sc, {}, [run(sc, **{"escapement.torque": m}) for m in (0.0015, 0.002, 0.003)])
    assert all("--set" in h.get("note", "") for h in hl)


# -- Fig. 5 ----------------------------------------------------------------------


def test_fig5_operating_point_and_q_sensitivity():
    """At Q = 1000, M = 0.4 N.cm: -100 < E_T < -50 s/day (the paper's two contours).
    Q 800 -> 1200: 'of the order of 50 s/day' -> between 25 and 100 (ours: 70)."""
    sc = scene("fig5")
    e = {Q: run(sc, **{"escapement.torque": 0.004, "pendulum.Q": Q})["result"]["E_T_s_per_day"]
         for Q in (800.0, 1000.0, 1200.0)}
    assert -100.0 < e[1000.0] < -50.0
    assert 25.0 < e[1200.0] - e[800.0] < 100.0
    # Negative at low Q, positive at high Q (paper).
    assert run(sc, **{"escapement.torque": 0.004, "pendulum.Q": 400.0})["result"]["E_T_s_per_day"] < 0
    assert run(sc, **{"escapement.torque": 0.004, "pendulum.Q": 3000.0})["result"]["E_T_s_per_day"] > 0


def test_fig5_contour_plot_on_a_small_grid():
    sc = scene("fig5")
    results = [run(sc, **{"escapement.torque": m, "pendulum.Q": q})
               for q in (300.0, 1000.0, 3000.0) for m in (0.0005, 0.002, 0.01)]
    assert results[0]["result"]["stalled"]  # low torque, low Q: no orbit
    fig = zplots.plot_contour(sc, results, sc.plots[0])
    assert fig is not None and fig.axes[0].collections


# -- Fig. 6 ----------------------------------------------------------------------


@pytest.mark.parametrize("profile,c2", [(1, 0.0), (2, 0.0), (3, 0.0), (1, 0.0015)])
def test_fig6_profiles_and_drag_match_the_reference(profile, c2):
    """Profiles and quadratic drag at the scene's master settings (5 ms, two
    coupling iterations) within 0.15 s/day of the monolithic reference (measured
    <= 0.09: Harrison's end of recoil at w = 0 is not a located event)."""
    sc = scene("fig6")
    res = run(sc, **{"escapement.profile": profile, "drag.c2": c2, "escapement.torque": 0.004})["result"]
    ref = reference.steady_state(reference.ClockParams(torque=0.004, profile=profile, c2=c2))
    assert abs(res["E_T_s_per_day"] - ref.E_T * DAY) < 0.15
    assert abs(res["amplitude_deg"] - math.degrees(ref.amplitude)) < 2e-3


def test_fig6_largest_amplitude_and_profile_effects():
    """Constant torque at 1 N.cm: A = 12 deg (paper, read off: +-0.5 deg). The increasing
    profile lowers the amplitude, the decreasing one raises it (paper)."""
    sc = scene("fig6")
    amp = {p: run(sc, **{"escapement.profile": p, "escapement.torque": 0.01})["result"]["amplitude_deg"]
           for p in (0, 1, 2)}
    assert abs(amp[0] - 12.0) < 0.5
    assert amp[1] < amp[0] < amp[2]


def test_fig6_energy_balance_guess_is_close():
    """The shooting start from the profile-aware energy balance is within 5 % of the orbit."""
    sc = scene("fig6")
    for p in (0, 1, 2, 3):
        r = run(sc, **{"escapement.profile": p, "escapement.torque": 0.004})["result"]
        assert abs(r["energy_balance_amplitude_deg"] / r["amplitude_deg"] - 1) < 0.05, (p, r)


# -- Fig. 7 ----------------------------------------------------------------------


def _kick(stem, *extra):
    sc = scene(stem, 'experiment.start="1990 s"', 'experiment.stop="2060 s"', *extra)  # later --set wins
    return run(sc)


def test_fig7_zero_crossing_kick_changes_amplitude_by_g_dt2_over_2L():
    """A kick g' = 2 g for dt at phi = 0 changes the speed by (g/L) w dt^2/2, so
    dA/A = g dt^2/(2 L) = 4.905e-6 at any amplitude (within 2 %: relaxation during
    the first period, T/(Q/omega0) = 0.6 %, and O(A^2) terms). The paper's 0.04 %
    and 0.05 s are ~1e4 larger: documented in the scene."""
    r = _kick("fig7a")
    res, s = r["result"], r["series"]
    assert abs(res["phi_at_kick_deg"]) < 1e-6
    assert res["w_at_kick_rad_per_s"] > 0  # on its way to +A
    assert res["baseline_max_abs_dT_over_T"] < 1e-10
    expected = 9.81 * 1e-3 ** 2 / 2.0
    assert abs(res["max_abs_dA_deg"] / res["amplitude_deg"] / expected - 1) < 0.02
    assert np.nanmin(s["dA_deg"]) < 0  # the extra gravity slows the swing: A drops
    assert res["max_abs_dT_over_T"] < 1e-7


def test_fig7_turning_point_kick_shifts_the_phase_by_dt():
    """At a turning point the same kick advances the swing by ~dt: dT/T = -dt/T
    (within 2 %: the phase shift is dt (1 - O(dt^2 omega^2)) plus the small amplitude effect)."""
    r = _kick("fig7a", "analysis.kick_at=turning_point")
    res = r["result"]
    assert abs(res["w_at_kick_rad_per_s"]) < 1e-8
    expected = -1e-3 / res["stationary_period_s"]
    assert abs(res["max_dT_over_T_signed"] / expected - 1) < 0.02


def test_fig7_panels_order():
    """Paper: (b) changes the rate more than (a); (c) has less total error than (a)."""
    # 400 s after the kick: long enough for Q = 500's faster recovery to win
    # (totals ~ jump x Q/omega0: (c) 2.3e-8 x 160 s < (a) 1.7e-8 x 319 s).
    long = ('experiment.stop="2400 s"',)
    a, c = _kick("fig7a", *long)["result"], _kick("fig7c", *long)["result"]
    sc_b = scene("fig7b", 'experiment.start="1990 s"', 'experiment.stop="2060 s"', 'analysis.amplitude="13.39 deg"')
    b = run(sc_b)["result"]
    assert b["max_abs_dT_over_T"] > a["max_abs_dT_over_T"]
    assert abs(c["time_error_end_s"]) < abs(a["time_error_end_s"])
    hl = headlines_for(scene("fig7a"), {}, [_kick("fig7a")])
    assert hl[0]["ours"] == pytest.approx(6.6)
