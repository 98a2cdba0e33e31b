"""The sweep's report: mean and 95 % CI per metric per cell, and plots against each axis.

:func:`summarise` groups the ``ok`` rows by cell; each metric gets its mean,
the half-width of its 95 % confidence interval (Student t, ``t_{0.975, n-1} ·
s / √n``; none for a single run) and the number of runs that have a value.
:func:`write_report` writes ``summary.csv`` and, for each metric and each swept
axis, ``plots/<metric>_vs_<axis>.png`` (:func:`metric_figure`): the mean over
the runs at each axis value (the other axes pooled) with CI bars, one line per
method along a numeric axis, grouped bars along a categorical one (or one that
is the method itself), titled with the scenario and the number of seeds.
:func:`print_summary` prints the table (a few main metrics; all are in the CSV).
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

__all__ = ["mean_ci", "metric_figure", "metric_label", "print_summary", "summarise", "write_report"]

_MAIN = ("gospa", "ospa", "rmse", "n_false_tracks", "ospa_after_burn_in")
#: Means beyond this are not drawn (matplotlib's autoscaling overflows near the float
#: limit); the value of jointtrack.experiments.plots.PLOT_LIMIT, not imported from
#: there because that module selects pyplot's Agg backend on import.
_PLOT_LIMIT = 1e150


def mean_ci(values) -> tuple[float | None, float | None, int]:
    """Mean, 95 % CI half-width (Student t) and count of the finite values.

    ``(None, None, 0)`` without values; the half-width is None for one value,
    ``inf`` when it lies beyond the float range (values near ±1.8e308).

    >>> m, h, n = mean_ci([1.0, 2.0, 3.0])
    >>> round(m, 3), round(h, 3), n
    (2.0, 2.484, 3)
    """
    xs = [float(v) for v in values if v is not None and math.isfinite(float(v))]
    n = len(xs)
    if n == 0:
        return None, None, 0
    # in units of the largest |value|: sums and squares of values near the float
    # limit (1e300) would overflow
    scale = max(abs(x) for x in xs) or 1.0
    ys = [x / scale for x in xs]
    mean_y = math.fsum(ys) / n
    if n == 1:
        return mean_y * scale, None, 1
    from scipy.stats import t

    sd_y = math.sqrt(math.fsum((y - mean_y) ** 2 for y in ys) / (n - 1))
    half = float(t.ppf(0.975, n - 1)) * sd_y / math.sqrt(n)
    # a half-width beyond the float range is reported as infinite, not as an error
    return mean_y * scale, half * scale if half < math.inf / scale else math.inf, n


def _metric_names(rows) -> list[str]:
    names = []
    for r in rows:
        for k in r:
            if k.startswith("metric.") and k[7:] not in names:
                names.append(k[7:])
    return names


def summarise(rows: list[dict], axes: dict) -> list[dict]:
    """One entry per cell: method, axis values, run counts, and per metric (mean, ci95, n).

    Parameters
    ----------
    rows : the stored rows (:meth:`~jointtrack.sweep.store.ResultStore.read_rows`).
    axes : the spec's axes (``"table.key" -> values``), shown per cell.
    """
    cells: dict[str, dict] = {}
    names = _metric_names(rows)
    for r in rows:
        c = cells.setdefault(
            r["cell_id"],
            {
                "cell_id": r["cell_id"],
                "method": r["method"],
                "axes": {a: json.loads(r["params"]).get(a) for a in axes},
                "rows": [],
                "n_failed": 0,
            },
        )
        if r["status"] == "ok":
            c["rows"].append(r)
        else:
            c["n_failed"] += 1
    out = []
    for c in cells.values():
        metrics = {}
        for name in names:
            m, h, n = mean_ci(r.get(f"metric.{name}") for r in c["rows"])
            if n:
                metrics[name] = (m, h, n)
        out.append(
            {
                "cell_id": c["cell_id"],
                "method": c["method"],
                "axes": c["axes"],
                "n_ok": len(c["rows"]),
                "n_failed": c["n_failed"],
                "metrics": metrics,
            }
        )
    return out


def _fmt(x) -> str:
    return "" if x is None else f"{x:.6g}"


def write_report(rows: list[dict], axes: dict, out_dir) -> dict:
    """Write ``summary.csv`` and the PNG plots into ``out_dir``; return their paths.

    Returns
    -------
    dict
        ``summary`` (the CSV path), ``plots`` (list of PNG paths) and ``cells``
        (:func:`summarise`'s result).
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    cells = summarise(rows, axes)
    names = _metric_names(rows)
    path = out_dir / "summary.csv"
    with open(path, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(
            ["method", *axes, "n_ok", "n_failed"]
            + [f"{n}_{part}" for n in names for part in ("mean", "ci95", "n")]
        )
        for c in cells:
            line = [c["method"], *(json.dumps(c["axes"][a]) for a in axes)]
            line += [c["n_ok"], c["n_failed"]]
            for n in names:
                m, h, k = c["metrics"].get(n, (None, None, 0))
                line += [_fmt(m), _fmt(h), k]
            w.writerow(line)
    plots = _plots(rows, axes, names, out_dir / "plots") if axes else []
    return {"summary": path, "plots": plots, "cells": cells}


#: What each metric of a sweep row is (:data:`jointtrack.sweep.cell.METRICS`) and its unit;
#: ``{p}`` is the run's GOSPA exponent (the parts are p-th powers).
_METRIC_LABELS = {
    "gospa": ("mean GOSPA per scan", "m"),
    "gospa_localisation": ("GOSPA$^{{{p}}}$ part: localisation, mean per scan", "m$^{{{p}}}$"),
    "gospa_missed": ("GOSPA$^{{{p}}}$ part: missed targets, mean per scan", "m$^{{{p}}}$"),
    "gospa_false": ("GOSPA$^{{{p}}}$ part: false tracks, mean per scan", "m$^{{{p}}}$"),
    "ospa": ("mean OSPA per scan", "m"),
    "gospa_after_burn_in": ("mean GOSPA per scan after burn-in", "m"),
    "ospa_after_burn_in": ("mean OSPA per scan after burn-in", "m"),
    "rmse": ("RMSE of the tracks' positions", "m"),
    "coverage": ("coverage: share of truth-scans with a track", "fraction"),
    "n_tracks": ("confirmed tracks", "count"),
    "n_false_tracks": ("false tracks", "count"),
    "n_id_switches": ("identity switches", "count"),
    "scans_per_second": ("speed", "scans/s"),
    "seconds_per_scan": ("time per scan", "s"),
}


def metric_label(name: str, p: float = 2) -> str:
    """Axis label of a metric with its unit, e.g. ``mean GOSPA per scan (m)``.

    >>> metric_label("gospa_missed")
    'GOSPA$^{2}$ part: missed targets, mean per scan (m$^{2}$)'
    >>> metric_label("something_new")
    'something_new'
    """
    if name not in _METRIC_LABELS:
        return name
    text, unit = (part.format(p=f"{p:g}") for part in _METRIC_LABELS[name])
    return f"{text} ({unit})"


def _value_key(v) -> str:
    return json.dumps(v, sort_keys=True)


def metric_figure(rows: list[dict], axes: dict, axis: str, name: str):
    """One metric against one swept axis (the other axes pooled), or None without values.

    A numeric axis along which some method has two or more values is drawn as
    lines with 95 % CI bars, one line per method. A categorical axis (a
    method, a tracker kind …) or one along which every method has a single
    value (the axis is the method itself) is drawn as grouped bars with CI
    bars and the mean written on each. Along a numeric axis the methods' lines
    are shifted by ±1.2 % of the axis' span so that equal means stay visible.
    The title names the scenario(s), the number of seeds and the axes pooled
    (those that vary within a method). Returns a :class:`matplotlib.figure.Figure` (no pyplot:
    no GUI backend is ever chosen).
    """
    from matplotlib.figure import Figure

    ok = [r for r in rows if r["status"] == "ok"]
    if not ok:
        return None
    values = list(axes[axis])
    numeric = all(isinstance(v, int | float) and not isinstance(v, bool) for v in values)
    methods = sorted({r["method"] for r in ok})
    params = [json.loads(r["params"]) for r in ok]
    stats: dict[str, list] = {}  # method -> [(axis value, mean, half-width, n)]
    skipped = 0  # means too large to draw
    for method in methods:
        for v in values:
            key = _value_key(v)
            m, h, n = mean_ci(
                r.get(f"metric.{name}")
                for r, q in zip(ok, params, strict=True)
                if r["method"] == method and _value_key(q.get(axis)) == key
            )
            if m is not None and abs(m) > _PLOT_LIMIT:
                skipped += 1  # matplotlib's autoscaling overflows near the float limit
            elif m is not None:
                h = 0.0 if h is None or not math.isfinite(h) else min(h, _PLOT_LIMIT)
                stats.setdefault(method, []).append((v, m, h, n))
    if not stats and not skipped:
        return None
    gospa_p = {q.get("metrics.p", 2) for q in params}
    p = gospa_p.pop() if len(gospa_p) == 1 else 2
    scenarios = sorted({str(q.get("scenario.name", "bojilov")) for q in params})
    n_seeds = len({r["seed"] for r in ok})
    bars = not numeric or all(len(pts) <= 1 for pts in stats.values())

    fig = Figure(figsize=(8.5, 4.4), layout="constrained")
    ax = fig.add_subplot()
    colors = {m: f"C{k % 10}" for k, m in enumerate(methods)}
    if bars:
        groups = [
            v
            for v in values
            if any(_value_key(v) == _value_key(pt[0]) for pts in stats.values() for pt in pts)
        ]
        for g, v in enumerate(groups):
            here = [
                (method, pt)
                for method, pts in stats.items()
                for pt in pts
                if _value_key(pt[0]) == _value_key(v)
            ]
            width = 0.8 / len(here)
            for k, (method, (_, m, h, _n)) in enumerate(here):
                cont = ax.bar(
                    g - 0.4 + width * (k + 0.5),
                    m,
                    width=width * 0.92,
                    yerr=h,
                    capsize=3,
                    color=colors[method],
                    label=method,
                )
                ax.bar_label(cont, fmt="%.3g", fontsize=7, padding=2)
        ax.set_xticks(range(len(groups)), [str(v) for v in groups])
        ax.margins(y=0.12)
    else:
        # methods with equal means would hide each other: each is shifted by a small
        # fraction of the axis' span (the ticks stay at the values)
        span = (max(values) - min(values)) or 1.0
        step = 0.012 * span if len(stats) > 1 else 0.0
        for k, (method, pts) in enumerate(stats.items()):
            shift = (k - (len(stats) - 1) / 2) * step
            ax.errorbar(
                [pt[0] + shift for pt in pts],
                [pt[1] for pt in pts],
                yerr=[pt[2] for pt in pts],
                marker="o",
                capsize=3,
                color=colors[method],
                label=method,
            )
    # one legend entry per method (bars repeat the label once per group)
    handles, labels = ax.get_legend_handles_labels()
    seen = dict(zip(labels, handles, strict=True))
    if seen:
        ax.legend(
            seen.values(),
            seen.keys(),
            title="method",
            fontsize="small",
            loc="upper left",
            bbox_to_anchor=(1.01, 1.0),
            borderaxespad=0.0,
        )
    ax.set_xlabel(axis)
    ax.set_ylabel(f"{metric_label(name, p)}\nmean ± 95 % CI", fontsize=9)
    # the other axes that vary within a method are pooled (an axis that is the
    # method, e.g. tracker.kind, is not)
    others = [
        a
        for a in axes
        if a != axis
        and any(
            len({_value_key(q.get(a)) for r, q in zip(ok, params, strict=True) if r["method"] == m})
            > 1
            for m in methods
        )
    ]
    pooled = f"; pooled over {', '.join(others)}" if others else ""
    note = f"; {skipped} mean(s) beyond ±{_PLOT_LIMIT:.0e} not drawn" if skipped else ""
    ax.set_title(
        f"{', '.join(scenarios)}: {name} vs {axis}\n"
        f"{n_seeds} seed{'s' if n_seeds != 1 else ''} per cell{pooled}{note}",
        fontsize=10,
    )
    ax.grid(alpha=0.3, axis="y" if bars else "both")
    return fig


def _plots(rows, axes, names, plot_dir: Path) -> list[Path]:
    """Each metric vs each axis (:func:`metric_figure`), written as PNGs into ``plot_dir``."""
    paths = []
    for axis in axes:
        for name in names:
            fig = metric_figure(rows, axes, axis, name)
            if fig is None:
                continue
            plot_dir.mkdir(parents=True, exist_ok=True)
            path = plot_dir / f"{name}_vs_{axis.replace('.', '_')}.png"
            fig.savefig(path, dpi=100)
            paths.append(path)
    return paths


def print_summary(cells: list[dict], axes: dict, console) -> None:
    """Print the per-cell table: method, axis values, runs, main metrics as mean ± CI."""
    from rich.table import Table

    names = []
    for c in cells:
        for n in c["metrics"]:
            if n in _MAIN and n not in names:
                names.append(n)
    table = Table(title="sweep summary (mean ± 95 % CI; all metrics in summary.csv)")
    table.add_column("method")
    for a in axes:
        table.add_column(a)
    table.add_column("ok", justify="right")
    table.add_column("failed", justify="right")
    for n in names:
        table.add_column(n, justify="right")
    for c in sorted(cells, key=lambda c: (c["method"], json.dumps(c["axes"], sort_keys=True))):
        line = [c["method"], *(str(c["axes"][a]) for a in axes)]
        line += [str(c["n_ok"]), str(c["n_failed"])]
        for n in names:
            m, h, _ = c["metrics"].get(n, (None, None, 0))
            if m is None:
                line.append("—")
            else:
                line.append(f"{m:.4g}" + ("" if h is None else f" ± {h:.2g}"))
        table.add_row(*line)
    console.print(table)
