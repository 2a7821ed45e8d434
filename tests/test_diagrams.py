"""The scripts in diagrams/ build and run their Diagrams (short durations)."""
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("script", sorted((ROOT / "diagrams").glob("*.py")), ids=lambda p: p.stem)
def test_diagram_script_runs(script, tmp_path):
    r = subprocess.run([sys.executable, str(script), "--duration", "3", "--out", str(tmp_path / "out.png")],
                       capture_output=True, text=True, timeout=300, cwd=tmp_path)
    assert r.returncode == 0, r.stderr[-2000:]
    assert (tmp_path / "out.png").stat().st_size > 5000
