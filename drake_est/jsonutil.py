"""JSON helpers shared by the CLI and reports."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np


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


def dump_json(obj, path) -> Path:
    """Write ``obj`` as indented JSON (numpy-aware) and return the path."""
    path = Path(path)
    path.write_text(json.dumps(obj, indent=2, default=to_jsonable))
    return path
