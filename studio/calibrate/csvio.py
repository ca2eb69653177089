"""CSV files of calibration: correspondences ``x,y,z,u,v``, points ``x,y,z``, and projected pixels ``u,v``.

What a real user's file may look like, and what is accepted:

* a header row is required; column names are matched case-insensitively after trimming spaces and
  quotes, and a unit in brackets is ignored (``" X"``, ``"U"``, ``"x [m]"``, ``"u (px)"`` all work);
  extra columns anywhere (an index column, a confidence, a file name) are ignored;
* the delimiter is ``,`` unless the header uses ``;`` or tabs (an Excel ``sep=;`` first line is
  honoured); with ``;`` or tab delimiters a decimal comma (``1,25``) is read as ``1.25``;
* UTF-8 with or without a BOM, UTF-16 with a BOM (Excel "Unicode text"), CRLF or LF line ends, spaces
  around cells, quoted cells, integers and scientific notation (``1e-3``, ``2.5E+01``);
* blank lines and lines starting with ``#`` are skipped, and so is a repeat of the header row (two
  files concatenated);
* a missing ``z`` column means ``z = 0`` (the point's height is unknown).

Refused, with the file and the line named: no header row (the first line is numbers), a required
column missing or named twice, a cell that is not a plain number (``1_000``, ``12 px``, an inline
``# comment``, an empty cell), a binary file (e.g. an ``.xlsx``), a file with a header but no rows.
``nan``/``inf`` cells are read as such and refused by the correspondence checks, which name the lines.
"""

from __future__ import annotations

import csv
import io
import math
import os
import re
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

_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")
_SPECIAL = re.compile(r"[+-]?(?:nan|inf|infinity)", re.IGNORECASE)
_DECIMAL_COMMA = re.compile(r"[+-]?\d+,\d+(?:[eE][+-]?\d+)?")
_UNIT = re.compile(r"\s*[\[(][^\])]*[\])]\s*$")


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


def _decode(p: Path) -> str:
    try:
        raw = p.read_bytes()
    except FileNotFoundError:
        raise CalibrationError(f"file not found: {p}") from None
    except IsADirectoryError:
        raise CalibrationError(f"{p}: is a directory, expected a CSV file") from None
    except OSError as exc:
        raise CalibrationError(f"cannot read {p}: {exc.strerror or exc}") from None
    if raw.startswith((b"\xff\xfe", b"\xfe\xff")):
        try:
            return raw.decode("utf-16")
        except UnicodeDecodeError:
            raise CalibrationError(f"{p}: not valid UTF-16 text") from None
    if b"\x00" in raw[:4096]:
        raise CalibrationError(
            f"{p}: a binary file, not CSV text (an Excel workbook? save it as 'CSV UTF-8')"
        )
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        return raw.decode("latin-1")  # numbers and column names are ASCII; only comments may differ


def _sep_line(line: str) -> str | None:
    """The delimiter of an Excel ``sep=X`` line, else None."""
    s = line.strip().strip('"')
    if s.lower().startswith("sep=") and len(s) == 5:
        return s[4]
    return None


def _delimiter(text: str) -> str:
    """``,`` unless the header line uses ``;`` or tabs instead (or a ``sep=`` line says so)."""
    for line in text.splitlines():
        if line.strip() and not line.lstrip().startswith("#"):
            sep = _sep_line(line)
            if sep is not None:
                return sep
            counts = {d: line.count(d) for d in (",", ";", "\t")}
            best = max(counts, key=lambda d: counts[d])
            return best if counts[best] > 0 else ","
    return ","


def _name(cell: str) -> str:
    return _UNIT.sub("", cell.strip().strip('"').strip()).strip().lower()


def _number(cell: str, decimal_comma: bool) -> float | None:
    s = cell.strip()
    if decimal_comma and _DECIMAL_COMMA.fullmatch(s):
        s = s.replace(",", ".")
    if _NUMBER.fullmatch(s) or _SPECIAL.fullmatch(s):
        return float(s)
    return None


def read_columns(
    path: str | os.PathLike[str], columns: tuple[str, ...], *, optional: tuple[str, ...] = ()
) -> CsvTable:
    """Read named numeric columns of a CSV file with a header (the formats of the module docstring).

    Args:
        path: the CSV file.
        columns: required column names, in the order of the returned values.
        optional: names among ``columns`` that may be absent (filled with 0).

    Raises:
        CalibrationError: the file is missing, unreadable or binary, has no header, a required column is
            missing or named twice, a cell is not a number, or there are no data rows (naming the line).
    """
    p = Path(path)
    text = _decode(p)
    delim = _delimiter(text)
    decimal_comma = delim != ","
    reader = csv.reader(io.StringIO(text, newline=""), delimiter=delim, skipinitialspace=True)
    header: list[str] | None = None
    header_line = 0
    index: dict[str, int] = {}
    rows: list[list[float]] = []
    lines: list[int] = []
    want = ",".join(columns)
    for cells in reader:
        lineno = reader.line_num
        if not cells or all(not c.strip() for c in cells) or cells[0].lstrip().startswith("#"):
            continue
        if header is None and len(cells) <= 2 and _sep_line(delim.join(cells)) is not None:
            continue
        names = [_name(c) for c in cells]
        if header is None:
            if all(_number(c, decimal_comma) is not None for c in cells if c.strip()):
                raise CalibrationError(
                    f"{p}: line {lineno} is numbers, not a header: the file needs a first row naming "
                    f"the columns ({want})"
                )
            header, header_line = names, lineno
            missing = [c for c in columns if c not in header and c not in optional]
            if missing:
                raise CalibrationError(
                    f"{p}: line {lineno}: the header needs columns {want}; missing "
                    f"{','.join(missing)} (found: {','.join(header) or 'nothing'})"
                )
            twice = [c for c in columns if header.count(c) > 1]
            if twice:
                raise CalibrationError(
                    f"{p}: line {lineno}: column {','.join(twice)} appears more than once in the header"
                )
            index = {c: header.index(c) for c in columns if c in header}
            continue
        if names == header:
            continue  # a repeated header (concatenated files)
        row = []
        for c in columns:
            if c not in index:
                row.append(0.0)
                continue
            j = index[c]
            cell = cells[j].strip() if j < len(cells) else ""
            value = _number(cell, decimal_comma)
            if value is None:
                what = f"'{cell}' is not a number" if cell else "is empty"
                raise CalibrationError(f"{p}: line {lineno}: column {c} {what}")
            row.append(value)
        rows.append(row)
        lines.append(lineno)
    if header is None:
        raise CalibrationError(f"{p}: empty file (expected a header row with {want})")
    if not rows:
        raise CalibrationError(f"{p}: no data rows after the header (line {header_line})")
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
