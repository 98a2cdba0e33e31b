r"""P(X = 1) at the saddle point: the correction behind ``method="saddle-corrected"``.

Notation of :mod:`jointtrack.saddle.derivative`: at u = log r the law with
generating function Ψ(e^u β)/Ψ(e^u) is that of

    X = Σ_k Y_k + Z,   Y_k one-hot over the M measurements (none w.p. p_k0),
                       Z_m ~ Poisson(λ_m), all independent,

p_km = f_km e^{u_m}/s_k, s_k = f_k0 + Σ_m f_km e^{u_m}, λ_m = a_m e^{u_m}, and

    I = e^{φ(u)} · P(X = 1)   exactly, for every u   (φ = log Ψ(e^u) − Σ u).

Eq. (30) takes the û with E[X] = 1 and puts the Gaussian density at the mean
for P(X = 1). Its global bias (Table 1: ≈ (e/√(2π))^M) is the lattice error
of each coordinate (a lone Poisson(1): e^{−1} against 1/√(2π)); its scatter
comes from how non-Gaussian each coordinate, and the dependence between
them, is. Here log P(X = 1) is instead split over clusters of coordinates;
every single coordinate and every pair is EXACT (closed form), and only the
weak dependence of three or more coordinates at once is asymptotic:

    log P(X = 1) = Σ_m ℓ_m + Σ_{m<n} ℓ_mn + ℓ_{≥3},

    ℓ_m    = log P(X_m = 1)                                   exact
    ℓ_mn   = log P(X_m = 1, X_n = 1) − ℓ_m − ℓ_n              exact
    ℓ_{≥3} ≈ [G − Σ_{m<n} G_mn] + [E − Σ_{m<n} E_mn]          Gaussian + Edgeworth

G = −½ log det R (R the correlation matrix of X: the Gaussian density at the
mean over the product of its marginal Gaussian densities), G_mn = −½ log(1 −
ρ_mn²) the same for the pair alone; E = e₂(X) − Σ_m e₂(X_m), the
second-order Edgeworth exponent of X at its mean minus those of its
coordinates, E_mn the same for the pair alone. ℓ_{≥3} is the Möbius
remainder of the cluster decomposition of the Edgeworth-corrected Gaussian:
everything it says about one coordinate or one pair cancels from it exactly
(so with M ≤ 2 the result is exact), and the per-coordinate lattice error
that biases (30) never enters.

Exact pieces
------------
Coordinate m is Poisson(λ_m) plus independent Bernoulli(p_km), k = 1…K; the
pair (X_m, X_n) is a Poisson pair plus K independent three-way draws (m w.p.
p_km, n w.p. p_kn, neither w.p. z_kmn). Both probabilities come from a two-
(four-) state recursion over the factors in log space — O(K M) and O(K M²),
no division, no cancellation, no underflow. The complements q_km = 1 − p_km
and z_kmn are sums of the factor's other probabilities (a product with a 0/1
mask), never differences, so a factor that takes a measurement almost surely
keeps its tiny complement to full relative precision.

Edgeworth pieces (no dense tensor beyond the 2×2×2×2 of a pair)
----------------------------------------------------------------
The local Edgeworth expansion of a lattice vector at its mean has the
polynomials of the density case (Bhattacharya & Rao, *Normal approximation
and asymptotic expansions*, §22); exponentiated,

    P(X = x̄) ≈ N(0; Σ) · exp(ρ₄/8 − ρ₁₃/8 − ρ₂₃/12),

ρ₄ = κ^{ijkl}S_ij S_kl, ρ₁₃ = κ^{ijk}S_ij S_kl κ^{lmn}S_mn, ρ₂₃ =
κ^{ijk}κ^{lmn}S_il S_jm S_kn, S = Σ^{−1} (one Poisson(1) coordinate: 1/8 −
1/8 − 1/12 = −1/12, the first Stirling term). The cumulant tensors of X are
sums over factors of those of a one-hot vector — whose moments are diagonal,
E[Y_i Y_j Y_k] = p_i δ_ijk, so its cumulants are sums over set partitions of
products of diagonal tensors — plus the Poisson diagonal λ_m δ at every
order. Every contraction with S then reduces to sums of products of p, S p,
diag S, S∘S and the K×K Gram matrices p S pᵀ, p (S∘S) pᵀ:
O(K² M² + K M² + M³) per problem (:func:`_edgeworth_term`, checked against
dense tensors in the tests; the exact pairs add O(K M³)). Pairs use the 2×2 version with the mixed
cumulants in closed form: κ_mmn = −Σ_k p_m p_n (1 − 2p_m), κ_mmmn = −Σ_k p_m
p_n (1 − 6 p_m q_m), κ_mmnn = −Σ_k p_m p_n [(1 − 2p_m)(1 − 2p_n) + 2 p_m p_n].

Where an expansion does not apply (validity conditions, not fitted)
-------------------------------------------------------------------
* A coordinate with large standardised cumulants (γ₃² or |γ₄| above
  :data:`MAX_STANDARDISED_CUMULANT` = 4, where the univariate terms γ₄/8 and
  5γ₃²/24 reach ½ and ~1 and stop being corrections — e.g. a measurement one
  factor takes almost surely: variance → 0, γ ~ 1/variance) is left out of
  both asymptotic parts: G and E are those of the marginal law of the other
  coordinates (their one-hot probabilities restricted to them). It keeps
  its exact single and pair terms. In every Table 1 cell no coordinate
  comes near the bound (γ ≤ 1.2), so it changes nothing there.
* E needs the whitened cumulants bounded too: whitening multiplies order-r
  standardised cumulants by up to λ_min(R)^{−r/2}, so E is used only when
  the smallest eigenvalue of R (kept coordinates) is ≥ 1/4 = 1/bound. Table
  1's smallest is 0.40; a near-permanent (K = M, little clutter, small
  f_k0) goes below, and there E made things worse (below).
* G needs a Gaussian density: with λ_min(R) < 1e-6 (factors with f_k0 = 0
  confined to as many measurements, X on a sublattice, det Σ → 0 where
  eq. 30 diverges) G is left out; :func:`log_unit_probability` flags such
  problems (when the degenerate direction involves ≥ 3 coordinates of all of
  X) and :func:`~jointtrack.saddle.derivative.log_mixed_derivative` computes
  them on the exact core — there is no interior saddle point to expand at.

Measured
--------
Table 1's setup (K ∈ {3,5,7} factors with constant 1, M ∈ {5,10,15}, a0 = 0,
a_m, f_km ~ U[0,1]; 1000 trials per cell, numpy seed 20150707 drawing a then F
per cell; exact by the core): mean of approx/exact and std/mean, cells K/M =
3/5 3/10 3/15 5/5 5/10 5/15 7/5 7/10 7/15.

Each variant: first line the means, second the std/mean, per cell.

* eq. (30), ``"saddle"``:
  1.453 2.209 3.324 1.450 2.213 3.337 1.469 2.204 3.340;
  1.64% 1.53% 1.25% 1.01% 0.68% 0.65% 0.43% 0.43% 0.35%
* (30) / (e/√(2π))^M: .969 .982 .985 .967 .984 .989 .979 .980 .990; same spread
* (30) · exp(second-order Edgeworth exponent of X):
  .985 .975 .964 .984 .977 .966 .987 .977 .966;
  0.67% 0.56% 0.44% 0.35% 0.20% 0.18% 0.12% 0.12% 0.08%
* exact marginals · Gaussian copula (singles + G, no pairs):
  1.007 1.015 1.012 .990 1.010 1.011 .993 1.001 1.009;
  0.83% 0.72% 0.56% 0.61% 0.39% 0.36% 0.17% 0.25% 0.25%
* exact marginals · exact pairs (nothing beyond):
  1.005 1.007 1.005 .985 .997 1.000 .986 .977 .991;
  0.63% 0.54% 0.34% 1.19% 0.66% 0.59% 0.62% 1.17% 0.74%
* exact singles and pairs + G beyond pairs (no E):
  1.011 1.012 1.008 .997 1.013 1.010 .997 1.006 1.011;
  0.66% 0.46% 0.33% 0.43% 0.28% 0.20% 0.13% 0.20% 0.17%
* exact marginals · G · E over all coordinates (no exact pairs):
  1.0035 1.0035 1.0024 .9980 1.0027 1.0018 .9997 1.0014 1.0016;
  0.41% 0.30% 0.24% 0.22% 0.12% 0.09% 0.06% 0.06% 0.05%
* **this module** (``"saddle-corrected"``: exact singles and pairs, G and E
  beyond): 1.0041 1.0016 1.0007 .9980 1.0021 1.0009 .9993 1.0010 1.0011;
  0.35% 0.21% 0.16% 0.19% 0.09% 0.06% 0.03% 0.05% 0.04%

The last two both meet |mean − 1| ≤ 1 % and std ≤ 1 % everywhere (worst
0.41 %/0.41 % and 0.41 %/0.35 %); the exact pairs were kept because away
from Table 1 they halve the spread (below).

Also measured and dropped: clusters over *factors* instead of coordinates
(exact marginals times the exact one- and two-factor corrections E[R_k],
E[R_k R_l] of the "factor takes several measurements" relaxation: 0.967–0.998,
up to 1.2 %), and the first order of the lattice characteristic-function
expansion in e^{iθ} − 1 (0.90–0.99, 1.6–3.5 %).

Away from Table 1 (300 draws each, approx/exact mean and std/mean, ``"saddle"``
→ this module): JPDA-like draws (f_k0 = 0.1, f_km ~ Exp(1)³, a_m ~
U[0.01, 0.1]) K/M = 3/5: 1.44 ± 13.8 % → 1.007 ± 3.1 %; 4/8: 1.74 ± 9.4 % →
1.007 ± 2.4 %; 5/10: 1.98 ± 9.2 % → 1.009 ± 2.2 %; log-uniform coefficients
over 1e-3…10, 4/8: 1.71 ± 12.7 % → 1.007 ± 3.1 %; U[0,1] 7/3 and 20/20:
± 0.3 % / 0.1 % → 1.000 / 0.999 ± 0.0 %. The weak case is a near-permanent:
K = M with little clutter and small f_k0 (6/6 above: 1.32 ± 24.7 % → 0.91 ±
7.6 %), where X nearly lives on the hyperplane Σ X = K and no Gaussian-based
remainder is good; there the exact core is cheap anyway. Without the exact
pairs (marginals · G · E) the JPDA-like spreads were 5.5 %, 4.0 %, 3.8 %
(3/5, 4/8, 5/10) instead of 3.1 %, 2.4 %, 2.2 %.
"""

from __future__ import annotations

import math

import numpy as np

from jointtrack.saddle._newton import tilt_batch

__all__ = ["MAX_STANDARDISED_CUMULANT", "Tilt", "log_unit_probability", "tilt"]

#: Coordinates with γ₃² or |γ₄| above this are left out of the Edgeworth part.
MAX_STANDARDISED_CUMULANT = 4.0

# below this smallest eigenvalue of the correlation matrix the Gaussian part is left out
_MIN_EIGENVALUE = 1e-6
# problems per chunk: keeps the (chunk, K, pairs) arrays near 32 MB
_CHUNK_ELEMENTS = 1 << 22


class Tilt:
    """The tilted law of X at u (batched over the leading axes).

    Attributes: ``lam`` (…, M) Poisson means; ``p`` (…, K, M) and ``p0`` (…, K)
    the one-hot probabilities; ``q`` (…, K, M) = 1 − p_km as a sum of the other
    probabilities (no cancellation); ``var`` (…, M) the variances λ_m + Σ_k
    p_km q_km; ``cov`` (…, M, M) the covariance of X (= ∇²φ).
    """

    __slots__ = ("cov", "lam", "p", "p0", "q", "var")

    def __init__(self, lam, p, p0, q):
        self.lam, self.p, self.p0, self.q = lam, p, p0, q
        self.var = lam + (p * q).sum(-2)
        cov = -(np.swapaxes(p, -1, -2) @ p)  # Σ_k p_k p_kᵀ (matmul: 3× einsum's speed)
        idx = np.arange(lam.shape[-1])
        cov[..., idx, idx] = self.var
        self.cov = cov


def tilt(u, a, F) -> Tilt:
    """The tilted probabilities at u, in log space (no overflow for any finite u).

    Computed by the compiled :func:`jointtrack.saddle._newton.tilt_batch`, the
    one implementation that Newton's method also uses.

    ``u`` (…, M), ``a`` (…, M) or (M,), ``F`` (…, K, M+1) with no factor
    identically zero.
    """
    u = np.asarray(u, dtype=float)
    F = np.asarray(F, dtype=float)
    batch = np.broadcast_shapes(u.shape[:-1], F.shape[:-2], np.shape(a)[:-1])
    M = u.shape[-1]
    K = F.shape[-2]
    B = math.prod(batch)
    with np.errstate(divide="ignore"):
        log_F = np.log(np.broadcast_to(F, (*batch, K, M + 1)).reshape(B, K, M + 1))
    lam, p, p0, q = tilt_batch(
        np.ascontiguousarray(np.broadcast_to(u, (*batch, M)).reshape(B, M)),
        np.ascontiguousarray(np.broadcast_to(a, (*batch, M)).reshape(B, M), dtype=float),
        log_F,
    )
    lam, p, p0, q = (
        lam.reshape(*batch, M),
        p.reshape(*batch, K, M),
        p0.reshape(*batch, K),
        q.reshape(*batch, K, M),
    )
    return Tilt(lam, p, p0, q)


# --------------------------------------------------------------------------- exact pieces


def _log(x):
    with np.errstate(divide="ignore"):
        return np.log(x)


def _log_single(lam, lp, lq):
    """log P(X_m = 1), (…, M): two-state recursion over the factors."""
    s0 = -lam
    s1 = _log(lam) - lam
    for k in range(lp.shape[-2]):
        s1 = np.logaddexp(s1 + lq[..., k, :], s0 + lp[..., k, :])
        s0 = s0 + lq[..., k, :]
    return s1


def _log_pair(lam_m, lam_n, lp_m, lp_n, lz):
    """log P(X_m = 1, X_n = 1) for pairs (…, P): four-state recursion over the factors."""
    s00 = -lam_m - lam_n
    s10 = s00 + _log(lam_m)
    s01 = s00 + _log(lam_n)
    s11 = s10 + _log(lam_n)
    for k in range(lz.shape[-2]):
        z, pm, pn = lz[..., k, :], lp_m[..., k, :], lp_n[..., k, :]
        s11 = np.logaddexp(s11 + z, np.logaddexp(s01 + pm, s10 + pn))
        s10, s01 = np.logaddexp(s10 + z, s00 + pm), np.logaddexp(s01 + z, s00 + pn)
        s00 = s00 + z
    return s11


# --------------------------------------------------------------------------- Edgeworth pieces


def _univariate_cumulants(tl: Tilt):
    p, q, lam = tl.p, tl.q, tl.lam
    pq = p * q
    k3 = lam + (pq * (q - p)).sum(-2)
    k4 = lam + (pq * (1.0 - 6.0 * pq)).sum(-2)
    return tl.var, k3, k4


def _e2(rho4, rho13, rho23):
    return rho4 / 8.0 - rho13 / 8.0 - rho23 / 12.0


def _edgeworth_term(p, w, S):
    """Second-order Edgeworth exponent ρ₄/8 − ρ₁₃/8 − ρ₂₃/12 at the mean, structured.

    ``p`` (…, K, M) one-hot probabilities, ``w`` (…, M) = λ + Σ_k p_k (the
    diagonal of every raw-moment tensor: Poisson cumulants plus one-hot
    moments), ``S`` (…, M, M) the inverse covariance. With d = diag S, Y = S pᵀ
    (columns S p_k), G = p S pᵀ, G₂ = p (S∘S) pᵀ:

    ρ₄  = Σ w d² + Σ_k [−4 Σ p∘d∘Sp − (p·d)² − 2 pᵀ(S∘S)p + 4 (p·d)(pᵀSp)
          + 8 Σ p∘(Sp)² − 6 (pᵀSp)²]_{p = p_k}
    v   = w∘d − Σ_k p_k∘((p_k·d) + 2 S p_k) + 2 Σ_k (p_kᵀSp_k) p_k,  ρ₁₃ = vᵀSv
    ρ₂₃ = wᵀ(S∘S∘S)w − 6 Σ_k wᵀ((S∘S)p_k ∘ Sp_k) + 4 Σ_k wᵀ(Sp_k)³
          + Σ_kl [3 G₂ G + 6 T + 4 G³ − 12 (Σ_i p_ki Y_il²) G]_kl,
    T_kl = (p_k∘Sp_l)ᵀ S (p_l∘Sp_k).
    """
    d = np.diagonal(S, axis1=-2, axis2=-1)
    S2 = S * S
    Y = np.einsum("...mn,...kn->...km", S, p)  # rows S p_k
    G = np.einsum("...km,...lm->...kl", p, Y)
    G2 = np.einsum("...km,...mn,...ln->...kl", p, S2, p)
    Gkk = np.diagonal(G, axis1=-2, axis2=-1)
    pd = (p * d[..., None, :]).sum(-1)  # (…, K)
    rho4 = (w * d * d).sum(-1) + (
        -4.0 * (p * d[..., None, :] * Y).sum(-1)
        - pd**2
        - 2.0 * np.diagonal(G2, axis1=-2, axis2=-1)
        + 4.0 * pd * Gkk
        + 8.0 * (p * Y * Y).sum(-1)
        - 6.0 * Gkk**2
    ).sum(-1)
    v = w * d - (p * (pd[..., None] + 2.0 * Y)).sum(-2) + 2.0 * (Gkk[..., None] * p).sum(-2)
    rho13 = np.einsum("...m,...mn,...n->...", v, S, v)
    SSp = np.einsum("...mn,...kn->...km", S2, p)
    A = np.einsum("...m,...mn,...n->...", w, S2 * S, w)
    AB = -6.0 * (w[..., None, :] * SSp * Y).sum((-1, -2))
    AC = 4.0 * (w[..., None, :] * Y**3).sum((-1, -2))
    # T_kl = Σ_ij p_ki Y_li S_ij p_lj Y_kj
    X = p[..., :, None, :] * Y[..., None, :, :]  # X_kli = p_ki (S p_l)_i
    T = np.einsum("...kli,...ij,...lkj->...kl", X, S, X)
    PY2 = np.einsum("...ki,...li->...kl", p, Y * Y)  # Σ_i p_ki Y_li²
    BC = (3.0 * G2 * G + 6.0 * T + 4.0 * G**3 - 12.0 * PY2 * G).sum((-1, -2))
    rho23 = A + AB + AC + BC
    return _e2(rho4, rho13, rho23)


def _pair_edgeworth(p_m, p_n, q_m, q_n, k2, k3, k4, iu, cov_mn):
    """Second-order Edgeworth exponent of each pair (X_m, X_n) alone, (…, P), and det Σ₂.

    Index pairs ``iu`` = (m's, n's); ``p_m`` = p[..., iu[0]] etc. The 2×2
    contractions are written out: an entry of κ₃ or κ₄ over {m, n} depends only
    on how many of its indices are n.
    """
    pp = p_m * p_n
    c3 = [
        k3[..., iu[0]],
        -(pp * (1.0 - 2.0 * p_m)).sum(-2),
        -(pp * (1.0 - 2.0 * p_n)).sum(-2),
        k3[..., iu[1]],
    ]
    c4 = [
        k4[..., iu[0]],
        -(pp * (1.0 - 6.0 * p_m * q_m)).sum(-2),
        -(pp * ((1.0 - 2.0 * p_m) * (1.0 - 2.0 * p_n) + 2.0 * pp)).sum(-2),
        -(pp * (1.0 - 6.0 * p_n * q_n)).sum(-2),
        k4[..., iu[1]],
    ]
    hm, hn = k2[..., iu[0]], k2[..., iu[1]]
    det = hm * hn - cov_mn * cov_mn
    inv = 1.0 / np.where(det > 0, det, np.inf)  # a numerically singular pair: no term
    S = ((hn * inv, -cov_mn * inv), (-cov_mn * inv, hm * inv))
    idx = (0, 1)
    rho4 = sum(
        c4[i + j + k + l] * S[i][j] * S[k][l] for i in idx for j in idx for k in idx for l in idx
    )
    v = [sum(c3[i + j + k] * S[i][j] for i in idx for j in idx) for k in idx]
    rho13 = sum(v[k] * S[k][l] * v[l] for k in idx for l in idx)
    # W = κ₃ with S applied to every index, one index at a time
    W = {(i, j, k): c3[i + j + k] for i in idx for j in idx for k in idx}
    for axis in range(3):
        W = {
            key: sum(S[key[axis]][x] * W[key[:axis] + (x,) + key[axis + 1 :]] for x in idx)
            for key in W
        }
    rho23 = sum(c3[sum(key)] * W[key] for key in W)
    return _e2(rho4, rho13, rho23), det


# --------------------------------------------------------------------------- the approximation


def _pieces(tl: Tilt, bound: float = MAX_STANDARDISED_CUMULANT) -> dict[str, np.ndarray]:
    """Every term of the decomposition (module docstring), per problem."""
    p, p0, lam = tl.p, tl.p0, tl.lam
    K, M = p.shape[-2:]
    lp, lq = _log(p), _log(tl.q)
    single = _log_single(lam, lp, lq)
    out = {"single": single.sum(-1)}
    # pairs m < n along one axis; z_kmn = p_k0 + Σ_{j ∉ {m, n}} p_kj: a masked
    # sum, never 1 − p_km − p_kn
    iu = np.triu_indices(M, 1)
    mask = np.ones((M, len(iu[0])))
    mask[iu[0], np.arange(len(iu[0]))] = 0.0
    mask[iu[1], np.arange(len(iu[0]))] = 0.0
    z = p0[..., None] + p @ mask
    p_m, p_n = p[..., iu[0]], p[..., iu[1]]
    pair = _log_pair(lam[..., iu[0]], lam[..., iu[1]], lp[..., iu[0]], lp[..., iu[1]], _log(z))
    with np.errstate(invalid="ignore"):
        # P(X_m = 1, X_n = 1) = 0 (or P(X_m = 1) = 0) makes P(X = 1) = 0
        pair = np.where(pair == -np.inf, -np.inf, pair - single[..., iu[0]] - single[..., iu[1]])
    out["pair"] = pair.sum(-1)
    del z, pair
    k2, k3, k4 = _univariate_cumulants(tl)
    # no interior saddle point: a linear combination of ≥ 3 coordinates has (numerically)
    # no variance — factors with f_k0 = 0 confined to as many measurements (Hall-tight)
    live = k2 > 0
    s_all = np.sqrt(np.where(live, k2, 1.0))
    R_all = np.where(live[..., :, None] & live[..., None, :], tl.cov, 0.0) / (
        s_all[..., :, None] * s_all[..., None, :]
    )
    R_all[..., np.arange(M), np.arange(M)] = 1.0
    out["singular"] = (np.linalg.eigvalsh(R_all)[..., 0] < _MIN_EIGENVALUE) & (M >= 3)
    # the coordinates with a meaningful expansion: standardised cumulants ≤ bound
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        g3 = k3 * k3 / k2**3
        g4 = np.abs(k4) / (k2 * k2)
        keep = (g3 <= bound) & (g4 <= bound)
        e2u = np.where(keep, _e2(g4 * np.sign(k4), g3, g3), 0.0)
    sd = np.sqrt(np.where(keep, k2, 1.0))
    inner = keep[..., :, None] & keep[..., None, :]
    R = np.where(inner, tl.cov, 0.0) / (sd[..., :, None] * sd[..., None, :])
    idx = np.arange(M)
    R[..., idx, idx] = 1.0
    lmin = np.linalg.eigvalsh(R)[..., 0]
    # Gaussian part: a numerically singular R (X on a sublattice: factors with
    # f_k0 = 0 confined to as many measurements) has no Gaussian density
    gauss = lmin >= _MIN_EIGENVALUE
    R[~gauss] = np.eye(M)
    G = -0.5 * np.linalg.slogdet(R)[1]
    rho = R[..., iu[0], iu[1]]
    out["gauss"] = G
    out["gauss_pairs"] = -0.5 * np.log1p(-rho * rho).sum(-1)
    # Edgeworth part: whitening multiplies order-r standardised cumulants by up to
    # λ_min(R)^{-r/2}; with λ_min < 1/bound they are no longer bounded
    whole = lmin * bound >= 1.0
    R[~whole] = np.eye(M)
    pk = np.where(keep[..., None, :], p, 0.0)
    w = np.where(keep, lam, 0.0) + pk.sum(-2)
    S = np.linalg.inv(R) / (sd[..., :, None] * sd[..., None, :])
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        e2p = _pair_edgeworth(
            p_m, p_n, tl.q[..., iu[0]], tl.q[..., iu[1]], k2, k3, k4, iu, tl.cov[..., iu[0], iu[1]]
        )[0]
    out["edgeworth"] = np.where(whole, _edgeworth_term(pk, w, S) - e2u.sum(-1), 0.0)
    both = keep[..., iu[0]] & keep[..., iu[1]] & whole[..., None]
    with np.errstate(invalid="ignore"):
        Ep = np.where(both, e2p - e2u[..., iu[0]] - e2u[..., iu[1]], 0.0)
    out["edgeworth_pairs"] = Ep.sum(-1)
    out["edgeworth_uni"] = e2u.sum(-1)
    out["kept"] = keep.sum(-1)
    return out


def log_unit_probability(tl: Tilt, *, with_flags: bool = False):
    """log P(X = 1) by exact singles and pairs plus the Gaussian–Edgeworth remainder.

    With ``with_flags``, also the problems without an interior saddle point
    (a correlation matrix singular in a direction of ≥ 3 coordinates: X on a
    sublattice, where the remainder has no Gaussian to stand on; the caller
    computes those exactly).
    """
    M = tl.lam.shape[-1]
    batch = tl.lam.shape[:-1]
    if M == 0:
        zero = np.zeros(batch)
        return (zero, zero.astype(bool)) if with_flags else zero
    K = tl.p.shape[-2]
    n = int(np.prod(batch)) if batch else 1
    per = max(1, _CHUNK_ELEMENTS // max(1, K * M * M))
    flat = [x.reshape(n, *x.shape[len(batch) :]) for x in (tl.lam, tl.p, tl.p0, tl.q)]
    out = np.empty(n)
    singular = np.empty(n, bool)
    for i in range(0, n, per):
        sl = slice(i, i + per)
        pc = _pieces(Tilt(*(x[sl] for x in flat)))
        out[sl] = _combine(pc)
        singular[sl] = pc["singular"]
    out, singular = out.reshape(batch), singular.reshape(batch)
    return (out, singular) if with_flags else out


def _combine(pc):
    res = (
        pc["single"]
        + pc["pair"]
        + pc["gauss"]
        - pc["gauss_pairs"]
        + pc["edgeworth"]
        - pc["edgeworth_pairs"]
    )
    return res
