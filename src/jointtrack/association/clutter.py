"""Clutter spatial density λ (Bojilov's β) for a JPDA cluster.

Four estimators:

* :func:`known_density` — λ given by the sensor model (passthrough, checked).
* :func:`track_sample_density` — the non-parametric PDA "sample spatial
  density" of one track, λ_i = m_i / V_i (Bar-Shalom & Li 1995, quoted by
  Bojilov et al. §3).
* :func:`cluster_heuristic_density` — Bojilov's heuristic (8),
  λ = Σ_i m_i / Σ_i V_i.
* :func:`union_sample_density` — the cluster sample density Bojilov's heuristic
  approximates, λ = N_M / |V_1 ∪ … ∪ V_N| with N_M the number of distinct
  measurements in the cluster, the union volume of the ellipsoidal gates
  estimated by Monte Carlo (:func:`union_gate_volume`, with a standard error).

How far is (8) from the union density? Write c(x) for the number of gates that
contain the point x. Then Σ_i m_i = Σ_j c(z_j) and Σ_i V_i = ∫_∪ c(x) dx, so

    (8) / union density = c̄_meas / c̄_vol,

the mean gate multiplicity of the cluster's measurements divided by the mean
multiplicity of its volume. The heuristic is exact whenever the measurements
overlap exactly as much as the gates do — identical gates (c ≡ N), disjoint
gates (c ≡ 1) — and is unbiased for Poisson clutter (E Σ m_i = λ Σ V_i). It is
off by up to a factor N (in either direction) when measurements sit
preferentially in, or away from, the overlaps: e.g. two unit discs whose
centres are one radius apart (overlap ≈ 39% of each disc) with every
measurement in the lens gives (8) = 2/1.243 = 1.61 × the union density.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from jointtrack.assignment._checks import _as_real_array
from jointtrack.association._validate import check_indices, check_integer
from jointtrack.association.gating import (
    Gating,
    _cholesky_checked,
    gate_threshold,
    unit_ball_log_volume,
)

__all__ = [
    "ClutterEstimate",
    "UnionVolume",
    "cluster_clutter_density",
    "cluster_heuristic_density",
    "cluster_heuristic_densities",
    "known_density",
    "track_sample_density",
    "union_gate_volume",
    "union_sample_density",
]


@dataclass(frozen=True)
class UnionVolume:
    """Monte Carlo estimate of |V_1 ∪ … ∪ V_N| (:func:`union_gate_volume`).

    ``volume`` ± ``std_error`` (one standard error); ``sum_volume`` = Σ V_i, so
    ``sum_volume / volume`` is the mean gate multiplicity c̄_vol of the union.
    """

    volume: float
    std_error: float
    sum_volume: float
    n_samples: int


@dataclass(frozen=True)
class ClutterEstimate:
    """A clutter density estimate λ with its (Monte Carlo) standard error.

    ``std_error`` is 0 for the closed-form estimators; ``union_volume`` is set
    only by the union estimator.
    """

    density: float
    std_error: float
    method: str
    union_volume: UnionVolume | None = None


def _float_array(x, name: str) -> np.ndarray:
    """A real float64 array (the shared check: no complex, bool, string or huge int)."""
    return _as_real_array(x, name)


def _counts_volumes(m, V) -> tuple[np.ndarray, np.ndarray]:
    m = _float_array(m, "m (measurement counts)")
    V = _float_array(V, "V (gate volumes)")
    if m.ndim != 1 or V.ndim != 1 or m.shape != V.shape:
        raise ValueError(
            f"measurement counts and gate volumes must be 1-D of equal length, got {m.shape} "
            f"and {V.shape}"
        )
    if not np.all(np.isfinite(m)) or np.any(m < 0) or np.any(m != np.round(m)):
        raise ValueError("measurement counts must be non-negative integers")
    if not np.all(np.isfinite(V)) or np.any(V <= 0):
        i = int(np.argmax(~(np.isfinite(V) & (V > 0))))
        raise ValueError(f"gate volume V[{i}] = {V[i]} must be positive and finite")
    return m, V


def known_density(clutter_density) -> float:
    """A known clutter spatial density λ (Bojilov's β in eqs. (1), (2), (5)), checked.

    Raises ValueError unless λ is a positive finite number.
    """
    try:
        lam = float(clutter_density)
    except (TypeError, ValueError):
        raise ValueError(f"clutter density must be a number, got {clutter_density!r}") from None
    if not np.isfinite(lam) or lam <= 0:
        raise ValueError(f"clutter density must be positive and finite, got {lam}")
    return lam


def track_sample_density(n_gated, gate_volume) -> np.ndarray:
    """Per-track non-parametric sample spatial density λ_i = m_i / V_i.

    Bar-Shalom & Li (1995), quoted by Bojilov et al. §3 ("β = m(k)/V(k)"). A
    track with an empty gate gets λ_i = 0 (it needs no clutter density: its
    row of L is empty).

    Parameters
    ----------
    n_gated : (N,) integer counts m_i (e.g. ``Gating.n_gated``)
    gate_volume : (N,) positive volumes V_i (e.g. ``Gating.gate_volume``)
    """
    m, V = _counts_volumes(n_gated, gate_volume)
    return m / V


def cluster_heuristic_density(n_gated, gate_volume) -> float:
    """Bojilov's heuristic cluster clutter density, eq. (8): λ = Σ_i m_i / Σ_i V_i.

    Shared measurements are counted once per gate that holds them, overlapping
    volume once per gate that covers it. See the module docstring for its exact
    relation to the union density.

    Raises ValueError on empty input, negative/non-integer counts,
    non-positive volumes, or volumes so small that λ exceeds the float range
    (e.g. one return in a gate of volume 1e-320) or so large that their sum
    does: λ is never returned as inf, nor silently as 0.
    """
    m, V = _counts_volumes(n_gated, gate_volume)
    if m.size == 0:
        raise ValueError("cluster has no tracks: the density (8) is undefined")
    return float(cluster_heuristic_densities(m, V, np.zeros(m.size, np.int64))[0])


def cluster_heuristic_densities(n_gated, gate_volume, track_cluster) -> np.ndarray:
    """Bojilov's (8), λ_k = Σ_{i ∈ k} m_i / Σ_{i ∈ k} V_i, for every cluster k at once.

    ``track_cluster`` (N,) gives each track's cluster label 0…K−1 (e.g.
    ``Clustering.track_cluster``); returns the (K,) densities in one pass, so a
    scan with thousands of clusters costs O(N). Raises ValueError, like
    :func:`cluster_heuristic_density`, if a density exceeds the float range.
    """
    m, V = _counts_volumes(n_gated, gate_volume)
    lab = np.asarray(track_cluster)
    if lab.shape != m.shape or (lab.size and (lab.min() < 0 or lab.dtype.kind not in "iu")):
        raise ValueError("track_cluster must hold one non-negative integer label per track")
    k = int(lab.max()) + 1 if lab.size else 0
    vol = np.bincount(lab, weights=V, minlength=k)
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
        lam = np.bincount(lab, weights=m, minlength=k) / vol
    if k and not (vol > 0).all():
        c = int(np.argmax(~(vol > 0)))
        raise ValueError(f"track_cluster has no track with label {c}: labels must be 0…K−1")
    if not np.isfinite(lam).all():
        # m / ΣV beyond the float range: refuse rather than return λ = inf (which
        # would silently zero every likelihood ratio of the cluster)
        c = int(np.argmax(~np.isfinite(lam)))
        raise ValueError(
            f"clutter density of cluster {c} overflows: its gate volumes sum to {vol[c]:.3g}, "
            "too small for a finite density Σ m_i / Σ V_i (gate_volume)"
        )
    if not np.isfinite(vol).all():  # ΣV overflowed: λ would silently underflow to 0
        c = int(np.argmax(~np.isfinite(vol)))
        raise ValueError(
            f"the gate volumes of cluster {c} sum beyond the float range (gate_volume); "
            "its clutter density Σ m_i / Σ V_i would underflow"
        )
    return lam


def _gates(centers, S, P_G, gamma):
    c = _float_array(centers, "centers")
    if c.ndim != 2 or c.shape[0] == 0 or c.shape[1] == 0:
        raise ValueError(f"centers must have shape (N ≥ 1, d ≥ 1), got {c.shape}")
    n, d = c.shape
    if not np.all(np.isfinite(c)):
        raise ValueError("centers must be finite")
    S = _float_array(S, "S")
    if S.shape != (n, d, d):
        raise ValueError(f"S must have shape ({n}, {d}, {d}) to match centers, got {S.shape}")
    chol = _cholesky_checked(S)
    if (P_G is None) == (gamma is None):
        raise ValueError("give exactly one of P_G (gate probability) or gamma (threshold)")
    if gamma is None:
        P_G = float(P_G)
        if not 0.0 < P_G < 1.0:
            raise ValueError(f"P_G must lie strictly between 0 and 1, got {P_G}")
        gamma = gate_threshold(P_G, d)
    gamma = float(gamma)
    if not np.isfinite(gamma) or gamma <= 0:
        raise ValueError(f"gate threshold gamma must be positive and finite, got {gamma}")
    return c, chol, gamma


def union_gate_volume(
    centers,
    S,
    *,
    P_G: float | None = None,
    gamma: float | None = None,
    n_samples: int = 100_000,
    rng=None,
) -> UnionVolume:
    """Volume of the union of ellipsoidal gates {x : (x−ẑ_i)ᵀS_i⁻¹(x−ẑ_i) ≤ γ}, by Monte Carlo.

    The denominator of the exact cluster sample density that Bojilov's (8)
    approximates (§3, "the total volume of all validation regions without
    duplicating the overlapping parts"). Estimator of Karp, Luby & Madras
    (J. Algorithms 10, 1989) for a union of sets of known volume: draw a gate i
    with probability V_i/ΣV, a point x uniform in it, and average 1/c(x),
    c(x) the number of gates containing x; then |∪V_i| = ΣV · E[1/c(x)].
    Since 1/c ∈ [1/N, 1] the relative standard error is at most (N−1)/(2√n),
    and it is exactly 0 for identical or for disjoint gates.

    Parameters
    ----------
    centers : (N, d) gate centres ẑ_i
    S : (N, d, d) symmetric positive definite innovation covariances
    P_G, gamma : give one — gate probability, or the threshold γ = χ²_d⁻¹(P_G)
    n_samples : number of Monte Carlo points, a whole number ≥ 2
    rng : numpy Generator, int seed or None

    Returns
    -------
    UnionVolume (volume, one standard error, ΣV_i, n_samples)
    """
    c, chol, gamma = _gates(centers, S, P_G, gamma)
    n_samples = check_integer(n_samples, "n_samples", minimum=2)
    rng = np.random.default_rng(rng)
    n, d = c.shape
    half_logdet = np.log(np.diagonal(chol, axis1=1, axis2=2)).sum(axis=1)
    log_V = unit_ball_log_volume(d) + 0.5 * d * np.log(gamma) + half_logdet
    log_sum = float(np.logaddexp.reduce(log_V))
    p = np.exp(log_V - log_sum)
    p /= p.sum()
    chol_inv = np.linalg.inv(chol)
    r = np.sqrt(gamma)
    chunk = max(1, min(n_samples, 4_000_000 // max(1, n * d)))
    s1 = 0.0
    s2 = 0.0
    done = 0
    while done < n_samples:
        k = min(chunk, n_samples - done)
        which = rng.choice(n, size=k, p=p)
        g = rng.standard_normal((k, d))
        g /= np.linalg.norm(g, axis=1, keepdims=True)
        u = g * rng.random(k)[:, None] ** (1.0 / d)  # uniform in the unit ball
        x = c[which] + r * np.einsum("kab,kb->ka", chol[which], u)
        w = np.einsum("nab,knb->kna", chol_inv, x[:, None, :] - c[None, :, :])
        inside = np.einsum("kna,kna->kn", w, w) <= gamma
        inside[np.arange(k), which] = True  # the source gate contains x (guard rounding)
        inv_c = 1.0 / inside.sum(axis=1)
        s1 += float(inv_c.sum())
        s2 += float((inv_c * inv_c).sum())
        done += k
    mean = s1 / n_samples
    var = max(s2 / n_samples - mean * mean, 0.0) * n_samples / (n_samples - 1)
    sum_volume = float(np.exp(log_sum))
    return UnionVolume(
        volume=sum_volume * mean,
        std_error=sum_volume * np.sqrt(var / n_samples),
        sum_volume=sum_volume,
        n_samples=n_samples,
    )


def union_sample_density(
    n_measurements: int,
    centers,
    S,
    *,
    P_G: float | None = None,
    gamma: float | None = None,
    n_samples: int = 100_000,
    rng=None,
) -> ClutterEstimate:
    """Exact cluster sample spatial density λ = N_M / |V_1 ∪ … ∪ V_N| (Bojilov §3).

    ``n_measurements`` is N_M, the number of *distinct* measurements in the
    cluster. The union volume comes from :func:`union_gate_volume`; the
    returned standard error is the delta-method one, N_M/U² · se(U).
    """
    try:
        nm = int(n_measurements)
    except (TypeError, ValueError):
        raise ValueError(f"n_measurements must be an integer, got {n_measurements!r}") from None
    if nm != n_measurements or nm < 0:
        raise ValueError(f"n_measurements must be a non-negative integer, got {n_measurements}")
    uv = union_gate_volume(centers, S, P_G=P_G, gamma=gamma, n_samples=n_samples, rng=rng)
    dens = nm / uv.volume
    return ClutterEstimate(
        density=float(dens),
        std_error=float(dens * uv.std_error / uv.volume),
        method="union",
        union_volume=uv,
    )


def cluster_clutter_density(
    gating: Gating,
    tracks=None,
    *,
    method: str = "heuristic",
    n_samples: int = 100_000,
    rng=None,
) -> ClutterEstimate:
    """Clutter density of a cluster of tracks straight from a :class:`Gating` result.

    ``method="heuristic"`` is Bojilov's (8), Σ m_i / Σ V_i; ``method="union"`` is
    N_M / |∪ V_i| (N_M = distinct measurements gated by the cluster's tracks)
    by :func:`union_sample_density`. ``tracks`` selects the cluster (default: all).
    """
    if not isinstance(gating, Gating):
        raise ValueError("gating must be a Gating result from gate_measurements")
    idx = np.arange(gating.n_tracks) if tracks is None else check_indices(tracks, "tracks")
    if idx.ndim != 1 or idx.size == 0:
        raise ValueError("tracks must be a non-empty 1-D index array")
    if np.any((idx < 0) | (idx >= gating.n_tracks)):
        raise ValueError(f"track index out of range 0..{gating.n_tracks - 1}")
    if method == "heuristic":
        lam = cluster_heuristic_density(gating.n_gated[idx], gating.gate_volume[idx])
        return ClutterEstimate(density=lam, std_error=0.0, method="heuristic")
    if method == "union":
        nm = int(gating.mask[idx].any(axis=0).sum())
        return union_sample_density(
            nm, gating.z_pred[idx], gating.S[idx], gamma=gating.gamma, n_samples=n_samples, rng=rng
        )
    raise ValueError(f"unknown method {method!r}: use 'heuristic' or 'union'")
