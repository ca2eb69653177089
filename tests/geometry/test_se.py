"""SE(2)/SE(3) helpers: compositions and inverses agree with matrices."""

from __future__ import annotations

import numpy as np
import pytest

from studio.geometry.se import (
    Pose2,
    Pose3,
    quat_from_rpy,
    rot_from_quat,
    rot_from_rpy,
    rpy_from_rot,
    wrap_angle,
)

rng = np.random.default_rng(0)


@pytest.mark.parametrize("seed", range(5))
def test_pose2_matches_matrices(seed: int) -> None:
    r = np.random.default_rng(seed)
    a = Pose2(*r.normal(size=2), r.uniform(-np.pi, np.pi))
    b = Pose2(*r.normal(size=2), r.uniform(-np.pi, np.pi))
    np.testing.assert_allclose(a.compose(b).matrix(), a.matrix() @ b.matrix(), atol=1e-12)
    np.testing.assert_allclose(a.inverse().matrix(), np.linalg.inv(a.matrix()), atol=1e-12)
    pts = r.normal(size=(7, 2))
    homog = np.c_[pts, np.ones(7)] @ a.matrix().T
    np.testing.assert_allclose(a.apply(pts), homog[:, :2], atol=1e-12)
    assert Pose2.from_matrix(a.matrix()) == pytest.approx(a)


@pytest.mark.parametrize("seed", range(5))
def test_pose3_rpy_quat_round_trips(seed: int) -> None:
    r = np.random.default_rng(seed)
    rpy = (r.uniform(-3, 3), r.uniform(-1.5, 1.5), r.uniform(-3, 3))
    R = rot_from_rpy(*rpy)
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
    np.testing.assert_allclose(rpy_from_rot(R), rpy, atol=1e-9)
    np.testing.assert_allclose(rot_from_quat(*quat_from_rpy(*rpy)), R, atol=1e-12)
    p = Pose3(R, r.normal(size=3))
    q = Pose3.from_xyz_rpy(*r.normal(size=3), *r.normal(size=3))
    np.testing.assert_allclose(p.compose(q).matrix(), p.matrix() @ q.matrix(), atol=1e-12)
    np.testing.assert_allclose(p.inverse().compose(p).matrix(), np.eye(4), atol=1e-12)


def test_yaw_convention_is_ccw() -> None:
    p = Pose3.from_xyz_rpy(yaw=np.pi / 2)
    np.testing.assert_allclose(p.apply([1.0, 0.0, 0.0]), [0.0, 1.0, 0.0], atol=1e-12)
    assert p.to_pose2().yaw == pytest.approx(np.pi / 2)
    assert float(wrap_angle(3 * np.pi)) == pytest.approx(-np.pi)


def test_bad_shapes_and_quaternions() -> None:
    with pytest.raises(ValueError, match="Pose3 needs"):
        Pose3(np.eye(2), np.zeros(3))
    with pytest.raises(ValueError, match="zero or non-finite"):
        rot_from_quat(0, 0, 0, 0)
