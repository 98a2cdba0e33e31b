r"""Superpositional sensors: Campbell/Gaussian, exact, Monte Carlo and saddlepoint likelihoods.

S. Nannuru and M. Coates, "Gaussian approximation for superpositional sensors",
technical report, McGill University, 2015; S. Nannuru, M. Coates and R. Mahler,
"Computationally-tractable approximate PHD and CPHD filters for superpositional
sensors", IEEE J. Sel. Topics Signal Process. 7(3):410-420, 2013.

A superpositional sensor reads y = Σ_{x ∈ Ξ} g(x) + noise (the report's (1)):
the sum of every target's contribution. This package holds the random finite
set models (:class:`MultiBernoulli`, :class:`IIDC`, :class:`Poisson`,
:class:`Union`), the measurement functions, the Campbell moments (4)–(7) and of
the reduced density (17), and :func:`likelihood` / :func:`log_likelihood_ratio`
with the methods "gaussian", "exact", "montecarlo", "saddlepoint" and "hybrid".

Examples
--------
>>> import numpy as np
>>> from jointtrack.superpositional import MultiBernoulli, likelihood
>>> mb = MultiBernoulli([0.9, 0.6], [[0.0, 0.0], [4.0, 4.0]], [np.eye(2), np.eye(2)])
>>> H = [[0.1, 0.7], [0.5, 0.5], [0.8, 0.2]]
>>> exact = likelihood([3.2, 4.0, 4.0], mb, H, 0.25 * np.eye(3), method="exact")
>>> gauss = likelihood([3.2, 4.0, 4.0], mb, H, 0.25 * np.eye(3))
>>> bool(exact.log_value > gauss.log_value)
True
"""

from jointtrack.superpositional.likelihood import (
    METHODS,
    LikelihoodResult,
    likelihood,
    log_likelihood_ratio,
)
from jointtrack.superpositional.measurement import (
    FunctionMeasurement,
    LinearMeasurement,
    as_measurement,
)
from jointtrack.superpositional.models import (
    IIDC,
    MultiBernoulli,
    Poisson,
    Union,
    reduced_mixture,
    sample_superposition,
)
from jointtrack.superpositional.moments import (
    campbell_moments,
    leave_one_out_moments,
    reduced_moments,
)

__all__ = [
    "IIDC",
    "METHODS",
    "FunctionMeasurement",
    "LikelihoodResult",
    "LinearMeasurement",
    "MultiBernoulli",
    "Poisson",
    "Union",
    "as_measurement",
    "campbell_moments",
    "leave_one_out_moments",
    "likelihood",
    "log_likelihood_ratio",
    "reduced_mixture",
    "reduced_moments",
    "sample_superposition",
]
