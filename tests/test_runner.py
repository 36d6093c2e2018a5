"""clockwork run end to end on small scenes: files written, stalls reported."""

import json
import math

import pytest

from clockwork.cli import main
from cwtest import FMU_DIR

SCENE = """
connections = [
  "pendulum.phi -> escapement.phi",
  "pendulum.w -> escapement.w",
  "escapement.tau -> pendulum.tau_escapement",
]

[scene]
title = "small grasshopper run"

[components.pendulum]
fmu = "Pendulum"
parameters = {{ Q = 100, phi_start = "{phi} deg" }}

[components.escapement]
fmu = "GrasshopperEscapement"
parameters = {{ torque = "{torque} N.cm", phi_r = "2 deg" }}

[experiment]
stop = "{stop} s"

[master]
step = "0.1 s"

[record]
outputs = ["pendulum.phi", "pendulum.tick_count", "escapement.tau"]
ticks = "pendulum"

[[plot]]
kind = "time_series"
y = ["pendulum.phi"]
file = "phi.png"
"""


@pytest.fixture(autouse=True)
def _fmus(monkeypatch):
    monkeypatch.setenv("CLOCKWORK_FMU_DIR", str(FMU_DIR))


def run(tmp_path, **kw):
    scene = tmp_path / "s.toml"
    scene.write_text(SCENE.format(**kw))
    out = tmp_path / "out"
    rc = main(["run", str(scene), "--out", str(out), "--no-progress"])
    return rc, out


def test_a_time_series_run_writes_its_files(tmp_path):
    rc, out = run(tmp_path, phi=6, torque=0.8, stop=20)
    assert rc == 0
    summary = json.loads((out / "summary.json").read_text())
    assert {"timeseries.csv", "ticks.csv", "phi.png", "summary.json"} <= set(summary["files"])
    assert summary["result"]["stalled"] is False
    assert summary["result"]["ticks"] >= 8
    assert summary["statistics"]["events"] >= 16
    header = (out / "timeseries.csv").read_text().splitlines()[0]
    assert header.split(",") == ["time", "pendulum.phi", "pendulum.tick_count", "escapement.tau"]
    for fmu in summary["fmus"].values():
        assert len(fmu["sha256"]) == 64


def test_a_stall_is_reported_as_a_result(tmp_path):
    """With almost no torque at Q = 100 the swing decays below phi_r."""
    rc, out = run(tmp_path, phi=3, torque=0.001, stop=60)
    assert rc == 0
    result = json.loads((out / "summary.json").read_text())["result"]
    assert result["stalled"] is True
    assert "phi_r" in result["reason"]
