"""A point's cache entry belongs to its analysis kind.

Analyses share the shape of their data (``"kind"`` in a result, e.g.
hoyng_stationary returns a steady_state result), so the kind of analysis a
point was computed for is part of its key and is checked when read back.
"""

from __future__ import annotations

import json

import pytest

from clockwork import cli
from clockwork.analyses.registry import ANALYSES, ANALYSIS_KEYS, _ANALYSIS_CONVERT, register

from cwtest import CLOCK_SCENE, FMU_DIR, fmu_file

SWEEP = '\n[sweep]\naxes = [ { parameter = "escapement.torque", values = ["0.4 N.cm", "0.5 N.cm"] } ]\n'


@pytest.fixture
def two_kinds(monkeypatch, tmp_path):
    """Two analysis kinds whose results have the same data kind but different numbers."""
    fmu_file("Pendulum")
    monkeypatch.setenv("CLOCKWORK_FMU_DIR", str(FMU_DIR))
    monkeypatch.setenv("CLOCKWORK_CACHE", str(tmp_path / "cache"))
    calls = []
    for name, value in (("cache_test_a", 1.0), ("cache_test_b", 2.0)):
        def analysis(scene, point, progress=False, _v=value, _n=name):
            calls.append(_n)
            return {"kind": "shared_shape", "result": {"value": _v}}
        register(name)(analysis)
    yield calls
    for name in ("cache_test_a", "cache_test_b"):
        ANALYSES.pop(name, None)
        ANALYSIS_KEYS.pop(name, None)
        _ANALYSIS_CONVERT.pop(name, None)


def _scene(tmp_path, kind):
    f = tmp_path / f"{kind}.toml"
    f.write_text(CLOCK_SCENE.format(stop=0.1, sweep=SWEEP).replace('kind = "time_series"', f'kind = "{kind}"'))
    return f


def _run(capsys, scene, out):
    capsys.readouterr()
    rc = cli.main(["run", str(scene), "--out", str(out), "--no-progress", "--workers", "1"])
    _, err = capsys.readouterr()
    assert rc == 0, err
    return json.loads((out / "summary.json").read_text()), err


def test_kinds_with_the_same_physics_do_not_share_cache_entries(tmp_path, capsys, two_kinds):
    a, b = _scene(tmp_path, "cache_test_a"), _scene(tmp_path, "cache_test_b")
    summary, err = _run(capsys, a, tmp_path / "a")
    assert [p["value"] for p in summary["points"]] == [1.0, 1.0] and err == ""
    summary, err = _run(capsys, b, tmp_path / "b")  # same physics, other kind: computed, not a's numbers
    assert [p["value"] for p in summary["points"]] == [2.0, 2.0] and summary["points_reused"] == 0
    assert err == "", err
    # Each kind's entries are reused, without a warning, from the cache and from points/.
    for kind, out in (("cache_test_a", "a2"), ("cache_test_b", "b")):
        summary, err = _run(capsys, _scene(tmp_path, kind), tmp_path / out)
        assert summary["points_reused"] == 2 and err == "", err
    assert two_kinds == ["cache_test_a"] * 2 + ["cache_test_b"] * 2

