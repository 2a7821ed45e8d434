"""`drake-est reproduce` options: --workers reaches the experiments that run seeds in parallel, and only them."""
import subprocess
import sys


def _run(*args):
    return subprocess.run([sys.executable, "-m", "drake_est", "reproduce", *args], capture_output=True, text=True,
                          timeout=120)


def test_workers_refused_where_an_experiment_runs_in_one_process(tmp_path):
    r = _run("friction-energy", "--workers", "2", "--out", str(tmp_path / "x"))
    assert r.returncode == 2
    assert "--workers" in r.stderr and "friction-energy" in r.stderr
    assert "Traceback" not in r.stderr and len(r.stderr.strip().splitlines()) == 1


def test_workers_must_be_a_positive_integer(tmp_path):
    r = _run("mbrl-cartpole", "--workers", "0", "--out", str(tmp_path / "x"))
    assert r.returncode == 2 and "--workers" in r.stderr and "Traceback" not in r.stderr


def test_workers_is_passed_as_the_experiments_own_parameter(monkeypatch, tmp_path):
    import argparse

    from drake_est.cli import reproduce as cli
    from drake_est import reproduce as rep

    seen = {}

    def fake(out_dir, quick=False, seed=0, jobs=None):
        """fake experiment"""
        seen["jobs"] = jobs
        return {"x": 1.0}

    monkeypatch.setattr(rep, "experiments", lambda: {"fake": fake})
    args = argparse.Namespace(name="fake", out=str(tmp_path / "o"), quick=True, seed=0, data=None, workers=3)
    assert cli.run(args) == 0
    assert seen["jobs"] == 3
