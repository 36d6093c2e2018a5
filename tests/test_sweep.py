"""Sweeps at scale: Dask, the result cache, resume after SIGKILL, worker count."""

import hashlib
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from clockwork.hashing import source_digest, tree_digest
from clockwork.results import cache
from clockwork.run import dask as sweep
from clockwork.run import scene_run as runner
from clockwork.run import run_scene
from clockwork.run import load_scene

ROOT = Path(__file__).resolve().parents[1]
FMU_DIR = Path(os.environ.get("CW_FMU_DIR", ROOT / "fmus"))

# A grasshopper clock whose torque is swept; each point is a short time
# series (a fraction of a second). `pendulum` is given by model name,
# `escapement` by a path relative to the scene file: both ways must ship.
SCENE = """
connections = [
  "pendulum.phi -> escapement.phi",
  "pendulum.w -> escapement.w",
  "escapement.tau -> pendulum.tau_escapement",
]

[scene]
title = "sweep test"

[components.pendulum]
fmu = "Pendulum"
parameters = {{ Q = 1000, phi_start = "5 deg" }}

[components.escapement]
fmu = "fmus_local/GrasshopperEscapement.fmu"
parameters = {{ torque = "0.4 N.cm", phi_r = "2 deg" }}

[experiment]
stop = "{stop} s"

[master]
step = "0.5 s"

[record]
outputs = ["pendulum.phi"]
interval = "2 s"
ticks = "pendulum"

[sweep]
axes = [ {{ parameter = "escapement.torque", start = "0.2 N.cm", stop = "0.6 N.cm", num = {num} }} ]
"""


@pytest.fixture(autouse=True)
def _env(monkeypatch, tmp_path):
    if not (FMU_DIR / "Pendulum.fmu").exists():
        pytest.fail(f"no FMUs in {FMU_DIR}: build them first")
    monkeypatch.setenv("CLOCKWORK_FMU_DIR", str(FMU_DIR))
    monkeypatch.setenv("CLOCKWORK_CACHE", "off")


def make_scene(d: Path, num: int = 4, stop: float = 10.0) -> Path:
    (d / "fmus_local").mkdir(parents=True, exist_ok=True)
    shutil.copy(FMU_DIR / "GrasshopperEscapement.fmu", d / "fmus_local" / "GrasshopperEscapement.fmu")
    f = d / "sweep.toml"
    f.write_text(SCENE.format(num=num, stop=stop))
    return f


def csv_text(d: Path) -> str:
    return (d / "sweep.csv").read_text()


def csv_table(d: Path) -> dict:
    """sweep.csv as {column: [exact text of each value]}.

    Column order is left out on purpose: the report orders result columns
    as they first appear, and points loaded from JSON (resumed or cached)
    have sorted keys while fresh ones keep the analysis' order.
    """
    header, *rows = (d / "sweep.csv").read_text().splitlines()
    names = header.split(",")
    cols = {n: [] for n in names}
    for row in rows:
        for n, v in zip(names, row.split(",")):
            cols[n].append(v)
    return cols


def test_dask_local_cluster_equals_local_run(tmp_path):
    from distributed import LocalCluster

    scene = load_scene(make_scene(tmp_path / "scene"))
    run_scene(scene, tmp_path / "local", workers=1, progress=False)
    with LocalCluster(processes=False, n_workers=1, threads_per_worker=2, dashboard_address=None) as cluster:
        run_scene(scene, tmp_path / "dask", scheduler=cluster.scheduler_address, progress=False)
    assert csv_text(tmp_path / "dask") == csv_text(tmp_path / "local")
    for f in (tmp_path / "local" / "points").glob("*.json"):
        a = json.loads(f.read_text())
        b = json.loads((tmp_path / "dask" / "points" / f.name).read_text())
        assert a["ticks"] == b["ticks"] and a["series"] == b["series"]


def test_dask_worker_process_equals_local_run(tmp_path):
    """A worker in its own process: the bundle and the task are pickled across (~10 s)."""
    from distributed import LocalCluster

    scene = load_scene(make_scene(tmp_path / "scene", num=2))
    run_scene(scene, tmp_path / "local", workers=1, progress=False)
    with LocalCluster(processes=True, n_workers=1, threads_per_worker=1, dashboard_address=None) as cluster:
        run_scene(scene, tmp_path / "dask", scheduler=cluster.scheduler_address, progress=False)
    assert csv_text(tmp_path / "dask") == csv_text(tmp_path / "local")


def test_bundle_is_self_contained(tmp_path):
    """The worker side needs nothing from the original files: delete them first."""
    src = make_scene(tmp_path / "scene")
    scene = load_scene(src)
    b = sweep.bundle(scene)
    assert set(b["fmus"]) == {"pendulum", "escapement"}
    shutil.rmtree(tmp_path / "scene")
    loaded = sweep.materialize(b, root=tmp_path / "worker")
    for c in loaded.components.values():
        assert Path(c.fmu_path).is_relative_to(tmp_path / "worker")
    # same FMU bytes and parameters: the same content address
    p = scene.points()[1]
    assert runner.point_key(loaded, p) == runner.point_key(scene, p)
    r = runner.run_point(loaded, p)
    assert r["ticks"] == runner.run_point(scene_from(tmp_path, b), p)["ticks"]


def scene_from(tmp_path, b):
    """The same bundle materialized a second time, elsewhere."""
    return sweep.materialize(b, root=tmp_path / "worker2")


def test_cache_across_output_dirs(tmp_path, monkeypatch):
    monkeypatch.setenv("CLOCKWORK_CACHE", str(tmp_path / "cache"))
    scene = load_scene(make_scene(tmp_path / "scene", num=3))
    run_scene(scene, tmp_path / "a", workers=1, progress=False)
    cached = list((tmp_path / "cache").rglob("*.json"))
    assert len(cached) == 3

    def no_compute(*a, **k):
        raise AssertionError("a cached point was computed again")

    monkeypatch.setattr(runner, "run_point", no_compute)
    summary = run_scene(scene, tmp_path / "b", workers=1, progress=False)
    assert summary["points_reused"] == 3
    assert csv_table(tmp_path / "b") == csv_table(tmp_path / "a")
    # another parameter value is another key: computed, not taken from the cache
    other = load_scene(tmp_path / "scene" / "sweep.toml", ["pendulum.Q=900"])
    with pytest.raises(AssertionError, match="computed again"):
        run_scene(other, tmp_path / "c", workers=1, progress=False)


def test_cache_off_and_code_namespace(tmp_path, monkeypatch):
    monkeypatch.setenv("CLOCKWORK_CACHE", "off")
    assert cache.cache_dir() is None
    monkeypatch.setenv("CLOCKWORK_CACHE", str(tmp_path))
    assert cache.cache_dir() == tmp_path / source_digest()
    cache.cache_store("k", {"error": "x"})
    assert cache.cache_load("k", {}, "ticks") is None  # failures are not cached


def test_code_digest_covers_names_and_contents_in_path_order(tmp_path):
    """The digest in every point key: each *.py file's relative name and
    bytes, in sorted pathlib order ("a/x.py" before "a.py", whose "." sorts
    before "/" as text); a changed byte or name changes it, other files do not."""
    for name, text in {"a.py": "1", "a/x.py": "2", "a.b/y.py": "3", "a_c.py": "4", "a/data.txt": "5"}.items():
        (tmp_path / name).parent.mkdir(exist_ok=True)
        (tmp_path / name).write_text(text)
    h = hashlib.sha256()
    for f in sorted(tmp_path.rglob("*.py")):
        h.update(str(f.relative_to(tmp_path)).encode() + b"\0" + f.read_bytes())
    before = tree_digest(tmp_path)
    assert before == h.hexdigest()[:16]
    (tmp_path / "a" / "data.txt").write_text("6")
    assert tree_digest(tmp_path) == before
    (tmp_path / "a" / "x.py").write_text("7")
    changed = tree_digest(tmp_path)
    assert changed != before
    (tmp_path / "a" / "x.py").rename(tmp_path / "a" / "z.py")
    assert tree_digest(tmp_path) not in (before, changed)


def _cli(*args):
    return [sys.executable, "-m", "clockwork", *map(str, args)]


def test_sigkill_resume_and_uninterrupted_equal(tmp_path):
    # Points long enough (~0.1 s each) that the kill lands halfway through the sweep.
    scene = make_scene(tmp_path / "scene", num=8, stop=4000.0)
    env = dict(os.environ, CLOCKWORK_FMU_DIR=str(FMU_DIR), CLOCKWORK_CACHE="off")
    out = tmp_path / "killed"
    proc = subprocess.Popen(_cli("run", scene, "--out", out, "--workers", 1, "--no-progress"),
                            env=env, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    deadline = time.monotonic() + 60
    points = out / "points"
    try:
        while time.monotonic() < deadline:
            done = list(points.glob("*.json")) if points.is_dir() else []
            if len(done) >= 3:
                break
            assert proc.poll() is None, proc.communicate()
            time.sleep(0.02)
        proc.send_signal(signal.SIGKILL)
        proc.wait(10)
    finally:
        if proc.poll() is None:
            proc.kill()
    finished = {f.name: (f.stat().st_mtime_ns, f.read_bytes()) for f in points.glob("*.json")}
    assert 3 <= len(finished) < 8, "the run was not interrupted halfway"
    assert not (out / "sweep.csv").exists()
    r = subprocess.run(_cli("run", scene, "--out", out, "--workers", 1, "--no-progress"),
                       env=env, cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["points_reused"] == len(finished)
    for name, (mtime, data) in finished.items():  # not recomputed, not rewritten
        f = points / name
        assert f.stat().st_mtime_ns == mtime and f.read_bytes() == data
    clean = tmp_path / "clean"
    r = subprocess.run(_cli("run", scene, "--out", clean, "--workers", 1, "--no-progress"),
                       env=env, cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert csv_table(out) == csv_table(clean)


def test_one_and_two_workers_bit_identical(tmp_path):
    scene = load_scene(make_scene(tmp_path / "scene", num=4))
    run_scene(scene, tmp_path / "w1", workers=1, progress=False)
    run_scene(scene, tmp_path / "w2", workers=2, progress=False)
    assert csv_text(tmp_path / "w1") == csv_text(tmp_path / "w2")
    for f in (tmp_path / "w1" / "points").glob("*.json"):
        a = json.loads(f.read_text())
        b = json.loads((tmp_path / "w2" / "points" / f.name).read_text())
        for k in ("result", "series", "ticks", "statistics"):
            assert a[k] == b[k], k


def test_a_sweep_keeps_no_point_series_once_the_point_is_written(capsys, tmp_path, monkeypatch):
    """Every point's recorded series stayed in memory until the sweep's end:
    the recording bound per point bounded no sweep (6 points of 2e6 values:
    615,152 KiB; 388,296 KiB now). Written points keep their series in
    points/<key>.json; in memory only the first point's stays."""
    from clockwork.results import report
    from clockwork.run import scene_run
    from cwtest import CLOCK_SCENE, fmu_file, run_cli

    fmu_file("Pendulum")
    sweep = '\n[sweep]\naxes = [ { parameter = "escapement.torque", values = ["0.4 N.cm", "0.45 N.cm", "0.5 N.cm"] } ]\n'
    f = tmp_path / "s.toml"
    f.write_text(CLOCK_SCENE.format(stop=1.0, sweep=sweep))
    monkeypatch.setenv("CLOCKWORK_CACHE", str(tmp_path / "cache"))
    seen = []
    real = report.write_outputs

    def spy(scene, out, results, *a, **k):
        seen.append([sorted(k for k in r if k in ("series", "ticks")) for r in results])
        return real(scene, out, results, *a, **k)

    monkeypatch.setattr(scene_run, "write_outputs", spy)
    for _ in range(2):  # computed, then read back from points/
        rc, _, err = run_cli(capsys, ["run", f, "--out", tmp_path / "out", "--no-progress", "--no-plot", "--workers", "1"])
        assert rc == 0, err
    assert seen == [[["series", "ticks"], [], []]] * 2, seen
    points = sorted((tmp_path / "out" / "points").glob("*.json"))
    assert len(points) == 3 and all("series" in json.loads(p.read_text()) for p in points)
