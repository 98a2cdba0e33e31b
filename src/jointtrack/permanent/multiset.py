"""Permanents and marginals of matrices with repeated rows and/or columns.

A compressed matrix W (distinct rows × distinct columns) with group sizes stands
for the expanded matrix in which row group q appears m_q times and column group
j appears n_j times. Schaub (§3-A, eq. 36–37) recasts Ryser's formula over the
group counts; here the same state space — the vector of how many members of
each group are already used, Π(n_j+1) states — carries a *cancellation-free*
dynamic programme instead, so no extended precision is needed.

Items (the expanded members of one side) are visited in order; the state counts
the used members of each group of the other side. An item of group p taking a
member of group q when d_q of its n_q members are used has weight
W[p, q]·(n_q − d_q) (which member is free to choose). The orientation with the
smaller state space (eq. 37) is chosen by :func:`choose_orientation`.
"""

from __future__ import annotations

import numba as nb
import numpy as np

_BIG = 2.0**400
_SMALL = 2.0**-400


@nb.njit(cache=True)
def _layout(cnt):
    g = cnt.shape[0]
    stride = np.empty(g, np.int64)
    t = np.int64(1)
    for q in range(g):
        stride[q] = t
        t *= cnt[q] + 1
    layer = np.zeros(t, np.int64)
    for s in range(t):
        r = s
        tot = 0
        for q in range(g):
            tot += r % (cnt[q] + 1)
            r //= cnt[q] + 1
        layer[s] = tot
    nl = cnt.sum() + 1
    counts = np.zeros(nl + 1, np.int64)
    for s in range(t):
        counts[layer[s] + 1] += 1
    for k in range(nl):
        counts[k + 1] += counts[k]
    order = np.empty(t, np.int64)
    fill = counts[:-1].copy()
    for s in range(t):
        order[fill[layer[s]]] = s
        fill[layer[s]] += 1
    return stride, order, counts


@nb.njit(cache=True)
def _rescale_layer(f, order, lo, hi):
    mx = 0.0
    for idx in range(lo, hi):
        v = f[order[idx]]
        if v > mx:
            mx = v
    if mx == 0.0 or (_SMALL < mx < _BIG):
        return 0
    e = -int(np.floor(np.log2(mx)))
    sc = 2.0**e
    for idx in range(lo, hi):
        f[order[idx]] *= sc
    return e


@nb.njit(cache=True)
def _forward_layers(W, items, cnt, stride, order, offs):
    """No-skip forward pass: item k moves layer k to layer k+1. f holds every layer."""
    g = cnt.shape[0]
    K = items.shape[0]
    t = order.shape[0]
    f = np.zeros(t)
    fexp = np.zeros(K + 1, np.int64)
    f[0] = 1.0
    for k in range(K):
        p = items[k]
        for idx in range(offs[k + 1], offs[k + 2]):
            s = order[idx]
            r = s
            acc = 0.0
            for q in range(g):
                d = r % (cnt[q] + 1)
                r //= cnt[q] + 1
                if d > 0:
                    w = W[p, q]
                    if w != 0.0:
                        acc += f[s - stride[q]] * w * (cnt[q] - d + 1)
            f[s] = acc
        fexp[k + 1] = fexp[k] + _rescale_layer(f, order, offs[k + 1], offs[k + 2])
    return f, fexp


@nb.njit(cache=True)
def _backward_layers(W, items, cnt, stride, order, offs):
    """No-skip backward pass: b[s] for s in layer k = weight of completing items k..K−1."""
    g = cnt.shape[0]
    K = items.shape[0]
    t = order.shape[0]
    b = np.zeros(t)
    bexp = np.zeros(K + 1, np.int64)
    for idx in range(offs[K], offs[K + 1]):
        b[order[idx]] = 1.0
    for k in range(K - 1, -1, -1):
        p = items[k]
        for idx in range(offs[k], offs[k + 1]):
            s = order[idx]
            r = s
            acc = 0.0
            for q in range(g):
                d = r % (cnt[q] + 1)
                r //= cnt[q] + 1
                if d < cnt[q]:
                    w = W[p, q]
                    if w != 0.0:
                        acc += w * (cnt[q] - d) * b[s + stride[q]]
            b[s] = acc
        bexp[k] = bexp[k + 1] + _rescale_layer(b, order, offs[k], offs[k + 1])
    return b, bexp


@nb.njit(cache=True)
def noskip_value(W, items, cnt):
    """Per when every item must be assigned (items ≤ members): (value, e), Per = value·2^-e."""
    stride, order, offs = _layout(cnt)
    K = items.shape[0]
    f, fexp = _forward_layers(W, items, cnt, stride, order, offs)
    total = 0.0
    for idx in range(offs[K], offs[K + 1]):
        total += f[order[idx]]
    return total, fexp[K]


@nb.njit(cache=True)
def noskip_marginals(W, items, cnt):
    """Per-item marginals M[k, q] (probability item k takes one given member of group q)."""
    stride, order, offs = _layout(cnt)
    g = cnt.shape[0]
    K = items.shape[0]
    f, _ = _forward_layers(W, items, cnt, stride, order, offs)
    b, _ = _backward_layers(W, items, cnt, stride, order, offs)
    M = np.zeros((K, g))
    for k in range(K):
        p = items[k]
        for idx in range(offs[k], offs[k + 1]):
            s = order[idx]
            fs = f[s]
            if fs == 0.0:
                continue
            r = s
            for q in range(g):
                d = r % (cnt[q] + 1)
                r //= cnt[q] + 1
                if d < cnt[q]:
                    M[k, q] += fs * (cnt[q] - d) * b[s + stride[q]]
        tot = 0.0
        for q in range(g):
            M[k, q] *= W[p, q] / cnt[q]
            tot += M[k, q] * cnt[q]
        if tot > 0.0:
            for q in range(g):
                M[k, q] /= tot
    return M


def state_count(counts) -> float:
    """Π(n_j + 1) as a float (it can exceed int64)."""
    return float(np.prod(np.asarray(counts, dtype=float) + 1.0))
