"""Hoyng Fig. 6: the clock for 110 days with torque noise, co-simulated.

``hoyng_long_run``: Pendulum + GrasshopperEscapement with torque noise, and
AveragedPendulum twins driven by the escapement's torque_amplitude (the
same mu0 (1 + delta)). psi_p = 2 pi i at the i-th tick, psi_m the twin's
phase at that time.
"""

from __future__ import annotations

import math
import time
from array import array

import numpy as np

from ...physics import analytic
from .. import keys
from ..context import build_system, experiment
from ..registry import register
from .common import TWO_PI, check_grasshopper_clock, grasshopper_clock, hoyng_components, linfit, subscene, \
    twin_values
from .tick_points import replay_schedule, run_tick_points


_KEYS = {"sample_every": keys.count(1, keys.MAX_COUNT), "stationary_start": keys.flag(),
         "twins": keys.one_of("replay", "cosimulate")}


def _twin_columns(avg: str) -> tuple[str, str, str]:
    """The result's (slope, end, circular) columns of an AveragedPendulum twin."""
    return f"psi_diff_slope_{avg}", f"psi_diff_end_{avg}_rad", f"circular_{avg}"


# The result's keys besides the twins' (the literal `res` below, and the fits; the noise's with noise).
COLUMNS = {"eps", "mu0", "phi0_rad", "ticks", "periods", "noise_start_periods", "wall_time_run_s", "cpu_time_run_s",
           "wall_time_cosimulation_s", "twins", "torque_changes", "periods_per_s", "rate_eq20", "rate_eq16_bessel",
           "gain_no_noise", "gain_fit_from_periods", "noise_rms_measured", "noise_renewals", "rms_deviation_cycles",
           "max_deviation_cycles", "rms_gain", "gain_noise"}


def columns(scene) -> set[str]:
    return COLUMNS | {c for a in hoyng_components(scene)[2] for c in _twin_columns(a)}


def _twin_series(avg: str) -> tuple[str, str]:
    """The series' (psi_p - psi_twin, psi_twin - t) columns of an AveragedPendulum twin, cycles."""
    return f"psi_p_minus_psi_{avg}_cycles", f"psi_{avg}_minus_t_cycles"


def series_columns(scene) -> set[str]:
    return {"tau", "periods", "psi_p_minus_t_cycles", *(c for a in hoyng_components(scene)[2] for c in _twin_series(a))}


@register("hoyng_long_run", set(_KEYS), keys.table_converter(_KEYS), columns=columns,
          check=lambda scene, point: check_grasshopper_clock(scene, "hoyng_long_run"),
          series=series_columns)
def hoyng_long_run(scene, point: dict, progress: bool = False) -> dict:
    cfg = scene.analysis or {}
    pend, esc, avgs, params, pp, ep, n = grasshopper_clock(scene, point, "hoyng_long_run")
    eps, mu0, phi0, w0 = n["eps"], n["mu"], n["phi0"], n["w0"]
    start, stop = experiment(scene, point)
    lam0 = analytic.hoyng_stationary_amplitude(mu0, eps, phi0)
    pt = dict(point)
    for a in avgs:
        pt.update(twin_values(a, pp, "GrasshopperEscapement", ep))
    if cfg.get("stationary_start", True):
        pt[(pend, "phi_start")] = 0.0
        pt[(pend, "w_start")] = lam0 * w0
        for a in avgs:
            pt[(a, "amplitude_start")] = lam0
            pt[(a, "phase_start")] = 0.0
    every = cfg.get("sample_every", 500)
    replay = cfg.get("twins", "replay") == "replay"
    noise_on = ep.get("noise_rms", 0.0) > 0 and ep.get("noise_start", 0.0) < stop
    t_noise = ep.get("noise_start", 0.0) if noise_on else stop
    torque0 = ep["torque"]
    record = {pend: ["tick_time"], esc: ["torque_amplitude"]}
    if replay:
        # The twins feed nothing back: run them afterwards on the recorded
        # torque, with communication points where it changed (the same zero-
        # order hold they would see in the co-simulation), instead of
        # stepping them through every step and event iteration of the
        # pendulum (they cost ~40 % of the co-simulation).
        cosim = subscene(scene, {pend, esc})
    else:
        cosim = scene
        for a in avgs:
            record[a] = ["phase", "rate"]
    system = build_system(cosim, pt, record=record)
    samples = {"tau": [], "psi_p": [], "t_tick": [], **{f"psi_{a}": [] for a in avgs}}
    noise = {"n": 0, "sum": 0.0, "sum2": 0.0, "head": []}
    change_t, change_v = array("d"), array("d")  # torque_amplitude: when it changed, to what
    t_wall, t_cpu = time.perf_counter(), time.process_time()
    with system:
        m = system.master
        P = m.ports[pend]
        i_tick = P.out_names.index("tick_time")
        E = m.ports[esc]
        i_amp = E.out_names.index("torque_amplitude")
        A = [] if replay else [(m.ports[a].out, m.ports[a].out_names.index("phase"),
                                m.ports[a].out_names.index("rate")) for a in avgs]
        pout, eout = P.out, E.out
        state = [pout[i_tick], 0, eout[i_amp]]  # last tick time, tick count, torque amplitude
        lists = [samples[f"psi_{a}"] for a in avgs]

        # A twin's rate output already follows a drive set at this point (direct
        # feedthrough); over the step that ended here it ran at the rate seen
        # at the previous point: a row holds those.
        watched = [(P, i_tick), (E, i_amp)]
        n_twins = len(A)

        def _sample():
            tt, i, *phases = last_tick
            samples["tau"].append(w0 * (tt - start))
            samples["psi_p"].append(TWO_PI * i)
            samples["t_tick"].append(tt)
            for lst, ph in zip(lists, phases):
                lst.append(ph)

        last_tick: list = []

        def on_rows(rows):
            """At each communication point of a batch where the tick time or the
            torque amplitude changed, a row (t, tick time, torque amplitude,
            the co-simulated twins' phases at t..., their rates at the point
            before...): the torque changes, the ticks and their noise. Kept in
            local variables over the batch: there is a row per period."""
            tt_last, i, amp_last = state
            count, total, total2, head = noise["n"], noise["sum"], noise["sum2"], noise["head"]
            for t, tt, amp, *twin in rows:
                if amp != amp_last:
                    amp_last = amp
                    change_t.append(t)
                    change_v.append(amp)
                if tt == tt_last:
                    continue
                tt_last = tt
                i += 1
                if t >= t_noise:
                    d = amp / torque0 - 1.0
                    count += 1
                    total += d
                    total2 += d * d
                    if len(head) < 8:
                        head.append(d)
                if twin:  # the twins' phases at the tick: back from this point at the step's rate
                    last_tick[:] = [tt, i] + [ph - w0 * r * (t - tt) for ph, r in zip(twin[:n_twins], twin[n_twins:])]
                if i % every == 0 or i == 1:
                    if not twin:
                        last_tick[:] = [tt, i]
                    _sample()
            state[:] = [tt_last, i, amp_last]
            noise["n"], noise["sum"], noise["sum2"] = count, total, total2
            if i and not A:  # the last tick, for the closing sample
                last_tick[:] = [tt_last, i]

        # The same points whether the twins are co-simulated or not; the
        # master returns to Python only with a batch of rows.
        run_tick_points(m, stop, watched, n["T0"], on_rows, progress, scene.path.stem,
                        outputs=[(m.ports[a], kp) for (_, kp, _), a in zip(A, avgs)],
                        before=[(m.ports[a], kr) for (_, _, kr), a in zip(A, avgs)])
        if state[1] % every and state[1] > 1:
            _sample()
        stats = vars(m.stats).copy()
    wall_cosim = time.perf_counter() - t_wall
    if replay and avgs:
        for a in avgs:
            pt[(a, "drive")] = torque0
        twins = build_system(subscene(scene, set(avgs)), pt, record={a: ["phase"] for a in avgs})
        with twins:
            _replay_twins(twins, avgs, samples, change_t, change_v, progress, f"{scene.path.stem} (twins)")
    wall = time.perf_counter() - t_wall
    tau = np.asarray(samples["tau"])
    psi_p = np.asarray(samples["psi_p"])
    y = psi_p - tau
    tau_n = w0 * (t_noise - start)
    res = {"eps": eps, "mu0": mu0, "phi0_rad": phi0, "ticks": state[1],
           "periods": w0 * (stop - start) / TWO_PI, "noise_start_periods": tau_n / TWO_PI if noise_on else None,
           "wall_time_run_s": wall, "cpu_time_run_s": time.process_time() - t_cpu,
           "wall_time_cosimulation_s": wall_cosim, "twins": "replay" if replay else "cosimulated",
           "torque_changes": len(change_t),
           "periods_per_s": w0 * (stop - start) / TWO_PI / wall,
           "rate_eq20": analytic.hoyng_stationary_rate(mu0, eps, phi0),
           "rate_eq16_bessel": float(analytic.hoyng_rate(lam0, mu0, phi0, bessel=True))}
    # Skip the amplitude transient (lambda^2 relaxes as exp(-2 eps t)) from the Eq. (19) start.
    skip = min(3.0 / (2.0 * eps), 0.5 * tau_n) if eps > 0 else 0.1 * tau_n
    quiet = (tau >= skip) & (tau <= tau_n)
    a0, b0 = linfit(tau[quiet], y[quiet])
    res["gain_no_noise"] = b0
    res["gain_fit_from_periods"] = skip / TWO_PI
    if noise_on:
        noisy = tau > tau_n
        dev = y[noisy] - (a0 + b0 * tau[noisy])
        span = (tau[-1] - tau_n) / TWO_PI
        res["noise_rms_measured"] = math.sqrt(noise["sum2"] / noise["n"] - (noise["sum"] / noise["n"]) ** 2) if noise["n"] > 1 else None
        res["noise_renewals"] = noise["n"]
        if dev.size:
            res["rms_deviation_cycles"] = float(np.sqrt(np.mean(dev**2)) / TWO_PI)
            res["max_deviation_cycles"] = float(np.max(np.abs(dev)) / TWO_PI)
            res["rms_gain"] = res["rms_deviation_cycles"] / span
            res["gain_noise"] = linfit(tau[noisy], y[noisy])[1]
    for a in avgs:
        d = psi_p - np.asarray(samples[f"psi_{a}"])
        late = tau >= 0.1 * tau[-1]
        slope, end, circular = _twin_columns(a)
        res[slope] = linfit(tau[late], d[late])[1]
        res[end] = float(d[-1])
        res[circular] = int(params[a].get("circular", 1))
    series = {"tau": tau.tolist(), "periods": (tau / TWO_PI).tolist(),
              "psi_p_minus_t_cycles": (y / TWO_PI).tolist()}
    for a in avgs:
        lead, lag = _twin_series(a)
        series[lead] = ((psi_p - np.asarray(samples[f"psi_{a}"])) / TWO_PI).tolist()
        series[lag] = ((np.asarray(samples[f"psi_{a}"]) - tau) / TWO_PI).tolist()
    return {"kind": "hoyng_long_run", "result": res, "series": series, "statistics": stats,
            "noise_head": noise["head"]}


def _replay_twins(twins, avgs, samples, change_t, change_v, progress, label, chunk: int = 1 << 16) -> None:
    """Step the AveragedPendulum twins through the recorded torque changes,
    reading their phases at the sampled tick times (a sample before the
    change seen at the point after it): tick_points.replay_schedule."""
    m = twins.master
    inputs = [(twins.instances[a], twins.instances[a].variables["drive"].vr) for a in avgs]
    outputs = [(m.ports[a], m.ports[a].out_names.index("phase")) for a in avgs]
    t_samples = np.asarray(samples["t_tick"], dtype=float)
    t_changes = np.frombuffer(change_t, dtype=float) if len(change_t) else np.zeros(0)
    times = np.concatenate([t_samples, t_changes])
    sets = np.concatenate([np.zeros(len(t_samples), dtype=bool), np.ones(len(t_changes), dtype=bool)])
    values = np.concatenate([np.zeros(len(t_samples)), np.frombuffer(change_v, dtype=float) if len(change_v)
                             else np.zeros(0)])
    order = np.lexsort((sets, times))  # by time; on a tie the sample first
    times, sets, values = times[order].tolist(), sets[order].tolist(), values[order].tolist()
    rows = replay_schedule(m, times, sets, values, inputs, outputs, progress, label, chunk)
    for col, a in enumerate(avgs, start=1):
        samples[f"psi_{a}"].extend(row[col] for row in rows)
