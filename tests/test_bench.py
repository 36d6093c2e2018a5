"""`clockwork bench`: the reference it measures against, and its plumbing on a
tiny configuration. Never speed: wall times are only checked to be measured."""

import csv
import importlib.util
import json
import math
import sys

import numpy as np
import pytest

from clockwork import bench as B
from clockwork import cli

from cwtest import FMU_DIR, fmu_file


@pytest.fixture(autouse=True)
def _fmus(monkeypatch):
    fmu_file("Pendulum")
    monkeypatch.setenv("CLOCKWORK_FMU_DIR", str(FMU_DIR))


def test_reference_agrees_with_closed_forms_itself_and_the_cosimulation():
    """AGM period, Hoyng Eqs. (19)/(20), shooting vs plain integration, two
    tolerances, and the co-simulation: each within the bound the module gives
    with its reason (bench.reference_checks)."""
    checks = B.reference_checks()
    names = " | ".join(c["check"] for c in checks)
    for needle in ("AGM", "Eq. (19)", "Eq. (20)", "integrated from the shot orbit", "rtol 1e-10", "co-simulation"):
        assert needle in names, needle
    for c in checks:
        print(f"{c['check']}: {c['value']:.3g} (bound {c['bound']:.3g} {c['unit']}: {c['reason']})")
    bad = [c for c in checks if not c["ok"]]
    assert not bad, bad


def test_operating_point_is_refined_to_its_amplitude():
    pt = B.steady_point("fig2b_chronometer")
    assert abs(math.degrees(pt.amplitude) / 5.0 - 1.0) < 1e-9
    assert pt.params.alpha_m1 < 0.0 and pt.params.alpha_m2 == 0.0  # the push before the lowest point
    # Fig. 2(b): pushing before the lowest point speeds the clock up (E_E < 0).
    assert pt.ref.E_E < 0.0


def _tiny(run_tool=B.RUN_TOOL, peers=("ecos",)):
    return B.BenchConfig(
        name="tiny", steady_points=("fig4a_5deg",),
        steady_families=(
            B.Family("GS, ZOH, events located (default)", {}, B.grid([0.5], [1e-10])),
            B.Family("events not located", {"event_location": False}, B.grid([1e-2], [1e-12])),
            B.Family("damping in Drag FMU, ZOH", {}, B.grid([0.1], [1e-12]), split=True),
        ),
        long_run_tolerances=(1e-3,), scipy_rtols=(1e-8,), peer_tools=peers, peer_steps=(1e-2,),
        peer_points=("fig4a_5deg",), peer_periods=3,
        hoyng_ticks=20, hoyng_jump_periods=10,
        hoyng_families=(B.Family("GS, ZOH, events located (default)", {}, B.grid([B.TWO_PI], [1e-10])),),
        hoyng_scipy_rtols=(1e-8,),
        chaos_t_end=10.0, chaos_transient=2.0,
        chaos_families=(B.Family("GS, ZOH, events located (default)", {}, B.grid([2e-3], [1e-10])),),
        chaos_scipy_rtols=(), chaos_peer_tools=(), chaos_peer_steps=(), repeats=1, targets=False,
        run_tool=run_tool, peer_timeout_s=120.0, me_ticks=5, me_rtols=(1e-8,), me_solvers=("dop853", "cvode"))


def test_bench_plumbing_on_a_tiny_configuration(tmp_path):
    peers = ("ecos",) if importlib.util.find_spec("ecospy") else ()
    blob = B.run_bench(tmp_path, _tiny(peers=peers), progress=False, command="test")
    for name in ("bench.csv", "bench.md", "bench.json", "work_precision.png"):
        assert (tmp_path / name).stat().st_size > 0, name
    with open(tmp_path / "bench.csv") as f:
        reader = csv.DictReader(f)
        assert reader.fieldnames == B.CSV_FIELDS
        rows = list(reader)
    problems = {r["problem"] for r in rows}
    assert problems == {"fig4a_5deg", "hoyng", "chaos_rate", "chaos_a2rms", "chaos_lambda2", "model_exchange"}
    # The Model Exchange pendulum: clockwork's wrapper beside fmpy's own CVode loop on the same FMU.
    me_rows = {r["family"]: r for r in rows if r["problem"] == "model_exchange"}
    assert me_rows["fmpy Model Exchange, CVode"]["status"] == "ok"
    assert float(me_rows["clockwork Model Exchange, DOP853"]["error"]) < 1e-6
    mine = [r for r in rows if r["tool"] in ("clockwork", "scipy")]
    for r in mine:
        assert r["status"] == "ok", r
        assert math.isfinite(float(r["error"])) and float(r["wall_s"]) > 0.0, r
    # Errors mean something: located events beat a fixed 10 ms grid, and the
    # default shooting row is within the bench's 1e-3 s/day.
    err = {r["family"]: float(r["error"]) for r in rows if r["problem"] == "fig4a_5deg" and r["tool"] == "clockwork"}
    assert err[B.DEFAULT_FAMILY] < 1e-3
    assert err["events not located"] > 10 * err[B.DEFAULT_FAMILY]
    # lambda2 from twin runs 1e-6 deg apart (0.15 1/s over these 10 s): the
    # co-simulated twins follow the reference's to a few percent.
    (lam,) = [r for r in rows if r["problem"] == "chaos_lambda2"]
    assert float(lam["error"]) < 0.05 * blob["info"]["chaos"]["lambda2_reference_per_s"], lam
    if peers:
        (peer,) = [r for r in rows if r["tool"] == "ecos" and r["problem"] == "fig4a_5deg"]
        assert peer["status"] == "ok", peer
        # A fixed 10 ms step delays each switch: the same order as our own fixed-step row.
        assert 0.1 < float(peer["error"]) / err["events not located"] < 10
    md = (tmp_path / "bench.md").read_text()
    assert "Reference agreement" in md
    for c in blob["checks"]:
        assert c["check"].replace("|", "\\|") in md
    assert json.loads((tmp_path / "bench.json").read_text())["config"] == "tiny"


def test_a_peer_crash_is_a_reported_result(tmp_path):
    crash = tmp_path / "crash.py"
    crash.write_text("import os\nos.abort()\n")
    res, wall, process, status = B.run_peer(_tiny(run_tool=crash), "fmpy", tmp_path / "x.ssp", 1, 0.01,
                                            ["a.b"], tmp_path / "x.npz")
    assert res is None
    assert status.startswith("crashed (SIGABRT)"), status
    fails = tmp_path / "fails.py"
    fails.write_text("import sys\nprint('boom', file=sys.stderr)\nsys.exit(3)\n")
    res, wall, process, status = B.run_peer(_tiny(run_tool=fails), "fmpy", tmp_path / "x.ssp", 1, 0.01,
                                            ["a.b"], tmp_path / "x.npz")
    assert res is None and status == "exited with 3: boom", status
    res, wall, process, status = B.run_peer(_tiny(run_tool=tmp_path / "missing.py"), "fmpy",
                                            tmp_path / "x.ssp", 1, 0.01, ["a.b"], tmp_path / "x.npz")
    assert res is None and "missing" in status


def test_a_missing_tool_is_a_row(monkeypatch, tmp_path):
    monkeypatch.setitem(B.PEER_MODULES, "nosuchtool", "no_such_module_for_clockwork_bench")
    assert B.tool_available("nosuchtool").startswith("not installed")
    assert B.tool_available("fmpy") is None  # fmpy is a dependency
    row = B.Row("p", "f", "nosuchtool", "x")
    assert B.PeerRunner(_tiny(), tmp_path).run(row, "nosuchtool", tmp_path / "x.ssp", 1, 0.01, ["a.b"]) is None
    assert row.status.startswith("not installed")


def test_ticks_from_a_held_output():
    held = np.array([0.0, 0.0, 1.5, 1.5, 1.5, 3.5, 3.5, 5.5])
    assert B.tick_times(held).tolist() == [1.5, 3.5, 5.5]


def test_cli_bench_quick_calls_the_bench(monkeypatch, tmp_path, capsys):
    seen = {}

    def fake(out, cfg, progress, command):
        seen.update(out=out, cfg=cfg, command=command)
        return {"rows": [], "checks": [{"check": "c", "ok": ok}], "info": {"wall_s": 0.0}}

    monkeypatch.setattr(B, "run_bench", fake)
    ok = True
    assert cli.main(["bench", "--quick", "--out", str(tmp_path / "b"), "--no-progress"]) == 0
    assert seen["cfg"].name == "quick" and seen["out"] == tmp_path / "b"
    assert "--quick" in seen["command"]
    ok = False
    assert cli.main(["bench", "--out", str(tmp_path / "c")]) == 1
    assert seen["cfg"].name == "full"
    assert "reference check failed: c" in capsys.readouterr().err
