"""Campbell moments (4)–(7) and the reduced moments of (17) against Monte Carlo."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from jointtrack.superpositional import (
    IIDC,
    FunctionMeasurement,
    MultiBernoulli,
    Poisson,
    Union,
    campbell_moments,
    leave_one_out_moments,
    reduced_moments,
    sample_superposition,
)
from jointtrack.superpositional.models import reduced_mixture
from superpositional_helpers import H3

N_MC = 60_000


def assert_moments_match(samples, mean, cov, k=5.0):
    """Mean and covariance within k Monte Carlo standard errors (estimated from the samples).

    The 1e-6 floor covers mixture members of weight ~1e-9 (a drawn r near 0) that
    no sample picks: their share of the moments is below it.
    """
    n = samples.shape[0]
    c = samples - samples.mean(0)
    se_mean = np.sqrt(samples.var(0) / n)
    assert np.all(np.abs(samples.mean(0) - mean) <= k * se_mean + 1e-6 * (1 + np.abs(mean))), (
        samples.mean(0),
        mean,
    )
    prod = c[:, :, None] * c[:, None, :]
    se_cov = prod.std(0) / math.sqrt(n)
    emp = np.cov(samples.T).reshape(cov.shape)
    assert np.all(np.abs(emp - cov) <= k * se_cov + 1e-6 * (1 + np.abs(cov))), (emp, cov)


unit = st.floats(0.0, 1.0)
coord = st.floats(-5.0, 5.0)


@st.composite
def gaussians(draw, n, dx=2):
    means = np.array([[draw(coord) for _ in range(dx)] for _ in range(n)])
    covs = []
    for _ in range(n):
        a = np.array([[draw(st.floats(-1, 1)) for _ in range(dx)] for _ in range(dx)])
        covs.append(a @ a.T + draw(st.floats(0.1, 2.0)) * np.eye(dx))
    return means, np.array(covs)


@st.composite
def multibernoullis(draw, max_n=4):
    n = draw(st.integers(1, max_n))
    r = [draw(unit) for _ in range(n)]
    means, covs = draw(gaussians(n))
    return MultiBernoulli(r, means, covs)


@st.composite
def iidcs(draw):
    pmf = np.array([draw(st.floats(0.0, 1.0)) for _ in range(draw(st.integers(1, 5)))]) + 1e-3
    k = draw(st.integers(1, 3))
    means, covs = draw(gaussians(k))
    w = [draw(st.floats(0.1, 1.0)) for _ in range(k)]
    return IIDC(pmf / pmf.sum(), w, means, covs)


@settings(max_examples=6, deadline=None)
@given(model=st.one_of(multibernoullis(), iidcs()), seed=st.integers(0, 2**32 - 1))
def test_campbell_moments_match_monte_carlo(model, seed):
    mean, cov = campbell_moments(model, H3)
    assert_moments_match(sample_superposition(model, H3, N_MC, rng=seed), mean, cov)


@settings(max_examples=4, deadline=None)
@given(a=multibernoullis(max_n=2), b=iidcs(), lam=st.floats(0.1, 3.0))
def test_union_moments_add_and_match_monte_carlo(a, b, lam):
    c = Poisson(lam, [1.0], [[1.0, -1.0]], [np.eye(2)])
    u = Union(a, b, c)
    mean, cov = campbell_moments(u, H3)
    parts = [campbell_moments(p, H3) for p in (a, b, c)]
    assert np.allclose(mean, sum(p[0] for p in parts))
    assert np.allclose(cov, sum(p[1] for p in parts))
    assert_moments_match(sample_superposition(u, H3, N_MC, rng=3), mean, cov)


def test_iidc_moments_closed_form_uses_g2():
    """Σ_Q = n̄ m₂ + (G₂ − n̄²) m₁m₁ᵀ: with G₂ ≠ n̄² the Poisson formula would be wrong."""
    pmf = np.array([0.0, 0.0, 1.0])  # exactly two points: G₂ = 2, n̄ = 2
    m = IIDC(pmf, [1.0], [[3.0]], [[[1.0]]])
    mean, cov = campbell_moments(m, [[1.0]])
    assert mean.tolist() == [6.0] and cov.tolist() == [[2.0]]  # two iid N(3, 1)


def test_uniform_and_particle_densities():
    iidc = IIDC.uniform([0.1, 0.4, 0.5], [0.0, 0.0], [20.0, 20.0])
    mean, cov = campbell_moments(iidc, H3)
    assert_moments_match(sample_superposition(iidc, H3, N_MC, rng=1), mean, cov)
    rng = np.random.default_rng(0)
    parts = [rng.normal(size=(50, 2)), rng.normal(3.0, 1.0, size=(30, 2))]
    w = [rng.uniform(size=50), rng.uniform(size=30)]
    mb = MultiBernoulli.from_particles([0.3, 0.7], parts, w)
    mean, cov = campbell_moments(mb, H3)
    assert_moments_match(sample_superposition(mb, H3, N_MC, rng=2), mean, cov)


def test_function_measurement_quadrature_matches_monte_carlo():
    sensors = np.array([[0.0, 0.0], [5.0, 5.0]])

    def amplitude(x):
        d = np.linalg.norm(x[..., None, :] - sensors, axis=-1)
        return 10.0 / (d + 1.0)

    g = FunctionMeasurement(amplitude, dy=2)
    mb = MultiBernoulli([0.6, 0.9], [[1.0, 2.0], [4.0, 3.0]], [0.5 * np.eye(2)] * 2)
    mean, cov = campbell_moments(mb, g)
    assert_moments_match(sample_superposition(mb, g, N_MC, rng=4), mean, cov)
    # a linear g given as a function gives the closed-form moments (quadrature exact for degree 2)
    glin = FunctionMeasurement(lambda x: x @ H3.T, dy=3)
    a, b = campbell_moments(mb, glin), campbell_moments(mb, H3)
    assert np.allclose(a[0], b[0]) and np.allclose(a[1], b[1])


def test_leave_one_out_moments_are_the_moments_of_the_smaller_set():
    rng = np.random.default_rng(1)
    mb = MultiBernoulli(rng.uniform(size=4), rng.uniform(0, 5, (4, 2)), [np.eye(2)] * 4)
    means, covs = leave_one_out_moments(mb, H3)
    for i in range(4):
        m, c = campbell_moments(mb.leave_one_out(i), H3)
        assert np.allclose(means[i], m) and np.allclose(covs[i], c)


def _sample_reduced(model, x, n, rng):
    """Samples of y* ~ Q^{*x}: pick a member of the reduced mixture, then sample its sets."""
    lw, subs = reduced_mixture(model, x[None])
    pick = rng.choice(len(subs), size=n, p=np.exp(lw[0]) / np.exp(lw[0]).sum())
    y = np.zeros((n, 3))
    for k, s in enumerate(subs):
        idx = np.flatnonzero(pick == k)
        y[idx] = sample_superposition(s, H3, idx.size, rng)
    return y


@settings(max_examples=5, deadline=None)
@given(model=st.one_of(multibernoullis(), iidcs()), xs=st.lists(coord, min_size=2, max_size=2))
def test_reduced_moments_match_monte_carlo_of_the_reduced_set(model, xs):
    x = np.array(xs)
    # a mixture member with weight in (0, 20/N) is almost never sampled, yet it moves the
    # moments by up to its weight times its scale: Monte Carlo cannot check such cases
    w = np.exp(reduced_mixture(model, x[None])[0][0])
    assume(np.all((w == 0) | (w > 20 / N_MC)))
    mean, cov = reduced_moments(model, H3, x[None])
    y = _sample_reduced(model, x, N_MC, np.random.default_rng(0))
    assert_moments_match(y, mean[0], cov[0])


def test_reduced_moments_of_union_mix_the_parts_and_part_reduces_one():
    mb = MultiBernoulli([0.5, 0.9], [[0.0, 0.0], [3.0, 0.0]], [np.eye(2)] * 2)
    iidc = IIDC([0.3, 0.3, 0.4], [1.0], [[1.5, 0.0]], [np.eye(2)])
    u = Union(mb, iidc)
    x = np.array([1.0, 0.0])
    mean, cov = reduced_moments(u, H3, x[None])
    assert_moments_match(_sample_reduced(u, x, N_MC, np.random.default_rng(1)), mean[0], cov[0])
    # part=0: reduce only the multi-Bernoulli part (the report's A in (17))
    m0, c0 = reduced_moments(u, H3, x[None], part=0)
    rm, rc = reduced_moments(mb, H3, x[None])
    im, ic = campbell_moments(iidc, H3)
    assert np.allclose(m0[0], rm[0] + im) and np.allclose(c0[0], rc[0] + ic)


def test_reduced_moments_agree_with_palm_kernel_estimate():
    """Independent of the derivation: Campbell–Mecke, E Σ_{ξ∈Ξ} k(ξ − x) φ(Ξ∖ξ) ≈ D(x) E*[φ]."""
    mb = MultiBernoulli([0.4, 0.8, 0.6], [[0.0], [1.0], [-1.0]], [[[1.0]], [[0.5]], [[1.0]]])
    iidc = IIDC([0.2, 0.3, 0.5], [0.5, 0.5], [[0.0], [2.0]], [[[1.0]], [[1.0]]])
    H = np.array([[1.0], [2.0]])
    x0, h = 0.3, 0.03
    for model in (mb, iidc):
        rng = np.random.default_rng(9)
        sets = model.sample(300_000, rng)
        ys = []
        for s in sets:
            pts = s[:, 0]
            near = np.flatnonzero(np.abs(pts - x0) < h)
            for j in near:
                ys.append(H @ np.delete(pts, j)[None].sum(axis=1) if pts.size > 1 else np.zeros(2))
        y = np.array(ys)
        mean, cov = reduced_moments(model, H, [[x0]])
        # kernel bias O(h²) is far below the Monte Carlo error of ~10⁴ points
        assert_moments_match(y, mean[0], cov[0])


def test_reduced_moments_bad_input():
    mb = MultiBernoulli([0.5], [[0.0, 0.0]], [np.eye(2)])
    with pytest.raises(ValueError, match="x"):
        reduced_moments(mb, H3, [[0.0, 0.0, 0.0]])
    with pytest.raises(ValueError, match="x"):
        reduced_moments(mb, H3, [[np.nan, 0.0]])
    with pytest.raises(ValueError, match="part"):
        reduced_moments(mb, H3, [[0.0, 0.0]], part=0)
    with pytest.raises(ValueError, match="MultiBernoulli"):
        leave_one_out_moments(IIDC([1.0], [1.0], [[0.0, 0.0]], [np.eye(2)]), H3)
    parts = MultiBernoulli.from_particles([0.5], [np.zeros((3, 2))])
    with pytest.raises(ValueError, match="particle"):
        reduced_moments(parts, H3, [[0.0, 0.0]])
    with pytest.raises(ValueError, match="model"):
        campbell_moments("mb", H3)
