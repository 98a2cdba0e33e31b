"""Measurement models: linear position and a 2-D range–bearing sensor.

Every model exposes the same small interface, which is all the filters in
:mod:`jointtrack.filters` use (so a linear model can go through the EKF code
path and give exactly the Kalman result):

``h(x)``
    predicted measurement, batched: ``(..., n) → (..., m)``.
``jacobian(x)``
    ∂h/∂x at ``x``: ``(..., n) → (..., m, n)``.
``residual(z, z_pred)``
    the innovation ``z − z_pred`` with angular components wrapped to (−π, π].
``R``
    measurement noise covariance ``(m, m)`` (read-only, symmetric positive definite).
``measurement_dim``, ``state_dim``
    m and n.

States use the blocked layout of :mod:`jointtrack.models.motion`: positions
first, ``x[..., :dim]``.

``R`` may be given as a scalar variance σ² (→ σ² I), a vector of variances
(→ diagonal) or a full matrix; it is checked (finite, symmetric, positive
definite) and stored read-only.
"""

from __future__ import annotations

import numbers
from dataclasses import dataclass

import numpy as np

__all__ = ["LinearPosition", "LinearPositionVelocity", "RangeBearing", "wrap_angle"]


def wrap_angle(a):
    """Wrap angles to the half-open interval (−π, π].

    ``wrap(a) = π − ((π − a) mod 2π)``, with the rounding case ``−π`` mapped to
    ``π``. Used for bearing innovations so that a target just across the ±π cut
    gives a small residual (Bar-Shalom, Willett & Tian 2011, polar measurements).
    """
    a = np.asarray(a, dtype=np.float64)
    w = np.pi - np.mod(np.pi - a, 2.0 * np.pi)
    w = np.where(w <= -np.pi, w + 2.0 * np.pi, w)
    return w if w.ndim else float(w)


def _as_cov(R, m: int, name: str = "R") -> np.ndarray:
    try:
        R = np.array(R, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a numeric array, got {R!r}") from None
    if R.ndim == 0:
        R = float(R) * np.eye(m)
    elif R.ndim == 1:
        if R.shape != (m,):
            raise ValueError(f"{name} given as variances must have shape ({m},), got {R.shape}")
        R = np.diag(R)
    if R.shape != (m, m):
        raise ValueError(f"{name} must have shape ({m}, {m}), got {R.shape}")
    if not np.isfinite(R).all():
        raise ValueError(f"{name} has non-finite entries")
    scale = np.abs(R).max()
    if np.abs(R - R.T).max() > 1e-9 * scale:
        raise ValueError(f"{name} is not symmetric (max |R − Rᵀ| = {np.abs(R - R.T).max():.3g})")
    R = 0.5 * (R + R.T)
    try:
        L = np.linalg.cholesky(R)
    except np.linalg.LinAlgError:
        raise ValueError(f"{name} is not positive definite") from None
    diag = np.diag(L)
    if not (diag.min() / diag.max()) ** 2 > m * np.finfo(np.float64).eps:
        raise ValueError(f"{name} is numerically singular")
    R.setflags(write=False)
    return R


def _check_state_dim(n, minimum: int) -> int:
    try:
        ok = not isinstance(n, bool) and int(n) == n and n >= minimum
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise ValueError(f"state_dim must be an integer ≥ {minimum}, got {n!r}")
    return int(n)


def _check_x(x, n: int) -> np.ndarray:
    x = np.asarray(x, dtype=np.float64)
    if x.ndim == 0 or x.shape[-1] != n:
        raise ValueError(f"state must have last dimension {n} (state_dim), got shape {x.shape}")
    return x


def _eq_fields(a, b, names) -> bool:
    if type(a) is not type(b):
        return NotImplemented
    return all(np.array_equal(getattr(a, k), getattr(b, k)) for k in names)


@dataclass(frozen=True, eq=False)
class LinearPosition:
    """Linear position measurement ``z = H x + v``, ``v ~ N(0, R)``.

    ``H = [I_dim 0]`` picks the position block of the state (Bar-Shalom, Willett
    & Tian 2011; positions first in every jointtrack state).

    Parameters
    ----------
    dim : int
        measured spatial dimension m (1, 2 or 3).
    R : float, (dim,) or (dim, dim) array
        measurement noise: scalar variance, per-axis variances, or full covariance.
    state_dim : int, optional
        length n of the state; default ``2·dim`` (nearly-constant velocity). Use
        ``motion.state_dim`` for other motion models.
    """

    dim: int
    R: np.ndarray
    state_dim: int | None = None

    def __post_init__(self):
        try:
            ok = not isinstance(self.dim, bool) and int(self.dim) == self.dim and self.dim >= 1
        except (TypeError, ValueError):
            ok = False
        if not ok:
            raise ValueError(f"dim must be a positive integer, got {self.dim!r}")
        dim = int(self.dim)
        object.__setattr__(self, "dim", dim)
        n = 2 * dim if self.state_dim is None else self.state_dim
        object.__setattr__(self, "state_dim", _check_state_dim(n, dim))
        object.__setattr__(self, "R", _as_cov(self.R, dim))

    def __eq__(self, other):
        return _eq_fields(self, other, ("dim", "R", "state_dim"))

    __hash__ = None

    @property
    def measurement_dim(self) -> int:
        """m = ``dim``."""
        return self.dim

    @property
    def H(self) -> np.ndarray:
        """Measurement matrix ``[I_dim 0]`` of shape (dim, state_dim)."""
        return np.eye(self.dim, self.state_dim)

    def h(self, x) -> np.ndarray:
        """``H x`` = the position block ``x[..., :dim]``."""
        x = _check_x(x, self.state_dim)
        return x[..., : self.dim].copy()

    def jacobian(self, x) -> np.ndarray:
        """``H`` broadcast to ``x.shape[:-1] + (dim, state_dim)`` (constant)."""
        x = _check_x(x, self.state_dim)
        return np.broadcast_to(self.H, x.shape[:-1] + (self.dim, self.state_dim)).copy()

    def residual(self, z, z_pred) -> np.ndarray:
        """Innovation ``z − z_pred`` (no angular components)."""
        return np.asarray(z, dtype=np.float64) - np.asarray(z_pred, dtype=np.float64)

    def position_and_covariance(self, z) -> tuple[np.ndarray, np.ndarray]:
        """Positions (k, dim) of measurements ``z`` (k, dim) and their covariances R."""
        z = np.asarray(z, dtype=np.float64).reshape(-1, self.dim)
        return z.copy(), np.broadcast_to(self.R, (len(z), self.dim, self.dim)).copy()


class LinearPositionVelocity:
    """Linear position-and-velocity measurement ``z = [p, v] = H x + w``.

    For targets that report their own velocity (AIS speed and course, ADS-B
    ground speed and track): ``H = [I_2d 0]`` picks the position and velocity
    blocks (positions first, then velocities, in every jointtrack state) and
    ``R = diag(R_position, velocity_variance·I)``. ``position_and_covariance``
    gives the position part, for track initiation.

    Parameters
    ----------
    position : :class:`LinearPosition` — the position part (its ``dim``, ``R``
        and ``state_dim``).
    velocity_variance : σ_v² of each reported velocity component, (m/s)², > 0.
    """

    def __init__(self, position: LinearPosition, velocity_variance: float):
        if not isinstance(position, LinearPosition):
            raise TypeError(f"position must be a LinearPosition, got {type(position).__name__}")
        ok = isinstance(velocity_variance, numbers.Real) and not isinstance(velocity_variance, bool)
        var = float(velocity_variance) if ok else -1.0
        if not (np.isfinite(var) and var > 0):
            raise ValueError(
                f"velocity_variance must be positive and finite, got {velocity_variance!r}"
            )
        d, n = position.dim, position.state_dim
        self.dim, self.state_dim = d, n
        self.R = np.zeros((2 * d, 2 * d))
        self.R[:d, :d] = position.R
        self.R[d:, d:] = var * np.eye(d)
        self.H = np.eye(2 * d, n)
        self._position = position

    @property
    def measurement_dim(self) -> int:
        """m = 2·``dim``."""
        return 2 * self.dim

    def residual(self, z, z_pred) -> np.ndarray:
        """Innovation ``z − z_pred``."""
        return np.asarray(z, dtype=np.float64) - np.asarray(z_pred, dtype=np.float64)

    def position_and_covariance(self, z) -> tuple[np.ndarray, np.ndarray]:
        """Positions (k, dim) of measurements ``z`` (k, 2·dim) and their covariances."""
        z = np.asarray(z, dtype=np.float64).reshape(-1, 2 * self.dim)
        return self._position.position_and_covariance(z[:, : self.dim])


@dataclass(frozen=True, eq=False)
class RangeBearing:
    """2-D range–bearing sensor at ``sensor_position`` (for the EKF).

    With ``(Δx, Δy) = (x[0] − s_x, x[1] − s_y)`` the target's offset from the
    sensor (the first two position components of the state)::

        h(x) = [ r, θ ] = [ √(Δx² + Δy²),  atan2(Δy, Δx) ]

        H(x) = ∂h/∂x = [[  Δx/r,   Δy/r, 0 … ],
                        [ −Δy/r²,  Δx/r², 0 … ]]

    (Bar-Shalom, Willett & Tian 2011, polar measurements and the EKF;
    Bar-Shalom & Li 1995). The bearing is measured anticlockwise from the +x axis, in (−π, π];
    bearing residuals are wrapped to (−π, π] by :meth:`residual`.

    Parameters
    ----------
    R : (2,) or (2, 2) array
        noise covariance of ``[r, θ]`` (m², rad²): variances or full matrix.
    sensor_position : (2,) array
        sensor location (x, y).
    state_dim : int
        length of the state (default 4: 2-D nearly-constant velocity).
    """

    R: np.ndarray
    sensor_position: np.ndarray = (0.0, 0.0)
    state_dim: int = 4

    #: index of the angular component of z
    angle_indices = (1,)

    def __post_init__(self):
        object.__setattr__(self, "R", _as_cov(self.R, 2))
        try:
            s = np.array(self.sensor_position, dtype=np.float64)
        except (TypeError, ValueError):
            raise ValueError(
                f"sensor_position must be 2 numbers, got {self.sensor_position!r}"
            ) from None
        if s.shape != (2,) or not np.isfinite(s).all():
            raise ValueError(f"sensor_position must be 2 finite numbers, got {s!r}")
        s.setflags(write=False)
        object.__setattr__(self, "sensor_position", s)
        object.__setattr__(self, "state_dim", _check_state_dim(self.state_dim, 2))

    def __eq__(self, other):
        return _eq_fields(self, other, ("R", "sensor_position", "state_dim"))

    __hash__ = None

    @property
    def measurement_dim(self) -> int:
        """m = 2 (range, bearing)."""
        return 2

    def h(self, x) -> np.ndarray:
        """``[r, θ]`` of each state, ``(..., n) → (..., 2)``."""
        x = _check_x(x, self.state_dim)
        dx = x[..., 0] - self.sensor_position[0]
        dy = x[..., 1] - self.sensor_position[1]
        return np.stack([np.hypot(dx, dy), np.arctan2(dy, dx)], axis=-1)

    def jacobian(self, x) -> np.ndarray:
        """∂h/∂x, ``(..., n) → (..., 2, n)``.

        Raises ValueError if a state sits on the sensor (r = 0), where the bearing
        is not differentiable.
        """
        x = _check_x(x, self.state_dim)
        dx = x[..., 0] - self.sensor_position[0]
        dy = x[..., 1] - self.sensor_position[1]
        r2 = dx * dx + dy * dy
        if np.any(~(r2 > 0)):
            bad = np.argwhere(np.atleast_1d(~(r2 > 0)))[0]
            where = f" (track {int(bad[0])})" if x.ndim > 1 else ""
            raise ValueError(
                f"state{where} is at the sensor position (range 0) or not finite: "
                "the range–bearing Jacobian is undefined"
            )
        r = np.sqrt(r2)
        J = np.zeros(x.shape[:-1] + (2, self.state_dim))
        J[..., 0, 0] = dx / r
        J[..., 0, 1] = dy / r
        J[..., 1, 0] = -dy / r2
        J[..., 1, 1] = dx / r2
        return J

    def H(self, x) -> np.ndarray:
        """Alias of :meth:`jacobian`."""
        return self.jacobian(x)

    def residual(self, z, z_pred) -> np.ndarray:
        """``z − z_pred`` with the bearing difference wrapped to (−π, π]."""
        d = np.asarray(z, dtype=np.float64) - np.asarray(z_pred, dtype=np.float64)
        d = np.array(d, copy=True)
        d[..., 1] = wrap_angle(d[..., 1])
        return d

    def to_position(self, z) -> np.ndarray:
        """Cartesian position ``s + r [cos θ, sin θ]`` of measurements ``(..., 2)``
        (the inverse of ``h`` on the position; e.g. for track initiation)."""
        z = np.asarray(z, dtype=np.float64)
        if z.ndim == 0 or z.shape[-1] != 2:
            raise ValueError(f"z must have last dimension 2 (range, bearing), got {z.shape}")
        r, th = z[..., 0], z[..., 1]
        return self.sensor_position + np.stack([r * np.cos(th), r * np.sin(th)], axis=-1)

    def position_and_covariance(self, z) -> tuple[np.ndarray, np.ndarray]:
        """Cartesian positions (k, 2) of ``z`` (k, 2) and their covariances J R Jᵀ.

        J = ∂(x, y)/∂(r, θ) = [[cos θ, −r sin θ], [sin θ, r cos θ]] (first-order
        conversion, e.g. for track initiation).
        """
        z = np.asarray(z, dtype=np.float64).reshape(-1, 2)
        r, th = z[:, 0], z[:, 1]
        J = np.empty((len(z), 2, 2))
        J[:, 0, 0], J[:, 0, 1] = np.cos(th), -r * np.sin(th)
        J[:, 1, 0], J[:, 1, 1] = np.sin(th), r * np.cos(th)
        return self.to_position(z), J @ self.R @ J.transpose(0, 2, 1)
