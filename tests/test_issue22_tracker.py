"""Issue 22, tracker items: covariances after long gaps (12), states that save but do
not load (14), and numeric input that was silently truncated or crashed (15)."""

from __future__ import annotations

import hashlib
import json
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import assume, example, given, settings
from hypothesis import strategies as st

from jointtrack.association.clutter import (
    cluster_clutter_density,
    cluster_heuristic_densities,
    cluster_heuristic_density,
    union_gate_volume,
)
from jointtrack.association.gating import gate_measurements, gate_pairs
from jointtrack.filters import pda_update, predict, update
from jointtrack.models import ConstantAcceleration, ConstantVelocity, LinearPosition
from jointtrack.trackers import JPDATracker, StateFileError, TrackerConfig, state_io

# ----------------------------------------------------------------------------- helpers


def _exact_pd(A: np.ndarray) -> bool:
    """Whether the float matrix A is positive definite in exact arithmetic.

    Sylvester's criterion on the exact integers ``A · 2^k`` (every float is a dyadic
    rational): fraction-free Bareiss elimination, whose k-th pivot is the k-th
    leading principal minor; all must be positive.
    """
    fr = [[Fraction(float(v)) for v in row] for row in A]
    den = max(f.denominator for row in fr for f in row)
    M = [[f.numerator * (den // f.denominator) for f in row] for row in fr]
    n, prev = len(M), 1
    for k in range(n):
        p = M[k][k]
        if p <= 0:
            return False
        for i in range(k + 1, n):
            for j in range(k + 1, n):
                M[i][j] = (M[i][j] * p - M[i][k] * M[k][j]) // prev  # exact (Bareiss)
        prev = p
    return True


def _assert_pd(P, what=""):
    """P (n, n) or (K, n, n): exactly symmetric, positive definite in exact arithmetic,
    factorisable by Cholesky, and its correlation matrix has a positive smallest
    eigenvalue (the scale-free form of "min eigenvalue > 0 relative to max": the raw
    eigvalsh of a covariance whose variances span 30 orders of magnitude cannot
    resolve its smallest eigenvalue)."""
    P = np.asarray(P)
    for k, A in enumerate(P.reshape(-1, P.shape[-1], P.shape[-1])):
        where = f"{what} matrix {k}"
        assert np.isfinite(A).all(), where
        assert np.array_equal(A, A.T), f"{where}: not exactly symmetric"
        np.linalg.cholesky(A)  # raises LinAlgError if not
        assert _exact_pd(A), f"{where}: indefinite in exact arithmetic: {A!r}"
        s = np.sqrt(np.diag(A))
        assert np.linalg.eigvalsh(A / np.outer(s, s))[0] > 0, where


# ----------------------------------------------------------------------------- item 12

exponents = st.floats(-6.0, 12.0)


@st.composite
def _covariance(draw, n, min_log_ridge=-17.0):
    """A symmetric positive definite n × n matrix from drawn entries, rank, ridge and scales."""
    rank = draw(st.integers(1, n))
    entries = draw(st.lists(st.floats(-1.0, 1.0), min_size=n * rank, max_size=n * rank))
    logs = draw(st.lists(st.floats(-3.0, 6.0), min_size=n, max_size=n))
    ridge = 10.0 ** draw(st.floats(min_log_ridge, -3.0))  # down to singular in working precision
    A = np.array(entries).reshape(n, rank)
    C = A @ A.T + ridge * np.eye(n)
    s = 10.0 ** np.array(logs)
    P = s[:, None] * C * s[None, :]
    return 0.5 * (P + P.T)


@st.composite
def _gap_problem(draw):
    ca = draw(st.booleans())
    dim = draw(st.integers(1, 3))
    q = draw(st.one_of(st.just(0.0), st.floats(-6.0, 3.0).map(lambda e: 10.0**e)))
    motion = (ConstantAcceleration if ca else ConstantVelocity)(dim=dim, q=q)
    n = motion.state_dim
    P = draw(_covariance(n))
    x = np.array(draw(st.lists(st.floats(-1e3, 1e3), min_size=n, max_size=n)))
    r = 10.0 ** draw(st.floats(-2.0, 3.0))
    dt = min(10.0 ** draw(exponents), motion.max_dt)
    noise = draw(st.lists(st.floats(-3.0, 3.0), min_size=4 * dim, max_size=4 * dim))
    beta = np.array(draw(st.lists(st.floats(0.01, 1.0), min_size=3, max_size=3)))
    return motion, x, P, r, dt, np.array(noise).reshape(4, dim), beta / beta.sum()


@settings(max_examples=60, deadline=None)
@given(_gap_problem())
def test_covariance_stays_positive_definite_through_a_gap(problem):
    """Issue 22 item 12: after predict, update and PDA update, for dt from 1e-6 to 1e12,
    then normal scans, every covariance is exactly PD (it was not: F P Fᵀ + Q after a
    long gap, and its updates, could be indefinite in the last bits while Cholesky
    still succeeded)."""
    motion, x, P, r, dt, noise, beta = problem
    dim = noise.shape[1]
    sensor = LinearPosition(dim, r, state_dim=motion.state_dim)
    sd = np.sqrt(r)
    for k, step in enumerate((dt, 1.0, 1.0)):
        x, P = predict(x, P, motion.transition(step), motion.noise(step))
        _assert_pd(P, f"predict dt={step}")
        z = x[:dim] + sd * noise[k]
        try:
            if k % 2 == 0:
                x, P = update(x, P, z, sensor.H, sensor.R)
            else:
                Z = np.stack([z, x[:dim] + sd * noise[3]])
                x, P = pda_update(x, P, Z, sensor.H, sensor.R, beta)
        except ValueError as exc:
            # axes whose variances differ by > 1/ε after the gap (q = 0, drawn scales):
            # the filter declines the singular-to-working-precision S by name
            assert "innovation covariance S" in str(exc) and "singular" in str(exc)
            assume(False)
        _assert_pd(P, "update" if k % 2 == 0 else "pda_update")


def test_near_singular_sweep_regression():
    """Seeded sweep of covariances whose correlation matrix is singular to working
    precision (what a long gap leaves behind), through one predict (dt 1e-6 … 1e12),
    update and PDA update each. At ebb8dbc trials 41 and 154 (predict), 72 (update)
    and 236 (PDA update) returned matrices that passed Cholesky but were indefinite
    in exact arithmetic."""
    for trial in range(250):
        rng = np.random.default_rng(trial)
        dim = int(rng.integers(1, 4))
        ca = rng.random() < 0.5
        q = 0.0 if rng.random() < 0.3 else 10 ** rng.uniform(-6, 3)
        motion = (ConstantAcceleration if ca else ConstantVelocity)(dim=dim, q=q)
        n = motion.state_dim
        U = rng.normal(size=(n, int(rng.integers(1, n))))
        C = U @ U.T + 10 ** rng.uniform(-17, -12) * np.eye(n)
        s = 10 ** rng.uniform(-3, 6, size=n)
        P = s[:, None] * C * s[None, :]
        P = 0.5 * (P + P.T)
        x = rng.normal(size=n)
        dt = min(10 ** rng.uniform(-6, 12), motion.max_dt)
        sensor = LinearPosition(dim, 10 ** rng.uniform(-2, 2), state_dim=n)
        z = x[:dim] + rng.normal(size=dim)
        beta = rng.dirichlet([1, 1, 1])
        _assert_pd(predict(x, P, motion.transition(dt), motion.noise(dt))[1], f"predict {trial}")
        _assert_pd(update(x, P, z, sensor.H, sensor.R)[1], f"update {trial}")
        Z = np.vstack([z, z + 1.0])
        _assert_pd(pda_update(x, P, Z, sensor.H, sensor.R, beta)[1], f"pda_update {trial}")


@pytest.mark.parametrize("motion", ["cv", "ca"])
@pytest.mark.parametrize("gap", [1e4, 1e8, 1e12])
def test_tracker_keeps_covariances_pd_after_a_long_gap(motion, gap):
    """JPDATracker with a long gap between scans: every track's P (confirmed and
    tentative, including tracks born across the gap) stays exactly PD for 30 scans."""
    rng = np.random.default_rng(7)
    trk = JPDATracker(TrackerConfig(clutter_density=1e-6, motion=motion))
    n = trk.state_dim
    truth = np.zeros((2, n))
    truth[:, :4] = [[0.0, 0.0, 1.0, 1.0], [500.0, 0.0, -1.0, 1.0]]
    trk.start_tracks(truth, np.diag([1.0, 1.0, 0.1, 0.1] + [1.0] * (n - 4)), time=0.0)
    t = 0.0
    for k in range(33):
        dt = gap if k == 2 else 1.0
        t += dt
        truth[:, :2] += dt * truth[:, 2:4]
        trk.step(t, truth[:, :2] + 10.0 * rng.normal(size=(2, 2)))
        _assert_pd(trk.P, f"scan {k}")


# ----------------------------------------------------------------------------- item 14


def _tracker():
    return JPDATracker(TrackerConfig(clutter_density=1e-4))


_P_ASYM = np.eye(4)
_P_ASYM[0, 1] = 0.5


@pytest.mark.parametrize(
    "kwargs, exc, match",
    [
        (dict(existence=float("nan")), ValueError, "existence"),
        (dict(existence=1.5), ValueError, "existence"),
        (dict(existence=-1.0), ValueError, "existence"),
        (dict(existence=True), ValueError, "existence"),
        (dict(existence="0.5"), ValueError, "existence"),
        (dict(existence=1 + 0j), ValueError, "existence"),
        (dict(P0=_P_ASYM), ValueError, "P0 is not symmetric"),
        (dict(P0=-np.eye(4)), ValueError, "P0 is not positive definite"),
        (dict(P0=np.eye(4) * (1 + 1e-3j)), ValueError, "P0 has complex"),
        (dict(P0=np.eye(3)), ValueError, "P0 must have shape"),
        (dict(x0=np.zeros((1, 4)) + 1j), ValueError, "x0 has complex"),
        (dict(x0=[[True, False, True, False]]), ValueError, "x0 is boolean"),
        (dict(x0=[[10**400, 0, 0, 0]]), ValueError, "x0 holds an integer too large"),
        (dict(confirmed="yes"), TypeError, "confirmed"),
        (dict(existence=0.0), ValueError, "existence must be > 0"),  # issue 31: no target
    ],
)
def test_start_tracks_refuses_what_load_would_refuse(kwargs, exc, match):
    trk = _tracker()
    args = dict(x0=np.zeros((1, 4)), P0=np.eye(4))
    args.update(kwargs)
    x0, P0 = args.pop("x0"), args.pop("P0")
    with pytest.raises(exc, match=match):
        trk.start_tracks(x0, P0, **args)
    assert len(trk.ids) == 0 and trk.next_id == 1


@settings(max_examples=25, deadline=None)
@given(
    existence=st.one_of(st.floats(5e-324, 1.0), st.sampled_from([5e-324, 1])),
    P0=_covariance(4, min_log_ridge=-3.0),
    x0=st.lists(st.floats(-1e300, 1e300), min_size=4, max_size=4),
    confirmed=st.booleans(),
)
def test_every_state_start_tracks_accepts_saves_and_loads(
    tmp_path_factory, existence, P0, x0, confirmed
):
    trk = _tracker()
    trk.start_tracks(np.array([x0]), P0, existence=existence, confirmed=confirmed)
    path = trk.save(tmp_path_factory.mktemp("s") / "state.npz")
    back = JPDATracker.load(path)
    np.testing.assert_array_equal(back.P, trk.P)
    np.testing.assert_array_equal(back.existence, trk.existence)


def _resave(path, out, mutate=None, header_text=None):
    """Rewrite the state file ``path`` to ``out`` with a VALID checksum, computed the way
    state_io does (SHA-256 of the canonical header JSON, then every array's name,
    dtype, shape and bytes). ``mutate(header)`` edits the decoded header;
    ``header_text`` replaces the canonical header JSON by a given string."""
    with np.load(path, allow_pickle=False) as npz:
        arrays = {k: npz[k] for k in npz.files}
    header = json.loads(arrays.pop("__header__").tobytes().decode())
    header.pop("sha256")
    if mutate:
        mutate(header)
    if header_text is None:
        header_text = json.dumps(header, sort_keys=True, separators=(",", ":"))
    h = hashlib.sha256(header_text.encode())
    for name in sorted(arrays):
        a = np.ascontiguousarray(arrays[name])
        h.update(f"{name}|{a.dtype.str}|{a.shape}|".encode())
        h.update(a.tobytes())
    assert header_text.startswith("{") and header_text.endswith("}")
    full = header_text[:-1] + f',"sha256":"{h.hexdigest()}"}}'
    blob = np.frombuffer(full.encode(), dtype=np.uint8)
    with open(out, "wb") as fh:
        np.savez(fh, __header__=blob, **arrays)
    return out


def _set(section, key, value):
    def mutate(h):
        h[section][key] = value

    return mutate


def _rng_state(h):
    h["rng"]["state"]["state"] = 2**200


def _empty_config(h):
    h["config"] = {}


def _drop_config_key(h):
    del h["config"]["p_d"]


@pytest.mark.parametrize(
    "mutate, match",
    [
        (_rng_state, "random-generator state"),
        (_set("scalars", "next_id", 2**70), "next_id"),
        (_set("scalars", "n_scans", 2**70), "n_scans"),
        (_set("scalars", "time", 10**400), "time"),
        (_empty_config, "missing tracker setting"),
        (_drop_config_key, "missing tracker setting.*p_d"),
    ],
)
def test_hand_made_state_files_give_state_file_error(tmp_path, mutate, match):
    trk = _tracker()
    trk.start_tracks(np.zeros((2, 4)), np.eye(4))
    good = trk.save(tmp_path / "good.npz")
    JPDATracker.load(_resave(good, tmp_path / "same.npz"))  # the rewrite itself is valid
    bad = _resave(good, tmp_path / "bad.npz", mutate=mutate)
    with pytest.raises(StateFileError, match=match):
        JPDATracker.load(bad)


def test_deeply_nested_header_gives_state_file_error(tmp_path):
    trk = _tracker()
    good = trk.save(tmp_path / "good.npz")
    with np.load(good, allow_pickle=False) as npz:
        header = json.loads(npz["__header__"].tobytes().decode())
    header.pop("sha256")
    header["run"] = None
    text = json.dumps(header, sort_keys=True, separators=(",", ":"))
    depth = 100_000
    text = text.replace('"run":null', '"run":' + "[" * depth + "]" * depth)
    bad = _resave(good, tmp_path / "deep.npz", header_text=text)
    with pytest.raises(StateFileError, match="nested too deeply"):
        JPDATracker.load(bad)
    with pytest.raises(StateFileError):
        state_io.read_run(bad)


# ----------------------------------------------------------------------------- item 15

_ZP = np.zeros((1, 2))
_S = np.eye(2)[None]
_Z = np.zeros((1, 2))


def _gating():
    return gate_measurements(_ZP, _S, np.array([[0.1, 0.0], [5.0, 5.0]]))


BAD_NUMERIC_CALLS = [
    # gating: complex was truncated, bool/str coerced, 10**400 a bare OverflowError
    ("gate z complex", lambda: gate_measurements(_ZP, _S, _Z + 1j), "z has complex"),
    ("gate z_pred complex", lambda: gate_measurements(_ZP + 1j, _S, _Z), "z_pred has complex"),
    ("gate S complex", lambda: gate_measurements(_ZP, _S + 0j, _Z), "S has complex"),
    ("gate z bool", lambda: gate_measurements(_ZP, _S, [[True, False]]), "z is boolean"),
    ("gate z str", lambda: gate_measurements(_ZP, _S, [["1", "2"]]), "z holds strings"),
    ("gate z huge", lambda: gate_measurements(_ZP, _S, [[10**400, 0]]), "z holds an integer"),
    ("gate P_G bool", lambda: gate_measurements(_ZP, _S, _Z, P_G=True), "P_G"),
    ("pairs z complex", lambda: gate_pairs(_ZP, _S, _Z + 1j), "z has complex"),
    ("pairs z str", lambda: gate_pairs(_ZP, _S, [["1", "2"]]), "z holds strings"),
    # clutter
    (
        "union n_samples float",
        lambda: union_gate_volume(_ZP, _S, P_G=0.9, n_samples=2.7),
        "n_samples",
    ),
    (
        "union n_samples bool",
        lambda: union_gate_volume(_ZP, _S, P_G=0.9, n_samples=True),
        "n_samples",
    ),
    ("cluster tracks float", lambda: cluster_clutter_density(_gating(), [0.5]), "tracks"),
    ("cluster tracks bool", lambda: cluster_clutter_density(_gating(), [True]), "tracks"),
    ("cluster tracks huge", lambda: cluster_clutter_density(_gating(), [2**70]), "tracks"),
    ("heuristic overflow", lambda: cluster_heuristic_density([1], [1e-320]), "overflows"),
    (
        "heuristics overflow",
        lambda: cluster_heuristic_densities([1, 0], [1e-320, 1.0], [0, 1]),
        "overflows",
    ),
    (
        "heuristic volume sum overflow",
        lambda: cluster_heuristic_density([1, 1], [1e308, 1e308]),
        "sum beyond the float range",
    ),
    ("heuristic complex", lambda: cluster_heuristic_density([1], [1 + 1j]), "complex"),
    ("heuristic bool counts", lambda: cluster_heuristic_density([True], [1.0]), "boolean"),
]


def _step_call(t=1.0, z=_Z):
    return lambda: _tracker().step(t, z)


BAD_STEP_CALLS = [
    ("step t str", _step_call(t="1.0"), TypeError, "scan time t"),
    ("step t bool", _step_call(t=True), ValueError, "scan time t"),
    ("step t np.bool_", _step_call(t=np.True_), TypeError, "scan time t"),
    ("step t complex", _step_call(t=1 + 0j), ValueError, "scan time t"),
    ("step t huge", _step_call(t=10**400), ValueError, "scan time t"),
    ("step t nan", _step_call(t=float("nan")), ValueError, "scan time t"),
    ("step z complex", _step_call(z=_Z + 1j), ValueError, "measurements z has complex"),
    ("step z bool", _step_call(z=[[True, False]]), ValueError, "measurements z is boolean"),
    ("step z str", _step_call(z=[["1", "2"]]), ValueError, "measurements z holds strings"),
    ("step z huge", _step_call(z=[[10**400, 0]]), ValueError, "measurements z holds an integer"),
    (
        "start_tracks time huge",
        lambda: _tracker().start_tracks(np.zeros((1, 4)), np.eye(4), time=10**400),
        ValueError,
        "scan time t",
    ),
]


@pytest.mark.parametrize(
    "call, match", [c[1:] for c in BAD_NUMERIC_CALLS], ids=[c[0] for c in BAD_NUMERIC_CALLS]
)
def test_bad_numeric_input_is_refused_by_name(call, match):
    with pytest.raises(ValueError, match=match):
        call()


@pytest.mark.parametrize(
    "call, exc, match", [c[1:] for c in BAD_STEP_CALLS], ids=[c[0] for c in BAD_STEP_CALLS]
)
def test_bad_scan_input_is_refused_by_name(call, exc, match):
    with pytest.raises(exc, match=match):
        call()


def test_failed_step_leaves_the_tracker_unchanged():
    trk = _tracker()
    trk.step(0.0, np.array([[1.0, 2.0]]))
    before = trk.state_dict()
    with pytest.raises(ValueError):
        trk.step(1.0, np.array([[1.0, 2.0]]) + 1j)
    after = trk.state_dict()
    for k, v in before.items():
        if isinstance(v, np.ndarray):
            np.testing.assert_array_equal(v, after[k])
        else:
            assert v == after[k]


reals = st.floats(-1e100, 1e100, allow_subnormal=True)


@pytest.mark.filterwarnings("ignore::jointtrack.errors.CoincidentReturnsWarning")
@settings(max_examples=40, deadline=None)
@given(
    z=st.lists(st.tuples(reals, reals), max_size=5),
    as_ints=st.booleans(),
    t=st.one_of(st.floats(-1e300, 1e300), st.integers(-(2**60), 2**60)),
)
def test_random_finite_real_input_is_still_accepted(z, as_ints, t):
    zz = [[int(a), int(b)] for a, b in z] if as_ints else [list(p) for p in z]
    g = gate_measurements(_ZP, _S, zz if zz else np.zeros((0, 2)))
    assert g.mask.shape == (1, len(zz))
    gp = gate_pairs(_ZP, _S, zz if zz else np.zeros((0, 2)))
    assert gp.n_measurements == len(zz)
    trk = _tracker()
    trk.step(t, zz if zz else np.zeros((0, 2)))
    assert trk.time == float(t) and trk.n_scans == 1


@settings(max_examples=60, deadline=None)
@given(
    m=st.lists(st.integers(0, 10**6), min_size=1, max_size=5),
    logv=st.lists(st.floats(-323.0, 307.0), min_size=5, max_size=5),
)
@example(m=[1], logv=[-320.0] * 5)
@example(m=[0], logv=[-323.0] * 5)
def test_heuristic_density_is_finite_or_refused(m, logv):
    """Bojilov (8) λ = Σm/ΣV against the exact rational ratio: a finite float within
    1e-12 relative, or (only when the exact value is beyond the float range) a
    ValueError — never inf."""
    V = [10.0**e for e in logv[: len(m)]]
    if any(v == 0.0 for v in V):
        with pytest.raises(ValueError, match="gate volume"):
            cluster_heuristic_density(m, V)
        return
    exact = Fraction(sum(m)) / sum(Fraction(v) for v in V)
    big = Fraction(np.finfo(float).max)
    try:
        lam = cluster_heuristic_density(m, V)
    except ValueError as exc:
        assert "overflows" in str(exc)
        assert exact > big * (1 - Fraction(1, 10**12))
        return
    assert np.isfinite(lam)
    assert exact <= big * (1 + Fraction(1, 10**12))
    if exact == 0:
        assert lam == 0.0
    elif exact >= Fraction(np.finfo(float).tiny):
        assert abs(Fraction(lam) - exact) <= Fraction(1, 10**12) * exact
