"""JPDA association engine: gating, clustering, clutter density and marginals.

Cluster convention (DESIGN.md): ``L`` (N tracks × M measurements, likelihood
ratios ``P_D g_ij / λ``, 0 = not gated), ``miss`` (N, ``1 − P_D P_G``); every
method returns ``beta`` (N × (M+1)), column 0 = no measurement, rows sum to 1.

Entry point: :func:`marginals` with ``method`` one of :data:`METHODS`:

``"exact"``      leaf folding + frontier subset DP, forward–backward (no enumeration)
``"enumerate"``  Bojilov's depth-first hypothesis generation with incremental products
``"pda"``        independent per-track PDA
``"lbp"``        Williams & Lau loopy belief propagation
``"mcmc"``       Oh–Russell–Sastry MCMC data association
``"kbest"``      k best joint events (Murty)

JPDA* (:func:`~jointtrack.association.coalescence.jpda_star`, Blom & Bloem:
of the events that differ only by a permutation, the most likely) is not a
method of the same marginals but another estimator, in its own module.

Gating, clustering, clutter density, lbp, mcmc, kbest and JPDA* live in their own
modules; their public names are re-exported here lazily (imported on first use).
"""

from __future__ import annotations

import importlib

from jointtrack.association.core import METHODS, marginals
from jointtrack.association.exact import (
    ExactResult,
    exact_jpda,
    exact_log_normalizer,
    exact_marginals,
)
from jointtrack.association.hypotheses import (
    DEFAULT_MAX_HYPOTHESES,
    EnumerationResult,
    bojilov_multiplication_counts,
    count_hypotheses,
    enumerate_jpda,
    enumerate_marginals,
    iter_hypotheses,
)
from jointtrack.association.pda import pda_marginals, pda_pair_marginals
from jointtrack.errors import InfeasibleAssignmentError

# Public names of the sibling modules (gating, clustering, clutter, lbp, mcmc,
# kbest, coalescence), resolved lazily by __getattr__ so that importing this package stays
# cheap and does not depend on all of them being importable.
_LAZY = {
    "Gating": "gating",
    "PairGating": "gating",
    "gate_measurements": "gating",
    "gate_pairs": "gating",
    "likelihood_ratio_pairs": "gating",
    "likelihood_ratios": "gating",
    "unit_ball_log_volume": "gating",
    "Cluster": "clustering",
    "Clustering": "clustering",
    "clusters": "clustering",
    "has_feasible_event": "clustering",
    "ClutterEstimate": "clutter",
    "UnionVolume": "clutter",
    "cluster_clutter_density": "clutter",
    "cluster_heuristic_density": "clutter",
    "cluster_heuristic_densities": "clutter",
    "known_density": "clutter",
    "track_sample_density": "clutter",
    "union_gate_volume": "clutter",
    "union_sample_density": "clutter",
    "LBPInfo": "lbp",
    "lbp_marginals": "lbp",
    "lbp_pair_marginals": "lbp",
    "mcmc_marginals": "mcmc",
    "KBestHypotheses": "kbest",
    "kbest_hypotheses": "kbest",
    "kbest_marginals": "kbest",
    "JPDAStarResult": "coalescence",
    "jpda_star": "coalescence",
    "jpda_star_marginals": "coalescence",
}
_SIBLINGS = ("gating", "clustering", "clutter", "lbp", "mcmc", "kbest", "coalescence")


def __getattr__(name: str):
    module = _LAZY.get(name)
    candidates = (module,) if module else _SIBLINGS
    for mod in candidates:
        try:
            m = importlib.import_module(f"jointtrack.association.{mod}")
        except ImportError:
            continue
        if name in getattr(m, "__all__", ()):
            value = getattr(m, name)
            globals()[name] = value
            return value
    raise AttributeError(f"module 'jointtrack.association' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_LAZY))


__all__ = [
    "DEFAULT_MAX_HYPOTHESES",
    "METHODS",
    "EnumerationResult",
    "ExactResult",
    "InfeasibleAssignmentError",
    "bojilov_multiplication_counts",
    "count_hypotheses",
    "enumerate_jpda",
    "enumerate_marginals",
    "exact_jpda",
    "exact_log_normalizer",
    "exact_marginals",
    "iter_hypotheses",
    "marginals",
    "pda_marginals",
    "pda_pair_marginals",
    *_LAZY,
]
