"""Write the regression kit: every case with its reference, events, tube and README.

Layout (DIR is ``clockwork export-suite DIR``)::

    DIR/README.md, DIR/suite.json
    DIR/fmus/2.0/cs/linux64/clockwork/<version>/<Model>/    single-FMU cases,
        <Model>.fmu  <Model>_ref.csv  <Model>_ref.opt        the FMI cross-check layout
        [<Model>_in.csv]  <Model>_events.csv  <Model>_case.json  README.md
                                                            (checked by fmpy.cross_check.validate_vendor_repo)
    DIR/ssp/<Name>/                                           coupled cases, in the same spirit
        <Name>.ssp  <Name>_ref.csv  <Name>_ref.opt  [<Name>_in.csv]  <Name>_events.csv  <Name>_case.json  README.md

``<Name>_case.json`` holds what ``clockwork compare`` grades with: the
expected event times (ticks and escapement switches, from the reference),
the tolerances (tube half-widths, event-time tolerances), the output grid
and the signal names. All files are written atomically; JSON is strict.

The same reference files are also described in the layout of the FMI
layered standard for related files (FMI-LS-REF): a manifest
``extra/org.fmi-standard.fmi-ls-ref/fmi-ls-manifest.xml`` whose
``<Related>`` entries name each file with its role (``result`` for the
reference and the events, ``testcase`` for the case description and the
input, ``document`` for the README). A single-FMU case carries it inside
its FMU (with the files beside the manifest, and
``documentation/fmi-ls-ref.txt``); a coupled case in its case directory,
pointing at the files there.

``fmi_version=3`` writes the cases with the FMI 3.0 builds of the bundled
FMUs (``master.fmi_version = 3``), single-FMU cases under
``fmus/3.0/cs/x86_64-linux/``.
"""

from __future__ import annotations

import io
import json
import platform
import shutil
import zipfile
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np

from ..version import __version__
from ..atomic import write_bytes_atomic, write_text_atomic
from .cases import CASES, Case, load_case_scene, reference
from .csvio import write_csv

PLATFORM = "linux64"
PLATFORM_FMI3 = "x86_64-linux"  # FMI 3.0 names platforms by tuple
LS_REF = "extra/org.fmi-standard.fmi-ls-ref"


def case_dir(root: Path, c: Case, fmi_version: int = 2) -> Path:
    if c.kind == "fmu":
        version, plat = ("3.0", PLATFORM_FMI3) if fmi_version == 3 else ("2.0", PLATFORM)
        return root / "fmus" / version / "cs" / plat / "clockwork" / __version__ / c.name
    return root / "ssp" / c.name


# What each file of a case is, for the FMI-LS-REF manifest: (suffix, MIME type, role, description).
def _related(c: Case) -> list[tuple[str, str, str, str]]:
    files = [(f"{c.name}_ref.csv", "text/csv", "result",
              "reference result: monolithic scipy DOP853 solution at rtol 1e-12, every switch located"),
             (f"{c.name}_events.csv", "text/csv", "result", "expected event times (ticks and escapement switches)"),
             (f"{c.name}_ref.opt", "text/plain", "testcase", "StartTime, StopTime, StepSize (output grid), RelTol"),
             (f"{c.name}_case.json", "application/json", "testcase",
              "tolerances, event times and signal names that clockwork compare grades with")]
    if c.jump:
        files.append((f"{c.name}_in.csv", "text/csv", "testcase", f"the input {c.jump[1]} (a step)"))
    files.append(("README.md", "text/markdown", "document", "what the case tests and its acceptance rules"))
    return files


def _manifest(c: Case, prefix: str) -> str:
    """The FMI-LS-REF manifest for a case's files; `prefix` leads from the
    manifest's folder to them."""
    rows = [f"  <Related type={quoteattr(t)} source={quoteattr(prefix + name)} role={quoteattr(role)} "
            f"description={quoteattr(desc)}>\n    <Label name={quoteattr('clockwork-case:' + c.name)}/>\n"
            f"  </Related>" for name, t, role, desc in _related(c)]
    return ('<?xml version="1.0" encoding="UTF-8"?>\n'
            '<fmiReferences xmlns:fmi-ls="http://fmi-standard.org/fmi-ls-manifest"\n'
            '    fmi-ls:fmi-ls-name="org.fmi-standard.fmi-ls-ref" fmi-ls:fmi-ls-version="1.0.0-alpha.1"\n'
            '    fmi-ls:fmi-ls-description="Layered Standard providing information on related files included '
            'in an FMU.">\n' + "\n".join(rows) + "\n</fmiReferences>\n")


def _fmu_with_references(fmu: bytes, c: Case, d: Path) -> bytes:
    """The FMU with the case's files and manifest in extra/org.fmi-standard.fmi-ls-ref/."""
    out = io.BytesIO()
    with zipfile.ZipFile(io.BytesIO(fmu)) as src, zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as z:
        for info in src.infolist():
            if not (info.filename.startswith(LS_REF + "/") or info.filename == "documentation/fmi-ls-ref.txt"):
                z.writestr(info, src.read(info))
        z.writestr(f"{LS_REF}/fmi-ls-manifest.xml", _manifest(c, ""))
        for name, *_ in _related(c):
            z.write(d / name, f"{LS_REF}/{name}")
        z.writestr("documentation/fmi-ls-ref.txt",
                   f"{c.name}: {c.title}.\n\nThe reference results of clockwork's regression-kit case {c.name} "
                   f"are in {LS_REF}/ (fmi-ls-manifest.xml lists them with their roles); README.md there "
                   "says what the case tests and how a result is graded.\n")
    return out.getvalue()


def _ref_opt(c: Case) -> str:
    # fmpy.util.read_ref_opt_file: "<Key>,<value>" lines
    return (f"StartTime,{0.0!r}\nStopTime,{c.stop!r}\nStepSize,{c.grid!r}\nRelTol,{1e-12!r}\n")


def _json(obj) -> str:
    return json.dumps(obj, indent=2, allow_nan=False) + "\n"


def _readme(c: Case, meta: dict, notes: list[str]) -> str:
    tol = c.tolerances
    lines = [f"# {c.name}", "", c.title + ".", "", "## What it tests", "", c.tests, ""]
    lines += ["## Files", ""]
    if c.kind == "fmu":
        lines += [f"- `{c.name}.fmu`: the FMU ({meta['fmi']} Co-Simulation); simulate it at its start values. "
                  f"It carries these files too, in `{LS_REF}/` with the manifest of the FMI layered standard "
                  "for related files (FMI-LS-REF).",
                  ]
    else:
        lines += [f"- `{c.name}.ssp`: the system (SSP 1.0: the FMUs ({meta['fmi']}), connections, parameter sets "
                  f"named `clockwork`, fixed step {meta['scene_step']:g} s as vendor annotations).",
                  f"- `{LS_REF}/fmi-ls-manifest.xml`: these files with their roles, in the layout of the FMI "
                  "layered standard for related files (FMI-LS-REF)."]
    lines += [f"- `{c.name}_ref.csv`: the reference on the output grid (every {c.grid:g} s, 0 to {c.stop:g} s): "
              "the monolithic scipy DOP853 solution at rtol 1e-12 with every escapement switch located "
              "(`clockwork.physics.reference`), known to about 1e-10.",
              f"- `{c.name}_ref.opt`: StartTime, StopTime, StepSize (the output grid), RelTol.",
              f"- `{c.name}_events.csv`: the expected event times (`time,event`: tick = upward zero crossing of phi, "
              "switch = change of the escapement's mode), from the reference.",
              f"- `{c.name}_case.json`: the same event times, the tolerances, signal names "
              "(read by `clockwork compare`)."]
    if c.jump:
        lines.append(f"- `{c.name}_in.csv`: the input `{c.jump[1]}`: {c.jump[2]:g} until t = {c.jump[0]!r} s, "
                     f"then {c.jump[3]:g} (a repeated time row marks the step).")
    lines += ["", "## Acceptance", "",
              f"Write the result at the multiples of {c.grid:g} s (extra rows, e.g. at events, are welcome) with "
              "columns named as the reference's (or any name ending with them, e.g. `model.root.pendulum.phi`), "
              f"then `clockwork compare RESULT.csv {c.name}/`. It passes when", ""]
    for s, width in tol.tube.items():
        lines.append(f"- every grid row of `{s}` is within {width:g} of the reference (fmpy's cross-check band, "
                     "dx = 1 sample, no outlier allowed);")
    lines.append(f"- each of the {meta['events']['count']['ticks']} ticks (upward zero crossings of `{c.phi}`) "
                 f"is within {tol.ticks_s:g} s of its expected time;")
    if c.switch_signal:
        lines.append(f"- each of the {meta['events']['count']['switches']} escapement switches (sign changes of "
                     f"`{c.switch_signal}`: the time of the first row with the new sign when it lies off the grid, "
                     f"a row written at the event; else placed by the kink the switch leaves in `{c.w}`) is within "
                     f"{tol.switches_s:g} s of its expected time,")
        lines.append("- and no tick or switch is missing or extra.")
    if notes:
        lines += ["", "## Notes", ""] + [f"- {n}" for n in notes]
    return "\n".join(lines) + "\n"


def write_case(root: Path, c: Case, fmi_version: int = 2) -> dict:
    d = case_dir(root, c, fmi_version)
    d.mkdir(parents=True, exist_ok=True)
    # A case is its FMUs, connections, parameters and step; how clockwork's
    # master would feed inputs is not part of it, and FMI 3.0 has no input
    # derivatives for extrapolation or strong coupling.
    fmi3 = ("master.fmi_version=3", "master.extrapolation=0", "master.iterations=0")
    scene = load_case_scene(c, fmi3 if fmi_version == 3 else ())
    ref = reference(c)
    data = np.column_stack([ref.time] + [ref.columns[s] for s in c.signals])
    write_csv(d / f"{c.name}_ref.csv", ["time"] + list(c.signals), data)
    write_text_atomic(d / f"{c.name}_ref.opt", _ref_opt(c))
    if c.kind != "fmu":
        from ..scene.ssp import export_ssp

        export_ssp(scene, d / f"{c.name}.ssp")
    if c.jump:
        t, sig, before, after = c.jump
        write_csv(d / f"{c.name}_in.csv", ["time", sig],
                  np.array([[0.0, before], [t, before], [t, after], [c.stop, after]]))
    meta = {
        "name": c.name, "kind": c.kind, "title": c.title, "tests": c.tests,
        "stop": c.stop, "grid": c.grid, "scene_step": scene.master.step,
        "fmi": f"FMI {fmi_version}.0",
        "reference": f"{c.name}_ref.csv",
        "signals": {"tube": list(c.tube_signals), "phi": c.phi, "w": c.w, "switch": c.switch_signal},
        "tolerances": {"tube": dict(c.tolerances.tube), "ticks_s": c.tolerances.ticks_s,
                       "switches_s": c.tolerances.switches_s},
        "events": {"ticks": [float(x) for x in ref.ticks], "switches": [float(x) for x in ref.switches],
                   "count": {"ticks": int(len(ref.ticks)), "switches": int(len(ref.switches))}},
        "input": None if not c.jump else {"file": f"{c.name}_in.csv", "signal": c.jump[1], "time": c.jump[0],
                                          "before": c.jump[2], "after": c.jump[3]},
        "generated_by": f"clockwork {__version__}",
    }
    write_text_atomic(d / f"{c.name}_case.json", _json(meta))
    ev = sorted([(float(x), "tick") for x in ref.ticks] + [(float(x), "switch") for x in ref.switches])
    write_text_atomic(d / f"{c.name}_events.csv", "time,event\n" + "".join(f"{t!r},{k}\n" for t, k in ev))
    write_text_atomic(d / "README.md", _readme(c, meta, ref.notes + list(c.notes)))
    if c.kind == "fmu":
        comp = next(iter(scene.components.values()))
        write_bytes_atomic(d / f"{c.name}.fmu", _fmu_with_references(Path(comp.fmu_path).read_bytes(), c, d))
    else:
        (d / LS_REF).mkdir(parents=True, exist_ok=True)
        write_text_atomic(d / LS_REF / "fmi-ls-manifest.xml", _manifest(c, "../../"))
    return {"name": c.name, "kind": c.kind, "path": str(d.relative_to(root)), "stop": c.stop, "grid": c.grid,
            "ticks": int(len(ref.ticks)), "switches": int(len(ref.switches)),
            "tolerances": meta["tolerances"]}


def export_suite(root: str | Path, names: list[str] | None = None, fmi_version: int = 2) -> dict:
    """Write every case (or `names`) under root, with the FMI 2.0 or 3.0
    build of the bundled FMUs; returns the suite's index."""
    root = Path(root)
    chosen = [CASES[n] for n in (names or list(CASES))]
    index = {"generated_by": f"clockwork {__version__}", "platform": PLATFORM_FMI3 if fmi_version == 3 else PLATFORM,
             "fmi_version": fmi_version, "machine": platform.machine(), "cases": []}
    for c in chosen:
        d = case_dir(root, c, fmi_version)
        if d.exists():  # a re-export replaces the case whole
            shutil.rmtree(d)
        index["cases"].append(write_case(root, c, fmi_version))
    write_text_atomic(root / "suite.json", _json(index))
    lines = ["# clockwork regression kit", "",
             "Cases for FMI co-simulation tools, with references from a monolithic solution of the clock "
             "equations. Grade a result with `clockwork compare RESULT.csv CASE_DIR` "
             "(docs/regression-kit.md in the clockwork repository).", "",
             "| case | kind | directory | horizon | grid | ticks | switches |", "|---|---|---|---|---|---|---|"]
    for e in index["cases"]:
        lines.append(f"| {e['name']} | {e['kind']} | `{e['path']}` | {e['stop']:g} s | {e['grid']:g} s | "
                     f"{e['ticks']} | {e['switches']} |")
    write_text_atomic(root / "README.md", "\n".join(lines) + "\n")
    return index
