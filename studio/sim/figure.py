"""Human figures in the panorama: per-pixel ray casting against a person's capsules.

Each capsule is intersected only with the rays of its own pixel window (its end points projected, grown
by its angular radius), shaded with light from above plus a little light from the camera, and the head
gets hair on top and at the back, a face with eyes and a mouth in front.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from studio.sim.body import Appearance, Capsules

__all__ = ["person_layer"]

FloatArray = NDArray[np.floating[Any]]


def person_layer(
    caps: Capsules,
    app: Appearance,
    cam: FloatArray,
    depth_bg: NDArray[Any],
    *,
    zc: float,
    az_cols: FloatArray,
    el_rows: FloatArray,
) -> tuple[int, int, NDArray[np.float32], NDArray[np.float32]] | None:
    """Ray-cast one person's capsules in the pixel window they cover.

    Args:
        caps: the person's capsules, world frame.
        app: the person's appearance (colours).
        cam: camera ``x, y, yaw`` in the world (metres, rad), level, ``zc`` above the floor.
        depth_bg: (H, W) background depth along the rays, metres (a person entirely behind it is skipped).
        zc: camera height, metres.
        az_cols: (W,) azimuth of each image column, rad.
        el_rows: (H,) elevation of each image row, rad.

    Returns:
        ``(c0, r0, depth, colour)``: the window's first column (may be negative or run past W: columns
        wrap) and first row, the depth (h, w) float32 (inf where the person is not) and BGR colour
        (h, w, 3) float32; None when nothing of the person can be seen.
    """
    W, H = az_cols.shape[0], el_rows.shape[0]
    ox, oy, yaw = (float(v) for v in cam)
    c, s = np.cos(yaw), np.sin(yaw)

    def to_cam(p: FloatArray) -> FloatArray:
        q = p - np.array([ox, oy, zc])
        return np.stack([c * q[:, 0] + s * q[:, 1], -s * q[:, 0] + c * q[:, 1], q[:, 2]], axis=1)

    A, B = to_cam(caps.a), to_cam(caps.b)
    fwd = np.array(
        [c * caps.forward[0] + s * caps.forward[1], -s * caps.forward[0] + c * caps.forward[1], 0.0]
    )
    centre = A[:2].mean(axis=0)
    az_c = float(np.arctan2(centre[1], centre[0]))
    u_c = (0.5 - az_c / (2 * np.pi)) * W
    k = A.shape[0]
    f = np.linspace(0.0, 1.0, 5)[:, None, None]
    pts = A[None] + f * (B - A)[None]  # (5, K, 3)
    dist = np.linalg.norm(pts, axis=2)
    if np.any(dist.min(axis=0) <= caps.r + 0.05):
        return None  # the camera is inside the body
    az = np.arctan2(pts[..., 1], pts[..., 0])
    el = np.arctan2(pts[..., 2], np.hypot(pts[..., 0], pts[..., 1]))
    u = u_c - ((az - az_c + np.pi) % (2 * np.pi) - np.pi) / (2 * np.pi) * W
    v = (0.5 - el / np.pi) * H
    rho = np.arcsin(np.clip(caps.r / dist.min(axis=0), 0.0, 1.0))
    m_u = rho / (2 * np.pi) * W / np.maximum(np.cos(np.abs(el).max(axis=0) + rho), 0.05) + 2
    m_v = rho / np.pi * H + 2
    cu0 = np.floor(u.min(axis=0) - m_u).astype(int)
    cu1 = np.ceil(u.max(axis=0) + m_u).astype(int)
    rv0 = np.clip(np.floor(v.min(axis=0) - m_v).astype(int), 0, H)
    rv1 = np.clip(np.ceil(v.max(axis=0) + m_v).astype(int), 0, H)
    c0, c1 = int(cu0.min()), int(cu1.max())
    r0, r1 = int(rv0.min()), int(rv1.max())
    if c1 - c0 > W or r1 <= r0:
        return None
    if float(depth_bg[r0:r1, np.arange(c0, c1) % W].max()) < float((dist - caps.r).min()):
        return None  # entirely behind walls or furniture
    light = np.array([0.3, 0.15, 1.0])
    light /= np.linalg.norm(light)
    light = np.array([c * light[0] + s * light[1], -s * light[0] + c * light[1], light[2]])
    side = np.array([-fwd[1], fwd[0], 0.0])
    # every (capsule, pixel of its window) pair in one flat batch, float32
    hs = np.maximum(rv1 - rv0, 0)
    ws = np.maximum(cu1 - cu0, 0)
    areas = hs * ws
    n = int(areas.sum())
    cap = np.repeat(np.arange(k), areas)
    local = np.arange(n) - np.repeat(np.cumsum(areas) - areas, areas)
    wcap = ws[cap]
    row = rv0[cap] + local // wcap
    col = cu0[cap] + local % wcap  # unwrapped column
    cw = col % W
    ce = np.cos(el_rows).astype(np.float32)[row]
    dx = ce * np.cos(az_cols).astype(np.float32)[cw]
    dy = ce * np.sin(az_cols).astype(np.float32)[cw]
    dz = np.sin(el_rows).astype(np.float32)[row]
    A32, B32 = A.astype(np.float32), B.astype(np.float32)
    BA = B32 - A32
    baba_k = np.einsum("ij,ij->i", BA, BA)
    baoa_k = -np.einsum("ij,ij->i", BA, A32)
    oaoa_k = np.einsum("ij,ij->i", A32, A32)
    r_k = caps.r.astype(np.float32)
    qc_k = baba_k * oaoa_k - baoa_k * baoa_k - r_k * r_k * baba_k
    bax, bay, baz = BA[cap, 0], BA[cap, 1], BA[cap, 2]
    ax, ay, az_ = A32[cap, 0], A32[cap, 1], A32[cap, 2]
    baba, baoa = baba_k[cap], baoa_k[cap]
    bard = dx * bax + dy * bay + dz * baz
    rdoa = -(dx * ax + dy * ay + dz * az_)
    qa = baba - bard * bard
    qb = baba * rdoa - baoa * bard
    h = qb * qb - qa * qc_k[cap]
    inf = np.float32(np.inf)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where((h >= 0) & (qa > 1e-12), (-qb - np.sqrt(np.maximum(h, 0))) / qa, inf)
        y = baoa + t * bard  # NaN for a missed ray perpendicular to the axis (inf·0): no body hit
    body = np.isfinite(t) & (y > 0) & (y < baba)
    cap_b = y >= baba  # end caps: spheres at a or b
    ocx = np.where(cap_b, -B32[cap, 0], -ax)
    ocy = np.where(cap_b, -B32[cap, 1], -ay)
    ocz = np.where(cap_b, -B32[cap, 2], -az_)
    bb = dx * ocx + dy * ocy + dz * ocz
    h2 = bb * bb - (ocx * ocx + ocy * ocy + ocz * ocz - r_k[cap] * r_k[cap])
    t = np.where(body, t, np.where(h2 > 0, -bb - np.sqrt(np.maximum(h2, 0)), inf))
    hit = np.nonzero(t > 0)[0]
    hit = hit[np.isfinite(t[hit])]
    wwin = c1 - c0
    pid = (row[hit] - r0) * wwin + (col[hit] - c0)
    flat = np.full((r1 - r0) * wwin, np.inf, dtype=np.float32)
    np.minimum.at(flat, pid, t[hit])
    win = t[hit] == flat[pid]
    hit, pid = hit[win], pid[win]
    pid, first = np.unique(pid, return_index=True)  # one winner per pixel (ties are rare)
    hit = hit[first]
    j = cap[hit]
    tt, ex, ey, ez = t[hit], dx[hit], dy[hit], dz[hit]
    px, py, pz = tt * ex - A32[j, 0], tt * ey - A32[j, 1], tt * ez - A32[j, 2]
    hh = np.clip((px * BA[j, 0] + py * BA[j, 1] + pz * BA[j, 2]) / np.maximum(baba_k[j], 1e-12), 0.0, 1.0)
    nx = (px - hh * BA[j, 0]) / r_k[j]
    ny = (py - hh * BA[j, 1]) / r_k[j]
    nz = (pz - hh * BA[j, 2]) / r_k[j]
    lam = np.maximum(0.0, nx * light[0] + ny * light[1] + nz * light[2])
    head_on = np.maximum(0.0, -(nx * ex + ny * ey + nz * ez))
    inten = (0.3 + 0.5 * lam + 0.3 * head_on).astype(np.float32)
    mat = caps.material[j]
    col_rgb = app.colors.astype(np.float32)[mat]
    head = mat == 1  # hair on top and at the back, a face in front with eyes and a mouth
    if head.any():
        nf = nx * fwd[0] + ny * fwd[1]
        ns = np.abs(nx * side[0] + ny * side[1])
        hair = head & ((nz > 0.42) | (nf < -0.05) | ((nz > 0.2) & (nf < 0.45)))
        col_rgb[hair] = app.colors[1]
        col_rgb[head & ~hair & (nf > 0.6) & (nz > 0.0) & (nz < 0.2) & (ns > 0.18) & (ns < 0.42)] = 35.0
        mouth = head & ~hair & (nf > 0.75) & (nz > -0.5) & (nz < -0.38) & (ns < 0.2)
        col_rgb[mouth] *= np.array([0.6, 0.6, 0.85], np.float32)
    depth = flat.reshape(r1 - r0, wwin)
    depth[:] = np.inf
    depth.reshape(-1)[pid] = tt
    color = np.zeros((r1 - r0, wwin, 3), dtype=np.float32)
    color.reshape(-1, 3)[pid] = col_rgb * inten[:, None]
    return c0, r0, depth, color
