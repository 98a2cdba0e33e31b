"""Figure of the Bojilov reproduction (matplotlib, Agg backend: files only, no display).

B. Bojilov, K. Alexiev and P. Konstantinova, "One particular program realisation
of JPDA algorithm", Tables 2 and 3 — the data come from
:func:`jointtrack.experiments.bojilov.reproduce`.

* :func:`bojilov_figure` / :func:`plot_bojilov` — seconds and operations per
  cluster vs targets in the cluster, ours and the paper's
  (``reproduce-bojilov.png``).

Every axis label ends with its unit ("(s)", "(count)"); one legend below the
panels explains every mark; values that cannot be drawn on the log axes are left
out and counted (:mod:`jointtrack.experiments._plot_values`).
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402

from jointtrack.experiments._plot_values import (  # noqa: E402
    REPRO_DPI,
    legend_below,
    off_scale_note,
    plottable,
)
from jointtrack.experiments.plots import save_figure  # noqa: E402

__all__ = ["bojilov_figure", "plot_bojilov"]

_METHOD_STYLE = {
    "naive": ("#c44e52", "naive enumeration"),
    "optimised": ("#4c72b0", "optimised enumeration"),
    "exact": ("#55a868", "jointtrack exact marginals"),
}


def _key(beta) -> str:
    return f"beta={float(beta):g}"


def _ours_vs_paper(ax, n, rows, keys, paper_rows, off) -> int:
    """Our means (filled, solid) and the paper's values (hollow, dashed); off-scale count.

    ``keys``: (method, result key); ``paper_rows``: the paper's table rows by
    cluster size; ``off``: its column offset for this β (naive at ``off``,
    optimised at ``off + 1``).
    """
    n_off = 0
    for m, key in keys:
        c, lab = _METHOD_STYLE[m]
        y, k = plottable([r.get(key) for r in rows], log=True)
        n_off += k
        ax.plot(n, y, "o-", c=c, label=f"ours: {lab}")
    for m, j in (("naive", 0), ("optimised", 1)):
        c, lab = _METHOD_STYLE[m]
        xs = sorted(paper_rows)
        y, k = plottable([paper_rows[x][off + j] for x in xs], log=True)
        n_off += k
        ax.plot(xs, y, "s--", mfc="none", c=c, ms=8, label=f"paper: {lab}")
    return n_off


def _log_panel(ax, title: str, ylabel: str) -> None:
    """Log y axis, title, labels, ticks at 2–5 targets and grid of a Bojilov panel."""
    ax.set_yscale("log")
    ax.set_title(title, fontsize=10)
    ax.set_ylabel(ylabel)
    ax.set_xticks([2, 3, 4, 5])
    ax.grid(alpha=0.3, which="both")


def bojilov_figure(result: dict):
    """Seconds and operations per cluster vs targets in the cluster, ours and the paper's.

    ``result`` is the dict of :func:`jointtrack.experiments.bojilov.reproduce`.
    Top row: Table 3 (seconds per cluster, log scale) for β = 1, 2; bottom
    row: Table 2 (operations per cluster: ours count multiplications, the paper
    floating point operations). Solid lines: ours; hollow squares: the paper's.
    """
    paper = result["paper"]
    betas = list(result["betas"])
    fig, axes = plt.subplots(
        2, len(betas), figsize=(6 * len(betas), 8.6), squeeze=False, layout="constrained"
    )
    p2 = {r[0]: r for r in paper["table2_flops_per_cluster"]["rows"]}
    p3 = {r[0]: r for r in paper["table3_seconds_per_cluster"]["rows"]}
    n_off = 0
    for col, beta in enumerate(betas):
        rows = result["results"][_key(beta)]["rows"]
        rows = [r for r in rows if r["n_clusters"] > 0]
        n = [r["targets"] for r in rows]
        off = 1 if float(beta) == 1.0 else 4  # paper column offset (beta1 / beta2)
        ax = axes[0, col]
        n_off += _ours_vs_paper(
            ax,
            n,
            rows,
            (
                ("naive", "mean_seconds_naive"),
                ("optimised", "mean_seconds_optimised"),
                ("exact", "mean_seconds_exact"),
            ),
            p3,
            off,
        )
        ax.axhline(1e-3, c="0.5", ls=":", lw=1, label="1 ms per cluster (the issue's target)")
        _log_panel(ax, f"Table 3: time per cluster, β = {beta:g}", "time per cluster (s)")
        ax = axes[1, col]
        n_off += _ours_vs_paper(
            ax,
            n,
            rows,
            (("naive", "mean_mult_naive"), ("optimised", "mean_mult_optimised")),
            p2,
            off,
        )
        ax.set_xlabel("targets (tracks) in the cluster (count)")
        _log_panel(
            ax,
            f"Table 2: operations per cluster, β = {beta:g}\n"
            "(ours: multiplications; paper: floating point operations)",
            "operations per cluster (count)",
        )
    legend_below(fig, axes.ravel(), ncols=3)
    note = off_scale_note(n_off, "values", log=True)
    fig.suptitle(
        f"Bojilov et al. Tables 2–3 vs jointtrack: cost of one cluster's association "
        f"({result['settings']['runs']} runs per β; the β units differ, compare trends)"
        + (f"\n{note}" if note else ""),
        fontsize=11,
    )
    return fig


def plot_bojilov(path, result: dict) -> Path:
    """Write :func:`bojilov_figure` to ``path``."""
    return save_figure(bojilov_figure(result), path, dpi=REPRO_DPI)
