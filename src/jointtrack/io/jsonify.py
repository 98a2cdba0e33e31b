"""The one numpy-aware JSON conversion of the package: :func:`to_jsonable`.

Used by :func:`jointtrack.io.write_metrics`, the run bookkeeping of
:mod:`jointtrack.experiments` and the benchmark result files of
:mod:`jointtrack.bench`.
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Callable, Mapping

import numpy as np

__all__ = ["to_jsonable"]

_NONFINITE = ("null", "string")


def _exception_text(obj) -> str:
    return f"{type(obj).__name__}: {obj}"


def to_jsonable(
    obj,
    *,
    nonfinite: str = "null",
    fallback: Callable | str | None = None,
    what: str = "metrics",
):
    """``obj`` as plain JSON data (dict / list / str / int / float / bool / None).

    numpy scalars and arrays → numbers and (nested) lists, dataclass instances
    → objects, mappings → objects (keys: strings, numbers → their text),
    tuples / sets → lists, paths → strings.

    Parameters
    ----------
    nonfinite : ``"null"`` (default): NaN and ±inf become ``None`` (JSON
        ``null``), so the result is standard JSON; ``"string"``: they become
        ``"nan"``, ``"inf"`` and ``"-inf"``.
    fallback : what to do with any other object: ``None`` (default) raises
        ValueError; ``"text"`` writes exceptions as ``"Type: message"`` and
        anything else as ``str(obj)``; a callable is applied and its result
        converted in turn.
    what : the name of the data in error messages.
    """
    if nonfinite not in _NONFINITE:
        raise ValueError(f"nonfinite must be one of {', '.join(_NONFINITE)}, got {nonfinite!r}")

    def conv(o):
        if dataclasses.is_dataclass(o) and not isinstance(o, type):
            return {f.name: conv(getattr(o, f.name)) for f in dataclasses.fields(o)}
        if isinstance(o, Mapping):
            out = {}
            for k, v in o.items():
                if isinstance(k, np.generic):
                    k = k.item()
                if not isinstance(k, str | int | float | bool) and k is not None:
                    raise ValueError(f"{what}: dict key {k!r} is not a string or number")
                out[str(k) if not isinstance(k, str) else k] = conv(v)
            return out
        if isinstance(o, np.ndarray):
            return conv(o.tolist())
        if isinstance(o, np.generic):
            return conv(o.item())
        if isinstance(o, bool) or o is None or isinstance(o, str | int):
            return o
        if isinstance(o, float):
            if math.isfinite(o):
                return o
            return None if nonfinite == "null" else str(o)
        if isinstance(o, os.PathLike):
            return os.fspath(o)
        if isinstance(o, list | tuple | set | frozenset):
            return [conv(v) for v in o]
        if fallback == "text":
            return _exception_text(o) if isinstance(o, BaseException) else str(o)
        if callable(fallback):
            return conv(fallback(o))
        if isinstance(o, complex):
            raise ValueError(f"{what}: complex value {o!r} cannot be written to JSON")
        raise ValueError(f"{what}: value of type {type(o).__name__} cannot be written to JSON")

    return conv(obj)
