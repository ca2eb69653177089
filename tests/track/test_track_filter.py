"""The CV-model UKF against filterpy's linear Kalman filter; our RTS smoother against its linear one."""

from __future__ import annotations

import numpy as np
import pytest
from filterpy.kalman import KalmanFilter

from studio.track.models import cv_fx, cv_matrix, make_ukf, pos_hx, white_accel_q
from studio.track.smooth import filter_track, rts_smooth

H = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]])


def _problem(seed: int = 3, n: int = 60):
    rng = np.random.default_rng(seed)
    dts = rng.uniform(0.02, 0.3, n)  # irregular
    dts[0] = 0.0
    stamps = 1_000_000_000 + np.round(np.cumsum(dts) * 1e9).astype(np.int64)
    dts = np.diff(stamps, prepend=stamps[0]) * 1e-9
    z = np.cumsum(rng.normal(0, 0.1, (n, 2)), axis=0) + rng.normal(0, 0.05, (n, 2))
    A = rng.normal(0, 0.1, (n, 2, 2))
    R = A @ np.swapaxes(A, 1, 2) + np.eye(2) * 0.01  # full, different per step
    z[rng.random(n) < 0.2] = np.nan
    z[0] = [0.3, -0.2]
    return stamps, dts, z, R


def _kf(z0, R0, speed_sigma):
    kf = KalmanFilter(dim_x=4, dim_z=2)
    kf.x = np.array([z0[0], z0[1], 0.0, 0.0])
    kf.P = np.zeros((4, 4))
    kf.P[:2, :2] = R0
    kf.P[2:, 2:] = np.eye(2) * speed_sigma**2
    kf.H = H
    return kf


def test_models_are_linear_cv():
    x = np.array([1.0, 2.0, -0.5, 0.25])
    np.testing.assert_allclose(cv_fx(x, 0.4), cv_matrix(0.4) @ x)
    np.testing.assert_allclose(pos_hx(x), H @ x)


def test_white_accel_q_is_consistent_over_split_steps():
    # one step of dt == two steps of dt/2 (continuous white-noise acceleration)
    dt, s = 0.7, 1.3
    F = cv_matrix(dt / 2)
    two = F @ white_accel_q(dt / 2, s) @ F.T + white_accel_q(dt / 2, s)
    np.testing.assert_allclose(two, white_accel_q(dt, s), atol=1e-12)
    np.testing.assert_array_equal(white_accel_q(0.0, s), np.zeros((4, 4)))


@pytest.mark.parametrize(("alpha", "kappa"), [(1.0, 0.0), (0.5, 0.0), (0.1, 1.0)])
def test_ukf_equals_linear_kf(alpha, kappa):
    stamps, dts, z, R = _problem()
    ukf = make_ukf(np.array([*z[0], 0.0, 0.0]), np.diag([*np.diag(R[0]), 1.0, 1.0]), alpha=alpha, kappa=kappa)
    ukf.P[:2, :2] = R[0]
    kf = _kf(z[0], R[0], 1.0)
    for k in range(1, len(stamps)):
        Q = white_accel_q(dts[k], 1.5)
        ukf.Q = Q
        ukf.predict(dt=dts[k])
        kf.predict(F=cv_matrix(dts[k]), Q=Q)
        np.testing.assert_allclose(ukf.x, kf.x, atol=1e-6)
        np.testing.assert_allclose(ukf.P, kf.P, atol=1e-6)
        if np.isfinite(z[k, 0]):
            ukf.update(z[k], R=R[k])
            kf.update(z[k], R=R[k])
            np.testing.assert_allclose(ukf.x, kf.x, atol=1e-6)
            np.testing.assert_allclose(ukf.P, kf.P, atol=1e-6)


def test_filter_track_and_rts_equal_linear_kf_and_rts():
    stamps, dts, z, R = _problem(seed=7)
    run = filter_track(stamps, z, R, accel_sigma=1.5, init_speed_sigma=1.0)
    kf = _kf(z[0], R[0], 1.0)
    Xs, Ps, Fs, Qs = [kf.x.copy()], [kf.P.copy()], [np.eye(4)], [np.zeros((4, 4))]
    for k in range(1, len(stamps)):
        Fs.append(cv_matrix(dts[k]))
        Qs.append(white_accel_q(dts[k], 1.5))
        kf.predict(F=Fs[-1], Q=Qs[-1])
        if np.isfinite(z[k, 0]):
            kf.update(z[k], R=R[k])
        Xs.append(kf.x.copy())
        Ps.append(kf.P.copy())
    np.testing.assert_allclose(run.x, np.array(Xs), atol=1e-6)
    np.testing.assert_allclose(run.P, np.array(Ps), atol=1e-6)
    np.testing.assert_array_equal(run.hit, np.isfinite(z[:, 0]))
    xs, ps = rts_smooth(run)
    xk, pk, _, _ = kf.rts_smoother(np.array(Xs), np.array(Ps), Fs=Fs, Qs=Qs)
    np.testing.assert_allclose(xs, xk, atol=1e-6)
    np.testing.assert_allclose(ps, pk, atol=1e-6)
    # smoothing never increases the uncertainty
    assert np.all(np.trace(ps, axis1=1, axis2=2) <= np.trace(run.P, axis1=1, axis2=2) + 1e-12)


def test_filter_track_rejects_bad_input():
    with pytest.raises(ValueError, match="first frame"):
        filter_track(
            np.array([0, 1]),
            np.array([[np.nan, np.nan], [0, 0]]),
            np.tile(np.eye(2), (2, 1, 1)),
            accel_sigma=1.0,
            init_speed_sigma=1.0,
        )
    with pytest.raises(ValueError, match="decrease"):
        filter_track(
            np.array([5, 1]),
            np.zeros((2, 2)),
            np.tile(np.eye(2), (2, 1, 1)),
            accel_sigma=1.0,
            init_speed_sigma=1.0,
        )


def test_observations_measured_off_the_frame_stamp_give_the_walker_where_they_were_at_the_stamp():
    """A walker at 1.4 m/s seen by scans taken up to 50 ms before and 125 ms after each 10 Hz frame (an
    unsynchronised 10 Hz scanner and its sweep): with the measurement times the smoothed positions at the
    frame stamps are the walker's to millimetres; taken as measured at the stamps they are off by the
    walker's motion in between (up to 17 cm)."""
    rng = np.random.default_rng(5)
    n = 40
    stamps = 2_000_000_000 + np.arange(n, dtype=np.int64) * 100_000_000
    v = np.array([1.4, -0.3])
    delta = rng.uniform(-0.05, 0.125, n)
    t = (stamps - stamps[0]) * 1e-9
    truth = np.array([1.0, 2.0]) + t[:, None] * v
    z = truth + delta[:, None] * v + rng.normal(0.0, 0.003, (n, 2))
    R = np.tile(np.eye(2) * 0.01**2, (n, 1, 1))
    errors = {}
    for name, dt in (("timed", delta), ("at the stamps", None)):
        xs, _ = rts_smooth(filter_track(stamps, z, R, accel_sigma=0.5, init_speed_sigma=1.0, measured_dt=dt))
        errors[name] = np.hypot(*(xs[:, :2] - truth).T)
        if dt is not None:
            np.testing.assert_allclose(xs[5:-5, 2:], np.tile(v, (n - 10, 1)), atol=0.05)
    assert errors["timed"][3:].max() < 0.01
    assert errors["at the stamps"].mean() > 0.03
    assert errors["at the stamps"].max() > 0.1
    # all measured at the stamp: the filter as before
    zero = filter_track(stamps, z, R, accel_sigma=0.5, init_speed_sigma=1.0, measured_dt=np.zeros(n))
    plain = filter_track(stamps, z, R, accel_sigma=0.5, init_speed_sigma=1.0)
    np.testing.assert_array_equal(zero.x, plain.x)
