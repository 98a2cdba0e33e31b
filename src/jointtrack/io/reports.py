"""Self-reports of real targets: AIS (ships) and ADS-B (aircraft) position reports.

A :class:`Reports` holds one row per report — time, WGS-84 latitude and
longitude, altitude, the reporter's identity (MMSI, icao24), speed and course —
read from one of three public formats:

* :func:`read_ais_csv`: the AIS CSV of Stone Soup's Solent demo
  (``Time,MMSI,Latitude_degrees,Longitude_degrees,COG_degrees,SOG_knots``;
  ``Time`` like ``2016-01-12 13:02:11.218``).
* :func:`read_opensky_states`: an OpenSky Network state-vector CSV
  (``time,icao24,lat,lon,velocity,heading,vertrate,callsign,onground,…,
  baroaltitude,geoaltitude,…``; ``time`` in Unix seconds).
* :func:`read_traffic_records`: the pandas "records" JSON of the ``traffic``
  library's sample collections (gzip-compressed or plain).

:func:`read_reports` picks the reader from the file. Every reader returns the
rows in time order (a stable sort: rows of equal time keep their file order)
with ``times`` in seconds since ``time_origin``, the earliest report's instant
in UTC. Timestamps without a UTC offset (the AIS file's) are taken as UTC.

Then :meth:`Reports.degrade` (seeded drop-outs, clutter, identities
stripped), :meth:`Reports.reduce` (Stone Soup's demo pipeline: one report per
identity per time window), and the two views a tracker run needs:
:meth:`Reports.detections` (:class:`~jointtrack.io.detections.Detections` in
a local east-north frame) and :meth:`Reports.truth` (the identities' own
positions as a truth table).

Every malformed file raises :class:`~jointtrack.io.errors.DetectionFileError`
naming the file, the row and the column.
"""

from __future__ import annotations

import gzip
import json
import math
import numbers
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from jointtrack.io._files import (
    CsvRecords,
    load_columns,
    open_input,
    row_error,
    string_array,
    text_array,
)
from jointtrack.io.detections import Detections
from jointtrack.io.errors import DetectionFileError
from jointtrack.io.geodetic import (
    ALT_RANGE,
    FOOT,
    KNOT,
    PLANE_MAX_ANGLE,
    DataCentre,
    LocalFrame,
    _km,
    data_centre,
    velocity_en,
)
from jointtrack.io.times import (
    format_timestamp,
    outside_time_range,
    parse_origin,
    parse_timestamp,
    span_problem,
    units_to_ns,
)

__all__ = [
    "MAX_JSON_BYTES",
    "MAX_WINDOW",
    "REPORT_FORMATS",
    "report_format",
    "Reports",
    "read_ais_csv",
    "read_opensky_states",
    "read_reports",
    "read_traffic_records",
]

#: the formats :func:`read_reports` knows (besides ``"auto"``)
REPORT_FORMATS = ("ais", "opensky", "traffic")

_NS = 1_000_000_000
#: AIS "not available" codes (ITU-R M.1371-5, message 1): COG 360°, SOG 102.3 kn,
#: latitude 91°, longitude 181°
_AIS_COG_UNAVAILABLE = 360.0
_AIS_SOG_UNAVAILABLE = 102.3
_AIS_LAT_UNAVAILABLE = 91.0
_AIS_LON_UNAVAILABLE = 181.0


@dataclass(frozen=True, eq=False)
class Reports:
    """Position reports of targets that report themselves (AIS, ADS-B).

    Attributes
    ----------
    times : (R,) float64 seconds since ``time_origin``, non-decreasing.
    time_origin : ISO-8601 instant of t = 0 (UTC, ``…Z``).
    lat, lon : (R,) degrees, WGS-84 (lat within [-90, 90], lon within [-180, 360]).
    alt : (R,) metres above the ellipsoid (ADS-B: geometric altitude, else
        barometric), NaN unknown. Default: all unknown.
    identity : (R,) str: the reporter (MMSI, icao24), ``""`` none (clutter,
        stripped). Default: all ``""``.
    speed : (R,) m/s over ground, ≥ 0, NaN unknown. Default: all unknown.
    course : (R,) degrees clockwise from north, NaN unknown. Default: all unknown.
    is_clutter : (R,) bool: rows added by :meth:`degrade`. Default: all False.
    source : the file read, if any.
    skipped : rows of the file left out (ADS-B states without a position).
    """

    times: np.ndarray
    time_origin: str
    lat: np.ndarray
    lon: np.ndarray
    alt: np.ndarray | None = None
    identity: np.ndarray | None = None
    speed: np.ndarray | None = None
    course: np.ndarray | None = None
    is_clutter: np.ndarray | None = None
    source: str | None = None
    skipped: int = 0

    def __post_init__(self):
        from jointtrack.io.geodetic import _altitudes, _latitudes, _longitudes, _real_array

        origin, _, _ = parse_origin(self.time_origin)
        if origin is None:
            raise ValueError("time_origin is needed (an ISO-8601 instant, e.g. 2016-01-12T13:02Z)")
        t = _real_array(self.times, "times").reshape(-1) if np.ndim(self.times) else None
        if t is None:
            raise ValueError("times must be a 1-D array")
        if t.size > 1 and np.any(np.diff(t) < 0):
            k = int(np.flatnonzero(np.diff(t) < 0)[0]) + 1
            raise ValueError(f"times must be non-decreasing: times[{k}] < times[{k - 1}]")
        n = t.size

        def column(value, name, default, check):
            if value is None:
                if default is None:
                    raise ValueError(f"{name} is needed: one value per report")
                return np.full(n, default)
            a = check(value, name)
            if a.shape != (n,):
                raise ValueError(f"{name} must have shape ({n},) like times, got {a.shape}")
            return a

        lat = column(self.lat, "lat", None, _latitudes)
        lon = column(self.lon, "lon", None, _longitudes)
        alt = column(self.alt, "alt", np.nan, lambda v, m: _altitudes(v, m, allow_nan=True))
        speed = column(self.speed, "speed", np.nan, lambda v, m: _real_array(v, m, allow_nan=True))
        if np.any(speed < 0):
            raise ValueError("speed must be ≥ 0 (or NaN: unknown)")
        course = column(
            self.course, "course", np.nan, lambda v, m: _real_array(v, m, allow_nan=True)
        )
        identity = column(self.identity, "identity", "", string_array)
        clutter = column(self.is_clutter, "is_clutter", False, _booleans)
        skipped = self.skipped
        if isinstance(skipped, bool) or not isinstance(skipped, numbers.Integral) or skipped < 0:
            raise ValueError(f"skipped must be a count ≥ 0, got {skipped!r}")
        for name, v in (
            ("times", t),
            ("time_origin", origin),
            ("lat", lat),
            ("lon", lon),
            ("alt", alt),
            ("identity", identity),
            ("speed", speed),
            ("course", course),
            ("is_clutter", clutter),
            ("skipped", int(skipped)),
        ):
            object.__setattr__(self, name, v)

    def __len__(self) -> int:
        return int(self.times.size)

    def _rows(self, rows: np.ndarray, **changes) -> Reports:
        """The reports at ``rows`` (indices, in that order), with fields replaced."""
        fields = {
            name: getattr(self, name)[rows]
            for name in ("times", "lat", "lon", "alt", "identity", "speed", "course", "is_clutter")
        }
        fields.update(changes)
        return Reports(
            time_origin=self.time_origin, source=self.source, skipped=self.skipped, **fields
        )

    def subset(self, rows) -> Reports:
        """The reports selected by ``rows``: a boolean mask of length R, or row indices
        (kept in time order). E.g. ``r.subset(r.lon < 10)`` drops a position glitch
        that would stretch the bounding box :meth:`frame` and :meth:`degrade` use."""
        a = np.asarray(rows)
        if a.dtype == np.bool_:
            if a.shape != (len(self),):
                raise ValueError(f"rows: a mask must have shape ({len(self)},), got {a.shape}")
            return self._rows(np.flatnonzero(a))
        if a.size == 0:
            return self._rows(np.zeros(0, np.int64))
        if a.dtype.kind not in "iu" or a.ndim != 1:
            raise TypeError(f"rows must be a boolean mask or integer indices, got dtype {a.dtype}")
        if a.min() < -len(self) or a.max() >= len(self):
            raise ValueError(f"rows: an index is outside 0..{len(self) - 1}")
        return self._rows(np.sort(np.mod(a, len(self)), kind="stable"))

    def centre(self) -> DataCentre:
        """:func:`~jointtrack.io.geodetic.data_centre` of the reports: the frame without
        a given reference, and the outliers (corrupt positions far from the bulk, such
        as the Solent AIS file's one report at 54.8° E among ships near 1° W, which
        would otherwise move a bounding-box centre ~1,900 km away) to leave out
        (:meth:`subset`)."""
        if not len(self):
            raise ValueError("no reports: give a reference to build a frame")
        return data_centre(self.lat, self.lon)

    def frame(self, reference=None) -> LocalFrame:
        """The local frame about ``reference`` ``(lat0, lon0[, alt0])``, or (None)
        :meth:`centre`'s: the centre of the bounding box of the reports that are not
        outliers. The outliers are not left out here (``subset(~r.centre().outliers)``).

        Raises ValueError when a report is more than
        :data:`~jointtrack.io.geodetic.PLANE_MAX_ANGLE` (60°, about 6,700 km)
        from the reference: the frame's east-north plane cannot represent it
        (:mod:`jointtrack.io.geodetic`), and tracks there would come back on the
        wrong part of the Earth.
        """
        if reference is not None:
            if isinstance(reference, LocalFrame):
                frame = reference
            elif isinstance(reference, str) or not hasattr(reference, "__len__"):
                raise ValueError(f"reference must be (lat0, lon0[, alt0]), got {reference!r}")
            elif len(reference) not in (2, 3):
                raise ValueError(f"reference must be (lat0, lon0[, alt0]), got {reference!r}")
            else:
                frame = LocalFrame(*reference)
        else:
            frame = self.centre().frame
        self._check_plane(frame, given=reference is not None)
        return frame

    def _check_plane(self, frame: LocalFrame, given: bool) -> None:
        """ValueError if a report lies beyond what ``frame``'s plane represents."""
        if not len(self):
            return
        angle = frame.plane_angle(self.lat, self.lon)
        far = angle > PLANE_MAX_ANGLE
        if not far.any():
            return
        i = int(np.argmax(angle))
        lat0, lon0, _ = frame.reference
        where = "the given reference" if given else "the centre of the reports"
        raise ValueError(
            f"{self.source or 'reports'}: {int(far.sum()):,} of {len(self):,} reports lie "
            f"more than {PLANE_MAX_ANGLE:g}° ({_km(PLANE_MAX_ANGLE)}) from {where} "
            f"(lat {lat0:.6g}, lon {lon0:.6g}), the farthest at lat {float(self.lat[i])!r}, "
            f"lon {float(self.lon[i])!r} ({float(angle[i]):.1f}° away); the east-north plane "
            "of a frame represents points up to that angle from its reference (beyond the "
            "horizon it folds the far side of the Earth onto the near side): give a "
            "reference near the reports (--reference LAT,LON; Reports.frame(reference)) or "
            "leave the far reports out (Reports.subset)"
        )

    # ------------------------------------------------------------------ degradation

    def degrade(
        self, *, p_d=1.0, clutter_rate=0.0, seed=0, strip_identities: bool = False
    ) -> Reports:
        """A degraded copy, as a non-cooperative sensor would see these targets.

        Each report is kept with probability ``p_d`` (independently); then
        Poisson clutter with ``clutter_rate`` false reports per second over the
        reports' time span (its count is Poisson with mean ``clutter_rate ×
        (t_max − t_min)``), each at a time uniform in [t_min, t_max] and a
        position uniform in degrees over the reports' latitude/longitude
        bounding box (across the antimeridian when that box is narrower). Clutter
        rows have ``is_clutter`` True, identity ``""`` and unknown altitude,
        speed and course. ``strip_identities`` blanks every identity.

        ``seed``: an integer ≥ 0 or a :class:`numpy.random.Generator` (then its
        state advances). The same seed gives the same result. Rows stay in time
        order; clutter at the time of a report comes after it.
        """
        p_d = _fraction(p_d, "p_d")
        rate = _rate(clutter_rate, "clutter_rate")
        if not isinstance(strip_identities, bool | np.bool_):
            raise TypeError(f"strip_identities must be True or False, got {strip_identities!r}")
        rng = _generator(seed)
        n = len(self)
        kept = np.flatnonzero(rng.random(n) < p_d) if p_d < 1.0 else np.arange(n)
        out = self._rows(kept)
        n_clutter = 0
        if n and rate > 0:
            t0, t1 = float(self.times.min()), float(self.times.max())
            n_clutter = int(rng.poisson(rate * (t1 - t0)))
        if n_clutter:
            lon_lo, lon_hi = _lon_box(self.lon)
            c_t = rng.uniform(t0, t1, n_clutter)
            c_lat = rng.uniform(float(self.lat.min()), float(self.lat.max()), n_clutter)
            c_lon = rng.uniform(lon_lo, lon_hi, n_clutter)
            c_lon = np.where(c_lon >= 180.0, c_lon - 360.0, c_lon) if lon_hi > 180.0 else c_lon
            times = np.concatenate([out.times, c_t])
            order = np.argsort(times, kind="stable")
            nan = np.full(n_clutter, np.nan)
            out = Reports(
                times=times[order],
                time_origin=self.time_origin,
                lat=np.concatenate([out.lat, c_lat])[order],
                lon=np.concatenate([out.lon, c_lon])[order],
                alt=np.concatenate([out.alt, nan])[order],
                identity=np.concatenate([out.identity, np.full(n_clutter, "")])[order],
                speed=np.concatenate([out.speed, nan])[order],
                course=np.concatenate([out.course, nan])[order],
                is_clutter=np.concatenate([out.is_clutter, np.ones(n_clutter, bool)])[order],
                source=self.source,
                skipped=self.skipped,
            )
        if strip_identities:
            out = out._rows(np.arange(len(out)), identity=np.full(len(out), ""))
        return out

    # ------------------------------------------------------------------ windows

    def window_index(self, window) -> tuple[np.ndarray, np.ndarray]:
        """``(k, ends)``: the time window of each report and the windows' end times.

        The windows of Stone Soup's ``TimeSyncFeeder(time_window=window)``
        (stonesoup.feeder.time): with t0 the first report's time, window 0 is
        the instant t0 alone and window k ≥ 1 is (t0 + (k−1)·w, t0 + k·w],
        yielded at its end ``ends[k] = t0 + k·w``; windows without reports
        (between the first and the last) are kept, empty. Times are compared in
        whole nanoseconds, so a report exactly on an end belongs to the window
        that ends there, as in Stone Soup (whose datetimes are exact).
        ``window`` is at most :data:`MAX_WINDOW` seconds.
        """
        w = _rate(window, "window")
        if w <= 0:
            raise ValueError(f"window must be > 0 seconds, got {window!r}")
        if w > MAX_WINDOW:
            raise ValueError(
                f"window must be at most {MAX_WINDOW:g} seconds (~31.7 years), got {window!r}: "
                "windows are counted in 64-bit nanoseconds"
            )
        w_ns = int(round(w * _NS))
        if w_ns < 1:
            raise ValueError(f"window must be at least 1 ns, got {window!r}")
        if not len(self):
            return np.zeros(0, np.int64), np.zeros(0)
        if np.abs(self.times).max() >= _MAX_NS_SECONDS:
            raise ValueError(
                f"times reach {float(np.abs(self.times).max()):g} s; windows count whole "
                f"nanoseconds in 64 bits, which hold up to {_MAX_NS_SECONDS:g} s (~292 years)"
            )
        ns = _whole_ns(self.times)
        rel = ns - ns[0]
        k = -(-rel // w_ns)  # ceil: (t0 + (k-1)w, t0 + kw]
        n_ends = int(k[-1]) + 1
        span_ns = (n_ends - 1) * w_ns
        if span_ns < 2**63 and abs(int(ns[0]) + span_ns) < 2**63:
            ends = (ns[0] + np.arange(n_ends, dtype=np.int64) * w_ns) / _NS
        else:  # the last end overflows int64: exact Python integers (few windows then),
            # rounded to float64 before the division as the int64 branch above is, so an
            # end is the same float whichever branch computes it (int / int would round once)
            ends = np.array([float(int(ns[0]) + j * w_ns) / _NS for j in range(n_ends)])
        return k.astype(np.int64), ends

    def reduce(self, window) -> Reports:
        """One report per identity per time window: Stone Soup's demo pipeline
        ``MetadataReducer(TimeSyncFeeder(reader, time_window=window), identity)``.

        In each window (:meth:`window_index`) only an identity's latest report
        survives (Stone Soup's ``MetadataReducer`` keeps the latest timestamp;
        among reports of one identity at the same latest instant, which it
        keeps depends on set order — here, the last in row order). Reports
        without an identity (``""``: clutter, stripped) are all kept. The
        surviving rows keep their own times and order.
        """
        k, _ = self.window_index(window)
        keep = np.ones(len(self), dtype=bool)
        ident = self.identity
        has = ident != ""
        # rows in order, so the last row of each (window, identity) is its latest report
        rows = np.flatnonzero(has)
        if rows.size:
            keys = np.rec.fromarrays([k[rows], ident[rows]])
            _, last = np.unique(keys[::-1], return_index=True)
            winners = rows[::-1][last]
            keep[rows] = False
            keep[winners] = True
        return self._rows(np.flatnonzero(keep))

    # ------------------------------------------------------------------ views

    def truth(self, frame=None):
        """The identities' own reports as a truth table, in ``frame``.

        Returns ``(times, truth_ids, positions, ids)``: for every report that
        is not clutter and has an identity, its time, an int64 truth id, and its
        ``(R, 2)`` east/north position in ``frame`` (a :class:`LocalFrame`, or
        None for :meth:`frame`); ``ids`` maps identity → truth id (0, 1, … in
        sorted identity order, so the ids do not depend on row order).
        """
        frame = self.frame(frame)
        rows = np.flatnonzero(~self.is_clutter & (self.identity != ""))
        names = sorted(set(self.identity[rows].tolist()))
        ids = {name: i for i, name in enumerate(names)}
        lookup = np.array(names or [""], dtype=str)
        truth_ids = np.searchsorted(lookup, self.identity[rows]).astype(np.int64)
        positions = frame.to_local(self.lat[rows], self.lon[rows])
        return self.times[rows].copy(), truth_ids, positions, ids

    def detections(
        self,
        frame=None,
        *,
        scan="report",
        labels: bool = False,
        velocities: bool = True,
        propagate: bool = False,
        excluded: DataCentre | None = None,
    ) -> Detections:
        """The reports as :class:`Detections` in a local east-north frame.

        Parameters
        ----------
        frame : :class:`LocalFrame` (or ``(lat0, lon0[, alt0])``), or None for :meth:`frame`.
        scan : ``"report"``: one scan per distinct report time; or a window in
            seconds: Stone Soup's time windows (:meth:`window_index`), one scan
            at each window's end holding its reports, empty windows included.
        labels : attach the identities as :attr:`Detections.labels`.
        velocities : attach east/north velocities from speed and course
            (:func:`velocity_en`; NaN unknown; a speed of 0 is a zero velocity
            whatever the course).
        propagate : with a window, move each report with a known velocity to
            its scan's time (dead reckoning, x + v·(t_scan − t_report)): a scan
            is taken to be at its window's end, and a ship at 10 m/s moves 600 m
            in a 60 s window. Reports without a velocity stay where they were.
        excluded : the :meth:`centre` whose outliers were left out of these reports
            (``subset``), recorded as :attr:`Detections.geo_outliers` and
            :attr:`Detections.geo_outlier_bound`; None: nothing left out.
        """
        frame = self.frame(frame)
        xy = frame.to_local(self.lat, self.lon)
        if isinstance(scan, str):
            if scan != "report":
                raise ValueError(f"scan must be 'report' or a window in seconds, got {scan!r}")
            if len(self):
                first = np.flatnonzero(np.r_[True, np.diff(self.times) != 0])
                times = self.times[first]
                group = np.cumsum(np.r_[True, np.diff(self.times) != 0]) - 1
            else:
                times, group = np.zeros(0), np.zeros(0, np.int64)
        else:
            group, times = self.window_index(scan)
        v = velocity_en(self.speed, self.course)
        v[self.speed == 0] = 0.0
        if propagate and not isinstance(scan, str) and len(self):
            lag = (times[group] - self.times)[:, None]
            xy = np.where(np.isfinite(v), xy + v * lag, xy)
        counts = np.bincount(group, minlength=times.size) if times.size else np.zeros(0, int)
        ends = np.cumsum(counts)
        bounds = list(zip((ends - counts).tolist(), ends.tolist(), strict=True))

        def split(a):
            return tuple(a[s:e] for s, e in bounds)

        vel = split(v) if velocities else None
        return Detections(
            times=times,
            scans=split(xy),
            source=self.source,
            time_origin=self.time_origin,
            labels=split(self.identity) if labels else None,
            velocities=vel,
            geo_reference=frame.reference,
            geo_outliers=0 if excluded is None else excluded.n_outliers,
            geo_outlier_bound=None if excluded is None else excluded.bound,
        )


# ----------------------------------------------------------------------------- checks


def _booleans(value, name: str) -> np.ndarray:
    a = np.asarray(value)
    if a.dtype != np.bool_ and a.size:
        raise TypeError(f"{name} must hold booleans, got dtype {a.dtype}")
    return a.astype(bool)


def _number(value, name: str) -> float:
    if isinstance(value, bool | np.bool_) or not isinstance(value, numbers.Real):
        raise TypeError(f"{name} must be a real number, got {value!r}")
    try:
        v = float(value)
    except OverflowError:
        raise ValueError(f"{name} is beyond the float range") from None
    if not np.isfinite(v):
        raise ValueError(f"{name} must be finite, got {v}")
    return v


def _fraction(value, name: str) -> float:
    v = _number(value, name)
    if not 0.0 <= v <= 1.0:
        raise ValueError(f"{name} must be within [0, 1], got {v}")
    return v


def _rate(value, name: str) -> float:
    v = _number(value, name)
    if v < 0:
        raise ValueError(f"{name} must be ≥ 0, got {v}")
    return v


def _generator(seed) -> np.random.Generator:
    if isinstance(seed, np.random.Generator):
        return seed
    if isinstance(seed, bool | np.bool_) or not isinstance(seed, numbers.Integral) or seed < 0:
        raise TypeError(f"seed must be an integer ≥ 0 or a numpy Generator, got {seed!r}")
    return np.random.default_rng(int(seed))


def _lon_box(lon: np.ndarray) -> tuple[float, float]:
    """The narrower longitude interval holding ``lon``: in [-180, 180) or in [0, 360)."""
    west = np.mod(lon + 180.0, 360.0) - 180.0
    east = np.mod(lon, 360.0)
    boxes = [(float(v.max() - v.min()), float(v.min()), float(v.max())) for v in (west, east)]
    _, lo, hi = min(boxes)
    return lo, hi


#: the longest window :meth:`Reports.window_index` takes, seconds: longer than the
#: span of any report file (and far from int64 nanoseconds' ~292 years, so that the
#: window ends, t0 + k·w, stay representable)
MAX_WINDOW = 1e9
#: |times| below this many seconds fit int64 nanoseconds
_MAX_NS_SECONDS = 2.0**63 / _NS


def _whole_ns(times: np.ndarray) -> np.ndarray:
    """Seconds → int64 nanoseconds (exact for times built from nanoseconds, up to ~100 days)."""
    return np.rint(np.asarray(times, dtype=np.float64) * _NS).astype(np.int64)


# ----------------------------------------------------------------------------- readers


def _pick(required, optional, nullable=()):
    def pick(path, names):
        return required, optional, "", nullable

    return pick


def _time_ns(path, err, raw, lines, name: str) -> np.ndarray:
    """int64 ns (UTC) of a column of ISO-8601 timestamps; naive ones are taken as UTC."""
    if not isinstance(raw, list):  # a Parquet column
        import pyarrow as pa

        if pa.types.is_timestamp(raw.type):
            from jointtrack.io._files import parquet_nulls

            parquet_nulls(path, err, raw, name)
            unit = {"s": _NS, "ms": 1_000_000, "us": 1_000, "ns": 1}[raw.type.unit]
            counts = raw.cast(pa.int64()).to_numpy(zero_copy_only=False)
            ns, bad = units_to_ns(counts, unit)
            if bad is not None:
                raise row_error(
                    err, path, f"{counts[bad]} {raw.type.unit} since 1970 is "
                    f"{outside_time_range()}", bad, None, name,
                )  # fmt: skip
            return ns
        raw = ["" if v is None else str(v) for v in raw.to_pylist()]
    out = np.empty(len(raw), dtype=np.int64)
    for i, cell in enumerate(raw):
        try:
            parsed = parse_timestamp(str(cell))
        except ValueError as exc:
            raise row_error(err, path, str(exc), i, lines, name) from None
        if parsed is None:
            what = "empty value" if not str(cell).strip() else f"value {str(cell).strip()!r}"
            raise row_error(
                err,
                path,
                f"{what} is not a timestamp (expected e.g. 2016-01-12 13:02:11.218)",
                i,
                lines,
                name,
            )
        out[i] = parsed[0]
    return out


def _identities(path, err, raw, lines, name: str) -> np.ndarray:
    """Identity cells as text with surrounding spaces removed (OpenSky pads callsigns);
    ``err`` at a cell with a NUL character (:data:`~jointtrack.io._files.NUL_REASON`)."""
    if not isinstance(raw, list):
        raw = ["" if v is None else str(v) for v in raw.to_pylist()]
    return text_array(path, err, [str(c).strip() for c in raw], lines, name)


def _check_range(path, err, v, lines, name, lo, hi) -> None:
    bad = np.flatnonzero((v < lo) | (v > hi))
    if bad.size:
        i = int(bad[0])
        raise row_error(err, path, f"{float(v[i])!r} is outside [{lo:g}, {hi:g}]", i, lines, name)


def _non_negative(path, err, v, lines, name) -> None:
    bad = np.flatnonzero(v < 0)
    if bad.size:
        i = int(bad[0])
        raise row_error(err, path, f"negative value {float(v[i])!r}", i, lines, name)


def _finite_or_nan(path, err, v, lines, name) -> None:
    bad = np.flatnonzero(np.isinf(v))
    if bad.size:
        i = int(bad[0])
        raise row_error(err, path, f"non-finite value {v[i]}", i, lines, name)


def _sorted_reports(path, ns, skipped=0, **columns) -> Reports:
    """Reports in time order (stable), ``times`` in seconds since the earliest instant."""
    problem = span_problem(ns)
    if problem is not None:  # the int64 differences below would wrap around
        raise DetectionFileError(path, problem)
    order = np.argsort(ns, kind="stable")
    ns = ns[order]
    ns0 = int(ns[0]) if ns.size else 0
    origin = format_timestamp(ns0, True)
    return Reports(
        times=(ns - ns0) / _NS,
        time_origin=origin,
        source=str(path),
        skipped=skipped,
        **{k: v[order] for k, v in columns.items()},
    )


def read_ais_csv(path) -> Reports:
    """Read AIS reports in the layout of Stone Soup's Solent demo.

    Columns (names matched case-insensitively; others ignored): ``Time``
    (ISO-8601 such as ``2016-01-12 13:02:11.218``; without an offset it is taken
    as UTC), ``MMSI`` (the identity, as text), ``Latitude_degrees``,
    ``Longitude_degrees``; optional ``COG_degrees`` (course over ground) and
    ``SOG_knots`` (speed over ground), empty = unknown. AIS's "not available"
    codes (ITU-R M.1371) — COG 360 and SOG 102.3 kn — are read as unknown;
    rows with latitude 91 or longitude 181 ("position not available") are
    left out and counted in :attr:`Reports.skipped`. CSV (``.csv``/``.csv.gz``)
    or Parquet with the same columns.

    Raises
    ------
    DetectionFileError
        naming the file, row and column of the first problem.
    """
    err = DetectionFileError
    path, cols, _, lines, n = load_columns(
        path,
        err,
        ("time", "mmsi", "latitude_degrees", "longitude_degrees"),
        ("cog_degrees", "sog_knots"),
        parse_extras=False,
        pick=_pick(
            ("time", "mmsi", "latitude_degrees", "longitude_degrees"),
            ("cog_degrees", "sog_knots"),
            ("cog_degrees", "sog_knots"),
        ),
        raw=("time", "mmsi"),
    )
    ns = _time_ns(path, err, cols["time"], lines, "time")
    lat, lon = cols["latitude_degrees"], cols["longitude_degrees"]
    # AIS's "position not available" (lat 91, lon 181): a report of nothing, left out
    ok = (lat != _AIS_LAT_UNAVAILABLE) & (lon != _AIS_LON_UNAVAILABLE)
    _check_range(path, err, np.where(ok, lat, 0.0), lines, "latitude_degrees", -90, 90)
    _check_range(path, err, np.where(ok, lon, 0.0), lines, "longitude_degrees", -180, 360)
    cog = cols.get("cog_degrees", np.full(n, np.nan))
    sog = cols.get("sog_knots", np.full(n, np.nan))
    for name, v in (("cog_degrees", cog), ("sog_knots", sog)):
        _finite_or_nan(path, err, v, lines, name)
    _non_negative(path, err, sog, lines, "sog_knots")
    cog = np.where(cog >= _AIS_COG_UNAVAILABLE, np.nan, cog)
    sog = np.where(sog >= _AIS_SOG_UNAVAILABLE, np.nan, sog)
    return _sorted_reports(
        path,
        ns[ok],
        skipped=int(n - ok.sum()),
        lat=lat[ok],
        lon=lon[ok],
        identity=_identities(path, err, cols["mmsi"], lines, "mmsi")[ok],
        speed=sog[ok] * KNOT,
        course=cog[ok],
    )


def read_opensky_states(path) -> Reports:
    """Read OpenSky Network state vectors (CSV, as in Stone Soup's OpenSky demo).

    Columns used: ``time`` (Unix seconds), ``icao24`` (the identity), ``lat``,
    ``lon`` (degrees), optional ``velocity`` (m/s over ground), ``heading``
    (degrees clockwise from north), ``geoaltitude`` and ``baroaltitude``
    (metres; the altitude is the geometric one, else the barometric one).
    Rows without a position (empty or NaN ``lat`` or ``lon``) are left out
    and counted in :attr:`Reports.skipped`. CSV or Parquet.

    Raises
    ------
    DetectionFileError
        naming the file, row and column of the first problem.
    """
    err = DetectionFileError
    optional = ("velocity", "heading", "geoaltitude", "baroaltitude")
    required = ("time", "icao24", "lat", "lon")
    path, cols, _, lines, n = load_columns(
        path,
        err,
        required,
        optional,
        parse_extras=False,
        pick=_pick(required, optional, ("lat", "lon", *optional)),
        raw=("icao24",),
    )
    t = cols["time"]
    if t.size and np.abs(t).max() > _UNIX_SECONDS_MAX:  # beyond year 2242: not Unix seconds
        i = int(np.flatnonzero(np.abs(t) > _UNIX_SECONDS_MAX)[0])
        raise row_error(err, path, f"{t[i]!r} is not a Unix time in seconds", i, lines, "time")
    lat, lon = cols["lat"], cols["lon"]
    for name in ("lat", "lon", *optional):
        if name in cols:
            _finite_or_nan(path, err, cols[name], lines, name)
    _check_range(path, err, lat, lines, "lat", -90, 90)
    _check_range(path, err, lon, lines, "lon", -180, 360)
    nan = np.full(n, np.nan)
    speed = cols.get("velocity", nan)
    _non_negative(path, err, speed, lines, "velocity")
    geo, baro = cols.get("geoaltitude", nan), cols.get("baroaltitude", nan)
    for name, v in (("geoaltitude", geo), ("baroaltitude", baro)):
        _check_range(path, err, v, lines, name, *ALT_RANGE)
    alt = np.where(np.isfinite(geo), geo, baro)
    ok = np.isfinite(lat) & np.isfinite(lon)
    ns = np.rint(t * _NS).astype(np.int64)
    return _sorted_reports(
        path,
        ns[ok],
        skipped=int(n - ok.sum()),
        lat=lat[ok],
        lon=lon[ok],
        alt=alt[ok],
        identity=_identities(path, err, cols["icao24"], lines, "icao24")[ok],
        speed=speed[ok],
        course=cols.get("heading", nan)[ok],
    )


#: (key in the reader's arrays, record field) of the numeric fields of a traffic record
_TRAFFIC_NUMBERS = (
    ("latitude", "latitude"),
    ("longitude", "longitude"),
    ("altitude", "altitude"),
    ("gs", "groundspeed"),
    ("track", "track"),
)


def read_traffic_records(path) -> Reports:
    """Read ADS-B points in the ``traffic`` library's pandas "records" JSON.

    The file (gzip-compressed or plain; ``.json``/``.json.gz``; at most
    :data:`MAX_JSON_BYTES` once decompressed) is a JSON list of objects with
    ``timestamp`` (Unix time — seconds or milliseconds, told apart by
    magnitude: see below — or an ISO-8601 string; no offset = UTC),
    ``icao24`` (the identity: text, the hex address), ``latitude``,
    ``longitude`` (degrees), and optional ``altitude`` (feet; taken as metres
    above the ellipsoid after conversion — it is barometric in ADS-B),
    ``groundspeed`` (knots) and ``track`` (degrees). Records without a
    position (null or missing latitude/longitude) are left out and counted in
    :attr:`Reports.skipped`. Errors name the record as ``data row R`` (1-based).

    A numeric ``timestamp`` of magnitude up to 2^33 is seconds since 1970 (as
    milliseconds it would be within 100 days of 1970-01-01, decades before
    ADS-B; as seconds it reaches the year 2242) and a larger one milliseconds
    (as seconds it would be after 2242), up to 2^43 ms (the year 2248); each
    value is read exactly, to the nanosecond.

    Raises
    ------
    DetectionFileError
        naming the file, record and field of the first problem.
    """
    err = DetectionFileError
    path = Path(os.fspath(path))
    raw = _json_bytes(path, err)
    try:
        records = json.loads(raw.decode("utf-8-sig"), parse_int=_json_int)
    except UnicodeDecodeError:
        raise err(path, "is not UTF-8 text (JSON)") from None
    except json.JSONDecodeError as exc:
        raise err(path, f"is not JSON: {exc.msg}", line=exc.lineno) from None
    except RecursionError:
        raise err(
            path, "nests JSON arrays/objects too deeply to read; expected a list of records"
        ) from None
    except MemoryError:
        raise err(path, "holds more JSON than fits in memory") from None
    if not isinstance(records, list):
        raise err(path, f"holds a JSON {_json_kind(records)}; expected a list of records")
    n = len(records)
    bad = next((i for i, rec in enumerate(records) if type(rec) is not dict), None)
    if bad is not None:
        raise err(path, f"is a JSON {_json_kind(records[bad])}, not an object", row=bad + 1)
    # one list per field, checked by the types present (a fast path for clean files;
    # the first bad record is found only when there is one)
    fields = {name: [rec.get(name) for rec in records] for name in ("timestamp", "icao24")}
    for name, col in fields.items():
        if any(v is None for v in col):
            i = next(i for i, v in enumerate(col) if v is None)
            raise err(path, "missing value", row=i + 1, column=name)
    ns = _record_times(path, err, fields["timestamp"])
    ident = _record_identities(path, err, fields["icao24"])
    vals = {
        key: _record_numbers(path, err, [rec.get(name) for rec in records], name)
        for key, name in _TRAFFIC_NUMBERS
    }
    lat, lon = vals["latitude"], vals["longitude"]
    for key, name in _TRAFFIC_NUMBERS:
        _finite_or_nan(path, err, vals[key], None, name)
    _check_range(path, err, lat, None, "latitude", -90, 90)
    _check_range(path, err, vals["altitude"], None, "altitude", *(a / FOOT for a in ALT_RANGE))
    _check_range(path, err, lon, None, "longitude", -180, 360)
    _non_negative(path, err, vals["gs"], None, "groundspeed")
    ok = np.isfinite(lat) & np.isfinite(lon)
    return _sorted_reports(
        path,
        ns[ok],
        skipped=int(n - ok.sum()),
        lat=lat[ok],
        lon=lon[ok],
        alt=vals["altitude"][ok] * FOOT,
        identity=ident[ok],
        speed=vals["gs"][ok] * KNOT,
        course=vals["track"][ok],
    )


#: the most bytes a JSON records file may hold once decompressed (256 MiB): the JSON
#: is parsed whole, and its Python objects take several times more memory than its
#: text; a file over the limit (such as a small gzip that inflates to gigabytes) is
#: refused after reading at most this much plus one block
MAX_JSON_BYTES = 256 * 2**20
#: the blocks a JSON file is read (and inflated) in
_JSON_BLOCK = 2**20


def _json_bytes(path: Path, err) -> bytes:
    """The bytes of a JSON file, inflated if it is gzip, refused past :data:`MAX_JSON_BYTES`."""
    import zlib

    fh = open_input(path, err, lambda: open(path, "rb"))  # closed below, after the gzip reader
    limit = MAX_JSON_BYTES
    with fh:
        zipped = fh.read(2) == b"\x1f\x8b"
        fh.seek(0)
        source = gzip.GzipFile(fileobj=fh, mode="rb") if zipped else fh
        blocks, size = [], 0
        try:
            while size <= limit:
                block = source.read(_JSON_BLOCK)
                if not block:
                    break
                blocks.append(block)
                size += len(block)
        except (OSError, EOFError, zlib.error) as exc:
            what = "gzip file" if zipped else "file"
            raise err(path, f"cannot read {what}: {exc}") from None
    if size > limit:
        what = "inflates to more than" if zipped else "holds more than"
        raise err(
            path,
            f"{what} {limit:,} bytes ({limit / 2**20:g} MiB), the most JSON read "
            "(jointtrack.io.reports.MAX_JSON_BYTES): it is parsed whole in memory",
        )
    return b"".join(blocks)


class _HugeInt(str):
    """A JSON integer too long for ``int`` (Python refuses over 4,300 digits), kept as
    its text so that the field's check names the record."""


def _json_int(text: str):
    # no float holds more than 309 digits: longer integers are refused by the field's
    # check, which names the record (int() would raise past 4,300 digits, unnamed)
    return _HugeInt(text) if len(text) > 400 else int(text)


def _json_kind(v) -> str:
    """The JSON name of a parsed value's type."""
    if isinstance(v, _HugeInt):
        return "number"
    kinds = {dict: "object", list: "array", str: "string", bool: "boolean", type(None): "null"}
    return kinds.get(type(v), "number")


def _show(v) -> str:
    """``repr`` of a record value, long ones shortened (a 5,000-digit number)."""
    text = str(v) if isinstance(v, _HugeInt) else repr(v)
    return text if len(text) <= 60 else f"{text[:24]}…{text[-8:]} ({len(text):,} characters)"


def _record_identities(path, err, col: list) -> np.ndarray:
    """The ``icao24`` texts, stripped; ``err`` at the first that is not a JSON string
    (a number would have lost the hex address's leading zeros; objects and lists are
    not addresses) or holds a NUL character."""
    bad = next((i for i, v in enumerate(col) if type(v) is not str), None)
    if bad is not None:
        v = col[bad]
        raise err(
            path,
            f"value {_show(v)} is a JSON {_json_kind(v)}; icao24 must be a string, the hex "
            'address (e.g. "3c4591"): a number loses leading zeros',
            row=bad + 1,
            column="icao24",
        )
    return text_array(path, err, [v.strip() for v in col], None, "icao24")


def _record_numbers(path, err, col: list, name: str) -> np.ndarray:
    """float64 values of a record field (None: NaN); ``err`` at the first non-number."""
    if set(map(type, col)) <= {int, float, type(None)}:
        try:
            return np.array(col, dtype=np.float64)  # None → NaN
        except OverflowError:
            pass
    out = np.full(len(col), np.nan)
    for i, v in enumerate(col):
        if v is None:
            continue
        if isinstance(v, _HugeInt):
            raise err(path, f"value {_show(v)} is beyond the float range", row=i + 1, column=name)
        if isinstance(v, bool) or not isinstance(v, int | float):
            raise err(path, f"value {_show(v)} is not a number", row=i + 1, column=name)
        try:
            out[i] = float(v)
        except OverflowError:
            raise err(
                path, f"value {_show(v)} is beyond the float range", row=i + 1, column=name
            ) from None
    return out


#: a numeric timestamp up to this magnitude is Unix seconds (2^33 s: the year 2242;
#: as milliseconds it would be within 100 days of 1970-01-01), above it milliseconds
_UNIX_SECONDS_MAX = 2**33
#: ... up to this many milliseconds (the year 2248; in nanoseconds within int64)
_UNIX_MS_MAX = 2**43


def _record_times(path, err, col: list) -> np.ndarray:
    """int64 ns since the epoch of the records' timestamps (see :func:`read_traffic_records`)."""
    if set(map(type, col)) == {int}:  # the traffic samples' form: a fast path
        try:
            v = np.array(col, dtype=np.int64)
        except OverflowError:
            v = None
        if v is not None and not np.any((v > _UNIX_MS_MAX) | (v < -_UNIX_MS_MAX)):
            seconds = (v >= -_UNIX_SECONDS_MAX) & (v <= _UNIX_SECONDS_MAX)
            return np.where(seconds, v * _NS, v * 1_000_000)
    return np.array([_record_time(path, err, v, i) for i, v in enumerate(col)], dtype=np.int64)


def _record_time(path, err, v, i: int) -> int:
    """ns since the epoch of a record's ``timestamp``: Unix seconds or milliseconds
    (by magnitude), or ISO-8601 text."""
    from fractions import Fraction

    def bad(reason):
        return err(path, reason, row=i + 1, column="timestamp")

    if isinstance(v, _HugeInt):
        raise bad(f"value {_show(v)} is {_UNIX_RANGE}")
    if isinstance(v, str):
        try:
            parsed = parse_timestamp(v)
        except ValueError as exc:
            raise bad(str(exc)) from None
        if parsed is None:
            raise bad(
                f"value {_show(v)} is neither a Unix time (seconds or milliseconds) nor an "
                "ISO-8601 timestamp"
            )
        return parsed[0]
    if isinstance(v, bool) or not isinstance(v, int | float):
        raise bad(f"value {_show(v)} (a JSON {_json_kind(v)}) is not a time")
    if isinstance(v, float) and not math.isfinite(v):
        raise bad(f"value {v!r} is not a time")
    if abs(v) > _UNIX_MS_MAX:  # compared as Python numbers: 10**30 stays exact
        raise bad(f"value {_show(v)} is {_UNIX_RANGE}")
    unit = _NS if abs(v) <= _UNIX_SECONDS_MAX else 1_000_000
    return round(Fraction(v) * unit)  # exact: a float's binary value, to the nearest ns


_UNIX_RANGE = (
    "outside the Unix times read: seconds up to ±2^33 (the year 2242) or milliseconds up "
    "to ±2^43 (the year 2248) since 1970"
)


def read_reports(path, format: str = "auto") -> Reports:  # noqa: A002 - the documented name
    """Read self-reports with the reader for ``format``: ``"ais"``
    (:func:`read_ais_csv`), ``"opensky"`` (:func:`read_opensky_states`),
    ``"traffic"`` (:func:`read_traffic_records`) or ``"auto"``: ``.json`` /
    ``.json.gz`` files are traffic records; for CSV the header decides (an
    ``MMSI`` column: AIS; ``icao24`` with ``lat``, ``lon``: OpenSky)."""
    if format not in ("auto", *REPORT_FORMATS):
        raise ValueError(
            f"format must be 'auto' or one of {', '.join(REPORT_FORMATS)}, got {format!r}"
        )
    readers = {"ais": read_ais_csv, "opensky": read_opensky_states, "traffic": read_traffic_records}
    if format == "auto":
        format = report_format(path)  # noqa: A001
        if format is None:
            p = Path(os.fspath(path))
            raise DetectionFileError(
                p,
                "is not a known report format: expected an AIS CSV (Time, MMSI, "
                "Latitude_degrees, Longitude_degrees, …), OpenSky states (time, icao24, lat, "
                "lon, …) or traffic records (.json / .json.gz); found columns: "
                f"{', '.join(_header(p)) or 'none'}",
            )
    return readers[format](path)


def report_format(path) -> str | None:
    """The report format of a file (``"ais"``, ``"opensky"``, ``"traffic"``), or None.

    ``.json`` / ``.json.gz`` files are traffic records; for CSV or Parquet the
    header decides (an ``MMSI`` column: AIS; ``icao24`` with ``lat``, ``lon``:
    OpenSky). Only the header is read; a missing file raises DetectionFileError.
    """
    p = Path(os.fspath(path))
    if p.name.lower().endswith((".json", ".json.gz")):
        return "traffic"
    low = {h.strip().lower() for h in _header(p)}
    if "mmsi" in low:
        return "ais"
    if {"icao24", "lat", "lon"} <= low:
        return "opensky"
    return None


def _header(p: Path) -> list[str]:
    from jointtrack.io._files import file_kind, parquet_table

    if file_kind(p, DetectionFileError) == "csv":
        return _csv_header(p)
    header, _, _ = parquet_table(p, DetectionFileError)
    return list(header)


def _csv_header(path: Path) -> list[str]:
    """The first non-blank line of a CSV file, split (only it is read)."""
    import csv

    try:
        fh = (
            gzip.open(path, "rt", newline="", encoding="utf-8-sig")
            if path.name.lower().endswith(".gz")
            else open(path, newline="", encoding="utf-8-sig")  # noqa: SIM115
        )
    except FileNotFoundError:
        raise DetectionFileError(path, "file not found") from None
    except OSError as exc:
        raise DetectionFileError(path, f"cannot open file: {exc.strerror or exc}") from None
    try:
        with fh:
            for rec in CsvRecords(fh):  # blank lines before the header skipped in bulk
                return [f.strip() for f in rec]
    except (UnicodeDecodeError, csv.Error, OSError, EOFError) as exc:
        raise DetectionFileError(path, f"cannot read file: {exc}") from None
    return []
