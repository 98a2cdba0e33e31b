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
"""

from __future__ import annotations

import logging

import numpy as np

from jointtrack.assignment._checks import _as_real_array, as_float
from jointtrack.association.clustering import clusters
from jointtrack.association.clutter import cluster_heuristic_densities
from jointtrack.association.gating import likelihood_ratio_pairs
from jointtrack.filters import pda_pairs_update, predict
from jointtrack.trackers.base import ClusterRecord, ScanResult, ScanTracker
from jointtrack.trackers.config import TrackerConfig
from jointtrack.trackers.existence import existence_update, merge_duplicates
from jointtrack.trackers.history import TrackHistory, is_datetime
from jointtrack.trackers.initiation import pair_returns
from jointtrack.trackers.state_io import covariance_problem, validate_tracker_arrays

__all__ = ["ClusterRecord", "JPDATracker", "ScanResult", "TrackHistory", "TrackerConfig"]

log = logging.getLogger("jointtrack.tracker")


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
        self.x = np.zeros((0, n))
        self.P = np.zeros((0, n, n))
        self.ids = np.zeros(0, np.int64)
        self.confirmed = np.zeros(0, bool)
        self.hit_history = np.zeros(0, np.int64)  # bit k: hit k scans ago
        self.age = np.zeros(0, np.int64)
        self.misses = np.zeros(0, np.int64)
        self.existence = np.zeros(0)
        # unassociated returns of the previous scan (positions, covariances): two-point seeds
        self.seeds = np.zeros((0, c.dim))
        self.seed_covs = np.zeros((0, c.dim, c.dim))
        self.seed_times = np.zeros(0)  # scan time of each seed

    # ------------------------------------------------------------------ scan
    def _step(self, t, z, same_time_ok=False) -> ScanResult:
        c = self.config
        t, z, dt, n_coincident = self._check_scan(t, z, same_time_ok)

        if dt is not None and dt > 0 and len(self.ids):
            self.x, self.P = predict(
                self.x, self.P, self._motion.transition(dt), self._motion.noise(dt)
            )
            if c.existence:
                self.existence = self.existence * c.p_survive
        # Confirmed tracks first; tentative ones only see the returns no confirmed
        # track gated, so clutter-born tentative tracks cannot glue true targets'
        # clusters together (cf. a separate initiator, Blackman & Popoli §6).
        N, M = len(self.ids), len(z)
        beta0 = np.ones(N)
        pair_rows, pair_cols, pair_w = [], [], []
        hit = np.zeros(N, bool)
        free = np.arange(M)
        sizes, seconds, methods, fallbacks, kinds = [], [], [], [], []
        # Confirmed tracks first, then tentative ones. With JIPDA the tentative
        # tracks see every return, each weighted by the probability that no
        # confirmed track took it (jointtrack.trackers.existence, point 1); with
        # M-of-N logic (no existence to weigh a clutter-born track's claim) they
        # see only the returns no confirmed track gated, so they cannot glue true
        # targets' clusters together (cf. a separate initiator, Blackman & Popoli §6).
        available = np.ones(M)  # JIPDA: P(return not taken by an earlier pass)
        ungated = np.ones(M, bool)  # JIPDA: returns no pass gated (two-point seeds)
        for group, loud in (
            (np.flatnonzero(self.confirmed), True),
            (np.flatnonzero(~self.confirmed), False),
        ):
            if len(group) == 0:
                continue
            if c.existence:
                b0, (pr, pc, pw), h, free_local, info, used = self._associate(
                    group, z, loud, available=available
                )
                available = np.clip(available - np.bincount(pc, used, minlength=M), 0.0, 1.0)
                in_no_gate = np.zeros(M, bool)
                in_no_gate[free_local] = True
                ungated &= in_no_gate
            else:
                b0, (pr, pc, pw), h, free_local, info, _ = self._associate(group, z[free], loud)
                pc = free[pc]
                free = free[free_local]
            beta0[group] = b0
            pair_rows.append(group[pr])
            pair_cols.append(pc)
            pair_w.append(pw)
            hit[group] = h
            for part, extra in zip((sizes, seconds, methods, fallbacks), info, strict=True):
                part.extend(extra)
            kinds.extend([loud] * len(info[0]))
        if c.existence:
            free = np.flatnonzero(ungated)
        unassoc = free
        if N:
            rows = np.concatenate(pair_rows) if pair_rows else np.zeros(0, np.int64)
            cols = np.concatenate(pair_cols) if pair_cols else np.zeros(0, np.int64)
            w = np.concatenate(pair_w) if pair_w else np.zeros(0)
            self.x, self.P = pda_pairs_update(
                self.x, self.P, z, beta0, rows, cols, w, **self._measurement_model()
            )
            self._track_logic(hit)
            keep, self.existence = merge_duplicates(
                self.x, self.P, self.ids, self.existence, self.confirmed, c.dim, c.merge_threshold
            )
            self._keep(keep)
        if c.existence and c.initiation == "one-point":
            # adaptive birth: every return, weighted by how unexplained it is
            # (jointtrack.trackers.existence, point 2)
            birth_r = c.r_init * available
            born = birth_r > c.r_delete
            self._initiate(z[born], t, birth_r[born])
        else:
            self._initiate(z[unassoc], t)
        self.time = t
        self.n_scans += 1
        keep = self.confirmed & (self.existence >= c.r_report) if c.existence else self.confirmed
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
        )

    def _associate(self, tracks, z, loud, available=None):
        """Association probabilities of the given tracks against ``z``, cluster by cluster.

        Gating on a KD-tree (:func:`~jointtrack.association.gate_pairs`), clusters
        from the gated pairs, Bojilov's (8) or the known clutter density, the
        likelihood ratios of the gated pairs, then per cluster: single tracks by
        PDA (exact for one track, all at once), the others by the configured
        method. Returns ``(beta0, (rows, cols, weights), hit, unassociated,
        (sizes, seconds, methods, fallbacks), used)`` with rows/cols local to
        ``tracks``/``z``; with JIPDA it updates the tracks' existence, the β are
        conditioned on existence and ``used`` holds the unconditional pair
        probabilities (what the returns' availability and birth existence need),
        else None. ``available`` (M,): the probability that each return was not
        taken by an earlier pass; it scales the likelihood ratios.
        """
        c = self.config
        n, M = len(tracks), len(z)
        g = self._gate(self.x[tracks], self.P[tracks], z)
        groups = clusters(g)
        if self._clutter is not None:
            lam = self._clutter
        else:
            # Bojilov (8): λ = Σ_i m_i / Σ_i V_i over each cluster's tracks
            dens = cluster_heuristic_densities(g.n_gated, g.gate_volume, groups.track_cluster)
            lam = np.ones(M)
            gated = groups.measurement_cluster >= 0
            lam[gated] = dens[groups.measurement_cluster[gated]]
        r = self.existence[tracks] if c.existence else np.ones(n)
        L_pairs, _ = likelihood_ratio_pairs(g, self._p_d * r, lam)
        if available is not None:  # a return taken by an earlier pass is less likely ours
            L_pairs = L_pairs * available[g.cols]
        pdg = c.detection_in_gate(self._p_d)
        miss = 1.0 - r * pdg
        rows, cols = g.rows, g.cols
        beta0, weights, groups, info = self._pair_marginals(
            self.ids[tracks], g, L_pairs, miss, loud, groups
        )
        used = None
        if c.existence:
            used = weights.copy()  # unconditional: how much each pair explains its return
            self.existence[tracks], beta0, weights = existence_update(r, beta0, weights, rows, pdg)
        return (
            beta0,
            (rows, cols, weights),
            g.n_gated > 0,
            groups.unassociated,
            info,
            used,
        )

    def _track_logic(self, hit):
        c = self.config
        self.age += 1
        self.hit_history = ((self.hit_history << 1) | hit.astype(np.int64)) & (
            (1 << c.confirm_n) - 1
        )
        self.misses = np.where(hit, 0, self.misses + 1)
        pos_var = np.einsum("nii->n", self.P[:, : c.dim, : c.dim]) / c.dim
        blown = np.sqrt(pos_var) > c.max_position_std
        if c.existence:
            self.confirmed |= self.existence >= c.r_confirm
            dead = self.existence < c.r_delete
        else:
            hits = np.array([bin(h).count("1") for h in self.hit_history], dtype=np.int64)
            self.confirmed |= hits >= c.confirm_m
            dead_tentative = ~self.confirmed & (self.age >= c.confirm_n)
            dead = dead_tentative | (self.confirmed & (self.misses >= c.delete_misses))
        self._keep(~(dead | blown))

    def _keep(self, keep):
        for name in ("x", "P", "ids", "confirmed", "hit_history", "age", "misses", "existence"):
            setattr(self, name, getattr(self, name)[keep])

    def _initiate(self, z_new, t, r0=None):
        """Start tentative tracks on the returns ``z_new`` (two- or one-point).

        ``r0``: the existence of each new track (default ``r_init``).

        Two-point pairs each return with a seed of the latest earlier scan time
        (with several sensors, seeds of the same time are never paired); the
        seeds of that time stay available until the time advances again.
        """
        c = self.config
        n = self._motion.state_dim
        d = c.dim
        pos, cov = self._sensor.position_and_covariance(z_new)
        earlier = self.seed_times < t
        latest = self.seed_times[earlier].max() if earlier.any() else None
        if c.initiation == "one-point":
            vel = np.zeros_like(pos)
            cov_vv = np.broadcast_to(np.eye(d) * (c.max_speed / 2.0) ** 2, cov.shape).copy()
            cov_pv = np.zeros_like(cov)
            self._set_seeds(np.zeros((0, d)), np.zeros((0, d, d)), np.zeros(0))
        elif latest is not None and len(pos):
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
            pos, cov = pos[rows], cov[rows]
        else:
            keep = self.seed_times >= (latest if latest is not None else t)
            self._set_seeds(
                np.concatenate([self.seeds[keep], pos]),
                np.concatenate([self.seed_covs[keep], cov]),
                np.concatenate([self.seed_times[keep], np.full(len(pos), t)]),
            )
            return
        k = len(pos)
        if k == 0:
            return
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
        self._append(x0, P0, confirmed=False, existence=c.r_init if r0 is None else r0)

    def _set_seeds(self, seeds, covs, times) -> None:
        self.seeds, self.seed_covs, self.seed_times = seeds, covs, np.asarray(times, float)

    def _append(self, x0, P0, *, confirmed, existence):
        k = len(x0)
        ids = np.arange(self.next_id, self.next_id + k)
        self.next_id += k
        self.x = np.concatenate([self.x, x0])
        self.P = np.concatenate([self.P, P0])
        self.ids = np.concatenate([self.ids, ids])
        self.confirmed = np.concatenate([self.confirmed, np.full(k, confirmed)])
        self.hit_history = np.concatenate([self.hit_history, np.ones(k, np.int64)])
        self.age = np.concatenate([self.age, np.zeros(k, np.int64)])
        self.misses = np.concatenate([self.misses, np.zeros(k, np.int64)])
        self.existence = np.concatenate(
            [self.existence, np.broadcast_to(np.asarray(existence, float), (k,))]
        )
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
        positive definite, ``existence`` outside [0, 1] — so every state this
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
        n = self._motion.state_dim
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
        existence = as_float(existence, "existence", minimum=0.0, maximum=1.0)
        if not isinstance(confirmed, bool | np.bool_):
            raise TypeError(f"confirmed must be True or False, got {confirmed!r}")
        ids = self._append(x0, P0, confirmed=bool(confirmed), existence=existence)
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
    )
    # state key -> attribute (``history()`` is the track-history method)
    _ATTRS = {"history": "hit_history"}

    def _validate_state(self, path, arrays: dict, scalars: dict) -> None:
        validate_tracker_arrays(path, arrays, scalars, self.state_dim, self.config.dim)
