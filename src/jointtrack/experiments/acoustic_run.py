"""``jointtrack run --scenario acoustic``: a superpositional-sensor filter on the acoustic scenario.

Runs SPS-CPHD (default), SPS-PHD or SPS-MB
(:mod:`jointtrack.superpositional.filters`) on
:func:`jointtrack.scenarios.acoustic.acoustic` and writes into ``out_dir``:

* ``tracks.csv`` — one row per estimate per scan: ``time, track_id, x, y, vx,
  vy``. SPS-MB estimates carry their component's label; SPS-PHD and SPS-CPHD
  estimates are unlabelled clusters, linked into tracks here by an optimal
  assignment between consecutive scans (distance < ``link_gate``), a new id
  otherwise.
* ``metrics.json`` — per scan: OSPA (c = 10 m, p = 1), GOSPA (c = 10 m, p = 2,
  α = 2) with its localisation / missed / false parts, true and estimated
  numbers of targets, seconds; their means (also after ``burn_in`` scans); the
  filter, its likelihood method and settings; the scenario's births and deaths.
* ``acoustic.png`` — sensors, true trajectories and estimates (start dots, end
  arrows, one colour per estimate track), and OSPA per scan (:func:`acoustic_figure`).

The filter settings used by the run (``FILTER_DEFAULTS``) are stated in
``metrics.json``.
"""

from __future__ import annotations

import csv
import time
from pathlib import Path

import numpy as np

from jointtrack.assignment._checks import as_int

__all__ = ["FILTER_DEFAULTS", "OSPA_C", "acoustic_figure", "run_acoustic"]

#: OSPA / GOSPA cut-off (m): a quarter of the region's side.
OSPA_C = 10.0
#: Settings of each filter in a run (:class:`~jointtrack.superpositional.filters.FilterSettings`).
FILTER_DEFAULTS = {
    "sps-cphd": {
        "n_particles": 4000,
        "n_birth_particles": 2000,
        "process_noise": 0.01,
        "birth_rate": 0.1,
        "max_cardinality": 12,
    },
    "sps-phd": {
        "n_particles": 4000,
        "n_birth_particles": 2000,
        "process_noise": 0.01,
        "birth_rate": 0.1,
        "initial_count": 3.0,
    },
    "sps-mb": {
        "n_particles": 1000,
        "n_birth_particles": 2000,
        "process_noise": 0.01,
        "birth_rate": 0.1,
    },
}
LIKELIHOODS = ("gaussian", "saddlepoint", "hybrid")


def make_filter(
    name: str, scenario, likelihood: str = "gaussian", seed: int = 0, particles=None, **overrides
):
    """The named filter with the run's settings for ``scenario`` (an AcousticScenario).

    ``particles`` sets ``n_particles`` (and caps ``n_birth_particles`` at it);
    ``overrides`` replace any other setting
    of ``FILTER_DEFAULTS`` (e.g. ``birth_rate``). Returns ``(filter, settings)``.
    """
    from jointtrack.superpositional.filters import FILTERS
    from jointtrack.superpositional.measurement import FunctionMeasurement

    if name not in FILTERS:
        raise ValueError(f"--filter must be one of {', '.join(FILTERS)}, got {name!r}")
    if likelihood not in LIKELIHOODS:
        raise ValueError(
            f"--likelihood must be one of {', '.join(LIKELIHOODS)}, got {likelihood!r}"
        )
    kw = dict(FILTER_DEFAULTS[name])
    if particles is not None:
        kw["n_particles"] = as_int(particles, "--particles", minimum=10)
        # fewer particles asked for (e.g. for a slow likelihood): fewer birth particles too
        kw["n_birth_particles"] = min(kw["n_birth_particles"], kw["n_particles"])
    kw.update(overrides)
    if name == "sps-cphd" and "initial_pmf" not in kw:
        # an uninformative start: the first readings decide how many targets there are
        n = kw["max_cardinality"] + 1
        kw["initial_pmf"] = np.full(n, 1.0 / n)
    meas = FunctionMeasurement(scenario.g, dy=scenario.sensors.shape[0], dx=4)
    f = FILTERS[name](
        meas,
        scenario.noise_cov,
        scenario.region,
        likelihood=likelihood,
        dt=scenario.dt,
        rng=np.random.default_rng([seed, 1]),
        **kw,
    )
    return f, kw


class _Linker:
    """Track ids for unlabelled estimates: optimal assignment to the previous scan's estimates."""

    def __init__(self, gate: float):
        self.gate = gate
        self.prev = np.zeros((0, 2))
        self.prev_ids = np.zeros(0, dtype=np.int64)
        self.next_id = 0

    def __call__(self, pos: np.ndarray) -> np.ndarray:
        from scipy.optimize import linear_sum_assignment

        ids = np.full(pos.shape[0], -1, dtype=np.int64)
        if pos.shape[0] and self.prev.shape[0]:
            d = np.hypot(*(pos[:, None, :] - self.prev[None, :, :]).transpose(2, 0, 1))
            rows, cols = linear_sum_assignment(np.minimum(d, 10 * self.gate))
            ok = d[rows, cols] < self.gate
            ids[rows[ok]] = self.prev_ids[cols[ok]]
        for i in np.flatnonzero(ids < 0):
            ids[i] = self.next_id
            self.next_id += 1
        self.prev, self.prev_ids = pos.copy(), ids.copy()
        return ids


def run_acoustic(
    out_dir="jointtrack-out",
    *,
    filter_name: str = "sps-cphd",
    likelihood: str = "gaussian",
    seed: int = 0,
    n_scans: int = 50,
    max_scans: int | None = None,
    particles: int | None = None,
    burn_in: int = 10,
    link_gate: float = 3.0,
    progress: bool = False,
    console=None,
    plots: bool = True,
) -> dict:
    """Run one filter on the acoustic scenario, write the outputs, return the metrics dict.

    Parameters
    ----------
    out_dir : output directory (created).
    filter_name : ``"sps-cphd"`` (default), ``"sps-phd"`` or ``"sps-mb"``.
    likelihood : ``"gaussian"`` (the paper's), ``"saddlepoint"`` or ``"hybrid"``.
    seed : scenario seed (the filter's generator is derived from it).
    n_scans : scans in the scenario; ``max_scans`` stops earlier.
    particles : ``n_particles`` of the filter (default ``FILTER_DEFAULTS``).
    burn_in : scans left out of the "after burn-in" means.
    link_gate : largest move (m) between scans that keeps a PHD/CPHD track id.
    progress : rich progress bar.
    """
    from rich.console import Console

    from jointtrack._console import progress_bar
    from jointtrack.io import write_metrics
    from jointtrack.metrics.ospa import gospa, ospa
    from jointtrack.scenarios.acoustic import acoustic

    wall0 = time.perf_counter()
    console = console or Console(quiet=True)
    seed = as_int(seed, "--seed", minimum=0)
    burn_in = as_int(burn_in, "burn_in", minimum=0)
    sc = acoustic(seed=seed, n_scans=n_scans)
    stop = (
        sc.n_scans
        if max_scans is None
        else min(sc.n_scans, as_int(max_scans, "--max-scans", minimum=1))
    )
    filt, settings = make_filter(filter_name, sc, likelihood, seed, particles)
    if likelihood != "gaussian":
        console.print(
            f"warning: the {likelihood} likelihood costs seconds per scan with a few hundred "
            "particles (measured: saddlepoint ~5 s, hybrid ~1 s per scan for SPS-CPHD with "
            "100 + 100 birth particles); consider --particles 100-300",
            style="yellow",
            markup=False,
            highlight=False,
            soft_wrap=True,
        )
    out_dir = Path(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise ValueError(f"--out {out_dir} is a file, not a directory")
    out_dir.mkdir(parents=True, exist_ok=True)

    linker = _Linker(link_gate)
    rows: list = []
    per_scan = {
        k: []
        for k in ("ospa", "gospa", "localisation", "missed", "false", "n_true", "n_est", "seconds")
    }
    with progress_bar(console, unit="scans", enabled=progress) as bar:
        task = bar.add_task(f"{filter_name} ({likelihood})", total=stop)
        for k in range(stop):
            t0 = time.perf_counter()
            filt.predict()
            filt.update(sc.measurements[k])
            if filter_name == "sps-mb":
                est, ids = filt.estimate_with_labels()
            else:
                est = filt.estimate()
                ids = linker(est[:, :2])
            per_scan["seconds"].append(time.perf_counter() - t0)
            truth = sc.truth_positions[k]
            per_scan["ospa"].append(ospa(truth, est[:, :2], c=OSPA_C, p=1))
            g = gospa(truth, est[:, :2], c=OSPA_C, p=2, alpha=2)
            for key in ("localisation", "missed", "false"):
                per_scan[key].append(getattr(g, key))
            per_scan["gospa"].append(g.total)
            per_scan["n_true"].append(int(truth.shape[0]))
            per_scan["n_est"].append(int(est.shape[0]))
            rows.extend(
                [float(sc.times[k]), int(i), *map(float, s)] for i, s in zip(ids, est, strict=True)
            )
            bar.update(task, advance=1)

    tracks_path = out_dir / "tracks.csv"
    with open(tracks_path, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(["time", "track_id", "x", "y", "vx", "vy"])
        w.writerows(rows)

    o = np.asarray(per_scan["ospa"])
    gs = np.asarray(per_scan["gospa"])
    after = slice(min(burn_in, stop), stop)
    metrics = {
        "scenario": {"name": "acoustic", "seed": seed, "n_scans": int(stop), **dict(sc.info)},
        "filter": {"name": filter_name, "likelihood": likelihood, **settings},
        "ospa": {"c": OSPA_C, "p": 1, "mean": float(o.mean()), "per_scan": o},
        "gospa": {
            "c": OSPA_C,
            "p": 2,
            "alpha": 2,
            "mean": float(gs.mean()),
            "per_scan": gs,
            **{key: np.asarray(per_scan[key]) for key in ("localisation", "missed", "false")},
        },
        "burn_in": burn_in,
        "ospa_mean_after_burn_in": float(o[after].mean()) if o[after].size else None,
        "gospa_mean_after_burn_in": float(gs[after].mean()) if gs[after].size else None,
        "cardinality": {"true": per_scan["n_true"], "estimated": per_scan["n_est"]},
        "diagnostics": _diagnostics(filt),
        "timing": {
            "seconds_per_scan": np.asarray(per_scan["seconds"]),
            "mean_seconds_per_scan": float(np.mean(per_scan["seconds"])),
        },
    }
    files = {"tracks": str(tracks_path), "metrics": str(out_dir / "metrics.json")}
    if plots:
        files["plot"] = str(
            _plot(out_dir / "acoustic.png", sc, rows, o, filter_name, likelihood, stop)
        )
    metrics["files"] = files
    metrics["timing"]["total_seconds"] = time.perf_counter() - wall0
    write_metrics(metrics, out_dir / "metrics.json")
    return metrics


def _diagnostics(filt) -> dict:
    """What the filter counted that a reader should know (PHD mass caps, CPHD truncation)."""
    out = {}
    if hasattr(filt, "n_mass_clipped"):
        out["phd_mass_clipped_updates"] = int(filt.n_mass_clipped)
    if hasattr(filt, "truncated_mass"):
        out["cphd_last_truncated_mass"] = float(filt.truncated_mass)
    return out


def acoustic_figure(sc, rows, ospa_per_scan, filter_name, likelihood, stop):
    """The figure of ``acoustic.png`` (open; the caller saves or closes it).

    Top: sensors, truth lines (a dot at the start, an arrow head at the end)
    and the estimates, one colour per estimate track (a ringed dot at its
    first estimate, an arrow head at its last); the legend, right of the axes,
    names every mark. Bottom: OSPA per scan.
    """
    from matplotlib.lines import Line2D

    from jointtrack.experiments.plots import _arrows, plt

    fig, (ax, ax2) = plt.subplots(
        2, 1, figsize=(11.0, 9.5), gridspec_kw={"height_ratios": [3, 1]}, layout="constrained"
    )
    ax.plot(sc.sensors[:, 0], sc.sensors[:, 1], "^", c="0.55", ms=7, zorder=1)
    tt, ti, tp = sc.truth_table()
    keep = tt < sc.times[stop - 1] + 0.5 * sc.dt
    truth_ends, truth_befores = [], []
    for i in np.unique(ti[keep]):
        m = keep & (ti == i)
        ax.plot(tp[m, 0], tp[m, 1], "-", c="k", lw=1.4, zorder=2)
        ax.plot(tp[m][:1, 0], tp[m][:1, 1], "o", c="k", ms=5, zorder=3)
        if m.sum() > 1:
            truth_ends.append(tp[m][-1, :2])
            truth_befores.append(tp[m][-2, :2])
    if truth_ends:
        _arrows(
            ax, np.asarray(truth_ends), np.asarray(truth_befores), ["k"] * len(truth_ends), 0.16, 3
        )
    n_tracks = 0
    if rows:
        arr = np.asarray(rows, dtype=float)
        ids = arr[:, 1].astype(int)
        cmap = plt.get_cmap("tab10")
        ends, befores, cols = [], [], []
        for n, i in enumerate(np.unique(ids)):
            m = ids == i
            col = cmap(n % 10)
            ax.plot(arr[m, 2], arr[m, 3], ".", ms=4, c=col, zorder=4)
            ax.plot(arr[m][:1, 2], arr[m][:1, 3], "o", ms=5, c=col, mec="k", mew=0.6, zorder=5)
            if m.sum() > 1:
                ends.append(arr[m][-1, 2:4])
                befores.append(arr[m][-2, 2:4])
                cols.append(col)
        n_tracks = len(np.unique(ids))
        if ends:
            _arrows(ax, np.asarray(ends), np.asarray(befores), cols, 0.12, 5)
    linked = "SPS-MB labels" if filter_name == "sps-mb" else "linked scan to scan"
    handles = [
        Line2D([], [], ls="none", marker="^", c="0.55", ms=7, label="sensors"),
        Line2D([], [], c="k", lw=1.4, label="truth"),
        Line2D([], [], ls="none", marker="o", c="k", ms=5, label="truth start"),
        Line2D(
            [],
            [],
            ls="none",
            marker=".",
            c="C0",
            ms=8,
            label=f"estimates: one colour per track\n({linked};\ncolours repeat after 10)",
        ),
        Line2D(
            [],
            [],
            ls="none",
            marker="o",
            c="C0",
            mec="k",
            mew=0.8,
            ms=6,
            label="first estimate of a track",
        ),
        Line2D([], [], ls="none", marker=">", c="0.3", ms=7, label="arrow: direction at the end"),
    ]
    ax.legend(
        handles=handles,
        loc="upper left",
        bbox_to_anchor=(1.02, 1.0),
        borderaxespad=0.0,
        fontsize=8,
    )
    ax.set_xlim(sc.region[0, 0] - 2, sc.region[0, 1] + 2)
    ax.set_ylim(sc.region[1, 0] - 2, sc.region[1, 1] + 2)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(
        f"acoustic, seed {sc.seed}: {filter_name} ({likelihood} likelihood) — "
        f"{stop} scans, {n_tracks} estimate tracks",
        fontsize=10,
    )
    ax.grid(alpha=0.2)
    ax2.plot(sc.times[:stop], ospa_per_scan, c="k", lw=1.3)
    ax2.set_xlabel("time (s)")
    ax2.set_ylabel(f"OSPA (m)\nc = {OSPA_C:g} m, p = 1")
    ax2.set_ylim(0, OSPA_C * 1.05)
    ax2.grid(alpha=0.2)
    return fig


def _plot(path, sc, rows, ospa_per_scan, filter_name, likelihood, stop) -> Path:
    """Write :func:`acoustic_figure` to ``path``."""
    from jointtrack.experiments.plots import save_figure

    fig = acoustic_figure(sc, rows, ospa_per_scan, filter_name, likelihood, stop)
    return save_figure(fig, path, dpi=100)


def print_acoustic_summary(metrics: dict, console) -> None:
    """A few lines: filter, mean OSPA / GOSPA (all scans and after burn-in), time per scan."""
    f = metrics["filter"]
    console.print(
        f"{f['name']} ({f['likelihood']} likelihood) on acoustic seed "
        f"{metrics['scenario']['seed']}, "
        f"{metrics['scenario']['n_scans']} scans",
        markup=False,
        highlight=False,
    )
    after = metrics["ospa_mean_after_burn_in"]
    after = "n/a" if after is None else f"{after:.3f} m"
    console.print(
        f"  OSPA mean {metrics['ospa']['mean']:.3f} m (after {metrics['burn_in']} scans: "
        f"{after}); GOSPA mean {metrics['gospa']['mean']:.3f}; "
        f"{1e3 * metrics['timing']['mean_seconds_per_scan']:.0f} ms per scan",
        markup=False,
        highlight=False,
    )
