"""Root fixtures of the test suites; shared paths live in cwtest.py."""

import os
from pathlib import Path

import pytest

from cwtest import FMU_DIR


@pytest.fixture(scope="session")
def fmu_dir() -> Path:
    return FMU_DIR


@pytest.fixture(scope="session", autouse=True)
def _own_cache(tmp_path_factory):
    """The suite's own point and FMU cache, one per session (one per
    pytest-xdist worker): never the user's ~/.cache/clockwork, whose
    entries would turn a test's computed points into reused ones, and never
    another worker's. A test that needs a cache of its own (or none) still
    sets CLOCKWORK_CACHE itself."""
    before = os.environ.get("CLOCKWORK_CACHE")
    os.environ["CLOCKWORK_CACHE"] = str(tmp_path_factory.mktemp("cache"))
    yield
    if before is None:
        os.environ.pop("CLOCKWORK_CACHE", None)
    else:
        os.environ["CLOCKWORK_CACHE"] = before
