"""Particle JPDA weights as mixed derivatives of a generating function (Streit).

R. L. Streit, "Saddle point method for JPDA and related filters", *Proc. 18th
International Conference on Information Fusion* (FUSION), 2015.

``generating``   Ψ(β) = exp(a0 + Σ a_m β_m)·Π_k (f_k0 + Σ f_km β_m); the JPDA
                 coefficients of eq. (7)/(14)
``derivative``   :func:`log_mixed_derivative` (exact on the assignment-sum core,
                 or the saddle-point approximation (30)); :func:`saddle_point`
                 (batched Newton); :func:`jpda_log_weights` (exact weights of all
                 particles of one target from one core call)
"""

from jointtrack.saddle.derivative import (
    ERROR_BOUNDS,
    METHODS,
    ExactRangeError,
    MixedDerivative,
    SaddlePoint,
    SaddlePointError,
    jpda_log_weights,
    log_mixed_derivative,
    saddle_point,
)
from jointtrack.saddle.generating import check_coefficients, jpda_coefficients, log_psi

__all__ = [
    "ERROR_BOUNDS",
    "METHODS",
    "ExactRangeError",
    "MixedDerivative",
    "SaddlePoint",
    "SaddlePointError",
    "check_coefficients",
    "jpda_coefficients",
    "jpda_log_weights",
    "log_mixed_derivative",
    "log_psi",
    "saddle_point",
]
