"""CSV files as real users write them: what is read, and what is refused with the line named."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from studio.calibrate.csvio import read_correspondences, read_points
from studio.calibrate.extrinsics import CalibrationError, project_points
from studio.cli import main
from studio.geometry.se import Pose3

ROWS = [(1.0, 2.0, 0.1, 100.0, 200.0), (2.5, -3.0, 0.0, 3000.0, 1500.0)]


def _lines(fmt: str = "{},{},{},{},{}") -> list[str]:
    return [fmt.format(*r) for r in ROWS]


ACCEPTED = {
    "utf-8 BOM": "\ufeffx,y,z,u,v\n" + "\n".join(_lines()) + "\n",
    "CRLF": "x,y,z,u,v\r\n" + "\r\n".join(_lines()) + "\r\n",
    "spaces after commas": "x, y, z, u, v\n" + "\n".join(_lines("{}, {}, {}, {}, {}")) + "\n",
    "upper-case, spaced names": " X , Y ,Z,  U,V \n" + "\n".join(_lines()) + "\n",
    "extra columns before/after": "frame,x,y,z,u,v,score\n"
    + "\n".join(f"img_{i}.png,{a},{b},{c},{d},{e},0.9" for i, (a, b, c, d, e) in enumerate(ROWS))
    + "\n",
    "index column (pandas)": ",x,y,z,u,v\n"
    + "\n".join(f"{i},{a},{b},{c},{d},{e}" for i, (a, b, c, d, e) in enumerate(ROWS))
    + "\n",
    "comments, blank and trailing empty lines": "# from ball.py\nx,y,z,u,v\n# station 1\n\n"
    + "\n   \n".join(_lines())
    + "\n\n\n",
    "integers and scientific notation": "x,y,z,u,v\n1e0,2.0E+00,1e-1,100,200\n25e-1,-3,0,3000,1.5e3\n",
    "units in brackets": "x [m],y [m],z (m),u [px],v [px]\n" + "\n".join(_lines()) + "\n",
    "quoted cells": '"x","y","z","u","v"\n' + "\n".join(_lines('"{}","{}","{}","{}","{}"')) + "\n",
    "semicolons and decimal commas": "x;y;z;u;v\n1,0;2;0,1;100;200\n2,5;-3;0;3000;1500,0\n",
    "Excel sep line": "sep=;\r\nx;y;z;u;v\r\n1;2;0,1;100;200\r\n2,5;-3;0;3000;1500\r\n",
    "tabs": "x\ty\tz\tu\tv\n" + "\n".join(_lines("{}\t{}\t{}\t{}\t{}")) + "\n",
    "trailing delimiter": "x,y,z,u,v,\n" + "\n".join(s + "," for s in _lines()) + "\n",
    "repeated header (two files concatenated)": "x,y,z,u,v\n" + _lines()[0] + "\nx,y,z,u,v\n" + _lines()[1],
}


@pytest.mark.parametrize("kind", list(ACCEPTED))
def test_real_world_variants_are_read(kind: str, tmp_path: Path) -> None:
    p = tmp_path / "c.csv"
    p.write_bytes(ACCEPTED[kind].encode("utf-8"))
    xyz, uv = read_correspondences(p)
    np.testing.assert_allclose(np.c_[xyz, uv], ROWS)


def test_utf16_with_bom_and_latin1_comments(tmp_path: Path) -> None:
    text = "x\ty\tz\tu\tv\n" + "\n".join("\t".join(str(c) for c in r) for r in ROWS) + "\n"
    p = tmp_path / "u16.csv"
    p.write_bytes(text.encode("utf-16"))  # Excel "Unicode text"
    np.testing.assert_allclose(np.c_[read_correspondences(p)], ROWS)
    p.write_bytes(("# mesure à 1 m\nx,y,z,u,v\n" + "\n".join(_lines()) + "\n").encode("latin-1"))
    np.testing.assert_allclose(np.c_[read_correspondences(p)], ROWS)


REFUSED = {
    "no header": ("1,2,0.1,100,200\n2,3,0.1,110,210\n", "line 1 is numbers, not a header"),
    "header only": ("# nothing yet\nx,y,z,u,v\n\n", "no data rows after the header (line 2)"),
    "column twice": ("x,y,z,u,v,x\n1,2,0.1,100,200,5\n", "line 1: column x appears more than once"),
    "missing column": ("x,y,z,u\n1,2,0.1,100\n", "missing v"),
    "inline comment": ("x,y,z,u,v\n1,2,0.1,100,200\n1,2,0.1,100,200 # bad\n", "line 3: column v"),
    "underscore digits": ("x,y,z,u,v\n1_000,2,0.1,100,200\n", "line 2: column x '1_000' is not a number"),
    "unit in a cell": ("x,y,z,u,v\n1,2,0.1,100 px,200\n", "line 2: column u '100 px'"),
    "short row": ("x,y,z,u,v\n1,2,0.1,100,200\n1,2,0.1,100\n", "line 3: column v is empty"),
    "binary (xlsx)": ("PK\x03\x04\x00\x00\x00", "binary file"),
}


@pytest.mark.parametrize("kind", list(REFUSED))
def test_unreadable_variants_name_the_line(kind: str, tmp_path: Path) -> None:
    text, words = REFUSED[kind]
    p = tmp_path / "c.csv"
    p.write_bytes(text.encode("utf-8"))
    with pytest.raises(CalibrationError, match=re.escape(words)) as info:
        read_correspondences(p)
    assert "\n" not in str(info.value)
    assert str(p) in str(info.value)


def test_nan_and_inf_cells_are_read_then_refused_by_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    p = tmp_path / "c.csv"
    p.write_text("x,y,z\n1,2,nan\n3,4,0\n")
    with pytest.raises(CalibrationError, match="line 2"):
        read_points(p)
    # through the command: one line, exit 2, the CSV line named
    true = Pose3.from_xyz_rpy(0.1, 0.0, 1.0, 0.0, 0.0, 0.3)
    a = np.linspace(-3.0, 3.0, 10)
    xyz = np.stack([3 * np.cos(a), 3 * np.sin(a), np.linspace(0.0, 0.4, 10)], axis=1)
    uv = project_points(true, xyz, image_size=(3840, 1920))
    lines = ["X, Y, Z, U, V"] + [", ".join(f"{c:.6g}" for c in r) for r in np.c_[xyz, uv]]
    lines[4] = lines[4].rsplit(",", 1)[0] + ", inf"
    p.write_text("\r\n".join(lines) + "\r\n")
    argv = ["calibrate", "extrinsics", "--correspondences", str(p), "--image-size", "3840x1920"]
    assert main([*argv, "--out", str(tmp_path / "calib.yaml")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert "line 5" in err
    assert "NaN or infinite" in err
    assert not (tmp_path / "calib.yaml").exists()
