"""`clockwork export-fmu`: a scene as one FMI 2.0 Co-Simulation FMU that
carries the scene's FMUs and clockwork's compiled master, with no Python.

The FMU's binary is the system front (src_c/export/cw_system.c with the
compiled core, built once by CMake as lib/cw_system.so); what makes it this
scene is its resources: the scene's FMUs unpacked under resources/fmus/,
and resources/clockwork/system.txt, which describes them and the master's
structs to the front. That description is taken from the master the scene
builds here (engine/compiled.py), after initialization, so that the front
fills the core's structs as Python does: the same orders, value references,
links, indicators and settings, field by field by name.

Its variables: the scene's parameters (``pendulum.Q``, fixed parameters
with the FMUs' units and descriptions), the recorded Real outputs (every
Real output of every FMU when the scene records none), and the Real inputs
no connection feeds. What the front cannot carry is refused here, in one
line: a sweep or an analysis that is not a time series, an FMU without a
binary for the target platform, FMI 1.0 or 3.0 FMUs, Model Exchange, input
files, algebraic loops, links that are not Real, step doubling.
"""

from __future__ import annotations

import dataclasses
import hashlib
import io
import os
import re
import zipfile
from ctypes import c_double, c_int, c_uint
from pathlib import Path
from xml.sax.saxutils import quoteattr

from ..analyses.context import master_settings, parameters
from ..atomic import write_bytes_unnamed
from ..engine.compiled import CompiledMaster
from ..engine.system import System
from ..errors import SceneError, UsageError
from ..fmi.archive import extract
from ..fmi.description import var_unit
from ..fmi.description import variables as variables_of
from ..paths import core_library
from ..results.files import check_output_file
from ..version import __version__
from .catalog import load_scene

DESCRIPTION = "clockwork/system.txt"  # CW_DESCRIPTION in cw_system.c
FORMAT = 1                            # CW_FORMAT
PLATFORM, SUFFIX = "linux64", ".so"   # the binary the front is built for here
PLATFORM3 = "x86_64-linux"            # its FMI 3.0 name
HISTORY = 3                           # HISTORY in cw_master.c
MAX_SINCE = 256

# The port's and the master's arrays as engine/compiled.py makes them:
# (field, kind, length). A length is a field name, a product "2*n_in", or
# a number; "z" after the kind: a work array of zeros.
_PORT_ARRAYS = [
    ("out_vr", "u", "n_out"), ("in_vr", "u", "n_in"), ("inp", "dz", "n_in"),
    ("der_vr", "u", "2*n_in"), ("der_order", "i", "2*n_in"), ("der", "dz", "2*n_in"),
    ("src_port", "i", "n_in"), ("src_pos", "i", "n_in"), ("sent", "dz", "n_in"),
    ("dsrc_port", "i", "n_in"), ("dsrc_vr", "u", "2*n_in"), ("dsrc_m", "i", "n_in"),
    ("hist_t", "dz", HISTORY + 1), ("hist_v", "dz", f"{HISTORY + 1}*n_in"),
    ("snap_hist_t", "dz", HISTORY + 1), ("snap_hist_v", "dz", f"{HISTORY + 1}*n_in"),
    ("scaled", "i", "n_scaled"), ("in_factor", "d", "n_scaled"), ("in_offset", "d", "n_scaled"),
    ("it_start", "dz", "n_in"), ("it_end", "dz", "n_in"),
]
_PORT_SCALARS = [("n_out", "i"), ("n_in", "i"), ("n_z", "i"), ("max_output_derivative_order", "i"),
                 ("n_scaled", "i"), ("ext_order", "i"), ("can_interpolate", "i")]
_MASTER_ARRAYS = [
    ("first", "i", "n_first"), ("dynamic", "i", "n_dynamic"), ("first_in_order", "i", "n_first_in_order"),
    ("final_order", "i", "n_final"), ("after_start", "i", "n_dynamic+1"), ("after_order", "i", "after"),
    ("z_port", "i", "n_z"), ("z_pos", "i", "n_z"), ("zs_port", "i", "n_z"), ("zs_pos", "i", "n_z"),
    ("zs_vr", "u", "n_z"),
] + [(n, "dz", "n_z") for n in ("z_start", "z_end", "prev_u", "prev_du", "amp_u", "amp_du", "z_seen", "end_rate",
                               "snap_z_end", "last_z")] + [
    ("prev_kind", "iz", "n_z"), ("end_rate_set", "iz", "n_z"), ("pred_kind", "iz", "2*n_z"),
    ("pred_u", "dz", "2*n_z"), ("pred_du", "dz", "2*n_z"), ("pred_ddu", "dz", "2*n_z"),
    ("since", "dz", MAX_SINCE), ("fmi3", "pz", 0),
]
_MASTER_SCALARS = [
    ("start_time", "d"), ("step", "d"), ("event_time_tolerance", "d"), ("event_indicator_tolerance", "d"),
    ("divergence_limit", "d"), ("iteration_tolerance", "d"),
    ("n_ports", "i"), ("n_first", "i"), ("n_dynamic", "i"), ("n_first_in_order", "i"), ("n_final", "i"),
    ("n_z", "i"), ("cap_since", "i"), ("jacobi", "i"), ("extrapolation", "i"), ("locating", "i"),
    ("has_sources", "i"), ("after_event", "i"), ("max_replay_steps", "i"), ("predicting", "i"),
    ("iterations", "i"), ("n_fmi3", "i"),
]
_CTYPES = {"d": c_double, "i": c_int, "u": c_uint}


def system_library(suffix: str = SUFFIX) -> Path:
    """The front's binary, beside the compiled core (lib/, or the package's
    data); `suffix` ".dll": its Windows build, where it was made."""
    return core_library().parent / f"cw_system{suffix}"


def _length(spec, struct) -> int:
    if isinstance(spec, int):
        return spec
    if spec == "after":
        return -1  # filled by the caller
    total = 0
    for term in spec.split("+"):
        factor = 1
        for part in term.split("*"):
            factor *= int(part) if part.isdigit() else getattr(struct, part)
        total += factor
    return total


def _text(s: str) -> str:
    """A token without whitespace: percent-encoded (cw_system.c's text_token)."""
    return "".join(c if c.isascii() and (c.isalnum() or c in "-_./:{}") else
                   "".join(f"%{b:02X}" for b in c.encode("utf-8")) for c in s)


def _number(kind: str, x) -> str:
    return float(x).hex() if kind == "d" else str(int(x))


def _struct_lines(struct, arrays, scalars, after_n: int | None = None) -> list[str]:
    lines = []
    for name, kind, spec in arrays:
        n = _length(spec, struct) if spec != "after" else after_n
        base = kind[0]
        if kind.endswith("z") or n == 0:
            lines.append(f"a {name} {base} {n} z")
            continue
        address = getattr(struct, name)
        values = (_CTYPES[base] * n).from_address(address)
        lines.append(f"a {name} {base} {n} " + " ".join(_number(base, x) for x in values))
    for name, kind in scalars:
        lines.append(f"s {name} {kind} {_number(kind, getattr(struct, name))}")
    return lines


def _identifier(stem: str) -> str:
    ident = re.sub(r"\W", "_", stem, flags=re.ASCII) or "system"
    return ident if ident[0].isalpha() else f"m_{ident}"


def _refuse(scene, key: str, what: str):
    return SceneError(f"{scene.path}: {key}: {what}")


def _check_scene(scene, settings, fmi: int) -> None:
    kind = (scene.analysis or {}).get("kind", "time_series")
    if scene.sweep is not None:
        raise _refuse(scene, "sweep", "a scene with a sweep is many runs; an exported FMU is one time series "
                      "(export a copy without [sweep], or --set its values)")
    if kind != "time_series":
        raise _refuse(scene, "analysis.kind", f"expected time_series (an exported FMU is one time series), "
                      f"got {kind!r}")
    if scene.inputs is not None:
        raise _refuse(scene, "inputs", "an input file cannot be carried: the exported FMU's open inputs take it")
    if settings.richardson:
        raise _refuse(scene, "master.richardson", "the compiled master does not do step doubling")
    own = [n for n, c in scene.components.items() if c.step is not None and c.step != settings.step]
    if own:  # the front's file carries no rates (cw_rates): it would step every component at master.step
        raise _refuse(scene, f"components.{own[0]}.step", "expected every component at master.step: the exported "
                      "FMU's front does not carry components at their own steps")
    for name, c in scene.components.items():
        md = c.model_description
        if not md.fmiVersion.startswith("2"):
            raise _refuse(scene, f"components.{name}.fmu",
                          f"{c.fmu_path.name} is FMI {md.fmiVersion}: the exported FMU carries FMI 2.0 FMUs only")
        if c.interface == "model-exchange" or md.coSimulation is None:
            raise _refuse(scene, f"components.{name}.fmu",
                          f"{c.fmu_path.name}: the exported FMU carries Co-Simulation FMUs only")


def _unit_xml(md_list, units: set[str]) -> str:
    found = {}
    for md in md_list:
        for u in getattr(md, "unitDefinitions", None) or []:
            found.setdefault(u.name, u)
    out = []
    for name in sorted(units):
        u = found.get(name)
        base = getattr(u, "baseUnit", None) if u is not None else None
        attrs = ""
        if base is not None:
            for a in ("kg", "m", "s", "A", "K", "mol", "cd", "rad"):
                v = getattr(base, a, 0)
                if v:
                    attrs += f' {a}="{int(v)}"'
            for a in ("factor", "offset"):
                v = getattr(base, a, None)
                if v is not None and float(v) != (1.0 if a == "factor" else 0.0):
                    attrs += f' {a}="{float(v)!r}"'
        out.append(f'    <Unit name={quoteattr(name)}>' + (f"<BaseUnit{attrs}/>" if attrs else "") + "</Unit>")
    return "  <UnitDefinitions>\n" + "\n".join(out) + "\n  </UnitDefinitions>\n" if out else ""


@dataclasses.dataclass
class _Variable:
    name: str
    vr: int
    type: str  # Real, Integer, Boolean (FMI 2.0's names)
    causality: str
    variability: str
    initial: str | None
    description: str | None
    unit: str | None
    start: str | None  # as written


_FMI3_TYPES = {"Real": "Float64", "Integer": "Int32", "Boolean": "Boolean"}


def _model_description(fmi: int, ident: str, guid: str, title: str, state: str, units: str, start: float,
                       stop: float, step: float, variables: list[_Variable]) -> str:
    """The exported FMU's modelDescription.xml, FMI 2.0 or 3.0."""
    def attrs(v: _Variable) -> str:
        out = f' unit={quoteattr(v.unit)}' if v.unit else ""
        return out + (f' start="{v.start}"' if v.start is not None else "")

    def head(v: _Variable) -> str:
        return (f'name={quoteattr(v.name)} valueReference="{v.vr}" causality="{v.causality}" '
                f'variability="{v.variability}"' + (f' initial="{v.initial}"' if v.initial else "")
                + (f" description={quoteattr(v.description)}" if v.description else ""))

    outputs = [(k + 1, v) for k, v in enumerate(variables) if v.causality == "output"]
    experiment = (f'  <DefaultExperiment startTime="{float(start)!r}" stopTime="{float(stop)!r}"'
                  f' stepSize="{float(step)!r}"/>\n')
    tool = f'generationTool="clockwork {__version__} export-fmu"'
    if fmi == 2:
        body = "\n".join(f"    <ScalarVariable {head(v)}>\n      <{v.type}{attrs(v)}/>\n    </ScalarVariable>"
                         for v in variables)
        structure = ("    <Outputs>\n" + "".join(f'      <Unknown index="{k}"/>\n' for k, _ in outputs)
                     + "    </Outputs>\n    <InitialUnknowns>\n"
                     + "".join(f'      <Unknown index="{k}"/>\n' for k, _ in outputs)
                     + "    </InitialUnknowns>\n") if outputs else ""
        return ('<?xml version="1.0" encoding="UTF-8"?>\n'
                f'<fmiModelDescription fmiVersion="2.0" modelName={quoteattr(ident)} guid="{guid}"\n'
                f'  description={quoteattr(title)} {tool}\n'
                '  variableNamingConvention="flat" numberOfEventIndicators="0">\n'
                f'  <CoSimulation modelIdentifier="{ident}" canHandleVariableCommunicationStepSize="true"'
                ' canInterpolateInputs="false" maxOutputDerivativeOrder="0" canBeInstantiatedOnlyOncePerProcess="false"'
                f' canGetAndSetFMUstate="{state}" canSerializeFMUstate="{state}"'
                ' canNotUseMemoryManagementFunctions="true"/>\n'
                + units + experiment + "  <ModelVariables>\n" + body + "\n  </ModelVariables>\n"
                "  <ModelStructure>\n" + structure + "  </ModelStructure>\n</fmiModelDescription>\n")
    body = "\n".join(f"    <{_FMI3_TYPES[v.type]} {head(v)}{attrs(v)}/>" for v in variables)
    structure = ("".join(f'    <Output valueReference="{v.vr}"/>\n' for _, v in outputs)
                 + "".join(f'    <InitialUnknown valueReference="{v.vr}"/>\n' for _, v in outputs))
    return ('<?xml version="1.0" encoding="UTF-8"?>\n'
            f'<fmiModelDescription fmiVersion="3.0" modelName={quoteattr(ident)} instantiationToken="{guid}"\n'
            f'  description={quoteattr(title)} {tool} variableNamingConvention="flat">\n'
            f'  <CoSimulation modelIdentifier="{ident}" canHandleVariableCommunicationStepSize="true"'
            ' maxOutputDerivativeOrder="0" canBeInstantiatedOnlyOncePerProcess="false"'
            f' canGetAndSetFMUState="{state}" canSerializeFMUState="{state}" hasEventMode="false"'
            ' providesIntermediateUpdate="false" canReturnEarlyAfterIntermediateUpdate="false"/>\n'
            + units + experiment + "  <ModelVariables>\n" + body + "\n  </ModelVariables>\n"
            "  <ModelStructure>\n" + structure + "  </ModelStructure>\n</fmiModelDescription>\n")


def build_export(scene, fmi: int = 2) -> tuple[bytes, dict]:
    """The exported FMU's bytes and a summary, from a loaded scene."""

    if fmi not in (2, 3):
        raise UsageError(f"--fmi {fmi}: expected 2 or 3")
    settings = master_settings(scene)
    _check_scene(scene, settings, fmi)
    binary = system_library()
    if not binary.is_file():
        raise SceneError(f"{binary}: the exported FMU's binary is missing: build it with tools/setup.sh")
    comps = scene.components
    # Every Real output when the scene records none (clockwork run then records nothing to compare).
    outputs = list(scene.record.outputs) or [
        (n, v.name) for n, c in comps.items() for v in c.model_description.modelVariables
        if v.causality == "output" and v.type == "Real" and not getattr(v, "dimensions", None)]
    record: dict[str, list[str]] = {}
    for inst, var in outputs:
        record.setdefault(inst, []).append(var)
    if scene.record.ticks:  # as analyses.time_series: the same ports as clockwork run's
        record.setdefault(scene.record.ticks, []).append("tick_time")
    params = parameters(scene)
    start = scene.experiment.start
    components = {n: (str(c.fmu_path), params[n]) for n, c in comps.items()}
    mds = {n: c.model_description for n, c in comps.items()}
    settings = dataclasses.replace(settings, engine="compiled", threads=1)
    system = System(components, [tuple(c) for c in scene.connections], settings, record=record, start_time=start,
                    model_descriptions=mds, interfaces={n: c.interface for n, c in comps.items()},
                    labels={n: c.fmu_label for n, c in comps.items() if c.fmu_label})
    with system:
        m = system.master
        if not isinstance(m, CompiledMaster):
            raise _refuse(scene, "master", f"the compiled master cannot run this scene: {m.engine_reason}")
        ports = m.ports
        if ports.loops:
            raise _refuse(scene, "connections", f"algebraic loop {ports.loops[0].name}: the exported FMU does not "
                          "solve algebraic loops yet")
        names = list(system.instances)
        index = {n: i for i, n in enumerate(names)}
        port_index = {id(p): i for i, p in enumerate(ports.all)}
        order = [port_index[id(x)] for x in ports.order]
        core = m._core
        lines = [f"clockwork-system {FORMAT}"]
        # The FMUs, each unpacked once under resources/fmus/<k>.
        fmu_dirs: dict[str, int] = {}
        files: list[tuple[str, Path]] = []
        fmu_lines = []
        for n in names:
            c = comps[n]
            key = str(c.fmu_path.resolve())
            if key in fmu_dirs:
                continue
            md = c.model_description
            ident = md.coSimulation.modelIdentifier
            unzip = extract(c.fmu_path)
            if not (unzip / "binaries" / PLATFORM / f"{ident}{SUFFIX}").is_file():
                raise _refuse(scene, f"components.{n}.fmu", f"{c.fmu_path.name} has no binary for {PLATFORM} "
                              f"(binaries/{PLATFORM}/{ident}{SUFFIX}), the exported FMU's platform")
            k = fmu_dirs[key] = len(fmu_dirs)
            fmu_lines.append(f"fmu {_text(f'fmus/{k}')} {_text(ident)} {_text(md.guid)}")
            for f in sorted(unzip.rglob("*")):
                if f.is_file() and not f.is_symlink() and not f.name.startswith(".clockwork"):  # the cache's own
                    files.append((f"resources/fmus/{k}/{f.relative_to(unzip).as_posix()}", f))
        # The exported variables.
        var_lines, xml_vars, units = [], [], set()

        def add(kind_role, inst, v, pos, start_value, causality, variability, initial):
            vr = len(var_lines)
            t = {"Real": "R", "Integer": "I", "Enumeration": "I", "Boolean": "B"}[v.type]
            var_lines.append(f"var {t} {kind_role} {vr} {index[inst]} {v.valueReference} {pos} "
                             f"{float(start_value).hex()}")
            unit = var_unit(v) if v.type == "Real" else None
            if unit:
                units.add(unit)
            text = None
            if start_value is not None and causality != "output":
                text = (repr(float(start_value)) if v.type == "Real" else
                        ("true" if start_value else "false") if v.type == "Boolean" else str(int(start_value)))
            xml_vars.append(_Variable(f"{inst}.{v.name}", vr, "Integer" if v.type == "Enumeration" else v.type,
                                      causality, variability, initial, v.description, unit, text))

        for n in names:  # parameters, in the order System sets them
            table = variables_of(mds[n])
            for var, value in params[n].items():
                v = table[var]
                if v.type not in ("Real", "Integer", "Enumeration", "Boolean") or getattr(v, "dimensions", None):
                    raise _refuse(scene, f"components.{n}.parameters.{var}",
                                  f"a {v.type} parameter: the exported FMU carries Real, Integer and Boolean ones")
                causality = "parameter" if v.causality in ("parameter", "input") else "parameter"
                add("p", n, v, 0, value, causality, "fixed", "exact")
        for n, var in outputs:
            v = variables_of(mds[n])[var]
            if v.type != "Real":
                continue  # a discrete output is not on the master's ports
            add("o", n, v, ports.out_pos[n][var], 0.0, "output", "continuous", None)
        linked = {(c.dst_instance, c.dst_var) for c in scene.connections}
        for n in names:
            for v in mds[n].modelVariables:
                if (v.causality == "input" and v.type == "Real" and (n, v.name) not in linked
                        and v.name not in params[n] and not getattr(v, "dimensions", None)):
                    add("i", n, v, 0, float(v.start) if v.start is not None else 0.0, "input", "continuous", None)
        if fmi == 3:  # FMI 3.0 has an independent variable: the time, read from the master
            var_lines.append(f"var R t {len(var_lines)} 0 0 0 {float(start).hex()}")
            xml_vars.append(_Variable("time", len(var_lines) - 1, "Real", "independent", "continuous", None,
                                      "Simulation time", "s", None))
            units.add("s")
        inst_lines = []
        for n in names:
            inst = system.instances[n]
            tol = settings.tolerance if settings.tolerance is not None else inst.default_tolerance
            inst_lines.append(f"instance {_text(n)} {fmu_dirs[str(comps[n].fmu_path.resolve())]} "
                              f"{int(tol is not None)} {float(tol or 0.0).hex()} "
                              f"{int(bool(getattr(inst, 'outputs_after_inputs', True)))}")
        struct_lines = ["master"] + _struct_lines(core, _MASTER_ARRAYS, _MASTER_SCALARS,
                                                  after_n=sum(len(x) for x in m._updates_after))
        for i, c in enumerate(m._cports):
            struct_lines += [f"port {i}"] + _struct_lines(c, _PORT_ARRAYS, _PORT_SCALARS)
        n_items = sum(1 for x in struct_lines if x.startswith(("a ", "s ")))
        body = [f"counts {len(fmu_lines)} {len(names)} {len(var_lines)} {n_items}",
                f"settings {float(start).hex()} {float(settings.step).hex()} {float(settings.divergence_limit).hex()}",
                *fmu_lines, *inst_lines, f"order {len(order)} " + " ".join(map(str, order)), *var_lines,
                *struct_lines, "end"]
        digest = hashlib.sha256("\n".join(lines + body).encode()).hexdigest()
        guid = f"{{{digest[:8]}-{digest[8:12]}-{digest[12:16]}-{digest[16:20]}-{digest[20:32]}}}"
        description = "\n".join(lines + [f"guid {guid}"] + body) + "\n"
    ident = _identifier(scene.path.stem)
    stop = scene.experiment.stop
    # The state is every inner FMU's, serialized: offered where every inner FMU offers both.
    state = "true" if all(md.coSimulation.canGetAndSetFMUstate and md.coSimulation.canSerializeFMUstate
                          for md in mds.values()) else "false"
    md_xml = _model_description(fmi, ident, guid, scene.title or ident, state, _unit_xml(list(mds.values()), units),
                                start, stop, settings.step, xml_vars)
    platform = PLATFORM if fmi == 2 else PLATFORM3
    # Windows too where the front's Windows build is there (lib/cw_system.dll, from the mingw-w64 cross
    # build) and every inner FMU carries a win64 DLL: the front loads the inner FMUs of its own platform.
    windows = system_library(".dll")
    with_windows = windows.is_file() and all(
        (extract(comps[n].fmu_path) / "binaries" / "win64" / f"{mds[n].coSimulation.modelIdentifier}.dll").is_file()
        for n in names)
    entries: list[tuple[str, bytes | Path]] = [
        ("modelDescription.xml", md_xml.encode()), (f"binaries/{platform}/{ident}{SUFFIX}", binary),
        (f"resources/{DESCRIPTION}", description.encode()), *files]
    if with_windows:
        entries.append((f"binaries/{'win64' if fmi == 2 else 'x86_64-windows'}/{ident}.dll", windows))
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as z:
        # The same scene gives the same bytes: entries sorted, one date, one mode (as tools/fmuzip.py).
        for arc, content in sorted(entries, key=lambda e: e[0]):
            info = zipfile.ZipInfo(arc, date_time=(1980, 1, 1, 0, 0, 0))
            info.compress_type = zipfile.ZIP_DEFLATED
            info.external_attr = 0o644 << 16
            z.writestr(info, content if isinstance(content, bytes) else content.read_bytes())
    summary = {"instances": len(names), "fmus": len(fmu_lines), "parameters": sum(1 for x in var_lines if " p " in x),
               "outputs": sum(1 for x in xml_vars if x.causality == "output"), "inputs": sum(1 for x in var_lines if " i " in x),
               "model_identifier": ident,
               "platforms": [platform] + ([("win64" if fmi == 2 else "x86_64-windows")] if with_windows else [])}
    return buf.getvalue(), summary


def export_fmu(scene_spec, out, fmi: int = 2, overrides=()) -> dict:
    """Write `out` (an .fmu that must not exist yet) from a scene file, an
    SSP or an FMU; bad input raises UsageError or SceneError before a byte
    is written, and the file is written whole or not at all."""

    out = Path(out)
    if out.suffix != ".fmu":
        raise UsageError(f"--out {out}: expected a file name ending .fmu")
    if os.path.lexists(out):
        raise UsageError(f"--out {out}: exists already: give a new file name (nothing is overwritten)")
    check_output_file(out, "--out")
    if fmi not in (2, 3):
        raise UsageError(f"--fmi {fmi}: expected 2 or 3")
    scene = load_scene(scene_spec, overrides)
    data, summary = build_export(scene, fmi)
    write_bytes_unnamed(out, data)
    summary["size_bytes"] = len(data)
    return summary
