"""Forward UKF over one track's frames and an unscented Rauch–Tung–Striebel smoother with variable dt.

The forward pass steps through *every* frame of the track's span (stamps in ns), updating only where the
track was observed, and stores each step's dt and process noise Q. The backward pass is the unscented RTS
smoother (Särkkä 2008) using those stored dt/Q — filterpy's ``rts_smoother`` applies one Q to every step,
which is wrong with irregular frame times and coasting gaps.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from filterpy.kalman import unscented_transform
from numpy.typing import NDArray

from studio.track.models import cv_fx, make_ukf, white_accel_q

__all__ = ["FilterRun", "filter_track", "rts_smooth"]

FloatArray = NDArray[np.float64]


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
        alpha, beta, kappa: the sigma-point parameters used (the smoother uses the same).
    """

    stamps_ns: NDArray[np.int64]
    x: FloatArray
    P: FloatArray
    dt: FloatArray
    Q: FloatArray
    hit: NDArray[np.bool_]
    alpha: float = 1.0
    beta: float = 2.0
    kappa: float = 0.0


def filter_track(
    stamps_ns: NDArray[np.int64],
    z: FloatArray,
    R: FloatArray,
    *,
    accel_sigma: float,
    init_speed_sigma: float,
    alpha: float = 1.0,
    beta: float = 2.0,
    kappa: float = 0.0,
) -> FilterRun:
    """Run the CV UKF forward over a track's frames.

    Args:
        stamps_ns: (K,) frame stamps, ns, non-decreasing; the first frame must have an observation.
        z: (K, 2) observed positions, metres; rows of NaN where the track was not observed.
        R: (K, 2, 2) observation covariances, m² (ignored where ``z`` is NaN).
        accel_sigma: white-noise acceleration, m/s² (:func:`studio.track.models.white_accel_q`).
        init_speed_sigma: prior standard deviation of the velocity, m/s.
        alpha, beta, kappa: sigma-point parameters.

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
    ukf = make_ukf(np.array([z[0, 0], z[0, 1], 0.0, 0.0]), P0, alpha=alpha, beta=beta, kappa=kappa)
    xs = np.zeros((K, 4))
    Ps = np.zeros((K, 4, 4))
    dts = np.zeros(K)
    Qs = np.zeros((K, 4, 4))
    xs[0], Ps[0] = ukf.x, ukf.P
    for k in range(1, K):
        dts[k] = (stamps[k] - stamps[k - 1]) * 1e-9
        Qs[k] = white_accel_q(dts[k], accel_sigma)
        ukf.Q = Qs[k]
        ukf.predict(dt=dts[k])
        if hit[k]:
            ukf.update(z[k], R=R[k])
            ukf.P = 0.5 * (ukf.P + ukf.P.T)
        xs[k], Ps[k] = ukf.x, ukf.P
    return FilterRun(stamps, xs, Ps, dts, Qs, hit, alpha, beta, kappa)


def rts_smooth(run: FilterRun) -> tuple[FloatArray, FloatArray]:
    """Unscented RTS smoothing of a forward run, with each step's own dt and Q.

    Returns:
        ``(x, P)``: (K, 4) smoothed states and (K, 4, 4) covariances.
    """
    K = len(run.x)
    xs, Ps = run.x.copy(), run.P.copy()
    if K < 2:
        return xs, Ps
    ukf = make_ukf(run.x[0], run.P[0], alpha=run.alpha, beta=run.beta, kappa=run.kappa)
    pts, Wm, Wc = ukf.points_fn, ukf.Wm, ukf.Wc
    for k in range(K - 2, -1, -1):
        dt = run.dt[k + 1]
        sigmas = pts.sigma_points(run.x[k], run.P[k])
        sigmas_f = np.array([cv_fx(s, dt) for s in sigmas])
        xb, Pb = unscented_transform(sigmas_f, Wm, Wc, run.Q[k + 1])
        Pxb = ((sigmas - run.x[k]).T * Wc) @ (sigmas_f - xb)
        G = np.linalg.solve(Pb.T, Pxb.T).T  # Pxb · Pb⁻¹
        xs[k] = run.x[k] + G @ (xs[k + 1] - xb)
        Pk = run.P[k] + G @ (Ps[k + 1] - Pb) @ G.T
        Ps[k] = 0.5 * (Pk + Pk.T)
    return xs, Ps
