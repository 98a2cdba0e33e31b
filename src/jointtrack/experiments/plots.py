"""Figures of the experiments (matplotlib, Agg backend: files only, no display).

* :func:`plot_scene` — truth, detections and tracks of a run (``scene.png``);
  :func:`scene_figure` returns the open figure.
* :func:`plot_gospa` — GOSPA over time and its decomposition (``gospa.png``);
  :func:`gospa_figure` returns the open figure.

The reproductions' figures live beside their experiments (``bojilov_plots``,
``schaub_plots``, ``streit_plots``, ``nannuru_plots``).
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

__all__ = [
    "PLOT_LIMIT",
    "gospa_figure",
    "plot_gospa",
    "plot_scene",
    "save_figure",
    "scene_figure",
]

_MAX_LABELLED_TRACKS = 60
#: A run with more tracks or scans than these is drawn as a long run: thin lines and
#: only the tracks that lasted at least ``_LONG_RUN_MIN_SCANS`` scans.
_LONG_RUN_TRACKS = 100
_LONG_RUN_SCANS = 500
_LONG_RUN_MIN_SCANS = 5
#: Coordinates beyond this are not drawn (the tracker refuses detections beyond it; a
#: truth file may hold more): matplotlib's autoscaling overflows near the float limit.
PLOT_LIMIT = 1e150


def save_figure(fig, path, dpi: int = 120) -> Path:
    """Write ``fig`` to ``path`` (its directory made), close it, return the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    return path


def _count(n: int, noun: str) -> str:
    """``1 track``, ``1,583 tracks``."""
    return f"{n:,} {noun}{'' if n == 1 else 's'}"


def _drawable(points) -> np.ndarray:
    """Rows of ``points`` whose first two coordinates are finite and within ±PLOT_LIMIT."""
    xy = np.asarray(points, dtype=float)
    if xy.ndim != 2 or xy.shape[0] == 0:
        return np.zeros(xy.shape[:1], dtype=bool)
    xy = xy[:, :2]
    return np.isfinite(xy).all(axis=1) & (np.abs(np.nan_to_num(xy)) <= PLOT_LIMIT).all(axis=1)


def _region_box(region):
    """``region``'s first two rows as a (2, 2) float box, or None if it cannot be drawn."""
    if region is None:
        return None
    box = np.asarray(region, dtype=float)[:2]
    if box.shape != (2, 2) or not np.isfinite(box).all() or (np.abs(box) > PLOT_LIMIT).any():
        return None
    return box


def _figsize(box) -> tuple[float, float]:
    """Width leaves room for the legend at the right of the axes."""
    if box is None:
        return (11.5, 7.5)
    w, h = float(box[0, 1] - box[0, 0]), float(box[1, 1] - box[1, 0])
    aspect = min(max(h / w, 0.35), 1.0) if w > 0 else 1.0
    return (14.0, max(4.8, 10.0 * aspect * 0.9))


def _directions(ends: np.ndarray, befores: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit direction vectors ``ends − befores`` (rows with no movement dropped), and the mask."""
    d = ends - befores
    n = np.hypot(d[:, 0], d[:, 1]) if len(d) else np.zeros(0)
    ok = np.isfinite(n) & (n > 0)
    return d[ok] / n[ok, None], ok


def _arrows(ax, ends, befores, colors, size_in: float, zorder: int) -> None:
    """Arrow heads of ``size_in`` inches at ``ends``, pointing from ``befores``."""
    if not len(ends):
        return
    uv, ok = _directions(ends, befores)
    if not ok.any():
        return
    ax.quiver(
        ends[ok, 0],
        ends[ok, 1],
        uv[:, 0],
        uv[:, 1],
        color=[colors[i] for i in np.flatnonzero(ok)],
        angles="xy",
        scale_units="inches",
        scale=1.0 / size_in,
        units="inches",
        width=size_in * 0.08,
        headwidth=5,
        headlength=6,
        headaxislength=5.5,
        pivot="tip",
        zorder=zorder,
    )


def _paths(t, i, p):
    """Per id (sorted): its positions in time order."""
    out = {}
    for k in np.unique(i):
        m = i == k
        o = np.argsort(t[m], kind="stable")
        out[k] = p[m][o]
    return out


def _draw_scene(ax, *, scans, origins, truth, tracks, box, sensor, crowded, first_label):
    """Detections, truth and tracks into ``ax``; returns the title's account of the tracks.

    ``crowded``: thin lines and only tracks of at least ``_LONG_RUN_MIN_SCANS``
    rows; ``first_label``: the legend's words for the start dot.
    """
    from matplotlib.lines import Line2D

    et, ei, ep = tracks
    n_tracks = len(np.unique(ei))
    min_scans = _LONG_RUN_MIN_SCANS if crowded else 1
    lw, lw_truth, ms_start, arrow_in = (0.7, 0.6, 3, 0.1) if crowded else (1.6, 1.2, 5, 0.16)
    dropped = 0
    handles: list = []

    pts = [np.asarray(z, dtype=float) for z in scans if len(z)]
    if pts:
        Z = np.concatenate([z[:, :2] for z in pts])
        keep = _drawable(Z)
        dropped += int((~keep).sum())
        if origins is not None:
            org = np.concatenate([o for o, z in zip(origins, scans, strict=True) if len(z)])
            clutter = org < 0
            kinds = (
                (clutter, 2, "0.8", "clutter (false detections)", 1),
                (~clutter, 4, "0.45", "target detections", 2),
            )
        else:
            kinds = ((np.ones(len(Z), bool), 3, "0.6", "detections", 1),)
        for sel, sz, grey, lab, zo in kinds:
            sel = sel & keep
            ax.scatter(Z[sel, 0], Z[sel, 1], s=sz, c=grey, lw=0, zorder=zo, rasterized=True)
            handles.append(Line2D([], [], ls="none", marker="o", ms=4, c=grey, label=lab))

    def draw_paths(paths, colors, width, z):
        starts, ends, befores, cols = [], [], [], []
        for p, col in zip(paths.values(), colors, strict=True):
            ax.plot(p[:, 0], p[:, 1], "-", c=col, lw=width, alpha=0.85, zorder=z)
            starts.append(p[0, :2])
            cols.append(col)
            ends.append(p[-1, :2])
            moved = np.flatnonzero((p[:, :2] != p[-1, :2]).any(axis=1))
            befores.append(p[moved[-1], :2] if len(moved) else p[-1, :2])
        if starts:
            S = np.asarray(starts)
            ax.scatter(S[:, 0], S[:, 1], s=ms_start**2, c=cols, lw=0, zorder=z + 1)
            _arrows(ax, np.asarray(ends), np.asarray(befores), cols, arrow_in, z + 1)

    has_truth = truth is not None and len(truth[0])
    if has_truth:
        tt, ti, tp = truth
        keep = _drawable(tp)
        dropped += int((~keep).sum())
        paths = _paths(tt[keep], ti[keep], tp[keep])
        draw_paths(paths, ["k"] * len(paths), lw_truth, 3)
        handles.append(Line2D([], [], c="k", lw=1.2, label="truth"))

    keep = _drawable(ep)
    dropped += int((~keep).sum())
    all_paths = _paths(et[keep], ei[keep], ep[keep])
    shown = {k: p for k, p in all_paths.items() if len(p) >= min_scans}
    cmap = plt.get_cmap("tab10" if len(shown) <= 10 else "tab20")
    colors = [cmap(n % cmap.N) for n in range(len(shown))]
    draw_paths(shown, colors, lw, 4)
    label_ids = len(shown) <= _MAX_LABELLED_TRACKS
    if label_ids:
        for (k, p), col in zip(shown.items(), colors, strict=True):
            ax.annotate(
                str(int(k)),
                p[-1, :2],
                xytext=(4, 4),
                textcoords="offset points",
                fontsize=8,
                color=col,
                fontweight="bold",
                zorder=5,
            )
    if shown:
        track_label = "confirmed tracks (one colour each"
        track_label += ", id at the end)" if label_ids else ")"
        handles.append(Line2D([], [], c=colors[0], lw=1.6, label=track_label))
    if shown or has_truth:
        handles.append(Line2D([], [], ls="none", marker="o", ms=5, c="0.3", label=first_label))
        handles.append(
            Line2D(
                [], [], ls="none", marker=">", ms=7, c="0.3", label="arrow: direction at the end"
            )
        )
    if sensor is not None:
        sx, sy = (float(v) for v in np.asarray(sensor, dtype=float)[:2])
        ax.plot([sx], [sy], "^", ms=9, c="k", mec="w", zorder=6)
        handles.append(Line2D([], [], ls="none", marker="^", ms=8, c="k", label="sensor"))

    _set_view(ax, box, ep[keep])
    head = _count(n_tracks, "confirmed track")
    if len(shown) < n_tracks:
        head += f", {len(shown):,} shown (those of ≥ {min_scans} scans)"
    if not label_ids:
        head += ", ids not shown"
    if dropped:
        head += f"; {_count(dropped, 'point')} not finite or beyond ±{PLOT_LIMIT:.0e} m not drawn"
    if handles:
        ax.legend(
            handles=handles,
            loc="upper left",
            bbox_to_anchor=(1.01, 1.0),
            borderaxespad=0.0,
            fontsize=8,
            framealpha=0.9,
        )
    return head


def _set_view(ax, box, points) -> None:
    """Axis limits: the region, widened to ``points`` (tracks that wander off stay in view)."""
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.grid(alpha=0.2)
    if box is None:
        return
    box = box.copy()
    if len(points):
        box[:, 0] = np.minimum(box[:, 0], points[:, :2].min(axis=0))
        box[:, 1] = np.maximum(box[:, 1], points[:, :2].max(axis=0))
    pad = 0.03 * (box[:, 1] - box[:, 0])
    ax.set_xlim(box[0, 0] - pad[0], box[0, 1] + pad[0])
    ax.set_ylim(box[1, 0] - pad[1], box[1, 1] + pad[1])


def _draw_density(fig, ax, positions, box) -> int:
    """Where the tracks were: estimates per cell of a 100 × 100 grid (log colour scale).

    Returns the number of positions left out as not drawable.
    """
    from matplotlib.colors import LogNorm

    keep = _drawable(positions)
    xy = positions[keep, :2]
    if box is None and len(xy):
        box = np.column_stack([xy.min(axis=0), xy.max(axis=0)])
    if box is not None and len(xy):
        box = box.copy()
        box[:, 0] = np.minimum(box[:, 0], xy.min(axis=0))
        box[:, 1] = np.maximum(box[:, 1], xy.max(axis=0))
        flat = box[:, 1] <= box[:, 0]
        box[flat, 1] = box[flat, 0] + 1.0  # a single point still gets a cell
        counts, xe, ye = np.histogram2d(xy[:, 0], xy[:, 1], bins=100, range=box)
        mesh = ax.pcolormesh(
            xe,
            ye,
            np.ma.masked_equal(counts.T, 0),
            norm=LogNorm(vmin=1, vmax=max(counts.max(), 2)),
            cmap="viridis",
            rasterized=True,
        )
        cb = fig.colorbar(mesh, ax=ax, shrink=0.9, pad=0.01)
        cb.set_label(f"track estimates per cell ({xe[1] - xe[0]:.3g} m × {ye[1] - ye[0]:.3g} m)")
    _set_view(ax, box, np.zeros((0, 2)))
    return int((~keep).sum())


#: Scans drawn in full detail at the end of a run longer than ``_LONG_RUN_SCANS``.
_WINDOW_SCANS = 100


def scene_figure(
    *,
    times,
    scans,
    tracks,
    origins=None,
    truth=None,
    region=None,
    title: str = "",
    sensor=None,
):
    """The figure of :func:`plot_scene` (open; the caller saves or closes it).

    Positions are in metres. Every track and truth line has a start dot and an
    arrow head at its last position (the direction of motion), and the legend,
    right of the axes, names every mark. A crowded run (more than 100 tracks)
    is drawn with thin lines and only the tracks that lasted at least 5 scans;
    the title says how many are shown. A run of more than 500 scans is drawn
    in two panels: where all tracks were (a density of their estimates) and
    the last 100 scans in detail. Points that are not finite or lie beyond
    ±``PLOT_LIMIT`` m are left out and counted in the title.
    """
    box = _region_box(region)
    times = np.asarray(times, dtype=float)
    et, ei, ep = (np.asarray(a) for a in tracks)
    et = et.astype(float)
    ep = np.asarray(ep, dtype=float).reshape(len(et), -1) if len(et) else np.zeros((0, 2))
    if truth is not None:
        truth = tuple(np.asarray(a) for a in truth)
        truth = (truth[0].astype(float), truth[1], truth[2].astype(float))
    scan_times = np.unique(times) if len(times) else times
    n_scans = len(scan_times)
    n_tracks = len(np.unique(ei))
    crowded = n_tracks > _LONG_RUN_TRACKS or n_scans > _LONG_RUN_SCANS
    if n_scans <= _LONG_RUN_SCANS:
        fig, ax = plt.subplots(figsize=_figsize(box), layout="constrained")
        head = _draw_scene(
            ax,
            scans=scans,
            origins=origins,
            truth=truth,
            tracks=(et, ei, ep),
            box=box,
            sensor=sensor,
            crowded=crowded,
            first_label="start (first position)",
        )
        ax.set_title(f"{title} — {_count(n_scans, 'scan')}, {head}".strip(" —"), fontsize=10)
        return fig

    fig, (ax_all, ax_end) = plt.subplots(1, 2, figsize=(17, 7.4), layout="constrained")
    dropped = _draw_density(fig, ax_all, ep, box)
    note = f"; {dropped:,} not drawable" if dropped else ""
    ax_all.set_title(
        f"where the tracks were: all {_count(n_tracks, 'track')}, all {_count(n_scans, 'scan')}"
        f"{note}",
        fontsize=10,
    )
    t0 = scan_times[-_WINDOW_SCANS]
    in_window = times >= t0
    aligned = len(scans) == len(times)
    w_scans = [z for z, w in zip(scans, in_window, strict=True) if w] if aligned else []
    w_origins = None
    if origins is not None and aligned:
        w_origins = [o for o, w in zip(origins, in_window, strict=True) if w]
    w_truth = None
    if truth is not None:
        m = truth[0] >= t0
        w_truth = (truth[0][m], truth[1][m], truth[2][m])
    m = et >= t0
    head = _draw_scene(
        ax_end,
        scans=w_scans,
        origins=w_origins,
        truth=w_truth,
        tracks=(et[m], ei[m], ep[m]),
        box=box,
        sensor=sensor,
        crowded=True,
        first_label="start (first position in these scans)",
    )
    ax_end.set_title(
        f"the last {_WINDOW_SCANS} scans (t ≥ {t0:g} s): {head}".replace(
            "confirmed track", "track"
        ),
        fontsize=10,
    )
    fig.suptitle(
        f"{title} — {_count(n_scans, 'scan')}, {_count(n_tracks, 'confirmed track')}".strip(" —"),
        fontsize=11,
    )
    return fig


def plot_scene(path, **kwargs) -> Path:
    """Truth lines, detections (grey dots, clutter lighter) and confirmed tracks with ids.

    Keyword arguments are those of :func:`scene_figure`: ``times``: the scan
    times; ``scans``: per-scan (M_k, d) detections as Cartesian positions
    (convert range–bearing measurements first); ``origins``: per-scan target
    id or −1 (clutter), or ``None`` (unknown); ``truth`` and ``tracks``: flat
    tables ``(times, ids, positions)``; ``region``: (d, 2) box for the axis
    limits; ``sensor``: (x, y) of a sensor to mark, or ``None``; ``title``.
    Only the first two coordinates are drawn.
    """
    return save_figure(scene_figure(**kwargs), path, dpi=100)


def gospa_figure(series, title: str = ""):
    """The figure of :func:`plot_gospa` (open; the caller saves or closes it)."""
    fig, (ax1, ax2) = plt.subplots(
        2,
        1,
        figsize=(11, 6.5),
        sharex=True,
        gridspec_kw={"height_ratios": [1, 1.3]},
        layout="constrained",
    )
    p = float(series.p)
    pw = f"{p:g}"
    t = np.asarray(series.times, dtype=float)
    g = np.asarray(series.gospa, dtype=float)
    # no line at c: unnormalised GOSPA grows with the number of targets (a missed
    # target adds c^p/2 to GOSPA^p), so c is no ceiling; the title states it
    ax1.plot(t, g, c="k", lw=1.4)
    ax1.set_ylabel("GOSPA (m)")
    head = f"GOSPA (c = {series.c:g} m, p = {pw}, α = 2), mean over scans {series.mean:.3g} m"
    ax1.set_title(f"{title} — {head}".strip(" —"), fontsize=10)
    ax1.set_ylim(bottom=0)
    ax1.grid(alpha=0.3)
    ax2.stackplot(
        t,
        series.localisation,
        series.missed,
        series.false,
        labels=[
            "localisation (matched targets)",
            f"missed targets (c$^{{{pw}}}$/2 each)",
            f"false tracks (c$^{{{pw}}}$/2 each)",
        ],
        colors=["#4c72b0", "#dd8452", "#c44e52"],
        alpha=0.85,
    )
    unit = "m$^{2}$" if p == 2 else f"m$^{{{pw}}}$"
    ax2.set_ylabel(f"GOSPA$^{{{pw}}}$ parts ({unit})")
    ax2.set_xlabel("time (s)")
    ax2.legend(
        loc="upper left",
        bbox_to_anchor=(1.01, 1.0),
        borderaxespad=0.0,
        fontsize=8,
        title=f"GOSPA$^{{{pw}}}$ = the sum",
        title_fontsize=8,
    )
    ax2.grid(alpha=0.3)
    return fig


def plot_gospa(path, series, title: str = "") -> Path:
    """GOSPA per scan in m (top) and its p-th-power parts stacked, in m^p (bottom)."""
    return save_figure(gospa_figure(series, title), path, dpi=100)
