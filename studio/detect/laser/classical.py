"""Classical 2D-laser people detector: segments → leg likelihood → leg pairs, single legs and blobs.

1. :func:`~studio.detect.laser.segment.segment_scan` splits the scan over its valid returns with a
   range-adaptive jump distance (missing beams, common on dark trousers, never split a segment).
2. Shape features per segment (width, extent, line / circle fit, bulge toward the sensor, occlusion by
   the neighbours, coverage of valid returns; jaggedness and turning of the outline averaged over ~3 cm,
   so range noise on the dense returns of a nearby leg is not read as a rough surface) go through a
   logistic model on a hinge basis (a generalised additive model) whose coefficients were fitted on the
   labelled scans of ``leg_tracker`` (``bench/laser_sweep.py`` reproduces them); no weights are downloaded.
   Scans with coarser beams than those (≥ 0.38° apart, e.g. 1° low-cost lidars: two returns on a leg 3 m away)
   are segmented from two returns on and scored by a second model fitted on the same scans thinned to
   0.70° and 1.05° beams.
3. Legs 0.1–0.6 m apart pair into one person at their midpoint; wide person-like segments are one
   person (legs together, skirts, coats); unpaired legs are persons with a lower score.
4. Over time (:meth:`ClassicalLaserDetector.detect_remembering`), legs are followed from scan to scan and
   two legs that the scans before mostly kept apart stay apart (:class:`LegMemory`): where the legs of two
   people stand in a row 0.2 m apart, one scan alone cannot tell whose leg is whose, the scans before can.

Several scanners: :meth:`ClassicalLaserDetector.detect_scans` detects per scan (each in the common frame
with its sensor origin) and merges detections closer than ``merge_radius``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import linear_sum_assignment

from studio.detect.laser.base import KIND_BLOB, KIND_LEG, KIND_PAIR, LaserDetections, merge_detections
from studio.detect.laser.errors import LaserDetectorError
from studio.detect.laser.segment import (
    FEATURE_NAMES,
    SegmentParams,
    estimate_angle_step,
    segment_features,
    segment_scan,
)

__all__ = ["LEG_MODEL", "LEG_MODEL_COARSE", "ClassicalLaserDetector", "LegMemory", "LegModel", "leg_basis"]

FloatArray = NDArray[np.float64]

# feature columns of segment_features used by the basis, and the hinge knots of each (metres unless noted)
_BASIS: tuple[tuple[int, tuple[float, ...]], ...] = (
    (1, (0.05, 0.1, 0.15, 0.2, 0.3, 0.45)),  # width
    (10, (0.03, 0.06, 0.1, 0.15, 0.25)),  # extent
    (3, (0.005, 0.01, 0.02, 0.04)),  # line residual
    (4, (0.05, 0.08, 0.12, 0.2, 0.4)),  # circle radius (clipped at 0.5)
    (5, (0.003, 0.01, 0.02, 0.04)),  # circle residual
    (6, (-0.02, 0.0, 0.01, 0.02, 0.04)),  # bulge
    (7, (-0.3, 0.0, 0.1, 0.3, 0.6)),  # occlusion min
    (8, (-0.3, 0.0, 0.3, 0.9)),  # occlusion max
    (9, (0.8, 0.9, 0.95)),  # coverage (fraction)
    (11, (1.1, 1.3, 1.6, 2.0, 3.0)),  # jaggedness (ratio)
    (12, (0.3, 0.6, 0.8, 0.95)),  # incidence (|cos|)
    (13, (0.1, 0.2, 0.4, 0.8)),  # turning, rad
    (14, (-0.2, 0.0, 0.1, 0.2, 0.4)),  # signed turning, rad
)


def leg_basis(features: FloatArray) -> FloatArray:
    """Hinge basis of segment features: per feature ``v`` and ``max(v − knot, 0)`` for each knot.

    Args:
        features: ``(S, F)`` from :func:`~studio.detect.laser.segment.segment_features`.

    Returns:
        ``(S, B)`` float64 basis.
    """
    f = np.asarray(features, dtype=np.float64).reshape(-1, len(FEATURE_NAMES))
    cols = []
    for col, knots in _BASIS:
        v = f[:, col]
        if col == 4:
            v = np.minimum(v, 0.5)
        cols.append(v)
        cols.extend(np.maximum(v - k, 0.0) for k in knots)
    return np.column_stack(cols) if f.shape[0] else np.zeros((0, sum(1 + len(k) for _, k in _BASIS)))


@dataclass(frozen=True)
class LegModel:
    """Logistic leg likelihood on the standardised hinge basis ``x``.

    ``p = sigmoid(((x − mean) / std) · coef + bias)``.
    """

    mean: tuple[float, ...]
    std: tuple[float, ...]
    coef: tuple[float, ...]
    bias: float

    def __call__(self, features: FloatArray) -> FloatArray:
        """Leg probability ``(S,)`` of segment features ``(S, F)``."""
        x = leg_basis(features)
        if x.shape[0] == 0:
            return np.zeros(0)
        z = (x - np.asarray(self.mean)) / np.asarray(self.std) @ np.asarray(self.coef) + self.bias
        return 1.0 / (1.0 + np.exp(-np.clip(z, -50.0, 50.0)))


# fitted by `bench/laser_sweep.py` on legs_labelled (positives) + negative_2 and the non-person
# segments outside the labelled wedge (negatives), class-balanced, L2 1e-3
# fmt: off
LEG_MODEL = LegModel(
    mean=(
        0.383127, 0.334759, 0.293483, 0.259814, 0.232914, 0.189453, 0.140925, 0.210438, 0.181527,
        0.157193, 0.132749, 0.110273, 0.078208, 0.013959, 0.009927, 0.00749, 0.005091, 0.002987,
        0.259524, 0.212099, 0.187719, 0.159634, 0.113401, 0.031121, 0.016995, 0.014647, 0.010824,
        0.007722, 0.00448, 0.002986, 0.027242, 0.00975, 0.005742, 0.003876, 0.002343, -0.076983,
        0.445206, 0.295254, 0.252246, 0.179755, 0.094412, 0.580381, 0.917021, 0.65447, 0.424549,
        0.056988, 0.987173, 0.189063, 0.092411, 0.045608, 1.08045, 0.052252, 0.016658, 0.003799,
        0.001138, 0.000196, 0.364569, 0.158862, 0.051726, 0.015206, 0.001707, 0.335027, 0.243651,
        0.164952, 0.071511, 0.018433, 0.077699, 0.28808, 0.106635, 0.069959, 0.050012, 0.028297,
    ),
    std=(
        0.449599, 0.448338, 0.442257, 0.431998, 0.418674, 0.389328, 0.344267, 0.260393, 0.259601,
        0.255928, 0.247075, 0.233245, 0.204572, 0.022055, 0.021552, 0.020519, 0.01813, 0.013755,
        0.185614, 0.18247, 0.176256, 0.164178, 0.133753, 0.045464, 0.028525, 0.028166, 0.026731,
        0.024285, 0.019822, 0.038308, 0.023912, 0.022211, 0.020156, 0.01817, 0.014835, 0.756752,
        0.529024, 0.413879, 0.374348, 0.292931, 0.167421, 0.572264, 0.48852, 0.425845, 0.329025,
        0.049395, 0.049741, 0.038929, 0.024921, 0.013769, 0.209146, 0.132527, 0.087201, 0.054358,
        0.035461, 0.01563, 0.303984, 0.222196, 0.110747, 0.045452, 0.008205, 0.268046, 0.258823,
        0.242052, 0.189873, 0.102462, 0.268534, 0.244177, 0.231521, 0.207152, 0.182915, 0.141368,
    ),
    coef=(
        -0.0225, -0.089442, -0.620216, -0.344323, -0.183255, -0.512957, -0.536043, 0.152395, 0.084102,
        0.010552, 0.358906, 0.036298, -0.187688, 0.402003, 0.307306, 0.150159, -0.490487, -0.704833,
        0.213409, -0.359415, -0.924964, -1.363319, 0.17645, 0.624887, -0.823179, -1.103643, 0.774272,
        0.77046, -0.683693, 0.652061, 0.262332, 0.748665, -0.850067, -0.758847, -0.453711, 0.643701,
        -0.423089, -0.23737, -0.40305, -1.340451, 1.178053, 0.174348, -0.464756, -0.188152, 0.01236,
        1.602771, 0.51432, -0.635783, -0.51472, 0.352193, 1.139383, 0.369184, -0.618132, -0.220474,
        0.191715, -0.107729, 0.112297, -0.207164, -0.004656, -0.744812, -0.090267, -1.291671, -0.825949,
        0.636041, 0.366447, 0.018023, 0.619034, 0.199987, -0.970675, -0.846987, 0.527173, -0.049083,
    ),
    bias=-3.389496,
)
# fmt: on

# fitted by `bench/laser_sweep.py --thin 2 3 --min-points 2` on the same scans with every 2nd / 3rd beam only
# (0.70° / 1.05° beams, as a coarser scanner sees them), segments from two returns on: the leg model for scans
# with beams at least `coarse_step_deg` apart
# fmt: off
LEG_MODEL_COARSE = LegModel(
    mean=(
        0.390672, 0.342496, 0.302471, 0.270022, 0.243116, 0.198543, 0.149013, 0.211037, 0.182409,
        0.159336, 0.135796, 0.113001, 0.080348, 0.013071, 0.009838, 0.007815, 0.005491, 0.003022,
        0.361687, 0.313185, 0.285895, 0.251817, 0.189323, 0.056685, 0.014174, 0.012472, 0.009596,
        0.007131, 0.004287, 0.000866, 0.024606, 0.00719, 0.004378, 0.003093, 0.001916, -0.064736,
        0.464148, 0.315394, 0.271009, 0.195566, 0.104944, 0.588482, 0.93339, 0.676556, 0.442799,
        0.059313, 0.983801, 0.185978, 0.09064, 0.044719, 1.058084, 0.040032, 0.015504, 0.006831,
        0.003203, 0.000602, 0.374578, 0.159749, 0.04669, 0.011044, 0.00084, 0.266886, 0.196216,
        0.140727, 0.072548, 0.023093, 0.053336, 0.270123, 0.093718, 0.063777, 0.046695, 0.027691,
    ),
    std=(
        0.454314, 0.452888, 0.445813, 0.434464, 0.420649, 0.390681, 0.343736, 0.256447, 0.25543,
        0.250811, 0.241024, 0.226638, 0.196412, 0.022696, 0.02181, 0.020587, 0.018003, 0.013434,
        0.177106, 0.174317, 0.16962, 0.160001, 0.134054, 0.048736, 0.028705, 0.028099, 0.026459,
        0.024002, 0.019655, 0.033983, 0.02186, 0.020212, 0.018161, 0.016313, 0.013231, 0.778678,
        0.545834, 0.426846, 0.386775, 0.303725, 0.173614, 0.595625, 0.494966, 0.420597, 0.323528,
        0.048963, 0.05569, 0.044699, 0.027703, 0.015066, 0.209245, 0.148561, 0.115448, 0.086451,
        0.061172, 0.024372, 0.289742, 0.211195, 0.10003, 0.036833, 0.005665, 0.316315, 0.294379,
        0.268212, 0.213167, 0.127856, 0.283119, 0.24779, 0.23227, 0.208066, 0.185076, 0.145745,
    ),
    coef=(
        -0.741276, -0.97971, -1.143304, -0.443105, -0.167878, -0.424505, -0.246865, -0.381392, -0.588203,
        -0.342498, 0.250166, -0.076387, -0.078456, 0.546908, 0.590241, 0.141209, -0.77083, -0.646033,
        1.14419, 0.15692, -0.66395, -1.512993, -0.379929, 0.261227, -0.372006, -0.109494, 0.995112,
        0.370278, -0.757206, 0.525465, -0.005431, 0.323737, -0.610857, -0.351992, 0.011432, 0.876948,
        -0.192287, -0.277732, -0.301755, -1.402325, 0.981166, 0.147054, -0.464588, -0.268072, -0.010543,
        1.756977, 0.370339, -0.618766, -0.30578, 0.220454, 1.479239, -0.49607, -0.303669, -0.491451,
        -0.064511, -0.000229, 0.133599, -0.241128, -0.30558, -0.567985, -0.063034, -0.503561, -0.365757,
        -0.08283, 0.243126, -0.080639, 0.080289, 0.277465, -0.194649, -0.566821, 0.057523, 0.336754,
    ),
    bias=-4.07916,
)
# fmt: on


def _along_beam(xy: FloatArray, origin: ArrayLike) -> FloatArray:
    """(N, 2) unit vectors from the sensor at ``origin`` towards each point (zero for a point on it)."""
    d = np.asarray(xy, dtype=np.float64).reshape(-1, 2) - np.asarray(origin, dtype=np.float64).reshape(1, 2)
    n = np.hypot(d[:, 0], d[:, 1])[:, None]
    return np.divide(d, n, out=np.zeros_like(d), where=n > 0)


_FORGET = 0.9  # per scan: what the scans before say fades over about ten scans (1 s at 10 Hz)


@dataclass(frozen=True)
class LegMemory:
    """The legs of one scanner's last scan, in a frame fixed to the world, followed from scan to scan, and how
    often each two of them were paired when they could have been.

    Where the legs of two people stand in a row about 0.2 m apart (people side by side), one scan cannot
    tell whose leg is whose: as soon as one leg hides, the two left (one of each) make one person between
    the two. The scans before can tell. Each scan is also paired on its own, and for every two legs seen
    within pairing distance the memory counts how often that pairing joined them (counts fade by
    :data:`_FORGET` per scan). Two legs that were mostly apart are not paired now, and two that
    were mostly paired are preferred (:attr:`ClassicalLaserDetector.memory_keep`). The counts come from
    each scan's own pairing, not from the pairing the memory chose, so one wrong choice is not kept alive
    by itself.

    Attributes:
        xy: ``(M, 2)`` leg positions in the fixed frame (odometry), metres.
        seen: ``(M, M)`` for each two legs, the (faded) number of scans in which both were seen within
            pairing distance.
        joined: ``(M, M)`` of those, the (faded) number in which each scan's own pairing joined them.
    """

    xy: FloatArray
    seen: FloatArray
    joined: FloatArray

    @staticmethod
    def empty() -> LegMemory:
        return LegMemory(np.zeros((0, 2)), np.zeros((0, 0)), np.zeros((0, 0)))

    def follow(self, xy: FloatArray, radius: float) -> NDArray[np.int64]:
        """``(N,)`` for each leg at ``xy`` (``(N, 2)``, fixed frame), the leg of the last scan it is: the
        nearest within ``radius`` metres, one to one; -1 for a new leg."""
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        was = np.full(len(xy), -1, dtype=np.int64)
        if len(xy) and len(self.xy) and radius > 0:
            d = np.hypot(*(xy[:, None, :] - self.xy[None, :, :]).transpose(2, 0, 1))
            rows, cols = linear_sum_assignment(np.where(d <= radius, d, 1e6))
            ok = d[rows, cols] <= radius
            was[rows[ok]] = cols[ok]
        return was

    def _carried(self, was: NDArray[np.int64]) -> tuple[FloatArray, FloatArray]:
        """The counts of the legs ``was`` points at (zero for new legs), ``(N, N)`` each."""
        n = len(was)
        seen, joined = np.zeros((n, n)), np.zeros((n, n))
        old = np.flatnonzero(was >= 0)
        if old.size:
            sub = np.ix_(old, old)
            seen[sub] = self.seen[np.ix_(was[old], was[old])]
            joined[sub] = self.joined[np.ix_(was[old], was[old])]
        return seen, joined

    def relations(
        self, was: NDArray[np.int64], *, min_seen: float, share: float
    ) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
        """``apart`` and ``together``, ``(N, N)`` over legs that were the legs ``was`` of the last scan
        (:meth:`follow`): two legs seen within pairing distance in at least ``min_seen`` (faded) scans and
        joined in at most a ``share`` / at least ``1 - share`` of them."""
        seen, joined = self._carried(was)
        known = seen >= min_seen
        return known & (joined <= share * seen), known & (joined >= (1.0 - share) * seen)

    def after(
        self, xy: FloatArray, was: NDArray[np.int64], in_range: NDArray[np.bool_], paired: NDArray[np.bool_]
    ) -> LegMemory:
        """The memory after a scan with legs at ``xy`` that were the legs ``was`` of the last scan:
        ``in_range`` and ``paired`` ``(N, N)`` say which two were within pairing distance and which two the
        scan's own pairing joined."""
        seen, joined = self._carried(was)
        return LegMemory(
            np.asarray(xy, dtype=np.float64).reshape(-1, 2),
            _FORGET * seen + in_range,
            _FORGET * joined + (in_range & paired),
        )


_EXACT_PAIRING_MAX = 10  # legs in one group of pairable legs searched exhaustively


def _pairing(a: NDArray[np.int64], b: NDArray[np.int64], score: FloatArray, dist: FloatArray) -> list[int]:
    """Which candidate pairs ``(a[k], b[k])`` of legs to form (indices ``k``), no leg in two pairs.

    Each group of legs linked by candidate pairs is explained with as many pairs as possible — every
    person has two legs, so two people standing side by side are four legs and two pairs, not one pair
    of their inner legs with two single legs beside it — and among those with the highest
    ``Σ (pair score − leg distance in metres)``: likely legs, close together. Groups larger than
    :data:`_EXACT_PAIRING_MAX` legs (clutter) are paired greedily by score.
    """
    if a.size == 0:
        return []
    legs = np.unique(np.concatenate([a, b]))
    group = {int(v): int(v) for v in legs}

    def root(v: int) -> int:
        while group[v] != v:
            group[v] = group[group[v]]
            v = group[v]
        return v

    for i, j in zip(a.tolist(), b.tolist(), strict=True):
        group[root(i)] = root(j)
    members: dict[int, list[int]] = {}
    for k in range(a.size):
        members.setdefault(root(int(a[k])), []).append(k)
    chosen: list[int] = []
    for ks in members.values():
        n_legs = len({int(a[k]) for k in ks} | {int(b[k]) for k in ks})
        if n_legs > _EXACT_PAIRING_MAX:
            used: set[int] = set()
            for k in sorted(ks, key=lambda k: -score[k]):
                if a[k] not in used and b[k] not in used:
                    used.update((int(a[k]), int(b[k])))
                    chosen.append(k)
            continue
        chosen.extend(_best_matching(ks, a, b, score - dist))
    return sorted(chosen, key=lambda k: -score[k])


def _best_matching(ks: list[int], a: NDArray[np.int64], b: NDArray[np.int64], value: FloatArray) -> list[int]:
    """The matching among pairs ``ks`` with the most pairs, then the highest total ``value`` (exhaustive)."""
    best: tuple[int, float, list[int]] = (0, 0.0, [])

    def search(rest: list[int], used: frozenset[int], picked: list[int], total: float) -> None:
        nonlocal best
        if (len(picked), total) > best[:2]:
            best = (len(picked), total, list(picked))
        for n, k in enumerate(rest):
            if a[k] in used or b[k] in used:
                continue
            picked.append(k)
            search(rest[n + 1 :], used | {int(a[k]), int(b[k])}, picked, total + float(value[k]))
            picked.pop()

    search(ks, frozenset(), [], 0.0)
    return best[2]


@dataclass(frozen=True)
class ClassicalLaserDetector:
    """Hand-built leg detector (see the module docstring). Implements ``LaserDetector``.

    Attributes:
        segment: segmentation options.
        leg_min_score: segments below this leg likelihood are not legs.
        max_leg_width: wider segments are blob candidates, metres.
        max_blob_width: wider segments are never people, metres.
        pair_min, pair_max: distance range between the centroids of two legs of one person, metres.
        single_leg_factor: score of an unpaired leg = its likelihood × this.
        blob_factor: score of a blob person = its likelihood × this.
        leg_radius: radius of a leg at scan height, metres. A segment's centroid lies on the lit surface;
            the leg's axis is ``2r/π`` further along the beam (centroid of a half circle), with ``r`` the
            segment's half width capped at this value.
        hidden_leg_offset: an unpaired leg is usually the nearer leg with the other one hidden behind it
            (seen on simulated walkers: unpaired legs sit 0.08 m short of the body centre, pairs 0.035 m), so
            a single-leg person is placed this much further along the beam than the leg, metres.
        merge_radius: detections of several scans closer than this are one person, metres.
        memory_radius: over time (:meth:`detect_remembering`), a leg this close to one of the scanner's last
            scan (in the fixed frame) is the same leg, metres; 0 pairs every scan on its own. A walker's
            legs move 0.1–0.2 m between scans at 10 Hz (the swinging one up to twice the body's speed).
        memory_keep: two legs mostly paired in the scans before count as this much closer together,
            metres (a preference, never a constraint).
        memory_min_seen: the memory has a say on two legs once they were seen within pairing distance in
            this many (faded) scans.
        memory_share: two legs joined in at most this share of those scans are kept apart; joined in at
            least ``1 - memory_share``, they are preferred.
        model: the leg likelihood (fitted on scans with 0.35° beams).
        coarse_step_deg: scans with beams this far apart or more are coarse, degrees: coarser than the
            0.35° the fine model was fitted on (simulated ``moving`` with 0.4° beams, seeds 1–4: F1 0.922,
            MOTA 0.850, 27 switches with the fine model, 0.954, 0.909, 17 with the coarse one; with 0.25°
            beams the fine model is the better one: 62 switches against 105 over seeds 1–20).
            On a coarse scanner a leg has few returns at any range (a 1° scanner puts 3 on a leg 2 m away,
            1–2 beyond 3 m), where on a fine one few returns mean clutter or a far leg.
        coarse_segment: segmentation options of coarse scans (segments from two returns on).
        coarse_model: the leg likelihood of coarse scans (fitted on the same scans thinned to 0.70° and
            1.05° beams, segmented with ``coarse_segment``).
    """

    segment: SegmentParams = field(default_factory=SegmentParams)
    leg_min_score: float = 0.3
    max_leg_width: float = 0.25
    max_blob_width: float = 0.8
    pair_min: float = 0.1
    pair_max: float = 0.6
    single_leg_factor: float = 0.7
    blob_factor: float = 1.0
    merge_radius: float = 0.3
    leg_radius: float = 0.07
    hidden_leg_offset: float = 0.045
    memory_radius: float = 0.3
    memory_keep: float = 0.2
    memory_min_seen: float = 2.0
    memory_share: float = 0.35
    model: LegModel = LEG_MODEL
    coarse_step_deg: float = 0.38
    coarse_segment: SegmentParams = field(default_factory=lambda: SegmentParams(min_points=2))
    coarse_model: LegModel = LEG_MODEL_COARSE

    def __post_init__(self) -> None:
        if not 0.0 <= self.pair_min < self.pair_max:
            raise LaserDetectorError(f"need 0 <= pair_min < pair_max, got {self.pair_min}, {self.pair_max}")
        if not self.model.coef or not self.coarse_model.coef:
            raise LaserDetectorError("the classical laser detector has no leg model coefficients")
        if not self.coarse_step_deg > 0:
            raise LaserDetectorError(f"need coarse_step_deg > 0, got {self.coarse_step_deg}")
        if self.memory_radius < 0 or self.memory_keep < 0 or self.memory_min_seen <= 0:
            raise LaserDetectorError(
                "need memory_radius >= 0, memory_keep >= 0, memory_min_seen > 0, got "
                f"{self.memory_radius}, {self.memory_keep}, {self.memory_min_seen}"
            )
        if not 0.0 <= self.memory_share < 0.5:
            raise LaserDetectorError(f"need 0 <= memory_share < 0.5, got {self.memory_share}")

    def is_coarse(self, step_deg: float) -> bool:
        """Whether a scan with beams ``step_deg`` degrees apart gets the ``coarse_`` options."""
        return abs(step_deg) >= self.coarse_step_deg

    # -- stages ---------------------------------------------------------------------------------------
    def legs(
        self, points: FloatArray, *, valid: NDArray[np.bool_] | None = None, origin: ArrayLike = (0.0, 0.0)
    ) -> LaserDetections:
        """Every segment as a leg candidate (before pairing): centroid, leg likelihood, width / 2.

        ``kind`` is :data:`KIND_LEG` for leg-sized segments and :data:`KIND_BLOB` for wider ones. A scan
        with coarse beams (the step measured on the returns' bearings) is segmented and scored with the
        ``coarse_`` options.
        """
        pts = _check_points(points)
        step = estimate_angle_step(pts, origin=origin)
        coarse = self.is_coarse(float(np.degrees(step)))
        params, model = (self.coarse_segment, self.coarse_model) if coarse else (self.segment, self.model)
        segs = segment_scan(pts, valid, origin=origin, params=params, angle_step=step)
        if not segs:
            return LaserDetections.empty(with_segments=True)
        feats = segment_features(pts, segs, valid, origin=origin)
        xy = np.array([pts[s].mean(0) for s in segs])
        p = model(feats)
        width = feats[:, 1]
        depth = (2.0 / np.pi) * np.minimum(width / 2.0, self.leg_radius)
        xy = xy + depth[:, None] * _along_beam(xy, origin)
        kind = np.where(width > self.max_leg_width, KIND_BLOB, KIND_LEG)
        return LaserDetections(xy, p, kind, np.maximum(width / 2.0, 0.05), tuple(segs))

    def people(
        self,
        legs: LaserDetections,
        *,
        origin: ArrayLike = (0.0, 0.0),
        apart: NDArray[np.bool_] | None = None,
        together: NDArray[np.bool_] | None = None,
    ) -> LaserDetections:
        """People from leg candidates: leg pairing (:func:`_pairing`), then unpaired legs and blobs.

        Args:
            legs: leg candidates as :meth:`legs` returns them (``segments`` optional).
            origin: ``(2,)`` the sensor's position (an unpaired leg's person lies behind it along the beam).
            apart, together: optional ``(N, N)`` bool over the candidates: pairs that must not be formed, and
                pairs preferred by :attr:`memory_keep` (what :meth:`LegMemory.relations` says).

        Returns:
            People; a pair's ``segments`` is the union of both legs' (None when ``legs`` has none), its
            ``legs`` the two legs' positions.
        """
        return self._people(legs, origin, apart, together)[0]

    def _people(
        self,
        legs: LaserDetections,
        origin: ArrayLike,
        apart: NDArray[np.bool_] | None,
        together: NDArray[np.bool_] | None,
    ) -> tuple[LaserDetections, NDArray[np.int64]]:
        """:meth:`people`, and ``(N,)`` the candidate each one was paired with (-1 unpaired)."""
        has_segs = legs.segments is not None
        segs_in = (
            legs.segments if legs.segments is not None else tuple(np.zeros(0, np.int64) for _ in legs.xy)
        )
        n = len(legs)
        width = 2.0 * legs.radius
        is_leg = (legs.kind == KIND_LEG) & (legs.scores >= self.leg_min_score)
        is_blob = (
            (legs.kind == KIND_BLOB) & (legs.scores >= self.leg_min_score) & (width <= self.max_blob_width)
        )
        li = np.flatnonzero(is_leg)
        xy, sc, kd, rad, seg, lg = [], [], [], [], [], []
        partner = np.full(n, -1, dtype=np.int64)
        if li.size >= 2:
            d = np.hypot(*(legs.xy[li, None, :] - legs.xy[None, li, :]).transpose(2, 0, 1))
            a, b = np.triu_indices(li.size, 1)
            ok = (d[a, b] >= self.pair_min) & (d[a, b] <= self.pair_max)
            a, b, dist = li[a[ok]], li[b[ok]], d[a[ok], b[ok]]
            if apart is not None:
                allowed = ~np.asarray(apart, dtype=bool).reshape(n, n)[a, b]
                a, b, dist = a[allowed], b[allowed], dist[allowed]
            pa, pb = legs.scores[a], legs.scores[b]
            pair_score = 1.0 - (1.0 - pa) * (1.0 - pb)
            if together is not None:
                dist = dist - self.memory_keep * np.asarray(together, dtype=bool).reshape(n, n)[a, b]
            for k in _pairing(a, b, pair_score, dist):
                i, j = a[k], b[k]
                partner[i], partner[j] = j, i
                c = (legs.xy[i] + legs.xy[j]) / 2.0
                xy.append(c)
                sc.append(pair_score[k])
                kd.append(KIND_PAIR)
                rad.append(np.hypot(*(legs.xy[i] - c)) + max(legs.radius[i], legs.radius[j]))
                seg.append(np.concatenate([segs_in[i], segs_in[j]]))
                lg.append(legs.xy[[i, j]])
        behind = self.hidden_leg_offset * _along_beam(legs.xy, origin)
        for i in np.flatnonzero((is_leg & (partner < 0)) | is_blob):
            single = legs.kind[i] == KIND_LEG
            factor = self.single_leg_factor if single else self.blob_factor
            xy.append(legs.xy[i] + behind[i] if single else legs.xy[i])
            sc.append(legs.scores[i] * factor)
            kd.append(int(legs.kind[i]))
            rad.append(max(float(legs.radius[i]), 0.15))
            seg.append(segs_in[i])
            lg.append(np.full((2, 2), np.nan))
        if not xy:
            return LaserDetections.empty(with_segments=has_segs), partner
        segments = tuple(seg) if has_segs else None
        people = LaserDetections(
            np.array(xy), np.clip(sc, 0.0, 1.0), np.array(kd), np.array(rad), segments, np.array(lg)
        )
        return people, partner

    def detect_remembering(
        self,
        points: FloatArray,
        *,
        valid: NDArray[np.bool_] | None = None,
        origin: ArrayLike = (0.0, 0.0),
        memory: LegMemory | None = None,
        to_fixed: ArrayLike | None = None,
    ) -> tuple[LaserDetections, LegMemory]:
        """People in one scan, paired with what the scanner's last scan showed (:class:`LegMemory`).

        Args:
            points, valid, origin: as :meth:`detect`.
            memory: what this method returned for the scanner's last scan (None: the first scan).
            to_fixed: ``(3, 3)`` homogeneous 2D transform from the frame of ``points`` to a frame fixed to the
                world (odometry; identity for a robot that does not move).

        Returns:
            The people, as :meth:`detect`, and the memory for the scanner's next scan.
        """
        m = np.eye(3) if to_fixed is None else np.asarray(to_fixed, dtype=np.float64).reshape(3, 3)
        legs = self.legs(points, valid=valid, origin=origin)
        memory = memory if memory is not None else LegMemory.empty()
        is_leg = np.flatnonzero((legs.kind == KIND_LEG) & (legs.scores >= self.leg_min_score))
        fixed = (legs.xy @ m[:2, :2].T + m[:2, 2])[is_leg]
        was = memory.follow(fixed, self.memory_radius)
        # this scan on its own: what the memory learns from (never from its own choices)
        people, partner = self._people(legs, origin, None, None)
        if self.memory_radius > 0 and is_leg.size >= 2:
            apart, together = (np.zeros((len(legs), len(legs)), dtype=bool) for _ in range(2))
            sub = np.ix_(is_leg, is_leg)
            apart[sub], together[sub] = memory.relations(
                was, min_seen=self.memory_min_seen, share=self.memory_share
            )
            if apart.any() or together.any():
                people = self._people(legs, origin, apart, together)[0]
        gap = np.hypot(*(fixed[:, None, :] - fixed[None, :, :]).transpose(2, 0, 1))
        in_range = (gap >= self.pair_min) & (gap <= self.pair_max)
        pos = np.full(len(legs), -1, dtype=np.int64)
        pos[is_leg] = np.arange(is_leg.size)
        mate = partner[is_leg]
        joined = np.zeros((is_leg.size, is_leg.size), dtype=bool)
        has = np.flatnonzero(mate >= 0)
        joined[has, pos[mate[has]]] = True
        return people, memory.after(fixed, was, in_range, joined)

    # -- LaserDetector ----------------------------------------------------------------------------------
    def detect(
        self,
        points: FloatArray,
        *,
        valid: NDArray[np.bool_] | None = None,
        origin: ArrayLike = (0.0, 0.0),
    ) -> LaserDetections:
        """People in one scan.

        Args:
            points: ``(M, 2)`` float64, beams in angle order, metres; invalid ones NaN or masked.
            valid: ``(M,)`` bool, optional mask of returns.
            origin: ``(2,)`` the sensor's position in the frame of ``points`` (ranges are measured from it).

        Returns:
            People in the frame of ``points``; ``segments`` index ``points``.
        """
        return self.people(self.legs(points, valid=valid, origin=origin), origin=origin)

    def detect_scans(
        self,
        scans: Sequence[tuple[FloatArray, NDArray[np.bool_] | None, ArrayLike]],
    ) -> LaserDetections:
        """People in several simultaneous scans given in one common frame (e.g. base_link).

        Args:
            scans: per scanner ``(points (M_i, 2), valid (M_i,) or None, sensor origin (2,))``, points in
                beam order, already transformed to the common frame.

        Returns:
            Merged people; ``segments`` index the concatenation of all scans' points, in order.
        """
        parts, offsets, off = [], [], 0
        for pts, valid, origin in scans:
            p = _check_points(pts)
            parts.append(self.detect(p, valid=valid, origin=origin))
            offsets.append(off)
            off += p.shape[0]
        return merge_detections(parts, radius=self.merge_radius, offsets=offsets)


def _check_points(points: FloatArray) -> FloatArray:
    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise LaserDetectorError(f"scan points must have shape (M, 2), got {pts.shape}")
    return pts
