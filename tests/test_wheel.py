"""The wheel, as a user gets it: built from this checkout, installed into a
fresh virtual environment outside the checkout, and used from a directory
that is not the checkout. It must carry the FMUs and the scenes itself.

The venv is empty: pip installs the wheel and its dependencies into it (from
the index, or pip's cache), as it would for a user; the test checks that the
package it runs lives in the venv, not in this checkout.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import zipfile

import pytest

from cwtest import ROOT




@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("wheel")
    dist = tmp / "dist"
    r = subprocess.run([sys.executable, "-m", "pip", "wheel", str(ROOT), "--no-deps", "-w", str(dist), "-q"],
                       capture_output=True, text=True, timeout=1200)
    assert r.returncode == 0, r.stderr[-3000:]
    (wheel,) = dist.glob("clockwork_fmi-*.whl")
    venv = tmp / "venv"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
    r = subprocess.run([str(venv / "bin" / "python"), "-m", "pip", "install", "-q", str(wheel)],
                       capture_output=True, text=True, timeout=1200)
    assert r.returncode == 0, r.stderr[-3000:]
    work = tmp / "elsewhere"
    work.mkdir()
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "CLOCKWORK_FMU_DIR", "VIRTUAL_ENV")}
    env.update(PATH=f"{venv / 'bin'}{os.pathsep}{env['PATH']}", CLOCKWORK_CACHE=str(tmp / "cache"),
               MPLBACKEND="Agg")

    def clockwork(*args, check=True):
        p = subprocess.run([str(venv / "bin" / "clockwork"), *map(str, args)], cwd=work, env=env,
                           capture_output=True, text=True, timeout=900)
        if check:
            assert p.returncode == 0, (args, p.stdout[-2000:], p.stderr[-2000:])
        return p

    return wheel, venv, work, env, clockwork


@pytest.mark.slow
def test_the_wheel_carries_the_fmus_scenes_and_license(installed):
    wheel = installed[0]
    names = zipfile.ZipFile(wheel).namelist()
    models = sorted(f"{p.name}.fmu" for p in (ROOT / "src_c" / "models").iterdir() if p.is_dir())
    for folder in ("clockwork/data/fmus/", "clockwork/data/fmus/fmi3/"):  # the FMI 2.0 and 3.0 builds
        fmus = sorted(n[len(folder):] for n in names if n.startswith(folder) and "/" not in n[len(folder):])
        assert fmus == models, folder
    scenes = {n.rsplit("/", 1)[1] for n in names if n.startswith("clockwork/data/scenarios/")}
    assert scenes == {p.name for p in (ROOT / "scenarios").iterdir() if p.suffix in (".toml", ".json")}
    assert any(n.endswith(".dist-info/licenses/LICENSE") for n in names)
    assert "clockwork/data/lib/libcw_master.so" in names  # the master's compiled core
    meta = zipfile.ZipFile(wheel).read(next(n for n in names if n.endswith(".dist-info/METADATA"))).decode()
    assert "Name: clockwork-fmi" in meta and "License-Expression: MIT" in meta
    dask = [ln for ln in meta.splitlines() if ln.startswith("Requires-Dist: dask")]
    assert dask and all("extra ==" in ln for ln in dask)  # an optional extra, never required


@pytest.mark.slow
def test_the_package_runs_from_the_venv(installed):
    _, venv, work, env, _ = installed
    p = subprocess.run([str(venv / "bin" / "python"), "-c", "import clockwork; print(clockwork.__file__)"],
                       cwd=work, env=env, capture_output=True, text=True)
    assert p.returncode == 0 and str(venv) in p.stdout, p


@pytest.mark.slow
def test_list_info_run_export_gallery_from_anywhere(installed):
    _, venv, work, env, clockwork = installed
    listed = clockwork("list").stdout
    assert "ziemkiewicz_fig4a.toml" in listed and "core_grasshopper.toml" in listed
    info = clockwork("info", "Pendulum").stdout
    assert info.startswith("Pendulum (FMI 2.0 Co-Simulation)") and str(venv) in info
    p = subprocess.run([str(venv / "bin" / "python"), "-c", "from clockwork.paths import fmu_dir; print(fmu_dir(3))"],
                       cwd=work, env=env, capture_output=True, text=True)
    info3 = clockwork("info", f"{p.stdout.strip()}/Pendulum.fmu").stdout
    assert info3.startswith("Pendulum (FMI 3.0 Co-Simulation)") and str(venv) in info3
    clockwork("run", "core_grasshopper", "--out", "run", "--no-progress", "--set", "master.engine=compiled")
    summary = json.loads((work / "run" / "summary.json").read_text())
    assert summary["settings"]["master"]["engine"] == "compiled"
    assert all((work / "run" / f).is_file() for f in summary["files"])
    clockwork("export-ssp", "core_grasshopper", "--out", "clock.ssp")
    assert zipfile.is_zipfile(work / "clock.ssp")
    clockwork("gallery", "--quick", "--only", "core_grasshopper", "--out", "gallery")
    assert (work / "gallery" / "index.md").is_file()


@pytest.mark.slow
def test_the_regression_kit_from_the_wheel(installed):
    _, _, work, _, clockwork = installed
    clockwork("export-suite", "kit")
    assert (work / "kit" / "suite.json").is_file()


def test_scheduler_without_dask_is_one_line(tmp_path, capsys, monkeypatch):
    import importlib.util

    from clockwork import cli

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "distributed" else real(name, *a))
    rc = cli.main(["run", str(ROOT / "scenarios" / "core_grasshopper.toml"), "--out", str(tmp_path / "d"),
                   "--scheduler", "tcp://127.0.0.1:1"])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1 and "pip install 'clockwork-fmi[dask]'" in err
    assert not (tmp_path / "d").exists()


@pytest.mark.slow
def test_load_and_the_notebook_from_the_wheel(installed):
    """clockwork.load on a run made by the installed command, from another
    directory, and the docs' notebook (its code cells as one script: no
    kernel in that venv) on the installed package."""
    _, venv, work, env, clockwork = installed
    clockwork("run", "core_grasshopper", "--out", "grasshopper", "--no-progress")
    other = work / "other"
    other.mkdir(exist_ok=True)
    code = ("import clockwork, sys\n"
            "r = clockwork.load(sys.argv[1])\n"
            "assert clockwork.__file__.startswith(sys.prefix), clockwork.__file__\n"
            "assert r.series.dtype.names[0] == 'time' and len(r.series) > 100\n"
            "assert [p.name for p in r.plots] == ['phi.png']\n"
            "assert 'data:image/png;base64,' in r._repr_html_()\n"
            "r.plot().savefig('quick.png')\n"
            "print('loaded', len(r.series))\n")
    p = subprocess.run([str(venv / "bin" / "python"), "-c", code, "../grasshopper"], cwd=other, env=env,
                       capture_output=True, text=True, timeout=300)
    assert p.returncode == 0 and "loaded" in p.stdout, p.stderr[-3000:]
    assert (other / "quick.png").is_file()
    # The notebook needs pandas (simulate's DataFrame): installed into the venv as a user would.
    r = subprocess.run([str(venv / "bin" / "python"), "-m", "pip", "install", "-q", "pandas"],
                       capture_output=True, text=True, timeout=1200)
    assert r.returncode == 0, r.stderr[-3000:]
    notebook = json.loads((ROOT / "docs" / "notebooks" / "tour.ipynb").read_text())
    script = "\n\n".join("".join(c["source"]) for c in notebook["cells"] if c["cell_type"] == "code")
    p = subprocess.run([str(venv / "bin" / "python"), "-c", script], cwd=other, env=env,
                       capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, (p.stdout[-2000:], p.stderr[-3000:])
