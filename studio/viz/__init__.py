"""The Rerun side of studio: the only package that imports ``rerun``.

* :class:`studio.viz.log.RunLogger` writes ``RUN/recording.rrd`` while ``studio label`` runs;
* :mod:`studio.viz.paths` documents the entity tree and timelines;
* :mod:`studio.viz.series` / :mod:`studio.viz.compare` log whole-run series and the ground-truth comparison;
* :mod:`studio.viz.blueprints` builds the ``review``, ``calibration`` and ``compare`` layouts;
* :mod:`studio.viz.viewer` opens a recording in the native viewer, the web viewer or a headless one.
"""

from __future__ import annotations

__all__ = ["RunLogger"]


def __getattr__(name: str) -> object:
    if name == "RunLogger":
        from studio.viz.log import RunLogger

        return RunLogger
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
