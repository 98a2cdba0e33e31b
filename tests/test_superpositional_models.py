"""RFS models of ``jointtrack.superpositional.models``: cardinality moments, samplers, bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.stats import poisson

from jointtrack.superpositional import (
    IIDC,
    FunctionMeasurement,
    LinearMeasurement,
    MultiBernoulli,
    Poisson,
    Union,
    as_measurement,
    sample_superposition,
)
from jointtrack.superpositional.models import reduced_mixture
from superpositional_helpers import H3


def truncated_poisson(n0, n_max=15):
    pmf = poisson.pmf(np.arange(n_max + 1), n0)
    return pmf / pmf.sum()


def test_paper_truncated_poisson_cardinality_moments():
    """§B: Poisson(8) truncated at 15 and renormalised: n̄ = 7.93, G₂ = 62.3 (≠ n̄²)."""
    m = IIDC(truncated_poisson(8), [1.0], [[0.0, 0.0]], [np.eye(2)])
    assert round(m.mean_cardinality, 2) == 7.93
    assert round(m.second_factorial_moment, 1) == 62.3
    assert m.second_factorial_moment != pytest.approx(m.mean_cardinality**2, rel=1e-3)


@settings(max_examples=25, deadline=None)
@given(r=st.lists(st.floats(0.0, 1.0), min_size=1, max_size=5))
def test_multibernoulli_cardinality_moments_match_samples(r):
    mb = MultiBernoulli(r, np.zeros((len(r), 1)), np.ones((len(r), 1, 1)))
    counts = np.array([len(s) for s in mb.sample(20_000, rng=1)], dtype=float)
    # n̄ = Σr, G₂ = (Σr)² − Σr²; tolerance 5 standard errors, plus n²/N for r near 0 or 1
    # (where a sample variance of 0 says nothing about the error)
    floor = len(r) ** 2 / counts.size
    se1 = math.sqrt(sum(p * (1 - p) for p in r) / counts.size)
    assert abs(counts.mean() - mb.mean_cardinality) <= 5 * se1 + floor
    f2 = counts * (counts - 1)
    assert abs(f2.mean() - mb.second_factorial_moment) <= 5 * f2.std() / math.sqrt(f2.size) + floor


def test_union_cardinality_moments_match_samples():
    mb = MultiBernoulli([0.3, 0.8], [[0.0], [1.0]], [[[1.0]], [[1.0]]])
    iidc = IIDC([0.2, 0.3, 0.5], [1.0], [[0.0]], [[[1.0]]])
    ppp = Poisson(1.5, [1.0], [[0.0]], [[[1.0]]])
    u = Union(mb, Union(iidc, ppp))
    assert len(u.parts) == 3  # nested unions are flattened
    counts = np.array([len(s) for s in u.sample(40_000, rng=2)], dtype=float)
    assert abs(counts.mean() - u.mean_cardinality) <= 5 * counts.std() / 200
    f2 = counts * (counts - 1)
    assert abs(f2.mean() - u.second_factorial_moment) <= 5 * f2.std() / 200


def test_sample_superposition_is_seeded_and_matches_set_sampler():
    rng = np.random.default_rng(0)
    mb = MultiBernoulli([0.4, 0.9], rng.uniform(0, 5, (2, 2)), [np.eye(2)] * 2)
    iidc = IIDC.uniform([0.25, 0.25, 0.5], [0, 0], [4, 4])
    u = Union(mb, iidc)
    a = sample_superposition(u, H3, 1000, rng=5)
    b = sample_superposition(u, H3, 1000, rng=5)
    assert a.shape == (1000, 3) and np.array_equal(a, b)
    # the same law as summing H x over sampled sets (means within 5 standard errors)
    sets = u.sample(20_000, rng=6)
    y_sets = np.array([H3 @ s.sum(axis=0) if len(s) else np.zeros(3) for s in sets])
    y_fast = sample_superposition(u, H3, 20_000, rng=7)
    se = np.sqrt(y_sets.var(0) / 20_000 + y_fast.var(0) / 20_000)
    assert np.all(np.abs(y_sets.mean(0) - y_fast.mean(0)) <= 5 * se)


def test_particle_models_sample_their_particles():
    parts = [np.array([[1.0, 0.0], [2.0, 0.0]]), np.array([[0.0, 3.0]])]
    mb = MultiBernoulli.from_particles([1.0, 1.0], parts, [np.array([1.0, 0.0]), np.array([2.0])])
    y = sample_superposition(mb, np.eye(2), 10, rng=0)
    assert np.allclose(y, [1.0, 3.0])  # only particle (1, 0) has weight
    ppp = Poisson.from_particles(2.0, [[1.0, 1.0]], [1.0])
    assert ppp.mean_count == 2.0 and ppp.second_factorial_moment == 4.0
    iidc = IIDC.from_particles([0.0, 1.0], [[1.0, 1.0], [2.0, 2.0]], [1.0, 1.0])
    s = iidc.sample(3, rng=0)
    assert all(len(w) == 1 for w in s)


def test_models_are_immutable():
    mb = MultiBernoulli([0.5], [[0.0]], [[[1.0]]])
    with pytest.raises(AttributeError):
        mb.r = np.array([0.9])
    with pytest.raises(ValueError):
        mb.r[0] = 0.9  # read-only array
    with pytest.raises(AttributeError):
        LinearMeasurement([[1.0]]).H = np.eye(2)


def test_reduced_mixture_iidc_and_multibernoulli():
    iidc = IIDC([0.1, 0.2, 0.7], [1.0], [[0.0]], [[[1.0]]])
    lw, subs = reduced_mixture(iidc, np.zeros((2, 1)))
    # π*(n) = (n + 1) π(n + 1) / n̄
    nbar = 0.2 + 1.4
    assert np.allclose(subs[0].cardinality_pmf, [0.2 / nbar, 1.4 / nbar])
    assert np.allclose(lw, 0.0)
    mb = MultiBernoulli([0.5, 1.0], [[0.0], [3.0]], [[[1.0]], [[1.0]]])
    lw, subs = reduced_mixture(mb, np.array([[0.0], [3.0]]))
    d = np.array(
        [
            [0.5 * math.exp(0.0), 1.0 * math.exp(-4.5)],
            [0.5 * math.exp(-4.5), 1.0 * math.exp(0.0)],
        ]
    )
    assert np.allclose(np.exp(lw), d / d.sum(1, keepdims=True))
    assert [s.n_components for s in subs] == [1, 1]
    assert subs[0].r.tolist() == [1.0] and subs[1].r.tolist() == [0.5]


# ----------------------------------------------------------------------------- bad input


def good():
    return {"r": [0.5, 0.6], "means": [[0.0, 0.0], [1.0, 1.0]], "covs": [np.eye(2), np.eye(2)]}


@pytest.mark.parametrize(
    ("change", "name"),
    [
        ({"r": [0.5, 1.2]}, "r"),
        ({"r": [-0.1, 0.2]}, "r"),
        ({"r": [0.5, float("nan")]}, "r"),
        ({"r": [0.5, 0.5j]}, "r"),
        ({"r": [True, 0.5]}, "r"),
        ({"r": [0.5]}, "means"),
        ({"means": [[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]]}, "covs"),
        ({"covs": [np.eye(2), [[1.0, 2.0], [2.0, 1.0]]]}, "covs[1]"),
        ({"covs": [np.eye(2), [[1.0, 0.5], [0.0, 1.0]]]}, "covs[1]"),
        ({"covs": [np.eye(2), np.full((2, 2), np.inf)]}, "covs"),
        ({"means": [[0.0, np.nan], [1.0, 1.0]]}, "means"),
    ],
)
def test_multibernoulli_bad_input_names_the_argument(change, name):
    kw = good() | change
    with pytest.raises(ValueError, match=name.replace("[", r"\[").replace("]", r"\]")):
        MultiBernoulli(kw["r"], kw["means"], kw["covs"])


@settings(max_examples=30, deadline=None)
@given(bad=st.one_of(st.floats(-10, -1e-9), st.floats(1 + 1e-9, 10)))
def test_existence_outside_unit_interval_is_rejected(bad):
    with pytest.raises(ValueError, match=r"r\[1\].*outside \[0, 1\]"):
        MultiBernoulli([0.5, bad], [[0.0], [1.0]], [[[1.0]], [[1.0]]])


@settings(max_examples=30, deadline=None)
@given(
    pmf=st.lists(st.floats(0.0, 1.0), min_size=1, max_size=6).filter(
        lambda p: abs(math.fsum(p) - 1.0) > 1e-6
    )
)
def test_pmf_not_summing_to_one_is_rejected(pmf):
    with pytest.raises(ValueError, match="cardinality_pmf"):
        IIDC(pmf, [1.0], [[0.0]], [[[1.0]]])


def test_iidc_poisson_union_bad_input():
    with pytest.raises(ValueError, match="cardinality_pmf.*negative"):
        IIDC([1.5, -0.5], [1.0], [[0.0]], [[[1.0]]])
    with pytest.raises(ValueError, match="weights"):
        IIDC([1.0], [1.0, -1.0], [[0.0], [1.0]], [[[1.0]], [[1.0]]])
    with pytest.raises(ValueError, match="weights.*dimension mismatch"):
        IIDC([1.0], [1.0], [[0.0], [1.0]], [[[1.0]], [[1.0]]])
    with pytest.raises(ValueError, match="mean_count"):
        Poisson(-1.0, [1.0], [[0.0]], [[[1.0]]])
    with pytest.raises(ValueError, match="mean_count"):
        Poisson(True, [1.0], [[0.0]], [[[1.0]]])
    with pytest.raises(ValueError, match="high"):
        IIDC.uniform([1.0], [0.0, 0.0], [1.0, 0.0])
    with pytest.raises(ValueError, match="dimension"):
        Union(MultiBernoulli([0.5], [[0.0]], [[[1.0]]]), IIDC.uniform([1.0], [0, 0], [1, 1]))
    with pytest.raises(ValueError, match="parts"):
        Union("not a model")
    with pytest.raises(ValueError, match="particles"):
        MultiBernoulli.from_particles([0.5, 0.5], [np.zeros((3, 2))])


def test_measurement_bad_input():
    with pytest.raises(ValueError, match="H"):
        as_measurement([[1.0, np.nan]])
    with pytest.raises(ValueError, match="H"):
        as_measurement([1.0, 2.0])
    with pytest.raises(ValueError, match="dimension mismatch"):
        as_measurement(H3, dx=3)
    with pytest.raises(ValueError, match="FunctionMeasurement"):
        as_measurement(lambda x: x)
    g = FunctionMeasurement(lambda x: x[..., :1] * np.nan, dy=1)
    with pytest.raises(ValueError, match="non-finite"):
        g(np.zeros((2, 2)))
    g = FunctionMeasurement(lambda x: x, dy=1)
    with pytest.raises(ValueError, match="shape"):
        g(np.zeros((2, 2)))
    with pytest.raises(ValueError, match="n_samples"):
        sample_superposition(MultiBernoulli([0.5], [[0.0]], [[[1.0]]]), [[1.0]], -1)
