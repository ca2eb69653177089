"""Simulated walkers and detections for the tracking tests (exposed through the ``sim`` fixture).

People walk between random waypoints at 0.8–1.4 m/s, stop for a while at some of them and turn; frames come
at about 10 Hz with jittered (irregular) stamps; detections have 5 cm noise, 10 % misses, some clutter, and
optional occlusion intervals. Each person wears clothes of random colours (an appearance descriptor, L*a*b* of
torso and legs); each detection carries a noisy copy of it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from types import SimpleNamespace

import numpy as np
import pytest
from numpy.typing import NDArray

from studio.geometry.se import Pose2
from studio.track import Observations, TrackResult

FloatArray = NDArray[np.float64]
APP_DIM = 6


def random_colours(rng: np.random.Generator, n: int) -> FloatArray:
    """(n, 6) clothing colours: L* 10–90, a* and b* within ±60, for torso and legs."""
    lo, hi = np.array([10.0, -60, -60] * 2), np.array([90.0, 60, 60] * 2)
    return rng.uniform(lo, hi, (n, APP_DIM))


@dataclass
class Scene:
    """Ground truth: ``stamps_ns`` (K,), ``truth`` (K, P, 2) m, ``visible`` (K, P), ``colours`` (P, D)."""

    stamps_ns: NDArray[np.int64]
    truth: FloatArray
    visible: NDArray[np.bool_]
    colours: FloatArray


@dataclass
class Detected:
    """Observations per frame and, per frame, the person index of each ``det_index`` (-1: clutter)."""

    observations: list[Observations]
    owner: list[dict[int, int]] = field(default_factory=list)


def stamps(
    seconds: float, *, rate_hz: float = 10.0, jitter_s: float = 0.015, seed: int = 0
) -> NDArray[np.int64]:
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, seconds, 1.0 / rate_hz)
    t = t + rng.uniform(-jitter_s, jitter_s, len(t))
    t[0] = 0.0
    return np.round(np.sort(t) * 1e9).astype(np.int64) + 1_700_000_000_000_000_000


def walker(t: FloatArray, rng: np.random.Generator, *, area: float = 4.0) -> FloatArray:
    """One person's positions (len(t), 2) at times t (s): waypoints, stops and turns."""
    p = rng.uniform(-area, area, 2)
    out = np.zeros((len(t), 2))
    time, k = float(t[0]), 0
    while k < len(t):
        if rng.random() < 0.3:  # stop
            until = time + rng.uniform(0.5, 2.0)
            while k < len(t) and t[k] <= until:
                out[k] = p
                k += 1
            time = until
        goal = rng.uniform(-area, area, 2)
        speed = rng.uniform(0.8, 1.4)
        dur = float(np.linalg.norm(goal - p)) / speed
        while k < len(t) and t[k] <= time + dur:
            out[k] = p + (goal - p) * (t[k] - time) / dur
            k += 1
        p, time = goal, time + dur
    return out


def random_scene(n_people: int, seconds: float, *, seed: int = 0) -> Scene:
    rng = np.random.default_rng(seed)
    st = stamps(seconds, seed=seed)
    t = (st - st[0]) * 1e-9
    truth = np.stack([walker(t, rng) for _ in range(n_people)], axis=1)
    colours = random_colours(rng, n_people)
    return Scene(st, truth, np.ones((len(st), n_people), dtype=bool), colours)


def occlude(scene: Scene, person: int, start_s: float, seconds: float) -> None:
    t = (scene.stamps_ns - scene.stamps_ns[0]) * 1e-9
    scene.visible[(t >= start_s) & (t < start_s + seconds), person] = False


def detect(
    scene: Scene,
    *,
    seed: int = 1,
    noise_m: float = 0.05,
    miss: float = 0.1,
    clutter_rate: float = 0.2,
    frames: list[Pose2] | None = None,
    appearance: bool = True,
) -> Detected:
    """Noisy detections of the scene; with ``frames`` (one robot pose per frame) in that robot frame."""
    rng = np.random.default_rng(seed)
    out = Detected([])
    for k, stamp in enumerate(scene.stamps_ns):
        xy, owner, app = [], [], []
        for p in np.flatnonzero(scene.visible[k]):
            if rng.random() < miss:
                continue
            xy.append(scene.truth[k, p] + rng.normal(0.0, noise_m, 2))
            owner.append(int(p))
            app.append(scene.colours[p] + rng.normal(0.0, 3.0, APP_DIM))
        for _ in range(rng.poisson(clutter_rate)):
            xy.append(rng.uniform(-5.0, 5.0, 2))
            owner.append(-1)
            app.append(random_colours(rng, 1)[0])
        order = rng.permutation(len(xy))
        pts = np.array(xy).reshape(-1, 2)[order]
        if frames is not None:
            pts = frames[k].inverse().apply(pts)
        det = np.arange(len(pts)) + 100  # det_index need not be the row
        out.observations.append(
            Observations.create(
                int(stamp),
                pts,
                sigma_m=noise_m,
                appearance=np.array(app).reshape(-1, APP_DIM)[order] if appearance else None,
                det_index=det,
            )
        )
        out.owner.append({int(det[i]): owner[o] for i, o in enumerate(order)})
    return out


def id_switches(result: TrackResult, owner: list[dict[int, int]]) -> tuple[int, dict[int, list[int]]]:
    """Identity switches: per person, how often the track id on its detections changes (tiny local helper).

    Returns:
        ``(switches, ids)`` with ``ids[person]`` the distinct track ids, in order of appearance.
    """
    last: dict[int, int] = {}
    ids: dict[int, list[int]] = {}
    switches = 0
    for frame, own in zip(result.frames, owner, strict=True):
        for p in frame.points:
            person = own.get(p.det_index, -1)
            if person < 0:
                continue
            if person in last and last[person] != p.track_id:
                switches += 1
            last[person] = p.track_id
            if p.track_id not in ids.setdefault(person, []):
                ids[person].append(p.track_id)
    return switches, ids


def rmse(result: TrackResult, owner: list[dict[int, int]], scene: Scene) -> float:
    """RMSE (m) of the points that carry a person's detection, against the truth."""
    err = [
        np.sum((p.xy - scene.truth[k, own[p.det_index]]) ** 2)
        for k, (frame, own) in enumerate(zip(result.frames, owner, strict=True))
        for p in frame.points
        if own.get(p.det_index, -1) >= 0
    ]
    return float(np.sqrt(np.mean(err)))


def points(stamp_ns: int, xy: FloatArray, source: str, appearance: FloatArray | None = None) -> Observations:
    """One frame of point observations at ``xy`` ``(N, 2)``, 0.1 m standard deviation, score 1."""
    n = len(xy)
    app = None if appearance is None else np.asarray(appearance, np.float32)[:n]
    return Observations(
        stamp_ns, xy, np.tile(np.eye(2) * 0.01, (n, 1, 1)), (source,) * n, np.ones(n), app, np.arange(n)
    )


@pytest.fixture(scope="session")
def sim() -> SimpleNamespace:
    """The helpers of this module."""
    return SimpleNamespace(
        Scene=Scene,
        stamps=stamps,
        walker=walker,
        random_scene=random_scene,
        occlude=occlude,
        detect=detect,
        id_switches=id_switches,
        rmse=rmse,
        points=points,
        APP_DIM=APP_DIM,
    )
