"""JSON helpers shared by the CLI and reports."""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from drake_est.errors import DataError


def to_jsonable(x):
    """``json.dumps(default=...)`` hook: numpy arrays/scalars and paths to plain Python."""
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, (np.floating, np.integer)):
        return x.item()
    if isinstance(x, np.bool_):
        return bool(x)
    if isinstance(x, Path):
        return str(x)
    raise TypeError(f"not JSON serializable: {type(x).__name__}")


def find_nonfinite(obj, where: str = "") -> str | None:
    """Key path (``a.b[3]``) of the first NaN/Infinity in a JSON-able tree, or None when all are finite."""
    if isinstance(obj, (float, np.floating)):
        return None if math.isfinite(float(obj)) else (where or "<top level>")
    if isinstance(obj, np.ndarray):
        if obj.dtype.kind in "fc" and not np.all(np.isfinite(obj)):
            i = np.unravel_index(int(np.flatnonzero(~np.isfinite(obj.ravel()))[0]), obj.shape)
            return f"{where}{list(int(k) for k in i)}"
        return None if obj.dtype.kind in "fcbiu" else find_nonfinite(obj.tolist(), where)
    if isinstance(obj, dict):
        for k, v in obj.items():
            w = find_nonfinite(v, f"{where}.{k}" if where else str(k))
            if w:
                return w
        return None
    if isinstance(obj, (list, tuple)):
        for i, v in enumerate(obj):
            w = find_nonfinite(v, f"{where}[{i}]")
            if w:
                return w
    return None


def finite_or_none(x):
    """``float(x)`` when finite, else None (JSON null), for values where 'no limit'/'undefined' is meant."""
    try:
        v = float(x)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) else None


def nonfinite_to_null(obj, where: str = "", found=None):
    """Copy of a JSON-able tree with NaN/Infinity replaced by None, and the list of their key paths
    (for results where 'undefined' is a legitimate outcome, e.g. a median over no successes: the caller
    records the list, so nothing is hidden)."""
    found = [] if found is None else found
    if isinstance(obj, (float, np.floating)):
        if not math.isfinite(float(obj)):
            found.append(where or "<top level>")
            return None, found
        return obj, found
    if isinstance(obj, np.ndarray):
        return nonfinite_to_null(obj.tolist(), where, found)
    if isinstance(obj, dict):
        return {k: nonfinite_to_null(v, f"{where}.{k}" if where else str(k), found)[0] for k, v in obj.items()}, found
    if isinstance(obj, (list, tuple)):
        return [nonfinite_to_null(v, f"{where}[{i}]", found)[0] for i, v in enumerate(obj)], found
    return obj, found


def dumps_json(obj) -> str:
    """Strict JSON text: numpy-aware; NaN/Infinity refused with a DataError naming the key."""
    bad = find_nonfinite(obj)
    if bad:
        raise DataError(f"refusing to write a non-finite number (NaN/Infinity) at '{bad}' to JSON")
    return json.dumps(obj, indent=2, default=to_jsonable, allow_nan=False)


def dump_json(obj, path) -> Path:
    """Write ``obj`` as indented strict JSON (numpy-aware) and return the path.

    NaN/Infinity are refused (DataError naming the key and file: strict JSON readers reject them);
    a file that cannot be written (read-only, disk full) gives a DataError naming the path."""
    path = Path(path)
    try:
        text = dumps_json(obj)
    except DataError as e:
        raise DataError(f"{path}: {e}") from None
    try:
        path.write_text(text)
    except OSError as e:
        raise DataError(f"cannot write {path}: {e.strerror or e}") from None
    return path
