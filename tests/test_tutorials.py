"""Execute every tutorial notebook top to bottom (small sizes) so they never rot."""
import os
from pathlib import Path

import pytest

TUTORIALS = sorted((Path(__file__).resolve().parents[1] / "tutorials").glob("*.ipynb"))


@pytest.mark.parametrize("path", TUTORIALS, ids=[p.stem for p in TUTORIALS])
def test_tutorial_runs(path, tmp_path, monkeypatch, require_module):
    nbformat = require_module("nbformat")   # skipped locally, a failure under CI=true
    nbclient = require_module("nbclient")
    monkeypatch.setenv("DRAKE_EST_TUTORIAL_SMALL", "1")
    monkeypatch.setenv("DRAKE_EST_NO_PROGRESS", "1")
    monkeypatch.setenv("MPLBACKEND", "Agg")
    nb = nbformat.read(str(path), as_version=4)
    client = nbclient.NotebookClient(nb, timeout=600, kernel_name="python3",
                                     resources={"metadata": {"path": str(path.parent)}})
    client.execute()
    errors = [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", []) if o.output_type == "error"]
    assert not errors
