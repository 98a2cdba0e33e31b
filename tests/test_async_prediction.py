"""Reporting targets (``reporting = "async"``): a track is predicted from its last update.

Between a track's own reports the tracker steps at every other target's report; the
track's prediction must not depend on how many such scans cut the interval (for the
IMM: one mixing over the whole interval, not one per scan). The state file holds each
track's last update; older states load.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from jointtrack.trackers.config import TrackerConfig
from jointtrack.trackers.jpda import JPDATracker
from jointtrack.trackers.state_io import StateFileError, read_state, write_state

_X0 = np.array([[10.0, -20.0, 3.0, 1.5]])
_P0 = np.diag([25.0, 16.0, 4.0, 9.0])


def _config(motion):
    imm = {}
    if motion == "imm":
        imm = {
            "imm_modes": ("cv", "stationary"),
            "imm_process_noise": (0.2, 2e-4),
            "imm_switching": [[0.999, 0.001], [0.002, 0.998]],
            "imm_switching_per": "second",
            "imm_initial": (0.6, 0.4),
        }
    return TrackerConfig(
        motion=motion,
        **imm,
        measurement_noise=2.0,
        max_speed=20.0,
        reporting="async",
        report_interval=10.0,
        existence=True,
        p_survive=1.0,
        p_survive_per="second",
        clutter_density=1e-9,
    )


def _tracker(motion):
    trk = JPDATracker(_config(motion))
    trk.start_tracks(_X0, _P0, existence=0.99, time=0.0)
    return trk


def _state(trk):
    return trk.x[0], trk.P[0], trk.mode_x[0], trk.mode_P[0], trk.mode_log_prob[0]


def _assert_close(a, b):
    for u, v in zip(a, b, strict=True):
        scale = max(1.0, np.abs(v).max(initial=0.0))
        np.testing.assert_allclose(u, v, rtol=1e-12, atol=1e-12 * scale)


_steps = st.lists(st.floats(0.01, 60.0), min_size=2, max_size=12)


@pytest.mark.parametrize("motion", ["cv", "imm"])
@settings(max_examples=25, deadline=None)
@given(steps=_steps)
def test_n_steps_without_update_equal_one_prediction_over_their_sum(motion, steps):
    many, one = _tracker(motion), _tracker(motion)
    t = 0.0
    for s in steps:  # scans with no report (another target's report that is not here)
        t += s
        many.step(t, np.zeros((0, 2)))
    one.step(t, np.zeros((0, 2)))
    _assert_close(_state(many), _state(one))


@pytest.mark.parametrize("motion", ["cv", "imm"])
def test_other_targets_reports_do_not_change_a_silent_tracks_prediction(motion):
    # the other target, 50 km away, reports every 7 s: its scans must not re-predict
    # the silent track (its state equals one prediction over the whole interval)
    busy, quiet = _tracker(motion), _tracker(motion)
    for k in range(1, 26):
        busy.step(7.0 * k, np.array([[50000.0 + 3.0 * k, 0.0]]))
    quiet.step(7.0 * 25, np.zeros((0, 2)))
    row = int(np.flatnonzero(busy.ids == quiet.ids[0])[0])
    _assert_close(
        (busy.x[row], busy.P[row], busy.mode_x[row], busy.mode_P[row], busy.mode_log_prob[row]),
        _state(quiet),
    )


def test_imm_scan_by_scan_would_differ():
    # the property above is not automatic: mixing at every scan gives another answer
    from jointtrack.filters.imm import imm_predict

    trk = _tracker("imm")
    x, P, lp = trk.mode_x, trk.mode_P, trk.mode_log_prob
    for _ in range(10):
        x, P, lp = imm_predict(x, P, lp, trk._imm, 18.0)
    one = imm_predict(trk.mode_x, trk.mode_P, trk.mode_log_prob, trk._imm, 180.0)
    assert not np.allclose(P, one[1], rtol=1e-6)


def test_an_update_restarts_the_prediction_from_it():
    trk = _tracker("imm")
    trk.step(30.0, np.array([[100.0, 25.0]]))  # the track's own report (in its gate)
    assert trk.updated_time[0] == 30.0
    np.testing.assert_array_equal(trk.updated_mode_P[0], trk.mode_P[0])
    trk.step(50.0, np.zeros((0, 2)))
    assert trk.updated_time[0] == 30.0  # no report: still predicted from 30 s


@pytest.mark.parametrize("motion", ["cv", "imm"])
def test_state_saved_between_reports_continues_identically(motion, tmp_path):
    trk = _tracker(motion)
    for k in range(1, 6):
        trk.step(7.0 * k, np.array([[50000.0 + 3.0 * k, 0.0]]))
    loaded = JPDATracker.load(trk.save(tmp_path / "s.npz"))
    np.testing.assert_array_equal(loaded.updated_time, trk.updated_time)
    for t in (60.0, 75.5):
        a, b = trk.step(t, np.zeros((0, 2))), loaded.step(t, np.zeros((0, 2)))
        np.testing.assert_array_equal(a.x, b.x)
        np.testing.assert_array_equal(a.P, b.P)


def test_older_state_without_last_updates_loads(tmp_path):
    trk = _tracker("imm")
    trk.step(7.0, np.array([[50000.0, 0.0]]))
    arrays, config, scalars, rng = read_state(trk.save(tmp_path / "new.npz"))
    for name in list(arrays):
        if name.startswith("updated_"):
            arrays.pop(name)
    write_state(tmp_path / "old.npz", arrays, config, scalars, rng)
    loaded = JPDATracker.load(tmp_path / "old.npz")
    # the saved state at the saved time: what the earlier run predicted from
    np.testing.assert_array_equal(loaded.updated_time, np.full(len(loaded.ids), 7.0))
    np.testing.assert_array_equal(loaded.updated_mode_P, trk.mode_P)
    loaded.step(20.0, np.zeros((0, 2)))


@pytest.mark.parametrize(
    "name, change, match",
    [
        ("updated_time", lambda a: a[:-1], "field 'updated_time' has shape"),
        ("updated_time", lambda a: a + 1e3, "'updated_time' holds a time after"),
        ("updated_time", lambda a: a * np.nan, "'updated_time' has non-finite"),
        ("updated_x", lambda a: a.astype(np.int64), "'updated_x' has dtype"),
        ("updated_P", lambda a: -a, "'updated_P' holds a covariance that"),
        ("updated_mode_log_prob", lambda a: a - 1.0, "'updated_mode_log_prob'"),
        ("updated_mode_P", lambda a: a[:, :1], "'updated_mode_P' has dtype"),
    ],
)
def test_damaged_last_updates_are_refused_naming_the_field(tmp_path, name, change, match):
    trk = _tracker("imm")
    trk.step(7.0, np.array([[50000.0, 0.0]]))
    arrays, config, scalars, rng = read_state(trk.save(tmp_path / "new.npz"))
    arrays[name] = change(arrays[name])
    write_state(tmp_path / "bad.npz", arrays, config, scalars, rng)
    with pytest.raises(StateFileError, match=match):
        JPDATracker.load(tmp_path / "bad.npz")
