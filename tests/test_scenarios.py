"""Simulated scenarios (jointtrack.scenarios)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components

from jointtrack.io import Detections
from jointtrack.scenarios import (
    Scenario,
    bojilov,
    crossing,
    many_targets,
    ncv_matrices,
    nominal_gate,
    simulate_scenario,
)

GENERATORS = {
    "bojilov": lambda seed: bojilov(2.0, seed=seed),
    "crossing": lambda seed: crossing(seed=seed),
    "many_targets": lambda seed: many_targets(n_targets=100, clutter_per_scan=50, seed=seed),
}


def _same(a: Scenario, b: Scenario) -> bool:
    if a.n_scans != b.n_scans or not np.array_equal(a.times, b.times):
        return False
    for f in ("truth_ids", "truth_states", "detections", "origins"):
        for x, y in zip(getattr(a, f), getattr(b, f), strict=True):
            if x.shape != y.shape or not np.array_equal(x, y):
                return False
    return True


# ----------------------------------------------------------------------------- common


@pytest.mark.parametrize("name", list(GENERATORS))
def test_seeded_determinism(name):
    make = GENERATORS[name]
    a, b, c = make(11), make(11), make(12)
    assert _same(a, b)
    assert not _same(a, c)
    g = make(np.random.default_rng(11))
    assert _same(a, g)  # a Generator seeded 11 is the same stream as seed 11
    assert a.seed == 11 and g.seed is None


@pytest.mark.parametrize("name", list(GENERATORS))
def test_structure_is_consistent(name):
    sc = GENERATORS[name](3)
    d = sc.dim
    assert d == 2 and sc.region.shape == (2, 2) and sc.R.shape == (2, 2)
    assert sc.truth_positions[0].shape[1] == d
    for k in range(sc.n_scans):
        ids, X = sc.truth_ids[k], sc.truth_states[k]
        assert X.shape == (ids.size, 2 * d)
        assert np.all(np.diff(ids) > 0)  # sorted, unique
        Z, o = sc.detections[k], sc.origins[k]
        assert Z.shape == (o.size, d)
        assert set(o[o >= 0].tolist()) <= set(ids.tolist())
        assert np.unique(o[o >= 0]).size == np.sum(o >= 0)  # ≤ 1 detection per target
        clutter = Z[sc.is_clutter(k)]
        assert np.all((clutter >= sc.region[:, 0]) & (clutter <= sc.region[:, 1]))
    volume = np.prod(sc.region[:, 1] - sc.region[:, 0])
    assert sc.clutter_density == pytest.approx(sc.clutter_rate / volume)
    det = sc.as_detections()
    assert isinstance(det, Detections) and len(det) == sc.n_scans
    assert det.scans[5] is sc.detections[5] or np.array_equal(det.scans[5], sc.detections[5])
    t, ids, P = sc.truth_table()
    assert t.size == ids.size == P.shape[0] == sum(a.size for a in sc.truth_ids)
    assert 0 < sc.p_d < 1


@pytest.mark.parametrize("bad", ["abc", -1, 1.5, True])
def test_bad_seed(bad):
    with pytest.raises(ValueError, match="seed"):
        crossing(seed=bad)


def test_bad_parameters():
    with pytest.raises(ValueError, match="clutter_density"):
        bojilov(-1.0)
    with pytest.raises(ValueError, match="n_targets"):
        many_targets(n_targets=0)
    with pytest.raises(ValueError, match="angle"):
        crossing(angle_deg=200)
    with pytest.raises(ValueError, match="p_d"):
        crossing(p_d=1.5)
    with pytest.raises(ValueError, match="t_meet"):
        bojilov(t_meet=1000.0)


# ----------------------------------------------------------------------------- statistics


def test_clutter_count_is_poisson_with_the_rate():
    rate = 7.0
    counts = []
    for seed in range(40):
        sc = crossing(seed=seed, n_scans=25, clutter_per_scan=rate)
        counts += [int(np.sum(o < 0)) for o in sc.origins]
    counts = np.array(counts)
    n = counts.size
    assert abs(counts.mean() - rate) < 4 * np.sqrt(rate / n)
    # Poisson: variance = mean (dispersion within ±25 % for n = 1000)
    assert counts.var() / counts.mean() == pytest.approx(1.0, abs=0.25)


def test_clutter_is_uniform_over_the_region():
    sc = many_targets(n_targets=10, clutter_per_scan=100, seed=2, n_scans=30)
    C = np.concatenate([z[o < 0] for z, o in zip(sc.detections, sc.origins, strict=True)])
    for a in range(2):
        lo, hi = sc.region[a]
        assert stats.kstest((C[:, a] - lo) / (hi - lo), "uniform").pvalue > 1e-3


def test_measurement_noise_and_detection_probability():
    sc = many_targets(n_targets=100, clutter_per_scan=0, seed=5, n_scans=100, p_d=0.8)
    res, n_true, n_det = [], 0, 0
    for ids, X, Z, o in zip(sc.truth_ids, sc.truth_states, sc.detections, sc.origins, strict=True):
        n_true += ids.size
        n_det += o.size
        idx = np.searchsorted(ids, o)
        res.append(Z - X[idx, :2])
    res = np.concatenate(res)
    assert n_det / n_true == pytest.approx(0.8, abs=0.02)
    C = np.cov(res.T)
    assert C == pytest.approx(sc.R, abs=0.06 * sc.R[0, 0])
    assert abs(res.mean(0)).max() < 0.5


def test_truth_follows_ncv_with_its_process_noise():
    q = 0.5
    sc = many_targets(
        n_targets=200, clutter_per_scan=0, seed=8, n_scans=30, process_noise=q, p_survival=1.0,
        birth_rate=0.0, region=((-1e6, 1e6), (-1e6, 1e6)),
    )  # fmt: skip
    X = np.stack(sc.truth_states)  # no births/deaths: (K, N, 4)
    F, Q = ncv_matrices(sc.dt, q, 2)
    W = (X[1:] - X[:-1] @ F.T).reshape(-1, 4)
    C = np.cov(W.T)
    assert np.diag(C) == pytest.approx(np.diag(Q), rel=0.07)
    assert C[0, 2] == pytest.approx(Q[0, 2], rel=0.1)
    assert abs(C[0, 1]) < 0.1 * Q[0, 0]


def test_ncv_matrices():
    F, Q = ncv_matrices(2.0, 3.0, 2)
    assert F[0, 2] == 2.0 and F[1, 3] == 2.0 and F[0, 1] == 0.0
    assert Q[0, 0] == pytest.approx(3 * 8 / 3) and Q[0, 2] == pytest.approx(3 * 2)
    assert Q[2, 2] == pytest.approx(6.0)
    with pytest.raises(ValueError, match="dt"):
        ncv_matrices(0.0, 1.0)


# ----------------------------------------------------------------------------- Bojilov


def test_nominal_gate_is_the_steady_state_kalman_gate():
    g = nominal_gate(1.0, 1e-4, 10.0, 0.99)
    # iterate the one-axis Riccati recursion to convergence (independent of the DARE)
    F, Q = ncv_matrices(1.0, 1e-4, 1)
    H = np.array([[1.0, 0.0]])
    P = np.eye(2) * 1e4
    for _ in range(20000):
        Pp = F @ P @ F.T + Q
        S = float((H @ Pp @ H.T)[0, 0]) + 100.0
        K = Pp @ H.T / S
        P = (np.eye(2) - K @ H) @ Pp
    assert g["S"] == pytest.approx(S, rel=1e-6)
    assert g["gamma"] == pytest.approx(9.2103, abs=1e-4)
    assert g["volume"] == pytest.approx(np.pi * g["gamma"] * g["S"])
    assert g["radius"] == pytest.approx(31.03, abs=0.01)


def test_bojilov_clutter_unit_is_per_gate_area():
    s1, s2 = bojilov(1.0, seed=0), bojilov(2.0, seed=0)
    area = np.prod(s1.region[:, 1] - s1.region[:, 0])
    assert s1.clutter_rate == pytest.approx(area / s1.info["gate_area"])
    assert s2.clutter_rate == pytest.approx(2 * s1.clutter_rate)
    assert s1.clutter_density * s1.info["gate_area"] == pytest.approx(1.0)
    counts = np.array([np.sum(o < 0) for o in s2.origins])
    assert abs(counts.mean() - s2.clutter_rate) < 4 * np.sqrt(s2.clutter_rate / counts.size)


def _clusters(sc, k):
    """Sizes of the target clusters at scan k: truth-centred nominal gates sharing a detection."""
    r = sc.info["gate_radius"]
    D = np.linalg.norm(sc.truth_positions[k][:, None] - sc.detections[k][None], axis=2) < r
    A = (D.astype(int) @ D.T.astype(int)) > 0
    _, lab = connected_components(csr_matrix(A))
    return np.bincount(lab)


def test_bojilov_geometry_forms_4_to_5_target_clusters_mid_run():
    sc = bojilov(1.0, seed=1)
    r = sc.info["gate_radius"]
    P = np.stack(sc.truth_positions)  # (K, 5, 2)
    pair = np.linalg.norm(P[:, :, None] - P[:, None, :], axis=3)
    off = ~np.eye(5, dtype=bool)
    # separated at the start: no two 99 % gates overlap
    assert pair[0][off].min() > 2 * r
    assert pair[-1][off].min() > 2 * r
    # mid-run: all five within ~1.3 gate widths of each other, and neighbours'
    # detections fall in each other's gates (chained cluster)
    k = int(np.argmin(pair.max(axis=(1, 2))))
    assert abs(sc.times[k] - sc.info["t_meet"]) <= 2
    assert pair[k].max() < 2 * (2 * r)
    lanes = np.argsort(P[k, :, 1])
    assert np.all(np.linalg.norm(np.diff(P[k, lanes], axis=0), axis=1) < r)
    # with detections: clusters of >= 4 targets form at many scans, 5 at some
    biggest = np.array([_clusters(sc, k).max() for k in range(sc.n_scans)])
    assert np.sum(biggest >= 4) >= 10
    assert np.any(biggest == 5)
    assert np.all(biggest[:8] == 1)


def test_bojilov_tracks_are_parallel_with_different_speeds():
    sc = bojilov(1.0, seed=2)
    X = np.stack(sc.truth_states)
    assert np.ptp(X[:, :, 1], axis=0).max() < 10  # lanes stay within a few metres
    v = X[:, :, 2].mean(axis=0)
    assert np.all(np.diff(np.sort(v)) > 1.5)
    assert np.allclose(X[0, :, 3], 0.0)


# ----------------------------------------------------------------------------- crossing, many


def test_crossing_is_an_x():
    sc = crossing(seed=4, process_noise=0.0)
    P = np.stack(sc.truth_positions)
    d = np.linalg.norm(P[:, 0] - P[:, 1], axis=1)
    k = int(np.argmin(d))
    assert sc.times[k] == pytest.approx(sc.info["t_cross"])
    assert d[k] < 1e-9
    assert d[0] > 200 and d[-1] > 200
    vy = np.stack(sc.truth_states)[0, :, 3]
    assert vy[0] > 0 > vy[1]


def test_many_targets_births_and_deaths():
    sc = many_targets(n_targets=100, clutter_per_scan=50, seed=6)
    first = {}
    last = {}
    for k, ids in enumerate(sc.truth_ids):
        for i in ids.tolist():
            first.setdefault(i, k)
            last[i] = k
    assert sc.n_targets >= 150  # ≥ 100 initial + births
    born = sum(1 for k in first.values() if k > 0)
    died = sum(1 for k in last.values() if k < sc.n_scans - 1)
    assert born >= 30 and died >= 30
    assert born == sc.info["n_born"] and died == sc.info["n_died"]
    alive = np.array([ids.size for ids in sc.truth_ids])
    assert alive[0] == 100 and 75 <= alive.mean() <= 110
    clutter = np.array([np.sum(o < 0) for o in sc.origins])
    assert abs(clutter.mean() - 50) < 4 * np.sqrt(50 / clutter.size)


def test_simulate_scenario_from_a_given_truth():
    times = np.arange(3.0)
    ids = [np.array([4]), np.array([4, 9]), np.zeros(0, int)]
    states = [
        np.array([[0, 0, 1, 0.0]]),
        np.array([[1, 0, 1, 0], [5, 5, 0, 0.0]]),
        np.zeros((0, 4)),
    ]
    sc = simulate_scenario(
        "custom", times, ids, states, region=[[-10, 10], [-10, 10]], p_d=1.0,
        clutter_rate=0.0, R=np.eye(2) * 1e-6, process_noise=0.0, rng=0,
    )  # fmt: skip
    assert [o.tolist() for o in map(np.sort, sc.origins)] == [[4], [4, 9], []]
    assert sc.detections[2].shape == (0, 2)
    with pytest.raises(ValueError, match="R must"):
        simulate_scenario(
            "x", times, ids, states, region=[[0, 1], [0, 1]], p_d=1, clutter_rate=0,
            R=-np.eye(2), process_noise=0, rng=0,
        )  # fmt: skip


def test_abreast_is_issue_11s_scene():
    from jointtrack.scenarios import abreast

    sc = abreast(3)
    assert sc.n_scans == 80 and sc.n_targets == 5 and sc.p_d == 0.9
    assert sc.clutter_density == pytest.approx(60 / (900 * 200))
    x0 = sc.truth_states[0]
    np.testing.assert_allclose(np.diff(x0[:, 1]), 20.0)  # lanes 20 apart
    np.testing.assert_allclose(x0[:, 2], 1.0)  # 1 unit/s in +x
    assert np.allclose(sc.R, 25.0 * np.eye(2))
    with pytest.raises(ValueError, match="lane_spacing"):
        abreast(0, lane_spacing=-1.0)
