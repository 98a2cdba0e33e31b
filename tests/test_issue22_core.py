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

import importlib
import itertools
import math
import warnings
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from brute import log_fraction
from jointtrack.assignment import assignment_sum, is_feasible, sinkhorn
from jointtrack.assignment._checks import (
    as_counts,
    as_float,
    as_int,
    as_log_weights,
    as_null_weights,
    as_weights,
)
from jointtrack.association import marginals as jpda_marginals
from jointtrack.errors import ExactLimitError, InfeasibleAssignmentError
from jointtrack.identity import deconflict
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


# --------------------------------------------------------------------------- item 11: sinkhorn


def _log_permanent_brute(L):
    """log Per(exp L) by enumeration, in log space (n ≤ 5)."""
    n = L.shape[0]
    terms = [math.fsum(L[i, p[i]] for i in range(n)) for p in itertools.permutations(range(n))]
    top = max(terms)
    return top + math.log(math.fsum(math.exp(t - top) for t in terms))


@settings(max_examples=40, deadline=None)
@given(
    st.integers(2, 5).flatmap(
        lambda n: st.lists(
            st.lists(st.floats(-1500.0, 1500.0), min_size=n, max_size=n),
            min_size=n,
            max_size=n,
        )
    )
)
def test_sinkhorn_deconflict_takes_strictly_positive_matrices(log_m):
    """Strictly positive M (finite log M) always has a Sinkhorn scaling (Sinkhorn 1964).

    The result is checked against what characterises the scaling: B is doubly
    stochastic, B is a diagonal scaling of M (every cross ratio of B equals that
    of M, where all four entries of B are in range) and van der Waerden's bounds
    bracket the exact log Per(M).
    """
    L = np.array(log_m)
    res = deconflict(log_M=L, method="sinkhorn")
    B = res.P
    assert not np.isnan(B).any()
    np.testing.assert_allclose(B.sum(axis=0), 1.0, rtol=0, atol=1e-9)
    np.testing.assert_allclose(B.sum(axis=1), 1.0, rtol=0, atol=1e-9)
    n = L.shape[0]
    with np.errstate(divide="ignore"):
        lb = np.log(B)
    for i, k in itertools.combinations(range(n), 2):
        for j, m in itertools.combinations(range(n), 2):
            quad = [lb[i, j], lb[i, m], lb[k, j], lb[k, m]]
            if min(quad) > -600.0:  # all four far from the underflow range
                got = quad[0] - quad[1] - quad[2] + quad[3]
                want = L[i, j] - L[i, m] - L[k, j] + L[k, m]
                assert got == pytest.approx(want, abs=1e-7), (i, j, k, m)
    exact = _log_permanent_brute(L)
    slack = 1e-9 * max(1.0, abs(exact))
    assert res.log_normalizer <= exact + slack
    assert exact <= res.info["log_normalizer_upper"] + slack


def test_sinkhorn_deconflict_issue_example():
    # flushing e^-800 relative to 1 left an upper-triangular support: "lacks total support"
    L = np.array([[0.0, 0.0, 5.0], [-800.0, 0.0, 3.0], [-900.0, -850.0, 0.0]])
    res = deconflict(log_M=L, method="sinkhorn")
    np.testing.assert_allclose(res.P.sum(axis=0), 1.0, atol=1e-9)
    np.testing.assert_allclose(res.P.sum(axis=1), 1.0, atol=1e-9)
    # the same scaling from the coefficients themselves when they are in range
    M = np.exp(np.array([[0.0, 0.0, 5.0], [-700.0, 0.0, 3.0], [-705.0, -702.0, 0.0]]))
    d1, B, d2 = sinkhorn(M)
    res = deconflict(M, method="sinkhorn")
    np.testing.assert_allclose(res.P, B, rtol=0, atol=1e-12)


# --------------------------------------------------------------------------- item 15: validation


def test_sinkhorn_name_is_the_function():
    import jointtrack.permanent.bethe  # noqa: F401  (imported the module behind it)
    from jointtrack.assignment import sinkhorn as s1
    from jointtrack.permanent import sinkhorn as s2

    assert callable(s1) and s1 is s2 is sinkhorn
    assert "sinkhorn" in importlib.import_module("jointtrack.assignment").__all__


@pytest.mark.parametrize(
    "args, name",
    [
        (([[1.0, np.nan]],), "W"),
        (([[np.inf]],), "W"),
        (([[-1.0]],), "W"),
        (([[1.0]], [np.nan]), "null"),
        (([[1.0]], None, [np.nan]), "row_counts"),
        (([[1.0]], None, None, [1.5]), "col_counts"),
    ],
)
def test_is_feasible_refuses_nan(args, name):
    with pytest.raises(ValueError, match=name):
        is_feasible(*args)


def test_is_feasible_still_decides():
    assert is_feasible([[1.0, 0.0], [0.0, 2.0]])
    assert not is_feasible([[1.0, 0.0], [1.0, 0.0]])
    assert is_feasible([[1.0, 0.0], [1.0, 0.0]], [0.0, 0.5])
    assert not is_feasible([[1.0, 0.0]], None, [2], [1, 1])
    assert is_feasible([[1.0, 1.0]], None, [2], [1, 1])


MASKED = np.ma.array([[1.0, 2.0], [3.0, 4.0]], mask=[[False, True], [False, False]])


@pytest.mark.parametrize(
    "call, name",
    [
        (lambda: as_weights(MASKED, "W"), "W"),
        (lambda: as_log_weights(MASKED, "log_W"), "log_W"),
        (lambda: as_null_weights(MASKED[0], 2, "null"), "null"),
        (lambda: as_counts(np.ma.array([1, 2], mask=[True, False]), 2, "row_counts"), "row_counts"),
        (lambda: as_float(np.ma.masked, "tol"), "tol"),
        (lambda: as_float(np.ma.array(2.0), "tol"), "tol"),
        (lambda: as_int(np.ma.array(3), "max_bits"), "max_bits"),
        (lambda: as_weights([[1.0, np.ma.masked]], "W"), "W"),
        # the public faces, through the shared validators
        (lambda: assignment_sum(MASKED), "W"),
        (lambda: log_permanent(MASKED), "A"),
        (lambda: jpda_marginals(MASKED, [0.5, 0.5]), "L"),
        (lambda: is_feasible(MASKED), "W"),
        (lambda: sinkhorn(MASKED), "A"),
    ],
)
def test_masked_arrays_are_refused(call, name):
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # and no "converting a masked element" warning
        with pytest.raises(TypeError, match=rf"{name} is a masked array"):
            call()


@pytest.mark.parametrize(
    "call, name, what",
    [
        (lambda: as_float(1 + 2j, "tol"), "tol", "real number"),
        (lambda: as_float(np.array(1 + 0j), "tol"), "tol", "real number"),
        (lambda: as_float(True, "tol"), "tol", "real number"),
        (lambda: as_float("1.0", "tol"), "tol", "real number"),
        (lambda: as_float(10**400, "tol"), "tol", "too large"),
        (lambda: as_int(10**400, "n_samples", 2), "n_samples", "too large"),
        (lambda: as_int(True, "n_samples"), "n_samples", "integer"),
        (lambda: as_int("3", "n_samples"), "n_samples", "whole number"),
        (lambda: as_int(3 + 0j, "n_samples"), "n_samples", "whole number"),
        (lambda: as_weights([[1 + 0j]], "W"), "W", "complex"),
        (lambda: as_weights([[True, 1.0]], "W"), "W", "boolean"),
        (lambda: as_weights(np.ones((1, 1), bool), "W"), "W", "boolean"),
        (lambda: as_weights([["a"]], "W"), "W", "real numbers"),
        (lambda: as_weights("abc", "W"), "W", "string"),
        (lambda: as_weights([[10**400]], "W"), "W", "too large"),
        (lambda: as_log_weights([[10**400]], "log_W"), "log_W", "too large"),
        (lambda: as_null_weights([10**400], 1, "null"), "null", "too large"),
        (lambda: as_null_weights([1j], 1, "null"), "null", "complex"),
        (lambda: as_counts([10**400], 1, "row_counts"), "row_counts", "too large"),
        (lambda: as_counts([True], 1, "row_counts"), "row_counts", "boolean"),
        (lambda: as_counts(["a"], 1, "row_counts"), "row_counts", "not a number"),
        (lambda: as_counts([1j], 1, "row_counts"), "row_counts", "complex"),
    ],
)
def test_shared_validators_refuse_non_real_input(call, name, what):
    with pytest.raises(ValueError, match=rf"(?s){name}.*{what}"):
        call()


# --------------------------------------------------------------------------- issue 25: warnings

#: a Newton trial step of this scaling overflowed ``c / tau`` in the error measure
OVERSHOOT = [
    [9.2946673269326e109, 1.5639949280567127e-191, 3.1710719848199776e-207],
    [0.0, 1.2821332808534318e16, 1.2718653427072846e63],
    [0.0, 1.4404384968131558e-274, 0.0],
]
OVERSHOOT = [
    OVERSHOOT[0] + [2.2347763763769203e-115, 2.103948039564816e-175],
    OVERSHOOT[1] + [4.705095930500076e32, 4.2768885814474567e192],
    OVERSHOOT[2] + [5.1618128297009646e-139, 4.364231140168713e-260],
]


def _check_scaling(A, d1, B, d2):
    """B = diag(d1) A diag(d2), rows summing to 1 and columns to n/m."""
    n, m = A.shape
    np.testing.assert_allclose(B.sum(axis=1), 1.0, rtol=0, atol=1e-9)
    np.testing.assert_allclose(B.sum(axis=0), n / m, rtol=0, atol=1e-9)
    assert (B[A == 0] == 0).all()
    # in logs: d1·A·d2 itself can pass through the subnormal range
    pos = (A > 0) & (B > 1e-280)
    with np.errstate(divide="ignore"):
        scaled = np.log(d1)[:, None] + np.log(A) + np.log(d2)[None, :]
        np.testing.assert_allclose(scaled[pos], np.log(B[pos]), rtol=0, atol=1e-9)


def test_sinkhorn_does_not_warn_on_an_overshooting_newton_step():
    A = np.array(OVERSHOOT)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        d1, B, d2 = sinkhorn(A)
    _check_scaling(A, d1, B, d2)


@settings(max_examples=40, deadline=None)
@given(
    st.integers(2, 4).flatmap(
        lambda n: st.tuples(
            st.just(n),
            st.integers(n, n + 2).flatmap(
                lambda m: st.lists(
                    st.lists(
                        st.one_of(st.integers(-300, 300).map(lambda e: 10.0**e), VALUE),
                        min_size=m,
                        max_size=m,
                    ),
                    min_size=n,
                    max_size=n,
                )
            ),
        )
    )
)
@example(problem=(2, [[1e285, 0.0, 1e7], [5e-324, 2.3444855318705343e21, 0.0]]))  # subnormal d
def test_sinkhorn_never_warns(problem):
    """Valid input: a scaling or a clear exception, and no RuntimeWarning either way."""
    _, rows = problem
    A = np.array(rows)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        try:
            d1, B, d2 = sinkhorn(A)
        except ValueError as exc:  # no total support / factors out of range: said clearly
            assert "A" in str(exc)
            return
    _check_scaling(A, d1, B, d2)
