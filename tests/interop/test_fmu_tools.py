"""The FMUs in other FMI tooling: fmpy's validator, fmu-manipulation-toolbox's
checker and its container builder.

- every built FMU: `fmpy validate` prints "No problems found." and
  `fmutool -input X.fmu -check` finds neither conformity nor semantic errors;
- a container FMU built by `fmucontainer` from the description that
  `clockwork export-ssp --container-dir` writes for a scene runs under
  `fmpy simulate`, and gives the numbers of the reference loop in the
  conventions it uses (outputs read right after each embedded FMU's step,
  consistent start): relative difference <= 1e-9.
"""

import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import reference_loop
from interop_common import FMU_DIR, RELATIVE_TOLERANCE, ROOT, relative_difference, require, scene

MODELS = ["Pendulum", "GrasshopperEscapement", "ChronometerEscapement", "Drag", "MechanismVibration",
          "AveragedPendulum"]


def _tool(name: str) -> str:
    exe = shutil.which(name) or str(Path(sys.executable).parent / name)
    if not Path(exe).exists():
        pytest.fail(f"{name} not found next to {sys.executable} nor on PATH")
    return exe


@pytest.mark.parametrize("model", MODELS)
def test_fmpy_validate(model):
    fmu = FMU_DIR / f"{model}.fmu"
    p = subprocess.run([sys.executable, "-m", "fmpy", "validate", str(fmu)],
                       capture_output=True, text=True, timeout=120)
    assert p.returncode == 0 and "No problems found." in p.stdout, p.stdout + p.stderr


@pytest.mark.parametrize("model", MODELS)
def test_fmutool_check(model):
    require("fmu_manipulation_toolbox")
    fmu = FMU_DIR / f"{model}.fmu"
    p = subprocess.run([_tool("fmutool"), "-input", str(fmu), "-check"], capture_output=True, text=True,
                       timeout=120)
    text = p.stdout + p.stderr
    assert p.returncode == 0, text
    assert "compliant with FMI-2.0" in text and "No semantic error" in text, text
    bad = [line for line in text.splitlines() if line.startswith(("ERROR", "CRITICAL", "WARNING"))]
    assert not bad, text


def test_container_from_scene_runs_under_fmpy_simulate(tmp_path):
    require("fmu_manipulation_toolbox")
    name = "core_grasshopper_drag"
    cdir = tmp_path / "container"
    p = subprocess.run([sys.executable, "-m", "clockwork", "export-ssp", f"scenarios/{name}.toml",
                        "--out", str(tmp_path / f"{name}.ssp"), "--container-dir", str(cdir)],
                       capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert p.returncode == 0, p.stdout + p.stderr
    p = subprocess.run([_tool("fmucontainer"), "-container", f"{name}.json", "-fmu-directory", str(cdir)],
                       capture_output=True, text=True, timeout=300)
    fmu = cdir / f"{name}.fmu"
    assert p.returncode == 0 and fmu.exists(), p.stdout + p.stderr
    p = subprocess.run([sys.executable, "-m", "fmpy", "validate", str(fmu)],
                       capture_output=True, text=True, timeout=120)
    assert "No problems found." in p.stdout, p.stdout + p.stderr
    sc = scene(name)
    h, n = sc.master.step, 2000
    csv = tmp_path / "out.csv"
    p = subprocess.run([sys.executable, "-m", "fmpy", "simulate", str(fmu), "--stop-time",
                        repr(n * h), "--output-interval", repr(h), "--output-file", str(csv)],
                       capture_output=True, text=True, timeout=300)
    assert p.returncode == 0 and csv.exists(), p.stdout + p.stderr
    res = np.genfromtxt(csv, delimiter=",", names=True)
    assert len(res) == n + 1 and abs(res["time"][-1] - n * h) < 1e-9
    loop = reference_loop.run(sc, n, ["pendulum.phi", "pendulum.w"], time="sum", sampling="held",
                              start="consistent")
    for var in ("phi", "w"):
        d = relative_difference(res[f"pendulum_{var}"][1:], loop[f"pendulum.{var}"])
        print(f"container under fmpy simulate vs reference loop (held, consistent): pendulum.{var} relative {d:.3g}")
        assert d <= RELATIVE_TOLERANCE
    assert np.isclose(res["pendulum_phi"][0], sc.components["pendulum"].parameters["phi_start"], rtol=0, atol=1e-15)
