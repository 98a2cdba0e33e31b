"""From nothing against the start-up floor: oracle IPDA confirmation, the floor, phases, scores.

Issue 33's benchmark (``benchmarks/from_nothing.py`` is its command line). A
tracker that starts with no tracks cannot report a target before the evidence
for it is in; how fast the evidence comes in is measured here by an *oracle*,
and the best a tracker could do from nothing by the *start-up floor*:

**Oracle IPDA confirmation** (:func:`oracle_confirmation`). For each target, one
single-target IPDA — :class:`~jointtrack.trackers.JPDATracker` with existence
and the settings ``run_scenario(..., tracker="jipda")`` derives for the scene
(:func:`~jointtrack.experiments.config.scenario_tracker_settings`) — is started
*tentative* at the target's true state (position and velocity) at its first
scan, with existence ``r_init`` and the covariance of the tracker's one-point
initiation (position: the measurement noise R; velocity: per-axis σ_v =
max_speed / 2, what a track born on that return would get), and run on the
scans from there. It is the only track: the tracks the tracker starts on the
returns are removed after every scan, so none competes for the target's
returns (no initiation of other tracks). Its scans are, by default
(``returns="all"``), the scene's scans as every tracker sees them — the
target's own returns, the clutter *and the other targets' returns*
(``returns="own"``: the other targets' returns removed, using the scene's
``origins``). When its track is deleted (existence below ``r_delete``: in
heavy clutter a track started with σ_v = max_speed / 2 can follow clutter away —
the headline scene's seed 0 target 0 does, at 7.5 m/s against its 2 m/s) it is
started again, the same way, at the target's true state of the next scan, as
the tracker's initiation would start one on the target's later returns
(``restart=False``: one track, never deleted). The target's *oracle
confirmation* is the number of scans from its first scan up to and including
the first at which the IPDA's existence reaches ``r_confirm`` (``None``: not
within the scene).

Measured on the headline scene, seeds 0–4 (``benchmarks/RESULTS.md``): median
15 scans with every return (18 with the target's own returns and the clutter
only: the neighbours' returns, 2σ away, add evidence), against the 17–19 of
issue 33's author, whose oracle is not specified further.

**The start-up floor** (:func:`floor_tracks`). The truth-started JIPDA run
(``run_scenario(..., start_from="truth")``), each of its truth-started tracks
shown only from its target's oracle confirmation scan (before it the target
counts as missed; never, when the oracle never confirms); tracks that run
initiated itself are kept as they are. It is scored exactly as the trackers:
a tracker from nothing that loses nothing to the start beyond what a lone,
perfectly started IPDA needs would score it.

**The matched floor** (:func:`false_track_rate`, :func:`matched_floor`). The
oracle pays no false alarms, but a tracker from nothing does: it starts a test
on every return — on the headline scene ≈ 60 clutter returns × 81 scans — and
at r_confirm = 0.9 from r_init = 0.02 Wald's bound, odds(r_init) /
odds(r_confirm), allows ≈ 11 false confirmations a run. The matched floor is
the floor with the oracle confirming at the threshold r* that a tracker from
nothing with the run's settings needs to hold at most :data:`FALSE_LIMIT`
false confirmed tracks per scan on that scene. r* is computed by simulation
from the scene's own settings: lone IPDAs (the oracle's settings: gate P_G,
P_D, λ, r_init, r_delete, r_report, the one-point covariance) born on clutter
returns uniform over the region, run on clutter-only scans of the scene's
``clutter_rate`` and scan times until deleted (multilevel splitting reaches
the rare confirmations); for each threshold r of :data:`MATCHED_GRID` the
expected false confirmed tracks per scan of a run is the clutter rate × the
expected scans a test born at a random scan of the run is reported confirmed
(existence reached r, still ≥ r_report, not deleted) / K; r* is the smallest r
on the grid at or below the limit (None when none is). A lone IPDA per birth is
the tracker that lets a target's evidence accumulate at the oracle's pace (the
issue's item 2); a tracker whose tentative tracks compete for returns suppresses
clutter tracks further but splits its targets' evidence. Targets' returns and
the births on them (duplicates, tracks that follow a target beyond c) are not
in this count: it is the clutter's share of the false-track line. At r* =
r_confirm the matched floor is the issue's floor.

**Scores** (:func:`score_tracks`): the run's own GOSPA (α = 2, the ``c`` and
``p`` of ``jointtrack run`` on the scene, :func:`scenario_metric_settings`,
else c = 5σ, p = 2) per scan and its parts (localisation, missed, false, in the
p-th power as ``metrics.json`` has them) per *phase*; the confirmation scans
per target (:func:`jointtrack.experiments.summary.confirmation_scans`: first
scan at which a reported track is the target's GOSPA partner within c); the
identity switches (:func:`jointtrack.metrics.track_statistics` with gate c);
false confirmed tracks per scan (GOSPA's unassigned tracks, mean over scans).

**Phases** (:func:`phases`), from the truth alone. d(k) is the smallest
distance between two targets at scan k, ``close`` the scans with d(k) <
``close_sigmas`` · σ (default 3σ, σ = √(mean diag R): the scale below which
two targets' returns fall in each other's gates). In scan order:

* ``start``: the first ``start_scans`` scans (default 20, the lone-IPDA
  confirmation time on the headline scene), cut short by the first close scan;
* ``approach``: after the start up to the first close scan (every scan between
  start and end when the targets never come close);
* ``close``: the first close scan to the last (after the start);
* ``separating``: after the last close scan, before the end;
* ``end``: the last ``end_scans`` scans (default 10) that are not close.

On the headline scene (Bojilov's lanes 20 m = 2σ apart, the adjacent targets
2 m/s apart, abreast at t = 40) close is t ≈ 29–51 on straight lanes (to t = 57
on seed 0, whose outer lanes drift together); on crossing (45°, 10 m/s)
t ≈ 27–33 (29–36 on seed 0); abreast's lanes are 4σ apart, close only where two lanes drift
together (the truth's process noise).

Every tracker is built exactly as ``run_scenario(name, start_from="nothing",
seed=s, tracker=K)`` builds it (the run itself is that call) on the same
detections; Stone Soup's tutorial JPDA tracker
(:func:`jointtrack.bench.stonesoup_tracker.run_stonesoup`) is an optional peer.

API: :func:`make_scene` (name → checked scene), :func:`oracle_confirmation`,
:func:`phases`, :func:`floor_tracks`, :func:`tracker_tracks`,
:func:`score_tracks`, :func:`evaluate` (one scene and seed, every tracker and
the floor), :func:`aggregate` (over seeds, with the issue's PASS/FAIL checks),
:func:`false_track_rate` (r*), :func:`matched_floor`.
"""

from __future__ import annotations

import dataclasses
import math
import tempfile
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

import numpy as np

__all__ = [
    "PHASES",
    "SCENES",
    "TRACKERS",
    "aggregate",
    "check_scene",
    "evaluate",
    "false_track_rate",
    "floor_tracks",
    "make_scene",
    "matched_floor",
    "oracle_confirmation",
    "phases",
    "score_tracks",
    "tracker_tracks",
]

#: the scenes of the benchmark: the headline of ``jointtrack run`` and two others
SCENES = ("bojilov", "abreast", "crossing")
#: trackers from nothing (``run_scenario``'s kinds) and the optional peer
TRACKERS = ("jipda", "pmb", "pmbm", "stonesoup")
#: phases in scan order (module docstring)
PHASES = ("start", "approach", "close", "separating", "end")
#: the issue's pass lines: GOSPA / floor, switches per run (per tracker kind)
RATIO_LIMIT = {"jipda": 1.15, "pmb": 1.3, "pmbm": 1.3}
SWITCH_LIMIT = {"jipda": 1.0, "pmb": 2.0, "pmbm": 2.0}
#: the oracle's r_delete when it does not delete (oracle_confirmation)
ORACLE_R_DELETE = 1e-12
CONFIRM_MARGIN = 2.0  # median confirmation ≤ oracle + 2 scans
FALSE_LIMIT = 0.1  # false confirmed tracks per scan
#: thresholds the matched floor's r* is chosen from (false_track_rate)
MATCHED_GRID = (0.5, 0.7, 0.8, 0.9, 0.95, 0.97, 0.98, 0.99, 0.995, 0.998, 0.999, 0.9995, 0.9999)
#: clutter-born lone IPDAs simulated per scene for r* (before the splitting's copies)
MATCHED_BIRTHS = 20000
#: log-odds (nats) between the splitting levels of false_track_rate
SPLIT_NATS = 1.0
#: at most this many levels split at once (2^this copies)
MAX_SPLIT_LEVELS = 4

Tracks = tuple  # (times (R,), ids (R,), positions (R, dim))


# ----------------------------------------------------------------------------- scenes


def check_scene(scenario, name: str = "scenario"):
    """Return ``scenario`` if it is a :class:`~jointtrack.scenarios.Scenario` with a
    truth at every scan; else raise ValueError naming the argument ``name``.

    The oracle and the floor are started from the truth and every score is
    against it: a scene without truth (detections read from a file, a scenario
    whose truth is empty) cannot be benchmarked, and guessing would be worse.
    """
    from jointtrack.scenarios import Scenario

    if not isinstance(scenario, Scenario):
        raise ValueError(
            f"{name} must be a jointtrack.scenarios.Scenario with a truth (the oracle and the "
            f"floor start from the truth), got {type(scenario).__name__}; detections without "
            "truth cannot be benchmarked against the floor"
        )
    if scenario.n_targets == 0:
        raise ValueError(
            f"{name} {scenario.name!r} has no truth (no target at any scan): the oracle and "
            "the floor start from the truth, so it cannot be benchmarked against the floor"
        )
    return scenario


def make_scene(name: str, seed: int, scenario_kwargs: Mapping | None = None):
    """The scene ``name`` (one of :data:`SCENES`) of ``seed``, built as ``run_scenario`` builds it
    (``scenario_kwargs``: the generator's keywords, e.g. ``n_scans`` for a short case)."""
    from jointtrack.experiments.config import make_scenario

    if not isinstance(name, str) or name not in SCENES:
        raise ValueError(f"scene must be one of {', '.join(SCENES)}, got {name!r}")
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise ValueError(f"seed must be an integer ≥ 0, got {seed!r}")
    return check_scene(make_scenario(name, int(seed), dict(scenario_kwargs or {})), "scene")


def _sigma(scenario) -> float:
    return float(math.sqrt(np.mean(np.diag(scenario.R))))


def jipda_config(scenario):
    """The JIPDA settings ``run_scenario(scenario, tracker="jipda")`` derives."""
    from jointtrack.experiments.config import (
        jpda_kind_overrides,
        make_tracker_config,
        scenario_tracker_settings,
    )

    return make_tracker_config(
        scenario_tracker_settings(scenario), jpda_kind_overrides("jipda", {})
    )


def metric_settings(scenario) -> tuple[float, float]:
    """GOSPA ``(c, p)`` of ``jointtrack run`` on the scene (its own, else 5σ and 2)."""
    from jointtrack.experiments.config import scenario_metric_settings

    own = scenario_metric_settings(scenario)
    return float(own.get("c", 5.0 * _sigma(scenario))), float(own.get("p", 2.0))


# ----------------------------------------------------------------------------- oracle


def _ipda_config(scenario, config):
    """``config``, or the scene's JIPDA settings; refused unless an IPDA's TrackerConfig."""
    from jointtrack.trackers import TrackerConfig

    cfg = jipda_config(scenario) if config is None else config
    if not isinstance(cfg, TrackerConfig) or not cfg.existence:
        raise ValueError("config must be a TrackerConfig with existence = true (an IPDA)")
    return cfg


def _threshold(r, cfg, name: str) -> float:
    """A confirmation threshold in (r_init, 1) as a float; else ValueError naming ``name``."""
    from jointtrack.assignment._checks import as_float

    return as_float(r, name, minimum=cfg.r_init, maximum=1.0, open_min=True, open_max=True)


def _threshold_grid(grid, cfg) -> tuple:
    """``grid`` as a tuple of floats strictly increasing in (r_init, 1); else ValueError."""
    if (
        isinstance(grid, str | bytes)
        or not isinstance(grid, Sequence | np.ndarray)
        or not len(grid)
    ):
        raise ValueError(f"grid must be a non-empty sequence of thresholds, got {grid!r}")
    out = tuple(_threshold(r, cfg, f"grid[{i}]") for i, r in enumerate(grid))
    if any(b <= a for a, b in zip(out[:-1], out[1:], strict=True)):
        raise ValueError(f"grid must be strictly increasing, got {list(out)}")
    return out


def oracle_confirmation(
    scenario, *, returns: str = "all", config=None, restart: bool = True
) -> dict:
    """Oracle-started single-target IPDA confirmation scans per target (module docstring).

    Parameters
    ----------
    scenario : a :class:`~jointtrack.scenarios.Scenario` with truth.
    returns : ``"all"`` (the scans as the trackers see them) or ``"own"`` (the
        other targets' returns removed; the target's own and the clutter kept).
    config : the :class:`~jointtrack.trackers.TrackerConfig` (default: the
        JIPDA settings ``run_scenario`` derives for the scene); its
        ``existence`` must be true.
    restart : when the IPDA's track is deleted (existence below ``r_delete``,
        as the tracker deletes it: it followed clutter away), start it again at
        the target's true state at the next scan, as the tracker's initiation
        would start a track on the target's later returns (default). False:
        one track, never deleted (``r_delete`` lowered to
        :data:`ORACLE_R_DELETE`); a target whose track is lost is then never
        confirmed.

    Returns
    -------
    dict
        ``{target id: {"first_scan": k0, "confirm_scan": k or None,
        "scans": k − k0 + 1 or None, "restarts": n}}``.
    """
    from jointtrack.trackers import JPDATracker

    check_scene(scenario)
    if returns not in ("all", "own"):
        raise ValueError(f'returns must be "all" or "own", got {returns!r}')
    cfg = _ipda_config(scenario, config)
    if not isinstance(restart, bool):
        raise ValueError(f"restart must be True or False, got {restart!r}")
    if not restart:
        cfg = dataclasses.replace(cfg, r_delete=min(cfg.r_delete, ORACLE_R_DELETE))
    d = scenario.dim
    out = {}
    for tid in scenario.target_ids.tolist():
        alive = [k for k, ids in enumerate(scenario.truth_ids) if tid in ids]
        first = alive[0]
        confirm, restarts, trk, oid = None, -1, None, None
        for k in alive:
            if trk is None:
                truth = scenario.truth_states[k][np.flatnonzero(scenario.truth_ids[k] == tid)[0]]
                trk = JPDATracker(cfg)
                # the one-point initiation's covariance on a return at the true position
                x0, P0 = trk._initial_states(truth[None, :d])
                x0[0, : 2 * d] = truth[: 2 * d]
                (oid,) = trk.start_tracks(x0, P0, confirmed=False, existence=cfg.r_init)
                restarts += 1
            z = scenario.detections[k]
            if returns == "own":
                o = scenario.origins[k]
                z = z[(o < 0) | (o == tid)]
            trk.step(float(scenario.times[k]), z)
            mine = trk.ids == oid
            if not mine.any():  # deleted: it followed clutter away
                if not restart:
                    break
                trk = None
                continue
            if trk.confirmed[mine][0]:
                confirm = k
                break
            trk._keep(mine)  # the lone IPDA: the tracks born on this scan's returns go
        out[int(tid)] = {
            "first_scan": first,
            "confirm_scan": confirm,
            "scans": None if confirm is None else confirm - first + 1,
            "restarts": max(restarts, 0),
        }
    return out


# ----------------------------------------------------------------------------- matched floor


def _logit(r: float) -> float:
    return math.log(r) - math.log1p(-r)


def false_track_rate(
    scenario,
    *,
    config=None,
    births: int = MATCHED_BIRTHS,
    grid: Sequence[float] = MATCHED_GRID,
    seed: int = 0,
    level_nats: float = SPLIT_NATS,
) -> dict:
    """Expected false confirmed tracks per scan of lone IPDAs born on clutter, per threshold.

    The simulation of the matched floor (module docstring): ``births`` lone
    IPDAs (``config``, default the scene's JIPDA settings as the oracle runs
    them), each born tentative on a clutter return drawn uniformly over the
    scene's region at its first scan (existence ``r_init``, the one-point
    covariance), each alone in its own copy of the region, whose clutter is
    Poisson with the scene's ``clutter_rate`` per scan, uniform over the region
    (drawn only where the region meets the track's gate: the rest cannot reach
    it). Each is run over the scene's scan times by the tracker's own step
    until the tracker deletes it; the tracks the step starts on the returns
    are removed after each scan (a lone test). Its existence is recorded at
    every scan.

    Rare confirmations (1e-4 per birth at 0.99 on the headline scene) are
    reached by splitting (multilevel splitting, H. Kahn and T. E. Harris,
    "Estimation of particle transmission by random sampling", *National Bureau
    of Standards Applied Mathematics Series* 12, 1951): when a track's
    existence log-odds first pass logit(r_init) + j·``level_nats`` it is
    copied (2^(levels passed) copies, each in a fresh copy of the region, each
    carrying that fraction of its weight), so that the weighted copies are an
    unbiased estimate of every count.

    For a threshold r, a clutter-born track is a false confirmed track at every
    scan from the first at which its existence reached r while it is reported
    (existence ≥ ``r_report``) and not deleted. A tracker from nothing starts
    such a test on each of the ``clutter_rate`` clutter returns of every scan
    and a test born at scan k₀ has the K − k₀ scans left of the run, so the
    expected false confirmed tracks per scan of a run of K scans are
    ``clutter_rate / K · E[Σ_{k ≥ c_r, reported} (K − k)]`` over births at the
    first scan (k relative to birth, c_r its confirmation scan).

    Returns
    -------
    dict
        ``grid`` (the thresholds), ``false_per_scan`` (and its Monte Carlo standard
        error ``false_per_scan_se``, over the births), ``p_confirm`` (the
        probability that a clutter-born test reaches r) and ``reported_scans``
        (mean scans a confirmed false track is reported, within the run) per
        threshold; ``r_star`` (the smallest threshold on the grid with at most
        :data:`FALSE_LIMIT` false per scan, None when none has), ``births``,
        ``copies`` (tracks simulated with the splits), ``seed``, ``clutter_rate``.
    """
    from jointtrack.assignment._checks import as_float, as_int
    from jointtrack.association.gating import gate_threshold
    from jointtrack.trackers import JPDATracker

    check_scene(scenario)
    cfg = _ipda_config(scenario, config)
    births = as_int(births, "births", minimum=1, maximum=10**6)
    seed = as_int(seed, "seed", minimum=0)
    level_nats = as_float(level_nats, "level_nats", minimum=0.05, maximum=20.0)
    grid = _threshold_grid(grid, cfg)
    d = scenario.dim
    lo = np.asarray(scenario.region, float)[:, 0]
    span = np.asarray(scenario.region, float)[:, 1] - lo
    if not (np.all(np.isfinite(span)) and np.all(span > 0)):
        raise ValueError(
            f"scenario.region must be a box of positive, finite extent (the clutter's), got "
            f"{np.asarray(scenario.region).tolist()}"
        )
    rate = float(scenario.clutter_rate)
    lam = rate / float(np.prod(span))
    times = np.asarray(scenario.times, float)
    K = len(times)
    # copies of the region far enough apart that no gate reaches another's clutter
    spacing = 100.0 * float(span.max()) + 1e4
    gamma = gate_threshold(min(float(cfg.p_g), 1.0 - 1e-12), d)
    ell0 = _logit(cfg.r_init)
    n_levels = max(0, math.ceil((_logit(grid[-1]) - ell0) / level_nats))
    rng = np.random.default_rng(seed)

    trk = JPDATracker(cfg)
    tile = np.arange(births)
    x0, P0 = trk._initial_states(lo + rng.random((births, d)) * span + _offset(tile, d, spacing))
    ids = np.asarray(trk.start_tracks(x0, P0, confirmed=False, existence=cfg.r_init, time=times[0]))
    leaf_ids, leaf_of = ids.copy(), np.arange(births)  # track id → leaf (ids increase)
    hist = np.full((births, K), np.nan)  # existence per leaf and scan (NaN: deleted)
    hist[:, 0] = cfg.r_init
    weight = np.ones(births)
    level = np.zeros(births, np.int64)
    root = np.arange(births)  # the birth each copy descends from (for the standard error)
    n_tiles = births
    for k in range(1, K):
        if not len(trk.ids):
            break
        t = float(times[k])
        dt = t - float(times[k - 1])
        F, Q = trk._motion.transition(dt), trk._motion.noise(dt)
        H, R = trk._sensor.H, trk._sensor.R
        xp = trk.x @ F.T
        S = H @ (F @ trk.P @ F.T + Q) @ H.T + R
        half = np.sqrt(gamma * np.linalg.eigvalsh(S)[:, -1]) * 1.01
        row = leaf_of[np.searchsorted(leaf_ids, trk.ids)]
        origin = lo + _offset(tile[row], d, spacing)
        centre = xp @ H.T
        box_lo = np.maximum(centre - half[:, None], origin)
        box_hi = np.minimum(centre + half[:, None], origin + span)
        size = np.clip(box_hi - box_lo, 0.0, None)
        n = rng.poisson(lam * np.prod(size, axis=1))
        z = np.repeat(box_lo, n, axis=0) + rng.random((int(n.sum()), d)) * np.repeat(
            size, n, axis=0
        )
        trk.step(t, z)
        trk._keep(np.isin(trk.ids, leaf_ids))  # lone tests: the tracks born on z go
        row = leaf_of[np.searchsorted(leaf_ids, trk.ids)]
        hist[row, k] = trk.existence
        # split the tracks whose log-odds passed new levels
        ell = np.log(trk.existence) - np.log1p(-np.minimum(trk.existence, 1 - 1e-16))
        reached = np.clip(np.floor((ell - ell0) / level_nats), 0, n_levels).astype(np.int64)
        up = np.minimum(reached - level[row], MAX_SPLIT_LEVELS)
        src = np.flatnonzero(up > 0)
        if src.size:
            level[row[src]] = reached[src]
            per = 2 ** up[src]
            weight[row[src]] /= per
            rep = np.repeat(src, per - 1)
            new_rows = np.arange(len(weight), len(weight) + rep.size)
            new_tiles = np.arange(n_tiles, n_tiles + rep.size)
            n_tiles += rep.size
            move = _offset(new_tiles, d, spacing) - _offset(tile[row[rep]], d, spacing)
            xs = trk.x[rep].copy()
            xs[:, :d] += move
            new_ids = trk._append(
                xs, trk.P[rep].copy(), confirmed=False, existence=trk.existence[rep], time=t
            )
            trk.confirmed[-rep.size :] = trk.confirmed[rep]
            hist = np.concatenate([hist, hist[row[rep]]])
            weight = np.concatenate([weight, weight[row[rep]]])
            level = np.concatenate([level, level[row[rep]]])
            root = np.concatenate([root, root[row[rep]]])
            tile = np.concatenate([tile, new_tiles])
            leaf_ids = np.concatenate([leaf_ids, new_ids])
            leaf_of = np.concatenate([leaf_of, new_rows])
    reported = np.nan_to_num(hist, nan=-1.0) >= cfg.r_report
    left = K - np.arange(K)  # scans of the run left from each scan of a birth at the first
    false_per_scan, false_se, p_confirm, reported_scans = [], [], [], []
    for r in grid:
        hit = np.nan_to_num(hist, nan=-1.0) >= r
        ever = hit.any(axis=1)
        first = np.where(ever, hit.argmax(axis=1), K)
        after = np.arange(K)[None, :] >= first[:, None]
        on = after & reported
        # per birth: its copies' weighted sum (independent across births: the standard error)
        per_birth = np.bincount(root, weight * (on * left).sum(axis=1), minlength=births)
        false_per_scan.append(rate / K * float(per_birth.mean()))
        false_se.append(
            rate / K * float(per_birth.std(ddof=1) / math.sqrt(births)) if births > 1 else math.inf
        )
        pc = float(weight @ ever) / births
        p_confirm.append(pc)
        reported_scans.append(float(weight @ on.sum(axis=1)) / births / pc if pc > 0 else None)
    ok = [r for r, f in zip(grid, false_per_scan, strict=True) if f <= FALSE_LIMIT]
    return {
        "grid": list(grid),
        "false_per_scan": false_per_scan,
        "false_per_scan_se": false_se,
        "p_confirm": p_confirm,
        "reported_scans": reported_scans,
        "r_star": ok[0] if ok else None,
        "births": births,
        "copies": len(weight),
        "seed": seed,
        "clutter_rate": rate,
    }


def _offset(tile: np.ndarray, d: int, spacing: float) -> np.ndarray:
    out = np.zeros((len(tile), d))
    out[:, 0] = np.asarray(tile, float) * spacing
    return out


# ----------------------------------------------------------------------------- phases


def phases(
    scenario, *, start_scans: int = 20, end_scans: int = 10, close_sigmas: float = 3.0
) -> np.ndarray:
    """The phase (index into :data:`PHASES`) of every scan, from the truth (module docstring)."""
    check_scene(scenario)
    for name, v in (("start_scans", start_scans), ("end_scans", end_scans)):
        if isinstance(v, bool) or not isinstance(v, int | np.integer) or v < 0:
            raise ValueError(f"{name} must be an integer ≥ 0, got {v!r}")
    if isinstance(close_sigmas, bool) or not isinstance(close_sigmas, int | float):
        raise ValueError(f"close_sigmas must be a number > 0, got {close_sigmas!r}")
    if not (math.isfinite(close_sigmas) and close_sigmas > 0):
        raise ValueError(f"close_sigmas must be finite and > 0, got {close_sigmas!r}")
    K = scenario.n_scans
    dmin = np.full(K, np.inf)
    for k, pos in enumerate(scenario.truth_positions):
        if len(pos) > 1:
            diff = pos[:, None, :] - pos[None, :, :]
            dist = np.sqrt(np.einsum("ijk,ijk->ij", diff, diff))
            dmin[k] = dist[np.triu_indices(len(pos), 1)].min()
    close = dmin < close_sigmas * _sigma(scenario)
    idx = np.flatnonzero(close)
    first_close = int(idx[0]) if idx.size else K
    k_start = min(int(start_scans), first_close, K)
    out = np.full(K, PHASES.index("approach"), dtype=np.int64)
    out[:k_start] = PHASES.index("start")
    late = idx[idx >= k_start]
    if late.size:
        lo, hi = int(late[0]), int(late[-1])
        out[hi + 1 :] = PHASES.index("separating")
        out[lo : hi + 1] = PHASES.index("close")
        end_from = max(K - int(end_scans), hi + 1, k_start)
    else:
        end_from = max(K - int(end_scans), k_start)
    out[end_from:] = PHASES.index("end")
    return out


# ----------------------------------------------------------------------------- runs


def _read_run_tracks(metrics: Mapping) -> Tracks:
    from jointtrack.io import read_tracks

    cols = read_tracks(metrics["files"]["tracks"])
    pos = np.stack([cols[a] for a in ("x", "y", "z") if a in cols], axis=1)
    return cols["time"], cols["track_id"], pos


def tracker_tracks(
    name: str,
    seed: int,
    kind: str,
    out_dir=None,
    *,
    budget: float | None = None,
    scenario_kwargs: Mapping | None = None,
) -> Tracks:
    """The confirmed tracks of tracker ``kind`` from nothing on scene ``name`` of ``seed``.

    ``kind`` in :data:`TRACKERS`: ``run_scenario(name, start_from="nothing",
    seed=seed, tracker=kind)`` (written to ``out_dir``, default a temporary
    directory), or Stone Soup's tutorial JPDA tracker (``budget``: its seconds;
    RuntimeError when it stops at the budget — a partial run is not scored).
    """
    if kind not in TRACKERS:
        raise ValueError(f"tracker must be one of {', '.join(TRACKERS)}, got {kind!r}")
    scene = make_scene(name, seed, scenario_kwargs)
    if kind == "stonesoup":
        from jointtrack.bench.stonesoup_tracker import run_stonesoup, stonesoup_available

        if not stonesoup_available():
            raise ValueError("tracker 'stonesoup' needs Stone Soup (the bench extra)")
        r = run_stonesoup(scene, budget)
        if not r.completed:  # scored, the scans it did not reach would read as all missed
            raise RuntimeError(
                f"stonesoup on {name} seed {seed} reached its budget of {budget:g} s after "
                f"{r.n_scans} of {scene.n_scans} scans; give a larger --budget"
            )
        return r.times, r.ids, r.positions
    return _run_tracks(name, seed, out_dir, scenario_kwargs, start_from="nothing", tracker=kind)


def _run_tracks(name, seed, out_dir, scenario_kwargs, **kw) -> Tracks:
    from jointtrack.experiments.run import run_scenario

    with tempfile.TemporaryDirectory(prefix="jointtrack-floor-") as tmp:
        where = Path(out_dir) if out_dir is not None else Path(tmp)
        m = run_scenario(
            name,
            seed=seed,
            scenario_kwargs=dict(scenario_kwargs or {}),
            plots=False,
            out_dir=where,
            **kw,
        )
        return _read_run_tracks(m)


def floor_tracks(scenario, truth_run: Tracks, oracle: Mapping) -> Tracks:
    """The start-up floor: ``truth_run`` (the truth-started JIPDA run's tracks) with each
    truth-started track kept only from its target's oracle confirmation scan.

    A truth-started track is one reported at the first scan; its target is the
    truth it is the GOSPA partner of there (within c). Tracks the run started
    later (from the detections) are kept whole.
    """
    from jointtrack.metrics import track_statistics

    check_scene(scenario)
    t, ids, pos = (np.asarray(a) for a in truth_run)
    c, _p = metric_settings(scenario)
    t0 = float(scenario.times[0])
    at0 = t == t0
    stats = track_statistics(*scenario.truth_table(), t[at0], ids[at0], pos[at0], gate=c)
    target_of = dict(
        zip(stats.assoc_track_ids.tolist(), stats.assoc_truth_ids.tolist(), strict=True)
    )
    scan = np.searchsorted(scenario.times, t)
    keep = np.ones(t.size, bool)
    for track, target in target_of.items():
        o = oracle.get(int(target))
        rows = ids == track
        if o is None or o["confirm_scan"] is None:
            keep[rows] = False
        else:
            keep[rows] = scan[rows] >= o["confirm_scan"]
    return t[keep], ids[keep], pos[keep]


# ----------------------------------------------------------------------------- scores


def score_tracks(scenario, tracks: Tracks, phase: np.ndarray | None = None) -> dict:
    """Score ``tracks`` against the scene's truth (module docstring).

    Returns a dict: ``gospa`` (mean), ``gospa_series`` (per scan),
    ``phases`` ({phase: {gospa, localisation, missed, false, n_scans}}),
    ``confirm_scans`` ({target: scans or None}), ``switches``,
    ``false_per_scan``, ``c``, ``p``.
    """
    from jointtrack.experiments.summary import confirmation_scans
    from jointtrack.metrics import gospa_series, track_statistics

    check_scene(scenario)
    phase = phases(scenario) if phase is None else np.asarray(phase)
    c, p = metric_settings(scenario)
    truth = scenario.truth_table()
    t, ids, pos = tracks
    series = gospa_series(*truth, t, ids, pos, c=c, p=p)
    stats = track_statistics(*truth, t, ids, pos, gate=c)
    # scans without truth or tracks are not in the series: align by time
    K = scenario.n_scans
    k_of = np.searchsorted(scenario.times, series.times)
    per = {}
    for name in ("gospa", "localisation", "missed", "false", "n_false"):
        a = np.zeros(K)
        a[k_of] = getattr(series, name)
        per[name] = a
    by_phase = {}
    for i, name in enumerate(PHASES):
        m = phase == i
        by_phase[name] = {
            "n_scans": int(m.sum()),
            **{
                part: (float(per[part][m].mean()) if m.any() else None)
                for part in ("gospa", "localisation", "missed", "false")
            },
        }
    return {
        "c": c,
        "p": p,
        "gospa": float(per["gospa"].mean()),
        "gospa_series": per["gospa"].tolist(),
        "phases": by_phase,
        "confirm_scans": confirmation_scans(scenario.times, truth, stats),
        "switches": int(stats.n_id_switches),
        "false_per_scan": float(per["n_false"].mean()),
    }


# ----------------------------------------------------------------------------- evaluate


def evaluate(
    name: str,
    seed: int,
    trackers: Sequence[str] = ("jipda", "pmb", "pmbm"),
    *,
    returns: str = "all",
    budget: float | None = None,
    scenario_kwargs: Mapping | None = None,
    on_step: Callable[[str], None] | None = None,
    r_matched: float | None = None,
) -> dict:
    """One scene and seed: the oracle, the floor and every tracker of ``trackers``, scored.

    Returns ``{"scene", "seed", "oracle": {target: scans or None}, "phases":
    [phase index per scan], "floor": score, "trackers": {kind: score}}``
    (scores: :func:`score_tracks`). ``scenario_kwargs``: the scene generator's
    keywords (e.g. ``{"n_scans": 15}``). ``on_step(label)`` is called after each part.
    ``r_matched`` (e.g. ``false_track_rate(scene)["r_star"]``): also the matched
    floor, ``"matched": {"r", "oracle", "floor"}`` (:func:`matched_floor`).
    """
    bad = [k for k in trackers if k not in TRACKERS]
    if bad or isinstance(trackers, str):
        raise ValueError(
            f"trackers must be a sequence of {', '.join(TRACKERS)}, got {list(trackers)!r}"
        )
    scene = make_scene(name, seed, scenario_kwargs)
    if r_matched is not None:
        r_matched = _threshold(r_matched, jipda_config(scene), "r_matched")  # before any run
    step = on_step or (lambda _label: None)
    phase = phases(scene)
    oracle = oracle_confirmation(scene, returns=returns)
    step("oracle")
    truth_run = _run_tracks(name, seed, None, scenario_kwargs, start_from="truth", tracker="jipda")
    floor = score_tracks(scene, floor_tracks(scene, truth_run, oracle), phase)
    step("floor")
    out = {
        "scene": name,
        "seed": int(seed),
        "n_scans": scene.n_scans,
        "oracle": {t: o["scans"] for t, o in oracle.items()},
        "phases": phase.tolist(),
        "floor": floor,
        "trackers": {},
    }
    if r_matched is not None:
        out["matched"] = matched_floor(scene, truth_run, r_matched, returns=returns, phase=phase)
    for kind in trackers:
        out["trackers"][kind] = score_tracks(
            scene,
            tracker_tracks(name, seed, kind, budget=budget, scenario_kwargs=scenario_kwargs),
            phase,
        )
        step(kind)
    return out


def matched_floor(
    scenario, truth_run: Tracks, r: float, *, returns: str = "all", phase=None
) -> dict:
    """The start-up floor with the oracle confirming at ``r`` instead of the settings' r_confirm.

    The oracle (:func:`oracle_confirmation`, ``returns``) with ``r_confirm = r``,
    and :func:`floor_tracks` of ``truth_run`` from its confirmations, scored
    (:func:`score_tracks`). Returns ``{"r", "oracle": {target: scans or None},
    "floor": score}``. At the settings' own r_confirm it is the issue's floor.
    """
    check_scene(scenario)
    cfg = jipda_config(scenario)
    r = _threshold(r, cfg, "r")
    cfg = dataclasses.replace(cfg, r_confirm=r)
    oracle = oracle_confirmation(scenario, returns=returns, config=cfg)
    floor = score_tracks(scenario, floor_tracks(scenario, truth_run, oracle), phase)
    return {"r": r, "oracle": {t: o["scans"] for t, o in oracle.items()}, "floor": floor}


def _median_scans(values) -> float | None:
    """Median with never (None) as +∞; None when empty or more than half never confirmed."""
    a = np.array([math.inf if v is None else v for v in values], float)
    if not a.size:
        return None
    m = float(np.median(a))
    return m if math.isfinite(m) else None


def _mean_std(values) -> dict:
    a = np.asarray(values, float)
    return {"mean": float(a.mean()), "std": float(a.std(ddof=1)) if a.size > 1 else 0.0}


def aggregate(runs: Sequence[Mapping]) -> dict:
    """Pool :func:`evaluate` results of one scene over seeds, with the issue's checks.

    Per tracker (and ``floor``): GOSPA mean ± std over seeds and per phase (over
    the seeds that have the phase, ``n_seeds``),
    ``ratio`` (GOSPA / floor per seed, mean ± std), switches per run, false
    per scan, the median confirmation scans over (seed, target) and the
    median of (tracker − oracle) over pairs both confirmed, and ``checks``
    ({line: PASS bool}) for the kinds the issue sets lines for. When every run
    has a ``matched`` floor (:func:`evaluate`'s ``r_matched``): ``matched``
    ({r, oracle_median, oracle_never}), a ``matched_floor`` row and each row's
    ``ratio_matched`` (GOSPA / matched floor per seed; information, not a check).
    """
    if not runs:
        raise ValueError("runs must hold at least one evaluate() result")
    scenes = {r["scene"] for r in runs}
    if len(scenes) != 1:
        raise ValueError(f"runs must be of one scene, got {sorted(scenes)}")
    oracle_all = [v for r in runs for v in r["oracle"].values()]
    out = {
        "scene": runs[0]["scene"],
        "seeds": [r["seed"] for r in runs],
        "oracle_median": _median_scans(oracle_all),
        "oracle_never": sum(v is None for v in oracle_all),
    }
    floor = [r["floor"]["gospa"] for r in runs]
    kinds = ["floor", *runs[0]["trackers"]]
    matched = [r.get("matched") for r in runs]
    if all(matched):
        rs = {m["r"] for m in matched}
        if len(rs) != 1:
            raise ValueError(f"runs must share one matched threshold, got {sorted(rs)}")
        m_oracle = [v for m in matched for v in m["oracle"].values()]
        out["matched"] = {
            "r": rs.pop(),
            "oracle_median": _median_scans(m_oracle),
            "oracle_never": sum(v is None for v in m_oracle),
        }
        kinds.insert(1, "matched_floor")
    for kind in kinds:
        sc = [
            r["floor"]
            if kind == "floor"
            else r["matched"]["floor"]
            if kind == "matched_floor"
            else r["trackers"][kind]
            for r in runs
        ]
        conf = [v for s in sc for v in s["confirm_scans"].values()]
        behind = [
            s["confirm_scans"][t] - o
            for r, s in zip(runs, sc, strict=True)
            for t, o in r["oracle"].items()
            if o is not None and s["confirm_scans"].get(t) is not None
        ]
        row = {
            "gospa": _mean_std([s["gospa"] for s in sc]),
            "ratio": _mean_std([s["gospa"] / f for s, f in zip(sc, floor, strict=True)]),
            # information beside the lines: GOSPA / the matched floor per seed
            **(
                {
                    "ratio_matched": _mean_std(
                        [s["gospa"] / m["floor"]["gospa"] for s, m in zip(sc, matched, strict=True)]
                    )
                }
                if "matched" in out
                else {}
            ),
            "switches": _mean_std([s["switches"] for s in sc]),
            "false_per_scan": _mean_std([s["false_per_scan"] for s in sc]),
            "confirm_median": _median_scans(conf),
            "confirm_never": sum(v is None for v in conf),
            "behind_oracle_median": float(np.median(behind)) if behind else None,
            # over the seeds that have the phase (abreast's close phase comes from lanes
            # drifting together on some seeds only)
            "phases": {
                ph: {
                    "n_seeds": len(having),
                    **{
                        part: _mean_std([s["phases"][ph][part] for s in having])
                        for part in ("gospa", "localisation", "missed", "false")
                    },
                }
                for ph in PHASES
                if (having := [s for s in sc if s["phases"][ph]["n_scans"]])
            },
        }
        if kind in RATIO_LIMIT:
            om = out["oracle_median"]
            cm = row["confirm_median"]
            row["checks"] = {
                f"GOSPA ≤ {RATIO_LIMIT[kind]:g} × floor": row["ratio"]["mean"] <= RATIO_LIMIT[kind],
                f"switches ≤ {SWITCH_LIMIT[kind]:g}/run": row["switches"]["mean"]
                <= SWITCH_LIMIT[kind],
                f"median confirmation ≤ oracle + {CONFIRM_MARGIN:g}": (
                    cm is not None and om is not None and cm <= om + CONFIRM_MARGIN
                ),
                f"false ≤ {FALSE_LIMIT:g}/scan": row["false_per_scan"]["mean"] <= FALSE_LIMIT,
            }
        out[kind] = row
    return out
