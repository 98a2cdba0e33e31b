r"""The generating function of particle JPDA and the coefficients of Streit's eq. (7).

R. L. Streit, "Saddle point method for JPDA and related filters", *Proc. 18th
International Conference on Information Fusion* (FUSION), Washington DC, 2015.
Equation numbers below are that paper's.

The function
------------
For M measurements and K linear factors,

.. math::

    \Psi(\beta) = \exp\Big(a_0 + \sum_{m=1}^M a_m \beta_m\Big)
                  \prod_{k=1}^K \Big(f_{k0} + \sum_{m=1}^M f_{km} \beta_m\Big),

held as plain arrays: ``a0`` (scalar), ``a`` (M,) and ``F`` (K, M+1) with column
0 the constants f_k0 — or a batch ``F`` (L, K, M+1) sharing ``a0`` and ``a``.
Its mixed derivative ∂^M Ψ/∂β_1…∂β_M at 0 is the coefficient of β_1⋯β_M: the
sum over assignments in which every measurement goes to the clutter term
(weight a_m) or to one factor (f_km), every factor takes at most one
measurement and an unused factor contributes f_k0, all times e^{a_0}.

The JPDA instance (14)
----------------------
For the marginal posterior of target n at state x, the factors are the
particle's own ``b_n·(x)`` and the other targets' particle-set integrals
``c_j·`` (j ≠ n), with the clutter terms a_m = Λ p_Λ(y_m) and a_0 = −Λ:

* ``b_n0(x) = μ_n(x)(1 − P_D(x))``, ``b_nm(x) = μ_n(x) P_D(x) p(y_m | x)``;
* ``c_j0 = ∫ μ_j (1 − P_D)``, ``c_jm = ∫ μ_j P_D p(y_m | ·)``.

**What a particle weight contains.** b_nm(x) of (7) includes the predicted
density μ_n(x). A particle x drawn *from* μ_n already carries μ_n through the
sampling, so its weight must use b without the μ_n(x) factor (importance
weight = target / proposal = μ_n(x)·(…) / μ_n(x)); counting it twice biases the
filter towards the prediction. :func:`jpda_coefficients` therefore takes
``p_d`` and ``likelihood`` per particle and multiplies by ``predicted_density``
only when it is given (particles drawn from another proposal). The integrals c
are particle averages over each target's predicted particles (equally weighted
after resampling): ``c_j0 = mean(1 − P_D)``, ``c_jm = mean(P_D p(y_m|·))``.
P_D may depend on the state (one value per particle).
"""

from __future__ import annotations

import numpy as np

from jointtrack.assignment._checks import _as_real_array, as_float

__all__ = ["check_coefficients", "jpda_coefficients", "log_psi"]


def _real(x, name: str, ndim: tuple[int, ...]) -> np.ndarray:
    arr = _as_real_array(x, name)
    if arr.ndim not in ndim:
        want = " or ".join(f"{d}-D" for d in ndim)
        raise ValueError(f"{name} must be {want}, got an array with {arr.ndim} dimension(s)")
    if not np.isfinite(arr).all():
        i = tuple(int(k) for k in np.argwhere(~np.isfinite(arr))[0])
        raise ValueError(f"{name} has a non-finite entry ({arr[i]}) at {i}")
    return arr


def check_coefficients(a0, a, F):
    """Validated ``(a0, a, F, batched)``: a_m > 0 (Ψ entire, §4.2), F ≥ 0 of shape (…, K, M+1)."""
    a0 = _real(a0, "a0", (0,))
    a = _real(a, "a", (1,))
    F = _real(F, "F", (2, 3))
    if (a <= 0).any():
        m = int(np.flatnonzero(a <= 0)[0])
        raise ValueError(
            f"a[{m}] = {a[m]}: every clutter term must be > 0 (with a_m = 0 Ψ is a polynomial "
            "in β_m and the saddle point need not exist, Streit §4.2; a measurement no clutter "
            "can explain must still get a tiny clutter intensity)"
        )
    if F.shape[-1] != a.size + 1:
        raise ValueError(
            f"F must have M + 1 = {a.size + 1} columns (column 0 the constants f_k0, then one "
            f"per measurement), got shape {F.shape}"
        )
    if (F < 0).any():
        i = tuple(int(k) for k in np.argwhere(F < 0)[0])
        raise ValueError(f"F has a negative coefficient ({F[i]}) at {i}; coefficients are ≥ 0")
    return float(a0), np.ascontiguousarray(a), np.ascontiguousarray(F), F.ndim == 3


def log_psi(u, a0, a, F) -> np.ndarray:
    """log Ψ(e^u) for real u (…, M): the function the saddle point minimises (minus Σ u).

    ``F`` (K, M+1) or (L, K, M+1); ``u`` broadcasts against the batch.
    """
    u = np.asarray(u, dtype=float)
    r = np.exp(u)
    s = F[..., 0] + np.einsum("...km,...m->...k", F[..., 1:], r)
    with np.errstate(divide="ignore"):
        return a0 + (a * r).sum(-1) + np.log(s).sum(-1)


def jpda_coefficients(
    clutter_intensity,
    p_d,
    likelihood,
    other_p_d,
    other_likelihood,
    *,
    expected_clutter: float | None = None,
    predicted_density=None,
):
    """Coefficients (7) of target n's marginal (14) for L particles: ``(a0, a, F)``.

    Parameters
    ----------
    clutter_intensity : (M,)
        a_m = Λ p_Λ(y_m) > 0 at each measurement.
    p_d : (L,)
        P_D at each of target n's particles.
    likelihood : (L, M)
        p(y_m | x_l) of target n's particles.
    other_p_d : sequence of (L_j,) arrays
        P_D at each particle of every other target j.
    other_likelihood : sequence of (L_j, M) arrays
        p(y_m | x) at those particles.
    expected_clutter : float, optional
        Λ; a_0 = −Λ (a global factor e^{−Λ}: irrelevant to normalised weights).
        Default: Σ a_m is not Λ, so a_0 = 0 unless given.
    predicted_density : (L,), optional
        μ_n(x_l), only for particles *not* drawn from μ_n (see the module
        docstring); omitted, the particles are taken to be draws from μ_n.

    Returns
    -------
    a0 : float
    a : (M,)
    F : (L, K, M+1)
        factor 0 is the particle's own b_n·, factors 1… the other targets' c_j·.
    """
    a = _real(clutter_intensity, "clutter_intensity", (1,))
    M = a.size
    pd = _real(p_d, "p_d", (1,))
    lik = _real(likelihood, "likelihood", (2,))
    L = pd.size
    if lik.shape != (L, M):
        raise ValueError(f"likelihood must have shape (L, M) = ({L}, {M}), got {lik.shape}")
    if ((pd < 0) | (pd > 1)).any():
        raise ValueError("p_d must lie in [0, 1]")
    if (lik < 0).any():
        raise ValueError("likelihood must be ≥ 0")
    b = np.empty((L, M + 1))
    b[:, 0] = 1.0 - pd
    b[:, 1:] = pd[:, None] * lik
    if predicted_density is not None:
        mu = _real(predicted_density, "predicted_density", (1,))
        if mu.shape != (L,) or (mu < 0).any():
            raise ValueError(f"predicted_density must be {L} values ≥ 0")
        b *= mu[:, None]
    if len(other_p_d) != len(other_likelihood):
        raise ValueError("other_p_d and other_likelihood must list the same targets")
    C = np.empty((len(other_p_d), M + 1))
    for j, (pj, lj) in enumerate(zip(other_p_d, other_likelihood, strict=True)):
        pj = _real(pj, f"other_p_d[{j}]", (1,))
        lj = _real(lj, f"other_likelihood[{j}]", (2,))
        if lj.shape != (pj.size, M):
            raise ValueError(
                f"other_likelihood[{j}] must have shape ({pj.size}, {M}), got {lj.shape}"
            )
        C[j, 0] = np.mean(1.0 - pj)
        C[j, 1:] = np.mean(pj[:, None] * lj, axis=0)
    F = np.concatenate([b[:, None, :], np.broadcast_to(C, (L, *C.shape))], axis=1)
    a0 = 0.0
    if expected_clutter is not None:
        a0 = -as_float(expected_clutter, "expected_clutter", minimum=0.0)
    return a0, a, np.ascontiguousarray(F)
