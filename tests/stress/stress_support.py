"""Shared setup of the stress tests (no conftest.py here: a second module
named `conftest` would shadow tests/conftest.py for `from cwtest import`).

Size: reduced by default (CI); `CLOCKWORK_STRESS=full` runs the full sizes
documented in docs/stress.md.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))

FULL = os.environ.get("CLOCKWORK_STRESS", "").lower() == "full"
FMU_DIR = Path(os.environ.get("CW_FMU_DIR", ROOT / "fmus"))


def size(ci, full):
    """The CI value, or the full-size one under CLOCKWORK_STRESS=full."""
    return full if FULL else ci


@pytest.fixture(autouse=True)
def fmus(monkeypatch):
    for name in ("Pendulum", "GrasshopperEscapement", "MechanismVibration"):
        if not (FMU_DIR / f"{name}.fmu").exists():
            pytest.fail(f"{FMU_DIR / name}.fmu is missing: build the FMUs first (cmake --build build)")
    monkeypatch.setenv("CLOCKWORK_FMU_DIR", str(FMU_DIR))
