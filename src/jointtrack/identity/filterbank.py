"""Per-track filter banks of joint identification: the coefficients a, b of the matrix M.

Reference: D. E. Schaub, "Joint Identification of Multiple Tracked Targets",
*Journal of Advances in Information Fusion*, vol. 12, no. 1, 2017. Equation
numbers below are that paper's.

What a filter bank keeps (§2-B, eqs. 20, 27–29)
-----------------------------------------------
Each observed track t runs one filter per identity i on the kinematic state,
with the identity's own motion model and static attribute
(:mod:`jointtrack.identity.database`), and keeps two running products:

* ``a[t, i] = Π_k K_{t,i}^k`` (eq. 27), with the likelihood factor (eq. 29)
  ``K = ∫ g_i(x) pred_i(x) dx`` and ``g_i(x) = p_f + p_d,i f(z | x)`` (eq. 26);
* ``b[t] = Π_k p_f^k`` (eqs. 27, 29), which is 0 once any measurement with
  ``p_f = 0`` has been associated: the track is then certain to exist
  (Appendix B-B).

Identically modelled identities (one equivalence class) have identical
filters, so a bank runs one filter per *class*; the class columns are then
exactly equal by construction. Everything is kept in log space (``log_a``,
``log_b``), so no floor is needed to avoid underflow; the 10⁻¹⁰⁰ Cromwell floor
Schaub applies before the permanent (§4-A.3) is available as an option of
:meth:`IdentityBank.log_M`.

The likelihood factor
---------------------
Schaub prints K for the Gaussian model as eqs. (51)–(52), which use
``Σ_P⁻¹`` and ``F⁻¹``. ``Σ_P`` (his 5×5 noise covariance of the state with the
attribute) is singular — always in the attribute, which never moves, and
entirely for an identity with zero process noise — so the equivalent
innovation form is used instead: with the prediction ``N(F μ, F Σ Fᵀ + Q_i)``,

    ∫ f(z | x) pred_i(x) dx = N(z; ẑ_i, S_i),
    ẑ_i = [H F μ; A_i],   S_i = H (F Σ Fᵀ + Q_i) Hᵀ + R,

the Kalman predictive density of the measurement ``z = [position; attribute]``
(eq. 47). The attribute enters with mean ``A_i`` and zero state variance (the
Dirac measure of eq. 3): the innovation is ``[z_pos − H F μ; z_attr − A_i]``
with ``S_i = [[H P⁻ Hᵀ + R_pp, R_pa], [R_ap, R_aa]]`` (``P⁻`` the predicted
covariance), entry for entry the innovation of the state augmented by the
attribute at variance 0, scored by :func:`jointtrack.filters.kalman.log_likelihood`.
Since the attribute is known given the identity, the kinematic posterior is the
:mod:`jointtrack.filters.kalman` update by the position measurement conditioned
on the attribute residual ``ν_a = z_attr − A_i``: measurement
``z_pos − R_pa R_aa⁻¹ ν_a`` with noise ``R_pp − R_pa R_aa⁻¹ R_ap``. This is the
update of the augmented state restricted to the kinematics (so if ``R``
correlates the position and attribute noise the kinematic update depends on
``A_i`` exactly as it should), but every covariance stays positive definite,
whereas the augmented one is singular, which would force the Kalman routines
onto their slow matrix-by-matrix factorisations.

Batches of tracks
-----------------
:meth:`IdentityBank.step` (and :meth:`IdentityBank.add_tracks`) compute all the
listed tracks together: the (tracks × classes) filters are stacked into one
batch for the batched :mod:`jointtrack.filters.kalman` routines, split only
where the measurements differ in which components they measure (e.g. the
attribute observed on some tracks and not on others) or the tracks in the time
since their last update. A single :class:`FilterBank` runs the same code on a
batch of one track, so a track gets the same numbers either way (to rounding:
the BLAS may round a matrix product of one row differently from a batched one).

False alarms (eq. 26)
---------------------
With ``p_f > 0``, ``K = p_f + p_d N(z; ẑ, S)`` and the posterior of each filter
is the two-component mixture of the prediction (weight ``p_f / K``: the
measurement was a false alarm) and the Kalman update (weight ``p_d N / K``).
It is collapsed to one Gaussian by moment matching — an approximation: the
exact density would double its number of components with every such update.
The K factors, and hence M, are exact given the filter densities they start
from. With ``p_f = 0`` the update is the plain Kalman update, ``K = p_d N``.

Unobserved components
---------------------
An infinite variance on the diagonal of ``R`` (Table I: the attribute of the
even tracks) means the component is not measured: its row and column of ``R``,
its entry of ``z`` (which may then be anything, NaN included) and its row of H
are dropped, and the marginal density of the rest is used. Off-diagonal
entries of ``R`` linking an unmeasured component to another must be 0. A
measurement with *every* component unmeasured carries no information about
the state: the filter is only predicted, and ``K = p_f + p_d`` (the empty
measurement's density is 1), so ``log K = log p_d`` when ``p_f = 0``.

The first measurement (§4-A.3)
------------------------------
Schaub starts every filter with zero velocity and a uniform prior in the other
kinematic dimensions, ``p¹ = 1`` on the track's region and ``M¹ = 1``.
:meth:`FilterBank.start` applies the first measurement to that prior in closed
form: the position posterior is the measured position with the covariance of
R's position block (conditioned on the measured attribute components minus
``A_i`` when R correlates them), the velocity is ``N(0, velocity_cov)``
(default 0, a Dirac at zero velocity, as in the paper), and

    log a = log(p_f + p_d N(z_attr; A_i, R_attr))     (= log p_d + log N(…) for p_f = 0),

the flat prior's integral of the position density being 1 (the unit density
of ``p¹ = 1``). With ``p_f = 0`` the flat prior's constant is common to every
identity of the track, i.e. a row scale of M, which cancels in the
deconfliction. With ``p_f > 0`` the result depends on that unit-density
convention, and the filter keeps only the detection branch (the false-alarm
branch of a flat prior is not a Gaussian).

The matrix M (eqs. 1, 30, 77)
-----------------------------
:class:`IdentityBank` holds the banks of the observed tracks and a number of
hidden tracks (eq. 1: tracks that are never observed, so that all observed
tracks may be false alarms). A hidden track's row of M is the prior, ``a = 1``
for every identity and ``b = 1``; those rows are identical, so they form one row
group with a count. :meth:`IdentityBank.log_M` returns the compressed
``log a`` (row groups × identity classes), ``log b``, and the row and column
counts, ready for the deconfliction.
"""

from __future__ import annotations

from collections.abc import Hashable, Mapping
from dataclasses import dataclass, replace
from types import MappingProxyType

import numpy as np

from jointtrack.assignment._checks import as_float, as_int
from jointtrack.filters import kalman
from jointtrack.filters.kalman import _check_psd, _check_sym, _chol_pd
from jointtrack.identity.database import (
    IdentityDatabase,
    _covariance,
    _frozen,
    _real,
)
from jointtrack.models.motion import cv_transition

__all__ = ["FilterBank", "IdentityBank"]


# ----------------------------------------------------------------------------- inputs


@dataclass(frozen=True)
class _Measurement:
    """A validated measurement: its measured components only.

    ``rows`` index the measured components of ``[position(dim); attribute(m)]``;
    ``z`` and ``R`` are restricted to them.
    """

    z: np.ndarray
    R: np.ndarray
    rows: np.ndarray


def _measurements(zs, Rs, db: IdentityDatabase) -> list[_Measurement]:
    """Check measurements ``(z, R)`` against the database and drop their unmeasured components.

    Vectorised over the list: each check runs over every measurement before the
    next check, so with several measurements an error names the check, not the
    measurement (:meth:`IdentityBank.step` then checks its tracks one at a time to
    name the first bad one). With one measurement the checks and messages are
    those of a measurement on its own.
    """
    d = db.measurement_dim
    Z = np.empty((len(zs), d))
    RR = np.empty((len(zs), d, d))
    for g, (z, R) in enumerate(zip(zs, Rs, strict=True)):
        z = _real(z, "z", allow_nonfinite=True)
        if z.shape != (d,):
            raise ValueError(
                f"z must have shape ({d},): {db.dim} position and {db.attribute_dim} attribute "
                f"component(s) (the database's attribute_dim is {db.attribute_dim}), got {z.shape}"
            )
        R = _real(R, "R", allow_nonfinite=True)
        if R.ndim == 1 and R.shape == (d,):
            R = np.diag(R)  # a vector of variances: off-diagonals are 0, so ∞ is allowed
        elif R.shape != (d, d):
            raise ValueError(f"R must have shape ({d}, {d}) or ({d},) (variances), got {R.shape}")
        Z[g], RR[g] = z, R
    if np.isnan(RR).any():
        _, i, j = np.argwhere(np.isnan(RR))[0]
        raise ValueError(f"R[{i}, {j}] is NaN")
    var = np.diagonal(RR, axis1=1, axis2=2)
    if (var < 0).any():
        g, i = np.argwhere(var < 0)[0]
        raise ValueError(f"R[{i}, {i}] = {var[g, i]} is a negative variance")
    off = RR.copy()
    off[:, np.arange(d), np.arange(d)] = 0.0
    if not np.isfinite(off).all():
        g, i, j = np.argwhere(~np.isfinite(off))[0]
        raise ValueError(
            f"R[{i}, {j}] = {RR[g, i, j]}: only variances (the diagonal) may be infinite"
        )
    unseen = np.isinf(var)
    # either index may be the unmeasured one: R[i, j] and R[j, i] are both checked
    link = (unseen[:, :, None] | unseen[:, None, :]) & (off != 0)
    if link.any():
        g, i, j = np.argwhere(link)[0]
        u, o = (i, j) if unseen[g, i] else (j, i)
        raise ValueError(
            f"R[{i}, {j}] = {RR[g, i, j]} links the unmeasured component {u} (infinite variance) "
            f"to component {o}; it must be 0"
        )
    blind = ~unseen & ~np.isfinite(Z)
    if blind.any():
        g, i = np.argwhere(blind)[0]
        raise ValueError(f"z[{i}] = {Z[g, i]} is not finite, but R[{i}, {i}] says it is measured")
    out: list = [None] * len(zs)
    for idx in _groups(unseen[g].tobytes() for g in range(len(zs))):
        rows = np.flatnonzero(~unseen[idx[0]])
        Ro = RR[np.ix_(idx, rows, rows)]
        if rows.size:
            Ro = _check_sym(Ro, "R", False)
            _check_psd(Ro, "R", False)
            _chol_pd(Ro, "R", False)  # the Kalman update needs a positive definite block
        zo = Z[np.ix_(idx, rows)]
        for r, g in enumerate(idx):
            out[g] = _Measurement(z=zo[r], R=Ro[r], rows=rows)
    return out


def _groups(keys) -> list[list[int]]:
    """Positions of equal keys, grouped in order of first appearance."""
    groups: dict = {}
    for j, key in enumerate(keys):
        groups.setdefault(key, []).append(j)
    return list(groups.values())


def _log_p_d(p_d, db: IdentityDatabase) -> np.ndarray:
    """log p_d per class: None (the database's), a scalar or one value per identity."""
    if p_d is None:
        return np.log(db.p_d)
    arr = _real(p_d, "p_d")
    bad = ~((arr > 0) & (arr <= 1))
    if bad.any():
        where = f"[{np.argwhere(bad)[0, 0]}]" if arr.ndim else ""
        raise ValueError(f"p_d{where} = {arr[bad].ravel()[0]} must be in (0, 1]")
    return np.log(db.per_class(arr, "p_d"))


def _log_p_f(p_f) -> float:
    p_f = as_float(p_f, "p_f", minimum=0.0, maximum=1.0, open_max=True)
    with np.errstate(divide="ignore"):
        return float(np.log(p_f))


# ----------------------------------------------------------------------------- filter states
# The steps below run on several tracks at once: the class filters of the tracks
# are stacked track-major into one batch of (tracks × classes) filters for the
# batched :mod:`jointtrack.filters.kalman` routines. One track is a batch of one,
# so a kalman error names the filter by its index in the batch: its class.


@dataclass(frozen=True)
class _State:
    """Everything a bank holds; updates build a new one, so a failure changes nothing."""

    time: float
    mean: np.ndarray  # (C, n)
    cov: np.ndarray  # (C, n, n)
    log_a: np.ndarray  # (C,)
    log_b: float


def _stacked(states) -> tuple[np.ndarray, np.ndarray]:
    """The class filters of the states, track-major: (tracks·C, n) and (tracks·C, n, n)."""
    return np.concatenate([s.mean for s in states]), np.concatenate([s.cov for s in states])


def _moment_match(w: np.ndarray, means: np.ndarray, covs: np.ndarray):
    """Mean and covariance of the mixtures Σ_k w[k, c] N(means[k, c], covs[k, c]).

    ``w`` (K, C) sums to 1 over k; returns (C, n) and (C, n, n), symmetrised.
    """
    mean = np.einsum("kc,kcn->cn", w, means)
    d = means - mean
    spread = covs + d[..., :, None] * d[..., None, :]
    cov = np.einsum("kc,kcij->cij", w, spread)
    return mean, 0.5 * (cov + np.swapaxes(cov, -1, -2))


def _kalman_error(exc: ValueError, what: str) -> ValueError:
    """A :mod:`jointtrack.filters.kalman` error in this module's terms: its batch
    index is an identity class, not a track."""
    return ValueError(f"{what}: {str(exc).replace('(track ', '(identity class ')}")


def _split(run, cov: np.ndarray):
    """``run(k)`` — a kalman step on the filters ``k`` of a batch — over the whole batch.

    The kalman routines factorise a batch of covariances at once and, when one of
    them is singular (a filter with a zero variance: the velocity of an identity
    without process noise started at velocity 0 stays exactly known), fall back to
    one matrix at a time for the whole batch. The filters are independent, so the
    batch is run as two parts, those with a zero variance and the others, which
    gives the same numbers without the slow fallback for the regular part. If a
    part raises, the whole batch is run again so that the error names the filter
    that a single call names.
    """
    zero = (np.diagonal(cov, axis1=1, axis2=2) == 0).any(axis=1)
    if zero.all() or not zero.any():
        return run(slice(None))
    parts = np.flatnonzero(~zero), np.flatnonzero(zero)
    try:
        done = [run(k) for k in parts]
    except ValueError:
        run(slice(None))
        raise
    x = np.empty((cov.shape[0], *done[0][0].shape[1:]))
    P = np.empty((cov.shape[0], *done[0][1].shape[1:]))
    for k, (xk, Pk) in zip(parts, done, strict=True):
        x[k], P[k] = xk, Pk
    return x, P


def _predict_stack(db: IdentityDatabase, mean, cov, dt: float):
    """Markov step (eq. 28) over dt > 0 of a stack of whole tracks' class filters."""
    F = cv_transition(dt, db.dim)
    Q = np.tile(db.process_noise_cov(dt), (mean.shape[0] // db.n_classes, 1, 1))
    try:
        return _split(lambda k: kalman.predict(mean[k], cov[k], F, Q[k]), cov)
    except ValueError as exc:
        raise _kalman_error(exc, f"prediction over dt = {dt:g}") from None


def _predict(db: IdentityDatabase, states: list[_State], t: float) -> list[_State]:
    """Every class filter of every state moved to time t (eq. 28); a, b unchanged.

    States at time t are returned as they are (zero-time transitions are identity
    maps, end of §2-B); the others are predicted in one batch per distinct dt.
    """
    out = list(states)
    dts = [t - s.time for s in states]
    for idx in _groups(dts):
        dt = dts[idx[0]]
        if dt == 0:
            continue
        mean, cov = _predict_stack(db, *_stacked([states[j] for j in idx]), dt)
        C = db.n_classes
        for r, j in enumerate(idx):
            out[j] = replace(
                states[j], time=t, mean=mean[r * C : (r + 1) * C], cov=cov[r * C : (r + 1) * C]
            )
    return out


def _filters(tracks, C: int) -> np.ndarray:
    """Batch indices of the class filters of the given track positions (track-major)."""
    return (np.asarray(tracks)[:, None] * C + np.arange(C)).ravel()


def _per_filter(R: np.ndarray, C: int) -> np.ndarray:
    """Per-track matrices (tracks, m, m) for a batch of tracks × C filters: one shared
    matrix when they are all equal (as for one track), else one per filter."""
    return R[0] if (R == R[0]).all() else np.repeat(R, C, axis=0)


def _with_attribute(nu_p, S_p, nu_a, R, C: int):
    """Innovation and its covariance for ``z = [position; attribute]``.

    The attribute is the class's Dirac value ``A_c`` (eq. 3), known exactly, so
    with the position innovations ``nu_p``, ``S_p`` and the attribute residuals
    ``nu_a = z_attr − A_c`` (per filter), and R (per track),

        ν = [ν_p; ν_a],    S = [[S_p, R_pa], [R_ap, R_aa]]:

    entry for entry the innovation of the state augmented by the attribute at
    variance 0.
    """
    p = S_p.shape[-1]
    S = np.repeat(0.5 * (R + np.swapaxes(R, 1, 2)), C, axis=0)
    S[:, :p, :p] = S_p
    return np.concatenate([nu_p, nu_a], axis=1), S


def _conditioned(zp, R, nu_a, C: int):
    """The position measurement and its noise given the attribute residual.

    With the attribute known given the class, the position measurement given
    ``ν_a = z_attr − A_c`` is ``z_pos − R_pa R_aa⁻¹ ν_a`` with noise
    ``R_pp − R_pa R_aa⁻¹ R_ap``: the Kalman update by it is the update of the
    state augmented by the attribute at variance 0, restricted to the
    kinematics. ``zp``, ``nu_a`` are per filter, ``R`` (measured block) per track;
    returns z_pos per filter and its noise per track.
    """
    p = zp.shape[1]
    gain = np.swapaxes(np.linalg.solve(R[:, p:, p:], R[:, p:, :p]), 1, 2)  # R_pa R_aa⁻¹
    shift = nu_a.reshape(R.shape[0], C, -1) @ np.swapaxes(gain, 1, 2)
    Rc = R[:, :p, :p] - gain @ R[:, p:, :p]
    return zp - shift.reshape(zp.shape), 0.5 * (Rc + np.swapaxes(Rc, 1, 2))


def _kalman_update(x, P, z, H, R):
    """kalman.update of a batch; R shared (m, m) or one per filter."""
    if R.ndim == 2:
        return _split(lambda k: kalman.update(x[k], P[k], z[k], H, R), P)
    return _split(lambda k: kalman.update(x[k], P[k], z[k], H, R[k]), P)


def _update(
    db: IdentityDatabase, states: list[_State], t: float, metas: list[_Measurement], log_pd, log_pf
) -> list[_State]:
    """Predict every state to t and apply its measurement (eqs. 26, 27, 29): the new states.

    The class filters of all tracks are stacked into one batch, split by the
    measured positions (one Kalman innovation and update each) and, for ``log K``,
    by the measured attribute components (e.g. "attribute observed" or not).
    """
    preds = _predict(db, states, t)
    G, C = len(states), db.n_classes
    x, P = _stacked(preds)
    n, dim = x.shape[1], db.dim
    log_n = np.zeros((G, C))  # nothing measured: the empty measurement's density is 1
    post_mean, post_cov = x, P
    try:
        with np.errstate(over="ignore", invalid="ignore"):  # non-finite → ValueError
            for idx in _groups(meas.rows[meas.rows < dim].tobytes() for meas in metas):
                pos = metas[idx[0]].rows[: np.count_nonzero(metas[idx[0]].rows < dim)]
                p, f = pos.size, _filters(idx, C)
                zp = np.repeat(np.stack([metas[j].z[:p] for j in idx]), C, axis=0)
                Rp = np.stack([metas[j].R[:p, :p] for j in idx])
                nu_p, S_p = np.empty((f.size, 0)), np.empty((f.size, 0, 0))
                if p:
                    H = np.zeros((p, n))
                    H[np.arange(p), pos] = 1.0
                    nu_p, S_p = kalman.innovation(x[f], P[f], zp, H, _per_filter(Rp, C))
                for sub in _groups(metas[j].rows.tobytes() for j in idx):
                    tracks = [idx[s] for s in sub]
                    rows, r = metas[tracks[0]].rows, _filters(sub, C)
                    if rows.size == 0:
                        continue
                    nu, S = nu_p[r], S_p[r]
                    if rows.size > p:  # attribute components measured
                        R = np.stack([metas[j].R for j in tracks])
                        z_a = np.stack([metas[j].z[p:] for j in tracks])
                        nu_a = (z_a[:, None] - db.attributes[:, rows[p:] - dim]).reshape(r.size, -1)
                        nu, S = _with_attribute(nu, S, nu_a, R, C)
                        if p and R[:, :p, p:].any():  # R correlates position and attribute
                            zp[r], Rp[sub] = _conditioned(zp[r], R, nu_a, C)
                    log_n[tracks] = np.reshape(kalman.log_likelihood(nu, S), (len(tracks), C))
                if p:  # with only attributes measured nothing is learnt about the kinematics
                    mean, cov = _kalman_update(x[f], P[f], zp, H, _per_filter(Rp, C))
                    if post_mean is x:
                        post_mean, post_cov = x.copy(), P.copy()
                    post_mean[f], post_cov[f] = mean, cov
    except ValueError as exc:
        raise _kalman_error(exc, f"update with z, R at t = {t:g}") from None
    log_det = np.tile(log_pd, G) + log_n.ravel()
    if log_pf == -np.inf:
        log_k, mean, cov = log_det, post_mean, post_cov
    else:
        log_k = np.logaddexp(log_pf, log_det)
        w = np.exp(np.stack([log_pf - log_k, log_det - log_k]))
        mean, cov = _moment_match(w, np.stack([x, post_mean]), np.stack([P, post_cov]))
    if not (np.isfinite(mean).all() and np.isfinite(cov).all() and not np.isnan(log_k).any()):
        raise ValueError(
            f"the update at t = {t:g} overflowed (non-finite state); check the scales of z and R"
        )
    mean, cov, log_k = mean.reshape(G, C, n), cov.reshape(G, C, n, n), log_k.reshape(G, C)
    return [
        _State(t, mean[j], cov[j], s.log_a + log_k[j], s.log_b + log_pf)
        for j, s in enumerate(states)
    ]


def _start(
    db: IdentityDatabase, velocity_cov, t: float, metas: list[_Measurement], log_pd, log_pf
) -> list[_State]:
    """The first measurements applied to the flat, zero-velocity prior of §4-A.3.

    Tracks with the same measured components are computed as one batch.
    """
    dim, C, n = db.dim, db.n_classes, db.state_dim
    out: list = [None] * len(metas)
    for idx in _groups(meas.rows.tobytes() for meas in metas):
        rows, G = metas[idx[0]].rows, len(idx)
        if not np.isin(np.arange(dim), rows).all():
            raise ValueError(
                "R: starting a track needs every position component measured (finite "
                "variance); the flat position prior has no posterior otherwise"
            )
        z = np.repeat(np.stack([metas[j].z for j in idx]), C, axis=0)
        R = np.stack([metas[j].R for j in idx])
        log_n = np.zeros(G * C)
        mean_pos, cov_pos = z[:, :dim], R[:, :dim, :dim]  # rows are sorted: positions first
        if rows.size > dim:
            # Flat prior on the position, Dirac at A_c on the attribute: the posterior
            # of the position is the conditional of the measurement noise given the
            # attribute residual, and the evidence is the attribute's marginal density.
            with np.errstate(over="ignore", invalid="ignore"):  # overflow → the check below
                resid = z[:, dim:] - np.tile(db.attributes[:, rows[dim:] - dim], (G, 1))
            try:
                log_n = np.atleast_1d(
                    kalman.log_likelihood(resid, _per_filter(R[:, dim:, dim:], C))
                )
            except ValueError as exc:
                raise _kalman_error(exc, f"start with z, R at t = {t:g}") from None
            mean_pos, cov_pos = _conditioned(mean_pos, R, resid, C)
        mean = np.zeros((G, C, n))
        mean[..., :dim] = mean_pos.reshape(G, C, dim)
        cov = np.zeros((G, C, n, n))
        cov[..., :dim, :dim] = cov_pos[:, None]
        cov[..., dim:, dim:] = velocity_cov
        log_det = np.tile(log_pd, G) + log_n
        log_a = log_det if log_pf == -np.inf else np.logaddexp(log_pf, log_det)
        if not (np.isfinite(mean).all() and np.isfinite(log_a).all()):
            raise ValueError(f"the start at t = {t:g} overflowed; check the scales of z and R")
        log_a = log_a.reshape(G, C)
        for g, j in enumerate(idx):
            out[j] = _State(t, mean[g], cov[g], log_a[g], log_pf)
    return out


# ----------------------------------------------------------------------------- one track


class FilterBank:
    """The filter bank of one observed track: one Kalman filter per identity class.

    Parameters
    ----------
    database : IdentityDatabase
    velocity_cov : float or (dim, dim) array_like
        covariance of the initial velocity (mean 0); a scalar s means s I. The
        default 0 is Schaub's zero initial velocity (a Dirac at 0).

    Notes
    -----
    Every update is validated and computed into a new state before anything
    is assigned, so a call that raises leaves the bank unchanged. The arrays
    returned by the properties are read-only.

    Examples
    --------
    >>> from jointtrack.identity.database import Identity, IdentityDatabase
    >>> db = IdentityDatabase([Identity("a", 0.0, 1.0), Identity("b", 1.0, 5.0)])
    >>> bank = FilterBank(db)
    >>> bank.start(0.0, [0.0, 0.0, 1.2], np.diag([4.0, 4.0, 4.0]))
    >>> bank.update(1.0, [0.1, -0.2, 0.8], np.diag([4.0, 4.0, np.inf]))  # attribute unseen
    >>> bank.log_a.shape
    (2,)
    """

    def __init__(self, database: IdentityDatabase, *, velocity_cov=0.0):
        if not isinstance(database, IdentityDatabase):
            raise ValueError(f"database must be an IdentityDatabase, got {type(database).__name__}")
        self._db = database
        self._velocity_cov = _covariance(velocity_cov, "velocity_cov", database.dim)
        self._state: _State | None = None

    # ------------------------------------------------------------------ state

    def _require(self) -> _State:
        if self._state is None:
            raise RuntimeError("the filter bank has not been started: call start() first")
        return self._state

    @property
    def database(self) -> IdentityDatabase:
        return self._db

    @property
    def started(self) -> bool:
        return self._state is not None

    @property
    def time(self) -> float:
        """Time of the filter densities (of the last start, predict or update)."""
        return self._require().time

    @property
    def mean(self) -> np.ndarray:
        """(C, 2·dim) kinematic mean of each class filter."""
        return _frozen(self._require().mean.copy())

    @property
    def cov(self) -> np.ndarray:
        """(C, 2·dim, 2·dim) kinematic covariance of each class filter."""
        return _frozen(self._require().cov.copy())

    @property
    def log_a(self) -> np.ndarray:
        """(C,) log of the coefficients a[t, i] (eq. 27) of each class."""
        return _frozen(self._require().log_a.copy())

    @property
    def log_b(self) -> float:
        """log b[t] = Σ log p_f over this track's measurements; −inf once a p_f was 0."""
        return self._require().log_b

    # ------------------------------------------------------------------ steps

    def start(self, t, z, R, *, p_d=None, p_f=0.0) -> None:
        """Initialise every class filter from the track's first measurement (§4-A.3).

        Position mean = measured position, covariance = R's position block
        (both conditioned on the measured attribute minus ``A_c`` if R
        correlates them); velocity ``N(0, velocity_cov)``;
        ``log_a = log(p_f + p_d N(z_attr; A_c, R_attr))`` (0 + log p_d when no
        attribute is measured) and ``log_b = log p_f`` — see the module
        docstring for the flat-prior convention. Calling ``start`` again
        restarts the bank.

        Parameters
        ----------
        t : float
            time of the measurement.
        z : (dim + attribute_dim,) array_like
            measured ``[position; attribute]``; entries whose variance is
            infinite are ignored.
        R : (d, d) or (d,) array_like
            measurement noise covariance (or its diagonal); ∞ on the diagonal
            marks an unmeasured component. The positions must be measured.
        p_d : None, float or (I,) array_like
            detection probability; None uses the database's. An (I,) array must
            be constant within each identity class.
        p_f : float in [0, 1)
            false-alarm probability of this measurement.
        """
        self._state = self._started(t, z, R, p_d, p_f)

    def predict(self, t) -> None:
        """Move every class filter to time t ≥ the current time (eq. 28; a, b unchanged).

        ``t`` equal to the current time is a no-op. Note that the discrete
        white-noise acceleration model is not a semigroup: predicting in two
        steps gives a (slightly) different covariance than in one.
        """
        self._state = _predict(self._db, [self._require()], self._time(t))[0]

    def update(self, t, z, R, *, p_d=None, p_f=0.0) -> None:
        """Predict to t and apply one measurement associated to this track (eqs. 26–29).

        ``log_a[c] += log K_c`` with ``K_c = p_f + p_d,c N(z; ẑ_c, S_c)`` and
        ``log_b += log p_f``. Arguments as in :meth:`start`; ``t`` must not be
        earlier than the bank's time (equal times are simultaneous
        measurements, applied one after the other with an identity transition,
        as at the end of §2-B).
        """
        self._state = self._updated(t, z, R, p_d, p_f)

    def _time(self, t) -> float:
        t = as_float(t, "t")
        now = self._require().time
        if t < now:
            raise ValueError(
                f"t = {t:g} is earlier than the bank's time {now:g}; times must not decrease"
            )
        return t

    def _started(self, t, z, R, p_d, p_f) -> _State:
        """The state after :meth:`start`, without assigning it."""
        t = as_float(t, "t")
        meas = _measurements([z], [R], self._db)[0]
        log_pd, log_pf = _log_p_d(p_d, self._db), _log_p_f(p_f)
        return _start(self._db, self._velocity_cov, t, [meas], log_pd, log_pf)[0]

    def _updated(self, t, z, R, p_d, p_f) -> _State:
        """The state after :meth:`update`, without assigning it (a batch of one track)."""
        state = self._require()
        t = self._time(t)
        meas = _measurements([z], [R], self._db)[0]
        log_pd, log_pf = _log_p_d(p_d, self._db), _log_p_f(p_f)
        return _update(self._db, [state], t, [meas], log_pd, log_pf)[0]

    # ------------------------------------------------------------------ track-level density

    def mixture(self, P_row) -> tuple[np.ndarray, np.ndarray]:
        """Track-level kinematic density (eq. 33), moment matched to one Gaussian.

        ``p_t(x) = Σ_i P[t, i] p_{t,i}(x)``, normalised by ``Σ_i P[t, i]`` (the
        probability that some identity is at the track), i.e. the density given
        that the track holds an identity.

        Parameters
        ----------
        P_row : (I,) array_like
            the deconflicted row of P for this track, one entry per identity,
            non-negative with a positive sum.

        Returns
        -------
        mean : (2·dim,) ndarray
        cov : (2·dim, 2·dim) ndarray
        """
        state = self._require()
        db = self._db
        P = _real(P_row, "P_row")
        if P.shape != (db.n_identities,):
            raise ValueError(
                f"P_row must have one entry per identity ({db.n_identities},), got {P.shape}"
            )
        if (P < 0).any():
            i = int(np.argmax(P < 0))
            raise ValueError(f"P_row[{i}] = {P[i]} is negative; probabilities are ≥ 0")
        w = np.bincount(db.classes, weights=P, minlength=db.n_classes)
        total = w.sum()
        if not total > 0:
            raise ValueError("P_row sums to 0: no identity is at this track")
        mean, cov = _moment_match((w / total)[:, None], state.mean[:, None], state.cov[:, None])
        return mean[0], cov[0]


# ----------------------------------------------------------------------------- all tracks


class IdentityBank:
    """The filter banks of all observed tracks plus a number of hidden tracks (eq. 1).

    Parameters
    ----------
    database : IdentityDatabase
    n_hidden : int ≥ 0
        number of hidden tracks (never observed; their rows of M are the prior).
    velocity_cov : float or (dim, dim) array_like
        initial velocity covariance of new tracks (see :class:`FilterBank`).

    Examples
    --------
    >>> from jointtrack.identity.database import Identity, IdentityDatabase
    >>> db = IdentityDatabase([Identity("a", 0.0), Identity("b", 0.0), Identity("c", 1.0)])
    >>> bank = IdentityBank(db, n_hidden=2)
    >>> _ = bank.add_track("t0", 0.0, [0.0, 0.0], np.eye(2))
    >>> bank.add_tracks(0.5, {"t1": ([9.0, 0.0], np.eye(2)), "t2": ([0.0, 9.0], np.eye(2))})
    >>> bank.step(1.0, {"t0": ([0.1, 0.0], np.eye(2)), "t2": ([0.0, 9.1], np.eye(2))})
    >>> log_A, log_b, rows, cols = bank.log_M()
    >>> log_A.shape, rows.tolist(), cols.tolist()
    ((4, 2), [1, 1, 1, 2], [2, 1])
    """

    def __init__(self, database: IdentityDatabase, n_hidden: int = 0, *, velocity_cov=0.0):
        if not isinstance(database, IdentityDatabase):
            raise ValueError(f"database must be an IdentityDatabase, got {type(database).__name__}")
        self._db = database
        self._velocity_cov = _covariance(velocity_cov, "velocity_cov", database.dim)
        self.n_hidden = n_hidden
        self._tracks: dict[Hashable, FilterBank] = {}

    @property
    def database(self) -> IdentityDatabase:
        return self._db

    @property
    def n_hidden(self) -> int:
        """Number of hidden tracks (settable)."""
        return self._n_hidden

    @n_hidden.setter
    def n_hidden(self, value) -> None:
        self._n_hidden = as_int(value, "n_hidden", minimum=0)

    @property
    def tracks(self) -> Mapping[Hashable, FilterBank]:
        """Read-only mapping key → :class:`FilterBank`, in the order the tracks were added."""
        return MappingProxyType(self._tracks)

    @property
    def n_tracks(self) -> int:
        """|T| = observed + hidden tracks."""
        return len(self._tracks) + self._n_hidden

    def add_track(self, key: Hashable, t, z, R, *, p_d=None, p_f=0.0) -> FilterBank:
        """Start an observed track from its first measurement (see :meth:`FilterBank.start`)."""
        try:
            known = key in self._tracks
        except TypeError:
            raise ValueError(f"key must be hashable, got {type(key).__name__}") from None
        if known:
            raise ValueError(f"key {key!r} is already a track")
        bank = FilterBank(self._db, velocity_cov=self._velocity_cov)
        bank.start(t, z, R, p_d=p_d, p_f=p_f)
        self._tracks[key] = bank
        return bank

    def add_tracks(self, t, measurements: Mapping[Hashable, tuple], *, p_d=None, p_f=0.0) -> None:
        """Start several observed tracks from their first measurements at time t.

        As :meth:`add_track` for each ``key → (z, R)`` of ``measurements``, in its
        order, with the inputs checked together; either every listed track is
        added or, if any input is bad (a key that is already a track included),
        none is, and the error names the first bad track.
        """
        new = self._new_states(
            measurements,
            known=False,
            batch=lambda keys, zs, Rs: self._started(t, zs, Rs, p_d, p_f),
            one=lambda key, z, R: self._bank()._started(t, z, R, p_d, p_f),
        )
        for key, state in new.items():
            self._tracks[key] = bank = self._bank()
            bank._state = state

    def step(self, t, measurements: Mapping[Hashable, tuple], *, p_d=None, p_f=0.0) -> None:
        """Update the tracks measured at time t (eq. 27); the others are untouched (eq. 28).

        Unmeasured tracks are not predicted (their a and b do not change); call
        ``tracks[key].predict(t)`` for a state estimate at t. Either every
        listed track is updated or, if any input is bad, none is; the error
        names the first bad track in the order of ``measurements``.

        The listed tracks are computed together: their inputs are checked as one
        stack and their (tracks × classes) filters are updated as one batch, split
        only by the time since each track's last update and by which components
        are measured (e.g. "attribute observed" or not). It is the computation of
        :meth:`FilterBank.update` on each track in turn (the same code, on a batch
        of one track), so the results agree to rounding (bitwise unless the BLAS
        rounds a product differently for a different batch size).

        Parameters
        ----------
        t : float
        measurements : mapping key → (z, R)
            one measurement per listed track, as in :meth:`FilterBank.update`.
        p_d, p_f :
            as in :meth:`FilterBank.update`, for every listed track (use
            ``tracks[key].update`` for per-track values).
        """
        new = self._new_states(
            measurements,
            known=True,
            batch=lambda keys, zs, Rs: self._updated(t, keys, zs, Rs, p_d, p_f),
            one=lambda key, z, R: self._tracks[key]._updated(t, z, R, p_d, p_f),
        )
        for key, state in new.items():
            self._tracks[key]._state = state

    # ------------------------------------------------------------------ all-or-nothing steps

    def _bank(self) -> FilterBank:
        return FilterBank(self._db, velocity_cov=self._velocity_cov)

    def _refusal(self, key, value, known: bool) -> str | None:
        """Why ``key → value`` cannot be applied (None if it can, as far as the key goes)."""
        if (key in self._tracks) != known:
            if known:
                return f"measurements[{key!r}]: no track has this key (add_track first)"
            return f"measurements[{key!r}]: key {key!r} is already a track"
        if not isinstance(value, tuple | list) or len(value) != 2:
            return f"measurements[{key!r}] must be a pair (z, R)"
        return None

    def _new_states(self, measurements, *, known: bool, batch, one) -> dict:
        """The new states of the listed tracks, without assigning them.

        ``batch(keys, zs, Rs)`` computes every track at once. If it raises, the
        tracks are computed one at a time in order by ``one(key, z, R)`` (the same
        computation on a batch of one track), so that the error is the first bad
        track's, named by its key, exactly as if the tracks were updated in turn.
        """
        if not isinstance(measurements, Mapping):
            raise ValueError(
                f"measurements must be a mapping key → (z, R), got {type(measurements).__name__}"
            )
        items = list(measurements.items())
        if not items:
            return {}
        keys = [key for key, _ in items]
        if not any(self._refusal(key, value, known) for key, value in items):
            try:
                states = batch(keys, [v[0] for _, v in items], [v[1] for _, v in items])
                return dict(zip(keys, states, strict=True))
            except ValueError:
                pass  # some track is bad: find the first one
        new = {}
        for key, value in items:
            refusal = self._refusal(key, value, known)
            if refusal is not None:
                raise ValueError(refusal)
            try:
                new[key] = one(key, value[0], value[1])
            except ValueError as exc:
                raise ValueError(f"measurements[{key!r}]: {exc}") from None
        return new

    def _started(self, t, zs, Rs, p_d, p_f) -> list[_State]:
        t = as_float(t, "t")
        metas = _measurements(zs, Rs, self._db)
        log_pd, log_pf = _log_p_d(p_d, self._db), _log_p_f(p_f)
        return _start(self._db, self._velocity_cov, t, metas, log_pd, log_pf)

    def _updated(self, t, keys, zs, Rs, p_d, p_f) -> list[_State]:
        t = as_float(t, "t")
        states = [self._tracks[key]._state for key in keys]
        if any(t < state.time for state in states):
            raise ValueError("t is earlier than the time of a listed track")
        metas = _measurements(zs, Rs, self._db)
        log_pd, log_pf = _log_p_d(p_d, self._db), _log_p_f(p_f)
        return _update(self._db, states, t, metas, log_pd, log_pf)

    def log_M(self, floor=None):
        """The compressed matrix M (eqs. 30, 77) in log space, for the deconfliction.

        Rows are the observed tracks (count 1 each, in the order added) then,
        if ``n_hidden > 0``, one group of hidden tracks (count ``n_hidden``,
        ``log a = 0`` for every class and ``log b = 0``: the prior). Columns
        are the identity classes with their sizes.

        Parameters
        ----------
        floor : None or float > 0
            Cromwell floor (Schaub floors a at 10⁻¹⁰⁰, §4-A.3): ``log a`` is
            raised to at least ``log(floor)``. None (default) applies none —
            everything is kept in log space, so nothing underflows. ``log b``
            is never floored (b = 0 means the track is certain to exist).

        Returns
        -------
        log_A : (G, C) ndarray
        log_b : (G,) ndarray
        row_counts : (G,) int ndarray
        col_counts : (C,) int ndarray
        """
        db = self._db
        banks = list(self._tracks.values())
        rows = [bank._state.log_a for bank in banks]
        log_b = [bank._state.log_b for bank in banks]
        counts = [1] * len(banks)
        if self._n_hidden:
            rows.append(np.zeros(db.n_classes))
            log_b.append(0.0)
            counts.append(self._n_hidden)
        log_A = np.array(rows, dtype=np.float64).reshape(len(rows), db.n_classes)
        if floor is not None:
            floor = as_float(floor, "floor", minimum=0.0, open_min=True)
            log_A = np.maximum(log_A, np.log(floor))
        return (
            log_A,
            np.array(log_b, dtype=np.float64),
            np.array(counts, dtype=np.int64),
            db.class_counts.copy(),
        )
