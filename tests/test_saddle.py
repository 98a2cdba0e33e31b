"""Streit's generating function: exact mixed derivative, saddle point (24)/(30), corrected."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from brute import log_fraction, mixed_derivative_fraction
from jointtrack.assignment import assignment_sum
from jointtrack.association import exact_log_normalizer
from jointtrack.saddle import (
    SaddlePointError,
    jpda_log_weights,
    log_mixed_derivative,
    saddle_point,
)
from jointtrack.saddle import corrections as C

SETTINGS = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
STIRLING = 1.0 - 0.5 * math.log(2.0 * math.pi)  # log(e/√(2π)) per measurement


# --------------------------------------------------------------------------- references


def brute_log_I(a0, a, F) -> float:
    """log ∂^M Ψ/∂β_1…∂β_M (0) by enumerating assignments in exact rationals.

    Each factor takes one measurement (f_km) or none (f_k0), each measurement at
    most one factor; a measurement no factor takes is clutter (a_m).
    """
    return a0 + log_fraction(mixed_derivative_fraction(a, F))


def feasible(F) -> bool:
    """Some assignment has positive weight (factors with f_k0 = 0 need their own measurement)."""
    F = np.asarray(F)
    K, M1 = F.shape
    for choice in itertools.product(range(M1), repeat=K):
        taken = [j for j in choice if j]
        if len(taken) == len(set(taken)) and all(F[k, j] > 0 for k, j in enumerate(choice)):
            return True
    return False


@st.composite
def tiny_problems(draw, max_k=3, max_m=4, zeros=True, exponent=140, spread=20):
    """(a0, a, F): K ≤ max_k factors, M ≤ max_m measurements, values drawn with zeros.

    Every value is 10^(x + row scale + column scale) with x within ±``spread``
    decades and the scales within ±``exponent``: magnitudes from ~1e-300 to
    ~1e300, while the ratios that decide the answer (f_km / a_m within a factor)
    stay in the float range (row and column scales factor out of I exactly).
    """
    K = draw(st.integers(0, max_k))
    M = draw(st.integers(0, max_m))
    dec = st.floats(-spread, spread)
    row = [draw(st.floats(-exponent, exponent)) for _ in range(K)]
    col = [draw(st.floats(-exponent, exponent)) for _ in range(M)]
    a = np.array([10.0 ** (draw(dec) + col[m]) for m in range(M)])
    F = np.empty((K, M + 1))
    for k in range(K):
        F[k, 0] = 10.0 ** (draw(dec) + row[k])
        for m in range(M):
            F[k, m + 1] = 10.0 ** (draw(dec) + row[k] + col[m])
    if zeros and F.size:
        off = draw(st.lists(st.booleans(), min_size=F.size, max_size=F.size))
        F[np.array(off).reshape(F.shape)] = 0.0
    a0 = draw(st.floats(-50.0, 50.0))
    return a0, a, F


def uniform_problem(rng, K, M, L=None):
    """Table 1's setup: f_k0 = 1, a_m and f_km ~ U[0, 1]."""
    a = rng.uniform(size=M)
    F = rng.uniform(size=(K, M + 1) if L is None else (L, K, M + 1))
    F[..., 0] = 1.0
    return a, F


# --------------------------------------------------------------------------- exact


@SETTINGS
@given(tiny_problems())
def test_exact_equals_enumeration_in_rationals(problem):
    a0, a, F = problem
    got = log_mixed_derivative(a0, a, F)
    want = brute_log_I(a0, a, F)
    if want == -math.inf:
        assert got == -math.inf
    else:
        assert got == pytest.approx(want, rel=1e-12, abs=1e-9)


@SETTINGS
@given(tiny_problems(max_m=0))
def test_no_measurement_is_e_a0_times_the_constants(problem):
    a0, a, F = problem
    with np.errstate(divide="ignore"):
        want = a0 + np.log(F[:, 0]).sum()
    assert log_mixed_derivative(a0, a, F) == pytest.approx(want, rel=1e-14, abs=1e-12)
    for method in ("saddle", "saddle-corrected"):
        assert log_mixed_derivative(a0, a, F, method) == pytest.approx(want, abs=1e-12)


@SETTINGS
@given(st.integers(1, 4), st.integers(1, 5), st.integers(0, 2**32 - 1))
def test_exact_equals_the_jpda_normaliser(N, M, seed):
    """Ψ of a JPDA cluster: f_k0 = 1 − P_D, f_km = P_D g_km, a_m = λ; I/Π a = Z(L, miss)."""
    rng = np.random.default_rng(seed)
    pd = rng.uniform(0.3, 1.0, N)
    pd[rng.random(N) < 0.3] = 1.0  # certainly detected tracks too
    g = rng.exponential(size=(N, M)) * (rng.random((N, M)) < 0.7)  # gating zeros
    lam = 10.0 ** rng.uniform(-3, 1, M)
    F = np.concatenate([(1.0 - pd)[:, None], pd[:, None] * g], axis=1)
    got = log_mixed_derivative(0.3, lam, F)
    L, miss = F[:, 1:] / lam, F[:, 0]
    core = assignment_sum(L, miss, marginals=False).log_normalizer
    want = 0.3 + np.log(lam).sum() + core
    if core == -math.inf:
        assert got == -math.inf
        return
    assert got == pytest.approx(want, rel=1e-12, abs=1e-10)
    assert exact_log_normalizer(L, miss) == pytest.approx(core, rel=1e-12, abs=1e-10)


@SETTINGS
@given(st.integers(1, 4), st.integers(0, 5), st.integers(1, 30), st.integers(0, 2**32 - 1))
def test_jpda_log_weights_equal_the_general_exact_path(K, M, L, seed):
    rng = np.random.default_rng(seed)
    a = 10.0 ** rng.uniform(-2, 1, M)
    b = rng.uniform(size=(L, M + 1)) * (rng.random((L, M + 1)) < 0.8)
    b[:, 0] = rng.uniform(0.05, 1.0, L)
    Cf = rng.uniform(size=(K - 1, M + 1))
    got = jpda_log_weights(-0.7, a, b, Cf)
    F = np.concatenate([b[:, None, :], np.broadcast_to(Cf, (L, K - 1, M + 1))], axis=1)
    want = log_mixed_derivative(-0.7, a, F)
    np.testing.assert_allclose(got, want, rtol=1e-10, atol=1e-10)


# --------------------------------------------------------------------------- saddle point


def test_figure_1_saddle_point():
    """f(z) = e^z (1 + 10z)^4 z^{-6}: r̂ = (19 + √601)/20, the root of 10z² − 19z − 6."""
    sp = saddle_point(0.0, [1.0], [[1.0, 10.0]] * 4, counts=[6.0])
    r = float(np.exp(sp.u[0]))
    root = (19.0 + math.sqrt(601.0)) / 20.0
    assert r == pytest.approx(root, rel=1e-12)
    assert 10 * r * r - 19 * r - 6 == pytest.approx(0.0, abs=1e-10)
    assert round(r, 2) == 2.18  # the paper's value

    def log_f(z):
        return z + 4 * math.log1p(10 * z) - 6 * math.log(z)

    assert sp.phi == pytest.approx(log_f(r), rel=1e-14)
    assert all(log_f(r * s) > log_f(r) for s in (0.999, 1.001, 0.5, 2.0))
    # d log f / d log z = 0 there
    h = 1e-6
    assert (log_f(r * math.exp(h)) - log_f(r * math.exp(-h))) / (2 * h) == pytest.approx(
        0.0, abs=1e-8
    )


@SETTINGS
@given(st.integers(0, 5), st.integers(1, 8), st.integers(0, 2**32 - 1))
def test_saddle_point_is_stationary_and_converged(K, M, seed):
    rng = np.random.default_rng(seed)
    a = 10.0 ** rng.uniform(-3, 2, M)
    F = 10.0 ** rng.uniform(-3, 2, (6, K, M + 1))
    sp = saddle_point(0.0, a, F)
    assert sp.converged.all()
    tl = C.tilt(sp.u, a, F)
    grad = tl.lam + tl.p.sum(-2) - 1.0  # E[X] − 1
    assert np.abs(grad).max() <= 1e-10
    assert sp.gradient_norm.max() <= 1e-10
    # log det enters eq. (30) as an exponent: its absolute error is what matters
    np.testing.assert_allclose(sp.log_det, np.linalg.slogdet(tl.cov)[1], rtol=1e-10, atol=1e-12)


def test_too_few_newton_steps_raise_a_clear_error():
    a, F = uniform_problem(np.random.default_rng(1), 3, 5, L=4)
    with pytest.raises(SaddlePointError, match="max_iter = 1 Newton steps"):
        saddle_point(0.0, a, F, max_iter=1)
    sp = saddle_point(0.0, a, F, max_iter=1, raise_on_failure=False)
    assert not sp.converged.all() and sp.iterations == 1
    assert saddle_point(0.0, a, F).converged.all()


@pytest.mark.parametrize("method", ["saddle", "saddle-corrected"])
def test_batched_equals_per_problem(method):
    rng = np.random.default_rng(2)
    for K, M in [(0, 3), (1, 1), (3, 5), (4, 9)]:
        a = 10.0 ** rng.uniform(-2, 1, M)
        F = 10.0 ** rng.uniform(-2, 1, (7, K, M + 1))
        F[2, :, 0] = 0.0  # certainly detected factors
        batched = log_mixed_derivative(0.5, a, F, method)
        one = np.array([log_mixed_derivative(0.5, a, Fi, method) for Fi in F])
        np.testing.assert_allclose(batched, one, rtol=1e-12, atol=1e-12)
        big = np.concatenate([F] * 3)  # chunking of large batches changes nothing
        np.testing.assert_allclose(log_mixed_derivative(0.5, a, big, method), np.tile(one, 3))


def test_saddle_against_exact_on_random_small_problems():
    """Eq. (30) carries the (e/√(2π))^M bias with a few % scatter; the corrected one none."""
    rng = np.random.default_rng(3)
    for K, M in [(1, 2), (2, 4), (3, 5), (4, 3), (5, 6)]:
        a, F = uniform_problem(rng, K, M, L=40)
        exact = log_mixed_derivative(0.0, a, F)
        plain = log_mixed_derivative(0.0, a, F, "saddle") - exact
        corrected = log_mixed_derivative(0.0, a, F, "saddle-corrected") - exact
        assert np.abs(plain - M * STIRLING).max() < 0.25  # Table 1's band, with few factors
        assert np.abs(corrected).max() < 0.05
        assert abs(np.exp(corrected).mean() - 1.0) < 0.01


@SETTINGS
@given(tiny_problems(max_k=4, max_m=2, exponent=100, spread=3))
def test_corrected_is_exact_up_to_two_measurements(problem):
    """Singles and pairs are exact, and with M ≤ 2 there is nothing beyond them."""
    a0, a, F = problem
    want = brute_log_I(a0, a, F)
    got = log_mixed_derivative(a0, a, F, "saddle-corrected")
    if want == -math.inf:
        assert got == -math.inf
    else:
        assert got == pytest.approx(want, rel=1e-9, abs=1e-7)


def test_corrected_is_exact_without_factors():
    a = np.array([0.3, 2.0, 7.5, 1e-3])
    F = np.ones((1, 0, 5))
    want = 1.5 + np.log(a).sum()
    assert log_mixed_derivative(1.5, a, F, "saddle-corrected")[0] == pytest.approx(want)


def test_table_1_cells_within_one_percent():
    """Table 1's setup, 250 trials a cell: |mean − 1| and std/mean of approx/exact ≤ 1 %."""
    for K in (3, 5, 7):
        for M in (5, 10, 15):
            rng = np.random.default_rng([7, K, M])
            a = rng.uniform(size=(250, M))
            F = rng.uniform(size=(250, K, M + 1))
            F[..., 0] = 1.0
            G = F.copy()
            G[..., 1:] /= a[:, None, :]  # β_m → β_m / a_m: every trial gets a = 1
            exact = log_mixed_derivative(0.0, np.ones(M), G) + np.log(a).sum(1)
            approx = log_mixed_derivative(0.0, np.ones(M), G, "saddle-corrected")
            ratio = np.exp(approx + np.log(a).sum(1) - exact)
            assert abs(ratio.mean() - 1.0) <= 0.01, (K, M, ratio.mean())
            assert ratio.std() / ratio.mean() <= 0.01, (K, M, ratio.std())


# --------------------------------------------------------------------------- degenerate


@pytest.mark.parametrize("method", ["exact", "saddle", "saddle-corrected"])
def test_zero_derivative_is_minus_infinity(method):
    a = np.array([0.5, 0.2])
    dead = np.array([[1.0, 0.3, 0.4], [0.0, 0.0, 0.0], [1.0, 0.0, 0.2]])  # a factor ≡ 0
    crowded = np.array([[0.0, 1.0, 0.0], [0.0, 2.0, 0.0], [1.0, 1.0, 1.0]])  # 2 for 1 slot
    assert log_mixed_derivative(0.0, a, dead, method) == -math.inf
    assert log_mixed_derivative(0.0, a, crowded, method) == -math.inf
    both = log_mixed_derivative(0.0, a, np.stack([dead, crowded, np.ones((3, 3))]), method)
    assert both[0] == both[1] == -math.inf and np.isfinite(both[2])


def test_a_factor_forced_onto_one_measurement():
    """f_k0 = 0 with one measurement: no interior saddle point (u → −∞), corrected still exact."""
    a = np.array([0.7, 1.3])
    F = np.array([[0.0, 2.0, 0.0], [0.5, 0.4, 0.9]])
    want = brute_log_I(0.0, a, F)
    assert log_mixed_derivative(0.0, a, F) == pytest.approx(want, rel=1e-12)
    assert log_mixed_derivative(0.0, a, F, "saddle-corrected") == pytest.approx(want, abs=1e-8)


@pytest.mark.parametrize("n", [2, 3, 4])
def test_a_tight_block_of_certain_factors(n):
    """n factors with f_k0 = 0 on exactly n measurements: no interior saddle point.

    The corrected method is exact for n ≤ 2 (singles, pairs) and hands n ≥ 3 to the core.
    """
    rng = np.random.default_rng(n)
    a = rng.uniform(size=n + 2)
    F = np.zeros((4, n + 1, n + 3))
    F[:, :n, 1 : n + 1] = rng.uniform(0.1, 1.0, size=(4, n, n))
    F[:, n] = rng.uniform(size=(4, n + 3))
    F[:, n, 0] = 1.0
    exact = log_mixed_derivative(0.0, a, F)
    np.testing.assert_allclose(
        log_mixed_derivative(0.0, a, F, "saddle-corrected"), exact, atol=1e-6
    )


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(tiny_problems(max_k=4, max_m=4, exponent=100, spread=60))
def test_saddle_methods_never_return_nan(problem):
    """Finite, or −inf exactly when I = 0, or a SaddlePointError — never NaN or +inf."""
    a0, a, F = problem
    for method in ("saddle", "saddle-corrected"):
        try:
            with np.errstate(divide="raise", over="raise", invalid="raise"):
                got = log_mixed_derivative(a0, a, F, method)
        except SaddlePointError:
            assert feasible(F)  # only a genuine failure of Newton's method raises
            continue
        assert not math.isnan(got) and got != math.inf
        assert (got == -math.inf) == (not feasible(F))


# --------------------------------------------------------------------------- structure


def _dense_cumulants(p, lam):
    """κ₃, κ₄ of X = Σ one-hot(p_k) + Poisson(λ) as dense tensors (set partitions)."""
    M = lam.size

    def partitions(s):
        if not s:
            yield []
            return
        first, rest = s[0], s[1:]
        for part in partitions(rest):
            for i in range(len(part)):
                yield part[:i] + [[first, *part[i]]] + part[i + 1 :]
            yield [[first], *part]

    def diag(v, r):
        T = np.zeros((M,) * r)
        T[(np.arange(M),) * r] = v
        return T

    out = []
    for r in (3, 4):
        T = diag(lam, r)
        for pk in p:
            for part in partitions(list(range(r))):
                b = len(part)
                coef = (-1) ** (b - 1) * math.factorial(b - 1)
                subs = ",".join("".join("abcd"[i] for i in blk) for blk in part)
                T = T + coef * np.einsum(
                    subs + "->" + "abcd"[:r], *[diag(pk, len(blk)) for blk in part]
                )
        out.append(T)
    return out


def _dense_e2(k3, k4, S):
    rho4 = np.einsum("ijkl,ij,kl->", k4, S, S)
    v = np.einsum("ijk,ij->k", k3, S)
    rho23 = np.einsum("ijk,lmn,il,jm,kn->", k3, k3, S, S, S)
    return rho4 / 8 - v @ S @ v / 8 - rho23 / 12


def test_structured_edgeworth_terms_equal_dense_tensors():
    rng = np.random.default_rng(4)
    for K, M in [(1, 3), (3, 4), (4, 2)]:
        a, F = uniform_problem(rng, K, M)
        sp = saddle_point(0.0, a, F)
        tl = C.tilt(sp.u, a, F)
        k3, k4 = _dense_cumulants(tl.p, tl.lam)
        S = np.linalg.inv(tl.cov)
        np.testing.assert_allclose(np.einsum("ij->i", np.eye(M) * tl.cov), tl.var)
        got = C._edgeworth_term(tl.p, tl.lam + tl.p.sum(-2), S)
        assert got == pytest.approx(_dense_e2(k3, k4, S), rel=1e-10, abs=1e-13)
        iu = np.triu_indices(M, 1)
        k2_, k3_, k4_ = C._univariate_cumulants(tl)
        np.testing.assert_allclose(k3_, np.einsum("iii->i", k3), rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(k4_, np.einsum("iiii->i", k4), rtol=1e-12, atol=1e-15)
        pe, _ = C._pair_edgeworth(
            tl.p[:, iu[0]],
            tl.p[:, iu[1]],
            tl.q[:, iu[0]],
            tl.q[:, iu[1]],
            k2_,
            k3_,
            k4_,
            iu,
            tl.cov[iu],
        )
        for j, (m, n) in enumerate(zip(*iu, strict=True)):
            ix = np.ix_([m, n], [m, n])
            sub3 = k3[np.ix_([m, n], [m, n], [m, n])]
            sub4 = k4[np.ix_([m, n], [m, n], [m, n], [m, n])]
            assert pe[j] == pytest.approx(
                _dense_e2(sub3, sub4, np.linalg.inv(tl.cov[ix])), rel=1e-10, abs=1e-13
            )


def test_exact_single_and_pair_probabilities():
    """P(X_m = 1) and P(X_m = 1, X_n = 1) of the tilted law, against direct sums.

    Coordinate m is Poisson(λ_m) plus a Bernoulli(p_km) per factor: one source
    gives the 1, every other stays silent; the pair needs one source for each,
    two different factors or the Poisson terms.
    """
    rng = np.random.default_rng(5)
    a, F = uniform_problem(rng, 3, 3)
    sp = saddle_point(0.0, a, F)
    tl = C.tilt(sp.u, a, F)
    pieces = C._pieces(tl)
    single = np.zeros(3)
    pair = np.zeros((3, 3))
    for m in range(3):
        q = 1.0 - tl.p[:, m]
        want = math.exp(-tl.lam[m]) * (
            tl.lam[m] * q.prod() + sum(tl.p[k, m] * np.delete(q, k).prod() for k in range(3))
        )
        single[m] = want
    assert pieces["single"] == pytest.approx(np.log(single).sum(), rel=1e-12)
    for m, n in itertools.combinations(range(3), 2):
        z = 1.0 - tl.p[:, m] - tl.p[:, n]
        x, y = tl.p[:, m], tl.p[:, n]
        lm, ln = tl.lam[m], tl.lam[n]
        val = lm * ln * z.prod()
        for k in range(3):
            rest = np.delete(z, k).prod()
            val += lm * y[k] * rest + ln * x[k] * rest
            for j in range(3):
                if j != k:
                    val += x[k] * y[j] * np.delete(z, [k, j]).prod()
        pair[m, n] = math.exp(-lm - ln) * val
    want = sum(
        math.log(pair[m, n]) - math.log(single[m]) - math.log(single[n])
        for m, n in itertools.combinations(range(3), 2)
    )
    assert pieces["pair"] == pytest.approx(want, rel=1e-10, abs=1e-13)


# --------------------------------------------------------------------------- bad input


GOOD_A = np.array([0.5, 0.2])
GOOD_F = np.array([[1.0, 0.3, 0.4], [1.0, 0.1, 0.9]])


@pytest.mark.parametrize("method", ["exact", "saddle", "saddle-corrected"])
@pytest.mark.parametrize(
    ("a0", "a", "F", "match"),
    [
        (0.0, [0.5, 0.0], GOOD_F, r"a\[1\] = 0"),
        (0.0, [-0.5, 0.2], GOOD_F, r"a\[0\] = -0.5"),
        (0.0, GOOD_A, [[1.0, -0.3, 0.4]], "F has a negative coefficient"),
        (0.0, GOOD_A, [[1.0, 0.3]], "F must have M \\+ 1 = 3 columns"),
        (0.0, GOOD_A, np.ones((2, 2, 2, 3)), "F must be 2-D or 3-D"),
        (0.0, [[0.5, 0.2]], GOOD_F, "a must be 1-D"),
        (0.0, [0.5, np.nan], GOOD_F, "a has a non-finite entry"),
        (0.0, GOOD_A, [[1.0, np.inf, 0.4]], "F has a non-finite entry"),
        (np.nan, GOOD_A, GOOD_F, "a0 has a non-finite entry"),
        (0.0, [0.5 + 1j, 0.2], GOOD_F, "a has complex entries"),
        (0.0, GOOD_A, GOOD_F.astype(complex), "F has complex entries"),
        (0.0, [True, True], GOOD_F, "a is boolean"),
        (True, GOOD_A, GOOD_F, "a0"),
        (0.0, GOOD_A, "F", "F must be an array of real numbers"),
    ],
)
def test_bad_input_names_the_argument(method, a0, a, F, match):
    with pytest.raises(ValueError, match=match):
        log_mixed_derivative(a0, a, F, method)


def test_bad_method_and_counts():
    with pytest.raises(ValueError, match="unknown method 'laplace'"):
        log_mixed_derivative(0.0, GOOD_A, GOOD_F, "laplace")
    with pytest.raises(ValueError, match="unknown method"):
        log_mixed_derivative(0.0, GOOD_A, GOOD_F, 3)
    for counts in ([1.0], [1.0, 0.0], [1.0, np.nan]):
        with pytest.raises(ValueError, match="counts must be 2 finite numbers > 0"):
            saddle_point(0.0, GOOD_A, GOOD_F, counts=counts)
    with pytest.raises(ValueError, match="every coefficient 0"):
        saddle_point(0.0, GOOD_A, np.zeros((1, 3)))
