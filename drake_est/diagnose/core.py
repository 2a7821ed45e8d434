"""The iterative diagnosis: nominal model -> candidate extensions -> held-out test -> repeat.

1. :func:`~drake_est.diagnose.nominal.prepare` selects samples (9.9), screens outliers and splits
   the log into alternating time blocks (even: training, odd: validation).
2. The nominal model (rigid body + symmetric Coulomb/viscous (9.2)) is fitted on the training part.
3. For every excited joint, every detector of :mod:`~drake_est.diagnose.detectors` proposes an
   extension from the *training* residual.  Each is refitted jointly with the current model on the
   training part and judged on the validation part by an F-test on the held-out residual sums of
   squares, F = ((RSS0 - RSS1) / d) / (RSS1 / (n - d)), together with a minimum relative RMSE
   reduction.  Among the significant ones the one with the largest held-out log-likelihood gain
   minus an AIC penalty, n log(RSS0 / RSS1) - 2 d, is accepted.
4. Repeat with the remaining candidates on the remaining residual until none is significant.
"""
from __future__ import annotations

import collections
import copy
import time
from dataclasses import dataclass, field

import numpy as np

import scipy.linalg
import scipy.stats

import drake_est.diagnose.competition as comp
import drake_est.diagnose.detectors as det
from drake_est.diagnose.quantization import torque_step  # noqa: F401  (re-exported)
from drake_est.diagnose.multilog import energy_fn, log_ids, per_log_offsets
from drake_est.diagnose.parallel import diagnosis_threads, pmap
from drake_est.diagnose.nominal import (EXTRAPOLATION_FACTOR, block_index, faster_than_training, joint_tau_step,
                                        nominal_columns, nominal_names, prepare, screen_outliers)
from drake_est.metrics import metrics_table
from drake_est.regression import ridge_solve, scaled_cholesky_solve

ALPHA = 1e-4          # significance level of the held-out F-test
MIN_GAIN = 0.02       # minimum relative reduction of the held-out RMSE of the affected joint(s)
MAX_FINDINGS = 6
#: periodic components the ripple candidate may hold (a cogging has several harmonics, e.g. 7, 14, 28 and 36
#: per revolution on the ODrive motor; weak ones are dropped by the detector)
RIPPLE_COMPONENTS = 4
#: a finding whose held-out score (log-likelihood gain minus AIC penalty) beats a significant competing
#: explanation of the same joint(s) by less than this is reported "ambiguous between A and B"
AMBIGUITY_MARGIN = 10.0


@dataclass
class Fit:
    pred: dict            # joint -> prediction of y at the joint's used rows
    coef: dict            # joint -> own coefficients (nominal first, then own extensions in order)
    shared: dict          # effect -> shared coefficients
    rss_val: dict         # joint -> validation RSS
    n_params: int
    per_log: dict = field(default_factory=dict)   # joint -> {log: [dkv, dkc]} (several logs, multilog.py)
    kv_held: set = field(default_factory=set)     # joints whose viscous coefficient is held at 0 (solve_kv_nonneg)


N_NOMINAL = 2          # nominal columns per joint [qd, sign(qd)], never penalized
RIDGE = 1e-4           # relative ridge on extension columns (times each column's energy)
#: inertia backfit of generic axes: a correction dJ is applied when |dJ| exceeds this many standard errors ...
INERTIA_BACKFIT_Z = 5.0
#: ... and this fraction of J
INERTIA_BACKFIT_REL = 0.05
#: a correction that changes J by more than this factor, or leaves J <= 0, must not be contradicted by the same
#: estimate beside a free friction curve of the speed (:func:`inertia_move_contradicted`)
INERTIA_BACKFIT_LARGE = 2.0
#: a correction that would move a positive J to J <= 0 is withheld (:func:`backfit_inertia`; seventy-fifth round)
INERTIA_BACKFIT_KEEPS_SIGN = True


def _ridge_lstsq(A, y, penalize):
    """Least squares with a small relative ridge on the extension columns (Eq. (6.8)).

    ``penalize``: number of leading unpenalized columns, or a boolean mask of penalized columns.
    The penalty RIDGE * ||A_k||^2 on column k (:func:`drake_est.regression.ridge_solve` with
    ``column_scaled=True``) keeps near-collinear extensions (e.g. periodic columns over few
    discrete speed levels) from trading huge coefficients against the nominal Coulomb/viscous ones."""
    p = A.shape[1]
    if isinstance(penalize, (int, np.integer)):
        mask = np.arange(p) >= penalize
    else:
        mask = np.asarray(penalize, bool)
    return ridge_solve(A, y, RIDGE, mask.astype(float), column_scaled=True, normal_equations=True)


def solve_kv_nonneg(solve, A, y, kv_cols=(0,)):
    """``solve(A, y)`` with the viscous coefficients at ``kv_cols`` kept >= 0 (a viscous friction does not
    decrease with speed, Sec. 9.1).  Unconstrained first; the columns whose coefficient comes out negative are
    fixed at zero and the rest solved again (the exact constrained optimum for one such column, the convex
    problem's minimum lies on its bound).  A friction that falls with speed over the whole selected range is
    then left in the residual, where only a speed law of the vocabulary (Stribeck) can take it; fitted as a
    negative kv it was absorbed instead by whatever correlates with speed (an energy state, a change of the
    speed profile).  Returns (coefficients, set of the columns held at zero)."""
    c = solve(A, y)
    keep = np.ones(A.shape[1], bool)
    held = set()
    # the columns whose coefficient comes out negative are held at zero and the rest solved again, until none is
    # negative (at most one pass per constrained column; the Stribeck basis' coefficients are held the same way)
    for _ in range(len(kv_cols)):
        neg = [i for i in kv_cols if keep[i] and c[i] < 0]
        if not neg:
            break
        keep[neg] = False
        held |= set(neg)
        c = np.zeros(A.shape[1])
        c[keep] = solve(A[:, keep], y, keep)
    return c, held


def _lstsq_kv(A, y, nonneg=(0,)):
    """Least squares with the columns ``nonneg`` >= 0 (kv, column 0, and an accepted Stribeck basis): the
    candidates' inner fits."""
    return solve_kv_nonneg(lambda A_, y_, keep=None: np.linalg.lstsq(A_, y_, rcond=None)[0], A, y, nonneg)[0]


#: the normal equations of :class:`InnerFits` are used while the scaled Gram matrix' Cholesky factor has a
#: diagonal ratio above this (condition number below ~1e10); least squares on the rows otherwise
GRAM_MIN_DIAG_RATIO = 1e-5


class InnerFits:
    """The candidates' trial fits of ``[X, C]`` for many column blocks ``C`` against one fixed model ``X`` (the
    detectors' inner-split and training-set errors): least squares by the normal equations, with ``X``'s Gram
    matrix formed once, so a trial costs O(n k (p + k)) for k candidate columns instead of a factorization of the
    n x (p + k) rows.  The columns are scaled to unit norm before the Cholesky factorization; when the scaled
    Gram matrix is too ill-conditioned (:data:`GRAM_MIN_DIAG_RATIO`) the trial falls back to least squares on the
    rows (as :func:`_lstsq_kv`), which the normal equations otherwise reproduce to rounding.  The columns ``nonneg`` (kv and an
    accepted Stribeck basis) are kept >= 0 as in :func:`solve_kv_nonneg`.

    ``fit_rows``: mask of the rows fitted; ``err_rows``: mask of the rows whose error is returned (the fitted
    ones when None)."""

    def __init__(self, X, y, fit_rows, err_rows=None, nonneg=(0,)):
        self.fit_rows = fit_rows
        self.err_rows = err_rows
        # the rows as indices, taken once: a trial selects its columns' rows with ``take`` (the same numbers as the
        # boolean masks, several times faster on ~10^4 of ~4.5 x 10^4 rows; thousands of trials a diagnosis)
        self._fit_idx = np.flatnonzero(fit_rows)
        self._err_idx = None if err_rows is None else np.flatnonzero(err_rows)
        self.Xa, self.ya = X[fit_rows], y[fit_rows]
        self.Gxx = self.Xa.T @ self.Xa
        self.gx = self.Xa.T @ self.ya
        if err_rows is not None:
            self.Xb, self.yb = X[err_rows], y[err_rows]
        self.nonneg = tuple(nonneg)
        self.p = X.shape[1]

    def _solve(self, G, g):
        return scaled_cholesky_solve(G, g, GRAM_MIN_DIAG_RATIO)

    def coef(self, C, nonneg=False):
        """Coefficients of ``[X, C]`` on the fitted rows (``nonneg``: C's coefficients kept >= 0 too)."""
        return self._coef(C.take(self._fit_idx, axis=0), nonneg)

    def _coef(self, Ca, nonneg=False):
        p, k = self.p, Ca.shape[1]
        G = np.empty((p + k, p + k))
        G[:p, :p] = self.Gxx
        G[p:, :p] = Ca.T @ self.Xa
        G[:p, p:] = G[p:, :p].T
        G[p:, p:] = Ca.T @ Ca
        g = np.concatenate([self.gx, Ca.T @ self.ya])
        nn = self.nonneg + (tuple(range(p, p + k)) if nonneg else ())

        def solve(_A, _y, keep=None):
            if keep is None:
                c = self._solve(G, g)
            else:
                c = self._solve(G[np.ix_(keep, keep)], g[keep])
            if c is None:
                A = np.hstack([self.Xa, Ca])
                A = A if keep is None else A[:, keep]
                c = np.linalg.lstsq(A, self.ya, rcond=None)[0]
            return c

        return solve_kv_nonneg(solve, G, g, nn)[0]

    def error(self, C, nonneg=False):
        """Sum of squared errors of ``[X, C]`` on the error rows."""
        Ca = C.take(self._fit_idx, axis=0)
        c = self._coef(Ca, nonneg)
        if self.err_rows is None:
            e = self.ya - self.Xa @ c[:self.p] - Ca @ c[self.p:]
        else:
            e = self.yb - self.Xb @ c[:self.p] - C.take(self._err_idx, axis=0) @ c[self.p:]
        return float(e @ e), c


class Model:
    """Nominal model plus accepted extensions, fitted by (weighted, stacked) least squares; the viscous
    coefficients are kept >= 0 (:func:`solve_kv_nonneg`)."""

    def __init__(self, prep, exts=()):
        self.prep = prep
        self.exts = list(exts)

    def own(self, j):
        return [e for e in self.exts if not e.shared and j in e.cols]

    def shared_exts(self):
        return [e for e in self.exts if e.shared]

    def design(self, j, extra=None):
        jd = self.prep.joints[j]
        blocks = [nominal_columns(jd, self.prep.robot_kind)] + [e.cols[j] for e in self.own(j)]
        if extra is not None:
            blocks.append(extra)
        return np.hstack(blocks)

    def design_with_shared(self, j):
        """:meth:`design` of joint ``j`` with the columns of the shared (several-joint) extensions after it."""
        X = self.design(j)
        shared = self.shared_exts()
        return np.hstack([X] + [e.cols[j] for e in shared]) if shared else X

    def penalized(self, j) -> np.ndarray:
        """Which columns of :meth:`design` carry the ridge: not the nominal ones, and not the gravity/spring
        harmonics sin q, cos q of a position-dependent load (physical, well conditioned columns whose
        coefficient may be hundreds of times the noise, where a relative ridge would leave a visible error)."""
        mask = [np.zeros(N_NOMINAL, bool)]
        for e in self.own(j):
            m = np.ones(e.cols[j].shape[1], bool)
            if e.spec.get("gravity_harmonic"):
                m[:2] = False
            mask.append(m)
        return np.concatenate(mask)

    def nonneg(self, j) -> list:
        """Columns of :meth:`design` whose coefficients are kept >= 0: kv (a viscous friction does not fall with
        speed) and the Stribeck coefficients, ks of the law or those of a basis in |qd| (a nonnegative mixture: the
        Stribeck effect is a friction *excess* that falls with speed from standstill, Sec. 9.1; a negative ks would
        be friction rising with speed, what a viscous term is for, :func:`~drake_est.diagnose.detectors.stribeck`)."""
        out, k = [0], N_NOMINAL
        for e in self.own(j):
            if e.effect == "stribeck":
                out += list(range(k, k + e.n_params))
            k += e.n_params
        return out

    def coef_slices(self, fit, j) -> dict:
        """The coefficients of joint ``j`` in ``fit`` by part: ``{"nominal": {name: value}, effect: array}`` (own
        extensions in the order of :meth:`design`)."""
        names = nominal_names(self.prep.robot_kind)
        c = fit.coef[j]
        out = {"nominal": dict(zip(names, c[:len(names)]))}
        k = len(names)
        for e in self.own(j):
            out[e.effect] = c[k:k + e.n_params]
            k += e.n_params
        return out

    def fit(self, sigma=None) -> Fit:
        prep = self.prep
        shared = self.shared_exts()
        pred, coef, rss = {}, {}, {}
        n_params = 0
        shared_coef = {}
        kv_held = set()
        if not shared:
            for j, jd in prep.joints.items():
                X = self.design(j)
                pen = self.penalized(j)
                c, held = solve_kv_nonneg(lambda A, y, keep=None, pen=pen: _ridge_lstsq(
                    A, y, pen if keep is None else pen[keep]), X[jd.train], jd.y[jd.train], self.nonneg(j))
                if 0 in held:
                    kv_held.add(j)
                coef[j] = c
                pred[j] = X @ c
                n_params += X.shape[1]
        else:
            js = list(prep.joints)
            own = {j: self.design(j) for j in js}
            S = [np.hstack([e.cols[j] for e in shared]) for j in js]
            ds = S[0].shape[1]
            offs = np.cumsum([0] + [own[j].shape[1] for j in js])
            P = int(offs[-1]) + ds
            rows_A, rows_y = [], []
            for k, j in enumerate(js):
                jd = prep.joints[j]
                w = 1.0 / (sigma[j] if sigma else 1.0)
                A = np.zeros((int(jd.train.sum()), P))
                A[:, offs[k]:offs[k + 1]] = own[j][jd.train]
                A[:, offs[-1]:] = S[k][jd.train]
                rows_A.append(w * A)
                rows_y.append(w * jd.y[jd.train])
            A = np.vstack(rows_A)
            pen = np.ones(P, dtype=bool)
            for k, j in enumerate(js):
                pen[offs[k]:offs[k + 1]] = self.penalized(j)
            nn = [int(offs[k]) + i for k, j in enumerate(js) for i in self.nonneg(j)]
            c, held = solve_kv_nonneg(lambda A_, y_, keep=None: _ridge_lstsq(A_, y_, pen if keep is None else pen[keep]),
                                      A, np.concatenate(rows_y), nn)
            kv_held |= {js[list(offs[:-1]).index(i)] for i in held if i in offs[:-1]}
            for k, j in enumerate(js):
                coef[j] = c[offs[k]:offs[k + 1]]
                pred[j] = own[j] @ coef[j] + S[k] @ c[offs[-1]:]
            i = int(offs[-1])
            for e in shared:
                shared_coef[e.effect] = c[i:i + e.n_params]
                i += e.n_params
            n_params = P
        per_log = {}
        for j, jd in prep.joints.items():
            ids = log_ids(prep, jd)
            if ids is not None:     # several logs: per-log Coulomb/viscous offsets (temperature), multilog.py
                pred[j], per_log[j] = per_log_offsets(jd, ids, pred[j])
            e = (jd.y - pred[j])[jd.val]
            rss[j] = float(e @ e)
        return Fit(pred, coef, shared_coef, rss, n_params, per_log, kv_held)


def _val_metrics(prep, fit, joints=None):
    joints = list(prep.joints) if joints is None else list(joints)
    y = np.concatenate([prep.joints[j].tau[prep.joints[j].rows][prep.joints[j].val] for j in joints])
    yh = np.concatenate([(prep.joints[j].rb[prep.joints[j].rows] + fit.pred[j])[prep.joints[j].val]
                         for j in joints])
    return metrics_table(y, yh, fit.n_params)


def _residual(prep, fit, j):
    jd = prep.joints[j]
    return jd.y - fit.pred[j]


def _energy_cols(model, j):
    """The columns of joint ``j``'s accepted energy-dependent friction, None when there is none."""
    for e in model.own(j):
        if e.effect == "energy_dependent_friction":
            return e.cols[j]
    return None


def _inner_fits(model, jd, X=None) -> "InnerFits":
    """The detectors' inner split of joint ``jd``'s training rows (fit on blocks 0 mod 4, error on blocks 2 mod 4)
    against ``model`` (its design ``X`` when already built)."""
    X = model.design_with_shared(jd.joint) if X is None else X
    block = block_index(jd.t, jd.rows)
    return InnerFits(X, jd.y, jd.train & (block % 4 == 0), jd.train & (block % 4 == 2), model.nonneg(jd.joint))


def _train_error_fn(model, jd, X=None):
    """``fit_train(C)``: the training error of ``model`` (its design ``X`` for joint ``jd`` when already built) plus
    columns C, and C's coefficients (the energy detector's variable projection)."""
    X = model.design_with_shared(jd.joint) if X is None else X
    train = InnerFits(X, jd.y, jd.train, None, model.nonneg(jd.joint))

    def fit_train(C, train=train):
        """Training error of the model plus columns C and C's coefficients."""
        err, c = train.error(C)
        return err, c[train.p:]
    return fit_train


def _nominal_friction(prep, fit, jd):
    """kv qd + kc sign(qd) of joint ``jd`` with ``fit``'s nominal coefficients: the friction whose power drives the
    energy state (Algorithm 6's first W)."""
    cj = fit.coef[jd.joint]
    names = nominal_names(prep.robot_kind)
    return cj[names.index("kv")] * jd.v + cj[names.index("kc")] * np.sign(jd.v)


def _candidates(prep, model, fit, accepted, cache=None, changed=None):
    """All extensions proposed for the current residual (not yet accepted ones). ``cache``: joint ->
    proposals from the previous round, reused for joints whose model did not change."""
    out = []
    for j, jd in prep.joints.items():
        if cache is not None and changed is not None and j not in changed and j in cache:
            out += [e for e in cache[j] if (e.effect, j) not in accepted]
            continue
        start = len(out)
        calls = []      # the detectors, run at once (parallel.pmap) in this order
        longest = None
        r = _residual(prep, fit, j)
        X = model.design_with_shared(j)
        inner = _inner_fits(model, jd, X)
        fit_train = _train_error_fn(model, jd, X)

        def fit_inner(C, nonneg=False, inner=inner):
            """Inner-split error of the model plus columns C (``nonneg``: C's coefficients kept >= 0 too)."""
            return inner.error(C, nonneg)[0]

        def have(effect, j=j):
            return (effect, j) in accepted

        if not have("asymmetric_coulomb"):
            calls.append(lambda: det.asymmetric(jd, r))
        if not have("position_dependent_friction"):
            calls.append(lambda: det.position_bfe(jd, r, None, fit_inner))
        if prep.robot is None and not have("position_dependent_load"):
            calls.append(lambda: det.position_load(jd, r, fit_inner))
        if not have("motor_position_ripple"):
            longest = len(calls)        # the ripple's scan: the longest detector, started first
            calls.append(lambda: det.ripple(jd, r, n_components=RIPPLE_COMPONENTS, fit_inner=fit_inner))
        if not have("energy_dependent_friction"):
            F_full = _nominal_friction(prep, fit, jd)
            calls.append(lambda: det.energy(jd, r, F_full, fit_train, energy_fn=energy_fn(prep)))
        if not have("abrupt_change"):
            ecols = _energy_cols(model, j)
            calls.append(lambda: det.change_point(jd, r, smooth_alternative=ecols is not None, energy_cols=ecols))
        if not have("stribeck"):
            calls.append(lambda: det.stribeck(jd, r, fit_inner, falling=j in fit.kv_held))
        if not have("time_periodic_disturbance"):
            calls.append(lambda: det.time_periodic(jd, r))
            # the whole scan's peak where it lies at a line of the motion (a slow disturbance under point-to-point
            # moves), on the joints where the nominal residual shows one (motion_line_gate): held against a free
            # function of the state in _round
            if j in prep.meta.get("motion_line_joints", ()):
                calls.append(lambda: at_line_refined(det.time_periodic_at_motion_line(jd, r), jd, r, X))
        if not have("gear_coupling") and len(prep.joints) > 1:
            calls.append(lambda: det.coupling(jd, r, prep))
        out += pmap(lambda f: f(), calls, first=[longest] if longest is not None else ())
        if cache is not None:
            cache[j] = [e for e in out[start:] if e is not None]
    if prep.robot is not None and ("payload", None) not in accepted:
        if "payload_ext" not in prep.meta:
            prep.meta["payload_ext"] = det.payload(prep)
        out.append(prep.meta["payload_ext"])
    return [c for c in out if c is not None]


def _test(prep, fit0, fit1, ext):
    js = list(ext.cols)
    n = int(sum(prep.joints[j].val.sum() for j in js))
    rss0 = sum(fit0.rss_val[j] for j in js)
    rss1 = sum(fit1.rss_val[j] for j in js)
    d = ext.n_params
    den = rss1 / max(n - d, 1)
    F = ((rss0 - rss1) / d) / den if den > 0 else (np.inf if rss0 > rss1 else 0.0)   # exact fit: rss1 = 0
    p = float(scipy.stats.f.sf(F, d, max(n - d, 1))) if F > 0 else 1.0
    gain = 1.0 - np.sqrt(rss1 / rss0) if rss0 > 0 else 0.0
    score = float(sum(prep.joints[j].val.sum() * np.log(fit0.rss_val[j] / max(fit1.rss_val[j], 1e-300))
                      for j in js) - 2 * d)
    return {"F": float(F), "p_value": p, "dof": [d, n - d], "rmse_reduction": float(gain), "score": score,
            "significant": bool(p < ALPHA and gain >= MIN_GAIN and score > 0)}


@dataclass
class Step:
    ext: object
    test: dict
    fit: object
    validation: dict
    validation_joint: dict
    competition: dict = field(default_factory=dict)


@dataclass
class DiagnosisResult:
    prep: object
    nominal_fit: object
    nominal_validation: dict
    nominal_validation_joint: dict
    steps: list
    final_fit: object
    final_model: object
    rejected: list
    timing: dict = field(default_factory=dict)
    sigma: dict = field(default_factory=dict)
    unexplained: list = field(default_factory=list)
    #: what every test of the final residual read, reported or not (:func:`~drake_est.diagnose.unexplained.test_readings`)
    structure_readings: list = field(default_factory=list)


def _above_quantization(prep, fit0, fit1, ext) -> bool:
    """Evidence beyond a coarse torque ADC.  A quantized torque (little noise before the ADC) carries a
    deterministic error e of at most half a step per sample that follows the torque level (e.g. one error
    per speed level), and a flexible extension can fit it.  Where the extension changes the held-out
    prediction by less than half a step it may be doing just that, so only the held-out samples where it
    changes the prediction by more (set S) count; there, fitting e alone lowers each squared residual by
    e^2 - (e - d)^2 <= e^2 <= (step / 2)^2.  The extension is evidence only when its held-out reduction on S
    exceeds that bound, |S| (step / 2)^2, with a z > 4 margin for the noise (a one-sided bound, not tuned)."""
    for j in ext.cols:
        jd = prep.joints[j]
        step = joint_tau_step(prep, j)
        if step > 0:
            d = (fit1.pred[j] - fit0.pred[j])[jd.val]
            S = np.abs(d) > 0.5 * step
            if S.sum() < max(20, 2 * ext.n_params):
                return False
            e0 = (jd.y - fit0.pred[j])[jd.val][S]
            e1 = (jd.y - fit1.pred[j])[jd.val][S]
            excess = e0 ** 2 - e1 ** 2 - (0.5 * step) ** 2
            if excess.mean() <= 4.0 * excess.std() / np.sqrt(S.sum()):
                return False
    return True


#: sixty-eighth round (tried, not kept) and sixty-ninth round (kept; see docs/readme/diagnose_testbench.md): a law of
#: the friction in time held back by the ADC guard (:func:`_above_quantization`) is judged by the likelihood of the
#: quantized readings instead, under the two conditions of :data:`TIME_LAW_RESCUE_CHECKS`
TIME_LAWS_BY_READINGS_LIKELIHOOD = True
#: the laws of the friction in time (the torque ADC's rounding error is a function of the torque level, hence of the
#: state at steady motion; these are functions of the time alone)
TIME_LAWS = ("energy_dependent_friction", "abrupt_change")
#: sixty-ninth round: a law in time is let past the guard by the readings only alone in time on its joint
#: and when it predicts the held-out residual given a free function of the joint's state
TIME_LAW_RESCUE_CHECKS = True


def time_law_beyond_rounding(prep, model, ext, alpha: float = ALPHA,
                             min_gain: float = None, why: dict | None = None) -> dict | None:
    """A law of the friction in time (:data:`TIME_LAWS`) that the ADC guard (:func:`_above_quantization`) holds back,
    judged by what the guard stands in for.  The guard assumes the worst: that the extension fits the rounding error
    e, at most half a step per sample, wherever it changes the prediction by less than half a step; a drift of the
    friction over minutes (Eq. (9.29)) changes it by less than that on every sample and is held back however strongly
    the held-out data favour it (closed-loop spec 103: a third-size energy drift at 50 Hz over 600 s, a 0.22 N m step,
    F = 903 and 9.8 % lower held-out RMSE, reported as "none").  The rounding error is a staircase of the torque
    level, a function of the state at steady motion; a law in time can take it only where the state drifts in time.
    The likelihood of the quantized readings themselves (:func:`rounding_loglik_gains`, each reading saying only that
    the torque lay within half a step of it) does not count the rounding as noise: the law is kept when its held-out
    gain there passes the likelihood-ratio bound of :func:`gain_within_rounding` (both gains).  Returns the gains
    (``heldout_loglik_gain``, ``heldout_loglik_gain_profiled``, ``rounding_lr_bound``) or None; ``why`` (a dict) gets
    ``rescue_explained_by_filter_slope`` (the law's test given the state's function) where the hundred-and-first
    round's check alone refused it (:func:`rescue_explained_by_filter_slope`)."""
    if ext.effect not in TIME_LAWS or ext.shared:
        return None
    if TIME_LAW_RESCUE_CHECKS and any(x is not ext and not x.shared and x.joint == ext.joint and x.effect in TIME_LAWS
                                      for x in model.exts):
        # a second law in time of the joint: below half a step it may take the misfit of the first one's shape (a
        # drift that is not the energy law's), which the readings cannot tell from a law of its own (loop spec 21435)
        return None
    min_gain = MIN_ROUNDING_LOGLIK_GAIN if min_gain is None else min_gain
    for e, info in rounding_loglik_gains(prep, model, only=ext):
        bound = rounding_lr_bound(info["finding_columns"], alpha)
        if info["heldout_loglik_gain"] >= min_gain and info["heldout_loglik_gain_profiled"] >= bound:
            if TIME_LAW_RESCUE_CHECKS:
                m0 = Model(prep, [x for x in model.exts if x is not ext])
                if _state_tests(prep, m0, ext.joint, ext.cols[ext.joint], alpha, MIN_GAIN) is not None:
                    # the guard's worry is a fit of the rounding error, a function of the state: the law must predict
                    # the held-out residual given a free function of the joint's state (loop specs 15992 and 11438,
                    # elastic gears: an abrupt change that given the state's function lowers the held-out RMSE by
                    # -0.04 % and -0.25 %)
                    return None
                refused = rescue_explained_by_filter_slope(prep, m0, ext, alpha)
                if refused is not None:
                    if why is not None:
                        why["rescue_explained_by_filter_slope"] = comp._brief(refused[1])
                    return None
            return {"heldout_loglik_gain": info["heldout_loglik_gain"],
                    "heldout_loglik_gain_profiled": info["heldout_loglik_gain_profiled"],
                    "rounding_lr_bound": bound, "adc_step": info["adc_step"],
                    "heldout_samples": info["heldout_samples"]}
    return None


#: hundred-and-first round: the rescue's check of a law in time against a free function of the joint's state
#: (:func:`time_law_beyond_rounding`) offers that function the derivative filter's error through the friction curve's
#: slope too where the joint's model holds a Stribeck law (:func:`rescue_explained_by_filter_slope`)
TIME_LAW_RESCUE_FILTER_SLOPE_RULE = True


def rescue_explained_by_filter_slope(prep, m0, ext, alpha: float = ALPHA) -> tuple | None:
    """With :data:`TIME_LAW_RESCUE_FILTER_SLOPE_RULE`, on a joint whose model ``m0`` (without the law in time ``ext``)
    holds a Stribeck law: whether the free function of the joint's state explains ``ext`` once it may also take the
    derivative filter's error through the friction curve's slope
    (:func:`~drake_est.diagnose.competition.filter_slope_columns`: the jerk times kernels in |qd|).  The filter's error
    in qd grows with the jerk; through Coulomb and viscous friction it reaches the torque times the constant kv (the
    state function's ``jerk`` block), through a Stribeck hump times a slope that is steep at low speed and flat at
    high speed, and where the log moves slowly in one part and fast in another a law in time takes that misfit below
    the torque ADC's step (fresh loop spec 36374: a load beside Stribeck at 1000 Hz with a quantized torque, an abrupt
    change held back by the ADC guard and let past by the readings' likelihood lowers the held-out RMSE by 4.8 %, by
    3.5 % given the state's function, by 0.7 % once the function may take the jerk through the slope; that function
    alone lowers it by 42 %).  Returns what :func:`_state_tests` returned with those columns offered, ``(N, the law's
    test given N, its own RMSE reduction, N's)`` (the law is then not let past the guard), else None: the rule off, no
    Stribeck law on the joint, no such columns, or the law still predicts the held-out residual."""
    if not TIME_LAW_RESCUE_FILTER_SLOPE_RULE or ext.shared:
        return None
    j = ext.joint
    if not any(e.effect == "stribeck" for e in m0.own(j)):
        return None
    F = comp.filter_slope_columns(prep, j)
    if F is None:
        return None
    return _state_tests(prep, m0, j, ext.cols[j], alpha, MIN_GAIN, extra={"filter_slope": F})


def _fit_of(results, ext):
    """The trial fit of candidate ``ext`` in a round's ``results``."""
    return next(f for e, _, f, _ in results if e is ext)


def held_back_rival_not_separated(prep, ext, tst, rival, rival_tst, results) -> float | None:
    """The paired p-value (:func:`~drake_est.diagnose.competition.paired_block_test`) of a round's winner ``ext``
    against a ``rival`` of its joint that scores more and failed only the paired block test (its held-out gain over
    the current model sits in a few blocks: ``not_separated_on_held_out_blocks``), when the winner does not predict
    the held-out blocks better than the rival either (p >= :data:`PAIRED_ALPHA`); None otherwise.  Then the rival's
    test, not the data, put the winner first, and the two stand side by side (:func:`_competition`; loop spec 28061: a
    position friction won its round over a Stribeck law that scored twice as much, whose paired p was 0.07, and the
    blocks did not show the friction predicting better than the Stribeck law, p = 0.31)."""
    if not rival_tst.get("not_separated_on_held_out_blocks") or rival_tst["score"] <= tst["score"]:
        return None
    joints = sorted(set(ext.cols) & set(rival.cols))
    if not joints:
        return None
    paired = comp.paired_block_test(prep, _fit_of(results, rival), _fit_of(results, ext), joints)
    return float(paired["p_value"]) if paired["p_value"] >= PAIRED_ALPHA else None


def _competition(ext, tst, results, prep=None) -> dict:
    """The runner-up among the competing explanations of the same residual (other effects on the same
    joint(s), judged on the same held-out data), the margin of the winner's score over it, and whether the
    evidence separates them (``ambiguous`` when a significant rival's score is within :data:`AMBIGUITY_MARGIN`,
    or, on a coarsely quantized torque, a simpler significant rival predicts within one quantization step).
    ``ambiguous_with``: every rival not separated that way, best first (the runner-up need not be one of them:
    a simpler rival further behind may predict as well to within the rounding of the torque).  With
    :data:`HELD_BACK_RIVALS`, a higher-scoring rival that only the paired block test held back joins them when the
    blocks do not show the winner predicting better than it (:func:`held_back_rival_not_separated`; its paired p under
    ``held_back_rivals_not_separated``)."""
    js = set(ext.cols)
    rivals = [(e, t) for e, t, _, _ in results if e is not ext and e.effect != ext.effect and js & set(e.cols)]
    if not rivals:
        return _time_confound(_speed_confound({"runner_up": None, "margin": None, "ambiguous": False}, tst), tst)
    rivals.sort(key=lambda r: -r[1]["score"])
    e2, t2 = rivals[0]
    margin = float(tst["score"] - t2["score"])
    out = {"runner_up": e2.effect, "runner_up_joint": int(e2.joint), "runner_up_score": float(t2["score"]),
           "runner_up_significant": bool(t2["significant"]), "margin": margin,
           "runner_up_rmse_reduction": None if t2.get("rmse_reduction") is None else float(t2["rmse_reduction"])}
    close, below_step, below_min_gain, held_back = [], False, {}, {}
    for e, t in rivals:
        if t.get("below_quantization_step") or (t.get("beyond_rounding_by_likelihood") and not t["significant"]):
            # (a law in time that the ADC guard held back and the readings' likelihood let through,
            # :func:`time_law_beyond_rounding`, but a later test did not: a rival as the guard left it)
            # a rival held back only by the quantization guard (its change of the prediction stays within half an
            # ADC step, _above_quantization) is still an explanation of the same residual: it stands beside the
            # winner when it is simpler and the winner does not beat it by the same guard (judged from the rival's
            # fit: what puts the winner ahead may be the rounding error), or when the held-out blocks do not
            # separate the two (competition.paired_block_test, as for the runner-up)
            if prep is None:
                continue
            fe, fw = _fit_of(results, e), _fit_of(results, ext)
            if e.n_params < ext.n_params and not _above_quantization(prep, fe, fw, ext):
                close.append(e.effect)
                below_step = True
            elif comp.paired_block_test(prep, fe, fw, sorted(js & set(e.cols)))["p_value"] >= PAIRED_ALPHA:
                close.append(e.effect)
            continue
        if HELD_BACK_RIVALS and prep is not None and t.get("not_separated_on_held_out_blocks"):
            p = held_back_rival_not_separated(prep, ext, tst, e, t, results)
            if p is not None:
                close.append(e.effect)
                held_back[e.effect] = p
                continue
        tie, sep = _tie(tst, t)
        if not t["significant"]:
            # a winner that is a constant torque while moving (an asymmetric Coulomb level) and a rival whose
            # model contains it (a position load: its kernels sum to a constant over the positions visited) that
            # predicts the held-out data within MIN_GAIN of it: both explain the same offset, the rival's F-test is
            # weaker for its shape's extra parameters, not its prediction, so the data do not name the cause of
            # the offset (the mirror of the twelfth round's load against one level per direction)
            if (prep is not None and sep is not None and sep < MIN_GAIN and _is_offset(prep, ext)
                    and _contains(prep, e, ext)):
                close.append(e.effect)
                below_min_gain[e.effect] = float(sep)
            continue
        if tie == "margin":
            close.append(e.effect)
        elif tie == "min_gain":
            # every finding must lower the held-out RMSE by MIN_GAIN; a rival that predicts within MIN_GAIN of the
            # winner's RMSE is not separated from it, however many samples make the score margin large (an
            # asymmetric Coulomb level is a constant torque while moving, and so is a position load that hardly
            # varies over the visited range)
            close.append(e.effect)
            below_min_gain[e.effect] = float(sep)
        elif prep is not None and _within_quantization_step(prep, ext, e, results):
            close.append(e.effect)
            below_step = True
    if prep is not None and t2["significant"] and e2.effect not in close:
        # the margin counts every held-out sample as independent; the winner must also predict the held-out blocks
        # better than the runner-up (competition.paired_block_test, as for a set-aside), else the order of two
        # scores that the blocks do not separate would name the cause
        f1, f2 = _fit_of(results, ext), _fit_of(results, e2)
        paired = comp.paired_block_test(prep, f2, f1, sorted(js & set(e2.cols)))
        out["paired_p_value"] = paired["p_value"]
        if paired["p_value"] >= PAIRED_ALPHA:
            close.insert(0, e2.effect)
            out["reason"] = (f"{e2.effect} scores {margin:.3g} lower, but the held-out blocks do not separate the two "
                             f"(paired p = {paired['p_value']:.2g})")
    out["ambiguous"] = bool(close)
    if close:
        out["ambiguous_with"] = close
    if below_step:
        out["separated_below_quantization_step"] = True
    if held_back:
        out["held_back_rivals_not_separated"] = held_back
        if "reason" not in out:
            name, p = next(iter(held_back.items()))
            out["reason"] = (f"{name} scores more but its gain over the model before this finding sits in a few "
                             f"held-out blocks; the held-out blocks do not show this finding predicting better than "
                             f"{name} either (paired p = {p:.2g})")
    if below_min_gain:
        out["separation_below_min_gain"] = below_min_gain
        if "reason" not in out:
            name, sep = next(iter(below_min_gain.items()))
            out["reason"] = (f"{name} predicts the held-out data of the round within {100 * sep:.2g} % of the RMSE "
                             f"(< {100 * MIN_GAIN:g} %, the gain every finding must show): not separated")
    return _time_confound(_speed_confound(out, tst), tst)


#: a rival contains the winner when, with the nominal columns, it reproduces the winner's columns on the training
#: rows to within this fraction of their norm (:func:`_contains`)
CONTAINS_TOL = 0.05


def _is_offset(prep, ext) -> bool:
    """Whether ``ext``'s columns are a constant torque while moving: within the span of the nominal [qd, sign(qd)]
    and a constant on the training rows (an asymmetric Coulomb level, 1[qd < 0])."""
    ones = {j: np.ones((C.shape[0], 1)) for j, C in ext.cols.items()}
    return _contains(prep, det.Extension("offset", ext.joint, ones, ["offset"], {}), ext)


def _contains(prep, rival, ext) -> bool:
    """Whether ``rival``'s columns, with the nominal [qd, sign(qd)], span ``ext``'s on the training rows of every
    joint ``ext`` acts on (relative residual of the least-squares fit below :data:`CONTAINS_TOL`)."""
    for j, C in ext.cols.items():
        if j not in rival.cols:
            return False
        jd = prep.joints[j]
        tr = jd.train
        A = np.hstack([nominal_columns(jd, prep.robot_kind), rival.cols[j]])[tr]
        B = np.asarray(C, float)[tr]
        nb = np.linalg.norm(B)
        if nb == 0.0:
            continue
        res = B - A @ np.linalg.lstsq(A, B, rcond=None)[0]
        if np.linalg.norm(res) > CONTAINS_TOL * nb:
            return False
    return True


def _separation(r_winner, r_rival):
    """How much better a winner predicts the held-out data of its round than a rival: 1 - (1 - r_winner) /
    (1 - r_rival), r their RMSE reductions against the model of the round (None when one is missing)."""
    if r_winner is None or r_rival is None or r_rival >= 1.0:
        return None
    return 1.0 - (1.0 - float(r_winner)) / (1.0 - float(r_rival))


def _tie(winner, rival):
    """Whether the tests of one round do not separate a winner from a rival (``winner``, ``rival``: their tests):
    ``"margin"`` when the scores are within :data:`AMBIGUITY_MARGIN`, ``"min_gain"`` when the winner predicts the
    held-out data within :data:`MIN_GAIN` of the rival's RMSE (:func:`_separation`), else None; with the separation
    (None when an RMSE reduction is missing).  Used for a round's rivals (:func:`_competition`) and for the rivals of
    a finding given the other findings (:func:`_mark_tied_rivals`)."""
    sep = _separation(winner.get("rmse_reduction"), rival.get("rmse_reduction"))
    if float(winner["score"] - rival["score"]) < AMBIGUITY_MARGIN:
        return "margin", sep
    if sep is not None and sep < MIN_GAIN:
        return "min_gain", sep
    return None, sep


def _speed_confound(out, tst) -> dict:
    """A law in time that a free friction curve explains as well (and the curve adds nothing to it,
    ``tst["confounded_with_speed"]`` from :func:`~drake_est.diagnose.competition.survives_speed_law`), or a position
    friction that the curve explains as well (:func:`~drake_est.diagnose.competition.position_law_confounded`): the
    log cannot tell it from a speed law, so the finding is also ambiguous with ``stribeck``."""
    c = tst.get("confounded_with_speed")
    if not c:
        return out
    position = "position_law_given_speed_law" in c
    rival = c.get("rival", "stribeck") if position else "stribeck"
    if position and rival == "asymmetric_coulomb":
        why = ("position and direction of motion are confounded in this log: one friction level per direction "
               "explains the held-out data as well as this position law (which adds nothing to it, "
               f"p = {c['position_law_given_direction_levels']['p_value']:.2g}), so an asymmetric Coulomb friction "
               "is not ruled out")
    elif position:
        why = ("position and speed are confounded in this log: a free friction curve of each direction explains "
               "the held-out data as well as this position law (which adds nothing to it, "
               f"p = {c['position_law_given_speed_law']['p_value']:.2g}; the curve given the position law: "
               f"p = {c['p_value']:.2g}), so a speed-dependent friction (stribeck) is not ruled out")
    else:
        why = ("time and speed are confounded in this log: a free friction curve of each direction explains the "
               "held-out data as well as this law in time (and adds nothing to it, "
               f"p = {c['p_value']:.2g}), so a speed-dependent friction (stribeck) is not ruled out")
    was = list(out.get("ambiguous_with") or []) if out.get("ambiguous") else []
    out.update({"ambiguous": True, "ambiguous_with": was + [e for e in [rival] if e not in was],
                "reason": "; ".join([r for r in [out.get("reason")] if r] + [why]), "confounded_with_speed": True})
    if position:
        out["position_vs_speed"] = True
    return out


def _mark_confounded_with_time(prep, model, best, results, alpha, min_gain) -> None:
    """The round's winner ``best`` on a joint whose time-periodic candidate at a line of the motion a free function of
    the state explained (``explained_by_state_law`` in ``results``): when the winner adds nothing to that sinusoid
    either (:func:`~drake_est.diagnose.competition.law_confounded_with_time`), its test gets
    ``confounded_with_time`` and :func:`_time_confound` reports it ambiguous with the disturbance."""
    ext, tst = best[0], best[1]
    if ext.shared or ext.effect in comp.PERIODIC_PAIR:
        return
    for e, t, _, _ in results:
        if t.get("explained_by_state_law") and not e.shared and e.joint == ext.joint:
            c = comp.law_confounded_with_time(prep, model, ext, e, t["state_law_test"], alpha, min_gain,
                                              solve=_model_solver(model, ext.joint))
            if c is not None:
                tst["confounded_with_time"] = c
            return


def _time_confound(out, tst) -> dict:
    """A law that adds nothing to a time-periodic candidate at a line of the motion, which in turn a free function of
    the state explained as well (``tst["confounded_with_time"]``, from
    :func:`~drake_est.diagnose.competition.law_confounded_with_time`): position, speed and time are confounded in
    this log, so the finding is also ambiguous with ``time_periodic_disturbance``."""
    c = tst.get("confounded_with_time")
    if not c:
        return out
    why = (f"state and time are confounded in this log: a disturbance periodic in time at {c['frequency_hz']:.3g} Hz "
           f"(a line of the motion, {c['at_motion_line_hz']:.3g} Hz) explains the held-out data as well as this law "
           f"(which adds nothing to it, p = {c['p_value']:.2g}), and a free function of position and speed as well "
           f"as the disturbance (p = {c['time_periodic_given_state']['p_value']:.2g}), so a disturbance in time is "
           "not ruled out")
    was = list(out.get("ambiguous_with") or []) if out.get("ambiguous") else []
    out.update({"ambiguous": True,
                "ambiguous_with": was + [e for e in ["time_periodic_disturbance"] if e not in was],
                "reason": "; ".join([r for r in [out.get("reason")] if r] + [why]), "confounded_with_time": True,
                "time_periodic_frequency_hz": float(c["frequency_hz"])})
    return out


def _within_quantization_step(prep, ext, e2, results) -> bool:
    """A coarse torque ADC: when the winner ``ext`` has more parameters than the rival ``e2`` and their held-out
    predictions differ by less than one quantization step, what puts the more flexible one ahead is the
    deterministic rounding error, not evidence (a simpler rival stands beside it: parsimony)."""
    if ext.n_params <= e2.n_params:
        return False
    f1, f2 = _fit_of(results, ext), _fit_of(results, e2)
    for j in set(ext.cols) & set(e2.cols):
        step = joint_tau_step(prep, j)
        jd = prep.joints[j]
        d = (f1.pred[j] - f2.pred[j])[jd.val]
        if step > 0 and float(np.sqrt(np.mean(d ** 2))) < step:
            return True
    return False


def _model_solver(model, j):
    """``solve(A, y, n)`` for :func:`~drake_est.diagnose.competition.survives_periodic`: the search's ridge with the
    model's own penalty mask on its first columns (:meth:`Model.penalized`), every column after them penalized."""
    def solve(A, y, _n):
        m = model.penalized(j)
        pen = np.concatenate([m, np.ones(A.shape[1] - m.size, bool)])
        return solve_kv_nonneg(lambda A_, y_, keep=None: _ridge_lstsq(A_, y_, pen if keep is None else pen[keep]),
                               A, y, model.nonneg(j))[0]
    return solve


def _best_surviving(prep, model, fit, sig, alpha, min_gain):
    """The best significant candidate that is not a smooth speed/time law merely absorbing a periodic
    residual (:func:`~drake_est.diagnose.competition.survives_periodic`), nor a law in time merely absorbing a
    misfit of the friction curve (:func:`~drake_est.diagnose.competition.survives_speed_law`), nor a change in time
    that the windows with bursts of misfit decide (:func:`~drake_est.diagnose.competition.survives_window_weights`),
    nor one that a disturbance's dither of the Coulomb friction explains
    (:func:`~drake_est.diagnose.competition.survives_dither`), nor a law of the speed that the rows where its joint
    slows down do not show (:func:`~drake_est.diagnose.competition.survives_both_speed_changes`); (None, [...]) when
    none is left.  Also returns the candidates set aside that way, with their partial tests (``explained_by``:
    ``"periodic_residual"``, ``"speed_law"``, ``"uneven_residual"``, ``"dither"`` or ``"one_speed_change"``)."""
    sig = sorted(sig, key=lambda r: -r[1]["score"])
    away, nuisance, speed_nuisance, dither = [], {}, {}, {}

    def set_aside(r, t, why):
        """Candidate ``r`` is not significant, explained by ``why``; its partial test ``t`` goes to ``away``."""
        r[1]["significant"] = False
        r[1][f"explained_by_{why}"] = True
        away.append({"effect": r[0].effect, "joint": int(r[0].joint), "explained_by": why,
                     **{k: v for k, v in t.items() if k != "significant"}})

    # joints where a better-scoring candidate was explained by the periodic residual: every lower-ranked candidate
    # that is not periodic itself must then beat that residual too (loop spec 2940: an abrupt change, score 907, was
    # explained by it, and a position load, score 417, named without that test; neither the load nor the position
    # friction it was ambiguous with had been planted)
    periodic_led = set()
    for r in sig:
        ext = r[0]
        if ext.effect in comp.TIME_LAWS and not ext.shared:
            if ext.joint not in speed_nuisance:
                speed_nuisance[ext.joint] = comp.speed_law_nuisance(prep, ext.joint)
            t = comp.survives_speed_law(prep, model, fit, ext, alpha, min_gain, nuisance=speed_nuisance[ext.joint],
                                        solve=_model_solver(model, ext.joint)) \
                if speed_nuisance[ext.joint] is not None else {"significant": True}
            if t.get("confounded_with_speed"):
                r[1]["confounded_with_speed"] = t["speed_law_given_it"]
            if not t["significant"]:
                set_aside(r, t, "speed_law")
                continue
            t = comp.survives_window_weights(prep, model, fit, ext, alpha, min_gain,
                                             solve=_model_solver(model, ext.joint))
            if not t["significant"]:
                set_aside(r, t, "uneven_residual")
                continue
        after = ext.joint in periodic_led
        if comp.periodic_test_applies(ext, after):
            key = (ext.joint, comp.nuisance_periods(ext.effect))
            if key not in nuisance:
                nuisance[key] = comp.periodic_nuisance(prep, model, fit, *key)
            t = comp.survives_periodic(prep, model, fit, ext, alpha, min_gain, nuisance=nuisance[key],
                                       solve=_model_solver(model, ext.joint), any_law=after) \
                if nuisance[key] is not None else {"significant": True}
            if not t["significant"]:
                set_aside(r, t, "periodic_residual")
                periodic_led.add(ext.joint)
                continue
        if not ext.shared and ext.effect != "time_periodic_disturbance":
            # a disturbance in the model dithers the Coulomb friction of its joint (competition.dither_nuisance)
            if ext.joint not in dither:
                dither[ext.joint] = comp.dither_nuisance(prep, model, ext.joint)
            if dither[ext.joint] is not None:
                t = comp.survives_dither(prep, model, fit, ext, alpha, min_gain, nuisance=dither[ext.joint],
                                         solve=_model_solver(model, ext.joint))
                if not t["significant"]:
                    set_aside(r, t, "dither")
                    continue
        if ext.effect in comp.SIDE_LAWS and not ext.shared:
            j = ext.joint
            t = comp.survives_both_speed_changes(prep, model, fit, ext, alpha, min_gain,
                                                 solve=_model_solver(model, j),
                                                 curve=ext.cols[j] @ r[3].coef_slices(r[2], j)[ext.effect])
            if not t["significant"]:
                set_aside(r, t, "one_speed_change")
                continue
        if ext.effect in comp.POSITION_LAWS and not ext.shared:
            # the round's winner: its own curve (knots spread in log-speed), built once here, none shared with the
            # laws in time above
            c = comp.position_law_confounded(prep, model, fit, ext, alpha, min_gain,
                                             solve=_model_solver(model, ext.joint))
            if c is not None:
                r[1]["confounded_with_speed"] = c
        return r, away
    return None, away


def _train_rss(prep, fit, j) -> float:
    jd = prep.joints[j]
    e = (jd.y - fit.pred[j])[jd.train]
    return float(e @ e)


def _backfit(prep, model, fit, sigma, effect, redetect):
    """Backfitting of the accepted extensions of one ``effect`` (Hastie & Tibshirani): each is estimated again on its
    partial residual (the current residual plus its own part), ``redetect(model, ext, jd, r_p)`` -> new extension or
    None, and replaced when that lowers the training residual of its joint.  Returns ``(model, fit, moved)`` with
    ``moved`` a list of (joint, old extension, new extension)."""
    moved = []
    for e in list(model.exts):
        if e.effect != effect or e.shared:
            continue
        j = e.joint
        jd = prep.joints[j]
        r_p = jd.y - fit.pred[j] + e.cols[j] @ model.coef_slices(fit, j)[e.effect]
        new = redetect(model, e, jd, r_p)
        if new is None:
            continue
        m2 = Model(prep, [new if x is e else x for x in model.exts])
        f2 = m2.fit(sigma)
        if _train_rss(prep, f2, j) < _train_rss(prep, fit, j):
            moved.append((j, e, new))
            model, fit = m2, f2
    return model, fit, moved


def backfit_changes(prep, model, fit, sigma):
    """Backfitting of accepted abrupt changes (:func:`_backfit`, Ch. 7's change-point search (7.8) as the smoother): a
    change time is found on the residual of the model at the time it is accepted, where effects not yet in the
    model (e.g. a position-dependent friction) can pull it seconds away.  Once later findings are in the model,
    each change time is searched again on its partial residual and the change moved there when that lowers the
    training residual.  Returns ``(model, fit, moved)`` with ``moved`` a list of (joint, old, new extension); the
    new one's evidence holds ``backfitted_from_t_change_s``."""
    def redetect(model, e, jd, r_p):
        j = e.joint
        drift = any(x.effect == "energy_dependent_friction" and x.joint == j for x in model.exts)
        new = det.change_point(jd, r_p, smooth_alternative=drift, energy_cols=_energy_cols(model, j))
        if new is None or new.spec["t_change"] == e.spec["t_change"]:
            return None
        new.evidence["backfitted_from_t_change_s"] = float(e.spec["t_change"])
        return new

    return _backfit(prep, model, fit, sigma, "abrupt_change", redetect)


def at_line_refined(ext, jd, r, X):
    """A time-periodic candidate at a line of the motion
    (:func:`~drake_est.diagnose.detectors.time_periodic_at_motion_line`, found on the residual ``r`` alone) with
    its frequency and harmonics chosen again beside the model's columns ``X``
    (:func:`~drake_est.diagnose.detectors.time_periodic_refit` with ``X``; evidence ``refined_from_frequency_hz``):
    a slow disturbance shares its frequencies with the motion, whose columns take part of it, so the residual alone
    places it off (0.0602 Hz for 0.06 Hz) and a position law is later named for the phase misfit.  ``ext`` itself
    when nothing moves; None for None."""
    if ext is None:
        return None
    new = det.time_periodic_refit(jd, r, ext, X=X, key="refined_from_frequency_hz", skip_motion_lines=False)
    return ext if new is None else new


def backfit_periodic(prep, model, fit, sigma):
    """Backfitting of an accepted time-periodic disturbance (:func:`_backfit`): its frequency and harmonics were found
    on the residual of the model at the time it was accepted, where a larger effect not yet in the model (a position
    friction, say) can bias the frequency and hide a harmonic; a harmonic left out moves the axis at its frequency,
    biases the inertia of the closed-loop fit and is later taken for another effect.  Once later findings are in
    the model, the disturbance is estimated again on its partial residual
    (:func:`~drake_est.diagnose.detectors.time_periodic_refit`) and replaced when that lowers the training
    residual; one at a line of the motion is estimated beside the rest of the model's columns (as
    :func:`at_line_refined` chose it).  Returns ``(model, fit, moved)`` with ``moved`` a list of (joint, old
    extension, new extension)."""
    def redetect(model, e, jd, r_p):
        if "at_motion_line_hz" not in e.evidence:
            return det.time_periodic_refit(jd, r_p, e)
        # at a line of the motion: beside the rest of the model, as when it was a candidate (at_line_refined)
        X = Model(prep, [x for x in model.exts if x is not e]).design_with_shared(e.joint)
        return det.time_periodic_refit(jd, r_p, e, X=X, skip_motion_lines=False)

    return _backfit(prep, model, fit, sigma, "time_periodic_disturbance", redetect)


def backfit_ripple(prep, model, fit, sigma):
    """Backfitting of an accepted motor-position ripple (:func:`_backfit`): its frequencies were found on the
    residual of the model at the time it was accepted, where a larger effect not yet in the model (an abrupt change
    of the friction, say) biases the scan's peak; a ripple at a slightly wrong frequency leaves a phase misfit that
    drifts over the joint's range, which a position law later takes.  Once later findings are in the model the
    ripple is detected again on its partial residual (:func:`~drake_est.diagnose.detectors.ripple` with the inner
    split of the model without it) and replaced when its frequencies differ, it has no more columns than the old one
    (the training residual is no fair judge of a larger ripple) and the joint's training residual goes down (loop spec
    17368: a ripple accepted before an abrupt change at 6.654 cycles/rad, the generator's 6.685, whose phase misfit a
    position load took).  The new extension's evidence holds ``backfitted_from_frequencies_per_arm_rad``."""
    def redetect(model, e, jd, r_p):
        m0 = Model(prep, [x for x in model.exts if x is not e])
        inner = _inner_fits(m0, jd)
        new = det.ripple(jd, r_p, n_components=RIPPLE_COMPONENTS,
                         fit_inner=lambda C, nonneg=False: inner.error(C, nonneg)[0])
        if new is None or new.cols[jd.joint].shape[1] > e.cols[jd.joint].shape[1]:
            return None
        new = det.ripple_refined(jd, r_p, new)
        if new.spec["frequencies_per_arm_rad"] == e.spec["frequencies_per_arm_rad"]:
            return None
        new.evidence["backfitted_from_frequencies_per_arm_rad"] = list(e.spec["frequencies_per_arm_rad"])
        return new

    return _backfit(prep, model, fit, sigma, "motor_position_ripple", redetect)


#: the ninety-fourth round's rule (:func:`ripple_refined_before_position_law`): a ripple of a joint refined on the
#: residual of the model without a law of the joint's position that a round has just accepted
RIPPLE_REFINED_BEFORE_POSITION_LAW_RULE = False
#: the ninety-fifth round's rule: the ninety-fourth's, acting only where the law just accepted is no longer significant
#: given the refined ripple (:func:`ripple_refined_before_position_law`)
RIPPLE_REFINED_WHERE_LAW_FALLS_RULE = True
#: the ninety-seventh round's rule (:func:`position_law_gain_concentrated_beside_dropped_rows`): with the
#: ninety-sixth round's rule (``nominal.BEYOND_TRAINING_POSITIONS_RULE``), a law of a joint's position on a joint
#: whose held-out rows beyond the training positions were dropped must not hold its held-out gain in a few groups;
#: acts only where that rule dropped rows
BEYOND_POSITIONS_CONCENTRATED_GAIN_RULE = False


def ripple_refined_before_position_law(prep, model, fit, sigma, ext, alpha=ALPHA, min_gain=MIN_GAIN):
    """A ripple of ``ext``'s joint refined before the position law ``ext`` can keep its phase misfit (the ninety-fourth
    round).  The ripple's frequencies come from the detector's greedy scan, whose velocity-dependent amplitude can
    bend a wrong frequency's phase back, and the backfit that follows a later finding (:func:`backfit_ripple`) looks
    again with that finding in the model: once a position law is accepted the law holds the misfit, which drifts over
    the joint's range, and the backfit settles beside it (loop spec 37278: a ripple of 5.570 cycles/rad placed at
    5.529 beside an abrupt change; the load accepted next took 71 % of the held-out RMSE, 0.104 against 0.030 Nm, and
    the ripple at the generator's frequency leaves the load nothing).  So when a round accepts a law of a joint's
    position beside a ripple of that joint, each such ripple's frequencies are chosen jointly
    (:func:`~drake_est.diagnose.detectors.ripple_refined`) on its partial residual of the model without the law,
    and the refined ripple replaces it when it lowers that model's training residual of the joint.  Returns
    ``(model, fit, moved)`` as the backfits do; a move runs the law's round again on the refined model
    (:data:`PERIODIC_REDOS`).

    With :data:`RIPPLE_REFINED_WHERE_LAW_FALLS_RULE` (the ninety-fifth round) the refined ripples are kept only when
    the law, tested again on the refined model without it (:func:`_evaluate`: every test of a round, at ``alpha`` and
    ``min_gain``), is no longer significant: the refinement then took what the law explained.  Where the law stands
    the model is left as it was (the ninety-fourth round's probe: loop spec 16004, an abrupt change beside a ripple at
    37.56 cycles/rad, whose ripple moved by 0.002 cycles/rad; the redo named a position friction that the rule-off
    search sets aside)."""
    falls = RIPPLE_REFINED_WHERE_LAW_FALLS_RULE
    if not (RIPPLE_REFINED_BEFORE_POSITION_LAW_RULE or falls):
        return model, fit, []

    def refine(m0, f0, e, jd, r_p):
        new = det.ripple_refined(jd, r_p, e)
        return None if new is e else (
            new, {"refined_before_position_law_from_frequencies_per_arm_rad": list(e.spec["frequencies_per_arm_rad"])})

    return _refined_before_position_law(prep, model, fit, sigma, ext, "motor_position_ripple", refine, falls, alpha,
                                        min_gain)


def _refined_before_position_law(prep, model, fit, sigma, ext, effect, refine, falls, alpha, min_gain):
    """The refinement of the ninety-fourth, ninety-fifth and hundredth rounds: when a round has just accepted the law
    of position ``ext``, each unshared extension of ``effect`` on its joint is estimated again on its partial residual
    of the model without the law, ``refine(m0, f0, e, jd, r_p)`` -> (new extension, its evidence) or None, and
    replaces the old one when that lowers the model's training residual of the joint.  With ``falls`` the refined
    extensions are kept only when the law, tested again on the refined model without it (:func:`_evaluate`), is no
    longer significant.  Returns ``(model, fit, moved)`` as the backfits do."""
    moved = []
    if ext.shared or ext.effect not in comp.POSITION_LAWS:
        return model, fit, moved
    j = ext.joint
    olds = [e for e in model.exts if e.effect == effect and not e.shared and e.joint == j]
    if not olds:
        return model, fit, moved
    jd = prep.joints[j]
    m0 = Model(prep, [x for x in model.exts if x is not ext])
    f0 = m0.fit(sigma)
    for e in olds:
        r_p = jd.y - f0.pred[j] + e.cols[j] @ m0.coef_slices(f0, j)[e.effect]
        got = refine(m0, f0, e, jd, r_p)
        if got is None:
            continue
        new, evidence = got
        m1 = Model(prep, [new if x is e else x for x in m0.exts])
        f1 = m1.fit(sigma)
        if _train_rss(prep, f1, j) < _train_rss(prep, f0, j):
            new.evidence.update(evidence)
            moved.append((j, e, new))
            m0, f0 = m1, f1
    if not moved:
        return model, fit, moved
    if falls and _evaluate(prep, m0, f0, sigma, ext, alpha, min_gain, {})[1]["significant"]:
        return model, fit, []
    swap = {id(old): new for _, old, new in moved}
    model = Model(prep, [swap.get(id(x), x) for x in model.exts])
    return model, model.fit(sigma), moved


#: the hundredth round's rule (:func:`change_refined_before_position_law`): when a round accepts a law of a joint's
#: position beside an abrupt change of that joint, the change's switch is chosen again jointly with the rest of the
#: model without the law, and the refined change kept where the law is then no longer significant
CHANGE_REFINED_WHERE_LAW_FALLS_RULE = True


def change_refined_before_position_law(prep, model, fit, sigma, ext, alpha=ALPHA, min_gain=MIN_GAIN):
    """An abrupt change of ``ext``'s joint whose switch is chosen again before the position law ``ext`` can keep the
    misfit of a misplaced switch (the hundredth round).  The change's switch is found on the residual of the model at
    the time it is accepted, and its backfit (:func:`backfit_changes`) searches again on its partial residual: both
    hold the rest of the model as fitted beside the old switch, and a ripple of many coefficients fitted before the
    change has taken part of the step there (loop spec 41128: a ripple and a change at 63.0 s; the change, found on
    the ripple's residual, sits at 44.1 s; the load accepted next lowers the held-out RMSE by 19 %, while the ripple
    and a change at 65.8 s, the middle of the training rows' gap around 63.0 s, leave it nothing and predict the
    held-out blocks three times better).  So when a round accepts a law of a joint's position beside an abrupt change
    of that joint, each such change's switch is chosen jointly with the other columns of the model without the law
    (:func:`~drake_est.diagnose.detectors.change_point_beside`) and replaces the old when it lowers that model's
    training residual of the joint and the law, tested again on the refined model without it (:func:`_evaluate`),
    is no longer significant: the refinement then took what the law explained.  Returns ``(model, fit, moved)`` as
    the backfits do; a move runs the law's round again on the refined model (:data:`PERIODIC_REDOS`)."""
    if not CHANGE_REFINED_WHERE_LAW_FALLS_RULE:
        return model, fit, []

    def refine(m0, f0, e, jd, r_p):
        j = e.joint
        drift = any(x.effect == "energy_dependent_friction" and x.joint == j for x in m0.exts)
        rest = Model(prep, [x for x in m0.exts if x is not e])
        new = det.change_point_beside(jd, rest.design_with_shared(j), r_p, smooth_alternative=drift,
                                      energy_cols=_energy_cols(m0, j))
        if new is None or new.spec["t_change"] == e.spec["t_change"]:
            return None
        return new, {"refined_before_position_law_from_t_change_s": float(e.spec["t_change"])}

    return _refined_before_position_law(prep, model, fit, sigma, ext, "abrupt_change", refine, True, alpha, min_gain)


#: how many times one search runs a round again after the Stribeck backfit reshaped the law (:func:`_search`)
STRIBECK_REDOS = 1
#: how many times one search runs a round again after a backfit moved a time-periodic disturbance's frequency or
#: harmonics, or a ripple's frequencies, right after it accepted a law of the joint's position (:func:`_search`)
PERIODIC_REDOS = 1
#: the periodic findings whose move by a backfit (a new frequency) runs the round of a law of position again
#: (:data:`PERIODIC_REDOS`): a time-periodic disturbance, and a motor ripple (:func:`backfit_ripple`)
PERIODIC_REDO_MOVED = ("time_periodic_disturbance", "motor_position_ripple")
#: the findings whose round :data:`PERIODIC_REDOS` runs again: laws of the joint's position, which on a repeated
#: motion can take the phase misfit of a time-periodic disturbance (or, over the joint's range, of a ripple) placed
#: at a slightly wrong frequency; and a time-periodic disturbance, which on a repeated motion takes a ripple's phase
#: misfit alike (sixty-fifth round, loop spec 19128: a 0.33 Hz disturbance of 13.8 % held-out gain beside a ripple
#: at 9.76 and 18.79 cycles/rad, -0.01 % once the ripple's backfit moved it to the generator's 9.708 and 19.42)
PERIODIC_REDO_LAWS = comp.POSITION_LAWS + ("motor_position_ripple", "time_periodic_disturbance")


def backfit_stribeck(prep, model, fit, sigma):
    """Backfitting of an accepted Stribeck law (:func:`_backfit`): its shape (vs and delta, or the basis in |qd|) was
    chosen on the inner split of the model at the time it was accepted, where an effect not yet in the model that
    goes with speed (an asymmetric Coulomb level where the two directions move at different speeds, say) bends
    the curve it sees; the misfit the wrong shape leaves is speed-shaped and later candidates are named for it.
    Once later findings are in the model the shape is chosen again (:func:`~drake_est.diagnose.detectors.stribeck`)
    against the model without it, and replaced when that lowers the training residual.  Returns
    ``(model, fit, moved)``; the new extension's evidence holds ``backfitted_from``."""
    def redetect(model, e, jd, r_p):
        j = e.joint
        m0 = Model(prep, [x for x in model.exts if x is not e])
        inner = _inner_fits(m0, jd)
        new = det.stribeck(jd, r_p, lambda C, nonneg=False: inner.error(C, nonneg)[0],
                           falling=j in m0.fit(sigma).kv_held)
        if new is None or new.spec == e.spec:
            return None
        new.evidence["backfitted_from"] = {k: v for k, v in e.spec.items() if k != "effect"}
        return new

    return _backfit(prep, model, fit, sigma, "stribeck", redetect)


def backfit_inertia(prep, model, fit) -> dict:
    """Backfitting of the inertia J of generic axes (the abrupt-change backfit's counterpart for the nominal
    model).  ``prepare`` identifies J before any finding is known, on the moving samples with the nominal
    friction only.  On closed-loop data that estimate is biased whenever an unmodeled torque moves the axis:
    the controller answers the disturbance, so the acceleration and the omitted torque are correlated (the
    classical bias of an open-loop fit of closed-loop data, Sec. 7.1's errors-in-variables setting).  Once the
    findings are in the model that torque is a regressor and the bias goes: J is re-estimated as one more
    column qdd_j beside the accepted model on the training rows.  A correction dJ larger than
    ``INERTIA_BACKFIT_Z`` standard errors and ``INERTIA_BACKFIT_REL`` of J is applied to the joint's rigid-body
    torque (rb += dJ qdd) and returned as {joint: (J_old, J_new)}; the caller repeats the search, since the
    findings themselves may have been made to absorb the old J error (e.g. a position-dependent load that is
    J-error times an acceleration correlated with position)."""
    out = {}
    if prep.robot is not None:
        return out
    for j, jd in prep.joints.items():
        J = jd.counts.get("inertia")
        if J is None:
            continue
        X = model.design_with_shared(j)
        tr = jd.train
        est = first_coefficient(np.column_stack([jd.a[jd.rows], X])[tr], jd.y[tr])
        if est is None:
            continue    # qdd not excited on the selected rows, or collinear with the model: keep J
        dJ, se = est
        if abs(dJ) > INERTIA_BACKFIT_Z * se and abs(dJ) > INERTIA_BACKFIT_REL * abs(J):
            why = inertia_move_contradicted(prep, model, j, J, J + dJ)
            if why is None and INERTIA_BACKFIT_KEEPS_SIGN:
                why = inertia_move_through_zero(J, J + dJ, se)
            if why is not None:
                jd.counts["inertia_backfit_withheld"] = why
                continue
            out[j] = (float(J), float(J + dJ))
    return out


def inertia_move_through_zero(J, J_new, se) -> dict | None:
    """A move of the inertia backfit (:func:`backfit_inertia`) from a positive J to ``J_new`` <= 0, withheld: an
    inertia is positive, so a correction through zero says that the acceleration column fits something other than
    the inertia torque.  At low sample rates under slow point-to-point moves the measured speed lags the true one by
    about qdd dt, and a friction law that falls steeply with the speed (a Stribeck hump) leaves a misfit that goes
    with -qdd (loop spec 21549: an asymmetric level beside Stribeck at 10 Hz, J 0.787 -> -19.3, the generator's
    0.919; the search run again named a load that was not planted).  Returns {J_moved, J_speed_curve: None,
    standard_error, reason: "nonpositive"} when withheld, else None.  J <= 0 from ``prepare`` is not this case
    (the fifty-sixth round's rule, not kept)."""
    if not (J > 0 and J_new <= 0):
        return None
    return {"J_moved": float(J_new), "J_speed_curve": None, "standard_error": float(se), "reason": "nonpositive"}


def inertia_move_contradicted(prep, model, j, J, J_new) -> dict | None:
    """A large move of the inertia backfit (:func:`backfit_inertia`: J -> ``J_new``, by more than a factor
    :data:`INERTIA_BACKFIT_LARGE` or to J_new <= 0) that the same fit with a free friction curve of the joint's speed
    beside the findings (:func:`~drake_est.diagnose.competition.speed_law_nuisance`, knots spread in log-speed)
    contradicts: that fit's J differs from ``J_new`` by more than :data:`INERTIA_BACKFIT_Z` of its standard errors.
    The backfit regresses the torque on qdd beside the findings over the training rows; a friction law of the speed
    that no finding holds yet (a Stribeck hump under point-to-point moves, where the speed and the acceleration
    change together at every start and stop) is then fitted by the qdd column, and J moves far (loop spec 12199: an
    asymmetric level beside Stribeck at 100 Hz, J 0.467 -> 3.97 while the generator's is 0.477; 2406: a load beside
    Stribeck at 1000 Hz, 1.81 -> -1.8, the generator's 1.89; the search run again names what the wrong J leaves).
    With the curve as nuisance, qdd can only take what no law of the speed explains (12199: -0.29 +- 0.63; 2406:
    1.69).  Returns {J_moved, J_speed_curve, standard_error, speed_curve_columns} when the move is withheld, else
    None (a small move, a move the curve's fit allows, or no curve: too few training samples per direction)."""
    if J_new > 0 and J > 0 and max(J_new / J, J / J_new) <= INERTIA_BACKFIT_LARGE:
        return None
    est = inertia_correction_beside_speed_curve(prep, model, j)
    if est is None:
        return None
    dJ, se, n_curve = est
    if abs(J + dJ - J_new) <= INERTIA_BACKFIT_Z * se:
        return None
    return {"J_moved": float(J_new), "J_speed_curve": float(J + dJ), "standard_error": float(se),
            "speed_curve_columns": n_curve}


def inertia_correction_beside_speed_curve(prep, model, j):
    """``(dJ, standard error, curve columns)``: the correction of joint ``j``'s inertia that :func:`backfit_inertia`'s
    fit gives (the torque on qdd beside ``model``'s findings over the training rows) with a free friction curve of the
    joint's speed as nuisance columns (:func:`~drake_est.diagnose.competition.speed_law_nuisance`, knots spread in
    log-speed), by :func:`projected_coefficient`; None when there is no curve (too few training samples per
    direction) or qdd lies in the span of the findings and the curve (:func:`inertia_move_contradicted`)."""
    N = comp.speed_law_nuisance(prep, j, spread=True)
    if N is None:
        return None
    jd = prep.joints[j]
    tr = jd.train
    est = projected_coefficient(jd.a[jd.rows][tr], np.column_stack([model.design_with_shared(j), N])[tr], jd.y[tr])
    return None if est is None else (est[0], est[1], int(N.shape[1]))


def projected_coefficient(a, Z, y):
    """(coefficient, standard error) of the column ``a`` in the least-squares fit of ``y`` on [a, Z], where ``Z`` may be
    rank deficient (a Stribeck finding's column lies in the span of a free speed curve): Z's span is taken by an SVD
    (singular values above 1e-9 of the largest), and a and y are projected off it.  None when a lies in that span."""
    U, sv, _ = np.linalg.svd(Z, full_matrices=False)
    U = U[:, sv > 1e-9 * sv[0]] if sv.size else U
    ar, yr = a - U @ (U.T @ a), y - U @ (U.T @ y)
    aa = float(ar @ ar)
    if aa <= 1e-12 * float(a @ a):
        return None
    c = float(ar @ yr) / aa
    e = yr - c * ar
    dof = max(y.size - U.shape[1] - 1, 1)
    return c, float(np.sqrt(float(e @ e) / dof / aa))


def first_coefficient(A, y):
    """(coefficient, standard error) of A's first column in the least-squares fit of y on A (QR, no inverse), or
    None when that column is not excited or A is numerically rank deficient (:func:`backfit_inertia`'s estimate)."""
    Qr, R = np.linalg.qr(A)
    if abs(R[0, 0]) < 1e-12 or np.min(np.abs(np.diag(R))) < 1e-10 * np.max(np.abs(np.diag(R))):
        return None
    c = scipy.linalg.solve_triangular(R, Qr.T @ y)
    e = y - A @ c
    dof = max(A.shape[0] - A.shape[1], 1)
    s2 = float(e @ e) / dof
    # standard error of c[0]: sqrt(s2 * [(R^T R)^-1]_00), from the first row of R^-1
    r_inv0 = scipy.linalg.solve_triangular(R.T, np.eye(A.shape[1])[:, 0], lower=True)
    return float(c[0]), float(np.sqrt(s2 * (r_inv0 @ r_inv0)))


#: a law in time may leave the friction torque kc + kv |qd| below zero by at most this many noise standard deviations
#: (:func:`negative_friction`)
NEGATIVE_FRICTION_SIGMAS = 2.0


def negative_friction(prep, model, fit, ext, sigma) -> dict | None:
    """A change or drift of friction in time must leave a friction: the Coulomb + viscous torque kc + kv |qd| in
    the direction of motion stays >= 0 (it dissipates energy) over the speeds of the whole log (the joint after a
    change is the same joint at every speed, also at those it happened to run only before it), before and after an
    abrupt change, and over the range of the energy state E of a drift ((9.29): kc + k_e E, kv + k_e,v E).  A
    fitted change to kv = -16 N m s/rad (say) does not describe a gearbox; it follows a misfit elsewhere in the
    model, e.g. of a low-speed law on a part of the log with slow moves only.  Returns None when the fitted law dissipates (to within :data:`NEGATIVE_FRICTION_SIGMAS` times the
    joint's noise level ``sigma[j]``), else where it does not: ``{"where", "speed", "friction_torque"}``."""
    if ext.effect not in ("abrupt_change", "energy_dependent_friction") or ext.shared:
        return None
    j = ext.joint
    jd = prep.joints[j]
    cs = model.coef_slices(fit, j)
    kv, kc = float(cs["nominal"]["kv"]), float(cs["nominal"]["kc"])
    c = np.asarray(cs[ext.effect], float)
    v = jd.v[jd.rows]
    slack = NEGATIVE_FRICTION_SIGMAS * float(sigma.get(j, 0.0))
    if ext.effect == "abrupt_change":
        sides = [("before the change", kc, kv), ("after the change", kc + c[1], kv + c[0])]
    else:
        E = np.asarray(ext.obj, float)[jd.rows] if ext.obj is not None else None
        if E is None or E.size == 0:
            return None
        kev = c[1] if c.size > 1 else 0.0
        sides = [(f"at energy state E = {e:.3g}", kc + c[0] * e, kv + kev * e) for e in (float(E.min()), float(E.max()))]
    speeds = det.extreme_speeds(v)
    if speeds is None:
        return None
    for where, kc_s, kv_s in sides:
        for sp in speeds:
            f = kc_s + kv_s * sp
            if f < -slack:
                return {"where": where, "speed": sp, "friction_torque": float(f), "kc": float(kc_s), "kv": float(kv_s)}
    return None


#: eighty-fifth round (kept; see ``docs/readme/diagnose_testbench.md``): an abrupt change that :func:`negative_friction`
#: refuses is searched again among the switches where the model with it dissipates (:func:`dissipative_change`)
DISSIPATIVE_CHANGE_RULE = True


def dissipative_switches(prep, model, fit, sigma, j, min_len) -> list:
    """The training-row switches k (segments of at least ``min_len`` rows) of an abrupt change on joint ``j`` where
    ``model`` with the change, fitted by least squares on the training rows, leaves a friction that dissipates before
    and after it at the log's lowest and highest speed (as :func:`negative_friction` asks, to within
    :data:`NEGATIVE_FRICTION_SIGMAS` noise levels), ordered by that fit's training residual, the best first.

    All switches at once: with the model's columns X and the change's columns C_k = [qd, sign(qd)] after k, the
    change's coefficients are d_k = (C_k^T M C_k)^-1 C_k^T r (M projects out X, r is X's residual) and X's move by
    -(X^T X)^-1 X^T C_k d_k (Frisch-Waugh-Lovell); C_k^T C_k, X^T C_k and C_k^T r are suffix sums.  [] where the
    model holds shared columns or X is rank deficient."""
    if model.shared_exts():
        return []
    jd = prep.joints[j]
    X = model.design(j)[jd.train]
    y = jd.y[jd.train]
    v = jd.v[jd.rows][jd.train]
    n, p = X.shape
    if n < 2 * max(int(min_len), 1) + 1:
        return []
    Q, R = np.linalg.qr(X)
    if np.min(np.abs(np.diag(R))) <= 1e-10 * np.max(np.abs(np.diag(R))):
        return []
    c0 = scipy.linalg.solve_triangular(R, Q.T @ y)
    r0 = y - X @ c0
    P = np.column_stack([v, det._sgn(v)])

    def suffix(a):
        out = np.zeros((a.shape[0] + 1,) + a.shape[1:])
        out[:-1] = np.cumsum(a[::-1], axis=0)[::-1]
        return out

    G = suffix(P[:, :, None] * P[:, None, :])                       # C_k^T C_k
    S = suffix(X[:, :, None] * P[:, None, :])                       # X^T C_k
    b = suffix(P * r0[:, None])                                     # C_k^T r
    ks = np.arange(max(int(min_len), 1), n - max(int(min_len), 1) + 1)
    Sk = S[ks]
    Z = scipy.linalg.solve_triangular(R, Sk.transpose(1, 0, 2).reshape(p, -1), trans="T")
    W = scipy.linalg.solve_triangular(R, Z).reshape(p, ks.size, 2).transpose(1, 0, 2)   # (X^T X)^-1 X^T C_k
    K = G[ks] - np.einsum("kpi,kpj->kij", Sk, W)
    ok = np.linalg.det(K) > 1e-12 * np.maximum(np.trace(K, axis1=1, axis2=2), 1e-300) ** 2
    if not ok.any():
        return []
    ks, K, W, bk = ks[ok], K[ok], W[ok], b[ks][ok]
    d = np.linalg.solve(K, bk[:, :, None])[:, :, 0]
    rss = float(r0 @ r0) - np.sum(bk * d, axis=1)
    names = nominal_names(prep.robot_kind)
    ikv, ikc = names.index("kv"), names.index("kc")
    dX = -np.einsum("kpi,ki->kp", W, d)
    kv_b, kc_b = c0[ikv] + dX[:, ikv], c0[ikc] + dX[:, ikc]
    laws = [(kc_b, kv_b), (kc_b + d[:, 1], kv_b + d[:, 0])]
    speeds = det.extreme_speeds(jd.v[jd.rows])
    if speeds is None:
        return []
    slack = NEGATIVE_FRICTION_SIGMAS * float(sigma.get(j, 0.0))
    good = np.ones(ks.size, bool)
    for kc_, kv_ in laws:
        for sp in speeds:
            good &= kc_ + kv_ * sp >= -slack
    order = np.argsort(rss[good], kind="stable")
    return [int(k) for k in ks[good][order]]


def dissipative_change(prep, model, fit, sigma, ext, min_frac: float = 0.1):
    """Under :data:`DISSIPATIVE_CHANGE_RULE`: the abrupt change ``ext`` that :func:`negative_friction` refused, at the
    best switch of :func:`dissipative_switches` instead (:func:`~drake_est.diagnose.detectors.change_at_split`, with
    the same identifiability check and smooth alternative as the search); its evidence holds
    ``refused_t_change_s``.  None when no switch dissipates or the candidate there fails those checks."""
    j = ext.joint
    jd = prep.joints[j]
    ks = dissipative_switches(prep, model, fit, sigma, j, det.change_min_length(jd.train.sum(), min_frac))
    if not ks:
        return None
    ecols = _energy_cols(model, j)
    new = det.change_at_split(jd, _residual(prep, fit, j), ks[0], None, smooth_alternative=ecols is not None,
                              energy_cols=ecols)
    if new is None:
        return None
    new.evidence["refused_t_change_s"] = float(ext.spec["t_change"])
    return new


def _round(prep, model, fit, sigma, accepted, alpha, min_gain, cache=None, changed=None):
    """One round of candidates on ``model``'s residual: [(ext, test, fit1, model1)], each test with
    ``significant`` (:func:`_evaluate`)."""
    state = {}
    return pmap(lambda ext: _evaluate(prep, model, fit, sigma, ext, alpha, min_gain, state),
                _candidates(prep, model, fit, accepted, cache, changed))


def position_law_gain_concentrated_beside_dropped_rows(prep, fit, f1, ext) -> dict | None:
    """Where a law of a joint's position (``ext``, fitted as ``f1`` beside ``fit``'s model) holds its held-out gain,
    when the joint's held-out rows beyond the training positions were dropped in ``prepare``
    (``nominal.beyond_training_positions``) and the gain sits in a few of the paired groups
    (:func:`~drake_est.diagnose.competition.gain_concentration`); None otherwise (the ninety-seventh round,
    :data:`BEYOND_POSITIONS_CONCENTRATED_GAIN_RULE`).

    The rows beyond the training positions are those where a position law extrapolates; dropping them takes from the
    held-out blocks the rows where a spurious law predicts worst (loop spec 5586: an elastic gear at 1000 Hz, whose
    load passes the paired test once its 24 such rows are gone).  A law that the remaining blocks confirm in a few
    stretches only is then not confirmed: the paired test of so few units is the only check left, and the log does
    not repeat what would decide (87 % of 5586's load gain lies in 2 of its 20 groups; the planted load of 37492,
    which the drop mends, spreads its gain over 14 groups)."""
    if ext.shared or ext.effect not in comp.POSITION_LAWS:
        return None
    jd = prep.joints.get(ext.joint)
    if jd is None or not jd.counts.get("beyond_training_positions"):
        return None
    return comp.gain_concentration(prep, fit, f1, list(ext.cols), PAIRED_ALPHA)


def _evaluate(prep, model, fit, sigma, ext, alpha, min_gain, state, retry=True) -> tuple:
    """(ext, test, fit1, model1) of one candidate ``ext`` on ``model``'s residual; the test's ``significant``: the
    held-out F-test, gain, score, the quantization guard, no negative friction (an abrupt change refused there is
    evaluated again at the best switch that leaves a friction, :func:`dissipative_change`, when ``retry`` and
    :data:`DISSIPATIVE_CHANGE_RULE`; it stands in for the refused one when it passes every test), the paired
    held-out block test (:func:`~drake_est.diagnose.competition.paired_block_test` at :data:`PAIRED_ALPHA`) and, for a
    time-periodic
    candidate at a line of the motion, the free function of the state (``state``: the round's nuisance per joint)."""
    m1 = Model(prep, model.exts + [ext])
    f1 = m1.fit(sigma)
    tst = _test(prep, fit, f1, ext)
    tst["significant"] = bool(tst["p_value"] < alpha and tst["rmse_reduction"] >= min_gain and tst["score"] > 0)
    if tst["significant"] and not _above_quantization(prep, fit, f1, ext):
        why = {}
        lr = time_law_beyond_rounding(prep, m1, ext, why=why) if TIME_LAWS_BY_READINGS_LIKELIHOOD else None
        if lr is not None:
            tst["beyond_rounding_by_likelihood"] = lr
        else:
            tst["significant"] = False
            tst["below_quantization_step"] = True
            tst.update(why)
    if tst["significant"]:
        neg = negative_friction(prep, m1, f1, ext, sigma)
        if neg is not None and retry and DISSIPATIVE_CHANGE_RULE and ext.effect == "abrupt_change" and not ext.shared:
            # the switch the search chose leaves no friction somewhere: the best switch that leaves one instead,
            # when it passes every test (else the refused one's result stands)
            new = dissipative_change(prep, model, fit, sigma, ext)
            if new is not None:
                out = _evaluate(prep, model, fit, sigma, new, alpha, min_gain, state, retry=False)
                if out[1]["significant"]:
                    out[1]["refused_switch"] = {"t_change_s": float(ext.spec["t_change"]), **neg}
                    return out
        if neg is not None:
            tst["significant"] = False
            tst["negative_friction"] = neg
    if tst["significant"]:
        # the F-test counts every held-out sample as independent; a closed-loop residual is correlated over a
        # move, and a flexible candidate can fit such structure in-sample without predicting the held-out
        # blocks any better: the gain must also hold across the held-out blocks (paired test)
        paired = comp.paired_block_test(prep, fit, f1, list(ext.cols))
        tst["paired_p_value"] = paired["p_value"]
        if paired["p_value"] >= PAIRED_ALPHA:
            tst["significant"] = False
            tst["not_separated_on_held_out_blocks"] = True
            # where its gain lies when a few stretches hold it (the log does not repeat what would confirm
            # it: next_experiment says what would); reported, never used to decide
            where = comp.gain_concentration(prep, fit, f1, list(ext.cols), PAIRED_ALPHA)
            if where is not None:
                tst["gain_concentration"] = where
    if tst["significant"] and BEYOND_POSITIONS_CONCENTRATED_GAIN_RULE:
        where = position_law_gain_concentrated_beside_dropped_rows(prep, fit, f1, ext)
        if where is not None:
            tst["significant"] = False
            tst["gain_concentrated_beside_dropped_positions"] = True
            tst["gain_concentration"] = where
    if ((tst["significant"] or tst.get("below_quantization_step")) and "at_motion_line_hz" in ext.evidence
            and not ext.shared):
        # a time-periodic candidate at a line of the motion must beat a free function of the state (every misfit
        # of the model's laws of the state repeats at the motion's lines); tested here, not only when it wins its
        # round, since a rival within the margin makes the winner ambiguous with it -- and a rival held back by the
        # ADC guard alone is one too (_competition; loop spec 5334: a ripple made ambiguous with such a candidate)
        solve = _model_solver(model, ext.joint)
        t = motion_line_state_test(prep, model, fit, ext, alpha, min_gain, state, solve)
        tst["state_law_test"] = comp._brief(t)
        if not t["significant"]:
            tst["significant"] = False
            tst.pop("below_quantization_step", None)
            tst["explained_by_state_law"] = True
        elif tst["significant"]:
            # and keep its amplitude and phase from one half of the log to the other (a misfit at the motion's lines
            # that no function of the state explains, e.g. backlash, follows the moves instead)
            h = comp.holds_across_halves(prep, model, ext, alpha, min_gain, tst["rmse_reduction"], solve=solve)
            tst["half_gains"] = h["half_gains"]
            if not h["significant"]:
                tst["significant"] = False
                tst["not_held_across_halves"] = True
    return ext, tst, f1, m1


#: hundred-and-sixth round: the free function of the state that a time-periodic candidate at a line of the motion must
#: beat (:func:`_evaluate`) is also offered a free linear response to the joint's acceleration
#: (:func:`motion_line_state_extra`); rule: ``benchmarks/results/diagnose_motion_line_linear_response_round106_rule.txt``
MOTION_LINE_LINEAR_RESPONSE_RULE = True


def motion_line_state_extra(prep, j) -> dict | None:
    """With :data:`MOTION_LINE_LINEAR_RESPONSE_RULE`: the block ``linear_response`` (:func:`linear_response_nuisance`)
    offered, once the blocks of :func:`~drake_est.diagnose.competition.state_blocks` are chosen (``after``: the
    function keeps them all, so the rule can only take from a candidate's gain), to the free function of joint ``j``'s
    state that a time-periodic candidate at a line of the motion must beat; None without the rule.  A misfit
    that follows the motion is periodic at the motion's lines whether it is a function of the instantaneous state or a
    filter of the motion: an elastic gear's resonance adds a torque that is a linear response to the acceleration
    (fresh loop spec 44020: a resonance at 100 Hz on multisine moves over 300 s, named a disturbance at 0.149 Hz on the
    motion's 0.150 Hz line; given the state's function it gains 7.3 %, given a 30-lag response to the acceleration
    -0.1 %, while that response given it gains 32 %)."""
    if not MOTION_LINE_LINEAR_RESPONSE_RULE:
        return None
    return {"linear_response": linear_response_nuisance(prep, j)}


def motion_line_state_test(prep, model, fit, ext, alpha, min_gain, state, solve=None) -> dict:
    """The state test of a time-periodic candidate ``ext`` at a line of the motion
    (:func:`~drake_est.diagnose.competition.survives_state_law`) given the free function of its joint's state, offered
    :func:`motion_line_state_extra` after its own blocks; ``state`` caches that function's columns by joint for one
    round."""
    if ext.joint not in state:
        state[ext.joint] = comp.state_nuisance(prep, model, ext.joint, solve=solve,
                                               after=motion_line_state_extra(prep, ext.joint))
    return comp.survives_state_law(prep, model, fit, ext, alpha, min_gain, nuisance=state[ext.joint], solve=solve)


def motion_line_gate(prep, alpha: float = ALPHA, min_gain: float = MIN_GAIN) -> frozenset:
    """The joints on which the search offers a time-periodic candidate at a line of the motion
    (:func:`~drake_est.diagnose.detectors.time_periodic_at_motion_line`): those where the nominal model's residual
    shows one, i.e. that candidate passes every test of a round given the nominal model (:func:`_evaluate`: the
    held-out F-test, the gain, the ADC guard, the paired block test, the free function of the state and the halves of
    the log).  Decided once per diagnosis, on the data as first
    prepared: a disturbance that only shows once other findings are in stays unseen at a line of the motion (as
    before the thirty-third round), and every other diagnosis runs as before it."""
    model = Model(prep)
    fit = model.fit()
    sigma = {j: float(np.sqrt(fit.rss_val[j] / max(prep.joints[j].val.sum(), 1))) for j in prep.joints}
    out = set()
    for j, jd in prep.joints.items():
        e = det.time_periodic_at_motion_line(jd, _residual(prep, fit, j))
        if e is None:
            continue
        ext, tst, _, _ = _evaluate(prep, model, fit, sigma, e, alpha, min_gain, {})
        if tst["significant"]:
            out.add(j)
    return frozenset(out)


#: hundred-and-eighth round: an abrupt change that the final model names beside an energy drift of its joint must stay
#: significant given the drift refitted to Algorithm 6's fixed point (:func:`change_beside_drift_at_fixed_point`)
CHANGE_BESIDE_DRIFT_AT_FIXED_POINT_RULE = True


def _energy_candidate(prep, model, fit, j, until_settled=None):
    """Joint ``j``'s energy-drift candidate on the residual of ``model`` (as :func:`_candidates` proposes it)."""
    jd = prep.joints[j]
    return det.energy(jd, _residual(prep, fit, j), _nominal_friction(prep, fit, jd), _train_error_fn(model, jd),
                      energy_fn=energy_fn(prep), until_settled=until_settled)


def change_beside_drift_at_fixed_point(prep, model, sigma, alpha: float = ALPHA, min_gain: float = MIN_GAIN):
    """``(ext, why)`` of an abrupt change that the final model names beside an energy drift of its joint, when the
    change is not significant given the drift fitted to Algorithm 6's fixed point; None otherwise.

    The search fits a drift with two passes of the fixed-point iteration (:func:`~drake_est.diagnose.detectors.energy`);
    a drift that takes a large share of the Coulomb level changes the friction power that drives it, and two passes
    leave its state short of the fixed point, with a misfit in time that a change can take (fresh spec 45767, an
    energy drift alone at 10 Hz over 600 s: a change at 300 s, the log's thermal peak, lowered the held-out RMSE by
    7.2 % beside the drift).  The drift is fitted again on the residual of the model without the change and without
    the drift, with passes until the friction power settles; where it settled within the two passes nothing changes.
    The change's round is then run on the model with the settled drift in place of the search's (its own candidate
    as in :func:`finding_to_set_aside`); a change that is not significant there is returned, to be set aside."""
    if not CHANGE_BESIDE_DRIFT_AT_FIXED_POINT_RULE:
        return None
    for e in model.exts:
        if e.shared or e.effect != "abrupt_change":
            continue
        j = e.joint
        drift = next((x for x in model.own(j) if x.effect == "energy_dependent_friction"), None)
        if drift is None:
            continue
        rest = [x for x in model.exts if x is not e and x is not drift]
        m1 = Model(prep, rest)
        f1 = m1.fit(sigma)
        settled = _energy_candidate(prep, m1, f1, j, until_settled=True)
        passes = settled.evidence.get("fixed_point_passes")
        if passes is None:
            continue        # settled within the search's two passes: the drift the change was judged beside
        m0 = Model(prep, rest + [settled])
        f0 = m0.fit(sigma)
        acc = {(x.effect, None if x.shared else x.joint) for x in m0.exts}
        results = [r for r in _round(prep, m0, f0, sigma, acc, alpha, min_gain)
                   if not r[0].shared and r[0].joint == j]
        own = comp.better_first(r for r in results if r[0].effect == e.effect)
        if own and own[0][1]["significant"]:
            continue
        info = {"fixed_point_passes": int(passes), "time_constant_s": float(settled.spec["tau_e"]),
                "search_time_constant_s": float(drift.spec["tau_e"]),
                "w_moved_after_two_passes": float(settled.w_moved_after_fixed_passes),
                "p_value": own[0][1]["p_value"] if own else None}
        return e, {"reason": (f"not significant given the energy drift of its joint fitted to Algorithm 6's fixed point "
                              f"({passes} passes; after the search's two the friction power still moved by "
                              f"{100 * info['w_moved_after_two_passes']:.1f} %): the change took the misfit of a drift "
                              "short of its fixed point"),
                   "drift_at_fixed_point": info}
    return None


def energy_fixed_point_gate(prep) -> dict:
    """{joint: how far the friction power W still moves after the two passes of Algorithm 6} for the joints whose
    energy candidate on the nominal model's residual (the search's first round) has W move by more than
    :data:`~drake_est.diagnose.detectors.ENERGY_FIXED_POINT_TOL` after them: where further passes
    (:data:`~drake_est.diagnose.detectors.ENERGY_FIXED_POINT_RULE`) would act in the first round.  A screen, not an
    exact gate: a later round's candidate, on the residual of a larger model, can need further passes where the first
    did not."""
    model = Model(prep)
    fit = model.fit()
    out = {}
    for j in prep.joints:
        moved = _energy_candidate(prep, model, fit, j, until_settled=False).w_moved_after_fixed_passes
        if moved is not None and moved > det.ENERGY_FIXED_POINT_TOL:
            out[j] = moved
    return out


#: seventy-third round, tried and not kept (off): a finding the round run again without it does not find significant
#: is also tested as it stands in the model (:func:`_own_finding_given_others`); it removed 11558's wrong name and
#: mended 27443 and 20162, but gave 4035 one (an asymmetric level named beside a position friction and a disturbance)
OWN_FINDING_IN_ITS_CHECK = False


def _own_finding_given_others(prep, m0, f0, sigma, e, alpha, min_gain, own):
    """The check of :func:`finding_to_set_aside` runs the candidates again on the model without the finding ``e``,
    each detected afresh on that model's residual.  A fresh detection may pick another shape than the finding's (a
    position law's number of kernels is chosen by an inner split of the residual alone, not beside the other findings'
    columns), and a shape that the joint fit beside those columns does not carry can predict the held-out data worse
    than the model without it (loop spec 11558: a load beside Stribeck at 1000 Hz; the load as accepted, 16 kernels,
    lowers the held-out RMSE by 54 % given a drift and a level, the fresh one, 32 kernels, raises it by 54 %, and the
    load was set aside as not significant).  When the fresh one is not significant, ``e`` itself is evaluated given
    the others (:func:`_evaluate`): ``[(e, test, fit1, model1)]`` when it passes every test, else ``own``."""
    mine = _evaluate(prep, m0, f0, sigma, e, alpha, min_gain, {})
    if not mine[1]["significant"]:
        return own
    mine[1]["as_accepted"] = True
    return [mine]


#: seventy-fourth round: a position law whose fresh re-detection in :func:`finding_to_set_aside` chose another number
#: of kernels than the finding's, and is not significant, is tested as accepted (:func:`_position_law_as_accepted`)
POSITION_LAW_AS_ACCEPTED_IN_ITS_CHECK = True


def _position_law_as_accepted(prep, m0, f0, sigma, e, alpha, min_gain, own):
    """The seventy-third round's test of a finding as it stands (:func:`_own_finding_given_others`), for the one case
    its reason covers: ``e`` is a position law (:data:`~drake_est.diagnose.detectors.POSITION_KERNEL_LAWS`) and the
    fresh candidate of its effect, not significant given the other findings, has another number of kernels than
    ``e``.  The kernel count is a nuisance choice of the detector (an inner split of a quarter of the training rows
    each way), not the hypothesis under test, which is whether the joint has that position law given the others: the
    kernel count it was accepted with is tested as well (loop spec 11558: the load as accepted, 16 kernels, lowers
    the held-out RMSE by 54 % given a drift and a level; the fresh one, 32 kernels, raises it by 54 %).  Other
    effects, whose fresh detection is the same test as at their acceptance or a scan (a frequency, a change time),
    are checked as before (the seventy-third round's rule gave 4035 a wrong name through a disturbance's scan).
    Returns ``own`` unchanged when the case does not apply or ``e`` fails a test."""
    if e.effect not in det.POSITION_KERNEL_LAWS or not own or own[0][1]["significant"]:
        return own
    if own[0][0].evidence.get("n_kernels") == e.evidence.get("n_kernels"):
        return own
    return _own_finding_given_others(prep, m0, f0, sigma, e, alpha, min_gain, own)


#: (ninetieth round) a finding is not set aside for a rival closed on its joint earlier in the diagnosis (set aside
#: itself): that rival cannot be named, so the check would close both (:func:`finding_to_set_aside`, ``closed``)
CLOSED_RIVAL_RULE = True


def _closed_key(ext):
    """The (effect, joint) key of a candidate among run_diagnosis' closed findings (joint None for a shared one)."""
    return ext.effect, (None if ext.shared else int(ext.joint))


def closed_rival(e, rival, paired_p, shut) -> dict | None:
    """With :data:`CLOSED_RIVAL_RULE` (``shut`` is empty without it): the set-aside entry of ``rival`` when it is
    closed on its joint (in ``shut``, run_diagnosis' closed findings by :func:`_closed_key`) and would set the finding
    ``e`` aside in :func:`finding_to_set_aside` (it beats ``e`` on the paired held-out blocks, ``paired_p`` below
    :data:`PAIRED_ALPHA`, or is not separated from it with fewer parameters); None otherwise."""
    c = shut.get(_closed_key(rival))
    if c is None or not (paired_p < PAIRED_ALPHA or rival.n_params < e.n_params):
        return None
    return c


def _closed_rival_mark(e, own, rival, rival_tst, entry) -> dict:
    """Competition fields of a finding ``e`` (its test ``own``) whose higher-scoring ``rival`` (its test
    ``rival_tst``) was set aside earlier in the diagnosis for ``e``'s effect (``entry``: that set-aside): each explains
    the joint's residual better given the findings of its own model, so the log does not decide between them."""
    return {"ambiguous": True, "ambiguous_with": [rival.effect], "runner_up": rival.effect,
            "runner_up_joint": int(e.joint), "runner_up_score": float(rival_tst["score"]),
            "runner_up_significant": True, "margin": float(own["score"] - rival_tst["score"]),
            "closed_rival": {"effect": rival.effect, "set_aside_for": e.effect,
                             "paired_p_value_when_set_aside": entry.get("paired_p_value")},
            "reason": (f"{rival.effect} scores more given the other findings, but it was set aside earlier for "
                       f"{e.effect} (paired p = {entry.get('paired_p_value', float('nan')):.2g}): each explains the "
                       "joint's residual better given the findings of its own model, so the log does not decide "
                       "between the two; this one is kept")}


def finding_to_set_aside(prep, model, sigma, alpha, min_gain, ambiguous=None, closed=None):
    """Each accepted finding must still be the best explanation of its joint's residual when all the *other*
    findings are in the model (the forward search accepts greedily: a first finding that only stood in for
    effects found later, e.g. a position load fitted to an asymmetric Coulomb level and a Stribeck hump that
    repeats at the move ends, is otherwise kept).  For every per-joint finding in turn the round of candidates
    is run on the model without it: when the finding is no longer significant there (a later finding explains
    it), or another candidate of its joint that survives the same checks scores more than
    :data:`AMBIGUITY_MARGIN` above it, it is returned as ``(effect, joint, why)`` (the search is then run
    again without it); None when every finding holds.  The last finding is not checked: the model without it is
    the one of the round that accepted it, as the best significant candidate.  A rival must also predict the
    held-out blocks better beyond chance (:func:`~drake_est.diagnose.competition.paired_block_test` at
    :data:`PAIRED_ALPHA`); when it does not, the finding stays and ``ambiguous[(effect, joint)]`` receives the
    competition fields that report it as ambiguous between the two.  ``closed``: the findings set aside so far in the
    diagnosis (run_diagnosis' entries, each with ``effect``, ``joint`` and, when a rival put it aside, ``better``);
    with :data:`CLOSED_RIVAL_RULE` a rival closed on the finding's joint does not set the finding aside (it cannot be
    named: loop spec 33077, an asymmetric level beside Stribeck, lost the load to the level and then the level to the
    closed load, and an abrupt change and a position friction took their place); the best rival that is not closed
    is judged instead, and when the closed one was set aside for this finding's effect the finding is reported
    ambiguous with it (:func:`_closed_rival_mark`)."""
    shut = {}
    if CLOSED_RIVAL_RULE and closed:
        shut = {(c["effect"], c.get("joint")): c for c in closed}
    for e in list(model.exts)[:-1]:
        if e.shared:
            continue
        others = [x for x in model.exts if x is not e]
        m0 = Model(prep, others)
        f0 = m0.fit(sigma)
        acc = {(x.effect, None if x.shared else x.joint) for x in others}
        results = [r for r in _round(prep, m0, f0, sigma, acc, alpha, min_gain)
                   if not r[0].shared and r[0].joint == e.joint]
        own = comp.better_first(r for r in results if r[0].effect == e.effect)
        if OWN_FINDING_IN_ITS_CHECK and (not own or not own[0][1]["significant"]):
            own = _own_finding_given_others(prep, m0, f0, sigma, e, alpha, min_gain, own)
        elif POSITION_LAW_AS_ACCEPTED_IN_ITS_CHECK:
            own = _position_law_as_accepted(prep, m0, f0, sigma, e, alpha, min_gain, own)
        if not own or not own[0][1]["significant"]:
            return e.effect, e.joint, {"reason": NOT_SIGNIFICANT_GIVEN_OTHERS,
                                       "p_value": own[0][1]["p_value"] if own else None}
        rivals = [r for r in results if r[0].effect != e.effect and r[1]["significant"]
                  and r[1]["score"] > own[0][1]["score"] + AMBIGUITY_MARGIN]
        if ambiguous is not None:
            _mark_tied_rivals(ambiguous, e, own[0][1], results)
        while rivals:
            best, _ = _best_surviving(prep, m0, f0, rivals, alpha, min_gain)
            paired = info = None
            if best is not None:
                paired = comp.paired_block_test(prep, own[0][2], best[2], [e.joint])
                info = {"better": best[0].effect, "score": float(own[0][1]["score"]),
                        "better_score": float(best[1]["score"]), "paired_statistic": paired["statistic"],
                        "paired_p_value": paired["p_value"], "paired_groups": paired["groups"]}
                c = closed_rival(e, best[0], paired["p_value"], shut)
                if c is not None:
                    # the rival would set the finding aside, but it is closed: it cannot be named
                    if c.get("better") == e.effect and ambiguous is not None:
                        mark = _closed_rival_mark(e, own[0][1], best[0], best[1], c)
                        had = [x for x in ambiguous.get((e.effect, e.joint), {}).get("ambiguous_with", [])
                               if x != best[0].effect]
                        mark["ambiguous_with"] += had
                        ambiguous[(e.effect, e.joint)] = mark
                    rivals = [r for r in rivals if _closed_key(r[0]) not in shut]
                    continue
            break
        if rivals and best is not None:
            if paired["p_value"] < PAIRED_ALPHA:
                return e.effect, e.joint, {"reason": f"{best[0].effect} explains the joint's residual better "
                                                     "given the other findings", **info}
            # the finding beat the rival in its round, the rival scores higher given the later findings, and the
            # held-out blocks do not separate them: the order decided, not the data.  Reported as ambiguous
            # between the two; the model keeps the one with fewer parameters (parsimony)
            if best[0].n_params < e.n_params:
                return e.effect, e.joint, {
                    "reason": f"{best[0].effect} explains the joint's residual as well given the other findings "
                              f"(not separated on the held-out blocks, paired p = {paired['p_value']:.2g}) with "
                              f"fewer parameters ({best[0].n_params} < {e.n_params})",
                    "not_separated": True, **info}
            if ambiguous is not None:
                tied = ambiguous.get((e.effect, e.joint), {}).get("ambiguous_with", [])
                ambiguous[(e.effect, e.joint)] = _not_separated(best[0].effect, e.joint, own[0][1]["score"],
                                                                best[1]["score"], paired["p_value"])
                if tied:
                    ambiguous[(e.effect, e.joint)]["ambiguous_with"] = [best[0].effect] + [
                        x for x in tied if x != best[0].effect]
    return None


#: the two laws in time that a log often does not separate (an abrupt change, a drift with the dissipated energy):
#: the laws whose periodic nuisance is floored, :data:`~drake_est.diagnose.competition.FLOORED_LAWS`
TIME_LAW_PAIR = comp.FLOORED_LAWS


def _fewer_findings_alternative(prep, fit, law, joint, others, closed, max_findings, alpha, min_gain):
    """The test shared by :func:`time_law_alternative` and :func:`set_aside_time_law_alternative`: the search run with
    ``closed`` (the blocked findings) names the law in time ``law`` on ``joint`` and only some of ``others`` (the final
    model's other findings, none new), and the paired held-out blocks do not show the final model (``fit``) predicting
    the joint better (:func:`~drake_est.diagnose.competition.paired_block_test` at :data:`PAIRED_ALPHA`).  Returns
    ``(alternative search output, info)`` (both held-out RMSEs, the paired p, the findings dropped), else None."""
    alt = _search(prep, max_findings, alpha, min_gain, closed)
    got = {(x.effect, None if x.shared else x.joint) for x in alt[5].exts}
    if (law, joint) not in got or not got - {(law, joint)} < others:
        return None
    paired = comp.paired_block_test(prep, alt[4], fit, [joint])
    if paired["p_value"] < PAIRED_ALPHA:
        return None
    rm, ra = _val_metrics(prep, fit, [joint])["rmse"], _val_metrics(prep, alt[4], [joint])["rmse"]
    info = {"alternative_findings": sorted(x for x, _ in got), "dropped": sorted(x for x, _ in others - got),
            "heldout_rmse": float(ra), "heldout_rmse_of_final_model": float(rm),
            "paired_p_value": float(paired["p_value"]), "paired_groups": paired["groups"],
            "groups_final_model_better": paired["groups_better"]}
    return alt, info


def time_law_alternative(prep, out, max_findings, alpha, min_gain, blocked=frozenset()):
    """A law in time (:data:`TIME_LAW_PAIR`) named ambiguous with the other one, beside further findings of its
    joint: the search run again with the named one closed fits the rival in its place.  When that alternative names
    the rival and only some of the other findings (none new) and the held-out blocks do not show the final model
    predicting the joint better (:func:`~drake_est.diagnose.competition.paired_block_test` at
    :data:`PAIRED_ALPHA`), the further findings only absorbed the misfit of the law the greedy order happened to
    choose (loop spec 10526: an abrupt change named as an energy drift, ambiguous with the change, and the drift's
    misfit fitted by a position friction, not planted; with the change in its place a motor ripple alone explains
    the rest).  The log then does not decide between the two laws, and the one that needs fewer findings is kept.
    Returns ``(effect, joint, rival, alternative search output, info)`` of the first such finding, else None."""
    steps, fit, model = out[3], out[4], out[5]
    named = {(x.effect, None if x.shared else x.joint) for x in model.exts}
    for st in steps:
        e = st.ext
        if e.shared or e.effect not in TIME_LAW_PAIR or not st.competition.get("ambiguous"):
            continue
        rival = TIME_LAW_PAIR[1 - TIME_LAW_PAIR.index(e.effect)]
        if rival not in comp.ambiguous_rivals(st.competition) or (rival, e.joint) in named:
            continue
        others = named - {(e.effect, e.joint)}
        if not any(j == e.joint for _, j in others):
            continue
        found = _fewer_findings_alternative(prep, fit, rival, e.joint, others, set(blocked) | {(e.effect, e.joint)},
                                            max_findings, alpha, min_gain)
        if found is not None:
            return e.effect, e.joint, rival, found[0], found[1]
    return None


#: (ninety-second round) a law in time set aside as not significant given the other findings, where the final model
#: names the other law in time on its joint beside further findings: the search is run again with the named law closed
#: and the set-aside one open (:func:`set_aside_time_law_alternative`)
SET_ASIDE_TIME_LAW_ALTERNATIVE = True

#: the reason :func:`finding_to_set_aside` gives a finding that a later one made redundant
NOT_SIGNIFICANT_GIVEN_OTHERS = "not significant given the other findings"


def set_aside_time_law_alternative(prep, out, set_aside, max_findings, alpha, min_gain, blocked=frozenset()):
    """A law in time (:data:`TIME_LAW_PAIR`) set aside as not significant given the other findings, while the final
    model names the other law in time on its joint beside further findings: the later law and the further findings
    together took what the first one explained, and the set-aside check, which removes one finding at a time, cannot
    compare the two models (loop spec 35738: an abrupt change beside a motor ripple at 10 Hz; the change and the
    ripple were found first, an energy drift and a position friction beside them, the change was then not significant
    given those, and with it closed the drift, the friction and a load were named).  The search is run again with the
    named law closed and the set-aside one open.  When that alternative names the set-aside law and only some of the
    final model's other findings (none new), and the held-out blocks do not show the final model predicting the joint
    better (:func:`~drake_est.diagnose.competition.paired_block_test` at :data:`PAIRED_ALPHA`), the log does not decide
    between the two laws, and the one that needs fewer findings is kept (as :func:`time_law_alternative` does for a
    law named ambiguous with the other).  ``set_aside``: run_diagnosis' entries so far.  Returns ``(effect, joint,
    rival, alternative search output, info)`` (``effect`` the set-aside law, ``rival`` the named one) of the first
    such entry, else None; None always without :data:`SET_ASIDE_TIME_LAW_ALTERNATIVE`."""
    if not SET_ASIDE_TIME_LAW_ALTERNATIVE:
        return None
    fit, model = out[4], out[5]
    named = {(x.effect, None if x.shared else x.joint) for x in model.exts}
    for entry in set_aside:
        effect, joint = entry["effect"], entry.get("joint")
        if effect not in TIME_LAW_PAIR or entry.get("reason") != NOT_SIGNIFICANT_GIVEN_OTHERS:
            continue
        rival = TIME_LAW_PAIR[1 - TIME_LAW_PAIR.index(effect)]
        if (rival, joint) not in named or (effect, joint) in named:
            continue
        others = named - {(rival, joint)}
        if not any(j == joint for _, j in others):
            continue
        found = _fewer_findings_alternative(prep, fit, effect, joint, others,
                                            (set(blocked) - {(effect, joint)}) | {(rival, joint)},
                                            max_findings, alpha, min_gain)
        if found is not None:
            return effect, joint, rival, found[0], {**found[1], "set_aside_before": dict(entry)}
    return None


def level_alternatives(prep, model, fit, max_findings, alpha, min_gain, blocked=frozenset()) -> dict:
    """The model-level rival of a finding that contains its joint's asymmetric Coulomb level (a position load:
    its kernels sum to a constant over the positions visited, and a constant torque while moving is that level
    given the nominal [qd, sign(qd)], :func:`_contains`).  The rounds compare the two given the findings of their
    time, whose shapes (a Stribeck law's, say) were fitted beside the load; the search run again with the finding
    closed fits them beside the level instead.  When it ends at the same findings with the level in the finding's
    place and the held-out blocks do not show the final model predicting the joint better than that alternative
    (:func:`~drake_est.diagnose.competition.paired_block_test` at :data:`PAIRED_ALPHA`), the log does not decide
    between the two explanations of the offset (loop spec 5775: an asymmetric level beside a Lorentzian Stribeck
    law at 250 Hz, named as a position load).  Returns ``{(effect, joint): competition fields}`` of such findings
    (the model is not changed)."""
    out = {}
    named = {(x.effect, None if x.shared else x.joint) for x in model.exts}
    for e in model.exts:
        if e.shared:
            continue
        lvl = det.asymmetric(prep.joints[e.joint], None)
        if lvl is None or (lvl.effect, e.joint) in named or not _contains(prep, e, lvl):
            continue
        alt = _search(prep, max_findings, alpha, min_gain, set(blocked) | {(e.effect, e.joint)})
        got = {(x.effect, None if x.shared else x.joint) for x in alt[5].exts}
        if got != (named - {(e.effect, e.joint)}) | {(lvl.effect, e.joint)}:
            continue
        paired = comp.paired_block_test(prep, alt[4], fit, [e.joint])
        if paired["p_value"] < PAIRED_ALPHA:
            continue
        rm, ra = _val_metrics(prep, fit, [e.joint])["rmse"], _val_metrics(prep, alt[4], [e.joint])["rmse"]
        out[(e.effect, e.joint)] = {
            "ambiguous": True, "ambiguous_with": [lvl.effect], "runner_up": lvl.effect,
            "runner_up_joint": int(e.joint), "runner_up_significant": True, "paired_p_value": float(paired["p_value"]),
            "alternative_model": {"findings": sorted(x for x, _ in got), "heldout_rmse": float(ra),
                                  "heldout_rmse_of_final_model": float(rm), "paired_groups": paired["groups"],
                                  "groups_final_model_better": paired["groups_better"]},
            "reason": (f"with {e.effect} closed the search ends at the same findings with {lvl.effect} in its place "
                       f"(held-out RMSE {ra:.3g} against {rm:.3g}), and the held-out blocks do not show the final "
                       f"model predicting better (paired p = {paired['p_value']:.2g}, {paired['groups_better']} of "
                       f"{paired['groups']} groups): the log does not decide between the two explanations of the "
                       "constant torque while moving")}
    return out


def _mark_tied_rivals(ambiguous, e, own, results) -> None:
    """A significant rival of a finding's joint that, given the other findings, scores within
    :data:`AMBIGUITY_MARGIN` of it or predicts the held-out data within :data:`MIN_GAIN` of its RMSE (:func:`_tie`,
    as for a round's rivals in :func:`_competition`): the greedy order chose the finding in an earlier round, the final
    model does not separate the two, so the finding is reported ambiguous with it (``ambiguous[(effect, joint)]``,
    the tied rivals under ``ambiguous_with``, best first).  Rivals that score higher are :func:`finding_to_set_aside`'s."""
    tied = []
    for r in results:
        if r[0].effect == e.effect or not r[1]["significant"] or r[1]["score"] > own["score"] + AMBIGUITY_MARGIN:
            continue
        tie, sep = _tie(own, r[1])
        if tie is not None:
            tied.append((r[1]["score"], r[0].effect, sep))
    if not tied:
        return
    tied.sort(key=lambda x: -x[0])
    names = [name for _, name, _ in tied]
    ambiguous[(e.effect, e.joint)] = {
        "ambiguous": True, "ambiguous_with": names, "runner_up": names[0], "runner_up_joint": int(e.joint),
        "runner_up_score": float(tied[0][0]), "runner_up_significant": True, "margin": float(own["score"] - tied[0][0]),
        "separation_given_the_other_findings": {name: (None if sep is None else float(sep)) for _, name, sep in tied},
        "reason": (f"given the other findings, {' and '.join(names)} predict{'s' if len(names) == 1 else ''} the "
                   f"held-out data as well (within {100 * MIN_GAIN:g} % of the RMSE or {AMBIGUITY_MARGIN:g} in "
                   "score): the order of the search chose this finding, not the data")}


def _resolve_named_rivals(steps, checked) -> None:
    """An ambiguity "A or B" that the data resolve as "A and B": when the rival B a finding was not separated from
    in its round is itself a finding of the same joint in the final model, the finding was accepted given B (B came
    first) or held in :func:`finding_to_set_aside`'s check given B (B came later; ``checked``: that check ran on the
    final model), so the held-out data need both.  B is dropped from ``ambiguous_with`` and listed under
    ``resolved_with``.  A law in time confounded with a free friction curve (``confounded_with_speed``) stays
    ambiguous: a named Stribeck law is one such curve, not all of them."""
    named = {(st.ext.effect, None if st.ext.shared else st.ext.joint) for st in steps}
    for i, st in enumerate(steps):
        c = st.competition
        if not c.get("ambiguous") or c.get("confounded_with_speed"):
            continue
        if i < len(steps) - 1 and not checked:
            continue
        rivals = comp.ambiguous_rivals(c)
        j = None if st.ext.shared else st.ext.joint
        done = [r for r in rivals if r is not None and r != st.ext.effect and ((r, j) in named or (r, None) in named)]
        if not done:
            continue
        left = [r for r in rivals if r not in done]
        c = dict(c, resolved_with=done, ambiguous=bool(left))
        c["reason"] = ((c.get("reason") + "; " if c.get("reason") else "")
                       + f"{' and '.join(done)} also named: the held-out data need both")
        if left:
            c["ambiguous_with"] = left
        else:
            c.pop("ambiguous_with", None)
        st.competition = c


def _not_separated(rival, joint, score, rival_score, p_value) -> dict:
    """Competition fields of a finding that a rival of its joint is not separated from on the held-out blocks
    (:func:`finding_to_set_aside`): ambiguous between the two."""
    return {"ambiguous": True, "runner_up": rival, "runner_up_joint": int(joint), "runner_up_score": float(rival_score),
            "runner_up_significant": True, "margin": float(score - rival_score),
            "reason": f"{rival} explains the joint's residual as well given the other findings: the held-out blocks "
                      f"do not separate them (paired p = {p_value:.2g}); the one with fewer parameters is kept",
            "paired_p_value": float(p_value)}


#: a rival must beat a finding at this level in the paired held-out block test (:func:`~drake_est.diagnose.
#: competition.paired_block_test`) for the finding to be set aside; otherwise the two are reported as ambiguous
PAIRED_ALPHA = 0.05
#: seventy-first round: a round's winner stands beside a higher-scoring rival of its joint that failed only the
#: paired block test when the winner does not predict the held-out blocks better than that rival (:func:`_competition`)
HELD_BACK_RIVALS = True


#: when the final residual of a joint still holds structure (the "unexplained" verdict), the model is
#: misspecified and the held-out F-test's null (white residual) does not hold.  A finding accepted after another
#: one on its joint was fitted to what the earlier findings left, misfit of their shapes included, and a small
#: gain there can come from soaking up part of that misfit rather than from an effect.  Such a later finding is
#: then confirmed only when it lowered the held-out RMSE of its joint(s) by at least this fraction in its round
#: (instead of :data:`MIN_GAIN`); one that did not is set aside (:func:`finding_not_confirmed`).  The first
#: finding of a joint, the best of every candidate against the nominal model, keeps the usual tests.
MIN_GAIN_NOT_WHITE = 0.15
#: how many findings may be set aside as not confirmed by a residual that is not white (each one closes its effect
#: on its joint and the search runs again).  A bound on the work only: a weak finding met after it is named.  Three
#: (before the thirty-fifth round) named one in a Stribeck law twice the generator's size (loop seed 3, 100 Hz), whose
#: shape misfit (5 x the noise) three weak candidates soaked up in turn before a fourth, an energy drift of 6 %, was met
MAX_NOT_CONFIRMED = 8
#: how often the search is run again after a finding was set aside (:func:`finding_to_set_aside`)
MAX_SET_ASIDE = 2


#: blocks of :func:`~drake_est.diagnose.competition.state_blocks` that a disturbance drives itself: in closed loop a
#: torque from outside the axis moves it, and the acceleration (and its derivative) carries the disturbance's own
#: frequency, so a function of them takes a real disturbance (loop spec 5597: a planted 15 Hz disturbance, 50 % lower
#: held-out RMSE alone, kept 2.0 % given the blocks with them).  :func:`disturbance_explained_by_state` leaves them out.
DISTURBANCE_DRIVEN_BLOCKS = ("inertia", "jerk")


def disturbance_explained_by_state(prep, model, alpha, min_gain):
    """A time-periodic finding of the final model off the motion's lines (no ``at_motion_line_hz``: the search tests
    one at a line against the state in its round, :func:`_evaluate`) must still predict its joint's held-out residual
    given the other findings and a free function of the joint's state
    (:func:`~drake_est.diagnose.competition.state_nuisance`, blocks chosen forward on the model without it, not those
    of :data:`DISTURBANCE_DRIVEN_BLOCKS`), unless the disturbance alone predicts that residual better than the state's
    function alone does.  A disturbance from outside the axis does not follow the axis' position, speed and
    direction; where the moves are slow, a misfit of the model's laws of the state is slow in time too and a sinusoid
    in time of a few periods per log fits it (loop spec 10942: a load beside a Stribeck hump at 250 Hz, the moves
    below twice the Stribeck speed, took a disturbance at 0.087 Hz with 17 % lower held-out RMSE that adds nothing
    given the state).  Returns the first finding the state explains as ``(effect, joint, why)`` (set aside, the
    search run again without it), None when every one holds."""
    for e in model.exts:
        if e.effect != "time_periodic_disturbance" or e.shared or "at_motion_line_hz" in e.evidence:
            continue
        m0 = Model(prep, [x for x in model.exts if x is not e])
        got = _state_explains(prep, m0, e.joint, e.cols[e.joint], alpha, min_gain, without=DISTURBANCE_DRIVEN_BLOCKS)
        if got is not None:
            return e.effect, e.joint, _state_entry(e.joint, got, "", "the disturbance", "the disturbance alone", "; a "
                                                   "disturbance from outside the axis does not follow its state")
    return None


def _state_explains(prep, m0, j, C, alpha, min_gain, without=(), rows=None, extra=None, chosen=None):
    """Whether a free function of joint ``j``'s state (:func:`~drake_est.diagnose.competition.state_nuisance`, its
    blocks chosen forward on the model ``m0`` without the finding, ``without``: blocks left out) explains the finding
    whose columns are ``C``: given the function they do not predict the held-out residual (partial held-out F-test at
    ``alpha``, gain ``min_gain``), and the function alone predicts it at least as well as they do alone.  The second
    condition: where the finding alone predicts the held-out residual better than the state's function does, the two
    are collinear on the training rows (a slow disturbance under slow moves) and the state's columns took the
    finding's part there, not the reverse (loop spec 3037: a planted 0.5 Hz disturbance at 10 Hz, 67 % lower held-out
    RMSE alone, 15 % higher given the state's 14 columns, which were chosen to predict the residual with the
    disturbance still in it).  ``(N, test given the function, own RMSE reduction, the function's)``, else None.  The
    checks of :func:`disturbance_explained_by_state` and :func:`time_law_explained_by_state`.  ``rows``: (fit rows,
    compared rows) instead of the joint's training and held-out rows (:func:`_state_tests`); ``extra``: more blocks
    offered to the function, ``chosen``: a list the joined blocks' names are appended to."""
    got = _state_tests(prep, m0, j, C, alpha, min_gain, without=without, rows=rows, extra=extra, chosen=chosen)
    if got is None or got[3] < got[2]:
        return None
    return got


def _state_tests(prep, m0, j, C, alpha, min_gain, without=(), chosen=None, rows=None, extra=None):
    """The finding with columns ``C`` against a free function of joint ``j``'s state
    (:func:`~drake_est.diagnose.competition.state_nuisance` on the model ``m0`` without it, ``without``: blocks left
    out, ``chosen``: a list the joined blocks' names are appended to): None when no block joins the function (none
    lowers the held-out error: nothing of the state to explain ``C``) or ``C`` predicts the held-out residual given the
    function (partial held-out F-test at ``alpha``, gain ``min_gain``), else ``(N, that test, C's own RMSE reduction,
    the function's)`` (:func:`_state_explains`, :func:`mark_disturbance_confounded_with_state`).  ``rows`` = (fit
    rows, compared rows), boolean over the joint's used rows, instead of its training and held-out rows (the blocks
    chosen and every test made on them); ``extra``: more blocks offered to the function
    (:func:`~drake_est.diagnose.competition.state_nuisance`)."""
    solve = _model_solver(m0, j)
    N = comp.state_nuisance(prep, m0, j, solve=solve, without=without, chosen=chosen, rows=rows, extra=extra)
    if not N.shape[1]:
        return None
    t = comp._partial_test(prep, m0, j, N, C, alpha, min_gain, solve, rows=rows)
    if t["significant"]:
        return None
    zero = np.zeros((C.shape[0], 0))
    own = comp._partial_test(prep, m0, j, zero, C, alpha, min_gain, solve, rows=rows)["rmse_reduction"]
    state = comp._partial_test(prep, m0, j, zero, N, alpha, min_gain, solve, rows=rows)["rmse_reduction"]
    return N, t, own, state


#: (ninety-first round) the checks of a law in time against a free function of the state
#: (:func:`_state_explains_one_way`) leave out the held-out rows faster than
#: :data:`~drake_est.diagnose.nominal.EXTRAPOLATION_FACTOR` times the joint's fastest training row
STATE_CHECK_WITHIN_TRAINING_SPEEDS = True


def state_check_rows(prep, j):
    """With :data:`STATE_CHECK_WITHIN_TRAINING_SPEEDS`: ``((training rows, held-out rows without the fast ones), how
    many were left out)`` when joint ``j`` has held-out rows faster than
    :data:`~drake_est.diagnose.nominal.EXTRAPOLATION_FACTOR` times its fastest training row
    (:func:`~drake_est.diagnose.nominal.faster_than_training`), else ``(None, 0)`` (the joint's own rows).  The free
    function of the state is a curve of the training speeds that holds its last value beyond them
    (:func:`~drake_est.diagnose.competition.speed_law_nuisance`), while a law in time carries the nominal [qd, sign(qd)]
    step of its segments: a few held-out samples of a move faster than any training one then decide which of the
    two predicts better, on the curve's extrapolation, not on the speeds both were fitted on (fresh loop spec 33429: an
    asymmetric level beside Stribeck at 100 Hz, 90 of 3,067 held-out samples at 0.35 rad/s against at most 0.17 in
    training; with them the state's function alone lowers the held-out RMSE by 74 % and the abrupt change named
    alone keeps 40 % given it, without them 89 % and 0.7 %)."""
    if not STATE_CHECK_WITHIN_TRAINING_SPEEDS:
        return None, 0
    jd = prep.joints[j]
    far = faster_than_training(jd.v[jd.rows], jd.train)
    n = int(far.sum())
    return ((jd.train, jd.val & ~far), n) if n else (None, 0)


def _state_explains_one_way(prep, m0, j, C, alpha, min_gain, extra=None, chosen=None):
    """``(what _state_explains returned, the function's partial test given C)`` when a free function of joint ``j``'s
    state explains the finding with columns ``C`` (:func:`_state_explains`) and, given ``C``, still predicts the
    held-out residual (partial held-out F-test at ``alpha``, gain ``min_gain``); None otherwise.  Where the function
    explains the finding and the finding explains the function back, the two are kept apart only by the finding,
    which then stays (a change of the friction over the log that the moves make look like a function of the state).
    The checks of :func:`time_law_explained_by_state` (fifty-third round) and
    :func:`sole_time_law_explained_by_state` (fifty-second round).  Returns ``(got, back, left out)``: the held-out
    rows of :func:`state_check_rows` left out of every test (ninety-first round), 0 when none.  ``extra``: more
    blocks offered to the function (:func:`_state_tests`), ``chosen``: a list the joined blocks' names are appended
    to."""
    got = _state_explains_with_back(prep, m0, j, C, alpha, min_gain, extra=extra, chosen=chosen)
    return got if got is not None and got[1]["significant"] else None


def _state_explains_with_back(prep, m0, j, C, alpha, min_gain, extra=None, chosen=None):
    """``(what _state_explains returned, the function's partial test given C, held-out rows left out)`` on the rows of
    :func:`state_check_rows` where a free function of joint ``j``'s state explains the finding with columns ``C``,
    None otherwise: the tests :func:`_state_explains_one_way` (the function still predicts given ``C``) and
    :func:`mark_time_law_beside_untestable_stribeck` (it does not) read."""
    rows, n_far = state_check_rows(prep, j)
    got = _state_explains(prep, m0, j, C, alpha, min_gain, rows=rows, extra=extra, chosen=chosen)
    if got is None:
        return None
    back = comp._partial_test(prep, m0, j, C, got[0], alpha, min_gain, _model_solver(m0, j), rows=rows)
    return got, back, n_far


def _beyond_speeds_note(why, n_far) -> dict:
    """The set-aside entry ``why`` of a law in time that a function of the state explains, with the held-out rows
    left out of the tests (:func:`state_check_rows`) said and counted."""
    if n_far:
        why["reason"] += (f" ({n_far} held-out samples faster than {EXTRAPOLATION_FACTOR:g} times the fastest "
                          "training sample left out of the comparison: the function is not known there)")
        why["held_out_rows_beyond_training_speeds"] = n_far
    return why


def _state_entry(j, got, beside, what, alone, tail):
    """The set-aside entry of a finding a free function of joint ``j``'s state explains (``got``: what
    :func:`_state_explains` returned): the reason (``beside``: after the columns' count, ``what``: the finding,
    ``alone``: it alone, ``tail``: the cause) and the partial tests."""
    N, t, own, state = got
    return {
        "reason": (f"explained by a function of the state of joint {j} (position, speed, direction and the time since "
                   f"the last reversal; {N.shape[1]} columns){beside}: given it and the other findings {what} lowers "
                   f"the held-out RMSE by {100 * t['rmse_reduction']:.1f} % (p = {t['p_value']:.2g}), not "
                   f"significantly, while the state's function alone lowers it by {100 * state:.1f} % ({alone} by "
                   f"{100 * own:.1f} %){tail}"),
        "explained_by_state": True, "state_law_test": comp._brief(t), "state_columns": int(N.shape[1]),
        "heldout_rmse_reduction_alone": float(own), "state_heldout_rmse_reduction": float(state)}


def time_law_explained_by_state(prep, model, steps, alpha, min_gain):
    """A friction law in time (an energy drift or an abrupt change) of the final ``model`` on a joint that also holds
    a law of the state, which a free function of the joint's state explains (:func:`_state_explains`: given the other
    findings and the function, :func:`~drake_est.diagnose.competition.state_nuisance` -- position, speed, direction
    and the time since the last reversal, blocks chosen forward on the model without the law -- its columns do not
    predict the joint's held-out residual, partial held-out F-test at ``alpha``, gain ``min_gain``, and the function
    alone predicts that residual at least as well as the law alone).  A drift or a change of the friction over the log
    is not a function of the state; the misfit of a law of the state's fixed shape is, and where the moves of the log
    differ between its parts a law in time takes it.  The laws checked (:func:`_time_laws_beside_state`): beside a
    Stribeck law, every one (forty-sixth round); beside another law of the state (a load, a position friction, an
    asymmetric level, a ripple), only one whose ``steps`` do not report it ambiguous with a law of the state
    (forty-eighth round): there the law in time stands for that law, and setting it aside loses the law (loop specs
    4320 and 1152 in the forty-seventh round: an energy drift ambiguous with Stribeck beside a load).
    A law the function explains is kept when, given the law, the function does not predict the held-out residual
    either (fifty-third round, as :func:`sole_time_law_explained_by_state`): the two then explain each other and only
    the law keeps them apart (loop spec 11098 on an AVX2 CPU, a planted change beside a ripple).  Beside a Stribeck
    law the function is also offered the derivative filter's error through the friction curve's slope
    (:func:`filter_slope_block`, hundred-and-second round; the entry then holds ``filter_slope_chosen`` where that
    block joined the function).  Where the function and the law explain each other on a joint that cannot test a
    Stribeck law, :func:`mark_time_law_beside_untestable_stribeck` reports the kept law ambiguous with ``stribeck``
    once the search ends (hundred-and-third round).
    :func:`time_law_within_speed_curve` holds the law against a curve of the speed only, which does not see direction
    or how long ago the joint reversed.  Loop spec 13761 (beside Stribeck): an asymmetric level beside Stribeck at 10
    Hz with Student-t noise; an abrupt change named with the level's part, ambiguous with a load, lowers the held-out
    RMSE by 6.7 % given the curve, by 1.3 % given the state's function, which alone lowers it by 60 %, the change alone
    by 43 %.  Loop spec 4345 (beside a position friction): an asymmetric level beside Stribeck at 100 Hz, reported as a
    position friction ambiguous with Stribeck and a load, and an energy drift named outright; given the state the
    drift lowers the held-out RMSE by -0.6 %, the state alone by 23 %, the drift alone by 20 %.  Returns the first such
    law as ``(effect, joint, why)``, else None."""
    for e, beside in _time_laws_beside_state(model, steps, named_rivals=True):
        j = e.joint
        # one way only (loop spec 11098 on an AVX2 CPU: a planted change beside a ripple at 1000 Hz, 0.6 % given the
        # function, the function alone 64.7 %, the change alone 64.3 %)
        extra = filter_slope_block(prep, j) if beside == ["stribeck"] else None
        chosen = []
        one_way = _state_explains_one_way(prep, Model(prep, [x for x in model.exts if x is not e]), j, e.cols[j],
                                          alpha, min_gain, extra=extra, chosen=chosen)
        if one_way is not None:
            got = one_way[0]
            if beside == ["stribeck"]:
                where, cause = " beside its Stribeck law", "the Stribeck law's shape"
            else:
                laws = " and ".join(x.replace("_", " ") for x in beside)
                where, cause = f" beside its {laws}", f"the fixed shape of its {laws}"
            slope = extra is not None and "filter_slope" in chosen
            if slope:
                where += (", the function holding the derivative filter's error through the friction curve's slope "
                          "(the jerk times kernels in |qd|)")
                cause += " and of the filtered speed"
            why = _state_entry(j, got, where, f"the {e.effect.replace('_', ' ')}", "the law alone",
                               f": the misfit of {cause}, not a change of the friction over the log")
            if slope:
                why["filter_slope_chosen"] = True
            named = _state_rivals_named_beside(model, steps, e) if beside != ["stribeck"] else []
            if named:
                why["ambiguous_with_named_beside"] = named
            return e.effect, j, _beyond_speeds_note(why, one_way[2])
    return None


#: hundred-and-second round: the forty-sixth round's check of a law in time beside a Stribeck law against a free
#: function of the joint's state (:func:`time_law_explained_by_state`) offers that function the derivative filter's
#: error through the friction curve's slope too (:func:`filter_slope_block`), as the hundred-and-first round's rescue
#: check does
TIME_LAW_BESIDE_STRIBECK_FILTER_SLOPE_RULE = True


def filter_slope_block(prep, j) -> dict | None:
    """With :data:`TIME_LAW_BESIDE_STRIBECK_FILTER_SLOPE_RULE`: ``{"filter_slope": columns}``
    (:func:`~drake_est.diagnose.competition.filter_slope_columns`), the block offered to the free function of joint
    ``j``'s state where :func:`time_law_explained_by_state` checks a law in time beside a Stribeck law; None with the
    rule off or where the training speeds span no range.  The derivative filter's error in qd grows with the jerk and
    reaches the torque through the friction curve's slope, steep at low speed beside a Stribeck hump; where the log
    moves differently in its parts, a law in time takes that misfit (fresh loop spec 41591: an asymmetric level beside
    Stribeck at 250 Hz with a quantized torque, an abrupt change at 70.7 s named beside them with 6 % lower held-out
    RMSE, where the jerk alone beside the level and the Stribeck law lowers it by 9 %)."""
    if not TIME_LAW_BESIDE_STRIBECK_FILTER_SLOPE_RULE:
        return None
    F = comp.filter_slope_columns(prep, j)
    return None if F is None else {"filter_slope": F}


#: the variables of the final residual's structure (:func:`~drake_est.diagnose.unexplained.residual_structure`) that
#: are the joint's state: :func:`sole_time_law_explained_by_state` runs where one of them is reported
STATE_STRUCTURE = ("position", "velocity", "acceleration")


def sole_time_law_explained_by_state(prep, model, unexplained, alpha, min_gain):
    """A friction law in time (an energy drift or an abrupt change) that is the only law of its joint in the final
    ``model`` (no single-joint finding outside :data:`~drake_est.diagnose.competition.TIME_LAWS` beside it, which
    :func:`time_law_explained_by_state` checks), while the final residual of that joint holds structure in its state
    (an ``unexplained`` entry in :data:`STATE_STRUCTURE`), and which a free function of the joint's state explains one
    way only: the function explains the law (:func:`_state_explains`: given it the law's columns do not predict the
    held-out residual, and the function alone predicts it at least as well as the law alone), and given the law the
    function still predicts the held-out residual (partial held-out F-test at ``alpha``, gain ``min_gain``).  A change
    of the friction over the log that the moves make look like a function of the state is explained by that function
    and explains it back (loop spec 8484: a planted abrupt change at 50 Hz; the change given the function -2.2 %, the
    function given the change -0.6 %): the two are kept apart only by the law.  A misfit of the state that the law
    took in part is not (loop spec 13761 on an AVX2 CPU: an asymmetric level beside Stribeck at 10 Hz reported as an
    abrupt change alone; the change given the function 1.1 %, the function given the change 47 %, p = 5e-50).
    Returns the first such law as ``(effect, joint, why)``, else None."""
    where = {}
    for u in unexplained:
        if u["variable"] in STATE_STRUCTURE:
            where.setdefault(int(u["joint"]), []).append(u["variable"])
    for e in model.exts:
        if e.effect not in TIME_LAW_PAIR or e.shared or e.joint not in where:
            continue
        j = e.joint
        if _laws_of_state(model, j):
            continue
        one_way = _state_explains_one_way(prep, Model(prep, [x for x in model.exts if x is not e]), j, e.cols[j],
                                          alpha, min_gain)
        if one_way is None:
            continue
        got, back, n_far = one_way
        why = _state_entry(j, got, "", f"the {e.effect.replace('_', ' ')}", "the law alone",
                           f"; given the law the function lowers it by {100 * back['rmse_reduction']:.1f} % "
                           f"(p = {back['p_value']:.2g}), and the final residual holds structure in "
                           f"{', '.join(sorted(set(where[j])))}: the law took part of a misfit of the state, not a "
                           "change of the friction over the log")
        why.update(sole_law_in_time=True, state_given_law=comp._brief(back))
        return e.effect, j, _beyond_speeds_note(why, n_far)
    return None


def _laws_of_state(model, j) -> list:
    """The effects (sorted, each once) of ``model``'s single-joint findings on joint ``j`` outside
    :data:`~drake_est.diagnose.competition.TIME_LAWS`: the laws of the state a law in time may stand beside."""
    return sorted({x.effect for x in model.exts if x.effect not in comp.TIME_LAWS and not x.shared and x.joint == j})


#: hundred-and-fourth round: the forty-eighth round's check of a law in time against a free function of its joint's
#: state (:func:`time_law_explained_by_state`) also checks a law whose step is reported ambiguous with laws of the
#: state when every one of those laws is itself a finding of the final model on the joint
#: (:func:`_state_rivals_named_beside`); rule: ``benchmarks/results/diagnose_time_law_rival_named_round104_rule.txt``
TIME_LAW_RIVAL_NAMED_RULE = True


def _state_rivals(steps, e) -> list:
    """The laws of the state (rivals outside :data:`~drake_est.diagnose.competition.TIME_LAWS`) that the step of the
    law in time ``e`` (in ``steps``) is reported ambiguous with."""
    st = next((s for s in steps if not s.ext.shared and (s.ext.effect, s.ext.joint) == (e.effect, e.joint)
               and s.competition.get("ambiguous")), None)
    return [] if st is None else [r for r in comp.ambiguous_rivals(st.competition) if r and r not in comp.TIME_LAWS]


def _state_rivals_named_beside(model, steps, e) -> list:
    """With :data:`TIME_LAW_RIVAL_NAMED_RULE`: the laws of the state the step of the law in time ``e`` is reported
    ambiguous with (:func:`_state_rivals`) when every one of them is a finding of ``model`` on ``e``'s joint
    (:func:`_laws_of_state`), else ``[]``.  The forty-eighth round skips a law in time reported ambiguous with a law of
    the state, since there the law in time stands for that law and setting it aside loses it; where the model holds
    that law beside it, nothing is lost (fresh loop spec 42666: a load beside a Stribeck hump almost as large as the
    Coulomb level at 100 Hz with Student-t noise, an energy drift named ambiguous with a position friction that the
    model names next, itself ambiguous with Stribeck; given the state's function and the other findings the drift
    lowers the held-out RMSE by -2.9 %)."""
    if not TIME_LAW_RIVAL_NAMED_RULE:
        return []
    held = _state_rivals(steps, e)
    beside = _laws_of_state(model, e.joint)
    return held if held and all(r in beside for r in held) else []


def _time_laws_beside_state(model, steps, named_rivals: bool = False) -> list:
    """The single-joint energy drifts and abrupt changes of ``model`` that :func:`time_law_explained_by_state`
    checks, each with the laws of the state beside it on its joint (single-joint findings outside
    :data:`~drake_est.diagnose.competition.TIME_LAWS`, sorted): every one beside a Stribeck law (then only
    ``["stribeck"]``, the forty-sixth round's check), and one beside other laws of the state that its step
    (``steps``) does not report ambiguous with a law of the state, or (``named_rivals``, the hundred-and-fourth round)
    only with laws of the state the model names beside it (:func:`_state_rivals_named_beside`)."""
    out = []
    for e in model.exts:
        if e.effect not in TIME_LAW_PAIR or e.shared:
            continue
        beside = _laws_of_state(model, e.joint)
        if "stribeck" in beside:
            out.append((e, ["stribeck"]))
        elif beside and (not _state_rivals(steps, e)
                         or (named_rivals and _state_rivals_named_beside(model, steps, e))):
            out.append((e, beside))
    return out


def finding_not_confirmed(steps, unexplained, min_gain_not_white=MIN_GAIN_NOT_WHITE):
    """The weakest finding accepted after another one on its joint(s) (``steps`` in the order of acceptance) whose
    held-out RMSE reduction in its round is below ``min_gain_not_white`` while the final residual of one of its
    joints holds structure (``unexplained``, :func:`~drake_est.diagnose.unexplained.residual_structure`), as
    ``(step, joints with structure)``; None when there is none."""
    weak = [sw for sw in _later_on_structure(steps, unexplained) if sw[0].test["rmse_reduction"] < min_gain_not_white]
    return min(weak, key=lambda sw: sw[0].test["rmse_reduction"]) if weak else None


#: a later finding's held-out gain sits in a few samples when the largest FEW_SAMPLES_SHARE of its joint's held-out
#: samples (at least one) hold at least FEW_SAMPLES_GAIN of its squared-error gain (:func:`gain_in_few_samples`)
FEW_SAMPLES_SHARE = 0.05
FEW_SAMPLES_GAIN = 0.5
#: ... and the check applies where the final held-out residual of the joint is heavy-tailed: its excess kurtosis
#: above zero at this level (one-sided D'Agostino test, scipy.stats.kurtosistest)
HEAVY_TAILS_ALPHA = 0.05


def gain_in_few_samples(prep, steps, model, fit, sigma):
    """A finding accepted after another one on its joint whose held-out gain sits in a few samples and does not show
    on the absolute errors.  Under heavy-tailed noise (a Student-t torque, spikes) a few large errors carry most of a
    squared-error gain; a law of the model changes the prediction wherever its regressors move, so a real one also
    lowers the absolute errors across the held-out blocks.  A law that acts on a few samples only (Stribeck at the
    few slow samples of a log) also holds its gain in a few samples, so the check applies only where the final
    held-out residual of the joint is heavy-tailed (excess kurtosis above zero, one-sided test at
    :data:`HEAVY_TAILS_ALPHA`; loop spec 7378, a planted Stribeck law at 10 Hz with Gaussian noise, 17 of 340
    held-out samples hold its gain, kurtosis test p = 0.17).  For each later finding of the final ``model`` (``fit``;
    single-joint, in the order of acceptance ``steps``), the model without it is fitted; when the largest
    :data:`FEW_SAMPLES_SHARE` of the per-sample gains ``e_without^2 - e_with^2`` hold at least
    :data:`FEW_SAMPLES_GAIN` of their sum, the absolute errors are paired over the held-out blocks
    (:func:`~drake_est.diagnose.competition.paired_block_test`, ``loss="absolute"``).  Returns the first finding
    whose absolute errors do not show the gain (p >= :data:`PAIRED_ALPHA`) as ``(step, why)``, else None (loop spec
    11752: an asymmetric level beside a load at 10 Hz with Student-t noise, 7.1 % lower held-out RMSE, 88 % of it in
    5 of 133 held-out samples)."""
    return _first_gain_in_few_samples(prep, [st for st, _ in _later_steps(steps)], model, fit, sigma)


def sole_finding_gain_in_few_samples(prep, steps, model, fit, sigma, unexplained):
    """:func:`gain_in_few_samples` for a finding that is the only one of its joint in the final ``model`` while the
    final residual of that joint still holds structure (``unexplained``,
    :func:`~drake_est.diagnose.unexplained.residual_structure`).  The first finding of a joint is the best candidate
    against the nominal model, but when the model stays misspecified (a structure no vocabulary entry explains) the
    held-out F-test's white-residual null does not hold, and under heavy-tailed noise a candidate can take its
    squared-error gain from the few large errors that structure leaves (fresh spec 13615: backlash at 50 Hz with
    Student-t noise, named an energy drift with 7.4 % lower held-out RMSE but 0.9 % lower mean absolute error,
    paired p = 0.32 on the absolute errors, 68 % of the final residual variance in its time correlation).  Returns
    ``(step, why)`` of the first such finding whose absolute errors do not show its gain, else None."""
    where = {int(u["joint"]) for u in unexplained}
    per_joint = collections.Counter(e.joint for e in model.exts if not e.shared)
    sole = [st for st in steps if not st.ext.shared and per_joint.get(st.ext.joint) == 1
            and int(st.ext.joint) in where]
    found = _first_gain_in_few_samples(prep, sole, model, fit, sigma)
    if found is not None:
        found[1]["sole_finding_of_joint"] = True
        found[1]["unexplained_in_final_residual"] = sorted({u["variable"] for u in unexplained
                                                            if int(u["joint"]) == int(found[0].ext.joint)})
    return found


def _first_gain_in_few_samples(prep, steps, model, fit, sigma):
    """The first of ``steps`` (findings of the final ``model``) whose held-out gain sits in a few samples of a
    heavy-tailed residual and does not show on the absolute errors (:func:`gain_in_few_samples`), as
    ``(step, why)``; None when there is none."""
    for st in steps:
        e = st.ext
        if e.shared or not any(x is e for x in model.exts):
            continue
        j = e.joint
        jd = prep.joints[j]
        eb = (jd.y - fit.pred[j])[jd.val]
        if eb.size < 20:
            continue
        # the final residual alone decides whether the check applies: tested before the model without the finding
        # is fitted
        tails = float(scipy.stats.kurtosistest(eb, alternative="greater").pvalue)
        if not tails < HEAVY_TAILS_ALPHA:
            continue
        f0 = Model(prep, [x for x in model.exts if x is not e]).fit(sigma)
        ea = (jd.y - f0.pred[j])[jd.val]
        g = ea ** 2 - eb ** 2
        total = float(g.sum())
        if total <= 0:
            continue
        k = max(1, int(np.ceil(FEW_SAMPLES_SHARE * g.size)))
        share = float(np.sort(g)[::-1][:k].sum()) / total
        if share < FEW_SAMPLES_GAIN:
            continue
        paired = comp.paired_block_test(prep, f0, fit, [j], loss="absolute")
        if paired["p_value"] < PAIRED_ALPHA:
            continue
        mae = 1.0 - float(np.mean(np.abs(eb))) / max(float(np.mean(np.abs(ea))), 1e-300)
        return st, {
            "reason": (f"its held-out gain sits in a few samples: the largest {k} of the {g.size} held-out samples "
                       f"hold {100 * share:.0f} % of its squared-error gain, and the held-out blocks do not show it on "
                       f"the absolute errors ({100 * mae:.1f} % lower mean absolute error, paired p = "
                       f"{paired['p_value']:.2g}), while the residual is heavy-tailed (kurtosis test p = {tails:.2g}): "
                       "a few large errors (of heavy-tailed noise, or of a misfit the model leaves elsewhere) carry "
                       "it, not a law of the joint"),
            "gain_in_few_samples": True, "few_samples": k, "heldout_samples": int(g.size),
            "heavy_tails_p_value": tails,
            "share_of_squared_error_gain": share, "mean_absolute_error_reduction": mae,
            "paired_p_value_absolute": float(paired["p_value"]), "groups": int(paired["groups"]),
            "groups_better": int(paired["groups_better"])}
    return None


#: the least held-out log-likelihood gain [nats] of a finding on a joint whose torque a coarse ADC rounds
#: (:func:`gain_within_rounding`): a likelihood ratio below e (2 ln B < 2) is "not worth more than a bare mention"
#: (Kass and Raftery 1995).  Loop spec 14517 (backlash at 1000 Hz, a 0.076 N m step) holds a Stribeck hump of
#: 0.025 N m whose gain is 3.5e-5 nats over 13,968 held-out readings: positive, and nothing.
MIN_ROUNDING_LOGLIK_GAIN = 1.0


def rounding_loglik_gains(prep, model, only=None):
    """The held-out log-likelihood gain of each finding of ``model`` on a joint whose torque a coarse ADC rounds
    (:func:`~drake_est.diagnose.quantization.torque_step`), weighed by the likelihood of the quantized readings, each
    one saying only that the torque lay within half a step of it (:func:`~drake_est.diagnose.quantization.interval_fit`:
    the model with and without the finding fitted on the training rows, the inertia free on generic axes since its
    estimate is a least-squares one too).  Both are scored on the held-out readings with one noise level, the larger
    of their two estimates (a noise level fitted to the training rows alone would reward or punish a model for it: a
    model that puts every training reading inside its step drives its own estimate towards zero).  Yields
    ``(ext, info)`` lazily, finding by finding (``only``: that finding alone), ``info["heldout_loglik_gain"]`` in nats.  Joints of several logs
    (per-log offsets), joints not on a grid and joints with too few rows are skipped."""
    from drake_est.diagnose.quantization import interval_fit, interval_loglik, interval_loglik_profiled
    for e in model.exts:
        if e.shared or (only is not None and e is not only):
            continue
        j = e.joint
        jd = prep.joints[j]
        step = joint_tau_step(prep, j)
        if step <= 0 or log_ids(prep, jd) is not None:
            continue
        X1 = model.design_with_shared(j)
        m0 = Model(prep, [x for x in model.exts if x is not e])
        X0 = m0.design_with_shared(j)
        # the columns kept >= 0 as in the least-squares fit (kv, a Stribeck law's coefficients)
        nn1, nn0 = model.nonneg(j), m0.nonneg(j)
        if prep.robot is None:
            a = jd.a[jd.rows][:, None]
            X1, X0 = np.hstack([a, X1]), np.hstack([a, X0])
            nn1, nn0 = [i + 1 for i in nn1], [i + 1 for i in nn0]
        lo, hi = jd.y - 0.5 * step, jd.y + 0.5 * step
        tr, va = jd.train, jd.val
        if va.sum() < 20 or tr.sum() <= X1.shape[1] + 1:
            continue
        # the least-squares fit's ridge (RIDGE times each penalized column's energy on the training rows), carried
        # over: without it a kernel basis fitted freely to the training readings can predict the held-out ones far
        # worse (loop spec 8192, a position load at 50 Hz)
        pen1, pen0 = model.penalized(j), m0.penalized(j)
        if prep.robot is None:
            pen1, pen0 = np.r_[False, pen1], np.r_[False, pen0]
        pen1 = np.r_[pen1, np.ones(X1.shape[1] - pen1.size, bool)]
        pen0 = np.r_[pen0, np.ones(X0.shape[1] - pen0.size, bool)]
        r1 = RIDGE * pen1 * np.sum(X1[tr] ** 2, axis=0)
        r0 = RIDGE * pen0 * np.sum(X0[tr] ** 2, axis=0)
        c0, s0 = interval_fit(X0[tr], lo[tr], hi[tr], nonneg=nn0, ridge=r0)
        # the model with the finding started from the one without it (zeros for the finding's columns): nested, it
        # cannot end with a lower training likelihood
        at = (1 if prep.robot is None else 0) + N_NOMINAL + sum(
            x.n_params for x in model.own(j)[:[id(x) for x in model.own(j)].index(id(e))])
        start = np.concatenate([c0[:at], np.zeros(X1.shape[1] - X0.shape[1]), c0[at:]])
        c1, s1 = interval_fit(X1[tr], lo[tr], hi[tr], coef0=start, sigma0=s0, nonneg=nn1, ridge=r1)
        s = max(s0, s1)
        gain = float(np.sum(interval_loglik(X1[va], c1, s, lo[va], hi[va])
                            - interval_loglik(X0[va], c0, s, lo[va], hi[va])))
        # the same gain with each model at the noise level its held-out readings favour (the likelihood ratio of
        # :func:`gain_within_rounding`'s bound): one level for both favours the model it came from
        ll1, h1 = interval_loglik_profiled(X1[va], c1, lo[va], hi[va])
        ll0, h0 = interval_loglik_profiled(X0[va], c0, lo[va], hi[va])
        yield e, {"adc_step": float(step), "noise_before_adc": float(s), "noise_before_adc_without": float(s0),
                  "noise_before_adc_with": float(s1), "heldout_loglik_gain": gain, "heldout_samples": int(va.sum()),
                  "heldout_loglik_gain_profiled": float(ll1 - ll0), "heldout_noise_without": h0,
                  "heldout_noise_with": h1, "finding_columns": int(X1.shape[1] - X0.shape[1])}


def rounding_lr_bound(k: int, alpha: float = ALPHA) -> float:
    """The least held-out log-likelihood ratio [nats] of a finding with ``k`` columns on a joint whose torque a coarse
    ADC rounds (:func:`gain_within_rounding`): half the chi-square quantile of ``k`` degrees of freedom at ``1 -
    alpha``, the likelihood-ratio test at the significance level of the held-out F-test (:data:`ALPHA`) that the
    rounding error, which is not noise, leaves without meaning there (7.6 nats for one column, 11.8 for four)."""
    return 0.5 * float(scipy.stats.chi2.isf(alpha, max(int(k), 1)))


def gain_within_rounding(prep, model, min_gain: float = MIN_ROUNDING_LOGLIK_GAIN, alpha: float = ALPHA):
    """A finding on a joint whose torque a coarse ADC rounds that does not make the quantized readings themselves
    more likely.  Least squares on the rounded torque treats the rounding error as noise; when the noise before the
    ADC is small against its step, that error is a staircase of the torque level, and the fit it biases leaves a
    misfit that a law in time or speed can take (closed-loop spec 1627, a null log at 1000 Hz with a 0.23 N m step:
    the viscous kv comes out 0.38 N m s/rad against the generator's 0.56, and an abrupt change of kv at 95 s is
    named, its gain in the one fast move after it).  A finding is set aside when its held-out log-likelihood gain
    (:func:`rounding_loglik_gains`) is below ``min_gain`` nats (:data:`MIN_ROUNDING_LOGLIK_GAIN`; not positive until
    the forty-fifth round), or when the same gain with each model at the noise level its held-out readings favour
    (``heldout_loglik_gain_profiled``) is below :func:`rounding_lr_bound` of its columns at ``alpha`` (sixty-sixth
    round: fresh spec 24500, a third-size abrupt change at 250 Hz with a 0.165 N m step, named a Stribeck law beside
    the change whose least-squares gain was 26 % and whose gain on the readings was 17.5 nats over 10,469 held-out
    samples at the noise level of the model with it, 5.7 at each model's own).  The first such finding of the model
    is returned as ``(ext, why)``, else None."""
    for e, info in rounding_loglik_gains(prep, model):
        gain = info["heldout_loglik_gain"]
        prof, k = info["heldout_loglik_gain_profiled"], info["finding_columns"]
        bound = rounding_lr_bound(k, alpha)
        if gain >= min_gain and prof >= bound:
            continue
        if gain < min_gain:
            how = (f"at least as well (log-likelihood gain {gain:.3g} nats over {info['heldout_samples']} samples)"
                   if gain <= 0 else
                   f"nearly as well (log-likelihood gain {gain:.3g} nats over {info['heldout_samples']} samples, below "
                   f"the {min_gain:g} nat a finding needs: a likelihood ratio under {np.exp(min_gain):.3g})")
        else:
            how = (f"within chance (log-likelihood gain {prof:.3g} nats over {info['heldout_samples']} samples, each "
                   f"model at the noise level its held-out readings favour, below the {bound:.3g} nats of a "
                   f"likelihood-ratio test of its {k} column{'s' if k != 1 else ''} at p = {alpha:g})")
        return e, {
            "reason": (f"the torque ADC's rounding (step {info['adc_step']:.3g} N m) explains it: fitted by the "
                       f"likelihood of the quantized readings (each within half a step of the torque; noise before the "
                       f"ADC {info['noise_before_adc']:.2g} N m), the model without it predicts the held-out readings "
                       f"{how}"),
            "within_rounding": True, "rounding_lr_bound": bound, **info}
    return None


#: eighty-sixth round (kept; see ``docs/readme/diagnose_testbench.md``): :func:`later_position_law_within_finer_basis`
#: also holds a motor-position ripple found after its joint's first position law against that law at a finer
#: resolution: a ripple of a few cycles per radian with a speed-dependent amplitude is a smooth law of the position
#: too, and takes what a coarse kernel basis leaves (fresh spec 31089); rule:
#: ``benchmarks/results/diagnose_finer_basis_ripple_round86_rule.txt``
FINER_BASIS_RIPPLE_RULE = True


def _later_than_first_position_law(model, j) -> tuple:
    """(the first position law of joint ``j`` in ``model``, the findings after it that
    :func:`later_position_law_within_finer_basis` holds against it: the later position laws and, with
    :data:`FINER_BASIS_RIPPLE_RULE`, the later motor-position ripples), or (None, [])."""
    own = model.own(j)
    laws = [e for e in own if e.effect in comp.POSITION_LAWS]
    if not laws:
        return None, []
    first = laws[0]
    later = [e for e in own[own.index(first) + 1:] if e.effect in comp.POSITION_LAWS
             or (FINER_BASIS_RIPPLE_RULE and e.effect == "motor_position_ripple")]
    return first, later


def later_position_law_within_finer_basis(prep, model, min_gain: float = MIN_GAIN):
    """A later position law (:data:`~drake_est.diagnose.competition.POSITION_LAWS`) on a joint whose final ``model``
    already holds an earlier one, that the earlier law at a finer resolution explains as well.  The inner split
    chooses a position law's number of kernels (:data:`~drake_est.diagnose.detectors.BFE_SIZES`) before the later
    findings are known; what the coarser basis cannot follow is left in the residual, where a second position law
    takes it (fresh spec 13599: a planted position friction of two bumps of unequal width, fitted with 8 kernels,
    then a load named for its misfit, 2 % lower held-out RMSE; the friction alone at 16 kernels predicts the held-out
    data as well as both).  The earlier law is refitted at the next finer size over the same range (its sign or its
    gravity harmonics as before) without the later one; when the model with both does not lower the joint's
    held-out RMSE by ``min_gain`` against it, the later law is returned as ``(ext, why)``, else None.  With
    :data:`FINER_BASIS_RIPPLE_RULE` a later motor-position ripple is held against it alike (fresh spec 31089: a
    position friction of two bumps 0.2 and 0.31 rad wide at 50 Hz, fitted with 8 kernels 0.34 rad apart, then a
    ripple of 2.07 cycles/rad with a speed-dependent amplitude named for the misfit, 2.2 % lower held-out RMSE; the
    friction alone at 16 kernels predicts the held-out data 1.9 % better than both)."""
    fit = None
    for j, jd in prep.joints.items():
        first, later = _later_than_first_position_law(model, j)
        if not later:
            continue
        centers = first.spec.get("centers")
        if not centers or len(centers) < 2:
            continue
        finer = [k for k in det.BFE_SIZES if k > len(centers)]
        if not finer:
            continue
        K = finer[0]
        refined = det.position_kernels_at(jd, first.effect, K, float(centers[0]), float(centers[-1]))
        if fit is None:
            fit = model.fit()
        n_val = max(int(jd.val.sum()), 1)
        rmse = float(np.sqrt(fit.rss_val[j] / n_val))
        for e in later:
            alt = Model(prep, [refined if x is first else x for x in model.exts if x is not e])
            rmse_alt = float(np.sqrt(alt.fit().rss_val[j] / n_val))
            gain = 1.0 - rmse / rmse_alt if rmse_alt > 0 else 0.0
            if gain >= min_gain:
                continue
            return e, {
                "reason": (f"{first.effect} at a finer resolution ({K} kernels instead of {len(centers)}) explains it: "
                           f"alone it predicts the held-out data within {100 * gain:.2f} % of the RMSE with both "
                           f"(< {100 * min_gain:g} %, the gain every finding must show), so {e.effect} is the earlier "
                           f"law's misfit, not a second cause"),
                "within_finer_basis": True, "earlier_law": first.effect, "kernels_before": len(centers),
                "kernels_finer": K, "heldout_rmse_with_both": rmse, "heldout_rmse_finer_alone": rmse_alt,
                "gain_over_finer": gain}
    return None


def position_friction_within_speed_curve(prep, model, alpha, min_gain):
    """A position friction (a Coulomb level that changes with q) of the final ``model`` on a joint that also holds a
    Stribeck law, which a free friction curve of the joint's speed explains: given the other findings and the curve
    (:func:`~drake_est.diagnose.competition.speed_law_nuisance`, knots at the training speeds' quantiles and spread
    in log-speed) its columns do not predict the joint's held-out residual (partial held-out F-test at ``alpha``, gain
    ``min_gain``).  The Stribeck law has one shape (kc + ks exp(-|qd/vs|^delta)); where each position is passed at
    its own speed (point-to-point moves), the misfit of that shape is a function of position too, and a level that
    changes with q takes it (fresh spec 14286: a load beside a Gaussian Stribeck law at 100 Hz with Student-t noise;
    the position friction named first lowers the held-out RMSE by 16 % given the load and Stribeck, by 0.8 % given
    the curve as well).  The round's own check (:func:`~drake_est.diagnose.competition.position_law_confounded`)
    tests a winner against the curve before the later findings are known, and only marks it ambiguous.  Returns the
    first such friction as ``(ext, why)``, else None."""
    return _within_speed_curve(prep, model, ("position_dependent_friction",), True, alpha, min_gain, "position_law",
                               "the misfit of the Stribeck law's shape, which point-to-point moves make a function of "
                               "position", digits=1)


def _beside_stribeck(model, effects) -> list:
    """The single-joint findings of ``model`` with an effect in ``effects`` on a joint whose model also holds a
    Stribeck finding, in the model's order (the findings :func:`_within_speed_curve` checks)."""
    stribeck = {x.joint for x in model.exts if x.effect == "stribeck" and not x.shared}
    return [e for e in model.exts if e.effect in effects and not e.shared and e.joint in stribeck]


def _finding_against_nuisance(prep, model, e, N, alpha, min_gain):
    """The partial held-out tests of the single-joint finding ``e`` of the final ``model`` against nuisance columns
    ``N`` of its joint, each with the other findings in the model (the search's ridge, :func:`_model_solver`): None when
    ``e`` predicts the held-out residual given ``N`` (it stands), else ``(t, own, back)``: ``e`` given ``N``, ``e``
    alone, and ``N`` given ``e`` (:func:`~drake_est.diagnose.competition._partial_test` results)."""
    j = e.joint
    m0 = Model(prep, [x for x in model.exts if x is not e])
    solve = _model_solver(m0, j)
    t = comp._partial_test(prep, m0, j, N, e.cols[j], alpha, min_gain, solve)
    if t["significant"]:
        return None
    own = comp._partial_test(prep, m0, j, np.zeros((N.shape[0], 0)), e.cols[j], alpha, min_gain, solve)
    back = comp._partial_test(prep, m0, j, e.cols[j], N, alpha, min_gain, solve)
    return t, own, back


def _explained_one_way(prep, model, e, N, alpha, min_gain):
    """:func:`_finding_against_nuisance` where the nuisance columns ``N`` must also predict the held-out residual given
    ``e`` (p < ``alpha``): ``(t, own, back)`` when ``N`` explains ``e`` one way, None when ``e`` stands, when ``N``
    does not predict it, or when ``N`` is not finite."""
    if not np.all(np.isfinite(N)):
        return None
    tests = _finding_against_nuisance(prep, model, e, N, alpha, min_gain)
    if tests is None or not tests[2]["p_value"] < alpha:
        return None
    return tests


def _latest_explained_one_way(prep, model, exts, nuisance, alpha, min_gain):
    """The latest of the single-joint findings ``exts`` (in the order accepted) that the columns ``nuisance(joint)``
    explain one way (:func:`_explained_one_way`), as ``(ext, N, (t, own, back))``; None when every one stands (the
    delay, inertia and linear-response checks)."""
    for e in reversed(exts):
        N = nuisance(e.joint)
        tests = _explained_one_way(prep, model, e, N, alpha, min_gain)
        if tests is not None:
            return e, N, tests
    return None


def _within_speed_curve(prep, model, effects, spread, alpha, min_gain, law, cause, digits):
    """The first finding of the final ``model`` with an effect in ``effects`` (single-joint, on a joint whose model
    also holds a Stribeck finding) whose columns do not predict the joint's held-out residual given the other findings
    and a free friction curve of the speed (:func:`~drake_est.diagnose.competition.speed_law_nuisance`, ``spread``
    knots or not), as ``(ext, why)``: the reason (``cause``: what the finding took instead; its gain given the curve
    with ``digits`` decimals) and the partial tests, keyed ``{law}_given_speed_curve`` and
    ``speed_curve_given_{law}``; None when there is none (the checks of
    :func:`position_friction_within_speed_curve` and :func:`time_law_within_speed_curve`)."""
    for e in _beside_stribeck(model, effects):
        j = e.joint
        N = comp.speed_law_nuisance(prep, j, spread=spread)
        if N is None:
            continue
        tests = _finding_against_nuisance(prep, model, e, N, alpha, min_gain)
        if tests is None:
            continue
        t, own, back = tests
        return e, {
            "reason": (f"a free friction curve of the speed of joint {j} explains it: given the other findings and the "
                       f"curve ({N.shape[1]} columns) it lowers the held-out RMSE by "
                       f"{100 * t['rmse_reduction']:.{digits}f} % (p = {t['p_value']:.2g}), not significantly (alone, "
                       f"given the other findings, by {100 * own['rmse_reduction']:.1f} %), while the curve given it "
                       f"lowers it by {100 * back['rmse_reduction']:.1f} %: {cause}"),
            "within_speed_curve": True, f"{law}_given_speed_curve": comp._brief(t),
            f"speed_curve_given_{law}": comp._brief(back), "heldout_rmse_reduction_alone": own["rmse_reduction"],
            "speed_curve_columns": int(N.shape[1])}
    return None


def time_law_within_speed_curve(prep, model, alpha, min_gain):
    """A friction law in time (an energy drift or an abrupt change) of the final ``model`` on a joint that also holds
    a Stribeck law, which a free friction curve of the joint's speed explains: given the other findings and the curve
    (:func:`~drake_est.diagnose.competition.speed_law_nuisance`, knots at the training speeds' quantiles, the curve of
    :func:`~drake_est.diagnose.competition.survives_speed_law`) its columns do not predict the joint's held-out
    residual (partial held-out F-test at ``alpha``, gain ``min_gain``).  The Stribeck law has one shape; where the
    speeds the joint runs at change over the log, the misfit of that shape changes with time too, and a law in time
    takes it.  The round's own test holds a law in time against the curve given the model of its round, before the
    later findings are known (fresh spec 14572: a load beside a Gaussian Stribeck law at 100 Hz; an energy drift with
    the scan's longest time constant was named first, 45 % lower held-out RMSE in its round against the nominal
    model; given the load, Stribeck and the curve it lowers the held-out RMSE by -0.01 %).  Returns the first such law
    as ``(ext, why)``, else None."""
    return _within_speed_curve(prep, model, ("energy_dependent_friction", "abrupt_change"), False, alpha, min_gain,
                               "law_in_time", "the misfit of the Stribeck law's shape, which a change over the log in "
                               "the speeds the joint runs at makes a function of time", digits=2)


def stribeck_on_one_side_of_change(prep, model, sigma=None):
    """A Stribeck law of the final ``model`` on a joint whose model also holds an abrupt change, that one side of the
    change does not show although it could: on that side at least :data:`~drake_est.diagnose.detectors.
    STRIBECK_MIN_LOW` of the joint's held-out rows move slower than 2 vs (the detector's own rule for a testable
    Stribeck velocity; vs of :func:`~drake_est.diagnose.detectors.stribeck_ks_vs`, every row when the fitted law never
    falls to ks / e), and the model with the law predicts that side's held-out rows worse than the model without it,
    refitted.  A Stribeck hump is a property of the contact (Sec. 9.1), there on both sides of a change of the Coulomb
    and viscous levels; one whose gain lies after the change only takes the change's misfit (fresh spec 16580: a
    third-size change at 100 Hz with a quantized torque and point-to-point moves, its viscous part after the change
    fitted on slow rows; a Stribeck hump of 1.6 % of the Coulomb level lowers the held-out RMSE after the change by
    47 % and raises it before the change by 7 %).  Returns the first such law as ``(ext, why)``, else None."""
    fit = None
    for e in model.exts:
        if e.effect != "stribeck" or e.shared:
            continue
        j = e.joint
        changes = [c for c in model.own(j) if c.effect == "abrupt_change"]
        if not changes:
            continue
        jd = prep.joints[j]
        if fit is None:
            fit = model.fit(sigma)
        without = Model(prep, [x for x in model.exts if x is not e]).fit(sigma)
        _, vs = det.stribeck_ks_vs(e.spec, model.coef_slices(fit, j)["stribeck"])
        val = jd.rows[jd.val]
        t, v = jd.t[val], jd.v[val]
        e1 = (jd.y - fit.pred[j])[jd.val]
        e0 = (jd.y - without.pred[j])[jd.val]
        slow = np.abs(v) < 2 * vs if vs is not None else np.ones(v.size, bool)
        for c in changes:
            tc = float(c.spec["t_change"])
            for side, s in (("before", t < tc), ("after", t >= tc)):
                n = int(s.sum())
                if n == 0:
                    continue
                low = float(np.mean(slow[s]))
                r0, r1 = float(e0[s] @ e0[s]), float(e1[s] @ e1[s])
                if low < det.STRIBECK_MIN_LOW or r1 <= r0:
                    continue
                gain = 1.0 - np.sqrt(r1 / r0) if r0 > 0 else 0.0
                other = ~s
                o0, o1 = float(e0[other] @ e0[other]), float(e1[other] @ e1[other])
                gain_other = 1.0 - np.sqrt(o1 / o0) if o0 > 0 else 0.0
                return e, {
                    "reason": (f"it does not hold {side} the abrupt change of joint {j} at {tc:.2f} s: there "
                               f"{100 * low:.0f} % of the {n} held-out rows move slower than 2 vs "
                               f"(>= {100 * det.STRIBECK_MIN_LOW:g} %, enough to show it), and it raises their RMSE "
                               f"by {-100 * gain:.1f} %, while on the other side it lowers it by "
                               f"{100 * gain_other:.1f} %: a friction hump of the contact is there on both sides, so "
                               "it took the misfit of the change's levels on one side"),
                    "one_side_of_change": True, "side": side, "t_change_s": tc, "heldout_rows_on_side": n,
                    "share_slower_than_2vs": low, "heldout_rmse_reduction_on_side": gain,
                    "heldout_rmse_reduction_other_side": gain_other}
    return None


def _later_on_structure(steps, unexplained):
    """(step, joints with structure) for every finding accepted after another one on its joint(s) while the final
    residual of one of them holds structure (``unexplained``), in the order of acceptance."""
    where = {}
    for u in unexplained:
        where.setdefault(int(u["joint"]), []).append(u["variable"])
    return [(st, {j: where[j] for j in sorted(js & where.keys())}) for st, js in _later_steps(steps)
            if js & where.keys()]


def _later_steps(steps):
    """(step, its joints) for every finding accepted after another one on one of its joints, in the order of
    acceptance ``steps``."""
    seen = set()
    for st in steps:
        js = {int(j) for j in st.ext.cols}
        if js & seen:
            yield st, js
        seen |= js


def _structure_text(where) -> str:
    """``{joint: [variables]}`` of :func:`_later_on_structure` as report text."""
    return "; ".join(f"joint {j}: {', '.join(v)}" for j, v in where.items())


def _one_way_text(tests, back_what: str, verb: str = "lowers") -> str:
    """The sentence every one-way check (:func:`_explained_one_way`) gives of its ``(t, own, back)`` tests: the finding's
    held-out gain given the nuisance, alone, and ``back_what`` (the nuisance, ``verb`` agreeing with it) given the
    finding."""
    t, own, back = tests
    return (f"it lowers the held-out RMSE by {100 * t['rmse_reduction']:.2f} % (p = {t['p_value']:.2g}), not "
            f"significantly (alone, given the other findings, by {100 * own['rmse_reduction']:.1f} %), while "
            f"{back_what} given it {verb} it by {100 * back['rmse_reduction']:.2f} % (p = {back['p_value']:.2g})")


def _one_way_entry(name: str, tests) -> dict:
    """The keys every one-way check records of its ``(t, own, back)`` tests against the nuisance ``name``."""
    t, own, back = tests
    return {f"explained_by_{name}": True, f"finding_given_{name}": comp._brief(t),
            f"{name}_given_finding": comp._brief(back), "heldout_rmse_reduction_alone": own["rmse_reduction"]}


def delay_nuisance(prep, j) -> np.ndarray:
    """Columns (at the joint's used rows) of what a delay d between the torque and position samples leaves in the
    residual: M(t - d) - M(t) ~ -d dM/dt, whose inertia and viscous parts are -d J x jerk and -d kv x qdd (the jerk is
    the derivative of the smoothed acceleration; the time-shift test's odd difference D_k,
    :func:`~drake_est.diagnose.unexplained._time_shift`, is nearly proportional to dM/dt away from velocity
    reversals).  Returns [jerk, qdd]."""
    jd = prep.joints[j]
    return np.column_stack([np.gradient(jd.a, jd.t)[jd.rows], jd.a[jd.rows]])


def finding_explained_by_delay(prep, model, unexplained, alpha, min_gain):
    """A finding of the final ``model`` that a delay between the torque and position samples explains, one way: on a
    joint whose final residual shows the torque shifted in time against the position (the
    ``time_shift_torque_vs_position`` entry of :func:`~drake_est.diagnose.unexplained.residual_structure`), a
    single-joint finding whose columns do not predict the held-out residual given the other findings and the delay's
    columns (:func:`delay_nuisance`; partial held-out F-test at ``alpha``, gain ``min_gain``), while those columns
    given the finding do.  A delay between the channels is not in the vocabulary; on a repeated motion the misfit d x
    dM/dt it leaves is a function of the position along the path, and a position law takes part of it (loop spec
    20547: a 0.0315 s delay of the encoder at 250 Hz named a position load).  The latest such finding as
    ``(ext, why)``, else None."""
    joints = {u["joint"] for u in unexplained if u.get("variable") == "time_shift_torque_vs_position"}
    got = _latest_explained_one_way(prep, model, [x for x in model.exts if not x.shared and x.joint in joints],
                                    lambda j: delay_nuisance(prep, j), alpha, min_gain)
    if got is not None:
        e, _, tests = got
        j = e.joint
        shift = [u for u in unexplained if u.get("variable") == "time_shift_torque_vs_position" and u["joint"] == j]
        return e, {
            "reason": (f"a delay between the torque and position samples of joint {j}, which no vocabulary entry "
                       f"describes, explains it: the final residual shows the torque shifted in time against the "
                       f"position, and given the other findings and the delay's columns (the jerk and the "
                       f"acceleration, -d dM/dt) " + _one_way_text(tests, "those columns", "lower")),
            **_one_way_entry("delay", tests),
            **({"torque_delay_s": shift[0]["torque_delay_s"]} if shift and "torque_delay_s" in shift[0] else {})}
    return None


def finding_explained_by_inertia(prep, model, steps, alpha, min_gain):
    """A later position load of the final ``model`` that an error of its joint's inertia explains, one way: a
    direction-independent law of position accepted after another finding of its joint (:func:`_later_steps`) whose
    columns do not predict the held-out residual given the other findings and a free acceleration column (qdd at the
    joint's used rows; partial held-out F-test at ``alpha``, gain ``min_gain``), while that column given the load does
    (p < ``alpha``).  In a point-to-point motion the acceleration is a function of the position along the path (each
    move speeds up near where it starts and slows down near where it ends, in both directions), so the misfit of an
    inertia that :func:`~drake_est.diagnose.nominal.prepare` estimated on the low-acceleration rows, and that the
    backfit (:func:`backfit_inertia`) left within :data:`INERTIA_BACKFIT_REL` of itself, has the shape of a load (loop
    spec 18186: an abrupt change at 250 Hz, then a load of 2.6 % held-out gain that given the acceleration gains
    nothing, the inertia 4 % too large).  The latest such finding as ``(ext, why)``, else None."""
    later = [st for st, _ in _later_steps(steps)
             if st.ext.effect == "position_dependent_load" and not st.ext.shared
             and any(x is st.ext for x in model.exts)]
    got = _latest_explained_one_way(
        prep, model, [st.ext for st in later],
        lambda j: np.asarray(prep.joints[j].a, float)[prep.joints[j].rows][:, None], alpha, min_gain)
    if got is not None:
        e, _, tests = got
        return e, {
            "reason": (f"an error of the inertia of joint {e.joint} explains it: given the other findings and a free "
                       f"acceleration column " + _one_way_text(tests, "the acceleration")
                       + ": in point-to-point moves the acceleration is a function of the position"),
            **_one_way_entry("inertia", tests)}
    return None


#: span [s] of the free linear response to the acceleration (:func:`linear_response_nuisance`): four periods of a
#: 4 Hz resonance
LINEAR_RESPONSE_SPAN_S = 1.0
#: at most this many lags of the acceleration in that response (evenly spaced over the span)
LINEAR_RESPONSE_TAPS = 30
#: the laws :func:`finding_explained_by_linear_response` holds against that response: smooth laws of the position
#: and speed.  A law that forces the axis at its own frequency (a time-periodic disturbance, a ripple) or in time (an
#: abrupt change, a drift) moves it, and a filter of the acceleration replays what it moved (sixty-first round: 17
#: planted disturbances at 10-100 Hz set aside)
LINEAR_RESPONSE_EFFECTS = ("position_dependent_load", "position_dependent_friction", "stribeck", "asymmetric_coulomb")
#: (seventy-eighth round) the linear-response check also holds the laws of a joint whose final residual is correlated
#: in time (a ``time_correlation`` entry), not only of one whose residual depends on the acceleration: a law of the
#: position that took part of an elastic gear's response can take its dependence on the acceleration with it, and the
#: rest of the response is still a filter of the motion (fresh compliance log, seed 2000160 of
#: ``benchmarks/bench_time_shift_null_rate.py``: a position load named at 50 Hz, the final residual 85 % correlated in
#: time and no ``acceleration`` entry; given the response the load gains -1.1 %, the response given the load 52.7 %;
#: rule: ``benchmarks/results/diagnose_linear_response_time_correlation_round78_rule.txt``; kept: it fired in none of the
#: 446 kept rows it can touch)
LINEAR_RESPONSE_ON_TIME_CORRELATION = True
#: the ``unexplained`` entries whose joints the linear-response check holds (``time_correlation`` too with
#: :data:`LINEAR_RESPONSE_ON_TIME_CORRELATION`)
LINEAR_RESPONSE_TRIGGERS = ("acceleration",)


def linear_response_nuisance(prep, j, span=LINEAR_RESPONSE_SPAN_S, taps=LINEAR_RESPONSE_TAPS) -> np.ndarray:
    """Columns (at the joint's used rows) of a free linear response to the acceleration: the smoothed acceleration of
    joint ``j`` and its copies delayed by lags evenly spaced over ``span`` seconds (at most ``taps`` distinct sample
    lags; before the log starts, its first value).  A causal filter of the motion of this length takes what an elastic
    gear's resonance, an error of the inertia or a delay leaves in the torque residual, none of which the vocabulary
    names as a law of the position, speed or time."""
    jd = prep.joints[j]
    a = np.asarray(jd.a, float)
    t = np.asarray(jd.t, float)
    dt = float(np.median(np.diff(t))) if t.size > 1 else 1.0
    lags = np.unique(np.round(np.linspace(0.0, span / dt, taps)).astype(int))
    lags = lags[lags < a.size]
    cols = []
    for m in lags:
        s = np.empty_like(a)
        s[m:] = a[:a.size - m]
        s[:m] = a[0]
        cols.append(s[jd.rows])
    return np.column_stack(cols)


#: eighty-eighth round (see ``docs/readme/diagnose_testbench.md``): the linear-response check also holds a disturbance
#: periodic in time that is not stationary over the log (:func:`disturbance_not_stationary`): a pump or a fan keeps
#: its amplitude and phase, while the part of an elastic gear's response that a sinusoid takes changes with the motion
#: (fresh spec 31260: a 4.6 Hz resonance at 100 Hz named a 2.57 Hz disturbance whose amplitude over eighths of the log
#: runs from 0.08 to 0.39 N m, coherence 0.73; rule: ``benchmarks/results/diagnose_disturbance_stationary_round88_rule.txt``)
LINEAR_RESPONSE_DISTURBANCE_RULE = True
#: the log is cut into this many pieces of equal duration for :func:`disturbance_stationarity`
DISTURBANCE_SEGMENTS = 8
#: a disturbance whose phasor coherence (:func:`disturbance_stationarity`) is below this is not stationary (the planted
#: disturbances that a free linear response explains one way, sixty-first round: 0.94 to 1.00)
DISTURBANCE_COHERENCE_MAX = 0.85


def disturbance_stationarity(prep, model, e, alpha, min_gain, segments=DISTURBANCE_SEGMENTS) -> dict:
    """How stationary the time-periodic disturbance ``e`` of the final ``model`` is: its cosine and sine columns fitted
    with one phasor per piece of the log (``segments`` pieces of equal duration; with the other findings, on the
    training rows), the ``coherence`` |mean phasor| / mean |phasor| of its first frequency (1 for a sinusoid of fixed
    amplitude and phase; it falls when the amplitude or phase wanders), the piece ``amplitudes``, and
    ``heterogeneity``: the held-out partial F-test of the per-piece columns given the model (the wandering beyond the
    noise)."""
    j = e.joint
    jd = prep.joints[j]
    C = e.cols[j]
    t = np.asarray(jd.t, float)[jd.rows]
    edges = np.linspace(t.min(), t.max(), segments + 1)
    seg = np.clip(np.searchsorted(edges, t, side="right") - 1, 0, segments - 1)
    S = np.hstack([C * (seg == k)[:, None] for k in range(1, segments)])
    m0 = Model(prep, [x for x in model.exts if x is not e])
    het = comp._partial_test(prep, m0, j, C, S, alpha, min_gain, _model_solver(m0, j), coef=True)
    c = np.asarray(het.pop("coef"), float)
    nx = m0.design_with_shared(j).shape[1]
    m = C.shape[1] // 2
    base = c[nx:nx + C.shape[1]]
    per = c[nx + C.shape[1]:].reshape(segments - 1, C.shape[1]) + base
    ph = np.concatenate([[base[0] + 1j * base[m]], per[:, 0] + 1j * per[:, m]])
    amps = np.abs(ph)
    coh = float(np.abs(ph.mean()) / amps.mean()) if amps.mean() > 0 else 1.0
    return {"coherence": coh, "amplitudes": [float(a) for a in amps], "heterogeneity": comp._brief(het),
            "segments": int(segments)}


def disturbance_not_stationary(prep, model, e, alpha, min_gain):
    """:func:`disturbance_stationarity` of the disturbance ``e`` when its per-piece phasors predict the held-out
    residual given the model (p < ``alpha``) and its coherence is below :data:`DISTURBANCE_COHERENCE_MAX`, else None."""
    st = disturbance_stationarity(prep, model, e, alpha, min_gain)
    if st["heterogeneity"]["p_value"] < alpha and st["coherence"] < DISTURBANCE_COHERENCE_MAX:
        return st
    return None


def finding_explained_by_linear_response(prep, model, unexplained, alpha, min_gain):
    """A finding of the final ``model`` that a linear response to the acceleration explains, one way: on a joint whose
    final residual depends on the acceleration (an ``acceleration`` entry of
    :func:`~drake_est.diagnose.unexplained.residual_structure`; a ``time_correlation`` entry too with
    :data:`LINEAR_RESPONSE_ON_TIME_CORRELATION`), a single-joint smooth law of the position or speed
    (:data:`LINEAR_RESPONSE_EFFECTS`) whose columns do not predict
    the held-out residual given the other findings and a free linear response to the acceleration
    (:func:`linear_response_nuisance`; partial held-out F-test at ``alpha``, gain ``min_gain``), while that response
    given the finding does.  An elastic gear (a lightly damped resonance between motor and link, the encoder on the
    motor) adds a torque that is a linear filter of the motion, which no vocabulary entry describes; on a repeated
    motion a law of the position takes part of it (loop spec 18456: a 6.4 Hz resonance at 1000 Hz named a position
    load, which given the response gains 0.2 % while the response given it gains 28 %).  The latest such finding as
    ``(ext, why)``, else None."""
    triggers = LINEAR_RESPONSE_TRIGGERS + (("time_correlation",) if LINEAR_RESPONSE_ON_TIME_CORRELATION else ())
    joints = {int(u["joint"]) for u in unexplained
              if u.get("variable") in triggers and u.get("joint") is not None}
    wandering = {}
    if LINEAR_RESPONSE_DISTURBANCE_RULE:
        for x in model.exts:
            if not x.shared and x.joint in joints and x.effect == "time_periodic_disturbance":
                st = disturbance_not_stationary(prep, model, x, alpha, min_gain)
                if st is not None:
                    wandering[id(x)] = st
    laws = [x for x in model.exts if not x.shared and x.joint in joints
            and (x.effect in LINEAR_RESPONSE_EFFECTS or id(x) in wandering)]
    got = _latest_explained_one_way(prep, model, laws, lambda j: linear_response_nuisance(prep, j), alpha, min_gain)
    if got is not None:
        e, N, tests = got
        st = wandering.get(id(e))
        extra = {} if st is None else {"disturbance_stationarity": st}
        why_st = "" if st is None else (
            f"; the disturbance is not stationary: fitted over {st['segments']} pieces of the log its amplitude runs "
            f"from {min(st['amplitudes']):.3g} to {max(st['amplitudes']):.3g}, phasor coherence "
            f"{st['coherence']:.2f} (a pump or a fan keeps its amplitude and phase)")
        return e, {**extra,
            "reason": (f"a linear response of joint {e.joint} to its acceleration, which no vocabulary entry describes "
                       f"(an elastic gear's resonance adds one), explains it: given the other findings and the "
                       f"acceleration with {N.shape[1]} lags over {LINEAR_RESPONSE_SPAN_S:g} s "
                       + _one_way_text(tests, "that response") + why_st),
            **_one_way_entry("linear_response", tests),
            "linear_response_span_s": LINEAR_RESPONSE_SPAN_S, "linear_response_taps": int(N.shape[1])}
    return None


#: eighty-seventh round (kept; see ``docs/readme/diagnose_testbench.md``): a finding beside a constant-amplitude
#: motor-position ripple of its joint is held against the ripple with the detector's speed-dependent amplitude
#: (:func:`finding_explained_by_ripple_amplitude`); rule:
#: ``benchmarks/results/diagnose_ripple_amplitude_round87_rule.txt``
RIPPLE_AMPLITUDE_RULE = True
#: the laws :func:`finding_explained_by_ripple_amplitude` holds against that ripple: the laws of the friction in time,
#: speed and position (a disturbance periodic in time is not among them: at one speed a ripple is one too, and the
#: search tells them apart by the speeds, :func:`~drake_est.diagnose.detectors.present_at_all_speeds`)
RIPPLE_AMPLITUDE_EFFECTS = ("energy_dependent_friction", "abrupt_change", "stribeck", "asymmetric_coulomb",
                            "position_dependent_friction", "position_dependent_load")


def ripple_amplitude_nuisance(prep, ripple):
    """Columns (at its joint's used rows) of the motor-position ripple ``ripple`` at its frequencies with the detector's
    speed-dependent amplitude: :data:`~drake_est.diagnose.detectors.RIPPLE_BASIS` normalized Gaussian functions of the
    speed over the ripple's speed range, each times the cosine and sine of every component (Ch. 10's LPV model; they
    span the constant amplitude too).  None when the ripple's amplitude already follows the speed."""
    from drake_est.identification.friction.extensions import RippleRegressors, ripple_regressors
    rr = ripple_regressors(ripple.spec)
    if rr.basis.n_basis != 1 or rr.freqs.size == 0:
        return None
    jd = prep.joints[ripple.joint]
    speed = RippleRegressors(rr.freqs, {**rr.basis_spec, "n_basis": det.RIPPLE_BASIS})
    return speed.regressors(jd.q[jd.rows], jd.v[jd.rows])


def finding_explained_by_ripple_amplitude(prep, model, alpha, min_gain):
    """With :data:`RIPPLE_AMPLITUDE_RULE`: a finding of the final ``model`` (:data:`RIPPLE_AMPLITUDE_EFFECTS`) on a joint
    whose model holds a motor-position ripple of constant amplitude, that the ripple with a speed-dependent amplitude
    (:func:`ripple_amplitude_nuisance`) explains one way: given the other findings and those columns it does not
    predict the held-out residual, while they given it do (:func:`_explained_one_way`).  The inner split chooses the
    ripple's amplitude model when it is found, on the training rows of the speeds that dominate them; in a closed loop
    the torque command holds the controller's response to the ripple, whose gain and phase change with the ripple's
    frequency in time, hence with the speed, and what the constant amplitude leaves at the speeds the log rarely holds
    is left for a later law (fresh spec 31044: a ripple alone at 50 Hz with Student-t noise and a 6.8 Hz loop, its
    misfit at 0.2-0.5 rad/s, 1-2.7 Hz in time, named an energy drift with kv falling by 15 N m s/rad over the log; given
    the speed-dependent ripple the drift gains -0.2 %, the ripple given the drift 8.5 %).  The latest such finding as
    ``(ext, why)``, else None."""
    if not RIPPLE_AMPLITUDE_RULE:
        return None
    for rip in model.exts:
        if rip.shared or rip.effect != "motor_position_ripple":
            continue
        N = ripple_amplitude_nuisance(prep, rip)
        if N is None:
            continue
        laws = [x for x in model.own(rip.joint) if x.effect in RIPPLE_AMPLITUDE_EFFECTS]
        got = _latest_explained_one_way(prep, model, laws, lambda j, N=N: N, alpha, min_gain)
        if got is None:
            continue
        e, N, tests = got
        return e, {
            "reason": (f"the motor-position ripple of joint {e.joint} with an amplitude that follows the speed (a closed "
                       f"loop's response to a ripple changes with its frequency in time) explains it: given the other "
                       f"findings and that ripple ({N.shape[1]} columns) "
                       + _one_way_text(tests, "the speed-dependent amplitude")
                       + ": it took the constant-amplitude ripple's misfit"),
            **_one_way_entry("ripple_amplitude", tests),
            "ripple_amplitude_basis_functions": int(det.RIPPLE_BASIS)}
    return None


#: (eighty-first round, off) a position friction of the final model on a joint whose final residual holds structure
#: must predict one half of the log from the other where both halves visit the same positions
#: (:func:`position_friction_not_held_across_halves`); rule:
#: ``benchmarks/results/diagnose_position_friction_halves_round81_rule.txt``
POSITION_FRICTION_ACROSS_HALVES = False


def _position_frictions_with_structure(items, unexplained, ext=lambda x: x):
    """The ``items`` (extensions, or steps with ``ext=lambda st: st.ext``), latest first, whose extension is a
    single-joint ``position_dependent_friction`` on a joint with an ``unexplained`` entry: the findings the final
    position-friction checks hold (:func:`position_friction_not_held_across_halves`,
    :func:`position_friction_weak_on_blocks`, :func:`position_friction_not_dissipative`)."""
    joints = {int(u["joint"]) for u in unexplained if u.get("joint") is not None}
    for x in reversed(items):
        e = ext(x)
        if not e.shared and e.effect == "position_dependent_friction" and e.joint in joints:
            yield x


def position_friction_not_held_across_halves(prep, model, unexplained, alpha, min_gain):
    """With :data:`POSITION_FRICTION_ACROSS_HALVES`: a single-joint ``position_dependent_friction`` of the final
    ``model`` on a joint with an ``unexplained`` entry that predicts neither half of the log from the other at the
    positions both visit (:func:`~drake_est.diagnose.competition.position_law_across_halves`).  A friction level that
    changes with the position is there at every pass; an elastic gear's ringing after a few point-to-point moves is
    a law of the position only in the blocks around those moves, whose training and held-out blocks interleave
    (fresh out-of-vocabulary spec 94: a 4.5 Hz resonance beside a 4.9 Hz loop at 50 Hz, gain 28 % on the whole log,
    -97 % and -9 % from one half to the other).  The latest such finding as ``(ext, why)``, else None."""
    if not POSITION_FRICTION_ACROSS_HALVES:
        return None
    for e in _position_frictions_with_structure(model.exts, unexplained):
        m0 = Model(prep, [x for x in model.exts if x is not e])
        solve = _model_solver(m0, e.joint)
        h = comp.position_law_across_halves(prep, m0, e, alpha, min_gain, solve=solve)
        if h["held"]:
            continue
        g = ", ".join(f"{100 * x:.1f} %" for x in h["half_gains"])
        return e, {
            "reason": (f"it does not predict one half of the log from the other where both visit the same positions "
                       f"(held-out RMSE changed by {g} on {h['rows_compared'][0]} and {h['rows_compared'][1]} rows, "
                       f"not significantly lower either way), while the final residual of joint {e.joint} still "
                       f"holds structure: a misfit that follows a few moves, not a friction of the position"),
            "not_held_across_halves": True, "half_gains": h["half_gains"], "half_p_values": h["half_p_values"],
            "rows_compared": h["rows_compared"]}
    return None


#: (eighty-second round, off) a position friction on a joint whose final residual holds structure must beat the
#: model without it on the paired held-out blocks at this stricter level (:func:`position_friction_weak_on_blocks`);
#: rule: ``benchmarks/results/diagnose_position_friction_paired_round82_rule.txt``
POSITION_FRICTION_STRICT_PAIRED = False
#: the paired level of that check (the search's own is :data:`PAIRED_ALPHA`)
STRICT_PAIRED_ALPHA = 0.01


def position_friction_weak_on_blocks(prep, steps, unexplained):
    """With :data:`POSITION_FRICTION_STRICT_PAIRED`: the latest single-joint ``position_dependent_friction`` step, on
    a joint with an ``unexplained`` entry, whose paired held-out block test in its round
    (:func:`~drake_est.diagnose.competition.paired_block_test`, ``paired_p_value`` of its test) is not below
    :data:`STRICT_PAIRED_ALPHA`.  A misfit that follows a few moves (an elastic gear ringing after point-to-point moves,
    fresh out-of-vocabulary spec 94: paired p = 0.041 with Gaussian noise, 0.049 with Student-t) predicts the few
    stretches where it rings and no others, while a friction level of the position is there at every pass.  As
    ``(step, why)``, else None."""
    if not POSITION_FRICTION_STRICT_PAIRED:
        return None
    for st in _position_frictions_with_structure(steps, unexplained, ext=lambda st: st.ext):
        e = st.ext
        p = st.test.get("paired_p_value")
        if p is None or p < STRICT_PAIRED_ALPHA:
            continue
        return st, {
            "reason": (f"on the paired held-out blocks it beat the model without it at p = {p:.2g} only (not below "
                       f"{STRICT_PAIRED_ALPHA:g}), while the final residual of joint {e.joint} still holds structure: "
                       f"a misfit of a few stretches, not a friction of the position"),
            "weak_on_blocks": True, "paired_p_value": float(p), "strict_paired_alpha": STRICT_PAIRED_ALPHA}
    return None


#: (eighty-ninth round) a position friction of the final model on a joint whose final residual holds structure must
#: leave a friction: its Coulomb level at every training position, at the log's extreme speeds, no lower than
#: -:data:`NEGATIVE_FRICTION_SIGMAS` noise levels (:func:`position_friction_not_dissipative`); rule:
#: ``benchmarks/results/diagnose_position_friction_dissipation_round89_rule.txt``
POSITION_FRICTION_DISSIPATION_RULE = True


def position_friction_level(prep, model, fit, ext, sigma) -> dict | None:
    """The friction torque along the motion that the final ``model`` (fit ``fit``) gives a single-joint
    ``position_dependent_friction`` ``ext``'s joint at the positions of its training rows, at the log's lowest and
    highest speed (:func:`~drake_est.diagnose.detectors.extreme_speeds`): the nominal Coulomb level kc, the
    asymmetric level in the direction of each row (when the model holds one), the position friction w(q) ((9.13):
    sign(qd) phi(q)^T w), kv times the speed and a Stribeck law's excess at that speed (when the model holds one).
    Laws in time (an abrupt change, an energy drift) are left out: :func:`negative_friction` checks them on their own.
    ``{"min_torque", "position", "speed", "direction", "slack", "share_below"}``: the lowest such torque, where and at
    which speed it falls, the slack (:data:`NEGATIVE_FRICTION_SIGMAS` times the joint's noise level ``sigma[j]``) and
    the share of training rows whose torque falls below minus the slack; None when the log has no nonzero speed."""
    j = ext.joint
    jd = prep.joints[j]
    cs = model.coef_slices(fit, j)
    kv, kc = float(cs["nominal"]["kv"]), float(cs["nominal"]["kc"])
    rows = jd.rows[jd.train]
    v = jd.v[rows]
    s = np.sign(v)
    level = kc + s * (np.asarray(ext.cols[j], float)[jd.train] @ np.asarray(cs[ext.effect], float))
    for e in model.own(j):
        if e.effect == "asymmetric_coulomb":
            level = level + s * (np.asarray(e.cols[j], float)[jd.train] @ np.asarray(cs[e.effect], float))
    speeds = det.extreme_speeds(jd.v[jd.rows])
    if speeds is None or level.size == 0:
        return None
    strib = next((e for e in model.own(j) if e.effect == "stribeck"), None)
    slack = NEGATIVE_FRICTION_SIGMAS * float(sigma.get(j, 0.0))
    best, low = None, np.zeros(level.size, bool)
    for sp in speeds:
        f = level + kv * sp
        if strib is not None:
            f = f + float(det.stribeck_curve(strib.spec, cs["stribeck"], [sp])[0])
        low |= f < -slack
        i = int(np.argmin(f))
        if best is None or f[i] < best["min_torque"]:
            best = {"min_torque": float(f[i]), "position": float(jd.q[rows][i]), "speed": float(sp),
                    "direction": "positive" if v[i] > 0 else "negative"}
    return {**best, "slack": slack, "share_below": float(np.mean(low))}


def position_friction_not_dissipative(prep, model, fit, unexplained, sigma):
    """With :data:`POSITION_FRICTION_DISSIPATION_RULE`: the latest single-joint ``position_dependent_friction`` of the
    final ``model``, on a joint with an ``unexplained`` entry, whose friction torque along the motion
    (:func:`position_friction_level`) falls below minus :data:`NEGATIVE_FRICTION_SIGMAS` noise levels at a training
    position: a friction that pushes the joint along its motion there does not describe a contact (Sec. 9.1, a
    friction dissipates), as :func:`negative_friction` asks of a law in time; it took a misfit the model does not hold
    elsewhere (loop spec 30798: an elastic gear at 1000 Hz, a position friction beside a load whose Coulomb level
    reaches -5.1 N m at the end of the range, against a noise level of 0.63 N m, while the final residual holds
    structure in time, position, speed and acceleration).  As ``(ext, why)``, else None."""
    if not POSITION_FRICTION_DISSIPATION_RULE:
        return None
    for e in _position_frictions_with_structure(model.exts, unexplained):
        lv = position_friction_level(prep, model, fit, e, sigma)
        if lv is None or lv["min_torque"] >= -lv["slack"]:
            continue
        return e, {
            "reason": (f"with it the friction of joint {e.joint} along the motion falls to {lv['min_torque']:.3g} N m "
                       f"at q = {lv['position']:.3g} rad ({lv['direction']} direction, {lv['speed']:.3g} rad/s; "
                       f"{100 * lv['share_below']:.1f} % of the training rows below -{lv['slack']:.3g} N m, "
                       f"{NEGATIVE_FRICTION_SIGMAS:g} noise levels), while the final residual of joint {e.joint} still "
                       f"holds structure: a friction that pushes the joint along its motion is not a friction; it "
                       f"took a misfit that the model does not hold"),
            "not_dissipative": True, "friction_level": lv}
    return None


def _joint_candidates(prep, model, fit, j, accepted):
    """:func:`_candidates` of joint ``j`` alone (the other joints' detectors are not run)."""
    cache = {k: [] for k in prep.joints if k != j}
    return [c for c in _candidates(prep, model, fit, accepted, cache, {j})
            if not c.shared and c.joint == j and list(c.cols) == [j]]


def _ambiguous_with(st, effect) -> bool:
    """Whether the step ``st`` is already reported ambiguous with ``effect`` (one of its rivals)."""
    return bool(st.competition.get("ambiguous")) and effect in comp.ambiguous_rivals(st.competition)


def _add_rivals(st, new, key, info, reason) -> None:
    """Mark the step ``st`` ambiguous with the rivals ``new`` (after those it already had), store ``info`` under
    ``key`` of its competition and add ``reason`` to the competition's reason (the final marks that turn a named
    finding ambiguous: :func:`mark_level_within_rival_pair`, :func:`mark_disturbance_confounded_with_state`,
    :func:`mark_position_laws_within_speed_curve`)."""
    c = st.competition
    had = comp.ambiguous_rivals(c) if c.get("ambiguous") else []
    st.competition = {**c, "ambiguous": True, "ambiguous_with": had + list(new), key: info,
                      "reason": f"{c.get('reason', '')}; {reason}".lstrip("; ") if c.get("ambiguous") else reason}


#: (ninety-ninth round) a motor-position ripple named on a joint whose nominal training residual is mostly a
#: sinusoid in time at the frequency locked to the held-out split is reported ambiguous with
#: ``time_periodic_disturbance`` (:func:`mark_ripple_beside_split_locked_disturbance`); rule:
#: ``benchmarks/results/diagnose_ripple_split_locked_round99_rule.txt``
RIPPLE_BESIDE_SPLIT_LOCKED_DISTURBANCE = True
#: ... from this share of the nominal training residual's variance (:func:`split_locked_disturbance`)
SPLIT_LOCKED_SHARE = 0.5


def split_locked_frequency_hz(prep, j):
    """The frequency [Hz] locked to joint ``j``'s held-out split (:func:`~drake_est.diagnose.nominal.block_split`,
    alternating blocks of L seconds): 1 / (2 L).  A sinusoid in time at it advances by half a cycle per block, so every
    training block sees the same half of its cycle and every held-out block the other half (at an odd multiple each
    block holds a whole cycle or more, which the fit sees).  None for several logs (whole logs are held out) or where
    it lies above 0.45 of the sampling rate."""
    from drake_est.diagnose.nominal import n_blocks_for
    jd = prep.joints[j]
    if "log_index" in getattr(getattr(prep, "log", None), "channels", {}):
        return None
    t0, t1 = float(jd.t[0]), float(jd.t[-1])
    if not t1 > t0:
        return None
    f = n_blocks_for(t1 - t0) / (2.0 * (t1 - t0))
    return float(f) if f <= 0.45 / float(np.median(np.diff(jd.t))) else None


def split_locked_disturbance(prep, j, r, min_share=None) -> dict | None:
    """With ``r`` joint ``j``'s nominal residual at its used rows: the share of its training rows' variance that a
    sinusoid in time at :func:`split_locked_frequency_hz` (cos, sin and a constant, against the constant alone)
    explains, when it is at least ``min_share`` (default :data:`SPLIT_LOCKED_SHARE`); else None.  The held-out
    comparison cannot judge a disturbance at that frequency: fitted on one half of each cycle it is judged on the
    other, where any misfit of its shape (the axis sticking under a Coulomb level larger than the disturbance) shows
    in full (fresh loop spec 40305: a 0.5 Hz disturbance alone, 91 % of the training residual's variance, 21 % higher
    held-out RMSE; with blocks of 0.7 s it is named, 88 % lower)."""
    min_share = SPLIT_LOCKED_SHARE if min_share is None else min_share
    f = split_locked_frequency_hz(prep, j)
    if f is None:
        return None
    jd = prep.joints[j]
    tr = jd.train
    y = np.asarray(r, float)[tr]
    if y.size < 10:
        return None
    y = y - y.mean()
    w = 2 * np.pi * f * jd.t[jd.rows][tr]
    B = np.column_stack([np.ones_like(w), np.cos(w), np.sin(w)])
    e = y - B @ np.linalg.lstsq(B, y, rcond=None)[0]
    ss = float(y @ y)
    share = 1.0 - float(e @ e) / ss if ss > 0 else 0.0
    if share < min_share:
        return None
    return {"frequency_hz": f, "block_s": 0.5 / f, "share_of_training_residual": share,
            "training_rows": int(tr.sum())}


def mark_ripple_beside_split_locked_disturbance(prep, fit0, steps) -> list:
    """With :data:`RIPPLE_BESIDE_SPLIT_LOCKED_DISTURBANCE`: each named ``motor_position_ripple`` step, not already
    ambiguous with ``time_periodic_disturbance``, on a joint whose nominal residual (of ``fit0``, the search's fit of
    the nominal model) :func:`split_locked_disturbance` finds mostly periodic in time at the split's locked frequency
    is marked ambiguous with that disturbance: the held-out blocks, which decided between them, cannot judge it.  The
    model is not changed.  Returns the marked steps."""
    if not RIPPLE_BESIDE_SPLIT_LOCKED_DISTURBANCE:
        return []
    marked = []
    for st in steps:
        e = st.ext
        if e.shared or e.effect != "motor_position_ripple" or e.joint not in prep.joints:
            continue
        if _ambiguous_with(st, "time_periodic_disturbance"):
            continue
        got = split_locked_disturbance(prep, e.joint, _residual(prep, fit0, e.joint))
        if got is None:
            continue
        reason = (f"a sinusoid in time at {got['frequency_hz']:.3g} Hz explains "
                  f"{100 * got['share_of_training_residual']:.0f} % of the nominal training residual of joint "
                  f"{e.joint}, and the held-out blocks alternate every {got['block_s']:.3g} s: every training block "
                  "sees the same half of its cycle and every held-out block the other half, so the held-out "
                  "comparison cannot judge a disturbance periodic in time at that frequency (time_periodic_disturbance)")
        _add_rivals(st, ["time_periodic_disturbance"], "split_locked_disturbance", got, reason)
        marked.append(st)
    return marked


#: (ninety-third round) a position load whose held-out gain lies mostly on the few samples moving in the direction in
#: which the log cannot test an asymmetric Coulomb level is reported ambiguous with that level
#: (:func:`mark_load_in_untested_direction`)
LOAD_IN_UNTESTED_DIRECTION_RULE = True
#: ... from this share of the load's held-out gain (the summed per-sample squared-error gains) on those samples
UNTESTED_DIRECTION_GAIN_SHARE = 0.5


def untested_direction(jd):
    """(direction name, its held-out rows, its selected training samples, all selected training samples) of the
    direction in which the selected training samples of ``jd`` are too few for an asymmetric Coulomb level
    (:func:`~drake_est.diagnose.detectors.asymmetric_testable`); None when the level is testable or there is no
    training row."""
    if not jd.train.any() or det.asymmetric_testable(jd):
        return None
    n_neg, n_tr = det.training_directions(jd)
    v = jd.v[jd.rows]
    if n_neg < n_tr - n_neg:
        return "negative", jd.val & (v < 0), n_neg, n_tr
    return "positive", jd.val & (v > 0), n_tr - n_neg, n_tr


def mark_load_in_untested_direction(prep, model, fit, steps, sigma) -> list:
    """A position load whose held-out gain lies mostly (:data:`UNTESTED_DIRECTION_GAIN_SHARE`) on the held-out samples
    moving in the direction in which the log cannot test an asymmetric Coulomb level (too few selected training
    samples that way, :func:`untested_direction`).  A load does not depend on the direction, and a real one lowers the
    errors wherever the joint moves; a gain that sits in the rare direction is what a friction level of that direction
    gives, which the load holds (its gravity harmonic and kernels sum to a constant over the positions visited) and the
    few training samples of that direction fix (loop spec 35997: an asymmetric level at 250 Hz, 8 of 6,350 selected
    training samples moving in the negative direction, named a load with 85 % of its held-out gain in the 57 held-out
    samples moving that way).  The level is then fitted in the load's place; when the paired held-out blocks do not
    show the load predicting the joint better (:func:`~drake_est.diagnose.competition.paired_block_test` at
    :data:`PAIRED_ALPHA`), the load's step is marked ambiguous with the level (its competition fields change in
    place; the model is not changed).  Runs on the final model only, after every check.  Returns the marked steps;
    none without :data:`LOAD_IN_UNTESTED_DIRECTION_RULE`."""
    if not LOAD_IN_UNTESTED_DIRECTION_RULE:
        return []
    named = {(x.effect, None if x.shared else x.joint) for x in model.exts}
    marked = []
    for st in steps:
        e = st.ext
        if (e.shared or e.effect != "position_dependent_load" or ("asymmetric_coulomb", e.joint) in named
                or not any(x is e for x in model.exts)):
            continue
        if _ambiguous_with(st, "asymmetric_coulomb"):
            continue
        j = e.joint
        jd = prep.joints[j]
        way = untested_direction(jd)
        if way is None or not way[1].any():
            continue
        name, rare_val, n_rare, n_tr = way
        others = [x for x in model.exts if x is not e]
        f0 = Model(prep, others).fit(sigma)
        gain = (jd.y - f0.pred[j]) ** 2 - (jd.y - fit.pred[j]) ** 2
        total = float(gain[jd.val].sum())
        if not total > 0:
            continue
        share = float(gain[rare_val].sum()) / total
        if share < UNTESTED_DIRECTION_GAIN_SHARE:
            continue
        fl = Model(prep, others + [det.asymmetric_level(jd)]).fit(sigma)
        paired = comp.paired_block_test(prep, fl, fit, [j])
        if paired["p_value"] < PAIRED_ALPHA:
            continue
        rm, rl = _val_metrics(prep, fit, [j])["rmse"], _val_metrics(prep, fl, [j])["rmse"]
        info = {"direction": name, "held_out_gain_share_in_direction": share,
                "held_out_samples_in_direction": [int(rare_val.sum()), int(jd.val.sum())],
                "selected_training_samples_in_direction": [int(n_rare), int(n_tr)],
                "heldout_rmse_level_in_its_place": float(rl), "heldout_rmse": float(rm),
                "paired_p_value": float(paired["p_value"]), "paired_groups": paired["groups"],
                "groups_load_better": paired["groups_better"]}
        reason = (f"{100 * share:.0f} % of its held-out gain lies in the {int(rare_val.sum())} of "
                  f"{int(jd.val.sum())} held-out samples moving in the {name} direction, where joint {j} has "
                  f"{n_rare} of its {n_tr} selected training samples, too few to test asymmetric_coulomb; with that "
                  f"level in the load's place the held-out RMSE is {rl:.3g} against {rm:.3g} and the held-out blocks "
                  f"do not show the load predicting better (paired p = {paired['p_value']:.2g}): the log does not "
                  "decide between a load and a friction level of that direction (see the next experiment)")
        _add_rivals(st, ["asymmetric_coulomb"], "untested_direction", info, reason)
        marked.append(st)
    return marked

def mark_level_within_rival_pair(prep, model, steps, unexplained, sigma) -> list:
    """An asymmetric Coulomb level named on a joint whose final residual holds structure (``unexplained``), against a
    rival that contains it (a position load: its kernels sum to a constant over the positions visited,
    :func:`_contains`) taken with a second law: the model without the level plus the rival and one more candidate
    of the joint (or none), against the same model plus the level and one more candidate (or none), the best pair of
    each by held-out RMSE.  When the rival's pair predicts the held-out blocks better
    (:func:`~drake_est.diagnose.competition.paired_block_test` at :data:`PAIRED_ALPHA`), the greedy search only chose
    the level because neither law of that pair wins a round alone (loop spec 21436: a spring-like load beside a
    Stribeck law at 10 Hz, the joint moving forward at negative positions and back at positive ones, named as the
    level; the load with the Stribeck law predicts 17 of 20 held-out groups better than the level with it).  The log
    then does not decide between the level and the rival: the level's step is marked ambiguous with it (its
    competition fields change in place).  Returns the marked steps."""
    struct = {int(u["joint"]) for u in unexplained}
    marked = []
    for st in steps:
        e = st.ext
        if e.shared or e.effect != "asymmetric_coulomb" or e.joint not in struct:
            continue
        j = e.joint
        base = Model(prep, [x for x in model.exts if x is not e])
        fb = base.fit(sigma)
        accepted = {(x.effect, None if x.shared else x.joint) for x in base.exts} | {(e.effect, j)}
        cands = _joint_candidates(prep, base, fb, j, accepted)
        rivals = [c for c in cands if _contains(prep, c, e)]
        if not rivals:
            continue
        had = comp.ambiguous_rivals(st.competition) if st.competition.get("ambiguous") else []

        def best_pair(first, others):
            best = None
            for x in [None] + others:
                f = Model(prep, base.exts + [first] + ([x] if x is not None else [])).fit(sigma)
                rm = _val_metrics(prep, f, [j])["rmse"]
                if best is None or rm < best[0]:
                    best = (rm, x, f)
            return best
        for rv in rivals:
            if rv.effect in had:
                continue
            others = [c for c in cands if c.effect != rv.effect]
            lv = best_pair(e, others)
            rp = best_pair(rv, others)
            if not rp[0] < lv[0]:
                continue
            paired = comp.paired_block_test(prep, lv[2], rp[2], [j])
            if paired["p_value"] >= PAIRED_ALPHA:
                continue
            pair = [rv.effect] + ([rp[1].effect] if rp[1] is not None else [])
            lpair = [e.effect] + ([lv[1].effect] if lv[1] is not None else [])
            info = {"rival_pair": pair, "heldout_rmse_rival_pair": float(rp[0]), "level_pair": lpair,
                    "heldout_rmse_level_pair": float(lv[0]), "paired_p_value": float(paired["p_value"]),
                    "paired_groups": paired["groups"], "groups_rival_pair_better": paired["groups_better"]}
            reason = (f"{' with '.join(pair)} predicts the held-out data of joint {j} better than {' with '.join(lpair)}"
                      f" (RMSE {rp[0]:.3g} against {lv[0]:.3g}, {paired['groups_better']} of {paired['groups']} "
                      f"held-out groups, paired p = {paired['p_value']:.2g}) while the final residual still holds "
                      f"structure: {rv.effect} holds the level, and the search chose the level because neither law "
                      "of that pair wins a round alone")
            _add_rivals(st, [rv.effect], "rival_pair", info, reason)
            had = comp.ambiguous_rivals(st.competition)
            marked.append(st)
    return marked


def mark_not_separated_under_misfit(steps, unexplained, min_gain_not_white=MIN_GAIN_NOT_WHITE) -> list:
    """The runner-up counterpart of :func:`finding_not_confirmed`: a later finding on a joint whose final residual
    holds structure must also predict the held-out data of its round better than its significant runner-up by
    ``min_gain_not_white`` of the RMSE, 1 - (1 - r_winner) / (1 - r_runner_up) with r the RMSE reductions; one that
    does not is marked ambiguous with the runner-up (its competition fields change in place).  Returns the marked
    steps."""
    marked = []
    for st, where in _later_on_structure(steps, unexplained):
        c = st.competition
        sep = _separation(st.test["rmse_reduction"], c.get("runner_up_rmse_reduction"))
        if c.get("ambiguous") or not c.get("runner_up_significant") or sep is None:
            continue
        if sep < min_gain_not_white:
            st.competition = {**c, "ambiguous": True, "ambiguous_with": [c["runner_up"]],
                              "separation_from_runner_up": float(sep),
                              "reason": (f"{c['runner_up']} predicts the held-out data of the round within "
                                         f"{100 * sep:.1f} % of the RMSE (< {100 * min_gain_not_white:g} %) while the "
                                         f"final residual still holds structure ({_structure_text(where)}): "
                                         "not separated")}
            marked.append(st)
    return marked


#: seventy-second round: on a joint whose final residual still depends on the velocity, the position laws are held
#: against a free friction curve of the speed in their place (:func:`mark_position_laws_within_speed_curve`)
POSITION_LAWS_AGAINST_SPEED_CURVE = True


def position_laws_not_separated_from_speed_curve(prep, model, fit, j, sigma) -> dict | None:
    """The position laws (:data:`~drake_est.diagnose.competition.POSITION_LAWS`) of joint ``j`` in the final ``model``
    against a free friction curve of the joint's speed in their place
    (:func:`~drake_est.diagnose.competition.speed_law_nuisance` with spread knots: hat functions of |qd| per
    direction, which hold one Coulomb level per direction and a speed law of any shape over the selected speeds).
    Returns what the comparison read when the held-out blocks do not show the final model (``fit``) predicting the
    joint better than the curve's (:func:`~drake_est.diagnose.competition.paired_block_test`, p >=
    :data:`PAIRED_ALPHA`), else None (also when the joint holds no position law or the curve cannot be built)."""
    laws = [e for e in model.own(j) if e.effect in comp.POSITION_LAWS]
    if not laws:
        return None
    N = comp.speed_law_nuisance(prep, j, spread=True)
    if N is None or not np.all(np.isfinite(N)):
        return None
    curve = det.Extension("stribeck", j, {j: N}, [f"curve_{i}" for i in range(N.shape[1])],
                          {"effect": "stribeck", "free_speed_curve": True})
    alt = Model(prep, [x for x in model.exts if not any(x is e for e in laws)] + [curve]).fit(sigma)
    paired = comp.paired_block_test(prep, alt, fit, [j])
    if paired["p_value"] < PAIRED_ALPHA:
        return None
    return {"position_laws": [e.effect for e in laws], "speed_curve_columns": int(N.shape[1]),
            "heldout_rmse": _val_metrics(prep, fit, [j])["rmse"],
            "heldout_rmse_speed_curve_in_their_place": _val_metrics(prep, alt, [j])["rmse"],
            "paired_p_value": float(paired["p_value"]), "paired_groups": paired["groups"],
            "groups_final_model_better": paired["groups_better"]}


#: ninety-eighth round: :func:`mark_position_laws_within_speed_curve` also runs on a joint whose Stribeck law is
#: untestable and whose final residual's velocity structure only the ADC guard held back
#: (:func:`velocity_structure_under_adc_step`); rule:
#: ``benchmarks/results/diagnose_speed_curve_adc_guarded_round98_rule.txt``
POSITION_LAWS_SPEED_CURVE_ADC_GUARDED = True


def velocity_structure_under_adc_step(prep, readings, j, alpha=None, min_share=None) -> dict | None:
    """The final residual's velocity reading of joint ``j`` (one of ``readings``,
    :func:`~drake_est.diagnose.unexplained.test_readings`) when it passes the level and share of
    :func:`~drake_est.diagnose.unexplained.residual_structure` (:func:`~drake_est.diagnose.unexplained.reportable`)
    and only the ADC guard held it back (its structure's RMS is below the torque ADC's step), on a joint whose Stribeck
    law is untestable (the selected training speeds span less than a factor 3,
    :func:`~drake_est.diagnose.detectors.stribeck_speeds`: no Stribeck candidate ever competed there); else None.
    The guard keeps a coarse ADC's rounding error, which follows the torque level and so the speed, from being
    reported as structure; the check it starts here (:func:`position_laws_not_separated_from_speed_curve`) judges the
    speed curve on the held-out blocks instead, and only marks an ambiguity (fresh loop spec 33286: Stribeck alone at
    50 Hz with a quantized torque, its selected speeds within 0.024-0.051 rad/s, named a position friction outright;
    the velocity reading holds 49 % of the held-out residual's variance at p = 0, RMS 0.133 N m under the ADC's step
    of 0.26 N m, and a free speed curve in the friction's place predicts the held-out groups as well, paired p =
    0.10)."""
    from drake_est.diagnose import unexplained as unx
    alpha = unx.ALPHA_UNEXPLAINED if alpha is None else alpha
    min_share = unx.MIN_SHARE if min_share is None else min_share
    jd = prep.joints.get(j)
    if jd is None or det.stribeck_speeds(jd.v[jd.rows][jd.train]).size:
        return None
    for r in readings or ():
        if r.get("joint") == int(j) and r.get("variable") == "velocity" and r.get("adc_guarded") \
                and unx.reportable(r["p_value"], r["share"], "velocity", r["n_tests"], alpha, min_share):
            return r
    return None


def position_laws_beside_guarded_velocity(prep, model, fit, j, sigma, reading) -> dict | None:
    """:func:`position_laws_not_separated_from_speed_curve` on a joint that
    :func:`velocity_structure_under_adc_step` found (``reading``), with that reading in what it returns (None: the
    held-out blocks separate the final model from the curve in the position laws' place)."""
    got = position_laws_not_separated_from_speed_curve(prep, model, fit, j, sigma)
    if got is None:
        return None
    return {**got, "velocity_reading_under_adc_step": {k: reading[k] for k in
                                                       ("p_value", "share", "structure_rms", "adc_step")}}


def mark_position_laws_within_speed_curve(prep, model, fit, steps, unexplained, sigma, readings=()) -> list:
    """Position laws named where the speed may be the cause.  In point-to-point moves each position is passed at its
    own speed, so a speed law's residual is a function of position too; where no Stribeck law is named on a joint (the
    detector does not run when the selected speeds span less than a factor 3, or a level took its place) position
    laws take that residual.  On a joint of the final ``model`` with a position law, no Stribeck finding and an
    ``unexplained`` entry on the velocity, :func:`position_laws_not_separated_from_speed_curve` holds the joint's
    position laws, all at once, against a free speed curve in their place; when the held-out blocks do not separate
    the two models, each position law's step is marked ambiguous with ``stribeck`` (loop spec 19899: an asymmetric
    level beside a Stribeck law at 50 Hz, speeds within a factor 3, named as a position load and a position friction;
    the curve in their place, paired p = 0.053; spec 25506: a load beside Stribeck at 10 Hz, a position friction named
    outright, p = 0.072).  The model is not changed.  With :data:`POSITION_LAWS_SPEED_CURVE_ADC_GUARDED` (ninety-eighth
    round) the same on a joint whose velocity structure in the final residual's ``readings`` only the ADC guard held
    back and whose Stribeck law is untestable (:func:`velocity_structure_under_adc_step`, through
    :func:`position_laws_beside_guarded_velocity`).  Returns the marked steps."""
    if not POSITION_LAWS_AGAINST_SPEED_CURVE:
        return []
    speed = {int(u["joint"]) for u in unexplained if u.get("variable") == "velocity" and u.get("joint") is not None}
    guarded = {}
    if POSITION_LAWS_SPEED_CURVE_ADC_GUARDED:
        for j in prep.joints:
            if j not in speed and any(x.effect in comp.POSITION_LAWS for x in model.own(j)):
                r = velocity_structure_under_adc_step(prep, readings, j)
                if r is not None:
                    guarded[j] = r
    marked = []
    for j in sorted(speed | set(guarded)):
        if j not in prep.joints or any(x.effect == "stribeck" for x in model.own(j)):
            continue
        if j in guarded:
            got = position_laws_beside_guarded_velocity(prep, model, fit, j, sigma, guarded[j])
        else:
            got = position_laws_not_separated_from_speed_curve(prep, model, fit, j, sigma)
        if got is None:
            continue
        r = got.get("velocity_reading_under_adc_step")
        if r is not None:
            depends = (f"the final residual still depends on the velocity ({100 * r['share']:.0f} % of its held-out "
                       f"variance, p = {r['p_value']:.2g}; its RMS {r['structure_rms']:.3g} lies under the torque "
                       f"ADC's step {r['adc_step']:.3g}, so it is not reported as unexplained) and the selected speeds "
                       "span too little to test a Stribeck law")
        else:
            depends = "the final residual still depends on the velocity"
        reason = (f"the held-out blocks do not show the final model predicting joint {j} better than a free friction "
                  f"curve of its speed in the place of its position laws ({', '.join(got['position_laws'])}): "
                  f"held-out RMSE {got['heldout_rmse']:.3g} against "
                  f"{got['heldout_rmse_speed_curve_in_their_place']:.3g} with the curve, better in "
                  f"{got['groups_final_model_better']} of {got['paired_groups']} groups (paired p = "
                  f"{got['paired_p_value']:.2g}), and {depends}: where each "
                  "position is passed at its own speed, a speed law (stribeck) leaves the same residual")
        for st in steps:
            e = st.ext
            if e.shared or e.joint != j or e.effect not in comp.POSITION_LAWS:
                continue
            if _ambiguous_with(st, "stribeck"):
                continue
            _add_rivals(st, ["stribeck"], "speed_curve_in_place", got, reason)
            marked.append(st)
    return marked


#: the vocabulary law each block of a free function of the state (:func:`~drake_est.diagnose.competition.state_blocks`)
#: stands for; the other blocks (inertia, jerk, reversal transients) name no vocabulary effect
STATE_BLOCK_EFFECTS = {"load": "position_dependent_load", "position_friction": "position_dependent_friction",
                       "speed": "stribeck"}


def mark_disturbance_confounded_with_state(prep, model, steps, alpha, min_gain) -> list:
    """A time-periodic finding of the final ``model`` off the motion's lines that a free function of its joint's state
    explains (its columns do not predict the held-out residual given the other findings and that function, the test of
    :func:`disturbance_explained_by_state`) but that stays because it alone predicts the held-out residual better than
    the function alone does, is marked ambiguous with the vocabulary laws the function was made of
    (:data:`STATE_BLOCK_EFFECTS` of its blocks, chosen forward).  On a multisine motion every misfit of a law of the
    state is quasi-periodic in time, at sums of the motion's frequencies, and a sinusoid at one of them stands in for
    the misfit as well as the misfit's law stands in for it (loop spec 9353: a position friction with a bump narrower
    than its kernels at 10 Hz, then a 0.39 Hz disturbance of 7.7 % held-out gain that given the state's position
    friction and reversal blocks gains -1.8 %, the blocks alone 4.3 %).  The log cannot tell them apart.

    The same mark (sixty-fourth round) for a friction law in time (:data:`TIME_LAW_PAIR`: an energy drift or an abrupt
    change) on a joint where the final model also holds such a disturbance: the disturbance drives the acceleration,
    so the state's function is the same one, without :data:`DISTURBANCE_DRIVEN_BLOCKS`.  Under slow moves the position
    sweeps its range over minutes, and a change of the friction level in time fits a position friction's misfit (loop
    spec 23681: a position friction and a 10 Hz disturbance at 10 Hz, the friction reported as an abrupt change of
    29 % held-out gain alone, which given the state's position-friction block gains -4.4 %, the block alone 15 %).
    Returns the marked steps (their competition fields change in place)."""
    marked = []
    disturbed = {x.joint for x in model.exts if x.effect == "time_periodic_disturbance" and not x.shared}
    for st in steps:
        e = st.ext
        if e.shared or not any(x is e for x in model.exts):
            continue
        if e.effect == "time_periodic_disturbance":
            if "at_motion_line_hz" in e.evidence:
                continue
            what, tail = "a sinusoid in time", "fits part of it where the motion repeats"
        elif e.effect in TIME_LAW_PAIR and e.joint in disturbed:
            what, tail = "a law in time", "fits part of it where the moves sweep the positions slowly"
        else:
            continue
        j = e.joint
        m0 = Model(prep, [x for x in model.exts if x is not e])
        chosen = []
        got = _state_tests(prep, m0, j, e.cols[j], alpha, min_gain, without=DISTURBANCE_DRIVEN_BLOCKS, chosen=chosen)
        if got is None:
            continue
        _, t, own, state = got
        c = st.competition
        had = comp.ambiguous_rivals(c) if c.get("ambiguous") else []
        laws = [STATE_BLOCK_EFFECTS[b] for b in chosen if b in STATE_BLOCK_EFFECTS]
        new = [x for x in dict.fromkeys(laws) if x not in had and x != e.effect]
        if not new:
            continue
        reason = (f"a free function of the state of joint {j} ({', '.join(chosen)}) explains it as well: given that "
                  f"function it lowers the held-out RMSE by {100 * t['rmse_reduction']:.2f} % (p = {t['p_value']:.2g}),"
                  f" not significantly, while alone it lowers it by {100 * own:.1f} % and the function alone by "
                  f"{100 * state:.1f} %: a misfit of {' or '.join(new)} follows the motion, and {what} {tail}")
        info = {"blocks": list(chosen), "finding_given_state": comp._brief(t),
                "heldout_rmse_reduction_alone": float(own), "state_heldout_rmse_reduction_alone": float(state)}
        if e.effect == "time_periodic_disturbance":
            info["disturbance_given_state"] = info["finding_given_state"]
        _add_rivals(st, new, "confounded_with_state", info, reason)
        marked.append(st)
    return marked


def _explain_each_other_with_speed(prep, model, e, alpha, min_gain, extra=None):
    """Where a free function of the state of the law in time ``e``'s joint, whose chosen blocks hold the speed, and
    ``e`` explain each other in the final ``model`` (:func:`_state_explains_with_back`: given the function the law
    does not predict the held-out residual, nor the function given the law; ``extra``: more blocks offered to the
    function): ``(the chosen blocks, the evidence, the numbers in words)``, else None.  The test of the
    hundred-and-third and hundred-and-fifth rounds' marks."""
    chosen = []
    m0 = Model(prep, [x for x in model.exts if x is not e])
    both = _state_explains_with_back(prep, m0, e.joint, e.cols[e.joint], alpha, min_gain, extra=extra, chosen=chosen)
    if both is None or "speed" not in chosen or both[1]["significant"]:
        return None
    (_, t, own, state), back, n_far = both
    law = e.effect.replace("_", " ")
    numbers = (f"given the function the {law} lowers the held-out RMSE by {100 * t['rmse_reduction']:.1f} % "
               f"(p = {t['p_value']:.2g}), given the {law} the function lowers it by "
               f"{100 * back['rmse_reduction']:.1f} % (p = {back['p_value']:.2g}); alone the {law} lowers it by "
               f"{100 * own:.1f} %, the function by {100 * state:.1f} %")
    info = {"blocks": list(chosen), "finding_given_state": comp._brief(t), "state_given_finding": comp._brief(back),
            "heldout_rmse_reduction_alone": float(own), "state_heldout_rmse_reduction_alone": float(state)}
    if n_far:
        info["held_out_rows_beyond_training_speeds"] = n_far
    return chosen, info, numbers


#: hundred-and-third round: a law in time beside a law of the state whose joint cannot test a Stribeck law, which a
#: free function of the joint's state with a speed block explains and which explains that function back, is marked
#: ambiguous with ``stribeck`` where another finding of its joint already is
#: (:func:`mark_time_law_beside_untestable_stribeck`); rule:
#: ``benchmarks/results/diagnose_time_law_beside_untestable_stribeck_round103_rule.txt``
TIME_LAW_BESIDE_UNTESTABLE_STRIBECK_RULE = True


def mark_time_law_beside_untestable_stribeck(prep, model, steps, alpha, min_gain) -> list:
    """With :data:`TIME_LAW_BESIDE_UNTESTABLE_STRIBECK_RULE`: a friction law in time (:data:`TIME_LAW_PAIR`, an energy
    drift or an abrupt change) of the final ``model`` that :func:`time_law_explained_by_state` checks
    (:func:`_time_laws_beside_state`), on a joint where

    * a Stribeck law is untestable (the selected training speeds span less than a factor 3,
      :func:`~drake_est.diagnose.detectors.stribeck_speeds`: no Stribeck candidate ever competed there),
    * another finding's step is already reported ambiguous with ``stribeck`` (the log confounds the speed with the
      position or the level), and
    * a free function of the joint's state whose chosen blocks hold the speed explains the law (:func:`_state_explains`)
      while the law explains the function back (given the law the function does not predict the held-out residual),

    is marked ambiguous with ``stribeck``.  The fifty-third round keeps such a law, since where the two explain each
    other only the law keeps them apart; but where the log cannot test a Stribeck law, a law in time whose segments
    take the friction curve's drop between the slow moves of one part of the log and the faster ones of another is
    as much a speed law the log cannot identify (fresh loop spec 41808: a load beside Stribeck at 50 Hz with Student-t
    noise, 97 % of the moving samples below twice vs; the load named ambiguous with Stribeck, then an abrupt change
    at 86.3 s with 42.5 % lower held-out RMSE, whose segments differ in their viscous slope, -6.3 against -1.9 N m
    s/rad; given the state's speed, inertia and load blocks the change lowers it by -15 %, given the change the
    function by -5.9 %).  The model is not changed.  Returns the marked steps."""
    if not TIME_LAW_BESIDE_UNTESTABLE_STRIBECK_RULE:
        return []
    marked = []
    for e, beside in _time_laws_beside_state(model, steps):
        j = e.joint
        jd = prep.joints.get(j)
        if jd is None or det.stribeck_speeds(jd.v[jd.rows][jd.train]).size:
            continue
        st = next((s for s in steps if s.ext is e), None)
        if st is None or _ambiguous_with(st, "stribeck"):
            continue
        others = [s for s in steps if s is not st and not s.ext.shared and s.ext.joint == j
                  and _ambiguous_with(s, "stribeck")]
        if not others:
            continue
        got = _explain_each_other_with_speed(prep, model, e, alpha, min_gain)
        if got is None:
            continue
        chosen, info, numbers = got
        reason = (f"joint {j} cannot test a Stribeck law (its selected training speeds span less than a factor 3), "
                  f"its {others[0].ext.effect.replace('_', ' ')} is already not separated from one, and a free "
                  f"function of its state ({', '.join(chosen)}) and the {e.effect.replace('_', ' ')} explain each "
                  f"other: {numbers}: where the moves differ between the log's parts, a speed law the log cannot "
                  "identify leaves the same residual")
        _add_rivals(st, ["stribeck"], "untestable_stribeck_beside", info, reason)
        marked.append(st)
    return marked


#: hundred-and-fifth round: a law in time beside a Stribeck law of its joint that a free function of the joint's state
#: with a speed block explains, and which explains that function back, is marked ambiguous with ``stribeck``
#: (:func:`mark_time_law_beside_stribeck_both_ways`); rule:
#: ``benchmarks/results/diagnose_time_law_beside_stribeck_both_ways_round105_rule.txt``
TIME_LAW_BESIDE_STRIBECK_BOTH_WAYS_RULE = True


def mark_time_law_beside_stribeck_both_ways(prep, model, steps, alpha, min_gain) -> list:
    """With :data:`TIME_LAW_BESIDE_STRIBECK_BOTH_WAYS_RULE`: a friction law in time (:data:`TIME_LAW_PAIR`) of the
    final ``model`` beside a Stribeck law of its joint (:func:`_time_laws_beside_state`, the forty-sixth round's
    check), not yet reported ambiguous with ``stribeck``, where a free function of the joint's state whose chosen
    blocks hold the speed (offered the derivative filter's error through the friction curve's slope,
    :func:`filter_slope_block`, as the check is) explains the law while the law explains the function back (the case
    the fifty-third round keeps the law in), is marked ambiguous with ``stribeck``: the two are kept apart only by the
    law, and a law in time whose segments take the misfit of the Stribeck law's fixed shape between the slow moves of
    one part of the log and the faster ones of another leaves the same residual as more of the speed law (fresh loop
    spec 43172: a load beside a Gaussian-law Stribeck hump at 100 Hz with a quantized torque, 99 % of the moving
    samples below twice vs; the Stribeck law fitted with vs = 0.43 against 0.20 rad/s planted, then an abrupt change
    at 74.3 s with 16.9 % lower held-out RMSE; given the state's speed and jerk blocks the change lowers it by 1.2 %,
    given the change the function by 1.5 %, both below the least gain).  The hundred-and-third round's mark is its
    twin on a joint that cannot test a Stribeck law.  The model is not changed.  Returns the marked steps."""
    if not TIME_LAW_BESIDE_STRIBECK_BOTH_WAYS_RULE:
        return []
    marked = []
    for e, beside in _time_laws_beside_state(model, steps):
        if beside != ["stribeck"]:
            continue
        st = next((s for s in steps if s.ext is e), None)
        if st is None or _ambiguous_with(st, "stribeck"):
            continue
        got = _explain_each_other_with_speed(prep, model, e, alpha, min_gain, extra=filter_slope_block(prep, e.joint))
        if got is None:
            continue
        chosen, info, numbers = got
        reason = (f"a free function of joint {e.joint}'s state ({', '.join(chosen)}) and the "
                  f"{e.effect.replace('_', ' ')} explain each other beside its Stribeck law: {numbers}: where the "
                  "moves differ between the log's parts, the misfit of the Stribeck law's fixed shape leaves the same "
                  "residual")
        _add_rivals(st, ["stribeck"], "stribeck_shape_beside", info, reason)
        marked.append(st)
    return marked


def _refit_steps(prep, steps, reshaped, sigma) -> None:
    """Parameters are reported from the fit of each step (report.effect_parameters): the steps from the first one
    whose extension a backfit reshaped (``reshaped``: (joint, old, new extension), a new Stribeck shape or
    disturbance frequency, possibly with other columns) on are refitted with the new columns (their tests and
    validation stay those of their round)."""
    if not reshaped:
        return
    first = min(k for k, st in enumerate(steps) if any(st.ext is m[2] for m in reshaped))
    for k in range(first, len(steps)):
        steps[k].fit = Model(prep, [s.ext for s in steps[:k + 1]]).fit(sigma)


#: seventieth round (kept; see docs/readme/diagnose_testbench.md and
#: benchmarks/results/diagnose_pair_rescue_round70_rule.txt): when a round has no significant candidate, two candidates
#: of one joint held back only by the paired held-out block test are let through together when each passes every test
#: of a round beside the other (:func:`pair_rescue`)
PAIR_RESCUE = True
#: seventieth round's second rule (after the first one's wrong name at loop spec 2145, a load entered beside an
#: asymmetric level and kept beside the Stribeck law the next round chose instead): the round after a pair rescue
#: must accept the partner itself, not only find it significant
PAIR_RESCUE_PARTNER_WINS = True
#: the best candidates (by score) among those held back only by the paired block test that :func:`pair_rescue` pairs
PAIR_RESCUE_TOP = 3
#: the tests of :func:`_evaluate` whose failure keeps a candidate out of :func:`pair_rescue` (besides the F-test, gain
#: and score, which a candidate held back by the paired block test has passed)
_PAIR_RESCUE_FLAGS = ("below_quantization_step", "negative_friction", "explained_by_state_law",
                      "not_held_across_halves")


def pair_rescue(prep, model, fit, sigma, results, alpha, min_gain):
    """Two effects of one joint that mask each other, let through together.

    Forward selection adds one law per round; when two effects share a joint, each alone leaves the other's misfit,
    its held-out gain sits in a few blocks, the paired block test
    (:func:`~drake_est.diagnose.competition.paired_block_test`) holds it back, and the search stops with neither named
    (loop spec 19128: an abrupt change with a motor ripple, named on one CPU with the change's paired p = 0.041 and
    not at all where the last digits give p = 0.053).  Of the round's candidates held back only by that test (the
    :data:`PAIR_RESCUE_TOP` best by score), a pair on one joint with two different effects is let through when the
    model with both predicts the joint's held-out blocks better than ``model`` (paired block test at
    :data:`PAIRED_ALPHA`) and each passes every test of a round (:func:`_evaluate`) with the other in the model.
    Returns ``(result, partner, info)`` for the first such pair by summed score -- ``result`` the round's entry
    ``(ext, test, fit1, model1)`` of the member with the higher score alone, its test marked significant with
    ``significant_beside`` (``info``), ``partner`` the other member's effect -- or None."""
    elig = [r for r in results if r[1].get("not_separated_on_held_out_blocks") and not r[0].shared
            and not any(r[1].get(f) for f in _PAIR_RESCUE_FLAGS)
            and r[1]["p_value"] < alpha and r[1]["rmse_reduction"] >= min_gain and r[1]["score"] > 0]
    elig = sorted(elig, key=lambda r: -r[1]["score"])[:PAIR_RESCUE_TOP]
    pairs = [(a, b) for i, a in enumerate(elig) for b in elig[i + 1:]
             if a[0].joint == b[0].joint and a[0].effect != b[0].effect]
    pairs.sort(key=lambda ab: -(ab[0][1]["score"] + ab[1][1]["score"]))
    for a, b in pairs:
        ea, eb = a[0], b[0]
        f_ab = Model(prep, model.exts + [ea, eb]).fit(sigma)
        both = comp.paired_block_test(prep, fit, f_ab, [ea.joint])
        if both["p_value"] >= PAIRED_ALPHA:
            continue
        tb = _evaluate(prep, a[3], a[2], sigma, eb, alpha, min_gain, {})[1]
        if not tb["significant"]:
            continue
        ta = _evaluate(prep, b[3], b[2], sigma, ea, alpha, min_gain, {})[1]
        if not ta["significant"]:
            continue
        info = {"partner": eb.effect, "joint": int(ea.joint), "paired_p_value_of_both": float(both["p_value"]),
                "groups_both_better": int(both["groups_better"]), "groups": int(both["groups"]),
                "test_given_partner": {k: v for k, v in ta.items() if k != "significant"},
                "partner_test_given_this": {k: v for k, v in tb.items() if k != "significant"}}
        tst = {**a[1], "significant": True, "significant_beside": info}
        tst.pop("not_separated_on_held_out_blocks", None)
        tst.pop("gain_concentration", None)
        return (ea, tst, a[2], a[3]), eb.effect, info
    return None


def _moved_into_steps(steps, moved) -> set:
    """Point the search's ``steps`` at the new extensions of ``moved`` ((joint, old, new) of a backfit or a
    refinement); returns the joints that moved."""
    for _, old_ext, new_ext in moved:
        for st in steps:
            if st.ext is old_ext:
                st.ext = new_ext
    return {j for j, _, _ in moved}


def _search(prep, max_findings, alpha, min_gain, blocked=frozenset()):
    """Forward search: from the nominal model, add the best significant candidate of each round (competitions,
    backfits of change times, Stribeck shapes, disturbance and ripple frequencies; the round run again once after the
    first Stribeck reshape, :data:`STRIBECK_REDOS`, and once after the first disturbance or ripple moved by a later
    law of position, :data:`PERIODIC_REDOS`) until none is left.  ``blocked``: (effect, joint) pairs closed from the
    start (findings set aside by :func:`finding_to_set_aside`)."""
    model = Model(prep)
    fit0 = model.fit()
    sigma = {j: float(np.sqrt(fit0.rss_val[j] / max(prep.joints[j].val.sum(), 1))) for j in prep.joints}
    nominal_val = _val_metrics(prep, fit0)
    nominal_joint = {j: _val_metrics(prep, fit0, [j]) for j in prep.joints}
    accepted = set(blocked)        # closed for their joint (set aside, see run_diagnosis)
    steps = []
    rejected = []
    fit = fit0
    cache, changed = {}, None
    redone = redone_periodic = 0
    pending = None      # a pair rescue's partner, awaited in the next round (pair_rescue)
    while len(steps) < max_findings:
        accepted_before = set(accepted)
        results = _round(prep, model, fit, sigma, accepted, alpha, min_gain, cache, changed)
        sig = [r for r in results if r[1]["significant"]]
        best, explained_away = _best_surviving(prep, model, fit, sig, alpha, min_gain)
        if pending is not None:
            # the round after a pair rescue: the partner must be significant on its joint (the second rule: and win
            # the round), else back to the stop
            if not any(e.effect == pending["partner"] and e.joint == pending["joint"] and t["significant"]
                       for e, t, _, _ in results) or (
                    PAIR_RESCUE_PARTNER_WINS and (best is None or best[0].effect != pending["partner"]
                                                  or best[0].joint != pending["joint"])):
                # (rejected still holds the stopped round's candidates: no round has stopped since)
                model, fit, steps = pending["model"], pending["fit"], pending["steps"]
                break
            pending = None
        if best is None:
            rejected = [{"effect": e.effect, "joint": e.joint, **{k: v for k, v in t.items() if k != "significant"}}
                        for e, t, _, _ in results]
            rescued = (pair_rescue(prep, model, fit, sigma, results, alpha, min_gain)
                       if PAIR_RESCUE and len(steps) + 2 <= max_findings else None)
            if rescued is not None:
                best, explained_away = _best_surviving(prep, model, fit, [rescued[0]], alpha, min_gain)
            if rescued is None or best is None:
                break
            pending = {"partner": rescued[1], "joint": rescued[2]["joint"], "model": model, "fit": fit,
                       "steps": [copy.copy(st) for st in steps]}
        best, periodic = comp.resolve_periodic(prep, best, results)
        ext, tst, f1, m1 = best
        _mark_confounded_with_time(prep, model, best, results, alpha, min_gain)
        competition = _competition(ext, tst, results, prep)
        if periodic is not None:      # one speed level: ripple in position vs in time not identifiable
            competition.update(periodic)
            competition["ambiguous_with"] = [periodic["runner_up"]]
            accepted.update((e, ext.joint) for e in comp.PERIODIC_PAIR)
        if explained_away:
            competition["explained_by_periodic_residual"] = explained_away
        model = m1
        fit = f1
        accepted.add((ext.effect, None if ext.shared else ext.joint))
        changed = set(prep.joints) if (ext.shared or model.shared_exts()) else set(ext.cols)
        reshaped = []
        if redone_periodic < PERIODIC_REDOS:
            # a ripple of the joint refined without the law just accepted, kept where the law then falls (the
            # ninety-fourth and ninety-fifth rounds); a move runs the law's round again on the refined model, so the
            # backfits wait for the round's next acceptance
            model, fit, moved = ripple_refined_before_position_law(prep, model, fit, sigma, ext, alpha, min_gain)
            changed |= _moved_into_steps(steps, moved)
            reshaped += moved
            # a change of the joint whose switch is chosen again jointly with the model without the law (the
            # hundredth round); likewise a move runs the law's round again
            model, fit, moved = change_refined_before_position_law(prep, model, fit, sigma, ext, alpha, min_gain)
            changed |= _moved_into_steps(steps, moved)
            reshaped += moved
        backfits = [(effect, backfit) for effect, backfit in (
            ("abrupt_change", backfit_changes), ("stribeck", backfit_stribeck),
            ("time_periodic_disturbance", backfit_periodic), ("motor_position_ripple", backfit_ripple))
            if ext.effect != effect and any(e.effect == effect for e in model.exts) and not reshaped]
        # the backfits at once on the model as it stands (parallel.pmap): each one's result holds while those before
        # it moved nothing (the same model), and is computed again on the moved model otherwise
        accepted_model = model

        def run_ahead(b, model=model, fit=fit):
            try:
                return b[1](prep, model, fit, sigma)
            except Exception:       # computed again in order below, and raised there if it must be
                return None
        ahead = pmap(run_ahead, backfits) if len(backfits) > 1 else [None] * len(backfits)
        for (effect, backfit), early in zip(backfits, ahead):
            if early is not None and model is accepted_model:
                model, fit, moved = early
            else:
                model, fit, moved = backfit(prep, model, fit, sigma)
            changed |= _moved_into_steps(steps, moved)
            if effect != "abrupt_change":
                # a new shape or frequency may have other columns than the old: refit the steps (below)
                reshaped += moved
        stribeck_redo = redone < STRIBECK_REDOS and any(old.effect == "stribeck" for _, old, _ in reshaped)
        periodic_redo = (not stribeck_redo and redone_periodic < PERIODIC_REDOS and ext.effect in PERIODIC_REDO_LAWS
                         # (a change in ``reshaped`` comes from its refinement: the change backfit's moves are not
                         # reshapes)
                         and any(old.effect in PERIODIC_REDO_MOVED + ("abrupt_change",) for _, old, _ in reshaped))
        if stribeck_redo or periodic_redo:
            # Stribeck: the round chose this finding against a Stribeck shape that the finding itself has now changed
            # (the shape bent by what it explains).  Disturbance (or ripple, whose frequency moves alike): the round
            # chose this law of position beside a disturbance whose frequency the backfit has now moved with the
            # finding in the model, so the finding may only have taken the phase misfit of the old frequency (loop
            # spec 16061: a ripple of 3.3 % held-out gain beside a 0.5 Hz disturbance placed at 0.499873 Hz, 0.3 %
            # once the disturbance is at 0.499977 Hz).
            # Either way run the round again on the reshaped model, whose competition is the one the report gives
            redone += stribeck_redo
            redone_periodic += periodic_redo
            model = Model(prep, [x for x in model.exts if x is not ext])
            fit = model.fit(sigma)
            accepted = accepted_before
            changed = set(prep.joints)
            _refit_steps(prep, steps, reshaped, sigma)
            continue
        js = list(ext.cols)
        steps.append(Step(ext, tst, f1, _val_metrics(prep, f1, js), {j: _val_metrics(prep, f1, [j]) for j in js},
                          competition))
        _refit_steps(prep, steps, reshaped, sigma)
    return fit0, nominal_val, nominal_joint, steps, fit, model, rejected, sigma


def _ext_hit(found):
    """``(effect, joint, why)`` of a check that returns ``(ext, why)`` (None stays None)."""
    return None if found is None else (found[0].effect, found[0].joint, found[1])


def _step_hit(found):
    """``(effect, joint, why)`` of a check that returns ``(step, why)`` (None stays None)."""
    return None if found is None else (found[0].ext.effect, found[0].ext.joint, found[1])


def _final_checks(prep, out, model, fit, unexplained, alpha, min_gain) -> list:
    """The checks of the final model's findings after the disturbances against the state, in the order they run:
    ``(name, check)``, each check a thunk returning ``(effect, joint, why)`` of the first finding it sets aside, or
    None.  Each may set findings aside at most :data:`MAX_NOT_CONFIRMED` times in a diagnosis
    (:func:`_first_final_check`)."""
    steps, sigma = out[3], out[7]
    return [
        # an abrupt change beside an energy drift of its joint, against the drift at Algorithm 6's fixed point
        ("change_beside_drift", lambda: _ext_hit(change_beside_drift_at_fixed_point(prep, model, sigma, alpha,
                                                                                    min_gain))),
        # later findings against heavy-tailed noise: the gain must show on the absolute errors when a few samples
        # hold it; then the only finding of a joint whose final residual still holds structure
        ("few_samples", lambda: _step_hit(gain_in_few_samples(prep, steps, model, fit, sigma)
                                          or sole_finding_gain_in_few_samples(prep, steps, model, fit, sigma,
                                                                              unexplained))),
        # findings on a joint with a coarse torque ADC, weighed by the likelihood of the quantized readings
        ("rounding", lambda: _ext_hit(gain_within_rounding(prep, model, alpha=alpha))),
        # later position laws against the earlier one of their joint at a finer resolution
        ("finer_basis", lambda: _ext_hit(later_position_law_within_finer_basis(prep, model, min_gain))),
        # position frictions beside a Stribeck law, against a free curve of the speed
        ("speed_curve", lambda: _ext_hit(position_friction_within_speed_curve(prep, model, alpha, min_gain))),
        # friction laws in time beside a Stribeck law, against a free curve of the speed
        ("time_law_speed_curve", lambda: _ext_hit(time_law_within_speed_curve(prep, model, alpha, min_gain))),
        # Stribeck laws beside an abrupt change, on both sides of the change
        ("one_side_of_change", lambda: _ext_hit(stribeck_on_one_side_of_change(prep, model, sigma))),
        # friction laws in time against a free function of the state
        ("time_law_state", lambda: time_law_explained_by_state(prep, model, steps, alpha, min_gain)),
        # a law in time alone on its joint, where the final residual holds structure in the state
        ("sole_time_law_state", lambda: sole_time_law_explained_by_state(prep, model, unexplained, alpha, min_gain)),
        # findings on a joint whose residual shows a delay between torque and position, against the delay's columns
        ("delay", lambda: _ext_hit(finding_explained_by_delay(prep, model, unexplained, alpha, min_gain))),
        # later position loads against a free acceleration column (an error of the inertia)
        ("inertia", lambda: _ext_hit(finding_explained_by_inertia(prep, model, steps, alpha, min_gain))),
        # findings on a joint whose residual depends on the acceleration, against a free linear response to it
        # (an elastic gear)
        ("linear_response", lambda: _ext_hit(finding_explained_by_linear_response(prep, model, unexplained, alpha,
                                                                                  min_gain))),
        # findings beside a constant-amplitude ripple of their joint, against the ripple with a speed-dependent
        # amplitude (RIPPLE_AMPLITUDE_RULE)
        ("ripple_amplitude", lambda: _ext_hit(finding_explained_by_ripple_amplitude(prep, model, alpha, min_gain))),
        # (off unless POSITION_FRICTION_ACROSS_HALVES) position frictions on a joint whose residual holds structure,
        # from one half of the log to the other where both visit the same positions
        ("position_friction_halves", lambda: _ext_hit(position_friction_not_held_across_halves(
            prep, model, unexplained, alpha, min_gain))),
        # (off unless POSITION_FRICTION_STRICT_PAIRED) position frictions on a joint whose residual holds structure,
        # against a stricter level of the paired block test
        ("position_friction_paired", lambda: _step_hit(position_friction_weak_on_blocks(prep, steps, unexplained))),
        # (off unless POSITION_FRICTION_DISSIPATION_RULE) position frictions on a joint whose residual holds structure,
        # whose Coulomb level falls below zero at a training position
        ("position_friction_dissipation", lambda: _ext_hit(position_friction_not_dissipative(
            prep, model, fit, unexplained, sigma))),
    ]


def _first_final_check(checks, counts):
    """The first hit ``(effect, joint, why)`` of ``checks`` (:func:`_final_checks`) whose count in ``counts`` is below
    :data:`MAX_NOT_CONFIRMED` (that count is incremented), else None."""
    for name, check in checks:
        if counts[name] >= MAX_NOT_CONFIRMED:
            continue
        hit = check()
        if hit is not None:
            counts[name] += 1
            return hit
    return None


def run_diagnosis(log, robot="generic", joints=None, seed: int = 0, max_findings: int = MAX_FINDINGS,
                  alpha: float = ALPHA, min_gain: float = MIN_GAIN, threads: int | None = None) -> DiagnosisResult:
    """Prepare the data, fit the nominal model, and extend it while held-out tests say so.

    Outliers are screened on the nominal residual first (:func:`prepare`); a large unmodeled effect
    can hide them there, so after the search the final residual is screened again (6 MAD) and, when
    it flags new samples, they are excluded and the search is repeated once.

    ``threads``: the candidates of a round (and a detector's trial shapes) are computed on this many threads
    (:mod:`drake_est.diagnose.parallel`; None: its default); the result does not depend on it."""
    with diagnosis_threads(threads) as n:
        res = _run_diagnosis(log, robot, joints, seed, max_findings, alpha, min_gain)
    res.timing["threads"] = n
    return res


def _run_diagnosis(log, robot, joints, seed, max_findings, alpha, min_gain) -> DiagnosisResult:
    """:func:`run_diagnosis` on the threads it set up."""
    t0 = time.perf_counter()
    prep = prepare(log, robot=robot, joints=joints, seed=seed)
    prep.meta["motion_line_joints"] = motion_line_gate(prep, alpha, min_gain)
    t_prep = time.perf_counter() - t0
    screened = inertia_done = False
    for _pass in range(3):
        out = _search(prep, max_findings, alpha, min_gain)
        fit, model = out[4], out[5]
        new = 0
        if not screened:
            screened = True
            for j, jd in prep.joints.items():
                bad, skipped = screen_outliers(jd.y - fit.pred[j], joint_tau_step(prep, j))
                if skipped:
                    # misfit the search has not explained, not outliers
                    jd.counts["outlier_screen_after_extension_skipped"] = skipped
                    continue
                if bad.any():
                    new += int(bad.sum())
                    jd.counts["outliers"] = int(jd.counts.get("outliers", 0) + bad.sum())
                    jd.counts["outliers_found_after_extension"] = int(bad.sum())
                    jd.drop_rows(bad)
        if not new and not inertia_done and model.exts:
            # the inertia with the findings as regressors (closed-loop bias), once; the search is repeated
            # when it moves
            inertia_done = True
            for j, (J_old, J_new) in backfit_inertia(prep, model, fit).items():
                jd = prep.joints[j]
                jd.rb = jd.rb + (J_new - J_old) * jd.a
                jd.counts["inertia"] = J_new
                jd.counts["inertia_before_backfit"] = J_old
                new += 1
        if not new:
            break
        prep.meta.pop("payload_ext", None)
    from drake_est.diagnose.unexplained import residual_structure
    blocked, set_aside = set(), []
    time_alt_done, time_alt = False, None
    n_weak = 0
    # how often each final-model check (_final_checks) has set a finding aside in this diagnosis
    n_check = collections.Counter()

    def close_and_search(effect, joint, entry):
        """Close ``effect`` on ``joint`` (None: a shared one), record ``entry`` among the findings set aside and run
        the search again without it."""
        blocked.add((effect, joint))
        set_aside.append(entry)
        prep.meta.pop("payload_ext", None)
        return _search(prep, max_findings, alpha, min_gain, blocked)

    while True:
        # every finding against the others (the forward search is greedy): a finding set aside is closed for its
        # joint and the search run again, at most MAX_SET_ASIDE times
        ambiguous = {}
        checked = False     # whether the final model's findings were each checked given the others
        for _ in range(MAX_SET_ASIDE):
            model, sigma = out[5], out[7]
            if not [e for e in model.exts if not e.shared]:
                checked = True
                break
            bad = finding_to_set_aside(prep, model, sigma, alpha, min_gain, ambiguous, closed=set_aside)
            if bad is None:
                checked = True
                break
            effect, joint, why = bad
            out = close_and_search(effect, joint, {"effect": effect, "joint": int(joint), **why})
            ambiguous = {}      # marks of a model that was just replaced
        # a law in time ambiguous with the other one, whose rival in its place needs fewer findings
        # (time_law_alternative): the alternative is kept, the rival ambiguous with it; once per diagnosis
        if not time_alt_done:
            time_alt_done = True
            alt = time_law_alternative(prep, out, max_findings, alpha, min_gain, blocked)
            if alt is not None:
                effect, joint, rival, out, info = alt
                blocked.add((effect, joint))
                set_aside.append({
                    "effect": effect, "joint": int(joint), "time_law_alternative": info,
                    "reason": (f"ambiguous with {rival}, and with {rival} in its place the search needs fewer "
                               f"findings (not {', '.join(info['dropped'])}; held-out RMSE "
                               f"{info['heldout_rmse']:.3g} against {info['heldout_rmse_of_final_model']:.3g}, the "
                               f"held-out blocks do not show the larger model predicting better, paired p = "
                               f"{info['paired_p_value']:.2g}): those findings only absorbed the misfit of "
                               f"{effect}")})
                time_alt = (rival, joint, effect, info, "ambiguous with it, ")
            else:
                # a law in time set aside as not significant given later findings among which the other law in
                # time stands: the search again with that law closed and the set-aside one open
                # (set_aside_time_law_alternative, ninety-second round)
                alt = set_aside_time_law_alternative(prep, out, set_aside, max_findings, alpha, min_gain, blocked)
                if alt is not None:
                    effect, joint, rival, out, info = alt
                    blocked.discard((effect, joint))
                    blocked.add((rival, joint))
                    # the set-aside law is named again: its entry moves into the rival's (it is no longer closed)
                    set_aside[:] = [r for r in set_aside if not (r["effect"] == effect and r.get("joint") == joint
                                                                 and r.get("reason") == NOT_SIGNIFICANT_GIVEN_OTHERS)]
                    set_aside.append({
                        "effect": rival, "joint": int(joint), "set_aside_time_law_alternative": info,
                        "reason": (f"with {rival} closed the search names {effect} in its place ({effect} had "
                                   f"been set aside as not significant given {rival} and the other findings of "
                                   f"that model) and needs fewer findings (not "
                                   f"{', '.join(info['dropped'])}; held-out RMSE {info['heldout_rmse']:.3g} against "
                                   f"{info['heldout_rmse_of_final_model']:.3g}, the held-out blocks do not show the "
                                   f"larger model predicting better, paired p = {info['paired_p_value']:.2g}): "
                                   f"those findings and {rival} only took what {effect} explained")})
                    time_alt = (effect, joint, rival, info, "")
            if alt is not None:
                prep.meta.pop("payload_ext", None)
                ambiguous = {}
        if time_alt is not None and any(x.effect == time_alt[0] and not x.shared and x.joint == time_alt[1]
                                        for x in out[5].exts):
            rival, joint, effect, info, how = time_alt
            key = "time_law_alternative" if how else "set_aside_time_law_alternative"
            ambiguous[(rival, joint)] = {
                "ambiguous": True, "ambiguous_with": [effect], "runner_up": effect, "runner_up_joint": int(joint),
                "runner_up_significant": True, "paired_p_value": info["paired_p_value"], key: info,
                "reason": (f"{effect} was named in its place at first, {how}and needed "
                           f"{', '.join(info['dropped'])} beside it, which {rival} does not: the log does not "
                           "decide between the two laws in time, and the one that needs fewer findings is kept")}
        # a finding that holds its joint's asymmetric level, against the search run again with the level in its
        # place (level_alternatives): ambiguous with the level when the held-out blocks do not separate the two models
        for key, c in level_alternatives(prep, out[5], out[4], max_findings, alpha, min_gain, blocked).items():
            if key in ambiguous:
                had = comp.ambiguous_rivals(ambiguous[key])
                more = [x for x in c["ambiguous_with"] if x not in had]
                ambiguous[key] = {**ambiguous[key], "ambiguous_with": had + more, "level_alternative": c}
            else:
                ambiguous[key] = c
        # findings that a rival is not separated from on the held-out blocks: ambiguous between the two (those of
        # the final model's check, and the simpler rivals a finding was set aside for)
        for r in set_aside:
            if r.get("not_separated"):
                ambiguous[(r["better"], r["joint"])] = _not_separated(r["effect"], r["joint"], r["better_score"],
                                                                      r["score"], r["paired_p_value"])
        for st in out[3]:
            key = (st.ext.effect, None if st.ext.shared else st.ext.joint)
            if key in ambiguous and not st.competition.get("ambiguous"):
                st.competition = {**ambiguous[key], "in_its_round": {
                    k: st.competition.get(k) for k in ("runner_up", "runner_up_score", "margin")}}
            elif key in ambiguous:
                # already ambiguous in its round: the rivals the final model does not separate from it join
                c = st.competition
                had = comp.ambiguous_rivals(c)
                more = [x for x in comp.ambiguous_rivals(ambiguous[key]) if x not in had and x != st.ext.effect]
                if more:
                    st.competition = {**c, "ambiguous_with": had + more, "given_the_other_findings": ambiguous[key]}
        _resolve_named_rivals(out[3], checked)
        fit, model = out[4], out[5]
        fit._model = model
        readings = []
        unexplained = residual_structure(prep, fit, tests_out=readings)
        weak = finding_not_confirmed(out[3], unexplained) if n_weak < MAX_NOT_CONFIRMED else None
        if weak is None:
            # the final model's disturbances off the motion's lines, each against a free function of the state; one
            # that it explains is set aside like a finding (its effect closed on its joint, so at most once a joint)
            state = disturbance_explained_by_state(prep, model, alpha, min_gain)
            hit = state if state is not None else _first_final_check(
                _final_checks(prep, out, model, fit, unexplained, alpha, min_gain), n_check)
            if hit is None:
                mark_level_within_rival_pair(prep, model, out[3], unexplained, out[7])
                mark_not_separated_under_misfit(out[3], unexplained)
                mark_disturbance_confounded_with_state(prep, model, out[3], alpha, min_gain)
                mark_position_laws_within_speed_curve(prep, model, fit, out[3], unexplained, out[7], readings)
                mark_load_in_untested_direction(prep, model, fit, out[3], out[7])
                mark_ripple_beside_split_locked_disturbance(prep, out[0], out[3])
                mark_time_law_beside_untestable_stribeck(prep, model, out[3], alpha, min_gain)
                mark_time_law_beside_stribeck_both_ways(prep, model, out[3], alpha, min_gain)
                break
            effect, joint, why = hit
            out = close_and_search(effect, joint, {"effect": effect, "joint": int(joint), **why})
            continue
        n_weak += 1
        st, where = weak
        out = close_and_search(st.ext.effect, None if st.ext.shared else st.ext.joint, {
            "effect": st.ext.effect, "joint": int(st.ext.joint) if not st.ext.shared else None,
            "reason": (f"not confirmed: it lowered the held-out RMSE by {100 * st.test['rmse_reduction']:.1f} % "
                       f"(< {100 * MIN_GAIN_NOT_WHITE:g} %) while the final residual still holds structure "
                       f"({_structure_text(where)}), which a candidate can soak up in part"),
            "not_confirmed": True, "heldout_rmse_reduction": float(st.test["rmse_reduction"])})
    prep.meta["set_aside"] = set_aside
    fit0, nominal_val, nominal_joint, steps, fit, model, rejected, sigma = out
    timing = {"prepare_s": t_prep, "total_s": time.perf_counter() - t0, "alpha": alpha, "min_gain": min_gain}
    return DiagnosisResult(prep, fit0, nominal_val, nominal_joint, steps, fit, model, rejected, timing, sigma,
                           unexplained, readings)
