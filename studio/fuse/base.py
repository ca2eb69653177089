"""Contract of fusion: people as positions with covariance and provenance, in the robot base frame."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from studio.detect.laser.base import KIND_PAIR

__all__ = ["HOW", "SOURCES", "FusionConfig", "PersonObservations", "ScanRays"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

SOURCES = ("fused", "laser", "image")
"""``fused``: a person box confirmed by laser; ``laser``: laser only; ``image``: image only."""

HOW = ("laser-detection", "scan-cluster", "foot-row", "torso-size", "laser-only", "beside-box")
"""How a position was measured: a laser people detection inside the box; the scan points inside the box
closest to the robot; the box's foot row on the ground plane; the apparent torso length; a laser detection
that no box confirmed; a laser detection that no box took, beside the one a box took, inside that box and at
its range (two people side by side often make one box: the camera saw someone there)."""


@dataclass(frozen=True)
class FusionConfig:
    """Association and uncertainty parameters (metres, radians, pixels).

    Attributes:
        foot_kpt_min_score: ankle keypoints at or above this score give the foot row.
        ankle_height: height of the ankle keypoint above the floor, m.
        foot_sigma_px: 1-σ of the foot row, px at 1920 px width (scaled with the panorama width).
        bearing_sigma_frac: 1-σ of the bearing as a fraction of the box width.
        torso_length: shoulder-to-hip length used for the size cue, m.
        torso_rel_sigma: relative 1-σ of the size-cue range.
        gate_sigma: association gate on the range difference, in standard deviations.
        gate_range_min: the range gate is never narrower than this, m.
        box_margin_frac: a laser detection may lie this fraction of the box width outside the box.
        cluster_core_frac: the scan-cluster fallback looks at this central fraction of the box width.
        cluster_gap: scan points closer than this in range belong to one cluster, m.
        cluster_min_points: smallest scan cluster that counts as a person.
        leg_radius: distance from a leg's visible surface to its centre, m.
        laser_sigma: 1-σ (per axis) of a laser person made of a leg pair, m.
        leg_sigma: 1-σ of a person seen as a single leg or a blob, m. A walker's legs are up to half a
            stride (≈ 0.3 m) in front of or behind the body, so one leg says less than a pair; measured on
            simulated walkers (``moving``, seeds 1–2): pairs 0.04–0.05 m, single legs 0.10–0.12 m, blobs
            0.10–0.13 m per axis.
        cluster_sigma: 1-σ of a scan-cluster position, m.
        same_person_radius: a laser detection no box took, inside the span of a box that took one and this
            close to it, is that person's other leg (or a part of them), not someone else, m.
        beside_box_range: a laser detection no box took, farther than ``same_person_radius`` from the one a
            box took but inside that box's span and within this range difference of it, is someone beside
            that person whom the camera saw in the same box (``how`` ``beside-box``: it counts as seen by
            the camera, see ``LabelOptions.min_camera_hits``), m; 0 turns this off.
        static_behind: a laser detection on never-moving structure is not taken by a box whose central
            columns (``cluster_core_frac``) hold at least ``cluster_min_points`` moving scan points this much
            nearer than it, m (0: no such check). The laser missed the person there, and what it found
            behind them is the wall seen between their legs; the box falls back to the nearer scan
            cluster, the person. Session 22 (``docs/results.md``): simulated ``moving`` seeds 1–8 with the
            camera F1 0.947 → 0.951, a track on such wall pieces for 11 s gone (seed 7).
        static_gate_sigma: a laser detection on never-moving structure is taken by a box only when their
            ranges differ by at most this many standard deviations (``gate_range_min`` does not widen it).
            Someone who stood still for the whole recording looks static, and their box's range agrees with
            the laser's; a far or loose box whose wide gate reaches a door frame or a pillar does not.
            Session 56 (``docs/results.md``): on simulated ``moving`` seeds 1–10 and 23, boxes took 75
            static laser detections; the 66 on a person lay within 1.4 σ, 4 of the 9 off anyone beyond 2.5 σ.
        see_through_halfwidth: an image-only position is dropped when the laser saw through it: the beams
            (:class:`ScanRays`) that pass within this distance of it cover at least ``see_through_span`` of
            that width, there are at least ``cluster_min_points`` of them, and every one ended beyond the
            farthest range the box allows (its range gate), m; 0 turns this off. The legs of someone standing
            there would have stopped some of them: such a box is a loose box on someone farther away (its
            bottom row below their feet), or no person. Narrow, so that an edge beside the person (a door
            frame they are seen through) is not in the way; with the coverage test, a window the scanner
            sees only part of (the edge of its field of view) says nothing. Session 36
            (``docs/results.md``): on simulated ``moving`` seeds 1–20 it drops 46 of 560 image-only
            positions, none within 0.2 m of a person (7 within 0.5 m).
        see_through_span: see ``see_through_halfwidth`` (a fraction of the window).
        nearer_laser: a box the range gate kept from every laser person takes one that no box took, nearer
            than the box's range and inside it (the one nearest its centre; never one on never-moving
            structure): the foot row was read too far. Session 54 (``docs/results.md``): on simulated
            ``moving`` seeds 1–10 and 35, of the image-only positions with such a laser person in their
            box, 56 of 57 lay more than 0.5 m from anyone, 50 of them with nobody else in the box.
        max_range: ignore people farther than this from the camera, m.
        floor_z: height of the floor in the base frame, m.
        head_top_z: nothing of a person is higher than this above the floor (a tall person's raised hands),
            m. A box's top row then bounds the person's range (``BoxRange.max_range``): a box whose feet
            are hidden (range ``none``) takes no laser person or scan cluster beyond it, times
            ``head_top_margin``. Someone next to the robot is tall in the image and their feet are hidden
            by its body; the laser person on their bearing may be someone 5 m behind them, whose clothes
            the box does not show (session 70, ``docs/results.md``).
        head_top_margin: see ``head_top_z``.
    """

    foot_kpt_min_score: float = 0.3
    ankle_height: float = 0.08
    foot_sigma_px: float = 4.0
    bearing_sigma_frac: float = 0.15
    torso_length: float = 0.5
    torso_rel_sigma: float = 0.3
    gate_sigma: float = 3.0
    gate_range_min: float = 0.6
    box_margin_frac: float = 0.15
    cluster_core_frac: float = 0.6
    cluster_gap: float = 0.3
    cluster_min_points: int = 3
    leg_radius: float = 0.06
    laser_sigma: float = 0.05
    leg_sigma: float = 0.11
    cluster_sigma: float = 0.10
    same_person_radius: float = 0.5
    beside_box_range: float = 0.5
    static_behind: float = 0.3
    static_gate_sigma: float = 2.0
    see_through_halfwidth: float = 0.1
    see_through_span: float = 0.8
    nearer_laser: bool = True
    max_range: float = 12.0
    floor_z: float = 0.0
    head_top_z: float = 2.3
    head_top_margin: float = 1.25

    def laser_sigmas(self, kind: NDArray[np.int64]) -> FloatArray:
        """1-σ of laser people of the given kinds (:data:`studio.detect.laser.base.KIND_PAIR` …), m."""
        return np.where(np.asarray(kind) == KIND_PAIR, self.laser_sigma, self.leg_sigma)


@dataclass(frozen=True)
class ScanRays:
    """A frame's laser beams that returned, in the base frame: the free space they saw.

    Attributes:
        origin: ``(M, 2)`` where each beam starts (its scanner), metres.
        end: ``(M, 2)`` where it returned, metres.
    """

    origin: FloatArray
    end: FloatArray

    def seen_through(
        self, xy: FloatArray, beyond: float, halfwidth: float, span: float, min_beams: int
    ) -> bool:
        """Did the beams pass ``xy`` by at most ``halfwidth`` and all end more than ``beyond`` past it?

        Only beams whose bearing (from their scanner) lies within ``atan(halfwidth / distance)`` of the
        point's count; they must be at least ``min_beams`` and span at least ``span`` of that window."""
        if not len(self.end):
            return False
        q = np.asarray(xy, dtype=np.float64)[None, :] - self.origin
        v = self.end - self.origin
        rho = np.hypot(q[:, 0], q[:, 1])
        dang = (np.arctan2(v[:, 1], v[:, 0]) - np.arctan2(q[:, 1], q[:, 0]) + np.pi) % (2 * np.pi) - np.pi
        half = np.arctan2(halfwidth, np.maximum(rho, 1e-6))
        sel = np.abs(dang) <= half
        if np.count_nonzero(sel) < max(min_beams, 1):
            return False
        if np.ptp(dang[sel]) < span * 2.0 * float(np.mean(half[sel])):
            return False
        return bool(np.all(np.hypot(v[sel, 0], v[sel, 1]) > rho[sel] + beyond))


@dataclass(frozen=True)
class PersonObservations:
    """People measured in one frame, N of them, positions in the base frame.

    Attributes:
        xy: ``(N, 2)`` metres.
        cov: ``(N, 2, 2)`` m², position covariance.
        score: ``(N,)`` in [0, 1].
        source: N strings of :data:`SOURCES`.
        how: N strings of :data:`HOW`.
        box: ``(N, 4)`` panorama box ``u1, v1, u2, v2`` in px (NaN rows when no box).
        box_index: ``(N,)`` index of the image detection, -1 when none.
        laser_index: ``(N,)`` index of the laser detection, -1 when none.
    """

    xy: FloatArray
    cov: FloatArray
    score: FloatArray
    source: tuple[str, ...]
    how: tuple[str, ...]
    box: FloatArray
    box_index: IntArray
    laser_index: IntArray

    def __post_init__(self) -> None:
        xy = np.asarray(self.xy, dtype=np.float64).reshape(-1, 2)
        n = len(xy)
        cov = np.asarray(self.cov, dtype=np.float64).reshape(n, 2, 2)
        score = np.asarray(self.score, dtype=np.float64).reshape(n)
        box = np.asarray(self.box, dtype=np.float64).reshape(n, 4)
        bi = np.asarray(self.box_index, dtype=np.int64).reshape(n)
        li = np.asarray(self.laser_index, dtype=np.int64).reshape(n)
        if len(self.source) != n or len(self.how) != n:
            raise ValueError("PersonObservations: source and how need one entry per person")
        if not set(self.source) <= set(SOURCES) or not set(self.how) <= set(HOW):
            raise ValueError(f"PersonObservations: unknown source/how {set(self.source)} {set(self.how)}")
        if not np.all(np.isfinite(xy)) or not np.all(np.isfinite(cov)):
            raise ValueError("PersonObservations: xy and cov must be finite")
        for name, val in (("xy", xy), ("cov", cov), ("score", score), ("box", box)):
            object.__setattr__(self, name, val)
        object.__setattr__(self, "box_index", bi)
        object.__setattr__(self, "laser_index", li)
        object.__setattr__(self, "source", tuple(self.source))
        object.__setattr__(self, "how", tuple(self.how))

    def __len__(self) -> int:
        return len(self.xy)

    @staticmethod
    def empty() -> PersonObservations:
        return PersonObservations(
            np.zeros((0, 2)),
            np.zeros((0, 2, 2)),
            np.zeros(0),
            (),
            (),
            np.zeros((0, 4)),
            np.zeros(0, np.int64),
            np.zeros(0, np.int64),
        )

    @staticmethod
    def concat(parts: list[PersonObservations]) -> PersonObservations:
        parts = [p for p in parts if len(p)]
        if not parts:
            return PersonObservations.empty()
        return PersonObservations(
            np.concatenate([p.xy for p in parts]),
            np.concatenate([p.cov for p in parts]),
            np.concatenate([p.score for p in parts]),
            tuple(s for p in parts for s in p.source),
            tuple(s for p in parts for s in p.how),
            np.concatenate([p.box for p in parts]),
            np.concatenate([p.box_index for p in parts]),
            np.concatenate([p.laser_index for p in parts]),
        )
