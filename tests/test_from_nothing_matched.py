"""bench.from_nothing's matched floor: r* from clutter-born lone IPDAs, the floor at r* (issue 33).

The simulation is checked against its own definition (the splitting's weighted
copies against plain Monte Carlo, and the tracker from nothing itself on
clutter-only scans), the matched floor against the issue's floor at the
settings' own threshold, and the bad input by name. Short scenes, few births.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from jointtrack.bench import from_nothing as fn
from jointtrack.trackers import JPDATracker

SHORT = {"n_scans": 12, "clutter_per_scan": 10.0}


@pytest.fixture(scope="module")
def scene():
    return fn.make_scene("crossing", 0, SHORT)


def _within(a, a_se, b, b_se, k=3.0):
    return abs(a - b) <= k * math.hypot(a_se, b_se) + 1e-12


def test_splitting_estimates_what_plain_monte_carlo_does(scene):
    """The split copies carry weights summing to their birth's: the estimate agrees with plain
    Monte Carlo (no level ever reached: level_nats 20) within 3 standard errors."""
    split = fn.false_track_rate(scene, births=300, seed=0)
    plain = fn.false_track_rate(scene, births=1500, seed=1, level_nats=20.0)
    assert plain["copies"] == plain["births"] and split["copies"] > split["births"]
    for i, r in enumerate(split["grid"][:6]):
        assert _within(
            split["false_per_scan"][i],
            split["false_per_scan_se"][i],
            plain["false_per_scan"][i],
            plain["false_per_scan_se"][i],
        ), r
    # rising thresholds only drop tests: never more false tracks
    assert all(np.diff(split["false_per_scan"]) <= 0) and all(np.diff(split["p_confirm"]) <= 0)
    ok = [r for r, f in zip(split["grid"], split["false_per_scan"], strict=True) if f <= 0.1]
    assert split["r_star"] == (ok[0] if ok else None)


def test_the_rate_is_the_tracker_from_nothing_on_clutter(scene):
    """The quantity simulated is what the tracker from nothing (each birth a lone IPDA:
    ``tentative_association = "alternatives"``) does on clutter-only scans of the scene:
    its confirmed, reported tracks per scan, mean over 16 clutter-only runs, within 3
    standard errors of the simulation at the settings' r_confirm."""
    cfg = fn.jipda_config(scene)
    sim = fn.false_track_rate(scene, births=200, grid=[cfg.r_confirm])
    lone = dataclasses.replace(cfg, tentative_association="alternatives")
    rng = np.random.default_rng(7)
    lo = scene.region[:, 0]
    span = scene.region[:, 1] - lo
    per_run = []
    for _ in range(16):
        trk = JPDATracker(lone)
        n = 0
        for t in scene.times:
            z = lo + rng.random((rng.poisson(scene.clutter_rate), scene.dim)) * span
            trk.step(float(t), z)
            n += int((trk.confirmed & (trk.existence >= lone.r_report)).sum())
        per_run.append(n / scene.n_scans)
    mean, se = float(np.mean(per_run)), float(np.std(per_run, ddof=1) / math.sqrt(len(per_run)))
    assert _within(mean, se, sim["false_per_scan"][0], sim["false_per_scan_se"][0])


def test_r_star_rises_with_sparse_clutter_and_dense_clutter_confirms_nothing():
    """More clutter returns per scan: more clutter-born tests, each return's likelihood ratio
    P_D g / λ still large while the gate holds few (false tracks per scan and r* rise); a gate
    holding many makes each scan's evidence its mean, neutral (no clutter-born test confirms
    at any threshold: the dense-clutter limit, where a target's evidence vanishes too)."""
    rates = [
        fn.false_track_rate(
            fn.make_scene("crossing", 0, SHORT | {"clutter_per_scan": c}), births=300, seed=3
        )
        for c in (1.0, 10.0, 300.0)
    ]
    sparse, mid, dense = rates
    assert sparse["r_star"] is not None and mid["r_star"] is not None
    assert sparse["r_star"] <= mid["r_star"]
    assert sparse["false_per_scan"][0] < mid["false_per_scan"][0]
    assert max(dense["false_per_scan"]) < min(sparse["false_per_scan"][0], 1e-3)
    assert dense["r_star"] == dense["grid"][0]


def test_matched_floor_at_the_settings_threshold_is_the_floor():
    """At r* = r_confirm of the settings the matched floor is the issue's floor (oracle and
    score alike); at a higher r the oracle confirms no earlier and the floor is no lower."""
    kw = {"n_scans": 10}
    r0 = fn.jipda_config(fn.make_scene("crossing", 0, kw)).r_confirm
    out = fn.evaluate("crossing", 0, [], scenario_kwargs=kw, r_matched=r0)
    assert out["matched"]["r"] == r0
    assert out["matched"]["oracle"] == out["oracle"]
    assert out["matched"]["floor"] == out["floor"]
    truth_run = fn._run_tracks("crossing", 0, None, kw, start_from="truth", tracker="jipda")
    scene = fn.make_scene("crossing", 0, kw)
    late = fn.matched_floor(scene, truth_run, 0.9999)
    for t, scans in out["oracle"].items():
        assert late["oracle"][t] is None or (scans is not None and late["oracle"][t] >= scans)
    assert late["floor"]["gospa"] >= out["floor"]["gospa"]
    agg = fn.aggregate([out])
    assert agg["matched"]["r"] == r0
    assert agg["matched_floor"]["gospa"] == agg["floor"]["gospa"]
    assert agg["floor"]["ratio_matched"]["mean"] == 1.0


def test_aggregate_ratio_to_the_matched_floor():
    def run(seed, floor, matched, tracker):
        score = {"gospa": 0.0, "phases": {p: {"n_scans": 0} for p in fn.PHASES},
                 "confirm_scans": {}, "switches": 0, "false_per_scan": 0.0}  # fmt: skip
        return {
            "scene": "crossing",
            "seed": seed,
            "oracle": {},
            "floor": score | {"gospa": floor},
            "matched": {"r": 0.97, "oracle": {0: 9}, "floor": score | {"gospa": matched}},
            "trackers": {"jipda": score | {"gospa": tracker}},
        }

    agg = fn.aggregate([run(0, 10.0, 20.0, 30.0), run(1, 10.0, 15.0, 60.0)])
    assert agg["matched"] == {"r": 0.97, "oracle_median": 9.0, "oracle_never": 0}
    assert agg["jipda"]["ratio"]["mean"] == pytest.approx(4.5)
    assert agg["jipda"]["ratio_matched"]["mean"] == pytest.approx((1.5 + 4.0) / 2)
    assert agg["matched_floor"]["ratio"]["mean"] == pytest.approx(1.75)
    mixed = run(1, 10.0, 15.0, 60.0)
    mixed["matched"]["r"] = 0.99
    with pytest.raises(ValueError, match="one matched threshold"):
        fn.aggregate([run(0, 10.0, 20.0, 30.0), mixed])
    plain = run(1, 10.0, 15.0, 60.0)
    del plain["matched"]
    assert "matched" not in fn.aggregate([run(0, 10.0, 20.0, 30.0), plain])


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"births": 0}, "births"),
        ({"births": True}, "births"),
        ({"births": 2.5}, "births"),
        ({"births": 10**400}, "births"),
        ({"seed": -1}, "seed"),
        ({"level_nats": float("nan")}, "level_nats"),
        ({"level_nats": 1j}, "level_nats"),
        ({"grid": []}, "grid"),
        ({"grid": "0.9"}, "grid"),
        ({"grid": [0.9, 0.9]}, "increasing"),
        ({"grid": [0.9, 1.0]}, r"grid\[1\]"),
        ({"grid": [0.01]}, r"grid\[0\]"),
        ({"grid": [True]}, r"grid\[0\]"),
        ({"grid": [0.9 + 0j]}, r"grid\[0\]"),
        ({"config": "jipda"}, "config"),
    ],
)
def test_bad_input_is_refused_by_name(scene, kwargs, match):
    with pytest.raises(ValueError, match=match):
        fn.false_track_rate(scene, **kwargs)


def test_bad_matched_threshold_and_scenes_are_refused(scene):
    with pytest.raises(ValueError, match="config"):
        fn.false_track_rate(
            scene, config=dataclasses.replace(fn.jipda_config(scene), existence=False)
        )
    with pytest.raises(ValueError, match="Scenario"):
        fn.false_track_rate(scene.detections)
    flat = dataclasses.replace(scene, region=np.array([[0.0, 0.0], [0.0, 100.0]]))
    with pytest.raises(ValueError, match="region"):
        fn.false_track_rate(flat)
    for bad in (1.0, True, float("inf"), 0.001):
        with pytest.raises(ValueError, match="r_matched"):
            fn.evaluate("crossing", 0, [], scenario_kwargs={"n_scans": 3}, r_matched=bad)
