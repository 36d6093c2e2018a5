"""Ziemkiewicz Fig. 8(a): the grasshopper clock's limit cycle.

``limit_cycle`` starts the clock from rest; its phase portrait spirals onto
the limit cycle. The limit-cycle amplitude comes from the last turning
points, beside Eq. (B6), and the angles where the torque switches.
"""

from __future__ import annotations

import math

import numpy as np

from ...errors import SimulationError
from ..context import build_system, experiment, find_component
from ..registry import register
from ..time_series import run_with_progress
from .parts import Parts, check_parts, convert_keys, on_grid, stats_of


# The keys of the result built at the end of limit_cycle.
COLUMNS = {"amplitude_start_deg", "limit_cycle_amplitude_deg", "limit_cycle_change_deg", "amplitude_B6_deg",
           "first_turn_amplitude_deg", "turns", "switches", "switch_abs_phi_deg_mean", "switch_abs_phi_deg_max_dev",
           "phi_r_deg", "Q", "torque_Ncm", "acceleration_jump_rad_per_s2"}


def _series(pendulum: str, escapement: str) -> list[str]:
    return ["time", f"{pendulum}.phi", f"{pendulum}.w", f"{escapement}.tau"]


def series_columns(scene) -> set[str]:
    return set(_series(find_component(scene, "Pendulum"), find_component(scene, "GrasshopperEscapement")))


@register("limit_cycle", {"sample_interval"}, convert_keys, columns=COLUMNS, series=series_columns,
          check=check_parts(escapement=True, on_grid=True))
def limit_cycle(scene, point: dict, progress: bool = False) -> dict:
    cfg = scene.analysis or {}
    parts = Parts(scene, point)
    pend, esc = parts.pendulum, parts.escapement
    if esc is None:
        raise SimulationError("limit_cycle needs a GrasshopperEscapement")
    _, stop = experiment(scene, point)
    interval = cfg.get("sample_interval")
    cols = {n: [] for n in _series(pend, esc)}
    turns: list[tuple[float, float]] = []
    switches: list[float] = []
    with build_system(scene, point, record={pend: ["amplitude"]}) as system:
        m = system.master
        state = {"amp": system.output(pend, "amplitude"), "tau": system.output(esc, "tau")}

        def sample(master) -> None:
            phi = system.output(pend, "phi")
            tau = system.output(esc, "tau")
            if tau * state["tau"] < 0.0:
                switches.append(phi)  # located: this point lies just past the crossing
            state["tau"] = tau
            a = system.output(pend, "amplitude")
            if a != state["amp"]:
                state["amp"] = a
                turns.append((master.t, a))
            if on_grid(master, interval):
                cols["time"].append(master.t)
                cols[f"{pend}.phi"].append(phi)
                cols[f"{pend}.w"].append(system.output(pend, "w"))
                cols[f"{esc}.tau"].append(tau)

        sample(m)
        run_with_progress(m, stop, sample, progress, label=scene.path.stem)
        stats = stats_of(m)
    if len(turns) < 6:
        raise SimulationError("limit_cycle: fewer than 6 turning points; run longer")
    amps = np.array([a for _, a in turns])
    last = amps[-4:]
    pp, e = parts.pp, parts.esc
    inertia = pp["m"] * pp["L"] ** 2
    # Eq. (B6) solved for A: the small-damping energy balance.
    a_b6 = (math.sqrt(4 * pp["Q"] * e["phi_r"] * e["torque"] / (math.pi * inertia * parts.omega0 ** 2))
            if pp["Q"] > 0 else None)
    sw = np.abs(np.asarray(switches))
    result = {
        "amplitude_start_deg": math.degrees(abs(pp["phi_start"])),
        "limit_cycle_amplitude_deg": float(np.degrees(last.mean())),
        "limit_cycle_change_deg": float(np.degrees(abs(amps[-1] - amps[-3]))),
        "amplitude_B6_deg": math.degrees(a_b6) if a_b6 else None,
        "first_turn_amplitude_deg": float(np.degrees(amps[0])),
        "turns": len(turns),
        "switches": len(switches),
        "switch_abs_phi_deg_mean": float(np.degrees(sw.mean())) if len(sw) else None,
        "switch_abs_phi_deg_max_dev": float(np.degrees(np.max(np.abs(sw - e["phi_r"])))) if len(sw) else None,
        "phi_r_deg": math.degrees(e["phi_r"]),
        "Q": pp["Q"],
        "torque_Ncm": 100.0 * e["torque"],
        # The kink in the portrait: dw/dphi = a/w jumps by 2 M/(I w) at a switch.
        "acceleration_jump_rad_per_s2": 2.0 * e["torque"] / inertia,
    }
    return {"kind": "limit_cycle", "result": result, "series": cols, "statistics": stats}
