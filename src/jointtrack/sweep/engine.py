"""The Dask driver of a sweep: submit every pending run, write each row as it completes.

:func:`run_sweep` runs the grid of a :class:`~jointtrack.sweep.spec.SweepSpec`
on Dask distributed — a ``LocalCluster`` of worker processes by default, an
existing scheduler (``scheduler="tcp://host:port"``) or a given ``Client`` —
with :func:`~jointtrack.sweep.cell.run_cell` as the one task function.

Nothing is lost, nothing is pretended:

* Only this driver writes results, one row per run as its future completes
  (:class:`~jointtrack.sweep.store.ResultStore`: one atomically renamed file
  per run, named by the run's id). A run whose worker dies is rescheduled by
  Dask on another worker (up to ``distributed.scheduler.allowed-failures``
  times, then recorded as failed with the ``KilledWorker`` error); a finished
  result is already on disk, so none is lost and none is written twice.
* A restarted sweep skips the runs with an ``ok`` row (resume) and reruns the
  missing and failed ones (a rerun replaces the failed row).
* An exception inside a run is recorded in its row (``status = "failed"``,
  ``error``) and the sweep goes on; with ``fail_fast`` the remaining runs are
  cancelled at the first failure. :attr:`SweepOutcome.complete` is true only if
  every run of the grid has an ``ok`` row.

:func:`plan` is the dry run: grid size, runs already done, and a cost estimate
from one pilot run per (scenario, method), run here.
"""

from __future__ import annotations

import json
import os
import time
import uuid
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from jointtrack._console import progress_bar
from jointtrack.sweep.cell import method_label, run_cell
from jointtrack.sweep.spec import SweepSpec
from jointtrack.sweep.store import ResultStore

__all__ = [
    "DASK_MISSING",
    "ResultStore",
    "SweepOutcome",
    "dask_available",
    "plan",
    "run_sweep",
]

#: The one-line message when Dask distributed is not installed.
DASK_MISSING = (
    "jointtrack sweep needs Dask distributed, which is not installed: "
    "pip install 'jointtrack[dask]'"
)
#: How many times Dask reschedules a run whose worker died before recording it as failed.
ALLOWED_FAILURES = 3


def dask_available() -> bool:
    """Whether ``dask.distributed`` can be imported."""
    try:
        import distributed  # noqa: F401
    except ImportError:
        return False
    return True


@dataclass
class SweepOutcome:
    """What a sweep did.

    Attributes
    ----------
    total : runs in the grid.
    skipped : runs already done (an ``ok`` row) when the sweep started.
    ran : runs whose row this sweep wrote.
    ok, failed : runs of the grid with an ``ok`` / ``failed`` row at the end.
    missing : ids of the runs of the grid with no row at the end (cancelled by
        ``fail_fast`` or an interrupt).
    wall_seconds : the sweep's wall time (cluster start included).
    workers : number of Dask workers (0 if nothing had to run).
    dashboard : the Dask dashboard link, if one was up.
    results : the Parquet dataset directory.
    """

    total: int
    skipped: int
    ran: int = 0
    ok: int = 0
    failed: int = 0
    missing: list = field(default_factory=list)
    wall_seconds: float = 0.0
    workers: int = 0
    dashboard: str | None = None
    results: Path | None = None

    @property
    def complete(self) -> bool:
        """Every run of the grid has an ``ok`` row."""
        return self.ok == self.total


def _task(params: dict, seed: int) -> dict:
    """The function a worker runs: :func:`run_cell` plus the worker's address."""
    row = run_cell(params, seed)
    try:
        from distributed import get_worker

        row["worker"] = get_worker().address
    except (ImportError, ValueError):
        row["worker"] = None
    return row


def _row(run, result: dict, submitted_at: float, version: str) -> dict:
    """The stored row of a run: ids, parameters, seed, version, status, metrics, timings."""
    received = time.time()
    row = {
        "run_id": run.run_id,
        "cell_id": run.cell_id,
        "method": method_label(run.params),
        "seed": int(run.seed),
        "params": json.dumps(run.params, sort_keys=True),
    }
    for key, value in run.params.items():
        row[key] = value
    row.update(
        status=result["status"],
        error=result.get("error"),
        kind=result.get("kind"),
        version=version,
    )
    for name, value in (result.get("metrics") or {}).items():
        row[f"metric.{name}"] = value
    started = result.get("started_at")
    run_s = result.get("run_seconds")
    row.update(
        run_seconds=run_s,
        # waiting for a free worker plus sending the task
        queue_seconds=None if started is None else max(0.0, started - submitted_at),
        # result back to this driver after the run ended
        overhead_seconds=(
            None if started is None or run_s is None else max(0.0, received - started - run_s)
        ),
        submitted_at=submitted_at,
        started_at=started,
        finished_at=received,
        host=result.get("host"),
        worker=result.get("worker"),
        pid=result.get("pid"),
    )
    return row


def _failed_result(exc: BaseException) -> dict:
    """A row's result for a run Dask gave up on (its worker died too often, cancelled, …)."""
    return {
        "status": "failed",
        "error": f"{type(exc).__name__}: {' '.join(str(exc).split())}",
        "metrics": {},
    }


def _progress(console, total: int, done: int):
    bar = progress_bar(console, unit="failed {task.fields[failed]}", remaining=True)
    task = bar.add_task("sweep", total=total, completed=done, failed=0)
    return bar, task


def _start_client(workers, scheduler, console):
    """A Dask client: on ``scheduler`` if given, else on a new LocalCluster of processes."""
    import dask
    from distributed import Client, LocalCluster

    dask.config.set({"distributed.scheduler.allowed-failures": ALLOWED_FAILURES})
    if scheduler is not None:
        try:
            return Client(scheduler, timeout="20s"), None
        except OSError as exc:
            raise ValueError(f"--scheduler {scheduler}: cannot connect ({exc})") from None
    n = (os.cpu_count() or 1) if workers is None else workers
    # Worker settings that slow the runs down (one Bojilov run, one worker vs this
    # process): the statistical profiler samples the task every 10 ms holding the GIL
    # (it only feeds the dashboard's profile page), and MALLOC_TRIM_THRESHOLD_=65536
    # makes glibc give memory back after every numpy temporary (0.79 s vs 0.68 s per
    # run; 0.69 s vs 0.66 s without it). One BLAS thread per worker is kept.
    environ = dict(dask.config.get("distributed.nanny.pre-spawn-environ", {}))
    environ.pop("MALLOC_TRIM_THRESHOLD_", None)
    dask.config.set(
        {
            "distributed.worker.profile.enabled": False,
            "distributed.nanny.pre-spawn-environ": environ,
        }
    )
    # one thread per worker process: the runs are CPU-bound Python and numba code
    cluster = LocalCluster(
        n_workers=n,
        threads_per_worker=1,
        processes=True,
        dashboard_address=":0",  # any free port: never clashes with another cluster
        silence_logs=40,  # ERROR: a killed worker's restart is expected, not news
    )
    return Client(cluster), cluster


def _dashboard(client, local: bool) -> str | None:
    """The dashboard link, only when a dashboard is really served.

    Without bokeh the scheduler still answers on the dashboard port, with a page
    asking to install bokeh; a local cluster's scheduler runs in this process,
    so bokeh here decides. A remote scheduler's environment is its own.
    """
    if local:
        try:
            import bokeh  # noqa: F401
        except ImportError:
            return None
    try:
        services = client.scheduler_info().get("services", {})
    except Exception:  # noqa: BLE001 - the link is a convenience, never a failure
        return None
    return client.dashboard_link if "dashboard" in services else None


def run_sweep(
    spec: SweepSpec,
    out_dir,
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    client=None,
    fail_fast: bool = False,
    progress: bool = False,
    console=None,
    on_row: Callable[[dict], None] | None = None,
) -> SweepOutcome:
    """Run every pending run of ``spec`` on Dask; rows go to ``out_dir/results``.

    Parameters
    ----------
    spec : the parsed sweep (:func:`~jointtrack.sweep.spec.load_spec`).
    out_dir : output directory; the Parquet dataset is ``out_dir/results``.
    workers : worker processes of the LocalCluster (default: the machine's cores).
    scheduler : address of an existing Dask scheduler (``tcp://host:port``);
        its workers must have jointtrack installed.
    client : an existing ``distributed.Client`` to use (not closed here; its
        workers' settings are its own). For its own LocalCluster the sweep sets,
        in this process's Dask config, ``allowed-failures`` (3), no worker
        profiler and no ``MALLOC_TRIM_THRESHOLD_`` (see ``_start_client``).
    fail_fast : cancel the remaining runs at the first failed run.
    progress : show a rich progress bar (runs done / total, failures, ETA).
    console : rich console for the progress bar and the dashboard link.
    on_row : called with each row right after it is written (tests, monitors).

    Returns
    -------
    SweepOutcome

    Raises
    ------
    ValueError
        A bad ``workers`` or an unreachable ``scheduler``.
    ImportError
        Dask distributed is not installed (message: :data:`DASK_MISSING`).
    """
    from rich.console import Console

    from jointtrack import __version__

    if workers is not None and (
        isinstance(workers, bool) or not isinstance(workers, int) or workers < 1
    ):
        raise ValueError(f"workers must be an integer ≥ 1, got {workers!r}")
    if scheduler is not None and workers is not None:
        raise ValueError("workers: the workers of an existing --scheduler are its own; omit it")
    console = console or Console(quiet=True)
    t0 = time.perf_counter()
    store = ResultStore(Path(out_dir) / "results")
    runs = spec.runs()
    ids = {r.run_id for r in runs}
    done = store.run_ids(status="ok") & ids
    pending = [r for r in runs if r.run_id not in done]
    outcome = SweepOutcome(total=len(runs), skipped=len(done), results=store.path)
    if pending:
        if not dask_available():
            raise ImportError(DASK_MISSING)
        _execute(
            pending,
            store,
            outcome,
            client=client,
            workers=workers,
            scheduler=scheduler,
            fail_fast=fail_fast,
            progress=progress,
            console=console,
            on_row=on_row,
            version=__version__,
        )
    ok = store.run_ids(status="ok") & ids
    present = store.run_ids() & ids
    outcome.ok = len(ok)
    outcome.failed = len(present - ok)
    outcome.missing = sorted(ids - present)
    outcome.wall_seconds = time.perf_counter() - t0
    return outcome


def _execute(
    pending,
    store,
    outcome,
    *,
    client,
    workers,
    scheduler,
    fail_fast,
    progress,
    console,
    on_row,
    version,
) -> None:
    """Submit ``pending`` to Dask, write each row to ``store`` as it arrives, count in ``outcome``.

    The connection settings and callbacks are :func:`run_sweep`'s, passed by keyword.
    """
    from distributed import as_completed

    own_cluster = None
    own_client = client is None
    if own_client:
        client, own_cluster = _start_client(workers, scheduler, console)
    futures = {}
    try:
        outcome.workers = len(client.scheduler_info().get("workers", {}))
        outcome.dashboard = _dashboard(client, getattr(client, "cluster", None) is not None)
        if outcome.dashboard:
            console.print(f"Dask dashboard: {outcome.dashboard}", markup=False, highlight=False)
        submitted_at = time.time()
        token = uuid.uuid4().hex[:8]
        for run in pending:
            # a fresh key per sweep: a key cancelled by an interrupted sweep on the same
            # cluster may still be in the scheduler; the store keeps one row per run id
            fut = client.submit(
                _task, run.params, run.seed, key=f"jointtrack-run-{run.run_id}-{token}"
            )
            futures[fut] = run
        bar = None
        if progress:
            bar, task = _progress(console, outcome.total, outcome.skipped)
            bar.start()
        failed = 0
        try:
            for fut in as_completed(list(futures)):
                run = futures[fut]
                try:
                    result = fut.result()
                except Exception as exc:  # noqa: BLE001 - KilledWorker, cancelled: recorded
                    result = _failed_result(exc)
                row = _row(run, result, submitted_at, version)
                store.write(row)
                outcome.ran += 1
                failed += row["status"] != "ok"
                if bar is not None:
                    bar.update(task, advance=1, failed=failed)
                if on_row is not None:
                    on_row(row)
                if fail_fast and row["status"] != "ok":
                    break
        finally:
            if bar is not None:
                bar.stop()
    finally:
        # cancelling what is left (fail-fast, interrupt) frees the workers at once
        pending_futures = [f for f in futures if not f.done()]
        if pending_futures:
            client.cancel(pending_futures)
        if own_client:
            client.close()
        if own_cluster is not None:
            own_cluster.close()


# ----------------------------------------------------------------------------- dry run


def plan(spec: SweepSpec, out_dir, *, workers: int | None = None, pilot: bool = True) -> dict:
    """The dry run: grid size, runs already done, and the estimated cost of the rest.

    Parameters
    ----------
    spec : the parsed sweep.
    out_dir : output directory (its ``results`` are read, nothing is written).
    workers : workers the estimate divides by (default: the machine's cores).
    pilot : time one pilot run per (scenario, method) here; without it there
        is no estimate.

    Returns
    -------
    dict
        ``cells``, ``seeds``, ``runs``, ``done``, ``failed_before``,
        ``pending``, ``workers``; with ``pilot``: ``pilots`` (list of
        (scenario, method, seconds, status)), ``cpu_seconds`` (pending runs ×
        their group's pilot time) and ``wall_seconds`` (``cpu_seconds /
        workers``, no Dask overhead counted). The basis is one run per group:
        runs of a group differ in size (``n_scans``, particles) and clutter,
        so it is an order of magnitude, not a promise.
    """
    store_dir = Path(out_dir) / "results"
    runs = spec.runs()
    ids = {r.run_id for r in runs}
    store = ResultStore(store_dir) if store_dir.is_dir() else None
    ok = (store.run_ids(status="ok") & ids) if store else set()
    present = (store.run_ids() & ids) if store else set()
    pending = [r for r in runs if r.run_id not in ok]
    n_workers = workers or os.cpu_count() or 1
    out = {
        "cells": spec.n_cells,
        "seeds": len(spec.seeds),
        "runs": len(runs),
        "done": len(ok),
        "failed_before": len(present - ok),
        "pending": len(pending),
        "workers": n_workers,
    }
    if not pilot:
        return out
    groups = {}
    for r in pending:
        groups.setdefault((r.params["scenario.name"], method_label(r.params)), []).append(r)
    pilots, cpu = [], 0.0
    for i, ((scenario, method), members) in enumerate(groups.items()):
        first = members[0]
        if i == 0:
            run_cell(first.params, first.seed)  # loads the compiled kernels: not timed
        res = run_cell(first.params, first.seed)
        pilots.append((scenario, method, res["run_seconds"], res["status"]))
        cpu += res["run_seconds"] * len(members)
    out.update(pilots=pilots, cpu_seconds=cpu, wall_seconds=cpu / n_workers)
    return out
