"""The fit's choice of the motion model and of coalescence avoidance for scan files
(issue 32, items 2 and 3): :func:`jointtrack.experiments.fit._choose_scan_models`.

Small simulated aircraft scenes (200 m/s, 10 s scans, σ 50 m, P_D 0.9, 5 false
returns a scan on a 400 km square): pairs flying in formation 300 m apart against
targets far apart; straight flight against turns of 3°/s for a fifth of the run. The
fit must turn JPDA* on for the pairs and not for the others, choose the IMM for the
turning targets and CV for the straight ones, say why with the counts, fit the
coordinated-turn mode's turn-rate walk from the turn rate the targets fly, and leave
alone what the user sets, the PMB/PMBM kinds and report-like files.
"""

from __future__ import annotations

import math
import tomllib

import numpy as np
import pytest

from jointtrack.experiments import fit as fitmod
from jointtrack.experiments.config import make_tracker_config
from jointtrack.experiments.fit import fit_tracker_settings
from jointtrack.io import Detections

TURN = math.radians(3.0)
DT = 10.0


def _aircraft(seed, *, pair=None, turn=0.0, n=24, scans=60, sigma=50.0, side=400e3, unit=1.0):
    """``n`` aircraft (``n/2`` pairs ``pair`` metres abeam when ``pair``), each turning
    at ±``turn`` rad/s for ``scans // 5`` scans from a random scan when ``turn``;
    positions in units of ``unit`` metres."""
    rng = np.random.default_rng(seed)
    m = n // 2 if pair else n
    true = np.zeros((n, scans, 2))
    for i in range(m):
        p = rng.uniform(0.3 * side, 0.7 * side, 2)
        h = rng.uniform(0, 2 * np.pi)
        w = np.zeros(scans)
        if turn:
            k0 = rng.integers(5, scans // 2)
            w[k0 : k0 + scans // 5] = turn * rng.choice([-1.0, 1.0])
        for k in range(scans):
            true[i, k] = p
            if pair:
                true[m + i, k] = p + pair * np.array([-math.sin(h), math.cos(h)])
            h += w[k] * DT
            p = p + 200.0 * DT * np.array([math.cos(h), math.sin(h)])
    seen = rng.random((n, scans)) < 0.9
    z = true + rng.normal(0, sigma, true.shape)
    dets = [
        np.concatenate([z[seen[:, k], k], rng.uniform(0, side, (rng.poisson(5), 2))])
        for k in range(scans)
    ]
    return Detections(times=np.arange(scans) * DT, scans=tuple(d / unit for d in dets), dim=2)


@pytest.mark.parametrize("seed", [0, 1])
def test_close_pairs_turn_jpda_star_on_and_far_targets_leave_it_off(seed):
    close = fit_tracker_settings(_aircraft(seed, pair=300.0))
    far = fit_tracker_settings(_aircraft(seed))
    assert not close.fallbacks and not far.fallbacks
    assert close.table["coalescence_avoidance"] is True
    assert far.table["coalescence_avoidance"] is False
    # the reason, with its evidence: the share of the targets' returns with a neighbour
    assert close.sources["coalescence_avoidance"].startswith("fitted: on (JPDA*)")
    assert far.sources["coalescence_avoidance"].startswith("fitted: off (plain JPDA)")
    assert close.evidence["pair_close"] >= fitmod.PAIR_SHARE * close.evidence["pair_returns"]
    assert far.evidence["pair_close"] == 0
    for f in (close, far):
        assert f"{f.evidence['pair_close']:,} of" in f.sources["coalescence_avoidance"]
    # straight flight: CV, and why
    assert close.table["motion"] == far.table["motion"] == "cv"
    assert "turns too rare" in far.sources["motion"]
    assert "turn_rate_std" not in far.table


@pytest.mark.parametrize("seed", [0, 1])
def test_turning_targets_get_the_imm_with_their_turn_rate(seed):
    f = fit_tracker_settings(_aircraft(seed, turn=TURN, scans=150))
    assert not f.fallbacks, f.fallbacks
    assert f.table["motion"] == "imm", f.sources["motion"]
    assert f.sources["motion"].startswith("fitted: imm")
    assert f.evidence["turn_turning"] >= fitmod.TURN_SHARE * f.evidence["turn_moving"]
    # the turn-rate walk reaches the 3°/s the targets fly in one scan (the turning
    # triples' median rate: chords inside the turn, a few at its ends)
    assert abs(f.table["turn_rate_std"] / (TURN / math.sqrt(DT)) - 1) < 0.2
    assert f.table["coalescence_avoidance"] is False
    cfg = make_tracker_config({"dim": 2}, f.table)  # a valid [tracker] table
    assert cfg.motion == "imm" and cfg.turn_rate_std == f.table["turn_rate_std"]
    assert tomllib.loads(f.to_toml())["tracker"] == f.table
    assert any(note.startswith("[tracker] motion = 'imm': fitted: imm") for note in f.notes())


@pytest.mark.parametrize(
    ("scene", "unit"), [({"pair": 300.0}, 2.0**-20), ({"turn": TURN, "scans": 150}, 2.0**30)]
)
def test_the_choices_do_not_depend_on_the_unit_of_length(scene, unit):
    # positions in another unit (a power of two: exact) — speeds, σ, q and gate radii
    # scale with it, counts and turn rates do not; the speed bound refuses max_speed
    # (2e8 units/s) or not (2e-7), and the choices and their counts must not move
    ref = fit_tracker_settings(_aircraft(0, **scene))
    f = fit_tracker_settings(_aircraft(0, **scene, unit=unit))
    keys = ("coalescence_avoidance", "motion", "turn_rate_std")
    assert {k: ref.table.get(k) for k in keys} == {k: f.table.get(k) for k in keys}
    for k in ("pair_returns", "pair_close", "turn_moving", "turn_turning"):
        assert f.evidence[k] == ref.evidence[k], k


def test_keys_the_user_sets_are_not_chosen():
    # (without these keys the same scenes choose JPDA* and the IMM: the tests above)
    f = fit_tracker_settings(_aircraft(0, pair=300.0), {"coalescence_avoidance": False})
    assert f.table["coalescence_avoidance"] is False
    assert f.sources["coalescence_avoidance"] == "set in [tracker]"
    turning = _aircraft(0, turn=TURN, scans=150)
    f = fit_tracker_settings(turning, {"motion": "cv"})
    assert f.table["motion"] == "cv" and f.sources["motion"] == "set in [tracker]"
    assert "turn_rate_std" not in f.table
    g = fit_tracker_settings(turning, {"turn_rate_std": 0.05})
    assert g.table["motion"] == "imm" and g.table["turn_rate_std"] == 0.05


def test_poisson_kinds_and_report_files_are_not_chosen_for():
    d = _aircraft(0, pair=300.0, scans=30)
    assert "coalescence_avoidance" in fit_tracker_settings(d).table
    for kind in ("pmb", "pmbm"):
        f = fit_tracker_settings(d, {}, kind)
        assert not {"motion", "coalescence_avoidance", "turn_rate_std"} & set(f.table)
    # the same returns one at a time (a report-like file): no scans to choose from
    t = np.concatenate([np.full(len(z), t0) for t0, z in zip(d.times, d.scans, strict=True)])
    t = t + np.arange(t.size) * (DT / (2 * t.size))
    z = np.concatenate(d.scans)
    f = fit_tracker_settings(Detections(times=t, scans=tuple(z[:, None, :]), dim=2))
    assert f.table["reporting"] == "async"
    assert not {"motion", "coalescence_avoidance", "turn_rate_std"} & set(f.table)
