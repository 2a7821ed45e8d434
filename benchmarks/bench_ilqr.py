"""Benchmark: control-limited iLQR on the issue's fixed cart-pole problem (J* = 786.1796) and an IRB 140
point-to-point motion, beside crocoddyl box-DDP and Drake DirectTranscription (SNOPT, IPOPT) run here.

Cart-pole: x = (theta, theta', p, v), theta'' = -(g/l) sin theta + (u/l) cos theta - 0.1 theta', p'' = u,
explicit Euler h = 0.01, J = sum x'Qx + R u^2 + x_T'Q x_T, Q = diag(1, .1, .1, .1), R = 0.01, T = 400,
|u| <= 10, x0 = (pi - 0.1, 0, 0, 0), u = 0 initially.  Figures per solver: seconds until the cost first is
within 1e-6 (relative) of J*, seconds until the solver stops converged, iterations, J, max |u|.
Single-threaded BLAS; our timings are the median of ``--repeats`` runs after a warm-up run (the warm-up
includes loading the numba cache / compiling and is reported separately).

    python benchmarks/bench_ilqr.py [--json FILE] [--repeats 5] [--skip-drake] [--skip-irb140]
"""
from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

import argparse  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from drake_est.control.cartpole import J_STAR, benchmark_problem  # noqa: E402
from drake_est.control.ilqr import ilqr  # noqa: E402

REL = 1e-6
ISSUE_CROCODDYL_CPP = {"seconds_to_1e-6": 0.18, "seconds": 0.41, "iterations_to_1e-6": 34}


def _first_within(costs, times):
    c = np.asarray(costs)
    hit = np.nonzero(c <= J_STAR * (1 + REL))[0]
    return (float(times[hit[0]]), int(hit[0])) if hit.size else (None, None)


def run_ours(repeats, numba=True):
    model, cost, x0, U0, lo, hi = benchmark_problem(numba=numba)
    t = time.perf_counter()
    ilqr(model, cost, x0, U0, lo, hi, numba=numba)
    warm = time.perf_counter() - t
    rows = []
    for _ in range(repeats):
        t = time.perf_counter()
        r = ilqr(model, cost, x0, U0, lo, hi, numba=numba)
        total = time.perf_counter() - t
        t6, it6 = _first_within(r.costs, r.times)
        rows.append((total, t6, it6, r))
    rows.sort(key=lambda z: z[0])
    total, t6, it6, r = rows[len(rows) // 2]
    return {"J": r.J, "seconds": total, "seconds_to_1e-6": t6, "iterations_to_1e-6": it6,
            "iterations": r.iterations, "max_abs_u": float(np.abs(r.U).max()), "status": r.status,
            "first_call_seconds": warm, "repeats": repeats,
            "seconds_all": [z[0] for z in rows]}


def run_crocoddyl():
    import crocoddyl
    h, g, l, d = 0.01, 9.81, 1.0, 0.1
    Q = np.diag([1.0, 0.1, 0.1, 0.1])
    R = 0.01

    class CartPole(crocoddyl.ActionModelAbstract):
        def __init__(self, terminal=False):
            crocoddyl.ActionModelAbstract.__init__(self, crocoddyl.StateVector(4), 1, 1)
            self.terminal = terminal
            self.u_lb = np.array([-10.0])
            self.u_ub = np.array([10.0])

        def calc(self, data, x, u=None):
            if u is None or self.terminal:
                data.xnext = x.copy()
                data.cost = float(x @ Q @ x)
                return
            th, w, p, v = x
            uu = u[0]
            data.xnext = np.array([th + h * w, w + h * (-(g / l) * np.sin(th) + (uu / l) * np.cos(th) - d * w),
                             p + h * v, v + h * uu])
            data.cost = float(x @ Q @ x + R * uu * uu)

        def calcDiff(self, data, x, u=None):
            data.Lx = 2 * Q @ x
            data.Lxx = 2 * Q
            if u is None or self.terminal:
                return
            th, uu = x[0], u[0]
            Fx = np.eye(4)
            Fx[0, 1] = h
            Fx[1, 0] = h * (-(g / l) * np.cos(th) - (uu / l) * np.sin(th))
            Fx[1, 1] = 1 - h * d
            Fx[2, 3] = h
            data.Fx = Fx
            data.Fu = np.array([[0.0], [h * np.cos(th) / l], [0.0], [h]])
            data.Lu = np.array([2 * R * uu])
            data.Luu = np.array([[2 * R]])

    class Rec(crocoddyl.CallbackAbstract):
        def __init__(self, t0):
            crocoddyl.CallbackAbstract.__init__(self)
            self.t0, self.costs, self.times = t0, [], []

        def __call__(self, solver):
            self.costs.append(solver.cost)
            self.times.append(time.perf_counter() - self.t0[0])

    x0 = np.array([np.pi - 0.1, 0.0, 0.0, 0.0])
    T = 400
    runs = []
    for _ in range(3):
        problem = crocoddyl.ShootingProblem(x0, [CartPole() for _ in range(T)], CartPole(True))
        solver = crocoddyl.SolverBoxDDP(problem)
        t0 = [0.0]
        rec = Rec(t0)
        solver.setCallbacks([rec])
        t0[0] = time.perf_counter()
        solver.solve([x0] * (T + 1), [np.zeros(1)] * T, 1000)
        total = time.perf_counter() - t0[0]
        us = np.array(solver.us)
        t6, it6 = _first_within(rec.costs, rec.times)
        runs.append({"J": float(solver.cost), "seconds": total, "seconds_to_1e-6": t6,
                     "iterations_to_1e-6": None if it6 is None else it6 + 1, "iterations": int(solver.iter),
                     "max_abs_u": float(np.abs(us).max())})
    runs.sort(key=lambda z: z["seconds"])
    out = runs[1]
    out["action_model"] = "Python (crocoddyl.ActionModelAbstract subclass)"
    return out


def run_direct_transcription(solver_name):
    from pydrake.solvers import IpoptSolver, SnoptSolver
    from pydrake.symbolic import Variable, cos, sin
    from pydrake.systems.primitives import SymbolicVectorSystem
    from pydrake.planning import DirectTranscription
    h, g, l, d, T = 0.01, 9.81, 1.0, 0.1, 400
    xs = [Variable(n) for n in ("th", "w", "p", "v")]
    u = Variable("u")
    f = [xs[1], -(g / l) * sin(xs[0]) + (u / l) * cos(xs[0]) - d * xs[1], xs[3], u]
    # discrete-time system x+ = x + h f(x, u): DirectTranscription then imposes exactly the explicit-Euler model
    sys_ = SymbolicVectorSystem(state=xs, input=[u], dynamics=[xi + h * fi for xi, fi in zip(xs, f)],
                                time_period=h)
    ctx = sys_.CreateDefaultContext()
    dt = DirectTranscription(sys_, ctx, T + 1)
    prog = dt.prog()
    x = dt.state()
    uu = dt.input()
    Q = np.diag([1.0, 0.1, 0.1, 0.1])
    dt.AddRunningCost((x.dot(Q @ x) + 0.01 * uu[0] * uu[0]) / h)
    dt.AddFinalCost(dt.final_state().dot(Q @ dt.final_state()))
    dt.AddConstraintToAllKnotPoints(uu[0] <= 10.0)
    dt.AddConstraintToAllKnotPoints(uu[0] >= -10.0)
    x0 = np.array([np.pi - 0.1, 0.0, 0.0, 0.0])
    prog.AddBoundingBoxConstraint(x0, x0, dt.initial_state())
    model, cost, _, U0, lo, hi = benchmark_problem()
    X0, _, _ = model.forward(x0, np.zeros((T + 1, 4)), U0, np.zeros((T, 1, 4)), np.zeros((T, 1)), 0.0,
                             np.full((T, 1), -10.0), np.full((T, 1), 10.0))
    for t in range(T + 1):
        prog.SetInitialGuess(dt.state(t), X0[t])
    solver = SnoptSolver() if solver_name == "snopt" else IpoptSolver()
    t0 = time.perf_counter()
    res = solver.Solve(prog)
    sec = time.perf_counter() - t0
    X = dt.GetStateSamples(res).T
    U = dt.GetInputSamples(res).T[:T]
    J = cost.value(X, U)
    return {"J": float(J), "seconds": sec, "success": bool(res.is_success()),
            "max_abs_u": float(np.abs(U).max())}


def run_irb140(repeats):
    from drake_est.control.problems import irb140_point_to_point
    p = irb140_point_to_point()
    rows = []
    for _ in range(repeats):
        t = time.perf_counter()
        r = ilqr(p.model, p.cost, p.x0, p.U0, p.lower, p.upper, max_iter=100)
        rows.append((time.perf_counter() - t, r))
    rows.sort(key=lambda z: z[0])
    sec, r = rows[len(rows) // 2]
    over = np.abs(r.U) / np.abs(p.upper)
    return {"J": r.J, "J_initial": r.costs[0], "seconds": sec, "iterations": r.iterations, "status": r.status,
            "max_abs_u": np.abs(r.U).max(axis=0).tolist(), "torque_limits": p.upper.tolist(),
            "max_torque_fraction_of_limit": float(over.max()),
            "final_position_error_rad": float(np.abs(r.X[-1, :6] - p.q_goal).max()),
            "T": int(r.U.shape[0]), "dt": p.dt, "derivatives": "Drake AutoDiffXd of the MultibodyPlant"}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", help="write the figures to this JSON file")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--skip-drake", action="store_true", help="skip DirectTranscription (SNOPT/IPOPT)")
    ap.add_argument("--skip-irb140", action="store_true")
    ap.add_argument("--skip-numpy", action="store_true", help="skip our pure-numpy path")
    a = ap.parse_args(argv)
    out = {"J_star": J_STAR}
    ours = run_ours(a.repeats)
    assert ours["max_abs_u"] <= 10.0, "bound violated"
    out["cartpole"] = ours
    print(f"{'solver':38s} {'J':>12s} {'s to 1e-6':>10s} {'s total':>8s} {'iters':>6s} {'max|u|':>7s}")

    def line(name, r):
        t6 = r.get("seconds_to_1e-6")
        print(f"{name:38s} {r['J']:12.6f} {('%.4f' % t6) if t6 is not None else '-':>10s} {r['seconds']:8.4f} "
              f"{str(r.get('iterations', '-')):>6s} {r['max_abs_u']:7.3f}")
    line("drake_est ilqr (numba)", ours)
    if not a.skip_numpy:
        npy = run_ours(max(1, a.repeats // 2), numba=False)
        out["cartpole_numpy"] = npy
        line("drake_est ilqr (numpy path)", npy)
    try:
        cr = run_crocoddyl()
        out["crocoddyl_boxddp_python_action"] = cr
        line("crocoddyl box-DDP (Python action)", cr)
    except ImportError as e:
        print(f"crocoddyl not importable ({e})")
    out["crocoddyl_boxddp_cpp_issue_figures"] = ISSUE_CROCODDYL_CPP
    print(f"{'crocoddyl box-DDP all-C++ (issue figures)':38s} {'':12s} {0.18:10.4f} {0.41:8.4f}     34")
    if not a.skip_drake:
        for s in ("snopt", "ipopt"):
            try:
                r = run_direct_transcription(s)
                out[f"direct_transcription_{s}"] = r
                line(f"Drake DirectTranscription {s.upper()}", r)
            except Exception as e:  # a solver missing in this Drake build
                print(f"DirectTranscription {s}: {type(e).__name__}: {e}")
    print(f"speed-up vs crocoddyl C++ (issue figures): to 1e-6 {0.18 / ours['seconds_to_1e-6']:.1f}x, "
          f"total {0.41 / ours['seconds']:.1f}x; first call (numba cache load) {ours['first_call_seconds']:.2f} s")
    if not a.skip_irb140:
        irb = run_irb140(max(1, min(3, a.repeats)))
        assert irb["max_torque_fraction_of_limit"] <= 1.0 + 1e-12, "torque limit violated"
        out["irb140_point_to_point"] = irb
        print(f"IRB140 point-to-point (T={irb['T']}, AutoDiffXd): J {irb['J_initial']:.1f} -> {irb['J']:.3f} in "
              f"{irb['iterations']} iterations, {irb['seconds']:.2f} s, max |tau|/limit "
              f"{irb['max_torque_fraction_of_limit']:.3f}, final |q - q_goal| {irb['final_position_error_rad']:.4f} rad")
    if a.json:
        from drake_est.jsonutil import dump_json
        dump_json(out, a.json)
    return out


if __name__ == "__main__":
    main()
