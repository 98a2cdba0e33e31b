"""Association methods on hostile clusters: any dynamic range, subnormal and zero weights.

Every method must work on every feasible cluster, whatever the scale of ``L``
(up to ~1e300) and ``miss`` (0, subnormal, 1e-300 … 1): ``enumerate`` and
exhaustive ``kbest`` exactly (against ``exact``), ``lbp`` and ``mcmc`` with
finite beta whose rows sum to 1 (``lbp`` exactly on trees).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from jointtrack.assignment import is_feasible
from jointtrack.association import count_hypotheses, enumerate_jpda, marginals
from jointtrack.association.kbest import kbest_hypotheses, kbest_marginals
from jointtrack.association.lbp import lbp_marginals
from jointtrack.association.mcmc import mcmc_marginals
from jointtrack.errors import InfeasibleAssignmentError

SUBNORMAL = 5e-324

# ------------------------------------------------------------------ strategies

l_entry = st.one_of(
    st.just(0.0),
    st.floats(min_value=1e-320, max_value=1e300, allow_nan=False, allow_infinity=False),
    st.sampled_from([1e-300, 1e300, 1.0, 2.5e299, SUBNORMAL]),
)
miss_entry = st.one_of(
    st.just(0.0),
    st.just(SUBNORMAL),
    st.floats(min_value=1e-300, max_value=1.0),
    st.sampled_from([1e-300, 1.0, 0.5]),
)


@st.composite
def clusters(draw, n_max=4, m_max=4):
    n = draw(st.integers(1, n_max))
    m = draw(st.integers(0, m_max))
    L = np.array(draw(st.lists(l_entry, min_size=n * m, max_size=n * m)), float).reshape(n, m)
    miss = np.array(draw(st.lists(miss_entry, min_size=n, max_size=n)), float)
    return L, miss


HOSTILE = settings(
    max_examples=150, deadline=None, suppress_health_check=[HealthCheck.filter_too_much]
)


def check_layout(beta, L, atol=1e-12):
    n, m = L.shape
    assert beta.shape == (n, m + 1)
    assert not np.isnan(beta).any()
    assert np.all(np.isfinite(beta)) and np.all(beta >= 0) and np.all(beta <= 1 + 1e-15)
    np.testing.assert_allclose(beta.sum(axis=1), 1.0, rtol=0, atol=atol)
    assert np.all(beta[:, 1:][L == 0] == 0)


def is_forest(L) -> bool:
    """True when the bipartite gating graph of ``L`` has no cycle."""
    n, m = L.shape
    r, c = np.nonzero(L > 0)
    g = coo_matrix((np.ones(r.size), (r, n + c)), shape=(n + m, n + m))
    k, _ = connected_components(g, directed=False)
    return r.size == n + m - k


# ------------------------------------------------------------- property tests


@HOSTILE
@given(cl=clusters())
def test_enumerate_matches_exact_on_any_feasible_cluster(cl):
    L, miss = cl
    if not is_feasible(L, miss):
        with pytest.raises(InfeasibleAssignmentError):
            marginals(L, miss, method="enumerate")
        return
    exact = marginals(L, miss, method="exact")
    for naive in (False, True):
        res = enumerate_jpda(L, miss, naive=naive)
        check_layout(res.beta, L)
        np.testing.assert_allclose(res.beta, exact, rtol=0, atol=1e-12)
        assert math.isfinite(res.log_normalizer)


@HOSTILE
@given(cl=clusters())
def test_kbest_exhaustive_matches_exact_on_any_feasible_cluster(cl):
    L, miss = cl
    if not is_feasible(L, miss):
        with pytest.raises(InfeasibleAssignmentError):
            kbest_marginals(L, miss, k=5)
        return
    n_events = int(count_hypotheses(L, miss))
    hyp = kbest_hypotheses(L, miss, k=n_events + 1)
    assert hyp.exhausted and len(hyp.log_weights) == n_events
    assert np.all(np.isfinite(hyp.log_weights))
    beta = kbest_marginals(L, miss, k=n_events)
    check_layout(beta, L)
    np.testing.assert_allclose(beta, marginals(L, miss, method="exact"), rtol=0, atol=1e-12)


@HOSTILE
@given(cl=clusters())
def test_lbp_finite_on_any_feasible_cluster_and_exact_on_trees(cl):
    L, miss = cl
    if not is_feasible(L, miss):
        with pytest.raises(InfeasibleAssignmentError):
            lbp_marginals(L, miss)
        return
    beta, info = lbp_marginals(L, miss, tol=1e-13)
    check_layout(beta, L)
    if L.shape[0] == 1 or is_forest(L):
        # belief propagation is exact on a cycle-free gating graph
        assert info.converged
        np.testing.assert_allclose(beta, marginals(L, miss, method="exact"), rtol=0, atol=1e-12)


@settings(max_examples=100, deadline=None)
@given(cl=clusters(), seed=st.integers(0, 2**32 - 1))
def test_mcmc_finite_on_any_feasible_cluster(cl, seed):
    L, miss = cl
    if not is_feasible(L, miss):
        with pytest.raises(InfeasibleAssignmentError):
            mcmc_marginals(L, miss, n_samples=100, rng=seed)
        return
    beta = mcmc_marginals(L, miss, n_samples=2_000, rng=seed)
    check_layout(beta, L)
    # a track whose every event takes the same option is sampled exactly
    exact = marginals(L, miss, method="exact")
    certain = np.isclose(exact.max(axis=1), 1.0, rtol=0, atol=1e-300)
    np.testing.assert_array_equal(beta[certain], np.round(exact[certain]))


@HOSTILE
@given(cl=clusters())
def test_pda_finite_on_any_valid_cluster(cl):
    L, miss = cl
    if ((miss == 0) & ~(L > 0).any(axis=1)).any():
        return  # a certainly detected track with nothing in its gate
    beta = marginals(L, miss, method="pda")
    check_layout(beta, L)


# --------------------------------------------------------- regression examples

ALT = [[0.0, 1.0], [1.0, 0.0], [0.0, 1.0], [1.0, 0.0]]
ALT_BETA = [[0.5, 0.0, 0.5], [0.5, 0.5, 0.0], [0.5, 0.0, 0.5], [0.5, 0.5, 0.0]]
SKEW = [[2.48196451438992, 0.0], [0.0, 10.0], [0.0, 1.0], [1.0, 0.0]]
# weights ∝ 1e-600 × {a·10, a·1, 1·10, 1·1}, a = 2.48196451438992 (tracks 0,1 vs 3,2)
_a = 2.48196451438992
_p0 = _a / (_a + 1.0)  # track 0 takes measurement 0
_p1 = 10.0 / 11.0  # track 1 takes measurement 1
SKEW_BETA = [
    [1 - _p0, _p0, 0.0],
    [1 - _p1, 0.0, _p1],
    [_p1, 0.0, 1 - _p1],
    [_p0, 1 - _p0, 0.0],
]
SUB = [[1.0], [10.0]]
SUB_BETA = [[10 / 11, 1 / 11], [1 / 11, 10 / 11]]
HUGE = [[6.37e299], [2.70e299]]
HUGE_BETA = [[2.70 / 9.07, 6.37 / 9.07], [6.37 / 9.07, 2.70 / 9.07]]
CERTAIN = [[4.98e254], [5.71e207]]
CERTAIN_MISS = [0.0, 0.9145]
CERTAIN_BETA = [[0.0, 1.0], [1.0, 0.0]]


@pytest.mark.parametrize(
    "L, miss, expect",
    [
        (ALT, [1e-300] * 4, ALT_BETA),
        (SKEW, [1e-300] * 4, SKEW_BETA),
        (SUB, [SUBNORMAL, SUBNORMAL], SUB_BETA),
        (HUGE, [1e-300, 1e-300], HUGE_BETA),
        (CERTAIN, CERTAIN_MISS, CERTAIN_BETA),
    ],
)
def test_enumerate_and_kbest_regressions(L, miss, expect):
    # before: ALT gave all NaN, SKEW was 0.02 off, SUB raised InfeasibleAssignmentError
    np.testing.assert_allclose(marginals(L, miss, method="exact"), expect, rtol=0, atol=1e-14)
    for naive in (False, True):
        res = enumerate_jpda(L, miss, naive=naive)
        np.testing.assert_allclose(res.beta, expect, rtol=0, atol=1e-14)
    np.testing.assert_allclose(marginals(L, miss, method="kbest"), expect, rtol=0, atol=1e-14)


def test_enumerate_counters_unchanged_on_hostile_scales():
    # 4 tracks, 2 measurements, a 4-cycle-free pattern: each track has 2 options
    res = enumerate_jpda(ALT, [1e-300] * 4)
    assert res.n_hypotheses == 9  # (1 + 2)² combinations of the two measurement pairs
    assert list(res.group_sizes) == [2, 2, 2, 2]
    naive = enumerate_jpda(ALT, [1e-300] * 4, naive=True)
    assert naive.n_multiplications == 3 * 9
    assert res.n_multiplications < naive.n_multiplications
    # log Z = log(4 · 1e-600): exact in split floats although Z itself underflows
    assert res.log_normalizer == pytest.approx(math.log(4.0) - 600 * math.log(10.0), rel=1e-14)


def test_lbp_regression_huge_ratios_against_tiny_miss():
    # before: "belief propagation degenerated" (row scaling underflowed miss to 0)
    beta, info = lbp_marginals(HUGE, [1e-300, 1e-300])
    np.testing.assert_allclose(beta, HUGE_BETA, rtol=0, atol=1e-14)  # a tree: exact
    assert info.converged
    beta = marginals(CERTAIN, CERTAIN_MISS, method="lbp")
    np.testing.assert_allclose(beta, CERTAIN_BETA, rtol=0, atol=1e-14)


def test_mcmc_regressions():
    # before: [[1, 0], [0, 1]] (chain stuck: the miss weights underflowed)
    beta = marginals(HUGE, [1e-300, 1e-300], method="mcmc", n_samples=20_000, rng=0)
    np.testing.assert_allclose(beta, HUGE_BETA, rtol=0, atol=0.03)
    # before: ValueError "no recorded MCMC step" (ε of the certain track was negligible)
    beta = marginals(CERTAIN, CERTAIN_MISS, method="mcmc", n_samples=3000)
    np.testing.assert_array_equal(beta, CERTAIN_BETA)
    for seed in range(5):
        beta = marginals(CERTAIN, CERTAIN_MISS, method="mcmc", n_samples=3000, rng=seed)
        np.testing.assert_array_equal(beta, CERTAIN_BETA)


def test_general_unused_weights_mcmc_matches_exact_on_a_loopy_cluster():
    # dense 3×3 with a huge dynamic range: the scaled chain must still target π
    L = np.array([[3e250, 1e249, 0.0], [2e250, 5e250, 1e-10], [0.0, 4e249, 7e250]])
    miss = np.array([1e-200, 0.5, 1e-300])
    exact = marginals(L, miss, method="exact")
    beta = marginals(L, miss, method="mcmc", n_samples=200_000, rng=1)
    assert np.abs(beta - exact).max() < 0.02
    lbp = marginals(L, miss, method="lbp")
    check_layout(lbp, L)
    assert np.abs(lbp - exact).max() < 0.1


# ----------------------------------------------------------------- argument checks


@pytest.mark.parametrize("bad", [None, 0, -3, 2.5, float("inf"), float("nan"), "5", True])
def test_kbest_rejects_bad_k(bad):
    with pytest.raises(ValueError, match=r"\bk\b"):
        kbest_marginals([[1.0]], [0.5], k=bad)
    with pytest.raises(ValueError, match=r"\bk\b"):
        marginals([[1.0]], [0.5], method="kbest", k=bad)


@pytest.mark.parametrize("bad", [float("inf"), float("nan"), 0, -1, 2.5, None, True, "10"])
def test_lbp_rejects_bad_max_iter(bad):
    with pytest.raises(ValueError, match="max_iter"):
        lbp_marginals([[1.0]], [0.5], max_iter=bad)


@pytest.mark.parametrize("bad", [float("nan"), -1e-9, 0.0, float("inf"), "1e-9", None, True])
def test_lbp_rejects_bad_tol(bad):
    with pytest.raises(ValueError, match="tol"):
        lbp_marginals([[1.0]], [0.5], tol=bad)


@pytest.mark.parametrize("bad", ["abc", -1, 1.5, [1, 2], object(), True])
def test_mcmc_rejects_bad_rng(bad):
    with pytest.raises(ValueError, match="rng"):
        mcmc_marginals([[1.0]], [0.5], n_samples=10, rng=bad)


@pytest.mark.parametrize("bad", [2.7, True, False, 0, None, float("nan"), "100"])
def test_mcmc_rejects_bad_n_samples(bad):
    with pytest.raises(ValueError, match="n_samples"):
        mcmc_marginals([[1.0]], [0.5], n_samples=bad, rng=0)


@pytest.mark.parametrize("bad", [-1, 1.5, True, float("inf")])
def test_mcmc_rejects_bad_burn_in(bad):
    with pytest.raises(ValueError, match="burn_in"):
        mcmc_marginals([[1.0]], [0.5], n_samples=10, burn_in=bad, rng=0)


METHODS = ["exact", "enumerate", "pda", "lbp", "mcmc", "kbest"]


@pytest.mark.parametrize("method", METHODS)
def test_every_method_rejects_complex_bool_and_huge_int_input(method):
    with pytest.raises(ValueError, match="L.*complex"):
        marginals([[1.0 + 1e-3j]], [0.5], method=method)
    with pytest.raises(ValueError, match="miss.*complex"):
        marginals([[1.0]], [0.5 + 0.1j], method=method)
    with pytest.raises(ValueError, match="miss.*complex"):
        marginals([[1.0]], np.array([0.5], complex), method=method)  # imaginary part 0
    with pytest.raises(ValueError, match="L.*too large"):
        marginals([[10**400]], [0.5], method=method)
    with pytest.raises(ValueError, match="L"):
        marginals([[2**1024]], [0.5], method=method)
    with pytest.raises(ValueError, match="L.*boolean"):
        marginals(np.array([[True]]), [0.5], method=method)
    with pytest.raises(ValueError, match="miss.*boolean"):
        marginals([[1.0]], np.array([True]), method=method)
    with pytest.raises(ValueError, match="miss"):
        marginals([[1.0]], [float("nan")], method=method)
    with pytest.raises(ValueError, match="L"):
        marginals([[float("inf")]], [0.5], method=method)
