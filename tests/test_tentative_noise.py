"""Extra process noise on tentative tracks (issue 33): ``TrackerConfig.tentative_process_noise``.

A tentative track's velocity is a guess from a few returns, some of them clutter;
with it, every tentative track is predicted with white-noise acceleration of
intensity q_t on top of the motion model's, a confirmed track with the model's
alone. The reference is the Kalman prediction written out (F P Fᵀ + Q), not taken
from the tracker.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from jointtrack.trackers import JPDATracker, TrackerConfig
from state_checks import assert_steps_alike, load_state_without


def _cv(dt, q):
    """F and the continuous white-noise acceleration Q of a 2-D CV model, written out."""
    F = np.eye(4)
    F[0, 2] = F[1, 3] = dt
    Q = np.zeros((4, 4))
    for a in range(2):
        Q[a, a], Q[a, a + 2], Q[a + 2, a], Q[a + 2, a + 2] = dt**3 / 3, dt**2 / 2, dt**2 / 2, dt
    return F, q * Q


@settings(max_examples=25, deadline=None)
@given(
    q=st.sampled_from([1e-4, 1.0, 50.0]),
    q_t=st.one_of(st.just(0.0), st.floats(1e-300, 1e3)),
    dt=st.floats(1e-3, 100.0),
    v=st.floats(-50.0, 50.0),
)
def test_tentative_tracks_predict_with_the_extra_noise(q, q_t, dt, v):
    """With no return in the scan (β₀ = 1: the update leaves P as predicted), a
    tentative track's covariance is F P Fᵀ + Q(q) + Q(q_t), a confirmed one's F P Fᵀ + Q(q)."""
    trk = JPDATracker(
        TrackerConfig(
            process_noise=q,
            measurement_noise=4.0,
            clutter_density=1e-4,
            merge_threshold=0.0,  # two wide tracks are not merged
            tentative_process_noise=q_t,
        )
    )
    x0 = np.array([[0.0, 0.0, v, 1.0], [500.0, 0.0, -v, 2.0]])
    P0 = np.array([np.diag([9.0, 4.0, 1.0, 2.0]), np.diag([1.0, 1.0, 0.5, 0.5])])
    P0[0, 0, 2] = P0[0, 2, 0] = 1.5
    trk.start_tracks(x0[:1], P0[:1], confirmed=True, existence=0.99, time=0.0)
    trk.start_tracks(x0[1:], P0[1:], confirmed=False, existence=0.5, time=0.0)
    trk.step(dt, np.zeros((0, 2)))
    F, Q = _cv(dt, q)
    _, Q_t = _cv(dt, q_t)
    assert not trk.confirmed[1]
    want_confirmed = F @ P0[0] @ F.T + Q
    want_tentative = F @ P0[1] @ F.T + Q + Q_t
    np.testing.assert_allclose(trk.P[0], want_confirmed, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(trk.P[1], want_tentative, rtol=1e-12, atol=1e-12)
    assert np.isfinite(trk.P).all()


@pytest.mark.parametrize(
    "bad",
    [
        -1.0,
        -1e-300,
        float("nan"),
        float("inf"),
        True,
        1 + 0j,
        "0.1",
        None,
        pytest.param(10**400, id="huge-int"),
    ],
)
def test_bad_tentative_process_noise_is_named(bad):
    with pytest.raises(ValueError, match="tentative_process_noise"):
        TrackerConfig(tentative_process_noise=bad)


@pytest.mark.parametrize("other", [{"motion": "imm"}, {"reporting": "async"}])
def test_tentative_process_noise_refuses_imm_and_async(other):
    with pytest.raises(ValueError, match="tentative_process_noise.*(imm|async)"):
        TrackerConfig(
            tentative_process_noise=0.1,
            clutter_density=1e-4,
            p_survive_per="second",
            **other,
        )


def test_pmb_run_refuses_tentative_process_noise():
    from jointtrack.experiments.config import RunConfigError, check_kind_keys

    with pytest.raises(RunConfigError, match="tentative_process_noise"):
        check_kind_keys("pmb", {"tentative_process_noise": 0.25}, {}, "run.toml")


def _scans(seed, n):
    rng = np.random.default_rng(seed)
    out = []
    for k in range(n):
        truth = np.array([[2.0 * k, 0.0], [2.0 * k, 30.0]])
        z = np.vstack([truth + rng.normal(0, 3, truth.shape), rng.uniform(-50, 100, (6, 2))])
        out.append((float(k), z))
    return out


def test_saved_run_with_tentative_noise_continues_identically(tmp_path):
    scans = _scans(3, 14)
    cfg = dict(
        measurement_noise=9.0,
        clutter_density=6 / 150**2,
        max_speed=5.0,
        tentative_association="alternatives",
        tentative_process_noise=0.25,
    )
    a = JPDATracker(TrackerConfig(**cfg))
    for t, z in scans[:8]:
        a.step(t, z)
    b = JPDATracker.load(a.save(tmp_path / "mid.npz"))
    assert b.config.tentative_process_noise == 0.25
    assert_steps_alike(a, b, scans[8:])


def test_state_written_before_the_setting_loads_without_extra_noise(tmp_path):
    scans = _scans(4, 12)
    trk = JPDATracker(TrackerConfig(measurement_noise=9.0, clutter_density=6 / 150**2))
    for t, z in scans[:8]:
        trk.step(t, z)
    loaded = load_state_without(trk, "tentative_process_noise", tmp_path)
    assert loaded.config.tentative_process_noise == 0.0
    assert_steps_alike(loaded, trk, scans[8:])
