"""Stone Soup drop-in data associators on jointtrack's exact engine, and converters.

For users of Stone Soup (Barr et al., "Stone Soup: announcement of beta release
of an open-source framework for tracking and state estimation", Proc. SPIE
11018, 2019): :class:`JPDAExact` and :class:`JPDALBP` are
:class:`stonesoup.dataassociator.base.DataAssociator` s with the constructor and
the return value of Stone Soup's ``JPDAwithEHM2``, so a Stone Soup tracker runs
unchanged with one of them swapped in::

    data_associator=JPDAExact(hypothesiser)   # was JPDAwithEHM2(hypothesiser)

What they compute
-----------------
The hypothesiser's weights are the JPDA single-target terms of S. Bojilov,
K. Alexiev and P. Konstantinova, "One particular program realization of JPDA
algorithm", *Information & Security* 9, 2002, eq. (7): for track i, ``p_i0``
for the missed detection and ``p_ij = P_D N(z_j; ẑ_i, S_i)/λ`` for each gated
detection j (Stone Soup's
``PDAHypothesiser``; any hypothesiser whose hypotheses carry a ``probability``
works). The marginal JPDA probabilities are the sum over joint events in which
each detection goes to at most one track, as ``JPDAwithEHM2`` computes them:

.. math::

    β_{ij} = \\frac{1}{Z} \\sum_{θ:\\,θ(i)=j} \\prod_k p_{kθ(k)},
    \\qquad Z = \\sum_θ \\prod_k p_{kθ(k)}.

Tracks are split into clusters that share no detection
(:func:`jointtrack.association.clusters`); each cluster goes to the
assignment-sum core (:mod:`jointtrack.assignment.core`) through
:func:`jointtrack.association.budget.budgeted_marginals`.

* The weights are read in log space (``Probability.log_value``). Each track's
  row is divided by its largest weight, which changes no β: every joint event
  takes exactly one entry of every row. A weight more than about 1e-308 below
  its row's largest is then treated as impossible, which moves no probability
  by more than that ratio.
* **Budget policy (large clusters).** :class:`JPDAExact` is exact for a cluster
  of at most ``exact_max_tracks`` tracks whose frontier DP fits ``max_bits``
  (a state of 2^max_bits subsets) and ``max_memory``. Past either limit it uses
  ``approximation`` (default ``"lbp"``: the loopy belief propagation of J. L.
  Williams and R. A. Lau, "Approximate evaluation of marginal association
  probabilities with belief propagation", IEEE Trans. Aerospace and Electronic
  Systems 50(4):2942–2959, 2014, with a certified stopping rule,
  :mod:`jointtrack.association.lbp`).
  Every such cluster is logged at WARNING and listed in ``last_clusters``.
  ``approximation="raise"`` raises :class:`jointtrack.errors.ExactLimitError`
  instead.
* A cluster of one track is PDA (Bojilov eqs. (1)–(3)), exact, for all such
  tracks at once (:func:`jointtrack.association.pda_pair_marginals`).
* :class:`JPDALBP` uses that LBP for every cluster of two or more tracks.
* :class:`FastPDAHypothesiser` is Stone Soup's ``PDAHypothesiser`` with the
  same hypotheses, computed with one prediction per track and the gate and
  likelihoods of all (linear-model) detections at once; in Stone Soup's
  tracker the hypothesiser is the larger cost once association is fast.
* ``last_clusters`` lists, after each call, every cluster as ``(n_tracks,
  n_detections, method, reason)``: ``method`` is ``"pda"`` for one-track
  clusters, else the method used; ``reason`` says why the approximation was
  used, empty when it was not.

Converters
----------
:func:`scans_from_stonesoup` turns detections into the ``(time, z)`` scans of
:class:`jointtrack.trackers.JPDATracker`; :func:`truth_from_stonesoup` turns
ground-truth paths into the ``(time, id, state)`` table of
:func:`jointtrack.metrics.gospa_series`; :func:`tracks_to_stonesoup` turns a
:class:`jointtrack.trackers.TrackHistory` into Stone Soup ``Track`` s, so Stone
Soup's metric generators run on jointtrack's output. jointtrack's states are
positions first (``[x, y, vx, vy]``); Stone Soup's constant-velocity models
interleave (``[x, vx, y, vy]``): the converters reorder (``interleave=True``)
or take an explicit index.

Stone Soup is an optional dependency: ``pip install 'jointtrack[stonesoup]'``.
Modules: :mod:`.associators` (``JPDAExact``, ``JPDALBP``), :mod:`.hypothesiser`
(``FastPDAHypothesiser``), :mod:`.converters`, :mod:`.serialise` (Stone Soup's
YAML reads configurations that name these components).
"""

from __future__ import annotations

try:
    import stonesoup  # noqa: F401
except ImportError as exc:  # pragma: no cover - exercised only without Stone Soup
    raise ImportError(
        "jointtrack.interop.stonesoup needs Stone Soup: pip install 'jointtrack[stonesoup]'"
    ) from exc

from jointtrack.interop.stonesoup.associators import JPDALBP, JPDAExact
from jointtrack.interop.stonesoup.converters import (
    scans_from_stonesoup,
    tracks_to_stonesoup,
    truth_from_stonesoup,
)
from jointtrack.interop.stonesoup.hypothesiser import FastPDAHypothesiser
from jointtrack.interop.stonesoup.serialise import TAG_PREFIX as _TAG_PREFIX  # noqa: F401 - registers the YAML reader

__all__ = [
    "FastPDAHypothesiser",
    "JPDAExact",
    "JPDALBP",
    "scans_from_stonesoup",
    "tracks_to_stonesoup",
    "truth_from_stonesoup",
]
