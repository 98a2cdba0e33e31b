"""PMB estimates that keep their lanes (issue 33, item 3).

Two targets on parallel lanes 2σ apart, known from the first scan (a Gaussian
prior at each, velocities known): the track-oriented PMB merges each
Bernoulli's mixture over its hypotheses, and without ``keep_apart`` both
Bernoullis weigh both targets' returns about equally, merge towards the middle
and their estimates hop from lane to lane. With it (the default) each Bernoulli
follows its own target. (The MAP event and the kept-apart weights against brute force:
``test_pmb_lanes_weights.py``.)
"""

from __future__ import annotations

import numpy as np
import pytest

from jointtrack.metrics import track_statistics
from jointtrack.trackers.pmbm import PMBMConfig, PMBMTracker, PMBTracker

SIGMA = 10.0
LANES = (0.0, 2 * SIGMA)
SPEED = 5.0


def _lanes_config(**over):
    """Two targets at x = 0 on the lanes, moving along x at SPEED, known at the start
    to σ/2 in position and only to σ_v = SPEED in velocity (as a start from nothing)."""
    means = [[0.0, y, SPEED, 0.0] for y in LANES]
    cov = np.diag([SIGMA**2 / 4, SIGMA**2 / 4, SPEED**2, SPEED**2]).tolist()
    settings = dict(
        measurement_noise=SIGMA**2,
        process_noise=0.01,
        p_d=0.95,
        clutter_density=1e-5,
        max_speed=2 * SPEED,
        birth_model="gaussian",
        birth_weights=[1e-6, 1e-6],
        birth_means=means,
        birth_covs=[cov, cov],
        prior_weight=2.0,
    )
    return PMBMConfig(**{**settings, **over})


def _lane_switches(kind, seed, n_scans=40, **over):
    """``(id switches, coverage)`` of the run by the package's track statistics
    (:func:`~jointtrack.metrics.track_statistics`, gate 5σ as a run scores).

    Detections: each target with P_D 0.95, noise σ; clutter on a 200 m × 100 m box
    around the pair at 1e-5 per m² (0.2 returns a scan).
    """
    rng = np.random.default_rng(seed)
    trk = kind(_lanes_config(**over))
    truth, est = [], []
    for k in range(n_scans):
        pos = np.array([[SPEED * k, y] for y in LANES])
        z = pos[rng.random(2) < 0.95]
        z = z + rng.normal(0.0, SIGMA, z.shape)
        clutter = rng.uniform([SPEED * k - 100, -40], [SPEED * k + 100, 60], (rng.poisson(0.2), 2))
        res = trk.step(float(k), np.concatenate([z, clutter]))
        truth += [(k, i, *p) for i, p in enumerate(pos)]
        est += [(k, i, *x[:2]) for i, x in zip(res.ids.tolist(), res.x, strict=True)]
    truth, est = np.array(truth, float), np.array(est, float).reshape(-1, 4)
    stats = track_statistics(
        truth[:, 0], truth[:, 1].astype(np.int64), truth[:, 2:],
        est[:, 0], est[:, 1].astype(np.int64), est[:, 2:], gate=5 * SIGMA,
    )  # fmt: skip
    return stats.n_id_switches, stats.coverage


#: the lanes' process noise: 2σ apart, the returns of a scan are often nearer the
#: other lane than their own, and a Bernoulli's prior is loose enough to be pulled
Q_LANES = 0.3


def test_pmb_keeps_both_lanes():
    """Default PMB, 6 seeds × 25 scans: both targets covered in ≥ 97 % of the scans of
    every run (coalesced Bernoullis would be one estimate between the lanes, merged
    as duplicates or reported as one), at most 2 id switches in any run (one swap of
    the two lanes) and at most 6 in all.

    Measured (35b1b0b): switches 0, 0, 2, 2, 0, 0, coverage 0.98–1.00; on 45abbd8
    (merged mixtures) 2, 2, 2, 2, 0, 6 (14): this test fails there. Over 40 scans,
    seeds 0–7: 2, 0, 2, 2, 4, 0, 0, 0 against 4, 2, 2, 2, 2, 6, 4, 4. With
    ``keep_apart = False`` the Bernoullis coalesce and are merged as duplicates:
    see the next test.
    """
    runs = [_lane_switches(PMBTracker, seed, 25, process_noise=Q_LANES) for seed in range(6)]
    switches = [s for s, _ in runs]
    assert min(c for _, c in runs) >= 0.97, runs
    assert max(switches) <= 2 and sum(switches) <= 6, runs


def test_pmb_without_keep_apart_loses_a_lane():
    """The control: ``keep_apart = False`` (the merged update of 45abbd8, with duplicates
    merged): some run covers the two targets in under 90 % of the scans (coalescence).
    Measured, seeds 0–7, 40 scans: coverage 0.84, 0.61, 0.74, 0.61, 0.91, 0.97, 0.62,
    0.68."""
    cover = [
        _lane_switches(PMBTracker, seed, process_noise=Q_LANES, keep_apart=False)[1]
        for seed in (0, 3, 7)
    ]
    assert min(cover) < 0.9, cover


def test_pmbm_track_estimator_keeps_both_lanes():
    """PMBM with ``estimator = "track"``, 20 scans (seed 0; seed 1 the same, measured):
    both targets covered in ≥ 97 % of the scans, at most 2 id switches (estimator 1
    too, on these)."""
    runs = [_lane_switches(PMBMTracker, 0, 20, process_noise=Q_LANES, estimator="track")]
    assert min(c for _, c in runs) >= 0.97, runs
    assert max(s for s, _ in runs) <= 2, runs


# ------------------------------------------------------------------ settings
@pytest.mark.parametrize(
    "name, value, want",
    [
        ("keep_apart", 1, "true or false"),
        ("keep_apart", "yes", "true or false"),
        ("keep_apart", None, "true or false"),
        ("duplicate_distance", -1.0, "duplicate_distance"),
        ("duplicate_distance", float("nan"), "duplicate_distance"),
        ("duplicate_distance", float("inf"), "duplicate_distance"),
        ("duplicate_distance", 1 + 2j, "duplicate_distance"),
        ("duplicate_distance", True, "duplicate_distance"),
        ("duplicate_distance", 10**400, "duplicate_distance"),
        ("estimator", "estimator 2", "'best' or 'track'"),
        ("estimator", None, "'best' or 'track'"),
        ("estimator", ["track"], "'best' or 'track'"),
    ],
)
def test_bad_lane_settings_are_refused_by_name(name, value, want):
    with pytest.raises(ValueError, match=f"PMBMConfig: {name} must be") as err:
        PMBMConfig(**{name: value})
    assert want in str(err.value)


def test_states_saved_before_the_lane_settings_continue_as_before():
    """A saved configuration without the issue-33 settings loads with the values under
    which its run continues exactly as before: merged update, no merging of
    Bernoullis, estimator 1, no measurement-driven birth."""
    d = PMBMConfig().to_dict()
    for name in ("keep_apart", "duplicate_distance", "estimator", "birth_per_return"):
        del d[name]
    cfg = PMBMConfig.from_dict(d, complete=True)
    assert (cfg.keep_apart, cfg.duplicate_distance, cfg.estimator, cfg.birth_per_return) == (
        False,
        0.0,
        "best",
        0.0,
    )
