"""``drake-est calibrate ft|laser DATA --out DIR``: sensor calibration on logged data (thesis Ch. 13).

Input layouts (SI units unless scaled with ``--length-scale``):

F/T sensor (``ft``), one row per static pose:
  * NPZ: ``wrench`` (N, 6) [fx fy fz N, tx ty tz N m] (or ``force`` (N, 3) and ``torque`` (N, 3)), and either
    ``poses`` (N, 4, 4) flange poses in the robot base [m] or ``q`` (N, 6) IRB 140 joint angles [rad].
  * CSV with a header: ``fx,fy,fz,tx,ty,tz`` and either ``q1..q6`` or ``r11,r12,r13,r21,...,r33,px,py,pz``.

Laser scanner (``laser``), one row per measured point:
  * NPZ: ``points`` (N, 3) in sensor coordinates [m] (a 2-D scanner has one coordinate identically 0),
    ``pose_index`` (N,) into ``poses`` (M, 4, 4) or ``q`` (M, 6); optional ``plane`` (N,) labels and
    ``T0`` (4, 4) initial guess of T_TF^S.
  * CSV with a header: ``x,y,z`` (sensor) [+ ``plane``] and the pose of each row (``q1..q6`` or
    ``r11..r33,px,py,pz``); consecutive rows with the same pose form one scan.
"""
from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np

from drake_est.errors import DataError

POSE_COLS = [f"r{i}{j}" for i in range(1, 4) for j in range(1, 4)] + ["px", "py", "pz"]


def register(sub):
    p = sub.add_parser("calibrate", help="calibrate a wrist F/T sensor or laser scanner from logged data (Ch. 13)",
                       description=__doc__.replace("``", ""), formatter_class=__import__("argparse").RawDescriptionHelpFormatter)
    p.add_argument("sensor", choices=["ft", "laser"], help="which sensor")
    p.add_argument("data", help="NPZ or CSV file (layout above)")
    p.add_argument("--out", default="calibration-out", help="output folder (JSON, histogram PNG)")
    p.add_argument("--method", default=None,
                   help="ft: relaxation (default) or cayley; laser: ls (default) or tls")
    p.add_argument("--mass", type=float, default=None, help="ft/cayley: payload mass [kg]")
    p.add_argument("--no-bias", action="store_true", help="ft: do not estimate force/torque offsets")
    p.add_argument("--iters", type=int, default=30, help="laser: two-step iterations (default 30)")
    p.add_argument("--refine", action="store_true", help="laser: final nonlinear refinement (13.29)")
    p.add_argument("--T0", default=None, help="laser: initial guess 'x y z roll pitch yaw' [m, deg] "
                   "(overrides T0 in the file; default identity)")
    p.add_argument("--min-planes", type=int, default=3, help="laser: minimum number of planes (default 3)")
    p.add_argument("--assign-threshold", type=float, default=0.02,
                   help="laser: RANSAC distance threshold [m] when no plane labels are given")
    p.add_argument("--length-scale", type=float, default=1.0,
                   help="multiply lengths in the file by this to get metres (e.g. 0.001 for mm)")
    p.set_defaults(func=run)


def _read_table(path: Path) -> dict:
    if path.suffix.lower() == ".npz":
        try:
            with np.load(path, allow_pickle=False) as z:
                return {k: z[k] for k in z.files}
        except Exception as err:  # noqa: BLE001 - BadZipFile, zlib.error, truncated members...: one line
            raise DataError(f"{path}: not a readable NPZ file of numeric arrays ({type(err).__name__})") from None
    if path.suffix.lower() == ".csv":
        with open(path) as fh:
            header = fh.readline().strip().split(",")
            if not any(line.strip() for line in fh):
                raise DataError(f"{path}: no data rows (the file is empty or has only a header)")
        header = [h.strip() for h in header]
        try:
            arr = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
        except (ValueError, UnicodeDecodeError) as err:
            raise DataError(f"{path}: cannot parse CSV numbers ({str(err).splitlines()[0][:120]})") from None
        if arr.shape[1] != len(header):
            raise DataError(f"{path}: header has {len(header)} columns but rows have {arr.shape[1]}")
        return {h: arr[:, i] for i, h in enumerate(header)}
    raise DataError(f"{path}: unsupported file type {path.suffix!r}; use .npz or .csv")


def _poses_from(tab: dict, scale: float, path: Path):
    if "poses" in tab:
        P = np.asarray(tab["poses"], float)
        if P.ndim != 3 or P.shape[1:] != (4, 4):
            raise DataError(f"{path}: 'poses' must have shape (N, 4, 4), got {P.shape}")
        P = P.copy()
        P[:, :3, 3] *= scale
        return P
    if all(c in tab for c in POSE_COLS):
        N = len(tab["px"])
        P = np.tile(np.eye(4), (N, 1, 1))
        for k, c in enumerate(POSE_COLS[:9]):
            P[:, k // 3, k % 3] = tab[c]
        P[:, :3, 3] = np.column_stack([tab["px"], tab["py"], tab["pz"]]) * scale
        return P
    q = tab.get("q")
    if q is None and all(f"q{i}" in tab for i in range(1, 7)):
        q = np.column_stack([tab[f"q{i}"] for i in range(1, 7)])
    if q is not None:
        q = np.atleast_2d(np.asarray(q, float))
        if q.shape[1] != 6:
            raise DataError(f"{path}: joint angles must have 6 columns (IRB 140), got {q.shape[1]}")
        from drake_est.robots import irb140

        return irb140().forward_kinematics_batch(q)
    raise DataError(f"{path}: no poses found; give 'poses' (N,4,4), columns r11..r33,px,py,pz, or q1..q6")


def _hist(residuals, xlabel, path, title):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    r = np.asarray(residuals).ravel()
    r = r[np.isfinite(r)]
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.hist(r, bins=60, color="C0", alpha=0.8)
    ax.set_xlabel(xlabel)
    ax.set_ylabel("count")
    ax.set_title(title)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def _parse_T0(text):
    from drake_est.calibration.so3 import make_pose, rpy_to_matrix

    try:
        vals = [float(v) for v in text.replace(",", " ").split()]
    except ValueError:
        raise DataError(f"--T0 needs 6 numbers 'x y z roll pitch yaw' [m, deg], got '{text}'") from None
    if len(vals) != 6:
        raise DataError(f"--T0 needs 6 numbers 'x y z roll pitch yaw' [m, deg], got {len(vals)}")
    if not np.all(np.isfinite(vals)):
        raise DataError(f"--T0 must hold 6 finite numbers, got '{text}'")
    return make_pose(rpy_to_matrix(np.radians(vals[3:])), vals[:3])


def run(args) -> int:
    from drake_est.calibration import calibrate_ft, calibrate_laser

    path = Path(args.data)
    if not path.exists():
        raise DataError(f"data file not found: {path}")
    if path.is_dir():
        raise DataError(f"{path} is a folder, expected a .npz or .csv data file")
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise DataError(f"--out {args.out} exists and is not a folder")
    for name, val, lo in (("--iters", args.iters, 1), ("--min-planes", args.min_planes, 1)):
        if val < lo:
            raise DataError(f"{name} must be >= {lo}, got {val}")
    from drake_est.cli._common import check_number

    for name, val, hi in (("--length-scale", args.length_scale, 1e6), ("--assign-threshold", args.assign_threshold, 10.0),
                          ("--mass", args.mass, 1e4)):
        check_number(name, val, 0, hi, lo_strict=True)
    tab = _read_table(path)
    scale = args.length_scale
    np.set_printoptions(precision=5, suppress=True)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        if args.sensor == "ft":
            P = _poses_from(tab, scale, path)
            if "wrench" in tab:
                W = np.asarray(tab["wrench"], float)
            elif "force" in tab:
                W = np.column_stack([tab["force"], tab["torque"]]) if "torque" in tab else np.asarray(tab["force"])
            elif all(c in tab for c in ("fx", "fy", "fz")):
                cols = ["fx", "fy", "fz"] + (["tx", "ty", "tz"] if all(c in tab for c in ("tx", "ty", "tz")) else [])
                W = np.column_stack([tab[c] for c in cols])
            else:
                raise DataError(f"{path}: no wrench found; give 'wrench' (N,6) or columns fx,fy,fz[,tx,ty,tz]")
            W = np.asarray(W, float).copy()
            if W.ndim != 2 or W.shape[1] not in (3, 6):
                raise DataError(f"{path}: the wrench must have shape (N, 6) [fx fy fz tx ty tz] or (N, 3), "
                                f"got {W.shape}")
            if W.shape[1] == 6:
                W[:, 3:] *= scale
            res = calibrate_ft(P, W, method=args.method or "relaxation", bias=not args.no_bias, mass=args.mass)
            summ = res.summary()
            print(f"F/T calibration ({res.method}) on {len(P)} poses")
            print("R_S^TF (flange -> sensor):\n" + str(res.R))
            print(f"mass {res.mass:.5g} kg, centre of mass (sensor frame) {res.com} m")
            print(f"force offset {res.force_bias} N, torque offset {res.torque_bias} N m")
            print(f"residual RMS: force {summ['residual_rms_force_N']:.4g} N (before: {summ['before_rms_force_N']:.4g}),"
                  f" torque {summ['residual_rms_torque_Nm']:.4g} N m (before: {summ['before_rms_torque_Nm']:.4g})")
            print(f"condition number of the gravity directions: {res.condition:.3g}")
            _hist(res.residuals[:, :3], "force residual [N]", out / "ft_residual_histogram.png",
                  "F/T calibration residuals (cf. Fig. 13.8)")
        else:
            P = _poses_from(tab, scale, path)
            if "points" in tab:
                pts = np.asarray(tab["points"], float) * scale
                idx = np.asarray(tab.get("pose_index", np.arange(len(pts))))
                if not np.issubdtype(idx.dtype, np.integer):
                    if not np.all(idx == np.round(idx)):
                        raise DataError(f"{path}: pose_index must hold integers")
                    idx = idx.astype(int)
            elif all(c in tab for c in ("x", "y")):
                pts = np.column_stack([tab["x"], tab["y"], tab.get("z", np.zeros(len(tab["x"])))]) * scale
                # consecutive rows with the same pose form one scan
                flat = P.reshape(len(P), -1)
                change = np.r_[True, np.any(np.diff(flat, axis=0) != 0, axis=1)]
                idx = np.cumsum(change) - 1
                P = P[change]
            else:
                raise DataError(f"{path}: no laser points found; give 'points' (N,3) + 'pose_index' or columns x,y[,z]")
            labels = tab.get("plane")
            if labels is not None:
                try:
                    labels = np.asarray(labels).astype(int)
                except (TypeError, ValueError):
                    raise DataError(f"{path}: plane labels ('plane') must be integers") from None
            T0 = _parse_T0(args.T0) if args.T0 else (np.asarray(tab["T0"], float) if "T0" in tab else None)
            if T0 is not None and args.T0 is None:
                if T0.shape != (4, 4) or not np.all(np.isfinite(T0)):
                    raise DataError(f"{path}: 'T0' must be a finite 4x4 transform, got shape {T0.shape}")
                T0 = T0.copy()
                T0[:3, 3] *= scale
            res = calibrate_laser(P, pts, idx, labels=labels, T0=T0, n_iter=args.iters, method=args.method or "ls",
                                  refine=args.refine, min_planes=args.min_planes,
                                  assign_threshold=args.assign_threshold)
            summ = res.summary()
            summ["rms_before_m"] = float(res.history_rms[0])
            print(f"laser calibration ({res.kind} scanner) on {len(pts)} points from {len(P)} poses, "
                  f"{len(res.planes)} planes, {res.iterations} iterations")
            print("T_TF^S (sensor in flange):\n" + str(res.T))
            r = res.residuals[np.isfinite(res.residuals)]
            print(f"point-to-plane RMS {res.rms * 1e3:.4g} mm (initial guess: {res.history_rms[0] * 1e3:.4g} mm), "
                  f"median |r| {np.median(np.abs(r)) * 1e3:.4g} mm, max |r| {np.abs(r).max() * 1e3:.4g} mm")
            if res.n_excluded:
                print(f"excluded {res.n_excluded} points (NaN or not assigned to a plane)")
            print(f"condition number {res.condition:.3g} (weakest parameter {res.weak_parameter})")
            if not res.rms < res.history_rms[0]:
                warnings.warn(f"calibration did not improve on the initial guess (RMS {res.rms * 1e3:.4g} mm vs "
                              f"{res.history_rms[0] * 1e3:.4g} mm): the result is not trustworthy"
                              + ("; the automatic plane assignment may have failed, give plane labels "
                                 "(column/array 'plane')" if labels is None else "; try a better --T0"))
            if res.condition > 1e4:
                warnings.warn(f"poses excite the sensor transform poorly (condition number {res.condition:.3g}); "
                              f"weakest parameter {res.weak_parameter}: add poses that change it")
            _hist(res.residuals * 1e3, "point-to-plane residual [mm]", out / "laser_residual_histogram.png",
                  "Laser calibration residuals (Fig. 13.8)")
    for w in caught:
        print(f"warning: {w.message}")
    summ["warnings"] = [str(w.message) for w in caught]
    out.mkdir(parents=True, exist_ok=True)
    from drake_est.jsonutil import dump_json

    dump_json(summ, out / f"calibrate_{args.sensor}.json")
    print(f"wrote {out}/calibrate_{args.sensor}.json and a residual histogram")
    return 0
