"""IRB 140 joint-state estimation: KF (linearized), EKF, UKF and particle filter side by side (thesis Ch. 4).

Truth: the IRB 140 ``MultibodyPlant`` (``drake_est.robots.RobotModel``: Drake's mass matrix, bias and gravity
terms) is simulated at 1 kHz under a computed-torque tracking controller, with *process noise*: a random joint
torque (std ``TORQUE_STD`` N m, piecewise constant over 10 ms).  Sensors at 100 Hz:

* joint encoders quantized to one count of a 12-bit motor resolver divided by the IRB 140 gear ratio
  (``models/irb140.toml``) -- the thesis gives no encoder resolution, so this is the assumption used here;
* a 3-axis accelerometer at the flange (``tool0``): specific force R_WF^T (a_F - g) in the flange frame plus
  white noise (std ``ACC_STD`` m/s^2).

Estimator model (all four filters): x = (q, v) (12 states), known input u = the controller's commanded joint
acceleration, q+ = q + h v + h^2/2 u, v+ = v + h u, process noise from an acceleration error of std
``ACC_PROCESS_STD`` rad/s^2; y = (quantized q, accelerometer) with the accelerometer model evaluated by Drake's
kinematics (flange pose, translational Jacobian and bias acceleration).  The Kalman filter uses that
measurement model linearized about the reference trajectory; EKF and UKF relinearize / propagate sigma points;
the PF is ``ParticleFilter.gaussian``.

    python diagrams/irb140_state_estimation.py [--duration 10] [--out irb140_estimation.png] [--particles 200]

Writes the figure, and ``<out stem>.json`` next to it with the RMSE of each filter (positions [rad],
velocities [rad/s]).  With ``--meshcat`` the true arm and the PF estimate are drawn in Meshcat when available.
"""
import argparse
import json
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from pydrake.multibody.tree import JacobianWrtVariable  # noqa: E402

from drake_est.estimation.kalman import KalmanFilter  # noqa: E402
from drake_est.estimation.pf import ParticleFilter  # noqa: E402
from drake_est.robots import RobotModel, irb140_metadata  # noqa: E402

DT_SIM, DT = 0.001, 0.01
TORQUE_STD = 1.0            # process noise torque [N m] (0.4-3 rad/s^2 through M^-1, wrist largest)
ACC_STD = 0.05              # accelerometer noise [m/s^2]
ACC_PROCESS_STD = 2.0       # estimator's acceleration error [rad/s^2] (noise torque through M^-1)
# the accelerometer also sees that unknown acceleration (lever ~0.5 m): the filters' accelerometer noise std
ACC_MODEL_STD = float(np.hypot(ACC_STD, 0.5 * ACC_PROCESS_STD))
RESOLVER_COUNTS = 4096      # 12-bit motor resolver (assumption, see module docstring)
# The encoders resolve ~1e-5 rad, far below the particles' one-step spread (~1e-4 rad): with the raw
# quantization variance the PF's weights collapse onto one particle every step (ESS = 1, the estimate then
# random-walks away; ``--pf-raw-encoder`` shows it).  The PF therefore uses a tempered encoder likelihood
# with this std [rad]; the Gaussian filters use the quantization variance res^2/12.
PF_ENCODER_STD = 1e-3
G_W = np.array([0.0, 0.0, -9.81])


def reference(t):
    """Smooth multi-joint reference q_ref(t), qd_ref, qdd_ref (sums of sines)."""
    amp = np.array([0.8, 0.4, 0.4, 0.8, 0.5, 1.0])
    w = 2 * np.pi * np.array([0.15, 0.2, 0.25, 0.3, 0.35, 0.4])
    off = np.array([0.0, 0.2, 0.1, 0.0, 0.6, 0.0])
    return off + amp * np.sin(w * t), amp * w * np.cos(w * t), -amp * w ** 2 * np.sin(w * t)


class Accelerometer:
    """Specific force at the flange in the flange frame, from Drake kinematics (vectorised by a loop)."""

    def __init__(self, robot: RobotModel):
        self.r = robot

    def one(self, q, v, qdd):
        p, ctx, F = self.r.plant, self.r.context, self.r.flange
        p.SetPositions(ctx, q)
        p.SetVelocities(ctx, v)
        W = p.world_frame()
        R_WF = F.CalcPoseInWorld(ctx).rotation().matrix()
        J = p.CalcJacobianTranslationalVelocity(ctx, JacobianWrtVariable.kV, F, np.zeros(3), W, W)
        bias = p.CalcBiasTranslationalAcceleration(ctx, JacobianWrtVariable.kV, F, np.zeros(3), W, W)[:, 0]
        return R_WF.T @ (J @ qdd + bias - G_W)

    def __call__(self, x, u):
        x = np.asarray(x, float)
        flat = x.reshape(-1, 12)
        out = np.empty((flat.shape[0], 3))
        for i, xi in enumerate(flat):
            out[i] = self.one(xi[:6], xi[6:], u)
        return out.reshape(x.shape[:-1] + (3,))


def simulate(duration, seed=0):
    """Truth at 100 Hz: x (T, 12), commanded acceleration u (T, 6), measurements y (T, 9)."""
    robot = RobotModel.irb140()
    acc = Accelerometer(robot)
    rng = np.random.default_rng(seed)
    gear = np.abs(irb140_metadata().gear_ratios)
    res = 2 * np.pi / RESOLVER_COUNTS / gear
    kp, kd = 100.0, 20.0
    q, v, _ = reference(0.0)
    v = v.copy()
    n_sub = int(round(DT / DT_SIM))
    T = int(round(duration / DT))
    X, U, Y = np.empty((T, 12)), np.empty((T, 6)), np.empty((T, 9))
    tau_noise = np.zeros(6)
    for k in range(T):
        t = k * DT
        qr, vr, ar = reference(t)
        a_cmd = ar + kp * (qr - q) + kd * (vr - v)
        tau_noise = TORQUE_STD * rng.standard_normal(6)
        tau = robot.inverse_dynamics(q, v, a_cmd) + tau_noise
        qdd = robot.forward_dynamics(q, v, tau)
        X[k, :6], X[k, 6:], U[k] = q, v, a_cmd
        Y[k, :6] = res * np.round(q / res)
        Y[k, 6:] = acc.one(q, v, qdd) + ACC_STD * rng.standard_normal(3)
        for j in range(n_sub):          # semi-implicit Euler at 1 kHz, u held (ZOH) over the 10 ms
            if j:
                qdd = robot.forward_dynamics(q, v, robot.inverse_dynamics(q, v, a_cmd) + tau_noise)
            v = v + DT_SIM * qdd
            q = q + DT_SIM * v
    return X, U, Y, res, robot


def model(robot, res, encoder_std=None):
    acc = Accelerometer(robot)
    h2 = DT * DT / 2

    def f(x, u, t):
        q, v = x[..., :6], x[..., 6:]
        return np.concatenate([q + DT * v + h2 * u, v + DT * u], axis=-1)

    def h(x, u, t):
        return np.concatenate([x[..., :6], acc(x, u)], axis=-1)

    s = ACC_PROCESS_STD
    B = np.vstack([h2 * np.eye(6), DT * np.eye(6)])
    R1 = s ** 2 * B @ B.T + 1e-14 * np.eye(12)       # acceleration error held over the step
    enc_var = res ** 2 / 12 + 1e-12 if encoder_std is None else np.full(6, encoder_std ** 2)
    R2 = np.diag(np.r_[enc_var, np.full(3, ACC_MODEL_STD ** 2)])
    return f, h, R1, R2


def adapted_pf(f, h, R1, R2, x0, P0, n_particles, seed):
    """Particle filter with the encoder-adapted proposal (the proposal variant of ``ParticleFilter``).

    The encoders are linear, y_enc = C x + e, so the proposal q(x+ | x, y_enc+) = N(m + K (y_enc+ - C m), S)
    with m = f(x, u), K = R1 C^T (C R1 C^T + R2_enc)^-1, S = R1 - K C R1 is the locally optimal one for them;
    its importance ratio is p(x+|x)/q(x+|x,y+) = p(y_enc+|x) / p(y_enc+|x+) (Bayes), which is what the two
    log-densities below return (``transition_logpdf`` 0, ``proposal_logpdf`` the negative log ratio), so the
    weights never divide nearly singular Gaussians.  The accelerometer enters through the measurement density."""
    from scipy.linalg import cho_factor, cho_solve

    C = np.hstack([np.eye(6), np.zeros((6, 6))])
    R2e, R2a = R2[:6, :6], R2[6:, 6:]
    S_y = C @ R1 @ C.T + R2e
    cf = cho_factor(S_y, lower=True)
    K = cho_solve(cf, C @ R1).T
    Sig = R1 - K @ C @ R1
    Ls = np.linalg.cholesky(0.5 * (Sig + Sig.T) + 1e-14 * np.eye(12))
    L0 = np.linalg.cholesky(P0)
    ld_pred = 2 * np.sum(np.log(np.diag(cf[0])))
    ld_e = np.sum(np.log(np.diag(R2e)))
    iR2a = 1.0 / np.diag(R2a)
    ld_a = np.sum(np.log(np.diag(R2a)))
    L1 = np.linalg.cholesky(R1)

    def gauss_diag(e, inv, ld):
        return -0.5 * (np.sum(e * e * inv, axis=-1) + ld + e.shape[-1] * np.log(2 * np.pi))

    def transition(x, u, t, rng):
        return f(x, u, t) + rng.standard_normal(x.shape) @ L1.T

    def proposal(x, u, t, y_next, rng):
        m = f(x, u, t)
        return m + (y_next[:6] - m[:, :6]) @ K.T + rng.standard_normal(x.shape) @ Ls.T

    def proposal_logpdf(xn, x, u, t, y_next):
        d = y_next[:6] - f(x, u, t)[:, :6]
        r = np.linalg.solve(cf[0], d.T).T            # cf[0] is the lower Cholesky factor of S_y
        log_pred = -0.5 * (np.sum(r * r, axis=1) + ld_pred + 6 * np.log(2 * np.pi))
        log_meas = gauss_diag(y_next[:6] - xn[:, :6], 1.0 / np.diag(R2e), ld_e)
        return log_meas - log_pred                   # = -log(p(y|x) / p(y|x+)) = log q - log p

    def measurement_logpdf(x, y, u, t):
        return (gauss_diag(y[:6] - x[:, :6], 1.0 / np.diag(R2e), ld_e)
                + gauss_diag(y[6:] - h(x, u, t)[:, 6:], iR2a, ld_a))

    return ParticleFilter(transition, measurement_logpdf, lambda rng, N: x0 + rng.standard_normal((N, 12)) @ L0.T,
                          n_particles, seed=seed, proposal=proposal, proposal_logpdf=proposal_logpdf,
                          transition_logpdf=lambda xn, x, u, t: np.zeros(len(x)), nu=6, ny=9)


def fd_jac(fun, x, u, eps=1e-6):
    m = fun(x, u, 0).shape[-1]
    J = np.empty((m, x.shape[0]))
    for i in range(x.shape[0]):
        d = np.zeros_like(x)
        d[i] = eps
        J[:, i] = (fun(x + d, u, 0) - fun(x - d, u, 0)) / (2 * eps)
    return J


def run_filters(X, U, Y, res, robot, n_particles=200, seed=0, pf_encoder_std=PF_ENCODER_STD):
    from drake_est.estimation.ekf import ExtendedKalmanFilter
    from drake_est.estimation.ukf import UnscentedKalmanFilter

    f, h, R1, R2 = model(robot, res)
    R2_pf = model(robot, res, pf_encoder_std)[3]
    T = Y.shape[0]
    x0 = X[0] + np.r_[np.full(6, 1e-3), np.full(6, 1e-2)]
    P0 = np.diag(np.r_[np.full(6, 1e-5), np.full(6, 1e-3)])
    out, times = {}, {}
    # KF: linear dynamics, measurement linearized about the reference trajectory
    A = np.block([[np.eye(6), DT * np.eye(6)], [np.zeros((6, 6)), np.eye(6)]])
    B = np.vstack([DT * DT / 2 * np.eye(6), DT * np.eye(6)])
    t0 = time.perf_counter()
    Cs, Ylin = np.empty((T, 9, 12)), np.empty_like(Y)
    for k in range(T):
        qr, vr, _ = reference(k * DT)
        xr = np.r_[qr, vr]
        Cs[k] = fd_jac(h, xr, U[k])
        Ylin[k] = Y[k] - h(xr, U[k], k) + Cs[k] @ xr
    out["KF (linearized)"] = KalmanFilter(A, Cs, R1, R2, x0, P0, B=B).forward_trajectory(U, Ylin).x_filt
    times["KF (linearized)"] = time.perf_counter() - t0
    for name, flt in (("EKF", ExtendedKalmanFilter(f, h, R1, R2, x0, P0, nu=6)),
                      ("UKF", UnscentedKalmanFilter(f, h, R1, R2, x0, P0, nu=6)),
                      (f"PF (N={n_particles})", adapted_pf(f, h, R1, R2, x0, P0, n_particles, seed)),
                      (f"bootstrap PF (N={n_particles})", ParticleFilter.gaussian(
                          f, h, R1, R2_pf, x0, P0, n_particles=n_particles, seed=seed, nu=6))):
        t0 = time.perf_counter()
        r = flt.forward_trajectory(U, Y)
        times[name] = time.perf_counter() - t0
        out[name] = r.x_filt
        if "PF" in name:
            times[name + " mean ESS"] = float(np.nanmean(r.extras["ess"]))
    return out, times


def rmse_table(X, est, skip=10):
    rows = {}
    for name, xe in est.items():
        e = xe[skip:] - X[skip:]
        rows[name] = {"rmse_q_rad": float(np.sqrt(np.mean(e[:, :6] ** 2))),
                      "rmse_v_rad_s": float(np.sqrt(np.mean(e[:, 6:] ** 2)))}
    return rows


def show_meshcat(robot, X, est_pf):
    try:
        from pydrake.geometry import StartMeshcat
        from pydrake.systems.framework import DiagramBuilder  # noqa: F401
        meshcat = StartMeshcat()
    except Exception as err:      # no Meshcat here (e.g. no port): say so, the figures are unaffected
        print(f"Meshcat not available: {err}")
        return
    print(f"Meshcat at {meshcat.web_url()} (flange path: true black, PF estimate blue)")
    from pydrake.geometry import Rgba
    pts = np.array([robot.forward_kinematics(x[:6]).translation() for x in X[::5]]).T
    pe = np.array([robot.forward_kinematics(x[:6]).translation() for x in est_pf[::5]]).T
    meshcat.SetLine("/true_flange", pts, 2.0, Rgba(0, 0, 0, 1))
    meshcat.SetLine("/pf_flange", pe, 2.0, Rgba(0, 0, 1, 1))
    import sys
    if sys.stdin.isatty():
        input("Meshcat is serving the scene; press Enter to exit ")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=10.0)
    ap.add_argument("--out", default="irb140_estimation.png")
    ap.add_argument("--particles", type=int, default=200)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--meshcat", action="store_true")
    ap.add_argument("--pf-raw-encoder", action="store_true",
                    help="give the PF the raw quantization variance (shows the weight collapse)")
    a = ap.parse_args()
    X, U, Y, res, robot = simulate(a.duration, a.seed)
    est, times = run_filters(X, U, Y, res, robot, a.particles, a.seed,
                             None if a.pf_raw_encoder else PF_ENCODER_STD)
    table = rmse_table(X, est)
    print(f"{'filter':24s} {'RMSE q [rad]':>13s} {'RMSE v [rad/s]':>15s} {'time [s]':>9s}")
    for name, r in table.items():
        print(f"{name:24s} {r['rmse_q_rad']:13.2e} {r['rmse_v_rad_s']:15.2e} {times[name]:9.2f}")
    for k in [k for k in times if k.endswith("mean ESS")]:
        print(f"{k[:-9]}: mean effective sample size {times[k]:.1f} of {a.particles}")
    t = DT * np.arange(len(X))
    fig, ax = plt.subplots(3, 1, figsize=(9, 9))
    ax[1].sharex(ax[0])
    j = 1                                  # joint 2 (1-based)
    ax[0].plot(t, X[:, 6 + j], "k", lw=2, label="true")
    for name, xe in est.items():
        ax[0].plot(t, xe[:, 6 + j], lw=1, label=name)
        ax[1].plot(t, xe[:, j] - X[:, j], lw=1, label=name)
    ax[1].plot(t, Y[:, j] - X[:, j], "0.6", lw=0.5, label="encoder - true")
    ax[0].set_ylabel("joint 2 velocity [rad/s]")
    ax[1].set_ylabel("joint 2 position error [rad]")
    ax[0].legend(fontsize=7, ncol=3)
    ax[1].legend(fontsize=7, ncol=3)
    names = list(table)
    xs = np.arange(len(names))
    ax[2].bar(xs, [table[n]["rmse_v_rad_s"] for n in names])
    ax[2].set_xticks(xs, names, fontsize=8)
    ax[2].set_ylabel("RMSE v [rad/s] (all joints)")
    ax[1].set_xlabel("time [s]")
    fig.suptitle(f"IRB 140 state estimation, {a.duration:g} s, encoders + flange accelerometer")
    fig.tight_layout()
    fig.savefig(a.out, dpi=100)
    out_json = Path(a.out).with_suffix(".json")
    # estimation error: worst joint-position RMSE of KF, EKF, UKF and the (adapted) PF [rad]
    err = max(r["rmse_q_rad"] for n, r in table.items() if not n.startswith("bootstrap"))
    out_json.write_text(json.dumps({"duration_s": a.duration, "rmse": table, "seconds": times,
                                    "estimation_error": err, "tracking_error": err},
                                   indent=1, allow_nan=False))
    print(f"wrote {a.out} and {out_json}")
    if a.meshcat:
        show_meshcat(robot, X, est[f"PF (N={a.particles})"])


if __name__ == "__main__":
    main()
