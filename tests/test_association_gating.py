"""Gating, clustering and clutter density (jointtrack.association.{gating,clustering,clutter})."""

from __future__ import annotations

import itertools
import math
import tracemalloc

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp
from scipy import stats

import jointtrack.association.clustering as clustering_module
import jointtrack.association.gating as gating_module
from jointtrack.association.clustering import clusters, has_feasible_event
from jointtrack.association.clutter import (
    cluster_clutter_density,
    cluster_heuristic_density,
    known_density,
    track_sample_density,
    union_gate_volume,
    union_sample_density,
)
from jointtrack.association.gating import (
    Gating,
    PairGating,
    gate_measurements,
    gate_pairs,
    likelihood_ratio_pairs,
    likelihood_ratios,
)


def _spd(rng, d, scale=1.0):
    A = rng.standard_normal((d, d))
    return scale * (A @ A.T + 0.5 * np.eye(d))


# ----------------------------------------------------------------------------- gating


@pytest.mark.parametrize("d", [1, 2, 3])
def test_gate_matches_explicit_formulas(d):
    rng = np.random.default_rng(d)
    n, m = 3, 7
    zp = rng.standard_normal((n, d))
    S = np.array([_spd(rng, d) for _ in range(n)])
    z = 2 * rng.standard_normal((m, d))
    g = gate_measurements(zp, S, z, P_G=0.95)
    gamma = stats.chi2.ppf(0.95, d)
    assert g.gamma == pytest.approx(gamma, rel=1e-14)
    for i in range(n):
        Si = np.linalg.inv(S[i])
        for j in range(m):
            e = z[j] - zp[i]
            assert g.d2[i, j] == pytest.approx(e @ Si @ e, rel=1e-10)
            assert g.log_g[i, j] == pytest.approx(
                stats.multivariate_normal(zp[i], S[i]).logpdf(z[j]), rel=1e-10, abs=1e-12
            )
    np.testing.assert_array_equal(g.mask, g.d2 <= gamma)
    # unit-ball volumes: 2, π, 4π/3
    c_d = {1: 2.0, 2: math.pi, 3: 4.0 * math.pi / 3.0}[d]
    V = c_d * gamma ** (d / 2) * np.sqrt(np.linalg.det(S))
    np.testing.assert_allclose(g.gate_volume, V, rtol=1e-12)
    np.testing.assert_allclose(g.log_gate_volume, np.log(V), rtol=1e-12)
    np.testing.assert_array_equal(g.n_gated, g.mask.sum(axis=1))


def test_gate_probability_is_P_G():
    # true measurements drawn from N(ẑ, S) fall in the gate with probability P_G
    rng = np.random.default_rng(0)
    S = np.array([[[2.0, 0.7], [0.7, 1.0]]])
    zt = rng.multivariate_normal([1.0, -1.0], S[0], size=40_000)
    g = gate_measurements([[1.0, -1.0]], S, zt, P_G=0.9)
    frac = g.mask.mean()
    se = math.sqrt(0.9 * 0.1 / zt.shape[0])
    assert abs(frac - 0.9) < 4 * se


def test_gate_log_space_extreme_covariances():
    # |S| = 1e-600 underflows a determinant; the Cholesky log-det does not
    S = np.array([1e-300 * np.eye(2), 1e300 * np.eye(2)])
    zp = np.zeros((2, 2))
    z = np.array([[1e-150, 0.0], [1e150, 0.0]])
    g = gate_measurements(zp, S, z)
    assert np.all(np.isfinite(g.log_g[g.mask])) and np.all(np.isfinite(g.log_gate_volume))
    assert not np.isnan(g.d2).any() and not np.isnan(g.log_g).any()
    assert g.d2[0, 1] == np.inf and g.log_g[0, 1] == -np.inf  # (1e300)² overflows: g = 0
    assert g.d2[0, 0] == pytest.approx(1.0, rel=1e-12)
    assert g.d2[1, 1] == pytest.approx(1.0, rel=1e-12)
    assert g.log_g[0, 0] == pytest.approx(-0.5 - math.log(2 * math.pi) + 300 * math.log(10))
    assert g.mask[0, 0] and g.mask[1, 1] and not g.mask[0, 1]


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(0, 4), m=st.integers(0, 5))
def test_gate_translation_invariant_and_ratios(seed, n, m):
    rng = np.random.default_rng(seed)
    d = 2
    zp = rng.standard_normal((n, d))
    S = np.array([_spd(rng, d) for _ in range(n)]).reshape(n, d, d)
    z = 1.5 * rng.standard_normal((m, d))
    g = gate_measurements(zp, S, z, P_G=0.99)
    shift = rng.standard_normal(d) * 10
    g2 = gate_measurements(zp + shift, S, z + shift, P_G=0.99)
    np.testing.assert_allclose(g.d2, g2.d2, rtol=1e-8, atol=1e-10)
    assert np.all(g.d2 >= 0)
    P_D = rng.uniform(0.5, 1.0, size=n)
    lam = rng.uniform(0.01, 1.0, size=m)
    L, miss = likelihood_ratios(g, P_D, lam)
    expect = np.where(g.mask, P_D[:, None] * np.exp(g.log_g) / lam[None, :], 0.0)
    np.testing.assert_allclose(L, expect, rtol=1e-12)
    np.testing.assert_allclose(miss, 1.0 - P_D * 0.99, rtol=1e-15)
    assert L.shape == (n, m) and np.all(L >= 0)


def test_likelihood_ratio_scalar_inputs():
    g = gate_measurements([[0.0]], [[[1.0]]], [[0.5], [10.0]], P_G=0.99)
    L, miss = likelihood_ratios(g, 0.9, 0.2)
    assert L[0, 0] == pytest.approx(0.9 * stats.norm.pdf(0.5) / 0.2, rel=1e-13)
    assert L[0, 1] == 0.0
    assert miss[0] == pytest.approx(1 - 0.9 * 0.99, rel=1e-15)


def test_gate_empty():
    g = gate_measurements(np.zeros((0, 2)), np.zeros((0, 2, 2)), np.ones((3, 2)))
    assert g.mask.shape == (0, 3) and g.gate_volume.shape == (0,)
    L, miss = likelihood_ratios(g, 0.9, 1.0)
    assert L.shape == (0, 3) and miss.shape == (0,)
    g = gate_measurements(np.zeros((2, 2)), np.array([np.eye(2)] * 2), np.zeros((0,)))
    assert g.mask.shape == (2, 0)
    L, miss = likelihood_ratios(g, 0.9, 1.0)
    assert L.shape == (2, 0) and miss.shape == (2,)


@pytest.mark.parametrize(
    ("S1", "msg"),
    [
        (np.array([[1.0, 2.0], [2.0, 1.0]]), "track 1.*not positive definite"),
        (np.array([[1.0, 1.0], [1.0, 1.0]]), "track 1"),
        (np.array([[1.0, 0.3], [0.0, 1.0]]), "track 1.*not symmetric"),
        (np.array([[1.0, np.nan], [np.nan, 1.0]]), "track 1.*non-finite"),
        (np.array([[1.0, 0.0], [0.0, 1e-20]]), "track 1.*singular"),
        (np.zeros((2, 2)), "track 1.*singular"),
    ],
)
def test_gate_bad_covariance_names_track(S1, msg):
    S = np.array([np.eye(2), S1, np.eye(2)])
    with pytest.raises(ValueError, match=msg):
        gate_measurements(np.zeros((3, 2)), S, np.zeros((1, 2)))


def test_gate_bad_shapes_and_parameters():
    S = np.array([np.eye(2)])
    with pytest.raises(ValueError, match="S must have shape"):
        gate_measurements(np.zeros((1, 2)), np.eye(2), np.zeros((1, 2)))
    with pytest.raises(ValueError, match="z must have shape"):
        gate_measurements(np.zeros((1, 2)), S, np.zeros((1, 3)))
    with pytest.raises(ValueError, match="z_pred must be 2-D"):
        gate_measurements(np.zeros(2), S, np.zeros((1, 2)))
    with pytest.raises(ValueError, match="P_G"):
        gate_measurements(np.zeros((1, 2)), S, np.zeros((1, 2)), P_G=1.5)
    # P_G = 1 is the infinite gate: every measurement gated, infinite volume
    far = gate_measurements(np.zeros((1, 2)), S, np.array([[1e9, -1e9]]), P_G=1.0)
    assert far.mask.all() and far.gamma == np.inf and far.gate_volume[0] == np.inf
    pairs = gate_pairs(np.zeros((1, 2)), S, np.array([[1e9, -1e9], [0.0, 1.0]]), P_G=1.0)
    assert pairs.rows.tolist() == [0, 0] and pairs.cols.tolist() == [0, 1]
    with pytest.raises(ValueError, match="measurement z\\[0\\]"):
        gate_measurements(np.zeros((1, 2)), S, np.array([[np.inf, 0.0]]))
    g = gate_measurements(np.zeros((1, 2)), S, np.zeros((2, 2)))
    with pytest.raises(ValueError, match="P_D"):
        likelihood_ratios(g, 1.5, 1.0)
    with pytest.raises(ValueError, match="clutter_density"):
        likelihood_ratios(g, 0.9, 0.0)
    with pytest.raises(ValueError, match="clutter_density"):
        likelihood_ratios(g, 0.9, [1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match="overflows"):
        likelihood_ratios(gate_measurements([[0.0]], [[[1e-300]]], [[0.0]]), 0.9, 1e-300)


# ------------------------------------------------------------------------- clustering


def _components_bfs(mask):
    """Reference: connected components by breadth-first search (tracks only)."""
    n, m = mask.shape
    label = [-1] * n
    k = 0
    for s in range(n):
        if label[s] >= 0:
            continue
        label[s] = k
        stack = [s]
        while stack:
            t = stack.pop()
            for j in np.flatnonzero(mask[t]):
                for u in np.flatnonzero(mask[:, j]):
                    if label[u] < 0:
                        label[u] = k
                        stack.append(u)
        k += 1
    return label


def test_clusters_example():
    mask = np.array(
        [
            [1, 0, 0, 0, 0],
            [0, 0, 1, 0, 0],
            [0, 1, 1, 0, 0],
            [0, 0, 0, 0, 0],
            [0, 1, 0, 0, 1],
        ],
        dtype=bool,
    )
    c = clusters(mask)
    assert len(c) == 3
    np.testing.assert_array_equal(c[0].tracks, [0])
    np.testing.assert_array_equal(c[0].measurements, [0])
    np.testing.assert_array_equal(c[1].tracks, [1, 2, 4])
    np.testing.assert_array_equal(c[1].measurements, [1, 2, 4])
    np.testing.assert_array_equal(c[2].tracks, [3])
    assert c[2].measurements.size == 0
    np.testing.assert_array_equal(c.unassociated, [3])
    np.testing.assert_array_equal(c.measurement_cluster, [0, 1, 1, -1, 1])
    L = np.arange(25.0).reshape(5, 5) * mask
    Ls, ms = c[1].select(L, np.arange(5.0))
    np.testing.assert_array_equal(Ls, L[np.ix_([1, 2, 4], [1, 2, 4])])
    np.testing.assert_array_equal(ms, [1.0, 2.0, 4.0])


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(0, 8), m=st.integers(0, 8))
def test_clusters_partition_matches_bfs(seed, n, m):
    rng = np.random.default_rng(seed)
    mask = rng.random((n, m)) < rng.random() * 0.5
    c = clusters(mask)
    ref = _components_bfs(mask)
    # same partition of tracks
    for a in range(n):
        for b in range(n):
            assert (c.track_cluster[a] == c.track_cluster[b]) == (ref[a] == ref[b])
    # every track exactly once, measurements partitioned, unassociated = ungated
    all_t = np.concatenate([k.tracks for k in c] + [np.zeros(0, int)])
    np.testing.assert_array_equal(np.sort(all_t), np.arange(n))
    all_m = np.concatenate([k.measurements for k in c] + [c.unassociated])
    np.testing.assert_array_equal(np.sort(all_m), np.arange(m))
    np.testing.assert_array_equal(c.unassociated, np.flatnonzero(~mask.any(axis=0)))
    for k, cl in enumerate(c):
        # no gated pair leaves the cluster
        rest = np.setdiff1d(np.arange(m), cl.measurements)
        assert not mask[np.ix_(cl.tracks, rest)].any()
        assert np.all(c.track_cluster[cl.tracks] == k)
    # clusters ordered by smallest track
    firsts = [int(k.tracks[0]) for k in c]
    assert firsts == sorted(firsts)


def test_clusters_accepts_likelihood_matrix_and_empty():
    c = clusters(np.array([[0.0, 2.5], [0.0, 0.0]]))
    assert len(c) == 2 and list(c.unassociated) == [0]
    assert len(clusters(np.zeros((0, 0)))) == 0
    assert (
        len(clusters(np.zeros((0, 4)))) == 0 and clusters(np.zeros((0, 4))).unassociated.size == 4
    )
    c = clusters(np.zeros((3, 0)))
    assert len(c) == 3 and all(k.measurements.size == 0 for k in c)
    with pytest.raises(ValueError, match="negative"):
        clusters(np.array([[-1.0]]))
    with pytest.raises(ValueError, match="2-D"):
        clusters(np.zeros((2, 2, 2)))


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 4), m=st.integers(0, 4))
def test_has_feasible_event_matches_enumeration(seed, n, m):
    rng = np.random.default_rng(seed)
    L = rng.random((n, m)) * (rng.random((n, m)) < 0.5)
    miss = np.where(rng.random(n) < 0.6, 0.0, 0.5)
    opts = [[-1] * int(miss[i] > 0) + list(np.flatnonzero(L[i] > 0)) for i in range(n)]
    feasible = any(
        len(set(j for j in a if j >= 0)) == sum(j >= 0 for j in a) for a in itertools.product(*opts)
    )
    assert has_feasible_event(L, miss) == feasible


# ---------------------------------------------------------------------------- clutter


def _disc_S(r, gamma):
    """Covariance whose γ-gate is the disc of radius r."""
    return (r * r / gamma) * np.eye(2)


def _lens_area(r, dist):
    return 2 * r * r * math.acos(dist / (2 * r)) - 0.5 * dist * math.sqrt(4 * r * r - dist * dist)


def test_simple_density_estimators():
    assert known_density(0.25) == 0.25
    for bad in (0.0, -1.0, np.inf, "x"):
        with pytest.raises(ValueError):
            known_density(bad)
    np.testing.assert_allclose(track_sample_density([3, 0, 5], [2.0, 1.0, 10.0]), [1.5, 0.0, 0.5])
    # Bojilov (8): Σ m_i / Σ V_i
    assert cluster_heuristic_density([3, 0, 5], [2.0, 1.0, 10.0]) == pytest.approx(8 / 13)
    with pytest.raises(ValueError, match="volume"):
        cluster_heuristic_density([1, 2], [1.0, 0.0])
    with pytest.raises(ValueError, match="integers"):
        track_sample_density([1.5], [1.0])
    with pytest.raises(ValueError, match="no tracks"):
        cluster_heuristic_density([], [])


def test_union_volume_exact_cases_and_lens():
    gamma = stats.chi2.ppf(0.99, 2)
    S = np.array([_disc_S(1.0, gamma)] * 2)
    # identical gates: every sample has c(x) = 2 → estimator exact, zero variance
    u = union_gate_volume([[0.0, 0.0], [0.0, 0.0]], S, gamma=gamma, n_samples=5000, rng=0)
    assert u.volume == pytest.approx(math.pi, rel=1e-12) and u.std_error == 0.0
    assert u.sum_volume == pytest.approx(2 * math.pi, rel=1e-12)
    # disjoint gates: c(x) = 1
    u = union_gate_volume([[0.0, 0.0], [3.0, 0.0]], S, P_G=0.99, n_samples=5000, rng=0)
    assert u.volume == pytest.approx(2 * math.pi, rel=1e-12) and u.std_error == 0.0
    # centres one radius apart: union = 2π − lens, within 4 standard errors
    u = union_gate_volume([[0.0, 0.0], [1.0, 0.0]], S, gamma=gamma, n_samples=200_000, rng=1)
    exact = 2 * math.pi - _lens_area(1.0, 1.0)
    assert abs(u.volume - exact) < 4 * u.std_error
    assert u.std_error < 0.002 * exact
    # reproducible for a seed
    u2 = union_gate_volume([[0.0, 0.0], [1.0, 0.0]], S, gamma=gamma, n_samples=200_000, rng=1)
    assert u2.volume == u.volume


def test_union_volume_1d_intervals_and_ellipses():
    # 1-D: intervals [−1, 1], [0.5, 2.5], [2, 4] → union [−1, 4] of length 5
    gamma = 1.0
    c = np.array([[0.0], [1.5], [3.0]])
    S = np.ones((3, 1, 1))
    u = union_gate_volume(c, S, gamma=gamma, n_samples=200_000, rng=2)
    assert abs(u.volume - 5.0) < 4 * u.std_error and u.std_error < 0.01
    # an ellipse inside a disc: union = disc
    S = np.array([np.diag([4.0, 4.0]), np.diag([1.0, 0.25])])
    u = union_gate_volume(np.zeros((2, 2)), S, gamma=1.0, n_samples=100_000, rng=3)
    assert abs(u.volume - 4 * math.pi) < 4 * u.std_error + 1e-12


def test_heuristic_8_versus_union_density():
    """How far Bojilov's (8) is from the exact N_M/|∪V| (module docstring identity)."""
    gamma = stats.chi2.ppf(0.99, 2)
    S = np.array([_disc_S(1.0, gamma)] * 2)
    V = np.array([math.pi, math.pi])
    m = 6

    # identical gates, all m measurements shared: the duplication in numerator and
    # denominator cancels and (8) is exact (m/V both) — not m/(2V)
    ex = union_sample_density(m, np.zeros((2, 2)), S, gamma=gamma, n_samples=2000, rng=0)
    heur = cluster_heuristic_density([m, m], V)
    assert ex.density == pytest.approx(m / math.pi, rel=1e-12)
    assert heur == pytest.approx(ex.density, rel=1e-12)

    # disjoint gates, 4 + 2 measurements: (8) is exact again
    ex = union_sample_density(m, [[0.0, 0.0], [5.0, 0.0]], S, gamma=gamma, n_samples=2000, rng=0)
    assert cluster_heuristic_density([4, 2], V) == pytest.approx(ex.density, rel=1e-12)

    # heavily overlapping gates (centres one radius apart, overlap 39 % of each disc)
    centres = [[0.0, 0.0], [1.0, 0.0]]
    ex = union_sample_density(m, centres, S, gamma=gamma, n_samples=200_000, rng=1)
    union = 2 * math.pi - _lens_area(1.0, 1.0)
    assert ex.density == pytest.approx(m / union, rel=4 * ex.std_error / ex.density)
    c_vol = 2 * math.pi / union  # mean gate multiplicity of the union volume, 1.243
    # (a) all measurements in the lens: (8) counts each twice → 2/c_vol = 1.61 × exact
    heur_in = cluster_heuristic_density([m, m], V)
    assert heur_in / ex.density == pytest.approx(2 / c_vol, rel=0.01)
    assert heur_in / ex.density > 1.5
    # (b) all measurements outside the lens: 1/c_vol = 0.80 × exact
    heur_out = cluster_heuristic_density([3, 3], V)
    assert heur_out / ex.density == pytest.approx(1 / c_vol, rel=0.01)
    assert heur_out / ex.density < 0.85


def test_heuristic_8_unbiased_for_poisson_clutter():
    """For Poisson clutter both estimators target λ; (8) is unbiased, E Σm_i = λΣV_i."""
    rng = np.random.default_rng(7)
    lam = 3.0
    gamma = stats.chi2.ppf(0.99, 2)
    centres = np.array([[0.0, 0.0], [1.0, 0.0], [0.5, 0.8]])
    S = np.array([_disc_S(1.0, gamma)] * 3)
    U = union_gate_volume(centres, S, gamma=gamma, n_samples=200_000, rng=0)
    box = np.array([[-1.0, 2.0], [-1.0, 1.8]])
    area = np.prod(box[:, 1] - box[:, 0])
    heur, exact = [], []
    for _ in range(1500):
        k = rng.poisson(lam * area)
        pts = box[:, 0] + rng.random((k, 2)) * (box[:, 1] - box[:, 0])
        inside = ((pts[None, :, :] - centres[:, None, :]) ** 2).sum(axis=2) <= 1.0
        heur.append(inside.sum() / (3 * math.pi))
        exact.append(inside.any(axis=0).sum() / U.volume)
    heur, exact = np.array(heur), np.array(exact)
    assert abs(heur.mean() - lam) < 4 * heur.std() / math.sqrt(heur.size)
    assert abs(exact.mean() - lam) < 4 * exact.std() / math.sqrt(exact.size) + 3 * lam * (
        U.std_error / U.volume
    )
    # …but (8) is noisier: shared measurements are counted more than once
    assert heur.std() > exact.std()


def test_cluster_clutter_density_from_gating():
    gamma = stats.chi2.ppf(0.99, 2)
    S = np.array([_disc_S(1.0, gamma)] * 2)
    z = np.array([[0.5, 0.0], [0.5, 0.1], [-0.9, 0.0], [5.0, 5.0]])
    g = gate_measurements([[0.0, 0.0], [1.0, 0.0]], S, z, P_G=0.99)
    np.testing.assert_array_equal(g.n_gated, [3, 2])
    h = cluster_clutter_density(g, method="heuristic")
    assert h.density == pytest.approx(5 / (2 * math.pi), rel=1e-12)
    u = cluster_clutter_density(g, [0, 1], method="union", n_samples=100_000, rng=0)
    union = 2 * math.pi - _lens_area(1.0, 1.0)
    assert u.density == pytest.approx(3 / union, abs=4 * u.std_error)
    with pytest.raises(ValueError, match="method"):
        cluster_clutter_density(g, method="nope")
    with pytest.raises(ValueError, match="exactly one"):
        union_gate_volume([[0.0, 0.0]], S[:1])


def test_gate_rejects_residual_returning_nan():
    z_pred = np.zeros((2, 2))
    S = np.stack([np.eye(2)] * 2)
    z = np.array([[0.5, 0.5], [1.0, -1.0], [3.0, 0.0]])

    def wrapped_residual(zz, zp):
        r = zz - zp
        return np.where(np.abs(r) > 2.5, np.nan, r)  # a buggy angle wrap

    with pytest.raises(ValueError, match="residual function.*wrapped_residual.*z\\[2\\]"):
        gate_measurements(z_pred, S, z, residual=wrapped_residual)
    with pytest.raises(ValueError, match="residual function.*<lambda>"):
        gate_measurements(z_pred, S, z, residual=lambda a, b: (a - b) + np.inf)
    with pytest.raises(ValueError, match="residual function.*complex"):
        gate_measurements(z_pred, S, z, residual=lambda a, b: (a - b) + 0j)
    with pytest.raises(ValueError, match="residual function.*shape"):
        gate_measurements(z_pred, S, z, residual=lambda a, b: np.zeros(5))
    # a finite residual gates as before
    g = gate_measurements(z_pred, S, z, residual=lambda a, b: a - b)
    np.testing.assert_array_equal(g.mask, gate_measurements(z_pred, S, z).mask)


# ------------------------------------------------------------- sparse gating (gate_pairs)


def _assert_same_clustering(a, b):
    assert len(a) == len(b)
    for ka, kb in zip(a, b, strict=True):
        np.testing.assert_array_equal(ka.tracks, kb.tracks)
        np.testing.assert_array_equal(ka.measurements, kb.measurements)
        assert ka.tracks.dtype == kb.tracks.dtype == np.int64
        assert ka.measurements.dtype == kb.measurements.dtype == np.int64
    for name in ("unassociated", "track_cluster", "measurement_cluster"):
        x, y = getattr(a, name), getattr(b, name)
        np.testing.assert_array_equal(x, y)
        assert x.dtype == y.dtype


_coord = st.floats(-6.0, 6.0, allow_nan=False, allow_infinity=False)
_factor = st.floats(-2.0, 2.0, allow_nan=False, allow_infinity=False)


@st.composite
def _gating_problem(draw):
    d = draw(st.sampled_from([2, 3]))
    n = draw(st.integers(0, 12))
    m = draw(st.integers(0, 20))
    z_pred = draw(hnp.arrays(np.float64, (n, d), elements=_coord))
    # SPD covariances from drawn factors: S_i = s_i (A_i A_iᵀ + ε_i I), cond ≲ 10³
    A = draw(hnp.arrays(np.float64, (n, d, d), elements=_factor))
    eps = draw(hnp.arrays(np.float64, (n,), elements=st.floats(0.05, 1.0)))
    scale = draw(hnp.arrays(np.float64, (n,), elements=st.sampled_from([0.01, 0.3, 1.0, 4.0])))
    S = scale[:, None, None] * (A @ np.swapaxes(A, 1, 2) + eps[:, None, None] * np.eye(d))
    # measurements: some near a track, the rest anywhere
    z = draw(hnp.arrays(np.float64, (m, d), elements=_coord))
    if n:
        near = draw(hnp.arrays(np.bool_, (m,)))
        host = draw(hnp.arrays(np.int64, (m,), elements=st.integers(0, n - 1)))
        z = np.where(near[:, None], z_pred[host] + 0.3 * z, z)
    P_G = draw(st.sampled_from([0.9, 0.99, 0.999]))
    P_D = draw(hnp.arrays(np.float64, (n,), elements=st.floats(0.05, 1.0)))
    lam = draw(hnp.arrays(np.float64, (m,), elements=st.floats(1e-6, 10.0)))
    return z_pred, S, z, P_G, P_D, lam


@settings(max_examples=200, deadline=None)
@given(problem=_gating_problem())
def test_gate_pairs_matches_dense(problem):
    z_pred, S, z, P_G, P_D, lam = problem
    n, m = z_pred.shape[0], z.shape[0]
    g = gate_measurements(z_pred, S, z, P_G=P_G)
    p = gate_pairs(z_pred, S, z, P_G=P_G)
    assert isinstance(p, PairGating)
    assert (p.n_tracks, p.n_measurements) == (n, m)
    assert p.rows.dtype == p.cols.dtype == np.int64
    # sorted by row then column, i.e. np.nonzero order, no duplicates
    r, c = np.nonzero(g.mask)
    np.testing.assert_array_equal(p.rows, r)
    np.testing.assert_array_equal(p.cols, c)
    assert p.n_candidates >= p.n_pairs
    np.testing.assert_array_equal(p.n_gated, g.n_gated)
    np.testing.assert_array_equal(p.indptr, np.r_[0, np.cumsum(g.n_gated)])

    dense = p.dense()
    assert isinstance(dense, Gating)
    np.testing.assert_array_equal(dense.mask, g.mask)
    np.testing.assert_allclose(dense.d2[g.mask], g.d2[g.mask], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(dense.log_g[g.mask], g.log_g[g.mask], rtol=1e-12, atol=1e-12)
    assert np.all(dense.d2[~g.mask] == np.inf) and np.all(dense.log_g[~g.mask] == -np.inf)
    assert dense.gamma == g.gamma and dense.P_G == g.P_G
    np.testing.assert_array_equal(dense.log_gate_volume, g.log_gate_volume)
    np.testing.assert_array_equal(dense.gate_volume, g.gate_volume)
    np.testing.assert_array_equal(dense.S, g.S)
    np.testing.assert_array_equal(dense.chol, g.chol)
    np.testing.assert_array_equal(dense.n_gated, g.n_gated)

    for pd_arg, lam_arg in ((P_D, lam), (0.9, 0.25)):
        L, miss = likelihood_ratios(g, pd_arg, lam_arg)
        Lp, missp = likelihood_ratio_pairs(p, pd_arg, lam_arg)
        assert Lp.shape == (p.n_pairs,)
        np.testing.assert_allclose(Lp, L[p.rows, p.cols], rtol=1e-11, atol=0)
        np.testing.assert_array_equal(missp, miss)
        # nothing lost off the pairs: the dense L is zero elsewhere
        rest = np.ones((n, m), dtype=bool)
        rest[p.rows, p.cols] = False
        assert not L[rest].any()

    ref = clusters(g.mask)
    _assert_same_clustering(clusters(p), ref)
    _assert_same_clustering(clusters((n, m, p.rows, p.cols)), ref)
    # any order, duplicates allowed
    perm = np.random.default_rng(n * 31 + m).permutation(2 * p.n_pairs) % max(p.n_pairs, 1)
    _assert_same_clustering(clusters((n, m, p.rows[perm], p.cols[perm])), ref)


@settings(max_examples=150, deadline=None)
@given(problem=_gating_problem())
def test_gate_pairs_all_pairs_path_equals_kd_tree_path(problem):
    """Tiny problems skip the KD-tree (every pair is a candidate): the same gating, bit for bit."""
    z_pred, S, z, P_G, _, _ = problem
    n, m = z_pred.shape[0], z.shape[0]
    assert n * m <= gating_module.ALL_PAIRS_MAX  # the drawn problems take the all-pairs path
    fast = gate_pairs(z_pred, S, z, P_G=P_G)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(gating_module, "ALL_PAIRS_MAX", -1)
        tree = gate_pairs(z_pred, S, z, P_G=P_G)
    for name in ("rows", "cols", "d2", "log_g", "gate_volume", "log_gate_volume", "S", "chol"):
        a, b = getattr(fast, name), getattr(tree, name)
        assert a.dtype == b.dtype, name
        np.testing.assert_array_equal(a, b, err_msg=name)
    assert fast.n_candidates == n * m >= tree.n_candidates


@settings(max_examples=150, deadline=None)
@given(
    n=st.integers(0, 9),
    m=st.integers(0, 9),
    pairs=st.lists(st.tuples(st.integers(0, 8), st.integers(0, 8)), max_size=90),
)
def test_clusters_union_find_equals_sparse_graph(n, m, pairs):
    """Few pairs go through a Python union–find, many through scipy: the same Clustering."""
    pairs = [(i, j) for i, j in pairs if i < n and j < m]  # duplicates and any order kept
    rows = np.array([i for i, _ in pairs], dtype=np.int64)
    cols = np.array([j for _, j in pairs], dtype=np.int64)
    small = clusters((n, m, rows, cols))
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(clustering_module, "_SMALL_PAIRS", -1)
        graph = clusters((n, m, rows, cols))
    _assert_same_clustering(small, graph)
    dense = np.zeros((n, m), dtype=bool)
    dense[rows, cols] = True
    _assert_same_clustering(small, clusters(dense))


def test_gate_pairs_scales_linearly():
    """N = 3000 tracks, M = 4500 measurements, ~1 measurement per gate: no N × M work."""
    rng = np.random.default_rng(2024)
    n, m, d = 3000, 4500, 2
    P_G = 0.99
    gamma = stats.chi2.ppf(P_G, d)
    # anisotropic rotated gates (axis ratio up to 3) so the λ_max ball is a loose bound
    theta = rng.uniform(0, np.pi, n)
    R = np.stack([np.cos(theta), -np.sin(theta), np.sin(theta), np.cos(theta)], 1).reshape(n, 2, 2)
    ax = rng.uniform(0.5, 1.5, (n, 2)) ** 2
    S = R @ (ax[:, :, None] * np.eye(2)) @ np.swapaxes(R, 1, 2)
    mean_volume = np.mean(math.pi * gamma * np.sqrt(np.linalg.det(S)))
    side = math.sqrt(m * mean_volume)  # M·V̄/area = 1 measurement per gate on average
    z_pred = rng.uniform(0, side, (n, d))
    z = rng.uniform(0, side, (m, d))

    tracemalloc.start()
    try:
        p = gate_pairs(z_pred, S, z, P_G=P_G)
        c = clusters(p)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert p.n_candidates < 20 * (n + m)
    assert peak < n * m  # not even one N × M boolean array
    assert 0.5 * n < p.n_pairs < 2 * n  # about one measurement per gate
    # the sparse result is the dense one, checked on a block of tracks
    blk = slice(0, 300)
    g = gate_measurements(z_pred[blk], S[blk], z, P_G=P_G)
    sel = p.rows < 300
    r, cc = np.nonzero(g.mask)
    np.testing.assert_array_equal(p.rows[sel], r)
    np.testing.assert_array_equal(p.cols[sel], cc)
    np.testing.assert_allclose(p.d2[sel], g.d2[r, cc], rtol=1e-12, atol=1e-12)
    mask = np.zeros((n, m), dtype=bool)
    mask[p.rows, p.cols] = True
    _assert_same_clustering(c, clusters(mask))


def test_gate_pairs_extreme_scales_and_empty():
    # the extreme covariances of test_gate_log_space_extreme_covariances, plus a huge one
    # whose search radius overflows (every measurement becomes a candidate) and
    # coordinates whose squares overflow (the KD-tree switches to the enclosing cube)
    S = np.array([1e-300 * np.eye(2), 1e300 * np.eye(2), 8e307 * np.eye(2)])
    zp = np.zeros((3, 2))
    z = np.array([[1e-150, 0.0], [1e150, 0.0], [1e300, 1e300], [-1e308, 0.0]])
    g = gate_measurements(zp, S, z)
    p = gate_pairs(zp, S, z)
    np.testing.assert_array_equal(p.dense().mask, g.mask)
    np.testing.assert_allclose(p.d2, g.d2[g.mask], rtol=1e-12)
    np.testing.assert_allclose(p.log_g, g.log_g[g.mask], rtol=1e-12)
    np.testing.assert_array_equal(p.log_gate_volume, g.log_gate_volume)

    p = gate_pairs(np.zeros((0, 2)), np.zeros((0, 2, 2)), np.ones((3, 2)))
    assert p.n_pairs == 0 and p.dense().mask.shape == (0, 3) and p.n_candidates == 0
    L, miss = likelihood_ratio_pairs(p, 0.9, 1.0)
    assert L.shape == (0,) and miss.shape == (0,)
    _assert_same_clustering(clusters(p), clusters(np.zeros((0, 3), dtype=bool)))
    p = gate_pairs(np.zeros((2, 2)), np.array([np.eye(2)] * 2), np.zeros((0,)))
    assert p.dense().mask.shape == (2, 0)
    np.testing.assert_array_equal(p.n_gated, [0, 0])
    L, miss = likelihood_ratio_pairs(p, 0.9, 1.0)
    assert L.shape == (0,) and miss.shape == (2,)
    _assert_same_clustering(clusters(p), clusters(np.zeros((2, 0), dtype=bool)))
    # 1-D measurements
    p = gate_pairs([[0.0], [5.0]], [[[1.0]], [[4.0]]], [[0.5], [10.0], [4.0], [-20.0]])
    g = gate_measurements([[0.0], [5.0]], [[[1.0]], [[4.0]]], [[0.5], [10.0], [4.0], [-20.0]])
    np.testing.assert_array_equal(p.dense().mask, g.mask)


def test_gate_pairs_residual_falls_back_to_dense():
    # bearings near ±π: a wrapped residual gates across the cut, a Euclidean ball would not
    def wrap(zz, zp):
        r = zz - zp
        return (r + np.pi) % (2 * np.pi) - np.pi

    z_pred = np.array([[3.1], [0.0]])
    S = np.array([[[0.01]], [[0.01]]])
    z = np.array([[-3.1], [0.05], [1.0]])
    g = gate_measurements(z_pred, S, z, residual=wrap)
    p = gate_pairs(z_pred, S, z, residual=wrap)
    assert g.mask[0, 0]  # wrapped across ±π
    np.testing.assert_array_equal(p.dense().mask, g.mask)
    np.testing.assert_array_equal(p.d2, g.d2[g.mask])
    np.testing.assert_array_equal(p.log_g, g.log_g[g.mask])
    assert p.n_candidates == 6
    assert not gate_pairs(z_pred, S, z).dense().mask[0, 0]  # Euclidean: not gated
    with pytest.raises(ValueError, match="residual function.*<lambda>"):
        gate_pairs(z_pred, S, z, residual=lambda a, b: (a - b) + np.inf)


@pytest.mark.parametrize(
    ("S1", "msg"),
    [
        (np.array([[1.0, 2.0], [2.0, 1.0]]), "track 1.*not positive definite"),
        (np.array([[1.0, 0.3], [0.0, 1.0]]), "track 1.*not symmetric"),
        (np.array([[1.0, np.nan], [np.nan, 1.0]]), "track 1.*non-finite"),
        (np.array([[1.0, 0.0], [0.0, 1e-20]]), "track 1.*singular"),
        (np.zeros((2, 2)), "track 1.*singular"),
    ],
)
def test_gate_pairs_bad_covariance_same_error(S1, msg):
    S = np.array([np.eye(2), S1, np.eye(2)])
    with pytest.raises(ValueError, match=msg) as dense_err:
        gate_measurements(np.zeros((3, 2)), S, np.zeros((1, 2)))
    with pytest.raises(ValueError, match=msg) as pair_err:
        gate_pairs(np.zeros((3, 2)), S, np.zeros((1, 2)))
    assert str(pair_err.value) == str(dense_err.value)


def test_gate_pairs_bad_inputs_and_ratios():
    S = np.array([np.eye(2)])
    cases = [
        ((np.zeros((1, 2)), np.eye(2), np.zeros((1, 2))), {}, "S must have shape"),
        ((np.zeros((1, 2)), S, np.zeros((1, 3))), {}, "z must have shape"),
        ((np.zeros(2), S, np.zeros((1, 2))), {}, "z_pred must be 2-D"),
        ((np.zeros((1, 2)), S, np.zeros((1, 2))), {"P_G": 1.5}, "P_G"),
        ((np.zeros((1, 2)), S, np.array([[np.inf, 0.0]])), {}, "measurement z\\[0\\]"),
        ((np.array([[np.nan, 0.0]]), S, np.zeros((1, 2))), {}, "z_pred\\[0\\]"),
    ]
    for args, kw, msg in cases:
        with pytest.raises(ValueError, match=msg):
            gate_pairs(*args, **kw)
    p = gate_pairs(np.zeros((1, 2)), S, np.zeros((2, 2)))
    with pytest.raises(ValueError, match="P_D"):
        likelihood_ratio_pairs(p, 1.5, 1.0)
    with pytest.raises(ValueError, match="clutter_density"):
        likelihood_ratio_pairs(p, 0.9, 0.0)
    with pytest.raises(ValueError, match="clutter_density"):
        likelihood_ratio_pairs(p, 0.9, [1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match="PairGating"):
        likelihood_ratio_pairs(gate_measurements(np.zeros((1, 2)), S, np.zeros((2, 2))), 0.9, 1.0)
    with pytest.raises(ValueError, match="L\\[0, 0\\].*overflows"):
        likelihood_ratio_pairs(gate_pairs([[0.0]], [[[1e-300]]], [[0.0]]), 0.9, 1e-300)
    # the lazy package exports
    import jointtrack.association as assoc

    assert assoc.gate_pairs is gate_pairs and assoc.PairGating is PairGating
    assert assoc.likelihood_ratio_pairs is likelihood_ratio_pairs


def test_clusters_sparse_pairs_example_and_validation():
    mask = np.array(
        [
            [1, 0, 0, 0, 0],
            [0, 0, 1, 0, 0],
            [0, 1, 1, 0, 0],
            [0, 0, 0, 0, 0],
            [0, 1, 0, 0, 1],
        ],
        dtype=bool,
    )
    rows, cols = np.nonzero(mask)
    _assert_same_clustering(clusters((5, 5, rows, cols)), clusters(mask))
    _assert_same_clustering(clusters((np.int64(5), 5, list(rows), list(cols))), clusters(mask))
    _assert_same_clustering(clusters((0, 0, [], [])), clusters(np.zeros((0, 0))))
    _assert_same_clustering(clusters((3, 0, [], [])), clusters(np.zeros((3, 0))))
    _assert_same_clustering(clusters((0, 4, [], [])), clusters(np.zeros((0, 4))))
    # a 4-row mask given as a tuple of rows is still a dense mask
    _assert_same_clustering(clusters(tuple(map(tuple, mask[:4]))), clusters(mask[:4]))
    with pytest.raises(ValueError, match="cols index 5 out of range"):
        clusters((5, 5, [0], [5]))
    with pytest.raises(ValueError, match="rows index -1 out of range"):
        clusters((5, 5, [-1], [0]))
    with pytest.raises(ValueError, match="same length"):
        clusters((5, 5, [0, 1], [0]))
    with pytest.raises(ValueError, match="integer index"):
        clusters((5, 5, [0.5], [0]))
    with pytest.raises(ValueError, match="non-negative"):
        clusters((-1, 5, [], []))
