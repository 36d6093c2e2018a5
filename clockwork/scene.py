"""Scene files: loading and strict validation (format: docs/scenes.md).

`load_scene(path, overrides)` reads a TOML scene, applies `--set`
overrides, checks every key and value against the FMUs' model descriptions
and returns a frozen `Scene` with all quantities converted to the
variables' own (SI) units. Every problem raises `SceneError` with a
one-line message naming the file, the dotted key and what was expected.
"""

from __future__ import annotations

import dataclasses
import difflib
import hashlib
import itertools
import json
import math
import os
import re
import tomllib
import xml.etree.ElementTree as ET
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, NamedTuple

import numpy as np

from .errors import SceneError
from .units import UnitError, fmt, parse_quantity, to_radians, to_seconds, to_unit

REPO = Path(__file__).resolve().parents[1]
NAME_RE = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
_REF_RE = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_]*)\.([A-Za-z_][A-Za-z0-9_.\[\]]*)\s*$")
_CONN_RE = re.compile(
    r"^\s*([A-Za-z_][A-Za-z0-9_]*)\.(\S+)\s*->\s*([A-Za-z_][A-Za-z0-9_]*)\.(\S+)\s*$"
)

# ---------------------------------------------------------------------------
# Registries of analysis and plot kinds

# kind -> allowed keys besides `kind`
ANALYSIS_KEYS: dict[str, set[str]] = {
    "time_series": set(),
    "steady_state": {"tolerance_s_per_day", "max_periods", "measure_periods", "amplitude_guess"},
    "ticks": set(),
}
PLOT_KEYS: dict[str, set[str]] = {
    "time_series": {"x", "y", "title", "file"},
    "phase_portrait": {"x", "y", "title", "file"},
    "sweep": {"x", "y", "title", "file"},
}
# kind -> function(table without `kind`) -> converted table; raises Invalid
_ANALYSIS_CONVERT: dict[str, Callable[[dict], dict]] = {}
_PLOT_CONVERT: dict[str, Callable[[dict], dict]] = {}


class Invalid(Exception):
    """Raised by a kind's converter: Invalid(key, 'what was expected')."""

    def __init__(self, key: str, expected: str):
        super().__init__(key, expected)
        self.key = key
        self.expected = expected


def register_analysis(kind: str, keys: set[str] | frozenset[str] = frozenset(),
                      convert: Callable[[dict], dict] | None = None) -> None:
    """Allow `[analysis] kind = "<kind>"` with the given keys.

    `convert(table)` gets the analysis table without `kind` (only allowed
    keys, raw TOML values) and returns the converted values; it raises
    `Invalid(key, expected)` for a bad value.
    """
    ANALYSIS_KEYS[kind] = set(keys)
    if convert is not None:
        _ANALYSIS_CONVERT[kind] = convert
    else:
        _ANALYSIS_CONVERT.pop(kind, None)


def register_plot(kind: str, keys: set[str] | frozenset[str] = frozenset(),
                  convert: Callable[[dict], dict] | None = None) -> None:
    """Allow `[[plot]] kind = "<kind>"` with the given keys (see register_analysis)."""
    PLOT_KEYS[kind] = set(keys)
    if convert is not None:
        _PLOT_CONVERT[kind] = convert
    else:
        _PLOT_CONVERT.pop(kind, None)


def _positive_number(key: str, v: object) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
        raise Invalid(key, "a positive number")
    return float(v)


def _positive_int(key: str, v: object) -> int:
    if isinstance(v, bool) or not isinstance(v, int) or v < 1:
        raise Invalid(key, "a positive integer")
    return v


def _convert_steady_state(t: dict) -> dict:
    out = {}
    if "tolerance_s_per_day" in t:
        out["tolerance_s_per_day"] = _positive_number("tolerance_s_per_day", t["tolerance_s_per_day"])
    for k in ("max_periods", "measure_periods"):
        if k in t:
            out[k] = _positive_int(k, t[k])
    if "amplitude_guess" in t:
        try:
            a = to_radians(t["amplitude_guess"])
        except UnitError as e:
            raise Invalid("amplitude_guess", str(e)) from None
        if not 0 < a <= math.pi:
            raise Invalid("amplitude_guess", "an angle in (0, 180] deg")
        out["amplitude_guess"] = a
    return out


def _convert_plot(t: dict) -> dict:
    out = dict(t)
    for k in ("x", "title"):
        if k in t and not isinstance(t[k], str):
            raise Invalid(k, "a string")
    if "y" in t:
        y = t["y"]
        if not (isinstance(y, str) or (isinstance(y, list) and y and all(isinstance(s, str) for s in y))):
            raise Invalid("y", "a string or a non-empty list of strings")
    if "file" in t:
        f = t["file"]
        if not isinstance(f, str) or not f or "/" in f or "\\" in f or f.startswith("."):
            raise Invalid("file", "a file name without a directory, e.g. \"phase.png\"")
    return out


_ANALYSIS_CONVERT["steady_state"] = _convert_steady_state
for _k in PLOT_KEYS:
    _PLOT_CONVERT[_k] = _convert_plot


# ---------------------------------------------------------------------------
# The validated scene


@dataclass(frozen=True)
class Component:
    name: str
    fmu_path: Path
    sha256: str
    model_description: Any  # fmpy.model_description.ModelDescription
    parameters: dict[str, float | int | bool | str]  # in the variable's unit (SI)
    event_indicators: tuple[str, ...] = ()  # from the `clockwork` vendor annotation

    @property
    def model_name(self) -> str:
        return self.model_description.modelName

    def variable(self, name: str):
        return _variables(self.model_description)[name]


class Connection(NamedTuple):
    src_instance: str
    src_var: str
    dst_instance: str
    dst_var: str

    def __str__(self) -> str:
        return f"{self.src_instance}.{self.src_var} -> {self.dst_instance}.{self.dst_var}"


@dataclass(frozen=True)
class Experiment:
    start: float  # s
    stop: float  # s


@dataclass(frozen=True)
class MasterConfig:
    """Field names match clockwork.master.MasterSettings."""

    step: float = 0.01  # s
    order: str = "gauss-seidel"
    extrapolation: int = 0
    event_location: bool = True
    event_time_tolerance: float = 1e-10  # s
    event_indicator_tolerance: float = 1e-12
    iterations: int = 0
    iteration_tolerance: float = 1e-10
    richardson: bool = False
    richardson_tolerance: float = 1e-8
    min_step: float = 1e-9  # s
    max_step: float = 0.01  # s

    def as_dict(self) -> dict:
        return dataclasses.asdict(self)


@dataclass(frozen=True)
class Record:
    outputs: tuple[tuple[str, str], ...]  # (instance, variable)
    interval: float | None  # s; None = every communication point
    ticks: str | None  # instance whose tick_time/tick_count are recorded


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
    master: MasterConfig
    record: Record
    analysis: dict | None  # {"kind": ..., converted keys}
    sweep: Sweep | None
    plots: tuple[dict, ...]
    overrides: tuple[str, ...] = ()  # the --set arguments applied
    sha256: str = ""  # of the scene file's bytes
    max_step_given: bool = field(default=False, repr=False, compare=False)

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
        master = dataclasses.asdict(self.master)
        exp = dataclasses.asdict(self.experiment)
        for (owner, name), value in values.items():
            if owner == "master":
                master[name] = value
                if name == "step" and not self.max_step_given and ("master", "max_step") not in values:
                    master["max_step"] = value
            elif owner == "experiment":
                exp[name] = value
            else:
                c = comps[owner]
                comps[owner] = dataclasses.replace(c, parameters={**c.parameters, name: value})
        m = MasterConfig(**master)
        e = Experiment(**exp)
        problem = _consistency(m, e)
        if problem:
            key, detail = problem
            raise SceneError(detail, self.path, f"{key} (with {_show_point(values)})")
        return dataclasses.replace(self, components=comps, master=m, experiment=e)


def _show_point(values: dict) -> str:
    return ", ".join(f"{a}.{b} = {_show(v)}" for (a, b), v in values.items())


def _consistency(m: MasterConfig, e: Experiment) -> tuple[str, str] | None:
    if not e.stop > e.start:
        return "experiment.stop", f"expected stop > start ({fmt(e.start)} s), got {fmt(e.stop)} s"
    if m.min_step > m.step:
        return "master.min_step", f"expected min_step <= step ({fmt(m.step)} s), got {fmt(m.min_step)} s"
    if m.max_step < m.step:
        return "master.max_step", f"expected max_step >= step ({fmt(m.step)} s), got {fmt(m.max_step)} s"
    return None


# ---------------------------------------------------------------------------
# FMUs


def fmu_dir() -> Path:
    """Where model names are looked up: $CLOCKWORK_FMU_DIR, else <repo>/fmus."""
    env = os.environ.get("CLOCKWORK_FMU_DIR")
    return Path(env) if env else REPO / "fmus"


_MD_CACHE: dict[tuple, tuple] = {}


class FmuError(Exception):
    """A missing or unusable FMU; str() is the reason."""


def resolve_fmu(spec: str, base_dir: Path | None = None) -> Path:
    """A model name -> <fmu_dir>/<name>.fmu; a path ending .fmu -> relative to base_dir."""
    if spec.endswith(".fmu"):
        p = Path(spec).expanduser()
        if not p.is_absolute():
            p = (base_dir or Path.cwd()) / p
        if not p.is_file():
            rel = "" if Path(spec).is_absolute() else " (a relative path is taken from the scene file's directory)"
            raise FmuError(f"no such FMU file: {p}{rel}")
        return p
    if not NAME_RE.match(spec):
        raise FmuError("expected a model name (e.g. \"Pendulum\") or a path ending .fmu")
    d = fmu_dir()
    p = d / f"{spec}.fmu"
    if p.is_file():
        return p
    known = sorted(q.stem for q in d.glob("*.fmu")) if d.is_dir() else []
    close = difflib.get_close_matches(spec, known, n=1)
    hint = f" (did you mean {close[0]}?)" if close else ""
    src = f"; there is no src_c/models/{spec} either" if not (REPO / "src_c" / "models" / spec).is_dir() else ""
    raise FmuError(
        f"no FMU named {spec}{hint}: looked for {p} (the FMU directory is $CLOCKWORK_FMU_DIR, "
        f"else <repo>/fmus; build the FMUs with `cmake --build build`{src})"
    )


def read_fmu(path: Path, need_binary: bool = True) -> tuple[Any, str, tuple[str, ...]]:
    """(model description, sha256, event indicators) of an FMU, cached by (path, mtime, size)."""
    import fmpy

    path = Path(path).resolve()
    try:
        st = path.stat()
    except OSError as e:
        raise FmuError(f"cannot read {path}: {e.strerror}") from None
    key = (str(path), st.st_mtime_ns, st.st_size)
    hit = _MD_CACHE.get(key)
    if hit is None:
        if not zipfile.is_zipfile(path):
            raise FmuError(f"{path} is not an FMU: not a zip archive")
        try:
            with zipfile.ZipFile(path) as z:
                names = set(z.namelist())
                if "modelDescription.xml" not in names:
                    raise FmuError(f"{path} is not an FMU: no modelDescription.xml in the archive")
                xml = z.read("modelDescription.xml")
        except (zipfile.BadZipFile, OSError) as e:
            raise FmuError(f"{path} is not a readable FMU: {e}") from None
        try:
            md = fmpy.read_model_description(str(path), validate=False)
        except Exception as e:  # fmpy raises bare Exceptions and lxml errors
            raise FmuError(f"{path}: unreadable modelDescription.xml: {e}") from None
        if md.fmiVersion != "2.0":
            raise FmuError(f"{path}: expected an FMI 2.0 FMU, found FMI {md.fmiVersion}")
        if md.coSimulation is None:
            raise FmuError(f"{path}: expected a Co-Simulation FMU (no <CoSimulation> element)")
        indicators = _event_indicators(xml)
        digest = hashlib.sha256(path.read_bytes()).hexdigest()
        binary = f"binaries/{fmpy.platform}/{md.coSimulation.modelIdentifier}{fmpy.sharedLibraryExtension}"
        hit = (md, digest, indicators, binary in names, binary)
        _MD_CACHE.clear() if len(_MD_CACHE) > 256 else None
        _MD_CACHE[key] = hit
    md, digest, indicators, has_binary, binary = hit
    if need_binary and not has_binary:
        raise FmuError(f"{path} has no binary for this platform ({binary}); rebuild it with `cmake --build build`")
    return md, digest, indicators


def _event_indicators(xml: bytes) -> tuple[str, ...]:
    try:
        root = ET.fromstring(xml)
    except ET.ParseError:
        return ()
    out = []
    for tool in root.findall("./VendorAnnotations/Tool"):
        if tool.get("name") == "clockwork":
            out += [i.get("name") for i in tool.findall("./EventIndicators/Indicator") if i.get("name")]
    return tuple(out)


def event_indicators(path: Path) -> tuple[str, ...]:
    """Names of the event-indicator outputs declared in an FMU's vendor annotation."""
    return read_fmu(path, need_binary=False)[2]


def _variables(md) -> dict:
    cache = getattr(md, "_cw_vars", None)
    if cache is None:
        cache = {v.name: v for v in md.modelVariables}
        try:
            md._cw_vars = cache
        except AttributeError:
            pass
    return cache


def var_unit(v) -> str | None:
    u = v.unit or (v.declaredType.unit if v.declaredType is not None else None)
    return u or None


def _var_limit(v, which: str):
    x = getattr(v, which)
    if x is None and v.declaredType is not None:
        x = getattr(v.declaredType, which, None)
    if x is None:
        return None
    return int(x) if v.type in ("Integer", "Enumeration") else float(x)


# ---------------------------------------------------------------------------
# Error helpers


def _show(value: object, limit: int = 60) -> str:
    """A value written as in TOML (for messages)."""
    if isinstance(value, bool):
        s = "true" if value else "false"
    elif isinstance(value, str):
        s = json.dumps(value, ensure_ascii=False)
    elif isinstance(value, float):
        s = fmt(value) if math.isfinite(value) else ("nan" if math.isnan(value) else ("inf" if value > 0 else "-inf"))
    elif isinstance(value, (int,)):
        s = str(value)
    elif isinstance(value, list):
        s = "[" + ", ".join(_show(x, limit) for x in value) + "]"
    elif isinstance(value, dict):
        s = "{" + ", ".join(f"{k} = {_show(x, limit)}" for k, x in value.items()) + "}"
    else:
        s = str(value)
    return s if len(s) <= limit else s[: limit - 3] + "..."


_MISSING = object()


class _Ctx:
    def __init__(self, path: Path, labels: dict[str, str]):
        self.path = path
        self.labels = labels  # dotted key -> "--set x.y" for overridden keys

    def key(self, key: str) -> str:
        return self.labels.get(key, key)

    def fail(self, key: str, detail: str) -> SceneError:
        return SceneError(detail, self.path, self.key(key))

    def bad(self, key: str, value: object, expected: str) -> SceneError:
        return SceneError(f"expected {expected}", self.path, f"{self.key(key)} = {_show(value)}")

    def check_keys(self, table: dict, allowed, where: str, required=()) -> None:
        allowed = list(allowed)
        for k in table:
            if k not in allowed:
                full = f"{where}.{k}" if where else k
                close = difflib.get_close_matches(k, allowed, n=1)
                hint = f" (did you mean {close[0]}?)" if close else ""
                extra = ""
                if k in _TOP_KEYS and where:
                    extra = f"; top-level key `{k}` must come before the first [table] header"
                allowed_s = ", ".join(sorted(allowed)) if allowed else "none"
                raise self.fail(full, f"unknown key{hint}; allowed: {allowed_s}{extra}")
        for k in required:
            if k not in table:
                if where:
                    raise self.fail(f"{where}.{k}", "missing required key")
                header = "components.<instance>" if k == "components" else k
                raise self.fail(k, f"missing required table [{header}]")

    def table(self, parent: dict, k: str, where: str, required: bool = False) -> dict | None:
        full = f"{where}.{k}" if where else k
        if k not in parent:
            if required:
                raise self.fail(full, "missing required table")
            return None
        t = parent[k]
        if not isinstance(t, dict):
            raise self.bad(full, t, "a table")
        return t

    def time(self, key: str, value: object) -> float:
        try:
            return to_seconds(value)
        except UnitError as e:
            raise self.bad(key, value, str(e)) from None


_TOP_KEYS = ("scene", "components", "connections", "experiment", "master", "record", "analysis", "sweep", "plot")
_OVERRIDABLE = ("scene", "experiment", "master", "record", "analysis")
_MASTER_DEFAULTS = {f.name: f.default for f in dataclasses.fields(MasterConfig)}


# ---------------------------------------------------------------------------
# Loading


def parse_override(text: str) -> tuple[str, str, object]:
    """'a.b=value' -> ('a', 'b', value); the value is TOML if it parses, else a bare string."""
    if "=" not in text:
        raise ValueError(f"--set {text}: expected instance.parameter=value (or master.key=value)")
    lhs, rhs = text.split("=", 1)
    lhs = lhs.strip()
    m = re.match(r"^([A-Za-z_][A-Za-z0-9_]*)\.([A-Za-z_][A-Za-z0-9_]*)$", lhs)
    if not m:
        raise ValueError(f"--set {text}: expected instance.parameter=value, got the key {lhs!r}")
    try:
        value = tomllib.loads("v = " + rhs)["v"]
    except tomllib.TOMLDecodeError:
        value = rhs.strip()
    return m.group(1), m.group(2), value


def load_scene(path: str | os.PathLike, overrides=()) -> Scene:
    """Load, override and validate a scene file; raises SceneError."""
    from . import analyses, plots  # noqa: F401  (register their kinds first)

    path = Path(path)
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise SceneError("no such scene file", path) from None
    except IsADirectoryError:
        raise SceneError("is a directory, expected a .toml scene file", path) from None
    except OSError as e:
        raise SceneError(f"cannot read: {e.strerror}", path) from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as e:
        raise SceneError(f"not UTF-8 text (byte {e.start})", path) from None
    try:
        raw = tomllib.loads(text)
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
    for text_ov in overrides:
        try:
            owner, name, value = parse_override(text_ov)
        except ValueError as e:
            raise SceneError(str(e), path) from None
        applied.append(text_ov)
        label = f"--set {owner}.{name}"
        if owner in _OVERRIDABLE:
            sect = raw.setdefault(owner, {})
            if not isinstance(sect, dict):
                raise SceneError(f"[{owner}] is not a table in the file", path, label)
            sect[name] = value
            labels[f"{owner}.{name}"] = label
            continue
        comps = raw.get("components")
        if owner in _TOP_KEYS:
            raise SceneError(
                f"cannot be set from the command line; settable: <instance>.<parameter>, "
                f"{', '.join(s + '.<key>' for s in _OVERRIDABLE)}", path, label)
        if not isinstance(comps, dict) or owner not in comps or not isinstance(comps[owner], dict):
            names = list(comps) if isinstance(comps, dict) else []
            close = difflib.get_close_matches(owner, names + list(_OVERRIDABLE), n=1)
            hint = f" (did you mean {close[0]}?)" if close else ""
            raise SceneError(
                f"no component named {owner}{hint}; components: {', '.join(names) or 'none'}", path, label)
        params = comps[owner].setdefault("parameters", {})
        if not isinstance(params, dict):
            raise SceneError(f"components.{owner}.parameters is not a table in the file", path, label)
        params[name] = value
        labels[f"components.{owner}.parameters.{name}"] = label

    ctx = _Ctx(path, labels)
    return _build(ctx, raw, tuple(applied), hashlib.sha256(data).hexdigest())


def _build(ctx: _Ctx, raw: dict, overrides: tuple[str, ...], digest: str) -> Scene:
    ctx.check_keys(raw, _TOP_KEYS, "", required=("scene", "components", "experiment"))

    scene_t = ctx.table(raw, "scene", "", required=True)
    ctx.check_keys(scene_t, ("title", "description", "reproduces"), "scene", required=("title",))
    for k in ("title", "description", "reproduces"):
        if k in scene_t and not isinstance(scene_t[k], str):
            raise ctx.bad(f"scene.{k}", scene_t[k], "a string")
    if not scene_t["title"].strip():
        raise ctx.bad("scene.title", scene_t["title"], "a non-empty title")

    components, input_params = _components(ctx, ctx.table(raw, "components", "", required=True))
    connections = _connections(ctx, raw.get("connections", []), components, input_params)
    experiment = _experiment(ctx, ctx.table(raw, "experiment", "", required=True))
    master, max_step_given = _master(ctx, ctx.table(raw, "master", "") or {})
    problem = _consistency(master, experiment)
    if problem:
        raise ctx.fail(*problem)
    record = _record(ctx, ctx.table(raw, "record", ""), components)
    analysis = _analysis(ctx, ctx.table(raw, "analysis", ""))
    connected_inputs = {(c.dst_instance, c.dst_var) for c in connections}
    sweep = _sweep(ctx, ctx.table(raw, "sweep", ""), components, connected_inputs)
    plots = _plots(ctx, raw.get("plot", []))

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
    )
    if sweep and any(a.parameter[0] in ("master", "experiment") for a in sweep.axes):
        for point in sweep.points():
            try:
                scene.variant(point)
            except SceneError as e:
                raise ctx.fail("sweep", f"a sweep point is inconsistent: {e.key}: {e.detail}") from None
    return scene


def _components(ctx: _Ctx, table: dict) -> tuple[dict[str, Component], set]:
    if not table:
        raise ctx.fail("components", "expected at least one [components.<instance>] table")
    out: dict[str, Component] = {}
    input_params = set()
    for name, t in table.items():
        where = f"components.{name}"
        if not NAME_RE.match(name):
            raise ctx.fail(where, "expected an instance name matching [A-Za-z_][A-Za-z0-9_]*")
        if name in _TOP_KEYS:
            raise ctx.fail(where, f"the instance name {name} is reserved (it names a scene section)")
        if not isinstance(t, dict):
            raise ctx.bad(where, t, f"a table [components.{name}] with keys fmu, parameters")
        ctx.check_keys(t, ("fmu", "parameters"), where, required=("fmu",))
        spec = t["fmu"]
        if not isinstance(spec, str):
            raise ctx.bad(f"{where}.fmu", spec, "a model name or a path ending .fmu")
        try:
            fpath = resolve_fmu(spec, ctx.path.parent)
            md, digest, indicators = read_fmu(fpath)
        except FmuError as e:
            raise ctx.fail(f"{where}.fmu", str(e)) from None
        params_t = ctx.table(t, "parameters", where) or {}
        params = {}
        variables = _variables(md)
        for pname, value in params_t.items():
            key = f"{where}.parameters.{pname}"
            v = _lookup(ctx, key, variables, pname, name, md.modelName, want="parameter")
            if v.causality == "input":
                input_params.add((name, pname, key))
            elif v.causality != "parameter":
                raise ctx.fail(
                    key, f"{md.modelName}.{pname} is {_article(v.causality)} {v.causality}, not a parameter; "
                    f"parameters: {', '.join(_names(variables, 'parameter'))}")
            params[pname] = _convert_value(ctx, key, value, v, md)
        out[name] = Component(name, fpath, digest, md, params, indicators)
    return out, input_params


def _article(word: str) -> str:
    return "an" if word[:1] in "aeiou" else "a"


def _names(variables: dict, *causalities: str) -> list[str]:
    return [n for n, v in variables.items() if v.causality in causalities]


def _lookup(ctx: _Ctx, key: str, variables: dict, name: str, instance: str, model: str, want: str):
    v = variables.get(name)
    if v is None:
        close = difflib.get_close_matches(name, list(variables), n=3)
        hint = f" (did you mean {' or '.join(close)}?)" if close else ""
        if want == "parameter":
            pool = _names(variables, "parameter")
            listing = f"; parameters: {', '.join(pool)}"
        else:
            listing = ""
        raise ctx.fail(key, f"{instance} ({model}) has no variable {name}{hint}{listing}")
    return v


def _convert_value(ctx: _Ctx, key: str, value: object, v, md):
    """A TOML value -> the variable's type and unit, range-checked."""
    unit = var_unit(v)
    if v.type == "Real":
        try:
            x = to_unit(value, md, unit)
        except UnitError as e:
            raise ctx.bad(key, value, str(e)) from None
    elif v.type in ("Integer", "Enumeration"):
        if isinstance(value, bool) or not isinstance(value, int):
            raise ctx.bad(key, value, "an integer")
        x = value
    elif v.type == "Boolean":
        if not isinstance(value, bool):
            raise ctx.bad(key, value, "true or false")
        return value
    elif v.type == "String":
        if not isinstance(value, str):
            raise ctx.bad(key, value, "a string")
        return value
    else:
        raise ctx.fail(key, f"variables of type {v.type} cannot be set")
    lo, hi = _var_limit(v, "min"), _var_limit(v, "max")
    if (lo is not None and x < lo) or (hi is not None and x > hi):
        u = f" {unit}" if unit else ""
        if lo is not None and hi is not None:
            expected = f"a value in [{fmt(lo)}, {fmt(hi)}]{u}"
        elif lo is not None:
            expected = f"a value >= {fmt(lo)}{u}"
        else:
            expected = f"a value <= {fmt(hi)}{u}"
        if isinstance(value, str) and parse_quantity(value)[1] not in (None, unit):
            expected += f" (got {fmt(x)}{u})"
        raise ctx.bad(key, value, expected)
    return x


def _connections(ctx: _Ctx, conns, components: dict[str, Component], input_params: set) -> tuple[Connection, ...]:
    if not isinstance(conns, list):
        raise ctx.bad("connections", conns, 'an array of "src.output -> dst.input" strings')
    out = []
    seen: dict[tuple[str, str], int] = {}
    set_inputs = {(inst, var): key for inst, var, key in input_params}
    checked = []
    for i, c in enumerate(conns):
        key = f"connections[{i}]"
        if not isinstance(c, str):
            raise ctx.bad(key, c, 'a string "src.output -> dst.input"')
        m = _CONN_RE.match(c)
        if not m:
            raise ctx.bad(key, c, 'a string "src.output -> dst.input"')
        si, sv, di, dv = m.groups()
        ends = []
        for inst, var in ((si, sv), (di, dv)):
            comp = components.get(inst)
            if comp is None:
                close = difflib.get_close_matches(inst, list(components), n=1)
                hint = f" (did you mean {close[0]}?)" if close else ""
                raise ctx.fail(key, f"no component named {inst}{hint}; components: {', '.join(components)}")
            variables = _variables(comp.model_description)
            ends.append((comp, _lookup(ctx, key, variables, var, inst, comp.model_name, want="any")))
        (sc, s), (dc, d) = ends
        if s.causality != "output":
            what = "an input used as a source" if s.causality == "input" else f"{_article(s.causality)} {s.causality}"
            raise ctx.fail(key, f"{si}.{sv} is {what}; expected an output on the left of ->; outputs: "
                                f"{', '.join(_names(_variables(sc.model_description), 'output'))}")
        if d.causality != "input":
            what = "an output connected to an output" if d.causality == "output" else f"{_article(d.causality)} {d.causality}"
            raise ctx.fail(key, f"{di}.{dv} is {what}; expected an input on the right of ->; inputs: "
                                f"{', '.join(_names(_variables(dc.model_description), 'input'))}")
        if (di, dv) in seen:
            raise ctx.fail(key, f"input {di}.{dv} is connected twice (also by connections[{seen[(di, dv)]}])")
        if (di, dv) in set_inputs:
            raise ctx.fail(key, f"input {di}.{dv} is connected and also set in {set_inputs[(di, dv)]}")
        seen[(di, dv)] = i
        checked.append((key, si, sv, di, dv, sc, s, dc, d))
    # Structure first (names, directions, duplicates), then types and units.
    for key, si, sv, di, dv, sc, s, dc, d in checked:
        if s.type != d.type:
            raise ctx.fail(key, f"type mismatch: {si}.{sv} is {s.type}, {di}.{dv} is {d.type}")
        su, du = var_unit(s), var_unit(d)
        # Strict by name: the master passes numbers on unconverted, and J into N.m is a modelling slip.
        if su != du:
            raise ctx.fail(key, f"unit mismatch: {si}.{sv} is in {su or 'no unit (dimensionless)'}, "
                                f"{di}.{dv} in {du or 'no unit (dimensionless)'}")
        out.append(Connection(si, sv, di, dv))
    return tuple(out)


def _experiment(ctx: _Ctx, t: dict) -> Experiment:
    ctx.check_keys(t, ("start", "stop"), "experiment", required=("stop",))
    start = ctx.time("experiment.start", t.get("start", 0.0))
    stop = ctx.time("experiment.stop", t["stop"])
    if not stop > start:
        raise ctx.bad("experiment.stop", t["stop"], f"a time > experiment.start ({fmt(start)} s)")
    return Experiment(start, stop)


def _master_value(ctx: _Ctx, key: str, value: object):
    full = f"master.{key}"
    if key in ("step", "min_step", "max_step", "event_time_tolerance"):
        x = ctx.time(full, value)
        if not x > 0:
            raise ctx.bad(full, value, "a time > 0")
        return x
    if key == "order":
        if value not in ("gauss-seidel", "jacobi"):
            raise ctx.bad(full, value, '"gauss-seidel" or "jacobi"')
        return value
    if key == "extrapolation":
        if isinstance(value, bool) or value not in (0, 1, 2) or not isinstance(value, int):
            raise ctx.bad(full, value, "0, 1 or 2 (order of the input extrapolation polynomial)")
        return value
    if key in ("event_location", "richardson"):
        if not isinstance(value, bool):
            raise ctx.bad(full, value, "true or false")
        return value
    if key == "iterations":
        if isinstance(value, bool) or not isinstance(value, int) or value < 0:
            raise ctx.bad(full, value, "an integer >= 0 (0 = no fixed-point iteration)")
        return value
    # the remaining tolerances are bare positive numbers
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
        raise ctx.bad(full, value, "a number > 0")
    return float(value)


def _master(ctx: _Ctx, t: dict) -> tuple[MasterConfig, bool]:
    ctx.check_keys(t, _MASTER_DEFAULTS, "master")
    values = dict(_MASTER_DEFAULTS)
    for k, v in t.items():
        values[k] = _master_value(ctx, k, v)
    if "max_step" not in t:
        values["max_step"] = values["step"]
    return MasterConfig(**values), "max_step" in t


def _parse_ref(ctx: _Ctx, key: str, ref: object, components: dict[str, Component], what: str):
    if not isinstance(ref, str) or not _REF_RE.match(ref):
        raise ctx.bad(key, ref, f'"instance.variable" naming {what}')
    inst, var = ref.strip().split(".", 1)
    comp = components.get(inst)
    if comp is None:
        close = difflib.get_close_matches(inst, list(components), n=1)
        hint = f" (did you mean {close[0]}?)" if close else ""
        raise ctx.fail(key, f"no component named {inst}{hint}; components: {', '.join(components)}")
    variables = _variables(comp.model_description)
    v = _lookup(ctx, key, variables, var, inst, comp.model_name, want="parameter" if what == "a parameter" else "any")
    return comp, v


def _record(ctx: _Ctx, t: dict | None, components: dict[str, Component]) -> Record:
    t = t or {}
    ctx.check_keys(t, ("outputs", "interval", "ticks"), "record")
    if "outputs" in t:
        refs = t["outputs"]
        if not isinstance(refs, list):
            raise ctx.bad("record.outputs", refs, 'an array of "instance.variable" strings')
        outputs = []
        for i, ref in enumerate(refs):
            key = f"record.outputs[{i}]"
            comp, v = _parse_ref(ctx, key, ref, components, "a variable")
            if v.causality not in ("output", "input", "parameter", "calculatedParameter"):
                raise ctx.fail(key, f"{ref} is {_article(v.causality)} {v.causality} variable; "
                                    "expected an output, input or parameter")
            pair = (comp.name, v.name)
            if pair in outputs:
                raise ctx.fail(key, f"{ref} is listed twice")
            outputs.append(pair)
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
        variables = _variables(components[ticks].model_description)
        for need in ("tick_time", "tick_count"):
            if need not in variables or variables[need].causality != "output":
                raise ctx.bad("record.ticks", ticks, "a component with tick_time and tick_count outputs (a Pendulum)")
    return Record(tuple(outputs), interval, ticks)


def _kind_table(ctx: _Ctx, t: dict, where: str, registry: dict, converters: dict) -> dict:
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


def _analysis(ctx: _Ctx, t: dict | None) -> dict | None:
    if t is None:
        return None
    return _kind_table(ctx, t, "analysis", ANALYSIS_KEYS, _ANALYSIS_CONVERT)


def _plots(ctx: _Ctx, plots) -> tuple[dict, ...]:
    if not isinstance(plots, list):
        raise ctx.bad("plot", plots, "an array of tables [[plot]]")
    out = []
    for i, t in enumerate(plots):
        if not isinstance(t, dict):
            raise ctx.bad(f"plot[{i}]", t, "a table [[plot]]")
        out.append(_kind_table(ctx, t, f"plot[{i}]", PLOT_KEYS, _PLOT_CONVERT))
    return tuple(out)


_SWEEPABLE_MASTER = ("step", "min_step", "max_step", "extrapolation", "iterations", "iteration_tolerance",
                     "event_time_tolerance", "event_indicator_tolerance", "richardson_tolerance",
                     "order", "event_location", "richardson")


def _sweep(ctx: _Ctx, t: dict | None, components: dict[str, Component], connected: set) -> Sweep | None:
    if t is None:
        return None
    ctx.check_keys(t, ("mode", "axes"), "sweep", required=("axes",))
    mode = t.get("mode", "grid")
    if mode not in ("grid", "zip"):
        raise ctx.bad("sweep.mode", mode, '"grid" or "zip"')
    axes_t = t["axes"]
    if not isinstance(axes_t, list) or not axes_t:
        raise ctx.bad("sweep.axes", axes_t, "a non-empty array of axis tables")
    axes = []
    for i, a in enumerate(axes_t):
        where = f"sweep.axes[{i}]"
        if not isinstance(a, dict):
            raise ctx.bad(where, a, "a table { parameter = ..., values = [...] }")
        ctx.check_keys(a, ("parameter", "values", "start", "stop", "num", "spacing"), where, required=("parameter",))
        pkey = f"{where}.parameter"
        ref = a["parameter"]
        if isinstance(ref, str) and ref.split(".", 1)[0] in ("master", "experiment") and ref.split(".", 1)[0] not in components:
            owner, name = ref.split(".", 1)
            allowed = _SWEEPABLE_MASTER if owner == "master" else ("start", "stop")
            if name not in allowed:
                close = difflib.get_close_matches(name, allowed, n=1)
                hint = f" (did you mean {owner}.{close[0]}?)" if close else ""
                raise ctx.bad(pkey, ref, f"a sweepable {owner} key{hint}: {', '.join(allowed)}")
            if owner == "master":
                def convert(k, x, name=name):
                    return _master_value_at(ctx, k, name, x)
            else:
                def convert(k, x):
                    return ctx.time(k, x)
            param = (owner, name)
            var = None
        else:
            comp, var = _parse_ref(ctx, pkey, ref, components, "a parameter")
            if var.causality not in ("parameter", "input"):
                raise ctx.fail(pkey, f"{ref} is {_article(var.causality)} {var.causality}, not a parameter")
            if var.causality == "input" and (comp.name, var.name) in connected:
                raise ctx.fail(pkey, f"{ref} is a connected input; it cannot be swept")
            md = comp.model_description

            def convert(k, x, var=var, md=md):
                return _convert_value(ctx, k, x, var, md)
            param = (comp.name, var.name)
        if param in [ax.parameter for ax in axes]:
            raise ctx.fail(pkey, f"{ref} is swept twice")
        has_values = "values" in a
        has_range = any(k in a for k in ("start", "stop", "num", "spacing"))
        if has_values == has_range:
            raise ctx.fail(where, "expected either values = [...] or start, stop, num (and spacing)")
        if has_values:
            vals = a["values"]
            if not isinstance(vals, list) or not vals:
                raise ctx.bad(f"{where}.values", vals, "a non-empty array of values")
            values = tuple(convert(f"{where}.values[{j}]", x) for j, x in enumerate(vals))
        else:
            for k in ("start", "stop", "num"):
                if k not in a:
                    raise ctx.fail(f"{where}.{k}", "missing required key (with start/stop/num)")
            num = a["num"]
            if isinstance(num, bool) or not isinstance(num, int) or num < 1:
                raise ctx.bad(f"{where}.num", num, "an integer >= 1")
            spacing = a.get("spacing", "linear")
            if spacing not in ("linear", "log"):
                raise ctx.bad(f"{where}.spacing", spacing, '"linear" or "log"')
            if var is not None and var.type not in ("Real", "Integer"):
                raise ctx.fail(where, f"{ref} is {var.type}: list its values instead of start/stop/num")
            lo = _range_end(ctx, f"{where}.start", a["start"], var, convert)
            hi = _range_end(ctx, f"{where}.stop", a["stop"], var, convert)
            if spacing == "log" and not (lo > 0 and hi > 0):
                bad_k = "start" if not lo > 0 else "stop"
                raise ctx.bad(f"{where}.{bad_k}", a[bad_k], "a value > 0 for log spacing")
            grid = np.geomspace(lo, hi, num) if spacing == "log" else np.linspace(lo, hi, num)
            if num == 1:
                grid = np.array([lo])
            seq = [float(x) for x in grid]
            if (var is not None and var.type == "Integer") or param in (("master", "iterations"), ("master", "extrapolation")):
                ints = [round(x) for x in seq]
                if any(abs(x - r) > 1e-9 * max(1.0, abs(x)) for x, r in zip(seq, ints)):
                    raise ctx.fail(where, f"{ref} is an integer but start/stop/num give non-integer values {seq}")
                seq = ints
            values = tuple(convert(f"{where}.start", x) for x in seq)
        axes.append(SweepAxis(param, values))
    if mode == "zip":
        n = len(axes[0].values)
        for i, ax in enumerate(axes):
            if len(ax.values) != n:
                raise ctx.fail(f"sweep.axes[{i}]", f"zip mode needs axes of equal length: "
                                                   f"{len(ax.values)} values here, {n} in sweep.axes[0]")
    return Sweep(mode, tuple(axes))


def _master_value_at(ctx: _Ctx, key: str, name: str, value: object):
    """Like _master_value but errors name `key` (a sweep entry) instead of master.<name>."""
    try:
        return _master_value(ctx, name, value)
    except SceneError as e:
        raise SceneError(e.detail, ctx.path, f"{ctx.key(key)} = {_show(value)}") from None


def _range_end(ctx: _Ctx, key: str, value: object, var, convert) -> float:
    """A sweep start/stop in the variable's unit (validated against its range)."""
    x = convert(key, value)
    if isinstance(x, bool) or not isinstance(x, (int, float)):
        raise ctx.bad(key, value, "a number")
    return float(x)
