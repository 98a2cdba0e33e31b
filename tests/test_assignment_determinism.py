"""The assignment-sum core gives bit-identical results wherever its arrays lie in memory.

The frontier kernels are compiled with ``reassoc``; a loop that both stored and
summed took LLVM's scalar fallback whenever two small state arrays were allocated
close together, so the same call returned results differing in the last bit from
call to call (seen as a tracker run that differed from an identical run). These
tests repeat identical calls between allocations of random sizes, which moves the
kernels' arrays around, and require one result.
"""

from __future__ import annotations

import numpy as np
import pytest

from jointtrack.assignment import assignment_sum
from jointtrack.association.exact import exact_marginals


def _shuffle_heap(rng):
    # allocations of random sizes, kept alive across the next call
    return [np.empty(int(rng.integers(1, 80))) for _ in range(int(rng.integers(1, 8)))]


# the cluster on which a tracker run first differed from an identical run
TRACKER_CLUSTER = (
    [[18.939842328109215, 33.88098140127758], [24.18890647758695, 13.66679955972508]],
    [0.11864279528749677, 0.11860554350897812],
)


def _random_cluster(shape):
    rng = np.random.default_rng(sum(shape))
    L = rng.random(shape) * 30.0 * (rng.random(shape) < 0.8)
    L[:, 0] += 0.1  # feasible
    return L, rng.random(shape[0]) * 0.2


@pytest.mark.parametrize("shape", [None, (2, 3), (3, 4), (4, 6), (5, 5), (7, 9)])
def test_exact_marginals_do_not_depend_on_memory_placement(shape):
    L, miss = (np.array(a) for a in TRACKER_CLUSTER) if shape is None else _random_cluster(shape)
    rng = np.random.default_rng(0)
    first = exact_marginals(L, miss)
    keep = []
    for _ in range(1000):
        keep.append(_shuffle_heap(rng))
        if len(keep) > 5:
            keep.pop(int(rng.integers(len(keep))))
        again = exact_marginals(L.copy(), miss.copy())
        assert again.tobytes() == first.tobytes()


def test_permanent_value_does_not_depend_on_memory_placement():
    rng = np.random.default_rng(7)
    W = rng.random((6, 6))
    first = assignment_sum(W, marginals=True)
    for _ in range(200):
        junk = _shuffle_heap(rng)
        again = assignment_sum(W.copy(), marginals=True)
        assert again.log_normalizer == first.log_normalizer
        assert again.P.tobytes() == first.P.tobytes()
        del junk


def test_parallel_results_do_not_depend_on_the_thread_count():
    import numba

    rng = np.random.default_rng(3)
    W = rng.random((17, 17))  # a 2^16+ state: the chunked (parallel) kernels run
    null = rng.random(17) * 0.1
    threads = numba.get_num_threads()
    try:
        results = []
        for n in sorted({1, threads}):
            numba.set_num_threads(n)
            results.append(assignment_sum(W, null, marginals=True, parallel=True))
    finally:
        numba.set_num_threads(threads)
    first = results[0]
    serial = assignment_sum(W, null, marginals=True)
    np.testing.assert_allclose(first.P, serial.P, rtol=1e-12, atol=1e-15)
    for res in results[1:]:
        assert res.log_normalizer == first.log_normalizer
        assert res.P.tobytes() == first.P.tobytes()
    assert first.info["max_frontier"] >= 16
