"""Run a scene: every sweep point through its analysis, then write the results.

Each finished sweep point is written to ``DIR/points/<key>.json`` as soon
as it completes (``key``: clockwork.run.points.point_key) and into the
point cache. A rerun into the same directory loads finished points instead
of recomputing them, so an interrupted sweep resumes without losing or
repeating work. Points run in this process, in a pool of processes
(``pool``) or on a Dask cluster (``dask``).
"""

from __future__ import annotations

import os
import time
from dataclasses import asdict
from pathlib import Path

from ..version import __version__
from ..analyses.context import reusing_systems, streaming_series
from ..errors import ParametersRefused, SceneError, SimulationError, printable
from ..processes import Child
from ..results.cache import cache_load, cache_store, read_point
from ..results.files import write_json_atomic
from ..results.outdir import OutputDir
from ..results.plots import Plotter
from ..results.plots.registry import unknown_column
from ..results.report import write_outputs
from ..results.series import FILE_NAMES, SeriesWriter, StreamedSeries, descriptions, estimate_bytes, require_formats
from .catalog import series_size
from .points import analysis_kind, failed_point, point_key, point_label, run_point


def run_scene(scene, out_dir, workers: int | None = None, scheduler: str | None = None,
              progress: bool = True, plot_process: Child | None = None) -> dict:
    """Run every point of `scene` and write its results into `out_dir`
    (see clockwork.results.outdir for how the directory is kept whole).
    `plot_process`: one the command forked at its start, for the plots
    (clockwork.results.plots.background)."""
    t_start = time.perf_counter()
    require_formats(scene.record.format)  # before the output directory is touched
    # The plot process starts first: it imports matplotlib while the points run,
    # and it must not inherit the output directory's lock.
    with Plotter.start(scene, plot_process) as plotter, OutputDir(out_dir) as out:
        try:
            return _run(scene, out, workers, scheduler, progress, plotter, t_start)
        finally:
            plotter.close()  # before the staging folder goes: nothing may write into it after


def _kept(r: dict | None, i: int) -> dict | None:
    """What a sweep keeps of a point once it is written to points/: its
    result, not its recorded series and ticks (only the first point's are
    kept), which no sweep output reads. Every point's series held until the
    end made the bound per point no bound on the sweep."""
    if r is None or i == 0:
        return r
    return {k: v for k, v in r.items() if k not in ("series", "ticks")}


def _run(scene, out: OutputDir, workers: int | None, scheduler: str | None, progress: bool,
         plotter: Plotter, t_start: float) -> dict:
    points = scene.points()
    sweep = scene.sweep is not None
    kind = analysis_kind(scene)
    results: list[dict | None] = [None] * len(points)
    # A sweep's points are content-addressed (points/, the cache); a single run
    # is neither, and its key would hash the package's whole source for nothing.
    keys = [point_key(scene, p) for p in points] if sweep else []
    if sweep:
        out.points.mkdir(exist_ok=True)
        for i, (k, p) in enumerate(zip(keys, points)):
            label = point_label(p)
            results[i] = read_point(out.points / f"{k}.json", label, kind)
            if results[i] is None:
                results[i] = cache_load(k, label, kind)
                if results[i] is not None:
                    write_json_atomic(out.points / f"{k}.json", results[i], unnamed=True)
            results[i] = _kept(results[i], i)
    todo = [i for i, r in enumerate(results) if r is None]
    reused = len(points) - len(todo)

    def finished(i: int, r: dict) -> None:
        results[i] = r
        if sweep:
            # Unnamed until complete: a sweep killed while writing a point leaves no .part.
            write_json_atomic(out.points / f"{keys[i]}.json", r, unnamed=True)
            cache_store(keys[i], r)
            results[i] = _kept(r, i)

    failure = None
    if not sweep:
        check_disk_space(scene, out.path)
        formats = scene.record.format

        def make_sink(names: list[str], text: set[str]) -> SeriesWriter:
            # Into the staging folder: committed with summary.json, or gone with it.
            return SeriesWriter(out.staging, names, text, formats, descriptions(scene, names))

        try:
            with streaming_series(make_sink):
                finished(0, run_point(scene, points[0], progress=progress))
        except ParametersRefused as e:  # the scene's values, not the run, are at fault
            if Path(scene.path).suffix.lower() == ".toml":
                raise SceneError(e.message, scene.path, f"components.{e.instance}.parameters") from None
            # an FMU alone or an SSP: the values came from --set or the SSP's parameter values, not a table
            given = {".fmu": "--set", ".xml": "--set or the OSP file's initial values"}.get(
                Path(scene.path).suffix.lower(), "--set or the SSP's parameter values")
            raise SceneError(e.message, scene.path, f"the values {given} gave {e.instance}") from None
        except SimulationError as e:
            # A failed run keeps its history: written and committed like a
            # result (summary.json says failed), then the error is raised.
            failure = e
            finished(0, failed_point(scene, points[0], e, time.perf_counter() - t_start))
        except OSError as e:  # the series' files (a full disk): named as the user will look for them
            raise _named(e, out) from None
    elif todo:
        from .pool import default_workers, run_in_pool  # a sweep's: start-up of a single run needs no process pool

        if progress:
            from tqdm import tqdm  # a bar's: tqdm's imports take 20-30 ms that a run without one is spared

            bar = tqdm(total=len(points), initial=reused, delay=1.0, desc=printable(scene.path.stem), unit="point")
        else:
            bar = _NoBar()
        n_workers = workers or default_workers(len(todo))
        if scheduler:
            from .dask import run_on_dask  # distributed is an optional extra: imported only when asked for

            done = run_on_dask(scheduler, scene, [points[i] for i in todo], todo)
        elif n_workers <= 1:
            done = ((i, run_point(scene, points[i], catch=True)) for i in todo)
        else:
            done = run_in_pool(scene, [points[i] for i in todo], todo, n_workers)
        try:
            with reusing_systems():  # points in this process share their FMU instances
                for i, r in done:
                    finished(i, r)
                    bar.update()
        finally:
            if hasattr(done, "close"):
                done.close()  # a pool stops its workers now, not when the generator is collected
            bar.close()

    summary = {
        "scene": str(scene.path),
        "title": scene.title,
        "reproduces": scene.reproduces,
        "tool": {"name": "clockwork", "version": __version__},
        "fmus": {n: {"file": str(c.fmu_path), "sha256": c.sha256, "model": c.model_description.modelName}
                 for n, c in scene.components.items()},
        "settings": {"master": scene.master.as_dict(), "experiment": asdict(scene.experiment),
                     "analysis": scene.analysis, "overrides": list(scene.overrides)},
        **({"inputs": {"file": str(scene.inputs.file), "sha256": scene.inputs.sha256,
                       "columns": scene.inputs.columns}} if scene.inputs is not None else {}),
        "points_total": len(points),
        "points_reused": reused,
    }
    unknown = unknown_column(scene, results)
    if unknown is not None:  # before anything is written: the points are kept for the rerun
        i, key, name, there = unknown
        shown = ", ".join(there[:12]) + (f" and {len(there) - 12} more" if len(there) > 12 else "")
        raise SceneError(f"no point has a column {name}: expected one of {shown}",
                         scene.path, f"plot[{i}].{key}")
    try:
        write_outputs(scene, out.staging, results, summary, t_start, plotter)
    except OSError as e:  # name the file the user asked for, not its staged copy
        raise _named(e, out) from None
    out.commit()
    for r in results[:1]:
        if r is not None and isinstance(r.get("series"), StreamedSeries):
            r["series"].committed(out.path)  # the staging folder is gone: read from the result
    if failure is not None:
        raise _failed_run(failure, out.path, summary)
    return summary


def _named(e: OSError, out: OutputDir) -> OSError:
    """`e` naming the file of the output directory instead of its staged copy."""
    if e.filename is None or Path(e.filename).parent != out.staging:
        return e
    # a hidden working file (.timeseries.csv, .timeseries.mat.rows) by the result it makes
    name = Path(e.filename).name.lstrip(".").removesuffix(".rows")
    return OSError(e.errno, e.strerror, str(out.path / name))


def check_disk_space(scene, folder: Path) -> None:
    """Refuse a single run whose series would not fit on the output
    directory's file system (its free space now against the most the
    series takes in the formats asked for), naming what to change."""
    rows, columns = series_size(scene)
    if not rows:
        return
    need = estimate_bytes(rows, columns, scene.record.format)
    try:
        st = os.statvfs(folder)
    except OSError:
        return  # no file system statistics: a full disk is then the run's failure
    free = st.f_bavail * st.f_frsize
    if need > free:
        files = ", ".join(FILE_NAMES[f] for f in scene.record.format)
        span = scene.experiment.stop - scene.experiment.start
        every = scene.record.interval or scene.master.step
        raise SceneError(f"a run of {span:g} s recording {columns} columns every {every:g} s writes up to "
                         f"{need / 1e6:.4g} MB ({rows:.3g} rows into {files}), more than the {free / 1e6:.4g} MB "
                         f"free on the file system of {folder}: free some space, or give a longer record.interval, "
                         "a shorter span (experiment.stop) or fewer record.outputs", scene.path, "experiment.stop")


class _NoBar:
    """The progress bar of a run that shows none."""

    def update(self) -> None:
        pass

    def close(self) -> None:
        pass


def _failed_run(e: SimulationError, where: Path, summary: dict) -> SimulationError:
    """The run's error, saying where its history is; it carries the summary
    (``summary``) and the failed point's data (``history``)."""
    series = (getattr(e, "history", None) or {}).get("series")
    kept = "the series until then and summary.json (it says failed) are" if series else \
        "summary.json (it says failed) is"
    err = SimulationError(f"{e.message}; {kept} in {where}", time=e.time, instance=e.instance, variable=e.variable)
    err.last_point = getattr(e, "last_point", None)
    err.history = getattr(e, "history", None)
    err.summary = summary
    return err
