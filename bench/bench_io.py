"""Throughput and memory of ``studio.io.iter_frames``: frames/s and peak RSS, printed as numbers.

Usage::

    .venv/bin/python bench/bench_io.py                      # synthetic bags of 20 s and 80 s (flat memory?)
    .venv/bin/python bench/bench_io.py --seconds 30 120     # other lengths
    .venv/bin/python bench/bench_io.py --bag REC --rig RIG  # a given recording
    .venv/bin/python bench/bench_io.py --ros1               # also as a ROS1 bag, with and without its index

Each measurement runs in a fresh subprocess so that its peak RSS (``VmHWM``) belongs to that run only;
the baseline is the RSS of the same process after the imports, before reading. Synthetic bags model the
thesis rig: 1920×960 JPEG panoramas at 10 Hz, two 1081-beam lasers at 40 Hz, odometry at 50 Hz, TF.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def _status_mb(key: str) -> float:
    """A memory figure of /proc/self/status (VmRSS: now, VmHWM: peak), MB."""
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(key + ":"):
                return int(line.split()[1]) / 1024
    return float("nan")


def measure(bag: str, rig_path: str) -> dict[str, float]:
    """Iterate all frames of ``bag``; returns frames, seconds, frames/s, baseline and peak RSS (MB)."""
    from studio.io import SyncReport, iter_frames, load_rig, open_recording

    rig = load_rig(rig_path)
    base = _status_mb("VmRSS")
    report = SyncReport()
    t0 = time.perf_counter()
    n = 0
    with open_recording(bag) as rec:
        for _frame in iter_frames(rec, rig, report=report):
            n += 1
    dt = time.perf_counter() - t0
    # VmHWM, not ru_maxrss: the latter carries over the parent's peak across fork + exec
    peak = _status_mb("VmHWM")
    return {
        "frames": n,
        "seconds": dt,
        "fps": n / dt if dt else 0.0,
        "base_rss_mb": base,
        "peak_rss_mb": peak,
    }


def synthesize(out: Path, seconds: float) -> tuple[Path, Path]:
    """Write a synthetic recording and its rig; returns (bag, rig)."""
    import cv2

    from studio.geometry.se import Pose2, Pose3
    from studio.io import (
        CameraConfig,
        LaserConfig,
        LaserScan,
        Odometry,
        OdometryConfig,
        RecordingWriter,
        Rig,
        save_rig,
    )

    t0 = 1_700_000_000_000_000_000
    bag = out / f"bench_{int(seconds)}s.mcap"
    rng = np.random.default_rng(0)
    yy, xx = np.mgrid[0:960, 0:1920]
    base_img = np.dstack([(xx // 8) % 256, (yy // 4) % 256, ((xx + yy) // 16) % 256]).astype(np.uint8)
    beams = 1081
    events: list[tuple[int, str]] = []
    events += [(t0 + k * 100_000_000, "image") for k in range(int(seconds * 10))]
    events += [(t0 + k * 25_000_000 + 3_000_000, "front") for k in range(int(seconds * 40))]
    events += [(t0 + k * 25_000_000 + 15_000_000, "back") for k in range(int(seconds * 40))]
    events += [(t0 + k * 20_000_000, "odom") for k in range(int(seconds * 50) + 1)]
    with RecordingWriter(bag, overwrite=True) as w:
        w.write_tf(
            [
                ("base_link", "front_laser", t0, Pose3.from_xyz_rpy(0.35, 0, 0.3)),
                ("base_link", "back_laser", t0, Pose3.from_xyz_rpy(-0.35, 0, 0.3, 0, 0, np.pi)),
            ],
            static=True,
            log_ns=t0,
        )
        for stamp, kind in sorted(events):
            ts = (stamp - t0) / 1e9
            if kind == "image":
                img = np.roll(base_img, int(ts * 50), axis=1)
                ok, jpg = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, 85])
                assert ok
                w.write_compressed_image("/camera/image/compressed", stamp, "camera", jpg.tobytes())
            elif kind in ("front", "back"):
                r = (3.0 + rng.normal(0, 0.01, beams)).astype(np.float32)
                scan = LaserScan(stamp, f"{kind}_laser", -2.356, 4.712 / (beams - 1), r, 0.05, 30.0)
                w.write_scan(f"/scan_{kind}", scan)
            else:
                pose = Pose2(0.5 * ts, 0.0, 0.0)
                w.write_odometry("/odom", Odometry(stamp, "odom", "base_link", pose), vx=0.5)
    rig = Rig(
        base_frame="base_link",
        odometry=OdometryConfig(topic="/odom"),
        camera=CameraConfig("/camera/image/compressed", Pose3.from_xyz_rpy(0, 0, 1.15)),
        lasers=(LaserConfig("/scan_front"), LaserConfig("/scan_back")),
    )
    rig_path = out / f"bench_{int(seconds)}s_rig.yaml"
    save_rig(rig, rig_path)
    return bag, rig_path


def to_ros1(src: Path, dst: Path) -> Path:
    """``src`` (an MCAP of ROS 2 messages) converted to a ROS1 bag by rosbags (1 MB chunks)."""
    from rosbags.convert.converter import convert
    from rosbags.typesys import Stores, get_typestore

    convert(
        [src],
        dst,
        "",
        1,
        None,
        "file",
        get_typestore(Stores.ROS2_HUMBLE),
        get_typestore(Stores.ROS1_NOETIC),
        [],
        [],
        [],
        [],
    )
    return dst


def _run_child(bag: Path | str, rig: Path | str) -> dict[str, float]:
    proc = subprocess.run(
        [sys.executable, __file__, "--child", str(bag), str(rig)], capture_output=True, text=True, check=True
    )
    return json.loads(proc.stdout.strip().splitlines()[-1])


def _print(label: str, size_mb: float, r: dict[str, float]) -> None:
    print(
        f"{label:<28} {size_mb:8.1f} MB  {int(r['frames']):6d} frames  {r['seconds']:7.2f} s  "
        f"{r['fps']:8.1f} frames/s  RSS base {r['base_rss_mb']:6.1f} MB  peak {r['peak_rss_mb']:6.1f} MB  "
        f"(+{r['peak_rss_mb'] - r['base_rss_mb']:.1f} MB)"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bag", help="recording to measure (with --rig)")
    ap.add_argument("--rig", help="rig.yaml for --bag")
    ap.add_argument("--seconds", type=float, nargs="+", default=[20.0, 80.0], help="synthetic lengths")
    ap.add_argument("--keep", action="store_true", help="keep the synthetic bags (in --out)")
    ap.add_argument("--out", default=None, help="folder for the synthetic bags (default: a temporary one)")
    ap.add_argument(
        "--ros1",
        action="store_true",
        help="also read each synthetic recording as a ROS1 bag, and as the same bag without its index (the "
        "recorder stopped before it wrote it: read by scanning the chunks)",
    )
    ap.add_argument("--child", nargs=2, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        print(json.dumps(measure(*args.child)))
        return
    if args.bag:
        if not args.rig:
            ap.error("--bag needs --rig")
        _print(Path(args.bag).name, Path(args.bag).stat().st_size / 2**20, _run_child(args.bag, args.rig))
        return
    with tempfile.TemporaryDirectory() as tmp_dir:
        tmp = args.out or tmp_dir
        Path(tmp).mkdir(parents=True, exist_ok=True)
        for s in args.seconds:
            t = time.perf_counter()
            bag, rig = synthesize(Path(tmp), s)
            print(f"(wrote {bag.name} in {time.perf_counter() - t:.1f} s)", file=sys.stderr)
            _print(f"synthetic {s:g} s", bag.stat().st_size / 2**20, _run_child(bag, rig))
            if args.ros1:
                ros1 = to_ros1(bag, bag.with_suffix(".bag"))
                _print("  as a ROS1 bag", ros1.stat().st_size / 2**20, _run_child(ros1, rig))
                cut = ros1.with_name(ros1.stem + "_no_index.bag")
                data = ros1.read_bytes()
                cut.write_bytes(data[: int(len(data) * 0.999)])  # the index is the last few KB
                del data
                _print("  ROS1, without its index", cut.stat().st_size / 2**20, _run_child(cut, rig))
                if not args.keep:
                    ros1.unlink()
                    cut.unlink()
            if not args.keep:
                bag.unlink()


if __name__ == "__main__":
    main()
