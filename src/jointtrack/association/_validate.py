"""Checks for the JPDA cluster convention shared by every association method.

Convention (DESIGN.md): ``L`` is N tracks × M measurements of likelihood ratios
``L[i, j] = P_D g_ij / λ`` (0 where measurement j is outside track i's gate);
``miss[i] = 1 − P_D P_G`` is the weight of "track i detected nothing". The
output ``beta`` is N × (M+1) with column 0 the no-measurement event.
"""

from __future__ import annotations

import numpy as np

from jointtrack.assignment._checks import _as_real_array, as_int, as_weights
from jointtrack.association.clustering import has_feasible_event
from jointtrack.errors import InfeasibleAssignmentError

NO_FEASIBLE_EVENT = (
    "no feasible joint association event: the certainly detected tracks (miss = 0) "
    "cannot all receive distinct gated measurements"
)


def check_cluster(L, miss) -> tuple[np.ndarray, np.ndarray]:
    """Return ``(L, miss)`` as float64 arrays after checking the cluster input.

    Raises
    ------
    ValueError
        wrong shapes, negative or non-finite entries, ``miss`` outside [0, 1].
    InfeasibleAssignmentError
        a track with ``miss == 0`` (certainly detected) has no gated measurement,
        or the cluster as a whole has no feasible joint event.
    """
    if isinstance(L, (list, tuple)) and len(L) == 0:
        L = np.zeros((0, 0))
    L = as_weights(L, "L")
    miss = _as_real_array(miss, "miss")
    if miss.ndim != 1:
        raise ValueError(f"miss must be 1-D (one entry per track), got {miss.ndim} dimension(s)")
    if miss.shape[0] != L.shape[0]:
        raise ValueError(
            f"miss has {miss.shape[0]} entries but L has {L.shape[0]} rows (tracks); "
            "they must match"
        )
    if not np.all(np.isfinite(miss)):
        i = int(np.argwhere(~np.isfinite(miss))[0, 0])
        raise ValueError(f"miss[{i}] is not finite ({miss[i]})")
    if np.any((miss < 0) | (miss > 1)):
        i = int(np.argwhere((miss < 0) | (miss > 1))[0, 0])
        raise ValueError(
            f"miss[{i}] = {miss[i]} is outside [0, 1]; miss is the probability-like weight "
            "1 − P_D·P_G of a track detecting nothing"
        )
    dead = (miss == 0) & ~np.any(L > 0, axis=1)
    if np.any(dead):
        i = int(np.argwhere(dead)[0, 0])
        raise InfeasibleAssignmentError(
            f"track {i} has miss = 0 (certainly detected) but no gated measurement: "
            "no feasible joint association event exists"
        )
    return np.ascontiguousarray(L), np.ascontiguousarray(miss)


def check_integer(value, name: str, minimum: int = 1) -> int:
    """``value`` as an int; ValueError unless it is a whole number ≥ ``minimum``."""
    return as_int(value, name, minimum)


def check_indices(value, name: str) -> np.ndarray:
    """``value`` as an int64 index array; ValueError unless its entries are integers.

    Floats (``0.5`` would be truncated to 0), booleans (a mask, not indices),
    complex numbers and strings are refused; range checks are the caller's.
    """
    if isinstance(value, (str, bytes)):
        raise ValueError(f"{name} must be integer indices, got a string")
    try:
        a = np.asarray(value)
    except (TypeError, ValueError, OverflowError) as exc:
        raise ValueError(f"{name} must be integer indices: {exc}") from None
    if a.size == 0:
        return a.astype(np.int64)
    if a.dtype.kind == "O":  # e.g. Python ints beyond int64
        raise ValueError(f"{name} must be integer indices that fit in int64")
    if a.dtype.kind not in "iu":
        raise ValueError(f"{name} must be integer indices, got dtype {a.dtype}")
    if a.dtype.kind == "u" and a.size and a.max() > np.iinfo(np.int64).max:
        raise ValueError(f"{name} has an index too large for int64")
    return a.astype(np.int64, copy=False)


def require_feasible_event(L, miss) -> None:
    """Raise :class:`InfeasibleAssignmentError` if no joint event has positive weight."""
    if not has_feasible_event(L, miss):
        raise InfeasibleAssignmentError(NO_FEASIBLE_EVENT)
