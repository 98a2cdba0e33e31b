"""PMB and PMBM trackers on whole scenes: false tracks in clutter, ids kept through a crossing."""

from __future__ import annotations

import numpy as np
import pytest

from jointtrack.scenarios import crossing
from jointtrack.trackers.pmbm import PMBMConfig, PMBMTracker, PMBTracker

KINDS = [PMBTracker, PMBMTracker]


@pytest.mark.parametrize(
    "kind, seed, n_scans",
    [(PMBTracker, 0, 100), (PMBTracker, 1, 100), (PMBMTracker, 0, 30)],
)
def test_clutter_only_false_reports_are_rare(kind, seed, n_scans):
    """Scans of 20 clutter returns uniform on a 1000 × 1000 box, no target.

    Default configuration (uniform birth 1e-7 per unit area, steady-state
    prior, max_speed 50, r_estimate 0.4) with the matching clutter density
    2e-5. Zero is NOT achieved. Measured over 100 scans (2000 returns):
    seed 0 — PMB 3 false ids, PMBM 4; seed 1 — 0 and 0; i.e. about 2 false
    tracks per 100 scans (a new Bernoulli starts at e/ρ ≈ 0.005, and with
    velocity σ = max_speed/2 its next gate holds ~0.4 clutter returns, each
    raising the odds ~10×: two or three lucky hits confirm it). Asserted bound:
    at most 6 reported ids per 100 scans (PMB). PMBM runs 30 scans of seed 0
    only — it takes ~2 s per scan of this clutter on the loaded 2-core test
    machine (PMB: 0.05 s) — and reported 3 false ids in them; bound 4.
    """
    rng = np.random.default_rng(seed)
    trk = kind(PMBMConfig(clutter_density=20 / 1e6))
    reported = set()
    for k in range(n_scans):
        z = rng.uniform(0.0, 1000.0, size=(rng.poisson(20), 2))
        reported.update(trk.step(float(k), z).ids.tolist())
    bound = 6 if kind is PMBTracker else 4
    assert len(reported) <= bound, sorted(reported)


def _crossing_config(sc):
    return PMBMConfig(
        process_noise=0.05,
        measurement_noise=float(sc.R[0, 0]),
        p_d=sc.p_d,
        clutter_density=sc.clutter_density,
        max_speed=15.0,
    )


def _assign(x, truth, radius=30.0):
    """Estimate index per truth row (−1 for none): the pairing of least total distance
    among those within ``radius`` (two targets: every pair is tried)."""
    d = np.linalg.norm(x[:, None, :2] - truth[None, :, :2], axis=2)  # (K, 2)
    best, best_cost = [-1, -1], (0, 0.0)
    options = [-1, *range(len(x))]
    for i in options:
        for j in options:
            if i == j != -1 or (i >= 0 and d[i, 0] > radius) or (j >= 0 and d[j, 1] > radius):
                continue
            n = (i >= 0) + (j >= 0)
            cost = (i >= 0 and d[i, 0]) + (j >= 0 and d[j, 1])
            if (n, -cost) > (best_cost[0], -best_cost[1]):
                best, best_cost = [i, j], (n, cost)
    return best


@pytest.mark.parametrize(
    "kind, seed",
    [(PMBTracker, 1), (PMBTracker, 2), (PMBTracker, 3), (PMBMTracker, 1), (PMBMTracker, 2)],
)
def test_crossing_targets_keep_their_ids(kind, seed):
    """Two targets crossing at 45° (σ = 10, P_D 0.9, 10 clutter/scan; within a few σ
    of each other for a few scans around t_c = 30). Each target is matched to the
    reported estimates (least total distance, within 3σ). Asserted: from scan 10
    to 5 scans before the crossing, and from 5 scans after it to the end, each
    target's matched estimates carry one id, the same before and after, and the
    two targets' ids differ; each target is matched in ≥ 90 % of the scans after
    the first 10."""
    sc = crossing(seed=seed)
    trk = kind(_crossing_config(sc))
    t_c = sc.info["t_cross"]
    ids_of = {0: set(), 1: set()}
    matched = {0: 0, 1: 0}
    for k, (t, z) in enumerate(zip(sc.times, sc.detections, strict=True)):
        r = trk.step(t, z)
        if k < 10:
            continue
        pick = _assign(r.x, sc.truth_states[k])
        for target, i in zip(sc.truth_ids[k].tolist(), pick, strict=True):
            if i < 0:
                continue
            matched[target] += 1
            if abs(t - t_c) > 5:
                ids_of[target].add(int(r.ids[i]))
    assert len(ids_of[0]) == 1 and len(ids_of[1]) == 1, ids_of
    assert ids_of[0] != ids_of[1], ids_of
    assert min(matched.values()) >= 0.9 * (len(sc.times) - 10), matched
