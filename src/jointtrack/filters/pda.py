"""PDA / JPDA state update with association probabilities, batched over tracks.

Given a track's prediction ``(x, P)``, measurements ``z_1 … z_M`` and the
association probabilities ``β_0`` (no measurement is the track's) and
``β_j`` (measurement j is), ``Σ_j β_j = 1``, the PDA update
(Bar-Shalom & Tse 1975; Bar-Shalom, Willett & Tian 2011, PDAF; Bojilov et al.,
eq. (4) and the modified covariance update that follows it) is::

    ν_j = z_j − ẑ                           individual innovations
    ν   = Σ_{j≥1} β_j ν_j                   combined innovation        (Bojilov eq. (4))
    x⁺  = x + K ν
    P⁺  = β_0 P + (1 − β_0) P^c + K P̃ Kᵀ
    P̃   = Σ_{j≥1} β_j ν_j ν_jᵀ − ν νᵀ        spread of the innovations

with ``K = P Hᵀ S⁻¹`` the Kalman gain and ``P^c = (I − K H) P (I − K H)ᵀ + K R Kᵀ``
the covariance of a standard update (Joseph form). JPDA is the same update
with the β's computed jointly over a cluster (Bojilov, the JPDA extension of
(3)): every method of :mod:`jointtrack.association` returns them as an
``N × (M+1)`` matrix with column 0 the "no measurement" event.

``(x⁺, P⁺)`` are exactly the mean and covariance of the Gaussian mixture
``β_0 N(x, P) + Σ_j β_j N(x + K ν_j, P^c)``. The spread term is evaluated as
``Σ_{j≥1} β_j (ν_j − ν)(ν_j − ν)ᵀ + β_0 ν νᵀ`` — the same matrix, written as a
sum of positive semi-definite terms so that it cannot lose definiteness to
cancellation — and ``P⁺`` is symmetrised and guaranteed Cholesky-factorisable
(see the Numerics notes of :mod:`jointtrack.filters.kalman`).
"""

from __future__ import annotations

import numpy as np

from jointtrack.filters.kalman import (
    _apply,
    _arr,
    _ensure_pd,
    _gain,
    _joseph,
    _linear_model,
    _linearise,
    _out,
    _state,
    _sym,
)

__all__ = ["pda_ekf_update", "pda_pairs_update", "pda_update"]

_BETA_SUM_TOL = 1e-6  # accepted |Σ_j β_ij − 1|; rows are renormalised exactly


def _measurements(z, m: int) -> np.ndarray:
    z = _arr(z, "z")
    if z.size == 0:
        z = z.reshape(0, m)
    if z.ndim != 2 or z.shape[1] != m:
        raise ValueError(f"z must have shape (M, {m}) (all measurements), got {z.shape}")
    if not np.isfinite(z).all():
        j = int(np.argwhere(~np.isfinite(z))[0, 0])
        raise ValueError(f"measurement z[{j}] is not finite")
    return z


def _beta(beta, N: int, M: int, single: bool) -> np.ndarray:
    beta = _arr(beta, "beta")
    want = (M + 1,) if single else (N, M + 1)
    if beta.shape != want:
        raise ValueError(
            f"beta must have shape {want} (column 0 = no measurement, then one per "
            f"measurement), got {beta.shape}"
        )
    beta = beta[None] if single else beta
    who = (lambda i: "beta") if single else (lambda i: f"beta[{i}] (track {i})")
    bad = ~np.isfinite(beta).all(axis=1)
    if bad.any():
        raise ValueError(f"{who(int(np.argmax(bad)))} has non-finite entries")
    bad = (beta < 0).any(axis=1)
    if bad.any():
        raise ValueError(f"{who(int(np.argmax(bad)))} has negative association probabilities")
    tot = beta.sum(axis=1)
    bad = ~(np.abs(tot - 1.0) <= _BETA_SUM_TOL)
    if bad.any():
        i = int(np.argmax(bad))
        raise ValueError(
            f"{who(i)} sums to {tot[i]:.12g}, not 1: association probabilities of a track "
            "(no-measurement entry included) must sum to one"
        )
    return beta / tot[:, None]


def _pda_core(x, P, zhat, H, R, z, beta, residual, single):
    """Dense-β front of :func:`_pda_pairs_core`: the pairs that carry probability."""
    ti, mj = np.nonzero(beta[:, 1:] > 0)
    return _pda_pairs_core(
        x, P, zhat, H, R, z, beta[:, 0], ti, mj, beta[ti, 1 + mj], residual, single
    )


def _pda_pairs_core(x, P, zhat, H, R, z, b0, ti, mj, w, residual, single):
    """Shared linear/EKF PDA update on (track, measurement, β) pairs.

    x (N,n), P (N,n,n), ẑ (N,m), H (1|N,m,n), R (1|N,m,m); ``b0`` (N,) the
    no-measurement probabilities; pair k = (ti[k], mj[k]) has probability w[k].
    """
    N, m = zhat.shape
    _, L, K = _gain(P, H, R, not single)
    Pc = _joseph(P, K, H, R, L)
    nu_p = np.asarray(residual(z[mj], zhat[ti]), dtype=np.float64)  # (K, m)

    nu = np.zeros((N, m))
    np.add.at(nu, ti, w[:, None] * nu_p)  # ν_i = Σ_j β_ij ν_ij   (Bojilov eq. (4))
    dev = nu_p - nu[ti]
    spread = np.zeros((N, m, m))
    np.add.at(spread, ti, w[:, None, None] * dev[:, :, None] * dev[:, None, :])
    spread += b0[:, None, None] * nu[:, :, None] * nu[:, None, :]

    xu = x + np.einsum("kij,kj->ki", K, nu)
    Pu = (
        b0[:, None, None] * P + (1.0 - b0)[:, None, None] * Pc + K @ spread @ np.swapaxes(K, -1, -2)
    )
    return _out(xu, _ensure_pd(_sym(Pu)), single)


def pda_update(x, P, z, H, R, beta):
    """PDA / JPDA update of one track or a batch of tracks with a linear model.

        ν = Σ_{j≥1} β_j (z_j − H x)                       (Bojilov et al. eq. (4))
        x⁺ = x + K ν,    K = P Hᵀ S⁻¹,   S = H P Hᵀ + R
        P⁺ = β_0 P + (1 − β_0) P^c + K (Σ_j β_j ν_j ν_jᵀ − ν νᵀ) Kᵀ

    with ``P^c`` the Joseph-form standard update (Bar-Shalom, Willett & Tian
    2011, PDAF/JPDAF). Equal to the moments of the mixture
    ``β_0 N(x, P) + Σ_j β_j N(x + K ν_j, P^c)``.

    Parameters
    ----------
    x, P : one track (n,), (n, n) or a batch (N, n), (N, n, n)
        predicted states and covariances.
    z : (M, m)
        all measurements of the cluster or scan (shared by the tracks).
    H : (m, n) or (N, m, n)
    R : (m, m) or (N, m, m), symmetric positive definite
    beta : (M+1,) for one track, (N, M+1) for a batch
        association probabilities, column 0 = no measurement; each row sums to 1
        (to 1e-6; rows are renormalised). A track uses only the measurements with
        ``beta > 0``, so the full JPDA matrix of a cluster or a scan can be passed
        once for all tracks (ragged gates).

    Returns
    -------
    (x⁺, P⁺) shaped like (x, P). A track with ``β_0 = 1`` keeps its prediction.
    """
    x, P, single = _state(x, P)
    H, R = _linear_model(H, R, x.shape, single)
    z = _measurements(z, H.shape[1])
    beta = _beta(beta, x.shape[0], z.shape[0], single)
    zhat = _apply(H, x)
    return _pda_core(x, P, zhat, H, R, z, beta, np.subtract, single)


def pda_ekf_update(x, P, z, model, beta):
    """PDA / JPDA update through an EKF linearisation at each track's prediction.

        H_i = ∂h/∂x |_{x_i},   ν_ij = residual(z_j, h(x_i))   (angles wrapped)
        ν_i = Σ_{j≥1} β_ij ν_ij                            (Bojilov et al. eq. (4))
        x_i⁺ = x_i + K_i ν_i,  P_i⁺ = β_i0 P_i + (1 − β_i0) P_i^c
                                     + K_i (Σ_j β_ij ν_ij ν_ijᵀ − ν_i ν_iᵀ) K_iᵀ

    (Bar-Shalom, Willett & Tian 2011, PDAF with EKF). Arguments as
    :func:`pda_update`, with ``model`` a :mod:`jointtrack.models` measurement
    model (``h``, ``jacobian``, ``residual``, ``R``) in place of ``H, R``.
    """
    x, P, single = _state(x, P)
    zhat, H, R = _linearise(x, model, single)
    z = _measurements(z, zhat.shape[1])
    beta = _beta(beta, x.shape[0], z.shape[0], single)
    return _pda_core(x, P, zhat, H, R, z, beta, model.residual, single)


def pda_pairs_update(x, P, z, beta0, rows, cols, weights, *, H=None, R=None, model=None):
    """:func:`pda_update` (``H``, ``R``) or :func:`pda_ekf_update` (``model``) on sparse β.

    For scans with thousands of tracks and returns, where the dense N × (M+1)
    β matrix would not fit: ``beta0`` (N,) are the no-measurement
    probabilities and pair k says that measurement ``cols[k]`` is track
    ``rows[k]``'s with probability ``weights[k]``; each track's ``beta0`` plus
    its pair weights must sum to 1 (to 1e-6; renormalised exactly). Same
    equations as :func:`pda_update` (Bojilov et al. eq. (4)).
    """
    if (H is None) == (model is None):
        raise ValueError("give either H and R (linear) or model (EKF)")
    x, P, single = _state(x, P)
    if single:
        raise ValueError("pda_pairs_update works on a batch: x (N, n), P (N, n, n)")
    N = x.shape[0]
    if model is None:
        H, R = _linear_model(H, R, x.shape, single)
        zhat, residual = _apply(H, x), np.subtract
    else:
        zhat, H, R = _linearise(x, model, single)
        residual = model.residual
    z = _measurements(z, zhat.shape[1])
    b0 = _arr(beta0, "beta0").reshape(-1)
    rows = np.asarray(rows, np.int64).reshape(-1)
    cols = np.asarray(cols, np.int64).reshape(-1)
    w = _arr(weights, "weights").reshape(-1)
    if b0.shape != (N,) or not (rows.shape == cols.shape == w.shape):
        raise ValueError("beta0 needs one entry per track and rows/cols/weights one per pair")
    if rows.size and (rows.min() < 0 or rows.max() >= N or cols.min() < 0 or cols.max() >= len(z)):
        raise ValueError("rows/cols index outside the tracks/measurements")
    if not (np.isfinite(b0).all() and np.isfinite(w).all()) or (b0 < 0).any() or (w < 0).any():
        raise ValueError("association probabilities must be finite and non-negative")
    tot = b0.copy()
    np.add.at(tot, rows, w)
    bad = ~(np.abs(tot - 1.0) <= _BETA_SUM_TOL)
    if bad.any():
        i = int(np.argmax(bad))
        raise ValueError(f"track {i}'s association probabilities sum to {tot[i]:.12g}, not 1")
    keep = w > 0
    return _pda_pairs_core(
        x,
        P,
        zhat,
        H,
        R,
        z,
        b0 / tot,
        rows[keep],
        cols[keep],
        w[keep] / tot[rows[keep]],
        residual,
        single,
    )
