"""A run's results: the metrics dict (``metrics.json``) and the rich summary tables.

:func:`_run_metrics` scores the tracks against the truth (GOSPA, OSPA, track
statistics) or counts them (no truth) and adds the timing per cluster size;
:func:`summary_tables` / :func:`print_summary` show a metrics dict on a rich
console (:func:`tracks_line` is its ``tracks`` row: coverage, breaks, identity
switches). The fields are described in :mod:`jointtrack.experiments.run`.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from jointtrack.association.budget import reason_kind
from jointtrack.experiments.config import TRUTH_START_NOTE, _describe
from jointtrack.trackers import TrackerConfig

__all__ = [
    "PARTICLE_START_NOTE",
    "association_line",
    "confirmation_scans",
    "count_cluster",
    "particle_metrics",
    "print_summary",
    "start_evidence",
    "start_description",
    "summary_tables",
    "tracker_description",
    "tracks_line",
]

PARTICLE_START_NOTE = (
    "targets started from the truth at the first scan: the particle JPDA tracker follows a "
    "known, fixed set of targets (no births, no deletions)"
)


def _cluster_timing(clusters: list) -> list[dict]:
    """Per number of tracks in a multi-track cluster: count, mean/max seconds, mean size."""
    by: dict[int, list] = {}
    for n_tr, n_me, sec in clusters:
        by.setdefault(int(n_tr), []).append((n_me, sec))
    out = []
    for n in sorted(by):
        a = np.array(by[n], dtype=float)
        out.append(
            {
                "n_tracks": n,
                "count": int(len(a)),
                "mean_measurements": float(a[:, 0].mean()),
                "mean_seconds": float(a[:, 1].mean()),
                "max_seconds": float(a[:, 1].max()),
                "total_seconds": float(a[:, 1].sum()),
            }
        )
    return out


def count_cluster(solved: dict, confirmed: bool, method: str, reason: str, n_tracks, n_meas):
    """Count one multi-track cluster in ``solved`` (a run's ``association.clusters`` tally).

    Key ``"<confirmed|tentative>|<method>|<reason kind>"`` (reason kind: the part
    of the fallback reason before its first ``:``/``;``, empty when the configured
    method solved it) → ``[count, min tracks, max tracks, min measurements, max
    measurements]``: plain JSON, kept in a checkpoint's run bookkeeping.
    """
    why = reason_kind(reason)
    key = f"{'confirmed' if confirmed else 'tentative'}|{method}|{why}"
    n_tracks, n_meas = int(n_tracks), int(n_meas)
    row = solved.get(key)
    if row is None:
        solved[key] = [1, n_tracks, n_tracks, n_meas, n_meas]
    else:
        row[0] += 1
        row[1], row[2] = min(row[1], n_tracks), max(row[2], n_tracks)
        row[3], row[4] = min(row[3], n_meas), max(row[4], n_meas)


def cluster_rows(solved: Mapping) -> list[dict]:
    """``metrics.json``'s ``association.clusters``: the :func:`count_cluster` tally as rows."""
    rows = []
    for key, (count, t0, t1, m0, m1) in sorted(solved.items()):
        kind, method, why = key.split("|", 2)
        rows.append(
            {
                "tracks": kind,
                "method": method,
                "reason": why,
                "count": int(count),
                "n_tracks": [int(t0), int(t1)],
                "n_measurements": [int(m0), int(m1)],
            }
        )
    return rows


#: how each method solved a cluster, in words
_BY = {
    "exact": "exactly",
    "enumerate": "exactly (hypothesis enumeration)",
    "lbp": "by loopy belief propagation",
    "lbp-sparse": "by sparse loopy belief propagation",
    "pda": "by per-track PDA",
    "mcmc": "by MCMC sampling",
    "kbest": "by the k best hypotheses",
    # PMBM (trackers.pmbm): Murty's ranked assignments, and its two budget tiers
    "murty": "exactly (ranked assignments)",
    "murty-truncated": "by fewer ranked assignments per hypothesis",
}


def _by(method: str) -> str:
    """How ``method`` solved a cluster, in words (PMBM's ``pmb-<tier>``: merged, then ``tier``)."""
    if method.startswith("pmb-"):
        tier = _BY.get(method[4:], f"by {method[4:]}")
        return f"merged to one Bernoulli per track (PMB) and solved {tier}"
    return _BY.get(method, f"by {method}")


def _span(lo: int, hi: int, noun: str) -> str:
    return f"{lo} {noun}" if lo == hi else f"{lo}–{hi} {noun}"


def _why(reason: str, assoc: Mapping) -> str:
    """A fallback's reason kind in words, naming the budget and its value."""
    if reason == "exact_max_tracks":
        return f"as they have more than exact_max_tracks = {assoc.get('exact_max_tracks', '?')}"
    if reason == "exact_max_bits_tentative":
        bits = assoc.get("exact_max_bits_tentative", "?")
        return (
            f"as their exact sum needs more than 2^{bits} states (the tentative-track "
            f"budget, exact_max_bits_tentative = {bits})"
        )
    if reason == "refused":
        return "as their exact sum is beyond the exact engine's state or memory limit"
    if reason in ("ranking_truncated", "ranking_merged"):
        return (
            "as ranking their assignments would exceed the PMBM work budget "
            f"(max_ranking_work = {assoc.get('max_ranking_work', '?')})"
        )
    if reason == "dense_budget":
        return "as they are too large for a tracks × measurements matrix"
    return f"({reason})"


def association_line(metrics: Mapping) -> str | None:
    """The run's association in one plain sentence, from ``association.clusters``.

    E.g. ``association: 57 clusters of confirmed tracks (2–5 tracks) solved
    exactly; 112 clusters of tentative tracks (2–185 tracks): 36 (2–85 tracks)
    solved exactly and 76 (91–185 tracks) by loopy belief propagation as their
    exact sum needs more than 2^12 states (…)``, or
    ``association: all 141 multi-track clusters solved exactly …`` when no
    cluster needed the approximation. None for a metrics dict without the tally
    (a particle run, or one written by an older jointtrack).
    """
    assoc = metrics.get("association") or {}
    rows = assoc.get("clusters")
    if rows is None:
        return None
    if not rows:
        return "association: no multi-track clusters (every cluster was a single track)"
    poisson = (metrics.get("tracker") or {}).get("kind") in ("pmb", "pmbm")
    exact = all(r["method"] in ("exact", "enumerate", "murty") and not r["reason"] for r in rows)

    def tracks_of(kind):
        return "tracks" if poisson else f"{kind} tracks"

    parts = []
    for kind in ("confirmed", "tentative"):
        mine = [r for r in rows if r["tracks"] == kind]
        if not mine:
            continue
        n = sum(r["count"] for r in mine)
        lo = min(r["n_tracks"][0] for r in mine)
        hi = max(r["n_tracks"][1] for r in mine)
        head = f"{n} cluster{'s' * (n != 1)} of {tracks_of(kind)} ({_span(lo, hi, 'tracks')})"
        if len(mine) == 1 and not mine[0]["reason"]:
            parts.append(head if exact else f"{head} solved {_by(mine[0]['method'])}")
            continue
        ways = []
        for r in sorted(mine, key=lambda r: (bool(r["reason"]), -r["count"])):
            by = _by(r["method"])
            ways.append(
                f"{r['count']} ({_span(*r['n_tracks'], 'tracks')}) "
                f"{'solved ' if by.startswith('exactly') else ''}{by}"
                + (f" {_why(r['reason'], assoc)}" if r["reason"] else "")
            )
        joined = ways[0] if len(ways) == 1 else ", ".join(ways[:-1]) + " and " + ways[-1]
        parts.append(f"{head}: {joined}")
    if exact:
        total = sum(r["count"] for r in rows)
        return f"association: all {total} multi-track clusters solved exactly ({', '.join(parts)})"
    return "association: " + "; ".join(parts)


def _ospa_mean(truth, tracks, scan_times, c, p) -> float:
    from jointtrack.metrics import ospa

    tt, _ti, tp = truth
    et, _ei, ep = tracks
    vals = []
    for t in scan_times:
        X = tp[tt == t]
        Y = ep[et == t]
        vals.append(ospa(X, Y, c, p))
    return float(np.mean(vals)) if vals else float("nan")


#: Monte Carlo samples of the expected existence gain per scan (:func:`start_evidence`)
EVIDENCE_SAMPLES = 2000
#: scans of the lone track :func:`start_evidence` follows at least (its gain then: gain_last_scan)
STEADY_SCANS = 50
#: expected clutter returns in a gate above which their sum is taken as its mean (the
#: gain is then O(1/μ) nats per scan, e.g. 0.025 at μ ≈ 30: no start to speak of, and the
#: Monte Carlo would draw ~μ·samples returns)
MAX_GATE_CLUTTER = 50.0
#: the summary lists each target's scans to confirm up to this many targets
MAX_LISTED_TARGETS = 12
#: the summary notes a slow start when a lone target needs more scans than this to confirm
SLOW_START_SCANS = 10


def _log_odds_survived(ell: float, log_ps: float) -> float:
    """logit(p_s · r) for r = expit(ell), in log space (no underflow near r = 0 or 1).

    The tracker's survival step, existence ← existence · p_s (``JPDATracker.step`` with
    the factor of :func:`~jointtrack.trackers.reporting.scan_detection`), in log-odds:
    ``trackers/existence.py`` has no survival function to share, and the tracker's
    product in probability space would round r near 1 (the evidence sum here runs to
    logit(r_confirm) and beyond)."""
    log_r = -np.logaddexp(0.0, -ell)
    log_not_r = -np.logaddexp(0.0, ell)
    # 1 − p_s·r = (1 − r) + r·(1 − p_s): no cancellation when r or p_s rounds to 1
    with np.errstate(divide="ignore"):  # p_s = 1: log(1 − p_s) = −inf, the term is 0
        log_not_survived = np.logaddexp(log_not_r, log_r + np.log(-np.expm1(log_ps)))
    return float(log_ps + log_r - log_not_survived)


def _expected_log_gain(cfg, sqrt_det_s: float, samples: int, seed: int) -> float:
    """E[log Λ] of one IPDA existence update of a lone, existing target's track.

    The odds update of a lone track (:func:`~jointtrack.trackers.existence.existence_update`
    with one track) is odds⁺ = odds⁻ · Λ, Λ = 1 − P_D·P_G + Σ_i P_D N(z_i; ẑ, S)/λ over the
    returns in its gate (P_D·P_G is P_D with ``miss_model = "1-pd"``). The target's return
    is there with probability P_D, with d² = (z − ẑ)ᵀS⁻¹(z − ẑ) ~ χ²_m and counted when
    d² < γ; Poisson(λ V_G) clutter returns are uniform in the gate (d² = γ U^{2/m}).
    The expectation is a Monte Carlo mean over ``samples`` draws of a fixed ``seed``
    (the same draws at every S: common random numbers), in log space; a gate
    expecting more than :data:`MAX_GATE_CLUTTER` clutter returns gives the
    law-of-large-numbers limit log(1 − P_D·P_G + P_D·p_g) (0 with the default
    miss model: no evidence).
    """
    from scipy import special

    from jointtrack.association.gating import gate_threshold

    m = cfg.dim
    pg = float(cfg.p_g)
    # p_g = 1 is the infinite gate: returns beyond χ² 1 − 1e-12 add < 1e-12 of a peak
    gamma = gate_threshold(min(pg, 1.0 - 1e-12), m)
    pdg = cfg.p_d * (pg if cfg.miss_model == "1-pd*pg" else 1.0)
    lam = float(cfg.clutter_density)
    log_unit = special.gammaln(m / 2 + 1) - (m / 2) * math.log(math.pi)  # 1 / unit-ball volume
    log_vg = (m / 2) * math.log(gamma) + math.log(sqrt_det_s) - log_unit
    mu = lam * math.exp(log_vg)  # clutter returns expected in the gate
    if mu > MAX_GATE_CLUTTER:
        # the clutter's sum is its mean (law of large numbers): Σ P_D N/λ over the gate's
        # clutter → P_D·P_G, and the target's own return adds O(1/μ)
        return math.log1p(cfg.p_d * pg - pdg)
    log_a = math.log(cfg.p_d) - math.log(lam) - (m / 2) * math.log(2 * math.pi)
    log_a -= math.log(sqrt_det_s)  # the peak likelihood ratio P_D N(ẑ; ẑ, S)/λ
    rng = np.random.default_rng(seed)
    n_clutter = rng.poisson(mu, samples)
    who = np.repeat(np.arange(samples), n_clutter)
    d2 = gamma * rng.random(who.size) ** (2.0 / m)
    own = (rng.random(samples) < cfg.p_d) & ((t2 := rng.chisquare(m, samples)) < gamma)
    who = np.concatenate([who, np.flatnonzero(own)])
    terms = log_a - 0.5 * np.concatenate([d2, t2[own]])
    with np.errstate(divide="ignore"):
        log_miss = math.log1p(-pdg) if pdg < 1 else -math.inf
    top = np.full(samples, log_miss)
    np.maximum.at(top, who, terms)
    with np.errstate(invalid="ignore", divide="ignore"):
        rest = np.exp(log_miss - top) + np.bincount(
            who, np.exp(terms - top[who]), minlength=samples
        )
        log_gain = top + np.log(rest)
    log_gain[~np.isfinite(top)] = -math.inf  # no return and a certain detection
    return float(log_gain.mean())


def start_evidence(
    cfg, dt: float, *, samples: int = EVIDENCE_SAMPLES, seed: int = 0, max_scans: int = 1000
) -> dict | None:
    """How fast a lone target's track earns the existence to be confirmed, from the settings.

    The track is started on the target's return as the tracker's one-point
    initiation starts it (existence ``r_init``, position covariance R, velocity
    σ = max_speed/2) and updated at every scan: its existence log-odds, from
    logit(r_init), gain the expected log Λ of :func:`_expected_log_gain` at
    the scan's innovation covariance S (the Kalman filter's covariance from
    the initiation one, a return at every scan) and lose the survival
    (odds of p_s·r) between scans. ``expected_scans`` is the first scan at which
    the expected log-odds reach logit(r_confirm) (the scan of the initiating
    return is scan 1; None if not within ``max_scans``, or when the log-odds stop
    growing): Wald's approximation (the mean drift, no overshoot) of the JIPDA
    test a lone IPDA runs. Past :data:`STEADY_SCANS` the gain of that scan is
    used for the rest.

    Returns None for settings it does not apply to (M-of-N confirmation, no
    clutter density given, a range–bearing sensor, IMM motion, reporting
    targets); else ``{"threshold_nats", "gain_first_scan", "gain_last_scan",
    "last_scan", "expected_scans", "samples"}`` (gains in nats per scan; the last
    scan is :data:`STEADY_SCANS` or the confirmation scan if later).
    """
    if isinstance(dt, bool) or not isinstance(dt, int | float | np.floating | np.integer):
        raise ValueError(f"dt must be a number of seconds > 0, got {dt!r}")
    if not (math.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be finite and > 0, got {dt!r}")
    if not isinstance(cfg, TrackerConfig):
        return None
    if not cfg.existence or cfg.clutter_density is None or cfg.sensor != "position":
        return None
    if cfg.motion == "imm" or cfg.reporting != "scan":
        return None
    # every run from nothing writes it: one Monte Carlo per settings (0.1–0.7 s each) in a
    # process, a copy per call so that a caller's changes (the summary's "slow") stay its own
    out = _start_evidence(cfg, float(dt), int(samples), int(seed), int(max_scans))
    return dict(out)


@functools.lru_cache(maxsize=32)
def _start_evidence(cfg, dt: float, samples: int, seed: int, max_scans: int) -> dict:
    """:func:`start_evidence` of settings it applies to (cached: the settings are frozen)."""
    from jointtrack.trackers import JPDATracker
    from jointtrack.trackers.reporting import scan_detection

    trk = JPDATracker(cfg)
    _x0, P0 = trk._initial_states(np.zeros((1, cfg.dim)))
    P = P0[0]
    F, Q = trk._motion.transition(dt), trk._motion.noise(dt)
    H, R = trk._sensor.H, trk._sensor.R
    # the tracker's survival factor of a scan dt after the last (per scan or per second)
    one = np.zeros(1)
    survive = scan_detection(cfg, cfg.p_d, dt, dt, 0.0, one, one, one.astype(bool)).survival[0]
    log_ps = math.log(survive)
    ell = math.log(cfg.r_init) - math.log1p(-cfg.r_init)
    goal = math.log(cfg.r_confirm) - math.log1p(-cfg.r_confirm) if cfg.r_confirm < 1 else math.inf
    threshold = goal - ell
    gains, scans, last_s, g = [], None, None, 0.0
    for k in range(1, max_scans + 1):
        if k > 1:
            P = F @ P @ F.T + Q
            ell = _log_odds_survived(ell, log_ps)
        S = H @ P @ H.T + R
        s = math.sqrt(np.linalg.det(S))
        # past STEADY_SCANS, or once the covariance has converged (to 1e-9), the last
        # gain stands (saves the Monte Carlo; √det S then shrinks by at most a few % more:
        # 3.6 % from scan 50 to 200 on the Bojilov scene's settings, its q = 1e-4)
        if k <= STEADY_SCANS and (last_s is None or abs(s - last_s) > 1e-9 * s):
            g = _expected_log_gain(cfg, s, samples, seed)
        last_s = s
        gains.append(g)
        ell += g
        P = P - P @ H.T @ np.linalg.solve(S, H @ P)
        P = 0.5 * (P + P.T)
        if scans is None and ell >= goal:
            scans = k
        if k >= STEADY_SCANS and (scans is not None or g <= 0.0):
            break  # confirmed, or never: the log-odds no longer grow
    return {
        "threshold_nats": threshold,
        "gain_first_scan": gains[0],
        "gain_last_scan": gains[-1],
        "last_scan": len(gains),
        "expected_scans": scans,
        "samples": int(samples),
    }


def confirmation_scans(scan_times, truth: tuple, stats) -> dict:
    """Scans each target took to be confirmed: ``{target id: scans or None}``.

    A target is confirmed at the first scan at which a reported (confirmed)
    track is its GOSPA partner within the cut-off — an association of
    :func:`~jointtrack.metrics.track_statistics` ``stats`` (gate c); the count
    runs from the target's first scan in ``truth`` (``(times, ids, positions)``),
    which is scan 1, to that scan. None: no track was ever its partner.
    ``scan_times``: the run's scan times (sorted); truth and association times
    are among them.
    """
    times = np.asarray(scan_times, float)
    tt, ti = np.asarray(truth[0], float), np.asarray(truth[1])
    out = {}
    for tid in np.unique(ti).tolist():
        first = int(np.searchsorted(times, tt[ti == tid].min()))
        hit = stats.assoc_times[stats.assoc_truth_ids == tid]
        out[int(tid)] = int(np.searchsorted(times, hit.min())) - first + 1 if hit.size else None
    return out


def _version() -> str:
    from jointtrack import __version__

    return __version__


def _run_metrics(
    src,
    cfg: TrackerConfig,
    identity: dict,
    tracks: tuple,
    tracks_path: Path,
    stop: int,
    n_done: int,
    clusters: list,
    total_loop: float,
    metrics_opts: Mapping | None,
    notes: list,
    output_times=None,
) -> tuple[dict, object, tuple | None]:
    """The metrics dict of a run (without ``files`` and ``timing.total_seconds``).

    ``src``: the run's source (``jointtrack.experiments.run._Source``); ``tracks``:
    the tracks written, ``(times, ids, positions)``; ``stop``: scans processed
    from the start, ``n_done`` of them in this run; ``clusters``: ``[n_tracks,
    n_measurements, seconds]`` per multi-track cluster; ``total_loop``: the
    tracking loop's time including earlier runs; ``notes``: the run's warnings
    (the truth-start note is put first); ``output_times``: the scan times whose
    tracks the file holds, when not every scan's (a run with an output interval:
    the confirmed tracks per scan are counted at those scans only). Returns
    ``(metrics, GOSPA series or None, truth up to the last scan or None)``.
    """
    t_last = float(src.times[stop - 1]) if stop else -math.inf
    scan_times = src.times[:stop]
    metrics: dict = {
        "jointtrack_version": _version(),
        "source": identity,
        "n_scans": int(stop),
        "n_scans_this_run": int(n_done),
        "n_detections": int(sum(len(z) for z in src.scans[:stop])),
        "tracker": cfg.to_dict(),
        # in words; start_from_truth is the older boolean, kept for existing readers
        "start": "truth" if src.x0 is not None else "nothing",
        "start_from_truth": src.x0 is not None,
        "tracks_file": str(tracks_path),
    }
    time_origin = getattr(src, "time_origin", None)  # detections with ISO-8601 times
    if time_origin is not None:
        metrics["time_origin"] = time_origin
        metrics["time_unit"] = "seconds since time_origin (tracks file, plots, notes)"
    sigma = src.sigma
    mo = dict(metrics_opts or {})
    own = getattr(src, "metric_defaults", None) or {}  # the scenario's, e.g. coalescence's c = 10
    c = float(mo.get("c", own.get("c", 5.0 * sigma)))
    p = float(mo.get("p", own.get("p", 2.0)))
    gamma = float(mo.get("switch_penalty", 0.0))
    convention = str(mo.get("switch_convention", "partner"))
    series = None
    truth = None
    stats = None
    if src.truth is not None:
        from jointtrack.metrics import gospa_series, track_statistics

        tt, ti, tp = src.truth
        keep = tt <= t_last
        truth = (tt[keep], ti[keep], tp[keep])
        series = gospa_series(
            *truth, *tracks, c=c, p=p, switch_penalty=gamma, switch_convention=convention
        )
        stats = track_statistics(*truth, *tracks, gate=c)
        metrics["gospa"] = {
            "c": c,
            "p": p,
            "alpha": 2.0,
            "switch_penalty": gamma,
            "switch_convention": series.switch_convention,
            "mean": series.mean,
            "mean_localisation": float(np.mean(series.localisation)),
            "mean_missed": float(np.mean(series.missed)),
            "mean_false": float(np.mean(series.false)),
            "parts_unit": f"p-th power (m^{p:g}); gospa**p = localisation + missed + false",
            "mean_n_missed": float(np.mean(series.n_missed)),
            "mean_n_false": float(np.mean(series.n_false)),
            # half switches (assigned ↔ unassigned) exist only in Stone Soup's convention
            "n_switches": (
                int(series.switches.sum())
                if series.switch_convention == "partner"
                else float(series.switches.sum())
            ),
            "total": series.total,
        }
        metrics["ospa"] = {"c": c, "p": p, "mean": _ospa_mean(truth, tracks, scan_times, c, p)}
        # which times are scored and where the truth comes from there (see run._Source)
        metrics["scoring"] = dict(getattr(src, "scoring", None) or {})
        metrics["tracks"] = stats.as_dict()
    else:
        ids = tracks[1]
        # scans whose tracks were not written hold no rows: counting them as scans
        # without tracks would report 5 ships held all along as 0.24 per scan
        counted = scan_times if output_times is None else np.asarray(output_times, float)
        per_scan = [int(np.sum(tracks[0] == t)) for t in counted]
        metrics["tracks"] = {
            "n_tracks": int(np.unique(ids).size),
            "mean_confirmed_per_scan": float(np.mean(per_scan)) if per_scan else 0.0,
            "max_confirmed_per_scan": int(max(per_scan, default=0)),
        }
        if output_times is not None:
            metrics["tracks"]["scans_counted"] = len(per_scan)
    metrics["timing"] = {
        "clusters": _cluster_timing(clusters),
        "association_seconds": float(sum(c_[2] for c_ in clusters)),
        "loop_seconds": total_loop,
        "scans_per_second": (stop / total_loop) if total_loop > 0 and stop else None,
        "note": "clusters = multi-track clusters of confirmed tracks (single-track gates use "
        "PDA directly; tentative tracks are associated in a separate pass); "
        "loop = predict/gate/cluster/associate/update/track logic + writing tracks",
    }
    if src.x0 is not None:
        notes.insert(0, TRUTH_START_NOTE)
    else:  # from nothing (a particle run starts from the truth)
        _start_metrics(metrics, cfg, scan_times, truth, stats, c, notes)
    metrics["notes"] = notes
    return metrics, series, truth


def _start_metrics(metrics: dict, cfg, scan_times, truth, stats, c: float, notes) -> None:
    """How a run from nothing started: ``metrics["confirmation"]`` (with ``truth`` and its
    track statistics ``stats``, gate c) and ``metrics["start_evidence"]``
    (:func:`start_evidence`), a note when slow."""
    if truth is not None:
        per = confirmation_scans(scan_times, truth, stats)
        done = [v for v in per.values() if v is not None]
        never = len(per) - len(done)
        # never confirmed counts as later than any scan: the median is None past half
        ranked = sorted(done) + [math.inf] * never
        median = float(np.median(ranked)) if ranked else None
        metrics["confirmation"] = {
            "scans_per_target": {str(k): v for k, v in per.items()},
            "median": median if median is not None and math.isfinite(median) else None,
            "never": never,
            "rule": f"scans from the target's first scan (scan 1) to the first at which a "
            f"reported track is its GOSPA partner within c = {c:g}; null: never",
        }
    times = np.asarray(scan_times, float)
    dt = float(np.median(np.diff(times))) if times.size > 1 else 0.0
    evidence = start_evidence(cfg, dt) if dt > 0 else None
    if evidence is None:
        return
    n = evidence["expected_scans"]
    evidence["slow"] = n is None or n > SLOW_START_SCANS
    metrics["start_evidence"] = evidence
    if evidence["slow"]:
        expect = f"about {n} scans" if n is not None else f"more than {evidence['last_scan']} scans"
        notes.append(
            "slow start: a lone target's track gains about "
            f"{evidence['gain_first_scan']:.2f}–{evidence['gain_last_scan']:.2f} nats of "
            f"existence evidence per scan against the {evidence['threshold_nats']:.2f} nats from "
            f"r_init = {cfg.r_init:g} to r_confirm = {cfg.r_confirm:g} (P_D {cfg.p_d:g}, clutter "
            f"density {cfg.clutter_density:.3g}): {expect} to confirm, so a run from nothing "
            "misses each target for about that long (start_evidence in metrics.json)"
        )


def particle_metrics(metrics: dict, config, scans: list) -> None:
    """Make a run's metrics dict (from :func:`_run_metrics`) that of a particle-tracker run.

    ``config``: the :class:`~jointtrack.trackers.particle.ParticleConfig`;
    ``scans``: per scan ``[coefficient seconds, derivative seconds, mean ESS,
    min ESS, largest component's measurements]``. Replaces
    ``tracker``, the cluster timing and the truth-start note, and adds the
    ``particle`` section (there is no association step and no ``association``
    section).
    """
    a = np.asarray(scans, dtype=float).reshape(-1, 5)
    L = config.particles
    weight = a[:, 0] + a[:, 1]

    def stat(x) -> dict:
        if not len(x):
            return {"total": 0.0, "mean": None, "max": None}
        return {"total": float(x.sum()), "mean": float(x.mean()), "max": float(x.max())}

    metrics["tracker"] = {"kind": "particle", **config.to_dict()}
    metrics["particle"] = {
        "weights": config.weights,
        "particles": L,
        "resampling": "systematic, every scan",
        "p_g": config.p_g,
        "weight_seconds_per_scan": stat(weight),
        "coefficient_seconds_per_scan": stat(a[:, 0]),
        "derivative_seconds_per_scan": stat(a[:, 1]),
        "mean_ess_fraction": float(a[:, 2].mean() / L) if len(a) else None,
        "min_ess": float(a[:, 3].min()) if len(a) else None,
        "max_component_measurements": int(a[:, 4].max()) if len(a) else 0,
        "note": "weights = coefficients (7) + derivatives (18) of every target, per scan; "
        "ESS = 1/sum(w^2) per target before resampling (jointtrack.trackers.particle)",
    }
    tm = metrics["timing"]
    for key in ("clusters", "association_seconds"):
        tm.pop(key, None)
    tm["weight_seconds"] = float(weight.sum())
    tm["note"] = (
        "loop = predict / likelihoods / particle weights / estimates / resampling + writing tracks"
    )
    notes = metrics.get("notes", [])
    metrics["notes"] = [PARTICLE_START_NOTE if n == TRUTH_START_NOTE else n for n in notes]


# ----------------------------------------------------------------------------- summary


def _fmt(v, spec=".3g") -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "–"
    if isinstance(v, int):
        return str(v)
    return format(v, spec)


def start_description(metrics: Mapping) -> str:
    """How a run's tracks started, in words (the summary's ``start`` row).

    From ``metrics["start"]`` (or ``start_from_truth`` of older metrics), the
    scenario and the tracker's initiation settings; says when Bojilov's scenario
    was not run as the paper's experiment.
    """
    start = metrics.get("start")
    if start is None:
        start = "truth" if metrics.get("start_from_truth") else "nothing"
    if "particle" in metrics:
        return PARTICLE_START_NOTE
    source = metrics.get("source")
    bojilov = isinstance(source, Mapping) and source.get("scenario") == "bojilov"
    if start == "truth":
        if bojilov:
            return (
                "tracks started from the truth (the paper's experiment: it studies track "
                "maintenance and association, not initiation)"
            )
        return (
            "tracks started from the truth at the first scan (--start-from truth); later "
            "births are initiated from the detections"
        )
    tr = metrics.get("tracker") if isinstance(metrics.get("tracker"), Mapping) else {}
    if tr.get("kind") in ("pmb", "pmbm"):
        return (
            "tracks started from nothing (Poisson intensity of undetected targets, "
            f"{tr.get('birth_model', 'uniform')} birth; tracks reported at existence ≥ "
            f"{tr.get('r_estimate', 0.4):g}"
            + (" in the best global hypothesis)" if tr["kind"] == "pmbm" else ")")
        )
    init = tr.get("initiation", "two-point")
    if tr.get("existence", True):
        confirm = f"confirmed at JIPDA existence ≥ {tr.get('r_confirm', 0.9):g}"
    else:
        confirm = f"confirmed by {tr.get('confirm_m', 2)}-of-{tr.get('confirm_n', 3)} hits"
    tentative = tr.get("tentative_association")
    if tentative == "alternatives":
        # jointtrack.trackers.existence, point 5: what makes a target confirm at a lone IPDA's pace
        init += " initiation, tentative tracks scored as alternatives (each a lone IPDA)"
    elif tentative == "splitting":
        # jointtrack.trackers.track_splitting: each tentative track a mixture of histories
        init += (
            " initiation, tentative tracks as integrated track splitting (each a lone IPDA "
            f"of ≤ {tr.get('tentative_components', 4)} Gaussian histories)"
        )
    else:
        init += " initiation"
    text = f"tracks started from nothing ({init}, {confirm})"
    if bojilov:
        text += "; the paper's experiment starts from the truth"
    detections = isinstance(source, Mapping) and "detections" in source
    if detections and tr.get("existence", True) and tentative not in ("alternatives", "splitting"):
        # experiments.config.FROM_NOTHING_JIPDA: measured on the real-data benches
        text += (
            "; a detections run keeps the joint association of tentative tracks (as "
            "alternatives it lost coverage and purity on held-out ADS-B flights)"
        )
    return text


#: what each tracker kind is, for the summary's ``tracker`` row
KIND_NAMES = {
    "jpda": "JPDA, M-of-N confirmation",
    "jipda": "JIPDA (JPDA with existence probabilities)",
    "pmb": "PMB (track-oriented Poisson multi-Bernoulli, exact marginals)",
    "pmbm": "PMBM (Poisson multi-Bernoulli mixture, Murty's k best)",
    "particle": "particle JPDA",
}


def tracker_description(tr) -> str:
    """The summary's ``tracker`` row: the kind of tracker and its association method."""
    if not isinstance(tr, Mapping):
        return "–"
    kind = tr.get("kind")
    if kind is None:  # metrics of runs before the kind was recorded
        kind = "jipda" if tr.get("existence", True) else "jpda"
    text = f"{kind}: {KIND_NAMES.get(kind, kind)}"
    if kind == "pmbm":
        text += f", ≤ {tr.get('max_hypotheses')} global hypotheses"
    if kind in ("pmb", "pmbm"):
        lam = tr.get("clutter_density")
        text += f"; clutter density {_fmt(lam, '.4g')}"
    elif kind != "particle":
        text += f"; association {tr.get('association')}"
    return text


def tracks_line(tr: Mapping) -> str:
    """The summary's ``tracks`` row from a run's ``metrics["tracks"]`` (with a truth).

    How well the targets were followed, not only whether: coverage (the share
    of truth-scans with an associated track), breaks and identity switches
    come first, and the count of targets tracked at some scan only after
    them — a run that found every target once but followed them for half the
    scans, breaking and swapping tracks, must not read "5/5 targets tracked".
    The words are the metrics' names (``coverage``, ``n_breaks``,
    ``n_id_switches``, ``n_fragmentations``, ``n_truths_tracked``).
    """
    return (
        f"{tr['n_tracks']} confirmed ({tr['n_true_tracks']} true, {tr['n_false_tracks']} false) "
        f"for {tr['n_truths']} targets: coverage {_fmt(tr['coverage'])}, "
        f"{tr['n_breaks']} breaks, {tr['n_id_switches']} identity switches "
        f"(fragmentations {tr['n_fragmentations']}); "
        f"{tr['n_truths_tracked']}/{tr['n_truths']} targets tracked at some scan"
    )


def no_tracks_reason(metrics: Mapping) -> str:
    """The summary's note for a run that confirmed no track: that it did, and the
    likely reason from its metrics (never a silent "0 confirmed")."""
    tr = metrics.get("tracker") if isinstance(metrics.get("tracker"), Mapping) else {}
    n_scans, n_det = metrics.get("n_scans") or 0, metrics.get("n_detections") or 0
    head = "no track was confirmed"
    if not n_det:
        return f"{head}: there are no detections"
    per_scan = n_det / max(n_scans, 1)
    if tr.get("reporting", "scan") == "scan" and per_scan <= 1.5 and n_scans > 1:
        return (
            f'{head}: {per_scan:.2f} returns per scan with reporting = "scan" counts each '
            "target as missed at every other target's report; targets that report one at "
            'a time need reporting = "async" in [tracker]'
        )
    if tr.get("kind") in ("pmb", "pmbm"):
        return (
            f"{head}: no Bernoulli reached r_estimate = {tr.get('r_estimate', 0.4):g}; check "
            "that the measurement noise, speeds and clutter density fit the detections' units"
        )
    confirm = (
        f"existence ≥ r_confirm = {tr.get('r_confirm', 0.9):g}"
        if tr.get("existence", True)
        else f"{tr.get('confirm_m', 2)} hits of {tr.get('confirm_n', 3)}"
    )
    return (
        f"{head} ({confirm}): the returns did not follow a track as the model expects — "
        f"check that measurement_noise ({tr.get('measurement_noise')}), max_speed "
        f"({tr.get('max_speed')}), p_d ({tr.get('p_d')}) and clutter_density "
        f"({tr.get('clutter_density')}) fit the detections' units and rates"
    )


def summary_tables(metrics: Mapping) -> list:
    """Rich tables summarising a run's metrics dict."""
    from rich.table import Table
    from rich.text import Text

    main = Table(title="jointtrack run", show_header=False, title_justify="left")
    main.add_column("what", style="bold")
    main.add_column("value")

    def add(what: str, value: str) -> None:
        # as text, not rich markup: "[parts² mean: …]" or "[sensors]" in a value would
        # be read as a style tag and vanish
        main.add_row(Text(what), Text(value))

    source = metrics.get("source")
    truth = source.get("truth") if isinstance(source, Mapping) else None
    add("source", _describe(source) + (f"; truth {truth}" if truth else ""))
    if metrics.get("time_origin"):
        add("times", f"seconds since {metrics['time_origin']}")
    add("scans", f"{metrics['n_scans']} ({metrics['n_detections']} detections)")
    add("tracker", tracker_description(metrics.get("tracker")))
    add("start", start_description(metrics))
    conf = metrics.get("confirmation")
    if isinstance(conf, Mapping):
        per = conf["scans_per_target"]
        if len(per) <= MAX_LISTED_TARGETS:
            each = "per target " + ", ".join(
                f"{k}: {'never' if v is None else v}" for k, v in per.items()
            )
        else:  # hundreds of targets: the spread (metrics.json has each)
            done = [v for v in per.values() if v is not None]
            q = np.percentile(done, [25, 75]) if done else (None, None)
            each = (
                f"{len(per)} targets, quartiles {_fmt(q[0] and float(q[0]))}–"
                f"{_fmt(q[1] and float(q[1]))}, {conf['never']} never"
            )
        add(
            "scans to confirm",
            f"{each}; median {_fmt(conf['median'])} (first scan a reported track is the "
            "target's GOSPA partner within c, the target's first scan = 1)",
        )
    tr = metrics["tracks"]
    if "gospa" in metrics:
        g, o = metrics["gospa"], metrics["ospa"]
        add("tracks", tracks_line(tr))
        add("position RMSE", _fmt(tr["rmse"]))
        add(
            f"GOSPA mean (c={g['c']:g}, p={g['p']:g})",
            f"{_fmt(g['mean'])}  [parts² mean: localisation {_fmt(g['mean_localisation'])}, "
            f"missed {_fmt(g['mean_missed'])}, false {_fmt(g['mean_false'])}]",
        )
        add(f"OSPA mean (c={o['c']:g}, p={o['p']:g})", _fmt(o["mean"]))
    else:
        add(
            "tracks",
            f"{tr['n_tracks']} confirmed ids; {_fmt(tr['mean_confirmed_per_scan'])} per scan "
            f"(max {tr['max_confirmed_per_scan']}); no truth, so no GOSPA "
            "(score with --truth FILE)",
        )
    if tr.get("n_tracks") == 0:
        add("note", no_tracks_reason(metrics))
    tm = metrics["timing"]
    pa = metrics.get("particle")
    if pa is not None:
        add(
            "particle tracker",
            f"{pa['particles']} particles per target, {pa['weights']} weights, "
            f"resampling {pa['resampling']}; ESS {_fmt(pa['mean_ess_fraction'])} of the "
            f"particles on average (min {_fmt(pa['min_ess'])})",
        )
        w = pa["weight_seconds_per_scan"]
        add(
            "time",
            f"{_fmt(tm['loop_seconds'])} s tracking, {_fmt(tm['scans_per_second'])} scans/s "
            f"({_fmt(tm['weight_seconds'])} s in particle weights: mean "
            f"{_fmt(None if w['mean'] is None else 1e3 * w['mean'])} ms, max "
            f"{_fmt(None if w['max'] is None else 1e3 * w['max'])} ms per scan)",
        )
    else:
        add(
            "time",
            f"{_fmt(tm['loop_seconds'])} s tracking, {_fmt(tm['scans_per_second'])} scans/s "
            f"({_fmt(tm['association_seconds'])} s in multi-track association)",
        )
    add("outputs", ", ".join(Path(f).name for f in metrics.get("files", {}).values()))
    for note in metrics.get("notes", []):
        if note not in (TRUTH_START_NOTE, PARTICLE_START_NOTE):  # the start row says it
            add("note", note)
    if pa is not None:
        return [main]  # no association step, so no cluster table
    if (metrics.get("tracker") or {}).get("kind") == "pmbm":
        return [main]  # Murty's k best per cluster of tracks: no marginals timed per cluster

    cl = Table(
        title="association time per multi-track cluster of confirmed tracks",
        title_justify="left",
    )
    for name in ("tracks in cluster", "clusters", "mean meas.", "mean ms", "max ms"):
        cl.add_column(name, justify="right")
    for row in tm["clusters"]:
        cl.add_row(
            str(row["n_tracks"]),
            str(row["count"]),
            f"{row['mean_measurements']:.1f}",
            f"{1e3 * row['mean_seconds']:.3f}",
            f"{1e3 * row['max_seconds']:.3f}",
        )
    if not tm["clusters"]:
        cl.add_row("–", "0", "–", "–", "–")
    return [main, cl]


def print_summary(metrics: Mapping, console) -> None:
    """Print :func:`summary_tables` to a rich console, and the approximation fallbacks once."""
    for table in summary_tables(metrics):
        console.print(table)
    line = association_line(metrics)
    assoc = metrics.get("association") or {}
    fallbacks = assoc.get("fallbacks") or {}
    if line is None and fallbacks:  # a metrics dict without the per-kind tally
        parts = ", ".join(f"{n} ({reason})" for reason, n in fallbacks.items())
        line = (
            f"{sum(fallbacks.values())} cluster(s) solved by {assoc.get('approximation')} "
            f"instead of {assoc.get('method')}: {parts}"
        )
    if line is not None:
        console.print(
            line,
            style="yellow" if fallbacks else None,
            markup=False,
            highlight=False,
            soft_wrap=True,
        )
