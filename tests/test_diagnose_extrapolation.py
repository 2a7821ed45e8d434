"""Held-out rows beyond the training speeds (nominal.beyond_training_speeds): left out of the judgement and
counted, in a log split in time blocks; a log split by whole logs keeps them."""
import numpy as np
import pytest

from conftest import closed_loop_case
from drake_est.diagnose import diagnose, diagnose_logs
from drake_est.diagnose.nominal import EXTRAPOLATION_FACTOR, ONE_LEVEL_SPREAD, beyond_training_speeds
from drake_est.diagnose.report import markdown


def test_only_held_out_rows_far_beyond_one_training_speed_level():
    v = np.array([1.2, -1.0, 0.5, -1.4, 1.6, -1.6, 3.0, 0.1])
    train = np.array([True, True, False, False, False, True, False, False])
    far = beyond_training_speeds(v, train)
    # training speeds 1.0-1.6 rad/s (one level: 95th / 5th percentile < 2); 1.5 x 1.6 = 2.4
    assert far.tolist() == [False, False, False, False, False, False, True, False]
    assert not far[train].any()                      # a training row is never left out
    assert beyond_training_speeds(v, train, factor=0.5).tolist() == [False, False, False, True, True, False, True,
                                                                      False]
    assert not beyond_training_speeds(v, np.zeros(v.size, bool)).any()
    # training speeds spread wider (0.2-1.6 rad/s): the speed terms are identified, nothing is left out
    v[0] = 0.2
    assert not beyond_training_speeds(v, train).any()
    assert beyond_training_speeds(v, train, one_level=10.0)[6]
    assert EXTRAPOLATION_FACTOR == 1.5 and ONE_LEVEL_SPREAD == 2.0


def test_one_fast_held_out_row_no_longer_decides_spec_2122():
    """Closed-loop spec 2122 (10 Hz, an abrupt change and a ripple): every training row lies at 0.06-0.10 rad/s and
    one held-out row at 0.49 rad/s, where the nominal kv and the change's [dkv, dkc] step (fitted on one speed
    level) extrapolate; that row made the step raise the held-out RMSE and a position load take the level change
    (a wrong name).  Left out (and counted), the change is named (ambiguous with the load) and nothing wrong."""
    mod, spec, log, truth = closed_loop_case(2122)
    d = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
    assert d["data"]["excluded"]["1"]["beyond_training_speeds"] == 1
    assert "1 held-out samples faster than 1.5 times the fastest training sample" in markdown(d)
    j = mod.judge(spec, d, truth["not_visible"])
    assert not j["wrong"]
    named = {e for f in d["findings"] for e in f.get("ambiguous_between", [f["effect"]])}
    assert "abrupt_change" in named


def test_a_split_by_whole_logs_keeps_its_fast_held_out_rows():
    """Several logs: a held-out log at other speeds is the test the issue asks for (effects seen across logs), so
    nothing is left out there, while the same speeds in one log's time blocks are."""
    from drake_est.data import from_arrays

    logs = []
    for i, speed in enumerate((0.3, 1.5)):
        t = np.arange(0.0, 120.0, 0.01)
        q = 2.0 * np.sin(speed * t / 2.0)           # top speed: speed rad/s
        v = np.gradient(q, t)
        tau = 0.3 * v + 0.5 * np.sign(v) + np.random.default_rng(i).normal(0, 0.02, t.size)
        logs.append(from_arrays(t, q[:, None], tau[:, None], derivatives=True))
    d = diagnose_logs(logs, robot="generic", seed=0, simulate=False).to_dict()
    assert d["data"]["validation_samples"]["1"] > 0
    assert "beyond_training_speeds" not in d["data"]["excluded"]["1"]


def test_the_logs_a_count_touches_are_found_without_diagnosing(tmp_path):
    """bench_diagnose_testbench --kept-with-count: the kept logs whose preparation records a count (here the
    held-out rows left out), written as an --only file that --rerun-kept reads back."""
    import json

    mod, spec, log, truth = closed_loop_case(2122)
    rows = [{"family": "loop", "robot": "generic", "k": k, "sample_rate": 10.0, "truth": "x", "got": "x"}
            for k in (2121, 2122)]
    (tmp_path / "diagnose_testbench_loop_heldout2100.json").write_text(json.dumps({"rows": rows}))
    out = mod.kept_logs_with_count("beyond_training_speeds", results_dir=tmp_path)
    assert out["logs"] == 2 and out["touched"] == [["loop", 2122, {"1": 1}]] and not out["refused"]
    f = tmp_path / "only.txt"
    f.write_text("loop 2122  # the one\n\nloop 7\n")
    assert mod.read_only_file(f) == {("loop", 2122), ("loop", 7)}
    f.write_text("loop x\n")
    with pytest.raises(SystemExit, match="line 1: expected 'FAMILY K'"):
        mod.read_only_file(f)
