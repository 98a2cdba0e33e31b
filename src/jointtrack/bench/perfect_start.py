"""A perfect start: the tracker from nothing given each target's true state at its first scan.

Issue 33 measures a tracker from nothing against the *start-up floor*
(:mod:`jointtrack.bench.from_nothing`): the truth-started JIPDA run, each
target's track shown only from the scan at which an oracle-started lone IPDA
confirms it. That floor's tracks are started at the true state with the
steady-state covariance of a long-followed track — they know every target's
velocity to a fraction of a metre per second from the first scan, and they are
confirmed (existence 0.99) while hidden. A tracker from nothing knows neither.

This module separates the two on the scene itself. :func:`perfect_start_tracks`
runs the JIPDA tracker exactly as ``run_scenario(name, start_from="nothing",
tracker="jipda")`` builds it (same settings, same initiation on every return)
and, before the first scan, adds **one tentative track per target** (existence
``r_init``, confirmed by the tracker's own rule like any other) at the target's
true position and velocity, with

* ``velocity_std = s`` (m/s): the one-point initiation's position covariance
  (the measurement noise R) and a per-axis velocity standard deviation ``s``
  around the *true* velocity — a start no tracker from nothing can beat at that
  velocity uncertainty (the one-point start's own is ``max_speed / 2``);
* ``velocity_std = "one-point"``: the one-point initiation's covariance itself
  (velocity σ = ``max_speed / 2`` per axis), at the true state: the start a
  tracker from nothing would give a track born on the target's first return,
  had it known which return that is and the velocity's mean;
* ``velocity_std = "steady"``: the floor's covariance (the steady-state
  covariance of the tracker's q and R), i.e. the floor's tracks, tentative;
* ``velocity_std = None``: no added track — the tracker from nothing itself
  (checked to give ``run_scenario``'s tracks bit for bit).

Sweeping ``s`` (``benchmarks/start_velocity.py``) shows how much of the gap
between a tracker from nothing and the floor is the start (which returns are a
target's) and how much is velocity knowledge that only the floor has.

API: :func:`perfect_start_tracks` (tracks of one scene), :func:`perfect_start_config`
(the tracker settings it runs).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from jointtrack.bench.from_nothing import Tracks, check_scene

__all__ = [
    "ONE_POINT",
    "STEADY",
    "named_velocity_stds",
    "perfect_start_config",
    "perfect_start_tracks",
]

#: ``velocity_std`` for the floor's (steady-state) covariance
STEADY = "steady"
#: ``velocity_std`` for the one-point initiation's covariance
ONE_POINT = "one-point"


def perfect_start_config(scenario, tracker: Mapping | None = None):
    """The TrackerConfig ``run_scenario(scenario.name, start_from="nothing",
    tracker="jipda", config=tracker)`` runs on ``scenario``."""
    from jointtrack.experiments.config import make_tracker_config, scenario_tracker_settings
    from jointtrack.experiments.run import start_settings

    if tracker is not None and not isinstance(tracker, Mapping):
        raise ValueError(f"tracker must be a mapping of [tracker] settings, got {tracker!r}")
    _start, over = start_settings("nothing", scenario.name, "jipda", dict(tracker or {}))
    return make_tracker_config(scenario_tracker_settings(scenario), over)


def _steady_covariance(scenario, cfg) -> np.ndarray:
    """The floor's covariance: the steady state of ``cfg``'s q and R at the scene's interval."""
    from jointtrack.experiments.config import steady_state_covariance

    dt = float(np.median(np.diff(scenario.times))) if scenario.n_scans > 1 else 1.0
    return steady_state_covariance(dt, cfg.process_noise, cfg.measurement_noise, scenario.dim)


def named_velocity_stds(scenario, tracker: Mapping | None = None) -> dict:
    """``{STEADY: σ_v, ONE_POINT: σ_v}``: the per-axis velocity standard deviation (first
    axis) the named starts have on ``scenario`` with the ``tracker`` overrides."""
    from jointtrack.trackers import JPDATracker

    check_scene(scenario)
    cfg = perfect_start_config(scenario, tracker)
    d = scenario.dim
    one_point = JPDATracker(cfg)._initial_states(np.zeros((1, d)))[1][0]
    steady = _steady_covariance(scenario, cfg)
    return {STEADY: float(np.sqrt(steady[d, d])), ONE_POINT: float(np.sqrt(one_point[d, d]))}


def _velocity_std(value):
    """``value`` as None, :data:`STEADY`, :data:`ONE_POINT` or a positive finite float;
    else ValueError."""
    from jointtrack.assignment._checks import as_float

    if value is None or (isinstance(value, str) and value in (STEADY, ONE_POINT)):
        return value
    if isinstance(value, str):
        raise ValueError(
            f'velocity_std must be a number > 0, "{STEADY}", "{ONE_POINT}" or None, got {value!r}'
        )
    return as_float(value, "velocity_std", minimum=0.0, open_min=True)


def perfect_start_tracks(scenario, velocity_std, *, tracker: Mapping | None = None) -> Tracks:
    """The confirmed tracks of the JIPDA tracker from nothing with a perfect start.

    Parameters
    ----------
    scenario : a :class:`~jointtrack.scenarios.Scenario` with truth.
    velocity_std : per-axis velocity standard deviation (m/s, > 0) of the
        tracks started at the true states, :data:`ONE_POINT` for the one-point
        initiation's covariance, :data:`STEADY` for the floor's steady-state
        covariance, or None for no started track (module docstring).
    tracker : ``[tracker]`` overrides, as ``run_scenario``'s ``config``.

    Returns
    -------
    (times, ids, positions) of every reported track and scan, as
    :func:`jointtrack.bench.from_nothing.score_tracks` takes them.
    """
    from jointtrack.trackers import JPDATracker

    check_scene(scenario)
    velocity_std = _velocity_std(velocity_std)
    cfg = perfect_start_config(scenario, tracker)
    steady = _steady_covariance(scenario, cfg)
    trk = JPDATracker(cfg)
    trk.keep_history = False
    d = scenario.dim
    started: set[int] = set()
    times, ids, pos = [], [], []
    for k in range(scenario.n_scans):
        if velocity_std is not None:
            for j, target in enumerate(np.asarray(scenario.truth_ids[k]).tolist()):
                if target in started:
                    continue
                started.add(target)
                truth = np.asarray(scenario.truth_states[k][j], dtype=float)
                # the one-point initiation's layout and position covariance on a
                # return at the true position, then the true velocity
                x0, P0 = trk._initial_states(truth[None, :d])
                x0[0, : 2 * d] = truth[: 2 * d]
                if velocity_std == STEADY:
                    P0[0, : 2 * d, : 2 * d] = steady
                elif velocity_std != ONE_POINT:
                    P0[0, d : 2 * d, :] = 0.0
                    P0[0, :, d : 2 * d] = 0.0
                    P0[0, d : 2 * d, d : 2 * d] = np.eye(d) * velocity_std**2
                # at the tracker's clock (None before the first scan): a target born
                # later is placed at its state of the scan it is born in
                trk.start_tracks(x0, P0, confirmed=False, existence=cfg.r_init, time=trk.time)
        res = trk.step(float(scenario.times[k]), scenario.detections[k])
        times.append(np.full(len(res.ids), float(scenario.times[k])))
        ids.append(np.asarray(res.ids))
        pos.append(np.asarray(res.x)[:, :d])
    return np.concatenate(times), np.concatenate(ids), np.concatenate(pos).reshape(-1, d)
