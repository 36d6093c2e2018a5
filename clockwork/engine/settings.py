"""What a master is asked to do, and what it counts while doing it."""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, field, fields

from ..errors import ClosedError, SceneError, UsageError
from ..numbers import shorten


ENGINES = ("auto", "python", "compiled")
# How Model Exchange FMUs are integrated (engine/me_step.py): "auto" (the
# Runge-Kutta pair the tolerance asks for, CVode once the model proves
# stiff), a pair ("dp54", "dop853") or CVode's BDF ("cvode").
ME_SOLVERS = ("auto", "dp54", "dop853", "cvode")
LOOP_MODES = ("solve", "delay")
MAX_THREADS = 256  # master.threads: more would be threads waiting for cores, and memory for their stacks


INT_MAX = 2**31 - 1  # the compiled core's counts are C ints


class BadSetting(ValueError):
    """A value outside its setting's kind or range (Setting.accept): the
    caller names where it came from (a scene key, --set, an argument)."""


@dataclass(frozen=True)
class Setting:
    """What one field of MasterSettings may hold, declared once beside the
    field (``setting(default, Setting(...))``) and read by every path that
    gives it a value: MasterSettings.check, a scene's ``[master]`` table,
    ``--set master.<key>``, a sweep axis, an SSP's clockwork annotation and
    ``clockwork.simulate(master=...)`` (scene/checks.py::master_value reads
    a scene's time units first and hands the number here).

    Attributes:
        kind: ``"time"`` (finite > 0, in `unit` s; a scene may add a unit,
            ``"5 ms"``), ``"number"`` (finite > 0), ``"count"`` (an integer
            from `low` to `high`), ``"choice"`` (one of `choices`) or
            ``"flag"`` (true or false).
        unit: The unit of a time or number ("s"; "1" for a relative
            tolerance; the signal's own unit for an indicator or output).
        low, high: The range of a count.
        choices: The values of a choice, as the field holds them.
        meanings: What each choice does, in the order of `choices`, for
            the refusal (none: the choices alone).
        noun: What a time or number is called in a refusal ("a time").
        note: Why the range is what it is, after the expected values.
        optional: None is a value too (the field's default: see the field).
        follows: In a scene, the field that gives this one its value when
            the scene does not (``max_step`` follows ``step``); the type's
            own default applies elsewhere.
    """

    kind: str
    unit: str = ""
    low: int = 0
    high: int = INT_MAX
    choices: tuple = ()
    meanings: tuple = ()
    noun: str = ""
    note: str = ""
    optional: bool = False
    follows: str = ""

    @property
    def expected(self) -> str:
        """What a refusal says was expected (the words after "expected")."""
        if self.kind in ("time", "number"):
            text = f"{self.noun or ('a time' if self.kind == 'time' else 'a number')} > 0"
        elif self.kind == "count":
            text = f"an integer in [{self.low}, {self.high}]"
        elif self.kind == "flag":
            text = "true or false"
        else:
            shown = [f'"{c}"' if isinstance(c, str) else str(c) for c in self.choices]
            shown = [f"{c} ({m})" for c, m in zip(shown, self.meanings)] or shown
            text = f"{', '.join(shown[:-1])} or {shown[-1]}"
        return f"{text} ({self.note})" if self.note else text

    def accept(self, value):
        """`value` as the field holds it (a float for a time or number, an
        int for a count); BadSetting when it is not of the kind or out of
        the range."""
        if value is None and self.optional:
            return None
        if self.kind == "flag":
            if isinstance(value, bool):
                return value
        elif isinstance(value, bool):
            pass  # true is no number, count or choice
        elif self.kind in ("time", "number"):
            if isinstance(value, numbers.Real):
                try:
                    x = float(value)
                except (OverflowError, TypeError, ValueError):  # an integer beyond a double
                    x = math.nan
                if math.isfinite(x) and x > 0:
                    return x
        elif self.kind == "count":
            if isinstance(value, numbers.Integral) and self.low <= value <= self.high:
                return int(value)
        elif isinstance(value, (str, numbers.Integral)):  # a choice: a text with texts, a number with numbers
            for c in self.choices:
                if isinstance(c, str) == isinstance(value, str) and c == value:
                    return c
        raise BadSetting(self.expected)


def setting(default, spec: Setting):
    """A MasterSettings field: its default and what it may hold."""
    return field(default=default, metadata={"setting": spec})


_TIME = Setting("time", "s")
_POSITIVE = Setting("number")
_FLAG = Setting("flag")


@dataclass
class MasterSettings:
    """What a master is asked to do: the communication step, the coupling,
    event location and the engine.

    The one type of the master's settings: a scene holds its ``[master]``
    table as one (scene.model.Scene.master), and every field is a key of
    that table (scenes.md), where times may carry a unit (``step = "5
    ms"``); here times are plain numbers in seconds. What each field may
    hold is declared once, beside it (`Setting`), and checked once, when
    the settings are made (``check``), so that a bad one fails here and not
    in a long ``run_until``; the scene's reading of a key, ``--set``, an SSP
    annotation and ``clockwork.simulate(master=...)`` check through the same
    declaration and name where the value came from.

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
            proposes, s (> 0); None: no cap. A scene that does not give it
            caps at its ``step`` (and a sweep of the step moves the cap
            with it): the field follows ``step`` there.
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
        me_groups: Model Exchange FMUs connected to each other run as one
            group (one integrator, their connections evaluated at every
            stage, their events located together); False: each steps
            alone and sees the others at communication points.
        algebraic_loops: How a loop of outputs with direct feedthrough runs:
            ``"solve"`` iterates it to a fixed point wherever outputs are
            brought up to date (to ``iteration_tolerance``), ``"delay"``
            breaks it by a one-step delay.
        threads: How many threads the compiled core steps instances on
            that do not depend on each other within a step (1 to 256; 1:
            one at a time). The same bits on any number; the Python engine
            uses one and says so. See docs/design.md, "Instances on threads".
        divergence_limit: An output whose magnitude exceeds this (in the
            output's unit) fails the run as diverged (``SimulationError``
            naming the instance and variable; > 0).

    Raises:
        SceneError: A value out of its range or of the wrong type, or a
            combination the master cannot run (``richardson`` with
            ``iterations``), in one line naming the key, e.g.
            ``master.step = 0: expected a time > 0``.

    Example:
        ```python
        MasterSettings(step=1e-3, extrapolation=1, engine="python")
        ```
    """

    step: float = setting(0.01, _TIME)  # nominal communication step, s
    order: str = setting("gauss-seidel", Setting("choice", choices=("gauss-seidel", "jacobi")))
    extrapolation: int = setting(0, Setting("choice", choices=(0, 1, 2),
                                            note="order of the input extrapolation polynomial"))
    event_location: bool = setting(True, _FLAG)
    # Predict an indicator's crossing before the step from its source's
    # output derivatives and land on it without a rollback (location.plan).
    event_prediction: bool = setting(True, _FLAG)
    event_time_tolerance: float = setting(1e-10, _TIME)  # s
    # in the indicator's unit (rad for the escapements)
    event_indicator_tolerance: float = setting(1e-12, Setting("number", "the indicator's"))
    # strong coupling: fixed-point iterations per step (0 = off)
    iterations: int = setting(0, Setting("count", low=0, high=INT_MAX, note="0 = no fixed-point iteration"))
    iteration_tolerance: float = setting(1e-10, Setting("number", "the signals'"))
    richardson: bool = setting(False, _FLAG)
    richardson_tolerance: float = setting(1e-8, Setting("number", "1"))
    min_step: float = setting(1e-9, _TIME)  # s
    max_step: float | None = setting(None, Setting("time", "s", optional=True, follows="step"))  # s; None: no cap
    # "compiled": the C stepping core (engine/compiled.py); "python": the
    # reference loop in master.py; "auto": compiled where it covers the settings.
    engine: str = setting("auto", Setting("choice", choices=ENGINES))
    # Relative tolerance passed to every FMU (fmi2SetupExperiment,
    # fmi3EnterInitializationMode); None:
    # each FMU's DefaultExperiment tolerance, where it declares one.
    tolerance: float | None = setting(None, Setting("number", "1", noun="a relative tolerance", optional=True,
                                                    note="given to every FMU's fmi2SetupExperiment"))
    # Which build of the bundled FMUs a model name loads: 2 (fmus/) or 3
    # (fmus/fmi3/); a path to an .fmu file is whatever it is.
    fmi_version: int = setting(2, Setting("choice", choices=(2, 3),
                                          note="which build of the bundled FMUs model names load"))
    # FMI 3.0 instances that declare mightReturnEarlyFromDoStep are allowed
    # to return early at their own events (handled there in event mode);
    # false: they handle them inside fmi3DoStep, as an FMI 2.0 FMU does.
    early_return: bool = setting(True, _FLAG)
    # The integrator of Model Exchange FMUs (ME_SOLVERS).
    me_solver: str = setting("auto", Setting("choice", choices=ME_SOLVERS,
                                             note="the integrator of Model Exchange FMUs"))
    # Model Exchange FMUs connected to each other run as one group: one
    # integrator over their states, their connections at every stage
    # (engine/me_group.py); false: each steps alone, as a Co-Simulation FMU.
    me_groups: bool = setting(True, _FLAG)
    # Algebraic loops (outputs with direct feedthrough that feed each other):
    # "solve" iterates each loop's inputs to a fixed point wherever outputs
    # are brought up to date, to iteration_tolerance; "delay" breaks it by a
    # one-step delay (the loop's members are read once, after their step).
    algebraic_loops: str = setting("solve", Setting("choice", choices=LOOP_MODES,
                                                    meanings=("iterate each loop to a fixed point",
                                                              "break it by one step")))
    # Threads the compiled core steps instances on (instances that do not
    # depend on each other within a step, each on one thread at a time;
    # engine/parallel.py), the same bits as 1. The Python engine steps on
    # one. The FMUs must allow instances on different threads: docs/design.md.
    threads: int = setting(1, Setting("count", low=1, high=MAX_THREADS,
                                      note="threads the compiled core steps independent instances on"))
    # |output| beyond this (in the output's unit) fails the run as diverged
    divergence_limit: float = setting(1e8, Setting("number", "the output's"))

    def __post_init__(self) -> None:
        self.check()  # a bad setting is refused where it is made, not in an endless run_until

    def check(self) -> None:
        """Refuse values and combinations the master cannot run, and hold
        each value as its field's kind (a float for a time, an int for a
        count: numpy's numbers become Python's).

        Called when the settings are made and again by every master, so a
        field changed afterwards is checked too.

        Raises:
            SceneError: The first bad value or combination, naming its key.
        """
        for name, spec in SETTINGS.items():
            value = getattr(self, name)
            try:
                accepted = spec.accept(value)
            except BadSetting as e:
                raise SceneError(f"expected {e}", key=f"master.{name} = {_shown(value)}") from None
            if accepted is not value:
                setattr(self, name, accepted)
        if self.richardson and self.iterations > 0:
            raise SceneError(f"expected 0 with master.richardson = true, got {self.iterations!r}: "
                             "step doubling does not iterate the coupling", key="master.iterations")

    def as_dict(self) -> dict:
        """{field: value}, in the order of the fields (a scene's [master] keys)."""
        return {name: getattr(self, name) for name in SETTINGS}


# {field: what it may hold}, in the order of the fields: the keys of a
# scene's [master] table, of --set master.<key>, of an SSP's annotation.
SETTINGS: dict[str, Setting] = {f.name: f.metadata["setting"] for f in fields(MasterSettings)}
DEFAULTS: dict[str, object] = {f.name: f.default for f in fields(MasterSettings)}


def _shown(value) -> str:
    """A refused value, for the line that refuses it."""
    if isinstance(value, numbers.Integral) and not isinstance(value, bool) and abs(value) > INT_MAX:
        return f"<an integer of {int(value).bit_length()} bits>"
    return shorten(repr(value), 60)


def check_run(instances: dict, t_now: float, t_stop, look: bool = True, call: str = "run_until") -> float:
    """The stop time of a run_until (or another `call`), checked: the
    instances still live (looked at unless `look` is false: none was freed
    since the last look), and `t_stop` a finite time (s) not before `t_now`.
    Returns it as a float."""
    if look and any(getattr(inst, "freed", False) for inst in instances.values()):
        raise ClosedError("this System was freed (used after its `with` block or free()): build a new System")
    if isinstance(t_stop, bool) or not isinstance(t_stop, numbers.Real) or not math.isfinite(t_stop):
        raise UsageError(f"{call}({t_stop!r}): expected a finite time in s")
    if t_stop < t_now:
        raise UsageError(f"{call}({t_stop!r}): the system is already at t = {t_now!r} s; "
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
