"""Interacting multiple model (IMM) filter steps, batched over tracks.

The IMM of Blom & Bar-Shalom ("The interacting multiple model algorithm for
systems with Markovian switching coefficients", IEEE Trans. Automatic Control
33(8), 1988), in the notation of Bar-Shalom, Li & Kirubarajan, *Estimation with
Applications to Tracking and Navigation* (2001), §11.6.6: ``r`` modes (motion
models) with mode probabilities ``μ_j`` and a Markov switching matrix
``Π = [π_ij]``, ``π_ij = P(mode j at k | mode i at k−1)`` (rows sum to one).
One cycle:

1. mixing probabilities (eq. 11.6.6-7)::

       c̄_j = Σ_i π_ij μ_i,         μ_{i|j} = π_ij μ_i / c̄_j

2. mixed initial conditions of each mode (eq. 11.6.6-8, 11.6.6-9)::

       x0_j = Σ_i μ_{i|j} x_i,     P0_j = Σ_i μ_{i|j} [P_i + (x_i − x0_j)(x_i − x0_j)ᵀ]

3. mode-conditioned prediction of ``(x0_j, P0_j)`` with mode j's motion model
   (an extended Kalman prediction for the coordinated turn) and update;
4. mode probabilities (eq. 11.6.6-15)::  ``μ_j ∝ Λ_j c̄_j``, ``Λ_j`` the
   likelihood of the scan's measurements under mode j;
5. the combined (moment-matched) estimate (eq. 11.6.6-16, 11.6.6-17)::

       x = Σ_j μ_j x_j,            P = Σ_j μ_j [P_j + (x_j − x)(x_j − x)ᵀ].

Modes of different state dimension: one common state
------------------------------------------------------
Every mode's estimate lives in one common state, the union of the modes'
components in the usual blocked layout — ``[position, velocity]``, then
``acceleration`` (dim components) if a constant-acceleration mode is present,
then the turn rate ω if a coordinated-turn mode is present (2-D). A mode
predicts its own components with its own model and sets the others to 0 with
zero variance and zero covariance — constant velocity has ω = 0 and a = 0 exactly,
the coordinated turn has a = 0 — so a component a mode does not model carries no
spurious uncertainty into that mode's likelihood, and the mixing formulas above
apply unchanged (every ``x_i`` has the same length). The alternative, per-mode
spaces with conversion maps, needs a choice of value and variance for the
missing components at every mixing; here that choice is the model itself (the
component is what the mode says it is: zero). Each mode is filtered in its own
state space (its components sliced out of the common state, where its covariance
is positive definite) and embedded back; in the common state a mode's covariance
is positive *semi*-definite (its inactive rows are zero), and the combined
covariance of position and velocity is positive definite.

A stationary mode (:class:`~jointtrack.models.Stationary`: the position a slow
random walk, the velocity 0) has the position alone as its own components; its
velocity is 0 with zero variance in the common state, as a CV mode's acceleration.

Switching in time
-----------------
The chain above steps once per scan. With targets that report themselves one at a
time (``reporting = "async"``) every report of every target is a scan — on Solent
AIS 3.7 a second — so a per-scan stay probability of 0.95 mixes the modes
completely within seconds, whatever the target did. With ``switching_per =
"second"`` the matrix is the one-second transition Π₁ of a continuous-time Markov
chain with generator ``G = log Π₁`` (rates per second, rows summing to 0; Norris,
*Markov Chains*, Cambridge University Press 1997, §2.1, §3.1), and a prediction over
Δt seconds mixes with ``Π(Δt) = e^{G Δt}`` (Π(1) = Π₁, Π(a)Π(b) = Π(a + b)): the
switching a track sees between two of its own reports depends on the time between
them, not on how many other targets reported in between.

Numerics
--------
Mode probabilities are carried as logarithms, ``log μ`` (N, r), normalised
(``logsumexp = 0``) and always finite: the mode update adds the modes' log
likelihoods to ``log c̄`` and renormalises by ``logsumexp``, so a mode whose
likelihood is e^{-2000} times another's keeps a finite (very negative) log
probability instead of an underflowed 0, and no 0/0 can arise. Zero entries of
Π are −∞ in ``log Π``; every column of Π must have a positive entry, so ``c̄_j``
is never 0. The mixing and combination weights are ``exp`` of normalised
logarithms (each in [0, 1]); a weight that underflows contributes below the
rounding of the others.

The IMM-PDA / IMM-JPDA update (:func:`imm_pda_pairs_update`) with the
association probabilities β of the mixture likelihood
``g_ik = Σ_j c̄_ij g_ijk`` (Blom & Bloem, "Probabilistic data association
avoiding track coalescence", IEEE Trans. Automatic Control 45(2), 2000;
Bar-Shalom, Li & Kirubarajan 2001 §11.6.6 with the PDAF of each mode): the
mode-conditioned association probabilities are ``β_ik|j = β_ik (g_ijk/g_ik) /
D_ij``, ``β_i0|j = β_i0 / D_ij`` with ``D_ij = β_i0 + Σ_k β_ik g_ijk/g_ik``, each
mode is updated by its own PDA with them, and ``μ_ij ∝ c̄_ij D_ij`` — which sums to
one over j exactly (``Σ_j c̄_ij g_ijk/g_ik = 1``). For one track and one
measurement with β = (0, 1) this is the IMM's ``μ_j ∝ c̄_j Λ_j``.
"""

from __future__ import annotations

import math

import numpy as np

from jointtrack.filters.kalman import (
    _arr,
    _state,
    ekf_predict_measurement,
    log_likelihood,
    predict,
    predict_measurement,
    update,
)
from jointtrack.filters.pda import pda_pairs_update
from jointtrack.models.motion import (
    ConstantAcceleration,
    ConstantVelocity,
    CoordinatedTurn,
    Stationary,
)

__all__ = [
    "IMMModes",
    "SWITCHING_PER",
    "imm_combine",
    "imm_mix",
    "imm_mixing",
    "imm_mode_update",
    "imm_pair_log_likelihoods",
    "imm_pda_pairs_update",
    "imm_predict",
    "imm_update",
    "switching_generator",
    "switching_over",
]

#: accepted |row sum − 1| of a switching matrix and |Σ μ − 1| of mode probabilities
_SUM_TOL = 1e-9


def _logsumexp(a: np.ndarray, axis: int) -> np.ndarray:
    """log Σ exp(a) along ``axis``; −∞ where every entry is −∞ (no warning, no NaN)."""
    top = np.max(a, axis=axis, keepdims=True)
    top = np.where(np.isfinite(top), top, 0.0)
    with np.errstate(divide="ignore"):
        out = np.log(np.sum(np.exp(a - top), axis=axis, keepdims=True)) + top
    return np.squeeze(out, axis=axis)


def _probability_vector(p, r: int, name: str) -> np.ndarray:
    """Positive probabilities summing to one (to 1e-9), renormalised; ValueError naming ``name``."""
    from jointtrack.assignment._checks import _as_real_array

    p = _as_real_array(p, name)
    if p.shape != (r,):
        raise ValueError(f"{name} must have one probability per mode ({r},), got shape {p.shape}")
    if not np.isfinite(p).all() or (p <= 0).any():
        raise ValueError(
            f"{name} must hold probabilities > 0 (a mode of probability 0 never returns), "
            f"got {p.tolist()}"
        )
    if abs(p.sum() - 1.0) > _SUM_TOL:
        raise ValueError(f"{name} must sum to 1, got {p.sum():.17g}")
    return p / p.sum()


def _switching_matrix(switching, r: int, name: str = "switching") -> np.ndarray:
    """A row-stochastic (r, r) matrix whose every column has a positive entry."""
    from jointtrack.assignment._checks import _as_real_array

    P = _as_real_array(switching, name)
    if P.shape != (r, r):
        raise ValueError(f"{name} must be a {r} × {r} matrix (one row per mode), got {P.shape}")
    if not np.isfinite(P).all() or (P < 0).any():
        raise ValueError(f"{name} must hold finite probabilities ≥ 0, got {P.tolist()}")
    sums = P.sum(axis=1)
    bad = np.abs(sums - 1.0) > _SUM_TOL
    if bad.any():
        i = int(np.argmax(bad))
        raise ValueError(
            f"{name} is not a stochastic matrix: row {i} (switching from mode {i}) sums to "
            f"{sums[i]:.17g}, not 1"
        )
    dead = ~(P > 0).any(axis=0)
    if dead.any():
        j = int(np.argmax(dead))
        raise ValueError(
            f"{name}: column {j} is all zero, so mode {j} could never be entered (its "
            "probability would be 0)"
        )
    return P / sums[:, None]


_KINDS = (
    (CoordinatedTurn, "ct"),
    (ConstantAcceleration, "ca"),
    (ConstantVelocity, "cv"),
    (Stationary, "stationary"),
)

#: how a switching matrix is meant: per scan (a step of the chain at every scan) or
#: per second (the one-second transition of a continuous-time chain)
SWITCHING_PER = ("scan", "second")


_EMBEDDABLE = (
    " (two modes with stay probabilities above 1/2, or r modes with stays above 1/r and "
    "the rest shared equally, always are)"
)


def switching_generator(switching, name: str = "switching") -> np.ndarray:
    """The generator ``G`` of the continuous-time chain whose one-second transition is
    ``switching``: ``expm(G) = Π₁``, off-diagonal rates ≥ 0, rows summing to 0.

    ``G = log Π₁`` (the principal matrix logarithm). Not every stochastic matrix is
    the one-second transition of a continuous-time chain (the embedding problem):
    a matrix with a zero or negative eigenvalue, or whose logarithm has a negative
    off-diagonal rate, is refused with a ValueError naming ``name``. Every matrix
    with stay probabilities above 1/2 on the diagonal of a two-mode chain, and
    every ``p I + (1 − p)/(r − 1)(11ᵀ − I)`` with ``p > 1/r``, is embeddable.
    """
    from scipy.linalg import logm

    P = np.asarray(switching, float)
    r = len(P)
    eig = np.linalg.eigvals(P)
    if (np.abs(eig.imag) <= 1e-12).all() and (eig.real <= 1e-12).any():
        raise ValueError(
            f"{name}: as a one-second switching matrix (imm_switching_per = 'second') it "
            f"needs positive eigenvalues, got {sorted(eig.real.tolist())}: it switches "
            "faster than any continuous-time chain" + _EMBEDDABLE
        )
    # Π₁ − I from the off-diagonal shares (rows of Π₁ sum to one): switching
    # probabilities far below the rounding of 1 on the diagonal are kept
    E = np.where(np.eye(r, dtype=bool), 0.0, P)
    E[np.diag_indices(r)] = -E.sum(axis=1)
    if r == 1 or not E.any():
        G = np.zeros((r, r))
    elif np.abs(E).sum(axis=1).max() <= 0.5:
        # log(I + E) = Σ_k (−1)^{k+1} Eᵏ/k, ‖E‖∞ ≤ 1/2: 64 terms leave < 2⁻⁶⁴/64, and a
        # tiny rate keeps its relative accuracy (its first term is the share itself)
        G, term = np.zeros((r, r)), np.eye(r)
        for k in range(1, 65):
            term = term @ E
            G += term * ((-1.0) ** (k + 1) / k)
    else:
        with np.errstate(all="ignore"):
            G = logm(P)
    G = np.asarray(G)
    if not np.isfinite(G).all() or (np.abs(np.imag(G)) > 1e-9).any():
        raise ValueError(
            f"{name}: as a one-second switching matrix (imm_switching_per = 'second') it "
            "has no real logarithm: it is not the one-second transition of a continuous-time "
            "chain" + _EMBEDDABLE
        )
    G = np.real(G)
    off = ~np.eye(r, dtype=bool)
    neg = off & (G < -1e-9)
    if neg.any():
        i, j = (int(v) for v in np.argwhere(neg)[0])
        raise ValueError(
            f"{name}: as a one-second switching matrix (imm_switching_per = 'second') its "
            f"logarithm has a negative switching rate {G[i, j]:.6g} per second from mode {i} "
            f"to mode {j}: it is not the one-second transition of a continuous-time chain"
            + _EMBEDDABLE
        )
    G = np.where(off, np.maximum(G, 0.0), 0.0)
    G[np.diag_indices(r)] = -G.sum(axis=1)  # rows of a generator sum to 0 exactly
    # the rates cut to 0 above were rounding (≥ −1e-9): the chain must still give Π₁
    from scipy.linalg import expm

    err = float(np.max(np.abs(expm(G) - P)))
    if not err <= 1e-9:
        raise ValueError(
            f"{name}: as a one-second switching matrix (imm_switching_per = 'second') it is "
            f"not the one-second transition of a continuous-time chain (the nearest one "
            f"differs by {err:.3g})" + _EMBEDDABLE
        )
    return G


def switching_over(generator, dt) -> np.ndarray:
    """``Π(Δt) = expm(G Δt)``, the switching matrix of a continuous-time chain over
    ``dt`` seconds (``dt`` ≥ 0 finite; ``Π(0) = I``, ``Π(a)Π(b) = Π(a + b)``).

    ``generator``: ``G`` (:func:`switching_generator`) or its :class:`_ChainInTime`
    (the eigendecomposition, made once: a tracker asks at every scan). Entries are ≥ 0
    (rounding below 0 is cut) and rows renormalised to sum to one.
    """
    chain = generator if isinstance(generator, _ChainInTime) else _ChainInTime(generator)
    return chain(dt)


class _ChainInTime:
    """``Δt ↦ e^{GΔt}`` of one generator. Two modes (rates a, b): the closed form
    ``π_01 = a/(a + b) · (1 − e^{−(a+b)Δt})``, ``π_10 = b/(a + b) · (1 − e^{−(a+b)Δt})``
    (Norris 1997, §2.1), each switching probability to its relative accuracy (expm1).
    More modes: ``I + V diag(expm1(λΔt)) V⁻¹`` when G has real eigenvalues and an
    eigenbasis that reproduces it (equal shares among the modes), else
    :func:`scipy.linalg.expm`."""

    def __init__(self, generator):
        self.G = np.asarray(generator, float)
        lam, V = np.linalg.eig(self.G)
        self.eig = None
        top = float(np.max(np.abs(self.G))) if self.G.size else 0.0
        if len(self.G) > 2 and (np.abs(lam.imag) <= 1e-12 * (1.0 + np.abs(lam.real))).all():
            V, lam_r = np.real(V), np.real(lam)
            if np.linalg.cond(V) < 1e6:
                W = np.linalg.inv(V)
                if np.max(np.abs((V * lam_r) @ W - self.G)) <= 1e-13 * top:
                    self.eig = (lam_r, V, W)
        # past 800 of the chain's slowest time constants every transient e^{−γΔt} is
        # below the smallest float: Π(Δt) is the limit, which that span already gives
        rates = -lam.real
        slow = rates[rates > 1e-12 * top]
        self.longest = 800.0 / float(slow.min()) if slow.size else math.inf

    def __call__(self, dt) -> np.ndarray:
        dt = float(dt)
        if not (math.isfinite(dt) and dt >= 0):
            raise ValueError(f"dt must be finite and ≥ 0 seconds, got {dt}")
        r = len(self.G)
        if dt == 0.0 or not self.G.any():
            return np.eye(r)
        span = min(dt, self.longest)
        if r == 2:
            a, b = self.G[0, 1], self.G[1, 0]
            moved = -math.expm1(-(a + b) * span)  # 1 − e^{−(a+b)Δt}, no cancellation
            p01, p10 = a / (a + b) * moved, b / (a + b) * moved
            return np.array([[1.0 - p01, p01], [p10, 1.0 - p10]])
        if self.eig is not None:
            lam, V, W = self.eig
            P = np.eye(r) + (V * np.expm1(lam * span)) @ W
        else:
            from scipy.linalg import expm

            P = expm(self.G * span)
        P = np.maximum(P, 0.0)
        return P / P.sum(axis=1, keepdims=True)


class IMMModes:
    """The modes of an IMM, their Markov switching and the common state they share.

    Parameters
    ----------
    models : sequence of motion models
        :class:`~jointtrack.models.ConstantVelocity`,
        :class:`~jointtrack.models.ConstantAcceleration` or
        :class:`~jointtrack.models.CoordinatedTurn` (2-D), all of one spatial
        dimension, or :class:`~jointtrack.models.Stationary` (position only, velocity
        0); two modes may be of one kind (e.g. CV with a small and a large q).
    switching : (r, r) array
        ``switching[i, j]`` = P(mode j now | mode i before): rows sum to one (to
        1e-9, renormalised); every column needs a positive entry.
    initial : (r,) array, optional
        mode probabilities of a new track, each > 0, summing to one (default uniform).
    names : sequence of str, optional
        one per mode (default ``"cv"``, ``"ca"``, ``"ct"``, ``"stationary"``).
    switching_per : {"scan", "second"}
        ``"scan"`` (default): ``switching`` is applied once per prediction, whatever
        its Δt. ``"second"``: ``switching`` is the one-second transition ``Π₁`` of
        a continuous-time chain, and a prediction over Δt seconds switches by
        ``Π(Δt) = expm(Δt log Π₁)`` (= ``Π₁^Δt``; :func:`switching_generator`,
        :func:`switching_over`) — a target between two of its own reports switches
        as often as the elapsed time says, not once per other target's report.

    Attributes
    ----------
    state_dim : int
        length of the common state: ``2·dim``, plus ``dim`` with a CA mode, plus 1
        with a CT mode; layout ``[position, velocity(, acceleration)(, ω)]``.
    dim, n_modes, names, switching, log_switching, initial, log_initial
    mode_indices : list of (k_j,) int arrays
        the common-state components of mode j, in that mode's own state order.
    acceleration_indices, turn_rate_index :
        where those components are in the common state (empty / None if absent).

    Examples
    --------
    >>> from jointtrack.models import ConstantVelocity, CoordinatedTurn
    >>> modes = IMMModes([ConstantVelocity(q=1.0), CoordinatedTurn(q=1.0)],
    ...                  [[0.95, 0.05], [0.05, 0.95]])
    >>> modes.state_dim, modes.names
    (5, ('cv', 'ct'))
    """

    def __init__(self, models, switching, initial=None, names=None, switching_per="scan"):
        models = list(models) if not isinstance(models, str) else None
        if not models:
            raise ValueError("models must be a non-empty sequence of motion models")
        kinds = []
        for j, m in enumerate(models):
            kind = next((k for cls, k in _KINDS if isinstance(m, cls)), None)
            if kind is None:
                raise ValueError(
                    f"models[{j}] = {m!r} is not a ConstantVelocity, ConstantAcceleration, "
                    "CoordinatedTurn or Stationary model"
                )
            kinds.append(kind)
        dims = {int(m.dim) for m in models}
        if len(dims) != 1:
            raise ValueError(f"models must share one spatial dimension, got {sorted(dims)}")
        d = dims.pop()
        r = len(models)
        self.models = tuple(models)
        self.kinds = tuple(kinds)
        self.dim = d
        self.n_modes = r
        if names is None:
            names = kinds
        names = tuple(names)
        if len(names) != r or not all(isinstance(s, str) for s in names):
            raise ValueError(f"names must be {r} strings (one per mode), got {names!r}")
        self.names = names
        self.switching = _switching_matrix(switching, r)
        with np.errstate(divide="ignore"):
            self.log_switching = np.log(self.switching)
        if switching_per not in SWITCHING_PER:
            raise ValueError(f"switching_per must be 'scan' or 'second', got {switching_per!r}")
        self.switching_per = switching_per
        self.generator = switching_generator(self.switching) if switching_per == "second" else None
        self._chain = None if self.generator is None else _ChainInTime(self.generator)
        self.initial = (
            np.full(r, 1.0 / r) if initial is None else _probability_vector(initial, r, "initial")
        )
        self.log_initial = np.log(self.initial)
        n = 2 * d
        self.acceleration_indices = np.zeros(0, np.int64)
        self.turn_rate_index = None
        if "ca" in kinds:
            self.acceleration_indices = np.arange(n, n + d)
            n += d
        if "ct" in kinds:
            self.turn_rate_index = n
            n += 1
        self.state_dim = n
        base = np.arange(2 * d)
        self.mode_indices = []
        for kind in kinds:
            if kind == "stationary":
                idx = np.arange(d)
            elif kind == "cv":
                idx = base
            elif kind == "ca":
                idx = np.concatenate([base, self.acceleration_indices])
            else:
                idx = np.concatenate([base, [self.turn_rate_index]])
            self.mode_indices.append(np.asarray(idx, np.int64))

    def __repr__(self) -> str:
        return f"IMMModes(names={self.names}, state_dim={self.state_dim})"

    def log_switching_over(self, dt) -> np.ndarray:
        """``log Π`` of a prediction over ``dt`` seconds: the per-scan matrix, or (with
        ``switching_per = "second"``) ``log expm(Δt log Π₁)`` (−∞ where an entry is 0)."""
        if self.generator is None:
            return self.log_switching
        with np.errstate(divide="ignore"):
            return np.log(self._chain(dt))

    def initial_states(self, x0, P0, acceleration_var=0.0, turn_rate_var=0.0):
        """Per-mode states ``(x (K, r, n), P (K, r, n, n), log μ (K, r))`` of new tracks.

        ``x0`` (K, 2·dim), ``P0`` (K, 2·dim, 2·dim): position and velocity. A mode
        that models acceleration (turn rate) starts it at 0 with variance
        ``acceleration_var`` (``turn_rate_var``); the other components are 0 with
        zero variance (see the module docstring).
        """
        x0, P0 = np.asarray(x0, float), np.asarray(P0, float)
        K, k = x0.shape
        r, n = self.n_modes, self.state_dim
        x = np.zeros((K, r, n))
        P = np.zeros((K, r, n, n))
        x[:, :, :k] = x0[:, None]
        P[:, :, :k, :k] = P0[:, None]
        for j, kind in enumerate(self.kinds):
            if kind == "stationary":  # its velocity is 0 exactly (zero variance)
                x[:, j], P[:, j] = self.from_mode(j, *self.to_mode(j, x[:, j], P[:, j]))
            if kind == "ca":
                a = self.acceleration_indices
                P[:, j, a, a] = acceleration_var
            elif kind == "ct":
                P[:, j, self.turn_rate_index, self.turn_rate_index] = turn_rate_var
        return x, P, np.broadcast_to(self.log_initial, (K, r)).copy()

    def predict_mode(self, j: int, x, P, dt):
        """Mode j's prediction of the common states ``x`` (N, n), ``P`` (N, n, n) by ``dt``.

        Its own components by its model, in its own state space (extended
        Kalman for the coordinated turn: ``x⁻ = f(x)``, ``P⁻ = J P Jᵀ + Q`` with
        ``J = ∂f/∂x``); the other components are 0 with zero variance.
        """
        model = self.models[j]
        xj, Pj = self.to_mode(j, x, P)
        Q = model.noise(dt)
        if self.kinds[j] == "ct":
            _, Pp = predict(xj, Pj, model.jacobian(xj, dt), Q)
            xp = model.propagate(xj, dt)
        else:
            xp, Pp = predict(xj, Pj, model.transition(dt), Q)
        return self.from_mode(j, xp, Pp)

    def to_mode(self, j: int, x, P):
        """Mode j's own components ``(x (N, k_j), P (N, k_j, k_j))`` of common states."""
        idx = self.mode_indices[j]
        return x[:, idx], P[:, idx[:, None], idx[None, :]]

    def from_mode(self, j: int, xj, Pj):
        """Common states of mode j's own ``(xj, Pj)``: the other components 0, zero variance."""
        idx, n = self.mode_indices[j], self.state_dim
        x = np.zeros((len(xj), n))
        P = np.zeros((len(xj), n, n))
        x[:, idx] = xj
        P[:, idx[:, None], idx[None, :]] = Pj
        return x, P

    def mode_measurement(self, j: int, H=None, R=None, model=None) -> dict:
        """The measurement model of the common state seen from mode j's own space:
        ``{"H": H[:, idx], "R": R}`` or ``{"model": …}`` (an EKF model evaluated at the
        common state with the other components 0)."""
        idx, n = self.mode_indices[j], self.state_dim
        if model is None:
            H = _arr(H, "H")
            k = H.shape[-1] if H.ndim >= 2 else -1
            if not 1 <= k <= n:
                raise ValueError(
                    f"H must be (m, k) with k ≤ {n}, the common state's length, got {H.shape}"
                )
            full = np.zeros((*H.shape[:-1], n))
            full[..., :k] = H  # a model of the first k components (position, velocity)
            return {"H": full[..., idx], "R": R}
        return {"model": _ModeSensor(model, idx, n)}


class _ModeSensor:
    """An EKF measurement model of the common state, on one mode's own components."""

    def __init__(self, model, idx, n):
        # the model sees the first k components of the common state (k = its
        # state_dim, e.g. position and velocity), which every mode has first
        self._k = int(getattr(model, "state_dim", n))
        if not 1 <= self._k <= n:
            raise ValueError(f"measurement model state_dim {self._k} exceeds the common {n}")
        self._model, self._idx, self._n = model, idx, n
        self.state_dim = len(idx)
        self.R = model.R
        self.residual = model.residual

    def _full(self, x):
        x = np.asarray(x, float)
        full = np.zeros((*x.shape[:-1], self._n))
        full[..., self._idx] = x
        return full[..., : self._k]

    def h(self, x):
        return self._model.h(self._full(x))

    def jacobian(self, x):
        J = np.asarray(self._model.jacobian(self._full(x)), float)
        full = np.zeros((*J.shape[:-1], self._n))
        full[..., : self._k] = J
        return full[..., self._idx]


def _mode_state(x, P, r=None):
    """Validate per-mode states x (N, r, n), P (N, r, n, n); returns float arrays."""
    x = _arr(x, "x")
    P = _arr(P, "P")
    if x.ndim != 3 or (r is not None and x.shape[1] != r):
        want = "(N, r, n)" if r is None else f"(N, {r}, n)"
        raise ValueError(f"x must be per-mode states {want}, got shape {x.shape}")
    N, r, n = x.shape
    if P.shape != (N, r, n, n):
        raise ValueError(f"P must have shape ({N}, {r}, {n}, {n}) to match x, got {P.shape}")
    # the filters' own checks (finite, symmetric, positive semi-definite), per mode
    for j in range(r):
        try:
            _state(x[:, j], P[:, j])
        except ValueError as exc:
            raise ValueError(f"mode {j}: {exc}") from None
    return x, P


def _log_probabilities(log_mu, N: int, r: int, name: str = "log_mu") -> np.ndarray:
    """Finite, normalised log mode probabilities (N, r); renormalised exactly."""
    from jointtrack.assignment._checks import _as_real_array

    log_mu = _as_real_array(log_mu, name)
    if log_mu.shape != (N, r):
        raise ValueError(f"{name} must have shape ({N}, {r}), got {log_mu.shape}")
    if not np.isfinite(log_mu).all():
        i = int(np.argwhere(~np.isfinite(log_mu))[0, 0])
        raise ValueError(
            f"{name}[{i}] (track {i}) is not finite: every mode probability must be > 0 "
            "(log probabilities are finite)"
        )
    tot = _logsumexp(log_mu, 1) if N else np.zeros(0)
    bad = np.abs(tot) > _SUM_TOL
    if bad.any():
        i = int(np.argmax(bad))
        raise ValueError(
            f"{name}[{i}] (track {i}): the mode probabilities sum to {math.exp(tot[i]):.17g}, not 1"
        )
    return log_mu - tot[:, None]


def _checked(modes, x, P):
    """Per-mode states validated against ``modes`` (IMMModes)."""
    if not isinstance(modes, IMMModes):
        raise ValueError(f"modes must be an IMMModes, got {type(modes).__name__}")
    x, P = _mode_state(x, P, modes.n_modes)
    if x.shape[2] != modes.state_dim:
        raise ValueError(
            f"x has {x.shape[2]} state components, the modes' common state has {modes.state_dim}"
        )
    return x, P


def imm_mixing(log_mu, switching):
    """Predicted mode and mixing probabilities, in logarithms (eq. 11.6.6-7).

    Parameters
    ----------
    log_mu : (N, r) array
        log mode probabilities of N tracks (finite; each row's probabilities sum to 1).
    switching : (r, r) array or IMMModes
        Markov switching matrix, ``switching[i, j] = π_ij``.

    Returns
    -------
    log_cbar : (N, r)
        ``log c̄_j = log Σ_i π_ij μ_i``, the predicted mode probabilities.
    log_mix : (N, r, r)
        ``log μ_{i|j} = log π_ij + log μ_i − log c̄_j`` (−∞ where π_ij = 0); over i
        the mixing probabilities of mode j sum to one.
    """
    if isinstance(switching, IMMModes):
        log_pi = switching.log_switching
        r = switching.n_modes
    else:
        pi = _switching_matrix(switching, np.shape(switching)[0] if np.ndim(switching) else 0)
        r = len(pi)
        with np.errstate(divide="ignore"):
            log_pi = np.log(pi)
    return _mixing(log_mu, log_pi, r)


def _mixing(log_mu, log_pi, r: int):
    """:func:`imm_mixing` with ``log Π`` given (its columns each with a finite entry)."""
    log_mu = np.atleast_2d(log_mu) if np.ndim(log_mu) == 1 else log_mu
    log_mu = _log_probabilities(log_mu, np.shape(log_mu)[0], r)
    joint = log_mu[:, :, None] + log_pi[None]  # log π_ij μ_i, (N, i, j)
    log_cbar = _logsumexp(joint, 1)  # finite: column j of Π has a positive entry, μ_i > 0
    return log_cbar, joint - log_cbar[:, None, :]


def imm_mix(x, P, log_mix):
    """Mixed initial conditions of every mode (eq. 11.6.6-8, 11.6.6-9).

    ``x`` (N, r, n), ``P`` (N, r, n, n) the modes' estimates, ``log_mix``
    (N, r, r) from :func:`imm_mixing`. Returns ``(x0, P0)`` of the same shapes:
    ``x0_j = Σ_i μ_{i|j} x_i``, ``P0_j = Σ_i μ_{i|j} [P_i + (x_i − x0_j)(x_i − x0_j)ᵀ]``
    (a sum of positive semi-definite terms: no cancellation).
    """
    x, P = _mode_state(x, P)
    w = np.exp(log_mix)  # (N, i, j), each column sums to 1
    x0 = np.einsum("nij,nik->njk", w, x)
    dev = x[:, :, None, :] - x0[:, None, :, :]  # (N, i, j, n)
    P0 = np.einsum("nij,nikl->njkl", w, P) + np.einsum("nij,nijk,nijl->njkl", w, dev, dev)
    return x0, 0.5 * (P0 + np.swapaxes(P0, -1, -2))


def imm_combine(x, P, log_mu):
    """The combined (moment-matched) estimate (eq. 11.6.6-16, 11.6.6-17).

    ``x = Σ_j μ_j x_j``, ``P = Σ_j μ_j [P_j + (x_j − x)(x_j − x)ᵀ]`` for per-mode
    ``x`` (N, r, n), ``P`` (N, r, n, n) and ``log_mu`` (N, r). Returns
    ``(x (N, n), P (N, n, n))``.
    """
    x, P = _mode_state(x, P)
    log_mu = _log_probabilities(log_mu, x.shape[0], x.shape[1])
    mu = np.exp(log_mu)
    xc = np.einsum("nj,njk->nk", mu, x)
    dev = x - xc[:, None, :]
    Pc = np.einsum("nj,njkl->nkl", mu, P) + np.einsum("nj,njk,njl->nkl", mu, dev, dev)
    return xc, 0.5 * (Pc + np.swapaxes(Pc, -1, -2))


def imm_mode_update(log_cbar, log_likelihood_ratio):
    """Posterior log mode probabilities ``log μ_j = log c̄_j + log Λ_j − log Σ_l c̄_l Λ_l``.

    (eq. 11.6.6-15.) ``log_likelihood_ratio`` (N, r): the log likelihood of
    each mode, up to a constant per track (finite, or −∞ for some but not all
    modes of a track). Normalised in log space: never 0/0, never an underflowed 0.
    """
    log_cbar = np.asarray(log_cbar, float)
    lam = np.asarray(log_likelihood_ratio, float)
    if lam.shape != log_cbar.shape:
        raise ValueError(
            f"log_likelihood_ratio must have shape {log_cbar.shape} (one per track and "
            f"mode), got {lam.shape}"
        )
    if np.isnan(lam).any() or np.isposinf(lam).any():
        raise ValueError("log_likelihood_ratio has NaN or +inf entries")
    post = log_cbar + lam
    tot = _logsumexp(post, 1)
    if not np.isfinite(tot).all():
        i = int(np.argmax(~np.isfinite(tot)))
        raise ValueError(f"track {i}: every mode has likelihood 0 (log −∞)")
    out = post - tot[:, None]
    # a mode of likelihood exactly 0 (−∞) keeps the smallest finite log probability,
    # never −∞: a mode of probability 0 could never come back
    return np.maximum(out, np.finfo(float).min)


def imm_predict(x, P, log_mu, modes: IMMModes, dt):
    """Mixing and mode-conditioned prediction: ``(x⁻, P⁻, log c̄)``.

    ``x`` (N, r, n), ``P`` (N, r, n, n), ``log_mu`` (N, r) the modes' estimates
    and log probabilities after the previous scan; ``dt`` > 0 (a number). Returns
    each mode's prediction of its mixed initial condition and the predicted log
    mode probabilities ``log c̄`` (steps 1–3 of the module docstring). The switching
    is ``modes``' per-scan matrix, or over ``dt`` seconds (``switching_per = "second"``).
    """
    x, P = _checked(modes, x, P)
    log_cbar, log_mix = _mixing(log_mu, modes.log_switching_over(dt), modes.n_modes)
    x0, P0 = imm_mix(x, P, log_mix)
    xp, Pp = np.empty_like(x0), np.empty_like(P0)
    for j in range(modes.n_modes):
        xp[:, j], Pp[:, j] = modes.predict_mode(j, x0[:, j], P0[:, j], dt)
    return xp, Pp, log_cbar


def _measurement(model, H, R):
    if (H is None) == (model is None):
        raise ValueError("give either H and R (linear) or model (EKF)")
    return {"H": H, "R": R} if model is None else {"model": model}


def imm_pair_log_likelihoods(modes, x, P, log_cbar, z, rows, cols, *, H=None, R=None, model=None):
    """Log likelihoods of (track, measurement) pairs under each mode and their mixture.

    ``modes`` (:class:`IMMModes`); ``x`` (N, r, n), ``P`` (N, r, n, n) predicted per
    mode, ``log_cbar`` (N, r); pair k is measurement ``z[cols[k]]`` with track
    ``rows[k]``; ``H`` (m, n) and ``R``, or an EKF ``model``, of the common state. Returns
    ``(log_g (K,), log_g_mode (K, r))``: ``log g_ijk = log N(z_k; ẑ_ij, S_ij)`` and
    the mixture ``log g_ik = log Σ_j c̄_ij g_ijk`` (what the association uses).
    """
    x, P = _checked(modes, x, P)
    N, r, _ = x.shape
    log_cbar = _log_probabilities(log_cbar, N, r, "log_cbar")
    z = _arr(z, "z")
    rows, cols = _pair_indices(rows, cols, N, z)
    _measurement(model, H, R)
    log_g_mode = np.empty((len(rows), r))
    for j in range(r):
        xj, Pj = modes.to_mode(j, x[:, j], P[:, j])
        kw = modes.mode_measurement(j, H, R, model)
        if model is None:
            zhat, S = predict_measurement(xj, Pj, kw["H"], kw["R"])
            nu = z[cols] - zhat[rows]
        else:
            zhat, S = ekf_predict_measurement(xj, Pj, kw["model"])
            nu = np.asarray(model.residual(z[cols], zhat[rows]), float)
        log_g_mode[:, j] = log_likelihood(nu, S[rows]) if len(rows) else np.zeros(0)
    log_g = _logsumexp(log_cbar[rows] + log_g_mode, 1)
    return log_g, log_g_mode


def _pair_indices(rows, cols, N: int, z: np.ndarray):
    """Validated pair indices: integers, equal lengths, inside the tracks / measurements."""
    from jointtrack.assignment._checks import _as_real_array

    out = []
    for name, v, hi, what in (("rows", rows, N, "tracks"), ("cols", cols, len(z), "measurements")):
        a = _as_real_array(v, name).reshape(-1)
        if not (np.isfinite(a).all() and (a == np.round(a)).all()):
            raise ValueError(f"{name} must hold integer indices")
        if a.size and (a.min() < 0 or a.max() >= hi):
            raise ValueError(f"{name} indexes outside the {hi} {what}")
        out.append(a.astype(np.int64))
    if out[0].shape != out[1].shape:
        raise ValueError("rows and cols must have one entry per pair")
    return out


def imm_pda_pairs_update(
    modes, x, P, log_cbar, z, beta0, rows, cols, weights, *, H=None, R=None, model=None
):
    """IMM-PDA / IMM-JPDA update on sparse association probabilities.

    ``beta0`` (N,), pairs ``(rows, cols, weights)`` as in
    :func:`~jointtrack.filters.pda_pairs_update`, computed with the mixture
    likelihoods of :func:`imm_pair_log_likelihoods`. Each mode is updated by its
    own PDA with the mode-conditioned β and the mode probabilities become
    ``μ_ij ∝ c̄_ij (β_i0 + Σ_k β_ik g_ijk / g_ik)`` (module docstring; Blom &
    Bloem 2000). Returns ``(x⁺ (N, r, n), P⁺ (N, r, n, n), log μ⁺ (N, r))``.
    """
    x, P = _checked(modes, x, P)
    N, r, _ = x.shape
    kw = _measurement(model, H, R)
    from jointtrack.assignment._checks import _as_real_array

    b0 = _as_real_array(beta0, "beta0").reshape(-1)
    rows, cols = _pair_indices(rows, cols, N, _arr(z, "z"))
    w = _as_real_array(weights, "weights").reshape(-1)
    if b0.shape != (N,) or w.shape != rows.shape:
        raise ValueError("beta0 needs one entry per track and rows/cols/weights one per pair")
    if not (np.isfinite(b0).all() and np.isfinite(w).all()) or (b0 < 0).any() or (w < 0).any():
        raise ValueError("association probabilities beta0/weights must be finite and ≥ 0")
    tot = b0.copy()
    np.add.at(tot, rows, w)
    bad = ~(np.abs(tot - 1.0) <= 1e-6)  # the PDA's tolerance (filters.pda), renormalised
    if bad.any():
        i = int(np.argmax(bad))
        raise ValueError(f"track {i}'s association probabilities sum to {tot[i]:.12g}, not 1")
    b0, w = b0 / tot, w / tot[rows]
    log_g, log_g_mode = imm_pair_log_likelihoods(modes, x, P, log_cbar, z, rows, cols, **kw)
    log_cbar = _log_probabilities(log_cbar, N, r, "log_cbar")
    # log(β_ik g_ijk / g_ik) per pair and mode; log β_i0 per track
    with np.errstate(divide="ignore"):
        log_w = np.log(w)[:, None] + log_g_mode - log_g[:, None]  # (K, r)
        log_b0 = np.log(b0)
    # log D_ij = log(β_i0 + Σ_k β_ik g_ijk/g_ik), per track and mode, in log space
    log_d = np.empty((N, r))
    for j in range(r):
        top = log_b0.copy()
        np.maximum.at(top, rows, log_w[:, j])
        top = np.where(np.isfinite(top), top, 0.0)
        acc = np.exp(log_b0 - top)
        np.add.at(acc, rows, np.exp(log_w[:, j] - top[rows]))
        with np.errstate(divide="ignore"):
            log_d[:, j] = np.log(acc) + top
    xu, Pu = np.empty_like(x), np.empty_like(P)
    for j in range(r):
        # mode-conditioned β: β_i0 / D_ij and β_ik g_ijk/g_ik / D_ij (each track sums to 1)
        with np.errstate(invalid="ignore"):
            bj0 = np.exp(log_b0 - log_d[:, j])
            wj = np.exp(log_w[:, j] - log_d[rows, j])
        xj, Pj = modes.to_mode(j, x[:, j], P[:, j])
        xj, Pj = pda_pairs_update(
            xj, Pj, z, bj0, rows, cols, wj, **modes.mode_measurement(j, H, R, model)
        )
        xu[:, j], Pu[:, j] = modes.from_mode(j, xj, Pj)
    return xu, Pu, imm_mode_update(log_cbar, log_d)


def imm_update(modes, x, P, log_cbar, z, H, R):
    """The IMM update with one measurement per track: ``(x⁺, P⁺, log μ⁺)``.

    Each mode's Kalman update (``z`` (N, m), a linear model ``H`` (m, n) in the
    common state, ``R`` (m, m)) and ``μ_j ∝ c̄_j N(z; H x_j, S_j)`` (eq.
    11.6.6-11 to 11.6.6-15).
    """
    x, P = _checked(modes, x, P)
    N, r, _ = x.shape
    log_cbar = _log_probabilities(log_cbar, N, r, "log_cbar")
    z = _arr(z, "z")
    if z.ndim != 2 or len(z) != N:
        raise ValueError(
            f"z must have one measurement per track (N, m) with N = {N}, got {z.shape}"
        )
    lam = np.empty((N, r))
    xu, Pu = np.empty_like(x), np.empty_like(P)
    for j in range(r):
        xj, Pj = modes.to_mode(j, x[:, j], P[:, j])
        kw = modes.mode_measurement(j, H, R)
        zhat, S = predict_measurement(xj, Pj, kw["H"], kw["R"])
        lam[:, j] = log_likelihood(z - zhat, S)
        xu[:, j], Pu[:, j] = modes.from_mode(j, *update(xj, Pj, z, kw["H"], kw["R"]))
    return xu, Pu, imm_mode_update(log_cbar, lam)
