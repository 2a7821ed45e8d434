"""Issue 19: bad input gives the project's one-line error (exit 2), never a traceback, never NaN out.

``test_bad_input_table`` runs every row of docs/readme/hardening.md (the README's bad-input list)."""
import errno
import json
import os
import re
import zipfile
from pathlib import Path

import numpy as np
import pytest

from drake_est.cli import main
from drake_est.errors import DataError, DrakeEstError

DOC = Path(__file__).resolve().parents[1] / "docs" / "readme" / "hardening.md"


def _log_cols(n=400, dt=0.01):
    t = np.arange(n) * dt
    q = 0.5 * np.sin(2 * np.pi * 0.5 * t)
    tau = 2.0 * np.cos(2 * np.pi * 0.5 * t) + 0.1
    return {"t": t, "q1": q, "tau1": tau}


def _csv(path, cols, first_line=None):
    names = list(cols)
    data = np.column_stack([cols[k] for k in names])
    lines = [",".join(names)] + [",".join(repr(float(v)) for v in row) for row in data]
    if first_line:
        lines.insert(0, first_line)
    path.write_text("\n".join(lines) + "\n")
    return path


def _with(cols, **kw):
    c = dict(cols)
    c.update(kw)
    return c


def _ft_npz(tmp, wrench_1d=False, scale_R=1.0):
    from drake_est.calibration import random_ft_poses, random_rotation, simulate_ft

    rng = np.random.default_rng(0)
    P = random_ft_poses(rng, 20)
    W = simulate_ft(P, random_rotation(rng), 1.0, [0, 0, 0.05], rng=rng)
    P = P.copy()
    P[:, :3, :3] *= scale_R
    np.savez(tmp / "ft.npz", poses=P, wrench=W[:, 0] if wrench_1d else W)
    return tmp / "ft.npz"


def _laser_npz(tmp, **extra):
    from drake_est.calibration import random_laser_problem

    pr = random_laser_problem(np.random.default_rng(1), n_rays=8, poses_per_plane=4)
    arrs = dict(poses=pr.poses, points=pr.points, pose_index=pr.pose_index, plane=pr.labels)
    arrs.update(extra)
    np.savez(tmp / "laser.npz", **arrs)
    return tmp / "laser.npz"


def _api_case(case):
    """A callable for an API row of the table (class 10): it must raise the project's error."""
    from drake_est.bfe import BasisFunctionExpansion
    from drake_est.calibration import calibrate_ft
    from drake_est.estimation.kalman import KalmanFilter
    from drake_est.identification import ltv
    from drake_est.regression import ridge_fit

    A, C, Q, R, x0, P0 = np.eye(2), np.eye(1, 2), np.eye(2), np.eye(1), np.zeros(2), np.eye(2)
    rng = np.random.default_rng(0)
    X, y = rng.standard_normal((30, 3)), rng.standard_normal(30)
    return {
        "api_kalman_not_pd": lambda: KalmanFilter(A, C, -Q, R, x0, P0),
        "api_kalman_nan_A": lambda: KalmanFilter(A * np.nan, C, Q, R, x0, P0),
        "api_kalman_shape": lambda: KalmanFilter(np.eye(3), C, Q, R, x0, P0),
        "api_kalman_short_tv_A": lambda: KalmanFilter(np.stack([A] * 10), C, Q, R, x0, P0).smooth(
            None, np.zeros((50, 1))),
        "api_tv_lambda_T2": lambda: ltv.tv_select_lambda_ml(rng.standard_normal((2, 2)), rng.standard_normal(2)),
        "api_ltv_lambda_T2": lambda: ltv.ltv_select_lambda_ml(rng.standard_normal((3, 2)),
                                                              rng.standard_normal((2, 1))),
        "api_ft_0_poses": lambda: calibrate_ft(np.zeros((0, 4, 4)), np.zeros((0, 6))),
        "api_bfe_all_equal": lambda: BasisFunctionExpansion.from_data(np.full(100, 0.3), 10),
        "api_ridge_negative_lam": lambda: ridge_fit(X, y, lam=-1.0),
        "api_ridge_nan_lam": lambda: ridge_fit(X, y, lam=float("nan")),
    }[case]


def _build(case, tmp):
    """argv (or a callable raising) for one row of the table."""
    c = _log_cols()
    f = tmp / "log.csv"
    if case == "t_1e300":
        t = c["t"].copy(); t[-1] = 1e300
        return ["check", str(_csv(f, _with(c, t=t)))]
    if case == "t_1e8":
        t = c["t"].copy(); t[-1] = 1e8
        return ["check", str(_csv(f, _with(c, t=t)))]
    if case == "t_gap":
        t = c["t"].copy(); t[200:] += 100.0
        return ["check", str(_csv(f, _with(c, t=t)))]
    if case == "t_ms":
        return ["check", str(_csv(f, _with(c, t=np.arange(400.0))))]
    if case == "t_ns":
        return ["check", str(_csv(f, _with(c, t=np.arange(400.0) * 1e6)))]
    if case == "t_tiny":
        return ["check", str(_csv(f, _with(c, t=np.arange(400) * 1e-12)))]
    if case == "tau_1e300":
        tau = c["tau1"].copy(); tau[7] = 1e300
        return ["check", str(_csv(f, _with(c, tau1=tau)))]
    if case == "col_1e-300":
        return ["check", str(_csv(f, _with(c, tau1=c["tau1"] * 1e-300)))]
    if case == "alias_q01":
        return ["check", str(_csv(f, _with(c, q01=c["q1"] + 1.0)))]
    if case == "joint0":
        return ["check", str(_csv(f, {"t": c["t"], "q0": c["q1"], "tau0": c["tau1"]}))]
    if case == "field_200k":
        f.write_text("t,q1,tau1\n0,0,0\n" + "1" * 200_000 + ",0,0\n")
        return ["check", str(f)]
    if case == "fifo":
        p = tmp / "pipe.csv"
        os.mkfifo(p)
        return ["check", str(p)]
    if case.startswith("npz_"):
        p = tmp / "log.npz"
        meta = {"npz_meta_bad": "{not json", "npz_meta_list": "[1, 2]"}.get(case, "{}")
        np.savez_compressed(p, meta_json=np.array(meta), **c)
        if case == "npz_truncated":
            b = p.read_bytes()
            p.write_bytes(b[:len(b) // 2])
        if case == "npz_corrupt":
            with zipfile.ZipFile(p) as z:
                info = z.getinfo("tau1.npy")
            b = bytearray(p.read_bytes())
            start = info.header_offset + 30 + len(info.filename) + len(info.extra) + 20
            for k in range(start, start + 40):
                b[k] ^= 0x5A
            p.write_bytes(bytes(b))
        return ["check", str(p)]
    if case == "window_nan":
        from drake_est.data import load_log

        return lambda: load_log(_csv(f, c), window_s=float("nan"))
    if case.startswith("api_"):
        return _api_case(case)
    out = ["--out", str(tmp / "out")]
    if case.startswith("deg_"):
        deg = str(_csv(f, _with(c, q1=np.degrees(c["q1"]) * 4)))      # +-115 "rad"
        urdf = str(Path(__file__).resolve().parents[1] / "models" / "irb140.urdf")
        return {"deg_check_urdf": ["check", deg, "--robot", urdf],
                "deg_diagnose_urdf": ["diagnose", deg, "--robot", urdf] + out,
                "deg_spectrum_irb140": ["spectrum", deg, "--signal", "tau1", "--position", "q1", "--robot",
                                        "irb140"] + out}[case]
    if case.startswith("urdf_"):
        import xml.etree.ElementTree as ET

        root = ET.parse(Path(__file__).resolve().parents[1] / "models" / "irb140.urdf").getroot()
        link1 = [el for el in root.iter("link") if el.get("name") == "link_1"][0]
        joint2 = [el for el in root.iter("joint") if el.get("name") == "joint_2"][0]
        if case == "urdf_nan_inertia":
            link1.find("inertial/inertia").set("ixx", "nan")
        elif case == "urdf_negative_mass":
            link1.find("inertial/mass").set("value", "-3")
        elif case == "urdf_limits_swapped":
            joint2.find("limit").set("lower", "2.5")
        elif case == "urdf_missing_joint":
            root.remove(joint2)
        elif case == "urdf_zero_cylinder":
            link1.find("visual/geometry/cylinder").set("length", "0")
        text = ET.tostring(root, encoding="unicode")
        if case == "urdf_truncated":
            text = text[:len(text) // 2]
        u = tmp / "robot.urdf"
        u.write_text(text)
        return ["check", str(_csv(f, c)), "--robot", str(u)]
    if case == "ft_wrench_1d":
        return ["calibrate", "ft", str(_ft_npz(tmp, wrench_1d=True))] + out
    if case == "ft_not_rigid":
        return ["calibrate", "ft", str(_ft_npz(tmp, scale_R=1.1))] + out
    if case == "laser_T0_3x3":
        return ["calibrate", "laser", str(_laser_npz(tmp, T0=np.eye(3)))] + out
    if case == "laser_T0_nan":
        return ["calibrate", "laser", str(_laser_npz(tmp)), "--T0", "nan 0 0 0 0 0"] + out
    if case == "laser_labels_str":
        return ["calibrate", "laser", str(_laser_npz(tmp, plane=np.array(["wall"] * 10)))] + out
    synth = ["synth", "--out", str(tmp / "s.csv")]
    if case == "synth_duration_nan":
        return synth + ["--duration", "nan"]
    if case == "synth_rate":
        return synth + ["--rate", "0.01"]
    if case == "synth_seed":
        return synth + ["--seed", "-1"]
    if case == "synth_noise_inf":
        return synth + ["--noise", "inf"]
    if case == "spectrum_gear_inf":
        return ["spectrum", str(_csv(f, c)), "--signal", "tau1", "--position", "q1", "--gear-ratio", "inf"] + out
    if case == "tau_constant_diagnose":
        return ["diagnose", str(_csv(f, _with(c, tau1=0.0 * c["tau1"]))), "--no-simulation"] + out
    if case == "tau_constant_friction":
        return ["fit-friction", str(_csv(f, _with(c, tau1=0.0 * c["tau1"]))), "--no-plots"] + out
    if case == "friction_holdout":
        return ["fit-friction", str(_csv(f, c)), "--holdout", "0.001"] + out
    raise KeyError(case)


def _table():
    rows = []
    for line in DOC.read_text().splitlines():
        if not line.startswith("|"):
            continue
        cells = [x.strip() for x in line.strip().strip("|").split("|")]
        if len(cells) == 4 and cells[0] not in ("case", "---") and not set(cells[0]) <= {"-"}:
            frag = re.findall(r"`([^`]*)`", cells[3])
            rows.append((cells[0], frag[0]))
    return rows


def test_table_is_complete():
    rows = _table()
    assert len(rows) >= 25 and len({r[0] for r in rows}) == len(rows)


@pytest.mark.parametrize("case,fragment", _table())
def test_bad_input_table(case, fragment, tmp_path, capsys):
    argv = _build(case, tmp_path)
    if callable(argv):
        with pytest.raises(DrakeEstError) as e:
            argv()
        msg = str(e.value)
    else:
        assert main(argv) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1, err
        msg = err
    assert fragment in msg, msg
    assert "Traceback" not in msg


def test_comment_line_and_aliases_are_not_silent(tmp_path, capsys):
    f = _csv(tmp_path / "c.csv", _log_cols(), first_line="# exported by the robot controller")
    assert main(["check", str(f)]) == 0
    assert "400 samples" in capsys.readouterr().out


def test_unwritable_output_names_the_path(tmp_path, capsys, monkeypatch):
    """Class 1: any OSError on output (disk full here) is one line naming the path, exit 2."""
    real = Path.write_text

    def full(self, *a, **k):
        if self.suffix == ".json":
            raise OSError(errno.ENOSPC, "No space left on device", str(self))
        return real(self, *a, **k)

    monkeypatch.setattr(Path, "write_text", full)
    ft = _ft_npz(tmp_path)
    assert main(["calibrate", "ft", str(ft), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "calibrate_ft.json" in err and "No space left" in err
    # and an OSError from anywhere else in a command (e.g. a plot) is caught by the CLI too
    from drake_est.jsonutil import dump_json

    if Path("/dev/full").exists():
        monkeypatch.setattr(Path, "write_text", real)
        with pytest.raises(DataError, match="cannot write /dev/full"):
            dump_json({"a": 1}, "/dev/full")


def test_json_writer_refuses_nonfinite(tmp_path):
    from drake_est.jsonutil import dump_json, finite_or_none

    with pytest.raises(DataError, match=r"'fit\.kv'"):
        dump_json({"fit": {"kv": float("nan")}}, tmp_path / "x.json")
    with pytest.raises(DataError, match=r"'a\[2\]'"):
        dump_json({"a": np.array([1.0, 2.0, np.inf])}, tmp_path / "x.json")
    assert not (tmp_path / "x.json").exists()
    dump_json({"a_max": finite_or_none(np.inf), "v": np.float64(1.5), "n": np.int64(3)}, tmp_path / "y.json")
    assert json.loads((tmp_path / "y.json").read_text()) == {"a_max": None, "v": 1.5, "n": 3}


def test_ft_force_only_writes_no_nan(tmp_path, capsys):
    """Class 7: force-only F/T data: the centre of mass is not determined -> null in the JSON."""
    from drake_est.calibration import random_ft_poses, random_rotation, simulate_ft

    rng = np.random.default_rng(2)
    P = random_ft_poses(rng, 30)
    W = simulate_ft(P, random_rotation(rng), 1.0, [0, 0, 0.05], rng=rng)
    np.savez(tmp_path / "f.npz", poses=P, wrench=W[:, :3])
    assert main(["calibrate", "ft", str(tmp_path / "f.npz"), "--out", str(tmp_path / "o")]) == 0
    text = (tmp_path / "o" / "calibrate_ft.json").read_text()
    assert "NaN" not in text and "Infinity" not in text
    assert json.loads(text)["com_sensor_m"] is None


def test_calibration_api_validation():
    from drake_est.calibration import calibrate_ft, calibrate_laser, random_laser_problem

    with pytest.raises(DataError, match="poses is empty"):
        calibrate_ft(np.zeros((0, 4, 4)), np.zeros((0, 6)))
    pr = random_laser_problem(np.random.default_rng(1), n_rays=8, poses_per_plane=4)
    with pytest.raises(DataError, match="T0"):
        calibrate_laser(pr.poses, pr.points, pr.pose_index, labels=pr.labels, T0=np.full((4, 4), np.nan))
    bad = pr.poses.copy()
    bad[3, :3, :3] *= 2.0
    with pytest.raises(DataError, match="pose 3 is not a rigid transform"):
        calibrate_laser(bad, pr.points, pr.pose_index, labels=pr.labels)


def test_time_gap_bounded_memory_in_derivatives():
    """Class 2: the uniform resampling grid of smooth_derivatives is bounded; a gap is refused with its row."""
    from drake_est.data import smooth_derivatives

    t = np.r_[np.arange(100) * 0.01, 1e5 + np.arange(100) * 0.0103]
    with pytest.raises(DataError, match="gap of .* after data row 100"):
        smooth_derivatives(t, np.sin(t))
    with pytest.raises(DataError, match="window_s"):
        smooth_derivatives(np.arange(50) * 0.01, np.zeros(50), window_s=-1.0)


def test_api_validation_names_the_argument():
    """Class 10: public functions raise the project's error naming the argument."""
    from drake_est.errors import IdentifiabilityError
    from drake_est.estimation.kalman import KalmanFilter
    from drake_est.identification import ltv

    A, C, Q, R, x0, P0 = np.eye(2), np.eye(1, 2), np.eye(2), np.eye(1), np.zeros(2), np.eye(2)
    with pytest.raises(DataError, match="R1 is not positive"):
        KalmanFilter(A, C, -Q, R, x0, P0)
    with pytest.raises(DataError, match="A contains NaN"):
        KalmanFilter(A * np.nan, C, Q, R, x0, P0)
    with pytest.raises(DataError, match="time-varying A has 10 steps"):
        KalmanFilter(np.stack([A] * 10), C, Q, R, x0, P0).smooth(None, np.zeros((50, 1)))
    rng = np.random.default_rng(0)
    with pytest.raises(IdentifiabilityError, match="too few samples"):
        ltv.tv_select_lambda_ml(rng.standard_normal((2, 2)), rng.standard_normal(2))
    with pytest.raises(DataError, match="lams"):
        ltv.tv_select_lambda_ml(rng.standard_normal((50, 2)), rng.standard_normal(50), lams=[1.0, np.nan])


# -- class 6: positions in degrees, with every robot option of every command that reads a log ---------------

def _deg_log(tmp, two_joints=False):
    t = np.arange(1000) * 0.01
    q = np.degrees(1.2 * np.sin(2 * np.pi * 0.3 * t))          # +-69 "rad": degrees
    tau = 2.0 * np.cos(2 * np.pi * 0.3 * t) + 0.3 * np.sign(np.cos(2 * np.pi * 0.3 * t))
    cols = {"t": t, "q1": q, "tau1": tau}
    if two_joints:   # the cart-pole: q1 the cart [m] (limits +-1000 m), q2 the continuous hinge
        cols = {"t": t, "q1": 0.1 * np.sin(t), "q2": q, "tau1": 0.1 * tau, "tau2": tau}
    return str(_csv(tmp / "deg.csv", cols))


MODELS = Path(__file__).resolve().parents[1] / "models"
DEG_REFUSED = [(cmd, robot) for robot in ("irb140", str(MODELS / "irb140.urdf"))
               for cmd in ("check", "diagnose", "spectrum")] + [("fit-friction", "irb140")]


def _deg_argv(cmd, robot, log, tmp):
    out = ["--out", str(tmp / "o")]
    if cmd == "check":
        return ["check", log, "--robot", robot]
    if cmd == "diagnose":
        return ["diagnose", log, "--robot", robot, "--no-simulation"] + out
    if cmd == "spectrum":
        return ["spectrum", log, "--signal", "tau1", "--position", "q1", "--robot", robot] + out
    return ["fit-friction", log, "--robot", robot, "--no-plots"] + out


@pytest.mark.parametrize("cmd,robot", DEG_REFUSED)
def test_degrees_refused_with_robot_limits(cmd, robot, tmp_path, capsys):
    """A robot with joint limits (irb140 or a URDF): positions in degrees are refused, exit 2, one line."""
    assert main(_deg_argv(cmd, robot, _deg_log(tmp_path), tmp_path)) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "joint 1 position range" in err and "looks like degrees" in err, err


@pytest.mark.parametrize("cmd", ["check", "diagnose", "spectrum", "fit-friction"])
def test_degrees_warned_with_generic_robot(cmd, tmp_path, capsys):
    """No limits (--robot generic): the run goes on, with a one-line warning naming the joint."""
    rc = main(_deg_argv(cmd, "generic", _deg_log(tmp_path), tmp_path))
    err = capsys.readouterr().err
    warn = [ln for ln in err.splitlines() if "warning" in ln and "degrees" in ln]
    assert rc == 0 and len(warn) == 1 and "joint 1 positions span 137.5" in warn[0], err


def test_degrees_with_urdf_continuous_joint(tmp_path, capsys):
    """A URDF joint without limits (cart-pole hinge) warns; its prismatic joint with limits is checked."""
    log = _deg_log(tmp_path, two_joints=True)
    assert main(["check", log, "--robot", str(MODELS / "cartpole.urdf")]) == 0
    err = capsys.readouterr().err
    assert "joint 2 positions span" in err and "joint 1" not in err, err
    # and a radian log of the same robot gives no warning
    assert main(["check", str(_csv(tmp_path / "rad.csv", _log_cols())), "--robot", "generic"]) == 0
    assert "warning" not in capsys.readouterr().err


def test_degrees_warnings_api():
    from drake_est.data import degrees_warnings, from_arrays

    t = np.arange(200) * 0.01
    deg = from_arrays(t, np.degrees(np.sin(t))[:, None] * 2, joints=[3])
    assert len(degrees_warnings(deg)) == 1 and "joint 3" in degrees_warnings(deg)[0]
    assert degrees_warnings(deg, prismatic={3}) == []                 # metres on a linear axis
    assert degrees_warnings(deg, limits={3: (-3.0, 3.0)}) == []       # judged by load_log's limit check
    multi_turn = from_arrays(t, (500 + 50 * t)[:, None], joints=[1])   # a motor far from zero: beyond +-400
    assert degrees_warnings(multi_turn) == []
    assert degrees_warnings(from_arrays(t, np.sin(t)[:, None], joints=[1])) == []


def test_robot_option_errors(tmp_path, capsys):
    log = str(_csv(tmp_path / "ok.csv", _log_cols()))
    bad = tmp_path / "bad.urdf"
    bad.write_text("<robot name='x'><link name='a'/>")
    for robot, frag in (("foo", "--robot must be"), (str(tmp_path / "none.urdf"), "robot model not found"),
                        (str(bad), "is not valid XML")):
        assert main(["check", log, "--robot", robot]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and frag in err, err


def test_diagnose_exact_fit_and_undefined_numbers():
    """Long-fuzz escapes: the F test of an exact fit (rss1 = 0) and report text of a null (undefined) RMSE."""
    from types import SimpleNamespace

    from drake_est.diagnose.core import _test
    from drake_est.diagnose.report import _num

    prep = SimpleNamespace(joints={1: SimpleNamespace(val=np.ones(50, bool))})
    fit0 = SimpleNamespace(rss_val={1: 2.0})
    fit1 = SimpleNamespace(rss_val={1: 0.0})
    out = _test(prep, fit0, fit1, SimpleNamespace(cols=[1], n_params=3))
    assert out["p_value"] == 0.0 and out["rmse_reduction"] == 1.0 and out["F"] == float("inf")
    assert _test(prep, fit0, fit0, SimpleNamespace(cols=[1], n_params=3))["p_value"] == 1.0
    assert _num(None, ".4g") == "undefined" and _num(1.23456, ".4g") == "1.235"
