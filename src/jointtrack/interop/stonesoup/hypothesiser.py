"""``FastPDAHypothesiser``: Stone Soup's ``PDAHypothesiser``, its detections taken at once.

In Stone Soup's tutorial JPDA tracker with :class:`JPDAExact` the hypothesiser is
about half of every step (``benchmarks/RESULTS.md``, issue 16): for each track
and each detection it asks the predictor and the updater for a prediction and a
measurement prediction (served from their caches after the first), and measures
the squared Mahalanobis distance of the gate through Stone Soup's ``Measure``
objects, one pair at a time. This subclass gives the same hypotheses, in the
same order, with the same objects (prediction, measurement prediction,
probability in log space), but per track it makes one prediction and one
measurement prediction for each group of detections that share a timestamp and
a measurement model, and computes the gate and the likelihoods of the whole
group at once:

.. math::

    d_j^2 = (z_j - \\hat z)^T S^{-1} (z_j - \\hat z), \\qquad
    \\log \\mathcal N(z_j; \\hat z, S) = -\\tfrac12 \\big(d_j^2 + \\log\\det S
    + k \\log 2\\pi\\big),

with one Cholesky factor of S (Stone Soup's ``batch_multivariate_normal_logpdf``
formula), factored and applied by the compiled loops of
:mod:`jointtrack._numba_linalg`, not by LAPACK: ``scipy.linalg.solve_triangular``
on a 2×2 factor and a dozen detections went to OpenBLAS's threaded ``trsm``,
which woke its worker threads on every call (≈ 17 ms of their CPU per
``associate`` call of the README's snippet; beside three busy processes on two
cores the snippet with this hypothesiser took 4.2× the time of Stone Soup's own:
``benchmarks/load.py``, ``benchmarks/RESULTS.md``, issue 34).

Detection j is in the gate when ``d_j² ≤ χ²_k(P_G)``, as in
``PDAHypothesiser``; the probabilities are then ``P_D N/λ`` (or the
validation-region form without λ) exactly as there.

Only detections whose measurement model is linear (``LinearModel``, e.g.
``LinearGaussian``) are taken this way: there ``z − ẑ`` is a plain difference.
For any other model (angles to wrap, non-linear functions) the call is
``PDAHypothesiser.hypothesise`` itself. The values agree with Stone Soup's to
rounding (the tests compare to 1e-12); a detection within rounding of the gate's
edge could fall on the other side of it.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from stonesoup.hypothesiser.probability import PDAHypothesiser
from stonesoup.models.base import LinearModel
from stonesoup.types.detection import MissedDetection
from stonesoup.types.hypothesis import SingleProbabilityHypothesis
from stonesoup.types.multihypothesis import MultipleHypothesis
from stonesoup.types.numeric import Probability

from jointtrack._numba_linalg import cholesky_lower, mahalanobis_sq

__all__ = ["FastPDAHypothesiser"]

_LOG_2PI = math.log(2.0 * math.pi)


class FastPDAHypothesiser(PDAHypothesiser):
    """``PDAHypothesiser`` with the gate and likelihoods of all detections computed at once.

    Same properties, same hypotheses (module docstring); a drop-in for the
    hypothesiser of Stone Soup's JPDA trackers and of their initiators.
    """

    def hypothesise(self, track, detections, timestamp, **kwargs):
        detections = list(detections)
        groups: dict[tuple, list[int]] = {}
        for n, det in enumerate(detections):
            model = det.measurement_model or self.updater.measurement_model
            if not isinstance(model, LinearModel):
                return super().hypothesise(track, detections, timestamp, **kwargs)
            groups.setdefault((det.timestamp, id(det.measurement_model)), []).append(n)

        prediction = self.predictor.predict(track, timestamp=timestamp, **kwargs)
        hypotheses = [
            SingleProbabilityHypothesis(
                prediction,
                MissedDetection(timestamp=timestamp),
                Probability(1 - self.prob_detect * self.prob_gate),
            )
        ]
        # per detection: (prediction, measurement prediction, log N, in the gate)
        per_detection: list = [None] * len(detections)
        for idx in groups.values():
            first = detections[idx[0]]
            pred = self.predictor.predict(track, timestamp=first.timestamp, **kwargs)
            mp = self.updater.predict_measurement(pred, first.measurement_model, **kwargs)
            found = _gaussian_log_pdf(
                [np.ravel(np.asarray(detections[n].state_vector, dtype=float)) for n in idx],
                np.ravel(np.asarray(mp.state_vector, dtype=float)),
                np.asarray(mp.covar, dtype=float),
            )
            if found is None:  # S not positive definite (Stone Soup repairs it), or shapes
                return super().hypothesise(track, detections, timestamp, **kwargs)
            log_n, d2 = found
            in_gate = d2 <= self._gate_threshold(self.prob_gate, mp.ndim)
            for j, n in enumerate(idx):
                per_detection[n] = (pred, mp, float(log_n[j]), bool(in_gate[j]))

        validated = 0
        for det, (pred, mp, log_n, in_gate) in zip(detections, per_detection, strict=True):
            validated += in_gate
            if not (self.include_all or in_gate):
                continue
            probability = Probability(log_n, log_value=True) * self.prob_detect
            if self.clutter_spatial_density is not None:
                probability /= self.clutter_spatial_density
            hypotheses.append(SingleProbabilityHypothesis(pred, det, probability, mp))

        if self.clutter_spatial_density is None:
            for hypothesis in hypotheses[1:]:
                hypothesis.probability *= (
                    self._validation_region_volume(
                        self.prob_gate, hypothesis.measurement_prediction
                    )
                    / validated
                )
        return MultipleHypothesis(hypotheses, normalise=self.normalise)


def _gaussian_log_pdf(rows, mean, covar):
    """``(log N(z_j; mean, covar), squared Mahalanobis distances)`` for the vectors z_j in
    ``rows``, or None when they cannot be taken here: ``covar`` not a positive definite
    k×k matrix for the k entries of ``mean``, a z_j of another length, or a value that is
    not finite (the caller then leaves them to Stone Soup, which repairs or refuses them)."""
    k = mean.size
    if covar.shape != (k, k) or any(z.size != k for z in rows):
        return None
    z = np.array(rows, dtype=float).reshape(len(rows), k)
    if not (np.isfinite(z).all() and np.isfinite(mean).all()):
        return None
    log_n = np.empty(len(rows))
    d2 = np.empty(len(rows))
    if not _gaussian_rows(z, mean, np.ascontiguousarray(covar), log_n, d2):
        return None
    return log_n, d2


@njit(cache=True)
def _gaussian_rows(z, mean, covar, log_n, d2):
    """:func:`_gaussian_log_pdf`'s loops: one Cholesky factor, one forward substitution
    per row into ``log_n`` and ``d2``; False if ``covar`` is not positive definite."""
    k = mean.size
    chol = np.zeros((k, k))
    ok, log_det = cholesky_lower(covar, chol)
    if not ok:
        return False
    white = np.empty(k)
    for j in range(z.shape[0]):
        d2[j] = mahalanobis_sq(chol, z[j], mean, white)
        if math.isnan(d2[j]):
            # finite inputs and factor: only an overflowed white[i] (then 0 · inf or
            # inf − inf further on) gives NaN, and then d² ≥ white[i]² = inf
            d2[j] = math.inf
        log_n[j] = -0.5 * (d2[j] + log_det + k * _LOG_2PI)
    return True
