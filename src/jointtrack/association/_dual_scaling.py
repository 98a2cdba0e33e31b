"""Dual scaling of a block: exact power-of-two row/column scales from the LSAP dual.

Step 3 of :mod:`jointtrack.association.exact`. Per block, the optimal dual of the
max-weight association (a shortest-augmenting-path assignment solve on log
weights) gives row and column scale factors, rounded to powers of two (exact),
after which every factor is ≤ ~1 and the best event has weight ≈ 1. Every event
that matters (≥ 1e-300 of the best) then has all partial products ≥ ~1e-300 — no
underflow anywhere in the DP, for any scale of L (a DP merely normalised per
layer by its maximum loses such paths). A row or column scaling multiplies every
joint event's weight by the same factor, so the marginals are unchanged and the
log of the removed scale is added back to log Z.

:func:`_block` extracts one connected component and scales it; :func:`_scatter`
writes the block's marginals back into the full arrays.
"""

from __future__ import annotations

import math

import numba
import numpy as np


@numba.njit(cache=True)
def _lsap_duals(cost):
    """Min-cost perfect matching of a square cost matrix (inf = forbidden).

    Shortest augmenting paths with potentials (Jonker–Volgenant / Crouse form).
    Returns ``(u, v, ok)`` with ``cost[i, j] − u[i] − v[j] ≥ 0`` everywhere and
    equality on the optimal matching; ``ok`` is False if no finite matching exists.
    """
    n = cost.shape[0]
    u = np.zeros(n)
    v = np.zeros(n)
    spc = np.empty(n)
    path = np.full(n, -1, np.int64)
    col4row = np.full(n, -1, np.int64)
    row4col = np.full(n, -1, np.int64)
    SR = np.zeros(n, np.bool_)
    SC = np.zeros(n, np.bool_)
    remaining = np.empty(n, np.int64)
    for cur in range(n):
        min_val = 0.0
        i = cur
        num_rem = n
        for it in range(n):
            remaining[it] = n - it - 1
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
                return u, v, False
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
        for jj in range(n):
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
    return u, v, True


@numba.njit(cache=True)
def _dual_scale(lw, lu, lv):
    """Row/column log scale factors (α, γ) making every factor ≤ 1 and the best event = 1.

    The association problem is embedded in an (R+C)×(C+R) assignment problem
    (row r ↔ col c, row r ↔ its own "unassigned" dummy, col c ↔ its dummy, dummy ↔
    dummy where (r, c) is gated); its optimal dual gives the scales. Returns
    ``(alpha, gamma, log_best, ok)``.
    """
    R, C = lw.shape
    n = R + C
    cost = np.full((n, n), np.inf)
    for r in range(R):
        for c in range(C):
            if lw[r, c] > -np.inf:
                cost[r, c] = -lw[r, c]
                cost[R + c, C + r] = 0.0
        if lu[r] > -np.inf:
            cost[r, C + r] = -lu[r]
    for c in range(C):
        if lv[c] > -np.inf:
            cost[R + c, c] = -lv[c]
    u, v, ok = _lsap_duals(cost)
    alpha = np.empty(R)
    gamma = np.empty(C)
    for r in range(R):
        alpha[r] = u[r] + v[C + r]
    for c in range(C):
        gamma[c] = v[c] + u[R + c]
    return alpha, gamma, -(u.sum() + v.sum()), ok


@numba.njit(cache=True)
def _block(k, lab_r, lab_c, E, Wm, We, um, ue, vm, ve):
    """Extract block k, dual-scale it by exact powers of two.

    Returns (rows, cols, W, u, v, shift, ok): every scaled factor ≤ ~1, the best
    event ≈ 1, ``shift`` = log of the scale removed (add back to log Z).
    """
    rows = np.flatnonzero(lab_r == k)
    cols = np.flatnonzero(lab_c == k)
    R = rows.size
    C = cols.size
    ln2 = math.log(2.0)
    lw = np.full((R, C), -np.inf)
    lu = np.full(R, -np.inf)
    lv = np.full(C, -np.inf)
    for a in range(R):
        r = rows[a]
        if um[r] > 0:
            lu[a] = math.log(um[r]) + ue[r] * ln2
        for b in range(C):
            c = cols[b]
            if E[r, c] and Wm[r, c] > 0:
                lw[a, b] = math.log(Wm[r, c]) + We[r, c] * ln2
    for b in range(C):
        c = cols[b]
        if vm[c] > 0:
            lv[b] = math.log(vm[c]) + ve[c] * ln2
    alpha, gamma, _, ok = _dual_scale(lw, lu, lv)
    W = np.zeros((R, C))
    u = np.zeros(R)
    v = np.zeros(C)
    ka = np.empty(R, np.int64)
    kg = np.empty(C, np.int64)
    for a in range(R):
        ka[a] = np.int64(np.rint(alpha[a] / ln2)) if ok else 0
    for b in range(C):
        kg[b] = np.int64(np.rint(gamma[b] / ln2)) if ok else 0
    # exact power-of-two scales (a row/column scaling leaves the marginals unchanged)
    for a in range(R):
        r = rows[a]
        u[a] = math.ldexp(um[r], ue[r] + ka[a])
        for b in range(C):
            c = cols[b]
            if E[r, c]:
                W[a, b] = math.ldexp(Wm[r, c], We[r, c] + ka[a] + kg[b])
    for b in range(C):
        c = cols[b]
        v[b] = math.ldexp(vm[c], ve[c] + kg[b])
    shift = (ka.sum() + kg.sum()) * ln2
    return rows, cols, W, u, v, shift, ok


@numba.njit(cache=True)
def _scatter(rows, cols, bu, bv, be, pu, pv, pe):
    for a in range(rows.size):
        pu[rows[a]] = bu[a]
        for b in range(cols.size):
            pe[rows[a], cols[b]] = be[a, b]
    for b in range(cols.size):
        pv[cols[b]] = bv[b]
