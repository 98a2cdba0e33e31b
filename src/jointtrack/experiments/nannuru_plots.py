"""Figures of the Nannuru & Coates reproduction (matplotlib, Agg backend: files only).

S. Nannuru and M. Coates, "Gaussian approximation for superpositional sensors",
technical report, McGill University, 2015 — figure numbers are that report's;
the data come from :func:`jointtrack.experiments.nannuru.reproduce`.

* :func:`histogram_figure` / :func:`plot_histograms` — Figures 1–3: histograms
  (1000 bins) of each component of y for n0 = 4, 6, 8 with the Campbell
  Gaussian overlaid.
* :func:`bins_figure` / :func:`plot_bins` — Figures 4–5: bin plot of R(x)
  against R₁(x).

The ``*_figure`` functions return the :class:`matplotlib.figure.Figure`; the
``plot_*`` functions write it and return the path. The measurement y = Σ Hxᵢ + noise
is in metres (the states are positions in a 20 m × 20 m region and H is
unitless); R and R₁ are ratios of likelihoods, dimensionless. Values that
cannot be drawn are left out and counted in the figure
(:mod:`jointtrack.experiments._plot_values`).
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402
from matplotlib.patches import Patch  # noqa: E402

from jointtrack.experiments._plot_values import (  # noqa: E402
    REPRO_DPI,
    off_scale_note,
    plottable,
)
from jointtrack.experiments.plots import save_figure  # noqa: E402

__all__ = ["bins_figure", "histogram_figure", "plot_bins", "plot_histograms"]

HIST_BINS = 1000


def _gaussian_pdf(t: np.ndarray, mean: float, var: float) -> np.ndarray | None:
    """N(mean, var) density at ``t``; None when ``var`` is no usable variance."""
    if not (np.isfinite(mean) and np.isfinite(var) and var > 0):
        return None
    s = np.sqrt(var)
    # far in the tails z² overflows to inf and exp(-inf) = 0 is the right density
    with np.errstate(over="ignore"):
        z = (t - mean) / s
        return np.exp(-0.5 * z * z) / (s * np.sqrt(2 * np.pi))


def histogram_figure(hists: list[dict], title: str):
    """Rows n0, columns y₁…y₃: normalised histogram and N(μ_Q, Σ_Q,jj) overlay."""
    dy = hists[0]["y"].shape[1]
    fig, axes = plt.subplots(
        len(hists),
        dy,
        figsize=(4.0 * dy, 2.5 * len(hists) + 0.8),
        squeeze=False,
        layout="constrained",
    )
    n_off = 0
    for i, h in enumerate(hists):
        for j in range(dy):
            ax = axes[i, j]
            y, k = plottable(h["y"][:, j])
            n_off += k
            y = y[np.isfinite(y)]
            if y.size:
                # np.histogram + stairs: one artist instead of 1000 bar patches
                dens, edges = np.histogram(y, bins=HIST_BINS, density=True)
                ax.stairs(dens, edges, fill=True, color="#4c72b0", alpha=0.7)
                t = np.linspace(y.min(), y.max(), 400)
                pdf = _gaussian_pdf(t, float(h["mean"][j]), float(h["var"][j]))
                if pdf is not None:
                    ax.plot(t, pdf, c="#c44e52", lw=1.2)
            ax.set_title(f"$n_0 = {h['n0']}$, component $y_{j + 1}$", fontsize=9)
            ax.grid(alpha=0.3)
            if i == len(hists) - 1:
                ax.set_xlabel(f"$y_{j + 1}$ (m)")
            if j == 0:
                ax.set_ylabel("density (1/m)")
    n = hists[0]["y"].shape[0]
    handles = [
        Patch(color="#4c72b0", alpha=0.7, label=f"histogram of {n} sampled y ({HIST_BINS} bins)"),
        Line2D(
            [],
            [],
            c="#c44e52",
            lw=1.2,
            label=r"Campbell Gaussian $\mathcal{N}(\mu_j, \Sigma_{jj})$ of (4)–(7)",
        ),
    ]
    fig.legend(handles=handles, loc="outside lower center", ncols=2, fontsize=8, frameon=False)
    note = off_scale_note(n_off, "samples")
    fig.suptitle(
        f"{title}: distribution of the superposed measurement y vs its Gaussian approximation"
        + (f"\n{note}" if note else ""),
        fontsize=10,
    )
    return fig


def plot_histograms(path, hists: list[dict], title: str) -> Path:
    """Write :func:`histogram_figure` to ``path``."""
    return save_figure(histogram_figure(hists, title), path, dpi=REPRO_DPI)


def bins_figure(bins: dict, title: str):
    """Mean (red), median (black) and 10–90 % (blue) of R per R₁ group; the diagonal R = R₁."""
    fig, ax = plt.subplots(figsize=(5.6, 5.6), layout="constrained")
    x, n_off = plottable(bins["x"])
    cols = {}
    for key in ("p10", "p90", "mean", "median"):
        cols[key], k = plottable(bins[key])
        n_off += k
    ok = np.isfinite(x)
    ax.vlines(
        x[ok],
        cols["p10"][ok],
        cols["p90"][ok],
        colors="#4c72b0",
        lw=1.5,
        label="10th–90th percentile of R in the group",
    )
    ax.plot(x, cols["mean"], "o", c="#c44e52", label="mean of R in the group")
    ax.plot(x, cols["median"], "s", c="k", ms=4, label="median of R in the group")
    tops = [
        v
        for v in (np.nanmax(cols["p90"], initial=0.0), np.nanmax(x, initial=0.0))
        if np.isfinite(v)
    ]
    hi = max([*tops, 1e-12])
    ax.plot([0, hi], [0, hi], c="0.4", lw=0.8, ls="--", label="R = R₁ (exact approximation)")
    ax.set_xlabel("R₁(x), Gaussian approximation (20), group mean (dimensionless)")
    ax.set_ylabel("R(x), exact update ratio (16) (dimensionless)")
    note = off_scale_note(n_off, "values")
    ax.set_title(
        f"{title}\n{len(x)} equal-count groups of states by R₁" + (f"; {note}" if note else ""),
        fontsize=9,
    )
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.12), ncols=2, frameon=False)
    return fig


def plot_bins(path, bins: dict, title: str) -> Path:
    """Write :func:`bins_figure` to ``path``."""
    return save_figure(bins_figure(bins, title), path, dpi=REPRO_DPI)
