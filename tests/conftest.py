"""Test-suite settings: hypothesis runs derandomised in CI (reproducible), random locally."""

from __future__ import annotations

import os

from hypothesis import settings

settings.register_profile("ci", derandomize=True, print_blob=True)
if os.environ.get("CI"):
    settings.load_profile("ci")

#: The files that take longest (worker seconds, ``--durations=0`` of the full suite),
#: run first: pytest-xdist's ``--dist loadfile`` hands files out in collection order,
#: and one of these started last keeps one core busy alone at the end (≈ 8 % of CI's
#: wall time was such a tail). Order only; nothing is skipped.
SLOWEST_FIRST = (
    "test_run_finish.py",
    "test_run_durable.py",
    "test_numba_cache.py",
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
)


def pytest_collection_modifyitems(config, items):
    rank = {name: i for i, name in enumerate(SLOWEST_FIRST)}
    # a stable sort: each file's tests keep their order, every worker sees the same order
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))
