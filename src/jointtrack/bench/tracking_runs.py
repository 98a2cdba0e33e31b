"""Running trackers on a simulated scene for the quality benchmark.

jointtrack's tracker settings come from the scene's physics only
(:func:`physical_config`); :class:`TrackRun` holds the confirmed tracks any
tracker reported as flat tables (see :mod:`jointtrack.bench.quality`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from jointtrack.scenarios import nominal_gate
from jointtrack.trackers import JPDATracker, TrackerConfig

MIN_TRACKER_Q = 0.01
P_G = 0.99


def tracker_q(sc) -> float:
    """The tracker's process noise for a scene: max(truth q, ``MIN_TRACKER_Q``)."""
    return max(float(sc.process_noise), MIN_TRACKER_Q)


def max_true_speed(sc) -> float:
    """The fastest true speed over the whole scene."""
    speeds = [float(np.hypot(*s[:, 2:4].T).max()) for s in sc.truth_states if len(s)]
    return max(speeds) if speeds else 0.0


def physical_config(sc, **overrides) -> TrackerConfig:
    """jointtrack's settings from the scene's physics only (module docstring), plus overrides.

    measurement_noise = σ² (R = σ² I), p_d = P_D, clutter_density = λ,
    process_noise = max(truth q, 0.01), max_speed = 1.5 × fastest true speed,
    p_g = 0.99; every other field is ``TrackerConfig``'s default.
    """
    settings = dict(
        measurement_noise=float(sc.R[0, 0]),
        p_d=float(sc.p_d),
        clutter_density=float(sc.clutter_density),
        process_noise=tracker_q(sc),
        max_speed=1.5 * max_true_speed(sc) or 1.0,
        p_g=P_G,
    )
    settings.update(overrides)
    return TrackerConfig(**settings)


def tracker_gate_area(sc) -> float:
    """V_G: the steady-state 99 % gate area of an NCV filter with the tracker's q and σ."""
    sigma = float(np.sqrt(sc.R[0, 0]))
    return float(nominal_gate(sc.dt, tracker_q(sc), sigma, P_G, sc.dim)["volume"])


def clutter_per_gate(sc) -> float:
    """λ·V_G: false returns per steady-state 99 % gate of the tracker's q and σ."""
    return float(sc.clutter_density * tracker_gate_area(sc))


def first_detections(sc) -> dict:
    """{target id: time of its first detection}, from the detections' origins."""
    first: dict = {}
    for t, o in zip(sc.times, sc.origins, strict=True):
        for tid in np.unique(o[o >= 0]).tolist():
            first.setdefault(int(tid), float(t))
    return first


@dataclass(frozen=True)
class TrackRun:
    """Confirmed tracks a tracker reported, as flat tables, and its step time.

    ``n_scans`` scans were run (the first ``n_scans`` of the scene; fewer than
    the scene's when a time budget stopped it, ``completed`` False).
    """

    times: np.ndarray
    ids: np.ndarray
    positions: np.ndarray
    seconds: float
    n_scans: int
    completed: bool = True

    @property
    def scans_per_second(self) -> float:
        return self.n_scans / self.seconds if self.seconds > 0 else float("nan")


def rows_to_run(rows, seconds, n_scans, completed=True) -> TrackRun:
    a = np.array(rows, dtype=np.float64).reshape(-1, 4)
    return TrackRun(a[:, 0], a[:, 1].astype(np.int64), a[:, 2:4], seconds, n_scans, completed)


def run_jointtrack(sc, cfg: TrackerConfig) -> TrackRun:
    """Run ``JPDATracker(cfg)`` over the scene from nothing; time ``step`` only."""
    trk = JPDATracker(cfg)
    rows = []
    seconds = 0.0
    for t, z in zip(sc.times, sc.detections, strict=True):
        t0 = time.perf_counter()
        r = trk.step(t, z)
        seconds += time.perf_counter() - t0
        rows += [(t, i, x[0], x[1]) for i, x in zip(r.ids.tolist(), r.x, strict=True)]
    return rows_to_run(rows, seconds, sc.n_scans)


def poisson_config(sc, **pmbm):
    """The PMB/PMBM settings of a scene: :func:`physical_config`'s shared settings and the
    birth model ``jointtrack run --tracker pmbm`` derives for it
    (:func:`jointtrack.experiments.config.make_pmbm_config`: the scene's Gaussian birth
    and prior for coalescence, else uniform births over its region), plus ``pmbm``
    overrides (PMBMConfig fields)."""
    from jointtrack.experiments.config import make_pmbm_config

    cfg, _ = make_pmbm_config(physical_config(sc), {}, pmbm, scenario=sc, region=sc.region)
    return cfg


def run_poisson(sc, kind: str, cfg=None, budget: float | None = None) -> TrackRun:
    """Run the PMB (``kind="pmb"``) or PMBM (``"pmbm"``) tracker over the scene from
    nothing; time ``step`` only. With ``budget`` seconds the run stops at the budget
    (the interrupted step leaves the tracker as it was) and reports the scans completed."""
    from jointtrack.bench.stonesoup_tracker import _OutOfTime, _time_limit
    from jointtrack.trackers.pmbm import PMBMTracker, PMBTracker

    trk = {"pmb": PMBTracker, "pmbm": PMBMTracker}[kind](cfg or poisson_config(sc))
    rows: list = []
    seconds = 0.0
    done = 0
    t0 = time.perf_counter()
    try:
        with _time_limit(budget):
            for k, (t, z) in enumerate(zip(sc.times, sc.detections, strict=True)):
                t0 = time.perf_counter()
                r = trk.step(t, z)
                seconds += time.perf_counter() - t0
                rows += [(t, i, x[0], x[1]) for i, x in zip(r.ids.tolist(), r.x, strict=True)]
                done = k + 1
    except _OutOfTime:
        seconds += time.perf_counter() - t0
    rows = [r for r in rows if r[0] <= sc.times[done - 1]] if done else []
    return rows_to_run(rows, seconds, done, done == sc.n_scans)
