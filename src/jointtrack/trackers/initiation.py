"""Track initiation from returns no track claimed: two-point and one-point.

Two-point initiation pairs each new return with an unassociated return of the
previous scan (a *seed*) that is no further than ``max_speed·dt`` plus three
standard deviations of the two position errors away, velocity = difference /
dt (Blackman & Popoli, *Design and Analysis of Modern Tracking Systems*, 1999,
§6.2). Among the admissible pairs, a minimum-total-distance assignment that
first maximises the number of pairs is chosen.

Cost grows with the number of admissible pairs, not with new × seeds: candidate
pairs come from a :class:`scipy.spatial.cKDTree` ball query, the assignment is
solved per connected component of the candidate graph with the package's one
solver (:func:`jointtrack.assignment.linear_assignment`), and a component whose
dense cost matrix would exceed the memory budget is matched greedily by
increasing distance (an approximation, logged).
"""

from __future__ import annotations

import logging

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from jointtrack.assignment import linear_assignment

__all__ = ["DEFAULT_COMPONENT_BUDGET", "pair_returns"]

log = logging.getLogger("jointtrack.tracker")

#: Largest dense cost matrix (entries) built for one component of candidate pairs.
DEFAULT_COMPONENT_BUDGET = 4_000_000
_FORBIDDEN = 1e12  # cost of a non-admissible pair inside a component's dense matrix


def _candidates(pos, cov, seeds, seed_covs, reach):
    """Admissible (new, seed) pairs and their distances, via a KD-tree on the seeds."""
    tr_new = np.trace(cov, axis1=1, axis2=2)
    tr_seed = np.trace(seed_covs, axis1=1, axis2=2)
    # sqrt(tr_i + tr_j) ≤ sqrt(tr_i + max tr_j): a ball that contains every admissible seed
    radius = reach + 3.0 * np.sqrt(tr_new + tr_seed.max())
    tree = cKDTree(seeds)
    lists = tree.query_ball_point(pos, radius)
    counts = np.fromiter((len(x) for x in lists), np.int64, len(lists))
    rows = np.repeat(np.arange(len(pos)), counts)
    cols = np.fromiter((j for x in lists for j in x), np.int64, int(counts.sum()))
    dist = np.linalg.norm(pos[rows] - seeds[cols], axis=1)
    ok = dist <= reach + 3.0 * np.sqrt(tr_new[rows] + tr_seed[cols])
    return rows[ok], cols[ok], dist[ok]


def _greedy(rows, cols, dist):
    order = np.argsort(dist, kind="stable")
    used_r, used_c, out = set(), set(), []
    for k in order:
        r, c = int(rows[k]), int(cols[k])
        if r not in used_r and c not in used_c:
            used_r.add(r)
            used_c.add(c)
            out.append(k)
    return np.asarray(out, np.int64)


def pair_returns(pos, cov, seeds, seed_covs, reach, budget=DEFAULT_COMPONENT_BUDGET):
    """Two-point pairs ``(new_index, seed_index)`` of returns ``pos`` with ``seeds``.

    ``cov``, ``seed_covs`` are the position covariances (k, d, d); ``reach`` =
    max_speed·dt. Returns two int arrays (sorted by new index).
    """
    n, m = len(pos), len(seeds)
    if n == 0 or m == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    rows, cols, dist = _candidates(pos, cov, seeds, seed_covs, reach)
    if rows.size == 0:
        return rows, cols
    graph = coo_matrix((np.ones(rows.size), (rows, n + cols)), shape=(n + m, n + m))
    ncomp, labels = connected_components(graph, directed=False)
    comp = labels[rows]
    order = np.argsort(comp, kind="stable")
    bounds = np.flatnonzero(np.diff(comp[order])) + 1
    out_r, out_c = [], []
    for idx in np.split(order, bounds):
        r, c, d = rows[idx], cols[idx], dist[idx]
        ur, r_loc = np.unique(r, return_inverse=True)
        uc, c_loc = np.unique(c, return_inverse=True)
        if len(ur) == 1 or len(uc) == 1:
            k = int(np.argmin(d))  # a star: the nearest partner
            out_r.append(r[k : k + 1])
            out_c.append(c[k : k + 1])
            continue
        if len(ur) * len(uc) > budget:
            log.warning(
                "two-point initiation: %d × %d candidate returns in one group exceed the "
                "budget of %d cost entries; pairing them greedily by distance",
                len(ur),
                len(uc),
                budget,
            )
            k = _greedy(r, c, d)
            out_r.append(r[k])
            out_c.append(c[k])
            continue
        cost = np.full((len(ur), len(uc)), _FORBIDDEN)
        cost[r_loc, c_loc] = d
        la = linear_assignment(cost)
        good = cost[la.rows, la.cols] < _FORBIDDEN
        out_r.append(ur[la.rows[good]])
        out_c.append(uc[la.cols[good]])
    pr = np.concatenate(out_r)
    pc = np.concatenate(out_c)
    order = np.argsort(pr, kind="stable")
    return pr[order], pc[order]
