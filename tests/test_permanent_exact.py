"""Exact permanent methods: brute force, each other, invariances, bad input."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from brute import brute_log_permanent, brute_marginals, brute_permanent, expand
from jointtrack import InfeasibleAssignmentError
from jointtrack.permanent import (
    assignment_marginals,
    log_permanent,
    permanent,
    sinkhorn,
)

EXACT = ["dp", "multiset", "auto"]


@st.composite
def matrices(draw, max_n=6, max_extra=2, square=False):
    """Random non-negative matrices with zeros and badly scaled entries."""
    n = draw(st.integers(1, max_n))
    m = n if square else n + draw(st.integers(0, max_extra))
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    A = rng.random((n, m))
    A[rng.random((n, m)) < draw(st.sampled_from([0.0, 0.2, 0.5]))] = 0.0
    decades = draw(st.sampled_from([0, 3, 30, 150]))
    A *= 10.0 ** rng.uniform(-decades, 0, (n, 1)) * 10.0 ** rng.uniform(-decades, 0, (1, m))
    return A


def rel(a, b):
    if b == 0:
        return abs(a)
    return abs(a / b - 1)


def log_close(a, b, tol=1e-13):
    """Relative error of exp(a) against exp(b), allowing for the rounding of b itself."""
    if b == -math.inf:
        return a == -math.inf
    return abs(math.expm1(a - b)) <= tol + 4 * 2.0**-53 * abs(b)


@settings(max_examples=120, deadline=None)
@given(matrices())
def test_exact_methods_match_brute_force(A):
    exact = brute_log_permanent(A)
    for method in EXACT:
        got = log_permanent(A, method)
        assert log_close(got, exact), (method, got, exact)
    if -700 < exact < 700:
        assert rel(permanent(A), math.exp(exact)) <= 1e-13 + 4 * 2.0**-53 * abs(exact)


@settings(max_examples=60, deadline=None)
@given(matrices(square=True))
def test_inclusion_exclusion_match_brute_force(A):
    # Alternating sums: accurate to 1e-12, or a RuntimeWarning with the estimated error.
    exact = brute_log_permanent(A)
    for method in ("glynn", "ryser"):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            got = log_permanent(A, method)
        warned = any("estimated relative rounding error" in str(w.message) for w in caught)
        assert warned or log_close(got, exact, tol=1e-12), method


@settings(max_examples=80, deadline=None)
@given(matrices())
def test_marginals_match_brute_force(A):
    if brute_log_permanent(A) == -math.inf:
        with pytest.raises(InfeasibleAssignmentError, match="no feasible assignment"):
            assignment_marginals(A)
        return
    P = assignment_marginals(A)
    np.testing.assert_allclose(P, brute_marginals(A), atol=1e-13)
    np.testing.assert_allclose(P.sum(axis=1), 1.0, atol=1e-13)
    if A.shape[0] == A.shape[1]:
        np.testing.assert_allclose(P.sum(axis=0), 1.0, atol=1e-13)


@pytest.mark.parametrize("n", [8, 11, 14])
def test_exact_methods_agree_with_each_other(n):
    rng = np.random.default_rng(n)
    for trial in range(3):
        A = rng.random((n, n)) * 10.0 ** rng.uniform(-3, 0, (n, 1))
        values, warned = {}, set()
        for method in ("dp", "multiset", "glynn", "ryser", "auto"):
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                values[method] = log_permanent(A, method)
            if caught:
                warned.add(method)
        assert not warned & {"dp", "multiset", "auto", "glynn"}
        ref = values["dp"]
        for method, v in values.items():
            tol = 1e-10 if method in warned else 1e-12
            assert abs(math.expm1(v - ref)) <= tol, (trial, method, v, ref)


def test_wide_rectangular_matches_direct_sum():
    # m ≫ n: padded with one group of m − n dummy rows (a factor m−n+1 of states).
    import itertools

    rng = np.random.default_rng(3)
    A = rng.random((3, 25)) * 10.0 ** rng.uniform(-40, 0, (1, 25))
    direct = math.fsum(
        A[0, i] * A[1, j] * A[2, k] for i, j, k in itertools.permutations(range(25), 3)
    )
    for method in ("auto", "dp", "multiset"):
        assert rel(permanent(A, method), direct) < 1e-13
    P = assignment_marginals(A)
    np.testing.assert_allclose(P.sum(axis=1), 1.0, atol=1e-13)
    # P[0, i] = A[0, i] · Per(rows 1–2 without column i) / Per(A)
    for i in (0, 7, 24):
        rest = np.delete(A[1:], i, axis=1)
        assert P[0, i] == pytest.approx(A[0, i] * permanent(rest) / direct, rel=1e-12)


@settings(max_examples=40, deadline=None)
@given(matrices(max_n=5, max_extra=3), st.integers(0, 2**32 - 1))
def test_permutation_and_scaling_invariance(A, seed):
    rng = np.random.default_rng(seed)
    n, m = A.shape
    base = log_permanent(A, "dp")
    if base == -math.inf:
        assert log_permanent(A[rng.permutation(n)][:, rng.permutation(m)]) == -math.inf
        return
    permuted = A[rng.permutation(n)][:, rng.permutation(m)]
    assert abs(log_permanent(permuted) - base) <= 1e-12 * max(1.0, abs(base))
    # Row scaling scales the permanent exactly (powers of two: no rounding at all).
    e = rng.integers(-40, 40, n)
    assert log_permanent(np.ldexp(A, e[:, None])) == pytest.approx(
        base + e.sum() * math.log(2), rel=0, abs=1e-12 * max(1.0, abs(base))
    )
    if n == m:
        d = 10.0 ** rng.uniform(-5, 5, m)
        want = base + np.log(d).sum()
        assert abs(log_permanent(A * d[None, :]) - want) <= 1e-12 * max(1.0, abs(want))
    else:
        c = 10.0 ** rng.uniform(-5, 5)
        want = base + n * math.log(c)
        assert abs(log_permanent(A * c) - want) <= 1e-12 * max(1.0, abs(want))


@st.composite
def compressed(draw):
    rows = draw(st.lists(st.integers(1, 3), min_size=1, max_size=3))
    cols = draw(st.lists(st.integers(1, 3), min_size=1, max_size=3))
    if sum(rows) > sum(cols):
        rows, cols = cols, rows
    if sum(cols) > 7:
        cols = [1] * sum(rows)
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    W = rng.random((len(rows), len(cols)))
    W[rng.random(W.shape) < 0.25] = 0
    return W, np.array(rows), np.array(cols)


# the rational brute force of a 7×7 expansion dominates: fewer, still drawn, cases
@settings(max_examples=35, deadline=None)
@given(compressed())
def test_repeated_rows_and_columns_equal_expanded(case):
    W, rows, cols = case
    E = expand(W, rows, cols)
    exact = brute_permanent(E)
    assert rel(permanent(W, row_counts=rows, col_counts=cols), exact) <= 1e-13
    assert rel(permanent(E), exact) <= 1e-13  # auto detects the repeats itself
    if exact == 0:
        with pytest.raises(InfeasibleAssignmentError):
            assignment_marginals(W, rows, cols)
        return
    P = assignment_marginals(W, rows, cols)
    want = brute_marginals(E)  # once: a 7×7 expansion enumerates 5,040 permutations
    np.testing.assert_allclose(expand(P, rows, cols), want, atol=1e-13)
    np.testing.assert_allclose(assignment_marginals(E), want, atol=1e-13)


def test_schaub_three_class_marginals_match_expanded_rows():
    # 100×100 with 3 column classes: the compressed result equals a row-orientation
    # DP on an independent expansion of 30 rows with the classes kept apart.
    rng = np.random.default_rng(5)
    W = rng.random((100, 3)) + 0.01
    cols = np.array([60, 30, 10])
    P = assignment_marginals(W, col_counts=cols)
    np.testing.assert_allclose(P @ cols, 1.0, atol=1e-12)
    np.testing.assert_allclose(P.sum(axis=0), 1.0, atol=1e-12)
    # Shrunk version small enough to expand: 9 rows, classes 5/3/1.
    small, c_small = W[:9], np.array([5, 3, 1])
    np.testing.assert_allclose(
        expand(assignment_marginals(small, col_counts=c_small), None, c_small),
        assignment_marginals(expand(small, None, c_small), None, None),
        atol=1e-13,
    )


def test_hidden_rows_and_rectangular_groups():
    rng = np.random.default_rng(6)
    W = rng.random((3, 8))
    rows = np.array([1, 1, 6])
    P = assignment_marginals(W, row_counts=rows)
    np.testing.assert_allclose(
        expand(P, rows, None), brute_marginals(expand(W, rows, None)), atol=1e-13
    )
    # and a rectangular one (columns may stay unused: the "skip" programme)
    rows = np.array([1, 3])
    W = rng.random((2, 7))
    P = assignment_marginals(W, row_counts=rows)
    np.testing.assert_allclose(
        expand(P, rows, None), brute_marginals(expand(W, rows, None)), atol=1e-13
    )
    assert rel(permanent(W, row_counts=rows), brute_permanent(expand(W, rows, None))) < 1e-13


def test_log_permanent_never_underflows():
    A = np.full((100, 100), 1e-50)
    want = 100 * math.log(1e-50) + math.lgamma(101)
    assert log_permanent(A) == pytest.approx(want, rel=1e-14)
    rng = np.random.default_rng(0)
    W = 1e-50 * (rng.random((100, 3)) + 0.01)
    v = log_permanent(W, col_counts=[60, 30, 10])
    assert math.isfinite(v) and v < -11000
    with pytest.raises(OverflowError, match="log_permanent"):
        permanent(A)
    with pytest.raises(OverflowError, match="log_permanent"):
        permanent(np.full((200, 200), 1e10))


def test_badly_scaled_dp_and_glynn_agree():
    rng = np.random.default_rng(11)
    n = 16
    for k in (2, 5, 20, 150):
        A = (
            rng.random((n, n))
            * 10.0 ** rng.uniform(-k, 0, (n, 1))
            * 10.0 ** rng.uniform(-k, 0, (1, n))
        )
        assert abs(math.expm1(log_permanent(A, "glynn") - log_permanent(A, "dp"))) < 1e-12


def test_no_feasible_assignment():
    A = np.array([[1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 1.0]])
    for method in ("auto", "dp", "multiset", "glynn", "ryser"):
        assert permanent(A, method) == 0.0
        assert log_permanent(A, method) == -math.inf
    with pytest.raises(InfeasibleAssignmentError, match="no feasible assignment"):
        assignment_marginals(A)
    with pytest.raises(InfeasibleAssignmentError):
        sinkhorn(A)


@pytest.mark.parametrize(
    "bad, message",
    [
        (np.ones(3), "2-D"),
        (np.ones((3, 2)), "more rows than columns"),
        (np.array([[1.0, -1.0], [1.0, 1.0]]), "negative"),
        (np.array([[1.0, np.nan], [1.0, 1.0]]), "non-finite"),
        (np.array([[1.0, np.inf], [1.0, 1.0]]), "non-finite"),
        ([["a", "b"]], "real numbers"),
    ],
)
def test_bad_input(bad, message):
    for fn in (permanent, log_permanent, assignment_marginals):
        with pytest.raises(ValueError, match=message):
            fn(bad)


def test_bad_counts():
    W = np.ones((2, 2))
    with pytest.raises(ValueError, match="row_counts"):
        permanent(W, row_counts=[1, 2, 3])
    with pytest.raises(ValueError, match="col_counts"):
        permanent(W, col_counts=[0, 2])
    with pytest.raises(ValueError, match="more rows than columns"):
        permanent(W, row_counts=[3, 3], col_counts=[1, 1])
    with pytest.raises(ValueError, match="integers"):
        permanent(W, row_counts=[1.5, 1])
    with pytest.raises(ValueError, match="unknown method"):
        permanent(W, method="magic")
    # rectangular input is padded to square with all-ones rows (Per([A; J]) = (m−n)! Per(A))
    assert permanent(np.ones((2, 3)), method="glynn") == pytest.approx(6.0, rel=1e-15)


def test_empty_and_trivial():
    assert permanent(np.zeros((0, 3))) == 1.0
    assert permanent([[2.5]]) == 2.5
    np.testing.assert_array_equal(assignment_marginals([[0.0, 3.0]]), [[0.0, 1.0]])


def test_sinkhorn_doubly_stochastic_and_eq39():
    rng = np.random.default_rng(2)
    A = rng.random((6, 6)) * 10.0 ** rng.uniform(-8, 0, (6, 1))
    d1, B, d2 = sinkhorn(A)
    np.testing.assert_allclose(B.sum(0), 1, atol=1e-11)
    np.testing.assert_allclose(B.sum(1), 1, atol=1e-11)
    np.testing.assert_allclose(B, d1[:, None] * A * d2[None, :], rtol=1e-12)
    # Schaub eq. (39): Per(B) = Π d1 Π d2 Per(A)
    assert log_permanent(B) == pytest.approx(
        np.log(d1).sum() + np.log(d2).sum() + log_permanent(A), abs=1e-11
    )
    R = rng.random((3, 5))
    _, B, _ = sinkhorn(R)
    np.testing.assert_allclose(B.sum(1), 1, atol=1e-11)
    np.testing.assert_allclose(B.sum(0), 3 / 5, atol=1e-11)
    with pytest.raises(ValueError, match="total support"):
        sinkhorn(np.array([[1.0, 1.0], [0.0, 1.0]]), max_iter=200)
