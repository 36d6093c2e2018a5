"""The notebook of the docs (docs/notebooks/tour.ipynb) runs from top to
bottom: an FMU, a scene and a sweep through clockwork.simulate, `clockwork
run` and clockwork.load. The site build executes it too (mkdocs-jupyter);
this test executes it with nbclient where that and a Python kernel are
installed (the test extra), and fails in CI if they are not."""

from __future__ import annotations

import os

import pytest

from cwtest import ROOT

NOTEBOOK = ROOT / "docs" / "notebooks" / "tour.ipynb"


@pytest.mark.slow
def test_the_tour_notebook_runs(tmp_path):
    try:
        import nbclient
        import nbformat
        import ipykernel  # noqa: F401
    except ImportError as e:
        if os.environ.get("CI"):
            pytest.fail(f"the test extra is not installed ({e}): pip install -e .[test]")
        pytest.skip(f"nbclient, nbformat or ipykernel missing ({e})")
    nb = nbformat.read(NOTEBOOK, as_version=4)
    nbclient.NotebookClient(nb, timeout=300, kernel_name="python3",
                            resources={"metadata": {"path": str(tmp_path)}}).execute()
    shown = [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])]
    assert not [o for o in shown if o.output_type == "error"]
    html = [o["data"]["text/html"] for o in shown if "text/html" in o.get("data", {})]
    # clockwork.load's display: a summary table and the plots inline, for the FMU, the scene and the sweep
    assert sum("data:image/png;base64," in h and "clockwork" in h for h in html) >= 3, len(html)
    assert any("image/png" in o.get("data", {}) for o in shown)  # Result.plot's figure
