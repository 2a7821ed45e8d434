"""From a log to a validated friction model: data selection (9.9), model builders, metrics,
hold-out split and :func:`fit_friction` (thesis Ch. 9)."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from drake_est.errors import DataError, DrakeEstError, IdentifiabilityError
from drake_est.metrics import fpe, fit_percent, mae, npe, rmse
from drake_est.regression import ridge_cv

from drake_est.identification.friction.energy import fit_energy
from drake_est.identification.friction.model import JointFriction
from drake_est.identification.friction.terms import (AsymmetricCoulomb, BFETerm, Coulomb, CoupledJoint, EnergyDynamics,
                                                     Gravity, Offset, Viscous, _cols)
from drake_est.joints import coupled_joints, index_to_joint, joint_to_index, resolve_index

# --------------------------------------------------------------------------- data selection (9.9)

@dataclass
class Selection:
    """Samples kept for identification and why others were dropped."""

    mask: np.ndarray
    v_min: float
    a_max: float
    n_total: int
    n_low_velocity: int
    n_accelerating: int
    n_kept: int
    extra: dict = field(default_factory=dict)

    def summary(self) -> str:
        return (f"kept {self.n_kept} of {self.n_total} samples (9.9): dropped {self.n_low_velocity} with "
                f"|v| <= {self.v_min:.3g} rad/s and {self.n_accelerating} more with |a| >= {self.a_max:.3g} rad/s^2")

    def to_dict(self):
        return {"n_total": self.n_total, "n_kept": self.n_kept, "n_low_velocity": self.n_low_velocity,
                "n_accelerating": self.n_accelerating, "v_min": self.v_min, "a_max": self.a_max}


def select_steady(dq, ddq=None, t=None, v_min: float | None = None, a_max: float | None = None,
                  v_rel: float = 0.05, a_factor: float = 5.0) -> Selection:
    """Samples that approximately satisfy (9.9): moving (C(p, v) v small is not
    checked; run one joint at a time) at nearly constant velocity.

    Thresholds (documented defaults):

    * ``v_min``: |v| must exceed ``v_rel`` (5 %) of the 99th percentile of |v|,
      and at least 1e-3 rad/s -- near-zero velocities have an uncertain sign
      and bias the Coulomb estimate (Sec. 9.2).
    * ``a_max``: |a| must be below ``a_factor`` (5) times the median |a| of the
      moving samples, and at least 0.02 rad/s^2 -- at constant-velocity segments
      the median |a| is the differentiation noise, so this drops the
      accelerating transitions whose inertial torque M a would bias the fit.

    ``dq``, ``ddq`` are (N,) or (N, n); with several joints a sample is kept when
    every joint satisfies the thresholds that apply to the moving joints (a
    joint whose |v| never exceeds v_min is treated as standing still and only
    its acceleration is checked)."""
    DQ = _cols(dq, "dq")
    N = DQ.shape[0]
    if ddq is None and a_max is not None and np.isinf(a_max):
        DDQ = np.zeros_like(DQ)
    elif ddq is None:
        if t is None:
            raise DataError("select_steady needs the acceleration ddq or the time vector t to compute it")
        DDQ = np.gradient(DQ, np.asarray(t, dtype=float), axis=0)
    else:
        DDQ = _cols(ddq, "ddq")
        if DDQ.shape != DQ.shape:
            raise DataError(f"ddq has shape {DDQ.shape}, dq has {DQ.shape}")
    absv = np.abs(DQ)
    vmax = np.quantile(absv, 0.99, axis=0)
    vmin = np.maximum(v_rel * vmax, 1e-3) if v_min is None else np.full(DQ.shape[1], float(v_min))
    moving_joint = vmax > vmin
    low = np.zeros(N, bool)
    for c in range(DQ.shape[1]):
        if moving_joint[c]:
            low |= absv[:, c] <= vmin[c]
    if a_max is None:
        moving = ~low
        base = np.median(np.abs(DDQ[moving]), axis=0) if np.any(moving) else np.zeros(DQ.shape[1])
        amax = np.maximum(a_factor * base, 0.02)
    else:
        amax = np.full(DQ.shape[1], float(a_max))
    acc = np.any(np.abs(DDQ) >= amax, axis=1) & ~low
    mask = ~low & ~acc
    return Selection(mask=mask, v_min=float(np.max(vmin)), a_max=float(np.max(amax)), n_total=N,
                     n_low_velocity=int(low.sum()), n_accelerating=int(acc.sum()), n_kept=int(mask.sum()))


# --------------------------------------------------------------------------- model builders

NOMINAL_KINDS = ("coulomb", "viscous", "asymmetric")


def nominal_terms(kind: str = "asymmetric", gravity: bool = False, offset: bool = False) -> list:
    """Terms of the nominal model: "coulomb" (9.1), "viscous" (9.2) or "asymmetric" (9.3)."""
    if kind == "coulomb":
        terms = [Coulomb()]
    elif kind == "viscous":
        terms = [Viscous(), Coulomb()]
    elif kind == "asymmetric":
        terms = [Viscous(), AsymmetricCoulomb()]
    else:
        raise DrakeEstError(f"unknown nominal friction model '{kind}'; choose one of {NOMINAL_KINDS}")
    if gravity:
        terms.append(Gravity())
    if offset:
        terms.append(Offset())
    return terms


MODELS = ("nominal", "position", "motor", "position+motor", "energy", "position+energy", "pve", "coupled")


def build_model(model: str, Q, DQ, joint: int | None = None, nominal: str = "asymmetric", gear_ratio: float | None = None,
                coupling=None, n_position: int = 12, n_motor: int = 36, n_velocity: int = 6,
                width_factor: float = 1.0, gravity: bool = False, lam="cv", joint_number=None,
                n_energy: int = 3, joint_numbers=None, index: int | None = None) -> JointFriction:
    """An unfitted :class:`JointFriction` of the named structure for data column ``index`` (0-based;
    ``joint=`` is its deprecated old name, see :func:`drake_est.joints.resolve_index`).

    * ``nominal``: (9.1)-(9.3);
    * ``position``: nominal + normalized Gaussian RBFs in arm position, split by sign of v (9.16);
    * ``motor``: nominal + RBFs in motor position x velocity (36 x 6 as in Sec. 9.6), needs ``gear_ratio``;
    * ``position+motor``: both expansions;
    * ``energy``: nominal + sign(v) E (9.22)-(9.24); fit with :func:`drake_est.identification.friction.energy.fit_energy`;
    * ``position+energy``: position model + energy (Table 9.2, right column);
    * ``pve``: nominal + P x V x E expansion (Sec. 9.6, 40 x 6 x 3 in the thesis) -- E must be estimated first;
    * ``coupled``: nominal + Coulomb/viscous terms of the gear-coupled wrist joints (9.12); ``coupling``
      is the robot's motor-from-arm matrix (q_motor = N q_arm) restricted to the joints in the data;
      ``joint_numbers`` (1-based, per data column) only label the columns."""
    joint = resolve_index(index, joint, "build_model")  # private: the 0-based column
    Q, DQ = _cols(Q, "q"), _cols(DQ, "dq")
    terms = nominal_terms(nominal, gravity=gravity)
    if model not in MODELS:
        raise DrakeEstError(f"unknown friction model '{model}'; choose one of {', '.join(MODELS)}")
    if model in ("position", "position+motor", "position+energy"):
        terms.append(BFETerm.from_data(["q"], Q, DQ, joint, n_position, width_factor, label="pos"))
    if model in ("motor", "position+motor"):
        if not gear_ratio:
            raise DrakeEstError("the motor-position model needs the gear ratio (--gear-ratio or robot metadata)")
        terms.append(BFETerm.from_data(["qm", "dq"], Q, DQ, joint, [n_motor, n_velocity], width_factor,
                                       gear_ratio=gear_ratio, label="motor"))
    if model == "coupled":
        if coupling is None:
            raise DrakeEstError("the gear-coupled model needs the coupling (motor-from-arm) matrix of the robot")
        N = np.asarray(coupling, dtype=float)
        if N.shape != (Q.shape[1], Q.shape[1]):
            raise DataError(f"coupling matrix has shape {N.shape} for a log with {Q.shape[1]} joints")
        ks = [joint_to_index(i) for i in coupled_joints(N, index_to_joint(joint))]
        if not ks:
            raise DrakeEstError(f"joint column {joint} is not gear-coupled to any other joint in the coupling matrix")
        for k in ks:
            terms.append(CoupledJoint(k, N, motor_side=False, label=f"q{(k + 1) if joint_numbers is None else joint_numbers[k]}"))
    energy = None
    if model in ("energy", "position+energy"):
        energy = EnergyDynamics(gain=0.0, time_constant=1.0, h=1.0)  # placeholder, set by fit_energy
    m = JointFriction(terms, index=joint, lam=lam, energy=energy, joint_number=joint_number, name=model)
    m.info["n_energy"] = n_energy
    m.info["n_position"] = n_position
    m.info["width_factor"] = width_factor
    return m


def add_energy_expansion(model: JointFriction, Q, DQ, E, n=(40, 6, 3), width_factor=1.0) -> JointFriction:
    """Replace a fitted energy model's sign(v) E term by a P x V x E expansion (Sec. 9.6)."""
    terms = [t for t in model.terms if not isinstance(t, BFETerm)]
    terms.append(BFETerm.from_data(["q", "dq", "E"], Q, DQ, model.index, list(n), width_factor, E=E, label="pve"))
    return JointFriction(terms, index=model.index, lam=model.lam, energy=None, joint_number=model.joint_number,
                         name="pve")


# --------------------------------------------------------------------------- metrics

def evaluate(y, yhat, n_params: int, truth: dict | None = None, params: dict | None = None) -> dict:
    """Validation metrics (Johansson 1993): Fit (%), FPE, RMSE, MAE, and NPE (9.28)
    over the parameters present in both ``truth`` and ``params``."""
    y = np.asarray(y, float).ravel()
    yhat = np.asarray(yhat, float).ravel()
    out = {"fit": fit_percent(y, yhat), "fpe": fpe(y, yhat, n_params), "rmse": rmse(y, yhat),
           "mae": mae(y, yhat), "n": int(y.size), "n_params": int(n_params)}
    if truth and params:
        keys = [k for k in truth if k in params and truth[k] != 0]
        if keys:
            out["npe"] = npe([params[k] for k in keys], [truth[k] for k in keys])
            out["npe_params"] = keys
    return out


def split_holdout(n: int, frac: float = 0.3, where: str = "end"):
    """Indices of a contiguous training block and a held-out validation block."""
    if not 0 < frac < 1:
        raise DrakeEstError(f"validation fraction must be in (0, 1), got {frac}")
    cut = int(round(n * (1 - frac)))
    idx = np.arange(n)
    if where == "end":
        return idx[:cut], idx[cut:]
    if where == "start":
        k = n - cut
        return idx[k:], idx[:k]
    raise DrakeEstError(f"unknown hold-out position '{where}'")


# --------------------------------------------------------------------------- from a log to a validated model

@dataclass
class FrictionResult:
    """Result of :func:`fit_friction`: the fitted model, the data selection, and the
    metrics on the training block and on the held-out validation block."""

    model: JointFriction
    selection: Selection
    train: dict
    validation: dict
    structure: dict
    arrays: dict = field(default_factory=dict, repr=False)  # t, q, dq, y, yhat, masks (for plots)

    def to_dict(self) -> dict:
        return {"model": self.model.to_dict(), "selection": self.selection.to_dict(), "train": self.train,
                "validation": self.validation, "structure": self.structure}


def _cv_subsample(idx: np.ndarray, max_rows: int = 3000) -> np.ndarray:
    step = max(1, int(np.ceil(idx.size / max_rows)))
    return idx[::step]


def _choose_structure(model_name, Q, DQ, y, joint, fit_idx, build_kw, candidates):
    """Pick (n_position, width_factor) of a position expansion by 5-fold contiguous CV."""
    sub = _cv_subsample(fit_idx, 8000)
    best, table = None, []
    for n, wf in candidates:
        m = build_model(model_name, Q[fit_idx], DQ[fit_idx], index=joint, n_position=n, width_factor=wf,
                        **build_kw)
        A, _ = m.regressors(Q[sub], DQ[sub])
        if A.shape[0] < 2 * A.shape[1]:
            continue
        pen = m.penalize
        errs = ridge_cv(A, y[sub], np.array([1e-5, 1e-3, 1e-1]) * sub.size, pen)
        e = float(np.min(errs))
        table.append({"n_position": n, "width_factor": wf, "cv_mse": e})
        if best is None or e < best[0]:
            best = (e, n, wf)
    if best is None:
        raise IdentifiabilityError(f"too few samples ({fit_idx.size}) for any position basis; use a longer log")
    return best[1], best[2], table


def fit_friction(t, Q, DQ, y, model: str = "nominal", joint: int | None = None, ddq=None, holdout: float = 0.3,
                 nominal: str = "asymmetric", gear_ratio: float | None = None, coupling=None,
                 n_position: int | None = None, width_factor: float | None = None, n_motor: int = 36,
                 n_velocity: int = 6, selection: Selection | None = None, v_min=None, a_max=None,
                 energy_iters: int = 50, energy_init=None, truth: dict | None = None, joint_number=None,
                 joint_numbers=None, gravity: bool = False, energy_power: str = "measured",
                 index: int | None = None) -> FrictionResult:
    """Fit the named model (see :func:`build_model`) to the friction torque ``y`` of
    data column ``index`` (0-based; ``joint=`` is its deprecated old name; ``joint_number`` the
    1-based joint number written to files) and validate it on a held-out block.

    * ``y`` is the measured torque minus what the rigid-body model explains (or the
      raw torque for a single joint at constant velocity, (9.9));
    * samples are selected by :func:`select_steady` (or the given ``selection``);
    * the last ``holdout`` fraction of the log is held out; all fitting (including
      the choice of penalty/basis by cross-validation) uses the first part only;
    * energy models are fitted by Algorithm 6 and validated by simulating E forward
      over the whole log from the model alone (W = |F^ v|), so validation never
      sees measured torque.
    ``truth`` (names -> values) adds NPE (9.28) to the metrics. ``energy_power``: see
    :func:`drake_est.identification.friction.energy.fit_energy`."""
    joint = resolve_index(index, joint, "fit_friction")  # private: the 0-based column
    t = np.asarray(t, float).ravel()
    Q, DQ = _cols(Q, "q"), _cols(DQ, "dq")
    y = np.asarray(y, float).ravel()
    N = t.size
    if Q.shape[0] != N or DQ.shape[0] != N or y.size != N:
        raise DataError(f"t has {N} samples, q {Q.shape[0]}, dq {DQ.shape[0]}, torque {y.size}")
    if not np.all(np.isfinite(y)) or not np.all(np.isfinite(DQ)):
        raise DataError("torque or velocity contains NaN/inf")
    if N < 20:
        raise IdentifiabilityError(f"only {N} samples; too few to identify a friction model")
    if selection is None:
        selection = select_steady(DQ[:, joint], None if ddq is None else _cols(ddq, "ddq")[:, joint], t=t,
                                  v_min=v_min, a_max=a_max)
    sel = selection.mask
    train_idx, val_idx = split_holdout(N, holdout)
    in_train = np.zeros(N, bool)
    in_train[train_idx] = True
    fit_mask = sel & in_train
    val_mask = sel & ~in_train
    if fit_mask.sum() == 0:
        raise IdentifiabilityError(f"no samples left for identification: {selection.summary()}")
    if val_mask.sum() == 0:
        raise IdentifiabilityError("no selected samples in the held-out block; use a longer log or a smaller holdout")
    build_kw = dict(nominal=nominal, gear_ratio=gear_ratio, coupling=coupling, n_motor=n_motor,
                    n_velocity=n_velocity, joint_number=joint_number, joint_numbers=joint_numbers, gravity=gravity)
    structure = {"model": model, "nominal": nominal}
    base = model.replace("+energy", "") if model.endswith("+energy") else model
    if "position" in model and (n_position is None or width_factor is None):
        fit_idx = np.flatnonzero(fit_mask)
        cands = [(n, w) for n in ((n_position,) if n_position else (10, 20, 30))
                 for w in ((width_factor,) if width_factor else (1.0, 2.0))]
        n_position, width_factor, table = _choose_structure(base, Q, DQ, y, joint, fit_idx, build_kw, cands)
        structure["position_cv"] = table
    n_position = n_position or 16
    width_factor = width_factor or 1.0
    structure.update({"n_position": n_position, "width_factor": width_factor})
    # the grid spans the training data
    m = build_model(model, Q[fit_mask], DQ[fit_mask], index=joint, n_position=n_position,
                    width_factor=width_factor, **build_kw)
    if m.energy is not None:

        g0, t0 = (None, None) if energy_init is None else energy_init
        tr = slice(0, int(train_idx[-1]) + 1)
        if m.has_bfe and energy_init is None:
            # Sec. 9.4: estimate E with the simple nominal model first; start the extended model from it and
            # from the torque-envelope guess (9.27), and keep the run with the lower training output error
            # (a flexible expansion fitted before E is known can absorb the warm-up transient)
            m0 = build_model("energy", Q[fit_mask], DQ[fit_mask], index=joint, **build_kw)
            e0 = fit_energy(m0, t[tr], Q[tr], DQ[tr], y[tr], mask=sel[tr], n_iter=energy_iters, power=energy_power)
            starts = [(m0.energy.gain, m0.energy.time_constant), (e0.initial["gain"], e0.initial["time_constant"])]
            structure["energy_stage1"] = {"gain": starts[0][0], "time_constant": starts[0][1], "initial": e0.initial}
            best = None
            for g0, t0 in starts:
                mc = m.copy()
                efc = fit_energy(mc, t[tr], Q[tr], DQ[tr], y[tr], mask=sel[tr], gain0=g0, tau0=t0,
                                 n_iter=energy_iters, power=energy_power)
                score = efc.history[-1]["rmse"]
                if best is None or score < best[0]:
                    best = (score, mc, efc)
            _, m, ef = best
        else:
            ef = fit_energy(m, t[tr], Q[tr], DQ[tr], y[tr], mask=sel[tr], gain0=g0, tau0=t0, n_iter=energy_iters,
                            power=energy_power)
        structure["energy_initial"] = ef.initial
        structure["energy_history"] = ef.history
        E_model = m.simulate_energy(Q, DQ)
        yhat = m.predict(Q, DQ, E_model)
        arrays_E = E_model
    else:
        m.fit(Q, DQ, y, mask=fit_mask)
        yhat = m.predict(Q, DQ)
        arrays_E = None
    p = m.n_params + (2 if m.energy is not None else 0)
    dof = m.info.get("dof", p) + (2 if m.energy is not None else 0)
    params = m.params()
    tr_metrics = evaluate(y[fit_mask], yhat[fit_mask], int(round(dof)), truth, params)
    va_metrics = evaluate(y[val_mask], yhat[val_mask], int(round(dof)), truth, params)
    structure["n_params"] = p
    structure["effective_params"] = float(dof)
    arrays = {"t": t, "q": Q[:, joint], "dq": DQ[:, joint], "y": y, "yhat": yhat, "selected": sel,
              "train": in_train, "E": arrays_E}
    return FrictionResult(model=m, selection=selection, train=tr_metrics, validation=va_metrics,
                          structure=structure, arrays=arrays)


def friction_target(log, joint_col: int, robot=None, inertia: bool = True):
    """The friction torque y of one joint from a :class:`drake_est.data.Log`: the
    measured torque minus the rigid-body torque when ``robot`` (a
    :class:`drake_est.robots.RobotModel` covering all logged joints) is given:
    ID(q, dq, ddq) with ``inertia``, else ID(q, dq, 0) (gravity, Coriolis and
    centrifugal torques only -- for constant-velocity data selected by (9.9), which
    avoids adding the noise of a differentiated acceleration)."""
    if log.tau is None:
        raise DataError("the log has no torque columns (tau<j>); friction cannot be identified")
    y = log.tau[:, joint_col].copy()
    if robot is not None:
        acc = log.ddq if inertia else np.zeros_like(log.q)
        idq = robot.inverse_dynamics_batch(log.q, log.dq, acc)
        y = y - idq[:, joint_col]
    return y
