"""Keep a Rerun viewer in step with the annotation page: corrected ground truth is logged live.

What it does: :class:`RerunLink` opens a recording stream with the *run's own* application and recording
id (read from ``RUN/recording.rrd``) and connects it to a running viewer (``rr.connect_grpc``, by default
``rerun+http://127.0.0.1:9876/proxy``, the viewer ``studio view RUN --blueprint compare`` starts). The
viewer merges what it receives into the recording it already shows, so the ``compare`` blueprint's ground
truth entities (``world/odom/ground_truth``, ``world/odom/errors``, ``camera/panorama/ground_truth`` and
the per-frame metric series, see :func:`studio.viz.compare.log_ground_truth`) show the *corrected* ground
truth against the auto labels. After each acknowledged edit the whole ground truth is re-logged in a
background thread (edits in quick succession are coalesced); rows logged later at the same time point
replace the earlier ones in the viewer's latest-at queries.

What it does not do: follow or move the viewer's time cursor. rerun-sdk 0.41 reports time-cursor events
(``TimeUpdateEvent``) and can set the time (``set_time_ctrl``) only for a viewer embedded in a notebook
(``rerun.notebook.Viewer``) or a web page through the npm ``@rerun-io/web-viewer`` package; the native
viewer and the served web viewer offer no such channel to the SDK, and the annotation page loads nothing
from outside 127.0.0.1. :meth:`RerunLink.status` says so (``can_follow: false``) and the page hides its
"follow Rerun" switch.
"""

from __future__ import annotations

import threading
from pathlib import Path
from typing import Any

from studio.errors import StudioError

__all__ = ["DEFAULT_URL", "RerunLink", "RerunLinkError", "run_recording_id"]

DEFAULT_URL = "rerun+http://127.0.0.1:9876/proxy"
FOLLOW_NOTE = (
    "the Rerun SDK cannot read or move a native viewer's time cursor (only notebook / npm web-viewer "
    "embeddings can); ground truth is logged live, step frames in each tool"
)


class RerunLinkError(StudioError):
    """The Rerun link cannot be set up (no recording.rrd to attach to, bad URL)."""


def run_recording_id(run_dir: str | Path) -> tuple[str, str] | None:
    """``(application_id, recording_id)`` of ``RUN/recording.rrd``, or None when there is none."""
    rrd = Path(run_dir) / "recording.rrd"
    if not rrd.is_file():
        return None
    from rerun.chunk import RrdReader

    recs = RrdReader(rrd).recordings()
    if not recs:
        return None
    return recs[0].application_id, recs[0].recording_id


class RerunLink:
    """Logs the annotation server's ground truth into a Rerun recording stream (see the module doc).

    Args:
        state: the :class:`studio.annotate.server.AnnotateServer`.
        rec: the recording stream to log into (already connected, or saving to a file in tests).
        url: where ``rec`` is connected (for :meth:`status`).
    """

    def __init__(self, state: Any, rec: Any, *, url: str | None = None) -> None:
        self.state = state
        self.rec = rec
        self.url = url
        self.logged_rev = -1
        self.error: str | None = None
        self._dirty = threading.Event()
        self._idle = threading.Event()
        self._closed = False
        self._dirty.set()  # log the current ground truth once at start
        self._thread = threading.Thread(target=self._loop, name="studio-rerun-link", daemon=True)
        self._thread.start()

    @classmethod
    def connect(cls, state: Any, *, url: str | None = None) -> RerunLink:
        """Attach to the run's recording in the viewer at ``url`` (default :data:`DEFAULT_URL`).

        Raises:
            RerunLinkError: the run has no ``recording.rrd`` (label without ``--no-rrd``).
        """
        import rerun as rr

        ids = run_recording_id(state.run_dir)
        if ids is None:
            raise RerunLinkError(
                f"{state.run_dir}: no recording.rrd to attach to (label the run without --no-rrd)"
            )
        app_id, rec_id = ids
        rec = rr.RecordingStream(app_id, recording_id=rec_id)
        rec.set_log_time_enabled(False)
        rec.set_log_tick_enabled(False)
        try:
            rec.connect_grpc(url or DEFAULT_URL)
        except Exception as exc:
            raise RerunLinkError(f"cannot connect to a Rerun viewer at {url or DEFAULT_URL}: {exc}") from None
        return cls(state, rec, url=url or DEFAULT_URL)

    # ------------------------------------------------------------------ server hooks
    def log_frames(self, frames: list[int]) -> None:
        """Called after an acknowledged edit of ``frames``: re-log the ground truth soon."""
        if frames:
            self._idle.clear()
            self._dirty.set()

    def status(self) -> dict[str, Any]:
        return {
            "connected": True,
            "url": self.url,
            "recording_id": getattr(self.rec, "get_recording_id", lambda: None)(),
            "logged_rev": self.logged_rev,
            "error": self.error,
            "can_follow": False,
            "frame": None,
            "note": FOLLOW_NOTE,
        }

    def set_frame(self, frame: int) -> dict[str, Any]:
        """The viewer's time cursor cannot be moved from the SDK (see the module doc)."""
        return {"moved": False, "frame": frame, "reason": FOLLOW_NOTE}

    def wait_idle(self, timeout_s: float = 30.0) -> bool:
        """Wait until everything edited so far is logged (for tests)."""
        return self._idle.wait(timeout_s)

    def close(self) -> None:
        self._closed = True
        self._dirty.set()
        self._thread.join(timeout=10)
        try:
            self.rec.flush()
            self.rec.disconnect()
        except Exception:
            pass

    # ------------------------------------------------------------------ logging
    def _loop(self) -> None:
        from studio.labels import LabelSet
        from studio.viz.compare import log_ground_truth

        auto = [self.state.auto[m] for m in self.state.frame_ids]
        while True:
            self._dirty.wait()
            self._dirty.clear()
            if self._closed:
                return
            with self.state.lock:
                rev = self.state.store.rev
                gt = LabelSet.from_frames(self.state.store.frames())
            try:
                log_ground_truth(self.rec, auto, gt, camera=self.state.camera())
                self.rec.flush()
                self.logged_rev, self.error = rev, None
            except Exception as exc:
                self.error = f"{type(exc).__name__}: {exc}"
            if not self._dirty.is_set():
                self._idle.set()
