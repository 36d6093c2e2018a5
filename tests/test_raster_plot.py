"""The default plot drawn by Pillow (clockwork/results/plots/raster.py): an
FMU's first run draws it without importing matplotlib, and any column a run
can record (non-finite, huge, subnormal, a single row, a million rows, names
in any script) gives a proper PNG."""

from __future__ import annotations

import io
import os
import subprocess
import sys

import numpy as np
import pytest
from PIL import Image

from clockwork.results.plots import raster
from clockwork.results.plots.outputs import Column, Pages
from cwtest import ROOT, test_fmu

pytestmark = pytest.mark.skipif(not raster.available(), reason="Pillow with FreeType, or matplotlib's font, missing")


def test_ticks_are_round_and_labels_tell_them_apart():
    assert raster.nice_ticks(-4.8, 4.6, 5) == [-4.0, -2.0, 0.0, 2.0, 4.0]
    assert raster.nice_ticks(-0.05, 1.05, 5) == [0.0, 0.25, 0.5, 0.75, 1.0]
    assert raster.tick_labels([0.0, 0.25, 0.5]) == (["0.00", "0.25", "0.50"], "")
    assert raster.tick_labels([-2.0, 0.0, 2.0]) == (["\u22122", "0", "2"], "")
    labels, offset = raster.tick_labels(raster.nice_ticks(1e-6, 3e-6, 5))
    assert offset == "1e-6" and len(set(labels)) == len(labels)
    assert raster.nice_ticks(-1e308, 1e308, 5)[0] >= -1e308  # no overflow


def _png(page) -> Image.Image:
    image = Image.open(io.BytesIO(page.png()))
    image.load()
    return image


@pytest.mark.parametrize("time, values, kind", [
    ([0.0, 1.0, 2.0], [1e308, -1e308, 0.0], "real"),
    ([0.0, 1.0, 2.0], [1e308] * 3, "real"),
    ([0.0, 1.0, 2.0], [0.0, 5e-324, 1e-320], "real"),
    ([0.0, 1.0, 2.0], [np.nan, np.inf, -np.inf], "real"),
    ([0.0, 1.0, 2.0], [np.inf, 1.0, np.nan], "discrete"),
    ([0.0], [2.0], "real"),
    ([0.0], [1.0], "boolean"),
    ([np.nan, np.nan], [1.0, 2.0], "real"),
    ([1e9, 1e9 + 1e-3], [1.0, 2.0], "real"),
    (np.linspace(0.0, 10.0, 1_000_000), np.sin(np.linspace(0.0, 10.0, 1_000_000)), "real"),
])
def test_every_column_gives_a_proper_png(time, values, kind):
    cols = [Column("y", np.asarray(values, dtype=float), "m", kind),
            Column("\u6f22\u5b57 $\\frac$ \U0001f600 " + "long " * 40, np.asarray(values, dtype=float), "m", kind)]
    pages = list(Pages(time, cols, "a title"))
    assert len(pages) == 1
    pages[0].footnote = "--set a.b=1"
    image = _png(pages[0])
    assert image.mode == "RGB" and image.width == 1100 and 200 < image.height < 1000
    assert round(image.info["dpi"][0]) == raster.DPI
    pixels = np.asarray(image)
    assert (pixels < 128).any() and (pixels == 255).mean() > 0.5  # something drawn on white


def test_pages_hold_a_screenful_each():
    cols = [Column(f"v{k}", np.arange(5.0) * k, f"u{k}", "real") for k in range(8)]
    pages = list(Pages(np.arange(5.0), cols, "many"))
    assert [len(p.axes) for p in pages] == [6, 2]
    assert pages[0].title == "many  (page 1 of 2)"
    assert _png(pages[0]).height <= 1000


def test_an_fmus_run_draws_its_plot_without_matplotlib(tmp_path):
    """Neither the command nor its plot process imports matplotlib (-X
    importtime is inherited by the forked plot process): the first run's
    time (benchmarks/bench_first_run.py)."""
    out = tmp_path / "r"
    env = dict(os.environ, PYTHONPATH=str(ROOT), CLOCKWORK_CACHE="off")
    r = subprocess.run([sys.executable, "-X", "importtime", "-m", "clockwork", "run", str(test_fmu("TestStair")),
                        "--out", str(out), "--no-progress", "--set", "experiment.stop=2"], env=env,
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    imported = {line.split("|")[-1].strip() for line in r.stderr.splitlines() if line.startswith("import time:")}
    assert "PIL.Image" in imported and "matplotlib" not in imported
    assert [line for line in r.stderr.splitlines() if not line.startswith("import time:")] == []
    image = Image.open(out / "outputs.png")
    assert image.size[0] == 1100
