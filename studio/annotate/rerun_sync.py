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

Time cursor: the link also attaches a :class:`rerun.experimental.ViewerClient` to the same viewer (rerun-sdk
0.41's viewer-control API, experimental) and polls ``get_state()`` a few times a second: the viewer's cursor
on the ``frame`` timeline (or on ``time``, mapped to the nearest frame stamp) of the run's recording is
reported to the page, which follows it; stepping frames on the page moves the viewer's cursor with
``set_time``. When that API is not available (an older viewer, a file sink in tests), ground truth is still
logged and :meth:`RerunLink.status` says ``can_follow: false``.
"""

from __future__ import annotations

import bisect
import threading
from pathlib import Path
from typing import Any

from studio.errors import StudioError

__all__ = ["DEFAULT_URL", "RerunLink", "RerunLinkError", "run_recording_id"]

DEFAULT_URL = "rerun+http://127.0.0.1:9876/proxy"
FOLLOW_NOTE = "no viewer control channel: ground truth is logged live, step frames in each tool"
POLL_S = 0.25


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

    def __init__(self, state: Any, rec: Any, *, url: str | None = None, viewer: Any = None) -> None:
        self.state = state
        self.rec = rec
        self.url = url
        self.viewer = viewer  # a rerun.experimental.ViewerClient, or None
        self.logged_rev = -1
        self.error: str | None = None
        self.viewer_frame: int | None = None
        self._dirty = threading.Event()
        self._idle = threading.Event()
        self._closed = False
        self._stop = threading.Event()
        self._dirty.set()  # log the current ground truth once at start
        self._thread = threading.Thread(target=self._loop, name="studio-rerun-link", daemon=True)
        self._thread.start()
        self._poller: threading.Thread | None = None
        if viewer is not None:
            self._frames = list(state.frame_ids)
            self._stamps = sorted(
                (f.stamp_ns, f.frame) for f in (state.auto[m] for m in self._frames) if f.stamp_ns is not None
            )
            self._poller = threading.Thread(target=self._poll, name="studio-rerun-cursor", daemon=True)
            self._poller.start()

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
        viewer = None
        try:
            from rerun.experimental import ViewerClient

            viewer = ViewerClient.connect(url or DEFAULT_URL)
            viewer.get_state()
        except Exception:  # no viewer-control API (older viewer): log only
            viewer = None
        return cls(state, rec, url=url or DEFAULT_URL, viewer=viewer)

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
            "can_follow": self.viewer is not None,
            "frame": self.viewer_frame,
            "note": None if self.viewer is not None else FOLLOW_NOTE,
        }

    def set_frame(self, frame: int) -> dict[str, Any]:
        """Move the viewer's time cursor to ``frame`` (on the ``frame`` timeline of the run's recording)."""
        if self.viewer is None:
            return {"moved": False, "frame": frame, "reason": FOLLOW_NOTE}
        from studio.viz.paths import TIMELINE_FRAME

        try:
            self.viewer.set_time(
                TIMELINE_FRAME, sequence=int(frame), play_state="paused", recording=self._store_id()
            )
        except Exception as exc:
            return {"moved": False, "frame": frame, "reason": f"the viewer refused: {exc}"}
        self.viewer_frame = int(frame)  # do not bounce back before the next poll
        return {"moved": True, "frame": int(frame)}

    def _store_id(self) -> str | None:
        """The viewer's id of the run's recording (None: let the viewer use its active one)."""
        rid = getattr(self.rec, "get_recording_id", lambda: None)()
        try:
            recs = self.viewer.get_state().recordings
        except Exception:
            return None
        return next((r.store_id for r in recs if rid and str(r.store_id).endswith(f":{rid}")), None)

    def _cursor_frame(self, timeline: str | None, value: int | None) -> int | None:
        from studio.viz.paths import TIMELINE_FRAME, TIMELINE_TIME

        if value is None:
            return None
        if timeline == TIMELINE_FRAME:
            return int(value)
        if timeline == TIMELINE_TIME and self._stamps:
            k = bisect.bisect_left(self._stamps, (int(value), -1))
            near = [self._stamps[i] for i in (k - 1, k) if 0 <= i < len(self._stamps)]
            return min(near, key=lambda sf: abs(sf[0] - int(value)))[1]
        return None

    def _poll(self) -> None:
        rid = getattr(self.rec, "get_recording_id", lambda: None)()
        while not self._stop.wait(POLL_S):
            try:
                st = self.viewer.get_state()
            except Exception:
                continue
            rec = next((r for r in st.recordings if rid and str(r.store_id).endswith(f":{rid}")), None)
            if rec is None:
                continue
            f = self._cursor_frame(rec.current_timeline, rec.current_time)
            if f is not None:
                self.viewer_frame = f

    def wait_idle(self, timeout_s: float = 30.0) -> bool:
        """Wait until everything edited so far is logged (for tests)."""
        return self._idle.wait(timeout_s)

    def close(self) -> None:
        self._closed = True
        self._stop.set()
        self._dirty.set()
        self._thread.join(timeout=10)
        if self._poller is not None:
            self._poller.join(timeout=5)
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
