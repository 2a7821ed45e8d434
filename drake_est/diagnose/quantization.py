"""Quantization of measured torques (a coarse ADC leaves a deterministic error below one step)."""
from __future__ import annotations

import numpy as np


def torque_step(y) -> float:
    """The quantization step of a torque signal (0 when it is not on a grid): the smallest gap between
    distinct values, when at least 99 % of the values sit on that grid."""
    u = np.unique(np.asarray(y, float))
    if u.size < 3 or u.size > 0.5 * y.size:
        return 0.0
    d = np.diff(u)
    step = float(np.min(d[d > 1e-12 * max(np.ptp(u), 1e-300)])) if np.any(d > 0) else 0.0
    if step <= 0:
        return 0.0
    k = (u - u[0]) / step
    return step if np.mean(np.abs(k - np.round(k)) < 0.05) > 0.99 else 0.0
