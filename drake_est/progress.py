"""Progress bars for long work (tqdm on stderr; silent when DRAKE_EST_NO_PROGRESS=1)."""
from __future__ import annotations

import os

from tqdm.auto import tqdm


def progress(iterable=None, desc: str = "", total: int | None = None, leave: bool = False):
    """Wrap ``iterable`` in a progress bar; disabled when not interactive or when
    the environment variable ``DRAKE_EST_NO_PROGRESS`` is set."""
    disable = bool(os.environ.get("DRAKE_EST_NO_PROGRESS")) or None  # None: auto (tty only)
    return tqdm(iterable, desc=desc, total=total, leave=leave, disable=disable, dynamic_ncols=True)
