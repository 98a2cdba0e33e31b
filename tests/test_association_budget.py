"""The one budget policy for a cluster's marginals (jointtrack.association.budget)."""

from __future__ import annotations

import numpy as np
import pytest

from jointtrack.association import exact_marginals
from jointtrack.association.budget import budgeted_marginals
from jointtrack.association.lbp import lbp_marginals


def _cluster(n=6, m=8, seed=0):
    rng = np.random.default_rng(seed)
    return rng.random((n, m)) * 5.0, np.full(n, 0.1)


def test_within_budget_is_exact():
    L, miss = _cluster()
    res = budgeted_marginals(L, miss)
    assert res.method == "exact" and res.reason == ""
    np.testing.assert_array_equal(res.beta, exact_marginals(L, miss))


def test_past_the_track_limit_or_the_state_budget_is_the_approximation():
    L, miss = _cluster()
    lbp, _ = lbp_marginals(L, miss)
    res = budgeted_marginals(L, miss, max_tracks=5)
    assert (res.method, res.reason) == ("lbp", "exact_max_tracks")
    np.testing.assert_array_equal(res.beta, lbp)
    res = budgeted_marginals(L, miss, exact_options={"max_bits": 3})
    assert res.method == "lbp" and res.reason.startswith("refused: ")
    assert "max_bits = 3" in res.reason
    np.testing.assert_array_equal(res.beta, lbp)


def test_mcmc_gets_the_generator_and_approximations_are_not_budgeted():
    L, miss = _cluster(4, 5)
    a = budgeted_marginals(
        L, miss, max_tracks=2, approximation="mcmc", rng=np.random.default_rng(1)
    )
    b = budgeted_marginals(
        L, miss, max_tracks=2, approximation="mcmc", rng=np.random.default_rng(1)
    )
    assert a.method == "mcmc"
    np.testing.assert_array_equal(a.beta, b.beta)
    res = budgeted_marginals(L, miss, method="lbp", max_tracks=1)
    assert (res.method, res.reason) == ("lbp", "")


@pytest.mark.parametrize(
    "kwargs",
    [
        {"max_tracks": 5},  # past the track limit
        {"exact_options": {"max_bits": 3}},  # refused by the exact engine
        {"method": "lbp"},  # the approximation asked for
    ],
)
def test_a_dense_approximation_past_max_work_goes_to_the_sparse_tiers(kwargs):
    L, miss = _cluster()  # 48 gated entries: 1,000 dense sweeps could take 48,000 updates
    dense = budgeted_marginals(L, miss, max_work=48_000, **kwargs)
    assert dense.method == "lbp"
    res = budgeted_marginals(L, miss, max_work=47_999, **kwargs)
    assert res.method == "lbp-sparse" and res.reason.startswith("dense_budget: ")
    assert "48 gated pairs" in res.reason and "47999 message updates" in res.reason
    # the same Williams-Lau BP on the pairs: β equal where both converged
    np.testing.assert_allclose(res.beta, dense.beta, atol=1e-6)
    unbounded = budgeted_marginals(L, miss, max_work=None, **kwargs)
    np.testing.assert_array_equal(unbounded.beta, dense.beta)
    assert budgeted_marginals(L, miss, max_work=10).method == "exact"  # exact: own budget


def test_bad_approximation_is_named():
    L, miss = _cluster(2, 2)
    with pytest.raises(ValueError, match="approximation"):
        budgeted_marginals(L, miss, approximation="exact")


def test_no_approximation_raises_past_the_budget():
    from jointtrack.errors import ExactLimitError

    L, miss = _cluster()
    with pytest.raises(ExactLimitError, match="max_tracks = 5"):
        budgeted_marginals(L, miss, max_tracks=5, approximation=None)
    with pytest.raises(ExactLimitError, match="max_bits"):
        budgeted_marginals(L, miss, exact_options={"max_bits": 3}, approximation=None)
    res = budgeted_marginals(L, miss, approximation=None)
    assert res.method == "exact"


def test_cluster_pair_marginals_equal_the_dense_exact_marginals():
    from jointtrack.association import exact_marginals
    from jointtrack.association.clustering import cluster_pair_marginals, clusters

    rng = np.random.default_rng(0)  # gating: clusters of 5, 1 and 1 tracks
    L = rng.random((7, 9)) * (rng.random((7, 9)) < 0.25)
    miss = rng.random(7) * 0.5 + 0.01
    rows, cols = np.nonzero(L)
    groups = clusters((7, 9, rows, cols))
    seen = []

    def solve(k, tr, ms, Lc, mc):
        seen.append(len(tr))
        return exact_marginals(Lc, mc)

    beta0, pair_beta = cluster_pair_marginals(groups, rows, cols, L[rows, cols], miss, solve)
    dense = exact_marginals(L, miss)
    np.testing.assert_allclose(beta0, dense[:, 0], rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(pair_beta, dense[rows, 1 + cols], rtol=1e-12, atol=1e-15)
    assert seen and all(n > 1 for n in seen)  # only multi-track clusters reach solve
    assert len(seen) < len(groups)  # and some tracks were alone (PDA)
