"""Chi-square validation gates and the gated likelihood-ratio matrix.

A measurement ``z_j`` is validated for track ``i`` when its squared Mahalanobis
distance from the predicted measurement ``ẑ_i`` under the innovation covariance
``S_i`` is at most the gate threshold ``γ``:

    d²_ij = (z_j − ẑ_i)ᵀ S_i⁻¹ (z_j − ẑ_i) ≤ γ,   γ = χ²_d⁻¹(P_G)

(Bar-Shalom & Li 1995, Bojilov's ref. [4]; Bojilov et al., d²_ij under eq. (2)). ``P_G`` is
the probability that the true measurement falls in the gate. The gate is an
ellipsoid of volume V_i = c_d γ^{d/2} √|S_i| with c_d = π^{d/2}/Γ(d/2 + 1) the
volume of the d-dimensional unit ball.

The JPDA cluster convention of :mod:`jointtrack.association` (DESIGN.md) is
produced by :func:`likelihood_ratios`:

    L[i, j] = P_D g_ij / λ   if d²_ij ≤ γ, else 0        (Bojilov eq. (5)/(7))
    miss[i] = 1 − P_D P_G

where g_ij = N(z_j; ẑ_i, S_i) is the Gaussian measurement likelihood (Bojilov's
g_ij, eq. (2)) and λ the clutter spatial density (Bojilov's β). Dividing every
factor of a joint hypothesis weight (5) by λ^{N_M} — the common factor of (7) —
turns each "measurement j is clutter" factor into 1, each detection factor into
P_D g_ij/λ, and each missed track into (1 − P_D P_G) (the extra P_G accounts for
target-originated measurements falling outside the gate; Bar-Shalom, Daum &
Huang, IEEE Control Syst. Mag. 29(6), 2009). Everything is computed in log
space so densities of very sharp or very wide gates neither underflow nor
overflow before the final ratio.
"""

from __future__ import annotations

import functools
import itertools
from dataclasses import dataclass

import numpy as np
from scipy import special

from jointtrack.assignment._checks import _as_real_array, as_float

__all__ = [
    "Gating",
    "PairGating",
    "gate_measurements",
    "gate_pairs",
    "gate_threshold",
    "likelihood_ratio_pairs",
    "likelihood_ratios",
    "unit_ball_log_volume",
]

_LOG_2PI = float(np.log(2.0 * np.pi))
# exp() of anything above this overflows float64
_MAX_LOG = float(np.log(np.finfo(np.float64).max))


def unit_ball_log_volume(d: int) -> float:
    """log c_d, c_d = π^{d/2} / Γ(d/2 + 1) the volume of the unit ball in ℝ^d.

    Used for the gate volume V = c_d γ^{d/2} √|S| (Bar-Shalom & Li 1995, Bojilov's ref. [4];
    Bojilov's V_i(k) under eq. (8)).
    """
    if int(d) != d or d < 1:
        raise ValueError(f"dimension must be a positive integer, got {d!r}")
    d = int(d)
    return 0.5 * d * np.log(np.pi) - float(special.gammaln(0.5 * d + 1.0))


@dataclass(frozen=True)
class Gating:
    """Result of :func:`gate_measurements` for N tracks and M measurements in ℝ^d.

    Attributes
    ----------
    mask : (N, M) bool
        ``d2 <= gamma``: measurement j lies in track i's validation gate.
    d2 : (N, M) float
        squared Mahalanobis distances d²_ij (Bojilov, under eq. (2)).
    log_g : (N, M) float
        log N(z_j; ẑ_i, S_i), the log Gaussian likelihood g_ij (Bojilov eq. (2)),
        for every pair, gated or not.
    gate_volume : (N,) float
        V_i = c_d γ^{d/2} √|S_i| (may be ``inf`` only if it overflows float64;
        ``log_gate_volume`` is always finite).
    log_gate_volume : (N,) float
        log V_i.
    gamma : float
        gate threshold γ = χ²_d⁻¹(P_G).
    P_G : float
        gate probability.
    z_pred : (N, d) float
        predicted measurements (gate centres).
    S : (N, d, d) float
        innovation covariances (symmetrised copy of the input).
    chol : (N, d, d) float
        lower Cholesky factors of ``S``.
    """

    mask: np.ndarray
    d2: np.ndarray
    log_g: np.ndarray
    gate_volume: np.ndarray
    log_gate_volume: np.ndarray
    gamma: float
    P_G: float
    z_pred: np.ndarray
    S: np.ndarray
    chol: np.ndarray

    @property
    def n_tracks(self) -> int:
        return int(self.mask.shape[0])

    @property
    def n_measurements(self) -> int:
        return int(self.mask.shape[1])

    @property
    def dim(self) -> int:
        return int(self.z_pred.shape[1])

    @property
    def n_gated(self) -> np.ndarray:
        """m_i: number of measurements in each track's gate (Bojilov's m_i(k), eq. (8))."""
        return self.mask.sum(axis=1).astype(np.int64)


def _as_float(x, name: str) -> np.ndarray:
    """A real float64 array (the shared check: no complex, bool, string or huge int)."""
    return _as_real_array(x, name)


def _gate_volumes(d: int, gamma: float, half_logdet: np.ndarray):
    """log V_i and V_i = c_d γ^{d/2} √|S_i| (V may overflow to inf; log V is kept)."""
    log_vol = unit_ball_log_volume(d) + 0.5 * d * np.log(gamma) + half_logdet
    with np.errstate(over="ignore"):
        return log_vol, np.exp(log_vol)


@functools.lru_cache(maxsize=64)
def gate_threshold(P_G: float, d: int) -> float:
    """γ = χ²_d⁻¹(P_G) = 2 P⁻¹(d/2, P_G) (the regularised incomplete gamma function's
    inverse: scipy.stats.chi2.ppf computes exactly this, but importing scipy.stats costs
    each run ~0.8 s), cached: a tracker gates every scan with the same (P_G, d)."""
    return float(2.0 * special.gammaincinv(0.5 * d, P_G))


def _check_prob(p, name: str, *, open_left: bool = True) -> float:
    """A gate probability in (0, 1]; 1 is the infinite gate (γ = ∞, everything gated)."""
    return as_float(p, name, minimum=0.0, maximum=1.0, open_min=open_left)


def _cholesky_checked(S: np.ndarray) -> np.ndarray:
    """Lower Cholesky factors of a stack of symmetric positive definite matrices.

    Raises ValueError naming the first track whose covariance is non-finite,
    asymmetric, not positive definite or numerically singular.
    """
    n, d, _ = S.shape
    if n == 0:
        return np.zeros_like(S)
    finite = np.isfinite(S).reshape(n, -1).all(axis=1)
    if not finite.all():
        i = int(np.argmin(finite))
        raise ValueError(f"innovation covariance S[{i}] (track {i}) has non-finite entries")
    scale = np.abs(S).reshape(n, -1).max(axis=1)
    St = np.swapaxes(S, 1, 2)
    if not (S == St).all():  # an exactly symmetric S (a filter's output) has no asymmetry
        asym = np.abs(S - St).reshape(n, -1).max(axis=1)
        bad = asym > 1e-9 * np.maximum(scale, np.finfo(np.float64).tiny)
        if bad.any():
            i = int(np.argmax(bad))
            raise ValueError(
                f"innovation covariance S[{i}] (track {i}) is not symmetric "
                f"(max |S − Sᵀ| = {asym[i]:.3g})"
            )
    zero = scale == 0
    if zero.any():
        i = int(np.argmax(zero))
        raise ValueError(f"innovation covariance S[{i}] (track {i}) is the zero matrix (singular)")
    Ssym = 0.5 * (S + np.swapaxes(S, 1, 2))
    try:
        chol = np.linalg.cholesky(Ssym)
    except np.linalg.LinAlgError:
        chol = None
    if chol is None or not np.isfinite(chol).all():
        # find the offending track(s) one by one to name them
        for i in range(n):
            try:
                c = np.linalg.cholesky(Ssym[i])
            except np.linalg.LinAlgError:
                raise ValueError(
                    f"innovation covariance S[{i}] (track {i}) is not positive definite"
                ) from None
            if not np.isfinite(c).all():
                raise ValueError(
                    f"innovation covariance S[{i}] (track {i}) is not positive definite"
                )
        raise AssertionError("unreachable")  # pragma: no cover
    diag = np.diagonal(chol, axis1=1, axis2=2)
    # reciprocal condition estimate from the Cholesky pivots: cond(S) ≳ (max/min)²
    rc = (diag.min(axis=1) / diag.max(axis=1)) ** 2
    sing = ~(rc > d * np.finfo(np.float64).eps)
    if sing.any():
        i = int(np.argmax(sing))
        raise ValueError(
            f"innovation covariance S[{i}] (track {i}) is numerically singular "
            f"(reciprocal condition ≈ {rc[i]:.2g})"
        )
    return chol


def _residual_name(residual) -> str:
    name = getattr(residual, "__qualname__", None) or getattr(residual, "__name__", None)
    return name if name else repr(residual)


def _checked_residual(residual, z: np.ndarray, z_pred: np.ndarray) -> np.ndarray:
    """``residual(z, z_pred)`` for every pair, checked: real, finite, shape (N, M, d).

    A user residual function returning NaN (e.g. an angle wrap of a NaN or an
    ``arctan2`` of zeros gone wrong) would otherwise compare false against the
    gate threshold and silently un-gate the pair.
    """
    name = _residual_name(residual)
    n, d = z_pred.shape
    m = z.shape[0]
    try:
        raw = np.asarray(residual(z[None, :, :], z_pred[:, None, :]))
    except (TypeError, ValueError) as exc:
        raise ValueError(f"residual function {name} failed: {exc}") from None
    if raw.dtype.kind == "c":
        raise ValueError(
            f"residual function {name} returned complex innovations; they must be real"
        )
    if raw.dtype.kind not in "iuf":
        raise ValueError(
            f"residual function {name} returned non-numeric innovations (dtype {raw.dtype})"
        )
    innov = raw.astype(np.float64)
    if innov.shape != (n, m, d):
        try:
            innov = np.broadcast_to(innov, (n, m, d))
        except ValueError:
            raise ValueError(
                f"residual function {name} returned shape {raw.shape}; expected ({n}, {m}, {d}) "
                "(it must broadcast over the leading axes of z[None] and z_pred[:, None])"
            ) from None
    if not np.isfinite(innov).all():
        i, j = (int(v) for v in np.argwhere(~np.isfinite(innov).all(axis=2))[0])
        raise ValueError(
            f"residual function {name} returned a non-finite innovation "
            f"({innov[i, j].tolist()}) for track {i} and measurement z[{j}]"
        )
    return innov


def _validate_gate_inputs(z_pred, S, z, P_G):
    """Shared input checks of :func:`gate_measurements` and :func:`gate_pairs`.

    Returns ``(P_G, z_pred, S, z)`` as floats / float64 arrays, ``z`` of shape (M, d).
    """
    P_G = _check_prob(P_G, "P_G")
    z_pred = _as_float(z_pred, "z_pred")
    S = _as_float(S, "S")
    z = _as_float(z, "z")
    if z_pred.ndim != 2:
        raise ValueError(f"z_pred must be 2-D (tracks × dimension), got shape {z_pred.shape}")
    n, d = z_pred.shape
    if d < 1:
        raise ValueError("measurement dimension d must be at least 1")
    if S.shape != (n, d, d):
        raise ValueError(
            f"S must have shape (N, d, d) = ({n}, {d}, {d}) to match z_pred, got {S.shape}"
        )
    if z.ndim == 1 and z.size == 0:
        z = z.reshape(0, d)
    if z.ndim != 2 or z.shape[1] != d:
        raise ValueError(f"z must have shape (M, {d}) to match z_pred, got {z.shape}")
    if not np.isfinite(z_pred).all():
        i = int(np.argwhere(~np.isfinite(z_pred))[0, 0])
        raise ValueError(f"z_pred[{i}] (track {i}) is not finite")
    if not np.isfinite(z).all():
        j = int(np.argwhere(~np.isfinite(z))[0, 0])
        raise ValueError(f"measurement z[{j}] is not finite")
    return P_G, z_pred, S, z


def gate_measurements(z_pred, S, z, *, P_G: float = 0.99, residual=None) -> Gating:
    """Chi-square validation gates of N tracks applied to M measurements.

    Implements the ellipsoidal validation region d²_ij ≤ γ with γ = χ²_d⁻¹(P_G)
    (Bar-Shalom & Li 1995; Bojilov et al., d²_ij and g_ij of eq. (2)),
    the gate volume V_i = c_d γ^{d/2} √|S_i| used by the sample spatial density
    (Bojilov eq. (8)) and the log Gaussian likelihoods log g_ij.

    Parameters
    ----------
    z_pred : (N, d) array
        predicted measurements ẑ_i (gate centres).
    S : (N, d, d) array
        innovation covariances; each must be symmetric positive definite.
    z : (M, d) array
        measurements. An empty ``(0,)`` array means no measurements.
    P_G : float in (0, 1]; 1 is the infinite gate (γ = ∞: every measurement gated)
        gate probability.
    residual : callable, optional
        ``residual(z, z_pred)`` → innovation, broadcasting over leading axes;
        default ``z − z_pred``. Pass a measurement model's ``residual`` for
        angular components (e.g. ``RangeBearing.residual`` wraps the bearing).

    Returns
    -------
    Gating
        ``mask``, ``d2``, ``log_g``, ``gate_volume`` and friends.

    Raises
    ------
    ValueError
        wrong shapes, non-finite inputs, ``P_G`` outside (0, 1), a covariance
        that is asymmetric, not positive definite or singular (the message names
        the track), or a ``residual`` function returning NaN/inf, complex or
        wrongly shaped innovations (the message names the function).
    """
    P_G, z_pred, S, z = _validate_gate_inputs(z_pred, S, z, P_G)
    n, d = z_pred.shape
    m = z.shape[0]

    chol = _cholesky_checked(S)
    gamma = gate_threshold(P_G, d)
    half_logdet = np.log(np.diagonal(chol, axis1=1, axis2=2)).sum(axis=1) if n else np.zeros(0)

    if n and m:
        # whitened innovations: chol_i⁻¹ (z_j − ẑ_i), one batched solve for all tracks
        if residual is None:
            innov = z[None, :, :] - z_pred[:, None, :]  # (N, M, d)
        else:
            innov = _checked_residual(residual, z, z_pred)
        w = np.linalg.solve(chol, np.swapaxes(innov, 1, 2))  # (N, d, M)
        d2 = np.einsum("ndm,ndm->nm", w, w)
    else:
        d2 = np.zeros((n, m))
    log_g = -0.5 * d2 - 0.5 * d * _LOG_2PI - half_logdet[:, None]
    mask = d2 <= gamma
    log_vol, vol = _gate_volumes(d, gamma, half_logdet)
    return Gating(
        mask=mask,
        d2=d2,
        log_g=log_g,
        gate_volume=vol,
        log_gate_volume=log_vol,
        gamma=gamma,
        P_G=P_G,
        z_pred=z_pred.copy(),
        S=0.5 * (S + np.swapaxes(S, 1, 2)),
        chol=chol,
    )


def _check_pd_clutter(P_D, clutter_density, n: int, m: int) -> tuple[np.ndarray, np.ndarray]:
    """Validated ``(P_D per track, clutter density per measurement)`` float arrays."""
    pd = _as_float(P_D, "P_D")
    if pd.ndim == 0:
        pd = np.full(n, float(pd))
    if pd.shape != (n,):
        raise ValueError(f"P_D must be a scalar or have shape ({n},), got {pd.shape}")
    if not np.all(np.isfinite(pd)) or np.any((pd <= 0) | (pd > 1)):
        bad = pd[~(np.isfinite(pd) & (pd > 0) & (pd <= 1))][0]
        raise ValueError(f"P_D must lie in (0, 1], got {bad}")
    lam = _as_float(clutter_density, "clutter_density")
    if lam.ndim == 0:
        lam = np.full(m, float(lam))
    if lam.shape != (m,):
        raise ValueError(
            f"clutter_density must be a scalar or have shape ({m},) (one per measurement), "
            f"got {lam.shape}"
        )
    if not np.all(np.isfinite(lam)) or np.any(lam <= 0):
        bad = lam[~(np.isfinite(lam) & (lam > 0))][0]
        raise ValueError(f"clutter_density must be positive and finite, got {bad}")
    return pd, lam


def likelihood_ratios(gating: Gating, P_D, clutter_density) -> tuple[np.ndarray, np.ndarray]:
    """Gated likelihood-ratio matrix ``L`` and miss weights in the JPDA cluster convention.

    ``L[i, j] = P_D g_ij / λ`` where measurement j is in track i's gate, else 0;
    ``miss[i] = 1 − P_D P_G``. These are the factors of Bojilov's hypothesis
    weight (5) after division by the common factor λ^{N_M} of (7) (clutter
    factors become 1), with the P_G correction for gated detection
    (the PDAF gate correction of Bar-Shalom, Daum & Huang, "The probabilistic data
    association filter", IEEE Control Syst. Mag. 29(6), 2009; DESIGN.md convention). Computed as
    ``exp(log P_D + log g_ij − log λ)``.

    Parameters
    ----------
    gating : Gating
        from :func:`gate_measurements`.
    P_D : float or (N,) array in (0, 1]
        detection probability (per track if an array).
    clutter_density : float or (M,) array, > 0
        clutter spatial density λ (Bojilov's β), one value or one per measurement
        (e.g. from :mod:`jointtrack.association.clutter`).

    Returns
    -------
    (L, miss) : ((N, M) array, (N,) array)

    Raises
    ------
    ValueError
        ``P_D`` outside (0, 1], non-positive or non-finite clutter density, wrong
        shapes, or a ratio that overflows float64 (clutter density absurdly small
        relative to the measurement likelihood).
    """
    if not isinstance(gating, Gating):
        raise ValueError("gating must be a Gating result from gate_measurements")
    n, m = gating.mask.shape
    pd, lam = _check_pd_clutter(P_D, clutter_density, n, m)
    log_L = np.log(pd)[:, None] + gating.log_g - np.log(lam)[None, :]
    log_L = np.where(gating.mask, log_L, -np.inf)
    if np.any(log_L > _MAX_LOG):
        i, j = (int(v) for v in np.argwhere(log_L > _MAX_LOG)[0])
        raise ValueError(
            f"likelihood ratio L[{i}, {j}] = exp({log_L[i, j]:.4g}) overflows float64: the "
            "clutter density is too small relative to the measurement likelihood"
        )
    L = np.exp(log_L)
    miss = 1.0 - pd * gating.P_G
    return L, miss


# ------------------------------------------------------------------ sparse (pair) gating

# relative slack on the KD-tree search radius √(γ λ_max(S_i)): covers the rounding of
# λ_max (eigvalsh, ~d·ε relative), of the tree's distance arithmetic (~d·ε) and of the
# whitened distance d²_ij itself (≲ √cond(S)·ε ≈ 3e-8 at the singularity limit of
# _cholesky_checked), so that no pair the dense computation would gate is ever missed.
_RADIUS_SLACK = 1e-4
#: Up to this many pairs N·M, :func:`gate_pairs` evaluates d² for every pair instead of
#: querying a KD-tree (the tree's set-up dominates tiny scans, e.g. one AIS report
#: against a hundred tracks); the gated set is the same, the candidates a superset.
ALL_PAIRS_MAX = 512
#: Largest number of candidate pairs listed by the KD-tree ball query (about
#: 100 bytes each downstream); past it each gate keeps its nearest returns.
MAX_CANDIDATES = 2**21


@dataclass(frozen=True)
class PairGating:
    """Sparse result of :func:`gate_pairs`: only the gated (track, measurement) pairs.

    Same quantities and definitions as :class:`Gating`, stored per gated pair
    instead of as dense N × M arrays. Pairs are sorted by track (``rows``), then
    by measurement (``cols``) — the order of ``np.nonzero(gating.mask)``.

    Attributes
    ----------
    rows, cols : (P,) int64
        track and measurement index of each gated pair (d²_ij ≤ γ).
    d2 : (P,) float
        squared Mahalanobis distances d²_ij of the gated pairs.
    log_g : (P,) float
        log N(z_j; ẑ_i, S_i) of the gated pairs.
    gate_volume, log_gate_volume : (N,) float
        V_i = c_d γ^{d/2} √|S_i| and its log, as in :class:`Gating`.
    gamma, P_G : float
        gate threshold γ = χ²_d⁻¹(P_G) and gate probability.
    n_tracks, n_measurements : int
        N and M.
    n_candidates : int
        number of (track, measurement) pairs whose d² was evaluated: the
        KD-tree ball candidates, or N·M on the dense fallback (``residual``
        given) and for tiny problems (N·M ≤ :data:`ALL_PAIRS_MAX`). At
        constant density this grows like N + M, not N·M.
    z_pred : (N, d) float
        gate centres.
    S : (N, d, d) float
        innovation covariances (symmetrised copy of the input).
    chol : (N, d, d) float
        lower Cholesky factors of ``S``.
    """

    rows: np.ndarray
    cols: np.ndarray
    d2: np.ndarray
    log_g: np.ndarray
    gate_volume: np.ndarray
    log_gate_volume: np.ndarray
    gamma: float
    P_G: float
    n_tracks: int
    n_measurements: int
    n_candidates: int
    z_pred: np.ndarray
    S: np.ndarray
    chol: np.ndarray

    @property
    def dim(self) -> int:
        return int(self.z_pred.shape[1])

    @property
    def n_pairs(self) -> int:
        """P, the number of gated pairs."""
        return int(self.rows.size)

    @property
    def n_gated(self) -> np.ndarray:
        """m_i: number of measurements in each track's gate (Bojilov's m_i(k), eq. (8))."""
        return np.bincount(self.rows, minlength=self.n_tracks).astype(np.int64)

    @property
    def indptr(self) -> np.ndarray:
        """(N + 1,) CSR row pointer: track i's pairs are ``indptr[i]:indptr[i + 1]``."""
        out = np.zeros(self.n_tracks + 1, dtype=np.int64)
        np.cumsum(self.n_gated, out=out[1:])
        return out

    def dense(self) -> Gating:
        """The equivalent dense :class:`Gating` (for tests and small problems).

        ``mask``, ``gate_volume``, ``gamma`` … equal those of
        :func:`gate_measurements`, and so do ``d2`` / ``log_g`` on the gated
        pairs. Entries of ungated pairs are not computed by :func:`gate_pairs`:
        they hold ``d2 = inf`` and ``log_g = -inf`` (g = 0), which every
        consumer of a :class:`Gating` ignores or treats as "not gated".
        Allocates three N × M arrays.
        """
        n, m = self.n_tracks, self.n_measurements
        mask = np.zeros((n, m), dtype=bool)
        d2 = np.full((n, m), np.inf)
        log_g = np.full((n, m), -np.inf)
        mask[self.rows, self.cols] = True
        d2[self.rows, self.cols] = self.d2
        log_g[self.rows, self.cols] = self.log_g
        return Gating(
            mask=mask,
            d2=d2,
            log_g=log_g,
            gate_volume=self.gate_volume.copy(),
            log_gate_volume=self.log_gate_volume.copy(),
            gamma=self.gamma,
            P_G=self.P_G,
            z_pred=self.z_pred.copy(),
            S=self.S.copy(),
            chol=self.chol.copy(),
        )


def _pair_d2(chol: np.ndarray, rows: np.ndarray, innov: np.ndarray) -> np.ndarray:
    """d²_p = |L_{rows[p]}⁻¹ innov_p|² by batched forward substitution over the pairs."""
    p, d = innov.shape
    Lr = chol[rows]  # (P, d, d)
    w = np.empty((p, d))
    with np.errstate(over="ignore", invalid="ignore"):
        for k in range(d):
            acc = innov[:, k].copy()
            for l in range(k):
                acc -= Lr[:, k, l] * w[:, l]
            w[:, k] = acc / Lr[:, k, k]
        return np.einsum("pd,pd->p", w, w)


def _ball_candidates(
    z_pred: np.ndarray, Ssym: np.ndarray, z: np.ndarray, gamma: float
) -> tuple[np.ndarray, np.ndarray]:
    """Candidate pairs (rows, cols), sorted, with z_j in the ball ⊇ track i's gate.

    The gate {e : eᵀS_i⁻¹e ≤ γ} lies in the ball |e| ≤ √(γ λ_max(S_i)); the balls
    are queried on a KD-tree of the measurements.
    """
    from scipy.spatial import cKDTree

    n = z_pred.shape[0]
    m = z.shape[0]
    with np.errstate(over="ignore", invalid="ignore"):
        lam_max = np.linalg.eigvalsh(Ssym)[:, -1]
        radius = np.sqrt(gamma * np.maximum(lam_max, 0.0)) * (1.0 + _RADIUS_SLACK)
    finite = np.isfinite(radius)
    radius = np.where(finite, radius, 0.0)
    # the tree squares coordinate differences: past ~1e150 they overflow, so query the
    # enclosing cube (Chebyshev ball, p = inf, same radius ⊇ Euclidean ball) instead
    with np.errstate(over="ignore"):
        extent = 2.0 * max(np.abs(z).max(), np.abs(z_pred).max()) + radius.max()
    p_norm = 2.0 if extent < 1e150 else np.inf
    tree = cKDTree(z)
    # count before listing: where everything coincides the lists are N·M long. The
    # slab |x − x_i| ≤ r_i holds the ball: its count (two binary searches) is a cheap
    # upper bound, and only past the budget are the balls counted on the tree
    if n * m > MAX_CANDIDATES and (
        slab_count(z[:, 0], z_pred[:, 0], radius) + m * int((~finite).sum()) > MAX_CANDIDATES
    ):
        counts = tree.query_ball_point(z_pred, radius, p=p_norm, return_length=True)
        total = int(counts.sum()) + m * int((~finite).sum())
        if total > MAX_CANDIDATES:
            return _nearest_candidates(tree, z_pred, radius, p_norm, total)
    hits = tree.query_ball_point(z_pred, radius, p=p_norm, return_sorted=True)
    if not finite.all():  # λ_max overflowed: every measurement is a candidate
        everything = list(range(m))
        for i in np.flatnonzero(~finite):
            hits[i] = everything
    counts = np.fromiter(map(len, hits), dtype=np.int64, count=n)
    total = int(counts.sum())
    cols = np.fromiter(itertools.chain.from_iterable(hits), dtype=np.int64, count=total)
    rows = np.repeat(np.arange(n, dtype=np.int64), counts)
    return rows, cols


def slab_count(points, centres, half_width) -> int:
    """Σ_i #{j : |points[j] − centres[i]| ≤ half_width[i]} (1-D), an upper bound on ball counts."""
    if points.size == 0 or centres.size == 0:
        return 0
    xs = np.sort(points)
    half_width = np.broadcast_to(half_width, centres.shape)
    order = np.argsort(centres)  # sorted needles: the searches walk memory in order
    c, w = centres[order], half_width[order]
    with np.errstate(invalid="ignore", over="ignore"):
        hi = np.searchsorted(xs, c + w, side="right")
        lo = np.searchsorted(xs, c - w, side="left")
    return int((hi - lo).sum())


def _nearest_candidates(tree, z_pred, radius, p_norm, total):
    """Each track's k nearest measurements within its ball, k·N ≤ MAX_CANDIDATES.

    Used only when the balls hold more than :data:`MAX_CANDIDATES` pairs (e.g. thousands
    of tracks and returns on one spot), where the full gate lists would not fit in
    memory: each gate keeps its ``k`` nearest returns (an approximation, logged).
    """
    import logging

    n = z_pred.shape[0]
    k = max(1, min(MAX_CANDIDATES // n, tree.n))
    logging.getLogger("jointtrack.association").warning(
        "gating: %d candidate (track, return) pairs exceed the budget of %d; each of the "
        "%d gates keeps its %d nearest returns",
        total,
        MAX_CANDIDATES,
        n,
        k,
    )
    r = np.where(np.isfinite(radius), radius, np.inf)
    d, idx = tree.query(z_pred, k=k, p=p_norm)
    d, idx = d.reshape(n, k), idx.reshape(n, k)
    keep = (d <= r[:, None]) & (idx < tree.n)  # tree.n: fewer than k returns
    rows = np.repeat(np.arange(n, dtype=np.int64), keep.sum(axis=1))
    cols = np.sort(np.where(keep, idx, tree.n), axis=1)  # sorted per track, misses last
    cols = cols[cols < tree.n].astype(np.int64)
    return rows, cols


def gate_pairs(z_pred, S, z, *, P_G: float = 0.99, residual=None) -> PairGating:
    """Sparse chi-square gating: :func:`gate_measurements` without N × M arrays.

    Same gate d²_ij ≤ γ, γ = χ²_d⁻¹(P_G), likelihoods log g_ij and gate volumes
    V_i as :func:`gate_measurements` (Bar-Shalom & Li 1995; Bojilov et al.
    eq. (2), (8)), but only the gated pairs are returned and, with the default
    Euclidean residual, only O(N + M) candidate pairs are examined at constant
    measurement density:

    1. KD-tree (:class:`scipy.spatial.cKDTree`) on the measurements;
    2. per track, the ball of radius √(γ λ_max(S_i)) — which contains the gate
       ellipsoid — is queried (λ_max batched with :func:`numpy.linalg.eigvalsh`);
    3. d² is evaluated for the candidates only, with the per-track Cholesky
       factors (batched forward substitution), and the pairs with d² ≤ γ kept.

    When N·M ≤ :data:`ALL_PAIRS_MAX` steps 1–2 are skipped and every pair is a
    candidate. Cost O((N + M) log M + candidates) time and O(N + M + candidates) memory.
    The candidates are counted before they are listed (a slab bound, then the
    tree's ball counts): past :data:`MAX_CANDIDATES` (e.g. thousands of tracks and
    returns piled on one spot, where the lists are N·M long) each gate keeps only
    its nearest ``MAX_CANDIDATES // N`` returns within its ball, with a warning on
    the ``jointtrack.association`` logger — an approximation that keeps memory
    bounded.

    With a ``residual`` function (e.g. a wrapped bearing) Euclidean balls do not
    bound the gate, so it falls back to the dense :func:`gate_measurements` and
    converts the result to pairs (O(N·M)).

    Parameters, validation and error messages are those of
    :func:`gate_measurements`. The gated set and the per-pair values agree with
    it up to floating-point rounding of d² (≈1e-15 relative; a pair exactly on
    the gate boundary may round either way).

    Returns
    -------
    PairGating
    """
    P_G, z_pred, S, z = _validate_gate_inputs(z_pred, S, z, P_G)
    n, d = z_pred.shape
    m = z.shape[0]
    if residual is not None:
        g = gate_measurements(z_pred, S, z, P_G=P_G, residual=residual)
        rows, cols = (a.astype(np.int64) for a in np.nonzero(g.mask))
        return PairGating(
            rows=rows,
            cols=cols,
            d2=g.d2[rows, cols],
            log_g=g.log_g[rows, cols],
            gate_volume=g.gate_volume,
            log_gate_volume=g.log_gate_volume,
            gamma=g.gamma,
            P_G=g.P_G,
            n_tracks=n,
            n_measurements=m,
            n_candidates=n * m,
            z_pred=g.z_pred,
            S=g.S,
            chol=g.chol,
        )

    chol = _cholesky_checked(S)
    Ssym = 0.5 * (S + np.swapaxes(S, 1, 2))
    gamma = gate_threshold(P_G, d)
    half_logdet = np.log(np.diagonal(chol, axis1=1, axis2=2)).sum(axis=1) if n else np.zeros(0)

    if n and m and n * m <= ALL_PAIRS_MAX:
        # a few pairs: d² of all of them costs less than building and querying a tree
        rows, cols = np.divmod(np.arange(n * m, dtype=np.int64), m)
    elif n and m:
        rows, cols = _ball_candidates(z_pred, Ssym, z, gamma)
    else:
        rows = cols = np.zeros(0, dtype=np.int64)
    n_candidates = int(rows.size)
    d2 = _pair_d2(chol, rows, z[cols] - z_pred[rows])
    keep = d2 <= gamma
    rows, cols, d2 = rows[keep], cols[keep], d2[keep]
    # same expression (and evaluation order) as gate_measurements
    log_g = -0.5 * d2 - 0.5 * d * _LOG_2PI - half_logdet[rows]
    log_vol, vol = _gate_volumes(d, gamma, half_logdet)
    return PairGating(
        rows=rows,
        cols=cols,
        d2=d2,
        log_g=log_g,
        gate_volume=vol,
        log_gate_volume=log_vol,
        gamma=gamma,
        P_G=P_G,
        n_tracks=n,
        n_measurements=m,
        n_candidates=n_candidates,
        z_pred=z_pred.copy(),
        S=Ssym,
        chol=chol,
    )


def likelihood_ratio_pairs(
    gating: PairGating, P_D, clutter_density
) -> tuple[np.ndarray, np.ndarray]:
    """Likelihood ratios of the gated pairs of a :class:`PairGating` and miss weights.

    The sparse counterpart of :func:`likelihood_ratios`, same conventions
    (DESIGN.md; Bojilov eq. (5)/(7) divided by λ^{N_M}): for pair p = (i, j)

        L_p = P_D,i g_ij / λ_j = exp(log P_D,i + log g_ij − log λ_j),
        miss[i] = 1 − P_D,i P_G,

    so ``L_p`` equals ``likelihood_ratios(gating.dense(), …)[0][i, j]`` and every
    ungated entry of the dense matrix is 0.

    Parameters
    ----------
    gating : PairGating
        from :func:`gate_pairs`.
    P_D : float or (N,) array in (0, 1]
    clutter_density : float or (M,) array, > 0
        one value or one per measurement.

    Returns
    -------
    (L, miss) : ((P,) array aligned with ``gating.rows`` / ``gating.cols``, (N,) array)

    Raises
    ------
    ValueError
        as :func:`likelihood_ratios`.
    """
    if not isinstance(gating, PairGating):
        raise ValueError("gating must be a PairGating result from gate_pairs")
    n, m = gating.n_tracks, gating.n_measurements
    pd, lam = _check_pd_clutter(P_D, clutter_density, n, m)
    rows, cols = gating.rows, gating.cols
    log_L = np.log(pd)[rows] + gating.log_g - np.log(lam)[cols]
    over = log_L > _MAX_LOG
    if np.any(over):
        p = int(np.argmax(over))
        i, j = int(rows[p]), int(cols[p])
        raise ValueError(
            f"likelihood ratio L[{i}, {j}] = exp({log_L[p]:.4g}) overflows float64: the "
            "clutter density is too small relative to the measurement likelihood"
        )
    L = np.exp(log_L)
    miss = 1.0 - pd * gating.P_G
    return L, miss
