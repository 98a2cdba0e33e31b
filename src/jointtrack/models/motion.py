"""Kinematic motion models: nearly-constant velocity, constant acceleration, coordinated turn.

State layout (the same in every jointtrack model, filter and tracker)
--------------------------------------------------------------------
Blocked by derivative order, positions first::

    nearly-constant velocity, 2-D:   [x, y, vx, vy]
    nearly-constant velocity, 3-D:   [x, y, z, vx, vy, vz]
    constant acceleration,   2-D:   [x, y, vx, vy, ax, ay]
    constant acceleration,   3-D:   [x, y, z, vx, vy, vz, ax, ay, az]

so the position is always ``x[..., :dim]`` (``position_indices``) whatever the
model order, and a position measurement is ``H = [I 0]``. Every matrix below is
the one-axis matrix Kronecker-multiplied by ``I_dim`` (axes independent).

Noise: continuous time
----------------------
Both models are the *continuous-time* white-noise kinematic models of
Bar-Shalom, Li & Kirubarajan, *Estimation with Applications to Tracking and
Navigation* (2001), §6.2 (also Bar-Shalom, Willett & Tian, *Tracking and Data
Fusion*, 2011): with ``ẋ = A x + G w(t)``, ``w`` zero-mean white noise of
power spectral density ``q`` (per axis),

    F(Δt) = e^{A Δt},      Q(Δt) = q ∫₀^{Δt} e^{Aτ} G Gᵀ e^{Aᵀτ} dτ.

* **Nearly-constant velocity** (continuous white-noise acceleration, CWNA,
  §6.2.2): ``w`` is the acceleration, ``q`` in m²/s³.
* **Constant acceleration** (continuous Wiener-process acceleration, §6.2.3):
  ``w`` is the jerk, ``q`` in m²/s⁵.

Being exact discretisations, both satisfy the semigroup identities
``F(a+b) = F(b)F(a)`` and ``Q(a+b) = F(b) Q(a) F(b)ᵀ + Q(b)``, so a scan interval
may vary from scan to scan without changing the model. A time step must be
finite, positive and at most the model's ``max_dt`` (the largest Δt for which F and
Q are finite: ``q Δt³/3`` overflows first for CV, ``q Δt⁵/20`` or ``Δt²/2`` for CA;
a larger one raises ``ValueError`` naming dt and the limit); the functions accept a
scalar ``dt`` (one ``(n, n)`` matrix) or a 1-D array of ``N`` steps (an
``(N, n, n)`` stack, e.g. one per track).

Coordinated turn
----------------
:class:`CoordinatedTurn` is the nearly-coordinated-turn model with the turn rate
estimated (Bar-Shalom, Li & Kirubarajan 2001, §11.7.1-§11.7.2), state
``[x, y, vx, vy, ω]`` (2-D, positions first as above, the turn rate ω in rad/s
last). It is nonlinear in ω: :meth:`CoordinatedTurn.propagate` is the exact
motion ``f(x, Δt)`` of a constant-speed turn at rate ω and
:meth:`CoordinatedTurn.jacobian` its Jacobian ``∂f/∂x`` (extended Kalman
prediction). Every coefficient is written so that ω → 0 needs no division by
ω: ``sin(ωΔt)/ω = Δt·sinc(ωΔt)``, ``(1 − cos ωΔt)/ω = Δt·(θ/2)·sinc²(θ/2)``
(θ = ωΔt) and their ω-derivatives by their Taylor series for |θ| ≤ 1, so at
ω = 0 the model is exactly the nearly-constant-velocity one.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

__all__ = [
    "ConstantAcceleration",
    "ConstantVelocity",
    "CoordinatedTurn",
    "Stationary",
    "ca_noise",
    "ca_transition",
    "cv_noise",
    "cv_transition",
]


def _check_dim(dim) -> int:
    try:
        ok = not isinstance(dim, bool) and int(dim) == dim and 1 <= dim <= 3
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise ValueError(f"spatial dimension must be 1, 2 or 3, got {dim!r}")
    return int(dim)


def _check_dt(dt) -> np.ndarray:
    try:
        dt = np.asarray(dt, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"time step dt must be a number or 1-D array, got {dt!r}") from None
    if dt.ndim > 1:
        raise ValueError(f"time step dt must be a scalar or 1-D array, got shape {dt.shape}")
    bad = ~(np.isfinite(dt) & (dt > 0))
    if bad.any():
        if dt.ndim == 0:
            raise ValueError(f"time step dt must be finite and > 0, got {float(dt)}")
        i = int(np.argmax(bad))
        raise ValueError(f"time step dt[{i}] (track {i}) must be finite and > 0, got {dt[i]}")
    return dt


def _check_q(q) -> float:
    try:
        q = float(q)
    except (TypeError, ValueError):
        raise ValueError(f"noise intensity q must be a number, got {q!r}") from None
    if not np.isfinite(q) or q < 0:
        raise ValueError(f"noise intensity q must be finite and ≥ 0, got {q}")
    return q


_FMAX = float(np.finfo(np.float64).max)


# cached: a function of (order, q) alone, and a tracker asks for it twice every scan
@functools.lru_cache(maxsize=256)
def _max_dt(order: int, q: float) -> float:
    """Largest time step for which F(Δt) and Q(Δt) of a kinematic model are finite.

    ``order`` 2 (CV) or 3 (CA). The binding entries are ``Δt`` (CV) or ``Δt²/2`` (CA)
    of F and ``q Δt³/3`` (CV) or ``q Δt⁵/20`` (CA) of Q: solved in logarithms (no
    overflow), then stepped down to the last float whose matrices are finite.
    """
    log_max = np.log(_FMAX)
    limits = [log_max] if order == 2 else [0.5 * (log_max + np.log(2.0))]
    if q > 0:
        k, c = (3, 3.0) if order == 2 else (5, 20.0)
        limits.append((log_max + np.log(c) - np.log(q)) / k)
    dt = float(np.exp(min(min(limits), log_max)))
    if not np.isfinite(dt):
        dt = _FMAX
    with np.errstate(over="ignore", invalid="ignore"):
        for _ in range(64):
            if np.isfinite(_blocks(order, np.asarray(dt), q)).all():
                break
            dt = float(dt * (1.0 - 4 * np.finfo(np.float64).eps))
    return dt


def _check_dt_range(dt: np.ndarray, order: int, q: float, what: str) -> None:
    """Raise a ValueError naming dt if F or Q overflow for this model and q."""
    dt_max = _max_dt(order, q)
    big = dt > dt_max
    if big.any():
        model = "constant-velocity" if order == 2 else "constant-acceleration"
        name = "dt" if dt.ndim == 0 else f"dt[{int(np.argmax(big))}] (track {int(np.argmax(big))})"
        val = float(dt) if dt.ndim == 0 else float(dt[int(np.argmax(big))])
        raise ValueError(
            f"time step {name} = {val:.6g} is too large: the {model} {what} overflows "
            f"(non-finite entries) beyond dt = {dt_max:.6g}, the largest usable dt for "
            f"this model{'' if what.startswith('transition') else f' with q = {q:g}'}; "
            "split the gap or re-initialise the track"
        )


def _blocks(order: int, dt: np.ndarray, q: float):
    """One-axis (F, Q) blocks, evaluated so that no intermediate overflows before the
    final entry does (products taken left to right, ``q`` first)."""
    scalar = dt.ndim == 0
    if scalar:  # one dt (a tracker's scan): the same IEEE products on Python floats
        dt = float(dt)
        one, zero = 1.0, 0.0
    else:
        one, zero = np.ones_like(dt), np.zeros_like(dt)
    if order == 2:
        F = _assemble([[one, dt], [zero, one]], scalar)
        qd = q * dt
        qd2 = qd * dt
        Q = _assemble([[qd2 * (dt / 3.0), qd2 / 2.0], [qd2 / 2.0, qd]], scalar)
        return F, Q
    half2 = dt * (0.5 * dt)
    F = _assemble([[one, dt, half2], [zero, one, dt], [zero, zero, one]], scalar)
    qd = q * dt
    qd2 = qd * dt
    qd3 = qd2 * dt
    qd4 = qd3 * dt
    Q = _assemble(
        [
            [qd4 * (dt / 20.0), qd4 / 8.0, qd3 / 6.0],
            [qd4 / 8.0, qd3 / 3.0, qd2 / 2.0],
            [qd3 / 6.0, qd2 / 2.0, qd],
        ],
        scalar,
    )
    return F, Q


def _assemble(rows: list, scalar: bool) -> np.ndarray:
    """A (k, k) block from Python floats, or an (N, k, k) stack from (N,) arrays."""
    if scalar:
        return np.array(rows, dtype=np.float64)
    return np.stack([np.stack(row, -1) for row in rows], -2)


def _kron_axes(block: np.ndarray, dim: int) -> np.ndarray:
    """``block ⊗ I_dim`` for a (k, k) or (N, k, k) one-axis block (blocked state layout)."""
    eye = np.eye(dim)
    out = block[..., :, None, :, None] * eye[:, None, :]
    k = block.shape[-1]
    return out.reshape(*block.shape[:-2], k * dim, k * dim)


def cv_transition(dt, dim: int = 2) -> np.ndarray:
    """Nearly-constant-velocity transition matrix F(Δt) = e^{AΔt}.

    Per axis ``[[1, Δt], [0, 1]]`` (Bar-Shalom, Li & Kirubarajan 2001,
    §6.2.2), in the blocked layout ``[pos(dim), vel(dim)]``::

        F = [[I, Δt I],
             [0,    I]]

    Parameters
    ----------
    dt : float or (N,) array, > 0
        time step(s).
    dim : {1, 2, 3}
        spatial dimension.

    Returns
    -------
    (2·dim, 2·dim) array, or (N, 2·dim, 2·dim) for an array ``dt``.
    """
    dim = _check_dim(dim)
    dt = _check_dt(dt)
    _check_dt_range(dt, 2, 0.0, "transition matrix F")
    return _kron_axes(_blocks(2, dt, 0.0)[0], dim)


def cv_noise(dt, q: float = 1.0, dim: int = 2) -> np.ndarray:
    """Nearly-constant-velocity process noise Q(Δt), continuous white-noise acceleration.

    Per axis (Bar-Shalom, Li & Kirubarajan 2001, §6.2.2; Bar-Shalom,
    Willett & Tian 2011)::

        Q = q [[Δt³/3, Δt²/2],
               [Δt²/2, Δt   ]]

    the exact integral q ∫₀^{Δt} e^{Aτ} G Gᵀ e^{Aᵀτ} dτ with ``G = [0, 1]ᵀ``.

    Parameters
    ----------
    dt : float or (N,) array, > 0
        time step(s).
    q : float ≥ 0
        power spectral density of the continuous acceleration noise (m²/s³), per axis.
    dim : {1, 2, 3}
        spatial dimension.

    Returns
    -------
    (2·dim, 2·dim) array, or (N, 2·dim, 2·dim) for an array ``dt``.
    """
    dim = _check_dim(dim)
    dt = _check_dt(dt)
    q = _check_q(q)
    _check_dt_range(dt, 2, q, "process noise Q")
    return _kron_axes(_blocks(2, dt, q)[1], dim)


def ca_transition(dt, dim: int = 2) -> np.ndarray:
    """Constant-acceleration transition matrix F(Δt) = e^{AΔt}.

    Per axis ``[[1, Δt, Δt²/2], [0, 1, Δt], [0, 0, 1]]`` (Bar-Shalom, Li &
    Kirubarajan 2001, §6.2.3), in the blocked layout ``[pos, vel, acc]``.

    Parameters
    ----------
    dt : float or (N,) array, > 0
        time step(s).
    dim : {1, 2, 3}
        spatial dimension.

    Returns
    -------
    (3·dim, 3·dim) array, or (N, 3·dim, 3·dim) for an array ``dt``.
    """
    dim = _check_dim(dim)
    dt = _check_dt(dt)
    _check_dt_range(dt, 3, 0.0, "transition matrix F")
    return _kron_axes(_blocks(3, dt, 0.0)[0], dim)


def ca_noise(dt, q: float = 1.0, dim: int = 2) -> np.ndarray:
    """Constant-acceleration process noise Q(Δt), continuous Wiener-process acceleration.

    Per axis (Bar-Shalom, Li & Kirubarajan 2001, §6.2.3)::

        Q = q [[Δt⁵/20, Δt⁴/8, Δt³/6],
               [Δt⁴/8,  Δt³/3, Δt²/2],
               [Δt³/6,  Δt²/2, Δt   ]]

    the exact integral q ∫₀^{Δt} e^{Aτ} G Gᵀ e^{Aᵀτ} dτ with ``G = [0, 0, 1]ᵀ``
    (white jerk of power spectral density ``q``).

    Parameters
    ----------
    dt : float or (N,) array, > 0
        time step(s).
    q : float ≥ 0
        power spectral density of the continuous jerk noise (m²/s⁵), per axis.
    dim : {1, 2, 3}
        spatial dimension.

    Returns
    -------
    (3·dim, 3·dim) array, or (N, 3·dim, 3·dim) for an array ``dt``.
    """
    dim = _check_dim(dim)
    dt = _check_dt(dt)
    q = _check_q(q)
    _check_dt_range(dt, 3, q, "process noise Q")
    return _kron_axes(_blocks(3, dt, q)[1], dim)


@dataclass(frozen=True)
class _KinematicModel:
    """Fields, checks and state indices shared by the kinematic models.

    A subclass sets ``_order``, the number of derivative blocks in its state
    (positions, velocities, …; see the module docstring), and provides
    ``transition`` and ``noise``.
    """

    dim: int = 2
    q: float = 1.0
    _order: ClassVar[int]

    def __post_init__(self):
        object.__setattr__(self, "dim", _check_dim(self.dim))
        object.__setattr__(self, "q", _check_q(self.q))

    @property
    def state_dim(self) -> int:
        """Length of the state vector, ``2·dim`` (velocity) or ``3·dim`` (acceleration)."""
        return self._order * self.dim

    @property
    def max_dt(self) -> float:
        """Largest time step for which ``transition`` and ``noise`` are finite.

        A larger ``dt`` raises ``ValueError`` (naming ``dt`` and this limit).
        """
        return _max_dt(self._order, self.q)

    @property
    def position_indices(self) -> np.ndarray:
        """Indices of the position components, ``[0, …, dim−1]``."""
        return np.arange(self.dim)

    @property
    def velocity_indices(self) -> np.ndarray:
        """Indices of the velocity components, ``[dim, …, 2·dim−1]``."""
        return np.arange(self.dim, 2 * self.dim)


@dataclass(frozen=True)
class ConstantVelocity(_KinematicModel):
    """Nearly-constant-velocity motion (continuous white-noise acceleration).

    State ``[x, y(, z), vx, vy(, vz)]`` (positions first, see module docstring).

    Parameters
    ----------
    dim : {1, 2, 3}
        spatial dimension.
    q : float ≥ 0
        power spectral density of the white acceleration noise (m²/s³), per axis.

    Examples
    --------
    >>> m = ConstantVelocity(dim=2, q=0.5)
    >>> F, Q = m.transition(1.0), m.noise(1.0)   # (4, 4) each
    """

    _order = 2

    def transition(self, dt) -> np.ndarray:
        """F(Δt), see :func:`cv_transition`."""
        return cv_transition(dt, self.dim)

    def noise(self, dt) -> np.ndarray:
        """Q(Δt), see :func:`cv_noise`."""
        return cv_noise(dt, self.q, self.dim)


@dataclass(frozen=True)
class ConstantAcceleration(_KinematicModel):
    """Constant-acceleration motion (continuous Wiener-process acceleration).

    State ``[x, y(, z), vx, vy(, vz), ax, ay(, az)]`` (positions first, see the
    module docstring).

    Parameters
    ----------
    dim : {1, 2, 3}
        spatial dimension.
    q : float ≥ 0
        power spectral density of the white jerk noise (m²/s⁵), per axis.
    """

    _order = 3

    @property
    def acceleration_indices(self) -> np.ndarray:
        """Indices of the acceleration components, ``[2·dim, …, 3·dim−1]``."""
        return np.arange(2 * self.dim, 3 * self.dim)

    def transition(self, dt) -> np.ndarray:
        """F(Δt), see :func:`ca_transition`."""
        return ca_transition(dt, self.dim)

    def noise(self, dt) -> np.ndarray:
        """Q(Δt), see :func:`ca_noise`."""
        return ca_noise(dt, self.q, self.dim)


@dataclass(frozen=True)
class Stationary(_KinematicModel):
    """A target at rest: zero velocity, its position a slow random walk.

    State ``[x, y(, z)]`` — the position alone; the velocity is exactly 0 (in an
    IMM's common state, :class:`~jointtrack.filters.imm.IMMModes`, the velocity
    components of this mode are 0 with zero variance). ``F(Δt) = I`` and
    ``Q(Δt) = q Δt I``: the position is a Wiener process of power spectral
    density ``q`` (m²/s, per axis) — a moored vessel swinging at its anchor, a
    parked vehicle's position jitter. It is the order-0 member of the
    continuous-time white-noise family of the module docstring (the noise drives
    the position itself), so the semigroup identities hold exactly:
    ``F(a+b) = I = F(b)F(a)``, ``Q(a+b) = (a + b) q I = Q(a) + Q(b)``.

    Parameters
    ----------
    dim : {1, 2, 3}
        spatial dimension.
    q : float ≥ 0
        power spectral density of the position's random walk (m²/s), per axis.

    Examples
    --------
    >>> m = Stationary(dim=2, q=0.01)
    >>> m.transition(60.0).tolist(), m.noise(60.0).diagonal().tolist()
    ([[1.0, 0.0], [0.0, 1.0]], [0.6, 0.6])
    """

    _order = 1

    @property
    def max_dt(self) -> float:
        """Largest time step for which ``noise`` is finite (``q Δt`` ≤ the largest float)."""
        if self.q == 0.0:
            return _FMAX
        dt = min(_FMAX / self.q, _FMAX)
        with np.errstate(over="ignore"):
            while not np.isfinite(self.q * dt):
                dt = float(dt * (1.0 - 4 * np.finfo(np.float64).eps))
        return dt

    @property
    def velocity_indices(self) -> np.ndarray:
        """No velocity components (the velocity is exactly 0): an empty array."""
        return np.zeros(0, np.int64)

    def _dt(self, dt) -> np.ndarray:
        dt = _check_dt(dt)
        big = dt > self.max_dt
        if big.any():
            i = int(np.argmax(big)) if dt.ndim else 0
            val = float(dt) if dt.ndim == 0 else float(dt[i])
            name = "dt" if dt.ndim == 0 else f"dt[{i}] (track {i})"
            raise ValueError(
                f"time step {name} = {val:.6g} is too large: the stationary process noise "
                f"Q overflows beyond dt = {self.max_dt:.6g} with q = {self.q:g}"
            )
        return dt

    def transition(self, dt) -> np.ndarray:
        """F(Δt) = I (dim × dim), or an (N, dim, dim) stack for an array ``dt``."""
        dt = self._dt(dt)
        eye = np.eye(self.dim)
        return eye if dt.ndim == 0 else np.broadcast_to(eye, (len(dt), self.dim, self.dim)).copy()

    def noise(self, dt) -> np.ndarray:
        """Q(Δt) = q Δt I (dim × dim), or an (N, dim, dim) stack for an array ``dt``."""
        dt = self._dt(dt)
        eye = np.eye(self.dim)
        if dt.ndim == 0:
            return (self.q * float(dt)) * eye
        return (self.q * dt)[:, None, None] * eye


# --------------------------------------------------------------------------- coordinated turn

#: Taylor coefficients (in θ²) of (sin θ − θ cos θ)/θ³ and (θ sin θ − (1 − cos θ))/θ²:
#: Σ_k (−1)^k 2(k+1)/(2k+3)! θ^{2k} and Σ_k (−1)^k (2k+1)/(2k+2)! θ^{2k}. Twelve terms
#: leave a truncation error below θ²⁴/26! ≈ 2.5e-27 for |θ| ≤ 1.
_DA_SERIES = tuple(
    (-1) ** k * 2.0 * (k + 1) / float(np.prod(np.arange(1, 2 * k + 4, dtype=np.float64)))
    for k in range(12)
)
_DB_SERIES = tuple(
    (-1) ** k * (2.0 * k + 1) / float(np.prod(np.arange(1, 2 * k + 3, dtype=np.float64)))
    for k in range(12)
)


def _horner(coeffs, u):
    acc = np.zeros_like(u)
    for c in reversed(coeffs):
        acc = acc * u + c
    return acc


def _turn_coefficients(omega: np.ndarray, dt: np.ndarray):
    """``(a, b, c, s, da, db)`` of a turn at rate ω over Δt, elementwise, θ = ωΔt.

    ``a = sin θ / ω``, ``b = (1 − cos θ)/ω``, ``c = cos θ``, ``s = sin θ``,
    ``da = ∂a/∂ω``, ``db = ∂b/∂ω``; finite and without division by ω at ω = 0
    (there ``a = Δt``, ``b = 0``, ``da = 0``, ``db = Δt²/2``).
    """
    theta = omega * dt
    half = 0.5 * theta
    sinc_half = np.sinc(half / np.pi)  # sin(θ/2)/(θ/2), exactly 1 at θ = 0
    a = dt * np.sinc(theta / np.pi)
    b = dt * half * sinc_half * sinc_half  # (1 − cos θ)/ω = 2 sin²(θ/2)/ω: no cancellation
    c, s = np.cos(theta), np.sin(theta)
    small = np.abs(theta) <= 1.0
    u = theta * theta
    with np.errstate(divide="ignore", invalid="ignore"):
        # direct forms only where |θ| > 1 (no cancellation there); series elsewhere
        da_direct = dt * dt * (theta * c - s) / (theta * theta)
        db_direct = dt * dt * (theta * s - (1.0 - c)) / (theta * theta)
    da = np.where(small, -dt * dt * theta * _horner(_DA_SERIES, u), da_direct)
    db = np.where(small, dt * dt * _horner(_DB_SERIES, u), db_direct)
    return a, b, c, s, da, db


def _check_turn_states(x, what="x") -> np.ndarray:
    from jointtrack.assignment._checks import _as_real_array

    x = _as_real_array(x, what)
    if x.ndim not in (1, 2) or x.shape[-1] != 5:
        raise ValueError(
            f"{what} must be one coordinated-turn state (5,) [x, y, vx, vy, ω] or a batch "
            f"(N, 5), got shape {x.shape}"
        )
    if not np.isfinite(x).all():
        raise ValueError(f"{what} has non-finite entries")
    return x


@dataclass(frozen=True)
class CoordinatedTurn:
    """Nearly-coordinated turn with the turn rate estimated, state ``[x, y, vx, vy, ω]``.

    The target moves at constant speed on a circle at turn rate ω (rad/s,
    positive counter-clockwise), Bar-Shalom, Li & Kirubarajan (2001) §11.7.1::

        x'  = x + a vx − b vy         a = sin(ωΔt)/ω
        y'  = y + b vx + a vy         b = (1 − cos ωΔt)/ω
        vx' = cos(ωΔt) vx − sin(ωΔt) vy
        vy' = sin(ωΔt) vx + cos(ωΔt) vy
        ω'  = ω

    Process noise: white acceleration of power spectral density ``q`` per
    axis on position and velocity (the continuous-time nearly-constant-velocity
    noise :func:`cv_noise`, exact at ω = 0) and a Wiener-process turn rate of
    power spectral density ``turn_rate_std²`` ((rad/s)²/s): ω's variance
    grows by ``turn_rate_std² Δt`` per step (§11.7.2).

    Parameters
    ----------
    q : float ≥ 0
        acceleration noise power spectral density (m²/s³), per axis.
    turn_rate_std : float ≥ 0
        σ of the turn-rate random walk, rad/s per √s.

    Examples
    --------
    >>> m = CoordinatedTurn(q=0.5, turn_rate_std=0.01)
    >>> x1 = m.propagate([0.0, 0.0, 10.0, 0.0, 0.05], 1.0)   # a left turn
    >>> J, Q = m.jacobian([0.0, 0.0, 10.0, 0.0, 0.05], 1.0), m.noise(1.0)
    """

    q: float = 1.0
    turn_rate_std: float = 0.01
    dim: ClassVar[int] = 2
    state_dim: ClassVar[int] = 5

    def __post_init__(self):
        object.__setattr__(self, "q", _check_q(self.q))
        try:
            w = float(self.turn_rate_std)
        except (TypeError, ValueError):
            raise ValueError(
                f"turn_rate_std must be a number, got {self.turn_rate_std!r}"
            ) from None
        if not (np.isfinite(w) and w >= 0) or isinstance(self.turn_rate_std, bool):
            raise ValueError(f"turn_rate_std must be finite and ≥ 0, got {self.turn_rate_std!r}")
        object.__setattr__(self, "turn_rate_std", w)

    @property
    def max_dt(self) -> float:
        """Largest time step: that of the nearly-constant-velocity part with this ``q``."""
        return _max_dt(2, max(self.q, self.turn_rate_std**2))

    @property
    def position_indices(self) -> np.ndarray:
        """``[0, 1]``."""
        return np.arange(2)

    @property
    def velocity_indices(self) -> np.ndarray:
        """``[2, 3]``."""
        return np.arange(2, 4)

    @property
    def turn_rate_index(self) -> int:
        """4: the turn rate ω is the last state component."""
        return 4

    def _dt(self, dt, n: int | None):
        dt = _check_dt(dt)
        _check_dt_range(dt, 2, max(self.q, self.turn_rate_std**2), "process noise Q")
        if dt.ndim == 1 and n is not None and len(dt) != n:
            raise ValueError(f"dt has {len(dt)} steps for {n} states; give one per state")
        return dt

    def _turn(self, x, dt):
        """``(single, X (N, 5), Δt, turn coefficients)`` of validated states ``x`` and
        step ``dt``: what :meth:`propagate` and :meth:`jacobian` both start from."""
        x = _check_turn_states(x)
        single = x.ndim == 1
        X = x[None] if single else x
        dt = self._dt(dt, None if single else len(X))
        return single, X, dt, _turn_coefficients(X[:, 4], dt)

    def propagate(self, x, dt) -> np.ndarray:
        """``f(x, Δt)``: the states ``x`` (5,) or (N, 5) after a turn of Δt seconds."""
        single, X, dt, (a, b, c, s, _, _) = self._turn(x, dt)
        vx, vy = X[:, 2], X[:, 3]
        out = np.stack(
            [X[:, 0] + a * vx - b * vy, X[:, 1] + b * vx + a * vy]
            + [c * vx - s * vy, s * vx + c * vy, X[:, 4]],
            axis=-1,
        )
        return out[0] if single else out

    def jacobian(self, x, dt) -> np.ndarray:
        """``∂f/∂x`` at ``x`` (5,) or (N, 5): (5, 5) or (N, 5, 5).

        The ω column is ``[a' vx − b' vy, b' vx + a' vy, −Δt (s vx + c vy),
        Δt (c vx − s vy), 1]`` with ``a' = ∂a/∂ω``, ``b' = ∂b/∂ω`` (series near ω = 0).
        """
        single, X, dt, (a, b, c, s, da, db) = self._turn(x, dt)
        vx, vy = X[:, 2], X[:, 3]
        N = len(X)
        J = np.zeros((N, 5, 5))
        J[:, 0, 0] = J[:, 1, 1] = J[:, 4, 4] = 1.0
        J[:, 0, 2], J[:, 0, 3] = a, -b
        J[:, 1, 2], J[:, 1, 3] = b, a
        J[:, 2, 2], J[:, 2, 3] = c, -s
        J[:, 3, 2], J[:, 3, 3] = s, c
        J[:, 0, 4] = da * vx - db * vy
        J[:, 1, 4] = db * vx + da * vy
        J[:, 2, 4] = -dt * (s * vx + c * vy)
        J[:, 3, 4] = dt * (c * vx - s * vy)
        return J[0] if single else J

    def noise(self, dt) -> np.ndarray:
        """Q(Δt) (5, 5), or (N, 5, 5) for an array ``dt``: :func:`cv_noise` on
        ``[x, y, vx, vy]`` and ``turn_rate_std² Δt`` on ω."""
        dt = self._dt(dt, None)
        Qcv = cv_noise(dt, self.q, 2)
        Q = np.zeros((*Qcv.shape[:-2], 5, 5))
        Q[..., :4, :4] = Qcv
        Q[..., 4, 4] = self.turn_rate_std**2 * dt
        return Q
