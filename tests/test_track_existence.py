"""Issue 11: finding targets from nothing — JIPDA existence, adaptive births, merging."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from jointtrack.bench.tracking_runs import first_detections
from jointtrack.metrics import tracking_quality
from jointtrack.scenarios import abreast
from jointtrack.trackers import JPDATracker, TrackerConfig
from jointtrack.trackers.existence import existence_update, merge_duplicates

GATE = 10.0  # metric association distance: half the lane spacing of the scene


def _config(sc, **kw):
    """Only physical settings: σ, P_D, λ, q and the largest speed (issue 11)."""
    return TrackerConfig(
        measurement_noise=float(sc.R[0, 0]),
        p_d=sc.p_d,
        clutter_density=sc.clutter_density,
        process_noise=0.01,
        max_speed=1.5,
        **kw,
    )


def _track(sc, cfg, scans=None):
    trk = JPDATracker(cfg)
    rows = []
    for t, z in list(zip(sc.times, scans or sc.detections, strict=True)):
        r = trk.step(t, z)
        rows += [(t, i, x[0], x[1]) for i, x in zip(r.ids, r.x, strict=True)]
    return np.array(rows).reshape(-1, 4)


def _small_scene(seed):
    return abreast(
        seed,
        n_targets=3,
        lane_spacing=40.0,
        n_scans=40,
        clutter_per_scan=30.0,
        region=((-250.0, 250.0), (-60.0, 140.0)),
    )


def test_small_scene_from_nothing_confirms_fast_and_holds():
    # 3 targets 40 apart at 1 unit/s, σ = 5, P_D = 0.9, λ = 3e-4 (as the issue's
    # scene), 8 seeds, started from nothing. Measured: 23/24 targets confirmed
    # within 10 scans of their first detection (the last in 13), every target
    # held in ≥ 96.8 % of its scans after confirmation, ≤ 0.1 false tracks/scan.
    ttc, held, false = [], [], []
    for seed in range(8):
        sc = _small_scene(seed)
        rows = _track(sc, _config(sc))
        q = tracking_quality(
            *sc.truth_table(),
            rows[:, 0],
            rows[:, 1].astype(int),
            rows[:, 2:4],
            gate=GATE,
            first_detection=first_detections(sc),
            scan_times=sc.times,
        )
        ttc += q.time_to_confirm.tolist()
        held += q.held_per_truth.tolist()
        false.append(q.false_per_scan)  # confirmed tracks no truth explains
    assert max(ttc) < math.inf  # every target found
    assert np.median(ttc) <= 6
    assert np.mean(np.array(ttc) <= 10) >= 0.9
    assert min(held) >= 0.95
    assert max(false) <= 0.5


@pytest.mark.xfail(
    strict=True,
    reason="issue 11 open: with r_init = 0.02, r_confirm = 0.9 the sequential test "
    "confirms 2–4 clutter tracks per 100 scans of 60 returns; 'none' needs ≈ 11 nats of "
    "evidence, ≈ 10 scans for a true target at this λ — the 10-scan bound then fails",
)
def test_clutter_only_scene_confirms_no_track():
    sc = abreast(0, n_targets=1, n_scans=100)
    clutter = [z[o < 0] for z, o in zip(sc.detections, sc.origins, strict=True)]
    rows = _track(sc, _config(sc), clutter)
    assert len(rows) == 0


def test_clutter_only_false_tracks_are_rare_and_short():
    # what the current logic does guarantee: few, short-lived false tracks
    sc = abreast(0, n_targets=1, n_scans=100)
    clutter = [z[o < 0] for z, o in zip(sc.detections, sc.origins, strict=True)]
    rows = _track(sc, _config(sc), clutter)
    assert len(rows) / sc.n_scans <= 0.2  # false confirmed tracks per scan
    assert len(np.unique(rows[:, 1])) <= 4 if len(rows) else True


# ----------------------------------------------------------------- existence update
@settings(max_examples=200, deadline=None)
@given(
    r=st.floats(1e-6, 1 - 1e-6),
    pd=st.floats(0.05, 0.99),
    pg=st.floats(0.5, 0.999),
    ratios=st.lists(st.floats(0.0, 1e3), max_size=5),
)
def test_single_track_existence_is_the_ipda_update(r, pd, pg, ratios):
    # One track: the IPDA update (Mušicki, Evans & Stanković 1994, eq. 31)
    # r' = r·Λ / (1 − r + r·Λ), Λ = 1 − P_D P_G + P_D Σ g_j/λ, with the β of the
    # joint events (exists/no return absorbed in β₀) as the tracker forms them.
    lr = np.array(ratios) * pd * r  # P_D r g/λ of each gated return
    miss = 1 - r * pd * pg
    total = miss + lr.sum()
    beta0 = np.array([miss / total])
    weights = lr / total
    rows = np.zeros(len(lr), np.int64)
    r_post, b0, w = existence_update(np.array([r]), beta0, weights, rows, pd * pg)
    lam = 1 - pd * pg + pd * float(np.sum(ratios))
    expected = r * lam / (1 - r + r * lam)
    assert r_post[0] == pytest.approx(expected, rel=1e-9, abs=1e-12)
    # given existence, the β sum to one
    assert b0[0] + w.sum() == pytest.approx(1.0, rel=1e-9)


# ----------------------------------------------------------------- merging
def _two(x2, P=25.0, confirmed=(True, False), existence=(0.9, 0.4)):
    x = np.array([[0.0, 0.0, 1.0, 0.0], x2], dtype=float)
    P = np.broadcast_to(np.diag([P, P, 0.5, 0.5]), (2, 4, 4)).copy()
    return x, P, np.array([1, 2]), np.array(existence), np.array(confirmed)


def test_duplicates_merge_into_the_confirmed_track_with_the_union_existence():
    x, P, ids, r, conf = _two([1.0, 0.5, 1.0, 0.0])
    keep, r2 = merge_duplicates(x, P, ids, r, conf, 2, threshold=1.0)
    assert keep.tolist() == [True, False]
    assert r2[0] == pytest.approx(1 - 0.1 * 0.6)


def test_tentative_duplicates_keep_the_more_probable_track():
    x, P, ids, r, conf = _two([1.0, 0.5, 1.0, 0.0], confirmed=(False, False), existence=(0.1, 0.3))
    keep, _ = merge_duplicates(x, P, ids, r, conf, 2, threshold=1.0)
    assert keep.tolist() == [False, True]


def test_two_confirmed_tracks_never_merge():
    # crossing targets come within d² < 1 of each other for a scan or two; merging
    # two confirmed tracks there would delete a real target
    x, P, ids, r, conf = _two([0.5, 0.2, 1.0, 0.1], confirmed=(True, True), existence=(0.9, 0.95))
    keep, r2 = merge_duplicates(x, P, ids, r, conf, 2, threshold=1.0)
    assert keep.all() and np.array_equal(r2, r)


def test_crossing_targets_keep_both_tracks():
    # two targets 10° apart crossing (jointtrack.identity.crossing's scene), tracked by
    # the plain tracker from the truth with the default merge threshold: both tracks live
    from jointtrack.identity.crossing import identity_crossing

    for seed in range(5):
        sc = identity_crossing(seed)
        cfg = TrackerConfig(
            measurement_noise=float(sc.measurement_noise[0, 0]),
            clutter_density=sc.position_clutter_density,
            p_d=sc.p_d,
            process_noise=1.0,
            max_speed=15.0,
        )
        trk = JPDATracker(cfg)
        trk.start_tracks(sc.truth[:, 0], np.diag([100.0, 100.0, 1.0, 1.0]))
        ids = set(trk.ids.tolist())
        for t, Z in zip(sc.times, sc.measurements, strict=True):
            trk.step(t, Z[:, :2])
            assert ids <= set(trk.ids.tolist()), f"seed {seed}: a true track was deleted at t={t}"


@pytest.mark.parametrize("threshold", [1.0, 0.0])
def test_neighbours_one_lane_apart_never_merge(threshold):
    x, P, ids, r, conf = _two([0.0, 20.0, 1.0, 0.0])
    keep, r2 = merge_duplicates(x, P, ids, r, conf, 2, threshold=threshold)
    assert keep.all() and np.array_equal(r2, r)


def test_merge_threshold_zero_disables_merging():
    x, P, ids, r, conf = _two([0.0, 0.0, 1.0, 0.0])
    keep, _ = merge_duplicates(x, P, ids, r, conf, 2, threshold=0.0)
    assert keep.all()


# ----------------------------------------------------------------- births
def test_a_return_explained_by_a_confirmed_track_starts_no_track():
    cfg = TrackerConfig(measurement_noise=25.0, clutter_density=1e-4, max_speed=2.0)
    trk = JPDATracker(cfg)
    trk.start_tracks([[0.0, 0.0, 1.0, 0.0]], np.diag([4.0, 4.0, 0.1, 0.1]))
    trk.step(1.0, np.array([[1.0, 0.0], [500.0, 500.0]]))
    new = trk.existence[trk.ids != 1]
    # the far return starts a track with r_init; the one on the track starts none
    # (its birth existence r_init·(1 − P(from the track)) is below r_delete)
    assert len(new) == 1 and new[0] == pytest.approx(cfg.r_init)


@pytest.mark.parametrize(
    "field, value",
    [
        ("r_report", 0.0),
        ("r_report", 1.5),
        ("r_report", True),
        ("r_report", 0.004),  # ≤ r_delete
        ("merge_threshold", -1.0),
        ("merge_threshold", math.nan),
        ("merge_threshold", math.inf),
        ("merge_threshold", "1"),
    ],
)
def test_bad_existence_settings_name_the_field(field, value):
    with pytest.raises(ValueError, match=field):
        TrackerConfig(**{field: value})
