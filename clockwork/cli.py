"""The `clockwork` command: run, validate, list, info, plot, export-ssp,
export-scene, gallery, bench, export-suite, compare, fit, stability, design.

Bad input of any kind ends with one line `clockwork: error: <message>` on
stderr and exit code 2; a failed simulation with one line and exit code 1.
"""

from __future__ import annotations

import argparse
import atexit
import contextlib
import dataclasses
import errno
import gc
import os
import signal
import sys
import threading
from pathlib import Path

from .version import __version__
from .errors import Interrupted, SceneError, SimulationError, UsageError, printable, say
from .files import absent
from .paths import matplotlib_folder, scenarios_dir
from . import watchdog
from .processes import Child, die_with_parent, fork_child, fork_is_safe


class _Parser(argparse.ArgumentParser):
    """argparse that raises instead of printing usage and exiting."""

    def error(self, message: str):
        sub = self.prog.removeprefix("clockwork").strip()
        raise UsageError(f"{sub}: {message}" if sub else message)


# More worker processes than this is a typo, not a machine.
MAX_WORKERS = 1024


def _positive_int(text: str) -> int:
    shown = text if len(text) <= 20 else text[:17] + "..."
    try:
        n = int(text) if len(text) <= 20 else None
    except ValueError:
        n = None
    if n is None or not 1 <= n <= MAX_WORKERS:
        raise argparse.ArgumentTypeError(f"expected a positive integer up to {MAX_WORKERS}, got {shown!r}")
    return n


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="clockwork", description="Pendulum-clock co-simulation: run and check FMUs (FMI 1.0, 2.0 and 3.0; Co-Simulation and Model Exchange), SSP files and scenes.")
    p.add_argument("--version", action="version", version=f"clockwork {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND", required=True)

    def add_set(sp):
        sp.add_argument("--set", dest="overrides", action="append", default=[], metavar="INST.PARAM=VALUE",
                        help='override a parameter or setting, e.g. pendulum.Q=500, '
                             'escapement.torque="0.4 N.cm", master.step=0.01 (repeatable)')

    def add_input(sp):
        sp.add_argument("--input", default=None, metavar="FILE.csv",
                        help="drive unconnected inputs from samples: a CSV file with a time column and one "
                             "column per input (instance.variable; the variable alone for one FMU)")

    r = sub.add_parser("run", help="run a scene, an SSP or an FMU and write its results")
    r.add_argument("scene", metavar="SCENE.toml|X.ssp|X.ssd|OspSystemStructure.xml|X.fmu")
    r.add_argument("--out", required=True, metavar="DIR", help="output directory (created if its parent exists)")
    add_set(r)
    add_input(r)
    r.add_argument("--workers", type=_positive_int, default=None, metavar="N",
                   help="parallel processes for sweeps (default: the runner's choice)")
    r.add_argument("--scheduler", default=None, metavar="ADDRESS", help="address of a distributed scheduler")
    r.add_argument("--no-progress", action="store_true", help="no progress bar")
    r.add_argument("--no-plot", action="store_true",
                   help="draw no plots, the default one included (no matplotlib process); `clockwork plot DIR` "
                        "draws the scene's plots later")
    r.add_argument("--format", action="append", default=None, metavar="csv|parquet|mat",
                   help="the files of a recorded series: timeseries.csv (the default), .parquet (needs "
                        "pyarrow: pip install 'clockwork[parquet]'), .mat (Modelica tools' result layout); "
                        "several as csv,mat or repeated; replaces the scene's record.format")
    r.set_defaults(func=cmd_run)

    v = sub.add_parser("validate", help="check a scene file (or an .ssp/.ssd, an OSP system structure, an .fmu) "
                                        "without running it")
    v.add_argument("scene", metavar="SCENE.toml|X.ssp|X.ssd|OspSystemStructure.xml|X.fmu")
    add_set(v)
    add_input(v)
    v.set_defaults(func=cmd_validate)

    ls = sub.add_parser("list", help="list the scenes of a directory")
    ls.add_argument("dir", nargs="?", default=None, metavar="DIR", help="default: the repository's scenarios/")
    ls.set_defaults(func=cmd_list)

    i = sub.add_parser("info", help="describe an FMU (capabilities, variables, event indicators) or an SSP "
                                    "(the flattened system)")
    i.add_argument("fmu", metavar="X.fmu|MODEL|X.ssp|X.ssd|OspSystemStructure.xml")
    i.set_defaults(func=cmd_info)

    pl = sub.add_parser("plot", help="draw a finished run's outputs again, grouped by unit")
    pl.add_argument("result", metavar="RESULT_DIR", help="the --out directory of a run (a time series)")
    pl.add_argument("--only", nargs="+", default=None, metavar="NAME",
                    help="only these columns (names or shell patterns, e.g. 'pendulum.*'; an array's name: its "
                         "elements)")
    pl.add_argument("--out", default=None, metavar="FILE.png",
                    help="the file to write [RESULT_DIR/outputs.png]; more pages go to FILE_2.png...")
    pl.set_defaults(func=cmd_plot)

    xs = sub.add_parser("export-scene", help="write the scene `clockwork run X.fmu` (or an OSP system structure) "
                                             "uses, as a scene file to start from")
    xs.add_argument("fmu", metavar="X.fmu|OspSystemStructure.xml")
    xs.add_argument("--out", required=True, metavar="SCENE.toml", help="scene file to write")
    add_set(xs)
    add_input(xs)
    xs.set_defaults(func=cmd_export_scene)

    e = sub.add_parser("export-ssp", help="write a scene as an SSP 1.0 archive for other FMI tools")
    e.add_argument("scene", metavar="SCENE.toml")
    e.add_argument("--out", required=True, metavar="X.ssp", help="archive to write (its folder is created if its parent exists)")
    add_set(e)
    e.add_argument("--container-dir", default=None, metavar="DIR",
                   help="also write DIR/<scene>.json for fmu-manipulation-toolbox's fmucontainer, with the FMUs")
    e.add_argument("--point", type=int, default=None, metavar="N",
                   help="sweep point to export, counted from 0 (required when the scene has a sweep)")
    e.set_defaults(func=cmd_export_ssp)

    xf = sub.add_parser("export-fmu", help="write a scene as one Co-Simulation FMU with its FMUs and the compiled "
                                           "master inside (docs/other-tools.md)")
    xf.add_argument("scene", metavar="SCENE.toml|X.ssp|X.fmu")
    xf.add_argument("--out", required=True, metavar="X.fmu", help="FMU to write (must not exist)")
    xf.add_argument("--fmi", type=int, default=2, choices=(2, 3), help="FMI version of the exported FMU (default 2)")
    add_set(xf)
    xf.set_defaults(func=cmd_export_fmu)

    g = sub.add_parser("gallery", help="run every scene and write the figures with an index page")
    g.add_argument("--out", required=True, metavar="DIR", help="output directory (one folder per scene + index.md)")
    g.add_argument("--quick", action="store_true",
                   help="reduced settings where <scenarios>/quick.json defines them")
    g.add_argument("--scenarios", default=None, metavar="DIR", help="default: the repository's scenarios/")
    g.add_argument("--only", nargs="+", default=None, metavar="STEM", help="only these scenes (file stems)")
    g.add_argument("--workers", type=_positive_int, default=None, metavar="N", help="processes for sweeps")
    g.add_argument("--no-progress", action="store_true", help="no progress bars")
    g.set_defaults(func=cmd_gallery)

    b = sub.add_parser("bench", help="accuracy against run time, beside other masters (see docs/benchmarks.md)")
    b.add_argument("--quick", action="store_true", help="a reduced set of rows (a few minutes)")
    b.add_argument("--out", default="out/bench", metavar="DIR", help="output directory [out/bench]")
    b.add_argument("--no-progress", action="store_true", help="no line per row")
    b.set_defaults(func=cmd_bench)
    st = sub.add_parser("stability", help="overlapping Allan deviation and time deviation of a clock's ticks "
                                           "(a scene's run, a run directory, or --data FILE.csv)")
    st.add_argument("source", nargs="?", default=None, metavar="SCENE|RUN_DIR",
                    help="a scene to run (its ticks), or the --out directory of a run with ticks.csv")
    st.add_argument("--data", default=None, metavar="FILE.csv", help="a tick log: one tick time per row")
    st.add_argument("--out", required=True, metavar="DIR", help="output directory (created if its parent exists)")
    add_set(st)
    st.set_defaults(func=cmd_stability)

    d = sub.add_parser("design", help="find the parameters within bounds that minimise a goal built from "
                                      "sensitivities of the steady rate (see docs/horology.md)")
    d.add_argument("scene", metavar="SCENE.toml")
    d.add_argument("--vary", action="append", default=[], metavar="NAME=LOW..HIGH",
                   help="a parameter to vary within its bounds, e.g. escapement.phi_r=1deg..5deg (repeatable)")
    d.add_argument("--goal", required=True, metavar="GOAL",
                   help="weighted sensitivities, e.g. 'd(E_T_s_per_day)/d(escapement.torque [N.cm]) + "
                        "0.5*d(E_T_s_per_day)/d(air.pressure [hPa])'; minimised: sum (weight x sensitivity)^2")
    d.add_argument("--amplitude", type=float, default=None, metavar="DEG",
                   help="hold this amplitude: the escapement's torque is solved for it at every design")
    d.add_argument("--step", type=float, default=None, metavar="REL",
                   help="relative step of the central differences [1e-2]")
    d.add_argument("--tolerance", type=float, default=None, metavar="S_PER_DAY",
                   help="the steady states' rate tolerance [1e-6 s/day]")
    d.add_argument("--out", required=True, metavar="DIR", help="output directory (created if its parent exists)")
    add_set(d)
    d.set_defaults(func=cmd_design)

    k = sub.add_parser("export-suite", help="write the regression kit: cases with references for other FMI tools")
    k.add_argument("dir", metavar="DIR", help="output directory (created with its parents)")
    k.add_argument("--only", nargs="+", default=None, metavar="CASE", help="only these cases")
    k.add_argument("--fmi-version", type=int, choices=(2, 3), default=2,
                   help="write the cases with the FMI 2.0 (default) or FMI 3.0 build of the FMUs")
    k.set_defaults(func=cmd_export_suite)

    c = sub.add_parser("compare", help="grade a tool's result CSV against a regression-kit case")
    c.add_argument("result", metavar="RESULT.csv", help="a result CSV (fmpy, OMSimulator, libcosim, ecos layouts) "
                   "or a directory of libcosim per-slave CSVs")
    c.add_argument("case", metavar="CASE", help="a case directory of `export-suite`, or a case name")
    c.add_argument("--json", default=None, metavar="FILE", help="also write the grade as JSON")
    c.set_defaults(func=cmd_compare)

    ft = sub.add_parser("fit", help="fit a steady-state scene's parameters to measurements (a CSV file) by "
                                    "weighted least squares (see docs/horology.md)")
    ft.add_argument("scene", metavar="SCENE.toml")
    ft.add_argument("--data", required=True, metavar="FILE.csv",
                    help="one row per measured condition: columns named after scene parameters set them, columns "
                         "named after result columns are measurements, sigma_<column> their uncertainties")
    ft.add_argument("--free", action="append", default=[], metavar="NAME[=GUESS]",
                    help="a parameter to fit within its declared range, e.g. pendulum.Q or "
                         'escapement.torque="0.3 N.cm" (repeatable)')
    ft.add_argument("--out", default=None, metavar="DIR", help="output directory [out/<scene>_fit]")
    add_set(ft)
    ft.add_argument("--workers", type=_positive_int, default=None, metavar="N",
                    help="parallel processes for the rows (default: the runner's choice)")
    ft.add_argument("--scheduler", default=None, metavar="ADDRESS", help="address of a distributed scheduler")
    ft.set_defaults(func=cmd_fit)
    return p


def cmd_fit(args) -> int:
    from .results.files import check_output_dir
    from .run.catalog import load_scene
    from .run.fit import report_lines, run_fit
    from .run.fit_data import parse_free, read_data

    scene = load_scene(args.scene, args.overrides)
    if args.scheduler:
        from .run.dask import require_dask

        require_dask()
    data = read_data(scene, args.data)
    free = parse_free(scene, args.free, data)
    if args.out is None:
        Path("out").mkdir(exist_ok=True)  # the default's parent
        args.out = f"out/{scene.path.stem}_fit"
    made = not Path(args.out).exists()
    out = check_output_dir(args.out)
    import shlex

    command = shlex.join(["clockwork", "fit", args.scene, "--data", args.data]
                         + [a for f in args.free for a in ("--free", f)]
                         + [a for o in args.overrides for a in ("--set", o)] + ["--out", str(args.out)])
    try:
        summary = run_fit(scene, data, free, out, workers=args.workers, scheduler=args.scheduler, command=command)
    except BaseException:
        if made:  # a fit that failed leaves no empty folder behind either
            with contextlib.suppress(OSError):
                out.rmdir()
        raise
    for line in report_lines(summary, out):
        _say_out(line)
    for note in summary.get("notes", []):
        say("note", note)
    if summary.get("plots_failed"):
        p = summary["plots_failed"][0]
        raise SimulationError(f"plot {p['file']} failed: {p['error']} (the fit's numbers are in {out})")
    return 0


def cmd_stability(args) -> int:
    from .run.stability import stability

    summary = stability(args.source, args.data, args.out, args.overrides)
    s = summary["stability"]
    c = s["columns"]
    _say_out(f"stability: {s['ticks']} ticks, mean period {s['mean_period_s']:.9g} s -> {args.out}")
    for tau, a, t in list(zip(c["tau_s"], c["oadev"], c["tdev_s"]))[:: -(-len(c["tau_s"]) // 6)]:  # <= 6 lines
        _say_out(f"  tau {tau:10.4g} s  ADEV {a:.3e}  TDEV {t:.3e} s")
    for key in ("plot_note", "plot_error"):
        if s.get(key):
            say("note", s[key])
    return 0


def cmd_design(args) -> int:
    from .run import design as dz

    summary = dz.design(args.scene, args.vary, args.goal, args.out, args.overrides, amplitude_deg=args.amplitude,
                        step=dz.DEFAULT_STEP if args.step is None else args.step,
                        tolerance_s_per_day=dz.DEFAULT_TOLERANCE_S_PER_DAY if args.tolerance is None
                        else args.tolerance)
    d = summary["design"]
    _say_out(f"design: goal {_short(d['goal']['before'])} -> {_short(d['goal']['after'])} -> {args.out}")
    for name, p in d["parameters"].items():
        _say_out(f"  {name} = {p['value']:.6g} {p['unit'] or ''} (was {p['before']:.6g})")
    for s in d["sensitivities"]:
        _say_out(f"  {s['term']}: {_short(s['before'])} -> {_short(s['after'])} {s['unit']}")
    return 0


def cmd_export_suite(args) -> int:
    from .kit.cases import CASES
    from .kit.suite import export_suite
    from .results.files import check_output_dir

    for name in args.only or []:
        if name not in CASES:
            raise UsageError(f"--only {name}: unknown case (known: {', '.join(CASES)})")
    out = check_output_dir(args.dir)
    index = export_suite(out, args.only, args.fmi_version)
    for e in index["cases"]:
        print(f"{e['name']:<18} {e['kind']:<4} {out / e['path']}")
    print(f"wrote {len(index['cases'])} cases -> {out / 'README.md'}")
    return 0


def cmd_compare(args) -> int:
    import json

    from .atomic import write_text_atomic
    from .kit.grade import compare
    from .results.files import check_output_file

    if args.json is not None:
        check_output_file(args.json, "--json")
    g = compare(args.result, args.case)
    for line in g.table():
        _say_out(line)
    if args.json:
        write_text_atomic(args.json, json.dumps(g.as_dict(), indent=2, allow_nan=False) + "\n")
    return 0 if g.passed else 1


def cmd_bench(args) -> int:
    from . import bench
    from .results.files import check_output_dir

    if args.out == "out/bench":
        Path("out").mkdir(exist_ok=True)  # the default's parent
    out = check_output_dir(args.out)
    cfg = bench.quick_config() if args.quick else bench.full_config()
    command = "clockwork bench" + (" --quick" if args.quick else "") + f" --out {args.out}"
    blob = bench.run_bench(out, cfg, progress=not args.no_progress, command=command)
    bad = [c["check"] for c in blob["checks"] if not c["ok"]]
    print(f"bench: {len(blob['rows'])} rows in {blob['info']['wall_s']:.0f} s -> {out / 'bench.md'}")
    for name in bad:
        print(f"bench: reference check failed: {name}", file=sys.stderr)
    return 1 if bad else 0


def _bars(args) -> bool:
    """Progress bars only where someone watches them: on a terminal. In a
    pipe or a CI log every update would be a line of carriage-return noise
    before the one line that matters."""
    return not args.no_progress and sys.stderr.isatty()


def cmd_gallery(args) -> int:
    from .results.files import check_output_dir
    from .run.gallery import run_gallery

    scenarios = Path(args.scenarios) if args.scenarios else None
    if scenarios is not None and not scenarios.is_dir():
        raise UsageError(f"no such directory: {scenarios}")
    out = check_output_dir(args.out)
    g = run_gallery(out, scenarios, quick=args.quick, only=args.only, workers=args.workers,
                    progress=not args.no_progress, bars=_bars(args))
    n = len(g["scenes"])
    print(f"gallery: {n - len(g['failed'])} of {n} scenes in {g['wall_time_s']:.1f} s -> {out / 'index.md'}")
    for stem in g["failed"]:
        print(f"gallery: {stem} failed", file=sys.stderr)
    return 1 if g["failed"] else 0


def cmd_run(args) -> int:
    from .results.files import check_output_dir
    from .run.catalog import load_scene

    formats = _formats(args.format)
    scene = load_scene(args.scene, args.overrides, args.input, streamed=True)
    if formats:
        scene = dataclasses.replace(scene, record=dataclasses.replace(scene.record, format=formats))
    from .results.series import require_formats

    require_formats(scene.record.format)  # pyarrow for parquet: before the output directory is made
    if args.no_plot:
        scene = dataclasses.replace(scene, plots=())
    if args.scheduler:
        from .run.dask import require_dask

        require_dask()  # before the output directory is made
    if scene.sweep is not None and scene.record.format != ("csv",):
        # Not an error (the scene may be swept as well as run alone), but not silently dropped either.
        say("warning", f"--format and record.format ({','.join(scene.record.format)}) are for a single run's series; "
                       "a sweep writes sweep.csv and a JSON file per point in points/")
    if scene.sweep is None and (args.workers or args.scheduler):
        # Not an error, but not silently dropped either.
        given = [o for o, v in (("--workers", args.workers), ("--scheduler", args.scheduler)) if v]
        say("warning", f"{' and '.join(given)} {'are' if len(given) > 1 else 'is'} for sweeps; "
                       f"{scene.path.name} is a single run, run in this process")
    out = check_output_dir(args.out)
    from .run.scene_run import run_scene

    summary = run_scene(scene, out, workers=args.workers, scheduler=args.scheduler, progress=_bars(args),
                        plot_process=args.plot_process)
    for line in _run_report(scene, out, summary):
        _say_out(line)
    for note in summary.get("plots_notes", []):
        say("note", note)
    failed = summary.get("points_failed", 0)
    if failed:
        # The other points are in the results; the failures are in summary.json.
        raise SimulationError(f"{failed} of {summary['points_total']} sweep points failed "
                              f"(their errors are in {out / 'summary.json'})")
    if summary.get("plots_failed"):
        p = summary["plots_failed"][0]
        raise SimulationError(f"plot {p['file']} ({p['kind']}) failed: {p['error']} "
                              f"({len(summary['plots_failed'])} plot(s) failed; the data are in {out})")
    return 0


def _formats(given: list[str] | None) -> tuple[str, ...]:
    """--format's values ("csv,mat", repeated): the formats in the order first given."""
    from .scene.model import RESULT_FORMATS

    out: list[str] = []
    for text in given or ():
        for name in text.split(","):
            name = name.strip().lower()
            if name not in RESULT_FORMATS:
                raise UsageError(f"--format {text}: expected {', '.join(RESULT_FORMATS)} "
                                 "(several as --format csv,mat or --format repeated)")
            if name not in out:
                out.append(name)
    return tuple(out)


def _run_report(scene, out: Path, summary: dict, most: int = 4) -> list[str]:
    """A few lines on stdout: where the results are, and the headline numbers."""
    n = summary.get("points_total", 1)
    what = f"{n} points" if n > 1 else "1 run"
    if summary.get("points_reused"):
        what += f", {summary['points_reused']} reused"
    lines = [f"{scene.path.stem}: {what} in {summary.get('wall_time_s', 0.0):.1f} s -> {out}"]
    lines.append("  files: " + ", ".join(summary.get("files", [])))
    for p in summary.get("plots_not_drawn", []):
        lines.append(f"  not drawn: {p['file']} ({p['reason']})")
    result = summary.get("result") or {}
    if result.get("stalled"):
        lines.append(f"  stalled: {result.get('reason', 'the clock stopped')}")
    heads = [h for h in summary.get("headlines", []) if h.get("ours") is not None]
    for h in heads[:most]:
        unit = f" {h['unit']}" if h.get("unit") else ""
        paper = f" (paper: {_flag(h['paper'])})" if h.get("paper") is not None else ""
        if not h.get("comparable", True):
            paper = " (--set moved the scene away from the paper's parameters: not comparable)"
        lines.append(f"  {h['quantity']}: {_short(h['ours'])}{unit}{paper}")
    if len(heads) > most:
        lines.append(f"  ... {len(heads) - most} more headline(s) in {out / 'summary.json'}")
    return lines


def _say_out(line: str = "") -> None:
    """A line on stdout that quotes files (a title, names, descriptions):
    what a terminal would act on is escaped (errors.printable)."""
    print(printable(line))


def _short(x) -> str:
    return f"{x:.4g}" if isinstance(x, float) else str(x)


def cmd_validate(args) -> int:
    from .run.catalog import check_loadable, load_scene

    scene = load_scene(args.scene, args.overrides, args.input, streamed=True)  # as `run` will
    from .results.series import require_formats

    require_formats(scene.record.format)
    check_loadable(scene)
    n, m = len(scene.components), len(scene.connections)
    points = len(scene.points())
    extra = f", {points} sweep points" if scene.sweep is not None else ""
    with_set = f", with --set {' '.join(scene.overrides)}" if scene.overrides else ""
    for note in scene.notes:
        _say_out(f"note: {note}")
    if scene.inputs is not None:
        extra += f", inputs from {scene.inputs.file.name}: {', '.join(scene.inputs.columns)}"
    rates = _rates(scene)
    if rates is not None:
        _say_out("steps: " + ", ".join(f"{name} {_component_step(scene, name, rates)}" for name in rates))
    _say_out(f"ok: {scene.title} ({n} component{'s' * (n != 1)}, {m} connection{'s' * (m != 1)}{extra}{with_set})")
    for name, comp in scene.components.items():
        _say_clocks(comp.model_description, name, scene)
    return 0


def cmd_plot(args) -> int:
    from .results.plots.redraw import redraw

    for name in redraw(args.result, args.only, args.out):
        print(f"wrote {name}")
    return 0


def cmd_export_scene(args) -> int:
    from .atomic import write_text_atomic
    from .run.catalog import load_scene
    from .scene.save import scene_toml, toml_problem

    if Path(args.fmu).suffix.lower() not in (".fmu", ".xml"):
        raise UsageError(f"export-scene {args.fmu}: expected an FMU file (X.fmu) or an OSP system structure "
                         "(OspSystemStructure.xml); a scene file is its own scene")
    out = Path(args.out)
    if out.suffix.lower() != ".toml":
        raise UsageError(f"--out {out}: expected a file name ending .toml")
    if not out.parent.is_dir():
        raise UsageError(f"--out {out}: no such directory: {out.parent}")
    if out.is_dir():
        raise UsageError(f"--out {out}: is a directory, expected a scene file name")
    scene = load_scene(args.fmu, args.overrides, args.input)
    problem = toml_problem(scene)
    if problem:
        raise SceneError(problem[1], scene.path, problem[0])
    write_text_atomic(out, scene_toml(scene, out, Path(args.fmu).name))
    if len(scene.components) == 1:
        (name, c), = scene.components.items()
        what = f"{name} ({c.fmu_path.name})"
    else:
        what = f"{len(scene.components)} components, {len(scene.connections)} connections"
    _say_out(f"wrote {out}: {what}, stop {scene.experiment.stop:g} s, step {scene.master.step:g} s, "
             f"{len(scene.record.outputs)} recorded output(s)")
    return 0


def cmd_list(args) -> int:
    from .run.catalog import load_scene

    d = Path(args.dir) if args.dir else scenarios_dir()
    if not d.is_dir():
        raise UsageError(f"{d}: {absent(d, 'a directory of scene files', 'no such directory')}")
    files = sorted(d.glob("*.toml"))
    width = max((len(f.name) for f in files), default=0)
    broken = 0
    for f in files:
        try:
            s = load_scene(f)
        except SceneError as e:
            broken += 1
            where = f"{e.key}: " if e.key else ""
            _say_out(f"{f.name:<{width}}  ERROR: {where}{e.detail}")
            continue
        line = f"{f.name:<{width}}  {s.title}"
        if s.reproduces:
            line += f"  [reproduces {s.reproduces}]"
        _say_out(line)
    return 1 if broken else 0


def cmd_export_ssp(args) -> int:
    from .results.files import check_output_file
    from .run.catalog import load_scene
    from .scene.ssp import PARAMETER_SET, export_ssp

    scene = load_scene(args.scene, args.overrides)
    if scene.inputs is not None:  # not silently dropped
        raise UsageError(f"{args.scene}: [inputs] drives inputs from {scene.inputs.file}, which an SSP cannot "
                         "carry: export a copy of the scene without [inputs]")
    out = Path(args.out)
    if out.suffix != ".ssp":
        raise UsageError(f"--out {out}: expected a file name ending .ssp")
    if not out.parent.is_dir():
        if not out.parent.parent.is_dir():  # like `run --out`: one missing level is created
            raise UsageError(f"--out {out}: no such directory: {out.parent}")
        out.parent.mkdir()
    check_output_file(out, "--out")
    points = scene.points()
    point = None
    if scene.sweep is not None:
        if args.point is None:
            raise UsageError(f"{args.scene} has a sweep of {len(points)} points: choose one with --point N")
        if not 0 <= args.point < len(points):
            raise UsageError(f"--point {args.point}: expected 0 to {len(points) - 1}")
        point = points[args.point]
    elif args.point not in (None, 0):
        raise UsageError(f"--point {args.point}: {args.scene} has no sweep")
    if args.container_dir is not None and not Path(args.container_dir).parent.is_dir():
        raise UsageError(f"--container-dir {args.container_dir}: no such directory: "
                         f"{Path(args.container_dir).parent}")
    export_ssp(scene, out, point)
    n = len(scene.components)
    print(f"wrote {out}: {n} component{'s' * (n != 1)}, step {scene.master.step:g} s, "
          f"parameter set {PARAMETER_SET!r}")
    if args.container_dir is not None:
        from .scene.ssp import write_container_description

        js = write_container_description(scene, args.container_dir, point)
        print(f"wrote {js}: fmucontainer -container {js.name} -fmu-directory {js.parent}")
    return 0


def cmd_export_fmu(args) -> int:
    from .run.export_fmu import export_fmu

    summary = export_fmu(args.scene, args.out, args.fmi, args.overrides)
    print(f"wrote {args.out}: {summary['instances']} instance{'s' * (summary['instances'] != 1)}, "
          f"{summary['parameters']} parameters, {summary['outputs']} outputs, {summary['inputs']} inputs "
          f"(FMI {args.fmi}.0 Co-Simulation, {summary['model_identifier']}; {', '.join(summary['platforms'])})")
    return 0


def _flag(x) -> str:
    if isinstance(x, bool):
        return "true" if x else "false"
    return "-" if x is None else str(x)


def _link(c) -> str:
    """A connection with its transformation, as `info` shows it."""
    if c.adds:
        return f"{c} (added to the links above it: a sum)"
    if (c.factor, c.offset) == (1.0, 0.0):
        return str(c)
    return f"{c} (x {c.factor:g}{f' + {c.offset:g}' if c.offset else ''})"


def _rates(scene) -> dict[str, int] | None:
    """{instance: decimation factor} where the scene's components step at different rates, else None."""
    from .engine.multirate import is_multirate
    from .scene.model import rates

    found = rates(scene.master, scene.components)
    return found if is_multirate(found) else None


def _component_step(scene, name: str, rates: dict[str, int]) -> str:
    """A component's own step, as `info` and `validate` show it (multi-rate)."""
    k = rates[name]
    return f"{k * scene.master.step:g} s ({k} base step{'s' * (k != 1)} of {scene.master.step:g} s)"


def _info_ssp(path: str) -> int:
    """`info` on an .ssp/.ssd or an OSP system structure: the flattened system as clockwork runs it."""
    from .run.catalog import load_scene

    scene = load_scene(path)
    n, m = len(scene.components), len(scene.connections)
    kind = "OSP" if Path(scene.path).suffix.lower() == ".xml" else "SSP"
    _say_out(f"{scene.title} ({kind}: {n} component{'s' * (n != 1)}, {m} connection{'s' * (m != 1)})")
    _say_out(f"  file         {scene.path}")
    _say_out(f"  sha256       {scene.sha256}")
    _say_out("components:")
    width = max(len(c) for c in scene.components)
    rates = _rates(scene)
    for name, c in scene.components.items():
        params = ", ".join(f"{k} = {v!r}" for k, v in c.parameters.items())
        _say_out(f"  {name:<{width}}  {c.model_name}  {c.fmu_shown}")
        if rates is not None:
            _say_out(f"  {'':<{width}}  step: {_component_step(scene, name, rates)}")
        if params:
            _say_out(f"  {'':<{width}}  parameters: {params}")
    _say_out("connections:")
    for c in scene.connections:
        _say_out(f"  {_link(c)}")
    _say_out(f"experiment: start {scene.experiment.start:g} s, stop {scene.experiment.stop:g} s")
    _say_out("master: " + ", ".join(f"{k} = {v}" for k, v in scene.master.as_dict().items()))
    interval = f", every {scene.record.interval:g} s" if scene.record.interval else ""
    _say_out(f"record{interval}: " + ", ".join(f"{i}.{v}" for i, v in scene.record.outputs))
    return 0


def _say_clocks(md, name: str | None = None, scene=None) -> None:
    """FMI 3.0 clocks and when each ticks (docs/clocks.md), in a scene with
    what ticks each triggered input clock; nothing without clocks."""
    from .fmi.clocks import clock_lines, clock_table, is_scheduled

    lines = clock_lines(md, "  " if name is None else f"  {name}.")
    if lines and scene is not None:
        columns = set(scene.inputs.columns) if scene.inputs is not None else set()
        for k, c in enumerate(clock_table(md).clocks.values()):
            if c.causality == "input" and c.variability == "triggered":
                sources = [f"{x.src_instance}.{x.src_var}" for x in scene.connections
                           if x.dst_instance == name and x.dst_var == c.name]
                sources += ["the input file"] * (f"{name}.{c.name}" in columns)
                lines[k] += f"; ticked here by {', '.join(sources) or 'nothing: it never ticks'}"
            elif c.causality == "output":
                targets = [f"{x.dst_instance}.{x.dst_var}" for x in scene.connections
                           if x.src_instance == name and x.src_var == c.name]
                lines[k] += f"; ticks {', '.join(targets) or 'no connected clock'}"
    if lines:
        how = "Scheduled Execution" if is_scheduled(md) else "Co-Simulation, Event Mode"
        _say_out(f"clocks{'' if name is None else f' of {name}'} ({how}):")
        for line in lines:
            _say_out(line)


def cmd_info(args) -> int:
    from .fmi.description import (NAME_RE, FmuError, fmi1_details, read_fmu, resolve_fmu, shape_text, type_name,
                                   var_unit)

    osp_folder = (Path(args.fmu) / "OspSystemStructure.xml").is_file()  # libcosim's form: the file's folder
    if Path(args.fmu).suffix.lower() in (".ssp", ".ssd", ".xml") or osp_folder:
        return _info_ssp(args.fmu)
    if not args.fmu.endswith(".fmu") and not NAME_RE.match(args.fmu):  # neither an FMU nor a model name
        scene = "; a scene file is checked by `clockwork validate`" if args.fmu.endswith(".toml") else ""
        raise UsageError(f"{args.fmu or repr(args.fmu)}: expected an FMU (X.fmu, or a model name such as "
                         f"Pendulum), an SSP (X.ssp, X.ssd) or an OSP system structure (OspSystemStructure.xml)"
                         f"{scene}")
    try:
        path = resolve_fmu(args.fmu)
        md, digest, indicators = read_fmu(path, need_binary=False)
    except FmuError as e:
        raise UsageError(str(e)) from None
    cs = md.coSimulation
    faces = [n for n, i in (("Co-Simulation", cs), ("Model Exchange", md.modelExchange)) if i is not None]
    _say_out(f"{md.modelName} (FMI {md.fmiVersion} {' and '.join(faces)})")
    _say_out(f"  file         {path}")
    _say_out(f"  sha256       {digest}")
    fmi3 = md.fmiVersion.startswith("3.")
    _say_out(f"  {'token' if fmi3 else 'guid':<12} {md.instantiationToken if fmi3 else md.guid}")
    _say_out(f"  generated by {md.generationTool or '-'}")
    if md.description:
        _say_out(f"  description  {md.description}")
    _say_out("capabilities:")
    caps = ("canHandleVariableCommunicationStepSize", "canGetAndSetFMUstate", "canSerializeFMUstate",
            "canInterpolateInputs", "maxOutputDerivativeOrder")
    if fmi3:  # FMI 3.0 has no input derivatives, and adds events
        caps = caps[:3] + ("maxOutputDerivativeOrder", "hasEventMode", "mightReturnEarlyFromDoStep",
                           "providesIntermediateUpdate")
    if md.fmiVersion == "1.0":  # no FMU state; an execution tool for CoSimulation_Tool
        caps = ("canHandleVariableCommunicationStepSize", "canInterpolateInputs", "maxOutputDerivativeOrder",
                "canRunAsynchronuously", "needsExecutionTool")
    if cs is None:  # Model Exchange only: what the master's wrapper reads
        cs = md.modelExchange
        caps = ("canGetAndSetFMUstate", "canSerializeFMUstate", "needsCompletedIntegratorStep")
    for cap in caps:
        _say_out(f"  {cap:<40} {_flag(getattr(cs, cap, None))}")
    if md.modelExchange is not None:
        _say_out(f"  {'continuous states (Model Exchange)':<40} {len(md.derivatives)}")
        _say_out(f"  {'event indicators (Model Exchange)':<40} {md.numberOfEventIndicators or 0}")
    negated = fmi1_details(md).negated
    rows = [("name", "causality", "variability", "type", "unit", "start", "min", "max", "description")]
    for v in md.modelVariables:
        kind = type_name(md, v) + (f"[{shape_text(v.shape)}]" if v.shape else "")  # an FMI 3.0 array: its shape
        start = " ".join(v.start) if isinstance(v.start, list) else v.start
        alias = "" if v.alias is None or md.fmiVersion != "1.0" else (
            f"(negated alias of {v.alias.name}) " if v.name in negated else f"(alias of {v.alias.name}) ")
        rows.append((v.name, v.causality or "-", v.variability or "-", kind, var_unit(v) or "-",
                     _flag(start), _flag(v.min), _flag(v.max), alias + (v.description or "")))
    widths = [max(len(r[k]) for r in rows) for k in range(len(rows[0]) - 1)]
    _say_out(f"variables ({len(md.modelVariables)}):")
    for r in rows:
        _say_out("  " + "  ".join(c.ljust(w) for c, w in zip(r, widths)) + "  " + r[-1])
    _say_out(f"event indicators: {', '.join(indicators) if indicators else 'none'}")
    _say_clocks(md)
    from .scene.fmu_alone import experiment_times, instance_name

    times, step = experiment_times(md, path)
    tol = getattr(md.defaultExperiment, "tolerance", None) if md.defaultExperiment is not None else None
    _say_out(f"clockwork run {path.name}: instance {instance_name(md)}, start {times['start']:g} s, "
             f"stop {times['stop']:g} s, step {step:g} s, tolerance {tol if tol not in (None, '') else '-'} "
             "(the DefaultExperiment, else fmpy's defaults)")
    return 0


# The machine failed the run (not the user's input).
# The machine ran out of something: a failed run (1), not bad input (2).
_RUN_FAILURES = (errno.ENOSPC, errno.EDQUOT, errno.EIO, errno.ENOMEM, errno.EFBIG, errno.EMFILE, errno.ENFILE,
                 errno.EAGAIN)


def _error(message: object) -> None:
    say("error", message)


def console() -> int:
    """The installed `clockwork` command and `python -m clockwork`: main(),
    then a quick exit. At exit the interpreter's collector would walk every
    object the run made or imported (a tenth of a second once matplotlib is
    loaded) only for the operating system to free the memory anyway;
    frozen objects are left out of that walk. Files are closed and atexit
    handlers run as usual.

    `clockwork run` forks its plot process first thing (_plot_process),
    before numpy and clockwork's modules are imported, and ends it here
    whatever became of the run."""
    _std_streams_open()
    # numpy's OpenBLAS starts a thread per core, and each spins for a while
    # after every call: on the cores that the plot process and the pool's
    # workers need. clockwork's arrays are far too small to gain from them.
    # A value the user set stands (before numpy is imported: read once).
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    plot_process = _plot_process(sys.argv[1:])
    try:
        code = main(plot_process=plot_process)
    finally:
        if plot_process is not None:
            plot_process.close()
    gc.freeze()
    if code > 128:
        # Interrupted: our cleanup is done (the with blocks ran; atexit next).
        # A pool's manager thread may wait forever for a message that a killed
        # worker left half-written; the interpreter would join it. Leave now.
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except (OSError, ValueError):
                pass
        atexit._run_exitfuncs()
        os._exit(code)
    return code


def _plot_process(argv: list[str]) -> Child | None:
    """For `clockwork run` with plots: a plot process forked now, which
    imports numpy, matplotlib and the plot kinds on the other core while
    this process imports what the run needs, loads the scene and runs its
    points; run_scene adopts it (clockwork.results.plots.background). None
    for the other commands, and when the heavy modules are already here
    (main() called within a Python program: nothing to gain) or forking is
    not safe. The arguments are only glanced at: a run that turns out to
    be bad input or to have no plots ends the process unused."""
    if argv[:1] != ["run"] or "--no-plot" in argv or "numpy" in sys.modules or not fork_is_safe():
        return None
    matplotlib_folder()  # its folder must outlive the child: made here
    try:
        return fork_child(_plot_process_body)
    except OSError:  # no more processes or pipes: run_scene forks later or draws here
        return None


def _plot_process_body(parent: int, job_fd: int, answer_fd: int) -> None:
    for sig in _STOP_SIGNALS:  # before its long imports: an interrupted run is the parent's to report
        signal.signal(sig, signal.SIG_IGN)
    die_with_parent(parent)
    gc.disable()  # imports make long-lived objects only: serve freezes them and enables the collector
    # Imported in the child only: the command's own start stays light.
    from .results.plots.background import serve

    # An FMU's run (console: the command's own arguments) has one plot, its default, which
    # Pillow draws: no matplotlib to import ahead
    fmu = any(a.lower().endswith(".fmu") for a in sys.argv[2:] if not a.startswith("-"))
    serve(None, parent, job_fd, answer_fd, default_plot_only=fmu)


def _std_streams_open() -> None:
    """A command started with a standard stream closed (`>&-`) gets /dev/null
    there: else the next file opened would take its number, and what is
    printed would land in it (or, with sys.stdout None, fail)."""
    for fd, name, mode in ((0, "stdin", "r"), (1, "stdout", "w"), (2, "stderr", "w")):
        try:
            os.fstat(fd)
        except OSError:
            null = os.open(os.devnull, os.O_RDWR)
            if null != fd:
                os.dup2(null, fd)
                os.close(null)
        if getattr(sys, name) is None:
            setattr(sys, name, open(fd, mode, closefd=False))


def main(argv=None, plot_process: Child | None = None) -> int:
    """The command line `argv` (default: sys.argv[1:]): its exit code.
    `plot_process`: one forked for `clockwork run` (console)."""
    with _signals_as_interrupts():
        return _main(argv, plot_process)


# Signals that end a run as Ctrl-C does: one line, exit code 128 + the signal's number.
_STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)


@contextlib.contextmanager
def _signals_as_interrupts():
    """SIGTERM and SIGHUP raise Interrupted where the process is (SIGINT raises
    KeyboardInterrupt), so that every `with` and `finally` cleans up: the
    staging folder, the worker and plot processes, the scratch folder. Once
    one has arrived, more of them wait until the cleanup is done."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    first: list[int] = []

    def stop(signo, frame):
        if first:
            return  # already on the way out
        watchdog.taken(signo)
        first.append(signo)
        if signo == signal.SIGINT:
            raise KeyboardInterrupt
        raise Interrupted(signo)

    before = {sig: signal.signal(sig, stop) for sig in _STOP_SIGNALS
              if signal.getsignal(sig) in (signal.default_int_handler, signal.SIG_DFL)}
    # A signal that arrives while an FMU call blocks (the main thread never
    # gets to run `stop`) ends the run from the watchdog's thread.
    watchdog.start()
    try:
        yield
    finally:
        watchdog.stop()
        for sig, handler in before.items():
            signal.signal(sig, handler)


def _main(argv=None, plot_process: Child | None = None) -> int:
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as e:  # --help / --version
        return e.code if isinstance(e.code, int) else 0
    except UsageError as e:
        _error(e)
        return 2
    args.plot_process = plot_process
    try:
        return args.func(args)
    except (SceneError, UsageError) as e:
        _error(e)
        return 2
    except SimulationError as e:
        _error(e)
        return 1
    except BrokenPipeError:  # e.g. `clockwork list | head`: the reader has what it wanted
        # Point stdout at /dev/null so the interpreter's final flush stays quiet.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except OSError as e:
        # Writing results: disk full, file size limit, permissions, a path below a regular file.
        where = f"{e.filename}: " if e.filename else ""
        if e.errno in _RUN_FAILURES:
            _error(f"{where}{e.strerror or e}: a limit of the machine, not bad input (free some, or raise "
                   "the limit, and run again)")
            return 1
        _error(f"{where}{e.strerror or e}")
        return 2
    except MemoryError:
        _error("out of memory (ulimit -v or the machine's memory): record fewer outputs, a longer "
               "record.interval or a shorter experiment, or run on a machine with more memory")
        return 1
    except KeyboardInterrupt as e:
        signo = getattr(e, "signo", signal.SIGINT)
        _error("interrupted" if signo == signal.SIGINT else f"interrupted by {signal.Signals(signo).name}")
        return 128 + signo

