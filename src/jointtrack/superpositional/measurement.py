r"""Measurement functions g of a superpositional sensor, y = Σ_{x ∈ Ξ} g(x) (1).

S. Nannuru and M. Coates, "Gaussian approximation for superpositional sensors",
technical report, McGill University, 2015. Equation numbers in this package refer
to that report.

A measurement maps single-target states ``(..., dx)`` to contributions
``(..., dy)``; the sensor reads the sum of the contributions of every target plus
Gaussian noise. :class:`LinearMeasurement` is g(x) = Hx (10), for which the
Campbell moments and the exact likelihood have closed forms;
:class:`FunctionMeasurement` wraps any vectorised callable.
"""

from __future__ import annotations

import numpy as np

from jointtrack.assignment._checks import _as_real_array, as_int

__all__ = ["FunctionMeasurement", "LinearMeasurement", "as_measurement"]


class LinearMeasurement:
    r"""The linear measurement function g(x) = Hx of (10).

    Parameters
    ----------
    H : array_like, shape (dy, dx)
        Real, finite measurement matrix.

    Examples
    --------
    >>> import numpy as np
    >>> g = LinearMeasurement([[1.0, 0.0], [1.0, 1.0]])
    >>> g(np.array([2.0, 3.0])).tolist()
    [2.0, 5.0]
    """

    __slots__ = ("H", "dx", "dy")

    def __init__(self, H):
        arr = _as_real_array(H, "H")
        if arr.ndim != 2 or arr.shape[0] < 1 or arr.shape[1] < 1:
            raise ValueError(f"H must be a non-empty 2-D (dy, dx) matrix, got shape {arr.shape}")
        if not np.isfinite(arr).all():
            raise ValueError("H has a non-finite entry (NaN or inf)")
        arr = np.array(arr, dtype=np.float64, copy=True)
        arr.flags.writeable = False
        object.__setattr__(self, "H", arr)
        object.__setattr__(self, "dy", int(arr.shape[0]))
        object.__setattr__(self, "dx", int(arr.shape[1]))

    def __setattr__(self, name, value):
        raise AttributeError("LinearMeasurement is immutable")

    def __call__(self, x) -> np.ndarray:
        x = np.asarray(x, dtype=np.float64)
        if x.shape[-1:] != (self.dx,):
            raise ValueError(f"x must have last dimension dx = {self.dx}, got shape {x.shape}")
        return x @ self.H.T

    def __repr__(self) -> str:
        return f"LinearMeasurement(H={self.H.tolist()!r})"


class FunctionMeasurement:
    r"""A general measurement function g given as a vectorised callable.

    Parameters
    ----------
    g : callable
        Maps an array of states ``(..., dx)`` to ``(..., dy)``.
    dy : int
        Dimension of one measurement vector.
    dx : int, optional
        State dimension; when given, inputs are checked against it.

    Notes
    -----
    Every call checks that g returned real, finite values of the announced
    shape, so a wrong g fails here with a clear message instead of deep inside a
    moment computation.

    Examples
    --------
    >>> import numpy as np
    >>> g = FunctionMeasurement(lambda x: 1.0 / (1.0 + (x**2).sum(-1, keepdims=True)), dy=1)
    >>> g(np.zeros((2, 2))).ravel().tolist()
    [1.0, 1.0]
    """

    __slots__ = ("_g", "dx", "dy")

    def __init__(self, g, dy, dx=None):
        if not callable(g):
            raise ValueError(f"g must be callable, got {type(g).__name__}")
        object.__setattr__(self, "_g", g)
        object.__setattr__(self, "dy", as_int(dy, "dy", minimum=1))
        object.__setattr__(self, "dx", None if dx is None else as_int(dx, "dx", minimum=1))

    def __setattr__(self, name, value):
        raise AttributeError("FunctionMeasurement is immutable")

    def __call__(self, x) -> np.ndarray:
        x = np.asarray(x, dtype=np.float64)
        if self.dx is not None and x.shape[-1:] != (self.dx,):
            raise ValueError(f"x must have last dimension dx = {self.dx}, got shape {x.shape}")
        out = _as_real_array(self._g(x), "g(x)")
        if out.shape != x.shape[:-1] + (self.dy,):
            raise ValueError(
                f"g(x) must have shape {x.shape[:-1] + (self.dy,)} for x of shape {x.shape}, "
                f"got {out.shape}"
            )
        if not np.isfinite(out).all():
            raise ValueError("g(x) returned a non-finite value (NaN or inf)")
        return out

    def __repr__(self) -> str:
        return f"FunctionMeasurement({self._g!r}, dy={self.dy}, dx={self.dx})"


def as_measurement(H_or_g, dx: int | None = None):
    """A measurement object from an (dy, dx) matrix or a measurement object.

    Parameters
    ----------
    H_or_g : array_like or LinearMeasurement or FunctionMeasurement
        The measurement matrix H of g(x) = Hx, or a measurement object.
    dx : int, optional
        The state dimension of the model the measurement is used with; checked
        when given.

    Returns
    -------
    LinearMeasurement or FunctionMeasurement

    Examples
    --------
    >>> as_measurement([[0.1, 0.7], [0.5, 0.5]]).dy
    2
    """
    if isinstance(H_or_g, LinearMeasurement | FunctionMeasurement):
        m = H_or_g
    elif callable(H_or_g):
        raise ValueError(
            "H must be an (dy, dx) array or a measurement object; wrap a callable g as "
            "FunctionMeasurement(g, dy)"
        )
    else:
        m = LinearMeasurement(H_or_g)
    if dx is not None and m.dx is not None and m.dx != dx:
        raise ValueError(
            f"H has {m.dx} columns but the model's states have dimension dx = {dx} "
            "(dimension mismatch)"
        )
    return m
