"""Exact JPDA marginals ("exact", "enumerate", "pda") against brute force and invariances."""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from jointtrack.association import (
    METHODS,
    InfeasibleAssignmentError,
    enumerate_jpda,
    exact_jpda,
    exact_marginals,
    iter_hypotheses,
    marginals,
    pda_marginals,
)

# ---------------------------------------------------------------------------
# references
# ---------------------------------------------------------------------------


def brute_jpda(L, miss, exact_arith=False):
    """JPDA by listing every feasible joint event (recursive, tracks in order).

    Returns (beta, Z). ``exact_arith`` uses Fractions (any scale, no rounding).
    Raises ZeroDivisionError when no event has positive weight.
    """
    L = np.asarray(L, dtype=float)
    miss = np.asarray(miss, dtype=float)
    N, M = L.shape
    conv = Fraction if exact_arith else float
    Lc = [[conv(float(x)) for x in row] for row in L]
    mc = [conv(float(x)) for x in miss]
    zero = conv(0)
    acc = [[zero] * (M + 1) for _ in range(N)]
    total = [zero]
    a = [0] * N
    used = [False] * M

    def rec(i, w):
        if w == 0:
            return
        if i == N:
            total[0] += w
            for t in range(N):
                acc[t][a[t]] += w
            return
        a[i] = 0
        rec(i + 1, w * mc[i])
        for j in range(M):
            if L[i, j] > 0 and not used[j]:
                used[j] = True
                a[i] = j + 1
                rec(i + 1, w * Lc[i][j])
                used[j] = False

    rec(0, conv(1))
    if total[0] == 0:
        raise ZeroDivisionError("no feasible joint event")
    beta = np.array([[float(x / total[0]) for x in row] for row in acc]).reshape(N, M + 1)
    return beta, total[0]


def numpy_subset_dp(L, miss):
    """Textbook subset DP (state = tracks used, one measurement per layer), vectorised
    with numpy: an independent implementation for clusters beyond brute force."""
    N, M = L.shape
    n = 1 << N
    S = np.arange(n)
    bits = [(S >> i) & 1 for i in range(N)]
    F = np.zeros((M + 1, n))
    F[0, 0] = 1.0
    for j in range(M):
        f = F[j].copy()
        for i in range(N):
            has = bits[i] == 1
            f[has] += L[i, j] * F[j][S[has] ^ (1 << i)]
        F[j + 1] = f
    V = np.ones(n)
    for i in range(N):
        V[bits[i] == 0] *= miss[i]
    Z = F[M] @ V
    beta = np.zeros((N, M + 1))
    for i in range(N):
        beta[i, 0] = F[M][bits[i] == 0] @ V[bits[i] == 0]
    B = V
    for j in range(M - 1, -1, -1):
        Bp = B.copy()
        for i in range(N):
            no = bits[i] == 0
            up = B[S[no] | (1 << i)]
            Bp[no] += L[i, j] * up
            beta[i, j + 1] = L[i, j] * (F[j][no] @ up)
        B = Bp
    return beta / Z, math.log(Z)


# ---------------------------------------------------------------------------
# random clusters
# ---------------------------------------------------------------------------


@st.composite
def clusters(draw, max_n=6, max_m=6):
    N = draw(st.integers(1, max_n))
    M = draw(st.integers(0, max_m))
    seed = draw(st.integers(0, 2**32 - 1))
    density = draw(st.sampled_from([0.0, 0.2, 0.5, 0.8, 1.0]))
    rng = np.random.default_rng(seed)
    L = rng.exponential(size=(N, M)) * (rng.random((N, M)) < density)
    if M and draw(st.booleans()):
        L[:, rng.integers(M)] = 0.0  # a measurement gated by no track
    if draw(st.booleans()):
        L[rng.integers(N), :] = 0.0  # a track with an empty gate
    miss = rng.uniform(0.01, 1.0, size=N)
    if draw(st.booleans()):
        miss[rng.integers(N)] = 0.0  # a certainly detected track
    return L, miss


EXACT_METHODS = ("exact", "enumerate")


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(clusters())
def test_exact_methods_match_brute_force(cluster):
    L, miss = cluster
    try:
        ref, Z = brute_jpda(L, miss)
    except ZeroDivisionError:
        for method in EXACT_METHODS:
            with pytest.raises(InfeasibleAssignmentError):
                marginals(L, miss, method=method)
        return
    for method in EXACT_METHODS:
        beta = marginals(L, miss, method=method)
        assert beta.shape == (L.shape[0], L.shape[1] + 1)
        np.testing.assert_allclose(beta, ref, rtol=0, atol=1e-12, err_msg=method)
    naive = enumerate_jpda(L, miss, naive=True).beta
    np.testing.assert_allclose(naive, ref, rtol=0, atol=1e-12)
    res = exact_jpda(L, miss)
    assert res.log_normalizer == pytest.approx(math.log(Z), abs=1e-12)
    assert enumerate_jpda(L, miss).log_normalizer == pytest.approx(math.log(Z), abs=1e-12)
    # the hypothesis iterator reproduces the marginals
    acc = np.zeros_like(ref)
    for a, p in iter_hypotheses(L, miss):
        acc[np.arange(L.shape[0]), a] += p
    np.testing.assert_allclose(acc, ref, rtol=0, atol=1e-12)


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(6, 8), st.integers(5, 9))
def test_exact_agrees_with_enumerate_1e12(seed, N, M):
    rng = np.random.default_rng(seed)
    L = 5 * rng.random((N, M)) * (rng.random((N, M)) < 0.55)
    miss = rng.uniform(0.05, 1, N)
    a = exact_marginals(L, miss)
    b = enumerate_jpda(L, miss, max_hypotheses=None).beta
    assert np.abs(a - b).max() <= 1e-12


@pytest.mark.parametrize(
    "N, M, density",
    [(12, 14, 1.0), (13, 9, 1.0), (8, 20, 1.0), (14, 18, 0.3), (15, 15, 0.2), (12, 30, 0.5)],
)
def test_exact_matches_textbook_dp_beyond_one_block(N, M, density):
    # K > 11 exercises the block-level (hi-bit) kernels; sparse cases the frontier
    # planner (items entering/leaving), leaf folding and component splitting
    rng = np.random.default_rng(N * 100 + M)
    L = 5 * rng.random((N, M)) * (rng.random((N, M)) < density)
    miss = rng.uniform(0.05, 1, N)
    ref, logz = numpy_subset_dp(L, miss)
    res = exact_jpda(L, miss)
    assert np.abs(res.beta - ref).max() <= 1e-12
    assert res.log_normalizer == pytest.approx(logz, abs=1e-11)


def test_checkpointing_and_threads_give_the_same_answer():
    rng = np.random.default_rng(7)
    L = 5 * rng.random((16, 20))
    miss = np.full(16, 0.1)
    full = exact_jpda(L, miss)
    assert full.max_frontier == 16
    ck = exact_jpda(L, miss, max_memory=14 * 8 * 2**16)  # forces recomputed segments
    assert ck.state_bytes < full.state_bytes
    np.testing.assert_allclose(ck.beta, full.beta, rtol=1e-13, atol=1e-15)
    par = exact_jpda(L, miss, parallel=True)
    np.testing.assert_allclose(par.beta, full.beta, rtol=1e-12, atol=1e-15)
    with pytest.raises(ValueError, match="max_memory"):
        exact_jpda(L, miss, max_memory=2 * 8 * 2**16)
    with pytest.raises(ValueError, match="lbp"):
        exact_jpda(L, miss, max_bits=12)


def test_sparse_structures_fold_or_stay_narrow():
    rng = np.random.default_rng(3)
    # a chain of 40 tracks, neighbours share one measurement: a tree, folded away
    N = 40
    L = np.zeros((N, 2 * N + 1))
    for i in range(N):
        L[i, 2 * i : 2 * i + 3] = rng.uniform(0.2, 3, 3)
    miss = rng.uniform(0.05, 0.5, N)
    res = exact_jpda(L, miss)
    assert res.n_components == 0 and res.max_frontier == 0
    sub = slice(0, 6)  # compare a short chain with brute force
    np.testing.assert_allclose(
        exact_marginals(L[sub, :13], miss[sub]), brute_jpda(L[sub, :13], miss[sub])[0], atol=1e-12
    )
    # a ring of 12 tracks: one cycle, the frontier stays small
    N = 12
    L = np.zeros((N, N))
    for i in range(N):
        L[i, i] = rng.uniform(0.2, 3)
        L[i, (i + 1) % N] = rng.uniform(0.2, 3)
    miss = rng.uniform(0.05, 0.5, N)
    res = exact_jpda(L, miss)
    assert res.n_components == 1 and res.max_frontier <= 3
    ref, logz = numpy_subset_dp(L, miss)
    assert np.abs(res.beta - ref).max() <= 1e-12
    assert res.log_normalizer == pytest.approx(logz, abs=1e-12)
    # a long ring (60 tracks) is still cheap
    N = 60
    L = np.zeros((N, N))
    for i in range(N):
        L[i, i] = 1.0
        L[i, (i + 1) % N] = 1.0
    res = exact_jpda(L, np.full(N, 0.5))
    assert res.max_frontier <= 3
    # by rotational symmetry every track has the same marginals
    assert np.abs(res.beta[:, 0] - res.beta[0, 0]).max() < 1e-12


# ---------------------------------------------------------------------------
# invariances and structure
# ---------------------------------------------------------------------------


def _random_cluster(seed, N=5, M=7, density=0.7):
    rng = np.random.default_rng(seed)
    L = rng.exponential(size=(N, M)) * (rng.random((N, M)) < density)
    miss = rng.uniform(0.05, 0.9, N)
    return L, miss


@pytest.mark.parametrize("method", ["exact", "enumerate", "pda"])
def test_permutations_permute_beta(method):
    L, miss = _random_cluster(11)
    rng = np.random.default_rng(0)
    p = rng.permutation(L.shape[0])
    q = rng.permutation(L.shape[1])
    beta = marginals(L, miss, method=method)
    beta2 = marginals(L[p][:, q], miss[p], method=method)
    np.testing.assert_allclose(beta2, beta[p][:, np.concatenate(([0], q + 1))], atol=1e-14)


@pytest.mark.parametrize("method", ["exact", "enumerate", "pda"])
def test_scaling_a_track_with_its_miss_weight_is_invariant(method):
    # each track contributes exactly one factor (miss or one L entry) to every
    # joint event, so scaling row i of [miss | L] cancels in (6)
    L, miss = _random_cluster(12)
    c = np.array([0.5, 1e-3, 1.0, 0.25, 1e-7])
    beta = marginals(L, miss, method=method)
    np.testing.assert_allclose(marginals(L * c[:, None], miss * c, method=method), beta, atol=1e-13)
    # so is scaling ALL of L and miss by one constant (≈ changing P_D·g units)
    np.testing.assert_allclose(marginals(L * 0.01, miss * 0.01, method=method), beta, atol=1e-13)


def test_scaling_l_alone_or_one_measurement_changes_jpda():
    # scaling L alone is a change of clutter density λ: not an invariance
    L, miss = _random_cluster(13)
    beta = exact_marginals(L, miss)
    assert np.abs(exact_marginals(L * 3.0, miss) - beta).max() > 1e-3
    # neither is scaling one measurement's column (its clutter weight stays 1)
    L2 = L.copy()
    j = int(np.argmax((L > 0).sum(axis=0)))
    L2[:, j] *= 5.0
    assert np.abs(exact_marginals(L2, miss) - beta).max() > 1e-3


def test_independent_blocks_and_ungated_measurements():
    L1, m1 = _random_cluster(21, 3, 4)
    L2, m2 = _random_cluster(22, 4, 3)
    L = np.zeros((7, 8))
    L[:3, :4] = L1
    L[3:, 4:7] = L2  # column 7: gated by nobody
    miss = np.concatenate((m1, m2))
    r = exact_jpda(L, miss)
    r1 = exact_jpda(L1, m1)
    r2 = exact_jpda(L2, m2)
    np.testing.assert_allclose(r.beta[:3, :5], r1.beta, atol=1e-14)
    np.testing.assert_allclose(r.beta[3:, [0, 5, 6, 7]], r2.beta, atol=1e-14)
    assert np.all(r.beta[:, 8] == 0)
    assert r.log_normalizer == pytest.approx(r1.log_normalizer + r2.log_normalizer, abs=1e-12)


def test_jpda_differs_from_pda_when_tracks_compete():
    # two tracks, one shared measurement: PDA lets both take it with prob 2/3;
    # JPDA's joint constraint lowers both
    L = np.array([[2.0], [2.0]])
    miss = np.array([1.0, 1.0])
    np.testing.assert_allclose(pda_marginals(L, miss), [[1 / 3, 2 / 3], [1 / 3, 2 / 3]])
    # events: none (1), 1 takes it (2), 2 takes it (2) -> Z = 5
    np.testing.assert_allclose(exact_marginals(L, miss), [[3 / 5, 2 / 5], [3 / 5, 2 / 5]])


def test_pda_is_per_track_eq_3():
    L, miss = _random_cluster(5)
    beta = pda_marginals(L, miss)
    ref = np.column_stack((miss, L))
    ref /= ref.sum(axis=1, keepdims=True)
    np.testing.assert_allclose(beta, ref, atol=1e-15)


# ---------------------------------------------------------------------------
# empty scans, bad input, extreme scales
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("method", ["exact", "enumerate", "pda"])
def test_empty_scans(method):
    assert marginals(np.zeros((0, 3)), np.zeros(0), method=method).shape == (0, 4)
    assert marginals(np.zeros((0, 0)), np.zeros(0), method=method).shape == (0, 1)
    b = marginals(np.zeros((3, 0)), np.array([0.1, 0.5, 1.0]), method=method)
    np.testing.assert_array_equal(b, np.ones((3, 1)))
    b = marginals(np.zeros((2, 3)), np.array([0.3, 0.4]), method=method)
    np.testing.assert_array_equal(b, [[1, 0, 0, 0], [1, 0, 0, 0]])


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize(
    "L, miss, match",
    [
        (np.ones((2, 3)), np.ones(3) * 0.5, "rows"),
        (np.array([[1.0, -1.0]]), [0.5], "negative"),
        (np.array([[1.0, np.nan]]), [0.5], "non-finite"),
        (np.array([[1.0, np.inf]]), [0.5], "non-finite"),
        (np.ones((1, 2)), [1.5], "outside"),
        (np.ones((1, 2)), [-0.1], "outside"),
        (np.ones((1, 2)), [np.nan], "finite"),
        (np.ones(3), [0.5], "2-D"),
    ],
)
def test_bad_input_raises_value_error(method, L, miss, match):
    with pytest.raises(ValueError, match=match):
        marginals(L, miss, method=method)


@pytest.mark.parametrize("method", METHODS)
def test_certainly_detected_track_without_measurement(method):
    with pytest.raises(InfeasibleAssignmentError, match="miss = 0"):
        marginals(np.array([[0.0, 0.0], [1.0, 1.0]]), [0.0, 0.5], method=method)


@pytest.mark.parametrize("method", EXACT_METHODS)
def test_jointly_infeasible_cluster(method):
    # both tracks certainly detected, one measurement between them
    with pytest.raises(InfeasibleAssignmentError):
        marginals(np.array([[1.0], [2.0]]), [0.0, 0.0], method=method)
    # …while a feasible all-detected cluster is fine and forces the assignment
    b = marginals(np.array([[1.0, 3.0], [2.0, 0.0]]), [0.0, 0.0], method=method)
    np.testing.assert_allclose(b, [[0, 0, 1], [0, 1, 0]], atol=1e-15)


def test_unknown_method_lists_the_methods():
    with pytest.raises(ValueError, match="exact, enumerate, pda, lbp, mcmc, kbest"):
        marginals(np.ones((1, 1)), [0.5], method="magic")


@pytest.mark.parametrize("method", EXACT_METHODS + ("pda",))
@pytest.mark.parametrize("scale", [1e-200, 1e-120, 1e120, 1e200, "mixed"])
def test_extreme_scales_are_finite_and_correct(method, scale):
    rng = np.random.default_rng(17)
    N, M = 5, 4  # N > M: every event misses a track
    A = rng.uniform(0.1, 1, (N, M)) * (rng.random((N, M)) < 0.8)
    if scale == "mixed":
        A *= 10.0 ** rng.choice([-200, 0, 200], size=(N, M))
    else:
        A *= scale
    miss = rng.uniform(0.05, 1, N)
    if method == "pda":
        ref = np.column_stack((miss, A)).astype(object)
        ref = np.array(
            [[float(Fraction(x) / sum(Fraction(y) for y in row)) for x in row] for row in ref]
        )
    else:
        ref = brute_jpda(A, miss, exact_arith=True)[0]
    beta = marginals(A, miss, method=method)
    assert np.all(np.isfinite(beta))
    np.testing.assert_allclose(beta.sum(axis=1), 1.0, atol=1e-14)
    np.testing.assert_allclose(beta, ref, rtol=0, atol=1e-12)


@pytest.mark.parametrize("method", EXACT_METHODS)
def test_intermediate_underflow_is_avoided(method):
    # Two 1e200 events compete; processing m1, m2 first makes "both tracks used"
    # 1e400 times the empty state, yet the empty state later wins m3, m4. A DP
    # normalised per layer by its maximum loses that path; the dual scaling keeps it.
    L = np.array([[1e200, 1e200, 1e200, 0.0], [1e200, 1e200, 0.0, 1e200]])
    miss = np.array([1e-300, 1e-300])
    ref = brute_jpda(L, miss, exact_arith=True)[0]
    beta = marginals(L, miss, method=method)
    np.testing.assert_allclose(beta, ref, rtol=0, atol=1e-12)
    assert beta[0, 3] == pytest.approx(3 / 7, rel=1e-12)


def test_dense_16_32_runs_with_full_frontier():
    rng = np.random.default_rng(0)
    L = 5 * rng.random((16, 32))
    res = exact_jpda(L, np.full(16, 0.1))
    assert res.max_frontier == 16 and res.n_components == 1 and res.n_folded == 0
    np.testing.assert_allclose(res.beta.sum(axis=1), 1.0, atol=1e-13)
    # column sums: each measurement is used at most once
    assert np.all(res.beta[:, 1:].sum(axis=0) <= 1 + 1e-12)
