"""From nothing against the start-up floor: trackers beside the oracle and the floor (issue 33).

Per scene (``bojilov`` — the headline scene of ``jointtrack run`` —, ``abreast``,
``crossing``) and seed: the oracle-started single-target IPDA confirmation scans
per target, the start-up floor (the truth-started JIPDA run, each target counted
from its oracle confirmation scan) and every tracker from nothing on the same
detections, each exactly as ``run_scenario(..., start_from="nothing",
tracker=K)`` builds it; Stone Soup's tutorial JPDA tracker with ``--trackers
...,stonesoup`` when installed. Definitions (oracle, floor, phases, scores):
:mod:`jointtrack.bench.from_nothing`.

Printed per scene: GOSPA mean ± std over seeds, its parts per phase (over the
seeds that have the phase: their number in parentheses when not all), the ratio
to the floor, switches per run, false confirmed tracks per scan, the median
confirmation scans (and the median of tracker − oracle), and the issue's lines
PASS/FAIL: GOSPA ≤ 1.15 × floor (1.3 for PMB/PMBM), ≤ 1 switch per run (≤ 2),
median confirmation ≤ oracle + 2 scans, ≤ 0.1 false per scan. ``--out
FILE.json`` writes every number (per seed too) and ``FILE.png`` beside it (GOSPA
per scan, mean over seeds: the floor and each tracker, the phases shaded); the
file is rewritten (atomically) after every scene and seed, and a run killed
part-way resumes from it with the same command (only unfinished seeds are run).
The command exits 1 when a run failed (the other runs are still reported).

Beside the issue's floor (never instead of it), the *matched floor*: the oracle
confirming at the threshold r* at which clutter-born lone IPDAs with the run's
settings give at most 0.1 false confirmed tracks per scan on the scene
(:func:`jointtrack.bench.from_nothing.false_track_rate`, simulated once per scene
with ``--matched-births`` births, seed 0; ``--matched-births 0``: not computed).
Printed: r*, the oracle median at r*, the matched floor's row and every
tracker's ratio to both floors (the PASS/FAIL lines stay the issue's).

Usage: ``python benchmarks/from_nothing.py [--seeds 5] [--scenes bojilov,abreast,crossing]
[--trackers jipda,pmb,pmbm[,stonesoup]] [--returns all|own] [--budget 300]
[--matched-births 2000] [--out FILE.json]``.
"""

from __future__ import annotations

import argparse
import json
import sys
import traceback
from pathlib import Path

import numpy as np

from jointtrack._console import make_console, progress_bar
from jointtrack.bench import from_nothing as fn


def _pm(d, spec=".1f") -> str:
    return f"{d['mean']:{spec}} ± {d['std']:{spec}}"


def _opt(v, spec=".1f") -> str:
    return "–" if v is None else format(v, spec)


def _phase_cell(phases: dict, p: str, n_seeds: int) -> str:
    """A phase's mean GOSPA, with the number of seeds that have it when not all do."""
    if p not in phases:
        return "–"
    n = phases[p]["n_seeds"]
    return _opt(phases[p]["gospa"]["mean"]) + (f" ({n})" if n < n_seeds else "")


def print_scene(console, agg: dict, rate: dict | None = None) -> None:
    from rich.table import Table

    seeds = agg["seeds"]
    console.print(
        f"\n{agg['scene']}: seeds {seeds[0]}–{seeds[-1]} ({len(seeds)}); oracle IPDA median "
        f"{_opt(agg['oracle_median'])} scans to confirm ({agg['oracle_never']} never)"
    )
    if rate is not None:
        fps = dict(zip(rate["grid"], rate["false_per_scan"], strict=True))
        console.print(
            f"matched: clutter-born lone IPDAs ({rate['births']} births, {rate['copies']} with "
            "the splits) give false confirmed tracks per scan "
            + ", ".join(f"{r:g}: {f:.3g}" for r, f in fps.items())
            + f"; r* = {_opt(rate['r_star'], 'g')}"
        )
    if "matched" in agg:
        m = agg["matched"]
        console.print(
            f"matched floor: oracle confirming at r* = {m['r']:g}, median "
            f"{_opt(m['oracle_median'])} scans ({m['oracle_never']} never)"
        )
    t = Table(title=f"{agg['scene']} from nothing", title_justify="left")
    for col in (
        "tracker",
        "GOSPA",
        "/ floor",
        *(["/ matched"] if "matched" in agg else []),
        *(f"{p}" for p in fn.PHASES),
        "switches/run",
        "false/scan",
        "confirm median",
        "− oracle",
    ):
        t.add_column(col, justify="right")
    rows = ("floor", *(["matched_floor"] if "matched" in agg else []))
    for kind in (*rows, *[k for k in agg if k in fn.TRACKERS]):
        row = agg[kind]
        t.add_row(
            kind,
            _pm(row["gospa"]),
            _pm(row["ratio"], ".2f"),
            *([_pm(row["ratio_matched"], ".2f")] if "matched" in agg else []),
            *(_phase_cell(row["phases"], p, len(seeds)) for p in fn.PHASES),
            _pm(row["switches"]),
            _pm(row["false_per_scan"], ".3f"),
            f"{_opt(row['confirm_median'])} ({row['confirm_never']} never)",
            _opt(row["behind_oracle_median"]),
        )
    console.print(t)
    parts = Table(title="GOSPA parts per phase (p-th power, mean over seeds)", title_justify="left")
    parts.add_column("tracker")
    for p in fn.PHASES:
        parts.add_column(f"{p} loc/miss/false", justify="right")
    for kind in (*rows, *[k for k in agg if k in fn.TRACKERS]):
        ph = agg[kind]["phases"]
        parts.add_row(
            kind,
            *(
                "/".join(f"{ph[p][q]['mean']:.0f}" for q in ("localisation", "missed", "false"))
                if p in ph
                else "–"
                for p in fn.PHASES
            ),
        )
    console.print(parts)
    for kind in fn.TRACKERS:
        if kind in agg and "checks" in agg[kind]:
            verdict = "  ".join(
                f"{line}: {'PASS' if ok else 'FAIL'}" for line, ok in agg[kind]["checks"].items()
            )
            console.print(f"  {kind:6s} {verdict}")


def plot(path: Path, aggs: dict, runs: dict) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from jointtrack.experiments.plots import save_figure

    scenes = list(aggs)
    fig, axes = plt.subplots(len(scenes), 1, figsize=(9, 3.2 * len(scenes)), squeeze=False)
    shades = ["#dddddd", "#ffffff", "#f6d5d5", "#ffffff", "#dddddd"]
    for ax, scene in zip(axes[:, 0], scenes, strict=True):
        rs = runs[scene]
        phase = np.asarray(rs[0]["phases"])
        for i, name in enumerate(fn.PHASES):
            ks = np.flatnonzero(phase == i)
            if ks.size:
                ax.axvspan(ks[0] - 0.5, ks[-1] + 0.5, color=shades[i], zorder=0)
                ax.text(
                    (ks[0] + ks[-1]) / 2,
                    1.0,
                    name,
                    transform=ax.get_xaxis_transform(),
                    ha="center",
                    va="bottom",
                    fontsize=8,
                )
        series = {"floor": [r["floor"]["gospa_series"] for r in rs]}
        if all("matched" in r for r in rs):
            series["matched floor"] = [r["matched"]["floor"]["gospa_series"] for r in rs]
        for kind in rs[0]["trackers"]:
            series[kind] = [r["trackers"][kind]["gospa_series"] for r in rs]
        for kind, ss in series.items():
            ax.plot(
                np.mean(ss, axis=0),
                label=kind,
                lw=2.2 if "floor" in kind else 1.3,
                color="k" if "floor" in kind else None,
                ls=":" if kind == "matched floor" else "-",
            )
        ax.set_ylabel("GOSPA (mean over seeds)")
        ax.set_title(f"{scene} from nothing ({len(rs)} seeds)", loc="left", pad=14)
        ax.legend(fontsize=8, ncol=len(series))
    axes[-1, 0].set_xlabel("scan")
    fig.tight_layout()
    save_figure(fig, path)
    plt.close(fig)


def _write(path: Path, doc: dict) -> None:
    from jointtrack._atomic import atomic_file

    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_file(path) as tmp:
        tmp.write_text(json.dumps(doc, indent=1, default=float))


def _resume(path: Path, setup: dict, scenes) -> dict:
    """{(scene, seed): run} already in ``path`` from a run with the same ``setup``, and
    ``"rates"``: {scene: false_track_rate result} already computed."""
    if not path.exists():
        return {}
    try:
        doc = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise SystemExit(f"--out {path}: not a from_nothing result ({exc}); remove it") from None
    if not isinstance(doc, dict) or doc.get("setup") != setup:
        raise SystemExit(
            f"--out {path} holds a run with other settings ({doc.get('setup')!r}, this one "
            f"{setup!r}); remove it or choose another --out"
        )
    out = {"rates": doc.get("rates", {})}
    for scene in scenes:
        for r in doc.get("runs", {}).get(scene, []):
            # JSON keys are strings: the targets' ids back to ints
            r["oracle"] = {int(k): v for k, v in r["oracle"].items()}
            extra = []
            if "matched" in r:
                r["matched"]["oracle"] = {int(k): v for k, v in r["matched"]["oracle"].items()}
                extra.append(r["matched"]["floor"])
            for sc in (r["floor"], *extra, *r["trackers"].values()):
                sc["confirm_scans"] = {int(k): v for k, v in sc["confirm_scans"].items()}
            out[scene, int(r["seed"])] = r
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=5, help="seeds 0..N−1 (default 5)")
    ap.add_argument("--scenes", default=",".join(fn.SCENES))
    ap.add_argument("--trackers", default="jipda,pmb,pmbm")
    ap.add_argument("--returns", default="all", choices=("all", "own"))
    ap.add_argument("--budget", type=float, default=300.0, help="seconds per Stone Soup run")
    ap.add_argument(
        "--matched-births",
        type=int,
        default=fn.MATCHED_BIRTHS,
        help="clutter-born IPDAs simulated per scene for the matched floor's r* (0: none)",
    )
    ap.add_argument("--out", default="", help="FILE.json (and FILE.png beside it)")
    args = ap.parse_args(argv)
    scenes = [s for s in args.scenes.split(",") if s]
    kinds = [k for k in args.trackers.split(",") if k]
    bad = [s for s in scenes if s not in fn.SCENES] + [k for k in kinds if k not in fn.TRACKERS]
    if bad or args.seeds < 1:
        ap.error(
            f"unknown scene/tracker {', '.join(bad)} (scenes: {', '.join(fn.SCENES)}; trackers: "
            f"{', '.join(fn.TRACKERS)})"
            if bad
            else "--seeds must be ≥ 1"
        )
    if not 0 <= args.matched_births <= 10**6:
        ap.error(f"--matched-births must be 0 … 10^6, got {args.matched_births}")
    if "stonesoup" in kinds:
        from jointtrack.bench.stonesoup_tracker import stonesoup_available

        if not stonesoup_available():
            ap.error("--trackers stonesoup: Stone Soup is not installed (the bench extra)")
    out = Path(args.out) if args.out else None
    if out is not None and out.suffix != ".json":
        ap.error("--out must name a .json file (the PNG goes beside it)")
    console = make_console(stderr=False)
    runs: dict = {s: [] for s in scenes}
    failed = []
    # every finished (scene, seed) is written at once: a killed run resumes from the file
    # (same --trackers and --returns), redoing only the unfinished ones
    setup = {"trackers": kinds, "returns": args.returns, "matched_births": args.matched_births}
    done = _resume(out, setup, scenes) if out is not None else {}
    rates: dict = dict(done.pop("rates", {}))
    steps = len(scenes) * args.seeds * (2 + len(kinds))
    with progress_bar(console, unit="steps", enabled=True, remaining=True) as bar:
        task = bar.add_task("from nothing", total=steps)
        for scene in scenes:
            if args.matched_births and scene not in rates:
                # r* from the scene's settings (the same on every seed of a scene: seed 0's)
                bar.update(task, description=f"{scene}: r* (matched floor)")
                try:
                    rates[scene] = fn.false_track_rate(
                        fn.make_scene(scene, 0), births=args.matched_births
                    )
                except Exception:  # noqa: BLE001 - report it, run the rest without it
                    failed.append(f"{scene} r*: {traceback.format_exc(limit=3)}")
                    rates[scene] = None
                if out is not None:
                    _write(out, {"setup": setup, "partial": True, "rates": rates, "runs": runs})
            r_star = (rates.get(scene) or {}).get("r_star")
            for seed in range(args.seeds):
                bar.update(task, description=f"{scene} seed {seed}")
                if (scene, seed) in done:
                    runs[scene].append(done[scene, seed])
                    bar.update(task, advance=2 + len(kinds))
                    continue
                try:
                    r = fn.evaluate(
                        scene,
                        seed,
                        kinds,
                        returns=args.returns,
                        budget=args.budget,
                        r_matched=r_star,
                        on_step=lambda label, s=scene, e=seed: bar.update(
                            task, advance=1, description=f"{s} seed {e}: {label} done"
                        ),
                    )
                    runs[scene].append(r)
                    if out is not None:
                        _write(out, {"setup": setup, "partial": True, "rates": rates, "runs": runs})
                except Exception:  # noqa: BLE001 - report the run that failed, keep the others
                    failed.append(f"{scene} seed {seed}: {traceback.format_exc(limit=3)}")
    aggs = {s: fn.aggregate(runs[s]) for s in scenes if runs[s]}
    for scene, agg in aggs.items():
        print_scene(console, agg, rates.get(scene))
    if out is not None:
        out.parent.mkdir(parents=True, exist_ok=True)
        doc = {
            "command": " ".join(sys.argv),
            "args": vars(args),
            "setup": setup,
            "partial": bool(failed),
            "scenes": aggs,
            "rates": rates,
            "runs": runs,
        }
        _write(out, doc)
        if aggs:
            plot(out.with_suffix(".png"), aggs, runs)
        console.print(f"wrote {out}" + (f" and {out.with_suffix('.png')}" if aggs else ""))
    for f in failed:
        console.print(f"FAILED {f}", style="red", markup=False)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
