"""Track tables: :func:`write_tracks` and :func:`read_tracks` (CSV / Parquet).

Format: see :mod:`jointtrack.io` (the package docstring).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from jointtrack.io._files import as_columns, check_integer, load_columns, out_path, write_columns
from jointtrack.io.errors import TrackFileError

__all__ = ["read_tracks", "with_geodetic_columns", "write_tracks"]

_TRACK_REQUIRED_2D = ("time", "track_id", "x", "y", "vx", "vy")
_TRACK_REQUIRED_3D = ("time", "track_id", "x", "y", "z", "vx", "vy", "vz")


def write_tracks(tracks_table, path, *, frame=None) -> Path:
    """Write a tracks table to CSV or Parquet (chosen by the extension).

    Parameters
    ----------
    tracks_table : mapping of column name → 1-D array (e.g. a dict), or a numpy
        structured array. Required columns ``time, track_id, x, y, vx, vy``;
        ``z`` and ``vz`` together for 3-D; extra numeric columns (covariance
        entries, ``existence``, an IMM tracker's mode probabilities
        ``mode_<name>``, …) are written after them in the given order.
        Required columns must be finite and ``track_id`` integer-valued.
    path : ``.csv``, ``.csv.gz``, ``.parquet`` or ``.pq``; parent directories are
        created.
    frame : optional :class:`~jointtrack.io.geodetic.LocalFrame` (or ``(lat0, lon0[,
        alt0])``) that ``x, y[, z]`` are east/north(/up) metres in: then ``lat, lon``
        (WGS-84 degrees; with ``z`` also ``alt``, metres) are written right after the
        local position, the inverse of the frame's projection
        (:meth:`~jointtrack.io.geodetic.LocalFrame.to_geodetic`). :func:`read_tracks`
        reads them back as extra columns.

    Returns the path written.
    """
    cols = as_columns(tracks_table, "tracks_table")
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
    if frame is not None:
        ordered = with_geodetic_columns(ordered, frame)
    path, kind = out_path(path)
    write_columns(path, kind, ordered, int_cols={"track_id"})
    return path


def with_geodetic_columns(cols: dict, frame) -> dict:
    """``cols`` (name → 1-D array, ``x, y[, z]`` among them) with ``lat, lon[, alt]`` of
    the local positions inserted right after ``y`` (``z`` when there is one).

    ``frame``: a :class:`~jointtrack.io.geodetic.LocalFrame` or ``(lat0, lon0[, alt0])``
    that ``x, y[, z]`` are east/north(/up) metres in. The tracks file of
    :func:`write_tracks` and of ``jointtrack run`` on report files (written once, in
    this final form) both take their columns from here.
    """
    from jointtrack.io.geodetic import GEO_COLUMNS, LocalFrame

    if not isinstance(frame, LocalFrame):
        sized = not isinstance(frame, str) and hasattr(frame, "__len__")
        if not sized or len(frame) not in (2, 3):
            raise ValueError(f"frame must be a LocalFrame or (lat0, lon0[, alt0]), got {frame!r}")
        try:
            frame = LocalFrame(*frame)
        except (TypeError, ValueError) as exc:
            raise type(exc)(f"frame: {exc}") from None
    has_z = "z" in cols
    names = GEO_COLUMNS if has_z else GEO_COLUMNS[:2]
    clash = [c for c in names if c in cols]
    if clash:
        raise ValueError(
            f"tracks_table already has column(s) {', '.join(clash)}; with a frame they are "
            "computed from x, y"
        )
    local = np.column_stack(
        [np.asarray(cols[c]).astype(np.float64) for c in (("x", "y", "z") if has_z else ("x", "y"))]
    )
    geo = frame.to_geodetic(local)
    out = {}
    for k, v in cols.items():
        out[k] = v
        if k == ("z" if has_z else "y"):
            out.update(zip(names, geo, strict=True))
    return out


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
    path, cols, extras, lines, _ = load_columns(
        path, err, ("time", "track_id", "x", "y", "vx", "vy"), ("z", "vz"), parse_extras=True
    )
    if ("z" in cols) != ("vz" in cols):
        raise err(path, "columns 'z' and 'vz' must be present together (3-D tracks)")
    cols["track_id"] = check_integer(path, err, cols["track_id"], "track_id", lines)
    order = [*(_TRACK_REQUIRED_3D if "z" in cols else _TRACK_REQUIRED_2D), *extras]
    return {k: cols[k] for k in order}
