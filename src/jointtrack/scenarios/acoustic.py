"""The ``acoustic`` scenario: amplitude sensors that sum every target's contribution.

A superpositional sensor network after the acoustic example of S. Nannuru,
M. Coates and R. Mahler, "Computationally-tractable approximate PHD and CPHD
filters for superpositional sensors", IEEE J. Sel. Topics Signal Process.
7(3):410-420, 2013 (and the technical report S. Nannuru and M. Coates,
"Gaussian approximation for superpositional sensors", McGill University, 2015,
eq. (1)): a 40 m × 40 m region watched by 5 × 5 amplitude sensors on a 10 m
grid (0, 10, …, 40 in each axis). Sensor ``s`` reads

.. math::

    y_s = \\sum_{x \\in X} g_s(x) + v_s, \\qquad
    g_s(x) = \\frac{\\Psi}{\\lVert p(x) - s \\rVert + d_0}, \\qquad
    v_s \\sim \\mathcal{N}(0, \\sigma_0^2)

with ``p(x)`` the position part of the state ``x = (px, py, vx, vy)``,
``Ψ = 10``, ``d0 = 0.1`` and ``σ0² = 0.01``, the noise independent across
sensors and scans. There are no detections: each scan is one vector of 25
readings.

Targets move by the nearly-constant-velocity model of
:mod:`jointtrack.scenarios.simulate` (:func:`ncv_matrices`). Between 3 and 5
targets appear over the run (drawn from the seed): at least two from the first
scan, the others born between 20 % and 50 % of the run, and one of the first
targets dies between 65 % and 90 % of the run, so every run has births and a
death; a target that leaves the region dies there. Starting positions are
uniform in the central 24 m × 24 m, headings uniform, speeds uniform in
``speed_range``.

Examples
--------
>>> sc = acoustic(seed=1, n_scans=10)
>>> sc.measurements.shape, sc.sensors.shape
((10, 25), (25, 2))
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from jointtrack.assignment._checks import as_float, as_int
from jointtrack.scenarios.simulate import _noise_factor, _rng, _seed_value, ncv_matrices

__all__ = [
    "ACOUSTIC_D0",
    "ACOUSTIC_NOISE_VARIANCE",
    "ACOUSTIC_PSI",
    "ACOUSTIC_REGION",
    "AcousticScenario",
    "acoustic",
    "acoustic_gain",
    "acoustic_sensor_grid",
]

#: Source amplitude Ψ of every target.
ACOUSTIC_PSI = 10.0
#: Distance offset d0 (m) that keeps g finite at a sensor.
ACOUSTIC_D0 = 0.1
#: Noise variance σ0² of each sensor reading.
ACOUSTIC_NOISE_VARIANCE = 0.01
#: The surveillance region [[xmin, xmax], [ymin, ymax]] (m).
ACOUSTIC_REGION = ((0.0, 40.0), (0.0, 40.0))


def acoustic_sensor_grid(spacing: float = 10.0, extent: float = 40.0) -> np.ndarray:
    """Sensor positions ``(S, 2)`` on a square grid ``0, spacing, …, extent`` (row-major in y).

    >>> acoustic_sensor_grid()[:3]
    array([[ 0.,  0.],
           [10.,  0.],
           [20.,  0.]])
    """
    spacing = as_float(spacing, "spacing", minimum=0.0, open_min=True)
    extent = as_float(extent, "extent", minimum=0.0, open_min=True)
    ticks = np.arange(0.0, extent + 0.5 * spacing, spacing)
    gx, gy = np.meshgrid(ticks, ticks)
    return np.column_stack([gx.ravel(), gy.ravel()])


def acoustic_gain(x, sensors, psi: float = ACOUSTIC_PSI, d0: float = ACOUSTIC_D0) -> np.ndarray:
    """Noise-free readings ``g(x)`` of every sensor: ``(..., S)`` for states ``(..., d)``.

    Only the first two state components (the position) are used, so ``x`` may
    be positions ``(..., 2)`` or full NCV states ``(..., 4)``.

    .. math:: g_s(x) = \\Psi / (\\lVert p(x) - s \\rVert + d_0)

    >>> acoustic_gain([[0.0, 0.0]], [[0.0, 0.0], [10.0, 0.0]]).round(3).tolist()
    [[100.0, 0.99]]
    """
    x = np.asarray(x, dtype=np.float64)
    sensors = np.asarray(sensors, dtype=np.float64)
    # per axis, (..., S): contiguous arrays, ~5x faster than a (..., S, 2) difference
    dx = x[..., 0, None] - sensors[:, 0]
    dy = x[..., 1, None] - sensors[:, 1]
    return psi / (np.sqrt(dx * dx + dy * dy) + d0)


@dataclass(frozen=True, eq=False)
class AcousticScenario:
    """Truth and sensor readings of one run of :func:`acoustic`.

    Attributes
    ----------
    name : ``"acoustic"``.
    times : (K,) scan times (s).
    dt : scan interval (s).
    truth_ids : K int64 arrays ``(n_k,)`` — ids of the targets alive at scan k.
    truth_states : K float64 arrays ``(n_k, 4)`` — their states ``(px, py, vx, vy)``.
    measurements : (K, S) sensor readings, one row per scan.
    sensors : (S, 2) sensor positions.
    psi, d0, noise_variance : the measurement model (module docstring).
    region : (2, 2) box ``[[xmin, xmax], [ymin, ymax]]``.
    process_noise : NCV acceleration spectral density q of the truth (m²/s³).
    seed : the integer seed, or None.
    info : births, deaths and the draws that made them.
    """

    name: str
    times: np.ndarray
    dt: float
    truth_ids: tuple
    truth_states: tuple
    measurements: np.ndarray
    sensors: np.ndarray
    psi: float
    d0: float
    noise_variance: float
    region: np.ndarray
    process_noise: float
    seed: int | None = None
    info: Mapping = field(default_factory=dict)

    dim = 2

    @property
    def n_scans(self) -> int:
        return int(self.times.size)

    def __len__(self) -> int:
        return self.n_scans

    @property
    def noise_cov(self) -> np.ndarray:
        """(S, S) measurement noise covariance σ0² I."""
        return self.noise_variance * np.eye(self.sensors.shape[0])

    def g(self, x) -> np.ndarray:
        """The noise-free readings ``(..., S)`` of states ``(..., d)`` (:func:`acoustic_gain`)."""
        return acoustic_gain(x, self.sensors, self.psi, self.d0)

    @property
    def truth_positions(self) -> tuple:
        """K arrays ``(n_k, 2)``: the true positions at each scan."""
        return tuple(s[:, :2] for s in self.truth_states)

    @property
    def n_targets(self) -> int:
        """Number of distinct targets over the run."""
        return int(np.unique(np.concatenate(self.truth_ids)).size)

    def truth_table(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Flat truth ``(times (R,), ids (R,), positions (R, 2))`` for the metrics."""
        n = [a.size for a in self.truth_ids]
        times = np.repeat(self.times, n)
        if sum(n) == 0:
            return times, np.zeros(0, np.int64), np.zeros((0, 2))
        return times, np.concatenate(self.truth_ids), np.concatenate(self.truth_positions)


def acoustic(
    seed=0,
    *,
    n_scans: int = 50,
    dt: float = 1.0,
    process_noise: float = 0.002,
    speed_range=(0.1, 0.4),
    psi: float = ACOUSTIC_PSI,
    d0: float = ACOUSTIC_D0,
    noise_variance: float = ACOUSTIC_NOISE_VARIANCE,
) -> AcousticScenario:
    """The seeded acoustic scenario (module docstring): truth and ``(K, 25)`` readings.

    Parameters
    ----------
    seed : int, numpy Generator or None.
    n_scans : number of scans K (≥ 10, so births and the death fit in the run).
    dt : scan interval (s).
    process_noise : NCV acceleration spectral density q of the truth (m²/s³).
    speed_range : (min, max) initial speed (m/s).
    psi, d0, noise_variance : measurement model (defaults: the paper's 10, 0.1, 0.01).

    Returns
    -------
    AcousticScenario
    """
    rng = _rng(seed)
    n_scans = as_int(n_scans, "n_scans", minimum=10)
    dt = as_float(dt, "dt", minimum=0.0, open_min=True)
    q = as_float(process_noise, "process_noise", minimum=0.0)
    psi = as_float(psi, "psi", minimum=0.0, open_min=True)
    d0 = as_float(d0, "d0", minimum=0.0, open_min=True)
    noise_variance = as_float(noise_variance, "noise_variance", minimum=0.0, open_min=True)
    try:
        lo, hi = (as_float(v, "speed_range") for v in speed_range)
    except TypeError:
        raise ValueError(f"speed_range must be (min, max), got {speed_range!r}") from None
    if not 0 <= lo <= hi:
        raise ValueError(f"speed_range must be (min, max) with 0 <= min <= max, got {speed_range}")
    region = np.asarray(ACOUSTIC_REGION, dtype=np.float64)
    sensors = acoustic_sensor_grid()

    n_total = int(rng.integers(3, 6))
    n_initial = max(2, n_total - 2)
    born = np.zeros(n_total, dtype=np.int64)
    born[n_initial:] = rng.integers(n_scans // 5, n_scans // 2 + 1, n_total - n_initial)
    died = np.full(n_total, n_scans, dtype=np.int64)  # first scan it is absent
    died[int(rng.integers(0, n_initial))] = int(
        rng.integers(int(0.65 * n_scans), int(0.9 * n_scans))
    )

    def spawn(m: int) -> np.ndarray:
        pos = 8.0 + 24.0 * rng.random((m, 2))
        head = rng.uniform(0.0, 2.0 * np.pi, m)
        spd = rng.uniform(lo, hi, m)
        return np.column_stack([pos, spd * np.cos(head), spd * np.sin(head)])

    F, Q = ncv_matrices(dt, q, 2)
    L = _noise_factor(Q)
    state = np.full((n_total, 4), np.nan)
    alive = np.zeros(n_total, dtype=bool)
    ids_k, states_k = [], []
    left_region = []
    for k in range(n_scans):
        if k > 0:
            state[alive] = state[alive] @ F.T + rng.standard_normal((int(alive.sum()), 4)) @ L.T
            outside = alive & ~np.all(
                (state[:, :2] >= region[:, 0]) & (state[:, :2] <= region[:, 1]), axis=1
            )
            for i in np.flatnonzero(outside):
                left_region.append(int(i))
                died[i] = k
        new = born == k
        state[new] = spawn(int(new.sum()))
        alive = (born <= k) & (died > k)
        ids_k.append(np.flatnonzero(alive).astype(np.int64))
        states_k.append(state[alive].copy())

    noise = np.sqrt(noise_variance) * rng.standard_normal((n_scans, sensors.shape[0]))
    y = np.stack([acoustic_gain(s, sensors, psi, d0).sum(axis=0) for s in states_k]) + noise
    info = {
        "n_targets": n_total,
        "born": born.tolist(),
        "died": [int(d) if d < n_scans else None for d in died],
        "left_region": left_region,
        "speed_range": [lo, hi],
    }
    return AcousticScenario(
        name="acoustic",
        times=dt * np.arange(n_scans),
        dt=dt,
        truth_ids=tuple(ids_k),
        truth_states=tuple(states_k),
        measurements=y,
        sensors=sensors,
        psi=psi,
        d0=d0,
        noise_variance=noise_variance,
        region=region,
        process_noise=q,
        seed=_seed_value(seed),
        info=info,
    )
