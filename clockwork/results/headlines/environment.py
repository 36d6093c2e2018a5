"""Headlines of the scenes with air: the outside numbers (Matthys, the
Trinity College clock, -alpha/2 x 86400, Baily's compensating arc) beside
ours. Every outside number is computed from the constants in
clockwork.physics.air, never typed in here.
"""

from __future__ import annotations

import numpy as np

from ...analyses.ziemkiewicz.clock import orbit_rows
from ...physics import air as airphys
from .pchip import pchip
from .registry import entry, headline

MS = 1e3  # ms per s


def _r(x, digits=4):
    return None if x is None else float(f"{x:.{digits}g}")


def compensating_arc(rows: list[dict], y: str = "barometric_s_per_day_per_hPa",
                     x: str = "amplitude_deg") -> float | None:
    """x (deg) where y changes sign over the sweep: the first bracket,
    PCHIP through the sweep and bisection; None without a sign change."""
    pts = sorted((r["result"][x], r["result"][y]) for r in rows if r["result"].get(y) is not None)
    if len(pts) < 2:
        return None
    xs, ys = map(np.asarray, zip(*pts))
    for k in range(len(xs) - 1):
        if ys[k] == 0.0:
            return float(xs[k])
        if (ys[k] < 0) != (ys[k + 1] < 0):
            a, b = xs[k], xs[k + 1]
            fa = ys[k]
            for _ in range(60):
                c = 0.5 * (a + b)
                fc = float(pchip(xs, ys, c))
                if (fc < 0) == (fa < 0):
                    a, fa = c, fc
                else:
                    b = c
            return float(0.5 * (a + b))
    return None


def _matthys_range_ms_per_hpa() -> str:
    lo, hi = (airphys.per_inhg_to_per_hpa(v) * MS for v in airphys.MATTHYS_S_PER_DAY_PER_INHG)
    return f"-{lo:.1f} to -{hi:.1f} (Matthys: {airphys.MATTHYS_S_PER_DAY_PER_INHG[0]}-" \
           f"{airphys.MATTHYS_S_PER_DAY_PER_INHG[1]} s/day per inHg, a loss)"


@headline("air_barometric_ziemkiewicz", "air_barometric_hoyng")
def _barometric(scene, summary, results):
    rows = sorted(orbit_rows(results), key=lambda r: r["result"]["amplitude_deg"])
    buoyancy = float(np.median([r["result"]["buoyancy_s_per_day_per_hPa"] for r in rows]))
    arc = compensating_arc(rows)
    smallest = rows[0]["result"]
    return [
        entry("buoyancy and added mass, arc held (median over the sweep)", _matthys_range_ms_per_hpa(),
              _r(buoyancy * MS), "ms/day per hPa",
              note="closed form sqrt((m + m_a)/(m - rho V)) with the Air FMU's densities"),
        entry("the same against the Trinity College clock (total, before its compensator)",
              airphys.TRINITY_S_PER_DAY_PER_HPA * MS, _r(buoyancy * MS), "ms/day per hPa"),
        entry(f"barometric coefficient at the smallest arc ({smallest['amplitude_deg']:.3g} deg)",
              None, _r(smallest["barometric_s_per_day_per_hPa"] * MS), "ms/day per hPa"),
        entry("compensating arc: barometric coefficient zero", "exists (Baily 1832): no number for this clock",
              _r(arc), "deg", note=None if arc is not None else "no sign change over the sweep"),
    ]


@headline("air_thermal")
def _thermal(scene, summary, results):
    out = []
    for r in sorted(orbit_rows(results), key=lambda r: -r["result"]["alpha_per_K"]):
        res = r["result"]
        alpha = res["alpha_per_K"]
        out.append(entry(f"rod alone, alpha = {alpha:.3g}/K: s/day per K", _r(airphys.thermal_rate_coefficient(alpha)),
                         _r(res["rod_s_per_day_per_K"]), "s/day per K", note="paper column: -alpha/2 x 86400"))
        out.append(entry(f"rod and air together, alpha = {alpha:.3g}/K", None, _r(res["thermal_s_per_day_per_K"]),
                         "s/day per K"))
    return out


@headline("air_weather_year")
def _year(scene, summary, results):
    res = results[0]["result"]
    out = [
        entry("compensating arc (secant search on the torque)", "exists (Baily 1832)",
              _r(res["compensating_amplitude_deg"]), "deg"),
    ]
    for name, label in (("scene", f"at {res['scene_amplitude_deg']:.3g} deg"),
                        ("compensating", "at the compensating arc")):
        out.append(entry(f"largest |accumulated error| over {res['days']:.0f} days, {label}", None,
                         _r(res[f"{name}_error_max_abs_s"]), "s"))
        out.append(entry(f"rms rate {label}", None, _r(res[f"{name}_rate_rms_s_per_day"]), "s/day"))
        if f"{name}_check_difference_s" in res:
            out.append(entry(f"co-simulation - averaged model after {res[f'{name}_check_hours']} h, {label}", None,
                             _r(res[f"{name}_check_difference_s"], 3), "s",
                             note=f"the clock's error then: {res[f'{name}_check_cosimulated_error_s']:.4g} s"))
    return out
