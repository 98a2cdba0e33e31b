"""Glynn's kernel: accuracy and honesty of its error estimate, against references.

The kernel (``_inclusion_exclusion.glynn_kernel``) keeps the running column sums
exact (H part, see ``_split_columns``) plus a small plain-double part; core.py
accepts its value when 4·√n·u·‖terms‖₂/|Per| ≤ GLYNN_TOLERANCE.  Here we check,
on uniform and badly-scaled matrices, that

* an accepted value has relative error ≤ 1e-12 (against the frontier DP);
* the estimate is honest: the kernel's actual relative error on the scaled,
  balanced matrix it is given is ≤ the estimate — against the exact permanent
  (integer Glynn) for n ≤ 14, and against the frontier DP (error ≲ n·u, plus
  the rounding of exp/log of its result) for larger n.
"""

from __future__ import annotations

import math
import warnings
from fractions import Fraction

import numpy as np
import pytest

import jointtrack.assignment.core as core
from jointtrack.assignment import _inclusion_exclusion as _ie
from jointtrack.assignment import assignment_sum

U = 2.0**-53


def family(n, k, seed):
    """Uniform matrix; with k > 0 rows and columns scaled by 10**U(−k, 0)."""
    rng = np.random.default_rng(seed)
    A = rng.random((n, n))
    if k:
        A = A * 10.0 ** rng.uniform(-k, 0, (n, 1)) * 10.0 ** rng.uniform(-k, 0, (1, n))
    return A


def exact_permanent(B):
    """Per(B) as a Fraction: Glynn's formula in Python integers (B's entries are dyadic)."""
    n = B.shape[0]
    e = min(math.frexp(x)[1] for x in B.ravel() if x != 0.0) - 53
    M = [[int(Fraction(float(x)) / Fraction(2) ** e) for x in row] for row in B]
    s = [sum(M[i][j] for i in range(n)) for j in range(n)]  # δ = all +1
    total = 0
    sign = 1
    g = 0
    for k in range(1, 2 ** (n - 1) + 1):
        total += sign * math.prod(s)
        if k == 2 ** (n - 1):
            break
        b = (k & -k).bit_length() - 1
        d = 2 if (g >> b) & 1 else -2
        g ^= 1 << b
        row = M[b + 1]
        s = [s[j] + d * row[j] for j in range(n)]
        sign = -sign
    return Fraction(total, 2 ** (n - 1)) * Fraction(2) ** (n * e)


def glynn_run(A, monkeypatch, tolerance=math.inf):
    """assignment_sum(method='glynn') with the kernel's input/output recorded."""
    seen = {}
    kernel = _ie.glynn_kernel

    def spy(B, log2_chunk):
        out = kernel(B, log2_chunk)
        seen["B"] = B.copy()
        seen["out"] = out
        return out

    with monkeypatch.context() as m:
        m.setattr(_ie, "glynn_kernel", spy)
        m.setattr(core, "GLYNN_TOLERANCE", tolerance)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            res = assignment_sum(A, marginals=False, method="glynn")
    return res, seen["B"], seen["out"]


def estimate_of(n, out):
    value, _, l2 = out
    return 4.0 * math.sqrt(n) * U * l2 / value if value > 0.0 else math.inf


SMALL = [(n, k, 100 * k + n) for n in (12, 13, 14) for k in (0, 2, 5, 20)]
LARGE = [(n, k, 100 * k + n) for n in (15, 16, 18, 20, 22) for k in (0, 2, 5, 20)]


@pytest.mark.parametrize(("n", "k", "seed"), SMALL)
def test_estimate_honest_against_exact(n, k, seed, monkeypatch):
    res, B, out = glynn_run(family(n, k, seed), monkeypatch)
    est = estimate_of(n, out)
    assert res.info["error_estimate"] == est
    err = abs(float(Fraction(out[0]) / exact_permanent(B) - 1))
    assert err <= est, (n, k, err, est)


@pytest.mark.parametrize(("n", "k", "seed"), SMALL + LARGE)
def test_accepted_value_accurate_and_estimate_honest(n, k, seed, monkeypatch):
    A = family(n, k, seed)
    ref = assignment_sum(A, marginals=False, method="frontier").log_normalizer
    res, B, out = glynn_run(A, monkeypatch)
    est = estimate_of(n, out)
    # the kernel's own relative error on B, against the DP on B: the DP's error
    # (≲ n·u) and the rounding of its log and of exp() are allowed on top
    ref_B = assignment_sum(B, marginals=False, method="frontier").log_normalizer
    err_B = abs(math.expm1(math.log(out[0]) - ref_B))
    assert err_B <= est + (n + 2) * U + 2 * U * abs(ref_B), (n, k, err_B, est)
    # what the user gets, through the accepting path
    accepted, _, _ = glynn_run(A, monkeypatch, tolerance=core.GLYNN_TOLERANCE)
    if est <= core.GLYNN_TOLERANCE:
        assert accepted.method == "glynn"
        assert abs(math.expm1(accepted.log_normalizer - ref)) <= 1e-12, (n, k)
        assert abs(accepted.log_normalizer - ref) <= 1e-12 * abs(ref)
    else:
        assert accepted.method != "glynn"


def test_kernel_matches_exact_small_and_degenerate():
    """n = 1…9 (fewer than the 2^6 lanes of one block), zero columns, ±1 entries."""
    rng = np.random.default_rng(5)
    for n in range(1, 10):
        A = rng.random((n, n))
        value, a, l2 = _ie.glynn_kernel(A, 12)
        exact = float(exact_permanent(A))
        assert abs(value / exact - 1) <= 4 * math.sqrt(n) * U * l2 / value + 2 * U
        assert a >= abs(value) * (1 - n * U) and l2 > 0.0
    Z = rng.random((7, 7))
    Z[:, 3] = 0.0
    assert _ie.glynn_kernel(Z, 12)[0] == 0.0
    assert _ie.glynn_kernel(np.ones((8, 8)), 12)[0] == pytest.approx(40320.0, rel=1e-15)


def test_kernel_chunking_does_not_change_the_value():
    A = family(17, 2, 3)
    ref = _ie.glynn_kernel(A, 12)
    for bits in (0, 6, 8, 16, 30):
        v = _ie.glynn_kernel(A, bits)
        assert v[0] == pytest.approx(ref[0], rel=1e-14)
        assert v[2] == pytest.approx(ref[2], rel=1e-12)
