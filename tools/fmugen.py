"""Generate a model's C variable table, modelDescription.xml, documentation and icon from model.toml.

Usage: python fmugen.py MODEL_DIR OUT_DIR [--sources a.c b.c ...] [--sources3 a.c ...]
                        [--fmi2-only] [--fmi1]

Writes OUT_DIR/cw_vars.h and, for the FMI 2.0 build, modelDescription.xml,
documentation/index.html and model.png (the last two by fmudoc.py); for the
FMI 3.0 build, OUT_DIR/fmi3/: modelDescription.xml, buildDescription.xml and
documentation/index.html (its icon is the same model.png); with --fmi1,
OUT_DIR/fmi1/modelDescription.xml for the FMI 1.0 Co-Simulation build
(test FMUs). CMakeLists.txt runs it for every model.

The TOML file is the single description of a model's variables; the C side
(value-reference enum and the metadata table the runtime checks against)
and both builds' modelDescription.xml come from it, so a new model gets both
builds. See docs/design.md for the table's keys.
"""

from __future__ import annotations

import argparse
import hashlib
import math
import re
import sys
import tomllib
import uuid
from pathlib import Path
from xml.sax.saxutils import escape as html_escape, quoteattr

import fmudoc
from fmudoc import number_text as _num

CAUSALITIES = {"parameter", "input", "output", "local"}
VARIABILITIES = {"fixed", "tunable", "discrete", "continuous"}
TYPES = {"Real", "Integer", "Boolean", "Enumeration", "String"}  # Enumeration: stored as an Integer
BASE_UNITS = ("kg", "m", "s", "A", "K", "mol", "cd", "rad")
VAR_KEYS = {
    "name", "vr", "type", "causality", "variability", "unit", "display_unit",
    "start", "min", "max", "depends_on", "initial_depends_on", "derivatives",
    "event_indicator", "description", "declared_type", "derivative_of",
}
# FMI 2.0 dependenciesKind values (Sec. 2.2.8). All but "dependent" describe a
# linear factor and so apply to Real unknowns only; InitialUnknowns use
# "dependent" alone.
DEPENDENCY_KINDS = {"dependent", "constant", "fixed", "tunable", "discrete"}
# depends_on = "undeclared": no dependencies attribute, which FMI 2.0 and 3.0
# read as "depends on every Known" (test FMUs that form formal loops).
UNDECLARED = "undeclared"
MODEL_KEYS = {
    "name", "description", "author", "version", "callbacks", "real_state",
    "uint_state", "interpolates_inputs", "max_input_order", "early_return", "output_clock", "variables_from",
}
# [model] output_clock (FMI 3.0 build only): a triggered output clock that
# ticks in Event Mode when the model's clock_ticks callback says so
# (docs/clocks.md).
OUTPUT_CLOCK_KEYS = {"name", "vr", "description", "depends_on"}
# The FMI 3.0 types of the table's types.
FMI3_TYPES = {"Real": "Float64", "Integer": "Int32", "Boolean": "Boolean"}
# FMI 3.0 needs one independent variable; it takes the value reference after
# the table's (CW_NVARS), which the runtime answers with the time.
TIME_NAME = "time"
MODELS_DIR = Path(__file__).resolve().parent.parent / "src_c" / "models"
# The cw_model callbacks (cw_runtime.h): field name -> (return type, parameters).
CALLBACKS = {
    "validate": ("fmi2Status", "cw_instance *inst"),
    "initialize": ("void", "cw_instance *inst"),
    "calc_outputs": ("void", "cw_instance *inst"),
    "do_step": ("fmi2Status", "cw_instance *inst, double t_end"),
    "commit": ("void", "cw_instance *inst"),
    "output_derivative": ("int", "cw_instance *inst, unsigned vr, int order, double *value"),
    "settle": ("void", "cw_instance *inst"),
    "clock_ticks": ("int", "cw_instance *inst"),
}
C_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


def c_name(name: str) -> str:
    """The C identifier of a variable: FMI names such as der(x) or a[1] made
    into der_x_, a_1_ (identifiers stay as they are)."""
    return re.sub(r"\W", "_", name)


def c_string(text: str) -> str:
    """A C string literal of text's UTF-8 bytes: printable ASCII as is, the
    rest as octal escapes (which, unlike hex ones, end after three digits)."""
    out = []
    for b in text.encode("utf-8"):
        ch = chr(b)
        out.append("\\" + ch if ch in '"\\' else ch if 32 <= b < 127 else f"\\{b:03o}")
    return '"' + "".join(out) + '"'


# The project's terms (LICENSE at the repository root), stated in every FMU.
COPYRIGHT = "Copyright (c) 2026 The clockwork authors"
LICENSE = "MIT"
DOC_KEYS = {"equations", "references", "example", "icon"}
C_TYPES = {"Real": "REAL", "Integer": "INTEGER", "Boolean": "BOOLEAN", "Enumeration": "INTEGER", "String": "STRING"}
GUID_NAMESPACE = uuid.UUID("5d1f7a0e-6c55-4c39-9a43-2f0b7f3c1c0e")


class TableError(ValueError):
    pass


MAX_COUNT = 100_000  # scalar variables one [[variable]] with count may stand for


def expand_counts(variables: list, path: Path) -> list:
    """A [[variable]] with ``count = n`` stands for n scalar variables
    name[1] .. name[n] (FMI 2.0's names of an array's elements) with the
    value references vr .. vr + n - 1 and otherwise its keys."""
    out = []
    for v in variables:
        n = v.get("count")
        if n is None:
            out.append(v)
            continue
        if isinstance(n, bool) or not isinstance(n, int) or not 1 <= n <= MAX_COUNT:
            raise TableError(f"{path}: variable {v.get('name', '?')!r}: count must be a whole number "
                             f"from 1 to {MAX_COUNT}")
        if not isinstance(v.get("vr"), int) or not isinstance(v.get("name"), str):
            raise TableError(f"{path}: variable {v.get('name', '?')!r}: count needs a name and a vr")
        base = {k: x for k, x in v.items() if k != "count"}
        out += [{**base, "name": f"{v['name']}[{i}]", "vr": v["vr"] + i - 1} for i in range(1, n + 1)]
    return out


def load(model_dir: Path) -> dict:
    path = model_dir / "model.toml"
    raw = path.read_bytes()
    try:
        table = tomllib.loads(raw.decode())
    except tomllib.TOMLDecodeError as e:
        raise TableError(f"{path}: {e}") from e
    base = table.get("model", {}).get("variables_from")
    if base is not None:
        # A variant of a bundled model (a test model): its variables and experiment.
        if not isinstance(base, str) or not C_NAME.fullmatch(base):
            raise TableError(f"{path}: [model] variables_from must name a model of src_c/models")
        base_path = MODELS_DIR / base / "model.toml"
        try:
            base_table = tomllib.loads(base_path.read_text())
        except (OSError, tomllib.TOMLDecodeError) as e:
            raise TableError(f"{path}: [model] variables_from = {base!r}: {e}") from e
        table["variable"] = base_table.get("variable", []) + table.get("variable", [])
        table.setdefault("experiment", base_table.get("experiment", {}))
    table["variable"] = expand_counts(table.get("variable", []), path)
    shared = model_dir.parent / "units.toml"
    units = tomllib.loads(shared.read_text()) if shared.exists() else {}
    if base is not None and (MODELS_DIR / "units.toml").exists():  # the bundled model's units
        units = {**tomllib.loads((MODELS_DIR / "units.toml").read_text()), **units}
    units.update(table.get("units", {}))
    used = {v.get("unit") for v in table.get("variable", [])} - {None}
    table["units"] = {k: u for k, u in units.items() if k in used}
    digest = hashlib.sha256(raw + repr(sorted(table["units"].items())).encode()).hexdigest()
    table["_guid"] = "{" + str(uuid.uuid5(GUID_NAMESPACE, digest)) + "}"
    table["_path"] = path
    table["_copyright"], table["_license"] = COPYRIGHT, LICENSE
    refs = model_dir.parent / "references.toml"
    table["_references"] = tomllib.loads(refs.read_text()) if refs.exists() else {}
    check(table)
    return table


def check(t: dict) -> None:
    path = t["_path"]
    model = t.get("model", {})
    for key in ("name", "description"):
        if key not in model:
            raise TableError(f"{path}: [model] needs '{key}'")
    unknown = set(model) - MODEL_KEYS
    if unknown:
        raise TableError(f"{path}: [model] has unknown keys {sorted(unknown)}")
    callbacks = model.get("callbacks", [])
    bad = [c for c in callbacks if c not in CALLBACKS]
    if bad or len(set(callbacks)) != len(callbacks):
        raise TableError(f"{path}: [model] callbacks must be distinct names from {sorted(CALLBACKS)}")
    slots = model.get("real_state", []) + model.get("uint_state", [])
    for s in slots:
        if not isinstance(s, str) or not C_NAME.fullmatch(s):
            raise TableError(f"{path}: state slot {s!r} is not a C identifier")
    if len(set(slots)) != len(slots):
        raise TableError(f"{path}: state slot names repeat")
    early = model.get("early_return", [])
    if not isinstance(early, list) or not all(isinstance(e, str) and e for e in early):
        raise TableError(f"{path}: [model] early_return must be a list of event names")
    check_model_c(t)
    check_output_clock(t)
    doc = t.get("documentation", {})
    unknown = set(doc) - DOC_KEYS
    if unknown:
        raise TableError(f"{path}: [documentation] has unknown keys {sorted(unknown)}")
    for key in doc.get("references", []):
        if key not in t["_references"]:
            raise TableError(f"{path}: reference {key!r} is not in references.toml")
    if doc.get("icon", "pendulum") not in fmudoc.ICONS:
        raise TableError(f"{path}: icon must be one of {sorted(fmudoc.ICONS)}")
    units = t.get("units", {})
    names, vrs = set(), set()
    variables = t.get("variable", [])
    for v in variables:
        where = f"{path}: variable {v.get('name', '?')!r}"
        unknown = set(v) - VAR_KEYS
        if unknown:
            raise TableError(f"{where}: unknown keys {sorted(unknown)}")
        for key in ("name", "vr", "type", "causality", "variability", "description"):
            if key not in v:
                raise TableError(f"{where}: missing '{key}'")
        if v["name"] in names:
            raise TableError(f"{where}: duplicate name")
        if v["name"] == TIME_NAME:
            raise TableError(f"{where}: '{TIME_NAME}' is the FMI 3.0 build's independent variable")
        if v["vr"] in vrs:
            raise TableError(f"{where}: duplicate value reference {v['vr']}")
        names.add(v["name"])
        vrs.add(v["vr"])
        if v["type"] not in TYPES:
            raise TableError(f"{where}: type must be one of {sorted(TYPES)}")
        if v["causality"] not in CAUSALITIES:
            raise TableError(f"{where}: causality must be one of {sorted(CAUSALITIES)}")
        if v["variability"] not in VARIABILITIES:
            raise TableError(f"{where}: variability must be one of {sorted(VARIABILITIES)}")
        if v["causality"] in ("parameter", "input") and "start" not in v:
            raise TableError(f"{where}: parameters and inputs need a start value")
        if "unit" in v and v["unit"] not in units:
            raise TableError(f"{where}: unit {v['unit']!r} is not declared in units.toml or [units]")
        if "display_unit" in v and v["display_unit"] not in units.get(v.get("unit"), {}).get("display", {}):
            raise TableError(f"{where}: display_unit {v['display_unit']!r} is not a display unit of {v.get('unit')!r}")
        if v["type"] == "String":
            if not isinstance(v.get("start", ""), str) or {"min", "max", "unit"} & set(v):
                raise TableError(f"{where}: a String takes a text start value and no min, max or unit")
        elif "start" in v and v["type"] != "Boolean":
            lo, hi = v.get("min", -math.inf), v.get("max", math.inf)
            if not lo <= v["start"] <= hi:
                raise TableError(f"{where}: start {v['start']} outside [{lo}, {hi}]")
        if (v["type"] == "Enumeration") != ("declared_type" in v):
            raise TableError(f"{where}: declared_type names the [types.<Name>] of an Enumeration, and only of one")
        if "declared_type" in v and not t.get("types", {}).get(v["declared_type"], {}).get("items"):
            raise TableError(f"{where}: declared_type {v['declared_type']!r} has no [types.<Name>] items")
        if "derivative_of" in v and not (v["type"] == "Real" and v["causality"] == "local"):
            raise TableError(f"{where}: derivative_of is for Real local variables (a state's derivative)")
    if len({c_name(v["name"]) for v in variables}) != len(variables):
        raise TableError(f"{path}: two variable names give the same C name")
    states = {v["derivative_of"] for v in variables if "derivative_of" in v}
    by_name = {v["name"]: v for v in variables}
    for x in states:
        if x not in by_name or by_name[x]["type"] != "Real" or by_name[x]["variability"] != "continuous":
            raise TableError(f"{path}: derivative_of {x!r} must name a continuous Real variable (the state)")
    inputs = {v["name"] for v in variables if v["causality"] == "input"}
    # Knowns in Initialization Mode: inputs and the variables with
    # initial="exact", which here are exactly the parameters.
    exact = inputs | {v["name"] for v in variables if v["causality"] == "parameter"}
    for v in variables:
        where = f"{path}: {v['name']}"
        for key in ("depends_on", "initial_depends_on"):
            if key in v and v["causality"] != "output" and "derivative_of" not in v:
                raise TableError(f"{where}: {key} is for outputs and state derivatives only")
        deps = v.get("depends_on", [])
        if deps == UNDECLARED:
            deps = []
        elif not isinstance(deps, (list, dict)):
            raise TableError(f"{where}: depends_on must be a list of inputs, a table input = kind "
                             f"or {UNDECLARED!r}")
        for dep in deps:
            # Knowns of an output at a communication point: inputs and states (FMI 2.0, 3.3.2).
            if dep not in inputs and dep not in states:
                raise TableError(f"{where} depends_on {dep!r}, which is neither an input nor a state")
        for dep, kind in (deps.items() if isinstance(deps, dict) else []):
            if kind not in DEPENDENCY_KINDS:
                raise TableError(f"{where}: dependency kind {kind!r} is not one of {sorted(DEPENDENCY_KINDS)}")
            if kind != "dependent" and v["type"] != "Real":
                raise TableError(f"{where}: dependency kind {kind!r} is for Real outputs only")
        for dep in v.get("initial_depends_on", []):
            if dep not in exact:
                raise TableError(
                    f"{where} initial_depends_on {dep!r}, which is neither an input nor a parameter"
                )


def check_output_clock(t: dict) -> None:
    """[model] output_clock: a name, a value reference above the table's
    (and the time's), the inputs it depends on; with the clock_ticks callback."""
    path, m = t["_path"], t["model"]
    clock = m.get("output_clock")
    has_callback = "clock_ticks" in m.get("callbacks", [])
    if clock is None:
        if has_callback:
            raise TableError(f"{path}: [model] callbacks has clock_ticks but there is no output_clock")
        return
    if not isinstance(clock, dict) or set(clock) - OUTPUT_CLOCK_KEYS or not {"name", "vr", "description"} <= set(clock):
        raise TableError(f"{path}: [model] output_clock must be a table with name, vr, description "
                         "(and depends_on)")
    if not has_callback:
        raise TableError(f"{path}: [model] output_clock needs the clock_ticks callback")
    vrs = [v["vr"] for v in t.get("variable", [])]
    if not isinstance(clock["vr"], int) or clock["vr"] <= max(vrs, default=-1) + 1:
        raise TableError(f"{path}: [model] output_clock vr must be above every variable's vr and the time's")
    names = {v["name"] for v in t.get("variable", [])}
    if clock["name"] in names:
        raise TableError(f"{path}: [model] output_clock name {clock['name']!r} is a variable's name")
    for d in clock.get("depends_on", []):
        if d not in names:
            raise TableError(f"{path}: [model] output_clock depends_on {d!r}: no such variable")


def check_model_c(t: dict) -> None:
    """model.c must define exactly the callbacks the table names: a missing
    one would be an undefined static function, an extra one dead code."""
    source = t["_path"].parent / "model.c"
    if not source.exists():
        return
    text = source.read_text()
    base = t["model"].get("variables_from")
    if base is not None and (MODELS_DIR / base / "model.c").exists():  # a variant includes the model's code
        text += (MODELS_DIR / base / "model.c").read_text()
    defined = {
        name for name in CALLBACKS
        if re.search(rf"^static\s[^;{{}}=]*\b{name}\s*\([^;]*?\)\s*\{{", text, re.M)
    }
    declared = set(t["model"].get("callbacks", []))
    if defined != declared:
        raise TableError(
            f"{t['_path']}: [model] callbacks = {sorted(declared)}, but {source.name} "
            f"defines {sorted(defined)}"
        )


def generate_model(t: dict) -> list[str]:
    """The model's cw_model, for model.c alone (guarded: the C test driver and
    the fuzz harness include cw_vars.h for the table only)."""
    m = t["model"]
    real, uint = m.get("real_state", []), m.get("uint_state", [])
    callbacks = m.get("callbacks", [])
    lines = ["#ifndef CW_VARS_TABLE_ONLY", ""]
    if real:
        lines += [f"enum cw_real_state_slot {{ {', '.join(real)}, CW_N_REAL_STATE }};"]
    if uint:
        lines += [f"enum cw_uint_state_slot {{ {', '.join(uint)}, CW_N_UINT_STATE }};"]
    if real or uint:
        lines.append("")
    lines.append("/* Defined in model.c. */")
    for name in CALLBACKS:
        if name in callbacks:
            ret, params = CALLBACKS[name]
            lines.append(f"static {ret} {name}({params});")
    lines += [
        "",
        "const cw_model CW_MODEL = {",
        "    .name = CW_MODEL_NAME,",
        "    .guid = CW_MODEL_GUID,",
        "    .nvars = CW_NVARS,",
        "    .vars = CW_VARS,",
        f"    .n_real_state = {'CW_N_REAL_STATE' if real else 0},",
        f"    .n_uint_state = {'CW_N_UINT_STATE' if uint else 0},",
    ]
    lines += [f"    .{name} = {name if name in callbacks else 'NULL'}," for name in CALLBACKS]
    if "max_input_order" in m:
        lines.append(f"    .max_input_order = {int(m['max_input_order'])},")
    if "output_clock" in m:
        lines.append(f"    .output_clock_vr = {int(m['output_clock']['vr'])},")
    lines += ["};", "", "#endif /* CW_VARS_TABLE_ONLY */", ""]
    return lines


def generate_header(t: dict) -> str:
    variables = sorted(t["variable"], key=lambda v: v["vr"])
    nvars = max(v["vr"] for v in variables) + 1
    lines = [
        "/* Generated by tools/fmugen.py from model.toml. Do not edit. */",
        "#ifndef CW_VARS_H",
        "#define CW_VARS_H",
        "#include <math.h>",
        '#include "cw_runtime.h"',
        "",
        f'#define CW_MODEL_NAME "{t["model"]["name"]}"',
        f'#define CW_MODEL_GUID "{t["_guid"]}"',
        f"#define CW_NVARS {nvars}",
        "",
        "enum cw_value_reference {",
    ]
    lines += [f"    VR_{c_name(v['name'])} = {v['vr']}," for v in variables]
    lines += ["};", "", "static const cw_var_info CW_VARS[CW_NVARS] = {"]
    for v in variables:
        def bound(key, default):
            return _num(v[key]) if key in v else default
        start = v.get("start", 0)
        text = ""
        if v["type"] == "String":
            start, text = 0, ", " + c_string(v.get("start", ""))
        if isinstance(start, bool):
            start = int(start)
        lines.append(
            f'    [{v["vr"]}] = {{"{v["name"]}", {v["vr"]}, CW_{C_TYPES[v["type"]]}, '
            f'CW_{v["causality"].upper()}, CW_{v["variability"].upper()}, '
            f'{_num(start)}, {bound("min", "-HUGE_VAL")}, {bound("max", "HUGE_VAL")}, '
            f'{int(v.get("derivatives", 0))}, {int(bool(v.get("event_indicator", False)))}{text}}},'
        )
    lines += [
        "};",
        "",
        "#define R(name) (inst->r[VR_##name])",
        "#define I(name) (inst->i[VR_##name])",
        "#define S(name) ((const char *)inst->str[VR_##name])",
        "#define IN(name, t) cw_input(inst, VR_##name, (t))",
        "",
    ]
    lines += generate_model(t)
    lines += [
        "#endif",
        "",
    ]
    return "\n".join(lines)


def _unit_xml(name: str, spec: dict) -> list[str]:
    base = " ".join(
        f'{k}="{_num(spec[k])}"' for k in BASE_UNITS + ("factor", "offset") if k in spec
    )
    out = [f"    <Unit name={quoteattr(name)}>", f"      <BaseUnit {base}/>" if base else "      <BaseUnit/>"]
    for dname, d in spec.get("display", {}).items():
        attrs = f'name={quoteattr(dname)} factor="{_num(d.get("factor", 1.0))}"'
        if "offset" in d:
            attrs += f' offset="{_num(d["offset"])}"'
        out.append(f"      <DisplayUnit {attrs}/>")
    out.append("    </Unit>")
    return out


def _about_attrs(m: dict) -> list[str]:
    """The <fmiModelDescription> attributes about the model, in FMI 2.0 and 3.0."""
    return [
        f"  description={quoteattr(m['description'])}",
        f"  author={quoteattr(m.get('author', 'clockwork'))}",
        f"  version={quoteattr(m.get('version', '0.1.0'))}",
        f"  copyright={quoteattr(COPYRIGHT)}",
        f"  license={quoteattr(LICENSE)}",
        '  generationTool="clockwork tools/fmugen.py"',
    ]


def _unit_definitions(units: dict) -> list[str]:
    """<UnitDefinitions>, the same in FMI 2.0 and 3.0 (none: no element)."""
    if not units:
        return []
    x = ["  <UnitDefinitions>"]
    for name, spec in units.items():
        x += _unit_xml(name, spec)
    return x + ["  </UnitDefinitions>"]


# The <LogCategories> of every model, in FMI 2.0 and 3.0.
_LOG_CATEGORIES = (
    "  <LogCategories>",
    '    <Category name="logEvents" description="Located crossings and mode switches"/>',
    '    <Category name="logStatusWarning"/>',
    '    <Category name="logStatusDiscard"/>',
    '    <Category name="logStatusError"/>',
    '    <Category name="logStatusFatal"/>',
    '    <Category name="logAll"/>',
    "  </LogCategories>",
)


def _default_experiment(exp: dict) -> str:
    """<DefaultExperiment> from the model table's [experiment], in FMI 2.0 and 3.0."""
    return (f'  <DefaultExperiment startTime="{_num(exp.get("start", 0.0))}" '
            f'stopTime="{_num(exp.get("stop", 10.0))}"'
            + (f' tolerance="{_num(exp["tolerance"])}"' if "tolerance" in exp else "")
            + f' stepSize="{_num(exp.get("step", 0.01))}"/>')


def _variable_attrs(v: dict) -> list[str]:
    """The attributes every variable has, in FMI 2.0's ScalarVariable and
    FMI 3.0's typed element alike."""
    attrs = [
        f"name={quoteattr(v['name'])}",
        f'valueReference="{v["vr"]}"',
        f"description={quoteattr(v['description'])}",
        f'causality="{v["causality"]}"',
        f'variability="{v["variability"]}"',
    ]
    if v["causality"] in ("output", "local"):
        attrs.append('initial="calculated"')
    return attrs


def _unit_and_range_attrs(v: dict) -> list[str]:
    """unit and displayUnit of a Real, min and max of a number (FMI 2.0 and 3.0)."""
    attrs = []
    if v["type"] == "Real":
        if "unit" in v:
            attrs.append(f"unit={quoteattr(v['unit'])}")
        if "display_unit" in v:
            attrs.append(f"displayUnit={quoteattr(v['display_unit'])}")
    if v["type"] not in ("Boolean", "String"):
        for key in ("min", "max"):
            if key in v:
                attrs.append(f'{key}="{_num(v[key])}"')
    return attrs


def _unknown_xml(index: dict, v: dict, kinds) -> str:
    """An <Unknown> with its dependencies in ScalarVariable index order, as
    FMI 2.0 requires (none given: UNDECLARED)."""
    if kinds == UNDECLARED:
        return f'      <Unknown index="{index[v["name"]]}"/>'
    deps = sorted((index[name], kind) for name, kind in kinds.items())
    if not deps:
        return f'      <Unknown index="{index[v["name"]]}" dependencies=""/>'
    return (
        f'      <Unknown index="{index[v["name"]]}" '
        f'dependencies="{" ".join(str(k) for k, _ in deps)}" '
        f'dependenciesKind="{" ".join(kind for _, kind in deps)}"/>'
    )


def _capabilities(indicators: list[str]) -> list[str]:
    """The one element of clockwork's FMI 2.0 Tool (FMI 3.0 Annotation):
    the schemas allow one. The runtime (src_c/runtime) computes outputs on
    every get from the inputs last set, so every FMU it builds declares
    that its outputs may be read after its inputs are set without a step
    between, what FMI 2.0 (4.2.4) and FMI 3.0's Step Mode do not allow an
    importer by default (docs/master.md, "The call sequence"); the event
    indicators, where there are any, are listed inside it."""
    if not indicators:
        return ['      <Capabilities outputsAfterInputs="true"/>']
    return ['      <Capabilities outputsAfterInputs="true">', "        <EventIndicators>",
            *[f"          <Indicator name={quoteattr(n)}/>" for n in indicators],
            "        </EventIndicators>", "      </Capabilities>"]


def generate_xml(t: dict, sources: list[str]) -> str:
    m = t["model"]
    variables = sorted(t["variable"], key=lambda v: v["vr"])
    index = {v["name"]: k + 1 for k, v in enumerate(variables)}
    max_order = max([int(v.get("derivatives", 0)) for v in variables] + [0])
    has_inputs = any(v["causality"] == "input" for v in variables)
    exp = t.get("experiment", {})
    x = [
        '<?xml version="1.0" encoding="UTF-8"?>',
        "<fmiModelDescription",
        '  fmiVersion="2.0"',
        f"  modelName={quoteattr(m['name'])}",
        f'  guid="{t["_guid"]}"',
        *_about_attrs(m),
        '  variableNamingConvention="structured"',
        '  numberOfEventIndicators="0">',
        "  <CoSimulation",
        f"    modelIdentifier={quoteattr(m['name'])}",
        '    needsExecutionTool="false"',
        '    canHandleVariableCommunicationStepSize="true"',
        f'    canInterpolateInputs="{"true" if m.get("interpolates_inputs", has_inputs) else "false"}"',
        f'    maxOutputDerivativeOrder="{max_order}"',
        '    canRunAsynchronuously="false"',
        '    canBeInstantiatedOnlyOncePerProcess="false"',
        '    canNotUseMemoryManagementFunctions="false"',
        '    canGetAndSetFMUstate="true"',
        '    canSerializeFMUstate="true"',
        '    providesDirectionalDerivative="false">',
    ]
    if sources:
        x.append("    <SourceFiles>")
        x += [f"      <File name={quoteattr(s)}/>" for s in sources]
        x.append("    </SourceFiles>")
    x.append("  </CoSimulation>")
    x += _unit_definitions(t.get("units", {}))
    used_types = sorted({v["declared_type"] for v in variables if "declared_type" in v})
    if used_types:
        x.append("  <TypeDefinitions>")
        for name in used_types:
            x += [f"    <SimpleType name={quoteattr(name)}>", "      <Enumeration>"]
            x += [f"        <Item name={quoteattr(item)} value=\"{k + 1}\"/>"
                  for k, item in enumerate(t["types"][name]["items"])]
            x += ["      </Enumeration>", "    </SimpleType>"]
        x.append("  </TypeDefinitions>")
    x += [
        *_LOG_CATEGORIES,
        _default_experiment(exp),
    ]
    indicators = [v["name"] for v in variables if v.get("event_indicator")]
    x += ["  <VendorAnnotations>", '    <Tool name="clockwork">', *_capabilities(indicators), "    </Tool>",
          "  </VendorAnnotations>"]
    x.append("  <ModelVariables>")
    for k, v in enumerate(variables):
        x.append(f"    <!-- index {k + 1} -->")
        x.append(f"    <ScalarVariable {' '.join(_variable_attrs(v))}>")
        tattrs = []
        if "declared_type" in v:
            tattrs.append(f"declaredType={quoteattr(v['declared_type'])}")
        if "derivative_of" in v:
            tattrs.append(f'derivative="{index[v["derivative_of"]]}"')
        tattrs += _unit_and_range_attrs(v)
        if v["causality"] in ("parameter", "input"):
            start = v["start"]
            tattrs.append(f"start={quoteattr(start)}" if v["type"] == "String" else f'start="{_num(start)}"')
        x.append(f"      <{v['type']} {' '.join(tattrs)}/>".replace("  />", " />"))
        x.append("    </ScalarVariable>")
    x.append("  </ModelVariables>")
    x.append("  <ModelStructure>")
    outputs = [v for v in variables if v["causality"] == "output"]
    derivatives = [v for v in variables if "derivative_of" in v]
    states = {v["derivative_of"] for v in derivatives}
    if outputs:
        # Outputs at communication points: the Knowns are the inputs (the
        # state is the FMU's own, or a declared state). Initialization Mode:
        # inputs and parameters, e.g. a state output depends on its start
        # parameter but on no input, so it closes no algebraic loop.
        x.append("    <Outputs>")
        for v in outputs:
            deps = v.get("depends_on", [])
            kinds = deps if isinstance(deps, dict) or deps == UNDECLARED else dict.fromkeys(deps, "dependent")
            x.append(_unknown_xml(index, v, kinds))
        x.append("    </Outputs>")
    if derivatives:
        x.append("    <Derivatives>")
        for v in derivatives:
            deps = v.get("depends_on", [])
            x.append(_unknown_xml(index, v, deps if isinstance(deps, dict) else dict.fromkeys(deps, "dependent")))
        x.append("    </Derivatives>")
    # Declared states and their derivatives are initial unknowns too (FMI 2.0, 3.3.2).
    initial = [v for v in variables if v["causality"] == "output" or "derivative_of" in v or v["name"] in states]
    if initial:
        x.append("    <InitialUnknowns>")
        for v in initial:
            if "initial_depends_on" in v:
                x.append(_unknown_xml(index, v, dict.fromkeys(v["initial_depends_on"], "dependent")))
            else:  # undeclared: depends on every Known
                x.append(f'      <Unknown index="{index[v["name"]]}"/>')
        x.append("    </InitialUnknowns>")
    x.append("  </ModelStructure>")
    x.append("</fmiModelDescription>")
    return "\n".join(x) + "\n"


def _dependencies3(kinds, vr_of: dict) -> str:
    """dependencies (value references, ascending) and dependenciesKind
    attributes of an FMI 3.0 unknown (none given: UNDECLARED)."""
    if kinds == UNDECLARED:
        return ""
    deps = sorted((vr_of[name], kind) for name, kind in kinds.items())
    if not deps:
        return 'dependencies=""'
    return (f'dependencies="{" ".join(str(r) for r, _ in deps)}" '
            f'dependenciesKind="{" ".join(kind for _, kind in deps)}"')


def generate_xml3(t: dict) -> str:
    """The FMI 3.0 modelDescription.xml: the same variables, units and
    dependencies as the FMI 2.0 one, in FMI 3.0's terms (typed variables,
    value references in ModelStructure, the independent variable time)."""
    m = t["model"]
    variables = sorted(t["variable"], key=lambda v: v["vr"])
    for v in variables:
        # The fmi3 face has no fmi3Get/SetInt64 (FMI 3.0's access to an
        # Enumeration) and a Co-Simulation FMU exposes no continuous states.
        if v["type"] == "String":
            raise TableError(f"{m['name']}: variable {v['name']!r}: the FMI 3.0 build takes no String "
                             "variables (fmi3Get/SetString not provided); build this model as FMI 2.0 only")
        if v["type"] == "Enumeration":
            raise TableError(f"{m['name']}: variable {v['name']!r}: the FMI 3.0 build takes no Enumeration "
                             "variables (fmi3Get/SetInt64 not provided); build this model as FMI 2.0 only")
        if "derivative_of" in v:
            raise TableError(f"{m['name']}: variable {v['name']!r}: the FMI 3.0 build takes no declared states "
                             "(derivative_of); build this model as FMI 2.0 only")
    vr_of = {v["name"]: v["vr"] for v in variables}
    time_vr = max(vr_of.values()) + 1  # CW_NVARS
    max_order = max([int(v.get("derivatives", 0)) for v in variables] + [0])
    early = bool(m.get("early_return"))
    # Float64 inputs are read by the model inside fmi3DoStep (its RK stages):
    # it calls the importer's intermediate update there, where the importer
    # sets them to the values of its input polynomials (what FMI 2.0 passes
    # with fmi2SetRealInputDerivatives, whose orders reach 2).
    intermediate = any(v["causality"] == "input" and v["type"] == "Real" for v in variables)
    exp = t.get("experiment", {})
    x = [
        '<?xml version="1.0" encoding="UTF-8"?>',
        "<fmiModelDescription",
        '  fmiVersion="3.0"',
        f"  modelName={quoteattr(m['name'])}",
        f'  instantiationToken="{t["_guid"]}"',
        *_about_attrs(m),
        '  variableNamingConvention="structured">',
        "  <CoSimulation",
        f"    modelIdentifier={quoteattr(m['name'])}",
        '    needsExecutionTool="false"',
        '    canBeInstantiatedOnlyOncePerProcess="false"',
        '    canGetAndSetFMUState="true"',
        '    canSerializeFMUState="true"',
        '    providesDirectionalDerivatives="false"',
        '    providesAdjointDerivatives="false"',
        '    providesPerElementDependencies="false"',
        '    canHandleVariableCommunicationStepSize="true"',
        f'    maxOutputDerivativeOrder="{max_order}"',
        f'    providesIntermediateUpdate="{"true" if intermediate else "false"}"',
        *(['    recommendedIntermediateInputSmoothness="2"'] if intermediate else []),
        f'    mightReturnEarlyFromDoStep="{"true" if early else "false"}"',
        '    canReturnEarlyAfterIntermediateUpdate="false"',
        '    hasEventMode="true"',
        '    providesEvaluateDiscreteStates="false"/>',
    ]
    units = t.get("units", {})
    x += _unit_definitions(units)
    time_unit = ' unit="s"' if "s" in units else ""  # only a declared unit may be named
    x += [
        *_LOG_CATEGORIES,
        _default_experiment(exp),
        "  <ModelVariables>",
        f'    <Float64 name="{TIME_NAME}" valueReference="{time_vr}" causality="independent" '
        f'variability="continuous"{time_unit} description="Simulation time"/>',
    ]
    for v in variables:
        attrs = _variable_attrs(v)
        if v["causality"] == "input" and v["type"] == "Real":
            attrs.append('intermediateUpdate="true"')
        attrs += _unit_and_range_attrs(v)
        if v["causality"] in ("parameter", "input"):
            start = v["start"]
            if v["type"] == "Boolean":
                start = bool(start)
            attrs.append(f'start="{_num(start)}"')
        x.append(f"    <{FMI3_TYPES[v['type']]} {' '.join(attrs)}/>")
    clock = m.get("output_clock")
    if clock is not None:
        x.append(f'    <Clock name={quoteattr(clock["name"])} valueReference="{clock["vr"]}" causality="output" '
                 f'intervalVariability="triggered" description={quoteattr(clock["description"])}/>')
    x.append("  </ModelVariables>")
    x.append("  <ModelStructure>")
    outputs = [v for v in variables if v["causality"] == "output"]
    # The same rules as the FMI 2.0 ModelStructure (see generate_xml); a
    # Co-Simulation FMU exposes no continuous states, so there are no
    # ContinuousStateDerivative elements, and its event indicators are
    # outputs the importer watches (Model Exchange's EventIndicator
    # elements do not apply): they are listed in the annotation below.
    for v in outputs:
        deps = v.get("depends_on", [])
        kinds = deps if isinstance(deps, dict) or deps == UNDECLARED else dict.fromkeys(deps, "dependent")
        x.append(f'    <Output valueReference="{v["vr"]}" {_dependencies3(kinds, vr_of)}'.rstrip() + "/>")
    if clock is not None:
        deps = _dependencies3(dict.fromkeys(clock.get("depends_on", []), "dependent"), vr_of)
        x.append(f'    <Output valueReference="{clock["vr"]}" {deps}'.rstrip() + "/>")
    for v in outputs:
        if "initial_depends_on" in v:
            deps = _dependencies3(dict.fromkeys(v["initial_depends_on"], "dependent"), vr_of)
            x.append(f'    <InitialUnknown valueReference="{v["vr"]}" {deps}/>')
        else:  # undeclared: depends on every Known
            x.append(f'    <InitialUnknown valueReference="{v["vr"]}"/>')
    if clock is not None:  # an output, initial="calculated" by default: an initial unknown (fmpy validate)
        x.append(f'    <InitialUnknown valueReference="{clock["vr"]}" {deps}'.rstrip() + "/>")
    x.append("  </ModelStructure>")
    indicators = [v["name"] for v in variables if v.get("event_indicator")]
    x += ["  <Annotations>", '    <Annotation type="clockwork">', *_capabilities(indicators), "    </Annotation>",
          "  </Annotations>"]
    x.append("</fmiModelDescription>")
    return "\n".join(x) + "\n"


# FMI 1.0's variability of the table's parameters (its parameters are fixed
# after fmiInitializeSlave) and causality of its locals.
FMI1_VARIABILITY = {"fixed": "parameter", "tunable": "parameter", "discrete": "discrete",
                    "continuous": "continuous"}
FMI1_CAUSALITY = {"parameter": "internal", "input": "input", "output": "output", "local": "internal"}


def _unit_definitions1(units: dict) -> list[str]:
    """FMI 1.0's <UnitDefinitions>: units by name with their display units
    (gain and offset), without FMI 2.0's base-unit exponents."""
    if not units:
        return []
    x = ["  <UnitDefinitions>"]
    for name, spec in units.items():
        display = spec.get("display", {})
        if not display:
            x.append(f"    <BaseUnit unit={quoteattr(name)}/>")
            continue
        x.append(f"    <BaseUnit unit={quoteattr(name)}>")
        for dname, d in display.items():
            x.append(f"      <DisplayUnitDefinition displayUnit={quoteattr(dname)} "
                     f'gain="{_num(d.get("factor", 1.0))}" offset="{_num(d.get("offset", 0.0))}"/>')
        x.append("    </BaseUnit>")
    return x + ["  </UnitDefinitions>"]


def generate_xml1(t: dict) -> str:
    """The FMI 1.0 Co-Simulation modelDescription.xml (the runtime's fmi1
    face, cw_fmi1.c): the same variables in FMI 1.0's terms. Parameters have
    variability "parameter"; an output's DirectDependency lists the inputs
    it depends on (its states are not inputs); there is no FMU state, no
    tolerance and no log categories; event indicators are named in the
    clockwork VendorAnnotation's Annotation elements. An output whose
    dependencies are undeclared has no DirectDependency: it depends on
    every input."""
    m = t["model"]
    variables = sorted(t["variable"], key=lambda v: v["vr"])
    inputs = {v["name"] for v in variables if v["causality"] == "input"}
    max_order = max([int(v.get("derivatives", 0)) for v in variables] + [0])
    has_inputs = bool(inputs)
    exp = t.get("experiment", {})
    about = [a for a in _about_attrs(m) if not a.lstrip().startswith(("copyright=", "license="))]
    x = [
        '<?xml version="1.0" encoding="UTF-8"?>',
        "<fmiModelDescription",
        '  fmiVersion="1.0"',
        f"  modelName={quoteattr(m['name'])}",
        f"  modelIdentifier={quoteattr(m['name'])}",
        f'  guid="{t["_guid"]}"',
        *about,
        '  variableNamingConvention="structured"',
        '  numberOfContinuousStates="0"',
        '  numberOfEventIndicators="0">',
    ]
    x += _unit_definitions1(t.get("units", {}))
    used_types = sorted({v["declared_type"] for v in variables if "declared_type" in v})
    if used_types:
        x.append("  <TypeDefinitions>")
        for name in used_types:
            x += [f"    <Type name={quoteattr(name)}>", "      <EnumerationType>"]
            x += [f"        <Item name={quoteattr(item)}/>" for item in t["types"][name]["items"]]
            x += ["      </EnumerationType>", "    </Type>"]
        x.append("  </TypeDefinitions>")
    x.append(f'  <DefaultExperiment startTime="{_num(exp.get("start", 0.0))}" '
             f'stopTime="{_num(exp.get("stop", 10.0))}"'
             + (f' tolerance="{_num(exp["tolerance"])}"' if "tolerance" in exp else "") + "/>")
    indicators = [v["name"] for v in variables if v.get("event_indicator")]
    x += ["  <VendorAnnotations>", '    <Tool name="clockwork">',
          '      <Annotation name="outputsAfterInputs" value="true"/>']
    x += [f'      <Annotation name="eventIndicator" value={quoteattr(n)}/>' for n in indicators]
    x += ["    </Tool>", "  </VendorAnnotations>"]
    x.append("  <ModelVariables>")
    for v in variables:
        attrs = [f"name={quoteattr(v['name'])}", f'valueReference="{v["vr"]}"',
                 f"description={quoteattr(v['description'])}",
                 f'variability="{FMI1_VARIABILITY[v["variability"]]}"',
                 f'causality="{FMI1_CAUSALITY[v["causality"]]}"']
        tattrs = []
        if "declared_type" in v:
            tattrs.append(f"declaredType={quoteattr(v['declared_type'])}")
        tattrs += _unit_and_range_attrs(v)
        if v["causality"] in ("parameter", "input"):
            start = v["start"]
            if v["type"] == "String":
                tattrs.append(f"start={quoteattr(start)}")
            elif v["type"] == "Boolean":
                tattrs.append(f'start="{"true" if start else "false"}"')
            else:
                tattrs.append(f'start="{_num(start)}"')
            tattrs.append('fixed="true"')
        element = f"      <{v['type']} {' '.join(tattrs)}/>".replace("  />", " />").replace(" />", "/>")
        x.append(f"    <ScalarVariable {' '.join(attrs)}>")
        x.append(element)
        if v["causality"] == "output" and v.get("depends_on") != UNDECLARED:  # none: every input
            deps = [d for d in v.get("depends_on", []) if d in inputs]
            if deps:
                x.append("      <DirectDependency>")
                x += [f"        <Name>{html_escape(d)}</Name>" for d in sorted(deps)]
                x.append("      </DirectDependency>")
            else:
                x.append("      <DirectDependency/>")
        x.append("    </ScalarVariable>")
    x.append("  </ModelVariables>")
    x += [
        "  <Implementation>",
        "    <CoSimulation_StandAlone>",
        "      <Capabilities",
        '        canHandleVariableCommunicationStepSize="true"',
        '        canHandleEvents="true"',
        '        canRejectSteps="false"',
        f'        canInterpolateInputs="{"true" if m.get("interpolates_inputs", has_inputs) else "false"}"',
        f'        maxOutputDerivativeOrder="{max_order}"',
        '        canRunAsynchronuously="false"',
        '        canSignalEvents="false"',
        '        canBeInstantiatedOnlyOncePerProcess="false"',
        '        canNotUseMemoryManagementFunctions="false"/>',
        "    </CoSimulation_StandAlone>",
        "  </Implementation>",
        "</fmiModelDescription>",
    ]
    return "\n".join(x) + "\n"


def generate_build_description(t: dict, sources: list[str]) -> str:
    """sources/buildDescription.xml of the FMI 3.0 build (FMI 3.0 Sec. 2.5)."""
    x = [
        '<?xml version="1.0" encoding="UTF-8"?>',
        '<fmiBuildDescription fmiVersion="3.0">',
        f"  <BuildConfiguration modelIdentifier={quoteattr(t['model']['name'])}>",
        '    <SourceFileSet language="C99">',
    ]
    x += [f"      <SourceFile name={quoteattr(s)}/>" for s in sources]
    x += ["    </SourceFileSet>", "  </BuildConfiguration>", "</fmiBuildDescription>"]
    return "\n".join(x) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("model_dir", type=Path)
    ap.add_argument("out_dir", type=Path)
    ap.add_argument("--sources", nargs="*", default=[], help="the FMI 2.0 build's C sources")
    ap.add_argument("--sources3", nargs="*", default=None,
                    help="the FMI 3.0 build's C sources (default: --sources with cw_fmi3.c for cw_fmi2.c)")
    ap.add_argument("--fmi2-only", action="store_true",
                    help="write no FMI 3.0 files (e.g. a test model whose C code calls FMI 2.0's logger)")
    ap.add_argument("--fmi1", action="store_true",
                    help="also write the FMI 1.0 Co-Simulation build's fmi1/modelDescription.xml (test FMUs)")
    ap.add_argument("--platforms2", nargs="+", default=["linux64"],
                    help="the binaries folders of the FMI 2.0 build, for its documentation")
    ap.add_argument("--platforms3", nargs="+", default=["x86_64-linux"],
                    help="the binaries folders of the FMI 3.0 build, for its documentation")
    a = ap.parse_args(argv)
    sources3 = a.sources3 if a.sources3 is not None else [
        "cw_fmi3.c" if s == "cw_fmi2.c" else s for s in a.sources]
    try:
        t = load(a.model_dir)
        files = [
            ("cw_vars.h", generate_header(t)),
            ("modelDescription.xml", generate_xml(t, a.sources)),
            ("documentation/index.html", fmudoc.generate_html(t, t["_references"], platforms=a.platforms2)),
            ("model.png", fmudoc.generate_png(t.get("documentation", {}).get("icon", "pendulum"))),
        ]
        if not a.fmi2_only:
            t3 = fmudoc.fmi3_prose(t)
            files += [
                ("fmi3/modelDescription.xml", generate_xml3(t3)),
                ("fmi3/buildDescription.xml", generate_build_description(t3, sources3)),
                ("fmi3/documentation/index.html", fmudoc.generate_html(t3, t["_references"], fmi_version=3,
                                                                          platforms=a.platforms3)),
            ]
        if a.fmi1:
            files.append(("fmi1/modelDescription.xml", generate_xml1(t)))
    except TableError as e:
        print(f"fmugen: {e}", file=sys.stderr)
        return 2
    for name, data in files:
        (a.out_dir / name).parent.mkdir(parents=True, exist_ok=True)
        data = data.encode() if isinstance(data, str) else data
        target = a.out_dir / name
        # Rewrite only on change so that the build stays incremental.
        if not target.exists() or target.read_bytes() != data:
            target.write_bytes(data)
    return 0


if __name__ == "__main__":
    sys.exit(main())
