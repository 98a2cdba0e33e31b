"""The JPDA tracker: predict → gate → cluster → associate → update → track logic.

Bojilov et al. describe the whole loop (§2–§4): per scan, every track's
validation gate is formed, tracks sharing measurements are grouped into
clusters, the association probabilities β of each cluster are computed (eq. 5–7,
here exactly by :func:`jointtrack.association.marginals` without enumeration)
and each track is updated with the combined innovation (eq. 4). Track
initiation, confirmation and deletion follow the usual M-of-N logic
(Blackman & Popoli 1999, §6.2) or, with ``existence=True``, the integrated
probability of target existence of JIPDA (Mušicki & Evans 2004, "Joint integrated
probabilistic data association: JIPDA", IEEE T-AES 40(3)).

All tracks live in a few arrays (states ``x`` (N, n), covariances ``P``
(N, n, n), ids, counters), so a scan is a handful of batched numpy calls plus
one association call per multi-track cluster — no per-track Python objects.

Id continuation (``TrackerConfig.id_continuation``, issue 32). A track that loses
its target (a turn, a run of misses) is deleted and the target's next returns start
a new track, under a new id: on the switzerland ADS-B scene half of all id changes
were such a death and rebirth. Causally, at the scan a new track confirms (before it
is ever reported), it takes the id of a confirmed track deleted at most
``id_continuation`` seconds before when the new track's position and velocity lie
inside the gate (:data:`CONTINUATION_GATE` over position and velocity) of that track's
coasted prediction: ``d² = (x − x̂)ᵀ(P + P̂)⁻¹(x − x̂) ≤ χ²_{2·dim}(0.99)``, the
consistency test of two estimates of one state (Bar-Shalom, Li & Kirubarajan,
*Estimation with Applications to Tracking and Navigation*, Wiley 2001, §11.7.3, with
the cross-covariance neglected). A confirmed track that is losing its target — it
missed this scan, or (JIPDA) its existence fell below ``r_confirm``: its returns lie
far out in its gate, where the new track's are near (on switzerland 43 of 71 rebirths
were confirmed while the old track was still reported, its existence 0.36–0.75) — is
a candidate too, with its current state: the new track takes its id and the losing
track ends. Only unambiguous pairs: the new track in the gate of exactly one candidate
and of no confirmed track still holding its target, that candidate in the gate of no
other new track — close targets get no id on a guess. Nothing already reported
changes. ``ScanResult.n_continued`` counts them. Measured (``benchmarks/RESULTS.md``):
on the held-out quickstart flights (close pairs orbiting together) the greedy
closest-first pairing in the ``p_g`` gate cost purity 0.853 → 0.827; this rule 0.834
(both with a 6-scan window and plain CV JPDA; with the fitted JPDA* and IMM: 0.838 at 6
scans, 0.856 at the fitted 3, 0.860 with continuation off).
The window bounds the gate: a deleted track's prediction coasted a minute is wide
enough to take in another aircraft kilometres away (on quickstart one landing, one
taking off); the fit's window for scan files (3 scan intervals,
:data:`jointtrack.experiments.fit.CONTINUATION_SCANS`) is what a rebirth takes.
"""

from __future__ import annotations

import dataclasses
import logging
import time

import numpy as np

from jointtrack.assignment._checks import _as_real_array, as_float
from jointtrack.association.clustering import clusters
from jointtrack.association.clutter import cluster_heuristic_densities
from jointtrack.association.coalescence import jpda_star_marginals
from jointtrack.association.gating import gate_threshold, likelihood_ratio_pairs
from jointtrack.association.pda import pda_pair_marginals
from jointtrack.errors import ExactLimitError
from jointtrack.filters import (
    imm_combine,
    imm_pair_log_likelihoods,
    imm_pda_pairs_update,
    imm_predict,
    pda_pairs_update,
    predict,
)
from jointtrack.filters.imm import IMMModes
from jointtrack.models import ConstantVelocity
from jointtrack.models.motion import ConstantAcceleration, Stationary, cv_noise
from jointtrack.trackers.base import ClusterRecord, ScanResult, ScanTracker
from jointtrack.trackers.config import TrackerConfig
from jointtrack.trackers.existence import (
    existence_update,
    merge_duplicates,
    most_probable_event,
)
from jointtrack.trackers.history import TrackHistory, is_datetime
from jointtrack.trackers.initiation import pair_returns
from jointtrack.trackers.reporting import (
    check_report_fields,
    label_identities,
    match_labels,
    scaled_pair_factor,
    scan_detection,
    seed_velocities,
)
from jointtrack.trackers.state_io import (
    StateFileError,
    covariance_problem,
    validate_component_arrays,
    validate_mode_arrays,
    validate_retired_arrays,
    validate_tracker_arrays,
    validate_update_arrays,
)
from jointtrack.trackers.track_splitting import component_layout, its_update, prune_children

__all__ = ["ClusterRecord", "JPDATracker", "ScanResult", "TrackHistory", "TrackerConfig"]

#: id continuation: the χ²_{2·dim} probability of the gate in which a new track's position
#: and velocity must lie around a deleted (or losing) track's (module docstring)
CONTINUATION_GATE = 0.99
#: tentative_association = "alternatives": the share of a confirming tentative track's
#: likelihood on returns confirmed tracks explain that makes it a duplicate
#: (:meth:`JPDATracker._duplicate_confirmations`)
DUPLICATE_SHARE = 0.15

log = logging.getLogger("jointtrack.tracker")
#: motion models whose ``transition`` / ``noise`` take an array of intervals (one
#: batched prediction of every track from its own last update, reporting = "async")
_INTERVAL_ARRAY_MODELS = (ConstantVelocity, ConstantAcceleration, Stationary)
#: this many tracks (or more) with one interval since their updates are predicted with one
#: shared F (see JPDATracker._predict_from_update)
SHARED_INTERVAL_TRACKS = 2


class JPDATracker(ScanTracker):
    """Multi-target JPDA tracker (see the module docstring).

    >>> import numpy as np
    >>> trk = JPDATracker(TrackerConfig(clutter_density=1e-4))
    >>> detections = [(float(t), np.array([[t, 0.0], [50.0, 3.0 * t]])) for t in range(5)]
    >>> for t, z in detections:            # z: (M, dim) positions at time t
    ...     result = trk.step(t, z)        # confirmed tracks in result.ids / result.x
    >>> table = trk.history()              # every confirmed estimate: a TrackHistory
    """

    KIND = "jpda"
    CONFIG = TrackerConfig
    REPORT_FIELDS = ("labels", "velocities")
    SUPPORTS_IMM = True

    def __init__(
        self,
        config: TrackerConfig | None = None,
        *,
        motion=None,
        sensor=None,
        sensors=None,
        on_cluster=None,
        keep_history: bool = True,
    ):
        """Build a tracker from ``config`` and, optionally, model objects.

        The arguments are those of :class:`~jointtrack.trackers.base.ScanTracker`:
        ``motion`` and ``sensor`` model objects (default: built from ``config``),
        ``sensors`` ``{id: Sensor}`` for multi-sensor runs (``step(t, z,
        sensor=id)``), ``on_cluster(record)`` called with a
        :class:`ClusterRecord` for every multi-track cluster, and
        ``keep_history`` (record every confirmed estimate for :meth:`history`).
        """
        super().__init__(
            config,
            motion=motion,
            sensor=sensor,
            sensors=sensors,
            on_cluster=on_cluster,
            keep_history=keep_history,
        )
        c = self.config
        n = self.state_dim
        # the sensor of scans whose reports all carry a velocity (measure_velocity)
        self._position_velocity = None
        if c.measure_velocity:
            from jointtrack.models import LinearPosition, LinearPositionVelocity

            self._position_velocity = LinearPositionVelocity(
                LinearPosition(c.dim, c.measurement_covariance(), state_dim=n), c.velocity_std**2
            )
        self.x = np.zeros((0, n))
        self.P = np.zeros((0, n, n))
        # motion = "imm": each track's modes — state in the modes' common state
        # (N, r, n_c), covariance and log probability (N, r); r = 0 without an IMM.
        # x and P above are then the combined position and velocity (what is
        # reported, gated and confirmed).
        self._imm = self._motion if isinstance(self._motion, IMMModes) else None
        r, nc = (self._imm.n_modes, self._imm.state_dim) if self._imm else (0, 0)
        self.mode_x = np.zeros((0, r, nc))
        self.mode_P = np.zeros((0, r, nc, nc))
        self.mode_log_prob = np.zeros((0, r))
        # Each track's state after its last update and that update's time: with
        # reporting = "async" a track no report updated is predicted from there over
        # the whole interval, not scan by scan (see _predict_from_update)
        self.updated_time = np.zeros(0)
        self.updated_x = np.zeros((0, n))
        self.updated_P = np.zeros((0, n, n))
        self.updated_mode_x = np.zeros((0, r, nc))
        self.updated_mode_P = np.zeros((0, r, nc, nc))
        self.updated_mode_log_prob = np.zeros((0, r))
        self.ids = np.zeros(0, np.int64)
        self.confirmed = np.zeros(0, bool)
        self.hit_history = np.zeros(0, np.int64)  # bit k: hit k scans ago
        self.age = np.zeros(0, np.int64)
        self.misses = np.zeros(0, np.int64)
        self.existence = np.zeros(0)
        # time of each track's last hit and of its birth, its (soft) number of
        # reports since birth (the reporting rate of reporting = "async"), its label
        self.last_hit = np.zeros(0)
        self.born = np.zeros(0)
        self.report_count = np.zeros(0)
        self.labels = np.zeros(0, dtype="U1")
        # every label seen (sorted) and the id of its target's track
        self.label_names = np.zeros(0, dtype="U1")
        self.label_ids = np.zeros(0, np.int64)
        # unassociated returns of the previous scan (positions, covariances): two-point seeds
        self.seeds = np.zeros((0, c.dim))
        self.seed_covs = np.zeros((0, c.dim, c.dim))
        self.seed_times = np.zeros(0)  # scan time of each seed
        # confirmed tracks deleted within the last id_continuation seconds (unlabelled):
        # id, combined state and covariance at deletion, and the time of that state
        self.retired_ids = np.zeros(0, np.int64)
        self.retired_x = np.zeros((0, 2 * c.dim))
        self.retired_P = np.zeros((0, 2 * c.dim, 2 * c.dim))
        self.retired_time = np.zeros(0)
        # tentative_association = "splitting": each tentative track's components
        # (jointtrack.trackers.track_splitting) in K slots — states (N, K, n),
        # covariances (N, K, n, n), log weights (N, K), how many slots are in use
        # (N,), the most probable first; K = 0 otherwise, and a confirmed track has none
        K = c.tentative_components if c.tentative_association == "splitting" else 0
        self.comp_x = np.zeros((0, K, n))
        self.comp_P = np.zeros((0, K, n, n))
        self.comp_log_w = np.zeros((0, K))
        self.comp_n = np.zeros(0, np.int64)

    # ------------------------------------------------------------------ scan
    def _step(self, t, z, same_time_ok=False, labels=None, velocities=None) -> ScanResult:
        c = self.config
        t, z, dt, n_coincident = self._check_scan(t, z, same_time_ok)
        n_continued = 0
        labels, repeated, velocities, n_coincident = self._check_report_fields(
            t, z, labels, velocities, n_coincident
        )
        if (
            c.measure_velocity
            and velocities is not None
            and self._active_sensor is None
            and len(z)
            and np.isfinite(velocities).all()
        ):
            # every report has a velocity: measure it too (z = [p, v]); _activate
            # puts the position sensor back at the next step
            z = np.hstack([z, velocities])
            self._sensor, self._mdim = self._position_velocity, 2 * c.dim

        if dt is None:  # the first scan: tracks started without a time are taken to be at it
            self.updated_time[:] = t
        if dt is not None and dt > 0 and len(self.ids):
            if c.reporting == "async":
                self._predict_from_update(t)
            elif self._imm is not None:
                # mixing and mode-conditioned prediction; the predicted mode
                # probabilities c̄ stand until an update (a track without a pair keeps them)
                self.mode_x, self.mode_P, self.mode_log_prob = imm_predict(
                    self.mode_x, self.mode_P, self.mode_log_prob, self._imm, dt
                )
                self._combine(slice(None))
            else:
                self.x, self.P = predict(
                    self.x, self.P, self._motion.transition(dt), self._motion.noise(dt)
                )
                if c.tentative_process_noise > 0:
                    # a tentative velocity is a guess from a few returns (config docstring)
                    d2 = 2 * c.dim
                    self.P[~self.confirmed, :d2, :d2] += cv_noise(
                        dt, c.tentative_process_noise, c.dim
                    )
                if self.comp_n.any():
                    self._predict_components(dt)
        self._scan_detection(t, 0.0 if dt is None else dt)
        if c.existence and len(self.ids):
            # survival to the time this scan's evidence is about (see _scan_detection)
            self.existence = self.existence * self._scan_survival
            alive = self.existence > 0.0
            if not alive.all():  # underflowed: no target left to associate or report
                self._retire(~alive, t)
                self._keep(alive)
                for name in self._SCAN_ARRAYS:
                    setattr(self, name, getattr(self, name)[alive])
        N, M = len(self.ids), len(z)
        beta0 = np.ones(N)
        pair_rows, pair_cols, pair_w = [], [], []
        hit = np.zeros(N, bool)
        # Reports that name their target go to that target's track (or start it);
        # only the rest, and the unlabelled tracks, take part in the association.
        labelled = self.labels != ""
        if labels is not None:
            lab_rows, lab_cols, open_cols = self._match_labels(labels, repeated)
            # a report outside its own track's gate: a position jump (see _restart)
            jumped = ~self._pairs_gated(self.x[lab_rows], self.P[lab_rows], z[lab_cols])
            beta0[labelled] = 1.0
            beta0[lab_rows] = 0.0
            hit[lab_rows] = True
            pair_rows.append(lab_rows)
            pair_cols.append(lab_cols)
            pair_w.append(np.ones(len(lab_rows)))
            z_index = np.flatnonzero((labels == "") & ~repeated)
        else:
            lab_rows = np.zeros(0, np.int64)
            open_cols = np.zeros(0, np.int64)
            z_index = np.arange(M)
        zu = z[z_index]
        Mu = len(zu)
        free = np.arange(Mu)
        sizes, seconds, methods, fallbacks, kinds = [], [], [], [], []
        # Confirmed tracks first, then tentative ones. With JIPDA the tentative
        # tracks see every return, each weighted by the probability that no
        # confirmed track took it (jointtrack.trackers.existence, point 1); with
        # M-of-N logic (no existence to weigh a clutter-born track's claim) they
        # see only the returns no confirmed track gated, so they cannot glue true
        # targets' clusters together (cf. a separate initiator, Blackman & Popoli §6).
        available = np.ones(Mu)  # JIPDA: P(return not taken by an earlier pass)
        tentative_pairs = None  # JIPDA: the tentative pass's pairs (duplicate confirmations)
        ungated = np.ones(Mu, bool)  # JIPDA: returns no pass gated (two-point seeds)
        for group, loud in (
            (np.flatnonzero(self.confirmed & ~labelled), True),
            (np.flatnonzero(~self.confirmed & ~labelled), False),
        ):
            if len(group) == 0:
                continue
            if c.existence:
                if not loud:
                    claimed = 1.0 - available  # by the confirmed tracks
                b0, (pr, pc, pw), h, free_local, info, used, raw = self._associate(
                    group, zu, loud, available=available
                )
                if not loud:
                    tentative_pairs = (group[pr], pc, used, raw)
                available = np.clip(available - np.bincount(pc, used, minlength=Mu), 0.0, 1.0)
                in_no_gate = np.zeros(Mu, bool)
                in_no_gate[free_local] = True
                ungated &= in_no_gate
            else:
                b0, (pr, pc, pw), h, free_local, info, _, _ = self._associate(group, zu[free], loud)
                pc = free[pc]
                free = free[free_local]
            beta0[group] = b0
            pair_rows.append(group[pr])
            pair_cols.append(z_index[pc])
            pair_w.append(pw)
            hit[group] = h
            for part, extra in zip((sizes, seconds, methods, fallbacks), info, strict=True):
                part.extend(extra)
            kinds.extend([loud] * len(info[0]))
        if c.existence:
            free = np.flatnonzero(ungated)
        unassoc = z_index[free]
        if N:
            rows = np.concatenate(pair_rows) if pair_rows else np.zeros(0, np.int64)
            cols = np.concatenate(pair_cols) if pair_cols else np.zeros(0, np.int64)
            w = np.concatenate(pair_w) if pair_w else np.zeros(0)
            if c.reporting == "async":  # reports seen: the track's own reporting rate
                self.report_count += np.bincount(rows, w, minlength=N)
            # Only tracks with a pair change: β₀ = 1 leaves x and P as they are (bit
            # for bit), and with one report per scan most tracks have no pair.
            touched = np.flatnonzero(beta0 < 1.0)
            local = np.full(N, -1)
            local[touched] = np.arange(len(touched))
            on = local[rows] >= 0
            if self._imm is not None:
                # IMM-JPDA: each mode's PDA with its mode-conditioned β, then the
                # mode probabilities (jointtrack.filters.imm, Blom & Bloem 2000)
                (
                    self.mode_x[touched],
                    self.mode_P[touched],
                    self.mode_log_prob[touched],
                ) = imm_pda_pairs_update(
                    self._imm,
                    self.mode_x[touched],
                    self.mode_P[touched],
                    self.mode_log_prob[touched],
                    z,
                    beta0[touched],
                    local[rows[on]],
                    cols[on],
                    w[on],
                    **self._measurement_model(),
                )
                self._combine(touched)
            else:
                self.x[touched], self.P[touched] = pda_pairs_update(
                    self.x[touched],
                    self.P[touched],
                    z,
                    beta0[touched],
                    local[rows[on]],
                    cols[on],
                    w[on],
                    **self._measurement_model(),
                )
            if len(lab_rows):
                self._restart(
                    lab_rows[jumped], z[lab_cols[jumped]], _rows(velocities, lab_cols[jumped])
                )
                self.existence[lab_rows] = c.r_labelled  # the report names a real target
            # the states predictions start from: a scanning sensor's tracks are all
            # predicted scan by scan; a reporting target's from its last update
            self._mark_updated(touched if c.reporting == "async" else slice(None), t)
            if c.existence and labelled.any():
                # a labelled track is detected with P_D,i (no gate: the label decides)
                unheard = labelled.copy()
                unheard[lab_rows] = False
                r, missed = self.existence[unheard], self._scan_missed[unheard]
                self.existence[unheard] = r * missed / ((1.0 - r) + r * missed)
            before = set(self.ids[self.confirmed].tolist())
            held = None
            if c.existence and c.tentative_association != "joint" and tentative_pairs:
                # a duplicate of a confirmed track does not confirm (point 5); it stays
                # tentative with its existence, and confirms once its returns are its own
                held = self._duplicate_confirmations(claimed, *tentative_pairs)
            self._track_logic(hit, t, held)
            if not self.confirmed.all():  # only a tentative track can be a duplicate
                keep, self.existence = merge_duplicates(
                    self.x,
                    self.P,
                    self.ids,
                    self.existence,
                    self.confirmed,
                    c.dim,
                    c.merge_threshold,
                    alternatives=c.tentative_association != "joint",
                )
                self._keep(keep)
            n_continued = self._continue_ids(before, t)
        if len(open_cols):
            self._initiate(
                z[open_cols],
                t,
                c.r_labelled,
                velocities=_rows(velocities, open_cols),
                labels=labels[open_cols],
            )
        if c.existence and c.initiation == "one-point":
            # adaptive birth: every return, weighted by how unexplained it is
            # (jointtrack.trackers.existence, point 2)
            birth_r = c.r_init * available
            born = birth_r > c.r_delete
            self._initiate(zu[born], t, birth_r[born], velocities=_rows(velocities, z_index[born]))
        else:
            self._initiate(z[unassoc], t, velocities=_rows(velocities, unassoc))
        self.time = t
        self.n_scans += 1
        keep = self.confirmed & (self.existence >= c.r_report) if c.existence else self.confirmed
        imm = {}
        if self._imm is not None:
            imm = {
                "mode_names": self._imm.names,
                "mode_probabilities": np.exp(self.mode_log_prob[keep]),
            }
        return ScanResult(
            time=t,
            ids=self.ids[keep].copy(),
            x=self.x[keep].copy(),
            P=self.P[keep].copy(),
            existence=(self.existence[keep] if c.existence else np.ones(int(keep.sum()))),
            n_tentative=int((~self.confirmed).sum()),
            n_measurements=len(z),
            n_unassociated=len(unassoc),
            cluster_sizes=sizes,
            cluster_seconds=seconds,
            cluster_methods=methods,
            cluster_confirmed=kinds,
            cluster_fallbacks=fallbacks,
            n_coincident=n_coincident,
            n_continued=n_continued,
            **imm,
        )

    def _predict_from_update(self, t) -> None:
        """Predict every track from its last update (``updated_*``) to ``t`` (reporting targets).

        A reporting target is heard at its own rate, while the tracker steps at
        every other target's report. Predicting scan by scan would mix the IMM's
        modes at each of those reports: between a moored vessel's reports 3 minutes
        apart the stationary mode would take in the CV mode's growing covariance
        several hundred times. One prediction over the whole interval — one mixing,
        the switching over the interval (``imm_switching_per = "second"``) — is the
        model's own prediction, and n steps without an update give exactly the
        prediction over their sum.

        Profiled on the Solent AIS file (one scan per report, ~60 live tracks) one
        ``predict`` call per distinct interval was 79 % of the CPU: nearly every track
        has an interval of its own. The motion models of :mod:`jointtrack.models.motion`
        take an array of intervals, so the tracks whose interval no two others share
        are predicted in one batched call, each with its own F(Δt_i), Q(Δt_i); two or
        more tracks with one interval are still predicted together with a shared F —
        numpy then forms F x with a BLAS product (fused multiply-adds) where the
        per-track stack uses another summation, and keeping the shared call keeps the
        states bit for bit as before (``benchmarks/realdata_async.py`` checks this on
        the whole Solent file). IMM tracks, and a motion object of the caller's, are
        predicted one interval at a time, the tracks with equal intervals together.
        """
        gaps = t - self.updated_time
        if isinstance(self._motion, _INTERVAL_ARRAY_MODELS):
            values, inverse, counts = np.unique(gaps, return_inverse=True, return_counts=True)
            shared = counts[inverse] >= SHARED_INTERVAL_TRACKS
            own = np.flatnonzero(~shared & (gaps > 0))
            # not moved since their update, or predicted below from it
            self.x[:], self.P[:] = self.updated_x, self.updated_P
            if len(own):
                g = gaps[own]
                self.x[own], self.P[own] = predict(
                    self.updated_x[own],
                    self.updated_P[own],
                    self._motion.transition(g),
                    self._motion.noise(g),
                )
            for k in np.flatnonzero((counts >= SHARED_INTERVAL_TRACKS) & (values > 0)):
                rows = np.flatnonzero(inverse == k)
                gap = values[k]
                F, Q = self._motion.transition(gap), self._motion.noise(gap)
                self.x[rows], self.P[rows] = predict(self.x[rows], self.P[rows], F, Q)
            return
        for gap in np.unique(gaps):
            rows = np.flatnonzero(gaps == gap)
            if self._imm is not None:
                xs, Ps, lps = (
                    self.updated_mode_x[rows],
                    self.updated_mode_P[rows],
                    self.updated_mode_log_prob[rows],
                )
                if gap > 0:
                    xs, Ps, lps = imm_predict(xs, Ps, lps, self._imm, gap)
                self.mode_x[rows], self.mode_P[rows], self.mode_log_prob[rows] = xs, Ps, lps
            else:
                x, P = self.updated_x[rows], self.updated_P[rows]
                if gap > 0:
                    F, Q = self._motion.transition(gap), self._motion.noise(gap)
                    x, P = predict(x, P, F, Q)
                self.x[rows], self.P[rows] = x, P
        if self._imm is not None:
            self._combine(slice(None))

    def _mark_updated(self, rows, t) -> None:
        """Record the tracks ``rows``' current states as their last update, at ``t``."""
        self.updated_time[rows] = t
        self.updated_x[rows], self.updated_P[rows] = self.x[rows], self.P[rows]
        self.updated_mode_x[rows] = self.mode_x[rows]
        self.updated_mode_P[rows] = self.mode_P[rows]
        self.updated_mode_log_prob[rows] = self.mode_log_prob[rows]

    def _combine(self, rows) -> None:
        """x, P of the tracks ``rows``: the modes' combined (moment-matched) position
        and velocity (:func:`~jointtrack.filters.imm.imm_combine`)."""
        k = self.state_dim
        x, P = imm_combine(self.mode_x[rows], self.mode_P[rows], self.mode_log_prob[rows])
        self.x[rows], self.P[rows] = x[:, :k], P[:, :k, :k]

    def _mode_states(self, x0, P0):
        """Per-mode states ``(mode_x, mode_P, mode_log_prob)`` of new tracks at ``x0, P0``."""
        c = self.config
        if self._imm is None:
            k = len(x0)
            return np.zeros((k, 0, 0)), np.zeros((k, 0, 0, 0)), np.zeros((k, 0))
        return self._imm.initial_states(
            x0, P0, (c.max_acceleration / 2.0) ** 2, (c.max_turn_rate / 2.0) ** 2
        )

    # ------------------------------------------------------- reporting targets
    def _check_report_fields(self, t, z, labels, velocities, n_coincident):
        """Validated ``labels`` and ``velocities`` of a scan's reports
        (:func:`~jointtrack.trackers.reporting.check_report_fields`)."""
        return check_report_fields(
            self.config.dim, z, labels, velocities, self._kept_rows, n_coincident
        )

    def _scan_detection(self, t, dt):
        """Per-track detection and survival of this scan
        (:func:`~jointtrack.trackers.reporting.scan_detection`).

        Sets ``_scan_pd`` (P_D,i), ``_scan_pdg`` (the P_D·P_G of the miss weight;
        P_D,i for a labelled track, which has no gate), ``_scan_missed`` = 1 −
        ``_scan_pdg``, the pair factor ``_scan_pd_ratio`` and ``_scan_survival``,
        the factor that takes each existence from the previous scan to this one.
        """
        c = self.config
        det = scan_detection(
            c,
            self._p_d,
            t,
            dt,
            t - dt if self.time is None else self.time,
            self.born,
            self.report_count,
            self.labels != "",
            in_gate=c.p_g if c.miss_model == "1-pd*pg" else 1.0,
        )
        self._scan_pd, self._scan_pdg, self._scan_missed = det.pd, det.pdg, det.missed
        self._scan_pd_ratio, self._scan_survival = det.pd_ratio, det.survival

    def _match_labels(self, labels, repeated):
        """``(track rows, report columns, open columns)`` of the labelled reports
        (:func:`~jointtrack.trackers.reporting.match_labels`)."""
        return match_labels(self.labels, labels, repeated)

    def _restart(self, rows, z_new, velocities):
        """Restart the tracks ``rows`` on the reports ``z_new``, keeping ids and labels.

        Used for a labelled report outside the validation gate of its own
        target's track: a position jump (or a manoeuvre the motion model cannot
        follow). Dragging the track part of the way with a huge innovation
        would leave it wrong for several reports; a new id would break the
        identity the label guarantees.
        """
        if len(rows):
            self.x[rows], self.P[rows] = self._initial_states(z_new, velocities)
            modes = self._mode_states(self.x[rows], self.P[rows])
            self.mode_x[rows], self.mode_P[rows], self.mode_log_prob[rows] = modes

    def _cluster_marginals(self, Lc, mc, loud):
        """β of one multi-track cluster: JPDA* for confirmed tracks with
        ``coalescence_avoidance`` (:func:`~jointtrack.association.coalescence.jpda_star`),
        else (and past JPDA*'s event budget, a counted fallback) the configured method.

        Only confirmed tracks: coalescence is what loses the ids of the targets
        being reported, and clusters of clutter-born tentative tracks are the
        large ones, where enumerating events would not pay.
        """
        if not (loud and self.config.coalescence_avoidance):
            return super()._cluster_marginals(Lc, mc, loud)
        t0 = time.perf_counter()
        try:
            beta = jpda_star_marginals(Lc, mc)
        except ExactLimitError as exc:
            beta, method, reason, _ = super()._cluster_marginals(Lc, mc, loud)
            own = f"jpda_star_budget: {exc}"
            if not reason:
                self._log_fallback(len(Lc), Lc.shape[1], loud, own, method)
            return beta, method, reason or own, time.perf_counter() - t0
        return beta, "jpda*", "", time.perf_counter() - t0

    def _exact_budget(self, loud):
        """Confirmed tracks (``loud``): ``exact_max_tracks``; tentative ones: the
        frontier-width budget ``exact_max_bits_tentative`` and no track limit (or,
        when that is None, ``exact_max_tracks`` as for confirmed tracks). The
        frontier width is the measure of the ``"exact"`` engine only; with
        ``association = "enumerate"`` (whose cost is the number of hypotheses)
        every cluster keeps ``exact_max_tracks``."""
        bits = self.config.exact_max_bits_tentative
        if loud or bits is None or self.config.association != "exact":
            return self.config.exact_max_tracks, None, ""
        return None, bits, "exact_max_bits_tentative"

    def _associate(self, tracks, z, loud, available=None):
        """Association probabilities of the given tracks against ``z``, cluster by cluster.

        Gating on a KD-tree (:func:`~jointtrack.association.gate_pairs`), clusters
        from the gated pairs, Bojilov's (8) or the known clutter density, the
        likelihood ratios of the gated pairs, then per cluster: single tracks by
        PDA (exact for one track, all at once), the others by the configured
        method. Returns ``(beta0, (rows, cols, weights), hit, unassociated,
        (sizes, seconds, methods, fallbacks), used, raw)`` with rows/cols local to
        ``tracks``/``z``; with JIPDA it updates the tracks' existence, the β are
        conditioned on existence and ``used`` holds the unconditional pair
        probabilities (what the returns' availability and birth existence need),
        else None. ``raw``: each pair's likelihood ratio before ``available``
        scaled it. ``available`` (M,): the probability that each return was not
        taken by an earlier pass; it scales the likelihood ratios.

        With ``tentative_association = "alternatives"`` the tentative tracks
        (``loud`` False) are each associated alone — single-track PDA, exact —
        whatever other tentative tracks gate their returns, and the β returned
        are those of each track's most probable event (its state follows one
        history; :mod:`jointtrack.trackers.existence`, point 5).
        """
        c = self.config
        if not loud and c.existence and c.tentative_association == "splitting":
            return self._associate_splitting(tracks, z, available)
        n, M = len(tracks), len(z)
        g = self._gate(self.x[tracks], self.P[tracks], z)
        groups = clusters(g)
        lam = self._clutter_densities(g, groups, M)
        r = self.existence[tracks] if c.existence else np.ones(n)
        # P_D,i·r_i / λ, both divided by a common scale (a rate may exceed 1)
        pd_r, scale = scaled_pair_factor(self._scan_pd_ratio[tracks], r)
        if self._imm is not None:
            # the association weighs each pair by the modes' mixture likelihood
            # Σ_j c̄_j g_ij (jointtrack.filters.imm); the gate is the combined estimate's
            log_g, _ = imm_pair_log_likelihoods(
                self._imm,
                self.mode_x[tracks],
                self.mode_P[tracks],
                self.mode_log_prob[tracks],
                z,
                g.rows,
                g.cols,
                **self._measurement_model(),
            )
            g = dataclasses.replace(g, log_g=log_g)
        raw, _ = likelihood_ratio_pairs(g, pd_r, lam / scale)
        L_pairs = raw
        if available is not None:  # a return taken by an earlier pass is less likely ours
            L_pairs = raw * available[g.cols]
        missed = self._scan_missed[tracks]
        miss = (1.0 - r) + r * missed  # 1 − r P_D P_G
        rows, cols = g.rows, g.cols
        if not loud and c.existence and c.tentative_association == "alternatives":
            # alternatives of one target do not compete for its returns: each alone
            beta0, weights = pda_pair_marginals(rows, L_pairs, miss)
            info = ([], [], [], [])
        else:
            beta0, weights, groups, info = self._pair_marginals(
                self.ids[tracks], g, L_pairs, miss, loud, groups
            )
        used = None
        if c.existence:
            used = weights.copy()  # unconditional: how much each pair explains its return
            self.existence[tracks], beta0, weights = existence_update(
                r, beta0, weights, rows, self._scan_pdg[tracks], missed=missed
            )
            if not loud and c.tentative_association == "alternatives":
                # each alternative follows one history: its most probable return
                beta0, weights = most_probable_event(beta0, weights, rows)
        return (
            beta0,
            (rows, cols, weights),
            g.n_gated > 0,
            groups.unassociated,
            info,
            used,
            raw,
        )

    def _clutter_densities(self, g, groups, M):
        """The clutter density of each of ``M`` returns: the known one, or Bojilov (8)
        over the clusters ``groups`` of the gated pairs ``g``."""
        if self._clutter is not None:
            return self._clutter
        # Bojilov (8): λ = Σ_i m_i / Σ_i V_i over each cluster's tracks
        dens = cluster_heuristic_densities(g.n_gated, g.gate_volume, groups.track_cluster)
        lam = np.ones(M)
        gated = groups.measurement_cluster >= 0
        lam[gated] = dens[groups.measurement_cluster[gated]]
        return lam

    def _associate_splitting(self, tracks, z, available):
        """:meth:`_associate` of tentative tracks with ``tentative_association =
        "splitting"``: each an integrated track-splitting filter
        (:mod:`jointtrack.trackers.track_splitting`), alone on the returns weighted by
        ``available``, as the alternatives are.

        Updates the tracks' existence, components and (moment-matched) ``x``, ``P``
        itself; returns :meth:`_associate`'s tuple with β₀ = 1 (nothing left for the
        PDA update) and the track–return pairs summed over components (what the
        returns' availability and the duplicate rule need).
        """
        n, M = len(tracks), len(z)
        owner, slot = component_layout(self.comp_n[tracks])
        cx = self.comp_x[tracks[owner], slot]
        cP = self.comp_P[tracks[owner], slot]
        log_w = self.comp_log_w[tracks[owner], slot]
        g = self._gate(cx, cP, z)
        groups = clusters(g)
        lam = self._clutter_densities(g, groups, M)
        r = self.existence[tracks]
        pd_r, scale = scaled_pair_factor(self._scan_pd_ratio[tracks][owner], r[owner])
        raw, _ = likelihood_ratio_pairs(g, pd_r, lam / scale)
        self.existence[tracks], miss_log_w, hit_log_w, used = its_update(
            r,
            log_w,
            owner,
            g.rows,
            raw * available[g.cols],
            self._scan_missed[tracks],
            self._scan_pdg[tracks],
        )
        p = len(g.rows)
        hx, hP = cx[g.rows], cP[g.rows]
        if p:  # each pair's child: its component's Kalman update on its return
            hx, hP = pda_pairs_update(
                hx,
                hP,
                z,
                np.zeros(p),
                np.arange(p),
                g.cols,
                np.ones(p),
                **self._measurement_model(),
            )
        child_owner = np.concatenate([owner, owner[g.rows]])
        keep, kept_log_w = prune_children(
            child_owner, np.concatenate([miss_log_w, hit_log_w]), self.comp_x.shape[1]
        )
        counts = np.bincount(child_owner[keep], minlength=n)
        new_owner, new_slot = component_layout(counts)
        for name in ("comp_x", "comp_P", "comp_log_w"):
            getattr(self, name)[tracks] = 0.0
        self.comp_x[tracks[new_owner], new_slot] = np.concatenate([cx, hx])[keep]
        self.comp_P[tracks[new_owner], new_slot] = np.concatenate([cP, hP])[keep]
        self.comp_log_w[tracks[new_owner], new_slot] = kept_log_w
        self.comp_n[tracks] = counts
        self._mixture_state(tracks)
        # the track–return pairs, summed over the components that gated the return
        key = owner[g.rows] * M + g.cols
        pairs, inv = np.unique(key, return_inverse=True)
        used_t = np.bincount(inv, used, minlength=len(pairs))
        raw_t = np.bincount(inv, np.exp(log_w[g.rows]) * raw, minlength=len(pairs))
        hit_t = np.bincount(inv, np.exp(hit_log_w), minlength=len(pairs))
        hit = np.bincount(owner, g.n_gated > 0, minlength=n) > 0
        return (
            np.ones(n),
            (pairs // M, pairs % M, hit_t),
            hit,
            groups.unassociated,
            ([], [], [], []),
            used_t,
            raw_t,
        )

    def _mixture_state(self, rows) -> None:
        """x, P of the tracks ``rows`` that hold components: their mixture's mean and
        covariance (moment matching, :func:`~jointtrack.filters.imm.imm_combine`)."""
        rows = np.asarray(rows)
        counts = self.comp_n[rows]
        for k in np.unique(counts[counts > 0]):
            at = rows[counts == k]
            self.x[at], self.P[at] = imm_combine(
                self.comp_x[at, :k], self.comp_P[at, :k], self.comp_log_w[at, :k]
            )

    def _predict_components(self, dt) -> None:
        """Predict every track component over ``dt`` (the motion model, plus
        ``tentative_process_noise`` as a tentative track's own prediction), then the
        tracks' moment-matched ``x``, ``P``."""
        c = self.config
        rows, slot = component_layout(self.comp_n)
        cx, cP = predict(
            self.comp_x[rows, slot],
            self.comp_P[rows, slot],
            self._motion.transition(dt),
            self._motion.noise(dt),
        )
        if c.tentative_process_noise > 0:
            d2 = 2 * c.dim
            cP[:, :d2, :d2] += cv_noise(dt, c.tentative_process_noise, c.dim)
        self.comp_x[rows, slot], self.comp_P[rows, slot] = cx, cP
        self._mixture_state(np.flatnonzero(self.comp_n))

    def _collapse(self, rows) -> None:
        """The tracks ``rows`` (just confirmed) leave their mixture for one Gaussian:
        its moment-matched ``x``, ``P`` (already held) or, with
        ``tentative_confirm_state = "dominant"``, its most probable component (slot 0)."""
        rows = rows[self.comp_n[rows] > 0]
        if not len(rows):
            return
        if self.config.tentative_confirm_state == "dominant":
            self.x[rows], self.P[rows] = self.comp_x[rows, 0], self.comp_P[rows, 0]
        for name in ("comp_x", "comp_P", "comp_log_w"):
            getattr(self, name)[rows] = 0.0
        self.comp_n[rows] = 0

    def _duplicate_confirmations(self, claimed, rows, cols, used, raw):
        """Tentative tracks about to confirm on returns a confirmed track explains (a mask:
        they stay tentative this scan).

        ``tentative_association = "alternatives"`` (:mod:`jointtrack.trackers.existence`,
        point 5). ``claimed`` (M,): the probability that each return of the scan
        is a confirmed track's; ``rows`` (tracks), ``cols`` (returns), ``used``
        (unconditional pair probabilities) and ``raw`` (likelihood ratios before
        the returns' availability scaled them) the tentative pass's gated pairs.
        In decreasing existence, a tentative track reaching ``r_confirm`` is a
        duplicate when at least :data:`DUPLICATE_SHARE` of its likelihood lies on
        claimed returns, Σ_m L(m)·claimed(m) / Σ_m L(m); otherwise it confirms and
        its own returns count as claimed for the tracks after it. A target's
        alternatives then confirm once, while a target in the next lane, whose
        likelihood lies on its own returns, confirms beside a confirmed neighbour.
        """
        c = self.config
        duplicate = np.zeros(len(self.ids), bool)
        ready = np.flatnonzero(
            ~self.confirmed & (self.labels == "") & (self.existence >= c.r_confirm)
        )
        if not len(ready):
            return duplicate
        claimed = claimed.copy()
        for i in ready[np.argsort(-self.existence[ready], kind="stable")]:
            mine = np.flatnonzero(rows == i)
            total = raw[mine].sum()
            if total > 0 and raw[mine] @ claimed[cols[mine]] >= DUPLICATE_SHARE * total:
                duplicate[i] = True
            else:
                claimed[cols[mine]] = np.minimum(claimed[cols[mine]] + used[mine], 1.0)
        return duplicate

    def _track_logic(self, hit, t, held=None):
        c = self.config
        self.age += 1
        self.last_hit = np.where(hit, t, self.last_hit)
        self.hit_history = ((self.hit_history << 1) | hit.astype(np.int64)) & (
            (1 << c.confirm_n) - 1
        )
        self.misses = np.where(hit, 0, self.misses + 1)
        pos_var = np.einsum("nii->n", self.P[:, : c.dim, : c.dim]) / c.dim
        blown = np.sqrt(pos_var) > c.max_position_std
        if c.existence:
            ready = self.existence >= c.r_confirm
            if held is not None:
                ready &= ~held
            self._collapse(np.flatnonzero(ready & ~self.confirmed))
            self.confirmed |= ready
            dead = self.existence < c.r_delete
        else:
            hits = np.array([bin(h).count("1") for h in self.hit_history], dtype=np.int64)
            self.confirmed |= hits >= c.confirm_m
            dead_tentative = ~self.confirmed & (self.age >= c.confirm_n)
            dead = dead_tentative | (self.confirmed & (self.misses >= c.delete_misses))
        # time-based deletion: coasted longer than max_coast seconds
        coasted = (t - self.last_hit) > c.max_coast
        gone = dead | blown | coasted
        self._retire(gone, t)
        self._keep(~gone)

    # ------------------------------------------------------------ id continuation
    def _retire(self, gone, t) -> None:
        """Remember the confirmed, unlabelled tracks ``gone`` (a mask) for id
        continuation, and forget those deleted more than ``id_continuation`` s before ``t``."""
        window = self.config.id_continuation
        if window <= 0:
            return
        fresh = (t - self.retired_time) <= window
        d2 = 2 * self.config.dim
        new = np.flatnonzero(gone & self.confirmed & (self.labels == ""))
        self.retired_ids = np.concatenate([self.retired_ids[fresh], self.ids[new]])
        self.retired_x = np.concatenate([self.retired_x[fresh], self.x[new, :d2]])
        self.retired_P = np.concatenate([self.retired_P[fresh], self.P[new, :d2, :d2]])
        self.retired_time = np.concatenate([self.retired_time[fresh], np.full(len(new), t)])

    def _continue_ids(self, before: set, t) -> int:
        """Give each track confirmed at this scan (its id not in ``before``) the id of a
        deleted track whose coasted prediction it matches, or of a confirmed track losing
        its target whose state it matches — that track then ends — when the match is
        unambiguous (module docstring); returns how many took an id."""
        c = self.config
        if c.id_continuation <= 0:
            return 0
        was = np.isin(self.ids, np.fromiter(before, np.int64, len(before)))
        unlabelled = self.labels == ""
        new = np.flatnonzero(self.confirmed & unlabelled & ~was)
        if not len(new):
            return 0
        retired = np.flatnonzero((t - self.retired_time) <= c.id_continuation)
        # losing its target: missed this scan, or (JIPDA) its existence fell below the
        # confirmation threshold — its returns are far in its gate, the new track's near
        losing = self.misses >= 1
        if c.existence:
            losing |= self.existence < c.r_confirm
        coasting = np.flatnonzero(self.confirmed & unlabelled & was & losing)
        held = np.flatnonzero(self.confirmed & was & ~losing)
        n_ret, n_coast = len(retired), len(coasting)
        if not n_ret + n_coast:
            return 0
        d2 = 2 * c.dim
        # the deleted tracks' states coasted to t (position and velocity: a CV
        # prediction, also for the CA and IMM trackers whose combined state starts so),
        # then the losing tracks' and the held tracks' states (at t already)
        cv = ConstantVelocity(dim=c.dim, q=c.process_noise)
        live = np.concatenate([coasting, held])
        xo = np.concatenate([self.retired_x[retired], self.x[live, :d2]])
        Po = np.concatenate([self.retired_P[retired], self.P[live, :d2, :d2]])
        for k, i in enumerate(retired):
            dt = t - self.retired_time[i]
            if dt > 0:  # 0: deleted at this scan, its state is already at t
                F = cv.transition(dt)
                xo[k], Po[k] = F @ xo[k], F @ Po[k] @ F.T + cv.noise(dt)
        e = self.x[new, None, :d2] - xo[None]  # (new, old, d2)
        S = self.P[new, None, :d2, :d2] + Po[None]
        dist = np.einsum("abi,abi->ab", e, np.linalg.solve(S, e[..., None])[..., 0])
        inside = dist <= gate_threshold(CONTINUATION_GATE, d2)
        # unambiguous pairs only: the new track in the gate of one track (deleted or
        # losing) and of no held one, and that track in the gate of no other new track
        # (two targets close together: no id is handed on a guess)
        cand = inside[:, : n_ret + n_coast]
        one = (inside.sum(axis=1) == 1) & cand.any(axis=1)
        forget = np.zeros(len(self.retired_ids), bool)
        ended = np.zeros(len(self.ids), bool)
        taken = 0
        for a in np.flatnonzero(one):
            b = int(np.flatnonzero(cand[a])[0])
            if cand[:, b].sum() != 1:
                continue
            taken += 1
            if b < n_ret:
                self.ids[new[a]] = self.retired_ids[retired[b]]
                forget[retired[b]] = True
            else:  # the losing track lost its target to the new one: it ends here
                self.ids[new[a]] = self.ids[coasting[b - n_ret]]
                ended[coasting[b - n_ret]] = True
        if forget.any():
            for name in ("retired_ids", "retired_x", "retired_P", "retired_time"):
                setattr(self, name, getattr(self, name)[~forget])
        if ended.any():
            self._keep(~ended)
        return taken

    #: each track's last update (asynchronous reporting: a track is predicted from here over
    #: the whole interval since, so the IMM mixes once per interval of its own)
    _UPDATE_ARRAYS = (
        "updated_time",
        "updated_x",
        "updated_P",
        "updated_mode_x",
        "updated_mode_P",
        "updated_mode_log_prob",
    )

    #: per-track quantities of the current scan (``_scan_detection``)
    _SCAN_ARRAYS = ("_scan_pd", "_scan_pdg", "_scan_missed", "_scan_pd_ratio", "_scan_survival")

    _TRACK_ARRAYS = (
        "x",
        "P",
        "ids",
        "confirmed",
        "hit_history",
        "age",
        "misses",
        "existence",
        "last_hit",
        "born",
        "report_count",
        "labels",
        "mode_x",
        "mode_P",
        "mode_log_prob",
        *_UPDATE_ARRAYS,
        "comp_x",
        "comp_P",
        "comp_log_w",
        "comp_n",
    )

    def _keep(self, keep):
        for name in self._TRACK_ARRAYS:
            setattr(self, name, getattr(self, name)[keep])

    def _initiate(self, z_new, t, r0=None, *, velocities=None, labels=None):
        """Start tentative tracks on the returns ``z_new`` (two- or one-point).

        ``r0``: the existence of each new track (default ``r_init``);
        ``velocities`` (K, dim, NaN where unknown): reported velocities that
        seed one-point tracks; ``labels`` (K,): the reports' labels — such
        tracks start confirmed (the report names a real target).

        Two-point pairs each return with a seed of the latest earlier scan time
        (with several sensors, seeds of the same time are never paired); the
        seeds of that time stay available until the time advances again.
        """
        c = self.config
        d = c.dim
        if labels is not None:
            x0, P0 = self._initial_states(z_new, velocities)
            self._append(x0, P0, confirmed=True, existence=r0, time=t, labels=labels)
            return
        earlier = self.seed_times < t
        latest = self.seed_times[earlier].max() if earlier.any() else None
        if c.initiation == "one-point":
            x0, P0 = self._initial_states(z_new, velocities)
            self._set_seeds(np.zeros((0, d)), np.zeros((0, d, d)), np.zeros(0))
            if len(x0):
                self._append(
                    x0, P0, confirmed=False, existence=c.r_init if r0 is None else r0, time=t
                )
            return
        pos, cov = self._sensor.position_and_covariance(z_new)
        if latest is not None and len(pos):
            cand = np.flatnonzero(self.seed_times == latest)
            dt = t - latest
            rows, loc = pair_returns(
                pos, cov, self.seeds[cand], self.seed_covs[cand], c.max_speed * dt
            )
            cols = cand[loc]
            unused = np.ones(len(pos), bool)
            unused[rows] = False
            vel = (pos[rows] - self.seeds[cols]) / dt
            cov_vv = (cov[rows] + self.seed_covs[cols]) / dt**2
            cov_pv = cov[rows] / dt
            # keep the seeds of times ≥ latest not used, plus this scan's leftovers
            keep = self.seed_times >= latest
            keep[cols] = False
            self._set_seeds(
                np.concatenate([self.seeds[keep], pos[unused]]),
                np.concatenate([self.seed_covs[keep], cov[unused]]),
                np.concatenate([self.seed_times[keep], np.full(int(unused.sum()), t)]),
            )
            if len(rows):
                x0, P0 = self._states(pos[rows], cov[rows], vel, cov_vv, cov_pv)
                self._append(x0, P0, confirmed=False, existence=c.r_init, time=t)
        else:
            keep = self.seed_times >= (latest if latest is not None else t)
            self._set_seeds(
                np.concatenate([self.seeds[keep], pos]),
                np.concatenate([self.seed_covs[keep], cov]),
                np.concatenate([self.seed_times[keep], np.full(len(pos), t)]),
            )

    def _initial_states(self, z_new, velocities=None):
        """One-point initial states ``(x0, P0)`` on the returns ``z_new``.

        Velocity zero with per-axis σ = max_speed/2, or the reported velocity
        with σ = velocity_std where ``velocities`` has one (finite rows).
        """
        c = self.config
        d = c.dim
        pos, cov = self._sensor.position_and_covariance(z_new)
        vel = np.zeros_like(pos)
        cov_vv = np.broadcast_to(np.eye(d) * (c.max_speed / 2.0) ** 2, cov.shape).copy()
        x0, P0 = self._states(pos, cov, vel, cov_vv, np.zeros_like(cov))
        return seed_velocities(x0, P0, velocities, d, c.velocity_std)

    def _states(self, pos, cov, vel, cov_vv, cov_pv):
        """Full states and covariances from position and velocity blocks."""
        c = self.config
        n, d, k = self.state_dim, c.dim, len(pos)
        x0 = np.zeros((k, n))
        x0[:, :d] = pos
        x0[:, d : 2 * d] = vel
        P0 = np.zeros((k, n, n))
        P0[:, :d, :d] = cov
        P0[:, d : 2 * d, d : 2 * d] = cov_vv
        P0[:, :d, d : 2 * d] = cov_pv
        P0[:, d : 2 * d, :d] = cov_pv.transpose(0, 2, 1)
        if n > 2 * d:  # constant acceleration: acceleration unknown
            a = np.arange(2 * d, 3 * d)
            P0[:, a, a] = (c.max_acceleration / 2.0) ** 2
        return x0, P0

    def _set_seeds(self, seeds, covs, times) -> None:
        self.seeds, self.seed_covs, self.seed_times = seeds, covs, np.asarray(times, float)

    def _append(self, x0, P0, *, confirmed, existence, time, labels=None):
        k = len(x0)
        self.last_hit = np.concatenate([self.last_hit, np.full(k, float(time))])
        self.born = np.concatenate([self.born, np.full(k, float(time))])
        self.report_count = np.concatenate([self.report_count, np.zeros(k)])
        new_labels = np.full(k, "") if labels is None else np.asarray(labels, dtype=str)
        self.labels = np.concatenate([self.labels, new_labels])
        ids = np.arange(self.next_id, self.next_id + k)
        self.next_id += k
        if labels is not None:
            ids, self.label_names, self.label_ids = label_identities(
                self.label_names, self.label_ids, new_labels, ids
            )
        self.x = np.concatenate([self.x, x0])
        self.P = np.concatenate([self.P, P0])
        mx, mP, ml = self._mode_states(x0, P0)
        self.mode_x = np.concatenate([self.mode_x, mx])
        self.mode_P = np.concatenate([self.mode_P, mP])
        self.mode_log_prob = np.concatenate([self.mode_log_prob, ml])
        self.updated_time = np.concatenate([self.updated_time, np.full(k, float(time))])
        self.updated_x = np.concatenate([self.updated_x, x0])
        self.updated_P = np.concatenate([self.updated_P, P0])
        self.updated_mode_x = np.concatenate([self.updated_mode_x, mx])
        self.updated_mode_P = np.concatenate([self.updated_mode_P, mP])
        self.updated_mode_log_prob = np.concatenate([self.updated_mode_log_prob, ml])
        self.ids = np.concatenate([self.ids, ids])
        self.confirmed = np.concatenate([self.confirmed, np.full(k, confirmed)])
        self.hit_history = np.concatenate([self.hit_history, np.ones(k, np.int64)])
        self.age = np.concatenate([self.age, np.zeros(k, np.int64)])
        self.misses = np.concatenate([self.misses, np.zeros(k, np.int64)])
        self.existence = np.concatenate(
            [self.existence, np.broadcast_to(np.asarray(existence, float), (k,))]
        )
        # a tentative track-splitting track starts as one component: its start
        K = self.comp_x.shape[1]
        cx, cP = np.zeros((k, K, *x0.shape[1:])), np.zeros((k, K, *P0.shape[1:]))
        split = K > 0 and not confirmed
        if split:
            cx[:, 0], cP[:, 0] = x0, P0
        self.comp_x = np.concatenate([self.comp_x, cx])
        self.comp_P = np.concatenate([self.comp_P, cP])
        self.comp_log_w = np.concatenate([self.comp_log_w, np.zeros((k, K))])
        self.comp_n = np.concatenate([self.comp_n, np.full(k, int(split), np.int64)])
        return ids

    def start_tracks(self, x0, P0, *, confirmed: bool = True, existence: float = 0.99, time=None):
        """Add tracks with known states (e.g. from a previous stage or ground truth).

        ``x0`` (K, n) states in the motion model's layout, ``P0`` (K, n, n) or
        (n, n) covariances. ``time``: the time the states refer to. A tracker
        that has seen no scan yet takes it as its clock, so the next ``step``
        predicts the new tracks from it (without it, the first scan is taken to
        be at the states' time and nothing is predicted); a tracker that has a
        clock requires ``time`` to equal it (predict states from other times
        yourself). Returns the new track ids.

        Raises ValueError (TypeError for a non-bool ``confirmed``) naming the
        argument for anything a saved state could not hold — complex, boolean,
        string or non-finite ``x0``/``P0``, a ``P0`` that is not symmetric
        positive definite, ``existence`` outside (0, 1] — so every state this
        accepts can be saved and loaded; nothing is changed then.
        """
        t0 = None
        if time is not None:
            origin = self.time_origin
            try:
                t0 = self._scan_time(time)
            finally:
                if self.time is None:  # nothing is changed until the tracks are valid
                    self.time_origin = origin
            if self.time is not None and t0 != self.time:
                raise ValueError(
                    f"time = {t0} differs from the tracker's clock ({self.time}); start tracks "
                    "at the current time or predict their states to it first"
                )
        # Everything accepted here must survive save() and load(): the same checks.
        n = self.state_dim
        x0 = np.atleast_2d(_as_real_array(x0, "x0"))
        if x0.ndim != 2 or x0.shape[1] != n:
            raise ValueError(f"x0 must have shape (K, {n}), got {x0.shape}")
        if not np.all(np.isfinite(x0)):
            raise ValueError("x0 must be finite")
        P0 = _as_real_array(P0, "P0")
        if P0.shape not in ((n, n), (len(x0), n, n)):
            raise ValueError(
                f"P0 must have shape ({n}, {n}) or ({len(x0)}, {n}, {n}), got {P0.shape}"
            )
        P0 = np.broadcast_to(P0, (len(x0), n, n))
        problem = covariance_problem(P0)
        if problem:
            raise ValueError(f"P0 {problem}; every P0 must be symmetric positive definite")
        P0 = 0.5 * (P0 + P0.transpose(0, 2, 1))  # exactly symmetric, as the filters keep it
        # existence 0: no target at all, nothing a track could stand for
        existence = as_float(existence, "existence", minimum=0.0, maximum=1.0, open_min=True)
        if not isinstance(confirmed, bool | np.bool_):
            raise TypeError(f"confirmed must be True or False, got {confirmed!r}")
        clock = t0 if t0 is not None else (self.time if self.time is not None else 0.0)
        ids = self._append(x0, P0, confirmed=bool(confirmed), existence=existence, time=clock)
        if t0 is not None and self.time is None:
            if is_datetime(time):
                self._scan_time(time)  # fixes time_origin, validated above
            self.time = t0
        return ids

    # ------------------------------------------------------------ save/load
    _ARRAYS = (
        "x",
        "P",
        "ids",
        "confirmed",
        "history",
        "age",
        "misses",
        "existence",
        "seeds",
        "seed_covs",
        "seed_times",
        "last_hit",
        "born",
        "report_count",
        "labels",
        "label_names",
        "label_ids",
        "mode_x",
        "mode_P",
        "mode_log_prob",
        "retired_ids",
        "retired_x",
        "retired_P",
        "retired_time",
        *_UPDATE_ARRAYS,
        "comp_x",
        "comp_P",
        "comp_log_w",
        "comp_n",
    )
    # state key -> attribute (``history()`` is the track-history method)
    _ATTRS = {"history": "hit_history"}

    def _validate_state(self, path, arrays: dict, scalars: dict) -> None:
        validate_tracker_arrays(path, arrays, scalars, self.state_dim, self.config.dim)
        validate_mode_arrays(path, arrays, self._imm)
        validate_update_arrays(path, arrays, scalars, self.state_dim, self._imm)
        if self.config.existence and (arrays["existence"] <= 0.0).any():
            # a JIPDA track of existence 0 is deleted before any state is saved
            raise StateFileError(f"{path}: field 'existence' holds a track of existence 0")
        validate_retired_arrays(path, arrays, scalars, 2 * self.config.dim)
        validate_component_arrays(path, arrays, self.state_dim, self.comp_x.shape[1])


def _rows(values, index):
    """``values[index]``, or None when there are no values."""
    return None if values is None else values[index]
