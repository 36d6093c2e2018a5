"""Broken FMU files through the clockwork command: one line on stderr, exit 2.

The CLI's bad-input table (tests/test_cli.py) covers scene and argument
errors and FMU files that are not zip archives; these are FMU archives that
look right from the outside but whose binary is missing, not loadable, or
does not belong to the model description (README: "Bad input of any kind
gives one line on stderr and exit code 2").
"""

import re
import zipfile

import pytest

from cwtest import FMU_DIR, fmu_file
from clockwork import cli

SCENE = ('[scene]\ntitle = "broken fmu"\n[components.pendulum]\nfmu = "{fmu}"\n'
         "[experiment]\nstop = 0.05\n[master]\nstep = 0.01\n")


@pytest.fixture(autouse=True)
def _fmu_dir(monkeypatch):
    fmu_file("Pendulum")
    monkeypatch.setenv("CLOCKWORK_FMU_DIR", str(FMU_DIR))


def _rewrite(src, dst, change):
    """Copy the FMU archive src to dst, passing each member through change(name, data) -> data | None."""
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w") as zout:
        for item in zin.infolist():
            data = change(item.filename, zin.read(item))
            if data is not None:
                zout.writestr(item, data)


def _no_binary(name, data):
    return None if name.startswith("binaries/") else data


def _garbage_binary(name, data):
    return b"\x7fELF" + b"\x01not a shared object" * 64 if name.startswith("binaries/") else data


def _other_guid(name, data):
    if name != "modelDescription.xml":
        return data
    return re.sub(rb'guid="\{[^}]*\}"', b'guid="{00000000-0000-4000-8000-000000000000}"', data, count=1)


def _other_models_binary(name, data):
    if not name.startswith("binaries/"):
        return data
    with zipfile.ZipFile(fmu_file("Drag")) as z:
        return z.read("binaries/linux64/Drag.so")


def _truncated(path):
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])


CASES = [
    pytest.param("no binary", _no_binary, ["Broken.fmu", "no binary"]),
    pytest.param("truncated archive", None, ["Broken.fmu", "not a zip archive"]),
    pytest.param("binary not loadable", _garbage_binary, ["Broken.fmu"]),
    pytest.param("GUID of another build", _other_guid, ["Broken.fmu", "GUID"]),
    pytest.param("another model's binary", _other_models_binary, ["Broken.fmu", "GUID"]),
]


@pytest.mark.parametrize("what, change, needles", CASES, ids=[c.values[0] for c in CASES])
def test_broken_fmu_is_bad_input(tmp_path, capsys, what, change, needles):
    broken = tmp_path / "Broken.fmu"
    if change is None:
        broken.write_bytes(fmu_file("Pendulum").read_bytes())
        _truncated(broken)
    else:
        _rewrite(fmu_file("Pendulum"), broken, change)
    scene = tmp_path / "scene.toml"
    scene.write_text(SCENE.format(fmu=broken))
    rc = cli.main(["run", str(scene), "--out", str(tmp_path / "out"), "--no-progress"])
    _, err = capsys.readouterr()
    lines = err.strip().splitlines()
    assert "Traceback" not in err, err
    assert len(lines) == 1 and lines[0].startswith("clockwork: error: "), err
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])
    assert rc == 2, err
