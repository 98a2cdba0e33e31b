"""Track-level statistics: true and false tracks, breaks, identity switches, RMSE.

Inputs are two flat tables, one row per (object, time) — the truth trajectories
``(truth_times, truth_ids, truth_positions)`` and the estimated tracks
``(track_times, track_ids, track_positions)`` (``positions`` are ``(R, d)``).
Scans are the distinct time values of both tables, matched exactly.

Association, per scan k: the truths X_k and tracks Y_k present at that time
are paired by the GOSPA assignment with cut-off ``gate`` and p = 2 (see
:mod:`jointtrack.metrics.ospa`): ``jointtrack.assignment.linear_assignment`` minimises
Σ min(‖x − y‖, gate)² over min(|X_k|, |Y_k|) pairs, and only pairs with
‖x − y‖ < gate are kept. A truth–track pair kept at scan k is an *association*.

Definitions (counts over the whole run):

* **true track** (a confirmed track of a real target): an estimated track
  associated with some truth in at least ``min_fraction`` (default ½) of the
  scans at which it exists; its *label* is the truth it is associated with
  most often. Every other track is a **false track**.
* **truths tracked**: truths associated with some track at ≥ 1 scan.
* **track break**: a truth associated at its previous scan of existence and
  not associated at the current one (the track was lost or drifted beyond the
  gate) — counted once per tracked → untracked transition.
* **fragmentation**: a truth that becomes associated again after at least one
  unassociated scan following an association (CLEAR-MOT "FM", Li, Huang &
  Nevatia, CVPR 2009); so ``n_fragmentations ≤ n_breaks``.
* **identity switch**: a truth associated with a different track from the one
  it was last associated with (CLEAR-MOT "IDSW", Bernardin & Stiefelhagen,
  EURASIP J. Image Video Process. 2008), whether or not scans in between were
  unassociated.
* **position RMSE**: √(mean ‖x − y‖² over all associations) (NaN if none).
* **coverage**: associated truth-scans / all truth-scans (NaN if no truth).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from jointtrack.metrics.ospa import _pair_tables, _scan_gospa

__all__ = ["TrackStatistics", "track_statistics"]


@dataclass(frozen=True, eq=False)
class TrackStatistics:
    """Result of :func:`track_statistics` (definitions in the module docstring).

    Arrays: ``assoc_times``, ``assoc_truth_ids``, ``assoc_track_ids``,
    ``assoc_errors`` (A,) — every association (time, truth, track, distance);
    ``track_ids`` (T,) every estimated track id (sorted) and ``track_labels``
    (T,) the truth id each is a true track of, or −1 for a false track.
    """

    n_truths: int
    n_tracks: int
    n_true_tracks: int
    n_false_tracks: int
    n_truths_tracked: int
    n_breaks: int
    n_fragmentations: int
    n_id_switches: int
    rmse: float
    coverage: float
    gate: float
    track_ids: np.ndarray
    track_labels: np.ndarray
    assoc_times: np.ndarray
    assoc_truth_ids: np.ndarray
    assoc_track_ids: np.ndarray
    assoc_errors: np.ndarray

    def as_dict(self) -> dict:
        """The scalar statistics as a plain dict (for JSON reports)."""
        keys = (
            "n_truths n_tracks n_true_tracks n_false_tracks n_truths_tracked n_breaks "
            "n_fragmentations n_id_switches rmse coverage gate"
        ).split()
        return {k: getattr(self, k) for k in keys}


def track_statistics(
    truth_times,
    truth_ids,
    truth_positions,
    track_times,
    track_ids,
    track_positions,
    gate: float,
    min_fraction: float = 0.5,
) -> TrackStatistics:
    """Associate tracks to truths scan by scan and count track-level events.

    Parameters
    ----------
    truth_times, truth_ids, truth_positions : (R,), (R,), (R, d) truth table.
    track_times, track_ids, track_positions : (S,), (S,), (S, d) track table.
    gate : association distance (same unit as the positions), > 0.
    min_fraction : a track is a *true* track when associated in at least this
        fraction of its scans, in (0, 1].
    """
    try:
        gate = float(gate)
        min_fraction = float(min_fraction)
    except (TypeError, ValueError):
        raise ValueError("gate and min_fraction must be numbers") from None
    if not (math.isfinite(gate) and gate > 0):
        raise ValueError(f"gate must be finite and > 0, got {gate}")
    if not (0 < min_fraction <= 1):
        raise ValueError(f"min_fraction must be in (0, 1], got {min_fraction}")
    truth, tracks = _pair_tables(
        (truth_times, truth_ids, truth_positions), (track_times, track_ids, track_positions)
    )

    a_t, a_x, a_y, a_e = [], [], [], []
    # partner[r] = track id associated with truth row r, or -1
    partner = np.full(truth[0].size, -1, dtype=np.int64)
    for _k, t, g, rows, partners in _scan_gospa(truth, tracks, gate, 2):
        if g.n_assigned:
            partner[rows] = partners
            a_t.append(np.full(g.n_assigned, t))
            a_x.append(truth[1][rows])
            a_y.append(partners)
            a_e.append(g.distances)
    if a_t:
        at, ax, ay, ae = (np.concatenate(v) for v in (a_t, a_x, a_y, a_e))
    else:
        at, ae = np.zeros(0), np.zeros(0)
        ax = ay = np.zeros(0, dtype=np.int64)

    # ---- per track: true or false, label = most frequent truth
    trk_ids, trk_len = np.unique(tracks[1], return_counts=True)
    labels = np.full(trk_ids.size, -1, dtype=np.int64)
    if ay.size:
        pairs, pair_n = np.unique(np.stack([ay, ax], axis=1), axis=0, return_counts=True)
        # for each track keep its most frequent truth (ties: smallest truth id)
        order = np.lexsort((pairs[:, 1], -pair_n, pairs[:, 0]))
        pairs, pair_n = pairs[order], pair_n[order]
        first = np.ones(pairs.shape[0], dtype=bool)
        first[1:] = pairs[1:, 0] != pairs[:-1, 0]
        best_trk, best_truth, best_n = pairs[first, 0], pairs[first, 1], pair_n[first]
        idx = np.searchsorted(trk_ids, best_trk)
        ok = best_n >= min_fraction * trk_len[idx] - 1e-12
        labels[idx[ok]] = best_truth[ok]
    n_true = int(np.sum(labels >= 0))

    # ---- per truth: breaks, fragmentations, switches (walk each truth's scans in time)
    tru_ids = np.unique(truth[1])
    n_breaks = n_frag = n_switch = 0
    if truth[0].size:
        order = np.lexsort((truth[0], truth[1]))
        ids_o, part_o = truth[1][order], partner[order]
        same = np.zeros(ids_o.size, dtype=bool)
        same[1:] = ids_o[1:] == ids_o[:-1]  # row continues the previous row's truth
        assoc = part_o >= 0
        prev_assoc = np.zeros_like(assoc)
        prev_assoc[1:] = assoc[:-1]
        n_breaks = int(np.sum(same & prev_assoc & ~assoc))
        # consecutive associations of the same truth: partner change = switch,
        # an unassociated scan in between = fragmentation
        pos = np.flatnonzero(assoc)
        ids_a, part_a = ids_o[pos], part_o[pos]
        cont = ids_a[1:] == ids_a[:-1]
        n_switch = int(np.sum(cont & (part_a[1:] != part_a[:-1])))
        n_frag = int(np.sum(cont & (np.diff(pos) > 1)))
    n_tracked = int(np.unique(ax).size)
    rmse = float(np.sqrt(np.mean(ae**2))) if ae.size else float("nan")
    coverage = float(ax.size / truth[0].size) if truth[0].size else float("nan")
    return TrackStatistics(
        n_truths=int(tru_ids.size),
        n_tracks=int(trk_ids.size),
        n_true_tracks=n_true,
        n_false_tracks=int(trk_ids.size - n_true),
        n_truths_tracked=n_tracked,
        n_breaks=n_breaks,
        n_fragmentations=n_frag,
        n_id_switches=n_switch,
        rmse=rmse,
        coverage=coverage,
        gate=gate,
        track_ids=trk_ids.astype(np.int64),
        track_labels=labels,
        assoc_times=at.astype(np.float64),
        assoc_truth_ids=ax.astype(np.int64),
        assoc_track_ids=ay.astype(np.int64),
        assoc_errors=ae.astype(np.float64),
    )
