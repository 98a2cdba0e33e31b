"""``Scenario.tracker_config()``: the tracker settings a scene was made with (issue 25).

The fields are read back against the generators' own arguments (drawn by hypothesis),
runs with the config find the targets within the first scans, and overrides are
checked by ``TrackerConfig`` (a bad name or value is an error naming it).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from jointtrack import JPDATracker, TrackerConfig
from jointtrack.experiments.config import scenario_tracker_settings
from jointtrack.scenarios import abreast, bojilov, coalescence, crossing, many_targets

SIGMA = st.floats(0.5, 30.0)
Q = st.floats(1e-4, 2.0)
P_D = st.floats(0.5, 1.0)
CLUTTER = st.sampled_from([0.0, 1.0, 7.5, 40.0])
DT = st.sampled_from([0.5, 1.0, 2.0])


def _check_matched(sc, cfg: TrackerConfig, *, sigma, q, p_d, clutter_rate, p_g=0.99):
    """cfg holds the generating parameters (given independently of the scenario's fields)."""
    assert isinstance(cfg, TrackerConfig)
    assert cfg.dim == 2 and cfg.motion == "cv" and cfg.sensor == "position"
    assert cfg.measurement_noise == pytest.approx(sigma**2, rel=1e-12)
    np.testing.assert_allclose(cfg.measurement_covariance(), sigma**2 * np.eye(2), rtol=1e-12)
    assert cfg.process_noise == pytest.approx(q, rel=1e-12)
    assert cfg.p_d == pytest.approx(p_d, rel=1e-12)
    assert cfg.p_g == pytest.approx(p_g, rel=1e-12)
    area = float(np.prod(sc.region[:, 1] - sc.region[:, 0]))
    if clutter_rate == 0:
        assert cfg.clutter_density is None  # nothing to match: estimated
    else:
        assert cfg.clutter_density == pytest.approx(clutter_rate / area, rel=1e-12)
    speeds = np.concatenate([np.linalg.norm(s[:, 2:], axis=1) for s in sc.truth_states])
    assert cfg.max_speed == pytest.approx(1.5 * speeds.max(), rel=1e-12)
    # the one mapping: exactly what `jointtrack run --scenario` derives
    assert cfg == TrackerConfig.from_dict(scenario_tracker_settings(sc))


@settings(max_examples=20, deadline=None)
@given(sigma=SIGMA, q=Q, p_d=P_D, clutter=CLUTTER, dt=DT, seed=st.integers(0, 2**16))
def test_crossing_config_is_its_generating_parameters(sigma, q, p_d, clutter, dt, seed):
    sc = crossing(
        seed,
        n_scans=6,
        dt=dt,
        sigma=sigma,
        process_noise=q,
        p_d=p_d,
        clutter_per_scan=clutter,
    )
    _check_matched(sc, sc.tracker_config(), sigma=sigma, q=q, p_d=p_d, clutter_rate=clutter)
    np.testing.assert_allclose(np.diff(sc.times), dt)  # the tracker's dt: the step times


@settings(max_examples=20, deadline=None)
@given(sigma=SIGMA, q=Q, p_d=P_D, clutter=CLUTTER, dt=DT, seed=st.integers(0, 2**16))
def test_abreast_config_is_its_generating_parameters(sigma, q, p_d, clutter, dt, seed):
    sc = abreast(
        seed,
        n_targets=3,
        n_scans=5,
        dt=dt,
        sigma=sigma,
        process_noise=q,
        p_d=p_d,
        clutter_per_scan=clutter,
    )
    _check_matched(sc, sc.tracker_config(), sigma=sigma, q=q, p_d=p_d, clutter_rate=clutter)


@settings(max_examples=20, deadline=None)
@given(
    sigma=SIGMA,
    q=Q,
    p_d=P_D,
    beta=st.floats(0.1, 3.0),
    p_g=st.floats(0.9, 0.999),
    seed=st.integers(0, 2**16),
)
def test_bojilov_config_is_its_generating_parameters(sigma, q, p_d, beta, p_g, seed):
    sc = bojilov(beta, seed, n_scans=5, sigma=sigma, process_noise=q, p_d=p_d, p_g=p_g)
    cfg = sc.tracker_config()
    # Bojilov's clutter: β returns per nominal gate area (the scene's info states the area)
    rate = beta / sc.info["gate_area"] * float(np.prod(sc.region[:, 1] - sc.region[:, 0]))
    _check_matched(sc, cfg, sigma=sigma, q=q, p_d=p_d, clutter_rate=rate, p_g=p_g)
    assert cfg.clutter_density == pytest.approx(beta / sc.info["gate_area"], rel=1e-12)


@settings(max_examples=10, deadline=None)
@given(sigma=SIGMA, q=Q, p_d=P_D, clutter=CLUTTER, seed=st.integers(0, 2**16))
def test_many_and_coalescence_configs_are_their_generating_parameters(sigma, q, p_d, clutter, seed):
    sc = many_targets(
        5, clutter, seed, n_scans=4, sigma=sigma, process_noise=q, p_d=p_d, p_survival=0.9
    )
    _check_matched(sc, sc.tracker_config(), sigma=sigma, q=q, p_d=p_d, clutter_rate=clutter)
    sc = coalescence(seed, n_steps=5, sigma=sigma, process_noise=q, p_d=p_d, clutter_rate=clutter)
    _check_matched(sc, sc.tracker_config(), sigma=sigma, q=q, p_d=p_d, clutter_rate=clutter)


def _run(sc, cfg):
    """First scan with a confirmed track, and per scan the distance from the worst-held
    target to its nearest confirmed track, in σ (∞ when there is no track)."""
    trk = JPDATracker(cfg)
    first, worst = None, []
    sigma = math.sqrt(sc.R[0, 0])
    for k, (t, z) in enumerate(zip(sc.times, sc.detections, strict=True)):
        res = trk.step(t, z)
        if first is None and len(res.ids):
            first = k
        est = np.asarray(res.x)[:, : sc.dim].reshape(-1, sc.dim)
        d = np.linalg.norm(sc.truth_positions[k][:, None, :] - est[None, :, :], axis=2)
        worst.append(float(d.min(axis=1).max()) / sigma if d.size else math.inf)
    return first, np.array(worst)


def _longest_gap(held) -> int:
    gap = longest = 0
    for h in held:
        gap = 0 if h else gap + 1
        longest = max(longest, gap)
    return longest


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_crossing_with_its_config_confirms_early_and_holds_both_targets(seed):
    sc = crossing(seed)
    first, worst = _run(sc, sc.tracker_config())
    # held: a confirmed track within 5σ, the GOSPA cut-off c `jointtrack run` scores with
    held = list(worst < 5)
    assert first is not None and first <= 5, first
    start = held.index(True)  # both targets held from here ...
    assert start <= 12, start
    assert _longest_gap(held[start:]) <= 2, held  # ... and neither lost for more than 2 scans
    assert np.all(worst[-20:] < 3), worst  # and within 3σ over the last third of the run


def test_the_matched_config_beats_the_readme_s_old_mismatched_one():
    """Issue 25: R = 25 with the default q = 1 on crossing (R = 100, q = 0.01)
    confirmed its first track at scan 22 of 61; the matched config at scan 3."""
    sc = crossing(seed=1)
    old, _ = _run(sc, TrackerConfig(clutter_density=1e-4, p_d=0.9, measurement_noise=25.0))
    new, worst = _run(sc, sc.tracker_config())
    assert new <= 5 < old
    assert np.sum(worst < 5) > len(worst) - 8


@pytest.mark.parametrize(
    "make",
    [lambda: abreast(0, n_scans=20), lambda: coalescence(1, n_steps=21)],
    ids=["abreast", "coalescence"],
)
def test_other_scenes_confirm_within_the_first_scans(make):
    sc = make()
    first, worst = _run(sc, sc.tracker_config())
    assert first is not None and first <= 5, first
    assert np.any(worst[:10] < 5), worst  # at a scan of the first 10, every target held


def test_overrides_replace_fields_and_keep_the_rest():
    sc = crossing(seed=1, n_scans=6)
    base = sc.tracker_config()
    cfg = sc.tracker_config(association="lbp", existence=False, p_d=0.8)
    assert (cfg.association, cfg.existence, cfg.p_d) == ("lbp", False, 0.8)
    for field in ("measurement_noise", "process_noise", "clutter_density", "max_speed", "p_g"):
        assert getattr(cfg, field) == getattr(base, field)


@pytest.mark.parametrize(
    ("overrides", "named"),
    [
        ({"measurment_noise": 1.0}, "measurment_noise"),  # a misspelt field
        ({"p_d": 1.5}, "p_d"),
        ({"p_d": True}, "p_d"),
        ({"process_noise": -1.0}, "process_noise"),
        ({"association": "magic"}, "association"),
        ({"dim": 3}, "dim"),
    ],
)
def test_bad_overrides_are_errors_naming_them(overrides, named):
    sc = crossing(seed=1, n_scans=6)
    with pytest.raises(ValueError, match=named):
        sc.tracker_config(**overrides)
