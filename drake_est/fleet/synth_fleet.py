"""A synthetic fleet of robots logging every day, with planted slow changes (truth kept apart).

Layout written by :func:`synth_fleet`::

    OUT/robot_017/2026-05-12.npz      one log per robot and day (drake_est log format)
    OUT/manifest.csv                  robot_id, joints, time, path, robot_model (one row per log)
    TRUTH (default OUT.truth.json)    what was planted where (never read by the diagnosis)

Robots are ``generic`` axes (fast numpy generator, :func:`axis_log`: rigid axis J qdd plus
Coulomb/viscous friction (9.2) and, when planted, a motor-position ripple, swept at
piecewise-constant velocities as in Sec. 9.6) or ``irb140`` (simulated once per robot and
condition in Drake by :func:`drake_est.synth.synthesize`; the daily logs are that simulation with
fresh torque noise and the day's extra Coulomb friction, so an IRB 140 fleet stays cheap).

Planted changes (one each by default, on distinct robots; all other robots are healthy):

* ``coulomb_wear``: the Coulomb level of one joint grows linearly from an onset day;
* ``gearbox_ripple``: a motor-position ripple appears on one joint at an onset day and grows 3x;
* ``payload``: an unmodeled payload is mounted on one IRB 140 on a given day;
* a few corrupt logs (truncated file, NaN torques, shuffled time stamps).
"""
from __future__ import annotations

import csv
import datetime as _dt
import json
from pathlib import Path

import numpy as np

from drake_est.errors import DataError

START_DATE = "2026-05-01"
SAMPLE_RATE = 100.0


def _day(start: str, d: int) -> str:
    return (_dt.date.fromisoformat(start) + _dt.timedelta(days=int(d))).isoformat()


def axis_trajectory(rng, duration, sample_rate=SAMPLE_RATE, lo=-1.2, hi=1.2, vmax=1.5, acc=6.0):
    """Piecewise-constant-velocity sweeps between ``lo`` and ``hi`` (Sec. 9.6), with acceleration-
    limited ramps.  The passes cycle through the speeds [0.2, 1] vmax in a random order, so every
    log holds several distinct speeds (with one speed only, v and sign(v) would be collinear and
    the Coulomb and viscous levels not separable).  Returns t, q, v, a."""
    dt = 1.0 / sample_rate
    t = np.arange(0.0, duration, dt)
    q = np.empty_like(t)
    v = np.empty_like(t)
    levels = vmax * rng.permutation(np.linspace(0.2, 1.0, 6))
    qk = rng.uniform(lo + 0.2 * (hi - lo), hi - 0.2 * (hi - lo))
    vk = 0.0
    direction = 1.0 if rng.random() < 0.5 else -1.0
    n_pass = 0
    cmd = levels[0]
    for k in range(len(t)):
        target = direction * cmd
        v_new = vk + np.clip(target - vk, -acc * dt, acc * dt)
        qk += 0.5 * (vk + v_new) * dt
        vk = v_new
        if (direction > 0 and qk >= hi) or (direction < 0 and qk <= lo):
            direction = -direction
            n_pass += 1
            cmd = levels[n_pass % len(levels)]
        q[k], v[k] = qk, vk
    a = np.gradient(v, dt)
    return t, q, v, a


def axis_log(rng, duration, axes, noise_std=0.05, sample_rate=SAMPLE_RATE):
    """A log of independent generic axes.  ``axes``: list of dicts with J [kg m^2], kc [N m],
    kv [N m s/rad], gear (motor turns per arm turn), and optional ripple ``(amp [N m], harmonic,
    phase)``: tau = J a + kv v + kc tanh(v/eps) + amp/(1+|v|) sin(h mod(gear q, 2 pi) + phase) + noise.
    Returns the columns dict (t, q<j>, tau<j>) with encoder-quantized positions."""
    cols = {}
    for i, ax in enumerate(axes, start=1):
        t, q, v, a = axis_trajectory(rng, duration, sample_rate)
        tau = ax["J"] * a + ax["kv"] * v + ax["kc"] * np.tanh(v / 2e-3)
        if ax.get("ripple"):
            amp, h, ph = ax["ripple"]
            tau = tau + amp / (1.0 + np.abs(v)) * np.sin(h * np.mod(ax["gear"] * q, 2 * np.pi) + ph)
        tau = tau + noise_std * rng.standard_normal(t.shape)
        step = 2 * np.pi / (4096 * ax["gear"])
        cols["t"] = t
        cols[f"q{i}"] = np.round(q / step) * step
        cols[f"tau{i}"] = tau
    return cols


def _save_cols(cols, path, meta):
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(path, meta_json=np.array(json.dumps(meta)), **cols)


def _corrupt(path: Path, kind: str, rng):
    """Damage a written log in one of three ways (for the fault tests and the fleet demo)."""
    if kind == "truncated":
        data = path.read_bytes()
        path.write_bytes(data[: len(data) // 3])
    elif kind == "nan_torque":
        with np.load(path) as z:
            d = {k: z[k] for k in z.files}
        tau = d["tau1"].copy()
        tau[rng.integers(0, len(tau), 5)] = np.nan
        d["tau1"] = tau
        np.savez_compressed(path, **d)
    elif kind == "time_reversed":
        with np.load(path) as z:
            d = {k: z[k] for k in z.files}
        d["t"] = d["t"][::-1].copy()
        np.savez_compressed(path, **d)
    else:  # pragma: no cover
        raise ValueError(kind)


def plan_fleet(robots: int, days: int, seed: int = 0, n_irb140: int | None = None, generic_axes: int = 2,
               start: str = START_DATE, n_corrupt: int | None = None) -> dict:
    """Choose robots, their friction and the planted changes (no logs written).  Returns the truth."""
    if robots < 3:
        raise DataError(f"--robots must be at least 3 (one per planted change), got {robots}")
    if days < 8:
        raise DataError(f"--days must be at least 8 (a change needs days before and after), got {days}")
    rng = np.random.default_rng([seed, 1])
    n_irb = max(1, robots // 25) if n_irb140 is None else int(n_irb140)
    ids = [f"robot_{k:03d}" for k in range(1, robots + 1)]
    irb = set(ids[-n_irb:]) if n_irb else set()
    rob = {}
    for k, rid in enumerate(ids):
        if rid in irb:
            rob[rid] = {"model": "irb140", "joints": [1], "sim_seed": int(rng.integers(1 << 30))}
        else:
            axes = []
            for _ in range(generic_axes):
                axes.append({"J": float(rng.uniform(0.2, 1.0)), "kc": float(rng.uniform(2.0, 6.0)),
                             "kv": float(rng.uniform(1.0, 4.0)), "gear": float(rng.choice([50.0, 80.0, 100.0, 121.0]))})
            rob[rid] = {"model": "generic", "joints": list(range(1, generic_axes + 1)), "axes": axes}
    generic_ids = [r for r in ids if rob[r]["model"] == "generic"]
    pick = rng.permutation(len(generic_ids))
    changes = []
    lo_day, hi_day = max(3, days // 4), max(4, days - max(5, days // 4))

    r1 = generic_ids[pick[0]]
    j1 = int(rng.integers(1, generic_axes + 1))
    d1 = int(rng.integers(lo_day, hi_day + 1))
    rate = float(rng.uniform(0.04, 0.06))  # relative Coulomb growth per day
    changes.append({"robot": r1, "joint": j1, "cause": "coulomb_wear", "onset_day": d1, "date": _day(start, d1),
                    "growth_per_day": rate, "kc_before": rob[r1]["axes"][j1 - 1]["kc"]})
    r2 = generic_ids[pick[1]]
    j2 = int(rng.integers(1, generic_axes + 1))
    d2 = int(rng.integers(lo_day, hi_day + 1))
    ax = rob[r2]["axes"][j2 - 1]
    h = int(rng.integers(1, 3))
    changes.append({"robot": r2, "joint": j2, "cause": "motor_position_ripple", "onset_day": d2,
                    "date": _day(start, d2), "amplitude_at_onset": 0.3 * ax["kc"],
                    "amplitude_at_end": 0.9 * ax["kc"], "harmonic_per_motor_rev": h, "gear_ratio": ax["gear"],
                    "frequency_per_arm_rev": h * ax["gear"], "phase": float(rng.uniform(0, 2 * np.pi))})
    if irb:
        r3 = sorted(irb)[0]
        d3 = int(rng.integers(lo_day, hi_day + 1))
        changes.append({"robot": r3, "joint": None, "cause": "payload", "onset_day": d3, "date": _day(start, d3),
                        "joints_moving": [2, 3]})
        rob[r3]["joints"] = [2, 3]
    n_corrupt = max(2, robots * days // 300) if n_corrupt is None else int(n_corrupt)
    kinds = ("truncated", "nan_torque", "time_reversed")
    corrupt = []
    pool = pick[2:] if len(pick) > 2 else pick       # healthy generic robots; the planted ones when none
    for c in range(n_corrupt):
        corrupt.append({"robot": generic_ids[pool[c % len(pool)]],
                        "day": int(rng.integers(0, days)), "kind": kinds[c % 3]})
    return {"seed": seed, "robots": rob, "days": days, "start_date": start, "changes": changes,
            "corrupt": corrupt, "sample_rate_hz": SAMPLE_RATE}


def _irb_base(rid, info, duration, payload):
    from drake_est.synth import synthesize
    effect = "payload" if payload else "none"
    log, truth = synthesize(effect, seed=info["sim_seed"], joints=info["joints"], duration=duration + 1.0,
                            experiment="excitation" if len(info["joints"]) > 1 else "sweep", noise_std=0.0)
    return log, truth


def synth_fleet(out, robots: int = 50, days: int = 30, seed: int = 0, duration: float = 20.0, truth_path=None,
                n_irb140: int | None = None, generic_axes: int = 2, noise_std: float = 0.05,
                start: str = START_DATE, show_progress: bool = True) -> dict:
    """Write a fleet (see module doc) to ``out``; returns a summary with the truth path."""
    from drake_est.progress import progress
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    truth = plan_fleet(robots, days, seed, n_irb140=n_irb140, generic_axes=generic_axes, start=start)
    truth["duration_s"] = duration
    ch_by_robot = {}
    for c in truth["changes"]:
        ch_by_robot.setdefault(c["robot"], []).append(c)
    corrupt = {(c["robot"], c["day"]): c["kind"] for c in truth["corrupt"]}
    rows = []
    irb_cache = {}
    for rid, info in truth["robots"].items():
        (out / rid).mkdir(parents=True, exist_ok=True)
        (out / rid / "robot.json").write_text(json.dumps({"model": info["model"], "joints": info["joints"]}))
    items = [(rid, d) for rid in truth["robots"] for d in range(days)]
    bar = progress(items, desc="synth-fleet logs", total=len(items)) if show_progress else items
    for rid, d in bar:
        info = truth["robots"][rid]
        rng = np.random.default_rng([seed, int(rid.split("_")[1]), d])
        date = _day(start, d)
        path = out / rid / f"{date}.npz"
        meta = {"robot_id": rid, "time": date, "robot": info["model"], "source": "drake_est.fleet.synth_fleet"}
        if info["model"] == "generic":
            axes = [dict(a) for a in info["axes"]]
            for c in ch_by_robot.get(rid, []):
                if d < c["onset_day"]:
                    continue
                ax = axes[c["joint"] - 1]
                if c["cause"] == "coulomb_wear":
                    ax["kc"] = ax["kc"] * (1.0 + c["growth_per_day"] * (d - c["onset_day"]))
                elif c["cause"] == "motor_position_ripple":
                    frac = (d - c["onset_day"]) / max(1, days - 1 - c["onset_day"])
                    amp = c["amplitude_at_onset"] + frac * (c["amplitude_at_end"] - c["amplitude_at_onset"])
                    ax["ripple"] = (amp, c["harmonic_per_motor_rev"], c["phase"])
            cols = axis_log(rng, duration, axes, noise_std=noise_std)
        else:
            payload = any(c["cause"] == "payload" and d >= c["onset_day"] for c in ch_by_robot.get(rid, []))
            if (rid, payload) not in irb_cache:
                irb_cache[(rid, payload)] = _irb_base(rid, info, duration, payload)
            base, bt = irb_cache[(rid, payload)]
            cols = {"t": base.t.copy()}
            for c, j in enumerate(base.joints):
                cols[f"q{j}"] = base.q[:, c]
                cols[f"tau{j}"] = base.tau[:, c] + 0.3 * rng.standard_normal(base.t.shape)
            if payload:
                c0 = [c for c in ch_by_robot[rid] if c["cause"] == "payload"][0]
                c0["mass_kg"] = float(bt["effect_parameters"]["payload"]["mass"])
        _save_cols(cols, path, meta)
        if (rid, d) in corrupt:
            _corrupt(path, corrupt[(rid, d)], rng)
        rows.append({"robot_id": rid, "joints": ",".join(str(j) for j in info["joints"]), "time": date,
                     "path": str(path.relative_to(out)), "robot_model": info["model"]})
    with open(out / "manifest.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=["robot_id", "joints", "time", "path", "robot_model"])
        w.writeheader()
        w.writerows(rows)
    truth_path = Path(truth_path) if truth_path else out.with_name(out.name + ".truth.json")
    from drake_est.jsonutil import dump_json
    dump_json(truth, truth_path)
    return {"out": str(out), "manifest": str(out / "manifest.csv"), "truth": str(truth_path), "logs": len(rows),
            "robots": robots, "days": days, "planted": len(truth["changes"]), "corrupt": len(truth["corrupt"])}
