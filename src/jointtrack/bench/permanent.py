"""Permanent engine vs thewalrus on the canonical workloads of DESIGN.md.

Run as ``jointtrack bench permanent [--quick] [--out FILE]`` or
``python benchmarks/permanent.py``. Everything is measured in one run: peers are
timed interleaved with ours (ours, peer, ours, peer, …) after one untimed
warm-up call each, and the median of the repeats is reported.

Workloads (seeded ``numpy.random.default_rng``)
-----------------------------------------------
* **uniform** ``rng.random((n, n))``, n = 16…26 (quick: 16, 18, 20): our
  :func:`~jointtrack.permanent.permanent` (``method="auto"``) against
  ``thewalrus.perm`` (its default, ``"bbfg"``), both timed on one core
  (``numba.set_num_threads(1)``: both Glynn kernels are numba-parallel).
  Relative errors are against the exact rational
  :func:`~jointtrack.permanent.reference.reference_permanent`
  for n ≤ 20; for n ≥ 22 that is too slow and the reference is the frontier DP
  (``assignment_sum(A, marginals=False, method="frontier", parallel=True)``;
  ``"auto"`` runs Glynn there, so this is an independent method), which only
  adds and multiplies non-negative numbers, so its relative error is rigorously
  ≤ 2n·2⁻⁵³ ≈ 6e-15. (``permanent(A, method="dp")`` is that same DP, ~n²·2^(n−1)
  on dense input.)
* **banded** n = 24, 40, 100: tridiagonal and 5-banded (|i − j| ≤ 1, 2) with
  all-ones or ``rng.random`` entries, our ``permanent`` (auto: the frontier DP
  with a 3- or 5-bit state) against the exact rational band DP
  :func:`banded_exact`; tridiagonal all-ones must equal the Fibonacci number
  F(n+1). thewalrus has no sparse method: it is timed at n = 24 and its time at
  n = 40, 100 is extrapolated (2^(n−1)·n), not run.
* **dense n = 28** (full run only): ``permanent(A)`` with "auto", which reaches
  Glynn's formula; its own rounding-error estimate
  (``assignment_sum(A, marginals=False).info["error_estimate"]``) is reported
  and thewalrus is timed once on the same matrix.
* **badly scaled** n = 20 (quick: 14): the uniform matrix with rows and columns
  multiplied by ``10**rng.uniform(-k, 0)``, k ∈ {2, 5, 20, 300}, and elementwise
  by ``10**rng.uniform(-30, 0)``. Our error is that of
  :func:`~jointtrack.permanent.log_permanent`, expm1(ours − ref) with the exact
  :func:`~jointtrack.permanent.reference.reference_log_permanent`; thewalrus'
  value is compared in log space when it is positive and reported as
  ``negative``/``zero``/``nan`` otherwise.
* **Schaub identity** 100×100: three column classes 60/30/10 with 100 distinct
  positive rows (compressed 100×3), and 6 observed rows + 94 identical hidden
  rows with 100 distinct columns (compressed 7×100). Full
  :func:`~jointtrack.permanent.assignment_marginals` against the exact
  :func:`~jointtrack.permanent.reference.reference_marginals`. thewalrus has no
  repeated-row/column form and its expanded 100×100 permanent is 2¹⁰⁰ terms.
* **second-process start-up**: a fresh interpreter importing jointtrack and
  computing one 20×20 permanent, twice (the first may fill numba's cache).

Targets (printed as PASS/FAIL): n = 24 and 26 at least 1.5× faster than
thewalrus with relative error ≤ 1e-12; banded n = 40, 100 each ≤ 10 ms with
relative error ≤ 1e-12 (tridiagonal all-ones = F(n+1)); dense n = 28 reaches
Glynn; badly scaled relative error ≤ 1e-11; Schaub cases ≤ 10 ms and max abs
error ≤ 1e-11; second process < 1 s.
"""

from __future__ import annotations

import json
import math
import os
import platform
import statistics
import subprocess
import sys
import time
from collections.abc import Callable

import numpy as np

from jointtrack.io import to_jsonable

TARGET_SPEEDUP = 1.5
TARGET_UNIFORM_ERR = 1e-12
TARGET_SCALED_ERR = 1e-11
TARGET_SCHAUB_TIME = 10e-3
TARGET_SCHAUB_ERR = 1e-11
TARGET_STARTUP = 1.0

STARTUP_CODE = (
    "import numpy as np; from jointtrack.permanent import permanent; "
    "permanent(np.random.default_rng(0).random((20,20)))"
)


# --------------------------------------------------------------------------- helpers


def _load_thewalrus():
    try:
        import thewalrus
        from thewalrus import perm
    except ImportError:
        return None, None
    return perm, getattr(thewalrus, "__version__", "?")


def _timed(fn: Callable[[], object]) -> tuple[float, object]:
    t0 = time.perf_counter()
    value = fn()
    return time.perf_counter() - t0, value


def _interleaved(fns: dict[str, Callable[[], object]], budget: float, max_reps: int = 25):
    """Median wall time of each function, timed alternately after warm-up.

    Each function is called once untimed (JIT compilation, caches) and once more
    to size the number of repeats so that one round costs about ``budget``.
    Returns ({name: median seconds}, {name: last value}, repeats). An exception
    in a function is recorded as its value and it is not timed again.
    """
    values: dict[str, object] = {}
    warm: dict[str, float] = {}
    for name, fn in fns.items():
        try:
            fn()
            warm[name], values[name] = _timed(fn)
        except Exception as exc:  # a peer failing is a result, not a crash
            values[name] = exc
    live = [name for name in fns if not isinstance(values[name], Exception)]
    per_round = sum(warm[name] for name in live) or 1e-9
    reps = int(min(max_reps, max(3, budget / per_round)))
    times: dict[str, list[float]] = {name: [] for name in live}
    for _ in range(reps):
        for name in live:
            dt, values[name] = _timed(fns[name])
            times[name].append(dt)
    med = {name: statistics.median(times[name]) for name in live}
    return med, values, reps


def _fmt_time(t: float | None) -> str:
    if t is None:
        return "—"
    if t >= 1.0:
        return f"{t:.2f} s"
    if t >= 1e-3:
        return f"{t * 1e3:.2f} ms"
    return f"{t * 1e6:.0f} µs"


def _fmt_err(e) -> str:
    if e is None:
        return "—"
    if isinstance(e, str):
        return e
    return f"{e:.1e}"


def _mark(ok: bool | None) -> str:
    if ok is None:
        return "[yellow]not run[/]"
    return "[green]PASS[/]" if ok else "[red]FAIL[/]"


def _rel_err(value: float, ref: float) -> float | str:
    if not math.isfinite(value):
        return "nan" if math.isnan(value) else "inf"
    if ref == 0.0:
        return 0.0 if value == 0.0 else "nonzero for Per = 0"
    return abs(value - ref) / ref


def _peer_log_err(value, ref_log: float) -> float | str:
    """Relative error of a peer's permanent, compared in log space when meaningful."""
    if isinstance(value, Exception):
        return f"error: {type(value).__name__}"
    v = complex(value)
    if v.imag != 0.0:
        return "complex"
    x = v.real
    if math.isnan(x):
        return "nan"
    if ref_log == -math.inf:
        return 0.0 if x == 0.0 else f"{x:.2g} for Per = 0"
    if x < 0.0:
        return f"negative ({x:.2g})"
    if x == 0.0:
        return "zero" + (" (Per underflows)" if ref_log < -708.4 else "")
    if math.isinf(x):
        return "inf"
    return abs(math.expm1(math.log(x) - ref_log))


def _dp_reference(A) -> float:
    """Cancellation-free reference value for n ≥ 22: the frontier DP (not Glynn).

    ``permanent(A, method="dp")`` is the frontier DP of :mod:`jointtrack.assignment`,
    ~n²·2^(n−1) on dense input; it is called through the core with both cores.
    """
    from jointtrack.assignment import assignment_sum

    res = assignment_sum(A, marginals=False, method="frontier", parallel=True)
    return math.exp(res.log_normalizer)


def banded(n: int, half_width: int, rng=None) -> np.ndarray:
    """All-ones (or ``rng.random`` valued) band matrix: A[i, j] ≠ 0 iff |i − j| ≤ half_width."""
    i, j = np.indices((n, n))
    A = (np.abs(i - j) <= half_width).astype(float)
    if rng is not None:
        A *= rng.random((n, n))
    return A


def banded_exact(A: np.ndarray, half_width: int):
    """Exact permanent of a band matrix as a Fraction (row-by-row DP over the window).

    State: which of the columns i−k … i+k are used after rows 0 … i−1 (a bitmask
    relative to i−k); every float entry is converted exactly, so the result is
    the exact permanent of the float64 matrix.
    """
    from fractions import Fraction

    n = A.shape[0]
    k = half_width
    states = {0: Fraction(1)}
    for i in range(n):
        nxt: dict[int, Fraction] = {}
        for mask, val in states.items():
            for d in range(2 * k + 1):
                j = i - k + d
                if j < 0 or j >= n or mask >> d & 1 or A[i, j] == 0.0:
                    continue
                m2 = mask | (1 << d)
                if m2 & 1 == 0 and i - k >= 0:
                    continue  # column i−k leaves the window unused: no permutation
                m2 >>= 1
                nxt[m2] = nxt.get(m2, Fraction(0)) + val * Fraction(float(A[i, j]))
        states = nxt
    return sum(states.values(), Fraction(0))


def _fibonacci(m: int) -> int:
    a, b = 0, 1
    for _ in range(m):
        a, b = b, a + b
    return a


# --------------------------------------------------------------------------- sections


def _uniform(console, quick: bool, tw_perm) -> list[dict]:
    import numba
    from rich.table import Table

    from jointtrack.permanent import permanent
    from jointtrack.permanent.reference import reference_permanent

    sizes = [16, 18, 20] if quick else [16, 18, 20, 22, 24, 26]
    rows = []
    for n in sizes:
        A = np.random.default_rng(n).random((n, n))
        fns = {"ours": lambda A=A: permanent(A)}
        if tw_perm is not None:
            fns["thewalrus"] = lambda A=A: tw_perm(A)
        # one core each: both Glynn kernels (ours, thewalrus') are numba-parallel, and
        # on a shared 2-core machine a static split over threads waits for the slowest
        threads = numba.get_num_threads()
        numba.set_num_threads(1)
        try:
            med, vals, reps = _interleaved(fns, budget=1.0 if quick else 4.0)
        finally:
            numba.set_num_threads(threads)
        if n <= 20:
            ref, ref_kind = reference_permanent(A), "exact rational"
        else:
            ref, ref_kind = _dp_reference(A), "frontier DP (≤ 2n·2⁻⁵³)"
        ours = vals["ours"]
        row = {
            "n": n,
            "reference": ref_kind,
            "repeats": reps,
            "ours_s": med.get("ours"),
            "ours_rel_err": _rel_err(float(ours), ref)
            if not isinstance(ours, Exception)
            else repr(ours),
            "thewalrus_s": med.get("thewalrus"),
            "thewalrus_rel_err": None,
            "speedup": None,
        }
        if tw_perm is not None:
            tw = vals["thewalrus"]
            row["thewalrus_rel_err"] = _peer_log_err(tw, math.log(ref) if ref > 0 else -math.inf)
            if row["thewalrus_s"] and row["ours_s"]:
                row["speedup"] = row["thewalrus_s"] / row["ours_s"]
        rows.append(row)

    table = Table(
        title="Uniform rng.random((n, n)): permanent, median wall time, one core "
        "(numba.set_num_threads(1) for both)",
        caption="reference: exact rational arithmetic for n ≤ 20; for n ≥ 22 the frontier "
        "DP's value (assignment_sum(A, marginals=False, method='frontier', parallel=True); "
        "'auto' picks Glynn there, so the DP is an independent method) — all terms "
        "non-negative, rel. err ≤ 2n·2⁻⁵³ ≈ 6e-15 rigorously",
    )
    for col in ("n", "ours (auto)", "thewalrus", "thewalrus/ours", "rel err ours"):
        table.add_column(col, justify="right")
    for col in ("rel err thewalrus", "reference", "reps"):
        table.add_column(col, justify="right")
    for r in rows:
        table.add_row(
            str(r["n"]),
            _fmt_time(r["ours_s"]),
            _fmt_time(r["thewalrus_s"]) if tw_perm else "not installed",
            f"{r['speedup']:.2f}×" if r["speedup"] else "—",
            _fmt_err(r["ours_rel_err"]),
            _fmt_err(r["thewalrus_rel_err"]),
            r["reference"],
            str(r["repeats"]),
        )
    console.print(table)
    return rows


BANDED_SIZES = (24, 40, 100)  # n = 24: thewalrus timed too (2^23 Gray-code steps)
TW_BANDED_MAX = 24  # thewalrus has no sparse method: its cost is 2^(n-1)·n at any band
TARGET_BANDED_TIME = 10e-3
TARGET_BANDED_ERR = 1e-12


def _banded(console, quick: bool, tw_perm) -> list[dict]:
    from rich.table import Table

    from jointtrack.assignment import assignment_sum
    from jointtrack.permanent import permanent

    rows = []
    tw_time_24: float | None = None
    for n in BANDED_SIZES:
        for k, label in ((1, "tridiagonal"), (2, "5-banded")):
            for valued in (False, True):
                A = banded(n, k, np.random.default_rng(1000 + n + k) if valued else None)
                fns = {"ours": lambda A=A: permanent(A)}
                if tw_perm is not None and n <= TW_BANDED_MAX:
                    fns["thewalrus"] = lambda A=A: tw_perm(A)
                med, vals, reps = _interleaved(fns, budget=0.3 if quick else 1.0, max_reps=50)
                exact = banded_exact(A, k)
                ref = float(exact)
                ours = vals["ours"]
                info = assignment_sum(A, marginals=False).info
                row = {
                    "n": n,
                    "band": label,
                    "values": "rng.random" if valued else "all ones",
                    "ours_s": med.get("ours"),
                    "value": float(ours) if not isinstance(ours, Exception) else repr(ours),
                    "ours_rel_err": _rel_err(float(ours), ref)
                    if not isinstance(ours, Exception)
                    else repr(ours),
                    "max_frontier": info.get("max_frontier"),
                    "fibonacci_ok": None,
                    "thewalrus_s": med.get("thewalrus"),
                    "thewalrus_rel_err": None,
                    "speedup": None,
                    "thewalrus_estimate_s": None,
                    "repeats": reps,
                }
                if k == 1 and not valued:
                    row["fibonacci_ok"] = exact == _fibonacci(n + 1)
                if "thewalrus" in vals:
                    row["thewalrus_rel_err"] = _peer_log_err(vals["thewalrus"], math.log(ref))
                    if row["thewalrus_s"] and row["ours_s"]:
                        row["speedup"] = row["thewalrus_s"] / row["ours_s"]
                        tw_time_24 = max(tw_time_24 or 0.0, row["thewalrus_s"])
                elif tw_perm is not None and tw_time_24:
                    # its Gray-code loop is 2^(n−1) steps of O(n) whatever the sparsity
                    row["thewalrus_estimate_s"] = tw_time_24 * 2.0 ** (n - 24) * n / 24
                rows.append(row)

    table = Table(
        title="Banded permanents: A(i, j) ≠ 0 iff |i − j| ≤ k, median wall time",
        caption="reference: exact rational row-by-row band DP (Fraction); tridiagonal all-ones "
        "must equal the Fibonacci number F(n+1). thewalrus has no sparse method (2^(n−1)·n "
        f"Gray-code steps at any band): timed for n ≤ {TW_BANDED_MAX}, above that the time is "
        "extrapolated from its n = 24 banded time in this run (not run).",
    )
    for col in ("n", "band", "values", "frontier", "ours (auto)", "rel err ours", "F(n+1)"):
        table.add_column(col, justify="right")
    for col in ("thewalrus", "thewalrus/ours", "rel err thewalrus"):
        table.add_column(col, justify="right")
    for r in rows:
        if r["thewalrus_s"] is not None:
            tw = _fmt_time(r["thewalrus_s"])
        elif r["thewalrus_estimate_s"]:
            est = r["thewalrus_estimate_s"]
            tw = (
                f"not run (≈ {est / 3600:.3g} h)"
                if est < 3.15e7
                else f"not run (≈ {est / 3.15e7:.2g} years)"
            )
        else:
            tw = "not installed" if tw_perm is None else "—"
        ratio = (
            f"{r['speedup']:.0f}×"
            if r["speedup"]
            else (
                f"≈ {r['thewalrus_estimate_s'] / r['ours_s']:.1e}×"
                if r["thewalrus_estimate_s"] and r["ours_s"]
                else "—"
            )
        )
        table.add_row(
            str(r["n"]),
            r["band"],
            r["values"],
            f"{r['max_frontier']} bits",
            _fmt_time(r["ours_s"]),
            _fmt_err(r["ours_rel_err"]),
            "—" if r["fibonacci_ok"] is None else ("= F(n+1)" if r["fibonacci_ok"] else "WRONG"),
            tw,
            ratio,
            _fmt_err(r["thewalrus_rel_err"]),
        )
    console.print(table)
    return rows


DENSE_N = 28


def _dense_large(console, tw_perm) -> dict:
    """n = 28 uniform via "auto" (Glynn with its own error estimate) vs thewalrus, once each."""
    from jointtrack.assignment import assignment_sum
    from jointtrack.permanent import permanent

    n = DENSE_N
    A = np.random.default_rng(n).random((n, n))
    permanent(A[:16, :16])
    t_ours, ours = _timed(lambda: permanent(A))
    t_res, res = _timed(lambda: assignment_sum(A, marginals=False))
    row = {
        "n": n,
        "ours_s": min(t_ours, t_res),
        "method": res.method,
        "error_estimate": res.info.get("error_estimate"),
        "value": ours,
        "thewalrus_s": None,
        "speedup": None,
        "rel_diff_vs_thewalrus": None,
    }
    if tw_perm is not None:
        t_tw, tw = _timed(lambda: tw_perm(A))
        row["thewalrus_s"] = t_tw
        row["speedup"] = t_tw / row["ours_s"]
        row["rel_diff_vs_thewalrus"] = _peer_log_err(tw, math.log(ours))
    console.print(
        f"Dense uniform n = {n} (rng.random, seed {n}), one call each: ours "
        f"(auto → {row['method']}) {_fmt_time(row['ours_s'])}, Glynn's error estimate "
        f"{_fmt_err(row['error_estimate'])}; thewalrus "
        f"{_fmt_time(row['thewalrus_s']) if tw_perm else 'not installed'}"
        + (
            f" ({row['speedup']:.2f}×, |rel diff| {_fmt_err(row['rel_diff_vs_thewalrus'])})"
            if row["speedup"]
            else ""
        )
        + ". No exact reference (the DP would need 2^28 states × 2 arrays = 4 GiB)."
    )
    return row


def _scaled_cases(n: int):
    rng = np.random.default_rng(2024)
    for k in (2, 5, 20, 300):
        U = rng.random((n, n))
        A = U * 10.0 ** rng.uniform(-k, 0, (n, 1)) * 10.0 ** rng.uniform(-k, 0, (1, n))
        yield f"rows·cols 10^U(-{k},0)", A
    U = rng.random((n, n))
    yield "elementwise 10^U(-30,0)", U * 10.0 ** rng.uniform(-30, 0, (n, n))


def _badly_scaled(console, quick: bool, tw_perm) -> list[dict]:
    from rich.table import Table

    from jointtrack.permanent import log_permanent
    from jointtrack.permanent.reference import reference_log_permanent

    n = 14 if quick else 20
    rows = []
    for label, A in _scaled_cases(n):
        fns = {"ours": lambda A=A: log_permanent(A)}
        if tw_perm is not None:
            fns["thewalrus"] = lambda A=A: tw_perm(A)
        med, vals, reps = _interleaved(fns, budget=0.5 if quick else 2.0)
        ref = reference_log_permanent(A)
        ours = vals["ours"]
        if isinstance(ours, Exception):
            err = f"error: {type(ours).__name__}"
        elif ref == -math.inf:
            err = 0.0 if ours == -math.inf else f"{ours:.3g} for Per = 0"
        else:
            err = abs(math.expm1(ours - ref))
        row = {
            "case": label,
            "n": n,
            "log_per_ref": ref,
            "zero_entries": int(np.count_nonzero(A == 0.0)),
            "ours_s": med.get("ours"),
            "ours_rel_err": err,
            "thewalrus_s": med.get("thewalrus"),
            "thewalrus_rel_err": _peer_log_err(vals["thewalrus"], ref) if tw_perm else None,
            "repeats": reps,
        }
        rows.append(row)

    table = Table(
        title=f"Badly scaled n = {n}: log_permanent vs exact reference",
        caption="rel err = |expm1(log ours − log exact)|; thewalrus compared in log space. "
        "Entries below ~5e-324 underflow to 0 when the matrix is formed (column 'zeros'); "
        "the exact permanent of the float64 matrix may then be 0 (log = -inf).",
    )
    for col in ("matrix", "log Per (exact)", "zeros (underflow)", "ours", "rel err ours"):
        table.add_column(col, justify="right")
    for col in ("thewalrus", "rel err thewalrus"):
        table.add_column(col, justify="right")
    for r in rows:
        table.add_row(
            r["case"],
            f"{r['log_per_ref']:.6g}",
            str(r["zero_entries"]),
            _fmt_time(r["ours_s"]),
            _fmt_err(r["ours_rel_err"]),
            _fmt_time(r["thewalrus_s"]) if tw_perm else "not installed",
            _fmt_err(r["thewalrus_rel_err"]),
        )
    console.print(table)
    return rows


def _schaub(console, quick: bool) -> list[dict]:
    from rich.table import Table

    from jointtrack.permanent import assignment_marginals
    from jointtrack.permanent.reference import reference_marginals

    rng = np.random.default_rng(7)
    cases = [
        (
            "3 classes 60/30/10",
            rng.random((100, 3)) + 0.01,
            None,
            np.array([60, 30, 10]),
            "compressed 100×3",
        ),
        (
            "6 observed + 94 hidden rows",
            rng.random((7, 100)) + 0.01,
            np.array([1, 1, 1, 1, 1, 1, 94]),
            None,
            "compressed 7×100",
        ),
    ]
    rows = []
    for label, W, rc, cc, shape in cases:

        def fn(W=W, rc=rc, cc=cc):
            return assignment_marginals(W, row_counts=rc, col_counts=cc)

        med, vals, reps = _interleaved({"ours": fn}, budget=0.5 if quick else 2.0, max_reps=50)
        t0 = time.perf_counter()
        ref = reference_marginals(W, row_counts=rc, col_counts=cc)
        t_ref = time.perf_counter() - t0
        P = vals["ours"]
        err = (
            float(np.max(np.abs(np.asarray(P) - ref)))
            if not isinstance(P, Exception)
            else f"error: {P!r}"
        )
        rows.append(
            {
                "case": label,
                "input": shape,
                "ours_s": med.get("ours"),
                "max_abs_err": err,
                "reference_s": t_ref,
                "repeats": reps,
            }
        )

    table = Table(title="Schaub identity 100×100: full assignment_marginals")
    for col in ("case", "input", "ours", "max abs err", "exact reference", "thewalrus"):
        table.add_column(col, justify="right")
    for r in rows:
        table.add_row(
            r["case"],
            r["input"],
            _fmt_time(r["ours_s"]),
            _fmt_err(r["max_abs_err"]),
            _fmt_time(r["reference_s"]),
            "cannot: no compressed form; expanded = 2¹⁰⁰ terms",
        )
    console.print(table)
    return rows


def _startup(console) -> dict:
    runs = []
    for _ in range(2):
        t0 = time.perf_counter()
        proc = subprocess.run(
            [sys.executable, "-c", STARTUP_CODE], capture_output=True, text=True, check=False
        )
        runs.append(
            {
                "wall_s": time.perf_counter() - t0,
                "returncode": proc.returncode,
                "stderr_tail": proc.stderr.strip().splitlines()[-3:] if proc.returncode else [],
            }
        )
    console.print(
        "Second-process start-up (import + one 20×20 permanent, fresh interpreter): "
        f"first {_fmt_time(runs[0]['wall_s'])}, second {_fmt_time(runs[1]['wall_s'])}"
    )
    for k, r in enumerate(runs, 1):
        if r["returncode"]:
            last = r["stderr_tail"][-1] if r["stderr_tail"] else ""
            console.print(f"[red]  run {k} failed (exit {r['returncode']}): {last}[/]", markup=True)
    return {"first_s": runs[0]["wall_s"], "second_s": runs[1]["wall_s"], "runs": runs}


def _targets(
    console, uniform, scaled, schaub, startup, tw_installed: bool, band=(), dense=None
) -> list[dict]:
    from rich.table import Table

    out = []
    by_n = {r["n"]: r for r in uniform}
    for n in (24, 26):
        r = by_n.get(n)
        if r is None:
            out.append({"target": f"n={n}: ≥ {TARGET_SPEEDUP}× thewalrus, err ≤ 1e-12", "ok": None})
            continue
        err_ok = isinstance(r["ours_rel_err"], float) and r["ours_rel_err"] <= TARGET_UNIFORM_ERR
        speed_ok = None if not tw_installed else bool((r["speedup"] or 0) >= TARGET_SPEEDUP)
        out.append(
            {
                "target": f"n={n}: ≥ {TARGET_SPEEDUP}× thewalrus, rel err ≤ 1e-12",
                "value": (
                    f"{r['speedup']:.2f}×, {_fmt_err(r['ours_rel_err'])}"
                    if r["speedup"]
                    else f"thewalrus not installed, {_fmt_err(r['ours_rel_err'])}"
                ),
                "ok": err_ok and speed_ok if speed_ok is not None else None,
            }
        )
    worst = [r["ours_rel_err"] for r in scaled]
    numeric = [e for e in worst if isinstance(e, float)]
    ok = len(numeric) == len(worst) and max(numeric) <= TARGET_SCALED_ERR
    out.append(
        {
            "target": "badly scaled: rel err ≤ 1e-11",
            "value": f"worst {_fmt_err(max(numeric)) if numeric else '—'}"
            + ("" if len(numeric) == len(worst) else "; some failed"),
            "ok": ok,
        }
    )
    for r in schaub:
        ok = (
            r["ours_s"] is not None
            and r["ours_s"] <= TARGET_SCHAUB_TIME
            and isinstance(r["max_abs_err"], float)
            and r["max_abs_err"] <= TARGET_SCHAUB_ERR
        )
        out.append(
            {
                "target": f"Schaub {r['case']}: ≤ 10 ms, max abs err ≤ 1e-11",
                "value": f"{_fmt_time(r['ours_s'])}, {_fmt_err(r['max_abs_err'])}",
                "ok": ok,
            }
        )
    for n in sorted({r["n"] for r in band if r["n"] >= 40}):
        rs = [r for r in band if r["n"] == n]
        worst_t = max(r["ours_s"] or math.inf for r in rs)
        errs = [r["ours_rel_err"] for r in rs]
        ok = (
            worst_t <= TARGET_BANDED_TIME
            and all(isinstance(e, float) and e <= TARGET_BANDED_ERR for e in errs)
            and all(r["fibonacci_ok"] is not False for r in rs)
        )
        out.append(
            {
                "target": f"banded n={n} (tri/5-band, ones/random): each ≤ 10 ms, "
                "rel err ≤ 1e-12, tridiagonal ones = F(n+1)",
                "value": f"worst {_fmt_time(worst_t)}, "
                f"{_fmt_err(max((e for e in errs if isinstance(e, float)), default=None))}",
                "ok": ok,
            }
        )
    if dense is not None:
        out.append(
            {
                "target": f"dense n={dense['n']} via auto reaches Glynn",
                "value": f"{dense['method']}, {_fmt_time(dense['ours_s'])}, "
                f"est. err {_fmt_err(dense['error_estimate'])}",
                "ok": dense["method"] == "glynn",
            }
        )
    ok = startup["second_s"] < TARGET_STARTUP and all(r["returncode"] == 0 for r in startup["runs"])
    out.append(
        {
            "target": "second process (import + 20×20) < 1 s",
            "value": _fmt_time(startup["second_s"]),
            "ok": ok,
        }
    )

    table = Table(title="Targets")
    table.add_column("target")
    table.add_column("measured", justify="right")
    table.add_column("", justify="center")
    for t in out:
        table.add_row(t["target"], t.get("value", "quick mode: not run"), _mark(t["ok"]))
    console.print(table)
    return out


# --------------------------------------------------------------------------- entry point


def run(quick: bool = False, out: str | None = None) -> dict:
    """Run the permanent benchmark, print rich tables, optionally write JSON to `out`.

    Parameters
    ----------
    quick : bool
        Smaller sizes (uniform n ≤ 20, badly scaled n = 14) and fewer repeats.
    out : str, optional
        Path of a JSON file receiving the returned dictionary.

    Returns
    -------
    dict
        ``{"meta", "uniform", "banded", "dense_28", "badly_scaled", "schaub", "startup",
        "targets"}``;
        times in seconds (medians), errors relative (or a string saying why not).
    """
    import numba

    from jointtrack._console import make_console

    console = make_console()
    tw_perm, tw_version = _load_thewalrus()
    meta = {
        "quick": quick,
        "python": platform.python_version(),
        "numpy": np.__version__,
        "numba": numba.__version__,
        "thewalrus": tw_version,
        "cpus": os.cpu_count(),
        "platform": platform.platform(),
    }
    console.print(
        f"[bold]jointtrack permanent benchmark[/] ({'quick' if quick else 'full'}) — "
        f"python {meta['python']}, numpy {meta['numpy']}, numba {meta['numba']}, "
        f"{meta['cpus']} CPUs; thewalrus {tw_version or 'NOT INSTALLED'}"
    )
    if tw_perm is None:
        console.print(
            "[yellow]thewalrus is not installed (pip install -e '.[bench]'): "
            "only jointtrack is timed, no peer ratios.[/]"
        )
    uniform = _uniform(console, quick, tw_perm)
    scaled = _badly_scaled(console, quick, tw_perm)
    band = _banded(console, quick, tw_perm)
    dense = None if quick else _dense_large(console, tw_perm)
    schaub = _schaub(console, quick)
    startup = _startup(console)
    targets = _targets(console, uniform, scaled, schaub, startup, tw_perm is not None, band, dense)
    result = {
        "meta": meta,
        "uniform": uniform,
        "banded": band,
        "dense_28": dense,
        "badly_scaled": scaled,
        "schaub": schaub,
        "startup": startup,
        "targets": targets,
    }
    if out:
        with open(out, "w", encoding="utf-8") as fh:
            json.dump(to_jsonable(result, nonfinite="string", fallback="text"), fh, indent=2)
        console.print(f"results written to {out}")
    return result
