"""Stone Soup's tutorial JPDA tracker end to end: ``JPDAwithEHM2`` vs jointtrack's ``JPDAExact``.

Run as ``python benchmarks/stonesoup_tracker.py [--quick] [--seed N] [--out FILE.json]``.

The tracker is Stone Soup's tutorial JPDA tracker as built by
:func:`jointtrack.bench.stonesoup_tracker.stonesoup_tracker` (``MultiTargetMixtureTracker``,
``PDAHypothesiser``, ``KalmanPredictor``/``KalmanUpdater``,
``MultiMeasurementInitiator(min_points=2)`` with ``GNNWith2DAssignment``,
``UpdateTimeStepsDeleter(3)``; the scene's σ², P_D, λ and q = max(truth q, 0.01)).
Only its data associator changes between the runs: Stone Soup's
``JPDAwithEHM2(hypothesiser)`` or :class:`jointtrack.interop.stonesoup.JPDAExact`
``(hypothesiser)``, on the *same* ``Detection`` objects.

Start: every run begins with the true targets already initiated — one Stone Soup
``Track`` per target, built from the truth at scan 0 (state interleaved to
``[x, vx, y, vy]``, covariance the steady-state updated covariance of the NCV
Kalman filter for the tracker's q and R); the scans after scan 0 are fed to
``update_tracker``. Two variants of the 8-target scene below:

* **tutorial tracker** — the initiator is kept, so clutter-born tracks (the
  tutorial's two-point ``MultiMeasurementInitiator`` confirms many at this
  clutter level) also enter the clusters;
* **initiator off** — the initiator replaced by one that starts nothing, so
  only the 8 true tracks are associated (deleter kept): association isolated.

* **Dense 8-target crossing (the "star").** 8 targets start on a circle and fly
  through the centre at 10 m/s; headings 45° apart plus an offset growing by
  2.8° per target (no two paths collinear), each passing the centre at
  t_c + δ_k with δ_k spread over ±1 s (t_c the middle of the run), so all
  eight meet within ≈ 10 m of one point; σ = 10 m, P_D = 0.9, NCV truth
  q = 0.01, Poisson clutter of 0.3 false returns per steady-state 99 % gate;
  36 scans (quick: 24). Per ``update_tracker`` call: total time, time inside
  the associator's ``associate`` and inside the hypothesiser's ``hypothesise``
  (both wrapped on the instances; ``hypothesise`` runs inside ``associate``),
  so *association proper* = associate − hypothesise (the marginals and
  building the output hypotheses) and the *rest* = step − associate
  (updater, Gaussian-mixture reduction, deleter, initiator with its own GNN
  hypothesiser). Runs alternate EHM2, ours, EHM2, ours (2 repeats; quick 1,
  after one untimed warm-up run of ours); per step the repeat with the
  smallest step time is kept with its parts. Median and total per quantity,
  shares of the step time, and the ratios EHM2 / ours; a per-step table in
  the full run. Largest cluster from ``JPDAExact.last_clusters``.
  A third configuration swaps Stone Soup's ``PDAHypothesiser`` (of the
  associator and of the initiator's GNN) for jointtrack's
  ``FastPDAHypothesiser`` (same hypotheses, detections taken at once) with
  ``JPDAExact``: its own table, total time per part and the ratio EHM2 / it.
  The runs' tracks are compared after every step: same number, and state
  vectors equal to 1e-9·max(1, |x|) after matching the tracks (minimum-cost
  assignment on the state distance: the clutter-born tracks have random ids).
  EHM2's runs have a time budget (120 s; quick 20 s).
* **20 targets in one dense cluster.** The same star with 20 targets meeting
  at t = 2 s (headings 18° apart, δ_k over ±0.3 s), 4 scans, the tutorial
  tracker (initiator kept): from the truth at scan 0, the three steps around
  the meeting put all 20 tracks in one cluster, each track gating most of the
  cluster's detections. ``JPDAExact`` is timed per
  step (3 runs, the fastest per step; quick 1; its cluster method must be
  "exact", at the default ``max_bits=22``); ``JPDAwithEHM2`` runs under a
  budget (60 s; quick 10 s). On the first step (identical start for
  everyone) Stone Soup's ``JPDAwithLBP`` and jointtrack's ``JPDALBP`` are
  timed too, association proper as above, with max |Δβ| against
  ``JPDAExact``'s β.

Printed: the tables, Stone Soup's version and the load average before and after.
With ``--out FILE.json`` the results are also written as JSON and the per-step
times of the crossing are plotted to ``FILE.png``.
"""

from __future__ import annotations

import argparse
import datetime
import gc
import json
import math
import os
import time

import numpy as np
from rich.table import Table
from scipy.optimize import linear_sum_assignment

from jointtrack._console import make_console
from jointtrack._provenance import machine_info
from jointtrack.bench.stonesoup_tracker import EPOCH, _OutOfTime, _time_limit, stonesoup_tracker
from jointtrack.bench.tracking_runs import MIN_TRACKER_Q, P_G, tracker_gate_area, tracker_q
from jointtrack.experiments.config import steady_state_covariance
from jointtrack.io import to_jsonable
from jointtrack.scenarios import nominal_gate, propagate_ncv, simulate_scenario

SS_ORDER = [0, 2, 1, 3]  # Stone Soup's [x, vx, y, vy] from jointtrack's [x, y, vx, vy]
STATE_TOL = 1e-9


# ------------------------------------------------------------------ scene
def star(
    n_targets: int,
    seed: int,
    *,
    n_scans: int,
    t_cross: float,
    stagger: float,
    speed: float = 10.0,
    sigma: float = 10.0,
    process_noise: float = 0.01,
    p_d: float = 0.9,
    clutter_per_gate: float = 0.3,
    margin: float = 100.0,
    dt: float = 1.0,
):
    """``n_targets`` flying through the origin from a circle (module docstring)."""
    k = np.arange(n_targets)
    heading = 2 * np.pi * k / n_targets + (np.pi / n_targets) * k / n_targets
    delta = stagger * (2 * k / max(n_targets - 1, 1) - 1)
    rng = np.random.default_rng(seed)
    delta = rng.permutation(delta)  # which heading meets early: seeded, not by angle
    vel = speed * np.column_stack([np.cos(heading), np.sin(heading)])
    x0 = np.concatenate([-vel * (t_cross + delta)[:, None], vel], axis=1)
    traj = propagate_ncv(x0, n_scans, dt, process_noise, rng)
    ext = speed * max(t_cross + stagger, (n_scans - 1) * dt - t_cross + stagger) + margin
    region = np.array([[-ext, ext], [-ext, ext]])
    ids = np.arange(n_targets, dtype=np.int64)
    kw = dict(
        region=region,
        p_d=p_d,
        R=sigma**2 * np.eye(2),
        process_noise=process_noise,
        info={"t_cross": t_cross, "stagger": stagger, "speed": speed, "sigma": sigma},
        seed=seed,
        dt=dt,
    )
    # clutter rate from the steady-state 99 % gate of the tracker's q (tracker_gate_area)
    gate = nominal_gate(dt, max(process_noise, MIN_TRACKER_Q), sigma, P_G)["volume"]
    rate = clutter_per_gate * (2 * ext) ** 2 / gate
    times = dt * np.arange(n_scans)
    return simulate_scenario(
        "star", times, [ids] * n_scans, list(traj), clutter_rate=rate, rng=rng, **kw
    )


# ------------------------------------------------------------------ Stone Soup plumbing
def stone_soup_scans(sc, mm):
    """Timestamps and one set of Stone Soup ``Detection`` s per scan (shared by every run)."""
    from stonesoup.types.detection import Detection

    stamps = [EPOCH + datetime.timedelta(seconds=float(t)) for t in sc.times]
    scans = [
        {Detection(z.reshape(-1, 1), timestamp=ts, measurement_model=mm) for z in Z}
        for ts, Z in zip(stamps, sc.detections, strict=True)
    ]
    return stamps, scans


def truth_tracks(sc, stamps) -> set:
    """One Stone Soup ``Track`` per target, from the truth at scan 0 (module docstring)."""
    from stonesoup.types.state import GaussianState
    from stonesoup.types.track import Track

    P = steady_state_covariance(sc.dt, tracker_q(sc), sc.R)[np.ix_(SS_ORDER, SS_ORDER)]
    return {
        Track([GaussianState(x[SS_ORDER].reshape(-1, 1), P, timestamp=stamps[0])], id=f"truth-{i}")
        for i, x in zip(sc.truth_ids[0].tolist(), sc.truth_states[0], strict=True)
    }


class Stopwatch:
    """Accumulates the time spent in one method of one object (wrapped on the instance)."""

    def __init__(self, obj, name: str):
        self.seconds = 0.0
        inner = getattr(obj, name)

        def timed(*args, **kwargs):
            t0 = time.perf_counter()
            try:
                return inner(*args, **kwargs)
            finally:
                self.seconds += time.perf_counter() - t0

        setattr(obj, name, timed)  # an instance attribute shadows the class's method

    def take(self) -> float:
        s, self.seconds = self.seconds, 0.0
        return s


def associator_factory(name: str, **options):
    from stonesoup.dataassociator.probability import JPDAwithEHM2, JPDAwithLBP

    from jointtrack.interop.stonesoup import JPDALBP, JPDAExact

    cls = {"ehm2": JPDAwithEHM2, "ours": JPDAExact, "ss-lbp": JPDAwithLBP, "our-lbp": JPDALBP}
    return lambda hypothesiser: cls[name](hypothesiser, **options)


def _no_initiator():
    """A Stone Soup ``Initiator`` that starts no track (the "initiator off" variant)."""
    from stonesoup.initiator.base import Initiator

    class NoInitiator(Initiator):
        def initiate(self, detections, timestamp, **kwargs):
            return set()

    return NoInitiator()


def run_tracker(
    sc,
    name: str,
    stamps,
    scans,
    *,
    budget=None,
    options=None,
    steps=None,
    initiator=True,
    fast_hypothesiser=False,
) -> dict:
    """Stone Soup's tutorial tracker with associator ``name`` from the true tracks at scan 0.

    Times every ``update_tracker`` call (scans 1…, or ``steps`` of them) and the
    associator's and hypothesiser's share of it; records each step's tracks and
    (for jointtrack's associators) clusters. ``initiator=False`` replaces the
    tutorial initiator by one that starts nothing. With ``budget`` seconds the
    run stops there (``finished`` False). ``fast_hypothesiser``: jointtrack's
    ``FastPDAHypothesiser`` instead of Stone Soup's ``PDAHypothesiser``.
    """
    from jointtrack.interop.stonesoup import FastPDAHypothesiser

    tracker, _ = stonesoup_tracker(
        sc,
        associator_factory(name, **(options or {})),
        hypothesiser_class=FastPDAHypothesiser if fast_hypothesiser else None,
    )
    if not initiator:
        tracker.initiator = _no_initiator()
    assoc = tracker.data_associator
    tracker.tracks.update(truth_tracks(sc, stamps))
    w_assoc = Stopwatch(assoc, "associate")
    w_hyp = Stopwatch(assoc.hypothesiser, "hypothesise")
    last = sc.n_scans if steps is None else 1 + steps
    keys = ("step", "associate", "hypothesise", "tracks", "clusters")
    rec = {key: [] for key in keys}
    finished = True
    gc.collect()  # the previous run's garbage is not collected inside this one's steps
    t_run = time.perf_counter()
    try:
        with _time_limit(budget):
            for k in range(1, last):
                t0 = time.perf_counter()
                _, tracks = tracker.update_tracker(stamps[k], scans[k])
                step = time.perf_counter() - t0
                rec["step"].append(step)
                rec["associate"].append(w_assoc.take())
                rec["hypothesise"].append(w_hyp.take())
                rec["tracks"].append(
                    [(str(t.id), np.asarray(t.state_vector, float).ravel()) for t in tracks]
                )
                rec["clusters"].append(list(getattr(assoc, "last_clusters", [])))
    except _OutOfTime:
        finished = False
        done = min(len(rec[key]) for key in keys)  # drop a step the alarm cut mid-record
        rec = {key: rec[key][:done] for key in keys}
    rec["finished"] = finished
    rec["seconds"] = time.perf_counter() - t_run
    rec["budget"] = budget
    return rec


def best_of(runs: list[dict]) -> dict:
    """Per step, the repeat with the smallest step time (its parts with it), over the steps
    every repeat completed."""
    n = min(len(r["step"]) for r in runs)
    out = {key: [] for key in ("step", "associate", "hypothesise", "tracks", "clusters")}
    for k in range(n):
        r = min(runs, key=lambda r: r["step"][k])
        for key in out:
            out[key].append(r[key][k])
    out["finished"] = all(r["finished"] for r in runs)
    out["seconds"] = max(r["seconds"] for r in runs)
    return out


def compare_tracks(a: dict, b: dict) -> dict:
    """Per common step: same number of tracks, max state difference after matching."""
    n_steps = min(len(a["tracks"]), len(b["tracks"]))
    counts_equal, worst_abs, worst_rel, first_bad = True, 0.0, 0.0, None
    for k in range(n_steps):
        ta, tb = a["tracks"][k], b["tracks"][k]
        if len(ta) != len(tb):
            counts_equal = False
            first_bad = k + 1 if first_bad is None else first_bad
            continue
        if not ta:
            continue
        xa = np.array([x for _, x in ta])
        xb = np.array([x for _, x in tb])
        cost = np.abs(xa[:, None, :] - xb[None, :, :]).max(axis=2)
        r, c = linear_sum_assignment(cost)
        d = np.abs(xa[r] - xb[c])
        rel = d / np.maximum(1.0, np.abs(xa[r]))
        worst_abs = max(worst_abs, float(d.max()))
        worst_rel = max(worst_rel, float(rel.max()))
        if rel.max() > STATE_TOL and first_bad is None:
            first_bad = k + 1
    return {
        "steps_compared": n_steps,
        "track_counts_equal": counts_equal,
        "max_abs_state_diff": worst_abs,
        "max_rel_state_diff": worst_rel,
        "same": counts_equal and worst_rel <= STATE_TOL,
        "first_differing_step": first_bad,
    }


def summary(rec: dict) -> dict:
    step = np.array(rec["step"])
    assoc = np.array(rec["associate"])
    hyp = np.array(rec["hypothesise"])
    proper = assoc - hyp
    rest = step - assoc
    out = {"steps": len(step), "finished": rec["finished"]}
    for key, v in (("step", step), ("association", proper), ("hypothesiser", hyp), ("rest", rest)):
        out[key] = {
            "median_ms": 1e3 * float(np.median(v)) if v.size else math.nan,
            "max_ms": 1e3 * float(v.max()) if v.size else math.nan,
            "total_s": float(v.sum()),
        }
    total = float(step.sum())
    out["association_share"] = float(proper.sum()) / total if total else math.nan
    out["hypothesiser_share"] = float(hyp.sum()) / total if total else math.nan
    return out


def largest_cluster(rec: dict):
    """(tracks, detections, method, step) of the largest cluster in a jointtrack run."""
    best = (0, 0, "", 0)
    methods = set()
    for k, cls in enumerate(rec["clusters"]):
        for n, m, method, _reason in cls:
            methods.add(method)
            if (n, m) > best[:2]:
                best = (n, m, method, k + 1)
    return best, sorted(methods)


def _fmt_ms(x):
    return "–" if x is None or not math.isfinite(x) else f"{x:.2f}"


def _ratio(a, b):
    return a / b if b > 0 and math.isfinite(a) else math.nan


# ------------------------------------------------------------------ sections
def _crossing_variant(console, sc, stamps, scans, *, initiator, quick, repeats, label) -> dict:
    budget = 20.0 if quick else 120.0
    runs = {"ehm2": [], "ours": [], "fast": []}
    for rep in range(repeats):
        console.print(f"   {label}: JPDAExact + FastPDAHypothesiser (repeat {rep + 1}/{repeats}) …")
        runs["fast"].append(
            run_tracker(sc, "ours", stamps, scans, initiator=initiator, fast_hypothesiser=True)
        )
        for name in ("ehm2", "ours"):
            if runs["ehm2"] and not runs["ehm2"][-1]["finished"] and name == "ehm2":
                continue  # EHM2 ran out of time once: do not spend the budget again
            console.print(
                f"   {label}: {'Stone Soup JPDAwithEHM2' if name == 'ehm2' else 'JPDAExact'}"
                f" (repeat {rep + 1}/{repeats}"
                + (f", budget {budget:.0f} s)" if name == "ehm2" else ")")
                + " …"
            )
            kw = {"budget": budget} if name == "ehm2" else {}
            runs[name].append(run_tracker(sc, name, stamps, scans, initiator=initiator, **kw))
    same = [compare_tracks(e, o) for e in runs["ehm2"] for o in runs["ours"]]
    same += [compare_tracks(runs["ours"][0], o) for o in runs["ours"][1:] + runs["fast"]]
    worst_same = max(same, key=lambda s: (not s["same"], s["max_rel_state_diff"]))
    ehm2, ours = best_of(runs["ehm2"]), best_of(runs["ours"])
    (cn, cm, cmethod, cstep), methods = largest_cluster(ours)
    s_e, s_o = summary(ehm2), summary(ours)
    n_det = [len(s) for s in scans[1:]]

    t = Table(
        title=f"8-target crossing, {label}: {s_o['steps']} steps, "
        f"per step the fastest of {repeats} repeat(s)"
    )
    cols = ("per step", "EHM2 median ms", "ours median ms", "ratio", "EHM2 total s")
    for col in (*cols, "ours total s", "ratio", "EHM2 share", "ours share"):
        t.add_column(col, justify="right" if col != "per step" else "left")
    rows = {}
    for key in ("step", "association", "hypothesiser", "rest"):
        e, o = s_e[key], s_o[key]
        share_e = e["total_s"] / s_e["step"]["total_s"] if s_e["step"]["total_s"] else math.nan
        share_o = o["total_s"] / s_o["step"]["total_s"]
        rows[key] = {
            "ratio_median": _ratio(e["median_ms"], o["median_ms"]),
            "ratio_total": _ratio(e["total_s"], o["total_s"]),
            "share_ehm2": share_e,
            "share_ours": share_o,
        }
        t.add_row(
            key if key != "association" else "association proper",
            _fmt_ms(e["median_ms"]),
            _fmt_ms(o["median_ms"]),
            f"{rows[key]['ratio_median']:.1f}×",
            f"{e['total_s']:.3f}",
            f"{o['total_s']:.3f}",
            f"{rows[key]['ratio_total']:.1f}×",
            f"{100 * share_e:.0f} %",
            f"{100 * share_o:.0f} %",
        )
    console.print(t)
    fast = best_of(runs["fast"])
    s_f = summary(fast)
    t = Table(title=f"{label}: both with jointtrack's FastPDAHypothesiser in place of Stone Soup's")
    for col in ("per step", "ours + fast hyp. median ms", "total s", "EHM2 total / this"):
        t.add_column(col, justify="right" if col != "per step" else "left")
    fast_rows = {}
    for key in ("step", "association", "hypothesiser", "rest"):
        f = s_f[key]
        fast_rows[key] = {"ratio_total_vs_ehm2": _ratio(s_e[key]["total_s"], f["total_s"])}
        t.add_row(
            key if key != "association" else "association proper",
            _fmt_ms(f["median_ms"]),
            f"{f['total_s']:.3f}",
            f"{fast_rows[key]['ratio_total_vs_ehm2']:.1f}×",
        )
    console.print(t)
    n_common = min(len(ehm2["step"]), len(ours["step"]))
    proper_e = [ehm2["associate"][k] - ehm2["hypothesise"][k] for k in range(n_common)]
    proper_o = [ours["associate"][k] - ours["hypothesise"][k] for k in range(n_common)]
    if n_common:
        worst = int(np.argmax(proper_e))
        console.print(
            f"   largest cluster (JPDAExact.last_clusters): {cn} tracks × {cm} detections at "
            f"step {cstep} ({cmethod}); methods used: {', '.join(methods)}; EHM2's slowest "
            f"association: step {worst + 1}, {1e3 * proper_e[worst]:.1f} ms vs ours "
            f"{1e3 * proper_o[worst]:.2f} ms ({_ratio(proper_e[worst], proper_o[worst]):.0f}×)",
            highlight=False,
        )
    if not ehm2["finished"]:
        console.print(
            f"   [red]EHM2 did not finish within {budget:.0f} s[/] "
            f"({len(ehm2['step'])} of {sc.n_scans - 1} steps); the table covers those steps"
        )
    n_tr = [len(x) for x in ours["tracks"]]
    console.print(
        f"   same tracks in all runs: {'YES' if worst_same['same'] else 'NO'} "
        f"(track counts equal: {worst_same['track_counts_equal']}, max |Δx| "
        f"{worst_same['max_abs_state_diff']:.2e}, relative {worst_same['max_rel_state_diff']:.2e}, "
        f"{worst_same['steps_compared']} steps); tracks per step {min(n_tr)}–{max(n_tr)}",
        highlight=False,
    )
    per_step = [
        {
            "step": k + 1,
            "n_detections": n_det[k],
            "n_tracks": len(ours["tracks"][k]),
            "n_truth_tracks": sum(i.startswith("truth-") for i, _ in ours["tracks"][k]),
            "largest_cluster": max((c[:2] for c in ours["clusters"][k]), default=(0, 0)),
            "ehm2_ms": [1e3 * ehm2[q][k] for q in ("step", "associate", "hypothesise")]
            if k < len(ehm2["step"])
            else None,
            "ours_ms": [1e3 * ours[q][k] for q in ("step", "associate", "hypothesise")],
        }
        for k in range(len(ours["step"]))
    ]
    t = Table(title=f"{label}, per step (association proper = associate − hypothesise)")
    cols = ("step", "detections", "tracks (from truth)", "largest cluster", "EHM2 assoc. ms")
    for col in (*cols, "ours assoc. ms", "ratio", "EHM2 step ms", "ours step ms"):
        t.add_column(col, justify="right")
    for r in per_step:
        o = r["ours_ms"]
        e = r["ehm2_ms"]
        pe, po = (e[1] - e[2] if e else math.nan), o[1] - o[2]
        t.add_row(
            str(r["step"]),
            str(r["n_detections"]),
            f"{r['n_tracks']} ({r['n_truth_tracks']})",
            "{} × {}".format(*r["largest_cluster"]),
            _fmt_ms(pe),
            _fmt_ms(po),
            f"{_ratio(pe, po):.1f}×",
            _fmt_ms(e[0] if e else math.nan),
            _fmt_ms(o[0]),
        )
    if not quick:
        console.print(t)
    return {
        "initiator": initiator,
        "repeats": repeats,
        "ehm2": s_e,
        "ours": s_o,
        "ratios": rows,
        "ours_fast_hypothesiser": s_f,
        "ratios_fast_hypothesiser": fast_rows,
        "ehm2_budget_s": budget,
        "ehm2_finished": ehm2["finished"],
        "largest_cluster": {"tracks": cn, "detections": cm, "method": cmethod, "step": cstep},
        "methods": methods,
        "same_tracks": worst_same,
        "per_step": per_step,
    }


def dense_crossing(console, quick: bool, seed: int, results: dict) -> None:
    n_scans = 24 if quick else 36
    sc = star(8, seed, n_scans=n_scans, t_cross=(n_scans - 1) / 2, stagger=1.0)
    _, mm = stonesoup_tracker(sc)
    stamps, scans = stone_soup_scans(sc, mm)
    n_det = [len(s) for s in scans[1:]]
    console.print(
        f"[bold]1. dense 8-target crossing[/]: {sc.n_scans} scans, seed {seed}, "
        f"{sc.clutter_rate:.1f} clutter/scan (λ = {sc.clutter_density:.3g} m⁻², "
        f"{sc.clutter_density * tracker_gate_area(sc):.2f} per gate), "
        f"{min(n_det)}–{max(n_det)} detections/scan"
    )
    console.print("   warm-up: JPDAExact run, untimed …")
    run_tracker(sc, "ours", stamps, scans)
    repeats = 1 if quick else 2
    variants = {}
    for initiator, label in ((True, "tutorial tracker"), (False, "initiator off")):
        variants["initiator" if initiator else "no_initiator"] = _crossing_variant(
            console,
            sc,
            stamps,
            scans,
            initiator=initiator,
            quick=quick,
            repeats=repeats,
            label=label,
        )
    results["dense_crossing"] = {
        "scene": {
            "n_targets": 8,
            "n_scans": sc.n_scans,
            "seed": seed,
            "clutter_rate": sc.clutter_rate,
            "clutter_density": sc.clutter_density,
            "clutter_per_gate": sc.clutter_density * tracker_gate_area(sc),
            "p_d": sc.p_d,
            "sigma": float(np.sqrt(sc.R[0, 0])),
            "info": dict(sc.info),
        },
        **variants,
    }


def _betas(out: dict) -> dict:
    """{(track id, detection or None): β} of an associator's output."""
    return {
        (str(trk.id), h.measurement if h else None): float(h.probability)
        for trk, mh in out.items()
        for h in mh
    }


def twenty_targets(console, quick: bool, seed: int, results: dict) -> None:
    sc = star(20, seed, n_scans=4, t_cross=2.0, stagger=0.3)
    _, mm = stonesoup_tracker(sc)
    stamps, scans = stone_soup_scans(sc, mm)
    console.print(
        f"[bold]2. 20 targets in one dense cluster[/]: steps 1–{sc.n_scans - 1}, seed {seed}, "
        f"{[len(s) for s in scans[1:]]} detections per step"
    )
    options = {}  # JPDAExact's defaults (max_bits=22) solve these clusters exactly
    console.print("   warm-up: JPDAExact, one step untimed …")
    run_tracker(sc, "ours", stamps, scans, steps=1, options=options)
    repeats = 1 if quick else 3
    console.print(f"   JPDAExact, {repeats} run(s) …")
    ours = best_of(
        [run_tracker(sc, "ours", stamps, scans, options=options) for _ in range(repeats)]
    )
    (cn, cm, cmethod, cstep), methods = largest_cluster(ours)
    if not set(methods) <= {"exact", "pda"}:  # "pda": one-track clusters, exact too
        raise RuntimeError(f"JPDAExact used {methods} on the 20-target scene, not exact only")
    budget = 10.0 if quick else 60.0
    console.print(f"   Stone Soup JPDAwithEHM2 (budget {budget:.0f} s) …")
    ehm2 = run_tracker(sc, "ehm2", stamps, scans, budget=budget)
    same = compare_tracks(ehm2, ours)

    t = Table(
        title="20 targets: per step, Stone Soup's tutorial tracker "
        f"(ours: the fastest of {repeats} run(s))"
    )
    for col in (
        "step",
        "detections",
        "largest cluster (ours)",
        "ours step ms",
        "ours association ms",
        "ours hypothesiser ms",
        "EHM2 step",
    ):
        t.add_column(col, justify="right")
    steps = []
    for k in range(len(ours["step"])):
        big = max(ours["clusters"][k])
        e = (
            f"{1e3 * ehm2['step'][k]:.1f} ms"
            if k < len(ehm2["step"])
            else (f"did not finish within {budget:.0f} s" if k == len(ehm2["step"]) else "–")
        )
        t.add_row(
            str(k + 1),
            str(len(scans[k + 1])),
            f"{big[0]} × {big[1]} ({big[2]})",
            f"{1e3 * ours['step'][k]:.1f}",
            f"{1e3 * (ours['associate'][k] - ours['hypothesise'][k]):.1f}",
            f"{1e3 * ours['hypothesise'][k]:.1f}",
            e,
        )
        steps.append(
            {
                "step": k + 1,
                "n_detections": len(scans[k + 1]),
                "largest_cluster": list(big),
                "ours_ms": [1e3 * ours[q][k] for q in ("step", "associate", "hypothesise")],
                "ehm2_ms": [1e3 * ehm2[q][k] for q in ("step", "associate", "hypothesise")]
                if k < len(ehm2["step"])
                else None,
            }
        )
    console.print(t)
    if ehm2["finished"]:
        console.print(
            f"   EHM2 finished all steps in {ehm2['seconds']:.1f} s; same tracks: {same['same']}"
        )
    else:
        console.print(
            f"   [red]JPDAwithEHM2 did not finish within {budget:.0f} s[/] "
            f"({len(ehm2['step'])} steps done)"
        )

    # LBPs on step 1 (identical start for everyone) against JPDAExact's β
    console.print("   step 1: JPDAExact vs JPDALBP vs Stone Soup JPDAwithLBP …")
    lbp_rows = {}
    exact_beta = None
    for name in ("ours", "our-lbp", "ss-lbp"):
        tracker, _ = stonesoup_tracker(sc, associator_factory(name))
        assoc = tracker.data_associator
        tracks = truth_tracks(sc, stamps)
        assoc.associate(tracks, scans[1], stamps[1])  # warm-up
        w_assoc = Stopwatch(assoc, "associate")
        w_hyp = Stopwatch(assoc.hypothesiser, "hypothesise")
        times = []
        for _ in range(1 if quick else 3):
            out = assoc.associate(tracks, scans[1], stamps[1])
            times.append(w_assoc.take() - w_hyp.take())
        beta = _betas(out)
        if name == "ours":
            exact_beta = beta
            err = 0.0
        else:
            assert beta.keys() == exact_beta.keys()
            err = max(abs(beta[key] - exact_beta[key]) for key in beta)
        lbp_rows[name] = {
            "association_ms": 1e3 * min(times),
            "max_abs_beta_error": err,
            "clusters": list(getattr(assoc, "last_clusters", [])),
        }
    t2 = Table(title="20 targets, step 1: association proper (best of runs), β vs exact")
    for col in ("associator", "ms", "max |Δβ| vs JPDAExact"):
        t2.add_column(col, justify="right" if col != "associator" else "left")
    labels = {
        "ours": "jointtrack JPDAExact",
        "our-lbp": "jointtrack JPDALBP",
        "ss-lbp": "Stone Soup JPDAwithLBP",
    }
    for name, r in lbp_rows.items():
        t2.add_row(labels[name], f"{r['association_ms']:.2f}", f"{r['max_abs_beta_error']:.2e}")
    console.print(t2)
    results["twenty_targets"] = {
        "scene": {
            "n_targets": 20,
            "n_scans": sc.n_scans,
            "seed": seed,
            "clutter_rate": sc.clutter_rate,
            "info": dict(sc.info),
        },
        "ours": summary(ours),
        "largest_cluster": {"tracks": cn, "detections": cm, "method": cmethod, "step": cstep},
        "options": options,
        "repeats": repeats,
        "ehm2": summary(ehm2) | {"budget_s": budget, "seconds": ehm2["seconds"]},
        "same_tracks_on_common_steps": same,
        "per_step": steps,
        "step1": lbp_rows,
    }


def plot(results: dict, path: str) -> None:
    """Per-step times of the 8-target crossing (both variants), EHM2 vs ours, as a PNG.

    Top row: association proper (associate − hypothesise), log scale; bottom row:
    the whole ``update_tracker`` step split into association proper, hypothesiser
    and rest, for each associator.
    """
    from jointtrack.experiments.plots import plt, save_figure  # the Agg backend

    variants = [
        (key, title)
        for key, title in (("initiator", "tutorial tracker"), ("no_initiator", "initiator off"))
        if key in results["dense_crossing"]
    ]
    fig, axes = plt.subplots(2, len(variants), figsize=(6.5 * len(variants), 7), squeeze=False)
    for col, (key, title) in enumerate(variants):
        rows = results["dense_crossing"][key]["per_step"]
        steps = np.array([r["step"] for r in rows])
        for name, field, colour in (
            ("EHM2", "ehm2_ms", "tab:red"),
            ("ours", "ours_ms", "tab:blue"),
        ):
            ms = np.array([r[field] for r in rows], dtype=float)  # step, associate, hypothesise
            proper = ms[:, 1] - ms[:, 2]
            axes[0, col].semilogy(steps, proper, "o-", ms=3, color=colour, label=name)
            rest = ms[:, 0] - ms[:, 1]
            offset = -0.2 if name == "EHM2" else 0.2
            bottom = np.zeros_like(proper)
            for part, alpha, label in (
                (proper, 1.0, "association"),
                (ms[:, 2], 0.55, "hypothesiser"),
                (rest, 0.25, "rest"),
            ):
                axes[1, col].bar(
                    steps + offset,
                    part,
                    0.4,
                    bottom=bottom,
                    color=colour,
                    alpha=alpha,
                    label=f"{name}: {label}",
                )
                bottom = bottom + part
        axes[0, col].set_title(f"8-target crossing, {title}: association proper")
        axes[0, col].set_ylabel("ms per step")
        axes[0, col].legend()
        axes[0, col].grid(alpha=0.3, which="both")
        axes[1, col].set_title("whole step (left bar EHM2, right bar ours)")
        axes[1, col].set_xlabel("step")
        axes[1, col].set_ylabel("ms per step")
        axes[1, col].legend(fontsize=7, ncol=2)
        axes[1, col].grid(alpha=0.3, axis="y")
    fig.tight_layout()
    save_figure(fig, path, dpi=110)


def run(quick: bool = False, seed: int = 0, out: str | None = None) -> dict:
    import stonesoup

    console = make_console()
    load0 = os.getloadavg()
    console.print(
        f"Stone Soup {stonesoup.__version__}; load average {load0[0]:.2f} {load0[1]:.2f} "
        f"{load0[2]:.2f}; {'quick' if quick else 'full'} run",
        highlight=False,
    )
    results: dict = {
        "quick": quick,
        "seed": seed,
        "stonesoup": stonesoup.__version__,
        "machine": machine_info(),
        "load_before": load0,
    }
    t0 = time.perf_counter()
    dense_crossing(console, quick, seed, results)
    twenty_targets(console, quick, seed, results)
    results["seconds"] = time.perf_counter() - t0
    results["load_after"] = os.getloadavg()
    console.print(
        f"total {results['seconds']:.0f} s; load average after "
        f"{' '.join(f'{x:.2f}' for x in results['load_after'])}",
        highlight=False,
    )
    if out:
        with open(out, "w", encoding="utf-8") as fh:
            json.dump(to_jsonable(results, fallback=str), fh, indent=2)
        png = os.path.splitext(out)[0] + ".png"
        plot(results, png)
        console.print(f"results: {out}, plot: {png}", markup=False, highlight=False)
    return results


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="fewer scans, shorter budgets")
    parser.add_argument("--seed", type=int, default=0, help="scene seed (default 0)")
    parser.add_argument("--out", help="also write the results as JSON to this file")
    args = parser.parse_args()
    if args.seed < 0:
        parser.error("--seed must be ≥ 0")
    run(quick=args.quick, seed=args.seed, out=args.out)
