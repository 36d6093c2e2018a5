"""Headlines of the chaos scenes (Ziemkiewicz Figs. 8-11)."""

from __future__ import annotations

from ...analyses.context import find_component, parameters
from ...physics.analytic import SECONDS_PER_DAY as DAY
from .registry import entry, headline


def _g(x) -> str:
    return "n/a" if x is None else f"{x:.3g}"


def _res(summary):
    return summary.get("result") or {}


def _points(summary):
    return [p for p in summary.get("points", []) if "error" not in p]


@headline("ziemkiewicz_fig8a")
def _h8a(scene, summary, results):
    r = _res(summary)
    return [
        entry("limit-cycle amplitude", "~7", r["limit_cycle_amplitude_deg"], "deg",
              note=f"Q = {r['Q']:g}, torque {r['torque_Ncm']:g} N.cm, start at {r['amplitude_start_deg']:g} deg"),
        entry("|phi| where the torque switches (portrait kinks)", "alpha_r = 2", r["switch_abs_phi_deg_mean"], "deg"),
    ]


@headline("ziemkiewicz_fig8b", "ziemkiewicz_fig9a")
def _h8b(scene, summary, results):
    r = _res(summary)
    return [
        entry("max |alpha_2|", "~1 (Sec. VIII: 'for alpha_2 ~ 1 degree')", r["a2_max_abs_deg"], "deg",
              note=f"quasi-static -C2 a1/omega02^2 alone: "
                   f"{abs(r['forced_gain_linear']) * r['a1_max_abs_deg']:.3g} deg"),
        entry("share of time with sign(alpha_2) = sign(M_F)", "square wave switching with the torque",
              r["sign_a2_equals_sign_tau"]),
        entry("Duffing / linear stiffness at max |alpha_2|", "Duffing dominated (chaotic)", r["duffing_over_linear"]),
    ]


@headline("ziemkiewicz_fig9b")
def _h9b(scene, summary, results):
    return [entry(f"Poincare ring width, C2 = {p['C2']:g}", "regular" if p["C2"] < 2.45 else "chaotic, fractal-like",
                  p.get("ring_width"),
                  note=f"{p.get('n_points')} points; occupied fraction {p.get('occupied_fraction', 0):.3g}; "
                       f"share with alpha_2 > 0: {p.get('positive_fraction', 0):.2f}")
            for p in _points(summary)]


@headline("ziemkiewicz_fig10a")
def _h10a(scene, summary, results):
    r = _res(summary)
    params = parameters(scene)
    pp, vib = params[find_component(scene, "Pendulum")], params[find_component(scene, "MechanismVibration")]
    # A mode much faster than the pendulum follows it quasi-statically: a2 = -C2 a1 / omega02^2
    # stiffens the pendulum by C1 C2 / omega02^2, and the rate by half that over omega01^2.
    static = vib["C1"] * vib["C2"] / (2 * (pp["g"] / pp["L"]) * vib["omega02"] ** 2) * DAY
    return [
        entry("momentary rate error: short-term variation (peak to peak)", "~20, semi-random",
              r["momentary_p2p_s_per_day"], "s/day",
              note=f"std {r['momentary_std_s_per_day']:.3g} s/day after {r['transient_s']:g} s"),
        entry("momentary rate error: mean against the uncoupled clock", "not given (~0 implied)",
              r["momentary_mean_s_per_day"], "s/day",
              note=f"quasi-static coupling C1 C2/(2 omega01^2 omega02^2) = {static:.3g} s/day"),
        entry("accumulated error at the end", "small, random-walk like", r["accumulated_end_s"], "s"),
    ]


@headline("ziemkiewicz_fig10b")
def _h10b(scene, summary, results):
    out = []
    for p in _points(summary):
        coupled = bool(p["C1"] or p["C2"])
        tag = f"C1 = {p['C1']:g}, C2 = {p['C2']:g}"
        for i, paper in ((2, 0.05), (1, 0.01)):
            out.append(entry(f"lambda_{i} ({tag})", paper if coupled else 0.0, p.get(f"lambda{i}_end_per_s"), "1/s",
                             note=f"late-half slope {_g(p.get(f'lambda{i}_late_per_s'))}; "
                                  f"d{i} grew x{_g(p.get(f'd{i}_growth'))}"))
    return out


@headline("ziemkiewicz_fig11")
def _h11(scene, summary, results):
    r = _res(summary)
    out = [entry("|E_C sim - E_C AGM| at default settings", "~1e-7 (100 us), ~1e-8 (10 us)",
                 abs(r["default_rel_err"]), "relative",
                 note=f"rtol {r['default_rtol']:g}, communication step {r['default_master_step_s']:g} s, "
                      f"{r['periods']} periods at {r['amplitude_deg']:g} deg")]
    for tag, paper in (("100us", "~1e-7"), ("10us", "~1e-8")):
        k = f"paper_a1_{tag}_quantized_rel_err"
        if k in r:
            out.append(entry(f"Eq. (A1) at {tag.replace('us', ' us')}, {r['paper_span_s']:g} s, ticks at step resolution",
                             paper, abs(r[k]), "relative",
                             note=f"ticks interpolated: {abs(r[f'paper_a1_{tag}_interpolated_rel_err']):.2g}"))
    out.append(entry("Eq. (2) one term at 5 deg", "under 6 s/year (~1e-7)", abs(r["eq2_one_term_s_per_year"]), "s/year"))
    return out
