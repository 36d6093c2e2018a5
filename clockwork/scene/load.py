"""Scene files: loading and strict validation (format: docs/scenes.md).

``load_scene(path, overrides, kinds)`` reads a TOML scene, applies ``--set``
overrides, checks every key and value against the FMUs' model descriptions
and returns a frozen ``Scene`` with all quantities converted to the
variables' own (SI) units. Every problem raises ``SceneError`` with a
one-line message naming the file, the dotted key and what was expected.
An SSP (``ssp/read.py``), an OSP system structure (``osp/read.py``) and
an FMU alone (``fmu.py``) are read into the components and sections a
scene file gives, and checked the same way; an
input file (``inputs.py``) drives unconnected inputs of any of them.
The ``[analysis]`` and ``[[plot]]`` tables are checked against ``kinds``,
which the layers above fill (clockwork.run.load_scene passes them all).
"""

from __future__ import annotations

import dataclasses
import difflib
import hashlib
import os
import re
import sys
from pathlib import Path

from ..engine import compiled, cvode, multirate
from ..fmi.description import (TEXT_TYPES, FmuError, default_tolerance_problem, element_names, link_shape_problem,
                                  read_fmu, resolve_fmu, type_name, types_connect, var_unit)
from ..fmi.description import variables as variables_of
from ..engine.me_step import MAX_RK_STATES
from ..engine.instances import make_instance
from ..engine.model_exchange import INTERFACES, interface_of, model_exchange_problem
from ..engine.names import split_link, split_ref
from ..engine.settings import DEFAULTS as MASTER_DEFAULTS
from ..engine.settings import SETTINGS as MASTER_SETTINGS
from ..engine.settings import BadSetting, MasterSettings
from ..engine.wiring import Link, loop_name
from ..engine.wiring import build as build_wiring
from ..errors import SceneError, say
from ..numbers import shorten
from .checks import (SETTABLE, STRUCTURAL, TOP_KEYS, Ctx, article, component, convert_value, instance_problem,
                     lookup, master_value, names_of, parse_ref, read_bounded, settable_problem)
from .inputs import Inputs, read_inputs
from .kinds import NO_KINDS, Invalid, Kinds
from .model import (RESULT_FORMATS, Component, ComponentVariables, Connection, Experiment, Record, Scene,
                    consistency, follow, rates, show)
from .sweep import parse_sweep
from .units import UnitError, fmt, link_conversion, to_seconds

MAX_SCENE_BYTES = 1 << 20  # scene files are a few kB; a larger one is not a scene
_OVERRIDABLE = ("scene", "experiment", "master", "record", "analysis")


@dataclasses.dataclass(frozen=True)
class Given:
    """A value a program gives (clockwork.simulate), in place of --set text:
    neither the key nor the value is parsed. `section` is "experiment",
    "master" or "record" with `key` one of its keys, or None with `key` a
    variable ("instance.variable", or the variable alone in a scene of one
    component): a variable named like a section key (`experiment.stop`)
    stays a variable; `key` None with `section` "plot" replaces the plots
    (`[]`: simulate draws none). `value` is what TOML would give (a bool,
    an int, a float, a string or a list of them); `label` names it in
    errors."""

    section: str | None
    key: str | None
    value: object
    label: str
    items: tuple[str, ...] = ()  # the labels of a list's items, when not label[i]

    def labels(self, owner: str, name: str) -> dict[str, str]:
        """{the key errors name: its label} (a list's items too)."""
        out = {f"{owner}.{name}": self.label}
        if isinstance(self.value, list):
            out.update((f"{owner}.{name}[{i}]", self.items[i] if i < len(self.items) else f"{self.label}[{i}]")
                       for i in range(len(self.value)))
        return out

    def text(self, owner: str, name: str) -> str:
        """As --set text (the scene's overrides list: titles and notes)."""
        from .save import toml_value

        try:
            value = toml_value(self.value)
        except TypeError:  # an integer TOML cannot hold: the value is refused when checked
            value = show(self.value)
        return f"{owner}.{name}={value}"


def parse_override(text: str, instances=()) -> tuple[str, str, object]:
    """'a.b=value' -> ('a', 'b', value); the value is TOML if it parses, else a bare string.

    The key is split against the scene's sections and the `instances`
    named (longest first, engine.names), so that `sub.comp.MLoad.k` is
    the parameter MLoad.k of the instance sub.comp; without a match, at
    the first dot."""
    if "=" not in text:
        raise ValueError(f"--set {text}: expected instance.parameter=value (or master.key=value)")
    lhs, rhs = text.split("=", 1)
    lhs = lhs.strip()
    owner = lhs.partition(".")[0]
    split = None if owner in _OVERRIDABLE else split_ref(lhs, list(instances))
    if split is None and len(instances) == 1 and "." not in lhs:
        split = (next(iter(instances)), lhs)  # one component: the instance prefix is optional
    if split is None:
        head, dot, tail = lhs.partition(".")
        split = (head, tail) if dot and head and tail and not tail.endswith(".") else None
    if split is None or not re.fullmatch(r"[^\s=]+(?:\s*[^\s=]+)*", lhs):
        raise ValueError(f"--set {text}: expected instance.parameter=value, got the key {lhs!r}")
    return split[0], split[1], _override_value(lhs, rhs)


def _override_value(lhs: str, rhs: str) -> object:
    import tomllib  # TOML's reader only where TOML is read: an FMU run alone reads none (start-up)

    try:
        return tomllib.loads("v = " + rhs)["v"]
    except tomllib.TOMLDecodeError:
        return rhs.strip()
    except RecursionError:
        raise ValueError(f"--set {lhs}: the value is nested deeper than Python can read") from None
    except ValueError as e:  # Python's own limits: int() of more than 4300 digits
        raise ValueError(f"--set {lhs}: {_number_limit(e)}") from None


def _number_limit(e: ValueError) -> str:
    """What a ValueError of tomllib's number conversion means for the user."""
    if "digits" in str(e):
        return (f"an integer of more than {sys.get_int_max_str_digits()} digits, more than Python reads (and far "
                "beyond any FMU type): expected a number a variable can hold")
    return f"expected a number that can be read ({shorten(str(e), 100)})"


_SCENE_FORMATS = ("a .toml scene file, an .ssp archive, an .ssd file, an OSP system structure "
                  "(OspSystemStructure.xml) or an FMU named X.fmu")

# Root elements of XML files a user may hand over for a scene, and what each is.
_XML_ROOTS = {
    "OspSystemStructure": "an Open Simulation Platform system structure (name it .xml)",
    "SystemStructureDescription": "an SSP system structure description (name it .ssd)",
    "fmiModelDescription": "an FMU's modelDescription.xml (give the .fmu that holds it)",
    "ParameterSet": "an SSP parameter set (.ssv): an .ssd or a scene names it",
    "ParameterMapping": "an SSP parameter mapping (.ssm): an .ssd names it",
    "OspModelDescription": "an OSP model description (*_OspModelDescription.xml)",
}


def _other_format(path: Path, text: str) -> str | None:
    """What a file that is no TOML is instead, where it can be told (XML by
    its root element, a zip archive, JSON), for the line that refuses it."""
    head = text.lstrip("\ufeff \t\r\n")
    if head.startswith("<"):
        m = re.search(r"<(?![?!])(?:[\w.-]+:)?([\w.-]+)", head[:65536])
        root = m.group(1) if m else None
        return _XML_ROOTS.get(root, f"an XML file (root element {shorten(root or '?', 60)})")
    if head.startswith("PK\x03\x04"):
        return "a zip archive"
    if head[:1] in "{[" and path.suffix.lower() == ".json":
        return "a JSON file"
    if path.suffix and path.suffix.lower() != ".toml":  # a .toml file's own TOML error says more
        return f"a {shorten(path.suffix, 20)} file that is no TOML"
    return None


def load_scene(path: str | os.PathLike, overrides=(), kinds: Kinds = NO_KINDS,
               input_file: str | os.PathLike | None = None) -> Scene:
    """Load, override and validate a scene file (or an .ssp/.ssd, or an
    .fmu alone); `input_file` (relative to the current directory) drives
    unconnected inputs, in place of the scene's [inputs]. Raises SceneError."""
    path = Path(path)
    # The readers of other formats imported for their files only: a TOML scene starts without them.
    if path.is_dir():
        from .osp.read import OSP_FILE

        if (path / OSP_FILE).is_file():
            path = path / OSP_FILE  # a folder of an OSP system, as libcosim takes it
    if path.suffix.lower() in (".ssp", ".ssd"):
        from .ssp.read import read_ssp

        return _load_system(path, read_ssp(path), overrides, kinds, input_file)
    if path.suffix.lower() == ".fmu":
        from .fmu_alone import read_fmu_scene

        return _load_system(path, read_fmu_scene(path), overrides, kinds, input_file)
    if path.suffix.lower() == ".xml":
        return _load_system(path, _read_xml(path), overrides, kinds, input_file)
    if path.is_dir():  # a folder stands for the OSP system in it, where there is one (above)
        from .osp.read import OSP_FILE

        raise SceneError(f"is a directory without an {OSP_FILE}, not a scene: expected {_SCENE_FORMATS}", path)
    import tomllib

    data = read_bounded(path, MAX_SCENE_BYTES, "scene file", "a .toml scene file")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as e:
        if data[:4] == b"PK\x03\x04":  # a zip archive: an FMU or an SSP given where a scene goes
            raise SceneError(f"a zip archive, not a scene: expected {_SCENE_FORMATS}", path) from None
        raise SceneError(f"not UTF-8 text (byte {e.start}), so not a scene: expected {_SCENE_FORMATS}",
                         path) from None
    try:
        raw = tomllib.loads(text)
    except RecursionError:
        raise SceneError("malformed TOML: arrays or tables nested too deeply", path) from None
    except tomllib.TOMLDecodeError as e:
        other = _other_format(path, text)
        if other:
            raise SceneError(f"{other}, not a scene: expected {_SCENE_FORMATS}", path) from None
        msg = str(e)
        m = re.search(r"\(at line (\d+), column (\d+)\)", msg)
        where = f"line {m.group(1)}" if m else "line ?"
        if m:
            msg = msg[: m.start()].strip() + f" at column {m.group(2)}"
        elif "end of document" in msg:
            where = f"line {text.count(chr(10)) + 1}"
        raise SceneError(f"malformed TOML: {msg}", path, where) from None
    except ValueError as e:  # Python's own limit, not TOML's: int() of more than 4300 digits
        raise SceneError(f"malformed TOML: {_number_limit(e)}", path) from None
    if "scene" not in raw and path.suffix and path.suffix.lower() != ".toml":
        # another file that happens to parse as TOML (an empty .json, an .ini): named, not read as a scene
        raise SceneError(f"a {shorten(path.suffix, 20)} file that is no scene (no [scene] table): expected "
                         f"{_SCENE_FORMATS}", path)

    labels: dict[str, str] = {}
    applied = []
    comps_raw = raw.get("components")
    instance_names = list(comps_raw) if isinstance(comps_raw, dict) else []
    for text_ov in overrides:
        if isinstance(text_ov, Given) and text_ov.key is None:
            raw[text_ov.section] = text_ov.value
            continue
        owner, name, value, label, section = _override(text_ov, instance_names, path)
        applied.append(text_ov.text(owner, name) if isinstance(text_ov, Given) else text_ov)
        if section:
            sect = raw.setdefault(owner, {})
            if not isinstance(sect, dict):
                raise SceneError(f"[{owner}] is not a table in the file", path, label)
            sect[name] = value
            labels.update(text_ov.labels(owner, name) if isinstance(text_ov, Given) else {f"{owner}.{name}": label})
            continue
        comps = raw.get("components")
        if owner in TOP_KEYS:
            raise SceneError(
                f"cannot be set from the command line; settable: <instance>.<parameter>, "
                f"{', '.join(s + '.<key>' for s in _OVERRIDABLE)}", path, label)
        if not isinstance(comps, dict) or owner not in comps or not isinstance(comps[owner], dict):
            raise _no_component(owner, list(comps) if isinstance(comps, dict) else [], path, label)
        params = comps[owner].setdefault("parameters", {})
        if not isinstance(params, dict):
            raise SceneError(f"components.{owner}.parameters is not a table in the file", path, label)
        params[name] = value
        labels[f"components.{owner}.parameters.{name}"] = label

    ctx = Ctx(path, labels)
    return _build(ctx, raw, tuple(applied), hashlib.sha256(data).hexdigest(), kinds, input_file=input_file)


def _read_xml(path: Path):
    """An OSP system structure; any other XML file is named with what was expected."""
    from .osp.read import OtherXml, read_osp

    try:
        return read_osp(path)
    except OtherXml as e:
        what = _XML_ROOTS.get(e.root, f"an XML file of root element {shorten(e.root, 60)}")
        what = what.replace(" (name it .ssd)", " named .xml (name it .ssd)")
        raise SceneError(f"{what}, not a scene: expected {_SCENE_FORMATS}", path) from None


def _override(text: str | Given, instances, path: Path, variables=None) -> tuple[str, str, object, str, bool]:
    """One --set (or Given value) of a scene file or an SSP: owner, name,
    value, the label its errors are reported under and whether the owner is
    a section (else an instance). `variables` (one component's, or None)
    lets a Given variable name with dots be that component's variable."""
    if isinstance(text, Given):
        if text.section is not None:
            return text.section, text.key, text.value, text.label, True
        names = list(instances)
        own = variables is not None and text.key in variables
        if len(names) == 1 and (own or split_ref(text.key, names) is None):
            return names[0], text.key, text.value, text.label, False
        split = split_ref(text.key, names)
        if split is None:
            raise _no_component(text.key.partition(".")[0], names, path, text.label, sections=False)
        return split[0], split[1], text.value, text.label, False
    try:
        owner, name, value = parse_override(text, instances)
    except ValueError as e:
        raise SceneError(str(e), path) from None
    return owner, name, value, f"--set {owner}.{name}", owner in _OVERRIDABLE


def _no_component(owner: str, names: list[str], path: Path, label: str, sections: bool = True) -> SceneError:
    pool = names + (list(_OVERRIDABLE) if sections else [])
    close = difflib.get_close_matches(owner, pool, n=1) if len(owner) <= 200 else []  # not a long name, quadratic
    hint = f" (did you mean {close[0]}?)" if close else ""
    return SceneError(f"no component named {shorten(owner, 80)}{hint}; components: "
                      f"{shorten(', '.join(names), 300) or 'none'}", path, label)


def _load_system(path: Path, ssp, overrides, kinds: Kinds, input_file) -> Scene:
    """An SSP archive, an SSD file or an FMU alone through the same checks
    as a scene file: the SSP (or FMU) gives the components and connections,
    its default experiment, annotations and --set the other sections
    (docs/scenes.md, "SSP and SSD"; docs/own-fmu.md)."""
    for w in ssp.warnings:
        say("warning", w)
    raw = {"scene": {"title": ssp.name, "description": ssp.description}, **ssp.sections}
    components = dict(ssp.components)
    connected = {(c.dst_instance, c.dst_var) for c in ssp.connections}
    labels: dict[str, str | tuple[str, str]] = dict(ssp.labels)  # where each section value came from
    applied = []
    only = variables_of(next(iter(components.values())).model_description) if len(components) == 1 else None
    for text in overrides:
        if isinstance(text, Given) and text.key is None:
            raw[text.section] = text.value
            continue
        owner, name, value, label, section = _override(text, components, path, only)
        applied.append(text.text(owner, name) if isinstance(text, Given) else text)
        if section:
            raw.setdefault(owner, {})[name] = value
            labels.update(text.labels(owner, name) if isinstance(text, Given) else {f"{owner}.{name}": label})
            continue
        if owner not in components and len(components) == 1:
            # one component: a dotted variable name needs no prefix either (`--set MLoad.k=2`)
            (only, comp), = components.items()
            if f"{owner}.{name}" in variables_of(comp.model_description):
                owner, name = only, f"{owner}.{name}"
        if owner not in components:
            raise _no_component(owner, list(components), path, label)
        inst = owner
        comp, var = components[inst], name
        ctx = Ctx(path, {})
        v = lookup(ctx, label, variables_of(comp.model_description), var, inst, comp.model_name, want="parameter")
        if v.causality == "structuralParameter":
            raise SceneError(f"{inst}.{var} {STRUCTURAL}", path, label)
        if v.causality == "input" and (inst, var) in connected:
            raise SceneError(f"{inst}.{var} is a connected input; expected {SETTABLE}", path, label)
        problem = settable_problem(v)
        if problem:
            raise SceneError(f"{inst}.{var} is {article(v.causality)} {v.causality} ({problem}); expected {SETTABLE}",
                             path, label)
        value = convert_value(ctx, label, value, v, comp.model_description)
        components[inst] = dataclasses.replace(comp, parameters={**comp.parameters, var: value})
    _ssp_stop(ssp, raw, labels)
    _ssp_step_hints(ssp, raw, components, labels)
    outputs = raw.get("record", {}).get("outputs")
    if isinstance(outputs, list) and all(isinstance(o, str) for o in outputs):
        # a system connector records the component output it passes on
        outputs = raw["record"]["outputs"] = [ssp.aliases.get(o, o) for o in outputs]
    raw.setdefault("analysis", {"kind": "time_series"})  # --set analysis.kind=... may choose another
    ctx = Ctx(path, labels)
    return _build(ctx, raw, tuple(applied), ssp.sha256, kinds, (components, ssp.connections), input_file)


def _ssp_stop(ssp, raw: dict, labels: dict) -> None:
    """An SSD without a stopTime (and no --set experiment.stop) stops 1 s
    after its start, as fmpy does (and OMSimulator, from 0 s), with a note."""
    experiment = raw.setdefault("experiment", {})
    if "stop" in experiment or ssp.no_stop is None:
        return
    try:
        start = to_seconds(experiment.get("start", 0.0))
    except UnitError:
        return  # refused under experiment.start
    experiment["stop"] = start + 1.0
    label, key = ssp.no_stop
    labels.setdefault("experiment.stop", (label, f"{key} (no stopTime: the start + 1 s)"))
    term = getattr(ssp, "stop_term", "ssd:DefaultExperiment stopTime")
    like = getattr(ssp, "stop_like", "as fmpy does")
    say("note", f"{label}: {key}: no {term}: the run stops 1 s after the start, at "
                f"{fmt(start + 1.0)} s, {like} (--set experiment.stop=<time> for another)")


def _ssp_step_hints(ssp, raw: dict, components: dict, labels: dict) -> None:
    """The components' osp:StepSizeHint (an SSD's OSP annotation; SSP itself
    has no per-component step) or OSP stepSize: libcosim steps a component
    every k-th base step with a step of k base steps (ecos too). Hints that
    give every component the same step make that step master.step (one
    rate: the single-rate master, as before); hints that differ become the
    components' own steps (multi-rate, engine/multirate.py), each checked
    as a whole multiple of master.step with the master (a refusal names the
    file and key of the hint). A --set master.step chooses the step for
    all, with a note."""
    hints = ssp.step_hints
    if not hints:
        return
    term = getattr(ssp, "step_term", "osp:StepSizeHint")
    if isinstance(labels.get("master.step"), str):  # a --set (the SSD's own steps are (file, key) pairs)
        label, key = next(iter(hints.values()))[1:]
        say("note", f"{label}: {key}: --set master.step steps every component alike; the "
                    f"components' {term} ({len(hints)}) are not applied")
        return
    master = raw.setdefault("master", {})
    base = master.get("step", MASTER_DEFAULTS["step"])
    steps = {inst: hints[inst][0] if inst in hints else base for inst in components}
    first = next(iter(steps))
    if all(h == steps[first] for h in steps.values()):
        master["step"] = steps[first]
        if first in hints:
            labels["master.step"] = tuple(hints[first][1:])
        return
    for inst, (step, label, key) in hints.items():
        components[inst] = dataclasses.replace(components[inst], step=step)
        labels[f"components.{inst}.step"] = (label, key)


def _build(ctx: Ctx, raw: dict, overrides: tuple[str, ...], digest: str, kinds: Kinds,
           prebuilt: tuple | None = None, input_file=None) -> Scene:
    if prebuilt is None:
        ctx.check_keys(raw, TOP_KEYS, "", required=("scene", "components", "experiment"))

    scene_t = ctx.table(raw, "scene", "", required=True)
    ctx.check_keys(scene_t, ("title", "description", "reproduces"), "scene", required=("title",))
    for k in ("title", "description", "reproduces"):
        if k in scene_t and not isinstance(scene_t[k], str):
            raise ctx.bad(f"scene.{k}", scene_t[k], "a string")
    if not scene_t["title"].strip():
        raise ctx.bad("scene.title", scene_t["title"], "a non-empty title")

    # The FMI version picks the build that model names load: known first.
    master_t = ctx.table(raw, "master", "") or {}
    fmi_version = (master_value(ctx, "fmi_version", master_t["fmi_version"]) if "fmi_version" in master_t
                   else MASTER_DEFAULTS["fmi_version"])
    if prebuilt is None:
        components, input_params = _components(ctx, ctx.table(raw, "components", "", required=True), fmi_version)
        connections, notes = _connections(ctx, raw.get("connections", []), components, input_params)
    else:
        components, connections = prebuilt
        notes = ()
    loops, wired = _check_wiring(ctx, components, connections)
    experiment = _experiment(ctx, ctx.table(raw, "experiment", "", required=True))
    master, master_given = _master(ctx, master_t)
    problem = multirate.loop_problem(rates(master, components), [
        (name, sorted({k.src for k in links} | {k.dst for k in links})) for name, links, _ in loops])
    if problem:
        raise ctx.fail("components", problem)
    if master.me_groups and sum(i.joins_me_group for i in wired.values()) > 1:
        notes = tuple(notes) + _me_group_notes(ctx, wired, connections)
    notes = tuple(notes) + tuple(_loop_note(name, links, master.algebraic_loops, held)
                                 for name, links, held in loops)
    problem = consistency(master, experiment, components, connections) or _fmi3_inputs(master, components, connections)
    if problem:
        raise ctx.fail(*problem)
    if master.tolerance is None:
        _check_default_tolerances(components)
    problem = _me_solver_problem(master, components)
    if problem:
        raise ctx.fail("master.me_solver", problem)
    if master.engine == "compiled":
        # Asked for by name: links the core cannot pass on are refused now, not at run time
        # (those of FMI 3.0 clocks are the clocks' part, engine/clocks.py, on either engine).
        reason = compiled.unsupported_links(
            (str(c), components[c.src_instance].variable(c.src_var).type) for c in connections
            if not _clocked(components[c.src_instance].variable(c.src_var))
            and not _clocked(components[c.dst_instance].variable(c.dst_var)))
        if reason:
            raise ctx.fail("master.engine", f'expected "auto" or "python" here: {reason}')
    record = _record(ctx, ctx.table(raw, "record", ""), components)
    analysis = _analysis(ctx, ctx.table(raw, "analysis", ""), kinds)
    _multirate_analysis(ctx, master, components, analysis)
    connected_inputs = {(c.dst_instance, c.dst_var) for c in connections}
    sweep = parse_sweep(ctx, ctx.table(raw, "sweep", ""), components, connected_inputs)
    plots = _plots(ctx, raw.get("plot", []), kinds)
    if (analysis or {}).get("kind", "time_series") == "time_series":
        plots = _plot_array_elements(plots, components)
        if not plots and sweep is None:  # a sweep's points are not one series
            plots = _default_plot(ctx, record, components, kinds)
        _check_series_plots(ctx, plots, record, components)
    inputs = _inputs(ctx, ctx.table(raw, "inputs", ""), components, connections, input_file)
    if inputs is not None and master.engine == "compiled":
        _check_compiled_inputs(ctx, inputs, components)

    scene = Scene(
        path=ctx.path,
        title=scene_t["title"],
        description=scene_t.get("description", ""),
        reproduces=scene_t.get("reproduces", ""),
        components=components,
        connections=connections,
        experiment=experiment,
        master=master,
        record=record,
        analysis=analysis,
        sweep=sweep,
        plots=plots,
        overrides=overrides,
        sha256=digest,
        master_given=master_given,
        notes=notes,
        inputs=inputs,
        origins=dict(ctx.labels),
    )
    if sweep and any(a.parameter[0] in ("master", "experiment") for a in sweep.axes):
        for point in sweep.points():
            try:
                scene.variant(point)
            except SceneError as e:
                raise ctx.fail("sweep", f"a sweep point is inconsistent: {e.key}: {e.detail}") from None
    return scene


# The plot a time series gets when its scene asks for none (results/plots/outputs.py).
DEFAULT_PLOT = {"kind": "outputs", "file": "outputs.png"}


def _default_plot(ctx: Ctx, record: Record, components: dict, kinds: Kinds) -> tuple[dict, ...]:
    """The recorded numbers, grouped by unit (where the plot layer registered
    the kind, and there is a number to draw: Strings are recorded as text)."""
    if DEFAULT_PLOT["kind"] not in kinds.plot_keys:
        return ()
    if all(components[i].variable(v).type in TEXT_TYPES for i, v in record.outputs):
        return ()
    return (_kind_table(ctx, dict(DEFAULT_PLOT), "plot[0]", kinds.plot_keys, kinds.plot_convert),)


def _inputs(ctx: Ctx, t: dict | None, components: dict, connections, given) -> Inputs | None:
    """The samples of [inputs] file (relative to the scene file), or of the
    file given on the command line (relative to the current directory)."""
    if t is not None:
        ctx.check_keys(t, ("file",), "inputs", required=("file",))
        if not isinstance(t["file"], str) or not t["file"].strip():
            raise ctx.bad("inputs.file", t["file"], "the path of a CSV input file")
    if given is not None:
        path = Path(given).expanduser()
    elif t is None:
        return None
    else:
        path = Path(t["file"]).expanduser()
        path = path if path.is_absolute() else ctx.path.parent / path
        if not path.exists():
            raise ctx.fail("inputs.file", f"no such input file: {path} (a relative path is taken from the "
                                          "scene file's directory)")
    connected = {(c.dst_instance, c.dst_var) for c in connections}
    given_values = {(n, p) for n, c in components.items() for p in c.parameters}
    return read_inputs(path, components, connected, given_values)


def _components(ctx: Ctx, table: dict, fmi_version: int = 2) -> tuple[dict[str, Component], set]:
    if not table:
        raise ctx.fail("components", "expected at least one [components.<instance>] table")
    out: dict[str, Component] = {}
    input_params = set()
    for name, t in table.items():
        where = f"components.{name}"
        problem = instance_problem(name)
        if problem:
            raise ctx.fail(where, problem)
        if not isinstance(t, dict):
            raise ctx.bad(where, t, f"a table [components.{name}] with keys fmu, parameters")
        ctx.check_keys(t, ("fmu", "parameters", "interface", "step"), where, required=("fmu",))
        spec = t["fmu"]
        if not isinstance(spec, str):
            raise ctx.bad(f"{where}.fmu", spec, "a model name or a path ending .fmu")
        try:
            fpath = resolve_fmu(spec, ctx.path.parent, fmi_version)
            md, digest, indicators = read_fmu(fpath)
        except FmuError as e:
            raise ctx.fail(f"{where}.fmu", str(e)) from None
        interface = t.get("interface")
        if interface is not None:
            if interface not in INTERFACES:
                raise ctx.bad(f"{where}.interface", interface, " or ".join(f'"{i}"' for i in INTERFACES))
            try:
                interface_of(md, interface)
            except SceneError as e:
                raise ctx.fail(f"{where}.interface", e.detail) from None
        if interface_of(md, interface) == "model-exchange":
            problem = model_exchange_problem(md)
            if problem:
                raise ctx.fail(f"{where}.fmu", f"{fpath.name}: {problem}")
            indicators = ()  # the FMU's own event indicators are located inside its wrapper
        params_t = ctx.table(t, "parameters", where) or {}
        params = {}
        variables = variables_of(md)
        for pname, value in params_t.items():
            key = f"{where}.parameters.{pname}"
            v = lookup(ctx, key, variables, pname, name, md.modelName, want="parameter")
            if v.causality == "input":
                input_params.add((name, pname, key))
            elif v.causality == "structuralParameter":
                raise ctx.fail(key, f"{md.modelName}.{pname} {STRUCTURAL}")
            elif settable_problem(v):
                raise ctx.fail(
                    key, f"{md.modelName}.{pname} is {article(v.causality)} {v.causality}, not a parameter "
                    f"({settable_problem(v)}); parameters: {', '.join(names_of(variables, 'parameter'))}")
            params[pname] = convert_value(ctx, key, value, v, md)
        step = _component_step(ctx, f"{where}.step", t["step"]) if "step" in t else None
        out[name] = Component(name, fpath, digest, md, params, indicators, interface, step=step)
    return out, input_params


# The analyses that step on the grid of master.step only (run_until), as the multi-rate master steps.
MULTIRATE_KINDS = ("time_series", "ticks")


def _multirate_analysis(ctx: Ctx, master: MasterSettings, components: dict, analysis: dict | None) -> None:
    """Components at different rates step on the base grid only: the
    analyses that choose their own steps (landing after a tick, a schedule
    of inputs) are refused in one line."""
    kind = (analysis or {}).get("kind", "time_series")
    if kind in MULTIRATE_KINDS or not multirate.is_multirate(rates(master, components)):
        return
    slow = ", ".join(f"{n} ({c.step:g} s)" for n, c in components.items() if c.step is not None)
    raise ctx.fail("analysis.kind", f"expected {' or '.join(MULTIRATE_KINDS)} with components at their own steps "
                                    f"({slow}): {kind} chooses the master's steps itself, and the multi-rate "
                                    "master takes whole base steps only")


def _component_step(ctx: Ctx, key: str, value) -> float:
    """[components.X] step: that component's own communication step, a time
    (a unit allowed, "20 ms") > 0; a whole multiple of master.step is
    checked with the master (model.component_steps_problem)."""
    x = ctx.time(key, value)
    try:
        return MASTER_SETTINGS["step"].accept(x)
    except BadSetting as e:
        raise ctx.bad(key, value, str(e)) from None


def _me_solver_problem(master: MasterSettings, components: dict[str, Component]) -> str | None:
    """What the Model Exchange wrapper refuses when it chooses its
    integrator at the start of the run (model_exchange._choose_method),
    said by validate too: more states than the Runge-Kutta pairs take, or
    CVode where this platform has no SUNDIALS."""
    for name, c in components.items():
        if not c.model_exchange:
            continue
        n = len(c.model_description.derivatives or [])
        solver = master.me_solver
        if solver == "cvode" or (solver == "auto" and n > MAX_RK_STATES):
            problem = cvode.problem()
            if problem:
                return f"{name} ({Path(c.fmu_shown).name}): {problem}"
        elif n > MAX_RK_STATES:
            return (f"{name} ({Path(c.fmu_shown).name}) has {n} continuous states, the Runge-Kutta pairs take at "
                    f"most {MAX_RK_STATES}; expected 'cvode' or 'auto'")
    return None


def _clocked(var) -> bool:
    """An FMI 3.0 clock or clocked variable: exchanged at ticks by the clocks' part, not by the core's links."""
    return var.type == "Clock" or bool(getattr(var, "clocks", None))


def _check_compiled_inputs(ctx: Ctx, inputs: Inputs, components: dict[str, Component]) -> None:
    """master.engine = "compiled" asked for by name: an input column the
    core cannot set (it sets Real inputs only) is refused now, naming the
    column, as the run would refuse it (engine.compiled.make_master)."""
    for j, sig in enumerate(inputs.samples.signals, start=1):
        var = components[sig.instance].variable(sig.variable)
        if _clocked(var):  # a clock's ticks (engine/clocks.py), on either engine
            continue
        reason = compiled.unsupported_inputs([(sig.name, var.type)])
        if reason:
            path, key = ctx.where("master.engine")
            raise SceneError(f'{reason}: expected master.engine = "auto" or "python" ({key} asks for the compiled '
                             f'core{"" if path == ctx.path else f" in {path}"})', inputs.file or ctx.path,
                             f"column {j + 1} ({shorten(sig.name, 60)})")


def _check_default_tolerances(components: dict[str, Component]) -> None:
    """Without master.tolerance each FMU gets its DefaultExperiment's
    tolerance (fmi2SetupExperiment, fmi3EnterInitializationMode; the Model
    Exchange wrapper integrates at it). A relative tolerance that is not > 0
    is refused where it would be used, naming the FMU's attribute: the
    schema lets any xs:double through, and an integrator at rtol -1 is no
    integration. FMI 1.0 Co-Simulation takes no tolerance: not used there."""
    for c in components.values():
        md = c.model_description
        problem = default_tolerance_problem(md)
        if problem:
            raise SceneError(f"{problem}; or give master.tolerance (the run's, for every FMU)", c.fmu_shown,
                             f"modelDescription.xml: DefaultExperiment tolerance = {md.defaultExperiment.tolerance}")


def _check_wiring(ctx: Ctx, components: dict[str, Component],
                  connections) -> list[tuple[str, list[Link], list[str]]]:
    """The wiring as the master will build it, by the engine's own code:
    what it refuses is refused now. Returns the algebraic loops (name,
    links inside, the members that do not allow outputs after inputs)."""
    instances = {}
    for n, c in components.items():
        try:
            instances[n] = make_instance(n, c.fmu_path, c.model_description, interface=c.interface)
        except SceneError as e:
            # the FMU's own fault, not the wiring's: named as the FMU (never its cache copy) and its key
            detail = str(e).replace(str(c.fmu_path), c.fmu_shown)
            if ctx.path.suffix.lower() == ".toml":
                raise ctx.fail(f"components.{n}.fmu", detail) from None
            raise SceneError(detail if c.fmu_shown in detail else f"{c.fmu_shown}: {detail}") from None
    try:
        wiring = build_wiring(instances, [Link(*c) for c in connections])
    except SceneError as e:
        raise ctx.fail("connections", e.detail) from None
    held = set(wiring.held_loops)
    return [(loop_name(m, links), links,
             [n for n in m if not instances[n].outputs_after_inputs] if i in held else [])
            for i, (m, links) in enumerate(zip(wiring.loops, wiring.loop_links))], instances


def _me_group_notes(ctx: Ctx, instances, connections) -> tuple[str, ...]:
    """A note per group of connected Model Exchange FMUs (engine/me_group.py);
    an algebraic loop inside one refused now, as the run would refuse it."""
    from ..engine.me_group import plan_groups
    try:
        plans = plan_groups(instances, [Link(*c) for c in connections])
    except SceneError as e:
        raise ctx.fail("connections", e.detail) from None
    return tuple(f"Model Exchange group {name}: {', '.join(members)} integrated as one system (one integrator, "
                 f"{len(inner)} connection{'s' * (len(inner) != 1)} evaluated at every stage, events located "
                 "together; master.me_groups = false steps them apart)" for name, members, inner in plans)


def _loop_note(name: str, links: list[Link], mode: str, held: list[str]) -> str:
    """How the master handles a loop; `held`: its members whose outputs may
    not be read after their inputs are set without a step (docs/master.md,
    "The call sequence")."""
    through = ", ".join(f"{k.src}.{k.output} -> {k.dst}.{k.input}" for k in links)
    how = ("solved to a fixed point at every communication point" if mode == "solve"
           else "broken by a one-step delay")
    if mode == "solve" and held:
        how = (f"solved in Initialization Mode, then broken by a one-step delay: {', '.join(held)} "
               f"do{'es' * (len(held) == 1)} not allow outputs to be read after inputs are set without a step "
               "(FMI 2.0 4.2.4, FMI 3.0 Step Mode)")
    return f'algebraic loop {name} (through {through}): {how} (master.algebraic_loops = "{mode}")'


def _connections(ctx: Ctx, conns, components: dict[str, Component],
                 input_params: set) -> tuple[tuple[Connection, ...], tuple[str, ...]]:
    if not isinstance(conns, list):
        raise ctx.bad("connections", conns, 'an array of "src.output -> dst.input" strings')
    out = []
    seen: dict[tuple[str, str], int] = {}
    set_inputs = {(inst, var): key for inst, var, key in input_params}
    checked = []
    known = ComponentVariables(components)
    for i, c in enumerate(conns):
        key = f"connections[{i}]"
        if not isinstance(c, str):
            raise ctx.bad(key, c, 'a string "src.output -> dst.input"')
        ends_text = split_link(c)
        if ends_text is None:
            raise ctx.bad(key, c, 'a string "src.output -> dst.input"')
        refs = []
        for ref in ends_text:
            split = split_ref(ref, known)
            if split is None:
                inst = ref.partition(".")[0]
                component(ctx, key, components, inst if "." in ref else ref)  # names the components
                raise ctx.bad(key, c, 'a string "src.output -> dst.input"')
            refs.append(split)
        (si, sv), (di, dv) = refs
        ends = []
        for inst, var in refs:
            comp = component(ctx, key, components, inst)
            ends.append((comp, lookup(ctx, key, variables_of(comp.model_description), var, inst, comp.model_name,
                                      want="any")))
        (sc, s), (dc, d) = ends
        if s.causality != "output":
            what = "an input used as a source" if s.causality == "input" else f"{article(s.causality)} {s.causality}"
            raise ctx.fail(key, f"{si}.{sv} is {what}; expected an output on the left of ->; outputs: "
                                f"{', '.join(names_of(variables_of(sc.model_description), 'output'))}")
        if d.causality != "input":
            what = "an output connected to an output" if d.causality == "output" else f"{article(d.causality)} {d.causality}"
            raise ctx.fail(key, f"{di}.{dv} is {what}; expected an input on the right of ->; inputs: "
                                f"{', '.join(names_of(variables_of(dc.model_description), 'input'))}")
        if (di, dv) in seen:
            raise ctx.fail(key, f"input {di}.{dv} is connected twice (also by connections[{seen[(di, dv)]}])")
        if (di, dv) in set_inputs:
            raise ctx.fail(key, f"input {di}.{dv} is connected and also set in {ctx.key(set_inputs[(di, dv)])}")
        seen[(di, dv)] = i
        checked.append((key, si, sv, di, dv, sc, s, dc, d))
    # Structure first (names, directions, duplicates), then types and units.
    notes = []
    for key, si, sv, di, dv, sc, s, dc, d in checked:
        if not types_connect(s.type, d.type):
            raise ctx.fail(key, f"type mismatch: {si}.{sv} is {type_name(sc.model_description, s)}, "
                                f"{di}.{dv} is {type_name(dc.model_description, d)}")
        problem = link_shape_problem(f"{si}.{sv}", s, f"{di}.{dv}", d)
        if problem:
            raise ctx.fail(key, problem)
        su, du = var_unit(s), var_unit(d)
        factor, offset = 1.0, 0.0
        if su != du and (su is None or du is None):
            # Most tools export signals without units; the number passes on as it is.
            notes.append(f"{key}: {si}.{sv} is in {su or 'no unit'}, {di}.{dv} in {du or 'no unit'}: "
                         f"the value passes unconverted")
        elif su != du:
            # Converted where both FMUs define the units on the same SI base unit.
            conversion = link_conversion(sc.model_description, su, dc.model_description, du)
            if conversion is None:
                raise ctx.fail(key, f"unit mismatch: {si}.{sv} is in {su}, {di}.{dv} in {du}, and their "
                                    f"UnitDefinitions do not give both the same SI base unit")
            factor, offset = conversion
        out.append(Connection(si, sv, di, dv, factor, offset))
    return tuple(out), tuple(notes)


def _experiment(ctx: Ctx, t: dict) -> Experiment:
    ctx.check_keys(t, ("start", "stop"), "experiment", required=("stop",))
    start = ctx.time("experiment.start", t.get("start", 0.0))
    stop = ctx.time("experiment.stop", t["stop"])
    if not stop > start:
        # the start given moved past a stop the user did not give (a file's own stop has a (file, key) origin)
        if isinstance(ctx.labels.get("experiment.start"), str) and not isinstance(ctx.labels.get("experiment.stop"), str):
            raise ctx.bad("experiment.start", t["start"], f"a time < experiment.stop ({fmt(stop)} s)")
        raise ctx.bad("experiment.stop", t["stop"], f"a time > experiment.start ({fmt(start)} s)")
    return Experiment(start, stop)


def _takes_intermediate_update(md, name: str) -> bool:
    """An FMI 3.0 input the FMU asks for at its own times (FMI 3.0's
    replacement for input derivatives)."""
    if not md.coSimulation or not md.coSimulation.providesIntermediateUpdate:
        return False
    return any(v.name == name and v.intermediateUpdate and not v.shape for v in md.modelVariables)  # arrays: no


def _fmi3_inputs(m: MasterSettings, components: dict[str, Component], connections) -> tuple[str, str] | None:
    """FMI 3.0 Co-Simulation takes no input derivatives: inputs given as
    polynomials (extrapolation, strong coupling) reach an FMI 3.0 FMU with
    dynamics (an output that does not depend on inputs) only through
    intermediate update, on inputs that declare it. The
    engine checks the exact rule again when it wires the FMUs."""
    key = "extrapolation" if m.extrapolation else "iterations" if m.iterations > 0 else None
    if key is None:
        return None
    for c in connections:
        comp = components[c.dst_instance]
        md = comp.model_description
        if comp.model_exchange:
            continue  # the Model Exchange wrapper takes input derivatives
        dynamic = any(o.dependencies is not None and not o.dependencies for o in md.outputs)
        if md.fmiVersion == "3.0" and dynamic and not _takes_intermediate_update(md, c.dst_var):
            return (f"master.{key}", f"{c.dst_instance} ({Path(comp.fmu_shown).name}) is an FMI 3.0 FMU with dynamics "
                    f"whose {c.dst_var} has no intermediate update, and its Co-Simulation interface takes no "
                    f"input derivatives: {key} needs them for {c.dst_instance}.{c.dst_var}; use "
                    f"master.{key} = 0 or an FMI 2.0 build")
    return None


def _master(ctx: Ctx, t: dict) -> tuple[MasterSettings, frozenset]:
    """The [master] table as the master's settings (its keys are
    MasterSettings' fields, each checked by its declaration), and the keys
    it gave."""
    ctx.check_keys(t, MASTER_SETTINGS, "master")
    values = dict(MASTER_DEFAULTS)
    for k, v in t.items():
        values[k] = master_value(ctx, k, v)
    try:
        return MasterSettings(**follow(values, t)), frozenset(t)
    except SceneError as e:  # a combination (each value is checked above)
        raise ctx.fail(e.key or "master", e.detail) from None


def _record(ctx: Ctx, t: dict | None, components: dict[str, Component]) -> Record:
    t = t or {}
    ctx.check_keys(t, ("outputs", "interval", "ticks", "format"), "record")
    if "outputs" in t:
        refs = t["outputs"]
        if not isinstance(refs, list):
            raise ctx.bad("record.outputs", refs, 'an array of "instance.variable" strings')
        outputs = {}  # (instance, variable) -> its position: a dict, for the duplicate check of thousands
        for i, ref in enumerate(refs):
            key = f"record.outputs[{i}]"
            comp, v = parse_ref(ctx, key, ref, components, "a variable")
            if v.type == "Clock" or getattr(v, "clocks", None):  # engine/clocks.py records them at their ticks
                raise ctx.fail(key, f"{ref} is {'a clock' if v.type == 'Clock' else 'clocked'}: its ticks and "
                                    "values at its ticks are in the result's clock_ticks and clocked; expected a "
                                    "variable of the communication points")
            if v.causality not in ("output", "input", "parameter", "calculatedParameter", "local"):
                raise ctx.fail(key, f"{ref} is {article(v.causality)} {v.causality} variable; "
                                    "expected an output, input, parameter or local variable (such as der(x))")
            for name in element_names(v):  # an FMI 3.0 array: each element
                pair = (comp.name, name)
                if pair in outputs:
                    raise ctx.fail(key, f"{comp.name}.{name} is listed twice")
                outputs[pair] = len(outputs)
    else:
        outputs = [(n, name) for n, c in components.items()
                   for v in c.model_description.modelVariables if v.causality == "output"
                   and v.type != "Clock" and not getattr(v, "clocks", None)  # at their ticks (engine/clocks.py)
                   for name in element_names(v)]
    interval = None
    if "interval" in t:
        interval = ctx.time("record.interval", t["interval"])
        if not interval > 0:
            raise ctx.bad("record.interval", t["interval"], "a time > 0")
    ticks = t.get("ticks")
    if ticks is not None:
        if not isinstance(ticks, str) or ticks not in components:
            raise ctx.bad("record.ticks", ticks, f"the name of a component: {', '.join(components)}")
        variables = variables_of(components[ticks].model_description)
        for need in ("tick_time", "tick_count"):
            if need not in variables or variables[need].causality != "output":
                raise ctx.bad("record.ticks", ticks, "a component with tick_time and tick_count outputs (a Pendulum)")
    formats = ("csv",)
    if "format" in t:
        formats = _formats(ctx, t["format"])
    return Record(tuple(outputs), interval, ticks, formats)


def _formats(ctx: Ctx, value) -> tuple[str, ...]:
    """record.format: a name or a list of names of RESULT_FORMATS ("csv,mat" too)."""
    expected = f"one of {', '.join(RESULT_FORMATS)}, or a list of them"
    names = value if isinstance(value, list) else [value]
    out: list[str] = []
    for i, name in enumerate(names):
        key = f"record.format[{i}]" if isinstance(value, list) else "record.format"
        if not isinstance(name, str):
            raise ctx.bad(key, name, expected)
        for part in name.split(","):
            part = part.strip().lower()
            if part not in RESULT_FORMATS:
                raise ctx.bad(key, name, expected)
            if part not in out:
                out.append(part)
    if not out:
        raise ctx.bad("record.format", value, expected)
    return tuple(out)


def _kind_table(ctx: Ctx, t: dict, where: str, registry: dict, converters: dict) -> dict:
    if "kind" not in t:
        raise ctx.fail(f"{where}.kind", f"missing required key; kinds: {', '.join(registry)}")
    kind = t["kind"]
    if not isinstance(kind, str) or kind not in registry:
        close = difflib.get_close_matches(kind, list(registry), n=1) if isinstance(kind, str) else []
        hint = f" (did you mean {close[0]}?)" if close else ""
        raise ctx.bad(f"{where}.kind", kind, f"one of {', '.join(registry)}{hint}")
    ctx.check_keys(t, {"kind"} | registry[kind], where)
    body = {k: v for k, v in t.items() if k != "kind"}
    conv = converters.get(kind)
    if conv is not None:
        try:
            body = conv(body)
        except Invalid as e:
            raise ctx.bad(f"{where}.{e.key}", t.get(e.key), e.expected) from None
    return {"kind": kind, **body}


def _analysis(ctx: Ctx, t: dict | None, kinds: Kinds) -> dict | None:
    if t is None:
        return None
    return _kind_table(ctx, t, "analysis", kinds.analysis_keys, kinds.analysis_convert)


# Plot kinds that draw the recorded outputs of a time_series analysis.
_SERIES_PLOTS = ("time_series", "phase_portrait", "outputs")


def _plot_array_elements(plots: tuple[dict, ...], components: dict) -> tuple[dict, ...]:
    """A series plot's `y` naming an FMI 3.0 array draws each of its elements."""
    variables = {n: variables_of(c.model_description) for n, c in components.items()}

    def elements(name: str) -> list[str]:
        split = split_ref(name, variables)
        v = variables[split[0]].get(split[1]) if split else None
        return [f"{split[0]}.{e}" for e in element_names(v)] if v is not None and v.shape else [name]

    out = []
    for spec in plots:
        ys = spec.get("y")
        if spec["kind"] in _SERIES_PLOTS and isinstance(ys, (str, list)):
            names = [ys] if isinstance(ys, str) else ys
            expanded = [e for y in names if isinstance(y, str) for e in elements(y)]
            if expanded != names:
                spec = {**spec, "y": expanded}
        out.append(spec)
    return tuple(out)


def _check_series_plots(ctx: Ctx, plots: tuple[dict, ...], record: Record, components: dict) -> None:
    """A time series can only draw what [record] records, and numbers only:
    refuse a typo or a String column now, not after the run."""
    recorded = {f"{inst}.{var}" for inst, var in record.outputs}
    text = {f"{inst}.{var}" for inst, var in record.outputs if components[inst].variable(var).type in TEXT_TYPES}
    for i, spec in enumerate(plots):
        if spec["kind"] not in _SERIES_PLOTS:
            continue
        for key in ("x", "y"):
            names = spec.get(key)
            for name in [names] if isinstance(names, str) else names or []:
                if name in text:
                    raise ctx.fail(f"plot[{i}].{key}", f"{name} is a String: a plot draws numbers; record it "
                                                       "without plotting it")
                if name != "time" and name not in recorded:
                    close = difflib.get_close_matches(name, sorted(recorded), n=1)
                    hint = f" (did you mean {close[0]}?)" if close else ""
                    raise ctx.fail(f"plot[{i}].{key}", f"{name} is not recorded{hint}: expected \"time\" or one "
                                                       f"of record.outputs ({', '.join(sorted(recorded)) or 'none'})")


def _plots(ctx: Ctx, plots, kinds: Kinds) -> tuple[dict, ...]:
    if not isinstance(plots, list):
        raise ctx.bad("plot", plots, "an array of tables [[plot]]")
    out = []
    for i, t in enumerate(plots):
        if not isinstance(t, dict):
            raise ctx.bad(f"plot[{i}]", t, "a table [[plot]]")
        out.append(_kind_table(ctx, t, f"plot[{i}]", kinds.plot_keys, kinds.plot_convert))
    files: dict[str, int] = {}
    for i, spec in enumerate(out):
        name = spec.get("file") or f"plot{i + 1}_{spec['kind']}.png"
        if name.lower() in files:
            raise ctx.fail(f"plot[{i}].file", f"{name} is also the file of plot[{files[name.lower()]}]: "
                                              "give each plot its own file name")
        files[name.lower()] = i
    return tuple(out)
