"""Brute-force references shared by the tests (itertools enumeration, tiny sizes only)."""

from __future__ import annotations

import itertools
from fractions import Fraction

import numpy as np


def _exact_permanent(A) -> Fraction:
    A = np.asarray(A, dtype=float)
    n, m = A.shape
    F = [[Fraction(float(x)) for x in row] for row in A]
    total = Fraction(0)
    for cols in itertools.permutations(range(m), n):
        p = Fraction(1)
        for i, j in enumerate(cols):
            p *= F[i][j]
            if p == 0:
                break
        total += p
    return total


def brute_permanent(A) -> float:
    """Sum over injective maps of rows into columns, in exact rational arithmetic."""
    return float(_exact_permanent(A))


def brute_marginals(A) -> np.ndarray:
    """P[t, i] = A[t, i] Per(A without row t, col i) / Per(A), by enumeration."""
    A = np.asarray(A, dtype=float)
    n, m = A.shape
    F = [[Fraction(float(x)) for x in row] for row in A]
    acc = [[Fraction(0)] * m for _ in range(n)]
    total = Fraction(0)
    for cols in itertools.permutations(range(m), n):
        p = Fraction(1)
        for i, j in enumerate(cols):
            p *= F[i][j]
        if p == 0:
            continue
        total += p
        for i, j in enumerate(cols):
            acc[i][j] += p
    if total == 0:
        raise ZeroDivisionError("no feasible assignment")
    return np.array([[float(x / total) for x in row] for row in acc])


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
