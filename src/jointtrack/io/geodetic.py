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
  height ``alt0`` (Newton's iteration on pymap3d's inverse) — so a 2-D round
  trip is exact to about 1e-9 m, not just to the curvature drop (≈ 8 m at
  10 km from the reference).

Units: :data:`KNOT` (m/s) and :data:`FOOT` (m) are exact by definition.
"""

from __future__ import annotations

import numbers

import numpy as np

__all__ = ["FOOT", "GEO_COLUMNS", "KNOT", "LocalFrame", "velocity_en"]

#: the names of WGS-84 columns in the package's files: degrees, degrees, metres
GEO_COLUMNS = ("lat", "lon", "alt")

#: one knot in metres per second (the international nautical mile, 1852 m, per hour)
KNOT = 1852.0 / 3600.0
#: one international foot in metres
FOOT = 0.3048


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
        self._alt0 = float(_real_array(alt0, "alt0"))

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
        la = _latitudes(lat).reshape(-1)
        lo = _longitudes(lon).reshape(-1)
        if la.shape != lo.shape:
            raise ValueError(f"lat and lon must have one shape, got {la.shape} and {lo.shape}")
        if not la.size:
            raise ValueError("lat and lon are empty: no data to centre a frame on")
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
            h = _real_array(alt, "alt").reshape(-1)
            if h.shape != la.shape:
                raise ValueError(f"alt must have the shape of lat, {la.shape}, got {h.shape}")
        if not la.size:
            return np.zeros((0, 2 if alt is None else 3))
        e, n, u = pymap3d.geodetic2enu(la, lo, h, self._lat0, self._lon0, self._alt0)
        cols = [e, n] if alt is None else [e, n, u]
        return np.column_stack([np.asarray(c, dtype=np.float64).reshape(-1) for c in cols])

    def to_geodetic(self, xy) -> tuple[np.ndarray, ...]:
        """``(lat, lon)`` degrees of ``(R, 2)`` east/north points (the inverse of the
        2-D :meth:`to_local`: the point at height ``alt0``), or ``(lat, lon, alt)`` of
        ``(R, 3)`` east/north/up points. Longitudes in [-180, 180]."""
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
        # Newton on the up coordinate: dh/du is the cosine of the angle between the
        # reference's and the point's verticals, ≈ 1 within thousands of km, so each
        # step gains several digits; 8 steps reach float64 resolution.
        u = np.zeros(p.shape[0])
        for _ in range(8):
            lat, lon, h = pymap3d.enu2geodetic(p[:, 0], p[:, 1], u, *ref)
            step = np.asarray(h, dtype=np.float64).reshape(-1) - self._alt0
            u = u - step
            if np.all(np.abs(step) < 1e-10):
                break
        lat, lon, _ = pymap3d.enu2geodetic(p[:, 0], p[:, 1], u, *ref)
        return (
            np.asarray(lat, dtype=np.float64).reshape(-1),
            np.asarray(lon, dtype=np.float64).reshape(-1),
        )


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
