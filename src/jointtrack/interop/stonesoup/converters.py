"""Converters between Stone Soup objects and jointtrack's arrays.

jointtrack's states are positions first (``[x, y, vx, vy]``); Stone Soup's
constant-velocity models interleave (``[x, vx, y, vy]``): the converters reorder
(``interleave=True``) or take an explicit index.
"""

from __future__ import annotations

import datetime as _dt
from collections.abc import Iterable

import numpy as np
from stonesoup.types.groundtruth import GroundTruthPath
from stonesoup.types.state import GaussianState
from stonesoup.types.track import Track

__all__ = ["scans_from_stonesoup", "tracks_to_stonesoup", "truth_from_stonesoup"]


def _index(n: int, dim: int, interleave: bool, state_index) -> np.ndarray:
    """``theirs = ours[index]``: jointtrack's positions-first state to Stone Soup's order."""
    if state_index is not None:
        idx = np.asarray(state_index)
        if idx.dtype.kind not in "iu" or sorted(idx.tolist()) != list(range(n)):
            raise ValueError(
                f"state_index must be a permutation of 0..{n - 1}, got {state_index!r}"
            )
        return idx.astype(np.int64)
    if not interleave:
        return np.arange(n)
    if isinstance(dim, bool) or not isinstance(dim, int) or dim < 1 or n % dim:
        raise ValueError(f"dim must be a positive integer dividing the state size {n}, got {dim!r}")
    order = n // dim
    # Stone Soup position k, derivative o sits at k·order + o; ours at o·dim + k
    return np.array([o * dim + k for k in range(dim) for o in range(order)], np.int64)


def _naive_utc(t) -> _dt.datetime:
    if not isinstance(t, _dt.datetime):
        raise TypeError(f"timestamps must be datetime.datetime, got {type(t).__name__}")
    if t.tzinfo is not None:
        return t.astimezone(_dt.UTC).replace(tzinfo=None)
    return t


def scans_from_stonesoup(scans: Iterable) -> list[tuple[_dt.datetime, np.ndarray]]:
    """Stone Soup detections as jointtrack scans ``[(timestamp, z (M, d)), …]``.

    ``scans`` is what a Stone Soup detector yields: ``(timestamp, detections)``
    pairs (a set of ``Detection``). ``z`` holds each detection's
    ``state_vector`` as a row, sorted lexicographically, so the order does not
    depend on set iteration (which follows object addresses). Pass the scans to
    :meth:`jointtrack.trackers.JPDATracker.step` as they are: it accepts
    datetimes.
    """
    out = []
    for item in scans:
        try:
            timestamp, detections = item
        except (TypeError, ValueError):
            raise TypeError(
                "scans must be (timestamp, detections) pairs, as a Stone Soup detector yields"
            ) from None
        rows = []
        for d in detections:
            if getattr(d, "state_vector", None) is None:
                raise TypeError(
                    f"scans at {timestamp}: a {type(d).__name__} is not a Stone Soup detection"
                )
            rows.append(np.asarray(d.state_vector, float).reshape(-1))
        dims = {r.size for r in rows}
        if len(dims) > 1:
            raise ValueError(f"detections at {timestamp} have different sizes {sorted(dims)}")
        z = np.array(rows, float).reshape(len(rows), dims.pop() if dims else 0)
        if z.size and not np.isfinite(z).all():
            raise ValueError(f"a detection at {timestamp} is not finite")
        if len(z) > 1:
            z = z[np.lexsort(z.T[::-1])]
        out.append((timestamp, z))
    return out


def truth_from_stonesoup(
    paths: Iterable,
    *,
    epoch: _dt.datetime,
    dim: int = 2,
    interleave: bool = True,
    state_index=None,
):
    """Ground-truth paths as jointtrack's truth table ``(time, id, x)``.

    ``time`` (R,) seconds after ``epoch``; ``id`` (R,) the path's position in
    ``paths`` (sorted by Stone Soup ``id`` first, so the numbering is stable);
    ``x`` (R, n) the states in jointtrack's positions-first order (the inverse
    of :func:`tracks_to_stonesoup`'s reordering). ``x[:, :dim]`` are the
    positions :func:`jointtrack.metrics.gospa_series` compares.
    """
    epoch = _naive_utc(epoch)
    paths = sorted(paths, key=lambda p: str(p.id))
    times, ids, states = [], [], []
    idx = None
    for k, path in enumerate(paths):
        if not isinstance(path, GroundTruthPath):
            raise TypeError(f"paths must be GroundTruthPath objects, got {type(path).__name__}")
        for st in path.states:
            sv = np.asarray(st.state_vector, float).reshape(-1)
            if idx is None:
                idx = _index(sv.size, dim, interleave, state_index)
            if sv.size != idx.size:
                raise ValueError(f"path {path.id} has states of size {sv.size}, not {idx.size}")
            ours = np.empty_like(sv)
            ours[idx] = sv
            times.append((_naive_utc(st.timestamp) - epoch).total_seconds())
            ids.append(k)
            states.append(ours)
    n = 0 if idx is None else idx.size
    return (
        np.asarray(times, float),
        np.asarray(ids, np.int64),
        np.asarray(states, float).reshape(len(states), n),
    )


def tracks_to_stonesoup(
    history,
    *,
    epoch: _dt.datetime | None = None,
    dim: int = 2,
    interleave: bool = True,
    state_index=None,
) -> set:
    """A :class:`jointtrack.trackers.TrackHistory` as a set of Stone Soup ``Track`` s.

    One ``Track`` per track id (``Track.id`` = ``"jointtrack-<id>"``), one
    ``GaussianState`` per row, with the state and covariance reordered to Stone
    Soup's layout (module docstring). Timestamps: ``epoch + time``; without
    ``epoch`` the history's ``time_origin`` (set when the tracker was given
    datetimes), as a naive UTC datetime like Stone Soup's own.
    """
    from jointtrack.trackers import TrackHistory

    if not isinstance(history, TrackHistory):
        raise TypeError(
            f"history must be a jointtrack TrackHistory (tracker.history()), got "
            f"{type(history).__name__}"
        )
    if epoch is None:
        if history.time_origin is None:
            raise ValueError("the history has no time_origin (the scans were seconds): pass epoch=")
        stamps = history.datetimes().astype("datetime64[us]").tolist()
    else:
        epoch = _naive_utc(epoch)
        stamps = [epoch + _dt.timedelta(seconds=float(t)) for t in history.time]
    idx = _index(history.state_dim, dim, interleave, state_index)
    x = history.x[:, idx]
    P = history.P[:, idx][:, :, idx]
    tracks = {}
    for r, tid in enumerate(history.track_id.tolist()):
        trk = tracks.get(tid)
        if trk is None:
            trk = tracks[tid] = Track(id=f"jointtrack-{tid}")
        trk.append(GaussianState(x[r].reshape(-1, 1), P[r], timestamp=stamps[r]))
    return set(tracks.values())
