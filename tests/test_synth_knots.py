"""synthesize(knot_offset=...): the reference's knots moved off the samples, and the kept measurement of what that
does to synth's null logs (benchmarks/bench_synth_knots.py)."""
import json
from pathlib import Path

import numpy as np
import pytest

from conftest import bench_module
from drake_est.errors import DrakeEstError
from drake_est.synth import synthesize

ROOT = Path(__file__).resolve().parents[1]


def test_knot_offset_outside_the_knot_spacing_is_a_one_line_error():
    for bad in (-0.001, 0.02, 0.5):
        with pytest.raises(DrakeEstError, match="knot_offset"):
            synthesize("none", seed=1, duration=3.0, knot_offset=bad)


def test_knot_offset_moves_the_reference_later():
    """With the knots moved 5 ms later the joint follows the same motion 5 ms later: its logged position matches the
    default log's interpolated 5 ms earlier far better than at the same instants."""
    kw = dict(seed=3, duration=12.0, sample_rate=100.0, noise_std=0.0)
    a, _ = synthesize("none", **kw)
    b, _ = synthesize("none", knot_offset=0.005, **kw)
    assert np.array_equal(a.t, b.t)
    qa, qb, t = a.q[:, 0], b.q[:, 0], a.t
    inner = slice(10, -10)
    shifted = np.interp(t - 0.005, t, qa)
    assert np.max(np.abs(qb - shifted)[inner]) < 0.2 * np.max(np.abs(qb - qa)[inner])


def test_the_docs_table_is_the_kept_json():
    mod = bench_module("bench_synth_knots")
    out = json.loads((ROOT / "benchmarks" / "results" / "synth_knots_null.json").read_text())
    assert out["summary"] == mod.summary(out["rows"])
    doc = (ROOT / "docs" / "readme" / "diagnose_testbench.md").read_text()
    for line in mod.table_lines(out["summary"]):
        assert line in doc, line
    at100 = {k: v for k, v in out["summary"].items() if k.startswith("100 Hz")}
    assert at100["100 Hz, knots on the samples"]["with_an_unexplained_entry"] == 4
    assert at100["100 Hz, knots between the samples"]["with_an_unexplained_entry"] == 0
