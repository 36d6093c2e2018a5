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


# -- an FMU that cannot save and restore its state -----------------------------

def _stateless(name, data):
    """The model description says canGetAndSetFMUstate="false" (the binary is unchanged)."""
    if name != "modelDescription.xml":
        return data
    out = data.replace(b'canGetAndSetFMUstate="true"', b'canGetAndSetFMUstate="false"')
    assert out != data
    return out


CLOCK = ('connections = ["pendulum.phi -> escapement.phi", "pendulum.w -> escapement.w", '
         '"escapement.tau -> pendulum.tau_escapement"]\n'
         '[scene]\ntitle = "a clock with an escapement that cannot roll back"\n'
         '[components.pendulum]\nfmu = "{pendulum}"\nparameters = {{ phi_start = "6 deg" }}\n'
         '[components.escapement]\nfmu = "{escapement}"\n'
         "[experiment]\nstop = 0.5\n[master]\nstep = 0.01\n{master}")


@pytest.mark.parametrize("stateless, master, key, needle", [
    ("escapement", "", "master.event_location", "locating events"),
    ("pendulum", "", "master.event_location", "locating events"),
    ("pendulum", "event_location = false\niterations = 2\n", "master.iterations", "iterating the coupling"),
    ("escapement", "event_location = false\nrichardson = true\n", "master.richardson", "step doubling"),
])
def test_an_fmu_without_state_is_refused_where_a_rollback_is_needed(tmp_path, capsys, stateless, master,
                                                                     key, needle):
    """Not at the first rollback in the middle of a run: at load, naming the
    scene file, the master key, the component and the missing capability."""
    models = {"pendulum": "Pendulum", "escapement": "GrasshopperEscapement"}
    files = {n: fmu_file(m) for n, m in models.items()}
    files[stateless] = tmp_path / "Stateless.fmu"
    _rewrite(fmu_file(models[stateless]), files[stateless], _stateless)
    scene = tmp_path / "clock.toml"
    scene.write_text(CLOCK.format(pendulum=files["pendulum"], escapement=files["escapement"], master=master))
    for command in (["validate", str(scene)], ["run", str(scene), "--out", str(tmp_path / "out"), "--no-progress"]):
        rc = cli.main(command)
        _, err = capsys.readouterr()
        lines = err.strip().splitlines()
        assert rc == 2 and len(lines) == 1 and "Traceback" not in err, err
        for part in ("clock.toml", key, f"components.{stateless}", "Stateless.fmu", "canGetAndSetFMUstate",
                     needle):
            assert part in lines[0], (part, lines[0])
    assert not (tmp_path / "out").exists()


def test_an_fmu_without_state_runs_where_no_rollback_is_needed(tmp_path, capsys):
    stateless = tmp_path / "Stateless.fmu"
    _rewrite(fmu_file("GrasshopperEscapement"), stateless, _stateless)
    scene = tmp_path / "clock.toml"
    scene.write_text(CLOCK.format(pendulum=fmu_file("Pendulum"), escapement=stateless,
                                  master="event_location = false\n"))
    rc = cli.main(["run", str(scene), "--out", str(tmp_path / "out"), "--no-progress"])
    _, err = capsys.readouterr()
    assert rc == 0, err
    # A sweep that turns event location on for some points is refused as a whole, before any point runs.
    scene.write_text(scene.read_text()
                     + '[sweep]\naxes = [{ parameter = "master.event_location", values = [false, true] }]\n')
    rc = cli.main(["run", str(scene), "--out", str(tmp_path / "sweep"), "--no-progress"])
    _, err = capsys.readouterr()
    lines = err.strip().splitlines()
    assert rc == 2 and len(lines) == 1, err
    assert all(s in lines[0] for s in ("clock.toml", "sweep", "master.event_location", "canGetAndSetFMUstate"))
    assert not (tmp_path / "sweep").exists()


@pytest.mark.parametrize("engine", ["python", "compiled"])
def test_the_engine_refuses_an_fmu_without_state_too(tmp_path, engine):
    """From Python, without a scene: the master says so before its first step."""
    from clockwork.engine import MasterSettings, System
    from clockwork.errors import SceneError

    stateless = tmp_path / "Stateless.fmu"
    _rewrite(fmu_file("GrasshopperEscapement"), stateless, _stateless)
    comps = {"pendulum": ("Pendulum", {"phi_start": 0.1}), "escapement": (str(stateless), {})}
    links = ["pendulum.phi -> escapement.phi", "pendulum.w -> escapement.w",
             "escapement.tau -> pendulum.tau_escapement"]
    with pytest.raises(SceneError, match="master.event_location: escapement .Stateless.fmu. cannot save"):
        System(comps, links, MasterSettings(step=0.01, engine=engine))
    with System(comps, links, MasterSettings(step=0.01, engine=engine, event_location=False)) as s:
        s.master.run_until(0.5)
        assert s.master.stats.states_saved == 0
