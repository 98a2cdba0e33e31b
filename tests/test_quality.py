"""tracking_quality on hand-made cases with known answers, its properties, and a
smoke test of `jointtrack bench quality` on a tiny scene."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from jointtrack.metrics import track_statistics, tracking_quality

GATE = 10.0


def _table(rows):
    """rows of (time, id, x, y) → (times, ids, positions)."""
    a = np.array(rows, dtype=np.float64).reshape(-1, 4)
    return a[:, 0], a[:, 1].astype(np.int64), a[:, 2:4]


def _hand_case():
    """Ten scans t = 0 … 9 (all answers worked out by hand in the tests).

    * truth 1 at (0, 0), t = 0 … 9, first detected at t = 1; track 10 on it
      (offset (3, 4): distance 5) from t = 4 (confirmed 3 scans after the first
      detection), absent at t = 6 (a gap: one break, one fragmentation).
    * truth 2 at (100, 0), t = 0 … 9, first detected at t = 0; track 20 on it at
      t = 0 … 4, then track 21 at t = 5 … 9 (one identity switch).
    * truth 3 at (200, 0), t = 2 … 6, first detected at t = 3, never tracked.
    * track 30 far from everything at t = 2 … 5: a false track for 4 of 10 scans.
    """
    truth, tracks = [], []
    for t in range(10):
        truth.append((t, 1, 0.0, 0.0))
        truth.append((t, 2, 100.0, 0.0))
        if 2 <= t <= 6:
            truth.append((t, 3, 200.0, 0.0))
        if t >= 4 and t != 6:
            tracks.append((t, 10, 3.0, 4.0))
        tracks.append((t, 20 if t <= 4 else 21, 100.0, 0.0))
        if 2 <= t <= 5:
            tracks.append((t, 30, 5000.0, 5000.0))
    return _table(truth), _table(tracks), {1: 1.0, 2: 0.0, 3: 3.0}


def test_hand_case_every_metric():
    truth, tracks, first = _hand_case()
    q = tracking_quality(*truth, *tracks, gate=GATE, first_detection=first)
    assert q.n_scans == 10 and q.n_truths == 3 and q.n_detected == 3
    # time to confirm: truth 1 → 4 − 1 = 3, truth 2 → 0, truth 3 → ∞
    np.testing.assert_array_equal(q.truth_ids, [1, 2, 3])
    np.testing.assert_array_equal(q.first_detection_scan, [1, 0, 3])
    np.testing.assert_array_equal(q.confirmation_scan, [4, 0, -1])
    np.testing.assert_array_equal(q.time_to_confirm, [3.0, 0.0, np.inf])
    assert q.time_to_confirm_median == 3.0
    assert q.time_to_confirm_max == math.inf
    assert q.n_confirmed == 2 and q.n_never_confirmed == 1 and q.n_censored == 0
    # held: truth 1 after t = 4: scans 5..9, associated at 5, 7, 8, 9 → 4/5;
    # truth 2 after t = 0: 9 of 9 → overall 13/14, worst 0.8
    np.testing.assert_allclose(q.held_per_truth[:2], [0.8, 1.0])
    assert math.isnan(q.held_per_truth[2])
    assert (q.n_held_scans, q.n_after_scans) == (13, 14)
    assert q.held_fraction == pytest.approx(13 / 14)
    assert q.held_worst == pytest.approx(0.8)
    # false confirmed tracks: track 30 at 4 of 10 scans
    assert q.n_false_track_scans == 4
    assert q.false_per_scan == pytest.approx(0.4)
    np.testing.assert_array_equal(q.n_false_per_scan, [0, 0, 1, 1, 1, 1, 0, 0, 0, 0])
    np.testing.assert_array_equal(q.n_tracks_per_scan, [1, 1, 2, 2, 3, 3, 1, 2, 2, 2])
    np.testing.assert_array_equal(q.n_truths_per_scan, [2, 2, 3, 3, 3, 3, 3, 2, 2, 2])
    # breaks, fragmentations, identity switches
    assert (q.n_breaks, q.n_fragmentations, q.n_id_switches) == (1, 1, 1)
    # GOSPA (c = 10, p = 2, α = 2): per scan GOSPA² = loc + 50·(missed + false)
    g2 = np.array([50, 50, 150, 150, 125, 125, 100, 25, 25, 25], dtype=float)
    np.testing.assert_allclose(q.gospa_per_scan, np.sqrt(g2))
    assert q.gospa_mean == pytest.approx(np.mean(np.sqrt(g2)))
    assert q.gospa_localisation == pytest.approx(5 * 25 / 10)
    assert q.gospa_missed == pytest.approx(50 * 10 / 10)
    assert q.gospa_false == pytest.approx(50 * 4 / 10)
    assert q.gospa_localisation + q.gospa_missed + q.gospa_false == pytest.approx(g2.mean())
    assert q.gospa_missed_per_scan == pytest.approx(1.0)
    assert q.gospa_false_per_scan == pytest.approx(0.4)
    d = q.as_dict()
    assert d["false_per_scan"] == pytest.approx(0.4) and d["time_to_confirm_max"] == math.inf
    assert set(d) >= {"held_fraction", "held_worst", "n_breaks", "n_id_switches", "gospa_mean"}


def test_first_detection_defaults_to_first_scan_of_existence():
    truth, tracks, _ = _hand_case()
    q = tracking_quality(*truth, *tracks, gate=GATE)
    np.testing.assert_array_equal(q.first_detection_scan, [0, 0, 2])
    np.testing.assert_array_equal(q.time_to_confirm, [4.0, 0.0, np.inf])
    assert q.time_to_confirm_median == 4.0


def test_undetected_truth_is_left_out():
    truth, tracks, first = _hand_case()
    del first[3]
    q = tracking_quality(*truth, *tracks, gate=GATE, first_detection=first)
    assert q.n_detected == 2 and q.n_never_confirmed == 0
    assert math.isnan(q.time_to_confirm[2])
    assert q.time_to_confirm_max == 3.0 and q.time_to_confirm_median == 1.5


def test_scan_times_count_empty_scans():
    truth, tracks, first = _hand_case()
    q = tracking_quality(
        *truth, *tracks, gate=GATE, first_detection=first, scan_times=np.arange(20.0)
    )
    assert q.n_scans == 20
    assert q.false_per_scan == pytest.approx(0.2)
    g2 = np.array([50, 50, 150, 150, 125, 125, 100, 25, 25, 25], dtype=float)
    assert q.gospa_mean == pytest.approx(np.sum(np.sqrt(g2)) / 20)
    assert q.time_to_confirm_max == math.inf  # unchanged by empty scans


def test_confirm_window_censors_short_lived_truths():
    truth, tracks, first = _hand_case()
    # truth 3: first detected at t = 3, last scan t = 6 → 3 scans after detection
    q3 = tracking_quality(*truth, *tracks, gate=GATE, first_detection=first, confirm_window=3)
    assert q3.n_never_confirmed == 1 and q3.n_censored == 0
    q4 = tracking_quality(*truth, *tracks, gate=GATE, first_detection=first, confirm_window=4)
    assert q4.n_never_confirmed == 0 and q4.n_censored == 1
    np.testing.assert_array_equal(q4.censored, [False, False, True])
    assert q4.time_to_confirm_max == 3.0 and q4.time_to_confirm_median == 1.5


def test_association_before_first_detection_is_ignored():
    truth = _table([(t, 5, 0.0, 0.0) for t in range(6)])
    tracks = _table([(t, 50, 1.0, 0.0) for t in (0, 1, 3, 4, 5)])
    q = tracking_quality(*truth, *tracks, gate=GATE, first_detection={5: 2.0})
    # associated at t = 0, 1 (before the first detection), then at t = 3
    assert q.confirmation_scan[0] == 3 and q.time_to_confirm[0] == 1.0
    assert q.held_fraction == 1.0  # t = 4, 5 after confirmation, both associated


def test_builds_on_track_statistics():
    truth, tracks, first = _hand_case()
    q = tracking_quality(*truth, *tracks, gate=GATE, first_detection=first)
    s = track_statistics(*truth, *tracks, gate=GATE)
    assert q.statistics.n_breaks == s.n_breaks
    np.testing.assert_array_equal(q.statistics.assoc_track_ids, s.assoc_track_ids)
    assert q.n_associated_per_scan.sum() == s.assoc_times.size


def test_no_truth_no_track():
    z = np.zeros((0, 2))
    e = np.zeros(0)
    q = tracking_quality(e, e.astype(int), z, e, e.astype(int), z, gate=1.0, scan_times=[0, 1])
    assert q.n_scans == 2 and q.n_truths == 0
    assert q.false_per_scan == 0.0 and q.gospa_mean == 0.0
    assert math.isnan(q.held_fraction) and math.isnan(q.time_to_confirm_median)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"gate": -1.0}, "gate"),
        ({"gate": GATE, "first_detection": [1, 2]}, "first_detection must be a mapping"),
        ({"gate": GATE, "first_detection": {9: 0.0}}, "first_detection: truth id 9"),
        ({"gate": GATE, "first_detection": {3: 0.0}}, "truth 3 does not exist at time 0.0"),
        ({"gate": GATE, "first_detection": {1: "x"}}, "first_detection: the time of truth 1"),
        ({"gate": GATE, "first_detection": {1.5: 0.0}}, "first_detection: keys"),
        ({"gate": GATE, "scan_times": [0.0, 1.0]}, "scan_times must contain"),
        ({"gate": GATE, "scan_times": [[0.0]]}, "scan_times must be 1-D"),
        ({"gate": GATE, "scan_times": [np.nan]}, "scan_times must be finite"),
        ({"gate": GATE, "confirm_window": 0}, "confirm_window"),
        ({"gate": GATE, "confirm_window": 2.5}, "confirm_window"),
    ],
)
def test_validation(kwargs, match):
    truth, tracks, _ = _hand_case()
    with pytest.raises(ValueError, match=match):
        tracking_quality(*truth, *tracks, **kwargs)


def test_validation_of_tables_names_the_argument():
    truth, tracks, _ = _hand_case()
    with pytest.raises(ValueError, match="tracks"):
        tracking_quality(*truth, tracks[0][:-1], tracks[1], tracks[2], gate=GATE)


# ------------------------------------------------------------------ properties


@st.composite
def scenes(draw):
    """Truths on lanes 100 apart (one contiguous life each); at most one track near
    each truth per scan (id from a small pool per truth, so switches happen), at an
    offset that may exceed the gate (then it is a false track beside the truth)."""
    n_scans = draw(st.integers(2, 12))
    n_truths = draw(st.integers(1, 4))
    truth, tracks = [], []
    for j in range(n_truths):
        a = draw(st.integers(0, n_scans - 1))
        b = draw(st.integers(a, n_scans - 1))
        for t in range(a, b + 1):
            truth.append((t, j, 0.0, 100.0 * j))
            if draw(st.booleans()):
                off = draw(st.floats(0.0, 2 * GATE, allow_nan=False))
                tracks.append((t, 10 * j + draw(st.integers(0, 2)), off, 100.0 * j))
    far_scans = draw(st.sets(st.integers(0, n_scans - 1), min_size=1))
    return n_scans, _table(truth), _table(tracks), sorted(far_scans)


def _same_per_truth(a, b):
    np.testing.assert_array_equal(a.time_to_confirm, b.time_to_confirm)
    np.testing.assert_array_equal(a.held_per_truth, b.held_per_truth)
    assert (a.n_breaks, a.n_id_switches, a.n_fragmentations) == (
        b.n_breaks,
        b.n_id_switches,
        b.n_fragmentations,
    )


@settings(max_examples=60, deadline=None)
@given(scenes())
def test_far_false_track_adds_exactly_its_scans(scene):
    n_scans, truth, tracks, far = scene
    scans = np.arange(float(n_scans))
    base = tracking_quality(*truth, *tracks, gate=GATE, scan_times=scans)
    extra = _table([(t, 999, 1e6, -1e6) for t in far])
    more = tuple(np.concatenate([u, v]) for u, v in zip(tracks, extra, strict=True))
    q = tracking_quality(*truth, *more, gate=GATE, scan_times=scans)
    assert q.false_per_scan == pytest.approx(base.false_per_scan + len(far) / n_scans)
    assert q.n_false_track_scans == base.n_false_track_scans + len(far)
    _same_per_truth(q, base)
    # the GOSPA false part grows by c²/2 per added false target
    assert q.gospa_false == pytest.approx(base.gospa_false + GATE**2 / 2 * len(far) / n_scans)
    assert q.gospa_localisation == pytest.approx(base.gospa_localisation)


@settings(max_examples=60, deadline=None)
@given(scenes(), st.randoms(use_true_random=False))
def test_row_order_and_consistency(scene, rnd):
    n_scans, truth, tracks, _ = scene
    q = tracking_quality(*truth, *tracks, gate=GATE)
    pt = list(range(truth[0].size))
    pk = list(range(tracks[0].size))
    rnd.shuffle(pt)
    rnd.shuffle(pk)
    q2 = tracking_quality(*(a[pt] for a in truth), *(a[pk] for a in tracks), gate=GATE)
    _same_per_truth(q, q2)
    assert q.false_per_scan == q2.false_per_scan and q.gospa_mean == pytest.approx(q2.gospa_mean)
    # false tracks are the GOSPA false targets: the same assignment
    assert q.false_per_scan == pytest.approx(q.gospa_false_per_scan)
    sq = q.gospa_localisation + q.gospa_missed + q.gospa_false
    assert sq == pytest.approx(np.mean(q.gospa_per_scan**2))
    # held counts only scans after confirmation; a confirmed truth is associated there
    assert q.n_held_scans <= q.n_after_scans
    assert q.n_confirmed + q.n_never_confirmed == q.n_detected


# ------------------------------------------------------------------ the benchmark


def test_bench_helpers_on_a_tiny_scene():
    from jointtrack.bench import quality as bench
    from jointtrack.scenarios import abreast

    sc = abreast(0, n_scans=8, clutter_per_scan=3.0)
    cfg = bench.physical_config(sc)
    assert cfg.measurement_noise == pytest.approx(25.0)
    assert cfg.p_d == sc.p_d and cfg.clutter_density == pytest.approx(sc.clutter_density)
    assert cfg.process_noise == pytest.approx(max(sc.process_noise, 0.01))
    assert cfg.max_speed == pytest.approx(1.5 * 1.0, rel=0.05)
    assert bench.physical_config(sc, existence=False).existence is False
    first = bench.first_detections(sc)
    for tid, t in first.items():
        k = int(np.searchsorted(sc.times, t))
        assert tid in sc.origins[k] and all(tid not in o for o in sc.origins[:k])
    assert bench.CONFIGURATIONS[0] == ("jointtrack (default)", {})
    run = bench.run_jointtrack(sc, cfg)
    assert run.n_scans == 8 and run.seconds > 0
    q = bench.evaluate(sc, run, gate=10.0)
    assert q.n_scans == 8 and q.n_truths == 5
    if bench.stonesoup_available():
        ss = bench.run_stonesoup(sc)
        assert ss.n_scans == 8
        qs = bench.evaluate(sc, ss, gate=10.0)
        assert qs.n_scans == 8
        # its tracks are reported in [x, y] like ours, and some hold a target
        assert qs.n_confirmed >= 1


def test_stonesoup_budget_stops_a_run_and_reports_its_scans():
    from jointtrack.bench import quality as bench
    from jointtrack.scenarios import abreast

    if not bench.stonesoup_available():
        pytest.skip("Stone Soup not installed")
    sc = abreast(0, n_scans=30)
    run = bench.run_stonesoup(sc, budget=0.5)
    assert not run.completed and run.n_scans < 30
    assert run.seconds >= 0.4  # includes the interrupted scan
    if run.n_scans:
        assert np.all(run.times <= sc.times[run.n_scans - 1])
    q = bench.evaluate(sc, run, gate=10.0)
    assert q.n_scans == run.n_scans
