"""Re-decide who is who while people are close, with the whole of their trajectories known.

The online tracker assigns each frame's detections from predictions made with the past alone. When two
people come within half a metre, their detections merge or shift by a few decimetres and a coasting track's
prediction overshoots (someone slowing down), so for a second the tracks take each other's detections in
turn: the evaluator sees a swap and a swap back.

For every two final tracks whose smoothed positions come closer than ``close_m`` (an *encounter*, padded by
``pad_frames`` on each side), the observations the two tracks held inside it are distributed between them
again: a beam search over the frames (in each, the two observations kept or exchanged, or one observation
given to either track) runs both tracks' constant-velocity Kalman filters from their states before the
encounter and scores each hypothesis by the negative log-likelihood of its observations, then of each
track's own observations for ``tail_frames`` after the encounter. The best hypothesis replaces the online
assignment when it scores ``margin`` better. Every observation stays with one of the two tracks.

Clothing colours take part when both tracks were described by ``appearance_views`` observations before the
encounter (their median colours are the tracks' colours then). A described observation given to a track
costs ``appearance_weight`` per ΔE of its difference to that track's colours (counted up to
``appearance_cap``), and the tracks may also leave the encounter *exchanged*: the beam search runs once with
each track keeping its own tail and once with the tails exchanged (each track continuing on the other's
observations after the encounter), and the median colours of each tail's first ``appearance_views``
described observations after it count as that many observations of the track that continues with them.
Motion alone cannot tell who leaves as whom when two people stand together or walk side by side (letting
it exchange tails made things worse, session 9), and colours alone are fooled by a crop that shows the
neighbour; together they decide the whole encounter at once. Without colours (a laser-only rig) the
tracks leave as they came, and :mod:`studio.track.swaps` and stitching have the last word. When only one
track has colours before the encounter (the camera did not describe the other: someone standing half
hidden), they take part only when they leave no doubt: the other tail has colours and matches them within
``one_side_match``, and the described track's own tail differs from them by more than ``one_side_differ``
ΔE or has no colours (the camera did not describe whom it left with: until session 43 this case was left
to motion, and on ``moving`` seed 14 a person walking past someone who stopped took the stopped one's
track); the undescribed track's observations then cost half the cap whoever takes them, and so does its
side of leaving. Letting one side's colours take part always got as many encounters wrong as right
(session 23). Where they leave doubt, the undescribed track's tail stands for it: with its colours after
the encounter as its colours, each described observation inside costs as above, but the tracks leave as
they came (the tails' colours decide who held what inside, not who leaves as whom); without colours
after it either, motion alone decides.

An encounter begins where both tracks exist, or where the later one begins: someone who appears beside
another person (stepping out from behind them, or out of the camera's blind spot) often has the other's
track take their first detections while their own track begins on the other's. A track that begins in the
encounter starts the beam search from its smoothed state at its first hit moved back a frame (its way
through the encounter is known from its later hits), with the forward filter's first covariance. Session
65 (``docs/results.md``): held-out ``moving`` seed 37 frames 95–105, a newcomer 0.4 m beside someone, three
switches to none.

Decided together, three or four tracks that come close at once (all ways of giving each frame's
observations to them, every permutation of their tails) did not do better than pair by pair (session 18,
``docs/results.md``), so encounters are decided in pairs.

A laser leg pair may also be split, one leg to each of two tracks, in a frame where fewer observations
than tracks were held: two people passing shoulder to shoulder put a leg of each side by side, the laser
detector pairs them, and the pair's centre lies between both people. A split scores two observations
(each leg with its own covariance, ``Observations.alt_of``) where the pair scored one. A leg's term is
negative, i.e. better than no observation, when it lies within about two standard deviations of its
track's prediction (with the 0.11 m leg σ and a track's own uncertainty, about 0.02 m² per axis, the
normalisation term is about −2), so a split wins where both legs fit their tracks and the pair's centre
fits neither. The online tracker splits pairs only between people walking together
(``UkfTrackerConfig.split_pair_max_relative_speed``); here, with both trajectories known, people passing
each other are split too. ``studio label`` turns the split off on rigs with a camera
(``EncounterConfig.split_legs``; :func:`studio.pipeline.label.tracking_config`): there it mostly fed a
duplicate track, one person's two legs given to two tracks 0.15–0.2 m apart (session 21,
``docs/results.md``), while people passing get a box each on the image frames.
"""

from __future__ import annotations

import bisect
import itertools
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from studio.track.appearance import appearance_distance
from studio.track.base import Observations
from studio.track.models import cv_matrix, white_accel_q
from studio.track.swaps import side_colours

__all__ = ["EncounterConfig", "reassign_encounters"]

FloatArray = NDArray[np.float64]
Hit = tuple[int, int]
Hits = list[Hit]
# hits -> forward-filtered states (K, 4), their covariances (K, 4, 4) and the smoothed states (K, 4) over
# the frames from the first hit's to the last hit's
Estimator = Callable[[Hits], tuple[FloatArray, FloatArray, FloatArray]]
_LOG_2PI = float(np.log(2.0 * np.pi))


@dataclass(frozen=True)
class EncounterConfig:
    """Options of :func:`reassign_encounters`.

    Attributes:
        close_m: two tracks whose smoothed positions are closer than this are in an encounter, metres.
        pad_frames: frames added on each side of an encounter.
        tail_frames: frames after the encounter whose observations also score a hypothesis.
        beam: hypotheses kept per frame.
        margin: the new assignment must lower the negative log-likelihood by more than this.
        appearance_weight: cost of a described observation per ΔE of colour difference to the colours of
            the track it is given to (0: motion alone, and the tracks leave every encounter as they came).
        appearance_cap: colour differences count up to this, ΔE.
        appearance_views: described observations whose median colours are a track's colours before an
            encounter and its tail's after it.
        split_legs: a laser leg pair may go one leg to each of two tracks (see the module docstring).
        one_side_match: when only one track has colours before the encounter, the other track's tail must
            match them within this, ΔE …
        one_side_differ: … and its own tail (where described) differ from them by more than this, for colours
            to take part.

    ``pad_frames`` 10 and ``margin`` 5 (session 16; before 5 and 10): on 16 simulated ``moving`` recordings
    (seeds 1–8 of simulator versions 2 and 3) identity switches 128 → 112, F1 and MOTA up 0.001–0.002, IDF1
    +0.003 / −0.004; laser-only replays 210 → 208 switches. Colours and exchanged tails: session 18
    (``docs/results.md``). ``tail_frames`` 20 (session 23; before 10): the tails' colours are then taken
    from further past the encounter, where a crop shows the neighbour less; v4 ``moving`` seed 2 3 → 0
    switches, the other replays of ``docs/results.md`` unchanged. One side's colours (session 24): of the
    17 encounters on v4 ``moving`` seeds 1–12 with one side described and both tails coloured, two fit the
    rule (seed 3: own tail 45.8 ΔE away, the other 4.1; seed 12: 39.7 and 2.7); in the others the own tail
    lies within 7.4 or the other 23 or more away, so any ``one_side_match`` in 5–23 with any
    ``one_side_differ`` in 8–39 picks these two alone.
    """

    close_m: float = 0.8
    pad_frames: int = 10
    tail_frames: int = 20
    beam: int = 16
    margin: float = 5.0
    appearance_weight: float = 0.2
    appearance_cap: float = 20.0
    appearance_views: int = 5
    split_legs: bool = True
    one_side_match: float = 8.0
    one_side_differ: float = 25.0

    def __post_init__(self) -> None:
        if self.close_m <= 0 or self.beam < 1 or min(self.pad_frames, self.tail_frames, self.margin) < 0:
            raise ValueError("close_m and beam must be positive, pad_frames, tail_frames and margin >= 0")
        if self.appearance_weight < 0 or self.appearance_cap <= 0 or self.appearance_views < 1:
            raise ValueError("appearance_weight must be >= 0, appearance_cap and appearance_views positive")
        if not 0 <= self.one_side_match <= self.one_side_differ:
            raise ValueError("one_side_match must be >= 0 and at most one_side_differ")


def _windows(
    tracks: dict[int, Hits], smoothed: dict[int, FloatArray], cfg: EncounterConfig
) -> list[tuple[int, int, int, int]]:
    """``(id_a, id_b, first frame, last frame)`` of every encounter, padded, in time order; both tracks
    exist before ``first`` or begin there."""
    out = []
    for a, b in itertools.combinations(sorted(tracks), 2):
        fa, fb = tracks[a][0][0], tracks[b][0][0]
        f0 = max(fa, fb, 1)
        f1 = min(fa + len(smoothed[a]), fb + len(smoothed[b])) - 1
        if f0 > f1:
            continue
        xa, xb = smoothed[a][f0 - fa : f1 - fa + 1, :2], smoothed[b][f0 - fb : f1 - fb + 1, :2]
        close = np.flatnonzero(np.hypot(*(xa - xb).T) < cfg.close_m)
        if not len(close):
            continue
        for run in np.split(close, np.flatnonzero(np.diff(close) > 2 * cfg.pad_frames) + 1):
            out.append((max(f0, f0 + run[0] - cfg.pad_frames), a, b, min(f1, f0 + run[-1] + cfg.pad_frames)))
    return [(a, b, f0, f1) for f0, a, b, f1 in sorted(out)]


_Option = tuple[Hit | None, ...]  # per track: the observation it is given, or None


def _beam(
    obs: Sequence[Observations],
    x0: FloatArray,
    P0: FloatArray,
    options: dict[int, list[_Option]],
    frames: range,
    accel_sigma: float,
    beam: int,
    app: dict[Hit, FloatArray],
) -> tuple[float, list[_Option]]:
    """The best way through ``frames``, choosing one of ``options[i]`` (the observation of each track; none
    where absent) in each frame, by the negative log-likelihood of the chosen observations under the
    tracks' constant-velocity Kalman filters started from ``x0`` ``(k, 4)``, ``P0`` ``(k, 4, 4)`` before
    the first frame, plus the colour cost ``app[hit][track]`` of each described observation. All kept
    hypotheses advance together (arrays over hypotheses); the ``beam`` best survive each frame.

    Returns:
        The best hypothesis's score and its choice in each frame.
    """
    k = len(x0)
    x, P = x0[None].copy(), P0[None].copy()  # (H, k, 4), (H, k, 4, 4)
    nll = np.zeros(1)
    back: list[tuple[NDArray[np.int64], NDArray[np.int64], list[_Option]]] = []
    for i in frames:
        dt = (obs[i].stamp_ns - obs[i - 1].stamp_ns) * 1e-9
        F, Q = cv_matrix(dt), white_accel_q(dt, accel_sigma)
        x = x @ F.T
        P = F @ P @ F.T + Q
        opts = options.get(i, [(None,) * k])
        n_h, n_o = len(nll), len(opts)
        x = np.repeat(x, n_o, axis=0)
        P = np.repeat(P, n_o, axis=0)
        nll = np.repeat(nll, n_o)
        for t in range(k):
            rows = [o for o, opt in enumerate(opts) if opt[t] is not None]
            if not rows:
                continue
            hits = [opts[o][t] for o in rows]
            sel = (np.arange(n_h)[:, None] * n_o + np.array(rows)[None, :]).ravel()
            z = np.array([obs[i].xy[h[1]] for h in hits])  # type: ignore[index]
            R = np.array([obs[i].cov[h[1]] for h in hits])  # type: ignore[index]
            z, R = np.tile(z, (n_h, 1)), np.tile(R, (n_h, 1, 1))
            xs, Ps = x[sel, t], P[sel, t]
            S = Ps[:, :2, :2] + R
            det = S[:, 0, 0] * S[:, 1, 1] - S[:, 0, 1] * S[:, 1, 0]
            Si = np.stack([S[:, 1, 1], -S[:, 0, 1], -S[:, 1, 0], S[:, 0, 0]], axis=-1).reshape(-1, 2, 2)
            Si /= det[:, None, None]
            y = z - xs[:, :2]
            K = Ps[:, :, :2] @ Si
            x[sel, t] = xs + np.einsum("hij,hj->hi", K, y)
            P[sel, t] = Ps - K @ Ps[:, :2, :]
            nll[sel] += 0.5 * (np.einsum("hi,hij,hj->h", y, Si, y) + np.log(det) + 2.0 * _LOG_2PI)
            if app:
                nll[sel] += np.tile([app[h][t] if h in app else 0.0 for h in hits], n_h)
        keep = np.argsort(nll, kind="stable")[:beam]
        back.append((keep // n_o, keep % n_o, opts))
        x, P, nll = x[keep], P[keep], nll[keep]
    choice: list[_Option] = []
    h = 0
    for parent, opt, opts in reversed(back):
        choice.append(opts[int(opt[h])])
        h = int(parent[h])
    return float(nll[0]), choice[::-1]


def _options(o: Observations, i: int, held: Sequence[Hit | None], split_legs: bool) -> list[_Option]:
    """The ways to give frame ``i``'s observations held by the tracks (``held``, one entry per track) to
    distinct tracks; where fewer were held than there are tracks (and ``split_legs``), also a laser leg
    pair's two legs to two tracks."""
    k = len(held)
    hits = [h for h in held if h is not None]
    sets = [hits]
    if split_legs and o.alt_of is not None and len(hits) < k:
        for n, h in enumerate(hits):
            legs = np.flatnonzero(o.alt_of == h[1])
            if len(legs) == 2:
                sets.append([*hits[:n], (i, int(legs[0])), (i, int(legs[1])), *hits[n + 1 :]])
    if len(hits) == 2 and o.joins is not None:
        sets += [[(i, r) for r in rows] for rows in _pairings(o, hits[0][1], hits[1][1])]
    out = []
    for items in sets:
        for slots in itertools.permutations(range(k), len(items)):
            opt: list[Hit | None] = [None] * k
            for h, s in zip(items, slots, strict=True):
                opt[s] = h
            out.append(tuple(opt))
    return out


def _pairings(o: Observations, ra: int, rb: int) -> list[tuple[int, int]]:
    """The other ways to pair the legs behind two held rows: for two leg pairs, the midpoints of their legs
    paired the other ways (``Observations.joins``); for two such midpoints that complement each other, the
    two pairs and the third way."""
    if o.joins is not None and o.alt_of is not None and o.complement(ra) == rb:
        pa, pb = (int(o.alt_of[leg]) for leg in o.joins[ra])
        return [(pa, pb), *[c for c in o.regroupings(pa, pb) if set(c) != {ra, rb}]]
    return o.regroupings(ra, rb)


def reassign_encounters(
    obs: Sequence[Observations],
    tracks: dict[int, Hits],
    estimate: Estimator,
    *,
    accel_sigma: float,
    config: EncounterConfig | None = None,
) -> tuple[dict[int, Hits], int]:
    """The tracks' hits after re-deciding every encounter (see the module docstring), and how many were
    changed; ``tracks`` is not modified."""
    cfg = config or EncounterConfig()
    tracks = {tid: sorted(h) for tid, h in tracks.items() if h}
    changed = 0
    smoothed = {tid: estimate(h)[2] for tid, h in tracks.items()}
    for a, b, f0, f1 in _windows(tracks, smoothed, cfg):
        if not all(tracks[t] and tracks[t][0][0] <= f0 <= tracks[t][-1][0] + 1 for t in (a, b)):
            continue  # an earlier re-decision moved a track's start or end past the encounter, or emptied it
        changed += _redecide(obs, tracks, [a, b], f0, f1, estimate, accel_sigma, cfg)
    return {tid: h for tid, h in tracks.items() if h}, changed


def _redecide(
    obs: Sequence[Observations],
    tracks: dict[int, Hits],
    pair: list[int],
    f0: int,
    f1: int,
    estimate: Estimator,
    accel_sigma: float,
    cfg: EncounterConfig,
) -> bool:
    """Re-decide the encounter of the tracks ``pair`` over frames ``f0``–``f1`` in place (the code holds for
    any number of tracks); whether anything changed."""
    k = len(pair)
    hs = [tracks[t] for t in pair]
    last = min(f1 + cfg.tail_frames, len(obs) - 1)
    # each track's hits from f0 to last (hits are sorted by frame)
    spans = [h[bisect.bisect_left(h, (f0, -1)) : bisect.bisect_left(h, (last + 1, -1))] for h in hs]
    held: dict[int, list[Hit | None]] = {}
    for t, span in enumerate(spans):
        for hit in span:
            if hit[0] <= f1:
                held.setdefault(hit[0], [None] * k)[t] = hit
    if not held:
        return False
    tails = [{i: r for i, r in span if i > f1} for span in spans]
    app, before, after, exchange = _appearance(obs, hs, spans, f0, last, cfg)
    identity = tuple(range(k))
    orders = list(itertools.permutations(range(k))) if app and exchange else [identity]

    def tail(order: tuple[int, ...]) -> dict[int, list[_Option]]:
        return {
            i: [tuple((i, tails[s][i]) if i in tails[s] else None for s in order)]
            for i in range(f1 + 1, last + 1)
        }

    def leaving(order: tuple[int, ...]) -> float:
        """Colour cost of the tracks leaving the encounter with the tails of ``order``."""
        if not app:
            return 0.0
        cost = 0.0
        for ref, s in zip(before, order, strict=True):  # a tail without colours: half the cap, either way
            c = after[s]
            if c is None or ref is None:
                cost += 0.5 * cfg.appearance_cap
            else:
                cost += min(appearance_distance(c, ref), cfg.appearance_cap)
        return cfg.appearance_weight * cfg.appearance_views * cost

    states = [estimate(h) for h in hs]
    x0, P0 = _start_states(obs, states, hs, f0)
    frames = range(f0, last + 1)
    current = {i: [tuple(v)] for i, v in held.items()}
    every = {i: _options(obs[i], i, v, cfg.split_legs) for i, v in held.items()}
    now = _beam(obs, x0, P0, tail(identity) | current, frames, accel_sigma, 1, app)[0] + leaving(identity)
    best, choice, best_order = np.inf, [], identity
    for order in orders:
        score, path = _beam(obs, x0, P0, tail(order) | every, frames, accel_sigma, cfg.beam, app)
        score += leaving(order)
        if score < best:
            best, choice, best_order = score, path, order
    if best + cfg.margin >= now:
        return False
    moved: list[Hits] = [[] for _ in range(k)]
    for opt in choice[: f1 - f0 + 1]:
        for t, given in enumerate(opt):
            if given is not None:
                moved[t].append(given)
    for t, s in enumerate(best_order):
        outside = [hit for hit in hs[t] if hit[0] < f0] + [hit for hit in hs[s] if hit[0] > f1]
        tracks[pair[t]] = sorted(outside + moved[t])
    return True


def _start_states(
    obs: Sequence[Observations],
    states: list[tuple[FloatArray, FloatArray, FloatArray]],
    hs: list[Hits],
    f0: int,
) -> tuple[FloatArray, FloatArray]:
    """The tracks' states and covariances before frame ``f0``: a track's forward-filtered state there, or,
    for one that begins at ``f0``, its smoothed state at its first hit moved back a frame with the forward
    filter's first covariance (its motion through the encounter known from its later hits)."""
    xs, Ps = [], []
    for (x, P, smoothed), h in zip(states, hs, strict=True):
        if h[0][0] < f0:
            xs.append(x[f0 - 1 - h[0][0]])
            Ps.append(P[f0 - 1 - h[0][0]])
        else:
            F = cv_matrix(-(obs[f0].stamp_ns - obs[f0 - 1].stamp_ns) * 1e-9)
            xs.append(F @ smoothed[0])
            Ps.append(P[0])
    return np.stack(xs), np.stack(Ps)


def _appearance(
    obs: Sequence[Observations], hs: list[Hits], spans: list[Hits], f0: int, last: int, cfg: EncounterConfig
) -> tuple[dict[Hit, FloatArray], list[NDArray[np.float32] | None], list[NDArray[np.float32] | None], bool]:
    """The colour cost, per track, of each described observation the tracks hold from ``f0`` to ``last``
    (their hits there: ``spans``; none when colours do not take part, see the module docstring), each
    track's colours before the encounter and its tail's after ``last``, and whether the tracks may leave
    the encounter exchanged."""
    views = cfg.appearance_views
    before = [side_colours(obs, h, f0, last, False, views) for h in hs]
    after = [side_colours(obs, h, f0, last, True, views) for h in hs]
    refs, exchange = before, True
    if cfg.appearance_weight <= 0 or all(c is None for c in before):
        return {}, before, after, False
    if any(c is None for c in before) and not _one_side_decides(before, after, cfg):
        # a track the camera did not describe before the encounter (it began there) is known by its
        # tail's colours; the tracks then leave as they came, and colours only say who held what inside
        refs, exchange = [b if b is not None else a for b, a in zip(before, after, strict=True)], False
        if any(c is None for c in refs):
            return {}, before, after, False
    out = {}
    for span in spans:
        for i, r in span:
            app = obs[i].appearance
            if app is not None and np.all(np.isfinite(app[r])):
                d = [
                    0.5 * cfg.appearance_cap
                    if c is None
                    else min(appearance_distance(app[r], c), cfg.appearance_cap)
                    for c in refs
                ]
                out[(i, r)] = cfg.appearance_weight * np.array(d)
    return out, before, after, exchange


def _one_side_decides(
    before: list[NDArray[np.float32] | None], after: list[NDArray[np.float32] | None], cfg: EncounterConfig
) -> bool:
    """Whether the colours of the tracks described before an encounter leave no doubt where they went:
    for each described track, every other track's tail has colours and one of them matches its colours
    within ``one_side_match``, while its own tail differs from them by more than ``one_side_differ`` or has
    no colours (the camera did not describe it after the encounter: someone standing half hidden)."""
    for t, ref in enumerate(before):
        if ref is None:
            continue
        others = [c for s, c in enumerate(after) if s != t]
        if any(c is None for c in others):
            return False
        if min(appearance_distance(c, ref) for c in others if c is not None) >= cfg.one_side_match:
            return False
        own = after[t]
        if own is not None and appearance_distance(own, ref) <= cfg.one_side_differ:
            return False
    return True
