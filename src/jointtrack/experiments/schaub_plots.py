"""Figures of the Schaub reproduction (matplotlib, Agg backend: files only, no display).

D. E. Schaub, "Joint identification of multiple tracked targets", *Journal of
Advances in Information Fusion* 12(1), 2017 — §4's examples, Figures 5–7; the
data come from :func:`jointtrack.experiments.schaub.reproduce`.

* :func:`schaub_figure` / :func:`plot_schaub` — max KL divergence (58) vs time
  step per method for one example (``schaub-example{1,2,3}.png``).

Axis labels carry units (nats; the step axis counts scans); the legend sits
below the axes, never over the curves; a divergence that cannot be
drawn (infinite, NaN, beyond 1e100) is a marker on the top edge, as the
one-hot max-weight answer's infinite divergence is
(:mod:`jointtrack.experiments._plot_values`).
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from jointtrack.experiments._plot_values import REPRO_DPI, plottable  # noqa: E402
from jointtrack.experiments.plots import save_figure  # noqa: E402

__all__ = ["plot_schaub", "schaub_figure"]

#: line style per method; max-weight gets markers: its finite stretches can be single steps
_STYLES = {"exact": "-", "sinkhorn": "--", "local": ":", "maxweight": "o-."}


def schaub_figure(res: dict, paper: dict):
    """Max KL (58) vs time step for every method — Schaub's Figures 5–7 for one example.

    An infinite divergence (the one-hot max-weight answer while it is wrong) is
    drawn as a marker at the top edge instead of a point.
    """
    from jointtrack.experiments.schaub import LABELS

    ex = str(res["example"])
    fig, ax = plt.subplots(figsize=(9.0, 5.6), layout="constrained")
    curves = {m: plottable(series) for m, series in res["max_kl"].items()}
    finite_max = max(
        (float(np.nanmax(y)) for y, _ in curves.values() if np.isfinite(y).any()), default=1.0
    )
    top = max(1.0, 1.15 * finite_max)
    colors = {}
    for m, (y, _) in curves.items():
        k = np.arange(1, y.size + 1)
        (line,) = ax.plot(k, y, _STYLES.get(m, "-"), ms=3, label=LABELS.get(m, m))
        colors[m] = line.get_color()
        off = ~np.isfinite(y)
        if off.any():
            ax.plot(
                k[off],
                np.full(int(off.sum()), top),
                "v",
                color=line.get_color(),
                markersize=4,
                label=f"{LABELS.get(m, m)}: KL = ∞ (one-hot answer wrong), drawn at the top",
            )
    med = res.get("over_seeds", {}).get("median_max_kl")
    if med and len(res["over_seeds"]["seeds"]) > 1:
        for m, series in med.items():
            y, _ = plottable(series)
            ax.plot(
                np.arange(1, y.size + 1),
                y,
                _STYLES.get(m, "-").replace("o", ""),
                lw=0.7,
                alpha=0.45,
                color=colors.get(m),
            )
        ax.plot(
            [],
            [],
            "k-",
            lw=0.7,
            alpha=0.45,
            label=f"thin lines: median over {len(res['over_seeds']['seeds'])} seeds",
        )
    ax.axhline(np.log(2), color="grey", lw=0.6, label="ln 2 nats: an unresolved pair of twins")
    ax.set_ylim(-0.03 * top, top * 1.05)  # room for a KL of 0 (max-weight right)
    ax.set_xlabel("time step k = time (s): one scan per second")
    ax.set_ylabel("max KL over observed tracks (nats)")
    ax.set_title(
        f"Schaub example {ex} (seed {res['seed']}): max KL (58) of each method's identity "
        f"marginals from the asymptotic matrix V (53), {res['plotted_kl']}\n"
        f"{res['n_observed_tracks']} observed tracks, "
        f"{res['n_identities']} identities — exact {1e3 * res['seconds_per_step']['exact']:.1f} "
        f"ms/step (paper {1e3 * paper['seconds_per_step'][ex]:.0f} ms/step)",
        fontsize=9,
    )
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.13), ncols=2, frameon=False)
    return fig


def plot_schaub(path, res: dict, paper: dict) -> Path:
    """Write :func:`schaub_figure` to ``path``."""
    return save_figure(schaub_figure(res, paper), path, dpi=REPRO_DPI)
