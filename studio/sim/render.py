"""Equirectangular panorama renderer: an analytic background per column plus ray-cast human figures.

The background (walls with doors, lintels and posters, floor tiles, ceiling lights, pillars, tables,
chairs and the robot's own top) is rendered at half resolution: each image column is one horizontal ray,
intersected with every vertical segment and cylinder of the world; each pixel then picks the first
object whose height interval contains the ray's height at that distance, or the floor or ceiling; table
tops and seats are horizontal rectangles. People are rendered at full resolution by intersecting the
pixel rays with their capsules (:mod:`studio.sim.figure`) and composited with a z-buffer against each
other and the background; the robot's own top hides the lowest rows. The camera is assumed level (no
roll or pitch), at ``zc`` metres above the floor.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from studio.geometry.base import pixel_to_angles
from studio.sim.base import WALL_HEIGHT, World
from studio.sim.body import Appearance, Capsules
from studio.sim.figure import person_layer

__all__ = ["PanoramaRenderer", "PersonRender"]

FloatArray = NDArray[np.floating[Any]]
_CEILING = np.array([228.0, 230.0, 232.0])
_ROBOT = np.array([52.0, 52.0, 56.0])
_DEPTH_TOL = np.float32(0.08)  # metres: the half-resolution floor depth must not eat the shoes


@dataclass(frozen=True)
class PersonRender:
    """What the renderer drew of one person.

    Attributes:
        pixels: rendered pixels when nothing occludes the person (full resolution).
        visible: pixels of the person in the final image.
        box: tight box ``(u1, v1, u2, v2)`` of the visible pixels, px (``u2`` may exceed W across the
            seam), or None when nothing is visible.
        box_full: the same box of the unoccluded figure, or None.
    """

    pixels: int
    visible: int
    box: tuple[float, float, float, float] | None
    box_full: tuple[float, float, float, float] | None


def _fmod(x: NDArray[np.float32], p: float) -> NDArray[np.float32]:
    """``x mod p`` (numpy's float ``%`` is several times slower)."""
    return x - np.floor(x * np.float32(1.0 / p)) * np.float32(p)


def _unwrap_box(
    c0: int, r0: int, mask: NDArray[np.bool_], width: int
) -> tuple[float, float, float, float] | None:
    if not mask.any():
        return None
    rows = np.nonzero(mask.any(axis=1))[0]
    cols = np.nonzero(mask.any(axis=0))[0]
    u1, u2 = c0 + int(cols[0]), c0 + int(cols[-1]) + 1
    shift = -width * ((u1) // width)
    return (float(u1 + shift), float(r0 + rows[0]), float(u2 + shift), float(r0 + rows[-1] + 1))


class PanoramaRenderer:
    """Renders ``width × height`` panoramas of the world with people.

    Args:
        world: the static scene.
        width, height: panorama size, px.
        zc: camera height above the floor, metres.
        cam_xy: camera position in the base frame ``(x, y)``, metres.
        cam_yaw: camera yaw in the base frame, rad (only for the robot's own top; the ``cam`` pose given
            to :meth:`render` is the camera's pose in the world).
        body: robot body ``(length, width, height)``, metres, centred on the base frame (seen from above).
    """

    def __init__(
        self,
        world: World,
        *,
        width: int,
        height: int,
        zc: float,
        cam_xy: tuple[float, float] = (0.0, 0.0),
        cam_yaw: float = 0.0,
        body: tuple[float, float, float] = (0.7, 0.6, 0.5),
    ) -> None:
        self.world = world
        self.W, self.H = int(width), int(height)
        self.zc = float(zc)
        self.cam_xy = np.asarray(cam_xy, dtype=np.float64)
        self.cam_yaw = float(cam_yaw)
        self.az, _ = pixel_to_angles(np.arange(self.W) + 0.5, np.zeros(self.W), self.W, self.H)
        _, self.el = pixel_to_angles(np.zeros(self.H), np.arange(self.H) + 0.5, self.W, self.H)
        self.Wh, self.Hh = self.W // 2, self.H // 2
        self.az_h, _ = pixel_to_angles(np.arange(self.Wh) + 0.5, np.zeros(self.Wh), self.Wh, self.Hh)
        _, self.el_h = pixel_to_angles(np.zeros(self.Hh), np.arange(self.Hh) + 0.5, self.Wh, self.Hh)
        self.tan_h = np.tan(self.el_h)
        self.cos_h = np.cos(self.el_h)
        self._robot = self._robot_overlay(body)
        rr = np.nonzero(self._robot[1].any(axis=1))[0]
        self._robot_rows = slice(int(rr[0]), int(rr[-1]) + 1) if rr.size else slice(0, 0)
        self._zbuf = np.full((self.H, self.W), np.inf, dtype=np.float32)
        self._bg_cache: tuple[Any, ...] | None = None
        full_rows = np.nonzero(self._robot[1].all(axis=1))[0]
        self._bg_rows = int(full_rows[0]) // 2 if full_rows.size else self.H // 2
        self._ids = np.full((self.H, self.W), -1, dtype=np.int16)
        # one poster or notice board per wall segment (texture), from the segment index
        rng = np.random.default_rng(12345)
        n = world.seg.shape[0]
        lengths = np.hypot(world.seg[:, 2] - world.seg[:, 0], world.seg[:, 3] - world.seg[:, 1])
        s0 = rng.uniform(0.2, 0.6, n) * lengths
        self._poster = np.stack(
            [s0, s0 + rng.uniform(0.5, 1.0, n), rng.uniform(1.1, 1.3, n), rng.uniform(1.6, 1.9, n)], 1
        )
        self._poster[(lengths < 1.5) | ~world.seg_full] = 0.0
        self._poster_color = rng.uniform(40, 230, (n, 3))
        self._seg_shade: FloatArray = np.asarray(rng.uniform(0.93, 1.05, n))
        parts = {
            "seg": world.seg_color,
            "circ": world.circ_color,
            "rect": world.rect_color,
            "poster": self._poster_color,
            "floor": np.array([world.floor_color[k] for k in ("A", "B", "C")]),
            "ceiling": (_CEILING * 0.88)[None, :],
            "light": np.full((1, 3), 255.0),
        }
        self._pal: dict[str, int] = {}
        start = 0
        for name, arr in parts.items():
            self._pal[name] = start
            start += arr.shape[0]
        self._palette = np.concatenate(list(parts.values())).astype(np.float32)

    # ------------------------------------------------------------------ robot top (fixed in the camera)
    def _robot_overlay(
        self, body: tuple[float, float, float]
    ) -> tuple[NDArray[np.float32], NDArray[np.bool_]]:
        length, width, top = body
        el = self.el[:, None]
        with np.errstate(divide="ignore"):
            hd = np.where(el < 0, (self.zc - top) / np.tan(-el), np.inf)
        x = self.cam_xy[0] + hd * np.cos(self.az + self.cam_yaw)[None, :]
        y = self.cam_xy[1] + hd * np.sin(self.az + self.cam_yaw)[None, :]
        mask = (np.abs(x) <= length / 2) & (np.abs(y) <= width / 2)
        depth = np.where(mask, hd / np.cos(el), np.inf).astype(np.float32)
        return depth, mask

    # ------------------------------------------------------------------ background
    def _background_static(self, cam: FloatArray) -> tuple[Any, ...]:
        """The scene without people: image, depth, floor coordinates of the lower rows, floor mask."""
        w = self.world
        ox, oy, yaw = (float(v) for v in cam)
        o = np.array([ox, oy])
        az = self.az_h + yaw
        d = np.stack([np.cos(az), np.sin(az)], axis=1)  # (Wh, 2)
        n_seg = w.seg.shape[0]
        # vertical segments
        p1 = w.seg[:, :2]
        e = w.seg[:, 2:] - p1
        wv = p1 - o
        denom = d[:, :1] * e[None, :, 1] - d[:, 1:] * e[None, :, 0]
        safe = np.where(np.abs(denom) > 1e-12, denom, 1e-12)
        t_s = (wv[None, :, 0] * e[None, :, 1] - wv[None, :, 1] * e[None, :, 0]) / safe
        u_s = (wv[None, :, 0] * d[:, 1:] - wv[None, :, 1] * d[:, :1]) / safe
        t_s = np.where((np.abs(denom) > 1e-12) & (t_s > 1e-6) & (u_s >= 0) & (u_s <= 1), t_s, np.inf)
        # cylinders
        oc = o - w.circ[:, :2]
        b = d @ oc.T
        cc = np.einsum("ij,ij->i", oc, oc) - w.circ[:, 2] ** 2
        disc = b * b - cc[None, :]
        t_c = -b - np.sqrt(np.maximum(disc, 0.0))
        t_c = np.where((disc >= 0) & (t_c > 1e-6), t_c, np.inf)
        t_all = np.concatenate([t_s, t_c], axis=1)  # (Wh, S + C)
        z_all = np.concatenate([w.seg_z, w.circ_z])
        full = np.concatenate([w.seg_full, (w.circ_z[:, 0] <= 0) & (w.circ_z[:, 1] >= WALL_HEIGHT)])
        t_full = np.where(full[None, :], t_all, np.inf)
        i_full = np.argmin(t_full, axis=1)
        cols = np.arange(self.Wh)
        d_full = t_full[cols, i_full]
        d_full = np.where(np.isfinite(d_full), d_full, 50.0)
        # texture coordinate along the wall and shading of the full-height hit
        is_seg = i_full < n_seg
        i_s = np.minimum(i_full, n_seg - 1)
        seg_len = np.hypot(e[i_s, 0], e[i_s, 1])
        s_along = u_s[cols, i_s] * seg_len
        cos_inc = np.abs(denom[cols, i_s]) / np.maximum(seg_len, 1e-9)
        i_c = np.maximum(i_full - n_seg, 0)
        hit = o + d_full[:, None] * d
        nrm = (hit - w.circ[i_c, :2]) / np.maximum(w.circ[i_c, 2], 1e-9)[:, None]
        cos_c = np.abs(np.einsum("ij,ij->i", nrm, d))
        shade_full = np.asarray(
            np.where(is_seg, (0.72 + 0.28 * cos_inc) * self._seg_shade[i_s], 0.5 + 0.5 * cos_c)
        )
        P = self._pal
        idx_full = np.where(is_seg, P["seg"] + i_s, P["circ"] + i_c)

        mid, nb = self.Hh // 2, self._bg_rows  # rows above the horizon; rows below nb show the robot
        tan_el = self.tan_h[:nb, None].astype(np.float32)
        d32 = d_full[None, :].astype(np.float32)
        z_wall = np.float32(self.zc) + d32 * tan_el  # (nb, Wh)
        # walls: colour per column, one poster per segment, baseboard
        ps = self._poster[i_s].astype(np.float32)
        sa = s_along.astype(np.float32)
        in_s = (is_seg & (sa >= ps[:, 0]) & (sa <= ps[:, 1]))[None, :]
        inp = in_s & (z_wall >= ps[None, :, 2]) & (z_wall <= ps[None, :, 3])
        idx = np.where(inp, (P["poster"] + i_s)[None, :], idx_full[None, :]).astype(np.int32)
        shade = np.where(z_wall < 0.1, np.float32(0.55), np.float32(1.0)) * shade_full[None, :].astype(
            np.float32
        )
        hd = np.repeat(d32, nb, axis=0)
        dx32, dy32 = d[None, :, 0].astype(np.float32), d[None, :, 1].astype(np.float32)
        # ceiling with light panels (rows above the horizon)
        top = slice(0, mid)
        ceil = z_wall[top] > WALL_HEIGHT
        h_c = np.float32(WALL_HEIGHT - self.zc) / tan_el[top]
        ex, ey = _fmod(np.float32(ox) + h_c * dx32, 2.4), _fmod(np.float32(oy) + h_c * dy32, 2.4)
        lit = (ex > 0.3) & (ex < 0.9) & (ey > 0.4) & (ey < 1.6)
        idx[top] = np.where(ceil, np.where(lit, P["light"], P["ceiling"]), idx[top])
        shade[top] = np.where(ceil, np.float32(1.0), shade[top])
        hd[top] = np.where(ceil, h_c, hd[top])
        # floor (rows below the horizon): tiles in A and C, planks in B, contact shadows
        bot = slice(mid, nb)
        floor = z_wall[bot] < 0
        h_f = np.float32(self.zc) / -tan_el[bot]
        hx = np.float32(ox) + h_f * dx32
        hy = np.float32(oy) + h_f * dy32
        in_b = hx > 6.0
        in_c = hy > 4.0
        f_idx = np.where(in_c, P["floor"] + 2, np.where(in_b, P["floor"] + 1, P["floor"]))
        tile = (np.abs(_fmod(hx + 0.3, 0.6) - 0.3) < 0.012) | (np.abs(_fmod(hy + 0.3, 0.6) - 0.3) < 0.012)
        plank = in_b & ~in_c & (np.abs(_fmod(hy + 0.1, 0.2) - 0.1) < 0.006)
        f_shade = np.where(tile & ~in_b, 1.0 - 0.25 * np.exp(-h_f / 3.0), np.float32(1.0))
        f_shade = np.where(plank, np.float32(0.8), f_shade).astype(np.float32)
        idx[bot] = np.where(floor, f_idx, idx[bot])
        shade[bot] = np.where(floor, f_shade, shade[bot])
        hd[bot] = np.where(floor, h_f, hd[bot])
        # partial-height vertical objects nearer than the wall (only the columns that see them)
        t_part = np.where(~full[None, :] & (t_all < d_full[:, None]), t_all, np.inf)
        k_max = int(np.isfinite(t_part).sum(axis=1).max()) if t_part.size else 0
        if k_max:
            order = np.argsort(t_part, axis=1)[:, :k_max]
            for k in range(k_max - 1, -1, -1):
                j_all = order[:, k]
                dk_all = t_part[cols, j_all]
                cs = np.nonzero(np.isfinite(dk_all))[0]
                j, dk = j_all[cs], dk_all[cs]
                zk = self.zc + dk[None, :] * self.tan_h[:nb, None]  # (nb, n)
                m = (zk >= z_all[j, 0][None, :]) & (zk <= z_all[j, 1][None, :]) & (dk[None, :] < hd[:, cs])
                rr, cc_ = np.nonzero(m)
                if rr.size == 0:
                    continue
                cc_g = cs[cc_]
                jj = j[cc_]
                hd[rr, cc_g] = dk[cc_]
                is_c = jj >= n_seg
                jc = np.maximum(jj - n_seg, 0)
                hp = o + dk[cc_, None] * d[cc_g]
                nr = (hp - w.circ[jc, :2]) / np.maximum(w.circ[jc, 2], 1e-9)[:, None]
                sh = np.where(is_c, 0.45 + 0.55 * np.abs(np.einsum("ij,ij->i", nr, d[cc_g])), 0.85)
                idx[rr, cc_g] = np.where(is_c, P["circ"] + jc, P["seg"] + jj)
                shade[rr, cc_g] = sh
        # horizontal rectangles (table tops, seats, shelf top)
        self._rects(idx, shade, hd, o, d)
        shade *= np.clip(1.08 - 0.03 * hd, 0.72, 1.0)
        img = np.zeros((self.Hh, self.Wh, 3), dtype=np.uint8)
        col = cv2.multiply(self._palette[idx], cv2.merge([shade, shade, shade]))
        img[:nb] = np.clip(col, 0, 255).astype(np.uint8)
        depth = np.full((self.Hh, self.Wh), np.inf, dtype=np.float32)
        depth[:nb] = hd / self.cos_h[:nb, None].astype(np.float32)
        on_floor = (idx[bot] >= P["floor"]) & (idx[bot] < P["floor"] + 3)
        return img, depth, hx, hy, on_floor

    def background(
        self, cam: FloatArray, people_xy: FloatArray
    ) -> tuple[NDArray[np.uint8], NDArray[np.float32]]:
        """Half-resolution background and its depth (distance along the ray, metres).

        The scene without people is cached for the last camera pose (a standing robot renders it once);
        people add soft contact shadows on the floor.

        Args:
            cam: camera ``x, y, yaw`` in the world (metres, rad).
            people_xy: (P, 2) people's floor positions (soft contact shadows), world, metres.

        Returns:
            BGR image (H/2, W/2, 3) uint8 and depth (H/2, W/2) float32.
        """
        key = tuple(float(v) for v in cam)
        if self._bg_cache is None or self._bg_cache[0] != key:
            self._bg_cache = (key, *self._background_static(cam))
        _, img0, depth, hx, hy, on_floor = self._bg_cache
        img = img0.copy()
        mid, nb = self.Hh // 2, self._bg_rows
        el_b = self.el_h[mid:nb]
        ox, oy = key[0], key[1]
        for px, py in people_xy:
            rho = float(np.hypot(px - ox, py - oy))
            if rho < 0.6:
                continue
            el_lo, el_hi = -np.arctan2(self.zc, rho - 0.5), -np.arctan2(self.zc, rho + 0.5)
            rows = np.nonzero((el_b >= el_lo) & (el_b <= el_hi))[0]
            if rows.size == 0:
                continue
            r = slice(int(rows[0]), int(rows[-1]) + 1)
            r2 = (hx[r] - px) ** 2 + (hy[r] - py) ** 2
            fac = np.where(on_floor[r], 1.0 - 0.45 * np.exp(-r2 / np.float32(2 * 0.16**2)), np.float32(1.0))
            ra = slice(mid + r.start, mid + r.stop)
            img[ra] = cv2.multiply(img[ra], cv2.merge([fac, fac, fac]), dtype=cv2.CV_8U)
        return img, depth

    def _rects(
        self,
        idx: NDArray[np.int32],
        shade: NDArray[np.float32],
        hd: NDArray[np.float32],
        o: FloatArray,
        d: FloatArray,
    ) -> None:
        w = self.world
        for k, (x0, x1, y0, y1, zr) in enumerate(w.rect):
            if zr >= self.zc:
                continue
            corners = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]]) - o
            dists = np.hypot(corners[:, 0], corners[:, 1])
            near = max(0.05, float(np.hypot(max(x0 - o[0], 0, o[0] - x1), max(y0 - o[1], 0, o[1] - y1))))
            el_lo = np.arctan2(zr - self.zc, near)
            el_hi = np.arctan2(zr - self.zc, float(dists.max()))
            rows = np.nonzero(
                (self.el_h[: hd.shape[0]] >= el_lo - 0.02) & (self.el_h[: hd.shape[0]] <= el_hi + 0.02)
            )[0]
            if rows.size == 0:
                continue
            r = slice(int(rows[0]), int(rows[-1]) + 1)
            t = ((self.zc - zr) / -self.tan_h[r])[:, None]
            px = o[0] + t * d[None, :, 0]
            py = o[1] + t * d[None, :, 1]
            m = (px >= x0) & (px <= x1) & (py >= y0) & (py <= y1) & (t < hd[r])
            if not m.any():
                continue
            hd[r] = np.where(m, t, hd[r])
            idx[r] = np.where(m, self._pal["rect"] + k, idx[r])
            shade[r] = np.where(m, np.float32(0.95), shade[r])

    # ------------------------------------------------------------------ people
    def _window(
        self, c0: int, r0: int, shape: tuple[int, ...]
    ) -> tuple[slice, slice] | tuple[NDArray[np.int64], ...]:
        """Index of a window of the panorama (plain slices unless it crosses the seam)."""
        c1 = c0 + shape[1]
        if c0 >= 0 and c1 <= self.W:
            return slice(r0, r0 + shape[0]), slice(c0, c1)
        return np.ix_(np.arange(r0, r0 + shape[0]), np.arange(c0, c1) % self.W)

    def render(
        self, cam: FloatArray, people: list[tuple[Capsules, Appearance]], people_xy: FloatArray
    ) -> tuple[NDArray[np.uint8], list[PersonRender]]:
        """One panorama.

        Args:
            cam: camera ``x, y, yaw`` in the world (metres, rad); its height is ``zc``.
            people: each person's capsules (world frame) and appearance.
            people_xy: (P, 2) people's floor positions for contact shadows, world, metres.

        Returns:
            BGR image (H, W, 3) uint8 and one :class:`PersonRender` per person.
        """
        bg, bg_depth = self.background(cam, people_xy)
        img = cv2.resize(bg, (self.W, self.H), interpolation=cv2.INTER_LINEAR)
        depth_bg = cv2.resize(bg_depth, (self.W, self.H), interpolation=cv2.INTER_NEAREST)
        r_rob = self._robot_rows
        depth_bg[r_rob] = np.minimum(depth_bg[r_rob], self._robot[0][r_rob])
        sub_img = img[r_rob]
        sub_img[self._robot[1][r_rob]] = _ROBOT.astype(np.uint8)
        zbuf, ids = self._zbuf, self._ids
        layers = []
        touched = []
        for i, (caps, app) in enumerate(people):
            layer = person_layer(caps, app, cam, depth_bg, zc=self.zc, az_cols=self.az, el_rows=self.el)
            layers.append(layer)
            if layer is None:
                continue
            c0, r0, dep, col = layer
            ix = self._window(c0, r0, dep.shape)
            touched.append(ix)
            cur = zbuf[ix]
            win = (dep < cur) & (dep < depth_bg[ix] + _DEPTH_TOL)
            if not win.any():
                continue
            zbuf[ix] = np.where(win, dep, cur)
            ids[ix] = np.where(win, i, ids[ix])
            img_win = img[ix]
            img[ix] = np.where(win[..., None], np.clip(col, 0, 255).astype(np.uint8), img_win)
        out = []
        for i, layer in enumerate(layers):
            if layer is None:
                out.append(PersonRender(0, 0, None, None))
                continue
            c0, r0, dep, _ = layer
            vis = ids[self._window(c0, r0, dep.shape)] == i
            full = np.isfinite(dep)
            out.append(
                PersonRender(
                    pixels=int(full.sum()),
                    visible=int(vis.sum()),
                    box=_unwrap_box(c0, r0, vis, self.W),
                    box_full=_unwrap_box(c0, r0, full, self.W),
                )
            )
        for ix in touched:  # reset the shared buffers for the next frame
            zbuf[ix] = np.inf
            ids[ix] = -1
        final: NDArray[np.uint8] = np.ascontiguousarray(cv2.GaussianBlur(img, (3, 3), 0.6), dtype=np.uint8)
        return final, out
