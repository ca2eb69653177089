"""``studio calibrate extrinsics|project``: outputs, round trip through calib.yaml / rig.yaml, user errors."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
import rerun as rr
import yaml

from studio.calibrate.csvio import read_correspondences, read_points
from studio.calibrate.extrinsics import cross_validate, project_points
from studio.calibrate.report import draw_report
from studio.cli import main
from studio.geometry.se import Pose3
from studio.io.rig import CameraConfig, LaserConfig, Rig, save_rig
from studio.viz.calibration import log_calibration

SIZE = (3840, 1920)
TRUE = Pose3.from_xyz_rpy(0.08, -0.03, 0.92, 0.01, -0.015, 0.6)
KEYS = "col_px_mean col_px_median col_px_p90 row_px_mean row_px_median ang_deg_mean n n_outliers".split()  # noqa: SIM905


def make_points(n: int = 40, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    r = rng.uniform(1.0, 6.0, n)
    a = rng.uniform(-math.pi, math.pi, n)
    xyz = np.stack([r * np.cos(a), r * np.sin(a), np.zeros(n)], axis=1)
    uv = project_points(TRUE, xyz, image_size=SIZE) + rng.normal(0.0, 0.7, (n, 2))
    uv[:, 0] %= SIZE[0]
    bad = np.array([3, 11, 25] if n >= 40 else [3] if n >= 20 else [], dtype=int)  # wrong pixels
    uv[bad, 0] = (uv[bad, 0] + 300.0) % SIZE[0]
    return xyz, uv, bad


def write_csv(path: Path, xyz: np.ndarray, uv: np.ndarray, *, header: str = "x,y,z,u,v,note") -> Path:
    lines = [header] + [f"{p[0]},{p[1]},{p[2]},{q[0]},{q[1]},ball" for p, q in zip(xyz, uv, strict=True)]
    path.write_text("\n".join(lines) + "\n")
    return path


def run_cli(*argv: str) -> int:
    return main(["calibrate", *argv])


def project_args(rig: object, points: object, out: object) -> list[str]:
    return [
        "project",
        "--rig",
        str(rig),
        "--points",
        str(points),
        "--image-size",
        "3840x1920",
        "--out",
        str(out),
    ]


def extrinsics_args(csv: Path, out: Path, *extra: str) -> list[str]:
    return [
        "extrinsics",
        "--correspondences",
        str(csv),
        "--image-size",
        "3840x1920",
        "--out",
        str(out),
        *extra,
    ]


def test_extrinsics_writes_calib_report_and_json(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    xyz, uv, _bad = make_points()
    csv = write_csv(tmp_path / "corr.csv", xyz, uv)
    out = tmp_path / "calib.yaml"
    assert run_cli(*extrinsics_args(csv, out, "--folds", "4", "--json", str(tmp_path / "m.json"))) == 0
    printed = capsys.readouterr().out
    assert "column (px)" in printed
    assert "row (px)" in printed
    assert "line 5" in printed  # row index 3 is on line 5 (header is line 1), listed as an outlier
    m = json.loads((tmp_path / "m.json").read_text())
    assert set(KEYS) <= set(m)
    assert m["n"] == 40
    assert m["n_outliers"] == 3
    assert m["folds"] == 4
    assert m["col_px_mean"] < 1.5
    assert m["col_px_median"] < 1.2
    calib = yaml.safe_load(out.read_text())
    pose = calib["camera"]["pose"]
    assert set(pose) == {"x", "y", "z", "roll", "pitch", "yaw"}
    assert abs(pose["yaw"] - 0.6) < 0.003
    assert abs(pose["z"] - 0.92) < 0.01
    c = calib["calibration"]
    assert c["n"] == 40
    assert c["n_outliers"] == 3
    assert c["image_size"] == [3840, 1920]
    assert c["z_constant"]
    assert c["cross_validation"]["col_px_mean"] == m["col_px_mean"]
    txt = (tmp_path / "calib_report.txt").read_text()
    assert "OUTLIER" in txt
    assert txt.count("\n") > 40
    img = cv2.imread(str(tmp_path / "calib_report.png"))
    assert img is not None
    assert img.shape[1] == 1600
    assert img.shape[0] > 800
    assert (tmp_path / "calib_report.rrd").stat().st_size > 1000
    assert not list(tmp_path.glob(".*tmp"))  # atomic writes leave no temporary files


def test_project_with_calib_and_with_rig(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    xyz, uv, _ = make_points()
    csv = write_csv(tmp_path / "corr.csv", xyz, uv)
    assert run_cli(*extrinsics_args(csv, tmp_path / "calib.yaml")) == 0
    pts = tmp_path / "pts.csv"
    pts.write_text("id,x,y,z\n" + "".join(f"{i},{p[0]},{p[1]},{p[2]}\n" for i, p in enumerate(xyz)))
    out = tmp_path / "uv.csv"
    assert run_cli(*project_args(str(tmp_path / "calib.yaml"), str(pts), str(out))) == 0
    got = np.loadtxt(out, delimiter=",", skiprows=1)
    calib = yaml.safe_load((tmp_path / "calib.yaml").read_text())
    expect = project_points(Pose3.from_xyz_rpy(**calib["camera"]["pose"]), xyz, image_size=SIZE)
    np.testing.assert_allclose(got, expect, atol=1e-3)
    assert np.median(np.abs(got - project_points(TRUE, xyz, image_size=SIZE))) < 1.0

    rig = Rig(base_frame="base_link", camera=CameraConfig("/cam", TRUE), lasers=(LaserConfig("/scan"),))
    save_rig(rig, tmp_path / "rig.yaml")
    assert run_cli(*project_args(str(tmp_path / "rig.yaml"), str(pts), str(out))) == 0
    got = np.loadtxt(out, delimiter=",", skiprows=1)
    np.testing.assert_allclose(got, project_points(TRUE, xyz, image_size=SIZE), atol=1e-3)

    # a rig.yaml with the calibration block pasted in is accepted too
    data = yaml.safe_load((tmp_path / "rig.yaml").read_text())
    data["calibration"] = calib["calibration"]
    (tmp_path / "rig2.yaml").write_text(yaml.safe_dump(data))
    assert run_cli(*project_args(str(tmp_path / "rig2.yaml"), str(pts), str(out))) == 0


def test_csv_reader_columns(tmp_path: Path) -> None:
    p = tmp_path / "c.csv"
    p.write_text("# comment\n U , v,X,y\n\n10,20,1,2\n11,21,3,4\n")
    xyz, uv = read_correspondences(p)
    np.testing.assert_array_equal(xyz, [[1, 2, 0], [3, 4, 0]])  # missing z → 0
    np.testing.assert_array_equal(uv, [[10, 20], [11, 21]])
    assert read_points(p).shape == (2, 3)
    p.write_text("x;y;z;u;v\n1;2;3;4;5\n")
    xyz, uv = read_correspondences(p)
    np.testing.assert_array_equal(np.c_[xyz, uv], [[1, 2, 3, 4, 5]])


def _rows(xyz: np.ndarray, uv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return xyz.copy(), uv.copy()


def _case(kind: str, tmp: Path) -> Path:
    xyz, uv, _ = make_points(n=12)
    if kind == "few":
        return write_csv(tmp / "c.csv", xyz[:5], uv[:5])
    if kind == "nan":
        uv[4, 1] = np.nan
    elif kind == "outside":
        uv[2, 0] = 3840.0
    elif kind == "collinear":
        s = np.linspace(1, 5, 12)
        xyz = np.stack([s, 2 * s, np.zeros(12)], axis=1)
        uv = project_points(TRUE, xyz, image_size=SIZE)
    elif kind == "duplicate":
        xyz[7], uv[7] = xyz[1], uv[1]
    elif kind == "missing column":
        return write_csv(tmp / "c.csv", xyz, uv, header="x,y,z,u,w,note")
    elif kind == "not a number":
        p = write_csv(tmp / "c.csv", xyz, uv)
        p.write_text(p.read_text().replace("\n", "\n1,2,3,abc,5,x\n", 1))
        return p
    elif kind == "empty":
        (tmp / "c.csv").write_text("")
        return tmp / "c.csv"
    elif kind == "missing file":
        return tmp / "nope.csv"
    return write_csv(tmp / "c.csv", xyz, uv)


ERRORS = {
    "few": "at least 6",
    "nan": "line 6",
    "outside": "outside",
    "collinear": "one line",
    "duplicate": "line 3, line 9",
    "missing column": "missing v",
    "not a number": "line 2: column u 'abc'",
    "empty": "empty",
    "missing file": "not found",
}


@pytest.mark.parametrize("kind", list(ERRORS))
def test_bad_correspondences_exit_2_with_one_line(
    kind: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    csv = _case(kind, tmp_path)
    out = tmp_path / "out" / "calib.yaml"
    assert run_cli(*extrinsics_args(csv, out, "--json", str(tmp_path / "out" / "m.json"))) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert err.startswith("studio calibrate: error:")
    assert ERRORS[kind] in err
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())


def test_subprocess_error_has_no_traceback(tmp_path: Path) -> None:
    xyz, uv, _ = make_points(n=12)
    uv[0, 1] = 5000.0
    csv = write_csv(tmp_path / "c.csv", xyz, uv)
    r = subprocess.run(
        [sys.executable, "-m", "studio.cli", *["calibrate", *extrinsics_args(csv, tmp_path / "k.yaml")]],
        capture_output=True,
        text=True,
        check=False,
    )
    assert r.returncode == 2, r.stderr
    assert "Traceback" not in r.stderr
    assert r.stderr.count("\n") == 1
    assert "line 2" in r.stderr
    assert not (tmp_path / "k.yaml").exists()


def test_project_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pts = tmp_path / "p.csv"
    pts.write_text("x,y,z\n1,2,0\n")
    rig = Rig(base_frame="base_link", camera=CameraConfig("/cam"), lasers=(LaserConfig("/scan"),))
    save_rig(rig, tmp_path / "rig.yaml")
    (tmp_path / "bad.yaml").write_text("camera: {pose: {x: 1, yaw: oops}}\n")
    (tmp_path / "none.yaml").write_text("lasers: []\n")
    cases = {
        "rig.yaml": "no camera pose",
        "bad.yaml": "camera.pose.yaw",
        "none.yaml": "no 'camera'",
        "missing.yaml": "not found",
    }
    for name, words in cases.items():
        args = [
            "project",
            "--rig",
            str(tmp_path / name),
            "--points",
            str(pts),
            "--image-size",
            "100x50",
            "--out",
            str(tmp_path / "uv.csv"),
        ]
        assert run_cli(*args) == 2, name
        err = capsys.readouterr().err
        assert words in err, err
        assert err.count("\n") == 1, err
    assert not (tmp_path / "uv.csv").exists()
    with pytest.raises(SystemExit):
        run_cli("project", "--rig", "x", "--points", "y", "--image-size", "0x5", "--out", "z")


def test_rerun_log_and_report_image(tmp_path: Path) -> None:
    xyz, uv, _bad = make_points(n=24)
    cv = cross_validate(xyz, uv, image_size=SIZE, folds=3)
    pano = np.full((SIZE[1], SIZE[0], 3), 60, np.uint8)
    img = draw_report(cv, uv, width=800, background=pano)
    assert img.shape == (400 + 160, 800, 3)
    red = (img[:400, :, 2] > 200) & (img[:400, :, 1] < 100)
    assert red.any()  # outliers drawn in red
    rec = rr.RecordingStream("studio")
    path = tmp_path / "c.rrd"
    rec.save(str(path))
    log_calibration(rec, cv, xyz, uv, panorama=pano, before=Pose3.from_xyz_rpy(z=1.0), face_size=64)
    rec.flush()
    rec.disconnect()
    entities = {}
    for chunk in rr.chunk.RrdReader(path).stream():
        entities.setdefault(chunk.entity_path, 0)
        entities[chunk.entity_path] += chunk.to_record_batch().num_rows
    for e in (
        "/camera/panorama",
        "/camera/panorama/scan/observed",
        "/camera/panorama/scan/projected",
        "/camera/panorama/scan/projected_before",
        "/camera/panorama/scan/residuals",
        "/camera/faces/front/scan/after",
        "/camera/faces/back/scan/before",
        "/world/odom/robot/calibration/points",
        "/world/odom/robot/sensors/camera",
    ):
        assert e in entities, e
    assert entities["/metrics/calibration/col_px"] >= 24  # one scalar per correspondence (+ style)


def test_bad_options_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    xyz, uv, _ = make_points(n=12)
    csv = write_csv(tmp_path / "c.csv", xyz, uv)
    assert run_cli(*extrinsics_args(csv, tmp_path / "k.yaml", "--folds", "1")) == 2
    assert "--folds" in capsys.readouterr().err
    assert run_cli(*extrinsics_args(csv, tmp_path)) == 2
    assert "is a directory" in capsys.readouterr().err
    assert not (tmp_path / "k.yaml").exists()
    # a non-2:1 size is allowed but warned about
    assert (
        run_cli(
            *extrinsics_args(csv, tmp_path / "k.yaml")[:-4],
            "--image-size",
            "3840x1921",
            "--out",
            str(tmp_path / "k.yaml"),
        )
        == 0
    )
    assert "not 2:1" in capsys.readouterr().out


def test_a_report_path_taken_by_a_folder_is_one_error_before_anything_is_written(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The calibration and the text report were written, then the PNG failed with a temporary file's name."""
    xyz, uv, _bad = make_points()
    csv = write_csv(tmp_path / "corr.csv", xyz, uv)
    (tmp_path / "calib_report.png").mkdir()
    assert run_cli(*extrinsics_args(csv, tmp_path / "calib.yaml")) == 2
    err = capsys.readouterr().err
    assert "calib_report.png: is a directory" in err
    assert err.count("\n") == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["calib_report.png", "corr.csv"]
