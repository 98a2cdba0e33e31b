"""Identity-aware JPDA (jointtrack.identity.jpda, Schaub §2-D).

The references are built here: the identity evidence and the
identity-conditional association probabilities are checked against a brute
enumeration of the joint association events (no package association code);
certain association against the filter bank's own K factor (eq. 29); the
identity-blind tracker against the package's plain JPDATracker; and the
crossing against position-only JPDA on the same scans.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from scipy import stats

import jointtrack.identity.jpda as jpda_module
from jointtrack.identity.crossing import identity_crossing, track_swapped
from jointtrack.identity.database import Identity, IdentityDatabase
from jointtrack.identity.filterbank import FilterBank
from jointtrack.identity.jpda import IdentityJPDA, IdentityJPDAConfig
from jointtrack.models.motion import cv_transition
from jointtrack.trackers import JPDATracker, TrackerConfig

SEEDS = range(20)


# ----------------------------------------------------------------------------- helpers


class _SchaubMotion:
    """The database's discrete white-noise acceleration model (eq. 44) for JPDATracker,
    so that the position-only tracker assumes exactly the identity tracker's motion."""

    def __init__(self, db: IdentityDatabase):
        self.db = db
        self.state_dim = db.state_dim

    def transition(self, dt):
        return cv_transition(dt, self.db.dim)

    def noise(self, dt):
        return self.db.process_noise_cov(dt)[0]


def _P0(scenario):
    s2 = scenario.measurement_noise[0, 0]
    return np.diag([s2, s2, 1.0, 1.0])


def _position_jpda(scenario, clutter_density):
    """Plain JPDA on positions, two confirmed tracks started on the truth: (N, K−1, 2)."""
    config = TrackerConfig(
        dim=2,
        measurement_noise=float(scenario.measurement_noise[0, 0]),
        p_d=scenario.p_d,
        p_g=0.99,
        clutter_density=clutter_density,
        existence=False,
        # no track management: clutter-born tracks stay tentative (30 of 30 hits
        # of a nearly stationary gate) and see only returns no confirmed track
        # gated; the started tracks are neither deleted nor merged
        initiation="one-point",
        max_speed=1e-3,
        confirm_m=30,
        confirm_n=30,
        delete_misses=10**6,
        merge_threshold=0.0,
    )
    tracker = JPDATracker(config, motion=_SchaubMotion(scenario.database), keep_history=False)
    ids = tracker.start_tracks(scenario.truth[:, 0], _P0(scenario))
    tracker.step(scenario.times[0], np.zeros((0, 2)))  # sets the clock; nothing to update
    path = []
    for t, Z in zip(scenario.times[1:], scenario.measurements[1:], strict=True):
        tracker.step(t, Z[:, :2])
        rows = [int(np.flatnonzero(tracker.ids == i)[0]) for i in ids]
        path.append(tracker.x[rows, :2])
    return np.stack(path, axis=1)


def _identity_jpda(scenario, config=None):
    """The identity-aware tracker on the truth's start: positions (N, K−1, 2), last scan."""
    tracker = IdentityJPDA(scenario.database, config or scenario.tracker_config())
    tracker.start(scenario.times[0], scenario.truth[:, 0], _P0(scenario))
    path, scans = [], []
    for t, Z in zip(scenario.times[1:], scenario.measurements[1:], strict=True):
        scans.append(tracker.step(t, Z))
        path.append(scans[-1].mean[:, :2])
    return np.stack(path, axis=1), scans


def _snapshot(tracker):
    mean, cov = tracker.estimate()
    return {
        "time": tracker.time,
        "log_a": tracker.log_a,
        "P": tracker.P,
        "class_mean": tracker.class_mean,
        "class_cov": tracker.class_cov,
        "mean": mean,
        "cov": cov,
    }


def _assert_same(a, b):
    assert a.keys() == b.keys()
    for key in a:
        np.testing.assert_array_equal(a[key], b[key], err_msg=key)


@pytest.fixture(scope="module")
def crossing_runs():
    """Both trackers on seeds 0–19 of the default crossing (shared by several tests)."""
    runs = []
    for seed in SEEDS:
        scenario = identity_crossing(seed)
        truth = scenario.truth[:, 1:, :2]
        plain = _position_jpda(scenario, scenario.position_clutter_density)
        aware, scans = _identity_jpda(scenario)
        runs.append((scenario, track_swapped(plain, truth), track_swapped(aware, truth), scans))
    return runs


# ----------------------------------------------------------------------------- the crossing


def test_position_jpda_swaps_where_identity_aware_jpda_does_not(crossing_runs):
    # Measured on seeds 0–19 of the defaults: position-only JPDA ends swapped in
    # 14 seeds (46 of seeds 0–59), the identity-aware tracker in none.
    plain = sum(bool(p.any()) for _, p, _, _ in crossing_runs)
    aware = sum(bool(a.any()) for _, _, a, _ in crossing_runs)
    assert plain >= 12, f"position-only JPDA swapped in only {plain} of {len(SEEDS)} seeds"
    assert aware == 0, f"identity-aware JPDA swapped in {aware} of {len(SEEDS)} seeds"


def test_identities_end_on_the_true_targets(crossing_runs):
    for _, _, _, scans in crossing_runs:
        P = scans[-1].P  # track k started on target k, which is identity k
        assert np.diag(P).min() > 0.99, P


def test_association_and_deconfliction_are_probabilities(crossing_runs):
    for _, _, _, scans in crossing_runs[:5]:
        previous = None
        for scan in scans:
            assert (scan.beta >= 0).all()
            np.testing.assert_allclose(scan.beta.sum(axis=1), 1.0, atol=1e-12)
            # as many tracks as identities: P is doubly stochastic
            np.testing.assert_allclose(scan.P.sum(axis=1), 1.0, atol=1e-9)
            np.testing.assert_allclose(scan.P.sum(axis=0), 1.0, atol=1e-9)
            assert (scan.P >= 0).all()
            if previous is not None:  # the association used the previous deconfliction
                np.testing.assert_array_equal(scan.P_prior, previous.P)
            previous = scan


def test_identity_blind_tracker_is_plain_jpda():
    # With the attribute unmeasured every class has the same density, so the
    # mixture is one Gaussian and the tracker must be JPDA on positions exactly.
    scenario = identity_crossing(4)
    R = scenario.measurement_noise.copy()
    R[2, 2] = np.inf
    blind = IdentityJPDAConfig(R, scenario.position_clutter_density, p_d=scenario.p_d)
    ours, scans = _identity_jpda(scenario, blind)
    theirs = _position_jpda(scenario, scenario.position_clutter_density)
    np.testing.assert_allclose(ours, theirs, rtol=0, atol=1e-8)
    np.testing.assert_allclose(scans[-1].P, 0.5)  # nothing tells the identities apart


def test_three_targets_hold_their_identities():
    scenario = identity_crossing(2, attributes=(0.0, 10.0, 20.0))
    est, scans = _identity_jpda(scenario)
    assert not track_swapped(est, scenario.truth[:, 1:, :2]).any()
    assert np.diag(scans[-1].P).min() > 0.99


# ----------------------------------------------------------------------------- the identity update


def _two_identities(noise_a=0.5, noise_b=2.0, p_d=1.0):
    return IdentityDatabase(
        [Identity("a", noise_a, 0.0, p_d=p_d), Identity("b", noise_b, 10.0, p_d=p_d)]
    )


@pytest.mark.parametrize(
    "R",
    [
        np.diag([4.0, 4.0, 6.0]),
        # position and attribute noise correlated: the kinematic update is
        # conditioned on the attribute residual, per class
        np.array([[4.0, 0.5, 1.5], [0.5, 4.0, -1.0], [1.5, -1.0, 6.0]]),
    ],
    ids=["diagonal", "correlated"],
)
def test_certain_association_is_the_filter_banks_k_factor(R):
    # one target, no clutter, p_d = 1 and no gate (p_g = 1): β = [0, 1] every scan,
    # so the identity update must be Schaub's K factor up to a per-track constant
    db = _two_identities()
    config = IdentityJPDAConfig(R, clutter_density=1e-3, p_g=1.0, velocity_cov=4.0)
    tracker = IdentityJPDA(db, config)
    bank = FilterBank(db, velocity_cov=4.0)
    rng = np.random.default_rng(7)
    z = np.array([0.0, 0.0, 1.5])
    tracker.start_on_measurements(0.0, [z])
    bank.start(0.0, z, R)
    np.testing.assert_allclose(tracker.log_a[0], bank.log_a)
    for k in range(1, 8):
        z = np.array([3.0 * k, -1.0 * k, 1.0]) + rng.normal(0.0, 2.0, 3)
        before, before_bank = tracker.log_a[0], bank.log_a.copy()
        scan = tracker.step(float(k), z[None])
        bank.update(float(k), z, R)
        np.testing.assert_allclose(scan.beta, [[0.0, 1.0]], atol=1e-15)
        ours, schaub = tracker.log_a[0] - before, bank.log_a - before_bank
        shift = ours - schaub
        assert np.ptp(shift) < 1e-9, (ours, schaub)  # equal up to one constant
        np.testing.assert_allclose(tracker.class_mean[0], bank.mean, rtol=1e-10, atol=1e-9)
        np.testing.assert_allclose(tracker.class_cov[0], bank.cov, rtol=1e-10, atol=1e-9)


def _gaussian(z, mean, S):
    return math.exp(stats.multivariate_normal(mean, S).logpdf(z))


def _events(n_tracks, n_meas):
    """Every joint association event: a tuple, track → measurement index or −1."""
    for choice in itertools.product(range(-1, n_meas), repeat=n_tracks):
        used = [j for j in choice if j >= 0]
        if len(used) == len(set(used)):
            yield choice


def _normaliser(rows_L, rows_miss, fixed=None):
    """Σ over events of Π L[t, j] Π miss[t]; ``fixed = (t, j)`` keeps events with t → j."""
    total = 0.0
    for event in _events(len(rows_L), len(rows_L[0])):
        if fixed is not None and event[fixed[0]] != fixed[1]:
            continue
        w = 1.0
        for t, j in enumerate(event):
            w *= rows_miss[t] if j < 0 else rows_L[t][j]
        total += w
    return total


def test_identity_evidence_is_the_ratio_of_jpda_normalisers():
    # Two tracks sharing measurements. f[t, c] must be Z_c / Z (track t's row
    # from class c, the other track's its mixture) and the class filters must be
    # updated with P(z_j is t's | t holds c) — checked by enumeration.
    db = IdentityDatabase(
        [Identity("a", 0.5, 0.0, p_d=0.9), Identity("b", 2.0, 10.0, p_d=0.7)], dim=2
    )
    R = np.diag([9.0, 9.0, 6.0])
    lam, p_g = 2e-4, 0.999
    tracker = IdentityJPDA(db, IdentityJPDAConfig(R, lam, p_g=p_g))
    x0 = np.array([[0.0, 0.0, 10.0, 0.5], [0.0, 12.0, 10.0, -0.5]])
    P0 = np.diag([16.0, 16.0, 1.0, 1.0])
    tracker.start(0.0, x0, P0)
    Z1 = np.array([[9.0, 1.0, 1.0], [11.0, 10.0, 9.0], [10.0, 5.0, 4.0]])
    tracker.step(1.0, Z1)  # makes P uneven, so the mixtures are genuine mixtures
    P_prior, log_a = tracker.P, tracker.log_a
    means, covs = tracker.class_mean, tracker.class_cov
    Z = np.array([[20.0, 3.0, 2.0], [21.0, 9.0, 8.0], [19.0, 6.0, 5.0], [40.0, 40.0, 3.0]])
    scan = tracker.step(2.0, Z)

    F = cv_transition(1.0, 2)
    Q = db.process_noise_cov(1.0)
    gamma = stats.chi2.ppf(p_g, 3)
    T, C, M = 2, 2, len(Z)
    L_class = np.zeros((T, C, M))
    miss_class = 1.0 - p_g * db.p_d
    pred_mean = np.zeros((T, C, 4))
    pred_cov = np.zeros((T, C, 4, 4))
    for t in range(T):
        for c in range(C):
            m, P = F @ means[t, c], F @ covs[t, c] @ F.T + Q[c]
            pred_mean[t, c], pred_cov[t, c] = m, P
            zhat = np.array([m[0], m[1], db.attributes[c, 0]])
            S = R.copy()
            S[:2, :2] += P[:2, :2]
            for j in range(M):
                nu = Z[j] - zhat
                if nu @ np.linalg.solve(S, nu) <= gamma:
                    L_class[t, c, j] = db.p_d[c] * _gaussian(Z[j], zhat, S) / lam
    w = P_prior  # two identities, one per class
    L_mix = np.einsum("tc,tcj->tj", w, L_class)
    miss_mix = w @ miss_class
    Z_mix = _normaliser(L_mix, miss_mix)
    beta = np.array(
        [[_normaliser(L_mix, miss_mix, (t, j)) / Z_mix for j in range(-1, M)] for t in range(T)]
    )
    np.testing.assert_allclose(scan.beta, beta, rtol=1e-9, atol=1e-12)
    H = np.eye(2, 4)
    for t in range(T):
        for c in range(C):
            L_c, miss_c = L_mix.copy(), miss_mix.copy()
            L_c[t], miss_c[t] = L_class[t, c], miss_class[c]
            Z_c = _normaliser(L_c, miss_c)
            increment = tracker.log_a[t, c] - log_a[t, c]
            assert increment == pytest.approx(math.log(Z_c / Z_mix), rel=1e-9, abs=1e-12)
            # the class filter: PDA with P(z_j is t's | t holds c)
            beta_c = [_normaliser(L_c, miss_c, (t, j)) / Z_c for j in range(M)]
            m, P = pred_mean[t, c], pred_cov[t, c]
            S = H @ P @ H.T + R[:2, :2]
            K = P @ H.T @ np.linalg.inv(S)
            innovation = sum(b * (Z[j, :2] - H @ m) for j, b in enumerate(beta_c))
            np.testing.assert_allclose(tracker.class_mean[t, c], m + K @ innovation, atol=1e-8)


def test_fewer_tracks_than_identities_use_hidden_tracks():
    # one track, three identities: two sit on hidden tracks (eq. 1). y and z are
    # one class (same model and attribute), so they get equal probabilities.
    db = IdentityDatabase(
        [Identity("x", 1.0, 0.0), Identity("y", 1.0, 5.0), Identity("z", 1.0, 5.0)]
    )
    tracker = IdentityJPDA(db, IdentityJPDAConfig(np.diag([4.0, 4.0, 4.0]), 1e-3))
    tracker.start(0.0, [[0.0, 0.0, 1.0, 0.0]], np.eye(4))
    for k in range(1, 6):
        scan = tracker.step(float(k), [[float(k), 0.0, 4.8]])
    assert scan.P.shape == (1, 3)
    np.testing.assert_allclose(scan.P.sum(), 1.0)
    assert scan.P[0, 1] == pytest.approx(scan.P[0, 2])
    assert scan.P[0, 1] + scan.P[0, 2] > 0.99


def test_unmeasured_attribute_columns_may_be_nan():
    db = _two_identities(p_d=0.9)
    R = np.array([4.0, 4.0, np.inf])
    tracker = IdentityJPDA(db, IdentityJPDAConfig(R, 1e-3))
    tracker.start(0.0, [[0.0, 0.0, 1.0, 0.0], [0.0, 50.0, 1.0, 0.0]], np.eye(4))
    scan = tracker.step(1.0, [[1.0, 0.0, np.nan], [1.0, 50.0, np.nan]])
    np.testing.assert_allclose(scan.P, 0.5)
    assert scan.beta[0, 1] > 0.99 and scan.beta[1, 2] > 0.99


def test_no_measurements_is_a_prediction():
    db = _two_identities(p_d=0.9)
    tracker = IdentityJPDA(db, IdentityJPDAConfig(np.diag([4.0, 4.0, 6.0]), 1e-3))
    tracker.start(0.0, [[0.0, 0.0, 1.0, 0.0]], np.eye(4))
    scan = tracker.step(2.0, np.zeros((0, 3)))
    np.testing.assert_allclose(scan.beta, [[1.0]])
    np.testing.assert_allclose(scan.mean[0], [2.0, 0.0, 1.0, 0.0])
    # equal detection probabilities: a miss says nothing about the identity
    np.testing.assert_allclose(tracker.log_a, 0.0, atol=1e-15)


# ----------------------------------------------------------------------------- atomic steps


def _small_tracker():
    db = _two_identities(p_d=0.9)
    tracker = IdentityJPDA(db, IdentityJPDAConfig(np.diag([4.0, 4.0, 6.0]), 1e-3))
    tracker.start(0.0, [[0.0, 0.0, 1.0, 0.0], [0.0, 5.0, 1.0, 0.0]], np.eye(4))
    tracker.step(1.0, [[1.0, 0.2, 0.5], [1.1, 5.0, 9.0], [30.0, 30.0, 3.0]])
    return tracker


SCAN = [[2.0, 0.1, 0.8], [2.1, 4.9, 10.5]]


@pytest.mark.parametrize("where", ["deconflict", "pda_update", "marginals"])
def test_a_failing_step_leaves_the_tracker_unchanged(monkeypatch, where):
    tracker = _small_tracker()
    before = _snapshot(tracker)

    def fail(*args, **kwargs):
        raise RuntimeError(f"injected failure in {where}")

    monkeypatch.setattr(jpda_module, where, fail)
    with pytest.raises(RuntimeError, match="injected"):
        tracker.step(2.0, SCAN)
    _assert_same(_snapshot(tracker), before)
    monkeypatch.undo()
    # the same scan then runs as on a tracker that never failed
    retried = tracker.step(2.0, SCAN)
    fresh = _small_tracker().step(2.0, SCAN)
    np.testing.assert_array_equal(retried.mean, fresh.mean)
    np.testing.assert_array_equal(retried.P, fresh.P)


def test_bad_input_leaves_the_tracker_unchanged():
    tracker = _small_tracker()
    before = _snapshot(tracker)
    for t, Z in ((2.0, [[2.0, np.nan, 1.0]]), (0.5, SCAN), (2.0, [[1.0, 2.0]])):
        with pytest.raises(ValueError):
            tracker.step(t, Z)
        _assert_same(_snapshot(tracker), before)


# ----------------------------------------------------------------------------- hostile input


R3 = np.diag([4.0, 4.0, 6.0])


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"measurement_noise": R3 + 0j, "clutter_density": 1e-3}, "measurement_noise"),
        ({"measurement_noise": R3 > 0, "clutter_density": 1e-3}, "measurement_noise"),
        ({"measurement_noise": np.zeros((2, 2, 2)), "clutter_density": 1e-3}, "measurement_noise"),
        ({"measurement_noise": R3, "clutter_density": 0.0}, "clutter_density"),
        ({"measurement_noise": R3, "clutter_density": np.nan}, "clutter_density"),
        ({"measurement_noise": R3, "clutter_density": True}, "clutter_density"),
        ({"measurement_noise": R3, "clutter_density": 1e-3 + 1j}, "clutter_density"),
        ({"measurement_noise": R3, "clutter_density": 1e-3, "p_d": 1.5}, "p_d"),
        ({"measurement_noise": R3, "clutter_density": 1e-3, "p_d": 0.0}, "p_d"),
        ({"measurement_noise": R3, "clutter_density": 1e-3, "p_g": 0.0}, "p_g"),
        ({"measurement_noise": R3, "clutter_density": 1e-3, "p_g": 1.01}, "p_g"),
        ({"measurement_noise": R3, "clutter_density": 1e-3, "p_g": np.nan}, "p_g"),
        ({"measurement_noise": R3, "clutter_density": 1e-3, "velocity_cov": -1.0}, "velocity_cov"),
    ],
)
def test_bad_config_is_named(kwargs, name):
    with pytest.raises(ValueError, match=name):
        IdentityJPDAConfig(**kwargs)


@pytest.mark.parametrize(
    ("R", "velocity_cov", "name"),
    [
        (np.diag([4.0, 4.0]), 0.0, "measurement_noise"),  # the database has an attribute
        (np.diag([np.inf, 4.0, 6.0]), 0.0, "measurement_noise"),  # a position unmeasured
        (np.array([[4.0, 1.0, 0], [0, 4.0, 0], [0, 0, 6.0]]), 0.0, "measurement_noise"),
        (np.diag([4.0, -4.0, 6.0]), 0.0, "measurement_noise"),
        (R3, np.eye(3), "velocity_cov"),
    ],
)
def test_config_that_does_not_fit_the_database_is_named(R, velocity_cov, name):
    config = IdentityJPDAConfig(R, 1e-3, velocity_cov=velocity_cov)
    with pytest.raises(ValueError, match=name):
        IdentityJPDA(_two_identities(), config)


def test_wrong_types_are_named():
    config = IdentityJPDAConfig(R3, 1e-3)
    with pytest.raises(ValueError, match="database"):
        IdentityJPDA("db", config)
    with pytest.raises(ValueError, match="config"):
        IdentityJPDA(_two_identities(), {"measurement_noise": R3})
    with pytest.raises(RuntimeError, match="start"):
        IdentityJPDA(_two_identities(), config).step(1.0, SCAN)


@pytest.mark.parametrize(
    ("t", "x0", "P0", "name"),
    [
        (np.nan, [[0, 0, 1, 0]], np.eye(4), "t"),
        (1j, [[0, 0, 1, 0]], np.eye(4), "t"),
        (True, [[0, 0, 1, 0]], np.eye(4), "t"),
        (0.0, [0, 0, 1, 0], np.eye(4), "x0"),
        (0.0, [[0, 0, 1]], np.eye(4), "x0"),
        (0.0, [[0, 0, 1, np.nan]], np.eye(4), "x0"),
        (0.0, [[0, 0, 1, 0]] * 3, np.eye(4), "x0"),  # more tracks than identities
        (0.0, [[0, 0, 1, 0], [1, 1, 1, 1]], np.eye(4)[None].repeat(3, 0), "P0"),
        (0.0, [[0, 0, 1, 0]], np.triu(np.ones((4, 4))), "P0"),
        (0.0, [[0, 0, 1, 0]], -np.eye(4), "P0"),
        (0.0, [[0, 0, 1, 0]], np.eye(4) + 0j, "P0"),
    ],
)
def test_bad_start_is_named(t, x0, P0, name):
    tracker = IdentityJPDA(_two_identities(), IdentityJPDAConfig(R3, 1e-3))
    with pytest.raises(ValueError, match=name):
        tracker.start(t, x0, P0)
    assert not tracker.started


@pytest.mark.parametrize(
    ("t", "Z", "name"),
    [
        (1.0, [[0.0, 0.0, 1.0]], "t"),  # not after the tracker's time (1.0)
        (0.5, [[0.0, 0.0, 1.0]], "t"),
        (np.nan, [[0.0, 0.0, 1.0]], "t"),
        (2.0 + 0j, [[0.0, 0.0, 1.0]], "t"),
        (False, [[0.0, 0.0, 1.0]], "t"),
        (2.0, [0.0, 0.0, 1.0], "measurements"),
        (2.0, [[0.0, 0.0]], "measurements"),
        (2.0, [[0.0, np.inf, 1.0]], "measurements"),
        (2.0, [[0.0, 0.0, np.nan]], "measurements"),  # the attribute is measured
        (2.0, [[0.0, 0.0, 1.0 + 1j]], "measurements"),
        (2.0, [[True, False, True]], "measurements"),
        (2.0, "abc", "measurements"),
    ],
)
def test_bad_step_is_named(t, Z, name):
    tracker = _small_tracker()
    with pytest.raises(ValueError, match=name):
        tracker.step(t, Z)


def test_bad_start_on_measurements_is_named():
    tracker = IdentityJPDA(_two_identities(), IdentityJPDAConfig(R3, 1e-3))
    with pytest.raises(ValueError, match="measurements"):
        tracker.start_on_measurements(0.0, [[0.0, 0.0, np.nan]])
    with pytest.raises(ValueError, match="measurements"):
        tracker.start_on_measurements(0.0, np.zeros((3, 3)))  # 3 tracks, 2 identities
    with pytest.raises(ValueError, match="measurements"):
        tracker.start_on_measurements(0.0, np.zeros((0, 3)))
    assert not tracker.started


# ----------------------------------------------------------------------------- scenario and swaps


def test_crossing_scenario_is_reproducible_and_consistent():
    a, b = identity_crossing(3), identity_crossing(3)
    np.testing.assert_array_equal(a.truth, b.truth)
    for za, zb, origin in zip(a.measurements, b.measurements, a.origins, strict=True):
        np.testing.assert_array_equal(za, zb)
        assert za.shape == (origin.size, 3)
        assert set(origin.tolist()) <= {-1, 0, 1}
    assert a.database.names == ("target 0", "target 1")
    assert a.truth.shape == (2, 61, 4)
    # the paths cross: the order of the targets in y flips
    y = a.truth[:, :, 1]
    assert y[0, 0] < y[1, 0] and y[0, -1] > y[1, -1]
    # the truth flies straight by default
    np.testing.assert_allclose(np.diff(a.truth[:, :, 2:], axis=1), 0.0, atol=1e-12)
    # attribute readings of the targets scatter around their values
    origin = np.concatenate(a.origins)
    attr = np.concatenate(a.measurements)[:, 2]
    assert abs(attr[origin == 1].mean() - 10.0) < 1.0
    assert a.clutter_density == pytest.approx(
        a.position_clutter_density / np.ptp(a.attribute_range)
    )


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"seed": -1}, "seed"),
        ({"seed": 1.5}, "seed"),
        ({"n_scans": 1}, "n_scans"),
        ({"angle_deg": 180.0}, "angle_deg"),
        ({"attributes": (1.0,)}, "attributes"),
        ({"attributes": (0.0, 1j)}, "attributes"),
        ({"attribute_variance": 0.0}, "attribute_variance"),
        ({"process_noise": (1.0, 1.0, 1.0)}, "process_noise"),
        ({"truth_process_noise": -1.0}, "truth_process_noise"),
        ({"p_d": 0.0}, "p_d"),
        ({"clutter_per_scan": np.nan}, "clutter_per_scan"),
    ],
)
def test_bad_scenario_parameters_are_named(kwargs, name):
    with pytest.raises(ValueError, match=name):
        identity_crossing(**kwargs)


def test_track_swapped():
    truth = np.zeros((2, 10, 2))
    truth[1, :, 1] = 10.0
    kept = truth + 1.0
    swapped = truth[::-1] + 1.0
    assert track_swapped(kept, truth).tolist() == [False, False]
    assert track_swapped(swapped, truth).tolist() == [True, True]
    # a swap only for the last 3 scans is not a swap "for the last 5"
    late = kept.copy()
    late[:, -3:] = swapped[:, -3:]
    assert track_swapped(late, truth).tolist() == [False, False]
    assert track_swapped(late, truth, n_last=3).tolist() == [True, True]
    # both tracks on target 1: track 0 left its target, track 1 did not
    merged = np.repeat(truth[1:2], 2, axis=0)
    assert track_swapped(merged, truth).tolist() == [True, False]
    with pytest.raises(ValueError, match="n_last"):
        track_swapped(kept, truth, n_last=11)
    with pytest.raises(ValueError, match="truth_positions"):
        track_swapped(kept, truth[:, :5])
