"""Close pairs keep their ids (issue 32, item 3): JPDA* against exact brute force, the
``coalescence_avoidance`` switch, and the close-pairs scenario's truth."""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from brute import log_fraction
from jointtrack.association import exact_marginals
from jointtrack.association.coalescence import jpda_star, jpda_star_marginals
from jointtrack.errors import ExactLimitError, InfeasibleAssignmentError
from jointtrack.scenarios import close_pairs
from jointtrack.trackers import JPDATracker, TrackerConfig

# ---------------------------------------------------------------------------
# reference: JPDA* by listing every joint event, in exact rationals
# ---------------------------------------------------------------------------


def brute_jpda_star(L, miss):
    """``(beta, Z*)`` as Fractions: every feasible event, grouped by (detected tracks,
    measurements used); per group the events of the largest weight share its weight
    equally (one event unless exact ties). Raises ZeroDivisionError if nothing has weight."""
    L = np.asarray(L, float)
    N, M = L.shape
    F = [[Fraction(float(x)) for x in row] for row in L]
    U = [Fraction(float(x)) for x in miss]
    groups: dict = {}

    def rec(i, a, used, w):
        if w == 0:
            return
        if i == N:
            key = (tuple(c > 0 for c in a), frozenset(c for c in a if c))
            groups.setdefault(key, []).append((tuple(a), w))
            return
        rec(i + 1, [*a, 0], used, w * U[i])
        for j in range(M):
            if j not in used and F[i][j] > 0:
                rec(i + 1, [*a, j + 1], used | {j}, w * F[i][j])

    rec(0, [], frozenset(), Fraction(1))
    acc = [[Fraction(0)] * (M + 1) for _ in range(N)]
    total = Fraction(0)
    for events in groups.values():
        top = max(w for _, w in events)
        best = [a for a, w in events if w == top]
        for a in best:
            for i, c in enumerate(a):
                acc[i][c] += top / len(best)
        total += top
    if total == 0:
        raise ZeroDivisionError("no feasible joint event")
    return [[x / total for x in row] for row in acc], total


# values from zero and subnormals to 1e300, and a few repeated ones (exact ties)
VALUES = st.one_of(
    st.just(0.0),
    st.sampled_from([5e-324, 1e-300, 0.5, 1.0, 3.0, 1e300]),
    st.floats(min_value=5e-324, max_value=1e300, allow_subnormal=True),
)
MISS = st.one_of(
    st.just(0.0),
    st.sampled_from([5e-324, 1e-300, 0.1, 0.5, 1.0]),
    st.floats(min_value=5e-324, max_value=1.0, allow_subnormal=True),
)


@st.composite
def clusters(draw, max_n=4, max_m=4):
    n = draw(st.integers(1, max_n))
    m = draw(st.integers(0, max_m))
    L = np.array(draw(st.lists(VALUES, min_size=n * m, max_size=n * m)), float).reshape(n, m)
    miss = np.array(draw(st.lists(MISS, min_size=n, max_size=n)), float)
    return L, miss


#: |β − β_exact| bound: each event's probability is exp(log w − log Z) with log w a
#: sum of ≤ 4 logs of magnitude ≤ 745, i.e. ≤ 4·745·2⁻⁵² ≈ 7e-13 relative; β is a ratio
#: of sums of such terms (≤ 2× that), 1e-11 leaves a margin
ATOL = 1e-11


@settings(max_examples=50, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(clusters())
@example((np.array([[1.0, 1.0], [1.0, 1.0]]), np.array([0.5, 0.5])))  # every event tied
@example((np.array([[1e300, 5e-324], [5e-324, 1e300]]), np.array([5e-324, 0.0])))
@example((np.zeros((2, 0)), np.array([0.3, 1.0])))
def test_jpda_star_matches_exact_brute_force(cluster):
    L, miss = cluster
    try:
        ref, total = brute_jpda_star(L, miss)
    except ZeroDivisionError:
        with pytest.raises(InfeasibleAssignmentError):
            jpda_star(L, miss)
        return
    res = jpda_star(L, miss)
    exact = np.array([[float(x) for x in row] for row in ref]).reshape(res.beta.shape)
    assert np.all(np.isfinite(res.beta))
    np.testing.assert_allclose(res.beta, exact, rtol=0, atol=ATOL)
    np.testing.assert_allclose(res.beta.sum(axis=1), 1.0, rtol=0, atol=1e-14)
    # log Z*: the kept weights' sum, beyond the float range (rounding of ≤ 4 logs)
    assert abs(res.log_normalizer - log_fraction(total)) <= 1e-12 * max(
        1.0, abs(log_fraction(total))
    )


@settings(max_examples=25, deadline=None)
@given(clusters(max_n=3, max_m=4), st.randoms(use_true_random=False))
def test_jpda_star_does_not_depend_on_the_track_order(cluster, rnd):
    L, miss = cluster
    try:
        beta = jpda_star_marginals(L, miss)
    except InfeasibleAssignmentError:
        return
    perm = list(range(len(L)))
    rnd.shuffle(perm)
    np.testing.assert_allclose(jpda_star_marginals(L[perm], miss[perm]), beta[perm], atol=ATOL)


def test_one_track_is_plain_pda():
    L = np.array([[2.0, 0.0, 7.0]])
    miss = np.array([0.3])
    np.testing.assert_allclose(jpda_star_marginals(L, miss), exact_marginals(L, miss), atol=1e-15)


def test_close_pair_keeps_the_best_permutation():
    # two tracks, two returns, the straight assignment 4× as likely as the swap:
    # JPDA mixes them, JPDA* keeps (0→0, 1→1) and drops (0→1, 1→0)
    L = np.array([[2.0, 1.0], [1.0, 2.0]])
    miss = np.array([0.1, 0.1])
    star = jpda_star_marginals(L, miss)
    jpda = exact_marginals(L, miss)
    assert star[0, 2] < jpda[0, 2]  # less weight on the other target's return
    # kept events: 00, 0→0, 0→1, 1→0, 1→1 alone, and (0→0, 1→1) of the two pairs
    z = 0.01 + 0.1 * (2 + 1 + 1 + 2) + 4.0
    assert star[0, 2] == pytest.approx(0.1 * 1.0 / z, rel=1e-13)


def test_jpda_star_budget_is_a_named_limit():
    L = np.ones((6, 8))
    miss = np.full(6, 0.5)
    with pytest.raises(ExactLimitError, match="max_hypotheses"):
        jpda_star(L, miss, max_hypotheses=100)
    with pytest.raises(ValueError, match="max_hypotheses"):
        jpda_star(L, miss, max_hypotheses=True)
    with pytest.raises(ValueError, match="L"):
        jpda_star(np.array([[1 + 1j]]), np.array([0.5]))


# ---------------------------------------------------------------------------
# the tracker switch
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("bad", ["yes", 1, 0.0, None, [True]])
def test_coalescence_avoidance_bad_input_is_named(bad):
    with pytest.raises(ValueError, match="coalescence_avoidance"):
        TrackerConfig(coalescence_avoidance=bad)


def test_pmbm_run_refuses_coalescence_avoidance():
    from jointtrack.experiments.config import RunConfigError, check_kind_keys

    with pytest.raises(RunConfigError, match="coalescence_avoidance"):
        check_kind_keys("pmbm", {"coalescence_avoidance": True}, {}, "run.toml")


def _two_close_tracks(**cfg):
    trk = JPDATracker(
        TrackerConfig(measurement_noise=2500.0, clutter_density=1e-9, process_noise=1.0, **cfg)
    )
    x0 = np.array([[0.0, 0.0, 200.0, 0.0], [0.0, 100.0, 200.0, 0.0]])
    trk.start_tracks(x0, np.diag([2500.0, 2500.0, 25.0, 25.0]), time=0.0)
    return trk


def test_tracker_uses_jpda_star_for_confirmed_clusters():
    z = np.array([[2000.0, 10.0], [2000.0, 90.0]])
    star = _two_close_tracks(coalescence_avoidance=True)
    plain = _two_close_tracks()
    r_star, r_plain = star.step(10.0, z), plain.step(10.0, z)
    assert r_star.cluster_methods == ["jpda*"] and r_plain.cluster_methods == ["exact"]
    # JPDA pulls both tracks towards the middle (coalescence); JPDA* keeps them apart
    gap_star = abs(r_star.x[1, 1] - r_star.x[0, 1])
    gap_plain = abs(r_plain.x[1, 1] - r_plain.x[0, 1])
    assert gap_star > gap_plain


# ---------------------------------------------------------------------------
# the scenario
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("separation", [100.0, 2000.0])
def test_close_pairs_truth_is_what_it_says(separation):
    sc = close_pairs(3, separation=separation, n_pairs=3, straight_scans=5, orbit_scans=9)
    assert sc.n_scans == 2 * 5 + 9 + 1 and sc.dt == 10.0
    X = np.stack(sc.truth_states)  # (K, 6, 4)
    for (a, b), v, w in zip(
        sc.info["pairs"], sc.info["speeds"], sc.info["turn_rates"], strict=True
    ):
        gap = np.linalg.norm(X[:, a, :2] - X[:, b, :2], axis=1)
        np.testing.assert_allclose(gap, separation, rtol=1e-9)
        assert 150.0 <= v <= 250.0 and 3.0 <= abs(math.degrees(w)) <= 5.0
        for t in (a, b):
            speed = np.linalg.norm(X[:, t, 2:], axis=1)
            np.testing.assert_allclose(speed, v, rtol=1e-12)
            heading = np.unwrap(np.arctan2(X[:, t, 3], X[:, t, 2]))
            turn = np.diff(heading) / sc.dt
            np.testing.assert_allclose(turn[:5], 0.0, atol=1e-12)  # straight
            np.testing.assert_allclose(turn[5:14], w, rtol=1e-9)  # the orbit
            np.testing.assert_allclose(turn[14:], 0.0, atol=1e-12)  # straight again
            step = np.linalg.norm(np.diff(X[:, t, :2], axis=0), axis=1)
            # straight legs cover v·dt; a turn's chord is 2 (v/ω) sin(ω dt / 2)
            np.testing.assert_allclose(step[:5], v * sc.dt, rtol=1e-12)
            np.testing.assert_allclose(step[5:14], 2 * v / abs(w) * math.sin(abs(w) * 5.0))
    # detections: targets and clutter inside the region, each target at most once per scan
    for z, o in zip(sc.detections, sc.origins, strict=True):
        assert np.all((z >= sc.region[:, 0]) & (z <= sc.region[:, 1]))
        tid = o[o >= 0]
        assert len(np.unique(tid)) == len(tid)
    assert sc.clutter_rate == 20.0 and sc.p_d == 0.9 and np.allclose(sc.R, 2500.0 * np.eye(2))


def test_close_pairs_is_seeded_and_checks_its_arguments():
    a, b = close_pairs(7, n_pairs=1), close_pairs(7, n_pairs=1)
    assert all(np.array_equal(x, y) for x, y in zip(a.detections, b.detections, strict=True))
    for kw, name in (
        ({"separation": 0.0}, "separation"),
        ({"separation": True}, "separation"),
        ({"n_pairs": 0}, "n_pairs"),
        ({"orbit_scans": 2.5}, "orbit_scans"),
        ({"p_d": 1.5}, "p_d"),
        ({"sigma": 1j}, "sigma"),
    ):
        with pytest.raises(ValueError, match=name):
            close_pairs(0, **kw)


def test_state_written_before_the_switch_loads_without_it(tmp_path):
    """A state file of main before ``coalescence_avoidance`` existed (same version, no
    such key) loads as plain JPDA and continues identically."""
    from jointtrack.trackers.state_io import read_state, write_state

    trk = _two_close_tracks()
    z = np.array([[2000.0, 10.0], [2000.0, 90.0]])
    trk.step(10.0, z)
    arrays, config, scalars, rng = read_state(trk.save(tmp_path / "now.npz"))
    config.pop("coalescence_avoidance")
    write_state(tmp_path / "before.npz", arrays, config, scalars, rng)
    loaded = JPDATracker.load(tmp_path / "before.npz")
    assert loaded.config.coalescence_avoidance is False
    z2 = z + [2000.0, 0.0]
    np.testing.assert_array_equal(loaded.step(20.0, z2).x, trk.step(20.0, z2).x)


def test_cluster_past_the_jpda_star_budget_keeps_jpda_and_is_counted(monkeypatch):
    import jointtrack.trackers.jpda as jpda_module

    def too_many(L, miss):
        raise ExactLimitError("jpda_star: this cluster has 1e6 feasible joint hypotheses")

    monkeypatch.setattr(jpda_module, "jpda_star_marginals", too_many)
    z = np.array([[2000.0, 10.0], [2000.0, 90.0]])
    star, plain = _two_close_tracks(coalescence_avoidance=True), _two_close_tracks()
    r_star, r_plain = star.step(10.0, z), plain.step(10.0, z)
    assert r_star.cluster_methods == ["exact"]
    assert r_star.cluster_fallbacks[0].startswith("jpda_star_budget: ")
    assert star.fallback_counts == {"jpda_star_budget": 1}
    np.testing.assert_array_equal(r_star.x, r_plain.x)
