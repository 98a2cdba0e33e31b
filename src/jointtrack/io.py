"""Reading detections and writing tracks and metrics (CSV, Parquet, JSON).

Detections file format
----------------------
One row per detection, as CSV (``.csv``, optionally gzip-compressed
``.csv.gz``) or Parquet (``.parquet`` / ``.pq``). A detection is either a
measured position (``x, y[, z]``):

=========  ========  ==========================================================
column     required  meaning
=========  ========  ==========================================================
``time``   yes       scan time stamp (any unit, e.g. seconds); finite
``x``      yes       position coordinate (any unit, e.g. metres); finite
``y``      yes       position coordinate; finite
``z``      no        third coordinate; its presence makes the detections 3-D
``sensor`` no        integer sensor id (e.g. for several radars)
=========  ========  ==========================================================

or a range–bearing measurement of a 2-D sensor (``range, bearing``; track it
with ``TrackerConfig(sensor="range-bearing", sensor_position=…)``):

===========  ========  ========================================================
column       required  meaning
===========  ========  ========================================================
``time``     yes       scan time stamp; finite
``range``    yes       distance from the sensor (e.g. metres); finite, ≥ 0
``bearing``  yes       angle in **radians**, anticlockwise from the +x axis;
                       finite, within [−2π, 2π] (larger values are taken for
                       degrees and rejected); not wrapped on reading
``sensor``   no        integer sensor id
===========  ========  ========================================================

The columns decide the kind (:attr:`Detections.kind`: ``"position"`` or
``"range-bearing"``); a file with columns of both kinds (``x``/``y``/``z``
and ``range``/``bearing``) or of neither is an error.

* CSV: comma-separated, the first non-blank line is the header; column names
  are matched case-insensitively, surrounding spaces ignored; blank lines are
  skipped; other columns (``snr``, ``amplitude``, …) are ignored. Parquet:
  the same column names; numeric column types (or strings holding numbers).
* Rows are in time order: ``time`` must be non-decreasing from row to row.
  Consecutive rows with the *same* time value form one scan; a scan with no
  detection cannot be represented (it has no row).
* Errors: every problem raises :class:`DetectionFileError` (a
  :class:`ValueError`) with a one-line message naming the file and, where
  there is one, the row — ``line L (data row R)`` for CSV (L the physical
  line, R the 1-based row after the header), ``data row R`` for Parquet —
  and the column: missing or unreadable file, unknown extension, missing
  required columns (all listed), a non-numeric, empty, NaN or infinite value,
  a non-integer sensor id, a row with the wrong number of fields, a time
  earlier than the row before it, position and range–bearing columns together
  (or neither), a negative range or a bearing outside [−2π, 2π].

Examples::

    time,x,y,sensor
    0.0,12.5,-3.0,1
    0.0,250.1,40.2,1
    1.0,13.4,-2.1,1

    time,range,bearing
    0.0,1250.0,0.7854
    0.0,980.5,-2.9671
    1.0,1243.2,0.7860

Tracks file format (:func:`write_tracks`, :func:`read_tracks`)
---------------------------------------------------------------
Columns ``time, track_id, x, y[, z], vx, vy[, vz]`` (``z`` and ``vz`` together)
followed by any extra numeric columns the caller supplies, e.g. covariance
entries (``P_x_x``, ``P_x_vx``, …) or an existence probability
(``existence``). CSV floats are written with ``repr`` (shortest round-trip),
so a CSV round trip is exact.

Metrics (:func:`write_metrics`): a JSON object; numpy scalars and arrays,
dataclasses, tuples and paths are converted; NaN and ±inf become ``null``.
"""

from __future__ import annotations

import csv
import dataclasses
import gzip
import io as _io
import json
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = [
    "DataFileError",
    "DetectionFileError",
    "Detections",
    "KINDS",
    "TrackFileError",
    "read_detections",
    "read_tracks",
    "write_detections",
    "write_metrics",
    "write_tracks",
]

#: the kinds of :class:`Detections` (:attr:`Detections.kind`)
KINDS = ("position", "range-bearing")
_POS_COLUMNS = ("x", "y", "z")
_RB_COLUMNS = ("range", "bearing")

_CSV_SUFFIXES = (".csv", ".csv.gz")
_PARQUET_SUFFIXES = (".parquet", ".pq")


# ----------------------------------------------------------------------------- errors


class DataFileError(ValueError):
    """A data file that cannot be used; the message is one line naming file and row.

    Attributes: ``path``, ``reason`` and, when known, ``row`` (1-based data
    row), ``line`` (1-based physical line, CSV only) and ``column``.
    """

    def __init__(
        self,
        path,
        reason: str,
        *,
        row: int | None = None,
        line: int | None = None,
        column: str | None = None,
    ):
        self.path = str(path)
        self.reason = reason
        self.row = row
        self.line = line
        self.column = column
        where = []
        if line is not None and row is not None:
            where.append(f"line {line} (data row {row})")
        elif row is not None:
            where.append(f"data row {row}")
        elif line is not None:
            where.append(f"line {line}")
        if column is not None:
            where.append(f"column '{column}'")
        prefix = ", ".join([self.path, *where])
        super().__init__(f"{prefix}: {reason}")


class DetectionFileError(DataFileError):
    """Raised by :func:`read_detections` for a bad detections file."""


class TrackFileError(DataFileError):
    """Raised by :func:`read_tracks` for a bad tracks file."""


# ----------------------------------------------------------------------------- Detections


@dataclass(frozen=True, eq=False)
class Detections:
    """Detections grouped into scans.

    Attributes
    ----------
    times : (K,) float64, strictly increasing scan times.
    scans : tuple of K float64 arrays, ``scans[k]`` of shape ``(M_k, dim)`` —
        the detections at ``times[k]`` (``M_k`` may be 0): positions, or
        ``[r, θ]`` rows (range, bearing in radians) when ``kind`` is
        ``"range-bearing"``.
    sensors : tuple of K int64 arrays ``(M_k,)`` with the sensor id of each
        detection, or ``None`` when there is no sensor information.
    dim : columns of a detection: the spatial dimension for positions (2 or 3
        from files; any ≥ 1 when built directly), 2 for range–bearing.
    source : the file the detections were read from, if any.
    kind : ``"position"`` (default) or ``"range-bearing"`` (ranges ≥ 0,
        bearings within [−2π, 2π]).

    ``len(d)`` is K; iterating yields ``(time, z)`` pairs; ``d[k]`` is
    ``(times[k], scans[k])``.
    """

    times: np.ndarray
    scans: tuple
    sensors: tuple | None = None
    dim: int = 2
    source: str | None = None
    kind: str = "position"

    def __post_init__(self):
        times = np.asarray(self.times, dtype=np.float64)
        if times.ndim != 1:
            raise ValueError(f"times must be 1-D, got shape {times.shape}")
        if not np.all(np.isfinite(times)):
            raise ValueError("times must be finite")
        if times.size > 1 and np.any(np.diff(times) <= 0):
            k = int(np.flatnonzero(np.diff(times) <= 0)[0]) + 1
            raise ValueError(
                f"scan times must be strictly increasing: times[{k}] = {times[k]} "
                f"<= times[{k - 1}] = {times[k - 1]}"
            )
        if isinstance(self.dim, bool) or int(self.dim) != self.dim or self.dim < 1:
            raise ValueError(f"dim must be a positive integer, got {self.dim!r}")
        dim = int(self.dim)
        if self.kind not in KINDS:
            raise ValueError(f"kind must be one of {', '.join(KINDS)}, got {self.kind!r}")
        if self.kind == "range-bearing" and dim != 2:
            raise ValueError(f"range-bearing detections have dim 2 (range, bearing), got {dim}")
        scans = tuple(self.scans)
        if len(scans) != times.size:
            raise ValueError(f"{times.size} scan times but {len(scans)} scans")
        fixed = []
        for k, z in enumerate(scans):
            z = np.asarray(z, dtype=np.float64)
            if z.size == 0:
                z = z.reshape(0, dim)
            if z.ndim != 2 or z.shape[1] != dim:
                raise ValueError(f"scans[{k}] must have shape (M, {dim}), got {z.shape}")
            if not np.all(np.isfinite(z)):
                raise ValueError(f"scans[{k}] has a non-finite coordinate")
            if self.kind == "range-bearing" and np.any(z[:, 0] < 0):
                raise ValueError(f"scans[{k}] has a negative range")
            if self.kind == "range-bearing" and np.any(np.abs(z[:, 1]) > 2 * np.pi):
                raise ValueError(f"scans[{k}] has a bearing outside [-2π, 2π] (radians expected)")
            fixed.append(z)
        sensors = self.sensors
        if sensors is not None:
            sensors = tuple(sensors)
            if len(sensors) != len(fixed):
                raise ValueError(f"{len(fixed)} scans but {len(sensors)} sensor arrays")
            fs = []
            for k, (s, z) in enumerate(zip(sensors, fixed, strict=True)):
                s = np.asarray(s)
                if s.size == 0:
                    s = s.reshape(0).astype(np.int64)
                if s.shape != (z.shape[0],):
                    raise ValueError(f"sensors[{k}] must have shape ({z.shape[0]},), got {s.shape}")
                if not np.issubdtype(s.dtype, np.integer):
                    raise ValueError(f"sensors[{k}] must hold integers, got dtype {s.dtype}")
                fs.append(s.astype(np.int64))
            sensors = tuple(fs)
        object.__setattr__(self, "times", times)
        object.__setattr__(self, "scans", tuple(fixed))
        object.__setattr__(self, "sensors", sensors)
        object.__setattr__(self, "dim", dim)

    def __len__(self) -> int:
        return int(self.times.size)

    def __iter__(self):
        return iter(zip(self.times.tolist(), self.scans, strict=True))

    def __getitem__(self, k: int):
        return float(self.times[k]), self.scans[k]

    @property
    def n_detections(self) -> int:
        """Total number of detections over all scans."""
        return int(sum(z.shape[0] for z in self.scans))

    def to_table(self) -> dict[str, np.ndarray]:
        """Flat columns ``time, x, y[, z][, sensor]`` or ``time, range, bearing[, sensor]``
        (the file layout)."""
        n = [z.shape[0] for z in self.scans]
        Z = (
            np.concatenate(self.scans, axis=0)
            if self.scans
            else np.zeros((0, self.dim), dtype=np.float64)
        )
        out = {"time": np.repeat(self.times, n)}
        names = list(_RB_COLUMNS) if self.kind == "range-bearing" else _coord_names(self.dim)
        for a in range(self.dim):
            out[names[a]] = Z[:, a].copy()
        if self.sensors is not None:
            out["sensor"] = np.concatenate(self.sensors) if self.sensors else np.zeros(0, np.int64)
        return out


def _coord_names(dim: int) -> list[str]:
    if dim <= 3:
        return ["x", "y", "z"][:dim]
    return [f"x{i}" for i in range(dim)]


# ----------------------------------------------------------------------------- reading


def _kind(path: Path, err) -> str:
    name = path.name.lower()
    if name.endswith(_CSV_SUFFIXES):
        return "csv"
    if name.endswith(_PARQUET_SUFFIXES):
        return "parquet"
    raise err(
        path,
        "unknown file extension; use .csv, .csv.gz, .parquet or .pq",
    )


def _read_csv(path: Path, err) -> tuple[list[str], list[list[str]], np.ndarray]:
    try:
        if path.name.lower().endswith(".gz"):
            fh = gzip.open(path, "rt", newline="", encoding="utf-8-sig")
        else:
            fh = open(path, newline="", encoding="utf-8-sig")  # noqa: SIM115
    except FileNotFoundError:
        raise err(path, "file not found") from None
    except IsADirectoryError:
        raise err(path, "is a directory, not a file") from None
    except OSError as exc:
        raise err(path, f"cannot open file: {exc.strerror or exc}") from None
    header = None
    rows: list[list[str]] = []
    lines: list[int] = []
    try:
        with fh:
            reader = csv.reader(fh)
            for rec in reader:
                if not rec or all(not f.strip() for f in rec):
                    continue
                if header is None:
                    header = [f.strip() for f in rec]
                    header_line = reader.line_num
                    continue
                if len(rec) != len(header):
                    raise err(
                        path,
                        f"has {len(rec)} fields but the header (line {header_line}) "
                        f"has {len(header)}",
                        row=len(rows) + 1,
                        line=reader.line_num,
                    )
                rows.append(rec)
                lines.append(reader.line_num)
    except UnicodeDecodeError:
        raise err(path, "is not a UTF-8 text (CSV) file") from None
    except csv.Error as exc:
        raise err(path, f"malformed CSV: {exc}", line=reader.line_num) from None
    except (OSError, EOFError) as exc:  # e.g. a corrupt .gz
        raise err(path, f"cannot read file: {exc}") from None
    if header is None:
        raise err(path, "is empty (no header line)")
    low = [h.lower() for h in header]
    dup = sorted({h for h in low if low.count(h) > 1 and h})
    if dup:
        raise err(path, f"duplicate column(s) in the header: {', '.join(dup)}")
    return header, rows, np.asarray(lines, dtype=np.int64)


def _row_error(err, path, reason: str, i: int, lines, column: str) -> DataFileError:
    """``err`` for data row ``i`` (0-based) of ``column``; ``lines``: CSV line numbers or None."""
    return err(
        path, reason, row=i + 1, line=None if lines is None else int(lines[i]), column=column
    )


def _bad_cell(s: str) -> str:
    """Why the text ``s`` of a cell is not a number."""
    return "empty value" if not s.strip() else f"non-numeric value {s.strip()!r}"


def _csv_column(path, err, rows, lines, j: int, name: str) -> np.ndarray:
    col = [r[j] for r in rows]
    try:
        vals = np.array(col, dtype=np.float64)
    except ValueError:
        vals = None
    if vals is None:  # find the first bad cell
        for i, s in enumerate(col):
            try:
                float(s)
            except ValueError:
                raise _row_error(err, path, _bad_cell(s), i, lines, name) from None
    return vals


def _parquet_columns(path: Path, err):
    try:
        import pyarrow.parquet as pq
    except ImportError:  # pragma: no cover - pyarrow is a dependency
        raise err(path, "reading Parquet needs pyarrow (pip install pyarrow)") from None
    if not path.exists():
        raise err(path, "file not found")
    if path.is_dir():
        raise err(path, "is a directory, not a file")
    try:
        table = pq.read_table(path)
    except Exception as exc:  # pyarrow raises several types for a non-Parquet file
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise err(path, f"cannot read Parquet file: {msg}") from None
    names = [str(n).strip() for n in table.column_names]
    low = [h.lower() for h in names]
    dup = sorted({h for h in low if low.count(h) > 1})
    if dup:
        raise err(path, f"duplicate column(s): {', '.join(dup)}")
    return names, table


def _parquet_column(path, err, table, j: int, name: str) -> np.ndarray:
    import pyarrow as pa

    col = table.column(j)
    if col.null_count:
        mask = np.asarray(col.is_null().to_numpy(zero_copy_only=False), dtype=bool)
        i = int(np.flatnonzero(mask)[0])
        raise _row_error(err, path, "missing (null) value", i, None, name)
    t = col.type
    if pa.types.is_integer(t) or pa.types.is_floating(t) or pa.types.is_decimal(t):
        return np.asarray(col.to_numpy(zero_copy_only=False), dtype=np.float64)
    if pa.types.is_string(t) or pa.types.is_large_string(t):
        strs = col.to_pylist()
        out = np.empty(len(strs), dtype=np.float64)
        for i, s in enumerate(strs):
            try:
                out[i] = float(s)
            except ValueError:
                raise _row_error(err, path, _bad_cell(s), i, None, name) from None
        return out
    raise err(path, f"has type {t}, expected a numeric column", column=name)


def _load(
    path,
    err,
    required: Sequence[str],
    optional: Sequence[str],
    parse_extras: bool,
    pick=None,
):
    """Read the named columns of a CSV/Parquet file as float64 arrays.

    Required and optional columns must be finite; other columns are ignored
    unless ``parse_extras`` (then they must be numeric, NaN allowed).
    ``pick(path, names)``, if given, chooses ``(required, optional, hint)`` from
    the file's column names instead (``hint`` is appended to a missing-column
    message; it may raise ``err``).
    Returns ``(path, columns dict, extra column names in file order, lines or None)``.
    """
    path = Path(os.fspath(path))
    kind = _kind(path, err)
    if kind == "csv":
        header, rows, lines = _read_csv(path, err)
        names = header

        def get(j, name):
            return _csv_column(path, err, rows, lines, j, name)

    else:
        names, table = _parquet_columns(path, err)
        lines = None

        def get(j, name):
            return _parquet_column(path, err, table, j, name)

    low = [n.lower() for n in names]
    hint = ""
    if pick is not None:
        required, optional, hint = pick(path, names)
    missing = [c for c in required if c not in low]
    if missing:
        raise err(
            path,
            f"missing required column(s): {', '.join(missing)} "
            f"(found: {', '.join(n for n in names if n) or 'none'}){hint}",
        )
    cols = {}
    wanted = list(required) + [c for c in optional if c in low]
    # extra columns keep their own spelling
    extras = [(j, n) for j, n in enumerate(names) if n and low[j] not in wanted]
    todo = [(low.index(c), c) for c in wanted] + (extras if parse_extras else [])
    for j, name in todo:
        v = get(j, name)
        if name in wanted:
            bad = ~np.isfinite(v)
            if bad.any():
                i = int(np.flatnonzero(bad)[0])
                raise _row_error(err, path, f"non-finite value {v[i]}", i, lines, name)
        cols[name] = v
    extras = [n for _, n in extras]
    return path, cols, extras, lines


def _check_integer(path, err, v: np.ndarray, name: str, lines) -> np.ndarray:
    bad = v != np.round(v)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise _row_error(err, path, f"value {float(v[i])!r} is not an integer", i, lines, name)
    return v.astype(np.int64)


def _pick_detection_columns(path, names):
    """Required/optional columns of a detections file from its header: position
    (``x, y[, z]``) or range–bearing (``range, bearing``), never both."""
    pos = [n for n in names if n.lower() in _POS_COLUMNS]
    rb = [n for n in names if n.lower() in _RB_COLUMNS]
    if pos and rb:
        raise DetectionFileError(
            path,
            f"has both position column(s) ({', '.join(pos)}) and range-bearing column(s) "
            f"({', '.join(rb)}); a detections file holds one kind: time, x, y[, z] or "
            "time, range, bearing",
        )
    if rb:
        return ("time", *_RB_COLUMNS), ("sensor",), ""
    hint = "" if pos else f"; or, for range-bearing detections: {', '.join(_RB_COLUMNS)}"
    return ("time", "x", "y"), ("z", "sensor"), hint


def read_detections(path) -> Detections:
    """Read a detections file (CSV or Parquet; format in the module docstring).

    Returns a :class:`Detections`: rows grouped into scans by equal
    consecutive ``time`` values; ``kind`` is ``"range-bearing"`` when the file
    has ``range, bearing`` columns (``scans`` rows are then ``[r, θ]``), else
    ``"position"``; ``dim`` is 3 when a ``z`` column is present, else 2;
    ``sensors`` is set when a ``sensor`` column is present.

    Raises
    ------
    DetectionFileError
        (a ValueError) with the file, row and column of the first problem.
    """
    err = DetectionFileError
    path, cols, _extras, lines = _load(
        path, err, (), (), parse_extras=False, pick=_pick_detection_columns
    )
    kind = "range-bearing" if "range" in cols else "position"
    t = cols["time"]
    if t.size > 1:
        back = np.flatnonzero(np.diff(t) < 0)
        if back.size:
            i = int(back[0]) + 1
            raise _row_error(
                err,
                path,
                f"time {float(t[i])!r} is earlier than the previous row's {float(t[i - 1])!r} "
                "(rows must be in non-decreasing time order)",
                i,
                lines,
                "time",
            )
    if kind == "range-bearing":
        coords = list(_RB_COLUMNS)
        neg = np.flatnonzero(cols["range"] < 0)
        if neg.size:
            i = int(neg[0])
            raise _row_error(
                err, path, f"negative range {float(cols['range'][i])!r}", i, lines, "range"
            )
        big = np.flatnonzero(np.abs(cols["bearing"]) > 2 * np.pi)
        if big.size:
            i = int(big[0])
            raise _row_error(
                err,
                path,
                f"bearing {float(cols['bearing'][i])!r} is outside [-2π, 2π]; bearings are in "
                "radians (degrees? multiply by π/180)",
                i,
                lines,
                "bearing",
            )
    else:
        coords = ["x", "y"] + (["z"] if "z" in cols else [])
    Z = np.column_stack([cols[c] for c in coords]) if t.size else np.zeros((0, len(coords)))
    sensor = None
    if "sensor" in cols:
        sensor = _check_integer(path, err, cols["sensor"], "sensor", lines)
    starts = np.flatnonzero(np.r_[True, np.diff(t) != 0]) if t.size else np.zeros(0, int)
    ends = np.r_[starts[1:], t.size].astype(int) if t.size else np.zeros(0, int)
    scans = tuple(Z[s:e] for s, e in zip(starts, ends, strict=True))
    sensors = None
    if sensor is not None:
        sensors = tuple(sensor[s:e] for s, e in zip(starts, ends, strict=True))
    return Detections(
        times=t[starts],
        scans=scans,
        sensors=sensors,
        dim=len(coords),
        source=str(path),
        kind=kind,
    )


# ----------------------------------------------------------------------------- writing


def _out_path(path, kind_err=ValueError) -> tuple[Path, str]:
    path = Path(os.fspath(path))
    name = path.name.lower()
    if name.endswith(_CSV_SUFFIXES):
        kind = "csv"
    elif name.endswith(_PARQUET_SUFFIXES):
        kind = "parquet"
    else:
        raise kind_err(f"{path}: unknown file extension; use .csv, .csv.gz, .parquet or .pq")
    path.parent.mkdir(parents=True, exist_ok=True)
    return path, kind


def _as_columns(table, what: str) -> dict[str, np.ndarray]:
    if isinstance(table, np.ndarray) and table.dtype.names:
        cols = {n: table[n] for n in table.dtype.names}
    elif isinstance(table, Mapping):
        cols = dict(table)
    else:
        raise ValueError(
            f"{what} must be a mapping of column name → 1-D array, or a numpy "
            f"structured array; got {type(table).__name__}"
        )
    out = {}
    n = None
    for k, v in cols.items():
        if not isinstance(k, str) or not k:
            raise ValueError(f"{what}: column names must be non-empty strings, got {k!r}")
        a = np.asarray(v)
        if a.ndim != 1:
            raise ValueError(f"{what}: column '{k}' must be 1-D, got shape {a.shape}")
        if a.size and not (np.issubdtype(a.dtype, np.number) or a.dtype == np.bool_):
            raise ValueError(f"{what}: column '{k}' must be numeric, got dtype {a.dtype}")
        if n is None:
            n = a.shape[0]
        elif a.shape[0] != n:
            raise ValueError(f"{what}: column '{k}' has {a.shape[0]} rows but the others have {n}")
        out[k] = a
    return out


def _write_columns(path: Path, kind: str, cols: dict[str, np.ndarray], int_cols) -> None:
    names = list(cols)
    if kind == "parquet":
        import pyarrow as pa
        import pyarrow.parquet as pq

        arrays = [
            pa.array(cols[n].astype(np.int64 if n in int_cols else np.float64)) for n in names
        ]
        pq.write_table(pa.Table.from_arrays(arrays, names=names), path)
        return
    n = len(next(iter(cols.values()))) if cols else 0
    txt = []
    for name in names:
        a = cols[name]
        if name in int_cols:
            txt.append([str(int(v)) for v in a.astype(np.int64).tolist()])
        else:
            txt.append([repr(float(v)) for v in a.astype(np.float64).tolist()])
    buf = _io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(names)
    w.writerows(zip(*txt, strict=True) if n else [])
    data = buf.getvalue()
    if path.name.lower().endswith(".gz"):
        with gzip.open(path, "wt", encoding="utf-8", newline="") as fh:
            fh.write(data)
    else:
        path.write_text(data, encoding="utf-8", newline="")


_TRACK_REQUIRED_2D = ("time", "track_id", "x", "y", "vx", "vy")
_TRACK_REQUIRED_3D = ("time", "track_id", "x", "y", "z", "vx", "vy", "vz")


def write_tracks(tracks_table, path) -> Path:
    """Write a tracks table to CSV or Parquet (chosen by the extension).

    Parameters
    ----------
    tracks_table : mapping of column name → 1-D array (e.g. a dict), or a numpy
        structured array. Required columns ``time, track_id, x, y, vx, vy``;
        ``z`` and ``vz`` together for 3-D; extra numeric columns (covariance
        entries, ``existence``, …) are written after them in the given order.
        Required columns must be finite and ``track_id`` integer-valued.
    path : ``.csv``, ``.csv.gz``, ``.parquet`` or ``.pq``; parent directories are
        created.

    Returns the path written.
    """
    cols = _as_columns(tracks_table, "tracks_table")
    has_z, has_vz = "z" in cols, "vz" in cols
    if has_z != has_vz:
        raise ValueError("tracks_table: columns 'z' and 'vz' must be given together (3-D)")
    required = _TRACK_REQUIRED_3D if has_z else _TRACK_REQUIRED_2D
    missing = [c for c in required if c not in cols]
    if missing:
        raise ValueError(f"tracks_table: missing required column(s): {', '.join(missing)}")
    for c in required:
        a = cols[c].astype(np.float64)
        if not np.all(np.isfinite(a)):
            i = int(np.flatnonzero(~np.isfinite(a))[0])
            raise ValueError(f"tracks_table: column '{c}' row {i} is not finite ({a[i]})")
    tid = cols["track_id"].astype(np.float64)
    if np.any(tid != np.round(tid)):
        i = int(np.flatnonzero(tid != np.round(tid))[0])
        raise ValueError(f"tracks_table: track_id row {i} is not an integer ({tid[i]})")
    ordered = {c: cols[c] for c in required}
    ordered.update({k: v for k, v in cols.items() if k not in ordered})
    path, kind = _out_path(path)
    _write_columns(path, kind, ordered, int_cols={"track_id"})
    return path


def read_tracks(path) -> dict[str, np.ndarray]:
    """Read a tracks file written by :func:`write_tracks` (or in its format).

    Returns a dict of columns in file order: ``track_id`` as int64, everything
    else float64. Required columns must be finite; extra columns may hold NaN.

    Raises
    ------
    TrackFileError
        (a ValueError) naming the file, row and column of the first problem.
    """
    err = TrackFileError
    path, cols, extras, lines = _load(
        path, err, ("time", "track_id", "x", "y", "vx", "vy"), ("z", "vz"), parse_extras=True
    )
    if ("z" in cols) != ("vz" in cols):
        raise err(path, "columns 'z' and 'vz' must be present together (3-D tracks)")
    cols["track_id"] = _check_integer(path, err, cols["track_id"], "track_id", lines)
    order = [*(_TRACK_REQUIRED_3D if "z" in cols else _TRACK_REQUIRED_2D), *extras]
    return {k: cols[k] for k in order}


def write_detections(detections: Detections, path) -> Path:
    """Write :class:`Detections` in the file format of :func:`read_detections`.

    Positions as ``time, x, y[, z][, sensor]``, range–bearing detections as
    ``time, range, bearing[, sensor]``. Empty scans are lost (a scan exists in
    the file only through its rows).
    """
    if not isinstance(detections, Detections):
        raise ValueError(f"expected Detections, got {type(detections).__name__}")
    if detections.dim not in (2, 3):
        raise ValueError(f"the file format holds 2-D or 3-D detections, got dim={detections.dim}")
    path, kind = _out_path(path)
    _write_columns(path, kind, detections.to_table(), int_cols={"sensor"})
    return path


def _jsonable(obj):
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return {f.name: _jsonable(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
    if isinstance(obj, Mapping):
        out = {}
        for k, v in obj.items():
            if isinstance(k, np.generic):
                k = k.item()
            if not isinstance(k, str | int | float | bool) and k is not None:
                raise ValueError(f"metrics: dict key {k!r} is not a string or number")
            out[str(k) if not isinstance(k, str) else k] = _jsonable(v)
        return out
    if isinstance(obj, np.ndarray):
        return _jsonable(obj.tolist())
    if isinstance(obj, np.generic):
        return _jsonable(obj.item())
    if isinstance(obj, bool) or obj is None or isinstance(obj, str | int):
        return obj
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, os.PathLike):
        return os.fspath(obj)
    if isinstance(obj, list | tuple | set | frozenset):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, complex):
        raise ValueError(f"metrics: complex value {obj!r} cannot be written to JSON")
    raise ValueError(f"metrics: value of type {type(obj).__name__} cannot be written to JSON")


def write_metrics(metrics: Mapping, path) -> Path:
    """Write a metrics mapping as a JSON object (``indent=2``, UTF-8).

    numpy scalars/arrays → numbers/lists, dataclasses → objects, tuples/sets →
    lists, paths → strings, NaN/±inf → ``null``. Parent directories are created.
    """
    if not isinstance(metrics, Mapping):
        raise ValueError(f"metrics must be a mapping (dict), got {type(metrics).__name__}")
    data = _jsonable(metrics)
    path = Path(os.fspath(path))
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(data, indent=2, allow_nan=False) + "\n", encoding="utf-8")
    return path
