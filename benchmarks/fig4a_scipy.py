"""Ziemkiewicz Fig. 4(a) the way a user would write it with SciPy alone: the
yardstick for `clockwork run scenarios/ziemkiewicz_fig4a.toml` as a whole
process (docs/benchmarks.md).

For each of the scene's 24 driving torques it shoots the periodic orbit of
the pendulum driven by the grasshopper escapement (a relay with hysteresis at
+-phi_r): one full swing from the positive turning point, integrated by
`solve_ivp` (DOP853, rtol 1e-11, the relay switches and the next turning
point located as events), and `brentq` on the amplitude until the swing
returns to where it started. It writes the same rate errors as the scene
(E_T, E_C by the AGM, E_E) to a CSV and a PNG.

    python benchmarks/fig4a_scipy.py --out out/fig4a_scipy
    python benchmarks/bench_fig4a_process.py --pairs 9   # the two side by side (docs/benchmarks.md)
"""

from __future__ import annotations

import argparse
import csv
import math
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

# The scene's physics (scenarios/ziemkiewicz_fig4a.toml).
L_M, MASS_KG, G_M_S2, Q = 1.0, 1.0, 9.81, 1000.0
PHI_R_RAD = math.radians(2.0)
TORQUES_NM = np.geomspace(0.05e-2, 1.0e-2, 24)  # 0.05 to 1.0 N.cm, log spacing
RTOL, ATOL = 1e-11, 1e-13
OMEGA0 = math.sqrt(G_M_S2 / L_M)
T0_S = 2.0 * math.pi / OMEGA0
SECONDS_PER_DAY = 86400.0


def swing(amplitude: float, torque: float) -> tuple[float, float]:
    """One period from the turning point phi = amplitude (w = 0, the relay
    pushing towards -phi): (period in s, amplitude at the next turning point)."""
    def rhs(t, y, d):
        return [y[1], -(G_M_S2 / L_M) * math.sin(y[0]) - (OMEGA0 / Q) * y[1] + d * torque / (MASS_KG * L_M ** 2)]

    t, y = 0.0, [amplitude, 0.0]
    # The relay flips to +1 where phi falls through -phi_r, then to -1 where
    # it rises through +phi_r; after that the next turning point (w: + to -).
    for d, crossing in ((-1.0, lambda t, y, d: y[0] + PHI_R_RAD), (1.0, lambda t, y, d: y[0] - PHI_R_RAD)):
        crossing.terminal = True
        crossing.direction = d
        sol = solve_ivp(rhs, (t, t + 2 * T0_S), y, method="DOP853", rtol=RTOL, atol=ATOL, args=(d,),
                        events=crossing)
        if not sol.t_events[0].size:
            return math.nan, 0.0  # the swing never reached the threshold: the clock stalls
        t, y = sol.t_events[0][0], sol.y_events[0][0]

    def turning(t, y, d):
        return y[1]

    turning.terminal, turning.direction = True, -1
    sol = solve_ivp(rhs, (t, t + T0_S), y, method="DOP853", rtol=RTOL, atol=ATOL, args=(-1.0,), events=turning)
    return sol.t_events[0][0], sol.y_events[0][0][0]


def circular_error(amplitude: float) -> float:
    """T/T0 - 1 of a free pendulum of this amplitude (arithmetic-geometric mean)."""
    a, b = 1.0, math.cos(amplitude / 2.0)
    for _ in range(64):  # converges quadratically; the bound only guards against rounding ping-pong
        if abs(a - b) <= 4e-16 * a:
            break
        a, b = (a + b) / 2.0, math.sqrt(a * b)
    return 1.0 / a - 1.0


def steady_state(torque: float) -> dict:
    # Energy balance (work 4 torque phi_r per period against the damping loss) for the bracket.
    guess = math.sqrt(4.0 * torque * PHI_R_RAD * Q / (math.pi * MASS_KG * G_M_S2 * L_M))
    lo, hi = max(PHI_R_RAD * 1.0001, 0.8 * guess), min(1.2 * guess, 3.0)
    amplitude = brentq(lambda a: swing(a, torque)[1] - a, lo, hi, xtol=1e-14, rtol=1e-14)
    period, _ = swing(amplitude, torque)
    E_T = period / T0_S - 1.0
    E_C = circular_error(amplitude)
    return {"torque_Nm": torque, "amplitude_deg": math.degrees(amplitude), "period_s": period,
            "E_T_s_per_day": E_T * SECONDS_PER_DAY, "E_C_s_per_day": E_C * SECONDS_PER_DAY,
            "E_E_s_per_day": (E_T - E_C) * SECONDS_PER_DAY}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, required=True)
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    rows = [steady_state(t) for t in TORQUES_NM]
    with open(args.out / "fig4a.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4))
    amp = [r["amplitude_deg"] for r in rows]
    for key in ("E_T_s_per_day", "E_C_s_per_day", "E_E_s_per_day"):
        ax.plot(amp, [r[key] for r in rows], "o-", ms=3, label=key)
    ax.set_xlabel("amplitude (deg)")
    ax.set_ylabel("rate error (s/day)")
    ax.legend()
    fig.savefig(args.out / "fig4a.png", dpi=120)


if __name__ == "__main__":
    main()
