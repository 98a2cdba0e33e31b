"""PMB and PMBM trackers: Poisson birth, multi-Bernoulli tracks, global hypotheses.

The Poisson multi-Bernoulli mixture (PMBM) is the conjugate prior of the
standard point-target model (A. F. García-Fernández, J. L. Williams,
K. Granström and L. Svensson, "Poisson multi-Bernoulli mixture filter: direct
derivation and implementation", *IEEE Transactions on Aerospace and Electronic
Systems* 54(4):1883–1901, 2018; J. L. Williams, "Marginal multi-Bernoulli
filters: RFS derivation of MHT, JIPDA, and association-based MeMBer", *IEEE
Transactions on Aerospace and Electronic Systems* 51(3):1664–1687, 2015):

* a **Poisson** intensity D(x) of targets never detected — a Gaussian mixture
  (prior, Gaussian birth) plus, with the uniform birth model, a constant
  density per unit area (births anywhere, for scenes and data with no birth
  model); predicted with P_S and birth (García-Fernández et al. eq. (12)),
  thinned by (1 − P_D) at each update (eq. (19));
* **Bernoulli** components (existence r, Gaussian density) for targets detected
  at least once, one *track* per measurement that ever started one; a track's
  single-target hypotheses are "missed" (r(1 − P_D)/(1 − r P_D), weight
  1 − r P_D, eq. (20)–(21)) or "measurement j" (r = 1, Kalman update, weight
  r P_D g_j, eq. (22)–(23)); each measurement also starts a new track whose
  Bernoulli is the Poisson posterior against it, with weight
  ρ_j = λ_c + e_j, e_j = P_D ∫ g_j D, and existence e_j / ρ_j (eq. (24)–(27)),
  or no Bernoulli when the measurement went to a prior track;
* **global hypotheses**: which single-target hypothesis of each track holds,
  with weights ∝ the product of the chosen single-target weights (eq. (28)).

Dividing every event weight by Π_j ρ_j puts one scan's association in the
cluster convention of :func:`jointtrack.association.marginals`: likelihood
ratios L_ij = r_i P_D g_ij / ρ_j, miss weights 1 − r_i P_D; a measurement whose
column is unused is a new target or clutter with weight 1. So:

* :class:`PMBTracker` (track-oriented PMB, Williams 2015 §IV) keeps one global
  hypothesis: the marginal association probabilities of every Bernoulli come
  **exactly** from the assignment-sum core, cluster by cluster, with the
  package's budget and LBP fallback (J. L. Williams and R. A. Lau,
  "Approximate evaluation of marginal association probabilities with belief
  propagation", *IEEE T-AES* 50(4), 2014) — the same
  :meth:`~jointtrack.trackers.base.ScanTracker._pair_marginals` as the JPDA
  tracker; the probability that measurement j is a new target is
  1 − Σ_i β_ij. Each Bernoulli's mixture over its hypotheses is then merged to
  one Bernoulli (Williams 2015 eq. (58)–(60)) — by default (``keep_apart``)
  without the returns that the most probable association event gives to
  another Bernoulli, so that two close targets' Bernoullis do not both merge to
  the middle (the coalescence of JPDA: H. A. P. Blom and E. A. Bloem,
  "Probabilistic data association avoiding track coalescence", *IEEE
  Transactions on Automatic Control* 45(2), 2000); the existences stay the
  exact marginals. Bernoullis whose states are within ``duplicate_distance``
  are one target's and are merged (the id reported first is kept).
* :class:`PMBMTracker` keeps up to ``max_hypotheses`` global hypotheses; from
  each prior hypothesis of normalised weight w_h the ⌈max_hypotheses · w_h⌉
  best new ones come from Murty's algorithm on the package's one LSAP
  (:func:`jointtrack.association.kbest_hypotheses`), per cluster of tracks
  that share gated measurements, the clusters' ranked lists combined exactly
  (García-Fernández et al. §V). The estimate (``estimator``): by default
  estimator 1 of that paper (§VI-A), the Bernoullis with r ≥ ``r_estimate`` in
  the most probable global hypothesis; or each track — one Bernoulli's lineage,
  with the id it was born with — whose existence summed over the global
  hypotheses is ≥ ``r_estimate``, at its state in the most probable hypothesis
  holding it (tracks that are alternatives for one target, within
  ``duplicate_distance``, reported once). A track keeps the id it was born with.

Approximations, each with its knob in :class:`~jointtrack.trackers.pmbm_config.PMBMConfig`:

* **gating** (``p_g``, default 0.9999): pairs outside the gate are not
  hypotheses; their weight is at most 1e-4 of a gated pair's relative to the
  miss. With p_g = 1 every pair is kept (the tests compare with full
  enumeration that way).
* **Gaussian sums collapsed**: PMB merges each Bernoulli's mixture (the
  defining PMB approximation); a new Bernoulli's Poisson posterior is one
  Gaussian by moment matching (both filters).
* **pruning**: Bernoullis with r < ``r_prune`` (1e-5) or r = 0, Poisson components
  with weight < ``poisson_prune`` (1e-5), global hypotheses with normalised
  weight < ``hypothesis_prune`` (1e-4; the most probable are always kept) and
  beyond ``max_hypotheses`` (200);
  Poisson components within ``poisson_merge`` (squared Mahalanobis distance 4)
  merged.
* **recycling** (``r_recycle``, 0.1): Bernoullis (PMBM: tracks in every
  global hypothesis) with existence below it that were never reported
  become Gaussian components of the Poisson intensity (J. L. Williams,
  "Hybrid Poisson and multi-Bernoulli filters", *15th International
  Conference on Information Fusion*, 2012): clutter-born Bernoullis then cost
  no association work. PMBM with ``recycle_existence = "marginal"``: a track
  whose existence summed over the global hypotheses is below it, so that a
  target's early evidence, spread over many hypotheses, is kept in one
  Gaussian of the intensity (issue 33).
* **work budgets** (``max_ranking_work``, 2^25): PMBM estimates each
  cluster's ranking work before doing it; past the budget the cluster gets
  fewer events per prior hypothesis (method ``"murty-truncated"``: still its
  best ones, exactly), and when not even two fit it is merged into one
  Bernoulli per track — its prior projected to one Bernoulli per track across
  the global hypotheses, then the PMB update (method ``"pmb-<tier>"``). Both
  filters solve a cluster whose dense approximation could take more than the
  sparse LBP tier's work by the sparse tiers directly. A 2,000-return clutter
  burst costs PMBM ~8 s CPU per scan instead of not finishing in 15 minutes
  (``benchmarks/RESULTS.md``, "Issue 31").
* **measurement-driven birth** (``birth_per_return``, default 0): each
  return no Bernoulli explains adds a birth component at its position for the
  next scan (B. Ristic, D. Clark, B.-N. Vo and B.-T. Vo, "Adaptive target birth
  intensity for PHD and CPHD filters", *IEEE T-AES* 48(2), 2012).
* **uniform birth** ignores the edges of ``birth_region`` (a measurement
  inside it gets the full density, one outside none).

**Reporting targets** (AIS, ADS-B; ``step(…, labels=, velocities=)``), by the
rules the JIPDA tracker uses (:mod:`jointtrack.trackers.reporting`):

* ``reporting = "async"``: each Bernoulli (PMBM: each single-target hypothesis)
  is a Poisson reporter of its own rate, learnt from its reports since birth, and
  dies at a rate per second; P_D,i, the miss weight and the survival over the
  interval since the previous scan are :func:`~jointtrack.trackers.reporting.scan_detection`'s,
  so a Bernoulli's update is exactly a JIPDA track's (tests/test_pmbm_reporting.py).
  Undetected targets report at p_d / ``report_interval``; the clutter and birth
  densities are per second, the pair weights P_D,i/Δt · g / ρ_j.
* labels: a labelled report goes to the Bernoulli carrying its label — updated,
  existence ``r_labelled``, or restarted on the report when outside its gate — or
  starts one (a label seen before takes back its id); it is never associated
  with another Bernoulli, and unlabelled reports never with a labelled one.
  Such a Bernoulli's association is certain, the same in every global
  hypothesis, so the labelled Bernoullis (``labelled_*``) are kept outside the
  hypotheses and the association.
* reported velocities seed the velocity of the Bernoullis the reports start
  (σ = ``velocity_std``); they are not measured.

**Manoeuvres** (``motion = "imm"``): each Bernoulli (PMBM: each single-target
hypothesis, labelled ones too) carries the modes of :mod:`jointtrack.filters.imm` —
mixed and predicted per mode, its pairs weighed by the modes' mixture likelihood,
updated by the IMM-PDA of its association probabilities (a detection child of
PMBM by the IMM update with its return), reporting the combined position and
velocity. The Poisson intensity moves with CV: it is a density of births, not a
track; its first detection starts a Bernoulli with ``imm_initial``. A cluster
merged past the ranking budget merges each mode across the hypotheses.

What they cost, measured on the coalescence scene (10 runs, seeds 0–9, mean
GOSPA c = 10, p = 2, α = 2; ``benchmarks/RESULTS.md``, "Issue 23"): with the
defaults and gate P_G = 0.99, PMBM 2.294 ± 0.073 and PMB 2.701 ± 0.079. Turning each approximation
off or widening it moves the mean by less than one standard error: no
recycling 2.262 / 2.687, no Poisson merging 2.268 / 2.679, P_G = 1 − 10⁻⁷
(instead of 0.99) 2.260 / 2.743, no hypothesis pruning 2.294 / 2.701; PMBM with 1,000 global
hypotheses 2.294 (3× slower), with 50 hypotheses 2.298 (2.4× faster).
"""

from __future__ import annotations

import dataclasses
import math
import time
from typing import NamedTuple

import numpy as np

from jointtrack.association.budget import (
    MAX_LBP_WORK,
)
from jointtrack.association.gating import likelihood_ratio_pairs
from jointtrack.association.kbest import kbest_hypotheses
from jointtrack.errors import InfeasibleAssignmentError
from jointtrack.filters import (
    ekf_update,
    imm_combine,
    imm_pair_log_likelihoods,
    imm_pda_pairs_update,
    imm_predict,
    pda_pairs_update,
    predict,
    update,
)
from jointtrack.filters.imm import IMMModes
from jointtrack.models import ConstantVelocity
from jointtrack.trackers.base import ScanResult, ScanTracker
from jointtrack.trackers.existence import existence_update
from jointtrack.trackers.pmbm_config import PMBMConfig
from jointtrack.trackers.pmbm_hypotheses import (
    RankedLists,
    check_pair_weights,
    combine_events,
    distinct_rows,
    merge_identical,
    rank_tuples,
    track_clusters,
)
from jointtrack.trackers.poisson import moment_match, prune_and_merge
from jointtrack.trackers.reporting import (
    ScanDetection,
    check_report_fields,
    label_identities,
    match_labels,
    miss_weight,
    missed_existence,
    scaled_pair_factor,
    scan_detection,
    seed_velocities,
    undetected_detection,
)
from jointtrack.trackers.state_io import (
    StateFileError,
    covariance_problem,
    validate_counters,
    validate_mode_arrays,
)

__all__ = ["PMBMConfig", "PMBMTracker", "PMBTracker"]


class _PoissonTracker(ScanTracker):
    """The Poisson part and the Bernoulli arithmetic both filters share."""

    CONFIG = PMBMConfig
    REPORT_FIELDS = ("labels", "velocities")
    SUPPORTS_IMM = True
    _POISSON = ("poisson_w", "poisson_m", "poisson_P", "undetected_density")
    #: Bernoullis of labelled targets (``step(…, labels=)``) and the label → id table.
    #: A labelled report goes to the Bernoulli carrying its label (or starts one) and
    #: no other: such a Bernoulli's association is certain, the same in every global
    #: hypothesis, so it is kept outside the hypotheses (and the PMB association).
    _LABELLED = (
        "labelled_r",
        "labelled_x",
        "labelled_P",
        "labelled_ids",
        "labelled_labels",
        "labelled_born",
        "labelled_reports",
        "labelled_mode_x",
        "labelled_mode_P",
        "labelled_mode_log_prob",
        "label_names",
        "label_ids",
    )
    #: the per-Bernoulli fields of the labelled Bernoullis (_LABELLED without the table)
    _LABELLED_ROWS = _LABELLED[:-2]

    def __init__(
        self,
        config: PMBMConfig | None = None,
        *,
        motion=None,
        sensor=None,
        sensors=None,
        keep_history: bool = True,
    ):
        """Build a tracker from ``config`` and, optionally, model objects.

        ``motion``, ``sensor``, ``sensors`` and ``keep_history`` are those of
        :class:`~jointtrack.trackers.jpda.JPDATracker`. The tracker starts from
        nothing: the prior Poisson intensity of the configuration (``prior_weight``
        or ``prior_density``) stands for the targets present before the first scan.
        """
        super().__init__(
            config, motion=motion, sensor=sensor, sensors=sensors, keep_history=keep_history
        )
        c = self.config
        n = self.state_dim
        if c.birth_model == "gaussian" and n != len(c.birth_means[0]):
            raise ValueError(
                f"birth_means have length {len(c.birth_means[0])}, but the motion model's "
                f"state_dim is {n}"
            )
        self._birth_w = np.asarray(c.birth_weights, float).reshape(-1)
        self._birth_m = np.asarray(c.birth_means, float).reshape(-1, n)
        self._birth_P = np.asarray(c.birth_covs, float).reshape(-1, n, n)
        if c.birth_model == "gaussian":
            total = self._birth_w.sum()
            share = self._birth_w / total if total > 0 else self._birth_w
            self.poisson_w = c.prior_weight * share
            self.poisson_m, self.poisson_P = self._birth_m.copy(), self._birth_P.copy()
            u0 = 0.0
        else:
            self.poisson_w, self.poisson_m = np.zeros(0), np.zeros((0, n))
            self.poisson_P = np.zeros((0, n, n))
            if c.reporting == "async":  # births per second against deaths and reports
                steady = c.birth_density / (-math.log(c.p_survive) + c.p_d / c.report_interval)
            else:
                steady = c.birth_density / (1.0 - c.p_survive * (1.0 - c.p_d))
            u0 = steady if c.prior_density is None else c.prior_density
        self.undetected_density = np.array([u0])
        keep = self.poisson_w > 0
        self.poisson_w = self.poisson_w[keep]
        self.poisson_m, self.poisson_P = self.poisson_m[keep], self.poisson_P[keep]
        self.labelled_r, self.labelled_x = np.zeros(0), np.zeros((0, n))
        self.labelled_P = np.zeros((0, n, n))
        self.labelled_ids = np.zeros(0, np.int64)
        self.labelled_labels = np.zeros(0, dtype="U1")
        self.labelled_born, self.labelled_reports = np.zeros(0), np.zeros(0)
        # motion = "imm": each Bernoulli's modes (state, covariance, log probability;
        # zero modes otherwise) and x, P their combined position and velocity. The
        # undetected targets' intensity moves with CV: it is a birth density, not a
        # track, and its first detection starts a Bernoulli with imm_initial
        self._imm = self._motion if isinstance(self._motion, IMMModes) else None
        self._poisson_motion = self._motion
        if self._imm is not None:
            self._poisson_motion = ConstantVelocity(dim=c.dim, q=c.process_noise)
        self.labelled_mode_x, self.labelled_mode_P, self.labelled_mode_log_prob = self._new_modes(
            np.zeros((0, n)), np.zeros((0, n, n))
        )
        # every label seen (sorted) and the id of its target's Bernoulli
        self.label_names, self.label_ids = np.zeros(0, dtype="U1"), np.zeros(0, np.int64)
        # the undetected targets' pair factor and miss probability of this scan
        self._u_pd_ratio, self._u_missed = c.p_d, 1.0 - c.p_d

    # ------------------------------------------------------------ reporting
    def _begin_scan(self, t, z, dt, n_coincident, labels, velocities):
        """The scan's clock and reports: validated ``labels`` and ``velocities``
        (:func:`~jointtrack.trackers.reporting.check_report_fields`), and the
        undetected targets' detection over the interval. Returns ``(labels,
        repeated, velocities, n_coincident, step)`` with ``step`` = Δt (0 at the
        first scan)."""
        labels, repeated, velocities, n_coincident = check_report_fields(
            self.config.dim, z, labels, velocities, self._kept_rows, n_coincident
        )
        step = 0.0 if dt is None else dt
        self._scan_t, self._scan_dt = t, step
        self._u_pd_ratio, self._u_missed = undetected_detection(self.config, self._p_d, step)
        return labels, repeated, velocities, n_coincident, step

    # ------------------------------------------------------------------ IMM
    def _new_modes(self, x0, P0):
        """Per-mode states ``(mode_x, mode_P, mode_log_prob)`` of Bernoullis started at
        ``x0, P0`` (zero modes without an IMM)."""
        c = self.config
        if self._imm is None:
            k = len(x0)
            return np.zeros((k, 0, 0)), np.zeros((k, 0, 0, 0)), np.zeros((k, 0))
        return self._imm.initial_states(
            x0, P0, (c.max_acceleration / 2.0) ** 2, (c.max_turn_rate / 2.0) ** 2
        )

    def _combined(self, modes):
        """``(x, P)``: the modes' combined position and velocity."""
        k = self.state_dim
        x, P = imm_combine(*modes)
        return x[:, :k], P[:, :k, :k]

    def _predict_set(self, x, P, modes, step, F, Q):
        """Bernoullis ``(x, P, modes)`` predicted over ``step`` seconds (IMM: mixing and
        mode-conditioned prediction, then combined; else ``F``, ``Q``)."""
        if not len(x):
            return x, P, modes
        if self._imm is None:
            x, P = predict(x, P, F, Q)
            return x, P, modes
        modes = imm_predict(*modes, self._imm, step)
        return (*self._combined(modes), modes)

    def _gate_set(self, x, P, modes, z):
        """The gated pairs of Bernoullis and returns; with an IMM each pair weighs the
        modes' mixture likelihood Σ_j c̄_j g_ij (the gate is the combined estimate's)."""
        g = self._gate(x, P, z)
        if self._imm is None or not len(g.rows):
            return g
        log_g, _ = imm_pair_log_likelihoods(
            self._imm, *modes, z, g.rows, g.cols, **self._measurement_model()
        )
        return dataclasses.replace(g, log_g=log_g)

    def _update_set(self, x, P, modes, z, beta0, rows, cols, w):
        """PDA update of Bernoullis by association probabilities; IMM-PDA per mode
        (each mode's PDA with its mode-conditioned β, Blom & Bloem 2000) and combined."""
        if self._imm is None:
            x, P = pda_pairs_update(x, P, z, beta0, rows, cols, w, **self._measurement_model())
            return x, P, modes
        modes = imm_pda_pairs_update(
            self._imm, *modes, z, beta0, rows, cols, w, **self._measurement_model()
        )
        return (*self._combined(modes), modes)

    def _detected_set(self, x, P, modes, z):
        """Each Bernoulli ``k`` updated by its own return ``z[k]`` (Kalman / EKF, or the
        IMM update: each mode's, μ_j ∝ c̄_j g_j)."""
        if self._imm is None or not len(x):
            x, P = self._pair_update(x, P, z)
            return x, P, modes
        k = np.arange(len(x))
        return self._update_set(x, P, modes, z, np.zeros(len(x)), k, k, np.ones(len(x)))

    def _detection(self, born, reports, labelled=False) -> ScanDetection:
        """Detection and survival of Bernoullis born at ``born`` with ``reports`` (soft)
        reports over this scan's interval (:func:`~jointtrack.trackers.reporting.scan_detection`;
        no gate factor: the Poisson multi-Bernoulli weights have none)."""
        t, dt = self._scan_t, self._scan_dt
        t_prev = t - dt if self.time is None else self.time
        flags = np.full(len(born), bool(labelled))
        return scan_detection(self.config, self._p_d, t, dt, t_prev, born, reports, flags)

    def _report_states(self, z, velocities=None):
        """``(x, P)`` of Bernoullis started on the returns ``z`` with nothing else known:
        the return's position, zero-mean velocity of per-axis σ = max_speed / 2
        (acceleration σ = max_acceleration / 2), or the reported velocity with σ =
        velocity_std where ``velocities`` has one."""
        c = self.config
        n, d, M = self.state_dim, c.dim, len(z)
        x, P = np.zeros((M, n)), np.zeros((M, n, n))
        if M == 0:
            return x, P
        pos, cov = self._sensor.position_and_covariance(z)
        x[:, :d] = pos
        P[:, :d, :d] = cov
        idx = np.arange(d, 2 * d)
        P[:, idx, idx] = (c.max_speed / 2.0) ** 2
        if n > 2 * d:
            a = np.arange(2 * d, min(3 * d, n))
            P[:, a, a] = (c.max_acceleration / 2.0) ** 2
        return seed_velocities(x, P, velocities, d, c.velocity_std)

    def _labelled_scan(self, t, z, labels, repeated, velocities, step=0.0, F=None, Q=None):
        """The labelled Bernoullis through one scan; returns the unlabelled returns' columns.

        Predicted with ``F``, ``Q`` (None: no time passed) and survival; a labelled
        report goes to the Bernoulli carrying its label — Kalman update, existence
        ``r_labelled`` (the report names a real target), or a restart on the report
        when it is outside that Bernoulli's gate (a position jump: a new id would
        break the identity the label guarantees) — or starts one (its id the label's
        old one if the label was seen before). A labelled Bernoulli not heard is
        missed with its own P_D,i (no gate: the label decides).
        """
        c = self.config
        modes = (self.labelled_mode_x, self.labelled_mode_P, self.labelled_mode_log_prob)
        if step > 0:
            self.labelled_x, self.labelled_P, modes = self._predict_set(
                self.labelled_x, self.labelled_P, modes, step, F, Q
            )
        det = self._detection(self.labelled_born, self.labelled_reports, labelled=True)
        self.labelled_r = self.labelled_r * det.survival
        if labels is None:
            rows = cols = open_cols = np.zeros(0, np.int64)
            z_index = np.arange(len(z))
        else:
            rows, cols, open_cols = match_labels(self.labelled_labels, labels, repeated)
            z_index = np.flatnonzero((labels == "") & ~repeated)
        heard = np.zeros(len(self.labelled_r), bool)
        heard[rows] = True
        self.labelled_r[~heard] = missed_existence(
            self.labelled_r[~heard], det._replace(missed=det.missed[~heard]), self._p_d
        )
        modes = tuple(a.copy() for a in modes)
        if len(rows):
            x, P = self.labelled_x[rows], self.labelled_P[rows]
            inside = self._pairs_gated(x, P, z[cols])
            x_new, P_new, m_new = self._detected_set(x, P, tuple(a[rows] for a in modes), z[cols])
            x_jump, P_jump = self._report_states(
                z[cols], None if velocities is None else velocities[cols]
            )
            m_jump = self._new_modes(x_jump, P_jump)
            self.labelled_x[rows] = np.where(inside[:, None], x_new, x_jump)
            self.labelled_P[rows] = np.where(inside[:, None, None], P_new, P_jump)
            for a, new, jump in zip(modes, m_new, m_jump, strict=True):
                a[rows] = np.where(inside.reshape(-1, *([1] * (a.ndim - 1))), new, jump)
            self.labelled_r[rows] = c.r_labelled
            self.labelled_reports[rows] += 1.0
        self.labelled_mode_x, self.labelled_mode_P, self.labelled_mode_log_prob = modes
        if len(open_cols):
            x0, P0 = self._report_states(
                z[open_cols], None if velocities is None else velocities[open_cols]
            )
            k = len(open_cols)
            ids, self.label_names, self.label_ids = label_identities(
                self.label_names, self.label_ids, labels[open_cols], np.arange(k) + self.next_id
            )
            self.next_id += k
            self.labelled_r = np.concatenate([self.labelled_r, np.full(k, c.r_labelled)])
            self.labelled_x = np.concatenate([self.labelled_x, x0])
            self.labelled_P = np.concatenate([self.labelled_P, P0])
            self.labelled_ids = np.concatenate([self.labelled_ids, ids])
            self.labelled_labels = np.concatenate([self.labelled_labels, labels[open_cols]])
            self.labelled_born = np.concatenate([self.labelled_born, np.full(k, float(t))])
            self.labelled_reports = np.concatenate([self.labelled_reports, np.zeros(k)])
            for name, a in zip(
                ("labelled_mode_x", "labelled_mode_P", "labelled_mode_log_prob"),
                self._new_modes(x0, P0),
                strict=True,
            ):
                setattr(self, name, np.concatenate([getattr(self, name), a]))
        keep = (self.labelled_r >= c.r_prune) & (self.labelled_r > 0)
        if not keep.all():
            for name in self._LABELLED_ROWS:
                setattr(self, name, getattr(self, name)[keep])
        return z_index

    def _result(self, t, ids, x, P, r, log_mu, **fields) -> ScanResult:
        """The scan's :class:`ScanResult`: the unlabelled estimates (``log_mu`` their log
        mode probabilities), then the labelled ones with r ≥ r_estimate."""
        on = self.labelled_r >= self.config.r_estimate
        imm = {}
        if self._imm is not None:
            log_mu = np.concatenate([log_mu, self.labelled_mode_log_prob[on]])
            imm = {"mode_names": self._imm.names, "mode_probabilities": np.exp(log_mu)}
        return ScanResult(
            time=t,
            ids=np.concatenate([ids, self.labelled_ids[on]]),
            x=np.concatenate([x, self.labelled_x[on]]),
            P=np.concatenate([P, self.labelled_P[on]]),
            existence=np.concatenate([r, self.labelled_r[on]]),
            **imm,
            **fields,
        )

    # ------------------------------------------------------------------ Poisson
    def _predict_poisson(self, F, Q, dt) -> None:
        """Survival and birth of the undetected intensity (García-Fernández et al. eq. (12)).

        Survival p_survive per scan, or p_survive^Δt (``p_survive_per = "second"``);
        births per scan, or per second × Δt (``reporting = "async"``).
        """
        c = self.config
        if len(self.poisson_w):
            self.poisson_m, self.poisson_P = predict(self.poisson_m, self.poisson_P, F, Q)
        survive = c.p_survive if c.p_survive_per == "scan" else c.p_survive**dt
        births = 1.0 if c.reporting == "scan" else dt
        self.poisson_w = survive * self.poisson_w
        if c.birth_model == "gaussian":
            self.poisson_w = np.concatenate([self.poisson_w, births * self._birth_w])
            self.poisson_m = np.concatenate([self.poisson_m, self._birth_m])
            self.poisson_P = np.concatenate([self.poisson_P, self._birth_P])
        else:
            self.undetected_density = survive * self.undetected_density + births * c.birth_density

    def _uniform_births(self, z):
        """``(e, x, P)``: the uniform part's P_D ∫ g_j D and posterior of every return.

        The uniform density u per unit area, seen through the sensor: a
        return's position ``pos`` (covariance ``C``) gets P_D · u · |det J|,
        J = ∂pos/∂z, so that the density is per unit of measurement volume
        (|det J| = √(det C / det R); 1 for a position sensor). The posterior
        is the return's position with zero-mean velocity of per-axis σ =
        max_speed / 2 (acceleration σ = max_acceleration / 2).
        """
        c = self.config
        n, M = self.state_dim, len(z)
        u = float(self.undetected_density[0])
        if M == 0 or c.birth_model != "uniform" or u == 0.0:
            return np.zeros(M), np.zeros((M, n)), np.zeros((M, n, n))
        x, P = self._report_states(z)
        pos, cov = x[:, : c.dim], P[:, : c.dim, : c.dim]
        # in log space: det of a 2-D covariance of σ² ~ 1e154 and more overflows to inf
        # (inf / inf = NaN birth existence), within the settings' bound MAX_VARIANCE
        log_det_cov = np.linalg.slogdet(cov)[1]
        log_det_R = np.linalg.slogdet(self._sensor.R)[1]
        jac = np.exp(0.5 * (log_det_cov - log_det_R))
        e = self._u_pd_ratio * u * jac
        if c.birth_region is not None:
            box = np.asarray(c.birth_region)
            inside = ((pos >= box[:, 0]) & (pos <= box[:, 1])).all(axis=1)
            e = np.where(inside, e, 0.0)
        return e, x, P

    def _pair_update(self, x, P, z):
        """Kalman (or EKF) update of each state ``x[k]`` with its own return ``z[k]``."""
        if not len(x):
            return x.copy(), P.copy()
        if self._linear:
            return update(x, P, z, self._sensor.H, self._sensor.R)
        return ekf_update(x, P, z, self._sensor)

    def _poisson_detection(self, z):
        """Everything the undetected targets say about the returns ``z``.

        Returns ``(rho, e, x_new, P_new)``: ρ_j = λ_c + e_j, the weight of
        "return j is clutter or a first detection"; e_j = P_D ∫ g_j(x) D(x) dx
        (García-Fernández et al. eq. (25)); and the moment-matched posterior
        of the new Bernoulli started by return j (eq. (26)).
        """
        M = len(z)
        e_u, x_u, P_u = self._uniform_births(z)
        weights, groups, xs, Ps = [e_u], [np.arange(M)], [x_u], [P_u]
        if len(self.poisson_w) and M:
            g = self._gate(self.poisson_m, self.poisson_P, z)
            with np.errstate(divide="ignore"):  # a component of weight 0 (a loaded state) adds 0
                w = np.exp(np.log(self.poisson_w[g.rows]) + math.log(self._u_pd_ratio) + g.log_g)
            xu, Pu = self._pair_update(self.poisson_m[g.rows], self.poisson_P[g.rows], z[g.cols])
            weights.append(w)
            groups.append(g.cols)
            xs.append(xu)
            Ps.append(Pu)
        e, x_new, P_new = moment_match(
            np.concatenate(weights), np.concatenate(groups), np.concatenate(xs),
            np.concatenate(Ps), M,
        )  # fmt: skip
        rho = self._clutter + e
        return rho, e, x_new, P_new

    def _thin_and_prune_poisson(self, recycled=None, unexplained=None) -> None:
        """(1 − P_D) thinning of the undetected (eq. (19)), recycling, births, pruning, merging.

        ``recycled``: ``(w, m, P)`` of posterior Bernoullis moved into the
        intensity (weight = existence; Williams 2012), added after the thinning.
        ``unexplained``: ``(z, q)``, the scan's returns and each one's probability
        of not having come from a prior Bernoulli; with ``birth_per_return`` > 0
        each return adds a birth component at its position (one-point: zero-mean
        velocity, :meth:`_report_states`) of weight ``birth_per_return`` · q — the
        measurement-driven birth of Ristic et al. 2012 (module docstring), with
        JIPDA's per-return initiation weight r_init · (1 − P(return from a track)).
        Births so follow the returns no track explains, wherever a target is lost
        or appears late, instead of a uniform density small enough for 60 clutter
        returns a scan.
        """
        c = self.config
        miss = self._u_missed
        self.undetected_density = miss * self.undetected_density
        w, m, P = miss * self.poisson_w, self.poisson_m, self.poisson_P
        if recycled is not None and len(recycled[0]):
            w = np.concatenate([w, recycled[0]])
            m = np.concatenate([m, recycled[1]])
            P = np.concatenate([P, recycled[2]])
        if c.birth_per_return > 0 and unexplained is not None and len(unexplained[0]):
            z, q = unexplained
            xb, Pb = self._report_states(z)
            w = np.concatenate([w, c.birth_per_return * np.clip(q, 0.0, 1.0)])
            m = np.concatenate([m, xb])
            P = np.concatenate([P, Pb])
        self.poisson_w, self.poisson_m, self.poisson_P = prune_and_merge(
            w, m, P, prune=c.poisson_prune, merge=c.poisson_merge, cap=c.max_poisson_components
        )

    def _pair_weights(self, r, g, rho, det: ScanDetection | None = None):
        """Likelihood ratios L = r P_D g / ρ of the gated pairs and miss weights 1 − r P_D.

        Reporting targets (``det`` of :meth:`_detection`; None: a scanning sensor):
        P_D,i/Δt per Bernoulli against ρ per second (numerator and ρ divided by a
        common scale: a rate may exceed 1), and the miss weight (1 − r) + r·missed.
        """
        if det is None or det.scan:
            L, _ = likelihood_ratio_pairs(g, self._p_d * r, rho)
            return L, 1.0 - self._p_d * r
        pd_r, scale = scaled_pair_factor(det.pd_ratio, r)
        L, _ = likelihood_ratio_pairs(g, pd_r, rho / scale)
        return L, miss_weight(r, det, self._p_d)

    def _pmb_update(self, ids, r, x, P, z, rows, cols, L, miss, loud, det: ScanDetection, modes):
        """PMB update of the Bernoullis ``(r, x, P)`` (ids ``ids``) by the returns ``z``.

        ``rows``/``cols``: the gated pairs (Bernoulli, return), ``L`` their
        likelihood ratios, ``miss`` the miss weights (:meth:`_pair_weights`).
        The marginal association probabilities come from the one assignment-sum
        core cluster by cluster under the package's budget
        (:meth:`~jointtrack.trackers.base.ScanTracker._pair_marginals`); each
        Bernoulli's mixture over its hypotheses is then merged to one Bernoulli
        (Williams 2015 eq. (58)–(60)). ``det``: the Bernoullis' detection over the
        interval (:meth:`_detection`); ``modes`` their IMM modes (zero modes without
        one). Returns ``(r, x, P, taken, info, reports, modes)``: the posterior
        Bernoullis, each return's probability of having come from one of them, the
        clusters' ``(sizes, seconds, methods, fallbacks)``, the reports each
        Bernoulli took given it exists, and the posterior modes.
        """
        # loud=False for PMB: fallbacks are logged at debug level and reported in the result
        pairs = _GatedPairs(len(r), len(z), rows, cols)
        beta0, w, groups, info = self._pair_marginals(ids, pairs, L, miss, loud)
        taken = np.bincount(cols, w, minlength=len(z))
        if det.scan:
            r_post, b0, wc = existence_update(r, beta0, w, rows, self._p_d)
        else:
            r_post, b0, wc = existence_update(r, beta0, w, rows, det.pdg, missed=det.missed)
        # the reports each Bernoulli took, given it exists (its own reporting rate)
        reports = np.bincount(rows, wc, minlength=len(r))
        if self.config.keep_apart:
            owner = _best_event_owners(groups, rows, cols, L, miss, len(z))
            b0, wc = _apart_weights(b0, wc, rows, cols, owner)
        x_post, P_post, modes = self._update_set(x, P, modes, z, b0, rows, cols, wc)
        return r_post, x_post, P_post, taken, info, reports, modes

    # --------------------------------------------------------------- checks
    def _labelled_spec(self) -> dict:
        """The state fields of the labelled Bernoullis (``_validate_common`` spec)."""
        n = self.state_dim
        return {
            "labelled_r": ("f", ("K",)),
            "labelled_x": ("f", ("K", n)),
            "labelled_P": ("f", ("K", n, n)),
            "labelled_ids": ("i", ("K",)),
            "labelled_labels": ("U", ("K",)),
            "labelled_born": ("f", ("K",)),
            "labelled_reports": ("f", ("K",)),
            "label_names": ("U", ("L",)),
            "label_ids": ("i", ("L",)),
        }

    def _validate_labelled(self, path, arrays) -> None:
        """Values of the labelled Bernoullis and the label table a tracker can hold."""

        def bad(what):
            return StateFileError(f"{path}: {what}")

        _check_existence(path, "labelled_r", arrays["labelled_r"])
        labels = arrays["labelled_labels"]
        if (labels == "").any() or len(np.unique(labels)) != len(labels):
            raise bad("field 'labelled_labels' must hold distinct non-empty labels")
        names = arrays["label_names"]
        if (names == "").any() or (names[1:] <= names[:-1]).any():
            raise bad("field 'label_names' must hold sorted, distinct, non-empty labels")
        if not np.isin(labels, names).all():
            raise bad("field 'labelled_labels' holds a label missing from 'label_names'")
        for name in ("labelled_reports", "report_count", "sth_reports"):
            if name in arrays and (arrays[name] < 0).any():
                raise bad(f"field {name!r} has negative values")
        count = len(arrays["labelled_r"])
        validate_mode_arrays(path, arrays, self._imm, prefix="labelled_", count=count)

    def _validate_common(self, path, arrays, spec, lengths):
        """Dtype/shape/finiteness of ``spec`` {name: (kind, shape with names)}."""

        def bad(what):
            return StateFileError(f"{path}: {what}")

        for name, (kind, shape) in spec.items():
            if name not in arrays:
                raise bad(f"missing field {name!r}")
            a = arrays[name]
            if a.dtype.kind != kind or a.ndim != len(shape):
                raise bad(f"field {name!r} has dtype {a.dtype} and {a.ndim} dimension(s)")
            want = tuple(lengths.setdefault(s, a.shape[i]) if isinstance(s, str) else s
                         for i, s in enumerate(shape))  # fmt: skip
            if a.shape != want:
                raise bad(f"field {name!r} has shape {a.shape}, expected {want}")
            if kind == "f" and not np.isfinite(a).all():
                raise bad(f"field {name!r} has non-finite values")
        for name, (_, shape) in spec.items():
            if len(shape) == 3:
                problem = covariance_problem(arrays[name])
                if problem:
                    raise bad(f"field {name!r} holds a covariance that {problem}")
        for name in ("poisson_w", "undetected_density"):
            if (arrays[name] < 0).any():
                raise bad(f"field {name!r} has negative values")
        if arrays["undetected_density"].shape != (1,):
            raise bad("field 'undetected_density' must hold one number")


class PMBTracker(_PoissonTracker):
    """Track-oriented Poisson multi-Bernoulli tracker (Williams 2015; module docstring).

    >>> import numpy as np
    >>> from jointtrack.trackers.pmbm import PMBTracker, PMBMConfig
    >>> trk = PMBTracker(PMBMConfig(clutter_density=1e-4, birth_density=1e-6))
    >>> for t in range(8):                # a target moving at 10 m/s, one at 3 m/s
    ...     result = trk.step(float(t), np.array([[10.0 * t, 0.0], [500.0, 3.0 * t]]))
    >>> result.ids.tolist()               # both found from nothing, ids from their birth
    [1, 2]
    """

    KIND = "pmb"
    _BERNOULLI = (
        "x",
        "P",
        "ids",
        "existence",
        "reported",
        "born",
        "report_count",
        "mode_x",
        "mode_P",
        "mode_log_prob",
    )
    _ARRAYS = (*_BERNOULLI, *_PoissonTracker._POISSON, *_PoissonTracker._LABELLED)

    def __init__(self, config=None, *, motion=None, sensor=None, sensors=None, keep_history=True):
        super().__init__(
            config, motion=motion, sensor=sensor, sensors=sensors, keep_history=keep_history
        )
        n = self.state_dim
        self.x, self.P = np.zeros((0, n)), np.zeros((0, n, n))
        self.ids, self.existence = np.zeros(0, np.int64), np.zeros(0)
        # reported at some scan (r ≥ r_estimate): never recycled, so its id is kept
        self.reported = np.zeros(0, bool)
        # birth time and (soft) number of reports of each Bernoulli: its own reporting
        # rate (reporting = "async")
        self.born, self.report_count = np.zeros(0), np.zeros(0)
        self.mode_x, self.mode_P, self.mode_log_prob = self._new_modes(self.x, self.P)

    def _modes(self):
        """The Bernoullis' IMM modes (without an IMM: zero modes, one row per Bernoulli)."""
        if self._imm is None:
            return self._new_modes(self.x, self.P)
        return self.mode_x, self.mode_P, self.mode_log_prob

    def _keep_bernoullis(self, keep) -> None:
        for name in self._BERNOULLI:
            setattr(self, name, getattr(self, name)[keep])

    def _step(self, t, z, same_time_ok=False, labels=None, velocities=None) -> ScanResult:
        c = self.config
        t, z, dt, n_coincident = self._check_scan(t, z, same_time_ok)
        labels, repeated, velocities, n_coincident, step = self._begin_scan(
            t, z, dt, n_coincident, labels, velocities
        )
        self.mode_x, self.mode_P, self.mode_log_prob = self._modes()
        F = Q = None
        if step > 0:
            F, Q = self._poisson_motion.transition(step), self._poisson_motion.noise(step)
            self.x, self.P, modes = self._predict_set(self.x, self.P, self._modes(), step, F, Q)
            self.mode_x, self.mode_P, self.mode_log_prob = modes
            self._predict_poisson(F, Q, step)
        det = self._detection(self.born, self.report_count)
        self.existence = det.survival * self.existence
        # existence that underflowed to 0 is no Bernoulli (its L = r P_D g / ρ would be
        # 0, a P_D of 0 to the association)
        live = self.existence > 0
        if not live.all():
            self._keep_bernoullis(live)
            det = ScanDetection(*(a[live] for a in det[:5]), det.scan)
        # labelled reports go to their own Bernoullis; the rest are associated here
        z_index = self._labelled_scan(t, z, labels, repeated, velocities, step, F, Q)
        zu = z[z_index]
        rho, e, x_new, P_new = self._poisson_detection(zu)
        if velocities is not None:
            seed_velocities(x_new, P_new, velocities[z_index], c.dim, c.velocity_std)
        M, N = len(zu), len(self.ids)
        taken = np.zeros(M)  # P(return j came from a prior Bernoulli)
        info = ([], [], [], [])
        gated = np.zeros(M, bool)
        if N and M:
            g = self._gate_set(self.x, self.P, self._modes(), zu)
            L, miss = self._pair_weights(self.existence, g, rho, det)
            r, x, P, ids = self.existence, self.x, self.P, self.ids
            r, x, P, taken, info, reports, modes = self._pmb_update(
                ids, r, x, P, zu, g.rows, g.cols, L, miss, False, det, self._modes()
            )
            self.existence, self.x, self.P = r, x, P
            self.mode_x, self.mode_P, self.mode_log_prob = modes
            self.report_count = self.report_count + reports
            gated[g.cols] = True
        elif N:  # nothing measured: every Bernoulli missed
            self.existence = missed_existence(self.existence, det, self._p_d)
        r_new = np.clip(1.0 - taken, 0.0, 1.0) * e / rho
        x = np.concatenate([self.x, x_new])
        P = np.concatenate([self.P, P_new])
        r = np.concatenate([self.existence, r_new])
        ids = np.concatenate([self.ids, np.zeros(M, np.int64)])  # new: numbered below
        reported = np.concatenate([self.reported, np.zeros(M, bool)])
        born = np.concatenate([self.born, np.full(M, float(t))])
        report_count = np.concatenate([self.report_count, np.zeros(M)])
        modes = [
            np.concatenate([a, b])
            for a, b in zip(self._modes(), self._new_modes(x_new, P_new), strict=True)
        ]
        weak = (r < c.r_recycle) & (r >= c.r_prune) & ~reported
        self._thin_and_prune_poisson((r[weak], x[weak], P[weak]), (zu, 1.0 - taken))
        keep = (r >= c.r_prune) & (r > 0) & ~weak  # r = 0: no Bernoulli at all
        self.x, self.P, self.existence, ids = x[keep], P[keep], r[keep], ids[keep]
        self.born, self.report_count = born[keep], report_count[keep]
        self.mode_x, self.mode_P, self.mode_log_prob = (a[keep] for a in modes)
        self.reported = reported[keep]
        self.ids = ids
        if c.duplicate_distance > 0 and len(ids) > 1:
            self._merge_duplicates()
            ids = self.ids
        self.reported = self.reported | (self.existence >= c.r_estimate)
        new = ids == 0
        ids[new] = np.arange(self.next_id, self.next_id + int(new.sum()))
        self.next_id += int(new.sum())
        self.ids = ids
        self.time = t
        self.n_scans += 1
        report = self.existence >= c.r_estimate
        sizes, seconds, methods, fallbacks = info
        return self._result(
            t,
            self.ids[report].copy(),
            self.x[report].copy(),
            self.P[report].copy(),
            self.existence[report].copy(),
            self.mode_log_prob[report],
            n_tentative=int((~report).sum()),
            n_measurements=len(z),
            n_unassociated=int((~gated).sum()),
            cluster_sizes=sizes,
            cluster_seconds=seconds,
            cluster_methods=methods,
            cluster_confirmed=[False] * len(sizes),
            cluster_fallbacks=fallbacks,
            n_coincident=n_coincident,
        )

    def _merge_duplicates(self) -> None:
        """Bernoullis of one target are one Bernoulli (``ids`` 0: born this scan).

        Groups of :func:`_duplicate_groups` (means within ``duplicate_distance``);
        each group becomes its leader — reported before never reported, then the
        oldest id, then the most probable — with existence 1 − Π(1 − r) (at least
        one of them exists) and the mixture's mean and covariance (moment matching,
        weights r). With an IMM the leader keeps its own modes.
        """
        c = self.config
        r, ids = self.existence, self.ids
        rank = np.lexsort((-r, np.where(ids > 0, ids, np.iinfo(np.int64).max), ~self.reported))
        # two returns of one scan are two targets (or clutter): their new Bernoullis
        # are never one target's duplicates
        group = _duplicate_groups(
            self.x, self.P, rank, c.duplicate_distance, c.dim, exclusive=ids == 0
        )
        n_groups = int(group.max()) + 1
        if n_groups == len(ids):
            return
        lead = np.full(n_groups, -1, np.int64)
        for i in rank[::-1]:  # the first in rank order of each group is written last
            lead[group[i]] = i
        _, x, P = moment_match(r, group, self.x, self.P, n_groups)
        # log P(none exists) = Σ log(1 − r): r = 1 gives −inf, and 1 − Π(1 − r) = 1
        with np.errstate(divide="ignore"):
            log_none = np.bincount(group, np.log1p(-r), minlength=n_groups)
        reported = np.bincount(group, self.reported, minlength=n_groups) > 0
        self._keep_bernoullis(lead)
        self.existence, self.reported = -np.expm1(log_none), reported
        if self._imm is None:  # with an IMM x, P are the leader's modes combined
            self.x, self.P = x, P

    def _validate_state(self, path, arrays, scalars):
        n = self.state_dim
        spec = {
            "x": ("f", ("N", n)),
            "P": ("f", ("N", n, n)),
            "ids": ("i", ("N",)),
            "existence": ("f", ("N",)),
            "reported": ("b", ("N",)),
            "born": ("f", ("N",)),
            "report_count": ("f", ("N",)),
            "poisson_w": ("f", ("C",)),
            "poisson_m": ("f", ("C", n)),
            "poisson_P": ("f", ("C", n, n)),
            "undetected_density": ("f", (1,)),
            **self._labelled_spec(),
        }
        self._validate_common(path, arrays, spec, {})
        _check_existence(path, "existence", arrays["existence"])
        self._validate_labelled(path, arrays)
        validate_mode_arrays(path, arrays, self._imm)
        ids = np.concatenate([arrays["ids"], arrays["labelled_ids"]])
        validate_counters(path, ids, scalars)


#: Largest cluster (Bernoullis × returns) whose most probable association event
#: :func:`_best_event_owners` finds: one assignment of an (N, N + M) matrix. The
#: clusters of the built-in scenes are far below it; a clutter burst's giant cluster
#: keeps the plain marginal update (its Bernoullis are clutter-born, not lanes).
APART_MAX_CELLS = 1 << 16


def _best_event_owners(groups, rows, cols, L, miss, M) -> np.ndarray:
    """``owner[j]``: the Bernoulli the most probable association event gives return j.

    Per cluster of two or more Bernoullis (one Bernoulli has nobody to be kept
    apart from) of at most :data:`APART_MAX_CELLS` cells, the MAP event by the
    package's one assignment solver (:func:`~jointtrack.association.kbest_hypotheses`
    with k = 1); −1 for returns the event leaves to clutter or a new target, and
    for the returns of the other clusters.
    """
    owner = np.full(M, -1, np.int64)
    if not len(rows):
        return owner
    # the pairs of each cluster, and each Bernoulli's and return's place in its cluster
    pair_cluster = groups.track_cluster[rows]
    order = np.argsort(pair_cluster, kind="stable")
    bounds = np.searchsorted(pair_cluster[order], np.arange(len(groups) + 1))
    local = np.zeros(len(groups.track_cluster), np.int64)
    local_m = np.zeros(M, np.int64)
    for k, cl in enumerate(groups):
        tr, ms = cl.tracks, cl.measurements
        if len(tr) < 2 or not len(ms) or len(tr) * (len(tr) + len(ms)) > APART_MAX_CELLS:
            continue
        local[tr] = np.arange(len(tr))
        local_m[ms] = np.arange(len(ms))
        p = order[bounds[k] : bounds[k + 1]]
        Lc = np.zeros((len(tr), len(ms)))
        Lc[local[rows[p]], local_m[cols[p]]] = L[p]
        try:
            a = kbest_hypotheses(Lc, np.ascontiguousarray(miss[tr], float), k=1).assignments[0]
        except InfeasibleAssignmentError:  # P_D = 1, r = 1: no event; nothing to keep apart
            continue
        hit = a > 0
        owner[ms[a[hit] - 1]] = tr[hit]
    return owner


def _apart_weights(b0, wc, rows, cols, owner):
    """Association weights of the Bernoullis' *state* update, kept apart by the MAP event.

    ``b0``, ``wc``: each Bernoulli's miss and pair probabilities given that it
    exists (:func:`~jointtrack.trackers.existence.existence_update`). A pair
    whose return the most probable event gives to *another* Bernoulli
    (``owner``, :func:`_best_event_owners`) is dropped, and the Bernoulli's other
    pairs take its weight in proportion (its probability of having been detected,
    1 − b0, is kept); a Bernoulli left with no pair is updated as missed.

    Why: the track-oriented PMB merges each Bernoulli's mixture over its
    hypotheses into one Gaussian (Williams 2015 eq. (58)–(60)). Two Bernoullis of
    targets closer than the measurement noise each weigh both targets' returns
    about equally, so both merged means sit between the lanes and the estimates
    hop from lane to lane — the coalescence of JPDA (Blom & Bloem, module
    docstring). Keeping
    the returns of the best event apart, as JPDA* keeps the best permutation,
    lets each Bernoulli follow its own target; the existences, the returns'
    probabilities of a new target and the reports stay the exact marginals.
    """
    if not len(wc):
        return b0, wc
    other = (owner[cols] >= 0) & (owner[cols] != rows)
    if not other.any():
        return b0, wc
    n = len(b0)
    total = np.bincount(rows, wc, minlength=n)
    kept_w = np.where(other, 0.0, wc)
    kept = np.bincount(rows, kept_w, minlength=n)
    some = kept > 0
    # share of the kept weight, then times the total: total / kept overflows when the
    # kept weight is subnormal beside a normal total
    share = np.divide(kept_w, kept[rows], out=np.zeros(len(wc)), where=some[rows])
    return np.where(some, b0, 1.0), share * total[rows]


def _duplicate_groups(x, P, rank, distance, dim, exclusive=None) -> np.ndarray:
    """Group labels of Bernoullis whose means are within ``distance`` of a leader's.

    Greedy in ``rank`` order (as Vo & Ma 2006, Table II): each Bernoulli not yet
    grouped leads a group of every ungrouped one whose mean differs from its own by
    a squared Mahalanobis distance ≤ ``distance`` in the sum of the two
    covariances (the whole state: position and velocity). A group holds at most one
    of the ``exclusive`` Bernoullis (bool mask; the nearest to its leader). Candidates
    come from a KD-tree on the positions: the position part of that distance is at
    most the whole, and at least |Δpos|² over the sum of the two position
    covariances' traces.
    """
    from scipy.spatial import cKDTree

    n = len(x)
    group = np.full(n, -1, np.int64)
    pos = x[:, :dim]
    tr = np.trace(P[:, :dim, :dim], axis1=1, axis2=2)
    radius = math.sqrt(distance * 2.0 * float(tr.max())) if distance > 0 else 0.0
    # the tree in units of the largest coordinate: squared distances of positions near
    # the coordinate limit (1e150 and more) would overflow in it
    scale = max(float(np.abs(pos).max()), radius, 1.0)
    if math.isfinite(scale):
        near = cKDTree(pos / scale).query_ball_point(pos / scale, radius / scale)
    else:  # a radius beyond the float range: every pair is a candidate
        near = [list(range(n))] * n
    g = 0
    for i in rank:
        if group[i] >= 0:
            continue
        group[i] = g
        cand = np.asarray([j for j in near[i] if group[j] < 0], np.int64)
        if len(cand):
            with np.errstate(all="ignore"):  # inf/NaN distances (near the limit) never merge
                d = x[cand] - x[i]
                S = P[cand] + P[i]
                d2 = np.einsum("ki,ki->k", d, np.linalg.solve(S, d[:, :, None])[:, :, 0])
            close = d2 <= distance
            if exclusive is not None:
                own = close & exclusive[cand]
                if exclusive[i]:
                    close &= ~own
                elif own.sum() > 1:
                    close &= ~own
                    close[np.flatnonzero(own)[np.argmin(d2[own])]] = True
            group[cand[close]] = g
        g += 1
    return group


def _check_existence(path, name, r) -> None:
    """Existence probabilities of Bernoullis a state holds lie in (0, 1].

    A Bernoulli of existence 0 is no Bernoulli: the trackers never keep one (its
    likelihood ratio r P_D g / ρ would give the association a P_D of 0).
    """
    if ((r <= 0) | (r > 1)).any():
        v = float(r[np.argmax((r <= 0) | (r > 1))])
        raise StateFileError(f"{path}: field {name!r} has values outside (0, 1] ({v!r})")


class _GatedPairs(NamedTuple):
    """Gated (Bernoulli, return) pairs in the form :func:`~jointtrack.association.clusters`
    and :meth:`~jointtrack.trackers.base.ScanTracker._pair_marginals` read."""

    n_tracks: int
    n_measurements: int
    rows: np.ndarray
    cols: np.ndarray


#: Work (in cost-matrix cells, ~15 ns each) of setting up one tuple's ranking: 0.2–0.4 ms
#: of Python per tuple, measured on a cluster of 200,000 tuples (``_ranking_cap``).
_TUPLE_WORK = 2**14

#: Association tiers from the most exact to the cheapest (the merge tier names the last it used).
_TIER_ORDER = ("exact", "enumerate", "kbest", "mcmc", "lbp", "lbp-sparse", "pda")


class _TuplePairs:
    """The gated pairs of the single-target hypotheses (STHs) one cluster tuple holds.

    ``tup`` (n,): an STH index per track of the cluster (−1: no Bernoulli);
    ``start`` the pair index of each STH's first gated pair (pairs sorted by STH).
    ``here`` the tracks holding an STH, ``sths`` those STHs, ``pairs`` their gated
    pairs, ``row_local`` each pair's position in ``sths``, ``ms`` the returns they
    gate.
    """

    __slots__ = ("here", "sths", "pairs", "row_local", "ms")

    def __init__(self, tup, rows, cols, start):
        self.here = np.flatnonzero(tup >= 0)
        self.sths = sths = tup[self.here]
        lo = start[sths]
        count = start[sths + 1] - lo
        self.row_local = np.repeat(np.arange(len(sths)), count)
        # the gated pairs of these hypotheses: lo[i] .. lo[i] + count[i] − 1 for each i
        self.pairs = np.arange(len(self.row_local)) + np.repeat(
            lo - (np.cumsum(count) - count), count
        )
        self.ms = np.unique(cols[self.pairs])


def _tuple_costs(tuples, start, miss, m):
    """What ranking each cluster tuple costs: ``(n, pairs, log_events, m)``.

    ``tuples`` (U, n_c) STH indices (−1: none); per tuple the Bernoullis ranked
    jointly ``n`` (0 when none gates anything), their gated pairs, the log of an
    upper bound of its number of events (Π_i options_i: gated returns, and the
    miss when it may miss), and its returns (at most the pairs and the cluster's
    ``m``), for :meth:`PMBMTracker._ranking_cap`.
    """
    present = tuples >= 0
    s = np.maximum(tuples, 0)
    count = np.where(present, start[s + 1] - start[s], 0)
    pairs = count.sum(axis=1)
    options = np.where(present, count + (miss[s] > 0), 1)
    with np.errstate(divide="ignore"):
        log_events = np.log(options).sum(axis=1)
    n = np.where(pairs > 0, present.sum(axis=1), 0)
    return n, pairs, log_events, np.minimum(pairs, m)


class _MergedChildren:
    """Children made by merged clusters, numbered from ``first`` on: ``(r, x, P, track,
    born, reports)``."""

    def __init__(self, first: int, n: int, modes):
        # ``modes``: empty mode arrays of the tracker (their trailing shapes)
        self.first, self.n, self.size, self.parts, self.modes = first, n, 0, [], modes

    def add(self, r, x, P, track, born, reports, modes) -> np.ndarray:
        """Append children; returns their indices."""
        idx = self.first + self.size + np.arange(len(r))
        k = len(r)
        self.parts.append(
            (
                r,
                x,
                P,
                np.asarray(track, np.int64),
                np.broadcast_to(np.asarray(born, float), (k,)),
                np.broadcast_to(np.asarray(reports, float), (k,)),
                *modes,
            )
        )
        self.size += len(r)
        return idx

    def arrays(self):
        if not self.parts:
            n = self.n
            none = np.zeros(0)
            modes = tuple(np.zeros((0, *a.shape[1:])) for a in self.modes)
            return (none, np.zeros((0, n)), np.zeros((0, n, n)), np.zeros(0, np.int64), none,
                    none, *modes)  # fmt: skip
        return tuple(np.concatenate(a) for a in zip(*self.parts, strict=True))


class PMBMTracker(_PoissonTracker):
    """Poisson multi-Bernoulli mixture tracker (García-Fernández et al. 2018; module docstring).

    State: single-target hypotheses (``sth_*``: existence, mean, covariance,
    track), the ids of the tracks, and the global hypotheses ``hyp`` (H, T)
    — for each track the index of its single-target hypothesis, −1 where the
    track has no Bernoulli in that hypothesis — with log weights ``hyp_logw``.

    >>> import numpy as np
    >>> from jointtrack.trackers.pmbm import PMBMTracker, PMBMConfig
    >>> trk = PMBMTracker(PMBMConfig(clutter_density=1e-4, birth_density=1e-6))
    >>> for t in range(8):
    ...     result = trk.step(float(t), np.array([[10.0 * t, 0.0], [500.0, 3.0 * t]]))
    >>> result.ids.tolist()
    [1, 2]
    """

    KIND = "pmbm"
    _ARRAYS = (
        "sth_r",
        "sth_x",
        "sth_P",
        "sth_track",
        "sth_born",
        "sth_reports",
        "sth_mode_x",
        "sth_mode_P",
        "sth_mode_log_prob",
        "track_ids",
        "track_reported",
        "hyp",
        "hyp_logw",
        *_PoissonTracker._POISSON,
        *_PoissonTracker._LABELLED,
    )
    _STH = ("sth_r", "sth_x", "sth_P", "sth_track", "sth_born", "sth_reports", "sth_mode_x",
            "sth_mode_P", "sth_mode_log_prob")  # fmt: skip

    def __init__(self, config=None, *, motion=None, sensor=None, sensors=None, keep_history=True):
        super().__init__(
            config, motion=motion, sensor=sensor, sensors=sensors, keep_history=keep_history
        )
        n = self.state_dim
        self.sth_r, self.sth_x, self.sth_P = np.zeros(0), np.zeros((0, n)), np.zeros((0, n, n))
        self.sth_track = np.zeros(0, np.int64)
        # each STH's birth time and reports (its own reporting rate, reporting = "async")
        self.sth_born, self.sth_reports = np.zeros(0), np.zeros(0)
        self.sth_mode_x, self.sth_mode_P, self.sth_mode_log_prob = self._new_modes(
            self.sth_x, self.sth_P
        )
        self.track_ids = np.zeros(0, np.int64)
        # reported at some scan (estimator 1): never recycled, so its id is kept
        self.track_reported = np.zeros(0, bool)
        self.hyp = np.zeros((1, 0), np.int64)  # one global hypothesis with no track
        self.hyp_logw = np.zeros(1)

    def _sth_modes(self, rows=slice(None)):
        """The STHs' IMM modes (without an IMM: zero modes, one row per STH)."""
        if self._imm is None:
            return self._new_modes(self.sth_x[rows], self.sth_P[rows])
        return self.sth_mode_x[rows], self.sth_mode_P[rows], self.sth_mode_log_prob[rows]

    def _lbp_work(self) -> int:
        """A merged cluster's sparse LBP works within ``max_ranking_work`` too (at most
        :data:`~jointtrack.association.budget.MAX_LBP_WORK`)."""
        budget = self.config.max_ranking_work
        return MAX_LBP_WORK if budget is None else min(MAX_LBP_WORK, budget)

    @property
    def n_hypotheses(self) -> int:
        """Number of global hypotheses kept."""
        return len(self.hyp_logw)

    def hypothesis_weights(self) -> np.ndarray:
        """Normalised weights of the global hypotheses (sum 1)."""
        w = np.exp(self.hyp_logw - self.hyp_logw.max())
        return w / w.sum()

    def _step(self, t, z, same_time_ok=False, labels=None, velocities=None) -> ScanResult:
        c = self.config
        t, z, dt, n_coincident = self._check_scan(t, z, same_time_ok)
        labels, repeated, velocities, n_coincident, step = self._begin_scan(
            t, z, dt, n_coincident, labels, velocities
        )
        self.sth_mode_x, self.sth_mode_P, self.sth_mode_log_prob = self._sth_modes()
        F = Q = None
        if step > 0:
            F, Q = self._poisson_motion.transition(step), self._poisson_motion.noise(step)
            self.sth_x, self.sth_P, modes = self._predict_set(
                self.sth_x, self.sth_P, self._sth_modes(), step, F, Q
            )
            self.sth_mode_x, self.sth_mode_P, self.sth_mode_log_prob = modes
            self._predict_poisson(F, Q, step)
        # each single-target hypothesis' detection over the interval (its own reporting
        # rate with reporting = "async"); scan-local, like the JPDA tracker's _scan_*
        det = self._detection(self.sth_born, self.sth_reports)
        self.sth_r = det.survival * self.sth_r
        live = self._drop_void_hypotheses()
        if live is not None:
            det = ScanDetection(*(a[live] for a in det[:5]), det.scan)
        self._det = det
        # labelled reports go to their own Bernoullis; the rest are associated here
        z_all = z
        z_index = self._labelled_scan(t, z, labels, repeated, velocities, step, F, Q)
        z = z[z_index]
        rho, e, x_new, P_new = self._poisson_detection(z)
        if velocities is not None:
            seed_velocities(x_new, P_new, velocities[z_index], c.dim, c.velocity_std)
        M, S, T = len(z), len(self.sth_r), len(self.track_ids)
        p_d = self._p_d
        # single-target hypotheses after the update (eq. (20)–(27)): children of STH s
        # are "missed" (index s) and "return j" (index S + pair); new track j is T + j
        # with hypothesis S + P + j; clusters merged past the ranking budget add
        # theirs after that (_hypotheses_after)
        if S and M:
            g = self._gate_set(self.sth_x, self.sth_P, self._sth_modes(), z)
            rows, cols = g.rows, g.cols
            L, miss = self._pair_weights(self.sth_r, g, rho, det)
        else:
            rows = cols = np.zeros(0, np.int64)
            L, miss = np.zeros(0), miss_weight(self.sth_r, det, p_d)
        n_pairs = len(rows)
        # pair index of (STH, return): pairs are sorted by STH, then return
        start = np.searchsorted(rows, np.arange(S + 1))
        new_rows, new_logw, merged, clusters = self._hypotheses_after(
            z, rows, cols, L, miss, start, S, T, n_pairs, (rho, e, x_new, P_new)
        )
        # prune and cap the global hypotheses (by normalised weight, in log space); the
        # most probable are kept whatever their weight: with many near-equal hypotheses
        # every normalised weight may be below hypothesis_prune
        new_logw = new_logw - new_logw.max()
        w = np.exp(new_logw)
        w /= w.sum()
        keep = np.flatnonzero((w >= c.hypothesis_prune) | (new_logw == 0.0))
        keep = keep[np.argsort(-w[keep], kind="stable")][: c.max_hypotheses]
        hyp, logw = new_rows[keep], new_logw[keep]
        # each return's probability of not having come from a prior track: its new
        # track's column is −1 exactly in the hypotheses that gave it to a prior one
        wk = np.exp(logw - logw.max())
        unexplained = (z, (wk @ (hyp[:, T:] >= 0)) / wk.sum())
        # the children the kept hypotheses hold, and only those, are computed (a clutter
        # burst gates millions of pairs; Kalman updates of them all would not be used)
        ref = np.unique(hyp[hyp >= 0])
        hyp = np.where(hyp >= 0, np.searchsorted(ref, np.maximum(hyp, 0)), -1)
        children = self._children(ref, S, T, z, rows, cols, (e / rho, x_new, P_new), merged)
        child_r, child_x, child_P, child_track, child_born, child_reports, child_modes = children
        # Bernoullis too unlikely to exist are dropped from every hypothesis (r = 0 always:
        # with r_prune = 0, a return outside birth_region would start a track that never goes)
        r_child = child_r[np.maximum(hyp, 0)]
        hyp = np.where((hyp >= 0) & (r_child >= c.r_prune) & (r_child > 0), hyp, -1)
        recycled = self._recycle(hyp, logw, child_r, child_x, child_P)
        # hypotheses that became identical are one hypothesis (logsumexp relative to the
        # group's largest: hypotheses below e^−745 do not underflow to −inf)
        hyp, logw = merge_identical(hyp, logw)
        # keep only referenced hypotheses and tracks, renumbered
        used = np.unique(hyp[hyp >= 0])
        track_used = np.zeros(T + M, bool)
        track_used[child_track[used]] = True
        track_map = np.cumsum(track_used) - 1
        sth_map = np.full(len(child_r), -1)
        sth_map[used] = np.arange(len(used))
        cols_kept = np.flatnonzero(track_used)
        hyp = hyp[:, cols_kept]
        self.hyp = np.where(hyp >= 0, sth_map[np.maximum(hyp, 0)], -1)
        self.hyp_logw = logw - logw.max()
        self.sth_r, self.sth_x, self.sth_P = child_r[used], child_x[used], child_P[used]
        self.sth_born, self.sth_reports = child_born[used], child_reports[used]
        self.sth_mode_x, self.sth_mode_P, self.sth_mode_log_prob = (a[used] for a in child_modes)
        self.sth_track = track_map[child_track[used]]
        born = cols_kept[cols_kept >= T]
        new_ids = np.arange(self.next_id, self.next_id + len(born))
        self.next_id += len(born)
        self.track_ids = np.concatenate([self.track_ids[cols_kept[cols_kept < T]], new_ids])
        self.track_reported = np.concatenate(
            [self.track_reported[cols_kept[cols_kept < T]], np.zeros(len(born), bool)]
        )
        order = np.argsort(-self.hyp_logw, kind="stable")
        self.hyp, self.hyp_logw = self.hyp[order], self.hyp_logw[order]
        self._thin_and_prune_poisson(recycled, unexplained)
        self.time = t
        self.n_scans += 1
        s, tracks, present = self._estimate()
        self.track_reported[tracks] = True
        gated = np.zeros(M, bool)
        gated[cols] = True
        sizes, seconds, methods, confirmed, fallbacks = clusters
        return self._result(
            t,
            self.track_ids[tracks].copy(),
            self.sth_x[s].copy(),
            self.sth_P[s].copy(),
            self.sth_r[s].copy(),
            self.sth_mode_log_prob[s],
            n_tentative=int(len(np.setdiff1d(present, tracks))),
            n_measurements=len(z_all),
            n_unassociated=int((~gated).sum()),
            cluster_sizes=sizes,
            cluster_seconds=seconds,
            cluster_methods=methods,
            cluster_confirmed=confirmed,
            cluster_fallbacks=fallbacks,
            n_coincident=n_coincident,
        )

    def _estimate(self):
        """``(sths, tracks, present)``: the STHs reported, their tracks, and the tracks
        in the best global hypothesis (the rest of them are counted as tentative).

        ``estimator = "best"``: estimator 1 of García-Fernández et al. (§VI-A), the
        Bernoullis of the most probable global hypothesis with r ≥ ``r_estimate``.
        ``estimator = "track"``: each track (one Bernoulli's lineage, one id) by its
        existence over all the global hypotheses, Σ_h w_h r_h (0 where h has no
        Bernoulli of it) ≥ ``r_estimate``, with the state of its Bernoulli in the
        most probable hypothesis that holds it; of tracks whose states are within
        ``duplicate_distance`` (alternatives for one target) only the one reported
        before, else the most probable. Why: in a cluster of close targets
        the most probable hypothesis changes from scan to scan between near-equal
        ones; estimator 1 then drops and restores tracks (and with them the
        coverage) scan by scan, while a track's existence summed over the
        hypotheses moves only as the evidence does, and its id is its lineage's.
        """
        c = self.config
        best = self.hyp[0]
        present = np.flatnonzero(best >= 0)
        if c.estimator == "best":
            s = best[present]
            report = self.sth_r[s] >= c.r_estimate
            return s[report], present[report], present
        w = self.hypothesis_weights()
        held = self.hyp >= 0
        r = np.where(held, self.sth_r[np.maximum(self.hyp, 0)], 0.0)
        existence = w @ r
        tracks = np.flatnonzero(existence >= c.r_estimate)
        # hypotheses are sorted by weight: the first that holds each track is its best
        sths = self.hyp[np.argmax(held[:, tracks], axis=0), tracks]
        if c.duplicate_distance > 0 and len(tracks) > 1:
            # tracks that are alternatives for one target (one in some hypotheses, the
            # other in the rest: a return that went to a prior track or started its own)
            # are one estimate, the track reported before (else the more probable)
            rank = np.lexsort((-existence[tracks], ~self.track_reported[tracks]))
            group = _duplicate_groups(
                self.sth_x[sths], self.sth_P[sths], rank, c.duplicate_distance, c.dim
            )
            lead = np.full(int(group.max()) + 1, -1, np.int64)
            lead[group[rank[::-1]]] = rank[::-1]
            lead = np.sort(lead)
            tracks, sths = tracks[lead], sths[lead]
        return sths, tracks, present

    def _drop_void_hypotheses(self):
        """Single-target hypotheses whose existence underflowed to 0 are no Bernoulli.

        Survival over a long gap (P_S^Δt) or many missed scans with ``r_prune = 0``
        can take r to 0; such an STH is removed from every global hypothesis (and from
        the state) before the update, whose likelihood ratios r P_D g / ρ would
        otherwise hand the association a P_D of 0. Returns the mask of the STHs
        kept (None when all are).
        """
        live = self.sth_r > 0
        if live.all():
            return None
        renumber = np.cumsum(live) - 1
        self.hyp = np.where(
            self.hyp >= 0, np.where(live, renumber, -1)[np.maximum(self.hyp, 0)], -1
        )
        for name in self._STH:
            setattr(self, name, getattr(self, name)[live])
        return live

    def _children(self, ref, S, T, z, rows, cols, born, merged):
        """``(r, x, P, track, born, reports, modes)`` of the child single-target hypotheses
        ``ref`` (sorted indices).

        Index space of :meth:`_step`: ``s < S`` the missed child of STH s, ``S + p``
        the detection child of gated pair p (Kalman update of its STH with its
        return), ``S + P + j`` the new track of return j (``born``: existence, mean
        and covariance of each return's new Bernoulli), then the children of merged
        clusters (``merged``: r, x, P, track, born, reports, modes). A child keeps its
        parent's birth time and reports (one more for a detection); a new track's
        are the scan's time and none. With an IMM a missed child keeps its parent's
        predicted modes, a detection child is the IMM update by its return and a new
        track starts with ``imm_initial``.
        """
        p_d = self._p_d
        n = self.state_dim
        n_pairs, M = len(rows), len(z)
        first_new, first_merged = S + n_pairs, S + n_pairs + M
        r_new, x_new, P_new = born
        m_r, m_x, m_P, m_track, m_born, m_reports, *m_modes = merged
        r = np.empty(len(ref))
        modes = tuple(np.empty((len(ref), *a.shape[1:])) for a in self._sth_modes())
        x = np.empty((len(ref), n))
        P = np.empty((len(ref), n, n))
        track = np.empty(len(ref), np.int64)
        t_born, reports = np.empty(len(ref)), np.empty(len(ref))
        miss = ref < S
        s = ref[miss]
        det = self._det
        r[miss] = missed_existence(self.sth_r[s], det._replace(missed=det.missed[s]), p_d)
        x[miss], P[miss], track[miss] = self.sth_x[s], self.sth_P[s], self.sth_track[s]
        t_born[miss], reports[miss] = self.sth_born[s], self.sth_reports[s]
        for a, parent in zip(modes, self._sth_modes(s), strict=True):
            a[miss] = parent
        hit = (ref >= S) & (ref < first_new)
        p = ref[hit] - S
        r[hit] = 1.0
        x[hit], P[hit], hit_modes = self._detected_set(
            self.sth_x[rows[p]], self.sth_P[rows[p]], self._sth_modes(rows[p]), z[cols[p]]
        )
        for a, child in zip(modes, hit_modes, strict=True):
            a[hit] = child
        track[hit] = self.sth_track[rows[p]]
        t_born[hit], reports[hit] = self.sth_born[rows[p]], self.sth_reports[rows[p]] + 1.0
        new = (ref >= first_new) & (ref < first_merged)
        j = ref[new] - first_new
        r[new], x[new], P[new], track[new] = r_new[j], x_new[j], P_new[j], T + j
        t_born[new], reports[new] = self._scan_t, 0.0
        for a, child in zip(modes, self._new_modes(x_new[j], P_new[j]), strict=True):
            a[new] = child
        mer = ref >= first_merged
        k = ref[mer] - first_merged
        r[mer], x[mer], P[mer], track[mer] = m_r[k], m_x[k], m_P[k], m_track[k]
        t_born[mer], reports[mer] = m_born[k], m_reports[k]
        for a, child in zip(modes, m_modes, strict=True):
            a[mer] = child[k]
        return r, x, P, track, t_born, reports, modes

    def _recycle(self, hyp, logw, child_r, child_x, child_P):
        """Never-reported tracks with existence below ``r_recycle`` go to the intensity.

        Which existence (``recycle_existence``): ``"least"``, below it in every
        global hypothesis holding the track; ``"marginal"``, Σ_h w_h r_h below it
        (normalised weights; 0 where h has no Bernoulli of the track). Each such
        track's single-target hypotheses become Gaussian components of the
        Poisson intensity with weight r × (total weight of the global
        hypotheses holding them) (Williams 2012) — summing to the track's
        marginal existence; the track is removed from every hypothesis (``hyp``
        is changed in place). Returns ``(w, m, P)``.
        """
        c = self.config
        n = self.state_dim
        none = (np.zeros(0), np.zeros((0, n)), np.zeros((0, n, n)))
        if c.r_recycle <= 0 or hyp.shape[1] == 0:
            return none
        present = hyp >= 0
        r_of = np.where(present, child_r[np.maximum(hyp, 0)], 0.0)
        reported = np.concatenate(
            [self.track_reported, np.zeros(hyp.shape[1] - len(self.track_reported), bool)]
        )
        wn = np.exp(logw - logw.max())
        wn /= wn.sum()
        if c.recycle_existence == "marginal":
            low = wn @ r_of < c.r_recycle
        else:
            low = (r_of < c.r_recycle).all(axis=0)
        weak = low & present.any(axis=0) & ~reported
        if not weak.any():
            return none
        sub = hyp[:, weak]
        hh, tt = np.nonzero(sub >= 0)
        s_idx = sub[hh, tt]
        sths, inv = np.unique(s_idx, return_inverse=True)
        w = np.bincount(inv.reshape(-1), wn[hh] * child_r[s_idx], minlength=len(sths))
        hyp[:, weak] = -1
        return w, child_x[sths], child_P[sths]

    def _hypotheses_after(self, z, rows, cols, L, miss, start, S, T, n_pairs, born):
        """Global hypotheses after the update, their log weights, merged children, clusters.

        Returns ``(rows (H', T + M), log weights (H',), merged, clusters)``: the
        child-hypothesis index of every track in every new global hypothesis,
        ``merged`` the ``(r, x, P, track)`` of the children made by clusters merged
        past the ranking budget (indices from S + n_pairs + M on), and
        ``clusters`` the ``(sizes, seconds, methods, confirmed, fallbacks)`` lists
        of :class:`~jointtrack.trackers.base.ScanResult` for every cluster with
        two or more Bernoullis to rank.

        From each prior global hypothesis h the ⌈max_hypotheses · w_h⌉ best
        association events; event weight = prior weight × Π chosen
        single-target weights / Π_j ρ_j (a factor common to all events).

        Tracks that share no gated return are independent, so the events are
        ranked per *cluster* of tracks (connected through the gated returns of
        any of their single-target hypotheses) and the ranked lists combined
        exactly. A cluster's ranking depends only on which single-target
        hypotheses it holds, so it is computed once per distinct tuple across the
        global hypotheses — a single track by sorting its options, several by
        Murty's algorithm on the package's LSAP — all tuples of a cluster in one
        compiled call (:func:`~jointtrack.trackers.pmbm_hypotheses.rank_tuples`),
        and the lists of all clusters combined for every prior hypothesis in
        another (:func:`~jointtrack.trackers.pmbm_hypotheses.combine_events`).
        Tracks that gate no return are missed in every event (their miss weight
        is a constant of the hypothesis).

        The ranking is budgeted per cluster (``max_ranking_work``,
        :meth:`_ranking_cap`): past it a cluster gets fewer events per
        hypothesis, or is merged (:meth:`_merge_cluster`).
        """
        c = self.config
        M = len(z)
        hyp = self.hyp
        k_h = np.maximum(1, np.ceil(c.max_hypotheses * self.hypothesis_weights())).astype(np.int64)
        pairs = check_pair_weights(start, cols, L, miss, M)
        log_miss = pairs.log_miss
        # clusters of the tracks that gate something (over all their hypotheses)
        groups = track_clusters(self.sth_track[rows], cols, T, M)
        # every track that gates nothing is missed: a constant per hypothesis
        quiet = np.ones(T, bool)
        quiet[groups.tracks] = False
        hq = hyp[:, quiet]
        const = np.where(hq >= 0, log_miss[np.maximum(hq, 0)], 0.0).sum(axis=1)
        merged = _MergedChildren(S + n_pairs + M, self.state_dim, self._sth_modes())
        clusters = ([], [], [], [], [])  # sizes, seconds, methods, confirmed, fallbacks
        born_as = []  # (returns, child index) of the new tracks of merged clusters
        ranked = []  # per cluster: (tracks, inverse (H,), RankedLists of its tuples)
        for g in range(len(groups.track_ptr) - 1):
            tracks = groups.tracks[groups.track_ptr[g] : groups.track_ptr[g + 1]]
            returns = groups.returns[groups.return_ptr[g] : groups.return_ptr[g + 1]]
            tuples, inv = distinct_rows(hyp[:, tracks])
            k_u = np.zeros(len(tuples), np.int64)
            np.maximum.at(k_u, inv, k_h)
            cost = _tuple_costs(tuples, start, miss, len(returns))
            cap, work = self._ranking_cap(cost, k_u)
            multi = cost[0].max() >= 2  # Bernoullis ranked jointly (Murty)
            if cap is None and not multi:  # one Bernoulli at a time: sorting
                ranked.append((tracks, inv, rank_tuples(tuples, k_u, pairs)))
                continue
            t0 = time.perf_counter()
            loud = bool(self.track_reported[tracks].any())
            where = (
                f"this cluster ({len(tracks)} tracks × {len(returns)} returns, "
                f"{len(tuples)} distinct single-target hypothesis tuples)"
            )
            over = f"~{work:.3g} units of work > max_ranking_work = {c.max_ranking_work}"
            if cap is None or (cap >= 2 and multi):
                ks = k_u if cap is None else np.minimum(k_u, cap)
                lists = rank_tuples(tuples, ks, pairs)
                method, reason = "murty", ""
                if cap is not None:
                    method = "murty-truncated"
                    reason = (
                        f"ranking_truncated: ranking the ⌈max_hypotheses · w_h⌉ (up to "
                        f"{int(k_u.max())}) best events of {where} would take {over}; "
                        f"ranked at most {cap} per hypothesis"
                    )
            else:
                lists, inv, born_idx, tier = self._merge_cluster(
                    tracks, tuples, returns, z, rows, cols, L, miss, start, born, T, merged, loud
                )
                born_as.append((returns, born_idx))
                method = f"pmb-{tier[0]}"
                reason = (
                    f"ranking_merged: ranking even the 2 best events per hypothesis of {where} "
                    f"would take {over}; merged into one Bernoulli per track (PMB) with "
                    f"marginals by {tier[0]}" + (f" ({tier[1]})" if tier[1] else "")
                )
            seconds = time.perf_counter() - t0
            if reason:
                self._log_fallback(len(tracks), len(returns), loud, reason, method)
            record = ((len(tracks), len(returns)), seconds, method, loud, reason)
            for out, value in zip(clusters, record, strict=True):
                out.append(value)
            ranked.append((tracks, inv, lists))
        new_track_hyp = S + n_pairs + np.arange(M)
        for returns, idx in born_as:
            new_track_hyp[returns] = idx
        # a track that must be detected gated nothing (const = −inf): h has no event
        out_rows, out_logw, n_events = combine_events(
            hyp, self.hyp_logw + const, k_h, new_track_hyp, ranked
        )
        if not n_events.any():
            raise InfeasibleAssignmentError(
                "no global hypothesis has an association event of positive weight "
                "(P_D = 1 and a track with existence 1 that gates no return?)"
            )
        return out_rows, out_logw, merged.arrays(), clusters

    def _ranking_cap(self, cost, k_u):
        """``(cap, work)``: how many events per hypothesis one cluster's ranking may have.

        ``cost``: :func:`_tuple_costs` of the cluster's distinct tuples, ``k_u``
        the events each must rank. ``work`` estimates the ranking in cost-matrix
        cells: Murty's algorithm solves at most 1 + (k − 1) n assignment
        problems for k events of n Bernoullis (each popped event spawns at most
        n subproblems), each scanning an n × (n + m) cost matrix (m gated
        returns), k at most the tuple's number of events; a tuple of one
        Bernoulli sorts its pairs; and every tuple costs :data:`_TUPLE_WORK`
        for its set-up. Measured: 9–26 ns per cell on the clutter clusters and
        blobs of ``benchmarks/pmbm_burst.py``. ``cap`` is None within
        ``max_ranking_work``, else the largest cap on the events per tuple that
        fits (0 when not even one event per tuple fits).
        """
        n, n_pairs, log_events, m = cost
        events = np.rint(np.exp(np.minimum(log_events, 60.0)))

        def work(cap):
            k = np.maximum(1.0, np.minimum(np.minimum(k_u, cap), events))
            murty = np.where(n >= 2, (1.0 + (k - 1.0) * n) * n * (n + m), n_pairs)
            return float((murty + _TUPLE_WORK).sum())

        k_max = int(k_u.max())
        full = work(k_max)
        budget = self.config.max_ranking_work
        if budget is None or full <= budget:
            return None, full
        lo, hi = 0, k_max  # work(lo) fits (0: nothing does), work(hi) does not
        while hi - lo > 1:
            mid = (lo + hi) // 2
            lo, hi = (mid, hi) if work(mid) <= budget else (lo, mid)
        return lo, full

    def _merge_cluster(
        self, tracks, tuples, returns, z, rows, cols, L, miss, start, born, T, merged, loud
    ):
        """One cluster past the ranking budget as one event: a PMB update of its tracks.

        The cluster's prior is first made one tuple: each track's single-target
        hypotheses across the global hypotheses are merged to one Bernoulli
        (existence Σ_h w_h r_h, the moment-matched mixture of their densities;
        the PMB projection of Williams 2015 eq. (58)–(60)) — nothing changes when
        every hypothesis holds the same tuple. That Bernoulli set is updated by
        the cluster's ``returns`` as :class:`PMBTracker` updates its own
        (:meth:`_pmb_update`: marginals of the one assignment-sum core under the
        package's budget, then each Bernoulli's mixture merged), and return j's
        new track gets existence (1 − Σ_i β_ij) e_j / ρ_j. The event is the same
        in every global hypothesis (so is the cluster's prior), so its weight is 0.

        Returns ``(lists, inverse, born_idx, (tier, reasons))``: the cluster's
        one-event ranked list for every hypothesis, the child index of the
        returns' new tracks, and the cheapest association tier used with the
        fallback reasons of the association.
        """
        rho, e, x_new, P_new = born
        n_c = len(tracks)
        if len(tuples) == 1:  # the Bernoullis as they are, with their gated pairs
            part = _TuplePairs(tuples[0], rows, cols, start)
            present, s = part.here, part.sths
            r, x, P = self.sth_r[s], self.sth_x[s], self.sth_P[s]
            t_born, reports = self.sth_born[s], self.sth_reports[s]
            modes = self._sth_modes(s)
            det = ScanDetection(*(a[s] for a in self._det[:5]), self._det.scan)
            local_rows = part.row_local
            local_cols = np.searchsorted(returns, cols[part.pairs])
            L_m, miss_m = L[part.pairs], miss[s]
        else:
            sub = self.hyp[:, tracks]
            hh, tt = np.nonzero(sub >= 0)
            s = sub[hh, tt]
            w = self.hypothesis_weights()[hh] * self.sth_r[s]
            r_m, x_m, P_m = moment_match(w, tt, self.sth_x[s], self.sth_P[s], n_c)
            present = np.flatnonzero(r_m > 0)
            r, x, P = np.minimum(r_m[present], 1.0), x_m[present], P_m[present]
            # the merged Bernoulli's age (its oldest hypothesis) and mean reports
            t_born = np.full(n_c, np.inf)
            np.minimum.at(t_born, tt, self.sth_born[s])
            mass = np.bincount(tt, w, minlength=n_c)
            reports = np.bincount(tt, w * self.sth_reports[s], minlength=n_c)
            t_born, reports = t_born[present], reports[present] / mass[present]
            modes = self._merged_modes(w, tt, s, n_c, present)
            det = self._detection(t_born, reports)
            g = self._gate_set(x, P, modes, z[returns])
            local_rows, local_cols = g.rows, g.cols
            L_m, miss_m = self._pair_weights(r, g, rho[returns], det)
        ids = self.track_ids[tracks[present]]
        r_post, x_post, P_post, taken, info, heard, modes_post = self._pmb_update(
            ids, r, x, P, z[returns], local_rows, local_cols, L_m, miss_m, loud, det, modes
        )
        r_born = np.clip(1.0 - taken, 0.0, 1.0) * e[returns] / rho[returns]
        child = np.full((1, n_c), -1, np.int64)
        child[0, present] = merged.add(
            r_post, x_post, P_post, tracks[present], t_born, reports + heard, modes_post
        )
        born_modes = self._new_modes(x_new[returns], P_new[returns])
        born_idx = merged.add(
            r_born, x_new[returns], P_new[returns], T + returns, self._scan_t, 0.0, born_modes
        )
        _, _, methods, fallbacks = info
        tier = max(methods, key=_TIER_ORDER.index, default="exact")
        why = "; ".join(dict.fromkeys(f for f in fallbacks if f))
        lists = RankedLists(np.array([0, 1]), np.zeros(1), child, np.full((1, n_c), -1, np.int64))
        return lists, np.zeros(len(self.hyp), np.int64), born_idx, (tier, why)

    def _merged_modes(self, w, tt, s, n_c, present):
        """IMM modes of the Bernoullis merged across global hypotheses: per track and
        mode, the moment match of its STHs' mode states with weights w_h r_h μ_hj, and
        the mode probabilities Σ_h w_h r_h μ_hj / Σ_h w_h r_h (zero modes without one)."""
        if self._imm is None:
            k = len(present)
            return np.zeros((k, 0, 0)), np.zeros((k, 0, 0, 0)), np.zeros((k, 0))
        mx, mP, ml = self._sth_modes(s)
        r, nc = ml.shape[1], mx.shape[2]
        wm = (w[:, None] * np.exp(ml)).reshape(-1)
        groups = (tt[:, None] * r + np.arange(r)).reshape(-1)
        mass, x, P = moment_match(wm, groups, mx.reshape(-1, nc), mP.reshape(-1, nc, nc), n_c * r)
        mass = mass.reshape(n_c, r)[present]
        with np.errstate(divide="ignore"):  # a mode's mass underflowed: its log is floored
            log_mu = np.log(np.maximum(mass / mass.sum(axis=1, keepdims=True), 1e-300))
        log_mu -= np.log(np.exp(log_mu).sum(axis=1, keepdims=True))
        return x.reshape(n_c, r, nc)[present], P.reshape(n_c, r, nc, nc)[present], log_mu

    def _validate_state(self, path, arrays, scalars):
        n = self.state_dim
        spec = {
            "sth_r": ("f", ("S",)),
            "sth_x": ("f", ("S", n)),
            "sth_P": ("f", ("S", n, n)),
            "sth_track": ("i", ("S",)),
            "sth_born": ("f", ("S",)),
            "sth_reports": ("f", ("S",)),
            "track_ids": ("i", ("T",)),
            "track_reported": ("b", ("T",)),
            "hyp": ("i", ("H", "T")),
            "hyp_logw": ("f", ("H",)),
            "poisson_w": ("f", ("C",)),
            "poisson_m": ("f", ("C", n)),
            "poisson_P": ("f", ("C", n, n)),
            "undetected_density": ("f", (1,)),
            **self._labelled_spec(),
        }
        lengths: dict = {}
        self._validate_common(path, arrays, spec, lengths)
        self._validate_labelled(path, arrays)
        validate_mode_arrays(path, arrays, self._imm, prefix="sth_", count=len(arrays["sth_r"]))

        def bad(what):
            return StateFileError(f"{path}: {what}")

        r = arrays["sth_r"]
        _check_existence(path, "sth_r", r)
        S, T = len(r), len(arrays["track_ids"])
        tr = arrays["sth_track"]
        if ((tr < 0) | (tr >= T)).any():
            raise bad("field 'sth_track' names a track that does not exist")
        bare = np.bincount(tr, minlength=T) == 0
        if bare.any():  # a track is its single-target hypotheses: none is no track
            raise bad(
                f"field 'sth_track': track {int(np.argmax(bare))} (id "
                f"{int(arrays['track_ids'][np.argmax(bare)])}) has no single-target hypothesis"
            )
        hyp = arrays["hyp"]
        if len(hyp) == 0:
            raise bad("field 'hyp' holds no global hypothesis")
        if ((hyp < -1) | (hyp >= S)).any():
            raise bad("field 'hyp' names a single-target hypothesis that does not exist")
        cols = np.broadcast_to(np.arange(T), hyp.shape)
        ok = hyp < 0
        ok |= tr[np.maximum(hyp, 0)] == cols
        if not ok.all():
            raise bad("field 'hyp' puts a single-target hypothesis under another track")
        if arrays["hyp_logw"].max() != 0.0:
            raise bad("field 'hyp_logw' is not normalised to a best hypothesis of 0")
        ids = np.concatenate([arrays["track_ids"], arrays["labelled_ids"]])
        validate_counters(path, ids, scalars, "track_ids")
