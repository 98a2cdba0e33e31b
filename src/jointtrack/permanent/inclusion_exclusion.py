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


@nb.njit(parallel=True, cache=True)
def glynn_kernel(A, log2_chunk):
    """Return (Σ terms, Σ |terms|, √Σ terms²) of Glynn's formula, each divided by 2^{n−1}."""
    n = A.shape[0]
    total = np.int64(1) << (n - 1)
    csize = min(total, np.int64(1) << log2_chunk)
    nchunks = total // csize
    A2 = 2.0 * A
    res = np.zeros(nchunks)
    comp = np.zeros(nchunks)
    absr = np.zeros(nchunks)
    sq = np.zeros(nchunks)
    for c in nb.prange(nchunks):
        start = c * csize
        g = start ^ (start >> 1)
        hi = np.empty(n)
        lo = np.empty(n)
        for j in range(n):
            h = A[0, j]
            lsum = 0.0
            for i in range(1, n):
                x = -A[i, j] if (g >> (i - 1)) & 1 else A[i, j]
                h, e = _two_sum(h, x)
                lsum += e
            hi[j] = h
            lo[j] = lsum
        parity = 0
        x = g
        while x:
            parity ^= x & 1
            x >>= 1
        sign = -1.0 if parity else 1.0
        acc = 0.0
        cacc = 0.0
        aacc = 0.0
        qacc = 0.0
        for k in range(start, start + csize):
            p1 = sign
            p2 = 1.0
            for j in range(0, n - 1, 2):
                p1 *= hi[j] + lo[j]
                p2 *= hi[j + 1] + lo[j + 1]
            if n & 1:
                p1 *= hi[n - 1] + lo[n - 1]
            p = p1 * p2
            acc, e = _two_sum(acc, p)
            cacc += e
            aacc += abs(p)
            qacc += p * p
            if k + 1 < start + csize:
                kk = k + 1
                b = 0
                while (kk & 1) == 0:
                    kk >>= 1
                    b += 1
                i = b + 1
                if (g >> b) & 1:
                    for j in range(n):
                        h, e = _two_sum(hi[j], A2[i, j])
                        hi[j] = h
                        lo[j] += e
                else:
                    for j in range(n):
                        h, e = _two_sum(hi[j], -A2[i, j])
                        hi[j] = h
                        lo[j] += e
                g ^= np.int64(1) << b
                sign = -sign
        res[c] = acc
        comp[c] = cacc
        absr[c] = aacc
        sq[c] = qacc
    s = 0.0
    cs = 0.0
    a = 0.0
    q = 0.0
    for c in range(nchunks):
        s, e = _two_sum(s, res[c])
        cs += e + comp[c]
        a += absr[c]
        q += sq[c]
    scale = 2.0 ** (1 - n)
    return (s + cs) * scale, a * scale, np.sqrt(q) * scale


@nb.njit(parallel=True, cache=True)
def ryser_kernel(A, log2_chunk):
    """Return (Σ terms, Σ |terms|, √Σ terms²) of Ryser's formula (Schaub eq. 35)."""
    n = A.shape[0]
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
        hi = np.empty(n)
        lo = np.empty(n)
        for i in range(n):
            h = 0.0
            lsum = 0.0
            for j in range(n):
                if (g >> j) & 1:
                    h, e = _two_sum(h, A[i, j])
                    lsum += e
            hi[i] = h
            lo[i] = lsum
        parity = n & 1
        x = g
        while x:
            parity ^= x & 1
            x >>= 1
        sign = -1.0 if parity else 1.0
        acc = 0.0
        cacc = 0.0
        aacc = 0.0
        qacc = 0.0
        for k in range(start, start + csize):
            p1 = sign
            p2 = 1.0
            for i in range(0, n - 1, 2):
                p1 *= hi[i] + lo[i]
                p2 *= hi[i + 1] + lo[i + 1]
            if n & 1:
                p1 *= hi[n - 1] + lo[n - 1]
            p = p1 * p2
            acc, e = _two_sum(acc, p)
            cacc += e
            aacc += abs(p)
            qacc += p * p
            if k + 1 < start + csize:
                kk = k + 1
                b = 0
                while (kk & 1) == 0:
                    kk >>= 1
                    b += 1
                if (g >> b) & 1:
                    for i in range(n):
                        h, e = _two_sum(hi[i], -A[i, b])
                        hi[i] = h
                        lo[i] += e
                else:
                    for i in range(n):
                        h, e = _two_sum(hi[i], A[i, b])
                        hi[i] = h
                        lo[i] += e
                g ^= np.int64(1) << b
                sign = -sign
        res[c] = acc
        comp[c] = cacc
        absr[c] = aacc
        sq[c] = qacc
    s = 0.0
    cs = 0.0
    a = 0.0
    q = 0.0
    for c in range(nchunks):
        s, e = _two_sum(s, res[c])
        cs += e + comp[c]
        a += absr[c]
        q += sq[c]
    return s + cs, a, np.sqrt(q)
