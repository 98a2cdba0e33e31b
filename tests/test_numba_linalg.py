"""The compiled Cholesky helpers of ``jointtrack._numba_linalg``: against numpy, and failures."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from jointtrack._numba_linalg import cholesky_lower, cholesky_solve, mahalanobis_sq
from jointtrack.superpositional import _exact


def spd(seed, d):
    rng = np.random.default_rng(seed)
    a = rng.standard_normal((d, d))
    return a @ a.T + 0.1 * np.eye(d), rng.standard_normal(d), rng.standard_normal(d)


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(1, 6))
def test_factor_solve_and_distance_match_numpy(seed, d):
    A, y, mean = spd(seed, d)
    upper_nan = A.copy()
    upper_nan[np.triu_indices(d, 1)] = np.nan  # only the lower triangle is read
    L = np.zeros((d, d))
    ok, log_det = cholesky_lower(upper_nan, L)
    ref = np.linalg.cholesky(A)
    assert ok
    np.testing.assert_allclose(np.tril(L), ref, rtol=1e-12, atol=1e-12)
    assert log_det == pytest.approx(np.linalg.slogdet(A)[1], abs=1e-12)
    in_place = np.tril(A)
    assert cholesky_lower(in_place, in_place) == (ok, log_det)
    np.testing.assert_array_equal(in_place, np.tril(L))
    z = np.empty(d)
    q = mahalanobis_sq(L, y, mean, z)
    r = y - mean
    assert q == pytest.approx(r @ np.linalg.solve(A, r), rel=1e-10)
    np.testing.assert_allclose(z, np.linalg.solve(ref, r), rtol=1e-10, atol=1e-12)
    x = np.empty(d)
    cholesky_solve(L, y, x)
    np.testing.assert_allclose(x, np.linalg.solve(A, y), rtol=1e-9, atol=1e-12)


def test_non_positive_pivot_fails_or_is_floored():
    A = np.array([[1.0, 0.0], [1.0, 1.0]])  # [[1, 1], [1, 1]]: second pivot 0
    L = np.zeros((2, 2))
    assert cholesky_lower(A, L) == (False, -math.inf)
    ok, log_det = cholesky_lower(A, L, 1e-300)
    assert ok and L[1, 1] == math.sqrt(1e-300)
    assert log_det == pytest.approx(math.log(1e-300), rel=1e-15)
    nan_pivot = np.array([[np.nan]])
    assert cholesky_lower(nan_pivot, L)[0] is False
    assert cholesky_lower(nan_pivot, L, 1e-300)[0] is True


def test_infinite_pivot_fails_even_with_a_floor():
    A = np.array([[np.inf]])
    assert cholesky_lower(A, np.zeros((1, 1)), 1e-300) == (False, -math.inf)


def test_exact_kernel_raises_on_a_covariance_not_positive_definite():
    """Never a NaN likelihood: the enumeration's kernel refuses an indefinite term covariance."""
    counts = np.ones((1, 1), np.int16)
    with pytest.raises(ValueError, match="not positive definite"):
        _exact._logsumexp_terms(
            counts,
            np.zeros(1),
            np.zeros((1, 2)),
            np.zeros((1, 2, 2)),
            np.array([[1.0, 0.0], [2.0, 1.0]]),  # lower triangle of [[1, 2], [2, 1]]
            np.zeros((1, 2)),
        )
