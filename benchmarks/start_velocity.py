"""The gap to the start-up floor: how much is the start, how much velocity knowledge (issue 33).

Per scene and seed: the start-up floor (:mod:`jointtrack.bench.from_nothing`),
the JIPDA tracker from nothing (``run_scenario(name, start_from="nothing",
tracker="jipda")``, reproduced bit for bit) and the same tracker given a
*perfect start* — one tentative track per target at its true position and
velocity at its first scan, with the velocity standard deviations of
``--velocities`` (:mod:`jointtrack.bench.perfect_start`): ``steady`` (the
floor's covariance), numbers in m/s, ``one-point`` (the one-point initiation's
covariance, σ_v = max_speed / 2). Each ``--config`` (a JSON object of
``[tracker]`` overrides, e.g. ``'{"tentative_association": "splitting"}'``) is
run separately.

Printed per scene and config: GOSPA mean ± std over seeds and the mean of the
paired difference to the tracker from nothing, for every row; the ratio to the
floor. ``--out FILE.json`` writes every number (per seed too), rewritten
atomically after every seed (a killed run resumes from it with the same command:
only the unfinished seeds are run), and ``FILE.png`` beside it (GOSPA against the
start's velocity σ, the floor and from nothing as lines).

Usage: ``python benchmarks/start_velocity.py [--seeds 0-9] [--scenes bojilov]
[--velocities steady,0.5,1,2,4,one-point] [--config '{}' ...] [--out FILE.json]``.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

import numpy as np

from jointtrack._console import make_console, progress_bar
from jointtrack.bench import from_nothing as fn
from jointtrack.bench import perfect_start as ps


def _seeds(text: str) -> list[int]:
    out = []
    for part in text.split(","):
        a, _, b = part.partition("-")
        out += list(range(int(a), int(b) + 1)) if b else [int(a)]
    if not out or min(out) < 0:
        raise argparse.ArgumentTypeError(
            f"--seeds must list seeds ≥ 0 (e.g. 0-9 or 0,3), got {text!r}"
        )
    return out


def _velocity(text: str):
    if text in (ps.STEADY, ps.ONE_POINT):
        return text
    try:
        v = float(text)
    except ValueError:
        v = float("nan")
    if not np.isfinite(v) or v <= 0:
        raise argparse.ArgumentTypeError(
            f"--velocities: {text!r} is not a number > 0, {ps.STEADY!r} or {ps.ONE_POINT!r}"
        )
    return v


def _config(text: str) -> dict:
    try:
        value = json.loads(text)
    except json.JSONDecodeError as exc:
        raise argparse.ArgumentTypeError(f"--config {text!r} is not JSON: {exc}") from None
    if not isinstance(value, dict):
        raise argparse.ArgumentTypeError(f"--config must be a JSON object, got {text!r}")
    return value


def _write(path: Path, data: dict) -> None:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(data, indent=1))
    os.replace(tmp, path)


def _label(v) -> str:
    return (
        "from nothing"
        if v is None
        else f"perfect start, σ_v {v}" + ("" if isinstance(v, str) else " m/s")
    )


def _run_seed(scene: str, seed: int, velocities, config: dict) -> dict:
    s = fn.make_scene(scene, seed)
    rows = {}
    for v in (None, *velocities):
        rows[str(v)] = fn.score_tracks(s, ps.perfect_start_tracks(s, v, tracker=config))["gospa"]
    return rows


def _plot(path: Path, table: dict, velocities) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker

    fig, axes = plt.subplots(1, len(table), figsize=(6.5 * len(table), 4.5), squeeze=False)
    for ax, (scene, by_cfg) in zip(axes[0], table.items(), strict=True):
        # the named starts at their own σ on this scene: a log axis in m/s
        named = ps.named_velocity_stds(fn.make_scene(scene, 0))
        at = [named[v] if isinstance(v, str) else v for v in velocities]
        floor = np.mean(list(by_cfg["floor"].values()))
        ax.axhline(floor, color="k", lw=1.5, label=f"start-up floor {floor:.1f}")
        ax.axhline(1.15 * floor, color="k", lw=0.8, ls=":", label="1.15 × floor (issue 33)")
        for i, (cfg, seeds) in enumerate(by_cfg["configs"].items()):
            col = f"C{i}"
            xs, ys, es = [], [], []
            for x, v in zip(at, velocities, strict=True):
                vals = [r[str(v)] for r in seeds.values()]
                xs.append(x)
                ys.append(np.mean(vals))
                es.append(np.std(vals))
            order = np.argsort(xs)
            xs, ys, es = (np.asarray(a)[order] for a in (xs, ys, es))
            ax.errorbar(xs, ys, es, color=col, marker="o", capsize=3, label=f"perfect start {cfg}")
            nothing = np.mean([r["None"] for r in seeds.values()])
            ax.axhline(
                nothing, color=col, ls="--", lw=1, label=f"from nothing {cfg}: {nothing:.1f}"
            )
        ax.set_xscale("log")
        ax.xaxis.set_major_formatter(matplotlib.ticker.FuncFormatter(lambda v, _p: f"{v:g}"))
        ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        for x, v in zip(at, velocities, strict=True):
            if isinstance(v, str):
                ax.annotate(
                    f"{v}\n{x:.2g} m/s",
                    (x, ax.get_ylim()[0]),
                    fontsize=7,
                    ha="center",
                    va="bottom",
                    xytext=(0, 4),
                    textcoords="offset points",
                )
        ax.set_xlabel("velocity σ of the perfect start (m/s, log)")
        ax.set_ylabel("mean GOSPA (m)")
        n = len(next(iter(by_cfg["configs"].values())))
        ax.set_title(f"{scene}: {n} seeds, mean ± std")
        ax.legend(fontsize=7)
        ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=_seeds, default=_seeds("0-9"))
    ap.add_argument("--scenes", default="bojilov")
    ap.add_argument("--velocities", default="steady,0.5,1,2,4,one-point")
    ap.add_argument("--config", type=_config, action="append")
    ap.add_argument("--out", type=Path)
    a = ap.parse_args(argv)
    scenes = a.scenes.split(",")
    bad = [s for s in scenes if s not in fn.SCENES]
    if bad:
        ap.error(f"--scenes: unknown {bad}; choose from {', '.join(fn.SCENES)}")
    try:
        velocities = [_velocity(v) for v in a.velocities.split(",")]
    except argparse.ArgumentTypeError as exc:
        ap.error(str(exc))
    configs = a.config or [{}]
    names = [json.dumps(c, sort_keys=True) for c in configs]
    args = {"velocities": [str(v) for v in velocities], "configs": names}
    table = {}
    if a.out is not None and a.out.exists():
        old = json.loads(a.out.read_text())
        if old.get("args") == args:
            table = old["table"]
    console = make_console()
    failed = 0
    work = [(s, seed) for s in scenes for seed in a.seeds]
    with progress_bar(console, unit="seeds") as bar:
        task = bar.add_task("perfect starts", total=len(work))
        for scene, seed in work:
            entry = table.setdefault(scene, {"floor": {}, "configs": {n: {} for n in names}})
            key = str(seed)
            if key not in entry["floor"]:
                entry["floor"][key] = fn.evaluate(scene, seed, trackers=())["floor"]["gospa"]
            for cfg, name in zip(configs, names, strict=True):
                if key in entry["configs"][name]:
                    continue
                try:
                    entry["configs"][name][key] = _run_seed(scene, seed, velocities, cfg)
                except Exception as exc:  # reported, the other runs go on; exit 1 at the end
                    failed += 1
                    console.print(f"[red]{scene} seed {seed} {name}: {exc!r}")
            if a.out is not None:
                _write(a.out, {"args": args, "table": table})
            bar.advance(task)
    for scene, entry in table.items():
        seeds = sorted(entry["floor"], key=int)
        floor = np.array([entry["floor"][s] for s in seeds])
        console.print(
            f"\n[bold]{scene}[/] — seeds {','.join(seeds)}; "
            f"floor {floor.mean():.2f} ± {floor.std():.2f}"
        )
        for name in names:
            rows = entry["configs"][name]
            done = [s for s in seeds if s in rows]
            console.print(f"  config {name}:")
            base = np.array([rows[s]["None"] for s in done])
            for v in (None, *velocities):
                vals = np.array([rows[s][str(v)] for s in done])
                console.print(
                    f"    {_label(v):34s} GOSPA {vals.mean():6.2f} ± {vals.std():5.2f}   "
                    f"Δ vs from nothing {np.mean(vals - base):+6.2f}   "
                    f"× floor {vals.mean() / floor.mean():4.2f}"
                )
    if a.out is not None:
        _plot(a.out.with_suffix(".png"), table, velocities)
        console.print(f"\nwrote {a.out} and {a.out.with_suffix('.png')}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
