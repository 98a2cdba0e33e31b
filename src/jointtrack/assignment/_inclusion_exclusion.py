"""Glynn's and Ryser's inclusion–exclusion formulas in Gray-code order.

Ryser (Schaub eq. 35): Per(A) = (−1)ⁿ Σ_{Y⊆cols} (−1)^{|Y|} Π_i Σ_{j∈Y} a_ij.
Glynn (Glynn 2010, "The permanent of a square matrix", Eur. J. Combin.):
Per(A) = 2^{1−n} Σ_{δ∈{±1}ⁿ, δ₁=1} (Π_k δ_k) Π_j Σ_i δ_i a_ij.

Both cancel: the result can be far smaller than the terms. Three safeguards
make them accurate on balanced input (see :func:`jointtrack.permanent.balance.balance_pow2`):

* the running sums do not drift along the 2^{n−1} Gray-code steps; drift, not
  the products, is what costs the usual implementations 3–4 digits at n = 26.
  Ryser keeps them in double-double (error-free two-sum updates); Glynn splits
  each column into a part whose signed sums are exact in plain doubles plus a
  tiny remainder (:func:`_split_columns`), which is as accurate and lets the
  inner loop run vectorised over 2^6 low-bit patterns at once;
* each parallel chunk recomputes its sums from scratch (compensated);
* terms are accumulated with compensated (Neumaier) summation.

Each kernel also returns Σ|term|, so the caller can bound the rounding error
by (n+4)·u·Σ|term| and fall back to the cancellation-free DP when the bound is
too large for the requested accuracy.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

try:  # LLVM's cttz; the loop in _flipped_bit otherwise
    from numba.cpython.unsafe.numbers import trailing_zeros as _cttz
except ImportError:  # pragma: no cover
    _cttz = None


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
def _trailing_zeros(k):
    return _cttz(k) if _cttz is not None else _flipped_bit(k)


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
    """(compensated Σ res, Σ absr, √Σ sq) of per-chunk partial sums."""
    s, cs, a, q = _combine_parts(res, comp, absr, sq)
    return s + cs, a, np.sqrt(q)


_LOW_BITS = 6  # rows 1…m enumerated in blocks of 2^m terms: the vectorised loop
_MAX_CHUNK_BITS = 24  # lo-sum drift bound below (need csize ≤ 2^24)
_MAX_CHUNKS_BITS = 20  # at most 2^20 chunk results (memory for n = 40)


@nb.njit(cache=True)
def _split_columns(A):
    """Split A = H + L per column so that every signed column sum of H is exact in doubles.

    Column j is rounded to multiples of the power of two q_j = 2^(e_j − 51),
    where c_j = Σ_i |a_ij| (as computed) < 2^e_j, so 2^−52·c_j ≤ q_j ≤ 4u·c_j
    up to the rounding of c_j (u = 2^−53).  Every partial sum Σ_{i∈S} ±h_ij is
    then a multiple of q_j of magnitude ≤ Σ_i|h_ij| ≤ c_j(1 + n·u) + n·q_j/2
    < 2^52·q_j, i.e. representable: every addition of such sums is EXACT,
    however many Gray-code steps are taken.  L = A − H is exact (Sterbenz) and
    |l_ij| ≤ q_j/2 ≤ 2u·c_j.
    """
    n = A.shape[0]
    H = np.zeros((n, n))
    L = np.zeros((n, n))
    for j in range(n):
        c = 0.0
        for i in range(n):
            c += abs(A[i, j])
        q = math.ldexp(1.0, math.frexp(c)[1] - 51) if c > 0.0 else 1.0
        for i in range(n):
            h = np.rint(A[i, j] / q) * q
            H[i, j] = h
            L[i, j] = A[i, j] - h
    return H, L


@nb.njit(cache=True)
def _low_tables(H, L, m):
    """Vh[j, l], Vl[j, l] = Σ_{r<m} ±(H, L)[r+1, j], minus where bit r of l is set.

    Vh is exact (a signed partial column sum of H); Vl has ≤ m roundings of
    sums of magnitude ≤ m·q_j/2.  sg[l] = (−1)^popcount(l).
    """
    n = H.shape[0]
    nl = 1 << m
    Vh = np.zeros((n, nl))
    Vl = np.zeros((n, nl))
    sg = np.ones(nl)
    for lo in range(nl):
        for r in range(m):
            neg = (lo >> r) & 1
            if neg:
                sg[lo] = -sg[lo]
            for j in range(n):
                Vh[j, lo] += -H[r + 1, j] if neg else H[r + 1, j]
                Vl[j, lo] += -L[r + 1, j] if neg else L[r + 1, j]
    return Vh, Vl, sg


@nb.njit(cache=True)
def _glynn_chunk(H, L, Vh, Vl, sg, m, start, csize):
    """Glynn's terms for the high Gray codes start … start+csize−1, 2^m terms each.

    Rows 1…m (the low bits) are enumerated inside a block of 2^m terms from
    the tables Vh, Vl; rows m+1…n−1 (the high bits) follow a Gray code, whose
    running sums Bh (exact, see :func:`_split_columns`) and Bl (plain doubles)
    are recomputed from scratch at the start of the chunk.  Column sum
    s_j = (Bh_j + Vh_jl) + (Bl_j + Vl_jl): the first addition is exact (a
    signed partial sum of H), so s_j carries one rounding plus the error of
    the lo part.  |Bl_j| ≤ n·q_j/2 and each of its ≤ csize+n additions adds
    ≤ u·n·q_j/2, so with csize ≤ 2^24, n ≤ 40 and q_j ≤ 4u·c_j the lo part is
    off by ≤ (2^24+n+m)·n·2u²·c_j < 2^−75·c_j: the sums are as accurate as
    double-double running sums, and the caller's per-term error model (≤ n+1
    roundings per product) is unchanged.
    """
    n = H.shape[0]
    nl = Vh.shape[1]
    g = start ^ (start >> 1)
    bh = H[0].copy()
    bl = L[0].copy()
    for i in range(m + 1, n):
        neg = (g >> (i - m - 1)) & 1
        for j in range(n):
            bh[j] += -H[i, j] if neg else H[i, j]
            bl[j] += -L[i, j] if neg else L[i, j]
    sign = -1.0 if _parity(g) else 1.0
    P = np.empty(nl)
    acc = np.zeros(nl)
    cacc = np.zeros(nl)
    aacc = np.zeros(nl)
    qacc = np.zeros(nl)
    for step in range(csize):
        if step > 0:
            # start is a multiple of csize, so start+step flips bit tz(step)
            b = _trailing_zeros(step)
            d = 2.0 if (g >> b) & 1 else -2.0
            g ^= np.int64(1) << b
            sign = -sign
            r = b + m + 1
            for j in range(n):  # ±2h: exact
                bh[j] += d * H[r, j]
                bl[j] += d * L[r, j]
        # the vectorised part: lanes are the 2^m low-bit patterns
        h = bh[0]
        e = bl[0]
        for lo in range(nl):
            P[lo] = sign * sg[lo] * ((h + Vh[0, lo]) + (e + Vl[0, lo]))
        for j in range(1, n):
            h = bh[j]
            e = bl[j]
            for lo in range(nl):
                P[lo] *= (h + Vh[j, lo]) + (e + Vl[j, lo])
        for lo in range(nl):
            p = P[lo]
            s = acc[lo] + p
            t = s - acc[lo]
            cacc[lo] += (acc[lo] - (s - t)) + (p - t)
            acc[lo] = s
            aacc[lo] += abs(p)
            qacc[lo] += p * p
    return _combine_parts(acc, cacc, aacc, qacc)


@nb.njit(cache=True)
def _combine_parts(res, comp, absr, sq):
    """(Σ res, its compensation, Σ absr, Σ sq), the first two by two-sum."""
    s = 0.0
    cs = 0.0
    a = 0.0
    q = 0.0
    for c in range(res.shape[0]):
        s, e = _two_sum(s, res[c])
        cs += e + comp[c]
        a += absr[c]
        q += sq[c]
    return s, cs, a, q


@nb.njit(parallel=True, cache=True)
def glynn_kernel(A, log2_chunk):
    """Return (Σ terms, Σ |terms|, √Σ terms²) of Glynn's formula, each divided by 2^{n−1}.

    Row 0 always enters with δ = +1.  Rows 1…m (m = min(6, n−1)) are bits
    0…m−1 of the in-block index, rows m+1…n−1 bits of the high Gray code
    (bit set means δ = −1).  ``log2_chunk`` is the log₂ of the number of terms
    per parallel chunk (raised to keep ≤ 2^20 chunks, capped at 2^30 terms).
    """
    n = A.shape[0]
    m = min(_LOW_BITS, n - 1)
    H, L = _split_columns(A)
    Vh, Vl, sg = _low_tables(H, L, m)
    total = np.int64(1) << (n - 1 - m)  # high Gray codes
    cbits = max(log2_chunk - m, n - 1 - m - _MAX_CHUNKS_BITS)
    csize = min(total, np.int64(1) << min(max(cbits, 0), _MAX_CHUNK_BITS))
    nchunks = total // csize
    res = np.zeros(nchunks)
    comp = np.zeros(nchunks)
    absr = np.zeros(nchunks)
    sq = np.zeros(nchunks)
    for c in nb.prange(nchunks):
        v, e, a, q = _glynn_chunk(H, L, Vh, Vl, sg, m, c * csize, csize)
        res[c] = v
        comp[c] = e
        absr[c] = a
        sq[c] = q
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
