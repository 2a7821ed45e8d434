"""``drake-est diagnose``: report files with the fixed report.json shape, a summary on stdout,
exit code 0; bad input exits 2 with one line on stderr.  The confusion-matrix benchmark is marked
``benchmark`` (run with ``pytest -m benchmark tests/test_diagnose_cli.py``)."""
from __future__ import annotations

import functools
import json
import re
from pathlib import Path

import numpy as np
import pytest

from drake_est.cli import main
from drake_est.data import Log, save_log
from drake_est.synth import synthesize


@functools.lru_cache(maxsize=None)
def _csv(tmpdir: str, effect: str = "position_dependent_friction", seed: int = 21) -> str:
    log, truth = synthesize(effect, seed=seed, duration=80.0)
    path = Path(tmpdir) / f"{effect}_{seed}.csv"
    save_log(Log(t=log.t, q=log.q, tau=log.tau, joints=log.joints), path)   # only t, q<j>, tau<j>
    return str(path)


@pytest.fixture(scope="module")
def log_csv(tmp_path_factory):
    return _csv(str(tmp_path_factory.mktemp("diag_cli")))


def test_cli_writes_report(log_csv, tmp_path, capsys):
    out = tmp_path / "diag"
    rc = main(["diagnose", log_csv, "--robot", "irb140", "--joints", "1", "--out", str(out), "--seed", "3"])
    assert rc == 0
    text = capsys.readouterr().out
    assert "nominal model: held-out RMSE" in text and "FOUND position_dependent_friction (joint 1" in text
    d = json.loads((out / "report.json").read_text())
    assert list(d)[:4] == ["data", "nominal", "findings", "final"]
    assert d["data"]["file"] == log_csv and d["data"]["joints"] == [1]
    assert d["data"]["samples"] > 7000 and d["data"]["duration_s"] > 70
    assert {"rmse", "mae", "fit", "fpe"} <= set(d["nominal"]["validation"])
    f = d["findings"][0]
    assert f["effect"] == "position_dependent_friction" and f["joint"] == 1
    assert f["evidence"]["p_value"] < 1e-4 and f["gain"]["rmse_ratio"] > 1.5
    assert {"rmse", "mae", "fit", "fpe"} <= set(f["validation"])
    assert d["final"]["effects"] == ["position_dependent_friction"]
    assert d["final"]["validation"]["rmse"] < d["nominal"]["validation"]["rmse"]
    md = (out / "report.md").read_text()
    assert "position_dependent_friction" in md and "residual_position.png" in md
    assert (out / "residual_position.png").exists() and (out / "simulation.png").exists()


def test_cli_generic_default_robot(log_csv, tmp_path, capsys):
    rc = main(["diagnose", log_csv, "--joints", "1", "--out", str(tmp_path / "g"), "--no-simulation"])
    assert rc == 0
    d = json.loads((tmp_path / "g" / "report.json").read_text())
    assert d["data"]["robot"] == "generic"
    assert "J" in d["nominal"]["parameters"]["1"]          # the axis inertia is identified
    assert d["findings"][0]["effect"] == "position_dependent_friction"


@pytest.mark.parametrize("args, needle", [
    (["diagnose", "/nonexistent/log.csv"], "file not found"),
    (["diagnose", "LOG", "--joints", "a,b"], "--joints"),
    (["diagnose", "LOG", "--joints", "9"], "joint 9"),
    (["diagnose", "LOG", "--robot", "kuka"], "--robot"),
])
def test_cli_bad_input_exits_2(args, needle, log_csv, capsys):
    args = [log_csv if a == "LOG" else a for a in args]
    rc = main(args)
    assert rc == 2
    err = capsys.readouterr().err.strip()
    assert needle in err and len(err.splitlines()) == 1


def test_cli_log_without_torque_exits_2(tmp_path, capsys):
    t = np.arange(0, 10, 0.01)
    p = tmp_path / "notau.csv"
    p.write_text("t,q1\n" + "\n".join(f"{a},{np.sin(a)}" for a in t))
    assert main(["diagnose", str(p)]) == 2
    assert "tau1" in capsys.readouterr().err


@pytest.mark.long
def test_run_demo(tmp_path):
    from drake_est.diagnose import run_demo
    rep = run_demo(tmp_path, duration=60.0)
    d = json.loads((tmp_path / "report.json").read_text())
    assert (tmp_path / "demo_log.csv").exists() and (tmp_path / "report.md").exists()
    assert d["findings"] and d["findings"][0]["effect"] == "motor_position_ripple"
    assert rep.findings[0]["joint"] == 1


@pytest.mark.benchmark
def test_confusion_matrix_benchmark(tmp_path):
    """>= 60 randomized logs (9 classes x 7 seeds): every top finding must name the hidden effect."""
    from conftest import bench_module
    mod = bench_module("bench_diagnose")
    rows = mod.confusion(7, Path("/tmp/drake_est_bench_diagnose"))
    mod.print_matrix(rows)
    assert len(rows) >= 60
    errors = [(r["class"], r["seed"], r["top"]) for r in rows if not r["ok"]]
    assert not errors, errors


# ---------------------------------------------------------------- issue 16, item 7: units


def _sine_csv(path, t, q, tau):
    path.write_text("t,q1,tau1\n" + "\n".join(f"{float(a)!r},{float(b)!r},{float(c)!r}" for a, b, c in zip(t, q, tau)))
    return str(path)


def test_millisecond_time_stamps_exit_2(tmp_path, capsys):
    t = np.arange(0, 20000, 10)                      # 100 Hz written in ms (integers)
    q = np.sin(2 * np.pi * t / 4000.0)
    p = _sine_csv(tmp_path / "ms.csv", t, q, 0.5 * np.sign(np.cos(2 * np.pi * t / 4000.0)))
    assert main(["diagnose", p]) == 2
    err = capsys.readouterr().err.strip()
    assert "milliseconds" in err and len(err.splitlines()) == 1
    assert main(["check", p]) == 2
    assert "milliseconds" in capsys.readouterr().err


def test_check_without_robot_spots_degrees(tmp_path, capsys):
    t = np.arange(0, 20, 0.01)
    q_deg = 90.0 * np.sin(2 * np.pi * t / 5.0)       # +-90 degrees written as numbers in degrees
    p = _sine_csv(tmp_path / "deg.csv", t, q_deg, np.cos(t))
    assert main(["check", p]) == 0
    err = capsys.readouterr().err
    assert "degrees" in err and "joint 1" in err
    q_rad = np.deg2rad(q_deg)
    p = _sine_csv(tmp_path / "rad.csv", t, q_rad, np.cos(t))
    assert main(["check", p]) == 0
    assert "degrees" not in capsys.readouterr().err


def test_torque_unit_follows_axis_type(tmp_path):
    from drake_est.diagnose import diagnose
    from drake_est.diagnose.testbench import generate
    log, _ = generate({}, seed=3, duration=60, sample_rate=50, prismatic=True)
    rep = diagnose(log, robot="generic", simulate=False)
    assert rep.to_dict()["data"]["torque_unit"] == "N"
    out = rep.write(tmp_path / "lin")
    md = (out / "report.md").read_text() if out.is_dir() else (tmp_path / "lin" / "report.md").read_text()
    assert "N m" not in md
    assert re.search(r"RMSE of \*\*[-0-9.e]+ N\*\*", md)
    log, _ = generate({}, seed=3, duration=60, sample_rate=50)
    assert diagnose(log, robot="generic", simulate=False).to_dict()["data"]["torque_unit"] == "N m"
