"""Execute every tutorial notebook top to bottom (small sizes) so they never rot."""
import os
from pathlib import Path

import pytest

TUTORIALS = sorted((Path(__file__).resolve().parents[1] / "tutorials").glob("*.ipynb"))
#: the fleet and real-data notebooks and the slowest others, each over 12 s on a 2-core machine: `long` cases (CI runs them after the
#: default run, README Quickstart), which keeps the default run well under 15 minutes
LONG_TUTORIALS = {"10_diagnose", "20_friction_identification", "40_lpv_spectral", "50_sensor_calibration",
                  "65_neural_dynamics", "70_ilqr_mbrl", "80_real_cogging", "82_real_linescanner", "83_real_emps",
                  "84_real_kuka", "90_fleet"}


@pytest.mark.parametrize("path", [pytest.param(p, marks=pytest.mark.long) if p.stem in LONG_TUTORIALS else p
                                  for p in TUTORIALS], ids=[p.stem for p in TUTORIALS])
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
