"""What a master is asked to do, and what it counts while doing it."""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

from ..errors import ClosedError, SceneError, UsageError


ENGINES = ("auto", "python", "compiled")


@dataclass
class MasterSettings:
    step: float = 0.01  # nominal communication step, s
    order: str = "gauss-seidel"  # or "jacobi"
    extrapolation: int = 0  # order of the input polynomials: 0, 1, 2
    event_location: bool = True
    # Predict an indicator's crossing before the step from its source's
    # output derivatives and land on it without a rollback (location.plan).
    event_prediction: bool = True
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
        for key in ("event_location", "event_prediction", "richardson"):
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
        if self.extrapolation not in (0, 1, 2):
            raise SceneError(f"master.extrapolation = {self.extrapolation}: expected 0, 1 or 2")


def _positive(key: str, v) -> None:
    if isinstance(v, bool) or not isinstance(v, numbers.Real) or not math.isfinite(v) or v <= 0:
        raise SceneError(f"master.{key} = {v!r}: expected a finite number > 0")


def check_run(instances: dict, t_now: float, t_stop) -> float:
    """The stop time of a run_until, checked: the instances still live, and
    `t_stop` a finite time (s) not before `t_now`. Returns it as a float."""
    if any(getattr(inst, "freed", False) for inst in instances.values()):
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
    predicted_landings: int = 0  # events located by a predicted step, without a rollback
    mispredicted: int = 0  # predicted steps that crossed beyond the tolerance (then replayed and located)
