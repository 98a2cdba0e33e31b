"""Tentative tracks as integrated track-splitting filters (issue 33).

D. Mušicki, B. La Scala and R. J. Evans, "Integrated track splitting filter —
efficient multi-scan single target tracking in clutter", *IEEE Transactions on
Aerospace and Electronic Systems* 43(4):1409–1425, 2007 (ITS below).

With ``tentative_association = "splitting"`` a JIPDA tentative track is its
existence r plus a Gaussian mixture of *track components*, each the Kalman
estimate along one measurement history with its probability given that the
target exists. Per scan (ITS §III):

* every component is predicted (the motion model, plus ``tentative_process_noise``);
* component c of weight w_c and gated return m (likelihood ratio
  L_cm = P_D r g_cm(z_m) / λ_m, scaled by the probability that no confirmed track
  took m) give the track's joint events "no return" (1 − r P_D P_G) and "return m
  through component c" (w_c L_cm) — the lone IPDA of
  :mod:`jointtrack.trackers.existence` (point 5) on the mixture's likelihood
  Σ_c w_c g_cm, so its existence update is
  :func:`~jointtrack.trackers.existence.existence_update` unchanged (ITS eq. 30–33);
* every component spawns a miss child (its estimate, weight w_c·β₀ given
  existence) and one child per gated return (its Kalman update, the pair's
  weight given existence; ITS eq. 34–38), so the children's weights sum to one;
* the children are pruned to the ``tentative_components`` most probable and
  renormalised (ITS §IV: the bound that keeps it "efficient"). Pruning never
  touches the existence, which is computed before it.

With no pruning the mixture is the exact posterior over measurement histories (the
tests enumerate them). With one component it is ``"alternatives"``: the surviving
child is the most probable event (a return only when strictly more probable than
"no return", the first of equal returns).
"""

from __future__ import annotations

import numpy as np

from jointtrack.association.pda import pda_pair_marginals
from jointtrack.trackers.existence import existence_update

__all__ = ["component_layout", "its_update", "prune_children"]


def component_layout(counts):
    """``(owner, slot)`` of every component of tracks holding ``counts`` (n,) components
    each: component k is slot ``slot[k]`` of track ``owner[k]`` (tracks in order)."""
    counts = np.asarray(counts, np.int64)
    owner = np.repeat(np.arange(len(counts)), counts)
    starts = np.cumsum(counts) - counts
    slot = np.arange(len(owner)) - starts[owner]
    return owner, slot


def its_update(r, log_w, owner, pair_comp, pair_L, missed, pdg):
    """One scan of ITS for tracks of existence ``r`` (n,).

    ``log_w`` (C,): each component's log weight (normalised within its track),
    ``owner`` (C,) its track; ``pair_comp`` (p,) the component of each gated
    pair and ``pair_L`` (p,) its likelihood ratio P_D r g / λ (module docstring);
    ``missed`` (n,) 1 − P_D P_G and ``pdg`` (n,) P_D P_G of each track.

    Returns ``(r_post, miss_log_w (C,), hit_log_w (p,), used (p,))``: the posterior
    existence, the log weights given existence of each component's miss child and
    of each pair's hit child (together they sum to one per track), and each pair's
    unconditional probability (what it explains of its return). A child whose
    weight underflows below the smallest float gets −∞ (the pruning drops it).
    """
    r = np.asarray(r, float)
    log_w = np.asarray(log_w, float)
    owner = np.asarray(owner, np.int64)
    pair_comp = np.asarray(pair_comp, np.int64)
    rows = owner[pair_comp]
    # the track's joint events: "no return" and "return m through component c"
    miss = (1.0 - r) + r * missed
    beta0, used = pda_pair_marginals(rows, np.exp(log_w[pair_comp]) * pair_L, miss)
    r_post, beta0_e, weights_e = existence_update(r, beta0, used, rows, pdg, missed=missed)
    with np.errstate(divide="ignore"):
        # given existence and no return, the histories keep their relative weights
        miss_log_w = log_w + np.log(beta0_e)[owner]
        hit_log_w = np.log(weights_e)
    return r_post, miss_log_w, hit_log_w, used


def prune_children(owner, log_w, k_max):
    """The children to keep: at most ``k_max`` of each track, the most probable.

    ``owner`` (C,) the track of each child, ``log_w`` (C,) its log weight (−∞:
    dropped). Ties keep the earlier child (miss children come first). Returns
    ``(keep, log_w_kept)``: the kept children's indices, grouped by track in
    decreasing weight, and their log weights renormalised within each track.
    """
    owner = np.asarray(owner, np.int64)
    log_w = np.asarray(log_w, float)
    order = np.lexsort((-log_w, owner))  # by track, largest first, stable on ties
    o = owner[order]
    first = np.r_[True, o[1:] != o[:-1]] if len(o) else np.zeros(0, bool)
    start = np.maximum.accumulate(np.where(first, np.arange(len(o)), 0))
    rank = np.arange(len(o)) - start
    keep = order[(rank < k_max) & np.isfinite(log_w[order])]
    kept_owner, kept = owner[keep], log_w[keep]
    # renormalise in log space (the largest of each track is its first kept child)
    top = np.full(int(owner.max()) + 1 if len(owner) else 0, -np.inf)
    np.maximum.at(top, kept_owner, kept)
    total = np.zeros(len(top))
    np.add.at(total, kept_owner, np.exp(kept - top[kept_owner]))
    return keep, kept - (top + np.log(np.where(total > 0, total, 1.0)))[kept_owner]
