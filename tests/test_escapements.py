"""The escapement registry (analyses/escapements.py): every escapement FMU
the project builds is registered, and each registration agrees with its
FMU and with itself."""

import math
from pathlib import Path

import pytest

from clockwork.analyses import escapements
from clockwork.analyses.context import ESCAPEMENTS
from clockwork.fmi.description import read_fmu, variables

ROOT = Path(__file__).resolve().parents[1]
MODELS = sorted(p.name for p in (ROOT / "src_c" / "models").iterdir() if p.name.endswith("Escapement"))


def _starts(model: str) -> dict:
    md = read_fmu(ROOT / "fmus" / f"{model}.fmu", need_binary=False)[0]
    return {n: float(v.start) for n, v in variables(md).items()
            if v.start is not None and v.type in ("Real", "Integer")}


def test_every_escapement_model_is_registered_once():
    # A new escapement FMU must be registered to be usable by the analyses.
    assert MODELS and MODELS == sorted(escapements.ESCAPEMENTS)
    assert ESCAPEMENTS == tuple(escapements.ESCAPEMENTS)
    assert escapements.escapement(None) is None and escapements.escapement("Pendulum") is None


@pytest.mark.parametrize("model", MODELS)
def test_work_beyond_the_window_is_the_energy_balance_work(model):
    kind = escapements.ESCAPEMENTS[model]
    p = _starts(model)
    p["profile"] = 0  # the constant torque the energy balance assumes
    edge = max(abs(p.get("alpha_m1", 0.0)), abs(p.get("alpha_m2", 0.0)), p.get("phi_r", 0.0))
    assert kind.min_amplitude(p) <= edge
    assert kind.work(p, edge + 0.1) == pytest.approx(kind.balance_work(p), rel=1e-12)
    assert kind.work(p, 0.0) <= kind.balance_work(p)


@pytest.mark.parametrize("model", MODELS)
def test_its_twin_and_normalized_quantities_fit_hoyng(model):
    kind = escapements.ESCAPEMENTS[model]
    p = _starts(model)
    twin = variables(read_fmu(ROOT / "fmus" / "AveragedPendulum.fmu", need_binary=False)[0])
    assert set(kind.twin(p)) <= set(twin)
    assert kind.twin(p)["escapement"] == kind.twin_kind
    n = kind.normalized(p, mgl=1.0)
    assert all(math.isfinite(v) for v in n.values())
    assert kind.drive(p, n) > 0.0
    assert kind.reference in ("grasshopper", "chronometer")  # physics.reference's kinds
