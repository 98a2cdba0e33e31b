"""Detections: the :class:`Detections` container and its files (CSV / Parquet).

File format: see :mod:`jointtrack.io` (the package docstring); ISO-8601 scan
times: :mod:`jointtrack.io.times`.
"""

from __future__ import annotations

import math
import numbers
import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from jointtrack.io._files import (
    NUL_REASON,
    check_integer,
    load_columns,
    nul_index,
    out_path,
    parquet_column,
    parquet_column_nullable,
    parquet_is_numeric,
    parquet_is_string,
    parquet_nulls,
    row_error,
    string_array,
    strings_to_floats,
    strings_to_floats_nullable,
    text_array,
    write_columns,
)
from jointtrack.io.errors import DetectionFileError
from jointtrack.io.times import (
    EXPECTED_TIMES,
    format_timestamp,
    outside_time_range,
    parse_origin,
    parse_timestamp,
    span_problem,
    units_to_ns,
)

__all__ = [
    "DETECTION_KINDS",
    "KINDS",
    "Detections",
    "read_detections",
    "sensor_ids",
    "write_detections",
]

#: the kinds of a measurement (a row of a scan)
KINDS = ("position", "range-bearing")
#: the kinds of :class:`Detections` (:attr:`Detections.kind`): a measurement kind,
#: or ``"mixed"`` (each row its own kind, :attr:`Detections.row_kinds`)
DETECTION_KINDS = (*KINDS, "mixed")
POS_COLUMNS = ("x", "y", "z")
RB_COLUMNS = ("range", "bearing")
SENSOR_POSITION_COLUMNS = ("sensor_x", "sensor_y")
VELOCITY_COLUMNS = ("vx", "vy", "vz")
GEO_COLUMNS = ("lat", "lon", "alt")
REFERENCE_COLUMNS = ("ref_lat", "ref_lon", "ref_alt")
COURSE_COLUMNS = ("speed_knots", "course_deg")

#: Largest |coordinate| (x, y, z, range, sensor_x, sensor_y) read from a file: the
#: filter squares differences of coordinates (innovations, gate distances), and
#: (2·10¹⁵⁰)² = 4·10³⁰⁰ leaves room below the float64 maximum (1.8·10³⁰⁸) for
#: dividing by a small noise variance. Beyond it a value cannot be tracked
#: meaningfully, and is refused with the file, row and column.
MAX_COORDINATE = 1e150
_COORDINATE_COLUMNS = (*POS_COLUMNS, *RB_COLUMNS[:1], *SENSOR_POSITION_COLUMNS)

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
    sensors : tuple of K arrays ``(M_k,)`` with the sensor id of each
        detection, or ``None`` when there is no sensor information. Sensor ids
        are labels: int64 arrays (any integer ids, exactly — no float
        rounding) or string arrays (``"radar_a"``), all scans of one kind
        (:func:`sensor_ids`); :meth:`sensor_kinds` and :meth:`sensor_scans`
        give them as Python ``int`` or ``str``.
    dim : columns of a detection: the spatial dimension for positions (2 or 3
        from files; any ≥ 1 when built directly), 2 for range–bearing.
    source : the file the detections were read from, if any.
    kind : ``"position"`` (default), ``"range-bearing"`` (ranges ≥ 0,
        bearings within [−2π, 2π]) or ``"mixed"``: 2-D scans whose rows are
        ``[x, y]`` or ``[r, θ]`` as :attr:`row_kinds` says (several sensors of
        different types in one file; needs ``sensors``, and each sensor id's
        rows are all of one kind).
    time_origin : ``None`` when ``times`` are plain numbers (e.g. read from a
        numeric ``time`` column); else the ISO-8601 timestamp of t = 0 — for a
        file with timestamps, the first scan's — so that the absolute time of
        scan k is ``time_origin + times[k]`` seconds (:meth:`timestamps`).
        Written ``…Z`` (UTC) for timestamps with an offset, without a suffix
        for naive (wall-clock) timestamps; an origin given with an offset is
        converted to UTC. See :mod:`jointtrack.io.times`.
    row_kinds : for ``kind == "mixed"``, a tuple of K string arrays ``(M_k,)``
        holding ``"position"`` or ``"range-bearing"`` per detection (given as
        strings, or as booleans = "is range-bearing"); ``None`` otherwise (every
        row is of ``kind``; :meth:`scan_kinds` gives the array either way).
    sensor_positions : ``None``, or (range-bearing and mixed detections) a
        tuple of K float arrays ``(M_k, 2)``: the position of the sensor that
        took each range–bearing detection (a moving sensor), NaN for rows
        without one (position rows; sensors at a fixed, configured position).
        The rows of one (scan, sensor) share one position, and a sensor id has
        a position on all its rows or on none.
    labels : ``None``, or a tuple of K string arrays ``(M_k,)``: an identity
        label per detection (an AIS MMSI, an ADS-B icao24), ``""`` for an
        unlabelled row.
    velocities : ``None``, or (position detections) a tuple of K float arrays
        ``(M_k, dim)``: a reported velocity per detection (e.g. from speed and
        course), NaN where unknown (a whole row, or a component).
    geo_reference : ``None``, or (position detections, dim 2 or 3) the WGS-84
        reference ``(lat0, lon0, alt0)`` (degrees, degrees, metres) of the
        local east-north(-up) frame the positions are in
        (:class:`~jointtrack.io.geodetic.LocalFrame`, :meth:`geo_frame`);
        given as 2 or 3 numbers, kept as 3 floats.
    geo_outliers : rows of the geodetic source left out as outliers, far from the
        data's median point (:func:`~jointtrack.io.geodetic.data_centre`; 0 with a
        given reference); needs ``geo_reference``.
    geo_outlier_bound : the distance (m) from the median point beyond which rows
        were outliers, or ``None`` (a given reference, data spread too widely).

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
    row_kinds: tuple | None = None
    sensor_positions: tuple | None = None
    labels: tuple | None = None
    velocities: tuple | None = None
    geo_reference: tuple | None = None
    geo_outliers: int = 0
    geo_outlier_bound: float | None = None

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
        if self.kind not in DETECTION_KINDS:
            raise ValueError(f"kind must be one of {', '.join(DETECTION_KINDS)}, got {self.kind!r}")
        if self.kind != "position" and dim != 2:
            raise ValueError(f"{self.kind} detections have dim 2 (range, bearing), got {dim}")
        scans = tuple(self.scans)
        if len(scans) != times.size:
            raise ValueError(f"{times.size} scan times but {len(scans)} scans")
        row_kinds = _check_row_kinds(self.kind, self.row_kinds, scans)
        fixed = []
        for k, z in enumerate(scans):
            z = np.asarray(z, dtype=np.float64)
            if z.size == 0:
                z = z.reshape(0, dim)
            if z.ndim != 2 or z.shape[1] != dim:
                raise ValueError(f"scans[{k}] must have shape (M, {dim}), got {z.shape}")
            if not np.all(np.isfinite(z)):
                raise ValueError(f"scans[{k}] has a non-finite coordinate")
            if z.size and np.abs(z).max() > MAX_COORDINATE:
                raise ValueError(
                    f"scans[{k}] has a coordinate beyond ±{MAX_COORDINATE:g}, which the tracker "
                    "cannot square (rescale the data)"
                )
            if row_kinds is not None and row_kinds[k].shape != (z.shape[0],):
                raise ValueError(
                    f"row_kinds[{k}] must have shape ({z.shape[0]},), got {row_kinds[k].shape}"
                )
            rb = z if self.kind == "range-bearing" else z[:0]
            if row_kinds is not None:
                rb = z[row_kinds[k] == "range-bearing"]
            if np.any(rb[:, 0] < 0):
                raise ValueError(f"scans[{k}] has a negative range")
            if np.any(np.abs(rb[:, 1]) > 2 * np.pi):
                raise ValueError(f"scans[{k}] has a bearing outside [-2π, 2π] (radians expected)")
            fixed.append(z)
        sensors = self.sensors
        if sensors is not None:
            sensors = tuple(sensors)
            if len(sensors) != len(fixed):
                raise ValueError(f"{len(fixed)} scans but {len(sensors)} sensor arrays")
            for k, (s, z) in enumerate(zip(sensors, fixed, strict=True)):
                shape = np.shape(s)
                if shape != (z.shape[0],) and not (z.shape[0] == 0 and np.size(s) == 0):
                    raise ValueError(f"sensors[{k}] must have shape ({z.shape[0]},), got {shape}")
            sensors = sensor_ids(sensors)
        if self.kind == "mixed":
            if sensors is None:
                raise ValueError(
                    "mixed detections need sensors: each sensor id's rows are of one kind"
                )
            _check_sensor_kinds(sensors, row_kinds)
        positions = _check_sensor_positions(self, fixed, sensors, row_kinds)
        labels = _check_labels(self.labels, fixed)
        velocities = _check_velocities(self.velocities, fixed, self.kind, dim)
        geo = _check_geo_reference(self.geo_reference, self.kind, dim)
        n_out, bound = _check_geo_outliers(self.geo_outliers, self.geo_outlier_bound, geo)
        object.__setattr__(self, "geo_outliers", n_out)
        object.__setattr__(self, "geo_outlier_bound", bound)
        object.__setattr__(self, "labels", labels)
        object.__setattr__(self, "velocities", velocities)
        object.__setattr__(self, "geo_reference", geo)
        object.__setattr__(self, "times", times)
        object.__setattr__(self, "scans", tuple(fixed))
        object.__setattr__(self, "sensors", sensors)
        object.__setattr__(self, "dim", dim)
        object.__setattr__(self, "time_origin", origin)
        object.__setattr__(self, "row_kinds", row_kinds)
        object.__setattr__(self, "sensor_positions", positions)

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

    def geo_frame(self):
        """The :class:`~jointtrack.io.geodetic.LocalFrame` of :attr:`geo_reference`,
        or ``None`` when the positions are not from geodetic data."""
        if self.geo_reference is None:
            return None
        from jointtrack.io.geodetic import LocalFrame

        return LocalFrame(*self.geo_reference)

    def scan_kinds(self, k: int) -> np.ndarray:
        """The measurement kind (``"position"`` / ``"range-bearing"``) of each row of scan k."""
        if self.row_kinds is not None:
            return self.row_kinds[k]
        return np.full(self.scans[k].shape[0], self.kind, dtype=_KIND_DTYPE)

    def sensor_kinds(self) -> dict:
        """``{sensor id: measurement kind of its rows}`` (empty without ``sensors``);
        ids as Python ``int`` or ``str``, sorted."""
        out: dict = {}
        for k, ids in enumerate(self.sensors or ()):
            for sid, kind in zip(ids.tolist(), self.scan_kinds(k).tolist(), strict=True):
                out.setdefault(sid, str(kind))
        return dict(sorted(out.items()))

    def sensor_scans(self, k: int) -> list[tuple]:
        """The (time, sensor) scans of scan k, in sensor-id order.

        A list of ``(sensor_id, kind, z, sensor_position)``: ``sensor_id`` is
        ``None`` without ``sensors`` (one entry, also for an empty scan);
        ``kind`` the measurement kind of the rows ``z``; ``sensor_position`` the
        (2,) position of a moving sensor (:attr:`sensor_positions`) or ``None``.
        """
        z = self.scans[k]
        kinds = self.scan_kinds(k)
        pos = None if self.sensor_positions is None else self.sensor_positions[k]

        def entry(sid, rows):
            kind = str(kinds[rows][0]) if len(kinds[rows]) else self.kind
            p = None
            if pos is not None and len(pos[rows]) and np.isfinite(pos[rows][0, 0]):
                p = pos[rows][0].copy()
            return sid, kind, z[rows], p

        if self.sensors is None or not len(self.sensors[k]):
            return [entry(None, np.arange(z.shape[0]))]
        ids = self.sensors[k]
        return [entry(sid, np.flatnonzero(ids == sid)) for sid in np.unique(ids).tolist()]

    def cartesian(self, sensor_position=(0.0, 0.0)) -> tuple:
        """The scans as Cartesian positions ``(M_k, dim)``: position rows as they
        are, range–bearing rows ``[r, θ]`` as ``s + r (cos θ, sin θ)``.

        ``s``: the row's :attr:`sensor_positions` entry when it has one, else
        ``sensor_position`` — a (2,) position, or a mapping ``{sensor id:
        (2,) position}`` (ids missing from it: its ``None`` entry, if any).
        """
        out = []
        for k, z in enumerate(self.scans):
            rb = self.scan_kinds(k) == "range-bearing"
            if not rb.any():
                out.append(z.copy())
                continue
            s = np.zeros((z.shape[0], 2))
            if isinstance(sensor_position, Mapping):
                ids = self.sensors[k].tolist() if self.sensors is not None else [None] * z.shape[0]
                for i, key in enumerate(ids):
                    if not rb[i]:
                        continue
                    if key not in sensor_position and None not in sensor_position:
                        raise ValueError(f"no position for range-bearing sensor {key}")
                    s[i] = sensor_position.get(key, sensor_position.get(None))
            else:
                s[:] = np.asarray(sensor_position, dtype=np.float64)
            if self.sensor_positions is not None:
                own = np.isfinite(self.sensor_positions[k][:, 0])
                s[own] = self.sensor_positions[k][own]
            p = z.copy()
            r, th = z[rb, 0], z[rb, 1]
            p[rb] = s[rb] + np.column_stack([r * np.cos(th), r * np.sin(th)])
            out.append(p)
        return tuple(out)

    def to_table(self) -> dict[str, np.ndarray]:
        """Flat columns ``time, x, y[, z][, sensor]`` or ``time, range, bearing[, sensor]``
        (the file layout); mixed detections: ``time, x, y, range, bearing, sensor``
        with NaN in the set a row does not fill; with :attr:`sensor_positions`
        also ``sensor_x, sensor_y`` (NaN for rows without); with :attr:`labels` a
        ``label`` column (strings, ``""`` unlabelled); with :attr:`velocities`
        ``vx, vy[, vz]`` (NaN unknown); with :attr:`geo_reference` also ``lat,
        lon[, alt]`` (WGS-84 degrees, metres) of the positions. Empty scans
        have no row here (:func:`write_detections` marks them)."""
        n = [z.shape[0] for z in self.scans]
        Z = (
            np.concatenate(self.scans, axis=0)
            if self.scans
            else np.zeros((0, self.dim), dtype=np.float64)
        )
        out = {"time": np.repeat(self.times, n)}
        if self.kind == "mixed":
            rb = np.concatenate([self.scan_kinds(k) for k in range(len(self))] or [[]])
            rb = rb == "range-bearing"
            for a, name in enumerate(("x", "y")):
                out[name] = np.where(rb, np.nan, Z[:, a])
            for a, name in enumerate(RB_COLUMNS):
                out[name] = np.where(rb, Z[:, a], np.nan)
        else:
            names = list(RB_COLUMNS) if self.kind == "range-bearing" else _coord_names(self.dim)
            for a in range(self.dim):
                out[names[a]] = Z[:, a].copy()
        if self.sensors is not None:
            out["sensor"] = np.concatenate(self.sensors) if self.sensors else np.zeros(0, np.int64)
            if out["sensor"].dtype.kind == "U" and not out["sensor"].size:
                out["sensor"] = np.zeros(0, np.int64)
        if self.sensor_positions is not None:
            S = np.concatenate(self.sensor_positions, axis=0) if self.scans else np.zeros((0, 2))
            out["sensor_x"], out["sensor_y"] = S[:, 0].copy(), S[:, 1].copy()
        if self.labels is not None:
            out["label"] = np.concatenate([np.asarray(a, dtype=str) for a in self.labels] or [[]])
            out["label"] = out["label"].astype(str)
        if self.velocities is not None:
            V = np.concatenate(self.velocities, axis=0) if self.scans else np.zeros((0, self.dim))
            for a, name in enumerate(VELOCITY_COLUMNS[: self.dim]):
                out[name] = V[:, a].copy()
        if self.geo_reference is not None:
            geo = self.geo_frame().to_geodetic(Z)
            for name, v in zip(GEO_COLUMNS, geo, strict=False):
                out[name] = v
        return out


_KIND_DTYPE = "<U13"
_INT64 = np.iinfo(np.int64)


def sensor_ids(sensors) -> tuple:
    """Sensor-id arrays as labels: all int64 (exact) or all strings.

    ``sensors``: a sequence of 1-D arrays (or lists) of integers — any integer
    dtype or Python ints within int64 — or of strings. Floats (ids that
    differ beyond 2^53 would merge), booleans and mixed kinds are refused
    with a ValueError naming ``sensors[k]``. Empty arrays take the kind of
    the others.
    """
    out, kinds = [], set()
    for k, s in enumerate(sensors):
        # a list as objects: numpy strings would drop trailing NULs before the check
        a = _as_array(s) if not isinstance(s, np.ndarray) else s
        if a.ndim != 1:
            a = a.reshape(-1) if a.size == 0 else a
        if a.ndim != 1:
            raise ValueError(f"sensors[{k}] must be 1-D, got shape {a.shape}")
        if a.size == 0:
            out.append(None)
            continue
        if a.dtype.kind == "O":
            vals = a.tolist()
            if all(isinstance(v, str) for v in vals):
                i = nul_index(vals)
                if i is not None:
                    raise ValueError(f"sensors[{k}]: {vals[i]!r} {NUL_REASON}")
                a = np.array(vals, dtype=str)
            elif all(isinstance(v, int | np.integer) and not isinstance(v, bool) for v in vals):
                if any(not (_INT64.min <= int(v) <= _INT64.max) for v in vals):
                    raise ValueError(f"sensors[{k}] has an id beyond 64-bit integers")
                a = np.array([int(v) for v in vals], dtype=np.int64)
            else:
                bad = next(
                    v
                    for v in vals
                    if not isinstance(v, str | int | np.integer) or isinstance(v, bool)
                )
                raise ValueError(f"sensors[{k}] holds {bad!r}; sensor ids are integers or strings")
        if a.dtype.kind == "u" and a.dtype.itemsize == 8 and a.size and a.max() > _INT64.max:
            raise ValueError(f"sensors[{k}] has an id beyond 64-bit signed integers")
        if a.dtype.kind in "iu":
            out.append(a.astype(np.int64))
            kinds.add("integer")
        elif a.dtype.kind == "U":
            out.append(a)
            kinds.add("string")
        else:
            raise ValueError(
                f"sensors[{k}] must hold integer or string ids (labels), got dtype {a.dtype}"
            )
    if len(kinds) > 1:
        raise ValueError("sensors: the ids are integers in some scans and strings in others")
    empty = np.zeros(0, dtype=str if kinds == {"string"} else np.int64)
    return tuple(empty if a is None else a for a in out)


def _as_array(s) -> np.ndarray:
    """A sequence of ids as an array: strings as objects (kept whole), else as numpy sees it."""
    a = np.asarray(s)
    return np.array(s, dtype=object) if a.dtype.kind == "U" else a


def _check_row_kinds(kind: str, row_kinds, scans) -> tuple | None:
    """``row_kinds`` as string arrays (mixed detections only)."""
    if kind != "mixed":
        if row_kinds is not None:
            raise ValueError(f"row_kinds are for mixed detections, not {kind} ones")
        return None
    if row_kinds is None:
        raise ValueError("mixed detections need row_kinds (the kind of each row)")
    row_kinds = tuple(row_kinds)
    if len(row_kinds) != len(scans):
        raise ValueError(f"{len(scans)} scans but {len(row_kinds)} row_kinds arrays")
    out = []
    for k, a in enumerate(row_kinds):
        a = np.asarray(a)
        if a.dtype == np.bool_:
            a = np.where(a, "range-bearing", "position")
        a = a.astype(_KIND_DTYPE).reshape(-1) if a.size else np.zeros(0, _KIND_DTYPE)
        bad = ~np.isin(a, KINDS)
        if bad.any():
            raise ValueError(
                f"row_kinds[{k}] holds {str(a[bad][0])!r}; expected {' or '.join(KINDS)}"
            )
        out.append(a)
    return tuple(out)


def _check_sensor_kinds(sensors, row_kinds) -> None:
    """Every sensor id's rows are of one kind."""
    first: dict[int, tuple[str, int]] = {}
    for k, (ids, kinds) in enumerate(zip(sensors, row_kinds, strict=True)):
        for sid, kind in zip(ids.tolist(), kinds.tolist(), strict=True):
            was = first.setdefault(sid, (kind, k))
            if was[0] != kind:
                raise ValueError(
                    f"sensor {sid} has {was[0]} rows (scans[{was[1]}]) and {kind} rows "
                    f"(scans[{k}]); a sensor's rows are of one kind"
                )


def _check_sensor_positions(d: Detections, scans, sensors, row_kinds) -> tuple | None:
    """:attr:`Detections.sensor_positions` as float arrays, checked."""
    if d.sensor_positions is None:
        return None
    if d.kind == "position":
        raise ValueError("sensor_positions are for range-bearing (or mixed) detections")
    positions = tuple(d.sensor_positions)
    if len(positions) != len(scans):
        raise ValueError(f"{len(scans)} scans but {len(positions)} sensor_positions arrays")
    out = []
    has: dict = {}  # sensor id → (has a position, scan index)
    for k, (p, z) in enumerate(zip(positions, scans, strict=True)):
        p = np.asarray(p, dtype=np.float64)
        if p.size == 0:
            p = p.reshape(0, 2)
        if p.shape != (z.shape[0], 2):
            raise ValueError(
                f"sensor_positions[{k}] must have shape ({z.shape[0]}, 2), got {p.shape}"
            )
        nan = np.isnan(p)
        if np.any(nan[:, 0] != nan[:, 1]) or np.any(np.isinf(p)):
            raise ValueError(f"sensor_positions[{k}]: a row has one coordinate only, or inf")
        given = ~nan[:, 0]
        if row_kinds is not None and np.any(given & (row_kinds[k] != "range-bearing")):
            raise ValueError(f"sensor_positions[{k}]: a position row has a sensor position")
        ids = sensors[k].tolist() if sensors is not None else [None] * z.shape[0]
        seen: dict = {}
        for i, sid in enumerate(ids):
            if row_kinds is not None and row_kinds[k][i] != "range-bearing":
                continue
            was = has.setdefault(sid, (bool(given[i]), k))
            if was[0] != bool(given[i]):
                raise ValueError(
                    f"sensor {sid} has rows with and without a sensor position "
                    f"(scans[{was[1]}], scans[{k}]); give it on all of a sensor's rows or none"
                )
            if given[i] and not np.array_equal(seen.setdefault(sid, p[i]), p[i]):
                raise ValueError(
                    f"sensor_positions[{k}]: sensor {sid} has two positions in one scan "
                    f"({seen[sid].tolist()} and {p[i].tolist()})"
                )
        out.append(p)
    return tuple(out)


def _check_labels(labels, scans) -> tuple | None:
    """:attr:`Detections.labels` as string arrays, one per scan, of the scans' lengths."""
    if labels is None:
        return None
    if isinstance(labels, str | np.ndarray) or not hasattr(labels, "__len__"):
        raise ValueError("labels must be a tuple of K string arrays (one per scan) or None")
    labels = tuple(labels)
    if len(labels) != len(scans):
        raise ValueError(f"{len(scans)} scans but {len(labels)} labels arrays")
    out = []
    for k, (a, z) in enumerate(zip(labels, scans, strict=True)):
        arr = string_array(a, f"labels[{k}]", ValueError)
        if arr.shape != (z.shape[0],):
            raise ValueError(f"labels[{k}] must have shape ({z.shape[0]},), got {arr.shape}")
        out.append(arr)
    return tuple(out)


def _check_velocities(velocities, scans, kind: str, dim: int) -> tuple | None:
    """:attr:`Detections.velocities` as float arrays ``(M_k, dim)``: finite or NaN."""
    if velocities is None:
        return None
    if kind != "position":
        raise ValueError(f"velocities are for position detections, not {kind} ones")
    velocities = tuple(velocities)
    if len(velocities) != len(scans):
        raise ValueError(f"{len(scans)} scans but {len(velocities)} velocities arrays")
    out = []
    for k, (v, z) in enumerate(zip(velocities, scans, strict=True)):
        a = np.asarray(v)
        if a.dtype == np.bool_ or a.dtype.kind not in "iuf" and a.size:
            raise ValueError(f"velocities[{k}] must hold real numbers, got dtype {a.dtype}")
        a = a.astype(np.float64)
        if a.size == 0:
            a = a.reshape(0, dim)
        if a.shape != (z.shape[0], dim):
            raise ValueError(
                f"velocities[{k}] must have shape ({z.shape[0]}, {dim}), got {a.shape}"
            )
        if np.any(np.isinf(a)) or (a.size and np.nanmax(np.abs(a), initial=0) > MAX_COORDINATE):
            raise ValueError(f"velocities[{k}] has an infinite or huge value (NaN = unknown)")
        out.append(a)
    return tuple(out)


def _check_geo_reference(ref, kind: str, dim: int) -> tuple | None:
    """:attr:`Detections.geo_reference` as ``(lat0, lon0, alt0)`` floats, checked."""
    if ref is None:
        return None
    if kind != "position" or dim not in (2, 3):
        raise ValueError("geo_reference is for 2-D or 3-D position detections")
    from jointtrack.io.geodetic import LocalFrame

    if isinstance(ref, str) or not hasattr(ref, "__len__") or len(ref) not in (2, 3):
        raise ValueError(f"geo_reference must be (lat0, lon0[, alt0]), got {ref!r}")
    try:
        return LocalFrame(*ref).reference
    except (TypeError, ValueError) as exc:
        raise type(exc)(f"geo_reference: {exc}") from None


def _check_geo_outliers(count, bound, geo) -> tuple[int, float | None]:
    """:attr:`Detections.geo_outliers` and :attr:`Detections.geo_outlier_bound`, checked."""
    if isinstance(count, bool | np.bool_) or not isinstance(count, numbers.Integral):
        raise TypeError(f"geo_outliers must be a count (an integer ≥ 0), got {count!r}")
    if count < 0:
        raise ValueError(f"geo_outliers must be ≥ 0, got {count!r}")
    if bound is not None:
        if isinstance(bound, bool | np.bool_) or not isinstance(bound, numbers.Real):
            raise TypeError(f"geo_outlier_bound must be metres or None, got {bound!r}")
        if not (math.isfinite(float(bound)) and float(bound) > 0):
            raise ValueError(f"geo_outlier_bound must be a positive distance, got {bound!r}")
        bound = float(bound)
    if (count or bound is not None) and geo is None:
        raise ValueError("geo_outliers and geo_outlier_bound need a geo_reference")
    if count and bound is None:
        raise ValueError("geo_outliers > 0 needs the geo_outlier_bound they lie beyond")
    return int(count), bound


def _coord_names(dim: int) -> list[str]:
    if dim <= 3:
        return ["x", "y", "z"][:dim]
    return [f"x{i}" for i in range(dim)]


def _offsets_ns(times: np.ndarray) -> list[int]:
    """Seconds → whole nanoseconds (exact for times read from timestamps)."""
    return [int(v) for v in np.rint(np.asarray(times, dtype=np.float64) * 1e9).tolist()]


# ----------------------------------------------------------------------------- reading


_VELOCITY_INPUTS = (*VELOCITY_COLUMNS, *COURSE_COLUMNS)
#: the columns read as text and parsed once empty-scan rows are set aside
_RAW_COLUMNS = ("time", "sensor", "label", *POS_COLUMNS, *RB_COLUMNS, *GEO_COLUMNS)


def _pick_detection_columns(path, names):
    """Required/optional columns of a detections file from its header: position
    (``x, y[, z]``), geodetic (``lat, lon[, alt]``, no ``x, y``), range–bearing
    (``range, bearing``), or both sets with a ``sensor`` column and no ``z``
    (mixed: each row fills one set)."""
    low = [n.lower() for n in names]
    pos = [n for n in names if n.lower() in POS_COLUMNS]
    rb = [n for n in names if n.lower() in RB_COLUMNS]
    where = tuple(c for c in SENSOR_POSITION_COLUMNS if c in low)
    if pos and rb:
        if "sensor" in low and "z" not in low:
            required = ("time", "x", "y", *RB_COLUMNS, "sensor")
            return required, (*where, "label"), "", where
        raise DetectionFileError(
            path,
            f"has both position column(s) ({', '.join(pos)}) and range-bearing column(s) "
            f"({', '.join(rb)}); a detections file holds one kind: time, x, y[, z] or "
            "time, range, bearing — or, mixing 2-D sensors of both kinds, time, sensor, "
            "x, y, range, bearing (each row fills one set)",
        )
    if rb:
        return ("time", *RB_COLUMNS), ("sensor", *where, "label"), "", where
    extra = ("sensor", "label", *_VELOCITY_INPUTS)
    if not pos and "lat" in low and "lon" in low:
        return ("time", "lat", "lon"), ("alt", *extra), "", _VELOCITY_INPUTS
    hint = (
        ""
        if pos
        else f"; or, for range-bearing detections: {', '.join(RB_COLUMNS)}; or, for WGS-84 "
        "positions: lat, lon (degrees)"
    )
    optional = ("z", *extra, *GEO_COLUMNS, *REFERENCE_COLUMNS)
    return ("time", "x", "y"), optional, hint, (*_VELOCITY_INPUTS, *REFERENCE_COLUMNS)


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


def _relative(path, err, ns: np.ndarray) -> np.ndarray:
    """Seconds since the first value of int64 nanoseconds (``err`` if their span
    overflows int64, where the differences would wrap around)."""
    problem = span_problem(ns)
    if problem is not None:
        raise err(path, problem, column="time")
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
    return _relative(path, err, ns), format_timestamp(int(ns[0]), bool(aware0))


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
        counts = raw.cast(pa.int64()).to_numpy(zero_copy_only=False)
        ns, bad = units_to_ns(counts, _UNIT_NS[t.unit])
        if bad is not None:
            raise row_error(
                err, path, f"{counts[bad]} {t.unit} since 1970 is {outside_time_range()}",
                bad, None, "time",
            )  # fmt: skip
        origin = format_timestamp(int(ns[0]), t.tz is not None) if ns.size else None
        return _relative(path, err, ns), origin
    if parquet_is_string(t):
        return _time_strings(path, err, raw.to_pylist(), None)
    raise err(
        path,
        f"has type {t}; {EXPECTED_TIMES}, or a Parquet timestamp column",
        column="time",
    )


_INT_TEXT = re.compile(r"[+-]?[0-9]+")


def _sensor_column(path, err, raw, lines) -> np.ndarray:
    """Sensor ids (labels) of the raw ``sensor`` column: int64 or strings, exactly.

    CSV cells that are all integers (``7``, ``4611686018427387905``; or
    integral numbers such as ``7.0`` up to 2^53, where floats are exact) are
    int64 ids; otherwise every cell is a string id, as written (``radar_a``).
    Parquet: an integer column gives int64 ids, a string column string ids, a
    float column int64 ids when integral and within ±2^53. Empty cells and
    nulls are errors, and so are integers beyond 64 bits.
    """
    if not isinstance(raw, list):  # a pyarrow column
        import pyarrow as pa

        parquet_nulls(path, err, raw, "sensor")
        t = raw.type
        if pa.types.is_integer(t):
            if pa.types.is_uint64(t):
                v = np.asarray(raw.to_numpy(zero_copy_only=False), dtype=np.uint64)
                big = np.flatnonzero(v > np.uint64(_INT64.max))
                if big.size:
                    i = int(big[0])
                    raise row_error(
                        err, path, f"sensor id {int(v[i])} is beyond 64-bit signed integers",
                        i, lines, "sensor",
                    )  # fmt: skip
            return np.asarray(raw.to_numpy(zero_copy_only=False)).astype(np.int64)
        if pa.types.is_floating(t):
            return _integral_floats(
                path, err, np.asarray(raw.to_numpy(zero_copy_only=False), float), lines
            )
        if parquet_is_string(t):
            return text_array(path, err, [str(v).strip() for v in raw.to_pylist()], None, "sensor")
        raise err(path, f"has type {t}; sensor ids are integers or strings", column="sensor")
    texts = [str(c).strip() for c in raw]
    for i, c in enumerate(texts):
        if not c:
            raise row_error(err, path, "empty value (a sensor id is needed)", i, lines, "sensor")
    if all(_INT_TEXT.fullmatch(c) for c in texts):
        ints = [int(c) for c in texts]
        for i, v in enumerate(ints):
            if not _INT64.min <= v <= _INT64.max:
                raise row_error(
                    err,
                    path,
                    f"sensor id {texts[i]} is beyond 64-bit integers (use a text id)",
                    i,
                    lines,
                    "sensor",
                )
        return np.array(ints, dtype=np.int64)
    if all(_is_number(c) for c in texts):  # e.g. 7.0 from a float column
        return _integral_floats(path, err, np.array(texts, dtype=np.float64), lines)
    return text_array(path, err, texts, lines, "sensor")


def _integral_floats(path, err, v: np.ndarray, lines) -> np.ndarray:
    """int64 ids from float ones: integral and within ±2^53 (where floats are exact)."""
    return check_integer(
        path,
        err,
        v,
        "sensor",
        lines,
        advice="write integer ids as integers, or use text ids",
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


def read_detections(path, *, allow_empty: bool = False, reference=None) -> Detections:
    """Read a detections file (CSV or Parquet; format in :mod:`jointtrack.io`).

    Returns a :class:`Detections`: rows grouped into scans by equal
    consecutive ``time`` values; ``kind`` is ``"range-bearing"`` when the file
    has ``range, bearing`` columns (``scans`` rows are then ``[r, θ]``), else
    ``"position"``, or ``"mixed"`` for a file with both sets and a ``sensor``
    column (rows' kinds in ``row_kinds``); ``sensor_positions`` is set when
    ``sensor_x, sensor_y`` columns are present (range-bearing and mixed
    files); ``dim`` is 3 when a ``z`` (or ``alt``) column is present, else 2;
    ``sensors`` is set when a ``sensor`` column is present, ``labels`` with a
    ``label`` column, ``velocities`` with ``vx, vy[, vz]`` or ``speed_knots,
    course_deg`` columns. With ISO-8601 timestamps in the ``time`` column,
    ``times`` are seconds since the first row's timestamp and ``time_origin``
    is that timestamp (else ``None``). A row whose only filled cell is its
    ``time`` is an empty scan.

    A file of WGS-84 positions (``lat, lon[, alt]`` columns, no ``x, y``) is
    projected into the local east-north(-up) frame about ``reference``
    (``(lat0, lon0[, alt0])``), recorded as ``geo_reference``. Without a
    reference the frame is :func:`~jointtrack.io.geodetic.data_centre`'s, the
    rule report files follow too: rows far from the data's median point are
    outliers, left out (a time whose rows are all outliers makes no scan) and
    counted in ``geo_outliers``, and the frame is the centre of the other rows'
    lat/lon bounding box, at altitude 0. A file with ``x, y`` is read as it is (``reference``
    must then be None or the file's own ``ref_lat, ref_lon[, ref_alt]``).

    A file with a header but no data rows is an error ("has no detections")
    unless ``allow_empty`` (then an empty :class:`Detections` is returned).

    Raises
    ------
    DetectionFileError
        (a ValueError) with the file, row and column of the first problem.
    ValueError, TypeError
        for a bad ``reference``.
    """
    if reference is not None:  # a bad argument is named before any file is opened
        reference = _reference_argument(reference)
    err = DetectionFileError
    path, cols, _extras, lines, n_rows = load_columns(
        path, err, (), (), parse_extras=False, pick=_pick_detection_columns, raw=_RAW_COLUMNS
    )
    if n_rows == 0 and not allow_empty:
        raise err(path, "has no detections: a header but no data rows")
    geo_in = "lat" in cols and "x" not in cols
    if "range" in cols:
        kind = "mixed" if "x" in cols else "range-bearing"
        coords = ("x", "y", *RB_COLUMNS) if kind == "mixed" else RB_COLUMNS
    else:
        kind = "position"
        coords = tuple(c for c in (GEO_COLUMNS if geo_in else POS_COLUMNS) if c in cols)
    t_all, origin = _time_column(path, err, cols["time"], lines)
    _check_time_order(path, err, t_all, origin, lines)
    # A row with nothing but its time marks an empty scan: set such rows aside, and
    # name the remaining rows by their place in the file (``err`` maps them back).
    marker = np.ones(n_rows, dtype=bool)
    for name, v in cols.items():
        if name != "time" and name not in REFERENCE_COLUMNS:  # the frame is on every row
            marker &= _empty_cells(v)
    refs = {c: cols[c] for c in REFERENCE_COLUMNS if c in cols}
    keep = np.flatnonzero(~marker)
    lines_all = lines
    if marker.any():
        cols = {k: (v if k == "time" else _take(v, keep)) for k, v in cols.items()}
        lines = None if lines is None else lines[keep]
        err = _renumbered(keep)
    t = t_all[keep]
    for c in (*coords, *(c for c in GEO_COLUMNS if c in cols and not geo_in)):
        nullable = kind == "mixed" or c not in coords
        cols[c] = _parse_coordinate(path, err, cols[c], lines, c, nullable)
    n_out, bound = 0, None
    if geo_in:
        Z, geo, outlier, bound = _project(path, err, cols, lines, reference)
        n_out = int(outlier.sum())
        cols.update(x=Z[:, 0], y=Z[:, 1], **({"z": Z[:, 2]} if Z.shape[1] == 3 else {}))
    else:
        geo = _file_reference(path, err, cols, lines, reference, refs, lines_all)
    _check_magnitudes(path, err, cols, lines)
    sensor = None
    row_rb = None
    if kind == "mixed":
        sensor = _sensor_column(path, err, cols["sensor"], lines)
        row_rb = _mixed_rows(path, err, cols, sensor, lines)
    if kind != "position":
        rb = slice(None) if row_rb is None else row_rb
        idx = np.arange(t.size)[rb]
        neg = np.flatnonzero(cols["range"][rb] < 0)
        if neg.size:
            i = int(idx[neg[0]])
            raise row_error(
                err, path, f"negative range {float(cols['range'][i])!r}", i, lines, "range"
            )
        big = np.flatnonzero(np.abs(cols["bearing"][rb]) > 2 * np.pi)
        if big.size:
            i = int(idx[big[0]])
            raise row_error(
                err,
                path,
                f"bearing {float(cols['bearing'][i])!r} is outside [-2π, 2π]; bearings are in "
                "radians (degrees? multiply by π/180)",
                i,
                lines,
                "bearing",
            )
    if sensor is None and "sensor" in cols:
        sensor = _sensor_column(path, err, cols["sensor"], lines)
    if kind == "range-bearing":
        Z = np.column_stack([cols[c] for c in RB_COLUMNS]) if t.size else np.zeros((0, 2))
    elif kind == "mixed":
        Z = np.zeros((t.size, 2))
        Z[~row_rb] = np.column_stack([cols["x"], cols["y"]])[~row_rb]
        Z[row_rb] = np.column_stack([cols[c] for c in RB_COLUMNS])[row_rb]
    else:
        names = ["x", "y"] + (["z"] if "z" in cols else [])
        Z = np.column_stack([cols[c] for c in names]) if t.size else np.zeros((0, len(names)))
    where = None
    if "sensor_x" in cols or "sensor_y" in cols:
        where = _sensor_position_rows(path, err, cols, t, sensor, row_rb, lines)
    labels = _label_column(path, err, cols["label"], lines) if "label" in cols else None
    velocities = _velocity_rows(path, err, cols, lines, Z.shape[1]) if kind == "position" else None
    if n_out:  # the outliers' rows are left out, as if the file had not held them
        inl = ~outlier
        t, Z = t[inl], Z[inl]
        sensor, labels, velocities, where = (
            None if a is None else a[inl] for a in (sensor, labels, velocities, where)
        )
    # the times of the rows kept (the outliers' times are not scans unless other rows share them)
    kept = np.sort(np.concatenate([t_all[marker], t]), kind="stable") if n_out else t_all
    # scans: one per distinct time of the file, the empty-scan rows' times included
    first = np.flatnonzero(np.r_[True, np.diff(kept) != 0]) if kept.size else np.zeros(0, int)
    scan_times = kept[first]
    group = np.searchsorted(scan_times, t).astype(np.int64)
    counts = np.bincount(group, minlength=scan_times.size)
    full = np.flatnonzero(marker)
    if full.size:
        busy = full[counts[np.searchsorted(scan_times, t_all[full])] > 0]
        if busy.size:
            raise row_error(
                DetectionFileError,
                path,
                "the row has a time but no other value (an empty scan), yet other rows at "
                "this time have detections; give the time's detections or mark it empty",
                int(busy[0]),
                lines_all,
                "time",
            )
    ends = np.cumsum(counts).astype(int)
    bounds = list(zip((ends - counts).tolist(), ends.tolist(), strict=True))

    def split(a):
        return None if a is None else tuple(a[s:e] for s, e in bounds)

    return Detections(
        times=scan_times,
        scans=split(Z),
        sensors=split(sensor),
        dim=Z.shape[1],
        source=str(path),
        kind=kind,
        time_origin=origin,
        row_kinds=split(row_rb),
        sensor_positions=split(where),
        labels=split(labels),
        velocities=split(velocities),
        geo_reference=geo,
        geo_outliers=n_out,
        geo_outlier_bound=bound,
    )


def _reference_argument(reference) -> tuple[float, float, float]:
    """``read_detections``'s ``reference`` as ``(lat0, lon0, alt0)``, checked."""
    from jointtrack.io.geodetic import LocalFrame

    sized = not isinstance(reference, str) and hasattr(reference, "__len__")
    if not sized or len(reference) not in (2, 3):
        raise ValueError(f"reference must be (lat0, lon0[, alt0]) or None, got {reference!r}")
    try:
        return LocalFrame(*reference).reference
    except (TypeError, ValueError) as exc:
        raise type(exc)(f"reference: {exc}") from None


def _empty_cells(v) -> np.ndarray:
    """Which cells of a column are empty: blank text, Parquet nulls, NaN (parsed columns)."""
    if isinstance(v, np.ndarray):
        return np.isnan(v)
    if isinstance(v, list):
        return np.array([not str(c).strip() for c in v], dtype=bool).reshape(-1)

    empty = np.asarray(v.is_null().to_numpy(zero_copy_only=False), dtype=bool)
    if parquet_is_string(v.type):
        empty |= np.array([c is not None and not c.strip() for c in v.to_pylist()], dtype=bool)
    return empty


def _take(v, idx: np.ndarray):
    """Rows ``idx`` of a column (text cells, a pyarrow column or an array)."""
    if isinstance(v, np.ndarray):
        return v[idx]
    if isinstance(v, list):
        return [v[i] for i in idx.tolist()]
    import pyarrow as pa

    return v.take(pa.array(idx, pa.int64()))


def _renumbered(rows: np.ndarray):
    """A :class:`DetectionFileError` maker for columns holding only the file's data rows
    ``rows`` (0-based): row i of them is reported as the file's data row ``rows[i] + 1``."""

    def err(path, reason, *, row=None, line=None, column=None):
        if row is not None:
            row = int(rows[row - 1]) + 1
        return DetectionFileError(path, reason, row=row, line=line, column=column)

    return err


def _parse_coordinate(path, err, raw, lines, name: str, nullable: bool) -> np.ndarray:
    """float64 values of a raw coordinate column: finite (else ``err``), or NaN where
    empty when ``nullable``."""
    if isinstance(raw, list):
        parse = strings_to_floats_nullable if nullable else strings_to_floats
        v = parse(path, err, raw, lines, name)
    else:
        parse = parquet_column_nullable if nullable else parquet_column
        v = parse(path, err, raw, name)
    bad = np.isinf(v) if nullable else ~np.isfinite(v)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise row_error(err, path, f"non-finite value {v[i]}", i, lines, name)
    return v


def _geo_rows(path, err, cols, lines, names) -> None:
    """``err`` at the first latitude outside [-90, 90] or longitude outside [-180, 360]."""
    for name, lim in zip(names, ((-90.0, 90.0), (-180.0, 360.0)), strict=False):
        v = cols[name]
        bad = np.flatnonzero((v < lim[0]) | (v > lim[1]))
        if bad.size:
            i = int(bad[0])
            raise row_error(
                err,
                path,
                f"{float(v[i])!r} is outside [{lim[0]:g}, {lim[1]:g}] degrees",
                i,
                lines,
                name,
            )


def _project(path, err, cols, lines, reference):
    """Local east-north(-up) positions of ``lat, lon[, alt]`` rows, the reference, the
    rows that are outliers (:func:`~jointtrack.io.geodetic.data_centre`; none with a
    given ``reference``: their positions are meaningless) and the outliers' bound."""
    from jointtrack.io.geodetic import LocalFrame, data_centre

    _geo_rows(path, err, cols, lines, ("lat", "lon"))
    lat, lon = cols["lat"], cols["lon"]
    alt = cols.get("alt")
    dim = 2 if alt is None else 3
    _geo_altitudes(path, err, alt, lines)  # before a wild altitude becomes a wild x
    outlier = np.zeros(lat.shape, dtype=bool)
    if not lat.size:
        return np.zeros((0, dim)), reference, outlier, None
    bound = None
    if reference is not None:
        frame = LocalFrame(*reference)
    else:
        centre = data_centre(lat, lon)
        frame, outlier, bound = centre.frame, centre.outliers, centre.bound
    Z = np.full((lat.size, dim), np.nan)
    inl = ~outlier
    if dim == 2:
        where = "the reference" if reference is not None else "the centre of the data"
        _geo_in_plane(path, err, frame, lat, lon, lines, where, skip=outlier)
    Z[inl] = frame.to_local(lat[inl], lon[inl], None if alt is None else alt[inl])
    # an outlier keeps a finite placeholder (the reference) until its row is left out
    Z[outlier] = 0.0
    return Z, frame.reference, outlier, bound


def _geo_altitudes(path, err, alt, lines) -> None:
    """``err`` at the first altitude outside :data:`~jointtrack.io.geodetic.ALT_RANGE`."""
    from jointtrack.io.geodetic import ALT_RANGE, ALT_RANGE_TEXT

    if alt is None:
        return
    bad = np.flatnonzero((alt < ALT_RANGE[0]) | (alt > ALT_RANGE[1]))
    if bad.size:
        i = int(bad[0])
        raise row_error(
            err, path, f"{float(alt[i])!r} is outside {ALT_RANGE_TEXT}", i, lines, "alt"
        )


def _geo_in_plane(path, err, frame, lat, lon, lines, where: str, skip=None) -> None:
    """``err`` at the first row (not in the mask ``skip``) beyond what ``frame``'s
    east-north plane represents (:data:`~jointtrack.io.geodetic.PLANE_MAX_ANGLE` from
    its reference)."""
    from jointtrack.io.geodetic import PLANE_MAX_ANGLE, _km

    angle = frame.plane_angle(lat, lon)
    far = np.flatnonzero((angle > PLANE_MAX_ANGLE) & (True if skip is None else ~skip))
    if far.size:
        i = int(far[0])
        raise row_error(
            err, path, f"lat, lon ({float(lat[i])!r}, {float(lon[i])!r}) is "
            f"{float(angle[i]):.1f}° from {where} (lat {frame.reference[0]:.6g}, lon "
            f"{frame.reference[1]:.6g}): the local east-north plane represents points up "
            f"to {PLANE_MAX_ANGLE:g}° ({_km(PLANE_MAX_ANGLE)}) from its reference; give a "
            "reference near the data (--reference LAT,LON) or split the data by region",
            i, lines, "lat",
        )  # fmt: skip


#: how far (metres) lat, lon may place a row from its x, y in the file's own frame: the
#: written 17-digit degrees reproduce x, y to ~1e-9 m, so this flags edited values only
_GEO_TOLERANCE = 1e-3


def _file_reference(path, err, cols, lines, reference, refs, ref_lines):
    """The ``ref_lat, ref_lon[, ref_alt]`` of an x, y file (``refs``: one value on every
    row of the file, whose lines are ``ref_lines``), with its ``lat, lon[, alt]`` checked
    against ``x, y[, z]``; ``None`` without them."""
    from jointtrack.io.geodetic import LocalFrame

    given = list(refs)
    if not given:
        if reference is not None:
            raise err(
                path,
                "has x, y positions already (no lat, lon to project) and no ref_lat, ref_lon; "
                "read it without a reference",
            )
        return None
    if given[:2] != ["ref_lat", "ref_lon"]:
        raise err(path, "has ref_alt without ref_lat, ref_lon; the reference needs both")
    values = []
    for c in given:
        v = refs[c]
        bad = np.flatnonzero(~np.isfinite(v) | (v != v[0])) if v.size else np.zeros(0, int)
        if bad.size:
            i = int(bad[0])
            raise row_error(
                DetectionFileError, path, f"{v[i]!r} differs from the reference of data row 1 "
                f"({v[0]!r}) or is not a number; the frame's reference is one point, the same "
                "on every row", i, ref_lines, c,
            )  # fmt: skip
        values.append(float(v[0]) if v.size else None)
    if not refs["ref_lat"].size:
        return reference
    try:
        frame = LocalFrame(*values)
    except (TypeError, ValueError) as exc:
        raise row_error(DetectionFileError, path, str(exc), 0, ref_lines, "ref_lat") from None
    if reference is not None and frame.reference != tuple(reference):
        raise err(
            path,
            f"has x, y in the frame about {frame.reference}, not the reference "
            f"{tuple(reference)} asked for; read it without a reference",
        )
    if "lat" in cols and "lon" in cols:
        dim = 3 if "z" in cols and "alt" in cols else 2
        _geo_rows(path, err, cols, lines, ("lat", "lon"))
        if dim == 3:
            _geo_altitudes(path, err, cols["alt"], lines)
        else:
            _geo_in_plane(path, err, frame, cols["lat"], cols["lon"], lines, "the file's reference")
        got = frame.to_local(cols["lat"], cols["lon"], cols["alt"] if dim == 3 else None)
        want = np.column_stack([cols[c] for c in ("x", "y", "z")[:dim]])
        off = np.sqrt(np.sum((got - want) ** 2, axis=1))
        bad = np.flatnonzero(~(off <= _GEO_TOLERANCE))
        if bad.size:
            i = int(bad[0])
            raise row_error(
                err, path, f"lat, lon place the row {off[i]:.6g} m from its x, y in the frame "
                f"about {frame.reference}; x, y are the positions read: fix lat, lon or drop "
                "those columns", i, lines, "lat",
            )  # fmt: skip
    return frame.reference


def _label_column(path, err, raw, lines) -> np.ndarray:
    """Labels as written (CSV text; a Parquet column's values as text, null → ""); ``err``
    at a label with a NUL character (:data:`~jointtrack.io._files.NUL_REASON`)."""
    if isinstance(raw, list):
        cells = [str(c) for c in raw]
    else:
        cells = ["" if c is None else str(c) for c in raw.to_pylist()]
    return text_array(path, err, cells, lines, "label")


def _velocity_rows(path, err, cols, lines, dim: int) -> np.ndarray | None:
    """``(N, dim)`` reported velocities (NaN unknown) from ``vx, vy[, vz]`` or from
    ``speed_knots, course_deg``; ``None`` without such columns."""
    from jointtrack.io.geodetic import KNOT, velocity_en

    have_v = [c for c in VELOCITY_COLUMNS if c in cols]
    have_c = [c for c in COURSE_COLUMNS if c in cols]
    if not have_v and not have_c:
        return None
    if have_v and have_c:
        raise err(
            path, "has both vx, vy and speed_knots, course_deg columns; give one velocity form"
        )
    for c in (*have_v, *have_c):
        inf = np.flatnonzero(np.isinf(cols[c]))
        if inf.size:
            i = int(inf[0])
            raise row_error(err, path, f"non-finite value {cols[c][i]}", i, lines, c)
    n = cols["x"].size
    V = np.full((n, dim), np.nan)
    if have_c:
        if len(have_c) != 2:
            raise err(path, f"has column {have_c[0]} but not the other of speed_knots, course_deg")
        s = cols["speed_knots"]
        neg = np.flatnonzero(s < 0)
        if neg.size:
            i = int(neg[0])
            raise row_error(err, path, f"negative speed {float(s[i])!r}", i, lines, "speed_knots")
        V[:, :2] = velocity_en(s * KNOT, cols["course_deg"])
        return V
    if have_v[:2] != ["vx", "vy"]:
        raise err(path, "velocity columns need vx and vy (and vz for 3-D positions)")
    if "vz" in cols and dim != 3:
        raise err(path, "has a vz column but 2-D positions (no z or alt)")
    for a, c in enumerate(have_v):
        V[:, a] = cols[c]
    return V


def _check_magnitudes(path, err, cols, lines) -> None:
    """``err`` at the first coordinate beyond ±:data:`MAX_COORDINATE` (NaN: an empty
    cell of a mixed file, checked elsewhere)."""
    for c in _COORDINATE_COLUMNS:
        if c not in cols:
            continue
        big = np.flatnonzero(np.abs(cols[c]) > MAX_COORDINATE)
        if big.size:
            i = int(big[0])
            raise row_error(
                err,
                path,
                f"value {float(cols[c][i])!r} is beyond ±{MAX_COORDINATE:g}: the tracker squares "
                "differences of coordinates, which would overflow; rescale the data (e.g. "
                "kilometres instead of metres)",
                i,
                lines,
                c,
            )


def _filled(path, err, cols, names, lines, what: str) -> np.ndarray:
    """Which rows fill the column set ``names`` (all cells, or none: else ``err``)."""
    vals = [cols[c] for c in names]
    given = [~np.isnan(v) for v in vals]
    for c, v in zip(names, vals, strict=True):
        inf = np.flatnonzero(np.isinf(v))
        if inf.size:
            i = int(inf[0])
            raise row_error(err, path, f"non-finite value {v[i]}", i, lines, c)
    some = np.logical_or.reduce(given)
    all_ = np.logical_and.reduce(given)
    half = np.flatnonzero(some & ~all_)
    if half.size:
        i = int(half[0])
        empty = next(c for c, g in zip(names, given, strict=True) if not g[i])
        raise row_error(
            err, path, f"empty value; {what} fills all of {', '.join(names)}", i, lines, empty
        )
    return all_


def _mixed_rows(path, err, cols, sensor, lines) -> np.ndarray:
    """Whether each row of a mixed file is range–bearing (else position), checked:
    one set filled per row, and each sensor's rows of one kind."""
    pos = _filled(path, err, cols, ("x", "y"), lines, "a position row")
    rb = _filled(path, err, cols, RB_COLUMNS, lines, "a range-bearing row")
    both = np.flatnonzero(pos & rb)
    if both.size:
        raise row_error(
            err,
            path,
            "the row fills both x, y and range, bearing; in a file mixing sensors each "
            "row fills the set of its sensor's type and leaves the other empty",
            int(both[0]),
            lines,
            "range",
        )
    neither = np.flatnonzero(~pos & ~rb)
    if neither.size:
        raise row_error(
            err,
            path,
            "empty value; the row fills neither x, y nor range, bearing (one set is needed)",
            int(neither[0]),
            lines,
            "x",
        )
    first: dict[int, int] = {}
    for i, sid in enumerate(sensor.tolist()):
        j = first.setdefault(sid, i)
        if rb[j] != rb[i]:
            kinds = ("position", "range-bearing")
            at = f"line {int(lines[j])}" if lines is not None else f"data row {j + 1}"
            raise row_error(
                err,
                path,
                f"sensor {sid} gives a {kinds[int(rb[i])]} row here but {kinds[int(rb[j])]} rows "
                f"before ({at}); a sensor's rows are all of one kind",
                i,
                lines,
                "range" if rb[i] else "x",
            )
    return rb


def _sensor_position_rows(path, err, cols, t, sensor, row_rb, lines) -> np.ndarray:
    """``(N, 2)`` per-row sensor positions (NaN where not given), checked."""
    for c in SENSOR_POSITION_COLUMNS:
        if c not in cols:
            other = next(o for o in SENSOR_POSITION_COLUMNS if o in cols)
            raise err(path, f"has column {other} but not {c}; a sensor position needs both")
    given = _filled(path, err, cols, SENSOR_POSITION_COLUMNS, lines, "a sensor position")
    P = np.column_stack([cols[c] for c in SENSOR_POSITION_COLUMNS]) if t.size else np.zeros((0, 2))
    rb = np.ones(t.size, bool) if row_rb is None else row_rb
    bad = np.flatnonzero(given & ~rb)
    if bad.size:
        raise row_error(
            err,
            path,
            "a position row has a sensor position; sensor_x, sensor_y are for "
            "range-bearing rows (leave them empty)",
            int(bad[0]),
            lines,
            "sensor_x",
        )
    ids = sensor.tolist() if sensor is not None else [None] * t.size

    def at(r: int) -> str:
        return f"line {int(lines[r])}" if lines is not None else f"data row {r + 1}"

    first: dict = {}  # sensor id → first range-bearing row
    scan: dict = {}  # (time, sensor id) → first row
    for i, sid in enumerate(ids):
        if not rb[i]:
            continue
        name = "the sensor" if sid is None else f"sensor {sid}"
        j = first.setdefault(sid, i)
        if given[j] != given[i]:
            raise row_error(
                err,
                path,
                f"{name} has a position (sensor_x, sensor_y) on some rows but not on others "
                f"({at(j)}); give it on all of the sensor's rows or none",
                i,
                lines,
                "sensor_x",
            )
        if not given[i]:
            continue
        j = scan.setdefault((float(t[i]), sid), i)
        for a, c in enumerate(SENSOR_POSITION_COLUMNS):
            if P[i, a] != P[j, a]:
                raise row_error(
                    err,
                    path,
                    f"{name} is at {c} = {float(P[j, a])!r} on {at(j)} but {float(P[i, a])!r} "
                    "here, at the same time; the rows of one (time, sensor) share its position",
                    i,
                    lines,
                    c,
                )
    return P


# ----------------------------------------------------------------------------- writing


def write_detections(detections: Detections, path) -> Path:
    """Write :class:`Detections` in the file format of :func:`read_detections`.

    Positions as ``time, x, y[, z][, sensor]``, range–bearing detections as
    ``time, range, bearing[, sensor][, sensor_x, sensor_y]``, mixed ones as
    ``time, x, y, range, bearing, sensor[, sensor_x, sensor_y]`` (the set a
    row does not fill: empty CSV cells, Parquet nulls); then ``label`` (with
    :attr:`~Detections.labels`), ``vx, vy[, vz]`` (with
    :attr:`~Detections.velocities`; unknown: empty) and, with a
    :attr:`~Detections.geo_reference`, ``lat, lon[, alt]`` of each position and
    the reference as ``ref_lat, ref_lon, ref_alt`` on every row. An empty scan
    is a row with its time and every other cell empty. With a ``time_origin``
    the ``time`` column holds ISO-8601 timestamps (CSV text; a Parquet
    ``timestamp[ns]`` column, UTC unless the origin is naive), else numbers.
    Reading the file back gives the same detections, exactly (x, y are read
    before lat, lon: see :mod:`jointtrack.io`).
    """
    if not isinstance(detections, Detections):
        raise ValueError(f"expected Detections, got {type(detections).__name__}")
    if detections.dim not in (2, 3):
        raise ValueError(f"the file format holds 2-D or 3-D detections, got dim={detections.dim}")
    path, kind = out_path(path)
    import pyarrow as pa

    table = detections.to_table()
    n_rows = table["time"].size
    # empty scans: a row with the scan's time and nothing else, at the scan's place
    counts = np.array([z.shape[0] for z in detections.scans], dtype=int)
    empty = np.flatnonzero(counts == 0)
    at = (np.cumsum(counts) - counts)[empty]
    blank = np.zeros(n_rows, dtype=bool)
    if empty.size:
        blank = np.insert(blank, at, True)
        for name, v in table.items():
            if name == "time":
                fill = detections.times[empty]
            elif v.dtype.kind == "U":
                fill = ""
            else:
                fill = 0 if v.dtype.kind in "iu" else np.nan
            table[name] = np.insert(v, at, fill)
    if detections.geo_reference is not None:  # the frame: on every row, empty scans' too
        for name, v in zip(REFERENCE_COLUMNS, detections.geo_reference, strict=True):
            table[name] = np.full(blank.size, v)
    text_cols = {}
    if detections.time_origin is not None:
        _, ns0, aware = parse_origin(detections.time_origin)
        ns = [ns0 + v for v in _offsets_ns(table["time"])]
        text = [format_timestamp(v, aware) for v in ns]
        arr = pa.array(
            np.asarray(ns, dtype=np.int64), pa.timestamp("ns", tz="UTC" if aware else None)
        )
        text_cols["time"] = (text, arr)
    for name, v in table.items():
        if name == "time":
            continue
        if v.dtype.kind == "U":
            # labels and string sensor ids: CSV text, a Parquet string column (null: empty scan)
            vals = v.tolist()
            text_cols[name] = (vals, pa.array(vals, pa.string(), mask=blank))
        elif v.dtype.kind in "iu":
            if blank.any():
                vals = ["" if b else str(int(a)) for a, b in zip(v.tolist(), blank, strict=True)]
                text_cols[name] = (vals, pa.array(v.astype(np.int64), pa.int64(), mask=blank))
        elif np.isnan(v).any():
            # a value a row does not have: an empty CSV cell, a Parquet null
            text = ["" if np.isnan(a) else repr(float(a)) for a in v.tolist()]
            text_cols[name] = (text, pa.array(v, pa.float64(), mask=np.isnan(v)))
    write_columns(path, kind, table, int_cols={"sensor"}, text_cols=text_cols)
    return path
