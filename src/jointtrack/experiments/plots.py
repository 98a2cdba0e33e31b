"""Figures of the experiments (matplotlib, Agg backend: files only, no display).

* :func:`plot_scene` — truth, detections and tracks of a run (``scene.png``).
* :func:`plot_gospa` — GOSPA over time and its decomposition (``gospa.png``).
* :func:`plot_bojilov` — association cost per cluster size vs Bojilov's
  Tables 2–3 (``reproduce-bojilov.png``).
* :func:`plot_schaub` — max KL divergence vs time step per method, one of
  Schaub's Figures 5–7 (``schaub-example{1,2,3}.png``).
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

__all__ = ["plot_bojilov", "plot_gospa", "plot_scene", "plot_schaub", "save_figure"]

_MAX_LABELLED_TRACKS = 60


def save_figure(fig, path, dpi: int = 120) -> Path:
    """Write ``fig`` to ``path`` (its directory made), close it, return the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    return path


def _figsize(region) -> tuple[float, float]:
    if region is None:
        return (9.0, 7.0)
    w, h = float(np.ptp(region[0])), float(np.ptp(region[1]))
    aspect = min(max(h / w, 0.35), 1.0) if w > 0 else 1.0
    return (12.0, max(4.5, 12.0 * aspect * 0.9))


def plot_scene(
    path,
    *,
    times,
    scans,
    tracks,
    origins=None,
    truth=None,
    region=None,
    title: str = "",
    sensor=None,
) -> Path:
    """Truth lines, detections (grey dots, clutter lighter) and confirmed tracks with ids.

    ``scans``: per-scan (M_k, d) detections as Cartesian positions (convert
    range–bearing measurements first); ``origins``: per-scan target id or
    −1 (clutter), or ``None`` (unknown); ``truth`` and ``tracks``: flat tables
    ``(times, ids, positions)``; ``region``: (d, 2) box for the axis limits;
    ``sensor``: (x, y) of a sensor to mark, or ``None``.
    Only the first two coordinates are drawn.
    """
    fig, ax = plt.subplots(figsize=_figsize(region))
    pts = [z for z in scans if len(z)]
    if pts:
        Z = np.concatenate(pts)
        if origins is not None:
            org = np.concatenate([o for o, z in zip(origins, scans, strict=True) if len(z)])
            clutter = org < 0
            for sel, sz, grey, lab, zo in (
                (clutter, 2, "0.82", "clutter", 1),
                (~clutter, 4, "0.45", "target detections", 2),
            ):
                ax.scatter(
                    Z[sel, 0], Z[sel, 1], s=sz, c=grey, lw=0, label=lab, zorder=zo, rasterized=True
                )
        else:
            ax.scatter(
                Z[:, 0], Z[:, 1], s=3, c="0.6", lw=0, label="detections", zorder=1, rasterized=True
            )
    if truth is not None and len(truth[0]):
        tt, ti, tp = truth
        first = True
        for i in np.unique(ti):
            m = ti == i
            o = np.argsort(tt[m], kind="stable")
            ax.plot(
                tp[m][o, 0],
                tp[m][o, 1],
                "-",
                c="k",
                lw=1.2,
                alpha=0.8,
                zorder=3,
                label="truth" if first else None,
            )
            first = False
    if sensor is not None:  # marked and named in place (the legend scales markers ×3)
        sx, sy = (float(v) for v in np.asarray(sensor, dtype=float)[:2])
        ax.plot([sx], [sy], "^", ms=9, c="k", mec="w", zorder=6)
        ax.annotate(
            "sensor", (sx, sy), xytext=(6, -4), textcoords="offset points", fontsize=8, zorder=6
        )
    et, ei, ep = tracks
    ids = np.unique(ei)
    cmap = plt.get_cmap("tab10" if len(ids) <= 10 else "tab20")
    label = len(ids) <= _MAX_LABELLED_TRACKS
    for n, i in enumerate(ids):
        m = ei == i
        o = np.argsort(et[m], kind="stable")
        p = ep[m][o]
        col = cmap(n % cmap.N)
        ax.plot(
            p[:, 0],
            p[:, 1],
            "-",
            c=col,
            lw=1.6,
            zorder=4,
            label="confirmed tracks" if n == 0 else None,
        )
        if label:
            ax.annotate(
                str(int(i)),
                p[-1, :2],
                xytext=(3, 3),
                textcoords="offset points",
                fontsize=8,
                color=col,
                fontweight="bold",
                zorder=5,
            )
    if region is not None:
        box = np.asarray(region, dtype=float)[:2].copy()
        if len(ep):  # tracks that wander off the region stay in view
            box[:, 0] = np.minimum(box[:, 0], ep[:, :2].min(axis=0))
            box[:, 1] = np.maximum(box[:, 1], ep[:, :2].max(axis=0))
        pad = 0.03 * np.ptp(box, axis=1)
        ax.set_xlim(box[0, 0] - pad[0], box[0, 1] + pad[0])
        ax.set_ylim(box[1, 0] - pad[1], box[1, 1] + pad[1])
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    n_t = len(np.unique(times)) if len(times) else 0
    extra = "" if label else " (ids not shown)"
    ax.set_title(f"{title} — {n_t} scans, {len(ids)} confirmed tracks{extra}".strip(" —"))
    if ax.get_legend_handles_labels()[0]:
        ax.legend(loc="upper left", fontsize=8, markerscale=3, framealpha=0.85)
    ax.grid(alpha=0.2)
    fig.tight_layout()
    return save_figure(fig, path)


def plot_gospa(path, series, title: str = "") -> Path:
    """GOSPA per scan (top) and its p-th-power parts stacked (bottom)."""
    fig, (ax1, ax2) = plt.subplots(
        2, 1, figsize=(10, 6.5), sharex=True, gridspec_kw={"height_ratios": [1, 1.3]}
    )
    t = series.times
    ax1.plot(t, series.gospa, c="k", lw=1.4)
    ax1.set_ylabel(f"GOSPA (c={series.c:g}, p={series.p:g})")
    ax1.set_title(f"{title} — mean GOSPA {series.mean:.3g}".strip(" —"))
    ax1.grid(alpha=0.3)
    ax2.stackplot(
        t,
        series.localisation,
        series.missed,
        series.false,
        labels=["localisation", "missed targets", "false targets"],
        colors=["#4c72b0", "#dd8452", "#c44e52"],
        alpha=0.85,
    )
    ax2.set_ylabel(f"GOSPA^{series.p:g} parts")
    ax2.set_xlabel("time")
    ax2.legend(loc="upper left", fontsize=8)
    ax2.grid(alpha=0.3)
    fig.tight_layout()
    return save_figure(fig, path)


_METHOD_STYLE = {
    "naive": ("#c44e52", "naive enumeration"),
    "optimised": ("#4c72b0", "optimised enumeration"),
    "exact": ("#55a868", "jointtrack exact"),
}


def _ours_vs_paper(ax, n, rows, keys, paper_rows, off, ours_note="", paper_note=""):
    """Our means (lines, ``keys``: (method, result key)) and the paper's values (hollow).

    ``paper_rows``: the paper's table rows by cluster size; ``off``: its column
    offset for this β (naive at ``off``, optimised at ``off + 1``).
    """
    for m, key in keys:
        c, lab = _METHOD_STYLE[m]
        ax.plot(n, [r[key] for r in rows], "o-", c=c, label=f"ours: {lab}{ours_note}")
    for m, j in (("naive", 0), ("optimised", 1)):
        c, lab = _METHOD_STYLE[m]
        xs = sorted(paper_rows)
        ax.plot(
            xs,
            [paper_rows[x][off + j] for x in xs],
            "s--",
            mfc="none",
            c=c,
            ms=8,
            label=f"paper: {lab}{paper_note}",
        )


def _log_panel(ax, title: str, ylabel: str) -> None:
    """Log y axis, title, labels, ticks at 2–5 targets, grid and legend of a Bojilov panel."""
    ax.set_yscale("log")
    ax.set_title(title)
    ax.set_ylabel(ylabel)
    ax.set_xticks([2, 3, 4, 5])
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=7, loc="upper left")


def plot_bojilov(path, result: dict) -> Path:
    """Seconds and multiplications per cluster vs targets in the cluster, ours and the paper's.

    ``result`` is the dict of :func:`jointtrack.experiments.bojilov.reproduce`.
    Top row: Table 3 (seconds per cluster, log scale) for β = 1, 2; bottom
    row: Table 2 (multiplications per cluster; the paper counts floating point
    operations). Lines: ours; hollow markers: the paper's values.
    """
    paper = result["paper"]
    betas = [b for b in result["betas"]]
    fig, axes = plt.subplots(2, len(betas), figsize=(6 * len(betas), 8), squeeze=False)
    p2 = {r[0]: r for r in paper["table2_flops_per_cluster"]["rows"]}
    p3 = {r[0]: r for r in paper["table3_seconds_per_cluster"]["rows"]}
    for col, beta in enumerate(betas):
        rows = result["results"][_key(beta)]["rows"]
        rows = [r for r in rows if r["n_clusters"] > 0]
        n = [r["targets"] for r in rows]
        off = 1 if float(beta) == 1.0 else 4  # paper column offset (beta1 / beta2)
        ax = axes[0, col]
        _ours_vs_paper(
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
        ax.axhline(1e-3, c="0.5", ls=":", lw=1)
        ax.text(2.0, 1.15e-3, "target 1 ms", fontsize=8, color="0.4")
        _log_panel(ax, f"Table 3: seconds per cluster, β = {beta:g}", "seconds per cluster")
        ax = axes[1, col]
        _ours_vs_paper(
            ax,
            n,
            rows,
            (("naive", "mean_mult_naive"), ("optimised", "mean_mult_optimised")),
            p2,
            off,
            ours_note=" (multiplications)",
            paper_note=" (flops)",
        )
        ax.set_xlabel("targets (tracks) in cluster")
        _log_panel(ax, f"Table 2: operations per cluster, β = {beta:g}", "operations per cluster")
    fig.suptitle(
        f"Bojilov et al. Tables 2–3 vs jointtrack ({result['settings']['runs']} runs per β; "
        "β units differ, compare trends)",
        fontsize=11,
    )
    fig.tight_layout()
    return save_figure(fig, path)


def _key(beta) -> str:
    return f"beta={float(beta):g}"


def plot_schaub(path, res: dict, paper: dict) -> Path:
    """Max KL (58) vs time step for every method — Schaub's Figures 5–7 for one example.

    An infinite divergence (the one-hot max-weight answer while it is wrong) is
    drawn as a marker at the top edge instead of a point.
    """
    from jointtrack.experiments.schaub import LABELS

    ex = str(res["example"])
    fig, ax = plt.subplots(figsize=(8.0, 4.8))
    finite_max = max(
        (v for series in res["max_kl"].values() for v in series if np.isfinite(v)), default=1.0
    )
    top = max(1.0, 1.15 * finite_max)
    styles = {"exact": "-", "sinkhorn": "--", "local": ":", "maxweight": "-."}
    colors = {}
    for m, series in res["max_kl"].items():
        y = np.array(series, dtype=float)
        k = np.arange(1, y.size + 1)
        finite = np.isfinite(y)
        (line,) = ax.plot(
            np.where(finite, k, np.nan),
            np.where(finite, y, np.nan),
            styles.get(m, "-"),
            label=LABELS.get(m, m),
        )
        colors[m] = line.get_color()
        if (~finite).any():
            ax.plot(
                k[~finite],
                np.full((~finite).sum(), top),
                "v",
                color=line.get_color(),
                markersize=4,
                label=f"{LABELS.get(m, m)}: ∞ (wrong)",
            )
    med = res.get("over_seeds", {}).get("median_max_kl")
    if med and len(res["over_seeds"]["seeds"]) > 1:
        for m, series in med.items():
            y = np.array(series, dtype=float)
            ax.plot(
                np.arange(1, y.size + 1),
                np.where(np.isfinite(y), y, np.nan),
                styles.get(m, "-"),
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
            label=f"thin: median over {len(res['over_seeds']['seeds'])} seeds",
        )
    ax.axhline(np.log(2), color="grey", lw=0.6)
    ax.text(1, np.log(2), " ln 2", va="bottom", fontsize=8, color="grey")
    ax.set_ylim(0, top * 1.05)
    ax.set_xlabel("time step k")
    ax.set_ylabel(f"max KL over observed tracks, nats ({res['plotted_kl']})")
    ax.set_title(
        f"Schaub example {ex} (seed {res['seed']}): {res['n_observed_tracks']} observed tracks, "
        f"{res['n_identities']} identities — exact {1e3 * res['seconds_per_step']['exact']:.1f} "
        f"ms/step (paper {1e3 * paper['seconds_per_step'][ex]:.0f} ms)",
        fontsize=9,
    )
    ax.legend(fontsize=8)
    fig.tight_layout()
    return save_figure(fig, path)
