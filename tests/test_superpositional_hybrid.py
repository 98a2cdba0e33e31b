"""The hybrid likelihood of superpositional sensors (jointtrack.superpositional.hybrid).

Ground truth: the exact Gaussian-mixture enumeration ("exact") and, for a
uniform-box part, closed forms / numerical integration / Rao-Blackwellised
Monte Carlo with its standard error.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import integrate
from scipy.stats import norm, poisson

from jointtrack.experiments.nannuru import union_truth
from jointtrack.superpositional import (
    IIDC,
    MultiBernoulli,
    Poisson,
    Union,
    likelihood,
    log_likelihood_ratio,
)
from jointtrack.superpositional import hybrid as hy
from superpositional_helpers import H3 as H
from superpositional_helpers import S0, assert_option_rejected

coords = st.floats(0.0, 10.0, allow_nan=False)


@st.composite
def mb_case(draw, max_n=5):
    n = draw(st.integers(1, max_n))
    r = np.array(draw(st.lists(st.floats(0.0, 1.0), min_size=n, max_size=n)))
    means = np.array(draw(st.lists(st.tuples(coords, coords), min_size=n, max_size=n)))
    scales = np.array(draw(st.lists(st.floats(0.3, 3.0), min_size=n, max_size=n)))
    covs = scales[:, None, None] * np.eye(2)
    shift = np.array(draw(st.tuples(coords, coords)))
    return MultiBernoulli(r, means, covs), H @ (means.sum(axis=0) + shift - 5.0)


@st.composite
def iidc_case(draw):
    K = draw(st.integers(1, 3))
    n_max = draw(st.integers(0, 5))
    pmf = np.array(draw(st.lists(st.floats(0.01, 1.0), min_size=n_max + 1, max_size=n_max + 1)))
    pmf /= pmf.sum()
    w = np.array(draw(st.lists(st.floats(0.1, 1.0), min_size=K, max_size=K)))
    means = np.array(draw(st.lists(st.tuples(coords, coords), min_size=K, max_size=K)))
    model = IIDC(pmf, w, means, np.broadcast_to(np.eye(2), (K, 2, 2)))
    return model, H @ np.array(draw(st.tuples(coords, coords))) * 2


def assert_hybrid_is_exact(model, y0, budget):
    """With the full mixture within ``budget``, hybrid reports and returns the exact value."""
    exact = likelihood(y0, model, H, S0, method="exact").log_value
    res = likelihood(y0, model, H, S0, method="hybrid", budget=budget)
    assert res.info["exact"]
    assert res.log_value == pytest.approx(exact, abs=1e-9)


@settings(max_examples=30, deadline=None)
@given(mb_case())
def test_equals_exact_within_budget_multi_bernoulli(case):
    assert_hybrid_is_exact(*case, budget=64)


@settings(max_examples=30, deadline=None)
@given(iidc_case())
def test_equals_exact_within_budget_iidc(case):
    assert_hybrid_is_exact(*case, budget=10_000)


def test_union_and_poisson_exact_within_budget():
    mb = MultiBernoulli([0.3, 0.8], [[0, 0], [4, 1]], [np.eye(2)] * 2)
    ppp = Poisson(1.2, [0.4, 0.6], [[2.0, 2.0], [5.0, 0.0]], [np.eye(2)] * 2)
    iidc = IIDC([0.2, 0.5, 0.3], [1.0], [[1.0, 3.0]], [2 * np.eye(2)])
    model = Union(mb, ppp, iidc)
    y0 = H @ np.array([8.0, 5.0])
    exact = likelihood(y0, model, H, S0, method="exact").log_value
    res = likelihood(y0, model, H, S0, method="hybrid", budget=100_000)
    assert res.log_value == pytest.approx(exact, abs=1e-9)


def test_budget_one_is_the_gaussian_approximation():
    mb = MultiBernoulli([0.3, 0.8, 0.6], [[0, 0], [4, 1], [1, 7]], [np.eye(2)] * 3)
    y0 = H @ np.array([5.0, 8.0])
    gauss = likelihood(y0, mb, H, S0).log_value
    assert likelihood(y0, mb, H, S0, method="hybrid", budget=1).log_value == pytest.approx(gauss)


def test_error_falls_with_budget():
    """Table I's setup, n0 = 5: the error shrinks (monotone-ish) as the budget grows."""
    rng = np.random.default_rng(3)
    pmf = poisson.pmf(np.arange(16), 5)
    pmf /= pmf.sum()
    errs = {b: [] for b in (1, 16, 128, 1024)}
    for _ in range(4):
        means = rng.uniform(0, 20, (5, 2))
        model = IIDC(pmf, np.ones(5), means, np.broadcast_to(np.eye(2), (5, 2, 2)))
        y0 = H @ means.sum(axis=0)
        exact = likelihood(y0, model, H, S0, method="exact").log_value
        for b in errs:
            val = likelihood(y0, model, H, S0, method="hybrid", budget=b).log_value
            errs[b].append(abs(math.expm1(val - exact)))
    mean = {b: float(np.mean(v)) for b, v in errs.items()}
    assert mean[1024] <= mean[128] + 1e-3 <= mean[1] + 2e-3
    assert mean[1024] < 0.05


def test_ratio_equals_exact_within_budget():
    model = MultiBernoulli([0.3, 0.8, 0.6, 0.95], [[0, 0], [4, 1], [1, 7], [9, 9]], [np.eye(2)] * 4)
    rng = np.random.default_rng(0)
    x = model.means[rng.integers(0, 4, 50)] + rng.standard_normal((50, 2))
    y0 = H @ model.means.sum(axis=0)
    exact = log_likelihood_ratio(y0, x, model, H, S0, method="exact")
    hyb = log_likelihood_ratio(y0, x, model, H, S0, method="hybrid")
    np.testing.assert_allclose(hyb, exact, atol=1e-9)
    ppp = Poisson(1.0, [1.0], [[3.0, 3.0]], [np.eye(2)])
    union = Union(model, ppp)
    exact = log_likelihood_ratio(y0, x, union, H, S0, method="exact", part=0)
    hyb = log_likelihood_ratio(y0, x, union, H, S0, method="hybrid", part=0, budget=10_000)
    np.testing.assert_allclose(hyb, exact, atol=1e-9)


@settings(max_examples=40, deadline=None)
@given(st.integers(1, 4), st.floats(-5.0, 30.0), st.floats(0.05, 3.0))
def test_uniform_sum_density_against_numerical_convolution(n, x, sd):
    """Σ of n uniforms on [1, 3] plus N(0, sd²): closed form vs numerical integration."""
    lo, w = 1.0, 2.0
    got = hy._uniform_sum_density(x, n, lo, w, sd)
    if n == 1:
        want = (norm.cdf((x - lo) / sd) - norm.cdf((x - lo - w) / sd)) / w
    else:
        # density of the unsmoothed sum (Irwin-Hall, sd = 0) convolved numerically
        def f(s):
            return hy._uniform_sum_density(s, n, lo, w, 0.0) * norm.pdf(x - s, scale=sd)

        knots = [n * lo + k * w for k in range(n + 1)]
        want = integrate.quad(f, n * lo, n * (lo + w), points=knots, limit=200)[0]
    assert got == pytest.approx(want, rel=1e-6, abs=1e-12)


def test_uniform_box_term_against_quadrature_2d():
    """The 2-D uniform expectation against scipy's dblquad (n = 1 and 2, correlated)."""
    cov = np.array([[1.5, 0.6], [0.6, 0.8]])
    lo, w = np.array([0.0, -1.0]), np.array([3.0, 4.0])
    inv = np.linalg.inv(cov)
    for n, mu in ((1, np.array([2.9, 0.5])), (2, np.array([3.0, 1.0]))):

        def f(b, a, mu=mu, n=n):
            d = np.array([a, b]) - mu
            dens = np.exp(-0.5 * d @ inv @ d) / (2 * np.pi * np.sqrt(np.linalg.det(cov)))
            return (
                dens
                * hy._uniform_sum_density(a, n, lo[0], w[0], 0.0)
                * (hy._uniform_sum_density(b, n, lo[1], w[1], 0.0))
            )

        want = integrate.dblquad(f, n * lo[0], n * (lo[0] + w[0]), n * lo[1], n * (lo[1] + w[1]))[0]
        got = hy._uniform_sum_expectation(mu, cov, n, lo, w, hy._GL_NODES, hy._GL_WEIGHTS)
        assert got == pytest.approx(want, rel=2e-3)


def test_union_with_uniform_part_against_monte_carlo():
    """Table III's kind of model: within 5 % + 3 s.e. of a Rao-Blackwellised Monte Carlo.

    (:func:`jointtrack.experiments.nannuru.union_truth`: the multi-Bernoulli part
    exact, 4000 uniform sums per cardinality; it uses the same H and Σ0.)
    """
    mb = MultiBernoulli([0.5, 0.9, 0.7], [[3, 4], [12, 15], [17, 6]], [np.eye(2)] * 3)
    pmf = np.full(3, 1.0 / 3.0)
    model = Union(mb, IIDC.uniform(pmf, [0.0, 0.0], [20.0, 20.0]))
    y0 = H @ mb.means.sum(axis=0)
    log_mc, rel_se = union_truth(mb, pmf, y0, 4000, np.random.default_rng(5))
    got = likelihood(y0, model, H, S0, method="hybrid").log_value
    assert abs(math.expm1(got - log_mc)) <= 0.05 + 3 * rel_se


@pytest.mark.parametrize(
    ("option", "value", "match"),
    [
        ("budget", 0, "budget"),
        ("budget", -3, "budget"),
        ("budget", 2.5, "budget"),
        ("budget", True, "budget"),
        ("remainder", "median", "remainder"),
        ("max_iter", 0, "max_iter"),
    ],
)
def test_bad_options(option, value, match):
    assert_option_rejected("hybrid", option, value, match)


def test_uniform_box_without_quadrature_falls_back():
    """dx = 3 (no quadrature): leaves by their moments, within 25 % of a large Monte Carlo.

    (The documented accuracy of this fallback: the quadrature is what makes
    Table III's uniform part accurate.)
    """
    H3 = np.array([[1.0, 0.2, 0.0], [0.0, 1.0, 0.3], [0.1, 0.0, 1.0]])
    model = IIDC.uniform([0.3, 0.4, 0.3], [0.0, 0.0, 0.0], [4.0, 4.0, 4.0])
    y0 = H3 @ np.array([3.0, 2.0, 2.5])
    noise = 0.5 * np.eye(3)
    res = likelihood(y0, model, H3, noise, method="hybrid")
    assert not res.info["box_quadrature"]
    mc = likelihood(y0, model, H3, noise, method="montecarlo", n_samples=200_000, rng=2)
    assert abs(res.log_value - mc.log_value) < math.log(1.25) + 3 * mc.std_error
    sp_leaves = likelihood(y0, model, H3, noise, method="hybrid", remainder="saddlepoint")
    assert np.isfinite(sp_leaves.log_value)
