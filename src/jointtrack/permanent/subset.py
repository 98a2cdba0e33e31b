"""Cancellation-free subset dynamic programme for the permanent and its minors.

The programme only adds and multiplies non-negative numbers, so every
intermediate value is a sum of non-negative terms and the result carries a
relative rounding error of at most about 2n·u (u = 2⁻⁵³), whatever the
conditioning of A. Magnitudes are kept in range by power-of-two rescaling
(exact) of each layer, with the exponent tracked separately.

Rows are assigned in order; the state is the set S of columns already used
(|S| = number of rows done), ``f[S] = Per(A[:|S|, S])``. Cost n·2^{n−1} for a
square matrix, memory 2^n. (Rectangular input is padded to square by the
caller, see :func:`jointtrack.permanent.exact.make_square`.)

Marginals come from a forward and a backward pass (all minors at once):
``Per(A)·P[t,i] = A[t,i] · Σ_{S: |S|=t, i∉S} f[S] · g[S ∪ {i}]``.
"""

from __future__ import annotations

import numba as nb
import numpy as np

_BIG = 2.0**400
_SMALL = 2.0**-400


@nb.njit(cache=True)
def _next_combination(x):
    # Gosper's hack: next integer with the same number of set bits.
    c = x & -x
    r = x + c
    return (((r ^ x) >> 2) // c) | r


@nb.njit(cache=True)
def _rescale(f, start_mask, k, m):
    """Rescale one popcount layer of f by a power of two; return the exponent used."""
    mx = 0.0
    if k == 0:
        return 0
    x = start_mask
    limit = np.int64(1) << m
    while x < limit:
        if f[x] > mx:
            mx = f[x]
        x = _next_combination(x)
    if mx == 0.0 or (_SMALL < mx < _BIG):
        return 0
    e = -int(np.floor(np.log2(mx)))
    s = 2.0**e
    x = start_mask
    while x < limit:
        f[x] *= s
        x = _next_combination(x)
    return e


@nb.njit(cache=True)
def pull_forward(A):
    """Forward pass over column subsets. Returns (f, exps) with layer k scaled by 2^exps[k]."""
    n, m = A.shape
    f = np.zeros(np.int64(1) << m)
    exps = np.zeros(n + 1, np.int64)
    f[0] = 1.0
    for k in range(1, n + 1):
        row = k - 1
        x = (np.int64(1) << k) - 1
        limit = np.int64(1) << m
        while x < limit:
            s = 0.0
            for j in range(m):
                if (x >> j) & 1:
                    s += f[x ^ (np.int64(1) << j)] * A[row, j]
            f[x] = s
            x = _next_combination(x)
        exps[k] = exps[k - 1] + _rescale(f, (np.int64(1) << k) - 1, k, m)
    return f, exps


@nb.njit(cache=True)
def pull_backward(A):
    """Backward pass: g[S] = Per of rows |S|..n−1 into columns outside S (layer-scaled)."""
    n, m = A.shape
    g = np.zeros(np.int64(1) << m)
    exps = np.zeros(n + 1, np.int64)
    limit = np.int64(1) << m
    x = (np.int64(1) << n) - 1
    while x < limit:
        g[x] = 1.0
        x = _next_combination(x)
    if n == 0:
        return g, exps
    for k in range(n - 1, -1, -1):
        if k == 0:
            s = 0.0
            for j in range(m):
                s += A[0, j] * g[np.int64(1) << j]
            g[0] = s
            exps[0] = exps[1]
            if s != 0.0 and not (_SMALL < s < _BIG):
                e = -int(np.floor(np.log2(s)))
                g[0] = s * 2.0**e
                exps[0] += e
            break
        x = (np.int64(1) << k) - 1
        while x < limit:
            s = 0.0
            for j in range(m):
                if not (x >> j) & 1:
                    s += A[k, j] * g[x | (np.int64(1) << j)]
            g[x] = s
            x = _next_combination(x)
        exps[k] = exps[k + 1] + _rescale(g, (np.int64(1) << k) - 1, k, m)
    return g, exps


@nb.njit(cache=True)
def pull_value(A):
    """Per(A) = f[full layer] as (mantissa-sum, exponent): Per = value · 2^-exp."""
    n, m = A.shape
    f, exps = pull_forward(A)
    if n == 0:
        return 1.0, 0
    total = 0.0
    x = (np.int64(1) << n) - 1
    limit = np.int64(1) << m
    while x < limit:
        total += f[x]
        x = _next_combination(x)
    return total, exps[n]


@nb.njit(cache=True)
def pull_marginals(A):
    """Row-normalised marginals P (n×m) from one forward and one backward pass."""
    n, m = A.shape
    f, _ = pull_forward(A)
    g, _ = pull_backward(A)
    P = np.zeros((n, m))
    limit = np.int64(1) << m
    for k in range(n):
        row = P[k]
        if k == 0:
            x = np.int64(0)
            for j in range(m):
                row[j] += f[0] * g[np.int64(1) << j]
        else:
            x = (np.int64(1) << k) - 1
            while x < limit:
                fx = f[x]
                if fx != 0.0:
                    for j in range(m):
                        if not (x >> j) & 1:
                            row[j] += fx * g[x | (np.int64(1) << j)]
                x = _next_combination(x)
        s = 0.0
        for j in range(m):
            row[j] *= A[k, j]
            s += row[j]
        if s > 0.0:
            for j in range(m):
                row[j] /= s
    return P
