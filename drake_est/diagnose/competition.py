"""Competing explanations of one residual pattern (issue #16, item 2).

Two checks that run before a candidate of :mod:`drake_est.diagnose.core` is accepted:

* **Position ripple vs time-periodic disturbance.**  A ripple periodic in motor position with f cycles/rad
  seen at speed v is a component at f v Hz; a disturbance periodic in time keeps its Hz at every speed.
  What tells them apart is therefore the *frequency signature across speeds* (Ch. 10: an LPV component in
  position keeps its cycles per rad).  When the log runs at one speed level (:func:`speed_level_ratio`
  below :data:`ONE_SPEED_RATIO`) the two are not identifiable, whatever their held-out scores: the finding
  is reported as "ambiguous between motor_position_ripple and time_periodic_disturbance" and the model
  keeps the position ripple when it is significant (a function of the state, which a simulation and
  another log can use), else the time-periodic one.  Both names are then closed for that joint.
* **A speed law or a drift that only absorbs a periodic residual.**  Stribeck friction, an energy drift and
  an abrupt change are smooth in speed or in time; on a log with a strong unmodeled periodic residual they
  can win a round merely by absorbing part of it.  Such a candidate must stay significant on the held-out
  data when the periodic structure of the current residual (:func:`periodic_nuisance`: the strongest
  sinusoids in time and the ripple components in position, found on the training part) is in the model
  as well: a partial F-test of the candidate given the periodic alternative.  For a law in time
  (:data:`FLOORED_LAWS`: a step or a drift) the nuisance's sinusoids have at least :data:`NUISANCE_MIN_PERIODS`
  periods in the log, since a slower sinusoid fits a step or a drift about as well as they do.
* **A drift, a change or a disturbance in time that only absorbs a speed-law misfit.**  An energy drift or an
  abrupt change claims that the friction changed *in time*, a time-periodic disturbance that a force recurs
  in time; when the fitted friction curve has the wrong shape (a Stribeck law of another form, a viscous term
  held at its bound), a time law can win a round by following how the speeds are distributed over the log
  (point-to-point moves that repeat every few seconds make a speed-law misfit periodic in time).  Such a
  candidate must stay significant on the held-out data given a free friction curve of each direction (:func:`speed_law_nuisance`: piecewise-linear in |qd|, knots at the
  training speeds' quantiles), the same partial F-test -- unless the free curve does not explain anything
  beyond the law in time either (speeds and time confounded in the log: e.g. the moves after a change all
  faster than those before it), when the law in time stands.
* **A position law that a speed law explains as well.**  Under point-to-point moves each position is
  passed at one speed (and in one direction, between two end points), and a friction level that changes with q,
  or a load that does, fits the misfit of a speed law of another shape or an asymmetric Coulomb level.  A
  position-dependent friction or load that is not significant given the free friction curve (its knots also spread
  in log-speed, so that a sparse tail of fast samples is spanned too) is reported as ambiguous with ``stribeck``,
  or with ``asymmetric_coulomb`` when one friction level per direction explains a load alone
  (:func:`position_law_confounded`); it stays in the model.
* **A later finding that a disturbance's dither of the Coulomb friction explains.**  A torque disturbance periodic in
  time shakes the axis: at speeds below the velocity amplitude A it adds, the Coulomb level averages over the
  dither to kc (2/pi) arcsin(qd/A) instead of kc sign(qd) (the describing function of a relay under a sinusoid),
  a friction deficit at low speed that no vocabulary entry has and that a position law fits where positions and
  speeds go together (loop spec 5369: a 15 Hz disturbance sampled at 50 Hz, then a position load).  On a joint
  whose model holds a time-periodic disturbance, every other candidate must stay significant given that column
  (:func:`dither_nuisance`: A and a positive coefficient fitted on the training rows), the same partial F-test; a
  position-dependent friction g(q) sign(qd) stands when it does so as it is or in its dithered form g(q) (2/pi)
  arcsin(qd/A).
* **A change in time that bursts of misfit decide.**  An abrupt change claims friction parameters that hold before
  and after one instant.  Where the residual's level varies strongly from window to window of the log (bursts of a
  misfit that no vocabulary entry has, e.g. a backlash crossed at low speed during some moves only), an unweighted
  fit lets the windows with bursts set the parameters, and a step wins by how the bursts fall on either side of it
  (loop spec 6531).  The change must stay significant by weighted least squares, each time window weighted by the
  inverse of its residual level under the model with the change, reweighted to convergence
  (:func:`survives_window_weights`).
"""
from __future__ import annotations

import numpy as np
import scipy.stats

from drake_est.diagnose.parallel import pmap


def ambiguous_rivals(competition) -> list:
    """The rivals an ambiguous finding is not separated from: ``ambiguous_with`` (best first), else the runner-up."""
    return list(competition.get("ambiguous_with") or [competition.get("runner_up")])


PERIODIC_PAIR = ("motor_position_ripple", "time_periodic_disturbance")
#: speed levels: the ratio of the 90 % to the 10 % quantile of the mean |qd| over windows of a few periods
#: (:func:`speed_level_ratio`); below this one speed level only (a ripple of f cycles/rad then sits at f v Hz within +-20 %
#: of one frequency, which is what a time-periodic disturbance at one frequency also gives)
ONE_SPEED_RATIO = 1.5
#: candidates that are smooth in speed or time and must beat a periodic alternative (see module docstring)
CONFOUNDABLE = ("stribeck", "energy_dependent_friction", "abrupt_change")
#: sinusoids in time in the periodic nuisance of :func:`periodic_nuisance`
NUISANCE_SINUSOIDS = 3
#: fewest periods in the log of a sinusoid of the periodic nuisance for any law but those of :data:`FLOORED_LAWS`
#: (the lowest frequency the time-periodic disturbance itself is scanned from)
NUISANCE_PERIODS = 4.0
#: laws in time (a step, a drift) whose periodic nuisance holds only sinusoids of at least
#: :data:`NUISANCE_MIN_PERIODS` periods in the log (thirty-first round): a slower sinusoid fits a step or a drift
#: about as well as the step or drift does, so the nuisance set aside the very law it was to test (loop spec 8484: a
#: third-size abrupt change set aside by a sinusoid of 4.2 periods, and a position friction named in its place).
#: Every other law keeps the 4-period nuisance: a speed law must still beat a slow disturbance (the several-log
#: test of a 45 s disturbance, 6 periods in the log, against Stribeck; the thirtieth round floored every law)
FLOORED_LAWS = ("abrupt_change", "energy_dependent_friction")
#: fewest periods in the log of a sinusoid of the periodic nuisance of a law of :data:`FLOORED_LAWS`
NUISANCE_MIN_PERIODS = 10.0


def nuisance_periods(effect: str) -> float:
    """Fewest periods in the log of a sinusoid of the periodic nuisance that a candidate of ``effect`` is tested
    against (:data:`NUISANCE_MIN_PERIODS` for the laws in time of :data:`FLOORED_LAWS`, else
    :data:`NUISANCE_PERIODS`)."""
    return NUISANCE_MIN_PERIODS if effect in FLOORED_LAWS else NUISANCE_PERIODS


#: laws in time that must beat a free friction curve (:func:`speed_law_nuisance`); the time-periodic disturbance
#: since the tenth round (loop spec 2032: a 0.17 Hz "disturbance" that followed a Lorentz Stribeck law's misfit
#: under repeated moves)
TIME_LAWS = ("energy_dependent_friction", "abrupt_change", "time_periodic_disturbance")
#: laws in position (a friction level, a load) reported ambiguous with ``stribeck`` when a free friction curve
#: explains them (:func:`position_law_confounded`)
POSITION_LAWS = ("position_dependent_friction", "position_dependent_load")
#: knots per direction of the free friction curve of :func:`speed_law_nuisance`
SPEED_LAW_KNOTS = 8


def speed_level_ratio(jd, window_s: float = 1.0) -> float:
    """q90 / q10 of the mean |qd| over consecutive windows of ``window_s`` seconds of the used rows
    (1 = one speed level).  The window should hold a few periods of the periodic component in question:
    within a period a ripple itself modulates the speed, which is not a second speed level."""
    rows = jd.rows
    t = jd.t[rows]
    b = np.floor((t - t[0]) / max(window_s, 1e-9)).astype(int)
    av = np.abs(jd.v[rows])
    cuts = np.flatnonzero(np.diff(b)) + 1
    means = np.array([np.mean(g) for g in np.split(av, cuts) if g.size >= 10])
    if means.size < 2:
        return 1.0
    lo, hi = np.quantile(means, [0.1, 0.9])
    return float(hi / max(lo, 1e-12))


def periodic_window_s(ext, jd) -> float:
    """Averaging window for :func:`speed_level_ratio` around a periodic candidate: three periods in time
    (a ripple of f cycles/rad at the median speed v has its period 1 / (f v)), at least one second."""
    ev = ext.evidence
    if "frequency_hz" in ev:
        f = float(ev["frequency_hz"])
    else:
        f = float(ev.get("frequency_per_arm_rad", 0.0)) * float(np.median(np.abs(jd.v[jd.rows])))
    return max(1.0, 3.0 / f) if f > 0 else 1.0


def one_speed_level(jd, window_s: float = 1.0) -> bool:
    """True when position-periodic and time-periodic explanations cannot be told apart (one speed level)."""
    return speed_level_ratio(jd, window_s) < ONE_SPEED_RATIO


def better_first(results) -> list:
    """Round results (ext, test, ...) of one effect and joint, the significant first, then by score: the time-periodic
    scan may offer two candidates (off and at a line of the motion), and the better one stands for the effect."""
    return sorted(results, key=lambda r: (not r[1]["significant"], -r[1]["score"]))


def resolve_periodic(prep, best, results):
    """``(kept, info)`` for the round's winner ``best`` = (ext, test, fit, model) among ``results``.

    ``info`` is None when nothing changes; else the competition fields of an ambiguous finding: the winner
    was one of :data:`PERIODIC_PAIR` on a one-speed log.  ``kept`` is the position ripple's result when it
    is significant, else ``best``."""
    ext = best[0]
    if ext.effect not in PERIODIC_PAIR or ext.shared:
        return best, None
    jd = prep.joints[ext.joint]
    ratio = speed_level_ratio(jd, periodic_window_s(ext, jd))
    if ratio >= ONE_SPEED_RATIO:
        return best, None
    partner = next(e for e in PERIODIC_PAIR if e != ext.effect)
    other = better_first(r for r in results if r[0].effect == partner and r[0].joint == ext.joint)
    kept = best
    if ext.effect != "motor_position_ripple" and other and other[0][1]["significant"]:
        kept = other[0]
    rival = other[0] if (other and kept is best) else (best if kept is not best else None)
    info = {"ambiguous": True, "runner_up": partner if kept[0].effect != partner else ext.effect,
            "runner_up_joint": int(ext.joint),
            "reason": f"one speed level (window-mean speed ratio {ratio:.3g} < {ONE_SPEED_RATIO}): a ripple in "
                      "position and a disturbance periodic in time give the same frequency",
            "speed_level_ratio": ratio}
    if kept[0].effect == "motor_position_ripple":
        info["frequencies_folded_per_arm_rad"] = folded_frequencies(kept[0], jd)
    if rival is not None:
        info["runner_up_score"] = float(rival[1]["score"])
        info["runner_up_significant"] = bool(rival[1]["significant"])
        info["margin"] = float(kept[1]["score"] - rival[1]["score"])
    else:
        info["runner_up_score"], info["runner_up_significant"], info["margin"] = None, False, None
    return kept, info


def folded_frequencies(ext, jd) -> list:
    """The ripple's frequencies [cycles/rad] folded to the lowest equivalent one at the log's one speed level:
    sampled at fs [Hz] while moving at v, a ripple of f cycles/rad is indistinguishable from f + m fs / v
    (any integer m); with one speed level nothing tells them apart, so the lowest |f - m fs / v| is reported."""
    fs = 1.0 / float(np.median(np.diff(jd.t)))
    v = float(np.median(np.abs(jd.v[jd.rows])))
    fn = fs / max(v, 1e-12)
    out = []
    for f in ext.evidence.get("frequencies_per_arm_rad", []):
        out.append(float(abs(f - np.round(f / fn) * fn)))
    return out


def _lstsq(A, y, n_unpenalized):
    return np.linalg.lstsq(A, y, rcond=None)[0]


def _fit_rss(A, y, train, val, n_unpenalized, solve):
    """(held-out RSS, coefficients) of ``A`` fitted to ``y`` on the training rows."""
    c = solve(A[train], y[train], n_unpenalized)
    e = y[val] - A[val] @ c
    return float(e @ e), c


def periodic_nuisance(prep, model, fit, j, min_periods: float = NUISANCE_PERIODS):
    """Columns (at the joint's used rows) of the periodic structure of the current residual of joint ``j``:
    up to :data:`NUISANCE_SINUSOIDS` sinusoids in time of at least ``min_periods`` periods in the log
    (:func:`nuisance_periods`; each found on the training residual left by the
    previous ones, :func:`~drake_est.diagnose.detectors.time_periodic`) and the ripple components in position
    (:func:`~drake_est.diagnose.detectors.ripple`).  Each component joins only when it lowers the held-out error
    of the model (fitted on the training rows): the scan sees the training blocks only, and their alternation
    with the held-out blocks (1 s on, 1 s off in a 120 s log) leaks any slow training residual to 0.5 Hz, where a
    sinusoid fits the training blocks and takes the opposite sign on the held-out ones.  Such a nuisance raises
    the held-out error of every partial test built on it and sets aside true findings (loop spec 2607: the
    0.5 Hz pair alone lowered the training error of the nominal model by a quarter and doubled its held-out
    error, and the ripple columns raised it by a quarter; given them Stribeck lost).  None when there is none."""
    import drake_est.diagnose.detectors as det
    jd = prep.joints[j]
    r = jd.y - fit.pred[j]
    X = model.design_with_shared(j)

    def fitted(A):
        c, *_ = np.linalg.lstsq(A[jd.train], jd.y[jd.train], rcond=None)
        e = jd.y - A @ c
        return float(e[jd.val] @ e[jd.val]), e

    cols = []
    best, _ = fitted(X)
    rk = r
    for _ in range(NUISANCE_SINUSOIDS):
        # motion-locked sinusoids included: the nuisance stands for any periodic structure of the residual
        e = det.time_periodic(jd, rk, skip_motion_lines=False, min_periods=min_periods)
        if e is None:
            break
        rss_val, res = fitted(np.hstack([X] + cols + [e.cols[j]]))
        if rss_val >= best:
            break
        best, rk = rss_val, res
        cols.append(e.cols[j])
    e = det.ripple(jd, r)
    if e is not None and fitted(np.hstack([X] + cols + [e.cols[j]]))[0] < best:
        cols.append(e.cols[j])
    return np.hstack(cols) if cols else None


#: a knot spread in log-speed joins the free friction curve (:func:`speed_law_nuisance`) only when each of the two
#: intervals it makes with its neighbours holds at least this many training samples of its direction
SPREAD_KNOT_MIN_SAMPLES = 20


def _supported_knots(a, x, extra) -> np.ndarray:
    """The sorted knots ``x`` with each of ``extra`` added in turn where both intervals it makes with its neighbours
    hold at least :data:`SPREAD_KNOT_MIN_SAMPLES` of the speeds ``a`` (a hat function over a few samples is fitted to
    them alone and extrapolates on the held-out rows: loop spec 56, a load at 1000 Hz whose partial test given the
    curve then raised the held-out error by 16 %)."""
    x = np.asarray(x, float)
    for e in extra:
        k = int(np.searchsorted(x, e))
        if k == 0 or k == x.size or e == x[k - 1] or e == x[k]:
            continue
        lo = np.sum((a >= x[k - 1]) & (a < e))
        hi = np.sum((a >= e) & (a <= x[k]))
        if min(lo, hi) >= SPREAD_KNOT_MIN_SAMPLES:
            x = np.insert(x, k, e)
    return x


#: a gap in a direction's training speeds: two consecutive speeds (sorted) more than this factor apart
SPEED_GAP_RATIO = 1.5


def _gap_knots(a, x) -> np.ndarray:
    """The sorted knots ``x`` with a knot at both edges of every gap in the speeds ``a`` (:data:`SPEED_GAP_RATIO`)
    that has at least :data:`SPREAD_KNOT_MIN_SAMPLES` speeds at or below its lower edge and as many at or above its
    upper edge; knots strictly inside such a gap are dropped.  No sample says what the friction curve does in a gap,
    and a curve linear across it ties the speeds beyond it to the slope of those below it (loop spec 8522: one
    direction's fast samples all at 0.347 rad/s, none from 0.029 rad/s up, and a position friction beside a load
    fitted the friction level at the fast speed)."""
    s = np.sort(np.asarray(a, float))
    x = np.asarray(x, float)
    if s.size < 2 * SPREAD_KNOT_MIN_SAMPLES:
        return x
    r = s[1:] / np.maximum(s[:-1], 1e-300)
    for i in np.flatnonzero(r > SPEED_GAP_RATIO):
        lo, hi = s[i], s[i + 1]
        if i + 1 >= SPREAD_KNOT_MIN_SAMPLES and s.size - (i + 1) >= SPREAD_KNOT_MIN_SAMPLES:
            x = np.unique(np.concatenate([x[(x < lo) | (x > hi)], [lo, hi]]))
    return x


def speed_law_nuisance(prep, j, knots: int = SPEED_LAW_KNOTS, spread: bool = False):
    """Columns (at the joint's used rows) of a free friction curve f(|qd|) for each direction of motion: hat
    functions of |qd| with ``knots`` knots at the quantiles of the training speeds of that direction (every
    monotone or non-monotone speed law, Stribeck of any shape, a viscous term held at its bound, is in their
    span up to the knot spacing).  With ``spread`` also ``knots`` knots spread evenly in log-speed between that
    direction's smallest and largest training speed, each where it leaves at least :data:`SPREAD_KNOT_MIN_SAMPLES`
    training samples on both sides (:func:`_supported_knots`): a sparse tail of faster samples otherwise lies
    between two quantile knots, and the curve's shape there escapes the span (loop spec 7975: six sevenths of one
    direction's samples below 0.045 rad/s, the last quantile knots at 0.045 and 0.32 rad/s, and a position load
    fitted the curve's shape between them), and knots at both edges of every gap in the speeds (:func:`_gap_knots`).
    None when a direction has too few training samples for it."""
    jd = prep.joints[j]
    v = jd.v[jd.rows]
    cols = []
    for side in (v > 0, v < 0):
        a = np.abs(v[side & jd.train])
        if a.size < 4 * knots:
            continue
        x = np.unique(np.quantile(a, np.linspace(0.0, 1.0, knots)))
        if spread and x[0] > 0:
            x = _gap_knots(a, _supported_knots(a, x, np.geomspace(x[0], x[-1], knots)[1:-1]))
        if x.size < 3:
            continue
        av = np.clip(np.abs(v), x[0], x[-1])
        H = np.zeros((v.size, x.size))
        k = np.clip(np.searchsorted(x, av, side="right") - 1, 0, x.size - 2)
        w = (av - x[k]) / (x[k + 1] - x[k])
        idx = np.arange(v.size)
        H[idx, k] = 1.0 - w
        H[idx, k + 1] = w
        cols.append(H * side[:, None])
    return np.hstack(cols) if cols else None


#: dither velocity amplitudes A tried by :func:`dither_nuisance` (log spaced from half the 2 % to the 90 % quantile of
#: the training speeds)
DITHER_GRID = 24


def dithered_sign(v, A: float) -> np.ndarray:
    """The mean of sign(qd + A sin phi) over a uniform phase phi: (2/pi) arcsin(qd / A), clipped to +-1 beyond A
    (the Coulomb level seen through a sinusoidal dither of velocity amplitude ``A``)."""
    return (2.0 / np.pi) * np.arcsin(np.clip(np.asarray(v, float) / A, -1.0, 1.0))


def dither_nuisance(prep, model, j):
    """One column (at the joint's used rows), dithered_sign(qd, A) - sign(qd): the change of a Coulomb friction
    that a time-periodic disturbance of joint ``j`` in ``model`` dithers (module docstring), with A on
    :data:`DITHER_GRID` chosen by the training residual of the model plus the column, whose coefficient must be
    positive (a dither lowers the mean friction; a negative one would be a friction excess at low speed, Stribeck).
    None when the model holds no time-periodic disturbance of the joint or no A gives a positive coefficient."""
    if not any(e.effect == "time_periodic_disturbance" and not e.shared and e.joint == j for e in model.exts):
        return None
    jd = prep.joints[j]
    v = jd.v[jd.rows]
    av = np.abs(v[jd.train])
    av = av[av > 0]
    if av.size < 10:
        return None
    X = model.design_with_shared(j)
    Xt, yt = X[jd.train], jd.y[jd.train]
    best = None
    for A in np.geomspace(0.5 * float(np.quantile(av, 0.02)), float(np.quantile(av, 0.9)), DITHER_GRID):
        c = dithered_sign(v, A) - np.sign(v)
        M = np.hstack([Xt, c[jd.train][:, None]])
        coef, *_ = np.linalg.lstsq(M, yt, rcond=None)
        if not coef[-1] > 0:
            continue
        e = yt - M @ coef
        rss = float(e @ e)
        if best is None or rss < best[0]:
            best = (rss, c)
    return None if best is None else best[1][:, None]


def survives_dither(prep, model, fit, ext, alpha: float, min_gain: float, nuisance=None, solve=None) -> dict:
    """Partial held-out F-test of ``ext`` given the dither column of its joint (:func:`dither_nuisance`; module
    docstring); ``{"significant": True, "skipped": ...}`` when it does not apply."""
    if ext.shared or ext.effect == "time_periodic_disturbance":
        return {"significant": True, "skipped": "a disturbance itself or a shared extension"}
    N = dither_nuisance(prep, model, ext.joint) if nuisance is None else nuisance
    if N is None:
        return {"significant": True, "skipped": "no time-periodic disturbance in the model, or no dither"}
    C = ext.cols[ext.joint]
    t = _partial_test(prep, model, ext.joint, N, C, alpha, min_gain, solve)
    if not t["significant"] and ext.effect in DITHERED_WITH_THE_LEVEL:
        # a Coulomb level that changes with position is dithered like the level: g(q) sign(qd) averages to
        # g(q) (2/pi) arcsin(qd/A), i.e. the columns times dithered_sign / sign (1 + N sign(qd)); the candidate
        # stands when either form explains what the dither column does not (loop specs 4167 and 4343)
        jd = prep.joints[ext.joint]
        td = _partial_test(prep, model, ext.joint, N, C * (1.0 + N[:, 0] * np.sign(jd.v[jd.rows]))[:, None],
                           alpha, min_gain, solve)
        if td["significant"]:
            return {**td, "dithered_form": True}
    return t


#: candidates whose columns are a function of position times sign(qd): tested by :func:`survives_dither` in their
#: dithered form too
DITHERED_WITH_THE_LEVEL = ("position_dependent_friction",)

#: laws in time tested by :func:`survives_window_weights`: a change of the friction parameters at one instant
STEP_LAWS = ("abrupt_change",)
#: time windows of :func:`window_weights` (fewer when the joint has under :data:`WEIGHT_WINDOW_ROWS` rows per window)
WEIGHT_WINDOWS = 40
WEIGHT_WINDOW_ROWS = 30
#: a window's mean square is floored at this share of the residual's mean square over all rows (a quiet window, or
#: one that a quantized torque lets the model fit exactly, does not get an unbounded weight)
WEIGHT_FLOOR = 0.1
#: reweightings of :func:`survives_window_weights` (iteratively reweighted least squares of the model with the change)
WEIGHT_ITERATIONS = 12


def window_weights(prep, j, e) -> np.ndarray:
    """Weights (one per used row of joint ``j``) of a feasible weighted least squares: the inverse of the mean square
    of the residual ``e`` over the row's time window (:data:`WEIGHT_WINDOWS` equal windows of the log, each holding
    training and held-out blocks), floored at :data:`WEIGHT_FLOOR` times the mean square over all rows and at the
    rounding noise step^2 / 12 of a quantized torque; windows of under 5 rows take the mean square over all rows.
    Normalized to mean 1 over the training rows."""
    from drake_est.diagnose.nominal import block_index, joint_tau_step
    jd = prep.joints[j]
    e2 = np.asarray(e, float) ** 2
    n_w = int(max(2, min(WEIGHT_WINDOWS, jd.rows.size // WEIGHT_WINDOW_ROWS)))
    win = block_index(jd.t, jd.rows, n_blocks=n_w)
    cnt = np.bincount(win, minlength=n_w)
    ms = np.bincount(win, weights=e2, minlength=n_w) / np.maximum(cnt, 1)
    every = float(np.mean(e2))
    floor = max(WEIGHT_FLOOR * every, joint_tau_step(prep, j) ** 2 / 12.0, 1e-300)
    ms = np.where(cnt >= 5, np.maximum(ms, floor), max(every, floor))
    w = 1.0 / ms[win]
    return w / max(float(np.mean(w[jd.train])), 1e-300)


def survives_window_weights(prep, model, fit, ext, alpha: float, min_gain: float, solve=None) -> dict:
    """Partial held-out F-test of a change of the friction parameters in time (:data:`STEP_LAWS`) by weighted least
    squares, each row weighted by the inverse of its time window's mean square residual under the model *with* the
    change (:func:`window_weights`).  A step claims parameters that hold before and after it; where the residual's
    level varies strongly from window to window (bursts of a misfit no vocabulary entry has), an unweighted fit lets
    the windows with bursts set the parameters, and a step wins by how the bursts fall on either side of it (loop spec
    6531: a backlash at 1000 Hz, windows of 6 s with residual RMS 0.6 beside ones of 0.08 before and after the
    "change"; unweighted held-out gain 15 %, weighted 0.04 %).  Weights from the alternative's own residual do not
    penalize a true change for the misfit it removes; :data:`WEIGHT_ITERATIONS` reweightings take the step's own
    compromise out of them.  ``{"significant": True, "skipped": ...}`` when it does not apply."""
    from drake_est.diagnose.nominal import nominal_names
    if ext.effect not in STEP_LAWS or ext.shared:
        return {"significant": True, "skipped": "not a change of the friction parameters in time"}
    solve = solve or _lstsq
    j = ext.joint
    jd = prep.joints[j]
    X = model.design_with_shared(j)
    C = ext.cols[j]
    A1 = np.hstack([X, C])
    n_nominal = len(nominal_names(prep.robot_kind))
    tr = jd.train
    w = np.ones(jd.rows.size)
    for _ in range(WEIGHT_ITERATIONS):
        sw = np.sqrt(w[tr])
        c = solve(A1[tr] * sw[:, None], jd.y[tr] * sw, n_nominal)
        w = window_weights(prep, j, jd.y - A1 @ c)
    t = _partial_test(prep, model, j, np.zeros((jd.rows.size, 0)), C, alpha, min_gain, solve, weights=w)
    t["weight_ratio_q90_q10"] = float(np.quantile(w, 0.9) / max(float(np.quantile(w, 0.1)), 1e-300))
    return t


#: laws of the speed tested by :func:`survives_both_speed_changes`: a friction excess at low speed (Sec. 9.1)
SIDE_LAWS = ("stribeck",)
#: :func:`survives_both_speed_changes` applies when the rows speeding up and those slowing down each hold at least
#: this many training and held-out rows
SIDE_MIN_ROWS = 20


def speeding_up(prep, j) -> np.ndarray:
    """Over the used rows of joint ``j``: whether the joint speeds up there (a qd > 0; on the way out of a
    standstill or a reversal) rather than slows down (a qd <= 0; on the way into one)."""
    jd = prep.joints[j]
    return (jd.a[jd.rows] * jd.v[jd.rows]) > 0


def survives_both_speed_changes(prep, model, fit, ext, alpha: float, min_gain: float, solve=None, curve=None) -> dict:
    """Held-out F-test of a friction law of the speed (:data:`SIDE_LAWS`) on the rows where its joint slows down: the
    law's curve there (zero elsewhere) added to the model with a scale of its own.  A friction curve F(|qd|)
    (Sec. 9.1) is a law of the sliding regime: an axis that slides into a stop or a reversal passes the low speeds
    sliding, and the law must show there.  The samples leaving a standstill or a reversal are no evidence of it on
    their own: breakaway, presliding, or the nominal model's error where the Coulomb sign changes within the
    derivative window can leave an excess there that no steady law describes (loop spec 7981, a null log at
    1000 Hz: a Stribeck hump at 0.025 rad/s, held-out RMSE 2.1 % lower, with 140 % of that gain in the slow samples
    within 0.1 s after a reversal, while the slow samples slowing down into a stop lose by it).  The reverse is not
    asked: planted laws in closed loop often show where the axis slows down and not where it speeds up (loop specs
    7378, 1438, 2563).

    ``curve``: the law's fitted curve at the used rows (its columns times its coefficients in the fit with it; one
    column, whatever the shape: a basis law's columns on one side extrapolate where that side has few slow samples);
    default the columns' least-squares fit to the model's residual on the training rows.  The rows speeding up keep
    their part of the curve at its fitted scale, taken off the torque (an offset): not a scale of their own (loop
    spec 5027: the curve is small there, 1 % of its mass, and a scale of their own, fitted on the training rows,
    came out at 34 and raised the held-out error fivefold), and not left out (a large law left out on one side biases
    the nominal fit: loop spec 7510 then gained a position friction).  The test needs
    p < ``alpha``, a positive score and a positive scale (training fit), no minimum gain (the law's gain is shared by
    the two sides): an excess only where the axis speeds up biases the nominal Coulomb and viscous fit, and the rows
    slowing down then take the curve with a negative scale.  Reports the same test on the rows speeding up too;
    ``{"significant": True, "skipped": ...}`` when it does not apply (another effect, or a side with under
    :data:`SIDE_MIN_ROWS` training or held-out rows)."""
    if ext.effect not in SIDE_LAWS or ext.shared:
        return {"significant": True, "skipped": "not a friction law of the speed"}
    j = ext.joint
    jd = prep.joints[j]
    C = ext.cols[j]
    up = speeding_up(prep, j)
    for side in (up, ~up):
        if min(int(np.sum(side & jd.train)), int(np.sum(side & jd.val))) < SIDE_MIN_ROWS:
            return {"significant": True, "skipped": "too few rows speeding up or slowing down"}
    if curve is None:
        tr = jd.train
        c = np.linalg.lstsq(C[tr], (jd.y - fit.pred[j])[tr], rcond=None)[0]
        curve = C @ c
    g = np.asarray(curve, float)
    none = np.zeros((g.size, 0))
    out = {}
    for name, side in (("slowing_down", ~up), ("speeding_up", up)):
        # the other side's part of the law at its fitted scale taken off the torque (an offset, no coefficient); the
        # side's own scale of the law (1: the law as fitted on both sides) is the last coefficient of the test's fit
        t = _partial_test(prep, model, j, none, np.where(side, g, 0.0)[:, None], alpha, 0.0, solve,
                          offset=np.where(side, 0.0, g), coef=True)
        scale = float(t["coef"][-1])
        out[name] = {**_brief(t), "scale": scale, "significant": bool(t["significant"] and scale > 0)}
    return {**out["slowing_down"], **out}


def survives_speed_law(prep, model, fit, ext, alpha: float, min_gain: float, nuisance=None, solve=None) -> dict:
    """Partial held-out F-test of a law in time (:data:`TIME_LAWS`) given a free friction curve of its joint
    (:func:`speed_law_nuisance`; module docstring); ``{"significant": True, "skipped": ...}`` when it does not
    apply."""
    if ext.effect not in TIME_LAWS or ext.shared:
        return {"significant": True, "skipped": "not a law in time"}
    N = speed_law_nuisance(prep, ext.joint) if nuisance is None else nuisance
    if N is None:
        return {"significant": True, "skipped": "too few samples per direction for a free friction curve"}
    t = _partial_test(prep, model, ext.joint, N, ext.cols[ext.joint], alpha, min_gain, solve)
    if not t["significant"]:
        # the reverse question: does the free curve explain anything the law in time does not?  When the speeds
        # before and after a change (or at low and high energy) do not overlap, neither adds to the other: time and
        # speed are confounded in this log, and the law in time is not set aside for a curve that is no better
        back = _partial_test(prep, model, ext.joint, ext.cols[ext.joint], N, alpha, min_gain, solve)
        t["speed_law_given_it"] = _brief(back)
        if not back["significant"]:
            t["significant"] = True
            t["confounded_with_speed"] = True
    return t


#: Gaussian kernels in position (alone and times sign(qd)) of the free function of the state that a time-periodic
#: candidate at a line of the motion must beat (:func:`state_nuisance`)
STATE_KERNELS = 12


#: the names of the blocks :func:`state_blocks` can return
STATE_BLOCK_NAMES = ("load", "position_friction", "speed", "inertia", "jerk", "reversal")


def state_blocks(prep, j, kernels: int = STATE_KERNELS) -> dict:
    """The blocks of a free function of the state of joint ``j`` (columns at the joint's used rows), by name: ``load``
    (sin q, cos q and ``kernels`` Gaussian kernels in q over the training range), ``position_friction`` (the same
    kernels times sign(qd)), ``speed`` (the free friction curve of each direction, knots at the quantiles and spread in
    log-speed, :func:`speed_law_nuisance`), ``inertia`` (qdd sign(qd), qdd |qd|, qdd sin q, qdd cos q: an inertia
    that differs with the direction or speed of motion or with the configuration), ``jerk`` (the lag of the
    derivative filter) and ``reversal`` (a transient after each reversal, :func:`reversal_columns`).  The position blocks are left out where the joint spans less than 0.02 rad, the speed curve
    where a direction has too few samples for it."""
    from drake_est.diagnose.detectors import gaussian_features
    jd = prep.joints[j]
    q, v, a = jd.q[jd.rows], jd.v[jd.rows], jd.a[jd.rows]
    lo, hi = np.quantile(q[jd.train], [0.002, 0.998])
    out = {}
    if hi - lo >= 0.02:
        G = gaussian_features(q, np.linspace(lo, hi, kernels), (hi - lo) / (kernels - 1))
        out["load"] = np.hstack([np.column_stack([np.sin(q), np.cos(q)]), G])
        out["position_friction"] = np.sign(v)[:, None] * G
    S = speed_law_nuisance(prep, j, spread=True)
    if S is not None:
        out["speed"] = S
    out["inertia"] = np.column_stack([a * np.sign(v), a * np.abs(v), a * np.sin(q), a * np.cos(q)])
    out["jerk"] = np.gradient(jd.a, jd.t)[jd.rows][:, None]
    rev = reversal_columns(jd)
    if rev is not None:
        out["reversal"] = rev
    return out


#: Gaussian kernels in |qd| of :func:`filter_slope_columns`
FILTER_SLOPE_KERNELS = 6


def filter_slope_columns(prep, j, kernels: int = FILTER_SLOPE_KERNELS):
    """Columns (at the joint's used rows) of the derivative filter's velocity error passed through a friction curve
    whose slope changes with the speed: the jerk (the filter's error in qd grows with it, as the ``jerk`` block of
    :func:`state_blocks` has it) times ``kernels`` Gaussians exp(-(qd/c_k)^2) in |qd|, alone and times sign(qd), the
    c_k log spaced from the 2 % to the 98 % quantile of the training speeds.  With Coulomb and viscous friction the
    slope is the constant kv and the jerk alone carries the error; beside a Stribeck law the slope is steep at low
    speed and flat at high speed, and the error with it (the hundred-and-first round,
    :func:`~drake_est.diagnose.core.rescue_explained_by_filter_slope`).  None when the training speeds span no range."""
    jd = prep.joints[j]
    v = jd.v[jd.rows]
    av = np.abs(v)
    lo, hi = np.quantile(av[jd.train], [0.02, 0.98])
    if not (lo > 0 and hi > lo):
        return None
    K = np.exp(-(av[:, None] / np.geomspace(lo, hi, kernels)[None, :]) ** 2)
    jerk = np.gradient(jd.a, jd.t)[jd.rows]
    return np.hstack([jerk[:, None] * K, (jerk * np.sign(v))[:, None] * K])


#: time constants [s] of the transients after a reversal of the direction of motion (:func:`reversal_columns`)
REVERSAL_TIME_CONSTANTS_S = (0.05, 0.2, 1.0)


def reversal_columns(jd):
    """Columns (at the joint's used rows) of a torque transient after the last reversal of the direction of motion:
    exp(-(t - t_r) / tau) and the same times sign(qd), for each tau of :data:`REVERSAL_TIME_CONSTANTS_S` (t_r: the
    last zero crossing of qd before t over the whole log).  Backlash crossed at each reversal, or a presliding
    transient, repeats with the moves like a function of the state does, but of the state's recent history; None
    when the log has no reversal."""
    v = np.asarray(jd.v, float)
    t = np.asarray(jd.t, float)
    s = np.sign(v)
    nz = np.flatnonzero(s != 0)
    if nz.size < 2:
        return None
    flips = nz[1:][s[nz[1:]] != s[nz[:-1]]]
    if flips.size == 0:
        return None
    last = np.searchsorted(flips, np.arange(v.size), side="right") - 1
    since = np.where(last >= 0, t - t[flips[np.clip(last, 0, None)]], np.inf)[jd.rows]
    sv = s[jd.rows]
    cols = []
    for tau in REVERSAL_TIME_CONSTANTS_S:
        e = np.exp(-since / tau)
        cols += [e, e * sv]
    return np.column_stack(cols)


def state_nuisance(prep, model, j, kernels: int = STATE_KERNELS, solve=None, without=(), chosen=None, rows=None,
                   extra=None, after=None):
    """Columns (at the joint's used rows) of a free function of the state of joint ``j`` that predicts its held-out
    residual: the blocks of :func:`state_blocks` joined one at a time, each time the one that lowers the held-out
    error of the model most (fitted on the training rows), while one does.  Blocks that overlap (the kernels times
    sign(qd) and the speed curve of each direction both span one level per direction) or that a few samples decide
    (the jerk) can raise the held-out error together where each alone lowers it, and a nuisance that predicts worse
    than the model makes any candidate look good given it (loop spec 5775: all blocks at once raised the held-out
    RMSE by 62 %); the forward choice keeps the nuisance a predictor, as :func:`periodic_nuisance` does.  No columns
    when no block lowers the held-out error (the candidate is then tested given the model alone).  ``without``: the
    names of blocks left out; ``chosen``: a list the names of the blocks joined are appended to, in their order;
    ``rows`` = (fit rows, compared rows), boolean over the used rows, instead of the joint's training and held-out
    rows (as in :func:`_partial_test`); ``extra``: more blocks by name (e.g. :func:`filter_slope_columns`), offered
    after those of :func:`state_blocks`; ``after``: blocks by name offered the same way only once the others' choice
    is done, so that the columns chosen without them are all kept (the function's span only grows)."""
    solve = solve or _lstsq
    from drake_est.diagnose.nominal import nominal_names
    n0 = len(nominal_names(prep.robot_kind))
    jd = prep.joints[j]
    X = model.design_with_shared(j)
    unknown = sorted(set(without) - set(STATE_BLOCK_NAMES))
    if unknown:
        raise ValueError(f"state_nuisance: no state block named {', '.join(unknown)} "
                         f"(the blocks: {', '.join(STATE_BLOCK_NAMES)})")
    blocks = {k: B for k, B in state_blocks(prep, j, kernels).items() if k not in without}
    clash = sorted((set(extra or {}) | set(after or {})) & set(blocks))
    if clash:
        raise ValueError(f"state_nuisance: extra block {', '.join(clash)} is already a state block")
    blocks.update(extra or {})
    train, val = (jd.train, jd.val) if rows is None else rows
    best, _ = _fit_rss(X, jd.y, train, val, n0, solve)
    cols = []
    for offered in (blocks, dict(after or {})):
        while offered:
            # the blocks' trials at once (parallel.pmap), in the blocks' order
            trial = dict(zip(offered, pmap(lambda B: _fit_rss(np.hstack([X] + cols + [B]), jd.y, train, val, n0,
                                                              solve)[0], list(offered.values()))))
            k = min(trial, key=trial.get)
            if not trial[k] < best:
                break
            best = trial[k]
            cols.append(offered.pop(k))
            if chosen is not None:
                chosen.append(k)
    return np.hstack(cols) if cols else np.zeros((X.shape[0], 0))


def survives_state_law(prep, model, fit, ext, alpha: float, min_gain: float, nuisance=None, solve=None) -> dict:
    """Partial held-out F-test of a time-periodic candidate at a line of the motion (evidence ``at_motion_line_hz``,
    :func:`~drake_est.diagnose.detectors.time_periodic_at_motion_line`) given a free function of the state of its
    joint (:func:`state_nuisance`; ``nuisance``: its columns, default made here).  Every misfit
    g(q, qd, qdd) of the model repeats with the motion and so is periodic at
    the motion's lines; a disturbance from outside the axis does not follow the state, and a sinusoid in time that
    still predicts the held-out data given any such g is one.  ``{"significant": True, "skipped": ...}`` when it
    does not apply."""
    if ext.effect != "time_periodic_disturbance" or ext.shared or "at_motion_line_hz" not in ext.evidence:
        return {"significant": True, "skipped": "not a time-periodic candidate at a line of the motion"}
    N = state_nuisance(prep, model, ext.joint, solve=solve) if nuisance is None else nuisance
    return _partial_test(prep, model, ext.joint, N, ext.cols[ext.joint], alpha, min_gain, solve)


#: the share of its own held-out gain that a time-periodic candidate at a line of the motion must keep when fitted on
#: one half of the log and judged on the other's held-out rows (:func:`holds_across_halves`)
HALF_GAIN_SHARE = 0.5


def holds_across_halves(prep, model, ext, alpha: float, min_gain: float, own_gain: float, solve=None) -> dict:
    """Whether a time-periodic candidate at a line of the motion keeps its amplitude and phase over the log: its
    columns (with the model's) fitted on the training rows of one half of the log (split at the median time of the
    joint's used rows) must predict the held-out rows of the *other* half, both ways, each time significantly
    (held-out F-test at ``alpha``, gain >= ``min_gain``) and with at least :data:`HALF_GAIN_SHARE` of
    ``own_gain``, its held-out gain on the whole log.  A disturbance from outside the axis keeps its phase whatever
    the axis does; a misfit that follows the moves (backlash, a friction law's misfit, a step in time that a sinusoid
    fits in part) is periodic at the motion's lines only as long as the moves repeat, and point-to-point moves differ
    from one half of the log to the other (loop spec 1317: backlash at 50 Hz, gain 4.2 % on the whole log, 2.6 % and
    0.8 % across the halves; a slow disturbance keeps 76 % of its gain or more).  Returns the test with ``significant``
    and the two gains."""
    j = ext.joint
    jd = prep.joints[j]
    t = jd.t[jd.rows]
    C = ext.cols[j]
    none = np.zeros((C.shape[0], 0))
    n_cols = model.design_with_shared(j).shape[1] + C.shape[1]
    mid = float(np.median(t))
    gains, ok = [], True
    for first in (t < mid, t >= mid):
        tr, va = jd.train & first, jd.val & ~first
        if tr.sum() <= n_cols or va.sum() <= C.shape[1]:
            return {"significant": False, "half_gains": [], "too_few_rows": True}
        h = _partial_test(prep, model, j, none, C, alpha, min_gain, solve, rows=(tr, va))
        g = h["rmse_reduction"]
        gains.append(g)
        ok = ok and h["p_value"] < alpha and g >= min_gain and g >= HALF_GAIN_SHARE * own_gain
    return {"significant": bool(ok), "half_gains": gains}


#: (eighty-first round) a held-out row of the other half is compared by :func:`position_law_across_halves` only where
#: a training row of the fitted half lies within this share of that half's position range (a law of the position
#: predicts where it was seen, not beyond)
VISITED_SHARE = 0.01
#: ... and a direction of that comparison is judged only with at least this many such rows (and more than five per
#: column of the law); with fewer the log cannot tell and the law stands
VISITED_MIN_ROWS = 50


def visited_rows(q, fit_rows, compare_rows, share: float = VISITED_SHARE) -> np.ndarray:
    """``compare_rows`` (boolean over ``q``) where a position of ``fit_rows`` lies within ``share`` of the fitted
    rows' position range."""
    qf = np.sort(np.asarray(q, float)[fit_rows])
    out = np.asarray(compare_rows, bool).copy()
    if qf.size == 0:
        out[:] = False
        return out
    if qf.size == 1:
        return out & (q == qf[0])
    i = np.clip(np.searchsorted(qf, q), 1, qf.size - 1)
    d = np.minimum(np.abs(q - qf[i - 1]), np.abs(q - qf[i]))
    return out & (d <= share * float(qf[-1] - qf[0]))


def position_law_across_halves(prep, model, ext, alpha: float, min_gain: float, solve=None) -> dict:
    """Whether a single-joint law of the position ``ext`` predicts one half of the log from the other, where both
    halves visit the same positions: its columns (with the model's) fitted on the training rows of one half (split at
    the median time of the joint's used rows), judged on the held-out rows of the other half within
    :data:`VISITED_SHARE` of a fitted position (:func:`visited_rows`), both ways (partial held-out F-test at
    ``alpha``, gain >= ``min_gain``).  A friction level or load that changes with q is there whenever the axis passes
    q; a misfit that follows the moves (an elastic gear ringing after the same few point-to-point moves, fresh
    out-of-vocabulary spec 94 of ``benchmarks/bench_time_shift_null_rate.py``) is a law of the position only in the
    blocks around those moves.  Returns ``held`` (False only when both directions were judged and neither
    predicts), the gains and the rows compared."""
    j = ext.joint
    jd = prep.joints[j]
    t = jd.t[jd.rows]
    q = jd.q[jd.rows]
    C = ext.cols[j]
    none = np.zeros((C.shape[0], 0))
    n_cols = model.design_with_shared(j).shape[1] + C.shape[1]
    mid = float(np.median(t))
    gains, p_values, rows, predicts = [], [], [], []
    for first in (t < mid, t >= mid):
        tr = jd.train & first
        va = visited_rows(q, tr, jd.val & ~first)
        n = int(va.sum())
        rows.append(n)
        if tr.sum() <= n_cols or n < max(VISITED_MIN_ROWS, 5 * C.shape[1]):
            gains.append(None)
            p_values.append(None)
            continue
        h = _partial_test(prep, model, j, none, C, alpha, min_gain, solve, rows=(tr, va))
        gains.append(float(h["rmse_reduction"]))
        p_values.append(float(h["p_value"]))
        predicts.append(bool(h["p_value"] < alpha and h["rmse_reduction"] >= min_gain))
    both_judged = len(predicts) == 2
    return {"held": bool(any(predicts) or not both_judged), "half_gains": gains, "half_p_values": p_values,
            "rows_compared": rows, "both_judged": both_judged}


def law_confounded_with_time(prep, model, ext, periodic, periodic_test, alpha: float, min_gain: float, solve=None):
    """A law ``ext`` of the joint where a time-periodic candidate at a line of the motion (``periodic``) was set aside
    because a free function of the state explains it as well (``periodic_test``, :func:`survives_state_law`): when
    the law adds nothing to that sinusoid either (partial held-out F-test of its columns given the sinusoid's), the
    log cannot tell a law of the state from a disturbance in time (slow moves that pass each position at one time:
    position and time confounded), and the finding is ambiguous with ``time_periodic_disturbance``.  Returns None
    when the law is separated, else the reverse test, the set-aside's test and the frequency."""
    if ext.shared or ext.effect in PERIODIC_PAIR:
        return None
    j = ext.joint
    t = _partial_test(prep, model, j, periodic.cols[j], ext.cols[j], alpha, min_gain, solve)
    if t["significant"]:
        return None
    return {**_brief(t), "time_periodic_given_state": _brief(periodic_test),
            "frequency_hz": float(periodic.evidence["frequency_hz"]),
            "at_motion_line_hz": float(periodic.evidence["at_motion_line_hz"])}


def position_law_confounded(prep, model, fit, ext, alpha: float, min_gain: float, nuisance=None, solve=None):
    """A position law (:data:`POSITION_LAWS`: a friction level that changes with q, or a load) that a free friction
    curve of its joint explains as well: the partial held-out F-test of its columns given the curve is not
    significant.  The curve (:func:`speed_law_nuisance` with ``spread``) has knots at the training speeds'
    quantiles and spread in log-speed, so that its span holds a speed law's shape over the whole speed range, not
    only where most samples lie; a law in time (:func:`survives_speed_law`), which the curve sets aside rather than
    marks ambiguous, keeps the quantile knots alone.  When each position is passed at one speed (point-to-point
    moves), a friction level that changes with q and one that changes with |qd| give the same residual, e.g. the
    misfit of a Stribeck law of another shape; when each position is also passed in one direction, so do a load and a
    direction-dependent level (an asymmetric Coulomb friction; loop specs 2453 and 2662 at 10 Hz, where a load
    was named for an asymmetric level and for a Lorentzian Stribeck law).  Unlike a law in time the finding is not
    set aside (it may be the step that lets a later, smaller finding be seen); it is reported as ambiguous with
    ``stribeck`` (the vocabulary's speed law, of any shape), or with ``asymmetric_coulomb`` when a load is explained
    as well by one friction level per direction alone (``rival``).  Returns None when it does not apply or the
    finding is separated, else the reverse test (the curve given the position law), the forward one and the
    rival."""
    if ext.effect not in POSITION_LAWS or ext.shared:
        return None
    N = speed_law_nuisance(prep, ext.joint, spread=True) if nuisance is None else nuisance
    if N is None:
        return None
    t = _partial_test(prep, model, ext.joint, N, ext.cols[ext.joint], alpha, min_gain, solve)
    if t["significant"]:
        return None
    back = _partial_test(prep, model, ext.joint, ext.cols[ext.joint], N, alpha, min_gain, solve)
    out = {**_brief(back), "position_law_given_speed_law": _brief(t), "rival": "stribeck"}
    if ext.effect == "position_dependent_load":
        # the curve's simplest part: one level per direction (an asymmetric Coulomb friction); when that alone
        # explains the load as well, it is the rival, not a speed law
        jd = prep.joints[ext.joint]
        v = jd.v[jd.rows]
        level = np.column_stack([(v > 0).astype(float), (v < 0).astype(float)])
        t2 = _partial_test(prep, model, ext.joint, level, ext.cols[ext.joint], alpha, min_gain, solve)
        if not t2["significant"]:
            out["rival"] = "asymmetric_coulomb"
            out["position_law_given_direction_levels"] = _brief(t2)
    return out


def periodic_test_applies(ext, any_law: bool = False) -> bool:
    """Whether :func:`survives_periodic` tests ``ext``: a joint's own smooth speed/time law (:data:`CONFOUNDABLE`), or
    with ``any_law`` any of its own candidates that is not itself periodic (:data:`PERIODIC_PAIR`)."""
    if ext.shared:
        return False
    return ext.effect not in PERIODIC_PAIR if any_law else ext.effect in CONFOUNDABLE


def survives_periodic(prep, model, fit, ext, alpha: float, min_gain: float, nuisance=None, solve=None,
                      any_law: bool = False) -> dict:
    """Partial held-out F-test of ``ext`` given the periodic nuisance of its joint (module docstring).

    ``solve(A, y, n_unpenalized)``: the least-squares solver of the search (the diagnosis passes its small
    relative ridge on the extension columns, Eq. (6.8)); default plain least squares.  ``any_law``: test any
    candidate that is not itself periodic (:data:`PERIODIC_PAIR`), not only the smooth speed/time laws of
    :data:`CONFOUNDABLE` (the search asks it of every candidate ranked below one the periodic residual explained).
    ``nuisance``: the columns of :func:`periodic_nuisance` for ``ext``'s joint and floor
    (:func:`nuisance_periods` of its law); default made here.
    Returns the test dict (``significant``: the candidate still explains held-out variance beyond the
    periodic alternative); ``{"significant": True, "skipped": ...}`` when it does not apply."""
    if not periodic_test_applies(ext, any_law):
        return {"significant": True, "skipped": "not a smooth speed/time law"}
    N = periodic_nuisance(prep, model, fit, ext.joint, nuisance_periods(ext.effect)) if nuisance is None else nuisance
    if N is None:
        return {"significant": True, "skipped": "no periodic structure in the residual"}
    return _partial_test(prep, model, ext.joint, N, ext.cols[ext.joint], alpha, min_gain, solve)


def _brief(t) -> dict:
    """The p-value, RMSE reduction and score of a partial test (:func:`_partial_test`), as reported."""
    return {k: t[k] for k in ("p_value", "rmse_reduction", "score")}


def _partial_test(prep, model, j, N, C, alpha, min_gain, solve=None, weights=None, offset=None,
                  coef: bool = False, rows=None) -> dict:
    """Held-out partial F-test of the columns ``C`` of joint ``j`` given the model and the nuisance columns ``N``
    (fitted on the training rows, compared on the validation rows of the joint; ``rows`` = (fit rows, compared
    rows), boolean over the used rows, instead); with ``weights`` (one per used row)
    weighted least squares and weighted held-out sums of squares; with ``offset`` (one per used row) a known part of
    the torque taken off it first; with ``coef`` also the coefficients of the fit with ``C`` (``"coef"``: model,
    nuisance, then ``C``'s columns)."""
    from drake_est.diagnose.nominal import nominal_names
    solve = solve or _lstsq
    n_nominal = len(nominal_names(prep.robot_kind))
    jd = prep.joints[j]
    X = model.design_with_shared(j)
    A0 = np.hstack([X, N])
    A1 = np.hstack([A0, C])
    y = jd.y if offset is None else jd.y - np.asarray(offset, float)
    if weights is not None:
        sw = np.sqrt(np.asarray(weights, float))
        A0, A1, y = A0 * sw[:, None], A1 * sw[:, None], y * sw
    train, val = (jd.train, jd.val) if rows is None else rows
    rss0, _ = _fit_rss(A0, y, train, val, n_nominal, solve)
    rss1, c1 = _fit_rss(A1, y, train, val, n_nominal, solve)
    n = int(val.sum())
    d = C.shape[1]
    F = ((rss0 - rss1) / d) / (rss1 / max(n - d, 1)) if rss1 > 0 else np.inf   # exact fit: rss1 = 0
    p = float(scipy.stats.f.sf(F, d, max(n - d, 1))) if F > 0 else 1.0
    gain = 1.0 - np.sqrt(rss1 / rss0) if rss0 > 0 else 0.0
    score = float(n * np.log(rss0 / max(rss1, 1e-300)) - 2 * d)
    out = {"F": float(F), "p_value": p, "rmse_reduction": float(gain), "score": score,
           "nuisance_columns": int(N.shape[1]),
           "significant": bool(p < alpha and gain >= min_gain and score > 0)}
    if coef:
        out["coef"] = c1
    return out


#: the held-out blocks of a paired comparison are pooled into at most this many contiguous groups (the
#: independent units of :func:`paired_block_test`; residuals are correlated over a block or two)
PAIRED_GROUPS = 20


def _group_diffs(prep, fit_a, fit_b, joints, loss: str = "squared") -> list:
    """Per joint of ``joints``: (joint, group of each held-out sample, per-group ``sum e_a^2 - sum e_b^2`` scaled by
    ``fit_a``'s held-out variance) over at most :data:`PAIRED_GROUPS` groups of contiguous validation blocks (the
    units of :func:`paired_block_test` and :func:`gain_concentration`); ``loss="absolute"``: ``sum |e_a| - sum
    |e_b|`` scaled by ``fit_a``'s held-out mean absolute error."""
    if loss not in ("squared", "absolute"):
        raise ValueError(f"loss must be 'squared' or 'absolute', got {loss!r}")
    from drake_est.diagnose.nominal import block_index

    out = []
    for j in joints:
        jd = prep.joints[j]
        val = jd.val
        ea = (jd.y - fit_a.pred[j])[val]
        eb = (jd.y - fit_b.pred[j])[val]
        blk = block_index(jd.t, jd.rows)[val]
        ub, inv = np.unique(blk, return_inverse=True)
        group = (inv * min(PAIRED_GROUPS, ub.size)) // ub.size
        if loss == "absolute":
            d = (np.abs(ea) - np.abs(eb)) / max(float(np.mean(np.abs(ea))), 1e-300)
        else:
            d = (ea ** 2 - eb ** 2) / max(float(np.mean(ea ** 2)), 1e-300)
        out.append((j, group, np.bincount(group, weights=d)))
    return out


def paired_block_test(prep, fit_a, fit_b, joints, loss: str = "squared") -> dict:
    """Does ``fit_b`` predict the held-out data of ``joints`` better than ``fit_a`` beyond chance?  Two
    non-nested models (e.g. the same findings with one of two rival extensions) are compared by their squared
    errors paired over the held-out time blocks: per group of contiguous validation blocks (at most
    :data:`PAIRED_GROUPS` per joint, each joint's errors scaled by ``fit_a``'s held-out variance) the difference
    ``sum e_a^2 - sum e_b^2``; a one-sided Wilcoxon signed-rank test of these differences over the groups.  The
    groups, not the samples, are the independent units: a closed-loop residual is correlated within a move.
    ``loss="absolute"`` pairs the absolute errors instead (:func:`_group_diffs`): under heavy-tailed noise a few
    large errors carry a squared-error gain.  Returns ``{"statistic", "p_value", "groups", "groups_better"}`` (p = 1
    when fewer than 3 groups)."""
    diffs = [g for _, _, g in _group_diffs(prep, fit_a, fit_b, joints, loss)]
    d = np.concatenate(diffs) if diffs else np.zeros(0)
    if d.size < 3 or not np.any(d):
        return {"statistic": 0.0, "p_value": 1.0, "groups": int(d.size), "groups_better": 0}
    # Wilcoxon signed-rank (one-sided): the gain of a drift or a warm-up sits in a few groups, which a t-test's
    # variance would let outweigh a consistent sign elsewhere
    res = scipy.stats.wilcoxon(d, alternative="greater")
    return {"statistic": float(res.statistic), "p_value": float(res.pvalue), "groups": int(d.size),
            "groups_better": int(np.sum(d > 0))}


#: a candidate's held-out gain is concentrated when at most this fraction of the paired groups holds ...
GAIN_FEW_GROUPS = 0.25
#: ... this share of its summed gain (the groups where it predicts better, :func:`gain_concentration`)
GAIN_SHARE = 0.8


def groups_needed(n_groups: int, alpha: float = 0.05) -> int | None:
    """The fewest of ``n_groups`` paired groups that must show a gain for :func:`paired_block_test` to reach
    ``alpha`` when those gains are the largest differences and every other group loses a little (the best case
    of a gain confined to some groups): the one-sided Wilcoxon signed-rank p of m top ranks.  None when even all
    groups would not do."""
    for m in range(1, n_groups + 1):
        d = np.concatenate([-np.arange(1.0, n_groups - m + 1), np.arange(n_groups - m + 1.0, n_groups + 1.0)])
        if float(scipy.stats.wilcoxon(d, alternative="greater").pvalue) < alpha:
            return m
    return None


def _conditions(jd, mask) -> dict:
    """Direction, speed and position of joint ``jd``'s held-out samples in ``mask``."""
    v = jd.v[jd.rows][jd.val][mask]
    q = jd.q[jd.rows][jd.val][mask]
    if v.size == 0:
        return {}
    return {"samples": int(v.size), "positive_direction_share": float(np.mean(v > 0)),
            "median_speed": float(np.median(np.abs(v))),
            "position_range": [float(np.quantile(q, 0.05)), float(np.quantile(q, 0.95))]}


def gain_concentration(prep, fit_a, fit_b, joints, alpha: float = 0.05) -> dict | None:
    """Where ``fit_b``'s held-out gain over ``fit_a`` lies when it sits in a few of the paired groups
    (:func:`paired_block_test`): at most :data:`GAIN_FEW_GROUPS` of the groups hold :data:`GAIN_SHARE` of the summed
    gain, and the gain over all groups is positive.  Such a candidate predicts the stretches where the log excites it
    much better and the rest no better, and the paired test cannot confirm it from so few units: the log does not
    repeat what would decide.  Returns the groups, the time stretches [s] that hold the gain, the direction, speed
    and position of each joint there and elsewhere, the number of groups the gain must reach
    (:func:`groups_needed`) and every group's span [s] and gain (``group_gains``: ``sum e_a^2 - sum e_b^2`` over
    its held-out samples in units of ``fit_a``'s held-out mean square); None when the gain is not concentrated."""
    parts = _group_diffs(prep, fit_a, fit_b, joints)
    units = [(j, g, float(x)) for j, _, gg in parts for g, x in enumerate(gg)]
    if len(units) < 3:
        return None
    d = np.array([u[2] for u in units])
    pos = np.sort(d[d > 0])[::-1]
    if d.sum() <= 0 or pos.size == 0:
        return None
    k = int(np.searchsorted(np.cumsum(pos), GAIN_SHARE * pos.sum()) + 1)
    if k > GAIN_FEW_GROUPS * len(units):
        return None
    top = sorted(np.argsort(-d, kind="stable")[:k])
    stretches, cond, per_group = [], {}, []
    for j, group, gg in parts:
        jd = prep.joints[j]
        t_all = jd.t[jd.rows][jd.val]
        for g, x in enumerate(gg):
            tg = t_all[group == g]
            per_group.append({"joint": int(j), "t_s": [float(tg.min()), float(tg.max())], "gain": float(x)})
        gains = sorted(units[i][1] for i in top if units[i][0] == j)
        if not gains:
            continue
        t = jd.t[jd.rows][jd.val]
        run = [gains[0]]
        for g in gains[1:] + [None]:
            if g is not None and g == run[-1] + 1:
                run.append(g)
                continue
            m = (group >= run[0]) & (group <= run[-1])
            stretches.append({"joint": int(j), "t_s": [float(t[m].min()), float(t[m].max())]})
            if g is not None:
                run = [g]
        inside = np.isin(group, gains)
        cond[str(j)] = {"in_gain_groups": _conditions(jd, inside), "elsewhere": _conditions(jd, ~inside)}
    return {"groups": len(units), "groups_holding_gain": k, "share_of_gain": float(d[top].clip(min=0).sum() / pos.sum()),
            "stretches": stretches, "conditions": cond, "groups_needed": groups_needed(len(units), alpha),
            "group_gains": per_group}
