"""The eighty-sixth round: a motor-position ripple found after its joint's first position law is held against that law
at a finer resolution, as a later position law is (``core.FINER_BASIS_RIPPLE_RULE``;
``benchmarks/results/diagnose_finer_basis_ripple_round86_rule.txt``)."""
import pytest

from drake_est.diagnose import core, diagnose
from drake_est.diagnose.testbench import generate


@pytest.fixture(scope="module")
def design_case():
    from conftest import closed_loop_case
    return closed_loop_case(31089)


def test_spec_31089_names_the_friction_alone_with_the_rule_on(monkeypatch, design_case):
    """The design log: off, the 8-kernel friction and a 2.07 cycles/rad ripple with a speed-dependent amplitude; on,
    the ripple is set aside for the friction at 16 kernels, which predicts the held-out data at least as well."""
    mod, spec, log, truth = design_case
    monkeypatch.setattr(core, "FINER_BASIS_RIPPLE_RULE", False)
    off = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
    assert sorted(f["effect"] for f in off["findings"]) == ["motor_position_ripple", "position_dependent_friction"]
    assert mod.judge(spec, off)["wrong"]
    monkeypatch.setattr(core, "FINER_BASIS_RIPPLE_RULE", True)
    on = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
    assert [f["effect"] for f in on["findings"]] == truth["planted"] == ["position_dependent_friction"]
    j = mod.judge(spec, on)
    assert j["correct"] and not j["wrong"] and not j["missed"]
    fine = [x for x in on["set_aside"] if x.get("within_finer_basis")]
    assert [x["effect"] for x in fine] == ["motor_position_ripple"]
    x = fine[0]
    assert x["earlier_law"] == "position_dependent_friction" and x["kernels_finer"] > x["kernels_before"]
    assert x["gain_over_finer"] < 0.0 < x["heldout_rmse_finer_alone"] < x["heldout_rmse_with_both"]


def test_only_findings_after_the_first_position_law_and_ripples_only_with_the_rule(monkeypatch):
    """:func:`core._later_than_first_position_law`: the later position laws always, the later ripples with the rule
    on; a ripple before the first position law is never held against it."""
    class E:
        shared = False

        def __init__(self, effect):
            self.effect, self.cols = effect, {1: None}

    class M:
        def __init__(self, exts):
            self.exts = exts

        def own(self, j):
            return [e for e in self.exts if j in e.cols]

    r0, f, r1, load = E("motor_position_ripple"), E("position_dependent_friction"), E("motor_position_ripple"), \
        E("position_dependent_load")
    m = M([r0, f, r1, load])
    monkeypatch.setattr(core, "FINER_BASIS_RIPPLE_RULE", False)
    assert core._later_than_first_position_law(m, 1) == (f, [load])
    monkeypatch.setattr(core, "FINER_BASIS_RIPPLE_RULE", True)
    assert core._later_than_first_position_law(m, 1) == (f, [r1, load])
    assert core._later_than_first_position_law(M([r0]), 1) == (None, [])


@pytest.mark.parametrize("seed", [0, 1])
def test_a_planted_ripple_beside_a_position_friction_is_still_named(seed):
    """A gear ripple of many cycles per radian and a friction that changes with position, both planted (open-loop
    testbench): the friction at a finer resolution does not explain the ripple."""
    log, truth = generate({"position_dependent_friction": 1.0, "motor_position_ripple": 1.0}, seed=seed,
                          duration=120.0, sample_rate=100.0, noise_std=0.05)
    rep = diagnose(log, robot="generic", seed=0, simulate=False)
    d = rep.to_dict()
    assert sorted(f["effect"] for f in d["findings"]) == ["motor_position_ripple", "position_dependent_friction"]
    assert not [x for x in d["set_aside"] if x.get("within_finer_basis")]


def test_kept_and_its_table_is_its_jsons():
    """Kept: the switch is on; the docs' table holds each probe JSON's row as --against-off-rows prints it; lane a is
    the 82 closed-loop logs whose kept rows named a ripple and a position law, lane b the 3 open-loop ones; the rule
    fired in the design log only, which lost its wrong name (its rule-on row is now its kept row), and nothing was
    lost."""
    from conftest import assert_rule_mended_only, bench_module, probe_lanes
    assert core.FINER_BASIS_RIPPLE_RULE is True
    probe = bench_module("probe_finer_basis_ripple")
    doc, files, examined, s = probe_lanes(probe, "diagnose_finer_basis_ripple_round86_lane_*.json", lanes="ab")
    assert len(examined["loop"]) == 82 and len(examined["testbench"]) == 3 and 31089 in examined["loop"]
    assert_rule_mended_only("diagnose_finer_basis_ripple_round86_lane_*.json", files, s, 31089)
