"""Motion and measurement models, as pure functions handed to the filter (filterpy style).

State ``x = [px, py, vx, vy]`` (metres, m/s) in the tracking frame; measurement ``z = [px, py]`` (metres).
"""

from __future__ import annotations

import numpy as np
from filterpy.kalman import MerweScaledSigmaPoints, UnscentedKalmanFilter
from numpy.typing import NDArray

__all__ = ["DIM_X", "DIM_Z", "cv_fx", "cv_matrix", "make_ukf", "pos_hx", "white_accel_q"]

FloatArray = NDArray[np.float64]

DIM_X = 4
DIM_Z = 2


def cv_fx(x: FloatArray, dt: float) -> FloatArray:
    """Constant-velocity motion: ``x`` (4,) advanced by ``dt`` seconds."""
    return np.array([x[0] + dt * x[2], x[1] + dt * x[3], x[2], x[3]])


def cv_matrix(dt: float) -> FloatArray:
    """The 4×4 transition matrix of :func:`cv_fx` (for linear reference filters and tests)."""
    F = np.eye(4)
    F[0, 2] = F[1, 3] = dt
    return F


def pos_hx(x: FloatArray) -> FloatArray:
    """Position measurement: ``x`` (4,) → ``z`` (2,)."""
    return np.array([x[0], x[1]])


def white_accel_q(dt: float, accel_sigma: float) -> FloatArray:
    """Process noise of the continuous white-noise acceleration model over ``dt`` seconds.

    Each axis gets ``q·[[dt³/3, dt²/2], [dt²/2, dt]]`` with the power spectral density ``q = accel_sigma²``
    (m²/s³; i.e. ``accel_sigma`` is the acceleration standard deviation, m/s², over one second). This model
    is consistent for any dt: two steps of dt/2 give the same noise as one of dt, so irregular frame times
    and long coasting gaps are handled right.

    Returns:
        (4, 4) covariance in the state order ``[px, py, vx, vy]``.
    """
    q = accel_sigma**2
    a, b, c = q * dt**3 / 3.0, q * dt**2 / 2.0, q * dt
    return np.array([[a, 0.0, b, 0.0], [0.0, a, 0.0, b], [b, 0.0, c, 0.0], [0.0, b, 0.0, c]])


def _upper_cholesky(P: FloatArray) -> FloatArray:
    """``U`` with ``Uᵀ U = P``: what filterpy's default (SciPy's ``cholesky``) returns, without SciPy's
    per-call argument checks (a third of the tracker's time on small matrices)."""
    return np.asarray(np.linalg.cholesky(P).T, dtype=np.float64)


def make_ukf(
    x0: FloatArray,
    P0: FloatArray,
    *,
    alpha: float = 1.0,
    beta: float = 2.0,
    kappa: float = 0.0,
) -> UnscentedKalmanFilter:
    """A filterpy UKF for the CV model with Van der Merwe's scaled sigma points.

    The default ``alpha = 1`` keeps the sigma-point weights small (well conditioned); for the linear CV
    model every choice gives the Kalman filter's result.

    Args:
        x0: (4,) initial state.
        P0: (4, 4) initial covariance.
        alpha, beta, kappa: sigma-point parameters.
    """
    points = MerweScaledSigmaPoints(DIM_X, alpha=alpha, beta=beta, kappa=kappa, sqrt_method=_upper_cholesky)
    ukf = UnscentedKalmanFilter(dim_x=DIM_X, dim_z=DIM_Z, dt=0.0, hx=pos_hx, fx=cv_fx, points=points)
    ukf.x = np.asarray(x0, dtype=np.float64).copy()
    ukf.P = np.asarray(P0, dtype=np.float64).copy()
    return ukf
