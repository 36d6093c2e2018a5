"""What a master is asked to do, and what it counts while doing it."""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

from ..errors import ClosedError, SceneError, UsageError


ENGINES = ("auto", "python", "compiled")
LOOP_MODES = ("solve", "delay")
MAX_THREADS = 256  # master.threads: more would be threads waiting for cores, and memory for their stacks


@dataclass
class MasterSettings:
    step: float = 0.01  # nominal communication step, s
    order: str = "gauss-seidel"  # or "jacobi"
    extrapolation: int = 0  # order of the input polynomials: 0, 1, 2
    event_location: bool = True
    event_time_tolerance: float = 1e-10  # s
    event_indicator_tolerance: float = 1e-12  # in the indicator's unit (rad)
    iterations: int = 0  # strong coupling: fixed-point iterations per step (0 = off)
    iteration_tolerance: float = 1e-10
    richardson: bool = False
    richardson_tolerance: float = 1e-8
    min_step: float = 1e-9  # s
    max_step: float | None = None  # s; None = step
    divergence_limit: float = 1e8  # |output| beyond this counts as divergence
    # "compiled": the C stepping core (engine/compiled.py); "python": the
    # reference loop in master.py; "auto": compiled where it covers the settings.
    engine: str = "auto"
    # Relative tolerance passed to every FMU (fmi2SetupExperiment,
    # fmi3EnterInitializationMode); None:
    # each FMU's DefaultExperiment tolerance, where it declares one.
    tolerance: float | None = None
    # Which build of the bundled FMUs a model name loads: 2 (fmus/) or 3
    # (fmus/fmi3/); a path to an .fmu file is whatever it is.
    fmi_version: int = 2
    # FMI 3.0 instances that declare mightReturnEarlyFromDoStep are allowed
    # to return early at their own events (handled there in event mode);
    # false: they handle them inside fmi3DoStep, as an FMI 2.0 FMU does.
    early_return: bool = True
    # Algebraic loops (outputs with direct feedthrough that feed each other):
    # "solve" iterates each loop's inputs to a fixed point wherever outputs
    # are brought up to date, to iteration_tolerance; "delay" breaks it by a
    # one-step delay (the loop's members are read once, after their step).
    algebraic_loops: str = "solve"
    # Threads the compiled core steps instances on (instances that do not
    # depend on each other within a step, each on one thread at a time;
    # engine/parallel.py), the same bits as 1. The Python engine steps on
    # one. The FMUs must allow instances on different threads: docs/design.md.
    threads: int = 1

    def __post_init__(self) -> None:
        self.check()  # a bad setting is refused where it is made, not in an endless run_until

    def check(self) -> None:
        """Refuse values and combinations the master cannot run (SceneError: bad input)."""
        for key in ("step", "event_time_tolerance", "event_indicator_tolerance", "iteration_tolerance",
                    "richardson_tolerance", "min_step", "divergence_limit"):
            _positive(key, getattr(self, key))
        if self.max_step is not None:
            _positive("max_step", self.max_step)
        for key in ("extrapolation", "iterations"):
            v = getattr(self, key)
            if isinstance(v, bool) or not isinstance(v, numbers.Integral) or v < 0:
                raise SceneError(f"master.{key} = {v!r}: expected a whole number >= 0")
        for key in ("event_location", "richardson"):
            if not isinstance(getattr(self, key), bool):
                raise SceneError(f"master.{key} = {getattr(self, key)!r}: expected true or false")
        if self.order not in ("gauss-seidel", "jacobi"):
            raise SceneError(f"master.order = {self.order!r}: expected 'gauss-seidel' or 'jacobi'")
        if self.richardson and self.iterations > 0:
            raise SceneError("master.richardson and master.iterations cannot be combined: "
                             "step doubling does not iterate the coupling")
        if self.engine not in ENGINES:
            raise SceneError(f"master.engine = {self.engine!r}: expected one of {', '.join(map(repr, ENGINES))}")
        if self.tolerance is not None and not (isinstance(self.tolerance, (int, float)) and self.tolerance > 0):
            raise SceneError(f"master.tolerance = {self.tolerance!r}: expected a number > 0")
        if self.fmi_version not in (2, 3):
            raise SceneError(f"master.fmi_version = {self.fmi_version!r}: expected 2 or 3")
        if self.algebraic_loops not in LOOP_MODES:
            raise SceneError(f"master.algebraic_loops = {self.algebraic_loops!r}: expected 'solve' or 'delay'")
        if (isinstance(self.threads, bool) or not isinstance(self.threads, numbers.Integral)
                or not 1 <= self.threads <= MAX_THREADS):
            raise SceneError(f"master.threads = {self.threads!r}: expected a whole number from 1 to {MAX_THREADS}")
        if self.extrapolation not in (0, 1, 2):
            raise SceneError(f"master.extrapolation = {self.extrapolation}: expected 0, 1 or 2")


def _positive(key: str, v) -> None:
    if isinstance(v, bool) or not isinstance(v, numbers.Real) or not math.isfinite(v) or v <= 0:
        raise SceneError(f"master.{key} = {v!r}: expected a finite number > 0")


def check_run(instances: dict, t_now: float, t_stop, look: bool = True) -> float:
    """The stop time of a run_until, checked: the instances still live
    (looked at unless `look` is false: none was freed since the last look),
    and `t_stop` a finite time (s) not before `t_now`. Returns it as a float."""
    if look and any(getattr(inst, "freed", False) for inst in instances.values()):
        raise ClosedError("this System was freed (used after its `with` block or free()): build a new System")
    if isinstance(t_stop, bool) or not isinstance(t_stop, numbers.Real) or not math.isfinite(t_stop):
        raise UsageError(f"run_until({t_stop!r}): expected a finite time in s")
    if t_stop < t_now:
        raise UsageError(f"run_until({t_stop!r}): the system is already at t = {t_now!r} s; "
                         "time only runs forward (restart() starts again)")
    return float(t_stop)


def rollback_need(settings, indicators: bool) -> tuple[str, str] | None:
    """(key, what needs it) when these settings take every FMU back to a
    saved state (fmi2GetFMUstate/fmi2SetFMUstate), else None. `settings`:
    anything with MasterSettings' field names; `indicators`: whether any
    FMU declares event indicators."""
    if settings.iterations > 0:
        return "master.iterations", "iterating the coupling"
    if settings.richardson:
        return "master.richardson", "step doubling"
    if settings.event_location and indicators:
        return "master.event_location", "locating events"
    return None


@dataclass
class Statistics:
    steps: int = 0
    events: int = 0
    event_iterations: int = 0
    rollbacks: int = 0
    replays: int = 0
    states_saved: int = 0
    rejected: int = 0
    coupling_iterations: int = 0
    loop_iterations: int = 0  # algebraic loops: fixed-point sweeps and Newton iterations
    loop_fallbacks: int = 0  # algebraic loops solved by the Newton fallback
