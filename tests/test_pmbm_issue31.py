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

import copy
import functools
import math
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import event, given, settings
from hypothesis import strategies as st

from jointtrack.scenarios import crossing
from jointtrack.trackers import StateFileError
from jointtrack.trackers.pmbm import PMBMConfig, PMBMTracker, PMBTracker
from jointtrack.trackers.state_io import read_state, write_state
from test_pmbm_pmb_exact import _enumerate as pmb_enumerate
from test_pmbm_pmb_exact import _log_uniform, pmb_scene
from test_pmbm_pmb_exact import _tracker as pmb_tracker

# ---------------------------------------------- birth density at the noise settings' bound


@pytest.mark.parametrize("kind", [PMBTracker, PMBMTracker])
@pytest.mark.parametrize("variance", [1.0, 1e154, 1e300])
def test_birth_density_is_finite_up_to_the_noise_bound(kind, variance):
    # |det J| = sqrt(det C / det R) overflowed to inf / inf = NaN birth existence once the
    # 2-D measurement variance reached ~1e154 (the settings allow up to MAX_VARIANCE = 1e300)
    trk = kind(PMBMConfig(clutter_density=1e-4, birth_density=1e-6, measurement_noise=variance))
    z = np.array([[0.0, 0.0], [3.0, -1.0]])
    u = float(trk.undetected_density[0])
    with np.errstate(all="raise"):
        e, _, _ = trk._uniform_births(z)
        trk.step(0.0, z)
    # a position sensor: the return's covariance is R itself, so |det J| = 1 and the
    # density is P_D times the undetected intensity's uniform density
    np.testing.assert_allclose(e, trk._p_d * u, rtol=1e-12)


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
    trk.sth_born, trk.sth_reports = np.zeros(2 * T), np.zeros(2 * T)
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
        trk.born, trk.report_count = np.zeros(2), np.zeros(2)
    else:
        trk.sth_r, trk.sth_x, trk.sth_P = r, x, P
        trk.sth_track, trk.track_ids = np.array([0, 1]), np.array([1, 2])
        trk.track_reported, trk.next_id = np.zeros(2, bool), 3
        trk.sth_born, trk.sth_reports = np.zeros(2), np.zeros(2)
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


# ------------------------------------------------------------------ 10: damaged states


def _config():
    sc = crossing(seed=3)
    return sc, PMBMConfig(process_noise=0.05, measurement_noise=float(sc.R[0, 0]), p_d=sc.p_d,
                          clutter_density=sc.clutter_density, max_speed=15.0,
                          birth_density=1e-6)  # fmt: skip


@functools.cache
def _warm_cached(kind, n_scans=30):
    sc, cfg = _config()
    trk = kind(cfg)
    for k in range(n_scans):
        trk.step(sc.times[k], sc.detections[k])
    return trk


@functools.cache
def _good_file(kind, directory):
    return str(_warm_cached(kind).save(f"{directory}/{kind.KIND}-good.npz"))


def _rewrite(src, dst, mutate):
    arrays, config, scalars, rng = read_state(src)
    arrays = {k: v.copy() for k, v in arrays.items()}
    mutate(arrays, scalars)
    return write_state(dst, arrays, config, scalars, rng)


def _strip_track(arrays, track):
    """Remove every STH of ``track`` (consistently renumbered): a track with none."""
    keep = arrays["sth_track"] != track
    renumber = np.cumsum(keep) - 1
    for name in PMBMTracker._STH:
        arrays[name] = arrays[name][keep]
    hyp = arrays["hyp"]
    hyp[:, track] = -1
    arrays["hyp"] = np.where(hyp >= 0, renumber[np.maximum(hyp, 0)], -1)


def test_a_track_without_single_target_hypotheses_is_refused(tmp_path):
    good = _warm_cached(PMBMTracker).save(tmp_path / "good.npz")
    bad = _rewrite(good, tmp_path / "bad.npz", lambda a, s: _strip_track(a, 0))
    with pytest.raises(StateFileError, match=r"bad.npz.*track 0 .*no single-target hypothesis"):
        PMBMTracker.load(bad)

    def nothing_left(a, s):  # tracks, and not one STH (it was: IndexError)
        for name in PMBMTracker._STH:
            a[name] = a[name][:0]
        a["hyp"] = np.full_like(a["hyp"], -1)

    bad = _rewrite(good, tmp_path / "none.npz", nothing_left)
    with pytest.raises(StateFileError, match="no single-target hypothesis"):
        PMBMTracker.load(bad)


@pytest.mark.parametrize("kind, field", [(PMBTracker, "existence"), (PMBMTracker, "sth_r")])
@pytest.mark.parametrize("value", [0.0, -0.0, -5e-324, 1.0 + 2**-52])
def test_existence_outside_zero_one_is_refused(tmp_path, kind, field, value):
    good = _warm_cached(kind).save(tmp_path / "good.npz")

    def mutate(a, s):
        a[field][-1] = value

    bad = _rewrite(good, tmp_path / "bad.npz", mutate)
    with pytest.raises(StateFileError, match=rf"'{field}' has values outside \(0, 1\]"):
        kind.load(bad)


FLOATS = [0.0, -0.0, 5e-324, 1e-300, 1e-12, 0.5, 1.0, 1.0 + 2**-52, 2.0, 1e300, -1.0,
          -1e300, np.nan, np.inf]  # fmt: skip


@st.composite
def damage(draw, fields):
    """A list of edits of a state's arrays: set an entry, cut rows, strip a track."""
    ops = []
    for _ in range(draw(st.integers(1, 3))):
        kind = draw(st.sampled_from(["set", "set", "cut", "strip"]))
        field = draw(st.sampled_from(fields))
        where = draw(st.floats(0, 1))
        if kind == "set":
            ops.append((kind, field, where, draw(st.sampled_from(FLOATS)),
                        draw(st.integers(-3, 3))))  # fmt: skip
        elif kind == "cut":
            ops.append((kind, field, where, draw(st.integers(1, 3)), 0))
        else:
            ops.append((kind, field, where, 0, 0))
    return ops


def _apply(ops, arrays):
    # strips first: they renumber a consistent state
    for kind, field, where, value, shift in sorted(ops, key=lambda op: op[0] != "strip"):
        a = arrays[field]
        if kind == "strip":
            if "sth_track" in arrays and len(arrays["track_ids"]):
                _strip_track(arrays, int(where * (len(arrays["track_ids"]) - 1)))
            continue
        if a.size == 0:
            continue
        flat = a.reshape(-1) if kind == "set" else a
        i = min(int(where * len(flat)), len(flat) - 1)
        if kind == "cut":
            arrays[field] = np.delete(a, range(i, min(i + value, len(a))), axis=0)
        elif a.dtype.kind == "f":
            flat[i] = value
        elif a.dtype.kind == "b":
            flat[i] = not flat[i]
        else:  # an index or id near a boundary: −2 … length + 3
            flat[i] = int(np.clip(flat[i] + shift, -2, 10**6)) if shift else len(flat) + 1


def _steps_cleanly(trk):
    """Three scans of the crossing after the state's own: no exception, sane output."""
    sc, _ = _config()
    for k in range(30, 33):
        res = trk.step(sc.times[k], sc.detections[k])
        assert np.isfinite(res.x).all() and np.isfinite(res.P).all()
        assert ((res.existence > 0) & (res.existence <= 1)).all()


@pytest.mark.xfail(
    strict=True,
    reason="open (issue 35): a covariance with one variance of 1e300 (within MAX_VARIANCE) "
    "loads, and the next step refuses its innovation covariance as numerically singular "
    "(the filters' test is the unscaled condition number); load should refuse what the "
    "step cannot take, or the test be scale-invariant",
)
@pytest.mark.parametrize(("kind", "field"), [(PMBTracker, "P"), (PMBMTracker, "sth_P")])
def test_a_loaded_covariance_the_step_cannot_take_is_refused(tmp_path, kind, field):
    """Found by test_damaged_checksummed_states_are_refused_or_step: [('set', 'P', 0.0,
    1e300, 0)] — the first variance of the first track set to 1e300."""
    good = _good_file(kind, str(tmp_path))
    bad = _rewrite(
        good, tmp_path / "bad.npz", lambda a, s: _apply([("set", field, 0.0, 1e300, 0)], a)
    )
    try:
        trk = kind.load(bad)
    except StateFileError:
        return
    _steps_cleanly(trk)


PMB_FIELDS = ["x", "P", "ids", "existence", "reported", "poisson_w", "poisson_m", "poisson_P",
              "undetected_density"]  # fmt: skip
PMBM_FIELDS = ["sth_r", "sth_x", "sth_P", "sth_track", "track_ids", "track_reported", "hyp",
               "hyp_logw", "poisson_w", "undetected_density"]  # fmt: skip


@pytest.mark.parametrize("kind, fields", [(PMBTracker, PMB_FIELDS), (PMBMTracker, PMBM_FIELDS)])
@settings(max_examples=60, deadline=None)
@given(data=st.data())
def test_damaged_checksummed_states_are_refused_or_step(tmp_path_factory, kind, fields, data):
    """Edited values, cut rows, stripped tracks — saved with a valid checksum: load
    refuses with StateFileError naming the file, or the tracker steps normally."""
    ops = data.draw(damage(fields))
    d = tmp_path_factory.mktemp("s")
    good = _good_file(kind, str(d))
    bad = _rewrite(good, d / "bad.npz", lambda a, s: _apply(ops, a))
    try:
        trk = kind.load(bad)
    except StateFileError as exc:
        assert "bad.npz" in str(exc)
        event("refused")
        return
    event("loaded")
    try:
        _steps_cleanly(copy.deepcopy(trk))
    except ValueError as exc:
        # open (issue 35): a variance up to MAX_VARIANCE (1e300) loads and the step then
        # refuses its innovation covariance as singular — the known defect, held by
        # test_a_loaded_covariance_the_step_cannot_take_is_refused (xfail); CI at 6617278
        # drew it here as well. Any other error still fails this test.
        if "numerically singular" not in str(exc):
            raise
        event("issue 35: a loaded covariance the step refuses")
