"""Re-run fusion and tracking on stored perception: measure a fusion or tracking change in seconds.

    .venv/bin/python bench/replay_tracking.py --scenario moving --seeds 1 2
    .venv/bin/python bench/replay_tracking.py --scenario static --seeds 1 --switches
    .venv/bin/python bench/replay_tracking.py --scenario moving --seeds 1 --image-period 0.3
    .venv/bin/python bench/replay_tracking.py --scenario moving --seeds 1 2 3 --laser-again
    .venv/bin/python bench/replay_tracking.py --scenario rooms --seeds 1 --laser-again --laser-only
    .venv/bin/python bench/replay_tracking.py --scenario moving --seeds 1 2 --laser-step 1.0
    .venv/bin/python bench/replay_tracking.py --scenario moving --seconds 60 --seeds 1 2 --camera-rate 30
    .venv/bin/python bench/replay_tracking.py --scenario moving --seeds 1 2 3 --laser-again --without swaps

Pass one of ``studio label`` (image and laser detection, ~2–3 min for a 96 s recording on 2 cores) runs once
per recording and is stored in ``bench/out/perception/<recording>-p2.pkl`` (``-laser.pkl`` laser only; a
development cache, not a contract: delete it when the detectors change, or raise :data:`CAMERA_PASS_ONE`;
one stored before session 42's beam times is named when loaded). Each
call then runs the static-world filter, fusion and offline tracking exactly as ``studio label`` does and
prints the metrics at 0.2 m; ``--switches`` also lists every identity
switch (frame, ground-truth id, range from the robot, distance to the nearest other person, the track ids
before and after, and its kind: an *encounter*'s, with someone else within 0.8 m; *after a gap*, where the
person had gone unmatched for more than 1 s; or *other*; and, where the track after it last had someone
else, who and when: a wrong link rather than a new track), marks the switches that were *undone* (the
person went from track A to B and back to A within 3 s: two tracks exchanged people for a moment)
and the switches *to check* (within 2 s of a review point of ``review.jsonl`` on the track before or after,
:mod:`studio.labels.review`: what a person checking the doubts the run lists would find) and *first* (such
a point has a doubt of 0.3 or more: the Rerun log's warnings), and counts the kinds, the undone, the
switches to check (first) and the review points per minute (to check first). ``--image-period``
emulates another image detector period from a pass one that ran the detector on every frame (stored
separately). ``--laser-again`` runs the current laser detector again on the stored scans (in the base frame,
so positions differ from ``studio label``'s in the last digits): a laser detector change measured in a minute
instead of a new pass one. ``--laser-step DEG`` simulates the recordings with coarser scanners (their own
folders and pass ones): what a robot with a low-cost lidar (~1°) would get. ``--camera-rate HZ`` simulates
them with the camera at another frame rate (own folders and pass ones; the same people and robot), e.g. 30
Hz as a Ricoh Theta streams its live panorama: tracking options counted in frames meet 3x as many.
``--laser-only`` labels as ``studio label --sources laser`` (the path of a rig without a camera) from a pass
one that ran without the image detector (stored separately, ~10x faster to make). ``--without STAGE ...``
switches stages of the offline tracker off (:data:`STAGES`): what each one still buys, measured on the same
detections.
``--oracle`` replaces the association (online pass, stitching, encounter and swap repairs) by the ground
truth: in every frame the observations go one to one to the nearest people within 0.5 m (Hungarian), and each
person's observations are smoothed, interpolated and output as ``studio label`` outputs a track
(:func:`studio.track.offline.tracks_from_hits`); fusion, the camera gate and the rest are unchanged. What it
scores is what these detections allow with a perfect association: the part of the errors that tracking can
still remove. ``--likelihood`` asks whether the tracker's own model could have told that association from
ours: on the observations both assign to someone (ours after the last tracking pass, the oracle's on those
same observations), it prints each one's number of tracks, the negative log-likelihood of the tracks'
observations under the constant-velocity Kalman filter the offline tracker uses
(:func:`association_likelihood`) and their colour spread (each described observation's ΔE to the median
colours of its track's ten described observations either side, up to 20). Where ours scores as well as the
oracle's, no search over associations under that model finds the oracle's: the evidence, not the search, is
what falls short. ``--jitter S`` moves every fused observation by Gaussian noise of standard deviation S
metres (a fixed generator per jitter seed and recording) before tracking, once per seed of ``--jitter-seeds``:
with S far below the detectors' own error (5 mm against about 60 mm) the detections are as good as before, so
the spread of the switch count over a few jitter seeds (printed at the end: per jitter seed the switches of
every recording and their total, then their mean and standard deviation) is how much a tracking change must
move it to mean anything; compare two versions on the same jitter seeds, the noise then is the same for both.
The recordings are those of ``bench/run_table.py``.
"""

from __future__ import annotations

import argparse
import pickle
import time
from collections import Counter
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
from run_table import OUT, recording

from studio.evaluate import evaluate
from studio.geometry import EquirectCamera
from studio.geometry.scan_match import ScanMatchConfig, ScanOdometry
from studio.geometry.se import Pose3
from studio.io import load_rig
from studio.labels import LabelSet, read_labels
from studio.pipeline import LabelOptions
from studio.pipeline.label import fuse_all, perceive, track_all
from studio.pipeline.perceive import compact_beams, detect_again, off_people
from studio.track.appearance import appearance_distance, median_appearance
from studio.track.models import cv_matrix
from studio.track.offline import track_offline, tracks_from_hits
from studio.track.smooth import filter_track

STAGES = ("colour_cuts", "swaps", "encounters", "excursions", "claim", "gap_fill", "duplicates", "stitch")
"""The stages of :func:`studio.track.offline.track_offline` that ``--without`` can switch off (its
``OfflineConfig`` fields set to None)."""
ORACLE_GATE_M = 0.5  # --oracle: an observation farther than this from every person is nobody's
CAMERA_PASS_ONE = 2
"""Raised when pass one's image detections change, so stored ones are not reused: 2 since session 74 (closer
looks on every look, at the far laser detections of the last 0.5 s). Laser-only ones do not carry it."""


def perception(rec: Path, options: LabelOptions) -> tuple[list[Any], EquirectCamera | None]:
    """The stored pass-one output of ``rec`` (computed and stored on the first call)."""
    tag = "-every-frame" if options.image_period_s == 0 else ""
    tag += "-laser" if options.sources == "laser" else f"-p{CAMERA_PASS_ONE}"
    path = OUT / "perception" / f"{rec.name}{tag}.pkl"
    if not path.exists():
        sizes: dict[str, tuple[int, int]] = {}

        def hook(frame: Any, _pf: Any) -> None:
            if frame.panorama is not None:
                sizes.setdefault("size", (frame.panorama.image.shape[1], frame.panorama.image.shape[0]))

        t = time.perf_counter()
        frames, info = perceive(rec / "recording.mcap", load_rig(rec / "rig.yaml"), options, on_frame=hook)
        print(f"perceived {rec.name} in {time.perf_counter() - t:.0f} s", flush=True)
        cam = None
        rig = info["rig"]
        if "size" in sizes and rig.camera is not None:
            pose = rig.camera.pose if rig.camera.pose is not None else Pose3.identity()
            cam = EquirectCamera(*sizes["size"], pose, rig.camera.lens_offset)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(pickle.dumps((frames, cam)))
    frames, cam = pickle.loads(path.read_bytes())
    for f in frames:
        if "scan_sizes" not in vars(f):  # stored before session 51: a height and a scanner index per beam
            owner = vars(f).pop("origin_of_point")
            f.points, f.scan_sizes, f.scan_planes = compact_beams(f.points, owner, len(f.origins))
    if any(f.laser is not None and f.beam_clocks is None for f in frames):
        print(f"{path.name}: stored before beam times were kept (session 42); delete it to make it again")
    if options.scan_matching and frames and frames[0].track_pose is None:  # stored before scan matching
        matcher = ScanOdometry(ScanMatchConfig(every=2))  # as studio label's pass one
        for f in frames:
            if f.laser is not None:
                f.track_pose = matcher.step(off_people(f.points, f.laser), f.robot_pose)
    return frames, cam


def laser_again(frames: list[Any]) -> list[Any]:
    """Pass one with the current classical laser detector run again on each frame's stored scans."""
    from studio.detect.laser import get_laser_detector

    detector = get_laser_detector("classical")
    out = []
    memory: dict[int, Any] = {}  # each scan's legs paired with the scanner's last scan, as in perceive
    for f in frames:
        laser, z = detect_again(f, detector, memory=memory)
        out.append(replace(f, laser=laser, laser_z=z))
    return out


def thin_images(frames: list[Any], period_s: float) -> list[Any]:
    """Pass one as if the image detector had run at most every ``period_s`` (the rule of ``perceive``), from
    a pass one that ran it on every frame."""
    out, last = [], None
    for f in frames:
        if f.image is None:
            out.append(f)
        elif last is None or f.stamp_ns - last >= period_s * 1e9 - 1e6:
            last = f.stamp_ns
            out.append(f)
        else:
            out.append(replace(f, image=None, appearance=None))
    return out


def oracle_tracker(fused: list[Any], gt: LabelSet) -> Any:
    """A tracker for :func:`track_all` that assigns the observations by ground truth (``--oracle``)."""
    from scipy.optimize import linear_sum_assignment

    by_frame = {f.frame: f for f in gt.frames}
    people = []  # per fused frame: ground-truth ids and positions in the tracking frame
    for fr in fused:
        f = by_frame.get(fr.index)
        ids = [p.id for p in f.people] if f is not None else []
        xy = np.array([[p.x, p.y] for p in f.people]).reshape(-1, 2) if f is not None else np.zeros((0, 2))
        people.append((ids, fr.world_pose.apply(xy) if len(xy) else xy))

    def track(observations: list[Any], *, config: Any) -> Any:
        hits: dict[int, list[tuple[int, int]]] = {}
        for i, (o, (ids, xy)) in enumerate(zip(observations, people, strict=True)):
            rows = np.arange(len(o.xy)) if o.alt_of is None else np.flatnonzero(o.alt_of < 0)
            if not len(rows) or not ids:
                continue
            d = np.hypot(*(o.xy[rows][:, None, :] - xy[None, :, :]).transpose(2, 0, 1))
            for r, c in zip(*linear_sum_assignment(d), strict=True):
                if d[r, c] < ORACLE_GATE_M:
                    hits.setdefault(ids[c], []).append((i, int(rows[r])))
        return tracks_from_hits(observations, hits, config=config)

    return track


Hits = dict[int, list[tuple[int, int]]]  # track -> (frame index, row in that frame's observations)
COLOUR_NEIGHBOURS = 10  # --likelihood: described observations either side that make a track's colours
COLOUR_CAP = 20.0  # --likelihood: ΔE counted up to this


def jitter(fused: list[Any], sigma: float, seed: tuple[int, int]) -> list[Any]:
    """``fused`` with every observation moved by Gaussian noise of ``sigma`` metres per axis."""
    rng = np.random.default_rng(seed)
    out = []
    for fr in fused:
        o = fr.observations
        out.append(replace(fr, observations=replace(o, xy=o.xy + rng.normal(0.0, sigma, o.xy.shape))))
    return out


@dataclass(frozen=True)
class Run:
    """The metrics of one tracking run of one recording."""

    jitter_seed: int
    seed: int
    switches: int
    f1: float
    mota: float
    idf1: float
    minutes: float


def summary(runs: list[Run]) -> list[str]:
    """Lines that sum the runs up: per jitter seed the switches over all recordings (per seed, total, per
    minute), mean F1 / MOTA / IDF1 and how many recordings meet each of issue #3's targets on their own
    (≤ 1 switch per minute, F1 ≥ 0.95, MOTA ≥ 0.85); with several jitter seeds, the mean and spread of the
    switch totals."""
    if len(runs) < 2:
        return []
    by_jitter: dict[int, list[Run]] = {}
    for r in runs:
        by_jitter.setdefault(r.jitter_seed, []).append(r)
    lines, totals = [], []
    for j, rs in by_jitter.items():
        n, minutes = sum(r.switches for r in rs), sum(r.minutes for r in rs)
        totals.append(n)
        head = f"jitter seed {j}" if len(by_jitter) > 1 else "all"
        lines.append(
            f"{head}: IDSW {' '.join(str(r.switches) for r in rs)} = {n} ({n / minutes:.2f}/min); "
            f"F1 {np.mean([r.f1 for r in rs]):.4f} MOTA {np.mean([r.mota for r in rs]):.4f} "
            f"IDF1 {np.mean([r.idf1 for r in rs]):.4f}; targets met by "
            f"{sum(r.switches <= r.minutes for r in rs)}/{len(rs)} (≤ 1 switch/min), "
            f"{sum(r.f1 >= 0.95 for r in rs)}/{len(rs)} (F1 ≥ 0.95), "
            f"{sum(r.mota >= 0.85 for r in rs)}/{len(rs)} (MOTA ≥ 0.85)"
        )
    if len(totals) > 1:
        t = np.array(totals, dtype=np.float64)
        lines.append(
            f"over {len(t)} jitter seeds: IDSW mean {t.mean():.1f} sd {t.std(ddof=1):.1f} "
            f"(min {t.min():.0f}, max {t.max():.0f})"
        )
    return lines


def capture(tracker: Any) -> tuple[Any, dict[str, Any]]:
    """``tracker`` wrapped so that its last call's observations, hits (per track, the observations its
    output points hold) and config are kept in the returned dict under ``"last"``."""
    seen: dict[str, Any] = {}

    def run(observations: list[Any], *, config: Any) -> Any:
        result = tracker(observations, config=config)
        hits: Hits = {}
        for i, (o, tf) in enumerate(zip(observations, result.frames, strict=True)):
            row = {int(d): r for r, d in enumerate(o.det_index)}
            for p in tf.points:
                if p.det_index >= 0:
                    hits.setdefault(p.track_id, []).append((i, row[p.det_index]))
        seen["last"] = (list(observations), hits, config)
        return result

    return run, seen


def association_likelihood(
    obs: list[Any], tracks: Hits, *, accel_sigma: float, init_speed_sigma: float
) -> tuple[float, float, int]:
    """How well an association fits the tracker's model: the negative log-likelihood of every track's
    observations under a constant-velocity Kalman filter (white acceleration ``accel_sigma``; each track
    starts at its first observation with speed σ ``init_speed_sigma``), the tracks' colour spread (see the
    module docstring) and how many described observations it sums over."""
    nll, spread, n_described = 0.0, 0.0, 0
    for hits in tracks.values():
        z = np.array([obs[i].xy[r] for i, r in hits])
        R = np.array([obs[i].cov[r] for i, r in hits])
        stamps = np.array([obs[i].stamp_ns for i, _ in hits], dtype=np.int64)
        run = filter_track(stamps, z, R, accel_sigma=accel_sigma, init_speed_sigma=init_speed_sigma)
        for k in range(1, len(hits)):  # each observation against the filter's prediction from the one before
            F = cv_matrix(run.dt[k])
            x, P = F @ run.x[k - 1], F @ run.P[k - 1] @ F.T + run.Q[k]
            S = P[:2, :2] + R[k]
            y = z[k] - x[:2]
            mahalanobis = float(y @ np.linalg.solve(S, y))
            nll += 0.5 * (mahalanobis + float(np.log(np.linalg.det(S))) + 2.0 * np.log(2.0 * np.pi))
        colours = [
            obs[i].appearance[r]
            for i, r in hits
            if obs[i].appearance is not None and np.all(np.isfinite(obs[i].appearance[r]))
        ]
        for k, c in enumerate(colours):
            lo = max(0, k - COLOUR_NEIGHBOURS)
            around = colours[lo:k] + colours[k + 1 : k + 1 + COLOUR_NEIGHBOURS]
            ref = median_appearance(np.array(around)) if around else None
            if ref is not None:
                spread += min(appearance_distance(c, ref), COLOUR_CAP)
                n_described += 1
    return nll, spread, n_described


def compare_likelihood(seen: dict[str, Any], oracle: Any) -> None:
    """Print :func:`association_likelihood` of our last tracking pass and of ``oracle`` (a tracker) on the
    same observations, both restricted to the observations both assign."""
    obs, ours, config = seen["last"]
    run, seen_oracle = capture(oracle)
    run(obs, config=config)
    truth = seen_oracle["last"][1]
    common = {h for hits in ours.values() for h in hits} & {h for hits in truth.values() for h in hits}
    t = config.tracker
    for name, tracks in (("ours", ours), ("oracle", truth)):
        kept = {k: [h for h in sorted(v) if h in common] for k, v in tracks.items()}
        kept = {k: v for k, v in kept.items() if v}
        nll, spread, n = association_likelihood(
            obs, kept, accel_sigma=t.accel_sigma, init_speed_sigma=t.init_speed_sigma
        )
        print(
            f"  likelihood, {name:6s}: {len(kept)} tracks over {len(common)} observations, motion NLL "
            f"{nll:.1f}, colour spread {spread:.1f} over {n} described"
        )


def frame_seconds(gt: LabelSet) -> dict[int, float]:
    """Each ground-truth frame's time, s (its stamp; its index at 10 Hz where it has none)."""
    return {f.frame: f.frame / 10 if f.stamp_ns is None else f.stamp_ns / 1e9 for f in gt.frames}


ENCOUNTER_M = 0.8  # a switch with another person this close is an encounter's
GAP_S = 1.0  # a switch this long after the person's last match is a re-identification's


def switch_kind(near_m: float, gap_s: float) -> str:
    """``encounter`` (someone else within :data:`ENCOUNTER_M`), ``after a gap`` (the person had gone
    unmatched for more than :data:`GAP_S` seconds: stitching or re-identification decided) or
    ``other``."""
    if near_m < ENCOUNTER_M:
        return "encounter"
    return "after a gap" if gap_s > GAP_S else "other"


UNDONE_S = 3.0  # a switch from track A to B undone (B back to A) within this many seconds
CHECK_S = 2.0  # a switch this near a review point of the track before or after it is one to check


def switches(labels: list[Any], ev: Any, gt: LabelSet) -> tuple[Counter[str], int, int, int, int, int, int]:
    """Print every identity switch with its context. Returns how many of each :func:`switch_kind`, how
    many went onto a track that last had someone else (the rest onto a new track or one of their own), how
    many of them come in *undone* pairs (the person went from track A to track B and back to A within
    :data:`UNDONE_S` seconds: two tracks exchanged people for a moment; each such pair is two switches),
    how many are *to check* (within :data:`CHECK_S` of a review point on track A or B, as ``studio
    label`` lists them in ``review.jsonl``), how many of those are to check *first* (such a point has a
    doubt of :data:`~studio.labels.review.FIRST_DOUBT` or more), how many review points there are and
    how many of them are to check first."""
    from studio.evaluate.align import align_frames
    from studio.evaluate.clear import ClearMOT
    from studio.labels.review import FIRST_DOUBT, review_points

    points = review_points(labels)

    gt_frames = {f.frame: f for f in gt.frames}
    seconds = frame_seconds(gt)
    # each ground-truth frame's prediction as the evaluator aligned it (interpolated where it had to be)
    aligned = {g.frame: pf for g, pf in align_frames(LabelSet.from_frames(labels), gt).pairs}
    last: dict[int, tuple[int, int]] = {}
    held: dict[int, tuple[int, int]] = {}  # track -> (frame, person) of its last match
    kinds: Counter[str] = Counter()
    taken = 0
    events: list[tuple[float, int, int, int | None, str]] = []  # time (s), person, from track, to track, text
    clear = ClearMOT(radius=ev.radius)  # CLEAR MOT's own correspondences (they decide the switches)
    for fe in ev.frames:
        pred = None if fe.pred_frame is None else aligned[fe.frame]
        cf = clear.update(gt_frames[fe.frame], pred, sequence=fe.sequence)
        assert sorted(cf.switches) == sorted(fe.switch_ids)
        match = {g: p for g, p, _ in cf.matches}
        for g in fe.switch_ids:
            people = {q.id: np.array([q.x, q.y]) for q in gt_frames[fe.frame].people}
            others = [float(np.hypot(*(people[g] - v))) for k, v in people.items() if k != g]
            near = min(others, default=np.inf)
            before, was = last.get(g, (-1, -1))
            gap_s = np.inf if before < 0 else seconds[fe.frame] - seconds[before]
            kind = switch_kind(near, gap_s)
            kinds[kind] += 1
            t = seconds[fe.frame]
            near_points = [
                p for p in points if {was, match.get(g)} & set(p.ids) and abs(p.stamp_ns / 1e9 - t) <= CHECK_S
            ]
            first = any(p.doubt >= FIRST_DOUBT for p in near_points)
            kinds["to check"] += bool(near_points)
            kinds["first"] += first
            prior = held.get(match.get(g, -1))
            taken += prior is not None and prior[1] != g
            text = (
                f"  frame {fe.frame:5d} person {g:3d} at {float(np.hypot(*people[g])):4.1f} m, "
                f"nearest other {near:4.2f} m: track {was} (its last match, frame {before}) "
                f"-> {match.get(g)} [{kind}]"
                + ("" if prior is None or prior[1] == g else f" (it had person {prior[1]}, frame {prior[0]})")
                + (" to check" if near_points else "")
                + (" first" if first else "")
            )
            events.append((seconds[fe.frame], g, was, match.get(g), text))
        for g, p in match.items():
            last[g] = (fe.frame, p)
            held[p] = (fe.frame, g)
    undone: set[int] = set()
    for i, (f, g, a, b, _) in enumerate(events):
        for j in range(i + 1, len(events)):
            f2, g2, a2, b2, _ = events[j]
            if f2 - f > UNDONE_S:
                break
            if g2 == g and a2 == b and b2 == a and i not in undone and j not in undone:
                undone |= {i, j}
                break
    for i, (*_, text) in enumerate(events):
        print(text + (" undone" if i in undone else ""))
    n_first = sum(p.doubt >= FIRST_DOUBT for p in points)
    check, first = kinds.pop("to check", 0), kinds.pop("first", 0)
    return kinds, taken, len(undone), check, first, len(points), n_first


HANDOVER_S = 3.0  # a track matched to another person within this many seconds of its last match


def handovers(ev: Any, gt: LabelSet) -> Counter[str]:
    """Print every time an output track goes on from one person to another (matched to person Q, then to
    person P within :data:`HANDOVER_S` seconds): with Q still there and how far apart the two are, or
    Q gone (a hand-off: Q was hidden or left just as P appeared). Returns how many of each kind (Q's
    distance in steps of 0.2 m, or ``the first one gone``)."""
    gt_frames = {f.frame: f for f in gt.frames}
    seconds = frame_seconds(gt)
    last: dict[int, tuple[int, int]] = {}  # track -> (frame, person) of its last match
    kinds: Counter[str] = Counter()
    for fe in ev.frames:
        people = {q.id: np.array([q.x, q.y]) for q in gt_frames[fe.frame].people}
        for g, p, _ in fe.matches:
            before, q = last.get(p, (-(10**9), g))
            after_s = seconds[fe.frame] - seconds[before] if before in seconds else np.inf
            if q != g and after_s <= HANDOVER_S:
                if q in people:
                    d = float(np.hypot(*(people[g] - people[q])))
                    lo = 0.2 * np.floor(d / 0.2)
                    kind = f"{lo:.1f}-{lo + 0.2:.1f} m"
                    how = f"person {q} still there, {d:.2f} m away"
                else:
                    kind, how = "the first one gone", f"person {q} gone"
                kinds[kind] += 1
                print(f"  frame {fe.frame:5d} track {p:3d}: person {q} -> {g} after {after_s:.1f} s; {how}")
            last[p] = (fe.frame, g)
    return kinds


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="moving")
    ap.add_argument("--seeds", nargs="+", type=int, default=[1])
    ap.add_argument("--seconds", type=float, default=None)
    ap.add_argument("--switches", action="store_true", help="list every identity switch")
    ap.add_argument(
        "--handovers", action="store_true", help="list every time an output track goes on with another person"
    )
    ap.add_argument(
        "--image-period",
        type=float,
        default=None,
        help="emulate this image detector period, s (pass one then runs the detector on every frame once)",
    )
    ap.add_argument(
        "--laser-step",
        type=float,
        default=None,
        metavar="DEG",
        help="simulate the scanners with this angular step (default 0.25°), e.g. 1.0 for a low-cost lidar",
    )
    ap.add_argument(
        "--camera-rate",
        type=float,
        default=None,
        metavar="HZ",
        help="simulate the camera at this frame rate (default 10 Hz), e.g. 30 as a Ricoh Theta streams",
    )
    ap.add_argument(
        "--laser-again", action="store_true", help="run the laser detector again on the stored scans"
    )
    ap.add_argument(
        "--laser-only", action="store_true", help="without the image detections, as --sources laser"
    )
    ap.add_argument(
        "--oracle", action="store_true", help="associate the observations by ground truth (an upper bound)"
    )
    ap.add_argument(
        "--jitter", type=float, default=0.0, help="move every fused observation by noise of this σ, m"
    )
    ap.add_argument(
        "--jitter-seeds",
        nargs="+",
        type=int,
        default=[0],
        help="seeds of the --jitter noise: one tracking run of each recording per seed, and their spread",
    )
    ap.add_argument(
        "--without",
        nargs="+",
        default=[],
        choices=STAGES,
        metavar="STAGE",
        help=f"switch these offline tracking stages off (ablation): {', '.join(STAGES)}",
    )
    ap.add_argument(
        "--min-walk",
        type=float,
        default=None,
        metavar="M",
        help="the walk gate of laser-only labels (LabelOptions.min_walk_m; default as studio label)",
    )
    ap.add_argument(
        "--likelihood",
        action="store_true",
        help="compare how well our association and the ground truth's fit the tracker's model",
    )
    args = ap.parse_args()
    if args.laser_step is not None and not args.laser_step > 0:
        ap.error(f"--laser-step must be > 0 degrees, got {args.laser_step}")
    if args.camera_rate is not None and not args.camera_rate > 0:
        ap.error(f"--camera-rate must be > 0 Hz, got {args.camera_rate}")
    options = LabelOptions()
    if args.min_walk is not None:
        options = replace(options, min_walk_m=args.min_walk)
    if args.without:
        options = replace(options, tracking=replace(options.tracking, **dict.fromkeys(args.without)))
    total: Counter[str] = Counter()
    total_handovers: Counter[str] = Counter()
    total_undone = total_taken = total_check = total_first = total_points = total_points_first = 0
    runs: list[Run] = []
    for seed in args.seeds:
        rec = recording(
            args.scenario, args.seconds, seed, laser_step_deg=args.laser_step, camera_rate_hz=args.camera_rate
        )
        if args.image_period is None:
            # laser only: a pass one without the image detector (~10x faster, stored on its own)
            frames, cam = perception(rec, replace(options, sources="laser") if args.laser_only else options)
        else:
            frames, cam = perception(rec, replace(options, image_period_s=0.0))
            frames = thin_images(frames, args.image_period)
            options = replace(options, image_period_s=args.image_period)
        if args.laser_again:
            frames = laser_again(frames)
        run_options = options
        if args.laser_only:
            frames = [replace(f, image=None, appearance=None) for f in frames]
            cam, run_options = None, replace(options, sources="laser")
        gt = read_labels(rec / "ground_truth.jsonl")
        t = time.perf_counter()
        fused_once = fuse_all(frames, cam, run_options)
        t_fuse = time.perf_counter() - t
        for jseed in args.jitter_seeds if args.jitter > 0 else [0]:
            t = time.perf_counter()
            fused = fused_once if args.jitter <= 0 else jitter(fused_once, args.jitter, (jseed, seed))
            tracker = oracle_tracker(fused, gt) if args.oracle else None
            seen: dict[str, Any] = {}
            if args.likelihood:
                tracker, seen = capture(tracker or track_offline)
            labels, _ = track_all(frames, fused, run_options, has_camera=cam is not None, tracker=tracker)
            t_track = time.perf_counter() - t
            ev = evaluate(LabelSet.from_frames(labels), gt)
            m = ev.metrics()
            minutes = (labels[-1].stamp_ns - labels[0].stamp_ns) / 60e9
            runs.append(Run(jseed, seed, m["id_switches"], m["f1"], m["mota"], m["idf1"], minutes))
            tag = f" jitter seed {jseed}" if args.jitter > 0 else ""
            print(
                f"{rec.name}{tag}: F1 {m['f1']:.3f} (P {m['precision']:.3f} R {m['recall']:.3f}) "
                f"MOTA {m['mota']:.3f} IDF1 {m['idf1']:.3f} HOTA {m['hota']:.3f} IDSW {m['id_switches']} "
                f"({m['id_switches'] / minutes:.1f}/min); static map + fusion {t_fuse:.1f} s, "
                f"tracking {t_track:.1f} s",
                flush=True,
            )
            if args.likelihood:
                compare_likelihood(seen, oracle_tracker(fused, gt))
            if args.switches:
                kinds, taken, undone, check, first, n_points, n_first = switches(labels, ev, gt)
                total += kinds
                total_taken += taken
                total_undone += undone
                total_check += check
                total_first += first
                total_points += n_points
                total_points_first += n_first
                print(
                    "  " + ", ".join(f"{k} {n}" for k, n in sorted(kinds.items())) + f"; {taken} onto "
                    f"someone else's track; {undone} undone; "
                    f"{check} to check ({first} first), review points {n_points} "
                    f"({n_points / minutes:.1f}/min, {n_first} to check first)"
                )
            if args.handovers:
                kinds = handovers(ev, gt)
                total_handovers += kinds
                print("  handovers: " + ", ".join(f"{k} {n}" for k, n in sorted(kinds.items())))
    for line in summary(runs):
        print(line)
    if args.handovers and len(args.seeds) > 1:
        print("all handovers: " + ", ".join(f"{k} {n}" for k, n in sorted(total_handovers.items())))
    if args.switches and len(args.seeds) > 1:
        from studio.labels.review import FIRST_DOUBT

        print(
            "all: "
            + ", ".join(f"{k} {n}" for k, n in sorted(total.items()))
            + f"; {total_taken} of them onto a track that last had someone else; {total_undone} undone "
            f"(A to B and back within {UNDONE_S:g} s)"
        )
        minutes = sum(r.minutes for r in runs)
        print(
            f"all: {total_check} of {sum(total.values())} switches to check (within {CHECK_S:g} s of a "
            f"review point on their tracks); {total_points} review points ({total_points / minutes:.1f}/min)"
        )
        print(
            f"all: {total_first} switches to check first (a point of doubt >= {FIRST_DOUBT:g}: "
            f"{total_points_first} points, {total_points_first / minutes:.1f}/min)"
        )


if __name__ == "__main__":
    main()
