"""Kalman, extended Kalman and PDA/JPDA filter steps, batched over tracks.

All functions take plain numpy arrays — one track ``x (n,)``, ``P (n, n)`` or a
batch ``x (N, n)``, ``P (N, n, n)`` — and return new arrays of the same shape.
Covariances are updated in Joseph form and symmetrised; log-likelihoods use
Cholesky factors. See :mod:`jointtrack.filters.kalman` and
:mod:`jointtrack.filters.pda`.
"""

from jointtrack.filters.kalman import (
    ekf_innovation,
    ekf_predict_measurement,
    ekf_update,
    innovation,
    log_likelihood,
    predict,
    predict_measurement,
    update,
)
from jointtrack.filters.pda import pda_ekf_update, pda_pairs_update, pda_update

__all__ = [
    "ekf_innovation",
    "ekf_predict_measurement",
    "ekf_update",
    "innovation",
    "log_likelihood",
    "pda_ekf_update",
    "pda_pairs_update",
    "pda_update",
    "predict",
    "predict_measurement",
    "update",
]
