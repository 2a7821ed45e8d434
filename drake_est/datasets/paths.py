"""Where the real data sets live: a user-given folder, else ``$DRAKE_EST_DATA``, else
``../shared/data`` relative to the working directory, else ``shared/data`` beside the
repository checkout."""
from __future__ import annotations

import os
from pathlib import Path

from drake_est.errors import DataError


def default_data_dir() -> Path:
    candidates = []
    if os.environ.get("DRAKE_EST_DATA"):
        candidates.append(Path(os.environ["DRAKE_EST_DATA"]))
    candidates.append(Path.cwd().parent / "shared" / "data")
    repo = Path(__file__).resolve().parents[2]
    candidates.append(repo.parent / "shared" / "data")
    for c in candidates:
        if c.is_dir():
            return c
    return candidates[-1]


def data_dir(path=None) -> Path:
    """Resolve the data folder; raise DataError when it does not exist."""
    p = Path(path) if path is not None else default_data_dir()
    if not p.is_dir():
        raise DataError(f"real-data folder not found: {p} (pass --data DIR or set DRAKE_EST_DATA)")
    return p


def data_file(sub: str, path=None) -> Path:
    """A file inside the data folder; DataError naming it when absent."""
    f = data_dir(path) / sub
    if not f.exists():
        raise DataError(f"data file not found: {f}")
    return f
