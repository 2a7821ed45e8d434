"""The report says why each candidate of the last round was rejected (drake_est.diagnose.report.rejection_reason)."""
from drake_est.diagnose.report import REJECTION_REASONS, markdown, rejection_reason


def test_each_flag_gives_its_reason_and_the_thresholds_come_last():
    for key, text in REJECTION_REASONS:
        assert rejection_reason({key: True, "p_value": 1.0, "rmse_reduction": 0.0}, 1e-4, 0.02) == text
    assert rejection_reason({"p_value": 0.5, "rmse_reduction": 0.1}, 1e-4, 0.02) == "not significant (p >= 0.0001)"
    assert rejection_reason({"p_value": 1e-9, "rmse_reduction": 0.01}, 1e-4, 0.02) == "gain below 2 %"
    # significant and large enough: it lost its round to a better candidate, no reason of its own
    assert rejection_reason({"p_value": 1e-9, "rmse_reduction": 0.1}, 1e-4, 0.02) == ""


def test_the_markdown_report_lists_the_reasons(tmp_path):
    from drake_est.diagnose import diagnose
    from drake_est.diagnose.testbench import generate
    log, _ = generate({"stribeck": 1.0}, seed=2, duration=60.0, sample_rate=100.0, noise_std=0.05)
    d = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
    md = markdown(d)
    lines = md[md.index("## Candidates rejected in the last round"):].splitlines()[2:]
    rows = [x for x in lines if x.startswith("- ")]
    assert rows and len(rows) == min(6, len(d["not_found"]))
    for row, r in zip(rows, d["not_found"]):
        why = rejection_reason(r, d["settings"]["alpha"], d["settings"]["min_rmse_reduction"])
        assert row.endswith(f" -- {why}") if why else " -- " not in row
