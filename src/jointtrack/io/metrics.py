"""Metrics files: :func:`write_metrics` (a JSON object)."""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from pathlib import Path

from jointtrack._atomic import atomic_file
from jointtrack.io.jsonify import to_jsonable

__all__ = ["write_metrics"]


def write_metrics(metrics: Mapping, path) -> Path:
    """Write a metrics mapping as a JSON object (``indent=2``, UTF-8).

    numpy scalars/arrays → numbers/lists, dataclasses → objects, tuples/sets →
    lists, paths → strings, NaN/±inf → ``null`` (:func:`jointtrack.io.to_jsonable`).
    Parent directories are created; the file is written atomically.
    """
    if not isinstance(metrics, Mapping):
        raise ValueError(f"metrics must be a mapping (dict), got {type(metrics).__name__}")
    data = to_jsonable(metrics)
    path = Path(os.fspath(path))
    path.parent.mkdir(parents=True, exist_ok=True)
    text = json.dumps(data, indent=2, allow_nan=False) + "\n"
    with atomic_file(path) as tmp:  # a kill leaves the old file or the new one
        tmp.write_text(text, encoding="utf-8")
    return path
