r"""How far identity probabilities are from the truth: V (53), class aggregation, max KL (58).

D. E. Schaub, "Joint identification of multiple tracked targets", *Journal of
Advances in Information Fusion* 12(1), 2017, §4-A.4.

With U the true track-to-identity map, the best any method can reach is the
asymptotic matrix (53): V[t, i] = 1/|𝓘(i)| when a member of i's class 𝓘(i)
sits on t, else 0 — indistinguishable identities share their track's
probability. Methods are compared by the largest Kullback–Leibler divergence
over the observed tracks (58),

.. math::

    \max_{t \in T_O} D_{KL}(V_t \,\|\, P_t) = \max_t \sum_i V_{t,i} \ln\frac{V_{t,i}}{P_{t,i}},

in nats, with 0·ln 0 = 0. It is +inf when P gives probability 0 to an identity
V allows — always the case for the one-hot maximum-weight matching (56) until
it is right, and for every one-hot answer when classes have more than one
member; the class-aggregated divergence (V and P summed over each class's
columns) is then the meaningful one: it is 0 exactly when the right class has
all the mass.
"""

from __future__ import annotations

import numpy as np

from jointtrack.assignment._checks import _as_real_array

__all__ = ["aggregate_classes", "asymptotic_matrix", "expand_columns", "kl_rows", "max_kl"]


def _probabilities(P, name):
    arr = _as_real_array(P, name)
    if arr.ndim != 2:
        raise ValueError(f"{name} must be 2-D (tracks × identities), got {arr.ndim} dimension(s)")
    if not np.isfinite(arr).all() or (arr < 0).any() or (arr > 1 + 1e-9).any():
        raise ValueError(f"{name} must hold probabilities in [0, 1]")
    return arr


def _classes(classes, n, name="classes"):
    arr = np.asarray(classes)
    if arr.shape != (n,) or arr.dtype.kind not in "iu" or (arr.size and arr.min() < 0):
        raise ValueError(f"{name} must be {n} non-negative class indices, one per identity")
    return arr.astype(np.int64)


def asymptotic_matrix(truth, classes) -> np.ndarray:
    """V of eq. (53): (observed tracks × identities).

    ``truth[t]`` is the identity on observed track t; ``classes[i]`` the class of
    identity i (identities with the same class index are indistinguishable).
    """
    classes = np.asarray(classes)
    cl = _classes(classes, classes.shape[0] if classes.ndim == 1 else -1)
    truth = np.asarray(truth)
    if (
        truth.ndim != 1
        or truth.dtype.kind not in "iu"
        or truth.size
        and (truth.min() < 0 or truth.max() >= cl.size)
    ):
        raise ValueError(f"truth must be identity indices in [0, {cl.size}), one per track")
    sizes = np.bincount(cl)
    V = (cl[None, :] == cl[truth][:, None]).astype(float)
    return V / sizes[cl][None, :]


def aggregate_classes(P, classes) -> np.ndarray:
    """Sum the columns of P over each class: (tracks × classes)."""
    P = _probabilities(P, "P")
    cl = _classes(classes, P.shape[1])
    out = np.zeros((P.shape[0], int(cl.max()) + 1 if cl.size else 0))
    np.add.at(out, (slice(None), cl), P)
    return out


def expand_columns(P, col_counts) -> np.ndarray:
    """Per-identity columns from a compressed P (each group's column repeated)."""
    P = _probabilities(P, "P")
    counts = np.asarray(col_counts)
    if counts.shape != (P.shape[1],) or counts.dtype.kind not in "iu" or (counts < 1).any():
        raise ValueError(f"col_counts must be {P.shape[1]} positive integers")
    return np.repeat(P, counts, axis=1)


def kl_rows(V, P) -> np.ndarray:
    """D_KL(V_t ‖ P_t) for every row, in nats; +inf where P_t misses V_t's support."""
    V = _probabilities(V, "V")
    P = _probabilities(P, "P")
    if V.shape != P.shape:
        raise ValueError(f"V {V.shape} and P {P.shape} must have the same shape")
    support = V > 0
    terms = np.zeros(V.shape)
    with np.errstate(divide="ignore"):
        terms[support] = V[support] * (np.log(V[support]) - np.log(P[support]))
    kl = terms.sum(axis=1)
    # rounding may leave −1e-16 for identical rows; a divergence is ≥ 0
    return np.maximum(kl, 0.0)


def max_kl(V, P) -> float:
    """Largest D_KL(V_t ‖ P_t) over the rows (eq. 58); +inf when any row misses V's support."""
    kl = kl_rows(V, P)
    return float(kl.max()) if kl.size else 0.0
