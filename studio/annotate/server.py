"""The annotation page's HTTP server: one static page plus a small JSON API over an :class:`AnnotationStore`.

Bound to 127.0.0.1 only. Every answer that is not a page, a script or an image is JSON; errors are
``{"error": "..."}`` with 400 (malformed request), 404 (unknown frame or path), 409 (conflict: the
frame changed since the client's ``base_rev``), 413 (body over 256 kB) or 422 (an operation that does
not apply). Nothing outside
the run directory is ever served: static files come from a fixed list of names, images from the
recording named in ``run.json``.

Endpoints::

    GET  /                              the page
    GET  /static/{name}                 index.html, app.js, style.css
    GET  /api/meta                      run name, frame count, stamps, camera, sizes, rev, doubt frames
    GET  /api/state                     rev, metrics rev, reviewed count, Rerun link (what a page polls)
    GET  /api/frame/{n}                 ground truth, auto labels, scan (xy + uv), trails, flags, doubts,
                                        who changed
    GET  /api/frame/{n}/panorama.jpg    the panorama (downscaled, cached)
    POST /api/op                        {"op": {...}, "base_rev": r, "client": "..."} → {rev, frames, op}
    POST /api/undo, /api/redo           {"base_rev": r, "client": "..."}
    GET  /api/history?frame=&limit=     the corrections log, newest first
    GET  /api/metrics                   auto labels vs ground truth on the reviewed frames
    GET  /api/next?kind=flag|unreviewed|doubt|worst&from=n&dir=1|-1   (doubt: review.jsonl's, unreviewed;
                                        worst: the unreviewed one of the highest doubt, anywhere)
    GET  /api/rerun                     the Rerun link's state; POST /api/rerun/time {"frame": n}
"""

from __future__ import annotations

import contextlib
import math
import re
import threading
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from studio.annotate.media import MediaError, RunMedia
from studio.errors import StudioError
from studio.labels import LabelError, read_review

__all__ = ["AnnotateServer", "ApiError", "ServerError"]

STATIC_DIR = Path(__file__).with_name("static")
STATIC_TYPES = {".html": "text/html; charset=utf-8", ".js": "text/javascript", ".css": "text/css"}
TRAIL_FRAMES = 25  # frames of history drawn as trails in the bird's-eye view
PERSON_HEIGHT = 1.7  # m: the panorama marker of a person spans the ground to this height
MAX_BODY = 256 * 1024  # bytes: the largest request body accepted (an op is well under 1 kB)


class ServerError(StudioError):
    """The server cannot start (run directory missing, port taken)."""


@dataclass
class ApiError(Exception):
    """An HTTP error answered as ``{"error": message}``."""

    status: int
    message: str
    extra: dict[str, Any] | None = None


def _int_param(value: Any, what: str) -> int:
    if isinstance(value, bool):
        raise ApiError(400, f"{what} must be an integer, got {value!r}")
    if isinstance(value, int):
        return value
    text = str(value)
    if not re.fullmatch(r"-?[0-9]{1,19}", text):  # not "1_0", "+1", " 1", "١"
        raise ApiError(400, f"{what} must be an integer, got {value!r}")
    return int(text)


class AnnotateServer:
    """The state behind the API: the store, the auto labels, the media reader, cached evaluations.

    Args:
        run_dir: the run directory.
        author: name recorded with each correction.
        store: an open store (default: ``AnnotationStore.open(run_dir, author=author)``).
        media: a media reader (default: one with its disk cache under ``RUN/annotations/cache``).
        on_change: called with the changed frame indices after each applied operation (Rerun link).
    """

    def __init__(
        self,
        run_dir: str | Path,
        *,
        author: str = "user",
        store: Any = None,
        media: RunMedia | None = None,
        on_change: Callable[[list[int]], None] | None = None,
    ) -> None:
        from studio.annotate.store import AnnotationStore
        from studio.labels import read_labels

        self.run_dir = Path(run_dir).resolve()
        if not (self.run_dir / "labels.jsonl").is_file():
            raise ServerError(f"{self.run_dir}: not a run directory (no labels.jsonl)")
        self.author = author
        self.auto = read_labels(self.run_dir / "labels.jsonl").by_frame()
        if not self.auto:
            raise ServerError(f"{self.run_dir}/labels.jsonl has no frames: nothing to annotate")
        try:
            points = read_review(self.run_dir / "review.jsonl")  # none in a run made before it existed
        except LabelError as exc:
            raise ServerError(str(exc)) from None
        self.doubts: dict[int, list[dict[str, Any]]] = {}  # frame -> the run's review points there
        for p in points:
            self.doubts.setdefault(p.frame, []).append(
                {"ids": list(p.ids), "kind": p.kind, "note": p.note, "doubt": p.doubt}
            )
        self.store = store if store is not None else AnnotationStore.open(self.run_dir, author=author)
        self.media = media or RunMedia(self.run_dir, cache_dir=self.run_dir / "annotations" / "cache")
        self.frame_ids = sorted(self.auto)
        self._frame_set = set(self.frame_ids)
        self._index = {m: i for i, m in enumerate(self.frame_ids)}
        self._reviewed: tuple[int, frozenset[int]] = (-1, frozenset())
        self._flags: tuple[int, dict[int, dict[str, Any]]] = (-2, {})
        self.lock = threading.RLock()
        self._closed = False
        self._ev_result: tuple[int, dict[str, Any]] = (-1, {})
        self._ev_cond = threading.Condition()
        self._ev_wanted = threading.Event()
        self._ev_wanted.set()
        threading.Thread(target=self._eval_loop, name="studio-annotate-eval", daemon=True).start()
        self.on_change = on_change
        self.rerun: Any = None  # a studio.annotate.rerun_sync.RerunLink when connected
        self._camera: Any = None

    def close(self) -> None:
        """Close the store, the media reader and the Rerun link."""
        self._closed = True
        self._ev_wanted.set()
        if self.rerun is not None:
            self.rerun.close()
        self.media.close()
        self.store.close()

    # ------------------------------------------------------------------ helpers
    def check_frame(self, n: Any) -> int:
        k = _int_param(n, "frame")
        if k not in self._frame_set:
            last = self.frame_ids[-1] if self.frame_ids else -1
            raise ApiError(404, f"unknown frame {k} (this run has frames 0..{last})")
        return k

    def camera(self) -> Any:
        """The panorama camera (original size, rig pose) or None."""
        if self._camera is None and self.media.has_camera and self.media.image_size is not None:
            rig = self.media._rig
            if rig is not None and rig.camera is not None:
                from studio.geometry import EquirectCamera
                from studio.geometry.se import Pose3

                pose = rig.camera.pose if rig.camera.pose is not None else Pose3.identity()
                w, h = self.media.image_size
                self._camera = EquirectCamera(w, h, pose, rig.camera.lens_offset)
        return self._camera

    def _people_json(self, frame: Any, who: dict[int, Any] | None = None) -> list[dict[str, Any]]:
        from studio.labels import frame_to_json

        if frame is None:
            return []
        people: list[dict[str, Any]] = frame_to_json(frame)["people"]
        cam = self.camera()
        for p in people:
            if who is not None and p["id"] in who:
                p["changed"] = who[p["id"]]
            if cam is not None:
                p["pano"] = self._pano_marker(cam, float(p["x"]), float(p["y"]))
        return people

    @staticmethod
    def _pano_marker(cam: Any, x: float, y: float) -> list[float] | None:
        import numpy as np

        uv, _ = cam.project(np.array([[x, y, 0.0], [x, y, PERSON_HEIGHT]]))
        if not np.all(np.isfinite(uv)):
            return None
        return [round(float(uv[0, 0]), 1), round(float(uv[1, 1]), 1), round(float(uv[0, 1]), 1)]

    def _trails(self, n: int, pose: Any) -> dict[str, list[list[float]]]:
        """Ground-truth positions of the last frames, in the base frame of frame ``n`` (m)."""
        x0, y0, yaw0 = (pose.x, pose.y, pose.yaw) if pose is not None else (0.0, 0.0, 0.0)
        c0, s0 = math.cos(yaw0), math.sin(yaw0)
        k = self._index[n]
        trails: dict[str, list[list[float]]] = {}
        for m in self.frame_ids[max(0, k - TRAIL_FRAMES) : k + 1]:
            f = self.store.frame(m)
            p = f.robot_pose
            xm, ym, yawm = (p.x, p.y, p.yaw) if p is not None else (0.0, 0.0, 0.0)
            cm, sm = math.cos(yawm), math.sin(yawm)
            for q in f.people:
                ox, oy = xm + cm * q.x - sm * q.y - x0, ym + sm * q.x + cm * q.y - y0  # odom, relative
                bx, by = c0 * ox + s0 * oy, -s0 * ox + c0 * oy  # into the base frame of frame n
                trails.setdefault(str(q.id), []).append([round(bx, 3), round(by, 3)])
        return trails

    def reviewed(self) -> frozenset[int]:
        """The store's reviewed frames, cached per revision (the store scans every frame)."""
        rev = self.store.rev
        if self._reviewed[0] != rev:
            self._reviewed = (rev, frozenset(self.store.reviewed()))
        return self._reviewed[1]

    # ------------------------------------------------------------------ evaluation (background)
    def _eval_loop(self) -> None:
        """Re-evaluate whenever the store's revision moved on (a 2 000-frame run takes a few seconds)."""
        from studio.evaluate import evaluate
        from studio.labels import LabelSet

        pred = LabelSet.from_frames(list(self.auto.values()))
        while not self._closed:
            self._ev_wanted.wait()
            self._ev_wanted.clear()
            if self._closed:
                return
            with self.lock:
                rev = self.store.rev
                if self._ev_result[0] == rev:
                    continue
                gt_all = self.store.frames()
                reviewed = self.store.reviewed()
            result: dict[str, Any] = {}
            for which, frames in (("all", gt_all), ("reviewed", [f for f in gt_all if f.frame in reviewed])):
                try:
                    result[which] = evaluate(pred, LabelSet.from_frames(frames)) if frames else None
                except Exception as exc:  # keep the thread alive: the page shows the error instead
                    result[which] = None
                    result["error"] = f"{type(exc).__name__}: {exc}"
            with self._ev_cond:
                self._ev_result = (rev, result)
                self._ev_cond.notify_all()

    def evaluation_error(self) -> str | None:
        """Why the latest evaluation failed (None: it did not)."""
        return self._ev_result[1].get("error")

    def evaluation(self, which: str, *, wait_s: float = 0.0) -> tuple[Any, int]:
        """The latest evaluation of the auto labels and its store revision (-1: none yet).

        ``"reviewed"``: against the ground truth of the reviewed frames (the page's metrics); ``"all"``:
        against every frame (flags). Computed in a background thread; with ``wait_s`` > 0, wait up to
        that long for the current revision's. The evaluation is None when there is nothing to evaluate.
        """
        rev = self.store.rev
        with self._ev_cond:
            if self._ev_result[0] != rev:
                self._ev_wanted.set()
                if wait_s > 0:
                    self._ev_cond.wait_for(lambda: self._ev_result[0] >= rev, timeout=wait_s)
            ev_rev, result = self._ev_result
        return result.get(which), ev_rev

    def flags(self, *, wait_s: float = 0.0) -> tuple[dict[int, dict[str, Any]], int]:
        """Frames where the auto labels disagree with the ground truth (FP / FN / ID switch ids), and
        the revision they were computed at."""
        ev, ev_rev = self.evaluation("all", wait_s=wait_s)
        cached = self._flags
        if cached[0] == ev_rev:
            return cached[1], ev_rev
        out: dict[int, dict[str, Any]] = {}
        for fe in ev.frames if ev is not None else ():
            if fe.fp or fe.fn or fe.id_switches:
                out[fe.frame] = {"fp": list(fe.fp_ids), "fn": list(fe.fn_ids), "switch": list(fe.switch_ids)}
        self._flags = (ev_rev, out)
        return out, ev_rev

    # ------------------------------------------------------------------ API bodies
    def meta(self) -> dict[str, Any]:
        with self.lock:
            reviewed = sorted(self.reviewed())
            rev = self.store.rev
        return {
            "run": self.run_dir.name,
            "num_frames": len(self.frame_ids),
            "frames": self.frame_ids,
            "stamps": [self.auto[m].stamp_ns for m in self.frame_ids],
            "has_camera": bool(self.media.has_camera),
            "image_size": list(self.media.image_size) if self.media.image_size else None,
            "display_size": list(d) if (d := self.media.display_size()) else None,
            "laser_topics": self.media.laser_topics,
            "media_problem": self.media.problem,
            "rev": rev,
            "reviewed": reviewed,
            "doubts": sorted(set(self.doubts) & self._frame_set),
            "author": self.author,
            "rerun": self.rerun.status() if self.rerun is not None else None,
        }

    def state(self) -> dict[str, Any]:
        """What a page polls every few seconds: small, whatever the run's length."""
        _, ev_rev = self.evaluation("all")  # starts a re-evaluation when the revision moved on
        return {
            "rev": self.store.rev,
            "metrics_rev": ev_rev,
            "reviewed_frames": len(self.reviewed()),
            "rerun": self.rerun.status() if self.rerun is not None else None,
        }

    def frame(self, n: Any) -> dict[str, Any]:
        k = self.check_frame(n)
        auto = self.auto.get(k)
        flags, flags_rev = self.flags()
        with self.lock:
            gt = self.store.frame(k)
            who = self.store.changed_by(k)
            body: dict[str, Any] = {
                "frame": k,
                "stamp_ns": gt.stamp_ns if gt.stamp_ns is not None else (auto.stamp_ns if auto else None),
                "robot_pose": (gt.robot_pose or (auto.robot_pose if auto else None)),
                "rev": self.store.rev,
                "frame_rev": self.store.frame_rev(k),
                "reviewed": k in self.reviewed(),
                "gt": self._people_json(gt, {int(i): v for i, v in who.items()}),
                "auto": self._people_json(auto),
                "flags": flags.get(k, {"fp": [], "fn": [], "switch": []}),
                "doubts": self.doubts.get(k, []),
                "flags_rev": flags_rev,
                "trails": self._trails(k, gt.robot_pose or (auto.robot_pose if auto else None)),
            }
        if body["robot_pose"] is not None:
            body["robot_pose"] = body["robot_pose"].as_dict()
        body["scan"] = None
        body["media_error"] = None
        stamp = body["stamp_ns"]
        if stamp is not None and self.media.laser_topics and self.media.problem is None:
            try:
                body["scan"] = self.media.scan(k, int(stamp)).to_json()
            except StudioError as exc:
                body["media_error"] = str(exc)
        self._prefetch(k)
        return body

    def _prefetch(self, k: int) -> None:
        if self.media.problem is not None:
            return
        i = self._index[k]
        near = [self.frame_ids[j] for j in (i + 1, i + 2, i - 1, i + 3) if 0 <= j < len(self.frame_ids)]
        pairs = [(m, int(s)) for m in near if (s := self.auto[m].stamp_ns) is not None]
        self.media.prefetch(pairs)

    def panorama(self, n: Any) -> bytes:
        k = self.check_frame(n)
        stamp = self.auto[k].stamp_ns
        if not self.media.has_camera:
            raise ApiError(404, "this run has no camera (laser-only): no panorama")
        if stamp is None:
            raise ApiError(404, f"frame {k} has no stamp_ns: cannot find its image")
        try:
            return self.media.panorama_jpeg(k, int(stamp))
        except MediaError as exc:
            raise ApiError(404, str(exc)) from None

    def apply(self, body: Any, kind: str) -> dict[str, Any]:
        from studio.annotate.log import check_name
        from studio.annotate.store import AnnotationError, ConflictError

        if not isinstance(body, dict):
            raise ApiError(400, "the request body must be a JSON object")
        base_rev = body.get("base_rev")
        if base_rev is not None:
            base_rev = _int_param(base_rev, "base_rev")
        try:
            client = check_name(body.get("client"), "client")
            author = check_name(body.get("author") or self.author, "author")
        except AnnotationError as exc:
            raise ApiError(400, str(exc)) from None
        with self.lock:
            try:
                if kind == "op":
                    op = body.get("op")
                    if isinstance(op, str):  # the op's own keys at the top level
                        op = {k: v for k, v in body.items() if k not in ("base_rev", "client", "author")}
                    if not isinstance(op, dict):
                        raise ApiError(400, 'expected {"op": {"op": "move", ...}, "base_rev": N}')
                    res = self.store.apply(op, base_rev=base_rev, author=author, client=client)
                elif kind == "undo":
                    res = self.store.undo(base_rev=base_rev, author=author, client=client)
                else:
                    res = self.store.redo(base_rev=base_rev, author=author, client=client)
            except ConflictError as exc:
                raise ApiError(409, str(exc), {"rev": self.store.rev}) from None
            except AnnotationError as exc:
                raise ApiError(422, str(exc), {"rev": self.store.rev}) from None
            frames = sorted(int(f) for f in res.frames)
            out = {"rev": res.rev, "frames": frames, "op": res.op}
        if self.on_change is not None and frames:
            with contextlib.suppress(Exception):
                self.on_change(frames)
        return out

    def history(self, frame: Any, limit: Any) -> dict[str, Any]:
        f = None if frame in (None, "") else self.check_frame(frame)
        lim = 50 if limit in (None, "") else _int_param(limit, "limit")
        if not 1 <= lim <= 1000:
            raise ApiError(400, f"limit must be 1..1000, got {lim}")
        with self.lock:
            return {"rev": self.store.rev, "history": self.store.history(frame=f, limit=lim)}

    def metrics(self, wait: Any = None) -> dict[str, Any]:
        wait_s = _wait_param(wait)
        ev, ev_rev = self.evaluation("reviewed", wait_s=wait_s)
        flags, _ = self.flags()
        flagged = sorted(flags)
        with self.lock:
            reviewed = sorted(self.reviewed())
            rev = self.store.rev
        out: dict[str, Any] = {
            "rev": rev,
            "metrics_rev": ev_rev,
            "stale": ev_rev != rev,
            "reviewed_frames": len(reviewed),
            "flagged_frames": len(flagged),
            "reviewed": reviewed,
            "flagged": flagged,
        }
        out["metrics"] = None if ev is None else ev.to_json()
        out["metrics_error"] = self.evaluation_error()
        return out

    def next_frame(self, kind: Any, start: Any, direction: Any, wait: Any = None) -> dict[str, Any]:
        if kind not in ("flag", "unreviewed", "doubt", "worst"):
            raise ApiError(400, f"kind must be 'flag', 'unreviewed', 'doubt' or 'worst', got {kind!r}")
        k = self.check_frame(start)
        step = 1 if direction in (None, "", "1", 1) else -1 if direction in ("-1", -1) else 0
        if step == 0:
            raise ApiError(400, f"dir must be 1 or -1, got {direction!r}")
        if kind == "flag":
            pool = set(self.flags(wait_s=_wait_param(wait) or 5.0)[0])
        elif kind in ("doubt", "worst"):  # the ones not marked reviewed yet: checked doubts are done
            with self.lock:
                pool = (set(self.doubts) & self._frame_set) - self.reviewed()
            if kind == "worst":  # the most doubtful first, wherever it is; of equals, the earliest
                worst = min(pool, key=lambda m: (-max(d["doubt"] for d in self.doubts[m]), m), default=None)
                return {"frame": worst, "remaining": len(pool)}
        else:
            with self.lock:
                pool = self._frame_set - self.reviewed()
        i = self._index[k]
        order = self.frame_ids[i + 1 :] if step > 0 else self.frame_ids[:i][::-1]
        nxt = next((m for m in order if m in pool), None)
        return {"frame": nxt, "remaining": len(pool)}


def _wait_param(value: Any) -> float:
    """``wait`` query parameter: seconds to wait for a fresh evaluation (0..60)."""
    if value in (None, ""):
        return 0.0
    try:
        w = float(value)
    except (TypeError, ValueError):
        raise ApiError(400, f"wait must be a number of seconds, got {value!r}") from None
    if not 0 <= w <= 60:
        raise ApiError(400, f"wait must be 0..60 s, got {w}")
    return w
