"""Reading detections and writing tracks and metrics (CSV, Parquet, JSON).

Detections file format
----------------------
One row per detection, as CSV (``.csv``, optionally gzip-compressed
``.csv.gz``) or Parquet (``.parquet`` / ``.pq``). A detection is either a
measured position (``x, y[, z]``):

=========  ========  ==========================================================
column     required  meaning
=========  ========  ==========================================================
``time``   yes       scan time: a number (any unit, e.g. seconds; finite)
                     or an ISO-8601 timestamp (see below)
``x``      yes       position coordinate (any unit, e.g. metres); finite
``y``      yes       position coordinate; finite
``z``      no        third coordinate; its presence makes the detections 3-D
``sensor`` no        sensor id, a label (e.g. for several radars): integers
                     (64-bit, exactly) or text such as ``radar_a``
=========  ========  ==========================================================

Optional columns of position files (:attr:`Detections.labels`,
:attr:`Detections.velocities`):

================================  =============================================
column                            meaning
================================  =============================================
``label``                         identity of the row's target as text (MMSI,
                                  icao24), read as written; empty: none
``vx, vy[, vz]``                  reported velocity (units of x per unit of
                                  time); an empty cell is unknown (NaN);
                                  ``vz`` only with ``z``
``speed_knots, course_deg``       instead of ``vx, vy``: speed over ground in
                                  knots and course in degrees clockwise from
                                  north, turned into east/north m/s
                                  (:func:`~jointtrack.io.geodetic.velocity_en`);
                                  empty: unknown
================================  =============================================

**Geodetic positions.** A file with ``lat, lon[, alt]`` columns (WGS-84
degrees; ``alt`` metres above the ellipsoid) instead of ``x, y`` is projected
into a local east-north(-up) frame in metres
(:class:`~jointtrack.io.geodetic.LocalFrame`, pymap3d): about
``read_detections(path, reference=(lat0, lon0[, alt0]))``, or by default
about the centre of the data's lat/lon bounding box (across the antimeridian
when narrower) at altitude 0. Without ``alt`` the detections are 2-D (east,
north of the point at the reference's height); with it, 3-D (east, north,
up). The reference is kept as :attr:`Detections.geo_reference`. Latitudes
outside [−90, 90] and longitudes outside [−180, 360] are errors naming the
row. Use metres-true speeds (``speed_knots``) with such files: velocities are
then m/s in the same frame.

:func:`write_detections` writes a geodetic :class:`Detections` as ``x, y[,
z]`` **and** ``lat, lon[, alt]``, with the frame in ``ref_lat, ref_lon,
ref_alt`` (the same on every row). On reading, **x, y take precedence**: they
are the detections (exact as written); the ``ref_*`` columns give
:attr:`Detections.geo_reference`, and ``lat, lon`` must then agree with ``x,
y`` within 1 mm (else an error: edit one or drop the other); without ``ref_*``
columns ``lat, lon`` beside ``x, y`` are ignored. ``reference=`` is refused
for an x, y file unless it equals the file's ``ref_*``.

**Empty scans.** A row whose only filled cell is its ``time`` (every other
column the reader uses empty; ``ref_*`` and ignored columns do not count) is a
scan with no detection; :func:`write_detections` writes empty scans so, and
reading the file back gives the same scans, empty ones included. Such a row at
a time that also has detections is an error.

or a range–bearing measurement of a 2-D sensor (``range, bearing``; track it
with ``TrackerConfig(sensor="range-bearing", sensor_position=…)``):

===========  ========  ========================================================
column       required  meaning
===========  ========  ========================================================
``time``     yes       scan time: a number or an ISO-8601 timestamp
``range``    yes       distance from the sensor (e.g. metres); finite, ≥ 0
``bearing``  yes       angle in **radians**, anticlockwise from the +x axis;
                       finite, within [−2π, 2π] (larger values are taken for
                       degrees and rejected); not wrapped on reading
``sensor``   no        sensor id: an integer or a text label
===========  ========  ========================================================

The columns decide the kind (:attr:`Detections.kind`: ``"position"`` or
``"range-bearing"``); a file with columns of neither kind is an error, and so
is one with columns of both kinds unless it is a **mixed** file: 2-D sensors
of both types in one file, columns ``time, sensor, x, y, range, bearing`` (no
``z``), each row filling the set of its sensor's type and leaving the other
empty (CSV: empty cells or ``nan``; Parquet: nulls or NaN). Each sensor id's
rows are all of one kind. Its :attr:`Detections.kind` is ``"mixed"``: scans
of ``[x, y]`` or ``[r, θ]`` rows as :attr:`Detections.row_kinds` says.

A moving range–bearing sensor gives its position per row in ``sensor_x,
sensor_y`` (range–bearing and mixed files; :attr:`Detections.sensor_positions`):
on all of a sensor's range–bearing rows or on none, the same on all rows of
one (time, sensor), empty on position rows.

* CSV: comma-separated, the first non-blank line is the header; column names
  are matched case-insensitively, surrounding spaces ignored; blank lines are
  skipped; other columns (``snr``, ``amplitude``, …) are ignored. Parquet:
  the same column names; numeric column types (or strings holding numbers);
  ``time`` may also be a Parquet ``timestamp`` column.
* Sensor ids are labels, never rounded: a CSV ``sensor`` column whose cells
  are all integers holds int64 ids (``4611686018427387905`` stays distinct
  from ``4611686018427387904``); otherwise each cell is a text id as written
  (``radar_a``). Parquet: an integer column, or a string column (text ids).
  A run's ``[sensors.ID]`` tables are matched by id (``[sensors.radar_a]``,
  ``[sensors.7]``).
* Times: numbers are used as they are (:attr:`Detections.time_origin` is
  ``None``). ISO-8601 timestamps (``2026-11-23T10:00:00.5Z``, with or without
  fraction, ``Z`` or ``±HH:MM`` offset; a space instead of ``T`` is accepted)
  or a Parquet timestamp column become **seconds since the first row's
  timestamp**, which is kept as :attr:`Detections.time_origin` (an ISO string,
  UTC ``…Z`` when the timestamps carry an offset, naive otherwise); details in
  :mod:`jointtrack.io.times`. All ``time`` values of a file are of one kind.
* Rows are in time order: ``time`` must be non-decreasing from row to row.
  Consecutive rows with the *same* time value form one scan; a scan with no
  detection is a row with only its time (above), and a file with a header
  but no rows is an error ("has no detections"; ``read_detections(…,
  allow_empty=True)`` reads it as no scans).
* Errors: every problem raises :class:`DetectionFileError` (a
  :class:`ValueError`) with a one-line message naming the file and, where
  there is one, the row — ``line L (data row R)`` for CSV (L the physical
  line, R the 1-based row after the header), ``data row R`` for Parquet —
  and the column: missing or unreadable file, unknown extension, missing
  required columns (all listed), no data rows, a non-numeric, empty, NaN or
  infinite value (for ``time``: neither a number nor an ISO-8601 timestamp —
  the message shows the cell and the accepted formats — or numbers and
  timestamps mixed), a coordinate (``x, y, z, range, sensor_x, sensor_y``)
  beyond ±10¹⁵⁰ (:data:`~jointtrack.io.detections.MAX_COORDINATE`: the
  tracker squares coordinate differences; rescale such data), an empty
  sensor id or an integer one beyond 64 bits, a row with the wrong number of
  fields, a time earlier than the row before it, position and range–bearing columns together
  (or neither) outside a mixed file, a negative range or a bearing outside
  [−2π, 2π]; in a mixed file a row filling both sets or neither (or half a
  set), a sensor whose rows change kind; a sensor position on some of a
  sensor's rows only, or differing within one (time, sensor).

Examples::

    time,x,y,sensor
    0.0,12.5,-3.0,1
    0.0,250.1,40.2,1
    1.0,13.4,-2.1,1

    time,x,y
    2026-11-23T10:00:00Z,12.5,-3.0
    2026-11-23T10:00:00.5Z,13.0,-2.6

    time,range,bearing
    0.0,1250.0,0.7854
    0.0,980.5,-2.9671
    1.0,1243.2,0.7860

Tracks file format (:func:`write_tracks`, :func:`read_tracks`)
---------------------------------------------------------------
Columns ``time, track_id, x, y[, z], vx, vy[, vz]`` (``z`` and ``vz`` together)
followed by any extra numeric columns the caller supplies, e.g. covariance
entries (``P_x_x``, ``P_x_vx``, …) or an existence probability
(``existence``). With ``write_tracks(…, frame=LocalFrame(…))`` the positions'
WGS-84 ``lat, lon[, alt]`` follow ``x, y[, z]`` (read back as extra columns).
CSV floats are written with ``repr`` (shortest round-trip), so a CSV round
trip is exact.

Self-reports (:mod:`~jointtrack.io.reports`)
--------------------------------------------
AIS and ADS-B position reports, read into :class:`Reports` (times since a UTC
origin, lat/lon, altitude, identity, speed, course): :func:`read_ais_csv`
(Stone Soup's Solent demo layout ``Time, MMSI, Latitude_degrees,
Longitude_degrees, COG_degrees, SOG_knots``), :func:`read_opensky_states`
(OpenSky state vectors), :func:`read_traffic_records` (the ``traffic``
library's JSON records, gzip or plain), :func:`read_reports` (chooses).
:meth:`Reports.degrade` (seeded drop-outs, Poisson clutter, identities
stripped), :meth:`Reports.reduce` (Stone Soup's TimeSyncFeeder +
MetadataReducer), :meth:`Reports.detections` and :meth:`Reports.truth`.

Truth file format (:func:`read_truth`, :func:`write_truth`)
-----------------------------------------------------------
Columns ``time, id, x, y[, z]``: the true position of target ``id`` at
``time``, one row per target per time, in time order; numbers or ISO-8601
timestamps, of the same kind as the detections they go with (timestamps are
measured from the detections' :attr:`Detections.time_origin`, so equal
instants give equal times). Details in :mod:`~jointtrack.io.truth`; errors
raise :class:`TruthFileError`. ``jointtrack run --detections FILE --truth
FILE`` scores the tracks with it.

Metrics (:func:`write_metrics`): a JSON object; numpy scalars and arrays,
dataclasses, tuples and paths are converted; NaN and ±inf become ``null``
(:func:`to_jsonable`, the package's one numpy-aware JSON conversion).

Modules: :mod:`~jointtrack.io.detections` (:class:`Detections`, reading and
writing detections), :mod:`~jointtrack.io.geodetic` (:class:`LocalFrame`,
WGS-84 ↔ local metres), :mod:`~jointtrack.io.reports` (AIS / ADS-B
self-reports), :mod:`~jointtrack.io.tracks` (track tables),
:mod:`~jointtrack.io.truth` (truth tables),
:mod:`~jointtrack.io.metrics` (metrics JSON), :mod:`~jointtrack.io.jsonify`
(:func:`to_jsonable`), :mod:`~jointtrack.io.times` (ISO-8601 times),
:mod:`~jointtrack.io.errors` (:class:`DataFileError` and subclasses). Every
public name is importable from :mod:`jointtrack.io`.
"""

from jointtrack.io.detections import (
    DETECTION_KINDS,
    KINDS,
    Detections,
    read_detections,
    write_detections,
)
from jointtrack.io.errors import DataFileError, DetectionFileError, TrackFileError, TruthFileError
from jointtrack.io.geodetic import FOOT, KNOT, LocalFrame, velocity_en
from jointtrack.io.jsonify import to_jsonable
from jointtrack.io.metrics import write_metrics
from jointtrack.io.reports import (
    Reports,
    read_ais_csv,
    read_opensky_states,
    read_reports,
    read_traffic_records,
)
from jointtrack.io.tracks import read_tracks, write_tracks
from jointtrack.io.truth import read_truth, write_truth

__all__ = [
    "DETECTION_KINDS",
    "DataFileError",
    "DetectionFileError",
    "Detections",
    "FOOT",
    "KINDS",
    "KNOT",
    "LocalFrame",
    "Reports",
    "TrackFileError",
    "TruthFileError",
    "read_ais_csv",
    "read_detections",
    "read_opensky_states",
    "read_reports",
    "read_tracks",
    "read_traffic_records",
    "read_truth",
    "velocity_en",
    "to_jsonable",
    "write_detections",
    "write_metrics",
    "write_tracks",
    "write_truth",
]
