"""Particle filters for superpositional sensors: SPS-PHD, SPS-CPHD and SPS-MB.

* :class:`SPSPHDFilter` — Poisson predicted RFS, posterior PHD D R (:mod:`.phd`).
* :class:`SPSCPHDFilter` — IIDC: cardinality pmf and particles (:mod:`.cphd`).
* :class:`SPSMBFilter` — Bernoulli components with particle sets (:mod:`.mb`).
* :class:`FilterSettings` — motion, survival, birth and particle counts (:mod:`._particles`).

All three take the likelihood method as a parameter (``"gaussian"``, the
paper's, by default; ``"saddlepoint"`` or ``"hybrid"``), and share one copy of
prediction, birth, resampling and state extraction.
"""

from jointtrack.superpositional.filters._particles import FilterSettings, systematic_resample
from jointtrack.superpositional.filters.cphd import SPSCPHDFilter
from jointtrack.superpositional.filters.mb import SPSMBFilter
from jointtrack.superpositional.filters.phd import SPSPHDFilter

#: filter name on the command line → class
FILTERS = {"sps-phd": SPSPHDFilter, "sps-cphd": SPSCPHDFilter, "sps-mb": SPSMBFilter}

__all__ = [
    "FILTERS",
    "FilterSettings",
    "SPSCPHDFilter",
    "SPSMBFilter",
    "SPSPHDFilter",
    "systematic_resample",
]
