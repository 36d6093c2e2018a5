"""Grade a tool's result against a kit case: fmpy's tube plus event times.

The tube is fmpy's cross-check band (``fmpy.cross_check.validate_signal``)
with the case's own width: the band is sampled on the case's output grid
(``num`` = grid points, so its nodes are the reference's samples), has no
horizontal slack (``dx`` = 1 sample) and an absolute half-width (``dy`` =
width / range of the signal). A result passes it when none of its rows on
the grid lies outside (fmpy's own rule lets 10 % of the samples out; with
its default band, 10 % of the range and 20 of 1000 samples wide, a master
that misses every switch passes). Added to it: the tick times and the
escapement switch times found in the result (events.py) against the
reference's, within the case's tolerances, and the number of each.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import UsageError
from ..files import read_regular
from ..numbers import parse_json, shorten
from . import events
from .csvio import Result, read_result


@dataclass
class CaseData:
    """What a case directory holds (or what cases.reference computes)."""

    name: str
    stop: float
    grid: float
    time: np.ndarray
    columns: dict
    ticks: np.ndarray
    switches: np.ndarray
    tolerances: dict  # {"tube": {...}, "ticks_s": x, "switches_s": y}
    phi: str
    w: str
    switch_signal: str | None
    path: str = ""


@dataclass
class Check:
    what: str
    tolerance: float
    worst: float
    ok: bool
    detail: str = ""

    def __post_init__(self):
        # NaN compares false both ways, so a check built on it could pass
        # (a NaN width makes a tube that nothing lies outside): never.
        if not math.isfinite(self.tolerance) or math.isnan(self.worst):
            self.ok = False


@dataclass
class Grade:
    case: str
    result: str
    rows: int
    grid_rows: int
    checks: list = field(default_factory=list)
    unmatched: list = field(default_factory=list)  # result columns no signal of the case matched
    missing: list = field(default_factory=list)  # signals of the case without a column
    problems: list = field(default_factory=list)  # reasons for failing besides the checks
    missing_why: dict = field(default_factory=dict)

    @property
    def passed(self) -> bool:
        return not self.problems and all(c.ok for c in self.checks)

    def as_dict(self) -> dict:
        def num(x):
            return x if isinstance(x, (int, bool)) or (isinstance(x, float) and math.isfinite(x)) else None

        return {"case": self.case, "result": self.result, "passed": self.passed, "rows": self.rows,
                "grid_rows": self.grid_rows, "unmatched": self.unmatched, "missing": self.missing,
                "problems": self.problems,
                "checks": [{"what": c.what, "tolerance": num(c.tolerance), "worst": num(c.worst), "ok": c.ok,
                            "detail": c.detail} for c in self.checks]}

    def table(self) -> list[str]:
        lines = [f"case {self.case}: {self.result} ({self.rows} rows, {self.grid_rows} on the output grid)"]
        for name in self.unmatched:
            lines.append(f"  unmatched column: {name} (not used: no signal of the case, "
                         "or one of several columns that match one)")
        for name, why in self.missing_why.items():
            lines.append(f"  missing signal: {name} ({why})")
        w = max([len(c.what) for c in self.checks] + [5])
        lines.append(f"  {'check':<{w}}  {'tolerance':>10}  {'worst':>10}  verdict")
        for c in self.checks:
            worst = f"{c.worst:.3g}" if math.isfinite(c.worst) else "inf"
            detail = f"  ({c.detail})" if c.detail else ""
            lines.append(f"  {c.what:<{w}}  {c.tolerance:>10.3g}  {worst:>10}  {'pass' if c.ok else 'FAIL'}{detail}")
        for p in self.problems:
            lines.append(f"  problem: {p}")
        lines.append(f"verdict: {'PASS' if self.passed else 'FAIL'}")
        return lines


# --- the case ---------------------------------------------------------------------


def load_case(spec: str | Path) -> CaseData:
    """A case directory (with <Name>_case.json) or the name of a kit case."""
    from .cases import CASES, case as case_by_name, reference

    path = Path(spec)
    if path.is_dir():
        found = sorted(path.glob("*_case.json"))
        if len(found) != 1:
            raise UsageError(f"{path}: not a case directory (expected one <Name>_case.json)")
        return _read_case(found[0])
    if path.is_file() and path.name.endswith("_case.json"):
        return _read_case(path)
    if str(spec) in CASES:
        c = case_by_name(str(spec))
        ref = reference(c)
        return CaseData(c.name, c.stop, c.grid, ref.time, ref.columns, ref.ticks, ref.switches,
                        {"tube": dict(c.tolerances.tube), "ticks_s": c.tolerances.ticks_s,
                         "switches_s": c.tolerances.switches_s}, c.phi, c.w, c.switch_signal, "(computed)")
    raise UsageError(f"unknown case {str(spec)!r}: neither a case directory nor one of {', '.join(CASES)}")


def _read_case(path: Path) -> CaseData:
    try:
        meta = parse_json(read_regular(path, "a JSON case file"))
    except (OSError, ValueError) as e:
        raise UsageError(f"{path}: not a readable case file: {getattr(e, 'strerror', None) or e}") from None
    field = _CaseField(path, meta)
    name = field.text("name")
    stop, grid = field.positive("stop"), field.positive("grid")
    tube_widths = field.table("tolerances", "tube")
    tolerances = {"tube": {s: field.positive("tolerances", "tube", s) for s in tube_widths},
                  "ticks_s": field.positive("tolerances", "ticks_s"),
                  "switches_s": field.positive("tolerances", "switches_s", optional=True)}
    ticks, switches = field.times("events", "ticks"), field.times("events", "switches", optional=True)
    phi, w = field.text("signals", "phi"), field.text("signals", "w")
    switch = field.text("signals", "switch", optional=True)
    res = read_result(path.parent / field.text("reference"))
    missing = [s for s in tube_widths if s not in res.columns]
    if missing:
        raise UsageError(f"{path}: tolerances.tube.{missing[0]}: the reference {res.source} has no column "
                         f"{missing[0]!r}")
    return CaseData(name=name, stop=stop, grid=grid, time=res.time,
                    columns={s: res.columns[s] for s in tube_widths}, ticks=ticks, switches=switches,
                    tolerances=tolerances, phi=phi, w=w, switch_signal=switch, path=str(path.parent))


class _CaseField:
    """The fields of a case file by their path of keys, each checked for its
    type: one line naming the file, the dotted key and what was expected."""

    def __init__(self, path: Path, meta):
        self.path, self.meta = path, meta

    def get(self, *keys: str, optional: bool = False):
        node = self.meta
        for part in keys:
            if not isinstance(node, dict) or part not in node:
                if optional:
                    return None
                raise UsageError(f"{self.path}: {'.'.join(keys)}: missing: expected a case file of "
                                 "clockwork export-suite")
            node = node[part]
        return node

    def bad(self, keys: tuple, value, expected: str) -> UsageError:
        return UsageError(f"{self.path}: {'.'.join(keys)} = {shorten(json.dumps(value), 80)}: expected {expected}")

    def positive(self, *keys: str, optional: bool = False) -> float | None:
        v = self.get(*keys, optional=optional)
        if v is None and optional:
            return None
        if not _is_number(v) or not v > 0:  # JSON numbers only: "1_0", NaN and infinity never get here
            raise self.bad(keys, v, "a number > 0")
        return float(v)

    def text(self, *keys: str, optional: bool = False) -> str | None:
        v = self.get(*keys, optional=optional)
        if v is None and optional:
            return None
        if not isinstance(v, str) or not v:
            raise self.bad(keys, v, "a non-empty string")
        return v

    def table(self, *keys: str) -> dict:
        v = self.get(*keys)
        if not isinstance(v, dict) or not v:
            raise self.bad(keys, v, "an object {signal: width}")
        return v

    def times(self, *keys: str, optional: bool = False) -> np.ndarray:
        v = self.get(*keys, optional=optional)
        if v is None and optional:
            return np.array([], float)
        if not isinstance(v, list) or not all(_is_number(x) for x in v):
            raise self.bad(keys, v, "a list of times (s)")
        return np.array(v, float)


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


# --- grading ----------------------------------------------------------------------


def _on_grid(t: np.ndarray, grid: float, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Rows of t on the grid k*grid (k = 0..n-1): (row indices, k), first row per k."""
    k = np.rint(t / grid)
    near = np.abs(t - k * grid) <= 1e-6 * grid
    near &= (k >= 0) & (k < n)
    rows = np.nonzero(near)[0]
    ks = k[rows].astype(int)
    _, first = np.unique(ks, return_index=True)
    return rows[first], ks[first]


def tube(t, y, t_ref, y_ref, t_start, t_stop, width) -> tuple[int, float, float]:
    """fmpy's cross-check band of half-width `width` around the reference
    sampled on its own grid; returns (outliers, worst excess over the band,
    largest |y - y_ref|)."""
    import warnings

    span = float(np.max(y_ref) - np.min(y_ref))
    dy = width / span if span > 0 else width
    with warnings.catch_warnings():  # it imports scipy.ndimage.filters (deprecated)
        warnings.simplefilter("ignore", DeprecationWarning)
        from fmpy.cross_check import validate_signal

        t_band, y_min, y_max, i_out = validate_signal(t=t, y=y, t_ref=t_ref, y_ref=y_ref, t_start=t_start,
                                                      t_stop=t_stop, num=len(t_ref), dx=1, dy=dy)
    lo = np.interp(t, t_band, y_min)
    hi = np.interp(t, t_band, y_max)
    excess = np.maximum(lo - y, y - hi)
    dev = np.abs(y - np.interp(t, t_ref, y_ref))
    return int(np.sum(i_out)), float(np.max(excess)), float(np.max(dev))


def grade(result: Result, case: CaseData) -> Grade:
    n_grid = len(case.time)
    rows, ks = _on_grid(result.time, case.grid, n_grid)
    g = Grade(case.name, result.source, len(result.time), len(rows))
    tol = case.tolerances
    wanted = list(tol["tube"]) + [case.phi, case.w] + ([case.switch_signal] if case.switch_signal else [])
    wanted = list(dict.fromkeys(wanted))
    matched = {s: result.match(s) for s in wanted}
    g.missing = [s for s, col in matched.items() if col is None]
    for s in g.missing:
        hits = [c for c in result.columns if c.endswith("." + s)]
        g.missing_why[s] = (f"no column ends with '{s}'" if not hits else
                            f"ambiguous: {len(hits)} columns end with '.{s}': {', '.join(hits[:4])}")
    used = set(col for col in matched.values() if col)
    g.unmatched = [c for c in result.columns if c not in used]

    if result.time[-1] < case.stop - 1e-6 * case.grid:
        g.problems.append(f"the result ends at {result.time[-1]:.9g} s, before the case's stop {case.stop:g} s")
    if len(rows) < max(2, n_grid // 10) or (len(rows) and ks[-1] != n_grid - 1):
        g.problems.append(f"only {len(rows)} of {n_grid} rows on the case's output grid (every {case.grid:g} s "
                          f"up to {case.stop:g} s): write the result at multiples of the grid")

    for s, width in tol["tube"].items():
        col = matched.get(s)
        if col is None:
            g.checks.append(Check(f"tube {s}", width, math.inf, False, "missing"))
            continue
        y = result.columns[col]
        if len(rows) < 2 or not np.all(np.isfinite(y)):
            g.checks.append(Check(f"tube {s}", width, math.inf, False, "no finite rows on the grid"))
            continue
        out, excess, dev = tube(result.time[rows], y[rows], case.time, case.columns[s], case.time[0],
                                case.time[-1], width)
        g.checks.append(Check(f"tube {s}", width, dev, out == 0,
                              f"{out} of {len(rows)} rows outside" if out else ""))

    t = result.time
    phi_col, w_col = matched.get(case.phi), matched.get(case.w)
    w = result.columns[w_col] if w_col else None
    margin = 3.0 * case.grid
    if phi_col is not None:
        found = events.ticks(t, result.columns[phi_col], w)
        m = events.match(found, case.ticks, margin, case.stop - margin)
        g.checks.append(_event_check(f"ticks ({m['expected']})", tol["ticks_s"], m))
    else:
        g.checks.append(Check("ticks", tol["ticks_s"], math.inf, False, f"{case.phi} missing"))
    if case.switch_signal and tol.get("switches_s") is not None:
        col = matched.get(case.switch_signal)
        if col is None:
            g.checks.append(Check("switches", tol["switches_s"], math.inf, False, f"{case.switch_signal} missing"))
        else:
            found, _ = events.switches(t, result.columns[col], w, case.grid)
            m = events.match(found, case.switches, margin, case.stop - margin)
            g.checks.append(_event_check(f"switches ({m['expected']})", tol["switches_s"], m))
    return g


def _event_check(what: str, tolerance: float, m: dict) -> Check:
    detail = []
    if m["missing"]:
        detail.append(f"{m['missing']} missing")
    if m["extra"]:
        detail.append(f"{m['extra']} extra")
    if m["expected"] and math.isfinite(m["worst_s"]) and m["worst_s"] > tolerance:
        detail.append(f"worst at {m['worst_at_s']:.6g} s")
    ok = not m["missing"] and not m["extra"] and m["worst_s"] <= tolerance
    return Check(what, tolerance, m["worst_s"], ok, ", ".join(detail))


def compare(result_path: str | Path, case_spec: str | Path) -> Grade:
    case = load_case(case_spec)
    result = read_result(result_path)
    return grade(result, case)
