"""jointtrack: exact, fast and honest multi-target association.

Quick start::

    from jointtrack import JPDATracker, TrackerConfig
    trk = JPDATracker(TrackerConfig(clutter_density=1e-4))
    result = trk.step(0.0, [[10.0, 0.0], [50.0, 3.0]])  # then step every scan

Map of the package:

* :mod:`jointtrack.assignment` — the one assignment-sum core (validation,
  scaling, folding, the DP, marginals) every other part is a face on;
* :mod:`jointtrack.permanent` — permanents and identity marginals on the core;
* :mod:`jointtrack.association` — JPDA association (exact, budgeted, LBP, k-best);
* :mod:`jointtrack.trackers` — JPDA/JIPDA, PMB/PMBM and particle trackers;
* :mod:`jointtrack.identity` — which known identity is on which track (Schaub);
* :mod:`jointtrack.saddle` — particle JPDA weights by the saddle point (Streit);
* :mod:`jointtrack.superpositional` — superpositional sensors (Nannuru & Coates);
* :mod:`jointtrack.filters`, :mod:`jointtrack.models` — Kalman filters, motion
  and measurement models;
* :mod:`jointtrack.io` — detections, reports (AIS, ADS-B), tracks, geodetic frames;
* :mod:`jointtrack.metrics` — GOSPA/OSPA, track statistics, self-report scores;
* :mod:`jointtrack.scenarios`, :mod:`jointtrack.experiments`, :mod:`jointtrack.sweep`,
  :mod:`jointtrack.bench` — scenes, the papers' reproductions, sweeps, benchmarks;
* :mod:`jointtrack.interop` — drop-in associators for Stone Soup;
* :mod:`jointtrack.errors` — the shared exceptions: ``InfeasibleAssignmentError``
  (no assignment has positive weight, e.g. a P_D = 1 track that gates nothing),
  ``ExactLimitError`` (an exact solve would exceed ``max_bits``/``max_memory``;
  the tracker falls back to its approximation) and ``CoincidentReturnsWarning``.
  Bad arguments raise ``ValueError``/``TypeError`` naming the argument.

Command line: ``jointtrack run`` (detections in, tracks out), ``jointtrack
reproduce``, ``jointtrack sweep``, ``jointtrack bench``; each has ``--help``.
"""

from importlib.metadata import PackageNotFoundError, version

from jointtrack.errors import InfeasibleAssignmentError

try:
    __version__ = version("jointtrack")
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0.0.0+unknown"

__all__ = ["InfeasibleAssignmentError", "JPDATracker", "TrackerConfig", "__version__"]


#: names imported on first use (``__getattr__``), listed by ``dir(jointtrack)``
_LAZY = ("JPDATracker", "TrackerConfig")


def __dir__():
    return sorted({*globals(), *_LAZY})


def __getattr__(name):
    # The tracker pulls in the filters and the association engine; import on use.
    if name in _LAZY:
        from jointtrack import trackers

        return getattr(trackers, name)
    raise AttributeError(f"module 'jointtrack' has no attribute {name!r}")
