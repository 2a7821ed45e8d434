"""Data preparation and the nominal model of the diagnosis (thesis Secs. 9.2-9.3, 9.6).

The nominal model of every excited joint ``j`` is

    tau_j = ID_j(q, qd, qdd) + kv_j qd_j + kc_j sign(qd_j)          (robot: Drake inverse dynamics)
    tau_j = J_j qdd_j        + kv_j qd_j + kc_j sign(qd_j)          (generic: inertia identified)

i.e. the rigid-body model plus the symmetric Coulomb + viscous friction law (9.2), fitted by
least squares.  For a generic axis J_j is identified with a constant and sin q, cos q as nuisance columns
(a gravity/spring load would otherwise bias it); the load itself is left to the held-out test
(``position_dependent_load``, whose candidate carries sin q, cos q exactly: issue 16 item 6).  :func:`prepare` computes derivatives, the rigid-body torque, the data selection of
(9.9) (velocity away from zero, small acceleration), the alternating-block train/validation split
and a robust outlier screen, and records how many samples each step excluded.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from drake_est.errors import DataError, DrakeEstError
from drake_est.joints import coupled_joints as _coupled_joints

#: the analysis uses at most this many selected samples per joint (uniformly thinned in time
#: beyond it; energy filtering always runs on the full-rate series)
MAX_ROWS = 30000
N_BLOCKS = 30          # at least this many alternating blocks ...
BLOCK_S = 1.0          # ... and blocks of at most about this many seconds (at most MAX_BLOCKS blocks)
MAX_BLOCKS = 2000


def n_blocks_for(duration: float) -> int:
    """Number of alternating train/validation blocks for a log of ``duration`` seconds (even)."""
    n = int(np.clip(np.ceil(duration / BLOCK_S), N_BLOCKS, MAX_BLOCKS))
    return n + (n % 2)
OUTLIER_MAD = 6.0
#: Savitzky-Golay window for velocities/accelerations computed from positions [s]
DERIV_WINDOW_S = 0.1


@dataclass
class JointData:
    """Everything the detectors need about one excited joint.

    Full-length arrays (N,) over the log plus ``rows``: indices of the samples used (selected by
    (9.9), not outliers, possibly thinned); ``train``/``val`` are boolean masks over ``rows``."""

    joint: int                 # 1-based joint number
    col: int                   # column in the log
    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    a: np.ndarray
    tau: np.ndarray
    rb: np.ndarray             # rigid-body torque ID_j (robot) or J_j qdd_j (generic)
    rows: np.ndarray = None
    train: np.ndarray = None
    val: np.ndarray = None
    counts: dict = field(default_factory=dict)
    gear_ratio: float | None = None

    @property
    def y(self) -> np.ndarray:
        """Torque not explained by the rigid-body model, at the used rows."""
        return (self.tau - self.rb)[self.rows]


@dataclass
class Prepared:
    """The prepared log: per-joint data, the robot, what was skipped and why."""

    log: object
    robot_kind: str                       # "irb140" | "generic" | "urdf"
    robot: object                         # RobotModel or None
    joints: dict                          # joint number -> JointData (excited joints only)
    skipped: dict                         # joint number -> reason
    q_full: np.ndarray = None             # (N, n_robot) positions used for ID (robot only)
    v_full: np.ndarray = None
    a_full: np.ndarray = None
    robot_cols: dict = field(default_factory=dict)   # joint number -> robot coordinate index
    meta: dict = field(default_factory=dict)


def load_robot(robot):
    """``robot``: "irb140", "generic", None (generic) or a URDF path. Returns (kind, RobotModel|None, metadata|None)."""
    if robot is None or str(robot).lower() == "generic":
        return "generic", None, None
    if str(robot).lower() == "irb140":
        from drake_est.robots import irb140, irb140_metadata
        return "irb140", irb140(), irb140_metadata()
    path = Path(str(robot))
    if path.suffix.lower() not in (".urdf", ".sdf", ".xml") or not path.exists():
        raise DataError(f"--robot must be 'irb140', 'generic' or an existing .urdf file, got '{robot}'")
    from drake_est.robots import RobotModel
    try:
        model = RobotModel(path)
    except DrakeEstError:
        raise
    except Exception as err:  # noqa: BLE001 - a broken model file is user input
        raise DataError(f"cannot load robot model {path}: {str(err).splitlines()[0][:200]}") from None
    return "urdf", model, None


def _robot_state(log, robot, joints_needed):
    """Full robot coordinates (N, n_robot); joints absent from the log are held at 0 (reported)."""
    n = robot.n
    N = log.n_samples
    Q, V, A = np.zeros((N, n)), np.zeros((N, n)), np.zeros((N, n))
    cols = {}
    for c, j in enumerate(log.joints):
        if not 1 <= j <= n:
            raise DataError(f"joint {j} in the log does not exist in the robot model ({n} joints)")
        Q[:, j - 1], V[:, j - 1], A[:, j - 1] = log.q[:, c], log.dq[:, c], log.ddq[:, c]
        cols[j] = j - 1
    missing = [j for j in range(1, n + 1) if j not in cols]
    return Q, V, A, cols, missing


def coupled_joints(j, moving, meta=None) -> list:
    """Joints whose motor friction can enter joint ``j``'s torque (9.12), among the ``moving`` joints
    (all 1-based): :func:`drake_est.joints.coupled_joints` with the robot's coupling matrix
    (``meta.motor_from_arm``), or every other moving joint without one (generic)."""
    return _coupled_joints(None if meta is None else meta.motor_from_arm, j, list(moving))


#: (9.9) lower speed bound of the selected samples, as a fraction of the 95th percentile of |v|
V_MIN_FRACTION = 0.05


def select_rows(v, a, t):
    """Data selection (9.9): |v| clearly above zero and |a| small. Returns (mask, counts, thresholds)."""
    av = np.abs(v)
    vref = float(np.quantile(av, 0.95))
    # |v| must be clearly above zero, where sign(v) is certain and the friction is in its sliding regime: above
    # 5 % of the top speed and above ten times the velocity noise (robust: the sample-to-sample jitter of v,
    # which a smooth trajectory does not have).  2 % was tried: it lets a Stribeck hump at vs = 5 % of the top
    # speed be seen, but also the first seconds after each reversal at the slowest speeds, where a backlash or
    # presliding transient was then named as a Stribeck law, a load and a disturbance periodic in time.
    dv = np.diff(v)
    v_noise = 1.4826 * float(np.median(np.abs(dv - np.median(dv)))) / np.sqrt(2.0) if dv.size else 0.0
    v_min = max(V_MIN_FRACTION * vref, 10.0 * v_noise)
    moving = av > v_min
    aa = np.abs(a)
    a_ref = float(np.median(aa[moving])) if moving.any() else 0.0
    a_max = max(3.0 * a_ref, 1e-9)
    steady = aa <= a_max
    mask = moving & steady
    counts = {"near_zero_velocity": int(np.sum(~moving)), "accelerating": int(np.sum(moving & ~steady))}
    return mask, counts, {"v_min": v_min, "a_max": a_max}


def block_index(t, rows, n_blocks=None):
    t0, t1 = float(t[0]), float(t[-1])
    n_blocks = n_blocks or n_blocks_for(t1 - t0)
    return np.minimum(((t[rows] - t0) / max(t1 - t0, 1e-12) * n_blocks).astype(int), n_blocks - 1)


def block_split(t, rows, n_blocks=None):
    """Alternating time blocks: even blocks train, odd blocks validate (both halves representative)."""
    t0, t1 = float(t[0]), float(t[-1])
    n_blocks = n_blocks or n_blocks_for(t1 - t0)
    b = np.minimum(((t[rows] - t0) / max(t1 - t0, 1e-12) * n_blocks).astype(int), n_blocks - 1)
    train = (b % 2) == 0
    return train, ~train


def _load_nuisance(q) -> list:
    """Columns [1, sin q, cos q] (a constant offset and a gravity/spring-like load), each kept only where it
    is not nearly collinear with the ones before it over the range of ``q`` (relative residual norm > 1e-3)."""
    cols = []
    for c in (np.ones_like(q), np.sin(q), np.cos(q)):
        if cols:
            B = np.column_stack(cols)
            c = c - B @ np.linalg.lstsq(B, c, rcond=None)[0]
        if np.linalg.norm(c) > 1e-3 * np.sqrt(q.size):
            cols.append(c)
    return cols


def prepare(log, robot="generic", joints=None, seed: int = 0, max_rows: int = MAX_ROWS) -> Prepared:
    """Derivatives, rigid-body torques, data selection, split and outlier screen for the diagnosis."""
    if log.tau is None:
        raise DataError("the log has no torque columns (tau<j>); the diagnosis compares torques")
    if log.dq is None or log.ddq is None or "derivatives" in log.meta:
        # derivatives computed by drake_est (not measured): recompute over a longer window than the
        # loader's default, the torque comparison needs low-noise accelerations
        from drake_est.data import Log
        log = Log(t=log.t, q=log.q, tau=log.tau, joints=list(log.joints), channels=dict(log.channels),
                  meta={k: v for k, v in log.meta.items() if k != "derivatives"}).with_derivatives(window_s=DERIV_WINDOW_S)
    kind, model, meta = load_robot(robot)
    if joints is None:
        joints = list(log.joints)
    joints = [int(j) for j in joints]
    for j in joints:
        log.col(j)  # raises DataError naming the joint
    prep = Prepared(log=log, robot_kind=kind, robot=model, joints={}, skipped={})
    prep.meta["robot_meta"] = meta
    if model is not None:
        Q, V, A, cols, missing = _robot_state(log, model, joints)
        prep.q_full, prep.v_full, prep.a_full, prep.robot_cols = Q, V, A, cols
        if missing:
            prep.meta["joints_held_at_zero"] = missing
    t = log.t
    cand = {}
    first = {}
    for j in joints:
        c = log.col(j)
        q, v, a = log.q[:, c], log.dq[:, c], log.ddq[:, c]
        span = float(np.ptp(q))
        if span < 0.02 or float(np.quantile(np.abs(v), 0.95)) < 1e-3:
            prep.skipped[j] = f"not excited (position range {span:.3g}, it holds still)"
            continue
        mask, counts, thr = select_rows(v, a, t)
        first[j] = (c, q, v, a, mask, counts, thr)
    for j, (c, q, v, a, mask, counts, thr) in first.items():
        # (9.9) also for the joints whose motors are coupled to this one (9.12): their velocity enters
        # this joint's friction through sign(v_i), so samples where it is near zero are not used
        coupled = [i for i in coupled_joints(j, list(first), meta) if i != j]
        if coupled:
            near = np.zeros_like(mask)
            for i in coupled:
                vi = first[i][2]
                near |= np.abs(vi) <= first[i][6]["v_min"]
            counts["coupled_joint_near_zero_velocity"] = int(np.sum(mask & near))
            mask = mask & ~near
        if mask.sum() < 200:
            prep.skipped[j] = f"too few samples at steady velocity ({int(mask.sum())} after selection (9.9))"
            continue
        rows = np.flatnonzero(mask)
        if rows.size > max_rows:
            step = int(np.ceil(rows.size / max_rows))
            counts["thinned"] = int(rows.size - rows[::step].size)
            rows = rows[::step]
        counts["selected"] = int(rows.size)
        cand[j] = (c, q, v, a, rows, counts, thr)
    # rigid-body torque only where it is needed (union of rows)
    rb_all = {}
    if model is not None and cand:
        union = np.unique(np.concatenate([x[4] for x in cand.values()]))
        ID = model.inverse_dynamics_batch(prep.q_full[union], prep.v_full[union], prep.a_full[union])
        prep.meta["id_rows"] = union
        prep.meta["id_values"] = ID
        for j in cand:
            rb = np.zeros(log.n_samples)
            rb[union] = ID[:, prep.robot_cols[j]]
            rb_all[j] = rb
    for j, (c, q, v, a, rows, counts, thr) in cand.items():
        rb = rb_all.get(j)
        if rb is None:
            # generic axis: inertia J identified with the nominal friction on all moving samples of
            # the training blocks (the accelerating ones carry the information about J), then fixed
            moving = np.flatnonzero(np.abs(v) > thr["v_min"])
            tr, _ = block_split(t, moving)
            idx = moving[tr]
            # the position-dependent load a real axis may carry (gravity, springs, cables: 1, sin q, cos q, not
            # times sign(qd)) is a nuisance of this regression only: without it J soaks up the load, because the
            # accelerations of a sweep correlate with position (turnarounds at the range ends), and the J error then
            # shows as position-and-direction-dependent torque (issue 16 item 6). The load itself is left to the
            # held-out test of the diagnosis (position_dependent_load), J is what is kept.
            X = np.column_stack([a[idx], v[idx], np.sign(v[idx])] + _load_nuisance(q[idx]))
            # robust: two passes, the second without 6-MAD outliers
            coef, *_ = np.linalg.lstsq(X, log.tau[idx, c], rcond=None)
            e = log.tau[idx, c] - X @ coef
            ok = np.abs(e - np.median(e)) <= OUTLIER_MAD * 1.4826 * max(np.median(np.abs(e - np.median(e))), 1e-12)
            coef, *_ = np.linalg.lstsq(X[ok], log.tau[idx, c][ok], rcond=None)
            counts["inertia"] = float(coef[0])
            rb = coef[0] * a
        jd = JointData(joint=j, col=c, t=t, q=q, v=v, a=a, tau=log.tau[:, c], rb=rb, rows=rows, counts=counts)
        if meta is not None:
            jd.gear_ratio = float(meta.gear_ratios[j - 1])
        jd.counts["thresholds"] = thr
        # robust outlier screen on the nominal residual (fit on all used rows, MAD scale)
        X = nominal_columns(jd, kind)
        coef, *_ = np.linalg.lstsq(X, jd.y, rcond=None)
        r = jd.y - X @ coef
        med = np.median(r)
        mad = 1.4826 * np.median(np.abs(r - med))
        bad = np.abs(r - med) > OUTLIER_MAD * max(mad, 1e-12)
        jd.counts["outliers"] = int(bad.sum())
        jd.rows = rows[~bad]
        jd.train, jd.val = block_split(t, jd.rows)
        if "log_index" in log.channels:
            # several logs: whole logs are held out (odd-numbered logs validate, even-numbered train)
            li = np.asarray(log.channels["log_index"]).astype(int)[jd.rows]
            jd.train, jd.val = (li % 2) == 0, (li % 2) == 1
        if jd.train.sum() < 100 or jd.val.sum() < 100:
            prep.skipped[j] = "too few samples in the training or validation half"
            continue
        prep.joints[j] = jd
    if not prep.joints:
        why = "; ".join(f"joint {j}: {r}" for j, r in prep.skipped.items()) or "no joints"
        raise DataError(f"no joint of the log can be diagnosed ({why})")
    prep.meta["seed"] = seed   # the procedure is deterministic; the seed is recorded for the report
    return prep


def nominal_columns(jd: JointData, kind: str) -> np.ndarray:
    """Regressors of the nominal friction at the used rows: [qd, sign(qd)] (9.2)."""
    v = jd.v[jd.rows]
    return np.column_stack([v, np.sign(v)])


def nominal_names(kind: str) -> list:
    """Names of the nominal columns (for generic axes the inertia J is identified first, see prepare)."""
    return ["kv", "kc"]
