"""The measured-data format: a :class:`Log` of time, joint positions, velocities,
accelerations, torques and any other named channel, loaded from / saved to CSV
or NPZ with checks that name what is wrong.

CSV layout (one header line, comma separated, SI units)::

    t, q1, ..., qN, [dq1..dqN], [ddq1..ddqN], [tau1..tauN], [any other channel, e.g. fx, temp]

* ``t`` in seconds, strictly increasing.
* ``q<j>`` joint positions [rad or m], ``dq<j>`` [rad/s], ``ddq<j>`` [rad/s^2],
  ``tau<j>`` joint (arm-side) torque [N m] or force [N]; ``<j>`` is the 1-based joint
  number, so a log of joints 1 and 3 has ``q1, q3, tau1, tau3``.
* NPZ layout: arrays with the same names (``t``, ``q1``, ...), plus optional ``meta_json``.

Derivatives that are absent are computed by :func:`smooth_derivatives`, a
Savitzky-Golay differentiator (local cubic least-squares fits) over a window of
``window_s`` seconds (default 0.04 s, at least 7 samples); non-uniformly sampled
logs are first interpolated to a uniform grid at the median sample interval,
differentiated there, and interpolated back.
"""
from __future__ import annotations

import csv
import json
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy.signal

from drake_est.errors import DataError

_QCOL = re.compile(r"^(q|dq|ddq|tau)(\d+)$")
MIN_SAMPLES = 20
# plausibility: magnitudes no machine produces (|value| above these, or a column scaled to ~0)
MAX_ABS = {"q": 1e4, "dq": 1e5, "ddq": 1e7, "tau": 1e7}
MAX_ABS_CHANNEL = 1e12
MIN_DT, MAX_DURATION = 1e-6, 1e6       # [s]: 1 MHz sampling, 11.6 days
MAX_GAP_FACTOR = 1000.0                 # a gap longer than this many median steps (and > 1 s) is refused
MAX_FIELD = 1 << 16                     # a CSV field longer than this is not a number


@dataclass
class Log:
    """A measured (or synthetic) experiment log.

    Attributes
    ----------
    t : (N,) time [s], strictly increasing.
    q : (N, n) joint positions [rad] (or [m] for prismatic axes).
    dq, ddq : (N, n) velocities and accelerations (computed when absent).
    tau : (N, n) joint torques [N m] (or forces [N]) or None.
    joints : 1-based joint numbers of the columns of q.
    channels : other named channels, each (N,).
    meta : free-form metadata (source file, units, excluded rows, derivative method...).
    """

    t: np.ndarray
    q: np.ndarray
    dq: np.ndarray | None = None
    ddq: np.ndarray | None = None
    tau: np.ndarray | None = None
    joints: list = field(default_factory=list)
    channels: dict = field(default_factory=dict)
    meta: dict = field(default_factory=dict)

    def __post_init__(self):
        self.t = np.asarray(self.t, dtype=float).ravel()
        self.q = _as_2d(self.q, "q")
        n = self.q.shape[1]
        if not self.joints:
            self.joints = list(range(1, n + 1))
        if len(self.joints) != n:
            raise DataError(f"{len(self.joints)} joint numbers given for {n} position columns")
        for name in ("dq", "ddq", "tau"):
            val = getattr(self, name)
            if val is not None:
                val = _as_2d(val, name)
                if val.shape != self.q.shape:
                    raise DataError(f"{name} has shape {val.shape}, q has {self.q.shape}")
                setattr(self, name, val)
        if self.q.shape[0] != self.t.shape[0]:
            raise DataError(f"t has {self.t.shape[0]} samples, q has {self.q.shape[0]}")

    # ------------------------------------------------------------------ basics
    @property
    def n_samples(self) -> int:
        return int(self.t.shape[0])

    @property
    def n_joints(self) -> int:
        return int(self.q.shape[1])

    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0]) if self.n_samples else 0.0

    @property
    def sample_rate(self) -> float:
        """Median sample rate [Hz]."""
        return float(1.0 / np.median(np.diff(self.t)))

    def col(self, joint: int) -> int:
        """Column index of a 1-based joint number."""
        try:
            return self.joints.index(int(joint))
        except ValueError:
            raise DataError(f"joint {joint} is not in the log (joints: {self.joints})") from None

    def column(self, name: str) -> np.ndarray:
        """A channel by its CSV name (``t``, ``q2``, ``tau1``, ``fx``, ...)."""
        if name == "t":
            return self.t
        m = _QCOL.match(name)
        if m:
            arr = getattr(self, m.group(1))
            if arr is None:
                raise DataError(f"column '{name}' is not in the log")
            return arr[:, self.col(int(m.group(2)))]
        if name in self.channels:
            return self.channels[name]
        raise DataError(f"column '{name}' is not in the log (have: {', '.join(self.column_names())})")

    def column_names(self) -> list:
        names = ["t"]
        for prefix in ("q", "dq", "ddq", "tau"):
            if getattr(self, prefix) is not None:
                names += [f"{prefix}{j}" for j in self.joints]
        return names + list(self.channels)

    def select(self, mask) -> "Log":
        """A new log with the rows where ``mask`` is true (or the given indices)."""
        idx = np.asarray(mask)
        pick = (lambda a: None if a is None else a[idx])
        return Log(t=self.t[idx], q=self.q[idx], dq=pick(self.dq), ddq=pick(self.ddq), tau=pick(self.tau),
                   joints=list(self.joints), channels={k: v[idx] for k, v in self.channels.items()},
                   meta=dict(self.meta))

    def time_slice(self, t0: float, t1: float) -> "Log":
        return self.select((self.t >= t0) & (self.t < t1))

    def with_derivatives(self, window_s: float | None = None) -> "Log":
        """Fill in dq / ddq (if absent) with :func:`smooth_derivatives`."""
        if self.dq is not None and self.ddq is not None:
            return self
        dq, ddq, info = smooth_derivatives(self.t, self.q, window_s=window_s)
        meta = dict(self.meta)
        meta["derivatives"] = info
        return Log(t=self.t, q=self.q, dq=self.dq if self.dq is not None else dq,
                   ddq=self.ddq if self.ddq is not None else ddq, tau=self.tau, joints=list(self.joints),
                   channels=dict(self.channels), meta=meta)

    def to_columns(self) -> dict:
        cols = {"t": self.t}
        for prefix in ("q", "dq", "ddq", "tau"):
            arr = getattr(self, prefix)
            if arr is not None:
                for i, j in enumerate(self.joints):
                    cols[f"{prefix}{j}"] = arr[:, i]
        cols.update(self.channels)
        return cols


def _as_2d(a, name):
    a = np.asarray(a, dtype=float)
    if a.ndim == 1:
        a = a[:, None]
    if a.ndim != 2:
        raise DataError(f"{name} must be (N,) or (N, n), got shape {a.shape}")
    return a


# ---------------------------------------------------------------- derivatives


def smooth_derivatives(t, q, window_s: float | None = None, polyorder: int = 3, min_window: int = 7):
    """Smoothed first and second derivatives of ``q`` (N, n) sampled at ``t``.

    Savitzky-Golay differentiation (local least-squares polynomial of order
    ``polyorder``) over ``window_s`` seconds (default 0.04 s, at least
    ``min_window`` samples, odd).  Non-uniform sampling (jitter > 1 % of the
    median interval) is handled by interpolating to a uniform grid first.
    Returns ``(dq, ddq, info)`` with ``info`` describing the method used."""
    t = np.asarray(t, dtype=float)
    q = _as_2d(q, "q")
    n = len(t)
    if n < 2 or len(q) != n:
        raise DataError(f"smooth_derivatives: t has {n} samples and q {len(q)}; need equal lengths >= 2")
    dts = np.diff(t)
    h = float(np.median(dts))
    if not (np.isfinite(h) and h > 0):
        raise DataError("smooth_derivatives: time stamps must be finite and strictly increasing")
    if window_s is None:
        window_s = 0.04
    if not (isinstance(window_s, (int, float, np.floating, np.integer)) and np.isfinite(window_s)
            and window_s > 0):
        raise DataError(f"window_s must be a finite number of seconds > 0, got {window_s!r}")
    w = int(round(window_s / h))
    w = max(w, min_window)
    if w % 2 == 0:
        w += 1
    if w > n:
        w = n if n % 2 == 1 else n - 1
    if w <= polyorder:
        raise DataError(f"too few samples ({n}) to differentiate positions (need more than {polyorder + 1})")
    uniform = np.max(np.abs(dts - h)) <= 0.01 * h
    if uniform:
        dq = scipy.signal.savgol_filter(q, w, polyorder, deriv=1, delta=h, axis=0, mode="interp")
        ddq = scipy.signal.savgol_filter(q, w, polyorder, deriv=2, delta=h, axis=0, mode="interp")
    else:
        n_grid = (t[-1] - t[0]) / h + 1
        if not n_grid <= 10 * n + 1000:   # bounded memory: a gap would blow up the uniform grid
            i = int(np.argmax(dts))
            raise DataError(f"time stamps have a gap of {dts[i]:.3g} s after data row {i + 1} (median step "
                            f"{h:.3g} s); split the log at the gap")
        tu = np.arange(t[0], t[-1] + 0.5 * h, h)
        qu = np.column_stack([np.interp(tu, t, q[:, i]) for i in range(q.shape[1])])
        dqu = scipy.signal.savgol_filter(qu, w, polyorder, deriv=1, delta=h, axis=0, mode="interp")
        ddqu = scipy.signal.savgol_filter(qu, w, polyorder, deriv=2, delta=h, axis=0, mode="interp")
        dq = np.column_stack([np.interp(t, tu, dqu[:, i]) for i in range(q.shape[1])])
        ddq = np.column_stack([np.interp(t, tu, ddqu[:, i]) for i in range(q.shape[1])])
    info = {"method": "savitzky-golay", "window_samples": int(w), "window_s": float(w * h), "polyorder": polyorder,
            "resampled": (not uniform)}
    return dq, ddq, info


# ----------------------------------------------------------------- loading


def _read_csv(path: Path):
    with open(path, newline="", encoding="utf-8-sig") as f:  # utf-8-sig: tolerate Excel's byte-order mark
        # leading '# ...' lines are comments (before the header)
        lines = (ln for ln in f if not ln.lstrip().startswith("#"))
        reader = csv.reader(lines)
        try:
            return _read_csv_rows(path, reader)
        except csv.Error as err:
            raise DataError(f"{path}: not a valid CSV near line {reader.line_num} ({err})") from None
        except UnicodeDecodeError:
            raise DataError(f"{path}: not a text CSV (binary or not UTF-8) near line {reader.line_num + 1}; "
                            "expected a UTF-8 CSV with a header, or an NPZ") from None


def _read_csv_rows(path: Path, reader):
    try:
        header = next(reader)
    except StopIteration:
        raise DataError(f"{path}: file is empty (or holds only '#' comment lines)") from None
    header = [h.strip() for h in header]
    if len(header) == 1:
        for sep, name in ((";", "semicolons"), ("\t", "tabs"), (" ", "spaces")):
            if sep in header[0]:
                raise DataError(f"{path}: the header is separated by {name}; the format wants commas "
                                f"(t,q1,tau1,...)")
    if not any(header):
        raise DataError(f"{path}: first line must be a header naming the columns (t, q1, tau1, ...)")
    dup = sorted({h for h in header if header.count(h) > 1})
    if dup:
        raise DataError(f"{path}: duplicated column name(s): {', '.join(dup)}")
    rows = []
    for lineno, row in enumerate(reader, start=2):
        if not row or all(not c.strip() for c in row):
            continue
        if len(row) != len(header):
            raise DataError(f"{path}: line {lineno} has {len(row)} fields, header has {len(header)}")
        if any(len(c) > MAX_FIELD for c in row):
            raise DataError(f"{path}: line {lineno} has a field longer than {MAX_FIELD} characters; "
                            "not a number (damaged file?)")
        rows.append(row)
    if not rows:
        raise DataError(f"{path}: no data rows after the header")
    try:
        data = np.array(rows, dtype=float)
    except ValueError:
        for lineno, row in enumerate(rows, start=2):
            for name, cell in zip(header, row):
                try:
                    float(cell)
                except ValueError:
                    raise DataError(f"{path}: column '{name}' has a non-numeric value {cell.strip()!r} "
                                    f"(data row {lineno - 1})") from None
        raise
    return {h: data[:, i] for i, h in enumerate(header)}


def _read_npz(path: Path):
    try:
        z = np.load(path, allow_pickle=False)
    except Exception as err:  # noqa: BLE001 - any unreadable file becomes a one-line DataError
        raise DataError(f"{path}: not a readable NPZ file ({err.__class__.__name__})") from None
    if not hasattr(z, "files"):
        raise DataError(f"{path}: a single .npy array, not an NPZ archive of named columns (t, q1, tau1, ...)")
    with z:
        return _read_npz_members(path, z)


def _read_npz_members(path: Path, z):
    cols, meta = {}, {}
    for k in z.files:
        try:
            val = z[k]
        except ValueError as err:
            if "pickle" in str(err).lower() or "object" in str(err).lower():
                raise DataError(f"{path}: array '{k}' holds Python objects; save plain numeric arrays") from None
            raise DataError(f"{path}: array '{k}' is damaged ({err.__class__.__name__})") from None
        except Exception as err:  # noqa: BLE001 - corrupt/truncated member, unsupported compression
            raise DataError(f"{path}: array '{k}' is damaged or truncated ({err.__class__.__name__})") from None
        if k == "meta_json":
            try:
                meta = json.loads(str(val))
            except ValueError:
                raise DataError(f"{path}: 'meta_json' is not valid JSON") from None
            if not isinstance(meta, dict):
                raise DataError(f"{path}: 'meta_json' must be a JSON object, got a {type(meta).__name__}")
            continue
        arr = np.asarray(val)
        if arr.dtype.kind not in "fiub":
            raise DataError(f"{path}: array '{k}' is not numeric (dtype {arr.dtype})")
        if arr.ndim != 1:
            raise DataError(f"{path}: array '{k}' must be 1-D (one channel), got shape {arr.shape}")
        cols[k] = arr.astype(float)
    lens = {k: len(v) for k, v in cols.items()}
    if len(set(lens.values())) > 1:
        raise DataError(f"{path}: arrays have different lengths: {lens}")
    return cols, meta


def load_log(path, require_tau: bool = True, derivatives: bool = True, limits=None, nan_policy: str = "raise",
             min_samples: int = MIN_SAMPLES, window_s: float | None = None) -> Log:
    """Load a CSV or NPZ log and check it.

    Parameters
    ----------
    require_tau : a ``tau<j>`` column is required for every ``q<j>``.
    derivatives : compute ``dq``/``ddq`` when absent (:func:`smooth_derivatives`).
    limits : optional ``{joint: (lo, hi)}`` position limits [rad]; positions beyond a limit by
        more than 0.5 rad (or 10 % of the range) are refused (degrees instead of radians?).
    nan_policy : ``"raise"`` (default) refuses NaN/inf with their count and location;
        ``"drop"`` removes those rows and records the count in ``meta["excluded_rows"]``.
    """
    path = Path(path)
    if not path.exists():
        raise DataError(f"file not found: {path}")
    if path.is_dir():
        raise DataError(f"{path} is a folder, expected a .csv or .npz log")
    if not path.is_file():
        raise DataError(f"{path} is not a regular file (a pipe or device?); save the log to a file first")
    suffix = path.suffix.lower()
    meta = {"file": str(path)}
    if suffix == ".npz":
        cols, m2 = _read_npz(path)
        meta.update(m2)
    elif suffix in (".csv", ".txt"):
        cols = _read_csv(path)
    else:
        raise DataError(f"{path}: unknown log format '{suffix}' (use .csv or .npz)")
    return log_from_columns(cols, source=str(path), meta=meta, require_tau=require_tau, derivatives=derivatives,
                            limits=limits, nan_policy=nan_policy, min_samples=min_samples, window_s=window_s)


def log_from_columns(cols: dict, source: str = "<arrays>", meta=None, require_tau: bool = True,
                     derivatives: bool = True, limits=None, nan_policy: str = "raise",
                     min_samples: int = MIN_SAMPLES, window_s: float | None = None) -> Log:
    """Build and check a :class:`Log` from named 1-D columns (see module doc)."""
    meta = dict(meta or {})
    if "t" not in cols:
        raise DataError(f"{source}: missing time column 't' (have: {', '.join(cols)})")
    groups = {"q": {}, "dq": {}, "ddq": {}, "tau": {}}
    names = {"q": {}, "dq": {}, "ddq": {}, "tau": {}}
    channels = {}
    for name, arr in cols.items():
        m = _QCOL.match(name)
        if m:
            kind, j = m.group(1), int(m.group(2))
            if j == 0:
                raise DataError(f"{source}: column '{name}' names joint 0; joints are numbered from 1 (q1, tau1, ...)")
            if j in names[kind]:
                raise DataError(f"{source}: columns '{names[kind][j]}' and '{name}' both name joint {j}; keep one")
            names[kind][j] = name
            groups[kind][j] = np.asarray(arr, dtype=float)
        elif name != "t":
            channels[name] = np.asarray(arr, dtype=float)
    if not groups["q"]:
        raise DataError(f"{source}: no joint position columns (expected q1, q2, ...; have: {', '.join(cols)})")
    joints = sorted(groups["q"])
    for kind in ("dq", "ddq", "tau"):
        extra = sorted(set(groups[kind]) - set(joints))
        if extra:
            raise DataError(f"{source}: column '{kind}{extra[0]}' has no matching position column 'q{extra[0]}'")
    if require_tau:
        missing = [f"tau{j}" for j in joints if j not in groups["tau"]]
        if missing:
            raise DataError(f"{source}: missing torque column(s) {', '.join(missing)}")
    if nan_policy not in ("raise", "drop"):
        raise DataError(f"unknown nan_policy '{nan_policy}' (use 'raise' or 'drop')")
    if window_s is not None and not (isinstance(window_s, (int, float, np.floating, np.integer))
                                     and np.isfinite(window_s) and window_s > 0):
        raise DataError(f"window_s must be a finite number of seconds > 0, got {window_s!r}")
    t = np.asarray(cols["t"], dtype=float)
    # -- NaN / inf
    allcols = {"t": t}
    for kind in groups:
        for j, a in groups[kind].items():
            allcols[f"{kind}{j}"] = a
    allcols.update(channels)
    bad_rows = np.zeros(len(t), dtype=bool)
    report = []
    for name, a in allcols.items():
        bad = ~np.isfinite(a)
        if bad.any():
            idx = np.flatnonzero(bad)
            report.append(f"'{name}': {bad.sum()} (first at data row {idx[0] + 1})")
            bad_rows |= bad
    excluded = {}
    if report:
        if nan_policy == "raise":
            raise DataError(f"{source}: NaN/inf values in {len(report)} column(s): " + "; ".join(report)
                            + " (fix the log or load with nan_policy='drop' / --drop-invalid)")
        elif nan_policy == "drop":
            excluded["nonfinite_rows"] = int(bad_rows.sum())
            keep = ~bad_rows
            t = t[keep]
            for kind in groups:
                groups[kind] = {j: a[keep] for j, a in groups[kind].items()}
            channels = {k: v[keep] for k, v in channels.items()}
        else:
            raise DataError(f"unknown nan_policy '{nan_policy}' (use 'raise' or 'drop')")
    # -- time stamps
    if len(t) < min_samples:
        raise DataError(f"{source}: too few samples ({len(t)}); at least {min_samples} are needed")
    dt = np.diff(t)
    if np.any(dt == 0):
        i = int(np.flatnonzero(dt == 0)[0])
        raise DataError(f"{source}: duplicated time stamp t = {t[i]:g} at data rows {i + 1} and {i + 2} "
                        f"({int(np.sum(dt == 0))} duplicates in all)")
    if np.any(dt < 0):
        i = int(np.flatnonzero(dt < 0)[0])
        raise DataError(f"{source}: time stamps not increasing: t = {t[i]:g} at data row {i + 1} is followed by "
                        f"t = {t[i + 1]:g} ({int(np.sum(dt < 0))} decreasing steps in all)")
    _check_time_units(t, source)
    _check_magnitudes(groups, channels, source)
    q = np.column_stack([groups["q"][j] for j in joints])
    # -- plausibility against limits
    if limits:
        for c, j in enumerate(joints):
            if j not in limits:
                continue
            lo, hi = limits[j]
            margin = max(0.5, 0.1 * (hi - lo))
            qmin, qmax = float(q[:, c].min()), float(q[:, c].max())
            if qmin < lo - margin or qmax > hi + margin:
                hint = " (looks like degrees; the format wants radians)" if max(abs(qmin), abs(qmax)) > 2 * np.pi else ""
                raise DataError(f"{source}: joint {j} position range [{qmin:.3g}, {qmax:.3g}] rad is far outside "
                                f"its limits [{lo:.3g}, {hi:.3g}] rad{hint}")

    def stack(kind):
        if not groups[kind]:
            return None
        missing = [j for j in joints if j not in groups[kind]]
        if missing:
            raise DataError(f"{source}: column '{kind}{missing[0]}' is missing while other {kind} columns exist")
        return np.column_stack([groups[kind][j] for j in joints])

    if excluded:
        meta["excluded_rows"] = excluded
    log = Log(t=t, q=q, dq=stack("dq"), ddq=stack("ddq"), tau=stack("tau"), joints=joints, channels=channels,
              meta=meta)
    if derivatives:
        log = log.with_derivatives(window_s=window_s)
    return log


def _check_time_units(t, source):
    """Refuse time stamps no robot log has: wrong units (ms, us, ns), absurd durations, huge gaps."""
    dt = np.diff(t)
    h = float(np.median(dt))
    if h < MIN_DT:
        raise DataError(f"{source}: median sample interval {h:.3g} s is implausibly short (over 1 MHz); "
                        "the time column 't' must be in seconds")
    if h >= 0.5 and np.all(t == np.round(t)):
        unit = "nanoseconds or microseconds" if h >= 1000 else "milliseconds"
        raise DataError(f"{source}: time stamps are integers with a median step of {h:.6g}; they look like "
                        f"{unit}, the time column 't' must be in seconds")
    if h >= 1000:
        raise DataError(f"{source}: median sample interval {h:.3g} s is implausibly long; the time column 't' "
                        "must be in seconds (nanoseconds or microseconds?)")
    if abs(t[0]) > 1e11 or abs(t[-1]) > 1e11:
        raise DataError(f"{source}: time stamps of magnitude {max(abs(t[0]), abs(t[-1])):.3g} s are implausible; "
                        "the time column 't' must be in seconds")
    if t[-1] - t[0] > MAX_DURATION:
        i = int(np.argmax(dt))
        raise DataError(f"{source}: the log spans {t[-1] - t[0]:.3g} s (largest step {dt[i]:.3g} s after data row "
                        f"{i + 1}); implausible time stamps, or split the log")
    i = int(np.argmax(dt))
    if dt[i] > MAX_GAP_FACTOR * h and dt[i] > 1.0:
        raise DataError(f"{source}: gap of {dt[i]:.3g} s in the time stamps after data row {i + 1} (median step "
                        f"{h:.3g} s); split the log at the gap or fix the time stamp")


def _check_magnitudes(groups, channels, source):
    """Refuse magnitudes no machine produces (e.g. a cell of 1e300) and columns scaled to ~1e-300."""
    for kind, limit in MAX_ABS.items():
        for j, a in groups[kind].items():
            _check_column(a, f"{kind}{j}", limit, source)
    for name, a in channels.items():
        _check_column(a, name, MAX_ABS_CHANNEL, source)


def _check_column(a, name, limit, source):
    if not len(a):
        return
    ab = np.abs(a)
    i = int(np.argmax(ab))
    if ab[i] > limit:
        raise DataError(f"{source}: column '{name}' holds {a[i]:.3g} at data row {i + 1}, beyond any plausible "
                        f"value (|{name}| <= {limit:.0e}); damaged cell or wrong units")
    if 0 < ab[i] < 1e-30:
        raise DataError(f"{source}: column '{name}' is scaled to ~{ab[i]:.1e} (all values below 1e-30); "
                        "wrong units or a damaged column")


def degrees_warnings(log: Log, limits=None, prismatic=()) -> list:
    """One-line warnings for joints whose positions look like degrees although no limits can tell.

    Joints with ``limits`` are judged by :func:`load_log` (refused when far outside them).  For the
    others (a generic axis, a continuous URDF joint) the only evidence is the numbers: a revolute joint
    (not in ``prismatic``, log not marked ``axis_type: prismatic``) that spans more than one revolution
    (2 pi) while staying within +-400 -- one revolution either way in degrees -- is most likely in degrees.
    A multi-turn axis in rad can look the same, so this warns instead of refusing."""
    if str(log.meta.get("axis_type", "")).lower() in ("prismatic", "linear"):
        return []
    limits = limits or {}
    out = []
    for c, j in enumerate(log.joints):
        if j in limits or j in prismatic:
            continue
        q = log.q[:, c]
        span, peak = float(np.ptp(q)), float(np.max(np.abs(q)))
        if span > 2 * np.pi and peak <= 400.0:
            out.append(f"joint {j} positions span {span:.4g} (q{j} in [{q.min():.4g}, {q.max():.4g}]): more than "
                       f"a revolution in rad but within +-400; if they are in degrees, convert them to radians "
                       f"(the format wants rad)")
    return out


def torque_unit(log: Log) -> str:
    """The unit of the logged torque column: N for linear (prismatic) axes, the log's own (e.g. A for a motor
    current) when it says so, else N m."""
    if log.meta.get("tau_unit"):
        return str(log.meta["tau_unit"])
    return "N" if str(log.meta.get("axis_type", "")).lower() in ("prismatic", "linear") else "N m"


def save_log(log: Log, path) -> Path:
    """Write a log as CSV (``.csv``) or NPZ (``.npz``) in the format read by :func:`load_log`."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    cols = log.to_columns()
    if path.suffix.lower() == ".npz":
        meta = json.dumps(log.meta, default=str)
        np.savez_compressed(path, meta_json=np.array(meta), **cols)
    elif path.suffix.lower() == ".csv":
        names = list(cols)
        data = np.column_stack([cols[n] for n in names])
        np.savetxt(path, data, delimiter=",", header=",".join(names), comments="", fmt="%.9g")
    else:
        raise DataError(f"{path}: unknown log format '{path.suffix}' (use .csv or .npz)")
    return path


def from_arrays(t, q, tau=None, dq=None, ddq=None, joints=None, channels=None, meta=None,
                derivatives: bool = False) -> Log:
    """Convenience constructor of a :class:`Log` from arrays."""
    log = Log(t=t, q=q, dq=dq, ddq=ddq, tau=tau, joints=list(joints or []), channels=dict(channels or {}),
              meta=dict(meta or {}))
    return log.with_derivatives() if derivatives else log
