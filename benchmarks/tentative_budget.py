"""Issue 25: what the exact engine costs on the clusters a run actually sees, per kind of track.

Runs the JIPDA tracker (``jointtrack run``'s settings, derived from each built-in
scenario) with an ``on_cluster`` hook that keeps every multi-track cluster —
confirmed and tentative — then solves each kept cluster again, offline, by the
exact engine (:func:`jointtrack.association.marginals`, ``method="exact"``, the
``max_bits = --max-bits``, above which the engine refuses a cluster before any
work) and by loopy BP (``method="lbp"``), timing both in CPU time (best of
``--repeat``: the machine may be shared). The tracker runs with the settings of
``jointtrack run`` (``--tracker-option`` to change them), so the clusters are
the ones a run sees.

Per scenario and kind (confirmed / tentative) it prints: clusters, tracks and
measurements per cluster (range), gating density (gated pairs / N·M), the
exact DP's frontier width (``max_frontier`` bits, the engine's own measure of
work: the state has 2^bits entries), exact and LBP milliseconds (median and
maximum), their ratio and LBP's largest error in β; then the clusters by
frontier width and by number of tracks.

    PYTHONPATH=src python benchmarks/tentative_budget.py [--scans 30] [--repeat 3]
"""

from __future__ import annotations

import argparse
import re
import sys
import time
from collections import defaultdict

import numpy as np

from jointtrack.assignment import assignment_sum
from jointtrack.association import marginals
from jointtrack.errors import ExactLimitError
from jointtrack.experiments.config import (
    jpda_kind_overrides,
    make_scenario,
    make_tracker_config,
    scenario_tracker_settings,
    start_truth_tracks,
)
from jointtrack.trackers import JPDATracker

#: (scenario, start) pairs: the default run, Bojilov's scene without a truth
#: start, and the other built-in scenes (which start from nothing).
RUNS = (
    ("bojilov", "truth"),
    ("bojilov", "nothing"),
    ("crossing", "nothing"),
    ("many", "nothing"),
    ("abreast", "nothing"),
    ("coalescence", "nothing"),
)


def capture(name: str, start: str, n_scans: int | None, options: dict) -> list:
    """Every multi-track cluster of a JIPDA run on scenario ``name``: (confirmed, L, miss)."""
    sc = make_scenario(name, 0, {})
    over = jpda_kind_overrides("jipda", dict(options))
    cfg = make_tracker_config(scenario_tracker_settings(sc), over)
    kept = []

    def keep(rec):
        if not hasattr(rec.L, "toarray"):  # dense clusters only (all of them here)
            kept.append((bool(rec.confirmed), np.array(rec.L), np.array(rec.miss)))

    trk = JPDATracker(cfg, on_cluster=keep)
    dt = float(np.median(np.diff(sc.times))) if len(sc.times) > 1 else 1.0
    if start == "truth":
        start_truth_tracks(trk, sc.truth_states[0], dt)
    stop = len(sc.times) if n_scans is None else min(n_scans, len(sc.times))
    for k in range(stop):
        trk.step(float(sc.times[k]), sc.detections[k])
    return kept


def best_time(fn, repeat: int) -> float:
    """Smallest CPU time of up to ``repeat`` calls (seconds; fewer calls past 0.2 s in all)."""
    best, spent = np.inf, 0.0
    for _ in range(repeat):
        t0 = time.process_time()
        fn()
        dt = time.process_time() - t0
        best, spent = min(best, dt), spent + dt
        if spent > 0.2:
            break
    return best


def measure(kept: list, repeat: int, max_bits: int) -> list:
    """Per cluster: kind, N, M, density, frontier bits, exact s (nan: refused), lbp s, max |Δβ|.

    A refused cluster's bits are those the engine named in its refusal (> max_bits).
    """
    rows = []
    refuse = []  # seconds the engine takes to refuse a cluster (its plan, before any DP)
    for confirmed, L, miss in kept:
        N, M = L.shape

        def exact(L=L, miss=miss):
            return marginals(L, miss, method="exact", max_bits=max_bits)

        try:
            bits = int(
                assignment_sum(L, miss, marginals=False, max_bits=max_bits).info["max_frontier"]
            )
            beta = exact()
            t_exact = best_time(exact, repeat)
        except ExactLimitError as exc:
            found = re.search(r"2\^(\d+)", str(exc))
            bits, beta, t_exact = int(found.group(1)) if found else -1, None, np.nan
            refuse.append(best_time(lambda: _refused(exact), repeat))
        lbp = marginals(L, miss, method="lbp")
        t_lbp = best_time(lambda L=L, miss=miss: marginals(L, miss, method="lbp"), repeat)
        err = float(np.abs(lbp - beta).max()) if beta is not None else np.nan
        dens = np.count_nonzero(L) / (N * M) if N * M else 0.0
        rows.append((confirmed, N, M, dens, bits, t_exact, t_lbp, err))
    if refuse:
        print(f"(refusals: {len(refuse)}, {_ms(refuse)} ms median / max)", file=sys.stderr)
    return rows


def _refused(exact):
    try:
        exact()
    except ExactLimitError:
        return
    raise AssertionError("the exact engine solved a cluster it had refused")


def _rng(values, fmt="{:d}") -> str:
    lo, hi = min(values), max(values)
    return fmt.format(lo) if lo == hi else f"{fmt.format(lo)}–{fmt.format(hi)}"


def _ms(t) -> str:
    t = np.asarray(t, float) * 1e3
    t = t[~np.isnan(t)]
    return f"{np.median(t):.3f} / {t.max():.3f}" if t.size else "–"


def report(label: str, rows: list) -> None:
    for confirmed in (True, False):
        part = [r for r in rows if r[0] == confirmed]
        kind = "confirmed" if confirmed else "tentative"
        if not part:
            print(f"| {label} | {kind} | 0 | – | – | – | – | – | – | – | – |")
            continue
        te = np.array([r[5] for r in part])
        tl = np.array([r[6] for r in part])
        ok = ~np.isnan(te)
        refused = int((~ok).sum())
        err = np.array([r[7] for r in part])[ok]
        print(
            f"| {label} | {kind} | {len(part)}{f' ({refused} refused)' if refused else ''} | "
            f"{_rng([r[1] for r in part])} | {_rng([r[2] for r in part])} | "
            f"{_rng([r[3] for r in part], '{:.2f}')} | {_rng([r[4] for r in part])} | "
            f"{_ms(te)} | {_ms(tl)} | "
            f"{_ms(te[ok] / tl[ok] / 1e3) if ok.any() else '–'} | "
            f"{f'{err.max():.3f}' if err.size else '–'} |"
        )


def by_key(rows: list, key: int, title: str) -> None:
    """Exact and LBP CPU time grouped by ``rows[key]`` (frontier bits or tracks), per kind."""
    groups = defaultdict(list)
    for r in rows:
        groups[(r[0], r[key])].append(r)
    other = "tracks" if key == 4 else "frontier bits"
    print()
    print(
        f"| kind | {title} | clusters | {other} | exact ms (median / max) | lbp ms (median / max) |"
    )
    print("|---|---|---|---|---|---|")
    for (confirmed, k), part in sorted(groups.items(), key=lambda kv: (not kv[0][0], kv[0][1])):
        te = [r[5] for r in part]
        refused = sum(np.isnan(te))
        print(
            f"| {'confirmed' if confirmed else 'tentative'} | {k} | {len(part)}"
            f"{f' ({refused} refused)' if refused else ''} | "
            f"{_rng([r[1 if key == 4 else 4] for r in part])} | {_ms(te)} | "
            f"{_ms([r[6] for r in part])} |"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scans", type=int, default=30, help="first scans of each run (30)")
    parser.add_argument("--repeat", type=int, default=3, help="timing repeats (best kept)")
    parser.add_argument(
        "--max-bits", type=int, default=20, help="the exact engine refuses wider frontiers (20)"
    )
    parser.add_argument(
        "--tracker-option",
        action="append",
        default=[],
        metavar="KEY=INT",
        help="a TrackerConfig integer override for the captured runs, e.g. exact_max_tracks=16",
    )
    args = parser.parse_args()
    options = {k: int(v) for k, v in (o.split("=", 1) for o in args.tracker_option)}
    # compile the kernels before timing anything
    L0 = np.array([[1.0, 0.5], [0.3, 2.0]])
    marginals(L0, np.array([0.1, 0.1]), method="exact")
    marginals(L0, np.array([0.1, 0.1]), method="lbp")
    print(
        "| run | kind | clusters | tracks | meas. | density | frontier bits | exact ms "
        "(median / max) | lbp ms (median / max) | exact/lbp (median / max) | "
        "max abs(β_lbp − β) |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    everything = []
    for name, start in RUNS:
        rows = measure(capture(name, start, args.scans, options), args.repeat, args.max_bits)
        everything += rows
        report(f"{name}, from {start}", rows)
    by_key(everything, 4, "frontier bits")
    by_key(everything, 1, "tracks")


if __name__ == "__main__":
    main()
