"""One factory (engine/instances.py) makes every instance: no other module
defines one, and it picks the face by the FMU's interface and version."""

import re
from pathlib import Path

import pytest

from clockwork.fmi.cs2 import Instance2
from clockwork.fmi.cs3 import Instance3
from clockwork.engine.instances import make_instance
from clockwork.errors import SceneError

ROOT = Path(__file__).resolve().parents[1]


def test_make_instance_is_defined_once():
    defined = [p.relative_to(ROOT).as_posix() for p in (ROOT / "clockwork").rglob("*.py")
               if re.search(r"^def make_instance\b", p.read_text(), flags=re.M)]
    assert defined == ["clockwork/engine/instances.py"]


@pytest.mark.parametrize("folder, face", [("fmus", Instance2), ("fmus/fmi3", Instance3)])
def test_it_picks_the_face_by_version_and_refuses_an_interface_the_fmu_lacks(folder, face):
    path = ROOT / folder / "Pendulum.fmu"
    inst = make_instance("p", path)
    assert type(inst) is face
    with pytest.raises(SceneError, match="no Model Exchange interface"):
        make_instance("p", path, interface="model-exchange")
