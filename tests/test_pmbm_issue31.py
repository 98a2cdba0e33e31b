"""Issue 31, defects 3, 4 and 10: PMB/PMBM on settings and states that killed them.

* **3** — ``hypothesis_prune`` in [0, 1) pruned *every* global hypothesis when the
  best normalised weight was below it (many near-equal hypotheses): "zero-size
  array to reduction operation maximum", at every retry. The most probable
  hypotheses are now always kept.
* **4** — a Bernoulli's detected mass was 1 − β₀, which for a weak Bernoulli
  (β₀ ≈ 1) keeps only the last bits of β₀: PMB then raised "association
  probabilities sum to 1.0000034"; PMBM let existence underflow to 0 and raised
  "P_D must lie in (0, 1], got 0.0". The detected mass is now Σ_j β_ij, and a
  Bernoulli of existence 0 is dropped. Checked against exact rational
  enumeration down to existence 1e-9.
* **10** — hand-made states with a valid checksum: tracks without single-target
  hypotheses raised IndexError on load, existence 0 loaded and then every step
  failed. Such states are refused with :class:`StateFileError`; damaged states
  drawn by hypothesis are either refused at load or step normally.
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from jointtrack.trackers.pmbm import PMBMConfig, PMBMTracker, PMBTracker
from test_pmbm_pmb_exact import _enumerate as pmb_enumerate
from test_pmbm_pmb_exact import _log_uniform, pmb_scene
from test_pmbm_pmb_exact import _tracker as pmb_tracker

# ------------------------------------------------------------------ 3: pruning to nothing


@pytest.mark.parametrize("seed", range(6))
def test_hypothesis_prune_never_prunes_every_hypothesis(seed):
    """The issue's reproduction: two returns 3 m apart, hypothesis_prune = 0.1."""
    trk = PMBMTracker(PMBMConfig(hypothesis_prune=0.1))
    rng = np.random.default_rng(seed)
    for t in range(12):
        trk.step(float(t), np.array([[0.0, 0.0], [3.0, 0.0]]) + rng.normal(0, 1, (2, 2)))
        w = trk.hypothesis_weights()
        assert trk.n_hypotheses >= 1 and trk.hyp_logw.max() == 0.0
        # kept: the best, and the others above the threshold (after merging duplicates
        # and recycling, weights only grow relative to the pruned set)
        assert w.max() == w[0]


def _equal_state(T, H, **config):
    """T tracks with two equal-existence STHs each, far from the returns; H hypotheses,
    each a different choice of STHs: after a scan every hypothesis weighs the same."""
    trk = PMBMTracker(
        PMBMConfig(clutter_density=1e-4, birth_density=1e-6, measurement_noise=1.0, **config)
    )
    trk.sth_r = np.full(2 * T, 0.9)
    trk.sth_x = np.array([[100.0 * i + 5.0 * b, 0.0, 1.0, 0.0] for i in range(T) for b in (0, 1)])
    trk.sth_P = np.tile(np.diag([4.0, 4.0, 1.0, 1.0]), (2 * T, 1, 1))
    trk.sth_track = np.repeat(np.arange(T), 2)
    trk.track_ids = np.arange(1, T + 1)
    trk.track_reported = np.zeros(T, bool)
    trk.next_id = T + 1
    bits = (np.arange(H)[:, None] >> np.arange(T)[None, :]) & 1
    trk.hyp = (2 * np.arange(T)[None, :] + bits).astype(np.int64)
    trk.hyp_logw = np.zeros(H)
    trk.time = 0.0
    return trk


@pytest.mark.parametrize("T, H, prune", [(9, 300, 0.01), (18, 200_000, 1e-4)])
def test_many_equal_hypotheses_keep_the_best(T, H, prune):
    """Every new hypothesis weighs 1/H < hypothesis_prune: the best — all of them, tied —
    are kept up to max_hypotheses (it was: none, and a ValueError)."""
    trk = _equal_state(T, H, hypothesis_prune=prune)
    assert 1.0 / H < trk.config.hypothesis_prune
    res = trk.step(1.0, np.array([[1e5, 1e5]]))
    assert trk.n_hypotheses == min(H, trk.config.max_hypotheses)
    np.testing.assert_array_equal(trk.hyp_logw, 0.0)
    assert len(res.ids) == T  # every track in the (any) best hypothesis, r ≥ r_estimate
    trk.step(2.0, np.array([[1e5, 1e5]]))  # and the next scan works too


# ------------------------------------------------------- 4: detected mass and r = 0


def test_pmb_weak_bernoulli_reproduction():
    """The issue's PMB run: r_prune = r_recycle = 0, five scans near the origin, then one
    return per scan far away; scan 19 raised "association probabilities sum to …"."""
    trk = PMBTracker(PMBMConfig(clutter_density=1e-4, birth_density=1e-6, r_prune=0.0,
                                r_recycle=0.0))  # fmt: skip
    for k in range(5):
        trk.step(float(k), np.array([[0.1 * k, 0.1 * k]]))
    for k in range(40):
        trk.step(float(5 + k), np.array([[5000.0 + 37 * k, 9000.0]]))
        assert ((trk.existence > 0) & (trk.existence <= 1)).all()
        assert np.isfinite(trk.x).all()


def test_pmbm_existence_underflow_reproduction():
    """The issue's PMBM run with p_survive = 0.5: existences halve and miss until they
    underflow to 0; scan 248 raised "P_D must lie in (0, 1], got 0.0"."""
    trk = PMBMTracker(PMBMConfig(clutter_density=1e-4, birth_density=1e-6, r_prune=0.0,
                                 r_recycle=0.0, p_survive=0.5))  # fmt: skip
    for k in range(5):
        trk.step(float(k), np.array([[0.1 * k, 0.1 * k]]))
    smallest = 1.0
    for k in range(255):
        trk.step(float(5 + k), np.array([[5000.0 + 37 * k, 9000.0]]))
        assert (trk.sth_r > 0).all()
        smallest = min(smallest, trk.sth_r.min())
    assert smallest < 1e-300  # the run went where the existences underflow


@pytest.mark.parametrize("kind", [PMBTracker, PMBMTracker])
def test_existence_that_underflows_in_the_prediction_is_dropped(kind):
    """r = 5e-324 times P_S = 0.5 is 0: that Bernoulli is gone, not handed to the
    association as a P_D of 0."""
    trk = kind(PMBMConfig(clutter_density=1e-4, r_prune=0.0, r_recycle=0.0, p_survive=0.5))
    x, P = np.array([[0.0, 0.0, 0.0, 0.0], [500.0, 0.0, 0.0, 0.0]]), np.stack([np.eye(4)] * 2)
    r = np.array([5e-324, 0.9])
    if kind is PMBTracker:
        trk.x, trk.P, trk.existence = x, P, r
        trk.ids, trk.reported, trk.next_id = np.array([1, 2]), np.zeros(2, bool), 3
    else:
        trk.sth_r, trk.sth_x, trk.sth_P = r, x, P
        trk.sth_track, trk.track_ids = np.array([0, 1]), np.array([1, 2])
        trk.track_reported, trk.next_id = np.zeros(2, bool), 3
        trk.hyp, trk.hyp_logw = np.array([[0, 1]]), np.zeros(1)
    trk.time = 0.0
    res = trk.step(1.0, np.array([[0.5, 0.0], [500.0, 0.5]]))
    assert 1 not in res.ids.tolist()
    ids = trk.ids if kind is PMBTracker else trk.track_ids[trk.sth_track]
    assert 1 not in ids.tolist()


@st.composite
def weak_pmb_scene(draw):
    """PMB scenes whose Bernoullis may be all but certainly absent (r down to 1e-9)."""
    sc = draw(pmb_scene())
    sc["r"] = [draw(st.one_of(st.just(1.0), _log_uniform(-9, 0))) for _ in sc["r"]]
    return sc


@settings(max_examples=80, deadline=None)
@given(sc=weak_pmb_scene())
def test_weak_bernoulli_existence_equals_the_rational_enumeration(sc):
    """r_i' = β_i0 r_i (1 − P_D) / (1 − r_i P_D) + Σ_j β_ij, exactly enumerated, to 1e-9
    relative: with 1 − β₀ for the detected mass it was off by up to 1e-5 at r = 1e-10
    (and the PDA update refused β₀ + Σ w ≠ 1)."""
    trk = pmb_tracker(sc)
    n = len(sc["r"])
    pd = Fraction(sc["p_d"])
    beta, beta0, _, _, _ = pmb_enumerate(sc)
    trk.step(0.0, sc["z"])
    for i in range(n):
        ri = Fraction(sc["r"][i])
        r_post = beta0[i] * ri * (1 - pd) / (1 - ri * pd) + sum(beta[i])
        assert math.isclose(trk.existence[i], float(r_post), rel_tol=1e-9), (i, r_post)
