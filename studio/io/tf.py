"""A TF buffer: the transform tree of a recording, looked up at any stamp.

Each frame has one parent (as in ROS tf2; a frame re-parented later keeps its latest parent). Dynamic
edges are interpolated linearly in translation and by slerp in rotation; static edges hold at any time.
A stamp outside a dynamic edge's data is clamped to the nearest sample when it is within
``tolerance_ns`` of it, else :class:`TfError` is raised.

Old ROS1 bags have no ``/tf_static``: fixed transforms were re-broadcast on ``/tf``. In
:meth:`TfBuffer.from_recording`, a ``/tf`` edge is therefore made static when every one of its samples is
the same transform (within 1e-6 m and 1e-6 rad) — and an edge seen only once on ``/tf`` too — so sensor
mounts are usable at any stamp; an edge that moves at all stays dynamic (odometry never becomes static).
Memory: dynamic edges keep all their samples (7 floats + stamp each, ~3 MB per hour of a 50 Hz edge).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from studio.geometry.se import Pose3, rot_from_quat
from studio.io.errors import TfError

if TYPE_CHECKING:
    from studio.io.reader import Recording

__all__ = ["TfBuffer", "TfEdge", "quat_from_rot", "slerp", "tf_topics"]

_SAME_T = 1e-6  # m
_SAME_ANGLE = 1e-6  # rad


def quat_from_rot(R: NDArray[np.float64]) -> NDArray[np.float64]:
    """Unit quaternion ``(x, y, z, w)`` with w ≥ 0 of a 3×3 rotation matrix (numerically robust)."""
    m = np.asarray(R, dtype=np.float64)
    tr = m[0, 0] + m[1, 1] + m[2, 2]
    if tr > 0:
        s = 2.0 * np.sqrt(tr + 1.0)
        q = np.array([(m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, 0.25 * s])
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = 2.0 * np.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        q = np.array([0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s, (m[2, 1] - m[1, 2]) / s])
    elif m[1, 1] > m[2, 2]:
        s = 2.0 * np.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
        q = np.array([(m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s, (m[0, 2] - m[2, 0]) / s])
    else:
        s = 2.0 * np.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
        q = np.array([(m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s, (m[1, 0] - m[0, 1]) / s])
    q /= np.linalg.norm(q)
    return -q if q[3] < 0 else q


def slerp(q0: NDArray[np.float64], q1: NDArray[np.float64], u: float) -> NDArray[np.float64]:
    """Spherical linear interpolation of unit quaternions ``(x, y, z, w)``, ``u`` in [0, 1] (shortest arc)."""
    d = float(np.dot(q0, q1))
    if d < 0.0:
        q1, d = -q1, -d
    if d > 0.9995:
        q = q0 + u * (q1 - q0)
    else:
        th = np.arccos(min(d, 1.0))
        q = (np.sin((1.0 - u) * th) * q0 + np.sin(u * th) * q1) / np.sin(th)
    return q / np.linalg.norm(q)


@dataclass(frozen=True)
class TfEdge:
    """Summary of one edge of the tree (for display).

    Attributes:
        parent: parent frame.
        child: child frame.
        static: True when the transform holds at any time.
        count: number of samples.
        first_ns: first sample stamp, ns.
        last_ns: last sample stamp, ns.
    """

    parent: str
    child: str
    static: bool
    count: int
    first_ns: int
    last_ns: int


class _Edge:
    def __init__(self, parent: str, static: bool) -> None:
        self.parent = parent
        self.static = static
        self._stamps: list[int] = []
        self._t: list[NDArray[np.float64]] = []
        self._q: list[NDArray[np.float64]] = []
        self._arrays: tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]] | None = None

    def add(self, stamp_ns: int, pose: Pose3) -> None:
        if self.static:  # latest static value wins
            self._stamps, self._t, self._q = [], [], []
        self._stamps.append(int(stamp_ns))
        self._t.append(np.asarray(pose.t, dtype=np.float64).copy())
        self._q.append(quat_from_rot(pose.R))
        self._arrays = None

    def arrays(self) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]:
        if self._arrays is None:
            s = np.asarray(self._stamps, dtype=np.int64)
            order = np.argsort(s, kind="stable")
            self._arrays = (s[order], np.asarray(self._t)[order], np.asarray(self._q)[order])
        return self._arrays

    def constant(self) -> bool:
        _, t, q = self.arrays()
        if len(t) <= 1:
            return True
        dt = float(np.max(np.linalg.norm(t - t[0], axis=1)))
        dots = np.clip(np.abs(q @ q[0]), 0.0, 1.0)
        dang = float(np.max(2.0 * np.arccos(dots)))
        return dt <= _SAME_T and dang <= _SAME_ANGLE

    def at(self, stamp_ns: int, tolerance_ns: int, child: str) -> Pose3:
        s, t, q = self.arrays()
        if self.static:
            return Pose3(rot_from_quat(*q[-1]), t[-1])
        if stamp_ns <= s[0]:
            if s[0] - stamp_ns > tolerance_ns:
                raise self._range_error(stamp_ns, child, s)
            return Pose3(rot_from_quat(*q[0]), t[0])
        if stamp_ns >= s[-1]:
            if stamp_ns - s[-1] > tolerance_ns:
                raise self._range_error(stamp_ns, child, s)
            return Pose3(rot_from_quat(*q[-1]), t[-1])
        i = int(np.searchsorted(s, stamp_ns, side="right"))
        s0, s1 = int(s[i - 1]), int(s[i])
        u = 0.0 if s1 == s0 else (stamp_ns - s0) / (s1 - s0)
        tt = (1.0 - u) * t[i - 1] + u * t[i]
        qq = slerp(q[i - 1], q[i], u)
        return Pose3(rot_from_quat(*qq), tt)

    def _range_error(self, stamp_ns: int, child: str, s: NDArray[np.int64]) -> TfError:
        return TfError(
            f"no transform {self.parent} → {child} at {stamp_ns / 1e9:.3f} s: "
            f"the recording has it from {s[0] / 1e9:.3f} s to {s[-1] / 1e9:.3f} s"
        )


class TfBuffer:
    """Transform tree with time-interpolated lookups.

    Args:
        tolerance_ns: how far outside a dynamic edge's samples a lookup is clamped rather than refused, ns.
    """

    def __init__(self, *, tolerance_ns: int = 100_000_000) -> None:
        self.tolerance_ns = int(tolerance_ns)
        self._edges: dict[str, _Edge] = {}  # child → edge to its parent

    def __len__(self) -> int:
        return len(self._edges)

    def add(self, parent: str, child: str, stamp_ns: int, pose: Pose3, *, static: bool) -> None:
        """Add ``T_parent_child`` at ``stamp_ns`` (ns). A static edge holds at any time."""
        parent, child = parent.lstrip("/"), child.lstrip("/")
        if not parent or not child or parent == child:
            raise ValueError(f"invalid TF edge '{parent}' → '{child}'")
        edge = self._edges.get(child)
        if edge is None or edge.parent != parent or (static and not edge.static):
            edge = _Edge(parent, static)
            self._edges[child] = edge
        elif edge.static and not static:
            return  # a static mount also re-sent on /tf: keep it static
        edge.add(stamp_ns, pose)

    def frames(self) -> list[str]:
        """All frames of the tree, sorted."""
        names = set(self._edges)
        names.update(e.parent for e in self._edges.values())
        return sorted(names)

    def edges(self) -> list[TfEdge]:
        """Every edge (parent → child), sorted by parent then child."""
        out = []
        for child, e in self._edges.items():
            s, _, _ = e.arrays()
            out.append(TfEdge(e.parent, child, e.static, len(s), int(s[0]), int(s[-1])))
        return sorted(out, key=lambda x: (x.parent, x.child))

    def make_constant_edges_static(self) -> list[tuple[str, str]]:
        """Turn dynamic edges whose samples are all the same transform into static ones; returns them."""
        changed = []
        for child, e in self._edges.items():
            if not e.static and e.constant():
                e.static = True
                e._arrays = None
                changed.append((e.parent, child))
        return changed

    def _chain(self, frame: str) -> list[str]:
        chain = [frame]
        seen = {frame}
        while (edge := self._edges.get(chain[-1])) is not None:
            if edge.parent in seen:  # a loop in the data: stop there
                break
            chain.append(edge.parent)
            seen.add(edge.parent)
        return chain

    def _unknown(self, frame: str) -> TfError:
        known = ", ".join(self.frames()) or "none: the recording has no /tf or /tf_static"
        return TfError(f"frame '{frame}' is not in the TF tree (known frames: {known})")

    def _to_root(self, chain: list[str], upto: int, stamp_ns: int) -> Pose3:
        """T_{chain[upto]}_{chain[0]}."""
        pose = Pose3.identity()
        for k in range(upto):
            child = chain[k]
            pose = self._edges[child].at(stamp_ns, self.tolerance_ns, child).compose(pose)
        return pose

    def lookup(self, target: str, source: str, stamp_ns: int) -> Pose3:
        """``T_target_source`` at ``stamp_ns``: maps points in ``source`` to ``target``.

        Raises:
            TfError: a frame is unknown, the frames are not connected, or the stamp is out of range.
        """
        target, source = target.lstrip("/"), source.lstrip("/")
        if target == source:
            return Pose3.identity()
        ct, cs = self._chain(target), self._chain(source)
        common = next((f for f in cs if f in set(ct)), None)
        if common is None:
            self.require(target, source)
            raise TfError(f"frames '{target}' and '{source}' are not connected in the TF tree")
        T_common_source = self._to_root(cs, cs.index(common), stamp_ns)
        T_common_target = self._to_root(ct, ct.index(common), stamp_ns)
        return T_common_target.inverse().compose(T_common_source)

    def can_transform(self, target: str, source: str, stamp_ns: int | None = None) -> bool:
        """Whether :meth:`lookup` would succeed (at any time when ``stamp_ns`` is None: connectivity only)."""
        target, source = target.lstrip("/"), source.lstrip("/")
        if target == source:
            return True
        if stamp_ns is None:
            known = self.frames()
            if target not in known or source not in known:
                return False
            return self._chain(target)[-1] == self._chain(source)[-1]
        try:
            self.lookup(target, source, stamp_ns)
        except TfError:
            return False
        return True

    def require(self, target: str, source: str) -> None:
        """Raise :class:`TfError` (naming the missing frame) unless the two frames are connected."""
        target, source = target.lstrip("/"), source.lstrip("/")
        if target == source:
            return
        known = self.frames()
        for f in (target, source):
            if f not in known:
                raise self._unknown(f)
        rt, rs = self._chain(target)[-1], self._chain(source)[-1]
        if rt != rs:
            raise TfError(
                f"frames '{target}' and '{source}' are not connected in the TF tree "
                f"('{target}' has root '{rt}', '{source}' has root '{rs}')"
            )

    def is_static_path(self, target: str, source: str) -> bool:
        """True when every edge between the two frames is static (the lookup does not depend on time)."""
        target, source = target.lstrip("/"), source.lstrip("/")
        if target == source:
            return True
        ct, cs = self._chain(target), self._chain(source)
        common = next((f for f in cs if f in set(ct)), None)
        if common is None:
            return False
        path = cs[: cs.index(common)] + ct[: ct.index(common)]
        return all(self._edges[f].static for f in path)

    @classmethod
    def from_recording(cls, rec: Recording, *, tolerance_ns: int = 100_000_000) -> TfBuffer:
        """Read ``/tf`` and ``/tf_static`` (tf2_msgs/TFMessage, or Foxglove frame transforms) of a recording.

        ``/tf`` edges whose samples never change become static (see the module docstring).
        """
        from studio.io.decode import decode_tf

        buf = cls(tolerance_ns=tolerance_ns)
        topics = tf_topics(rec)
        if not topics:
            return buf
        static_topics = {t for t in topics if t.lstrip("/") == "tf_static"}
        for raw in rec.messages(topics):
            static = raw.topic in static_topics
            for parent, child, stamp, pose in decode_tf(rec.decode(raw)):
                buf.add(parent, child, stamp, pose, static=static)
        buf.make_constant_edges_static()
        return buf


def tf_topics(rec: Recording) -> list[str]:
    """Topics of ``rec`` that carry transforms (``/tf``, ``/tf_static`` or TF message types)."""
    out = []
    for name, info in rec.topics.items():
        if name.lstrip("/") in ("tf", "tf_static") or info.msgtype.endswith(
            ("TFMessage", "FrameTransform", "FrameTransforms")
        ):
            out.append(name)
    return sorted(out)
