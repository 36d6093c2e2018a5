"""`clockwork stability`: the Allan and time deviations of a clock's ticks.

The ticks come from one of three places:

- a tick log (``--data FILE.csv``): a measured one, a timer's export, or a
  run's ``ticks.csv``; read by ``read_tick_log``;
- a finished run's directory (its ``ticks.csv``);
- a scene, run here with the ``ticks`` analysis (the time series of the
  scene, keeping only the pendulum's tick times): Hoyng's noisy clock, a
  long chaotic run.

The result goes into an output directory as a run's does (staged, then
swapped in whole): ``stability.csv`` (clockwork.analyses.stability.COLUMNS),
``summary.json`` (``stability``: the columns, the tick count, the mean
period, the confidence and the estimators) and ``stability.png`` (log-log,
with the intervals as error bars).
"""

from __future__ import annotations

import dataclasses
import math
import re
from pathlib import Path

from ..version import __version__
from ..analyses import stability as st
from ..errors import SceneError, UsageError
from ..files import NotRegularFile, read_regular
from ..numbers import parse_real, shorten
from ..scene.units import TIME_UNITS

MAX_LOG_BYTES = 1 << 30  # a billion bytes: tens of millions of ticks
# Header names of the tick-time column (case-insensitive), with an optional unit: "time [s]", "time_s".
# (Not "tick": clockwork's ticks.csv numbers its ticks in a column of that name.)
_TIME_NAMES = ("time_s", "time", "tick_time_s", "tick_time", "t", "timestamp")
_HEADER = re.compile(r"^\s*([^\[\]]*?)\s*(?:\[\s*([^\[\]]*?)\s*\])?\s*$")


def read_tick_log(path: str | Path) -> list[float]:
    """Tick times (s) from a CSV file: one row per tick. With a header, the
    column named time_s, time, tick_time_s, tick_time, t or timestamp, the
    first of these there is (a unit in
    brackets: s, ms, us, min, h, d); else the first column. Comma,
    semicolon or tab separated; blank lines and lines starting with # are
    skipped. Every time a finite number, strictly increasing; at least
    MIN_TICKS of them. Else SceneError naming the file, line and column."""
    try:
        data = read_regular(path, "a tick log (CSV)", limit=MAX_LOG_BYTES)
    except NotRegularFile as e:
        raise SceneError(e.detail, path) from None
    except FileNotFoundError:
        raise SceneError("no such file", path) from None
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        raise SceneError(f"not UTF-8 text (byte {e.start}): expected a CSV tick log", path) from None
    rows = [(n, line) for n, line in enumerate(text.splitlines(), 1)
            if line.strip() and not line.lstrip().startswith("#")]
    if not rows:
        raise SceneError(f"no ticks: expected at least {st.MIN_TICKS} tick times, one per line", path)
    sep = next((s for s in ("\t", ";", ",") if s in rows[0][1]), ",")
    first = [f.strip().strip('"') for f in rows[0][1].split(sep)]
    column, scale, what = 0, 1.0, "column 1"
    if not _numeric(first[0]):
        names = [_HEADER.match(f) for f in first]
        found = sorted(((_TIME_NAMES.index(m.group(1).lower()), i, m.group(2)) for i, m in enumerate(names)
                        if m and m.group(1).lower() in _TIME_NAMES))  # the first name of the list there is
        if not found:
            raise SceneError(f"no tick-time column: expected one named {', '.join(_TIME_NAMES[:-1])} or timestamp "
                             f"(a unit in brackets allowed), or no header; the header has "
                             f"{shorten(', '.join(first), 120)}", path, f"line {rows[0][0]}")
        _, column, unit = found[0]
        what = f"column {first[column]}"
        if unit is not None:
            if unit not in TIME_UNITS:
                raise SceneError(f"expected a time unit: one of {', '.join(TIME_UNITS)}", path,
                                 f"line {rows[0][0]}, {what}")
            scale = TIME_UNITS[unit]
        rows = rows[1:]
    times: list[float] = []
    for n, line in rows:
        fields = line.split(sep)
        if column >= len(fields):
            raise SceneError(f"expected {column + 1} fields, found {len(fields)}", path, f"line {n}")
        field = fields[column].strip().strip('"')
        try:
            t = parse_real(field) * scale
        except ValueError:
            raise SceneError(f"expected a number (a tick time), got {shorten(field, 40)!r}", path,
                             f"line {n}, {what}") from None
        if not math.isfinite(t):
            raise SceneError("expected a finite tick time", path, f"line {n}, {what}")
        if times and not t > times[-1]:
            raise SceneError(f"expected tick times that increase: {t!r} s after {times[-1]!r} s", path,
                             f"line {n}, {what}")
        times.append(t)
    check_enough(times, path)
    return times


def _numeric(text: str) -> bool:
    try:
        parse_real(text)
        return True
    except ValueError:
        return False


def check_enough(times, where) -> None:
    if len(times) < st.MIN_TICKS:
        raise SceneError(f"{len(times)} ticks: expected at least {st.MIN_TICKS} (16 periods: the deviation at "
                         "tau0, 2 tau0 and 4 tau0)", where)


def ticks_of_run(directory: Path) -> tuple[list[float], str]:
    """A finished run's ticks (its ticks.csv), and where they came from."""
    path = directory / "ticks.csv"
    if not path.is_file():
        raise UsageError(f"{directory}: no ticks.csv: expected the --out directory of a run that recorded ticks "
                         "(record.ticks, the ticks analysis), a scene, or --data FILE.csv")
    return read_tick_log(path), str(path)


def scene_for_ticks(spec: str, overrides):
    """The scene to run for its ticks: the ``ticks`` analysis in place of its
    own, its plots and its sweep set aside (one run at the scene's values,
    --set for others, gives one tick log); and whether it had a sweep."""
    from ..analyses.context import find_component
    from .catalog import load_scene

    scene = load_scene(spec, overrides)
    if scene.record.ticks is None and find_component(scene, "Pendulum") is None:
        raise SceneError("no ticks to record: expected a Pendulum component or record.ticks", scene.path,
                         "record.ticks")
    return dataclasses.replace(scene, analysis={"kind": "ticks"}, plots=(), sweep=None), scene.sweep is not None


def ticks_of_scene(scene) -> list[float]:
    from ..errors import SimulationError
    from .points import run_point

    ticks = run_point(scene, {}).get("ticks") or []
    if len(ticks) < st.MIN_TICKS:
        raise SimulationError(f"{scene.path}: the run gave {len(ticks)} ticks, fewer than the {st.MIN_TICKS} the "
                              "deviations need: a longer experiment.stop")
    return [float(t) for t in ticks]


def stability(source: str | None, data: str | None, out_dir, overrides=()) -> dict:
    """Read or run the ticks, compute, write; returns the summary."""
    from ..results.files import write_csv_atomic, write_json_atomic
    from ..results.outdir import OutputDir

    if (source is None) == (data is None):
        raise UsageError("stability: give a run directory or a scene, or --data FILE.csv (one of them)")
    if data is not None and overrides:
        raise UsageError("stability: --set is for a scene; --data reads a tick log")
    scene = ticks = None
    sweep_set_aside = False
    if data is not None:
        ticks, origin = read_tick_log(data), str(data)
    elif Path(source).is_dir():
        if overrides:
            raise UsageError("stability: --set is for a scene; a run directory holds finished ticks")
        ticks, origin = ticks_of_run(Path(source))
    else:
        scene, sweep_set_aside = scene_for_ticks(source, overrides)
        origin = str(scene.path)
    # opened before a scene runs (a bad output directory is refused first); swapped in whole at the end
    with OutputDir(out_dir) as out:
        if ticks is None:
            ticks = ticks_of_scene(scene)
        result = st.allan(ticks)
        cols = result["columns"]
        write_csv_atomic(out.staging / "stability.csv", list(cols), [cols[k] for k in cols])
        files = ["stability.csv"]
        try:
            if draw(result, out.staging / "stability.png", origin):
                files.append("stability.png")
            else:
                result["plot_note"] = "no plot: every deviation is 0 (nothing to draw on log axes)"
        except Exception as e:  # a plot must not take the numbers with it
            result["plot_error"] = f"{type(e).__name__}: {e}"
        summary = {"tool": {"name": "clockwork", "version": __version__}, "source": origin,
                   **({"overrides": list(scene.overrides)} if scene is not None and scene.overrides else {}),
                   **({"scene_sweep_set_aside": True} if sweep_set_aside else {}),
                   "stability": result, "files": files + ["summary.json"]}
        write_json_atomic(out.staging / "summary.json", summary)
        out.commit()
    return summary


def draw(result: dict, path: Path, origin: str) -> bool:
    """The plot into `path`; False when there is nothing to draw."""
    from ..results.plots.registry import quiet_matplotlib, save
    from ..results.plots.stability import figure

    with quiet_matplotlib():
        fig = figure(result, origin)
        if fig is None:
            return False
        save(fig, path)
    return True
