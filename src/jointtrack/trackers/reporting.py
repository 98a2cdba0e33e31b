"""Reporting targets — the rules every tracker applies to reports, in one place.

Targets that report themselves (AIS, ADS-B) bring three things a scanning
sensor does not: an asynchronous detection pattern (each target a Poisson
reporter of its own rate, ``reporting = "async"``), an identity per report
(``labels``: association given the label) and sometimes a velocity
(``velocities``: it seeds the velocity of a track started on the report). The
JPDA/JIPDA tracker (:class:`~jointtrack.trackers.jpda.JPDATracker`) and the
PMB/PMBM trackers (:mod:`jointtrack.trackers.pmbm`) use these functions, so
that each rule exists once:

* :func:`check_report_fields` — the ``labels`` / ``velocities`` of a scan,
  validated and aligned with the returns the scan kept;
* :func:`scan_detection` — each track's (Bernoulli's) probability of being
  heard in the interval since the previous scan, its miss weight and survival
  (the continuous-time model of ``reporting = "async"``, or a scanning sensor);
* :func:`undetected_detection` — the same for the never-detected targets of a
  Poisson intensity;
* :func:`match_labels`, :func:`label_identities` — which track a labelled
  report belongs to, and the id a label keeps across its tracks;
* :func:`seed_velocities` — reported velocities into initial states.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from jointtrack.assignment._checks import _as_real_array
from jointtrack.trackers.existence import _missed_share, silence_outcomes

__all__ = [
    "ScanDetection",
    "check_report_fields",
    "label_identities",
    "match_labels",
    "miss_weight",
    "missed_existence",
    "scaled_pair_factor",
    "scan_detection",
    "seed_velocities",
    "undetected_detection",
]


class ScanDetection(NamedTuple):
    """Per-track detection and survival over one scan interval (:func:`scan_detection`).

    ``pd`` P_D,i; ``pdg`` the P_D·P_G of the miss weight; ``missed`` = 1 − ``pdg``
    (formed without the subtraction); ``pd_ratio`` the pair factor of the
    likelihood ratios (P_D,i, or P_D,i/Δt against a clutter density per second);
    ``survival`` the factor taking each existence from the previous scan to this
    one; ``scan``: the scanning-sensor model (P_D,i = p_d for every track).
    """

    pd: np.ndarray
    pdg: np.ndarray
    missed: np.ndarray
    pd_ratio: np.ndarray
    survival: np.ndarray
    scan: bool


def scan_detection(
    config, p_d, t, dt, t_prev, born, report_count, labelled, in_gate=1.0
) -> ScanDetection:
    """Per-track detection and survival of the scan at ``t``, ``dt`` after the previous one.

    ``config``: the tracker's settings (``reporting``, ``report_interval``,
    ``p_survive``, ``p_survive_per``); ``p_d`` the active sensor's P_D; ``t_prev``
    the previous scan's time; ``born`` (N,) each track's birth time,
    ``report_count`` (N,) its (soft) number of reports since birth, ``labelled``
    (N,) whether it carries a label (no gate: the label decides); ``in_gate``
    the P_G factor of an unlabelled track's miss weight (1 without one).

    Scanning sensor: P_D = p_d for every track, survival p_survive per scan or
    p_survive^Δt per second. Reporting targets (``reporting = "async"``): the
    track's rate estimate at time s is λ_i(s) = (1 + reports) /
    (report_interval + (s − born)); its reports are received with probability
    p_d (and fall in the gate with P_G), so nothing is received in (t − Δt, t]
    with probability exp(−p_d ∫λ_i) = (β₀/β₁)^(p_d(1 + reports)), β₀, β₁ =
    report_interval + seconds tracked at the interval's ends, and P_D,i = 1 −
    (β₀/β₁)^(p_d(1 + reports)). For p_d = 1 it is the Gamma–Poisson predictive
    (negative binomial) of the track's own rate. The pairs' likelihood ratios use
    P_D,i/Δt (→ p_d·λ_i as Δt → 0) against a clutter density per second.

    The target also dies at the rate μ = −log p_survive per second, at any
    moment of the interval, so the interval ends in one of three ways
    (:func:`~jointtrack.trackers.existence.silence_outcomes`): the target is
    alive and unheard (probability a), was heard before dying (e), or died
    unheard (d = 1 − a − e). The existence is predicted to r(1 − d) (alive
    when it is heard, or at t) and the miss weight's P_D·P_G is e/(a + e): a
    missed scan then leaves exactly the continuous-time posterior ra / (1 − re)
    — which composes, scan after scan, into the posterior of the whole silence,
    so a silence costs the same existence however many other targets' reports
    cut it into scans. Without deaths (p_survive = 1) d = 0 and the miss
    probabilities themselves telescope.
    """
    c = config
    n = len(born)
    if c.reporting == "scan":
        pd = np.full(n, p_d)
        pdg = np.where(labelled, pd, p_d * in_gate)
        survive = c.p_survive ** (dt if c.p_survive_per == "second" else 1.0)
        return ScanDetection(pd, pdg, 1.0 - pdg, pd, np.full(n, survive if dt > 0 else 1.0), True)
    alpha = 1.0 + report_count
    beta0 = c.report_interval + np.maximum(t_prev - born, 0.0)
    # seconds tracked within the interval: Δt itself (no cancellation for tiny Δt)
    # unless the track was born inside it
    elapsed = np.minimum(dt, np.maximum(t - born, 0.0))
    hazard = alpha * np.log1p(elapsed / beta0)  # ∫ λ_i(s) ds over the interval
    pd = -np.expm1(-p_d * hazard)
    gate = np.where(labelled, 1.0, in_gate)
    death_rate = -math.log(c.p_survive)
    if death_rate > 0.0 and dt > 0:
        silent, heard, _ = silence_outcomes(p_d * gate * alpha, beta0, elapsed, death_rate)
        survival = alive = silent + heard  # = 1 − died, without cancellation
        # a track whose survival underflowed to 0 is dropped before it is used
        pdg = np.divide(heard, alive, out=np.zeros_like(heard), where=alive > 0)
        missed = np.divide(silent, alive, out=np.ones_like(heard), where=alive > 0)
    else:
        survival = np.ones(n)
        pdg = -np.expm1(-p_d * gate * hazard)
        missed = np.exp(-p_d * gate * hazard)
    pd_ratio = p_d * alpha / beta0 if dt == 0 else pd / dt
    return ScanDetection(pd, pdg, missed, pd_ratio, survival, False)


def undetected_detection(config, p_d, dt) -> tuple[float, float]:
    """``(pd_ratio, missed)`` of a target never detected (a Poisson intensity), over ``dt``.

    Scanning sensor: ``(p_d, 1 − p_d)``. Reporting targets: an undetected target
    reports at the prior rate 1/report_interval, each report received with
    probability p_d, so it is missed over Δt with probability exp(−p_d Δt /
    report_interval) and its pair factor is P_D/Δt (p_d/report_interval as Δt →
    0), as a track's in :func:`scan_detection` with no report and no age.
    """
    if config.reporting == "scan":
        return p_d, 1.0 - p_d
    rate = p_d / config.report_interval
    if dt == 0:
        return rate, 1.0
    return -math.expm1(-rate * dt) / dt, math.exp(-rate * dt)


def scaled_pair_factor(pd_ratio, r):
    """``(P_D,i·r_i / scale, scale)``: the pair factor of the likelihood ratios.

    With reporting targets P_D,i is a rate (per second) that may exceed 1, so the
    numerator and the clutter (ρ) are divided by a common scale. Floored at the
    smallest normal float: survival per second over a long gap (0.99**1e6) or an
    underflowing P_D,i/Δt gives exactly 0, which the pair likelihoods refuse as a
    P_D; such a track explains nothing either way.
    """
    pd_r = pd_ratio * r
    scale = max(1.0, float(pd_r.max())) if len(pd_r) else 1.0
    return np.maximum(pd_r / scale, np.finfo(float).tiny), scale


def miss_weight(r, det: ScanDetection, p_d):
    """Weight 1 − r P_D of "Bernoulli ``r`` took no return" (scanning sensor, as the
    Poisson trackers always formed it), or (1 − r) + r·missed of :func:`scan_detection`."""
    if det.scan:
        return 1.0 - p_d * r
    return (1.0 - r) + r * det.missed


def missed_existence(r, det: ScanDetection, p_d):
    """Existence of a Bernoulli ``r`` that took no return: r(1 − P_D)/(1 − r P_D) (0 for
    r = 1 and P_D = 1: such a target cannot go unheard)."""
    if det.scan:
        return _missed_share(r * (1.0 - p_d), 1.0 - p_d * r)
    return _missed_share(r * det.missed, (1.0 - r) + r * det.missed)


def check_report_fields(dim, z, labels, velocities, kept, n_coincident):
    """Validated ``labels`` (M,) str and ``velocities`` (M, dim) of a scan's reports.

    Given for the scan's rows as passed to ``step``; ``kept``: the rows of ``z``
    the scan kept after merging exactly repeated returns (None: all), which are
    dropped with them. Two reports naming one target in one scan keep the first
    (counted in ``n_coincident``, like a repeated return). Returns ``(labels,
    repeated, velocities, n_coincident)``; ``repeated`` marks the dropped
    repeats (None without labels).
    """
    M = len(z) + (n_coincident if kept is not None else 0)
    repeated = None
    if labels is not None:
        if isinstance(labels, str | bytes):
            raise TypeError("labels must be a sequence of strings, one per report")
        try:
            arr = np.asarray(labels, dtype=object)
        except (TypeError, ValueError) as exc:  # ragged nesting
            raise TypeError(f"labels must be a sequence of strings: {exc}") from None
        if arr.ndim != 1 or len(arr) != M:
            # (M, 1) nesting was flattened silently before: one string per report
            raise ValueError(f"labels must have one entry per report ({M},), got shape {arr.shape}")
        if not all(isinstance(v, str) for v in arr):
            bad = next(v for v in arr if not isinstance(v, str))
            raise TypeError(f"labels must be strings ('' for none), got {bad!r}")
        from jointtrack.io._files import NUL_REASON, nul_index

        if (i := nul_index(arr.tolist())) is not None:  # numpy would merge "A", "A\0"
            raise ValueError(f"labels[{i}] = {arr[i]!r} {NUL_REASON}")
        labels = np.asarray(arr.tolist() if M else [], dtype=str).reshape(M)
        if kept is not None:
            labels = labels[kept]
        repeated = np.zeros(len(z), bool)
        named = np.flatnonzero(labels != "")
        _, first = np.unique(labels[named], return_index=True)
        if len(first) < len(named):
            repeat = np.ones(len(z), bool)
            repeat[named[first]] = False
            repeat[labels == ""] = False
            n_coincident += int(repeat.sum())
            labels = labels.copy()
            labels[repeat] = ""
            repeated = repeat
    if velocities is not None:
        v = _as_real_array(velocities, "velocities")
        if v.shape != (M, dim):
            raise ValueError(f"velocities must have shape ({M}, {dim}), got {v.shape}")
        if np.isinf(v).any():
            raise ValueError("velocities must be finite (NaN where unknown)")
        velocities = v if kept is None else v[kept]
    return labels, repeated, velocities, n_coincident


def match_labels(track_labels, labels, repeated):
    """``(track rows, report columns, open columns)`` of a scan's labelled reports.

    ``track_labels`` (N,): each track's label (``""`` for none); ``labels`` (M,)
    the reports'. A labelled report whose label a track carries goes to that
    track (row, column); one whose label no track carries starts one (open
    column); repeats (``repeated``) and unlabelled reports are neither.
    """
    track_of = {lab: i for i, lab in enumerate(track_labels.tolist()) if lab}
    rows, cols, open_cols = [], [], []
    for j, lab in enumerate(labels.tolist()):
        if lab == "" or repeated[j]:
            continue
        i = track_of.get(lab)
        if i is None:
            open_cols.append(j)
        else:
            rows.append(i)
            cols.append(j)
    return (
        np.asarray(rows, np.int64),
        np.asarray(cols, np.int64),
        np.asarray(open_cols, np.int64),
    )


def label_identities(names, numbers, new_labels, ids):
    """Ids of tracks started on labelled reports, and the label → id table after them.

    ``names`` (sorted) and ``numbers``: every label seen and the id of its
    target's track; ``new_labels`` (K,) the new tracks' labels, ``ids`` (K,) the
    fresh ids they would get. A target that reports under a label again takes
    back its old id: the label is its identity, whatever happened to its track
    in between. Returns ``(ids, names, numbers)``.
    """
    ids = np.array(ids, np.int64, copy=True)
    if len(names):
        pos = np.minimum(np.searchsorted(names, new_labels), len(names) - 1)
        known = names[pos] == new_labels
        ids[known] = numbers[pos[known]]
    if len(new_labels):
        all_names = np.concatenate([names, new_labels])
        all_numbers = np.concatenate([numbers, ids])
        names, first = np.unique(all_names, return_index=True)
        numbers = all_numbers[first]
    return ids, names, numbers


def seed_velocities(x0, P0, velocities, dim, velocity_std):
    """Initial states ``(x0, P0)`` with the reported velocities where known (in place).

    Rows of ``velocities`` (K, dim) that are finite replace the velocity block of
    the state by the reported velocity with per-axis σ = ``velocity_std`` and no
    position–velocity correlation; NaN rows leave the state as it is.
    """
    if velocities is None or not len(x0):
        return x0, P0
    known = np.flatnonzero(np.isfinite(velocities).all(axis=1))
    v, every = np.arange(dim, 2 * dim), np.arange(x0.shape[1])
    x0[np.ix_(known, v)] = velocities[known]
    P0[np.ix_(known, v, every)] = 0.0
    P0[np.ix_(known, every, v)] = 0.0
    P0[np.ix_(known, v, v)] = np.eye(dim) * velocity_std**2
    return x0, P0
