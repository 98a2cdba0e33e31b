"""Issue 25: the exact budget per kind of track, and the run's association sentence.

Clusters of tentative tracks are budgeted by the exact engine's own measure of
work (``exact_max_bits_tentative``: the frontier width of the exact DP), not by
``exact_max_tracks``; the closing line of ``jointtrack run`` says in words how
many clusters of which kind and size were solved how, and why.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from jointtrack.association import marginals
from jointtrack.experiments.config import RunConfigError, check_kind_keys, make_tracker_config
from jointtrack.experiments.run import run_scenario
from jointtrack.experiments.summary import association_line, cluster_rows, count_cluster
from jointtrack.trackers import JPDATracker, TrackerConfig
from jointtrack.trackers.config import check_field
from jointtrack.trackers.state_io import write_state

FIELD = "exact_max_bits_tentative"


# ------------------------------------------------------------------ the setting


@pytest.mark.parametrize(
    "bad", [True, False, -1, 31, 10**100, "16", 16.0, 1 + 2j, np.float64(3), [16]]
)
def test_bad_budget_is_refused_naming_the_field(bad):
    with pytest.raises(ValueError, match=FIELD):
        TrackerConfig(**{FIELD: bad})
    with pytest.raises(ValueError, match=FIELD):
        check_field(FIELD, bad)


@pytest.mark.parametrize("good", [None, 0, 12, 30, np.int64(20)])
def test_good_budget_is_kept(good):
    cfg = TrackerConfig(**{FIELD: good})
    assert getattr(cfg, FIELD) == good
    assert TrackerConfig.from_dict(cfg.to_dict()) == cfg


def test_budget_from_toml_and_refused_for_poisson_kinds(tmp_path):
    assert getattr(make_tracker_config({}, {FIELD: 12}), FIELD) == 12
    with pytest.raises(RunConfigError, match=FIELD):
        make_tracker_config({}, {FIELD: -3}, source="run.toml")
    with pytest.raises(RunConfigError, match=FIELD):
        check_kind_keys("pmb", {FIELD: 12}, {}, "run.toml")


# ------------------------------------------------------------ tracker routing


def _tentative_cluster(n=6, **cfg):
    """Step two scans of ``n`` close returns: one cluster of ``n`` tentative tracks.

    Returns the records of every multi-track cluster of the second scan and its result.
    """
    seen = []
    trk = JPDATracker(
        TrackerConfig(clutter_density=1e-4, **cfg), on_cluster=lambda rec: seen.append(rec)
    )
    z = np.column_stack([np.arange(n) * 3.0, np.zeros(n)])
    trk.step(0.0, z)
    seen.clear()
    res = trk.step(1.0, z + 0.5)
    return seen, res


def test_tentative_cluster_above_the_track_limit_is_solved_exactly():
    seen, res = _tentative_cluster(exact_max_tracks=2)
    big = [r for r in seen if len(r.track_ids) > 2]
    assert big and all(not r.confirmed for r in big)
    assert all(r.method == "exact" for r in big)
    assert res.n_fallbacks == 0
    for r in big:  # the engine's β, not an approximation's
        np.testing.assert_allclose(r.beta, marginals(r.L, r.miss, method="exact"), atol=1e-12)


def test_tentative_cluster_past_the_bits_budget_goes_to_lbp_naming_it():
    seen, res = _tentative_cluster(exact_max_tracks=2, exact_max_bits_tentative=1)
    big = [r for r in seen if len(r.track_ids) > 2]
    assert big and all(r.method == "lbp" for r in big)
    reasons = [f for f in res.cluster_fallbacks if f]
    assert reasons and all(f.startswith(f"{FIELD}: ") for f in reasons)
    assert all("max_bits = 1" in f for f in reasons)


def test_none_budgets_tentative_clusters_by_exact_max_tracks():
    """None: the behaviour before the setting (state files written before it load so)."""
    seen, res = _tentative_cluster(exact_max_tracks=2, exact_max_bits_tentative=None)
    big = [r for r in seen if len(r.track_ids) > 2]
    assert big and all(r.method == "lbp" for r in big)
    assert set(f for f in res.cluster_fallbacks if f) == {"exact_max_tracks"}


def test_state_file_without_the_setting_loads_with_none(tmp_path):
    trk = JPDATracker(TrackerConfig(clutter_density=1e-4, exact_max_bits_tentative=9))
    trk.step(0.0, np.array([[0.0, 0.0], [3.0, 0.0]]))
    assert getattr(JPDATracker.load(trk.save(tmp_path / "now.npz")).config, FIELD) == 9
    old = trk.config.to_dict()
    del old[FIELD]  # as written before the setting existed
    arrays = {n: getattr(trk, trk._attr(n)) for n in trk._ARRAYS}
    path = write_state(
        tmp_path / "old.npz", arrays, old, trk._saved_scalars(), trk.rng.bit_generator.state
    )
    assert getattr(JPDATracker.load(path).config, FIELD) is None


# ------------------------------------------------------------------ the sentence


def _metrics(rows, **assoc):
    solved = {}
    for kind, method, reason, n_tr, n_me in rows:
        count_cluster(solved, kind == "confirmed", method, reason, n_tr, n_me)
    return {"association": {"clusters": cluster_rows(solved), **assoc}}


def test_all_exact_says_so():
    m = _metrics(
        [
            ("confirmed", "exact", "", 2, 3),
            ("confirmed", "exact", "", 5, 8),
            ("tentative", "exact", "", 40, 20),
        ]
    )
    line = association_line(m)
    assert line.startswith("association: all 3 multi-track clusters solved exactly")
    assert "2 clusters of confirmed tracks (2–5 tracks)" in line
    assert "1 cluster of tentative tracks (40 tracks)" in line
    assert "belief" not in line


def test_fallbacks_name_count_sizes_kind_and_budget():
    m = _metrics(
        [
            ("confirmed", "exact", "", 2, 3),
            ("tentative", "exact", "", 3, 4),
            ("tentative", "lbp", "exact_max_bits_tentative: the exact DP …", 18, 9),
            ("tentative", "lbp", "exact_max_bits_tentative: the exact DP …", 24, 30),
            ("tentative", "lbp", "exact_max_bits_tentative: the exact DP …", 20, 11),
        ],
        exact_max_tracks=16,
        exact_max_bits_tentative=7,
    )
    line = association_line(m)
    assert line.count("association:") == 1
    assert "1 cluster of confirmed tracks (2 tracks) solved exactly" in line
    assert "4 clusters of tentative tracks (3–24 tracks)" in line
    assert "1 (3 tracks) solved exactly and 3 (18–24 tracks) by loopy belief propagation" in line
    assert "needs more than 2^7 states" in line and "exact_max_bits_tentative = 7" in line
    m = _metrics([("confirmed", "lbp", "exact_max_tracks", 20, 30)], exact_max_tracks=16)
    assert "more than exact_max_tracks = 16" in association_line(m)


def test_pmbm_budget_tiers_are_said_in_words():
    m = _metrics(
        [
            ("confirmed", "murty", "", 2, 3),
            ("confirmed", "murty-truncated", "ranking_truncated: ranking …", 30, 40),
            ("confirmed", "pmb-lbp-sparse", "ranking_merged: ranking even …", 90, 2000),
        ],
        max_ranking_work=2**25,
    )
    m["tracker"] = {"kind": "pmbm"}
    line = association_line(m)
    assert "1 (2 tracks) solved exactly (ranked assignments)" in line
    assert "1 (30 tracks) by fewer ranked assignments per hypothesis" in line
    assert "1 (90 tracks) merged to one Bernoulli per track (PMB) and solved by sparse" in line
    assert line.count(f"max_ranking_work = {2**25}") == 2
    assert "pmb-" not in line and "murty" not in line
    only_ranked = _metrics([("confirmed", "murty", "", 2, 3)])
    assert association_line(only_ranked).startswith("association: all 1 multi-track")


def test_older_metrics_have_no_sentence():
    assert association_line({"association": {"fallbacks": {"x": 1}}}) is None


def _run(tmp_path, name, **tracker):
    run_scenario("bojilov", tracker, tmp_path / name, plots=False, max_scans=10)
    return json.loads((tmp_path / name / "metrics.json").read_text())


def test_run_forced_past_a_small_budget_counts_and_says_it(tmp_path):
    m = _run(tmp_path, "small", exact_max_bits_tentative=2)
    assoc = m["association"]
    rows = [r for r in assoc["clusters"] if r["reason"] == FIELD]
    assert rows and all(r["tracks"] == "tentative" and r["method"] == "lbp" for r in rows)
    n = sum(r["count"] for r in rows)
    assert assoc["fallbacks"] == {f"{FIELD}, tentative tracks": n}
    line = association_line(m)
    lo = min(r["n_tracks"][0] for r in rows)
    hi = max(r["n_tracks"][1] for r in rows)
    assert f"{n} ({lo}–{hi} tracks) by loopy belief propagation" in line
    assert "exact_max_bits_tentative = 2" in line


def test_default_run_solves_large_tentative_clusters_exactly(tmp_path):
    """The default run's tentative clusters are budgeted by frontier width, not by tracks.

    Clusters of more than exact_max_tracks tentative tracks are solved exactly when
    their DP is narrow; only those wider than the default budget go to LBP, and
    the sentence says so.
    """
    m = _run(tmp_path, "default")
    assoc = m["association"]
    assert assoc["exact_max_bits_tentative"] == TrackerConfig().exact_max_bits_tentative == 12
    assert not any(k.startswith("exact_max_tracks") for k in assoc["fallbacks"])
    exact = [r for r in assoc["clusters"] if r["tracks"] == "tentative" and r["method"] == "exact"]
    assert max(r["n_tracks"][1] for r in exact) > assoc["exact_max_tracks"]
    approx = [r for r in assoc["clusters"] if r["reason"]]
    assert all(r["reason"] == FIELD and r["tracks"] == "tentative" for r in approx)
    line = association_line(m)
    assert line.count("association:") == 1 and "solved exactly" in line
    if approx:
        assert "exact_max_bits_tentative = 12" in line
    else:
        assert line.startswith("association: all ")


def test_resumed_run_tallies_every_scan(tmp_path):
    """The tally is kept in the checkpoint: a resumed run reports the whole run's clusters."""
    whole = _run(tmp_path, "whole")
    part, ck = tmp_path / "part", tmp_path / "ck.npz"
    run_scenario("bojilov", {}, part, plots=False, max_scans=4, checkpoint=ck)
    run_scenario("bojilov", {}, part, plots=False, max_scans=10, resume=ck)
    resumed = json.loads((part / "metrics.json").read_text())
    assert resumed["association"]["clusters"] == whole["association"]["clusters"]
    assert association_line(resumed) == association_line(whole)


def test_enumerate_keeps_the_track_limit_for_tentative_clusters():
    """Frontier bits measure the exact DP only: enumeration keeps exact_max_tracks."""
    seen, res = _tentative_cluster(association="enumerate", exact_max_tracks=2)
    big = [r for r in seen if len(r.track_ids) > 2]
    assert big and all(r.method == "lbp" for r in big)
    assert set(f for f in res.cluster_fallbacks if f) == {"exact_max_tracks"}
