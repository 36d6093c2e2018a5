"""Scene files: loading and strict validation (format: docs/scenes.md).

``load_scene(path, overrides, kinds)`` reads a TOML scene, applies ``--set``
overrides, checks every key and value against the FMUs' model descriptions
and returns a frozen ``Scene`` with all quantities converted to the
variables' own (SI) units. Every problem raises ``SceneError`` with a
one-line message naming the file, the dotted key and what was expected.
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
import tomllib
from pathlib import Path

from ..engine import compiled
from ..engine.description import (TEXT_TYPES, FmuError, read_fmu, resolve_fmu, type_name, types_connect,
                                  var_unit)
from ..engine.description import variables as variables_of
from ..engine.fmu3 import make_instance
from ..engine.names import instance_name_problem, split_link, split_ref
from ..engine.wiring import Link, loop_name
from ..engine.wiring import build as build_wiring
from ..errors import SceneError
from .checks import TOP_KEYS, Ctx, article, component, convert_value, lookup, master_value, names_of, parse_ref
from .kinds import NO_KINDS, Invalid, Kinds
from .model import (Component, ComponentVariables, Connection, Experiment, MasterConfig, Record, Scene, consistency)
from .ssp.read import read_ssp
from .sweep import parse_sweep
from .units import fmt, link_conversion

MAX_SCENE_BYTES = 1 << 20  # scene files are a few kB; a larger one is not a scene
_OVERRIDABLE = ("scene", "experiment", "master", "record", "analysis")
_MASTER_DEFAULTS = {f.name: f.default for f in dataclasses.fields(MasterConfig)}


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
    if split is None:
        head, dot, tail = lhs.partition(".")
        split = (head, tail) if dot and head and tail and not tail.endswith(".") else None
    if split is None or not re.fullmatch(r"[^\s=]+(?:\s*[^\s=]+)*", lhs):
        raise ValueError(f"--set {text}: expected instance.parameter=value, got the key {lhs!r}")
    return split[0], split[1], _override_value(lhs, rhs)


def _override_value(lhs: str, rhs: str) -> object:
    try:
        return tomllib.loads("v = " + rhs)["v"]
    except tomllib.TOMLDecodeError:
        return rhs.strip()
    except RecursionError:
        raise ValueError(f"--set {lhs}: the value is nested deeper than Python can read") from None


def load_scene(path: str | os.PathLike, overrides=(), kinds: Kinds = NO_KINDS) -> Scene:
    """Load, override and validate a scene file (or an .ssp/.ssd); raises SceneError."""
    path = Path(path)
    if path.suffix.lower() in (".ssp", ".ssd"):
        return _load_ssp(path, overrides, kinds)
    try:
        # Read at most one byte past the limit: a device or a pipe reports no size.
        with open(path, "rb") as f:
            data = f.read(MAX_SCENE_BYTES + 1)
        if len(data) > MAX_SCENE_BYTES:
            size = path.stat().st_size if path.is_file() else None
            raise SceneError(f"{size if size else 'more than ' + str(MAX_SCENE_BYTES)} bytes: "
                             f"a scene file is at most {MAX_SCENE_BYTES} bytes", path)
    except FileNotFoundError:
        raise SceneError("no such scene file", path) from None
    except IsADirectoryError:
        raise SceneError("is a directory, expected a .toml scene file", path) from None
    except OSError as e:
        raise SceneError(f"cannot read: {e.strerror}", path) from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as e:
        if data[:4] == b"PK\x03\x04":  # a zip archive: an FMU or an SSP given where a scene goes
            raise SceneError("a zip archive, not a scene: expected a .toml scene file, an .ssp archive or "
                             "an .ssd file (an FMU is run from a scene that names it; `clockwork info` lists "
                             "its variables)", path) from None
        raise SceneError(f"not UTF-8 text (byte {e.start})", path) from None
    try:
        raw = tomllib.loads(text)
    except RecursionError:
        raise SceneError("malformed TOML: arrays or tables nested too deeply", path) from None
    except tomllib.TOMLDecodeError as e:
        msg = str(e)
        m = re.search(r"\(at line (\d+), column (\d+)\)", msg)
        where = f"line {m.group(1)}" if m else "line ?"
        if m:
            msg = msg[: m.start()].strip() + f" at column {m.group(2)}"
        elif "end of document" in msg:
            where = f"line {text.count(chr(10)) + 1}"
        raise SceneError(f"malformed TOML: {msg}", path, where) from None

    labels: dict[str, str] = {}
    applied = []
    comps_raw = raw.get("components")
    instance_names = list(comps_raw) if isinstance(comps_raw, dict) else []
    for text_ov in overrides:
        owner, name, value, label = _override(text_ov, instance_names, path)
        applied.append(text_ov)
        if owner in _OVERRIDABLE:
            sect = raw.setdefault(owner, {})
            if not isinstance(sect, dict):
                raise SceneError(f"[{owner}] is not a table in the file", path, label)
            sect[name] = value
            labels[f"{owner}.{name}"] = label
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
    return _build(ctx, raw, tuple(applied), hashlib.sha256(data).hexdigest(), kinds)


def _override(text: str, instances, path: Path) -> tuple[str, str, object, str]:
    """One --set of a scene file or an SSP: owner, name, value and the label
    its errors are reported under."""
    try:
        owner, name, value = parse_override(text, instances)
    except ValueError as e:
        raise SceneError(str(e), path) from None
    return owner, name, value, f"--set {owner}.{name}"


def _no_component(owner: str, names: list[str], path: Path, label: str) -> SceneError:
    close = difflib.get_close_matches(owner, names + list(_OVERRIDABLE), n=1)
    hint = f" (did you mean {close[0]}?)" if close else ""
    return SceneError(f"no component named {owner}{hint}; components: {', '.join(names) or 'none'}", path, label)


def _load_ssp(path: Path, overrides, kinds: Kinds) -> Scene:
    """An SSP archive or SSD file through the same checks as a scene file:
    the SSP gives the components and connections, its default experiment,
    annotations and --set the other sections (docs/scenes.md, "SSP and SSD")."""
    ssp = read_ssp(path)
    for w in ssp.warnings:
        print(f"clockwork: warning: {w}", file=sys.stderr)
    raw = {"scene": {"title": ssp.name, "description": ssp.description}, **ssp.sections}
    components = dict(ssp.components)
    connected = {(c.dst_instance, c.dst_var) for c in ssp.connections}
    labels: dict[str, str] = {}
    applied = []
    for text in overrides:
        owner, name, value, label = _override(text, components, path)
        applied.append(text)
        if owner in _OVERRIDABLE:
            raw.setdefault(owner, {})[name] = value
            labels[f"{owner}.{name}"] = label
            continue
        if owner not in components:
            raise _no_component(owner, list(components), path, label)
        inst = owner
        comp, var = components[inst], name
        ctx = Ctx(path, {})
        v = lookup(ctx, label, variables_of(comp.model_description), var, inst, comp.model_name, want="parameter")
        if v.causality not in ("parameter", "input") or (inst, var) in connected:
            what = "a connected input" if v.causality == "input" else f"{article(v.causality)} {v.causality}"
            raise SceneError(f"{inst}.{var} is {what}; expected a parameter or an unconnected input", path, label)
        value = convert_value(ctx, label, value, v, comp.model_description)
        components[inst] = dataclasses.replace(comp, parameters={**comp.parameters, var: value})
    if "stop" not in raw.get("experiment", {}):
        raise SceneError("missing: the SSD has no ssd:DefaultExperiment stopTime; expected one, or "
                         "--set experiment.stop=<time>", path, "ssd:DefaultExperiment stopTime")
    outputs = raw.get("record", {}).get("outputs")
    if isinstance(outputs, list) and all(isinstance(o, str) for o in outputs):
        # a system connector records the component output it passes on
        outputs = raw["record"]["outputs"] = [ssp.aliases.get(o, o) for o in outputs]
    raw.setdefault("analysis", {"kind": "time_series"})  # --set analysis.kind=... may choose another
    series = isinstance(raw["analysis"], dict) and raw["analysis"].get("kind") == "time_series"
    if series and isinstance(outputs, list) and outputs and all(isinstance(o, str) for o in outputs):
        # Strings are recorded as text, not drawn.
        variables = ComponentVariables(components)
        numbers = [o for o in outputs if _column_type(o, variables) not in TEXT_TYPES]
        if numbers:
            raw["plot"] = [{"kind": "time_series", "x": "time", "y": numbers, "title": ssp.name,
                            "file": "outputs.png"}]
    ctx = Ctx(path, labels)
    return _build(ctx, raw, tuple(applied), ssp.sha256, kinds, (components, ssp.connections))


def _build(ctx: Ctx, raw: dict, overrides: tuple[str, ...], digest: str, kinds: Kinds,
           prebuilt: tuple | None = None) -> Scene:
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
    fmi_version = master_value(ctx, "fmi_version", master_t["fmi_version"]) if "fmi_version" in master_t else 2
    if prebuilt is None:
        components, input_params = _components(ctx, ctx.table(raw, "components", "", required=True), fmi_version)
        connections, notes = _connections(ctx, raw.get("connections", []), components, input_params)
    else:
        components, connections = prebuilt
        notes = ()
    loops = _check_wiring(ctx, components, connections)
    experiment = _experiment(ctx, ctx.table(raw, "experiment", "", required=True))
    master, max_step_given = _master(ctx, master_t)
    notes = tuple(notes) + tuple(_loop_note(name, links, master.algebraic_loops) for name, links in loops)
    problem = consistency(master, experiment, components) or _fmi3_inputs(master, components, connections)
    if problem:
        raise ctx.fail(*problem)
    if master.engine == "compiled":
        # Asked for by name: links the core cannot pass on are refused now, not at run time.
        reason = compiled.unsupported_links(
            (str(c), components[c.src_instance].variable(c.src_var).type) for c in connections)
        if reason:
            raise ctx.fail("master.engine", f'expected "auto" or "python" here: {reason}')
    record = _record(ctx, ctx.table(raw, "record", ""), components)
    analysis = _analysis(ctx, ctx.table(raw, "analysis", ""), kinds)
    connected_inputs = {(c.dst_instance, c.dst_var) for c in connections}
    sweep = parse_sweep(ctx, ctx.table(raw, "sweep", ""), components, connected_inputs)
    plots = _plots(ctx, raw.get("plot", []), kinds)
    if (analysis or {}).get("kind", "time_series") == "time_series":
        _check_series_plots(ctx, plots, record, components)

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
        max_step_given=max_step_given,
        notes=notes,
    )
    if sweep and any(a.parameter[0] in ("master", "experiment") for a in sweep.axes):
        for point in sweep.points():
            try:
                scene.variant(point)
            except SceneError as e:
                raise ctx.fail("sweep", f"a sweep point is inconsistent: {e.key}: {e.detail}") from None
    return scene


def _components(ctx: Ctx, table: dict, fmi_version: int = 2) -> tuple[dict[str, Component], set]:
    if not table:
        raise ctx.fail("components", "expected at least one [components.<instance>] table")
    out: dict[str, Component] = {}
    input_params = set()
    for name, t in table.items():
        where = f"components.{name}"
        problem = instance_name_problem(name)
        if problem:
            raise ctx.fail(where, problem)
        if name in TOP_KEYS:
            raise ctx.fail(where, f"the instance name {name} is reserved (it names a scene section)")
        if not isinstance(t, dict):
            raise ctx.bad(where, t, f"a table [components.{name}] with keys fmu, parameters")
        ctx.check_keys(t, ("fmu", "parameters"), where, required=("fmu",))
        spec = t["fmu"]
        if not isinstance(spec, str):
            raise ctx.bad(f"{where}.fmu", spec, "a model name or a path ending .fmu")
        try:
            fpath = resolve_fmu(spec, ctx.path.parent, fmi_version)
            md, digest, indicators = read_fmu(fpath)
        except FmuError as e:
            raise ctx.fail(f"{where}.fmu", str(e)) from None
        params_t = ctx.table(t, "parameters", where) or {}
        params = {}
        variables = variables_of(md)
        for pname, value in params_t.items():
            key = f"{where}.parameters.{pname}"
            v = lookup(ctx, key, variables, pname, name, md.modelName, want="parameter")
            if v.causality == "input":
                input_params.add((name, pname, key))
            elif v.causality != "parameter":
                raise ctx.fail(
                    key, f"{md.modelName}.{pname} is {article(v.causality)} {v.causality}, not a parameter; "
                    f"parameters: {', '.join(names_of(variables, 'parameter'))}")
            params[pname] = convert_value(ctx, key, value, v, md)
        out[name] = Component(name, fpath, digest, md, params, indicators)
    return out, input_params


def _check_wiring(ctx: Ctx, components: dict[str, Component], connections) -> list[tuple[str, list[Link]]]:
    """The wiring as the master will build it, by the engine's own code:
    what it refuses is refused now. Returns the algebraic loops (name,
    links inside)."""
    try:
        instances = {n: make_instance(n, c.fmu_path, c.model_description) for n, c in components.items()}
        wiring = build_wiring(instances, [Link(*c) for c in connections])
    except SceneError as e:
        raise ctx.fail("connections", e.detail) from None
    return [(loop_name(m, links), links) for m, links in zip(wiring.loops, wiring.loop_links)]


def _loop_note(name: str, links: list[Link], mode: str) -> str:
    through = ", ".join(f"{k.src}.{k.output} -> {k.dst}.{k.input}" for k in links)
    how = ("solved to a fixed point at every communication point" if mode == "solve"
           else "broken by a one-step delay")
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
            raise ctx.fail(key, f"input {di}.{dv} is connected and also set in {set_inputs[(di, dv)]}")
        seen[(di, dv)] = i
        checked.append((key, si, sv, di, dv, sc, s, dc, d))
    # Structure first (names, directions, duplicates), then types and units.
    notes = []
    for key, si, sv, di, dv, sc, s, dc, d in checked:
        if not types_connect(s.type, d.type):
            raise ctx.fail(key, f"type mismatch: {si}.{sv} is {type_name(sc.model_description, s)}, "
                                f"{di}.{dv} is {type_name(dc.model_description, d)}")
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
        raise ctx.bad("experiment.stop", t["stop"], f"a time > experiment.start ({fmt(start)} s)")
    return Experiment(start, stop)


def _takes_intermediate_update(md, name: str) -> bool:
    """An FMI 3.0 input the FMU asks for at its own times (FMI 3.0's
    replacement for input derivatives)."""
    if not md.coSimulation or not md.coSimulation.providesIntermediateUpdate:
        return False
    return any(v.name == name and v.intermediateUpdate for v in md.modelVariables)


def _fmi3_inputs(m: MasterConfig, components: dict[str, Component], connections) -> tuple[str, str] | None:
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
        dynamic = any(o.dependencies is not None and not o.dependencies for o in md.outputs)
        if md.fmiVersion == "3.0" and dynamic and not _takes_intermediate_update(md, c.dst_var):
            return (f"master.{key}", f"{c.dst_instance} ({comp.fmu_path.name}) is an FMI 3.0 FMU with dynamics "
                    f"whose {c.dst_var} has no intermediate update, and its Co-Simulation interface takes no "
                    f"input derivatives: {key} needs them for {c.dst_instance}.{c.dst_var}; use "
                    f"master.{key} = 0 or an FMI 2.0 build")
    return None


def _master(ctx: Ctx, t: dict) -> tuple[MasterConfig, bool]:
    ctx.check_keys(t, _MASTER_DEFAULTS, "master")
    values = dict(_MASTER_DEFAULTS)
    for k, v in t.items():
        values[k] = master_value(ctx, k, v)
    if "max_step" not in t:
        values["max_step"] = values["step"]
    return MasterConfig(**values), "max_step" in t


def _record(ctx: Ctx, t: dict | None, components: dict[str, Component]) -> Record:
    t = t or {}
    ctx.check_keys(t, ("outputs", "interval", "ticks"), "record")
    if "outputs" in t:
        refs = t["outputs"]
        if not isinstance(refs, list):
            raise ctx.bad("record.outputs", refs, 'an array of "instance.variable" strings')
        outputs = {}  # (instance, variable) -> its position: a dict, for the duplicate check of thousands
        for i, ref in enumerate(refs):
            key = f"record.outputs[{i}]"
            comp, v = parse_ref(ctx, key, ref, components, "a variable")
            if v.causality not in ("output", "input", "parameter", "calculatedParameter", "local"):
                raise ctx.fail(key, f"{ref} is {article(v.causality)} {v.causality} variable; "
                                    "expected an output, input, parameter or local variable (such as der(x))")
            pair = (comp.name, v.name)
            if pair in outputs:
                raise ctx.fail(key, f"{ref} is listed twice")
            outputs[pair] = i
    else:
        outputs = [(n, v.name) for n, c in components.items()
                   for v in c.model_description.modelVariables if v.causality == "output"]
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
    return Record(tuple(outputs), interval, ticks)


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
_SERIES_PLOTS = ("time_series", "phase_portrait")


def _column_type(name: str, variables: dict) -> str | None:
    """The FMI type of a recorded column "instance.variable" (None: not a variable)."""
    split = split_ref(name, variables)
    return None if split is None or split[1] not in variables[split[0]] else variables[split[0]][split[1]].type


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
