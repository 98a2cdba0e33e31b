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
"""

from __future__ import annotations

import re
from datetime import datetime

__all__ = ["EXPECTED_TIMES", "format_timestamp", "parse_timestamp"]

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
    return ns, aware


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
