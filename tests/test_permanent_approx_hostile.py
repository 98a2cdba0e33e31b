"""Approximate permanents and Sinkhorn on hostile input: any dynamic range, bad arguments.

Ground truth: the exact ``log_permanent`` of the assignment-sum core (robust over
any dynamic range).
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from jointtrack.assignment import sinkhorn
from jointtrack.errors import InfeasibleAssignmentError
from jointtrack.permanent import log_permanent, permanent
from jointtrack.permanent.bethe import bethe_permanent
from jointtrack.permanent.sampling import sample_permanent

# rank-one 4×5, columns spanning 10^-50 … 10^200
RANK_ONE = np.outer([1.0, 2, 3, 4], 10.0 ** np.array([0, 0, -50, 200, 100]))

# found by fuzzing rank-one × 10^U(−150, 150) with zeros: the old Bethe code returned
# log perB = 1139.5 > log Per = 628.8 with a column sum of 1.2
_E6 = [
    [11.7, 0.0, 93.4, -150.6, 105.8, -141.3, 67.5],
    [11.3, 128.7, 93.0, -151.0, 0.0, 0.0, 67.1],
    [13.0, 130.4, 94.7, -149.3, 107.1, -140.0, 68.8],
    [13.0, 0.0, 0.0, -149.2, 107.2, -140.0, 68.9],
    [12.9, 130.3, 0.0, -149.4, 107.0, -140.1, 0.0],
    [13.0, 130.4, 0.0, -149.3, 107.1, -140.1, 68.8],
]
_S6 = [
    [1, 0, 1, 1, 1, 1, 1],
    [1, 1, 1, 1, 0, 0, 1],
    [1, 1, 1, 1, 1, 1, 1],
    [1, 0, 0, 1, 1, 1, 1],
    [1, 1, 0, 1, 1, 1, 0],
    [1, 1, 0, 1, 1, 1, 1],
]
WIDE_6x7 = 10.0 ** np.array(_E6) * np.array(_S6)

# found the same way: the old sampler returned log 2.5e-7 = −15.2 with rel_stderr 0
# for log Per = 289.0 (off by e^304)
WIDE_3x4 = 10.0 ** np.array(
    [[127.4, -111.3, 0.0, -4.9], [-139.7, -133.0, 0.0, 105.5], [131.3, 0.0, 0.0, -115.0]]
) * np.array([[1, 1, 0, 1], [1, 1, 0, 1], [1, 0, 0, 1]])


def _assert_feasible_beliefs(A, G):
    n, m = A.shape
    assert np.all(np.isfinite(G)) and np.all(G >= 0)
    assert np.all(G[A == 0] == 0)
    assert np.all(G.sum(axis=1) <= 1 + 1e-12) and np.all(G.sum(axis=1) >= 1 - 1e-12)
    assert np.all(G.sum(axis=0) <= 1 + 1e-12)
    if n == m:
        np.testing.assert_allclose(G.sum(axis=0), 1.0, atol=1e-12)


def _le(a: float, b: float) -> bool:
    """a ≤ b up to a relative 1e-9 of the values (perB ≤ Per·(1 + 1e-9))."""
    return a <= b + 1e-9 * (1.0 + abs(b))


# ----------------------------------------------------------------------------------------
# Bethe
# ----------------------------------------------------------------------------------------


@pytest.mark.parametrize("A", [RANK_ONE, WIDE_6x7, WIDE_3x4], ids=["rank1", "6x7", "3x4"])
def test_bethe_wide_range_is_feasible_lower_bound(A):
    exact = log_permanent(A)
    r = bethe_permanent(A)
    _assert_feasible_beliefs(A, r.marginals)
    assert math.isfinite(r.log_value)
    assert _le(r.log_value, exact)
    # and not absurdly low: at least the best single assignment
    assert r.log_value >= exact - A.shape[0] * math.log(A.shape[1]) - 1e-9


def test_bethe_rank_one_example_value():
    assert math.log(permanent(RANK_ONE)) == pytest.approx(697.1316355589, abs=1e-9)
    r = bethe_permanent(RANK_ONE)
    assert r.converged
    assert 690.0 < r.log_value <= 697.1316355589
    assert r.marginals.sum(axis=0).max() <= 1 + 1e-12


def test_bethe_nearly_decomposable_square_block_converges():
    """One dominant entry: the projection must not stall (it used to fall short)."""
    A = np.full((5, 5), 0.0625)
    A[0, 0] = 943.0
    r = bethe_permanent(A)
    assert r.converged
    _assert_feasible_beliefs(A, r.marginals)
    lp = log_permanent(A)
    assert _le(r.log_value, lp) and lp <= r.log_value + 2.5 * math.log(2) + 1e-9


# ----------------------------------------------------------------------------------------
# importance sampling
# ----------------------------------------------------------------------------------------


def _consistent(res, exact: float, k: float = 6.0) -> bool:
    """Within k reported standard errors of the exact value, or honestly unconverged.

    Slack 10/N: a share p of the mass that the proposal reaches with probability
    ~p stays unseen in all N samples with probability (1 − p)^N, e^−10 at p = 10/N;
    no sample-based error estimate can see it. An error of e^210 is far outside.
    """
    if not res.converged:
        return True
    err = abs(math.expm1(exact - res.log_value))  # |Per/est − 1|
    return err <= k * res.rel_stderr + 10.0 / res.n_samples


@pytest.mark.parametrize("A", [RANK_ONE, WIDE_6x7, WIDE_3x4], ids=["rank1", "6x7", "3x4"])
def test_sampling_wide_range_regressions(A):
    exact = log_permanent(A)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        res = sample_permanent(A, 2_000, rng=0)
    assert math.isfinite(res.log_value)
    assert _consistent(res, exact), (res, exact)
    assert res.converged  # these are easy once the proposal is scaled
    assert abs(res.log_value - exact) < 0.05


def test_sampling_fuzz_rank_one_times_wide_range():
    rng = np.random.default_rng(2025)
    for _ in range(60):
        n = int(rng.integers(2, 8))
        m = n + int(rng.integers(0, 3))
        A = np.outer(rng.random(n), 10.0 ** rng.uniform(-150, 150, m))
        A *= rng.random((n, m)) < 0.7
        exact = log_permanent(A)
        if not math.isfinite(exact):
            continue
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            res = sample_permanent(A, 500, rng=1)
        assert math.isfinite(res.log_value)
        assert _consistent(res, exact), (A, res, exact)


def test_sampling_reports_non_convergence():
    """A proposal that cannot see the mass: tiny effective sample size → warned, flagged."""
    # one row whose mass sits on an entry it rarely reaches given the others' choices
    rng = np.random.default_rng(3)
    A = rng.random((8, 8)) ** 40
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = sample_permanent(A, 20, rng=0)
    assert res.effective_sample_size <= res.n_samples + 1e-9
    if not res.converged:
        assert any("effective sample size" in str(w.message) for w in caught)
    ok = sample_permanent(np.ones((4, 4)), 100, rng=0)
    assert ok.converged and ok.effective_sample_size == pytest.approx(100.0)


# ----------------------------------------------------------------------------------------
# Sinkhorn
# ----------------------------------------------------------------------------------------


def test_sinkhorn_newton_on_nearly_decomposable():
    A = np.array([[1e8, 1.0], [1.0, 1.0]])
    # within 100 iterations (the work bound; plain Sinkhorn needs ~1e8 on this matrix)
    d1, B, d2 = sinkhorn(A, max_iter=100)
    np.testing.assert_allclose(B.sum(0), 1, atol=1e-12)
    np.testing.assert_allclose(B.sum(1), 1, atol=1e-12)
    np.testing.assert_allclose(B, d1[:, None] * A * d2[None, :], rtol=1e-12)
    assert B[0, 1] == pytest.approx(1e-4, rel=1e-3)


def test_sinkhorn_extreme_ranges_give_finite_factors():
    for A in (
        [[1e300, 1e-320], [1e-320, 1e300]],
        [[1e-320, 1e-320], [1e-320, 1e300]],
        [[1e-320]],
        [[1e-300, 1.0, 1e300]],
    ):
        d1, B, d2 = sinkhorn(A)
        for d in (d1, d2):
            assert np.all(np.isfinite(d)) and np.all(d > 0)
        np.testing.assert_allclose(B.sum(1), 1, atol=1e-12)
    # column sums 1/3 need d2 to span 2e623: the exact factors exist but no float64
    # holds them; refused rather than returned as inf / 0
    with pytest.raises(ValueError, match="not representable"):
        sinkhorn([[5e-324, 1.0, 1e300]])


def test_sinkhorn_group_counts_newton():
    A = np.array([[1e6, 1.0], [1.0, 1.0]])
    d1, B, d2 = sinkhorn(A, row_counts=[2, 1], col_counts=[1, 2])
    # expanded sums: rows Σ_j b_j B_ij = 1, columns Σ_i a_i B_ij = 1
    np.testing.assert_allclose(B @ [1, 2], 1, atol=1e-12)
    np.testing.assert_allclose([2, 1] @ B, 1, atol=1e-12)


def test_sinkhorn_errors():
    with pytest.raises(ValueError, match="total support"):
        sinkhorn([[1.0, 1.0], [0.0, 1.0]])
    with pytest.raises(ValueError, match="total support"):
        sinkhorn([[1.0, 1.0, 0.0], [1.0, 1.0, 0.0]])  # a column no row can fill
    with pytest.raises(InfeasibleAssignmentError):
        sinkhorn([[1.0, 0.0], [1.0, 0.0]])


# ----------------------------------------------------------------------------------------
# argument checks
# ----------------------------------------------------------------------------------------

_BAD_MATRICES = [
    ([[1 + 1j, 1.0], [1.0, 1.0]], "complex"),
    ([[True, False], [False, True]], "boolean"),
    ([[10**400, 1], [1, 1]], "too large"),
]


@pytest.mark.parametrize("bad, message", _BAD_MATRICES)
def test_bad_matrices(bad, message):
    for fn in (bethe_permanent, sample_permanent, sinkhorn):
        with pytest.raises(ValueError, match=message):
            fn(bad)


@pytest.mark.parametrize("value", [math.inf, math.nan, 2.5, 0, True, "10"])
def test_bad_max_iter(value):
    for fn in (bethe_permanent, sinkhorn):
        with pytest.raises(ValueError, match="max_iter"):
            fn(np.ones((2, 2)), max_iter=value)


@pytest.mark.parametrize("value", [math.nan, 0.0, -1e-3, math.inf, True])
def test_bad_tol(value):
    for fn in (bethe_permanent, sinkhorn):
        with pytest.raises(ValueError, match="tol"):
            fn(np.ones((2, 2)), tol=value)


@pytest.mark.parametrize("value", [2.7, True, 0, 1, math.nan, "10", None])
def test_bad_n_samples(value):
    with pytest.raises(ValueError, match="n_samples"):
        sample_permanent(np.ones((2, 2)), value)


@pytest.mark.parametrize("value", ["abc", -1, 1.5])
def test_bad_rng(value):
    with pytest.raises(ValueError, match="rng"):
        sample_permanent(np.ones((2, 2)), 10, rng=value)


def test_bad_bethe_options():
    for kw, name in (({"damping": 1.0}, "damping"), ({"anderson": 1.5}, "anderson")):
        with pytest.raises(ValueError, match=name):
            bethe_permanent(np.ones((2, 2)), **kw)


# ----------------------------------------------------------------------------------------
# properties over the whole float range
# ----------------------------------------------------------------------------------------

_wide = st.one_of(
    st.just(0.0),
    st.floats(1e-320, 1e300, allow_nan=False, allow_infinity=False, allow_subnormal=True),
)
_positive = st.floats(1e-320, 1e300, allow_nan=False, allow_infinity=False, allow_subnormal=True)


@st.composite
def _matrices(draw, elements, square=False):
    n = draw(st.integers(1, 6))
    m = n if square else draw(st.integers(n, 6))
    return draw(arrays(np.float64, (n, m), elements=elements))


_prop = settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])


@_prop
@given(_matrices(_wide))
def test_property_bethe_feasible_and_below_permanent(A):
    exact = log_permanent(A)
    if exact == -math.inf:
        with pytest.raises(InfeasibleAssignmentError):
            bethe_permanent(A)
        return
    r = bethe_permanent(A)
    assert not math.isnan(r.log_value) and math.isfinite(r.log_value)
    _assert_feasible_beliefs(A, r.marginals)
    assert _le(r.log_value, exact), (r.log_value, exact)


@_prop
@given(_matrices(_positive))
def test_property_sinkhorn_positive(A):
    tol = 1e-10
    try:
        d1, B, d2 = sinkhorn(A, tol=tol)
    except ValueError as exc:
        # honest refusal: the exact factors exist but span more than float64's range
        assert "not representable" in str(exc)
        return
    n, m = A.shape
    for d in (d1, d2):
        assert np.all(np.isfinite(d)) and np.all(d > 0)
    assert np.all(np.isfinite(B))
    assert np.max(np.abs(B.sum(1) - 1)) <= 2 * tol
    assert np.max(np.abs(B.sum(0) / (n / m) - 1)) <= 2 * tol


@_prop
@given(_matrices(_wide))
def test_property_sampling_log_estimate_finite(A):
    exact = log_permanent(A)
    if exact == -math.inf:
        with pytest.raises(InfeasibleAssignmentError):
            sample_permanent(A, 50, rng=0)
        return
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        res = sample_permanent(A, 200, rng=0)
    assert not math.isnan(res.log_value) and math.isfinite(res.log_value)
    assert not math.isnan(res.rel_stderr) and res.rel_stderr >= 0
    assert 0 < res.effective_sample_size <= res.n_samples * (1 + 1e-12)
