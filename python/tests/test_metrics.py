"""synthgen.metrics against numpy references and against `synthgen eval`."""

from __future__ import annotations

import numpy as np
import pytest
from synthgen import metrics


def rot_z(deg: float) -> np.ndarray:
    a = np.radians(deg)
    return np.array(
        [[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1.0]]
    )


@pytest.fixture()
def points() -> np.ndarray:
    return np.random.default_rng(0).uniform(-0.05, 0.05, size=(200, 3))


def ref_add(p, R1, t1, R2, t2):  # type: ignore[no-untyped-def]
    return float(np.linalg.norm((p @ R1.T + t1) - (p @ R2.T + t2), axis=1).mean())


def ref_adi(p, R1, t1, R2, t2):  # type: ignore[no-untyped-def]
    g, e = p @ R1.T + t1, p @ R2.T + t2
    return float(np.sqrt(((g[:, None, :] - e[None, :, :]) ** 2).sum(-1)).min(1).mean())


def test_identical_poses_score_zero(points: np.ndarray) -> None:
    R, t = rot_z(30), np.array([0.1, 0.0, 0.8])
    assert metrics.add(points, R, t, R, t) == 0.0
    assert metrics.add_s(points, R, t, R, t) == 0.0
    assert metrics.re(R, R) == pytest.approx(0.0, abs=1e-6)
    assert metrics.te(t, t) == 0.0
    assert metrics.within_5cm5deg(R, t, R, t)


def test_against_numpy(points: np.ndarray) -> None:
    R1, t1 = rot_z(10), np.array([0.0, 0.0, 1.0])
    R2, t2 = rot_z(17) @ np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0.0]]), np.array(
        [0.01, -0.02, 1.03]
    )
    assert metrics.add(points, R1, t1, R2, t2) == pytest.approx(
        ref_add(points, R1, t1, R2, t2), rel=1e-12
    )
    assert metrics.add_s(points, R1, t1, R2, t2) == pytest.approx(
        ref_adi(points, R1, t1, R2, t2), rel=1e-12
    )
    assert metrics.te(t1, t2) == pytest.approx(np.linalg.norm(t1 - t2), rel=1e-12)
    cos = (np.trace(R2 @ R1.T) - 1) / 2
    assert metrics.re(R1, R2) == pytest.approx(np.degrees(np.arccos(cos)), rel=1e-9)
    assert metrics.add_s(points, R1, t1, R2, t2) <= metrics.add(points, R1, t1, R2, t2)


def test_5cm5deg_thresholds() -> None:
    R, t = np.eye(3), np.zeros(3)
    assert metrics.within_5cm5deg(R, t, rot_z(4.9), t + [0.049, 0, 0])
    assert not metrics.within_5cm5deg(R, t, rot_z(5.1), t)
    assert not metrics.within_5cm5deg(R, t, R, t + [0, 0.051, 0])
    assert metrics.TE_THRESHOLD_M == 0.05 and metrics.RE_THRESHOLD_DEG == 5.0


def test_pose_errors_as_eval_scores(points: np.ndarray) -> None:
    R, t = np.eye(3), np.array([0, 0, 1.0])
    e = metrics.pose_errors(points, 0.1, False, R, t, R, t + [0.005, 0, 0])
    assert e["add"] == pytest.approx(0.005) and e["add_or_s"] == e["add"]
    assert e["correct"] is True  # 5 mm < 10% of 10 cm
    e = metrics.pose_errors(points, 0.1, True, R, t, rot_z(180), t)
    assert e["add_or_s"] == e["add_s"] and e["re"] == pytest.approx(180.0)


def test_bad_shapes_are_errors(points: np.ndarray) -> None:
    import synthgen

    with pytest.raises(synthgen.InputError, match="3x3"):
        metrics.re(np.eye(2), np.eye(3))
    with pytest.raises(synthgen.InputError, match="3 elements"):
        metrics.te([0, 0], [0, 0, 0])
