"""ISO-8601 scan times: parsing, the time origin, and formatting back.

A detections file's ``time`` column holds either numbers (seconds, or any
unit) or ISO-8601 timestamps such as ``2026-11-23T10:00:00.5Z``. Timestamps
become **seconds since the first row's timestamp** (the first scan is at
t = 0); that first timestamp is kept as the *time origin*, an ISO string
(:attr:`jointtrack.io.Detections.time_origin`), so absolute times are never
lost: absolute time = origin + t seconds.

Accepted timestamps: ``YYYY-MM-DD``, optionally followed by ``T`` (or ``t`` or a
space) and ``HH:MM``, ``HH:MM:SS`` or ``HH:MM:SS.fraction`` (``.`` or ``,``;
any number of digits, nanosecond resolution, further digits truncated), then
optionally ``Z`` or a UTC offset ``±HH:MM`` / ``±HHMM`` / ``±HH``.

* With a ``Z`` or an offset, timestamps are instants: differences are exact
  across offsets and the origin is written in UTC (``…Z``).
* Without, they are naive wall-clock times: differences are taken as written
  (no time zone, no daylight-saving changes) and the origin has no suffix.
* A column mixing the two (or mixing numbers and timestamps) is an error.

Instants are held as int64 nanoseconds since 1970-01-01, so timestamps must lie
within :data:`TIME_RANGE` (1677-09-21T00:12:43.145224192 to
2262-04-11T23:47:16.854775807); others are refused, not wrapped around.
"""

from __future__ import annotations

import re
from datetime import datetime

import numpy as np

__all__ = ["EXPECTED_TIMES", "TIME_RANGE", "format_timestamp", "parse_timestamp"]

#: the formats a ``time`` cell may have (for error messages)
EXPECTED_TIMES = (
    "expected a number (e.g. seconds: 12.5) or an ISO-8601 timestamp "
    "(e.g. 2026-11-23T10:00:00.5Z, 2026-11-23T10:00:00+01:00, 2026-11-23 10:00:00)"
)

_ISO = re.compile(
    r"(\d{4})-(\d{2})-(\d{2})"
    r"(?:[Tt ](\d{2}):(\d{2})(?::(\d{2})(?:[.,](\d+))?)?"
    r"(?:([Zz])|([+-])(\d{2})(?::?(\d{2}))?)?)?"
)
_EPOCH = datetime(1970, 1, 1)
_NS = 1_000_000_000
#: the nanoseconds since 1970-01-01 an instant may have: int64's range
NS_RANGE = (-(2**63), 2**63 - 1)


def parse_timestamp(s: str) -> tuple[int, bool] | None:
    """``(nanoseconds since 1970-01-01T00:00:00 [UTC], has_offset)`` of an
    ISO-8601 timestamp, or ``None`` if ``s`` is not one.

    Naive timestamps (no ``Z``/offset) count from 1970-01-01T00:00:00 of their
    own wall clock. Raises ValueError for a well-formed but impossible date or
    time (month 13, hour 25, …) with the reason.
    """
    m = _ISO.fullmatch(s.strip())
    if m is None:
        return None
    y, mo, d, hh, mm, ss, frac, z, sign, oh, om = m.groups()
    try:
        dt = datetime(int(y), int(mo), int(d), int(hh or 0), int(mm or 0), int(ss or 0))
    except ValueError as exc:
        raise ValueError(f"{s.strip()!r} is not a valid date/time ({exc})") from None
    delta = dt - _EPOCH
    ns = (delta.days * 86400 + delta.seconds) * _NS
    if frac:
        ns += int((frac + "000000000")[:9])
    aware = bool(z or sign)
    if sign:
        off = int(oh) * 60 + int(om or 0)
        if int(oh) > 23 or int(om or 0) > 59:
            raise ValueError(f"{s.strip()!r} has an invalid UTC offset")
        ns -= (1 if sign == "+" else -1) * off * 60 * _NS
    if not NS_RANGE[0] <= ns <= NS_RANGE[1]:
        raise ValueError(f"{s.strip()!r} is {outside_time_range()}")
    return ns, aware


def units_to_ns(values: np.ndarray, unit_ns: int) -> tuple[np.ndarray, int | None]:
    """int64 counts of a time unit (``unit_ns`` nanoseconds: a Parquet timestamp's
    s, ms, us) as int64 nanoseconds, and the index of the first count whose instant
    is outside :data:`TIME_RANGE` (None if none): multiplied as they are, those would
    wrap around silently."""
    v = np.asarray(values, dtype=np.int64)
    lo, hi = -(NS_RANGE[1] // unit_ns), NS_RANGE[1] // unit_ns
    bad = np.flatnonzero((v < lo) | (v > hi))
    if bad.size:
        return np.zeros(0, np.int64), int(bad[0])
    return v * unit_ns, None


def span_problem(ns) -> str | None:
    """Why int64 nanoseconds ``ns`` cannot be taken relative to one another (their
    span does not fit 64 bits: more than ~292 years), or None."""
    if not len(ns):
        return None
    span = int(np.max(ns)) - int(np.min(ns))  # in Python integers: no wrap-around
    if span > NS_RANGE[1]:
        return (
            f"the times span {span / _NS / 86400 / 365.25:,.0f} years, more than the ~292 "
            "years that nanosecond differences hold in 64 bits"
        )
    return None


def outside_time_range() -> str:
    """The end of a message on an instant beyond :data:`TIME_RANGE`."""
    return (
        f"outside the times that can be held, {TIME_RANGE[0]} to {TIME_RANGE[1]} "
        "(nanoseconds since 1970 in 64 bits)"
    )


def format_timestamp(ns: int, aware: bool) -> str:
    """ISO-8601 text of ``ns`` nanoseconds since 1970-01-01T00:00:00: seconds
    with the shortest exact fraction, ``Z`` when ``aware``."""
    sec, frac = divmod(int(ns), _NS)
    days, rem = divmod(sec, 86400)
    base = datetime.fromordinal(_EPOCH.toordinal() + days)
    h, rem = divmod(rem, 3600)
    mi, s = divmod(rem, 60)
    text = f"{base:%Y-%m-%d}T{h:02d}:{mi:02d}:{s:02d}"
    if frac:
        text += "." + f"{frac:09d}".rstrip("0")
    return text + ("Z" if aware else "")


def parse_origin(origin) -> tuple[str | None, int | None, bool]:
    """Check a time origin (``None`` or one ISO-8601 timestamp): ``(canonical
    text, ns, aware)``; ValueError otherwise."""
    if origin is None:
        return None, None, False
    if not isinstance(origin, str):
        raise ValueError(
            f"time_origin must be an ISO-8601 timestamp string or None, got {origin!r}"
        )
    parsed = parse_timestamp(origin)
    if parsed is None:
        raise ValueError(
            f"time_origin must be an ISO-8601 timestamp (e.g. 2026-11-23T10:00:00.5Z), "
            f"got {origin!r}"
        )
    ns, aware = parsed
    return format_timestamp(ns, aware), ns, aware


#: the first and last instants that can be held (ISO-8601, UTC or wall clock)
TIME_RANGE = tuple(format_timestamp(v, False) for v in NS_RANGE)
