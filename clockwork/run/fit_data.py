"""What `clockwork fit` reads: the measurements (a CSV file) and the free
parameters (``--free NAME[=GUESS]``), checked against the scene.

The data file has one row per measured condition. A column is, by its
header (its name, then optionally a unit in square brackets,
``escapement.torque [N.cm]``):

- a scene parameter ``instance.variable`` (a parameter or an unconnected
  input): it sets that parameter for the row; the unit is the bracket's,
  converted with the FMU's unit definitions (clockwork.scene.units), else
  the variable's own;
- a result column of the scene's analysis (``amplitude_deg``,
  ``E_T_s_per_day``): a measurement of it, in the unit its name ends with
  (a bracket may repeat that unit; an angle may be given in rad);
- ``sigma_<column>``: the standard uncertainty of that measurement, in its
  unit;
- a timer's column (case-insensitive): ``time``, ``date``, ``timestamp``,
  ``datetime`` or ``elapsed`` labels the row and is not read as a number;
  ``rate`` is the daily rate a timer shows, s/day, positive when the clock
  gains, so it measures -E_T_s_per_day; ``amplitude`` is amplitude_deg
  (deg, or a bracket [rad]); ``pressure`` (hPa unless a bracket says
  otherwise) sets the Air component's pressure; ``temperature`` (degC unless
  a bracket says otherwise) sets the Air component's temperature and the
  Pendulum's rod temperature where that input is not connected.

An empty measurement cell is a condition where that quantity was not
measured; every other cell must be a decimal number.
"""

from __future__ import annotations

import csv
import difflib
import hashlib
import io
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..analyses import registry
from ..analyses.context import parameters
from ..fmi.description import REAL_TYPES, var_limit, var_unit, variables as variables_of
from ..engine.names import split_ref
from ..errors import SceneError, UsageError
from ..files import NotRegularFile, read_regular
from ..numbers import parse_real, shorten
from ..results.plots.registry import unit_of
from ..scene.model import ComponentVariables
from ..scene.units import UnitError, apply_conversion, fmt, parse_quantity, unit_conversions

MAX_DATA_BYTES = 1 << 24  # 16 MiB: a timer's log of years, far more rows than a fit can use
MAX_ROWS = 100_000
NOT_MEASURABLE = frozenset({"stalled", "reason", "engine", "engine_reason", "notes", "ended"})  # no numbers
TIME_WORDS = ("time", "date", "timestamp", "datetime", "elapsed", "elapsed time")
_HEADER = re.compile(r"^(.*?)\s*\[([^\[\]]*)\]\s*$")
# A result column's unit (the tail of its name) and the other spellings a bracket may give it in.
_RESULT_UNITS = {"deg": {"deg": 1.0, "rad": 180.0 / math.pi, "mrad": 0.18 / math.pi}}


@dataclass(frozen=True)
class Target:
    """A settable Real variable of the scene."""

    instance: str
    variable: str
    unit: str | None
    lo: float | None
    hi: float | None
    model_description: object = field(repr=False, compare=False)

    @property
    def name(self) -> str:
        return f"{self.instance}.{self.variable}"

    @property
    def key(self) -> tuple[str, str]:
        return self.instance, self.variable

    def convert(self, x: float, unit: str | None) -> float:
        """`x` given in `unit` (None: the variable's own) into the variable's unit; UnitError."""
        if unit is None or unit == self.unit:
            return x
        if not self.unit:
            raise UnitError("no unit (the variable is dimensionless)")
        conv = unit_conversions(self.model_description, self.unit)
        if unit not in conv:
            raise UnitError(f"a unit of {self.unit}: one of {', '.join(conv)}")
        return apply_conversion(conv[unit], x)

    def range_text(self) -> str:
        u = f" {self.unit}" if self.unit else ""
        return f"[{fmt(self.lo)}, {fmt(self.hi)}]{u}" if self.lo is not None and self.hi is not None else \
            (f">= {fmt(self.lo)}{u}" if self.lo is not None else f"<= {fmt(self.hi)}{u}")


@dataclass
class Data:
    """The rows of a data file, checked and converted."""

    path: Path
    sha256: str
    lines: list[int]  # the file's line number of each row
    labels: list[str] | None  # the time column's text, or None
    settings: list[dict]  # per row: {(instance, variable): value in the variable's unit}
    set_columns: dict[str, str]  # parameter name -> the header that sets it
    measured: dict[str, np.ndarray]  # result column -> values per row (nan: not measured)
    sigma: dict[str, np.ndarray]  # result column -> standard uncertainty per row (only where given)
    headers: dict[str, str]  # result column -> the header it was read from
    signs: dict[str, float] = field(default_factory=dict)  # result column -> +1, or -1 for a timer's rate

    @property
    def rows(self) -> int:
        return len(self.lines)


def settable(scene, ref: str) -> Target | None:
    """The scene's Real parameter or unconnected input `ref` ("instance.variable"), else None."""
    split = split_ref(ref, ComponentVariables(scene.components))
    if split is None:
        return None
    inst, name = split
    comp = scene.components[inst]
    v = variables_of(comp.model_description).get(name)
    if v is None or v.causality not in ("parameter", "input"):
        return None
    if v.causality == "input" and any((c.dst_instance, c.dst_var) == (inst, name) for c in scene.connections):
        return None
    if v.type not in REAL_TYPES or getattr(v, "shape", None):
        return None
    return Target(inst, name, var_unit(v), var_limit(v, "min"), var_limit(v, "max"), comp.model_description)


def result_columns(scene) -> frozenset[str] | None:
    """Every column the scene's analysis declares for its results, or None."""
    declared = registry._declared(registry.RESULT_COLUMNS, scene)
    return None if declared is None else declared - NOT_MEASURABLE


def _why_not_settable(scene, ref: str) -> str:
    split = split_ref(ref, ComponentVariables(scene.components))
    if split is None:
        return ""
    inst, name = split
    v = variables_of(scene.components[inst].model_description).get(name)
    if v is None:
        return ""
    if v.causality == "input":
        return f" ({ref} is a connected input: the connection sets it)"
    if v.causality not in ("parameter", "input"):
        return f" ({ref} is {'an' if v.causality[0] in 'aeiou' else 'a'} {v.causality}, not a parameter)"
    return f" ({ref} is of type {v.type}: only Real parameters are fitted and set)"


def _settable_names(scene) -> list[str]:
    """"instance.variable" of every Real parameter of the scene (for a hint)."""
    return [f"{i}.{v}" for i, c in scene.components.items() for v, var in variables_of(c.model_description).items()
            if var.causality == "parameter" and var.type in REAL_TYPES]


def _component(scene, model: str) -> str | None:
    return next((n for n, c in scene.components.items() if c.model_description.modelName == model), None)


def _timer_targets(scene, word: str) -> list[Target]:
    found = []
    if word == "pressure":
        air = _component(scene, "Air")
        if air is not None:
            found.append(settable(scene, f"{air}.pressure"))
    else:  # temperature: the room's, so the air's and the rod's
        for model in ("Air", "Pendulum"):
            inst = _component(scene, model)
            if inst is not None:
                found.append(settable(scene, f"{inst}.temperature"))
    return [t for t in found if t is not None]


def read_data(scene, path: str | Path) -> Data:
    """The data file at `path`, checked against `scene`; SceneError naming the file and the column or line."""
    path = Path(path)
    try:
        raw = read_regular(path, "a CSV data file", MAX_DATA_BYTES)
    except NotRegularFile as e:
        raise SceneError(e.detail, path) from None
    except FileNotFoundError:
        raise SceneError("no such data file", path) from None
    except OSError as e:
        raise SceneError(f"cannot read: {e.strerror}", path) from None
    digest = hashlib.sha256(raw).hexdigest()
    if raw.startswith(b"\xef\xbb\xbf"):  # a byte order mark (spreadsheets write one)
        raw = raw[3:]
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as e:
        raise SceneError(f"not UTF-8 text (byte {e.start})", path) from None
    try:
        records = [(k, row) for k, row in _records(text)]
    except csv.Error as e:
        raise SceneError(f"malformed CSV: {e}", path) from None
    if not records:
        raise SceneError("empty: expected a header line (parameters, measurements) and one row per measured "
                         "condition", path)
    header_line, header = records[0]
    rows = records[1:]
    if not rows:
        raise SceneError("no data rows: expected one row per measured condition after the header line", path)
    if len(rows) > MAX_ROWS:
        raise SceneError(f"{len(rows)} rows: a data file has at most {MAX_ROWS}", path)
    return _parse(scene, path, digest, header_line, [h.strip() for h in header], rows)


def _records(text: str):
    """(line number, cells) of each line that is neither blank nor a comment."""
    for k, line in enumerate(io.StringIO(text, newline=None), start=1):
        line = line.rstrip("\r\n")
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        yield k, next(csv.reader([line], strict=True))


def _split_header(header: str) -> tuple[str, str | None]:
    m = _HEADER.match(header)
    if m:
        return m.group(1).strip(), m.group(2).strip() or None
    return header, None


def _parse(scene, path: Path, digest: str, header_line: int, header: list[str], rows: list) -> Data:
    def fail(j: int | None, detail: str, line: int | None = None) -> SceneError:
        where = []
        if line is not None:
            where.append(f"line {line}")
        if j is not None:
            where.append(f"column {shorten(header[j], 60)}")
        return SceneError(detail, path, ", ".join(where) or None)

    if len(header) == 1 and (";" in header[0] or "\t" in header[0]):
        raise fail(None, "one column only: expected comma-separated values", header_line)
    declared = result_columns(scene)
    if not declared:
        kind = (scene.analysis or {}).get("kind", "time_series")
        raise SceneError(f"the analysis {kind} declares no result columns to fit to: expected a scene with a "
                         "steady-state analysis (kind = \"steady_state\", or one of the clock-in-air kinds)",
                         scene.path, "analysis.kind")
    label_col = None
    params: dict[int, tuple[list[Target], str | None]] = {}  # column -> (targets, unit)
    meas: dict[int, tuple[str, float, float]] = {}  # column -> (result column, factor, sign)
    sig: dict[int, tuple[str, float]] = {}  # column -> (result column, factor)
    sig_names: dict[int, str] = {}
    seen: dict[str, int] = {}
    for j, h in enumerate(header):
        name, unit = _split_header(h)
        if not name:
            raise fail(j, "an empty column name: expected a scene parameter (instance.variable), a result "
                          "column of the analysis or sigma_<column>", header_line)
        if name in seen:
            raise fail(j, f"{name} is given twice (also column {seen[name] + 1})", header_line)
        seen[name] = j
        word = name.lower()
        if word in TIME_WORDS:
            if label_col is not None:
                raise fail(j, f"a second time column (the first is {header[label_col]})", header_line)
            label_col = j
            continue
        if name.startswith("sigma_"):
            sig_names[j] = name[len("sigma_"):]
            continue
        column = _measured_name(name, word, declared)
        if column is not None:
            meas[j] = (column, _result_factor(fail, j, header_line, column, unit), -1.0 if word == "rate" else 1.0)
            continue
        target = settable(scene, name) if "." in name else None
        if target is not None:
            params[j] = ([target], unit)
            continue
        if word in ("pressure", "temperature"):
            targets = _timer_targets(scene, word)
            if not targets:
                raise fail(j, f"a timer's {word} column sets the Air component's {word}: this scene has no "
                              f"settable {word} (no Air component, or its input is connected)", header_line)
            params[j] = (targets, unit if unit is not None else ("hPa" if word == "pressure" else "degC"))
            continue
        why = _why_not_settable(scene, name) if "." in name else ""
        known = sorted(declared) + _settable_names(scene)
        close = difflib.get_close_matches(name, known, n=1) if len(name) <= 200 else []
        hint = f" (did you mean {close[0]}?)" if close else ""
        raise fail(j, f"names no settable parameter of the scene and no result column of its analysis{why}{hint}: "
                      f"expected instance.variable, one of {', '.join(sorted(declared))}, sigma_<column>, or a "
                      "timer's time, rate, amplitude, pressure or temperature", header_line)
    if not meas:
        raise fail(None, "no measured column: expected at least one result column of the analysis "
                         f"({', '.join(sorted(declared))}) or a timer's rate or amplitude", header_line)
    by_column = {c: j for j, (c, _, _) in meas.items()}
    if len(by_column) != len(meas):
        twice = next(c for c in by_column if sum(1 for m in meas.values() if m[0] == c) > 1)
        raise fail(None, f"{twice} is measured by two columns: expected one", header_line)
    for j, target_name in sig_names.items():
        word = target_name.lower()
        column = _measured_name(target_name, word, declared)
        if column is None or column not in by_column:
            raise fail(j, f"the uncertainty of {shorten(target_name, 60)}, which no column of this file measures: "
                          f"expected sigma_<column> for one of {', '.join(header[k] for k in meas)}", header_line)
        _, unit = _split_header(header[j])
        sig[j] = (column, _result_factor(fail, j, header_line, column, unit))
    sigma_of = {c for c, _ in sig.values()}
    if sigma_of and sigma_of != set(by_column):
        missing = sorted(set(by_column) - sigma_of)
        raise fail(by_column[missing[0]], f"has no sigma_ column while {', '.join(sorted(sigma_of))} has one: give "
                                          "an uncertainty for every measured column or for none (then the scale "
                                          "comes from the residuals)", header_line)
    set_columns: dict[str, str] = {}
    for j, (targets, _) in params.items():
        for t in targets:
            if t.name in set_columns:
                raise fail(j, f"sets {t.name}, which column {set_columns[t.name]} sets too", header_line)
            set_columns[t.name] = header[j]

    lines, labels, settings = [], [], []
    measured = {c: [] for c, _, _ in meas.values()}
    sigma = {c: [] for c, _ in sig.values()}
    for k, cells in rows:
        if len(cells) != len(header):
            raise fail(None, f"{len(cells)} values for {len(header)} columns", k)
        lines.append(k)
        if label_col is not None:
            labels.append(cells[label_col].strip())
        row: dict = {}
        for j, (targets, unit) in params.items():
            x = _number(fail, j, k, cells[j], "a number")
            for t in targets:
                try:
                    value = t.convert(x, unit)
                except UnitError as e:
                    raise fail(j, f"{unit}: expected {e}", header_line) from None
                if not math.isfinite(value) or (t.lo is not None and value < t.lo) or \
                        (t.hi is not None and value > t.hi):
                    raise fail(j, f"{shorten(cells[j].strip(), 40)}{f' {unit}' if unit else ''} gives {t.name} = "
                                  f"{fmt(value)}{f' {t.unit}' if t.unit else ''}: expected a value in its range "
                                  f"{t.range_text()}", k)
                row[t.key] = value
        settings.append(row)
        for j, (column, factor, sign) in meas.items():
            cell = cells[j].strip()
            measured[column].append(math.nan if cell == "" else sign * factor * _number(fail, j, k, cell, "a number"))
        for j, (column, factor) in sig.items():
            cell = cells[j].strip()
            given = not math.isnan(measured[column][-1])
            if cell == "":
                if given:
                    raise fail(j, f"empty, while {header[by_column[column]]} is given: expected its standard "
                                  "uncertainty, a number > 0", k)
                sigma[column].append(math.nan)
                continue
            s = factor * _number(fail, j, k, cell, "a standard uncertainty, a number > 0")
            if not s > 0:
                raise fail(j, f"{shorten(cell, 40)}: expected a standard uncertainty, a number > 0", k)
            sigma[column].append(s)
    if not any(not math.isnan(x) for col in measured.values() for x in col):
        raise SceneError("no measured value in any row: every measurement cell is empty", path)
    return Data(path=path, sha256=digest, lines=lines, labels=labels if label_col is not None else None,
                settings=settings, set_columns=set_columns,
                measured={c: np.asarray(v, dtype=float) for c, v in measured.items()},
                sigma={c: np.asarray(v, dtype=float) for c, v in sigma.items()},
                headers={c: header[j] for j, (c, _, _) in meas.items()},
                signs={c: s for c, _, s in meas.values()})


def _measured_name(name: str, word: str, declared: frozenset[str]) -> str | None:
    if name in declared:
        return name
    if word == "rate" and "E_T_s_per_day" in declared:
        return "E_T_s_per_day"
    if word == "amplitude" and "amplitude_deg" in declared:
        return "amplitude_deg"
    return None


def _result_factor(fail, j: int, line: int, column: str, unit: str | None) -> float:
    """The factor from a bracket's `unit` to the unit `column`'s name ends with."""
    own = unit_of(column)
    if unit is None or unit == own:
        return 1.0
    factors = _RESULT_UNITS.get(own or "", {})
    if unit in factors:
        return factors[unit]
    allowed = ", ".join([own] + [u for u in factors if u != own]) if own else "none (the column is dimensionless)"
    raise fail(j, f"[{unit}]: expected the unit of {column}: {allowed}", line)


def _number(fail, j: int, line: int, cell: str, what: str) -> float:
    cell = cell.strip()
    try:
        x = parse_real(cell)
    except ValueError:
        raise fail(j, f"expected {what}, got {shorten(cell, 40)!r}", line) from None
    if not math.isfinite(x):
        raise fail(j, f"expected {what}, got {shorten(cell, 40)!r}", line)
    return x


@dataclass(frozen=True)
class Free:
    """A parameter to fit: its target, first guess and bounds (in the variable's unit)."""

    target: Target
    guess: float
    lo: float
    hi: float

    @property
    def name(self) -> str:
        return self.target.name


def parse_free(scene, specs: list[str], data: Data) -> list[Free]:
    """``--free NAME[=GUESS]`` arguments, checked; UsageError naming the argument."""
    if not specs:
        raise UsageError("fit: expected at least one --free NAME[=GUESS]")
    current = parameters(scene)
    out: list[Free] = []
    for spec in specs:
        name, eq, guess_text = spec.partition("=")
        name = name.strip()
        shown = shorten(spec, 80)
        target = settable(scene, name)
        if target is None:
            why = _why_not_settable(scene, name)
            close = difflib.get_close_matches(name, _settable_names(scene), n=1) if len(name) <= 200 else []
            hint = f" (did you mean {close[0]}?)" if close else ""
            raise UsageError(f"--free {shown}: names no Real parameter of the scene{why}{hint}: expected "
                             "instance.variable of a parameter with a declared range")
        if any(f.name == target.name for f in out):
            raise UsageError(f"--free {shown}: {target.name} is freed twice")
        if target.name in data.set_columns:
            raise UsageError(f"--free {shown}: {target.name} is set row by row by the data file's column "
                             f"{data.set_columns[target.name]}: a parameter is either measured or fitted")
        if target.lo is None or target.hi is None:
            missing = " and ".join(w for w, x in (("min", target.lo), ("max", target.hi)) if x is None)
            raise UsageError(f"--free {shown}: {target.name} declares no range (no {missing} in "
                             f"{scene.components[target.instance].model_name}'s modelDescription.xml): a fitted "
                             "parameter must have a declared range to search within")
        if eq:
            try:
                number, unit = parse_quantity(guess_text.strip())
                guess = target.convert(number, unit)
            except UnitError as e:
                raise UsageError(f"--free {shown}: expected a guess: {e}") from None
        else:
            guess = float(current[target.instance][target.variable])
        if not (math.isfinite(guess) and target.lo <= guess <= target.hi):
            raise UsageError(f"--free {shown}: the guess {fmt(guess)}{f' {target.unit}' if target.unit else ''} "
                             f"is outside {target.name}'s range {target.range_text()}")
        if not target.lo < target.hi:
            raise UsageError(f"--free {shown}: {target.name}'s range {target.range_text()} leaves nothing to fit")
        out.append(Free(target, guess, target.lo, target.hi))
    return out

