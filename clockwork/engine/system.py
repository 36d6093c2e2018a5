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
from pathlib import Path

from ..errors import ClosedError, SceneError, UsageError
from .description import resolve_fmu
from .fmu import Instance, free_all
from .model_exchange import MEOptions, make_instance
from .compiled import make_master
from .samples import Samples
from .settings import MasterSettings
from .wiring import Link, parse_link


class System:
    """FMU instances, wired and initialized, with the master that steps them.

    Making one loads and instantiates every FMU, checks the links,
    parameters and recorded outputs against the model descriptions, builds
    the master that ``settings.engine`` asks for and initializes the system
    at ``start_time``: it is then ready to step (``system.master.run_until(t)``).
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
            also takes a factor and an offset).
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

    def __init__(self, components: dict[str, tuple[str, dict]], connections: list[str],
                 settings: MasterSettings | None = None, record: dict[str, list[str]] | None = None,
                 start_time: float = 0.0, model_descriptions: dict | None = None,
                 interfaces: dict[str, str | None] | None = None, labels: dict[str, str] | None = None,
                 inputs: Samples | None = None):
        if not isinstance(components, dict) or not all(
                isinstance(c, (tuple, list)) and len(c) == 2 and isinstance(c[1], dict) for c in components.values()):
            raise UsageError("System: components must be {instance: (model name or .fmu path, {parameter: value})}")
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
            self.master = make_master(self.instances, links, settings,
                                      start_time=start_time, extra_outputs=record, inputs=inputs)
            self.master.initialize(self.parameters)
        except BaseException:
            self.free()
            raise

    master = None  # until built

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
        self.parameters = {name: dict(p) for name, p in parameters.items()}
        self.master.restart(self.parameters)

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
        inst = self.instances.get(instance)
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
        if v.shape:
            return self.instances[instance].get_values([name])[0]
        return self.instances[instance].get_real([name])[0]

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
        free_all(self.instances)
        self.instances = {}
        self._freed = True
        if self.master is not None:
            self.master.stop_threads()  # now, not when the collector finds the master
            _close(self.master)

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        release, self.release = self.release, None
        if release is not None and exc_type is None and self.instances:
            release(self)
        else:
            self.free()


def _close(master) -> None:
    """Every public method of a freed system's master raises ClosedError
    (the FMU instances it would call are gone), also through a reference
    kept from before."""
    def closed(*args, **kwargs):
        raise ClosedError("this System was freed (used after its `with` block or free()): build a new System")
    for name in dir(type(master)):
        if not name.startswith("_") and callable(getattr(type(master), name, None)):
            setattr(master, name, closed)
