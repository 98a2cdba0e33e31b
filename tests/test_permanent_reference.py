"""The exact rational reference for permanents and assignment marginals.

Both the reference and the brute-force enumeration in ``brute.py`` are exact
rationals rounded once, so they must agree *bit for bit* — the tests use
equality, not tolerances, wherever both are exact.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from brute import brute_marginals, brute_permanent, expand
from jointtrack.errors import InfeasibleAssignmentError
from jointtrack.permanent.reference import (
    reference_log_permanent,
    reference_marginals,
    reference_permanent,
)

# --------------------------------------------------------------------------- strategies


@st.composite
def entries(draw, wide: bool):
    """A non-negative float: 0 sometimes, else mantissa × 10^e (|e| ≤ 300 when wide)."""
    if draw(st.integers(0, 4)) == 0:
        return 0.0
    mant = draw(st.floats(1.0, 10.0, allow_nan=False, allow_infinity=False))
    e = draw(st.integers(-300, 300)) if wide else draw(st.integers(-2, 2))
    return mant * 10.0**e


@st.composite
def matrices(draw, max_n: int = 6, max_m: int = 7, wide: bool = True):
    n = draw(st.integers(1, max_n))
    m = draw(st.integers(n, max(n, max_m)))
    if n * m > 36:  # keep the m!/(m-n)! enumeration of brute.py small
        m = n
    vals = draw(st.lists(entries(wide), min_size=n * m, max_size=n * m))
    return np.array(vals, dtype=float).reshape(n, m)


def brute_or_inf(A) -> float:
    try:
        return brute_permanent(A)
    except OverflowError:  # float(Fraction) overflows: the correctly rounded value is inf
        return math.inf


def row_scale_log(A):
    """Exact power-of-two row scaling: (B, c) with Per(A) = Per(B)·2^c, row maxima in [.5, 1)."""
    B = A.copy()
    c = 0
    for t in range(A.shape[0]):
        mx = A[t].max()
        if mx > 0:
            k = math.frexp(mx)[1]
            B[t] = np.ldexp(A[t], -k)
            c += k
    return B, c


# --------------------------------------------------------------------------- vs brute force


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(matrices(wide=True))
def test_permanent_is_correctly_rounded_wide_range(A):
    # entries 1e-300..1e300 and zeros: the exact value may over- or underflow
    assert reference_permanent(A) == brute_or_inf(A)


@settings(max_examples=150, deadline=None)
@given(matrices(wide=False))
def test_permanent_is_correctly_rounded_moderate(A):
    assert reference_permanent(A) == brute_permanent(A)


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(matrices(wide=True))
def test_log_permanent_matches_brute_after_exact_rescaling(A):
    B, c = row_scale_log(A)
    per_b = brute_permanent(B)  # Per(B) ≤ m!/(m-n)!: cannot overflow
    got = reference_log_permanent(A)
    if per_b == 0.0:
        # exact zero, or an underflow of B's permanent; the reference must know which
        exact_zero = reference_permanent(np.where(A > 0, 1.0, 0.0)) == 0.0
        assert (got == -math.inf) == exact_zero
        return
    assume(per_b > 2.0**-1000)  # a normal float: log(per_b) is then accurate
    want = math.log(per_b) + c * math.log(2.0)
    assert got == pytest.approx(want, rel=1e-14, abs=1e-13)


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(matrices(wide=True))
def test_marginals_are_correctly_rounded(A):
    try:
        want = brute_marginals(A)
    except ZeroDivisionError:
        with pytest.raises(InfeasibleAssignmentError):
            reference_marginals(A)
        return
    got = reference_marginals(A)
    assert got.shape == A.shape
    np.testing.assert_array_equal(got, want)


def test_known_values():
    assert reference_permanent(np.ones((10, 10))) == math.factorial(10)
    assert reference_permanent(np.ones((4, 9))) == 9 * 8 * 7 * 6
    assert reference_permanent([[1.0, 2.0], [3.0, 4.0]]) == 10.0
    assert reference_permanent(np.zeros((0, 0))) == 1.0  # empty product
    assert reference_log_permanent(np.eye(5)) == 0.0
    # one compressed group: the all-ones 100×100 matrix, Per = 100!
    assert reference_permanent([[1.0]], [100], [100]) == float(math.factorial(100))
    assert reference_log_permanent([[1.0]], [100], [100]) == pytest.approx(
        math.log(math.factorial(100)), rel=1e-15
    )


def test_exact_zero_is_distinguished_from_underflow():
    A = np.array([[1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 1.0]])  # Hall's condition fails
    assert reference_permanent(A) == 0.0
    assert reference_log_permanent(A) == -math.inf
    with pytest.raises(InfeasibleAssignmentError, match="permanent is 0"):
        reference_marginals(A)
    tiny = np.full((4, 4), 1e-200)  # Per = 24e-800: underflows but is not zero
    assert reference_permanent(tiny) == 0.0
    assert reference_log_permanent(tiny) == pytest.approx(math.log(24) + 4 * math.log(1e-200))
    np.testing.assert_array_equal(reference_marginals(tiny), np.full((4, 4), 0.25))


def test_overflow_rounds_to_inf_and_log_stays_finite():
    A = np.full((3, 3), 1e200)
    assert reference_permanent(A) == math.inf
    assert reference_log_permanent(A) == pytest.approx(math.log(6) + 3 * math.log(1e200))


# --------------------------------------------------------------------------- compressed


@st.composite
def compressed(draw):
    g = draw(st.integers(1, 3))
    h = draw(st.integers(1, 3))
    rows = draw(st.lists(st.integers(1, 3), min_size=g, max_size=g))
    cols = draw(st.lists(st.integers(1, 4), min_size=h, max_size=h))
    assume(sum(rows) <= sum(cols) <= 7)
    vals = draw(st.lists(entries(wide=False), min_size=g * h, max_size=g * h))
    return np.array(vals).reshape(g, h), np.array(rows), np.array(cols)


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(compressed())
def test_compressed_equals_expanded(case):
    W, rows, cols = case
    E = expand(W, rows, cols)
    per = reference_permanent(W, rows, cols)
    assert per == reference_permanent(E) == brute_permanent(E)
    assert reference_log_permanent(W, rows, cols) == reference_log_permanent(E)
    if per == 0.0:
        with pytest.raises(InfeasibleAssignmentError):
            reference_marginals(W, rows, cols)
        return
    P = reference_marginals(W, rows, cols)
    PE = brute_marginals(E)
    np.testing.assert_array_equal(expand(P, rows, cols), PE)  # every member gets the value
    np.testing.assert_allclose((P * cols).sum(axis=1), 1.0, rtol=1e-14)


def test_compressed_groups_on_both_sides():
    W = np.array([[0.3, 2.0], [1.5, 0.25]])
    rows, cols = [2, 3], [4, 2]
    E = expand(W, rows, cols)
    assert E.shape == (5, 6)
    assert reference_permanent(W, rows, cols) == brute_permanent(E)
    np.testing.assert_array_equal(
        expand(reference_marginals(W, rows, cols), rows, cols), brute_marginals(E)
    )


def _minor_check(W, rows, cols, P, q, j):
    """P[q, j] = W[q, j]·Per(minor)/Per, the minor removing one member of each group."""
    r2, c2 = np.array(rows).copy(), np.array(cols).copy()
    r2[q] -= 1
    c2[j] -= 1
    keep_r, keep_c = r2 > 0, c2 > 0
    log_minor = reference_log_permanent(W[keep_r][:, keep_c], r2[keep_r], c2[keep_c])
    want = W[q, j] * math.exp(log_minor - reference_log_permanent(W, rows, cols))
    assert P[q, j] == pytest.approx(want, rel=1e-12)


def test_schaub_three_classes_100x100():
    rng = np.random.default_rng(3)
    W = rng.random((100, 3)) + 0.01
    rows, cols = np.ones(100, int), np.array([60, 30, 10])
    P = reference_marginals(W, None, cols)
    assert P.shape == (100, 3)
    np.testing.assert_allclose((P * cols).sum(axis=1), 1.0, rtol=1e-14)  # rows
    np.testing.assert_allclose(P.sum(axis=0), 1.0, rtol=1e-13)  # every identity used once
    for q, j in [(0, 0), (17, 1), (99, 2)]:
        _minor_check(W, rows, cols, P, q, j)


def test_schaub_hidden_rows_100x100():
    rng = np.random.default_rng(4)
    W = rng.random((7, 100)) + 0.01  # 6 observed tracks + one hidden row repeated 94 times
    rows, cols = np.array([1, 1, 1, 1, 1, 1, 94]), np.ones(100, int)
    P = reference_marginals(W, rows, None)
    assert P.shape == (7, 100)
    np.testing.assert_allclose(P.sum(axis=1), 1.0, rtol=1e-13)
    np.testing.assert_allclose((P * rows[:, None]).sum(axis=0), 1.0, rtol=1e-13)
    for q, j in [(0, 0), (5, 42), (6, 99)]:
        _minor_check(W, rows, cols, P, q, j)


def test_log_form_finite_for_tiny_30x30():
    # entries ~1e-50·U: Per ≈ 1e-1500·30!·…, far below float64; scaled by an exact power of two
    rng = np.random.default_rng(5)
    U = rng.random((30, 3)) + 0.05
    cols = [10, 10, 10]
    A = np.ldexp(U, -166)  # 2^-166 ≈ 1.1e-50
    got = reference_log_permanent(A, None, cols)
    assert math.isfinite(got) and got < -3000
    assert reference_permanent(A, None, cols) == 0.0  # underflow, not zero
    assert got == pytest.approx(reference_log_permanent(U, None, cols) - 30 * 166 * math.log(2))
    # and a dense (uncompressed) one
    D = np.ldexp(rng.random((12, 12)), -166)
    want = reference_log_permanent(np.ldexp(D, 166)) - 12 * 166 * math.log(2)
    assert reference_log_permanent(D) == pytest.approx(want, rel=1e-15)


def test_rectangular_marginals_rows_sum_to_one():
    rng = np.random.default_rng(6)
    A = rng.random((6, 11))
    P = reference_marginals(A)
    np.testing.assert_allclose(P.sum(axis=1), 1.0, rtol=1e-14)
    assert np.all(P.sum(axis=0) < 1.0)  # 5 columns stay free in every assignment
    np.testing.assert_allclose(P.sum(), 6.0, rtol=1e-14)


# --------------------------------------------------------------------------- bad input


@pytest.mark.parametrize(
    ("A", "kwargs", "match"),
    [
        ([[1.0, -1.0], [1.0, 1.0]], {}, "negative"),
        ([[1.0, np.nan], [1.0, 1.0]], {}, "non-finite"),
        ([[1.0, np.inf], [1.0, 1.0]], {}, "non-finite"),
        ([1.0, 2.0], {}, "2-D"),
        (np.ones((3, 2)), {}, "more rows than columns"),
        ([["a", "b"]], {}, "real numbers"),
        ([[1.0, 2.0]], {"col_counts": [1, 0]}, "≥ 1"),
        ([[1.0, 2.0]], {"col_counts": [1]}, "one entry per"),
        ([[1.0, 2.0]], {"col_counts": [1.5, 1]}, "integers"),
        ([[1.0, 2.0]], {"row_counts": [3]}, "more rows than columns"),
    ],
)
@pytest.mark.parametrize("fn", [reference_permanent, reference_log_permanent, reference_marginals])
def test_bad_input_raises_value_error(fn, A, kwargs, match):
    with pytest.raises(ValueError, match=match):
        fn(A, **kwargs)


@pytest.mark.parametrize("fn", [reference_permanent, reference_marginals])
def test_refuses_sizes_that_would_take_hours(fn):
    with pytest.raises(ValueError, match="too large for the exact reference"):
        fn(np.ones((30, 30)))
    # compression makes the same matrix trivial
    assert reference_permanent(np.ones((1, 1)), [30], [30]) == float(math.factorial(30))
