"""Data preparation and the nominal model of the diagnosis (thesis Secs. 9.2-9.3, 9.6).

The nominal model of every excited joint ``j`` is

    tau_j = ID_j(q, qd, qdd) + kv_j qd_j + kc_j sign(qd_j)          (robot: Drake inverse dynamics)
    tau_j = J_j qdd_j        + kv_j qd_j + kc_j sign(qd_j)          (generic: inertia identified)

i.e. the rigid-body model plus the symmetric Coulomb + viscous friction law (9.2), fitted by
least squares.  For a generic axis J_j is identified with a constant and sin q, cos q as nuisance columns
(a gravity/spring load would otherwise bias it); the load itself is left to the held-out test
(``position_dependent_load``, whose candidate carries sin q, cos q exactly: issue 16 item 6).  When several
logged joints move, the rigid-body torque of a generic joint also holds the coupled terms of a serial arm that
the data identify (gravity of the links beyond, coupling inertia, centripetal and Coriolis torques:
:func:`select_coupled_rigid_body`).  :func:`prepare` computes derivatives, the rigid-body torque, the data selection of
(9.9) (velocity away from zero, small acceleration), the alternating-block train/validation split
and a robust outlier screen, and records how many samples each step excluded.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy.stats

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
#: largest share of a joint's rows an outlier screen (:func:`screen_outliers`: on the nominal residual in
#: :func:`prepare`, on the final residual after the search) may flag; above it the tails are structure the model
#: misses (e.g. one direction of an asymmetric Coulomb level), not outliers, and nothing is screened
OUTLIER_MAX_SHARE = 0.05
#: held-out rows faster than this multiple of the fastest training row are not used to judge a model where the
#: training rows see one speed level (a log split in time blocks only; see :func:`beyond_training_speeds`)
EXTRAPOLATION_FACTOR = 1.5
#: training speeds whose 95th and 5th percentiles of |qd| lie within this ratio are one speed level
ONE_LEVEL_SPREAD = 2.0
#: the ninety-sixth round's rule (:func:`beyond_training_positions`): held-out rows at positions the training rows
#: never visit, beyond a margin, are not used to judge a model.  Off: kept on a sample, it failed its rule file's
#: conditions once every kept row was screened (loop spec 5586, an elastic gear at 1000 Hz, gains a wrong name: the
#: dropped rows had kept a spurious position load from the held-out blocks; docs/readme/diagnose_testbench.md)
BEYOND_TRAINING_POSITIONS_RULE = False
#: that margin, as a share of the span of the training positions: one kernel width of the coarsest position law
#: (8 Gaussian kernels over the span, :data:`~drake_est.diagnose.detectors.BFE_SIZES`)
BEYOND_POSITIONS_MARGIN = 1.0 / 7.0
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
    #: the ripple detector's periodogram plans (:func:`drake_est.spectral.detect.find_periodic_components`'s
    #: ``scan_plans``): reused while the rows are unchanged; not pickled (NUFFT plans)
    scan_plans: dict = field(default_factory=dict, repr=False, compare=False)
    #: the motion's own spectral lines (:func:`drake_est.diagnose.detectors.motion_lines_hz`) by (share, swing),
    #: with the t, q, v arrays they came from: those full-length arrays are not changed by any step of a diagnosis
    #: (rows are dropped, the arrays stay), so the lines are computed once per joint, not once per round
    motion_lines: dict = field(default_factory=dict, repr=False, compare=False)
    #: columns the detectors build round after round from the used rows alone (position kernels, Stribeck shapes):
    #: :meth:`cached_columns`; not pickled
    column_cache: dict = field(default_factory=dict, repr=False, compare=False)

    def __getstate__(self):
        state = dict(self.__dict__)
        state["scan_plans"] = {}
        state["motion_lines"] = {}
        state["column_cache"] = {}
        return state

    def cached_columns(self, key, make) -> np.ndarray:
        """``make()``, columns that depend only on this joint's used rows and ``key`` (e.g. the Gaussian kernels of
        one size over one range), kept while ``rows`` is the same array and at most :data:`COLUMN_CACHE_MAX_ELEMS`
        numbers are kept; returned read-only.  Every round's position and Stribeck candidates build the same columns
        again otherwise."""
        c = self.column_cache
        if c.get("_rows") is not self.rows:          # rows dropped (a new array): nothing kept is valid
            c.clear()
            c["_rows"] = self.rows
        hit = c.get(key)
        if hit is not None:
            return hit
        A = np.asarray(make())
        A.setflags(write=False)
        size = sum(v.size for k, v in list(c.items()) if k != "_rows")
        if size + A.size <= COLUMN_CACHE_MAX_ELEMS and c.get("_rows") is self.rows:
            c[key] = A
        return A

    def drop_rows(self, mask) -> None:
        """Stop using the rows where ``mask`` (over ``rows``) is True: ``rows``, ``train`` and ``val`` together."""
        keep = ~np.asarray(mask, bool)
        self.rows, self.train, self.val = self.rows[keep], self.train[keep], self.val[keep]

    @property
    def y(self) -> np.ndarray:
        """Torque not explained by the rigid-body model, at the used rows."""
        return (self.tau - self.rb)[self.rows]


#: :meth:`JointData.cached_columns` keeps at most this many numbers per joint (64 MB)
COLUMN_CACHE_MAX_ELEMS = 8_000_000


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


#: (9.9) order of the differences the velocity's jitter is read from (:func:`velocity_jitter`): 1, the
#: sample-to-sample change.  2 (second differences, blind to a steady acceleration, so that at 10 Hz the speed bound
#: falls from up to half the top speed to 5 % of it) was tried in the twenty-second and sixty-seventh rounds and not
#: kept: it finds most Stribeck laws missed at 10 Hz but names causes that were not planted
#: (``benchmarks/probe_jitter_second_differences.py``).
V_JITTER_DIFFERENCE_ORDER = 1


def velocity_jitter(v, order: int = 1) -> float:
    """Robust standard deviation of the velocity's sample-to-sample noise: the median absolute deviation of its
    ``order``-th differences (1 or 2), scaled to the noise level of white noise (which the differences amplify by
    sqrt(2) and sqrt(6)).  A smooth motion adds its own change between samples: its acceleration times the sample
    period to the first differences, its change of acceleration times the period squared to the second."""
    if order not in (1, 2):
        raise ValueError(f"velocity_jitter: order must be 1 or 2, got {order!r}")
    d = np.diff(v, order)
    if not d.size:
        return 0.0
    return 1.4826 * float(np.median(np.abs(d - np.median(d)))) / np.sqrt(2.0 if order == 1 else 6.0)


def select_rows(v, a, t):
    """Data selection (9.9): |v| clearly above zero and |a| small. Returns (mask, counts, thresholds)."""
    av = np.abs(v)
    vref = float(np.quantile(av, 0.95))
    # |v| must be clearly above zero, where sign(v) is certain and the friction is in its sliding regime: above
    # 5 % of the top speed and above ten times the velocity noise (robust: the sample-to-sample jitter of v,
    # which a smooth trajectory does not have).  2 % was tried: it lets a Stribeck hump at vs = 5 % of the top
    # speed be seen, but also the first seconds after each reversal at the slowest speeds, where a backlash or
    # presliding transient was then named as a Stribeck law, a load and a disturbance periodic in time.
    v_noise = velocity_jitter(v, V_JITTER_DIFFERENCE_ORDER)
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


def beyond_training_speeds(v, train, factor: float = EXTRAPOLATION_FACTOR,
                           one_level: float = ONE_LEVEL_SPREAD) -> np.ndarray:
    """Validation rows (``~train``) faster than ``factor`` times the fastest training row, where the training rows
    see one speed level (95th / 5th percentile of their |qd| below ``one_level``); else none.

    On one speed level [qd, sign(qd)] of (9.2) are nearly collinear: kv and kc are not told apart, nor an abrupt
    change's [dkv, dkc] step or a speed law's terms, and every candidate extrapolates to a faster held-out row with
    an error that grows with |qd|, so that one such row can decide a comparison that the speeds the fit saw do not.
    Where the training speeds spread wider the speed terms are identified and a faster held-out row is a fair test
    (it also keeps a position load fitted for a backlash from being accepted: closed-loop spec 195)."""
    av = np.abs(np.asarray(v, float))
    train = np.asarray(train, bool)
    if not train.any():
        return np.zeros(av.shape, bool)
    lo, hi = np.quantile(av[train], [0.05, 0.95])
    if hi >= one_level * lo:
        return np.zeros(av.shape, bool)
    return faster_than_training(av, train, factor)


def beyond_training_positions(q, train, margin: float = BEYOND_POSITIONS_MARGIN) -> np.ndarray:
    """Validation rows (``~train``) whose position lies beyond the training positions' range by more than ``margin``
    times its span (the ninety-sixth round, :data:`BEYOND_TRAINING_POSITIONS_RULE`).

    A law of the joint's position is fitted on the training positions only; beyond them a Gaussian kernel expansion
    and its gravity harmonic extrapolate, and every position law predicts those rows worse than none, while a law in
    time takes the difference.  So a log whose held-out blocks wander where its training blocks never went would
    judge the position laws on positions they were not fitted to (fresh loop spec 37492: a load at 10 Hz whose
    training blocks visit -0.41 to 0.80 rad, while 14 of its 371 held-out samples reach 1.33 rad; every load candidate
    predicted the held-out blocks worse than the nominal model, 0.0958 N m with 8 kernels against 0.0885, and an
    abrupt change was named in its place; on the held-out rows within the margin the load gives 0.0808 against the
    change's 0.0834).  Within one coarsest kernel width of the range the laws are still fitted; beyond it no position
    law is identified, and the rows are counted and reported, not used."""
    q = np.asarray(q, float)
    train = np.asarray(train, bool)
    if not train.any():
        return np.zeros(q.shape, bool)
    lo, hi = float(q[train].min()), float(q[train].max())
    m = margin * (hi - lo)
    return ~train & ((q < lo - m) | (q > hi + m))


def faster_than_training(v, train, factor: float = EXTRAPOLATION_FACTOR) -> np.ndarray:
    """Validation rows (``~train``) faster than ``factor`` times the fastest training row, whatever the spread of the
    training speeds (:func:`beyond_training_speeds` drops them where the training rows see one speed level; the
    free function of the state of :func:`~drake_est.diagnose.core._state_explains_one_way` leaves them out of its
    comparison everywhere: its speed curve holds its last value beyond the training speeds)."""
    av = np.abs(np.asarray(v, float))
    train = np.asarray(train, bool)
    if not train.any():
        return np.zeros(av.shape, bool)
    return ~train & (av > factor * float(av[train].max()))


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


#: significance level of the held-out F-test that admits a group of coupled rigid-body columns into a generic
#: axis' nominal model (the diagnosis' own level, :data:`drake_est.diagnose.core.ALPHA`)
COUPLING_ALPHA = 1e-4
#: a coupled column is dropped when, after removing what a function of the joint's own position can carry
#: ([1, sin q, cos q]), less than this fraction of its norm is left (not identifiable apart from the load)
COUPLING_MIN_NORM = 1e-3
#: the selected design (columns scaled to unit norm) must have a condition number below this
COUPLING_MAX_COND = 1e6
#: kernel counts of the own-position nuisance of that selection: the coupled columns are smooth (trigonometric of
#: degree <= 2 in each angle), so only the smooth part of a joint's own position dependence can be confused
#: with them; the finer kernel expansions of the candidates (up to 64) would only cost the test its power
OWN_KERNELS = (4, 8, 16)
#: numbers of equal time segments of the time-varying friction nuisance of that selection (none is also tried)
FRICTION_SEGMENTS = (4, 8, 16)
#: the constant part of the coupled terms enters the model only when its standard error is below this fraction of
#: the noise level: a constant error e raises the RMSE by a factor sqrt(1 + (e / sigma)^2), by less than the
#: diagnosis' minimum gain of 2 % (core.MIN_GAIN) for e < 0.2 sigma
CONSTANT_MAX_SE = 0.2
#: ... or below this fraction of the constant itself (keeping it then leaves at most about a tenth of the offset)
CONSTANT_REL_SE = 0.1


def coupled_rigid_body_groups(j, q, v, a, others) -> dict:
    """Candidate columns of the rigid-body regressor (Sec. 9.2: the dynamics are linear in the inertial
    parameters, tau = Y(q, qd, qdd) theta) that couple joint ``j`` to each other moving joint ``k`` of a serial
    arm, for a generic axis (no kinematic model; joints numbered from the base).  ``q``, ``v``, ``a``:
    {joint: full-length array}; ``others``: the other moving joints.  The angles that set the relative pose of
    j and k are those of the moving joints d with min(j, k) < d <= max(j, k).  Gravity is linear in the
    rotation matrices (degree 1 in the sine/cosine of each angle); inertia and velocity terms are quadratic
    in them (degree 2 adds sin 2q, cos 2q).  With h1(q) = [sin q, cos q], h2(q) = [sin 2q, cos 2q], per k:

    - ``gravity_k``: [sin q_k, cos q_k] and their products with [sin q_j, cos q_j] (e.g. sin(q_j + q_k) for
      parallel axes, products for crossed ones);
    - ``own_inertia_k`` (d != j): qdd_j h1(q_d) -- the own inertia M_jj varies with a distal angle;
      ``own_inertia2_k``: qdd_j h2(q_d);
    - ``inertia_k``: qdd_k [1, h1(q_d)] -- the coupling inertia M_jk; ``inertia2_k``: qdd_k h2(q_d);
    - ``velocity_k``: qd_k^2 h1(q_d) and qd_j qd_k h1(q_d) (centripetal and Coriolis); ``velocity2_k``: the
      same with h2.

    The degree-2 terms are groups of their own, so that the held-out selection can take the first-degree ones
    alone when the angle range does not identify more.  Returns {group name: (names, (N, m) columns)}; empty
    for a joint that moves alone."""
    def h(d, deg):
        if deg == 1:
            return [np.sin(q[d]), np.cos(q[d])], [f"sin_q{d}", f"cos_q{d}"]
        return [np.sin(2 * q[d]), np.cos(2 * q[d])], [f"sin_2q{d}", f"cos_2q{d}"]

    out = {}
    sj, cj = np.sin(q[j]), np.cos(q[j])
    moving = sorted(set(others) | {j})
    for k in others:
        sk, ck = np.sin(q[k]), np.cos(q[k])
        out[f"gravity_{k}"] = ([f"sin_q{k}", f"cos_q{k}", f"sin_q{j}_sin_q{k}", f"sin_q{j}_cos_q{k}",
                                f"cos_q{j}_sin_q{k}", f"cos_q{j}_cos_q{k}"],
                               np.column_stack([sk, ck, sj * sk, sj * ck, cj * sk, cj * ck]))
        between = [d for d in moving if min(j, k) < d <= max(j, k)]
        for deg, sfx in ((1, ""), (2, "2")):
            inames, icols = ([f"qdd{k}"], [a[k]]) if deg == 1 else ([], [])
            onames, ocols, vnames, vcols = [], [], [], []
            for d in between:
                hc, hn = h(d, deg)
                inames += [f"qdd{k}_{n}" for n in hn]
                icols += [a[k] * c for c in hc]
                if d != j:
                    onames += [f"qdd{j}_{n}" for n in hn]
                    ocols += [a[j] * c for c in hc]
                vnames += [f"qd{k}^2_{n}" for n in hn] + [f"qd{j}_qd{k}_{n}" for n in hn]
                vcols += [v[k] ** 2 * c for c in hc] + [v[j] * v[k] * c for c in hc]
            for name, nn, cc in ((f"own_inertia{sfx}_{k}", onames, ocols), (f"inertia{sfx}_{k}", inames, icols),
                                 (f"velocity{sfx}_{k}", vnames, vcols)):
                if cc:
                    out[name] = (nn, np.column_stack(cc))
    return out


def _own_load_basis(qj):
    """[1, sin q, cos q] of the joint's own position (the space the ``position_dependent_load`` candidate covers
    with its harmonic columns)."""
    return np.column_stack([np.ones_like(qj), np.sin(qj), np.cos(qj)])


def robust_scale(e, step: float = 0.0) -> float:
    """The robust noise scale of a residual for the outlier screens: 1.4826 times the median absolute deviation,
    at least the standard deviation of a rounding error, step / sqrt(12), when the torque is quantized with
    ``step`` (:func:`~drake_est.diagnose.quantization.torque_step`).  A coarse ADC whose input barely moves
    between steps leaves most residuals on one level: the MAD is then a small fraction of a step, and every sample
    one step off (8 % of a log in closed-loop spec 746) would be screened as an outlier."""
    e = np.asarray(e, float)
    med = np.median(e)
    return max(1.4826 * float(np.median(np.abs(e - med))), float(step) / np.sqrt(12.0), 1e-12)


def joint_tau_step(prep, j, tau=None) -> float:
    """The quantization step of joint ``j``'s torque (``tau``, default the joint's; 0 when not on a grid,
    :func:`~drake_est.diagnose.quantization.torque_step`), computed once and kept in ``prep.meta["tau_step"]``."""
    steps = prep.meta.setdefault("tau_step", {})
    if j not in steps:
        from drake_est.diagnose.quantization import torque_step
        steps[j] = torque_step(prep.joints[j].tau if tau is None else tau)
    return steps[j]


def outlier_mask(e, step: float = 0.0):
    """The samples of a residual ``e`` more than ``OUTLIER_MAD`` robust standard deviations (:func:`robust_scale`,
    floored at the rounding noise of a torque quantized with ``step``) from its median."""
    e = np.asarray(e, float)
    return np.abs(e - np.median(e)) > OUTLIER_MAD * robust_scale(e, step)


def screen_outliers(e, step: float = 0.0):
    """The outliers of a residual to screen out: :func:`outlier_mask`, or none when it flags more than
    ``OUTLIER_MAX_SHARE`` of the samples (those tails are misfit, and removing them would remove the evidence).
    Returns (mask, how many were flagged but not screened: 0 when the mask is applied)."""
    bad = outlier_mask(e, step)
    if bad.mean() > OUTLIER_MAX_SHARE:
        return np.zeros_like(bad), int(bad.sum())
    return bad, 0


def _robust_lstsq(X, y, step: float = 0.0):
    """Least squares, refitted once without the 6-MAD outliers of the first fit (:func:`outlier_mask`). Returns
    (coef, inlier mask)."""
    coef, *_ = np.linalg.lstsq(X, y, rcond=None)
    ok = ~outlier_mask(y - X @ coef, step)
    coef, *_ = np.linalg.lstsq(X[ok], y[ok], rcond=None)
    return coef, ok


def _own_kernels(qj, vj, idx, t, y, Xb):
    """Gaussian kernels in q_j, unsigned and times sign(qd_j) (the bases of the position_dependent_load and
    _friction candidates, :mod:`~drake_est.diagnose.detectors`), as a nuisance at the rows ``idx``.  The number
    of kernels (none or one of :data:`OWN_KERNELS`) is chosen by the inner held-out RSS (:func:`_inner_rss`) of
    the full model: ``Xb`` (the other nuisances and every candidate column) plus the kernels."""
    from drake_est.identification.friction.extensions import gaussian_features
    none = np.zeros((qj.size, 0))
    lo, hi = np.quantile(qj, [0.002, 0.998])
    span = hi - lo
    if span < 0.02:
        return none
    s = np.sign(vj)[:, None]

    def kernels():
        for K in OWN_KERNELS:
            G = gaussian_features(qj, np.linspace(lo, hi, K), span / (K - 1))
            yield np.hstack([G, s * G])

    return _best_nuisance(kernels(), Xb, y, _inner_folds(t, idx), none)


def _friction_segments(vj, idx, t, y, Xb):
    """[qd_j, sign(qd_j)] times the indicators of equal time segments of the log (all but the first), as a
    nuisance at the rows ``idx``: friction that changes over the log (an abrupt change, an energy drift: the
    time-varying candidates of the diagnosis) would otherwise be absorbed by slow coupled columns.  The number of
    segments (none or one of :data:`FRICTION_SEGMENTS`) is chosen like the kernels' (:func:`_own_kernels`)."""
    tt = t[idx]
    t0, t1 = float(t[0]), float(t[-1])

    def segments():
        for S in FRICTION_SEGMENTS:
            seg = np.minimum(((tt - t0) / max(t1 - t0, 1e-12) * S).astype(int), S - 1)
            H = (seg[:, None] == np.arange(1, S)[None, :]).astype(float)
            C = np.hstack([H * vj[:, None], H * np.sign(vj)[:, None]])
            yield C[:, np.linalg.norm(C, axis=0) > 0]

    return _best_nuisance(segments(), Xb, y, _inner_folds(t, idx), np.zeros((idx.size, 0)))


def _best_nuisance(candidates, Xb, y, folds, none):
    """The candidate column block (of growing size) with the lowest inner held-out RSS (:func:`_inner_rss`) of
    ``[Xb, C]``, or ``none`` when no candidate beats ``Xb`` alone; candidates stop once ``[Xb, C]`` would have half
    as many columns as the smaller fold has fitting rows."""
    best = (_inner_rss(Xb, y, folds)[0], none)
    for C in candidates:
        if Xb.shape[1] + C.shape[1] >= 0.5 * min(f[0].sum() for f in folds):
            break
        err = _inner_rss(np.hstack([Xb, C]), y, folds)[0]
        if err < best[0]:
            best = (err, C)
    return best[1]


def _inner_folds(t, idx):
    """Two inner folds of the rows ``idx`` (training blocks): time blocks 0, 4, 8, ... fit and 2, 6, 10, ...
    validate, and the other way round."""
    blk = block_index(t, idx)
    a, b = (blk % 4) == 0, (blk % 4) == 2
    return [(a, b), (b, a)]


def _inner_rss(X, y, folds):
    """Held-out RSS summed over ``folds`` and the number of held-out rows (each row is held out once)."""
    rss, n = 0.0, 0
    for tr, va in folds:
        if tr.sum() <= X.shape[1] or va.sum() == 0:
            return np.inf, 0
        rss += _heldout_rss(X, y, tr, va)
        n += int(va.sum())
    return rss, n


def _heldout_rss(X, y, tr, va):
    c, *_ = np.linalg.lstsq(X[tr], y[tr], rcond=None)
    e = y[va] - X[va] @ c
    return float(e @ e)


def _forward_select(X0, y, groups, idx, t, alpha):
    """Forward selection of column groups (``groups``: {name: (names, full-length columns)}) on the rows
    ``idx``: the group that lowers the held-out RSS of the two inner folds of ``idx`` (:func:`_inner_folds`)
    the most is added while its F-test has p < ``alpha`` and the scaled design keeps a condition number
    below :data:`COUPLING_MAX_COND`. Returns (chosen names, final design)."""
    folds = _inner_folds(t, idx)
    chosen, X = [], X0
    rss0, n_va = _inner_rss(X, y, folds)
    while n_va > 0 and 0 < rss0 < np.inf:
        best = None
        for g, (_, U) in groups.items():
            if g in chosen:
                continue
            X1 = np.hstack([X, U[idx]])
            sc = np.linalg.norm(X1, axis=0)
            if np.any(sc <= 0) or np.linalg.cond(X1 / sc) > COUPLING_MAX_COND:
                continue
            rss1, _ = _inner_rss(X1, y, folds)
            m = U.shape[1]
            dof = max(n_va - X1.shape[1], 1)
            F = ((rss0 - rss1) / m) / max(rss1 / dof, 1e-300)
            p = float(scipy.stats.f.sf(F, m, dof)) if F > 0 else 1.0
            if p < alpha and (best is None or rss1 < best[1]):
                best = (g, rss1, X1)
        if best is None:
            break
        chosen.append(best[0])
        rss0, X = best[1], best[2]
    return chosen, X


def _orthogonal_to(groups, B, Bi, idx, subtract=None):
    """Each group's columns minus their least-squares projection on the basis ``B`` (full length; ``Bi`` its
    rows ``idx``) fitted on ``idx`` -- only the part along the columns of B flagged in ``subtract`` (default all)
    is removed.  Columns with less than :data:`COUPLING_MIN_NORM` of their norm left after the full projection
    are dropped (not identifiable apart from B), and groups with none left."""
    sub = np.ones(B.shape[1], bool) if subtract is None else np.asarray(subtract, bool)
    out = {}
    for g, (names, C) in groups.items():
        gam, *_ = np.linalg.lstsq(Bi, C[idx], rcond=None)
        U = C - B[:, sub] @ gam[sub]
        resid = C[idx] - Bi @ gam
        keep = np.linalg.norm(resid, axis=0) > COUPLING_MIN_NORM * np.maximum(np.linalg.norm(C[idx], axis=0), 1e-300)
        if keep.any():
            out[g] = ([n for n, k in zip(names, keep) if k], U[:, keep])
    return out


def select_coupled_rigid_body(j, q, v, a, tau, idx_moving, idx_steady, t, others, alpha=COUPLING_ALPHA, step=None):
    """The inertia J of a generic axis ``j`` that moves together with ``others``, and the coupled rigid-body
    terms (:func:`coupled_rigid_body_groups`) that the data identify (issue 16 item 6).

    Both stages share the nuisance columns [qd_j, sign(qd_j), 1, sin q_j, cos q_j] (the nominal friction (9.2)
    and the joint's own load, as in :func:`prepare`) and the other joints' friction columns [qd_k, sign(qd_k)]
    (gear coupling (9.12), left to its own held-out test, so that rigid-body columns do not absorb it).

    1. On the moving samples of the training blocks ``idx_moving`` (the accelerating ones carry the
       information about inertia): J and the own-inertia groups qdd_j h(q_d) (made orthogonal to qdd_j, so
       that J is the mean inertia), with every other coupled column as a nuisance.
    2. With those fixed, the other groups on the steady-velocity samples (9.9) of the training blocks
       ``idx_steady``, where the filtered accelerations are accurate (fitted at the accelerating samples, 15-30
       columns carry the derivative error into every sample).  Their nuisance also holds Gaussian kernels in
       q_j with and without sign(qd_j) (:func:`_own_kernels`): over a log of a few sweeps a slow coupled
       column correlates with any slow function of q_j and would absorb a position-dependent friction.

    Every other group loses its part along sin q_j, cos q_j (projected on [1, sin q_j, cos q_j] on its rows):
    that part of the joint's load is left to ``position_dependent_load``, whose candidate carries exactly these
    two columns, as for a joint moving alone.  The regression has a constant of its own (a nuisance, so a real
    Coulomb asymmetry is not absorbed); the constant part of the fitted coupled terms (e.g. the mean of a
    gravity term of the links beyond) is added to the model when its standard error is below
    :data:`CONSTANT_MAX_SE` times the noise level or :data:`CONSTANT_REL_SE` times the constant -- left out,
    nothing but ``asymmetric_coulomb`` would take it.  Groups enter by :func:`_forward_select` (held-out F-test at level ``alpha``, conditioning).

    Returns ``(torque, info)``: the coupled torque over the whole log (zeros when nothing is selected) and
    {"groups": [...], "columns": [...], "coef": [...], "inertia": J, "constant": c0, "constant_se": its standard
    error, "constant_kept": bool}.  ``step``: the quantization step of ``tau`` when known (default: computed,
    :func:`~drake_est.diagnose.quantization.torque_step`); the outlier screens are floored at its rounding noise
    (:func:`robust_scale`)."""
    if step is None:
        from drake_est.diagnose.quantization import torque_step
        step = torque_step(tau)
    N = q[j].size
    groups = coupled_rigid_body_groups(j, q, v, a, others)
    L = _own_load_basis(q[j])
    fric = np.column_stack([v[j], np.sign(v[j])] + [c for k in others for c in (v[k], np.sign(v[k]))])
    own = {g: x for g, x in groups.items() if g.startswith("own_inertia")}
    rest = {g: x for g, x in groups.items() if not g.startswith("own_inertia")}
    # 1. J and the own-inertia variation on the moving samples
    idx = idx_moving
    A = a[j][:, None]
    own = _orthogonal_to(own, A, A[idx], idx)      # J is then the mean inertia over these samples
    C_rest = np.hstack([C for _, C in rest.values()]) if rest else np.zeros((N, 0))
    X0 = np.column_stack([a[j][idx], fric[idx], L[idx], C_rest[idx]])
    chosen1, X = _forward_select(X0, tau[idx], own, idx, t, alpha)
    coef, _ = _robust_lstsq(X, tau[idx], step)
    J = float(coef[0])
    tau_c = np.zeros(N)
    names, beta_all = [], []
    if chosen1:
        U = np.hstack([own[g][1] for g in chosen1])
        beta = coef[X0.shape[1]:]
        tau_c += U @ beta
        names += [n for g in chosen1 for n in own[g][0]]
        beta_all += [float(b) for b in beta]
    info = {"groups": list(chosen1), "columns": names, "coef": beta_all, "inertia": J}
    if not rest:
        return tau_c, info
    # 2. the other groups on the steady samples, with J and the own inertia fixed
    idx = idx_steady
    y = tau[idx] - J * a[j][idx] - tau_c[idx]
    # the own-load columns that are not collinear over the sampled range (else the condition check fails)
    Xn = np.column_stack([fric[idx]] + _load_nuisance(q[j][idx]))
    ortho = _orthogonal_to(rest, L, L[idx], idx)
    # the same columns with their constant part: only the sin q_j, cos q_j part is left out (the load candidate
    # carries exactly those two, unpenalized); the constant part of the fitted terms is added below when the data
    # determine it (the regression has a constant of its own, so the coefficients are those of ``ortho``)
    ortho_rb = _orthogonal_to(rest, L, L[idx], idx, subtract=[False, True, True])   # differs by a constant
    X_all = np.hstack([Xn] + [U[idx] for _, U in ortho.values()])
    X0 = np.hstack([Xn, _own_kernels(q[j][idx], v[j][idx], idx, t, y, X_all)])
    X0 = np.hstack([X0, _friction_segments(v[j][idx], idx, t, y, np.hstack([X0, X_all[:, Xn.shape[1]:]]))])
    chosen2, X = _forward_select(X0, y, ortho, idx, t, alpha)
    if chosen2:
        U = np.hstack([ortho[g][1] for g in chosen2])
        coef, ok = _robust_lstsq(X, y, step)
        beta = coef[X0.shape[1]:]
        tau_c += U @ beta
        # the constant part of the selected terms (what ortho_rb keeps beyond ortho, one number per column): kept
        # when the data determine it -- its standard error below CONSTANT_MAX_SE of the noise level (an offset
        # error of that size raises the RMSE by less than the 2 % a finding needs) or below CONSTANT_REL_SE of
        # the constant itself (at most a tenth of it is left); a constant extrapolated from terms that barely
        # vary over the range (e.g. cos q_k over a few tenths of a rad) is neither
        d = np.concatenate([(ortho_rb[g][1][idx[:1]] - ortho[g][1][idx[:1]])[0] for g in chosen2])
        c0 = float(d @ beta)
        r = (y - X @ coef)[ok]
        sigma = float(np.sqrt(r @ r / max(r.size - X.shape[1], 1)))
        gvec = np.concatenate([np.zeros(X0.shape[1]), d])
        w, *_ = np.linalg.lstsq(X[ok].T, gvec, rcond=None)     # ||w||^2 = g' (X'X)^+ g
        se = sigma * float(np.linalg.norm(w))
        info.update(constant=c0, constant_se=se,
                    constant_kept=bool(se < max(CONSTANT_MAX_SE * sigma, CONSTANT_REL_SE * abs(c0))))
        if info["constant_kept"]:
            tau_c += c0
        info["groups"] += chosen2
        info["columns"] += [n for g in chosen2 for n in ortho[g][0]]
        info["coef"] += [float(b) for b in beta]
    return tau_c, info


def with_diagnosis_derivatives(log):
    """``log`` with the derivatives the diagnosis uses: measured ones as they are; ones computed by drake_est (or
    none) recomputed over :data:`DERIV_WINDOW_S`, longer than the loader's default (the torque comparison needs
    low-noise accelerations)."""
    if log.dq is None or log.ddq is None or "derivatives" in log.meta:
        from drake_est.data import Log
        log = Log(t=log.t, q=log.q, tau=log.tau, joints=list(log.joints), channels=dict(log.channels),
                  meta={k: v for k, v in log.meta.items() if k != "derivatives"}).with_derivatives(window_s=DERIV_WINDOW_S)
    return log


def prepare(log, robot="generic", joints=None, seed: int = 0, max_rows: int = MAX_ROWS) -> Prepared:
    """Derivatives, rigid-body torques, data selection, split and outlier screen for the diagnosis."""
    if log.tau is None:
        raise DataError("the log has no torque columns (tau<j>); the diagnosis compares torques")
    log = with_diagnosis_derivatives(log)
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
            # several joints moving together: the other joints' positions, velocities and accelerations enter this
            # joint's torque through the rigid body (gravity of the links beyond, coupling inertia, centripetal
            # and Coriolis torques); the terms the data identify are part of the nominal model (issue 16 item 6)
            others = [k for k in first if k != j]
            tau_c, info = np.zeros(log.n_samples), {"groups": [], "inertia": None}
            if others:
                qs, vs, as_ = ({k: first[k][i] for k in first} for i in (1, 2, 3))
                # identified on the training blocks of the samples (9.9) selects (steady velocity): at the
                # accelerating ones the filtered accelerations are least accurate, and 15-30 coupled columns
                # fitted there carry that error into every sample
                sel = rows[block_split(t, rows)[0]]
                tau_c, info = select_coupled_rigid_body(j, qs, vs, as_, log.tau[:, c], idx, sel, t, others,
                                                       step=joint_tau_step(prep, j, log.tau[:, c]))
            if info["groups"]:
                prep.meta.setdefault("coupled_rigid_body", {})[j] = info
            if info["inertia"] is not None:
                # J identified with the other joints' friction and rigid-body columns as nuisances
                J = info["inertia"]
            else:
                X = np.column_stack([a[idx], v[idx], np.sign(v[idx])] + _load_nuisance(q[idx]))
                # robust: two passes, the second without 6-MAD outliers
                coef, _ = _robust_lstsq(X, log.tau[idx, c], joint_tau_step(prep, j, log.tau[:, c]))
                J = float(coef[0])
            counts["inertia"] = J
            rb = J * a + tau_c
        jd = JointData(joint=j, col=c, t=t, q=q, v=v, a=a, tau=log.tau[:, c], rb=rb, rows=rows, counts=counts)
        if meta is not None:
            jd.gear_ratio = float(meta.gear_ratios[j - 1])
        jd.counts["thresholds"] = thr
        # robust outlier screen on the nominal residual (fit on all used rows, MAD scale floored at the rounding
        # noise of a quantized torque)
        X = nominal_columns(jd, kind)
        coef, *_ = np.linalg.lstsq(X, jd.y, rcond=None)
        bad, skipped = screen_outliers(jd.y - X @ coef, joint_tau_step(prep, j, log.tau[:, c]))
        if skipped:
            jd.counts["outlier_screen_skipped"] = skipped
        jd.counts["outliers"] = int(bad.sum())
        jd.rows = rows[~bad]
        jd.train, jd.val = block_split(t, jd.rows)
        if "log_index" in log.channels:
            # several logs: whole logs are held out (odd-numbered logs validate, even-numbered train)
            li = np.asarray(log.channels["log_index"]).astype(int)[jd.rows]
            jd.train, jd.val = (li % 2) == 0, (li % 2) == 1
        else:
            far = beyond_training_speeds(jd.v[jd.rows], jd.train)
            if far.any():
                jd.counts["beyond_training_speeds"] = int(far.sum())
                jd.drop_rows(far)
            if BEYOND_TRAINING_POSITIONS_RULE:
                far = beyond_training_positions(jd.q[jd.rows], jd.train)
                if far.any():
                    jd.counts["beyond_training_positions"] = int(far.sum())
                    jd.drop_rows(far)
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
