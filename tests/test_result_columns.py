"""Every analysis kind declares the columns its results and series hold,
and the declaration is the code's: for every bundled scene (at reduced
size), and for the tests' clock recording ticks, the result of its first
point holds only declared columns and its
series exactly the declared ones, and over all the scenes every declared
result column is produced, but for the few listed below that these cases
cannot reach (each with the reason)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from cwtest import CLOCK_SCENE, FMU_DIR, fmu_file
from clockwork.analyses import registry
from clockwork.run import load_scene, run_point

SCENES = Path(__file__).resolve().parents[1] / "scenarios"
QUICK = json.loads((SCENES / "quick.json").read_text())
# Smaller still than the gallery's --quick, so that one point takes a few seconds.
SMALLER = {
    "ziemkiewicz_fig9b": ["experiment.stop=600 s"],
    "ziemkiewicz_fig10a": ["experiment.stop=200 s"],
    "ziemkiewicz_fig10b": ["experiment.stop=200 s"],
    "ziemkiewicz_fig11": ["analysis.periods=2", 'analysis.fixed_steps=["10 ms", "100 ms"]', "analysis.rtols=[1e-6]",
                          'analysis.comm_steps=["100 ms"]', 'analysis.paper_steps=["1 ms"]', 'analysis.paper_span="10 s"'],
}
STEMS = sorted(f.stem for f in SCENES.glob("*.toml"))

# Declared columns that no bundled scene's first point holds, and why.
UNREACHED = {
    "time_series": {"engine_reason": "only when the compiled engine is refused",
                    "ended": "only when an FMU ends the simulation", "notes": "only with the master's notes",
                    "reason": "only for a stalled clock",
                    "clock_ticks": "only with FMI 3.0 clocks (no bundled FMU has one; tests/test_clocks.py)",
                    "clocked": "only with FMI 3.0 clocks (no bundled FMU has one; tests/test_clocks.py)"},
    "steady_orbit": {"turns_inside_window": "only for a ChronometerEscapement", "reason": "only when stalled or omitted"},
    "disturbance": {"turns_inside_window": "only for a ChronometerEscapement", "reason": "only when stalled or omitted"},
    "hoyng_stationary": {"reason": "only for a stalled clock"},
    "barometric_coefficient": {"reason": "only for a stalled clock"},
    "thermal_coefficient": {"reason": "only for a stalled clock"},
}


@pytest.fixture(autouse=True)
def _fmus(monkeypatch):
    for name in ("Pendulum", "Air"):
        fmu_file(name)
    monkeypatch.setenv("CLOCKWORK_FMU_DIR", str(FMU_DIR))


def test_every_analysis_kind_declares_its_columns():
    assert set(registry.ANALYSES) == set(registry.RESULT_COLUMNS) == set(registry.SERIES_COLUMNS)


@pytest.fixture(scope="module")
def produced():
    """kind -> (scene stem -> (declared, produced columns)), filled as the scenes run."""
    return {}


@pytest.mark.parametrize("stem", STEMS + ["ticks recorded"])
def test_a_bundled_scene_produces_only_declared_columns(stem, produced, tmp_path):
    if stem == "ticks recorded":  # the tests' clock: a time_series run that records ticks
        f = tmp_path / "clock.toml"
        f.write_text(CLOCK_SCENE.format(stop=6, sweep=""))
        sc = load_scene(f)
    else:
        sc = load_scene(SCENES / f"{stem}.toml", QUICK.get(stem, []) + SMALLER.get(stem, []))
    kind = (sc.analysis or {}).get("kind", "time_series")
    point = sc.points()[0] if sc.sweep else {}
    result = run_point(sc, point)
    declared, there = registry.result_columns(sc), set(result["result"])
    assert there <= declared, f"{kind} produces undeclared columns {sorted(there - declared)}"
    assert set(result.get("series") or {}) == registry.series_columns(sc)
    produced.setdefault(kind, {})[stem] = (declared, there)


def test_every_declared_column_is_produced_by_some_scene(produced):
    if len(produced) < len({k for k in registry.ANALYSES if k != "ticks"}):
        pytest.skip("needs every scene's run above")
    never = {}
    for kind, cases in produced.items():
        declared = set().union(*(d for d, _ in cases.values()))
        missing = declared - set().union(*(there for _, there in cases.values()))
        if missing:
            never[kind] = sorted(missing)
    assert never == {kind: sorted(why) for kind, why in UNREACHED.items()}
