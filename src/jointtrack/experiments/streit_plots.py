"""Figures of the Streit reproduction (matplotlib, Agg backend: files only, no display).

R. L. Streit, "Saddle point method for JPDA and related filters", *Proc. 18th
International Conference on Information Fusion* (FUSION), 2015 — figure numbers
are that paper's; the data come from :func:`jointtrack.experiments.streit.reproduce`.

* :func:`figure1` / :func:`plot_figure1` — Re and Im of f(z) = e^z (1+10z)^4
  z^{-6} on three circles (``streit-figure1.png``).
* :func:`figure3` / :func:`plot_figure3` — histograms of approximate/exact for
  N = 7, M = 5, one panel per variant (``streit-figure3.png``).
* :func:`figure4` / :func:`plot_figure4` — histogram of the exact derivatives
  there (``streit-figure4.png``).
* :func:`cost_figure` / :func:`plot_cost` — seconds per particle vs M, one
  panel per N, and §7's parts (``streit-cost.png``).

The ``figure*`` functions return the :class:`matplotlib.figure.Figure` (for
tests and notebooks); the ``plot_*`` functions write it and return the path.
Every axis label ends with its unit, or says "(count)" / "(dimensionless)";
legends sit below the axes, never over the data; values that cannot be drawn
(non-finite, beyond 1e100, ≤ 0 on a log axis) are left out and counted in the
figure (:mod:`jointtrack.experiments._plot_values`).
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.ticker import Formatter, MaxNLocator  # noqa: E402

from jointtrack.experiments._plot_values import (  # noqa: E402
    REPRO_DPI,
    legend_below,
    off_scale_note,
    plottable,
)
from jointtrack.experiments.plots import save_figure  # noqa: E402

__all__ = [
    "cost_figure",
    "figure1",
    "figure3",
    "figure4",
    "plot_cost",
    "plot_figure1",
    "plot_figure3",
    "plot_figure4",
]

#: ticks at multiples of π/2 on the θ axis of Figure 1
_PI_TICKS = (
    [-np.pi, -np.pi / 2, 0.0, np.pi / 2, np.pi],
    [r"$-\pi$", r"$-\pi/2$", "0", r"$\pi/2$", r"$\pi$"],
)


class _FewestDecimals(Formatter):
    """Tick labels with the fewest decimals (up to 8) that reproduce every tick's value.

    The default formatter writes 0.99880, 0.99920, … around a ratio of 1; the
    ticks of a 0.0004 step need four decimals, not five.
    """

    def format_ticks(self, values):
        locs = np.asarray(values, dtype=float)
        finite = locs[np.isfinite(locs)]
        span = float(np.ptp(finite)) if finite.size > 1 else 1.0
        tol = 1e-9 * max(span, 1e-300)
        d = next(
            (d for d in range(9) if np.all(np.abs(np.round(finite, d) - finite) <= tol)),
            8,
        )
        return [f"{v:.{d}f}" for v in locs]

    def __call__(self, x, pos=None):
        return f"{x:.8g}"


def figure1(fig1: dict, n_theta: int = 2001):
    """Re f (left) and Im f (right) vs θ on r = 1.1, r̂, 6.3 (top to bottom), as Figure 1."""
    from jointtrack.experiments.streit import fig1_f

    theta = np.linspace(-np.pi, np.pi, n_theta)
    radii = fig1["radii"]
    fig, axes = plt.subplots(
        len(radii), 2, figsize=(10, 2.7 * len(radii)), sharex=True, layout="constrained"
    )
    for row, r in enumerate(radii):
        w = fig1_f(r * np.exp(1j * theta))
        on_saddle = abs(r - fig1["r_hat"]) < 1e-12
        circle = rf"$r = \hat r = {r:.4g}$ (saddle point)" if on_saddle else f"$r = {r:.4g}$"
        for col, (part, name) in enumerate(((w.real, "Re"), (w.imag, "Im"))):
            ax = axes[row, col]
            ax.plot(theta, part, lw=1.0, c="#4c72b0" if col == 0 else "#c44e52")
            ax.axhline(0.0, c="0.6", lw=0.6)
            ax.set_title(
                rf"$\mathrm{{{name}}}\,f(r e^{{i\theta}})$ on the circle {circle}", fontsize=9
            )
            ax.set_ylabel(rf"$\mathrm{{{name}}}\,f$ (dimensionless)", fontsize=9)
            ax.grid(alpha=0.3)
            ax.set_xticks(*_PI_TICKS)
            if row == len(radii) - 1:
                ax.set_xlabel(r"angle $\theta$ on the circle $z = r e^{i\theta}$ (rad)")
    fig.suptitle(
        rf"Streit Figure 1: $f(z) = e^z (1+10z)^4 z^{{-6}}$ on three circles; "
        rf"$\hat r = {fig1['r_hat']:.4f}$; "
        rf"$\frac{{1}}{{2\pi}}\int f\,d\theta = {fig1['coefficient_z6']:.4f}$ on every circle",
        fontsize=10,
    )
    return fig


def plot_figure1(path, fig1: dict, n_theta: int = 2001) -> Path:
    """Write :func:`figure1` to ``path``."""
    return save_figure(figure1(fig1, n_theta), path, dpi=REPRO_DPI)


def figure3(result: dict):
    """Histogram of approximate/exact per variant for N = 7, M = 5 (Figure 3), with the paper's."""
    from jointtrack.experiments.streit import VARIANTS

    f3 = result["figure3"]
    paper = f3["paper"]
    fig, axes = plt.subplots(
        1, len(VARIANTS), figsize=(5.6 * len(VARIANTS), 4.6), squeeze=False, layout="constrained"
    )
    for ax, v in zip(axes[0], VARIANTS, strict=True):
        st = f3["variants"].get(v, {"status": "not available"})
        ax.set_title(
            f"{v}: approximate / exact derivative (N = {f3['N']}, M = {f3['M']})", fontsize=9
        )
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
        r, n_off = plottable(f3["ratios"][v])
        r = r[np.isfinite(r)]
        label = f"{r.size} trials (histogram, 40 bins)"
        note = off_scale_note(n_off, "ratios")
        if note:
            label += f"; {note}"
        if r.size:
            ax.hist(r, bins=40, color="#4c72b0", alpha=0.85, label=label)
        ax.axvline(
            st["mean"],
            c="k",
            lw=1.2,
            label=f"ours: mean μ = {st['mean']:.4f} (σ = {st['std']:.4f})",
        )
        if v == "saddle":
            lo, hi = paper["mean"] - paper["std"], paper["mean"] + paper["std"]
            ax.axvline(
                paper["mean"],
                c="#c44e52",
                ls="--",
                lw=1.2,
                label=f"paper: mean μ = {paper['mean']}",
            )
            ax.axvspan(
                lo, hi, color="#c44e52", alpha=0.12, label=f"paper: μ ± σ (σ = {paper['std']})"
            )
        else:
            ax.axvline(1.0, c="#55a868", ls="--", lw=1.2, label="ratio 1 (approximation exact)")
        # at most 5 ticks with just enough decimals: the labels of a narrow
        # histogram around 1 (saddle-corrected) otherwise run together
        ax.xaxis.set_major_locator(MaxNLocator(nbins=5, steps=[1, 2, 2.5, 5, 10]))
        ax.xaxis.set_major_formatter(_FewestDecimals())
        ax.set_xlabel("approximate / exact mixed derivative (dimensionless)")
        ax.set_ylabel("trials per bin (count)")
        ax.legend(
            fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.16), ncols=2, frameon=False
        )
        ax.grid(alpha=0.3)
    fig.suptitle(
        f"Streit Figure 3: ratio of the saddle-point approximation to the exact derivative, "
        f"{result['settings']['trials']} random problems, seed {result['settings']['seed']}",
        fontsize=10,
    )
    return fig


def plot_figure3(path, result: dict) -> Path:
    """Write :func:`figure3` to ``path``."""
    return save_figure(figure3(result), path, dpi=REPRO_DPI)


def figure4(result: dict):
    """Histogram of the exact derivatives for N = 7, M = 5 (Figure 4)."""
    f4 = result["figure4"]
    x, n_off = plottable(f4["exact"])
    x = x[np.isfinite(x)]
    fig, ax = plt.subplots(figsize=(7, 4.4), layout="constrained")
    if x.size:
        ax.hist(x, bins=40, color="#55a868", alpha=0.85)
    note = off_scale_note(n_off, "derivatives")
    if note:
        ax.text(0.98, 0.97, note, ha="right", va="top", fontsize=7, transform=ax.transAxes)
    ax.set_xlabel("exact mixed derivative, eq. (18) (dimensionless)")
    ax.set_ylabel("trials per bin (count)")
    ax.set_title(
        f"Streit Figure 4: exact derivatives of {x.size} random problems, N = {f4['N']}, "
        f"M = {f4['M']}\nours {f4['min']:.3g} to {f4['max']:.3g}; paper: {f4['paper']['range']}",
        fontsize=9,
    )
    ax.grid(alpha=0.3)
    return fig


def plot_figure4(path, result: dict) -> Path:
    """Write :func:`figure4` to ``path``."""
    return save_figure(figure4(result), path, dpi=REPRO_DPI)


_STYLE = {
    "exact": ("#c44e52", "o-"),
    "exact-batched": ("#dd8452", "s-"),
    "saddle": ("#4c72b0", "^-"),
    "saddle-corrected": ("#8172b3", "v--"),
}
#: legend text per method: what each line times
_LEGEND = {
    "exact": "exact, one particle at a time",
    "exact-batched": "exact, all particles at once (jpda_log_weights)",
    "saddle": "saddle point",
    "saddle-corrected": "saddle point, corrected",
}


def _log_log(ax, ms) -> None:
    """Log axes with the grid's M values as x ticks: a power law is a straight line."""
    ax.set_xscale("log")
    ax.set_yscale("log")
    ms = sorted({int(m) for m in ms})
    ax.set_xticks(ms)
    ax.set_xticklabels([str(m) for m in ms])
    ax.minorticks_off()


def cost_figure(result: dict):
    """Seconds per particle vs M, one panel per N; last panel: §7's parts at the largest N.

    Hollow circles: a per-particle exact cell stopped by the time budget (the
    mean over the particles done). One legend below the panels explains every
    mark.
    """
    from jointtrack.experiments.streit import COST_METHODS

    rows = result["cost"]["rows"]
    Ns = sorted({r["N"] for r in rows})
    n = len(Ns) + 1
    ncols = min(3, n)
    nrows = -(-n // ncols)
    fig, grid = plt.subplots(
        nrows,
        ncols,
        figsize=(4.6 * ncols, 3.4 * nrows + 1.0),
        squeeze=False,
        sharey=True,
        layout="constrained",
    )
    axes = grid.ravel()
    for ax in axes[n:]:
        ax.set_visible(False)
    n_off = 0
    for ax, N in zip(axes, Ns, strict=False):
        mine = sorted((r for r in rows if r["N"] == N), key=lambda r: r["M"])
        for m in COST_METHODS:
            c, st = _STYLE[m]
            pts = [r for r in mine if r["methods"][m]["status"] in ("ok", "stopped")]
            if not pts:
                continue
            y, k = plottable([r["methods"][m]["seconds_per_particle"] for r in pts], log=True)
            n_off += k
            ms = np.array([r["M"] for r in pts], dtype=float)
            ax.plot(ms, y, st, c=c, ms=4, label=_LEGEND[m])
            stop = np.array([r["methods"][m]["status"] == "stopped" for r in pts])
            if stop.any():
                ax.plot(
                    ms[stop],
                    y[stop],
                    "o",
                    ms=9,
                    mfc="none",
                    c="k",
                    label="stopped by the time budget (mean of the particles done)",
                )
        _log_log(ax, [r["M"] for r in mine])
        ax.set_title(f"N = {N} targets: time per particle", fontsize=9)
        ax.set_xlabel("M, measurements (count)")
        ax.grid(alpha=0.3, which="both")
    for row in grid:
        row[0].set_ylabel("time per particle (s)")
    ax = axes[n - 1]
    N = Ns[-1]
    mine = sorted((r for r in rows if r["N"] == N), key=lambda r: r["M"])
    Ms = np.array([r["M"] for r in mine], dtype=float)
    for key, c, lab in (
        ("coefficients", "#55a868", "§7 part: coefficients, eq. (7)"),
        ("saddle_search", "#4c72b0", "§7 part: saddle search, eq. (24)"),
        ("determinants", "#c44e52", "§7 part: determinants, eq. (30)"),
    ):
        y, k = plottable([r["parts"][key] for r in mine], log=True)
        n_off += k
        ax.plot(Ms, y, "o-", c=c, ms=4, mfc="white", label=lab)
    det, _ = plottable([r["parts"]["determinants"] for r in mine], log=True)
    if len(Ms) > 1 and np.isfinite(det[-1]):
        for p, ls in ((1, ":"), (3, "--")):
            ax.plot(
                Ms,
                det[-1] * (Ms / Ms[-1]) ** p,
                ls,
                c="0.5",
                lw=0.8,
                label=rf"reference slope $\propto M^{p}$ (through the last determinant point)",
            )
    _log_log(ax, Ms)
    ax.set_title(f"§7 parts of the saddle method, N = {N}", fontsize=9)
    ax.set_xlabel("M, measurements (count)")
    ax.grid(alpha=0.3, which="both")
    note = off_scale_note(n_off, "times", log=True)
    L = result["settings"]["particles"]
    title = f"Streit §7: cost per particle (one target, L = {L} particles)"
    fig.suptitle(title + (f"; {note}" if note else ""), fontsize=10)
    legend_below(fig, axes[:n], ncols=2)
    return fig


def plot_cost(path, result: dict) -> Path:
    """Write :func:`cost_figure` to ``path``."""
    return save_figure(cost_figure(result), path, dpi=REPRO_DPI)
