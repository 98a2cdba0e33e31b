"""Glynn's and Ryser's inclusion–exclusion formulas in Gray-code order.

Ryser (Schaub eq. 35): Per(A) = (−1)ⁿ Σ_{Y⊆cols} (−1)^{|Y|} Π_i Σ_{j∈Y} a_ij.
Glynn (Glynn 2010, "The permanent of a square matrix", Eur. J. Combin.):
Per(A) = 2^{1−n} Σ_{δ∈{±1}ⁿ, δ₁=1} (Π_k δ_k) Π_j Σ_i δ_i a_ij.

Both cancel: the result can be far smaller than the terms. Three safeguards
make them accurate on balanced input (see :func:`jointtrack.permanent.balance.balance_pow2`):

* the running sums are kept in double-double (error-free two-sum updates), so
  they do not drift along the 2^{n−1} Gray-code steps; drift, not the products,
  is what costs the usual implementations 3–4 digits at n = 26;
* each parallel chunk recomputes its sums from scratch (compensated);
* terms are accumulated with compensated (Neumaier) summation.

Each kernel also returns Σ|term|, so the caller can bound the rounding error
by (n+4)·u·Σ|term| and fall back to the cancellation-free DP when the bound is
too large for the requested accuracy.
"""

from __future__ import annotations

import numba as nb
import numpy as np


@nb.njit(cache=True, inline="always")
def _two_sum(a, b):
    s = a + b
    bb = s - a
    return s, (a - (s - bb)) + (b - bb)


@nb.njit(cache=True, inline="always")
def _parity(g):
    parity = 0
    while g:
        parity ^= g & 1
        g >>= 1
    return parity


@nb.njit(cache=True, inline="always")
def _signed_product(sign, hi, lo, n):
    # two interleaved partial products: half the dependency chain, same rounding
    p1 = sign
    p2 = 1.0
    for j in range(0, n - 1, 2):
        p1 *= hi[j] + lo[j]
        p2 *= hi[j + 1] + lo[j + 1]
    if n & 1:
        p1 *= hi[n - 1] + lo[n - 1]
    return p1 * p2


@nb.njit(cache=True, inline="always")
def _dd_add(hi, lo, values, scale):
    """Running double-double sums: (hi, lo) += scale · values, error-free per step."""
    for j in range(hi.shape[0]):
        h, e = _two_sum(hi[j], scale * values[j])
        hi[j] = h
        lo[j] += e


@nb.njit(cache=True, inline="always")
def _flipped_bit(k):
    """Index of the bit that changes between Gray codes k−1 and k (k ≥ 1)."""
    b = 0
    while (k & 1) == 0:
        k >>= 1
        b += 1
    return b


@nb.njit(cache=True)
def _combine(res, comp, absr, sq):
    s = 0.0
    cs = 0.0
    a = 0.0
    q = 0.0
    for c in range(res.shape[0]):
        s, e = _two_sum(s, res[c])
        cs += e + comp[c]
        a += absr[c]
        q += sq[c]
    return s + cs, a, np.sqrt(q)


@nb.njit(parallel=True, cache=True)
def glynn_kernel(A, log2_chunk):
    """Return (Σ terms, Σ |terms|, √Σ terms²) of Glynn's formula, each divided by 2^{n−1}.

    Row 0 always enters with δ = +1; bit i−1 of the Gray code g set means δ_i = −1.
    """
    n = A.shape[0]
    total = np.int64(1) << (n - 1)
    csize = min(total, np.int64(1) << log2_chunk)
    nchunks = total // csize
    res = np.zeros(nchunks)
    comp = np.zeros(nchunks)
    absr = np.zeros(nchunks)
    sq = np.zeros(nchunks)
    for c in nb.prange(nchunks):
        start = c * csize
        g = start ^ (start >> 1)
        hi = A[0].copy()
        lo = np.zeros(n)
        for i in range(1, n):
            _dd_add(hi, lo, A[i], -1.0 if (g >> (i - 1)) & 1 else 1.0)
        sign = -1.0 if _parity(g) else 1.0
        acc = cacc = aacc = qacc = 0.0
        for k in range(start, start + csize):
            p = _signed_product(sign, hi, lo, n)
            acc, e = _two_sum(acc, p)
            cacc += e
            aacc += abs(p)
            qacc += p * p
            if k + 1 < start + csize:
                b = _flipped_bit(k + 1)
                _dd_add(hi, lo, A[b + 1], 2.0 if (g >> b) & 1 else -2.0)
                g ^= np.int64(1) << b
                sign = -sign
        res[c] = acc
        comp[c] = cacc
        absr[c] = aacc
        sq[c] = qacc
    value, a, q = _combine(res, comp, absr, sq)
    scale = 2.0 ** (1 - n)
    return value * scale, a * scale, q * scale


@nb.njit(parallel=True, cache=True)
def ryser_kernel(A, log2_chunk):
    """Return (Σ terms, Σ |terms|, √Σ terms²) of Ryser's formula (Schaub eq. 35).

    Bit j of the Gray code g set means column j is in the subset Y.
    """
    n = A.shape[0]
    AT = np.ascontiguousarray(A.T)
    total = np.int64(1) << n
    csize = min(total, np.int64(1) << log2_chunk)
    nchunks = total // csize
    res = np.zeros(nchunks)
    comp = np.zeros(nchunks)
    absr = np.zeros(nchunks)
    sq = np.zeros(nchunks)
    for c in nb.prange(nchunks):
        start = c * csize
        g = start ^ (start >> 1)
        hi = np.zeros(n)
        lo = np.zeros(n)
        for j in range(n):
            if (g >> j) & 1:
                _dd_add(hi, lo, AT[j], 1.0)
        sign = -1.0 if (n & 1) ^ _parity(g) else 1.0
        acc = cacc = aacc = qacc = 0.0
        for k in range(start, start + csize):
            p = _signed_product(sign, hi, lo, n)
            acc, e = _two_sum(acc, p)
            cacc += e
            aacc += abs(p)
            qacc += p * p
            if k + 1 < start + csize:
                b = _flipped_bit(k + 1)
                _dd_add(hi, lo, AT[b], -1.0 if (g >> b) & 1 else 1.0)
                g ^= np.int64(1) << b
                sign = -sign
        res[c] = acc
        comp[c] = cacc
        absr[c] = aacc
        sq[c] = qacc
    return _combine(res, comp, absr, sq)
