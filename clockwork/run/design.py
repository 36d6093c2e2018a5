"""`clockwork design`: the escapement and drive that make a clock's rate
insensitive to what it cannot hold constant.

    clockwork design SCENE --vary NAME=LOW..HIGH ... --goal GOAL [--amplitude DEG] --out DIR

GOAL is a sum of weighted sensitivities of steady-state result columns to
parameters (or unconnected inputs):

    [WEIGHT *] d(COLUMN)/d(INSTANCE.VARIABLE [UNIT]) [* WEIGHT] + ...

e.g. ``d(E_T_s_per_day)/d(escapement.torque [N.cm]) + 0.5 * d(E_T_s_per_day)/d(air.pressure [hPa])``.
A sensitivity S is in the column's unit per the parameter's UNIT (its own
SI unit without one). The goal minimised is sum (WEIGHT * S)^2: a weight
is the number of the term's units one is willing to trade for one unit of
another term.

Each S is a central difference at the operating point: the parameter
moved by -h and +h relative to its value (``--step``, default 1e-2), each
side a steady state by shooting (the scene's analysis replaced by
``steady_state``; clockwork.analyses.steady_state). With ``--amplitude``
the operating point holds the pendulum's amplitude: at every design the
escapement's torque (the drive) is solved first, by secant steps on log
amplitude against log torque, until the steady amplitude is the one asked
for (relative 1e-7). Every steady state is a point of the scene, run by
``run.points.run_point`` on reused FMU instances and kept in the point
cache (clockwork.results.cache): a point asked for again, in this run or
a later one, is not recomputed.

The optimiser is SciPy's: bounded Brent (``minimize_scalar``) for one
varied parameter, Nelder-Mead within the bounds (``minimize``) for more,
in coordinates scaled to [0, 1] per parameter. The result is checked by a
forward simulation: the steady rate at the drive's torque x 0.9, x 1 and
x 1.1 for the scene's design and the one found.
"""

from __future__ import annotations

import dataclasses
import math
import re
from pathlib import Path

from ..version import __version__
from ..analyses.context import ESCAPEMENTS, find_component, parameters, reusing_systems
from ..analyses.steady_state import COLUMNS as STEADY_COLUMNS
from ..analyses.steady_state import clock_check
from ..errors import SceneError, SimulationError, UsageError
from ..numbers import shorten
from ..results.cache import cache_load, cache_store
from ..scene.checks import Ctx, convert_value, parse_ref, settable_problem
from ..scene.kinds import Invalid
from ..scene.units import UnitError, to_unit
from .points import point_key, point_label, run_point

# Analyses built on steady states: a design runs their scenes as steady_state points.
STEADY_KINDS = ("steady_state", "barometric_coefficient", "thermal_coefficient")
# The clock's own numbers (not the search's diagnostics: iterations, residual, tolerance, last change).
NUMERIC_COLUMNS = sorted(STEADY_COLUMNS - {"stalled", "reason", "shooting_iterations", "shooting_residual_rad_per_s",
                                           "rate_tolerance_s_per_day", "rate_change_s_per_day"})
DEFAULT_STEP = 1e-2
DEFAULT_TOLERANCE_S_PER_DAY = 1e-6  # on the steady rate: far below the differences a 1 % step makes
AMPLITUDE_RTOL = 1e-7
FORWARD_FACTORS = (0.9, 1.0, 1.1)
SCAN_POINTS = 7  # the goal's plot: points across +-10 % of each range around the optimum


@dataclasses.dataclass(frozen=True)
class Parameter:
    instance: str
    variable: str
    unit: str | None  # the variable's own (SI)

    @property
    def name(self) -> str:
        return f"{self.instance}.{self.variable}"


@dataclasses.dataclass(frozen=True)
class Vary:
    parameter: Parameter
    low: float  # in the variable's unit
    high: float
    text: str


@dataclasses.dataclass(frozen=True)
class Term:
    column: str
    parameter: Parameter
    unit: str | None  # the unit the derivative is taken per (the given one, else the variable's)
    per_unit: float  # the variable's units in one `unit`
    weight: float

    @property
    def label(self) -> str:
        u = f" [{self.unit}]" if self.unit else ""
        return f"d({self.column})/d({self.parameter.name}{u})"

    @property
    def unit_label(self) -> str:
        return f"{_column_unit(self.column)} per {self.unit or '1'}"


def _column_unit(column: str) -> str:
    for suffix, unit in (("_s_per_day", "s/day"), ("_deg", "deg"), ("_s", "s"), ("_Nm", "N.m"),
                         ("_rad_per_s", "rad/s")):
        if column.endswith(suffix):
            return unit
    return "1"


def _ctx(label: str) -> Ctx:
    """Error lines name the option as given (``--vary NAME=...``), no file."""

    class _OptionCtx(Ctx):
        def where(self, key):
            return None, label

    return _OptionCtx(Path("."), {})


def _parameter(scene, ref: str, label: str) -> tuple[Parameter, object, object]:
    """(Parameter, its variable, its model description) for INSTANCE.VARIABLE:
    a Real parameter or unconnected input of the scene, else SceneError."""
    from ..fmi.description import var_unit

    ctx = _ctx(label)
    comp, var = parse_ref(ctx, "x", ref.strip(), scene.components, "a parameter")
    problem = settable_problem(var)
    if problem or var.causality == "structuralParameter":
        raise ctx.fail("x", f"{ref} is {var.causality}: expected a parameter or an unconnected input")
    if var.causality == "input" and any((c.dst_instance, c.dst_var) == (comp.name, var.name)
                                        for c in scene.connections):
        raise ctx.fail("x", f"{ref} is a connected input: expected a parameter or an unconnected input")
    if var.type not in ("Real", "Float64", "Float32") or getattr(var, "shape", None):
        raise ctx.fail("x", f"{ref} is {var.type}: expected a Real (scalar) parameter")
    return Parameter(comp.name, var.name, var_unit(var)), var, comp.model_description


def parse_vary(scene, text: str) -> Vary:
    label = f"--vary {shorten(text, 80)}"
    name, eq, rng = text.partition("=")
    if not eq or not rng.strip():
        raise SceneError("expected NAME=LOW..HIGH (a range to search, e.g. escapement.phi_r=1deg..4deg)", None,
                         label)
    param, var, md = _parameter(scene, name, label)
    parts = rng.split("..")
    if len(parts) != 2 or not all(p.strip() for p in parts):
        raise SceneError("expected NAME=LOW..HIGH (two values joined by '..', each with an optional unit)", None,
                         label)
    ctx = _ctx(label)
    low, high = (float(convert_value(ctx, "x", p.strip(), var, md)) for p in parts)
    if not low < high:
        raise SceneError(f"expected LOW < HIGH, got {low:g} .. {high:g} {param.unit or ''}".rstrip(), None, label)
    return Vary(param, low, high, text)


_NUM = r"[-+]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][-+]?\d+)?"
_TERM = re.compile(rf"\s*(?:(?P<w1>{_NUM})\s*\*\s*)?d\(\s*(?P<col>[^()]*?)\s*\)\s*/\s*d\(\s*(?P<par>[^()\[\]]*?)"
                   rf"\s*(?:\[\s*(?P<unit>[^\[\]()]*?)\s*\])?\s*\)(?:\s*\*\s*(?P<w2>{_NUM}))?\s*")
GOAL_SYNTAX = "[WEIGHT *] d(COLUMN)/d(INSTANCE.VARIABLE [UNIT]) [* WEIGHT], terms joined by +"


def parse_goal(scene, text: str) -> list[Term]:
    label = "--goal"
    terms: list[Term] = []
    pos = 0
    while True:
        m = _TERM.match(text, pos)
        if m is None or m.end() == pos:
            shown = shorten(text[pos:], 40) or "(nothing)"
            raise SceneError(f"expected {GOAL_SYNTAX}; at character {pos + 1}: {shown!r}", None, label)
        col = m.group("col")
        if col not in NUMERIC_COLUMNS:
            import difflib

            close = difflib.get_close_matches(col, NUMERIC_COLUMNS, n=1)
            hint = f" (did you mean {close[0]}?)" if close else ""
            raise SceneError(f"d({shorten(col, 60)}) names no result column of the steady state{hint}: expected one of "
                             f"{', '.join(NUMERIC_COLUMNS)}", None, label)
        if m.group("w1") and m.group("w2"):
            raise SceneError(f"{m.group(0).strip()}: expected one weight per term", None, label)
        weight = float(m.group("w1") or m.group("w2") or 1.0)
        if not (math.isfinite(weight) and weight > 0):
            raise SceneError(f"{m.group(0).strip()}: expected a finite weight > 0", None, label)
        param, var, md = _parameter(scene, m.group("par"), f"{label} {m.group(0).strip()}")
        unit = m.group("unit")
        per_unit = 1.0
        if unit:
            try:
                per_unit = to_unit(f"1 {unit}", md, param.unit) - to_unit(f"0 {unit}", md, param.unit)
            except UnitError as e:
                raise SceneError(f"[{unit}]: expected {e}", None, f"{label} {m.group(0).strip()}") from None
        terms.append(Term(col, param, unit or param.unit, per_unit, weight))
        pos = m.end()
        if pos == len(text):
            break
        if text[pos] != "+":
            raise SceneError(f"expected + between terms ({GOAL_SYNTAX}); at character {pos + 1}: "
                             f"{shorten(text[pos:], 40)!r}", None, label)
        pos += 1
    labels = [t.label for t in terms]
    twice = next((x for x in labels if labels.count(x) > 1), None)
    if twice:
        raise SceneError(f"{twice} is given twice", None, label)
    return terms


def design_scene(scene, tolerance_s_per_day: float):
    """The scene as the design runs it: its analysis a steady_state (keeping
    the search's keys), its sweep and plots set aside; else SceneError."""
    cfg = scene.analysis or {}
    kind = cfg.get("kind", "time_series")
    if kind not in STEADY_KINDS:
        raise SceneError(f"expected a steady-state scene (analysis.kind one of {', '.join(STEADY_KINDS)}): a design "
                         f"is made of periodic orbits, and {kind} gives none", scene.path, "analysis.kind")
    analysis = {"kind": "steady_state", "tolerance_s_per_day": tolerance_s_per_day}
    for k in ("max_periods", "amplitude_guess"):
        if k in cfg:
            analysis[k] = cfg[k]
    out = dataclasses.replace(scene, analysis=analysis, sweep=None, plots=())
    try:
        clock_check(out, {}, "clockwork design")
    except Invalid as e:
        raise SceneError(f"expected {e.expected}", scene.path, f"analysis.{e.key}") from None
    return out


class Evaluator:
    """Steady states of the design scene, by point, cached; the goal."""

    def __init__(self, scene, varies: list[Vary], terms: list[Term], step: float, amplitude_deg: float | None):
        self.scene, self.varies, self.terms, self.step = scene, varies, terms, step
        self.amplitude_deg = amplitude_deg
        self.drive: Parameter | None = None
        base = parameters(scene, {})
        if amplitude_deg is not None:
            esc = find_component(scene, ESCAPEMENTS)
            if esc is None:
                raise SceneError("--amplitude holds the amplitude by the escapement's torque: expected a scene "
                                 "with an escapement", scene.path, "components")
            self.drive = Parameter(esc, "torque", base[esc].unit("torque"))
            self.drive_guess = float(base[esc]["torque"])
            for v in varies:
                if v.parameter == self.drive:
                    raise SceneError("the drive is solved for the amplitude: expected --vary of other parameters "
                                     "with --amplitude", None, f"--vary {v.text}")
        self.base = base
        self.sweep_set_aside = False  # the scene's sweep, if any, is not the operating point
        self.memory: dict[str, dict] = {}
        self.points_run = 0
        self.points_cached = 0
        self.evaluations: list[dict] = []

    def value(self, p: Parameter, values: dict) -> float:
        return float(values.get((p.instance, p.variable), self.base[p.instance][p.variable]))

    def steady(self, values: dict) -> dict:
        """The steady_state result at these {(instance, variable): value}."""
        # Only what differs from the scene: one set of values is one point
        # (one label) whichever way it was reached, so the cache's check
        # that an entry belongs to its point holds across designs.
        point = {k: float(v) for k, v in values.items() if float(v) != self.base[k[0]][k[1]]}
        key = point_key(self.scene, point)
        if key in self.memory:
            return self.memory[key]
        label = point_label(point)
        r = cache_load(key, label, "steady_state")
        if r is None:
            r = run_point(self.scene, point)
            cache_store(key, r)
            self.points_run += 1
        else:
            self.points_cached += 1
        self.memory[key] = r["result"]
        return r["result"]

    def operating_point(self, x: dict) -> tuple[dict, dict]:
        """(values, steady result) of the design x: with --amplitude, the drive solved for it."""
        values = dict(x)
        if self.drive is None:
            return values, self.steady(values)
        target = math.radians(self.amplitude_deg)
        key = (self.drive.instance, self.drive.variable)
        tau = self.drive_guess
        history: list[tuple[float, float]] = []
        for _ in range(40):
            values[key] = tau
            r = self.steady(values)
            if r.get("stalled"):
                tau *= 2.0
                continue
            a = math.radians(r["amplitude_deg"])
            if abs(a / target - 1.0) <= AMPLITUDE_RTOL:
                self.drive_guess = tau
                return values, r
            history.append((math.log(tau), math.log(a)))
            slope = 0.5  # energy balance: amplitude ~ sqrt(torque)
            if len(history) >= 2 and history[-1][0] != history[-2][0]:
                s = (history[-1][1] - history[-2][1]) / (history[-1][0] - history[-2][0])
                if 0.05 < s < 5.0:
                    slope = s
            tau = math.exp(history[-1][0] + (math.log(target) - history[-1][1]) / slope)
        raise SimulationError(f"no drive ({self.drive.name}) found that gives the amplitude {self.amplitude_deg:g} deg "
                              f"at {_shown(x)}")

    def sensitivities(self, values: dict) -> list[float]:
        out = []
        for t in self.terms:
            key = (t.parameter.instance, t.parameter.variable)
            p0 = self.value(t.parameter, values)
            if p0 == 0.0:
                raise SceneError(f"{t.parameter.name} is 0 at the operating point: a relative step needs a value "
                                 "other than 0", None, f"--goal {t.label}")
            h = self.step * abs(p0)
            lo = self.steady({**values, key: p0 - h})
            hi = self.steady({**values, key: p0 + h})
            if lo.get("stalled") or hi.get("stalled") or lo.get(t.column) is None or hi.get(t.column) is None:
                out.append(math.inf)
                continue
            out.append((hi[t.column] - lo[t.column]) / (2.0 * h) * t.per_unit)
        return out

    def goal_of(self, sens: list[float]) -> float:
        return sum((t.weight * s) ** 2 for t, s in zip(self.terms, sens))

    def evaluate(self, x: dict) -> dict:
        values, r = self.operating_point(x)
        sens = [math.inf] * len(self.terms) if r.get("stalled") else self.sensitivities(values)
        g = self.goal_of(sens)
        e = {"x": dict(x), "values": values, "result": r, "sensitivities": sens, "goal": g}
        self.evaluations.append(e)
        return e


def _shown(x: dict) -> str:
    return ", ".join(f"{a}.{b} = {v:.6g}" for (a, b), v in x.items()) or "the scene's values"


def _optimise(ev: Evaluator) -> tuple[dict, dict]:
    """(best x, optimiser report); SimulationError when SciPy reports a failure."""
    from scipy import optimize

    varies = ev.varies

    def x_of(u) -> dict:
        return {(v.parameter.instance, v.parameter.variable): v.low + min(max(float(ui), 0.0), 1.0) * (v.high - v.low)
                for v, ui in zip(varies, u)}

    def f(u) -> float:
        g = ev.evaluate(x_of(u))["goal"]
        return g if math.isfinite(g) else 1e300

    if len(varies) == 1:
        res = optimize.minimize_scalar(lambda u: f([u]), bounds=(0.0, 1.0), method="bounded",
                                       options={"xatol": 1e-5, "maxiter": 100})
        u = [float(res.x)]
        method = "scipy.optimize.minimize_scalar (bounded Brent)"
    else:
        u0 = []
        for v in varies:
            x0 = ev.value(v.parameter, {})
            u0.append(min(max((x0 - v.low) / (v.high - v.low), 0.0), 1.0))
        # converged when the simplex is 1e-4 of each range across, or its goals agree to 1e-10 of the
        # scene's goal (a valley of equally good designs: any point on its floor is one)
        g0 = ev.evaluations[0]["goal"] if ev.evaluations and math.isfinite(ev.evaluations[0]["goal"]) else 1.0
        res = optimize.minimize(f, u0, method="Nelder-Mead", bounds=[(0.0, 1.0)] * len(varies),
                                options={"xatol": 1e-4, "fatol": 1e-10 * g0, "maxfev": 200 * len(varies)})
        u = [float(x) for x in res.x]
        method = "scipy.optimize.minimize (Nelder-Mead within the bounds)"
    if not math.isfinite(float(res.fun)) or float(res.fun) >= 1e300:
        raise SimulationError(f"the optimiser failed: no design it tried within the bounds has the steady "
                              f"states the goal needs (the clock stalls) ({res.nfev} evaluations)")
    if not res.success:
        raise SimulationError(f"the optimiser failed: {shorten(str(getattr(res, 'message', res)), 160)} "
                              f"({res.nfev} evaluations)")
    return x_of(u), {"method": method, "success": bool(res.success), "message": str(getattr(res, "message", "")),
                     "evaluations": int(res.nfev)}


def design(scene_spec: str, vary_args: list[str], goal_text: str, out_dir, overrides=(), amplitude_deg=None,
           step: float = DEFAULT_STEP, tolerance_s_per_day: float = DEFAULT_TOLERANCE_S_PER_DAY) -> dict:
    from ..results.outdir import OutputDir
    from .catalog import load_scene

    if not vary_args:
        raise UsageError("design: expected at least one --vary NAME=LOW..HIGH")
    if not (math.isfinite(step) and 0 < step <= 0.25):
        raise UsageError(f"design: --step {step!r}: expected a relative step in (0, 0.25]")
    if not (math.isfinite(tolerance_s_per_day) and 1e-9 <= tolerance_s_per_day <= 1.0):
        raise UsageError(f"design: --tolerance {tolerance_s_per_day!r}: expected 1e-9 to 1 s/day")
    if amplitude_deg is not None and not (math.isfinite(amplitude_deg) and 0 < amplitude_deg < 150):
        raise UsageError(f"design: --amplitude {amplitude_deg!r}: expected an amplitude in (0, 150) deg")
    loaded = load_scene(scene_spec, overrides)
    scene_sweep_set_aside = loaded.sweep is not None
    scene = design_scene(loaded, tolerance_s_per_day)
    varies = [parse_vary(scene, v) for v in vary_args]
    names = [v.parameter.name for v in varies]
    twice = next((n for n in names if names.count(n) > 1), None)
    if twice:
        raise SceneError(f"{twice} is varied twice", None, "--vary")
    terms = parse_goal(scene, goal_text)
    ev = Evaluator(scene, varies, terms, step, amplitude_deg)
    _check_steps(ev)
    ev.sweep_set_aside = scene_sweep_set_aside  # said in summary.json: the operating point is not a sweep's
    # Opened (made, locked, checked for foreign files) after the input is known
    # good and before the points run; the result is swapped in whole at the end.
    with OutputDir(out_dir) as out, reusing_systems():
        before = ev.evaluate({})
        best_x, report = _optimise(ev)
        after = ev.evaluate(best_x)
        forward = {"before": _forward(ev, before["values"]), "after": _forward(ev, after["values"])}
        scan = _scan(ev, best_x)
        return _write(out, scene, ev, varies, terms, goal_text, before, after, report, forward, scan, step,
                      tolerance_s_per_day)


def _check_steps(ev: Evaluator) -> None:
    """A relative step needs a parameter that is never 0: its scene value,
    or, varied, a range on one side of 0 (the solved drive is > 0)."""
    for t in ev.terms:
        if t.parameter == ev.drive:
            continue
        varied = next((v for v in ev.varies if v.parameter == t.parameter), None)
        if varied is not None:
            if varied.low <= 0.0 <= varied.high:
                raise SceneError(f"{t.parameter.name} is varied over a range that holds 0: a relative step needs "
                                 "values other than 0", None, f"--goal {t.label}")
        elif ev.value(t.parameter, {}) == 0.0:
            raise SceneError(f"{t.parameter.name} is 0 in the scene: a relative step needs a value other than 0 "
                             f"(--set {t.parameter.name}=...)", None, f"--goal {t.label}")


def _forward(ev: Evaluator, values: dict) -> dict:
    """The rate at the drive's torque x 0.9, 1, 1.1 (the escapement's
    torque), two ways: the steady state by shooting, and a plain forward
    co-simulation (the ``ticks`` analysis, no shooting) started at the
    steady orbit's turning point and run for FORWARD_DAMPING_TIMES damping
    times (Q/pi periods each), the rate from the mean period of its last
    fifth."""
    esc = find_component(ev.scene, ESCAPEMENTS)
    if esc is None:
        return {}
    key = (esc, "torque")
    tau = float(values.get(key, ev.base[esc]["torque"]))
    rows = [ev.steady({**values, key: f * tau}) for f in FORWARD_FACTORS]
    rates = [r.get("E_T_s_per_day") for r in rows]
    out = {"torque_factors": list(FORWARD_FACTORS), "torque_Nm": [f * tau for f in FORWARD_FACTORS],
           "amplitude_deg": [r.get("amplitude_deg") for r in rows], "E_T_s_per_day": rates,
           "rate_change_s_per_day_over_pm10_percent": _change(rates)}
    if all(r.get("amplitude_right_deg") is not None for r in rows):
        timed = [_time_domain(ev, {**values, key: f * tau}, r) for f, r in zip(FORWARD_FACTORS, rows)]
        out["time_domain"] = {"E_T_s_per_day": [t[0] for t in timed], "periods": timed[0][1],
                              "rate_change_s_per_day_over_pm10_percent": _change([t[0] for t in timed])}
    return out


FORWARD_DAMPING_TIMES = 8  # the start's offset from the orbit decays by e^-8 before the rate is read


def _change(rates: list) -> float | None:
    return rates[2] - rates[0] if all(x is not None for x in rates) else None


def _time_domain(ev: Evaluator, values: dict, steady: dict) -> tuple[float | None, int]:
    """(E_T in s/day, periods run) of a forward run from the turning point of `steady`."""
    from ..analyses.context import find_component as component
    from ..physics import analytic

    pendulum = component(ev.scene, "Pendulum")
    pp = parameters(ev.scene, {k: v for k, v in values.items()})[pendulum]
    T0 = 2.0 * math.pi * math.sqrt(pp["L"] / pp["g"])
    periods = int(min(20000, max(500, math.ceil(FORWARD_DAMPING_TIMES * pp["Q"] / math.pi))))
    start = ev.scene.experiment.start
    scene = dataclasses.replace(ev.scene, analysis={"kind": "ticks"},
                                experiment=dataclasses.replace(ev.scene.experiment, stop=start + periods * T0))
    point = {**values, (pendulum, "phi_start"): math.radians(steady["amplitude_right_deg"]),
             (pendulum, "w_start"): 0.0}
    ticks = run_point(scene, point).get("ticks") or []
    tail = ticks[-max(2, len(ticks) // 5):]
    if len(ticks) < 10 or len(tail) < 2:
        return None, periods
    mean_period = (tail[-1] - tail[0]) / (len(tail) - 1)
    return (mean_period / T0 - 1.0) * analytic.SECONDS_PER_DAY, periods


def _scan(ev: Evaluator, best: dict) -> list[dict]:
    """The goal along each varied parameter through the optimum, the others held."""
    out = []
    for v in ev.varies:
        key = (v.parameter.instance, v.parameter.variable)
        width = 0.1 * (v.high - v.low)
        lo, hi = max(v.low, best[key] - width), min(v.high, best[key] + width)
        xs = [lo + (hi - lo) * i / (SCAN_POINTS - 1) for i in range(SCAN_POINTS)]
        evals = [ev.evaluate({**best, key: x}) for x in xs]
        out.append({"parameter": v.parameter.name, "unit": v.parameter.unit, "values": xs,
                    "goal": [e["goal"] for e in evals], "optimum": best[key],
                    "sensitivities": {t.label: [e["sensitivities"][k] for e in evals] for k, t in enumerate(ev.terms)}})
    return out


def _write(out, scene, ev: Evaluator, varies, terms, goal_text, before, after, report, forward, scan, step,
           tolerance) -> dict:
    from ..results.files import write_csv_atomic, write_json_atomic

    def finite(x):
        return x if isinstance(x, (int, float)) and math.isfinite(x) else None

    params = {}
    for v in varies:
        key = (v.parameter.instance, v.parameter.variable)
        params[v.parameter.name] = {"value": after["values"][key], "unit": v.parameter.unit,
                                    "before": ev.value(v.parameter, before["values"]), "bounds": [v.low, v.high]}
    if ev.drive is not None:
        key = (ev.drive.instance, ev.drive.variable)
        params[ev.drive.name] = {"value": after["values"][key], "unit": ev.drive.unit,
                                 "before": before["values"][key], "solved_for": "the amplitude"}
    sens = [{"term": t.label, "unit": t.unit_label, "weight": t.weight, "before": finite(b), "after": finite(a)}
            for t, b, a in zip(terms, before["sensitivities"], after["sensitivities"])]
    summary = {
        "tool": {"name": "clockwork", "version": __version__},
        "scene": str(scene.path), "title": scene.title, "overrides": list(scene.overrides),
        "design": {
            "parameters": params,
            "goal": {"expression": goal_text, "definition": "sum of (weight x sensitivity)^2",
                     "before": finite(before["goal"]), "after": finite(after["goal"])},
            "sensitivities": sens,
            "operating_point": {
                "amplitude_deg": ev.amplitude_deg,
                "held": "the amplitude, by the escapement's torque" if ev.drive else "the scene's values",
                "scene_sweep_set_aside": ev.sweep_set_aside,
                "before": {k: before["result"].get(k) for k in ("amplitude_deg", "E_T_s_per_day", "torque_Nm")},
                "after": {k: after["result"].get(k) for k in ("amplitude_deg", "E_T_s_per_day", "torque_Nm")}},
            "step": {"relative": step, "method": "central differences of steady states (shooting)"},
            "steady_state_tolerance_s_per_day": tolerance,
            "optimiser": report,
            "forward_check": forward,
            "scan": [{k: v for k, v in s.items()} for s in scan],
            "points": {"run": ev.points_run, "from_cache": ev.points_cached},
        },
    }
    header = [v.parameter.name for v in varies] + ([ev.drive.name] if ev.drive else []) + \
        ["amplitude_deg", "E_T_s_per_day"] + [t.label for t in terms] + ["goal"]
    rows = []
    for e in ev.evaluations:
        row = [ev.value(v.parameter, e["values"]) for v in varies]
        if ev.drive:
            row.append(e["values"][(ev.drive.instance, ev.drive.variable)])
        row += [e["result"].get("amplitude_deg"), e["result"].get("E_T_s_per_day")]
        row += [finite(s) for s in e["sensitivities"]] + [finite(e["goal"])]
        rows.append(row)
    write_csv_atomic(out.staging / "design.csv", header, [list(c) for c in zip(*rows)])
    files = ["design.csv"]
    try:
        _draw(scene, scan, terms, out.staging / "design_goal.png", goal_text)
        files.append("design_goal.png")
    except Exception as e:  # a plot must not take the numbers with it
        summary["design"]["plot_error"] = f"{type(e).__name__}: {e}"
    summary["files"] = files + ["summary.json"]
    write_json_atomic(out.staging / "summary.json", summary)
    out.commit()
    return summary


def _draw(scene, scan: list[dict], terms, path: Path, goal_text: str) -> None:
    """Top: the goal along each varied parameter through the optimum (log);
    below: each weighted sensitivity there (signed, linear), whose zeros the
    optimum balances."""
    import numpy as np

    from ..results.plots.registry import display, quiet_matplotlib, save, subplots

    def clean(values):
        return [x if x is not None and math.isfinite(x) else float("nan") for x in values]

    with quiet_matplotlib():
        fig, axes = subplots(2, len(scan), figsize=(max(7, 5 * len(scan)), 6.5), squeeze=False, sharex="col")
        for k, s in enumerate(scan):
            xs, label = display(scene, s["parameter"], s["values"])
            opt = display(scene, s["parameter"], [s["optimum"]])[0][0]
            top, bottom = axes[0][k], axes[1][k]
            top.plot(xs, [g if g > 0 else float("nan") for g in clean(s["goal"])], "o-", ms=3)
            top.set_yscale("log")
            top.set_ylabel("goal = sum (w S)^2")
            for t in terms:
                bottom.plot(xs, t.weight * np.asarray(clean(s["sensitivities"][t.label])), "o-", ms=3,
                            label=f"{t.weight:g} x {t.label} ({t.unit_label})")
            bottom.axhline(0.0, color="0.5", lw=0.6)
            bottom.set_ylabel("weighted sensitivity")
            bottom.set_xlabel(label)
            bottom.legend(fontsize=7)
            for ax in (top, bottom):
                ax.axvline(opt, color="C3", lw=0.8)
                ax.grid(True, which="both", alpha=0.3)
        fig.suptitle(f"{Path(str(scene.path)).name}: the goal near the optimum (red line), the others held", fontsize=9)
        save(fig, path)
