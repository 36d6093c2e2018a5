"""Shared pieces of the interop tests: FMUs, exported archives, tool runs.

(A module of its own, not conftest.py: test modules import it by name, and
tests/conftest.py already owns the name `conftest`.)

Every external tool runs in a subprocess (clockwork/bench/peer_tool.py): a crash in native
code (libcosim, ecos) must fail one test, not end pytest.
"""

from __future__ import annotations

import functools
import importlib
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from clockwork.bench import peer_tool

HERE = Path(__file__).resolve().parent
PEER_TOOL = Path(peer_tool.__file__)
ROOT = HERE.parents[1]
FMU_DIR = Path(os.environ.get("CW_FMU_DIR", ROOT / "fmus"))
SCENES = ["core_grasshopper", "core_grasshopper_drag", "core_vibration"]
PERIODS = 100
RELATIVE_TOLERANCE = 1e-9  # same algorithm, same numbers


def require(module: str):
    """Import a tool's Python package; skip when missing, except in CI where
    everything is installed and a missing tool is a failure."""
    try:
        return importlib.import_module(module)
    except Exception as e:  # ImportError, or OSError from a missing shared library
        reason = f"{module} cannot be imported ({type(e).__name__}: {e}); install the extra: pip install -e .[interop]"
        if os.environ.get("CI"):
            pytest.fail(reason)
        pytest.skip(reason)


@functools.lru_cache(maxsize=None)
def scene(name: str):
    from clockwork.run import load_scene

    os.environ["CLOCKWORK_FMU_DIR"] = str(FMU_DIR)
    return load_scene(ROOT / "scenarios" / f"{name}.toml")


def steps(sc) -> int:
    """Communication steps of the scene's experiment (which covers 100 periods)."""
    return round((sc.experiment.stop - sc.experiment.start) / sc.master.step)


def recorded(sc) -> list[str]:
    names = ["pendulum.phi", "pendulum.w", "pendulum.tick_time", "pendulum.amplitude"]
    if "vibration" in sc.components:
        names.append("vibration.a2")
    return names


def compared(sc) -> list[str]:
    """Outputs without direct feedthrough, compared step by step."""
    return [n for n in recorded(sc) if n.split(".")[1] in ("phi", "w", "a2")]


@functools.lru_cache(maxsize=None)
def exported(name: str, directory: str) -> Path:
    from clockwork.scene.ssp import export_ssp

    out = Path(directory) / f"{name}.ssp"
    export_ssp(scene(name), out)
    return out


def run_tool(tool: str, name: str, directory: str) -> dict[str, np.ndarray]:
    sc = scene(name)
    ssp = exported(name, directory)
    out = Path(directory) / f"{name}.{tool}.npz"
    cmd = [sys.executable, str(PEER_TOOL), tool, str(ssp), "--steps", str(steps(sc)),
           "--step", repr(sc.master.step), "--out", str(out), *recorded(sc)]
    env = dict(os.environ, CLOCKWORK_FMU_DIR=str(FMU_DIR))
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=600, env=env)
    if p.returncode != 0:
        pytest.fail(f"{tool} on {ssp.name} exited with {p.returncode}:\n{p.stdout[-3000:]}\n{p.stderr[-3000:]}")
    return dict(np.load(out))


def relative_difference(a: np.ndarray, b: np.ndarray) -> float:
    """max |a - b| / max |b| over the run."""
    a, b = np.asarray(a), np.asarray(b)
    assert a.shape == b.shape, (a.shape, b.shape)
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


def check_tool(tool: str, name: str, directory: str) -> None:
    """Run the exported scene in `tool` and check it against
    (1) the reference loop in the tool's conventions: relative difference
        <= 1e-9 on pendulum.phi, pendulum.w (and vibration.a2) at every
        communication point of the 100 periods;
    (2) clockwork's accurate run (event location on): the first 100 tick
        times and 200 amplitudes inside the interval prediction.predict
        derives from the step size (see prediction.py for the bound)."""
    import prediction
    import reference_loop

    sc = scene(name)
    n = steps(sc)
    got = run_tool(tool, name, directory)
    assert len(got["time"]) == n
    # The tool's clock: only its rounding differs from the loop's.
    loop = reference_loop.run_as(tool, sc, n, recorded(sc))
    assert np.max(np.abs(got["time"] - loop["time"])) < 1e-9 * sc.experiment.stop
    for var in compared(sc):
        d = relative_difference(got[var], loop[var])
        print(f"{name}: {tool}: {var}: tool vs reference loop ({tool} conventions), relative {d:.3g}")
        assert d <= RELATIVE_TOLERANCE, (var, d)

    ticks = prediction.changes(got["pendulum.tick_time"])
    amplitudes = prediction.changes(got["pendulum.amplitude"])
    assert len(ticks) >= PERIODS and len(amplitudes) >= 2 * PERIODS
    modes = reference_loop.TOOL_MODES[tool]
    interval = prediction.predict(sc, modes["sampling"], modes["start"], [amplitudes],
                                  sc.experiment.start + n * sc.master.step)
    r = prediction.check(interval, ticks, amplitudes, PERIODS)
    lo, hi = r["tick_interval_s"]
    alo, ahi = r["amplitude_interval_rad"]
    print(f"{name}: {tool}: tick {PERIODS} - accurate run = {r['tick_error_s']:.4g} s, predicted "
          f"[{lo:.4g}, {hi:.4g}] s; amplitude {2 * PERIODS} - accurate = {np.degrees(r['amplitude_error_rad']):.4g} deg, "
          f"predicted [{np.degrees(alo):.4g}, {np.degrees(ahi):.4g}] deg; worst excess over the interval: "
          f"tick {r['worst_tick_excess_s']:.3g} s (#{r['worst_tick_at']}), amplitude "
          f"{r['worst_amplitude_excess_rad']:.3g} rad (#{r['worst_amplitude_at']})")
    assert r["worst_tick_excess_s"] <= 0.0, r
    assert r["worst_amplitude_excess_rad"] <= 0.0, r


def console_tool(name: str) -> str:
    """A console script of an installed package: on PATH or beside this Python."""
    exe = shutil.which(name) or str(Path(sys.executable).parent / name)
    if not Path(exe).exists():
        pytest.fail(f"{name} not found next to {sys.executable} nor on PATH")
    return exe


def fmutool_container(name: str, out: Path) -> Path:
    """fmu-manipulation-toolbox's container FMU of a scene, built by
    `fmucontainer` from what `clockwork export-ssp --container-dir` writes."""
    require("fmu_manipulation_toolbox")
    cdir = out / "container"
    p = subprocess.run([sys.executable, "-m", "clockwork", "export-ssp", f"scenarios/{name}.toml",
                        "--out", str(out / f"{name}.ssp"), "--container-dir", str(cdir)],
                       capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert p.returncode == 0, p.stdout + p.stderr
    p = subprocess.run([console_tool("fmucontainer"), "-container", f"{name}.json", "-fmu-directory", str(cdir)],
                       capture_output=True, text=True, timeout=300)
    fmu = cdir / f"{name}.fmu"
    assert p.returncode == 0 and fmu.exists(), p.stdout + p.stderr
    return fmu
