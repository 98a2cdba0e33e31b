"""OSPA / GOSPA / GOSPA over time / track statistics (jointtrack.metrics)."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from jointtrack.metrics import (
    GOSPA,
    gospa,
    gospa_series,
    ospa,
    track_statistics,
)

# ----------------------------------------------------------------------------- helpers

coord = st.floats(-10, 10, allow_nan=False, allow_infinity=False)
point_set = st.lists(st.tuples(coord, coord), min_size=0, max_size=5).map(
    lambda pts: np.array(pts, dtype=float).reshape(-1, 2)
)
cutoff = st.floats(0.5, 20, allow_nan=False)
order = st.sampled_from([1.0, 2.0, 3.0])


def _brute_gospa_p(X, Y, c, p, alpha):
    """min over injections of Σ min(d, c)^p + c^p/α |m − n| (the definition)."""
    if X.shape[0] > Y.shape[0]:
        X, Y = Y, X
    n, m = X.shape[0], Y.shape[0]
    best = math.inf
    for perm in itertools.permutations(range(m), n):
        s = sum(min(np.linalg.norm(X[i] - Y[j]), c) ** p for i, j in enumerate(perm))
        best = min(best, s)
    if n == 0:
        best = 0.0
    return best + c**p / alpha * (m - n)


def _brute_gospa2_assignment_form(X, Y, c, p):
    """α = 2 assignment form: min over partial assignments with d < c."""
    n, m = X.shape[0], Y.shape[0]
    best = math.inf
    for k in range(min(n, m) + 1):
        for rows in itertools.combinations(range(n), k):
            for cols in itertools.permutations(range(m), k):
                d = [np.linalg.norm(X[i] - Y[j]) for i, j in zip(rows, cols, strict=True)]
                if any(x >= c for x in d):
                    continue
                best = min(best, sum(x**p for x in d) + c**p / 2 * (n + m - 2 * k))
    return best


# ----------------------------------------------------------------------------- hand cases


def test_one_missed_target_costs_half_c_to_the_p():
    g = gospa([[0.0, 0.0]], np.zeros((0, 2)), c=10, p=2)
    assert isinstance(g, GOSPA)
    assert g.total == pytest.approx(math.sqrt(50))
    assert (g.missed, g.false, g.localisation) == (50.0, 0.0, 0.0)
    assert (g.n_missed, g.n_false, g.n_assigned) == (1, 0, 0)


def test_one_false_target_and_empty_given_as_flat_array():
    g = gospa([], [[1.0, 2.0, 3.0]], c=4, p=1)
    assert g.total == pytest.approx(2.0)
    assert g.false == pytest.approx(2.0) and g.missed == 0 and g.n_false == 1


def test_close_pair_is_localisation_far_pair_is_missed_plus_false():
    near = gospa([[0, 0]], [[0, 3]], c=10, p=2)
    assert near.total == pytest.approx(3.0)
    assert near.localisation == pytest.approx(9.0) and near.n_assigned == 1
    far = gospa([[0, 0]], [[0, 20]], c=10, p=2)
    assert far.total == pytest.approx(10.0)
    assert (far.n_assigned, far.n_missed, far.n_false) == (0, 1, 1)
    assert far.missed == far.false == pytest.approx(50.0)


def test_two_by_two_worked_by_hand():
    # (0,0)-(0,3) at d = 3; (5,5) and (100,0) are beyond c: 9 + 50 + 50
    g = gospa([[0, 0], [5, 5]], [[0, 3], [100, 0]], c=10, p=2)
    assert g.total == pytest.approx(math.sqrt(109))
    assert g.assignment.tolist() == [[0, 0]]
    assert g.distances.tolist() == pytest.approx([3.0])


def test_p1_worked_by_hand():
    g = gospa([[0, 0]], [[0, 1], [0, 5]], c=3, p=1)
    assert g.total == pytest.approx(1 + 1.5)


def test_ospa_worked_by_hand():
    assert ospa([[0.0]], [[0.0], [100.0]], c=10, p=1) == pytest.approx(5.0)
    # (0,0)-(0,4) at 4, (3,0) unassigned: ((16 + 100)/2)^(1/2)
    assert ospa([[0, 0], [3, 0]], [[0, 4]], c=10, p=2) == pytest.approx(math.sqrt(58))
    assert ospa([], [], c=3) == 0.0
    assert ospa([[1, 1]], [], c=3) == 3.0
    assert ospa([], [[1, 1], [2, 2]], c=3, p=2) == pytest.approx(3.0)


def test_gospa_empty_sets():
    g = gospa(np.zeros((0, 3)), np.zeros((0, 3)), c=1)
    assert g.total == 0.0 and g.assignment.shape == (0, 2)


def test_alpha_below_two_counts_cardinality_mismatch_only():
    # α = 1: a far pair is *assigned* at cost c^p, the extra point costs c^p/α
    g = gospa([[0, 0]], [[0, 20], [0, 30]], c=10, p=1, alpha=1)
    assert g.total == pytest.approx(10 + 10)
    assert g.n_assigned == 1 and g.n_false == 1


@pytest.mark.parametrize(
    "kwargs, msg",
    [
        ({"c": 0}, "cut-off"),
        ({"c": float("inf")}, "cut-off"),
        ({"c": 1, "p": 0.5}, "order p"),
        ({"c": 1, "alpha": 3}, "alpha"),
        ({"c": 1, "alpha": 0}, "alpha"),
    ],
)
def test_bad_parameters(kwargs, msg):
    with pytest.raises(ValueError, match=msg):
        gospa([[0, 0]], [[1, 1]], **kwargs)


def test_bad_points():
    with pytest.raises(ValueError, match="same dimension"):
        gospa([[0, 0]], [[1, 1, 1]], c=1)
    with pytest.raises(ValueError, match="non-finite"):
        ospa([[0, np.nan]], [[1, 1]], c=1)
    with pytest.raises(ValueError, match="2-D"):
        ospa(np.zeros((2, 2, 2)), [[1, 1]], c=1)


# ---------------------------------------------------------------- against the definition


@pytest.mark.parametrize("alpha", [2.0, 1.0, 0.5])
def test_gospa_matches_brute_force_definition(alpha):
    rng = np.random.default_rng(7)
    for _ in range(60):
        n, m = rng.integers(0, 5, size=2)
        X = rng.uniform(0, 10, (n, 2))
        Y = rng.uniform(0, 10, (m, 2))
        c = rng.uniform(0.5, 8)
        p = rng.choice([1.0, 2.0])
        g = gospa(X, Y, c, p, alpha)
        assert g.total**p == pytest.approx(_brute_gospa_p(X, Y, c, p, alpha), rel=1e-9, abs=1e-12)
        if alpha == 2.0:
            assert g.total**p == pytest.approx(
                _brute_gospa2_assignment_form(X, Y, c, p), rel=1e-9, abs=1e-12
            )


# ----------------------------------------------------------------------------- properties


@settings(max_examples=150, deadline=None)
@given(point_set, point_set, cutoff, order)
def test_gospa_decomposition_sums_to_total(X, Y, c, p):
    g = gospa(X, Y, c, p)
    assert g.localisation + g.missed + g.false == pytest.approx(g.total**p, rel=1e-9, abs=1e-12)
    assert g.missed == pytest.approx(c**p / 2 * g.n_missed)
    assert g.false == pytest.approx(c**p / 2 * g.n_false)
    assert g.n_assigned + g.n_missed == X.shape[0]
    assert g.n_assigned + g.n_false == Y.shape[0]
    assert np.all(g.distances < c)
    assert g.localisation == pytest.approx(np.sum(g.distances**p))


@settings(max_examples=150, deadline=None)
@given(point_set, point_set, cutoff, order)
def test_gospa_alpha1_and_ospa_relation(X, Y, c, p):
    N = max(X.shape[0], Y.shape[0])
    g1 = gospa(X, Y, c, p, alpha=1).total
    o = ospa(X, Y, c, p)
    assert g1**p == pytest.approx(N * o**p, rel=1e-9, abs=1e-12)
    assert 0 <= o <= c + 1e-12


@settings(max_examples=150, deadline=None)
@given(point_set, point_set, cutoff, order)
def test_identity_and_symmetry(X, Y, c, p):
    assert ospa(X, X, c, p) == 0.0
    assert gospa(X, X, c, p).total == 0.0
    assert ospa(X, Y, c, p) == pytest.approx(ospa(Y, X, c, p), rel=1e-12, abs=1e-12)
    assert gospa(X, Y, c, p).total == pytest.approx(gospa(Y, X, c, p).total, rel=1e-12, abs=1e-12)
    # permuting the points does not matter (sets)
    perm = np.arange(X.shape[0])[::-1]
    assert ospa(X[perm], Y, c, p) == pytest.approx(ospa(X, Y, c, p), rel=1e-12, abs=1e-12)


@settings(max_examples=150, deadline=None)
@given(point_set, cutoff)
def test_distinct_sets_have_positive_distance(X, c):
    Y = np.vstack([X, [[50.0, 50.0]]])  # one extra point
    assert ospa(X, Y, c) > 0
    assert gospa(X, Y, c).total == pytest.approx((c**2 / 2) ** 0.5)


@settings(max_examples=200, deadline=None)
@given(point_set, point_set, point_set, cutoff, order)
def test_triangle_inequality(X, Y, Z, c, p):
    tol = 1e-9 * c
    assert ospa(X, Z, c, p) <= ospa(X, Y, c, p) + ospa(Y, Z, c, p) + tol
    for alpha in (2.0, 1.0):
        dxz = gospa(X, Z, c, p, alpha).total
        dxy = gospa(X, Y, c, p, alpha).total
        dyz = gospa(Y, Z, c, p, alpha).total
        assert dxz <= dxy + dyz + tol


def test_triangle_inequality_fails_for_a_non_metric_sanity_check():
    # the test above can fail: the cut-off-free "sum of squared errors" is no metric
    def sse(A, B):
        return float(np.sum((np.asarray(A) - np.asarray(B)) ** 2))

    assert sse([[0]], [[2]]) > sse([[0]], [[1]]) + sse([[1]], [[2]])


# ----------------------------------------------------------------------------- over time


def _table(rows):
    t = np.array([r[0] for r in rows], float)
    i = np.array([r[1] for r in rows], int)
    P = np.array([r[2] for r in rows], float).reshape(-1, 2)
    return t, i, P


def test_gospa_series_by_hand_with_switches():
    # truths 0 at y=0 and 1 at y=100 over 4 scans; tracks 10/11 swap at scan 2
    truth = _table([(k, j, (k, 100 * j)) for k in range(4) for j in (0, 1)])
    rows = []
    for k in range(4):
        a, b = (10, 11) if k < 2 else (11, 10)
        rows += [(k, a, (k, 1.0)), (k, b, (k, 102.0))]
    rows.append((5, 99, (0, 0)))  # a track at a time with no truth: one false target
    tracks = _table(rows)
    s = gospa_series(*truth, *tracks, c=10, p=2, switch_penalty=3.0)
    assert s.times.tolist() == [0, 1, 2, 3, 5]
    assert s.gospa[:4] == pytest.approx(np.full(4, math.sqrt(1 + 4)))
    assert s.gospa[4] == pytest.approx(math.sqrt(50)) and s.n_false[4] == 1
    assert s.switches.tolist() == [0, 0, 2, 0, 0]
    assert s.switch_cost == pytest.approx(2 * 9.0)
    assert s.total == pytest.approx(math.sqrt(4 * 5 + 50 + 18))
    # without penalty it is the l_p sum of per-scan GOSPA
    s0 = gospa_series(*truth, *tracks, c=10, p=2)
    assert s0.total == pytest.approx(math.sqrt(4 * 5 + 50))


def test_gospa_series_gap_without_change_is_not_a_switch():
    truth = _table([(k, 0, (k, 0)) for k in range(5)])
    tracks = _table([(k, 7, (k, 0.5)) for k in (0, 1, 3, 4)])  # missing at scan 2
    s = gospa_series(*truth, *tracks, c=5, switch_penalty=10)
    assert s.switches.sum() == 0
    assert s.n_missed.tolist() == [0, 0, 1, 0, 0]


def test_gospa_series_identical_is_zero_and_row_order_free():
    rng = np.random.default_rng(3)
    t = np.repeat(np.arange(6.0), 4)
    ids = np.tile(np.arange(4), 6)
    P = rng.uniform(0, 100, (24, 2))
    s = gospa_series(t, ids, P, t, ids + 100, P, c=5, switch_penalty=1)
    assert s.total == 0.0 and s.switches.sum() == 0
    Q = P + rng.normal(0, 1, P.shape)
    perm = rng.permutation(24)
    a = gospa_series(t, ids, P, t, ids, Q, c=5)
    b = gospa_series(t[perm], ids[perm], P[perm], t, ids, Q, c=5)
    assert a.total == pytest.approx(b.total) and a.gospa == pytest.approx(b.gospa)


def test_gospa_series_validation():
    t, i, P = _table([(0, 0, (0, 0))])
    with pytest.raises(ValueError, match="same number of rows"):
        gospa_series(t, i, P[:0], t, i, P, c=1)
    with pytest.raises(ValueError, match="twice"):
        gospa_series(np.r_[t, t], np.r_[i, i], np.r_[P, P], t, i, P, c=1)
    with pytest.raises(ValueError, match="switch_penalty"):
        gospa_series(t, i, P, t, i, P, c=1, switch_penalty=-1)
    with pytest.raises(ValueError, match="integers"):
        gospa_series(t, np.array([0.5]), P, t, i, P, c=1)


# ----------------------------------------------------------------------------- track statistics


def _stats_case():
    truth, tracks = [], []
    for k in range(6):
        truth += [(k, 0, (k, 0.0)), (k, 1, (k, 100.0))]
        if k < 2:
            truth.append((k, 2, (k, 300.0)))
            tracks.append((k, 14, (k, 300.0)))  # tracks truth 2 until it dies
        if k != 3:
            tracks.append((k, 10, (k, 1.0)))  # truth 0, lost at k = 3
        tracks.append((k, 11 if k < 3 else 12, (k, 102.0)))  # truth 1, switch 11 → 12
        if k < 4:
            tracks.append((k, 13, (500.0, 500.0)))  # false track
            tracks.append((k, 15, (k, 200.0 if k else 0.5)))  # 1 of 4 scans near truth 0
    return _table(truth), _table(tracks)


def test_track_statistics_by_hand():
    truth, tracks = _stats_case()
    s = track_statistics(*truth, *tracks, gate=5.0)
    assert (s.n_truths, s.n_tracks) == (3, 6)
    labels = dict(zip(s.track_ids.tolist(), s.track_labels.tolist(), strict=True))
    assert labels == {10: 0, 11: 1, 12: 1, 13: -1, 14: 2, 15: -1}
    assert (s.n_true_tracks, s.n_false_tracks) == (4, 2)
    assert s.n_truths_tracked == 3
    # truth 0: at k = 3 track 10 is absent; track 15 is at (3, 200): no association
    assert s.n_breaks == 1 and s.n_fragmentations == 1
    # k = 0: truth 0 has tracks 10 (d = 1) and 15 (d = 0.5): it takes 15, then
    # 10 from k = 1 — a switch — and truth 1 switches 11 → 12
    assert s.n_id_switches == 2
    errs = [0.5] + [1.0] * 4 + [2.0] * 6 + [0.0] * 2
    assert s.rmse == pytest.approx(math.sqrt(np.mean(np.square(errs))))
    assert s.coverage == pytest.approx(13 / 14)
    assert s.assoc_errors.size == 13


def test_track_statistics_associations_listed():
    truth, tracks = _stats_case()
    s = track_statistics(*truth, *tracks, gate=5.0)
    pairs = set(
        zip(
            s.assoc_times.tolist(),
            s.assoc_truth_ids.tolist(),
            s.assoc_track_ids.tolist(),
            strict=True,
        )
    )
    assert (0.0, 0, 15) in pairs and (1.0, 0, 10) in pairs and (3.0, 1, 12) in pairs
    assert not any(tr == 13 for _, _, tr in pairs)
    # shuffling the rows changes nothing
    perm = np.random.default_rng(1).permutation(tracks[0].size)
    s2 = track_statistics(*truth, *(a[perm] for a in tracks), gate=5.0)
    assert s2.as_dict() == s.as_dict()


def test_track_statistics_perfect_tracking_on_a_scenario():
    from jointtrack.scenarios import many_targets

    sc = many_targets(n_targets=100, clutter_per_scan=0, seed=4, n_scans=30)
    t, ids, P = sc.truth_table()
    noise = np.random.default_rng(0).normal(0, 1.0, P.shape)
    s = track_statistics(t, ids, P, t, ids + 1000, P + noise, gate=20.0)
    assert s.n_true_tracks == s.n_tracks == s.n_truths == sc.n_targets
    assert s.n_false_tracks == s.n_breaks == s.n_id_switches == s.n_fragmentations == 0
    assert s.coverage == 1.0
    assert s.rmse == pytest.approx(math.sqrt(2), rel=0.1)
    assert np.all(s.track_labels == s.track_ids - 1000)
    d = s.as_dict()
    assert d["n_truths"] == sc.n_targets and set(d) >= {"rmse", "n_id_switches"}


def test_track_statistics_no_tracks_and_validation():
    truth = _table([(0, 0, (0, 0)), (1, 0, (1, 0))])
    empty = (np.zeros(0), np.zeros(0, int), np.zeros((0, 2)))
    s = track_statistics(*truth, *empty, gate=1.0)
    assert s.n_tracks == 0 and math.isnan(s.rmse) and s.coverage == 0.0
    with pytest.raises(ValueError, match="gate"):
        track_statistics(*truth, *empty, gate=0)
    with pytest.raises(ValueError, match="min_fraction"):
        track_statistics(*truth, *empty, gate=1, min_fraction=0)
    with pytest.raises(ValueError, match="-D"):
        track_statistics(*truth, np.zeros(1), np.zeros(1, int), np.zeros((1, 3)), gate=1)
