"""``jointtrack bench tracker``'s scaling of JIPDA, PMB and PMBM and memory against scans
(issue 34, item 5), on tiny scenes: the points, the slope, the memory growth, the
plot, and refusals of unknown parts. No timing is asserted (the benchmark's numbers
are in benchmarks/RESULTS.md)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from typer.testing import CliRunner

from jointtrack.bench import tracker as bench
from jointtrack.cli import app


@pytest.mark.parametrize("kind", bench.KINDS)
def test_scaling_points_of_each_tracker(kind):
    points = bench.scaling_points(kind, {16: (1, 1), 32: (1, 1)}, warm_targets=8)
    assert [p["n_targets"] for p in points] == [16, 32]
    for p in points:
        assert p["tracker"] == kind
        assert math.isfinite(p["scans_per_second"]) and p["scans_per_second"] > 0
        assert p["ms_per_scan_mean"] == pytest.approx(1e3 / p["scans_per_second"])
        assert 0 <= p["cpu_ms_per_scan_mean"] < math.inf
        # n·P_D targets and n/2 clutter returns a scan, roughly
        assert 0.8 * p["n_targets"] < p["mean_detections"] < 2.2 * p["n_targets"]


def test_loglog_slope_is_the_exponent():
    n = np.array([100.0, 300.0, 1000.0, 3000.0])
    assert bench.loglog_slope(n, 3e-3 * n**1.1) == pytest.approx(1.1, abs=1e-12)


def test_memory_series_and_growth():
    scans, held = bench.memory_series("pmb", 6, every=2, n_targets=10)
    assert scans.tolist() == [2, 4, 6]
    assert (held > 0).all()  # the tracker's own arrays, at least
    s = np.array([10, 20, 30, 40])
    assert bench.memory_growth(s, np.array([5, 100, 100, 100])) == 0.0  # flat second half
    assert bench.memory_growth(s, np.array([100, 100, 100, 110])) == pytest.approx(0.1)


def test_plot_has_a_line_per_tracker_and_the_memory(tmp_path):
    pts = {
        k: [
            {"n_targets": n, "scans_per_second": 1e3 / (c * n), "ms_per_scan_mean": c * n}
            for n in (100, 300, 1000)
        ]
        for k, c in zip(bench.KINDS, (0.1, 0.2, 2.0), strict=True)
    }
    memory = {
        "trackers": {
            k: {"scans": [10, 20], "held_bytes": [2**20, 2**20], "growth_second_half": 0.0}
            for k in bench.KINDS
        }
    }
    path = bench.plot_tracker_scaling(pts, memory, tmp_path / "s.png")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_unknown_parts_and_kinds_are_refused():
    with pytest.raises(ValueError, match="unknown part.*bogus"):
        bench.run(parts=["bogus"])
    with pytest.raises(ValueError, match="kind must be one of"):
        bench.scaling_tracker("jpda", bench.scaling_scene(10, 2))
    res = CliRunner().invoke(app, ["bench", "tracker", "--part", "bogus"])
    assert res.exit_code != 0
    assert "bogus" in res.output
