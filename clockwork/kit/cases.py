"""The regression kit's cases: what each one runs, how it is graded, its reference.

A case is a scene (a bundled scenario or one of ``kit/scenes``) cut to a
horizon, an output grid, the signals its tube covers and the events it
checks. Its reference comes from ``physics.reference`` (the whole clock in
one scipy DOP853 integration at rtol 1e-12 with every escapement switch
located), never from a co-simulation.

The tolerances (``Tolerances``) were sized by ``benchmarks/regression_kit_table.py
--calibrate``: clockwork's own master (event location on, the scene's
settings) on each case, its worst error (as written, and from its grid rows
alone, as a tool that writes only the grid would show it) times 10, rounded
up to 1, 2 or 5 times a power of ten, at least 1e-9 (the reference is known
to ~1e-10); the same master without event location, and with a coarse fixed
step of 5 grid intervals, fails every case with events.
docs/regression-kit.md has the numbers.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import UsageError
from ..paths import scenarios_dir
from ..physics import analytic
from ..physics.reference import ClockParams, Vibration, simulate

HERE = Path(__file__).resolve().parent
SCENES = HERE / "scenes"
HOYNG_MU0 = 2e-5
HOYNG_EPS = 2.5e-4
HOYNG_PHI0 = 0.03
HOYNG_T0 = 2.0 * math.pi


@dataclass(frozen=True)
class Tolerances:
    """A case's acceptance tube and event tolerances.

    tube: {signal: half-width in the signal's unit} around the reference at
    every sample of the output grid (fmpy's band with dx = 1 sample: no
    horizontal slack); ticks_s / switches_s: largest |t - t_expected| of
    the detected ticks (upward zero crossings of phi) and escapement
    switches (sign changes of the escapement torque), s."""

    tube: dict
    ticks_s: float
    switches_s: float | None = None


@dataclass(frozen=True)
class Case:
    name: str  # the model name of the case's files (<name>.fmu / <name>.ssp)
    kind: str  # "fmu": one FMU in the cross-check layout; "ssp": a coupled system
    scene: str  # scene file (relative to the repository or kit/scenes)
    title: str
    tests: str  # what it tests (README)
    stop: float  # s
    grid: float  # s, output interval of the reference and of the tools' results
    tolerances: Tolerances
    overrides: tuple = ()
    phi: str = "pendulum.phi"  # signal names as the case's files write them
    w: str = "pendulum.w"
    tube_signals: tuple = ("pendulum.phi", "pendulum.w")
    switch_signal: str | None = "escapement.tau"
    jump: tuple | None = None  # (t s, input signal, value before, value after)
    notes: list = field(default_factory=list)

    @property
    def signals(self) -> tuple:
        """Columns of the reference CSV."""
        return self.tube_signals + ((self.switch_signal,) if self.switch_signal else ())


def _hoyng_w_start() -> float:
    return analytic.hoyng_stationary_amplitude(HOYNG_MU0, HOYNG_EPS, HOYNG_PHI0)  # omega0 = 1 rad/s


def _cases() -> list[Case]:
    return [
        Case("Pendulum", "fmu", str(SCENES / "free_pendulum.toml"),
             "The free pendulum (Pendulum FMU alone, start values of its model description)",
             "The pendulum's own integration over 10 swings: the nonlinear period (AGM, Ziemkiewicz "
             "Eq. 2 with its circular error) at a decaying amplitude (Q = 1000), no escapement. "
             "A tool passes if it reproduces phi and w on the 0.01 s grid and the upward zero "
             "crossings of phi (ticks).",
             stop=20.0, grid=0.01,
             tolerances=Tolerances({"phi": 1e-9, "w": 1e-9}, ticks_s=1e-9),
             phi="phi", w="w", tube_signals=("phi", "w"), switch_signal=None),
        Case("GrasshopperClock", "ssp", "core_grasshopper.toml",
             "The grasshopper clock (Pendulum + GrasshopperEscapement), 100 s",
             "The relay escapement's switches at phi = +-phi_r: a master must switch the torque "
             "where phi crosses the switch angle, not at the next communication point. "
             "A late switch changes the energy per period, hence amplitude and rate.",
             stop=100.0, grid=0.01, overrides=("experiment.stop=100",),
             tolerances=Tolerances({"pendulum.phi": 1e-9, "pendulum.w": 1e-9}, ticks_s=1e-9, switches_s=1e-5)),
        Case("ChronometerClock", "ssp", str(SCENES / "chronometer.toml"),
             "The chronometer (Pendulum + ChronometerEscapement), 60 s",
             "A torque that switches on at the window's lower edge when moving up, off at the upper "
             "edge: two switches per period, each a discontinuity of the pendulum's acceleration.",
             stop=60.0, grid=0.01,
             tolerances=Tolerances({"pendulum.phi": 1e-9, "pendulum.w": 1e-9}, ticks_s=1e-9, switches_s=5e-6)),
        Case("DragClock", "ssp", "core_grasshopper_drag.toml",
             "The grasshopper clock with air drag (Pendulum + GrasshopperEscapement + Drag), 100 s",
             "A direct-feedthrough element (drag torque -(c1 w + c2 w|w|) from the pendulum's velocity) "
             "in the loop beside the relay: a master must feed it without a step's delay.",
             stop=100.0, grid=0.01, overrides=("experiment.stop=100",),
             tolerances=Tolerances({"pendulum.phi": 1e-5, "pendulum.w": 5e-5}, ticks_s=2e-5, switches_s=1e-4)),
        Case("HoyngTorqueJump", "ssp", str(SCENES / "hoyng_jump.toml"),
             "Hoyng's torque jump (normalized units: period 2 pi s), 125.66 s (20 nominal periods)",
             "A time event from outside: the drive doubles at t = 20 pi s (the case's _in.csv steps "
             "escapement.vibration_velocity from 0 to 1, velocity_gain = 1), off the output grid, "
             "on a clock whose escapement torque is small (mu = 2e-5): the rate and amplitude answer "
             "of Hoyng Eqs. (16), (18).",
             stop=125.66, grid=0.02,
             overrides=(f"pendulum.w_start={_hoyng_w_start()!r}", "experiment.stop=125.66"),
             tolerances=Tolerances({"pendulum.phi": 1e-9, "pendulum.w": 1e-9}, ticks_s=2e-8, switches_s=1e-5),
             jump=(10.0 * HOYNG_T0, "escapement.vibration_velocity", 0.0, 1.0)),
        Case("VibratingClock", "ssp", "core_vibration.toml",
             "The clock with a vibrating mechanism (Pendulum + GrasshopperEscapement + MechanismVibration), 16 s",
             "Two dynamic FMUs coupled both ways (phi to the mechanism, its torque back), plus the "
             "relay. The horizon, 16 s, is shorter than the Lyapunov time of the two-oscillator "
             "clock: 1/lambda = 20 s with the paper's largest exponent (0.05 1/s, Ziemkiewicz "
             "Fig. 10(b)); clockwork measures 2.1e-3 1/s for that nonlinear clock (docs/gallery.md), "
             "and this mode is the linear (kappa = 0), detuned one of core_vibration.toml. So the "
             "reference is a meaningful target: errors are not amplified chaotically.",
             stop=16.0, grid=0.01, overrides=("experiment.stop=16",),
             tube_signals=("pendulum.phi", "pendulum.w", "vibration.a2"),
             tolerances=Tolerances({"pendulum.phi": 5e-6, "pendulum.w": 1e-5, "vibration.a2": 5e-5},
                                   ticks_s=5e-6, switches_s=1e-3)),
    ]


CASES = {c.name: c for c in _cases()}


def case(name: str) -> Case:
    if name not in CASES:
        raise UsageError(f"unknown case {name!r} (known: {', '.join(CASES)})")
    return CASES[name]


def load_case_scene(c: Case, extra: tuple = ()):
    """The case's scene (run layer's loader, every kind registered)."""
    from ..run.catalog import load_scene

    path = Path(c.scene)
    if not path.is_absolute():  # a scene that comes with clockwork
        path = scenarios_dir() / path
    return load_scene(path, list(c.overrides) + list(extra))


# --- the reference ---------------------------------------------------------------


def clock_params(scene) -> tuple[ClockParams, float, float]:
    """The scene's clock as physics.reference parameters, and (phi0, w0)."""
    from ..analyses.context import parameters
    from ..analyses.escapements import GRASSHOPPER, escapement

    p = parameters(scene)

    def val(inst, name):
        return float(p[inst][name])

    cp = ClockParams(L=val("pendulum", "L"), m=val("pendulum", "m"), g=val("pendulum", "g"),
                     Q=val("pendulum", "Q"), escapement="none")
    if "escapement" in p:
        model = scene.components["escapement"].model_name
        cp.torque = val("escapement", "torque")
        kind = escapement(model)
        if kind is None:
            raise ValueError(f"kit cases know no escapement {model}")
        cp.escapement = kind.reference
        if model == GRASSHOPPER:
            cp.phi_r = val("escapement", "phi_r")
            if int(val("escapement", "profile")) != 0 or val("escapement", "noise_rms") != 0.0:
                raise ValueError("kit cases use the constant profile without noise")
        else:
            cp.alpha_m1, cp.alpha_m2 = val("escapement", "alpha_m1"), val("escapement", "alpha_m2")
    if "drag" in p:
        cp.c1, cp.c2 = val("drag", "c1"), val("drag", "c2")
    if "vibration" in p:
        if abs(val("vibration", "inertia") - cp.inertia) > 1e-12 * cp.inertia:
            raise ValueError("the reference assumes vibration.inertia = m L^2")
        cp.vibration = Vibration(gamma2=val("vibration", "gamma2"), omega02=val("vibration", "omega02"),
                                 kappa=val("vibration", "kappa"), C1=val("vibration", "C1"),
                                 C2=val("vibration", "C2"), a2_start=val("vibration", "a2_start"),
                                 a2dot_start=val("vibration", "a2dot_start"))
    return cp, val("pendulum", "phi_start"), val("pendulum", "w_start")


@dataclass
class Reference:
    time: np.ndarray  # s, the output grid
    columns: dict  # {signal: values on the grid}
    ticks: np.ndarray  # s
    switches: np.ndarray  # s
    notes: list


def grid_times(c: Case) -> np.ndarray:
    n = round(c.stop / c.grid)
    return np.arange(n + 1) * c.grid


def reference(c: Case, rtol: float = 1e-12, atol: float = 1e-14) -> Reference:
    """The monolithic scipy solution of the case on its output grid."""
    scene = load_case_scene(c)
    cp, phi0, w0 = clock_params(scene)
    t = grid_times(c)
    segments = []
    if c.jump is None:
        segments.append(simulate(cp, phi0, w0, c.stop, dense=True, rtol=rtol, atol=atol))
    else:
        t_jump, _, before, after = c.jump
        gain = 1.0  # escapement.velocity_gain in the kit's scene
        cp.torque = float(scene.components["escapement"].parameters["torque"]) * (1.0 + gain * abs(before))
        first = simulate(cp, phi0, w0, t_jump, dense=True, rtol=rtol, atol=atol)
        segments.append(first)
        cp2 = ClockParams(**{**cp.__dict__})
        cp2.torque = float(scene.components["escapement"].parameters["torque"]) * (1.0 + gain * abs(after))
        vib0 = tuple(first.y[2:4]) if cp.vibration is not None else None
        segments.append(simulate(cp2, first.y[0], first.y[1], c.stop, t0=t_jump, mode=first.mode, vib0=vib0,
                                 dense=True, rtol=rtol, atol=atol))
    values = np.empty((len(t), 4 if cp.vibration is not None else 2))
    bounds = [0.0] + ([c.jump[0]] if c.jump else []) + [c.stop]
    for k, seg in enumerate(segments):
        last = k == len(segments) - 1
        sel = (t >= bounds[k]) & ((t <= bounds[k + 1]) if last else (t < bounds[k + 1]))
        values[sel] = seg.sol(t[sel]).T
    names = {"phi": 0, "w": 1, "a2": 2}
    columns = {s: values[:, names[s.split(".")[-1]]] for s in c.tube_signals}
    ticks = np.concatenate([s.ticks for s in segments])
    switches = np.concatenate([s.switch_times for s in segments])
    if c.switch_signal:
        columns[c.switch_signal] = _torque(cp, phi0, w0, switches, t, c, scene)
    notes = []
    if c.kind == "fmu" and cp.escapement == "none":
        notes.append(_agm_note(cp, segments[0]))
    return Reference(t, columns, ticks, switches, notes)


def _torque(cp: ClockParams, phi0: float, w0: float, switches: np.ndarray, t: np.ndarray, c: Case,
            scene) -> np.ndarray:
    """The escapement torque on the grid (right limits): every switch flips
    the grasshopper's direction or the chronometer's on/off."""
    from ..physics.reference import initial_mode

    flips = np.searchsorted(switches, t, side="right") % 2 == 1
    base = float(scene.components["escapement"].parameters.get("torque", cp.torque))
    amp = np.full(len(t), base)
    if c.jump is not None:
        amp = np.where(t < c.jump[0], base * (1 + abs(c.jump[2])), base * (1 + abs(c.jump[3])))
    mode = initial_mode(cp, phi0, w0)
    if cp.escapement == "grasshopper":
        return np.where(flips, -mode[0], mode[0]) * amp
    return np.where(flips != bool(mode[0]), amp, 0.0)


def _agm_note(cp: ClockParams, res) -> str:
    """The reference's periods against the AGM period at the swing's amplitude."""
    turns = np.abs(res.turn_phi)
    T = np.diff(res.ticks)
    # The period between ticks k and k+1 spans the turning points between them.
    worst = 0.0
    for k in range(len(T)):
        inside = turns[(res.turn_times > res.ticks[k]) & (res.turn_times < res.ticks[k + 1])]
        if len(inside) == 0:
            continue
        A = float(np.mean(inside))
        worst = max(worst, abs(T[k] / analytic.exact_period(A, cp.L, cp.g) - 1.0))
    return (f"Periods between ticks against the AGM period at the mean amplitude of the swing "
            f"(Q = {cp.Q:g}: the amplitude decays by {100 * (1 - turns[-1] / turns[0]):.2f} % over the run): "
            f"largest relative difference {worst:.2g}.")
