"""One meaning of "joint": a 1-based joint number in the public API, files and reports.

0-based array positions are private and called ``index``; convert at the boundary with these helpers.
"""
from __future__ import annotations

from drake_est.errors import DataError


def joint_to_index(joint, n_joints: int | None = None, name: str = "joint") -> int:
    """1-based joint number -> 0-based index, with a one-line error naming ``name``."""
    try:
        j = int(joint)
    except (TypeError, ValueError):
        raise DataError(f"{name} must be a joint number (1-based integer), got {joint!r}") from None
    if j != joint or j < 1:
        raise DataError(f"{name} must be a joint number >= 1 (joints are numbered from 1), got {joint!r}")
    if n_joints is not None and j > n_joints:
        raise DataError(f"{name} {j} does not exist: the model has joints 1..{n_joints}")
    return j - 1


def index_to_joint(index: int) -> int:
    """0-based index -> 1-based joint number."""
    return int(index) + 1


def joints_to_indices(joints, n_joints: int | None = None, name: str = "joints") -> list[int]:
    """A list of 1-based joint numbers -> 0-based indices (duplicates refused)."""
    out = [joint_to_index(j, n_joints, name) for j in joints]
    if len(set(out)) != len(out):
        raise DataError(f"{name} lists a joint twice: {list(joints)}")
    return out
