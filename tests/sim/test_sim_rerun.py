"""Rerun's own MCAP importer opens the simulated bag: images as EncodedImage, TF as Transform3D."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from studio.sim import SimResult


def _rerun() -> str:
    exe = Path(sys.executable).with_name("rerun")
    found = str(exe) if exe.exists() else shutil.which("rerun")
    if found is None:
        pytest.skip("the rerun command is not installed")
    return found


def test_rerun_mcap_importer_reads_the_recording(moving_sim: SimResult, tmp_path: Path) -> None:
    rerun = _rerun()
    rrd = tmp_path / "sim.rrd"
    subprocess.run(
        [rerun, "mcap", "convert", str(moving_sim.recording), "-o", str(rrd)],
        check=True,
        capture_output=True,
        timeout=300,
    )
    text = subprocess.run(
        [rerun, "rrd", "print", str(rrd)], check=True, capture_output=True, text=True, timeout=300
    ).stdout
    lines = [ln for ln in text.splitlines() if "data columns" in ln]
    assert any("/theta_camera/image/compressed" in ln and "EncodedImage:blob" in ln for ln in lines)
    assert any(ln.split(" - ")[1] == "/tf" and "Transform3D" in ln for ln in lines if " - " in ln)
    assert any("/tf_static" in ln and "Transform3D" in ln for ln in lines)
    for topic in ("/scan_front", "/scan_rear", "/odom"):
        assert any(f" - {topic} - " in ln for ln in lines), topic
