"""Kalman, extended Kalman and PDA/JPDA filter steps, batched over tracks.

All functions take plain numpy arrays — one track ``x (n,)``, ``P (n, n)`` or a
batch ``x (N, n)``, ``P (N, n, n)`` — and return new arrays of the same shape.
Covariances are updated in Joseph form and symmetrised; log-likelihoods use
Cholesky factors. See :mod:`jointtrack.filters.kalman`,
:mod:`jointtrack.filters.pda` and :mod:`jointtrack.filters.imm` (interacting
multiple models).
"""

from jointtrack.filters.imm import (
    IMMModes,
    imm_combine,
    imm_mix,
    imm_mixing,
    imm_mode_update,
    imm_pair_log_likelihoods,
    imm_pda_pairs_update,
    imm_predict,
    imm_update,
)
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
    "IMMModes",
    "ekf_innovation",
    "ekf_predict_measurement",
    "ekf_update",
    "imm_combine",
    "imm_mix",
    "imm_mixing",
    "imm_mode_update",
    "imm_pair_log_likelihoods",
    "imm_pda_pairs_update",
    "imm_predict",
    "imm_update",
    "innovation",
    "log_likelihood",
    "pda_ekf_update",
    "pda_pairs_update",
    "pda_update",
    "predict",
    "predict_measurement",
    "update",
]
