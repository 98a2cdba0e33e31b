"""Scoring tracks against the targets' own reports (AIS, ADS-B self-reports).

Real data has no simulated truth: the reference is what each vessel or
aircraft reported of itself — irregular in time, one identity (MMSI, icao24)
per target. :func:`score_self_reports` samples both the self-reports and the
tracks at common *evaluation instants* and then scores them with the
package's existing metrics; nothing here re-implements GOSPA or an assignment.

Evaluation instants. ``t_k = t0 + k·window`` for k = 0, 1, … while
``t_k ≤ t_end``, ``t_end`` the last report or track time; ``t0`` defaults to
the first report time (the first track time when there is no report). A
time span after the last instant (shorter than one window) is not scored.

Truth at an instant t (the reference). For each identity, its reports sorted
by time (reports of one identity at the same time are averaged: real AIS
files hold such duplicates):

* at a report time, the reported position;
* strictly between two consecutive reports τ_j < t < τ_{j+1}, the linear
  interpolation ``p_j + (t − τ_j)/(τ_{j+1} − τ_j) · (p_{j+1} − p_j)`` —
  **only if** the gap τ_{j+1} − τ_j ≤ ``max_gap``; an identity silent for
  longer than ``max_gap`` is *not present* anywhere inside that gap;
* before its first report or after its last one, not present (no
  extrapolation).

Tracks at an instant t. Each track id's latest estimate at a time τ ≤ t,
provided t − τ < ``window`` (τ in the half-open window (t − window, t]); a
track with no estimate in that window is *absent* at t. The estimate's
position is used as is (no prediction to t), so a track reported at the
window's start carries up to one window of lag: a target at 250 m/s (an
airliner) moves 2.5 km in a 10 s window. To score without that lag, put the
instants on the tracker's scan times (``t0`` = the first scan time and
``window`` = the scan spacing): each track's estimate is then taken at the
instant itself.

Figures. The sampled tables go to
:func:`jointtrack.metrics.track_statistics` (cut-off ``gate = c``,
``min_fraction = ½``) for the associations — per instant the GOSPA
assignment with p = 2, a pair kept when its distance is < c — and to
:func:`jointtrack.metrics.gospa_series` (c, p = 2, α = 2; the same per-instant
assignment) for GOSPA. An identity is *associated* at an instant when
track_statistics pairs it with a track there. Then:

* **GOSPA**: mean over all instants of the per-instant GOSPA d_2^(c,2) (an
  instant with neither truth nor track counts as 0), and the means of its
  parts on the squared scale — localisation Σ d², missed (c²/2)·n_missed,
  false (c²/2)·n_false, so ``localisation + missed + false`` = mean GOSPA²
  — and the mean numbers of missed and false targets per instant.
* **coverage**: associated identity-instants / identity-instants (overall),
  and per identity.
* **tracks per identity** (fragmentation): the number of distinct track ids
  ever associated with an identity; the mean is over the identities
  associated at least once (identities never tracked show as coverage 0).
* **identity switches**: an identity associated with a different track from
  the one it was last associated with (track_statistics' definition); total
  and per identity.
* **purity**: for each track associated at ≥ 1 instant, the share of its
  associated instants on its most frequent identity; the mean over those
  tracks weighted by their associated instants (``purity``) and unweighted
  (``purity_unweighted``).
* **false tracks**: track ids present at ≥ 1 instant for which no single
  identity is associated in at least half of their instants
  (track_statistics' false tracks with ``min_fraction = ½``); also per hour,
  over ``duration`` when given, else over the span of the instants.
* **confirmed track ids**: the distinct ids of the track table given (every
  row is taken as a confirmed track's estimate), and how many of them are
  present at some instant.
* **ids held** (fragmentation counted the second way): a track id is *held*
  by an identity when it is associated with it at instants covering at least
  ``hold`` seconds (count × ``window`` ≥ ``hold``; default 60 s, i.e. six
  10 s instants or one 60 s instant). ``tracks_per_identity_held`` is the mean
  number of held ids over the identities that hold at least one
  (``n_identities_held`` of them): brief fragments a tracker starts and drops
  at once count in ``tracks_per_identity`` but not here.

Classes of identity-instants. Every sampled truth point (an identity at an
instant) is in exactly one class, decided from the self-reports alone (not
from any track):

* **close pair** when another identity is present at the same instant within
  ``pair_distance`` (default 2,000 position units — 2 km in metres) of it
  (Euclidean, all coordinates);
* else **manoeuvre** when its turn rate exceeds ``turn_rate`` (default
  1 °/s). The turn rate at instant t is the angle between the two chords
  ``p(t) − p(t − turn_span)`` and ``p(t + turn_span) − p(t)`` of the
  interpolated truth (the same interpolation as the reference; in the first
  two coordinates), divided by ``turn_span`` (default 30 s) — exact for a
  constant-rate turn at constant speed. It is taken only where the identity
  is present at both t ± turn_span and moves at ≥ ``min_speed`` (default
  1 unit/s) along both chords; a slower or stationary target, or one at the
  start or end of its reports, has no heading to turn and is not a manoeuvre;
* else **straight** (every other instant).

Close pair wins over manoeuvre. Per class: ``n_<class>`` identity-instants,
``coverage_<class>`` the share of them associated, and ``lost_<class>`` the
share not associated (1 − coverage_<class>; both NaN for an empty class),
with ``class_of`` the class of each sampled truth point (0 straight,
1 manoeuvre, 2 close pair).

Undefined figures (no instants, no identity-instants, no associated track,
a zero span) are NaN on :class:`SelfReportScore` and ``None`` in
:meth:`SelfReportScore.as_dict`, which holds plain JSON numbers only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction

import numpy as np

from jointtrack.assignment._checks import _as_real_array, _holds_bool, as_float
from jointtrack.metrics.ospa import gospa_series
from jointtrack.metrics.tracks import TrackStatistics, track_statistics

__all__ = ["SelfReportScore", "score_self_reports"]

#: Refuse more evaluation instants than this (a tiny ``window`` over a long record).
MAX_INSTANTS = 10_000_000

_SCALARS = (
    "n_instants window c max_gap t0 hours coverage n_identity_instants n_associated "
    "n_identities n_identities_tracked tracks_per_identity n_id_switches purity "
    "purity_unweighted n_false_tracks false_tracks_per_hour n_confirmed_track_ids "
    "n_tracks_present gospa_mean gospa_localisation gospa_missed gospa_false "
    "missed_per_instant false_per_instant hold tracks_per_identity_held n_identities_held "
    "turn_rate turn_span min_speed pair_distance "
    "n_straight n_manoeuvre n_close_pair coverage_straight coverage_manoeuvre "
    "coverage_close_pair lost_straight lost_manoeuvre lost_close_pair"
).split()

#: the classes of identity-instants, in the order of ``SelfReportScore.class_of``
CLASSES = ("straight", "manoeuvre", "close_pair")


@dataclass(frozen=True, eq=False)
class SelfReportScore:
    """Result of :func:`score_self_reports` (definitions in the module docstring).

    Scalars: those listed by :meth:`as_dict` (NaN where undefined). Per
    evaluation instant (``instants``, (K,)): ``gospa_per_instant``,
    ``n_truths_per_instant``, ``n_tracks_per_instant``. Per identity
    (``identity_ids``, (N,), every identity of the reports, sorted):
    ``identity_instants``, ``identity_associated``, ``identity_coverage`` (NaN
    where the identity is present at no instant), ``identity_tracks``,
    ``identity_switches``. Per track present at some instant (``track_ids``,
    (T,)): ``track_instants``, ``track_associated``, ``track_purity`` (NaN
    when never associated). ``truth_sampled`` and ``tracks_sampled`` are the
    sampled tables ``(times, ids, positions)`` that were scored, and
    ``statistics`` the :class:`~jointtrack.metrics.TrackStatistics` of them.
    """

    n_instants: int
    window: float
    c: float
    max_gap: float
    t0: float
    hours: float
    coverage: float
    n_identity_instants: int
    n_associated: int
    n_identities: int
    n_identities_tracked: int
    tracks_per_identity: float
    n_id_switches: int
    purity: float
    purity_unweighted: float
    n_false_tracks: int
    false_tracks_per_hour: float
    n_confirmed_track_ids: int
    n_tracks_present: int
    gospa_mean: float
    gospa_localisation: float
    gospa_missed: float
    gospa_false: float
    missed_per_instant: float
    false_per_instant: float
    hold: float
    tracks_per_identity_held: float
    n_identities_held: int
    turn_rate: float
    turn_span: float
    min_speed: float
    pair_distance: float
    n_straight: int
    n_manoeuvre: int
    n_close_pair: int
    coverage_straight: float
    coverage_manoeuvre: float
    coverage_close_pair: float
    lost_straight: float
    lost_manoeuvre: float
    lost_close_pair: float
    class_of: np.ndarray
    identity_tracks_held: np.ndarray
    instants: np.ndarray
    gospa_per_instant: np.ndarray
    n_truths_per_instant: np.ndarray
    n_tracks_per_instant: np.ndarray
    identity_ids: np.ndarray
    identity_instants: np.ndarray
    identity_associated: np.ndarray
    identity_coverage: np.ndarray
    identity_tracks: np.ndarray
    identity_switches: np.ndarray
    track_ids: np.ndarray
    track_instants: np.ndarray
    track_associated: np.ndarray
    track_purity: np.ndarray
    truth_sampled: tuple
    tracks_sampled: tuple
    statistics: TrackStatistics

    def as_dict(self) -> dict:
        """Scalars and per-identity figures as plain JSON numbers.

        Undefined values (NaN on this object, e.g. coverage with no
        identity-instants, purity with no associated track, a rate over a
        zero span) are ``None``; ``max_gap`` = ∞ is ``None`` too (JSON has no
        infinity). ``per_identity`` maps ``str(identity id)`` to its
        ``instants``, ``coverage``, ``tracks``, ``tracks_held`` and ``switches``.
        """
        out = {k: _plain(getattr(self, k)) for k in _SCALARS}
        out["per_identity"] = {
            str(int(i)): {
                "instants": int(n),
                "coverage": _plain(cov),
                "tracks": int(nt),
                "tracks_held": int(nh),
                "switches": int(sw),
            }
            for i, n, cov, nt, nh, sw in zip(
                self.identity_ids,
                self.identity_instants,
                self.identity_coverage,
                self.identity_tracks,
                self.identity_tracks_held,
                self.identity_switches,
                strict=True,
            )
        }
        return out

    def summary(self) -> str:
        """One line: instants, coverage, purity, tracks per identity, switches,
        false tracks and mean GOSPA."""

        def f(x, fmt):
            return "n/a" if not math.isfinite(x) else format(x, fmt)

        return (
            f"{self.n_instants} instants of {self.window:g} s: coverage {f(self.coverage, '.3f')}, "
            f"purity {f(self.purity, '.3f')}, tracks/identity "
            f"{f(self.tracks_per_identity, '.2f')} (held ≥ {self.hold:g} s: "
            f"{f(self.tracks_per_identity_held, '.2f')}), {self.n_id_switches} id switches, "
            f"coverage straight/manoeuvre/close pair {f(self.coverage_straight, '.3f')}/"
            f"{f(self.coverage_manoeuvre, '.3f')}/{f(self.coverage_close_pair, '.3f')}, "
            f"{self.n_false_tracks} false tracks ({f(self.false_tracks_per_hour, '.2f')}/h) "
            f"of {self.n_confirmed_track_ids} confirmed ids, GOSPA mean "
            f"{f(self.gospa_mean, '.1f')} (c = {self.c:g})"
        )


def _plain(x):
    """A JSON-able Python number: int stays int, non-finite float → None."""
    if isinstance(x, int | np.integer) and not isinstance(x, bool | np.bool_):
        return int(x)
    x = float(x)
    return x if math.isfinite(x) else None


# ----------------------------------------------------------------------------- checks


def _times(values, name: str) -> np.ndarray:
    t = _as_real_array(values, name)
    if t.ndim != 1:
        raise ValueError(f"{name} must be 1-D, got shape {t.shape}")
    if not np.all(np.isfinite(t)):
        i = int(np.flatnonzero(~np.isfinite(t))[0])
        raise ValueError(f"{name}[{i}] is not finite ({t[i]})")
    return t


def _ids(values, name: str) -> np.ndarray:
    """Integer identities as int64; booleans, strings, non-integral or huge values refused."""
    if isinstance(values, str | bytes):
        raise ValueError(f"{name} must be a 1-D array of integers, got a string")
    try:
        raw = np.asarray(values)
    except (TypeError, ValueError, OverflowError) as exc:
        raise ValueError(f"{name} must be a 1-D array of integers: {exc}") from None
    if raw.ndim != 1:
        raise ValueError(f"{name} must be 1-D, got shape {raw.shape}")
    if raw.dtype.kind == "b" or _holds_bool(values):
        raise ValueError(f"{name} holds booleans; pass integer ids")
    if raw.size == 0:
        return np.zeros(0, dtype=np.int64)
    if raw.dtype.kind in "iu":
        if raw.dtype.kind == "u" and raw.max() > np.iinfo(np.int64).max:
            raise ValueError(f"{name} holds an id beyond the int64 range")
        return raw.astype(np.int64)
    if raw.dtype.kind == "f":
        bad = ~np.isfinite(raw) | (raw != np.round(raw)) | (np.abs(raw) > 2.0**53)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise ValueError(f"{name}[{i}] = {raw[i]} is not a whole number (ids are integers)")
        return raw.astype(np.int64)
    raise ValueError(
        f"{name} must hold integers (ids), got dtype {raw.dtype}"
        + (" (e.g. an integer beyond the int64 range)" if raw.dtype.kind == "O" else "")
    )


def _positions(values, name: str, rows: int) -> np.ndarray:
    P = _as_real_array(values, name)
    if P.ndim == 1 and P.size == 0:
        P = P.reshape(0, 0)
    if P.ndim != 2:
        raise ValueError(f"{name} must be a 2-D (rows, d) array, got shape {P.shape}")
    if P.shape[0] != rows:
        raise ValueError(f"{name} has {P.shape[0]} rows but the times have {rows}")
    if not np.all(np.isfinite(P)):
        r = int(np.argwhere(~np.isfinite(P))[0, 0])
        raise ValueError(f"{name} has a non-finite coordinate in row {r}: {P[r].tolist()}")
    return P


def _table(times, ids, positions, prefix: str):
    t = _times(times, f"{prefix}_times")
    i = _ids(ids, f"{prefix}_ids")
    if i.size != t.size:
        raise ValueError(
            f"{prefix}_ids has {i.size} entries but {prefix}_times has {t.size}: one id per row"
        )
    P = _positions(positions, f"{prefix}_positions", t.size)
    return t, i, P


def _unique_pairs(a: np.ndarray, b: np.ndarray):
    """Distinct pairs ``(a_i, b_i)`` sorted by (a, b) and how often each occurs
    (a lexsort: ``np.unique(axis=0)`` is several times slower on long tables)."""
    if a.size == 0:
        return a[:0], b[:0], np.zeros(0, dtype=np.int64)
    o = np.lexsort((b, a))
    a, b = a[o], b[o]
    new = np.r_[True, (a[1:] != a[:-1]) | (b[1:] != b[:-1])]
    starts = np.flatnonzero(new)
    return a[starts], b[starts], np.diff(np.r_[starts, a.size])


def _groups(ids: np.ndarray, times: np.ndarray):
    """Row order sorted by (id, time) and the start of each id's block."""
    order = np.lexsort((times, ids))
    ids_o = ids[order]
    starts = np.flatnonzero(np.r_[True, ids_o[1:] != ids_o[:-1]]) if ids.size else np.zeros(0, int)
    return order, np.r_[starts, ids.size].astype(np.int64)


# ----------------------------------------------------------------------------- sampling


def _report_tracks(times, ids, P):
    """Each identity's reports: ``(identity, τ sorted unique, positions)``, reports of one
    identity at one time averaged (real AIS files hold such duplicates)."""
    order, bounds = _groups(ids, times)
    for a, b in zip(bounds[:-1], bounds[1:], strict=True):
        rows = order[a:b]
        tau, pos = times[rows], P[rows]
        tau, inv = np.unique(tau, return_inverse=True)
        if tau.size < rows.size:
            pos = (
                np.stack([np.bincount(inv, weights=col) for col in pos.T], axis=1)
                / np.bincount(inv)[:, None]
            )
        yield ids[rows[0]], tau, pos


def _interpolate(tau, pos, T, max_gap):
    """An identity's reference at the times ``T`` (sorted, any values): ``(present, X)``
    with ``X`` the rows of ``T[present]`` (module docstring: reported position at a
    report time, linear interpolation across a gap ≤ ``max_gap``, absent elsewhere)."""
    inside = (T >= tau[0]) & (T <= tau[-1])
    Ti = T[inside]
    j = np.searchsorted(tau, Ti, side="right") - 1  # tau[j] <= t, j in [0, n-1]
    exact = tau[j] == Ti
    nxt = np.minimum(j + 1, tau.size - 1)
    gap = tau[nxt] - tau[j]
    ok = exact | (gap <= max_gap)
    # a rounded gap equal to max_gap may hide an exact gap just above it (rounding is
    # monotone, so only ties are in doubt): decide those in rationals
    for k in np.flatnonzero(~exact & (gap == max_gap)):
        exact_gap = Fraction(float(tau[nxt[k]])) - Fraction(float(tau[j[k]]))
        ok[k] = exact_gap <= Fraction(max_gap)
    j, nxt, gap, exact, Ti = j[ok], nxt[ok], gap[ok], exact[ok], Ti[ok]
    w = np.where(exact, 0.0, (Ti - tau[j]) / np.where(exact, 1.0, gap))
    present = inside.copy()
    present[inside] = ok
    return present, pos[j] + w[:, None] * (pos[nxt] - pos[j])


def _sample_truth(times, ids, P, instants, max_gap, turn_span, min_speed, turn_rate):
    """The reports of every identity at the instants (module docstring), and whether
    each sampled point is a manoeuvre (turn rate above ``turn_rate`` rad/s)."""
    out_t, out_i, out_p, out_m = [], [], [], []
    for ident, tau, pos in _report_tracks(times, ids, P):
        lo = np.searchsorted(instants, tau[0], side="left")
        hi = np.searchsorted(instants, tau[-1], side="right")
        present, X = _interpolate(tau, pos, instants[lo:hi], max_gap)
        T = instants[lo:hi][present]
        if T.size == 0:
            continue
        out_t.append(T)
        out_i.append(np.full(T.size, ident, dtype=np.int64))
        out_p.append(X)
        out_m.append(_manoeuvring(tau, pos, T, X, max_gap, turn_span, min_speed, turn_rate))
    return (out_t, out_i, out_p), out_m


def _manoeuvring(tau, pos, T, X, max_gap, turn_span, min_speed, turn_rate):
    """Turn rate above ``turn_rate`` (rad/s) at the times ``T`` (positions ``X``): the
    angle between the chords over [t − span, t] and [t, t + span] / span (module
    docstring); False where either end is absent or a chord is slower than min_speed."""
    out = np.zeros(T.size, dtype=bool)
    if pos.shape[1] < 2:
        return out
    before_ok, before = _interpolate(tau, pos, T - turn_span, max_gap)
    after_ok, after = _interpolate(tau, pos, T + turn_span, max_gap)
    both = before_ok & after_ok
    # a chord of inf or NaN length (coordinates near ±1e308) has no heading: not moving
    with np.errstate(over="ignore", invalid="ignore"):
        a = X[both, :2] - before[both[before_ok], :2]
        b = after[both[after_ok], :2] - X[both, :2]
        na, nb = np.hypot(*a.T), np.hypot(*b.T)
        moving = (np.minimum(na, nb) >= min_speed * turn_span) & (na > 0) & (nb > 0)
        moving &= np.isfinite(na) & np.isfinite(nb)
        # unit chords: products of coordinates up to 1e300 would overflow
        ua = a / np.where(moving, na, 1.0)[:, None]
        ub = b / np.where(moving, nb, 1.0)[:, None]
        cross = ua[:, 0] * ub[:, 1] - ua[:, 1] * ub[:, 0]
        angle = np.abs(np.arctan2(cross, np.sum(ua * ub, axis=1)))
    out[both] = moving & (angle > turn_rate * turn_span)
    return out


def _close_pairs(times, positions, pair_distance):
    """Whether another row at the same time lies within ``pair_distance`` of each row."""
    out = np.zeros(times.size, dtype=bool)
    order = np.argsort(times, kind="stable")
    t = times[order]
    starts = np.flatnonzero(np.r_[True, t[1:] != t[:-1]])
    ends = np.r_[starts[1:], t.size]
    shared = ends - starts > 1  # instants holding one identity have no pair
    for a, b in zip(starts[shared], ends[shared], strict=True):
        rows = order[a:b]
        p = positions[rows]
        # hypot, not a sum of squares (no overflow at 1e300); a difference of ±1e308
        # overflowing to inf is correctly "not near"
        with np.errstate(over="ignore"):
            diff = np.abs(p[:, None, :] - p[None, :, :])
        near = np.all(diff <= pair_distance, axis=2)
        np.fill_diagonal(near, False)
        if near.any():
            d = np.hypot.reduce(diff, axis=2) if p.shape[1] > 1 else diff[:, :, 0]
            near &= d <= pair_distance
        out[rows] = near.any(axis=1)
    return out


def _sample_tracks(times, ids, P, instants, window):
    """Each track's latest estimate in (t − window, t] at every instant t."""
    out_t, out_i, out_p = [], [], []
    order, bounds = _groups(ids, times)
    for a, b in zip(bounds[:-1], bounds[1:], strict=True):
        rows = order[a:b]
        tau, pos = times[rows], P[rows]
        lo = np.searchsorted(instants, tau[0], side="left")
        hi = np.searchsorted(instants, tau[-1] + window, side="right")  # a superset
        T = instants[lo:hi]
        if T.size == 0:
            continue
        j = np.searchsorted(tau, T, side="right") - 1
        keep = (j >= 0) & (T - tau[np.maximum(j, 0)] < window)
        T, j = T[keep], j[keep]
        out_t.append(T)
        out_i.append(np.full(T.size, ids[rows[0]], dtype=np.int64))
        out_p.append(pos[j])
    return out_t, out_i, out_p


def _stack(parts, d: int):
    t, i, p = parts
    if not t:
        return np.zeros(0), np.zeros(0, dtype=np.int64), np.zeros((0, d))
    return np.concatenate(t), np.concatenate(i), np.concatenate(p).reshape(-1, d)


def _share(part: int, whole: int) -> float:
    return part / whole if whole else math.nan


# ----------------------------------------------------------------------------- scoring


def score_self_reports(
    truth_times,
    truth_ids,
    truth_positions,
    track_times,
    track_ids,
    track_positions,
    *,
    window: float,
    c: float,
    max_gap: float = 600.0,
    duration: float | None = None,
    t0: float | None = None,
    hold: float = 60.0,
    turn_rate: float = 1.0,
    turn_span: float = 30.0,
    min_speed: float = 1.0,
    pair_distance: float = 2000.0,
) -> SelfReportScore:
    """Score tracks against self-reports at instants ``t0 + k·window``.

    Parameters
    ----------
    truth_times, truth_ids, truth_positions : (R,), (R,), (R, d)
        The targets' own reports: time (s), integer identity, position in a
        local frame (e.g. east/north metres). Irregular in time, any order.
    track_times, track_ids, track_positions : (S,), (S,), (S, d)
        The confirmed tracks' estimates (same time base and frame); one row
        per (time, track id).
    window : float, > 0
        Spacing of the evaluation instants (s), and how recent a track's
        estimate must be to count at an instant: τ in (t − window, t].
    c : float, > 0
        GOSPA cut-off and association gate (position unit).
    max_gap : float, > 0 (∞ allowed)
        Longest gap between two reports of an identity across which it is
        interpolated; inside a longer gap it is not present.
    duration : float, > 0, optional
        Hours of data for the false-track rate = duration / 3600 (s); default
        the span of the instants.
    t0 : float, optional
        First instant; default the first report time (the first track time
        when there is no report). Give the tracker's first scan time to put
        the instants on its scans (no lag: module docstring).
    hold : float, > 0
        Seconds of associated instants that make a track id *held* by an
        identity (``tracks_per_identity_held``); default one minute.
    turn_rate : float, > 0
        °/s above which a truth point is a manoeuvre (classes in the module
        docstring).
    turn_span : float, > 0
        Seconds either side of an instant over which the heading change is taken.
    min_speed : float, ≥ 0
        Position units per second below which a chord has no heading (not a
        manoeuvre).
    pair_distance : float, > 0
        A truth point with another identity this close at the same instant is
        in a close pair (position units).

    Returns
    -------
    SelfReportScore
        The figures of the module docstring; ``.as_dict()`` for JSON,
        ``.summary()`` for one line.

    Examples
    --------
    One ship reporting every 10 s, tracked exactly:

    >>> import numpy as np
    >>> t = np.arange(0.0, 100.0, 10.0)
    >>> xy = np.c_[5.0 * t, 0.0 * t]
    >>> s = score_self_reports(t, np.zeros(10, int), xy, t, np.ones(10, int), xy,
    ...                        window=30.0, c=500.0)
    >>> s.coverage, s.purity, s.gospa_mean
    (1.0, 1.0, 0.0)
    """
    window = as_float(window, "window", minimum=0.0, open_min=True)
    c = as_float(c, "c", minimum=0.0, open_min=True)
    if isinstance(max_gap, float | np.floating) and max_gap == math.inf:
        max_gap = math.inf
    else:
        max_gap = as_float(max_gap, "max_gap", minimum=0.0, open_min=True)
    if duration is not None:
        duration = as_float(duration, "duration", minimum=0.0, open_min=True)
    if t0 is not None:
        t0 = as_float(t0, "t0")
    hold = as_float(hold, "hold", minimum=0.0, open_min=True)
    turn_rate = as_float(turn_rate, "turn_rate", minimum=0.0, open_min=True)
    turn_span = as_float(turn_span, "turn_span", minimum=0.0, open_min=True)
    min_speed = as_float(min_speed, "min_speed", minimum=0.0)
    pair_distance = as_float(pair_distance, "pair_distance", minimum=0.0, open_min=True)
    rt, ri, rp = _table(truth_times, truth_ids, truth_positions, "truth")
    st, si, sp = _table(track_times, track_ids, track_positions, "track")
    if rp.shape[0] == 0 and sp.shape[0] == 0:
        d = max(rp.shape[1], sp.shape[1], 1)
    else:
        d = rp.shape[1] if rp.shape[0] else sp.shape[1]
    # an empty table carries no dimension: it adopts the other table's
    if rp.shape[0] == 0:
        rp = rp.reshape(0, d)
    if sp.shape[0] == 0:
        sp = sp.reshape(0, d)
    if rp.shape[1] != sp.shape[1]:
        raise ValueError(
            f"truth_positions are {rp.shape[1]}-D but track_positions are {sp.shape[1]}-D"
        )
    if st.size:
        if _unique_pairs(si, st)[0].size != st.size:
            raise ValueError(
                "track_times/track_ids: a track id appears twice at the same time "
                "(one estimate per track and time)"
            )

    # ---- evaluation instants
    if t0 is None:
        t0 = float(rt.min()) if rt.size else (float(st.min()) if st.size else 0.0)
    ends = [float(x.max()) for x in (rt, st) if x.size]
    if ends and max(ends) >= t0:
        span = (max(ends) - t0) / window
        if span >= MAX_INSTANTS:
            raise ValueError(
                f"window = {window} s gives more than {MAX_INSTANTS} evaluation instants over "
                f"{max(ends) - t0} s of data; use a longer window"
            )
        instants = t0 + window * np.arange(int(math.floor(span)) + 1)
        instants = instants[instants <= max(ends)]
    else:
        instants = np.zeros(0)
    K = instants.size

    sampled, manoeuvre = _sample_truth(
        rt, ri, rp, instants, max_gap, turn_span, min_speed, math.radians(turn_rate)
    )
    truth_s = _stack(sampled, d)
    class_of = np.concatenate(manoeuvre).astype(np.int8) if manoeuvre else np.zeros(0, np.int8)
    class_of[_close_pairs(truth_s[0], truth_s[2], pair_distance)] = 2  # wins over manoeuvre
    tracks_s = _stack(_sample_tracks(st, si, sp, instants, window), d)
    stats = track_statistics(*truth_s, *tracks_s, gate=c, min_fraction=0.5)
    g = gospa_series(*truth_s, *tracks_s, c=c, p=2)

    # ---- GOSPA over all instants (an instant with nothing in it scores 0)
    gk = np.searchsorted(instants, g.times)
    parts = {}
    for name in ("gospa", "localisation", "missed", "false", "n_missed", "n_false"):
        v = np.zeros(K)
        v[gk] = getattr(g, name)
        parts[name] = float(np.mean(v)) if K else math.nan
        if name == "gospa":
            gospa_k = v

    # ---- per identity: instants, associations, coverage, tracks, switches
    ident = np.unique(ri)
    N = ident.size
    n_inst = np.bincount(np.searchsorted(ident, truth_s[1]), minlength=N)
    at, ax, ay = stats.assoc_times, stats.assoc_truth_ids, stats.assoc_track_ids
    ax_idx = np.searchsorted(ident, ax)
    n_assoc = np.bincount(ax_idx, minlength=N)
    with np.errstate(invalid="ignore", divide="ignore"):
        cov_id = np.where(n_inst > 0, n_assoc / np.maximum(n_inst, 1), np.nan)
    pair_x, _, pair_n = _unique_pairs(ax, ay)
    n_trk_id = np.bincount(np.searchsorted(ident, pair_x), minlength=N)
    # ids held: associated at instants covering ≥ hold seconds (n · window ≥ hold)
    held_pair = pair_n * window >= hold
    n_held_id = np.bincount(np.searchsorted(ident, pair_x[held_pair]), minlength=N)
    holding = n_held_id > 0
    # ---- per class of identity-instant: the class of each association's truth point
    # (identity, instant) keys: truth points are unique by them, associations a subset
    truth_key = np.searchsorted(ident, truth_s[1]) * K + np.searchsorted(instants, truth_s[0])
    by_key = np.argsort(truth_key, kind="stable")
    at_row = np.searchsorted(truth_key[by_key], ax_idx * K + np.searchsorted(instants, at))
    assoc_class = class_of[by_key[at_row]] if ax.size else np.zeros(0, np.int8)
    n_class = np.bincount(class_of, minlength=3)
    n_class_assoc = np.bincount(assoc_class, minlength=3)
    o = np.lexsort((at, ax))
    ax_o, ay_o = ax[o], ay[o]
    switch = (ax_o[1:] == ax_o[:-1]) & (ay_o[1:] != ay_o[:-1])
    sw_id = np.bincount(np.searchsorted(ident, ax_o[1:][switch]), minlength=N)
    tracked = n_trk_id > 0

    # ---- per track (present at some instant): instants, associations, purity
    trk = stats.track_ids
    T = trk.size
    trk_inst = np.bincount(np.searchsorted(trk, tracks_s[1]), minlength=T)
    trk_assoc = np.bincount(np.searchsorted(trk, ay), minlength=T)
    best = np.zeros(T, dtype=np.int64)
    if ay.size:
        tp_track, _, tp_n = _unique_pairs(ay, ax)
        np.maximum.at(best, np.searchsorted(trk, tp_track), tp_n)
    with_assoc = trk_assoc > 0
    purity_trk = np.full(T, np.nan)
    purity_trk[with_assoc] = best[with_assoc] / trk_assoc[with_assoc]

    n_id_inst = int(truth_s[0].size)
    if duration is not None:
        hours = duration / 3600.0
    else:
        hours = float(instants[-1] - instants[0]) / 3600.0 if K else math.nan
    n_false = int(stats.n_false_tracks)
    return SelfReportScore(
        n_instants=int(K),
        window=window,
        c=c,
        max_gap=max_gap,
        t0=float(t0),
        hours=hours,
        coverage=int(ax.size) / n_id_inst if n_id_inst else math.nan,
        n_identity_instants=n_id_inst,
        n_associated=int(ax.size),
        n_identities=int(N),
        n_identities_tracked=int(tracked.sum()),
        tracks_per_identity=float(np.mean(n_trk_id[tracked])) if tracked.any() else math.nan,
        n_id_switches=int(switch.sum()),
        purity=float(best.sum() / trk_assoc.sum()) if with_assoc.any() else math.nan,
        purity_unweighted=float(np.mean(purity_trk[with_assoc])) if with_assoc.any() else math.nan,
        n_false_tracks=n_false,
        false_tracks_per_hour=n_false / hours if hours > 0 else math.nan,
        n_confirmed_track_ids=int(np.unique(si).size),
        n_tracks_present=int(T),
        gospa_mean=parts["gospa"],
        gospa_localisation=parts["localisation"],
        gospa_missed=parts["missed"],
        gospa_false=parts["false"],
        missed_per_instant=parts["n_missed"],
        false_per_instant=parts["n_false"],
        hold=hold,
        tracks_per_identity_held=float(np.mean(n_held_id[holding])) if holding.any() else math.nan,
        n_identities_held=int(holding.sum()),
        turn_rate=turn_rate,
        turn_span=turn_span,
        min_speed=min_speed,
        pair_distance=pair_distance,
        n_straight=int(n_class[0]),
        n_manoeuvre=int(n_class[1]),
        n_close_pair=int(n_class[2]),
        coverage_straight=_share(int(n_class_assoc[0]), int(n_class[0])),
        coverage_manoeuvre=_share(int(n_class_assoc[1]), int(n_class[1])),
        coverage_close_pair=_share(int(n_class_assoc[2]), int(n_class[2])),
        lost_straight=_share(int(n_class[0] - n_class_assoc[0]), int(n_class[0])),
        lost_manoeuvre=_share(int(n_class[1] - n_class_assoc[1]), int(n_class[1])),
        lost_close_pair=_share(int(n_class[2] - n_class_assoc[2]), int(n_class[2])),
        class_of=class_of,
        identity_tracks_held=n_held_id,
        instants=instants,
        gospa_per_instant=gospa_k,
        n_truths_per_instant=np.bincount(np.searchsorted(instants, truth_s[0]), minlength=K),
        n_tracks_per_instant=np.bincount(np.searchsorted(instants, tracks_s[0]), minlength=K),
        identity_ids=ident,
        identity_instants=n_inst,
        identity_associated=n_assoc,
        identity_coverage=cov_id,
        identity_tracks=n_trk_id,
        identity_switches=sw_id,
        track_ids=trk,
        track_instants=trk_inst,
        track_associated=trk_assoc,
        track_purity=purity_trk,
        truth_sampled=truth_s,
        tracks_sampled=tracks_s,
        statistics=stats,
    )
