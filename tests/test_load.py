"""clockwork.load(DIR): a finished run as an object (its summary, its data
read on first use from timeseries.parquet, .csv or .mat, its plots), shown
in a notebook, drawn, as pandas; bad directories refused in one line; and
clockwork.simulate(output_format=...)."""

from __future__ import annotations

import json
import os
import sys

import numpy as np
import pytest

import clockwork
from clockwork.errors import UsageError
from cwtest import CLOCK_SCENE, fmu_file, run_cli, test_fmu


def _run(capsys, tmp_path, target, name="run", *more):
    out = tmp_path / name
    rc, _, err = run_cli(capsys, ["run", target, "--out", out, "--no-progress", *more])
    assert rc == 0, err
    return out


def _same(a, b):
    assert a.dtype == b.dtype, (a.dtype, b.dtype)
    for n in a.dtype.names:
        assert np.array_equal(a[n], b[n], equal_nan=a[n].dtype.kind == "f"), n


@pytest.fixture(scope="module")
def decay(tmp_path_factory):
    """`clockwork run TestDecay.fmu`: a run of one FMU with its default plot."""
    from clockwork import cli

    out = tmp_path_factory.mktemp("decay") / "run"
    assert cli.main(["run", str(test_fmu("TestDecay")), "--out", str(out), "--no-progress"]) == 0
    return out


def test_a_run_loads_as_simulate_gives_it(decay):
    r = clockwork.load(decay)
    _same(r.series, clockwork.simulate(test_fmu("TestDecay")))
    assert r.summary["tool"]["name"] == "clockwork" and not r.is_sweep and r.failed is None
    assert [p.name for p in r.plots] == ["outputs.png"] and r.plots[0].is_file()
    assert r.columns[0] == "time" and r.series_file.name == "timeseries.csv"
    assert clockwork.load(str(decay)).series is not None  # a str path too


def test_every_fmi_type_comes_back_as_simulate_types_it(capsys, tmp_path):
    out = _run(capsys, tmp_path, test_fmu("TestTypes"))
    got, want = clockwork.load(out).series, clockwork.simulate(test_fmu("TestTypes"))
    assert got.dtype.names == want.dtype.names
    for n in want.dtype.names:
        assert got[n].dtype == want[n].dtype or (want[n].dtype == np.int32 and got[n].dtype == np.int64), n
        assert list(got[n]) == list(want[n]), n


def _write_parquet(series, path, names):
    pa = pytest.importorskip("pyarrow")
    import pyarrow.parquet as pq

    pq.write_table(pa.table({full: series[n] for full, n in zip(names, series.dtype.names)}), path)


def _chars(rows, trans):
    """A character matrix as savemat writes one: a string per row (a name per
    column with binTrans)."""
    width = max(1, max(len(r) for r in rows))
    padded = [r.ljust(width) for r in rows]
    return np.array(["".join(col) for col in zip(*padded)] if trans else padded)


def _write_mat(series, path, names, trans=True):
    """A result file in the Modelica layout (Dymola's dsres): time the abscissa
    (dataInfo block 0), the trajectories in data_2, a variable per row with binTrans."""
    scipy_io = pytest.importorskip("scipy.io")
    info = np.array([[0 if i == 0 else 2, i + 1, 0, -1] for i in range(len(names))], dtype=np.int32)
    data2 = np.array([np.asarray(series[n], dtype=np.float64) for n in series.dtype.names])
    data1 = np.array([[series["time"][0], series["time"][-1]]])
    aclass = _chars(["Atrajectory", "1.1", "", "binTrans" if trans else "binNormal"], False)
    scipy_io.savemat(path, {"Aclass": aclass, "name": _chars(names, trans),
                            "description": _chars([f"the {n}" for n in names], trans),
                            "dataInfo": info.T if trans else info,
                            "data_1": data1.T if trans else data1, "data_2": data2 if trans else data2.T},
                     format="5" if trans else "4")


@pytest.mark.parametrize("fmt", ["parquet", "mat-binTrans", "mat-binNormal"])
def test_parquet_and_mat_read_back_the_csvs_bits(decay, tmp_path, fmt):
    import shutil

    folder = tmp_path / "r"
    shutil.copytree(decay, folder)
    want = clockwork.load(folder).series
    full = ["time"] + [f"TestDecay.{n}" for n in want.dtype.names[1:]]
    if fmt == "parquet":
        _write_parquet(want, folder / "timeseries.parquet", full)
    else:
        _write_mat(want, folder / "timeseries.mat", full, trans=fmt == "mat-binTrans")
    (folder / "timeseries.csv").unlink()  # the other format alone
    r = clockwork.load(folder)
    assert r.series_file.suffix == "." + fmt.split("-")[0]
    _same(r.series, want)


def test_a_mat_file_with_a_negated_alias_and_a_constant(decay, tmp_path):
    import shutil

    scipy_io = pytest.importorskip("scipy.io")
    folder = tmp_path / "r"
    shutil.copytree(decay, folder)
    (folder / "timeseries.csv").unlink()
    t = np.array([0.0, 0.5, 1.0])
    names = ["time", "a.x", "a.minus_x", "a.k"]
    info = np.array([[0, 1, 0, -1], [2, 2, 0, -1], [2, -2, 0, -1], [1, 1, 0, 0]], dtype=np.int32).T
    scipy_io.savemat(folder / "timeseries.mat", {
        "Aclass": _chars(["Atrajectory", "1.1", "", "binTrans"], False),
        "name": _chars(names, True), "description": _chars([""] * 4, True), "dataInfo": info,
        "data_1": np.array([[2.5, 2.5]]).T, "data_2": np.array([t, [1.0, 2.0, 3.0]])})
    s = clockwork.load(folder).series
    assert s.dtype.names == ("time", "a.x", "a.minus_x", "a.k")
    assert list(s["a.minus_x"]) == [-1.0, -2.0, -3.0] and list(s["a.k"]) == [2.5, 2.5, 2.5]


@pytest.fixture(scope="module")
def sweep(tmp_path_factory):
    from clockwork import cli

    fmu_file("Pendulum")
    tmp = tmp_path_factory.mktemp("sweep")
    axes = '\n[sweep]\naxes = [ { parameter = "escapement.torque", values = ["0.4 N.cm", "0.5 N.cm"] } ]\n'
    scene = tmp / "s.toml"
    scene.write_text(CLOCK_SCENE.format(stop=0.5, sweep=axes))
    assert cli.main(["run", str(scene), "--out", str(tmp / "run"), "--no-progress"]) == 0
    return tmp / "run"


def test_a_sweep_loads_its_table(sweep):
    r = clockwork.load(sweep)
    assert r.is_sweep and r.columns[0] == "escapement.torque" and len(r.table) == 2
    with pytest.raises(UsageError, match="a sweep of 2 points"):
        r.series
    assert "sweep of 2 points" in repr(r)
    assert "<table>" in r._repr_html_()


def test_a_failed_run_loads_with_its_history(capsys, tmp_path):
    scene = tmp_path / "s.toml"
    fmu_file("Pendulum")
    scene.write_text(CLOCK_SCENE.format(stop=2.0, sweep="").replace('stop = "2.0 s"', 'stop = "2.0 s"'))
    out = tmp_path / "run"
    rc, _, err = run_cli(capsys, ["run", scene, "--out", out, "--no-progress", "--set", "master.divergence_limit=0.01"])
    if rc != 1:
        pytest.skip(f"the run did not fail ({rc}): {err}")
    r = clockwork.load(out)
    assert r.failed and "failed" in repr(r)


def test_the_rich_display_shows_the_summary_and_the_plots(decay, tmp_path):
    import shutil

    r = clockwork.load(decay)
    page = r._repr_html_()
    assert "<table>" in page and "data:image/png;base64," in page and "TestDecay" in page
    assert "clockwork result" in repr(r) and "outputs.png" in repr(r)

    class Printer:
        def __init__(self):
            self.out = []

        def text(self, s):
            self.out.append(s)

    p = Printer()
    r._repr_pretty_(p, False)
    assert p.out == [repr(r)]
    # text from the files is escaped, never markup
    folder = tmp_path / "r"
    shutil.copytree(decay, folder)
    summary = json.loads((folder / "summary.json").read_text())
    summary["title"] = "<script>alert(1)</script>"
    (folder / "summary.json").write_text(json.dumps(summary))
    page = clockwork.load(folder)._repr_html_()
    assert "<script>" not in page and "&lt;script&gt;" in page


def test_plot_draws_chosen_columns(decay):
    pytest.importorskip("matplotlib")
    r = clockwork.load(decay)
    fig = r.plot()
    assert fig.axes and fig._repr_png_().startswith(b"\x89PNG")
    names = r.columns[1:]
    fig = r.plot(names[0])
    assert [ln.get_label() for ax in fig.axes for ln in ax.get_lines()] == [names[0]]
    from matplotlib.figure import Figure

    ax = Figure().subplots()
    assert r.plot(names[0], ax=ax) is ax.figure
    with pytest.raises(UsageError, match="no column matches"):
        r.plot("nothing*")
    with pytest.raises(UsageError, match="expected column names"):
        r.plot(3)


def test_to_pandas_and_simulate_output_format(decay):
    pd = pytest.importorskip("pandas")
    r = clockwork.load(decay)
    df = r.to_pandas()
    assert list(df.columns) == list(r.columns) and np.array_equal(df["time"].to_numpy(), r.series["time"])
    got = clockwork.simulate(test_fmu("TestDecay"), output_format="pandas")
    want = clockwork.simulate(test_fmu("TestDecay"), output_format="structured")
    assert isinstance(got, pd.DataFrame) and list(got.columns) == list(want.dtype.names)
    for n in want.dtype.names:
        assert np.array_equal(got[n].to_numpy(), want[n]), n


@pytest.mark.parametrize("value", ["csv", "Pandas", "", None, 3, ["pandas"]])
def test_an_unknown_output_format_is_one_line_naming_it(value):
    with pytest.raises(UsageError) as e:
        clockwork.simulate(test_fmu("TestDecay"), output_format=value)
    assert "simulate(): output_format = " in str(e.value) and "'structured' or 'pandas'" in str(e.value)
    assert "\n" not in str(e.value)


def test_a_str_subclass_output_format_is_its_characters():
    class Odd(str):
        def __eq__(self, other):
            return True

        __hash__ = str.__hash__

    with pytest.raises(UsageError, match="output_format"):
        clockwork.simulate(test_fmu("TestDecay"), output_format=Odd("csv"))
    assert isinstance(clockwork.simulate(test_fmu("TestDecay"), output_format=Odd("structured")), np.ndarray)


def test_without_pandas_one_line_says_how_to_install_it(decay, monkeypatch):
    monkeypatch.setitem(sys.modules, "pandas", None)
    with pytest.raises(UsageError, match="pip install pandas"):
        clockwork.load(decay).to_pandas()
    with pytest.raises(UsageError, match=r"simulate\(output_format='pandas'\) needs pandas"):
        clockwork.simulate(test_fmu("TestDecay"), output_format="pandas")


def test_parquet_alone_without_pyarrow_says_how_to_install_it(decay, tmp_path, monkeypatch):
    import shutil

    folder = tmp_path / "r"
    shutil.copytree(decay, folder)
    (folder / "timeseries.csv").rename(folder / "timeseries.parquet")
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda n, *a: None if n == "pyarrow" else real(n, *a))
    with pytest.raises(UsageError, match=r"timeseries.parquet: reading Parquet needs pyarrow: pip install"):
        clockwork.load(folder).series


# -- bad directories: one line, naming the path --------------------------------------------


def _copy(decay, tmp_path):
    import shutil

    folder = tmp_path / "r"
    shutil.copytree(decay, folder)
    return folder


def _writes(text):
    def write(folder):
        (folder / "summary.json").write_bytes(text if isinstance(text, bytes) else text.encode())
        return folder
    return write


def _summary_edit(change):
    def edit(folder):
        s = json.loads((folder / "summary.json").read_text())
        change(s)
        (folder / "summary.json").write_text(json.dumps(s))
    return edit


BAD_DIRECTORIES = {
    "missing": (lambda f: f.joinpath("gone"), "gone: no such directory: expected the --out directory"),
    "a file": (lambda f: (f / "summary.json"), "summary.json: is a regular file, expected the --out directory"),
    "no summary": (lambda f: (f / "summary.json").unlink() or f, "no summary.json: expected the --out directory"),
    "another program's summary": (_writes('{"name": "x", "version": 3}'),
                                  "summary.json: tool: expected"),
    "another tool": (lambda f: _summary_edit(lambda s: s.update(tool={"name": "other"}))(f) or f, "tool: expected"),
    "malformed JSON": (_writes('{"tool": '), "not a summary clockwork wrote"),
    "JSON with NaN": (_writes('{"tool": NaN}'), "not a summary clockwork wrote"),
    "a key twice": (_writes('{"a": 1, "a": 2}'), "given twice"),
    "not an object": (_writes('[1, 2]'), "expected a JSON object"),
    "huge": (lambda f: os.truncate(f / "summary.json", (1 << 26) + 1) or f, "more than 67108864 bytes"),
    "not UTF-8": (_writes(b'{"tool": "\xff"}'), "not a summary"),
    "summary a directory": (lambda f: ((f / "summary.json").unlink(), (f / "summary.json").mkdir()) and f,
                            "no summary.json"),
    "files not a list": (lambda f: _summary_edit(lambda s: s.update(files="x.png"))(f) or f,
                         "files: expected a list of file names"),
    "a file outside": (lambda f: _summary_edit(lambda s: s["files"].append("../../etc/x.png"))(f) or f,
                       "expected the name of a file in"),
    "a hidden file": (lambda f: _summary_edit(lambda s: s["files"].append(".x.png"))(f) or f,
                      "expected the name of a file in"),
    "columns not an object": (lambda f: _summary_edit(lambda s: s.update(columns=[1]))(f) or f,
                              "columns: expected an object"),
}


@pytest.mark.parametrize("case", list(BAD_DIRECTORIES))
def test_a_directory_that_is_no_clockwork_result_is_one_line(decay, tmp_path, case):
    make, needle = BAD_DIRECTORIES[case]
    target = make(_copy(decay, tmp_path))
    with pytest.raises(UsageError) as e:
        clockwork.load(target)
    text = str(e.value)
    assert needle in text and "\n" not in text and str(tmp_path) in text, text


def test_a_fifo_summary_is_refused_without_blocking(decay, tmp_path):
    folder = _copy(decay, tmp_path)
    (folder / "summary.json").unlink()
    os.mkfifo(folder / "summary.json")
    with pytest.raises(UsageError, match="no summary.json"):
        clockwork.load(folder)


@pytest.mark.parametrize("path", [3, b"/tmp", None, "", ["a"]])
def test_a_path_of_another_kind_is_one_line(path):
    with pytest.raises(UsageError, match=r"load\(\): path = "):
        clockwork.load(path)


BAD_SERIES = {
    "a word for a number": ("time,TestDecay.x\n0.0,1.0\n0.1,abc\n", "line 3, column 2 (TestDecay.x): expected a number"),
    "1_0 for a number": ("time,TestDecay.x\n0.0,1_0\n", "line 2, column 2"),
    "a short row": ("time,TestDecay.x\n0.0,1.0\n0.1\n", "line 3: 1 values for 2 columns"),
    "no time first": ("x,time\n1.0,0.0\n", "expected time"),
    "empty": ("", "line 1: expected a header line"),
    "not UTF-8": (b"time,x\n\xff,1\n", "cannot read"),
}


@pytest.mark.parametrize("case", list(BAD_SERIES))
def test_a_broken_series_file_is_one_line_naming_it(decay, tmp_path, case):
    folder = _copy(decay, tmp_path)
    text, needle = BAD_SERIES[case]
    p = folder / "timeseries.csv"
    p.write_bytes(text if isinstance(text, bytes) else text.encode())
    with pytest.raises(UsageError) as e:
        clockwork.load(folder).series
    msg = str(e.value)
    assert str(p) in msg and "\n" not in msg
    assert any(n in msg for n in needle.split("|")), msg


@pytest.mark.parametrize("name, data", [("timeseries.parquet", b"PAR1 not really"),
                                        ("timeseries.mat", b"MATLAB 5.0 garbage" + bytes(200)),
                                        ("timeseries.mat", b"")])
def test_a_broken_parquet_or_mat_file_is_one_line(decay, tmp_path, name, data):
    if name.endswith("parquet"):
        pytest.importorskip("pyarrow")
    folder = _copy(decay, tmp_path)
    (folder / "timeseries.csv").unlink()
    (folder / name).write_bytes(data)
    with pytest.raises(UsageError) as e:
        clockwork.load(folder).series
    assert str(folder / name) in str(e.value) and "\n" not in str(e.value)


def test_a_mat_file_of_another_layout_is_one_line(decay, tmp_path):
    scipy_io = pytest.importorskip("scipy.io")
    folder = _copy(decay, tmp_path)
    (folder / "timeseries.csv").unlink()
    scipy_io.savemat(folder / "timeseries.mat", {"x": np.arange(3.0)})
    with pytest.raises(UsageError, match="not a result file in the Modelica layout: no Aclass"):
        clockwork.load(folder).series


def test_load_refuses_every_other_kind_of_path():
    """Each sample value the path spec refuses (hostile objects among them): one line naming the argument."""
    refused = clockwork.load.__arguments__["path"].refused()
    assert refused
    for bad in refused:
        with pytest.raises(UsageError) as e:
            clockwork.load(bad)
        assert str(e.value).startswith("load(): path = ") and "\n" not in str(e.value)


def test_parquet_columns_of_other_widths_come_back_in_the_variables_types(capsys, tmp_path):
    """A Parquet writer may keep an Integer as int64 or a Boolean as a number:
    the series gives each in its FMI type, as from the CSV."""
    pa = pytest.importorskip("pyarrow")
    import pyarrow.parquet as pq

    out = _run(capsys, tmp_path, test_fmu("TestTypes"))
    r = clockwork.load(out)
    want = r.series
    info = r.summary["columns"]
    strip = next(iter(r.summary["fmus"]))
    table = {}
    for n in want.dtype.names:
        full = n if n == "time" else f"{strip}.{n}"
        col = want[n]
        kind = info.get(full, {}).get("type")
        table[full] = col.astype(np.int64) if col.dtype.kind in "iu" else (
            col.astype(np.float64) if kind == "Boolean" else col)
    (out / "timeseries.csv").unlink()
    pq.write_table(pa.table(table), out / "timeseries.parquet")
    _same(clockwork.load(out).series, want)
