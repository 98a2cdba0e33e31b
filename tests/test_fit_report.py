"""The report-like fit's model choice (issue 32, Solent): targets at rest and under way.

A report file of moored and moving vessels gets the IMM with a stationary mode — the
moving targets' q for its CV mode, the at-rest links' q for the stationary one,
switching per second — and ``max_speed`` from the moving targets' links (the trimmed
core's speeds are the moored vessels': 0.011 m/s on the bench's Solent scene). A file
of moving targets only keeps CV; a key the user sets is never chosen over.
"""

from __future__ import annotations

import numpy as np
import pytest

from jointtrack.experiments import fit as fitmod
from jointtrack.experiments.config import make_tracker_config
from jointtrack.experiments.fit import fit_tracker_settings
from jointtrack.io import Detections
from jointtrack.trackers.base import imm_modes
from test_fit import _moored_and_moving, report_like_detections


@pytest.mark.parametrize("seed", [0, 1])
def test_moored_and_moving_targets_get_cv_plus_stationary(seed):
    """Twelve moored targets and four under way (q 0.5, σ 1 m): the IMM with CV (q within
    a factor 2 of the movers') and a stationary mode whose random walk over a typical gap
    stays far below σ²; switching per second; max_speed from the movers (1.5 × their own
    99 % speed, within 25 %), where the trimmed core's speeds are the moored targets'."""
    q = 0.5
    det, (t0, _, t2, z0, _, z2) = _moored_and_moving(seed, q)
    # the movers' own 99 % speed (their velocity walks: q·1,800 s gives σ_v ≈ 30 m/s)
    v99 = np.quantile(np.linalg.norm(z2 - z0, axis=1) / (t2 - t0), 0.99)
    f = fit_tracker_settings(det)
    tb = f.table
    assert tb["motion"] == "imm" and tuple(tb["imm_modes"]) == ("cv", "stationary")
    q_cv, q_rest = tb["imm_process_noise"]
    assert 0.5 < q_cv / q < 2.0, f.sources["imm_process_noise"]
    assert q_rest * 10.0 < 0.1 * tb["measurement_noise"]  # 10 s of drift ≪ the noise
    assert tb["imm_switching_per"] == "second"
    assert abs(tb["max_speed"] / (fitmod.SPEED_MARGIN * v99) - 1) < 0.25, f.sources["max_speed"]
    assert "moving" in f.sources["max_speed"] and "at rest" in f.sources["motion"]
    n_mov = f.evidence["report_triples_moving"]
    n_rest = f.evidence["report_triples_at_rest"]
    assert n_rest >= 100 and n_mov >= 100
    assert 0.0 < tb["imm_initial"][0] < 1.0 and abs(sum(tb["imm_initial"]) - 1) < 1e-12
    assert f"{n_mov:,} of " in f.sources["motion"] and f"{n_rest:,} of " in f.sources["motion"]
    cfg = make_tracker_config({"dim": 2}, tb)
    modes = imm_modes(cfg)
    assert modes.kinds == ("cv", "stationary") and modes.generator is not None
    # the fitted table is a TOML run --config accepts
    assert 'imm_modes = ["cv", "stationary"]' in f.to_toml()


@pytest.mark.parametrize("seed", [0, 1])
def test_moving_targets_only_keep_cv(seed):
    f = fit_tracker_settings(report_like_detections(np.random.default_rng(seed)))
    assert f.table.get("motion", "cv") == "cv" and "imm_modes" not in f.table
    assert "needs both" in f.evidence["report_motion"]
    assert 10.0 <= f.table["max_speed"] <= 30.0


def test_user_keys_are_kept_and_poisson_kinds_get_no_imm():
    det, _ = _moored_and_moving(0, 0.5)
    f = fit_tracker_settings(det, {"motion": "cv"})
    assert f.table["motion"] == "cv" and "imm_modes" not in f.table
    assert f.sources["motion"] == "set in [tracker]"
    f = fit_tracker_settings(det, {"imm_modes": ["cv", "ct"]})
    assert "motion" not in f.table and list(f.table["imm_modes"]) == ["cv", "ct"]
    f = fit_tracker_settings(det, {"imm_switching_per": "scan"})
    assert f.table["motion"] == "imm" and f.table["imm_switching_per"] == "scan"
    f = fit_tracker_settings(det, {"imm_initial": [0.2, 0.8]})
    assert f.table["motion"] == "imm" and list(f.table["imm_initial"]) == [0.2, 0.8]
    assert f.sources["imm_initial"] == "set in [tracker]"
    for kind in ("pmb", "pmbm"):
        assert "imm_modes" not in fit_tracker_settings(det, kind=kind).table


def test_max_speed_without_moving_links_is_refused_not_taken_from_moored_ones():
    """Only targets at rest: there is no speed scale; max_speed falls back to the stated
    default and says why (the moored links' ~0 m/s is not taken)."""
    rng = np.random.default_rng(3)
    ts, ps = [], []
    for i in range(12):
        t = np.cumsum(rng.exponential(10.0, 300))
        t = t[t < 1800.0]
        x = np.array([3000.0 * (i % 4), 4000.0 * (i // 4)])
        ts.append(t)
        ps.append(x + rng.normal(0, 1.0, (t.size, 2)))
    t, p = np.concatenate(ts), np.concatenate(ps)
    o = np.argsort(t, kind="stable")
    f = fit_tracker_settings(Detections(times=t[o], scans=tuple(p[o][:, None, :]), dim=2))
    assert "max_speed" in f.fallbacks and "moving target" in f.fallbacks["max_speed"]
    assert f.table["max_speed"] == fitmod._defaults()["max_speed"]
