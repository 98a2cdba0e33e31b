"""Test-suite settings: hypothesis runs derandomised in CI (reproducible), random locally."""

from __future__ import annotations

import os

from hypothesis import settings

settings.register_profile("ci", derandomize=True, print_blob=True)
if os.environ.get("CI"):
    settings.load_profile("ci")

# The files that take longest (measured with `pytest -n 2 --durations=0`, 2026-11-27: the
# numba-cache test compiles every parallel kernel in fresh processes, ~70 s; the kill/resume
# files run dozens of CLI subprocesses) go first, so that under `-n auto --dist loadfile` a
# worker does not start one of them while the other has nothing left to do.
_SLOWEST_FIRST = (
    "test_numba_cache.py",
    "test_run_durable.py",
    "test_run_realdata.py",
    "test_issue22_io.py",
)


def pytest_collection_modifyitems(config, items):
    def rank(item):
        name = item.path.name
        return _SLOWEST_FIRST.index(name) if name in _SLOWEST_FIRST else len(_SLOWEST_FIRST)

    items.sort(key=rank)  # stable: the order within and among the other files is kept
