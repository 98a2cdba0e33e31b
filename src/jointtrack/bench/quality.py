"""Tracking quality from nothing, beside Stone Soup's tutorial JPDA tracker on the same detections.

Run as ``jointtrack bench quality [--quick] [--out FILE]`` or
``python benchmarks/quality.py``. Stone Soup is optional (the ``bench`` extra,
``stonesoup==1.9.1``); without it the benchmark says "not installed" and
reports jointtrack alone.

Scenes (seeded; every tracker starts with no tracks)
-----------------------------------------------------
Seeds 0, 1, 2 (quick: seed 0, and about half the scans). The metric cut-off c
(GOSPA c = association gate of the track statistics) is 3σ of the scene's
measurement noise — a 2-D estimate with per-axis error σ lies beyond it 1.1 %
of the time, so normal estimation error is not counted as a lost target and a
false track — but at most half the spacing of targets that move in lanes, so
a track between two lanes counts for neither (abreast: c = 10 = 2σ). Bojilov's
lanes are 2σ apart, below any gate that accepts normal error; there c = 2σ.
"False returns per gate" below is λ·V_G, V_G the steady-state 99 % gate
area of an NCV filter with the *tracker's* q and the scene's σ
(:func:`jointtrack.scenarios.nominal_gate`).

* **abreast** — :func:`scenarios.abreast` as issue 11 gives it: 5 targets 20
  apart abreast at 1 unit/s, σ = 5, P_D = 0.9, 60 clutter/scan, 80 scans
  (quick 40); ≈ 0.3 false returns per gate; c = 10.
* **crossing** — :func:`scenarios.crossing`: two targets crossing at 45°,
  10 m/s, σ = 10, P_D = 0.9, 61 scans (quick 41); clutter chosen as
  ``CROSSING_BETA`` = 0.3 false returns per gate (≈ 29 clutter/scan over the
  scene's region), the density of issue 11's scene; c = 30.
* **births** — :func:`scenarios.many_targets`: 20 targets at the start on a
  2 × 2 km square, 5–25 m/s, σ = 10, P_D = 0.95, q = 0.1, survival 0.995
  per scan and 0.2 births per scan (plus targets leaving the square), 60
  scans (quick 40); moderate clutter, ``BIRTHS_BETA`` = 0.1 false returns
  per gate; c = 30. Each death costs any tracker at least one scan of a
  coasting track that no truth explains, so deaths per scan (≈ 0.2 here)
  are a floor under the false tracks per scan.
* **heavy clutter** — :func:`scenarios.bojilov` with β = 1: Bojilov's five
  targets on lanes 20 m apart drifting into one cluster, σ = 10, P_D = 0.9,
  81 scans (quick 41), exactly one false return per nominal 99 % gate of the
  truth's q (≈ 1.1 per gate of the tracker's larger q); c = 20.
* **coalescence** — :func:`scenarios.coalescence`: Williams' four targets that
  meet at the midpoint (one dies there), σ = 1, P_D = 0.9, Poisson(10) clutter
  on [0, 300]², 81 scans (quick 21); c = 10, the GOSPA cut-off of
  García-Fernández et al. (2018), whose PMBM set-up the scene mirrors.

Trackers ("configurations")
---------------------------
jointtrack's settings come only from the scene's physics
(:func:`physical_config`): measurement_noise = σ², p_d = P_D,
clutter_density = λ, process_noise q = max(truth q, 0.01) (a floor, not a
per-scene tuning: three scenes simulate almost straight-line truth with
q = 10⁻⁴, and a tracker is not told its targets are that benign),
max_speed = 1.5 × the fastest true speed, p_g = 0.99; everything else is
``TrackerConfig``'s default.
:data:`CONFIGURATIONS` lists (name, overrides) — add entries to compare more.

The PMB and PMBM trackers (:data:`POISSON_CONFIGURATIONS`,
:mod:`jointtrack.trackers.pmbm`) share those settings (P_G is their own 0.9999:
their weights have no gate factor) with the birth model ``jointtrack run --tracker
pmbm`` derives (:func:`jointtrack.bench.tracking_runs.poisson_config`): the paper's
Gaussian birth and prior on coalescence; elsewhere uniform births of 0.01 per scan
over the scene's region (0.2 per scan on births, the scene's own rate) with a
prior of one undetected target over the region at the first scan. PMBM's cost grows
with the global hypotheses it keeps, so each PMB/PMBM run has a time budget
(``POISSON_BUDGET``: 120 s, quick 8 s) and is reported over the scans it completed,
as Stone Soup's are.

Stone Soup's tutorial JPDA tracker is the tracker of Stone Soup's example
"Comparing Efficient Hypothesis Management (EHM) with probability associators"
(https://stonesoup.readthedocs.io/en/latest/auto_examples/dataassociation/Comparing_EHM_JPDA_example.html,
the JPDA tutorial https://stonesoup.readthedocs.io/en/latest/auto_tutorials/08_JPDATutorial.html
with the initiator and deleter of tutorial 9,
https://stonesoup.readthedocs.io/en/latest/auto_tutorials/09_Initiators_%26_Deleters.html), fed
the same physical settings on the identical detections (:func:`stonesoup_tracker`):

* ``CombinedLinearGaussianTransitionModel([ConstantVelocity(q), ConstantVelocity(q)])``
  (the same NCV Q as ours), ``LinearGaussian(4, (0, 2), σ² I)``,
  ``KalmanPredictor``, ``KalmanUpdater``;
* ``PDAHypothesiser(predictor, updater, clutter_spatial_density=λ,
  prob_detect=P_D)`` (its default ``prob_gate`` = 0.95, as in the example);
* ``MultiTargetMixtureTracker(initiator, deleter, detector=None,
  data_associator=JPDAwithEHM2(PDAHypothesiser(...)), updater)`` fed scan by
  scan with ``update_tracker(time, detections)``;
* ``deleter = UpdateTimeStepsDeleter(3)`` (delete after 3 scans without an
  update), as in the example;
* ``MultiMeasurementInitiator(prior_state=GaussianState(0, diag(0, σ_v², 0,
  σ_v²)), measurement_model, deleter, data_associator=GNNWith2DAssignment(
  PDAHypothesiser(...)), updater, min_points=2)``. The example's prior is
  ``diag([5, 0.5, 5, 0.5])²``; the position entries are replaced by the
  measurement (``SimpleMeasurementInitiator``) and the velocity σ_v is
  max_speed/2, the physical setting jointtrack's one-point initiation uses.
  The example's initiator associates with ``GlobalNearestNeighbour``, which
  enumerates the product of every holding track's hypotheses — with the
  ~50–80 holding tracks of these scenes, 12 scans of the abreast scene did
  not finish in 10 minutes — so its 2-D assignment form
  ``GNNWith2DAssignment`` (tutorial 9's initiator associator) is used.

Its confirmed tracks are the tracks the ``MultiTargetMixtureTracker`` holds
after each scan (the initiator releases a track once it has ``min_points`` = 2
updates; holding tracks are tentative), as the example counts them; each
reports its state at that scan, ``[x, vx, y, vy]`` → position ``(x, y)``.

Stone Soup's tutorial tracker confirms most clutter pairs and its clusters can
grow without bound (EHM2's cost is exponential in a cluster's overlap): each
of its runs has a time budget (``STONESOUP_BUDGET`` s, SIGALRM on the main
thread). A run stopped by the budget is reported over the scans it completed
("k/K scans"), and the GOSPA comparison of the targets uses jointtrack's
GOSPA over the same scans of the same seeds.

Measured (:func:`jointtrack.metrics.tracking_quality`, definitions there;
pooled over seeds: time to confirm median/max over all targets, held = all
held target-scans / all target-scans after confirmation, false per scan =
all false track-scans / all scans, breaks and switches summed, GOSPA means
over all scans). Targets whose first detection is fewer than 10 scans before
they vanish and that are never confirmed are censored (``confirm_window`` =
10): they cannot show confirmation within 10 scans. Speed: scans per second
of ``JPDATracker.step`` / ``update_tracker`` over all scans run (jointtrack
after one untimed warm-up scene that compiles the numba kernels; Stone Soup's
``Detection`` objects built before timing; a budget-stopped run's time
includes the scan the budget interrupted).

Targets (issue 11, printed PASS/FAIL per scene for "jointtrack (default)"):
every target confirmed within 10 scans of its first detection; held in
≥ 95 % of its scans after confirmation (pooled); ≤ 0.5 false confirmed tracks
per scan; mean GOSPA below Stone Soup's tutorial tracker on the same
detections. With ``--out FILE`` the results are also written as JSON and a
plot next to it (``<stem>_quality.png``): per scene, targets vs confirmed
true and false tracks over time (mean over seeds) and GOSPA per scan; and
``<stem>_gospa_parts.png``: per scene, GOSPA's three parts per scan —
localisation, missed targets, false tracks (m², α = 2, p = 2; GOSPA² is their
sum) — for every tracker, Stone Soup's included.
"""

from __future__ import annotations

import json
import logging
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from rich.table import Table

from jointtrack._console import make_console
from jointtrack.bench.quality_plot import plot_gospa_parts, plot_quality
from jointtrack.bench.stonesoup_tracker import run_stonesoup, stonesoup_available
from jointtrack.bench.tracking_runs import (
    TrackRun,
    clutter_per_gate,
    first_detections,
    physical_config,
    run_jointtrack,
    run_poisson,
    tracker_gate_area,
)
from jointtrack.io import to_jsonable
from jointtrack.metrics import TrackingQuality, gospa_series, tracking_quality
from jointtrack.scenarios import abreast, bojilov, coalescence, crossing, many_targets

#: (name, TrackerConfig overrides on top of :func:`physical_config`); the first is the
#: configuration the targets are checked for.
CONFIGURATIONS: list[tuple[str, dict]] = [
    ("jointtrack (default)", {}),
    ("jointtrack two-point M-of-N", {"existence": False}),
]
#: (name, kind) of the Poisson trackers, run with :func:`poisson_config` of the scene
POISSON_CONFIGURATIONS: list[tuple[str, str]] = [
    ("jointtrack PMB", "pmb"),
    ("jointtrack PMBM", "pmbm"),
]
STONESOUP = "Stone Soup tutorial JPDA (EHM2)"
#: seconds per PMB/PMBM run (full, quick): PMBM's cost grows with the hypotheses kept
POISSON_BUDGET = {False: 120.0, True: 8.0}

SEEDS_FULL = (0, 1, 2)
SEEDS_QUICK = (0,)
STONESOUP_BUDGET = {False: 40.0, True: 15.0}  # seconds per Stone Soup run (full, quick)
CROSSING_BETA = 0.3  # false returns per steady-state 99 % gate
BIRTHS_BETA = 0.1
BIRTHS_SIDE = 2000.0
# every death costs any tracker at least one scan of a coasting (false) track, so
# deaths per scan are a floor under "false confirmed tracks per scan": keep them
# (≈ 20·(1 − 0.995) + border exits ≈ 0.2 per scan) well below the target of 0.5
BIRTHS_SURVIVAL = 0.995
BIRTHS_RATE = 0.2

# issue 11's numbers
TARGET_CONFIRM = 10  # scans from first detection
TARGET_HELD = 0.95
TARGET_FALSE = 0.5  # false confirmed tracks per scan


# ------------------------------------------------------------------ scenes


@dataclass(frozen=True)
class Scene:
    """A benchmark scene: ``make(seed, quick)`` builds it; ``gate`` is the metric cut-off c."""

    name: str
    description: str
    make: Callable
    gate: float


def _rate_for(beta: float, probe) -> float:
    """Clutter per scan giving ``beta`` false returns per tracker gate over ``probe``'s region."""
    area = float(np.prod(probe.region[:, 1] - probe.region[:, 0]))
    return beta * area / tracker_gate_area(probe)


def make_abreast(seed: int, quick: bool = False):
    return abreast(seed, n_scans=40 if quick else 80)


def make_crossing(seed: int, quick: bool = False):
    n = 41 if quick else 61
    probe = crossing(0, n_scans=n, clutter_per_scan=0.0)  # the region is seed-independent
    return crossing(seed, n_scans=n, clutter_per_scan=_rate_for(CROSSING_BETA, probe))


def make_births(seed: int, quick: bool = False):
    kw = dict(
        n_scans=40 if quick else 60,
        region=((0.0, BIRTHS_SIDE), (0.0, BIRTHS_SIDE)),
        p_survival=BIRTHS_SURVIVAL,
        birth_rate=BIRTHS_RATE,
    )
    probe = many_targets(20, 0.0, 0, **(kw | {"n_scans": 1}))
    return many_targets(20, _rate_for(BIRTHS_BETA, probe), seed, **kw)


def make_heavy(seed: int, quick: bool = False):
    return bojilov(1.0, seed, n_scans=41 if quick else 81)


def make_coalescence(seed: int, quick: bool = False):
    # odd: the targets meet at the midpoint step (n_steps + 1)/2
    return coalescence(seed, n_steps=21 if quick else 81)


SCENES: tuple[Scene, ...] = (
    Scene(
        "abreast",
        "5 targets abreast 20 apart, σ = 5, 60 clutter/scan (issue 11)",
        make_abreast,
        10.0,
    ),
    Scene(
        "crossing",
        f"2 targets crossing at 45°, σ = 10, {CROSSING_BETA} false/gate",
        make_crossing,
        30.0,
    ),
    Scene(
        "births",
        f"20 targets with births and deaths on {BIRTHS_SIDE / 1e3:g} km², σ = 10, "
        f"{BIRTHS_BETA} false/gate",
        make_births,
        30.0,
    ),
    Scene(
        "heavy clutter", "Bojilov's 5 lanes, β = 1 false return per gate, σ = 10", make_heavy, 20.0
    ),
    Scene(
        "coalescence",
        "4 targets meeting mid-run (Williams 2015), σ = 1, 10 clutter/scan; GOSPA c = 10 as "
        "in García-Fernández et al. 2018",
        make_coalescence,
        10.0,
    ),
)


# ------------------------------------------------------------------ running trackers


def evaluate(sc, run: TrackRun, gate: float) -> TrackingQuality:
    """:func:`tracking_quality` of a run over the scans it completed (``confirm_window`` 10)."""
    k = run.n_scans
    scan_times = sc.times[:k]
    tt, ti, tp = sc.truth_table()
    keep = tt <= scan_times[-1] if k else np.zeros(tt.size, dtype=bool)
    last = scan_times[-1] if k else -np.inf
    first = {i: t for i, t in first_detections(sc).items() if t <= last}
    return tracking_quality(
        tt[keep],
        ti[keep],
        tp[keep],
        run.times,
        run.ids,
        run.positions,
        gate=gate,
        first_detection=first,
        scan_times=scan_times,
        confirm_window=TARGET_CONFIRM,
    )


# ------------------------------------------------------------------ pooling over seeds


def pool(qs: list[TrackingQuality], runs: list[TrackRun], n_full: list[int]) -> dict:
    """Pool per-seed results (module docstring) into one row of numbers."""
    ttc = np.concatenate(
        [q.time_to_confirm[(q.first_detection_scan >= 0) & ~q.censored] for q in qs]
    )
    n_scans = sum(q.n_scans for q in qs)
    after = sum(q.n_after_scans for q in qs)
    held = sum(q.n_held_scans for q in qs)
    worst = [q.held_worst for q in qs if not np.isnan(q.held_worst)]
    seconds = sum(r.seconds for r in runs)

    def per_scan(attr):  # a scan-weighted mean; a run stopped before its first scan has none
        total = sum(getattr(q, attr) * q.n_scans for q in qs if q.n_scans)
        return total / n_scans if n_scans else float("nan")

    return dict(
        seeds=len(qs),
        scans=n_scans,
        scans_in_scenes=sum(n_full),
        completed=all(r.completed for r in runs),
        truths=sum(q.n_truths for q in qs),
        detected=sum(q.n_detected for q in qs),
        censored=sum(q.n_censored for q in qs),
        confirm_median=float(np.median(ttc)) if ttc.size else float("nan"),
        confirm_max=float(np.max(ttc)) if ttc.size else float("nan"),
        never_confirmed=sum(q.n_never_confirmed for q in qs),
        held=held / after if after else float("nan"),
        held_worst=min(worst) if worst else float("nan"),
        false_per_scan=(
            sum(q.n_false_track_scans for q in qs) / n_scans if n_scans else float("nan")
        ),
        breaks=sum(q.n_breaks for q in qs),
        fragmentations=sum(q.n_fragmentations for q in qs),
        id_switches=sum(q.n_id_switches for q in qs),
        gospa_mean=per_scan("gospa_mean"),
        gospa_localisation=per_scan("gospa_localisation"),
        gospa_missed=per_scan("gospa_missed"),
        gospa_false=per_scan("gospa_false"),
        missed_per_scan=per_scan("gospa_missed_per_scan"),
        seconds=seconds,
        scans_per_second=n_scans / seconds if seconds > 0 else float("nan"),
        per_seed=[q.as_dict() | {"scans_run": r.n_scans} for q, r in zip(qs, runs, strict=True)],
    )


def gospa_parts(sc, run: TrackRun, gate: float) -> dict:
    """Per scan (the scans the run completed) the GOSPA parts (α = 2, p = 2, c = ``gate``):
    ``localisation``, ``missed``, ``false``, in m² (GOSPA² = their sum)."""
    k = run.n_scans
    scans = sc.times[:k]
    tt, ti, tp = sc.truth_table()
    keep = tt <= scans[-1] if k else np.zeros(tt.size, dtype=bool)
    g = gospa_series(tt[keep], ti[keep], tp[keep], run.times, run.ids, run.positions, c=gate, p=2)
    out = {}
    for name in ("localisation", "missed", "false"):
        v = np.zeros(k)
        v[np.searchsorted(scans, g.times)] = getattr(g, name)
        out[name] = v
    return out


def _series(qs: list[TrackingQuality], length: int, parts: list[dict] | None = None) -> dict:
    """Per-scan means over seeds (NaN where no seed reached the scan), for the plots."""
    out = {}
    keys = [
        ("truths", "n_truths_per_scan"),
        ("true_tracks", "n_associated_per_scan"),
        ("false_tracks", "n_false_per_scan"),
        ("gospa", "gospa_per_scan"),
    ]
    if parts is not None:
        keys += [(f"gospa_{n}", n) for n in ("localisation", "missed", "false")]
    for key, attr in keys:
        m = np.full((len(qs), length), np.nan)
        for i, q in enumerate(qs):
            v = parts[i][attr] if key.startswith("gospa_") else getattr(q, attr)
            m[i, : v.size] = v
        with np.errstate(all="ignore"):
            ok = ~np.all(np.isnan(m), axis=0)
            mean = np.full(length, np.nan)
            mean[ok] = np.nanmean(m[:, ok], axis=0)
        out[key] = mean
    return out


# ------------------------------------------------------------------ output


def _f(x, fmt="{:.1f}"):
    if x is None or (isinstance(x, float) and np.isnan(x)):
        return "—"
    if isinstance(x, float) and np.isinf(x):
        return "∞"
    return fmt.format(x)


def _table(scene: Scene, res: dict) -> Table:
    t = Table(
        title=f"{scene.name}: {scene.description} — {res['seeds_text']}, c = {scene.gate:g}, "
        f"{res['clutter_per_gate']:.2f} false returns per tracker gate",
        caption="confirm: scans from first detection (median / max; ∞: a target never "
        "confirmed); held: % of target-scans after confirmation (worst target); GOSPA: mean "
        "per scan and √(mean of its squared parts) localisation / missed / false",
    )
    for col in (
        "tracker",
        "scans\nrun",
        "confirm\nmed / max",
        "never\nconfirmed",
        "held %\n(worst)",
        "false\n/ scan",
        "breaks /\nID switches",
        "GOSPA\nmean",
        "√ parts\nloc/miss/false",
        "scans/s",
    ):
        if col == "tracker":
            t.add_column(col, no_wrap=True)
        else:
            t.add_column(col, justify="right", no_wrap=True)
    for name, r in res["rows"].items():
        parts = "/".join(
            _f(np.sqrt(r[k])) for k in ("gospa_localisation", "gospa_missed", "gospa_false")
        )
        t.add_row(
            name,
            f"{r['scans']}/{r['scans_in_scenes']}",
            f"{_f(r['confirm_median'], '{:.0f}')} / {_f(r['confirm_max'], '{:.0f}')}",
            f"{r['never_confirmed']} of {r['detected'] - r['censored']}",
            f"{_f(100 * r['held'])} ({_f(100 * r['held_worst'], '{:.0f}')})",
            _f(r["false_per_scan"], "{:.2f}"),
            f"{r['breaks']} / {r['id_switches']}",
            _f(r["gospa_mean"], "{:.2f}"),
            parts,
            _f(r["scans_per_second"], "{:.0f}" if r["scans_per_second"] >= 10 else "{:.2f}"),
        )
    return t


def _targets(console, scene: Scene, res: dict) -> dict:
    name = CONFIGURATIONS[0][0]
    r = res["rows"][name]
    checks = {}
    ok = r["never_confirmed"] == 0 and r["confirm_max"] <= TARGET_CONFIRM
    checks["confirm"] = dict(
        passed=bool(ok),
        text=f"every target confirmed within {TARGET_CONFIRM} scans: max "
        f"{_f(r['confirm_max'], '{:.0f}')}, never confirmed {r['never_confirmed']}"
        + (
            f" ({r['censored']} censored: gone < 10 scans after detection)" if r["censored"] else ""
        ),
    )
    checks["held"] = dict(
        passed=bool(r["held"] >= TARGET_HELD),
        text=f"held ≥ {100 * TARGET_HELD:.0f} % after confirmation: {_f(100 * r['held'])} % "
        f"(worst target {_f(100 * r['held_worst'])} %)",
    )
    checks["false"] = dict(
        passed=bool(r["false_per_scan"] <= TARGET_FALSE),
        text=f"≤ {TARGET_FALSE} false confirmed tracks per scan: {r['false_per_scan']:.2f}",
    )
    ss = res["rows"].get(STONESOUP)
    if ss is None:
        checks["gospa"] = dict(
            passed=None, text="GOSPA below Stone Soup's: n/a (Stone Soup not installed)"
        )
    else:
        ours = res["gospa_same_scans"]
        scope = (
            "all scans"
            if ss["completed"]
            else f"the {ss['scans']} of {ss['scans_in_scenes']} scans Stone Soup completed"
        )
        checks["gospa"] = dict(
            passed=bool(ours < ss["gospa_mean"]),
            text=f"mean GOSPA below Stone Soup's: {ours:.2f} vs {ss['gospa_mean']:.2f} "
            f"over {scope}",
            ours=ours,
            stonesoup=ss["gospa_mean"],
        )
    for c in checks.values():
        mark = "n/a" if c["passed"] is None else ("PASS" if c["passed"] else "FAIL")
        console.print(f"  {scene.name} — {name}: {c['text']} — {mark}")
    return checks


# ------------------------------------------------------------------ the benchmark


def _warm_up() -> None:
    """One small untimed scene: compiles and loads the numba kernels."""
    sc = abreast(0, n_scans=6)
    run_jointtrack(sc, physical_config(sc))


def run(quick: bool = False, out: str | None = None) -> dict:
    from jointtrack._console import progress_bar

    console = make_console()
    seeds = SEEDS_QUICK if quick else SEEDS_FULL
    have_ss = stonesoup_available()
    budget = STONESOUP_BUDGET[bool(quick)]
    results: dict = {
        "quick": quick,
        "seeds": list(seeds),
        "configurations": [[n, o] for n, o in CONFIGURATIONS],
        "stonesoup": None,
        "stonesoup_budget_seconds": budget,
        "scenes": {},
    }
    if have_ss:
        import stonesoup

        results["stonesoup"] = stonesoup.__version__
    else:
        console.print(f"{STONESOUP}: not installed (pip install stonesoup==1.9.1); jointtrack only")
    poisson_budget = POISSON_BUDGET[bool(quick)]
    results["poisson_budget_seconds"] = poisson_budget
    results["poisson_configurations"] = [[n, k] for n, k in POISSON_CONFIGURATIONS]
    trackers = (
        [n for n, _ in CONFIGURATIONS]
        + [n for n, _ in POISSON_CONFIGURATIONS]
        + ([STONESOUP] if have_ss else [])
    )
    logging.disable(logging.WARNING)
    t_start = time.perf_counter()
    try:
        _warm_up()
        with progress_bar(console, transient=True) as bar:
            task = bar.add_task("quality", total=len(SCENES) * len(seeds) * len(trackers))
            per_scene = {}
            for scene in SCENES:
                qs: dict = {n: [] for n in trackers}
                runs: dict = {n: [] for n in trackers}
                parts: dict = {n: [] for n in trackers}
                scenarios = []
                for seed in seeds:
                    sc = scene.make(seed, quick)
                    scenarios.append(sc)
                    for name, overrides in CONFIGURATIONS:
                        bar.update(task, description=f"{scene.name}, seed {seed}: {name}")
                        r = run_jointtrack(sc, physical_config(sc, **overrides))
                        runs[name].append(r)
                        qs[name].append(evaluate(sc, r, scene.gate))
                        parts[name].append(gospa_parts(sc, r, scene.gate))
                        bar.advance(task)
                    for name, kind in POISSON_CONFIGURATIONS:
                        bar.update(
                            task,
                            description=f"{scene.name}, seed {seed}: {name} "
                            f"(≤ {poisson_budget:.0f} s)",
                        )
                        r = run_poisson(sc, kind, budget=poisson_budget)
                        runs[name].append(r)
                        qs[name].append(evaluate(sc, r, scene.gate))
                        parts[name].append(gospa_parts(sc, r, scene.gate))
                        bar.advance(task)
                    if have_ss:
                        bar.update(
                            task,
                            description=f"{scene.name}, seed {seed}: {STONESOUP} "
                            f"(≤ {budget:.0f} s)",
                        )
                        r = run_stonesoup(sc, budget)
                        runs[STONESOUP].append(r)
                        qs[STONESOUP].append(evaluate(sc, r, scene.gate))
                        parts[STONESOUP].append(gospa_parts(sc, r, scene.gate))
                        bar.advance(task)
                per_scene[scene.name] = (scenarios, qs, runs, parts)
    finally:
        logging.disable(logging.NOTSET)
    wall = time.perf_counter() - t_start

    default = CONFIGURATIONS[0][0]
    all_pass = True
    for scene in SCENES:
        scenarios, qs, runs, parts = per_scene[scene.name]
        n_full = [sc.n_scans for sc in scenarios]
        rows = {n: pool(qs[n], runs[n], n_full) for n in trackers}
        res = dict(
            description=scene.description,
            gate=scene.gate,
            seeds_text=f"{len(seeds)} seed{'s' if len(seeds) > 1 else ''} × {n_full[0]} scans",
            n_scans=n_full,
            targets_per_seed=[sc.n_targets for sc in scenarios],
            clutter_per_scan=float(np.mean([sc.clutter_rate for sc in scenarios])),
            clutter_per_gate=float(np.mean([clutter_per_gate(sc) for sc in scenarios])),
            rows=rows,
            series={
                n: {k: v.tolist() for k, v in _series(qs[n], max(n_full), parts[n]).items()}
                for n in trackers
            },
        )
        if have_ss:
            # our GOSPA over exactly the scans Stone Soup completed, seed by seed
            done = [r.n_scans for r in runs[STONESOUP]]
            g = np.concatenate(
                [q.gospa_per_scan[:k] for q, k in zip(qs[default], done, strict=True)]
            )
            res["gospa_same_scans"] = float(g.mean()) if g.size else float("nan")
        console.print(_table(scene, res))
        if have_ss:
            ours, ss = rows[default], rows[STONESOUP]
            ratio = ours["scans_per_second"] / ss["scans_per_second"]
            res["speed_ratio"] = ratio
            console.print(
                f"  speed: {default} {ours['scans_per_second']:.0f} scans/s, {STONESOUP} "
                f"{ss['scans_per_second']:.2f} scans/s — {ratio:,.0f}× faster"
                + ("" if ss["completed"] else f" (Stone Soup stopped at the {budget:.0f} s budget)")
            )
        res["checks"] = _targets(console, scene, res)
        all_pass &= all(c["passed"] is True for c in res["checks"].values())
        results["scenes"][scene.name] = res
    results["all_targets_met"] = bool(all_pass)
    results["wall_seconds"] = wall
    console.print(
        f"issue 11 targets on every scene: {'PASS' if all_pass else 'FAIL'} "
        f"({wall:.0f} s of tracking and evaluation)"
    )
    if out:
        png = Path(out).with_name(Path(out).stem + "_quality.png")
        try:
            results["plot"] = str(plot_quality(results, png, CONFIGURATIONS[0][0], STONESOUP))
            console.print(f"quality plot: {png}")
            png = Path(out).with_name(Path(out).stem + "_gospa_parts.png")
            results["parts_plot"] = str(plot_gospa_parts(results, png, STONESOUP))
            console.print(f"GOSPA parts per scan: {png}")
        except ImportError as exc:  # matplotlib is a dependency, but say so rather than fail
            console.print(f"quality plot not written: {exc}")
        with open(out, "w") as fh:
            json.dump(to_jsonable(results, fallback=float), fh, indent=2)
    return results
