"""The default recording of ``studio demo``: a short ``moving`` simulation, generated on first use.

A panoramic recording is large (about 75 MB per minute), so the repository does not carry one; instead
the default is simulated deterministically (same scenario, duration and seed → the same messages and
ground truth) the first time it is needed and kept for later runs in ``default/`` under:

1. ``$STUDIO_RECORDINGS`` when set,
2. else the checkout's ``recordings/`` folder when it exists and is writable,
3. else ``~/.cache/studio/recordings``.

Delete that ``default/`` folder to regenerate it (it is also regenerated when its length does not match, or
when it was made by another version of the simulator: ``default/sim_version``).
"""

from __future__ import annotations

import math
import os
from pathlib import Path

from studio.sim.base import SimRig
from studio.sim.simulate import OUTPUT_FILES, SIM_VERSION, Progress, simulate

__all__ = ["DEFAULT_RECORDING", "default_recording", "recordings_root"]

DEFAULT_RECORDING: tuple[str, float, int] = ("moving", 20.0, 0)
"""Scenario, duration (s) and seed of the default recording."""


def recordings_root() -> Path:
    """Where generated recordings are kept (see the module docstring)."""
    env = os.environ.get("STUDIO_RECORDINGS")
    if env:
        return Path(env).expanduser()
    checkout = Path(__file__).resolve().parents[2] / "recordings"
    if checkout.is_dir() and os.access(checkout, os.W_OK):
        return checkout
    return Path.home() / ".cache" / "studio" / "recordings"


def default_recording(*, root: Path | None = None, progress: Progress | None = None) -> Path:
    """The directory of the default recording, simulating it first if it is not there yet.

    Args:
        root: folder to keep it in (default :func:`recordings_root`).
        progress: ``progress(done, total)`` callback while simulating.

    Returns:
        A directory with ``recording.mcap``, ``rig.yaml``, ``ground_truth.yaml``, ``ground_truth.jsonl``.
    """
    sc, sec, seed = DEFAULT_RECORDING
    out = (root or recordings_root()) / "default"
    if _complete(out, sec):
        return out
    (out / "sim_version").unlink(missing_ok=True)  # simulate() writes only into its own files' folder
    simulate(sc, out=out, seconds=sec, seed=seed, progress=progress)
    (out / "sim_version").write_text(f"{SIM_VERSION}\n", encoding="utf-8")
    return out


def _complete(out: Path, seconds: float) -> bool:
    """All output files are there, made by this simulator version, and the ground truth has one frame per
    image of ``seconds``."""
    if not all((out / name).is_file() for name in OUTPUT_FILES):
        return False
    try:
        if (out / "sim_version").read_text(encoding="utf-8").strip() != str(SIM_VERSION):
            return False
    except OSError:
        return False
    rig = SimRig()
    expected = math.floor((seconds - rig.camera_offset_s) * rig.camera_rate_hz + 1e-9) + 1
    try:
        with open(out / "ground_truth.jsonl", encoding="utf-8") as f:
            return sum(1 for line in f if line.strip()) == expected
    except OSError:
        return False
