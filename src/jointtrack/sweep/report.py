"""The sweep's report: mean and 95 % CI per metric per cell, and plots against each axis.

:func:`summarise` groups the ``ok`` rows by cell; each metric gets its mean,
the half-width of its 95 % confidence interval (Student t, ``t_{0.975, n-1} ·
s / √n``; none for a single run) and the number of runs that have a value.
:func:`write_report` writes ``summary.csv`` and, for each metric and each swept
axis, ``plots/<metric>_vs_<axis>.png``: the mean over the runs at each axis
value (the other axes pooled), one line per method, with CI bars.
:func:`print_summary` prints the table (a few main metrics; all are in the CSV).
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

__all__ = ["mean_ci", "print_summary", "summarise", "write_report"]

_MAIN = ("gospa", "ospa", "rmse", "n_false_tracks", "ospa_after_burn_in")


def mean_ci(values) -> tuple[float | None, float | None, int]:
    """Mean, 95 % CI half-width (Student t) and count of the finite values.

    ``(None, None, 0)`` without values; the half-width is None for one value.

    >>> m, h, n = mean_ci([1.0, 2.0, 3.0])
    >>> round(m, 3), round(h, 3), n
    (2.0, 2.484, 3)
    """
    xs = [float(v) for v in values if v is not None and math.isfinite(float(v))]
    n = len(xs)
    if n == 0:
        return None, None, 0
    mean = math.fsum(xs) / n
    if n == 1:
        return mean, None, 1
    from scipy.stats import t

    sd = math.sqrt(math.fsum((x - mean) ** 2 for x in xs) / (n - 1))
    return mean, float(t.ppf(0.975, n - 1)) * sd / math.sqrt(n), n


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


def _plots(rows, axes, names, plot_dir: Path) -> list[Path]:
    """Each metric vs each axis, one line per method (the other axes pooled), 95 % CI bars."""
    from matplotlib.figure import Figure  # no pyplot: no GUI backend is ever chosen

    ok = [r for r in rows if r["status"] == "ok"]
    if not ok:
        return []
    plot_dir.mkdir(parents=True, exist_ok=True)
    methods = sorted({r["method"] for r in ok})
    params = [json.loads(r["params"]) for r in ok]
    paths = []
    for axis, values in axes.items():
        numeric = all(isinstance(v, int | float) and not isinstance(v, bool) for v in values)
        xs = list(values) if numeric else list(range(len(values)))
        keys = [json.dumps(v, sort_keys=True) for v in values]
        for name in names:
            fig = Figure(figsize=(6.0, 4.0))
            ax = fig.add_subplot()
            drawn = False
            for method in methods:
                px, py, pe = [], [], []
                for x, key in zip(xs, keys, strict=True):
                    vals = [
                        r.get(f"metric.{name}")
                        for r, p in zip(ok, params, strict=True)
                        if r["method"] == method and json.dumps(p.get(axis), sort_keys=True) == key
                    ]
                    m, h, _ = mean_ci(vals)
                    if m is not None:
                        px.append(x)
                        py.append(m)
                        pe.append(0.0 if h is None else h)
                if px:
                    ax.errorbar(px, py, yerr=pe, marker="o", capsize=3, label=method)
                    drawn = True
            if not drawn:
                continue
            if not numeric:
                ax.set_xticks(xs, [str(v) for v in values])
            ax.set_xlabel(axis)
            ax.set_ylabel(f"{name} (mean, 95 % CI)")
            ax.legend(fontsize="small")
            ax.grid(alpha=0.3)
            fig.tight_layout()
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
