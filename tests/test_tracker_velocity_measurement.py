"""Issue 24: reported velocities measured as well as positions (measure_velocity)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from jointtrack.experiments.realdata import LABELLED, REALDATA_TRACKER, realdata_settings
from jointtrack.models import ConstantVelocity, LinearPosition, LinearPositionVelocity
from jointtrack.trackers.config import TrackerConfig
from jointtrack.trackers.jpda import JPDATracker

finite = st.floats(-1e4, 1e4, allow_nan=False)


def _config(**kw):
    base = dict(
        reporting="async",
        clutter_density=1e-14,
        p_survive=0.9999,
        p_survive_per="second",
        measurement_noise=225.0,
        process_noise=0.01,
        velocity_std=0.3,
    )
    return TrackerConfig(**{**base, **kw})


def test_model_blocks():
    m = LinearPositionVelocity(LinearPosition(2, [[225.0, 10.0], [10.0, 100.0]]), 0.09)
    assert m.measurement_dim == 4 and m.H.shape == (4, 4)
    np.testing.assert_array_equal(m.H, np.eye(4))
    np.testing.assert_array_equal(m.R[:2, :2], [[225.0, 10.0], [10.0, 100.0]])
    np.testing.assert_array_equal(m.R[2:, 2:], 0.09 * np.eye(2))
    assert not m.R[:2, 2:].any()
    pos, cov = m.position_and_covariance([[1.0, 2.0, 3.0, 4.0]])
    np.testing.assert_array_equal(pos, [[1.0, 2.0]])
    np.testing.assert_array_equal(cov[0], m.R[:2, :2])


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan"), float("inf"), True, "1"])
def test_model_refuses_bad_variance(bad):
    with pytest.raises((ValueError, TypeError), match="velocity_variance"):
        LinearPositionVelocity(LinearPosition(2, 1.0), bad)


def test_model_needs_a_position_model():
    with pytest.raises(TypeError, match="position must be a LinearPosition"):
        LinearPositionVelocity(np.eye(2), 1.0)


def test_config_needs_the_position_sensor():
    with pytest.raises(ValueError, match="measure_velocity needs the position sensor"):
        TrackerConfig(measure_velocity=True, sensor="range-bearing")
    with pytest.raises(ValueError, match="measure_velocity"):
        TrackerConfig(measure_velocity=1)


@settings(max_examples=40, deadline=None)
@given(finite, finite, st.floats(-20, 20), st.floats(-20, 20), st.floats(1.0, 600.0))
def test_labelled_update_is_the_kalman_update_of_position_and_velocity(px, py, vx, vy, dt):
    """A labelled report (β = 1) with a velocity updates its track exactly as the
    Kalman filter with H = I₄ and R = diag(R_p, σ_v² I) would (to 1e-9 relative)."""
    cfg = _config(measure_velocity=True)
    trk = JPDATracker(cfg)
    trk.step(0.0, [[0.0, 0.0]], labels=["A"], velocities=[[1.0, 0.0]])
    x0, P0 = trk.x[0].copy(), trk.P[0].copy()
    z = np.array([px, py, vx, vy])
    trk.step(dt, z[None, :2], labels=["A"], velocities=z[None, 2:])
    cv = ConstantVelocity(2, cfg.process_noise)
    F, Q = cv.transition(dt), cv.noise(dt)
    xp, Pp = F @ x0, F @ P0 @ F.T + Q
    R = np.diag([225.0, 225.0, 0.09, 0.09])
    S = Pp + R
    K = Pp @ np.linalg.inv(S)
    x_exp = xp + K @ (z - xp)
    if (z - xp) @ np.linalg.solve(S, z - xp) > 13.28:  # χ²₄(0.99): a jump, restarted
        return
    P_exp = (np.eye(4) - K) @ Pp
    np.testing.assert_allclose(trk.x[0], x_exp, rtol=1e-9, atol=1e-9 * (1 + abs(z).max()))
    np.testing.assert_allclose(trk.P[0], P_exp, rtol=1e-7, atol=1e-9)


def test_reported_velocities_are_measured():
    """A vessel under way at 2 m/s east reports twice, 10 s apart: with the
    velocities measured its track's velocity spread is that of two measurements of
    σ_v = 0.3, ≈ 0.3/√2; with the velocity only seeding the track (and positions
    15 m apart in σ, 10 s apart, adding little) it stays ≈ 0.3."""
    sd, est = {}, {}
    for measure in (False, True):
        trk = JPDATracker(_config(measure_velocity=measure, process_noise=0.0005))
        rng = np.random.default_rng(1)
        for t in (0.0, 10.0):
            z = np.array([[2.0 * t, 0.0]]) + rng.normal(0.0, 15.0, (1, 2))
            trk.step(float(t), z, velocities=[[2.0, 0.0]] + rng.normal(0.0, 0.3, (1, 2)))
        assert len(trk.ids) == 1
        sd[measure], est[measure] = float(np.sqrt(trk.P[0, 2, 2])), float(trk.x[0, 2])
    assert abs(sd[True] - 0.3 / np.sqrt(2)) < 0.01 and abs(est[True] - 2.0) < 1.0
    assert abs(sd[False] - 0.3) < 0.02


def test_scans_with_a_missing_velocity_measure_positions_only():
    trk = JPDATracker(_config(measure_velocity=True))
    r = trk.step(0.0, [[0.0, 0.0], [5000.0, 0.0]], velocities=[[0.0, 0.0], [np.nan, np.nan]])
    assert r.n_measurements == 2
    np.testing.assert_array_equal(trk.x[:, 2:], 0.0)  # the known one seeded 0, the other 0 mean


def test_realdata_presets():
    assert REALDATA_TRACKER["ais"]["measure_velocity"] is True
    assert realdata_settings("ais", labelled=True)["measure_velocity"] is False
    assert realdata_settings("ais", labelled=True)["clutter_density"] == LABELLED["clutter_density"]
    assert realdata_settings("ais", labelled=False) == REALDATA_TRACKER["ais"]
    for fam in ("ais", "adsb"):
        for labelled in (False, True):
            TrackerConfig(**realdata_settings(fam, labelled=labelled))
