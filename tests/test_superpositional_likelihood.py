"""``likelihood`` / ``log_likelihood_ratio``: exact vs brute force and Monte Carlo; bad input."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.special import logsumexp
from scipy.stats import multivariate_normal as mvn

from jointtrack.errors import ExactLimitError
from jointtrack.superpositional import (
    IIDC,
    FunctionMeasurement,
    MultiBernoulli,
    Poisson,
    Union,
    campbell_moments,
    likelihood,
    log_likelihood_ratio,
    reduced_moments,
)
from superpositional_helpers import H3, S0

# ----------------------------------------------------------------------------- brute force


def brute_mb_terms(mb):
    """(coefficient, mean, cov) of every subset, by explicit loops (y-space, no noise)."""
    out = []
    for bits in itertools.product([0, 1], repeat=mb.n_components):
        c, mean, cov = 1.0, np.zeros(3), np.zeros((3, 3))
        for i, b in enumerate(bits):
            c *= mb.r[i] if b else 1.0 - mb.r[i]
            if b:
                mean = mean + H3 @ mb.means[i]
                cov = cov + H3 @ mb.covs[i] @ H3.T
        out.append((c, mean, cov))
    return out


def brute_iidc_terms(iidc):
    """Every ordered sequence of mixture components for every cardinality (no multinomials)."""
    sp = iidc.spatial
    out = []
    for n, p in enumerate(iidc.cardinality_pmf):
        for seq in itertools.product(range(len(sp.weights)), repeat=n):
            c, mean, cov = p, np.zeros(3), np.zeros((3, 3))
            for k in seq:
                c *= sp.weights[k]
                mean = mean + H3 @ sp.means[k]
                cov = cov + H3 @ sp.covs[k] @ H3.T
            out.append((c, mean, cov))
    return out


def brute_log(terms, y):
    """log Σ c N(y; mean, Σ0 + cov), summed in log space (values reach e^-700 and below)."""
    return logsumexp(
        [math.log(c) + mvn.logpdf(y, mean, S0 + cov) for c, mean, cov in terms if c > 0]
    )


def brute_product(a, b):
    return [(ca * cb, ma + mb, sa + sb) for ca, ma, sa in a for cb, mb, sb in b]


@st.composite
def small_mb(draw, max_n=4):
    n = draw(st.integers(1, max_n))
    r = [draw(st.floats(0.0, 1.0)) for _ in range(n)]
    means = np.array([[draw(st.floats(0, 6)), draw(st.floats(0, 6))] for _ in range(n)])
    scales = [draw(st.floats(0.2, 2.0)) for _ in range(n)]
    return MultiBernoulli(r, means, [s * np.eye(2) for s in scales])


@st.composite
def small_iidc(draw):
    pmf = np.array([draw(st.floats(0.0, 1.0)) for _ in range(draw(st.integers(1, 4)))]) + 0.01
    k = draw(st.integers(1, 3))
    means = np.array([[draw(st.floats(0, 6)), draw(st.floats(0, 6))] for _ in range(k)])
    w = [draw(st.floats(0.05, 1.0)) for _ in range(k)]
    return IIDC(pmf / pmf.sum(), w, means, [np.eye(2)] * k)


y0s = st.lists(st.floats(-2.0, 12.0), min_size=3, max_size=3).map(np.array)


@settings(max_examples=15, deadline=None)
@given(mb=small_mb(), y0=y0s)
def test_exact_multibernoulli_matches_brute_force(mb, y0):
    got = likelihood(y0, mb, H3, S0, method="exact")
    assert got.log_value == pytest.approx(brute_log(brute_mb_terms(mb), y0), abs=1e-9)
    assert got.std_error is None and got.method == "exact"


@settings(max_examples=15, deadline=None)
@given(iidc=small_iidc(), y0=y0s)
def test_exact_iidc_matches_brute_force(iidc, y0):
    got = likelihood(y0, iidc, H3, S0, method="exact")
    want = brute_log(brute_iidc_terms(iidc), y0)
    assert got.log_value == pytest.approx(want, abs=1e-9)


@settings(max_examples=8, deadline=None)
@given(mb=small_mb(max_n=2), iidc=small_iidc(), y0=y0s)
def test_exact_union_matches_brute_force(mb, iidc, y0):
    got = likelihood(y0, Union(mb, iidc), H3, S0, method="exact")
    want = brute_log(brute_product(brute_mb_terms(mb), brute_iidc_terms(iidc)), y0)
    assert got.log_value == pytest.approx(want, abs=1e-9)


def test_exact_matches_monte_carlo_within_its_standard_error():
    rng = np.random.default_rng(3)
    mb = MultiBernoulli(rng.uniform(0.2, 1, 4), rng.uniform(0, 8, (4, 2)), [np.eye(2)] * 4)
    iidc = IIDC([0.2, 0.5, 0.3], [0.5, 0.5], rng.uniform(0, 8, (2, 2)), [np.eye(2)] * 2)
    ppp = Poisson(1.2, [1.0], [[4.0, 4.0]], [np.eye(2)])
    for model in (mb, iidc, ppp, Union(mb, iidc)):
        mean, _ = campbell_moments(model, H3)
        ex = likelihood(mean, model, H3, S0, method="exact")
        mc = likelihood(mean, model, H3, S0, method="montecarlo", n_samples=100_000, rng=1)
        assert mc.std_error < 0.05
        assert abs(ex.log_value - mc.log_value) <= 5 * mc.std_error
    assert likelihood(mean, ppp, H3, S0, method="exact").info["truncated_mass"] < 1e-15


def test_gaussian_is_exact_when_q_is_gaussian():
    """All r_i = 1: y is a sum of Gaussians, so (9) is exact; one component: (20) is exact too."""
    mb = MultiBernoulli([1.0, 1.0], [[1.0, 2.0], [3.0, 1.0]], [np.eye(2), 2 * np.eye(2)])
    y0 = np.array([1.0, 2.0, 3.0])
    g = likelihood(y0, mb, H3, S0)
    assert g.log_value == pytest.approx(likelihood(y0, mb, H3, S0, method="exact").log_value)
    one = MultiBernoulli([1.0], [[1.0, 2.0]], [np.eye(2)])
    x = np.array([[0.0, 0.0], [1.0, 3.0]])
    want = mvn.logpdf(y0 - x @ H3.T, np.zeros(3), S0) - mvn.logpdf(
        y0, H3 @ [1.0, 2.0], S0 + H3 @ H3.T
    )
    for method in ("gaussian", "exact"):
        assert np.allclose(log_likelihood_ratio(y0, x, one, H3, S0, method=method), want)


def brute_mb_ratio(mb, y0, x):
    """(16) from the set integral: x produced by component i, the rest a subset of the others."""
    den = brute_log(brute_mb_terms(mb), y0)
    out = []
    for xi in x:
        num, dens = [], []
        for i in range(mb.n_components):
            if mb.r[i] == 0:
                continue
            lpx = math.log(mb.r[i]) + mvn.logpdf(xi, mb.means[i], mb.covs[i])
            dens.append(lpx)
            rest = mb.leave_one_out(i)
            num.append(lpx + brute_log(brute_mb_terms(rest), y0 - H3 @ xi))
        out.append(logsumexp(num) - logsumexp(dens) - den)
    return np.array(out)


@settings(max_examples=10, deadline=None)
@given(mb=small_mb(), y0=y0s, seed=st.integers(0, 1000))
def test_exact_ratio_matches_the_definition(mb, y0, seed):
    if mb.mean_cardinality == 0.0:
        return
    x = np.random.default_rng(seed).uniform(0, 6, (3, 2))
    got = log_likelihood_ratio(y0, x, mb, H3, S0, method="exact")
    assert np.allclose(got, brute_mb_ratio(mb, y0, x), atol=1e-8)


def test_exact_ratio_iidc_and_monte_carlo_ratio():
    iidc = IIDC([0.1, 0.3, 0.6], [0.5, 0.5], [[1.0, 1.0], [4.0, 2.0]], [np.eye(2)] * 2)
    y0 = np.array([2.0, 3.0, 3.5])
    x = np.array([[1.0, 1.0], [3.0, 2.0]])
    # (16) for an IIDC: Σ_k (k + 1) π(k + 1)/n̄ ∫ N(y0 − Hx − ζ) Π s over ordered k-tuples
    nbar = iidc.mean_cardinality
    reduced = IIDC(
        np.array([1 * 0.3, 2 * 0.6]) / nbar, [0.5, 0.5], [[1.0, 1.0], [4.0, 2.0]], [np.eye(2)] * 2
    )
    den = brute_log(brute_iidc_terms(iidc), y0)
    want = [brute_log(brute_iidc_terms(reduced), y0 - H3 @ xi) - den for xi in x]
    got = log_likelihood_ratio(y0, x, iidc, H3, S0, method="exact")
    assert np.allclose(got, want, atol=1e-9)
    mc = log_likelihood_ratio(y0, x, iidc, H3, S0, method="montecarlo", n_samples=200_000, rng=0)
    # numerator and denominator each have a std error below 0.01 here: 0.05 is > 3.5 sigma
    assert np.allclose(mc, want, atol=0.05)
    mb = MultiBernoulli([0.6, 0.8], [[1.0, 1.0], [4.0, 2.0]], [np.eye(2)] * 2)
    mc = log_likelihood_ratio(y0, x, mb, H3, S0, method="montecarlo", n_samples=200_000, rng=1)
    assert np.allclose(mc, log_likelihood_ratio(y0, x, mb, H3, S0, method="exact"), atol=0.05)


def test_gaussian_ratio_is_equation_20():
    rng = np.random.default_rng(0)
    mb = MultiBernoulli(rng.uniform(0.2, 1, 3), rng.uniform(0, 5, (3, 2)), [np.eye(2)] * 3)
    u = Union(mb, IIDC.uniform([0.5, 0.5], [0, 0], [5, 5]))
    y0, x = np.array([2.0, 2.5, 3.0]), rng.uniform(0, 5, (4, 2))
    for model in (mb, u):
        mq, sq = campbell_moments(model, H3)
        rm, rc = reduced_moments(model, H3, x)
        want = [
            mvn.logpdf(y0 - H3 @ xi - rm[k], np.zeros(3), S0 + rc[k]) - mvn.logpdf(y0, mq, S0 + sq)
            for k, xi in enumerate(x)
        ]
        assert np.allclose(log_likelihood_ratio(y0, x, model, H3, S0), want)


def test_montecarlo_is_seeded_and_its_std_error_is_honest():
    mb = MultiBernoulli([0.5, 0.7, 0.4], [[0, 0], [3, 1], [1, 4]], [np.eye(2)] * 3)
    y0 = np.array([1.5, 2.0, 2.0])
    a = likelihood(y0, mb, H3, S0, method="montecarlo", n_samples=2000, rng=7)
    b = likelihood(y0, mb, H3, S0, method="montecarlo", n_samples=2000, rng=7)
    assert a == b
    runs = [
        likelihood(y0, mb, H3, S0, method="montecarlo", n_samples=2000, rng=s) for s in range(40)
    ]
    spread = np.std([r.log_value for r in runs], ddof=1)
    reported = np.mean([r.std_error for r in runs])
    assert 0.6 < spread / reported < 1.6


def test_values_stay_finite_far_from_the_mass():
    mb = MultiBernoulli([0.5, 0.5], [[0, 0], [1, 1]], [np.eye(2)] * 2)
    y0 = np.array([1e4, -1e4, 1e4])
    for method in ("gaussian", "exact", "montecarlo"):
        v = likelihood(
            y0, mb, H3, S0, method=method, **({"rng": 0} if method == "montecarlo" else {})
        )
        assert np.isfinite(v.log_value) and v.log_value < -1e6
    lr = log_likelihood_ratio(y0, [[0.0, 0.0]], mb, H3, S0, method="exact")
    assert np.isfinite(lr).all()


def test_exact_budget_raises_exact_limit_error():
    mb = MultiBernoulli(np.full(5, 0.5), np.zeros((5, 2)), [np.eye(2)] * 5)
    with pytest.raises(ExactLimitError, match="max_terms = 16"):
        likelihood(np.zeros(3), mb, H3, S0, method="exact", max_terms=16)
    assert likelihood(np.zeros(3), mb, H3, S0, method="exact", max_terms=32).info["terms"] == 32
    big = IIDC(np.full(40, 1 / 40), np.ones(8), np.zeros((8, 2)), [np.eye(2)] * 8)
    with pytest.raises(ExactLimitError, match="max_terms"):
        likelihood(np.zeros(3), big, H3, S0, method="exact")


def test_exact_refuses_what_it_cannot_enumerate():
    u = IIDC.uniform([0.5, 0.5], [0, 0], [1, 1])
    with pytest.raises(ValueError, match="uniform"):
        likelihood(np.zeros(3), u, H3, S0, method="exact")
    p = MultiBernoulli.from_particles([0.5], [np.zeros((3, 2))])
    with pytest.raises(ValueError, match="particle"):
        likelihood(np.zeros(3), p, H3, S0, method="exact")
    g = FunctionMeasurement(lambda x: x @ H3.T, dy=3)
    mb = MultiBernoulli([0.5], [[0.0, 0.0]], [np.eye(2)])
    with pytest.raises(ValueError, match="linear"):
        likelihood(np.zeros(3), mb, g, S0, method="exact")


def test_function_measurement_gaussian_matches_linear_and_monte_carlo_agrees():
    """A linear g given as a callable: same Gaussian values (quadrature is exact for degree 2)."""
    mb = MultiBernoulli([0.5, 0.9], [[0, 0], [3, 1]], [np.eye(2)] * 2)
    g = FunctionMeasurement(lambda x: x @ H3.T, dy=3, dx=2)
    y0, x = np.array([1.0, 2.0, 2.0]), np.array([[0.0, 0.0], [3.0, 1.0]])
    assert likelihood(y0, mb, g, S0).log_value == pytest.approx(
        likelihood(y0, mb, H3, S0).log_value
    )
    assert np.allclose(
        log_likelihood_ratio(y0, x, mb, g, S0), log_likelihood_ratio(y0, x, mb, H3, S0)
    )
    mc = likelihood(y0, mb, g, S0, method="montecarlo", n_samples=50_000, rng=3)
    ex = likelihood(y0, mb, H3, S0, method="exact")
    assert abs(mc.log_value - ex.log_value) <= 5 * mc.std_error


def test_particle_moments_option_is_the_papers_estimator():
    mb = MultiBernoulli([0.5, 0.9], [[0, 0], [3, 1]], [np.eye(2)] * 2)
    y0 = np.array([1.0, 2.0, 2.0])
    closed = likelihood(y0, mb, H3, S0).log_value
    nv = likelihood(y0, mb, H3, S0, moment_particles=10_000, rng=0).log_value
    assert nv != closed and abs(nv - closed) < 0.05
    lr = log_likelihood_ratio(y0, [[0.0, 0.0]], mb, H3, S0, moment_particles=1000, rng=0)
    assert np.isfinite(lr).all()


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"y0": [1.0, 2.0]}, "y0.*dimension mismatch"),
        ({"y0": [1.0, np.nan, 0.0]}, "y0"),
        ({"y0": [1.0, 1j, 0.0]}, "y0"),
        ({"y0": [True, 0.0, 0.0]}, "y0"),
        ({"noise_cov": -np.eye(3)}, "noise_cov.*positive definite"),
        ({"noise_cov": np.eye(2)}, "noise_cov.*dimension mismatch"),
        ({"H": np.eye(3)}, "dimension mismatch"),
        ({"method": "magic"}, "method"),
        ({"model": "mb"}, "model"),
        ({"method": "montecarlo", "n_samples": 1}, "n_samples"),
        ({"method": "montecarlo", "rng": "seed"}, "rng"),
        ({"method": "exact", "max_terms": 0}, "max_terms"),
        ({"bogus": 1}, "bogus"),
        ({"method": "exact", "bogus": 1}, "bogus"),
        ({"method": "montecarlo", "bogus": 1}, "bogus"),
    ],
)
def test_bad_input_names_the_argument(kwargs, match):
    args = {
        "y0": np.zeros(3),
        "model": MultiBernoulli([0.5], [[0.0, 0.0]], [np.eye(2)]),
        "H": H3,
        "noise_cov": S0,
    }
    opts = {k: v for k, v in kwargs.items() if k not in args}
    args |= {k: v for k, v in kwargs.items() if k in args}
    with pytest.raises(ValueError, match=match):
        likelihood(args["y0"], args["model"], args["H"], args["noise_cov"], **opts)


def test_ratio_bad_states():
    mb = MultiBernoulli([0.5], [[0.0, 0.0]], [np.eye(2)])
    with pytest.raises(ValueError, match="x"):
        log_likelihood_ratio(np.zeros(3), np.zeros((2, 3)), mb, H3, S0)
    with pytest.raises(ValueError, match="part"):
        log_likelihood_ratio(np.zeros(3), np.zeros((2, 2)), mb, H3, S0, part=0)
