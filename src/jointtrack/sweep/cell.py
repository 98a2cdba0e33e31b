"""The one "run one cell → metrics row" function of a sweep (:func:`run_cell`).

Every runnable thing goes through it: the Kalman JPDA tracker and the particle
JPDA tracker (:func:`jointtrack.experiments.run.run_scenario`, scenarios
bojilov, crossing, many, abreast, coalescence) and the superpositional filters
(:func:`jointtrack.experiments.acoustic_run.run_acoustic`, scenario acoustic).
A run writes its usual files into a temporary directory that is removed
afterwards; only the row is kept. The row's metrics depend on the parameters
and the seed only (the runs are seeded), so a cell run on a Dask worker and the
same cell run here give the same metrics; its timings and host do not.
"""

from __future__ import annotations

import contextlib
import math
import os
import socket
import tempfile
import time
import traceback
from collections.abc import Mapping
from pathlib import Path

__all__ = ["METRICS", "TIMING_METRICS", "method_label", "run_cell"]

#: The metrics a row carries, by kind of run: column name → path in the run's metrics dict.
METRICS = {
    "tracker": {
        "gospa": ("gospa", "mean"),
        "gospa_localisation": ("gospa", "mean_localisation"),
        "gospa_missed": ("gospa", "mean_missed"),
        "gospa_false": ("gospa", "mean_false"),
        "ospa": ("ospa", "mean"),
        "rmse": ("tracks", "rmse"),
        "coverage": ("tracks", "coverage"),
        "n_tracks": ("tracks", "n_tracks"),
        "n_false_tracks": ("tracks", "n_false_tracks"),
        "n_id_switches": ("tracks", "n_id_switches"),
        "scans_per_second": ("timing", "scans_per_second"),
    },
    "acoustic": {
        "gospa": ("gospa", "mean"),
        "ospa": ("ospa", "mean"),
        "gospa_after_burn_in": ("gospa_mean_after_burn_in",),
        "ospa_after_burn_in": ("ospa_mean_after_burn_in",),
        "seconds_per_scan": ("timing", "mean_seconds_per_scan"),
    },
}
#: Metrics that are timings: they differ from run to run of the same cell and seed.
TIMING_METRICS = frozenset({"scans_per_second", "seconds_per_scan"})


def _tables(params: Mapping) -> dict:
    out = {"tracker": {}, "scenario": {}, "metrics": {}, "filter": {}}
    for key, value in params.items():
        table, _, name = key.partition(".")
        out[table][name] = value
    return out


def method_label(params: Mapping) -> str:
    """The method a cell runs, for the report's lines: e.g. ``jpda/exact``, ``sps-mb/gaussian``.

    >>> method_label({"scenario.name": "bojilov", "tracker.association": "lbp"})
    'jpda/lbp'
    >>> method_label({"scenario.name": "acoustic", "filter.name": "sps-mb"})
    'sps-mb/gaussian'
    """
    t = _tables(params)
    if t["scenario"].get("name") == "acoustic":
        f = t["filter"]
        return f"{f.get('name', 'sps-cphd')}/{f.get('likelihood', 'gaussian')}"
    if t["tracker"].get("kind") == "particle":
        return f"particle/{t['tracker'].get('weights', 'exact')}"
    return f"jpda/{t['tracker'].get('association', 'exact')}"


def _run(params: Mapping, seed: int, out_dir: str) -> tuple[str, dict]:
    """Run the cell; ``(kind, metrics dict)``."""
    t = _tables(params)
    name = t["scenario"].pop("name", "bojilov")
    if name == "acoustic":
        from jointtrack.experiments.acoustic_run import run_acoustic

        f = dict(t["filter"])
        kwargs = {
            "filter_name": f.pop("name", "sps-cphd"),
            "likelihood": f.pop("likelihood", "gaussian"),
            **f,
        }
        return "acoustic", run_acoustic(out_dir, seed=seed, plots=False, **kwargs)
    from jointtrack.experiments.config import TRACKER_OPTION_KEYS
    from jointtrack.experiments.run import run_scenario

    tracker = dict(t["tracker"])
    options = {k: tracker.pop(k) for k in TRACKER_OPTION_KEYS if k in tracker}
    # the tracker's own generator (mcmc association, particles) follows the run's seed
    tracker.setdefault("seed", seed)
    particle = None
    if options.get("kind") == "particle":
        particle = {k: options[k] for k in ("weights", "particles") if k in options}
    scen = t["scenario"]
    start = {k: scen.pop(k) for k in ("start_from", "start_from_truth") if k in scen}
    metrics = run_scenario(
        name,
        tracker,
        out_dir,
        seed=seed,
        scenario_kwargs=scen,
        metrics_opts=t["metrics"] or None,
        plots=False,
        particle=particle,
        **start,
    )
    return "tracker", metrics


def _number(value):
    """A finite float, or None: NaN and ±inf never reach a row."""
    if value is None or isinstance(value, bool):
        return None
    try:
        x = float(value)
    except (TypeError, ValueError):
        return None
    return x if math.isfinite(x) else None


def _pick(metrics: Mapping, path: tuple):
    node = metrics
    for key in path:
        if not isinstance(node, Mapping) or key not in node:
            return None
        node = node[key]
    return _number(node)


def _one_blas_thread():
    """Run the cell with one BLAS thread, wherever it runs.

    Dask's worker processes start with one BLAS thread (its nanny sets
    ``OMP_NUM_THREADS=1`` and friends); a multi-threaded BLAS sums in another
    order and changes the last bits of the metrics. One thread everywhere
    makes a cell's metrics the same on a worker and in a serial loop here (and
    a sweep already runs one cell per core). Without threadpoolctl (installed
    with ``jointtrack[dask]``) the process's setting is kept.
    """
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:
        return contextlib.nullcontext()
    # the limit reaches the BLAS libraries loaded when it is set: load them all first
    # (scipy brings its own OpenBLAS, loaded on the first import of scipy.linalg)
    import scipy.linalg  # noqa: F401

    import jointtrack.experiments.acoustic_run  # noqa: F401
    import jointtrack.experiments.run  # noqa: F401

    return threadpool_limits(limits=1, user_api="blas")


def run_cell(params: Mapping, seed: int) -> dict:
    """Run one cell of a sweep with one seed and return its row.

    Parameters
    ----------
    params : flat ``"table.key" -> value`` settings of the cell
        (:attr:`jointtrack.sweep.spec.Run.params`).
    seed : the run's seed (scenario seed; the tracker's unless ``tracker.seed``
        is set).

    Returns
    -------
    dict
        ``status`` (``"ok"`` or ``"failed"``), ``error`` (the exception's type,
        message and where it was raised, or None), ``kind``
        (``"tracker"`` or ``"acoustic"``), ``metrics`` (name → finite float or
        None; :data:`METRICS`), ``run_seconds``, ``started_at`` (Unix time),
        ``host`` and ``pid``. An exception inside the run is caught and
        reported in the row, never raised: a deterministic failure would fail
        again on a retry. BLAS is limited to one thread during the run (with
        threadpoolctl), as in a Dask worker, so the metrics do not depend on
        where the cell ran.
    """
    started_at = time.time()
    t0 = time.perf_counter()
    kind = "acoustic" if params.get("scenario.name") == "acoustic" else "tracker"
    status, error, values = "ok", None, {}
    try:
        with _one_blas_thread(), tempfile.TemporaryDirectory(prefix="jointtrack-cell-") as tmp:
            kind, metrics = _run(params, int(seed), tmp)
        values = {col: _pick(metrics, path) for col, path in METRICS[kind].items()}
    except Exception as exc:  # noqa: BLE001 - every failure becomes the row's error
        status = "failed"
        frame = traceback.extract_tb(exc.__traceback__)[-1]
        error = (
            f"{type(exc).__name__}: {' '.join(str(exc).split())} "
            f"(at {Path(frame.filename).name}:{frame.lineno} in {frame.name})"
        )
    return {
        "status": status,
        "error": error,
        "kind": kind,
        "metrics": values,
        "run_seconds": time.perf_counter() - t0,
        "started_at": started_at,
        "host": socket.gethostname(),
        "pid": os.getpid(),
    }
