"""Paths shared by the test suites (import as `from cwtest import ...`).

A module with its own name: several test folders have a conftest.py, and
`from conftest import` would pick whichever pytest loaded last.
"""

import os
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
FMU_DIR = Path(os.environ.get("CW_FMU_DIR", ROOT / "fmus"))
BUILD_DIR = Path(os.environ.get("CW_BUILD_DIR", ROOT / "build"))


def fmu_file(name: str) -> Path:
    path = FMU_DIR / f"{name}.fmu"
    if not path.exists():
        pytest.fail(f"{path} is missing: build the FMUs first (cmake --build build)")
    return path
