"""Viewer layouts of a studio recording, built in code: ``review``, ``calibration`` and ``compare``.

``python -m studio.viz.blueprints [--check] [DIR]`` writes them to ``blueprints/<name>.rbl`` (the default
directory is the repository's ``blueprints/``). Rerun writes a fresh recording id, row ids and log times
into every ``.rbl``, so the files are not byte-reproducible; views and containers get stable ids here
(uuid5 of the blueprint name and their place in the tree) and :func:`describe` reads a file back into a
canonical description (entity paths and component values, without those volatile columns). The generator
rewrites a file only when its description changed, and ``--check`` (and the test) fail when a committed
file differs from the code.
"""

from __future__ import annotations

import argparse
import json
import sys
import uuid
from collections.abc import Callable
from pathlib import Path
from typing import Any

import rerun as rr
import rerun.blueprint as rrb

from studio.viz import paths as ep

__all__ = [
    "BLUEPRINTS",
    "blueprint",
    "calibration_blueprint",
    "compare_blueprint",
    "describe",
    "main",
    "review_blueprint",
    "write_blueprints",
]

_NAMESPACE = uuid.UUID("5f0c8a4e-2b7d-4c39-9a61-3d1e7b2c9f10")


def _stable_ids(name: str, node: Any, where: str = "root") -> Any:
    """Give every container and view of a blueprint tree an id that depends only on its place."""
    node.id = uuid.uuid5(_NAMESPACE, f"{name}/{where}")
    for k, child in enumerate(getattr(node, "contents", ()) if isinstance(node, rrb.Container) else ()):
        _stable_ids(name, child, f"{where}/{k}")
    return node


def _faces(contents_extra: tuple[str, ...] = ()) -> list[rrb.View]:
    return [
        rrb.Spatial2DView(
            origin=f"{ep.FACES}/{n}", name=f"face {n}", contents=["$origin/**", *contents_extra]
        )
        for n in ep.FACE_NAMES
    ]


def _birds_eye(name: str, contents: list[str], *, origin: str = ep.WORLD) -> rrb.Spatial3DView:
    return rrb.Spatial3DView(
        origin=origin,
        name=name,
        contents=contents,
        eye_controls=rrb.EyeControls3D(
            kind=rrb.Eye3DKind.Orbital,
            position=(-6.0, 0.0, 14.0),
            look_target=(2.0, 0.0, 0.0),
            eye_up=(0.0, 0.0, 1.0),
        ),
    )


def _panorama(name: str, contents: list[str]) -> rrb.Spatial2DView:
    return rrb.Spatial2DView(origin=ep.PANORAMA, name=name, contents=contents)


def _metrics() -> rrb.Tabs:
    return rrb.Tabs(
        rrb.TimeSeriesView(origin=f"{ep.METRICS}/counts", name="counts"),
        rrb.TimeSeriesView(origin=f"{ep.METRICS}/eval", name="metrics vs ground truth"),
        rrb.TextLogView(origin=ep.REVIEW, name="identities to check (click to jump)"),
        name="metrics",
    )


def _blueprint(name: str, root: rrb.Container) -> rrb.Blueprint:
    """The layout ``root`` with stable ids, the time panel collapsed on the frame timeline."""
    return rrb.Blueprint(
        _stable_ids(name, root),
        rrb.TimePanel(state="collapsed", timeline=ep.TIMELINE_FRAME),
        collapse_panels=True,
    )


def review_blueprint() -> rrb.Blueprint:
    """Panorama with boxes and projected scan; bird's-eye 3D view; cube faces; metrics plots and the
    identities to check (review points)."""
    root = rrb.Vertical(
        rrb.Horizontal(
            _panorama("panorama", ["$origin/**", f"- {ep.PANORAMA}/ground_truth"]),
            _birds_eye("bird's eye (odom frame)", ["$origin/**", f"- {ep.ODOM}/errors"]),
            column_shares=[2.2, 1.0],
        ),
        rrb.Horizontal(
            rrb.Grid(*_faces(), grid_columns=4, name="cube faces"),
            _metrics(),
            column_shares=[2.2, 1.0],
        ),
        row_shares=[2.0, 1.0],
    )
    return _blueprint("review", root)


def laser_blueprint() -> rrb.Blueprint:
    """A run without camera images (a laser-only rig): the bird's-eye view large, the scans around the
    robot in its own frame, metrics plots — none of the review's empty panorama and face views."""
    root = rrb.Horizontal(
        _birds_eye("bird's eye (odom frame)", ["$origin/**", f"- {ep.ODOM}/errors"]),
        rrb.Vertical(
            _birds_eye("laser (base frame)", ["$origin/**"], origin=ep.ROBOT),
            _metrics(),
            row_shares=[1.2, 1.0],
        ),
        column_shares=[2.0, 1.0],
    )
    return _blueprint("laser", root)


def calibration_blueprint() -> rrb.Blueprint:
    """Scan points and laser detections projected over the panorama and the faces; residual plots."""
    pano = ["$origin", "$origin/scan/**", "$origin/laser_people", "$origin/boxes"]
    root = rrb.Vertical(
        _panorama("panorama: projected laser", pano),
        rrb.Grid(*_faces(), grid_columns=4, name="cube faces"),
        rrb.Horizontal(
            rrb.TimeSeriesView(origin=ep.CALIBRATION, name="residuals (px)"),
            _birds_eye("laser (base frame)", ["$origin/**"], origin=ep.ROBOT),
            column_shares=[2.0, 1.0],
        ),
        row_shares=[2.0, 1.2, 1.0],
    )
    return _blueprint("calibration", root)


def compare_blueprint() -> rrb.Blueprint:
    """Automatic labels vs ground truth in one bird's-eye view and on the panorama; error plot; events."""
    root = rrb.Vertical(
        rrb.Horizontal(
            _birds_eye(
                "auto (tracks) vs manual (GT)",
                [
                    f"{ep.ODOM}/tracks",
                    f"{ep.ODOM}/trails",
                    f"{ep.ODOM}/ground_truth",
                    f"{ep.ODOM}/errors",
                    f"{ep.ROBOT}",
                    f"{ep.ROBOT}/footprint",
                    f"{ep.ROBOT}/scan/**",
                ],
            ),
            _panorama("panorama: tracks vs GT", ["$origin", "$origin/tracks", "$origin/ground_truth"]),
            column_shares=[1.0, 2.0],
        ),
        rrb.Horizontal(
            rrb.TimeSeriesView(
                origin=f"{ep.METRICS}/eval",
                name="per-frame FP / FN / ID switches",
                contents=["$origin/fp", "$origin/fn", "$origin/id_switches"],
            ),
            rrb.TimeSeriesView(
                origin=f"{ep.METRICS}/eval",
                name="position error (m), running F1 / MOTA",
                contents=["$origin/error_m", "$origin/running_f1", "$origin/running_mota"],
            ),
            rrb.TextLogView(origin=ep.COMPARE_EVENTS, name="disagreements (click to jump)"),
            rrb.TextDocumentView(origin=ep.COMPARE_SUMMARY, name="summary"),
            column_shares=[1.2, 1.2, 1.5, 1.0],
        ),
        row_shares=[2.0, 1.0],
    )
    return _blueprint("compare", root)


BLUEPRINTS: dict[str, Callable[[], rrb.Blueprint]] = {
    "review": review_blueprint,
    "laser": laser_blueprint,
    "calibration": calibration_blueprint,
    "compare": compare_blueprint,
}


def blueprint(name: str) -> rrb.Blueprint:
    """The blueprint called ``name``.

    Raises:
        StudioError: unknown name (the message lists the known ones).
    """
    from studio.errors import StudioError

    if name not in BLUEPRINTS:
        raise StudioError(f"unknown blueprint '{name}' (known: {', '.join(BLUEPRINTS)})")
    return BLUEPRINTS[name]()


_VOLATILE = ("rerun.controls.RowId", "log_time", "log_tick", "blueprint")


def describe(path: str | Path) -> list[dict[str, Any]]:
    """Canonical description of a ``.rbl`` file: one entry per logged row, sorted, without ids and times.

    Each entry is ``{"entity": path, "static": bool, "components": {name: value}}``; the application id is
    included as the first entry.
    """
    reader = rr.chunk.RrdReader(str(path))
    stores = reader.blueprints()
    if not stores:
        raise ValueError(f"{path}: no blueprint in the file")
    rows: list[dict[str, Any]] = []
    for chunk in reader.stream(store=stores[0]):
        rb = chunk.to_record_batch()
        cols = [f.name for f in rb.schema if f.name not in _VOLATILE]
        data = {c: rb.column(c).to_pylist() for c in cols}
        for r in range(rb.num_rows):
            comps = {c: _plain(data[c][r]) for c in cols if data[c][r] is not None}
            rows.append({"entity": chunk.entity_path, "static": chunk.is_static, "components": comps})
    rows.sort(key=lambda e: json.dumps(e, sort_keys=True))
    return [{"application_id": stores[0].application_id}, *rows]


def _plain(v: Any) -> Any:
    if isinstance(v, bytes):
        return v.hex()
    if isinstance(v, list):
        return [_plain(x) for x in v]
    if isinstance(v, dict):
        return {k: _plain(x) for k, x in v.items()}
    return v


def write_blueprints(out_dir: str | Path, *, only_if_changed: bool = True) -> list[Path]:
    """Write every blueprint to ``out_dir/<name>.rbl``; returns the files written (changed ones only when
    ``only_if_changed``)."""
    import tempfile

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    with tempfile.TemporaryDirectory() as tmp:
        for name, make in BLUEPRINTS.items():
            fresh = Path(tmp) / f"{name}.rbl"
            make().save(ep.APP_ID, fresh)
            target = out / f"{name}.rbl"
            if only_if_changed and target.exists() and describe(target) == describe(fresh):
                continue
            target.write_bytes(fresh.read_bytes())
            written.append(target)
    return written


def default_dir() -> Path:
    """The repository's ``blueprints/`` directory (next to the ``studio`` package)."""
    return Path(__file__).resolve().parents[2] / "blueprints"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m studio.viz.blueprints", description=__doc__.split("\n")[0]
    )
    parser.add_argument(
        "out", nargs="?", default=None, help="output directory (default: the repo's blueprints/)"
    )
    parser.add_argument("--check", action="store_true", help="only check that the files match the code")
    args = parser.parse_args(argv)
    out = Path(args.out) if args.out else default_dir()
    if args.check:
        import tempfile

        with tempfile.TemporaryDirectory() as tmp:
            write_blueprints(tmp, only_if_changed=False)
            stale = [
                n
                for n in BLUEPRINTS
                if not (out / f"{n}.rbl").exists()
                or describe(out / f"{n}.rbl") != describe(Path(tmp) / f"{n}.rbl")
            ]
        for n in stale:
            print(f"{out / n}.rbl is out of date (run python -m studio.viz.blueprints)")
        return 1 if stale else 0
    for path in write_blueprints(out):
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
