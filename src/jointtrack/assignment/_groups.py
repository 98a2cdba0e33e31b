r"""Group-count dynamic programme for repeated rows or columns, forward–backward.

A compressed problem (distinct rows × distinct columns with group sizes) stands
for its expansion. One side is expanded into *items* visited one at a time; the
other side stays as *groups* with capacities ``cap[q]``, and the DP state is the
vector d of how many members of each group are used — Π_q (cap_q + 1) states
(Schaub eq. 37 chooses the side with fewer). An item of group p either stays
null (weight ``a[p]``) or takes a free member of group q (weight ``W[p, q]``,
times ``cap_q − d_q`` for the choice of member):

.. math::

    f_{k+1}(d) = a_p f_k(d) + \sum_q W_{pq}\,(c_q - d_q + 1)\, f_k(d - e_q),
    \qquad Z = \sum_d f_K(d) \prod_q t_q^{\,c_q - d_q},

with ``t[q]`` the weight of a group member left unused at the end. This is
Schaub's eq. (36) (with the binomial C(n_j, d_j) and d_j = 0…n_j) carried out
as a cancellation-free recursion instead of an alternating sum. The backward
pass is the adjoint recursion; their contraction gives, for every item, the
probability of staying null or of taking some member of each group, and for
every group the expected number of unused members.

Only states whose total ``|d|`` is reachable after k items are visited (a window
of layers); every step is renormalised by a power of two so that the largest
state is ≈ 1, and the terminal weights are combined in log space, so nothing
over- or underflows that matters (the caller scales the problem first, see
:mod:`jointtrack.assignment.scaling`).
"""

from __future__ import annotations

import math

import numba
import numpy as np

__all__ = ["group_dp", "state_count"]


@numba.njit(cache=True)
def _layout(cap):
    """Mixed-radix strides and the states sorted by total used (order, layer offsets)."""
    g = cap.shape[0]
    stride = np.empty(g, np.int64)
    t = np.int64(1)
    for q in range(g):
        stride[q] = t
        t *= cap[q] + 1
    layer = np.zeros(t, np.int64)
    for s in range(t):
        r = s
        tot = 0
        for q in range(g):
            tot += r % (cap[q] + 1)
            r //= cap[q] + 1
        layer[s] = tot
    nl = cap.sum() + 1
    offs = np.zeros(nl + 1, np.int64)
    for s in range(t):
        offs[layer[s] + 1] += 1
    for k in range(nl):
        offs[k + 1] += offs[k]
    order = np.empty(t, np.int64)
    fill = offs[:-1].copy()
    for s in range(t):
        order[fill[layer[s]]] = s
        fill[layer[s]] += 1
    return stride, order, offs


@numba.njit(cache=True)
def _normalise(f, order, lo, hi):
    """Scale states of layers offs-range [lo, hi) so the largest is in [0.5, 1); return exponent."""
    mx = 0.0
    for idx in range(lo, hi):
        v = f[order[idx]]
        if v > mx:
            mx = v
    if mx == 0.0:
        return 0
    e = math.frexp(mx)[1]
    sc = math.ldexp(1.0, -e)
    for idx in range(lo, hi):
        f[order[idx]] *= sc
    return e


@numba.njit(cache=True)
def _log_terminal(cap, t, stride, order, offs, lo, hi):
    """log Π_q t_q^(cap_q − d_q) for every state (−inf where a zero weight is raised to > 0)."""
    g = cap.shape[0]
    out = np.full(order.size, -np.inf)
    for idx in range(offs[lo], offs[hi + 1]):
        s = order[idx]
        r = s
        acc = 0.0
        for q in range(g):
            d = r % (cap[q] + 1)
            r //= cap[q] + 1
            k = cap[q] - d
            if k > 0:
                if t[q] == 0.0:
                    acc = -np.inf
                    break
                acc += k * math.log(t[q])
        out[s] = acc
    return out


@numba.njit(cache=True)
def group_dp(W, items, a, cap, t, marginals):
    """Forward (and backward) group-count DP.

    Parameters: ``W`` (item groups × state groups), ``items`` (item group of each
    expanded item, in visiting order), ``a`` (null weight per item group),
    ``cap`` (state group sizes), ``t`` (unused weight per state group member).

    Returns ``(logZ, item_null, item_take, unused)``: per item the probability of
    staying null and of taking *some* member of each state group, and per state
    group the expected fraction of its members left unused. Without
    ``marginals`` only ``logZ`` is meaningful.
    """
    g = cap.shape[0]
    K = items.shape[0]
    total_cap = cap.sum()
    stride, order, offs = _layout(cap)
    T = order.size
    # window of layers (total used) reachable after k items
    lo = np.zeros(K + 1, np.int64)
    hi = np.zeros(K + 1, np.int64)
    for k in range(K):
        hi[k + 1] = min(hi[k] + 1, total_cap)
        lo[k + 1] = lo[k] if a[items[k]] > 0.0 else lo[k] + 1
    # members with a zero unused weight must all be taken by the end, which
    # bounds the window from below: |d| ≥ need − (items still to come)
    need = 0
    for q in range(g):
        if t[q] == 0.0:
            need += cap[q]
    for k in range(K + 1):
        lo[k] = max(lo[k], need - (K - k))
    item_null = np.zeros(K)
    item_take = np.zeros((K, g))
    unused = np.zeros(g)
    for k in range(K + 1):
        if lo[k] > hi[k]:
            return -np.inf, item_null, item_take, unused
    if lo[K] > total_cap:
        return -np.inf, item_null, item_take, unused
    # Two full-size rolling arrays do the arithmetic; with marginals each step's
    # window is also kept, compactly (in layer order), for the backward pass —
    # Σ_k |window_k| entries, which is T when every row must be assigned.
    base = np.zeros(K + 2, np.int64)
    for k in range(K + 1):
        base[k + 1] = base[k] + offs[hi[k] + 1] - offs[lo[k]]
    store = np.empty(base[K + 1] if marginals else 0)
    F = np.zeros((2, T))
    fexp = np.zeros(K + 1, np.int64)
    F[0, 0] = 1.0
    if marginals:
        store[0] = 1.0
    for k in range(K):
        p = items[k]
        x = F[k % 2]
        y = F[(k + 1) % 2]
        ap = a[p]
        for idx in range(offs[lo[k + 1]], offs[hi[k + 1] + 1]):
            s = order[idx]
            r = s
            acc = ap * x[s]
            for q in range(g):
                d = r % (cap[q] + 1)
                r //= cap[q] + 1
                if d > 0:
                    w = W[p, q]
                    if w != 0.0:
                        acc += x[s - stride[q]] * w * (cap[q] - d + 1)
            y[s] = acc
        # states below the new window (stale from two steps back) must not leak
        for idx in range(offs[lo[max(k - 1, 0)]], offs[lo[k + 1]]):
            y[order[idx]] = 0.0
        fexp[k + 1] = fexp[k] + _normalise(y, order, offs[lo[k + 1]], offs[hi[k + 1] + 1])
        if marginals:
            o = offs[lo[k + 1]]
            for idx in range(o, offs[hi[k + 1] + 1]):
                store[base[k + 1] + idx - o] = y[order[idx]]
    FK = F[K % 2]
    logT = _log_terminal(cap, t, stride, order, offs, lo[K], hi[K])
    # Z = Σ_d F_K(d)·T(d)·2^fexp[K], combined in log space
    mx = -np.inf
    for idx in range(offs[lo[K]], offs[hi[K] + 1]):
        s = order[idx]
        if FK[s] > 0.0 and logT[s] > -np.inf:
            v = math.log(FK[s]) + logT[s]
            if v > mx:
                mx = v
    if mx == -np.inf:
        return -np.inf, item_null, item_take, unused
    zsum = 0.0
    for idx in range(offs[lo[K]], offs[hi[K] + 1]):
        s = order[idx]
        if FK[s] > 0.0 and logT[s] > -np.inf:
            zsum += FK[s] * math.exp(logT[s] - mx)
    ln2 = math.log(2.0)
    logZ = mx + math.log(zsum) + fexp[K] * ln2
    if not marginals:
        return logZ, item_null, item_take, unused
    # unused members per state group, from the terminal distribution
    for idx in range(offs[lo[K]], offs[hi[K] + 1]):
        s = order[idx]
        if FK[s] > 0.0 and logT[s] > -np.inf:
            w = FK[s] * math.exp(logT[s] - mx) / zsum
            r = s
            for q in range(g):
                d = r % (cap[q] + 1)
                r //= cap[q] + 1
                unused[q] += w * (cap[q] - d) / cap[q]
    # backward: b_K = T (scaled by 2^-bexp), then the adjoint recursion
    b = np.zeros(T)
    bn = np.zeros(T)
    bexp = math.floor(mx / ln2)
    for idx in range(offs[lo[K]], offs[hi[K] + 1]):
        s = order[idx]
        if logT[s] > -np.inf:
            b[s] = math.exp(logT[s] - bexp * ln2)
    x = np.zeros(T)  # F_k scattered back from the compact store
    for k in range(K - 1, -1, -1):
        p = items[k]
        if k < K - 1:
            for idx in range(offs[lo[k + 1]], offs[hi[k + 1] + 1]):
                x[order[idx]] = 0.0
        o = offs[lo[k]]
        for idx in range(o, offs[hi[k] + 1]):
            x[order[idx]] = store[base[k] + idx - o]
        ap = a[p]
        # log of the factor that turns a contraction F_k·b_{k+1} into a probability
        lsc = (fexp[k] + bexp) * ln2 - logZ
        snull = 0.0
        stake = np.zeros(g)
        for idx in range(offs[lo[k]], offs[hi[k] + 1]):
            s = order[idx]
            r = s
            bv = b[s]
            acc = ap * bv
            fs = x[s]
            snull += fs * bv
            for q in range(g):
                d = r % (cap[q] + 1)
                r //= cap[q] + 1
                if d < cap[q]:
                    w = W[p, q]
                    if w != 0.0:
                        nb = b[s + stride[q]] * (cap[q] - d)
                        acc += w * nb
                        stake[q] += fs * nb
            bn[s] = acc
        if snull > 0.0:
            item_null[k] = math.exp(math.log(ap * snull) + lsc) if ap > 0.0 else 0.0
        for q in range(g):
            if stake[q] > 0.0 and W[p, q] > 0.0:
                item_take[k, q] = math.exp(math.log(W[p, q] * stake[q]) + lsc)
        # clear b outside the next window, then renormalise
        for idx in range(offs[lo[k]], offs[hi[k] + 1]):
            s = order[idx]
            b[s] = bn[s]
        for idx in range(offs[hi[k] + 1], offs[min(hi[k + 1], total_cap) + 1]):
            b[order[idx]] = 0.0
        bexp += _normalise(b, order, offs[lo[k]], offs[hi[k] + 1])
    return logZ, item_null, item_take, unused


def state_count(counts) -> float:
    """Π(n_j + 1) as a float (it can exceed int64; inf past the float range, without a warning)."""
    return math.prod([float(n) + 1.0 for n in np.asarray(counts).ravel().tolist()])
