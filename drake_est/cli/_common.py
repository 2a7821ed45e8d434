"""Helpers shared by the CLI commands: validation of numeric options with one-line messages."""
from __future__ import annotations

import math

from drake_est.errors import DataError


def check_number(name: str, val, lo=None, hi=None, lo_strict: bool = False, hi_strict: bool = False,
                 integer: bool = False, unit: str = ""):
    """Refuse a numeric option that is NaN/inf or outside [lo, hi] (open ends with ``*_strict``).

    ``None`` (option not given) passes.  The message names the option, its value and the range."""
    if val is None:
        return val
    if integer and (isinstance(val, bool) or int(val) != val):
        raise DataError(f"{name} must be an integer, got {val}")
    v = float(val)
    fmt = (lambda x: str(int(x))) if integer else (lambda x: f"{x:g}")
    rng = (("(" if lo_strict else "[") + ("-inf" if lo is None else fmt(lo)) + ", "
           + ("inf" if hi is None else fmt(hi)) + (")" if hi_strict else "]"))
    u = f" {unit}" if unit else ""
    if not math.isfinite(v):
        raise DataError(f"{name} must be a finite number in {rng}{u}, got {val}")
    if (lo is not None and (v < lo or (lo_strict and v == lo))) or (hi is not None and (v > hi or (hi_strict and v == hi))):
        raise DataError(f"{name} must be in {rng}{u}, got {val if integer else format(val, 'g')}")
    return val


def warn(command: str, message: str) -> None:
    """A one-line warning on stderr (the run goes on)."""
    import sys

    print(f"drake-est {command}: warning: {message}", file=sys.stderr)


def load_log_checked(path, robot, command: str, nan_policy: str = "raise", **kw):
    """``load_log`` with the position-unit checks of ``robot`` ("irb140", "generic"/None, a URDF path):
    joints with known limits are refused when far outside them (degrees), the others warn when their
    positions look like degrees (:func:`drake_est.data.degrees_warnings`)."""
    from drake_est.data import degrees_warnings, load_log
    from drake_est.robots import robot_position_limits

    limits, prismatic = robot_position_limits(robot)
    log = load_log(path, limits=limits or None, nan_policy=nan_policy, **kw)
    for w in degrees_warnings(log, limits, prismatic):
        warn(command, f"{path}: {w}")
    return log
