"""Detections: the :class:`Detections` container and its files (CSV / Parquet).

File format: see :mod:`jointtrack.io` (the package docstring); ISO-8601 scan
times: :mod:`jointtrack.io.times`.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from jointtrack.io._files import (
    check_integer,
    load_columns,
    out_path,
    parquet_is_numeric,
    parquet_is_string,
    parquet_nulls,
    row_error,
    write_columns,
)
from jointtrack.io.errors import DetectionFileError
from jointtrack.io.times import EXPECTED_TIMES, format_timestamp, parse_origin, parse_timestamp

__all__ = ["KINDS", "Detections", "read_detections", "write_detections"]

#: the kinds of :class:`Detections` (:attr:`Detections.kind`)
KINDS = ("position", "range-bearing")
POS_COLUMNS = ("x", "y", "z")
RB_COLUMNS = ("range", "bearing")

_NS = 1_000_000_000
_UNIT_NS = {"s": _NS, "ms": 1_000_000, "us": 1_000, "ns": 1}


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
    time_origin : ``None`` when ``times`` are plain numbers (e.g. read from a
        numeric ``time`` column); else the ISO-8601 timestamp of t = 0 — for a
        file with timestamps, the first scan's — so that the absolute time of
        scan k is ``time_origin + times[k]`` seconds (:meth:`timestamps`).
        Written ``…Z`` (UTC) for timestamps with an offset, without a suffix
        for naive (wall-clock) timestamps; an origin given with an offset is
        converted to UTC. See :mod:`jointtrack.io.times`.

    ``len(d)`` is K; iterating yields ``(time, z)`` pairs; ``d[k]`` is
    ``(times[k], scans[k])``.
    """

    times: np.ndarray
    scans: tuple
    sensors: tuple | None = None
    dim: int = 2
    source: str | None = None
    kind: str = "position"
    time_origin: str | None = None

    def __post_init__(self):
        origin, _, _ = parse_origin(self.time_origin)
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
        object.__setattr__(self, "time_origin", origin)

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

    def timestamps(self) -> list[str] | None:
        """ISO-8601 timestamps of the scans (``time_origin`` + ``times`` seconds,
        nanosecond resolution), or ``None`` when there is no ``time_origin``."""
        if self.time_origin is None:
            return None
        _, ns0, aware = parse_origin(self.time_origin)
        return [format_timestamp(ns0 + v, aware) for v in _offsets_ns(self.times)]

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
        names = list(RB_COLUMNS) if self.kind == "range-bearing" else _coord_names(self.dim)
        for a in range(self.dim):
            out[names[a]] = Z[:, a].copy()
        if self.sensors is not None:
            out["sensor"] = np.concatenate(self.sensors) if self.sensors else np.zeros(0, np.int64)
        return out


def _coord_names(dim: int) -> list[str]:
    if dim <= 3:
        return ["x", "y", "z"][:dim]
    return [f"x{i}" for i in range(dim)]


def _offsets_ns(times: np.ndarray) -> list[int]:
    """Seconds → whole nanoseconds (exact for times read from timestamps)."""
    return [int(v) for v in np.rint(np.asarray(times, dtype=np.float64) * 1e9).tolist()]


# ----------------------------------------------------------------------------- reading


def _pick_detection_columns(path, names):
    """Required/optional columns of a detections file from its header: position
    (``x, y[, z]``) or range–bearing (``range, bearing``), never both."""
    pos = [n for n in names if n.lower() in POS_COLUMNS]
    rb = [n for n in names if n.lower() in RB_COLUMNS]
    if pos and rb:
        raise DetectionFileError(
            path,
            f"has both position column(s) ({', '.join(pos)}) and range-bearing column(s) "
            f"({', '.join(rb)}); a detections file holds one kind: time, x, y[, z] or "
            "time, range, bearing",
        )
    if rb:
        return ("time", *RB_COLUMNS), ("sensor",), ""
    hint = "" if pos else f"; or, for range-bearing detections: {', '.join(RB_COLUMNS)}"
    return ("time", "x", "y"), ("z", "sensor"), hint


def _is_number(s: str) -> bool:
    try:
        float(s)
    except ValueError:
        return False
    return True


def _finite_times(path, err, v: np.ndarray, lines) -> np.ndarray:
    bad = ~np.isfinite(v)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise row_error(err, path, f"non-finite value {v[i]}", i, lines, "time")
    return v


def _relative(ns: np.ndarray) -> np.ndarray:
    """Seconds since the first value of int64 nanoseconds."""
    return (ns - ns[0]).astype(np.float64) / 1e9 if ns.size else np.zeros(0)


def _time_strings(path, err, cells: list, lines) -> tuple[np.ndarray, str | None]:
    """A ``time`` column of text cells: all numbers, or all ISO-8601 timestamps."""
    try:
        return _finite_times(path, err, np.array(cells, dtype=np.float64), lines), None
    except (ValueError, TypeError):
        pass

    def bad(i, reason):
        return row_error(err, path, f"{reason}; {EXPECTED_TIMES}", i, lines, "time")

    def timestamp(i, s):
        try:
            return parse_timestamp(s)
        except ValueError as exc:
            raise bad(i, str(exc)) from None

    texts = [str(s).strip() for s in cells]
    first = texts[0]
    if _is_number(first):  # a numeric column with a bad cell
        for i, s in enumerate(texts):
            if _is_number(s):
                continue
            if not s:
                raise bad(i, "empty value")
            if timestamp(i, s) is not None:
                raise bad(
                    i,
                    f"timestamp {s!r} in a column of numbers (data row 1: {first!r}); "
                    "use numbers throughout or timestamps throughout",
                )
            raise bad(i, f"value {s!r} is neither a number nor an ISO-8601 timestamp")
    ns = np.empty(len(texts), dtype=np.int64)
    aware0 = None
    for i, s in enumerate(texts):
        if not s:
            raise bad(i, "empty value")
        parsed = timestamp(i, s)
        if parsed is None:
            if _is_number(s):
                raise bad(
                    i,
                    f"number {s!r} in a column of timestamps (data row 1: {first!r}); "
                    "use numbers throughout or timestamps throughout",
                )
            raise bad(i, f"value {s!r} is neither a number nor an ISO-8601 timestamp")
        ns[i], aware = parsed
        if aware0 is None:
            aware0 = aware
        elif aware != aware0:
            has, lacks = ("has", "lacks") if aware else ("lacks", "has")
            raise bad(
                i,
                f"timestamp {s!r} {has} a UTC offset (Z or ±HH:MM) but data row 1 "
                f"({first!r}) {lacks} one; give an offset on all timestamps or on none",
            )
    return _relative(ns), format_timestamp(int(ns[0]), bool(aware0))


def _time_column(path, err, raw, lines) -> tuple[np.ndarray, str | None]:
    """Scan times (float64 seconds) and the time origin of the raw ``time`` column."""
    if isinstance(raw, list):  # CSV cells
        return _time_strings(path, err, raw, lines)
    import pyarrow as pa

    parquet_nulls(path, err, raw, "time")
    t = raw.type
    if parquet_is_numeric(t):
        v = np.asarray(raw.to_numpy(zero_copy_only=False), dtype=np.float64)
        return _finite_times(path, err, v, None), None
    if pa.types.is_timestamp(t):
        ns = raw.cast(pa.int64()).to_numpy(zero_copy_only=False).astype(np.int64)
        ns = ns * _UNIT_NS[t.unit]
        origin = format_timestamp(int(ns[0]), t.tz is not None) if ns.size else None
        return _relative(ns), origin
    if parquet_is_string(t):
        return _time_strings(path, err, raw.to_pylist(), None)
    raise err(
        path,
        f"has type {t}; {EXPECTED_TIMES}, or a Parquet timestamp column",
        column="time",
    )


def _check_time_order(path, err, t: np.ndarray, origin, lines) -> None:
    """``err`` at the first row whose time is earlier than the row before it."""
    if t.size < 2:
        return
    back = np.flatnonzero(np.diff(t) < 0)
    if back.size:
        i = int(back[0]) + 1
        if origin is None:
            now, before = repr(float(t[i])), repr(float(t[i - 1]))
        else:
            _, ns0, aware = parse_origin(origin)
            now, before = (format_timestamp(ns0 + v, aware) for v in _offsets_ns(t[[i, i - 1]]))
        raise row_error(
            err,
            path,
            f"time {now} is earlier than the previous row's {before} "
            "(rows must be in non-decreasing time order)",
            i,
            lines,
            "time",
        )


def read_detections(path, *, allow_empty: bool = False) -> Detections:
    """Read a detections file (CSV or Parquet; format in :mod:`jointtrack.io`).

    Returns a :class:`Detections`: rows grouped into scans by equal
    consecutive ``time`` values; ``kind`` is ``"range-bearing"`` when the file
    has ``range, bearing`` columns (``scans`` rows are then ``[r, θ]``), else
    ``"position"``; ``dim`` is 3 when a ``z`` column is present, else 2;
    ``sensors`` is set when a ``sensor`` column is present. With ISO-8601
    timestamps in the ``time`` column, ``times`` are seconds since the first
    row's timestamp and ``time_origin`` is that timestamp (else ``None``).

    A file with a header but no data rows is an error ("has no detections")
    unless ``allow_empty`` (then an empty :class:`Detections` is returned).

    Raises
    ------
    DetectionFileError
        (a ValueError) with the file, row and column of the first problem.
    """
    err = DetectionFileError
    path, cols, _extras, lines, n_rows = load_columns(
        path, err, (), (), parse_extras=False, pick=_pick_detection_columns, raw=("time",)
    )
    if n_rows == 0 and not allow_empty:
        raise err(path, "has no detections: a header but no data rows")
    kind = "range-bearing" if "range" in cols else "position"
    t, origin = _time_column(path, err, cols["time"], lines)
    _check_time_order(path, err, t, origin, lines)
    if kind == "range-bearing":
        coords = list(RB_COLUMNS)
        neg = np.flatnonzero(cols["range"] < 0)
        if neg.size:
            i = int(neg[0])
            raise row_error(
                err, path, f"negative range {float(cols['range'][i])!r}", i, lines, "range"
            )
        big = np.flatnonzero(np.abs(cols["bearing"]) > 2 * np.pi)
        if big.size:
            i = int(big[0])
            raise row_error(
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
        sensor = check_integer(path, err, cols["sensor"], "sensor", lines)
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
        time_origin=origin,
    )


# ----------------------------------------------------------------------------- writing


def write_detections(detections: Detections, path) -> Path:
    """Write :class:`Detections` in the file format of :func:`read_detections`.

    Positions as ``time, x, y[, z][, sensor]``, range–bearing detections as
    ``time, range, bearing[, sensor]``. Empty scans are lost (a scan exists in
    the file only through its rows). With a ``time_origin`` the ``time``
    column holds ISO-8601 timestamps (CSV text; a Parquet ``timestamp[ns]``
    column, UTC unless the origin is naive), so reading the file back gives
    the same ``times`` and ``time_origin``; else numbers.
    """
    if not isinstance(detections, Detections):
        raise ValueError(f"expected Detections, got {type(detections).__name__}")
    if detections.dim not in (2, 3):
        raise ValueError(f"the file format holds 2-D or 3-D detections, got dim={detections.dim}")
    path, kind = out_path(path)
    table = detections.to_table()
    text_cols = {}
    if detections.time_origin is not None:
        import pyarrow as pa

        _, ns0, aware = parse_origin(detections.time_origin)
        ns = [ns0 + v for v in _offsets_ns(table["time"])]
        text = [format_timestamp(v, aware) for v in ns]
        arr = pa.array(
            np.asarray(ns, dtype=np.int64), pa.timestamp("ns", tz="UTC" if aware else None)
        )
        text_cols["time"] = (text, arr)
    write_columns(path, kind, table, int_cols={"sensor"}, text_cols=text_cols)
    return path
