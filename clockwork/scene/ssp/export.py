"""Export a scene as an SSP 1.0 archive (System Structure and Parameterization).

The archive holds

- ``SystemStructure.ssd``: one ``ssd:System`` with a ``ssd:Component`` per
  scene component, its connected inputs and all its outputs as connectors,
  the scene's connections, the units the connectors use and the experiment;
- ``resources/<Model>.fmu``: each FMU once;
- ``resources/<instance>.ssv``: the scene's parameter values of one
  component (variable names without the instance prefix), bound to that
  component with ``ssd:ParameterBinding source=...``. All sets are named
  ``PARAMETER_SET`` (ecos applies a parameter set only when asked by name).

Choices made so that fmpy (``fmpy.ssp.read_ssd`` with schema validation),
libcosim, ecos and OMSimulator all read the same file:

- the prefixes ``ssd``, ``ssc``, ``ssv`` are written literally (libcosim,
  ecos and OMSimulator match element names with their prefixes);
- parameter bindings sit on the components: libcosim and ecos ignore
  bindings on the system;
- only connected inputs are connectors: fmpy's SSP runner sets every input
  connector every step (to 0 until a connection feeds it), which would
  overwrite e.g. a constant ``g_factor``, and it fails on an unconnected one;
- the fixed step is given twice as vendor annotations: ``org.openmodelica``
  (``oms:SimulationInformation/oms:FixedStepMaster``, which OMSimulator needs
  to make the system a weakly coupled one) on the system, and
  ``com.opensimulationplatform`` (``osp:Algorithm/osp:FixedStepAlgorithm``,
  libcosim's default algorithm) on the default experiment. Both are
  annotations, which the SSP schema lets through.

Values are written with ``repr`` (shortest round-trip form), so the tools
read back exactly the scene's doubles.
"""

from __future__ import annotations

import io
import json
import re
import zipfile
from pathlib import Path

from lxml import etree

from ...version import __version__
from ...atomic import write_bytes_atomic, write_text_atomic
from ...fmi.description import INTEGER_TYPES, REAL_TYPES, var_unit
from ...errors import SceneError
from .common import CW_ANNOTATION, CW_NS, NS, OMS_NS, OSP_NS, q as _q

_WRITTEN = ("ssd", "ssc", "ssv")  # the namespaces an exported SSD declares
PARAMETER_SET = "clockwork"
FMU_TYPE = "application/x-fmu-sharedlibrary"
_BASE_UNITS = ("kg", "m", "s", "A", "K", "mol", "cd", "rad")


def _sub(parent, prefix: str, tag: str, **attrs):
    el = etree.SubElement(parent, _q(prefix, tag))
    for k, v in attrs.items():
        if v is not None:
            el.set(k, v)
    return el


def _real(x: float) -> str:
    return repr(float(x))


def _identifier(text: str) -> str:
    name = re.sub(r"[^A-Za-z0-9_]", "_", text)
    return name if re.match(r"[A-Za-z_]", name) else "_" + name


def _connector_type(v) -> str:
    """The SSP 1.0 connector type of a variable: FMI 3.0's Float32 is a
    Real, its integers of every size are Integers."""
    if v.type in REAL_TYPES:
        return "Real"
    if v.type in INTEGER_TYPES and v.type != "Enumeration":
        return "Integer"
    return v.type


def _type_element(v, path, key: str) -> str:
    """The ssv element of a parameter value (an Enumeration's is its
    integer); SceneError at the scene's `key` for a type SSP 1.0 lacks."""
    kind = "Integer" if v.type == "Enumeration" else _connector_type(v)
    if kind not in ("Real", "Integer", "Boolean", "String"):
        raise SceneError(f"{v.name} is {v.type}, which an SSP 1.0 parameter set cannot carry; expected "
                         f"a Real, Integer, Boolean, String or Enumeration parameter", path, key)
    return kind


def _value_text(type_name: str, value) -> str:
    if type_name == "Real":
        return _real(value)
    if type_name == "Integer":
        return str(int(value))
    if type_name == "Boolean":
        return "true" if value else "false"
    return str(value)


def parameter_set_xml(name: str, parameters: list[tuple[str, str, object]]) -> bytes:
    """An ssv:ParameterSet document; parameters as (name, FMI type, value)."""
    root = etree.Element(_q("ssv", "ParameterSet"), nsmap={"ssv": NS["ssv"]})
    root.set("version", "1.0")
    root.set("name", name)
    params = _sub(root, "ssv", "Parameters")
    for pname, type_name, value in parameters:
        p = _sub(params, "ssv", "Parameter", name=pname)
        _sub(p, "ssv", type_name, value=_value_text(type_name, value))
    return etree.tostring(root, xml_declaration=True, encoding="UTF-8", pretty_print=True)


# OMSimulator's own defaults, for a scene whose FMUs take no tolerance parameter.
_OMS_DEFAULT_TOLERANCE = 1e-4


def _tolerances(scene) -> tuple[float, float]:
    """(relative, absolute) tolerance for the OMSimulator annotation: the
    tightest `rtol`/`atol` any component is given (or starts with)."""
    found: dict[str, list[float]] = {"rtol": [], "atol": []}
    for comp in scene.components.values():
        starts = {v.name: v.start for v in comp.model_description.modelVariables}
        for key in found:
            value = comp.parameters.get(key, starts.get(key))
            if value is not None:
                found[key].append(float(value))
    return (min(found["rtol"], default=_OMS_DEFAULT_TOLERANCE),
            min(found["atol"], default=_OMS_DEFAULT_TOLERANCE))


def _refuse_sums(scene, what: str) -> None:
    """SceneError for a sum of outputs into one input (an OSP Sum), which `what` cannot say."""
    c = next((c for c in scene.connections if c.adds), None)
    if c is not None:
        raise SceneError(f"{what} feeds an input from one output; {c.dst_instance}.{c.dst_var} is a sum of several "
                         "(an OSP Sum): not exported", scene.path, f"connection {c}")


def build_ssp(scene, point: dict | None = None) -> dict[str, bytes]:
    """The archive's files {path: bytes} for a scene (and a sweep point)."""
    if point:
        scene = scene.variant(point)
    _refuse_sums(scene, "an SSP")
    files: dict[str, bytes] = {}
    # One resource per distinct FMU file; the model name when it is free.
    fmu_names: dict[str, str] = {}
    for comp in scene.components.values():
        if comp.sha256 in fmu_names:
            continue
        base = _identifier(comp.model_name)
        name, k = base, 1
        while f"resources/{name}.fmu" in files:
            k += 1
            name = f"{base}_{k}"
        files[f"resources/{name}.fmu"] = Path(comp.fmu_path).read_bytes()
        fmu_names[comp.sha256] = f"resources/{name}.fmu"

    connected_inputs = {(c.dst_instance, c.dst_var) for c in scene.connections}
    root = etree.Element(_q("ssd", "SystemStructureDescription"),
                         nsmap={**{k: NS[k] for k in _WRITTEN}, "oms": OMS_NS, "osp": OSP_NS, "cw": CW_NS})
    root.set("version", "1.0")
    root.set("name", _identifier(scene.path.stem))
    root.set("generationTool", f"clockwork {__version__}")
    system = _sub(root, "ssd", "System", name="root", description=scene.title or None)
    elements = _sub(system, "ssd", "Elements")
    used_units: dict[str, object] = {}
    for inst, comp in scene.components.items():
        md = comp.model_description
        arrays = [v.name for v in md.modelVariables if v.shape]
        if arrays:
            raise SceneError(f"{comp.model_name} has FMI 3.0 array variables ({', '.join(arrays[:4])}"
                             f"{', ...' if len(arrays) > 4 else ''}), which SSP 1.0 connectors and parameter "
                             "sets cannot describe", scene.path, f"components.{inst}.fmu")
        el = _sub(elements, "ssd", "Component", name=inst, type=FMU_TYPE, source=fmu_names[comp.sha256])
        if comp.interface == "model-exchange":  # asked for where the FMU has both interfaces
            el.set("implementation", "ModelExchange")
        connectors = []
        for v in md.modelVariables:
            if v.causality == "output" or (v.causality == "input" and (inst, v.name) in connected_inputs):
                connectors.append(v)
        if connectors:  # an empty ssd:Connectors is invalid
            cs = _sub(el, "ssd", "Connectors")
            for v in connectors:
                c = _sub(cs, "ssd", "Connector", name=v.name, kind=v.causality)
                unit = var_unit(v) if v.type in REAL_TYPES else None
                declared = getattr(v.declaredType, "name", None) if v.type == "Enumeration" else None
                _sub(c, "ssc", _connector_type(v), unit=unit, name=declared)
                if unit:
                    used_units.setdefault(unit, md)
        params = []
        variables = {v.name: v for v in md.modelVariables}
        for name, value in comp.parameters.items():
            params.append((name, _type_element(variables[name], scene.path, f"components.{inst}.parameters.{name}"),
                           value))
        if params:
            ssv_path = f"resources/{inst}.ssv"
            files[ssv_path] = parameter_set_xml(PARAMETER_SET, params)
            bindings = _sub(el, "ssd", "ParameterBindings")
            _sub(bindings, "ssd", "ParameterBinding", type="application/x-ssp-parameter-set", source=ssv_path)
        if comp.step is not None:  # its own step (multi-rate): the OSP annotation libcosim and ecos read
            osp = _sub(_sub(el, "ssd", "Annotations"), "ssc", "Annotation", type="com.opensimulationplatform")
            _sub(osp, "osp", "StepSizeHint", value=_real(comp.step))

    if scene.connections:
        conns = _sub(system, "ssd", "Connections")
        for c in scene.connections:
            transformed = (c.factor, c.offset) != (1.0, 0.0)
            # an identity between different units: an OSP link, which passes the number unconverted
            units_differ = (var_unit(scene.components[c.src_instance].variable(c.src_var))
                            != var_unit(scene.components[c.dst_instance].variable(c.dst_var)))
            # The link's whole factor and offset (a unit conversion folded in):
            # written as they are, with the tools' own unit conversion off, so
            # that every reader applies the very doubles the scene does.
            el = _sub(conns, "ssd", "Connection", startElement=c.src_instance, startConnector=c.src_var,
                      endElement=c.dst_instance, endConnector=c.dst_var,
                      suppressUnitConversion="true" if transformed or units_differ else None)
            if transformed:
                _sub(el, "ssc", "LinearTransformation", factor=_real(c.factor), offset=_real(c.offset))

    step = _real(scene.master.step)
    annotations = _sub(system, "ssd", "Annotations")
    oms = _sub(annotations, "ssc", "Annotation", type="org.openmodelica")
    info = _sub(_sub(oms, "oms", "Annotations"), "oms", "SimulationInformation")
    rtol, atol = _tolerances(scene)
    _sub(info, "oms", "FixedStepMaster", description="oms-ma", stepSize=step,
         absoluteTolerance=_real(atol), relativeTolerance=_real(rtol))
    _clockwork_annotation(annotations, scene)

    if used_units:
        units = _sub(root, "ssd", "Units")
        for uname, md in used_units.items():
            u = _sub(units, "ssc", "Unit", name=uname)
            base = next((d.baseUnit for d in md.unitDefinitions if d.name == uname), None)
            attrs = {}
            if base is not None:
                for k in _BASE_UNITS:
                    if getattr(base, k, 0):
                        attrs[k] = str(int(getattr(base, k)))
                if base.factor != 1.0:
                    attrs["factor"] = _real(base.factor)
                if base.offset != 0.0:
                    attrs["offset"] = _real(base.offset)
            _sub(u, "ssc", "BaseUnit", **attrs)

    exp = _sub(root, "ssd", "DefaultExperiment", startTime=_real(scene.experiment.start),
               stopTime=_real(scene.experiment.stop))
    osp = _sub(_sub(exp, "ssd", "Annotations"), "ssc", "Annotation", type="com.opensimulationplatform")
    _sub(_sub(osp, "osp", "Algorithm"), "osp", "FixedStepAlgorithm", baseStepSize=step)

    files["SystemStructure.ssd"] = etree.tostring(root, xml_declaration=True, encoding="UTF-8",
                                                  pretty_print=True)
    return files


def _setting(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    return _real(value) if isinstance(value, float) else str(value)


def _clockwork_annotation(annotations, scene) -> None:
    """The master settings and what to record, for clockwork to run the SSP
    back exactly as the scene (clockwork.scene.ssp.read)."""
    # one child element: the schema allows a single element in an ssc:Annotation
    cw = _sub(_sub(annotations, "ssc", "Annotation", type=CW_ANNOTATION), "cw", "Settings")
    master = _sub(cw, "cw", "Master")
    for k, v in scene.master.as_dict().items():
        if (k == "max_step" and not scene.max_step_given) or v is None:
            continue  # max_step follows the step, also under --set master.step; None is the default
        master.set(k, _setting(v))
    record = _sub(cw, "cw", "Record")
    if scene.record.interval is not None:
        record.set("interval", _real(scene.record.interval))
    if scene.record.ticks is not None:
        record.set("ticks", scene.record.ticks)
    for inst, var in scene.record.outputs:
        _sub(record, "cw", "Output", name=f"{inst}.{var}")


def export_ssp(scene, out: str | Path, point: dict | None = None) -> Path:
    """Write the scene as an SSP archive; returns the path."""
    out = Path(out)
    files = build_ssp(scene, point)
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("SystemStructure.ssd", files.pop("SystemStructure.ssd"))
        for name in sorted(files):
            z.writestr(name, files[name])
    return write_bytes_atomic(out, buf.getvalue())


def container_description(scene, point: dict | None = None) -> tuple[dict, dict[str, Path]]:
    """An fmu-manipulation-toolbox ``fmucontainer`` description (JSON) of the
    scene: its FMUs (one entry per instance, named ``<instance>.fmu``), links,
    parameter values as start values, every output exposed as
    ``<instance>_<output>`` and the unconnected inputs as inputs. Returns (description, {entry name: FMU file}).

    fmucontainer also reads .ssp archives, but (version 2.0) without their
    parameter bindings; the JSON form carries them."""
    if point:
        scene = scene.variant(point)
    _refuse_sums(scene, "an fmucontainer description")
    files = {f"{inst}.fmu": Path(c.fmu_path) for inst, c in scene.components.items()}
    start, outputs = [], []
    for inst, comp in scene.components.items():
        for name, value in comp.parameters.items():
            if isinstance(value, float):
                value = float(value)
            start.append([f"{inst}.fmu", name, value])
        for v in comp.model_description.modelVariables:
            if v.causality == "output":
                # "<instance>.<output>" is taken: fmucontainer names its
                # internal (linked) variables so.
                outputs.append([f"{inst}.fmu", v.name, f"{inst}_{v.name}"])
    desc = {
        "name": f"{_identifier(scene.path.stem)}.fmu",
        "step_size": scene.master.step,
        "auto_link": False,
        "auto_input": True,  # unconnected inputs become the container's, at their start values
        "auto_output": False,
        "fmu": list(files),
        "link": [[f"{c.src_instance}.fmu", c.src_var, f"{c.dst_instance}.fmu", c.dst_var]
                 for c in scene.connections],
        "output": outputs,
        "start": start,
    }
    return desc, files


def write_container_description(scene, directory: str | Path, point: dict | None = None) -> Path:
    """Write DIR/<scene>.json for ``fmucontainer -container <scene>.json
    -fmu-directory DIR`` with a copy of each instance's FMU beside it."""
    directory = Path(directory)
    directory.mkdir(exist_ok=True)
    desc, files = container_description(scene, point)
    for name, src in files.items():
        write_bytes_atomic(directory / name, Path(src).read_bytes())
    return write_text_atomic(directory / (Path(desc["name"]).stem + ".json"), json.dumps(desc, indent=2) + "\n")


def fmpy_parameter_set(ssp: str | Path):
    """The components' parameter bindings as one fmpy ParameterSet whose names
    carry the instance prefix, for ``fmpy.ssp.simulation.simulate_ssp``
    (which applies only the set it is given, not the SSD's bindings)."""
    from fmpy.ssp.ssd import Parameter, ParameterSet, find_components, read_ssd

    ssd = read_ssd(str(ssp))
    out = ParameterSet(name=PARAMETER_SET)
    for comp in find_components(ssd.system):
        for binding in comp.parameterBindings:
            for pset in binding.parameterValues:
                for p in pset.parameters:
                    # fmpy's set_value converts Reals itself but tests Booleans with != 0.0
                    value = {"Real": float, "Integer": int}.get(p.type, lambda x: x)(p.value)
                    if p.type == "Boolean":
                        value = 1.0 if p.value in ("true", "1") else 0.0
                    out.parameters.append(Parameter(name=f"{comp.name}.{p.name}", type=p.type, value=value))
    return out
