"""Root fixtures of the test suites; shared paths live in cwtest.py."""

from pathlib import Path

import pytest

from cwtest import FMU_DIR


@pytest.fixture(scope="session")
def fmu_dir() -> Path:
    return FMU_DIR
