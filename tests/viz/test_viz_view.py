"""``studio view``: clear one-line errors (exit 2), and a headless viewer screenshot per blueprint."""

from __future__ import annotations

import glob
import shutil
import sys
from pathlib import Path

import pytest
import viz_synth as vs

from studio.cli import main


@pytest.mark.parametrize(
    ("content", "message"),
    [
        (None, "no such run directory or .rrd file"),
        (b"", "not a readable Rerun recording"),
        (b"not an rrd at all, just some text" * 10, "not a readable Rerun recording"),
    ],
)
def test_missing_or_corrupt_rrd_exits_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], content: bytes | None, message: str
) -> None:
    path = tmp_path / "x.rrd"
    if content is not None:
        path.write_bytes(content)
    assert main(["view", str(path)]) == 2
    err = capsys.readouterr().err
    assert message in err
    assert err.count("\n") == 1
    assert "Traceback" not in err


def test_truncated_rrd_and_empty_run_dir(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    syn = vs.build(tmp_path, with_gt=False)
    vs.log_run(tmp_path / "recording.rrd", syn)
    data = (tmp_path / "recording.rrd").read_bytes()
    (tmp_path / "cut.rrd").write_bytes(data[: len(data) // 3])
    assert main(["view", str(tmp_path / "cut.rrd")]) == 2
    assert "not a readable Rerun recording" in capsys.readouterr().err
    (tmp_path / "run").mkdir()
    assert main(["view", str(tmp_path / "run")]) == 2
    assert "no recording.rrd" in capsys.readouterr().err


def test_a_screenshot_path_that_cannot_be_written_is_one_error_before_the_viewer_starts(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    syn = vs.build(tmp_path, with_gt=False)
    vs.log_run(tmp_path / "recording.rrd", syn)
    (tmp_path / "afile").write_text("x")
    for shot, message in (
        (tmp_path / "afile" / "x.png", "afile is not a folder"),
        (tmp_path, "is a directory"),
    ):
        assert main(["view", str(tmp_path / "recording.rrd"), "--screenshot", str(shot)]) == 2
        err = capsys.readouterr().err
        assert message in err
        assert err.count("\n") == 1


def test_unknown_blueprint_exits_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["view", str(tmp_path), "--blueprint", "nope"]) == 2
    assert "known: review, laser, calibration, compare" in capsys.readouterr().err


def _viewer_available() -> bool:
    exe = Path(sys.executable).parent / "rerun"
    return (exe.exists() or shutil.which("rerun") is not None) and bool(
        glob.glob("/usr/share/vulkan/icd.d/lvp_icd*.json")
        or glob.glob("/usr/share/vulkan/icd.d/nvidia*.json")
    )


@pytest.mark.viewer
@pytest.mark.slow
@pytest.mark.skipif(
    not _viewer_available(), reason="needs the rerun viewer and a Vulkan driver (mesa-vulkan-drivers)"
)
def test_headless_screenshot_every_blueprint(tmp_path: Path) -> None:
    from studio.viz.blueprints import BLUEPRINTS
    from studio.viz.viewer import screenshot

    syn = vs.build(tmp_path)
    vs.log_run(tmp_path / "recording.rrd", syn, ground_truth=syn.gt_path, faces_every=2)
    expected = {
        "review": {"panorama", "bird's eye (odom frame)", "face front", "counts"},
        "laser": {"bird's eye (odom frame)", "laser (base frame)", "counts"},
        "calibration": {"panorama: projected laser", "residuals (px)", "face back"},
        "compare": {
            "auto (tracks) vs manual (GT)",
            "per-frame FP / FN / ID switches",
            "disagreements (click to jump)",
        },
    }
    for name in BLUEPRINTS:
        png = tmp_path / f"{name}.png"
        res = screenshot(tmp_path, png, blueprint_name=name)
        assert res.errors() == [], res.errors()
        assert expected[name] <= {v[0] for v in res.views}, res.views
        assert {"frame", "time"} <= set(res.timelines)
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert png.stat().st_size > 20_000


@pytest.mark.parametrize(
    ("run_json", "name"),
    [
        ('{"image_size": null}', "laser"),  # no camera images: a laser-only rig or --sources laser
        ('{"image_size": [1920, 960]}', "review"),
        ("{}", "review"),
        ("not json", "review"),
        (None, "review"),  # an .rrd without its run directory
    ],
)
def test_a_run_without_images_opens_with_the_laser_blueprint(
    tmp_path: Path, run_json: str | None, name: str
) -> None:
    from studio.commands.view import default_blueprint

    if run_json is not None:
        (tmp_path / "run.json").write_text(run_json)
    assert default_blueprint(tmp_path / "recording.rrd") == name


def test_native_viewer_without_display_is_a_user_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    if not sys.platform.startswith("linux"):
        pytest.skip("the display check is for Linux")
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    syn = vs.build(tmp_path, with_gt=False)
    vs.log_run(tmp_path / "recording.rrd", syn)
    assert main(["view", str(tmp_path)]) == 2
    assert "no display" in capsys.readouterr().err
