"""jointtrack: exact, fast and honest multi-target association.

The core is one assignment-sum engine (:mod:`jointtrack.permanent`) on which the
JPDA association, identity management and superpositional-sensor filters are
built.
"""

from importlib.metadata import PackageNotFoundError, version

from jointtrack.errors import InfeasibleAssignmentError

try:
    __version__ = version("jointtrack")
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0.0.0+unknown"

__all__ = ["InfeasibleAssignmentError", "JPDATracker", "TrackerConfig", "__version__"]


def __getattr__(name):
    # The tracker pulls in the filters and the association engine; import on use.
    if name in ("JPDATracker", "TrackerConfig"):
        from jointtrack import trackers

        return getattr(trackers, name)
    raise AttributeError(f"module 'jointtrack' has no attribute {name!r}")
