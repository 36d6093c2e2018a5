"""Ziemkiewicz Figs. 2-6: steady-state rate errors, and the steady orbit.

- ``escapement_steady_state`` (Figs. 2, 4, 5, 6): the periodic orbit by
  shooting, like ``steady_state``, with an energy-balance start that knows
  the torque profiles and the drag, E_E also against the right and left
  turning amplitudes, and chronometer orbits that turn inside the impulse
  window marked as omitted.
- ``steady_orbit`` (Fig. 3): the torque that gives a wanted steady
  amplitude, then a few periods of the orbit recorded.
"""

from __future__ import annotations

import math

import numpy as np

from ..context import ESCAPEMENTS, find_component
from ..registry import register
from .clock import Clock, advance_to, check_clock, convert_keys, steady_for


@register("escapement_steady_state", {"tolerance_s_per_day", "max_periods", "amplitude_guess"}, convert_keys,
          check=check_clock,
          columns=Clock.RESULT_COLUMNS | {"energy_balance_amplitude_deg"}, series=set())
def escapement_steady_state(scene, point: dict, progress: bool = False) -> dict:
    """Steady-state rate errors by shooting, for any escapement, profile and drag."""
    with Clock(scene, point) as c:
        st = c.steady()
        out = c.result(st)
        out["energy_balance_amplitude_deg"] = (math.degrees(c.guess()) if c.guess() else None)
        stats = vars(c.system.master.stats).copy()
    return {"kind": "escapement_steady_state", "result": out, "statistics": stats}


# What steady_orbit adds to the clock's result.
ORBIT_COLUMNS = {"orbit_closure_rad_per_s", "orbit_closure_phi_rad", "periods", "recoil_fraction", "phi_r_deg",
                 "max_abs_phi_deg"}


def _orbit_series(pendulum: str, escapement: str) -> dict[str, str]:
    """The sampled orbit's series columns, by sample."""
    return {"time": "time", "phi": f"{pendulum}.phi", "w": f"{pendulum}.w", "tau": f"{escapement}.tau"}


def orbit_series_columns(scene) -> set[str]:
    names = _orbit_series(find_component(scene, "Pendulum"), find_component(scene, ESCAPEMENTS))
    return {*names.values(), "recoil"}


@register("steady_orbit", {"amplitude", "periods", "tolerance_s_per_day", "max_periods"}, convert_keys,
          check=check_clock,
          columns=Clock.RESULT_COLUMNS | ORBIT_COLUMNS, series=orbit_series_columns)
def steady_orbit(scene, point: dict, progress: bool = False) -> dict:
    """A few periods of the steady orbit, for a given torque or amplitude (Fig. 3)."""
    cfg = scene.analysis or {}
    periods = cfg.get("periods", 2)
    with Clock(scene, point) as c:
        st = steady_for(c, cfg)
        W = c.orbit_start(st)
        params = {k: dict(v) for k, v in c.params.items()}
        params[c.pendulum].update(phi_start=0.0, w_start=W)
        m = c.system.master
        m.reinitialize(params)
        t0 = m.t
        cols = {"time": [], "phi": [], "w": [], "tau": []}

        def sample():
            cols["time"].append(m.t)
            cols["phi"].append(c.system.output(c.pendulum, "phi"))
            cols["w"].append(c.system.output(c.pendulum, "w"))
            cols["tau"].append(c.system.output(c.escapement, "tau"))

        sample()
        advance_to(m, t0 + periods * st.period, sample)
        out = c.result(st)
        # Closing the orbit checks that the start was on it.
        out["orbit_closure_rad_per_s"] = abs(cols["w"][-1] - W)
        out["orbit_closure_phi_rad"] = abs(cols["phi"][-1])
        stats = vars(m.stats).copy()
    t, phi, w, tau = (np.asarray(cols[k]) for k in ("time", "phi", "w", "tau"))
    # Recoil: the torque opposes the motion. Time share from the samples,
    # crossing times from linear interpolation of w and the located switches.
    recoil = tau * w < 0.0
    dt = np.diff(t)
    share = float(np.sum(dt * recoil[1:]) / (t[-1] - t[0]))
    out.update(periods=periods, recoil_fraction=share,
               phi_r_deg=math.degrees(c.esc["phi_r"]) if "phi_r" in c.esc else None,
               max_abs_phi_deg=float(np.degrees(np.max(np.abs(phi)))))
    series = {name: cols[k] for k, name in _orbit_series(c.pendulum, c.escapement).items()}
    series["recoil"] = [float(r) for r in recoil]
    return {"kind": "steady_orbit", "result": out, "series": series, "statistics": stats}
