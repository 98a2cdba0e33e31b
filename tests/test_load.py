"""Issue 34 item 4: small problems never wake a thread pool, and what replaced it is exact.

Beside busy processes on two cores, ``FastPDAHypothesiser`` + ``JPDAExact`` took
4.2× the time of Stone Soup's ``PDAHypothesiser`` + ``JPDAwithEHM2``: the
hypothesiser whitened each track's detections with ``scipy.linalg.solve_triangular``,
whose OpenBLAS ``trsm`` woke its worker threads for a 2×2 factor on every call
(``benchmarks/load.py`` measured their CPU: ~17 ms per ``associate`` call, against
none for the other components). The whitening is now the compiled Cholesky and
forward substitution of :mod:`jointtrack._numba_linalg`. The tests: a JPDA step of
two tracks and a dozen detections leaves every other thread of the process idle
(counted in the kernel's per-thread CPU times, not timed); the compiled Gaussian
log density against exact rational arithmetic over magnitudes from 2^-1000 to
2^1000 and zeros.
"""

from __future__ import annotations

import datetime
import math
import os
from fractions import Fraction

import numpy as np
import pytest

pytest.importorskip("stonesoup")

from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402
from stonesoup.models.measurement.linear import LinearGaussian  # noqa: E402
from stonesoup.models.transition.linear import (  # noqa: E402
    CombinedLinearGaussianTransitionModel,
    ConstantVelocity,
)
from stonesoup.predictor.kalman import KalmanPredictor  # noqa: E402
from stonesoup.types.detection import Detection  # noqa: E402
from stonesoup.types.state import GaussianState  # noqa: E402
from stonesoup.types.track import Track  # noqa: E402
from stonesoup.updater.kalman import KalmanUpdater  # noqa: E402

from jointtrack.interop.stonesoup import FastPDAHypothesiser, JPDAExact  # noqa: E402
from jointtrack.interop.stonesoup.hypothesiser import _gaussian_log_pdf  # noqa: E402

T0 = datetime.datetime(2025, 1, 1)
T1 = T0 + datetime.timedelta(seconds=1)


def _other_threads_cpu_ticks() -> int:
    """User + system clock ticks of every thread of this process but the calling one."""
    me = os.getpid()
    own = __import__("threading").get_native_id()
    ticks = 0
    for tid in os.listdir(f"/proc/{me}/task"):
        if int(tid) == own:
            continue
        try:
            with open(f"/proc/{me}/task/{tid}/stat") as fh:
                fields = fh.read().rsplit(")", 1)[1].split()
        except OSError:  # the thread ended meanwhile
            continue
        ticks += int(fields[11]) + int(fields[12])  # utime, stime (fields 14, 15 of stat)
    return ticks


@pytest.mark.skipif(not os.path.isdir("/proc/self/task"), reason="needs Linux /proc")
def test_a_small_jpda_step_wakes_no_other_thread():
    transition = CombinedLinearGaussianTransitionModel([ConstantVelocity(0.005)] * 2)
    measurement = LinearGaussian(ndim_state=4, mapping=(0, 2), noise_covar=np.eye(2) * 0.75)
    hypothesiser = FastPDAHypothesiser(
        KalmanPredictor(transition),
        KalmanUpdater(measurement),
        clutter_spatial_density=0.125,
        prob_detect=0.9,
        include_all=True,  # every pair hypothesised: one 2 × 12 cluster
    )
    associator = JPDAExact(hypothesiser=hypothesiser)
    cov = np.diag([1.5, 0.5, 1.5, 0.5])
    tracks = {
        Track([GaussianState([[0.0], [1.0], [y], [0.0]], cov, timestamp=T0)]) for y in (0.0, 2.0)
    }
    rng = np.random.default_rng(0)
    detections = {
        Detection(rng.uniform(-3, 3, (2, 1)), timestamp=T1, measurement_model=measurement)
        for _ in range(12)
    }
    out = associator.associate(tracks, detections, T1)  # first call: kernels loaded
    assert [len(out[t]) for t in tracks] == [13, 13]  # the miss and 12 detections
    assert max(n for n, *_ in associator.last_clusters) == 2  # one 2-track cluster
    before = _other_threads_cpu_ticks()
    for _ in range(60):
        associator.associate(tracks, detections, T1)
    # 831ecfa: OpenBLAS's trsm workers took 0.61 s of CPU (61 ticks) in these 60 calls
    assert _other_threads_cpu_ticks() - before <= 2


# ---------------------------------------------------- the Gaussian log density, exactly
def _exact_solve(S, d):
    """x with S x = d, by Gaussian elimination in Fractions (S positive definite)."""
    k = len(d)
    a = [[Fraction(S[i][j]) for j in range(k)] + [Fraction(d[i])] for i in range(k)]
    for c in range(k):
        for r in range(c + 1, k):
            f = a[r][c] / a[c][c]
            a[r] = [x - f * y for x, y in zip(a[r], a[c], strict=True)]
    x = [Fraction(0)] * k
    for r in range(k - 1, -1, -1):
        x[r] = (a[r][k] - sum(a[r][j] * x[j] for j in range(r + 1, k))) / a[r][r]
    det = math.prod(a[i][i] for i in range(k))
    return x, det


def _log_fraction(q: Fraction) -> float:
    return math.log(q.numerator) - math.log(q.denominator)


@st.composite
def gaussians(draw):
    """S = 2^e (M Mᵀ + I) for a small-integer M (exact in binary), rows z = mean + 2^f·n."""
    k = draw(st.integers(1, 4))
    small = st.integers(-3, 3)
    M = np.array([[draw(small) for _ in range(k)] for _ in range(k)], float)
    e = draw(st.integers(-1000, 990))
    S = (M @ M.T + np.eye(k)) * 2.0**e
    f = draw(st.integers(-1000, 1000))
    mean = np.array([draw(st.sampled_from([0.0, 1.0, -2.5, 1e300, -1e-300])) for _ in range(k)])
    n_rows = draw(st.integers(0, 5))
    steps = [[draw(st.integers(-7, 7)) for _ in range(k)] for _ in range(n_rows)]
    rows = [mean + np.array(s, float) * 2.0**f for s in steps]
    return S, mean, rows


@settings(max_examples=50, deadline=None)
@given(gaussians())
def test_gaussian_log_pdf_against_exact_rationals(case):
    S, mean, rows = case
    k = mean.size
    got = _gaussian_log_pdf(rows, mean, S)
    assert got is not None
    log_n, d2 = got
    assert log_n.shape == d2.shape == (len(rows),)
    assert not np.isnan(d2).any() and not np.isnan(log_n).any()
    for j, z in enumerate(rows):
        d = [Fraction(float(a)) - Fraction(float(b)) for a, b in zip(z, mean, strict=True)]
        x, det = _exact_solve(S, d)
        exact = sum(a * b for a, b in zip(d, x, strict=True))
        log_det = _log_fraction(det)
        if exact == 0:
            assert d2[j] == 0.0
        elif Fraction(2) ** -900 < exact < Fraction(2) ** 900:
            assert abs(d2[j] - float(exact)) <= 1e-11 * float(exact)
            want = -0.5 * (float(exact) + log_det + k * math.log(2 * math.pi))
            assert abs(log_n[j] - want) <= 1e-11 * (abs(want) + abs(log_det) + 1.0)
        elif exact > Fraction(2) ** 1024:  # past the largest double: inf, never NaN
            assert d2[j] == math.inf and log_n[j] == -math.inf
        else:  # near the edges of the range: rounding only, the sign and order right
            assert d2[j] >= 0.0


def test_gaussian_log_pdf_leaves_what_it_cannot_take_to_stone_soup():
    mean = np.zeros(2)
    rows = [np.array([1.0, 0.5])]
    assert _gaussian_log_pdf(rows, mean, np.array([[1.0, 2.0], [2.0, 1.0]])) is None  # indefinite
    assert _gaussian_log_pdf(rows, mean, np.array([[1.0, 0.0], [0.0, np.nan]])) is None
    assert _gaussian_log_pdf(rows, mean, np.eye(3)) is None  # covariance of another size
    assert _gaussian_log_pdf([np.zeros(3)], mean, np.eye(2)) is None  # detection of another size
    log_n, d2 = _gaussian_log_pdf([], mean, np.eye(2))
    assert log_n.shape == d2.shape == (0,)
    assert _gaussian_log_pdf([np.array([np.inf, 0.0])], mean, np.eye(2)) is None  # not finite
    assert _gaussian_log_pdf(rows, np.array([np.nan, 0.0]), np.eye(2)) is None
