"""PMBM re-acquisition: tentative tracks recycled by their marginal existence (issue 33, item 4).

``recycle_existence = "marginal"``: a never-reported PMBM track whose existence
summed over the global hypotheses, Σ_h w_h r_h, is below ``r_recycle`` goes to the
Poisson intensity with exactly that weight, even where some hypothesis holds it at
r = 1 (a return of the scan detected it there). With the default ``"least"`` such a
track is kept while any hypothesis holds it at ``r_recycle`` or more — from nothing
in dense clutter every tentative track is, and the hypotheses fill with
alternatives of one target's evidence (``benchmarks/RESULTS.md``, "Issue 33, PMBM
re-acquisition").
"""

from __future__ import annotations

import copy
import dataclasses

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from jointtrack.trackers.pmbm import PMBMConfig, PMBMTracker
from state_checks import assert_steps_alike

SIDE = 200.0


def _config(**over) -> PMBMConfig:
    """Dense clutter on a 200 m square (3e-4 per m², the headline's), σ = 10 m,
    P_D 0.9; intensity components neither pruned nor merged, so that what the
    step recycles is visible as components."""
    base = dict(
        clutter_density=3e-4,
        measurement_noise=100.0,
        max_speed=15.0,
        process_noise=0.01,
        birth_density=0.01 / SIDE**2,
        prior_density=1.0 / SIDE**2,
        poisson_prune=0.0,
        poisson_merge=0.0,
        max_poisson_components=10_000,
        r_recycle=0.0,
    )
    return PMBMConfig(**{**base, **over})


def _marginal_existence(trk: PMBMTracker) -> np.ndarray:
    """Σ_h w_h r_h per track, from the tracker's own global hypotheses."""
    w = trk.hypothesis_weights()
    held = trk.hyp >= 0
    r = np.where(held, trk.sth_r[np.maximum(trk.hyp, 0)], 0.0)
    return w @ r


def _twins(history, z, threshold):
    """Trackers with no recycling stepped through ``history``; then one more scan
    ``z`` by a copy without recycling and a copy recycling by the marginal at
    ``threshold``: ``(kept, recycling, result of recycling)``."""
    trk = PMBMTracker(_config(), keep_history=False)
    for t, zs in enumerate(history):
        trk.step(float(t), zs)
    kept = copy.deepcopy(trk)
    recycling = copy.deepcopy(trk)
    recycling.config = dataclasses.replace(
        trk.config, recycle_existence="marginal", r_recycle=threshold
    )
    t = float(len(history))
    kept.step(t, z)
    return kept, recycling, recycling.step(t, z)


def _track_state(trk: PMBMTracker) -> dict:
    """Each track id → the sorted existences of its single-target hypotheses."""
    return {
        int(i): sorted(trk.sth_r[trk.sth_track == j].tolist()) for j, i in enumerate(trk.track_ids)
    }


point = st.tuples(st.floats(60.0, 140.0), st.floats(60.0, 140.0))


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    # distinct returns in a scan: a repeated one is merged with a warning (not the subject here)
    history=st.lists(st.lists(point, min_size=0, max_size=3, unique=True), min_size=1, max_size=2),
    last=st.lists(point, min_size=1, max_size=3, unique=True),
    threshold=st.sampled_from([0.05, 0.3, 0.9]),
)
def test_marginal_recycling_moves_exactly_the_weak_tracks_with_their_marginal(
    history, last, threshold
):
    """After the same scan, the tracks the recycling tracker removed are exactly
    the never-reported ones whose marginal existence (computed from the
    non-recycling twin's hypotheses) is below the threshold; the intensity gains
    one component per removed single-target hypothesis, and per track their
    weights sum to that marginal existence (rtol 1e-12); every other track is
    kept with the same single-target hypotheses."""
    history = [np.array(h, float).reshape(-1, 2) for h in history]
    kept, recycling, _ = _twins(history, np.array(last, float), threshold)
    marginal = _marginal_existence(kept)
    weak = (marginal < threshold) & ~kept.track_reported
    assert set(recycling.track_ids.tolist()) == set(kept.track_ids[~weak].tolist())
    before = _track_state(kept)
    after = _track_state(recycling)
    for i in recycling.track_ids.tolist():
        np.testing.assert_allclose(after[i], before[i], rtol=1e-12)
    # no component was in the intensity before the scan (no recycling until then):
    # every component is one recycled single-target hypothesis
    n_sth = sum(len(before[int(i)]) for i in kept.track_ids[weak])
    assert len(recycling.poisson_w) == n_sth
    np.testing.assert_allclose(
        np.sum(recycling.poisson_w), np.sum(marginal[weak]), rtol=1e-12, atol=0.0
    )
    # component by component: each recycled single-target hypothesis s with weight
    # r_s × Σ of the weights of the hypotheses holding it
    w = kept.hypothesis_weights()
    want = [
        kept.sth_r[s] * w[kept.hyp[:, j] == s].sum()
        for j in np.flatnonzero(weak)
        for s in np.flatnonzero(kept.sth_track == j)
    ]
    np.testing.assert_allclose(np.sort(recycling.poisson_w), np.sort(want), rtol=1e-12)


def test_a_track_likely_in_some_hypotheses_is_recycled_only_by_its_marginal():
    """A prior track near a return: in one hypothesis the return detected it, in
    the other the return started a new track of existence e/ρ ≥ 0.5 (dense prior
    intensity, sparse clutter) — but the marginal of that new track is below 0.5.
    "least" at 0.5 keeps it (some hypothesis holds it above 0.5), "marginal" at 0.5
    recycles it, and the intensity holds its marginal (with those of the other
    tracks recycled at that scan)."""
    cfg = _config(clutter_density=1e-6, prior_density=1e-3, birth_density=1e-5)
    trk = PMBMTracker(cfg, keep_history=False)
    trk.step(0.0, np.array([[100.0, 100.0]]))
    trk.step(1.0, np.array([[101.0, 100.0]]))
    z = np.array([[102.0, 100.0]])
    least = copy.deepcopy(trk)
    least.config = dataclasses.replace(cfg, r_recycle=0.5)
    marginal = copy.deepcopy(trk)
    marginal.config = dataclasses.replace(cfg, r_recycle=0.5, recycle_existence="marginal")
    plain = copy.deepcopy(trk)
    plain.step(2.0, z)
    new = int(np.flatnonzero(~plain.track_reported)[-1])
    r_new = plain.sth_r[plain.sth_track == new]
    m_new = _marginal_existence(plain)[new]
    assert r_new.max() >= 0.5 > m_new > 0.0, (r_new, m_new)
    least.step(2.0, z)
    marginal.step(2.0, z)
    assert plain.track_ids[new] in least.track_ids
    assert plain.track_ids[new] not in marginal.track_ids
    assert marginal.n_hypotheses <= least.n_hypotheses
    # the intensity holds the marginals of the tracks recycled (this one among them)
    gone = ~np.isin(plain.track_ids, marginal.track_ids)
    assert gone[new] and not plain.track_reported[gone].any()
    np.testing.assert_allclose(
        marginal.poisson_w.sum(), _marginal_existence(plain)[gone].sum(), rtol=1e-12
    )


def test_marginal_recycling_resumes_exactly(tmp_path):
    """A run with the setting saved mid-way and loaded steps on bit for bit."""
    rng = np.random.default_rng(3)
    scans = [
        (float(k), np.vstack([rng.uniform(0, SIDE, (6, 2)), [[40.0 + 4 * k, 100.0]]]))
        for k in range(8)
    ]
    trk = PMBMTracker(_config(r_recycle=0.3, recycle_existence="marginal"), keep_history=False)
    for t, z in scans[:5]:
        trk.step(t, z)
    path = trk.save(tmp_path / "state.npz")
    loaded = PMBMTracker.load(path, keep_history=False)
    assert loaded.config.recycle_existence == "marginal"
    assert_steps_alike(trk, loaded, scans[5:])


def test_states_saved_before_the_setting_recycle_as_before():
    """A saved configuration without it loads with "least" (its run continues as before)."""
    d = PMBMConfig(r_recycle=0.3).to_dict()
    del d["recycle_existence"]
    assert PMBMConfig.from_dict(d, complete=True).recycle_existence == "least"


@pytest.mark.parametrize(
    "value", ["Marginal", "track", "", None, 1, True, 1j, ["marginal"], np.array(["marginal"])]
)
def test_bad_recycle_existence_is_refused_by_name(value):
    with pytest.raises(ValueError, match="PMBMConfig: recycle_existence must be") as err:
        PMBMConfig(recycle_existence=value)
    assert "'least' or 'marginal'" in str(err.value)
