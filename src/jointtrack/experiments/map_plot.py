"""A map of tracks over the targets' own reports, in longitude and latitude.

:func:`plot_track_map` writes a PNG (matplotlib, Agg backend: files only):
the self-reports (AIS, ADS-B) as small grey dots and every confirmed track as
a thin coloured line with a circle at its start and an arrow head at its end
pointing along its last leg. Longitude is on x, latitude on y, with the axes'
aspect 1/cos(lat0) (lat0 the middle of the latitude range), so a degree of
longitude is drawn as long as it is on the ground there and shapes are not
stretched. The legend explaining the marks sits below the map, off the data.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402

from jointtrack.assignment._checks import _as_real_array, _holds_bool, as_int  # noqa: E402

__all__ = ["TrackMap", "plot_track_map"]

# a qualitative palette: neighbouring track ids get distinguishable colours
_PALETTE = plt.get_cmap("tab20").colors


@dataclass(frozen=True, eq=False)
class TrackMap:
    """What :func:`plot_track_map` drew, read back from the figure before closing it.

    ``path``: the PNG written; ``xlabel``, ``ylabel``, ``title``: the axes'
    texts; ``n_track_lines``: the line artists on the axes (one per track
    drawn); ``n_tracks_skipped``: tracks with fewer than ``min_points`` points;
    ``n_reports``: report dots; ``n_identities``: distinct ``report_ids`` (None
    without them); ``n_outside``: report and track points outside the view;
    ``aspect``: the axes' aspect (1/cos lat0); ``figure``: the
    open :class:`matplotlib.figure.Figure` when ``keep_figure=True`` (the
    caller closes it with ``plt.close``), else None.
    """

    path: Path
    xlabel: str
    ylabel: str
    title: str
    n_track_lines: int
    n_tracks_skipped: int
    n_reports: int
    n_identities: int | None
    n_outside: int
    aspect: float
    figure: object | None = None


def _coords(lat, lon, prefix: str) -> tuple[np.ndarray, np.ndarray]:
    la = _as_real_array(lat, f"{prefix}_lat")
    lo = _as_real_array(lon, f"{prefix}_lon")
    for a, name in ((la, f"{prefix}_lat"), (lo, f"{prefix}_lon")):
        if a.ndim != 1:
            raise ValueError(f"{name} must be 1-D, got shape {a.shape}")
        if not np.all(np.isfinite(a)):
            i = int(np.flatnonzero(~np.isfinite(a))[0])
            raise ValueError(f"{name}[{i}] is not finite ({a[i]})")
    if la.size != lo.size:
        raise ValueError(f"{prefix}_lat has {la.size} entries but {prefix}_lon has {lo.size}")
    if la.size and np.max(np.abs(la)) > 90:
        i = int(np.argmax(np.abs(la)))
        raise ValueError(f"{prefix}_lat[{i}] = {la[i]} is not a latitude in [-90, 90] degrees")
    if lo.size and (lo.min() < -180 or lo.max() > 360):
        i = int(np.argmax((lo < -180) | (lo > 360)))
        raise ValueError(f"{prefix}_lon[{i}] = {lo[i]} is not a longitude in [-180, 360] degrees")
    return la, lo


def _track_ids(ids, n: int) -> np.ndarray:
    raw = np.asarray(ids)
    if raw.ndim != 1 or raw.size != n:
        raise ValueError(
            f"track_ids must be 1-D with one id per track point ({n}), got {raw.shape}"
        )
    if raw.dtype.kind == "b" or _holds_bool(ids):
        raise ValueError("track_ids holds booleans; pass integer track ids")
    if n and raw.dtype.kind not in "iu":
        raise ValueError(f"track_ids must be integers, got dtype {raw.dtype}")
    return raw.astype(np.int64)


def _view(values: np.ndarray, pad_min: float) -> tuple[float, float]:
    """Axis limits holding the bulk of ``values`` and everything near it.

    Real feeds hold garbage positions (the Solent AIS file has one report at
    54.8° E among ships between 1.39° W and 0.76° W). The view is the run of
    sorted values around the median with no empty stretch wider than the
    1st–99th percentile range: a stray point beyond such a gap is out of view
    (and counted), while spread-out genuine data, which has no such gap, is
    shown whole. Then padded.
    """
    v = np.sort(values)
    p1, p99 = np.percentile(v, [1.0, 99.0])
    gap = max(float(p99 - p1), pad_min)
    cut = np.flatnonzero(np.diff(v) > gap)  # a cut between v[i] and v[i + 1]
    mid = v.size // 2
    below, above = cut[cut < mid], cut[cut >= mid]
    lo = float(v[below[-1] + 1]) if below.size else float(v[0])
    hi = float(v[above[0]]) if above.size else float(v[-1])
    pad = max(0.04 * (hi - lo), pad_min)
    return lo - pad, hi + pad


def _unwrap(report_lon: np.ndarray, track_lon: np.ndarray, centre: float | None):
    """``(report_lon, track_lon)`` in one run of 360°: [centre - 180, centre + 180)
    about ``centre`` (the view's middle), or else the narrower of [-180, 180) and
    [0, 360) for the data. Longitudes already in the run keep their exact values."""
    both = np.concatenate([report_lon, track_lon])

    def about(c):
        turns = np.floor((both - c + 180.0) / 360.0)
        return np.where(turns == 0, both, both - 360.0 * turns)

    if centre is not None:
        out = about(centre)
    else:
        west, east = about(0.0), about(180.0)
        out = east if both.size and np.ptp(east) < np.ptp(west) else west
    return out[: report_lon.size], out[report_lon.size :]


def _wrap180(lon: float) -> float:
    """A longitude in (-180, 180] (180° E stays 180)."""
    w = math.fmod(lon + 180.0, 360.0)
    w = w + 360.0 if w < 0 else w
    return 180.0 if w == 0.0 else w - 180.0


def _extent(extent) -> tuple[tuple[float, float], tuple[float, float]]:
    box = _as_real_array(extent, "extent")
    if box.shape != (4,) or not np.all(np.isfinite(box)):
        raise ValueError(
            "extent must be four finite numbers (lon_min, lon_max, lat_min, lat_max), "
            f"got {extent!r}"
        )
    if not (box[0] < box[1] and box[2] < box[3] and -90 <= box[2] and box[3] <= 90):
        raise ValueError(
            "extent must be (lon_min, lon_max, lat_min, lat_max) with lon_min < lon_max and "
            f"-90 <= lat_min < lat_max <= 90, got {tuple(box.tolist())}"
        )
    return (float(box[0]), float(box[1])), (float(box[2]), float(box[3]))


def plot_track_map(
    path,
    report_lat,
    report_lon,
    track_lat,
    track_lon,
    track_ids,
    *,
    title: str,
    report_ids=None,
    min_points: int = 3,
    track_times=None,
    extent=None,
    keep_figure: bool = False,
    dpi: int = 130,
) -> TrackMap:
    """Write a PNG map of the tracks over the self-reports.

    Parameters
    ----------
    path : str or Path
        The PNG to write (its directory is made).
    report_lat, report_lon : (R,) degrees
        The targets' own reports, drawn as small grey dots.
    track_lat, track_lon, track_ids : (S,), (S,) degrees, (S,) integers
        The confirmed tracks' estimates, one row per (time, track). Each
        track's points are joined in ``track_times`` order when given, else in
        the order of the rows (a tracker's history is in time order).
    title : str
        The figure title.
    report_ids : (R,) array, optional
        The reports' identities (MMSI, icao24, any type): only counted, for the
        legend.
    min_points : int ≥ 1
        Tracks with fewer points are not drawn (counted in
        ``n_tracks_skipped``).
    track_times : (S,) array, optional
        Times of the track rows, to order each track's points.
    extent : (lon_min, lon_max, lat_min, lat_max), optional
        The view. Default: the reports and tracks, less stray points beyond an
        empty stretch wider than the data's 1st–99th percentile range (per
        axis), so a few garbage positions do not shrink the map to a dot;
        points outside the view are counted in ``TrackMap.n_outside`` and the
        legend.
    keep_figure : bool
        Return the open figure in ``TrackMap.figure`` (the caller closes it)
        instead of closing it.
    dpi : int
        Resolution of the PNG.

    Returns
    -------
    TrackMap
        The path and what was drawn, read back from the figure.
    """
    if not isinstance(title, str):
        raise ValueError(f"title must be a string, got {type(title).__name__}")
    min_points = as_int(min_points, "min_points", minimum=1)
    dpi = as_int(dpi, "dpi", minimum=10, maximum=1200)
    if not isinstance(keep_figure, bool):
        raise ValueError(f"keep_figure must be True or False, got {keep_figure!r}")
    if not isinstance(path, str | Path):
        raise ValueError(f"path must be a str or Path, got {type(path).__name__}")
    rla, rlo = _coords(report_lat, report_lon, "report")
    tla, tlo = _coords(track_lat, track_lon, "track")
    tid = _track_ids(track_ids, tla.size)
    n_ident = None
    if report_ids is not None:
        rid = np.asarray(report_ids)
        if rid.ndim != 1 or rid.size != rla.size:
            raise ValueError(
                f"report_ids must be 1-D with one id per report ({rla.size}), got {rid.shape}"
            )
        n_ident = int(np.unique(rid).size)
    if track_times is not None:
        tt = _as_real_array(track_times, "track_times")
        if tt.ndim != 1 or tt.size != tla.size:
            raise ValueError(
                f"track_times must be 1-D with one time per track point ({tla.size}), "
                f"got {tt.shape}"
            )
        if not np.all(np.isfinite(tt)):
            raise ValueError("track_times must be finite")
        order = np.lexsort((tt, tid))
    else:
        order = np.argsort(tid, kind="stable")  # rows of one track keep their order
    tla, tlo, tid = tla[order], tlo[order], tid[order]

    # longitudes in one run of 360° about the data: the narrower of [-180, 180) and
    # [0, 360), so data across the antimeridian (179.9°, -179.9°) is drawn together,
    # not at both ends of a 360° axis
    box = _extent(extent) if extent is not None else None
    rlo, tlo = _unwrap(rlo, tlo, None if box is None else 0.5 * (box[0][0] + box[0][1]))
    all_lat = np.concatenate([rla, tla])
    all_lon = np.concatenate([rlo, tlo])
    if box is not None:
        xlim, ylim = box
    elif all_lat.size:
        xlim, ylim = _view(all_lon, 0.005), _view(all_lat, 0.005)
    else:
        xlim, ylim = (-1.0, 1.0), (-1.0, 1.0)
    lat0 = 0.5 * (ylim[0] + ylim[1])
    n_outside = int(
        np.sum(
            (all_lon < xlim[0]) | (all_lon > xlim[1]) | (all_lat < ylim[0]) | (all_lat > ylim[1])
        )
    )
    # a degree of longitude is cos(lat0) times a degree of latitude on the ground
    aspect = 1.0 / max(math.cos(math.radians(lat0)), 1e-3)
    ratio = (ylim[1] - ylim[0]) * aspect / (xlim[1] - xlim[0])
    width = 10.0
    height = min(max(width * ratio, 3.0), 14.0) + 1.0  # room for the legend below

    # constrained layout keeps the legend below the axes, clear of the tick labels
    fig, ax = plt.subplots(figsize=(width, height), layout="constrained")
    if rla.size:
        ax.scatter(rlo, rla, s=2, c="0.6", lw=0, zorder=1, rasterized=True)

    starts = np.flatnonzero(np.r_[True, tid[1:] != tid[:-1]]) if tid.size else np.zeros(0, int)
    bounds = np.r_[starts, tid.size]
    start_x, start_y, start_c = [], [], []
    drawn = skipped = 0
    for k, (a, b) in enumerate(zip(bounds[:-1], bounds[1:], strict=True)):
        if b - a < min_points:
            skipped += 1
            continue
        colour = _PALETTE[k % len(_PALETTE)]
        x, y = tlo[a:b], tla[a:b]
        ax.plot(x, y, "-", lw=0.9, color=colour, zorder=2)
        drawn += 1
        start_x.append(x[0])
        start_y.append(y[0])
        start_c.append(colour)
        # the arrow runs along the last leg of non-zero length (a track may stand still)
        moved = np.flatnonzero((x[:-1] != x[-1]) | (y[:-1] != y[-1]))
        if moved.size:
            j = moved[-1]
            ax.annotate(
                "",
                xy=(x[-1], y[-1]),
                xytext=(x[j], y[j]),
                arrowprops={"arrowstyle": "-|>", "color": colour, "lw": 0.9, "mutation_scale": 9},
                zorder=3,
            )
    if start_x:
        ax.scatter(start_x, start_y, s=14, facecolors="none", edgecolors=start_c, lw=0.9, zorder=3)

    ax.set_xlim(*xlim)
    ax.set_ylim(*ylim)
    if xlim[0] < -180.0 or xlim[1] > 180.0:  # ticks past ±180° labelled within (-180, 180]
        ticks = ax.xaxis.get_major_locator().tick_values(*xlim)
        ticks = ticks[(ticks >= xlim[0]) & (ticks <= xlim[1])]
        step = float(np.min(np.diff(ticks))) if ticks.size > 1 else 1.0
        decimals = max(0, -math.floor(math.log10(step) + 1e-9)) if step > 0 else 0
        ax.set_xticks(ticks, [f"{_wrap180(t):.{decimals}f}" for t in ticks])
    ax.set_aspect(aspect)
    ax.set_xlabel("longitude (°E)")
    ax.set_ylabel("latitude (°N)")
    ax.set_title(title)
    ax.grid(True, lw=0.3, alpha=0.5)
    report_label = f"self-reports ({rla.size}"
    report_label += f" from {n_ident} identities)" if n_ident is not None else ")"
    # legend proxies are not added to the axes: ax.lines holds the tracks only
    proxies = [
        Line2D([], [], ls="", marker="o", ms=3, color="0.6", label=report_label),
        Line2D([], [], ls="-", lw=0.9, color=_PALETTE[0], label=f"track ({drawn} drawn)"),
        Line2D(
            [], [], ls="", marker="o", ms=5, mfc="none", mec=_PALETTE[0], label="start of a track"
        ),
        Line2D([], [], ls="", marker=">", ms=6, color=_PALETTE[0], label="end, pointing onward"),
    ]
    if n_outside:
        proxies.append(
            Line2D([], [], ls="", marker="", label=f"{n_outside} points outside this view")
        )
    fig.legend(
        handles=proxies, loc="outside lower center", ncol=len(proxies), fontsize=8, frameon=False
    )
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=dpi, bbox_inches="tight")
    out = TrackMap(
        path=path,
        xlabel=ax.get_xlabel(),
        ylabel=ax.get_ylabel(),
        title=ax.get_title(),
        n_track_lines=len(ax.lines),
        n_tracks_skipped=skipped,
        n_reports=int(rla.size),
        n_identities=n_ident,
        n_outside=n_outside,
        aspect=float(ax.get_aspect()),
        figure=fig if keep_figure else None,
    )
    if not keep_figure:
        plt.close(fig)
    return out
