"""Geodetic positions (WGS-84 latitude, longitude, altitude) and a local east-north-up frame.

Real sensors (AIS, ADS-B) report degrees; the trackers work in metres. A
:class:`LocalFrame` is the east/north(/up) tangent frame at a reference point
(lat0, lon0, alt0); the conversions are pymap3d's ``geodetic2enu`` and
``enu2geodetic`` on the WGS-84 ellipsoid (no geodesy is written here).

Two projections:

* 3-D, ``to_local(lat, lon, alt)`` → ``(R, 3)`` E, N, U: the exact ENU
  coordinates; ``to_geodetic`` of them gives (lat, lon, alt) back.
* 2-D, ``to_local(lat, lon)`` → ``(R, 2)`` E, N of the point at height
  ``alt0`` (its own altitude is ignored): the orthographic projection of the
  surface at ``alt0`` onto the tangent plane. ``to_geodetic`` of ``(R, 2)``
  inverts it exactly — it finds the up coordinate at which that point lies at
  height ``alt0`` by Newton's method on pymap3d's inverse, iterated until the
  step is below :data:`NEWTON_TOLERANCE` (an error if it is not) — so a 2-D
  round trip is exact to about 1e-8 m, not just to the curvature drop (≈ 8 m
  at 10 km from the reference).

The plane holds only part of the Earth. The orthographic projection folds the
far hemisphere onto the near one (the antipode lands on the reference), and
towards the horizon it squeezes ground distances along the line of sight by
cos θ, θ the angle between the point's vertical and the reference's; a plane
error δ (a track's estimate, rounding) is δ / cos θ on the ground. Measured
(``benchmarks/io_issue31.py plane``; ``benchmarks/RESULTS.md``, issue 31): the
round trip stays below 2e-8 m up to θ = 80° and grows as 1 / cos θ (1.6e-6 m
at 89.9°), while the old 8 fixed steps were off by 2e-5 m at θ = 20°, 53 m at
45° and 6 km at 60°. So a 2-D frame represents the points within :data:`PLANE_MAX_ANGLE`
(60°, about 6,700 km) of its reference: there cos θ ≥ 1/2, ground lengths
shrink at most by half and plane errors at most double. ``to_local`` refuses
points beyond, and ``to_geodetic`` plane points whose ground point lies
beyond (or that no point projects to, such as 1e8 m east). The 3-D east,
north, up coordinates are exact everywhere and have no such limit.

Without a given reference the frame is centred on the data by :func:`data_centre`,
one rule for every geodetic input (detection files with ``lat, lon`` columns and
report files): reports far from the bulk of the data — a corrupt position such as
the Solent AIS file's one report at 54.8° E among ships near 1° W — are outliers,
left out and counted, and the frame is the centre of the bounding box of the rest.

Altitudes (``alt0``, ``alt``) are within :data:`ALT_RANGE`, metres.

Units: :data:`KNOT` (m/s) and :data:`FOOT` (m) are exact by definition.
"""

from __future__ import annotations

import numbers
from dataclasses import dataclass

import numpy as np

__all__ = [
    "ALT_RANGE",
    "FOOT",
    "GEO_COLUMNS",
    "KNOT",
    "LocalFrame",
    "NEWTON_TOLERANCE",
    "OUTLIER_MEDIANS",
    "OUTLIER_MIN_DISTANCE",
    "PLANE_MAX_ANGLE",
    "DataCentre",
    "data_centre",
    "velocity_en",
]

#: the names of WGS-84 columns in the package's files: degrees, degrees, metres
GEO_COLUMNS = ("lat", "lon", "alt")

#: one knot in metres per second (the international nautical mile, 1852 m, per hour)
KNOT = 1852.0 / 3600.0
#: one international foot in metres
FOOT = 0.3048

#: the largest angle (degrees) between a point's vertical and the reference's that a
#: 2-D frame represents: cos 60° = 1/2, so ground lengths shrink at most by half in the
#: plane (the orthographic projection's radial scale is cos θ) and a plane error at
#: most doubles on the ground; beyond the horizon (90°) the plane folds the far side
#: of the Earth onto the near side
PLANE_MAX_ANGLE = 60.0
#: mean Earth radius (m, IUGG), only to state angles as approximate distances
_EARTH_RADIUS = 6_371_008.8
#: :func:`data_centre`: a report is an outlier when it is farther from the data's
#: median point than this many times the median distance of the reports from it ...
OUTLIER_MEDIANS = 10.0
#: ... and farther than this (metres along the surface, roughly): a single AIS
#: receiver hears ships up to ~75 km away and an ADS-B receiver aircraft up to
#: ~450 km, so no report of one receiver's area is an outlier, whatever the
#: median (a port's moored ships 2 km from the median point, one ship 100 km out)
OUTLIER_MIN_DISTANCE = 500_000.0
#: Newton's method in ``to_geodetic`` stops once every step is below this (metres)
NEWTON_TOLERANCE = 1e-7
#: ... or fails after this many steps (it converges quadratically: 5 or 6 suffice at 60°)
_NEWTON_STEPS = 40
#: altitudes (m above the WGS-84 ellipsoid) a frame takes: 1,000 km below (far below
#: any ocean floor or mine, and far from the Earth's centre, where geodetic heights stop
#: being unique) to 100,000 km above (beyond geostationary orbit); values such as
#: 1e300 m are no positions near the Earth and would overflow the east/north coordinates
ALT_RANGE = (-1.0e6, 1.0e8)
#: ALT_RANGE in words, for messages
ALT_RANGE_TEXT = (
    f"[{ALT_RANGE[0]:g}, {ALT_RANGE[1]:g}] metres (1,000 km below to 100,000 km above "
    "the WGS-84 ellipsoid)"
)


def _real_array(value, name: str, *, allow_nan: bool = False) -> np.ndarray:
    """``value`` (a real number or array of them) as float64, else a ValueError/TypeError
    naming ``name``: bools, complex numbers, text and huge integers are refused."""
    if isinstance(value, bool | np.bool_):
        raise TypeError(f"{name} must be a real number, got the bool {value!r}")
    if isinstance(value, str | bytes):
        raise TypeError(f"{name} must be a real number, got the text {value!r}")
    if isinstance(value, numbers.Number) and not isinstance(value, numbers.Real):
        raise TypeError(f"{name} must be a real number, got the complex {value!r}")
    if isinstance(value, list | tuple):
        # numpy would turn True into 1.0 and "1" into 1.0 silently: look at the items
        try:
            items = np.array(value, dtype=object).reshape(-1).tolist()
        except ValueError:
            raise ValueError(f"{name} must be a regular array of numbers") from None
        for v in items:
            if isinstance(v, bool | np.bool_ | str | bytes) or not isinstance(v, numbers.Real):
                raise TypeError(f"{name} must hold real numbers, got {v!r}")
    a = np.asarray(value)
    if a.dtype == np.bool_:
        raise TypeError(f"{name} must hold real numbers, got booleans")
    if a.dtype.kind == "c":
        raise TypeError(f"{name} must hold real numbers, got complex values")
    if a.dtype.kind in "USO":
        items = a.reshape(-1).tolist()
        bad = next(
            (
                v
                for v in items
                if isinstance(v, bool | str | bytes) or not isinstance(v, numbers.Real)
            ),
            None,
        )
        if bad is not None or a.dtype.kind in "US":
            raise TypeError(f"{name} must hold real numbers, got {bad!r}")
        try:
            a = np.array(items, dtype=np.float64).reshape(a.shape)
        except OverflowError:
            raise ValueError(f"{name} holds an integer beyond the float range") from None
    if a.dtype.kind not in "iuf":
        raise TypeError(f"{name} must hold real numbers, got dtype {a.dtype}")
    a = a.astype(np.float64)
    bad = np.isinf(a) if allow_nan else ~np.isfinite(a)
    if bad.any():
        raise ValueError(f"{name} must be finite, got {a[bad].reshape(-1)[0]}")
    return a


def _altitudes(alt, name: str = "alt", *, allow_nan: bool = False) -> np.ndarray:
    """``alt`` as float64 metres within :data:`ALT_RANGE` (NaN passes when ``allow_nan``)."""
    a = _real_array(alt, name, allow_nan=allow_nan)
    bad = (a < ALT_RANGE[0]) | (a > ALT_RANGE[1])
    if bad.any():
        raise ValueError(
            f"{name} must be within {ALT_RANGE_TEXT}, got {float(a[bad].reshape(-1)[0])!r}"
        )
    return a


def _km(angle_deg: float) -> str:
    """An angle at the Earth's centre as an approximate distance, e.g. "about 6,672 km"."""
    return f"about {np.deg2rad(angle_deg) * _EARTH_RADIUS / 1000:,.0f} km"


def _latitudes(lat, name: str = "lat") -> np.ndarray:
    a = _real_array(lat, name)
    if a.size and np.abs(a).max() > 90:
        raise ValueError(f"{name} must be within [-90, 90] degrees, got {a[np.abs(a) > 90][0]}")
    return a


def _longitudes(lon, name: str = "lon") -> np.ndarray:
    a = _real_array(lon, name)
    bad = (a < -180) | (a > 360)
    if bad.any():
        raise ValueError(f"{name} must be within [-180, 360] degrees, got {a[bad][0]}")
    return a


class LocalFrame:
    """East-north(-up) metres about a WGS-84 reference point.

    Parameters
    ----------
    lat0, lon0 : reference latitude and longitude, degrees (lat0 within
        [-90, 90], lon0 within [-180, 360]).
    alt0 : reference altitude, metres above the ellipsoid (default 0).

    Examples
    --------
    >>> f = LocalFrame(50.0, -1.0)
    >>> xy = f.to_local([50.0, 50.01], [-1.0, -1.0])
    >>> [round(float(v), 3) for v in xy[:, 1]]
    [0.0, 1112.292]
    """

    __slots__ = ("_lat0", "_lon0", "_alt0")

    def __init__(self, lat0, lon0, alt0=0.0):
        for name, v in (("lat0", lat0), ("lon0", lon0), ("alt0", alt0)):
            if np.ndim(v) != 0:
                raise ValueError(f"{name} must be one number, got shape {np.shape(v)}")
        self._lat0 = float(_latitudes(lat0, "lat0"))
        self._lon0 = float(_longitudes(lon0, "lon0"))
        self._alt0 = float(_altitudes(alt0, "alt0"))

    @property
    def reference(self) -> tuple[float, float, float]:
        """``(lat0, lon0, alt0)``: degrees, degrees, metres."""
        return self._lat0, self._lon0, self._alt0

    def __repr__(self) -> str:
        return f"LocalFrame({self._lat0!r}, {self._lon0!r}, {self._alt0!r})"

    def __eq__(self, other) -> bool:
        return isinstance(other, LocalFrame) and self.reference == other.reference

    def __hash__(self) -> int:
        return hash(self.reference)

    @classmethod
    def centre(cls, lat, lon, alt0=0.0) -> LocalFrame:
        """The frame at the centre of the data's latitude/longitude bounding box.

        Longitudes are taken modulo 360 and the box is the narrower of the one
        in [-180, 180) and the one in [0, 360), so data straddling the
        antimeridian (179.9°, -179.9°) is centred on 180°, not on 0°. The
        centre's longitude is given in [-180, 180).
        """
        la, lo = _lat_lon_to_centre(lat, lon)
        west = np.mod(lo + 180.0, 360.0) - 180.0  # [-180, 180)
        east = np.mod(lo, 360.0)  # [0, 360)
        mids = []
        for v in (west, east):
            lo_min, lo_max = float(v.min()), float(v.max())
            mids.append((lo_max - lo_min, 0.5 * (lo_min + lo_max)))
        width, mid = min(mids)
        mid = float(np.mod(mid + 180.0, 360.0) - 180.0)
        return cls(0.5 * (float(la.min()) + float(la.max())), mid, alt0)

    def to_local(self, lat, lon, alt=None) -> np.ndarray:
        """``(R, 2)`` east, north metres (``alt`` None: points at height ``alt0``),
        or ``(R, 3)`` east, north, up metres (``alt`` given, metres)."""
        import pymap3d

        la = _latitudes(lat).reshape(-1)
        lo = _longitudes(lon).reshape(-1)
        if la.shape != lo.shape:
            raise ValueError(f"lat and lon must have one shape, got {la.shape} and {lo.shape}")
        if alt is None:
            h = np.full(la.shape, self._alt0)
        else:
            h = _altitudes(alt, "alt").reshape(-1)
            if h.shape != la.shape:
                raise ValueError(f"alt must have the shape of lat, {la.shape}, got {h.shape}")
        if not la.size:
            return np.zeros((0, 2 if alt is None else 3))
        if alt is None:
            angle = self.plane_angle(la, lo)
            far = np.flatnonzero(angle > PLANE_MAX_ANGLE)
            if far.size:
                i = int(far[0])
                raise ValueError(
                    f"lat, lon [{i}] = ({float(la[i])!r}, {float(lo[i])!r}) is {angle[i]:.1f}° "
                    f"({_km(angle[i])}) from the frame's reference ({self._lat0!r}, "
                    f"{self._lon0!r}): {self._plane_limit()}; choose a reference nearer the "
                    "points"
                )
        e, n, u = pymap3d.geodetic2enu(la, lo, h, self._lat0, self._lon0, self._alt0)
        cols = [e, n] if alt is None else [e, n, u]
        return np.column_stack([np.asarray(c, dtype=np.float64).reshape(-1) for c in cols])

    def plane_angle(self, lat, lon) -> np.ndarray:
        """Degrees between each point's vertical (the WGS-84 ellipsoid normal) and the
        reference's: a 2-D frame represents the points up to :data:`PLANE_MAX_ANGLE`.
        Times the Earth's radius it is roughly the distance from the reference."""
        la = np.deg2rad(_latitudes(lat).reshape(-1))
        lo = _longitudes(lon).reshape(-1)
        if la.shape != lo.shape:
            raise ValueError(f"lat and lon must have one shape, got {la.shape} and {lo.shape}")
        return self._angle(la, lo)

    def _angle(self, lat_rad: np.ndarray, lon_deg: np.ndarray) -> np.ndarray:
        lat0, dlon = np.deg2rad(self._lat0), np.deg2rad(lon_deg - self._lon0)
        # the normals' dot and cross products: atan2 keeps small angles exact
        # (arccos of a dot product near 1 loses half the digits)
        a = np.array([np.cos(lat_rad) * np.cos(dlon), np.cos(lat_rad) * np.sin(dlon)])
        a = np.vstack([a, np.sin(lat_rad)[None]])
        b = np.array([np.cos(lat0), 0.0, np.sin(lat0)])[:, None]
        cross = np.linalg.norm(np.cross(a, b, axis=0), axis=0)
        return np.rad2deg(np.arctan2(cross, np.sum(a * b, axis=0)))

    def _plane_limit(self) -> str:
        return (
            f"a 2-D (east, north) frame represents points up to {PLANE_MAX_ANGLE:g}° "
            f"({_km(PLANE_MAX_ANGLE)}) from its reference, where its plane shortens ground "
            "lengths at most by half (beyond the horizon it folds the far side of the Earth "
            "onto the near side)"
        )

    def to_geodetic(self, xy) -> tuple[np.ndarray, ...]:
        """``(lat, lon)`` degrees of ``(R, 2)`` east/north points (the inverse of the
        2-D :meth:`to_local`: the point at height ``alt0``), or ``(lat, lon, alt)`` of
        ``(R, 3)`` east/north/up points. Longitudes in [-180, 180].

        Raises ValueError for a 2-D point whose ground point is more than
        :data:`PLANE_MAX_ANGLE` from the reference, or that no ground point
        projects to (beyond the Earth's disc in the plane)."""
        import pymap3d

        p = _real_array(xy, "xy")
        if p.ndim == 1 and p.size in (2, 3):
            p = p.reshape(1, -1)
        if p.ndim != 2 or p.shape[1] not in (2, 3):
            raise ValueError(f"xy must have shape (R, 2) or (R, 3), got {p.shape}")
        ref = (self._lat0, self._lon0, self._alt0)
        if not p.shape[0]:
            empty = np.zeros(0)
            return (empty, empty.copy()) if p.shape[1] == 2 else (empty, empty.copy(), empty.copy())
        if p.shape[1] == 3:
            lat, lon, h = pymap3d.enu2geodetic(p[:, 0], p[:, 1], p[:, 2], *ref)
            return tuple(np.asarray(v, dtype=np.float64).reshape(-1) for v in (lat, lon, h))
        # Newton on the up coordinate u: the height h grows along the reference's
        # vertical at the rate dh/du = cos θ, the cosine of the angle between the
        # reference's and the point's verticals (h's gradient is the point's unit
        # normal). Above the ellipsoid h is the distance to a convex surface, so it is
        # convex in u, and Newton from u = 0 (above the surface at alt0) descends
        # monotonically to the near-side root, quadratically. A plane point beyond the
        # Earth's disc has no root: its iterates reach the far side (cos θ ≤ 0) or do
        # not settle; both are refused, as is a root beyond PLANE_MAX_ANGLE.
        n = p.shape[0]
        u = np.zeros(n)
        lost = np.zeros(n, dtype=bool)
        converged = False
        for _ in range(_NEWTON_STEPS):
            lat, lon, h = (
                np.asarray(v, dtype=np.float64).reshape(-1)
                for v in pymap3d.enu2geodetic(p[:, 0], p[:, 1], u, *ref)
            )
            cos = np.cos(np.deg2rad(self._angle(np.deg2rad(lat), lon)))
            # at the horizon (cos θ → 0) a step would divide by nearly nothing: such
            # points are far beyond the limit, stop them there
            lost |= ~(cos > 1e-3)
            step = np.where(lost, 0.0, (h - self._alt0) / np.where(lost, 1.0, cos))
            u = u - step
            if np.all(np.abs(step) <= NEWTON_TOLERANCE):
                converged = True
                break
        lat, lon, _ = (
            np.asarray(v, dtype=np.float64).reshape(-1)
            for v in pymap3d.enu2geodetic(p[:, 0], p[:, 1], u, *ref)
        )
        angle = self._angle(np.deg2rad(lat), lon)
        # the limit with one part in 1e9 to spare: to_local accepts a point at 60°
        # whose round trip lands a rounding error beyond
        bad = lost | (angle > PLANE_MAX_ANGLE * (1 + 1e-9))
        if not converged:
            bad |= np.abs(step) > NEWTON_TOLERANCE
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise ValueError(
                f"xy[{i}] = ({float(p[i, 0])!r}, {float(p[i, 1])!r}) m is not in this frame's "
                f"plane: no ground point within {PLANE_MAX_ANGLE:g}° of the reference "
                f"({self._lat0!r}, {self._lon0!r}) projects there; {self._plane_limit()}"
            )
        return lat, lon


@dataclass(frozen=True, eq=False)
class DataCentre:
    """The frame :func:`data_centre` picks for geodetic data, and the outliers it left out.

    Attributes
    ----------
    frame : :class:`LocalFrame` at the centre of the bounding box of the inliers,
        altitude ``alt0``.
    outliers : (R,) bool: the reports farther than ``bound`` from ``median``.
    median : ``(lat, lon)`` degrees: the data's median point.
    bound : metres (the angle at the Earth's centre times its mean radius): reports
        farther from ``median`` are outliers; ``None`` when the data is spread too
        widely for any report to be called one (the bound would pass
        :data:`PLANE_MAX_ANGLE`).
    """

    frame: LocalFrame
    outliers: np.ndarray
    median: tuple[float, float]
    bound: float | None

    @property
    def n_outliers(self) -> int:
        """How many reports are outliers."""
        return int(np.count_nonzero(self.outliers))


def _lat_lon_to_centre(lat, lon) -> tuple[np.ndarray, np.ndarray]:
    """``lat, lon`` as validated flat arrays of one shape, not empty (a frame's centre)."""
    la = _latitudes(lat).reshape(-1)
    lo = _longitudes(lon).reshape(-1)
    if la.shape != lo.shape:
        raise ValueError(f"lat and lon must have one shape, got {la.shape} and {lo.shape}")
    if not la.size:
        raise ValueError("lat and lon are empty: no data to centre a frame on")
    return la, lo


def data_centre(lat, lon, alt0=0.0) -> DataCentre:
    """The local frame for geodetic data without a given reference, robust to corrupt reports.

    1. The data's *median point*: the coordinate-wise median of the reports' unit
       normals (x, y, z of the WGS-84 vertical), normalised — one corrupt report
       in any number of others moves it by at most one report's rank, and the
       normals have no antimeridian or pole to wrap around.
    2. Each report's distance from it (the angle between the verticals,
       :meth:`LocalFrame.plane_angle`), and their median d.
    3. Reports farther than ``max(OUTLIER_MEDIANS · d, OUTLIER_MIN_DISTANCE)``
       are outliers (:data:`OUTLIER_MEDIANS`, :data:`OUTLIER_MIN_DISTANCE`). When
       that bound passes :data:`PLANE_MAX_ANGLE` the data is not one area with a
       few strays, and nothing is an outlier (a frame that cannot hold the data
       is then refused where it is used).
    4. The frame: :meth:`LocalFrame.centre` of the other reports (the centre of
       their bounding box, so the plane's largest angle is as small as the box
       allows), at altitude ``alt0``.

    Data without outliers thus gets :meth:`LocalFrame.centre` of all of it.

    Examples
    --------
    >>> c = data_centre([50.80, 50.81, 50.79, 50.80], [-1.10, -1.09, -1.11, 54.8])
    >>> c.outliers.tolist(), [round(v, 2) for v in c.frame.reference[:2]]
    ([False, False, False, True], [50.8, -1.1])
    """
    la, lo = _lat_lon_to_centre(lat, lon)
    phi, lam = np.deg2rad(la), np.deg2rad(lo)
    normal = np.median(
        np.column_stack([np.cos(phi) * np.cos(lam), np.cos(phi) * np.sin(lam), np.sin(phi)]),
        axis=0,
    )
    norm = float(np.linalg.norm(normal))
    none = np.zeros(la.shape, dtype=bool)
    if not norm > 1e-6:  # reports all round the Earth: no median point, no outliers
        return DataCentre(LocalFrame.centre(la, lo, alt0), none, (0.0, 0.0), None)
    normal = normal / norm
    median = (
        float(np.rad2deg(np.arcsin(np.clip(normal[2], -1.0, 1.0)))),
        float(np.rad2deg(np.arctan2(normal[1], normal[0]))),
    )
    angle = LocalFrame(*median).plane_angle(la, lo)
    bound_deg = max(OUTLIER_MEDIANS * float(np.median(angle)), _degrees(OUTLIER_MIN_DISTANCE))
    if bound_deg > PLANE_MAX_ANGLE:
        return DataCentre(LocalFrame.centre(la, lo, alt0), none, median, None)
    outliers = angle > bound_deg
    inliers = ~outliers
    frame = LocalFrame.centre(la[inliers], lo[inliers], alt0)
    return DataCentre(frame, outliers, median, np.deg2rad(bound_deg) * _EARTH_RADIUS)


def _degrees(metres: float) -> float:
    """A distance along the surface as the angle at the Earth's centre (mean radius)."""
    return float(np.rad2deg(metres / _EARTH_RADIUS))


def velocity_en(speed_mps, course_deg) -> np.ndarray:
    """``(R, 2)`` east, north velocity of speeds (m/s, ≥ 0) along courses (degrees
    clockwise from north). NaN in either input gives a NaN row (unknown)."""
    s = _real_array(speed_mps, "speed_mps", allow_nan=True).reshape(-1)
    c = _real_array(course_deg, "course_deg", allow_nan=True).reshape(-1)
    if s.shape != c.shape:
        raise ValueError(
            f"speed_mps and course_deg must have one shape, got {s.shape} and {c.shape}"
        )
    if np.any(s < 0):
        raise ValueError(f"speed_mps must be ≥ 0 (or NaN: unknown), got {s[s < 0][0]}")
    rad = np.deg2rad(c)
    return np.column_stack([s * np.sin(rad), s * np.cos(rad)])
