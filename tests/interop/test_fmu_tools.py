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

import subprocess
import sys

import numpy as np
import pytest

import reference_loop
from interop_common import (FMU_DIR, RELATIVE_TOLERANCE, console_tool, fmutool_container, relative_difference,
                             require, scene)

MODELS = ["Pendulum", "GrasshopperEscapement", "ChronometerEscapement", "Drag", "MechanismVibration",
          "AveragedPendulum", "Air"]


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
    p = subprocess.run([console_tool("fmutool"), "-input", str(fmu), "-check"], capture_output=True, text=True,
                       timeout=120)
    text = p.stdout + p.stderr
    assert p.returncode == 0, text
    assert "compliant with FMI-2.0" in text and "No semantic error" in text, text
    bad = [line for line in text.splitlines() if line.startswith(("ERROR", "CRITICAL", "WARNING"))]
    assert not bad, text


def test_container_from_scene_runs_under_fmpy_simulate(tmp_path):
    name = "core_grasshopper_drag"
    fmu = fmutool_container(name, tmp_path)
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
