"""Seeded simulation of targets and detections: the :class:`Scenario` container.

Motion: nearly-constant velocity (NCV, the continuous white-noise acceleration
model, Bar-Shalom, Li & Kirubarajan 2001 §6.2.2), state blocked by derivative
order ``[x, y, vx, vy]`` (3-D: ``[x, y, z, vx, vy, vz]``) — the layout of
:mod:`jointtrack.models` — with, per axis and scan interval T,

    F = [[1, T], [0, 1]],    Q = q · [[T³/3, T²/2], [T²/2, T]]

(q the acceleration power spectral density, m²/s³), each axis independent.

Measurements: each live target is detected independently with probability
P_D; a detection is ``z = H x + v``, ``H = [I 0]`` (the position), ``v ~ N(0, R)``.
Target detections are *not* clipped to the surveillance region.

Clutter: Poisson-distributed in number with mean ``clutter_rate`` per scan and
uniform over the surveillance region (a box), i.e. a Poisson point process of
spatial density ``clutter_density = clutter_rate / |region|``.

Within a scan the detections are shuffled, so their order does not reveal their
origin; ``origins[k][j]`` records it (target id, or −1 for clutter).

Randomness: every generator takes ``seed`` = a :class:`numpy.random.Generator`
(used as is and advanced), an ``int`` or ``None`` (fresh OS entropy); the same
integer seed gives bit-identical scenarios. The truth is drawn first, then the
detections scan by scan.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from jointtrack.io import Detections

__all__ = ["Scenario", "ncv_matrices", "propagate_ncv", "simulate_scenario"]


def _rng(seed) -> np.random.Generator:
    if isinstance(seed, np.random.Generator):
        return seed
    if seed is None:
        return np.random.default_rng()
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer):
        raise ValueError(
            f"seed must be a numpy.random.Generator, an int or None, got {type(seed).__name__}"
        )
    if seed < 0:
        raise ValueError(f"seed must be a non-negative integer, got {seed}")
    return np.random.default_rng(int(seed))


def _seed_value(seed):
    if isinstance(seed, int | np.integer) and not isinstance(seed, bool):
        return int(seed)
    return None


def _real(x, name: str) -> float:
    """``x`` as a float; a bool, a complex, a non-number or an int beyond the float
    range raises ValueError naming ``name`` (``float(True)`` would pass as 1.0)."""
    if isinstance(x, bool | np.bool_) or isinstance(x, complex | np.complexfloating):
        raise ValueError(f"{name} must be a real number, got {x!r}")
    try:
        return float(x)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, got {x!r}") from None
    except OverflowError:
        raise ValueError(f"{name} must be finite, got an integer beyond the float range") from None


def _pos_float(x, name: str, allow_zero: bool = False) -> float:
    x = _real(x, name)
    ok = math.isfinite(x) and (x >= 0 if allow_zero else x > 0)
    if not ok:
        raise ValueError(f"{name} must be finite and {'>= 0' if allow_zero else '> 0'}, got {x}")
    return x


def _prob(x, name: str, allow_zero: bool = False) -> float:
    x = _real(x, name)
    if not ((0 <= x if allow_zero else 0 < x) and x <= 1):
        raise ValueError(f"{name} must be in {'[0, 1]' if allow_zero else '(0, 1]'}, got {x}")
    return x


def _count(x, name: str, minimum: int = 1) -> int:
    if isinstance(x, bool) or not isinstance(x, int | np.integer) or x < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum}, got {x!r}")
    return int(x)


def ncv_matrices(dt: float, q: float, dim: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """NCV transition ``F`` and process noise ``Q`` for state ``[pos, vel]`` in ``dim`` axes.

    ``F = [[I, T I], [0, I]]``, ``Q = q [[T³/3 I, T²/2 I], [T²/2 I, T I]]``.
    """
    dt = _pos_float(dt, "dt")
    q = _pos_float(q, "process noise q", allow_zero=True)
    dim = _count(dim, "dim")
    I = np.eye(dim)
    F = np.block([[I, dt * I], [np.zeros((dim, dim)), I]])
    Q = q * np.block([[dt**3 / 3 * I, dt**2 / 2 * I], [dt**2 / 2 * I, dt * I]])
    return F, Q


def _noise_factor(Q: np.ndarray) -> np.ndarray:
    """A matrix ``L`` with ``L Lᵀ = Q`` for symmetric PSD ``Q`` (zero allowed)."""
    w, V = np.linalg.eigh(Q)
    return V * np.sqrt(np.clip(w, 0.0, None))


@dataclass(frozen=True, eq=False)
class Scenario:
    """A simulated multi-target scenario: truth, detections and the model used.

    Attributes
    ----------
    name : generator name (``"bojilov"``, ``"crossing"``, ``"many_targets"``, …).
    times : (K,) float64 scan times (s), strictly increasing.
    dt : nominal scan interval (s).
    truth_ids : K int64 arrays ``(n_k,)`` — ids of the targets alive at scan k
        (sorted ascending for the built-in generators).
    truth_states : K float64 arrays ``(n_k, 2·dim)`` — their NCV states
        ``[x, y, vx, vy]`` (positions first), row-aligned with ``truth_ids``.
    detections : K float64 arrays ``(M_k, dim)`` — all measured positions at
        scan k (target detections and clutter, shuffled).
    origins : K int64 arrays ``(M_k,)`` — target id of each detection, −1 for
        clutter.
    region : (dim, 2) surveillance box ``[[xmin, xmax], [ymin, ymax]]``; clutter
        is uniform in it.
    p_d : detection probability P_D.
    clutter_rate : mean number of clutter detections per scan (Poisson).
    clutter_density : clutter spatial density λ = clutter_rate / |region|, in
        detections per unit area (volume) per scan — the λ of the tracker's
        likelihood ratios ``P_D g / λ``.
    R : (dim, dim) measurement noise covariance; ``H = [I 0]``.
    process_noise : NCV acceleration spectral density q (m²/s³) of the truth.
    motion_model : ``"ncv"``.
    seed : the integer seed used, or None (a Generator or OS entropy).
    info : generator-specific numbers (e.g. Bojilov's β and nominal gate).
    """

    name: str
    times: np.ndarray
    dt: float
    truth_ids: tuple
    truth_states: tuple
    detections: tuple
    origins: tuple
    region: np.ndarray
    p_d: float
    clutter_rate: float
    clutter_density: float
    R: np.ndarray
    process_noise: float
    motion_model: str = "ncv"
    seed: int | None = None
    info: Mapping = field(default_factory=dict)

    @property
    def dim(self) -> int:
        """Spatial dimension d (2 or 3)."""
        return int(self.region.shape[0])

    @property
    def n_scans(self) -> int:
        return int(self.times.size)

    def __len__(self) -> int:
        return self.n_scans

    @property
    def truth_positions(self) -> tuple:
        """K arrays ``(n_k, dim)``: the true positions at each scan."""
        return tuple(s[:, : self.dim] for s in self.truth_states)

    @property
    def target_ids(self) -> np.ndarray:
        """Sorted ids of every target that is alive at some scan."""
        if not self.truth_ids:
            return np.zeros(0, dtype=np.int64)
        return np.unique(np.concatenate(self.truth_ids))

    @property
    def n_targets(self) -> int:
        """Number of distinct targets over the whole scenario."""
        return int(self.target_ids.size)

    def is_clutter(self, k: int) -> np.ndarray:
        """Boolean mask of the clutter detections at scan k."""
        return self.origins[k] < 0

    def as_detections(self) -> Detections:
        """The detections as :class:`jointtrack.io.Detections` (what a tracker consumes)."""
        return Detections(
            times=self.times, scans=self.detections, sensors=None, dim=self.dim, source=None
        )

    def tracker_config(self, **overrides):
        """The :class:`~jointtrack.TrackerConfig` matched to how this scenario was made.

        The settings are those ``jointtrack run --scenario`` derives
        (:func:`jointtrack.experiments.config.scenario_tracker_settings`, the one
        mapping): ``dim``, NCV motion (``motion="cv"``) with the truth's process
        noise q, ``measurement_noise`` = R, ``p_d``, ``p_g`` (the scenario's, else
        0.99), the clutter density λ the clutter was drawn with (``None``, i.e.
        estimated, for a scene without clutter) and ``max_speed`` = 1.5 × the
        fastest true speed. The scan interval needs no setting: the tracker takes
        it from the times passed to ``step`` (``self.times``, spaced ``self.dt``).

        Parameters
        ----------
        **overrides
            any :class:`~jointtrack.TrackerConfig` field, replacing the derived
            value (e.g. ``association="lbp"``, ``existence=False``). An unknown
            name or a bad value raises ValueError naming it; ``dim`` may only
            restate the scenario's own.

        Returns
        -------
        TrackerConfig

        Examples
        --------
        >>> from jointtrack import JPDATracker
        >>> from jointtrack.scenarios import crossing
        >>> sc = crossing(seed=1)  # R = 100 I, q = 0.01, P_D = 0.9
        >>> cfg = sc.tracker_config()
        >>> cfg.measurement_noise, cfg.process_noise, cfg.p_d
        (100.0, 0.01, 0.9)
        >>> trk = JPDATracker(sc.tracker_config(association="lbp"))
        >>> sc.tracker_config(measurment_noise=1.0)  # doctest: +ELLIPSIS
        Traceback (most recent call last):
        ...
        ValueError: unknown tracker setting(s): measurment_noise; known: ...
        """
        # imported here: experiments builds on scenarios, not the other way round
        from jointtrack.experiments.config import scenario_tracker_settings
        from jointtrack.trackers.config import TrackerConfig

        if "dim" in overrides and overrides["dim"] != self.dim:
            raise ValueError(
                f"dim = {overrides['dim']!r} does not match the {self.dim}-D scenario "
                f"{self.name!r}; leave dim out"
            )
        return TrackerConfig.from_dict({**scenario_tracker_settings(self), **overrides})

    def truth_table(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Flat truth ``(times (R,), ids (R,), positions (R, dim))`` for the metrics."""
        n = [a.size for a in self.truth_ids]
        times = np.repeat(self.times, n)
        if sum(n) == 0:
            return times, np.zeros(0, np.int64), np.zeros((0, self.dim))
        ids = np.concatenate(self.truth_ids)
        pos = np.concatenate(self.truth_positions, axis=0)
        return times, ids, pos


def _check_region(region) -> np.ndarray:
    try:
        B = np.asarray(region, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError("region must be a numeric (dim, 2) array of [min, max] rows") from None
    if B.ndim != 2 or B.shape[1] != 2 or not 1 <= B.shape[0] <= 3:
        raise ValueError(f"region must have shape (dim, 2) with dim in 1..3, got {B.shape}")
    if not np.all(np.isfinite(B)) or np.any(B[:, 1] <= B[:, 0]):
        raise ValueError(f"region rows must be finite [min, max] with min < max, got {B.tolist()}")
    return B


def simulate_scenario(
    name: str,
    times,
    truth_ids,
    truth_states,
    *,
    region,
    p_d: float,
    clutter_rate: float,
    R,
    process_noise: float,
    rng,
    info: Mapping | None = None,
    seed=None,
    dt: float | None = None,
) -> Scenario:
    """Draw detections for a given truth and package everything as a :class:`Scenario`.

    ``truth_ids``/``truth_states`` are per-scan sequences as in :class:`Scenario`.
    For each scan: each target is detected with probability ``p_d`` at
    ``pos + v``, ``v ~ N(0, R)``; ``Poisson(clutter_rate)`` clutter points are
    uniform in ``region``; the detections are shuffled. ``rng`` is a
    Generator, int or None; ``seed`` is only recorded in the result; ``dt``
    (default: the median scan interval) is the nominal scan interval.
    """
    rng = _rng(rng)
    region = _check_region(region)
    dim = region.shape[0]
    p_d = _prob(p_d, "p_d")
    clutter_rate = _pos_float(clutter_rate, "clutter_rate", allow_zero=True)
    process_noise = _pos_float(process_noise, "process_noise", allow_zero=True)
    R = np.asarray(R, dtype=np.float64)
    if R.shape != (dim, dim) or not np.all(np.isfinite(R)) or not np.allclose(R, R.T):
        raise ValueError(f"R must be a finite symmetric ({dim}, {dim}) matrix, got {R.shape}")
    if np.linalg.eigvalsh(R).min() <= 0:
        raise ValueError("R must be positive definite")
    times = np.asarray(times, dtype=np.float64)
    if times.ndim != 1 or (times.size > 1 and np.any(np.diff(times) <= 0)):
        raise ValueError("times must be a strictly increasing 1-D array")
    K = times.size
    if len(truth_ids) != K or len(truth_states) != K:
        raise ValueError("truth_ids and truth_states need one entry per scan")
    LR = np.linalg.cholesky(R)
    volume = float(np.prod(region[:, 1] - region[:, 0]))
    ids_out, st_out, det_out, org_out = [], [], [], []
    for k in range(K):
        ids = np.asarray(truth_ids[k], dtype=np.int64).reshape(-1)
        X = np.asarray(truth_states[k], dtype=np.float64).reshape(ids.size, 2 * dim)
        detected = rng.random(ids.size) < p_d
        z_t = X[detected, :dim] + rng.standard_normal((int(detected.sum()), dim)) @ LR.T
        n_c = int(rng.poisson(clutter_rate))
        z_c = region[:, 0] + rng.random((n_c, dim)) * (region[:, 1] - region[:, 0])
        Z = np.concatenate([z_t, z_c], axis=0)
        org = np.concatenate([ids[detected], np.full(n_c, -1, dtype=np.int64)])
        perm = rng.permutation(Z.shape[0])
        ids_out.append(ids)
        st_out.append(X)
        det_out.append(Z[perm])
        org_out.append(org[perm])
    return Scenario(
        name=name,
        times=times,
        dt=_pos_float(dt, "dt")
        if dt is not None
        else (float(np.median(np.diff(times))) if K > 1 else 1.0),
        truth_ids=tuple(ids_out),
        truth_states=tuple(st_out),
        detections=tuple(det_out),
        origins=tuple(org_out),
        region=region,
        p_d=p_d,
        clutter_rate=clutter_rate,
        clutter_density=clutter_rate / volume,
        R=R.copy(),
        process_noise=float(process_noise),
        motion_model="ncv",
        seed=_seed_value(seed),
        info=dict(info or {}),
    )


def propagate_ncv(x0: np.ndarray, n_scans: int, dt: float, q: float, rng) -> np.ndarray:
    """NCV trajectories of ``N`` targets: ``(n_scans, N, 2·dim)`` from ``x0`` (N, 2·dim).

    Scan 0 is ``x0`` itself; then ``x_{k+1} = F x_k + w_k``, ``w_k ~ N(0, Q)``.
    ``rng`` is a Generator, int or None.
    """
    rng = _rng(rng)
    n_scans = _count(n_scans, "n_scans")
    x0 = np.asarray(x0, dtype=np.float64)
    if x0.ndim != 2 or x0.shape[1] not in (2, 4, 6) or not np.all(np.isfinite(x0)):
        raise ValueError(f"x0 must be a finite (N, 2·dim) array of NCV states, got {x0.shape}")
    N, n = x0.shape
    dim = n // 2
    F, Q = ncv_matrices(dt, q, dim)
    L = _noise_factor(Q)
    out = np.empty((n_scans, N, n))
    out[0] = x0
    for k in range(1, n_scans):
        out[k] = out[k - 1] @ F.T + rng.standard_normal((N, n)) @ L.T
    return out
