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

__all__ = ["Cluster", "Clustering", "clusters", "has_feasible_event"]


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
    try:
        mask = np.asarray(mask)
    except (TypeError, ValueError) as exc:  # pragma: no cover - asarray rarely fails
        raise ValueError(f"mask must be an array: {exc}") from None
    if mask.ndim == 1 and mask.size == 0:
        mask = mask.reshape(0, 0)
    if mask.ndim != 2:
        raise ValueError(f"mask must be 2-D (tracks × measurements), got {mask.ndim} dimension(s)")
    if mask.dtype != bool:
        if not np.issubdtype(mask.dtype, np.number):
            raise ValueError(f"mask must be boolean or numeric, got dtype {mask.dtype}")
        if not np.all(np.isfinite(mask)):
            raise ValueError("mask has non-finite entries")
        if np.any(mask < 0):
            raise ValueError("mask has negative entries (use a boolean gate mask or L ≥ 0)")
        mask = mask != 0
    return mask


def clusters(mask) -> Clustering:
    """Partition tracks and measurements into independent JPDA clusters.

    Connected components of the bipartite gating graph (Bojilov et al. §2,
    "clusterisation"), computed with
    :func:`scipy.sparse.csgraph.connected_components` (a union–find equivalent,
    O(N + M + nnz)).

    Parameters
    ----------
    mask : (N, M) bool array, or a likelihood-ratio matrix ``L`` (non-zero = gated)

    Returns
    -------
    Clustering
        clusters (each with sorted track and measurement indices), the
        unassociated measurements, and per-node cluster labels. 0 tracks or 0
        measurements are fine.
    """
    mask = _as_mask(mask)
    n, m = mask.shape
    rows, cols = np.nonzero(mask)
    graph = coo_matrix(
        (np.ones(rows.size, dtype=np.int8), (rows, n + cols)), shape=(n + m, n + m)
    ).tocsr()
    _, labels = connected_components(graph, directed=False)
    t_lab = labels[:n]
    m_lab = labels[n:]
    # relabel components by first appearance among tracks: cluster order = min track index
    n_lab = int(labels.max()) + 1 if labels.size else 0
    remap = np.full(n_lab, -1, dtype=np.int64)
    uniq, first = np.unique(t_lab, return_index=True)
    remap[uniq[np.argsort(first)]] = np.arange(uniq.size)
    track_cluster = remap[t_lab]
    gated = mask.any(axis=0) if n else np.zeros(m, dtype=bool)
    measurement_cluster = np.where(gated, remap[m_lab], -1).astype(np.int64)
    out = []
    for k in range(uniq.size):
        out.append(
            Cluster(
                tracks=np.flatnonzero(track_cluster == k),
                measurements=np.flatnonzero(measurement_cluster == k),
            )
        )
    return Clustering(
        clusters=tuple(out),
        unassociated=np.flatnonzero(~gated),
        track_cluster=track_cluster,
        measurement_cluster=measurement_cluster,
    )


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
