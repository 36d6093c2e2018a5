"""A wired, instantiated system of FMUs: the engine's front door.

Scenes are turned into one by the analyses (clockwork.analyses.context);
tests, benchmarks and the Python API build one directly:
``System({"pendulum": ("Pendulum", {...})}, ["pendulum.phi -> escapement.phi", ...],
MasterSettings(...))``. A model name is looked up in $CLOCKWORK_FMU_DIR
(else the repository's fmus/); a path ending .fmu is taken as it is.
``inputs`` (engine.samples.Samples) drives unconnected inputs from samples.
"""

from __future__ import annotations

import difflib
import math
import numbers
import threading
from pathlib import Path

from ..arguments import Anything, Call, Either, Instance as Of, Integer, Mapping, Optional, Path as PathSpec, Real, Sequence, Text, \
    Flag, Tuple, checked, show
from ..errors import ClosedError, SceneError, UsageError
from ..fmi.description import INTEGER_TYPES, REAL_TYPES, int_range, resolve_fmu
from ..fmi.description import variables as described
from ..fmi.calls import free_all
from ..fmi.contract import Instance
from ..fmi.values3 import flat_values
from .instances import make_instance
from .model_exchange import MEOptions
from .compiled import make_master
from .marks import Marks
from .samples import Samples
from .settings import MasterSettings
from .wiring import Link, parse_link


_NAME = Text("an instance name (a non-empty string)")
_PARAMETERS = Mapping(Text("a variable name (a non-empty string)"), Anything(), "{parameter: value}")
_COMPONENTS = Mapping(_NAME, Tuple(PathSpec("a model name or a path to an .fmu file"), _PARAMETERS,
                                   what="a pair (model name or .fmu path, {parameter: value})"),
                      "{instance: (model name or .fmu path, {parameter: value})}")
_LINK = Either(Text("a link 'instance.output -> instance.input'"), Of(Link, "a Link"),
               Tuple(Text(), Text(), Text(), Text(), Real(), Real(), Flag(), optional=3,
                     what="(source, output, target, input[, factor[, offset[, adds]]])"),
               what="a link: 'instance.output -> instance.input', a Link or (source, output, target, input)")
_RECORD = Optional(Mapping(_NAME, Sequence(Text("an output name"), "a list of output names"),
                           "{instance: [output name, ...]}"))


class System:
    """FMU instances, wired and initialized, with the master that steps them.

    Arguments are checked as they enter (a UsageError naming the argument,
    instance and variable). A System belongs to one thread at a time: a
    call while another thread is inside one of its methods (or its
    master's) is refused with a UsageError, on both engines. It cannot be
    pickled or copied (a UsageError): it holds loaded FMU libraries.

    Making one loads and instantiates every FMU, checks the links,
    parameters and recorded outputs against the model descriptions, builds
    the master that ``settings.engine`` asks for and initializes the system
    at ``start_time``: it is then ready to step (``system.master.run_until(t)``).
    Model Exchange FMUs connected to each other become one group in the
    master (``engine/me_group.py``; ``settings.me_groups``): ``instances``
    holds the group (named ``member+member``), while links, parameters,
    ``record``, ``output`` and ``value`` keep the members' names.
    Use it in a ``with`` block, or call `free()`: that frees the FMU
    instances, after which every method of the System and of its master
    raises `ClosedError`.

    Args:
        components: ``{instance name: (fmu, {parameter: value})}``. ``fmu`` is
            the model name of a bundled FMU (``"Pendulum"``: looked up in
            ``$CLOCKWORK_FMU_DIR``, else the checkout's ``fmus/``, else the
            FMUs installed with the package; their FMI 3.0 builds in
            ``fmi3/`` when ``settings.fmi_version`` is 3) or a path ending
            ``.fmu`` (relative to the current directory): any FMI 2.0 or
            3.0 Co-Simulation FMU. Parameter values are plain numbers,
            bools or strings in the unit the FMU declares for the variable
            (SI for the bundled FMUs: rad, s, N.m), set before
            initialization; nothing converts units here (scene files do).
        connections: One link per entry, ``"source.output -> target.input"``
            (instance names may contain dots: they are matched longest
            first), or a ``Link`` from ``clockwork.engine.wiring`` (which
            also takes a factor, an offset and ``adds``: the output added
            to the links before it into the same input, an OSP Sum).
        settings: The master's settings; None: ``MasterSettings()``.
        record: ``{instance name: [output name, ...]}``: outputs kept up to
            date at every communication point besides the connected ones,
            to be read with `output()`.
        start_time: Time of initialization and of the first communication
            point, s.
        model_descriptions: ``{instance name: fmpy ModelDescription}``
            already read, so that they are not read again (the scene layer
            passes them).
        interfaces: ``{instance name: "co-simulation" or "model-exchange"}``:
            the interface of an FMU that has both (default Co-Simulation);
            a Model Exchange FMU is integrated by the master's wrapper
            (``master.me_solver``, ``master.tolerance``).
        labels: ``{instance name: text}``: what messages call an instance's
            FMU (the scene layer: a copied FMU by its original name).
        inputs: Signals given as samples (``engine.samples.Samples``, read
            from an input file or fmpy's ``input=`` array) that drive
            unconnected inputs at every communication point: continuous
            Real inputs interpolated linearly, the others held, as fmpy
            does; a communication step ends at each input event.
        rates: ``{instance name: k}``: that component steps every k base
            steps, with a step of k * ``settings.step`` (multi-rate, as
            libcosim's decimation factors; engine/multirate.py); the others
            every base step. The Python engine runs it (``engine = "auto"``
            falls back to it, with ``master.engine_reason``).

    Attributes:
        master: The master (``Master``, or its compiled twin with the same
            methods): ``master.run_until(t)`` steps, ``master.t`` is the
            current communication point (s), ``master.stats`` counts steps,
            events and rollbacks.
        instances: ``{instance name: FMU instance}`` (empty once freed).
        parameters: ``{instance name: {parameter: value}}`` of the last
            initialization.

    Raises:
        UsageError: ``components`` not of the form above; a link, parameter
            or recorded output that names an instance or a variable that
            does not exist (with the nearest name), or a link whose ends are
            not an output and an input.
        SceneError: An FMU that is missing or cannot be read or loaded (no
            binary for this platform), a malformed link, ``master.engine =
            "compiled"`` for settings or links only the Python engine runs,
            or settings these FMUs cannot run (event location, ``iterations``
            or ``richardson`` with an FMU that cannot save its state;
            ``extrapolation`` into an FMI 3.0 FMU without intermediate
            update).
        ParametersRefused: An FMU refused its parameter values (a
            ``SimulationError``).
        SimulationError: An FMU failed to instantiate or initialize.

    Example:
        ```python
        from clockwork.engine import MasterSettings, System

        with System({"pendulum": ("Pendulum", {"Q": 1000.0, "phi_start": 0.1})}, [],
                    MasterSettings(step=0.1), record={"pendulum": ["phi"]}) as s:
            s.master.run_until(2.0)
            print(s.master.t, s.output("pendulum", "phi"))  # s, rad
        ```
    """

    @checked(components=_COMPONENTS, connections=Sequence(_LINK, "a list of links"),
             settings=Optional(Of(MasterSettings, "a MasterSettings (clockwork.engine.MasterSettings(...))")),
             record=_RECORD, start_time=Real("a finite start time in s"),
             model_descriptions=Optional(Mapping(_NAME, Anything(), "{instance: model description}")),
             interfaces=Optional(Mapping(_NAME, Optional(Text("'co-simulation' or 'model-exchange'")),
                                         "{instance: 'co-simulation' or 'model-exchange'}")),
             labels=Optional(Mapping(_NAME, Text("a label (a non-empty string)"), "{instance: label}")),
             inputs=Optional(Of(Samples, "input samples (clockwork.engine.samples.Samples)")),
             rates=Optional(Mapping(_NAME, Integer("a whole number of base steps >= 1"),
                                    "{instance: its step in base steps}")))
    def __init__(self, components: dict[str, tuple[str, dict]], connections: list[str],
                 settings: MasterSettings | None = None, record: dict[str, list[str]] | None = None,
                 start_time: float = 0.0, model_descriptions: dict | None = None,
                 interfaces: dict[str, str | None] | None = None, labels: dict[str, str] | None = None,
                 inputs: Samples | None = None, rates: dict[str, int] | None = None):
        self.parameters = {name: dict(params) for name, (_, params) in components.items()}
        self.instances: dict[str, Instance] = {}
        self._freed = False
        # On a clean exit of a `with` block, hand the system to this callable
        # instead of freeing it (analyses.context.reusing_systems).
        self.release = None
        settings = settings or MasterSettings()
        me_options = MEOptions(settings.me_solver, settings.event_time_tolerance)
        try:
            for name, (fmu, _) in components.items():
                md = (model_descriptions or {}).get(name)
                inst = make_instance(name, resolve_fmu(str(fmu), Path.cwd(), settings.fmi_version), md,
                                     settings.early_return,
                                     bool(settings.extrapolation) or settings.iterations > 0,
                                     (interfaces or {}).get(name), me_options)
                inst.label = (labels or {}).get(name) or None  # what messages call a copied FMU
                inst.instantiate()
                self.instances[name] = inst
            known = {n: inst.variables for n, inst in self.instances.items()}
            links = [c if isinstance(c, Link) else self._parse_link(c, known) if isinstance(c, str) else Link(*c)
                     for c in connections]
            for link in links:
                self._variable(link.src, link.output, "output", "a link's source")
                self._variable(link.dst, link.input, "input", "a link's target")
            for what, table in (("a parameter", self.parameters), ("a recorded output", record or {})):
                for inst, names in table.items():
                    for var in names:
                        self._variable(inst, var, None, what)
            self._check_values(self.parameters, "System(): components")
            # connected Model Exchange FMUs: one group each (engine/me_group.py);
            # its module is imported only where two could form one
            if settings.me_groups and sum(i.joins_me_group for i in self.instances.values()) > 1:
                links, record, inputs = self._form_groups(links, record, inputs, me_options)
            self.master = make_master(self.instances, links, settings,
                                      start_time=float(start_time), extra_outputs=record, inputs=inputs,
                                      rates=rates)
            self._guard = _guard_master(self.master)
            self.master.initialize(self._grouped(self.parameters))
        except BaseException:
            self.free()
            raise

    master = None  # until built
    _guard = None
    _group_of: dict = {}  # member instance -> its Model Exchange group's name
    _members: dict = {}  # member instance name -> the member (an MEInstance inside a group)

    def _form_groups(self, links, record, inputs, me_options):
        """Connected Model Exchange instances as groups; the links, the
        recorded outputs and the input samples re-addressed to them."""
        from dataclasses import replace

        from .me_group import form_groups
        instances, links, group_of = form_groups(self.instances, links, me_options)
        if not group_of:
            return links, record, inputs
        self._members = {m.name: m for g in instances.values() for m in getattr(g, "members", ())}
        self.instances, self._group_of = instances, group_of
        if record:
            grouped: dict[str, list[str]] = {}
            for inst, names in record.items():
                g = group_of.get(inst)
                grouped.setdefault(g or inst, []).extend(f"{inst}.{n}" if g else n for n in names)
            record = grouped
        if inputs is not None and any(s.instance in group_of for s in inputs.signals):
            inputs = Samples(inputs.times, [replace(s, instance=group_of[s.instance], variable=f"{s.instance}."
                                                    f"{s.variable}") if s.instance in group_of else s
                                            for s in inputs.signals])
        return links, record, inputs

    def _grouped(self, parameters: dict) -> dict:
        """{instance: {variable: value}} with the members of groups as "member.variable" of their group."""
        if not self._group_of:
            return parameters
        out: dict[str, dict] = {}
        for inst, values in parameters.items():
            g = self._group_of.get(inst)
            out.setdefault(g or inst, {}).update({f"{inst}.{k}" if g else k: v for k, v in values.items()})
        return out

    def _where(self, instance: str, name: str) -> tuple[str, str]:
        """The master's instance and variable name of `instance.name` (a group's member: its group)."""
        g = self._group_of.get(instance)
        return (g, f"{instance}.{name}") if g else (instance, name)

    @checked(parameters=Mapping(_NAME, _PARAMETERS, "{instance: {parameter: value}}"))
    def restart(self, parameters: dict[str, dict[str, object]]) -> None:
        """Start again from `parameters` on the same instances and wiring:
        fmi2Reset every FMU, initialize again, statistics from zero. The
        same bits as a new System with these parameters, without loading and
        instantiating the FMUs again.

        Args:
            parameters: ``{instance name: {parameter: value}}``, as in
                ``components``; the time starts again at ``start_time``.

        Raises:
            ClosedError: The System was freed.
            UsageError: A parameter that names no instance or variable.
            ParametersRefused: An FMU refused the values.
        """
        if self._freed:
            raise ClosedError("this System was freed (used after its `with` block or free()): build a new System")
        for inst, names in parameters.items():
            for var in names:
                self._variable(inst, var, None, "a parameter")
        self._check_values(parameters, "System.restart(): parameters")
        with self._guard:
            self.parameters = {name: dict(p) for name, p in parameters.items()}
            self.master.restart(self._grouped(self.parameters))

    def _check_values(self, parameters: dict, where: str) -> None:
        """Each value of the type and within the range its variable declares:
        a UsageError naming the instance and the variable, before any FMU
        call (else a float('abc') deep inside, or the FMU's own refusal)."""
        for inst, values in parameters.items():
            for name, value in values.items():
                instance = self.instances.get(inst) or self._members[inst]
                v = described(instance.md)[name]
                problem = value_problem(v, value)
                if problem:
                    raise UsageError(f"{where}[{inst!r}] {inst}.{name} = {show(value)}: expected {problem} "
                                     f"({instance.model_name}'s {name} is {v.type})")

    @staticmethod
    def _parse_link(text: str, known: dict) -> Link:
        """The link, its instance names matched longest first; where nothing
        matches, split at the first dot so that _variable names what is missing."""
        try:
            return parse_link(text, known)
        except SceneError:
            return parse_link(text)

    def _variable(self, instance: str, name: str, causality: str | None, what: str):
        """The variable `instance.name`, or UsageError naming both (with the nearest names)."""
        if self._freed:
            raise ClosedError("this System was freed (used after its `with` block or free()): build a new System")
        inst = self.instances.get(instance) or self._members.get(instance)
        if inst is None:
            close = difflib.get_close_matches(str(instance), list(self.instances), n=1)
            raise UsageError(f"{what} {instance}.{name}: no instance {instance!r}"
                             + (f" (did you mean {close[0]}?)" if close else "")
                             + f"; the instances are {', '.join(self.instances) or 'none'}")
        v = inst.variables.get(name)
        if v is None:
            close = difflib.get_close_matches(str(name), list(inst.variables), n=1)
            raise UsageError(f"{what} {instance}.{name}: {inst.model_name} has no variable {name!r}"
                             + (f" (did you mean {close[0]}?)" if close else ""))
        if causality is not None and v.causality != causality:
            raise UsageError(f"{what} {instance}.{name}: expected an {causality}, {name} is a {v.causality}")
        return v

    @checked(instance=_NAME, name=Text("a variable name (a non-empty string)"))
    def value(self, instance: str, name: str) -> float | list:
        """Current value of a Real variable (not on the hot path); of an FMI
        3.0 array, the list of its values (row-major).

        Args:
            instance: The instance name.
            name: Any Real variable of it (parameter, state, local, output),
                read from the FMU now (``fmi2GetReal``), in its declared unit.

        Raises:
            UsageError: No such instance or variable.
            ClosedError: The System was freed.
        """
        v = self._variable(instance, name, None, "value")
        instance, name = self._where(instance, name)
        with self._guard:
            if v.shape:
                return self.instances[instance].get_values([name])[0]
            return self.instances[instance].get_real([name])[0]

    @checked(instance=_NAME, name=Text("an output name (a non-empty string)"))
    def output(self, instance: str, name: str) -> float | list:
        """Cached value of a connected or recorded output at the current point
        (of an FMI 3.0 array, the list of its elements' values).

        Reads no FMU: the value the master keeps from the last communication
        point, in the output's declared unit.

        Args:
            instance: The instance name.
            name: An output that is connected or listed in ``record``.

        Raises:
            UsageError: No such instance or variable, or an output neither
                connected nor recorded (record it, or use `value()`).
            ClosedError: The System was freed.
        """
        self._variable(instance, name, None, "output")
        instance, name = self._where(instance, name)
        port = self.master.ports[instance]
        elements = self.instances[instance].elements.get(name)
        if elements is not None and all(e in port.out_names for e in elements):  # an FMI 3.0 array: a list
            return [port.out[port.out_names.index(e)] for e in elements]
        if name not in port.out_names:
            raise UsageError(f"output {instance}.{name}: neither connected nor recorded; "
                             f"record it (record={{{instance!r}: [{name!r}]}}) or use value()")
        return port.out[port.out_names.index(name)]

    def free(self) -> None:
        """Free every FMU instance; later calls of the System's or its
        master's methods raise `ClosedError`. Leaving the ``with`` block
        calls it; calling it twice is harmless."""
        with self._guard or _NO_GUARD:
            if self.master is not None and not self._freed:
                self.master.stop_threads()  # now, not when the collector finds the master
            free_all(self.instances)
            self.instances = {}
            self._freed = True
            if self.master is not None:
                _close(self.master)

    def __reduce_ex__(self, protocol):
        raise UsageError("a System cannot be pickled or copied: it holds loaded FMU libraries and their "
                         "instances' C state; pass its components and settings to the other process and build "
                         "a System there")

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        release, self.release = self.release, None
        if release is not None and exc_type is None and self.instances:
            release(self)
        else:
            self.free()


def value_problem(v, value) -> str | None:
    """What a value for variable `v` (a model description's ScalarVariable)
    should have been, or None when it is of the variable's type. The declared
    min and max are the FMU's to enforce (a refusal is ParametersRefused);
    so is a NaN (a Real may hold one: the run then fails as a simulation).
    An FMI 3.0 array takes a list or tuple (nested or not) whose every
    element is of its type; its length is the adapter's to check."""
    if getattr(v, "shape", None):
        if not isinstance(value, (list, tuple)):
            return "a list of values (nested by the array's shape, or flat; a NumPy array: .tolist())"
        for x in flat_values(value):
            problem = _scalar_problem(v.type, x)
            if problem:
                return f"a list whose every element is {problem}, got an element {show(x)}"
        return None
    return _scalar_problem(v.type, value)


def _scalar_problem(t: str, value) -> str | None:
    if t in REAL_TYPES:
        if isinstance(value, bool) or not isinstance(value, numbers.Real):
            return "a number"
        return None
    if t in INTEGER_TYPES:
        if isinstance(value, bool) or not isinstance(value, numbers.Integral):
            return "a whole number (an int)"
        lo, hi = int_range(t) or (-2**31, 2**31 - 1)  # what the C type holds: never wrapped
        if not lo <= value <= hi:
            return f"a whole number in [{lo}, {hi}] ({t})"
        return None
    if t == "Boolean":
        return None if isinstance(value, bool) or type(value).__name__ == "bool_" else "True or False (a bool)"
    if t == "String":
        return None if isinstance(value, str) else "a string"
    if t == "Binary":
        try:
            bytes.fromhex(value)
        except (TypeError, ValueError):
            return "hexadecimal digits (a string)"
    return None


class _Guard:
    """One thread at a time inside a System and its master: entering from
    a second thread while the first is inside is refused (a UsageError),
    re-entering from the same thread (a callback, the master's own calls)
    is free."""

    def __init__(self):
        self.lock = threading.Lock()
        self.owner: int | None = None
        self.depth = 0

    @staticmethod
    def busy() -> UsageError:
        return UsageError("this System is in use by another thread: a System (and its master) runs in one "
                          "thread at a time; build one System per thread, or wait for the other call to return")

    def __enter__(self):
        me = threading.get_ident()
        if self.owner == me:
            self.depth += 1
            return self
        if not self.lock.acquire(blocking=False):
            raise self.busy()
        self.owner, self.depth = me, 1
        return self

    def __exit__(self, *exc):
        self.depth -= 1
        if self.depth == 0:
            self.owner = None
            self.lock.release()


class _NoGuard:
    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return None


_NO_GUARD = _NoGuard()


# The master's public methods and their arguments, checked when called from
# outside (a System's master; its own calls to itself are not checked again).
MASTER_ARGUMENTS = {
    "step": {"h": Real("a step > 0 in s (a finite number)", positive=True)},
    "run_until": {"on_point": Optional(Call())},
    "run_marks": {"t_stop": Real("a finite time in s"),
                  "marks": Of(Marks, "a Marks plan (clockwork.engine.marks.Marks)"), "on_rows": Optional(Call())},
    "initialize": {"parameters": Mapping(_NAME, _PARAMETERS, "{instance: {parameter: value}}")},
    "reinitialize": {"parameters": Mapping(_NAME, _PARAMETERS, "{instance: {parameter: value}}")},
    "restart": {"parameters": Mapping(_NAME, _PARAMETERS, "{instance: {parameter: value}}")},
}


_MISSING = object()
# The parts of one communication step, which step calls (several times per
# step; count_loop from an algebraic loop's iterations): not entry points,
# and not guarded, so that a step pays one wrapper.
STEP_PARTS = ("advance", "record_history", "count_loop")


def _guard_master(master) -> _Guard:
    """Every public method of the master but the parts of a step enters the
    System's guard, so that two threads never step one set of FMUs at once
    (the compiled core releases the GIL while it steps), and checks its
    arguments when called from outside. The master's calls to itself
    (inside the guard) go straight through; step, called once per
    communication step (the shooting loops call it from outside), has a
    wrapper of its own signature that takes the lock without a second frame:
    about 2,200 instructions per outside step of the compiled engine (10 %),
    1,300 per step inside the Python engine's run_until (1.5 %)."""
    guard = _Guard()
    lock, me, inf = guard.lock, threading.get_ident, math.inf

    def outside(entry, args, kwargs):
        if not lock.acquire(False):
            raise guard.busy()
        guard.owner, guard.depth = me(), 1
        try:
            return entry(*args, **kwargs)
        finally:
            guard.owner, guard.depth = None, 0
            lock.release()

    for name in dir(type(master)):
        if name.startswith("_") or name in STEP_PARTS or not callable(getattr(type(master), name, None)):
            continue
        method = getattr(master, name)
        entry = checked(**MASTER_ARGUMENTS[name])(method) if name in MASTER_ARGUMENTS else method

        def guarded(*args, _method=method, _entry=entry, **kwargs):
            if guard.owner == me():
                return _method(*args, **kwargs)
            return outside(_entry, args, kwargs)

        if name == "step":
            def guarded(h=_MISSING, *more, _method=method, _entry=entry, **kwargs):  # noqa: F811
                if more or kwargs or h is _MISSING or type(h) is not float or not 0.0 < h < inf:
                    if guard.owner == me():
                        return _method(h, *more, **kwargs)
                    return outside(_entry, () if h is _MISSING else (h, *more), kwargs)
                if guard.owner == me():
                    return _method(h)
                if not lock.acquire(False):  # the shooting loops' step from outside: no second frame
                    raise guard.busy()
                guard.owner, guard.depth = me(), 1
                try:
                    return _method(h)
                finally:
                    guard.owner, guard.depth = None, 0
                    lock.release()

        guarded.__name__ = guarded.__qualname__ = name
        guarded.__doc__ = method.__doc__
        setattr(master, name, guarded)
    return guard


def _close(master) -> None:
    """Every public method of a freed system's master raises ClosedError
    (the FMU instances it would call are gone), also through a reference
    kept from before."""
    def closed(*args, **kwargs):
        raise ClosedError("this System was freed (used after its `with` block or free()): build a new System")
    for name in dir(type(master)):
        if not name.startswith("_") and callable(getattr(type(master), name, None)):
            setattr(master, name, closed)
