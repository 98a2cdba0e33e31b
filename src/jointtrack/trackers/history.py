"""Track history: every confirmed estimate a tracker produced, as one tidy table.

:meth:`JPDATracker.history() <jointtrack.trackers.jpda.JPDATracker.history>`
returns a :class:`TrackHistory` with one row per (scan time, track id):

==============  ===========  ==============================================
column          array        meaning
==============  ===========  ==============================================
``time``        (R,)         scan time in seconds (relative to
                             ``time_origin`` when the scans were datetimes)
``track_id``    (R,)         track id
``x``           (R, n)       state estimate
``P``           (R, n, n)    its covariance
``existence``   (R,)         probability of existence (1.0 without JIPDA)
``mode_probabilities`` (R, r) an IMM tracker's mode probabilities
                             (``motion = "imm"``; names in ``mode_names``),
                             else None
==============  ===========  ==============================================

Rows are in scan order and, within a scan, by track id. :meth:`TrackHistory.to_dict`
flattens the table into plain 1-D columns (``x_0 … x_{n-1}`` and the upper
triangle ``P_i_j``, i ≤ j) for CSV or Parquet writers; :meth:`TrackHistory.to_pandas`
gives a :class:`pandas.DataFrame` when pandas is installed (it is not a
jointtrack dependency).

This module also converts scan times: :func:`scan_time_ns` turns a
``datetime.datetime`` (naive = UTC) or ``numpy.datetime64`` into integer
nanoseconds since the Unix epoch, and :func:`iso_from_ns` / :func:`ns_from_iso`
convert that to and from the ISO-8601 string kept as ``time_origin``.
"""

from __future__ import annotations

import datetime as _dt
import re
from collections.abc import Iterator

import numpy as np

__all__ = ["TrackHistory", "is_datetime", "iso_from_ns", "ns_from_iso", "scan_time_ns"]

_EPOCH = _dt.datetime(1970, 1, 1, tzinfo=_dt.UTC)
_NS_PER_UNIT = {
    "W": 7 * 86_400 * 10**9,
    "D": 86_400 * 10**9,
    "h": 3_600 * 10**9,
    "m": 60 * 10**9,
    "s": 10**9,
    "ms": 10**6,
    "us": 10**3,
    "ns": 1,
}
_SUB_NS = {"ps": 10**3, "fs": 10**6, "as": 10**9}


# ------------------------------------------------------------------ times
def is_datetime(t) -> bool:
    """True for a ``datetime.datetime`` or a (0-d) ``numpy.datetime64`` scan time."""
    if isinstance(t, _dt.datetime | np.datetime64):
        return True
    return isinstance(t, np.ndarray) and t.ndim == 0 and t.dtype.kind == "M"


def scan_time_ns(t) -> int:
    """Integer nanoseconds since 1970-01-01T00:00:00Z of a datetime scan time.

    ``datetime.datetime``: naive values are taken as UTC, aware ones converted to
    UTC. ``numpy.datetime64`` (any unit; UTC by numpy's convention) and pandas
    ``Timestamp`` keep their full resolution (down to nanoseconds). Exact
    (Python integers), so offsets from a ``time_origin`` lose nothing.
    """
    if isinstance(t, np.ndarray):
        t = t[()]
    if isinstance(t, _dt.datetime) and hasattr(t, "to_datetime64"):  # pandas.Timestamp
        t = t.to_datetime64()  # the UTC instant, nanosecond resolution
    if isinstance(t, np.datetime64):
        if np.isnat(t):
            raise ValueError("scan time is NaT (not a time)")
        unit, count = np.datetime_data(t.dtype)
        if unit in ("Y", "M", "generic"):
            if unit == "generic":
                raise ValueError(f"scan time {t!r} has no time unit")
            t = t.astype("datetime64[D]")
            unit, count = "D", 1
        value = int(t.astype(np.int64)) * count
        if unit in _SUB_NS:
            return value // _SUB_NS[unit]
        return value * _NS_PER_UNIT[unit]
    if isinstance(t, _dt.datetime):
        if t.tzinfo is None or t.tzinfo.utcoffset(t) is None:
            t = t.replace(tzinfo=_dt.UTC)
        return ((t - _EPOCH) // _dt.timedelta(microseconds=1)) * 1000
    raise TypeError(f"not a datetime: {t!r}")


def iso_from_ns(ns: int) -> str:
    """ISO-8601 UTC string (``…+00:00``, up to nanoseconds) of :func:`scan_time_ns` output."""
    us, sub = divmod(int(ns), 1000)
    s = (_EPOCH + _dt.timedelta(microseconds=us)).isoformat(
        timespec="microseconds" if sub else "auto"
    )
    if sub:
        s = s[:-6] + f"{sub:03d}" + s[-6:]  # nanosecond digits before the "+00:00"
    return s


_FRACTION = re.compile(r"(\.\d{6})(\d{1,3})")


def ns_from_iso(s: str) -> int:
    """Inverse of :func:`iso_from_ns`; any ISO-8601 date-time, naive meaning UTC."""
    if not isinstance(s, str):
        raise TypeError(f"time origin must be an ISO-8601 string, got {s!r}")
    extra = 0
    m = _FRACTION.search(s)
    if m:  # datetime parses microseconds; keep the nanosecond digits ourselves
        extra = int(m.group(2).ljust(3, "0"))
        s = s[: m.end(1)] + s[m.end(2) :]
    try:
        t = _dt.datetime.fromisoformat(s)
    except ValueError:
        raise ValueError(f"time origin {s!r} is not an ISO-8601 date-time") from None
    return scan_time_ns(t) + extra


# ------------------------------------------------------------------ table
class TrackHistory:
    """A tidy table of confirmed track estimates (see the module docstring).

    ``len(h)`` is the number of rows; iterating yields ``(track_id, rows)``
    pairs, one per track in ascending id order (``rows`` a :class:`TrackHistory`
    of that track alone), so ``dict(h)`` maps ids to their rows.
    ``time_origin`` is the ISO-8601 UTC instant that ``time == 0`` stands for
    when the scans were given as datetimes, else ``None``. The arrays are
    read-only.
    """

    def __init__(
        self,
        time,
        track_id,
        x,
        P,
        existence,
        *,
        time_origin: str | None = None,
        mode_names=(),
        mode_probabilities=None,
    ):
        time = np.asarray(time, dtype=float).reshape(-1)
        track_id = np.asarray(track_id, dtype=np.int64).reshape(-1)
        x = np.asarray(x, dtype=float)
        P = np.asarray(P, dtype=float)
        existence = np.asarray(existence, dtype=float).reshape(-1)
        R = len(time)
        if x.ndim != 2 or len(x) != R:
            raise ValueError(f"x must have shape ({R}, n), got {x.shape}")
        n = x.shape[1]
        if P.shape != (R, n, n):
            raise ValueError(f"P must have shape ({R}, {n}, {n}), got {P.shape}")
        if track_id.shape != (R,) or existence.shape != (R,):
            raise ValueError("time, track_id and existence must have one value per row")
        if time_origin is not None:
            ns_from_iso(time_origin)  # validates
        mode_names = tuple(mode_names)
        if mode_names:
            mode_probabilities = np.asarray(mode_probabilities, dtype=float)
            if mode_probabilities.shape != (R, len(mode_names)):
                raise ValueError(
                    f"mode_probabilities must have shape ({R}, {len(mode_names)}), got "
                    f"{mode_probabilities.shape}"
                )
            mode_probabilities.flags.writeable = False
        elif mode_probabilities is not None:
            raise ValueError("mode_probabilities need mode_names")
        for a in (time, track_id, x, P, existence):
            a.flags.writeable = False
        self.mode_names = mode_names
        self.mode_probabilities = mode_probabilities
        self.time = time
        self.track_id = track_id
        self.x = x
        self.P = P
        self.existence = existence
        self.time_origin = time_origin

    # -------------------------------------------------------------- shape
    @property
    def state_dim(self) -> int:
        """n, the length of each state vector."""
        return self.x.shape[1]

    @property
    def track_ids(self) -> np.ndarray:
        """The distinct track ids, ascending."""
        return np.unique(self.track_id)

    def __len__(self) -> int:
        return len(self.time)

    def __iter__(self) -> Iterator[tuple[int, TrackHistory]]:
        if len(self) == 0:
            return
        order = np.argsort(self.track_id, kind="stable")
        ids = self.track_id[order]
        cuts = np.flatnonzero(np.diff(ids)) + 1
        for rows in np.split(order, cuts):
            yield int(self.track_id[rows[0]]), self._take(rows)

    def __repr__(self) -> str:
        origin = f", time_origin={self.time_origin!r}" if self.time_origin else ""
        return (
            f"TrackHistory({len(self)} rows, {len(self.track_ids)} tracks, "
            f"state_dim={self.state_dim}{origin})"
        )

    def _take(self, rows) -> TrackHistory:
        return TrackHistory(
            self.time[rows],
            self.track_id[rows],
            self.x[rows],
            self.P[rows],
            self.existence[rows],
            time_origin=self.time_origin,
            mode_names=self.mode_names,
            mode_probabilities=(
                None if self.mode_probabilities is None else self.mode_probabilities[rows]
            ),
        )

    def track(self, track_id: int) -> TrackHistory:
        """The rows of one track, in time order; KeyError if it never was confirmed."""
        rows = np.flatnonzero(self.track_id == int(track_id))
        if rows.size == 0:
            raise KeyError(f"track {track_id} has no confirmed estimate in this history")
        return self._take(rows)

    def datetimes(self) -> np.ndarray:
        """``time`` as ``numpy.datetime64[ns]`` instants (UTC); needs a ``time_origin``."""
        if self.time_origin is None:
            raise ValueError("this history has numeric scan times (no time_origin)")
        origin = np.datetime64(ns_from_iso(self.time_origin), "ns")
        return origin + np.round(self.time * 1e9).astype("timedelta64[ns]")

    # ------------------------------------------------------------ columns
    def columns(self) -> list[str]:
        """Names of :meth:`to_dict`'s columns, in order."""
        n = self.state_dim
        iu, ju = np.triu_indices(n)
        return [
            "time",
            "track_id",
            *(f"x_{i}" for i in range(n)),
            *(f"P_{i}_{j}" for i, j in zip(iu, ju, strict=True)),
            "existence",
            *(f"mode_{m}" for m in self.mode_names),
        ]

    def to_dict(self) -> dict[str, np.ndarray]:
        """Plain 1-D columns: time, track_id, x_0…x_{n-1}, P_i_j (i ≤ j), existence
        (and an IMM's mode probabilities, ``mode_<name>``).

        Every value is a 1-D array of length ``len(self)``, ready for a CSV or
        Parquet writer; :meth:`from_dict` rebuilds the table (P symmetric).
        """
        n = self.state_dim
        out = {"time": self.time, "track_id": self.track_id}
        for i in range(n):
            out[f"x_{i}"] = self.x[:, i]
        for i, j in zip(*np.triu_indices(n), strict=True):
            out[f"P_{i}_{j}"] = self.P[:, i, j]
        out["existence"] = self.existence
        for k, m in enumerate(self.mode_names):
            out[f"mode_{m}"] = self.mode_probabilities[:, k]
        return out

    @classmethod
    def from_dict(cls, columns, *, time_origin: str | None = None) -> TrackHistory:
        """Rebuild a table from :meth:`to_dict`-style columns (e.g. read back from CSV)."""
        n = 0
        while f"x_{n}" in columns:
            n += 1
        time = np.asarray(columns["time"], dtype=float)
        R = len(time)
        x = np.zeros((R, n))
        P = np.zeros((R, n, n))
        for i in range(n):
            x[:, i] = columns[f"x_{i}"]
        for i, j in zip(*np.triu_indices(n), strict=True):
            P[:, i, j] = P[:, j, i] = columns[f"P_{i}_{j}"]
        names = tuple(k.removeprefix("mode_") for k in columns if k.startswith("mode_"))
        modes = np.column_stack([columns[f"mode_{m}"] for m in names]) if names else None
        return cls(
            time,
            np.asarray(columns["track_id"]).astype(np.int64),
            x,
            P,
            columns["existence"],
            time_origin=time_origin,
            mode_names=names,
            mode_probabilities=modes,
        )

    def to_pandas(self):
        """The :meth:`to_dict` columns as a :class:`pandas.DataFrame` (needs pandas).

        ``time_origin`` is kept in ``DataFrame.attrs["time_origin"]``.
        """
        try:
            import pandas as pd
        except ImportError as exc:
            raise ImportError(
                "TrackHistory.to_pandas() needs pandas, which jointtrack does not depend on: "
                "install it (pip install pandas), or use TrackHistory.to_dict() for plain "
                "numpy columns"
            ) from exc
        df = pd.DataFrame({k: np.array(v) for k, v in self.to_dict().items()})
        df.attrs["time_origin"] = self.time_origin
        return df
