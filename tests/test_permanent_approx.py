"""Tests of the approximate permanents: Bethe (belief propagation) and importance sampling.

Exact references: ``brute`` (enumeration in rationals, n ≤ 7) and a subset
dynamic programme written here (n ≤ 14), independent of the package.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from brute import brute_marginals, brute_permanent
from jointtrack.errors import InfeasibleAssignmentError
from jointtrack.permanent.bethe import BethePermanent, bethe_permanent
from jointtrack.permanent.sampling import SampledPermanent, sample_permanent

# ----------------------------------------------------------------------------------------
# exact references
# ----------------------------------------------------------------------------------------


def _popcounts(m: int) -> np.ndarray:
    masks = np.arange(1 << m)
    return np.array([bin(int(x)).count("1") for x in masks])


def dp_permanent(A) -> float:
    """Per(A) for n×m, n ≤ m ≤ 14: f[S] = Σ_{j∈S} A[|S|−1, j] f[S∖j] (non-negative sums)."""
    A = np.asarray(A, dtype=float)
    n, m = A.shape
    pc = _popcounts(m)
    f = np.zeros(1 << m)
    f[0] = 1.0
    for k in range(1, n + 1):
        layer = np.flatnonzero(pc == k)
        for j in range(m):
            sel = layer[(layer >> j) & 1 == 1]
            f[sel] += A[k - 1, j] * f[sel ^ (1 << j)]
    return float(f[pc == n].sum())


def dp_marginals(A) -> tuple[float, np.ndarray]:
    """(Per(A), P) for square A, n ≤ 14, by a forward and a backward subset DP.

    P[i, j] = Σ_{|S| = i, j ∉ S} f[S] A[i, j] g[∁(S ∪ {j})] / Per, where f[S] is the
    permanent of rows 0..i−1 on columns S and g[T] that of rows n−|T|..n−1 on T.
    """
    A = np.asarray(A, dtype=float)
    n = A.shape[0]
    assert A.shape == (n, n)
    full = (1 << n) - 1
    pc = _popcounts(n)
    f = np.zeros(1 << n)
    g = np.zeros(1 << n)
    f[0] = g[0] = 1.0
    for k in range(1, n + 1):
        layer = np.flatnonzero(pc == k)
        for j in range(n):
            sel = layer[(layer >> j) & 1 == 1]
            f[sel] += A[k - 1, j] * f[sel ^ (1 << j)]
            g[sel] += A[n - k, j] * g[sel ^ (1 << j)]
    per = float(f[full])
    P = np.zeros((n, n))
    for i in range(n):
        layer = np.flatnonzero(pc == i)
        for j in range(n):
            S = layer[(layer >> j) & 1 == 0]
            P[i, j] = A[i, j] * np.sum(f[S] * g[full ^ S ^ (1 << j)]) / per
    return per, P


def test_dp_references_agree_with_brute_force():
    rng = np.random.default_rng(0)
    for shape in [(3, 3), (4, 6), (5, 5), (2, 7)]:
        A = rng.random(shape) * (rng.random(shape) < 0.8)
        assert dp_permanent(A) == pytest.approx(brute_permanent(A), rel=1e-12, abs=1e-300)
    A = rng.random((6, 6))
    per, P = dp_marginals(A)
    assert per == pytest.approx(brute_permanent(A), rel=1e-12)
    np.testing.assert_allclose(P, brute_marginals(A), rtol=1e-10, atol=1e-14)


# ----------------------------------------------------------------------------------------
# strategies
# ----------------------------------------------------------------------------------------

_entry = st.one_of(
    st.just(0.0),
    st.floats(1e-3, 1e3, allow_nan=False, allow_infinity=False),
    st.sampled_from([1.0, 2.0, 3.0]),
)


@st.composite
def square_matrices(draw, max_n=6):
    n = draw(st.integers(1, max_n))
    return draw(arrays(np.float64, (n, n), elements=_entry))


@st.composite
def wide_matrices(draw, max_m=6):
    m = draw(st.integers(2, max_m))
    n = draw(st.integers(1, m - 1))
    return draw(arrays(np.float64, (n, m), elements=_entry))


_hyp = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def _close_le(a: float, b: float, rtol: float = 1e-9) -> bool:
    """a ≤ b up to rounding (relative to the magnitudes involved)."""
    return a <= b + rtol * (1.0 + abs(a) + abs(b))


# ----------------------------------------------------------------------------------------
# Bethe permanent
# ----------------------------------------------------------------------------------------


@_hyp
@given(square_matrices())
def test_bethe_gurvits_bounds_square(A):
    """perB(A) ≤ Per(A) ≤ 2^{n/2} perB(A) (Gurvits 2011; Anari & Rezaei 2019)."""
    n = A.shape[0]
    per = brute_permanent(A)
    if per == 0:
        with pytest.raises(InfeasibleAssignmentError):
            bethe_permanent(A)
        return
    res = bethe_permanent(A)
    assert isinstance(res, BethePermanent)
    assert math.isfinite(res.log_value)
    lp = math.log(per)
    assert _close_le(res.log_value, lp)
    assert _close_le(lp, res.log_value + 0.5 * n * math.log(2.0))
    _check_beliefs(A, res.marginals)


@_hyp
@given(wide_matrices())
def test_bethe_rectangular_between_padded_bethe_and_permanent(A):
    """Column-slack Bethe: perB([A;1])/(m−n)! ≤ perB(A) ≤ Per(A) (observed property)."""
    n, m = A.shape
    per = brute_permanent(A)
    if per == 0:
        with pytest.raises(InfeasibleAssignmentError):
            bethe_permanent(A)
        return
    res = bethe_permanent(A)
    padded = bethe_permanent(np.vstack([A, np.ones((m - n, m))]))
    assert _close_le(padded.log_value - math.lgamma(m - n + 1), res.log_value)
    assert _close_le(res.log_value, math.log(per))
    _check_beliefs(A, res.marginals)


def _check_beliefs(A, G):
    n, m = A.shape
    assert G.shape == (n, m)
    assert np.all(G >= 0) and np.all(G <= 1)
    assert np.all(G[A == 0] == 0)
    np.testing.assert_allclose(G.sum(axis=1), 1.0, atol=1e-12)
    if n == m:
        np.testing.assert_allclose(G.sum(axis=0), 1.0, atol=1e-9)
    else:
        assert np.all(G.sum(axis=0) <= 1.0 + 1e-9)


def test_bethe_exact_on_trivial_and_tree_supports():
    rng = np.random.default_rng(1)
    # 1×1 and a single row: the factor graph is a tree
    r = bethe_permanent([[2.5]])
    assert r.log_value == pytest.approx(math.log(2.5), abs=1e-15)
    a = rng.random(7)
    r = bethe_permanent(a[None, :])
    assert r.log_value == pytest.approx(math.log(a.sum()), rel=1e-12)
    np.testing.assert_allclose(r.marginals[0], a / a.sum(), rtol=1e-10)
    # diagonal and permutation supports: a single assignment, γ is that permutation
    d = rng.random(6) + 0.1
    r = bethe_permanent(np.diag(d))
    assert r.log_value == pytest.approx(np.log(d).sum(), rel=1e-13)
    perm = rng.permutation(6)
    P = np.zeros((6, 6))
    P[np.arange(6), perm] = d
    r = bethe_permanent(P)
    assert r.log_value == pytest.approx(np.log(d).sum(), rel=1e-13)
    np.testing.assert_array_equal(r.marginals, (P > 0).astype(float))
    # random bipartite forests with n < m (at-most-one columns): BP is exact on trees
    tested = 0
    for trial in range(20):
        n = int(rng.integers(2, 6))
        m = n + int(rng.integers(1, 3))
        A = _random_forest_support(rng, n, m) * (rng.random((n, m)) + 0.2)
        per = brute_permanent(A)
        if per == 0:
            continue
        tested += 1
        r = bethe_permanent(A)
        assert r.converged
        assert r.log_value == pytest.approx(math.log(per), rel=1e-9, abs=1e-9), (trial, A)
        np.testing.assert_allclose(r.marginals, brute_marginals(A), atol=1e-8)
    assert tested >= 10


def _random_forest_support(rng, n, m):
    """0/1 n×m matrix whose bipartite graph is a random forest (Kruskal on shuffled edges)."""
    S = np.zeros((n, m))
    comp = list(range(n + m))  # union-find over rows 0..n-1 and columns n..

    def find(x):
        while comp[x] != x:
            comp[x] = comp[comp[x]]
            x = comp[x]
        return x

    edges = [(i, j) for i in range(n) for j in range(m)]
    rng.shuffle(edges)
    for i, j in edges[: 2 * (n + m)]:
        a, b = find(i), find(n + j)
        if a != b:
            comp[a] = b
            S[i, j] = 1
    return S


def test_bethe_two_by_two_closed_form_and_vertex_optimum():
    """For 2×2, G(γ) is linear in γ_11, so perB = max(a11 a22, a12 a21) (Vontobel 2013)."""
    rng = np.random.default_rng(2)
    for _ in range(20):
        A = rng.random((2, 2))
        r = bethe_permanent(A)
        expected = max(A[0, 0] * A[1, 1], A[0, 1] * A[1, 0])
        assert r.log_value == pytest.approx(math.log(expected), rel=1e-13)
        assert r.converged
    # a 3×3 block whose Bethe optimum is the vertex of its best assignment (ρ(M) ≤ 1)
    A = np.array([[0.0, 2, 3], [1, 1, 1], [1, 3, 2]])
    r = bethe_permanent(A)
    assert r.log_value == pytest.approx(math.log(9.0), rel=1e-14)
    np.testing.assert_array_equal(r.marginals, [[0, 0, 1], [1, 0, 0], [0, 1, 0]])


def test_bethe_scaling_and_permutation_invariance():
    rng = np.random.default_rng(3)
    A = rng.random((7, 7)) * (rng.random((7, 7)) < 0.7) + np.eye(7)
    base = bethe_permanent(A)
    d1 = np.exp(rng.uniform(-40, 40, 7))
    d2 = np.exp(rng.uniform(-40, 40, 7))
    scaled = bethe_permanent(d1[:, None] * A * d2[None, :])
    expected = base.log_value + np.log(d1).sum() + np.log(d2).sum()
    assert scaled.log_value == pytest.approx(expected, abs=1e-8)
    np.testing.assert_allclose(scaled.marginals, base.marginals, atol=1e-8)
    p, q = rng.permutation(7), rng.permutation(7)
    permuted = bethe_permanent(A[p][:, q])
    assert permuted.log_value == pytest.approx(base.log_value, abs=1e-9)
    np.testing.assert_allclose(permuted.marginals, base.marginals[p][:, q], atol=1e-8)
    # rectangular: row scaling factors out (column scaling does not for the permanent)
    W = rng.random((5, 8))
    d = np.exp(rng.uniform(-30, 30, 5))
    assert bethe_permanent(d[:, None] * W).log_value == pytest.approx(
        bethe_permanent(W).log_value + np.log(d).sum(), abs=1e-8
    )


def test_bethe_anderson_and_plain_bp_reach_the_same_fixed_point():
    rng = np.random.default_rng(4)
    for shape in [(6, 6), (5, 9), (12, 12)]:
        A = rng.random(shape) ** 3
        fast = bethe_permanent(A)
        plain = bethe_permanent(A, anderson=0, damping=0.5)
        assert fast.converged and plain.converged
        assert fast.log_value == pytest.approx(plain.log_value, abs=1e-9)
        np.testing.assert_allclose(fast.marginals, plain.marginals, atol=1e-8)
        assert fast.iterations <= plain.iterations


def test_bethe_is_additive_over_blocks_and_unconverged_value_is_a_lower_bound():
    rng = np.random.default_rng(13)
    A1 = rng.random((2, 2))  # vertex optimum: max(a11 a22, a12 a21)
    A2 = rng.random((5, 5))  # interior optimum
    A3 = rng.random((3, 6))  # rectangular block
    A = np.zeros((10, 13))
    A[:2, :2], A[2:7, 2:7], A[7:, 7:] = A1, A2, A3
    parts = [bethe_permanent(X).log_value for X in (A1, A2, A3)]
    whole = bethe_permanent(A)
    assert whole.log_value == pytest.approx(sum(parts), abs=1e-9)
    assert parts[0] == pytest.approx(math.log(max(A1[0, 0] * A1[1, 1], A1[0, 1] * A1[1, 0])))
    # stopped early, the value is G at a feasible γ: below the optimum, above its vertex
    early = bethe_permanent(A2, max_iter=2, anderson=0)
    assert not early.converged
    assert early.log_value < parts[1]
    _check_beliefs(A2, early.marginals)


def test_bethe_falls_back_to_plain_bp_if_acceleration_ends_below_a_vertex(monkeypatch):
    """Guard against an extrapolation that 'converges' towards a wrong face."""
    import jointtrack.permanent.bethe as bethe_mod

    A = np.random.default_rng(14).random((4, 4)) + np.eye(4)
    honest = bethe_permanent(A, anderson=0)
    real_run = bethe_mod._run_bp

    def fake_run(L_sub, ii, jj, shape, ld, tol, max_iter, damping, anderson, **kw):
        if anderson == 0:
            return real_run(L_sub, ii, jj, shape, ld, tol, max_iter, damping, anderson, **kw)
        # beliefs pinned to the anti-diagonal permutation, claimed converged
        d = np.where(ii + jj == shape[0] - 1, 40.0, -40.0)
        return d, 3, True

    monkeypatch.setattr(bethe_mod, "_run_bp", fake_run)
    res = bethe_permanent(A)
    assert res.log_value == pytest.approx(honest.log_value, abs=1e-12)
    assert res.converged == honest.converged
    assert res.iterations == 3 + honest.iterations  # the plain rerun happened
    np.testing.assert_allclose(res.marginals, honest.marginals, atol=1e-12)


# Documented in bethe.py ("Measured accuracy"): the bounds asserted here.
BETHE_GAP_RANGE = (1.2, 1.8)  # log Per − log perB, uniform n = 8..12
BETHE_MARGINAL_ERR = 0.02  # max_ij |γ_ij − P_ij|


def test_bethe_measured_accuracy_uniform_8_to_12():
    rng = np.random.default_rng(2024)
    gaps, errs = [], []
    for n in range(8, 13):
        for _ in range(5):
            A = rng.random((n, n))
            per, P = dp_marginals(A)
            r = bethe_permanent(A)
            assert r.converged
            gaps.append(math.log(per) - r.log_value)
            errs.append(float(np.max(np.abs(r.marginals - P))))
    gaps, errs = np.array(gaps), np.array(errs)
    print(
        f"\nBethe, uniform n=8..12: gap in [{gaps.min():.3f}, {gaps.max():.3f}], "
        f"max marginal error in [{errs.min():.4f}, {errs.max():.4f}]"
    )
    assert np.all(gaps >= BETHE_GAP_RANGE[0]) and np.all(gaps <= BETHE_GAP_RANGE[1])
    assert np.all(errs <= BETHE_MARGINAL_ERR)
    # the gap grows with n (≈ ½ log(2πn/e) for the all-ones matrix)
    assert gaps[-5:].mean() > gaps[:5].mean()


def test_bethe_converges_fast_on_large_random_matrices():
    rng = np.random.default_rng(5)
    for shape in [(100, 100), (100, 130)]:
        A = rng.random(shape)
        r = bethe_permanent(A)
        assert r.converged and r.iterations < 100
        _check_beliefs(A, r.marginals)
    # entries ~1e-50: everything in log space; the value is exactly shifted
    A = rng.random((100, 100))
    tiny = bethe_permanent(A * 1e-50)
    assert tiny.value == 0.0 and math.isfinite(tiny.log_value)
    assert tiny.log_value == pytest.approx(
        bethe_permanent(A).log_value + 100 * math.log(1e-50), abs=1e-7
    )


def test_bethe_all_ones_closed_form():
    """By symmetry and concavity γ = J/n for the all-ones matrix: log perB = n² G(1/n)."""
    for n in (3, 5, 10):
        r = bethe_permanent(np.ones((n, n)))
        g = 1.0 / n
        expected = n * n * (g * math.log(1.0 / g) + (1 - g) * math.log(1 - g))
        assert r.log_value == pytest.approx(expected, rel=1e-10)
        np.testing.assert_allclose(r.marginals, g, atol=1e-10)


def test_bethe_input_errors():
    with pytest.raises(InfeasibleAssignmentError):
        bethe_permanent([[1.0, 0.0], [1.0, 0.0]])
    with pytest.raises(InfeasibleAssignmentError):
        bethe_permanent(np.zeros((2, 3)))
    for bad in ([[1.0, -1.0]], [[np.nan]], [1.0, 2.0], np.ones((3, 2))):
        with pytest.raises(ValueError):
            bethe_permanent(bad)
    for kw in (
        {"tol": 0.0},
        {"tol": np.nan},
        {"max_iter": 0},
        {"max_iter": 2.5},
        {"damping": 1.0},
        {"damping": -0.1},
        {"anderson": -1},
    ):
        with pytest.raises(ValueError):
            bethe_permanent(np.ones((2, 2)), **kw)
    empty = bethe_permanent(np.zeros((0, 3)))
    assert empty.log_value == 0.0 and empty.value == 1.0


def test_bethe_result_is_frozen():
    r = bethe_permanent(np.ones((3, 3)))
    with pytest.raises(AttributeError):
        r.log_value = 0.0  # type: ignore[misc]
    with pytest.raises(ValueError):
        r.marginals[0, 0] = 0.5


# ----------------------------------------------------------------------------------------
# importance sampling
# ----------------------------------------------------------------------------------------


def _z(res: SampledPermanent, exact: float) -> float:
    if res.rel_stderr == 0:
        return 0.0 if res.value == pytest.approx(exact, rel=1e-12) else math.inf
    return abs(res.value / exact - 1.0) / res.rel_stderr


def test_sampling_within_five_standard_errors_brute_force():
    rng = np.random.default_rng(6)
    checked = 0
    while checked < 12:
        n = int(rng.integers(2, 8))
        m = n + int(rng.integers(0, 3)) if n < 7 else 7
        A = rng.random((n, m)) * (rng.random((n, m)) < 0.75)
        exact = brute_permanent(A)
        if exact == 0:
            continue
        checked += 1
        for seed in range(3):
            res = sample_permanent(A, 2_000, rng=seed)
            assert isinstance(res, SampledPermanent) and res.n_samples == 2_000
            assert _z(res, exact) <= 5.0, (A, res, exact)


# Documented in sampling.py ("Measured accuracy").
SAMPLING_REL_STDERR_12 = 0.02  # uniform 12×12 at 10⁴ samples


def test_sampling_within_five_standard_errors_dp():
    rng = np.random.default_rng(7)
    A = rng.random((12, 12))
    exact = dp_permanent(A)
    for seed in range(3):
        res = sample_permanent(A, 10_000, rng=seed)
        assert _z(res, exact) <= 5.0
        assert 0 < res.rel_stderr < SAMPLING_REL_STDERR_12
    W = rng.random((10, 13)) * (rng.random((10, 13)) < 0.6)
    exact = dp_permanent(W)
    assert exact > 0
    for seed in range(3):
        assert _z(sample_permanent(W, 10_000, rng=seed), exact) <= 5.0


def test_sampling_stderr_shrinks_like_inverse_sqrt():
    A = np.random.default_rng(8).random((9, 9)) ** 2
    small = sample_permanent(A, 1_000, rng=1).rel_stderr
    large = sample_permanent(A, 16_000, rng=1).rel_stderr
    assert 2.5 < small / large < 6.0  # √16 = 4


def test_sampling_reproducible_and_rng_forms():
    A = np.random.default_rng(9).random((6, 8))
    a = sample_permanent(A, 500, rng=42)
    b = sample_permanent(A, 500, rng=np.random.default_rng(42))
    c = sample_permanent(A, 500, rng=43)
    assert a == b
    assert a.log_value != c.log_value
    assert math.isfinite(sample_permanent(A, 500).log_value)  # rng=None


def test_sampling_zero_variance_cases_are_exact():
    n = 6
    res = sample_permanent(np.full((n, n), 3.0), 50, rng=0)
    assert res.rel_stderr == pytest.approx(0.0, abs=1e-12)
    assert res.log_value == pytest.approx(math.lgamma(n + 1) + n * math.log(3.0), rel=1e-12)
    d = np.random.default_rng(10).random(5) + 0.5
    perm = np.array([3, 0, 4, 1, 2])
    P = np.zeros((5, 5))
    P[np.arange(5), perm] = d
    res = sample_permanent(P, 20, rng=0)
    assert res.log_value == pytest.approx(np.log(d).sum(), rel=1e-12)
    assert res.rel_stderr == pytest.approx(0.0, abs=1e-12)


def test_sampling_tiny_entries_large_matrix():
    A = np.random.default_rng(11).random((100, 100))
    res = sample_permanent(A * 1e-50, 2_000, rng=3)
    ref = sample_permanent(A, 2_000, rng=3)
    assert res.value == 0.0 and math.isfinite(res.log_value)
    assert res.log_value == pytest.approx(ref.log_value + 100 * math.log(1e-50), abs=1e-6)
    assert res.rel_stderr == pytest.approx(ref.rel_stderr, rel=1e-6)
    lo, hi = res.confidence_interval(log=True)
    assert lo < res.log_value < hi and math.isfinite(lo)


def test_sampling_confidence_interval_coverage():
    A = np.random.default_rng(12).random((6, 6))
    exact = brute_permanent(A)
    hits = 0
    for seed in range(40):
        res = sample_permanent(A, 400, rng=seed)
        lo, hi = res.confidence_interval(0.95)
        assert lo < res.value < hi
        llo, lhi = res.confidence_interval(0.95, log=True)
        assert llo == pytest.approx(math.log(lo)) and lhi == pytest.approx(math.log(hi))
        hits += lo <= exact <= hi
    assert hits >= 32  # nominal 38/40; binomial 1e-3 quantile ≈ 34
    with pytest.raises(ValueError):
        res.confidence_interval(1.0)


def test_sampling_input_errors():
    with pytest.raises(InfeasibleAssignmentError):
        sample_permanent([[1.0, 0.0], [2.0, 0.0]], 100, rng=0)
    for bad in (0, 1, 2.5, True, "10", None):
        with pytest.raises(ValueError):
            sample_permanent(np.ones((2, 2)), bad)
    with pytest.raises(ValueError):
        sample_permanent(np.ones((2, 2)), 10, rng="seed")
    with pytest.raises(ValueError):
        sample_permanent(np.ones((3, 2)), 10)
    res = sample_permanent(np.zeros((0, 4)), 10)
    assert res.log_value == 0.0 and res.value == 1.0


def test_sampling_prunes_entries_outside_every_matching():
    # row 1 forces column 0, so row 0 must take its tiny entry: a single assignment
    A = np.array([[1.0, 1e-300, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 1.0]])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        res = sample_permanent(A, 10, rng=0)
    assert res.log_value == pytest.approx(math.log(1e-300), rel=1e-12)
    assert res.rel_stderr == pytest.approx(0.0, abs=1e-12)
