"""Brute-force references shared by the tests (itertools enumeration, tiny sizes only).

Exact arithmetic on integers: every float64 is a dyadic rational, an integer times
2⁻¹⁰⁷⁴ (:func:`_scaled`), so a product of k weights is an integer times 2⁻¹⁰⁷⁴ᵏ. Each
enumerated term below is a product of the same number of weights (one per row), so
the terms add as plain integers and one :class:`~fractions.Fraction` is formed at the
end — the same exact values as adding Fractions term by term, without the gcd that
Fraction takes after every operation (that gcd was most of the property tests' CPU).
"""

from __future__ import annotations

import itertools
from fractions import Fraction

import numpy as np

#: every finite float64 is an integer multiple of 2⁻¹⁰⁷⁴ (the smallest subnormal)
_SCALE_BITS = 1074


def _scaled(x) -> int:
    """The float ``x`` times 2¹⁰⁷⁴: an integer, exactly."""
    p, q = float(x).as_integer_ratio()  # q is a power of two ≤ 2¹⁰⁷⁴
    return p * ((1 << _SCALE_BITS) // q)


def _unscaled(total: int, factors: int) -> Fraction:
    """``total`` · 2^(−1074 · factors): a sum of products of ``factors`` weights, exactly."""
    return Fraction(total, 1 << (_SCALE_BITS * factors))


def _exact_permanent(A) -> Fraction:
    A = np.asarray(A, dtype=float)
    n, m = A.shape
    F = [[_scaled(x) for x in row] for row in A]
    total = 0
    for cols in itertools.permutations(range(m), n):
        p = 1
        for i, j in enumerate(cols):
            p *= F[i][j]
            if p == 0:
                break
        total += p
    return _unscaled(total, n)


def brute_permanent(A) -> float:
    """Sum over injective maps of rows into columns, in exact rational arithmetic."""
    return float(_exact_permanent(A))


def brute_marginals(A) -> np.ndarray:
    """P[t, i] = A[t, i] Per(A without row t, col i) / Per(A), by enumeration."""
    A = np.asarray(A, dtype=float)
    n, m = A.shape
    F = [[_scaled(x) for x in row] for row in A]
    acc = [[0] * m for _ in range(n)]
    total = 0
    for cols in itertools.permutations(range(m), n):
        p = 1
        for i, j in enumerate(cols):
            p *= F[i][j]
        if p == 0:
            continue
        total += p
        for i, j in enumerate(cols):
            acc[i][j] += p
    if total == 0:
        raise ZeroDivisionError("no feasible assignment")
    # the common scale 2^(1074 n) cancels: the exact quotient, rounded once
    return np.array([[float(Fraction(x, total)) for x in row] for row in acc])


def _log_fraction(x: Fraction) -> float:
    import math

    if x == 0:
        return -math.inf
    p, q = x.numerator, x.denominator
    sp, sq = max(p.bit_length() - 60, 0), max(q.bit_length() - 60, 0)
    return math.log(p >> sp) - math.log(q >> sq) + (sp - sq) * math.log(2)


def brute_log_permanent(A) -> float:
    """log of the exact permanent (finite even when the value under/overflows float64)."""
    return _log_fraction(_exact_permanent(A))


def _matchings(R: int, C: int, allow_null):
    """Every partial matching: tuples of a column index or None per row."""

    def rec(r, used):
        if r == R:
            yield ()
            return
        if allow_null[r]:
            for rest in rec(r + 1, used):
                yield (None, *rest)
        for c in range(C):
            if c not in used:
                for rest in rec(r + 1, used | {c}):
                    yield (c, *rest)

    yield from rec(0, frozenset())


def brute_assignment(W, null=None, row_counts=None, col_counts=None):
    """Exact (Fraction) Z, pair marginals and null marginals of the assignment sum.

    Compressed input is expanded; the marginals returned are those of the first
    member of each row group and column group (any member gives the same).
    Returns ``(Z, P, Pnull)`` with P, Pnull as lists of Fractions (None if Z = 0).
    """
    W = np.asarray(W, dtype=float)
    R0, C0 = W.shape
    rc = [1] * R0 if row_counts is None else [int(x) for x in row_counts]
    cc = [1] * C0 if col_counts is None else [int(x) for x in col_counts]
    nl = [0.0] * R0 if null is None else [float(x) for x in np.broadcast_to(null, (R0,))]
    rows = [q for q in range(R0) for _ in range(rc[q])]
    cols = [j for j in range(C0) for _ in range(cc[j])]
    F = [[_scaled(W[q, j]) for j in cols] for q in rows]
    U = [_scaled(nl[q]) for q in rows]
    R, C = len(rows), len(cols)
    acc = [[0] * C for _ in range(R)]
    accn = [0] * R
    total = 0
    for sigma in _matchings(R, C, [u != 0 for u in U]):
        p = 1  # one weight per row (a column's or the null): R factors of 2^1074
        for r, c in enumerate(sigma):
            p *= U[r] if c is None else F[r][c]
            if p == 0:
                break
        if p == 0:
            continue
        total += p
        for r, c in enumerate(sigma):
            if c is None:
                accn[r] += p
            else:
                acc[r][c] += p
    if total == 0:
        return Fraction(0), None, None
    first_r = np.concatenate([[0], np.cumsum(rc)[:-1]]).astype(int)
    first_c = np.concatenate([[0], np.cumsum(cc)[:-1]]).astype(int)
    P = [[Fraction(acc[r][c], total) for c in first_c] for r in first_r]
    Pn = [Fraction(accn[r], total) for r in first_r]
    return _unscaled(total, R), P, Pn


def log_fraction(x: Fraction) -> float:
    """Natural log of a non-negative Fraction (−inf for 0), correct beyond the float range."""
    return _log_fraction(x)


def expand(A, row_counts=None, col_counts=None) -> np.ndarray:
    """Expand a compressed matrix (row group q repeated row_counts[q] times, …)."""
    A = np.asarray(A, dtype=np.float64)
    r = np.ones(A.shape[0], int) if row_counts is None else np.asarray(row_counts, int)
    c = np.ones(A.shape[1], int) if col_counts is None else np.asarray(col_counts, int)
    return np.repeat(np.repeat(A, r, axis=0), c, axis=1)


def brute_grouped(W, null=None, row_counts=None, col_counts=None):
    """Exact (Fraction) ``(Z, P, Pnull)`` of compressed input without expanding it.

    Enumerates the count matrices k (k[q][c] = how many members of row group q
    take a member of column group c). One k stands for

        Π_q n_q! / (Π_c k[q][c]! · (n_q − s_q)!) · Π_c m_c! / (m_c − t_c)!

    matchings of the expansion (s_q, t_c the row/column sums of k), each of weight
    Π W[q][c]^k[q][c] · Π null_q^(n_q − s_q). By symmetry one member of row group
    q takes one member of column group c with probability E[k[q][c]] / (n_q m_c)
    and stays unassigned with probability E[n_q − s_q] / n_q. Same conventions
    and return value as :func:`brute_assignment` (whose expansion it equals), but
    cheap for large groups.
    """
    from math import factorial

    W = np.asarray(W, dtype=float)
    R0, C0 = W.shape
    rc = [1] * R0 if row_counts is None else [int(x) for x in row_counts]
    cc = [1] * C0 if col_counts is None else [int(x) for x in col_counts]
    nl = [0.0] * R0 if null is None else [float(x) for x in np.broadcast_to(null, (R0,))]
    F = [[_scaled(W[q, c]) for c in range(C0)] for q in range(R0)]
    U = [_scaled(x) for x in nl]

    def row_vectors(q, free):
        # every k[q] with Σ_c k[q][c] ≤ rc[q] (== if null is 0) and k[q][c] ≤ free[c]
        def rec(c, left):
            if c == C0:
                if U[q] == 0 and left != 0:
                    return
                yield ()
                return
            for k in range(min(left, free[c]) + 1):
                if k and F[q][c] == 0:
                    break
                for rest in rec(c + 1, left - k):
                    yield (k, *rest)

        yield from rec(0, rc[q])

    # each row group q contributes rc[q] weights (k's and nulls): Σ rc factors of 2^1074
    total = 0
    acc = [[0] * C0 for _ in range(R0)]
    accn = [0] * R0

    def rec(q, free, ks):
        nonlocal total
        if q == R0:
            w = 1
            for qq, kq in enumerate(ks):
                s = sum(kq)
                mult = factorial(rc[qq]) // factorial(rc[qq] - s)
                for c, k in enumerate(kq):
                    mult //= factorial(k)
                    w *= F[qq][c] ** k
                w *= mult * U[qq] ** (rc[qq] - s)
            for c in range(C0):
                t = cc[c] - free[c]
                w *= factorial(cc[c]) // factorial(cc[c] - t)
            if w == 0:
                return
            total += w
            for qq, kq in enumerate(ks):
                accn[qq] += w * (rc[qq] - sum(kq))
                for c, k in enumerate(kq):
                    if k:
                        acc[qq][c] += w * k
            return
        for kq in row_vectors(q, free):
            rec(q + 1, [f - k for f, k in zip(free, kq, strict=True)], ks + [kq])

    rec(0, list(cc), [])
    if total == 0:
        return Fraction(0), None, None
    P = [[Fraction(acc[q][c], total * rc[q] * cc[c]) for c in range(C0)] for q in range(R0)]
    Pn = [Fraction(accn[q], total * rc[q]) for q in range(R0)]
    return _unscaled(total, sum(rc)), P, Pn


def mixed_derivative_fraction(a, F) -> Fraction:
    """Streit's ∂^M Ψ/∂β_1…∂β_M (0) at a0 = 0 in exact rationals, by enumeration.

    Each factor takes one measurement (f_km) or none (f_k0), each measurement at
    most one factor; a measurement no factor takes is clutter (a_m).
    """
    a = [_scaled(x) for x in a]
    F = [[_scaled(x) for x in row] for row in np.asarray(F, float)]
    M = len(a)
    # a term has a weight per factor and per measurement left to clutter: at most
    # len(F) + M weights; one with fewer is brought to that common scale by a shift
    most = len(F) + M
    total = 0
    for choice in itertools.product(range(M + 1), repeat=len(F)):  # 0 = none
        taken = [j for j in choice if j]
        if len(taken) != len(set(taken)):
            continue
        w = 1
        for k, j in enumerate(choice):
            w *= F[k][j]
        for m in range(M):
            if m + 1 not in taken:
                w *= a[m]
        total += w << (_SCALE_BITS * len(taken))
    return _unscaled(total, most)
