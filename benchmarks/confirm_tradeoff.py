"""Issue 32: straight flight lost against false tracks over the confirmation setting.

The switzerland bare command (``benchmarks/fit_realdata.py``: every model value
fitted) with only ``r_confirm`` set (``--config``), for each value and degradation
seed; the scores of each run, then one PNG: straight-flight truth points lost
(x) against false tracks per hour (y, log scale), one line per seed, the first seed's points
labelled with their ``r_confirm``, the issue's targets (≤ 1 % lost, ≤ 3 false tracks/h) drawn in.

    python benchmarks/confirm_tradeoff.py --out DIR [--values 0.5 0.7 0.9 0.97] [--seeds 1 2]

A run whose ``DIR/rc<value>-s<seed>/fit_realdata.json`` exists is not run again
(the runs take minutes each); ``--plot PNG`` names the figure (default
``DIR/confirm_tradeoff.png``). The fitted tracker's own ``r_confirm`` is the
TrackerConfig default, 0.9 (the fit does not set it).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

KEYS = (
    "lost_straight",
    "false_tracks_per_hour",
    "coverage",
    "purity",
    "tracks_per_identity",
    "tracks_per_identity_held",
)


def run_one(value: float, seed: int, folder: Path) -> dict:
    """The bare command with ``r_confirm = value`` on ``seed``; its fit_realdata row."""
    done = folder / "fit_realdata.json"
    if not done.exists():
        folder.mkdir(parents=True, exist_ok=True)
        toml = folder / "r_confirm.toml"
        toml.write_text(f"[tracker]\nr_confirm = {value!r}\n")
        argv = [sys.executable, str(Path(__file__).with_name("fit_realdata.py"))]
        argv += ["--seeds", str(seed), "--out", str(folder), "--config", str(toml)]
        subprocess.run(argv, check=True)
    (row,) = json.loads(done.read_text())
    return row


def plot(rows: list[dict], path: Path) -> None:
    """Straight flight lost (%) against false tracks/h, one line per seed."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    for n, seed in enumerate(sorted({r["seed"] for r in rows})):
        mine = sorted((r for r in rows if r["seed"] == seed), key=lambda r: r["r_confirm"])
        x = [100.0 * r["lost_straight"] for r in mine]
        y = [r["false_tracks_per_hour"] for r in mine]
        ax.plot(x, y, "o-", label=f"seed {seed}")
        for r, xi, yi in zip(mine, x, y, strict=True) if n == 0 else ():  # one seed's labels
            ax.annotate(
                f"{r['r_confirm']:g}", (xi, yi), textcoords="offset points", xytext=(-26, -4)
            )
    ax.axvline(1.0, color="grey", ls="--", lw=0.8)
    ax.axhline(3.0, color="grey", ls="--", lw=0.8)
    ax.annotate(
        "target: ≤ 1 % lost, ≤ 3 false/h",
        (1.0, 3.0),
        textcoords="offset points",
        xytext=(4, -12),
        color="grey",
        fontsize=8,
    )
    ax.set_xlabel("straight flight lost (% of truth points)")
    ax.set_ylabel("false tracks per hour (log scale)")
    ax.set_yscale("log")
    ax.set_title("switzerland, bare command, r_confirm swept (labels)")
    ax.set_xlim(left=0.0)
    ax.legend(loc="lower left")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", required=True, help="working folder")
    parser.add_argument("--values", type=float, nargs="+", default=[0.5, 0.7, 0.9, 0.97])
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--plot", default=None, help="the PNG (default OUT/confirm_tradeoff.png)")
    args = parser.parse_args()
    out = Path(args.out)
    rows = []
    for seed in args.seeds:
        for value in args.values:
            row = run_one(value, seed, out / f"rc{value:g}-s{seed}")
            bare = row["bare"]
            rows.append(
                {"seed": seed, "r_confirm": value, "cpu_s": row["cpu_s"]}
                | {k: bare[k] for k in KEYS}
            )
            print(
                f"seed {seed} r_confirm {value:g}: "
                + ", ".join(f"{k} {bare[k]:.4g}" for k in KEYS)
                + f"; CPU {row['cpu_s']:.0f} s ({row['data_hours'] * 3600 / row['cpu_s']:.0f}×)"
            )
    (out / "confirm_tradeoff.json").write_text(json.dumps(rows, indent=1))
    plot(rows, Path(args.plot) if args.plot else out / "confirm_tradeoff.png")


if __name__ == "__main__":
    main()
