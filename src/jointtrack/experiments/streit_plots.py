"""Figures of the Streit reproduction (matplotlib, Agg backend: files only, no display).

R. L. Streit, "Saddle point method for JPDA and related filters", *Proc. 18th
International Conference on Information Fusion* (FUSION), 2015 — figure numbers
are that paper's; the data come from :func:`jointtrack.experiments.streit.reproduce`.

* :func:`plot_figure1` — Re and Im of f(z) = e^z (1+10z)^4 z^{-6} on three
  circles (``streit-figure1.png``).
* :func:`plot_figure3` — histograms of approximate/exact for N = 7, M = 5, one
  panel per variant (``streit-figure3.png``).
* :func:`plot_figure4` — histogram of the exact derivatives there
  (``streit-figure4.png``).
* :func:`plot_cost` — seconds per particle vs M, one panel per N, and §7's
  parts (``streit-cost.png``).
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from jointtrack.experiments.plots import save_figure  # noqa: E402

__all__ = ["plot_cost", "plot_figure1", "plot_figure3", "plot_figure4"]


def plot_figure1(path, fig1: dict, n_theta: int = 2001) -> Path:
    """Re f (left) and Im f (right) vs θ on r = 1.1, r̂, 6.3 (top to bottom), as Figure 1."""
    from jointtrack.experiments.streit import fig1_f

    theta = np.linspace(-np.pi, np.pi, n_theta)
    radii = fig1["radii"]
    fig, axes = plt.subplots(len(radii), 2, figsize=(10, 2.6 * len(radii)), sharex=True)
    for row, r in enumerate(radii):
        w = fig1_f(r * np.exp(1j * theta))
        which = "r̂ (saddle point)" if abs(r - fig1["r_hat"]) < 1e-12 else "r"
        for col, (part, name) in enumerate(((w.real, "Re"), (w.imag, "Im"))):
            ax = axes[row, col]
            ax.plot(theta, part, lw=1.0, c="#4c72b0" if col == 0 else "#c44e52")
            ax.axhline(0.0, c="0.6", lw=0.6)
            ax.set_title(f"{name} f(r e^{{iθ}}), {which} = {r:.4g}", fontsize=9)
            ax.grid(alpha=0.3)
            if row == len(radii) - 1:
                ax.set_xlabel("θ")
    fig.suptitle(
        f"Streit Figure 1: f(z) = e^z (1+10z)^4 z^-6; r̂ = {fig1['r_hat']:.4f}; "
        f"(1/2π)∫ f dθ = {fig1['coefficient_z6']:.4f} on every circle",
        fontsize=10,
    )
    fig.tight_layout()
    return save_figure(fig, path)


def plot_figure3(path, result: dict) -> Path:
    """Histogram of approximate/exact per variant for N = 7, M = 5 (Figure 3), with the paper's."""
    from jointtrack.experiments.streit import VARIANTS

    f3 = result["figure3"]
    paper = f3["paper"]
    fig, axes = plt.subplots(1, len(VARIANTS), figsize=(5.5 * len(VARIANTS), 4.2), squeeze=False)
    for ax, v in zip(axes[0], VARIANTS, strict=True):
        st = f3["variants"].get(v, {"status": "not available"})
        ax.set_title(f"{v}: approximate / exact (N = {f3['N']}, M = {f3['M']})", fontsize=9)
        if st.get("status") != "ok":
            ax.text(
                0.5,
                0.5,
                f"{v}: {st.get('status')}",
                ha="center",
                va="center",
                transform=ax.transAxes,
            )
            ax.set_xticks([])
            ax.set_yticks([])
            continue
        r = np.asarray(f3["ratios"][v], dtype=float)
        r = r[np.isfinite(r)]
        ax.hist(r, bins=40, color="#4c72b0", alpha=0.85)
        ax.axvline(
            st["mean"], c="k", lw=1.2, label=f"ours μ = {st['mean']:.4f}, σ = {st['std']:.4f}"
        )
        if v == "saddle":
            lo, hi = paper["mean"] - paper["std"], paper["mean"] + paper["std"]
            ax.axvline(
                paper["mean"],
                c="#c44e52",
                ls="--",
                lw=1.2,
                label=f"paper μ = {paper['mean']}, σ = {paper['std']}",
            )
            ax.axvspan(lo, hi, color="#c44e52", alpha=0.12, label="paper μ ± σ")
        else:
            ax.axvline(1.0, c="#55a868", ls="--", lw=1.2, label="1 (exact)")
        ax.set_xlabel("ratio")
        ax.set_ylabel("trials")
        ax.legend(fontsize=7)
        ax.grid(alpha=0.3)
    fig.suptitle(
        f"Streit Figure 3: {result['settings']['trials']} trials, "
        f"seed {result['settings']['seed']}",
        fontsize=10,
    )
    fig.tight_layout()
    return save_figure(fig, path)


def plot_figure4(path, result: dict) -> Path:
    """Histogram of the exact derivatives for N = 7, M = 5 (Figure 4)."""
    f4 = result["figure4"]
    x = np.asarray(f4["exact"], dtype=float)
    fig, ax = plt.subplots(figsize=(7, 4.2))
    ax.hist(x, bins=40, color="#55a868", alpha=0.85)
    ax.set_xlabel("exact mixed derivative (18)")
    ax.set_ylabel("trials")
    ax.set_title(
        f"Streit Figure 4: exact derivatives, N = {f4['N']}, M = {f4['M']} — ours "
        f"{f4['min']:.3g}–{f4['max']:.3g}; paper: {f4['paper']['range']}",
        fontsize=9,
    )
    ax.grid(alpha=0.3)
    fig.tight_layout()
    return save_figure(fig, path)


_STYLE = {
    "exact": ("#c44e52", "o-"),
    "exact-batched": ("#dd8452", "s-"),
    "saddle": ("#4c72b0", "^-"),
    "saddle-corrected": ("#8172b3", "v--"),
}


def _log_log(ax, ms) -> None:
    """Log axes with the grid's M values as x ticks: a power law is a straight line."""
    ax.set_xscale("log")
    ax.set_yscale("log")
    ms = sorted({int(m) for m in ms})
    ax.set_xticks(ms)
    ax.set_xticklabels([str(m) for m in ms])
    ax.minorticks_off()


def plot_cost(path, result: dict) -> Path:
    """Seconds per particle vs M, one panel per N; last panel: §7's parts at the largest N.

    Hollow markers: a per-particle exact cell stopped by the time budget (the
    mean over the particles done).
    """
    from jointtrack.experiments.streit import COST_LABELS, COST_METHODS

    rows = result["cost"]["rows"]
    Ns = sorted({r["N"] for r in rows})
    n = len(Ns) + 1
    ncols = min(3, n)
    nrows = -(-n // ncols)
    fig, grid = plt.subplots(
        nrows, ncols, figsize=(4.6 * ncols, 3.9 * nrows), squeeze=False, sharey=True
    )
    axes = grid.ravel()
    for ax in axes[n:]:
        ax.set_visible(False)
    for ax, N in zip(axes, Ns, strict=False):
        mine = sorted((r for r in rows if r["N"] == N), key=lambda r: r["M"])
        for m in COST_METHODS:
            c, st = _STYLE[m]
            pts = [
                (r["M"], r["methods"][m]["seconds_per_particle"], r["methods"][m]["status"])
                for r in mine
                if r["methods"][m]["status"] in ("ok", "stopped")
            ]
            if not pts:
                continue
            ax.plot([p[0] for p in pts], [p[1] for p in pts], st, c=c, ms=4, label=COST_LABELS[m])
            stop = [p for p in pts if p[2] == "stopped"]
            if stop:
                ax.plot(
                    [p[0] for p in stop],
                    [p[1] for p in stop],
                    "o",
                    ms=9,
                    mfc="none",
                    c="k",
                    label="stopped (budget)",
                )
        _log_log(ax, [r["M"] for r in mine])
        ax.set_title(f"N = {N}", fontsize=9)
        ax.set_xlabel("M (measurements)")
        ax.grid(alpha=0.3, which="both")
    for row in grid:
        row[0].set_ylabel("seconds per particle")
    handles = {}
    for ax in axes[: n - 1]:
        for h, lab in zip(*ax.get_legend_handles_labels(), strict=True):
            handles.setdefault(lab, h)
    axes[0].legend(handles.values(), handles.keys(), fontsize=7, loc="upper left")
    ax = axes[n - 1]
    N = Ns[-1]
    mine = sorted((r for r in rows if r["N"] == N), key=lambda r: r["M"])
    Ms = np.array([r["M"] for r in mine], dtype=float)
    for key, c, lab in (
        ("coefficients", "#55a868", "coefficients (7)"),
        ("saddle_search", "#4c72b0", "saddle search (24)"),
        ("determinants", "#c44e52", "determinants (30)"),
    ):
        y = np.array([r["parts"][key] for r in mine], dtype=float)
        y = np.where(y > 0, y, np.nan)
        ax.plot(Ms, y, "o-", c=c, ms=4, label=lab)
    if len(Ms) > 1:
        ref = np.array([r["parts"]["determinants"] for r in mine], dtype=float)[-1]
        if ref > 0:
            for p, ls in ((1, ":"), (3, "--")):
                ax.plot(
                    Ms,
                    ref * (Ms / Ms[-1]) ** p,
                    ls,
                    c="0.5",
                    lw=0.8,
                    label=f"∝ M{'¹' if p == 1 else '³'}",
                )
    _log_log(ax, Ms)
    ax.set_title(f"§7 parts, N = {N}", fontsize=9)
    ax.set_xlabel("M (measurements)")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=7, loc="upper left")
    fig.suptitle(
        f"Streit §7: cost per particle (one target, L = {result['settings']['particles']})",
        fontsize=10,
    )
    fig.tight_layout()
    return save_figure(fig, path)
