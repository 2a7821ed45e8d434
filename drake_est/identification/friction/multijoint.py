"""Several joints at once: friction + gravity regressor of a Drake plant (footnote 9.2)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from drake_est.errors import DataError, IdentifiabilityError
from drake_est.regression import ridge_fit

from drake_est.identification.friction.fit import evaluate, nominal_terms, split_holdout
from drake_est.identification.friction.model import JointFriction, _check_identifiable
from drake_est.identification.friction.terms import _cols

# --------------------------------------------------------------------------- multi-joint: friction + gravity

def gravity_regressor(plant, Q, context=None):
    """Gravity torque regressor of a MultibodyPlant: G(q) = Y(q) theta, linear in the
    mass-moment parameters theta = [m_b, m_b c_b] (4 per body, c_b the centre of mass
    in the body frame). For a body with origin Jacobian Jv and angular Jacobian Jw,
    the holding torque is G_b = -(Jv^T g m_b + Jw^T ((R m_b c_b) x g)).

    Returns (Y of shape (N, n, 4 B), names). Many columns are not identifiable from
    gravity alone (e.g. the base body's); :func:`fit_multi_joint` regularizes them."""
    from pydrake.multibody.tree import JacobianWrtVariable

    Q = _cols(Q, "q")
    ctx = context or plant.CreateDefaultContext()
    g = plant.gravity_field().gravity_vector()
    W = plant.world_frame()
    from pydrake.multibody.tree import BodyIndex

    bodies = [plant.get_body(BodyIndex(i)) for i in range(plant.num_bodies())
              if BodyIndex(i) != plant.world_body().index()]
    n = plant.num_velocities()
    if Q.shape[1] != plant.num_positions():
        raise DataError(f"plant has {plant.num_positions()} positions, data has {Q.shape[1]}")
    Y = np.zeros((Q.shape[0], n, 4 * len(bodies)))
    names = []
    for b in bodies:
        names += [f"m_{b.name()}", f"mcx_{b.name()}", f"mcy_{b.name()}", f"mcz_{b.name()}"]
    for k in range(Q.shape[0]):
        plant.SetPositions(ctx, Q[k])
        for bi, b in enumerate(bodies):
            F = b.body_frame()
            Jv = plant.CalcJacobianTranslationalVelocity(ctx, JacobianWrtVariable.kV, F, np.zeros(3), W, W)
            Jw = plant.CalcJacobianAngularVelocity(ctx, JacobianWrtVariable.kV, F, W, W)
            R = F.CalcRotationMatrixInWorld(ctx).matrix()
            Y[k, :, 4 * bi] = -(Jv.T @ g)
            for c in range(3):
                Y[k, :, 4 * bi + 1 + c] = -(Jw.T @ np.cross(R[:, c], g))
    return Y, names


@dataclass
class MultiJointFit:
    """Result of :func:`fit_multi_joint`."""

    models: list            # JointFriction per joint column
    gravity_coef: np.ndarray
    gravity_names: list
    gravity_rank: int
    train: dict
    validation: dict

    def gravity(self, Y) -> np.ndarray:
        return np.asarray(Y) @ self.gravity_coef


def fit_multi_joint(Q, DQ, TAU, Y, joints=None, nominal: str = "viscous", mask=None, holdout: float = 0.3,
                    lam_gravity: float = 1e-6, gravity_names=None):
    """All joints at once (Sec. 9.2, "Estimation in multi-joint robots"): friction of
    each joint in ``joints`` (0-based columns, default all) together with a gravity
    model G(q) = Y(q) theta shared by all joints:

        tau_j = F_j(q, dq) + [Y(q) theta]_j        for every joint j.

    ``TAU``: (N, n) torque minus any known inertial/Coriolis torque; ``Y``: (N, n, p)
    from :func:`gravity_regressor`. The gravity parameters carry a tiny ridge penalty
    (``lam_gravity`` per row) so that unidentifiable combinations stay finite; their
    numerical rank is reported. Samples in ``mask`` (N,) or (N, n) are used; the
    last ``holdout`` fraction is held out."""
    Q, DQ, TAU = _cols(Q, "q"), _cols(DQ, "dq"), _cols(TAU, "tau")
    N, n = Q.shape
    Y = np.asarray(Y, float)
    if Y.shape[:2] != (N, n):
        raise DataError(f"gravity regressor has shape {Y.shape}, expected ({N}, {n}, p)")
    joints = list(range(n)) if joints is None else list(joints)
    M = np.ones((N, n), bool) if mask is None else np.asarray(mask, bool)
    if M.ndim == 1:
        M = np.repeat(M[:, None], n, axis=1)
    train_idx, val_idx = split_holdout(N, holdout)
    models = [JointFriction(nominal_terms(nominal), index=j, lam=0.0, name="nominal") for j in joints]
    blocks = [m.regressors(Q, DQ)[0] for m in models]
    p_f = [b.shape[1] for b in blocks]
    P = sum(p_f) + Y.shape[2]

    def stack(idx):
        rows, ys = [], []
        off = 0
        for jj, (j, B) in enumerate(zip(joints, blocks)):
            use = idx[M[idx, j]]
            A = np.zeros((use.size, P))
            A[:, off:off + p_f[jj]] = B[use]
            A[:, sum(p_f):] = Y[use, j, :]
            rows.append(A)
            ys.append(TAU[use, j])
            off += p_f[jj]
        return np.vstack(rows), np.concatenate(ys)

    A, yv = stack(train_idx)
    if A.shape[0] < P:
        raise IdentifiabilityError(f"{A.shape[0]} samples for {P} friction + gravity parameters")
    for jj, (j, B) in enumerate(zip(joints, blocks)):
        use = train_idx[M[train_idx, j]]
        _check_identifiable(B[use], models[jj].names, np.zeros(p_f[jj]), models[jj].terms, DQ[use, j])
    pen = np.r_[np.zeros(sum(p_f)), np.ones(Y.shape[2])]
    # scale gravity columns so that the penalty is relative
    scale = np.r_[np.ones(sum(p_f)), np.maximum(np.linalg.norm(A[:, sum(p_f):], axis=0), 1e-12)]
    res = ridge_fit(A / scale, yv, lam_gravity * A.shape[0], penalize=pen)
    coef = res.coef / scale
    sv = np.linalg.svd(A[:, sum(p_f):] / scale[sum(p_f):], compute_uv=False)
    rank = int(np.sum(sv > 1e-8 * sv[0])) if sv.size else 0
    off = 0
    for jj, m in enumerate(models):
        m.coef = coef[off:off + p_f[jj]]
        off += p_f[jj]
    theta = coef[sum(p_f):]

    def metrics(idx):
        yy, yh = [], []
        for jj, j in enumerate(joints):
            use = idx[M[idx, j]]
            yy.append(TAU[use, j])
            yh.append(models[jj].predict(Q[use], DQ[use]) + Y[use, j, :] @ theta)
        return evaluate(np.concatenate(yy), np.concatenate(yh), sum(p_f) + rank)

    return MultiJointFit(models=models, gravity_coef=theta, gravity_names=list(gravity_names or []), gravity_rank=rank,
                         train=metrics(train_idx), validation=metrics(val_idx))
