"""The test suite's own rules: under CI=true a missing optional test extra or real data set fails instead of
skipping (tests/conftest.py); benchmarks live in benchmarks/, not in tests/."""
import ast
from pathlib import Path

import pytest

import conftest

TESTS = Path(__file__).resolve().parent


@pytest.mark.parametrize("ci, outcome", [(False, pytest.skip.Exception), (True, pytest.fail.Exception)])
def test_missing_extra_or_data_skips_locally_and_fails_in_ci(monkeypatch, ci, outcome):
    monkeypatch.setattr(conftest, "CI", ci)
    with pytest.raises(outcome, match="no_such_module_xyz"):
        conftest._require_module("no_such_module_xyz")
    with pytest.raises(outcome, match="missing.mat"):
        conftest.unavailable("real data nope/missing.mat not found")
    assert conftest._require_module("json").dumps([1]) == "[1]"     # present modules come back


TEST_EXTRAS = ("pytest", "nbclient", "nbformat", "ipykernel", "hypothesis")   # pyproject [test]


def test_no_silent_skips_for_test_extras_or_data():
    """importorskip of a test extra / skipif on data would vanish in CI: tests use require_module /
    requires_data instead (importorskip of a *bench* peer such as filterpy stays a legitimate skip)."""
    bad = []
    for p in sorted(TESTS.glob("test_*.py")):
        tree = ast.parse(p.read_text())
        for node in ast.walk(tree):
            if not isinstance(node, ast.Call):
                continue
            name = ast.unparse(node.func)
            if name.endswith("importorskip") and node.args and isinstance(node.args[0], ast.Constant) \
                    and str(node.args[0].value).split(".")[0] in TEST_EXTRAS:
                bad.append(f"{p.name}:{node.lineno}: importorskip of a test extra (use the require_module fixture)")
            if name.endswith("mark.skipif"):
                text = ast.unparse(node)
                if "data" in text.lower() and "exists" in text:
                    bad.append(f"{p.name}:{node.lineno}: skipif on data (use @pytest.mark.requires_data)")
    assert not bad, "; ".join(bad)
