"""``JPDAExact`` and ``JPDALBP``: Stone Soup data associators on the assignment-sum core.

What they compute, the log-space row scaling and the budget policy are described
in :mod:`jointtrack.interop.stonesoup` (S. Bojilov, K. Alexiev and P.
Konstantinova, "One particular program realization of JPDA algorithm",
*Information & Security* 9, 2002; J. L. Williams and R. A. Lau, "Approximate
evaluation of marginal association probabilities with belief propagation", IEEE
Trans. Aerospace and Electronic Systems 50(4):2942–2959, 2014).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping

import numpy as np
from stonesoup.base import Property
from stonesoup.dataassociator.base import DataAssociator
from stonesoup.hypothesiser import Hypothesiser
from stonesoup.types.hypothesis import SingleProbabilityHypothesis
from stonesoup.types.multihypothesis import MultipleHypothesis
from stonesoup.types.numeric import Probability

from jointtrack.association.budget import APPROXIMATIONS, budgeted_marginals
from jointtrack.association.clustering import cluster_pair_marginals, clusters
from jointtrack.errors import ExactLimitError, InfeasibleAssignmentError

__all__ = ["JPDAExact", "JPDALBP"]

log = logging.getLogger(__name__)

DEFAULT_MAX_BITS = 22  # 2^22 states · 8 B = 32 MiB per DP array: well under a second
DEFAULT_MAX_MEMORY = 2**30
DEFAULT_MAX_TRACKS = 64


def _log_weight(hyp, track) -> float:
    """log of a hypothesis' probability; a clear error for hypotheses without one."""
    p = getattr(hyp, "probability", None)
    if p is None:
        raise TypeError(
            f"the hypothesiser gave track {track!r} a {type(hyp).__name__} without a "
            "probability; JPDA needs probability hypotheses (e.g. PDAHypothesiser)"
        )
    if isinstance(p, Probability):
        lw = float(p.log_value)
    else:
        if isinstance(p, bool | complex) or not isinstance(p, int | float | np.floating):
            raise TypeError(f"hypothesis probability must be a real number, got {p!r}")
        if not p >= 0.0:
            raise ValueError(f"hypothesis probability must be ≥ 0, got {p!r} for track {track!r}")
        lw = math.log(p) if p > 0 else -math.inf
    if math.isnan(lw) or lw == math.inf:
        raise ValueError(f"hypothesis probability {p!r} of track {track!r} is not finite")
    return lw


class JPDAExact(DataAssociator):
    """JPDA with exact marginal association probabilities from jointtrack's engine.

    A drop-in for Stone Soup's ``JPDAwithEHM2``: same constructor argument (the
    hypothesiser), same :meth:`associate` result (a ``MultipleHypothesis`` per
    track of ``SingleProbabilityHypothesis`` objects, normalised, the
    missed-detection hypothesis included, in the hypothesiser's order). The
    budget policy for large clusters is in the module docstring.

    Examples
    --------
    >>> import datetime
    >>> import numpy as np
    >>> from stonesoup.hypothesiser.probability import PDAHypothesiser
    >>> from stonesoup.models.measurement.linear import LinearGaussian
    >>> from stonesoup.models.transition.linear import (
    ...     CombinedLinearGaussianTransitionModel, ConstantVelocity)
    >>> from stonesoup.predictor.kalman import KalmanPredictor
    >>> from stonesoup.types.detection import Detection
    >>> from stonesoup.types.state import GaussianState
    >>> from stonesoup.types.track import Track
    >>> from stonesoup.updater.kalman import KalmanUpdater
    >>> t0 = datetime.datetime(2025, 1, 1)
    >>> cv = CombinedLinearGaussianTransitionModel([ConstantVelocity(0.1)] * 2)
    >>> mm = LinearGaussian(ndim_state=4, mapping=(0, 2), noise_covar=np.eye(2))
    >>> hyp = PDAHypothesiser(KalmanPredictor(cv), KalmanUpdater(mm),
    ...                       clutter_spatial_density=1e-3, prob_detect=0.9)
    >>> tracks = {Track([GaussianState([[x], [1], [0], [0]], np.eye(4), t0)]) for x in (0, 2)}
    >>> t1 = t0 + datetime.timedelta(seconds=1)
    >>> dets = {Detection([[x], [0]], timestamp=t1, measurement_model=mm) for x in (1, 3)}
    >>> out = JPDAExact(hyp).associate(tracks, dets, t1)
    >>> all(abs(float(sum(h.probability for h in mh)) - 1) < 1e-12 for mh in out.values())
    True
    """

    hypothesiser: Hypothesiser = Property(
        doc="Generates the hypotheses (with probabilities) of each track-detection pair"
    )
    exact_max_tracks: int = Property(
        default=DEFAULT_MAX_TRACKS,
        doc="Clusters with more tracks use the approximation without trying the exact DP",
    )
    max_bits: int = Property(
        default=DEFAULT_MAX_BITS,
        doc="Exact budget: the frontier DP's state may hold at most 2^max_bits subsets",
    )
    max_memory: int = Property(
        default=DEFAULT_MAX_MEMORY, doc="Exact budget: bytes the exact DP may allocate"
    )
    approximation: str = Property(
        default="lbp",
        doc="Method past the budget: 'lbp' (default), 'mcmc', 'kbest', 'pda', or 'raise'",
    )

    _method = "exact"

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        if self.approximation != "raise" and self.approximation not in APPROXIMATIONS:
            raise ValueError(
                f"approximation must be one of {', '.join(APPROXIMATIONS)} or 'raise', "
                f"got {self.approximation!r}"
            )
        for name in ("exact_max_tracks", "max_bits", "max_memory"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 0:
                raise ValueError(f"{name} must be an integer ≥ 0, got {value!r}")
        #: per cluster of the last call: (n_tracks, n_detections, method, reason)
        self.last_clusters: list[tuple[int, int, str, str]] = []

    def associate(self, tracks, detections, timestamp, **kwargs):
        """Associate tracks and detections (Stone Soup's ``DataAssociator`` interface).

        Parameters
        ----------
        tracks : set of stonesoup.types.track.Track
        detections : set of stonesoup.types.detection.Detection
        timestamp : datetime.datetime
            time of the detections (the hypothesiser predicts to it).

        Returns
        -------
        dict
            ``Track → MultipleHypothesis`` of ``SingleProbabilityHypothesis``
            objects whose probabilities are the JPDA marginals, summing to 1.
        """
        hypotheses = self.generate_hypotheses(tracks, detections, timestamp, **kwargs)
        return self.associate_hypotheses(hypotheses)

    def associate_hypotheses(self, hypotheses: Mapping) -> dict:
        """JPDA marginals for already generated hypotheses ``{track: MultipleHypothesis}``."""
        track_list = list(hypotheses)
        N = len(track_list)
        log_miss = np.full(N, -np.inf)
        has_miss = np.zeros(N, bool)
        column: dict[int, int] = {}
        rows, cols, logw = [], [], []
        for i, track in enumerate(track_list):
            seen = set()
            hyps = list(hypotheses[track])
            if not hyps:
                raise ValueError(f"the hypothesiser gave no hypothesis for track {track!r}")
            for hyp in hyps:
                lw = _log_weight(hyp, track)
                if not hyp:  # the missed-detection hypothesis
                    if has_miss[i]:
                        raise ValueError(f"track {track!r} has two missed-detection hypotheses")
                    has_miss[i] = True
                    log_miss[i] = lw
                    continue
                key = id(hyp.measurement)
                if key in seen:
                    raise ValueError(f"track {track!r} has two hypotheses for one detection")
                seen.add(key)
                rows.append(i)
                cols.append(column.setdefault(key, len(column)))
                logw.append(lw)
        rows = np.asarray(rows, np.int64)
        cols = np.asarray(cols, np.int64)
        logw = np.asarray(logw, float)
        # divide each track's weights by its largest (no β changes; nothing overflows)
        top = log_miss.copy()
        np.maximum.at(top, rows, logw)
        if not np.isfinite(top).all():
            i = int(np.argmin(np.isfinite(top)))
            raise ValueError(f"every hypothesis of track {track_list[i]!r} has probability 0")
        with np.errstate(under="ignore"):
            L_pairs = np.exp(logw - top[rows])
            miss = np.exp(log_miss - top)
        groups = clusters((N, len(column), rows, cols))
        # one-track clusters: PDA (exact); the others under the budget
        self.last_clusters = [
            (1, int(len(cl.measurements)), "pda", "") for cl in groups if len(cl.tracks) == 1
        ]

        def solve(k, tr, ms, L, miss_k):
            beta, method, reason = self._cluster_beta(L, miss_k, tr, track_list)
            self.last_clusters.append((len(tr), len(ms), method, reason))
            return beta

        miss_beta, pair_beta = cluster_pair_marginals(groups, rows, cols, L_pairs, miss, solve)
        pair_of = {(int(r), int(c)): k for k, (r, c) in enumerate(zip(rows, cols, strict=True))}
        return self._hypotheses_out(hypotheses, track_list, pair_of, pair_beta, miss_beta, column)

    def _cluster_beta(self, L, miss, tr, track_list):
        method = self._method
        try:
            res = budgeted_marginals(
                L,
                miss,
                method=method,
                approximation=None if self.approximation == "raise" else self.approximation,
                max_tracks=self.exact_max_tracks if method == "exact" else None,
                exact_options={"max_bits": self.max_bits, "max_memory": self.max_memory},
            )
        except ExactLimitError as exc:
            raise ExactLimitError(
                f"cluster of {L.shape[0]} tracks and {L.shape[1]} detections is past the "
                f"exact budget ({exc})"
            ) from None
        except InfeasibleAssignmentError:
            raise InfeasibleAssignmentError(
                "no joint association of tracks "
                f"{[track_list[int(t)] for t in tr]!r} has positive probability (every "
                "track must take a detection, P_D·P_G = 1, and there are too few)"
            ) from None
        if res.reason:
            log.warning(
                "cluster of %d tracks and %d detections past the exact budget (%s): used %s",
                L.shape[0],
                L.shape[1],
                res.reason,
                res.method,
            )
        return res.beta, res.method, res.reason

    @staticmethod
    def _hypotheses_out(hypotheses, track_list, pair_of, pair_beta, miss_beta, column):
        out = {}
        for i, track in enumerate(track_list):
            single = []
            for hyp in hypotheses[track]:
                if not hyp:
                    b = miss_beta[i]
                else:
                    b = pair_beta[pair_of[i, column[id(hyp.measurement)]]]
                single.append(
                    SingleProbabilityHypothesis(
                        hyp.prediction,
                        hyp.measurement,
                        measurement_prediction=hyp.measurement_prediction,
                        probability=Probability(float(b)),
                    )
                )
            # β rows already sum to 1 (to rounding): Stone Soup's normalise=True
            # would redo it in Probability arithmetic, about 40 % of the call
            mh = MultipleHypothesis(single, normalise=False, total_weight=1)
            mh.normalise = True  # what EHM2's result says, and true
            out[track] = mh
        return out


class JPDALBP(JPDAExact):
    """JPDA with loopy-belief-propagation marginals (Williams & Lau), on jointtrack's LBP.

    Same interface as :class:`JPDAExact` (and Stone Soup's ``JPDAwithLBP``);
    every cluster uses :func:`jointtrack.association.lbp.lbp_marginals`, whose
    stopping rule certifies the distance to the BP fixed point when every
    missed-detection weight is positive. Exact for clusters of one track and for
    clusters whose gating graph has no cycle.
    """

    _method = "lbp"
