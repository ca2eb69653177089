"""Open a studio recording in a Rerun viewer: native window, web viewer, or a headless screenshot.

The blueprint is built in code (:mod:`studio.viz.blueprints`), saved to a temporary ``.rbl`` and opened
before the recording (the viewer applies a blueprint to the recordings of its application id).
"""

from __future__ import annotations

import contextlib
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import time
import warnings
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from studio.errors import StudioError
from studio.viz import paths as ep
from studio.viz.blueprints import blueprint

__all__ = ["ScreenshotResult", "ViewerError", "open_native", "resolve_rrd", "screenshot", "serve_web"]


class ViewerError(StudioError):
    """The recording cannot be opened, or the viewer cannot be started."""


def resolve_rrd(target: str | Path) -> Path:
    """The ``.rrd`` of a run directory (``RUN/recording.rrd``) or an ``.rrd`` path, checked to be readable.

    Raises:
        ViewerError: missing, not a Rerun recording, or corrupt (truncated) — one readable line.
    """
    p = Path(target)
    if p.is_dir():
        p = p / "recording.rrd"
        if not p.exists():
            raise ViewerError(
                f"{target}: no recording.rrd in this run directory (was it labeled with --no-rrd?)"
            )
    elif not p.exists():
        raise ViewerError(f"{target}: no such run directory or .rrd file")
    try:
        import rerun as rr

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            reader = rr.chunk.RrdReader(str(p))
            if not reader.recordings():
                raise ViewerError(f"{p}: holds no Rerun recording")
            for _ in reader.stream():
                pass
    except ViewerError:
        raise
    except Exception as exc:  # the reader raises RuntimeError/ValueError with a long message
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        msg = msg.split(": ", 1)[-1] if msg.startswith("Failed to read RRD file") else msg
        raise ViewerError(f"{p}: not a readable Rerun recording ({msg})") from None
    return p


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _rerun_exe() -> str:
    here = Path(sys.executable).parent / "rerun"
    exe = str(here) if here.exists() else shutil.which("rerun")
    if exe is None:
        raise ViewerError("the Rerun viewer executable 'rerun' is not installed (pip install rerun-sdk)")
    return exe


@contextlib.contextmanager
def _blueprint_file(name: str) -> Iterator[Path]:
    bp = blueprint(name)
    with tempfile.TemporaryDirectory(prefix="studio-view-") as tmp:
        path = Path(tmp) / f"{name}.rbl"
        bp.save(ep.APP_ID, path)
        yield path


@contextlib.contextmanager
def _quiet_viewer_env() -> Iterator[None]:
    """Spawned viewers inherit the environment: keep their log to warnings and give them a runtime dir."""
    old = {k: os.environ.get(k) for k in ("RUST_LOG", "XDG_RUNTIME_DIR")}
    os.environ["RUST_LOG"] = old["RUST_LOG"] or "error"
    runtime = old["XDG_RUNTIME_DIR"]
    if not runtime or not Path(runtime).is_dir():
        d = Path(tempfile.gettempdir()) / f"studio-xdg-{os.getuid()}"
        d.mkdir(mode=0o700, exist_ok=True)
        os.environ["XDG_RUNTIME_DIR"] = str(d)
    try:
        yield
    finally:
        for k, v in old.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def _open(client: Any, rrd: Path, bp_path: Path) -> None:
    client.open(str(bp_path), navigate=False)
    client.open(str(rrd.resolve()))


@dataclass
class ScreenshotResult:
    """What the headless viewer showed.

    Attributes:
        png: the screenshot file.
        views: ``(name, view_class, reports)`` per view of the blueprint; reports are
            ``(severity, summary)`` pairs, empty for a healthy view.
        timelines: names of the recording's timelines.
    """

    png: Path
    views: list[tuple[str, str, list[tuple[str, str]]]] = field(default_factory=list)
    timelines: list[str] = field(default_factory=list)

    def errors(self) -> list[str]:
        """``"view: summary"`` of every view that reported an error or warning."""
        return [f"{name}: {sev} {summary}" for name, _, reps in self.views for sev, summary in reps]


def screenshot(
    target: str | Path,
    png: str | Path,
    *,
    blueprint_name: str = "review",
    frame: int | None = None,
    timeout_s: float = 90.0,
    settle_s: float = 3.0,
) -> ScreenshotResult:
    """Render a recording with a blueprint in a headless viewer and save a PNG screenshot.

    Args:
        target: run directory or ``.rrd``.
        png: output file.
        blueprint_name: ``review``, ``calibration`` or ``compare``.
        frame: put the time cursor on this frame (default: the middle of the recording).
        timeout_s: give up loading after this long, s.
        settle_s: wait this long after loading for the views to draw, s.

    Raises:
        ViewerError: unreadable recording, or the viewer failed (e.g. no Vulkan driver: install Mesa's
            ``mesa-vulkan-drivers``).
    """
    from rerun.experimental import ViewerClient

    rrd = resolve_rrd(target)
    out = Path(png)
    with _blueprint_file(blueprint_name) as bp_path, _quiet_viewer_env():
        try:
            client = ViewerClient.spawn(
                headless=True, port=_free_port(), hide_welcome_screen=True, executable_path=_rerun_exe()
            )
        except Exception as exc:
            raise ViewerError(f"cannot start the headless Rerun viewer: {str(exc).splitlines()[0]}") from None
        try:
            _open(client, rrd, bp_path)
            state = _wait_loaded(client, timeout_s)
            rec = next((r for r in state.recordings if r.store_id == state.active_recording), None)
            timelines = [t.name for t in rec.timelines] if rec is not None else []
            tl = next((t for t in rec.timelines if t.name == ep.TIMELINE_FRAME), None) if rec else None
            if tl is not None and tl.start is not None and tl.end is not None:
                seq = frame if frame is not None else (tl.start + tl.end) // 2
                client.set_time(ep.TIMELINE_FRAME, sequence=int(seq), play_state="paused")
            time.sleep(settle_s)
            client.take_screenshot()  # the first paint after a time change can miss late chunks
            time.sleep(1.0)
            out.parent.mkdir(parents=True, exist_ok=True)
            out.write_bytes(client.take_screenshot())
            state = client.get_state()
            views = [
                (v.name, v.view_class, [(r.severity, r.summary) for r in v.reports]) for v in state.views
            ]
            return ScreenshotResult(out, views, timelines)
        except ViewerError:
            raise
        except Exception as exc:
            raise ViewerError(f"the headless Rerun viewer failed: {str(exc).splitlines()[0]}") from None
        finally:
            with contextlib.suppress(Exception):
                client.quit()


def _wait_loaded(client: Any, timeout_s: float) -> Any:
    t_end = time.monotonic() + timeout_s
    while True:
        state = client.get_state()
        rec = next((r for r in state.recordings if r.store_id == state.active_recording), None)
        if not state.loading and rec is not None and rec.timelines and state.views:
            return state
        if time.monotonic() > t_end:
            raise ViewerError(f"the viewer did not finish loading the recording within {timeout_s:.0f} s")
        time.sleep(0.5)


def open_native(target: str | Path, *, blueprint_name: str = "review") -> None:
    """Open the recording in the native viewer (a detached window that outlives this process)."""
    from rerun.experimental import ViewerClient

    rrd = resolve_rrd(target)
    bp = blueprint(blueprint_name)
    if sys.platform.startswith("linux") and not (
        os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
    ):
        raise ViewerError(
            "no display (neither DISPLAY nor WAYLAND_DISPLAY is set): use --web or --screenshot"
        )
    tmp = Path(tempfile.mkdtemp(prefix="studio-view-"))
    bp_path = tmp / f"{blueprint_name}.rbl"
    bp.save(ep.APP_ID, bp_path)
    try:
        client = ViewerClient.spawn(
            headless=False,
            port=_free_port(),
            hide_welcome_screen=True,
            detach_process=True,
            executable_path=_rerun_exe(),
        )
        _open(client, rrd, bp_path)
    except Exception as exc:
        raise ViewerError(
            f"cannot open the native Rerun viewer ({str(exc).splitlines()[0]}); "
            "on a machine without a display "
            "use --web or --screenshot"
        ) from None


def serve_web(
    target: str | Path, *, blueprint_name: str = "review", web_port: int = 9090, grpc_port: int | None = None
) -> tuple[subprocess.Popen[bytes], str, Path]:
    """Serve the web viewer on 127.0.0.1 with the recording and the blueprint.

    Returns:
        The server process (stop it with ``terminate()``), the URL to open, and the temporary blueprint file
        (delete its directory when done).
    """
    rrd = resolve_rrd(target)
    tmp = Path(tempfile.mkdtemp(prefix="studio-view-"))
    bp_path = tmp / f"{blueprint_name}.rbl"
    blueprint(blueprint_name).save(ep.APP_ID, bp_path)
    grpc = grpc_port or _free_port()
    cmd = [
        _rerun_exe(),
        "--serve-web",
        "--bind",
        "127.0.0.1",
        "--port",
        str(grpc),
        "--web-viewer-port",
        str(web_port),
        str(bp_path),
        str(rrd.resolve()),
    ]
    env = dict(os.environ, RUST_LOG=os.environ.get("RUST_LOG", "warn"))
    proc = subprocess.Popen(cmd, env=env)
    url = f"http://127.0.0.1:{web_port}/?url=rerun%2Bhttp://127.0.0.1:{grpc}/proxy"
    return proc, url, bp_path
