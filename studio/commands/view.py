"""``studio view RUN|RRD [--blueprint NAME] [--web] [--screenshot PNG]``: open a run in the Rerun viewer."""

from __future__ import annotations

import argparse
import contextlib
import json
import shutil
import signal
from pathlib import Path

from studio.atomic import out_file
from studio.errors import StudioError

__all__ = ["default_blueprint", "run"]


def default_blueprint(rrd: Path) -> str:
    """``laser`` for a run without camera images (its ``run.json`` beside the recording says so), else
    ``review``."""
    try:
        info = json.loads((rrd.parent / "run.json").read_text())
    except (OSError, ValueError):
        return "review"
    no_images = isinstance(info, dict) and "image_size" in info and info["image_size"] is None
    return "laser" if no_images else "review"


def run(args: argparse.Namespace) -> int:
    from studio.viz.blueprints import BLUEPRINTS
    from studio.viz.viewer import open_native, resolve_rrd, screenshot, serve_web

    if args.blueprint is not None and args.blueprint not in BLUEPRINTS:
        raise StudioError(f"unknown blueprint '{args.blueprint}' (known: {', '.join(BLUEPRINTS)})")
    if args.web and args.screenshot:
        raise StudioError("--web and --screenshot exclude each other")
    rrd = resolve_rrd(args.run)
    shot = out_file(args.screenshot, "--screenshot", inputs=[rrd])  # before the viewer starts
    name = args.blueprint or default_blueprint(rrd)
    if shot is not None:
        res = screenshot(rrd, shot, blueprint_name=name)
        print(f"screenshot of {rrd} with blueprint '{name}' → {res.png}")
        for line in res.errors():
            print(f"view report: {line}")
        return 0
    if args.web:
        proc, url, bp_path = serve_web(rrd, blueprint_name=name)
        print(f"serving {rrd} with blueprint '{name}': open {url}  (Ctrl-C to stop)", flush=True)

        def _stop(signum: int, frame: object) -> None:
            raise KeyboardInterrupt

        old = signal.signal(signal.SIGTERM, _stop)
        try:
            proc.wait()
        except KeyboardInterrupt:
            pass
        finally:
            signal.signal(signal.SIGTERM, old)
            if proc.poll() is None:
                proc.terminate()
                with contextlib.suppress(Exception):
                    proc.wait(timeout=5)
            shutil.rmtree(bp_path.parent, ignore_errors=True)
        return 0
    open_native(rrd, blueprint_name=name)
    print(f"opened {rrd} in the Rerun viewer with blueprint '{name}'")
    return 0
