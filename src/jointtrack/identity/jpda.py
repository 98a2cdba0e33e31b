r"""Identity-aware JPDA: joint identification inside the association loop.

Reference: D. E. Schaub, "Joint Identification of Multiple Tracked Targets",
*Journal of Advances in Information Fusion*, vol. 12, no. 1, 2017 — §2-D
("Tracking and Identification using (J)PDAF"). Equation numbers below are that
paper's.

What §2-D asks for
------------------
With (J)PDA the targets' densities overlap, so the disjoint-region condition 2
of §2-B fails and the joint density is written as the sum over identity-track
permutations (34). The filter banks and the deconfliction stay as they are,
"albeit at the loss of mathematical optimality", but the *association* must
use the previous step's deconflicted weights, ``P[t, i] p_{t,i}(x)`` (the
track density (33)) rather than each bank's own coefficients — "an
optimally-implemented (J)PDA filter requires that the identity deconfliction
step be carried out prior to each new measurement".

One scan of :class:`IdentityJPDA`
---------------------------------
Tracks t = 1 … T each carry a :class:`~jointtrack.identity.filterbank.FilterBank`
(one Kalman filter per identity class c, coefficients ``log a[t, c]``). The
deconflicted matrix P (tracks × classes, per-member probabilities, eq. 31) of
the coefficients after scan k − 1 is kept; it is computed right after each
update, i.e. before the next measurement arrives, as §2-D requires. At scan k
with measurements ``z_j = [position; attribute]`` (clutter included):

a. every class filter is predicted to t (eq. 28; a unchanged);
b. ``w[t, c] = n_c P[t, c]`` — the probability that track t holds a member of
   class c (n_c members) — from the stored deconfliction;
c. the association uses the mixture (33) of the predicted class densities,
   truncated to each class's chi-square gate:

   .. math::

       g_{tj} = \sum_c w_{tc}\, p_{d,c}\, N(z_j; \hat z_{tc}, S_{tc})\,
                [d^2_{tcj} \le \gamma], \qquad
       \mathrm{miss}_t = 1 - P_G \sum_c w_{tc}\, p_{d,c},

   ``L = g / λ`` with λ the clutter density over the measured space (position
   × attribute), and ``β = association.marginals(L, miss, "exact")`` over all
   tracks at once (the exact engine splits independent clusters itself);
d. each class filter of track t is updated by PDA with the identity-conditional
   weights, and the coefficient takes the scan's identity evidence:

   .. math::

       r_{cj} = \frac{p_{d,c} N_c(z_j)}{g_{tj}}, \quad
       r_{c0} = \frac{1 - P_G\, p_{d,c}}{\mathrm{miss}_t}, \quad
       f_{tc} = \beta_{t0} r_{c0} + \sum_j \beta_{tj} r_{cj},

       \beta^{(c)}_{tj} = \beta_{tj} r_{cj} / f_{tc}, \qquad
       \log a[t, c] \mathrel{+}= \log f_{tc};

   with one detection probability for all classes ``r_c0 = 1`` and
   ``r_cj = N_c(z_j) / N_mix,t(z_j)``;
e. the updated coefficients are deconflicted (exact permanent ratios, eq. 31)
   and each track's estimate is the P-weighted mixture (33), moment matched
   (:meth:`FilterBank.mixture`).

Why f is the identity evidence
------------------------------
The JPDA normaliser Z (the sum of the weights of all joint association events)
is linear in track t's row ``(miss_t, L_t1, …, L_tM)``: every event uses
exactly one entry of it. That row is the w-mixture of the class rows
``(1 − P_G p_d,c, p_d,c N_c(z_j)/λ, …)``, so ``Z = Σ_c w_tc Z_c`` where ``Z_c``
is the normaliser with track t holding class c and every other track its
mixture; and since ``β_tj = L_tj ∂Z/∂L_tj / Z``,

.. math::

    \frac{Z_c}{Z} = \beta_{t0} r_{c0} + \sum_j \beta_{tj} r_{cj} = f_{tc} .

So f is the likelihood of the scan given that track t holds class c, up to the
factor Z, which is the same for every class of the track — a row scale of M,
which the deconfliction ignores. ``w_tc f_tc`` is the Bayes posterior of
track t's class when ``z_j`` is its return with probability ``β_tj``, and
``β^(c)`` are the association probabilities given that class
(``L^c_tj ∂Z/∂L_tj / Z_c``). With certain association (``β_t1 = 1``: one
track, one return, ``p_d P_G = 1``) ``f_tc = p_d,c N_c(z_1) / g_t1``:
Schaub's K factor (eq. 29 with p_f = 0) divided by a per-track constant.

What is approximate
-------------------
* The joint density is the permutation sum (34), but the tracker keeps only
  its factors a[t, i] and p_{t,i} (as in (20)) and the association sees each
  track through its marginal mixture (33). So each track's factor f
  conditions on *its own* class with the other tracks at their mixtures: the
  exact evidence of a full identity assignment σ, ``Z(σ)``, does not factor
  over tracks when tracks share gated measurements, and ``Π_t f_{t,σ(t)}``
  replaces it. For a track alone in its cluster f is exact.
* The class posteriors ``β^(c)_0 N(pred) + Σ_j β^(c)_j N(updated_j)`` are
  collapsed to one Gaussian by moment matching (the PDA update), so later K
  factors use approximate densities — the usual PDA loss.
* Class densities are truncated to their gates (``P_G``), Poisson clutter of
  known density λ is assumed, and every track holds a target (tracks are
  neither born nor deleted here).

Tracks and identities
---------------------
The tracker follows a known set of T targets: T tracks, started from known
states (:meth:`IdentityJPDA.start`) or from one measurement each
(:meth:`IdentityJPDA.start_on_measurements`, Schaub's flat prior, §4-A.3).
T must not exceed the number of identities I. When T < I the other I − T
identities sit on hidden tracks (eq. 1): one row group with the prior a = 1,
never observed (their returns, if any, count as clutter). More tracks than
identities (tracks that may hold no identity, the J block of eq. 77) would need
a false-track model for b and are refused.

Examples
--------
>>> import numpy as np
>>> from jointtrack.identity.jpda import IdentityJPDA
>>> from jointtrack.identity.crossing import identity_crossing, track_swapped
>>> scenario = identity_crossing(seed=1)
>>> tracker = IdentityJPDA(scenario.database, scenario.tracker_config())
>>> tracker.start(scenario.times[0], scenario.truth[:, 0], np.diag([100.0, 100.0, 1.0, 1.0]))
>>> path = []
>>> for t, Z in zip(scenario.times[1:], scenario.measurements[1:]):
...     scan = tracker.step(t, Z)
...     path.append(scan.mean[:, :2])
>>> scan.P.round(3).tolist()  # rows: tracks, columns: identities "target 0", "target 1"
[[1.0, 0.0], [0.0, 1.0]]
>>> track_swapped(np.stack(path, axis=1), scenario.truth[:, 1:, :2]).tolist()
[False, False]
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass

import numpy as np
from scipy.special import logsumexp

from jointtrack.assignment._checks import as_float
from jointtrack.association import marginals
from jointtrack.association.gating import gate_measurements
from jointtrack.filters import kalman
from jointtrack.filters.kalman import _check_psd, _check_sym
from jointtrack.filters.pda import pda_update
from jointtrack.identity.database import (
    IdentityDatabase,
    _covariance,
    _frozen,
    _real,
)
from jointtrack.identity.deconflict import deconflict
from jointtrack.identity.filterbank import FilterBank, _State

__all__ = ["IdentityJPDA", "IdentityJPDAConfig", "IdentityScan"]


# ----------------------------------------------------------------------------- configuration


@dataclass(frozen=True, eq=False)
class IdentityJPDAConfig:
    """Sensor and association settings of :class:`IdentityJPDA`.

    Parameters
    ----------
    measurement_noise : (d, d) or (d,) array_like
        R of a measurement ``[position(dim); attribute(m)]``, d = dim + m, or
        its diagonal. ``inf`` on the diagonal marks a component that is not
        measured (e.g. an attribute the sensor cannot see); its column of the
        measurements is then ignored. The positions must be measured.
    clutter_density : float > 0
        λ, expected clutter returns per unit volume of the *measured* space
        (position × measured attribute components) per scan.
    p_d : float in (0, 1] or None
        detection probability of every identity; None uses each identity's
        own ``p_d`` from the database.
    p_g : float in (0, 1]
        gate probability; γ = χ²_m⁻¹(p_g) on the measured components. 1 means
        no gate (every measurement is scored against every class).
    velocity_cov : float or (dim, dim) array_like
        initial velocity covariance of :meth:`IdentityJPDA.start_on_measurements`
        (0: Schaub's zero initial velocity, a Dirac).

    Every value is checked on construction (complex, bool, NaN and values out
    of range raise ValueError naming the field); ``measurement_noise`` is
    checked against the database by the tracker.
    """

    measurement_noise: object
    clutter_density: float
    p_d: float | None = None
    p_g: float = 0.99
    velocity_cov: object = 0.0

    def __post_init__(self):
        R = _real(self.measurement_noise, "measurement_noise", allow_nonfinite=True)
        if R.ndim not in (1, 2):
            raise ValueError(
                f"measurement_noise must be a (d, d) covariance or a (d,) vector of "
                f"variances, got shape {R.shape}"
            )
        object.__setattr__(self, "measurement_noise", _frozen(R))
        lam = as_float(self.clutter_density, "clutter_density", minimum=0.0, open_min=True)
        object.__setattr__(self, "clutter_density", lam)
        if self.p_d is not None:
            p_d = as_float(self.p_d, "p_d", minimum=0.0, maximum=1.0, open_min=True)
            object.__setattr__(self, "p_d", p_d)
        p_g = as_float(self.p_g, "p_g", minimum=0.0, maximum=1.0, open_min=True)
        object.__setattr__(self, "p_g", p_g)
        vel = _covariance(self.velocity_cov, "velocity_cov")
        object.__setattr__(self, "velocity_cov", float(vel) if vel.ndim == 0 else _frozen(vel))


@dataclass(frozen=True, eq=False)
class IdentityScan:
    """What one :meth:`IdentityJPDA.step` produced (plain arrays, T tracks, M measurements).

    Attributes
    ----------
    time : float
    mean : (T, 2·dim) ndarray
        track estimates: the mean of the P-weighted mixture (33) after the scan.
    cov : (T, 2·dim, 2·dim) ndarray
        its covariance (moment matched).
    P : (T, I) ndarray
        deconflicted track-to-identity probabilities after the scan (eq. 31),
        one column per identity.
    P_prior : (T, I) ndarray
        the probabilities the association used (after the previous scan).
    beta : (T, M + 1) ndarray
        association probabilities, column 0 = no measurement; rows sum to 1.
    """

    time: float
    mean: np.ndarray
    cov: np.ndarray
    P: np.ndarray
    P_prior: np.ndarray
    beta: np.ndarray


# ----------------------------------------------------------------------------- the tracker


class IdentityJPDA:
    """JPDA over known targets whose identities are tracked jointly (Schaub §2-D).

    See the module docstring for the algorithm, its derivation and what is
    approximate.

    Parameters
    ----------
    database : IdentityDatabase
        the identities (motion models, attributes, detection probabilities).
    config : IdentityJPDAConfig
        sensor noise, clutter density, detection and gate probabilities.

    Notes
    -----
    :meth:`start`, :meth:`start_on_measurements` and :meth:`step` compute
    everything into temporaries and assign at the end: a call that raises
    leaves the tracker exactly as it was. The arrays returned are copies.
    """

    def __init__(self, database: IdentityDatabase, config: IdentityJPDAConfig):
        if not isinstance(database, IdentityDatabase):
            raise ValueError(f"database must be an IdentityDatabase, got {type(database).__name__}")
        if not isinstance(config, IdentityJPDAConfig):
            raise ValueError(f"config must be an IdentityJPDAConfig, got {type(config).__name__}")
        self._db = database
        self._config = config
        bank = FilterBank(database, velocity_cov=config.velocity_cov)  # checks its shape
        try:
            # a start on a probe checks R against the database (shape, symmetry,
            # definiteness, infinite variances) and that every position is measured
            bank.start(0.0, np.zeros(database.measurement_dim), config.measurement_noise)
        except ValueError as exc:
            raise ValueError(f"measurement_noise: {exc}") from None
        R = config.measurement_noise
        R = np.diag(R) if R.ndim == 1 else R
        # the measured components (finite variance), positions first
        self._rows = np.flatnonzero(np.isfinite(np.diagonal(R)))
        self._R = R[np.ix_(self._rows, self._rows)]
        C = database.n_classes
        p_d = database.p_d if config.p_d is None else np.full(C, config.p_d)
        self._log_pd = np.log(p_d)
        # the class's probability of a missed or ungated return, 1 − P_G p_d,c
        self._miss_class = 1.0 - config.p_g * p_d
        self._banks: tuple[FilterBank, ...] = ()
        self._P: np.ndarray | None = None  # (T, C) per-member, after the last update

    # ------------------------------------------------------------------ state

    @property
    def database(self) -> IdentityDatabase:
        return self._db

    @property
    def config(self) -> IdentityJPDAConfig:
        return self._config

    @property
    def started(self) -> bool:
        return self._P is not None

    @property
    def n_tracks(self) -> int:
        return len(self._banks)

    def _require(self) -> np.ndarray:
        if self._P is None:
            raise RuntimeError("the tracker has no tracks: call start() first")
        return self._P

    @property
    def time(self) -> float:
        """Time of the last start or scan."""
        self._require()
        return self._banks[0].time

    @property
    def log_a(self) -> np.ndarray:
        """(T, C) log coefficients a[t, c] of the class filters (eqs. 27–29)."""
        self._require()
        return np.array([bank.log_a for bank in self._banks])

    @property
    def P(self) -> np.ndarray:
        """(T, I) deconflicted track-to-identity probabilities (eq. 31), per identity."""
        return self._require()[:, self._db.classes].copy()

    @property
    def class_mean(self) -> np.ndarray:
        """(T, C, 2·dim) means of every track's class filters."""
        self._require()
        return np.array([bank.mean for bank in self._banks])

    @property
    def class_cov(self) -> np.ndarray:
        """(T, C, 2·dim, 2·dim) covariances of every track's class filters."""
        self._require()
        return np.array([bank.cov for bank in self._banks])

    def estimate(self) -> tuple[np.ndarray, np.ndarray]:
        """Track estimates: mean (T, 2·dim) and covariance of the mixtures (33)."""
        P = self._require()
        return _mixtures(self._banks, P[:, self._db.classes])

    # ------------------------------------------------------------------ starting

    def start(self, t, x0, P0) -> None:
        """Start one track per row of ``x0`` with a known state and a uniform identity prior.

        Every class filter of track k starts at ``N(x0[k], P0[k])`` and
        ``a[k, c] = 1`` (Schaub's M¹ = 1): the identity is unknown. Calling it
        again restarts the tracker.

        Parameters
        ----------
        t : float
        x0 : (T, 2·dim) array_like
            states ``[position, velocity]``; 1 ≤ T ≤ number of identities.
        P0 : (2·dim, 2·dim) or (T, 2·dim, 2·dim) array_like
            symmetric positive semi-definite covariances.
        """
        db = self._db
        t = as_float(t, "t")
        n = db.state_dim
        x0 = _real(x0, "x0")
        if x0.ndim != 2 or x0.shape[1] != n:
            raise ValueError(f"x0 must have shape (T, {n}) (one state per track), got {x0.shape}")
        T = self._check_count(x0.shape[0], "x0")
        P0 = _real(P0, "P0")
        if P0.shape == (n, n):
            P0 = np.broadcast_to(P0, (T, n, n))
        elif P0.shape != (T, n, n):
            raise ValueError(f"P0 must have shape ({n}, {n}) or ({T}, {n}, {n}), got {P0.shape}")
        P0 = _check_sym(np.array(P0), "P0", True)
        _check_psd(P0, "P0", True)
        C = db.n_classes
        banks = []
        for k in range(T):
            state = _State(
                t,
                np.repeat(x0[k][None], C, axis=0),
                np.repeat(P0[k][None], C, axis=0),
                np.zeros(C),
                0.0,
            )
            banks.append(self._bank(state))
        self._commit(tuple(banks), self._deconflict(banks))

    def start_on_measurements(self, t, measurements) -> None:
        """Start one track per measurement with Schaub's flat prior (§4-A.3).

        Each row goes through :meth:`FilterBank.start`: position from the
        measurement, velocity ``N(0, config.velocity_cov)``, and ``log a`` the
        evidence of the measured attribute. Every measurement is taken to be a
        target's (p_f = 0).

        Parameters
        ----------
        t : float
        measurements : (T, dim + attribute_dim) array_like
            1 ≤ T ≤ number of identities; unmeasured components may be NaN.
        """
        t = as_float(t, "t")
        Z = self._measurement_table(measurements)
        T = self._check_count(Z.shape[0], "measurements")
        banks = []
        for k in range(T):
            bank = FilterBank(self._db, velocity_cov=self._config.velocity_cov)
            try:
                bank.start(t, Z[k], self._config.measurement_noise, p_d=self._config.p_d)
            except ValueError as exc:
                raise ValueError(f"measurements[{k}]: {exc}") from None
            banks.append(bank)
        self._commit(tuple(banks), self._deconflict(banks))

    def _check_count(self, T: int, name: str) -> int:
        I = self._db.n_identities
        if not 1 <= T <= I:
            raise ValueError(
                f"{name} has {T} rows (tracks); give between 1 and the number of identities "
                f"({I}): more tracks than identities would need a false-track model"
            )
        return T

    def _bank(self, state: _State) -> FilterBank:
        bank = FilterBank(self._db, velocity_cov=self._config.velocity_cov)
        bank._state = state  # a bank is a filter state; FilterBank has no public setter
        return bank

    def _commit(self, banks: tuple[FilterBank, ...], P: np.ndarray) -> None:
        self._banks, self._P = banks, P

    # ------------------------------------------------------------------ one scan

    def step(self, t, measurements) -> IdentityScan:
        """Process the measurements of one scan at time t (see the module docstring, a–e).

        Parameters
        ----------
        t : float
            scan time, later than the tracker's time.
        measurements : (M, dim + attribute_dim) array_like
            positions and attribute readings of every return of the scan,
            clutter included, in any order; M may be 0. Components marked
            unmeasured by ``measurement_noise`` are ignored (may be NaN).

        Returns
        -------
        IdentityScan

        Raises
        ------
        ValueError
            bad ``t`` or ``measurements`` (named); a scale that overflows.
        RuntimeError
            the tracker has not been started.
        """
        P_prior = self._require()
        t = as_float(t, "t")
        if not t > self.time:
            raise ValueError(
                f"t = {t:g} is not after the tracker's time {self.time:g}; scan times must increase"
            )
        Z = self._measurement_table(measurements)[:, self._rows]
        db, cfg = self._db, self._config
        T, C, M = self.n_tracks, db.n_classes, Z.shape[0]

        # a. prediction of every class filter (eq. 28), on copies of the banks
        preds = [copy.copy(bank) for bank in self._banks]
        for pred in preds:
            pred.predict(t)
        x = np.concatenate([pred.mean for pred in preds])  # (T·C, n), track-major
        P_kin = np.concatenate([pred.cov for pred in preds])
        # the predictive density N(z; ẑ_c, S_c) of the measured components per class:
        # the attribute sits at its Dirac value A_c with zero state variance (eq. 3)
        p = db.dim  # the positions are measured and come first
        pos_pred, S_pos = kalman.predict_measurement(
            x, P_kin, np.eye(p, db.state_dim), self._R[:p, :p]
        )
        attrs = np.tile(db.attributes[:, self._rows[p:] - p], (T, 1))
        z_pred = np.concatenate([pos_pred, attrs], axis=1)
        S = np.repeat(self._R[None], T * C, axis=0)
        S[:, :p, :p] = S_pos
        gates = gate_measurements(z_pred, S, Z, P_G=cfg.p_g)

        # b–c. association with the previous deconfliction's mixtures (33)
        w = P_prior * db.class_counts  # P(track t holds a member of class c)
        # log p_d,c N_c(z_j) inside class c's gate, −inf outside (the truncated density)
        log_det = np.where(gates.mask, gates.log_g, -np.inf).reshape(T, C, M)
        log_det = log_det + self._log_pd[None, :, None]
        with np.errstate(divide="ignore"):
            log_w = np.log(w)
        log_mix = logsumexp(log_w[:, :, None] + log_det, axis=1)  # (T, M)
        with np.errstate(over="ignore"):
            L = np.exp(log_mix - math.log(cfg.clutter_density))
        if not np.isfinite(L).all():
            raise ValueError(
                "clutter_density is too small for these measurement densities: the "
                "likelihood ratios overflow"
            )
        miss = np.clip(w @ self._miss_class, 0.0, 1.0)  # 1 − P_G Σ_c w_tc p_d,c
        beta = marginals(L, miss, "exact")

        # d. identity-conditional association weights and the identity evidence f
        with np.errstate(divide="ignore", invalid="ignore"):
            log_r_det = np.where(
                np.isfinite(log_mix)[:, None, :], log_det - log_mix[:, None], -np.inf
            )
            log_r_miss = np.where(
                miss[:, None] > 0, np.log(self._miss_class)[None] - np.log(miss)[:, None], -np.inf
            )
            log_beta = np.log(beta)
        log_terms = np.concatenate([log_r_miss[:, :, None], log_r_det], axis=2)
        log_terms = np.where(beta[:, None, :] > 0, log_terms + log_beta[:, None, :], -np.inf)
        log_f = logsumexp(log_terms, axis=2)  # (T, C)
        possible = np.isfinite(log_f)
        with np.errstate(invalid="ignore"):
            beta_class = np.where(possible[:, :, None], np.exp(log_terms - log_f[:, :, None]), 0.0)
        beta_class[~possible, 0] = 1.0  # a class that explains nothing: prediction only

        try:
            mean, cov = self._pda(x, P_kin, Z, beta_class.reshape(T * C, M + 1))
        except ValueError as exc:
            raise ValueError(f"the update at t = {t:g}: {exc}") from None
        if not (np.isfinite(mean).all() and np.isfinite(cov).all()):
            raise ValueError(
                f"the update at t = {t:g} overflowed; check the scales of the measurements "
                "and measurement_noise"
            )
        banks = [
            self._bank(
                _State(
                    t,
                    mean[k * C : (k + 1) * C],
                    cov[k * C : (k + 1) * C],
                    pred.log_a + log_f[k],
                    pred.log_b,
                )
            )
            for k, pred in enumerate(preds)
        ]

        # e. deconfliction of the updated coefficients (31) and the estimates (33)
        P_post = self._deconflict(banks)
        P_ident = P_post[:, db.classes]
        mean, cov = _mixtures(banks, P_ident)
        self._commit(tuple(banks), P_post)
        return IdentityScan(
            time=t,
            mean=mean,
            cov=cov,
            P=P_ident,
            P_prior=P_prior[:, db.classes],
            beta=beta,
        )

    # ------------------------------------------------------------------ helpers

    def _pda(self, x, P, Z, beta):
        """PDA update of the (T·C) class filters with their identity-conditional β.

        The attribute is known given the class (its Dirac value), so the update
        of the augmented state restricted to the kinematics is the update by the
        positions conditioned on the attribute residual ``ν_a = z_attr − A_c``:
        ``z_pos − R_pa R_aa⁻¹ ν_a`` with noise ``R_pp − R_pa R_aa⁻¹ R_ap`` (as in
        the filter bank's own update). Without correlation that is the plain
        position update, one batch for every filter.
        """
        db = self._db
        R, rows = self._R, self._rows
        p = db.dim  # the positions are measured and come first
        H = np.eye(p, db.state_dim)
        Rpa = R[:p, p:]
        if not Rpa.any():
            return pda_update(x, P, Z[:, :p], H, R[:p, :p], beta)
        gain = np.linalg.solve(R[p:, p:], Rpa.T).T  # R_pa R_aa⁻¹
        R_cond = R[:p, :p] - gain @ Rpa.T
        R_cond = 0.5 * (R_cond + R_cond.T)
        attrs = db.attributes[:, rows[p:] - p]
        mean, cov = np.empty_like(x), np.empty_like(P)
        C = db.n_classes
        for c in range(C):
            z_cond = Z[:, :p] - (Z[:, p:] - attrs[c]) @ gain.T
            mean[c::C], cov[c::C] = pda_update(x[c::C], P[c::C], z_cond, H, R_cond, beta[c::C])
        return mean, cov

    def _measurement_table(self, measurements) -> np.ndarray:
        """``measurements`` as (M, d); its measured components must be finite."""
        d = self._db.measurement_dim
        Z = _real(measurements, "measurements", allow_nonfinite=True)
        if Z.size == 0 and Z.ndim <= 2:
            Z = Z.reshape(0, d)
        if Z.ndim != 2 or Z.shape[1] != d:
            raise ValueError(
                f"measurements must have shape (M, {d}): {self._db.dim} position and "
                f"{self._db.attribute_dim} attribute component(s) per return, got {Z.shape}"
            )
        measured = Z[:, self._rows]
        if not np.isfinite(measured).all():
            j, col = np.argwhere(~np.isfinite(measured))[0]
            col = int(self._rows[col])
            raise ValueError(
                f"measurements[{j}, {col}] = {Z[j, col]} is not finite, but "
                f"measurement_noise says component {col} is measured"
            )
        return Z

    def _deconflict(self, banks) -> np.ndarray:
        """Per-member P (T, C) of the observed tracks; hidden tracks fill up to I (eq. 1)."""
        db = self._db
        log_A = np.array([bank.log_a for bank in banks])
        rows = np.ones(len(banks), np.int64)
        n_hidden = db.n_identities - len(banks)
        if n_hidden:
            log_A = np.vstack([log_A, np.zeros(db.n_classes)])  # the prior row, a = 1
            rows = np.append(rows, n_hidden)
        result = deconflict(
            log_M=log_A, row_counts=rows, col_counts=db.class_counts, method="exact"
        )
        return np.ascontiguousarray(result.P[: len(banks)])


def _mixtures(banks, P_ident: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Means and covariances of the track mixtures (33), one row of P per bank."""
    pairs = [bank.mixture(row) for bank, row in zip(banks, P_ident, strict=True)]
    return np.array([m for m, _ in pairs]), np.array([c for _, c in pairs])
