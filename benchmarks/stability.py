"""Numerical-stability stress measurements of the co-simulation master.

A library (tests/stress imports it) and a command that writes tables
(CSV + Markdown) and plots:

    python benchmarks/stability.py limits   --out out/stress [--size ci|full]
    python benchmarks/stability.py extremes --out out/stress
    python benchmarks/stability.py drift    --out out/stress [--periods N]
    python benchmarks/stability.py rollback --out out/stress [--events N]
    python benchmarks/stability.py all      --out out/stress [--size full]

Four parts (docs/stress.md has the measured figures):

- limits: Pendulum + MechanismVibration (Ziemkiewicz Eq. 7) with the
  communication step swept up to and past each master configuration's
  stability limit; amplification per pendulum period beyond the physical one.
- extremes: Pendulum + GrasshopperEscapement at extreme Q, amplitude, phi_r
  next to the amplitude, zero torque, one step for the whole run.
- drift: the phase drift of Hoyng's clock at point C over many periods
  against the exact periodic orbit, early and at the end of 110 days.
- rollback: many located events (each one a rollback) and the resident
  memory (VmRSS) before and after.

FMUs come from $CLOCKWORK_FMU_DIR (default: the repository's fmus/).
"""

from __future__ import annotations

import argparse
import csv
import gc
import itertools
import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from clockwork.physics import analytic, reference  # noqa: E402
from clockwork.errors import SimulationError  # noqa: E402
from clockwork.engine import MasterSettings  # noqa: E402
from clockwork.analyses.steady_state import energy_balance_amplitude, find_steady_state
from clockwork.engine.shooting import Shooter  # noqa: E402
from clockwork.engine import System  # noqa: E402
from clockwork.engine.recording import Recorder  # noqa: E402

G = 9.81  # m/s^2
OMEGA01 = math.sqrt(G)  # rad/s, pendulum of L = 1 m
T0 = 2 * math.pi / OMEGA01  # s, small-angle period of the 1 m pendulum
CLOCK_LINKS = ["pendulum.phi -> escapement.phi", "pendulum.w -> escapement.w",
               "escapement.tau -> pendulum.tau_escapement"]
VIB_LINKS = ["pendulum.phi -> vibration.a1", "vibration.tau -> pendulum.tau_coupling"]


# ---------------------------------------------------------------------------
# 1. Stability limits of the pendulum-vibration coupling
# ---------------------------------------------------------------------------

@dataclass(frozen=True)
class Coupling:
    """Mechanism mode of Ziemkiewicz Eq. (7), C1 = 1, omega02 = 7 omega01."""

    kappa: float  # 1/(rad^2 s^2)
    C2: float  # 1/s^2
    C1: float = 1.0  # 1/s^2
    omega02: float = 7.0 * OMEGA01  # rad/s
    gamma2: float = math.pi / 500 / 100  # 1/s, gamma1/100 as in the paper

    @property
    def label(self) -> str:
        return f"kappa={self.kappa:g}, C2={self.C2:g}"


# The pendulum is undamped (Q = 0): the only physical loss is gamma2, so
# any energy gain per period is the co-simulation's. The pendulum swings at
# 5 deg; the mechanism starts deflected by 1 mrad (at kappa = 1e9 the cubic
# term is then twice the linear one).
VIB_PHI_START = math.radians(5.0)  # rad
VIB_A2_START = 1e-3  # rad
VIB_RTOL, VIB_ATOL = 1e-11, 1e-13


@dataclass(frozen=True)
class Config:
    order: str = "gauss-seidel"
    extrapolation: int = 0
    iterations: int = 0
    richardson: bool = False

    @property
    def label(self) -> str:
        parts = ["GS" if self.order == "gauss-seidel" else "Jacobi", f"ex{self.extrapolation}"]
        if self.iterations:
            parts.append(f"it{self.iterations}")
        if self.richardson:
            parts.append("rich")
        return " ".join(parts)

    def settings(self, step: float) -> MasterSettings:
        # max_step = step as in scenes: Richardson may shrink the step, not grow it past h.
        return MasterSettings(step=step, order=self.order, extrapolation=self.extrapolation,
                              iterations=self.iterations, richardson=self.richardson, max_step=step)


def all_configs(iterations: int = 5, richardson_iterations: bool = False) -> list[Config]:
    """Every master configuration: order x extrapolation x iterations x Richardson.

    With Richardson on, the master ignores `iterations` (Master.step takes
    the Richardson branch first), so those variants are left out unless
    asked for; tests/stress checks that they are bit-identical.
    """
    out = []
    for order, ex, it, rich in itertools.product(("gauss-seidel", "jacobi"), (0, 1, 2), (0, iterations),
                                                 (False, True)):
        if rich and it and not richardson_iterations:
            continue
        out.append(Config(order, ex, it, rich))
    return out


def vibration_system(c: Coupling, settings: MasterSettings) -> System:
    pend = dict(L=1.0, m=1.0, g=G, Q=0.0, phi_start=VIB_PHI_START, w_start=0.0, rtol=VIB_RTOL, atol=VIB_ATOL)
    vib = dict(gamma2=c.gamma2, omega02=c.omega02, kappa=c.kappa, C1=c.C1, C2=c.C2, inertia=1.0,
               a2_start=VIB_A2_START, a2dot_start=0.0, rtol=VIB_RTOL, atol=VIB_ATOL)
    return System({"pendulum": ("Pendulum", pend), "vibration": ("MechanismVibration", vib)}, VIB_LINKS,
                  settings, record={"pendulum": ["phi", "w"], "vibration": ["a2", "a2dot"]})


def energies(c: Coupling, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(E_free, H) per unit moment of inertia, J/(kg m^2), from states [phi, w, a2, a2dot].

    E_free is the energy of the mechanism mode's free oscillation: the
    deviation of a2 from its quasi-static response to the pendulum,
    (omega02^2 - omega01^2) a + kappa a^3 = -C2 phi (exact for a harmonic phi
    at kappa = 0), so that it does not beat with the pendulum's phase: over
    20 periods of the reference it varies by 0.3 % (kappa = 0) to 24 %
    (kappa = 1e9), the mode's total energy by a factor 3 to 8.
    H = C2 E_pend + C1 E_vib + C1 C2 phi a2 is conserved by Eq. (7) without
    damping (dH/dt = -C1 gamma2 a2dot^2 here, Q = 0), for any kappa and the
    full sin(phi).
    """
    phi, w, a2, v2 = y
    lin = c.omega02**2 - OMEGA01**2
    a = -c.C2 * phi / lin
    if c.kappa:
        for _ in range(40):  # Newton; monotone cubic, converges from the linear root
            a = a - (lin * a + c.kappa * a**3 + c.C2 * phi) / (lin + 3.0 * c.kappa * a**2)
    stiff = lin + 3.0 * c.kappa * a**2
    d, dv = a2 - a, v2 + c.C2 * w / stiff
    e_free = (0.5 * dv**2 + 0.5 * (c.omega02**2 + 3.0 * c.kappa * a**2) * d**2
              + c.kappa * a * d**3 + 0.25 * c.kappa * d**4)
    e_vib = 0.5 * v2**2 + 0.5 * c.omega02**2 * a2**2 + 0.25 * c.kappa * a2**4
    e_pend = 0.5 * w**2 + G * (1.0 - np.cos(phi))
    return e_free, c.C2 * e_pend + c.C1 * e_vib + c.C1 * c.C2 * phi * a2


_REFERENCE_CACHE: dict = {}


def vibration_reference(c: Coupling, t_end: float):
    """Dense monolithic solution (scipy DOP853) of the same system."""
    key = (c, t_end)
    if key not in _REFERENCE_CACHE:
        p = reference.ClockParams(L=1.0, m=1.0, g=G, Q=0.0, escapement="none",
                                  vibration=reference.Vibration(c.gamma2, c.omega02, c.kappa, c.C1, c.C2,
                                                                VIB_A2_START, 0.0))
        res = reference.simulate(p, VIB_PHI_START, 0.0, t_end, dense=True, rtol=1e-12, atol=1e-14)
        _REFERENCE_CACHE[key] = res.sol
    return _REFERENCE_CACHE[key]


def _slope(t: np.ndarray, x: np.ndarray) -> float:
    return float(np.polyfit(t, np.log(x), 1)[0])


def amplification(c: Coupling, config: Config, step: float, periods: int = 40,
                  threshold: float = 0.01) -> dict:
    """Energy amplification per pendulum period beyond the physical one.

    Co-simulates `periods` small-angle periods T0 and compares two windows
    of periods/4 each, periods/2 apart: [P/4, P/2) and [3P/4, P). The first
    quarter is left out: a coarse step kicks the free mode to a new level
    within a few periods, an error but not a growth. A_vib is the growth per
    period of the largest E_free in a window (at coarse steps E_free
    beats with the sampling; the window maximum does not), A_energy that of
    the mean of H; each is divided by the same ratio of the monolithic
    reference sampled at the same times. amplification = the larger of the
    two; unstable when it exceeds 1 + threshold or the master reports
    divergence. `excitation` is the largest E_free over the last three
    quarters relative to the reference's (an accuracy figure, not stability).
    """
    t_end = periods * T0
    ts, ys = [], []
    row = dict(kappa=c.kappa, C2=c.C2, order=config.order, extrapolation=config.extrapolation,
               iterations=config.iterations, richardson=config.richardson, step_s=step, periods=periods)
    wall = time.perf_counter()
    error = None
    with vibration_system(c, config.settings(step)) as system:
        m = system.master
        pp, pv = m.ports["pendulum"], m.ports["vibration"]
        ip = [pp.out_names.index(n) for n in ("phi", "w")]
        iv = [pv.out_names.index(n) for n in ("a2", "a2dot")]

        def sample(master) -> None:
            ts.append(master.t)
            ys.append((pp.out[ip[0]], pp.out[ip[1]], pv.out[iv[0]], pv.out[iv[1]]))

        sample(m)
        try:
            m.run_until(t_end, sample)
        except SimulationError as e:
            error = e
        steps = m.stats.steps
    row["wall_s"] = time.perf_counter() - wall
    row["steps"] = steps
    if error is not None:
        row.update(A_vib=math.inf, A_energy=math.inf, amplification=math.inf, excitation=math.inf, unstable=True,
                   diverged=True, error=str(error), error_time_s=error.time, error_instance=error.instance,
                   error_variable=error.variable)
        return row
    t = np.asarray(ts)
    y = np.asarray(ys).T
    ef, h = energies(c, y)
    ef_ref, h_ref = energies(c, vibration_reference(c, t_end)(t))
    early = (t >= 0.25 * t_end) & (t < 0.5 * t_end)
    late = t >= 0.75 * t_end
    if not early.any() or not late.any():
        raise ValueError(f"step {step} s leaves a window of {periods} periods empty")
    span = 0.5 * periods

    def growth(x, x_ref, stat):
        ratio = (stat(x[late]) / stat(x[early])) / (stat(x_ref[late]) / stat(x_ref[early]))
        # H changed sign between the windows (the coupling term C1 C2 phi a2
        # outgrew the rest): a co-simulation that far off is unstable. The
        # power of a negative ratio would be NaN, which max() below drops.
        return ratio ** (1.0 / span) if ratio > 0 else math.inf

    a_vib = growth(ef, ef_ref, np.max)
    a_h = growth(h, h_ref, np.mean)
    amp = max(a_vib, a_h)
    rest = t >= 0.25 * t_end
    row.update(A_vib=a_vib, A_energy=a_h, amplification=amp, excitation=float(np.max(ef[rest]) / np.max(ef_ref[rest])),
               unstable=amp > 1.0 + threshold, diverged=False, error="")
    return row


def step_grid(lo: float = 0.01, hi: float = 2.6, per_octave: int = 2) -> list[float]:
    """Steps lo * 2^(k/per_octave) up to hi, s."""
    n = int(math.floor(per_octave * math.log2(hi / lo) + 1e-9))
    return [lo * 2.0 ** (k / per_octave) for k in range(n + 1)]


def stability_limit(rows: list[dict]) -> tuple[float, float | None, bool]:
    """(largest step below which every swept step was stable, first unstable
    step or None, whether a larger step was stable again)."""
    rows = sorted(rows, key=lambda r: r["step_s"])
    limit, first_bad, again = 0.0, None, False
    for r in rows:
        if r["unstable"]:
            if first_bad is None:
                first_bad = r["step_s"]
        elif first_bad is None:
            limit = r["step_s"]
        else:
            again = True
    return limit, first_bad, again


LIMIT_SIZES = {
    # couplings, steps, periods, steps for Richardson (its controller
    # picks its own steps; the nominal one only starts it)
    "ci": dict(couplings=[Coupling(0.0, 5.0), Coupling(1e9, 5.0)], steps=step_grid(0.04, 2.6, 1),
               periods=20, richardson_steps=[2.56]),
    "full": dict(couplings=[Coupling(k, c2) for k in (0.0, 1e7, 1e9) for c2 in (0.0, 2.5, 5.0)],
                 steps=step_grid(0.01, 2.6, 2), periods=40, richardson_steps=[2.56]),
}


def limit_sweep(couplings, configs, steps, periods, richardson_steps=None, progress=None) -> list[dict]:
    """Every (coupling, configuration, step). A run found unstable without
    diverging is measured again over twice as many periods and that one
    counts: at steps longer than the vibration period the free mode
    wanders (beats, aliasing) and a short window can mistake that for
    growth; a sustained growth only shows more clearly in a longer run."""
    rows = []
    for c in couplings:
        for cfg in configs:
            grid = richardson_steps if (cfg.richardson and richardson_steps) else steps
            for h in grid:
                r = amplification(c, cfg, h, periods)
                r["first_amplification"] = r["amplification"]
                if r["unstable"] and not r["diverged"]:
                    first = r["amplification"]
                    r = amplification(c, cfg, h, 2 * periods)
                    r["first_amplification"] = first
                rows.append(r)
                if progress:
                    progress(c, cfg, r)
    return rows


def write_limits(rows: list[dict], out: Path) -> list[Path]:
    out.mkdir(parents=True, exist_ok=True)
    cols = ["kappa", "C2", "order", "extrapolation", "iterations", "richardson", "step_s", "periods",
            "A_vib", "A_energy", "amplification", "first_amplification", "excitation", "unstable", "diverged",
            "steps", "wall_s", "error"]
    csv_path = out / "stability_limits.csv"
    with open(csv_path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(cols)
        for r in rows:
            w.writerow([_fmt_csv(r.get(k)) for k in cols])
    couplings = sorted({(r["kappa"], r["C2"]) for r in rows})
    configs = []
    for r in rows:
        key = Config(r["order"], r["extrapolation"], r["iterations"], r["richardson"])
        if key not in configs:
            configs.append(key)
    lines = ["# Stability limits: Pendulum + MechanismVibration", "",
             "Largest communication step (s) below which every swept step kept the energy",
             "amplification per pendulum period within 1 % of the monolithic reference",
             "(`amplification` in stability_limits.csv; a run above 1 % is measured again over",
             "twice the periods and that one counts).",
             "`> h` = stable at every swept step up to h; `*` = a larger step was stable again;",
             "(x.xx) = the first unstable step.", "",
             "| master | " + " | ".join(f"kappa={k:g} C2={c2:g}" for k, c2 in couplings) + " |",
             "|---|" + "---|" * len(couplings)]
    for cfg in configs:
        cells = []
        for k, c2 in couplings:
            sel = [r for r in rows if (r["kappa"], r["C2"]) == (k, c2)
                   and Config(r["order"], r["extrapolation"], r["iterations"], r["richardson"]) == cfg]
            if not sel:
                cells.append("-")
                continue
            limit, bad, again = stability_limit(sel)
            if bad is None:
                cells.append(f"> {max(r['step_s'] for r in sel):.3g}")
            else:
                cells.append(f"{limit:.3g} ({bad:.3g}){'*' if again else ''}")
        lines.append(f"| {cfg.label} | " + " | ".join(cells) + " |")
    md_path = out / "stability_limits.md"
    md_path.write_text("\n".join(lines) + "\n")
    png = out / "stability_amplification.png"
    plot_limits(rows, png)
    return [csv_path, md_path, png]


def read_limits(path: Path) -> list[dict]:
    """Rows of a stability_limits.csv, typed as `amplification` returns them."""
    rows = []
    with open(path, newline="") as f:
        for r in csv.DictReader(f):
            row = dict(r)
            for k in ("kappa", "C2", "step_s", "A_vib", "A_energy", "amplification", "first_amplification",
                      "excitation", "wall_s"):
                row[k] = float(r[k])
            for k in ("extrapolation", "iterations", "periods", "steps"):
                row[k] = int(r[k])
            for k in ("richardson", "unstable", "diverged"):
                row[k] = r[k] == "True"
            rows.append(row)
    return rows


def _fmt_csv(v):
    if isinstance(v, float):
        return "inf" if math.isinf(v) else f"{v:.10g}"
    return "" if v is None else v


def plot_limits(rows: list[dict], path: Path) -> None:
    import matplotlib
    import matplotlib.ticker

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    couplings = sorted({(r["kappa"], r["C2"]) for r in rows if r["C2"] != 0.0}) or \
        sorted({(r["kappa"], r["C2"]) for r in rows})
    orders = ["gauss-seidel", "jacobi"]
    fig, axes = plt.subplots(len(couplings), 2, figsize=(11, 3.0 * len(couplings) + 0.6), squeeze=False,
                             sharex=True)
    colors = {0: "tab:blue", 1: "tab:orange", 2: "tab:green"}
    top = 3.0  # amplifications above are drawn at the top
    for i, (k, c2) in enumerate(couplings):
        for j, order in enumerate(orders):
            ax = axes[i][j]
            sel = [r for r in rows if (r["kappa"], r["C2"]) == (k, c2) and r["order"] == order]
            groups = sorted({(r["extrapolation"], r["iterations"], r["richardson"]) for r in sel})
            for ex, it, rich in groups:
                g = sorted((r for r in sel if (r["extrapolation"], r["iterations"], r["richardson"]) == (ex, it, rich)),
                           key=lambda r: r["step_s"])
                h = [r["step_s"] for r in g]
                a = [min(r["amplification"], top) for r in g]
                style = ":" if rich else ("--" if it else "-")
                label = f"ex{ex}" + (f" it{it}" if it else "") + (" rich" if rich else "")
                ax.plot(h, a, style, marker="o", ms=3, color=colors[ex], label=label)
                div = [(x, top) for x, r in zip(h, g) if r["diverged"]]
                if div:
                    ax.plot(*zip(*div), "x", color=colors[ex], ms=8)
            ax.axhline(1.01, color="k", lw=0.8, ls="-.")
            ax.axvline(2 * math.pi / (7 * OMEGA01), color="grey", lw=0.8, ls=":")
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.yaxis.set_major_formatter(matplotlib.ticker.ScalarFormatter())
            ax.yaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
            ax.set_ylim(0.85, top * 1.1)
            ax.set_yticks([0.9, 1.0, 1.25, 1.5, 2.0, 3.0])
            ax.set_title(f"{'Gauss-Seidel' if order == 'gauss-seidel' else 'Jacobi'}: kappa = {k:g}, C2 = {c2:g}",
                         fontsize=9)
            if j == 0:
                ax.set_ylabel("energy amplification\nper pendulum period")
            if i == len(couplings) - 1:
                ax.set_xlabel("communication step (s)")
    axes[0][0].legend(fontsize=7, ncol=3, loc="upper left")
    fig.suptitle("Pendulum + mechanism vibration: energy amplification per period beyond the monolithic "
                 f"reference\n(dash-dot: 1 % limit; dotted: vibration period; clipped at {top:g}; x: diverged)",
                 fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


# ---------------------------------------------------------------------------
# 2. Extreme parameters of the grasshopper clock
# ---------------------------------------------------------------------------

def clock_system(pendulum: dict, escapement: dict, settings: MasterSettings, start_time: float = 0.0,
                 record=("tick_time", "tick_w", "amplitude")) -> System:
    return System({"pendulum": ("Pendulum", pendulum), "escapement": ("GrasshopperEscapement", escapement)},
                  CLOCK_LINKS, settings, record={"pendulum": list(record)}, start_time=start_time)


def torque_for_amplitude(amplitude: float, phi_r: float, Q: float, L: float = 1.0, m: float = 1.0,
                         g: float = G) -> float:
    """Torque (N.m) whose energy balance 4 M phi_r = pi I omega0^2 A^2/Q gives amplitude A (rad)."""
    return math.pi * m * L * g * amplitude**2 / (4.0 * phi_r * Q)


def clock_steady_state(Q: float, torque: float, phi_r: float, step: float = 0.5,
                       tolerance_s_per_day: float = 1e-4, rtol: float = 1e-11, atol: float = 1e-13):
    """Co-simulated periodic orbit (clockwork.engine.shooting)."""
    pp = dict(L=1.0, m=1.0, g=G, Q=Q, rtol=rtol, atol=atol)
    esc = dict(torque=torque, phi_r=phi_r)
    with clock_system(pp, esc, MasterSettings(step=step)) as s:
        shooter = Shooter(s.master, {"pendulum": pp, "escapement": esc}, "pendulum", pp)
        guess = energy_balance_amplitude(pp, "GrasshopperEscapement", esc)
        if not guess:
            return None
        return find_steady_state(shooter, guess, phi_r, tolerance=tolerance_s_per_day / analytic.SECONDS_PER_DAY)


def reference_steady_state(Q: float, torque: float, phi_r: float):
    return reference.steady_state(reference.ClockParams(L=1.0, m=1.0, g=G, Q=Q, torque=torque, phi_r=phi_r),
                                  a_max=3.1)


def free_period(amplitude: float, periods: int = 10, step: float = 0.05, escapement: bool = False) -> dict:
    """Mean period of the undamped pendulum released at `amplitude` (rad), from
    its tick times, against clockwork.physics.analytic.exact_period. With
    `escapement`, a GrasshopperEscapement with zero torque is wired in (its
    switches are located but push nothing)."""
    pp = dict(L=1.0, m=1.0, g=G, Q=0.0, phi_start=amplitude, rtol=1e-12, atol=1e-14)
    comps = {"pendulum": ("Pendulum", pp)}
    links = []
    if escapement:
        comps["escapement"] = ("GrasshopperEscapement", dict(torque=0.0, phi_r=math.radians(2.0)))
        links = CLOCK_LINKS
    exact = analytic.exact_period(amplitude, 1.0, G)
    ticks = []
    with System(comps, links, MasterSettings(step=step), record={"pendulum": ["tick_time", "amplitude"]}) as s:
        m = s.master
        port = m.ports["pendulum"]
        i = port.out_names.index("tick_time")

        def on_point(master) -> None:
            if port.out[i] > 0 and (not ticks or port.out[i] != ticks[-1]):
                ticks.append(port.out[i])

        # A tick is an upward zero crossing, at (k + 3/4) periods: stop between two of them.
        m.run_until((periods + 1.0) * exact, on_point)
        events = m.stats.events
        amp_out = s.output("pendulum", "amplitude")
    t = np.asarray(ticks)
    period = (t[-1] - t[0]) / (len(t) - 1)
    return dict(amplitude_deg=math.degrees(amplitude), escapement=escapement, ticks=len(t), period_s=period,
                exact_s=exact, rel_error=period / exact - 1.0, amplitude_out_deg=math.degrees(amp_out),
                events=events)


def clock_run(step: float, stop: float, phi_start_deg: float = 5.0, torque: float = 0.004, Q: float = 1000.0,
              phi_r_deg: float = 2.0, event_location: bool = True) -> dict:
    """Time-series run of the clock: tick times, event count, final state."""
    pp = dict(L=1.0, m=1.0, g=G, Q=Q, phi_start=math.radians(phi_start_deg), rtol=1e-12, atol=1e-14)
    esc = dict(torque=torque, phi_r=math.radians(phi_r_deg))
    ticks, points = [], []
    with clock_system(pp, esc, MasterSettings(step=step, event_location=event_location),
                      record=("tick_time", "phi", "w")) as s:
        m = s.master
        port = m.ports["pendulum"]
        i = port.out_names.index("tick_time")

        def on_point(master) -> None:
            points.append(master.t)
            if port.out[i] > 0 and (not ticks or port.out[i] != ticks[-1]):
                ticks.append(port.out[i])

        m.run_until(stop, on_point)
        return dict(ticks=ticks, events=m.stats.events, points=points, t=m.t,
                    phi=s.output("pendulum", "phi"), w=s.output("pendulum", "w"), stats=vars(m.stats).copy())


def extremes(size: str = "full") -> dict[str, list[dict]]:
    """Every extreme-parameter table."""
    phi_r = math.radians(2.0)
    tables: dict[str, list[dict]] = {}
    rows = []
    qs = (5, 30, 1e3, 1e5, 1e6, 1e7) if size == "full" else (5, 1e3, 1e5)
    for Q in qs:
        M = torque_for_amplitude(math.radians(5.0), phi_r, Q)
        wall = time.perf_counter()
        ours = clock_steady_state(Q, M, phi_r)
        wall = time.perf_counter() - wall
        ref = reference_steady_state(Q, M, phi_r)
        rows.append(dict(Q=Q, torque_Nm=M, stalled=ours.stalled, amplitude_deg=math.degrees(ours.amplitude),
                         amplitude_ref_deg=math.degrees(ref.amplitude),
                         E_T_s_per_day=ours.E_T * analytic.SECONDS_PER_DAY,
                         E_T_ref_s_per_day=ref.E_T * analytic.SECONDS_PER_DAY,
                         diff_s_per_day=(ours.E_T - ref.E_T) * analytic.SECONDS_PER_DAY,
                         iterations=ours.iterations, wall_s=wall))
    tables["extreme_Q"] = rows
    rows = []
    amps = (0.1, 1, 5, 20, 45, 90, 120, 150, 170) if size == "full" else (0.1, 90, 170)
    for a in amps:
        for esc in (False, True):
            rows.append(free_period(math.radians(a), escapement=esc))
    tables["free_period"] = rows
    rows = []
    clock_amps = ((0.1, 0.04), (1, 0.4), (3, 2), (10, 2), (30, 2), (60, 2), (90, 2)) if size == "full" \
        else ((0.1, 0.04), (30, 2))
    for a, pr in clock_amps:
        M = torque_for_amplitude(math.radians(a), math.radians(pr), 1000.0)
        ours = clock_steady_state(1000.0, M, math.radians(pr))
        ref = reference_steady_state(1000.0, M, math.radians(pr))
        rows.append(dict(target_deg=a, phi_r_deg=pr, torque_Nm=M, amplitude_deg=math.degrees(ours.amplitude),
                         amplitude_ref_deg=math.degrees(ref.amplitude),
                         E_T_s_per_day=ours.E_T * analytic.SECONDS_PER_DAY,
                         diff_s_per_day=(ours.E_T - ref.E_T) * analytic.SECONDS_PER_DAY))
    tables["clock_amplitude"] = rows
    rows = []
    for ratio in (0.9, 0.99, 1.01, 1.1):
        M = torque_for_amplitude(ratio * phi_r, phi_r, 1000.0)
        ours = clock_steady_state(1000.0, M, phi_r)
        ref = reference_steady_state(1000.0, M, phi_r)
        rows.append(dict(energy_balance_over_phi_r=ratio, torque_Nm=M, stalled=ours.stalled,
                         stalled_ref=ref.stalled, amplitude_deg=math.degrees(ours.amplitude),
                         amplitude_ref_deg=math.degrees(ref.amplitude), reason=ours.reason))
    tables["phi_r_near_amplitude"] = rows
    rows = []
    for stop in (20.0, 100.0):
        small = clock_run(0.01, stop)
        one = clock_run(stop, stop)
        n = min(len(small["ticks"]), len(one["ticks"]))
        rows.append(dict(stop_s=stop, events_small_step=small["events"], events_one_step=one["events"],
                         ticks_small_step=len(small["ticks"]), ticks_one_step=len(one["ticks"]),
                         first_point_s=one["points"][0], phi_diff_rad=one["phi"] - small["phi"],
                         max_tick_diff_s=float(np.max(np.abs(np.subtract(small["ticks"][-n:], one["ticks"][-n:]))))
                         if n else math.nan))
    tables["one_step"] = rows
    return tables


# ---------------------------------------------------------------------------
# 3. Phase drift over many periods (Hoyng's point C)
# ---------------------------------------------------------------------------

HOYNG_EPS, HOYNG_MU, HOYNG_PHI0 = 1.167245e-4, 1.5e-5, 0.03  # point C of Hoyng's Fig. 3
HOYNG_PERIODS_110_DAYS = 4.8e6  # 1e9 steps of dt = 0.03 in his units


def hoyng_parameters(rtol: float = 1e-11, atol: float = 1e-13) -> tuple[dict, dict]:
    """Hoyng's normalized pendulum phi'' + 2 eps phi' + sin phi = mu d: L = g = m = 1
    (omega0 = 1 rad/s, I = 1, torques in units of m g L), Q = 1/(2 eps)."""
    pend = dict(L=1.0, m=1.0, g=1.0, Q=1.0 / (2.0 * HOYNG_EPS), rtol=rtol, atol=atol)
    esc = dict(torque=HOYNG_MU, phi_r=HOYNG_PHI0)
    return pend, esc


def hoyng_reference():
    """Exact periodic orbit (monolithic scipy shooting, rtol 1e-12)."""
    pend, esc = hoyng_parameters()
    return reference.steady_state(reference.ClockParams(L=1.0, m=1.0, g=1.0, Q=pend["Q"], torque=esc["torque"],
                                                        phi_r=esc["phi_r"]))


def hoyng_settings(step: float, t_end: float) -> MasterSettings:
    """The event time tolerance cannot be finer than the spacing of doubles at
    t_end (see docs/stress.md: below it the master fails)."""
    tol = max(1e-10, 4.0 * math.ulp(t_end))
    return MasterSettings(step=step, event_time_tolerance=tol)


def cosim_limit_cycle(step: float = 1.0, rtol: float = 1e-11, atol: float = 1e-13) -> tuple[float, float]:
    """(W*, T) of the co-simulated orbit on the section phi = 0, w > 0: secant
    iteration on the one-period map to its round-off floor."""
    ref = hoyng_reference()
    pend, esc = hoyng_parameters(rtol, atol)
    params = {"pendulum": pend, "escapement": esc}
    with clock_system(dict(pend, phi_start=0.0, w_start=0.05), esc, MasterSettings(step=step)) as s:
        shooter = Shooter(s.master, params, "pendulum", pend)
        W0 = math.sqrt(2.0 * (1.0 - math.cos(ref.amplitude)))
        W_next, T, *_ = shooter.period_map(W0)
        F0, W1 = W_next - W0, W_next
        for _ in range(30):
            W_next, T, *_ = shooter.period_map(W1)
            F1 = W_next - W1
            if F1 == 0.0 or F1 == F0:
                break
            W0, F0, W1 = W1, F1, W1 - F1 * (W1 - W0) / (F1 - F0)
    return W1, T


def drift_run(periods: int, start_time: float = 0.0, step: float = 1.0, W: float | None = None,
              rtol: float = 1e-11, atol: float = 1e-13, progress=None) -> dict:
    """Tick times of Hoyng's clock started on its co-simulated limit cycle
    (phi = 0, w = W at start_time) over `periods` periods; drift against
    t_1 + k T_ref with T_ref the exact orbit period."""
    ref = hoyng_reference()
    if W is None:
        W, _ = cosim_limit_cycle(step, rtol, atol)
    pend, esc = hoyng_parameters(rtol, atol)
    t_end = start_time + (periods + 0.5) * ref.period
    ticks = np.empty(periods + 2)
    n = 0
    wall = time.perf_counter()
    with clock_system(dict(pend, phi_start=0.0, w_start=W), esc, hoyng_settings(step, t_end),
                      start_time=start_time, record=("tick_time",)) as s:
        m = s.master
        # Ticks only: the compiled core records them without calling back.
        recorder = Recorder(m, [], ticks_of="pendulum")
        chunk = 1000 * ref.period
        while m.t < t_end - 1e-9:
            m.run_until(min(t_end, m.t + chunk), recorder)
            if progress:
                progress(min(len(recorder.ticks), periods), periods)
        n = min(len(recorder.ticks), len(ticks))
        ticks[:n] = recorder.ticks[:n]
        stats = vars(m.stats).copy()
    wall = time.perf_counter() - wall
    # Tick 0 is the start itself (phi = 0 crossing from below is not seen
    # at t0); the first located tick closes period 1.
    t = ticks[:n] - start_time
    k = np.arange(1, n + 1)
    drift = t - k * ref.period
    return dict(periods=n, start_time_s=start_time, step_s=step, T_ref_s=ref.period, drift_end_s=float(drift[-1]),
                per_period_s=float(np.polyfit(k, drift, 1)[0]) if n > 1 else math.nan,
                max_abs_drift_s=float(np.max(np.abs(drift))), wall_s=wall, wall_per_period_us=wall / max(n, 1) * 1e6,
                event_time_tolerance_s=hoyng_settings(step, t_end).event_time_tolerance, stats=stats,
                drift=drift)


def drift_budget(periods: int, per_period_error: float, t_start: float, t_end: float) -> float:
    """Allowed |drift| (s) after `periods` periods run between t_start and t_end.

    - systematic: the error of the co-simulated orbit's period,
      |T_cs - T_ref| from one-period shooting, +10 % for that one-period
      measurement;
    - absolute time: the FMUs and the master step in absolute time, so
      every internal step rounds t + h to the doubles near t. Measured at
      t = 3e7 s (ulp 3.7e-9 s): a bias of -0.3 ulp per period and a random
      walk of 5 ulp per period (no correlation between periods). Allowed:
      1 ulp per period of bias and 3 sigma of a 10 ulp random walk;
    - 16 ulp(t_end) for quantizing the first and the last tick.
    """
    ts = np.linspace(t_start, t_end, 257)
    ulps = np.array([math.ulp(max(abs(x), 1.0)) for x in ts])
    return (periods * (1.1 * abs(per_period_error) + float(np.mean(ulps)))
            + 3.0 * 10.0 * float(np.sqrt(np.mean(ulps**2))) * math.sqrt(periods)
            + 16.0 * math.ulp(max(abs(t_end), 1.0)))


# ---------------------------------------------------------------------------
# 4. Rollback-heavy runs and memory
# ---------------------------------------------------------------------------

def rss_kib() -> int:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    raise RuntimeError("no VmRSS in /proc/self/status")


def rollback_run(events: int, L: float = 0.01, warmup_events: int = 2000, step_fraction: float = 0.25,
                 samples: int = 20) -> dict:
    """A short pendulum (L = 1 cm, T0 = 0.2 s) driven at 5 deg: two located
    torque switches per period, each located by rollback (event prediction
    off: it would land most switches without one). RSS is read after a
    warm-up (allocator pools, caches filled) and at the end."""
    T = analytic.small_angle_period(L, G)
    phi_r = math.radians(2.0)
    M = torque_for_amplitude(math.radians(5.0), phi_r, 1000.0, L=L)
    pp = dict(L=L, m=1.0, g=G, Q=1000.0, phi_start=math.radians(5.0))
    esc = dict(torque=M, phi_r=phi_r)
    trace = []
    with clock_system(pp, esc, MasterSettings(step=step_fraction * T, event_prediction=False), record=()) as s:
        m = s.master
        while m.stats.events < warmup_events:
            m.run_until(m.t + 100 * T)
        gc.collect()
        rss0, e0, rb0 = rss_kib(), m.stats.events, m.stats.rollbacks
        wall = time.perf_counter()
        chunk = max(10.0, events / samples / 2.0) * T
        while m.stats.events - e0 < events:
            m.run_until(m.t + chunk)
            trace.append((m.stats.events - e0, rss_kib()))
        wall = time.perf_counter() - wall
        gc.collect()
        rss1 = rss_kib()
        done, rollbacks = m.stats.events - e0, m.stats.rollbacks - rb0
    return dict(events=done, rollbacks=rollbacks, rss_before_kib=rss0, rss_after_kib=rss1,
                rss_growth_kib=rss1 - rss0, rss_max_kib=max(r for _, r in trace), wall_s=wall,
                wall_per_event_us=wall / done * 1e6, trace=trace)


# ---------------------------------------------------------------------------
# command line
# ---------------------------------------------------------------------------

def _write_table(rows: list[dict], out: Path, stem: str, title: str, note: str = "") -> list[Path]:
    out.mkdir(parents=True, exist_ok=True)
    cols = [k for k in rows[0] if k not in ("stats", "drift", "trace")]
    with open(out / f"{stem}.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(cols)
        for r in rows:
            w.writerow([_fmt_csv(r.get(k)) for k in cols])
    lines = [f"# {title}", ""] + ([note, ""] if note else [])
    lines.append("| " + " | ".join(cols) + " |")
    lines.append("|" + "---|" * len(cols))
    for r in rows:
        lines.append("| " + " | ".join(_fmt_md(r.get(k)) for k in cols) + " |")
    (out / f"{stem}.md").write_text("\n".join(lines) + "\n")
    return [out / f"{stem}.csv", out / f"{stem}.md"]


def _fmt_md(v) -> str:
    if isinstance(v, bool) or v is None:
        return str(v)
    if isinstance(v, float):
        return f"{v:.6g}"
    return str(v)


def cmd_limits(args) -> None:
    if args.from_csv:
        for p in write_limits(read_limits(Path(args.from_csv)), Path(args.out)):
            print("wrote", p)
        return
    size = LIMIT_SIZES[args.size]
    configs = all_configs()
    total = len(size["couplings"]) * sum(len(size["richardson_steps"] if c.richardson else size["steps"])
                                         for c in configs)
    done = [0]

    def progress(c, cfg, r):
        done[0] += 1
        print(f"[{done[0]}/{total}] {c.label:22s} {cfg.label:18s} h={r['step_s']:.4g} s "
              f"A={r['amplification']:.4g}{' DIVERGED' if r['diverged'] else ''} ({r['wall_s']:.2f} s)", flush=True)

    rows = limit_sweep(size["couplings"], configs, size["steps"], size["periods"], size["richardson_steps"],
                       progress=progress)
    for p in write_limits(rows, Path(args.out)):
        print("wrote", p)


def cmd_extremes(args) -> None:
    tables = extremes(args.size)
    titles = {
        "extreme_Q": "Steady state at 5 deg for Q from 5 to 1e7 (torque from the energy balance) "
                     "against the monolithic reference",
        "free_period": "Free pendulum period against the exact (AGM) period",
        "clock_amplitude": "Grasshopper clock from 0.1 to 90 deg (Q = 1000) against the monolithic reference",
        "phi_r_near_amplitude": "Energy-balance amplitude next to phi_r = 2 deg: stall detection",
        "one_step": "One communication step for the whole run (event location on) against a 0.01 s step",
    }
    for stem, rows in tables.items():
        for p in _write_table(rows, Path(args.out), stem, titles[stem]):
            print("wrote", p)


def cmd_drift(args) -> None:
    out = Path(args.out)
    W, T_cs = cosim_limit_cycle(args.step)
    ref = hoyng_reference()
    e = T_cs - ref.period
    print(f"T_ref = {ref.period!r} s, T_cosim = {T_cs!r} s, per-period error {e:.3e} s", flush=True)
    rows = []
    late = HOYNG_PERIODS_110_DAYS * ref.period
    for start, n in ((0.0, args.periods), (late, min(args.periods, args.late_periods))):
        def progress(k, total, start=start):
            if k % 100000 < 1000:
                print(f"  start {start:.3g} s: {k}/{total} periods", flush=True)

        r = drift_run(n, start_time=start, step=args.step, W=W, progress=progress)
        t_end = start + n * ref.period
        r["budget_s"] = drift_budget(n, e, start, t_end)
        r["cosim_period_error_s"] = e
        r["within_budget"] = abs(r["drift_end_s"]) <= r["budget_s"]
        print({k: v for k, v in r.items() if k not in ("drift", "stats")}, flush=True)
        rows.append(r)
    full = drift_budget(int(HOYNG_PERIODS_110_DAYS), e, 0.0, late)
    note = (f"Budget for the full 110 days ({HOYNG_PERIODS_110_DAYS:g} periods, t up to {late:.3g} s): "
            f"{full:.3g} s. Estimated wall time of the full run: "
            f"{rows[0]['wall_per_period_us'] * HOYNG_PERIODS_110_DAYS / 60e6:.0f} min.")
    for p in _write_table(rows, out, "drift", "Phase drift of Hoyng's clock at point C", note):
        print("wrote", p)
    plot_drift(rows, out / "drift.png")


def plot_drift(rows: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(rows), figsize=(5.5 * len(rows), 3.6), squeeze=False)
    for ax, r in zip(axes[0], rows):
        d = r["drift"]
        k = np.arange(1, len(d) + 1)
        stride = max(1, len(d) // 20000)
        ax.plot(k[::stride], d[::stride] * 1e6, lw=0.8)
        ax.plot(k, r["budget_s"] * 1e6 * k / k[-1], "k--", lw=0.8)
        ax.plot(k, -r["budget_s"] * 1e6 * k / k[-1], "k--", lw=0.8)
        ax.set_xlabel("period")
        ax.set_ylabel("t_k - k T_ref (us)")
        ax.set_title(f"start t = {r['start_time_s']:.3g} s", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def cmd_rollback(args) -> None:
    r = rollback_run(args.events)
    print({k: v for k, v in r.items() if k != "trace"})
    for p in _write_table([r], Path(args.out), "rollback", "Rollback-heavy run: memory"):
        print("wrote", p)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("part", choices=["limits", "extremes", "drift", "rollback", "all"])
    p.add_argument("--out", default="out/stress")
    p.add_argument("--size", choices=["ci", "full"], default="full")
    p.add_argument("--periods", type=int, default=None, help="drift: periods from t = 0 [full: 4.8e6, ci: 2000]")
    p.add_argument("--late-periods", type=int, default=2000, help="drift: periods from the 110-day point")
    p.add_argument("--step", type=float, default=1.0, help="drift: communication step in Hoyng's units (s)")
    p.add_argument("--from-csv", default=None, metavar="CSV",
                   help="limits: redo the table and plot from an earlier stability_limits.csv")
    p.add_argument("--events", type=int, default=None, help="rollback: located events [full: 1e6, ci: 2e4]")
    args = p.parse_args(argv)
    if args.periods is None:
        args.periods = int(HOYNG_PERIODS_110_DAYS) if args.size == "full" else 2000
    if args.events is None:
        args.events = 1_000_000 if args.size == "full" else 20_000
    parts = ["limits", "extremes", "drift", "rollback"] if args.part == "all" else [args.part]
    for part in parts:
        print(f"== {part}", flush=True)
        {"limits": cmd_limits, "extremes": cmd_extremes, "drift": cmd_drift, "rollback": cmd_rollback}[part](args)
    return 0


if __name__ == "__main__":
    sys.exit(main())
