"""numba's on-disk cache must not segfault on a later run (issue 22, item 1).

A ``parallel=True`` kernel needs numba's threading layer started before its code
runs. A function loaded from the cache starts it only if it was compiled in a
process that compiled the parallel code itself: numba does not carry that
"start the threads" note over from a callee that was *loaded* from the cache into
a caller compiled on top of it (numba issues #8578, #4807). So a cached caller
compiled on a cached callee that holds parallel code is cached without the note
and dies with SIGSEGV when it is next loaded — here ``jointtrack run`` cached
the frontier kernels and then the README's saddle example compiled
``frontier_value`` on them and crashed on every later run.

The rule that rules this out: a cached function that holds parallel code (its
own, or through its callees) is only ever called from Python, and everything
between it and the ``parallel=True`` kernels is uncached, so it is always compiled
in one piece with the parallel code. :func:`test_cached_parallel_code_is_only_called_from_python`
checks that rule on every jitted function of the package (every ``cache=True``
uses); :func:`test_cached_frontier_kernels_survive_reload` runs the failing
sequence in fresh processes on a fresh cache.
"""

from __future__ import annotations

import importlib
import itertools
import math
import os
import pkgutil
import subprocess
import sys
import types
from pathlib import Path

import numpy as np
import pytest
from numba.core.registry import CPUDispatcher

import jointtrack
from jointtrack.assignment._plan import frontier_plan

# --------------------------------------------------------------------------- static rule


def _all_dispatchers():
    """Every jitted function defined in the package: {qualified name: dispatcher}."""
    found = {}
    for info in pkgutil.walk_packages(jointtrack.__path__, "jointtrack."):
        module = importlib.import_module(info.name)
        for name, obj in vars(module).items():
            if isinstance(obj, CPUDispatcher) and obj.py_func.__module__ == info.name:
                found[f"{info.name}.{name}"] = obj
    return found


def _code_names(code):
    names = set(code.co_names)
    for const in code.co_consts:
        if isinstance(const, types.CodeType):
            names |= _code_names(const)
    return names


def _callees(dispatcher, by_id):
    """Jitted functions a jitted function names: globals and attributes of imported modules."""
    glob = dispatcher.py_func.__globals__
    names = _code_names(dispatcher.py_func.__code__)
    out = set()
    for name in names:
        obj = glob.get(name)
        if isinstance(obj, CPUDispatcher) and id(obj) in by_id:
            out.add(by_id[id(obj)])
        elif isinstance(obj, types.ModuleType):
            for attr in names:
                sub = getattr(obj, attr, None)
                if isinstance(sub, CPUDispatcher) and id(sub) in by_id:
                    out.add(by_id[id(sub)])
    return out


def _is_cached(dispatcher):
    return bool(dispatcher.targetoptions.get("cache", False)) or (
        type(dispatcher._cache).__name__ != "NullCache"
    )


def test_cached_parallel_code_is_only_called_from_python():
    disp = _all_dispatchers()
    by_id = {id(d): name for name, d in disp.items()}
    calls = {name: _callees(d, by_id) for name, d in disp.items()}
    callers = {name: set() for name in disp}
    for name, out in calls.items():
        for callee in out:
            callers[callee].add(name)
    parallel = {name for name, d in disp.items() if d.targetoptions.get("parallel")}

    # functions that hold parallel code: the parallel kernels and their transitive callers
    holds = set(parallel)
    changed = True
    while changed:
        changed = False
        for name, out in calls.items():
            if name not in holds and out & holds:
                holds.add(name)
                changed = True

    # the analysis sees what it must (else the rule below would pass vacuously)
    fr = "jointtrack.assignment._frontier."
    ie = "jointtrack.assignment._inclusion_exclusion."
    assert sum(_is_cached(d) for d in disp.values()) >= 60
    assert {fr + "_fwd_par", fr + "_bwd_par", ie + "glynn_kernel", ie + "ryser_kernel"} <= parallel
    assert fr + "_op_fwd" in calls[fr + "frontier_value"]
    assert fr + "_layer_fwd" in calls[fr + "_op_fwd"]
    assert fr + "_fwd_par" in calls[fr + "_layer_fwd"]
    assert {fr + "frontier_dp", fr + "frontier_value"} <= holds

    bad = sorted(
        f"{name} (cached, holds parallel code) is called from jitted {sorted(callers[name])}"
        for name in holds
        if _is_cached(disp[name]) and callers[name]
    )
    assert not bad, "\n".join(bad)


# --------------------------------------------------------------------------- the sequence

# The plan (frontier_plan, not part of the sequence) comes from the test's process in a
# file: compiled once in the suite's cache instead of once more in each fresh one.
_SCRIPT = r"""
import sys
import numpy as np
from jointtrack.assignment._frontier import frontier_dp, frontier_value
from jointtrack.assignment._inclusion_exclusion import glynn_kernel, ryser_kernel

plan = np.load(sys.argv[1])
W = plan["W"]
R, C = W.shape
u = np.ones(R)
v = np.ones(C)
K = int(plan["K"])
op_kind, op_arg, slot_of, lay_slot, term = (
    plan[k] for k in ("op_kind", "op_arg", "slot_of", "lay_slot", "term")
)
for entry in sys.argv[2:]:
    name, nchunk = entry.split(":")
    nchunk = int(nchunk)
    if name == "frontier_value":
        out = frontier_value(W, u, v, K, op_kind, op_arg, slot_of, lay_slot, term, nchunk)
    elif name == "frontier_dp":
        out = frontier_dp(W, u, v, K, op_kind, op_arg, slot_of, lay_slot, term, 1, nchunk)[3]
    elif name == "glynn_kernel":
        out = np.log(glynn_kernel(W, 2)[0])
    else:
        out = np.log(ryser_kernel(W, 2)[0])
    print(entry, float(out).hex())
"""


def _matching_sum(W):
    """Σ over partial matchings of Π W (null and unused weights 1), in exact-ish fsum."""
    R, C = W.shape
    terms = []
    for k in range(min(R, C) + 1):
        for rows in itertools.combinations(range(R), k):
            for cols in itertools.permutations(range(C), k):
                terms.append(math.prod(W[r, c] for r, c in zip(rows, cols, strict=True)))
    return math.fsum(terms)


def _permanent(W):
    n = W.shape[0]
    return math.fsum(
        math.prod(W[i, p[i]] for i in range(n)) for p in itertools.permutations(range(n))
    )


def _write_plan(path, W):
    """``W`` and its frontier plan, as the script reads them."""
    _, K, op_kind, op_arg, slot_of, lay_slot, term = frontier_plan(W > 0.0)
    np.savez(
        path,
        W=W,
        K=K,
        op_kind=op_kind,
        op_arg=op_arg,
        slot_of=slot_of,
        lay_slot=lay_slot,
        term=term,
    )
    return path


def _run(cache_dir, plan, entries):
    env = dict(os.environ)
    env["NUMBA_CACHE_DIR"] = str(cache_dir)
    env["PYTHONPATH"] = os.pathsep.join(
        [str(Path(jointtrack.__file__).parents[1]), env.get("PYTHONPATH", "")]
    )
    proc = subprocess.run(
        [sys.executable, "-c", _SCRIPT, str(plan), *entries],
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 0, (
        f"{entries} exited with {proc.returncode} (-11 = SIGSEGV)\n{proc.stderr[-2000:]}"
    )
    return dict(line.split() for line in proc.stdout.splitlines())


def test_cached_frontier_kernels_survive_reload(tmp_path):
    """The issue's sequence: cache one caller, compile another on it, load that one."""
    W = np.array([[0.5, 2.0, 0.0], [1.5, 0.25, 3.0], [0.0, 1.0, 0.75]])
    # 64 chunks: the parallel branch, as the core runs K ≥ 16 states
    dp, value, glynn, ryser = (
        "frontier_dp:64",
        "frontier_value:64",
        "glynn_kernel:0",
        "ryser_kernel:0",
    )
    plan = _write_plan(tmp_path / "plan.npz", W)
    # 1. like `jointtrack run`: frontier_dp (and its callees) compiled and cached
    first = _run(tmp_path, plan, [dp, glynn])
    # 2. like the saddle example: frontier_value compiled on top of that cache
    second = _run(tmp_path, plan, [value, ryser, "frontier_value:1"])
    # 3. everything loaded from the cache: this run segfaulted
    third = _run(tmp_path, plan, [value, dp, glynn, ryser, "frontier_value:1", "frontier_dp:1"])
    # the runs above did go through the on-disk cache
    assert list(tmp_path.glob("**/_frontier.frontier_value-*.nbi"))
    assert list(tmp_path.glob("**/_frontier.frontier_dp-*.nbi"))

    log_z = math.log(_matching_sum(W))
    log_per = math.log(_permanent(W))
    for run in (first, second, third):
        for entry, out in run.items():
            want = log_per if entry.startswith(("glynn", "ryser")) else log_z
            assert float.fromhex(out) == pytest.approx(want, rel=1e-13, abs=1e-13), entry
    # the same bits whichever process compiled it and whatever the chunking
    for entry in (value, dp):
        assert third[entry] == (first | second)[entry]
    assert third["frontier_value:1"] == third[value] == third[dp] == third["frontier_dp:1"]
