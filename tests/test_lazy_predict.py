"""Reports one at a time (``reporting = "async"``): the cost of predicting the tracks.

Each report is a scan, and every track is predicted from its own last update
(``JPDATracker._predict_from_update``). Nearly every track then has an interval of
its own; one ``predict`` call per distinct interval was 79 % of the CPU on the Solent
AIS file (issue 34, item 3). The prediction is one batched call for the tracks
whose interval no other track shares (plus one per interval shared by several), and
it is each track's own prediction from its update.
"""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

import jointtrack.trackers.jpda as jpda
from jointtrack.filters import predict
from jointtrack.trackers.config import TrackerConfig
from jointtrack.trackers.jpda import JPDATracker


def _tracker(n, motion="cv", q=0.005):
    cfg = TrackerConfig(
        motion=motion,
        process_noise=q,
        measurement_noise=225.0,
        reporting="async",
        report_interval=120.0,
        existence=True,
        p_survive=0.9999,
        p_survive_per="second",
        clutter_density=1e-11,
    )
    trk = JPDATracker(cfg)
    k = trk.state_dim
    x0 = np.zeros((n, k))
    x0[:, 0] = 1000.0 * np.arange(n)  # 1 km apart: one track per report
    P0 = np.broadcast_to(np.diag(np.r_[np.full(2, 225.0), np.full(k - 2, 1.0)]), (n, k, k))
    trk.start_tracks(x0, P0, existence=0.99, time=0.0)
    return trk


def _counting(monkeypatch):
    calls = []

    def counted(*args):
        calls.append(len(np.atleast_2d(args[0])))
        return predict(*args)

    monkeypatch.setattr(jpda, "predict", counted)
    return calls


def test_prediction_calls_do_not_grow_with_the_tracks(monkeypatch):
    """300 tracks, each last updated at a time of its own: one report predicts them in
    one batched call (the code before issue 34 made 300 calls)."""
    trk = _tracker(300)
    trk.updated_time = -np.linspace(0.5, 600.0, 300)  # 300 distinct intervals
    calls = _counting(monkeypatch)
    trk.step(1.0, np.array([[150_000.0, 150_000.0]]))  # far from every track
    assert len(calls) == 1 and calls[0] == 300
    assert len(trk.ids) >= 300


def test_shared_intervals_cost_one_call_each(monkeypatch):
    """Tracks updated at one time (a cluster's update, a burst of births) share their
    interval: one call per shared interval, one for all the others."""
    trk = _tracker(40)
    times = -np.linspace(0.5, 300.0, 40)
    times[:10] = -7.0  # ten tracks updated together
    times[10:13] = -11.0  # three more
    trk.updated_time = times
    calls = _counting(monkeypatch)
    trk._predict_from_update(1.0)
    assert sorted(calls) == [3, 10, 27]


_magnitude = st.sampled_from([0.0, 1e-300, 1e-9, 1e-3, 1.0, 1e3, 1e6, 1e9])


@settings(max_examples=30, deadline=None)
@given(
    motion=st.sampled_from(["cv", "ca"]),
    n=st.integers(1, 12),
    data=st.data(),
)
def test_each_track_is_its_own_prediction_from_its_update(motion, n, data):
    """``_predict_from_update(t)`` gives every track ``predict`` of its own last update
    over its own interval (0: the update itself), whatever intervals other tracks
    share: bit for bit for the tracks whose interval is their own or shared (both
    are the one ``predict``), checked against one call per track."""
    trk = _tracker(n, motion)
    k = trk.state_dim
    pool = data.draw(st.lists(st.sampled_from([0.0, 1e-6, 0.3, 7.0, 180.0, 3600.0]), min_size=1))
    gaps = np.array([data.draw(st.sampled_from(pool)) for _ in range(n)])
    scale = np.array([data.draw(_magnitude) for _ in range(k)])
    rng = np.random.default_rng(data.draw(st.integers(0, 2**32 - 1)))
    x = rng.normal(size=(n, k)) * scale
    A = rng.normal(size=(n, k, k))
    P = A @ np.swapaxes(A, 1, 2) + np.eye(k)
    t = 5000.0
    trk.updated_time = t - gaps
    gaps = t - trk.updated_time  # the intervals as the tracker forms them (rounded)
    trk.updated_x, trk.updated_P = x.copy(), P.copy()
    trk._predict_from_update(t)
    motion_model = trk._motion
    for i in range(n):
        if gaps[i] > 0:
            xi, Pi = predict(
                x[i : i + 1],
                P[i : i + 1],
                motion_model.transition(gaps[i]),
                motion_model.noise(gaps[i]),
            )
        else:
            xi, Pi = x[i : i + 1], P[i : i + 1]
        # the same numbers up to the order of a product's sum (a stack of per-track
        # F or one shared F: BLAS or not), an ulp or two of each entry or of P⁻'s
        # largest; below the normal range (2.2e-308) a product keeps fewer digits
        tiny = 1e-306
        np.testing.assert_allclose(
            trk.x[i], xi[0], rtol=1e-14, atol=max(1e-13 * np.abs(xi).max(), tiny)
        )
        np.testing.assert_allclose(trk.P[i], Pi[0], rtol=1e-14, atol=1e-14 * np.abs(Pi).max())
        assert np.isfinite(trk.x[i]).all() and np.isfinite(trk.P[i]).all()
