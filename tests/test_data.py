import subprocess
import sys

import numpy as np
import pytest

from drake_est.cli import main
from drake_est.data import DataError, from_arrays, load_log, save_log, smooth_derivatives
from drake_est.robots import irb140_metadata


def write(tmp_path, text, name="log.csv"):
    p = tmp_path / name
    p.write_text(text)
    return p


def good_csv(n=50):
    t = np.arange(n) * 0.01
    lines = ["t,q1,tau1,temp"] + [f"{ti},{0.1 * np.sin(ti)},{np.cos(ti)},20" for ti in t]
    return "\n".join(lines) + "\n"


def test_roundtrip_csv_and_npz(tmp_path):
    t = np.linspace(0, 1, 101)
    log = from_arrays(t, np.c_[np.sin(t), t], tau=np.c_[np.cos(t), t], joints=[1, 3], channels={"fx": t * 2})
    for name in ("a.csv", "a.npz"):
        back = load_log(save_log(log, tmp_path / name))
        np.testing.assert_allclose(back.q, log.q, rtol=1e-8, atol=1e-12)
        np.testing.assert_allclose(back.tau, log.tau, rtol=1e-8, atol=1e-12)
        assert back.joints == [1, 3]
        np.testing.assert_allclose(back.column("fx"), t * 2, rtol=1e-8)
        assert back.dq is not None and back.ddq is not None


def test_derivatives_of_a_known_signal():
    t = np.arange(0, 10, 0.01)
    q = np.sin(1.3 * t)[:, None]
    dq, ddq, info = smooth_derivatives(t, q)
    inner = slice(20, -20)
    np.testing.assert_allclose(dq[inner, 0], 1.3 * np.cos(1.3 * t[inner]), atol=1e-3)
    np.testing.assert_allclose(ddq[inner, 0], -1.69 * np.sin(1.3 * t[inner]), atol=1e-2)
    assert info["method"] == "savitzky-golay"
    # non-uniform sampling is resampled, not rejected
    rng = np.random.default_rng(0)
    tn = np.sort(rng.uniform(0, 10, 2000))
    dqn, _, infon = smooth_derivatives(tn, np.sin(1.3 * tn)[:, None])
    assert infon["resampled"]
    np.testing.assert_allclose(dqn[50:-50, 0], 1.3 * np.cos(1.3 * tn[50:-50]), atol=2e-2)


BAD = {
    "missing_t": ("q1,tau1\n0,1\n" * 1, "missing time column 't'"),
    "missing_tau": ("t,q1,q2,tau1\n" + "".join(f"{i},0,0,0\n" for i in range(30)), "missing torque column(s) tau2"),
    "nan": ("t,q1,tau1\n" + "".join(f"{i},{'nan' if i in (5, 9) else 0},0\n" for i in range(30)),
            "NaN/inf values in 1 column(s): 'q1': 2 (first at data row 6)"),
    "duplicate_time": ("t,q1,tau1\n" + "".join(f"{min(i, 10)},0,0\n" for i in range(30)), "duplicated time stamp"),
    "decreasing_time": ("t,q1,tau1\n" + "".join(f"{30 - i if i == 12 else i},0,0\n" for i in range(30)),
                        "time stamps not increasing"),
    "too_few": ("t,q1,tau1\n" + "".join(f"{i},0,0\n" for i in range(5)), "too few samples (5)"),
    "non_numeric": ("t,q1,tau1\n" + "".join(f"{i},{'abc' if i == 3 else 0},0\n" for i in range(30)),
                    "column 'q1' has a non-numeric value 'abc'"),
    "empty": ("", "file is empty"),
    "ragged": ("t,q1,tau1\n0,1\n", "line 2 has 2 fields, header has 3"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_input_clear_error(tmp_path, case):
    text, msg = BAD[case]
    with pytest.raises(DataError) as err:
        load_log(write(tmp_path, text))
    assert msg in str(err.value)
    assert "\n" not in str(err.value)


def test_missing_file(tmp_path):
    with pytest.raises(DataError, match="file not found"):
        load_log(tmp_path / "nope.csv")


def test_degrees_instead_of_radians(tmp_path):
    t = np.arange(100) * 0.01
    text = "t,q1,tau1\n" + "".join(f"{ti},{170 * np.sin(ti * 3)},0\n" for ti in t)
    with pytest.raises(DataError, match=r"joint 1 .* far outside .*looks like degrees"):
        load_log(write(tmp_path, text), limits=irb140_metadata().limits_dict())


def test_nan_drop_is_counted(tmp_path):
    text = "t,q1,tau1\n" + "".join(f"{i * 0.01},{'nan' if i in (5, 9) else 0},0\n" for i in range(40))
    log = load_log(write(tmp_path, text), nan_policy="drop")
    assert log.n_samples == 38
    assert log.meta["excluded_rows"]["nonfinite_rows"] == 2


def test_channels_kept(tmp_path):
    log = load_log(write(tmp_path, good_csv()))
    assert "temp" in log.channels and log.joints == [1]


@pytest.mark.parametrize("case", sorted(BAD))
def test_cli_bad_input_exit_code_2(tmp_path, case, capsys):
    rc = main(["check", str(write(tmp_path, BAD[case][0]))])
    err = capsys.readouterr().err.strip()
    assert rc == 2
    assert len(err.splitlines()) == 1 and BAD[case][1] in err


def test_cli_check_subprocess_no_traceback(tmp_path):
    p = write(tmp_path, BAD["nan"][0])
    r = subprocess.run([sys.executable, "-m", "drake_est", "check", str(p)], capture_output=True, text=True)
    assert r.returncode == 2
    assert "Traceback" not in r.stderr and "NaN/inf" in r.stderr
    r = subprocess.run([sys.executable, "-m", "drake_est", "check", str(tmp_path / "missing.csv")],
                       capture_output=True, text=True)
    assert r.returncode == 2 and "file not found" in r.stderr
