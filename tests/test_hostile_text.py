"""Text from files, drawn and echoed: FMU variable names, units and titles
reach matplotlib as plain text (no mathtext, "_x" kept in legends, missing
glyphs without a warning, long text cut), reach the terminal with their
control characters escaped, and reach the CSV writer only as names FMI
allows; `clockwork plot` checks what it reads and touches only the files it
writes; the default plot draws a bounded number of pages, each saved
before the next is built."""

from __future__ import annotations

import csv
import json
import os
import subprocess
import sys
import warnings
import zipfile
from pathlib import Path

import pytest

from clockwork.errors import SceneError, SimulationError, printable
from clockwork.results.plots import outputs as outputs_mod
from clockwork.results.plots import redraw as redraw_mod
from clockwork.results.plots import registry
from clockwork.results.plots.outputs import MAX_AXES, MAX_LINES, Column, draw_outputs
from cwtest import ROOT, assert_one_line_error, fmu_file, run_cli

import numpy as np

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


def _cli(args: list, cwd: Path) -> subprocess.CompletedProcess:
    """`clockwork` as a user runs it: its early plot process forked at the start."""
    env = {**os.environ, "CLOCKWORK_CACHE": "off"}
    return subprocess.run([sys.executable, "-m", "clockwork", *map(str, args)], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=300)


# -- 8. names drawn as plain text ------------------------------------------------------------

def test_hostile_names_are_drawn_by_the_plot_process_and_clockwork_plot_without_a_word(tmp_path):
    fmu = renamed_pendulum(tmp_path)
    r = _cli(["run", fmu, "--out", tmp_path / "r", "--no-progress", "--set", "experiment.stop=0.5"], tmp_path)
    assert r.returncode == 0 and r.stderr == "", r.stderr
    assert (tmp_path / "r" / "outputs.png").stat().st_size > 10_000
    header = next(csv.reader(open(tmp_path / "r" / "timeseries.csv", newline="", encoding="utf-8")))
    assert {r"Pendulum.$\frac$", "Pendulum._hidden", "Pendulum.温度😀"} <= set(header)
    (tmp_path / "r" / "outputs.png").unlink()
    r = _cli(["plot", tmp_path / "r"], tmp_path)
    assert r.returncode == 0 and r.stderr == "", r.stderr
    assert (tmp_path / "r" / "outputs.png").stat().st_size > 10_000


def test_labels_are_the_names_as_written_underscore_and_dollars_included(tmp_path):
    names = [r"$\frac$", "_hidden", "a$b$c", "温度😀", "line\nbreak", "x" * 1000]
    cols = [Column(n, np.array([0.0, 1.0]), "m", "real") for n in names]
    with registry.quiet_matplotlib():
        fig = draw_outputs([0.0, 1.0], cols, "$x$ " + "t" * 100_000)[0]
    texts = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert texts[:4] == [r"\$\frac\$", "_hidden", r"a\$b\$c", "温度😀"]
    assert texts[4] == r"line\x0abreak"
    assert len(texts[5]) == registry.MAX_LABEL and texts[5].endswith("\u2026")
    title = fig._suptitle.get_text()
    assert len(title.replace(r"\$", "$")) == registry.MAX_TITLE and title.startswith(r"\$x\$ tt")
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        with registry.quiet_matplotlib():
            registry.save(fig, tmp_path / "p.png")
    assert not [w for w in seen if "Glyph" in str(w.message)], [str(w.message) for w in seen]


def test_plain_leaves_ordinary_text_alone():
    for s in ("Ziemkiewicz Fig. 4(a): rate errors", "pendulum.phi (deg)", "E_T_s_per_day", "温度"):
        assert registry.plain(s) == s


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


def _result(d: Path, header: list[str], summary: dict | str = "{}", rows=((0.0, 1.0), (1.0, 2.0))) -> Path:
    d.mkdir(parents=True, exist_ok=True)
    (d / "summary.json").write_text(summary if isinstance(summary, str) else json.dumps(summary))
    with open(d / "timeseries.csv", "w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(header)
        w.writerows(rows)
    return d


def test_clockwork_plot_echoes_column_names_escaped(capsys, tmp_path):
    d = _result(tmp_path / "r", ["time", "\x1b]0;owned\x07x\u202e"])
    rc, _, err = run_cli(capsys, ["plot", d, "--only", "nothing"])
    assert_one_line_error(rc, err, r"\x1b]0;owned\x07x\u202e")
    assert not any(c in err for c in "\x1b\x07\u202e")


# -- 9. clockwork plot on a hostile result folder ----------------------------------------------

@pytest.mark.parametrize("summary, needle", [
    ({"columns": {"x": []}}, 'columns["x"]: expected an object, got an array'),
    ({"columns": {"x": {"unit": ["m"]}}}, 'columns["x"].unit: expected a string or null, got an array'),
    ({"columns": {"x": {"type": {}}}}, 'columns["x"].type: expected a string or null, got an object'),
    ({"columns": {"x": {"variability": 3}}}, 'columns["x"].variability: expected a string or null, got a number'),
    ({"columns": []}, "columns: expected an object, got an array"),
    ({"title": ["t"]}, "title: expected a string, got an array"),
    ({"fmus": "P"}, "fmus: expected an object, got a string"),
    ("[" * 100_000 + "]" * 100_000, "not a summary clockwork wrote"),
])
def test_clockwork_plot_refuses_a_malformed_summary_in_one_line(capsys, tmp_path, summary, needle):
    d = _result(tmp_path / "r", ["time", "x"], summary)
    rc, _, err = run_cli(capsys, ["plot", d])
    assert_one_line_error(rc, err, "summary.json", needle)


def test_clockwork_plot_does_not_read_a_huge_summary(capsys, tmp_path, monkeypatch):
    d = _result(tmp_path / "r", ["time", "x"])
    with open(d / "summary.json", "wb") as f:
        f.truncate(3 << 30)  # sparse: 3 GiB of nothing on disk
    read = []
    real_open = open

    def spy(path, *a, **k):
        read.append(Path(path).name)
        return real_open(path, *a, **k)

    monkeypatch.setattr("builtins.open", spy)
    rc, _, err = run_cli(capsys, ["plot", d])
    assert_one_line_error(rc, err, "summary.json: more than 67108864 bytes")
    assert "summary.json" not in read


def test_clockwork_plot_draws_a_huge_title_and_names_cut_short(capsys, tmp_path, monkeypatch):
    d = _result(tmp_path / "r", ["time", "n" * 100_000], {"title": "T" * 200_000})
    drawn = []
    real_save = redraw_mod.save

    def spy(fig, path):
        drawn.append([fig._suptitle.get_text()] + [t.get_text() for t in fig.axes[0].get_legend().get_texts()])
        real_save(fig, path)

    monkeypatch.setattr(redraw_mod, "save", spy)
    rc, out, err = run_cli(capsys, ["plot", d])
    assert rc == 0 and err == "" and (d / "outputs.png").stat().st_size > 1000, err
    (title, label), = drawn
    assert title == "T" * (registry.MAX_TITLE - 1) + "\u2026"
    assert label == "n" * (registry.MAX_LABEL - 1) + "\u2026"


def test_clockwork_plot_refuses_an_out_that_is_a_directory(capsys, tmp_path):
    d = _result(tmp_path / "r", ["time", "x"])
    (tmp_path / "x.png").mkdir()
    rc, _, err = run_cli(capsys, ["plot", d, "--out", tmp_path / "x.png"])
    assert_one_line_error(rc, err, f"--out {tmp_path / 'x.png'}: is a directory")


def test_clockwork_plot_removes_no_file_it_did_not_write(capsys, tmp_path):
    d = _result(tmp_path / "r", ["time", "x"])
    (tmp_path / "mine").mkdir()
    mine = tmp_path / "mine" / "holiday_2.png"
    mine.write_bytes(b"a holiday photo")
    rc, out, err = run_cli(capsys, ["plot", d, "--out", tmp_path / "mine" / "holiday.png"])
    assert rc == 0 and out.strip() == f"wrote {tmp_path / 'mine' / 'holiday.png'}"
    assert mine.read_bytes() == b"a holiday photo"
    assert err.startswith("clockwork: note: ") and "holiday_2.png" in err and len(err.splitlines()) == 1


# -- 14. many outputs: bounded pages, one at a time ---------------------------------------------

def test_many_outputs_draw_at_most_max_pages_each_saved_before_the_next(capsys, tmp_path, monkeypatch):
    n = MAX_AXES * MAX_LINES * 3 + 5  # full pages: three of them and a bit
    d = _result(tmp_path / "r", ["time"] + [f"y{k}" for k in range(n)], rows=[[0.0] + [1.0] * n, [1.0] * (n + 1)])
    monkeypatch.setattr(outputs_mod, "MAX_PAGES", 2)
    saved = []
    real_save = redraw_mod.save

    def spy(fig, path):
        assert all(not f.axes for f in saved), "a page was built before the one before it was let go"
        real_save(fig, path)
        saved.append(fig)

    monkeypatch.setattr(redraw_mod, "save", spy)
    rc, out, err = run_cli(capsys, ["plot", d])
    assert rc == 0, err
    assert out.split() == ["wrote", str(d / "outputs.png"), "wrote", str(d / "outputs_2.png")]
    drawn = 2 * MAX_AXES * MAX_LINES
    assert err.strip() == (f"clockwork: note: {d / 'outputs.png'}: drew {drawn} of the {n} recorded numbers on 2 "
                           f"pages, the most a drawing has; the other {n - drawn} are in timeseries.csv; "
                           f"`clockwork plot {d} --only PATTERN...` draws those")


def test_a_run_with_more_pages_than_the_bound_says_what_it_left_out(capsys, tmp_path, monkeypatch):
    monkeypatch.setattr(outputs_mod, "MAX_PAGES", 1)
    monkeypatch.setattr(outputs_mod, "MAX_AXES", 1)  # a page for each unit: the Pendulum has several
    rc, out, err = run_cli(capsys, ["run", fmu_file("Pendulum"), "--out", tmp_path / "r", "--no-progress",
                                    "--set", "experiment.stop=0.2"])
    assert rc == 0, err
    summary = json.loads((tmp_path / "r" / "summary.json").read_text())
    assert [f for f in summary["files"] if f.startswith("outputs")] == ["outputs.png"]
    (note,) = summary["plots_notes"]
    assert note.startswith("outputs.png: drew ") and "recorded numbers on 1 pages" in note
    assert err.strip() == f"clockwork: note: {note}"


def test_clockwork_plot_reads_no_more_values_than_a_run_records(capsys, tmp_path, monkeypatch):
    from clockwork.analyses.bounds import MAX_KEPT_VALUES

    assert redraw_mod.MAX_SERIES_VALUES == MAX_KEPT_VALUES
    monkeypatch.setattr(redraw_mod, "MAX_SERIES_VALUES", 10)
    d = _result(tmp_path / "r", ["time", "x"], rows=[(t, t) for t in range(6)])
    rc, _, err = run_cli(capsys, ["plot", d])
    assert_one_line_error(rc, err, "timeseries.csv: more than 10 values")
    d = _result(tmp_path / "s", ["time", "x"], rows=[(t, t) for t in range(5)])
    rc, _, err = run_cli(capsys, ["plot", d])
    assert rc == 0, err


def test_info_validate_and_list_print_file_text_escaped(capsys, tmp_path):
    fmu = renamed_pendulum(tmp_path)
    rc, out, err = run_cli(capsys, ["info", fmu])
    assert rc == 0 and r"bidi\u202ex\x9by" in out and not any(c in out for c in "\u202e\x9b"), err
    d = tmp_path / "scenes"
    d.mkdir()
    (d / "s.toml").write_text('[scene]\ntitle = "t\\u001b[2Jx\\u202e"\n[components.p]\nfmu = "Pendulum"\n'
                              '[experiment]\nstop = 0.1\n')
    for cmd in (["validate", d / "s.toml"], ["list", d]):
        rc, out, err = run_cli(capsys, cmd)
        assert rc == 0 and r"t\x1b[2Jx\u202e" in out and not any(c in out for c in "\x1b\u202e"), (cmd, out, err)


def test_the_progress_bar_names_the_scene_escaped(capsys, tmp_path, monkeypatch):
    """The bar's label is the scene file's name, which may hold terminal
    escapes: shown escaped, as every other text from the user's files."""
    import sys
    import types

    from cwtest import CLOCK_SCENE, fmu_file, run_cli

    fmu_file("Pendulum")
    sweep = '\n[sweep]\naxes = [ { parameter = "escapement.torque", values = ["0.4 N.cm", "0.45 N.cm"] } ]\n'
    f = tmp_path / "s\x1b[2J\u202e.toml"
    f.write_text(CLOCK_SCENE.format(stop=0.2, sweep=sweep))
    labels = []

    class Bar:
        def __init__(self, *a, desc="", **k):
            labels.append(desc)

        def update(self, *a, **k):
            pass

        def close(self):
            pass

        def __getattr__(self, name):
            return lambda *a, **k: None

    monkeypatch.setitem(sys.modules, "tqdm", types.SimpleNamespace(tqdm=Bar))
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True)  # a bar only on a terminal
    monkeypatch.setenv("CLOCKWORK_CACHE", "off")
    rc, _, err = run_cli(capsys, ["run", f, "--out", tmp_path / "out", "--no-plot", "--workers", "1"])
    assert rc == 0, err
    assert labels == ["s\\x1b[2J\\u202e"], labels
