"""A birth that follows the returns: the measurement-driven birth of the Poisson trackers.

``birth_per_return`` (issue 33, item 4): each return no Bernoulli explains adds a
birth component at its position to the next scan's undetected intensity (Ristic,
Clark, Vo & Vo 2012), weighted as JIPDA's per-return initiation. A target that
appears late where the uniform birth density is nil is found from its own
returns within a few scans; without it, never.
"""

from __future__ import annotations

import numpy as np
import pytest

from jointtrack.trackers.pmbm import PMBMConfig, PMBMTracker, PMBTracker

APPEARS = 20  # the scan at which the target appears
SIDE = 1000.0


def _late_target(kind, seed, n_clutter, n_scans, **over):
    """``(scans from appearing to its first report or None, false ids)``.

    Clutter: Poisson(n_clutter) returns uniform on a 1 km square; the target appears
    at scan APPEARS at (200, 500) and moves at 10 m/s along x, detected with P_D 0.9,
    noise σ = 10 m. A report within 50 m of it is the target's, any other id false.
    """
    rng = np.random.default_rng(seed)
    cfg = PMBMConfig(
        clutter_density=n_clutter / SIDE**2,
        measurement_noise=100.0,
        max_speed=30.0,
        process_noise=0.1,
        **over,
    )
    trk = kind(cfg)
    first, false = None, set()
    for k in range(n_scans):
        z = rng.uniform(0.0, SIDE, (rng.poisson(n_clutter), 2))
        target = np.array([200.0 + 10.0 * (k - APPEARS), 500.0])
        if k >= APPEARS and rng.random() < 0.9:
            z = np.vstack([z, target + rng.normal(0.0, 10.0, 2)])
        res = trk.step(float(k), z)
        for i, x in zip(res.ids.tolist(), res.x, strict=True):
            if k >= APPEARS and np.linalg.norm(x[:2] - target) < 50.0:
                first = k - APPEARS if first is None else first
            else:
                false.add(i)
    return first, len(false)


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_pmb_finds_a_late_target_from_its_returns(seed):
    """No uniform birth (birth_density 0) and birth_per_return 0.005, 20 clutter
    returns a scan: the late target is reported within 5 scans of appearing, with at
    most 4 false ids over the 32 scans (640 clutter returns). Measured: 1, 4, 1, 2
    scans; 3, 0, 0, 0 false ids."""
    first, false = _late_target(PMBTracker, seed, 20, 32, birth_density=0.0, birth_per_return=0.005)
    assert first is not None and first <= 5, first
    assert false <= 4, false


def test_pmb_without_it_never_finds_the_late_target():
    """The control: the same scenes without it — no birth at all — never report it."""
    for seed in (0, 1):
        first, _ = _late_target(PMBTracker, seed, 20, 32, birth_density=0.0)
        assert first is None


def test_pmbm_finds_a_late_target_from_its_returns():
    """PMBM the same way, in lighter clutter (4 returns a scan: its global hypotheses
    cost ~2 s a scan in 20): reported within 5 scans."""
    first, false = _late_target(PMBMTracker, 0, 4, 28, birth_density=0.0, birth_per_return=0.005)
    assert first is not None and first <= 5, first
    assert false <= 2, false


@pytest.mark.parametrize(
    "value", [-0.1, 1.0, 2.0, float("nan"), float("inf"), 1j, True, None, "0.1", 10**400]
)
def test_bad_birth_per_return_is_refused_by_name(value):
    with pytest.raises(ValueError, match="PMBMConfig: birth_per_return must be"):
        PMBMConfig(birth_per_return=value)
