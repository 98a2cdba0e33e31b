"""Argument checks shared by every public function of the package.

One place decides what counts as a weight matrix, a vector of null weights, a
group-size vector, a whole number or a probability, so that every face of the
assignment-sum core (permanents, JPDA, particle weights, identities) rejects bad
input with the same clear message naming the argument. Rejected everywhere:
complex numbers (their imaginary part would otherwise be dropped silently),
booleans used as numbers, Python integers too large for a float, strings and
ragged nested sequences, NaN and infinities, and masked arrays (``numpy.ma``: a
TypeError, since ``np.asarray`` would drop the mask and use the hidden values).
"""

from __future__ import annotations

import math
import numbers

import numpy as np

__all__ = [
    "as_counts",
    "as_log_weights",
    "as_float",
    "as_int",
    "as_null_weights",
    "as_rng",
    "as_weights",
]

#: Largest group size accepted (a group count is a number of tracks or identities).
MAX_COUNT = 2**31 - 1
_MAX_INT = 2**63 - 1


def _as_real_array(value, name: str) -> np.ndarray:
    """``value`` as a float64 array; ValueError naming ``name`` for anything not real."""
    if type(value) is np.ndarray and value.dtype == np.float64:
        return value  # the hot path: the tracker passes float64 arrays
    if isinstance(value, (str, bytes)):
        raise ValueError(f"{name} must be an array of real numbers, got a string")
    _refuse_masked(value, name)
    try:
        raw = np.asarray(value)
    except (TypeError, ValueError, OverflowError) as exc:
        raise ValueError(f"{name} must be an array of real numbers: {exc}") from None
    kind = raw.dtype.kind
    if kind in "iuf" and _holds_bool(value):
        raise ValueError(f"{name} holds a boolean; pass numbers")
    if kind == "c":
        raise ValueError(
            f"{name} has complex entries; it must be real (the imaginary part "
            "would otherwise be dropped)"
        )
    if kind == "b":
        raise ValueError(f"{name} is boolean; pass numeric weights (e.g. {name}.astype(float))")
    if kind in "USV":  # numpy would parse "1.0" silently
        raise ValueError(f"{name} holds strings (dtype {raw.dtype}); pass real numbers")
    if kind in "OUSV":
        # object arrays: huge Python ints, mixed types, ragged lists
        flat = raw.ravel() if raw.dtype.kind == "O" else ()
        for x in flat:
            if isinstance(x, bool | np.bool_):
                raise ValueError(f"{name} holds a boolean; pass numbers")
            if isinstance(x, complex | np.complexfloating):
                raise ValueError(f"{name} holds a complex number ({x}); it must be real")
            if isinstance(x, numbers.Integral) and abs(int(x)) > 2**1023:
                raise ValueError(
                    f"{name} holds an integer too large for a float64 "
                    f"({len(str(abs(int(x))))} digits)"
                )
        try:
            return np.asarray(raw, dtype=np.float64)
        except (TypeError, ValueError, OverflowError) as exc:
            raise ValueError(f"{name} must be an array of real numbers: {exc}") from None
    if kind not in "iuf":
        raise ValueError(f"{name} must be an array of real numbers, got dtype {raw.dtype}")
    return np.asarray(raw, dtype=np.float64)


def _refuse_masked(value, name: str) -> None:
    """TypeError for a masked array (or a sequence holding masked entries)."""
    if _holds(value, np.ma.MaskedArray):
        raise TypeError(
            f"{name} is a masked array (numpy.ma); its mask would be dropped silently: "
            f"pass a plain array (e.g. {name}.filled(0.0) or {name}.compressed())"
        )


def _holds(value, cls) -> bool:
    """``value`` is a ``cls``, or a nested list/tuple holding one."""
    if isinstance(value, cls):
        return True
    if isinstance(value, list | tuple):
        return any(_holds(v, cls) for v in value)
    return False


def _holds_bool(value) -> bool:
    """A nested list/tuple with a bool among numbers (numpy would coerce it silently)."""
    if isinstance(value, np.ndarray):
        return False
    if isinstance(value, bool | np.bool_):
        return True
    if isinstance(value, list | tuple):
        return any(_holds_bool(v) for v in value)
    return False


def _first_bad(mask: np.ndarray) -> tuple:
    return tuple(int(i) for i in np.argwhere(mask)[0])


def as_weights(A, name: str = "A") -> np.ndarray:
    """A non-negative, finite, 2-D float64 weight matrix (C-contiguous)."""
    arr = _as_real_array(A, name)
    if arr.ndim != 2:
        raise ValueError(f"{name} must be 2-D, got an array with {arr.ndim} dimension(s)")
    # one pass in the common case: NaN fails ≥ 0, so this accepts only finite ≥ 0 … or +inf
    if not ((arr >= 0.0).all() and np.isfinite(arr).all()):
        finite = np.isfinite(arr)
        if not finite.all():
            bad = _first_bad(~finite)
            raise ValueError(f"{name} has a non-finite entry ({arr[bad]}) at {bad}")
        bad = _first_bad(arr < 0)
        raise ValueError(f"{name} has a negative entry ({arr[bad]}) at {bad}; weights are ≥ 0")
    return np.ascontiguousarray(arr)


def as_log_weights(L, name: str = "log_W", ndim: int = 2) -> np.ndarray:
    """Logarithms of non-negative weights: real, finite or −inf (log 0); no NaN, no +inf."""
    arr = _as_real_array(L, name)
    if arr.ndim != ndim:
        raise ValueError(f"{name} must be {ndim}-D, got an array with {arr.ndim} dimension(s)")
    bad = np.isnan(arr) | (arr == np.inf)
    if bad.any():
        i = _first_bad(bad)
        raise ValueError(
            f"{name} has an entry {arr[i]} at {i}; a log weight is a real number or -inf (weight 0)"
        )
    return np.ascontiguousarray(arr)


def as_null_weights(null, n: int, name: str = "null") -> np.ndarray:
    """Per-row null weights: None (all 0), a scalar, or a length-``n`` vector, finite ≥ 0."""
    if null is None:
        return np.zeros(n)
    arr = _as_real_array(null, name)
    if arr.ndim == 0:
        arr = np.full(n, float(arr))
    if arr.ndim != 1 or arr.shape[0] != n:
        raise ValueError(f"{name} must have one entry per row ({n}), got shape {arr.shape}")
    finite = np.isfinite(arr)
    if not finite.all():
        i = _first_bad(~finite)[0]
        raise ValueError(f"{name}[{i}] is not finite ({arr[i]})")
    if (arr < 0).any():
        i = _first_bad(arr < 0)[0]
        raise ValueError(f"{name}[{i}] = {arr[i]} is negative; weights are ≥ 0")
    return np.ascontiguousarray(arr)


def as_counts(counts, length: int, name: str) -> np.ndarray:
    """Group sizes: None (all 1) or ``length`` whole numbers in [1, 2^31)."""
    if counts is None:
        return np.ones(length, np.int64)
    if isinstance(counts, (str, bytes)):
        raise ValueError(f"{name} must be a 1-D array of positive integers, got a string")
    _refuse_masked(counts, name)
    try:
        raw = np.asarray(counts)
    except (TypeError, ValueError, OverflowError) as exc:
        raise ValueError(f"{name} must be a 1-D array of positive integers: {exc}") from None
    if raw.ndim != 1 or raw.shape[0] != length:
        raise ValueError(
            f"{name} must have one entry per group of the compressed matrix ({length}), "
            f"got shape {raw.shape}"
        )
    if raw.dtype.kind == "b" or _holds_bool(counts if not isinstance(counts, np.ndarray) else []):
        raise ValueError(f"{name} holds booleans; group sizes are positive integers")
    if raw.dtype.kind == "c":
        raise ValueError(f"{name} holds complex numbers; group sizes are positive integers")
    values = []
    for i, x in enumerate(raw.tolist()):
        if isinstance(x, float) and not (math.isfinite(x) and x == int(x)):
            raise ValueError(f"{name}[{i}] = {x} is not a whole number (group sizes are integers)")
        if not isinstance(x, numbers.Real):
            raise ValueError(f"{name}[{i}] = {x!r} is not a number")
        x = int(x)
        if x < 1:
            raise ValueError(f"{name}[{i}] = {x}: must be ≥ 1 (a group has at least one member)")
        if x > MAX_COUNT:
            raise ValueError(f"{name}[{i}] = {x} is too large for a group size (max {MAX_COUNT})")
        values.append(x)
    return np.asarray(values, np.int64).reshape(length)


def as_int(value, name: str, minimum: int | None = None, maximum: int | None = None) -> int:
    """A whole number (Python or numpy int, or an integral float) within the bounds.

    Without an explicit ``maximum``, at most 2^63 − 1 (what numpy can index or
    allocate with): a 10**400 is refused here, not deep inside numpy.
    """
    _refuse_masked(value, name)
    if isinstance(value, bool | np.bool_) or value is None:
        raise ValueError(f"{name} must be an integer, got {value!r}")
    if isinstance(value, numbers.Integral):
        out = int(value)
    elif isinstance(value, numbers.Real) and math.isfinite(value) and float(value).is_integer():
        out = int(value)
    else:
        raise ValueError(f"{name} must be a whole number, got {value!r}")
    if minimum is not None and out < minimum:
        raise ValueError(f"{name} must be ≥ {minimum}, got {out}")
    if maximum is not None and out > maximum:
        raise ValueError(f"{name} must be ≤ {maximum}, got {out}")
    if maximum is None and out > _MAX_INT:
        raise ValueError(f"{name} is too large ({len(str(out))} digits; at most 2^63 - 1)")
    return out


def as_float(
    value,
    name: str,
    *,
    minimum: float | None = None,
    maximum: float | None = None,
    open_min: bool = False,
    open_max: bool = False,
) -> float:
    """A finite real number within the bounds (open or closed at each end).

    A 0-d real array (what numpy reductions and indexing return) counts as a number.
    """
    _refuse_masked(value, name)
    if isinstance(value, np.ndarray) and value.ndim == 0 and value.dtype.kind in "iuf":
        value = value[()]
    if isinstance(value, bool | np.bool_) or not isinstance(value, numbers.Real):
        raise ValueError(f"{name} must be a real number, got {value!r}")
    try:
        out = float(value)
    except OverflowError:  # a Python int beyond the float range
        raise ValueError(
            f"{name} is an integer too large for a float64 ({len(str(abs(int(value))))} digits)"
        ) from None
    if not math.isfinite(out):
        raise ValueError(f"{name} must be finite, got {out}")
    if minimum is not None and (out < minimum or (open_min and out == minimum)):
        raise ValueError(f"{name} must be {'>' if open_min else '≥'} {minimum}, got {out}")
    if maximum is not None and (out > maximum or (open_max and out == maximum)):
        raise ValueError(f"{name} must be {'<' if open_max else '≤'} {maximum}, got {out}")
    return out


def as_rng(rng, name: str = "rng") -> np.random.Generator:
    """A numpy Generator from None, a non-negative integer seed, a SeedSequence or a Generator."""
    if isinstance(rng, np.random.Generator):
        return rng
    if rng is None or isinstance(rng, np.random.SeedSequence):
        return np.random.default_rng(rng)
    if isinstance(rng, numbers.Integral) and not isinstance(rng, bool | np.bool_):
        if int(rng) < 0:
            raise ValueError(f"{name} seed must be ≥ 0, got {rng}")
        return np.random.default_rng(int(rng))
    raise ValueError(
        f"{name} must be None, a non-negative integer seed or a numpy.random.Generator, "
        f"got {type(rng).__name__}"
    )
