"""The validated scene: what a scene file says, in SI units, frozen.

``Scene.variant(point)`` applies a sweep point (or any other set of values)
and checks that the result is still consistent.
"""

from __future__ import annotations

import dataclasses
import itertools
import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NamedTuple

from ..errors import SceneError
from ..engine import compiled, multirate
from ..fmi.description import no_state_reason, variables as variables_of
from ..engine.model_exchange import interface_of
from ..engine.settings import SETTINGS, MasterSettings, rollback_need
from .units import fmt

@dataclass(frozen=True)
class Component:
    name: str
    fmu_path: Path
    sha256: str
    model_description: Any  # fmpy.model_description.ModelDescription
    parameters: dict[str, float | int | bool | str]  # in the variable's unit (SI)
    event_indicators: tuple[str, ...] = ()  # from the `clockwork` vendor annotation
    # "co-simulation" or "model-exchange"; None: Co-Simulation where the FMU has it
    interface: str | None = None
    # What messages call the FMU: an SSP archive's member ("x.ssp/resources/m.fmu")
    # rather than its copy in the cache; "" for the file itself.
    fmu_label: str = ""
    # Its own communication step, s: a whole multiple of master.step (multi-rate,
    # engine/multirate.py); None: master.step.
    step: float | None = None

    @property
    def model_name(self) -> str:
        return self.model_description.modelName

    @property
    def model_exchange(self) -> bool:
        """Whether the master runs it through its Model Exchange interface."""
        return interface_of(self.model_description, self.interface) == "model-exchange"

    @property
    def capabilities(self):
        """The <CoSimulation> or <ModelExchange> element it runs through."""
        md = self.model_description
        return md.modelExchange if self.model_exchange else md.coSimulation

    @property
    def fmu_shown(self) -> str:
        """The FMU as messages name it."""
        return self.fmu_label or str(self.fmu_path)

    def variable(self, name: str):
        return variables_of(self.model_description)[name]


class ComponentVariables(Mapping):
    """{instance: its variables by name} over a scene's components, each
    looked up when asked (engine.names.split_ref splits references against
    it): made once per scene, not once per reference."""

    def __init__(self, components: Mapping[str, Component]):
        self._components = components

    def __getitem__(self, name: str) -> dict:
        return variables_of(self._components[name].model_description)

    def __iter__(self):
        return iter(self._components)

    def __len__(self) -> int:
        return len(self._components)


class Connection(NamedTuple):
    """The input receives factor * output + offset (engine.wiring.Link's
    fields, in order): a linear transformation or a unit conversion. With
    `adds`, the output is added to what the connections listed before it
    give the same input (an OSP Sum; factor 1, offset 0)."""

    src_instance: str
    src_var: str
    dst_instance: str
    dst_var: str
    factor: float = 1.0
    offset: float = 0.0
    adds: bool = False

    def __str__(self) -> str:
        return f"{self.src_instance}.{self.src_var} -> {self.dst_instance}.{self.dst_var}"


@dataclass(frozen=True)
class Experiment:
    start: float  # s
    stop: float  # s


@dataclass(frozen=True)
class Record:
    outputs: tuple[tuple[str, str], ...]  # (instance, variable)
    interval: float | None  # s; None = every communication point
    ticks: str | None  # instance whose tick_time/tick_count are recorded
    format: tuple[str, ...] = ("csv",)  # the files of the series: RESULT_FORMATS, in the order given


# The formats a recorded series is written in (results.series), as record.format and --format name them.
RESULT_FORMATS = ("csv", "parquet", "mat")


@dataclass(frozen=True)
class SweepAxis:
    parameter: tuple[str, str]  # (instance, variable), or ("master"|"experiment", key)
    values: tuple  # SI values


@dataclass(frozen=True)
class Sweep:
    mode: str  # "grid" or "zip"
    axes: tuple[SweepAxis, ...]

    def points(self) -> list[dict[tuple[str, str], object]]:
        """The parameter sets of the sweep; grid: first axis varies slowest."""
        keys = [a.parameter for a in self.axes]
        if self.mode == "zip":
            combos = zip(*(a.values for a in self.axes))
        else:
            combos = itertools.product(*(a.values for a in self.axes))
        return [dict(zip(keys, c)) for c in combos]

    @property
    def shape(self) -> tuple[int, ...]:
        if self.mode == "zip":
            return (len(self.axes[0].values),)
        return tuple(len(a.values) for a in self.axes)


@dataclass(frozen=True)
class Scene:
    path: Path
    title: str
    description: str
    reproduces: str
    components: dict[str, Component]  # in file order
    connections: tuple[Connection, ...]
    experiment: Experiment
    master: MasterSettings  # the one type of the master's settings (engine/settings.py)
    record: Record
    analysis: dict | None  # {"kind": ..., converted keys}
    sweep: Sweep | None
    plots: tuple[dict, ...]
    overrides: tuple[str, ...] = ()  # the --set arguments applied
    sha256: str = ""  # of the scene file's bytes
    # master fields the scene gave (else they follow another: Setting.follows, max_step the step)
    master_given: frozenset = field(default=frozenset(), repr=False, compare=False)
    notes: tuple[str, ...] = field(default=(), repr=False, compare=False)  # what `validate` says beside "ok"
    inputs: Any = None  # scene.inputs.Inputs: samples that drive unconnected inputs, or None
    # where a value came from, for refusals after loading: dotted key -> "--set <key>", or (file, key) of
    # another file (an FMU's DefaultExperiment, an SSD's attribute); a key absent here is the scene file's
    origins: dict = field(default_factory=dict, repr=False, compare=False)

    @property
    def max_step_given(self) -> bool:
        """Whether the scene gave master.max_step (else it is the step)."""
        return "max_step" in self.master_given

    def refused_at(self, e: SceneError) -> SceneError:
        """`e` (raised against this scene's file and a dotted key) named by
        where the key's value came from instead, when it came from elsewhere."""
        if e.key is None or e.path != str(self.path):
            return e
        base, rest = (e.key.split(" ", 1) + [""])[:2]
        origin = self.origins.get(base)
        if origin is None:
            return e
        path, key = origin if isinstance(origin, tuple) else (self.path, origin)
        return SceneError(e.detail, path, f"{key} {rest}".rstrip())

    def parameters(self) -> dict[str, dict[str, object]]:
        """{instance: {variable: value}} for every component."""
        return {n: dict(c.parameters) for n, c in self.components.items()}

    def points(self) -> list[dict[tuple[str, str], object]]:
        """Sweep points ([{}] without a sweep)."""
        return self.sweep.points() if self.sweep else [{}]

    def variant(self, values: dict[tuple[str, str], object]) -> "Scene":
        """A copy with some values replaced (already in SI, e.g. a sweep point).

        Keys are (instance, variable), ("master", key) or ("experiment", key).
        Raises SceneError when the result is inconsistent (stop <= start...).
        """
        comps = dict(self.components)
        master = self.master.as_dict()
        exp = dataclasses.asdict(self.experiment)
        for (owner, name), value in values.items():
            if owner == "master":
                master[name] = value
            elif owner == "experiment":
                exp[name] = value
            else:
                c = comps[owner]
                comps[owner] = dataclasses.replace(c, parameters={**c.parameters, name: value})
        follow(master, self.master_given | {name for owner, name in values if owner == "master"})
        e = Experiment(**exp)
        try:
            m = MasterSettings(**master)
        except SceneError as err:  # a combination of the point's values (each was checked as it was read)
            m, problem = None, (err.key or "master", err.detail)
        else:
            problem = consistency(m, e, comps, self.connections)
        if problem:
            key, detail = problem
            raise SceneError(detail, self.path, f"{key} (with {_show_point(values)})")
        return dataclasses.replace(self, components=comps, master=m, experiment=e)


def _show_point(values: dict) -> str:
    return ", ".join(f"{a}.{b} = {show(v)}" for (a, b), v in values.items())


SPAN_RESOLUTION = 1e-12  # a run's end, relative to max(1 s, |stop|): closer to the stop is the stop


def follow(master: dict, given) -> dict:
    """`master` ({field: value}) with each field the scene did not give
    (`given`: names) and that follows another (Setting.follows: max_step the
    step) set to that one's value; returned."""
    for name, spec in SETTINGS.items():
        if spec.follows and name not in given:
            master[name] = master[spec.follows]
    return master


def consistency(m: MasterSettings, e: Experiment, components: dict[str, Component],
                connections: tuple = ()) -> tuple[str, str] | None:
    """The first problem of these settings with each other and with the
    components (and their `connections`), as (key, what was expected), or None."""
    if not e.stop > e.start:
        return "experiment.stop", f"expected stop > start ({fmt(e.start)} s), got {fmt(e.stop)} s"
    if e.stop - e.start <= SPAN_RESOLUTION * max(1.0, abs(e.stop)):
        # the run ends within this of the stop (analyses.time_series): a shorter span would not step at all
        return "experiment.stop", (f"expected stop more than {fmt(SPAN_RESOLUTION * max(1.0, abs(e.stop)))} s "
                                   f"after start ({fmt(e.start)} s), got {fmt(e.stop)} s")
    if m.min_step > m.step:
        if m.min_step == MasterSettings.min_step:  # the default: the step is what was given too small
            return "master.step", (f"expected a step >= master.min_step ({fmt(m.min_step)} s, its default), got "
                                   f"{fmt(m.step)} s")
        return "master.min_step", f"expected min_step <= step ({fmt(m.step)} s), got {fmt(m.min_step)} s"
    if m.max_step is not None and m.max_step < m.step:
        return "master.max_step", f"expected max_step >= step ({fmt(m.step)} s), got {fmt(m.max_step)} s"
    if m.engine == "compiled":
        # Asked for by name: where the core cannot serve, say so before the run.
        reason = compiled.unsupported(m) or compiled.core_problem()
        if reason:
            return "master.engine", f'expected "auto" or "python" here: {reason}'
    problem = rollback_problem(m, components)
    if problem:
        return problem
    problem = component_steps_problem(m, e, components, connections)
    if problem:
        return problem
    # A step below the time resolution at the end would never move the clock.
    resolution = 64 * math.ulp(max(abs(e.start), abs(e.stop)))
    if m.step < resolution:
        return "master.step", (f"expected a step of at least {fmt(resolution)} s: a double cannot tell "
                               f"{fmt(e.stop)} s from {fmt(e.stop)} s + {fmt(m.step)} s apart well enough")
    return None



def rollback_problem(m: MasterSettings, components: dict[str, Component]) -> tuple[str, str] | None:
    """An FMU that does not declare canGetAndSetFMUstate, where the settings
    roll every FMU back: it would fail at its first rollback."""
    need = rollback_need(m, any(c.event_indicators for c in components.values()))
    if need is None:
        return None
    key, why = need
    for c in components.values():
        if not c.capabilities.canGetAndSetFMUstate:
            return key, (f"expected {'0' if key == 'master.iterations' else 'false'} here: components.{c.name} "
                         f"({Path(c.fmu_shown).name}) cannot save and restore its state "
                         f"({no_state_reason(c.model_description)}), and {why} rolls every FMU back")
    return None


def show(value: object, limit: int = 60) -> str:
    """A value written as in TOML (for messages)."""
    if isinstance(value, bool):
        s = "true" if value else "false"
    elif isinstance(value, str):
        s = json.dumps(value, ensure_ascii=False)
    elif isinstance(value, float):
        s = fmt(value) if math.isfinite(value) else ("nan" if math.isnan(value) else ("inf" if value > 0 else "-inf"))
    elif isinstance(value, (int,)):
        # Python refuses str() of an integer of more than 4300 digits
        s = str(value) if value.bit_length() <= 13000 else f"<an integer of {value.bit_length()} bits>"
    elif isinstance(value, list):
        s = "[" + ", ".join(show(x, limit) for x in value) + "]"
    elif isinstance(value, dict):
        s = "{" + ", ".join(f"{k} = {show(x, limit)}" for k, x in value.items()) + "}"
    else:
        s = str(value)
    return s if len(s) <= limit else s[: limit - 3] + "..."


def rates(m: MasterSettings, components: dict[str, Component]) -> dict[str, int] | None:
    """{instance: decimation factor} where a component has a step of its own
    (a whole multiple of master.step, engine/multirate.py), else None."""
    if all(c.step is None for c in components.values()):
        return None
    found = {n: (multirate.decimation(c.step, m.step) if c.step is not None else 1) for n, c in components.items()}
    return None if None in found.values() else found


def component_steps_problem(m: MasterSettings, e: Experiment, components: dict[str, Component],
                            connections: tuple = ()) -> tuple[str, str] | None:
    """The first component step that is no whole multiple of master.step
    (within rounding), or what of the settings the multi-rate master does
    not do, as (key, what was expected), or None."""
    for name, c in components.items():
        if c.step is not None and multirate.decimation(c.step, m.step) is None:
            return f"components.{name}.step", (f"expected a whole multiple of master.step ({fmt(m.step)} s), got "
                                               f"{fmt(c.step)} s")
        if c.step is not None and c.step > e.stop - e.start:
            return f"components.{name}.step", (f"expected at most the run's span ({fmt(e.stop - e.start)} s), got "
                                               f"{fmt(c.step)} s: the component would never step")
    k = rates(m, components)
    if not multirate.is_multirate(k):
        return None
    clocked = [n for n, c in components.items() if any(v.type == "Clock" for v in c.model_description.modelVariables)]
    if clocked:  # engine/clocks.py lands a communication point of every component on each tick
        slow = next(n for n, r in k.items() if r != 1)
        return f"components.{slow}.step", (f"expected every component at master.step ({fmt(m.step)} s) with FMI 3.0 "
                                           f"clocks ({', '.join(clocked)}): a tick is a communication point of every "
                                           "component, and the multi-rate master steps on the base grid only")
    problem = multirate.problem(m, k, {n: c.event_indicators for n, c in components.items()},
                                [(c.src_instance, c.dst_instance) for c in connections])
    if problem:  # named where the slow component's step comes from (a scene key, an OSP or SSD attribute)
        slow, detail = problem
        return f"components.{slow}.step", detail
    problem = multirate.stop_problem(k, m.step, e.start, e.stop)
    if problem:
        return "experiment.stop", problem
    indicators = {n: c.event_indicators for n, c in components.items()}
    refused = compiled.unsupported_rates(m, k, indicators) if m.engine == "compiled" else None
    if refused:
        return "master.engine", f'expected "auto" or "python" here: {refused}'
    return None

