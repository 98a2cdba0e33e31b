"""Clusters of tracks that share gated measurements.

Bojilov et al. §2: "all existing targets have to be divided into separate groups
(clusters). Every such a group will contain tracks with overlapping validation
gates and shared observations." Two tracks are in the same cluster when they are
connected in the bipartite gating graph (track i — measurement j whenever j is in
i's gate); the JPDA joint events of different clusters are independent, so the
association problem factorises over clusters.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from jointtrack.assignment._checks import as_weights

__all__ = ["Cluster", "Clustering", "cluster_pair_marginals", "clusters", "has_feasible_event"]


@dataclass(frozen=True)
class Cluster:
    """One connected component of the gating graph.

    ``tracks`` and ``measurements`` are sorted index arrays into the full
    problem. A track whose gate holds no measurement forms a cluster of its own
    with an empty ``measurements`` array.
    """

    tracks: np.ndarray
    measurements: np.ndarray

    def select(self, L, miss) -> tuple[np.ndarray, np.ndarray]:
        """The cluster's sub-problem ``(L[tracks][:, measurements], miss[tracks])``."""
        L = np.asarray(L)
        miss = np.asarray(miss)
        return L[np.ix_(self.tracks, self.measurements)], miss[self.tracks]


@dataclass(frozen=True)
class Clustering:
    """Result of :func:`clusters`.

    Attributes
    ----------
    clusters : tuple of Cluster
        ordered by their smallest track index; every track is in exactly one.
    unassociated : (K,) int array
        measurements in no track's gate (clutter for certain; they belong to
        no cluster).
    track_cluster : (N,) int array
        index into ``clusters`` of each track.
    measurement_cluster : (M,) int array
        index into ``clusters`` of each measurement, −1 for unassociated ones.
    """

    clusters: tuple[Cluster, ...]
    unassociated: np.ndarray
    track_cluster: np.ndarray
    measurement_cluster: np.ndarray

    def __len__(self) -> int:
        return len(self.clusters)

    def __iter__(self):
        return iter(self.clusters)

    def __getitem__(self, k: int) -> Cluster:
        return self.clusters[k]


def _as_mask(mask) -> np.ndarray:
    """A 2-D bool gate mask: booleans as given, anything else through the shared weight check.

    Numbers must pass :func:`~jointtrack.assignment._checks.as_weights` (real,
    finite, ≥ 0; complex, strings, booleans mixed with numbers and integers too
    large for a float are refused, naming ``mask``); non-zero = gated.
    """
    if isinstance(mask, np.ndarray) and mask.dtype == bool:
        arr = mask
    else:
        try:
            arr = np.asarray(mask)
        except (TypeError, ValueError):  # ragged: as_weights names the problem
            arr = None
        if arr is not None and arr.ndim == 1 and arr.size == 0:
            arr = arr.reshape(0, 0)
        if arr is None or arr.dtype != bool:
            arr = as_weights(mask if arr is None or arr.size else arr, "mask") != 0
    if arr.ndim != 2:
        raise ValueError(f"mask must be 2-D (tracks × measurements), got {arr.ndim} dimension(s)")
    return arr


def _is_index_scalar(x) -> bool:
    return isinstance(x, int | np.integer) and not isinstance(x, bool | np.bool_)


def _sparse_pairs(obj):
    """``(n, m, rows, cols)`` if ``obj`` is a sparse gating description, else None.

    Accepted: a :class:`~jointtrack.association.gating.PairGating` (anything with
    ``n_tracks``, ``n_measurements``, ``rows``, ``cols``) or a 4-tuple
    ``(n_tracks, n_measurements, rows, cols)`` of two integers and two 1-D
    index arrays. (A nested sequence of mask rows never has integer first
    elements, so it stays a dense mask.)
    """
    if isinstance(obj, np.ndarray):
        return None
    if all(hasattr(obj, a) for a in ("n_tracks", "n_measurements", "rows", "cols")):
        return obj.n_tracks, obj.n_measurements, obj.rows, obj.cols
    if (
        isinstance(obj, tuple)
        and len(obj) == 4
        and _is_index_scalar(obj[0])
        and _is_index_scalar(obj[1])
        and np.ndim(obj[2]) == 1
        and np.ndim(obj[3]) == 1
    ):
        return obj
    return None


def _check_pairs(n, m, rows, cols) -> tuple[int, int, np.ndarray, np.ndarray]:
    if not (_is_index_scalar(n) and _is_index_scalar(m)) or n < 0 or m < 0:
        raise ValueError(
            f"n_tracks and n_measurements must be non-negative integers, got {n!r}, {m!r}"
        )
    n, m = int(n), int(m)
    out = []
    for name, idx, size in (("rows", rows, n), ("cols", cols, m)):
        a = np.asarray(idx)
        if a.ndim != 1:
            raise ValueError(f"{name} must be a 1-D index array, got {a.ndim} dimension(s)")
        if a.size == 0:
            a = a.astype(np.int64)
        if a.dtype.kind not in "iu":
            raise ValueError(f"{name} must be an integer index array, got dtype {a.dtype}")
        a = a.astype(np.int64, copy=False)
        if a.size and (a.min() < 0 or a.max() >= size):
            bad = a[(a < 0) | (a >= size)][0]
            raise ValueError(f"{name} index {bad} out of range 0..{size - 1}")
        out.append(a)
    if out[0].size != out[1].size:
        raise ValueError(
            f"rows and cols must have the same length, got {out[0].size} and {out[1].size}"
        )
    return n, m, out[0], out[1]


def clusters(mask) -> Clustering:
    """Partition tracks and measurements into independent JPDA clusters.

    Connected components of the bipartite gating graph (Bojilov et al. §2,
    "clusterisation"), computed with
    :func:`scipy.sparse.csgraph.connected_components` (a union–find equivalent,
    O(N + M + nnz)); the clusters are then gathered by a stable sort of the
    labels, so no step costs O(N · clusters).

    Parameters
    ----------
    mask : (N, M) bool array, a likelihood-ratio matrix ``L`` (non-zero = gated),
        a :class:`~jointtrack.association.gating.PairGating` (from
        :func:`~jointtrack.association.gating.gate_pairs`), or a tuple
        ``(n_tracks, n_measurements, rows, cols)`` listing the gated pairs
        (duplicates allowed, any order). The sparse forms never build an N × M
        array and give the identical :class:`Clustering` to the dense mask with
        exactly those entries set.

    Returns
    -------
    Clustering
        clusters (each with sorted track and measurement indices), the
        unassociated measurements, and per-node cluster labels. 0 tracks or 0
        measurements are fine.
    """
    sparse = _sparse_pairs(mask)
    if sparse is not None:
        n, m, rows, cols = _check_pairs(*sparse)
    else:
        mask = _as_mask(mask)
        n, m = mask.shape
        rows, cols = np.nonzero(mask)
    return _clustering_from_pairs(n, m, rows, cols)


#: At most this many gated pairs: components by a union–find over the pairs in Python
#: instead of a sparse graph for scipy (whose set-up costs ~0.3 ms whatever the size:
#: the usual scan of a tracker with a few returns gates a handful of pairs).
_SMALL_PAIRS = 64
#: The ``measurements`` of every cluster whose gates hold none (read-only, so sharing it
#: is safe): most clusters of a scan with few returns.
_NO_MEASUREMENTS = np.zeros(0, dtype=np.int64)
_NO_MEASUREMENTS.flags.writeable = False


def _representatives(n: int, m: int, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """(N,) int64: the smallest track index in each track's connected component."""
    if rows.size > _SMALL_PAIRS:
        graph = coo_matrix(
            (np.ones(rows.size, dtype=np.float64), (rows, n + cols)), shape=(n + m, n + m)
        ).tocsr()
        _, labels = connected_components(graph, directed=False)
        t_lab = labels[:n].astype(np.int64, copy=False)
        first = np.full(int(labels.max()) + 1 if labels.size else 0, n, dtype=np.int64)
        np.minimum.at(first, t_lab, np.arange(n, dtype=np.int64))
        return first[t_lab]
    rep = np.arange(n, dtype=np.int64)
    if rows.size == 0:
        return rep
    # union–find on the touched nodes (tracks i, measurements ~j), roots = smallest track
    parent: dict = {}

    def find(a):
        root = a
        while parent.get(root, root) != root:
            root = parent[root]
        while a != root:  # path compression
            parent[a], a = root, parent[a]
        return root

    for i, j in zip(rows.tolist(), cols.tolist(), strict=True):
        a, b = find(i), find(~j)
        if a != b:
            # keep a track as the root, the smaller one when both are tracks (j ≥ 0 ⇒ ~j < 0)
            if b >= 0 and (a < 0 or b < a):
                a, b = b, a
            parent[b] = a
    touched = np.unique(rows)
    rep[touched] = [find(int(i)) for i in touched.tolist()]
    return rep


def _clustering_from_pairs(n: int, m: int, rows: np.ndarray, cols: np.ndarray) -> Clustering:
    """:class:`Clustering` of the bipartite graph with edges (rows[p], cols[p]); O(N + M + P)."""
    rep = _representatives(n, m, rows, cols)
    # clusters ordered by their smallest track: rank of each component's first track
    is_first = rep == np.arange(n, dtype=np.int64)
    rank = np.cumsum(is_first, dtype=np.int64) - 1
    n_clusters = int(is_first.sum())
    track_cluster = rank[rep]
    measurement_cluster = np.full(m, -1, dtype=np.int64)
    measurement_cluster[cols] = track_cluster[rows]  # all of a return's pairs agree
    gated = measurement_cluster >= 0

    # gather members: stable argsort by cluster label keeps indices increasing in each cluster
    t_order = np.argsort(track_cluster, kind="stable")
    t_bounds = np.zeros(n_clusters + 1, dtype=np.int64)
    np.cumsum(np.bincount(track_cluster, minlength=n_clusters), out=t_bounds[1:])
    g_idx = np.flatnonzero(gated)
    g_lab = measurement_cluster[g_idx]
    m_order = g_idx[np.argsort(g_lab, kind="stable")]
    m_bounds = np.zeros(n_clusters + 1, dtype=np.int64)
    np.cumsum(np.bincount(g_lab, minlength=n_clusters), out=m_bounds[1:])
    # Python ints: slicing with them is several times cheaper than with numpy scalars,
    # and a scan of a large tracker builds one Cluster per track
    tb, mb = t_bounds.tolist(), m_bounds.tolist()
    out = tuple(
        Cluster(t_order[t0:t1], m_order[m0:m1] if m1 > m0 else _NO_MEASUREMENTS)
        for t0, t1, m0, m1 in zip(tb[:-1], tb[1:], mb[:-1], mb[1:], strict=True)
    )
    return Clustering(
        clusters=out,
        unassociated=np.flatnonzero(~gated),
        track_cluster=track_cluster,
        measurement_cluster=measurement_cluster,
    )


def cluster_pair_marginals(
    groups: Clustering,
    rows,
    cols,
    L_pairs,
    miss,
    solve,
    solve_pairs=None,
    max_dense: int | None = None,
):
    """β of every track's missed detection and of every gated pair, cluster by cluster.

    ``rows``/``cols`` (P,) are the gated pairs (track, measurement) that
    ``groups`` was built from, ``L_pairs`` (P,) their likelihood ratios,
    ``miss`` (N,) the miss weights. One-track clusters (usually most tracks) get
    PDA, exact for one track, all at once
    (:func:`~jointtrack.association.pda.pda_pair_marginals`). Each multi-track
    cluster ``k`` of at most ``max_dense`` (default
    :data:`~jointtrack.association.budget.DENSE_MAX_ENTRIES`) tracks ×
    measurements is handed to ``solve(k, tracks, measurements, L, miss_k)`` as
    its dense ``L`` (n_k × m_k) and ``miss_k``; ``solve`` returns its β
    (n_k × (m_k + 1)), column 0 = no measurement. A larger cluster is never
    made dense (its N × M matrix may not fit in memory): it goes to
    ``solve_pairs(k, tracks, measurements, a, b, L_values, miss_k)`` with its
    gated pairs (``a``, ``b`` local row-major indices), which returns
    ``(beta0_k, pair_beta_k)``; by default the tiers of
    :func:`~jointtrack.association.budget.fallback_pair_marginals`.

    Returns ``(beta0 (N,), pair_beta (P,))``.
    """
    from jointtrack.association.pda import pda_pair_marginals

    rows = np.asarray(rows, np.int64)
    cols = np.asarray(cols, np.int64)
    size = np.bincount(groups.track_cluster, minlength=len(groups.clusters))
    alone = size[groups.track_cluster] == 1
    pair_alone = alone[rows]
    beta0 = np.ones(len(miss))
    pair_beta = np.zeros(len(rows))
    # tracks of larger clusters have no pairs in this call: a dummy miss of 1 keeps
    # a zero miss weight there from reading as "no way to explain this track"
    b0, w = pda_pair_marginals(rows[pair_alone], L_pairs[pair_alone], np.where(alone, miss, 1.0))
    beta0[alone] = b0[alone]
    pair_beta[pair_alone] = w
    multi = np.flatnonzero(size > 1)
    if multi.size == 0:
        return beta0, pair_beta
    # the gated pairs of each multi-track cluster, contiguous
    pair_cluster = groups.track_cluster[rows]
    order = np.argsort(pair_cluster, kind="stable")
    starts = np.searchsorted(pair_cluster[order], multi, side="left")
    ends = np.searchsorted(pair_cluster[order], multi, side="right")
    if max_dense is None or solve_pairs is None:
        from jointtrack.association import budget

        max_dense = budget.DENSE_MAX_ENTRIES if max_dense is None else max_dense
        solve_pairs = solve_pairs or _default_solve_pairs
    for k, lo, hi in zip(multi, starts, ends, strict=True):
        tr, ms = groups.clusters[k].tracks, groups.clusters[k].measurements
        idx = order[lo:hi]
        a, b = np.searchsorted(tr, rows[idx]), np.searchsorted(ms, cols[idx])
        if len(tr) * len(ms) > max_dense:  # checked before any N × M allocation
            row_major = np.lexsort((b, a))
            idx, a, b = idx[row_major], a[row_major], b[row_major]
            b0, pb = solve_pairs(int(k), tr, ms, a, b, L_pairs[idx], miss[tr])
            beta0[tr] = b0
            pair_beta[idx] = pb
            continue
        L = np.zeros((len(tr), len(ms)))
        L[a, b] = L_pairs[idx]
        beta = solve(int(k), tr, ms, L, miss[tr])
        beta0[tr] = beta[:, 0]
        pair_beta[idx] = beta[a, 1 + b]
    return beta0, pair_beta


def _default_solve_pairs(k, tracks, measurements, a, b, L_values, miss):
    from jointtrack.association.budget import fallback_pair_marginals

    res = fallback_pair_marginals(a, b, L_values, miss, len(measurements), reason="dense_budget")
    return res.beta0, res.pair_beta


def has_feasible_event(L, miss) -> bool:
    """True when at least one joint association event has positive weight.

    An event has positive weight iff every track with ``miss == 0`` (certainly
    detected) receives a distinct gated measurement, i.e. the bipartite gating
    graph restricted to those tracks has a matching saturating them (Hall's
    condition; the package's one test, :func:`jointtrack.assignment.is_feasible`).
    The feasibility constraints are Bojilov et al. §2 (each target at most one
    measurement, each measurement at most one target).
    """
    from jointtrack.assignment.feasibility import is_feasible

    return is_feasible(np.asarray(L), np.asarray(miss))
