"""People's bodies: appearance, an articulated skeleton with a walking gait, and its primitives.

One skeleton drives both sensors: the laser sees the two shins where they cross the scanning plane
(:func:`leg_circles`), the camera sees capsules built on the same joints (:func:`body_capsules`). The
gait is a function of the walked distance (phase) and speed: the feet swing fore and aft in opposition
with an amplitude that grows with speed and vanishes when the person stands (feet together), the knees
follow by two-bone inverse kinematics and the arms swing against the legs.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from studio.sim.base import LASER_Z
from studio.sim.motion import stride_length

__all__ = ["Appearance", "Capsules", "body_capsules", "draw_appearance", "leg_circles"]

FloatArray = NDArray[np.floating[Any]]

_SKIN = ((170, 195, 235), (140, 172, 222), (112, 148, 200), (80, 112, 165), (55, 78, 118))
_HAIR = ((25, 25, 30), (30, 45, 70), (40, 70, 110), (100, 165, 205), (150, 150, 150))
_SHIRT = (
    (235, 235, 235), (35, 35, 35), (120, 120, 120), (90, 40, 20), (40, 40, 190), (170, 90, 40),
    (60, 130, 60), (40, 190, 220), (30, 120, 230), (120, 50, 110), (150, 190, 215), (130, 130, 40),
)  # fmt: skip
_TROUSERS = ((120, 70, 40), (30, 30, 32), (85, 85, 85), (130, 170, 190), (70, 40, 30), (50, 60, 45))
_SHOES = ((30, 30, 30), (225, 225, 225), (60, 80, 110), (40, 40, 120))

# material of each capsule: 0 skin, 1 head (skin + hair), 2 shirt, 3 sleeve, 4 trousers, 5 shoes
_MATERIALS = np.array([2, 2, 4, 2, 0, 1, 3, 3, 3, 3, 0, 0, 4, 4, 4, 4, 5, 5, 2])


@dataclass(frozen=True)
class Appearance:
    """How one person looks.

    Attributes:
        height: body height, metres.
        colors: (6, 3) BGR colours of the materials skin, hair, shirt, sleeve/forearm, trousers, shoes.
        dark: how dark the trousers are in [0, 1] (raises the laser dropout rate on the legs).
    """

    height: float
    colors: FloatArray
    dark: float

    def __post_init__(self) -> None:
        if np.shape(self.colors) != (6, 3):
            raise ValueError("Appearance.colors must be (6, 3)")


def draw_appearance(rng: np.random.Generator) -> Appearance:
    """A random person: height 1.58–1.92 m, skin, hair and clothing colours."""
    jitter = lambda c: np.clip(np.array(c, float) * rng.uniform(0.85, 1.1) + rng.normal(0, 8, 3), 0, 255)  # noqa: E731
    skin = jitter(_SKIN[int(rng.integers(len(_SKIN)))])
    hair = jitter(_HAIR[int(rng.integers(len(_HAIR)))])
    shirt = jitter(_SHIRT[int(rng.integers(len(_SHIRT)))])
    trousers = jitter(_TROUSERS[int(rng.integers(len(_TROUSERS)))])
    shoes = jitter(_SHOES[int(rng.integers(len(_SHOES)))])
    sleeve = shirt if rng.random() < 0.55 else skin
    colors = np.stack([skin, hair, shirt, sleeve, trousers, shoes])
    dark = float(1.0 - trousers.mean() / 255.0)
    return Appearance(height=float(rng.uniform(1.58, 1.92)), colors=colors, dark=dark)


def _legs(
    h: FloatArray, speed: FloatArray, phase: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Hips, knees, ankles (P, 2, 3) in each person's frame (x forward, y left, z up) and gait factors (P,).

    Args:
        h: (P,) body heights, metres.
        speed: (P,) walking speeds, m/s.
        phase: (P,) gait phases, rad.
    """
    s = h / 1.75
    a = np.clip(speed / 0.35, 0.0, 1.0)
    D = a * stride_length(speed) / 4.0  # fore-aft amplitude of each foot
    hip_z = 0.52 * h
    sin, cos = np.sin(phase), np.cos(phase)
    n = h.shape[0]
    hips = np.zeros((n, 2, 3))
    hips[:, 0, 1], hips[:, 1, 1] = 0.09 * s, -0.09 * s
    hips[:, :, 2] = hip_z[:, None]
    ankles = hips.copy()
    ankles[:, 0, 0], ankles[:, 1, 0] = D * sin, -D * sin
    ankles[:, 0, 2] = 0.08 + 0.07 * a * np.maximum(0.0, cos)  # the swinging foot lifts
    ankles[:, 1, 2] = 0.08 + 0.07 * a * np.maximum(0.0, -cos)
    bone = (0.5 * (hip_z - 0.08) * 1.01)[:, None]
    d = ankles - hips
    L = np.linalg.norm(d, axis=2)
    u = d / L[..., None]
    perp = -u[..., 0:1] * u
    perp[..., 0] += 1.0  # forward minus its component along the leg: the knee bends forward
    perp /= np.linalg.norm(perp, axis=2, keepdims=True)
    bend = np.sqrt(np.maximum(bone**2 - (0.5 * L) ** 2, 0.0))
    knees = 0.5 * (hips + ankles) + bend[..., None] * perp
    return hips, knees, ankles, a


def _to_world(p: FloatArray, x: float, y: float, heading: float) -> FloatArray:
    c, s = np.cos(heading), np.sin(heading)
    out = p.copy()
    out[..., 0] = x + c * p[..., 0] - s * p[..., 1]
    out[..., 1] = y + s * p[..., 0] + c * p[..., 1]
    return out


def leg_circles(states: FloatArray, heights: FloatArray) -> FloatArray:
    """Where each person's shins cross the laser plane.

    Args:
        states: (P, 5) ``x, y, heading, speed, phase`` in the world (metres, rad, m/s, rad).
        heights: (P,) body heights, metres.

    Returns:
        (P, 2, 3) circles ``cx, cy, r`` (world, metres) of the left and right leg at z = LASER_Z.
    """
    st = np.asarray(states, dtype=np.float64).reshape(-1, 5)
    h = np.asarray(heights, dtype=np.float64)
    out = np.zeros((st.shape[0], 2, 3))
    if st.shape[0] == 0:
        return out
    _, knees, ankles, _ = _legs(h, st[:, 3], st[:, 4])
    w = np.clip((LASER_Z - ankles[..., 2]) / (knees[..., 2] - ankles[..., 2]), 0.0, 1.0)[..., None]
    p = ankles + w * (knees - ankles)  # (P, 2, 3) where the shins cross the laser plane
    c, s = np.cos(st[:, 2])[:, None], np.sin(st[:, 2])[:, None]
    out[..., 0] = st[:, 0:1] + c * p[..., 0] - s * p[..., 1]
    out[..., 1] = st[:, 1:2] + s * p[..., 0] + c * p[..., 1]
    out[..., 2] = (0.058 * h / 1.75)[:, None]
    return out


@dataclass(frozen=True)
class Capsules:
    """A body as capsules (a segment swept by a sphere), world frame.

    Attributes:
        a, b: (K, 3) segment end points, metres.
        r: (K,) radii, metres.
        material: (K,) material index into :attr:`Appearance.colors`.
        forward: (3,) the facing direction (unit, horizontal), for the face/hair split of the head.
    """

    a: FloatArray
    b: FloatArray
    r: FloatArray
    material: NDArray[np.int64]
    forward: FloatArray


def body_capsules(state: FloatArray, app: Appearance) -> Capsules:
    """The 19 capsules of a person in ``state`` ``(x, y, heading, speed, phase)`` (world frame)."""
    x, y, hd, v, ph = (float(c) for c in state)
    h = app.height
    s = h / 1.75
    hips_, knees_, ankles_, a_ = _legs(np.array([h]), np.array([v]), np.array([ph]))
    hips, knees, ankles, a = hips_[0], knees_[0], ankles_[0], float(a_[0])
    hip_z = 0.52 * h
    lean = 0.03 * a
    sh_z = 0.80 * h
    A: list[FloatArray] = []
    B: list[FloatArray] = []
    R: list[float] = []

    def cap(
        p: tuple[float, float, float] | FloatArray, q: tuple[float, float, float] | FloatArray, r: float
    ) -> None:
        A.append(np.asarray(p, float))
        B.append(np.asarray(q, float))
        R.append(r)

    for side in (1.0, -1.0):  # torso: two capsules side by side (wide, not deep)
        cap((0.0, side * 0.065 * s, hip_z + 0.08), (lean, side * 0.075 * s, 0.775 * h), 0.115 * s)
    cap((0.0, 0.1 * s, hip_z + 0.02), (0.0, -0.1 * s, hip_z + 0.02), 0.105 * s)  # pelvis
    cap((lean, 0.16 * s, sh_z), (lean, -0.16 * s, sh_z), 0.068 * s)  # shoulders
    cap((lean, 0.0, sh_z), (lean + 0.01, 0.0, 0.87 * h), 0.047 * s)  # neck
    cap((lean + 0.015 * s, 0.0, 0.913 * h), (lean + 0.015 * s, 0.0, 0.943 * h), 0.086 * s)  # head
    elbows, hands = [], []
    for k, side in enumerate((1.0, -1.0)):  # arms swing against the legs
        alpha = (-0.4 if k == 0 else 0.4) * a * np.sin(ph)
        beta = 0.2 + 0.35 * a
        sh = np.array([lean, side * 0.2 * s, sh_z - 0.02])
        el = sh + 0.29 * s * np.array([np.sin(alpha), side * 0.06, -np.cos(alpha)])
        hand = el + 0.26 * s * np.array([np.sin(alpha + beta), side * 0.02, -np.cos(alpha + beta)])
        cap(sh, el, 0.046 * s)
        elbows.append(el)
        hands.append(hand)
    for k in range(2):
        cap(elbows[k], hands[k], 0.038 * s)
    # material order above: torso ×2, pelvis, shoulders, neck, head, upper arms ×2 (sleeve), forearms ×2
    for k in range(2):
        cap(hands[k], hands[k] + np.array([0.0, 0.0, -0.04 * s]), 0.042 * s)  # hands
    for k in range(2):
        cap(hips[k], knees[k], 0.075 * s)  # thighs
    for k in range(2):
        cap(knees[k], ankles[k], 0.058 * s)  # shins
    for k in range(2):
        f = ankles[k]
        cap(f + np.array([-0.05 * s, 0.0, -0.035]), f + np.array([0.13 * s, 0.0, -0.04]), 0.045 * s)  # shoes
    cap((0.0, 0.0, hip_z + 0.1), (lean, 0.0, 0.76 * h), 0.125 * s)  # fills the back and the chest
    a_w = _to_world(np.array(A), x, y, hd)
    b_w = _to_world(np.array(B), x, y, hd)
    mat = _MATERIALS.copy()
    mat[6:8] = 2  # upper arms: shirt
    return Capsules(
        a=a_w, b=b_w, r=np.array(R), material=mat, forward=np.array([np.cos(hd), np.sin(hd), 0.0])
    )
