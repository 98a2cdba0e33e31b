"""The coalescence scenario of the PMBM literature: four targets that meet mid-run.

J. L. Williams, "Marginal multi-Bernoulli filters: RFS derivation of MHT,
JIPDA, and association-based MeMBer", *IEEE Transactions on Aerospace and
Electronic Systems* 51(3), 2015 — the scenario; Á. F. García-Fernández,
J. L. Williams, K. Granström and L. Svensson, "Poisson multi-Bernoulli mixture
filter: direct derivation and implementation", *IEEE Transactions on Aerospace
and Electronic Systems* 54(4), 2018, §VI — its set-up for the PMBM filter,
whose authors' MATLAB code (github.com/Agarciafernandez/MTT, folder
``PMBM filter``: ``ScenarioWilliams15.m``, ``TrajectoryWilliams15.m``,
``CreateMeasurement.m``) :func:`coalescence` mirrors.

Set-up (defaults)
-----------------
* Steps k = 1 … 81, scan interval T = 1 s; step k is at time k·T (the
  paper's step numbers are the scan times, so "step 41" is ``t = 41``).
* Nearly-constant velocity (:mod:`jointtrack.scenarios.simulate`) with
  q = 0.02: Q = 0.02·kron(I₂, [[T³/3, T²/2], [T²/2, T]]). This is the value of
  ``ScenarioWilliams15.m`` since the authors' commit 87f5776 (2022); their
  first published version (2019) had q = 0.01 — pass ``process_noise=0.01``
  for that one.
* Position measurements, R = I₂ (σ = 1), P_D = 0.9; Poisson(10) clutter
  returns per scan, uniform on [0, 300]² (λ = 10 / 300² ≈ 1.1·10⁻⁴).
* Four targets, all present at step 1. At the midpoint step
  m = (K + 1)/2 = 41 their states are drawn independently from
  N([150, 150, 0, 0], 0.1·I₄) (our layout ``[x, y, vx, vy]``; the paper's
  ``[x, vx, y, vy]`` mean (150, 0, 150, 0) is the same point, and 0.1·I₄ is
  the same in either layout) and propagated forward with the NCV model,
  ``x_{k+1} = F x_k + w_k``, and backward with the authors' noisy reverse
  step ``x_{k−1} = F⁻¹ (x_k + w_k)``, w_k ~ N(0, Q) independent — as
  ``TrajectoryWilliams15.m`` does. Noisy, not deterministic, backward
  propagation, because that is what the published experiments ran on: the
  targets spread out from the meeting point in both directions of time by
  the same velocity random walk (velocity variance 0.1 + j·q·T after j steps
  either way), so they are together at the midpoint and apart at both ends.
  The forward draws come first and then the backward ones (their loop
  interleaves them; the distribution is the same).
* Target 0 (the paper's first target) dies at the midpoint: as in
  ``TrajectoryWilliams15.m`` (``t_death = (K+1)/2``) and
  ``CreateMeasurement.m`` (a target is present at step k when
  ``t_birth ≤ k < t_death``) it is present at steps 1 … 40 and absent from
  step 41 on. The other three live to the end. There are no births.

``info`` holds the filter model of the paper (plain JSON values; vectors and
matrices in our layout ``[x, y, vx, vy]``): the birth intensity (weight
0.005, mean [100, 100, 0, 0], covariance diag(150², 150², 1, 1)), the Poisson
prior intensity at time 0 (λ₀ = 3 with the same density), P_S = 0.99, and the
GOSPA parameters c = 10, p = 2, α = 2 with which the paper scores (the cut-off
``jointtrack run`` uses for this scene).
"""

from __future__ import annotations

import numpy as np

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

__all__ = ["coalescence"]

#: number of targets, fixed by the scenario
N_TARGETS = 4
#: surveillance region [0, 300]² of the paper (``Area = [300 300]``)
REGION = ((0.0, 300.0), (0.0, 300.0))
#: covariance scale of the midpoint states (``Pmid = 0.1*eye(4)``)
MIDPOINT_VARIANCE = 0.1
#: the paper's filter model, layout [x, y, vx, vy]
BIRTH_WEIGHT = 0.005
PRIOR_LAMBDA = 3.0
P_SURVIVAL = 0.99
DENSITY_MEAN = (100.0, 100.0, 0.0, 0.0)
DENSITY_STD = (150.0, 150.0, 1.0, 1.0)
GOSPA = {"c": 10.0, "p": 2.0, "alpha": 2.0}


def _density() -> dict:
    """The birth / prior Gaussian density of the paper, as plain lists."""
    return {"mean": list(DENSITY_MEAN), "cov": np.diag(np.square(DENSITY_STD)).tolist()}


def coalescence(
    seed=0,
    *,
    n_steps: int = 81,
    dt: float = 1.0,
    p_d: float = 0.9,
    clutter_rate: float = 10.0,
    process_noise: float = 0.02,
    sigma: float = 1.0,
) -> Scenario:
    """Williams' coalescence scenario as set up for the PMBM filter (module docstring).

    Parameters
    ----------
    seed : numpy Generator, non-negative int or None (see
        :mod:`jointtrack.scenarios.simulate`).
    n_steps : number of steps K, odd and ≥ 3 (the midpoint (K + 1)/2 is a
        step); 81 in the paper.
    dt : scan interval T (s); step k is at time k·T.
    p_d : detection probability P_D.
    clutter_rate : mean number of clutter returns per scan (Poisson), uniform
        on [0, 300]².
    process_noise : NCV acceleration spectral density q of the truth.
    sigma : measurement noise standard deviation per axis (R = σ² I).

    Returns
    -------
    Scenario
        Named ``"coalescence"``; target ids 0 … 3, id 0 absent from the
        midpoint step on; ``info`` as in the module docstring plus
        ``midpoint_step``, ``midpoint_time`` and ``death_step`` (of target 0).
    """
    rng = _rng(seed)
    K = _count(n_steps, "n_steps", 3)
    if K % 2 == 0:
        raise ValueError(f"n_steps must be odd (the midpoint (n_steps + 1)/2 is a step), got {K}")
    dt = _pos_float(dt, "dt")
    q = _pos_float(process_noise, "process_noise", allow_zero=True)
    sigma = _pos_float(sigma, "sigma")
    clutter_rate = _pos_float(clutter_rate, "clutter_rate", allow_zero=True)
    p_d = _prob(p_d, "p_d")  # checked before any draw, so a bad value costs nothing

    mid = (K + 1) // 2  # the midpoint step, 1-based as in the paper
    n_half = mid - 1
    centre = np.array([(lo + hi) / 2 for lo, hi in REGION] + [0.0, 0.0])
    x_mid = centre + np.sqrt(MIDPOINT_VARIANCE) * rng.standard_normal((N_TARGETS, 4))
    forward = propagate_ncv(x_mid, n_half + 1, dt, q, rng)  # steps mid … K
    F, Q = ncv_matrices(dt, q, 2)
    L = _noise_factor(Q)
    F_inv = np.linalg.inv(F)
    backward = np.empty((n_half + 1, N_TARGETS, 4))  # steps mid, mid − 1, …, 1
    backward[0] = x_mid
    for j in range(1, n_half + 1):
        w = rng.standard_normal((N_TARGETS, 4)) @ L.T
        backward[j] = (backward[j - 1] + w) @ F_inv.T
    states = np.concatenate([backward[:0:-1], forward], axis=0)  # steps 1 … K

    all_ids = np.arange(N_TARGETS, dtype=np.int64)
    survivors = all_ids[1:]
    truth_ids, truth_states = [], []
    for k in range(1, K + 1):
        alive = all_ids if k < mid else survivors
        truth_ids.append(alive)
        truth_states.append(states[k - 1][alive])
    info = {
        "paper": "Williams (2015) coalescence scenario, set up as in Garcia-Fernandez, "
        "Williams, Granstrom & Svensson (2018) sec. VI",
        "layout": "[x, y, vx, vy]",
        "birth": {"weight": BIRTH_WEIGHT, **_density()},
        "prior": {"lambda": PRIOR_LAMBDA, **_density()},
        "p_s": P_SURVIVAL,
        "gospa": dict(GOSPA),
        "midpoint_step": mid,
        "midpoint_time": float(mid * dt),
        "midpoint_mean": centre.tolist(),
        "midpoint_variance": MIDPOINT_VARIANCE,
        "death_step": mid,
        "sigma": sigma,
    }
    return simulate_scenario(
        "coalescence",
        dt * np.arange(1, K + 1),
        truth_ids,
        truth_states,
        region=np.array(REGION),
        p_d=p_d,
        clutter_rate=clutter_rate,
        R=sigma**2 * np.eye(2),
        process_noise=q,
        rng=rng,
        info=info,
        seed=seed,
        dt=dt,
    )
