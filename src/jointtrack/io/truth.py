"""Ground truth files: :func:`read_truth` and :func:`write_truth` (CSV / Parquet).

A truth file holds the true target positions, one row per target per time:

=========  ========  ==========================================================
column     required  meaning
=========  ========  ==========================================================
``time``   yes       a number, or an ISO-8601 timestamp (as in a detections
                     file; :mod:`jointtrack.io.times`)
``id``     yes       integer target id (the same target keeps its id)
``x``      yes       position coordinate; finite
``y``      yes       position coordinate; finite
``z``      no        third coordinate; its presence makes the truth 3-D
=========  ========  ==========================================================

The file conventions are those of a detections file (CSV or Parquet, header
matched case-insensitively, other columns ignored, rows in non-decreasing
time order, errors as one line naming the file, row and column —
:class:`TruthFileError`). Further: a target appears at most once per time
(a repeated ``(time, id)`` pair is an error), and a header without rows is an
error ("has no truth rows").

Times and the detections' clock: :func:`read_truth` returns times on the
clock of the detections it is meant for. With ``time_origin=None`` (the
detections have numeric times) the ``time`` column must hold numbers in the
same unit, used as they are. With ``time_origin`` (the detections'
:attr:`~jointtrack.io.Detections.time_origin`) the column must hold
timestamps (or be a Parquet ``timestamp`` column), of the same kind — with an
offset / ``Z`` if and only if the origin has one — and they become seconds
since that origin, exactly as the detections' times are: the same instant
gives the same float in both. Mixing numbers in one file with timestamps in
the other is an error.

Scoring matches truth and tracks by *exact* time equality (as for the
built-in scenarios), so truth rows should be at scan times; what
``jointtrack run --truth`` does with other rows is described in
:func:`jointtrack.experiments.run.run_detections`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from jointtrack.io._files import check_integer, load_columns, out_path, row_error, write_columns
from jointtrack.io.detections import _check_time_order, _offsets_ns, _time_column
from jointtrack.io.errors import TruthFileError
from jointtrack.io.times import format_timestamp, parse_origin

__all__ = ["read_truth", "write_truth"]

_REQUIRED = ("time", "id", "x", "y")


def read_truth(path, *, time_origin: str | None = None):
    """Read a truth file (format in :mod:`jointtrack.io.truth`).

    Returns ``(times (R,) float64, ids (R,) int64, positions (R, dim) float64)``
    — the table of :meth:`jointtrack.scenarios.Scenario.truth_table` — in file
    order; ``dim`` is 3 with a ``z`` column, else 2. ``time_origin``: the
    detections' time origin (``None`` for numeric times); see the module
    docstring.

    Raises
    ------
    TruthFileError
        (a ValueError) naming the file, row and column of the first problem.
    """
    err = TruthFileError
    origin_d, ns_d0, aware_d = parse_origin(time_origin)
    path, cols, _extras, lines, n_rows = load_columns(
        path, err, _REQUIRED, ("z",), parse_extras=False, raw=("time",)
    )
    if n_rows == 0:
        raise err(path, "has no truth rows: a header but no data rows")
    t, origin = _time_column(path, err, cols["time"], lines)
    _check_time_order(path, err, t, origin, lines)
    if origin is None and origin_d is not None:
        raise row_error(
            err,
            path,
            f"holds numbers but the detections' times are ISO-8601 timestamps (time origin "
            f"{origin_d}); give timestamps in both files or numbers in both",
            0,
            lines,
            "time",
        )
    if origin is not None:
        _, ns_t0, aware_t = parse_origin(origin)
        if origin_d is None:
            raise row_error(
                err,
                path,
                f"holds ISO-8601 timestamps ({origin}) but the detections' times are plain "
                "numbers; give numbers in both files or timestamps in both",
                0,
                lines,
                "time",
            )
        if aware_t != aware_d:
            has, lacks = ("has", "lacks") if aware_t else ("lacks", "has")
            raise row_error(
                err,
                path,
                f"timestamp {origin} {has} a UTC offset (Z or ±HH:MM) but the detections' "
                f"time origin {origin_d} {lacks} one; give an offset in both files or in neither",
                0,
                lines,
                "time",
            )
        ns = ns_t0 + np.asarray(_offsets_ns(t), dtype=np.int64)
        t = (ns - ns_d0).astype(np.float64) / 1e9
    ids = check_integer(path, err, cols["id"], "id", lines)
    order = np.lexsort((ids, t))
    same = (np.diff(t[order]) == 0) & (np.diff(ids[order]) == 0)
    if same.any():
        j = int(np.flatnonzero(same)[0])
        first, i = sorted((int(order[j]), int(order[j + 1])))
        where = f"line {int(lines[first])}" if lines is not None else f"data row {first + 1}"
        raise row_error(
            err,
            path,
            f"target id {int(ids[i])} appears twice at one time (also {where}); a target has "
            "one true position per time",
            i,
            lines,
            "id",
        )
    coords = ["x", "y"] + (["z"] if "z" in cols else [])
    pos = np.column_stack([cols[c] for c in coords]).astype(np.float64)
    return t, ids, pos


def write_truth(truth, path, *, time_origin: str | None = None) -> Path:
    """Write a truth table ``(times, ids, positions)`` (e.g. a scenario's
    :meth:`~jointtrack.scenarios.Scenario.truth_table`) in the format of
    :func:`read_truth`: columns ``time, id, x, y[, z]``. With ``time_origin``
    the ``time`` column holds ISO-8601 timestamps (``time_origin`` + times
    seconds), so ``read_truth(path, time_origin=time_origin)`` gives the same
    times back. Returns the path written.
    """
    times, ids, pos = truth
    times = np.asarray(times, dtype=np.float64).reshape(-1)
    ids = np.asarray(ids).reshape(-1)
    pos = np.asarray(pos, dtype=np.float64)
    if pos.ndim != 2 or pos.shape[1] not in (2, 3):
        raise ValueError(f"truth positions must have shape (R, 2) or (R, 3), got {pos.shape}")
    if not (times.size == ids.size == pos.shape[0]):
        raise ValueError(
            f"truth columns differ in length: {times.size} times, {ids.size} ids, "
            f"{pos.shape[0]} positions"
        )
    path, kind = out_path(path)
    cols = {"time": times, "id": ids.astype(np.int64)}
    for a, name in enumerate(["x", "y", "z"][: pos.shape[1]]):
        cols[name] = pos[:, a].copy()
    text_cols = {}
    if time_origin is not None:
        import pyarrow as pa

        _, ns0, aware = parse_origin(time_origin)
        ns = [ns0 + v for v in _offsets_ns(times)]
        arr = pa.array(
            np.asarray(ns, dtype=np.int64), pa.timestamp("ns", tz="UTC" if aware else None)
        )
        text_cols["time"] = ([format_timestamp(v, aware) for v in ns], arr)
    write_columns(path, kind, cols, int_cols={"id"}, text_cols=text_cols)
    return path
