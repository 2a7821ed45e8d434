import json

import pytest

from drake_est.cli import main


@pytest.mark.long
def test_demo_default_out_dir(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["demo"]) == 0
    out = tmp_path / "drake_est_demo-1"
    text = capsys.readouterr().out
    assert str(out.resolve() / "report.md") in text
    pngs = list(out.glob("*.png"))
    assert pngs and all(p.stat().st_size > 10_000 for p in pngs)
    rep = json.loads((out / "report.json").read_text())
    # the bundled log hides position-dependent friction and motor ripple on joint 1: both must be named
    found = {(f["effect"], f["joint"]) for f in rep["findings"]}
    assert {("position_dependent_friction", 1), ("motor_position_ripple", 1)} <= found
    assert "all hidden effects named" in text
    # --out DIR writes into that folder
    assert main(["demo", "--out", str(tmp_path / "mine")]) == 0
    assert (tmp_path / "mine" / "report.md").exists()
