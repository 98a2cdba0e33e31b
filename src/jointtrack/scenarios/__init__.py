"""Seeded simulated scenarios (truth, detections, clutter) for trackers and metrics.

* :func:`bojilov` — Bojilov et al.'s five targets on parallel, closely spaced
  trajectories drifting into 4–5-target clusters, Poisson clutter β per gate.
* :func:`abreast` — targets abreast on parallel lanes at one speed (issue 11).
* :func:`crossing` — two targets crossing in an X.
* :func:`many_targets` — ≥ 100 NCV targets with births and deaths in clutter.
* :func:`close_pairs` — aircraft pairs 0.1–2 km apart that fly straight and orbit
  together at 3–5 °/s, 10 s scanning sensor (issue 32; not a run/sweep name).
* :func:`coalescence` — Williams' four targets that meet mid-run, one dying
  there (the PMBM papers' scenario, with their filter model in ``info``).
* :func:`acoustic` — 3–5 targets read by a 5 × 5 grid of superpositional
  amplitude sensors (no detections; :class:`AcousticScenario`).
* :class:`Scenario` — the result (:meth:`Scenario.tracker_config`: the matched
  ``TrackerConfig``); :func:`simulate_scenario` builds one from
  any truth; :func:`nominal_gate` the steady-state NCV gate used as Bojilov's
  clutter unit.
"""

from jointtrack.scenarios.acoustic import AcousticScenario, acoustic
from jointtrack.scenarios.close_pairs import close_pairs
from jointtrack.scenarios.coalescence import coalescence
from jointtrack.scenarios.generators import abreast, bojilov, crossing, many_targets, nominal_gate
from jointtrack.scenarios.simulate import (
    Scenario,
    ncv_matrices,
    propagate_ncv,
    simulate_scenario,
)

#: Detection scenarios by their run/sweep name (``[scenario] name``) → generator.
GENERATORS = {
    "bojilov": bojilov,
    "crossing": crossing,
    "many": many_targets,
    "abreast": abreast,
    "coalescence": coalescence,
}


def run_name(name: str) -> str:
    """The run/sweep name (a key of :data:`GENERATORS`) of a detection scenario.

    ``name``: a run name, or the :attr:`Scenario.name` its generator gives
    (``"many_targets"`` → ``"many"``); any other name is returned unchanged.
    A run records this name, so that ``--resume`` can rebuild the scenario.
    """
    for key, fn in GENERATORS.items():
        if name in (key, fn.__name__):
            return key
    return name


__all__ = [
    "GENERATORS",
    "AcousticScenario",
    "Scenario",
    "abreast",
    "acoustic",
    "bojilov",
    "close_pairs",
    "coalescence",
    "crossing",
    "many_targets",
    "ncv_matrices",
    "nominal_gate",
    "propagate_ncv",
    "run_name",
    "simulate_scenario",
]
