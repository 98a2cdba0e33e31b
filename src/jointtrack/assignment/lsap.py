r"""Linear sum assignment with dual potentials: the package's one assignment solver.

:func:`scipy.optimize.linear_sum_assignment` returns the optimal matching but not
the dual potentials, and the core needs them: the optimal dual of the
max-weight assignment gives the power-of-two row/column scaling
(:mod:`jointtrack.assignment.scaling`) that puts every assignment-sum problem in
range. One solver therefore serves every assignment solve in the package
(scaling, Bojilov's best hypothesis, Murty's k-best, OSPA/GOSPA, track
matching), so that a bug fixed here is fixed everywhere.

For an n×m cost matrix C (n ≤ m, ``inf`` = forbidden) it solves

.. math::

    \min_{\sigma \text{ injective}} \sum_{i} C_{i\sigma(i)}
    \quad\text{and the dual}\quad
    \max \sum_i u_i + \sum_{j \in \sigma} v_j
    \;\text{s.t.}\; C_{ij} - u_i - v_j \ge 0,\; v \le 0,

with equality on the matched pairs (complementary slackness).

References
----------
.. [1] R. Jonker and A. Volgenant, "A shortest augmenting path algorithm for
   dense and sparse linear assignment problems", *Computing* 38(4), 325–340, 1987.
.. [2] D. F. Crouse, "On implementing 2D rectangular assignment algorithms",
   *IEEE Transactions on Aerospace and Electronic Systems* 52(4), 1679–1696, 2016.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from jointtrack.assignment._checks import _as_real_array
from jointtrack.errors import InfeasibleAssignmentError

__all__ = ["LinearAssignment", "linear_assignment"]


@numba.njit(cache=True)
def _shortest_augmenting_paths(cost):
    """Min-cost matching of every row of an n×m cost matrix (n ≤ m, inf = forbidden).

    Shortest augmenting paths with potentials in Crouse's form [2]. Returns
    ``(col4row, u, v, ok)`` with ``cost[i, j] − u[i] − v[j] ≥ 0`` on every finite
    entry, equality on the matching, ``v ≤ 0`` and ``v = 0`` on unmatched columns;
    ``ok`` is False if no finite matching of all rows exists.
    """
    n, m = cost.shape
    u = np.zeros(n)
    v = np.zeros(m)
    spc = np.empty(m)
    path = np.full(m, -1, np.int64)
    col4row = np.full(n, -1, np.int64)
    row4col = np.full(m, -1, np.int64)
    SR = np.zeros(n, np.bool_)
    SC = np.zeros(m, np.bool_)
    remaining = np.empty(m, np.int64)
    for cur in range(n):
        min_val = 0.0
        i = cur
        num_rem = m
        for it in range(m):
            remaining[it] = m - it - 1
        SR[:] = False
        SC[:] = False
        spc[:] = np.inf
        sink = -1
        while sink == -1:
            index = -1
            lowest = np.inf
            SR[i] = True
            for it in range(num_rem):
                j = remaining[it]
                r = min_val + cost[i, j] - u[i] - v[j]
                if r < spc[j]:
                    path[j] = i
                    spc[j] = r
                if spc[j] < lowest or (spc[j] == lowest and row4col[j] == -1):
                    lowest = spc[j]
                    index = it
            min_val = lowest
            if min_val == np.inf or index < 0:
                return col4row, u, v, False
            j = remaining[index]
            if row4col[j] == -1:
                sink = j
            else:
                i = row4col[j]
            SC[j] = True
            num_rem -= 1
            remaining[index] = remaining[num_rem]
        u[cur] += min_val
        for ii in range(n):
            if SR[ii] and ii != cur:
                u[ii] += min_val - spc[col4row[ii]]
        for jj in range(m):
            if SC[jj]:
                v[jj] -= min_val - spc[jj]
        j = sink
        while True:
            i = path[j]
            row4col[j] = i
            tmp = col4row[i]
            col4row[i] = j
            j = tmp
            if i == cur:
                break
    return col4row, u, v, True


@dataclass(frozen=True)
class LinearAssignment:
    """Result of :func:`linear_assignment`.

    Attributes
    ----------
    rows, cols : ndarray of int
        Matched pairs ``(rows[k], cols[k])``, rows increasing (scipy's convention).
    cost : float
        Total cost (or weight, with ``maximize=True``) of the matching.
    u, v : ndarray
        Dual potentials of the (minimisation) problem in the input orientation:
        ``C[i, j] − u[i] − v[j] ≥ 0`` with equality on the matching.
    """

    rows: np.ndarray
    cols: np.ndarray
    cost: float
    u: np.ndarray
    v: np.ndarray


def linear_assignment(cost, *, maximize: bool = False) -> LinearAssignment:
    """Optimal assignment of an n×m cost matrix with its dual potentials.

    Drop-in for :func:`scipy.optimize.linear_sum_assignment` (``inf`` marks a
    forbidden pair; the smaller side is matched completely) that also returns the
    optimal dual.

    Parameters
    ----------
    cost : (n, m) array_like of real numbers; ``+inf`` forbids a pair
        (``-inf`` with ``maximize=True``).
    maximize : bool
        Maximise the total instead.

    Returns
    -------
    LinearAssignment

    Raises
    ------
    ValueError
        NaN, ``-inf`` (``+inf`` when maximising), complex or non-2-D input.
    InfeasibleAssignmentError
        no matching of the smaller side avoids every forbidden pair.

    Examples
    --------
    >>> from jointtrack.assignment import linear_assignment
    >>> r = linear_assignment([[4.0, 1.0, 3.0], [2.0, 0.0, 5.0], [3.0, 2.0, 2.0]])
    >>> r.cols.tolist(), r.cost
    ([1, 0, 2], 5.0)
    """
    C = _as_real_array(cost, "cost")
    if C.ndim != 2:
        raise ValueError(f"cost must be 2-D, got {C.ndim} dimension(s)")
    if np.isnan(C).any():
        raise ValueError("cost has a NaN entry")
    if maximize:
        C = -C
    if np.isneginf(C).any():
        raise ValueError(
            "cost has an entry of " + ("+inf with maximize=True" if maximize else "-inf")
        )
    transposed = C.shape[0] > C.shape[1]
    work = np.ascontiguousarray(C.T if transposed else C)
    if work.shape[0] == 0:
        empty = np.zeros(0, np.int64)
        return LinearAssignment(empty, empty, 0.0, np.zeros(C.shape[0]), np.zeros(C.shape[1]))
    col4row, u, v, ok = _shortest_augmenting_paths(work)
    if not ok:
        raise InfeasibleAssignmentError(
            "cost matrix is infeasible: no assignment of the "
            + ("columns" if transposed else "rows")
            + " avoids every forbidden (infinite) entry"
        )
    rows = np.arange(work.shape[0])
    cols = col4row
    if transposed:
        rows, cols = cols, rows
        u, v = v, u
        order = np.argsort(rows)
        rows, cols = rows[order], cols[order]
    total = float(C[rows, cols].sum())
    if maximize:
        total, u, v = -total, -u, -v
    return LinearAssignment(rows.astype(np.int64), cols.astype(np.int64), total, u, v)
