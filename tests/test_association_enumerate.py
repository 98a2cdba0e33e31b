"""Bojilov's hypothesis enumeration: counters, closed forms, Table 1 listing, limits."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from jointtrack.association import (
    InfeasibleAssignmentError,
    bojilov_multiplication_counts,
    count_hypotheses,
    enumerate_jpda,
    enumerate_marginals,
    exact_marginals,
    iter_hypotheses,
    marginals,
)


def full_gating_count(N, M):
    return sum(math.comb(N, k) * math.comb(M, k) * math.factorial(k) for k in range(min(N, M) + 1))


def grouped_cluster(groups, rng):
    """N targets whose gates hold disjoint measurements: group i has n_i = 1 + (#meas)
    options (Bojilov's section-3 setting, every combination feasible)."""
    N = len(groups)
    M = sum(g - 1 for g in groups)
    L = np.zeros((N, M))
    c = 0
    for i, g in enumerate(groups):
        L[i, c : c + g - 1] = rng.uniform(0.1, 2.0, g - 1)
        c += g - 1
    return L, rng.uniform(0.05, 0.9, N)


@pytest.mark.parametrize("N, M", [(1, 1), (1, 5), (3, 4), (4, 10), (5, 5), (6, 3), (2, 9)])
def test_hypothesis_counter_matches_closed_form_on_full_gating(N, M):
    rng = np.random.default_rng(N * 10 + M)
    L = rng.uniform(0.01, 3, (N, M))
    miss = rng.uniform(0.05, 1, N)
    expected = full_gating_count(N, M)
    for naive in (False, True):
        assert enumerate_jpda(L, miss, naive=naive).n_hypotheses == expected
    assert count_hypotheses(L, miss) == expected
    assert sum(1 for _ in iter_hypotheses(L, miss)) == expected


def test_count_hypotheses_on_big_clusters_without_enumerating():
    # 12 × 24 full gating: ~1e20 hypotheses, counted by the DP (enumerating them would
    # never finish, so an enumeration regression shows as a hung CI, not a wrong count)
    c = count_hypotheses(np.ones((12, 24)), np.ones(12))
    assert c == pytest.approx(full_gating_count(12, 24), rel=1e-12)


@pytest.mark.parametrize(
    "groups, ratio_paper",
    [([5, 5, 5, 5, 5], 3.2), ([3, 4, 5, 6, 7], 3.4), ([7, 3, 6, 4, 5], 3.4)],
)
def test_multiplication_counts_match_bojilov_formulas(groups, ratio_paper):
    rng = np.random.default_rng(0)
    L, miss = grouped_cluster(groups, rng)
    opt = enumerate_jpda(L, miss)
    naive = enumerate_jpda(L, miss, naive=True)
    M_formula, Mp_formula = bojilov_multiplication_counts(sorted(groups))
    assert opt.n_multiplications == Mp_formula
    assert naive.n_multiplications == M_formula
    assert opt.n_hypotheses == naive.n_hypotheses == math.prod(groups)
    # the paper's quoted reduction ratios (3.2 for N=n=5, 3.4 for groups 3..7)
    assert naive.n_multiplications / opt.n_multiplications == pytest.approx(ratio_paper, abs=0.05)
    # levels were taken by increasing group size
    assert list(opt.group_sizes) == sorted(groups)
    np.testing.assert_allclose(opt.beta, naive.beta, atol=1e-14)


def test_closed_forms_and_the_optimal_order():
    assert bojilov_multiplication_counts([5] * 5) == (5**5 * 4, 25 * (1 + 5 * (1 + 5 * (1 + 5))))
    assert bojilov_multiplication_counts([3, 4, 5, 6, 7]) == (10080, 2952)
    assert bojilov_multiplication_counts([4]) == (0, 0)
    assert bojilov_multiplication_counts([]) == (0, 0)
    # M' is smallest for increasing group sizes, as the paper states
    best = bojilov_multiplication_counts([3, 4, 5, 6, 7])[1]
    for perm in itertools.permutations([3, 4, 5, 6, 7]):
        assert bojilov_multiplication_counts(perm)[1] >= best
    # …and our ordering picks it: given order 7,6,5,4,3 costs more multiplications
    rng = np.random.default_rng(1)
    L, miss = grouped_cluster([7, 6, 5, 4, 3], rng)
    given = enumerate_jpda(L, miss, order="given")
    sorted_ = enumerate_jpda(L, miss)
    assert given.n_multiplications == bojilov_multiplication_counts([7, 6, 5, 4, 3])[1]
    assert sorted_.n_multiplications == best < given.n_multiplications
    np.testing.assert_allclose(given.beta, sorted_.beta, atol=1e-14)


def test_conflicts_prune_hypotheses_and_multiplications():
    # with shared measurements the counts fall below the all-feasible formulas
    rng = np.random.default_rng(2)
    L = rng.uniform(0.1, 2, (4, 5))
    miss = np.full(4, 0.3)
    r = enumerate_jpda(L, miss)
    rn = enumerate_jpda(L, miss, naive=True)
    M_all, Mp_all = bojilov_multiplication_counts([6] * 4)
    assert r.n_hypotheses == full_gating_count(4, 5) < 6**4
    assert rn.n_multiplications == r.n_hypotheses * 3 < M_all
    assert r.n_multiplications < Mp_all
    assert r.n_multiplications < rn.n_multiplications


def test_table1_listing_reproduced():
    # Table 1: target 1 gates {1,2,3}, target 2 {3,4,5}, target 3 {5,6}
    beta_ = 0.7  # clutter density β
    PD = 0.9
    g = {
        (1, 1): 0.3,
        (1, 2): 0.5,
        (1, 3): 0.2,
        (2, 3): 0.4,
        (2, 4): 0.1,
        (2, 5): 0.6,
        (3, 5): 0.25,
        (3, 6): 0.35,
    }
    L = np.zeros((3, 6))
    for (t, m), v in g.items():
        L[t - 1, m - 1] = PD * v / beta_
    miss = np.full(3, 1 - PD)
    hyps = list(iter_hypotheses(L, miss, order="given"))
    listing = [tuple(int(x) for x in a) for a, _ in hyps[:6]]
    assert listing == [(0, 0, 0), (0, 0, 5), (0, 0, 6), (0, 3, 0), (0, 3, 5), (0, 3, 6)]
    # probabilities ∝ the paper's bracketed products (times β^{N_M} = β^6, common)
    b1 = beta_ * (1 - PD)
    paper = [
        b1**3,
        b1**2 * PD * g[3, 5],
        b1**2 * PD * g[3, 6],
        b1 * PD * g[2, 3] * b1,
        b1 * PD * g[2, 3] * PD * g[3, 5],
        b1 * PD * g[2, 3] * PD * g[3, 6],
    ]
    ours = [p for _, p in hyps[:6]]
    np.testing.assert_allclose(np.array(ours) / ours[0], np.array(paper) / paper[0], rtol=1e-12)
    # every listed assignment is feasible, and there are no others
    for a, _ in hyps:
        used = [x for x in a if x]
        assert len(used) == len(set(used))
        for t, x in enumerate(a):
            assert x == 0 or (t + 1, int(x)) in g
    assert len(hyps) == count_hypotheses(L, miss)


def test_limit_is_checked_before_enumerating_and_names_exact():
    rng = np.random.default_rng(3)
    L = 5 * rng.random((10, 20))
    miss = np.full(10, 0.1)
    with pytest.raises(ValueError, match="method='exact'"):
        enumerate_jpda(L, miss)
    with pytest.raises(ValueError, match="max_hypotheses"):
        marginals(L, miss, method="enumerate")
    with pytest.raises(ValueError, match="exact"):
        next(iter_hypotheses(L, miss))
    # a cluster too big even for an exact count is refused from a cheap lower bound
    with pytest.raises(ValueError, match="at least 2"):
        enumerate_jpda(np.ones((24, 48)), np.full(24, 0.1))
    # a small limit is honoured too, and None disables the check
    small_L = rng.random((3, 3))
    with pytest.raises(ValueError):
        enumerate_jpda(small_L, np.full(3, 0.5), max_hypotheses=10)
    r = enumerate_jpda(small_L, np.full(3, 0.5), max_hypotheses=None)
    assert r.n_hypotheses == full_gating_count(3, 3)


def test_zero_probability_options_are_not_hypotheses():
    # a certainly detected track (miss = 0) has no "0" option
    L = np.array([[1.0, 2.0, 0.0], [0.5, 0.0, 1.5]])
    miss = np.array([0.0, 0.4])
    r = enumerate_jpda(L, miss)
    assert list(r.group_sizes) == [2, 3]
    # track 0 takes m0 or m1; track 1 takes nothing, m0 or m2, no clash: 2*3 - 1
    assert r.n_hypotheses == 5
    assert r.beta[0, 0] == 0.0
    np.testing.assert_allclose(r.beta, exact_marginals(L, miss), atol=1e-14)


def test_empty_and_degenerate_clusters():
    r = enumerate_jpda(np.zeros((0, 4)), np.zeros(0))
    assert r.n_hypotheses == 1 and r.beta.shape == (0, 5)
    r = enumerate_jpda(np.zeros((3, 0)), np.full(3, 0.2), naive=True)
    assert r.n_hypotheses == 1 and r.n_multiplications == 2
    np.testing.assert_array_equal(r.beta, np.ones((3, 1)))
    assert list(iter_hypotheses(np.zeros((2, 0)), [0.5, 0.5]))[0][1] == pytest.approx(1.0)
    assert count_hypotheses(np.zeros((0, 0)), np.zeros(0)) == 1
    with pytest.raises(InfeasibleAssignmentError):
        enumerate_jpda(np.array([[1.0], [1.0]]), [0.0, 0.0])
    assert count_hypotheses(np.array([[1.0], [1.0]]), [0.0, 0.0]) == 0


def test_stats_flag_and_order_validation():
    L = np.array([[1.0, 0.5], [0.2, 3.0]])
    miss = np.array([0.3, 0.6])
    res = enumerate_marginals(L, miss, stats=True)
    # 3 × 3 combinations minus the two that reuse a measurement; with two levels
    # every feasible hypothesis costs exactly one multiplication
    assert res.n_hypotheses == 7 and res.n_multiplications == 7
    assert res.n_additions == 7 * 3
    np.testing.assert_allclose(enumerate_marginals(L, miss), res.beta)
    with pytest.raises(ValueError, match="order"):
        enumerate_jpda(L, miss, order="random")


def test_extreme_scales_enumerate_without_overflow():
    rng = np.random.default_rng(9)
    for scale in (1e-250, 1e250):
        L = scale * rng.uniform(0.1, 1, (6, 3))  # N > M: ≥ 3 misses per hypothesis
        miss = rng.uniform(0.1, 1, 6)
        for naive in (False, True):
            r = enumerate_jpda(L, miss, naive=naive)
            assert np.all(np.isfinite(r.beta))
            np.testing.assert_allclose(r.beta, exact_marginals(L, miss), atol=1e-12)


def test_enumerate_and_kbest_use_the_package_assignment_solver(monkeypatch):
    import scipy.optimize

    from jointtrack.association import kbest

    def forbidden(*args, **kwargs):
        raise AssertionError("scipy's linear_sum_assignment must not be used")

    monkeypatch.setattr(scipy.optimize, "linear_sum_assignment", forbidden)
    assert not hasattr(kbest, "linear_sum_assignment")
    L = np.array([[1.0, 2.0], [0.5, 3.0]])
    miss = np.array([0.2, 0.4])
    np.testing.assert_allclose(enumerate_jpda(L, miss).beta, exact_marginals(L, miss), atol=1e-14)
    np.testing.assert_allclose(
        marginals(L, miss, method="kbest", k=50), exact_marginals(L, miss), atol=1e-14
    )


@pytest.mark.parametrize(
    "L, miss, expect",
    [
        # all NaN before (a partial product overflowed: 2^996 · 2^996)
        (
            [[0, 1], [1, 0], [0, 1], [1, 0]],
            [1e-300] * 4,
            [[0.5, 0, 0.5], [0.5, 0.5, 0], [0.5, 0, 0.5], [0.5, 0.5, 0]],
        ),
        # 0.02 off before (a partial product of two miss weights underflowed)
        (
            [[2.48196451438992, 0], [0, 10], [0, 1], [1, 0]],
            [1e-300] * 4,
            [
                [1 / 3.48196451438992, 2.48196451438992 / 3.48196451438992, 0],
                [1 / 11, 0, 10 / 11],
                [10 / 11, 0, 1 / 11],
                [2.48196451438992 / 3.48196451438992, 1 / 3.48196451438992, 0],
            ],
        ),
        # InfeasibleAssignmentError before (10 · 2^1074 overflowed to inf)
        ([[1.0], [10.0]], [5e-324, 5e-324], [[10 / 11, 1 / 11], [1 / 11, 10 / 11]]),
    ],
)
def test_enumerate_split_float_regressions(L, miss, expect):
    for naive in (False, True):
        r = enumerate_jpda(L, miss, naive=naive)
        assert np.all(np.isfinite(r.beta))
        np.testing.assert_allclose(r.beta, expect, rtol=0, atol=1e-14)
        np.testing.assert_allclose(r.beta, exact_marginals(L, miss), rtol=0, atol=1e-14)
        assert np.isfinite(r.log_normalizer)
    # the counters do not depend on the scale of the weights
    L1 = (np.asarray(L) > 0).astype(float)
    ref = enumerate_jpda(L1, np.full(len(miss), 0.5))
    r = enumerate_jpda(L, miss)
    assert (r.n_hypotheses, r.n_multiplications) == (ref.n_hypotheses, ref.n_multiplications)


def test_enumerate_log_normalizer_beyond_float_range():
    # Z far above the float64 range: kept in split floats
    L = np.diag([1e300, 1e300, 1e300, 1e300])
    miss = np.full(4, 1e-300)
    r = enumerate_jpda(L, miss)
    # Z = Π (1e300 + 1e-300) ≈ 1e1200
    assert r.log_normalizer == pytest.approx(1200 * math.log(10.0), rel=1e-14)
    np.testing.assert_array_equal(r.beta, np.hstack([np.zeros((4, 1)), np.eye(4)]))
