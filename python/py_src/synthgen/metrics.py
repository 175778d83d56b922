"""Pose metrics on numpy arrays, computed by the same Rust functions as ``synthgen eval``.

Rotations are 3x3 matrices of ``cam_from_obj``, translations and points in metres, angles in
degrees. For an object of a dataset, :meth:`synthgen.Dataset.eval_model` gives the points,
diameter and symmetry ``synthgen eval`` scores it with.
"""

from __future__ import annotations

from typing import Dict, Union

import numpy as np
from numpy.typing import ArrayLike

from . import _native

_m = _native

#: ADD(-S) counts as correct below this fraction of the object's diameter.
ADD_THRESHOLD_FRACTION: float = _m.ADD_THRESHOLD_FRACTION
#: 5cm5°: translation error below this (metres) ...
TE_THRESHOLD_M: float = _m.TE_THRESHOLD_M
#: ... and rotation error below this (degrees).
RE_THRESHOLD_DEG: float = _m.RE_THRESHOLD_DEG

__all__ = [
    "ADD_THRESHOLD_FRACTION",
    "RE_THRESHOLD_DEG",
    "TE_THRESHOLD_M",
    "add",
    "add_s",
    "pose_errors",
    "re",
    "te",
    "within_5cm5deg",
]


def _r(a: ArrayLike) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float64)


def _pts(a: ArrayLike) -> np.ndarray:
    return np.ascontiguousarray(np.asarray(a, dtype=np.float64).reshape(-1, 3))


def add(
    points: ArrayLike,
    R_gt: ArrayLike,
    t_gt: ArrayLike,
    R_est: ArrayLike,
    t_est: ArrayLike,
) -> float:
    """ADD: mean over the model points of ``|(R_gt p + t_gt) - (R_est p + t_est)|`` (metres)."""
    return _m.add(
        _pts(points), _r(R_gt), _r(t_gt).ravel(), _r(R_est), _r(t_est).ravel()
    )


def add_s(
    points: ArrayLike,
    R_gt: ArrayLike,
    t_gt: ArrayLike,
    R_est: ArrayLike,
    t_est: ArrayLike,
) -> float:
    """ADD-S (ADI): mean over the GT-posed points of the distance to the nearest
    estimate-posed point (metres). O(M^2) in the number of points."""
    return _m.add_s(
        _pts(points), _r(R_gt), _r(t_gt).ravel(), _r(R_est), _r(t_est).ravel()
    )


def re(R_gt: ArrayLike, R_est: ArrayLike) -> float:
    """Rotation error ``arccos((tr(R_est R_gt^-1) - 1) / 2)`` in degrees (0..180), as
    bop_toolkit's ``re``."""
    return _m.re(_r(R_gt), _r(R_est))


def te(t_gt: ArrayLike, t_est: ArrayLike) -> float:
    """Translation error ``|t_gt - t_est|`` in metres."""
    return _m.te(_r(t_gt).ravel(), _r(t_est).ravel())


def within_5cm5deg(
    R_gt: ArrayLike, t_gt: ArrayLike, R_est: ArrayLike, t_est: ArrayLike
) -> bool:
    """5cm5°: translation error below 5 cm and rotation error below 5°."""
    return _m.within_5cm5deg(_r(R_gt), _r(t_gt).ravel(), _r(R_est), _r(t_est).ravel())


def pose_errors(
    points: ArrayLike,
    diameter: float,
    symmetric: bool,
    R_gt: ArrayLike,
    t_gt: ArrayLike,
    R_est: ArrayLike,
    t_est: ArrayLike,
) -> Dict[str, Union[float, bool]]:
    """All errors of one estimate as ``synthgen eval`` scores it: ``add``, ``add_s``,
    ``add_or_s`` (ADD-S for symmetric objects, else ADD), ``te``, ``re``, ``correct``
    (``add_or_s`` below 10% of the diameter) and ``within_5cm5deg``."""
    return _m.pose_errors(
        _pts(points),
        float(diameter),
        bool(symmetric),
        _r(R_gt),
        _r(t_gt).ravel(),
        _r(R_est),
        _r(t_est).ravel(),
    )
