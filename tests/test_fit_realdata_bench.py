"""benchmarks/fit_realdata.py's split of the straight flight a run lost (issue 32):
each lost truth point in exactly one kind, each id change a new flight, a rebirth or an overlap."""

import numpy as np
import pytest

from benchmark_scripts import load_benchmark
from jointtrack.metrics.selfreport import score_self_reports


@pytest.fixture(scope="module")
def bench():
    return load_benchmark("fit_realdata")


def _rows(ident, times, pos):
    times = np.asarray(times, float)
    return times, np.full(len(times), ident), np.asarray(pos, float).reshape(-1, 2)


def test_each_lost_straight_point_has_one_kind_and_each_id_change_one_class(bench):
    # aircraft 0 flies x = 200 t (0–170 s), aircraft 1 at y = 50 km (0–150 s): straight
    # aircraft 2 at y = −50 km flies twice: 0–50 s and 800–850 s (silent longer than
    # the scorer's max_gap, 600 s, in between)
    ta, tb = np.arange(0.0, 171.0, 10.0), np.arange(0.0, 151.0, 10.0)
    tc = np.r_[np.arange(0.0, 51.0, 10.0), np.arange(800.0, 851.0, 10.0)]
    truth_t = np.concatenate([ta, tb, tc])
    truth_i = np.repeat([0, 1, 2], [len(ta), len(tb), len(tc)])
    truth_p = np.concatenate(
        [
            np.c_[200.0 * ta, 0 * ta],
            np.c_[200.0 * tb, 0 * tb + 50e3],
            np.c_[200.0 * (tc % 400), 0 * tc - 50e3],
        ]
    )
    # aircraft 0: id 1 confirmed at 30 s (0–20 s lost: start), 2 km off at 60 s (off),
    # not reported at 70 s (unreported), ends at 100 s; id 2 from 120 s (110 s lost
    # between two ids: id_change; a rebirth) to 150 s (160, 170 s lost: end)
    t1 = np.array([30.0, 40, 50, 60, 80, 90, 100])
    p1 = np.c_[200.0 * t1, np.where(t1 == 60.0, 2000.0, 0.0)]
    t2 = np.arange(120.0, 151.0, 10.0)
    # aircraft 1: id 3 exact until 70 s, id 4 100 m off from 50 s on — both reported
    # 50–70 s, the scorer keeps id 3 there (closer), then id 4: an overlap
    t3, t4 = np.arange(0.0, 71.0, 10.0), np.arange(50.0, 151.0, 10.0)
    # aircraft 2: id 5 on its first flight, id 6 from the second flight's second instant
    # (810 s; 800 s lost: that flight's start) — a new flight, not a rebirth
    t5, t6 = np.arange(0.0, 51.0, 10.0), np.arange(810.0, 851.0, 10.0)
    parts = [
        _rows(1, t1, p1),
        _rows(2, t2, np.c_[200.0 * t2, 0 * t2]),
        _rows(3, t3, np.c_[200.0 * t3, 0 * t3 + 50e3]),
        _rows(4, t4, np.c_[200.0 * t4, 0 * t4 + 50e3 + 100.0]),
        _rows(5, t5, np.c_[200.0 * t5, 0 * t5 - 50e3]),
        _rows(6, t6, np.c_[200.0 * (t6 % 400), 0 * t6 - 50e3]),
    ]
    tt, ti, tp = (np.concatenate(x) for x in zip(*parts, strict=True))
    score = score_self_reports(truth_t, truth_i, truth_p, tt, ti, tp, window=10.0, c=500.0)
    assert score.n_straight == 46
    got = bench.lost_by_kind(score)
    want = {"start": 4, "end": 2, "off": 1, "unreported": 1, "id_change": 1}
    assert {k: round(got[f"lost_straight_{k}"] * 46) for k in bench.LOST_KINDS} == want
    assert sum(got[f"lost_straight_{k}"] for k in bench.LOST_KINDS) == pytest.approx(
        score.lost_straight, abs=1e-15
    )
    changes = ("new_flight", "rebirth", "overlap")
    assert tuple(got[f"id_changes_{k}"] for k in changes) == (1, 1, 1)
    assert got["flights_per_identity"] == pytest.approx(4 / 3)
