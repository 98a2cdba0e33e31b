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
import numbers
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from jointtrack.io._files import load_columns, row_error, string_array
from jointtrack.io.detections import Detections
from jointtrack.io.errors import DetectionFileError
from jointtrack.io.geodetic import FOOT, KNOT, LocalFrame, velocity_en
from jointtrack.io.times import format_timestamp, parse_origin, parse_timestamp

__all__ = [
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
#: AIS "not available" codes (ITU-R M.1371-5, message 1): COG 360°, SOG 102.3 kn
_AIS_COG_UNAVAILABLE = 360.0
_AIS_SOG_UNAVAILABLE = 102.3


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
        from jointtrack.io.geodetic import _latitudes, _longitudes, _real_array

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
        alt = column(self.alt, "alt", np.nan, lambda v, m: _real_array(v, m, allow_nan=True))
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

    def frame(self, reference=None) -> LocalFrame:
        """The local frame about ``reference`` ``(lat0, lon0[, alt0])``, or (None)
        about the centre of the reports' lat/lon bounding box (:meth:`LocalFrame.centre`)
        without the 1 % most extreme reports on each side in latitude and
        longitude: one glitch (the Solent AIS file has a report at 54.8° E among
        ships near 1° W) would otherwise move the centre ~1,900 km away."""
        if reference is not None:
            if isinstance(reference, LocalFrame):
                return reference
            if isinstance(reference, str) or not hasattr(reference, "__len__"):
                raise ValueError(f"reference must be (lat0, lon0[, alt0]), got {reference!r}")
            if len(reference) not in (2, 3):
                raise ValueError(f"reference must be (lat0, lon0[, alt0]), got {reference!r}")
            return LocalFrame(*reference)
        if not len(self):
            raise ValueError("no reports: give a reference to build a frame")
        lat_lo, lat_hi = np.quantile(self.lat, [0.01, 0.99])
        lon_lo, lon_hi = np.quantile(self.lon, [0.01, 0.99])
        core = (self.lat >= lat_lo) & (self.lat <= lat_hi)
        core &= (self.lon >= lon_lo) & (self.lon <= lon_hi)
        if not core.any():  # (data across the antimeridian) the full box
            core[:] = True
        return LocalFrame.centre(self.lat[core], self.lon[core])

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
        """
        w = _rate(window, "window")
        if w <= 0:
            raise ValueError(f"window must be > 0 seconds, got {window!r}")
        w_ns = int(round(w * _NS))
        if w_ns < 1:
            raise ValueError(f"window must be at least 1 ns, got {window!r}")
        if not len(self):
            return np.zeros(0, np.int64), np.zeros(0)
        ns = _whole_ns(self.times)
        rel = ns - ns[0]
        k = -(-rel // w_ns)  # ceil: (t0 + (k-1)w, t0 + kw]
        ends = (ns[0] + np.arange(int(k[-1]) + 1, dtype=np.int64) * w_ns) / _NS
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
            return raw.cast(pa.int64()).to_numpy(zero_copy_only=False).astype(np.int64) * unit
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


def _identities(raw) -> np.ndarray:
    """Identity cells as text with surrounding spaces removed (OpenSky pads callsigns)."""
    if not isinstance(raw, list):
        raw = ["" if v is None else str(v) for v in raw.to_pylist()]
    return np.array([str(c).strip() for c in raw] or [""], dtype=str)[: len(raw)]


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
    codes — COG 360 and SOG 102.3 kn (ITU-R M.1371) — are read as unknown.
    CSV (``.csv``/``.csv.gz``) or Parquet with the same columns.

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
    _check_range(path, err, lat, lines, "latitude_degrees", -90, 90)
    _check_range(path, err, lon, lines, "longitude_degrees", -180, 360)
    cog = cols.get("cog_degrees", np.full(n, np.nan))
    sog = cols.get("sog_knots", np.full(n, np.nan))
    for name, v in (("cog_degrees", cog), ("sog_knots", sog)):
        _finite_or_nan(path, err, v, lines, name)
    _non_negative(path, err, sog, lines, "sog_knots")
    cog = np.where(cog >= _AIS_COG_UNAVAILABLE, np.nan, cog)
    sog = np.where(sog >= _AIS_SOG_UNAVAILABLE, np.nan, sog)
    return _sorted_reports(
        path,
        ns,
        lat=lat,
        lon=lon,
        identity=_identities(cols["mmsi"]),
        speed=sog * KNOT,
        course=cog,
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
    if t.size and np.abs(t).max() > 2.0**33:  # beyond year 2242: not Unix seconds
        i = int(np.flatnonzero(np.abs(t) > 2.0**33)[0])
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
        identity=_identities(cols["icao24"])[ok],
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

    The file (gzip-compressed or plain; ``.json``/``.json.gz``) is a JSON
    list of objects with ``timestamp`` (milliseconds since the Unix epoch, or
    an ISO-8601 string; no offset = UTC), ``icao24`` (the identity),
    ``latitude``, ``longitude`` (degrees), and optional ``altitude`` (feet;
    taken as metres above the ellipsoid after conversion — it is barometric in
    ADS-B), ``groundspeed`` (knots) and ``track`` (degrees). Records without a
    position (null or missing latitude/longitude) are left out and counted in
    :attr:`Reports.skipped`. Errors name the record as ``data row R`` (1-based).

    Raises
    ------
    DetectionFileError
        naming the file, record and field of the first problem.
    """
    err = DetectionFileError
    path = Path(os.fspath(path))
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise err(path, "file not found") from None
    except IsADirectoryError:
        raise err(path, "is a directory, not a file") from None
    except OSError as exc:
        raise err(path, f"cannot open file: {exc.strerror or exc}") from None
    if raw[:2] == b"\x1f\x8b":
        try:
            raw = gzip.decompress(raw)
        except (OSError, EOFError) as exc:
            raise err(path, f"cannot read gzip file: {exc}") from None
    try:
        records = json.loads(raw.decode("utf-8-sig"))
    except UnicodeDecodeError:
        raise err(path, "is not UTF-8 text (JSON)") from None
    except json.JSONDecodeError as exc:
        raise err(path, f"is not JSON: {exc.msg}", line=exc.lineno) from None
    if not isinstance(records, list):
        raise err(path, f"holds a JSON {type(records).__name__}; expected a list of records")
    n = len(records)
    bad = next((i for i, rec in enumerate(records) if type(rec) is not dict), None)
    if bad is not None:
        what = type(records[bad]).__name__
        raise err(path, f"is a JSON {what}, not an object", row=bad + 1)
    # one list per field, checked by the types present (a fast path for clean files;
    # the first bad record is found only when there is one)
    fields = {name: [rec.get(name) for rec in records] for name in ("timestamp", "icao24")}
    for name, col in fields.items():
        if any(v is None for v in col):
            i = next(i for i, v in enumerate(col) if v is None)
            raise err(path, "missing value", row=i + 1, column=name)
    ns = _record_times(path, err, fields["timestamp"])
    ident = [str(v).strip() for v in fields["icao24"]]
    vals = {
        key: _record_numbers(path, err, [rec.get(name) for rec in records], name)
        for key, name in _TRAFFIC_NUMBERS
    }
    lat, lon = vals["latitude"], vals["longitude"]
    for key, name in _TRAFFIC_NUMBERS:
        _finite_or_nan(path, err, vals[key], None, name)
    _check_range(path, err, lat, None, "latitude", -90, 90)
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
        identity=np.array(ident or [""], dtype=str)[:n][ok],
        speed=vals["gs"][ok] * KNOT,
        course=vals["track"][ok],
    )


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
        if isinstance(v, bool) or not isinstance(v, int | float):
            raise err(path, f"value {v!r} is not a number", row=i + 1, column=name)
        try:
            out[i] = float(v)
        except OverflowError:
            raise err(
                path, f"value {v!r} is beyond the float range", row=i + 1, column=name
            ) from None
    return out


def _record_times(path, err, col: list) -> np.ndarray:
    """int64 ns since the epoch of the records' timestamps."""
    if set(map(type, col)) == {int}:  # milliseconds, the traffic samples' form
        try:
            ms = np.array(col, dtype=np.int64)
        except OverflowError:
            ms = None
        if ms is not None and np.abs(ms).max() <= 2**43:
            return ms * 1_000_000
    return np.array([_record_time(path, err, v, i) for i, v in enumerate(col)], dtype=np.int64)


def _record_time(path, err, v, i: int) -> int:
    """ns since the epoch of a record's ``timestamp``: ms since the epoch, or ISO-8601 text."""
    if isinstance(v, str):
        try:
            parsed = parse_timestamp(v)
        except ValueError as exc:
            raise err(path, str(exc), row=i + 1, column="timestamp") from None
        if parsed is None:
            raise err(
                path,
                f"value {v!r} is neither milliseconds since 1970 nor an ISO-8601 timestamp",
                row=i + 1,
                column="timestamp",
            )
        return parsed[0]
    if isinstance(v, bool) or not isinstance(v, int | float) or not np.isfinite(v):
        raise err(path, f"value {v!r} is not a time", row=i + 1, column="timestamp")
    if abs(v) > 2.0**43:  # ms beyond year 2248
        raise err(
            path, f"value {v!r} is not milliseconds since 1970", row=i + 1, column="timestamp"
        )
    return int(round(v * 1_000_000))


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
            for rec in csv.reader(fh):
                if rec and any(f.strip() for f in rec):
                    return [f.strip() for f in rec]
    except (UnicodeDecodeError, csv.Error, OSError, EOFError) as exc:
        raise DetectionFileError(path, f"cannot read file: {exc}") from None
    return []
