"""Analytic 2D laser ray casting: beams × wall segments + cylinders (pillars, furniture legs, people's legs).

Returns follow REP-117: a beam that hits nothing within ``range_max`` reads ``+inf``; a *dropout* (no
return although something is there: dark or thin objects, grazing incidence, far targets) and a beam
that hits the robot's own body read ``NaN``. Both count as invalid in :meth:`studio.io.base.LaserScan.valid`.
Ranges get Gaussian noise of ``noise_sigma``.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from studio.io.base import upside_down
from studio.sim.base import LASER_Z, LaserSpec, SimRig, World

__all__ = ["LaserCaster", "ScanResult"]

FloatArray = NDArray[np.floating[Any]]

_P_WALL = 0.003  # dropout probability on walls at normal incidence
_P_THIN = 0.06  # on furniture legs
_P_LEG = 0.02  # on people's legs, plus up to 0.08 more for dark trousers

SWEEP_PIECE_S = 0.0025
"""A sweeping scan is cast in pieces of at most this long, seconds (the robot turning at 0.6 rad/s moves a
return 5 m away by under 4 mm within a piece)."""


@dataclass(frozen=True)
class ScanResult:
    """One simulated scan.

    Attributes:
        ranges: (n,) float32 ranges, metres (+inf: nothing in range; NaN: dropout or own body).
        true_ranges: (n,) noise-free ranges of the first hit, metres (inf: nothing).
        person: (n,) index of the person whose leg the beam hit, -1 otherwise.
        person_hits: (P,) number of valid (non-dropout) returns on each person's legs.
    """

    ranges: NDArray[np.float32]
    true_ranges: FloatArray
    person: NDArray[np.int64]
    person_hits: NDArray[np.int64]


def _pairs(
    lo: FloatArray, width: FloatArray, a0: float, inc: float, n: int
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """(object, beam) pairs of beams whose angle lies in each object's interval ``[lo, lo + width]`` (rad)."""
    full = round(2.0 * np.pi / inc)
    rel = np.mod(lo - a0, 2.0 * np.pi)
    i0 = np.ceil(rel / inc - 1e-9).astype(np.int64)
    i1 = np.floor((rel + width) / inc + 1e-9).astype(np.int64)
    counts = np.maximum(i1 - i0 + 1, 0)
    obj = np.repeat(np.arange(lo.shape[0]), counts)
    start = np.cumsum(counts) - counts
    beam = (i0[obj] + np.arange(obj.shape[0]) - start[obj]) % full
    keep = beam < n
    return obj[keep], beam[keep]


def _seg_hits(
    o: FloatArray, seg: FloatArray, ang: FloatArray, a0: float, inc: float
) -> tuple[FloatArray, ...]:
    """Hits of beams on segments: (object, beam, distance, |cos incidence|) for every crossing pair."""
    n = ang.shape[0]
    if seg.shape[0] == 0:
        z = np.zeros(0)
        return z.astype(np.int64), z.astype(np.int64), z, z
    t1 = np.arctan2(seg[:, 1] - o[1], seg[:, 0] - o[0])
    t2 = np.arctan2(seg[:, 3] - o[1], seg[:, 2] - o[0])
    dw = np.mod(t2 - t1, 2.0 * np.pi)
    lo = np.where(dw < np.pi, t1, t2)
    width = np.where(dw < np.pi, dw, 2.0 * np.pi - dw)
    obj, beam = _pairs(lo, width, a0, inc, n)
    d = np.stack([np.cos(ang[beam]), np.sin(ang[beam])], axis=1)
    p1 = seg[obj, :2]
    e = seg[obj, 2:] - p1
    w = p1 - o
    denom = d[:, 0] * e[:, 1] - d[:, 1] * e[:, 0]
    safe = np.where(np.abs(denom) > 1e-12, denom, 1e-12)
    t = (w[:, 0] * e[:, 1] - w[:, 1] * e[:, 0]) / safe
    u = (w[:, 0] * d[:, 1] - w[:, 1] * d[:, 0]) / safe
    ok = (np.abs(denom) > 1e-12) & (t > 1e-6) & (u >= -1e-9) & (u <= 1.0 + 1e-9)
    cos_inc = np.abs(denom) / np.maximum(np.hypot(e[:, 0], e[:, 1]), 1e-12)
    return obj[ok], beam[ok], t[ok], cos_inc[ok]


def _circ_hits(
    o: FloatArray, circ: FloatArray, ang: FloatArray, a0: float, inc: float
) -> tuple[FloatArray, ...]:
    """Hits of beams on circles ``cx, cy, r``: (object, beam, distance, |cos incidence|)."""
    n = ang.shape[0]
    rel = circ[:, :2] - o
    dist = np.hypot(rel[:, 0], rel[:, 1])
    outside = dist > circ[:, 2] + 1e-6
    if not np.any(outside):
        z = np.zeros(0)
        return z.astype(np.int64), z.astype(np.int64), z, z
    idx = np.nonzero(outside)[0]
    phi = np.arctan2(rel[idx, 1], rel[idx, 0])
    half = np.arcsin(np.clip(circ[idx, 2] / dist[idx], 0.0, 1.0))
    k, beam = _pairs(phi - half, 2.0 * half, a0, inc, n)
    obj = idx[k]
    d = np.stack([np.cos(ang[beam]), np.sin(ang[beam])], axis=1)
    oc = -rel[obj]
    b = np.einsum("ij,ij->i", d, oc)
    cc = np.einsum("ij,ij->i", oc, oc) - circ[obj, 2] ** 2
    disc = b * b - cc
    t = -b - np.sqrt(np.maximum(disc, 0.0))
    ok = (disc >= 0.0) & (t > 1e-6)
    hitp = oc + t[:, None] * d
    cos_inc = np.abs(np.einsum("ij,ij->i", hitp, d)) / circ[obj, 2]
    return obj[ok], beam[ok], t[ok], cos_inc[ok]


class LaserCaster:
    """Casts the scans of the rig's lasers in the static world plus people's legs.

    Args:
        world: the static scene (only objects crossing the plane z = LASER_Z count).
        rig: the robot (its body blocks beams).
    """

    def __init__(self, world: World, rig: SimRig) -> None:
        at = (world.seg_z[:, 0] <= LASER_Z) & (world.seg_z[:, 1] >= LASER_Z)
        self.seg = world.seg[at]
        cat = (world.circ_z[:, 0] <= LASER_Z) & (world.circ_z[:, 1] >= LASER_Z)
        self.circ = world.circ[cat]
        self.circ_p = np.where(self.circ[:, 2] < 0.05, _P_THIN, _P_WALL)
        hx, hy = rig.body_length / 2, rig.body_width / 2
        self.body = np.array([[hx, hy, -hx, hy], [-hx, hy, -hx, -hy], [-hx, -hy, hx, -hy], [hx, -hy, hx, hy]])

    def cast_sweep(
        self,
        spec: LaserSpec,
        t: float,
        robot_at: Callable[[float], FloatArray],
        legs_at: Callable[[float], FloatArray],
        dark: FloatArray,
        rng: np.random.Generator | None,
    ) -> ScanResult:
        """One scan stamped ``t`` whose beams leave over ``spec.sweep_s`` (beam i at ``t + i · sweep_s /
        (n − 1)``): cast in pieces of at most :data:`SWEEP_PIECE_S`, each from the robot pose and the people
        of its middle time. Without a sweep, :meth:`cast` at ``t``.

        Args:
            robot_at: true robot pose ``x, y, yaw`` in the world at a time, seconds.
            legs_at: people's leg circles (P, 2, 3) in the world at a time, seconds.
            spec, dark, rng: as :meth:`cast`.
        """
        n = spec.n_beams
        if spec.sweep_s <= 0.0 or n < 2:
            return self.cast(spec, robot_at(t), legs_at(t), dark, rng)
        dt = spec.sweep_s / (n - 1)
        pieces = min(n, int(np.ceil(spec.sweep_s / SWEEP_PIECE_S)))
        edges = np.linspace(0, n, pieces + 1).round().astype(int)
        parts = []
        for j0, j1 in itertools.pairwise(edges):
            tj = t + 0.5 * (j0 + j1 - 1) * dt
            piece = replace(spec, angle_min=spec.angle_min + j0 * spec.angle_increment, n_beams=int(j1 - j0))
            parts.append(self.cast(piece, robot_at(tj), legs_at(tj), dark, rng))
        return ScanResult(
            ranges=np.concatenate([r.ranges for r in parts]),
            true_ranges=np.concatenate([r.true_ranges for r in parts]),
            person=np.concatenate([r.person for r in parts]),
            person_hits=np.sum([r.person_hits for r in parts], axis=0).astype(np.int64),
        )

    def cast(
        self,
        spec: LaserSpec,
        robot: FloatArray,
        legs: FloatArray,
        dark: FloatArray,
        rng: np.random.Generator | None,
    ) -> ScanResult:
        """One scan.

        Args:
            spec: the laser (its pose in the base frame sets the origin and heading).
            robot: true robot pose ``x, y, yaw`` in the world at the scan stamp.
            legs: (P, 2, 3) people's leg circles in the world at the scan stamp.
            dark: (P,) trouser darkness in [0, 1] (dropout rate on the legs).
            rng: noise and dropouts; None gives the noise-free scan without dropouts.

        Returns:
            The :class:`ScanResult`.
        """
        x, y, yaw = (float(v) for v in robot)
        c, s = np.cos(yaw), np.sin(yaw)
        lt = spec.pose.t
        o = np.array([x + c * lt[0] - s * lt[1], y + s * lt[0] + c * lt[1]])
        n = spec.n_beams
        # cast counter-clockwise; a scanner that sweeps clockwise in the base frame (mounted upside down, or
        # a negative angle_increment) gets its beams back in its own order at the end
        sign = -1.0 if upside_down(spec.pose) else 1.0
        backwards = sign * spec.angle_increment < 0
        if backwards:
            last = spec.angle_min + (n - 1) * spec.angle_increment
            a0 = float(sign * last + yaw + spec.pose.to_pose2().yaw)
        else:
            a0 = float(sign * spec.angle_min + yaw + spec.pose.to_pose2().yaw)
        inc = abs(float(spec.angle_increment))
        ang = a0 + inc * np.arange(n)
        body_w = self.body.copy()
        for k in (0, 2):
            bx, by = self.body[:, k], self.body[:, k + 1]
            body_w[:, k], body_w[:, k + 1] = x + c * bx - s * by, y + s * bx + c * by
        n_people = legs.shape[0]
        segs = np.concatenate([self.seg, body_w])
        seg_kind = np.concatenate([np.zeros(len(self.seg), np.int64), np.full(4, 3)])
        circs = np.concatenate([self.circ, legs.reshape(-1, 3)])
        circ_kind = np.concatenate([np.where(self.circ[:, 2] < 0.05, 1, 0), np.full(2 * n_people, 2)])
        circ_p = np.concatenate([self.circ_p, _P_LEG + 0.08 * np.repeat(dark, 2)])
        so, sb, st, sc = _seg_hits(o, segs, ang, a0, inc)
        co, cb, ct, cci = _circ_hits(o, circs, ang, a0, inc)
        beam = np.concatenate([sb, cb])
        t = np.concatenate([st, ct])
        kind = np.concatenate([seg_kind[so], circ_kind[co]])
        pdrop = np.concatenate([np.where(sc < 0.15, 0.5, _P_WALL), np.where(cci < 0.1, 0.5, circ_p[co])])
        who = np.concatenate(
            [np.full(so.shape[0], -1), np.where(co >= len(self.circ), (co - len(self.circ)) // 2, -1)]
        )
        order = np.lexsort((t, beam))
        beam, t, kind, pdrop, who = beam[order], t[order], kind[order], pdrop[order], who[order]
        first = np.ones(beam.shape[0], dtype=bool)
        first[1:] = beam[1:] != beam[:-1]
        b1 = beam[first]
        true = np.full(n, np.inf)
        true[b1] = t[first]
        kinds = np.full(n, -1)
        kinds[b1] = kind[first]
        p = np.zeros(n)
        p[b1] = pdrop[first]
        person = np.full(n, -1)
        person[b1] = who[first]
        hit = true <= spec.range_max
        true = np.where(hit, true, np.inf)
        person = np.where(hit, person, -1)
        ranges = true.copy()
        if rng is not None:
            p = p + np.clip(0.05 * (np.where(hit, true, 0.0) - 8.0), 0.0, None)
            drop = hit & (rng.random(n) < p)
            ranges = ranges + np.where(hit, rng.normal(0.0, spec.noise_sigma, n), 0.0)
            ranges = np.where(hit, np.maximum(ranges, spec.range_min), ranges)
            ranges = np.where(drop, np.nan, ranges)
        else:
            drop = np.zeros(n, dtype=bool)
        ranges = np.where(hit & (kinds == 3), np.nan, ranges)
        person = np.where(drop, -1, person)
        counts = np.bincount(person[person >= 0], minlength=n_people) if n_people else np.zeros(0, np.int64)
        if backwards:
            ranges, true, person = ranges[::-1], true[::-1], person[::-1]
        return ScanResult(
            ranges=ranges.astype(np.float32),
            true_ranges=true,
            person=person,
            person_hits=counts.astype(np.int64),
        )
