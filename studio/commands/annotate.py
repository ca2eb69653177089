"""``studio annotate RUN [--port P]``: the annotation page on 127.0.0.1 (DESIGN.md §2, docs/annotation.md)."""

from __future__ import annotations

import argparse
import getpass
from pathlib import Path

from studio.errors import StudioError

__all__ = ["run"]


def run(args: argparse.Namespace) -> int:
    from studio.annotate.app import bind_socket, make_server
    from studio.annotate.server import AnnotateServer

    run_dir = Path(args.run)
    if not run_dir.is_dir():
        raise StudioError(f"{run_dir}: no such run directory")
    if not (run_dir / "labels.jsonl").is_file():
        raise StudioError(f"{run_dir}: not a run directory (no labels.jsonl; make one with 'studio label')")
    author = getattr(args, "author", None) or _user()
    sock = bind_socket(int(args.port))
    state = AnnotateServer(run_dir, author=author)
    if getattr(args, "rerun", None):
        from studio.annotate.rerun_sync import RerunLink

        state.rerun = RerunLink.connect(state, url=args.rerun)
        state.on_change = state.rerun.log_frames
    port = sock.getsockname()[1]
    print(f"studio annotate: {run_dir} ({len(state.frame_ids)} frames) as '{author}'", flush=True)
    if state.media.problem:
        print(f"studio annotate: warning: no panoramas or scans: {state.media.problem}", flush=True)
    print(
        f"open http://127.0.0.1:{port}/  (Ctrl-C to stop; every edit is saved when acknowledged)", flush=True
    )
    server = make_server(state)
    try:
        server.run(sockets=[sock])
    except KeyboardInterrupt:
        pass
    finally:
        state.close()
        sock.close()
    return 0


def _user() -> str:
    try:
        return getpass.getuser() or "user"
    except (OSError, KeyError):
        return "user"
