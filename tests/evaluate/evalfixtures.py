"""Random tracking fixtures for the evaluator tests (births, deaths, noise, misses, clutter, id swaps)."""

from __future__ import annotations

import numpy as np

from studio.labels import LabelFrame, LabelPerson


def frame(k: int, people: dict[int, tuple[float, float]], **kw: object) -> LabelFrame:
    """A frame from ``{id: (x, y)}``."""
    return LabelFrame(
        frame=k,
        people=tuple(LabelPerson(id=i, x=float(x), y=float(y)) for i, (x, y) in people.items()),
        **kw,  # type: ignore[arg-type]
    )


def _snap(v: tuple[float, float]) -> tuple[float, float]:
    return (round(v[0] * 20) / 20, round(v[1] * 20) / 20)


def random_sequence(seed: int, *, radius: float = 0.2) -> tuple[list[LabelFrame], list[LabelFrame | None]]:
    """Ground-truth frames and aligned predicted frames (None: no predicted frame for that GT frame)."""
    rng = np.random.default_rng(seed)
    n_frames = int(rng.integers(5, 45))
    n_tracks = int(rng.integers(0, 9))
    area = float(rng.uniform(0.6, 4.0))  # small areas crowd people together → ambiguous matchings
    births = rng.integers(0, n_frames, n_tracks)
    lengths = rng.integers(1, n_frames + 1, n_tracks)
    pos = rng.uniform(0, area, (n_tracks, 2))
    vel = rng.normal(0, 0.05, (n_tracks, 2))
    p_miss = float(rng.uniform(0.0, 0.5))
    noise = float(rng.uniform(0.1, 0.8)) * radius
    clutter = float(rng.uniform(0.0, 2.0))
    p_no_frame = float(rng.uniform(0.0, 0.2))
    if seed % 3 == 0:  # a good tracker: few misses, little noise and clutter
        p_miss, noise, clutter = p_miss / 5, noise / 3, clutter / 8
    grid = seed % 4 == 1  # positions on a 5 cm grid: exact distance ties and pairs at exactly the radius
    # predicted identity of each GT track, changed now and then (swaps, fragmentation → new ids)
    pred_id = {t: 100 + t for t in range(n_tracks)}
    next_id = 1000
    gts: list[LabelFrame] = []
    preds: list[LabelFrame | None] = []
    for k in range(n_frames):
        pos += vel + rng.normal(0, 0.02, pos.shape)
        alive = [t for t in range(n_tracks) if births[t] <= k < births[t] + lengths[t]]
        if rng.random() < 0.1:
            alive = []  # an empty frame
        order = rng.permutation(alive).tolist() if alive else []
        gt = {100_000 + t: (pos[t, 0], pos[t, 1]) for t in order}
        if len(alive) >= 2 and rng.random() < 0.15:  # swap two predicted identities
            a, b = rng.choice(alive, 2, replace=False)
            pred_id[int(a)], pred_id[int(b)] = pred_id[int(b)], pred_id[int(a)]
        if alive and rng.random() < 0.05:  # a track restarts under a new id
            t = int(rng.choice(alive))
            pred_id[t] = next_id
            next_id += 1
        pr: dict[int, tuple[float, float]] = {}
        for t in order:
            if rng.random() < p_miss:
                continue
            x, y = pos[t] + rng.normal(0, noise, 2)
            pr[pred_id[t]] = (x, y)
        for _ in range(int(rng.poisson(clutter))):
            cid = int(rng.integers(5000, 5040))
            if cid in pr:
                continue
            if alive and rng.random() < 0.5:  # clutter near someone
                t = int(rng.choice(alive))
                pr[cid] = tuple(pos[t] + rng.normal(0, radius, 2))
            else:
                pr[cid] = tuple(rng.uniform(0, area, 2))
        keys = list(pr)
        rng.shuffle(keys)
        if grid:
            gt = {i: _snap(v) for i, v in gt.items()}
            pr = {i: _snap(v) for i, v in pr.items()}
        gts.append(frame(k, gt))
        preds.append(None if rng.random() < p_no_frame else frame(k, {i: pr[i] for i in keys}))
    return gts, preds
