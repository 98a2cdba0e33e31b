"""Monte Carlo sweeps on Dask: a TOML grid of cells × seeds, one Parquet row per run.

* :mod:`~jointtrack.sweep.spec` — :func:`load_spec` / :func:`parse_spec`: the
  ``[sweep]`` axes over the ``[tracker]``/``[scenario]``/``[metrics]``/``[filter]``
  base tables, checked; stable run ids (:func:`run_id`).
* :mod:`~jointtrack.sweep.cell` — :func:`run_cell`: the one "run one cell →
  metrics row" function (JPDA tracker, particle JPDA, superpositional filters).
* :mod:`~jointtrack.sweep.store` — :class:`ResultStore`: the Parquet dataset,
  one atomically renamed file per run.
* :mod:`~jointtrack.sweep.engine` — :func:`run_sweep` (the Dask driver; resume,
  retries, fail-fast) and :func:`plan` (the dry run).
* :mod:`~jointtrack.sweep.report` — mean and 95 % CI per metric per cell,
  ``summary.csv`` and plots of each metric vs each axis.

Dask is an optional extra (``pip install 'jointtrack[dask]'``); everything
here but :func:`run_sweep` works without it. The command is ``jointtrack sweep
SPEC.toml``.
"""

from __future__ import annotations

from jointtrack.sweep.cell import run_cell
from jointtrack.sweep.engine import SweepOutcome, plan, run_sweep
from jointtrack.sweep.report import summarise, write_report
from jointtrack.sweep.spec import SweepSpec, load_spec, parse_spec, run_id
from jointtrack.sweep.store import ResultStore

__all__ = [
    "ResultStore",
    "SweepOutcome",
    "SweepSpec",
    "load_spec",
    "parse_spec",
    "plan",
    "run_cell",
    "run_id",
    "run_sweep",
    "summarise",
    "write_report",
]
