"""Configuration of the PMB and PMBM trackers: one frozen dataclass of plain numbers.

The motion, sensor and association fields mean exactly what they mean in
:class:`~jointtrack.trackers.config.TrackerConfig` (and are checked by the same
field checks); the rest describe the Poisson intensity of undetected targets,
the pruning and capping of the mixture, and the estimator. See
:mod:`jointtrack.trackers.pmbm` for the filters.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import asdict, dataclass

import numpy as np

from jointtrack.trackers.config import (
    ModelSettings,
    TrackerConfig,
    check_field,
    config_from_dict,
)
from jointtrack.trackers.config import _non_negative as config_non_negative
from jointtrack.trackers.config import _positive as config_positive

__all__ = ["BIRTH_MODELS", "ESTIMATORS", "PMBMConfig"]

#: PMBM estimators: estimator 1, or a track's existence over all global hypotheses.
ESTIMATORS = ("best", "track")

#: PMBM: which existence of a never-reported track is compared with r_recycle.
RECYCLE_EXISTENCES = ("least", "marginal")

#: Kinds of birth (and prior) intensity of undetected targets.
BIRTH_MODELS = ("uniform", "gaussian")

#: Settings added after PMBM state files were first written → the value under which an
#: older state's run continues exactly as before (no ranking budget).
_ADDED_SETTINGS = {
    "max_ranking_work": None,
    # issue 33: the PMB state update kept apart by the most probable event; before, merged
    "keep_apart": False,
    "duplicate_distance": 0.0,
    "birth_per_return": 0.0,
    "estimator": "best",
    "recycle_existence": "least",
    # reporting targets (issue 32): a scanning sensor, survival per scan, as before
    "reporting": "scan",
    "report_interval": 60.0,
    "p_survive_per": "scan",
    "velocity_std": 1.0,
    "r_labelled": 0.999,
    # the interacting multiple model (issue 32; unused by the CV/CA runs of older states)
    "imm_modes": ("cv", "ct"),
    "imm_switching": 0.95,
    "imm_initial": None,
    "turn_rate_std": 0.02,
    "max_turn_rate": 0.2,
    # switching per second and per-mode q (issue 32): per scan, one q, as before
    "imm_switching_per": "scan",
    "imm_process_noise": None,
}

#: The settings of issue 33 (PMB/PMBM from nothing): a state saved before them
#: continues with the values in _ADDED_SETTINGS.
ISSUE_33_SETTINGS = (
    "keep_apart",
    "duplicate_distance",
    "birth_per_return",
    "estimator",
    "recycle_existence",
)

#: Fields shared with TrackerConfig, checked by its field checks.
_SHARED = (
    "dim",
    "motion",
    "process_noise",
    "measurement_noise",
    "sensor",
    "sensor_position",
    "range_noise",
    "bearing_noise",
    "p_d",
    "p_g",
    "association",
    "exact_max_tracks",
    "approximation",
    "max_speed",
    "max_acceleration",
    "p_survive",
    "seed",
    "reporting",
    "report_interval",
    "p_survive_per",
    "velocity_std",
    "r_labelled",
    "imm_modes",
    "imm_switching",
    "imm_initial",
    "turn_rate_std",
    "max_turn_rate",
    "imm_switching_per",
    "imm_process_noise",
)


@dataclass(frozen=True)
class PMBMConfig(ModelSettings):
    """Everything that defines a PMB or PMBM tracker; plain numbers, TOML-friendly.

    Attributes
    ----------
    dim, motion, process_noise, measurement_noise, sensor, sensor_position,
    range_noise, bearing_noise, p_d, p_survive, association, exact_max_tracks,
    approximation, seed, reporting, report_interval, p_survive_per, velocity_std,
    r_labelled, imm_modes, imm_switching, imm_initial, turn_rate_std, max_turn_rate,
    imm_switching_per, imm_process_noise :
        as in :class:`~jointtrack.trackers.config.TrackerConfig` (and checked by it).
        ``motion = "imm"``: each Bernoulli (PMBM: each single-target hypothesis)
        carries the modes' states and probabilities of
        :mod:`jointtrack.filters.imm`; the Poisson intensity of undetected targets
        moves with the CV model (a birth density, not a track: its first detection
        starts a Bernoulli with ``imm_initial``). With
        ``reporting = "async"`` (targets that report themselves one at a time:
        AIS, ADS-B; it needs ``p_survive_per = "second"``) each Bernoulli is
        detected with its own P_D,i over the interval since the previous scan
        (:func:`~jointtrack.trackers.reporting.scan_detection`), an undetected
        target reports at the rate p_d/``report_interval``, and
        ``clutter_density`` and ``birth_density`` are per second.
        ``velocity_std``: σ of the reported velocities that seed new
        Bernoullis (``step(…, velocities=)``); ``r_labelled``: existence of a
        Bernoulli detected by a labelled report (``step(…, labels=)``).
    p_g : gate probability P_G of the chi-square gates (default 0.9999: the
        Poisson multi-Bernoulli weights have no gate factor, so the gate only
        cuts pairs whose weight is negligible; 1 = no gating).
    clutter_density : λ_c, false returns per unit measurement volume per scan
        (must be known: the Poisson/clutter split of every return depends on it).
    birth_model : ``"uniform"`` (default) — new targets appear uniformly in
        position (``birth_region``, or anywhere when it is None) at
        ``birth_density`` per unit area (volume) per scan, with zero-mean
        Gaussian velocity of per-axis σ = ``max_speed``/2 (acceleration σ =
        ``max_acceleration``/2 for ``motion = "ca"``); or ``"gaussian"`` — a
        Gaussian mixture ``birth_weights``, ``birth_means``, ``birth_covs`` in
        the state layout of the motion model (positions, then velocities).
    birth_density : uniform births per unit area (volume) per scan (per second
        with ``reporting = "async"``).
    birth_region : None (unbounded) or ``((xmin, xmax), (ymin, ymax)[, (zmin, zmax)])``.
    birth_per_return : measurement-driven (adaptive) birth, in [0, 1): each
        unlabelled return adds to the undetected intensity of the next scan a
        Gaussian at its position (zero-mean velocity of per-axis σ =
        ``max_speed``/2) of weight birth_per_return × the probability that no
        prior Bernoulli took it (Ristic et al. 2012; as the JIPDA tracker's
        per-return initiation, ``r_init``). A target lost, or appearing where the
        uniform density is thin, is then found from its own returns as fast as
        JIPDA finds one. Default 0 (births only from ``birth_model``);
        :func:`~jointtrack.experiments.config.make_pmbm_config` sets it for scenes
        and files with no birth model known.
    prior_density : undetected targets per unit area at the first scan
        (uniform model; None = the steady state of birth, survival and
        missed detection, birth_density / (1 − P_S (1 − P_D))).
    birth_weights, birth_means, birth_covs : the Gaussian birth mixture.
    prior_weight : λ₀, the expected number of undetected targets at the first
        scan (Gaussian model), with the birth mixture's normalised density.
    poisson_prune : Gaussian components of the undetected intensity with a
        weight below this are dropped.
    poisson_merge : components closer than this squared Mahalanobis distance
        are merged (moment matching; 0 = never).
    max_poisson_components : cap on the Gaussian components kept (largest first).
    r_prune : Bernoulli components with existence below this are dropped.
    r_recycle : Bernoullis (PMBM: tracks in every global hypothesis) with
        existence below this that were never reported are *recycled*: moved
        into the Poisson intensity as Gaussian components of weight r
        (Williams 2012; 0 = never). A
        clutter-born Bernoulli then costs no association work, and a real
        target's evidence is kept in the intensity until it is strong. A
        Bernoulli once reported is never recycled (it keeps its id through
        missed detections until its existence falls below ``r_prune``).
    recycle_existence : PMBM: which existence of a never-reported track is
        compared with ``r_recycle`` — ``"least"`` (default): its existence in
        every global hypothesis holding it; ``"marginal"``: its existence over
        the global hypotheses, Σ_h w_h r_h (the one the intensity receives).
        Why: from nothing in dense clutter, a target's early evidence is spread
        over hundreds of global hypotheses (in each, one of its returns detected
        the track: r = 1 there), so no tentative track is ever below
        ``r_recycle`` in all of them; the hypotheses fill the cap with
        alternatives of that evidence, the most probable holds ~5 % of the weight
        and estimator 1 misses the target. Recycled by its marginal, the evidence
        is kept in one Gaussian of the intensity, as PMB keeps it in one
        Bernoulli, and the track returns when a return makes it likely (Williams
        2012). Measured (``benchmarks/RESULTS.md``, "Issue 33, PMBM re-acquisition"):
        with ``r_recycle = 0.3`` the headline scene from nothing improves in
        GOSPA and coverage but its id switches rise, so it is an option, not the
        default. PMB is unaffected (one Bernoulli per track: the two are equal).
        A state saved before this setting existed loads with ``"least"``.
    keep_apart : PMB (and PMBM clusters merged past the ranking budget): each
        Bernoulli's *state* is updated by its association probabilities without the
        returns that the most probable association event gives to another Bernoulli
        (its other pairs take their weight in proportion); the existences stay the
        exact marginals. Without it (False) two Bernoullis of targets closer than the
        measurement noise both merge to the middle and their estimates hop between
        the lanes (the coalescence of JPDA; Blom & Bloem 2000). Default True; a
        state saved before this setting existed loads with False.
    duplicate_distance : PMB: Bernoullis whose means (position and velocity)
        differ by a squared Mahalanobis distance at most this (in the sum of their
        covariances) are one target's and are merged after each update — the one
        reported first (else the oldest) keeps its id, with existence
        1 − Π(1 − r) and the moment-matched state (0 = never). Why: a target's
        returns start a Bernoulli while the Poisson intensity still holds its
        recycled evidence, so one target gets two or three Bernoullis of existence
        ≈ 0.5 that split its returns and are both reported. Default 1.0 (two
        distinct targets' states are far further apart once their velocities are
        known); a state saved before this setting existed loads with 0.
    r_estimate : Bernoullis reported as targets have existence ≥ this
        (PMBM: as ``estimator`` says).
    estimator : PMBM estimate: ``"best"`` (default) — estimator 1 of
        García-Fernández et al. 2018 (§VI-A), the Bernoullis of the most probable
        global hypothesis with r ≥ ``r_estimate``, whose tracks come and go as that
        hypothesis changes between near-equal ones in a cluster of close targets;
        or ``"track"`` — each track (a Bernoulli's lineage: its id from the return
        that started it) whose existence summed over the global hypotheses,
        Σ_h w_h r_h, is ≥ ``r_estimate``, at its state in the most probable
        hypothesis holding it (alternatives for one target within
        ``duplicate_distance`` reported once). Measured (``benchmarks/RESULTS.md``,
        "Issue 33"): ``"track"`` cuts the headline scene's id switches from nothing
        (12.2 → 9.0 per run) at equal GOSPA, but costs the coalescence scene 11 %
        (2.31 → 2.57), so it is not the default.
    max_hypotheses : PMBM cap on global hypotheses (the k of Murty's algorithm
        is ⌈max_hypotheses · w_h⌉ for a prior hypothesis of weight w_h).
    hypothesis_prune : PMBM global hypotheses with a normalised weight below
        this are dropped (the most probable ones are always kept: a scan never
        ends with no hypothesis).
    max_ranking_work : PMBM work budget of one cluster's association (None =
        no budget), in cost-matrix cells: the ranking of the cluster's
        ⌈max_hypotheses · w_h⌉ best events by Murty's algorithm is estimated
        before any work as Σ (1 + (k − 1) n) · n · (n + m) + 2^14 over the
        cluster's distinct single-target-hypothesis tuples (n Bernoullis, m
        returns, k events, at most the tuple's number of events; a tuple of
        one Bernoulli counts its gated pairs; 2^14 is the set-up of a tuple).
        Past it the cluster gets the most events per hypothesis that fit
        (method ``"murty-truncated"``), and when not even two fit it is merged
        into one Bernoulli per track, PMB style, its marginals from the
        package's association tiers with the sparse LBP within this many
        message updates (method ``"pmb-<tier>"``). Each such cluster is
        named in ``ScanResult.cluster_methods`` / ``cluster_fallbacks``, counted
        in ``fallback_counts`` and logged. The default 2^25 is about half a
        second of ranking (measured 8–26 ns per cell, 0.24 ms per tuple) and
        keeps a 2,000-return clutter burst at ~8 s CPU per scan; the clusters of
        the built-in scenes are estimated at ≤ 3.5·10⁶ (≤ 1.7·10⁷ with
        ``max_hypotheses = 1000``) and ranked in full (``benchmarks/pmbm_burst.py``,
        ``benchmarks/RESULTS.md``, "Issue 31"). A state saved before this
        setting existed loads with None: its run continues exactly as before.

    Every field is checked on construction; a bad value raises ValueError
    naming the field.
    """

    p_g: float = 0.9999
    p_survive: float = 0.99
    clutter_density: float = 1e-4
    association: str = "exact"
    exact_max_tracks: int = 16
    approximation: str = "lbp"
    max_speed: float = 50.0
    max_acceleration: float = 10.0
    birth_model: str = "uniform"
    birth_density: float = 1e-7
    birth_region: tuple | None = None
    prior_density: float | None = None
    birth_per_return: float = 0.0
    birth_weights: tuple = ()
    birth_means: tuple = ()
    birth_covs: tuple = ()
    prior_weight: float = 0.0
    poisson_prune: float = 1e-5
    poisson_merge: float = 4.0
    max_poisson_components: int = 100
    r_prune: float = 1e-5
    r_recycle: float = 0.1
    recycle_existence: str = "least"
    keep_apart: bool = True
    duplicate_distance: float = 1.0
    r_estimate: float = 0.4
    estimator: str = "best"
    max_hypotheses: int = 200
    hypothesis_prune: float = 1e-4
    max_ranking_work: int | None = 2**25
    seed: int | None = 0
    reporting: str = "scan"
    report_interval: float = 60.0
    p_survive_per: str = "scan"
    velocity_std: float = 1.0
    r_labelled: float = 0.999
    imm_modes: tuple = ("cv", "ct")
    imm_switching: float | tuple = 0.95
    imm_initial: tuple | None = None
    turn_rate_std: float = 0.02
    max_turn_rate: float = 0.2
    imm_switching_per: str = "scan"
    imm_process_noise: tuple | None = None

    def __post_init__(self):
        for name in _SHARED:
            object.__setattr__(self, name, _checked(check_field, name, getattr(self, name)))
        try:
            noise = TrackerConfig(dim=self.dim, measurement_noise=self.measurement_noise)
        except ValueError as exc:
            raise ValueError(str(exc).replace("TrackerConfig:", "PMBMConfig:")) from None
        object.__setattr__(self, "measurement_noise", noise.measurement_noise)
        if self.motion == "imm":  # the IMM settings against each other, as TrackerConfig's
            try:
                self._jpda_twin()
            except ValueError as exc:
                raise ValueError(str(exc).replace("TrackerConfig:", "PMBMConfig:")) from None
        if self.reporting == "async" and self.p_survive_per != "second":
            raise _fail(
                "p_survive_per",
                "'second' with reporting = 'async' (a scan per report: survival per scan "
                "would depend on how often other targets report)",
                self.p_survive_per,
            )
        if self.sensor != "position" and self.dim != 2:
            raise _fail("sensor", "'position' in 3-D (range-bearing is 2-D)", self.sensor)
        set_ = object.__setattr__
        set_(self, "clutter_density", _positive("clutter_density", self.clutter_density))
        if self.birth_model not in BIRTH_MODELS:
            raise _fail("birth_model", " or ".join(map(repr, BIRTH_MODELS)), self.birth_model)
        set_(self, "birth_density", _non_negative("birth_density", self.birth_density))
        set_(self, "birth_region", _region(self.birth_region, self.dim))
        if self.prior_density is not None:
            set_(self, "prior_density", _non_negative("prior_density", self.prior_density))
        set_(self, "prior_weight", _non_negative("prior_weight", self.prior_weight))
        self._check_gaussian_birth()
        for name in (
            "poisson_prune",
            "r_prune",
            "r_recycle",
            "hypothesis_prune",
            "birth_per_return",
        ):
            v = _non_negative(name, getattr(self, name))
            if v >= 1:
                raise _fail(name, "a number in [0, 1)", v)
            set_(self, name, v)
        set_(self, "poisson_merge", _non_negative("poisson_merge", self.poisson_merge))
        set_(
            self,
            "duplicate_distance",
            _non_negative("duplicate_distance", self.duplicate_distance),
        )
        for name in ("max_poisson_components", "max_hypotheses"):
            set_(self, name, _count(name, getattr(self, name)))
        if self.max_ranking_work is not None:
            set_(self, "max_ranking_work", _work("max_ranking_work", self.max_ranking_work))
        if self.estimator not in ESTIMATORS:
            raise _fail("estimator", " or ".join(map(repr, ESTIMATORS)), self.estimator)
        # a str first: `in` on an array or other unhashable value would not name the field
        if not isinstance(self.recycle_existence, str) or (
            self.recycle_existence not in RECYCLE_EXISTENCES
        ):
            want = " or ".join(map(repr, RECYCLE_EXISTENCES))
            raise _fail("recycle_existence", want, self.recycle_existence)
        if not isinstance(self.keep_apart, bool | np.bool_):
            raise _fail("keep_apart", "true or false", self.keep_apart)
        set_(self, "keep_apart", bool(self.keep_apart))
        r = _non_negative("r_estimate", self.r_estimate)
        if not 0 < r <= 1:
            raise _fail("r_estimate", "a number in (0, 1]", r)
        set_(self, "r_estimate", r)

    def _check_gaussian_birth(self) -> None:
        n = (3 if self.motion == "ca" else 2) * self.dim
        w, m, P = self.birth_weights, self.birth_means, self.birth_covs
        for name, v in (("birth_weights", w), ("birth_means", m), ("birth_covs", P)):
            if isinstance(v, str | bytes) or not isinstance(v, list | tuple | np.ndarray):
                raise _fail(name, "a list", v)
        wa = _real_array("birth_weights", w).reshape(-1)
        ma = _real_array("birth_means", m)
        Pa = _real_array("birth_covs", P)
        k = len(wa)
        if self.birth_model == "gaussian" and k == 0:
            raise _fail("birth_weights", "at least one component for birth_model 'gaussian'", w)
        if k == 0 and ma.size == 0 and Pa.size == 0:
            ma, Pa = ma.reshape(0, n), Pa.reshape(0, n, n)
        state = f"(one per weight; the state is {n}-D for motion {self.motion!r} in {self.dim}-D)"
        if ma.shape != (k, n):
            raise _fail("birth_means", f"{k} means of length {n} {state}", np.shape(m))
        if Pa.shape != (k, n, n):
            raise _fail("birth_covs", f"{k} covariances {n} × {n} {state}", np.shape(P))
        for name, a in (("birth_weights", wa), ("birth_means", ma), ("birth_covs", Pa)):
            if not np.isfinite(a).all() or a.dtype.kind != "f":
                raise _fail(name, "finite numbers", a.tolist())
        if (wa < 0).any():
            raise _fail("birth_weights", "non-negative", w)
        for i, C in enumerate(Pa):
            if not np.allclose(C, C.T, rtol=1e-12, atol=0.0):
                raise _fail("birth_covs", f"symmetric (component {i})", C.tolist())
            try:
                np.linalg.cholesky(C)
            except np.linalg.LinAlgError:
                raise _fail(
                    "birth_covs", f"positive definite (component {i})", C.tolist()
                ) from None
        set_ = object.__setattr__
        set_(self, "birth_weights", tuple(float(v) for v in wa))
        set_(self, "birth_means", tuple(tuple(float(v) for v in row) for row in ma))
        set_(self, "birth_covs", tuple(tuple(tuple(float(v) for v in r) for r in C) for C in Pa))

    def _jpda_twin(self) -> TrackerConfig:
        """The TrackerConfig of this configuration's motion (its IMM checks and matrices)."""
        return TrackerConfig(
            dim=self.dim,
            motion=self.motion,
            process_noise=self.process_noise,
            imm_modes=self.imm_modes,
            imm_switching=self.imm_switching,
            imm_initial=self.imm_initial,
            turn_rate_std=self.turn_rate_std,
            max_turn_rate=self.max_turn_rate,
            imm_switching_per=self.imm_switching_per,
            imm_process_noise=self.imm_process_noise,
        )

    def imm_switching_matrix(self) -> np.ndarray:
        """The (r, r) switching matrix of ``imm_switching`` for the ``imm_modes``."""
        return self._jpda_twin().imm_switching_matrix()

    def measurement_covariance(self) -> np.ndarray:
        """R of the position sensor as a (dim, dim) array (from ``measurement_noise``)."""
        return TrackerConfig(
            dim=self.dim, measurement_noise=self.measurement_noise
        ).measurement_covariance()

    @classmethod
    def from_dict(cls, d: dict, *, complete: bool = False) -> PMBMConfig:
        """Build from a (TOML) mapping; unknown keys are an error naming them.

        Missing keys take their defaults, unless ``complete=True`` (a saved
        configuration): then they are an error — except the settings added
        after a state file could have been written, which get the value under
        which its run continues exactly as before (``max_ranking_work``: None).
        """
        if complete and isinstance(d, dict):
            d = {**_ADDED_SETTINGS, **d}
        return config_from_dict(cls, d, "PMBM tracker", complete=complete)

    @classmethod
    def from_tracker_config(cls, cfg: TrackerConfig, **overrides) -> PMBMConfig:
        """The shared motion, sensor and association settings of a :class:`TrackerConfig`.

        ``cfg.clutter_density`` must be known (or given in ``overrides``).
        """
        shared = {name: getattr(cfg, name) for name in _SHARED}
        if cfg.clutter_density is not None:
            shared["clutter_density"] = cfg.clutter_density
        shared.update(overrides)
        return cls(**shared)

    def to_dict(self) -> dict:
        return asdict(self)


def _fail(name: str, want: str, value) -> ValueError:
    return ValueError(f"PMBMConfig: {name} must be {want}, got {value!r}")


def _number(name: str, v, want: str) -> float:
    if isinstance(v, bool | np.bool_) or not isinstance(v, numbers.Real):
        raise _fail(name, want, v)
    try:
        v = float(v)
    except OverflowError:
        raise _fail(name, want, v) from None
    if not math.isfinite(v):
        raise _fail(name, want, v)
    return v


def _real_array(name: str, v) -> np.ndarray:
    """``v`` as a float64 array of real numbers; bools, complex, strings, ragged
    lists and ints beyond the float range raise ValueError naming ``name``."""
    want = "a (nested) list of real numbers"
    try:
        a = np.asarray(v, dtype=object)
    except ValueError:  # ragged nesting numpy cannot even hold as objects
        raise _fail(name, want, v) from None
    for x in a.reshape(-1):
        if isinstance(x, bool | np.bool_) or not isinstance(x, numbers.Real):
            raise _fail(name, want, v)
    try:
        return a.astype(np.float64)
    except (TypeError, ValueError, OverflowError):
        raise _fail(name, want, v) from None


def _checked(check, name: str, v):
    """``check(name, v)`` of :mod:`jointtrack.trackers.config`, its errors naming PMBMConfig."""
    try:
        return check(name, v)
    except ValueError as exc:
        raise ValueError(str(exc).replace("TrackerConfig:", "PMBMConfig:")) from None


def _positive(name: str, v) -> float:
    return _checked(config_positive, name, v)


def _non_negative(name: str, v) -> float:
    return _checked(config_non_negative, name, v)


def _count(name: str, v) -> int:
    if isinstance(v, bool | np.bool_) or not isinstance(v, numbers.Integral) or not 1 <= v <= 10**6:
        raise _fail(name, "an integer in [1, 1000000]", v)
    return int(v)


def _work(name: str, v) -> int:
    if isinstance(v, bool | np.bool_) or not isinstance(v, numbers.Integral) or not 1 <= v <= 2**62:
        raise _fail(name, "None or an integer in [1, 2**62]", v)
    return int(v)


def _region(v, dim: int):
    if v is None:
        return None
    want = f"None or {dim} (min, max) pairs with min < max"
    if isinstance(v, str | bytes) or not isinstance(v, list | tuple | np.ndarray) or len(v) != dim:
        raise _fail("birth_region", want, v)
    out = []
    for pair in v:
        if isinstance(pair, str | bytes) or not isinstance(pair, list | tuple | np.ndarray):
            raise _fail("birth_region", want, v)
        if len(pair) != 2:
            raise _fail("birth_region", want, v)
        lo, hi = (_number("birth_region", a, want) for a in pair)
        if not lo < hi:
            raise _fail("birth_region", want, v)
        out.append((lo, hi))
    return tuple(out)
