"""The tracker's model fitted to a detections file (issue 32.1): ``jointtrack fit`` and
every ``jointtrack run --detections`` that does not set a value.

What is estimated, and how
--------------------------
Links. Each detection is linked to its nearest neighbour in the scan ``L`` scans
later when it is that detection's nearest neighbour back (mutual nearest
neighbours, :class:`scipy.spatial.cKDTree`), for the lags L of :data:`LAGS`; two links
that share their middle detection make a triple ``z0, z1, z2`` at times
``t0 < t1 < t2`` (gaps ``a = t1 − t0``, ``b = t2 − t1``). A report-like file
(:func:`jointtrack.experiments.run.reporting_from_data`: irregular times, about
one return per time — targets reporting one at a time) has no scans: each report
is linked to its mutual nearest neighbour among the next
:data:`REPORT_WINDOW` reports, whatever their times, and a report's triples at lag
L are it and the L-th and 2L-th reports along its chain of links.

Noise. The velocity difference of a triple, ``D = (z2 − z1)/b − (z1 − z0)/a``,
has per axis, for white-noise-acceleration (CV) motion of power spectral density
q and independent position noise σ² (Bar-Shalom, Li & Kirubarajan, *Estimation
with Applications to Tracking and Navigation*, Wiley 2001, §6.2.2),

    E[D²] = n σ² + p q,   n = 1/a² + (1/a + 1/b)² + 1/b²,   p = (a + b)/3      (1)

— for equal gaps LΔt, times (LΔt)², the classical 6σ² + (2/3) q (LΔt)³. The
lags (or the spread of a report file's gaps) separate σ² and q. Clutter and
mis-links contaminate the triples, so (1) is fitted by trimmed least squares
(concentration steps, as in Rousseeuw & Van Driessen's FAST-MCD, *Technometrics*
41(3), 1999): start from the medians of each lag's ``D²``, keep the triples whose
normalised ``ΣD²/(nσ² + pq)`` is within the χ²_dim 99 % point, refit by
weighted non-negative least squares (weights 1/(nσ² + pq)², the inverse variance
of a Gaussian ``D²``) with the truncated χ² consistency factor, until the kept set
stops changing. Measured on the package's simulated scenes (known σ, q, P_D and
clutter; ``tests/test_fit.py``, three seeds each): σ within 10 %, the triples' q
within a factor 2, P_D within 0.06 (low: targets that die or leave count as
misses), clutter within 25 %. Lags 1 and 2 alone could not resolve q where its
share of (1), (2/3)qΔt³ against 6σ², is below ~1 % (σ 10 m, q 0.5, Δt 1 s: q off
by 5×); lags up to 8 bring it to 20–50 %. A first tracker pass with EM on its
innovations was not chosen: it needs a model to start from (the defaults the
issue found hold nothing on real data) and costs a full run; the link statistics
take 11–15 s on 17 h of 10 s scans (248k detections, a loaded machine). Triples
that repeat one position exactly (moored vessels' quantised AIS positions) are
left out and counted. A fitted σ above :data:`CHANCE_SPACING` × the median
distance between the detections of one scan is refused: the links are chance
(clutter only).

Speed. ``max_speed`` = :data:`SPEED_MARGIN` × the 99 % point of the speeds
``|z2 − z0|/(a + b)`` of the longest lag's inlier triples (the noise's share of a
speed falls with the span); a 99 % point above :data:`MAX_SPEED_BOUND` is refused.

P_D and clutter. From each inlier lag-1 triple the target's position at the next
scan is predicted (straight on); the fraction ``f`` of predictions with a
detection inside their χ² 99.99 % ellipse of (1) gives P_D = (1 − (1 − f)·e^{λA})
/ P_G (a clutter return inside the ellipse, λA, taken out). The clutter density
λ is the detections in no inlier triple per scan (per second for a report-like
file) per area of the detections' bounding box
(:func:`jointtrack.experiments.config.detections_extent`, as the PMB/PMBM
estimate uses).

Gate with q. One missed scan must not lose a straight-flying target (issue 32:
q = 1 with a 99 % gate lost aircraft after one miss; q 20 with P_G 0.9999 held
them). For each inlier lag-1 link followed by a lag-2 link (the return after a
one-scan gap), the residual to the straight-on prediction is normalised by its
variance under (1). When the :data:`NIS_POINT` point of these NIS exceeds the
χ² one — real motion has heavier tails than white acceleration, and the
trimmed fit sees the straight core — q is raised (bisection in log q) until it
matches (NIS consistency). That core leaves the manoeuvring targets' returns out:
on switzerland the tracks that died (142 of 226 id changes on the first 1,500 scans)
lost their aircraft in turns and speed changes, 1–4 km off at their last output. So
q is raised further until the :data:`NIS_TAIL` (99.9 %) point is consistent too,
while the gate after one miss (``P_G_HOLD``, median return) is expected to hold at
most :data:`GATE_CLUTTER` false returns: where clutter is sparse the mis-links a
high point would follow are few and a wide gate costs little; in dense clutter the
core's q stays. ``p_g`` is then the χ² probability of the 99 % point, at least
:data:`P_G_HOLD`, within [:data:`P_G_MIN`, :data:`P_G_MAX`]. Measured: on the
sparse simulated scenes the core raise leaves q as fitted on 5 of 6 seeds (one:
0.5 → 5.6); in dense clutter (gates holding several false returns, e.g. 50 per
scan on 10 km² with σ 30 m) mis-linked returns make it raise q 200× (a safe
direction: wider gates, later confirmation) and the tail adds nothing (0.32 false
returns in the gate). Aircraft-like targets with one 1°/s turn each
(``tests/test_fit.py``): the returns after one miss outside the gate 2.9–3.5 % with
the core alone, 0.26–0.39 % with the tail. On the switzerland ADS-B scene (σ 50 m
synthetic noise on top of the reports' own jitter) the triples give σ ≈ 67 m and q
≈ 0.05, the core q ≈ 3.3, the tail q ≈ 34 m²/s³ (0.003 false returns in the gate):
ids per aircraft 1.64 → 1.34, false tracks 5.3 → 2.4 per hour on the first 1,500
scans (``benchmarks/RESULTS.md``). A larger q (100) did better still there (1.22)
and a CV/CT IMM at q 30 did not (1.33, more false tracks): the fit keeps CV.

Id continuation. A scan file's ``id_continuation`` is :data:`CONTINUATION_SCANS`
median scan intervals: a track confirmed that soon after a confirmed track was
deleted takes its id when it lies in the gate of that track's coasted prediction,
and so does one confirmed in the gate of a track losing its target (missed, or its
existence below ``r_confirm``), which then ends — unambiguous pairs only
(:mod:`jointtrack.trackers.jpda`). On switzerland half of the id changes (60 of 122
on the first 1,500 scans) were a track dying — 43 % of them in turns — and a new one
born on the same aircraft; the window covers the scans from a death to the new
track's confirmation (one-point birth, confirmed on its third return: two scans, and
one missed scan). A longer window hands ids between aircraft: with 6 scans, on the
held-out quickstart flights (JPDA* and the IMM on) 8 of 12 hand-overs mixed two
aircraft, all 50–80 s from the old track's last report to the new one's first —
mostly one slowing to land (≤ 34 m/s in 6) and another taking off kilometres away,
admitted by the wide gate of a prediction coasted that long: purity 0.860 → 0.838.
Measured (``benchmarks/RESULTS.md``): quickstart seed 1 purity 0.860 (off) / 0.838
(6 scans) / 0.856 (3 scans), false tracks 4.7 / 5.0 / 4.3 per hour; seed 2 0.863
(off) / 0.856 (3 scans) — continuation still costs a little purity there; switzerland
seed 2 1.80 (off) / 1.607 (6 scans) / 1.608 (3 scans) ids per aircraft. What is left
there is mostly not the tracker's: 402 of the 550–562 id changes (seeds 2, 1) are an
aircraft's next flight, after it sent no report for longer than the scorer's 600 s —
1.477 flights per aircraft, the fewest ids any tracker without identities can score; a
continuation window could not bridge them without handing ids between aircraft. The
tracker's own are 71–74 rebirths and 77–86 overlapping ids. Report-like files do not
get it.

Report-like files: q and the gate from the moving targets. A report file has no
scans, so no returns after a miss; and on AIS the core of the linked triples is the
moored vessels' (Solent: 40 % of the reports, positions repeated to the quantum):
the trimmed fit of one lag gave σ 0.68 m and q ≈ 0 (q floored), a model the moving
vessels' reports are far outside of (half the reports counted as clutter). The
lag-1 triples whose ends lie apart beyond the noise's :data:`FOUND` ellipse (the
target moved) are the ones the gate must hold: q is raised until their
:data:`REPORT_NIS_POINT` NIS point is the χ² one and ``p_g`` is the χ² probability
of their 99 % point (:func:`_fit_report_gate`); the clutter density then counts the reports
in no linked triple consistent with the final σ and q. Measured on Solent's first 42
minutes (chosen there; the rest of the file held out): σ 1.84 m; the moving
vessels' median NIS asks q 0.002, below the floor 10⁻³σ²/Δt³ = 0.32 (Δt the median gap
between any two reports), which is kept; p_g 0.999999 from their 99 % point.

Report-like files: at rest and under way (JPDA/JIPDA; :func:`_choose_report_models`).
One CV q cannot hold moored vessels and vessels under way: a track started on a moored
vessel's report, with a CV velocity spread, takes its neighbour's report a minute later
(Solent: moored vessels 150–300 m apart reporting every 3 minutes), and a q for the
moving vessels widens every gate. The lag-1 triples whose two links both stay within
the noise's :data:`FOUND` ellipse over at least the median span are *at rest*; the
triples of the longest lag with :data:`MIN_TRIPLES` of them whose ends lie apart beyond
it, and which the fitted σ and q hold, are *moving*. With at least :data:`REST_SHARE`
of each (and :data:`MIN_TRIPLES`), the fit chooses ``motion = "imm"`` with the modes
CV (q as above: the moving targets') and ``"stationary"``
(:class:`~jointtrack.models.Stationary`, q from the at-rest links' spread beyond 2σ²,
floored at 10⁻³σ²/gap), switching in continuous time at :data:`STAY_PER_SECOND` a
second (a stated value, not fitted: :mod:`jointtrack.filters.imm`, "Switching in
time") and a new track's mode probabilities in the proportion of the two classes.
``max_speed`` is 1.5 × the 99 % point of the moving triples' speeds, or refused
(the default, with the reason) when fewer than :data:`REST_SHARE` of them move: the
trimmed core's speeds had been the moored vessels' (0.003 m/s on the first 30
minutes of the bench's Solent scene). Measured (``benchmarks/RESULTS.md``, "Issue 32:
Solent with a stationary IMM mode"): the bench's Solent scene, bare command, coverage
0.810 → 0.870, purity 0.560 → 0.709, ids per vessel 7.08 → 5.58; the plain Solent
file's first 20 minutes 0.506 → 0.526 (purity 0.762 → 0.816) — its vessels at rest
reporting every 3 minutes are still covered ~0.15 (whole file 0.474 → 0.505). Two
causes are reproduced in process — mixing the modes at every other vessel's report
(gone: a reporting target's track is predicted from its last update, purity 0.816 →
0.834 on that slice, the class unchanged at 0.148), and a new track's prior reporting
rate (``report_interval``, the links' mean gap, 11.7 s there; the links cannot see a
3-minute reporter: :data:`REPORT_WINDOW` reports ≈ 108 s) that has it deleted before
its vessel's next report — report_interval 180 s gives 0.158, with new tracks at rest
0.265 (purity 0.782): measured, not chosen here.

Close pairs and turns (scan files, JPDA/JIPDA; :func:`_choose_scan_models`). Both
choices are stated with their counts in the sources, and a key ``[tracker]`` sets is
left alone. ``coalescence_avoidance`` (JPDA*, :mod:`jointtrack.association.coalescence`):
the targets' returns are those of the lag-1 triples whose two links are no faster
than ``max_speed`` — linked either way round, since two targets closer than their
motion in a scan swap their mutual nearest neighbours — and each is measured against
the nearest other such return of its scan in units of a steady track's gate radius
(√(χ²_dim(p_g)·S), S the innovation variance of the steady-state NCV filter at the
fitted σ² and q). JPDA* is chosen when at least :data:`PAIR_SHARE` of them (and
:data:`MIN_TRIPLES`) have one within :data:`PAIR_GATES` radii: their gates overlap,
the two tracks share a cluster, and plain JPDA pulls them together. Where no gates
overlap JPDA* is plain JPDA (one detected track per class), so the rule only says
whether it can matter. ``motion``: the heading change per second of each triple at
the shortest lag whose chords resolve a :data:`TURN_RATE` (1°/s, the scorer's
manoeuvre) turn at :data:`TURN_Z` σ of the position noise (the median triple's;
lag 2 at 10 s scans and σ ≈ 60 m); a turn is *sustained* when the triple one link
on turns the same way beyond both bounds too — noise and ADS-B position jitter
reverse from chord to chord, a turn a CV track loses its target in does not. The
IMM (CV + coordinated turn) is chosen when at least :data:`TURN_SHARE` of the moving
targets' triples (and :data:`MIN_TRIPLES`) turn, sustained; its turn-rate walk
``turn_rate_std`` = the sustained turns' median rate / √Δt (that rate reached in one
scan). Measured (``benchmarks/RESULTS.md``, "Issue 32: the fit chooses JPDA* and the
IMM"): on the held-out quickstart ADS-B scene 18 % of the targets' returns have a
neighbour within two gate radii and 3.3 % of the moving lag-2 triples turn,
sustained, at a median 1.8°/s; on switzerland 0.5 % and 1.0 % (its turning chords'
median 4.8°/s: position jitter, not airliners' turns); straight simulated aircraft
0.2–0.7 % turning, turning ones (3°/s for a fifth of the run) 21 %; the IMM turn
scene (``benchmarks/imm_turn.py``, 5°/s) 84–87 % at lag 8, turn_rate_std 0.085–0.086
(5°/s in one 1 s scan: 0.087). Hand-set on the same
scenes: quickstart with JPDA*: coverage 0.930 → 0.965, close-pair points lost 18.5 →
5.7 %; with JPDA* and the IMM: manoeuvre points lost 7.1 → 2.0 %; switzerland with
the IMM (seeds 1, 2): coverage and ids as CV, but 4.0–4.5 false tracks/h (CV 1.8–2.0)
and 374–382× real time (CV 682–761×) — so the fit keeps CV there (and JPDA* would
have nothing to separate).

A value that cannot be fitted (too few triples, a fitted value outside physical
bounds) is not used: the key gets the TrackerConfig default (or the report-file
default) and :attr:`ModelFit.fallbacks` says why.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
from scipy import optimize, stats
from scipy.spatial import cKDTree

__all__ = [
    "MAX_SPEED_BOUND",
    "MIN_TRIPLES",
    "ModelFit",
    "fit_tracker_settings",
]

#: scan lags of the links: 1 and 2 for P_D and the gate, and longer ones so that q is
#: resolved where its share of (1) at lag 1, (2/3)qΔt³ against 6σ², is small
LAGS = (1, 2, 4, 8)
#: fewer inlier triples than this: the noise, speed, P_D and gate are not fitted
MIN_TRIPLES = 30
#: a fitted speed above this (m/s) is not physical for the targets a file holds
MAX_SPEED_BOUND = 1000.0
#: max_speed = this × the 99 % point of the linked speeds (a one-point track's
#: velocity spread σ_v = max_speed/2 must hold the fastest targets)
SPEED_MARGIN = 1.5
#: a fitted σ above this fraction of the median distance between the detections of one
#: scan is refused: the links are chance (uniform clutter alone fits σ ≈ 0.4 of it;
#: the simulated scenes 0.01–0.04, switzerland ADS-B < 0.01)
CHANCE_SPACING = 0.25
#: report-like files: a report is linked among the next this many reports
REPORT_WINDOW = 400
#: the gate probability chosen with q lies within these
P_G_MIN, P_G_MAX = 0.99, 0.999999
#: the largest gate the fit gives before it raises q instead (issue 32: q 20 with P_G
#: 0.9999 held the aircraft that q 1 with P_G 0.99 lost after one miss)
P_G_HOLD = 0.9999
#: q is raised until this point of the NIS after one miss is the χ² one (consistency,
#: robust to the few per cent of mis-linked returns a 99 % point is not)
NIS_POINT = 0.9
#: then q is raised further until this point of that NIS is the χ² one — the returns
#: of manoeuvring targets, which a 90 % point leaves out of the gate (switzerland: the
#: tracks that died did so in turns and speed changes) — while the gate after one miss
#: is expected to hold at most :data:`GATE_CLUTTER` false returns (sparse clutter: mis-links
#: are few, wide gates cost little; dense clutter: no tail raise)
NIS_TAIL = 0.999
#: the expected false returns in the P_G_HOLD gate after one miss that stop the tail raise
GATE_CLUTTER = 0.1
#: report-like files: q is raised until this point of the moving targets' NIS is the χ²
#: one — the core of their motion; the tails go to the gate (p_g from the 99 % point).
#: Their tails are heavy (Solent's first 42 minutes: the 50 / 75 / 90 % points ask
#: q 0.002 / 0.17 / 2.0 m²/s³), and one q serves moored and moving vessels alike: on the
#: first 20 minutes q 3 (the 90 % point) confirmed 32 tracks for 79 vessels, coverage
#: 0.42, q 0.3 43 tracks, coverage 0.50 at a better purity (0.78 against 0.73); on the
#: whole file the 75 % point (q 0.74) gave coverage 0.43 (``benchmarks/RESULTS.md``)
REPORT_NIS_POINT = 0.5
#: report-like files: the IMM with a stationary mode (CV + at rest) when at least this
#: share of the lag-1 triples, and of :data:`MIN_TRIPLES`, is each of at rest and moving
REST_SHARE = 0.1
#: report-like files with the stationary mode: the probability per second of staying in
#: a mode (a vessel stops or gets under way about once in a quarter of an hour; the
#: chain is in continuous time, ``imm_switching_per = "second"``)
STAY_PER_SECOND = 0.999
#: scan files: a new track takes the id of a track deleted at most this many median scan
#: intervals before (``id_continuation``): a rebirth's confirmation latency (two scans)
#: and one missed scan; 6 mixed aircraft on quickstart (module docstring, "Id continuation")
CONTINUATION_SCANS = 3
#: P_D estimates are kept within these (a tracker with P_D = 1 treats any miss as death)
P_D_MIN, P_D_MAX = 0.05, 0.995
#: the trimming point of the concentration steps (χ²_dim probability)
TRIM = 0.99
#: a detection after the prediction counts as present inside this χ²_dim probability
FOUND = 0.9999
#: the keys a fit can set (in this order in the TOML)
FIT_KEYS = (
    "measurement_noise",
    "process_noise",
    "max_speed",
    "p_d",
    "p_g",
    "clutter_density",
    "id_continuation",
    "report_interval",
)
#: the keys the PMB/PMBM trackers take from a fit (the rest are JPDA/JIPDA track logic
#: or chosen by make_pmbm_config)
POISSON_FIT_KEYS = ("measurement_noise", "process_noise", "p_d", "clutter_density")
_KINDS = (None, "jipda", "jpda", "pmb", "pmbm")
#: close pairs: another target's return within this many gate radii of a target's return
#: (their gates overlap: the two tracks share a cluster and its returns)
PAIR_GATES = 2.0
#: JPDA* on when at least this share of the targets' returns have such a neighbour
PAIR_SHARE = 0.01
#: turns: a heading change faster than this (rad/s; the scorer's manoeuvre, 1°/s) ...
TURN_RATE = math.radians(1.0)
#: ... and beyond this many standard deviations of its noise
TURN_Z = 3.0
#: the IMM when at least this share of the moving targets' triples turn, sustained
TURN_SHARE = 0.02


@dataclass(frozen=True)
class ModelFit:
    """A fitted ``[tracker]`` table and where each value came from.

    Attributes
    ----------
    table : the user's keys plus every fitted or defaulted key, ready for
        :func:`jointtrack.experiments.config.make_tracker_config`
        (``clutter_density = "estimate"`` where the default estimates it).
    sources : key → one sentence: how the value was obtained, from what evidence.
    fallbacks : key → why the fit could not be made (the value in ``table`` is
        then the stated default).
    evidence : counts behind the fit (detections, links, triples, inliers).
    """

    table: dict
    sources: dict
    fallbacks: dict = field(default_factory=dict)
    evidence: dict = field(default_factory=dict)

    @property
    def fitted(self) -> tuple:
        """The keys whose value was fitted from the data."""
        return tuple(k for k, s in self.sources.items() if s.startswith("fitted"))

    def notes(self) -> list[str]:
        """Sentences for metrics.json and the summary: each fitted value with its source,
        the keys of :data:`FIT_KEYS` set in ``[tracker]``, the report-file settings and
        the defaults used — keys that share a source or a reason in one sentence."""
        keys = [k for k in self.sources if k in FIT_KEYS or not self.sources[k].startswith("set")]
        groups: dict = {}
        for k in keys:
            if k in self.fallbacks:
                groups.setdefault(("default", self.fallbacks[k]), []).append(k)
            else:
                groups.setdefault(("source", self.sources[k]), []).append(k)
        out = []
        for (what, text), ks in groups.items():
            values = ", ".join(f"{k} = {_value_text(self.table[k])}" for k in ks)
            if what == "default":
                text = f"the default{'s' if len(ks) > 1 else ''}; {text}"
            out.append(f"[tracker] {values}: {text}")
        return out

    def identity(self) -> dict:
        """The fitted values as JSON-able entries (part of a run's identity)."""
        return {k: self.table[k] for k in self.sources if not self.sources[k].startswith("set in")}

    def to_toml(self) -> str:
        """A commented ``[tracker]`` TOML table that ``jointtrack run --config`` accepts."""
        lines = [
            "# jointtrack fit: the tracker model fitted to the detections",
            "# (edit and pass to `jointtrack run --config`; each value's source is its comment)",
            "[tracker]",
        ]
        for key, value in self.table.items():
            why = self.sources.get(key)
            if why:
                lines.append(f"# {why}")
            lines.append(f"{key} = {_toml_value(value)}")
        return "\n".join(lines) + "\n"


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int | np.integer):
        return str(int(v))
    if isinstance(v, float | np.floating):
        v = float(v)
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, list | tuple):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if v is None:
        raise ValueError("a [tracker] value None has no TOML form")
    raise ValueError(f"a [tracker] value of type {type(v).__name__} has no TOML form")


def _value_text(v) -> str:
    if isinstance(v, float):
        return f"{v:.4g}"
    return repr(v) if isinstance(v, str) else str(v)


def _defaults() -> dict:
    from jointtrack.trackers.config import TrackerConfig

    d = TrackerConfig().to_dict()
    return {k: ("estimate" if d[k] is None else d[k]) for k in FIT_KEYS}


# ----------------------------------------------------------------------------- links


def _mutual(a: np.ndarray, b: np.ndarray, tree_a, tree_b) -> tuple[np.ndarray, np.ndarray]:
    """Indices (i, j) of mutual nearest neighbours between point sets a and b."""
    if not len(a) or not len(b):
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    _, j = tree_b.query(a)
    _, i_back = tree_a.query(b)
    i = np.arange(len(a))
    keep = i_back[j] == i
    return i[keep], np.asarray(j)[keep]


def _scan_triples(times, scans, dim):
    """Triples of mutually linked detections at lags 1 and 2 (scan files).

    Returns ``(g0, g1, g2, lag, pos, t, spacing)``: global row indices of the three
    detections and each triple's lag, the positions and times of every detection
    (global rows), and the median distance from a detection to its nearest
    neighbour in its own scan (None without a scan of two).
    """
    sizes = np.array([len(z) for z in scans])
    start = np.concatenate([[0], np.cumsum(sizes)])
    pos = np.concatenate(
        [np.asarray(z, float).reshape(-1, dim) for z in scans] or [np.zeros((0, dim))]
    )
    t = np.repeat(np.asarray(times, float), sizes)
    trees = [cKDTree(np.asarray(z, float).reshape(-1, dim)) if len(z) else None for z in scans]
    K = len(scans)
    # the spacing of detections within a scan: links much shorter than it are no chance
    spacing = [
        tree.query(tree.data, k=2)[0][:, 1] for tree in trees if tree is not None and tree.n > 1
    ]
    spacing = float(np.median(np.concatenate(spacing))) if spacing else None
    out = []
    for lag in LAGS:
        nxt = np.full(len(pos), -1, np.int64)
        for k in range(K - lag):
            if trees[k] is None or trees[k + lag] is None:
                continue
            i, j = _mutual(scans[k], scans[k + lag], trees[k], trees[k + lag])
            nxt[start[k] + i] = start[k + lag] + j
        g0 = np.flatnonzero(nxt >= 0)
        g1 = nxt[g0]
        has = nxt[g1] >= 0
        g0, g1 = g0[has], g1[has]
        out.append((g0, g1, nxt[g1], np.full(g0.size, lag)))
    g0, g1, g2, lag = (np.concatenate(c) for c in zip(*out, strict=True))
    return g0, g1, g2, lag, pos, t, spacing


def _report_triples(times, scans, dim):
    """Triples of mutually linked reports (report-like files: a report is linked to its
    nearest neighbour among the next :data:`REPORT_WINDOW` reports), each report with
    the L-th and 2L-th reports along its chain of links for the lags L of :data:`LAGS`."""
    sizes = np.array([len(z) for z in scans])
    pos = np.concatenate(
        [np.asarray(z, float).reshape(-1, dim) for z in scans] or [np.zeros((0, dim))]
    )
    t = np.repeat(np.asarray(times, float), sizes)
    n = len(pos)
    fwd = np.full(n, -1, np.int64)
    back = np.full(n, -1, np.int64)
    if n >= 2:
        bf = np.full(n, np.inf)
        bb = np.full(n, np.inf)
        for s in range(1, min(REPORT_WINDOW, n - 1) + 1):
            d = np.sum((pos[s:] - pos[:-s]) ** 2, axis=1)
            d[t[s:] <= t[:-s]] = np.inf  # same time: another target
            i = np.arange(n - s)
            better = d < bf[:-s]
            fwd[i[better]] = i[better] + s
            bf[:-s][better] = d[better]
            better_b = d < bb[s:]
            back[(i + s)[better_b]] = i[better_b]
            bb[s:][better_b] = d[better_b]
    nxt = np.full(n, -1, np.int64)
    ok = fwd >= 0
    ok[ok] = back[fwd[ok]] == np.flatnonzero(ok)
    nxt[ok] = fwd[ok]
    # chains of links: the L-th linked report after one, for the lags L of LAGS (one lag
    # alone could not separate σ from q where the gaps' spread is small against their
    # mean: a mixture of moored and moving vessels fitted σ 7× too small, q as 0)
    out = []
    ahead = np.arange(n)
    step = 0
    for L in LAGS:
        while step < L:
            ahead = np.where(ahead >= 0, nxt[np.maximum(ahead, 0)], -1)
            step += 1
        g0 = np.flatnonzero(ahead >= 0)
        g1 = ahead[g0]
        has = ahead[g1] >= 0
        g0, g1 = g0[has], g1[has]
        out.append((g0, g1, ahead[g1], np.full(g0.size, L, np.int64)))
    g0, g1, g2, lag = (np.concatenate(c) for c in zip(*out, strict=True))
    return g0, g1, g2, lag, pos, t, None


# ----------------------------------------------------------------------------- noise


def _design(t0, t1, t2):
    a, b = t1 - t0, t2 - t1
    n = 1 / a**2 + (1 / a + 1 / b) ** 2 + 1 / b**2
    p = (a + b) / 3
    return a, b, n, p


def _fit_noise(D2, n, p, lag, dim):
    """Trimmed weighted NNLS of (1): ``(σ², q, inlier mask)`` or None.

    Solved in units of the medians of ``D²/dim``, ``n`` and ``p`` (each column and the
    right-hand side O(1)), so that data near the float range's ends neither overflow
    nor underflow inside the least squares; the scale goes back on at the end.
    """
    k = stats.chi2.ppf(TRIM, dim)
    # E[u | u ≤ k] / dim for u ~ χ²_dim: the trimmed set's variance shrinks by this
    consistency = stats.chi2.cdf(k, dim + 2) / stats.chi2.cdf(k, dim)
    y_ref, n_ref, p_ref = float(np.median(D2)) / dim, float(np.median(n)), float(np.median(p))
    if not (y_ref > 0 and n_ref > 0 and p_ref > 0):
        return None
    Y, N, P = D2 / dim / y_ref, n / n_ref, p / p_ref
    # start: each lag group's median (χ²_dim median / dim = the variance's share)
    med = stats.chi2.median(dim) / dim
    groups = np.unique(lag)
    if len(groups) > 1:
        A = np.array([[np.median(N[lag == L]), np.median(P[lag == L])] for L in groups])
        y = np.array([np.median(Y[lag == L]) / med for L in groups])
    else:  # one group (a report file): the spread of the gaps separates them
        sel = Y <= np.quantile(Y, 0.5)
        A, y = np.column_stack([N[sel], P[sel]]), Y[sel] / (med * consistency)
    theta, _ = optimize.nnls(A, y)
    if not np.any(theta > 0):
        theta = np.array([1.0 / med, 0.0])
    inl = None
    for _ in range(50):
        s = N * theta[0] + P * theta[1]
        new = Y / s <= k / dim
        if new.sum() < 3:
            return None
        if inl is not None and np.array_equal(new, inl):
            break
        inl = new
        w = 1.0 / s[inl]
        theta, _ = optimize.nnls(
            np.column_stack([N[inl], P[inl]]) * w[:, None], Y[inl] * w / consistency
        )
        if not np.any(theta > 0):
            return None
    with np.errstate(over="ignore"):
        return theta[0] * (y_ref / n_ref), theta[1] * (y_ref / p_ref), inl


# ----------------------------------------------------------------------------- the fit


def fit_tracker_settings(
    detections, table: Mapping | None = None, kind: str | None = None
) -> ModelFit:
    """Fit the tracker's model to ``detections`` (module docstring).

    Parameters
    ----------
    detections : :class:`jointtrack.io.Detections`, position detections.
    table : the user's ``[tracker]`` table; a key it sets is never fitted (its
        source is "set in [tracker]").
    kind : the tracker kind, None (JIPDA), ``"jipda"``, ``"jpda"``, ``"pmb"`` or
        ``"pmbm"``: PMB/PMBM take :data:`POISSON_FIT_KEYS` only.

    Returns
    -------
    ModelFit

    Raises
    ------
    TypeError, ValueError
        ``detections`` not a Detections, ``table`` not a mapping, an unknown ``kind``.
    """
    from jointtrack.experiments.config import detections_extent
    from jointtrack.experiments.run import reporting_from_data
    from jointtrack.io import Detections

    if not isinstance(detections, Detections):
        raise TypeError(
            f"detections must be a jointtrack.io.Detections, got {type(detections).__name__}"
        )
    if table is not None and not isinstance(table, Mapping):
        raise TypeError(f"table must be a mapping ([tracker] keys), got {type(table).__name__}")
    if kind not in _KINDS:
        raise ValueError(f"kind must be None, jipda, jpda, pmb or pmbm, got {kind!r}")
    user = dict(table or {})
    out, note = reporting_from_data(detections, user, kind)
    sources = {k: "set in [tracker]" for k in user}
    report_like = note is not None
    if report_like:
        for k in out:
            if k not in user:
                sources[k] = "report-like file: " + note
    keys = POISSON_FIT_KEYS if kind in ("pmb", "pmbm") else FIT_KEYS
    # report_interval: report-like files only; id_continuation: scan files only (its
    # window is a number of scans)
    drop = "id_continuation" if report_like else "report_interval"
    keys = tuple(k for k in keys if k != drop)
    wanted = [k for k in keys if k not in user]
    defaults = _defaults()
    if report_like:
        defaults["clutter_density"] = (
            out["clutter_density"] if "clutter_density" not in user else None
        )
    fallbacks: dict = {}
    fitted: dict = {}
    evidence: dict = {
        "detections": int(detections.n_detections),
        "times": int(detections.times.size),
    }

    def fall_all(why: str) -> ModelFit:
        for k in wanted:
            fallbacks[k] = why
        return _finish(out, sources, fitted, fallbacks, defaults, wanted, evidence)

    if not wanted:
        return _finish(out, sources, fitted, fallbacks, defaults, wanted, evidence)
    if detections.kind != "position":
        return fall_all(f"not fitted: {detections.kind} detections (the fit needs positions)")
    dim = detections.dim
    scans = detections.scans
    times = detections.times
    if detections.n_detections < 3 or times.size < 3:
        return fall_all(
            f"not fitted: too few detections ({detections.n_detections} at {times.size} times; "
            "the fit links three in a row)"
        )
    build = _report_triples if report_like else _scan_triples
    g0, g1, g2, lag, pos, t, spacing = build(times, scans, dim)
    fin = np.all(np.isfinite(pos), axis=1)
    keep = fin[g0] & fin[g1] & fin[g2]
    g0, g1, g2, lag = g0[keep], g1[keep], g2[keep], lag[keep]
    evidence["triples"] = int(g0.size)
    # every linked triple, with those that repeat a position (at rest, to the quantum)
    linked = (g0, g1, g2, lag)
    if g0.size < MIN_TRIPLES:
        return fall_all(
            f"not fitted: {g0.size} linked triples of detections (fewer than {MIN_TRIPLES}: too "
            "few reports, too few scans with the same target, or clutter only)"
        )
    a, b, n, p = _design(t[g0], t[g1], t[g2])
    with np.errstate(over="ignore", invalid="ignore"):
        D = (pos[g2] - pos[g1]) / b[:, None] - (pos[g1] - pos[g0]) / a[:, None]
        D2 = np.sum(D**2, axis=1)
    # a triple whose squares leave the float range (coordinates near 1e150, gaps near 0)
    # cannot be weighed: left out, never an inf in the fit
    finite = np.isfinite(D2) & np.isfinite(n) & np.isfinite(p) & (n > 0) & (p > 0)
    evidence["triples_out_of_range"] = int((~finite).sum())
    # a triple that repeats one position exactly (a moored vessel's quantised AIS
    # position) says nothing about the noise of a moving target: left out, counted
    evidence["triples_repeating"] = int(np.count_nonzero(finite & (D2 == 0)))
    finite &= D2 > 0
    if not finite.all():
        g0, g1, g2, lag = g0[finite], g1[finite], g2[finite], lag[finite]
        a, b, n, p, D2 = a[finite], b[finite], n[finite], p[finite], D2[finite]
    if g0.size < MIN_TRIPLES:
        return fall_all(
            f"not fitted: {g0.size} linked triples that do not repeat a position, with squares "
            f"in the float range (fewer than {MIN_TRIPLES})"
        )
    res = _fit_noise(D2, n, p, lag, dim)
    if res is None:
        return fall_all(
            "not fitted: no consistent set of linked triples (clutter only, or positions "
            "without noise)"
        )
    sigma2, q, inl = res
    n_in = int(inl.sum())
    evidence["inliers"] = n_in
    evidence["q_triples"] = float(q)
    if n_in < MIN_TRIPLES:
        return fall_all(
            f"not fitted: {n_in} linked triples consistent with one motion model (fewer than "
            f"{MIN_TRIPLES}: too few reports or clutter only)"
        )
    side, _ = detections_extent(scans, dim)
    extent = float(np.max(side)) if side is not None else 0.0
    lags = ", ".join(str(int(L)) for L in np.unique(lag[inl]))
    how = f"{n_in:,} of {g0.size:,} linked triples" + (
        f", lags {lags}"
        if not report_like
        else f" of reports (each with its mutual nearest next report), lags {lags}"
    )
    sigma = math.sqrt(sigma2)
    evidence["spacing"] = spacing
    if spacing is not None and sigma > CHANCE_SPACING * spacing:
        return fall_all(
            f"not fitted: the fitted noise σ = {sigma:.4g} is {sigma / spacing:.2g} × the median "
            f"distance between detections of one scan ({spacing:.4g}): the links are no closer "
            "than chance (clutter only, or targets closer together than their noise)"
        )
    sigma_ok = sigma2 > 0 and sigma < extent
    if not sigma_ok:
        why = (
            f"measurement noise σ = {sigma:.4g} refused: larger than the data's extent "
            f"({extent:.4g})"
            if sigma2 > 0
            else "measurement noise fitted as 0 (no position noise separable from the motion)"
        )
        for k in ("measurement_noise", "process_noise", "p_d", "p_g"):
            fallbacks[k] = "not fitted: " + why
    else:
        fitted["measurement_noise"] = (
            float(sigma2),
            f"fitted: σ = {sigma:.4g} from the velocity differences of {how} (trimmed least "
            "squares of E[D²] = nσ² + pq)",
        )
    dt = float(np.median(np.diff(times))) if times.size > 1 else 1.0
    if not report_like:
        fitted["id_continuation"] = (
            CONTINUATION_SCANS * dt,
            f"fitted: {CONTINUATION_SCANS} × the median scan interval ({dt:.4g} s)",
        )
    q_floor = 1e-3 * max(sigma2, 1e-300) / dt**3
    if sigma_ok:
        if q < q_floor:
            fitted["process_noise"] = (
                float(q_floor),
                f"fitted: q below what {how} resolve ({q:.3g}); set to 10⁻³ σ²/Δt³",
            )
            q = q_floor
        else:
            fitted["process_noise"] = (
                float(q),
                f"fitted: white-acceleration q from the same {n_in:,} triples (σ and q together)",
            )
    # speeds of the inlier triples' first links
    # over the longest inlier triples: the noise's share of a speed falls with the span
    longest = inl & (lag == lag[inl].max())
    span_t = a[longest] + b[longest]
    speed = np.linalg.norm(pos[g2[longest]] - pos[g0[longest]], axis=1) / span_t
    v99 = float(np.quantile(speed, 0.99))
    if v99 > MAX_SPEED_BOUND:
        fallbacks["max_speed"] = (
            f"not fitted: the linked speeds' 99 % point {v99:,.4g} m/s refused (above "
            f"{MAX_SPEED_BOUND:,.0f} m/s: not a target's speed; are the positions in metres "
            "and the times in seconds?)"
        )
    else:
        vmax = max(SPEED_MARGIN * v99, 1e-6)
        fitted["max_speed"] = (
            float(vmax),
            f"fitted: {SPEED_MARGIN:g} × the 99 % point ({v99:.4g}) of the speeds of {how}",
        )
    # clutter: detections in no inlier triple
    used = np.zeros(len(pos), bool)
    used[g0[inl]] = used[g1[inl]] = used[g2[inl]] = True
    n_free = int(len(pos) - used.sum())
    area = float(np.prod(side)) if side is not None else 0.0
    span = float(times[-1] - times[0])
    per = span if report_like else float(times.size)
    unit = "per second per m²" if report_like else "per scan per unit area"
    lam = None
    if area > 0 and per > 0:
        lam = max(n_free, 0.5) / (per * area)
        fitted["clutter_density"] = (
            float(lam),
            f"fitted: {n_free:,} of {len(pos):,} detections in no linked triple, "
            f"{unit} of the bounding box ({area:.4g})"
            + (" (none: half a detection assumed)" if n_free == 0 else ""),
        )
    else:
        fallbacks["clutter_density"] = "not fitted: the detections' bounding box has no area"
    if report_like:
        fallbacks.setdefault(
            "p_d",
            "not fitted for a report-like file (no scans: a target's missing reports are not "
            "seen as such)",
        )
        q_gate = None
        if sigma_ok:
            # the tracker's innovations are one report apart: the lag-1 triples
            one = lag == 1
            q_gate = _fit_report_gate(
                fitted, fallbacks, pos, g0[one], g2[one], n[one], p[one], D2[one], sigma2, q, dim
            )
        if q_gate is not None and lam is not None:
            # clutter: the reports in no triple consistent with the model the tracker gets
            # (the trimmed core alone left the moving targets' reports as clutter)
            held = D2 / (n * sigma2 + p * q_gate) <= stats.chi2.ppf(FOUND, dim)
            used = np.zeros(len(pos), bool)
            used[g0[held]] = used[g1[held]] = used[g2[held]] = True
            n_free = int(len(pos) - used.sum())
            lam = max(n_free, 0.5) / (per * area)
            fitted["clutter_density"] = (
                float(lam),
                f"fitted: {n_free:,} of {len(pos):,} reports in no linked triple within the "
                f"{FOUND:.2%} ellipse of the fitted σ and q, per second per m² of the bounding "
                f"box ({area:.4g})" + (" (none: half a report assumed)" if n_free == 0 else ""),
            )
        if sigma_ok:
            _choose_report_models(
                fitted, fallbacks, wanted, out, evidence, pos, t, linked, sigma2, kind
            )
        gaps = a[inl & (lag == 1)]
        fitted["report_interval"] = (
            float(np.mean(gaps)),
            f"fitted: the mean gap between a target's linked reports ({gaps.size:,} links)",
        )
    elif sigma_ok:
        _fit_pd_gate(
            fitted,
            fallbacks,
            pos,
            t,
            times,
            scans,
            dim,
            g0,
            g1,
            g2,
            lag,
            inl,
            sigma2,
            q,
            lam,
            dt,
            how,
        )
    _choose_scan_models(fitted, wanted, out, evidence, kind, report_like, pos, t, g0, g1, g2, lag)
    return _finish(out, sources, fitted, fallbacks, defaults, wanted, evidence)


def _raise_q(q0: float, short) -> float:
    """The smallest q ≥ ``q0`` (bisection in log q, 24 steps) where ``short(q)`` stops
    holding; ``short`` holds below some q and not above it (e.g. a NIS point above its
    χ² value). ``q0`` itself when ``short(q0)`` does not hold."""
    if not short(q0):
        return q0
    lo, hi = math.log(q0), math.log(q0) + 1.0
    while short(math.exp(hi)) and hi < math.log(q0) + 60 and math.exp(hi) < 1e290:
        hi += 2.0
    for _ in range(24):
        mid_q = 0.5 * (lo + hi)
        lo, hi = (mid_q, hi) if short(math.exp(mid_q)) else (lo, mid_q)
    return math.exp(hi)


def _fit_report_gate(fitted, fallbacks, pos, g0, g2, n, p, D2, sigma2, q, dim) -> float | None:
    """A report-like file's q and gate with q, from the moving targets' linked reports;
    returns the q the tracker gets (None: not fitted, the reason in ``fallbacks``).

    The trimmed fit of (1) sees the core of the linked triples, and on an AIS file that
    core is the moored vessels' (Solent: σ 0.68 m, q ≈ 0 — a gate of a few metres,
    too narrow for a vessel under way, whose reports then start new tracks or count as
    clutter). The triples whose ends ``z0, z2`` lie apart beyond the noise's
    :data:`FOUND` ellipse (``|z2 − z0|² > χ²_dim(FOUND) · 2σ²``: the target moved)
    are the ones the gate must hold: q is raised until the :data:`REPORT_NIS_POINT`
    point of their ``D²/(nσ² + pq)`` is the χ² one (NIS consistency, as a scan file's
    returns after one miss; robust to the mis-links), and ``p_g`` is the χ²
    probability of their 99 % point, at least :data:`P_G_HOLD`. Each report's D of
    (1) is the innovation of its straight-on prediction from the two before it, times
    ``1/b``: the tracker's own innovation for a target reporting at these gaps.
    """
    moving = np.sum((pos[g2] - pos[g0]) ** 2, axis=1) > stats.chi2.ppf(FOUND, dim) * 2 * sigma2
    n_mov = int(moving.sum())
    if n_mov < MIN_TRIPLES:
        fallbacks["p_g"] = (
            f"not fitted: {n_mov} linked triples of reports of a moving target (fewer than "
            f"{MIN_TRIPLES})"
        )
        return None
    Dm, nm, pm = D2[moving], n[moving], p[moving]

    def nis_at(qq: float, point: float) -> float:
        return float(np.quantile(Dm / (nm * sigma2 + pm * qq), point))

    gamma = stats.chi2.ppf(REPORT_NIS_POINT, dim)
    q0 = q if q > 0 else 1e-3 * sigma2 / float(np.median(p)) ** 3
    q_used = _raise_q(q0, lambda qq: nis_at(qq, REPORT_NIS_POINT) > gamma)
    text = (
        f"{n_mov:,} linked triples of reports of moving targets (ends apart beyond the "
        f"noise's {FOUND:.2%} ellipse): NIS {REPORT_NIS_POINT:.0%} point "
        f"{nis_at(q_used, REPORT_NIS_POINT):.3g} (χ² {gamma:.3g})"
    )
    if q_used > q0:
        fitted["process_noise"] = (
            float(q_used),
            f"fitted with the gate: raised from q = {q:.3g} until {text} (NIS "
            "consistency; the trimmed core is the stationary targets')",
        )
    pg = max(float(stats.chi2.cdf(nis_at(q_used, 0.99), dim)), P_G_HOLD)
    pg_c = float(min(max(pg, P_G_MIN), P_G_MAX))
    fitted["p_g"] = (
        pg_c,
        f"fitted with q: the χ² probability of the 99 % point of the NIS of {text}, at least "
        f"{P_G_HOLD}" + (f"; {pg:.6g} kept within [{P_G_MIN}, {P_G_MAX}]" if pg_c != pg else ""),
    )
    return q_used


def _choose_report_models(
    fitted, fallbacks, wanted, table, evidence, pos, t, linked, sigma2, kind=None
):
    """A report-like file's ``max_speed`` from its moving targets, and the IMM with a
    stationary mode when it holds targets at rest and moving ones (module docstring,
    "Report-like files: at rest and under way").

    ``linked``: every linked triple ``(g0, g1, g2, lag)`` (those repeating a position
    too). At rest: lag-1 triples spanning at least their median span whose both links
    stay within the noise's :data:`FOUND` ellipse (``|Δz|² ≤ χ²_dim(FOUND)·2σ²``).
    Moving: triples of the longest lag with :data:`MIN_TRIPLES` of them whose ends
    ``z0``, ``z2`` lie apart beyond it and that the fitted σ and q hold (D of (1) in
    their FOUND ellipse: a mis-link between two targets is a jump no such motion
    explains). Moored targets' chains of links are short (their nearest next report is
    any of their own), so the at-rest class is counted at lag 1.
    """
    dim = pos.shape[1]
    bound = stats.chi2.ppf(FOUND, dim) * 2.0 * sigma2
    q_fit = float(fitted["process_noise"][0]) if "process_noise" in fitted else None

    def classes(L):
        """``(g0, g1, g2, at rest, moving)`` of the lag-L triples (docstring)."""
        g0, g1, g2 = (v[linked[3] == L] for v in linked[:3])
        d01 = np.sum((pos[g1] - pos[g0]) ** 2, axis=1)
        d12 = np.sum((pos[g2] - pos[g1]) ** 2, axis=1)
        d02 = np.sum((pos[g2] - pos[g0]) ** 2, axis=1)
        span = t[g2] - t[g0]
        # at rest over at least the median span: a target under way reported twice in a
        # few seconds has not yet moved beyond its noise
        rest = (d01 <= bound) & (d12 <= bound) & (span >= np.median(span) if span.size else 0)
        moving = d02 > bound
        if q_fit is not None and g0.size:
            a, b, n, p = _design(t[g0], t[g1], t[g2])
            with np.errstate(all="ignore"):
                D = (pos[g2] - pos[g1]) / b[:, None] - (pos[g1] - pos[g0]) / a[:, None]
                nis = np.sum(D**2, axis=1) / (n * sigma2 + p * q_fit)
            moving &= nis <= stats.chi2.ppf(FOUND, dim)
        return g0, g1, g2, rest, moving

    g0, g1, g2, rest, _ = classes(1)
    n_all, n_rest = int(g0.size), int(rest.sum())
    # the moving targets at the longest lag that has enough of them: over a long span
    # their speed is the least noisy (the noise's share falls with the span)
    L = 1
    for lag_ in sorted(np.unique(linked[3]).tolist(), reverse=True):
        m0, _, m2, _, moving = classes(lag_)
        if moving.sum() >= MIN_TRIPLES or lag_ == 1:
            L, n_lag = int(lag_), int(m0.size)
            break
    n_mov = int(moving.sum())
    d01 = np.sum((pos[g1] - pos[g0]) ** 2, axis=1)
    d02m = np.sum((pos[m2[moving]] - pos[m0[moving]]) ** 2, axis=1)
    evidence["report_triples_at_rest"], evidence["report_triples_moving"] = n_rest, n_mov
    counts = (
        f"of the linked reports' triples, {n_mov:,} of {n_lag:,} at lag {L} moving (ends "
        f"apart beyond the noise's {FOUND:.2%} ellipse, the fitted σ and q holding their "
        f"motion) and {n_rest:,} of {n_all:,} at lag 1 at rest (both links inside it over at "
        "least the median span)"
    )
    enough_moving = n_mov >= max(MIN_TRIPLES, REST_SHARE * n_lag)
    # max_speed: the moving targets' speeds (the trimmed core's are the moored ones')
    if "max_speed" in wanted:
        fitted.pop("max_speed", None)
        if not enough_moving:
            fallbacks["max_speed"] = (
                f"not fitted: {n_mov} of {n_lag} linked triples at lag {L} of reports of a "
                f"moving target (fewer than {MIN_TRIPLES} or {REST_SHARE:.0%}; the speeds of "
                "targets at rest are no speed scale)"
            )
        else:
            span = t[m2[moving]] - t[m0[moving]]
            v99 = float(np.quantile(np.sqrt(d02m) / span, 0.99))
            if v99 > MAX_SPEED_BOUND:
                fallbacks["max_speed"] = (
                    f"not fitted: the moving targets' speeds' 99 % point {v99:,.4g} m/s "
                    f"refused (above {MAX_SPEED_BOUND:,.0f} m/s: not a target's speed)"
                )
            else:
                fitted["max_speed"] = (
                    float(SPEED_MARGIN * v99),
                    f"fitted: {SPEED_MARGIN:g} × the 99 % point ({v99:.4g}) of the speeds "
                    f"|z2 − z0|/(t2 − t0) of the {n_mov:,} moving triples {counts}",
                )
    # JPDA/JIPDA only (PMB/PMBM take POISSON_FIT_KEYS); the user's motion or modes stand
    # (any other IMM key the user sets is kept beside the choice)
    user_motion = "motion" in table or "imm_modes" in table
    if kind in ("pmb", "pmbm") or user_motion or "process_noise" not in fitted:
        return
    both = n_rest >= max(MIN_TRIPLES, REST_SHARE * n_all) and enough_moving
    if not both:
        # the motion stays the default (cv); why, in the evidence
        evidence["report_motion"] = (
            f"cv: {counts} — the IMM with a stationary mode needs both at least "
            f"{REST_SHARE:.0%} (and {MIN_TRIPLES})"
        )
        return
    q_move = float(fitted["process_noise"][0])
    # the at-rest mode's random walk: E|z1 − z0|²/dim = 2σ² + q_s·(t1 − t0) over the at-rest
    # links (a moment estimate; a quantised position repeats exactly: q_s floored)
    gap = t[g1[rest]] - t[g0[rest]]
    excess = float(np.mean(d01[rest])) / dim - 2.0 * sigma2
    floor = 1e-3 * sigma2 / float(np.median(gap))
    q_rest = max(excess / float(np.mean(gap)), floor)
    share = (n_mov / n_lag) / (n_mov / n_lag + n_rest / n_all)
    stay = STAY_PER_SECOND
    text = f"{counts}; per-mode q: cv {q_move:.3g} m²/s³ (the moving targets'), "
    text += f"stationary {q_rest:.3g} m²/s (the at-rest links' spread beyond 2σ²"
    text += ", floored at 10⁻³σ²/gap)" if q_rest == floor else ")"
    for key, value in (
        ("motion", "imm"),
        ("imm_modes", ("cv", "stationary")),
        ("imm_process_noise", (float(q_move), float(q_rest))),
        ("imm_switching", ((stay, 1.0 - stay), (1.0 - stay, stay))),
        ("imm_switching_per", "second"),
        ("imm_initial", (share, 1.0 - share)),
    ):
        if key not in table:  # a key the user set is kept
            wanted.append(key)
            fitted[key] = (value, f"fitted: imm (CV + stationary): {text}")
    if "imm_switching" in fitted:
        fitted["imm_switching"] = (
            fitted["imm_switching"][0],
            f"stated: stay {stay} per second in continuous time (a target stops or gets "
            "under way about once in a quarter of an hour)",
        )
    if "imm_initial" in fitted:
        fitted["imm_initial"] = (
            (share, 1.0 - share),
            f"fitted: the shares of moving and at-rest triples ({n_mov:,} of {n_lag:,} : "
            f"{n_rest:,} of {n_all:,})",
        )


def _fit_pd_gate(
    fitted, fallbacks, pos, t, times, scans, dim, g0, g1, g2, lag, inl, sigma2, q, lam, dt, how
):
    """P_D from straight-on predictions of the inlier lag-1 triples; P_G from the
    detections after one miss against the tracker's own gate after a miss."""
    sizes = np.array([len(z) for z in scans])
    scan_of = np.repeat(np.arange(len(scans)), sizes)
    m1 = inl & (lag == 1)
    k2 = scan_of[g2[m1]]
    nxt_scan = k2 + 1
    ok = nxt_scan < len(scans)
    i0, i1, i2 = g0[m1][ok], g1[m1][ok], g2[m1][ok]
    ks = nxt_scan[ok]
    if i0.size < MIN_TRIPLES:
        fallbacks["p_d"] = f"not fitted: {i0.size} triples with a following scan"
        return
    bb = times[ks] - t[i2]
    aa = t[i2] - t[i1]
    pred = pos[i2] + (pos[i2] - pos[i1]) * (bb / aa)[:, None]
    _, _, n, p = _design(t[i1], t[i2], times[ks])
    var = bb**2 * (n * sigma2 + p * q)  # per axis, of z3 − prediction, by (1)
    gamma = stats.chi2.ppf(FOUND, dim)
    radius = np.sqrt(gamma * var)
    found = np.zeros(i0.size, bool)
    for k in np.unique(ks):
        m = ks == k
        z = np.asarray(scans[k], float).reshape(-1, dim)
        if not len(z):
            continue
        d, _ = cKDTree(z).query(pred[m])
        found[m] = d <= radius[m]
    f = float(found.mean())
    ball = math.pi ** (dim / 2) / math.gamma(dim / 2 + 1) * np.median(radius) ** dim
    lam_area = (lam or 0.0) * ball
    pd = (1.0 - (1.0 - f) * math.exp(lam_area)) / FOUND
    pd_c = float(min(max(pd, P_D_MIN), P_D_MAX))
    fitted["p_d"] = (
        pd_c,
        f"fitted: {found.sum():,} of {found.size:,} straight-on predictions from {how} had a "
        f"detection in their {FOUND:.2%} ellipse (clutter in it taken out)"
        + (f"; {pd:.3g} kept within [{P_D_MIN}, {P_D_MAX}]" if pd_c != pd else ""),
    )
    # gate with q: lag-1 link (k−1 → k) then lag-2 link (k → k+2): the return after a miss
    m1l = lag == 1
    m2l = lag == 2
    nxt2 = np.full(len(pos), -1, np.int64)
    nxt2[g0[m2l]] = g1[m2l]
    prev1 = g0[m1l & inl]
    mid = g1[m1l & inl]
    after = nxt2[mid]
    has = after >= 0
    prev1, mid, after = prev1[has], mid[has], after[has]
    if prev1.size < MIN_TRIPLES:
        fallbacks["p_g"] = f"not fitted: {prev1.size} linked returns after a one-scan gap"
        return
    gap = t[after] - t[mid]
    vel = (pos[mid] - pos[prev1]) / (t[mid] - t[prev1])[:, None]
    e = pos[after] - pos[mid] - vel * gap[:, None]
    # screen mis-links: beyond ~10 standard deviations of the triples' model
    _, _, n, p = _design(t[prev1], t[mid], t[after])
    e2 = np.sum(e**2, axis=1)
    real = e2 <= stats.chi2.ppf(1 - 1e-6, dim) * 2 * gap**2 * (n * sigma2 + p * q)
    if real.sum() < MIN_TRIPLES:
        fallbacks["p_g"] = f"not fitted: {int(real.sum())} plausible returns after a one-scan gap"
        return
    e2, gap, n, p = e2[real], gap[real], n[real], p[real]

    def s_after(qq: float) -> np.ndarray:
        """Per-axis variance of each return's residual after one miss, by (1)."""
        return gap**2 * (n * sigma2 + p * qq)

    def nis_at(qq: float, point: float) -> float:
        """The ``point`` quantile of the returns' NIS in the tracker's gate after one miss."""
        return float(np.quantile(e2 / s_after(qq), point))

    if not (q > 0 and math.isfinite(q)):
        fallbacks["p_g"] = f"not fitted: q = {q:.4g} leaves no gate to choose with it"
        return
    # the core: the NIS_POINT point consistent (the gate alone would have to exceed P_G_HOLD)
    q_core = _raise_q(q, lambda qq: nis_at(qq, NIS_POINT) > stats.chi2.ppf(NIS_POINT, dim))
    # the tail: the manoeuvring returns too, while the gate after a miss stays clear of clutter
    q_tail = _raise_q(q_core, lambda qq: nis_at(qq, NIS_TAIL) > stats.chi2.ppf(NIS_TAIL, dim))
    gamma_hold = stats.chi2.ppf(P_G_HOLD, dim)
    unit_ball = math.pi ** (dim / 2) / math.gamma(dim / 2 + 1)

    def gate_clutter(qq: float) -> float:
        """Expected false returns in the P_G_HOLD gate after one miss (median return)."""
        return (lam or 0.0) * unit_ball * (gamma_hold * float(np.median(s_after(qq)))) ** (dim / 2)

    q_clear = _raise_q(q_core, lambda qq: gate_clutter(qq) <= GATE_CLUTTER) if lam else q_core
    q_final = max(q_core, min(q_tail, q_clear))
    u = nis_at(q_final, NIS_POINT)
    # the gate: the χ² probability of the returns' 99 % point, at least P_G_HOLD
    nis99 = nis_at(q_final, 0.99)
    pg = max(float(stats.chi2.cdf(nis99, dim)), P_G_HOLD)
    pg_c = float(min(max(pg, P_G_MIN), P_G_MAX))
    text = (
        f"{int(real.sum()):,} linked returns after a one-scan gap: NIS {NIS_POINT:.0%} point "
        f"{u:.3g} of the model (χ² {stats.chi2.ppf(NIS_POINT, dim):.3g}), "
        f"{NIS_TAIL:.1%} point {nis_at(q_final, NIS_TAIL):.3g} "
        f"(χ² {stats.chi2.ppf(NIS_TAIL, dim):.3g}), {gate_clutter(q_final):.2g} false returns "
        "expected in the gate after a miss"
    )
    if q_final > q:
        why = (
            f"the {NIS_TAIL:.1%} point consistent too"
            if q_final == q_tail and q_tail > q_core
            else f"the {NIS_TAIL:.1%} point raise stopped at {GATE_CLUTTER:g} false returns "
            "expected in the gate after a miss"
            if q_final > q_core
            else f"the {NIS_TAIL:.1%} point not raised: the gate after a miss would hold "
            f"more than {GATE_CLUTTER:g} false returns"
            if q_tail > q_core
            else f"the {NIS_TAIL:.1%} point consistent already"
        )
        fitted["process_noise"] = (
            float(q_final),
            f"fitted with the gate: raised from the triples' q = {q:.3g} until {text}; {why} "
            "(NIS consistency; real motion has heavier tails than white acceleration)",
        )
    fitted["p_g"] = (
        pg_c,
        f"fitted with q: the χ² probability of the 99 % point of the NIS of {text}, at least "
        f"{P_G_HOLD}" + (f"; {pg:.6g} kept within [{P_G_MIN}, {P_G_MAX}]" if pg_c != pg else ""),
    )


def _choose_scan_models(
    fitted, wanted, table, evidence, kind, report_like, pos, t, g0, g1, g2, lag
):
    """Choose ``coalescence_avoidance`` and ``motion`` (with ``turn_rate_std``) of a scan
    file from its linked triples (module docstring, "Close pairs and turns"); each choice
    goes into ``fitted`` (its key into ``wanted``) with its evidence as the source.

    Only for JPDA/JIPDA (JPDA* is JPDA's; PMB/PMBM take :data:`POISSON_FIT_KEYS`) on
    scan files whose σ and q were fitted (the gate radius and the turn rates' noise are
    in their units), and never for a key ``table`` (the user's) sets.
    """
    if report_like or kind in ("pmb", "pmbm"):
        return
    if "measurement_noise" not in fitted or "process_noise" not in fitted:
        return
    from jointtrack.experiments.config import steady_state_covariance

    dim = pos.shape[1]
    sigma2 = float(fitted["measurement_noise"][0])
    q = float(fitted["process_noise"][0])
    p_g = float(fitted["p_g"][0]) if "p_g" in fitted else _defaults()["p_g"]

    def design(L):
        m = lag == L
        i0, i1, i2 = g0[m], g1[m], g2[m]
        a, b, n, p = _design(t[i0], t[i1], t[i2])
        v1 = (pos[i1] - pos[i0]) / a[:, None]
        v2 = (pos[i2] - pos[i1]) / b[:, None]
        return i1, a, b, n, p, v1, v2

    # mis-links: faster than the speed scale of the lag-1 triples the fitted model holds
    # (SPEED_MARGIN × their 99 % point; recomputed here, in the data's own units, since
    # a refused max_speed is no screen)
    _, a, b, n, p, v1, v2 = design(1)
    held = np.sum((v2 - v1) ** 2, axis=1) <= stats.chi2.ppf(FOUND, dim) * (n * sigma2 + p * q)
    if np.count_nonzero(held) < MIN_TRIPLES:
        return
    speed1 = 0.5 * np.linalg.norm(v1 + v2, axis=1)
    vmax = SPEED_MARGIN * float(np.quantile(speed1[held], 0.99))

    def choose(key, value, why):
        fitted[key] = (value, why)
        wanted.append(key)

    if "coalescence_avoidance" not in table:
        # the targets' returns: those of the lag-1 triples moving at a target's speed —
        # linked either way round (two targets closer than their scan-to-scan motion swap
        # their mutual nearest neighbours, which the fitted model does not hold)
        i1, a, b, n, p, v1, v2 = design(1)
        m = lag == 1
        real = (np.linalg.norm(v1, axis=1) <= vmax) & (np.linalg.norm(v2, axis=1) <= vmax)
        mids = np.unique(np.concatenate([g0[m][real], i1[real], g2[m][real]]))
        dt = float(np.median(a)) if a.size else 1.0
        # a steady track's gate radius: the NCV filter's innovation at σ², q, one scan
        # (where the Riccati solve fails — q and σ² at the float range's ends — the
        # straight-on prediction's residual from two returns, which bounds it above)
        # (solved in units of σ², where only q/σ² matters: steady_state_covariance floors q)
        try:
            with np.errstate(all="ignore"):
                P = steady_state_covariance(dt, q / sigma2, 1.0, 1)
                s_pos = sigma2 * (
                    P[0, 0] + 2 * dt * P[0, 1] + dt**2 * P[1, 1] + q / sigma2 * dt**3 / 3 + 1.0
                )
        except (np.linalg.LinAlgError, ValueError):
            s_pos = math.nan
        if not (math.isfinite(s_pos) and s_pos > 0):
            s_pos = 6.0 * sigma2 + 2.0 / 3.0 * q * dt**3
        radius = math.sqrt(stats.chi2.ppf(p_g, dim) * s_pos)
        near = np.full(mids.size, np.inf)
        tm = t[mids]
        order = np.argsort(tm, kind="stable")
        for grp in np.split(order, np.flatnonzero(np.diff(tm[order])) + 1):
            if grp.size > 1:
                dd, _ = cKDTree(pos[mids[grp]]).query(pos[mids[grp]], k=2)
                near[grp] = dd[:, 1]
        n_close = int(np.count_nonzero(near < PAIR_GATES * radius))
        share = n_close / max(mids.size, 1)
        on = mids.size >= MIN_TRIPLES and share >= PAIR_SHARE and n_close >= MIN_TRIPLES
        evidence["pair_returns"], evidence["pair_close"] = int(mids.size), n_close
        choose(
            "coalescence_avoidance",
            bool(on),
            f"fitted: {'on (JPDA*)' if on else 'off (plain JPDA)'}: {n_close:,} of {mids.size:,} "
            f"targets' returns ({share:.2%}; on at {PAIR_SHARE:.0%} and {MIN_TRIPLES}) had "
            f"another target's return within {PAIR_GATES:g} gate radii ({PAIR_GATES * radius:.4g}) "
            "in their scan — "
            + (
                "close pairs, whose tracks plain JPDA pulls together"
                if on
                else "too few close pairs for JPDA* to change a cluster"
            ),
        )
    if "motion" not in table:
        # the shortest lag whose chords resolve a TURN_RATE turn at TURN_Z (median triple)
        for L in sorted({int(x) for x in np.unique(lag)}):
            i1, a, b, n, p, v1, v2 = design(L)
            half = 0.5 * (a + b)
            speed = 0.5 * np.linalg.norm(v1 + v2, axis=1)
            with np.errstate(divide="ignore", invalid="ignore"):
                omega_sd = np.sqrt(n * sigma2) / speed / half
            if a.size and np.median(omega_sd) * TURN_Z < TURN_RATE:
                break
        # moving: a heading defined (its noise below 1/TURN_Z rad), speeds a target's
        moving = (
            (omega_sd * half * TURN_Z < 1.0)
            & (np.linalg.norm(v1, axis=1) <= vmax)
            & (np.linalg.norm(v2, axis=1) <= vmax)
        )
        cross = v1[:, 0] * v2[:, 1] - v1[:, 1] * v2[:, 0] if dim == 2 else np.zeros(a.size)
        omega = np.arctan2(cross, np.sum(v1 * v2, axis=1)) / half
        turning = moving & (np.abs(omega) > TURN_RATE) & (np.abs(omega) > TURN_Z * omega_sd)
        # sustained: the triple one link on (starting at this one's middle) turns the same
        # way — a turn, where noise and position jitter reverse from chord to chord
        start = np.full(len(pos), -1, np.int64)
        start[g0[lag == L]] = np.arange(a.size)
        on = start[i1]
        has = on >= 0
        sustained = np.zeros(a.size, bool)
        sustained[has] = (
            turning[has] & turning[on[has]] & (np.sign(omega[has]) == np.sign(omega[on[has]]))
        )
        n_mov = int(np.count_nonzero(moving & has))
        n_turn = int(sustained.sum())
        share = n_turn / max(n_mov, 1)
        imm = dim == 2 and n_turn >= MIN_TRIPLES and share >= TURN_SHARE
        evidence["turn_moving"], evidence["turn_turning"] = n_mov, n_turn
        text = (
            f"{n_turn:,} of {n_mov:,} moving targets' lag-{L} triples ({share:.2%}; imm at "
            f"{TURN_SHARE:.0%} and {MIN_TRIPLES}) changed heading faster than "
            f"{math.degrees(TURN_RATE):g}°/s and {TURN_Z:g}σ of their noise, the same way as "
            "the next triple along"
        )
        if imm:
            rate = float(np.median(np.abs(omega[sustained])))
            scan = float(np.median(a)) / L
            choose(
                "motion",
                "imm",
                f"fitted: imm (CV + coordinated turn, turn rate estimated): {text} — turns "
                "a CV track loses its target in",
            )
            if "turn_rate_std" in table:
                return
            # the CT mode's turn-rate walk (variance turn_rate_std²·Δt) reaches a typical
            # turn's rate in one scan: a track picks up the turn at the scan it starts
            choose(
                "turn_rate_std",
                rate / math.sqrt(scan),
                f"fitted: the turning triples' median turn rate ({math.degrees(rate):.3g}°/s) "
                f"reached in one scan ({scan:.4g} s): rate/√Δt",
            )
        else:
            why = (
                "not 2-D (the coordinated-turn mode is)"
                if dim != 2
                else "turns too rare for the IMM's cost"
            )
            choose("motion", "cv", f"fitted: cv: {text} — {why}")


def _finish(out, sources, fitted, fallbacks, defaults, wanted, evidence) -> ModelFit:
    from jointtrack.trackers.config import check_field

    for key, (value, _) in list(fitted.items()):
        # a fitted value the tracker cannot take (e.g. a variance above 1e300 from data
        # near the coordinate limit) is refused, naming it, never passed on
        try:
            finite = (
                isinstance(value, str | tuple)  # a chosen model's name, modes, matrix
                or math.isfinite(value)
            )
            ok = finite and check_field(key, value) is not None
        except ValueError as exc:
            ok, why = False, str(exc)
        else:
            why = "not finite"
        if not ok:
            del fitted[key]
            fallbacks[key] = f"not fitted: the fitted {key} = {_value_text(value)} refused ({why})"
    table = dict(out)
    srcs = dict(sources)
    fb = {}
    for k in wanted:
        if k in fitted:
            table[k], srcs[k] = fitted[k]
        else:
            why = fallbacks.get(k, "not fitted")
            default = table.get(k, defaults.get(k))
            if default is None:
                continue
            table[k] = default
            fb[k] = why
            srcs[k] = f"default ({_value_text(default)}): {why}"
    return ModelFit(table=table, sources=srcs, fallbacks=fb, evidence=evidence)
