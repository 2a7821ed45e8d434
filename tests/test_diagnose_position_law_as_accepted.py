"""The seventy-fourth round: the check that sets a finding aside as "not significant given the other findings" tests
a position law with the kernel count it was accepted with, when the fresh re-detection of the law on the model without
it chose another count and is not significant (core._position_law_as_accepted behind
core.POSITION_LAW_AS_ACCEPTED_IN_ITS_CHECK)."""
import numpy as np
import pytest

from drake_est.diagnose import core, detectors as det, diagnose
from conftest import closed_loop_case, closed_loop_case_where, load_set_aside_as_not_significant


@pytest.fixture(scope="module")
def spec135():
    # loop spec 135: a position friction alone at 10 Hz, named by the search
    _, _, log, _ = closed_loop_case(135)
    r = core.run_diagnosis(log, robot="generic", seed=0)
    (e,) = r.final_model.exts
    m0 = core.Model(r.prep, [])
    return r, e, m0, m0.fit(r.sigma)


def _fresh(e, K, significant=False):
    """A stand-in for the check's fresh candidate of ``e``'s effect: ``K`` kernels, its test ``significant``."""
    f = det.Extension(e.effect, e.joint, e.cols, e.names, e.spec, {**e.evidence, "n_kernels": K})
    return [(f, {"significant": significant, "score": -1.0})]


def test_the_law_as_accepted_stands_in_only_for_another_kernel_count(spec135):
    r, e, m0, f0 = spec135
    assert e.effect == "position_dependent_friction"
    args = (r.prep, m0, f0, r.sigma, e, core.ALPHA, core.MIN_GAIN)
    other = _fresh(e, e.evidence["n_kernels"] * 2)
    got = core._position_law_as_accepted(*args, other)
    assert got is not other and got[0][0] is e and got[0][1]["significant"] and got[0][1]["as_accepted"]
    for own in (_fresh(e, e.evidence["n_kernels"]),                    # the same count: the same test
                _fresh(e, e.evidence["n_kernels"] * 2, significant=True),   # the fresh one passes
                []):                                                    # nothing fresh to stand in for
        assert core._position_law_as_accepted(*args, own) is own


def test_only_position_laws_are_tested_as_accepted(spec135):
    r, e, m0, f0 = spec135
    n = e.cols[e.joint].shape[0]
    tpd = det.Extension("time_periodic_disturbance", e.joint, {e.joint: np.ones((n, 2))}, ["a", "b"],
                        {"effect": "time_periodic_disturbance"}, {"n_kernels": 3})
    own = _fresh(e, 7)
    assert core._position_law_as_accepted(r.prep, m0, f0, r.sigma, tpd, core.ALPHA, core.MIN_GAIN, own) is own


def test_a_law_that_fails_the_round_is_not_kept(spec135):
    r, e, m0, f0 = spec135
    n = e.cols[e.joint].shape[0]
    noise = det.Extension(e.effect, e.joint, {e.joint: np.random.default_rng(74).standard_normal((n, 3))},
                          ["a", "b", "c"], {"effect": e.effect}, {"n_kernels": 3})
    own = _fresh(e, 5)
    assert core._position_law_as_accepted(r.prep, m0, f0, r.sigma, noise, core.ALPHA, core.MIN_GAIN, own) is own


@pytest.mark.long
def test_loop_case_11558_keeps_its_load(monkeypatch):
    # loop spec 11558 (a load beside Stribeck at 1000 Hz, quantized torque): the load as accepted (16 kernels) lowers the
    # held-out RMSE by 54 % given a drift and a level; the fresh load of the check (32 kernels) raised it by 54 %, the
    # load was set aside, and the report named a position friction (not planted).  Whether the search reaches that
    # check with the load depends on the CPU's last digits (on the seventy-fourth round's machine as generated; on the
    # eighty-eighth round's Intel Xeon the load is set aside for another reason as generated and at 1 ulp of the
    # position reference, and as not significant at 2 and 3 ulps), so the log is taken at the first of a few last
    # digits where the rule-off diagnosis sets the load aside as not significant
    monkeypatch.setattr(core, "POSITION_LAW_AS_ACCEPTED_IN_ITS_CHECK", False)
    found = closed_loop_case_where(11558, load_set_aside_as_not_significant)
    if found is None:
        pytest.fail("at none of the last digits tried does the rule-off diagnosis set the load aside as not significant")
    mod, spec, log, _, off = found
    assert mod.judge(spec, off)["wrong"] != []
    monkeypatch.setattr(core, "POSITION_LAW_AS_ACCEPTED_IN_ITS_CHECK", True)
    d = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
    assert mod.judge(spec, d)["wrong"] == [], d["findings"]
    assert "position_dependent_load" in {f["effect"] for f in d["findings"]}
    assert not load_set_aside_as_not_significant(d)


def test_the_rule_is_on_and_its_table_is_its_jsons():
    """The seventy-fourth round was kept: the switch is on, the docs' table holds each probe JSON's row as
    --against-off-rows prints it, every one of the 751 touchable kept rows was examined, no row gained a wrong name,
    11558 lost its, no outright-correct row turned ambiguous, each rule-off row is its log's kept row as it was, and
    every row where the rule fired is now the kept row of its log (folded)."""
    from conftest import bench_module, probe_results
    assert core.POSITION_LAW_AS_ACCEPTED_IN_ITS_CHECK is True
    probe = bench_module("probe_position_law_as_accepted")
    doc, files, differences = probe_results("diagnose_position_law_as_accepted_round74_*.json")
    # lanes a and b: the selection; c: the rows of fresh blocks added after it; d: the rows with a position law set
    # aside since then (the seventy-fifth round's fold of 21549, fresh blocks 28700-28899); e: fresh blocks 28900-29099;
    # f: fresh blocks 29100-29299; g: fresh blocks 29300-29499; h: fresh blocks 29500-29699; i: fresh blocks 29700-29899;
    # j: fresh blocks 29900-30099; k: fresh blocks 30100-30299; l-y: the fresh blocks after them, up to 33000-33199, then za: 33200-33399, zb: 33400-33599,
    # zc: 33600-33999, zd: 33429 (folded by the ninety-first round),
    # ze: 34000-34399, zf: 34400-34799, zg: 34800-34999, zh: 35000-35399, zi: 35400-35599, zj: 35600-35999, zk: 36000-36399, zl: 36400-36799, zm: 36800-37199, zn: 37200-37399, zo: 37400-37599, zp: 37600-37999, zq: 38000-38199, zr: 38200-38399, zs: 38400-38599, zt: 38600-38799, zu: 38800-38999, zv: 39000-39199, zw: 39200-39399, zx: 39400-39599, zy: 39600-39799, zz: 39800-39999, zza: 40000-40199, zzb: 40200-40399, zzc: 40400-40599, zzd: 40600-40799, zze: 40800-40999, zzf: 41000-41199, zzg: 41200-41399, zzh: 41400-41599, zzi: 41600-41799, zzj: 41800-41999, zzk: 42000-42199, zzl: 42200-42399, zzm: 42400-42599, zzn: 42600-42799, zzo: 42800-42999, zzp: 43000-43399, zzq: 43400-43999, zzr: 44000-44199, zzs: 44200-44399, zzt: 44400-44599, zzu: 44600-44799, zzv: 44800-44999, zzw: 45000-45199, zzx: 45200-45399, zzy: 45400-45599, zzz: 45600-45799, zzza: 45767 (folded by the hundred-and-eighth round), zzzb: 45800-45999, zzzc: 46000-46199, zzzd: 46200-46399, zzze: 46400-46599, zzzf: 46600-46799, zzzg: 46800-46999, zzzh: 47000-47199
    assert len(files) == 86
    assert probe.AGAINST_OFF_HEADER in doc
    lost, examined = [], set()
    for f, d in files:
        s = probe.against_off([str(f)])
        assert probe.against_off_row(f.name, s) in doc
        assert s["wrong_gained"] == s["null_findings_gained"] == s["oov_unexplained_lost"] == s["outright_lost"] == []
        assert s["off_differs_from_kept_row"] == []
        assert s["missed_on"] <= s["missed_off"]
        lost += s["wrong_lost"]
        examined |= set(d["keys_examined"])
        assert differences(d) == [], f.name
    assert lost == [11558]
    # the selection: every kept row with a position law set aside (11558's folded row no longer has one)
    # (rows the ninety-sixth, hundred-and-fourth and hundred-and-fifth rounds refolded may have entered the selection)
    from conftest import REFOLDED_ROUND_96, REFOLDED_ROUND_104, REFOLDED_ROUND_105
    assert examined >= set(probe.touchable_keys()) - REFOLDED_ROUND_96 - REFOLDED_ROUND_104 - REFOLDED_ROUND_105
    assert len(examined) == 751 and f"all {len(examined)} such kept rows" in " ".join(doc.split())
