"""What a tracking run imports: no module it does not use at ~1 CPU-s a process.

Every ``jointtrack run`` is a fresh process, and so is each CLI subprocess of the tests
(the killed runs), each Dask worker of a sweep and each xdist worker. scipy.stats costs
one about 1 CPU-s to import (its distributions build their docstrings on import); the
tracker needs one χ² quantile from it, which :func:`jointtrack.association.gating.gate_threshold`
computes from ``scipy.special`` (the same bits). A crossing run took 6.25 → 5.26 CPU-s
without it (three runs each).
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import jointtrack

#: what ``jointtrack run --config`` imports to track a scenario and write its outputs
_RUN_MODULES = (
    "jointtrack.cli",
    "jointtrack.experiments.run",
    "jointtrack.experiments.writers",
    "jointtrack.experiments.config",
    "jointtrack.scenarios",
    "jointtrack.trackers",
)


def test_a_scenario_run_does_not_import_scipy_stats():
    # a fresh process: this one has imported everything the other tests use
    code = (
        "import importlib, sys\n"
        f"for name in {_RUN_MODULES!r}:\n"
        "    importlib.import_module(name)\n"
        "print(sorted(m for m in sys.modules if m.split('.')[:2] == ['scipy', 'stats']))\n"
    )
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(
        [str(Path(jointtrack.__file__).parents[1]), env.get("PYTHONPATH", "")]
    )
    proc = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "[]", f"imported: {proc.stdout.strip()[:300]}"
