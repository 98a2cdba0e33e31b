"""Aircraft flying in close pairs that orbit together, seen by a 10 s scanning sensor (issue 32).

Each pair is two aircraft a fixed ``separation`` apart (0.1–2 km in the
issue), abreast at the start: they fly straight and level, then orbit together
— both at the same speed and the same turn rate, so the second aircraft's path
is the first one's translated by the initial offset and the distance between
them is ``separation`` at every instant (abreast on the straight leg, in trail a
quarter orbit later) — and then straight again. Pairs are far apart from each
other (``pair_spacing``), so every multi-target cluster of a tracker is one
pair (plus clutter). Made for the question "do two aircraft orbiting together
keep their track ids?": with 50 m noise and 100 m separation the returns of
the two are within two standard deviations of each other at every scan.

Set-up (defaults)
-----------------
* Scan interval 10 s; ``straight_scans`` intervals straight, ``orbit_scans``
  orbiting, ``straight_scans`` straight again: 30 + 36 + 30 intervals, 97 scan
  times from t = 0 (36 scans at 4°/s = 1440°, four full orbits).
* Per pair (drawn from the seed): speed uniform in [150, 250] m/s, turn rate
  magnitude uniform in [3, 5] °/s with a random sign, initial heading uniform.
  The turn is a coordinated turn of constant rate ω: position
  ``p(t) = c + (v/ω)(sin(h₀ + ωt), −cos(h₀ + ωt))`` about the orbit centre c.
* P_D 0.9 per target, σ = 50 m per axis (R = 2500 I m²), Poisson clutter of
  mean ``clutter_per_scan`` (20) uniform over the trajectories' bounding box
  plus ``margin`` (the sensor's region).
* Target ids: pair k holds targets 2k and 2k + 1.

``info`` holds the separation, each pair's speed, turn rate (rad/s, signed)
and target ids, and the scan index ranges of the orbit.
"""

from __future__ import annotations

import math

import numpy as np

from jointtrack.scenarios.simulate import (
    Scenario,
    _count,
    _pos_float,
    _prob,
    _rng,
    simulate_scenario,
)

__all__ = ["close_pairs"]

#: speed range of the aircraft (m/s) and turn-rate magnitude range (°/s) of the orbits
SPEED_RANGE = (150.0, 250.0)
TURN_RATE_RANGE_DEG = (3.0, 5.0)


def _path(t, t_turn_start, t_turn_end, speed, heading, omega):
    """Positions and velocities (len(t), 4) of one aircraft: straight, turn, straight.

    Starts at the origin with heading ``heading``; turns at the constant rate
    ``omega`` (rad/s) for t in [t_turn_start, t_turn_end]; flies straight on
    its final heading after that. Closed forms, so the truth is exact.
    """
    t = np.asarray(t, float)
    u = np.clip(t - t_turn_start, 0.0, t_turn_end - t_turn_start)  # time spent turning
    before = np.minimum(t, t_turn_start)
    after = np.maximum(t - t_turn_end, 0.0)
    h0 = heading
    h1 = heading + omega * u
    r = speed / omega
    d0 = np.array([math.cos(h0), math.sin(h0)])
    p = speed * before[:, None] * d0
    p = p + r * np.stack([np.sin(h1) - math.sin(h0), math.cos(h0) - np.cos(h1)], -1)
    d1 = np.stack([np.cos(h1), np.sin(h1)], -1)
    p = p + speed * after[:, None] * d1
    return np.concatenate([p, speed * d1], axis=1)


def close_pairs(
    seed=None,
    *,
    separation: float = 500.0,
    n_pairs: int = 4,
    straight_scans: int = 30,
    orbit_scans: int = 36,
    dt: float = 10.0,
    p_d: float = 0.9,
    sigma: float = 50.0,
    clutter_per_scan: float = 20.0,
    pair_spacing: float = 40_000.0,
    margin: float = 5_000.0,
) -> Scenario:
    """Pairs of aircraft ``separation`` metres apart, flying straight, orbiting, then straight.

    Parameters
    ----------
    seed : int, numpy Generator or None
        Draws the pairs' speeds, turn rates and headings, then the detections.
    separation : float
        Distance between the two aircraft of a pair (m), > 0; constant all run.
    n_pairs : int
        Number of pairs (≥ 1), laid out on a line ``pair_spacing`` apart.
    straight_scans, orbit_scans : int
        Scans of straight flight before (and after) the orbit, and of orbit.
    dt : float
        Scan interval (s).
    p_d, sigma, clutter_per_scan
        Detection probability, measurement noise s.d. per axis (m), mean
        clutter returns per scan over the region.
    pair_spacing, margin : float
        Distance between the pairs' start points (m) and the region's margin
        around the trajectories (m).

    Returns
    -------
    Scenario
        ``name = "close_pairs"``, NCV-layout truth ``[x, y, vx, vy]``; ``info``
        as in the module docstring.

    Raises
    ------
    ValueError
        a parameter of the wrong type or out of range, naming it.
    """
    rng = _rng(seed)
    separation = _pos_float(separation, "separation")
    n_pairs = _count(n_pairs, "n_pairs")
    straight_scans = _count(straight_scans, "straight_scans", 0)
    orbit_scans = _count(orbit_scans, "orbit_scans")
    dt = _pos_float(dt, "dt")
    sigma = _pos_float(sigma, "sigma")
    pair_spacing = _pos_float(pair_spacing, "pair_spacing")
    margin = _pos_float(margin, "margin", allow_zero=True)
    p_d = _prob(p_d, "p_d")
    clutter = _pos_float(clutter_per_scan, "clutter_per_scan", allow_zero=True)
    n_scans = 2 * straight_scans + orbit_scans + 1
    times = dt * np.arange(n_scans)
    t_on, t_off = straight_scans * dt, (straight_scans + orbit_scans) * dt
    speeds = rng.uniform(*SPEED_RANGE, n_pairs)
    rates = np.deg2rad(rng.uniform(*TURN_RATE_RANGE_DEG, n_pairs)) * rng.choice([-1, 1], n_pairs)
    headings = rng.uniform(0.0, 2 * math.pi, n_pairs)
    states = np.zeros((n_scans, 2 * n_pairs, 4))
    for k in range(n_pairs):
        lead = _path(times, t_on, t_off, speeds[k], headings[k], rates[k])
        lead[:, 0] += k * pair_spacing
        # abreast at the start: the offset is perpendicular to the initial heading
        offset = separation * np.array([-math.sin(headings[k]), math.cos(headings[k])])
        wing = lead.copy()
        wing[:, :2] += offset
        states[:, 2 * k], states[:, 2 * k + 1] = lead, wing
    pos = states[..., :2].reshape(-1, 2)
    region = np.stack([pos.min(axis=0) - margin, pos.max(axis=0) + margin], axis=1)
    ids = np.arange(2 * n_pairs, dtype=np.int64)
    return simulate_scenario(
        "close_pairs",
        times,
        [ids] * n_scans,
        list(states),
        region=region,
        p_d=p_d,
        clutter_rate=clutter,
        R=sigma**2 * np.eye(2),
        process_noise=0.0,
        rng=rng,
        info={
            "separation": separation,
            "speeds": speeds.tolist(),
            "turn_rates": rates.tolist(),
            "pairs": [[2 * k, 2 * k + 1] for k in range(n_pairs)],
            "orbit_scans": [straight_scans, straight_scans + orbit_scans],
            "sigma": sigma,
        },
        seed=seed,
        dt=dt,
    )
