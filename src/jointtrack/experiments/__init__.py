"""Experiments: the main job (``jointtrack run``) and reproductions of the papers' tables.

* :mod:`jointtrack.experiments.run` — :func:`run_scenario`, :func:`run_detections`:
  tracker on a built-in scenario or a detections file; tracks, metrics, plots. Its
  parts: :mod:`~jointtrack.experiments.config` (config file, scenarios, tracker
  settings), :mod:`~jointtrack.experiments.writers` (tracks file, checkpoint
  bookkeeping), :mod:`~jointtrack.experiments.summary` (metrics, summary tables).
* :mod:`jointtrack.experiments.bojilov` — :func:`reproduce`: Bojilov et al.'s
  Tables 2–3 (hypotheses, multiplications, seconds per cluster) beside the paper's.
* :mod:`jointtrack.experiments.plots` — the figures (matplotlib, Agg backend).
* :mod:`jointtrack.experiments.map_plot` — :func:`plot_track_map`: tracks over the
  targets' self-reports on a longitude/latitude map (PNG).

Names are imported on first use, so importing this package stays cheap.
"""

from __future__ import annotations

import importlib

_LAZY = {
    "run_scenario": "run",
    "run_detections": "run",
    "load_config": "run",
    "RunConfig": "run",
    "RunConfigError": "run",
    "reproduce": "bojilov",
    "PAPER_TABLES": "bojilov",
}

__all__ = sorted(_LAZY)


def __getattr__(name: str):
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'jointtrack.experiments' has no attribute {name!r}")
    value = getattr(importlib.import_module(f"jointtrack.experiments.{module}"), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(_LAZY))
