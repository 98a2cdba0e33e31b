"""Regression examples of the assignment-sum core and its faces, against exact truth.

Every expected value is computed here, exactly, by enumeration in rational
arithmetic (``brute.brute_assignment``); nothing is a hard-coded float. The
comment next to each example gives the value it was reported with (and what
went wrong at the time).

Tolerances as in ``test_assignment_core``: ``log`` values to ``1e-12 ·
max(1, |log|)``, values (when inside float64) to a relative 1e-12 (plus one
subnormal unit), every probability to an absolute 1e-12, rows summing to 1.
"""

from __future__ import annotations

import math
import sys
import warnings
from fractions import Fraction

import numpy as np
import pytest

from brute import brute_assignment, log_fraction
from jointtrack.assignment import assignment_sum
from jointtrack.association import exact_jpda, marginals
from jointtrack.errors import InfeasibleAssignmentError
from jointtrack.permanent import assignment_marginals, log_permanent, permanent

TOL = 1e-12
SMALLEST = 2.0**-1074
PERMANENT_METHODS = ("dp", "multiset", "auto", "reference")
CORE_METHODS = ("frontier", "groups", "auto")


# --------------------------------------------------------------------------- helpers


def exact(W, null=None, row_counts=None, col_counts=None):
    """(Z, P, Pnull) as Fractions, Z the permanent when null is None."""
    return brute_assignment(np.asarray(W, dtype=float), null, row_counts, col_counts)


def float_or_none(Z: Fraction):
    """float(Z) correctly rounded, or None if a positive Z rounds to 0 or overflows."""
    if Z == 0:
        return 0.0
    try:
        f = float(Z)
    except OverflowError:
        return None
    return None if f == 0.0 or math.isinf(f) else f


def assert_log(got, Z, what="log"):
    assert not math.isnan(got), f"{what} is NaN"
    if Z == 0:
        assert got == -math.inf, f"{what}: Z = 0 but got {got!r}"
        return
    true = log_fraction(Z)
    assert abs(got - true) <= TOL * max(1.0, abs(true)), f"{what}: got {got!r}, true {true!r}"


def assert_value(got, Z, what="value"):
    f = float_or_none(Z)
    assert f is not None
    assert not math.isnan(got)
    assert abs(got - f) <= TOL * abs(f) + (SMALLEST if f else 0.0), (
        f"{what}: got {got!r}, true {f!r}"
    )


def assert_probabilities(P, Pt, what="P", cols=None):
    P = np.asarray(P)
    Pt = np.array([[float(x) for x in row] for row in Pt])
    assert P.shape == Pt.shape, (P.shape, Pt.shape)
    assert not np.isnan(P).any(), f"{what} has NaN:\n{P!r}"
    err = np.abs(P - Pt).max()
    assert err <= TOL, f"{what}: error {err:.3g}\ngot\n{P!r}\ntrue\n{Pt!r}"


def beta_true(Pt, Pnt):
    return [[pn, *row] for pn, row in zip(Pnt, Pt, strict=True)]


def check_permanent(A, method, row_counts=None, col_counts=None):
    """permanent(A, method): the true value, or OverflowError naming log_permanent."""
    Z = exact(A, None, row_counts, col_counts)[0]
    kw = dict(row_counts=row_counts, col_counts=col_counts)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # glynn/ryser falling back to the DP
        if float_or_none(Z) is None:
            with pytest.raises(OverflowError, match="log_permanent"):
                permanent(A, method, **kw)
        else:
            assert_value(permanent(A, method, **kw), Z, f"permanent({method})")
        assert_log(log_permanent(A, method, **kw), Z, f"log_permanent({method})")


# --------------------------------------------------------------------------- the examples

# (id, A, row_counts, col_counts): faces permanent / log_permanent / assignment_marginals
PERMANENT_CASES = [
    # log_permanent: true -478.94 (Per = 1e-208)
    ("per-1e-208", [[0, 1e-10, 1e122, 0], [0, 0, 1e-198, 1e9], [0, 0, 0, 1]], None, None),
    # permanent: true 1.8e201
    ("per-1.8e201", [[1, 1, 1, 1e200]] * 3, None, None),
    # permanent: true 1e-10
    (
        "per-1e-10",
        [[0, 0, 1, 0, 0], [0, 0, 0, 1, 0], [1e-54, 0, 0, 1e68, 0], [0, 0, 1e249, 0, 1e44]],
        None,
        None,
    ),
    # log_permanent: true -297.03; assignment_marginals was a bare OverflowError
    ("per-e-297", [[1, 1, 0], [0, 1e-129, 1e188], [0, 0, 1]], None, None),
    # assignment_marginals: were NaN rows
    ("nan-rows", [[1, 0, 0, 0, 0], [1e111, 0, 0, 1e-120, 0], [1e220, 1, 1e89, 0, 0]], None, None),
    # log_permanent: true -744.44 (Per = 5e-324, the smallest subnormal)
    ("per-5e-324", [[5e-324, 1, 0], [0, 1, 0]], None, None),
    # permanent, compressed: true 1.8e241
    ("grp-1.8e241", [[1.0, 1e240]], [3], [3, 1]),
    # log_permanent, compressed: true -491.37
    ("grp-e-491", [[1e-283, 1e69]], [2], [2, 1]),
    # log_permanent, compressed: true 187.90
    ("grp-e188", [[1e201, 1e-120, 0.0]], [2], [1, 2, 1]),
]
PERMANENT_IDS = [c[0] for c in PERMANENT_CASES]

# (id, L, miss): the JPDA face (jointtrack.association.marginals)
JPDA_CASES = [
    # was ZeroDivisionError
    ("jpda-miss-1e-300", [[1.0, 1e171], [1e-164, 1.0], [1e199, 0.0]], [1e-300] * 3),
    # was ZeroDivisionError
    (
        "jpda-subnormal",
        [[0, 1, 4.904079099405633e-294, 0], [0, 0, 1e162, 0], [0, 1e162, 1, 0]],
        [1.0, 1.0, 0.0],
    ),
]
JPDA_IDS = [c[0] for c in JPDA_CASES]


def test_reported_true_values():
    """The values the examples were reported with are those of the exact sums."""
    reported = {
        "per-1e-208": -478.94,
        "per-e-297": -297.03,
        "per-5e-324": -744.44,
        "grp-e-491": -491.37,
        "grp-e188": 187.90,
    }
    for name, A, rc, cc in PERMANENT_CASES:
        Z = exact(A, None, rc, cc)[0]
        if name in reported:
            assert round(log_fraction(Z), 2) == reported[name], name
    by_id = {c[0]: c for c in PERMANENT_CASES}
    assert exact(*[by_id["per-1e-208"][1]])[0] == Fraction(1e-10) * Fraction(1e-198)
    assert float(exact(by_id["per-1.8e201"][1])[0]) == pytest.approx(1.8e201, rel=1e-15)
    assert float(exact(by_id["per-1e-10"][1])[0]) == pytest.approx(1e-10, rel=1e-15)
    assert float(exact(by_id["per-5e-324"][1])[0]) == 5e-324
    _, A, rc, cc = by_id["grp-1.8e241"]
    assert float(exact(A, None, rc, cc)[0]) == pytest.approx(1.8e241, rel=1e-15)


@pytest.mark.parametrize("method", PERMANENT_METHODS)
@pytest.mark.parametrize("case", PERMANENT_CASES, ids=PERMANENT_IDS)
def test_log_permanent_regression(case, method):
    _, A, rc, cc = case
    Z = exact(A, None, rc, cc)[0]
    assert_log(
        log_permanent(A, method, row_counts=rc, col_counts=cc), Z, f"log_permanent({method})"
    )


@pytest.mark.parametrize("method", PERMANENT_METHODS)
@pytest.mark.parametrize("case", PERMANENT_CASES, ids=PERMANENT_IDS)
def test_permanent_regression(case, method):
    _, A, rc, cc = case
    check_permanent(A, method, rc, cc)


@pytest.mark.parametrize("method", ["glynn", "ryser"])
@pytest.mark.parametrize("case", PERMANENT_CASES, ids=PERMANENT_IDS)
def test_inclusion_exclusion_regression(case, method):
    """Glynn/Ryser: within 1e-10 of the truth, or a RuntimeWarning (and then the DP's value)."""
    _, A, rc, cc = case
    Z = exact(A, None, rc, cc)[0]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        got = log_permanent(A, method, row_counts=rc, col_counts=cc)
    warned = any(issubclass(w.category, RuntimeWarning) for w in caught)
    true = log_fraction(Z)
    assert not math.isnan(got)
    if warned:
        assert_log(got, Z, f"log_permanent({method}) after its warning")
    else:
        assert abs(got - true) <= 1e-10 * max(1.0, abs(true)), (method, got, true)


@pytest.mark.parametrize("case", PERMANENT_CASES, ids=PERMANENT_IDS)
def test_assignment_marginals_regression(case):
    _, A, rc, cc = case
    Z, Pt, _ = exact(A, None, rc, cc)
    P = assignment_marginals(A, rc, cc)
    assert_probabilities(P, Pt, "assignment_marginals")
    cols = np.ones(np.shape(A)[1]) if cc is None else np.asarray(cc, float)
    assert np.abs(P @ cols - 1.0).max() <= TOL


@pytest.mark.parametrize("marginals_", [True, False], ids=["marginals", "value"])
@pytest.mark.parametrize("method", CORE_METHODS)
@pytest.mark.parametrize("case", PERMANENT_CASES, ids=PERMANENT_IDS)
def test_core_on_permanent_regressions(case, method, marginals_):
    _, A, rc, cc = case
    Z, Pt, Pnt = exact(A, None, rc, cc)
    res = assignment_sum(A, None, row_counts=rc, col_counts=cc, marginals=marginals_, method=method)
    assert_log(res.log_normalizer, Z, f"assignment_sum({method})")
    if marginals_:
        assert_probabilities(res.beta, beta_true(Pt, Pnt), f"assignment_sum({method}).beta")


@pytest.mark.parametrize("case", JPDA_CASES, ids=JPDA_IDS)
def test_jpda_marginals_regression(case):
    _, L, miss = case
    Z, Pt, Pnt = exact(L, miss)
    beta = marginals(L, miss)
    assert_probabilities(beta, beta_true(Pt, Pnt), "marginals(method='exact')")
    assert np.abs(beta.sum(axis=1) - 1.0).max() <= TOL
    res = exact_jpda(L, miss)
    assert_log(res.log_normalizer, Z, "exact_jpda.log_normalizer")
    assert_probabilities(res.beta, beta_true(Pt, Pnt), "exact_jpda.beta")


@pytest.mark.parametrize("marginals_", [True, False], ids=["marginals", "value"])
@pytest.mark.parametrize("method", CORE_METHODS)
@pytest.mark.parametrize("case", JPDA_CASES, ids=JPDA_IDS)
def test_core_on_jpda_regressions(case, method, marginals_):
    _, L, miss = case
    Z, Pt, Pnt = exact(L, miss)
    res = assignment_sum(L, miss, marginals=marginals_, method=method)
    assert_log(res.log_normalizer, Z, f"assignment_sum({method})")
    if marginals_:
        assert_probabilities(res.beta, beta_true(Pt, Pnt), f"assignment_sum({method}).beta")


# --------------------------------------------------------------------------- OverflowError contract


def diag(*d):
    return np.diag(np.array(d, dtype=float))


MAX = sys.float_info.max
# permanent(A) must raise OverflowError (naming log_permanent) exactly when the
# exact permanent, rounded to float64, is 0 or inf although it is positive.
OVERFLOW_CASES = [
    ("diag(1e200,1e200)", diag(1e200, 1e200)),  # 1e400: overflows
    ("diag(1e-200,1e-200)", diag(1e-200, 1e-200)),  # 1e-400: underflows
    ("diag(1e200,1.8e108)", diag(1e200, 1.8e108)),  # 1.8e308 > MAX: overflows
    ("diag(2^600,2^424)", diag(2.0**600, 2.0**424)),  # 2^1024: overflows
    ("diag(2^-600,2^-476)", diag(2.0**-600, 2.0**-476)),  # 2^-1076: rounds to 0
    ("4x4 all 1e100", np.full((4, 4), 1e100)),  # 24e400
    ("2x3 all 1e-200", np.full((2, 3), 1e-200)),  # 6e-400
    ("diag(1e200,1.7e108)", diag(1e200, 1.7e108)),  # 1.7e308: representable
    ("[[MAX]]", np.array([[MAX]])),  # the largest float
    ("diag(2^600,2^423)", diag(2.0**600, 2.0**423)),  # 2^1023
    ("diag(2^-600,2^-474)", diag(2.0**-600, 2.0**-474)),  # 2^-1074: smallest subnormal
    ("diag(1e-200,3e-124)", diag(1e-200, 3e-124)),  # 3e-324 → 5e-324
    ("3x3 all 1e100", np.full((3, 3), 1e100)),  # 6e300
    ("[[1,1,1,1e200]]*3", np.array([[1, 1, 1, 1e200]] * 3, dtype=float)),
]
OVERFLOW_IDS = [c[0] for c in OVERFLOW_CASES]


@pytest.mark.parametrize("method", [*PERMANENT_METHODS, "glynn", "ryser"])
@pytest.mark.parametrize("case", OVERFLOW_CASES, ids=OVERFLOW_IDS)
def test_permanent_overflow_contract(case, method):
    _, A = case
    check_permanent(A, method)


@pytest.mark.parametrize("method", ["dp", "multiset", "auto", "reference"])
def test_compressed_overflow_contract(method):
    # [[1e200]] with 2 rows × 2 columns: Per = 2·1e400 (overflows)
    check_permanent([[1e200]], method, [2], [2])
    # [[1e-200, 1]] with 2 rows × (2 + 1) columns: dominated by 2·1e-200 ≈ representable
    check_permanent([[1e-200, 1.0]], method, [2], [2, 1])
    # [[1e-200]] with 2 rows × 2 columns: 2·1e-400 underflows
    check_permanent([[1e-200]], method, [2], [2])


@pytest.mark.parametrize("rows", [1, 2, 5])
def test_no_columns_is_the_product_of_the_null_weights(rows):
    # zero columns used to reach uninitialised memory in the frontier plan (an
    # intermittent segfault); run it several times to make a recurrence likely to show
    null = np.linspace(0.2, 0.9, rows)
    for _ in range(20):
        r = assignment_sum(np.zeros((rows, 0)), null, marginals=False)
        assert r.log_normalizer == pytest.approx(np.log(null).sum(), rel=1e-15)
    r = assignment_sum(np.zeros((rows, 0)), null)
    assert r.beta.tolist() == [[1.0]] * rows
    assert assignment_sum(np.zeros((rows, 0)), 0.0, marginals=False).log_normalizer == -np.inf
    with pytest.raises(InfeasibleAssignmentError):
        assignment_sum(np.zeros((rows, 0)), 0.0)
