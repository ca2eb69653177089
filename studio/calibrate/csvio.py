"""CSV files of calibration: correspondences ``x,y,z,u,v``, points ``x,y,z``, and projected pixels ``u,v``.

A header row is required (comma-separated; ``;`` or tab also work); column names are matched
case-insensitively after trimming spaces, extra columns are ignored, and blank lines and lines starting
with ``#`` are skipped. A missing ``z`` column means ``z = 0`` (the point's height is unknown). Error
messages name the file and its line numbers.
"""

from __future__ import annotations

import csv
import io
import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from studio.atomic import atomic_write_text
from studio.calibrate.extrinsics import CalibrationError

__all__ = [
    "CsvTable",
    "read_columns",
    "read_correspondences",
    "read_points",
    "write_uv",
]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class CsvTable:
    """Numeric columns read from a CSV file.

    Attributes:
        path: the file.
        values: ``(N, C)`` float64 in the order of the requested columns.
        lines: ``(N,)`` 1-based line numbers of the rows in the file.
    """

    path: Path
    values: FloatArray
    lines: tuple[int, ...]

    def labels(self) -> list[str]:
        """``"line K"`` for every row (for error messages)."""
        return [f"line {k}" for k in self.lines]


def _delimiter(text: str) -> str:
    """``,`` unless the header line uses ``;`` or tabs instead."""
    for line in text.splitlines():
        if line.strip() and not line.lstrip().startswith("#"):
            counts = {d: line.count(d) for d in (",", ";", "\t")}
            best = max(counts, key=lambda d: counts[d])
            return best if counts[best] > 0 else ","
    return ","


def read_columns(
    path: str | os.PathLike[str], columns: tuple[str, ...], *, optional: tuple[str, ...] = ()
) -> CsvTable:
    """Read named numeric columns of a CSV file with a header.

    Args:
        path: the CSV file.
        columns: required column names, in the order of the returned values.
        optional: names among ``columns`` that may be absent (filled with 0).

    Raises:
        CalibrationError: the file is missing or unreadable, has no header or a required column is
            missing, or a cell is not a number (naming the line and column).
    """
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8-sig")
    except FileNotFoundError:
        raise CalibrationError(f"file not found: {p}") from None
    except IsADirectoryError:
        raise CalibrationError(f"{p}: is a directory, expected a CSV file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise CalibrationError(f"cannot read {p}: {exc}") from None
    reader = csv.reader(io.StringIO(text), delimiter=_delimiter(text))
    header: list[str] | None = None
    index: dict[str, int] = {}
    rows: list[list[float]] = []
    lines: list[int] = []
    for cells in reader:
        lineno = reader.line_num
        if not cells or all(not c.strip() for c in cells) or cells[0].lstrip().startswith("#"):
            continue
        if header is None:
            header = [c.strip().lower() for c in cells]
            missing = [c for c in columns if c not in header and c not in optional]
            if missing:
                raise CalibrationError(
                    f"{p}: line {lineno}: the header needs columns {','.join(columns)}; missing "
                    f"{','.join(missing)} (found: {','.join(header) or 'nothing'})"
                )
            index = {c: header.index(c) for c in columns if c in header}
            continue
        row = []
        for c in columns:
            if c not in index:
                row.append(0.0)
                continue
            j = index[c]
            cell = cells[j].strip() if j < len(cells) else ""
            try:
                row.append(float(cell))
            except ValueError:
                what = f"'{cell}' is not a number" if cell else "is empty"
                raise CalibrationError(f"{p}: line {lineno}: column {c} {what}") from None
        rows.append(row)
        lines.append(lineno)
    if header is None:
        raise CalibrationError(f"{p}: empty file (expected a header row with {','.join(columns)})")
    values = np.asarray(rows, dtype=np.float64).reshape(-1, len(columns))
    return CsvTable(path=p, values=values, lines=tuple(lines))


def read_correspondences(path: str | os.PathLike[str]) -> tuple[FloatArray, FloatArray]:
    """Read an ``x,y,z,u,v`` correspondence file.

    Returns:
        ``xyz`` ``(N, 3)`` metres and ``uv`` ``(N, 2)`` px (not yet validated: see
        :func:`studio.calibrate.extrinsics.check_correspondences`).
    """
    t = read_columns(path, ("x", "y", "z", "u", "v"), optional=("z",))
    return t.values[:, :3].copy(), t.values[:, 3:].copy()


def read_points(path: str | os.PathLike[str]) -> FloatArray:
    """Read the ``x,y,z`` columns of a CSV file (``z`` optional, 0), ``(N, 3)`` metres.

    Raises:
        CalibrationError: unreadable file, missing column, a cell that is not a finite number.
    """
    t = read_columns(path, ("x", "y", "z"), optional=("z",))
    bad = ~np.isfinite(t.values).all(axis=1)
    if bad.any():
        where = ", ".join(f"line {t.lines[i]}" for i in np.flatnonzero(bad)[:8])
        raise CalibrationError(f"{t.path}: NaN or infinite coordinates at {where}")
    return t.values


def write_uv(path: str | os.PathLike[str], uv: ArrayLike) -> None:
    """Write ``u,v`` rows (px, 4 decimals; empty cells for points that do not project) atomically."""
    a = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
    out = ["u,v"]
    for u, v in a:
        out.append(f"{u:.4f},{v:.4f}" if math.isfinite(u) and math.isfinite(v) else ",")
    atomic_write_text(path, "\n".join(out) + "\n")
