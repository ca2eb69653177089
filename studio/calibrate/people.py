"""Target-free calibration from people: camera latency (camera–laser time offset) and camera pose.

Any recording where the camera and the lasers both see people calibrates itself (issue #7, "people").
The image detector gives each person's azimuth in the camera frame (and the elevation of the ankles when
seen); the laser detector gives people's positions at every scan stamp. For a candidate camera latency
``L`` (capture time = image header stamp − ``L``, the rig's ``sync.camera_latency_s``) the laser people
are interpolated to each image's capture time in the odometry frame, so the robot's own motion is
compensated exactly by the odometry, and projected into the camera at that instant.

1. *Coarse*: on a 20 ms grid over the rig's latency ± ``max_offset_s``, every box–laser azimuth
   difference votes into a kernel histogram (σ = 2°); the score is its peak within ± ``max_yaw_deg``
   (the share of boxes explained) and the peak's position the camera's yaw error. No association and no
   initial yaw are needed.
2. *Fine*: around the best latency, a bounded per-box cost (1 − exp(−e²/2σ²), σ = 1.5°, against the
   nearest laser person) on a 5 ms grid; a quadratic through the minimum gives the latency.
3. *Fit*: one-to-one pairs (Hungarian, within 4°) feed a robust weighted least squares (Cauchy loss;
   residuals scaled by ``sqrt(0.3°² + (5 cm / range)²)``) over the latency, the camera yaw and, with
   enough ankle rows, roll and pitch (plus a foot-row bias). Steps 2–3 alternate three times.

Uncertainty: the largest of the fit's standard error, a block bootstrap (2 s blocks of images) of the
fine cost, and ``noise / (spread · √n)`` where ``spread`` is the RMS of the paired people's apparent
angular rates about their mean (rates from velocities measured over ≥ 0.5 s, so range noise does not
look like motion; a common rate, such as the robot turning steadily, trades off against the yaw). With
a static robot among standing people the spread is nil: :class:`UnobservableError`, not a number.

The data (:func:`collect_people`, :class:`PeopleData` and the errors) live in
:mod:`studio.calibrate.people_data`.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from studio.calibrate.people_data import (
    PeopleCalibrationError,
    PeopleData,
    UnobservableError,
    _wrap,
    collect_people,
)
from studio.geometry.se import Pose3

__all__ = [
    "PeopleCalibration",
    "PeopleCalibrationError",
    "UnobservableError",
    "calibrate_people",
    "collect_people",
]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
_ANKLE_Z = 0.08  # height of the ankle keypoint above the floor, m (as studio.fuse)


@dataclass
class PeopleCalibration:
    """Result of :func:`calibrate_people`.

    Attributes:
        latency_s, latency_std_s, latency_before_s: the camera latency found, its 1σ uncertainty and the
            rig's value, s.
        pose_before, pose_after: ``T_base_cam`` before and after.
        n_images, n_pairs, n_foot_pairs: images used; box–laser pairs of the fit, and those with ankles.
        residual_deg: median absolute azimuth residual of the pairs, degrees.
        motion_deg_s: RMS apparent angular rate of the paired people in the camera, deg/s.
        refined: the camera angles fitted.
        curve: coarse ``latency_s`` / ``score`` (higher is better), fine ``fine_latency_s`` / ``fine_cost``.
        rig: the input rig with the new camera pose and latency.
    """

    latency_s: float
    latency_std_s: float
    latency_before_s: float
    pose_before: Pose3
    pose_after: Pose3
    n_images: int
    n_pairs: int
    n_foot_pairs: int
    residual_deg: float
    motion_deg_s: float
    refined: tuple[str, ...]
    curve: dict[str, list[float]] = field(default_factory=dict)
    rig: Any = None

    @property
    def offset_s(self) -> float:
        """Change of the camera latency (new − rig's), s."""
        return self.latency_s - self.latency_before_s

    def pose_change(self) -> dict[str, float]:
        """Pose after − before: ``x y z`` in m, ``roll pitch yaw`` in degrees."""
        a, b = self.pose_after.as_dict(), self.pose_before.as_dict()
        out = {k: a[k] - b[k] for k in ("x", "y", "z")}
        for k in ("roll", "pitch", "yaw"):
            out[k] = math.degrees(math.remainder(a[k] - b[k], 2 * math.pi))
        return out

    def to_json(self) -> dict[str, Any]:
        """Plain-JSON form (``--json``)."""
        return {
            "camera_latency_s": self.latency_s,
            "camera_latency_std_s": self.latency_std_s,
            "camera_latency_before_s": self.latency_before_s,
            "offset_s": self.offset_s,
            "pose_before": self.pose_before.as_dict(),
            "pose_after": self.pose_after.as_dict(),
            "pose_change": self.pose_change(),
            "refined": list(self.refined),
            **{k: getattr(self, k) for k in ("n_images", "n_pairs", "n_foot_pairs", "residual_deg")},
            "motion_deg_s": self.motion_deg_s,
            "curve": self.curve,
        }

    def summary(self) -> str:
        """Readable three-line summary."""
        d = self.pose_change()
        return (
            f"camera latency: {self.latency_s:+.3f} s ± {self.latency_std_s:.3f} s "
            f"(rig had {self.latency_before_s:+.3f} s; change {self.offset_s:+.3f} s)\n"
            f"camera pose change: yaw {d['yaw']:+.2f}°, roll {d['roll']:+.2f}°, pitch {d['pitch']:+.2f}° "
            f"(fitted: {', '.join(self.refined)})\n"
            f"pairs: {self.n_pairs} ({self.n_foot_pairs} with ankles) from {self.n_images} images; median "
            f"azimuth residual {self.residual_deg:.2f}°; apparent motion {self.motion_deg_s:.1f}°/s RMS"
        )


# ------------------------------------------------------------------------------------------ estimation
class _Pairs(NamedTuple):
    img: IntArray  # image index
    az: FloatArray  # box azimuth, rad
    el: FloatArray  # ankle elevation, rad (NaN: none)
    g: IntArray  # laser person: index into LaserPeople.xy


class _Problem:
    """All images' people as padded ``(N, B)`` arrays, and the laser people at any latency."""

    def __init__(self, data: PeopleData) -> None:
        imgs = [im for im in data.images if len(im.az)]
        self.stamp = np.array([im.stamp_ns for im in imgs], dtype=np.int64)
        self.az = np.full((len(imgs), max((len(im.az) for im in imgs), default=0)), np.nan)
        self.el = self.az.copy()
        for i, im in enumerate(imgs):
            self.az[i, : len(im.az)], self.el[i, : len(im.az)] = im.az, im.el_foot
        self.las = data.laser
        self.owner = np.repeat(np.arange(len(self.las.count)), self.las.count)
        self.n_boxes = int(np.isfinite(self.az).sum())

    def capture(self, latency_s: float, img: Any = slice(None)) -> IntArray:
        return np.asarray(self.stamp[img] - round(latency_s * 1e9), dtype=np.int64)

    def laser_at(self, latency_s: float) -> tuple[FloatArray, NDArray[np.bool_], IntArray]:
        """``(N, M, 3)`` base-frame laser people at each image's capture time, ``(N, M)`` mask and index g."""
        L, t = self.las, self.capture(latency_s)
        k = np.searchsorted(L.stamp_ns, t, side="right") - 1
        inside = (k >= 0) & (k < len(L.stamp_ns) - 1)
        k = np.clip(k, 0, max(len(L.stamp_ns) - 2, 0))
        inside &= (L.stamp_ns[k + 1] - L.stamp_ns[k]) < 300_000_000
        cnt = np.where(inside, L.count[k], 0)
        j = np.arange(int(cnt.max()) if len(cnt) else 0)[None, :]
        mask = j < cnt[:, None]
        g = np.where(mask, L.start[k][:, None] + j, 0)
        return self.points(t[:, None], g), mask, g

    def points(self, t: IntArray, g: IntArray, *, slow: bool = False) -> FloatArray:
        """Base-frame points ``(..., 3)`` (z: ankle height) of laser people ``g`` at stamps ``t``: each
        moves linearly to its match in the next frame (``slow``: with its ≥ 0.5 s velocity); the robot
        as its odometry."""
        L = self.las
        if len(L.xy) == 0:
            return np.zeros((*np.broadcast_shapes(t.shape, g.shape), 3))
        k0 = self.owner[g]
        t0, t1 = L.stamp_ns[k0], L.stamp_ns[np.minimum(k0 + 1, len(L.stamp_ns) - 1)]
        if slow:
            p = L.xy[g] + L.velocity[g] * ((t - t0) * 1e-9)[..., None]
        else:
            p = L.xy[g] + ((t - t0) / np.maximum(t1 - t0, 1))[..., None] * (L.xy_next[g] - L.xy[g])
        tt = np.broadcast_to(t, p.shape[:-1]).astype(np.float64)
        rx, ry, ryaw = (np.interp(tt, L.stamp_ns.astype(np.float64), L.robot[:, i]) for i in range(3))
        dx, dy, c, s = p[..., 0] - rx, p[..., 1] - ry, np.cos(ryaw), np.sin(ryaw)
        return np.stack([c * dx + s * dy, -s * dx + c * dy, np.full(dx.shape, _ANKLE_Z)], -1)

    @staticmethod
    def angles(pts: FloatArray, pose: Pose3) -> tuple[FloatArray, FloatArray]:
        """Camera-frame azimuth and elevation (rad) of base-frame points ``(..., 3)``."""
        pc = (pts - pose.t) @ pose.R
        return np.arctan2(pc[..., 1], pc[..., 0]), np.arctan2(pc[..., 2], np.hypot(pc[..., 0], pc[..., 1]))

    def diffs(self, latency_s: float, pose: Pose3) -> tuple[FloatArray, IntArray]:
        """``(N, B, M)`` azimuth differences box − laser person, rad (NaN: missing), and ``g`` ``(N, M)``."""
        pts, mask, g = self.laser_at(latency_s)
        az = np.where(mask, self.angles(pts, pose)[0], np.nan)
        return _wrap(self.az[:, :, None] - az[:, None, :]), g


def _coarse(pr: _Problem, lats: FloatArray, pose: Pose3, max_yaw: float) -> tuple[FloatArray, FloatArray]:
    """Kernel-vote score per latency (share of boxes explained) and the yaw bias at its peak (rad)."""
    step, sigma = math.radians(0.25), math.radians(2.0)
    edges = np.arange(-max_yaw - 4 * sigma, max_yaw + 4 * sigma + step, step)
    centres = 0.5 * (edges[1:] + edges[:-1])
    kern = np.exp(-0.5 * (np.arange(-4 * sigma, 4 * sigma + step, step) / sigma) ** 2)
    inner = np.abs(centres) <= max_yaw
    score, bias = np.zeros(len(lats)), np.zeros(len(lats))
    for i, lat in enumerate(lats):
        d = pr.diffs(float(lat), pose)[0]
        s = np.convolve(np.histogram(d[np.isfinite(d)], bins=edges)[0], kern, mode="same")[inner]
        j = int(np.argmax(s))
        score[i], bias[i] = s[j] / max(pr.n_boxes, 1), centres[inner][j]
    return score, bias


def _frame_costs(pr: _Problem, lats: FloatArray, pose: Pose3) -> FloatArray:
    """``(N, len(lats))`` per-image cost: per box 1 − exp(−e²/2σ²) to its nearest laser person (σ = 1.5°)."""
    out, box, sigma = np.zeros((len(pr.stamp), len(lats))), np.isfinite(pr.az), math.radians(1.5)
    for j, lat in enumerate(lats):
        d = pr.diffs(float(lat), pose)[0]
        e = np.where(np.isfinite(d), np.abs(d), np.inf).min(axis=2, initial=np.inf)
        out[:, j] = np.where(box, 1.0 - np.exp(-0.5 * (e / sigma) ** 2), 0.0).sum(1)
    return out


def _quad_min(x: FloatArray, y: FloatArray, half: int = 6) -> float:
    """Minimum of a quadratic fitted to the ``2·half + 1`` samples around the smallest ``y``."""
    i = int(np.argmin(y))
    lo, hi = max(0, i - half), min(len(x), i + half + 1)
    if hi - lo >= 3:
        a, b, _ = np.polyfit(x[lo:hi] - x[i], y[lo:hi], 2)
        if a > 0 and abs(b / (2 * a)) <= x[hi - 1] - x[lo]:
            return float(x[i] - b / (2 * a))
    return float(x[i])


def _bootstrap(stamp: IntArray, x: FloatArray, costs: FloatArray, n: int, seed: int) -> float:
    """Std of the fine-cost minimum over resamples of 2 s blocks of images."""
    if n <= 1 or len(stamp) < 2:
        return 0.0
    ids, inv = np.unique((stamp - stamp.min()) // 2_000_000_000, return_inverse=True)
    per = np.zeros((len(ids), costs.shape[1]))
    np.add.at(per, inv, costs)
    rng = np.random.default_rng(seed)
    return float(np.std([_quad_min(x, per[rng.integers(0, len(ids), len(ids))].sum(0)) for _ in range(n)]))


def _pairs(pr: _Problem, lat: float, pose: Pose3, gate: float) -> _Pairs:
    """One-to-one box ↔ laser person pairs per image (Hungarian on |Δaz|), within ``gate`` rad."""
    from scipy.optimize import linear_sum_assignment

    d, g = pr.diffs(lat, pose)
    rows: list[tuple[int, int, int]] = []
    for i in range(d.shape[0]):
        c = np.where(np.isfinite(d[i]), np.abs(d[i]), 1e3)
        if c.size:
            r, k = linear_sum_assignment(c)
            rows += [(i, int(a), int(b)) for a, b in zip(r, k, strict=True) if c[a, b] < gate]
    ix = np.array(rows, dtype=np.int64).reshape(-1, 3)
    return _Pairs(ix[:, 0], pr.az[ix[:, 0], ix[:, 1]], pr.el[ix[:, 0], ix[:, 1]], g[ix[:, 0], ix[:, 2]])


def _pose_of(base: Pose3, delta: Sequence[float] | FloatArray, names: Sequence[str]) -> Pose3:
    d = base.as_dict()
    for n, v in zip(names, delta, strict=False):
        d[n] += float(v)
    return Pose3.from_xyz_rpy(**d)


def _fit(
    pr: _Problem, lat0: float, pose0: Pose3, pp: _Pairs, names: tuple[str, ...]
) -> tuple[float, Pose3, FloatArray, float]:
    """Robust weighted least squares over (latency, camera angles ``names``, ankle-row bias).

    Returns:
        Latency (s), pose, azimuth residuals (degrees) and the latency's standard error (s).
    """
    from scipy.optimize import least_squares

    foot, use_el = np.isfinite(pp.el), len(names) > 1
    rng = np.hypot(*(pr.points(pr.capture(lat0, pp.img), pp.g)[:, :2] - pose0.t[:2]).T)
    sig = np.radians(np.hypot(0.3, np.degrees(0.05 / np.maximum(rng, 0.3))))  # near people: wide, jittery
    scale = np.concatenate([sig, sig[foot]]) if use_el else sig

    def resid(p: FloatArray) -> FloatArray:
        a, e = pr.angles(pr.points(pr.capture(lat0 + p[0], pp.img), pp.g), _pose_of(pose0, p[1:], names))
        r = [_wrap(pp.az - a)] + ([pp.el[foot] - e[foot] - p[-1]] if use_el else [])
        return np.concatenate(r) / scale

    # 3-point differences: 2-point ones stalled in the narrow latency–yaw valley
    sol = least_squares(resid, np.zeros(1 + len(names) + use_el), loss="cauchy", f_scale=1.5, jac="3-point",
                        x_scale="jac")  # fmt: skip
    ok = np.abs(sol.fun) < 3.0
    s2 = max(float(np.median(np.abs(sol.fun[ok])) * 1.4826) ** 2, 1.0) if ok.any() else 1.0
    try:
        std = math.sqrt(s2 * float(np.linalg.inv(sol.jac[ok].T @ sol.jac[ok])[0, 0]))
    except np.linalg.LinAlgError:
        std = math.inf
    return (
        lat0 + float(sol.x[0]),
        _pose_of(pose0, sol.x[1:], names),
        np.degrees(sol.fun[: len(sig)] * sig),
        std,
    )


def calibrate_people(
    data: PeopleData,
    *,
    max_offset_s: float = 2.0,
    max_yaw_deg: float = 30.0,
    max_std_s: float = 0.05,
    min_motion_deg_s: float = 2.0,
    refine: Sequence[str] = ("yaw", "roll", "pitch"),
    min_foot_pairs: int = 30,
    bootstrap: int = 200,
    seed: int = 0,
) -> PeopleCalibration:
    """Estimate the camera latency and refine the camera pose from people (see the module docstring).

    Args:
        data: from :func:`collect_people`.
        max_offset_s: search the latency within the rig's value ± this, s.
        max_yaw_deg: largest camera yaw error the coarse search considers, degrees.
        max_std_s: a latency less certain than this (1σ, s) is unobservable.
        min_motion_deg_s: so is one where the paired people's apparent angular rates spread (RMS about
            their mean) less than this, deg/s.
        refine: camera angles to fit (``yaw``, ``roll``, ``pitch``); roll and pitch need ankle rows.
        min_foot_pairs: pairs with ankles needed to fit roll and pitch.
        bootstrap: block-bootstrap resamples; seed: their random seed.

    Raises:
        UnobservableError: nothing moves across the view enough to pin the offset down.
        PeopleCalibrationError: too few people seen by both sensors.
    """
    rig = data.rig
    pose0 = rig.camera.pose if rig.camera.pose is not None else Pose3.identity()
    lat_rig = float(rig.sync.camera_latency_s)
    pr = _Problem(data)
    if pr.n_boxes < 10:
        raise PeopleCalibrationError(f"only {pr.n_boxes} people found in the images: too few to calibrate")
    lats = lat_rig + np.arange(-max_offset_s, max_offset_s + 0.01, 0.02)
    score, bias = _coarse(pr, lats, pose0, math.radians(max_yaw_deg))
    i = int(np.argmax(score))
    lat, pose = float(lats[i]), _pose_of(pose0, [-bias[i]], ("yaw",))
    names = tuple(n for n in ("yaw", "roll", "pitch") if n in refine) or ("yaw",)
    fitted: tuple[str, ...] = ("yaw",)
    resid, lat_std = np.zeros(0), math.inf
    for _ in range(3):
        fine = lat + np.arange(-0.1, 0.1 + 1e-9, 0.005)
        lat = _quad_min(fine, _frame_costs(pr, fine, pose).sum(0))
        pp = _pairs(pr, lat, pose, math.radians(4.0))
        if len(pp.img) < 10:
            raise PeopleCalibrationError(
                f"only {len(pp.img)} image–laser pairs agree at the best offset: too few to calibrate"
            )
        fitted = names if int(np.isfinite(pp.el).sum()) >= min_foot_pairs else ("yaw",)
        lat, pose, resid, lat_std = _fit(pr, lat, pose, pp, fitted)
    fine = lat + np.arange(-0.1, 0.1 + 1e-9, 0.005)
    costs = _frame_costs(pr, fine, pose)
    inl = np.abs(resid) < 3.0
    h = 0.02  # apparent angular rate of the paired people, from their ≥ 0.5 s velocities
    a1 = pr.angles(pr.points(pr.capture(lat + h, pp.img), pp.g, slow=True), pose)[0]
    a0 = pr.angles(pr.points(pr.capture(lat - h, pp.img), pp.g, slow=True), pose)[0]
    rate = np.degrees(_wrap(a1 - a0) / (2 * h))[inl]
    rate = rate[np.isfinite(rate)]
    spread = float(np.sqrt(np.mean((rate - rate.mean()) ** 2))) if len(rate) > 1 else 0.0
    noise = max(float(np.median(np.abs(resid[inl]))) * 1.4826, 0.2) if inl.any() else 1.0
    std = max(lat_std, noise / (spread * math.sqrt(len(rate))) if spread > 0 else math.inf)
    if spread < min_motion_deg_s or not std <= max_std_s:
        why = f"at least {min_motion_deg_s:.1f}°/s needed" if spread < min_motion_deg_s else (
            f"uncertainty {std:.3f} s > {max_std_s:.3f} s")  # fmt: skip
        raise UnobservableError(
            f"the camera–laser time offset is unobservable here: the paired people move across the view at "
            f"{spread:.1f}°/s RMS about their common rate ({why}); record people walking around the robot, "
            "or the robot turning"
        )
    std = max(std, _bootstrap(pr.stamp, fine, costs, bootstrap, seed))
    sync = dataclasses.replace(rig.sync, camera_latency_s=round(lat, 4))
    return PeopleCalibration(
        latency_s=lat,
        latency_std_s=std,
        latency_before_s=lat_rig,
        pose_before=pose0,
        pose_after=pose,
        n_images=len(pr.stamp),
        n_pairs=int(inl.sum()),
        n_foot_pairs=int(np.isfinite(pp.el[inl]).sum()),
        residual_deg=float(np.median(np.abs(resid[inl]))) if inl.any() else math.nan,
        motion_deg_s=float(np.sqrt(np.mean(rate**2))) if len(rate) else 0.0,
        refined=fitted,
        curve={
            "latency_s": [round(float(x), 4) for x in lats],
            "score": [round(float(x), 5) for x in score],
            "fine_latency_s": [round(float(x), 4) for x in fine],
            "fine_cost": [round(float(x), 5) for x in costs.sum(0) / max(pr.n_boxes, 1)],
        },
        rig=dataclasses.replace(rig, camera=dataclasses.replace(rig.camera, pose=pose), sync=sync),
    )
