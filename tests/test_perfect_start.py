"""bench.perfect_start: from nothing, with one perfectly started track per target (issue 33)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from benchmark_scripts import load_benchmark
from jointtrack.bench import from_nothing as fn
from jointtrack.bench import perfect_start as ps
from jointtrack.experiments.config import steady_state_covariance
from jointtrack.scenarios import crossing
from jointtrack.trackers import JPDATracker


def _scene(n_scans=12, clutter=3.0):
    return crossing(seed=3, n_scans=n_scans, clutter_per_scan=clutter)


def test_without_a_start_it_is_the_tracker_from_nothing_bit_for_bit(tmp_path):
    """velocity_std None: run_scenario's own tracks (same settings, initiation and scans)."""
    sc = fn.make_scene("crossing", 1, {"n_scans": 15})
    got = ps.perfect_start_tracks(sc, None)
    want = fn.tracker_tracks("crossing", 1, "jipda", tmp_path, scenario_kwargs={"n_scans": 15})
    assert len(want[0]) > 0
    for a, b in zip(got, want, strict=True):
        np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("velocity_std", [0.5, 3.0, ps.STEADY, ps.ONE_POINT])
def test_one_tentative_track_per_target_at_its_true_state(monkeypatch, velocity_std):
    """Each target gets exactly one start, before its first scan's update, at its true state,
    tentative with existence r_init, with the covariance the argument names."""
    calls = []
    real = JPDATracker.start_tracks

    def spy(self, x0, P0, **kw):
        calls.append((int(self.n_scans), np.array(x0), np.array(P0), kw))
        return real(self, x0, P0, **kw)

    monkeypatch.setattr(JPDATracker, "start_tracks", spy)
    sc = _scene()
    cfg = ps.perfect_start_config(sc)
    ps.perfect_start_tracks(sc, velocity_std)
    firsts = {}
    for k, ids in enumerate(sc.truth_ids):
        for j, t in enumerate(np.asarray(ids).tolist()):
            firsts.setdefault(t, (k, sc.truth_states[k][j]))
    assert len(calls) == len(firsts) == 2
    d = sc.dim
    one_point = JPDATracker(cfg)._initial_states(np.zeros((1, d)))[1][0]
    for (scan, x0, P0, kw), (k, truth) in zip(calls, firsts.values(), strict=True):
        assert scan == k
        assert kw["confirmed"] is False and kw["existence"] == cfg.r_init
        np.testing.assert_array_equal(x0[0, : 2 * d], truth[: 2 * d])
        P = P0[0]
        if velocity_std == ps.STEADY:
            dt = float(sc.times[1] - sc.times[0])
            want = steady_state_covariance(dt, cfg.process_noise, cfg.measurement_noise, d)
            np.testing.assert_allclose(P[: 2 * d, : 2 * d], want, rtol=0, atol=0)
        elif velocity_std == ps.ONE_POINT:
            np.testing.assert_array_equal(P, one_point)
        else:
            np.testing.assert_array_equal(P[:d, :d], one_point[:d, :d])
            np.testing.assert_array_equal(P[d : 2 * d, d : 2 * d], np.eye(d) * velocity_std**2)
            assert not P[:d, d : 2 * d].any() and not P[d : 2 * d, :d].any()


def test_named_velocity_stds_are_the_one_point_starts_and_the_steady_state():
    sc = _scene()
    cfg = ps.perfect_start_config(sc)
    named = ps.named_velocity_stds(sc)
    assert named[ps.ONE_POINT] == pytest.approx(cfg.max_speed / 2, rel=1e-12)
    dt = float(sc.times[1] - sc.times[0])
    P = steady_state_covariance(dt, cfg.process_noise, cfg.measurement_noise, sc.dim)
    assert named[ps.STEADY] == pytest.approx(np.sqrt(P[sc.dim, sc.dim]), rel=1e-12)
    assert 0 < named[ps.STEADY] < named[ps.ONE_POINT]


@pytest.mark.parametrize(
    "value", [0, -1.0, float("nan"), float("inf"), True, 1j, 10**400, "fast", [1.0]]
)
def test_bad_velocity_std_is_refused_by_name(value):
    with pytest.raises(ValueError, match="velocity_std"):
        ps.perfect_start_tracks(_scene(n_scans=3), value)


def test_bad_tracker_and_scenes_without_truth_are_refused():
    sc = _scene(n_scans=3)
    with pytest.raises(ValueError, match="tracker must be a mapping"):
        ps.perfect_start_tracks(sc, 1.0, tracker=[("r_confirm", 0.9)])
    empty = dataclasses.replace(
        sc,
        truth_ids=tuple(np.zeros(0, np.int64) for _ in sc.times),
        truth_states=tuple(np.zeros((0, 4)) for _ in sc.times),
    )
    with pytest.raises(ValueError, match="has no truth"):
        ps.perfect_start_tracks(empty, 1.0)


def test_the_command_refuses_bad_arguments(capsys):
    bench = load_benchmark("start_velocity")
    for argv, msg in [
        (["--velocities", "0"], "not a number > 0"),
        (["--velocities", "fast"], "not a number > 0"),
        (["--scenes", "many"], "unknown"),
        (["--config", "[1]"], "JSON object"),
        (["--seeds", "-1"], "seeds"),
    ]:
        with pytest.raises(SystemExit) as exc:
            bench.main(argv)
        assert exc.value.code == 2
        assert msg in capsys.readouterr().err
