"""The quality benchmark's plot: tracks over time and GOSPA per scan, per scene."""

from __future__ import annotations

from pathlib import Path

import numpy as np


def plot_quality(results: dict, path, default: str, stonesoup: str) -> Path:
    """Per scene: targets, confirmed true / false tracks over time (default vs Stone Soup)
    and GOSPA per scan (every tracker), means over seeds (matplotlib, Agg)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scenes = results["scenes"]
    n = len(scenes)
    fig, axes = plt.subplots(2, n, figsize=(4.6 * n, 7.5), squeeze=False, constrained_layout=True)
    for j, (name, res) in enumerate(scenes.items()):
        top, bottom = axes[0, j], axes[1, j]
        # arrays (NaN where no seed reached a scan; None after a JSON round trip)
        series = {
            tr: {key: np.asarray(v, dtype=np.float64) for key, v in ser.items()}
            for tr, ser in res["series"].items()
        }
        first = next(iter(series.values()))
        k = np.arange(len(first["truths"]))
        top.plot(k, first["truths"], color="k", lw=2, label="targets")
        for tracker, color in ((default, "C0"), (stonesoup, "C3")):
            if tracker not in series:
                continue
            s = series[tracker]
            top.plot(k, s["true_tracks"], color=color, label=f"{tracker}: true tracks")
            top.plot(k, s["false_tracks"], color=color, ls="--", label=f"{tracker}: false tracks")
        top.set_title(name)
        top.set_xlabel("scan")
        top.set_ylabel("tracks (mean over seeds)")
        # linear up to the number of targets, logarithmic above (Stone Soup's false tracks)
        linthresh = max(10.0, float(np.nanmax(first["truths"])))
        top.set_yscale("symlog", linthresh=linthresh)
        ymax = max(
            float(np.nanmax(ser[key]))
            for ser in series.values()
            for key in ("truths", "true_tracks", "false_tracks")
        )
        ticks = (
            (0, 1, 2, 5, 10, 20, 50, 100, 200, 500)
            if linthresh <= 10
            else (0, 5, 10, 20, 50, 100, 200, 500)
        )
        top.set_yticks([v for v in ticks if v <= 1.5 * ymax])
        top.yaxis.set_major_formatter(matplotlib.ticker.ScalarFormatter())
        top.grid(True, alpha=0.3)
        for i, (tracker, s) in enumerate(series.items()):
            color = "C3" if tracker == stonesoup else f"C{i if i < 3 else i + 1}"
            bottom.plot(k, s["gospa"], color=color, label=tracker)
        bottom.set_xlabel("scan")
        bottom.set_ylabel(f"GOSPA (m), c = {res['gate']:g} m, p = 2")
        bottom.set_yscale("log")
        bottom.grid(True, which="both", alpha=0.3)
        if j == 0:
            top.legend(fontsize=7)
            bottom.legend(fontsize=7)
    fig.suptitle("Tracking quality from nothing: jointtrack vs Stone Soup's tutorial JPDA tracker")
    path = Path(path)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


#: the GOSPA parts (α = 2, p = 2) per scan, as stored in the results' series
PARTS = (("localisation", "localisation"), ("missed", "missed targets"), ("false", "false tracks"))


def plot_gospa_parts(results: dict, path, stonesoup: str) -> Path:
    """Per scene (columns) and GOSPA part (rows: localisation, missed, false), the part
    per scan of every tracker, mean over seeds (m²; GOSPA² = the sum of the three),
    Stone Soup's tutorial tracker in red (matplotlib, Agg)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scenes = results["scenes"]
    n = len(scenes)
    fig, axes = plt.subplots(
        len(PARTS), n, figsize=(4.6 * n, 9.0), squeeze=False, constrained_layout=True
    )
    for j, (name, res) in enumerate(scenes.items()):
        for i, (key, label) in enumerate(PARTS):
            ax = axes[i, j]
            for c, (tracker, ser) in enumerate(res["series"].items()):
                v = np.asarray(ser.get(f"gospa_{key}", []), dtype=np.float64)
                if not v.size:
                    continue
                color = "C3" if tracker == stonesoup else f"C{c if c < 3 else c + 1}"
                ax.plot(np.arange(v.size), v, color=color, lw=1.2, label=tracker)
            ax.set_yscale("symlog", linthresh=1.0)
            ax.grid(True, alpha=0.3)
            if i == 0:
                ax.set_title(f"{name} (c = {res['gate']:g} m)")
            if i == len(PARTS) - 1:
                ax.set_xlabel("scan")
            if j == 0:
                ax.set_ylabel(f"GOSPA$^2$ part: {label} (m$^2$)")
            if i == 0 and j == 0:
                ax.legend(fontsize=7)
    fig.suptitle(
        "GOSPA per scan in its parts (α = 2, p = 2; mean over seeds): localisation, "
        "missed targets (c²/2 each), false tracks (c²/2 each)"
    )
    path = Path(path)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path
