"""The undetected intensity keeps a recycled track's evidence where it is (issue 33, item 4).

``poisson.prune_and_merge`` merges Gaussian components greedily (Vo & Ma 2006,
Table II): the heaviest absorbs every component within squared Mahalanobis
distance ``merge`` *in that component's own covariance*. Measured in the heavy
one's covariance (as before), a broad prior — the coalescence scene's, 150 m per
axis with weight 3 — absorbed every recycled track within 300 m, and its
evidence was lost for a scan (``benchmarks/RESULTS.md``, "Issue 33, PMBM
re-acquisition").
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from jointtrack.trackers.poisson import prune_and_merge


def test_a_sharp_component_beside_a_broad_heavy_one_is_kept():
    """A recycled track (σ 5 m, weight 0.15) 60 m from a broad prior (σ 150 m,
    weight 3): 0.16 in the prior's covariance, 144 in its own — kept, with its
    weight, mean and covariance; a second sharp one 4 m from it (d² 0.64 in its
    own covariance) merges into it."""
    w = np.array([3.0, 0.15, 0.05])
    m = np.array([[100.0, 100.0, 0, 0], [160.0, 100.0, 0, 0], [164.0, 100.0, 0, 0]])
    P = np.stack([np.diag([150.0**2, 150.0**2, 1, 1]), *[np.diag([25.0, 25.0, 1, 1])] * 2])
    w2, m2, P2 = prune_and_merge(w, m, P, prune=1e-5, merge=4.0, cap=100)
    assert len(w2) == 2
    np.testing.assert_array_equal(w2, [3.0, 0.2])
    np.testing.assert_array_equal(m2[0], m[0])
    np.testing.assert_allclose(m2[1], [161.0, 100.0, 0, 0], rtol=1e-15)


def _greedy_groups(w, m, P, merge):
    """Table II's grouping written out with exact rational arithmetic: the
    heaviest remaining (first by index among equals) absorbs each remaining i
    with (m_i − m_lead)ᵀ P_i⁻¹ (m_i − m_lead) ≤ merge (diagonal P)."""
    left = sorted(range(len(w)), key=lambda i: (-Fraction(w[i]), i))
    groups = []
    while left:
        lead = left[0]
        close = [
            i
            for i in left
            if sum(
                (Fraction(m[i][k]) - Fraction(m[lead][k])) ** 2 / Fraction(P[i][k])
                for k in range(len(m[i]))
            )
            <= Fraction(merge)
        ]
        groups.append(close)
        left = [i for i in left if i not in close]
    return groups


finite = st.floats(-1e3, 1e3, allow_subnormal=False)
variance = st.one_of(st.floats(1e-3, 1e6), st.sampled_from([1e-300, 1e300]))


@settings(max_examples=40, deadline=None)
@given(
    comps=st.lists(
        st.tuples(st.floats(1e-3, 10.0), finite, finite, variance, variance),
        min_size=1,
        max_size=6,
    ),
    merge=st.sampled_from([0.5, 4.0, 16.0]),
)
def test_merged_weights_are_the_exact_greedy_groups(comps, merge):
    """The merged weights are the sums over Table II's groups, each distance in the
    candidate's covariance, against the exact rational grouping (rtol 1e-12;
    positions in a 2 km box, variances from 1e-300 to 1e300). Components with
    identical weights keep their index order (a stable sort)."""
    w = np.array([c[0] for c in comps])
    m = np.array([[c[1], c[2]] for c in comps])
    var = np.array([[c[3], c[4]] for c in comps])
    P = np.stack([np.diag(v) for v in var])
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
        w2, _, _ = prune_and_merge(w, m, P, prune=0.0, merge=merge, cap=100)
    want = [sum(Fraction(w[i]) for i in g) for g in _greedy_groups(w, m, var, merge)]
    np.testing.assert_allclose(np.sort(w2), np.sort([float(x) for x in want]), rtol=1e-12)
