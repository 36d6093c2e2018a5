"""Text from files, echoed: control characters reach the terminal escaped,
and the CSV writer gets only names FMI allows."""

from __future__ import annotations

import zipfile
from pathlib import Path

import pytest

from clockwork.errors import SceneError, SimulationError, printable
from cwtest import assert_one_line_error, fmu_file, run_cli

# Names of Pendulum's outputs replaced (XML text: character references allowed).
HOSTILE = {"phi": r"$\frac$", "w": "_hidden", "a": "温度😀", "energy": "a$b$c", "period": "bidi&#8238;x&#155;y"}


def renamed_pendulum(d: Path, names: dict[str, str] = HOSTILE) -> Path:
    """Pendulum.fmu with outputs renamed in its modelDescription.xml (the
    binary knows value references only)."""
    dst = d / "P.fmu"
    with zipfile.ZipFile(fmu_file("Pendulum")) as zin, zipfile.ZipFile(dst, "w") as zout:
        for item in zin.infolist():
            data = zin.read(item)
            if item.filename == "modelDescription.xml":
                text = data.decode()
                for old, new in names.items():
                    assert f'name="{old}"' in text
                    text = text.replace(f'ScalarVariable name="{old}"', f'ScalarVariable name="{new}"', 1)
                data = text.encode()
            zout.writestr(item, data)
    return dst


# -- 8. names FMI allows

@pytest.mark.parametrize("ref", ["&#10;", "&#13;", "&#9;"])
def test_a_name_with_a_line_break_or_a_tab_is_refused_naming_the_file_and_variable(capsys, tmp_path, ref):
    fmu = renamed_pendulum(tmp_path, {"phi": f"ph{ref}i"})
    for cmd in (["validate", fmu], ["run", fmu, "--out", tmp_path / "r", "--no-progress"]):
        rc, _, err = run_cli(capsys, cmd)
        assert_one_line_error(rc, err, "P.fmu: modelDescription.xml", "name", "CR, LF and TAB")
    assert not (tmp_path / "r" / "summary.json").exists()


# -- 10. control characters echoed escaped ----------------------------------------------------

def test_printable_escapes_what_a_terminal_acts_on():
    assert printable("a\x1b[2Jb\x9bc\u202ed\x7fe\ud800f") == r"a\x1b[2Jb\x9bc\u202ed\x7fe\ud800f"
    assert printable("Ärger 温度 $x$ tab") == "Ärger 温度 $x$ tab"
    assert "\x1b" not in str(SceneError("bad \x1b]0;title\x07", "f\x1b.toml", "k\u202e"))
    assert "\x1b" not in str(SimulationError("m", time=0.0, instance="i\x1b", variable="v\x9b"))


def test_an_input_csv_header_with_escape_bytes_is_echoed_escaped(capsys, tmp_path):
    (tmp_path / "in.csv").write_bytes(b"time,\x1b[31mred\x1b[0m\xc2\x9b\xe2\x80\xae\n0,1\n1,2\n")
    rc, _, err = run_cli(capsys, ["run", fmu_file("Pendulum"), "--input", tmp_path / "in.csv", "--out",
                                  tmp_path / "r", "--no-progress"])
    assert_one_line_error(rc, err, r"\x1b[31mred")
    assert not any(c in err for c in "\x1b\x9b\u202e")


