"""Test-suite settings: hypothesis runs derandomised in CI (reproducible), random locally."""

from __future__ import annotations

import os

from hypothesis import settings

# numba's parallel kernels run on OpenMP (libgomp) threads, which by default spin for
# ~10 ms after each parallel region before they sleep: with two xdist workers on two
# cores that spinning takes the CPU from the other worker (tests/test_tracker.py: 15.9
# → 12.1 CPU-s). Waiting passively changes no result, only what idle threads cost.
# Set before any parallel kernel starts libgomp (it reads this once); the CLI
# subprocesses of the tests inherit it.
os.environ.setdefault("OMP_WAIT_POLICY", "passive")

settings.register_profile("ci", derandomize=True, print_blob=True)
if os.environ.get("CI"):
    settings.load_profile("ci")

#: The files that take longest (worker seconds, ``--durations=0`` of the full suite),
#: run first: with ``--no-loadscope-reorder`` (pyproject's addopts) pytest-xdist's
#: ``--dist loadfile`` hands files out in collection order — by default it sorts them by
#: their number of tests, which put these few-test, slow files last, one core busy
#: alone at the end (≈ 8 % of CI's wall time). Order only; nothing is skipped.
#: test_numba_cache.py second: it compiles in a cache of its own, so on a fresh
#: install the second worker does not compile the JIPDA run's kernels at the same
#: time as the first (test_run_finish.py's first run compiles them into the shared
#: cache, ≈ 80 CPU-s; test_run_durable.py then loads them).
SLOWEST_FIRST = (
    "test_run_finish.py",
    "test_numba_cache.py",
    "test_run_durable.py",
    "test_issue31_tracker.py",
    "test_run_realdata.py",
    "test_issue22_io.py",
    "test_run_pmbm.py",
    "test_assignment_core.py",
    "test_metrics.py",
    "test_interop_stonesoup.py",
    "test_issue22_schaub.py",
    "test_pmbm_issue31.py",
    "test_sweep.py",
    "test_cli.py",
    "test_nannuru.py",
    # CPU-s ≥ 18 in a cold-cache -n 2 run of ed4855f, not ranked before
    "test_pmbm_state.py",
    "test_pmbm_budget.py",
    "test_identity_jpda.py",
    "test_repro_plots_readable.py",
)


def pytest_collection_modifyitems(config, items):
    rank = {name: i for i, name in enumerate(SLOWEST_FIRST)}
    # a stable sort: each file's tests keep their order, every worker sees the same order
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))
