"""Kalman and extended Kalman filter steps, batched over tracks.

Shapes
------
Every function takes either one track or a batch of N tracks:

=========  ===================  ==========================
argument   one track            N tracks
=========  ===================  ==========================
``x``      (n,)                 (N, n)
``P``      (n, n)               (N, n, n)
``z``      (m,)                 (N, m)  (one measurement per track)
``F, Q``   (n, n)               (n, n) shared or (N, n, n)
``H, R``   (m, n), (m, m)       shared or (N, m, n), (N, m, m)
=========  ===================  ==========================

and returns arrays of the matching shape. Model matrices come from
:mod:`jointtrack.models` (state layout: positions first).

Numerics
--------
* Covariance updates use the Joseph form and the result is symmetrised, so
  covariances stay symmetric positive semi-definite even when the gain is
  computed inaccurately (Bar-Shalom, Li & Kirubarajan 2001, Joseph form).
* Long gaps (Δt up to the model's ``max_dt``, covariances spanning 60+ orders of
  magnitude): the prediction is formed from a Cholesky factor,
  ``P⁻ = (F L)(F L)ᵀ + Q``, and the Joseph form as the Gram matrix of
  ``[(I − K H) L, K L_R]``, so neither can cancel into an indefinite matrix; for a
  measurement matrix with orthonormal rows (position measurements) the measured
  rows of ``I − K H`` are ``R S⁻¹ H``, not ``1 − (1 − R/S)``. Every covariance
  returned by ``predict``, ``update``, ``ekf_update`` and the PDA updates, for
  every finite ``dt``, is exactly symmetric and positive definite with margin: its
  correlation matrix ``D^{-1/2} P D^{-1/2}`` minus ``4 n² ε I`` factorises by
  Cholesky, which certifies that the stored floats form a positive definite matrix
  in exact arithmetic (a bare Cholesky success does not: after a long gap it can
  succeed on a matrix that is indefinite in its last bits). Where the exact result
  is singular to working precision (e.g. ``F P Fᵀ`` with ``q = 0`` and a long gap)
  only its near-null correlation eigenvalues are raised to that margin
  (``_ensure_pd``); every other covariance is returned bit for bit. A prediction
  that overflows raises ``ValueError`` asking for a smaller ``dt``.
* The innovation covariance ``S`` is factorised once by Cholesky, ``S = L Lᵀ``;
  the gain and the log-likelihood use triangular solves with ``L``. No matrix is
  inverted and no determinant is formed.
* Bad input — wrong shapes, non-finite numbers, covariances that are asymmetric,
  not positive (semi-)definite or singular — raises ``ValueError`` naming the
  argument and, for batches, the track index.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from jointtrack._numba_linalg import cholesky_lower

__all__ = [
    "ekf_innovation",
    "ekf_predict_measurement",
    "ekf_update",
    "innovation",
    "log_likelihood",
    "predict",
    "predict_measurement",
    "update",
]

_LOG_2PI = float(np.log(2.0 * np.pi))
_EPS = float(np.finfo(np.float64).eps)
_SYM_TOL = 1e-9  # relative asymmetry accepted (and removed) in input covariances
_PSD_TOL = 1e-10  # relative negative eigenvalue tolerated in PSD inputs


# ----------------------------------------------------------------------------- checks


def _arr(a, name: str) -> np.ndarray:
    try:
        return np.asarray(a, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a numeric array") from None


def _who(name: str, i, batched: bool) -> str:
    return f"{name}[{i}] (track {i})" if batched else name


def _check_finite(a: np.ndarray, name: str, batched: bool) -> None:
    """a has the track index first if batched."""
    if a.size and not np.isfinite(a).all():
        if batched:
            i = int(np.argwhere(~np.isfinite(a))[0, 0])
            raise ValueError(f"{_who(name, i, True)} has non-finite entries")
        raise ValueError(f"{name} has non-finite entries")


def _check_sym(A: np.ndarray, name: str, batched: bool) -> np.ndarray:
    """Finite and symmetric to ``_SYM_TOL`` (relative); returns the symmetrised stack.

    ``A`` is (K, d, d); ``batched`` says whether K indexes tracks.
    """
    if A.shape[0] == 0:
        return A
    At = np.swapaxes(A, -1, -2)
    if (A == At).all():  # exactly symmetric (every covariance a filter returns): no asymmetry
        _check_finite(A, name, batched)
        return 0.5 * (A + At)
    _check_finite(A, name, batched)
    k = A.shape[0]
    asym = np.abs(A - At).reshape(k, -1).max(axis=1)
    scale = np.abs(A).reshape(k, -1).max(axis=1)
    bad = asym > _SYM_TOL * scale
    if bad.any():
        i = int(np.argmax(bad))
        raise ValueError(
            f"{_who(name, i, batched)} is not symmetric (max |A − Aᵀ| = {asym[i]:.3g}, "
            f"max |A| = {scale[i]:.3g})"
        )
    return 0.5 * (A + At)


def _check_psd(A: np.ndarray, name: str, batched: bool) -> None:
    """Positive semi-definite up to a relative tolerance (A symmetric, (K, d, d)).

    The test is a Cholesky factorisation of the correlation-scaled matrix
    ``D^{-1/2} A D^{-1/2} + tol·I``, so it does not depend on the units of the
    state components.
    """
    if A.shape[0] == 0:
        return
    # compiled: numpy's scaling and a batched LAPACK call (~0.5 µs per small matrix)
    # were most of a tracker's scan, which checks ~100 track covariances several times
    i, negative = _psd_failure(A, _PSD_TOL)
    if negative:
        raise ValueError(
            f"{_who(name, i, batched)} is not positive semi-definite (negative variance)"
        )
    if i >= 0:
        raise ValueError(f"{_who(name, i, batched)} is not positive semi-definite")


@njit(cache=True)
def _psd_failure(A, tol):
    """``(i, negative)``: the first matrix of the stack ``A`` (K, d, d) failing :func:`_check_psd`.

    First the first matrix with a negative variance (``negative`` True), else the
    first whose scaled matrix ``D^{-1/2} A D^{-1/2} + tol·I`` has no Cholesky
    factor; ``(-1, False)`` when all pass. Zero variances are scaled by 1.
    """
    k, d = A.shape[0], A.shape[1]
    for i in range(k):
        for a in range(d):
            if A[i, a, a] < 0.0:
                return i, True
    s = np.empty(d)
    C = np.empty((d, d))
    L = np.empty((d, d))
    for i in range(k):
        for a in range(d):
            v = A[i, a, a]
            s[a] = math.sqrt(v) if v > 0.0 else 1.0
        for a in range(d):
            for b in range(d):
                C[a, b] = A[i, a, b] / (s[a] * s[b])
            C[a, a] += tol
        ok, _ = cholesky_lower(C, L)
        if not ok:
            return i, False
    return -1, False


def _chol_pd(S: np.ndarray, name: str, batched: bool) -> np.ndarray:
    """Lower Cholesky factors of a stack (K, m, m) of symmetric positive definite matrices.

    Raises ValueError (naming the track) if a matrix is not positive definite or
    is numerically singular (reciprocal condition estimate (min Lᵢᵢ / max Lᵢᵢ)² below
    m·ε).
    """
    if S.shape[0] == 0:
        return S.copy()
    L = None
    try:
        L = np.linalg.cholesky(S)
    except np.linalg.LinAlgError:
        pass
    if L is None or not np.isfinite(L).all():
        for i in range(S.shape[0]):
            try:
                c = np.linalg.cholesky(S[i])
            except np.linalg.LinAlgError:
                c = None
            if c is None or not np.isfinite(c).all():
                raise ValueError(f"{_who(name, i, batched)} is not positive definite") from None
        raise AssertionError("unreachable")  # pragma: no cover
    dg = np.diagonal(L, axis1=-2, axis2=-1)
    rc = (dg.min(axis=1) / dg.max(axis=1)) ** 2
    sing = ~(rc > S.shape[-1] * _EPS)
    if sing.any():
        i = int(np.argmax(sing))
        raise ValueError(
            f"{_who(name, i, batched)} is numerically singular (reciprocal condition ≈ {rc[i]:.2g})"
        )
    return L


def _state(x, P):
    """Validate and batch (x, P). Returns (x (N,n), P (N,n,n), single)."""
    x = _arr(x, "x")
    P = _arr(P, "P")
    if x.ndim == 1:
        n = x.shape[0]
        if P.shape != (n, n):
            raise ValueError(
                f"P must have shape ({n}, {n}) to match x of shape {x.shape}, got {P.shape}"
            )
        x, P, single = x[None], P[None], True
    elif x.ndim == 2:
        N, n = x.shape
        if P.shape != (N, n, n):
            raise ValueError(
                f"P must have shape ({N}, {n}, {n}) to match x of shape {x.shape}, got {P.shape}"
            )
        single = False
    else:
        raise ValueError(f"x must be (n,) for one track or (N, n) for N tracks, got {x.shape}")
    if x.shape[1] < 1:
        raise ValueError("state dimension must be at least 1")
    _check_finite(x, "x", not single)
    P = _check_sym(P, "P", not single)
    _check_psd(P, "P", not single)
    return x, P, single


def _model_matrix(A, N: int, shape: tuple, name: str, single: bool, *, kind: str | None = None):
    """A shared (r, c) matrix or a per-track (N, r, c) stack, validated.

    ``kind``: None (any matrix), "psd" or "pd" (symmetric covariances). Returns a
    (1, r, c) or (N, r, c) array that broadcasts against the track batch.
    """
    A = _arr(A, name)
    if A.shape == shape:
        A, per_track = A[None], False
    elif not single and A.shape == (N, *shape):
        per_track = True
    else:
        want = f"{shape}" if single else f"{shape} or {(N, *shape)}"
        raise ValueError(f"{name} must have shape {want}, got {A.shape}")
    if kind is None:
        _check_finite(A, name, per_track)
    else:
        A = _check_sym(A, name, per_track)
        if kind == "psd":
            _check_psd(A, name, per_track)
        else:
            _chol_pd(A, name, per_track)
    return A


def _meas(z, N: int, m: int, single: bool, name: str = "z") -> np.ndarray:
    z = _arr(z, name)
    want = (m,) if single else (N, m)
    if z.shape != want:
        raise ValueError(f"{name} must have shape {want}, got {z.shape}")
    z = z[None] if single else z
    _check_finite(z, name, not single)
    return z


def _linear_model(H, R, xshape, single):
    """Validate a linear measurement model (H, R) against states of shape (N, n)."""
    N, n = xshape
    H = _arr(H, "H")
    if H.ndim not in (2, 3) or H.shape[-1] != n:
        want = f"(m, {n})" if single else f"(m, {n}) or ({N}, m, {n})"
        raise ValueError(f"H must have shape {want} to match the state, got {H.shape}")
    m = H.shape[-2]
    H = _model_matrix(H, N, (m, n), "H", single)
    R = _model_matrix(R, N, (m, m), "R", single, kind="pd")
    return H, R


def _linear_inputs(x, P, z, H, R):
    """Validate and batch a linear update's inputs: (x, P, z, H, R, single)."""
    x, P, single = _state(x, P)
    H, R = _linear_model(H, R, x.shape, single)
    z = _meas(z, x.shape[0], H.shape[1], single)
    return x, P, z, H, R, single


def _apply(A, x):
    """A x for a shared (1, r, c) or per-track (N, r, c) matrix and x (N, c)."""
    if A.shape[0] == 1:
        return x @ A[0].T
    return np.einsum("kij,kj->ki", A, x)


def _out(x, P, single):
    return (x[0], P[0]) if single else (x, P)


# ----------------------------------------------------------------------------- linear algebra


def _solve_lower(L: np.ndarray, B: np.ndarray) -> np.ndarray:
    """L⁻¹ B by forward substitution; L (..., m, m) lower, B (..., m, k). Broadcasts."""
    m = L.shape[-1]
    shape = np.broadcast_shapes(L.shape[:-2], B.shape[:-2]) + B.shape[-2:]
    X = np.empty(shape)
    for i in range(m):
        acc = B[..., i, :]
        for j in range(i):
            acc = acc - L[..., i, j, None] * X[..., j, :]
        X[..., i, :] = acc / L[..., i, i, None]
    return X


def _solve_upper_t(L: np.ndarray, B: np.ndarray) -> np.ndarray:
    """L⁻ᵀ B by back substitution; L (..., m, m) lower, B (..., m, k). Broadcasts."""
    m = L.shape[-1]
    shape = np.broadcast_shapes(L.shape[:-2], B.shape[:-2]) + B.shape[-2:]
    X = np.empty(shape)
    for i in range(m - 1, -1, -1):
        acc = B[..., i, :]
        for j in range(i + 1, m):
            acc = acc - L[..., j, i, None] * X[..., j, :]
        X[..., i, :] = acc / L[..., i, i, None]
    return X


def _sym(A: np.ndarray) -> np.ndarray:
    return 0.5 * (A + np.swapaxes(A, -1, -2))


def _congruence(A, P, Q):
    """A P Aᵀ + Q, symmetrised: the predicted covariance (A = F) or the innovation one (A = H)."""
    return _sym(A @ P @ np.swapaxes(A, -1, -2) + Q)


def _gain(P, H, R, batched: bool):
    """S = H P Hᵀ + R, its Cholesky factor L and the gain K = P Hᵀ S⁻¹.

    K is formed as Kᵀ = L⁻ᵀ (L⁻¹ (H P)) with two triangular solves.
    """
    HP = H @ P  # (N, m, n)
    S = _sym(HP @ np.swapaxes(H, -1, -2) + R)
    L = _chol_pd(S, "innovation covariance S", batched)
    Kt = _solve_upper_t(L, _solve_lower(L, HP))
    return S, L, np.swapaxes(Kt, -1, -2)


def _factor(P):
    """A square-root factor W, W Wᵀ = P, of a stack (K, n, n) of symmetric PSD matrices.

    Cholesky where it succeeds (always for the positive definite covariances the
    filters return); for a singular P an eigen-factor of the correlation-scaled
    matrix with the (rounding-level) negative eigenvalues clipped to zero.
    """
    try:
        return np.linalg.cholesky(P)
    except np.linalg.LinAlgError:
        pass
    W = np.empty_like(P)
    for i in range(P.shape[0]):
        try:
            W[i] = np.linalg.cholesky(P[i])
        except np.linalg.LinAlgError:
            d = np.diagonal(P[i])
            s = np.sqrt(np.where(d > 0, d, 1.0))
            w, V = np.linalg.eigh(P[i] / (s[:, None] * s[None, :]))
            W[i] = s[:, None] * V * np.sqrt(np.clip(w, 0.0, None))
    return W


def _pd_margin(n: int) -> float:
    """Smallest eigenvalue kept in a returned covariance's correlation matrix.

    ``4 n² ε`` bounds the rounding of forming ``D^{-1/2} P D^{-1/2}`` and of its
    Cholesky factorisation (backward error ≤ n(n + 1) ε in the 2-norm for a
    unit-diagonal matrix), so a correlation matrix whose Cholesky factorisation
    succeeds after this shift is positive definite in exact arithmetic — and so is
    the stored float matrix ``P``.
    """
    return 4.0 * n * n * _EPS


def _ensure_pd(P):
    """Return the symmetric stack P (K, n, n) with every matrix positive definite with margin.

    A covariance that is positive definite in exact arithmetic can come out of the
    filter's rounding indefinite, or positive definite only by luck of the last
    bits, when its correlation matrix ``C = D^{-1/2} P D^{-1/2}`` is singular to
    working precision — e.g. ``F P Fᵀ`` after a long gap (position-velocity
    correlation 1 − O(1/Δt²)), or its updates in the scans after the gap. The test
    is scale-free: ``C − τ I`` must factorise by Cholesky, ``τ = 4 n² ε``
    (:func:`_pd_margin`), which certifies that the stored float matrix is positive
    definite in exact arithmetic (so every later Cholesky, triangular solve and
    determinant of it is well defined, whatever the units or the gap). A matrix
    that fails gets the eigenvalues of ``C`` below ``2τ`` raised to ``2τ`` (the
    nearest such matrix in the Frobenius norm; only the near-null directions,
    i.e. changes of relative size ~1e-14, move), retried with a 4× larger floor
    until the test passes. Matrices with a zero variance (legitimately singular,
    e.g. a component known exactly) and matrices that pass are returned
    unchanged, so the common case costs one scaling and one batched Cholesky.
    """
    if P.shape[0] == 0:
        return P
    tau = _pd_margin(P.shape[-1])
    ok = _pd_with_margin(P, tau)
    if ok.all():
        return P
    P = P.copy()
    n = P.shape[-1]
    for i in np.flatnonzero(~ok):
        d = np.diagonal(P[i]).copy()
        if not (d > 0).all():
            continue  # a zero variance: positive semi-definite by construction
        s = np.sqrt(d)
        w, V = np.linalg.eigh(_sym(P[i] / (s[:, None] * s[None, :])))
        floor = 2.0 * tau
        while True:
            C = (V * np.maximum(w, floor)) @ V.T
            Pi = _sym(s[:, None] * C * s[None, :])
            if _pd_with_margin(Pi[None], tau)[0] or floor > n:
                break
            floor *= 4.0
        P[i] = Pi
    return P


def _pd_with_margin(P, tau):
    """(K,) bool: which matrices of P (K, n, n) have correlation matrices with C − τI ≻ 0.

    Tested as a Cholesky factorisation of ``P − τ diag(P)`` = ``D^{1/2} (C − τ I) D^{1/2}``:
    diagonal scaling changes neither the signs of the pivots nor (to first order)
    the componentwise backward error of Cholesky, so this is the scale-free test
    without forming C. A zero or negative variance fails.
    """
    n = P.shape[-1]
    M = P.copy()  # C-contiguous: the diagonal of every matrix is a stride-(n+1) slice
    M.reshape(P.shape[0], n * n)[:, :: n + 1] *= 1.0 - tau
    try:
        np.linalg.cholesky(M)
        return np.ones(P.shape[0], bool)
    except np.linalg.LinAlgError:
        pass
    ok = np.zeros(P.shape[0], bool)
    for k in range(P.shape[0]):
        try:
            np.linalg.cholesky(M[k])
            ok[k] = True
        except np.linalg.LinAlgError:
            pass
    return ok


def _complement(K, H, R, L):
    """I − K H for the Joseph form.

    When H has orthonormal rows (a position measurement ``[I 0]``, any motion
    model), the measured rows are formed as ``Hᵀ R S⁻¹ H`` — the identity
    ``H (I − K H) = R S⁻¹ H`` — instead of ``1 − (1 − R/S)``, which cancels to
    rounding noise once the prior variance exceeds R by 1/ε (long gaps); the
    other rows are ``(I − HᵀH)(I − K H)``, which has no cancellation.
    """
    A = np.eye(K.shape[-2]) - K @ H
    Ht = np.swapaxes(H, -1, -2)
    if L is None or H.shape[0] == 0 or np.abs(H @ Ht - np.eye(H.shape[-2])).max() > 4 * _EPS:
        return A
    SiR = _solve_upper_t(L, _solve_lower(L, np.broadcast_to(R, L.shape)))  # S⁻¹ R
    Pi = Ht @ H  # projector onto the measured coordinates
    return (np.eye(K.shape[-2]) - Pi) @ A + Ht @ np.swapaxes(SiR, -1, -2) @ H


def _joseph(P, K, H, R, L=None):
    """Joseph form (I − K H) P (I − K H)ᵀ + K R Kᵀ, symmetrised.

    Evaluated as the Gram matrix ``W Wᵀ`` of ``W = [(I − K H) L_P, K L_R]`` with
    ``L_P``, ``L_R`` square-root factors of P and R, so that it is positive
    semi-definite up to rounding relative to its own diagonal even when P spans
    many orders of magnitude (e.g. after a long prediction gap). ``L``, the
    Cholesky factor of S, enables the accurate ``I − K H`` of :func:`_complement`.
    """
    M = _complement(K, H, R, L) @ _factor(P)
    KL = K @ np.linalg.cholesky(R)
    G = M @ np.ascontiguousarray(np.swapaxes(M, -1, -2))
    G += KL @ np.ascontiguousarray(np.swapaxes(KL, -1, -2))
    return _sym(G)


# ----------------------------------------------------------------------------- public API


def predict(x, P, F, Q):
    """Kalman prediction of one track or a batch (Bar-Shalom, Willett & Tian 2011):

        x⁻ = F x,        P⁻ = F P Fᵀ + Q   (symmetrised)

    Parameters
    ----------
    x : (n,) or (N, n)
    P : (n, n) or (N, n, n), symmetric positive semi-definite
    F : (n, n) or (N, n, n) transition matrix (e.g. ``ConstantVelocity.transition(dt)``)
    Q : (n, n) or (N, n, n) process noise, symmetric positive semi-definite

    Returns
    -------
    (x⁻, P⁻) shaped like (x, P).
    """
    x, P, single = _state(x, P)
    N, n = x.shape
    F = _model_matrix(F, N, (n, n), "F", single)
    Q = _model_matrix(Q, N, (n, n), "Q", single, kind="psd")
    xp = _apply(F, x)
    # P⁻ = (F L)(F L)ᵀ + Q with P = L Lᵀ: a Gram matrix plus Q, so no cancellation
    # in F P Fᵀ can make it indefinite (long gaps: F has entries Δt, Δt²/2).
    with np.errstate(over="ignore", invalid="ignore"):
        FL = F @ _factor(P)
        Pp = _sym(FL @ np.ascontiguousarray(np.swapaxes(FL, -1, -2)) + Q)
    if not (np.isfinite(Pp).all() and np.isfinite(xp).all()):
        bad = ~(np.isfinite(Pp).all(axis=(1, 2)) & np.isfinite(xp).all(axis=1))
        i = int(np.argmax(bad))
        raise ValueError(
            f"predicted {_who('covariance', i, not single)} overflows (non-finite entries): "
            "the time step dt of F and Q is too large for this covariance"
        )
    return _out(xp, _ensure_pd(Pp), single)


def predict_measurement(x, P, H, R):
    """Predicted measurement and innovation covariance of a linear model:

        ẑ = H x,        S = H P Hᵀ + R   (symmetrised)

    (Bar-Shalom, Willett & Tian 2011). ``(ẑ, S)`` are the gate centres and
    covariances for :func:`jointtrack.association.gating.gate_measurements`.

    Returns
    -------
    (ẑ, S): (m,), (m, m) for one track; (N, m), (N, m, m) for a batch.
    """
    x, P, single = _state(x, P)
    H, R = _linear_model(H, R, x.shape, single)
    S = _congruence(H, P, R)
    return _out(_apply(H, x), S, single)


def innovation(x, P, z, H, R):
    """Innovation and its covariance for a linear measurement model:

        ν = z − H x,     S = H P Hᵀ + R   (symmetrised)

    (Bar-Shalom, Willett & Tian 2011; Bojilov et al. z̃_ij under eq. (4)).

    Parameters
    ----------
    x, P : one track (n,), (n, n) or a batch (N, n), (N, n, n)
    z : (m,) or (N, m), one measurement per track
    H : (m, n) or (N, m, n)
    R : (m, m) or (N, m, m), symmetric positive definite

    Returns
    -------
    (ν, S): (m,), (m, m) or (N, m), (N, m, m).
    """
    x, P, z, H, R, single = _linear_inputs(x, P, z, H, R)
    S = _congruence(H, P, R)
    return _out(z - _apply(H, x), S, single)


def update(x, P, z, H, R):
    """Kalman measurement update (Bar-Shalom, Willett & Tian 2011; Bar-Shalom & Li 1995):

        S = H P Hᵀ + R,   K = P Hᵀ S⁻¹,   x⁺ = x + K (z − H x),
        P⁺ = (I − K H) P (I − K H)ᵀ + K R Kᵀ        (Joseph form, symmetrised)

    ``K`` is computed from the Cholesky factor of ``S`` (no inverse).

    Parameters
    ----------
    x, P : one track (n,), (n, n) or a batch (N, n), (N, n, n)
    z : (m,) or (N, m), one measurement per track
    H : (m, n) or (N, m, n)
    R : (m, m) or (N, m, m), symmetric positive definite

    Returns
    -------
    (x⁺, P⁺) shaped like (x, P).
    """
    x, P, z, H, R, single = _linear_inputs(x, P, z, H, R)
    return _update_core(x, P, z - _apply(H, x), H, R, single)


def _update_core(x, P, nu, H, R, single):
    _, L, K = _gain(P, H, R, not single)
    xu = x + np.einsum("kij,kj->ki", K, nu)
    Pu = _ensure_pd(_joseph(P, K, H, R, L))
    return _out(xu, Pu, single)


def log_likelihood(nu, S):
    """Gaussian log density of innovations, log N(ν; 0, S), batched.

        log N(ν; 0, S) = −½ νᵀ S⁻¹ ν − ½ log|2π S|
                       = −½ ‖L⁻¹ ν‖² − Σᵢ log Lᵢᵢ − (m/2) log 2π,   S = L Lᵀ

    (the measurement likelihood g_ij of Bojilov et al. eq. (2); Bar-Shalom,
    Willett & Tian 2011). Evaluated with a Cholesky factor only, so it is
    accurate for ill-conditioned ``S`` and never under/overflows before the log.

    Parameters
    ----------
    nu : (..., m)
        innovations.
    S : (..., m, m)
        innovation covariances, symmetric positive definite. The leading
        dimensions of ``nu`` and ``S`` broadcast: e.g. ``nu`` (N, M, m) with
        ``S[:, None]`` (N, 1, m, m) gives the (N, M) track × measurement table.

    Returns
    -------
    float or array of shape ``broadcast(nu.shape[:-1], S.shape[:-2])``.
    """
    nu = _arr(nu, "nu")
    S = _arr(S, "S")
    if S.ndim < 2 or S.shape[-1] != S.shape[-2]:
        raise ValueError(f"S must be (..., m, m), got shape {S.shape}")
    m = S.shape[-1]
    if nu.ndim < 1 or nu.shape[-1] != m:
        raise ValueError(f"nu must be (..., {m}) to match S of shape {S.shape}, got {nu.shape}")
    try:
        batch = np.broadcast_shapes(nu.shape[:-1], S.shape[:-2])
    except ValueError:
        raise ValueError(
            f"leading dimensions of nu {nu.shape} and S {S.shape} do not broadcast"
        ) from None
    if nu.size and not np.isfinite(nu).all():
        idx = tuple(int(v) for v in np.argwhere(~np.isfinite(nu))[0][:-1])
        raise ValueError(f"nu{list(idx)} has non-finite entries")
    batched = S.ndim == 3
    Sf = S.reshape(-1, m, m)
    try:
        Sf = _check_sym(Sf, "S", batched)
        L = _chol_pd(Sf, "S", batched)
    except ValueError as exc:
        if S.ndim > 3:  # name the multi-index instead of the flat one
            raise ValueError(f"{exc} (flat index into S.shape[:-2] = {S.shape[:-2]})") from None
        raise
    L = L.reshape(S.shape)
    w = _solve_lower(L, nu[..., None])[..., 0]
    half_logdet = np.log(np.diagonal(L, axis1=-2, axis2=-1)).sum(axis=-1)
    ll = -0.5 * np.einsum("...i,...i->...", w, w) - half_logdet - 0.5 * m * _LOG_2PI
    ll = np.broadcast_to(ll, batch)
    return float(ll) if ll.ndim == 0 else ll.copy()


# ----------------------------------------------------------------------------- EKF


def _check_model(model):
    for attr in ("h", "jacobian", "residual", "R"):
        if not hasattr(model, attr):
            raise ValueError(
                f"measurement model {model!r} lacks '{attr}'; expected the interface of "
                "jointtrack.models (h, jacobian, residual, R)"
            )


def _linearise(x, model, single):
    """ẑ = h(x), H = ∂h/∂x at x, R, for a batch x (N, n)."""
    _check_model(model)
    n = x.shape[1]
    if getattr(model, "state_dim", n) != n:
        raise ValueError(f"model expects state_dim {model.state_dim}, but x has {n} components")
    zhat = np.asarray(model.h(x), dtype=np.float64)
    H = np.asarray(model.jacobian(x), dtype=np.float64)
    N = x.shape[0]
    if zhat.ndim != 2 or zhat.shape[0] != N:
        raise ValueError(f"model.h returned shape {zhat.shape}, expected (N, m) with N = {N}")
    m = zhat.shape[1]
    if H.shape != (N, m, n):
        raise ValueError(f"model.jacobian returned shape {H.shape}, expected {(N, m, n)}")
    _check_finite(zhat, "h(x)", not single)
    _check_finite(H, "jacobian(x)", not single)
    R = _model_matrix(model.R, N, (m, m), "R", single, kind="pd")
    return zhat, H, R


def _ekf_inputs(x, P, z, model):
    """Validate and batch an EKF update's inputs, linearise: (x, P, ν, H, R, single)."""
    x, P, single = _state(x, P)
    zhat, H, R = _linearise(x, model, single)
    z = _meas(z, x.shape[0], zhat.shape[1], single)
    nu = np.asarray(model.residual(z, zhat), dtype=np.float64)
    return x, P, nu, H, R, single


def ekf_predict_measurement(x, P, model):
    """EKF predicted measurement and innovation covariance (Bar-Shalom & Li 1995):

        ẑ = h(x),    H = ∂h/∂x |ₓ,    S = H P Hᵀ + R   (symmetrised)

    ``model`` is a :mod:`jointtrack.models` measurement model (``h``,
    ``jacobian``, ``residual``, ``R``). Returns ``(ẑ, S)`` shaped like
    :func:`predict_measurement`.
    """
    x, P, single = _state(x, P)
    zhat, H, R = _linearise(x, model, single)
    S = _congruence(H, P, R)
    return _out(zhat, S, single)


def ekf_innovation(x, P, z, model):
    """EKF innovation and covariance (Bar-Shalom & Li 1995):

        ν = residual(z, h(x))  (angles wrapped to (−π, π]),   S = H P Hᵀ + R

    with ``H`` the Jacobian of ``h`` at ``x``. Shapes as :func:`innovation`.
    """
    x, P, nu, H, R, single = _ekf_inputs(x, P, z, model)
    S = _congruence(H, P, R)
    return _out(nu, S, single)


def ekf_update(x, P, z, model):
    """Extended Kalman filter update (Bar-Shalom & Li 1995; Bar-Shalom, Willett & Tian 2011):

        H = ∂h/∂x |ₓ,   ν = residual(z, h(x)),   S = H P Hᵀ + R,   K = P Hᵀ S⁻¹,
        x⁺ = x + K ν,   P⁺ = (I − K H) P (I − K H)ᵀ + K R Kᵀ   (Joseph, symmetrised)

    The residual wraps angular components to (−π, π] (e.g. the bearing of
    :class:`jointtrack.models.RangeBearing`); with a linear model
    (:class:`jointtrack.models.LinearPosition`) this is exactly :func:`update`.

    Parameters
    ----------
    x, P : one track (n,), (n, n) or a batch (N, n), (N, n, n)
    z : (m,) or (N, m), one measurement per track
    model : measurement model with ``h``, ``jacobian``, ``residual``, ``R``

    Returns
    -------
    (x⁺, P⁺) shaped like (x, P).
    """
    x, P, nu, H, R, single = _ekf_inputs(x, P, z, model)
    return _update_core(x, P, nu, H, R, single)
