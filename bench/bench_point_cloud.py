"""How long slicing a 3-D lidar's point cloud into a planar scan takes (``studio.io.decode_scan`` with a
rig ``cloud``), per cloud, for the sizes of common spinning lidars; printed as numbers.

Usage::

    .venv/bin/python bench/bench_point_cloud.py

Each cloud is one organised sweep in an Ouster-like layout (48-byte points: x, y, z, intensity, ``t`` in ns
after the stamp, ...), rings spread over ±22.5° (±15° for 16 rings), every return 6 m away, 10 Hz; the
band is 0.2–0.6 m above the floor for a lidar 0.8 m up. The time per cloud bounds the reading cost of a
laser-only frame (a frame is a sweep).
"""

from __future__ import annotations

import time
from types import SimpleNamespace as NS  # noqa: N814

import numpy as np

from studio.io.base import CloudSlice
from studio.io.decode import decode_scan

LAYOUT = (("x", 0, "<f4", 7), ("y", 4, "<f4", 7), ("z", 8, "<f4", 7), ("intensity", 16, "<f4", 7),
          ("t", 20, "<u4", 6), ("ring", 24, "<u2", 4), ("range", 32, "<u4", 6))  # fmt: skip


def cloud(rings: int, columns: int, fov_deg: float) -> NS:
    """One 10 Hz sweep of ``rings`` × ``columns`` returns (a PointCloud2-shaped message)."""
    dtype = np.dtype({"names": [f[0] for f in LAYOUT], "formats": [f[2] for f in LAYOUT],
                      "offsets": [f[1] for f in LAYOUT], "itemsize": 48})  # fmt: skip
    az = np.tile(np.linspace(np.pi, -np.pi, columns, endpoint=False), rings)
    el = np.repeat(np.radians(np.linspace(-fov_deg / 2, fov_deg / 2, rings)), columns)
    rec = np.zeros(rings * columns, dtype)
    rec["x"], rec["y"], rec["z"] = 6 * np.cos(el) * np.cos(az), 6 * np.cos(el) * np.sin(az), 6 * np.sin(el)
    rec["t"] = np.tile(np.arange(columns) * (1e8 / columns), rings).astype(np.uint32)
    fields = [NS(name=n, offset=o, datatype=d, count=1) for n, o, _, d in LAYOUT]
    return NS(
        header=NS(stamp=NS(sec=1, nanosec=0), frame_id="lidar"), height=rings, width=columns, fields=fields,
        is_bigendian=False, point_step=48, row_step=48 * columns, data=rec.tobytes(), is_dense=True,
    )  # fmt: skip


def main() -> None:
    band = CloudSlice(min_z=-0.6, max_z=-0.2)
    for name, rings, columns, fov in (
        ("16 rings × 1800 (VLP-16 class)", 16, 1800, 30.0),
        ("64 rings × 1024", 64, 1024, 45.0),
        ("128 rings × 2048 (OS1-128 class)", 128, 2048, 45.0),
    ):
        msg = cloud(rings, columns, fov)
        scan = decode_scan(msg, cloud=band)
        reps = 20
        t0 = time.perf_counter()
        for _ in range(reps):
            decode_scan(msg, cloud=band)
        ms = (time.perf_counter() - t0) / reps * 1e3
        print(
            f"{name}: {rings * columns} points, {ms:.1f} ms per cloud ({100 / ms:.0f}× real time at 10 Hz); "
            f"{int(scan.valid().sum())} of {len(scan)} beams hit, {scan.time_increment * 1e6:.1f} µs apart"
        )


if __name__ == "__main__":
    main()
