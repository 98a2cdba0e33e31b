"""Approximate JPDA marginals: loopy BP, MCMCDA and k-best (Murty) against brute force."""

from __future__ import annotations

import functools
import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from jointtrack.association.kbest import kbest_hypotheses, kbest_marginals
from jointtrack.association.lbp import lbp_marginals
from jointtrack.association.mcmc import mcmc_marginals
from jointtrack.errors import InfeasibleAssignmentError

# ------------------------------------------------------------------ brute-force JPDA


@functools.cache
def _events(n: int, m: int) -> np.ndarray:
    """All joint events of n tracks and m measurements as (E, n) beta columns (0 = miss)."""
    out = [
        a
        for a in itertools.product(range(m + 1), repeat=n)
        if len([j for j in a if j]) == len({j for j in a if j})
    ]
    return np.array(out, dtype=np.int64).reshape(len(out), n)


def brute_events(L, miss):
    """(events, weights) of every joint event with positive weight (Bojilov eq. (5)–(7))."""
    L = np.asarray(L, float)
    miss = np.asarray(miss, float)
    n, m = L.shape
    ev = _events(n, m)
    ext = np.concatenate([miss[:, None], L], axis=1)
    w = ext[np.arange(n), ev].prod(axis=1) if n else np.ones(len(ev))
    keep = w > 0
    return ev[keep], w[keep]


def brute_marginals(L, miss):
    """Exact JPDA marginals by enumerating every feasible joint event."""
    n, m = np.shape(L)
    ev, w = brute_events(L, miss)
    beta = np.zeros((n, m + 1))
    for i in range(n):
        beta[i] = np.bincount(ev[:, i], weights=w, minlength=m + 1)
    return beta / w.sum()


def dense(seed, n, m):
    rng = np.random.default_rng(seed)
    return 5 * rng.random((n, m)), np.full(n, 0.1)


def random_cluster(seed, n_max=4, m_max=5, allow_certain=False):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, n_max + 1))
    m = int(rng.integers(0, m_max + 1))
    L = rng.exponential(2.0, (n, m)) * (rng.random((n, m)) < rng.uniform(0.2, 1.0))
    miss = rng.uniform(0.01, 1.0, n)
    if allow_certain:
        miss[rng.random(n) < 0.3] = 0.0
    return L, miss


def random_forest(seed):
    """A cluster whose bipartite gating graph has no cycles (BP is exact on it)."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 6))
    m = int(rng.integers(1, 7))
    nodes = [("t", i) for i in range(n)] + [("m", j) for j in range(m)]
    order = rng.permutation(len(nodes))
    placed = []
    L = np.zeros((n, m))
    for k in order:
        kind, idx = nodes[k]
        other = [p for p in placed if p[0] != kind]
        if other and rng.random() < 0.85:
            _, o = other[rng.integers(len(other))]
            i, j = (idx, o) if kind == "t" else (o, idx)
            L[i, j] = rng.exponential(3.0)
        placed.append(nodes[k])
    return L, rng.uniform(0.05, 1.0, n)


def check_layout(beta, L):
    n, m = np.shape(L)
    assert beta.shape == (n, m + 1)
    assert np.all(np.isfinite(beta)) and np.all(beta >= 0) and np.all(beta <= 1)
    np.testing.assert_allclose(beta.sum(axis=1), 1.0, rtol=0, atol=1e-12)
    assert np.all(beta[:, 1:][np.asarray(L) == 0] == 0)


def test_brute_force_reference_itself():
    # one track: PDA, β_0 ∝ miss, β_j ∝ L_j; two tracks one measurement by hand
    b = brute_marginals([[2.0, 1.0]], [0.5])
    np.testing.assert_allclose(b, [[0.5 / 3.5, 2 / 3.5, 1 / 3.5]])
    b = brute_marginals([[2.0], [3.0]], [0.5, 0.25])
    z = 0.5 * 0.25 + 2 * 0.25 + 0.5 * 3
    np.testing.assert_allclose(b, [[(0.125 + 1.5) / z, 0.5 / z], [(0.125 + 0.5) / z, 1.5 / z]])
    # hypothesis count on full gating: Σ_k C(N,k) C(M,k) k!
    assert len(_events(5, 10)) == sum(
        math.comb(5, k) * math.comb(10, k) * math.factorial(k) for k in range(6)
    )


# ------------------------------------------------------------------------------ LBP


def test_lbp_single_track_is_pda():
    L = np.array([[0.3, 0.0, 4.0, 1.2]])
    miss = np.array([0.2])
    beta, info = lbp_marginals(L, miss)
    expect = np.concatenate([miss, L[0]]) / (miss[0] + L.sum())
    np.testing.assert_allclose(beta[0], expect, rtol=1e-14)
    assert info.converged and info.certified and info.iterations <= 3


def test_lbp_exact_on_chain():
    # t0 — z0 — t1 — z1 — t2 — z2 — t3 : a path, no cycles
    L = np.array(
        [[2.0, 0, 0, 0], [1.5, 0.7, 0, 0], [0, 3.0, 0.4, 0], [0, 0, 2.2, 0.9]], dtype=float
    )
    miss = np.array([0.3, 0.1, 0.5, 0.05])
    beta, info = lbp_marginals(L, miss, tol=1e-13)
    assert info.converged and info.error_bound <= 1e-13
    np.testing.assert_allclose(beta, brute_marginals(L, miss), rtol=0, atol=1e-12)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_lbp_exact_on_forests(seed):
    L, miss = random_forest(seed)
    beta, info = lbp_marginals(L, miss, tol=1e-13)
    assert info.converged
    check_layout(beta, L)
    np.testing.assert_allclose(beta, brute_marginals(L, miss), rtol=0, atol=1e-11)


def test_lbp_dense_5x10_error_bound():
    """The accuracy stated in lbp_marginals' docstring: max error ≤ 0.03 on dense 5×10."""
    errs = []
    for seed in range(200):
        L, miss = dense(seed, 5, 10)
        beta, info = lbp_marginals(L, miss)
        assert info.converged and info.certified
        check_layout(beta, L)
        errs.append(np.abs(beta - brute_marginals(L, miss)).max())
    errs = np.array(errs)
    # measured: max 0.0093, median 0.0038
    assert errs.max() <= 0.03
    assert np.median(errs) <= 0.01
    assert errs.min() > 1e-4  # genuinely approximate on loopy graphs (the test can fail)


def test_lbp_certified_bound_holds():
    L, miss = dense(11, 8, 16)
    ref, rinfo = lbp_marginals(L, miss, tol=1e-14, max_iter=100_000)
    assert rinfo.converged
    for tol in (1e-1, 1e-3, 1e-6):
        beta, info = lbp_marginals(L, miss, tol=tol)
        assert info.converged and info.error_bound <= tol
        # message error ε ⇒ beliefs within e^{±2ε} of the fixed-point beliefs
        assert np.abs(np.log(beta) - np.log(ref)).max() <= 2 * info.error_bound + 1e-12
    # one sweep does not certify a dense cluster at 1e-9
    beta, info = lbp_marginals(L, miss, max_iter=1)
    assert not info.converged and info.iterations == 1 and info.error_bound > 1e-9
    check_layout(beta, L)


@settings(max_examples=80, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_lbp_layout_random_clusters(seed):
    L, miss = random_cluster(seed)
    beta, info = lbp_marginals(L, miss)
    check_layout(beta, L)
    assert info.converged and info.certified and info.error_bound <= 1e-9
    assert np.abs(beta - brute_marginals(L, miss)).max() < 0.25


def test_lbp_dense_20x40_converges():
    # speed against Stone Soup's JPDAwithLBP lives in benchmarks/ (no timed unit tests);
    # here: the canonical 20 x 40 cluster converges and its rows are distributions
    L, miss = dense(0, 20, 40)
    beta, info = lbp_marginals(L, miss)
    assert info.converged
    check_layout(beta, L)


def test_lbp_certain_tracks_and_edge_cases():
    L = np.array([[1.0, 2.0], [0.5, 0.0]])
    beta, info = lbp_marginals(L, [0.0, 0.3])
    assert not info.certified and info.error_bound == np.inf
    check_layout(beta, L)
    assert beta[0, 0] == 0.0
    np.testing.assert_allclose(beta, brute_marginals(L, [0.0, 0.3]), atol=1e-9)  # a tree
    with pytest.raises(InfeasibleAssignmentError):
        lbp_marginals([[1.0], [1.0]], [0.0, 0.0])
    with pytest.raises(InfeasibleAssignmentError):
        lbp_marginals([[0.0]], [0.0])
    b, _ = lbp_marginals(np.zeros((0, 3)), np.zeros(0))
    assert b.shape == (0, 4)
    b, _ = lbp_marginals(np.zeros((2, 0)), [0.5, 0.5])
    np.testing.assert_array_equal(b, [[1.0], [1.0]])
    with pytest.raises(ValueError, match="tol"):
        lbp_marginals([[1.0]], [0.5], tol=0)
    with pytest.raises(ValueError, match="max_iter"):
        lbp_marginals([[1.0]], [0.5], max_iter=0)
    with pytest.raises(ValueError):
        lbp_marginals([[-1.0]], [0.5])


# ----------------------------------------------------------------------------- MCMC


def test_mcmc_error_shrinks_with_samples():
    L, miss = dense(3, 5, 10)
    exact = brute_marginals(L, miss)
    e_small = [
        np.abs(mcmc_marginals(L, miss, n_samples=2_000, rng=s) - exact).max() for s in range(6)
    ]
    e_big = [
        np.abs(mcmc_marginals(L, miss, n_samples=200_000, rng=s) - exact).max() for s in range(6)
    ]
    # measured: mean 0.062 at 2k steps, 0.0067 at 200k (∝ n^{-1/2})
    assert np.mean(e_big) < np.mean(e_small) / 3
    assert max(e_big) < 0.03


@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_mcmc_random_sparse_clusters(seed):
    L, miss = random_cluster(seed, allow_certain=True)
    if brute_events(L, miss)[1].size == 0:
        with pytest.raises(InfeasibleAssignmentError):
            mcmc_marginals(L, miss, n_samples=100, rng=seed)
        return
    exact = brute_marginals(L, miss)
    beta = mcmc_marginals(L, miss, n_samples=200_000, rng=seed)
    check_layout(beta, L)
    # a handful of states; 200k correlated steps: |error| ≲ 0.01 typically
    assert np.abs(beta - exact).max() < 0.04


def test_mcmc_certain_tracks():
    L = np.array([[1.0, 2.0, 0.0], [0.5, 0.0, 1.0], [0.3, 0.7, 2.0]])
    miss = np.array([0.0, 0.2, 0.0])
    beta = mcmc_marginals(L, miss, n_samples=400_000, rng=5)
    check_layout(beta, L)
    assert beta[0, 0] == 0.0 and beta[2, 0] == 0.0
    assert np.abs(beta - brute_marginals(L, miss)).max() < 0.02


def test_mcmc_reproducible_and_seedable():
    L, miss = dense(1, 4, 6)
    a = mcmc_marginals(L, miss, n_samples=5_000, rng=42)
    b = mcmc_marginals(L, miss, n_samples=5_000, rng=np.random.default_rng(42))
    c = mcmc_marginals(L, miss, n_samples=5_000, rng=43)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)
    check_layout(a, L)
    mcmc_marginals(L, miss, n_samples=10)  # rng=None works


def test_mcmc_edge_cases():
    b = mcmc_marginals(np.zeros((0, 2)), np.zeros(0), rng=0)
    assert b.shape == (0, 3)
    b = mcmc_marginals(np.zeros((2, 3)), [0.5, 1.0], rng=0)
    np.testing.assert_array_equal(b[:, 0], 1.0)
    with pytest.raises(InfeasibleAssignmentError):
        mcmc_marginals([[1.0], [1.0]], [0.0, 0.0], rng=0)
    with pytest.raises(ValueError, match="n_samples"):
        mcmc_marginals([[1.0]], [0.5], n_samples=0)
    with pytest.raises(ValueError, match="burn_in"):
        mcmc_marginals([[1.0]], [0.5], burn_in=-1)


# --------------------------------------------------------------------------- k-best


@settings(max_examples=80, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_kbest_exhaustive_is_exact(seed):
    L, miss = random_cluster(seed, allow_certain=True)
    ev, w = brute_events(L, miss)
    if w.size == 0:
        with pytest.raises(InfeasibleAssignmentError):
            kbest_marginals(L, miss, k=10)
        return
    hyp = kbest_hypotheses(L, miss, k=len(w) + 5)
    assert hyp.exhausted and len(hyp.log_weights) == len(w)
    # distinct events, best first, weights equal to the enumerated ones
    assert len({tuple(a) for a in hyp.assignments}) == len(w)
    assert np.all(np.diff(hyp.log_weights) <= 0)
    np.testing.assert_allclose(np.sort(hyp.log_weights), np.sort(np.log(w)), rtol=0, atol=1e-12)
    beta = kbest_marginals(L, miss, k=len(w))
    check_layout(beta, L)
    np.testing.assert_allclose(beta, brute_marginals(L, miss), rtol=0, atol=1e-12)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), k=st.integers(1, 12))
def test_kbest_are_the_top_k(seed, k):
    L, miss = random_cluster(seed)
    ev, w = brute_events(L, miss)
    hyp = kbest_hypotheses(L, miss, k=k)
    kk = min(k, len(w))
    assert len(hyp.log_weights) == kk and hyp.exhausted == (len(w) < k)
    top = np.sort(np.log(w))[::-1][:kk]
    np.testing.assert_allclose(hyp.log_weights, top, rtol=0, atol=1e-12)
    # each reported event really has the reported weight
    with np.errstate(divide="ignore"):
        ext = np.log(np.concatenate([miss[:, None], L], axis=1))
    n = L.shape[0]
    recomputed = ext[np.arange(n), hyp.assignments].sum(axis=1)
    np.testing.assert_allclose(recomputed, hyp.log_weights, rtol=0, atol=1e-12)
    if k == 1:  # the MAP event
        np.testing.assert_array_equal(hyp.assignments[0], ev[np.argmax(w)])


def test_kbest_dense_error_decreases_with_k():
    errs = {k: [] for k in (10, 100, 1000)}
    for seed in range(6):
        L, miss = dense(seed, 5, 10)
        exact = brute_marginals(L, miss)
        for k in errs:
            beta = kbest_marginals(L, miss, k=k)
            check_layout(beta, L)
            errs[k].append(np.abs(beta - exact).max())
    mean = {k: float(np.mean(v)) for k, v in errs.items()}
    # measured over 20 clusters (docstring): mean 0.77 / 0.55 / 0.23, worst 0.84 / 0.74 / 0.34
    assert mean[10] > mean[100] > mean[1000]
    assert max(errs[1000]) < 0.4
    assert min(errs[10]) > 0.3  # truncation is crude on dense flat clusters


def test_kbest_edge_cases():
    hyp = kbest_hypotheses(np.zeros((0, 3)), np.zeros(0), k=3)
    assert hyp.assignments.shape == (1, 0)
    assert kbest_marginals(np.zeros((0, 3)), np.zeros(0)).shape == (0, 4)
    np.testing.assert_array_equal(kbest_marginals(np.zeros((2, 0)), [0.5, 0.5]), [[1.0], [1.0]])
    with pytest.raises(InfeasibleAssignmentError):
        kbest_marginals([[1.0], [1.0]], [0.0, 0.0])
    with pytest.raises(ValueError, match="k must"):
        kbest_marginals([[1.0]], [0.5], k=0)
    # a certainly detected track never misses
    b = kbest_marginals([[1.0, 3.0], [2.0, 0.0]], [0.0, 0.5], k=50)
    np.testing.assert_allclose(b, brute_marginals([[1.0, 3.0], [2.0, 0.0]], [0.0, 0.5]), atol=1e-14)
    assert b[0, 0] == 0.0


# ------------------------------------------- general unused weights (after scaling)


def test_mcmc_kernel_targets_the_general_unused_weights():
    """π(ω) ∝ Π W · Π miss · Π_{j unused} v_j: compare the chain with enumeration."""
    from jointtrack.association.mcmc import _mcmc_chunk

    rng = np.random.default_rng(5)
    W = rng.uniform(0.2, 1, (3, 3))
    miss = np.array([0.5, 0.3, 0.8])
    v = np.array([0.05, 1.0, 3.0])
    ev, w = brute_events(W, miss)
    used = np.zeros((len(ev), 3), bool)
    for h, a in enumerate(ev):
        used[h, a[a > 0] - 1] = True
    w = w * np.where(used, 1.0, v).prod(axis=1)
    expect = np.zeros((3, 4))
    for i in range(3):
        expect[i] = np.bincount(ev[:, i], weights=w, minlength=4)
    expect /= w.sum()
    ei, ej = np.nonzero(W > 0)
    at = np.full(3, -1, np.int64)
    am = np.full(3, -1, np.int64)
    counts = np.zeros((3, 4))
    state = np.zeros(2, np.int64)
    k = 400_000
    _mcmc_chunk(
        ei.astype(np.int64), ej.astype(np.int64), np.log(W), np.log(miss), np.log(v),
        np.zeros(3, bool), rng.integers(0, ei.size, k), np.log(rng.random(k)),
        at, am, counts, True, state,
    )  # fmt: skip
    beta = counts / counts.sum(axis=1, keepdims=True)
    assert np.abs(beta - expect).max() < 0.015


def test_mcmc_exchange_move_lets_certain_tracks_trade():
    # tracks 1 and 2 are certainly detected and compete for measurements 0 and 1;
    # every path through an event with one of them unmatched weighs ~1e-300 of the
    # modes, so without the exchange move the chain stays in its first mode
    # (measured: error 0.71 at 2·10^5 steps) — with it, ≈ 0.01 at 10^5
    from jointtrack.association import exact_marginals

    L = np.array(
        [
            [5.352e299, 3.449e16, 3.449e16, 5.992e16],
            [1e300, 6.082e298, 1.138e299, 0.0],
            [5.352e299, 5.992e16, 1.371e-104, 0.0],
        ]
    )
    miss = np.array([5e-324, 0.0, 0.0])
    beta = mcmc_marginals(L, miss, n_samples=100_000, rng=3)
    check_layout(beta, L)
    assert np.abs(beta - exact_marginals(L, miss)).max() < 0.03
