"""A scene written back as a TOML scene file (`clockwork export-scene X.fmu`):
the scene clockwork built for an FMU, with the --set values and the input
file, as a file to start from. Loading what is written gives the same
scene (values are written exactly: a float as Python's repr, which TOML
reads back to the same double).
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

from ..fmi.description import var_unit
from ..engine.settings import DEFAULTS as _DEFAULTS
from .model import Scene
from .units import link_conversion



def toml_value(value) -> str:
    """A value as TOML: strings as basic strings (JSON's escapes are TOML's),
    floats exactly, lists inline (numpy's scalars as Python's: their repr
    is not TOML); TypeError for what TOML has no form for."""
    if hasattr(value, "dtype") and hasattr(value, "item") and getattr(value, "ndim", None) == 0:
        value = value.item()
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        if not -2**63 <= value < 2**64:  # TOML's integers are 64-bit: not one TOML reads back
            raise TypeError(f"no TOML form for an integer of {value.bit_length()} bits")
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(toml_value(x) for x in value) + "]"
    raise TypeError(f"no TOML form for {type(value).__name__}")


def _path_for(target: Path, scene_file: Path) -> str:
    """A path as the scene file names it: relative to its folder when the
    target lies below that folder, else absolute."""
    target = Path(target).resolve()
    base = scene_file.resolve().parent
    try:
        return target.relative_to(base).as_posix()
    except ValueError:
        return str(target)


def toml_problem(scene: Scene) -> tuple[str, str] | None:
    """(key, detail) where the scene file `scene_toml` writes would not run
    as `scene`, else None: a TOML link gives the unit conversion between
    its variables and nothing else, so a link of another factor or offset
    (an OSP or SSP linear transformation, an OSP link passed unconverted
    between different units) has no form in it."""
    summed = next((c for c in scene.connections if c.adds), None)
    if summed is not None:
        return (f"connection {summed}", f"{summed.dst_instance}.{summed.dst_var} is a sum of several outputs (an OSP "
                                        "Sum), which a scene file cannot say; run this file itself")
    for c in scene.connections:
        sc, dc = scene.components[c.src_instance], scene.components[c.dst_instance]
        su, du = var_unit(sc.variable(c.src_var)), var_unit(dc.variable(c.dst_var))
        toml = (1.0, 0.0)
        if su != du and su is not None and du is not None:
            toml = link_conversion(sc.model_description, su, dc.model_description, du)
        if toml != (c.factor, c.offset):
            said = "it would be refused" if toml is None else f"x {toml[0]:g} + {toml[1]:g}"
            return (f"connection {c}", f"the link gives x {c.factor:g} + {c.offset:g}, which a scene file cannot "
                                       f"say (its links convert units only: {said}); expected links without a "
                                       "linear transformation, or run this file itself")
    return None


def scene_toml(scene: Scene, scene_file: Path, source: str) -> str:
    """The text of a TOML scene file, to be written to `scene_file`, for
    `scene`; `source` says what it was made from (a comment)."""
    scene_file = Path(scene_file)
    lines = [f"# Written by clockwork export-scene from {source}: the scene `clockwork run` used.",
             "# Edit and run it with: clockwork run " + os.path.basename(scene_file) + " --out DIR", ""]
    if scene.connections:
        lines.append("connections = [")
        lines += [f"  {toml_value(str(c))}," for c in scene.connections]
        lines += ["]", ""]
    lines += ["[scene]", f"title = {toml_value(scene.title)}"]
    if scene.description:
        lines.append(f"description = {toml_value(scene.description)}")
    for name, c in scene.components.items():
        lines += ["", f"[components.{toml_value(name)}]", f"fmu = {toml_value(_path_for(c.fmu_path, scene_file))}"]
        if c.step is not None:  # its own step (multi-rate)
            lines.append(f"step = {toml_value(float(c.step))}")
        if c.parameters:
            lines.append("[components." + toml_value(name) + ".parameters]")
            lines += [f"{toml_value(k)} = {toml_value(v)}" for k, v in c.parameters.items()]
    e = scene.experiment
    lines += ["", "[experiment]", f"start = {toml_value(float(e.start))}", f"stop = {toml_value(float(e.stop))}"]
    lines += ["", "[master]"]
    master = scene.master.as_dict()
    for key, value in master.items():
        if key == "max_step" and not scene.max_step_given:
            continue
        if key == "step" or value != _DEFAULTS[key]:
            lines.append(f"{key} = {toml_value(float(value) if key in ('step', 'max_step') else value)}")
    r = scene.record
    lines += ["", "[record]", "outputs = [" + ", ".join(toml_value(f"{i}.{v}") for i, v in r.outputs) + "]"]
    if r.interval is not None:
        lines.append(f"interval = {toml_value(float(r.interval))}")
    if r.ticks is not None:
        lines.append(f"ticks = {toml_value(r.ticks)}")
    if r.format != ("csv",):
        lines.append(f"format = {toml_value(list(r.format))}")
    if scene.analysis is not None:
        lines += ["", "[analysis]"] + [f"{k} = {toml_value(v)}" for k, v in scene.analysis.items()]
    if scene.inputs is not None and scene.inputs.file is not None:
        lines += ["", "[inputs]", f"file = {toml_value(_path_for(scene.inputs.file, scene_file))}"]
    for spec in scene.plots:
        lines += ["", "[[plot]]"] + [f"{k} = {toml_value(v)}" for k, v in spec.items()]
    return "\n".join(lines) + "\n"
