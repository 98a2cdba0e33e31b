"""PMB and PMBM with an interacting multiple model (``motion = "imm"``, issue 32 item 2).

* one target, P_D = 1, P_S = 1 and a Bernoulli of existence 1: its only event is the detection
  (the miss weight 1 − r P_D is 0), so PMB, PMBM and a labelled Bernoulli must each be
  exactly the IMM filter (:func:`jointtrack.filters.imm.imm_predict`, then
  :func:`~jointtrack.filters.imm.imm_update` by the return) — modes, probabilities
  and the combined estimate to 1e-12, scan after scan;
* PMBM on a target in a 5°/s turn keeps one id with CV+CT, where CV fragments;
* the settings are checked by TrackerConfig's IMM checks (tests/test_imm_tracker.py
  runs its bad-settings cases on PMBMConfig too), state files carry the modes,
  ``jointtrack run`` writes the mode columns.
"""

from __future__ import annotations

import numpy as np
import pytest

from jointtrack.filters.imm import imm_combine, imm_predict, imm_update
from jointtrack.trackers.pmbm import PMBMConfig, PMBMTracker, PMBTracker
from jointtrack.trackers.state_io import StateFileError, read_state, write_state
from test_imm_tracker import CLUTTER_PER_SCAN, HALF_WIDTH, SIGMA, _turn


def _truth_turn(k):
    w = np.deg2rad(5.0)
    t = float(k)
    if k < 10:
        return np.array([30.0 * t, 0.0])
    th = w * (t - 10)
    return np.array([300.0 + 30.0 / w * np.sin(th), 30.0 / w * (1 - np.cos(th))])


@pytest.mark.parametrize("kind", [PMBTracker, PMBMTracker])
@pytest.mark.parametrize("labelled", [False, True])
def test_one_target_with_pd_1_is_the_imm_filter(kind, labelled):
    cfg = PMBMConfig(
        motion="imm", imm_modes=("cv", "ct", "ca"), p_d=1.0, p_survive=1.0, clutter_density=1e-6,
        birth_density=0.0, prior_density=1e-7, measurement_noise=SIGMA**2, process_noise=0.5,
        r_recycle=0.0,
    )  # fmt: skip
    trk = kind(cfg)
    rng = np.random.default_rng(7)
    z0 = _truth_turn(0)[None] + rng.normal(size=(1, 2)) * SIGMA
    lab = {"labels": ["T"]} if labelled else {}
    trk.step(0.0, z0, **lab)
    if labelled:
        modes = [trk.labelled_mode_x, trk.labelled_mode_P, trk.labelled_mode_log_prob]
    elif kind is PMBTracker:
        modes = [trk.mode_x, trk.mode_P, trk.mode_log_prob]
    else:
        modes = [trk.sth_mode_x, trk.sth_mode_P, trk.sth_mode_log_prob]
    assert len(modes[0]) == 1
    if not labelled:  # its existence: e / (λ + e) of the first return; make it certain
        if kind is PMBTracker:
            trk.existence[:] = 1.0
        else:
            trk.sth_r[:] = 1.0
    ref = [a.copy() for a in modes]
    meas = trk._measurement_model()
    for k in range(1, 40):
        z = _truth_turn(k)[None] + rng.normal(size=(1, 2)) * SIGMA
        res = trk.step(float(k), z, **lab)
        ref = imm_predict(*ref, trk._imm, 1.0)
        ref = imm_update(trk._imm, *ref, z, meas["H"], meas["R"])
        if labelled:
            got = (trk.labelled_mode_x, trk.labelled_mode_P, trk.labelled_mode_log_prob)
        elif kind is PMBTracker:
            got = (trk.mode_x, trk.mode_P, trk.mode_log_prob)
        else:
            assert trk.n_hypotheses == 1 and len(trk.sth_r) == 1
            got = (trk.sth_mode_x, trk.sth_mode_P, trk.sth_mode_log_prob)
        for a, b in zip(got, ref, strict=True):
            np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12 * np.abs(b).max())
        x, P = imm_combine(*ref)
        i = int(np.flatnonzero(res.ids == res.ids.min())[0])
        np.testing.assert_allclose(res.x[i], x[0, :4], rtol=1e-12, atol=1e-9)
        np.testing.assert_allclose(res.P[i], P[0, :4, :4], rtol=1e-12, atol=1e-9)
        np.testing.assert_allclose(res.mode_probabilities[i], np.exp(ref[2][0]), rtol=1e-12)
        assert res.mode_names == ("cv", "ct", "ca")


def _ids_on_target(trk, scans):
    for t, z in scans:
        trk.step(t, z)
    h = trk.history()
    near = np.array(
        [np.hypot(*(x[:2] - _truth_turn(int(t)))) < 60.0 for t, x in zip(h.time, h.x, strict=True)]
    )
    return set(h.track_id[near].tolist())


def test_pmbm_in_a_turn_keeps_one_id_with_imm():
    scans = _turn(0)
    base = dict(
        clutter_density=CLUTTER_PER_SCAN / (2 * HALF_WIDTH) ** 2,
        measurement_noise=SIGMA**2, process_noise=0.5, birth_density=1e-8, max_speed=60.0,
    )  # fmt: skip
    imm = _ids_on_target(PMBMTracker(PMBMConfig(motion="imm", **base)), scans)
    cv = _ids_on_target(PMBMTracker(PMBMConfig(**base)), scans)
    assert len(imm) == 1, imm
    assert len(cv) > 1, cv  # the test is sharp: CV loses the target in the turn


@pytest.mark.parametrize("kind", [PMBTracker, PMBMTracker])
def test_imm_state_saved_and_loaded_continues_identically(kind, tmp_path):
    scans = _turn(1)
    cfg = PMBMConfig(motion="imm", clutter_density=1e-6, birth_density=1e-8,
                     measurement_noise=SIGMA**2, process_noise=0.5)  # fmt: skip
    trk = kind(cfg)
    for t, z in scans[:20]:
        trk.step(t, z, labels=["A"] + [""] * (len(z) - 1) if len(z) else None)
    trk.save(tmp_path / "s.npz")
    again = kind.load(tmp_path / "s.npz")
    for t, z in scans[20:30]:
        a, b = trk.step(t, z), again.step(t, z)
        np.testing.assert_array_equal(a.x, b.x)
        np.testing.assert_array_equal(a.mode_probabilities, b.mode_probabilities)
    # a damaged mode field is refused naming it
    arrays, config, scalars, rng = read_state(tmp_path / "s.npz")
    name = "labelled_mode_log_prob"  # the labelled Bernoulli "A"'s
    assert len(arrays[name]) == 1
    arrays[name] = arrays[name].copy()
    arrays[name][0] += 1.0
    write_state(tmp_path / "bad.npz", arrays, config, scalars, rng)
    with pytest.raises(StateFileError, match=f"bad.npz.*{name}"):
        kind.load(tmp_path / "bad.npz")


def test_clusters_merged_past_the_budget_merge_each_mode():
    """PMBM with IMM: a state of several global hypotheses stepped with a ranking budget
    of 1 merges its cluster PMB style (``pmb-*``) across them; the merged Bernoullis'
    modes are moment-matched per mode, their probabilities still a distribution."""
    base = dict(motion="imm", clutter_density=CLUTTER_PER_SCAN / (2 * HALF_WIDTH) ** 2,
                measurement_noise=SIGMA**2, process_noise=0.5, birth_density=1e-8,
                max_speed=60.0)  # fmt: skip
    rng = np.random.default_rng(3)

    def scan(t):  # two targets 30 m apart (one cluster), and clutter
        truth = np.array([[10.0 * t, 0.0], [10.0 * t, 30.0]])
        return np.vstack([truth + rng.normal(size=(2, 2)) * 5.0, rng.uniform(-2e3, 2e3, (3, 2))])

    full = PMBMTracker(PMBMConfig(**base))
    for t in range(12):
        full.step(float(t), scan(t))
    assert full.n_hypotheses > 1
    trk = PMBMTracker(PMBMConfig(**base, max_ranking_work=1))
    trk._restore(full.state_dict())
    res = trk.step(12.0, scan(12))
    assert any(m.startswith("pmb-") for m in res.cluster_methods), res.cluster_methods
    np.testing.assert_allclose(np.exp(trk.sth_mode_log_prob).sum(axis=1), 1.0, rtol=1e-12)
    np.testing.assert_allclose(res.mode_probabilities.sum(axis=1), 1.0, rtol=1e-12)
    assert len(res.ids) >= 2
