"""Forward filter over one track's frames and a Rauch–Tung–Striebel smoother with variable dt.

The forward pass steps through *every* frame of the track's span (stamps in ns), updating only where the
track was observed, and stores each step's transition F and process noise Q; the backward pass is filterpy's
``KalmanFilter.rts_smoother`` with those per-step F and Q (irregular frame times and coasting gaps).

For the constant-velocity model with position measurements both the motion and the measurement are linear,
so the unscented transform of the online tracker is exact and its UKF gives the linear Kalman filter's
result to rounding (``tests/track/test_track_filter.py``); the offline pass therefore runs filterpy's linear
``KalmanFilter``, which needs no sigma points: on the simulated ``moving`` recording (960 frames) the
smoothing of all tracklets and tracks took 19 s with the UKF and its unscented smoother, 2 s this way.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from filterpy.kalman import KalmanFilter
from numpy.typing import NDArray

from studio.track.models import DIM_X, DIM_Z, cv_matrix, white_accel_q

__all__ = ["FilterRun", "filter_track", "rts_smooth"]

FloatArray = NDArray[np.float64]
_H = np.eye(DIM_Z, DIM_X)


def _h_at(delta: float) -> FloatArray:
    """Measurement matrix of a position measured ``delta`` seconds after the state's time."""
    H = np.eye(DIM_Z, DIM_X)
    H[0, 2] = H[1, 3] = delta
    return H


@dataclass(frozen=True)
class FilterRun:
    """A forward pass over K frames.

    Attributes:
        stamps_ns: (K,) int64 frame stamps, ns, non-decreasing.
        x: (K, 4) filtered states ``[px, py, vx, vy]`` (m, m/s).
        P: (K, 4, 4) filtered covariances.
        dt: (K,) seconds from the previous frame (0 for the first).
        Q: (K, 4, 4) process noise of the step into each frame (zeros for the first).
        hit: (K,) whether the frame had an observation of the track.
    """

    stamps_ns: NDArray[np.int64]
    x: FloatArray
    P: FloatArray
    dt: FloatArray
    Q: FloatArray
    hit: NDArray[np.bool_]


def _kf(x0: FloatArray, P0: FloatArray) -> KalmanFilter:
    kf = KalmanFilter(dim_x=DIM_X, dim_z=DIM_Z)
    kf.x = x0.copy()
    kf.P = P0.copy()
    kf.H = _H
    return kf


def filter_track(
    stamps_ns: NDArray[np.int64],
    z: FloatArray,
    R: FloatArray,
    *,
    accel_sigma: float,
    init_speed_sigma: float,
    measured_dt: FloatArray | None = None,
) -> FilterRun:
    """Run the CV Kalman filter forward over a track's frames.

    Args:
        stamps_ns: (K,) frame stamps, ns, non-decreasing; the first frame must have an observation.
        z: (K, 2) observed positions, metres; rows of NaN where the track was not observed.
        R: (K, 2, 2) observation covariances, m² (ignored where ``z`` is NaN).
        accel_sigma: white-noise acceleration, m/s² (:func:`studio.track.models.white_accel_q`).
        init_speed_sigma: prior standard deviation of the velocity, m/s.
        measured_dt: (K,) when each observation was measured, seconds after its frame stamp (None: 0): the
            state stays the person's at the frame stamp and an observation made ``δ`` later is where they
            were then, position + ``δ`` · velocity.

    Returns:
        The filtered states, covariances and the per-step dt and Q.
    """
    stamps = np.asarray(stamps_ns, dtype=np.int64)
    K = len(stamps)
    hit = np.all(np.isfinite(z), axis=1)
    if K == 0 or not hit[0]:
        raise ValueError("a track's first frame must have an observation")
    if np.any(np.diff(stamps) < 0):
        raise ValueError("stamps must not decrease")
    P0 = np.zeros((4, 4))
    P0[:2, :2] = R[0]
    P0[2:, 2:] = np.eye(2) * init_speed_sigma**2
    kf = _kf(np.array([z[0, 0], z[0, 1], 0.0, 0.0]), P0)
    xs = np.zeros((K, 4))
    Ps = np.zeros((K, 4, 4))
    dts = np.zeros(K)
    Qs = np.zeros((K, 4, 4))
    xs[0], Ps[0] = kf.x, kf.P
    for k in range(1, K):
        dts[k] = (stamps[k] - stamps[k - 1]) * 1e-9
        Qs[k] = white_accel_q(dts[k], accel_sigma)
        kf.predict(F=cv_matrix(dts[k]), Q=Qs[k])
        if hit[k]:
            delta = 0.0 if measured_dt is None else float(measured_dt[k])
            kf.update(z[k], R=R[k], H=_H if delta == 0.0 else _h_at(delta))
            kf.P = 0.5 * (kf.P + kf.P.T)
        xs[k], Ps[k] = kf.x, kf.P
    return FilterRun(stamps, xs, Ps, dts, Qs, hit)


def rts_smooth(run: FilterRun) -> tuple[FloatArray, FloatArray]:
    """RTS smoothing of a forward run, with each step's own F and Q.

    Returns:
        ``(x, P)``: (K, 4) smoothed states and (K, 4, 4) covariances.
    """
    if len(run.x) < 2:
        return run.x.copy(), run.P.copy()
    Fs = np.array([cv_matrix(dt) for dt in run.dt])
    xs, Ps, _, _ = _kf(run.x[0], run.P[0]).rts_smoother(run.x, run.P, Fs=Fs, Qs=run.Q)
    return xs, 0.5 * (Ps + np.swapaxes(Ps, 1, 2))
