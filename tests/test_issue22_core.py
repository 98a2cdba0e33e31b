"""Regressions of issue 22 in the assignment core, permanents and deconfliction.

* item 2: blocks of ≥ 1024 columns raised a bare ``OverflowError`` (``2.0 ** K`` in
  the cost model); they are small problems for the DP and must be exact;
* item 11: ``deconflict(method="sinkhorn")`` refused strictly positive matrices;
* item 15: the shared validators let NaN (``is_feasible``) and masked arrays
  through; ``jointtrack.assignment.sinkhorn`` was the module, not the function.

Exact references are closed forms evaluated in rational arithmetic
(:class:`fractions.Fraction`, every float64 is a dyadic rational): for one or two
rows the assignment sum is

* 1 row:  ``Z = u + S``, ``S = Σ_c w_c``;
* 2 rows: ``Z = u₁u₂ + u₁S₂ + u₂S₁ + S₁S₂ − D``, ``D = Σ_c w₁c w₂c``,
  ``P(1 ↔ c) = w₁c (u₂ + S₂ − w₂c) / Z``, ``P(1 ↔ ∅) = u₁ (u₂ + S₂) / Z``.

Tolerances as in tests/test_assignment_core.py: ``log Z`` to 1e-12 relative (absolute
below 1), every marginal to 1e-12 absolute.
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from brute import log_fraction
from jointtrack.assignment import assignment_sum
from jointtrack.association import marginals as jpda_marginals
from jointtrack.errors import ExactLimitError, InfeasibleAssignmentError
from jointtrack.permanent import assignment_marginals, log_permanent, permanent

TOL_LOG = 1e-12
TOL_P = 1e-12
SETTINGS = settings(
    max_examples=30,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)

# --------------------------------------------------------------------------- item 2: wide blocks

#: zeros, arbitrary floats from the subnormal range to 1e300, powers of ten
VALUE = st.one_of(
    st.just(0.0),
    st.floats(min_value=5e-324, max_value=1e300, allow_subnormal=True),
    st.integers(-320, 300).map(lambda e: 10.0**e),
    st.just(1.0),
)
NULL = st.one_of(
    st.just(0.0),
    st.floats(min_value=5e-324, max_value=1.0, allow_subnormal=True),
    st.just(1.0),
)


@st.composite
def wide_rows(draw, n_rows):
    """(W, null): 1024…1100 columns; each row a drawn base value with ≤ 8 drawn exceptions.

    A hypothesis buffer cannot hold 2000 independently drawn floats, so each row
    is a repeated value with a few columns set apart (both drawn, so failures
    shrink); the exceptions make columns distinct, so the frontier DP runs too.
    """
    C = draw(st.integers(1024, 1100))
    W = np.empty((n_rows, C))
    for r in range(n_rows):
        W[r] = draw(VALUE)
        for c, x in draw(st.dictionaries(st.integers(0, C - 1), VALUE, max_size=8)).items():
            W[r, c] = x
    null = np.array([draw(NULL) for _ in range(n_rows)])
    return W, null


_SHIFT = 1074  # every float64 is an integer multiple of 2^-1074


def _int(x):
    """x · 2^1074 as an exact Python int."""
    n, d = float(x).as_integer_ratio()
    return n * ((1 << _SHIFT) // d)


def _exact(W, null):
    """(log Z, P, Pnull) of the assignment sum of 1 or 2 rows, exactly (closed forms).

    Evaluated on the integers x · 2^1074, so every sum and product is exact; each
    probability is one correctly rounded int / int division. ``P`` is None when
    Z = 0 (log Z = -inf).
    """
    R, C = W.shape
    F = [[_int(x) for x in row] for row in W]
    U = [_int(x) for x in null]
    S = [sum(row) for row in F]
    if R == 1:
        Z = U[0] + S[0]
        if Z == 0:
            return -math.inf, None, None
        return _log_int(Z, 1), np.array([[w / Z for w in F[0]]]), np.array([U[0] / Z])
    D = sum(a * b for a, b in zip(F[0], F[1], strict=True))
    Z = U[0] * U[1] + U[0] * S[1] + U[1] * S[0] + S[0] * S[1] - D
    if Z == 0:
        return -math.inf, None, None
    P = [
        [F[0][c] * (U[1] + S[1] - F[1][c]) / Z for c in range(C)],
        [F[1][c] * (U[0] + S[0] - F[0][c]) / Z for c in range(C)],
    ]
    Pn = [U[0] * (U[1] + S[1]) / Z, U[1] * (U[0] + S[0]) / Z]
    return _log_int(Z, 2), np.array(P), np.array(Pn)


def _log_int(Z, factors):
    """log(Z · 2^(−1074·factors)) for a positive int Z of any size."""
    return log_fraction(Fraction(Z, 1 << (_SHIFT * factors)))


def _check_log(got, want):
    if want == -math.inf:
        assert got == -math.inf
        return
    assert abs(got - want) <= TOL_LOG * max(1.0, abs(want)), (got, want)


def _check_p(got, want):
    assert not np.isnan(got).any()
    np.testing.assert_allclose(got, want, rtol=0, atol=TOL_P)


@SETTINGS
@given(st.integers(1, 2).flatmap(wide_rows), st.sampled_from(["auto", "frontier"]))
def test_wide_blocks_are_exact(problem, method):
    W, null = problem
    logz, P, Pn = _exact(W, null)
    res = assignment_sum(W, null, marginals=False, method=method)
    _check_log(res.log_normalizer, logz)
    if P is None:
        with pytest.raises(InfeasibleAssignmentError):
            assignment_sum(W, null, method=method)
        return
    res = assignment_sum(W, null, method=method)
    _check_log(res.log_normalizer, logz)
    _check_p(res.P, P)
    _check_p(res.null, Pn)
    # the JPDA face on the same core: beta = [null | P]
    if (null > 0).all():
        beta = jpda_marginals(W, null)
        _check_p(beta[:, 1:], P)
        _check_p(beta[:, 0], Pn)


@SETTINGS
@given(st.integers(1, 2).flatmap(wide_rows))
def test_wide_permanents_are_exact(problem):
    W, _ = problem
    R = W.shape[0]
    logz, P, _ = _exact(W, np.zeros(R))
    _check_log(log_permanent(W), logz)
    if P is None:
        assert permanent(W) == 0.0
        with pytest.raises(InfeasibleAssignmentError):
            assignment_marginals(W)
        return
    _check_p(assignment_marginals(W), P)
    if -700.0 < logz < 700.0:  # permanent() itself is in the float range
        assert math.log(permanent(W)) == pytest.approx(logz, rel=TOL_LOG, abs=TOL_LOG)


@SETTINGS
@given(wide_rows(2), st.sampled_from(["auto", "frontier"]))
def test_wide_blocks_transposed(problem, method):
    """1024+ rows of two columns: with all null weights 1 it is the transposed problem."""
    W, _ = problem
    R, C = W.shape
    logz, P, _ = _exact(W, np.ones(R))
    res = assignment_sum(W.T, np.ones(C), method=method)
    _check_log(res.log_normalizer, logz)
    _check_p(res.P.T, P)


def test_issue_examples_of_wide_blocks():
    n = 1024
    assert log_permanent(np.ones((2, n))) == pytest.approx(math.log(n * (n - 1)), rel=1e-15)
    assert permanent(np.ones((2, n))) == pytest.approx(n * (n - 1), rel=1e-15)
    beta = jpda_marginals(np.ones((2, n)), [0.1, 0.1])
    # Z = u² + 2u·n + n(n−1); P(r ↔ c) = (u + n − 1)/Z, P(r ↔ ∅) = u(u + n)/Z
    u = Fraction(0.1)  # the float 0.1 exactly (it is not 1/10)
    Z = u * u + 2 * u * n + n * (n - 1)
    np.testing.assert_allclose(beta[:, 1:], float((u + n - 1) / Z), rtol=0, atol=TOL_P)
    np.testing.assert_allclose(beta[:, 0], float(u * (u + n) / Z), rtol=0, atol=TOL_P)


def test_a_wide_block_past_the_budget_is_refused_cleanly():
    # 31 rows fully gated with 1024 distinct columns: 2^31 subsets either way
    W = 1.0 + np.arange(31 * 1024, dtype=float).reshape(31, 1024) / 7.0
    with pytest.raises(ExactLimitError, match="max_bits"):
        assignment_sum(W, np.ones(31))
    with pytest.raises(ExactLimitError, match="max_bits"):
        log_permanent(W)
