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


def coupled_joints(motor_from_arm, joint: int, candidates=None) -> list[int]:
    """1-based joints whose motor friction enters joint ``joint``'s torque through the gear coupling (9.12).

    With a coupling matrix ``motor_from_arm`` (q_motor = N q_arm, lower-triangular wrist structure of
    Eq. (9.10)): the joints i != ``joint`` with N[joint, i] != 0; without one (None: generic axes) every
    other joint.  ``candidates``: 1-based joints to choose from (default: all joints of N)."""
    import numpy as np
    j = joint_to_index(joint, None, "joint") + 1
    if motor_from_arm is None:
        if candidates is None:
            raise DataError("coupled_joints needs the coupling matrix or the candidate joints")
        return [int(i) for i in candidates if i != j]
    N = np.asarray(motor_from_arm, dtype=float)
    if j > N.shape[0]:
        raise DataError(f"joint {j} does not exist: the coupling matrix has joints 1..{N.shape[0]}")
    cand = range(1, N.shape[1] + 1) if candidates is None else candidates
    return [int(i) for i in cand if i != j and N[j - 1, i - 1] != 0.0]


def resolve_index(index, joint, where: str) -> int:
    """The 0-based data column of a function that used to call it ``joint`` (before issue #18).

    ``index`` is the new name; an old ``joint=`` argument is still honoured *as a 0-based column*
    (never reinterpreted, so old code keeps its meaning) with a DeprecationWarning."""
    import warnings
    if index is not None:
        if joint is not None:
            raise DataError(f"{where}: pass the 0-based data column as index= only (joint= is its old name)")
        return int(index)
    if joint is not None:
        warnings.warn(f"{where}(joint=...) is the 0-based data column: pass index= instead (in drake_est "
                      f"'joint' means a 1-based joint number)", DeprecationWarning, stacklevel=3)
        return int(joint)
    return 0
