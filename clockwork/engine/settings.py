"""What a master is asked to do, and what it counts while doing it."""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

from ..errors import ClosedError, SceneError, UsageError
from ..numbers import shorten


ENGINES = ("auto", "python", "compiled")
# How Model Exchange FMUs are integrated (engine/me_step.py): "auto" (the
# Runge-Kutta pair the tolerance asks for, CVode once the model proves
# stiff), a pair ("dp54", "dop853") or CVode's BDF ("cvode").
ME_SOLVERS = ("auto", "dp54", "dop853", "cvode")
LOOP_MODES = ("solve", "delay")
MAX_THREADS = 256  # master.threads: more would be threads waiting for cores, and memory for their stacks


_INT_MAX = 2**31 - 1  # the compiled core's counts are C ints


@dataclass
class MasterSettings:
    """What a master is asked to do: the communication step, the coupling,
    event location and the engine.

    Every field is also a key of a scene's ``[master]`` table (scenes.md),
    where times may carry a unit (``step = "5 ms"``); here times are plain
    numbers in seconds. The values are checked when the settings are made,
    so that a bad one fails here and not in a long ``run_until``.

    Attributes:
        step: Nominal communication step, s (finite, > 0). ``run_until``
            steps on the drift-free grid ``start_time + k * step``; located
            events add communication points between grid points.
        order: ``"gauss-seidel"`` (each dynamic FMU sees the newest outputs
            of those stepped before it) or ``"jacobi"`` (every FMU sees the
            values at the start of the step).
        extrapolation: Order of the polynomials that hand a dynamic FMU its
            inputs over a step: 0 (zero-order hold), 1 or 2 (through
            ``fmi2SetRealInputDerivatives``, or FMI 3.0's intermediate
            update); lowered per FMU to what it accepts (``master.notes``).
        event_location: Locate the sign changes of the event indicators the
            FMUs declare, rolling every FMU back to a saved state, and put a
            communication point just past each (every FMU must then declare
            ``canGetAndSetFMUstate``).
        event_prediction: Where an indicator's source offers output
            derivatives, extrapolate the indicator before a step near a
            crossing and shorten the step to land just past the predicted
            crossing, without a rollback; a prediction that misses is
            replayed from the last saved state and located as without it.
        event_time_tolerance: How close in time a located event must be to
            the crossing, s (> 0).
        event_indicator_tolerance: How close to zero an event indicator must
            come, in the indicator's own unit (rad for the escapements; > 0).
        iterations: Strong coupling: fixed-point iterations of each step on
            the coupling signals (whole number >= 0; 0: off).
        iteration_tolerance: When strong coupling has converged (the largest
            change of a coupling output between iterations) and when an
            algebraic loop has (``iteration_tolerance * max(1, |input|)``),
            in the signals' own units (> 0).
        richardson: Step doubling: each step is taken whole and as two
            halves, and the step size controlled by the difference (Python
            engine; not together with ``iterations``).
        richardson_tolerance: Tolerance of step doubling on the dynamic FMUs'
            outputs, mixed relative and absolute: a step is accepted where
            ``|whole - halves| / (2 ** (extrapolation + 1) - 1) <=
            richardson_tolerance * (1 + |halves|)`` for every output, or
            where it is already ``min_step`` long (> 0).
        min_step: Smallest step the step-size control of ``richardson``
            takes, s (> 0).
        max_step: Largest step the step-size control of ``richardson``
            proposes, s (> 0); None: no cap (a scene's default is its
            ``step``).
        divergence_limit: An output whose magnitude exceeds this (in the
            output's unit) fails the run as diverged (``SimulationError``
            naming the instance and variable; > 0).
        engine: ``"compiled"`` (the C stepping core), ``"python"`` (the
            reference loop) or ``"auto"`` (the core wherever it covers the
            settings and the links' types, else the Python loop with the
            reason in ``master.engine_reason``). Both give the same bits.
        tolerance: Relative tolerance passed to every FMU
            (``fmi2SetupExperiment``, ``fmi3EnterInitializationMode``; > 0);
            None: each FMU's DefaultExperiment tolerance, where it declares
            one.
        fmi_version: Which build of the bundled FMUs a model name loads: 2
            (``fmus/``) or 3 (``fmus/fmi3/``); a path to an .fmu file is
            whatever version it is.
        early_return: Let FMI 3.0 FMUs that declare
            ``mightReturnEarlyFromDoStep`` return early at their own events,
            which the master handles in Event Mode; False: they handle them
            inside ``fmi3DoStep``, as an FMI 2.0 FMU does.
        me_solver: The integrator of Model Exchange FMUs: ``"auto"`` (the
            Runge-Kutta pair the tolerance asks for, DOP853 at rtol <= 1e-6,
            else Dormand-Prince 5(4); CVode's BDF from the step its
            stiffness test fires), ``"dp54"``, ``"dop853"`` or ``"cvode"``.
        algebraic_loops: How a loop of outputs with direct feedthrough runs:
            ``"solve"`` iterates it to a fixed point wherever outputs are
            brought up to date (to ``iteration_tolerance``), ``"delay"``
            breaks it by a one-step delay.
        threads: How many threads the compiled core steps instances on
            that do not depend on each other within a step (1 to 256; 1:
            one at a time). The same bits on any number; the Python engine
            uses one and says so. See docs/design.md, "Instances on threads".

    Raises:
        SceneError: A value out of its range or of the wrong type, or a
            combination the master cannot run (``richardson`` with
            ``iterations``), in one line naming the key, e.g.
            ``master.step = 0: expected a finite number > 0``.

    Example:
        ```python
        MasterSettings(step=1e-3, extrapolation=1, engine="python")
        ```
    """

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
    # The integrator of Model Exchange FMUs (ME_SOLVERS).
    me_solver: str = "auto"
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
        """Refuse values and combinations the master cannot run.

        Called when the settings are made and again by every master, so a
        field changed afterwards is checked too.

        Raises:
            SceneError: The first bad value or combination, naming its key.
        """
        for key in ("step", "event_time_tolerance", "event_indicator_tolerance", "iteration_tolerance",
                    "richardson_tolerance", "min_step", "divergence_limit"):
            _positive(key, getattr(self, key))
        if self.max_step is not None:
            _positive("max_step", self.max_step)
        for key in ("extrapolation", "iterations"):
            v = getattr(self, key)
            if isinstance(v, bool) or not isinstance(v, numbers.Integral) or not 0 <= v <= _INT_MAX:
                shown = f"<an integer of {int(v).bit_length()} bits>" if isinstance(v, numbers.Integral) \
                    and not isinstance(v, bool) and v > _INT_MAX else repr(v)
                raise SceneError(f"master.{key} = {shown}: expected a whole number from 0 to {_INT_MAX}")
        for key in ("event_location", "event_prediction", "richardson"):
            if not isinstance(getattr(self, key), bool):
                raise SceneError(f"master.{key} = {getattr(self, key)!r}: expected true or false")
        if self.order not in ("gauss-seidel", "jacobi"):
            raise SceneError(f"master.order = {self.order!r}: expected 'gauss-seidel' or 'jacobi'")
        if self.richardson and self.iterations > 0:
            raise SceneError(f"expected 0 with master.richardson = true, got {self.iterations!r}: "
                             "step doubling does not iterate the coupling", key="master.iterations")
        if self.engine not in ENGINES:
            raise SceneError(f"master.engine = {self.engine!r}: expected one of {', '.join(map(repr, ENGINES))}")
        if self.tolerance is not None and not (isinstance(self.tolerance, (int, float)) and self.tolerance > 0):
            raise SceneError(f"master.tolerance = {self.tolerance!r}: expected a number > 0")
        if self.fmi_version not in (2, 3):
            raise SceneError(f"master.fmi_version = {self.fmi_version!r}: expected 2 or 3")
        if self.me_solver not in ME_SOLVERS:
            raise SceneError(f"master.me_solver = {self.me_solver!r}: expected one of "
                             f"{', '.join(map(repr, ME_SOLVERS))}")
        if self.algebraic_loops not in LOOP_MODES:
            raise SceneError(f"master.algebraic_loops = {self.algebraic_loops!r}: expected 'solve' or 'delay'")
        if (isinstance(self.threads, bool) or not isinstance(self.threads, numbers.Integral)
                or not 1 <= self.threads <= MAX_THREADS):
            raise SceneError(f"master.threads = {self.threads!r}: expected a whole number from 1 to {MAX_THREADS}")
        if self.extrapolation not in (0, 1, 2):
            raise SceneError(f"master.extrapolation = {self.extrapolation}: expected 0, 1 or 2")


def _positive(key: str, v) -> None:
    try:
        ok = not isinstance(v, bool) and isinstance(v, numbers.Real) and math.isfinite(v) and v > 0
    except OverflowError:  # an integer beyond a double
        ok = False
    if not ok:
        raise SceneError(f"master.{key} = {shorten(repr(v), 60)}: expected a finite number > 0")


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


def with_model_exchange(stats: "Statistics", instances: list) -> "Statistics":
    """`stats` with each Model Exchange instance's own counts (its
    integrator's steps, right-hand sides, events...) as ``model_exchange``,
    {instance name: counts}, where there are any (else no such attribute, so
    that the statistics of other scenes stay as they are)."""
    if instances:
        stats.model_exchange = {inst.name: inst.statistics() for inst in instances}
    return stats


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
    loop_iterations: int = 0  # algebraic loops: fixed-point sweeps and Newton iterations
    loop_fallbacks: int = 0  # algebraic loops solved by the Newton fallback
