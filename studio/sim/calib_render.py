"""Ray-cast panoramas of the calibration room and its targets (:mod:`studio.sim.calib`).

The room (walls with panels and skirting, tiled floor, ceiling, the robot's top) is rendered once per
camera as a background; a target (ball, green/white board or checkerboard, see the constants below) is
composited over it inside its bounding sphere's image, with the coverage of each pixel from a supersampled
grid of rays. Pixel centres are at ``+0.5``; colours are BGR.
"""

from __future__ import annotations

import functools
import math

import numpy as np
from numpy.typing import NDArray

from studio.geometry.base import pixel_to_angles
from studio.geometry.equirect import EquirectCamera
from studio.geometry.se import rot_from_rpy
from studio.sim.base import LASER_Z, WALL_HEIGHT

__all__ = [
    "BALL_RADIUS",
    "BOARD_HEIGHT",
    "BOARD_WIDTH",
    "CHECKER_SQUARE",
    "CHECKER_SQUARES",
    "ROOM",
    "SUPERSAMPLE",
    "cached_background",
    "render_target",
    "room_background",
]

FloatArray = NDArray[np.float64]

BALL_RADIUS = 0.25
BALL_BGR = np.array([25.0, 95.0, 235.0])
BOARD_WIDTH = 0.80
BOARD_HEIGHT = (0.0, 0.80)
"""Bottom and top of the board above the floor, m; green below :data:`LASER_Z`, white above."""
BOARD_GREEN = np.array([60.0, 165.0, 40.0])
BOARD_WHITE = np.array([238.0, 240.0, 240.0])
CHECKER_SQUARES = (9, 6)
"""Squares along the board's width and height (8 × 5 inner corners)."""
CHECKER_SQUARE = 0.07
ROOM = (-4.5, 4.5, -3.5, 3.5)
"""The room's walls ``x0, x1, y0, y1`` in the world (= base) frame, m."""
SUPERSAMPLE = {"ball": 3, "board": 2, "checkerboard": 2}  # supersampling per axis on the target


def _room_colour(o: FloatArray, d: FloatArray) -> FloatArray:
    """Colour (N, 3) BGR of the room (walls, floor, ceiling, robot top) along rays ``d`` (N, 3) from ``o``."""
    x0, x1, y0, y1 = ROOM
    with np.errstate(divide="ignore", invalid="ignore"):
        tx = np.where(d[:, 0] > 0, (x1 - o[0]) / d[:, 0], (x0 - o[0]) / d[:, 0])
        ty = np.where(d[:, 1] > 0, (y1 - o[1]) / d[:, 1], (y0 - o[1]) / d[:, 1])
        tz = np.where(d[:, 2] > 0, (WALL_HEIGHT - o[2]) / d[:, 2], -o[2] / d[:, 2])
    tx, ty, tz = (np.where(np.isfinite(a) & (a > 0), a, np.inf) for a in (tx, ty, tz))
    t = np.minimum(np.minimum(tx, ty), tz)
    p = o + t[:, None] * d
    col = np.empty((d.shape[0], 3))
    wall = (tx <= ty) & (tx <= tz) | (ty < tx) & (ty <= tz)
    along = np.where(tx <= ty, p[:, 1], p[:, 0])
    panel = 0.93 + 0.07 * (np.floor(along / 1.0) % 2)
    base = np.array([185.0, 200.0, 212.0])
    col[:] = base * panel[:, None]
    skirting = wall & (p[:, 2] < 0.1)
    col[skirting] = [110.0, 115.0, 120.0]
    floor = ~wall & (d[:, 2] < 0)
    tile = 0.96 + 0.04 * ((np.floor(p[:, 0] / 0.6) + np.floor(p[:, 1] / 0.6)) % 2)
    col[floor] = (np.array([150.0, 146.0, 140.0]) * tile[:, None])[floor]
    ceil = ~wall & (d[:, 2] > 0)
    col[ceil] = [225.0, 228.0, 230.0]
    # the robot's top (0.70 × 0.60 m at 0.5 m) below the camera
    with np.errstate(divide="ignore", invalid="ignore"):
        tb = (0.5 - o[2]) / d[:, 2]
    pb = o + np.where(tb > 0, tb, np.nan)[:, None] * d
    top = (np.abs(pb[:, 0]) <= 0.35) & (np.abs(pb[:, 1]) <= 0.30)
    col[top] = [52.0, 52.0, 56.0]
    return col


def _target_hits(
    kind: str, par: FloatArray, o: FloatArray, d: FloatArray
) -> tuple[NDArray[np.bool_], FloatArray]:
    """Which rays (N, 3) hit the target and their colour (N, 3) BGR."""
    n = d.shape[0]
    col = np.zeros((n, 3))
    if kind == "ball":
        c = par[:3]
        oc = o - c
        b = d @ oc
        disc = b * b - (oc @ oc - BALL_RADIUS**2)
        hit = disc >= 0
        t = -b - np.sqrt(np.maximum(disc, 0.0))
        nrm = (o + t[:, None] * d - c) / BALL_RADIUS
        light = np.array([0.3, 0.2, 0.93])
        shade = 0.6 + 0.4 * np.clip(nrm @ light, 0.0, 1.0)
        col[:] = BALL_BGR * shade[:, None]
        return hit & (t > 0), col
    if kind == "board":
        c = np.array([par[0], par[1], LASER_Z])
        nrm = np.array([math.cos(par[2]), math.sin(par[2]), 0.0])
        ex = np.array([-nrm[1], nrm[0], 0.0])
        ey = np.array([0.0, 0.0, 1.0])
        half, (b0, b1) = BOARD_WIDTH / 2, (BOARD_HEIGHT[0] - LASER_Z, BOARD_HEIGHT[1] - LASER_Z)
    else:
        c, ex, ey, nrm = _checker_frame(par)
        sq = CHECKER_SQUARE
        half = (CHECKER_SQUARES[0] + 1) * sq / 2
        b0, b1 = -(CHECKER_SQUARES[1] + 1) * sq / 2, (CHECKER_SQUARES[1] + 1) * sq / 2
    den = d @ nrm
    with np.errstate(divide="ignore", invalid="ignore"):
        t = ((c - o) @ nrm) / den
    p = o + np.where(np.isfinite(t), t, 0.0)[:, None] * d - c
    a, b = p @ ex, p @ ey
    hit = np.isfinite(t) & (t > 0) & (np.abs(a) <= half) & (b >= b0) & (b <= b1)
    if kind == "board":
        col[:] = np.where((b < 0)[:, None], BOARD_GREEN, BOARD_WHITE)
    else:
        sq = CHECKER_SQUARE
        nx, ny = CHECKER_SQUARES
        i = np.floor(a / sq + nx / 2)
        j = np.floor(b / sq + ny / 2)
        inside = (i >= 0) & (i < nx) & (j >= 0) & (j < ny)
        black = inside & ((i + j) % 2 == 0)
        col[:] = np.where(black[:, None], 25.0, 235.0)
    return hit, col


def _checker_frame(par: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Centre and axes (along the width, along the height, normal) of the checkerboard ``x, y, z, tilt_a,
    tilt_b, yaw``: normal heading ``yaw`` (horizontal), then tilted about its width and height axes."""
    yaw = par[5]
    r0 = np.array(
        [[-math.sin(yaw), 0.0, math.cos(yaw)], [math.cos(yaw), 0.0, math.sin(yaw)], [0.0, 1.0, 0.0]]
    )
    r = r0 @ rot_from_rpy(float(par[3]), float(par[4]), 0.0)
    return np.asarray(par[:3], dtype=np.float64), r[:, 0], r[:, 1], r[:, 2]


def _bound(kind: str, par: FloatArray) -> tuple[FloatArray, float]:
    """Bounding sphere (centre, radius) of the target, metres."""
    if kind == "ball":
        return par[:3].copy(), BALL_RADIUS
    if kind == "board":
        zc = 0.5 * (BOARD_HEIGHT[0] + BOARD_HEIGHT[1])
        return np.array([par[0], par[1], zc]), math.hypot(
            BOARD_WIDTH / 2, (BOARD_HEIGHT[1] - BOARD_HEIGHT[0]) / 2
        )
    return par[:3].copy(), math.hypot(CHECKER_SQUARES[0] + 1, CHECKER_SQUARES[1] + 1) * CHECKER_SQUARE / 2


def room_background(cam: EquirectCamera) -> NDArray[np.uint8]:
    """The room without the target, as seen by ``cam`` (robot at the world origin)."""
    v, u = np.mgrid[0 : cam.height, 0 : cam.width]
    az, el = pixel_to_angles(u.ravel() + 0.5, v.ravel() + 0.5, cam.width, cam.height)
    ce = np.cos(el)
    rays = np.stack([ce * np.cos(az), ce * np.sin(az), np.sin(el)], axis=1) @ cam.pose.R.T
    img = np.clip(np.rint(_room_colour(cam.pose.t, rays)), 0, 255).astype(np.uint8)
    return img.reshape(cam.height, cam.width, 3)


def render_target(
    kind: str, par: FloatArray, bg: NDArray[np.uint8], cam: EquirectCamera
) -> NDArray[np.uint8]:
    """The panorama with the target composited over the background (coverage from 3 × 3 subsamples)."""
    H, W = bg.shape[:2]
    img = bg.copy()
    centre, rad = _bound(kind, par)
    rng = np.random.default_rng(0)
    sph = rng.normal(size=(400, 3))
    sph = centre + 1.05 * rad * sph / np.linalg.norm(sph, axis=1, keepdims=True)
    uv, _ = cam.project(np.vstack([centre, sph]))
    du = (uv[1:, 0] - uv[0, 0] + W / 2) % W - W / 2
    c0 = math.floor(uv[0, 0] + du.min()) - 3
    c1 = math.ceil(uv[0, 0] + du.max()) + 3
    r0 = max(math.floor(uv[:, 1].min()) - 3, 0)
    r1 = min(math.ceil(uv[:, 1].max()) + 3, H)
    cols = np.arange(c0, c1)
    rows = np.arange(r0, r1)
    ss = SUPERSAMPLE[kind]
    off = (np.arange(ss) + 0.5) / ss
    uu = (cols[None, :, None, None] + off[None, None, None, :]) + 0 * rows[:, None, None, None]
    vv = (rows[:, None, None, None] + off[None, None, :, None]) + 0 * uu
    uu = np.broadcast_to(uu, vv.shape)
    az, el = pixel_to_angles(uu.ravel(), vv.ravel(), W, H)
    ce = np.cos(el)
    rays = np.stack([ce * np.cos(az), ce * np.sin(az), np.sin(el)], axis=1) @ cam.pose.R.T
    hit, col = _target_hits(kind, par, cam.pose.t, rays)
    shape = (rows.size, cols.size, ss * ss)
    hit = hit.reshape(shape)
    col = col.reshape((*shape, 3))
    cov = hit.mean(axis=2)
    tgt = (col * hit[..., None]).sum(axis=2) / np.maximum(hit.sum(axis=2), 1)[..., None]
    ci = cols % W
    win = img[r0:r1][:, ci].astype(np.float64)
    win = cov[..., None] * tgt + (1.0 - cov[..., None]) * win
    img[r0:r1, ci] = np.clip(np.rint(win), 0, 255).astype(np.uint8)
    return img


@functools.lru_cache(maxsize=4)
def cached_background(cam: EquirectCamera) -> NDArray[np.uint8]:
    """:func:`room_background` of ``cam``, cached (the last 4 cameras) and read-only."""
    img = room_background(cam)
    img.setflags(write=False)
    return img
