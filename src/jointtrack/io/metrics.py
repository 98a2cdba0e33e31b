"""Metrics files: :func:`write_metrics` (a JSON object)."""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from pathlib import Path

from jointtrack.io.jsonify import to_jsonable

__all__ = ["write_metrics"]


def write_metrics(metrics: Mapping, path) -> Path:
    """Write a metrics mapping as a JSON object (``indent=2``, UTF-8).

    numpy scalars/arrays → numbers/lists, dataclasses → objects, tuples/sets →
    lists, paths → strings, NaN/±inf → ``null`` (:func:`jointtrack.io.to_jsonable`).
    Parent directories are created.
    """
    if not isinstance(metrics, Mapping):
        raise ValueError(f"metrics must be a mapping (dict), got {type(metrics).__name__}")
    data = to_jsonable(metrics)
    path = Path(os.fspath(path))
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(data, indent=2, allow_nan=False) + "\n", encoding="utf-8")
    return path
