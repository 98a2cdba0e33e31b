"""Tracking quality from nothing: time to confirm, targets held, false tracks, GOSPA.

Inputs are the flat tables of :func:`jointtrack.metrics.track_statistics` — the
truth ``(truth_times, truth_ids, truth_positions)`` and the *confirmed* tracks
a tracker reported ``(track_times, track_ids, track_positions)`` — plus,
optionally, each truth's first detection time (``first_detection``, a mapping
truth id → time) and the list of all scan times (``scan_times``).

Scans. The scan list is ``scan_times`` (sorted, duplicates dropped) when given
— it must contain every truth and track time, and scans holding neither
truths nor tracks then count (as zero false tracks and zero GOSPA) — else the
distinct times of both tables. A truth's or track's *scan index* is the
position of its time in that list; all times are matched exactly.

Association. Nothing is re-implemented: the truth ↔ track associations are
those of :func:`~jointtrack.metrics.track_statistics` with cut-off ``gate``
(per scan, the GOSPA assignment with c = ``gate``, p = 2; a pair is kept when
its distance is < ``gate``), and the GOSPA terms those of
:func:`~jointtrack.metrics.gospa_series` with c = ``gate``, p = 2, α = 2 —
the same per-scan assignment. A truth is *associated* at a scan when
track_statistics pairs it with a track there.

Definitions (per truth, then over the run):

* **first detection scan**: the scan of ``first_detection[id]`` (a benchmark
  derives it from the detections' origins; it must be a time at which the
  truth exists); truths absent from ``first_detection`` were never detected
  and take no part in the time-to-confirm and held statistics. Without
  ``first_detection``: the truth's first scan of existence.
* **confirmation scan**: the first scan at or after the first detection scan
  at which the truth is associated with a (confirmed) track. Associations
  before the first detection are ignored: no track can be of a target that
  was never seen.
* **time to confirm** = confirmation scan index − first detection scan index,
  in scans (0: confirmed at the scan of its first detection). A detected truth
  that is never associated has time to confirm = ∞ and is **never confirmed**
  — unless ``confirm_window`` = W is given and it ceased to exist less than W
  scans after its first detection (last scan index − first detection index <
  W): then whether it would have been confirmed within W scans is unknown and
  it is **censored** (left out of the median, the max and the never-confirmed
  count; counted in ``n_censored``). Reported: median and max over the
  detected, uncensored truths (max = ∞ when any is never confirmed; NaN when
  there is none) and the number never confirmed.
* **held fraction**: over all truth-scans *strictly after* each truth's
  confirmation scan (every scan at which the truth exists), the fraction at
  which the truth is associated (``n_held_scans / n_after_scans``; NaN when
  there are no such truth-scans). **Worst held**: the smallest per-truth held
  fraction among truths with at least one scan after confirmation (NaN if
  none).
* **false confirmed tracks per scan**: the mean over all scans of (confirmed
  tracks present − tracks associated with a truth), i.e. false track-scans /
  number of scans. (It equals the mean number of GOSPA false targets per scan:
  the same assignment.)
* **breaks**, **fragmentations**, **identity switches**: those of
  :func:`~jointtrack.metrics.track_statistics` (a break: associated at the
  truth's previous scan of existence and not at this one; a switch: associated
  with a different track from the one it was last associated with).
* **GOSPA**: the mean over all scans of the per-scan GOSPA d_2^(c,2) (c =
  ``gate``) and the mean over all scans of each of its parts — localisation
  Σ d², missed (c²/2)·n_missed and false (c²/2)·n_false, on the squared scale,
  so ``gospa_localisation + gospa_missed + gospa_false`` = mean of GOSPA² —
  plus the mean numbers of missed and false targets per scan.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from jointtrack.metrics.ospa import _pair_tables, gospa_series
from jointtrack.metrics.tracks import TrackStatistics, track_statistics

__all__ = ["TrackingQuality", "tracking_quality"]

_SCALARS = (
    "n_scans n_truths n_detected n_confirmed n_never_confirmed n_censored "
    "time_to_confirm_median time_to_confirm_max held_fraction held_worst n_held_scans "
    "n_after_scans false_per_scan n_false_track_scans n_breaks n_fragmentations "
    "n_id_switches gospa_mean gospa_localisation gospa_missed gospa_false "
    "gospa_missed_per_scan gospa_false_per_scan gate confirm_window"
).split()


@dataclass(frozen=True, eq=False)
class TrackingQuality:
    """Result of :func:`tracking_quality` (definitions in the module docstring).

    Scalars: see :meth:`as_dict`. Per truth (sorted ``truth_ids``, (N,)):
    ``first_detection_scan`` (scan index, −1 if never detected),
    ``confirmation_scan`` (−1 if never confirmed), ``time_to_confirm``
    (float scans; ∞ never confirmed, NaN never detected), ``censored`` (bool)
    and ``held_per_truth`` (NaN without a scan after confirmation). Per scan
    (``scan_times``, (K,)): ``n_truths_per_scan``, ``n_tracks_per_scan``,
    ``n_associated_per_scan``, ``n_false_per_scan`` (ints) and
    ``gospa_per_scan``. ``statistics`` is the underlying
    :class:`~jointtrack.metrics.TrackStatistics`.
    """

    n_scans: int
    n_truths: int
    n_detected: int
    n_confirmed: int
    n_never_confirmed: int
    n_censored: int
    time_to_confirm_median: float
    time_to_confirm_max: float
    held_fraction: float
    held_worst: float
    n_held_scans: int
    n_after_scans: int
    false_per_scan: float
    n_false_track_scans: int
    n_breaks: int
    n_fragmentations: int
    n_id_switches: int
    gospa_mean: float
    gospa_localisation: float
    gospa_missed: float
    gospa_false: float
    gospa_missed_per_scan: float
    gospa_false_per_scan: float
    gate: float
    confirm_window: int | None
    truth_ids: np.ndarray
    first_detection_scan: np.ndarray
    confirmation_scan: np.ndarray
    time_to_confirm: np.ndarray
    censored: np.ndarray
    held_per_truth: np.ndarray
    scan_times: np.ndarray
    n_truths_per_scan: np.ndarray
    n_tracks_per_scan: np.ndarray
    n_associated_per_scan: np.ndarray
    n_false_per_scan: np.ndarray
    gospa_per_scan: np.ndarray
    statistics: TrackStatistics

    def as_dict(self) -> dict:
        """The scalar results as a plain dict (for JSON reports; ∞/NaN kept as floats)."""
        return {k: getattr(self, k) for k in _SCALARS}


def _scan_list(scan_times, truth_t: np.ndarray, track_t: np.ndarray) -> np.ndarray:
    used = np.unique(np.concatenate([truth_t, track_t]))
    if scan_times is None:
        return used
    try:
        s = np.asarray(scan_times, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError("scan_times must be a 1-D array of numbers") from None
    if s.ndim != 1:
        raise ValueError(f"scan_times must be 1-D, got shape {s.shape}")
    if not np.all(np.isfinite(s)):
        raise ValueError("scan_times must be finite")
    s = np.unique(s)
    missing = used[~np.isin(used, s)]
    if missing.size:
        raise ValueError(
            "scan_times must contain every truth and track time; missing "
            f"{missing.size} time(s), the first {float(missing[0])!r}"
        )
    return s


def _first_detection(first_detection, tru_ids, truth) -> dict:
    """Validate ``first_detection``: {truth id: time at which that truth exists}."""
    if not isinstance(first_detection, Mapping):
        raise ValueError(
            "first_detection must be a mapping {truth id: time}, got "
            f"{type(first_detection).__name__}"
        )
    known = set(tru_ids.tolist())
    exists = set(zip(truth[1].tolist(), truth[0].tolist(), strict=True))
    out = {}
    for key, value in first_detection.items():
        if isinstance(key, bool) or not isinstance(key, numbers.Integral):
            raise ValueError(f"first_detection: keys must be integer truth ids, got {key!r}")
        try:
            t = float(value)
        except (TypeError, ValueError):
            raise ValueError(
                f"first_detection: the time of truth {key} must be a number, got {value!r}"
            ) from None
        if not math.isfinite(t):
            raise ValueError(f"first_detection: the time of truth {key} must be finite, got {t}")
        if int(key) not in known:
            raise ValueError(f"first_detection: truth id {key} is not in truth_ids")
        if (int(key), t) not in exists:
            raise ValueError(
                f"first_detection: truth {key} does not exist at time {t} (a detection "
                "comes from a target that exists)"
            )
        out[int(key)] = t
    return out


def _median(v: np.ndarray) -> float:
    return float(np.median(v)) if v.size else float("nan")


def tracking_quality(
    truth_times,
    truth_ids,
    truth_positions,
    track_times,
    track_ids,
    track_positions,
    *,
    gate: float,
    first_detection: Mapping | None = None,
    scan_times=None,
    confirm_window: int | None = None,
) -> TrackingQuality:
    """Time to confirm, targets held, false tracks per scan, breaks, switches and GOSPA.

    Parameters
    ----------
    truth_times, truth_ids, truth_positions : (R,), (R,), (R, d) truth table.
    track_times, track_ids, track_positions : (S,), (S,), (S, d) table of the
        *confirmed* tracks reported at each scan.
    gate : association cut-off (same unit as the positions), > 0: the cut-off
        of :func:`track_statistics` and the GOSPA c.
    first_detection : optional mapping truth id → time of the truth's first
        detection (a time at which the truth exists). Truths not in it were
        never detected. Default: every truth is first detected at its first
        scan of existence.
    scan_times : optional 1-D array of every scan time (must contain every
        truth and track time); scans with no truth and no track then count.
        Default: the distinct times of both tables.
    confirm_window : optional integer W ≥ 1: a detected truth that is never
        confirmed and ceased to exist less than W scans after its first
        detection is censored (module docstring). Default: no censoring.

    Returns
    -------
    TrackingQuality
        Definitions in the module docstring.
    """
    if confirm_window is not None and (
        isinstance(confirm_window, bool)
        or not isinstance(confirm_window, numbers.Integral)
        or confirm_window < 1
    ):
        raise ValueError(f"confirm_window must be None or an integer >= 1, got {confirm_window!r}")
    stats = track_statistics(
        truth_times, truth_ids, truth_positions, track_times, track_ids, track_positions, gate
    )
    gate = stats.gate
    truth, tracks = _pair_tables(
        (truth_times, truth_ids, truth_positions), (track_times, track_ids, track_positions)
    )
    scans = _scan_list(scan_times, truth[0], tracks[0])
    K = scans.size
    tru_ids = np.unique(truth[1])
    N = tru_ids.size
    fd_map = None if first_detection is None else _first_detection(first_detection, tru_ids, truth)

    # ---- per truth-row: scan index and association flag
    row_scan = np.searchsorted(scans, truth[0])
    row_truth = np.searchsorted(tru_ids, truth[1])
    assoc_key = np.searchsorted(tru_ids, stats.assoc_truth_ids) * K + np.searchsorted(
        scans, stats.assoc_times
    )
    row_assoc = np.isin(row_truth * K + row_scan, assoc_key)

    first_scan = np.full(N, -1, dtype=np.int64)
    conf_scan = np.full(N, -1, dtype=np.int64)
    last_scan = np.full(N, -1, dtype=np.int64)
    held = np.full(N, np.nan)
    n_held = np.zeros(N, dtype=np.int64)
    n_after = np.zeros(N, dtype=np.int64)
    order = np.lexsort((row_scan, row_truth))
    starts = np.searchsorted(row_truth[order], np.arange(N + 1))
    for j in range(N):
        rows = order[starts[j] : starts[j + 1]]
        s, a = row_scan[rows], row_assoc[rows]
        last_scan[j] = s[-1]
        if fd_map is None:
            first_scan[j] = s[0]
        elif int(tru_ids[j]) in fd_map:
            first_scan[j] = int(np.searchsorted(scans, fd_map[int(tru_ids[j])]))
        else:
            continue  # never detected
        hit = np.flatnonzero(a & (s >= first_scan[j]))
        if hit.size == 0:
            continue
        conf_scan[j] = s[hit[0]]
        after = s > conf_scan[j]
        n_after[j] = int(after.sum())
        n_held[j] = int((a & after).sum())
        if n_after[j]:
            held[j] = n_held[j] / n_after[j]

    detected = first_scan >= 0
    confirmed = conf_scan >= 0
    ttc = np.full(N, np.nan)
    ttc[detected] = np.inf
    ttc[confirmed] = (conf_scan - first_scan)[confirmed].astype(np.float64)
    censored = np.zeros(N, dtype=bool)
    if confirm_window is not None:
        censored = detected & ~confirmed & (last_scan - first_scan < confirm_window)
    judged = ttc[detected & ~censored]
    n_never = int(np.sum(detected & ~confirmed & ~censored))
    after_total = int(n_after.sum())
    held_total = int(n_held.sum())
    with_after = ~np.isnan(held)

    # ---- per scan: truths, tracks, associations, false tracks, GOSPA
    n_truth_k = np.bincount(row_scan, minlength=K)
    n_track_k = np.bincount(np.searchsorted(scans, tracks[0]), minlength=K)
    n_assoc_k = np.bincount(np.searchsorted(scans, stats.assoc_times), minlength=K)
    n_false_k = n_track_k - n_assoc_k
    g = gospa_series(truth[0], truth[1], truth[2], tracks[0], tracks[1], tracks[2], c=gate, p=2)
    gk = np.searchsorted(scans, g.times)
    parts = {}
    for name in ("gospa", "localisation", "missed", "false", "n_missed", "n_false"):
        v = np.zeros(K)
        v[gk] = getattr(g, name)
        parts[name] = v

    def mean(v):
        return float(np.mean(v)) if K else float("nan")

    return TrackingQuality(
        n_scans=int(K),
        n_truths=int(N),
        n_detected=int(detected.sum()),
        n_confirmed=int(confirmed.sum()),
        n_never_confirmed=n_never,
        n_censored=int(censored.sum()),
        time_to_confirm_median=_median(judged),
        time_to_confirm_max=float(np.max(judged)) if judged.size else float("nan"),
        held_fraction=held_total / after_total if after_total else float("nan"),
        held_worst=float(np.min(held[with_after])) if with_after.any() else float("nan"),
        n_held_scans=held_total,
        n_after_scans=after_total,
        false_per_scan=mean(n_false_k),
        n_false_track_scans=int(n_false_k.sum()),
        n_breaks=stats.n_breaks,
        n_fragmentations=stats.n_fragmentations,
        n_id_switches=stats.n_id_switches,
        gospa_mean=mean(parts["gospa"]),
        gospa_localisation=mean(parts["localisation"]),
        gospa_missed=mean(parts["missed"]),
        gospa_false=mean(parts["false"]),
        gospa_missed_per_scan=mean(parts["n_missed"]),
        gospa_false_per_scan=mean(parts["n_false"]),
        gate=gate,
        confirm_window=None if confirm_window is None else int(confirm_window),
        truth_ids=tru_ids,
        first_detection_scan=first_scan,
        confirmation_scan=conf_scan,
        time_to_confirm=ttc,
        censored=censored,
        held_per_truth=held,
        scan_times=scans,
        n_truths_per_scan=n_truth_k,
        n_tracks_per_scan=n_track_k,
        n_associated_per_scan=n_assoc_k,
        n_false_per_scan=n_false_k,
        gospa_per_scan=parts["gospa"],
        statistics=stats,
    )
