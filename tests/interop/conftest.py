"""Fixtures of the interop tests (helpers: interop_common.py)."""

import pytest

from interop_common import FMU_DIR


@pytest.fixture(autouse=True)
def _fmus(monkeypatch):
    monkeypatch.setenv("CLOCKWORK_FMU_DIR", str(FMU_DIR))


@pytest.fixture(scope="session")
def ssp_dir(tmp_path_factory) -> str:
    return str(tmp_path_factory.mktemp("ssp"))
