"""The ``studio`` command.

The argument parser is the CLI contract of DESIGN.md §2 and lives here, in one place; each command's
work is done by ``studio.commands.<name>.run(args) -> int``, imported only when that command runs so
that ``studio --help`` stays fast and light.

User errors (:class:`studio.errors.StudioError`) print one line and exit with status 2.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import importlib.util
import os
import signal
import sys
import threading
from collections.abc import Callable, Sequence

from studio import __version__
from studio.errors import StudioError

__all__ = ["build_parser", "main"]


_RECORDING = "ROS1 .bag or a folder of them (one recording), ROS2 bag directory / .db3 / .mcap, or plain MCAP"


def _image_size(text: str) -> tuple[int, int]:
    try:
        w, h = text.lower().split("x")
        size = int(w), int(h)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected WIDTHxHEIGHT such as 1920x960, got '{text}'") from None
    if size[0] <= 0 or size[1] <= 0:
        raise argparse.ArgumentTypeError(f"image size must be positive, got '{text}'")
    return size


def _positive_float(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got '{text}'") from None
    if not 0 < v < float("inf"):
        raise argparse.ArgumentTypeError(f"expected a positive number, got '{text}'")
    return v


def _in_range(lo: float, hi: float, *, integer: bool = False) -> Callable[[str], float]:
    """An argparse type: a number (``integer``: a whole one) from ``lo`` to ``hi``."""

    def parse(text: str) -> float:
        try:
            v: float = int(text) if integer else float(text)
        except ValueError:
            kind = "a whole number" if integer else "a number"
            raise argparse.ArgumentTypeError(f"expected {kind}, got '{text}'") from None
        if not lo <= v <= hi:
            raise argparse.ArgumentTypeError(f"expected a number from {lo:g} to {hi:g}, got '{text}'")
        return v

    return parse


def _non_negative_float(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got '{text}'") from None
    if not 0 <= v < float("inf"):
        raise argparse.ArgumentTypeError(f"expected a number >= 0, got '{text}'")
    return v


def _pattern(text: str) -> tuple[int, int]:
    try:
        cols, rows = (int(x) for x in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected inner corners as COLSxROWS (e.g. 8x5), got '{text}'"
        ) from None
    if cols < 2 or rows < 2:
        raise argparse.ArgumentTypeError(f"a checkerboard needs at least 2x2 inner corners, got '{text}'")
    return cols, rows


def _help(command: str, text: str) -> str:
    """The command's help line, marked when its module is not there yet."""
    module, issue = _COMMANDS[command]
    if importlib.util.find_spec(module) is None:
        return f"{text} — not built yet (issue #{issue})"
    return text


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="studio",
        description="Panoramic People Studio: people's positions from 360° camera + 2D laser recordings.",
    )
    parser.add_argument("--version", action="version", version=f"studio {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)

    p = sub.add_parser("demo", help="label the bundled recording, evaluate it, write a Rerun recording")
    p.add_argument("--out", default="runs/demo", help="output run directory (default: runs/demo)")

    p = sub.add_parser("simulate", help="write a synthetic recording with exact ground truth")
    p.add_argument("--scenario", required=True, help="static | moving | rooms (and calib-* scenarios)")
    p.add_argument("--seconds", type=_positive_float, default=None, help="duration (default: the scenario's)")
    p.add_argument("--seed", type=int, default=0, help="random seed (same seed, same recording)")
    p.add_argument("--out", required=True, help="output directory")

    p = sub.add_parser("inspect", help="topics, counts, rates, TF frames and sync statistics of a recording")
    p.add_argument("recording", help=_RECORDING)
    p.add_argument(
        "--rig",
        default=None,
        help="rig.yaml: also report frame synchronisation and sensor poses for this rig (without: a rig.yaml "
        "to start from)",
    )

    p = sub.add_parser("label", help="auto-label people's positions and identities in a recording")
    p.add_argument("recording", help=_RECORDING)
    p.add_argument("--rig", required=True, help="rig.yaml describing the sensors")
    p.add_argument("--out", required=True, help="run directory to write")
    p.add_argument("--method", choices=["studio", "thesis"], default="studio")
    p.add_argument("--sources", choices=["both", "laser", "camera"], default="both")
    p.add_argument("--image-detector", default=None, help="detector name or a YOLO .onnx file")
    p.add_argument("--laser-detector", default=None, help="detector name or a model file")
    p.add_argument("--no-rrd", action="store_true", help="do not write RUN/recording.rrd")
    p.add_argument("--export-frames", action="store_true", help="also write the labeled panoramas as JPEG")
    p.add_argument(
        "--min-walk",
        type=_non_negative_float,
        default=None,
        metavar="M",
        help="without the camera, keep only tracks that walked M metres somewhere (default 1; 0 also keeps "
        "whoever stood still the whole recording, and the furniture); with it, a track is also output where "
        "it walked M metres, not only near the camera's detections (0: only there)",
    )
    p.add_argument(
        "--ground-truth", default=None, help="ground truth to log beside the labels (compare view)"
    )

    p = sub.add_parser("evaluate", help="compare labels with ground truth (P/R/F1, CLEAR MOT, IDF1, HOTA)")
    p.add_argument("pred", help="predicted labels (.yaml thesis format or .jsonl)")
    p.add_argument("gt", help="ground truth (.yaml or .jsonl)")
    p.add_argument("--radius", type=_positive_float, default=0.2, help="match radius in metres (default 0.2)")
    p.add_argument(
        "--frame",
        choices=("base", "odom"),
        default="base",
        help="compare positions in the robot's base frame (x, y; default) or the odom frame (x_odom, y_odom)",
    )
    p.add_argument(
        "--max-range",
        type=_positive_float,
        default=None,
        help="the ground truth lists people within this many metres of the robot only: people and "
        "predictions farther away count only where they match (base frame; default: everywhere)",
    )
    p.add_argument("--json", default=None, help="also write the metrics as JSON to this file")

    p = sub.add_parser("view", help="open a run in the Rerun viewer with a blueprint")
    p.add_argument("run", help="run directory or .rrd file")
    p.add_argument(
        "--blueprint",
        default=None,
        help="review | laser | calibration | compare (default: review, laser for a run without images)",
    )
    p.add_argument("--web", action="store_true", help="serve the web viewer instead of the native one")
    p.add_argument("--screenshot", default=None, help="render headless and save a PNG screenshot")

    p = sub.add_parser("annotate", help=_help("annotate", "correct ground truth in the browser (127.0.0.1)"))
    p.add_argument("run", help="run directory")
    p.add_argument("--port", type=int, default=8765, help="port on 127.0.0.1 (0 picks a free one)")
    p.add_argument("--author", default=None, help="name recorded with each correction (default: login name)")
    p.add_argument(
        "--rerun",
        nargs="?",
        const="rerun+http://127.0.0.1:9876/proxy",
        default=None,
        metavar="URL",
        help="log corrected ground truth live into a Rerun viewer showing this run (needs RUN/recording.rrd)",
    )

    p = sub.add_parser("calibrate", help=_help("calibrate", "laser ↔ panorama calibration"))
    csub = p.add_subparsers(dest="calib_command", metavar="SUBCOMMAND", required=True)
    c = csub.add_parser("extrinsics", help="fit the camera pose from x,y,z,u,v correspondences")
    c.add_argument("--correspondences", required=True, help="CSV with columns x,y,z,u,v")
    c.add_argument("--image-size", type=_image_size, required=True, help="panorama size WxH")
    c.add_argument("--folds", type=int, default=5, help="cross-validation folds (default 5)")
    c.add_argument("--json", default=None, help="also write the errors as JSON")
    c.add_argument("--out", required=True, help="calib.yaml to write")
    c = csub.add_parser("project", help="project x,y,z points into the panorama")
    c.add_argument("--rig", required=True, help="rig.yaml or calib.yaml")
    c.add_argument("--points", required=True, help="CSV with columns x,y,z")
    c.add_argument("--image-size", type=_image_size, required=True, help="panorama size WxH")
    c.add_argument("--out", required=True, help="CSV of u,v to write")
    c = csub.add_parser(
        "targets", help="x,y,z,u,v correspondences from a calibration recording (ball | board)"
    )
    c.add_argument("recording", help="calibration recording (the target moved around the robot)")
    c.add_argument("--rig", required=True, help="rig.yaml (nominal camera pose is enough)")
    c.add_argument("--target", choices=("ball", "board"), default="ball")
    c.add_argument("--out", required=True, help="correspondences CSV to write")
    c.add_argument("--ball-radius", type=_positive_float, default=0.25, help="ball radius, m (default 0.25)")
    c.add_argument("--board-width", type=_positive_float, default=0.8, help="board width, m (default 0.8)")
    c.add_argument(
        "--max-offset",
        type=_in_range(0.0, 30.0),
        default=0.5,
        help="search the camera time offset within ±S s (0: off; at most 30)",
    )
    c.add_argument("--include-moving", action="store_true", help="also keep samples while the target moves")
    c.add_argument("--json", default=None, help="also write a report as JSON")
    c = csub.add_parser("intrinsics", help="check the spherical camera model with a checkerboard")
    c.add_argument("source", help="a recording (with --rig) or a folder of panorama images")
    c.add_argument("--rig", default=None, help="rig.yaml when SOURCE is a recording")
    c.add_argument("--pattern", type=_pattern, default=(8, 5), help="inner corners COLSxROWS (default 8x5)")
    c.add_argument("--square", type=_positive_float, default=0.07, help="square size, m (default 0.07)")
    c.add_argument(
        "--face-size",
        type=_in_range(32, 4096, integer=True),
        default=None,
        help="cube-face size, px, 32-4096 (default: from the image)",
    )
    c.add_argument(
        "--every", type=_in_range(1, 10**6, integer=True), default=1, help="use every n-th panorama"
    )
    c.add_argument("--json", default=None, help="also write the report as JSON")
    c = csub.add_parser("people", help="camera pose and camera-laser latency from people (no target)")
    c.add_argument("--recording", required=True, help="any recording with people, camera and lasers")
    c.add_argument("--rig", required=True, help="rig.yaml to refine")
    c.add_argument("--out", required=True, help="rig.yaml to write, with the new camera pose and latency")
    c.add_argument("--run", default=None, help="a labeled run: reuse its image detections")
    c.add_argument("--max-offset-s", type=_positive_float, default=2.0, help="latency search range ±S s")
    c.add_argument("--max-yaw-deg", type=_positive_float, default=30.0, help="yaw search range ±D°")
    c.add_argument("--image-period-s", type=_positive_float, default=0.2, help="run the detector every S s")
    c.add_argument("--max-std-s", type=_positive_float, default=0.05, help="refuse a less certain latency")
    c.add_argument("--json", default=None, help="also write the result as JSON")

    p = sub.add_parser("detect-image", help="run the image people detector alone on panoramas")
    p.add_argument("panoramas", nargs="+", help="equirectangular images")
    p.add_argument("--out", required=True, help="JSONL file to write")
    p.add_argument("--image-detector", default=None, help="detector name or a YOLO .onnx file")
    return parser


# command name → (module, issue that builds it)
_COMMANDS: dict[str, tuple[str, int]] = {
    "demo": ("studio.commands.demo", 2),
    "simulate": ("studio.commands.simulate", 2),
    "inspect": ("studio.commands.inspect", 2),
    "label": ("studio.commands.label", 3),
    "evaluate": ("studio.commands.evaluate", 4),
    "view": ("studio.commands.view", 5),
    "annotate": ("studio.commands.annotate", 6),
    "calibrate": ("studio.commands.calibrate", 7),
    "detect-image": ("studio.commands.detect_image", 3),
}


def _handler(command: str) -> Callable[[argparse.Namespace], int]:
    module_name, issue = _COMMANDS[command]
    try:
        module = importlib.import_module(module_name)
    except ModuleNotFoundError as exc:
        if exc.name != module_name:
            raise
        raise StudioError(f"'studio {command}' is not built yet (planned in issue #{issue})") from None
    run: Callable[[argparse.Namespace], int] = module.run
    return run


class _Terminated(KeyboardInterrupt):
    """SIGTERM (``kill``, a job scheduler's time limit): unwinds as Ctrl-C does, so no half-written output
    or temporary folder is left."""


def _terminate(signum: int, frame: object) -> None:
    raise _Terminated


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    on_main_thread = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGTERM, _terminate) if on_main_thread else None
    try:
        return int(_handler(args.command)(args) or 0)
    except StudioError as exc:
        print(f"studio {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except _Terminated:
        print(f"studio {args.command}: terminated", file=sys.stderr)
        return 143
    except KeyboardInterrupt:
        print(f"studio {args.command}: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # e.g. `studio inspect BAG | head`
        with contextlib.suppress(OSError):
            sys.stdout = open(os.devnull, "w")  # noqa: SIM115 - silence the flush at exit
        return 0
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


if __name__ == "__main__":
    sys.exit(main())
