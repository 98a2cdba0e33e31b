"""Figures of the Nannuru & Coates reproduction (matplotlib, Agg backend: files only).

S. Nannuru and M. Coates, "Gaussian approximation for superpositional sensors",
technical report, McGill University, 2015 — figure numbers are that report's;
the data come from :func:`jointtrack.experiments.nannuru.reproduce`.

* :func:`plot_histograms` — Figures 1–3: histograms (1000 bins) of each
  component of y for n0 = 4, 6, 8 with the Campbell Gaussian overlaid.
* :func:`plot_bins` — Figures 4–5: bin plot of R(x) against R₁(x).
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from jointtrack.experiments.plots import save_figure  # noqa: E402

__all__ = ["plot_bins", "plot_histograms"]

HIST_BINS = 1000
_DPI = 110


def plot_histograms(path, hists: list[dict], title: str) -> Path:
    """Rows n0, columns y₁…y₃: normalised histogram and N(μ_Q, Σ_Q,jj) overlay."""
    dy = hists[0]["y"].shape[1]
    fig, axes = plt.subplots(len(hists), dy, figsize=(4.0 * dy, 2.6 * len(hists)), squeeze=False)
    for i, h in enumerate(hists):
        for j in range(dy):
            ax = axes[i, j]
            y = h["y"][:, j]
            # np.histogram + stairs: one artist instead of 1000 bar patches
            dens, edges = np.histogram(y, bins=HIST_BINS, density=True)
            ax.stairs(dens, edges, fill=True, color="#4c72b0", alpha=0.7)
            s = np.sqrt(h["var"][j])
            t = np.linspace(y.min(), y.max(), 400)
            ax.plot(
                t,
                np.exp(-0.5 * ((t - h["mean"][j]) / s) ** 2) / (s * np.sqrt(2 * np.pi)),
                c="#c44e52",
                lw=1.2,
            )
            ax.set_title(f"n0 = {h['n0']}, y{j + 1}", fontsize=9)
            ax.grid(alpha=0.3)
    fig.suptitle(
        f"{title}: histogram of y ({hists[0]['y'].shape[0]} samples) and the Campbell Gaussian",
        fontsize=10,
    )
    fig.tight_layout()
    return save_figure(fig, path, dpi=_DPI)


def plot_bins(path, bins: dict, title: str) -> Path:
    """Mean (red), median (black) and 10–90 % (blue) of R per R₁ group; the diagonal R = R₁."""
    fig, ax = plt.subplots(figsize=(5.5, 5.0))
    x = np.asarray(bins["x"])
    ax.vlines(x, bins["p10"], bins["p90"], colors="#4c72b0", lw=1.5, label="10–90 %")
    ax.plot(x, bins["mean"], "o", c="#c44e52", label="mean R")
    ax.plot(x, bins["median"], "s", c="k", ms=4, label="median R")
    hi = max(float(np.max(bins["p90"])), float(x.max()), 1e-12)
    ax.plot([0, hi], [0, hi], c="#4c72b0", lw=0.8)
    ax.set_xlabel("R1(x) (Gaussian, group mean)")
    ax.set_ylabel("R(x) (exact)")
    ax.set_title(f"{title}: bin plot of R vs R1", fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    return save_figure(fig, path, dpi=_DPI)
