"""TF buffer: chaining, interpolation, static edges, clamping and errors."""

from __future__ import annotations

import numpy as np
import pytest

from studio.geometry.se import Pose3, rot_from_quat, rot_from_rpy
from studio.io import TfBuffer, TfError
from studio.io.tf import quat_from_rot, slerp

S = 1_000_000_000


def _tree() -> TfBuffer:
    """map → odom (static), odom → base (dynamic: x 0→2 m, yaw 0→90° over 0–2 s), base → laser (static)."""
    tf = TfBuffer(tolerance_ns=S // 10)
    tf.add("map", "odom", 0, Pose3.from_xyz_rpy(10.0, 0.0, 0.0, 0.0, 0.0, np.pi / 2), static=True)
    for k in range(3):
        tf.add(
            "odom",
            "base",
            k * S,
            Pose3.from_xyz_rpy(k * 1.0, 0.0, 0.0, 0.0, 0.0, k * np.pi / 4),
            static=False,
        )
    tf.add("/base", "/laser", 0, Pose3.from_xyz_rpy(0.5, 0.0, 0.2, 0.0, 0.0, np.pi), static=True)
    return tf


@pytest.mark.parametrize(
    ("target", "source", "stamp", "xyz", "yaw"),
    [
        ("odom", "base", 0, (0.0, 0.0, 0.0), 0.0),
        ("odom", "base", S // 2, (0.5, 0.0, 0.0), np.pi / 8),  # halfway: lerp + slerp
        ("odom", "base", 3 * S // 2, (1.5, 0.0, 0.0), 3 * np.pi / 8),
        ("odom", "base", 2 * S, (2.0, 0.0, 0.0), np.pi / 2),
        ("odom", "base", 2 * S + S // 20, (2.0, 0.0, 0.0), np.pi / 2),  # clamped within tolerance
        ("odom", "laser", S, (1 + 0.5 * np.sqrt(0.5), 0.5 * np.sqrt(0.5), 0.2), np.pi / 4 - np.pi),  # chain
        ("map", "base", 0, (10.0, 0.0, 0.0), np.pi / 2),
        ("map", "laser", 0, (10.0, 0.5, 0.2), np.pi / 2 + np.pi - 2 * np.pi),
        ("base", "odom", 2 * S, (0.0, 2.0, 0.0), -np.pi / 2),  # inverse direction
        ("laser", "laser", 123, (0.0, 0.0, 0.0), 0.0),
        ("unknown", "unknown", 0, (0.0, 0.0, 0.0), 0.0),  # same frame: identity even if unknown
    ],
)
def test_lookup_table(target: str, source: str, stamp: int, xyz: tuple, yaw: float) -> None:
    T = _tree().lookup(target, source, stamp)
    np.testing.assert_allclose(T.t, xyz, atol=1e-9)
    np.testing.assert_allclose(T.R, rot_from_rpy(0.0, 0.0, yaw), atol=1e-9)


def test_lookup_consistent_with_composition() -> None:
    tf = _tree()
    t = 1_234_567_890
    a = tf.lookup("map", "laser", t)
    b = (
        tf.lookup("map", "odom", t)
        .compose(tf.lookup("odom", "base", t))
        .compose(tf.lookup("base", "laser", t))
    )
    np.testing.assert_allclose(a.matrix(), b.matrix(), atol=1e-12)
    inv = tf.lookup("laser", "map", t)
    np.testing.assert_allclose(inv.matrix() @ a.matrix(), np.eye(4), atol=1e-12)


@pytest.mark.parametrize(
    ("target", "source", "stamp", "match"),
    [
        ("odom", "base", 3 * S, "from 0.000 s to 2.000 s"),  # out of range beyond tolerance
        ("odom", "base", -S, "from 0.000 s to 2.000 s"),
        (
            "odom",
            "nowhere",
            0,
            "frame 'nowhere' is not in the TF tree .*known frames: base, laser, map, odom",
        ),
        ("nowhere", "base", 0, "frame 'nowhere'"),
    ],
)
def test_lookup_errors(target: str, source: str, stamp: int, match: str) -> None:
    tf = _tree()
    with pytest.raises(TfError, match=match):
        tf.lookup(target, source, stamp)
    assert not tf.can_transform(target, source, stamp)


def test_static_edges_hold_at_any_time_and_disconnected_trees() -> None:
    tf = _tree()
    np.testing.assert_allclose(tf.lookup("base", "laser", 10**18).t, (0.5, 0.0, 0.2))
    tf.add("world", "other", 0, Pose3.identity(), static=True)
    assert tf.can_transform("map", "laser")
    assert not tf.can_transform("map", "other")
    with pytest.raises(TfError, match="not connected"):
        tf.lookup("map", "other", 0)
    with pytest.raises(TfError, match="not connected"):
        tf.require("laser", "other")
    assert tf.is_static_path("map", "odom")
    assert not tf.is_static_path("map", "base")
    assert tf.frames() == ["base", "laser", "map", "odom", "other", "world"]
    edges = {(e.parent, e.child): e for e in tf.edges()}
    assert edges[("odom", "base")].count == 3
    assert not edges[("odom", "base")].static
    assert edges[("base", "laser")].static


def test_constant_tf_edges_become_static_moving_ones_do_not() -> None:
    tf = TfBuffer()
    mount = Pose3.from_xyz_rpy(0.3, 0.0, 0.2, 0.0, 0.0, 0.1)
    for k in range(5):
        tf.add("base", "laser", k * S, mount, static=False)
        tf.add("odom", "base", k * S, Pose3.from_xyz_rpy(0.1 * k), static=False)
    tf.add("base", "camera", 7 * S, Pose3.identity(), static=False)  # seen once on /tf
    changed = tf.make_constant_edges_static()
    assert sorted(changed) == [("base", "camera"), ("base", "laser")]
    np.testing.assert_allclose(tf.lookup("base", "laser", 100 * S).t, mount.t)
    with pytest.raises(TfError):
        tf.lookup("odom", "base", 100 * S)


def test_empty_buffer_message() -> None:
    with pytest.raises(TfError, match="no /tf or /tf_static"):
        TfBuffer().lookup("base_link", "laser", 0)


def test_unsorted_samples_and_slerp_shortest_arc() -> None:
    tf = TfBuffer()
    tf.add("a", "b", 2 * S, Pose3.from_xyz_rpy(yaw=np.pi - 0.1), static=False)
    tf.add("a", "b", 0, Pose3.from_xyz_rpy(yaw=-np.pi + 0.1), static=False)  # added out of order
    T = tf.lookup("a", "b", S)  # shortest way round is through ±pi
    np.testing.assert_allclose(T.R, rot_from_rpy(0.0, 0.0, np.pi), atol=1e-9)


@pytest.mark.parametrize(
    "rpy", [(0, 0, 0), (0.1, -0.2, 3.0), (np.pi, 0, 0), (0, np.pi / 2, 0), (2.0, 1.0, -2.5)]
)
def test_quat_from_rot_round_trip(rpy: tuple) -> None:
    R = rot_from_rpy(*rpy)
    q = quat_from_rot(R)
    assert q[3] >= 0
    assert abs(np.linalg.norm(q) - 1) < 1e-12
    np.testing.assert_allclose(rot_from_quat(*q), R, atol=1e-12)


def test_slerp_endpoints() -> None:
    q0, q1 = quat_from_rot(rot_from_rpy(0, 0, 0)), quat_from_rot(rot_from_rpy(0, 0, 1.0))
    np.testing.assert_allclose(slerp(q0, q1, 0.0), q0, atol=1e-12)
    np.testing.assert_allclose(slerp(q0, q1, 1.0), q1, atol=1e-12)
    np.testing.assert_allclose(rot_from_quat(*slerp(q0, q1, 0.25)), rot_from_rpy(0, 0, 0.25), atol=1e-12)


def test_add_rejects_self_edge() -> None:
    with pytest.raises(ValueError, match="invalid TF edge"):
        TfBuffer().add("a", "/a", 0, Pose3.identity(), static=True)
