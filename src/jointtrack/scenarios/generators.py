"""Built-in scenarios: Bojilov's five parallel targets, two crossing targets, many targets.

Bojilov et al., *One particular program realisation of JPDA*, §4: "five
targets moving along five parallel and closely spaced trajectories. In the
beginning of the process targets are so separated that their validation
regions do not overlap. […] Because of the different velocities the five
targets become moving closer and validation regions of some of them become
overlapped. […] In the middle of the scenario more often four or five targets
move in a cluster", with Poisson clutter of density β = 1 and β = 2, averaged
over ten runs. The paper gives no numbers for the geometry; :func:`bojilov`
uses the following (all adjustable by keyword).

Bojilov geometry (defaults)
---------------------------
* Scan interval T = 1 s, 81 scans (t = 0 … 80 s), P_D = 0.9.
* Measurement noise σ = 10 m per axis (R = 100 I m²); NCV truth with
  q = 10⁻⁴ m²/s³ (velocity wanders ≈ 0.06 m/s and position ≈ 4 m (1 s.d.)
  over the 80 s run, so the tracks stay essentially straight and parallel).
* Nominal gate (the unit of β): P_G = 0.99, γ = χ²₂⁻¹(0.99) = 9.21, with
  the steady-state innovation covariance S of the NCV Kalman filter for
  these T, q, R (discrete Riccati equation): S ≈ 104.6 I m², gate radius
  r_G = √(γ s) ≈ 31.0 m, gate area V_G = π γ √|S| ≈ 3026 m².
* Five lanes y_i = 20 i m (i = 0 … 4), 0.64 r_G apart, all moving in +x with
  speeds v_i = 2, 4, 6, 8, 10 m/s, placed so that all five reach x = 0 at
  t_meet = 40 s: x_i(0) = −v_i t_meet. Adjacent targets start 80 m apart in
  x (centre distance 82 m > 2 r_G = 62 m: no gates overlap at the start) and
  close at 2 m/s; at time t the adjacent centre distance is
  √((2|t − 40|)² + 20²) m, so adjacent gates overlap (distance < 2 r_G) for
  |t − 40| < 29 s and each target's own detection lies inside its
  neighbours' gates for |t − 40| < 12 s: a chained 5-target cluster for
  ≈ 25 scans mid-run, 4–5-target clusters around it depending on where
  detections and clutter fall, and separated targets again at the end.
* Region: the trajectories' bounding box plus a 60 m (≈ 2 r_G) margin:
  x ∈ [−460, 460] m, y ∈ [−60, 140] m, area 184 000 m² ≈ 60.8 V_G.
* Clutter: ``clutter_density`` β is in **expected clutter returns per nominal
  gate area V_G** per scan, so β = 1 puts on average one clutter point in each
  99 % gate ("light" clutter) and β = 2 two ("heavy"); λ = β / V_G
  (≈ 3.30·10⁻⁴ m⁻² for β = 1), i.e. ≈ 60.8 (β = 1) or 122 (β = 2) clutter
  points per scan over the region.
* Measured (10 seeds, gates of radius r_G centred on the true positions,
  clusters = targets linked through shared detections): in scans 30–50 a
  gate holds on average ≈ 3.0 detections at β = 1 and ≈ 4.0 at β = 2; the
  largest cluster has all 5 targets in most runs for t ≈ 32–53 s (β = 1)
  and 29–51 s (β = 2), clusters of ≥ 4 occur from t ≈ 18 s to 63 s, and
  every target is alone before t ≈ 12 s. Bojilov's Table 2 (≈ 8 800
  hypotheses for a 5-target cluster at β = 1) implies more detections per
  gate than this: his tracker's gates were wider than the steady-state 99 %
  gate used here as the unit of β (a tracker with a larger q, or early in
  a track's life, has larger gates).
"""

from __future__ import annotations

import math

import numpy as np
from scipy import linalg

from jointtrack.association.gating import gate_threshold
from jointtrack.scenarios.simulate import (
    Scenario,
    _count,
    _noise_factor,
    _pos_float,
    _prob,
    _rng,
    ncv_matrices,
    propagate_ncv,
    simulate_scenario,
)

__all__ = ["abreast", "bojilov", "crossing", "many_targets", "nominal_gate"]


def nominal_gate(
    dt: float, process_noise: float, sigma: float, p_g: float = 0.99, dim: int = 2
) -> dict:
    """Steady-state validation gate of an NCV Kalman filter with position measurements.

    Solves the discrete algebraic Riccati equation for the one-axis predicted
    covariance P (F, Q of :func:`~jointtrack.scenarios.simulate.ncv_matrices`,
    H = [1 0], R = σ²), so S = P_xx + σ² per axis (S = s I). Returns a dict
    with ``S`` (s), ``gamma`` = χ²_dim⁻¹(p_g), ``radius`` = √(γ s) and
    ``volume`` = c_dim γ^{dim/2} s^{dim/2} (c_dim the unit-ball volume).
    """
    dt = _pos_float(dt, "dt")
    q = _pos_float(process_noise, "process_noise", allow_zero=True)
    sigma = _pos_float(sigma, "sigma")
    p_g = _prob(p_g, "p_g")
    if p_g >= 1:
        raise ValueError("p_g must be < 1 (the gate would be infinite)")
    F, Q = ncv_matrices(dt, q, 1)
    H = np.array([[1.0, 0.0]])
    if q == 0:
        s = sigma**2  # the filter converges to a perfect track: S → R
    else:
        P = linalg.solve_discrete_are(F.T, H.T, Q, np.array([[sigma**2]]))
        s = float(P[0, 0] + sigma**2)
    gamma = gate_threshold(p_g, dim)
    unit = math.pi ** (dim / 2) / math.gamma(dim / 2 + 1)
    return {
        "S": s,
        "gamma": gamma,
        "radius": math.sqrt(gamma * s),
        "volume": unit * (gamma * s) ** (dim / 2),
        "p_g": p_g,
    }


def _speeds(speeds, n_min: int = 1) -> np.ndarray:
    try:
        v = np.asarray(speeds, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        raise ValueError("speeds must be a sequence of numbers") from None
    if v.size < n_min or not np.all(np.isfinite(v)):
        raise ValueError(f"speeds must hold at least {n_min} finite numbers, got {speeds!r}")
    return v


def _lanes(speeds, lane_spacing, t_meet, n_scans, dt, q, rng):
    """Targets on lanes y = i·lane_spacing moving in +x at ``speeds``, all at x = 0
    at ``t_meet``: the start states (n, 4) and the NCV trajectories."""
    n = speeds.size
    x0 = np.zeros((n, 4))
    x0[:, 0] = -speeds * t_meet
    x0[:, 1] = lane_spacing * np.arange(n)
    x0[:, 2] = speeds
    return x0, propagate_ncv(x0, n_scans, dt, q, rng)


def bojilov(
    clutter_density: float = 1.0,
    seed=None,
    *,
    n_scans: int = 81,
    dt: float = 1.0,
    p_d: float = 0.9,
    sigma: float = 10.0,
    process_noise: float = 1e-4,
    lane_spacing: float = 20.0,
    speeds=(2.0, 4.0, 6.0, 8.0, 10.0),
    t_meet: float | None = None,
    margin: float = 60.0,
    p_g: float = 0.99,
) -> Scenario:
    """Bojilov et al.'s five targets on parallel, closely spaced trajectories.

    Geometry and units are documented in the module docstring. ``clutter_density``
    is β in clutter returns per nominal 99 % gate area per scan (β = 1 "light",
    β = 2 "heavy"); the scenario's ``clutter_density`` field is λ = β / V_G per
    m², and ``info`` holds β, the nominal gate (``gate_S``, ``gate_radius``,
    ``gate_area``, ``gamma``), the lanes, speeds and ``t_meet``.

    ``t_meet`` (default: the middle of the run) is when all targets are
    abreast at x = 0. ``speeds`` gives one target per lane (lane i at
    y = i·lane_spacing).
    """
    beta = _pos_float(clutter_density, "clutter_density (beta)", allow_zero=True)
    rng = _rng(seed)
    n_scans = _count(n_scans, "n_scans", 2)
    dt = _pos_float(dt, "dt")
    sigma = _pos_float(sigma, "sigma")
    q = _pos_float(process_noise, "process_noise", allow_zero=True)
    lane_spacing = _pos_float(lane_spacing, "lane_spacing")
    margin = _pos_float(margin, "margin", allow_zero=True)
    v = _speeds(speeds, 2)
    t_end = (n_scans - 1) * dt
    t_meet = t_end / 2 if t_meet is None else float(t_meet)
    if not (0 <= t_meet <= t_end):
        raise ValueError(f"t_meet must be within the run [0, {t_end}], got {t_meet}")
    gate = nominal_gate(dt, q, sigma, p_g, 2)

    n = v.size
    x0, traj = _lanes(v, lane_spacing, t_meet, n_scans, dt, q, rng)
    times = dt * np.arange(n_scans)
    # region from the noise-free trajectories, so it does not depend on the seed
    xs = np.concatenate([x0[:, 0], x0[:, 0] + v * t_end])
    region = np.array(
        [
            [xs.min() - margin, xs.max() + margin],
            [-margin, lane_spacing * (n - 1) + margin],
        ]
    )
    area = float(np.prod(region[:, 1] - region[:, 0]))
    rate = beta * area / gate["volume"]
    ids = np.arange(n, dtype=np.int64)
    info = {
        "beta": beta,
        "beta_unit": "clutter returns per nominal gate area per scan",
        "gate_S": gate["S"],
        "gate_radius": gate["radius"],
        "gate_area": gate["volume"],
        "gamma": gate["gamma"],
        "p_g": gate["p_g"],
        "lanes_y": (lane_spacing * np.arange(n)).tolist(),
        "speeds": v.tolist(),
        "t_meet": t_meet,
        "sigma": sigma,
    }
    return simulate_scenario(
        "bojilov",
        times,
        [ids] * n_scans,
        list(traj),
        region=region,
        p_d=p_d,
        clutter_rate=rate,
        R=sigma**2 * np.eye(2),
        process_noise=q,
        rng=rng,
        info=info,
        seed=seed,
        dt=dt,
    )


def abreast(
    seed=None,
    *,
    n_targets: int = 5,
    n_scans: int = 80,
    dt: float = 1.0,
    speed: float = 1.0,
    lane_spacing: float = 20.0,
    p_d: float = 0.9,
    sigma: float = 5.0,
    process_noise: float = 1e-4,
    clutter_per_scan: float = 60.0,
    region=((-450.0, 450.0), (-60.0, 140.0)),
) -> Scenario:
    """Targets moving abreast: ``n_targets`` parallel lanes, same speed, in clutter.

    Lane i is at y = i·lane_spacing; every target moves in +x at ``speed`` and
    passes x = 0 at the middle of the run. ``clutter_per_scan`` Poisson clutter
    is uniform over ``region`` (default 900 × 200: with 60 returns per scan,
    λ ≈ 3.3·10⁻⁴ per unit area). The defaults are the scene of issue 11 —
    5 targets 20 units apart at 1 unit/s, σ = 5, P_D = 0.9, 80 scans — where
    targets are 4σ apart and a tracker must find them with no start from the
    truth; their steady-state 99 % gates hold ≈ 0.3 false returns each.
    """
    rng = _rng(seed)
    n = _count(n_targets, "n_targets", 1)
    n_scans = _count(n_scans, "n_scans", 2)
    dt = _pos_float(dt, "dt")
    speed = _pos_float(speed, "speed", allow_zero=True)
    lane_spacing = _pos_float(lane_spacing, "lane_spacing")
    sigma = _pos_float(sigma, "sigma")
    q = _pos_float(process_noise, "process_noise", allow_zero=True)
    _, traj = _lanes(np.full(n, speed), lane_spacing, (n_scans - 1) * dt / 2, n_scans, dt, q, rng)
    ids = np.arange(n, dtype=np.int64)
    return simulate_scenario(
        "abreast",
        dt * np.arange(n_scans),
        [ids] * n_scans,
        list(traj),
        region=region,
        p_d=p_d,
        clutter_rate=_pos_float(clutter_per_scan, "clutter_per_scan", allow_zero=True),
        R=sigma**2 * np.eye(2),
        process_noise=q,
        rng=rng,
        info={"speed": speed, "lane_spacing": lane_spacing, "sigma": sigma},
        seed=seed,
        dt=dt,
    )


def crossing(
    seed=None,
    *,
    n_scans: int = 61,
    dt: float = 1.0,
    speed: float = 10.0,
    angle_deg: float = 45.0,
    p_d: float = 0.9,
    sigma: float = 10.0,
    process_noise: float = 1e-2,
    clutter_per_scan: float = 10.0,
    margin: float = 100.0,
) -> Scenario:
    """Two targets crossing in an X at the middle of the run.

    Target 0 heads at +angle/2 and target 1 at −angle/2 from the +x axis, both
    at ``speed``; both pass through the origin at t_c = (n_scans − 1)·dt/2, so
    their separation is 2·speed·|t − t_c|·sin(angle/2) (≈ 7.7 m per second
    from the crossing with the defaults: within σ-scale distance for a few
    scans). ``clutter_per_scan`` Poisson clutter uniform over the bounding
    box of the trajectories plus ``margin``.
    """
    rng = _rng(seed)
    n_scans = _count(n_scans, "n_scans", 2)
    dt = _pos_float(dt, "dt")
    speed = _pos_float(speed, "speed")
    sigma = _pos_float(sigma, "sigma")
    q = _pos_float(process_noise, "process_noise", allow_zero=True)
    margin = _pos_float(margin, "margin", allow_zero=True)
    angle = _pos_float(angle_deg, "angle_deg")
    if angle >= 180:
        raise ValueError(f"angle_deg must be in (0, 180), got {angle}")
    half = math.radians(angle) / 2
    t_c = (n_scans - 1) * dt / 2
    vel = speed * np.array([[math.cos(half), math.sin(half)], [math.cos(half), -math.sin(half)]])
    x0 = np.concatenate([-vel * t_c, vel], axis=1)
    traj = propagate_ncv(x0, n_scans, dt, q, rng)
    ext = np.abs(vel).max(axis=0) * t_c
    region = np.stack([-ext - margin, ext + margin], axis=1)
    ids = np.arange(2, dtype=np.int64)
    return simulate_scenario(
        "crossing",
        dt * np.arange(n_scans),
        [ids] * n_scans,
        list(traj),
        region=region,
        p_d=p_d,
        clutter_rate=_pos_float(clutter_per_scan, "clutter_per_scan", allow_zero=True),
        R=sigma**2 * np.eye(2),
        process_noise=q,
        rng=rng,
        info={"t_cross": t_c, "angle_deg": angle, "speed": speed, "sigma": sigma},
        seed=seed,
        dt=dt,
    )


def many_targets(
    n_targets: int = 100,
    clutter_per_scan: float = 50.0,
    seed=None,
    *,
    n_scans: int = 100,
    dt: float = 1.0,
    region=((0.0, 10_000.0), (0.0, 10_000.0)),
    speed_range=(5.0, 25.0),
    p_survival: float = 0.99,
    birth_rate: float | None = None,
    p_d: float = 0.95,
    sigma: float = 10.0,
    process_noise: float = 0.1,
) -> Scenario:
    """Many NCV targets with births and deaths in uniform Poisson clutter.

    Scan 0 holds ``n_targets`` targets, uniform in ``region`` with uniform
    heading and speed uniform in ``speed_range``. Each later scan, every
    target survives with probability ``p_survival`` (and dies when it leaves
    the region), and ``Poisson(birth_rate)`` new targets are born (drawn like
    the initial ones). The default ``birth_rate = n_targets·(1 − p_survival)``
    balances the random deaths, so the number alive stays near ``n_targets``
    (slightly below: a few targets also leave the region). Ids are
    consecutive integers in order of birth.
    """
    rng = _rng(seed)
    n_targets = _count(n_targets, "n_targets", 1)
    n_scans = _count(n_scans, "n_scans", 1)
    dt = _pos_float(dt, "dt")
    p_s = _prob(p_survival, "p_survival", allow_zero=True)
    birth = n_targets * (1 - p_s) if birth_rate is None else birth_rate
    birth = _pos_float(birth, "birth_rate", allow_zero=True)
    sigma = _pos_float(sigma, "sigma")
    q = _pos_float(process_noise, "process_noise", allow_zero=True)
    B = np.asarray(region, dtype=np.float64)
    if B.shape != (2, 2) or not np.all(np.isfinite(B)) or np.any(B[:, 1] <= B[:, 0]):
        raise ValueError(f"region must be [[xmin, xmax], [ymin, ymax]], got {region!r}")
    sr = _speeds(speed_range, 2)
    if sr.size != 2 or not (0 <= sr[0] <= sr[1]):
        raise ValueError(f"speed_range must be (min, max) with 0 <= min <= max, got {speed_range}")

    def spawn(m: int) -> np.ndarray:
        pos = B[:, 0] + rng.random((m, 2)) * (B[:, 1] - B[:, 0])
        head = rng.uniform(0, 2 * np.pi, m)
        spd = rng.uniform(sr[0], sr[1], m)
        return np.column_stack([pos, spd * np.cos(head), spd * np.sin(head)])

    F, Q = ncv_matrices(dt, q, 2)
    L = _noise_factor(Q)
    X = spawn(n_targets)
    ids = np.arange(n_targets, dtype=np.int64)
    next_id = n_targets
    all_ids, all_states = [ids], [X]
    n_born = n_died = 0
    for _k in range(1, n_scans):
        X = X @ F.T + rng.standard_normal(X.shape) @ L.T
        inside = np.all((X[:, :2] >= B[:, 0]) & (X[:, :2] <= B[:, 1]), axis=1)
        keep = inside & (rng.random(ids.size) < p_s)
        n_died += int(ids.size - keep.sum())
        m = int(rng.poisson(birth))
        n_born += m
        X = np.concatenate([X[keep], spawn(m)], axis=0)
        ids = np.concatenate([ids[keep], np.arange(next_id, next_id + m, dtype=np.int64)])
        next_id += m
        all_ids.append(ids)
        all_states.append(X)
    info = {
        "n_initial": n_targets,
        "birth_rate": birth,
        "p_survival": p_s,
        "n_born": n_born,
        "n_died": n_died,
        "speed_range": sr.tolist(),
        "sigma": sigma,
    }
    return simulate_scenario(
        "many_targets",
        dt * np.arange(n_scans),
        all_ids,
        all_states,
        region=B,
        p_d=p_d,
        clutter_rate=_pos_float(clutter_per_scan, "clutter_per_scan", allow_zero=True),
        R=sigma**2 * np.eye(2),
        process_noise=q,
        rng=rng,
        info=info,
        seed=seed,
        dt=dt,
    )
