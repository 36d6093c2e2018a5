"""Hoyng Fig. 6 from the model equations alone: the AveragedPendulum.

``hoyng_averaged_run``: the AveragedPendulum alone, driven with the
escapement's noise sequence (same generator and seed), renewed at the
model's own upward zero crossings (psi = 2 pi k) and averaged over blocks
of ``block_periods`` periods (``sample_periods``, the spacing of the
recorded phases, must be a multiple of it). What the averaging costs is
measured in scenarios/hoyng_fig6_averaged.toml.
"""

from __future__ import annotations

import math
import time
from ctypes import c_double, c_uint

import numpy as np

from ...errors import SceneError, SimulationError
from ...physics import analytic
from ...scene.kinds import Invalid
from .. import keys
from ..context import build_system, experiment, parameters
from ..registry import register
from .common import AVERAGED, TWO_PI, escapement_noise, linfit, normalized


_KEYS = {"torque": keys.torque_in(0, None, also="required; its stationary amplitude (Hoyng Eq. 19) within the "
                                                 "AveragedPendulum's range of amplitude_start, [0, 180] deg"),
         # As GrasshopperEscapement's noise_rms, whose deviates it draws.
         "noise_rms": keys.number(0, 10),
         "noise_start": keys.duration(0, None, lo_open=False, also="before experiment.stop when noise_rms > 0"),
         "noise_seed": keys.count(0, 2**32 - 1),  # the FMU's seed is 32 bits
         "block_periods": keys.count(1, keys.MAX_COUNT),
         "sample_periods": keys.count(1, keys.MAX_COUNT, also="a multiple of block_periods")}


def _check(scene, point: dict) -> None:
    """What hoyng_averaged_run refuses at run time, and noise that would never start."""
    cfg = scene.analysis or {}
    avgs = _twins(scene)
    if len(avgs) != 1:
        raise Invalid("kind", "a scene with one AveragedPendulum for hoyng_averaged_run")
    if "torque" not in cfg:
        raise Invalid("torque", "a value: hoyng_averaged_run needs analysis.torque")
    block, sample = cfg.get("block_periods", 50), cfg.get("sample_periods", 500)
    if sample % block:
        raise Invalid("sample_periods", f"a multiple of block_periods = {block} (the samples fall on block ends)")
    ap = parameters(scene, point)[avgs[0]]
    n = normalized(ap)
    lam0 = analytic.hoyng_stationary_amplitude(cfg["torque"] / n["mgl"], n["eps"], ap["phi_r"]) \
        if n["eps"] > 0 and ap["phi_r"] > 0 else math.inf
    keys.within_fmu(scene, "torque", avgs[0], "amplitude_start", (lam0,), "the stationary amplitude (Eq. 19)")
    _, stop = experiment(scene, point)
    if cfg.get("noise_rms", 0.0) > 0 and cfg.get("noise_start", 0.0) >= stop:
        raise Invalid("noise_start", f"a start before experiment.stop = {stop:g} s, else the noise never starts")


def _twins(scene) -> list[str]:
    return [n for n, c in scene.components.items() if c.model_description.modelName == AVERAGED]


def _twin_series(avg: str) -> str:
    """The series column of the AveragedPendulum's psi - t, cycles."""
    return f"psi_{avg}_minus_t_cycles"


def series_columns(scene) -> set[str]:
    return {"tau", "periods", *(_twin_series(a) for a in _twins(scene))}


# The result's keys (the literal `res` below, the fit, and the noise's with noise).
COLUMNS = {"eps", "mu0", "phi0_rad", "periods", "wall_time_run_s", "cpu_time_run_s", "block_periods", "circular",
           "rate_eq20", "gain_no_noise", "rms_deviation_cycles", "max_deviation_cycles", "rms_gain"}


@register("hoyng_averaged_run", set(_KEYS), keys.table_converter(_KEYS), columns=COLUMNS, check=_check,
          series=series_columns)
def hoyng_averaged_run(scene, point: dict, progress: bool = False) -> dict:
    cfg = scene.analysis or {}
    avgs = _twins(scene)
    if len(avgs) != 1 or "torque" not in cfg:
        raise SimulationError("hoyng_averaged_run needs one AveragedPendulum and analysis.torque")
    avg = avgs[0]
    params = parameters(scene, point)
    ap = params[avg]
    n = normalized(ap)
    eps, w0, T0 = n["eps"], n["w0"], n["T0"]
    mu0 = cfg["torque"] / n["mgl"]
    phi0 = ap["phi_r"]
    start, stop = experiment(scene, point)
    rms = cfg.get("noise_rms", 0.0)
    t_noise = cfg.get("noise_start", 0.0) if rms > 0 else stop
    t_noise = min(max(t_noise, start), stop)
    lam0 = analytic.hoyng_stationary_amplitude(mu0, eps, phi0)
    pt = dict(point)
    pt.update({(avg, "amplitude_start"): lam0, (avg, "phase_start"): 0.0, (avg, "escapement"): 0,
               (avg, "drive"): cfg["torque"]})
    block_periods, sample_periods = cfg.get("block_periods", 50), cfg.get("sample_periods", 500)
    if sample_periods % block_periods:
        raise SceneError(f"analysis.sample_periods = {sample_periods} is not a multiple of "
                         f"analysis.block_periods = {block_periods}: the samples must fall on block ends",
                         scene.path, "analysis.sample_periods")
    blocks_per_sample = sample_periods // block_periods
    block = block_periods * T0
    sample = sample_periods * T0
    taus, ys = [], []
    t_wall, t_cpu = time.perf_counter(), time.process_time()
    system = build_system(scene, pt, record={avg: ["phase", "rate"]})
    with system:
        m = system.master
        port = m.ports[avg]
        out = port.out
        kp, kr = port.out_names.index("phase"), port.out_names.index("rate")
        inst = system.instances[avg]
        taus.append(0.0)
        ys.append(out[kp] - 0.0)
        # Without noise the drive is constant: one step per sample.
        while m.t < t_noise - 1e-9 * T0:
            m.step(min(sample, t_noise - m.t))
            taus.append(w0 * (m.t - start))
            ys.append(out[kp] - taus[-1])
        if t_noise < stop:
            j_n = math.floor(out[kp] / TWO_PI) + 1  # first crossing after noise start
            n_max = int(math.ceil(w0 * (stop - m.t) * (1.0 + abs(out[kr] - 1.0) + 1e-3) / TWO_PI)) + 64
            D = escapement_noise(cfg.get("noise_seed", 1), rms, n_max)
            # held[j - j_n + 1]: the delta that holds after crossing j (0 before
            # the first renewal); prefix[k]: the sum of the first k deltas.
            held = np.concatenate([[0.0], D])
            prefix = np.concatenate([[0.0], np.cumsum(D)])
            first = j_n - 1

            # Preallocated arrays: set_values builds them per call (7 us of 10).
            vr = (c_uint * 1)(inst.variables["drive"].vr)
            value = (c_double * 1)()
            c_set, comp = inst.c_setReal, inst.component

            torque = cfg["torque"]
            t_blocks = m.t  # blocks end on t_blocks + k block, without drift
            k_block = 0
            from tqdm import tqdm
            with tqdm(total=stop - m.t, disable=not progress, delay=1.0, desc=scene.path.stem,
                      unit="s sim") as bar:
                t_bar = m.t
                while m.t < stop - 1e-9 * T0:
                    k_block += 1
                    h = min(t_blocks + k_block * block, stop) - m.t
                    psi_b = out[kp]
                    r = out[kr] * w0  # dpsi/dt, rad/s
                    j1 = math.floor(psi_b / TWO_PI) + 1
                    j2 = math.floor((psi_b + r * h) / TWO_PI)
                    # The block's mean delta, each held from one crossing
                    # 2 pi j of the phase to the next (see the scene file
                    # for what averaging over a block costs).
                    if j2 < j1:
                        mean = held[j1 - 1 - first]
                    else:
                        t1 = (TWO_PI * j1 - psi_b) / r
                        t2 = (TWO_PI * j2 - psi_b) / r
                        lo, hi = max(j1, j_n), j2  # deltas after crossings lo .. hi - 1
                        inner = prefix[hi - j_n] - prefix[lo - j_n] if hi > lo else 0.0
                        mean = (t1 * held[j1 - 1 - first] + (TWO_PI / r) * inner
                                + (h - t2) * held[j2 - first]) / h
                    value[0] = torque * (1.0 + mean)
                    st = c_set(comp, vr, 1, value)
                    if st:
                        inst.check(st, "fmi2SetReal (drive)")
                    m.step(h)
                    if k_block % blocks_per_sample == 0 or m.t >= stop - 1e-9 * T0:
                        taus.append(w0 * (m.t - start))
                        ys.append(out[kp] - taus[-1])
                        bar.update(m.t - t_bar)
                        t_bar = m.t
        stats = vars(m.stats).copy()
    wall = time.perf_counter() - t_wall
    tau = np.asarray(taus)
    y = np.asarray(ys)
    tau_n = w0 * (t_noise - start)
    res = {"eps": eps, "mu0": mu0, "phi0_rad": phi0, "periods": w0 * (stop - start) / TWO_PI,
           "wall_time_run_s": wall, "cpu_time_run_s": time.process_time() - t_cpu,
           "block_periods": cfg.get("block_periods", 50),
           "circular": int(ap.get("circular", 1)),
           "rate_eq20": analytic.hoyng_stationary_rate(mu0, eps, phi0)}
    quiet = (tau >= 0.1 * tau_n) & (tau <= tau_n)
    a0, b0 = linfit(tau[quiet], y[quiet])
    res["gain_no_noise"] = b0
    if t_noise < stop:
        noisy = tau > tau_n
        dev = y[noisy] - (a0 + b0 * tau[noisy])
        res["rms_deviation_cycles"] = float(np.sqrt(np.mean(dev**2)) / TWO_PI)
        res["max_deviation_cycles"] = float(np.max(np.abs(dev)) / TWO_PI)
        res["rms_gain"] = res["rms_deviation_cycles"] / ((tau[-1] - tau_n) / TWO_PI)
    series = {"tau": tau.tolist(), "periods": (tau / TWO_PI).tolist(),
              _twin_series(avg): (y / TWO_PI).tolist()}
    return {"kind": "hoyng_averaged_run", "result": res, "series": series, "statistics": stats}
