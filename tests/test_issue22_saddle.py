"""Issue 22 (saddle, superpositional): exact paths against rational references at any magnitude.

The property tests draw the magnitudes that found the defects: coefficients from
subnormal to 1e300 and exact zeros, Poisson means up to 1e6.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st
from scipy.special import logsumexp
from scipy.stats import norm, poisson

from brute import log_fraction, mixed_derivative_fraction
from jointtrack.saddle import (
    ERROR_BOUNDS,
    ExactRangeError,
    SaddlePointError,
    jpda_coefficients,
    jpda_log_weights,
    log_mixed_derivative,
    saddle_point,
)
from jointtrack.superpositional import (
    MultiBernoulli,
    Poisson,
    Union,
    likelihood,
    log_likelihood_ratio,
)

SETTINGS = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])

# --------------------------------------------------------------------------- strategies

#: a positive float anywhere from the smallest subnormal to 1e300, log-uniformly
positive = st.builds(
    lambda m, e: float(m * 10.0**e),
    st.floats(1.0, 9.99),
    st.integers(-323, 299),
).filter(lambda x: 0.0 < x < math.inf)
#: a coefficient: those magnitudes, exact zeros, and plain values
coefficient = st.one_of(st.just(0.0), st.just(1.0), st.floats(0.0, 1.0), positive)


@st.composite
def problems(draw, max_k=3, max_m=3):
    M = draw(st.integers(1, max_m))
    K = draw(st.integers(1, max_k))
    a = draw(st.lists(st.one_of(positive, st.floats(1e-3, 1.0)), min_size=M, max_size=M))
    F = draw(
        st.lists(st.lists(coefficient, min_size=M + 1, max_size=M + 1), min_size=K, max_size=K)
    )
    return np.array(a), np.array(F, dtype=float)


# --------------------------------------------------------------------------- references


brute_I = mixed_derivative_fraction  # exact rational ∂^M Ψ (tests/brute.py)


def _span(a, F) -> float:
    """Widest spread (nats) of the ratios f_km/a_m and f_k0 within one factor."""
    with np.errstate(divide="ignore"):
        L = np.concatenate([np.log(F[:, :1]), np.log(F[:, 1:]) - np.log(a)[None]], axis=1)
    L = np.where(np.isfinite(L), L, np.nan)
    with np.errstate(invalid="ignore"):
        spans = np.nanmax(L, axis=1) - np.nanmin(L, axis=1)
    return float(np.nanmax(spans, initial=0.0))


# --------------------------------------------------------------------------- item 5


def test_jpda_weight_of_a_measurement_another_target_holds_almost_surely():
    # issue 22 item 5: 1 − P.sum(0) cancelled to 0, then was divided by a tiny a_m
    got = jpda_log_weights(0.0, [1e-20], [[1e-30, 1.0], [0.5, 0.5]], [[1.0, 1.0]])
    np.testing.assert_allclose(got, [0.0, 0.0], atol=1e-15)


@st.composite
def jpda_problems(draw):
    """(a, b, C): clutter terms, L particles' own factors, the other targets' factors."""
    M = draw(st.integers(1, 3))
    row = st.lists(coefficient, min_size=M + 1, max_size=M + 1)
    a = draw(st.lists(st.one_of(positive, st.floats(1e-3, 1.0)), min_size=M, max_size=M))
    b = draw(st.lists(row, min_size=1, max_size=3))
    C = draw(st.lists(row, min_size=0, max_size=2))
    return np.array(a), np.array(b, dtype=float), np.array(C, dtype=float).reshape(-1, M + 1)


@SETTINGS
@example(problem=(np.array([1e-20]), np.array([[1e-30, 1.0], [0.5, 0.5]]), np.array([[1.0, 1.0]])))
@given(jpda_problems())
def test_jpda_log_weights_equal_rational_enumeration(problem):
    a, b, C = problem
    exact = [brute_I(a, np.vstack([bl[None], C])) for bl in b]
    top = max(exact)
    try:
        got = jpda_log_weights(0.0, a, b, C)
    except ExactRangeError:
        assert C.shape[0] and _span(a, C) > 1300.0
        return
    assert got.shape == (b.shape[0],) and not np.isnan(got).any()
    if top == 0:
        assert (got == -np.inf).all()
        return
    log_top = log_fraction(top)
    for g, e in zip(got, exact, strict=True):
        rel = float(e / top)  # the exact weight relative to the largest
        assert abs(math.exp(g - log_top) - rel) <= 1e-12, (g, log_fraction(e))
        if e == 0:
            assert g == -np.inf
        elif rel > 1e-250:
            # and each weight relative to itself (not merely to the largest)
            le = log_fraction(e)
            assert abs(g - le) <= 1e-12 * max(1.0, abs(le)), (g, le)


# --------------------------------------------------------------------------- item 6


def test_exact_derivative_when_one_factor_spans_beyond_the_float_range():
    # issue 22 item 6: f_01/a_1 = 1e200 and f_02/a_2 = 1e-200 in one factor flushed to 0
    assert log_mixed_derivative(0.0, [1e-200, 1e200], [[0, 1, 1], [0, 1, 0]]) == 0.0


def test_exact_refuses_what_no_float_problem_holds():
    # 1e-600 against 1e600 in one factor, both needed: a clear error, never −inf
    with pytest.raises(ExactRangeError, match=r"F\[0\].*span"):
        log_mixed_derivative(0.0, [1e-300, 1e300], [[0, 1e300, 1e-300], [0, 1, 0]])


@SETTINGS
@example(problem=(np.array([1e-200, 1e200]), np.array([[0.0, 1, 1], [0, 1, 0]])))
@given(problems())
def test_exact_derivative_equals_rational_enumeration_at_any_magnitude(problem):
    a, F = problem
    exact = brute_I(a, F)
    try:
        got = log_mixed_derivative(0.0, a, F)
    except ExactRangeError:
        assert _span(a, F) > 1300.0
        return
    if exact == 0:
        assert got == -math.inf
        return
    ref = log_fraction(exact)
    assert abs(got - ref) <= 1e-12 * max(1.0, abs(ref)), (got, ref)


# --------------------------------------------------------------------------- item 7


def _poisson_reference(lam, m, P, s0, y):
    """log Σ_n Poisson(n; λ) N(y; n m, s0 + n P) by scipy, summed over λ ± 40√λ."""
    half = 40.0 * math.sqrt(lam) + 40.0
    n = np.arange(max(0, int(lam - half)), int(lam + half) + 1)
    return float(logsumexp(poisson.logpmf(n, lam) + norm.logpdf(y, n * m, np.sqrt(s0 + n * P))))


def _exact_poisson(lam, m, P, s0, y):
    model = Poisson(lam, [1.0], [[m]], [[[P]]])
    return likelihood(np.array([y]), model, np.array([[1.0]]), np.array([[s0]]), method="exact")


@pytest.mark.parametrize("lam", [40_000.0, 70_000.0])
def test_exact_poisson_likelihood_counts_beyond_int16(lam):
    # issue 22 item 7: counts stored as int16 wrapped at 32 768 (−707.9, +683 421)
    y = lam * 1.0 + 3.0
    got = _exact_poisson(lam, 1.0, 0.5, 0.3, y).log_value
    assert got == pytest.approx(_poisson_reference(lam, 1.0, 0.5, 0.3, y), abs=1e-9)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@example(lam=40_000.0, z=0.3, m=1.0)
@example(lam=1e6, z=-1.0, m=0.01)
@given(
    lam=st.one_of(st.just(0.0), st.floats(0.0, 1e6)),
    z=st.floats(-3.0, 3.0),
    m=st.floats(1e-3, 10.0),
)
def test_exact_poisson_likelihood_equals_scipy_for_means_up_to_1e6(lam, z, m):
    P, s0 = 0.25 * m * m, 0.3
    y = lam * m + z * math.sqrt(s0 + lam * (m * m + P))  # within a few sd of the mean
    got = _exact_poisson(lam, m, P, s0, y).log_value
    ref = _poisson_reference(lam, m, P, s0, y)
    assert got == pytest.approx(ref, abs=1e-8 * max(1.0, abs(ref)))


# --------------------------------------------------------------------------- item 15

_A, _F = [0.5, 0.7], [[1.0, 0.5, 0.2], [1.0, 0.3, 0.9]]


@pytest.mark.parametrize(
    ("option", "value", "match"),
    [
        ("tol", 0, "tol must be > 0"),
        ("tol", 0.0, "tol must be > 0"),
        ("tol", -1e-12, "tol must be > 0"),
        ("tol", float("nan"), "tol must be finite"),
        ("tol", float("inf"), "tol must be finite"),
        ("tol", True, "tol must be a real number"),
        ("tol", 1e-12 + 0j, "tol must be a real number"),
        ("tol", "1e-12", "tol must be a real number"),
        ("max_iter", 0, "max_iter must be ≥ 1"),
        ("max_iter", -3, "max_iter must be ≥ 1"),
        ("max_iter", 2.5, "max_iter must be a whole number"),
        ("max_iter", True, "max_iter must be an integer"),
        ("max_iter", 10 + 0j, "max_iter must be a whole number"),
        ("max_iter", float("inf"), "max_iter must be a whole number"),
        ("raise_on_failure", "no", "raise_on_failure must be True or False"),
        ("raise_on_failure", 0, "raise_on_failure must be True or False"),
    ],
)
def test_saddle_point_options_are_checked(option, value, match):
    with pytest.raises(ValueError, match=match):
        saddle_point(0.0, _A, _F, **{option: value})


@pytest.mark.parametrize("value", [True, 1 + 0j, "3", -1.0, float("nan"), 10**400])
def test_expected_clutter_is_checked(value):
    with pytest.raises(ValueError, match="expected_clutter"):
        jpda_coefficients([1.0], [0.9], [[0.5]], [], [], expected_clutter=value)


# --------------------------------------------------------------------------- item 10

_STIRLING = 1.0 - 0.5 * math.log(2.0 * math.pi)  # eq. (30)'s known bias per measurement
_OUTSIDE = [
    (np.array([1e-10]), np.array([[1.0, 1.0]])),  # eq. (30) was 89× off
    (np.full(3, 1e-6), np.ones((3, 4))),  # the corrected method was 5.9× off
]


def _error(method, value, exact, M):
    return value - exact - (M * _STIRLING if method == "saddle" else 0.0)


@pytest.mark.parametrize("method", ["saddle", "saddle-corrected"])
@pytest.mark.parametrize(("a", "F"), _OUTSIDE)
def test_small_clutter_against_tight_factors_is_exact_or_flagged(method, a, F):
    exact = log_mixed_derivative(0.0, a, F)
    res = log_mixed_derivative(0.0, a, F, method, full_output=True)
    assert res.method == method and res.converged
    assert res.info["exact"] and res.info["bound_holds"]
    assert res.log_normalizer == pytest.approx(exact, abs=1e-12)
    assert log_mixed_derivative(0.0, a, F, method) == res.log_normalizer
    flagged = log_mixed_derivative(0.0, a, F, method, exact_fallback=False, full_output=True)
    assert not flagged.info["exact"] and not flagged.info["bound_holds"]


@pytest.mark.parametrize("method", ["saddle", "saddle-corrected"])
def test_batched_flags_are_per_problem(method):
    rng = np.random.default_rng(5)
    a = np.full(3, 1e-6)
    inside = np.concatenate([np.ones((3, 1)), 1e-6 * rng.random((3, 3))], axis=1)
    tight = np.ones((3, 4))
    F = np.stack([inside, tight])
    res = log_mixed_derivative(0.0, a, F, method, exact_fallback=False, full_output=True)
    assert res.info["bound_holds"].tolist() == [True, False]
    exact = log_mixed_derivative(0.0, a, F)
    res = log_mixed_derivative(0.0, a, F, method, full_output=True)
    assert res.info["exact"].tolist() == [False, True]
    assert res.log_normalizer[1] == pytest.approx(exact[1], abs=1e-12)


@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@example(problem=_OUTSIDE[0])
@example(problem=_OUTSIDE[1])
@given(problems(max_k=3, max_m=3))
def test_the_flag_is_set_whenever_the_stated_bound_fails(problem):
    """The bound's honesty: error above ERROR_BOUNDS ⇒ info["bound_holds"] is False."""
    a, F = problem
    try:
        exact = log_mixed_derivative(0.0, a, F)
    except ExactRangeError:
        return
    M = a.size
    for method in ("saddle", "saddle-corrected"):
        try:
            res = log_mixed_derivative(0.0, a, F, method, exact_fallback=False, full_output=True)
            cheap = log_mixed_derivative(0.0, a, F, method, full_output=True)
        except SaddlePointError:
            continue  # reported, not a silent wrong value
        bound = ERROR_BOUNDS[method]
        if exact == -math.inf:
            assert res.log_normalizer == cheap.log_normalizer == -math.inf
            continue
        if abs(_error(method, res.log_normalizer, exact, M)) > bound:
            assert not res.info["bound_holds"], (method, res.log_normalizer, exact)
        # with the exact fallback (every problem here is cheap) the bound always holds
        assert cheap.info["bound_holds"]
        if cheap.info["exact"]:
            assert cheap.log_normalizer == pytest.approx(exact, abs=1e-9 * max(1.0, abs(exact)))
        else:
            assert abs(_error(method, cheap.log_normalizer, exact, M)) <= bound


# --------------------------------------------------------------------------- item 10, hybrid

_H3 = np.array([[0.1, 0.7], [0.5, 0.5], [0.8, 0.2]])
_S0 = 0.25 * np.eye(3)


@pytest.mark.parametrize("mu", [1e155, 1e200])
@pytest.mark.parametrize("method", ["hybrid", "gaussian"])
def test_a_far_component_of_tiny_existence_probability_keeps_the_likelihood_finite(mu, method):
    # issue 22 item 10: r(1 − r) m mᵀ overflowed (m mᵀ first): −inf, or a wrong "exact" value
    mb = MultiBernoulli([1e-300, 0.5], [[mu, mu], [1.0, 2.0]], [np.eye(2)] * 2)
    y0 = np.zeros(3)
    exact = likelihood(y0, mb, _H3, _S0, method="exact").log_value
    if method == "hybrid":
        res = likelihood(y0, mb, _H3, _S0, method=method)
        # the whole mixture fits the budget: the exact value (a node whose every leaf
        # weighs e^-1e300 may stay unrefined, so info["exact"] need not say so)
        assert res.log_value == pytest.approx(exact, abs=1e-12)
        return
    # the Gaussian approximation (9): finite, or a clear error where Σ0 + Σ_Q is singular
    # in float (a rank-one 1e100 term beside 0.25), never −inf
    try:
        assert math.isfinite(likelihood(y0, mb, _H3, _S0, method=method).log_value)
    except ValueError as exc:
        assert "not positive definite" in str(exc)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    r=st.lists(
        st.one_of(st.sampled_from([5e-324, 1e-300, 1e-100, 1.0 - 1e-16, 1.0]), st.floats(0.0, 1.0)),
        min_size=1,
        max_size=4,
    ),
    scale=st.sampled_from([1.0, 1e50, 1e100, 1e150]),
    data=st.data(),
)
def test_hybrid_with_the_whole_mixture_in_budget_is_the_exact_mixture(r, scale, data):
    n = len(r)
    means = np.array(
        data.draw(st.lists(st.tuples(st.floats(-1, 1), st.floats(-1, 1)), min_size=n, max_size=n))
    )
    pick = np.array(data.draw(st.lists(st.booleans(), min_size=n, max_size=n)))
    # the components the reading is made of near the origin, the others up to `scale`
    # away (far ones at 1e150 are what overflowed): y0 − mean stays well conditioned
    means = np.where(pick[:, None], means, scale * means)
    mb = MultiBernoulli(r, means, [np.eye(2)] * n)
    y0 = _H3 @ means[pick].sum(axis=0) if pick.any() else np.zeros(3)
    exact = likelihood(y0, mb, _H3, _S0, method="exact").log_value
    res = likelihood(y0, mb, _H3, _S0, method="hybrid")
    assert res.log_value == pytest.approx(exact, abs=1e-9 * max(1.0, abs(exact)))


@pytest.mark.parametrize("method", ["gaussian", "exact", "hybrid", "saddlepoint"])
@pytest.mark.parametrize("part", [True, -1, 2, 1.5, 1 + 0j, "0"])
def test_ratio_part_is_checked_for_every_method(method, part):
    mb = MultiBernoulli([0.5], [[0.0, 0.0]], [np.eye(2)])
    model, x = Union(mb, mb), np.zeros((1, 2))
    with pytest.raises(ValueError, match="part"):
        log_likelihood_ratio(np.zeros(3), x, model, _H3, _S0, method, part=part)


@pytest.mark.parametrize("value", [np.array(["gaussian"]), ["gaussian"], 1, None])
def test_hybrid_remainder_must_be_a_name(value):
    mb = MultiBernoulli([0.5], [[0.0, 0.0]], [np.eye(2)])
    with pytest.raises(ValueError, match="remainder must be"):
        likelihood(np.zeros(3), mb, _H3, _S0, method="hybrid", remainder=value)


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@example(r=[5e-324, 5e-324, 5e-324, 0.5], scale=1e50, budget=2, far=3)
@given(
    r=st.lists(
        st.one_of(st.sampled_from([5e-324, 1e-300, 1.0 - 1e-16]), st.floats(0.0, 1.0)),
        min_size=1,
        max_size=4,
    ),
    scale=st.sampled_from([1.0, 1e50, 1e150]),
    budget=st.integers(1, 16),
    far=st.integers(0, 3),
)
def test_a_hybrid_zero_where_the_likelihood_is_positive_is_flagged(r, scale, budget, far):
    """−inf (or any value) below the exact one by an underflowed stand-in is reported."""
    n = len(r)
    means = np.zeros((n, 2))
    means[min(far, n - 1)] = [0.0, 0.005 * scale]
    mb = MultiBernoulli(r, means, [np.eye(2)] * n)
    exact = likelihood(np.zeros(3), mb, _H3, _S0, method="exact").log_value
    res = likelihood(np.zeros(3), mb, _H3, _S0, method="hybrid", budget=budget)
    assert not math.isnan(res.log_value)
    if res.log_value == -math.inf and exact > -math.inf:
        assert res.info["underflowed_terms"] > 0 and not res.info["exact"]
    if res.info["exact"]:
        assert res.log_value == pytest.approx(exact, abs=1e-9 * max(1.0, abs(exact)))
