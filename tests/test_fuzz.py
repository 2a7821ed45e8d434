"""Property-based fuzzing of the loaders (issue 19): random corruptions of valid logs, NPZ archives and
calibration files give a result or the project's one-line error (DrakeEstError) -- never another
exception, never NaN in the result, in bounded time.  Short budget by default; ``-m slow`` runs long."""
import io
import os
import re
import zipfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from drake_est.data import load_log
from drake_est.errors import DrakeEstError

SHORT = int(os.environ.get("DRAKE_EST_FUZZ_EXAMPLES", "100"))
LONG = 3000
COMMON = dict(deadline=10_000, suppress_health_check=list(HealthCheck), derandomize=True, database=None)


def _valid_csv() -> bytes:
    t = np.arange(120) * 0.01
    cols = {"t": t, "q1": 0.4 * np.sin(3 * t), "q2": 0.2 * np.cos(2 * t), "tau1": np.cos(3 * t),
            "tau2": 0.5 * np.sin(2 * t), "temp": 20 + 0 * t}
    lines = [",".join(cols)] + [",".join(f"{v:.6g}" for v in row) for row in np.column_stack(list(cols.values()))]
    return ("\n".join(lines) + "\n").encode()


def _valid_npz() -> bytes:
    t = np.arange(120) * 0.01
    buf = io.BytesIO()
    np.savez_compressed(buf, meta_json=np.array('{"robot": "x"}'), t=t, q1=np.sin(t), tau1=np.cos(t))
    return buf.getvalue()


CSV, NPZ = _valid_csv(), _valid_npz()
TOKENS = [b"nan", b"inf", b"-inf", b"1e300", b"-1e300", b"1e-300", b"", b"abc", b",", b"\n", b"#", b";", b"\t",
          b'"', b"0", b"1e8", b"q01", b"q0", b"tau0", b"\x00", b"\xff\xfe", b"9" * 400]


@st.composite
def corrupt(draw, base: bytes):
    """A few random edits of ``base``: byte flips, token insertions/replacements, truncation, duplication."""
    b = bytearray(base)
    for _ in range(draw(st.integers(1, 4))):
        op = draw(st.sampled_from(["flip", "insert", "replace", "truncate", "delete", "dup"]))
        if not b:
            break
        i = draw(st.integers(0, len(b) - 1))
        if op == "flip":
            b[i] ^= draw(st.integers(1, 255))
        elif op == "insert":
            b[i:i] = draw(st.sampled_from(TOKENS))
        elif op == "replace":
            j = min(len(b), i + draw(st.integers(1, 12)))
            b[i:j] = draw(st.sampled_from(TOKENS))
        elif op == "truncate":
            del b[i:]
        elif op == "delete":
            del b[i:i + draw(st.integers(1, 50))]
        else:
            j = min(len(b), i + draw(st.integers(1, 200)))
            b[j:j] = b[i:j]
    return bytes(b)


def _check(path, **kw):
    try:
        log = load_log(path, **kw)
    except DrakeEstError as e:
        assert "\n" not in str(e).strip()
        return
    for a in (log.t, log.q, log.dq, log.ddq, log.tau):
        if a is not None:
            assert np.all(np.isfinite(a))
    assert np.all(np.diff(log.t) > 0)


def _fuzz_csv(data, d):
    p = d / "log.csv"
    p.write_bytes(data)
    _check(p)
    _check(p, nan_policy="drop")


def _fuzz_npz(data, d):
    p = d / "log.npz"
    p.write_bytes(data)
    _check(p)


@settings(max_examples=SHORT, **COMMON)
@given(data=corrupt(CSV))
def test_fuzz_csv_loader(data, tmp_path_factory):
    _fuzz_csv(data, tmp_path_factory.mktemp("fz"))


@settings(max_examples=SHORT, **COMMON)
@given(data=corrupt(NPZ))
def test_fuzz_npz_loader(data, tmp_path_factory):
    _fuzz_npz(data, tmp_path_factory.mktemp("fz"))


NPZ_MEMBERS = dict(meta=st.one_of(st.text(max_size=30), st.sampled_from(["[1]", "1", "null", '"s"', "{",
                                                                        '{"a": NaN}'])),
                   member=st.sampled_from(["t", "q1", "tau1"]), cut=st.integers(0, 400))


def _fuzz_npz_member(meta, member, cut, d):
    """Bad meta_json and damaged compressed members inside an otherwise valid zip."""
    buf = io.BytesIO()
    t = np.arange(120) * 0.01
    np.savez_compressed(buf, meta_json=np.array(meta), t=t, q1=np.sin(t), tau1=np.cos(t))
    b = bytearray(buf.getvalue())
    with zipfile.ZipFile(io.BytesIO(bytes(b))) as z:
        info = z.getinfo(member + ".npy")
    k = info.header_offset + 30 + len(info.filename) + len(info.extra) + cut % max(info.compress_size, 1)
    b[k] ^= 0xA5
    _fuzz_npz(bytes(b), d)


@settings(max_examples=SHORT, **COMMON)
@given(**NPZ_MEMBERS)
def test_fuzz_npz_members(meta, member, cut, tmp_path_factory):
    _fuzz_npz_member(meta, member, cut, tmp_path_factory.mktemp("fz"))


def _ft_bytes(csv_format: bool) -> bytes:
    from drake_est.calibration import random_ft_poses, random_rotation, simulate_ft

    rng = np.random.default_rng(0)
    P = random_ft_poses(rng, 15)
    W = simulate_ft(P, random_rotation(rng), 1.0, [0, 0, 0.05], rng=rng)
    if csv_format:
        cols = {f"r{i+1}{j+1}": P[:, i, j] for i in range(3) for j in range(3)}
        cols.update(px=P[:, 0, 3], py=P[:, 1, 3], pz=P[:, 2, 3])
        cols.update({k: W[:, i] for i, k in enumerate(["fx", "fy", "fz", "tx", "ty", "tz"])})
        return (",".join(cols) + "\n" + "\n".join(",".join(f"{v:.6g}" for v in r)
                                                   for r in np.column_stack(list(cols.values()))) + "\n").encode()
    buf = io.BytesIO()
    np.savez(buf, poses=P, wrench=W)
    return buf.getvalue()


FT_CSV, FT_NPZ = _ft_bytes(True), _ft_bytes(False)


FT_FILE = st.one_of(corrupt(FT_CSV).map(lambda b: ("ft.csv", b)), corrupt(FT_NPZ).map(lambda b: ("ft.npz", b)))


def _fuzz_cal_reader(data, d):
    """The calibration file reader and pose/wrench extraction of `drake-est calibrate` (no fit, no plot)."""
    from drake_est.cli.calibrate import _poses_from, _read_table

    p = d / data[0]
    p.write_bytes(data[1])
    try:
        tab = _read_table(p)
        _poses_from(tab, 1.0, p)
    except (DrakeEstError, UnicodeDecodeError):   # UnicodeDecodeError: the CLI's one-line handler
        return


@settings(max_examples=SHORT, **COMMON)
@given(data=FT_FILE)
def test_fuzz_calibration_reader(data, tmp_path_factory):
    _fuzz_cal_reader(data, tmp_path_factory.mktemp("fzr"))


def _run_cli(argv):
    """``drake-est ARGV`` in this process: (exit code, stderr without warning lines, all stderr)."""
    import contextlib

    from drake_est.cli import main

    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        rc = main(argv)
    text = err.getvalue()
    warning = re.compile(r"^(drake-est [\w-]+: warning: |WARNING:|\[\d{4}-\d\d-\d\d .*\] \[\w+\] \[warning\])")
    return rc, [ln for ln in text.splitlines() if not warning.match(ln)], text


def _assert_cli_ok(rc, lines, text, out_dir=None):
    """The CLI property: exit 0 (then no NaN/Infinity in any JSON written) or exit 2 with one line."""
    assert rc in (0, 2), (rc, text)
    if rc == 2:
        assert len(lines) == 1 and re.match(r"^drake-est [\w -]+: error: ", lines[0]) and "Traceback" not in text, text
    elif out_dir is not None and Path(out_dir).exists():
        for f in Path(out_dir).rglob("*.json"):
            body = f.read_text()
            assert "NaN" not in body and "Infinity" not in body, f


def _fuzz_cal_cli(data, d):
    """`drake-est calibrate ft` on a corrupted CSV/NPZ calibration file."""
    p = d / data[0]
    p.write_bytes(data[1])
    _assert_cli_ok(*_run_cli(["calibrate", "ft", str(p), "--out", str(d / "out")]), d / "out")


# -- URDF: corruptions of models/irb140.urdf through every entry point that takes a robot model ---------------

URDF = (Path(__file__).resolve().parents[1] / "models" / "irb140.urdf").read_text()
URDF_BAD_NUMBERS = ["nan", "inf", "-inf", "-1", "0", "1e300", "-1e300", "1e-300", "", "abc", "1 2", "1 2 3 4",
                    "0 0 0", "1e9", "-0.5", "3.14159"]
JOINT_TYPES = ["revolute", "continuous", "prismatic", "fixed", "floating", "planar", "spherical", "bogus", ""]


@st.composite
def corrupt_urdf(draw):
    """1-3 structural edits of the IRB 140 URDF (delete/duplicate an element, a bad number, a renamed
    link reference, another joint type), then maybe a text edit (truncation, byte flip, token)."""
    import copy
    import xml.etree.ElementTree as ET

    root = ET.fromstring(URDF)
    for _ in range(draw(st.integers(1, 3))):
        parents = [(par, ch) for par in root.iter() for ch in list(par)]
        op = draw(st.sampled_from(["delete", "duplicate", "number", "number", "link_ref", "joint_type"]))
        if op in ("delete", "duplicate"):
            par, ch = draw(st.sampled_from(parents))
            if op == "delete":
                par.remove(ch)
            else:
                par.insert(list(par).index(ch), copy.deepcopy(ch))
        elif op == "number":
            els = [el for el in root.iter() if any(a in el.attrib for a in
                                                   ("value", "ixx", "ixy", "iyy", "izz", "xyz", "rpy", "lower",
                                                    "upper", "velocity", "effort", "damping"))]
            el = draw(st.sampled_from(els))
            attr = draw(st.sampled_from(sorted(a for a in el.attrib if a not in ("name", "link", "type"))))
            val = draw(st.one_of(st.sampled_from(URDF_BAD_NUMBERS),
                                 st.floats(allow_nan=True, allow_infinity=True).map(repr)))
            el.set(attr, val)
        elif op == "link_ref":
            refs = [el for el in root.iter() if el.tag in ("parent", "child")]
            links = [el.get("name") for el in root.iter("link")] + ["nope", "world", ""]
            if refs:
                draw(st.sampled_from(refs)).set("link", draw(st.sampled_from(links)))
        else:
            joints = [el for el in root.iter("joint") if el.get("type") is not None]
            if joints:
                draw(st.sampled_from(joints)).set("type", draw(st.sampled_from(JOINT_TYPES)))
    text = ET.tostring(root, encoding="unicode").encode()
    if draw(st.booleans()):
        text = draw(corrupt(text))
    return text


def _urdf_entry(entry, path):
    """Run one entry point on a URDF; returns a numeric result to check for finiteness (or None)."""
    from pydrake.systems.framework import DiagramBuilder

    from drake_est.robots import RobotModel, robot_position_limits

    if entry == "RobotModel":
        m = RobotModel(path)
        q = np.zeros(m.n)
        return np.r_[m.inverse_dynamics(q, q, q), m.forward_kinematics(q).GetAsMatrix4().ravel()]
    if entry == "robot_position_limits":
        lim, _ = robot_position_limits(path)
        return np.array([v for lo_hi in lim.values() for v in lo_hi])
    if entry == "diagnose.load_robot":
        from drake_est.diagnose.nominal import load_robot

        load_robot(str(path))
        return None
    if entry == "AddRobotPlant":
        from drake_est.systems.builders import AddRobotPlant

        AddRobotPlant(DiagramBuilder(), path)
        return None
    raise KeyError(entry)


URDF_ENTRIES = ["RobotModel", "robot_position_limits", "diagnose.load_robot", "AddRobotPlant"]


def _fuzz_urdf(data, entry, d):
    p = d / "robot.urdf"
    p.write_bytes(data)
    try:
        out = _urdf_entry(entry, p)
    except DrakeEstError as e:
        assert "\n" not in str(e).strip(), str(e)
        return
    if out is not None:
        assert np.all(np.isfinite(out)), out


@settings(max_examples=max(SHORT // 4, 10), **COMMON)
@given(data=corrupt_urdf(), entry=st.sampled_from(URDF_ENTRIES))
def test_fuzz_urdf(data, entry, tmp_path_factory):
    """A corrupted URDF gives a model or the project's one-line error through every entry point."""
    _fuzz_urdf(data, entry, tmp_path_factory.mktemp("fzu"))


def _log_for_check(d):
    t = np.arange(200) * 0.01
    cols = {"t": t, **{f"q{j}": 0.3 * np.sin(t + j) for j in range(1, 7)},
            **{f"tau{j}": np.cos(t + j) for j in range(1, 7)}}
    p = d / "log.csv"
    p.write_text(",".join(cols) + "\n" + "\n".join(",".join(f"{v:.6g}" for v in r)
                                                  for r in np.column_stack(list(cols.values()))) + "\n")
    return p


def _fuzz_urdf_cli(data, d):
    """`drake-est check LOG --robot BAD.urdf`: exit 0, or exit 2 with one line."""
    p = d / "robot.urdf"
    p.write_bytes(data)
    _assert_cli_ok(*_run_cli(["check", str(_log_for_check(d)), "--robot", str(p)]))


@settings(max_examples=max(SHORT // 10, 5), **COMMON)
@given(data=corrupt_urdf())
def test_fuzz_urdf_cli(data, tmp_path_factory):
    _fuzz_urdf_cli(data, tmp_path_factory.mktemp("fzuc"))


def _fuzz_urdf_diagnose(data, d):
    """`drake-est diagnose LOG --robot BAD.urdf` (no simulation): exit 0 or a one-line exit 2, no NaN out."""
    p = d / "robot.urdf"
    p.write_bytes(data)
    out = d / "out"
    _assert_cli_ok(*_run_cli(["diagnose", str(_irb140_log(d)), "--robot", str(p), "--no-simulation", "--out",
                              str(out)]), out)


def _irb140_log(d):
    """A 6 s IRB 140 log (rigid-body torque + friction) for the diagnose target."""
    from drake_est.robots import irb140

    m = irb140()
    t = np.arange(600) * 0.01
    Q = np.column_stack([0.5 * np.sin(2 * np.pi * 0.4 * t + j) for j in range(6)])
    QD = np.gradient(Q, t, axis=0)
    QDD = np.gradient(QD, t, axis=0)
    tau = m.inverse_dynamics_batch(Q, QD, QDD) + 0.5 * np.sign(QD) + 0.3 * QD
    cols = {"t": t, **{f"q{j + 1}": Q[:, j] for j in range(6)}, **{f"tau{j + 1}": tau[:, j] for j in range(6)}}
    p = d / "irb.csv"
    p.write_text(",".join(cols) + "\n" + "\n".join(",".join(f"{v:.9g}" for v in r)
                                                   for r in np.column_stack(list(cols.values()))) + "\n")
    return p


def _friction_csv() -> bytes:
    """A 12 s one-joint log with Coulomb + viscous friction and a position ripple: long enough that most
    corruptions leave a log every command accepts."""
    t = np.arange(1200) * 0.01
    q = 1.5 * np.sin(2 * np.pi * 0.2 * t)
    dq = 1.5 * 2 * np.pi * 0.2 * np.cos(2 * np.pi * 0.2 * t)
    tau = 0.8 * np.sign(dq) + 0.4 * dq + 0.1 * np.sin(8 * q) + 0.01 * np.sin(37 * t)
    lines = ["t,q1,tau1"] + [f"{a:.6g},{b:.6g},{c:.6g}" for a, b, c in zip(t, q, tau)]
    return ("\n".join(lines) + "\n").encode()


FRICTION_CSV = _friction_csv()


@st.composite
def corrupt_values(draw):
    """1-3 numeric edits of the friction log that keep a well-formed CSV: a cell set to an extreme value, a
    column scaled or quantized or held constant, the time axis rescaled, a gap, swapped/duplicated rows,
    a short log -- damage that passes the parser and must be caught (or handled) by the numerics."""
    rows = np.array([[float(x) for x in ln.split(",")] for ln in FRICTION_CSV.decode().splitlines()[1:]])
    for _ in range(draw(st.integers(1, 3))):
        n = rows.shape[0]
        op = draw(st.sampled_from(["cell", "scale", "quantize", "constant", "time_scale", "gap", "swap", "dup",
                                   "short", "offset"]))
        i = draw(st.integers(0, n - 1))
        c = draw(st.integers(0, 2))
        if op == "cell":
            rows[i, c] = draw(st.one_of(st.sampled_from([np.nan, np.inf, -np.inf, 1e300, -1e300, 1e8, 0.0, 1e-300]),
                                        st.floats(allow_nan=False, allow_infinity=False)))
        elif op == "scale":
            rows[:, c] *= draw(st.sampled_from([1e-300, 1e-6, 1e3, 1e6, -1.0, 0.0]))
        elif op == "quantize":
            step = draw(st.sampled_from([0.5, 0.1, 1.0]))
            rows[:, draw(st.integers(1, 2))] = np.round(rows[:, c] / step) * step
        elif op == "constant":
            rows[:, draw(st.integers(1, 2))] = draw(st.sampled_from([0.0, 1.0]))
        elif op == "time_scale":
            rows[:, 0] *= draw(st.sampled_from([1e-3, 1e3, 1e6, 1e-9]))
        elif op == "gap":
            rows[i:, 0] += draw(st.sampled_from([0.5, 10.0, 1e4, 1e7]))
        elif op == "swap" and n > 1:
            j = draw(st.integers(0, n - 1))
            rows[[i, j]] = rows[[j, i]]
        elif op == "dup":
            rows = np.insert(rows, i, rows[i], axis=0)
        elif op == "short":
            rows = rows[:max(2, draw(st.integers(2, 60)))]
        else:
            rows[:, 1] += draw(st.sampled_from([1e3, -50.0, 2 * np.pi]))
    text = "t,q1,tau1\n" + "\n".join(",".join(repr(float(v)) for v in r) for r in rows) + "\n"
    return text.encode()
LOG_COMMANDS = {
    "check": lambda p, o: ["check", p],
    "fit-friction": lambda p, o: ["fit-friction", p, "--no-plots", "--out", o],
    "spectrum": lambda p, o: ["spectrum", p, "--signal", "tau1", "--position", "q1", "--schedule", "dq1",
                              "--out", o],
    "diagnose": lambda p, o: ["diagnose", p, "--no-simulation", "--out", o],
}


def _fuzz_log_command(data, command, d):
    """A corrupted log through a command's whole input path (load, fit, write): exit 0 or one line."""
    p = d / "log.csv"
    p.write_bytes(data)
    out = d / "out"
    _assert_cli_ok(*_run_cli(LOG_COMMANDS[command](str(p), str(out))), out)


# -- the long run: every target for a share of DRAKE_EST_FUZZ_SECONDS (default 300 s in all) -------------------
#    DRAKE_EST_FUZZ_SECONDS=600 DRAKE_EST_FUZZ_REPORT=fuzz.json python -m pytest tests/test_fuzz.py -m slow
#: name -> (strategies for @given, body(d, **drawn), examples per hypothesis call, share of the budget)
LONG_TARGETS = {
    "csv_loader": (dict(data=corrupt(CSV)), lambda d, data: _fuzz_csv(data, d), 100, 2),
    "npz_loader": (dict(data=corrupt(NPZ)), lambda d, data: _fuzz_npz(data, d), 100, 1),
    "npz_members": (NPZ_MEMBERS, lambda d, **kw: _fuzz_npz_member(d=d, **kw), 100, 1),
    "calibration_reader": (dict(data=FT_FILE), lambda d, data: _fuzz_cal_reader(data, d), 100, 1),
    "calibrate_ft_cli": (dict(data=FT_FILE), lambda d, data: _fuzz_cal_cli(data, d), 5, 1),
    "urdf_entries": (dict(data=corrupt_urdf(), entry=st.sampled_from(URDF_ENTRIES)),
                     lambda d, data, entry: _fuzz_urdf(data, entry, d), 50, 2),
    "urdf_check_cli": (dict(data=corrupt_urdf()), lambda d, data: _fuzz_urdf_cli(data, d), 20, 1),
    "urdf_diagnose_cli": (dict(data=corrupt_urdf()), lambda d, data: _fuzz_urdf_diagnose(data, d), 2, 1),
    "log_commands": (dict(data=corrupt(FRICTION_CSV), command=st.sampled_from(sorted(LOG_COMMANDS))),
                     lambda d, data, command: _fuzz_log_command(data, command, d), 5, 3),
    "log_values_commands": (dict(data=corrupt_values(), command=st.sampled_from(sorted(LOG_COMMANDS))),
                            lambda d, data, command: _fuzz_log_command(data, command, d), 3, 3),
}
FUZZ_SECONDS = float(os.environ.get("DRAKE_EST_FUZZ_SECONDS", "300"))


@pytest.mark.slow
@pytest.mark.parametrize("target", list(LONG_TARGETS))
def test_fuzz_long(target, tmp_path_factory):
    """Random (not derandomized) examples of one target until its share of the time budget is spent."""
    import json
    import time

    strategies, body, chunk, share = LONG_TARGETS[target]
    budget = FUZZ_SECONDS * share / sum(v[3] for v in LONG_TARGETS.values())
    count = [0]

    @settings(max_examples=chunk, **{**COMMON, "derandomize": False, "deadline": None})
    @given(**strategies)
    def run(**drawn):
        count[0] += 1
        body(tmp_path_factory.mktemp("fzl"), **drawn)

    t0 = time.monotonic()
    while time.monotonic() - t0 < budget:
        run()
    seconds = time.monotonic() - t0
    report = os.environ.get("DRAKE_EST_FUZZ_REPORT")
    if report:
        with open(report, "a") as f:
            f.write(json.dumps({"target": target, "examples": count[0], "seconds": round(seconds, 1),
                                "budget_s": round(budget, 1), "failures": 0}) + "\n")
    assert count[0] >= chunk
