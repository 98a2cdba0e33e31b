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
import numbers
import time as _time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.sparse import csr_array

from jointtrack.assignment._checks import _as_real_array, as_float
from jointtrack.association.budget import (
    DENSE_MAX_ENTRIES,
    budgeted_marginals,
    fallback_pair_marginals,
)
from jointtrack.association.clustering import cluster_pair_marginals, clusters
from jointtrack.association.clutter import cluster_heuristic_densities
from jointtrack.association.gating import gate_pairs, likelihood_ratio_pairs
from jointtrack.errors import CoincidentReturnsWarning
from jointtrack.filters import (
    ekf_predict_measurement,
    pda_pairs_update,
    predict,
    predict_measurement,
)
from jointtrack.models import (
    ConstantAcceleration,
    ConstantVelocity,
    LinearPosition,
    RangeBearing,
)
from jointtrack.trackers.config import TrackerConfig
from jointtrack.trackers.existence import existence_update, merge_duplicates
from jointtrack.trackers.history import (
    TrackHistory,
    is_datetime,
    iso_from_ns,
    ns_from_iso,
    scan_time_ns,
)
from jointtrack.trackers.initiation import pair_returns
from jointtrack.trackers.sensors import Sensor
from jointtrack.trackers.state_io import (
    StateFileError,
    covariance_problem,
    read_state,
    validate_tracker_arrays,
    write_state,
)

__all__ = ["ClusterRecord", "JPDATracker", "ScanResult", "TrackHistory", "TrackerConfig"]

log = logging.getLogger("jointtrack.tracker")


@dataclass(frozen=True)
class ScanResult:
    """What one call of :meth:`JPDATracker.step` did.

    The confirmed tracks after the update: ``ids`` (K,), ``x`` (K, n),
    ``P`` (K, n, n), ``existence`` (K,) (1.0 without JIPDA). ``time`` is in
    seconds — for datetime scans, seconds after the tracker's ``time_origin``.
    ``cluster_sizes`` lists (tracks, measurements) of every multi-track
    cluster, ``cluster_seconds`` the association time of each,
    ``cluster_methods`` the method used, ``cluster_confirmed`` whether it
    was a cluster of confirmed (True) or tentative (False) tracks and
    ``cluster_fallbacks`` why the approximation replaced the configured method
    (``""`` when it did not; ``"exact_max_tracks"`` for a cluster above the
    budget; ``"refused: …"`` when the exact engine declined it;
    ``"dense_budget: …"`` for a cluster too large for an N × M matrix).
    ``n_coincident``: returns dropped because they repeated another return of
    the scan exactly (see :meth:`JPDATracker.step`).
    """

    time: float
    ids: np.ndarray
    x: np.ndarray
    P: np.ndarray
    existence: np.ndarray
    n_tentative: int
    n_measurements: int
    n_unassociated: int
    cluster_sizes: list = field(default_factory=list)
    cluster_seconds: list = field(default_factory=list)
    cluster_methods: list = field(default_factory=list)
    cluster_confirmed: list = field(default_factory=list)
    cluster_fallbacks: list = field(default_factory=list)
    n_coincident: int = 0

    @property
    def n_fallbacks(self) -> int:
        """Clusters solved by the approximation instead of the configured method."""
        return sum(1 for f in self.cluster_fallbacks if f)


def _merge_coincident(z: np.ndarray, t: float) -> tuple[np.ndarray, int]:
    """``z`` with each set of identical rows kept once (first occurrence, order kept)."""
    if len(z) < 2:
        return z, 0
    x = np.sort(z[:, 0])
    if not (x[1:] == x[:-1]).any():  # the usual scan: no tie in the first coordinate
        return z, 0
    _, first = np.unique(z, axis=0, return_index=True)
    n_dropped = len(z) - len(first)
    if n_dropped == 0:
        return z, 0
    warnings.warn(
        f"scan at t={t}: {n_dropped} of {len(z)} returns repeat another return of the scan "
        f"exactly (identical measurement vectors; a stuck or replayed detector?); each set of "
        f"identical returns is treated as one return ({len(first)} kept)",
        CoincidentReturnsWarning,
        stacklevel=4,
    )
    return z[np.sort(first)], n_dropped


@dataclass(frozen=True)
class ClusterRecord:
    """One multi-track cluster as the association engine saw it (for ``on_cluster``).

    ``L``, ``miss`` and ``beta`` are in the cluster convention of
    :func:`jointtrack.association.marginals` (β before the JIPDA existence
    conditioning); ``confirmed`` tells the confirmed-track pass from the
    tentative one. For a cluster too large for dense matrices (method
    ``"lbp-sparse"`` or ``"pda"`` with reason ``"dense_budget: …"``), ``L`` and
    ``beta`` are :class:`scipy.sparse.csr_array` of the gated pairs.
    """

    track_ids: np.ndarray
    L: np.ndarray
    miss: np.ndarray
    beta: np.ndarray
    seconds: float
    method: str
    confirmed: bool


class JPDATracker:
    """Multi-target JPDA tracker (see the module docstring).

    >>> import numpy as np
    >>> trk = JPDATracker(TrackerConfig(clutter_density=1e-4))
    >>> detections = [(float(t), np.array([[t, 0.0], [50.0, 3.0 * t]])) for t in range(5)]
    >>> for t, z in detections:            # z: (M, dim) positions at time t
    ...     result = trk.step(t, z)        # confirmed tracks in result.ids / result.x
    >>> table = trk.history()              # every confirmed estimate: a TrackHistory
    """

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

        ``motion``: any object with ``state_dim``, ``transition(dt)`` and
        ``noise(dt)`` (default: :class:`~jointtrack.models.ConstantVelocity` or
        :class:`~jointtrack.models.ConstantAcceleration` from ``config.motion``).
        ``sensor``: a linear model with an ``H`` matrix and ``R`` (default
        :class:`~jointtrack.models.LinearPosition`), or a nonlinear one with
        ``h``, ``jacobian``, ``residual`` and ``R`` (EKF; default
        :class:`~jointtrack.models.RangeBearing` for ``config.sensor =
        "range-bearing"``); for initiation it must also provide
        ``position_and_covariance(z)``. ``sensors`` (optional): ``{id: Sensor}``
        (:class:`~jointtrack.trackers.sensors.Sensor`, or a bare model) for
        multi-sensor runs, selected per scan by ``step(t, z, sensor=id)``.
        ``on_cluster(record)`` (optional) is
        called with a :class:`ClusterRecord` for every multi-track cluster; it
        is not part of the saved state. ``keep_history``: record every confirmed
        estimate for :meth:`history` (turn off for memory-bound runs; it can be
        switched at any time through the ``keep_history`` attribute).
        """
        self.config = config or TrackerConfig()
        self.on_cluster = on_cluster
        self.keep_history = bool(keep_history)
        # (time, ids, x, P, existence) per successful scan; outside the saved and
        # restored state: appended only after a step succeeded
        self._history_rows: list[tuple] = []
        c = self.config
        if motion is None:
            model = ConstantVelocity if c.motion == "cv" else ConstantAcceleration
            motion = model(dim=c.dim, q=c.process_noise)
        for attr in ("state_dim", "transition", "noise"):
            if not hasattr(motion, attr):
                raise ValueError(f"motion model {motion!r} has no {attr!r}")
        self._motion = motion
        n = int(motion.state_dim)
        if n < 2 * c.dim:
            raise ValueError(
                f"motion model state_dim = {n} cannot hold position and velocity in {c.dim}-D"
            )
        if sensor is None:
            if c.sensor == "position":
                sensor = LinearPosition(c.dim, c.measurement_noise, state_dim=n)
            else:
                sensor = RangeBearing(
                    [c.range_noise, c.bearing_noise],
                    sensor_position=c.sensor_position,
                    state_dim=n,
                )
        # id None: the configuration's sensor; further ids from ``sensors``
        self._sensors = {None: Sensor(sensor)}
        for sid, spec in (sensors or {}).items():
            if not isinstance(spec, Sensor):
                spec = Sensor(spec)
            self._sensors[sid] = spec
        self._activate(None)
        self.rng = np.random.default_rng(c.seed)
        self.time: float | None = None
        # ISO-8601 UTC instant of t = 0 when the scans are datetimes (set by the first one)
        self.time_origin: str | None = None
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
        self.next_id = 1
        self.n_scans = 0

    def add_sensor(self, sensor_id, sensor) -> None:
        """Register (or replace) a sensor for ``step(t, z, sensor=sensor_id)``.

        ``sensor``: a :class:`~jointtrack.trackers.sensors.Sensor` or a bare
        measurement model. Sensors are configuration, not state: after
        :meth:`load`, register them again.
        """
        if sensor_id is None:
            raise ValueError("sensor_id None is the configuration's own sensor")
        self._sensors[sensor_id] = sensor if isinstance(sensor, Sensor) else Sensor(sensor)

    @property
    def state_dim(self) -> int:
        """Length of a track state (from the motion model)."""
        return int(self._motion.state_dim)

    @property
    def default_sensor(self) -> Sensor:
        """The sensor built from the configuration (used when ``step`` names none)."""
        return self._sensors[None]

    def _activate(self, sensor_id) -> None:
        """Make ``sensor_id``'s model, P_D and clutter density the ones this scan uses."""
        try:
            spec = self._sensors[sensor_id]
        except (KeyError, TypeError):
            known = ", ".join(str(k) for k in self._sensors if k is not None) or "none"
            raise ValueError(
                f"unknown sensor {sensor_id!r}; this tracker's sensors: {known}"
            ) from None
        c = self.config
        self._sensor = spec.model
        self._linear, self._mdim = spec.linear, spec.measurement_dim
        self._p_d = c.p_d if spec.p_d is None else float(spec.p_d)
        self._clutter = c.clutter_density if spec.clutter_density is None else spec.clutter_density

    # ------------------------------------------------------------------ scan
    def step(self, t: float, z, sensor=None) -> ScanResult:
        """Process the measurements ``z`` (M, dim) taken at time ``t``.

        ``sensor``: the id of the sensor that took the scan (see ``sensors`` in
        the constructor); scans of different sensors may share a time, and are
        then processed one after another without prediction between them.

        ``t``: a number (seconds), a ``datetime.datetime`` (naive = UTC, or
        timezone-aware) or a ``numpy.datetime64``. Datetimes are converted to
        seconds after ``time_origin``, the instant of the run's first datetime
        scan (an ISO-8601 string, saved with the state); one run takes either
        numbers or datetimes, never both. ``ScanResult.time`` is in seconds.

        Exactly coincident returns — identical measurement vectors within one
        scan (a stuck or replayed detector) — are treated as one return: the
        first of each set is kept, a
        :class:`~jointtrack.errors.CoincidentReturnsWarning` names how many were
        dropped, and ``ScanResult.n_coincident`` counts them. (Left in, 500
        copies of one return would start hundreds of tracks.)

        Clusters of any size are associated: past the exact budget by the
        configured approximation, past that (or when a cluster's tracks ×
        measurements exceed
        :data:`~jointtrack.association.budget.DENSE_MAX_ENTRIES`) by sparse LBP,
        then per-track PDA on the gated pairs
        (:func:`~jointtrack.association.budget.fallback_pair_marginals`); each
        cluster's method is in ``ScanResult.cluster_methods``.

        Atomic: if any stage raises (bad input, a failing model, an interrupt),
        the tracker is left exactly as it was before the call and the
        exception propagates, so the same scan can be retried. Only a step
        that succeeded adds rows to :meth:`history`.
        """
        saved = self.state_dict()
        try:
            self._activate(sensor)
            result = self._step(t, z, sensor is not None)
        except BaseException:
            self._restore(saved)
            raise
        if self._history_rows and self._history_rows[-1][0][:1].tolist() == [result.time]:
            # another sensor's scan at the same time: its update supersedes the rows
            self._history_rows.pop()
        if self.keep_history and len(result.ids):
            order = np.argsort(result.ids, kind="stable")
            self._history_rows.append(
                (
                    np.full(len(order), result.time),
                    result.ids[order],  # fancy indexing: copies, so callers may
                    result.x[order],  # change the ScanResult's arrays freely
                    result.P[order],
                    np.asarray(result.existence, dtype=float)[order],
                )
            )
        return result

    def _scan_time(self, t) -> float:
        """Seconds of a scan time; fixes ``time_origin`` at the first datetime scan."""
        if is_datetime(t):
            if self.time is not None and self.time_origin is None:
                raise ValueError(
                    f"scan time {t!r} is a datetime, but this run's earlier scan times were "
                    "numbers; one run takes either numbers (seconds) or datetimes, not both"
                )
            ns = scan_time_ns(t)
            if self.time_origin is None:
                self.time_origin = iso_from_ns(ns)  # restored by step() if the scan fails
            return (ns - ns_from_iso(self.time_origin)) / 1e9
        if self.time_origin is not None:
            raise ValueError(
                f"scan time {t!r} is a number, but this run's scan times are datetimes "
                f"(time_origin {self.time_origin}); one run takes either numbers (seconds) "
                "or datetimes, not both"
            )
        if not isinstance(t, numbers.Number | np.ndarray):  # str, None, date, …
            raise TypeError(
                "scan time t must be a number (seconds), a datetime.datetime or a "
                f"numpy.datetime64, got {type(t).__name__}"
            )
        # bools, complex numbers, ints beyond the float range, NaN/inf: ValueError naming t
        return as_float(t, "scan time t")

    def _step(self, t, z, same_time_ok=False) -> ScanResult:
        c = self.config
        t = self._scan_time(t)
        z = _as_real_array(z, "measurements z")  # no complex, bool, string or huge-int z
        mdim = self._mdim
        if z.size == 0:
            z = z.reshape(0, mdim)
        if z.ndim != 2 or z.shape[1] != mdim:
            raise ValueError(f"measurements must have shape (M, {mdim}), got {z.shape}")
        if not np.all(np.isfinite(z)):
            raise ValueError(f"scan at t={t} has a non-finite measurement")
        if self.time is not None and not (t > self.time or (same_time_ok and t == self.time)):
            raise ValueError(f"scan times must increase: got t={t} after t={self.time}")
        dt = None if self.time is None else t - self.time
        z, n_coincident = _merge_coincident(z, t)

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
            if self._linear:
                model = {"H": self._sensor.H, "R": self._sensor.R}
            else:
                model = {"model": self._sensor}
            self.x, self.P = pda_pairs_update(self.x, self.P, z, beta0, rows, cols, w, **model)
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
        x, P = self.x[tracks], self.P[tracks]
        if self._linear:
            z_pred, S = predict_measurement(x, P, self._sensor.H, self._sensor.R)
            g = gate_pairs(z_pred, S, z, P_G=c.p_g)
        else:
            z_pred, S = ekf_predict_measurement(x, P, self._sensor)
            g = gate_pairs(z_pred, S, z, P_G=c.p_g, residual=self._sensor.residual)
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
        sizes, seconds, methods, fallbacks = [], [], [], []

        def solve(k, tr, ms, Lc, mc):
            bc, method, reason, dt_s = self._cluster_marginals(Lc, mc, loud)
            fallbacks.append(reason)
            seconds.append(dt_s)
            sizes.append((len(tr), len(ms)))
            methods.append(method)
            if self.on_cluster is not None:
                self.on_cluster(ClusterRecord(self.ids[tracks[tr]], Lc, mc, bc, dt_s, method, loud))
            return bc

        def solve_pairs(k, tr, ms, a, b, vals, mc):
            # too large for an N × M matrix: the tiers on the gated pairs, never dense
            t0 = _time.perf_counter()
            reason = (
                f"dense_budget: {len(tr)} tracks × {len(ms)} measurements > "
                f"{DENSE_MAX_ENTRIES} entries"
            )
            res = fallback_pair_marginals(a, b, vals, mc, len(ms), reason=reason)
            dt_s = _time.perf_counter() - t0
            self._log_fallback(len(tr), len(ms), loud, res.reason, res.method)
            fallbacks.append(res.reason)
            seconds.append(dt_s)
            sizes.append((len(tr), len(ms)))
            methods.append(res.method)
            if self.on_cluster is not None:
                shape = (len(tr), len(ms))
                Lc = csr_array((vals, (a, b)), shape=shape)
                bc = csr_array(
                    (
                        np.concatenate([res.beta0, res.pair_beta]),
                        (np.concatenate([np.arange(len(tr)), a]), np.concatenate([0 * tr, b + 1])),
                    ),
                    shape=(len(tr), len(ms) + 1),
                )
                rec = ClusterRecord(self.ids[tracks[tr]], Lc, mc, bc, dt_s, res.method, loud)
                self.on_cluster(rec)
            return res.beta0, res.pair_beta

        beta0, weights = cluster_pair_marginals(
            groups, rows, cols, L_pairs, miss, solve, solve_pairs, DENSE_MAX_ENTRIES
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
            (sizes, seconds, methods, fallbacks),
            used,
        )

    def _cluster_marginals(self, Lc, mc, loud):
        """β of one multi-track cluster by the configured method under the exact
        budget (:func:`~jointtrack.association.budget.budgeted_marginals`), each
        fallback to the approximation logged."""
        c = self.config
        t0 = _time.perf_counter()
        res = budgeted_marginals(
            Lc,
            mc,
            method=c.association,
            approximation=c.approximation,
            max_tracks=c.exact_max_tracks,
            rng=self.rng,
        )
        if res.reason:
            self._log_fallback(len(Lc), Lc.shape[1], loud, res.reason, res.method)
        return res.beta, res.method, res.reason, _time.perf_counter() - t0

    @staticmethod
    def _log_fallback(n, m, loud, reason, method):
        (log.warning if loud else log.debug)(
            "%s association of a cluster of %d %s tracks and %d measurements not used "
            "(%s): used %s",
            "the configured" if reason.startswith("dense_budget") else "exact",
            n,
            "confirmed" if loud else "tentative",
            m,
            reason,
            method,
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

    # -------------------------------------------------------------- history
    def history(self) -> TrackHistory:
        """Every confirmed estimate this tracker produced: a :class:`TrackHistory`.

        One row per (scan time, track id) with ``time`` (seconds; after
        ``time_origin`` for datetime scans), ``track_id``, ``x`` (n,), ``P``
        (n, n) and ``existence``: the ``ScanResult`` of every successful
        :meth:`step` since the tracker was built (or :meth:`clear_history`).
        Not part of the saved state: after :meth:`load` it starts empty.
        Raises RuntimeError if recording is off (``keep_history=False``) and
        nothing was recorded.
        """
        if not self.keep_history and not self._history_rows:
            raise RuntimeError(
                "this tracker does not record its history (JPDATracker(keep_history=False))"
            )
        n = self._motion.state_dim
        if len(self._history_rows) > 1:  # consolidate, so repeated calls are cheap
            self._history_rows = [
                tuple(np.concatenate(cols) for cols in zip(*self._history_rows, strict=True))
            ]
        if self._history_rows:
            time, ids, x, P, existence = self._history_rows[0]
        else:
            time, ids, x, P, existence = (
                np.zeros(0),
                np.zeros(0, np.int64),
                np.zeros((0, n)),
                np.zeros((0, n, n)),
                np.zeros(0),
            )
        return TrackHistory(time, ids, x, P, existence, time_origin=self.time_origin)

    def clear_history(self) -> None:
        """Forget the recorded history (the tracker state is unchanged)."""
        self._history_rows = []

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
    _SCALARS = ("time", "next_id", "n_scans", "time_origin")
    # state key -> attribute (``history()`` is the track-history method)
    _ATTRS = {"history": "hit_history"}

    @classmethod
    def _attr(cls, name: str) -> str:
        return cls._ATTRS.get(name, name)

    def state_dict(self) -> dict:
        """Everything needed to continue the run identically (copies of plain types and arrays).

        The track history (:meth:`history`) is not part of it.
        """
        state = {
            name: np.array(getattr(self, self._attr(name)), copy=True) for name in self._ARRAYS
        }
        state.update({name: getattr(self, name) for name in self._SCALARS})
        state["config"] = self.config.to_dict()
        state["rng"] = self.rng.bit_generator.state
        return state

    def _restore(self, state: dict) -> None:
        """Put back a :meth:`state_dict` (used by :meth:`step` when a stage fails)."""
        for name in self._ARRAYS:
            setattr(self, self._attr(name), state[name])
        for name in self._SCALARS:
            setattr(self, name, state[name])
        self.rng.bit_generator.state = state["rng"]

    def save(self, path, *, run=None) -> Path:
        """Write the tracker state to ``path`` (see :mod:`jointtrack.trackers.state_io`).

        A versioned, checksummed ``.npz`` archive of plain arrays with a JSON
        header, written atomically (temporary file, fsync, rename); never pickle.
        ``time_origin`` (datetime scans) is saved with the state; the track
        history (:meth:`history`) is not.
        """
        scalars = {
            "time": None if self.time is None else float(self.time),
            "next_id": int(self.next_id),
            "n_scans": int(self.n_scans),
            "time_origin": self.time_origin,
        }
        arrays = {name: getattr(self, self._attr(name)) for name in self._ARRAYS}
        # ``run``: a caller's JSON-able bookkeeping, saved atomically with the state
        return write_state(
            path, arrays, self.config.to_dict(), scalars, self.rng.bit_generator.state, run=run
        )

    @classmethod
    def load(cls, path, *, keep_history: bool = True) -> JPDATracker:
        """Restore a tracker written by :meth:`save`; the run continues identically.

        The track history is not saved: :meth:`history` of the loaded tracker
        starts empty and records the scans stepped after loading
        (``keep_history`` as in the constructor). ``time_origin`` is restored,
        so a datetime run continues on the same time axis.

        Raises
        ------
        ValueError
            (:class:`~jointtrack.trackers.state_io.StateFileError`) for a missing,
            damaged, truncated, foreign, wrong-version or pickle file, or values
            that a tracker cannot hold (including a configuration with missing
            settings: they are never filled with defaults); the message names the
            file and the problem.
        """
        arrays, config, scalars, rng = read_state(path)
        try:  # complete: a missing setting is damage, not a default
            cfg = TrackerConfig.from_dict(config, complete=True)
        except (TypeError, ValueError, OverflowError, RecursionError) as exc:
            raise StateFileError(f"{path}: invalid tracker configuration ({exc})") from None
        trk = cls(cfg, keep_history=keep_history)
        validate_tracker_arrays(path, arrays, scalars, trk._motion.state_dim, cfg.dim)
        origin = scalars.get("time_origin")  # absent in files of numeric-time runs
        if origin is not None:
            try:
                iso_from_ns(ns_from_iso(origin))
            except (TypeError, ValueError, OverflowError) as exc:
                raise StateFileError(f"{path}: invalid scalar 'time_origin' ({exc})") from None
        for name in cls._ARRAYS:
            setattr(trk, cls._attr(name), arrays[name])
        trk.time_origin = origin
        trk.time = scalars["time"]
        trk.next_id = scalars["next_id"]
        trk.n_scans = scalars["n_scans"]
        try:
            trk.rng.bit_generator.state = rng
        except (TypeError, ValueError, KeyError, OverflowError) as exc:
            raise StateFileError(f"{path}: invalid random-generator state ({exc})") from None
        return trk
