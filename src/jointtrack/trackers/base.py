"""The tracker layer every scan-based tracker shares: clock, sensors, gating, clusters, state.

:class:`ScanTracker` holds what :class:`~jointtrack.trackers.jpda.JPDATracker`
and the PMB/PMBM trackers of :mod:`jointtrack.trackers.pmbm` have in common, so
that it exists once:

* the scan clock — seconds or datetimes (``time_origin``), increasing times,
  several sensors at one time (:meth:`ScanTracker._scan_time`,
  :meth:`ScanTracker._check_scan`);
* motion and sensor model objects, built from the configuration or passed in
  (:class:`~jointtrack.trackers.sensors.Sensor`; linear or EKF);
* atomic steps — a failing scan leaves the tracker as it was — and the
  history of reported estimates (:meth:`ScanTracker.step`, :meth:`history`);
* gating on a KD-tree and the association of every multi-track cluster by
  the one assignment-sum core under its budget, with sparse LBP / PDA
  fallbacks (:meth:`ScanTracker._gate`, :meth:`ScanTracker._pair_marginals`);
* versioned, checksummed state files (:mod:`jointtrack.trackers.state_io`):
  a subclass names its arrays and scalars, :meth:`save`/:meth:`load` do the rest.

A subclass provides ``_step(t, z, same_time_ok)`` returning a
:class:`ScanResult`, its ``_ARRAYS``/``_SCALARS``, its configuration class
(``CONFIG``), its kind (``KIND``, stored in the state file) and
``_validate_state``.
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
    MAX_LBP_WORK,
    budgeted_marginals,
    fallback_pair_marginals,
    reason_kind,
)
from jointtrack.association.clustering import cluster_pair_marginals, clusters
from jointtrack.association.gating import gate_measurements, gate_pairs
from jointtrack.errors import CoincidentReturnsWarning
from jointtrack.filters import ekf_predict_measurement, predict_measurement
from jointtrack.filters.imm import IMMModes
from jointtrack.models import (
    ConstantAcceleration,
    ConstantVelocity,
    CoordinatedTurn,
    LinearPosition,
    RangeBearing,
    Stationary,
)
from jointtrack.trackers.history import (
    TrackHistory,
    is_datetime,
    iso_from_ns,
    ns_from_iso,
    scan_time_ns,
)
from jointtrack.trackers.sensors import Sensor
from jointtrack.trackers.state_io import StateFileError, read_state, write_state

__all__ = ["ClusterRecord", "ScanResult", "ScanTracker", "merge_coincident", "motion_model"]

log = logging.getLogger("jointtrack.tracker")

#: Tracker kinds a state file may hold → the class that loads it.
TRACKER_KINDS = {"jpda": "JPDATracker", "pmb": "PMBTracker", "pmbm": "PMBMTracker"}


@dataclass(frozen=True)
class ScanResult:
    """What one call of a tracker's ``step`` did.

    The confirmed tracks after the update: ``ids`` (K,), ``x`` (K, n),
    ``P`` (K, n, n), ``existence`` (K,) (1.0 without JIPDA). ``time`` is in
    seconds — for datetime scans, seconds after the tracker's ``time_origin``.
    ``cluster_sizes`` lists (tracks, measurements) of every multi-track
    cluster, ``cluster_seconds`` the association time of each,
    ``cluster_methods`` the method used, ``cluster_confirmed`` whether it
    was a cluster of confirmed (True) or tentative (False) tracks and
    ``cluster_fallbacks`` why the approximation replaced the configured method
    (``""`` when it did not; ``"exact_max_tracks"`` for a cluster above the
    budget; ``"exact_max_bits_tentative: …"`` for a cluster of tentative tracks
    whose exact DP is wider than their budget; ``"refused: …"`` when the exact
    engine declined it at its own limits;
    ``"dense_budget: …"`` for a cluster too large for an N × M matrix).
    ``n_coincident``: returns dropped because they repeated another return of
    the scan exactly (see :meth:`JPDATracker.step`). ``n_continued``: tracks
    confirmed at this scan that took a deleted or losing track's id (JPDA/JIPDA
    ``id_continuation``).
    With ``motion = "imm"``: ``mode_names`` (r,) and ``mode_probabilities``
    (K, r), each confirmed track's mode probabilities after the update (else
    ``()`` and None); ``x``, ``P`` are then the modes' combined position and velocity.
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
    n_continued: int = 0
    mode_names: tuple = ()
    mode_probabilities: np.ndarray | None = None

    @property
    def n_fallbacks(self) -> int:
        """Clusters solved by the approximation instead of the configured method."""
        return sum(1 for f in self.cluster_fallbacks if f)


def merge_coincident(z: np.ndarray, t: float, return_index: bool = False):
    """``(z, n_dropped)``: ``z`` with each set of identical rows kept once (first
    occurrence, order kept); with ``return_index`` also the kept rows' indices
    (None when every row is kept)."""

    def out(z, n, kept):
        return (z, n, kept) if return_index else (z, n)

    if len(z) < 2:
        return out(z, 0, None)
    x = np.sort(z[:, 0])
    if not (x[1:] == x[:-1]).any():  # the usual scan: no tie in the first coordinate
        return out(z, 0, None)
    _, first = np.unique(z, axis=0, return_index=True)
    n_dropped = len(z) - len(first)
    if n_dropped == 0:
        return out(z, 0, None)
    warnings.warn(
        f"scan at t={t}: {n_dropped} of {len(z)} returns repeat another return of the scan "
        f"exactly (identical measurement vectors; a stuck or replayed detector?); each set of "
        f"identical returns is treated as one return ({len(first)} kept)",
        CoincidentReturnsWarning,
        stacklevel=4,
    )
    kept = np.sort(first)
    return out(z[kept], n_dropped, kept)


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


def motion_model(config, motion=None):
    """``motion``, checked, or the configuration's NCV / constant-acceleration / IMM model.

    Any object with ``state_dim``, ``transition(dt)`` and ``noise(dt)`` is a
    motion model, and so is an :class:`~jointtrack.filters.imm.IMMModes`; the
    default is built from ``config.motion``, ``config.dim`` and
    ``config.process_noise`` (and, for ``motion = "imm"``, ``imm_modes``,
    ``imm_switching``, ``imm_initial`` and ``turn_rate_std``).
    """
    if motion is None and config.motion == "imm":
        if not hasattr(config, "imm_modes"):
            raise ValueError(
                f"motion = 'imm' is available to the JPDA/JIPDA tracker (TrackerConfig) only, "
                f"not to {type(config).__name__}"
            )
        return imm_modes(config)
    if motion is None:
        model = ConstantVelocity if config.motion == "cv" else ConstantAcceleration
        motion = model(dim=config.dim, q=config.process_noise)
    if isinstance(motion, IMMModes):
        return motion
    for attr in ("state_dim", "transition", "noise"):
        if not hasattr(motion, attr):
            raise ValueError(f"motion model {motion!r} has no {attr!r}")
    return motion


def imm_modes(config) -> IMMModes:
    """The :class:`~jointtrack.filters.imm.IMMModes` of a ``motion = "imm"`` configuration."""
    d = config.dim
    qs = getattr(config, "imm_process_noise", None) or (config.process_noise,) * len(
        config.imm_modes
    )
    build = {
        "cv": lambda q: ConstantVelocity(dim=d, q=q),
        "ca": lambda q: ConstantAcceleration(dim=d, q=q),
        "ct": lambda q: CoordinatedTurn(q=q, turn_rate_std=config.turn_rate_std),
        "stationary": lambda q: Stationary(dim=d, q=q),
    }
    return IMMModes(
        [build[name](q) for name, q in zip(config.imm_modes, qs, strict=True)],
        config.imm_switching_matrix(),
        initial=config.imm_initial,
        names=config.imm_modes,
        switching_per=getattr(config, "imm_switching_per", "scan"),
    )


class ScanTracker:
    """Base of the scan trackers (see the module docstring); not used on its own."""

    #: the tracker kind stored in state files (``TRACKER_KINDS``)
    KIND = ""
    #: the configuration dataclass (``from_dict(d, complete=True)``, ``to_dict()``)
    CONFIG = None
    #: state arrays / scalars saved by :meth:`save` besides the clock and counters
    _ARRAYS: tuple = ()
    _SCALARS: tuple = ("time", "next_id", "n_scans", "time_origin")
    #: state key -> attribute, where they differ
    _ATTRS: dict = {}
    #: per-report fields ``step`` accepts besides ``z`` (``labels``, ``velocities``)
    REPORT_FIELDS: tuple = ()
    #: whether the tracker runs an interacting multiple model (``motion = "imm"``)
    SUPPORTS_IMM: bool = False

    def __init__(
        self,
        config=None,
        *,
        motion=None,
        sensor=None,
        sensors=None,
        on_cluster=None,
        keep_history: bool = True,
    ):
        """Clock, models, sensors, history and random generator from ``config``.

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
        is not part of the saved state. ``keep_history``: record every reported
        estimate for :meth:`history` (turn off for memory-bound runs; it can be
        switched at any time through the ``keep_history`` attribute).
        """
        if config is None:
            config = self.CONFIG()
        elif not isinstance(config, self.CONFIG):
            raise TypeError(
                f"config must be a {self.CONFIG.__name__} (or None for the defaults), got "
                f"{type(config).__name__}"
            )
        self.config = config
        self.on_cluster = on_cluster
        self.keep_history = bool(keep_history)
        # (time, ids, x, P, existence) per successful scan; outside the saved and
        # restored state: appended only after a step succeeded
        self._history_rows: list[tuple] = []
        # clusters the approximation solved, by reason (fallback_counts; not state)
        self._fallbacks: dict = {}
        c = self.config
        self._motion = motion = motion_model(c, motion)
        if isinstance(motion, IMMModes) and not self.SUPPORTS_IMM:
            raise ValueError(
                f"motion = 'imm' (an IMMModes motion model) is available to the JPDA/JIPDA "
                f"tracker only, not to {type(self).__name__}"
            )
        if isinstance(motion, IMMModes) and motion.dim != c.dim:
            raise ValueError(f"motion: the IMM modes are {motion.dim}-D, but dim = {c.dim}")
        # an IMM's tracks report (and are gated, confirmed and saved by) the combined
        # position and velocity; its modes' common state is the tracker's business
        n = 2 * c.dim if isinstance(motion, IMMModes) else int(motion.state_dim)
        self._state_dim = n
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
        """Length of a (reported) track state: the motion model's, or ``2·dim``
        (position and velocity) for an IMM."""
        return self._state_dim

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
        self._active_sensor = sensor_id
        self._sensor = spec.model
        self._linear, self._mdim = spec.linear, spec.measurement_dim
        self._p_d = c.p_d if spec.p_d is None else float(spec.p_d)
        self._clutter = c.clutter_density if spec.clutter_density is None else spec.clutter_density

    # ------------------------------------------------------------------ scan
    def step(self, t: float, z, sensor=None, *, labels=None, velocities=None) -> ScanResult:
        """Process the measurements ``z`` (M, dim) taken at time ``t``.

        ``labels`` (M,) strings, ``""`` for none: the identity each report names
        (an AIS MMSI, an ADS-B icao24), used as given (association by label);
        ``velocities`` (M, dim), NaN where unknown: reported velocities that
        seed the tracks started on these reports. Trackers that take them list
        them in ``REPORT_FIELDS``; others refuse them.

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
        extra = {
            name: value
            for name, value in (("labels", labels), ("velocities", velocities))
            if value is not None
        }
        unsupported = sorted(set(extra) - set(self.REPORT_FIELDS))
        if unsupported:
            raise ValueError(
                f"{type(self).__name__}.step does not take {' or '.join(unsupported)} "
                f"(JPDATracker does)"
            )
        saved = self.state_dict()
        try:
            self._activate(sensor)
            result = self._step(t, z, sensor is not None, **extra)
        except BaseException:
            self._restore(saved)
            raise
        if self._history_rows and self._history_rows[-1][0][:1].tolist() == [result.time]:
            # another sensor's scan at the same time: its update supersedes the rows
            self._history_rows.pop()
        if self.keep_history and len(result.ids):
            order = np.argsort(result.ids, kind="stable")
            modes = result.mode_probabilities
            self._history_rows.append(
                (
                    np.full(len(order), result.time),
                    result.ids[order],  # fancy indexing: copies, so callers may
                    result.x[order],  # change the ScanResult's arrays freely
                    result.P[order],
                    np.asarray(result.existence, dtype=float)[order],
                    np.zeros((len(order), 0)) if modes is None else modes[order],
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

    def _check_scan(self, t, z, same_time_ok=False):
        """``(t, z, dt, n_coincident)`` of a scan: validated time (seconds) and returns.

        ``dt`` is None at the first scan; ``z`` has exact repeats merged
        (:func:`merge_coincident`).
        """
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
        z, n_coincident, self._kept_rows = merge_coincident(z, t, return_index=True)
        return t, z, dt, n_coincident

    def _pairs_gated(self, x, P, z_pairs, chunk=256):
        """Whether each report ``z_pairs[k]`` is in the gate of the state ``x[k], P[k]``
        (a labelled report in its own track's gate; outside it: a position jump).

        The diagonal of the dense gate, formed ``chunk`` pairs at a time: the
        whole (K, K) gate of K labelled reports took 7 s and 1.5 GB per scan
        at K = 5000.
        """
        inside = np.zeros(len(z_pairs), bool)
        for a in range(0, len(z_pairs), chunk):
            b = a + chunk
            inside[a:b] = np.diagonal(self._gate(x[a:b], P[a:b], z_pairs[a:b], dense=True).mask)
        return inside

    def _gate(self, x, P, z, dense: bool = False):
        """Chi-square gates of the states ``(x, P)`` on ``z`` (P_G = p_g): the gated
        pairs (:func:`gate_pairs`), or with ``dense`` the (N, M)
        :class:`~jointtrack.association.gating.Gating` (:func:`gate_measurements`)."""
        c = self.config
        gate = gate_measurements if dense else gate_pairs
        if self._linear:
            z_pred, S = predict_measurement(x, P, self._sensor.H, self._sensor.R)
            return gate(z_pred, S, z, P_G=c.p_g)
        z_pred, S = ekf_predict_measurement(x, P, self._sensor)
        return gate(z_pred, S, z, P_G=c.p_g, residual=self._sensor.residual)

    def _measurement_model(self) -> dict:
        """The keyword arguments of the filters' update for the active sensor."""
        if self._linear:
            return {"H": self._sensor.H, "R": self._sensor.R}
        return {"model": self._sensor}

    def _pair_marginals(self, track_ids, g, L_pairs, miss, loud, groups=None):
        """Association marginals of gated pairs, cluster by cluster, on the one core.

        ``g``: the :class:`~jointtrack.association.gating.PairGating` of the
        tracks ``track_ids`` (for :class:`ClusterRecord`); ``L_pairs`` the
        likelihood ratio of each gated pair, ``miss`` (N,) each track's weight
        of detecting nothing (the cluster convention of
        :func:`jointtrack.association.marginals`). Single-track clusters are
        exact PDA; the others go to :meth:`_cluster_marginals` (the configured
        method under the exact budget), clusters too large for an N × M matrix
        to the sparse tiers. ``groups``: ``clusters(g)`` if the caller already
        has it. Returns ``(beta0, pair_beta, groups, (sizes,
        seconds, methods, fallbacks))``.
        """
        sizes, seconds, methods, fallbacks = [], [], [], []

        def solve(k, tr, ms, Lc, mc):
            bc, method, reason, dt_s = self._cluster_marginals(Lc, mc, loud)
            fallbacks.append(reason)
            seconds.append(dt_s)
            sizes.append((len(tr), len(ms)))
            methods.append(method)
            if self.on_cluster is not None:
                self.on_cluster(ClusterRecord(track_ids[tr], Lc, mc, bc, dt_s, method, loud))
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
                rec = ClusterRecord(track_ids[tr], Lc, mc, bc, dt_s, res.method, loud)
                self.on_cluster(rec)
            return res.beta0, res.pair_beta

        if groups is None:
            groups = clusters(g)
        beta0, weights = cluster_pair_marginals(
            groups, g.rows, g.cols, L_pairs, miss, solve, solve_pairs, DENSE_MAX_ENTRIES
        )
        return beta0, weights, groups, (sizes, seconds, methods, fallbacks)

    def _cluster_marginals(self, Lc, mc, loud):
        """β of one multi-track cluster by the configured method under the exact
        budget of its kind of track (:meth:`_exact_budget`;
        :func:`~jointtrack.association.budget.budgeted_marginals`), each
        fallback to the approximation logged."""
        c = self.config
        max_tracks, max_bits, label = self._exact_budget(loud)
        t0 = _time.perf_counter()
        res = budgeted_marginals(
            Lc,
            mc,
            method=c.association,
            approximation=c.approximation,
            max_tracks=max_tracks,
            rng=self.rng,
            exact_options=None if max_bits is None else {"max_bits": max_bits},
            max_work=self._lbp_work(),
        )
        reason = res.reason
        if (
            max_bits is not None
            and reason.startswith("refused: ")
            and (f"above max_bits = {max_bits};" in reason)
        ):
            # the engine refused the cluster at this kind's budget, not at its own limits:
            # name the setting, so that counts and messages say which budget it was
            reason = f"{label}: {reason.removeprefix('refused: ')}"
        if reason:
            self._log_fallback(len(Lc), Lc.shape[1], loud, reason, res.method)
        return res.beta, res.method, reason, _time.perf_counter() - t0

    def _lbp_work(self) -> int:
        """Message updates an approximation may spend on one cluster: a dense one whose
        sweeps could take more goes to the sparse tiers, which work within it
        (:func:`~jointtrack.association.budget.budgeted_marginals`)."""
        return MAX_LBP_WORK

    def _exact_budget(self, loud):
        """``(max_tracks, max_bits, label)``: the exact budget of a cluster of this kind.

        ``loud``: the cluster's kind (JPDA: confirmed tracks). Here every cluster has
        ``exact_max_tracks`` and the exact engine's own limits (``max_bits`` None);
        :class:`~jointtrack.trackers.JPDATracker` gives tentative tracks a budget in
        frontier bits instead. ``label`` names the ``max_bits`` setting in the reason
        of a cluster the engine refused at it.
        """
        return self.config.exact_max_tracks, None, ""

    def _log_fallback(self, n, m, loud, reason, method):
        """Count a cluster the configured method did not solve; log the first of each kind.

        One WARNING line per kind of reason and track (confirmed clusters; tentative
        ones at DEBUG), then DEBUG only: a long run would otherwise log one line per
        approximated cluster. :attr:`fallback_counts` holds the counts.
        """
        key = reason_kind(reason) + ("" if loud else ", tentative tracks")
        self._fallbacks[key] = self._fallbacks.get(key, 0) + 1
        first = self._fallbacks[key] == 1 and loud
        (log.warning if first else log.debug)(
            "%s association of a cluster of %d %s tracks and %d measurements not used "
            "(%s): used %s%s",
            "the configured" if reason.startswith("dense_budget") else "exact",
            n,
            "confirmed" if loud else "tentative",
            m,
            reason,
            method,
            "; further such clusters are counted in fallback_counts, not logged" if first else "",
        )

    @property
    def fallback_counts(self) -> dict:
        """Clusters solved by the approximation instead of the configured method since
        this tracker was built, by reason (``", tentative tracks"`` marks tentative ones)."""
        return dict(self._fallbacks)

    # -------------------------------------------------------------- history
    def history(self) -> TrackHistory:
        """Every reported estimate this tracker produced: a :class:`TrackHistory`.

        One row per (scan time, track id) with ``time`` (seconds; after
        ``time_origin`` for datetime scans), ``track_id``, ``x`` (n,), ``P``
        (n, n), ``existence`` and, with ``motion = "imm"``, ``mode_probabilities``: the
        ``ScanResult`` of every successful
        :meth:`step` since the tracker was built (or :meth:`clear_history`).
        Not part of the saved state: after :meth:`load` it starts empty.
        Raises RuntimeError if recording is off (``keep_history=False``) and
        nothing was recorded.
        """
        if not self.keep_history and not self._history_rows:
            raise RuntimeError("this tracker does not record its history (keep_history=False)")
        n = self.state_dim
        if len(self._history_rows) > 1:  # consolidate, so repeated calls are cheap
            self._history_rows = [
                tuple(np.concatenate(cols) for cols in zip(*self._history_rows, strict=True))
            ]
        names = self._motion.names if isinstance(self._motion, IMMModes) else ()
        if self._history_rows:
            time, ids, x, P, existence, modes = self._history_rows[0]
        else:
            time, ids, x, P, existence, modes = (
                np.zeros(0),
                np.zeros(0, np.int64),
                np.zeros((0, n)),
                np.zeros((0, n, n)),
                np.zeros(0),
                np.zeros((0, len(names))),
            )
        return TrackHistory(
            time,
            ids,
            x,
            P,
            existence,
            time_origin=self.time_origin,
            mode_names=names,
            mode_probabilities=modes if names else None,
        )

    def clear_history(self) -> None:
        """Forget the recorded history (the tracker state is unchanged)."""
        self._history_rows = []

    # ------------------------------------------------------------ save/load
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
        # step() snapshots the state every scan: the configuration is frozen and its
        # dict holds only immutable values (numbers, strings, tuples), so its
        # to_dict() (a deep copy) is taken once per config object and each state gets
        # a fresh shallow copy of it
        cached = self.__dict__.get("_config_state")
        if cached is None or cached[0] is not self.config:
            cached = self._config_state = (self.config, self.config.to_dict())
        state["config"] = dict(cached[1])
        state["rng"] = self.rng.bit_generator.state
        return state

    def _restore(self, state: dict) -> None:
        """Put back a :meth:`state_dict` (used by :meth:`step` when a stage fails)."""
        for name in self._ARRAYS:
            setattr(self, self._attr(name), state[name])
        for name in self._SCALARS:
            setattr(self, name, state[name])
        self.rng.bit_generator.state = state["rng"]

    def _saved_scalars(self) -> dict:
        """The JSON scalars of the state file (clock, counters, kind)."""
        scalars = {
            "time": None if self.time is None else float(self.time),
            "next_id": int(self.next_id),
            "n_scans": int(self.n_scans),
            "time_origin": self.time_origin,
        }
        if self.KIND != "jpda":  # JPDA files keep their original header (kind by default)
            scalars["tracker"] = self.KIND
        return scalars

    def save(self, path, *, run=None) -> Path:
        """Write the tracker state to ``path`` (see :mod:`jointtrack.trackers.state_io`).

        A versioned, checksummed ``.npz`` archive of plain arrays with a JSON
        header, written atomically (temporary file, fsync, rename); never pickle.
        ``time_origin`` (datetime scans) is saved with the state; the track
        history (:meth:`history`) is not. A path that cannot be written (a
        directory, a missing or read-only directory, a full disk) raises
        :class:`~jointtrack.trackers.state_io.StateFileError` naming it; the file
        already there, if any, is then left as it was and no temporary file remains.
        """
        arrays = {name: getattr(self, self._attr(name)) for name in self._ARRAYS}
        # ``run``: a caller's JSON-able bookkeeping, saved atomically with the state
        return write_state(
            path,
            arrays,
            self.config.to_dict(),
            self._saved_scalars(),
            self.rng.bit_generator.state,
            run=run,
        )

    def _validate_state(self, path, arrays: dict, scalars: dict) -> None:
        """Raise :class:`StateFileError` naming the field for values this tracker cannot hold."""
        raise NotImplementedError

    @classmethod
    def load(cls, path, *, keep_history: bool = True):
        """Restore a tracker written by :meth:`save`; the run continues identically.

        The track history is not saved: :meth:`history` of the loaded tracker
        starts empty and records the scans stepped after loading
        (``keep_history`` as in the constructor). ``time_origin`` is restored,
        so a datetime run continues on the same time axis.

        Raises
        ------
        ValueError
            (:class:`~jointtrack.trackers.state_io.StateFileError`) for a missing,
            damaged, truncated, foreign, wrong-version or pickle file, a state of
            another kind of tracker, or values that a tracker cannot hold
            (including a configuration with missing settings: they are never
            filled with defaults); the message names the file and the problem.
        """
        arrays, config, scalars, rng = read_state(path)
        kind = scalars.get("tracker", "jpda")
        if kind != cls.KIND:
            owner = TRACKER_KINDS.get(kind) if isinstance(kind, str) else None
            hint = f"; load it with {owner}.load" if owner else ""
            raise StateFileError(
                f"{path}: holds the state of a {kind!r} tracker, not of a {cls.__name__} "
                f"({cls.KIND!r}){hint}"
            )
        try:  # complete: a missing setting is damage, not a default
            cfg = cls.CONFIG.from_dict(config, complete=True)
        except (TypeError, ValueError, OverflowError, RecursionError) as exc:
            raise StateFileError(f"{path}: invalid tracker configuration ({exc})") from None
        trk = cls(cfg, keep_history=keep_history)
        trk._validate_state(path, arrays, scalars)
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
