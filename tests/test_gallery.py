"""clockwork gallery on a temporary scenarios dir: figures, headlines, wall times, quick mode."""

import json
import math
import os
import shutil
from pathlib import Path

import pytest

from clockwork import cli

ROOT = Path(__file__).resolve().parents[1]
FMU_DIR = Path(os.environ.get("CW_FMU_DIR", ROOT / "fmus"))

BROKEN = '[scene]\ntitle = "broken"\n[components.p]\nfmu = "NoSuchModel"\n[experiment]\nstop = 1\n'


@pytest.fixture(autouse=True)
def _env(monkeypatch):
    if not (FMU_DIR / "Pendulum.fmu").exists():
        pytest.fail(f"no FMUs in {FMU_DIR}: build them first")
    monkeypatch.setenv("CLOCKWORK_FMU_DIR", str(FMU_DIR))
    monkeypatch.setenv("CLOCKWORK_CACHE", "off")


def test_gallery_quick(tmp_path, capsys):
    scen = tmp_path / "scenarios"
    scen.mkdir()
    shutil.copy(ROOT / "scenarios" / "hoyng_fig4.toml", scen)
    shutil.copy(ROOT / "scenarios" / "hoyng_appC.toml", scen)
    # quick: Fig. 4 for 170 periods (the jump at 150)
    (scen / "quick.json").write_text(json.dumps({"hoyng_fig4": [f"experiment.stop={170 * 2 * math.pi!r}"]}))
    out = tmp_path / "gallery"
    rc = cli.main(["gallery", "--out", str(out), "--scenarios", str(scen), "--quick", "--no-progress"])
    assert rc == 0, capsys.readouterr().err
    g = json.loads((out / "gallery.json").read_text())
    assert [e["scene"] for e in g["scenes"]] == ["hoyng_appC", "hoyng_fig4"]
    assert all(e["status"] == "ok" and e["wall_time_s"] > 0 for e in g["scenes"])
    fig4 = g["scenes"][1]
    assert fig4["quick"] and fig4["overrides"]
    s4 = json.loads((out / "hoyng_fig4" / "summary.json").read_text())
    assert s4["result"]["periods"] == 170  # the quick setting was applied
    index = (out / "index.md").read_text()
    for e in g["scenes"]:
        for png in e["files"]:
            assert (out / e["scene"] / png).stat().st_size > 10_000
            assert f"![{png}]({e['scene']}/{png})" in index
    assert "appC_rate.png" in g["scenes"][0]["files"] and "fig4_phi.png" in fig4["files"]
    # headlines side by side: the paper's 3.2e-4 rate after the jump and ours; the quick run shortened
    # the experiment, so the paper's value is marked as belonging to the scene as written
    assert "| rate right after the jump | 0.00032 (scene as written; not comparable) | 0.000322 |" in index
    jump = next(h for h in s4["headlines"] if h["quantity"] == "rate right after the jump")
    assert jump["comparable"] is False and "--set experiment.stop=" in jump["note"]
    appc = json.loads((out / "hoyng_appC" / "summary.json").read_text())["headlines"]
    assert appc and all("comparable" not in h for h in appc)  # run as written
    assert "| quantity | paper | ours | unit | tolerance | note |" in index
    assert "Wall time" in index and "total wall time" in index


def test_gallery_reports_a_broken_scene_and_goes_on(tmp_path, capsys):
    scen = tmp_path / "scenarios"
    scen.mkdir()
    (scen / "a_broken.toml").write_text(BROKEN)
    shutil.copy(ROOT / "scenarios" / "hoyng_fig4.toml", scen)
    (scen / "quick.json").write_text(json.dumps({"hoyng_fig4": [f"experiment.stop={155 * 2 * math.pi!r}"]}))
    out = tmp_path / "g"
    rc = cli.main(["gallery", "--out", str(out), "--scenarios", str(scen), "--quick", "--no-progress"])
    err = capsys.readouterr().err
    assert rc == 1 and "a_broken failed" in err
    g = json.loads((out / "gallery.json").read_text())
    assert g["failed"] == ["a_broken"]
    assert g["scenes"][1]["status"] == "ok"
    index = (out / "index.md").read_text()
    assert "**Failed:**" in index and "NoSuchModel" in index


def test_gallery_without_quick_runs_in_full(tmp_path):
    from clockwork.run.gallery import quick_overrides, run_gallery

    scen = tmp_path / "scenarios"
    scen.mkdir()
    shutil.copy(ROOT / "scenarios" / "hoyng_appC.toml", scen)
    (scen / "quick.json").write_text(json.dumps({"hoyng_appC": ["pendulum.Q=4000"]}))
    assert quick_overrides(scen) == {"hoyng_appC": ["pendulum.Q=4000"]}
    g = run_gallery(tmp_path / "g", scen, quick=False, progress=False)
    assert g["scenes"][0]["overrides"] == []
    s = json.loads((tmp_path / "g" / "hoyng_appC" / "summary.json").read_text())
    assert s["settings"]["overrides"] == []
