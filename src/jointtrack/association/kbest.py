"""JPDA marginals from the k best joint association events (Murty's algorithm).

K. G. Murty, "An algorithm for ranking all the assignments in order of
increasing cost", Operations Research 16(3):682–687, 1968; applied to JPDA
hypotheses as in I. J. Cox and M. L. Miller, "On finding ranked assignments
with application to multitarget tracking and motion correspondence", IEEE
T-AES 31(1):486–489, 1995.

Joint events ↔ assignments of the standard augmented N × (M+N) cost matrix

    C[i, j]     = −log L_ij         measurement j (∞ where not gated, L_ij = 0)
    C[i, M + i] = −log miss_i       track i detects nothing (∞ if miss_i = 0)
    C[i, M + k] = ∞                 k ≠ i

in which every track takes exactly one column and each column is used at most
once; measurements whose columns are unused are clutter (factor 1). The cost
of an assignment is −log of the event weight Π L · Π miss (Bojilov eq. (7)
after the common factor), so the cheapest assignment is the MAP event. Each
assignment problem is solved by the package's one assignment solver, the
kernel behind :func:`jointtrack.assignment.linear_assignment` (∞ = forbidden;
it reports when no assignment avoids them); Murty's partition then yields the
next best events in order. The partition loop, its priority queue and the
constraints (cost edits: forbidden = ∞, forced = ∞ on the rest of the row and
column) run in one compiled kernel that calls the solver's kernel directly, as
the tracker ranks many small clusters per scan and per-subproblem Python
overhead dominated; results are identical to the former Python loop over the
public solver (``benchmarks/kbest_speed.py`` checks and times both).
Everything is in log space — costs, event log weights and the final
renormalisation relative to the best event — so likelihood ratios near the
float64 limit or subnormal miss weights are handled as they are.

The marginals of the k best events renormalise the exact sum over all events
restricted to those k; with k ≥ the number of feasible events they are exact.
Measured here (``tests/test_association_approx``): on dense random 5×10
clusters (L = 5·U[0,1], miss = 0.1; 63 591 feasible events), over 20 clusters,
the maximum absolute marginal error is 0.77 on average (worst 0.84) at k = 10,
0.55 (0.74) at k = 100 and 0.23 (0.34) at k = 1000 — truncation is a poor
approximation on dense clusters with flat weights, and good only when a few
events carry most of the weight.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from jointtrack.assignment._checks import as_int
from jointtrack.assignment.lsap import _shortest_augmenting_paths
from jointtrack.association._validate import NO_FEASIBLE_EVENT, check_cluster
from jointtrack.errors import InfeasibleAssignmentError

__all__ = ["KBestHypotheses", "kbest_hypotheses", "kbest_marginals"]

_FLOAT64 = np.dtype(np.float64)
_MAX_K = 2**63 - 1  # as_int's bound: what the kernel's int64 holds


@dataclass(frozen=True)
class KBestHypotheses:
    """The k best joint association events, best first.

    Attributes
    ----------
    assignments : (K, N) int array
        event h assigns track i to column ``assignments[h, i]`` of the beta
        layout: 0 = no measurement, j + 1 = measurement j.
    log_weights : (K,) float array
        log Π L · Π miss of each event, non-increasing.
    exhausted : bool
        True when fewer than the requested k events exist (all were found).
    """

    assignments: np.ndarray
    log_weights: np.ndarray
    exhausted: bool


@numba.njit(cache=True)
def _pairwise_block(a, lo, n):
    # numpy's pairwise_sum on a block of at most 128 entries: 8 running sums
    if n < 8:
        res = 0.0
        for i in range(lo, lo + n):
            res += a[i]
        return res
    r0, r1, r2, r3 = a[lo], a[lo + 1], a[lo + 2], a[lo + 3]
    r4, r5, r6, r7 = a[lo + 4], a[lo + 5], a[lo + 6], a[lo + 7]
    i = 8
    while i < n - n % 8:
        j = lo + i
        r0 += a[j]
        r1 += a[j + 1]
        r2 += a[j + 2]
        r3 += a[j + 3]
        r4 += a[j + 4]
        r5 += a[j + 5]
        r6 += a[j + 6]
        r7 += a[j + 7]
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < n:
        res += a[lo + i]
        i += 1
    return res


@numba.njit(cache=True)
def _pairwise_sum(a, n):
    """``a[:n].sum()`` bit for bit as numpy computes it (pairwise summation).

    Costs and log weights are summed exactly as the NumPy implementation this
    kernel replaced summed them, so near-ties between events break the same
    way. Above 128 entries numpy halves the range (at a multiple of 8) and adds
    the two halves' sums; that recursion runs here on an explicit stack, since
    a recursive function in numba's on-disk cache crashed on reload.
    """
    if n <= 128:
        return _pairwise_block(a, 0, n)
    # entries (lo, length, halves-done) of the ranges still to sum; sums wait on `acc`
    todo_lo = np.empty(192, np.int64)
    todo_n = np.empty(192, np.int64)
    todo_state = np.empty(192, np.int64)
    acc = np.empty(192)
    top = 0
    n_acc = 0
    todo_lo[0] = 0
    todo_n[0] = n
    todo_state[0] = 0
    top = 1
    while top > 0:
        top -= 1
        lo = todo_lo[top]
        size = todo_n[top]
        if size <= 128:
            acc[n_acc] = _pairwise_block(a, lo, size)
            n_acc += 1
        elif todo_state[top] == 1:  # both halves summed: add them
            n_acc -= 1
            acc[n_acc - 1] = acc[n_acc - 1] + acc[n_acc]
        else:
            half = size // 2
            half -= half % 8
            todo_state[top] = 1
            top += 1
            todo_lo[top] = lo + half
            todo_n[top] = size - half
            todo_state[top] = 0
            top += 1
            todo_lo[top] = lo
            todo_n[top] = half
            todo_state[top] = 0
            top += 1
    return acc[0]


@numba.njit(cache=True)
def _solve_node(
    C, work, vals, forced, extra_row, extra_col, parent, node_parent, node_row, node_col
):
    """Optimal assignment of ``C`` under one Murty node's constraints.

    The node's forbidden pairs are ``(extra_row, extra_col)`` (if ≥ 0) and those
    of ``parent`` and its ancestors (each node stores the one pair it adds);
    ``forced[r] = c ≥ 0`` forces row r onto column c. Constraints are cost edits
    on the full matrix (forbidden = ∞; forced = ∞ on the rest of row r and
    column c), the matrix the public solver was given before, so the one LSAP
    kernel sees the same problem and returns the same matching.

    Returns ``(cost, col4row, ok)``; ``ok`` is False when no finite assignment
    satisfies the constraints.
    """
    n, width = C.shape
    # element loops throughout: numba's array-to-array copies compile slowly
    for r in range(n):
        for c in range(width):
            work[r, c] = C[r, c]
    if extra_row >= 0:
        work[extra_row, extra_col] = np.inf
    p = parent
    while p >= 0:
        if node_row[p] >= 0:
            work[node_row[p], node_col[p]] = np.inf
        p = node_parent[p]
    for r in range(n):
        c = forced[r]
        if c >= 0:
            keep = work[r, c]
            for cc in range(width):
                work[r, cc] = np.inf
            for rr in range(n):
                work[rr, c] = np.inf
            work[r, c] = keep
    none = np.empty(0, np.int64)
    for r in range(n):  # a row with nothing allowed: infeasible without a solve
        finite = False
        for c in range(width):
            if work[r, c] < np.inf:
                finite = True
                break
        if not finite:
            return np.inf, none, False
    col4row, _, _, ok = _shortest_augmenting_paths(work)
    if not ok:
        return np.inf, none, False
    for r in range(n):
        vals[r] = work[r, col4row[r]]
        if not vals[r] < np.inf:
            return np.inf, none, False
    return _pairwise_sum(vals, n), col4row, True


@numba.njit(cache=True)
def _heap_less(cost, a, b):
    # nodes are ranked by (cost, creation order): a total order, so the pop
    # order does not depend on how the heap is laid out
    return cost[a] < cost[b] or (cost[a] == cost[b] and a < b)


@numba.njit(cache=True)
def _heap_push(heap, size, cost, node):
    i = size
    heap[i] = node
    while i > 0:
        up = (i - 1) // 2
        if _heap_less(cost, heap[i], heap[up]):
            heap[i], heap[up] = heap[up], heap[i]
            i = up
        else:
            break
    return size + 1


@numba.njit(cache=True)
def _heap_pop(heap, size, cost):
    top = heap[0]
    size -= 1
    heap[0] = heap[size]
    i = 0
    while True:
        left = 2 * i + 1
        if left >= size:
            break
        best = left
        if left + 1 < size and _heap_less(cost, heap[left + 1], heap[left]):
            best = left + 1
        if _heap_less(cost, heap[best], heap[i]):
            heap[i], heap[best] = heap[best], heap[i]
            i = best
        else:
            break
    return top, size


@numba.njit(cache=True)
def _grow_vector(a, size):
    # plain loops: numba compiles these far faster than a generic slice copy
    out = np.empty(size, a.dtype)
    for i in range(a.shape[0]):
        out[i] = a[i]
    return out


@numba.njit(cache=True)
def _grow_rows(a, size):
    out = np.empty((size, a.shape[1]), a.dtype)
    for i in range(a.shape[0]):
        for j in range(a.shape[1]):
            out[i, j] = a[i, j]
    return out


@numba.njit(cache=True)
def _copy_row(a, row, values):
    for j in range(values.shape[0]):
        a[row, j] = values[j]


@numba.njit(cache=True)
def _stable_order_decreasing(x):
    """``np.argsort(-x, kind="stable")`` (equal keys keep their order): numba's
    mergesort is numpy's stable sort."""
    return np.argsort(-x, kind="mergesort")


@numba.njit(cache=True)
def _murty(L, miss, log_ext, k):
    """The k cheapest assignments of the augmented cost matrix (Murty 1968).

    ``log_ext`` is the log of :func:`_checked_extended`'s ``[miss | L]`` (zeros
    read as 1; those entries are forbidden). Returns ``(assignments,
    log_weights, found)`` in the beta layout, best first (ties in creation
    order); ``found = 0`` when no event has positive weight.
    """
    n, m = L.shape
    C = np.full((n, m + n), np.inf)
    for i in range(n):
        for j in range(m):
            if L[i, j] > 0:
                C[i, j] = -log_ext[i, j + 1]
        if miss[i] > 0:
            C[i, m + i] = -log_ext[i, 0]
    work = np.empty_like(C)
    vals = np.empty(n)

    # Murty nodes: cost, matching, forced column per row (−1: free), parent
    # and the one forbidden pair the node adds to its parent's (−1 at the root)
    cap = 64
    node_cost = np.empty(cap)
    node_cols = np.empty((cap, n), np.int64)
    node_forced = np.empty((cap, n), np.int64)
    node_parent = np.empty(cap, np.int64)
    node_row = np.empty(cap, np.int64)
    node_col = np.empty(cap, np.int64)
    heap = np.empty(cap, np.int64)

    forced = np.full(n, -1, np.int64)
    cost, cols, ok = _solve_node(C, work, vals, forced, -1, -1, -1, node_parent, node_row, node_col)
    if not ok:
        return np.zeros((0, n), np.int64), np.zeros(0), 0
    node_cost[0] = cost
    _copy_row(node_cols, 0, cols)
    _copy_row(node_forced, 0, forced)
    node_parent[0] = -1
    node_row[0] = -1
    node_col[0] = -1
    n_nodes = 1
    size = _heap_push(heap, 0, node_cost, 0)

    out = np.empty((min(k, 64), n), np.int64)
    found = 0
    while size > 0 and found < k:
        p, size = _heap_pop(heap, size, node_cost)
        if found == out.shape[0]:
            out = _grow_rows(out, min(k, 2 * found))
        _copy_row(out, found, node_cols[p])
        found += 1
        if found == k:
            break
        # children: the free rows in order, row r forbidden its parent column
        # and every earlier free row forced onto its parent column
        for r in range(n):
            forced[r] = node_forced[p, r]
        for r in range(n):
            if node_forced[p, r] >= 0:
                continue
            c = node_cols[p, r]
            cost, cols, ok = _solve_node(
                C, work, vals, forced, r, c, p, node_parent, node_row, node_col
            )
            if ok:
                if n_nodes == cap:
                    cap *= 2
                    node_cost = _grow_vector(node_cost, cap)
                    node_cols = _grow_rows(node_cols, cap)
                    node_forced = _grow_rows(node_forced, cap)
                    node_parent = _grow_vector(node_parent, cap)
                    node_row = _grow_vector(node_row, cap)
                    node_col = _grow_vector(node_col, cap)
                    heap = _grow_vector(heap, cap)
                node_cost[n_nodes] = cost
                _copy_row(node_cols, n_nodes, cols)
                _copy_row(node_forced, n_nodes, forced)
                node_parent[n_nodes] = p
                node_row[n_nodes] = r
                node_col[n_nodes] = c
                size = _heap_push(heap, size, node_cost, n_nodes)
                n_nodes += 1
            forced[r] = c

    # exact log weights recomputed from the events (not the solver's sums)
    assignments = np.empty((found, n), np.int64)
    log_weights = np.empty(found)
    for h in range(found):
        for i in range(n):
            a = out[h, i] + 1 if out[h, i] < m else 0
            assignments[h, i] = a
            vals[i] = log_ext[i, a]
        log_weights[h] = _pairwise_sum(vals, n)
    order = _stable_order_decreasing(log_weights)
    sorted_assignments = np.empty_like(assignments)
    sorted_weights = np.empty_like(log_weights)
    for h in range(found):
        sorted_weights[h] = log_weights[order[h]]
        for i in range(n):
            sorted_assignments[h, i] = assignments[order[h], i]
    return sorted_assignments, sorted_weights, found


@numba.njit(cache=True)
def _checked_extended(L, miss):
    """``(ok, ext)``: is ``(L, miss)`` a valid cluster, and ``[miss | L]`` with 0 → 1.

    ``ok`` is :func:`~jointtrack.association._validate.check_cluster`'s verdict
    on float64 arrays of matching shapes (entries of ``L`` finite and ≥ 0,
    ``miss`` finite in [0, 1], no track with ``miss = 0`` and nothing gated),
    taken in one compiled pass because that check costs more than a small
    ranking; when it is False the caller runs ``check_cluster`` for its message.
    ``ext`` holds the weights of the beta layout (column 0 the miss) whose
    logs the kernel needs, taken by NumPy in one call so that they are the
    very values the NumPy implementation used.
    """
    n, m = L.shape
    ext = np.empty((n, m + 1))
    for i in range(n):
        x = miss[i]
        if not (x >= 0.0 and x <= 1.0):  # NaN fails too
            return False, ext
        ext[i, 0] = x if x > 0 else 1.0
        gated = False
        for j in range(m):
            x = L[i, j]
            if not (x >= 0.0 and x < np.inf):
                return False, ext
            gated = gated or x > 0
            ext[i, j + 1] = x if x > 0 else 1.0
        if miss[i] == 0 and not gated:
            return False, ext
    return True, ext


def kbest_hypotheses(L, miss, *, k: int = 100) -> KBestHypotheses:
    """The k most probable JPDA joint association events by Murty's algorithm.

    Murty (1968) ranking over the package's one assignment solver
    (:mod:`jointtrack.assignment.lsap`) on the augmented cost matrix of the
    module docstring (Cox & Miller 1995), in one compiled loop. Events come
    out distinct and in non-increasing weight (Bojilov eq. (7)); ``k = 1``
    gives the MAP event.

    Raises
    ------
    ValueError
        bad input (``check_cluster``) or ``k`` not a whole number ≥ 1.
    InfeasibleAssignmentError
        no joint event has positive weight.
    """
    ok = (
        type(L) is np.ndarray
        and type(miss) is np.ndarray
        and L.dtype == _FLOAT64  # a dtype against a dtype: far cheaper than against np.float64
        and miss.dtype == _FLOAT64
        and L.ndim == 2
        and miss.ndim == 1
        and miss.shape[0] == L.shape[0]
    )
    if ok:  # the tracker's case: checked in one compiled pass
        L, miss = np.ascontiguousarray(L), np.ascontiguousarray(miss)
        ok, ext = _checked_extended(L, miss)
    if not ok:
        L, miss = check_cluster(L, miss)  # raises with the clear message
        ok, ext = _checked_extended(L, miss)
        if not ok:
            raise RuntimeError(
                "kbest_hypotheses: check_cluster accepted a cluster the kernel refused"
            )
    if type(k) is not int or not 1 <= k <= _MAX_K:  # plain ints in range skip the full check
        k = as_int(k, "k", minimum=1)
    if L.shape[0] == 0:
        return KBestHypotheses(np.zeros((1, 0), dtype=np.int64), np.zeros(1), k > 1)
    assignments, log_weights, found = _murty(L, miss, np.log(ext), k)
    if found == 0:
        raise InfeasibleAssignmentError(NO_FEASIBLE_EVENT)
    return KBestHypotheses(assignments, log_weights, exhausted=bool(found < k))


def _relative_weights(L, miss, assignments) -> np.ndarray:
    """Event weights relative to the first (best) event, in split-float form.

    Each factor is a mantissa in [0.5, 1) times an integer power of two; the
    ratio to the best event is ``exp(Σ Δ log mantissa) · 2^(Σ Δ exponent)``, so
    it keeps full relative precision however far the weights are from 1 (a
    difference of two log weights near ±700 would lose ~1e-13).
    """
    n = L.shape[0]
    ext = np.concatenate([miss[:, None], L], axis=1)
    mant, expo = np.frexp(ext)
    with np.errstate(divide="ignore"):
        lmant = np.log(mant)
    rows = np.arange(n)
    lm = lmant[rows, assignments].sum(axis=1)
    ex = expo[rows, assignments].astype(np.int64).sum(axis=1)
    return np.ldexp(np.exp(lm - lm[0]), np.clip(ex - ex[0], -2000, 2000))


def kbest_marginals(L, miss, *, k: int = 100) -> np.ndarray:
    """Approximate JPDA marginals from the k best joint events (Murty 1968).

    β_ij = Σ_{h ∈ k best, h ∋ (i,j)} w_h / Σ_{h ∈ k best} w_h with w_h the event
    weight (Bojilov eqs. (6)–(7) restricted to the k best hypotheses), computed
    relative to the best event so nothing underflows. Exact when ``k`` is at
    least the number of feasible events. See :func:`kbest_hypotheses`.

    Returns
    -------
    beta : (N, M+1) array, column 0 = no measurement, rows sum to 1
    """
    L, miss = check_cluster(L, miss)
    n, m = L.shape
    hyp = kbest_hypotheses(L, miss, k=k)
    beta = np.zeros((n, m + 1))
    if n == 0:
        return beta
    w = _relative_weights(L, miss, hyp.assignments)
    w /= w.sum()
    rows = np.broadcast_to(np.arange(n), hyp.assignments.shape)
    np.add.at(beta, (rows.ravel(), hyp.assignments.ravel()), np.repeat(w, n))
    beta /= beta.sum(axis=1, keepdims=True)
    return beta
