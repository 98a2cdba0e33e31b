"""Configuration of the JPDA tracker: one frozen dataclass of plain, TOML-friendly numbers."""

from __future__ import annotations

import math
import numbers
from dataclasses import asdict, dataclass, fields

import numpy as np

__all__ = [
    "IMM_MODES",
    "MAX_STD",
    "MAX_VARIANCE",
    "MISS_MODELS",
    "REPORTING",
    "TENTATIVE_ASSOCIATIONS",
    "ModelSettings",
    "TrackerConfig",
    "check_field",
    "config_from_dict",
]

#: How the weight of "track detected nothing" is formed (see ``TrackerConfig.miss_model``).
MISS_MODELS = ("1-pd*pg", "1-pd")
#: How targets are detected (see ``TrackerConfig.reporting``).
REPORTING = ("scan", "async")
#: How JIPDA's tentative tracks share returns (see ``TrackerConfig.tentative_association``).
TENTATIVE_ASSOCIATIONS = ("joint", "alternatives", "splitting")
#: The Gaussian a "splitting" track confirms with (``TrackerConfig.tentative_confirm_state``).
TENTATIVE_CONFIRM_STATES = ("moment", "dominant")
#: Largest standard-deviation-like setting: ``max_speed``, ``max_acceleration``
#: (each halved into a per-axis σ) and ``velocity_std``, which the tracker squares
#: into covariances. Equal to the coordinate limit
#: :data:`jointtrack.io.detections.MAX_COORDINATE` (a test keeps them equal;
#: ``jointtrack.io`` is not imported for it): squares of 10¹⁵⁰ stay below 10³⁰¹,
#: leaving float64 (maximum 1.8·10³⁰⁸) room for the filter's sums and products,
#: whereas (max_speed/2)² overflowed for max_speed > 1.3·10¹⁵⁴.
MAX_STD = 1e150
#: Largest variance-like setting: ``process_noise``, ``measurement_noise`` (each
#: entry), ``range_noise`` and ``bearing_noise`` — MAX_STD², for the same reason
#: (10³⁰⁸ made the model's own noise matrix overflow into a refusal that named no
#: setting).
MAX_VARIANCE = 1e300


def config_from_dict(cls, d: dict, noun: str, *, complete: bool = False):
    """``cls(**d)`` for a config dataclass; unknown keys are an error naming them.

    ``complete=True`` (a saved configuration, e.g. in a tracker state file): every
    field must be present — a missing key is an error naming it, never a default,
    since a default would silently change the run that continues from the file.
    """
    known = {f.name for f in fields(cls)}
    unknown = sorted(set(d) - known)
    if unknown:
        raise ValueError(
            f"unknown {noun} setting(s): {', '.join(unknown)}; known: {', '.join(sorted(known))}"
        )
    missing = sorted(known - set(d)) if complete else []
    if missing:
        raise ValueError(f"missing {noun} setting(s): {', '.join(missing)}")
    return cls(**d)


@dataclass(frozen=True)
class ModelSettings:
    """The motion and sensor fields every scan tracker's configuration starts with.

    Shared by :class:`TrackerConfig` and
    :class:`~jointtrack.trackers.pmbm_config.PMBMConfig` (their docstrings
    describe them); checked by :func:`check_field`.
    """

    dim: int = 2
    motion: str = "cv"
    process_noise: float = 1.0
    measurement_noise: float | tuple = 100.0
    sensor: str = "position"
    sensor_position: tuple = (0.0, 0.0)
    range_noise: float = 25.0
    bearing_noise: float = 1e-4
    p_d: float = 0.9


@dataclass(frozen=True)
class TrackerConfig(ModelSettings):
    """Everything that defines a JPDA tracker; plain numbers, TOML-friendly.

    Attributes
    ----------
    dim : 2 or 3, spatial dimension; measurements are positions ``[x, y(, z)]``.
    motion : ``"cv"`` (nearly constant velocity), ``"ca"`` (constant acceleration)
        or ``"imm"``: an interacting multiple model of the modes ``imm_modes``
        (:mod:`jointtrack.filters.imm`; JPDA/JIPDA), each track carrying its mode
        probabilities and one state per mode, reporting the combined
        ``[x, y(, z), vx, vy(, vz)]``.
    process_noise : q of the motion model (m²/s³ for CV, m²/s⁵ for CA); at most
        ``MAX_VARIANCE`` (1e300), like every variance-like setting.
    measurement_noise : measurement noise R of ``sensor="position"``: a number
        σ² (R = σ² I), a per-axis σ² vector of length ``dim`` (R = diag), or a
        full ``dim × dim`` symmetric positive definite covariance (TOML: a list
        or a list of lists). Stored as a float or a tuple (of tuples), so the
        config stays hashable and TOML-friendly; :meth:`measurement_covariance`
        gives the matrix. Passed to :class:`jointtrack.models.LinearPosition`.
    sensor : ``"position"`` (linear, measurements ``[x, y(, z)]``) or
        ``"range-bearing"`` (2-D only; measurements ``[r, θ]`` from a sensor at
        ``sensor_position``, EKF with the bearing residual wrapped to (−π, π]).
    sensor_position : position of the range–bearing sensor.
    range_noise, bearing_noise : σ_r² (m²) and σ_θ² (rad²) of the range–bearing
        sensor; ``clutter_density`` is then per unit of range × bearing.
        Every measurement noise covariance the tracker will use (also
        diag(R, velocity_std² I) with ``measure_velocity``) must pass the filters'
        own test — Cholesky with a reciprocal condition above m·ε, i.e. variances
        within ~1e15 of each other — or the configuration is refused naming them.
    p_d : detection probability P_D.
    p_g : gate probability P_G in (0, 1] (chi-square gate γ = χ²_d⁻¹(P_G)).
        ``p_g = 1`` means an infinite gate, γ = ∞: every measurement is gated
        with every track (no gating; each track's miss weight is then 1 − P_D).
    clutter_density : λ, false returns per unit volume; ``None`` estimates it per
        cluster by Bojilov's heuristic (8), λ = Σ m_i / Σ V_i.
    association : method for clusters within budget (``"exact"`` by default).
    exact_max_tracks : clusters of confirmed tracks with more tracks than this use
        ``approximation`` (logged as a warning with the cluster size); so do
        clusters of tentative tracks when ``exact_max_bits_tentative`` is None.
    exact_max_bits_tentative : the exact budget of clusters of tentative tracks,
        in the exact engine's own measure of work: such a cluster is solved
        exactly, whatever its number of tracks, when the exact DP's state needs
        at most 2^exact_max_bits_tentative subsets (its frontier width, see
        :func:`jointtrack.assignment.assignment_sum`); wider ones are refused by
        the engine before any work and go to ``approximation``. An integer in
        [0, 30], or None: tentative clusters are budgeted like confirmed ones,
        by ``exact_max_tracks`` (the behaviour before this setting; state files
        written before it load with None). Applies with ``association =
        "exact"``; with ``"enumerate"`` every cluster has ``exact_max_tracks``.
        Default 12, from the measurement in ``benchmarks/tentative_budget.py``
        (issue 25; ``benchmarks/RESULTS.md``): tentative clusters in heavy
        clutter are clutter-born tracks glued by shared returns, up to ~200
        tracks, yet many separate into a narrow frontier; every one of at most
        12 bits (up to 93 tracks) took at most 7 ms (median 0.15–0.3 ms, 1–6 ×
        LBP's time), the next measured widths 17, 18 and 22 bits 0.28 s, 0.8 s
        and 13–15 s (200–7000 × LBP). The engine's refusal of a wider cluster
        (its plan, before any DP) takes 2–4 ms. Confirmed clusters keep
        ``exact_max_tracks``: their β matter most (LBP was off by up to 0.4
        there) and the measured ones (2–5 tracks) took under 0.4 ms.
    approximation : ``"lbp"``, ``"mcmc"``, ``"kbest"`` or ``"pda"``.
    initiation : ``"one-point"`` (default: a track on one return, zero mean
        velocity with per-axis σ_v = max_speed/2; with ``existence`` every
        return starts one, with existence r_init·(1 − P(return from a track)),
        see :mod:`jointtrack.trackers.existence`) or ``"two-point"`` (velocity
        from two unassociated returns of consecutive scans no further apart
        than ``max_speed·dt``; its velocity spread √2·σ/dt is wide when the
        measurement noise σ exceeds speed·dt).
    max_speed : largest target speed, m/s; at most ``MAX_STD`` (1e150, the
        coordinate limit), since (max_speed/2)² is a covariance entry.
    max_acceleration : largest target acceleration, m/s² (initial acceleration
        uncertainty σ_a = max_acceleration/2 of constant-acceleration tracks);
        at most ``MAX_STD``.
    confirm_m, confirm_n : M-of-N confirmation (hits = scans with a gated return);
        1 ≤ confirm_m ≤ confirm_n ≤ 30.
    delete_misses : consecutive scans without a gated return that delete a
        confirmed track.
    max_position_std : delete a track whose position standard deviation
        √(tr P_pos / dim) exceeds this (covariance growth).
    existence : use JIPDA existence probabilities (default) instead of M-of-N
        logic; M-of-N confirms nearly every clutter-born track once gates hold
        about one false return each.
    p_survive : probability that a target survives one scan, or one second with
        ``p_survive_per = "second"`` (JIPDA).
    r_init, r_confirm, r_delete : initial, confirmation and deletion thresholds
        of the existence probability (JIPDA); 0 < r_delete < r_init ≤ r_confirm ≤ 1.
        logit(r_confirm) − logit(r_init) is the sequential test's threshold:
        larger confirms later and falsely less often.
    r_report : a confirmed JIPDA track is reported (in ``ScanResult`` and the
        history) while its existence is ≥ r_report; r_delete < r_report ≤ 1.
    merge_threshold : two tracks whose state distance (x₁ − x₂)ᵀ(P₁ + P₂)⁻¹(x₁ − x₂)
        is below this, at least one of them tentative, are duplicates of one
        target and merged (0: never; two confirmed tracks are never merged).
    tentative_association : how JIPDA's tentative tracks share returns.
        ``"joint"`` (the default): one joint association of all tentative tracks
        (after the confirmed ones), so tracks on one target split its returns.
        ``"alternatives"``: tentative tracks on one target are alternative
        hypotheses of that target, not competitors — each is a single-target IPDA
        (exact PDA) on the returns weighted by the probability that no confirmed
        track took them, its existence accumulating as a lone IPDA's and its
        state following its most probable return; a tentative
        track reaching ``r_confirm`` on returns that a confirmed track (or one
        confirmed before it at this scan) already explains is a duplicate and
        stays tentative; merged duplicates keep the larger existence, not the
        union (see :mod:`jointtrack.trackers.existence`, point 5). Measured on the
        Bojilov scene from nothing it confirms sooner, covers more and scores
        better (GOSPA 45–49 against 57) but does not reach the start-up floor
        (25.9; ``benchmarks/RESULTS.md``), so it is not the default. With
        ``existence`` only.
        ``"splitting"``: each tentative track is an integrated track-splitting filter
        (Mušicki, La Scala & Evans 2007; :mod:`jointtrack.trackers.track_splitting`):
        its existence plus a Gaussian mixture of at most ``tentative_components``
        measurement histories; its existence is the lone IPDA's on the mixture's
        likelihood, and the duplicate and merge rules are those of "alternatives".
        ``existence`` only, ``motion`` "cv" or "ca", ``reporting = "scan"``.
    tentative_components : the most track components (measurement histories) a
        ``"splitting"`` tentative track keeps after each scan (an integer in [1, 256];
        the most probable are kept). 1 is ``"alternatives"`` exactly. Default 4: on
        the Bojilov scene from nothing (seeds 0–4) 4, 8 and 16 scored GOSPA 44.0,
        45.6 and 44.6 (within the seeds' spread) and 4 costs least
        (``benchmarks/RESULTS.md``, issue 33).
    tentative_confirm_state : the one Gaussian with which a ``"splitting"`` track
        enters the confirmed set: ``"moment"`` (the mixture's mean and covariance) or
        ``"dominant"`` (its most probable component).
    tentative_process_noise : q (m²/s³, ≥ 0) of white-noise acceleration added to
        the prediction of every tentative track, on top of the motion model's
        (default 0: none). A tentative track started from one return carries a
        velocity guessed from a few returns, some of them clutter; with the small
        q of a nearly-constant-velocity scene its velocity variance shrinks as if
        each were the target's, so a track that followed clutter confirms with a
        wrong velocity it never corrects. The extra noise keeps the tentative
        velocity open; a confirmed track predicts with the model alone. Scan
        reporting, ``motion`` "cv" or "ca" only (measured: ``benchmarks/RESULTS.md``,
        issue 33).
    seed : seed of the random generator used by randomised approximations
        (an integer ≥ 0, or None).

    Every field is checked on construction — type (a string, a bool or a list
    where a number is expected, NaN, a float where an integer is expected) and
    range — and cross-field rules (``confirm_m ≤ confirm_n``, ``r_delete <
    r_init ≤ r_confirm``); a bad value raises ValueError naming the field
    (:func:`check_field` checks one field on its own).
    miss_model : weight of "track detected nothing" in the cluster's joint
        events: ``"1-pd*pg"`` (default; a target-originated return may fall
        outside the gate, Bar-Shalom, Daum & Huang 2009) or ``"1-pd"``
        (Bojilov et al. eqs. (1)/(5), which assume the gate holds every
        target-originated return). JIPDA multiplies either by the existence.
    reporting : ``"scan"`` (default: a scanning sensor that sees every target
        with probability ``p_d`` per scan) or ``"async"``: targets that report
        themselves one at a time at irregular intervals (AIS, ADS-B), each as a
        Poisson process of its own rate λ_i, each report received with
        probability p_d. λ_i is the track's own estimate (Gamma–Poisson:
        λ_i(s) = (1 + reports) / (report_interval + seconds tracked at s),
        prior mean 1/report_interval). A scan that follows the previous one by
        Δt detects track i with probability P_D,i = 1 − exp(−p_d ∫λ_i(s) ds)
        = 1 − (β₀/β₁)^(p_d(1 + reports)), β = report_interval + seconds
        tracked at the interval's start and end — so a silence costs the same
        existence however many other targets' reports cut it into scans
        (deaths included — the target dies at the rate −log p_survive per second
        at any moment, and each scan applies the continuous-time outcome of its
        interval; see ``JPDATracker._scan_detection``): a
        vessel not heard for 30 s is not "missed" once per other vessel's
        report. ``clutter_density`` is then false reports per unit area **per
        second** (it is required), and the likelihood ratio of a pair is
        P_D,i/Δt · g / λ_c (→ p_d·λ_i·g/λ_c as Δt → 0), finite as Δt → 0 — so
        one scan per report time is exact. Needs JIPDA
        (``existence``) and ``p_survive_per = "second"``.
    report_interval : prior mean interval between one target's reports, s
        (``reporting = "async"``).
    p_survive_per : ``"scan"`` (default) — ``p_survive`` is per scan — or
        ``"second"``: per second of elapsed time (a scanning sensor: existence ×
        p_survive^Δt before each scan; reporting targets: deaths at the rate
        −log p_survive per second within the interval, see ``reporting``).
    max_coast : a track without a hit for longer than this many seconds is
        deleted (time-based deletion; default ∞: never by time).
    velocity_std : σ of reported velocities (m/s, per axis) when ``step`` is
        given ``velocities`` (e.g. AIS speed and course): a track started on
        such a report takes it as its initial velocity with this spread,
        instead of zero mean and σ = max_speed/2; at most ``MAX_STD``.
    measure_velocity : with ``step(…, velocities=)``, measure the reported
        velocity as well as the position (z = [p, v], σ = velocity_std per
        component; :class:`~jointtrack.models.LinearPositionVelocity`) in scans
        whose every report has one; ``clutter_density`` is then per unit area
        per unit of velocity area ((m/s)²) for those scans. A moored vessel
        reporting speed 0 keeps its velocity pinned, so its position
        uncertainty does not grow between its reports (position sensor only).
    r_labelled : existence of a track started on a labelled report
        (``step(…, labels=)``: the report names its target, so it is real);
        < 1 so that a target that stops reporting still fades out.
    imm_modes : the modes of ``motion = "imm"``, distinct names among ``"cv"``
        (nearly constant velocity, q = ``process_noise``), ``"ct"`` (coordinated
        turn with the turn rate estimated, 2-D: acceleration noise
        ``process_noise``, turn-rate noise ``turn_rate_std``), ``"ca"``
        (constant acceleration, jerk noise ``process_noise`` in m²/s⁵) and
        ``"stationary"`` (at rest: velocity 0, the position a random walk of
        ``process_noise`` m²/s; :class:`~jointtrack.models.Stationary`); default
        ``("cv", "ct")``.
    imm_process_noise : None (default: every mode takes ``process_noise``) or one
        q ≥ 0 per mode of ``imm_modes``, in that mode's unit (cv, ct: m²/s³; ca:
        m²/s⁵; stationary: m²/s) — e.g. a moving mode's q and an at-rest mode's.
    imm_switching : the Markov switching matrix of the modes: a number p in
        (0, 1], the probability of staying in a mode from one scan (or second,
        ``imm_switching_per``) to the next (the rest shared equally among the
        other modes), or a square row-stochastic matrix, one row per mode,
        ``[i][j]`` = P(mode j | mode i before); every column needs a positive
        entry. Default 0.95.
    imm_switching_per : ``"scan"`` (default: ``imm_switching`` applies once per
        scan, whatever its interval) or ``"second"``: ``imm_switching`` is the
        one-second transition of a continuous-time chain and a scan Δt seconds
        after the previous one switches by its Δt-th power (the matrix exponential
        of Δt × its logarithm, :mod:`jointtrack.filters.imm`) — with reporting
        targets (``reporting = "async"``, a scan per report) a target switches as
        often as time says, not once per other target's report. The matrix must
        then be such a transition (positive eigenvalues, a logarithm with
        switching rates ≥ 0; two modes with stays above 1/2, or a stay p > 1/r with
        the rest shared equally, are).
    imm_initial : mode probabilities of a new track, one per mode, each > 0,
        summing to 1; None (default) = uniform.
    turn_rate_std : σ of the coordinated-turn mode's turn-rate random walk,
        rad/s per √s (its variance grows by turn_rate_std²·Δt); ≥ 0.
    max_turn_rate : largest turn rate, rad/s: a new track's turn rate starts at 0
        with σ = max_turn_rate/2 (``"ct"`` mode). Default 0.2 rad/s (11°/s).
    coalescence_avoidance : JPDA* (Blom & Bloem 2000,
        :mod:`jointtrack.association.coalescence`) for clusters of confirmed
        tracks: of the joint events that differ only by which detected track took
        which return, only the most likely is kept, so two close targets' tracks
        do not coalesce (and swap ids). Clusters with more feasible events than
        ``jointtrack.association.coalescence.JPDA_STAR_MAX_HYPOTHESES`` use
        ``association`` instead (a counted fallback, ``jpda_star_budget``).
        Default false (plain JPDA β).
    id_continuation : seconds (≥ 0; 0, the default, is off): a track confirmed
        within this long after a confirmed track was deleted (or while a confirmed
        track is losing its target) takes that track's id when its position and
        velocity lie in the χ²(0.99) gate of that track's coasted prediction and
        the pair is unambiguous — a target's track that died and was born again
        keeps one id (causal: decided when the new track confirms, before it is
        reported; the rule: :mod:`jointtrack.trackers.jpda`). ``jointtrack run --detections``
        fits it for scan files (:mod:`jointtrack.experiments.fit`).
    """

    p_g: float = 0.99
    clutter_density: float | None = None
    association: str = "exact"
    exact_max_tracks: int = 16
    exact_max_bits_tentative: int | None = 12
    approximation: str = "lbp"
    initiation: str = "one-point"
    max_speed: float = 50.0
    max_acceleration: float = 10.0
    confirm_m: int = 2
    confirm_n: int = 3
    delete_misses: int = 3
    max_position_std: float = math.inf
    existence: bool = True
    p_survive: float = 0.99
    r_init: float = 0.02
    r_confirm: float = 0.9
    r_delete: float = 0.005
    r_report: float = 0.3
    merge_threshold: float = 1.0
    tentative_association: str = "joint"
    tentative_process_noise: float = 0.0
    tentative_components: int = 4
    tentative_confirm_state: str = "moment"
    seed: int | None = 0
    miss_model: str = "1-pd*pg"
    reporting: str = "scan"
    report_interval: float = 60.0
    p_survive_per: str = "scan"
    max_coast: float = math.inf
    velocity_std: float = 1.0
    measure_velocity: bool = False
    r_labelled: float = 0.999
    imm_modes: tuple = ("cv", "ct")
    imm_switching: float | tuple = 0.95
    imm_initial: tuple | None = None
    turn_rate_std: float = 0.02
    max_turn_rate: float = 0.2
    imm_switching_per: str = "scan"
    imm_process_noise: tuple | None = None
    coalescence_avoidance: bool = False
    id_continuation: float = 0.0

    def __post_init__(self):
        for f in fields(self):
            object.__setattr__(self, f.name, check_field(f.name, getattr(self, f.name)))

        def need(cond, msg):
            if not cond:
                raise ValueError(f"TrackerConfig: {msg}")

        need(
            self.sensor == "position" or self.dim == 2,
            f"sensor: the range-bearing sensor is 2-D, but dim = {self.dim}",
        )
        object.__setattr__(
            self, "measurement_noise", _check_noise(self.measurement_noise, self.dim)
        )
        need(
            self.confirm_m <= self.confirm_n,
            f"confirm_m must be ≤ confirm_n (M-of-N), got confirm_m = {self.confirm_m} "
            f"> confirm_n = {self.confirm_n}",
        )
        need(
            self.r_delete < self.r_init,
            f"r_delete must be < r_init, got r_delete = {self.r_delete} ≥ r_init = {self.r_init}",
        )
        need(
            self.p_g < 1.0 or self.clutter_density is not None,
            "p_g = 1 (an infinite gate) needs a known clutter_density: Bojilov's "
            "heuristic (8) divides by the gate volumes, which are then infinite",
        )
        need(
            self.r_delete < self.r_report,
            f"r_report must be > r_delete, got r_report = {self.r_report} ≤ "
            f"r_delete = {self.r_delete}",
        )
        need(
            self.r_init <= self.r_confirm,
            f"r_init must be ≤ r_confirm (a new track must not start confirmed), got "
            f"r_init = {self.r_init} > r_confirm = {self.r_confirm}",
        )

        need(
            self.r_labelled > self.r_delete,
            f"r_labelled must be > r_delete, got r_labelled = {self.r_labelled} ≤ "
            f"r_delete = {self.r_delete} (every labelled track would be deleted at its "
            "next scan and restarted under a new id)",
        )

        need(
            not self.measure_velocity or self.sensor == "position",
            "measure_velocity needs the position sensor (sensor = 'position')",
        )
        self._check_noise_conditioning()
        if self.motion == "imm":  # the IMM settings are unused otherwise
            self._check_imm()
        need(
            self.existence or self.tentative_association == "joint",
            f"tentative_association = {self.tentative_association!r} needs existence = true "
            "(JIPDA): alternatives and track components are weighed by their existence",
        )
        need(
            self.tentative_association != "splitting"
            or (self.motion != "imm" and self.reporting == "scan"),
            "tentative_association = 'splitting' needs motion 'cv' or 'ca' and reporting = "
            f"'scan' (got motion = {self.motion!r}, reporting = {self.reporting!r})",
        )
        need(
            self.tentative_process_noise == 0.0
            or (self.motion != "imm" and self.reporting == "scan"),
            "tentative_process_noise > 0 needs motion 'cv' or 'ca' and reporting = 'scan' "
            f"(got motion = {self.motion!r}, reporting = {self.reporting!r})",
        )
        if self.reporting == "async":
            need(self.existence, "reporting = 'async' needs existence = true (JIPDA)")
            need(
                self.clutter_density is not None,
                "reporting = 'async' needs a clutter_density (false reports per unit area "
                "per second); Bojilov's per-scan heuristic (8) has no time base",
            )
            need(
                self.p_survive_per == "second",
                "reporting = 'async' needs p_survive_per = 'second' (a scan per report: "
                "survival per scan would depend on how often other targets report)",
            )

    def _check_imm(self) -> None:
        """The IMM settings against each other and ``dim`` (messages name the key)."""
        r = len(self.imm_modes)
        if "ct" in self.imm_modes and self.dim != 2:
            raise ValueError(
                f"TrackerConfig: imm_modes: the coordinated-turn mode 'ct' is 2-D, but dim = "
                f"{self.dim}"
            )
        try:
            M = self.imm_switching_matrix()
            if self.imm_switching_per == "second":
                from jointtrack.filters.imm import switching_generator

                switching_generator(M, "imm_switching")
        except ValueError as exc:
            rest = str(exc).removeprefix("imm_switching")
            raise ValueError(f"TrackerConfig: imm_switching{rest}") from None
        if self.imm_process_noise is not None and len(self.imm_process_noise) != r:
            raise ValueError(
                f"TrackerConfig: imm_process_noise must have one q per mode of imm_modes "
                f"({r}: {list(self.imm_modes)}), got {len(self.imm_process_noise)}"
            )
        if self.imm_initial is not None:
            from jointtrack.filters.imm import _probability_vector

            if len(self.imm_initial) != r:
                raise ValueError(
                    f"TrackerConfig: imm_initial must have one probability per mode of "
                    f"imm_modes ({r}), got {len(self.imm_initial)}"
                )
            try:
                _probability_vector(self.imm_initial, r, "imm_initial")
            except ValueError as exc:
                raise ValueError(f"TrackerConfig: {exc}") from None

    def imm_switching_matrix(self) -> np.ndarray:
        """The (r, r) switching matrix of ``imm_switching`` for the ``imm_modes``."""
        from jointtrack.filters.imm import _switching_matrix

        r = len(self.imm_modes)
        if isinstance(self.imm_switching, float):
            p = self.imm_switching
            if r == 1:
                return np.ones((1, 1))
            M = np.full((r, r), (1.0 - p) / (r - 1))
            np.fill_diagonal(M, p)
            return M
        M = np.asarray(self.imm_switching, dtype=np.float64)
        if M.shape != (r, r):
            raise ValueError(
                f"imm_switching must be a {r} × {r} matrix (one row and column per mode of "
                f"imm_modes = {list(self.imm_modes)}), got shape {M.shape}"
            )
        return _switching_matrix(M, r, "imm_switching")

    def _check_noise_conditioning(self) -> None:
        """The measurement noise covariances the tracker will filter with, as the
        filters test them (``jointtrack.filters.kalman``: Cholesky, reciprocal condition
        above m·ε): refused here, naming the settings, rather than at the first update.
        """
        from jointtrack.filters.kalman import _chol_pd

        d = self.dim
        if self.sensor == "range-bearing":
            matrices = [
                ("range_noise and bearing_noise", np.diag([self.range_noise, self.bearing_noise]))
            ]
        else:
            matrices = [("measurement_noise", self.measurement_covariance())]
            if self.measure_velocity:  # z = [p, v]: R = diag(R_position, velocity_std² I)
                R = np.zeros((2 * d, 2 * d))
                R[:d, :d] = matrices[0][1]
                R[d:, d:] = self.velocity_std**2 * np.eye(d)
                matrices.append(("measurement_noise and velocity_std (measure_velocity)", R))
        for names, R in matrices:
            try:
                _chol_pd(R[None], "R", False)
            except ValueError as exc:
                problem = str(exc).removeprefix("R ")
                raise ValueError(
                    f"TrackerConfig: {names}: the measurement noise covariance {problem}; "
                    "the filters need its variances within ~1e15 of each other"
                ) from None

    def measurement_covariance(self) -> np.ndarray:
        """R of the position sensor as a (dim, dim) array (from ``measurement_noise``)."""
        R = np.asarray(self.measurement_noise, dtype=np.float64)
        if R.ndim == 0:
            return float(R) * np.eye(self.dim)
        if R.ndim == 1:
            return np.diag(R)
        return R.copy()

    @classmethod
    def from_dict(cls, d: dict, *, complete: bool = False) -> TrackerConfig:
        """Build from a (TOML) mapping; unknown keys are an error naming them.

        Missing keys take their defaults, unless ``complete=True`` (a saved
        configuration, e.g. :meth:`JPDATracker.load`): then they are an error.
        """
        return config_from_dict(cls, d, "tracker", complete=complete)

    def to_dict(self) -> dict:
        return asdict(self)

    def detection_in_gate(self, p_d: float | None = None) -> float:
        """The P_D·P_G or P_D that the miss weight subtracts (see ``miss_model``).

        ``p_d``: a sensor's own detection probability (default: this config's).
        """
        p_d = self.p_d if p_d is None else p_d
        return p_d * self.p_g if self.miss_model == "1-pd*pg" else p_d


# ----------------------------------------------------------------------------- field checks


def _fail(name: str, want: str, value) -> ValueError:
    return ValueError(f"TrackerConfig: {name} must be {want}, got {value!r}")


def _real(name: str, v, want: str) -> float:
    """A real number (not a bool, not NaN) as float."""
    if isinstance(v, bool | np.bool_) or not isinstance(v, numbers.Real):
        raise _fail(name, want, v)
    try:
        v = float(v)
    except OverflowError:  # an int beyond the float range
        raise _fail(name, want, f"an integer of {len(str(v))} digits") from None
    if math.isnan(v):
        raise _fail(name, want, v)
    return v


def _int(name: str, v, want: str) -> int:
    if isinstance(v, bool | np.bool_) or not isinstance(v, numbers.Integral):
        raise _fail(name, want, v)
    return int(v)


def _positive(name, v):
    want = "a positive finite number"
    v = _real(name, v, want)
    if not (math.isfinite(v) and v > 0):
        raise _fail(name, want, v)
    return v


def _bounded(limit: float, why: str):
    """A positive finite number ≤ ``limit``; beyond it the message says ``why``."""

    def check(name, v):
        v = _positive(name, v)
        if v > limit:
            raise _fail(
                name,
                f"a positive finite number ≤ {limit:g} ({why}; beyond it float64 overflows)",
                v,
            )
        return v

    return check


_std = _bounded(MAX_STD, "it is squared into the tracks' covariances")
_variance = _bounded(
    MAX_VARIANCE, "it enters the tracks' covariances, which are added and multiplied"
)


def _non_negative(name, v):
    want = "a finite number ≥ 0"
    v = _real(name, v, want)
    if not (math.isfinite(v) and v >= 0):
        raise _fail(name, want, v)
    return v


def _probability(name, v):
    want = "a number in (0, 1]"
    v = _real(name, v, want)
    if not 0 < v <= 1:
        raise _fail(name, want, v)
    return v


def _open_probability(name, v):
    want = "a number in (0, 1)"
    v = _real(name, v, want)
    if not 0 < v < 1:
        raise _fail(name, want, v)
    return v


def _choice(options):
    def check(name, v):
        if not isinstance(v, str) or v not in options:
            raise _fail(name, "one of " + ", ".join(repr(o) for o in options), v)
        return v

    return check


def _int_range(lo, hi=None):
    def check(name, v):
        want = f"an integer ≥ {lo}" if hi is None else f"an integer in [{lo}, {hi}]"
        v = _int(name, v, want)
        if v < lo or (hi is not None and v > hi):
            raise _fail(name, want, v)
        return v

    return check


def _dim(name, v):
    want = "2 or 3"
    v = _int(name, v, want)
    if v not in (2, 3):
        raise _fail(name, want, v)
    return v


def _sensor_position(name, v):
    want = "a pair of finite numbers (x, y)"
    if isinstance(v, str | bytes) or not hasattr(v, "__len__") or len(v) != 2:
        raise _fail(name, want, v)
    try:
        out = tuple(_real(name, a, want) for a in v)
    except ValueError:
        raise _fail(name, want, v) from None
    if not all(map(math.isfinite, out)):
        raise _fail(name, want, v)
    return out


def _clutter(name, v):
    if v is None:
        return None
    want = 'a positive finite number (or None / "estimate" in TOML)'
    v = _real(name, v, want)
    if not (math.isfinite(v) and v > 0):
        raise _fail(name, want, v)
    return v


def _positive_or_inf(name, v):
    want = "a positive number (inf allowed)"
    v = _real(name, v, want)
    if not v > 0:
        raise _fail(name, want, v)
    return v


def _bool(name, v):
    if not isinstance(v, bool | np.bool_):
        raise _fail(name, "true or false (a bool)", v)
    return bool(v)


def _seed(name, v):
    if v is None:
        return None
    want = "an integer ≥ 0 or None"
    v = _int(name, v, want)
    if v < 0:
        raise _fail(name, want, v)
    return v


def _bits_or_none(name, v):
    """A frontier-width budget in bits: None, or an integer in [0, 30] (2^30 states is
    the exact engine's own default limit, ``jointtrack.assignment.core.DEFAULT_MAX_BITS``)."""
    if v is None:
        return None
    return _int_range(0, 30)(name, v)


def _association(name, v):
    from jointtrack.association.core import METHODS

    return _choice(tuple(METHODS))(name, v)


def _noise_shape(name, v):
    """measurement_noise without knowing dim: a positive number, or a (nested)
    sequence of finite numbers, as a float or tuple (of tuples)."""
    want = (
        "a positive number σ², a list of per-axis σ² (length dim) or a dim × dim "
        "covariance (list of lists)"
    )
    if isinstance(v, np.ndarray):
        v = v.tolist()
    if isinstance(v, list | tuple):
        if not v:
            raise _fail(name, want, v)
        if all(isinstance(r, list | tuple | np.ndarray) for r in v):
            rows = [list(r) for r in v]
            if any(len(r) != len(rows) for r in rows):
                raise _fail(name, want + " (a square matrix)", v)
            return tuple(tuple(_real(name, a, want) for a in r) for r in rows)
        return tuple(_real(name, a, want) for a in v)
    return _real(name, v, want)


def _check_noise(v, dim: int):
    """measurement_noise against ``dim``: σ² > 0, per-axis σ² > 0, or an SPD matrix."""
    name = "measurement_noise"
    if isinstance(v, float):
        if not (math.isfinite(v) and v > 0):
            raise _fail(name, "positive and finite (σ²)", v)
        return _variance(name, v)
    a = np.asarray(v, dtype=np.float64)
    if not np.all(np.isfinite(a)):
        raise _fail(name, "finite", v)
    if np.abs(a).max() > MAX_VARIANCE:
        raise _fail(
            name,
            f"a covariance with entries ≤ {MAX_VARIANCE:g} in magnitude (it is added and "
            "multiplied in the filter; beyond that float64 overflows)",
            v,
        )
    if a.ndim == 1:
        if a.size != dim:
            raise _fail(name, f"a number or a list of {dim} per-axis variances (dim = {dim})", v)
        if np.any(a <= 0):
            raise _fail(name, "positive in every axis (per-axis σ²)", v)
        return v
    if a.shape != (dim, dim):
        raise _fail(name, f"a {dim} × {dim} covariance matrix (dim = {dim})", v)
    if not np.allclose(a, a.T, rtol=1e-12, atol=0.0):
        raise _fail(name, "a symmetric covariance matrix", v)
    try:
        np.linalg.cholesky(a)
    except np.linalg.LinAlgError:
        raise _fail(name, "a positive definite covariance matrix", v) from None
    return v


#: Modes of ``motion = "imm"`` (``TrackerConfig.imm_modes``).
IMM_MODES = ("cv", "ct", "ca", "stationary")


def _imm_modes(name, v):
    want = f"a non-empty list of distinct mode names among {', '.join(map(repr, IMM_MODES))}"
    if isinstance(v, str | bytes) or not isinstance(v, list | tuple) or not v:
        raise _fail(name, want, v)
    for m in v:
        if not isinstance(m, str) or m not in IMM_MODES:
            raise ValueError(
                f"TrackerConfig: {name}: unknown mode name {m!r} (known: "
                f"{', '.join(map(repr, IMM_MODES))})"
            )
    if len(set(v)) != len(v):
        raise _fail(name, want + " (each at most once)", v)
    return tuple(v)


def _imm_switching(name, v):
    """A stay probability in (0, 1] or a square matrix of numbers in [0, 1] (rows are
    checked against imm_modes by TrackerConfig)."""
    want = "a stay probability in (0, 1] or a square row-stochastic matrix (list of lists)"
    if isinstance(v, np.ndarray):
        v = v.tolist()
    if isinstance(v, list | tuple):
        if not v or not all(isinstance(r, list | tuple) and len(r) == len(v) for r in v):
            raise _fail(name, want, v)
        rows = tuple(tuple(_real(name, a, want) for a in r) for r in v)
        if not all(0.0 <= a <= 1.0 for r in rows for a in r):
            raise _fail(name, want + " with entries in [0, 1]", v)
        return rows
    return _probability(name, v)


def _per_mode_list(name, v, want: str):
    """``v`` as a non-empty list (an array is one) of per-mode values, else the error."""
    if isinstance(v, np.ndarray):
        v = v.tolist()
    if isinstance(v, str | bytes) or not isinstance(v, list | tuple) or not v:
        raise _fail(name, want, v)
    return v


def _imm_initial(name, v):
    if v is None:
        return None
    want = "None or a list of mode probabilities > 0 (one per mode) summing to 1"
    out = tuple(_real(name, a, want) for a in _per_mode_list(name, v, want))
    if not all(math.isfinite(a) and a > 0 for a in out):
        raise _fail(name, want + " (a mode of probability 0 could never be entered)", v)
    return out


def _imm_process_noise(name, v):
    if v is None:
        return None
    want = "None or a list of process noise intensities q ≥ 0, one per mode of imm_modes"
    return tuple(_variance(name, a) for a in _per_mode_list(name, v, want))


_CHECKS = {
    "dim": _dim,
    "motion": _choice(("cv", "ca", "imm")),
    "process_noise": _variance,
    "measurement_noise": _noise_shape,
    "sensor": _choice(("position", "range-bearing")),
    "sensor_position": _sensor_position,
    "range_noise": _variance,
    "bearing_noise": _variance,
    "p_d": _probability,
    "p_g": _probability,
    "clutter_density": _clutter,
    "association": _association,
    "exact_max_tracks": _int_range(1),
    "exact_max_bits_tentative": _bits_or_none,
    "approximation": _choice(("lbp", "mcmc", "kbest", "pda")),
    "initiation": _choice(("two-point", "one-point")),
    "max_speed": _std,
    "max_acceleration": _std,
    "confirm_m": _int_range(1, 30),
    "confirm_n": _int_range(1, 30),
    "delete_misses": _int_range(1),
    "max_position_std": _positive_or_inf,
    "existence": _bool,
    "p_survive": _probability,
    "r_init": _open_probability,
    "r_confirm": _probability,
    "r_delete": _open_probability,
    "r_report": _probability,
    "merge_threshold": _non_negative,
    "tentative_association": _choice(TENTATIVE_ASSOCIATIONS),
    "tentative_process_noise": _non_negative,
    "tentative_components": _int_range(1, 256),
    "tentative_confirm_state": _choice(TENTATIVE_CONFIRM_STATES),
    "seed": _seed,
    "miss_model": _choice(MISS_MODELS),
    "reporting": _choice(REPORTING),
    "report_interval": _positive,
    "p_survive_per": _choice(("scan", "second")),
    "max_coast": _positive_or_inf,
    "velocity_std": _std,
    "measure_velocity": _bool,
    "r_labelled": _open_probability,
    "imm_modes": _imm_modes,
    "imm_switching": _imm_switching,
    "imm_initial": _imm_initial,
    "turn_rate_std": _non_negative,
    "max_turn_rate": _positive,
    "imm_switching_per": _choice(("scan", "second")),
    "imm_process_noise": _imm_process_noise,
    "coalescence_avoidance": _bool,
    "id_continuation": _non_negative,
}


def check_field(name: str, value):
    """Check one :class:`TrackerConfig` field on its own (type and range).

    Returns the value normalised (numbers as float/int, sequences as tuples);
    raises ValueError naming the field. Cross-field rules (``confirm_m ≤
    confirm_n``, ``r_delete < r_init ≤ r_confirm``, the length of a per-axis
    ``measurement_noise``) need the whole config and are checked by
    :class:`TrackerConfig`.
    """
    if name not in _CHECKS:
        raise ValueError(f"TrackerConfig: unknown field {name!r}")
    return _CHECKS[name](name, value)
