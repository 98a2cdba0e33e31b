"""PMB and PMBM on reporting targets (issue 32, item 4): the asynchronous reporting model,
labels and reported velocities, through the rules the JIPDA tracker uses
(:mod:`jointtrack.trackers.reporting`).

* the async model in PMB equals JIPDA's on one target where the two models are the
  same model: a Bernoulli with no birth intensity (e = 0, so ρ = λ_c) against a JIPDA
  track with the miss weight 1 − r P_D (``miss_model = "1-pd"``: the Poisson weights
  have no gate factor) and no gate — predicted existence, posterior existence, mean
  and covariance to 1e-12, deaths included. They differ, by design, in how a target
  is born (PMB: the Poisson intensity's e_j/ρ_j; JIPDA: r_init × availability), so
  births are not compared;
* the PMB association of several Bernoullis under the async model against the exact
  rational enumeration of its events (``brute.brute_assignment``), the per-Bernoulli
  P_D,i and the undetected targets' rate formed here from the model's definition;
* labels: a labelled report updates only the Bernoulli carrying its label (or starts
  one, with the label's old id), so two targets that cross are never swapped;
* reported velocities seed new Bernoullis, labelled or not;
* state files hold the new fields; an older (version 5) PMB/PMBM state is migrated
  and continues exactly.
"""

from __future__ import annotations

import json
import math
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.stats import multivariate_normal

from brute import brute_assignment
from jointtrack.models import ConstantVelocity
from jointtrack.trackers import JPDATracker, TrackerConfig, state_io
from jointtrack.trackers.pmbm import PMBMConfig, PMBMTracker, PMBTracker
from jointtrack.trackers.state_io import StateFileError


def _finite(lo, hi):
    return st.floats(lo, hi, allow_nan=False, allow_infinity=False, allow_subnormal=False)


def _log_uniform(lo, hi):
    return _finite(lo, hi).map(lambda v: 10.0**v)


def _async(**kw):
    base = dict(
        reporting="async",
        p_survive_per="second",
        p_survive=0.9999,
        report_interval=30.0,
        clutter_density=1e-10,
        birth_density=1e-10,
        measurement_noise=25.0,
        max_speed=20.0,
        process_noise=0.05,
    )
    return PMBMConfig(**{**base, **kw})


def _set_bernoullis(trk, x, P, r, born, reports, t0):
    n = len(r)
    trk.x, trk.P = np.array(x, float), np.array(P, float)
    trk.existence = np.array(r, float)
    trk.ids = np.arange(1, n + 1, dtype=np.int64)
    trk.reported = np.ones(n, bool)
    trk.born, trk.report_count = np.array(born, float), np.array(reports, float)
    trk.next_id, trk.time = n + 1, t0


# ------------------------------------------------------- the async model = JIPDA's


@st.composite
def one_target(draw):
    sx = draw(_log_uniform(0, 4))
    P = np.diag([sx, draw(_log_uniform(0, 4)), draw(_log_uniform(-2, 2)), 1.0])
    return {
        "x": np.array([draw(_finite(-100, 100)), draw(_finite(-100, 100)), 3.0, -1.0]),
        "P": P,
        "r": draw(st.one_of(st.just(1.0), _finite(1e-3, 1.0))),
        "age": draw(_finite(0.0, 600.0)),
        "reports": draw(_finite(0.0, 50.0)),
        "dt": draw(_log_uniform(-3, 3)),
        "p_d": draw(_finite(0.3, 1.0)),
        "p_survive": draw(st.one_of(st.just(1.0), _finite(0.9, 0.999999))),
        "lam": draw(_log_uniform(-12, -4)),
        "interval": draw(_log_uniform(0, 3)),
        "z": [
            [draw(_finite(-150, 150)), draw(_finite(-150, 150))]
            for _ in range(draw(st.integers(0, 2)))
        ],
    }


@settings(max_examples=40, deadline=None)
@given(sc=one_target())
def test_async_pmb_bernoulli_equals_the_jipda_track(sc):
    shared = dict(
        p_d=sc["p_d"],
        p_g=1.0,
        p_survive=sc["p_survive"],
        clutter_density=sc["lam"],
        report_interval=sc["interval"],
        reporting="async",
        p_survive_per="second",
        measurement_noise=25.0,
        process_noise=0.5,
    )
    t0 = 1000.0
    pmb = PMBTracker(
        PMBMConfig(**shared, birth_density=0.0, prior_density=0.0, r_prune=0.0, r_recycle=0.0)
    )
    _set_bernoullis(pmb, [sc["x"]], [sc["P"]], [sc["r"]], [t0 - sc["age"]], [sc["reports"]], t0)
    jipda = JPDATracker(
        TrackerConfig(**shared, existence=True, miss_model="1-pd", r_delete=1e-300, r_init=1e-3)
    )
    jipda.start_tracks(sc["x"][None], sc["P"], existence=sc["r"], time=t0)
    jipda.born[:], jipda.report_count[:] = t0 - sc["age"], sc["reports"]
    z = np.array(sc["z"], float).reshape(-1, 2)
    t = t0 + sc["dt"]
    pmb.step(t, z)
    jipda.step(t, z)
    # the Bernoulli (id 1) and the track (id 1): nothing else was born from a return
    # in PMB (e = 0); JIPDA's new tracks come after its own
    i = int(np.flatnonzero(pmb.ids == 1)[0])
    assert jipda.ids[0] == 1
    np.testing.assert_allclose(pmb.existence[i], jipda.existence[0], rtol=1e-12, atol=0)
    np.testing.assert_allclose(pmb.x[i], jipda.x[0], rtol=1e-12, atol=1e-12)
    scale = np.abs(jipda.P[0]).max()
    np.testing.assert_allclose(pmb.P[i], jipda.P[0], rtol=1e-12, atol=1e-12 * scale)
    assert pmb.report_count[i] == pytest.approx(jipda.report_count[0], rel=1e-12, abs=1e-300)


# ----------------------------------------------- async PMB against exact enumeration


@st.composite
def async_scene(draw):
    n = draw(st.integers(1, 3))
    m = draw(st.integers(1, 3))
    x = np.array(
        [[draw(_finite(-100, 100)), draw(_finite(-100, 100)), draw(_finite(-3, 3)), 0.0]
         for _ in range(n)]
    )  # fmt: skip
    P = np.stack([np.diag([draw(_log_uniform(0, 3)), draw(_log_uniform(0, 3)), 1.0, 1.0])
                  for _ in range(n)])  # fmt: skip
    z = np.array([[draw(_finite(-120, 120)), draw(_finite(-120, 120))] for _ in range(m)])
    if len({tuple(row) for row in z.tolist()}) < m:  # coincident returns are merged
        z = z[:1]
    return {
        "r": [draw(st.one_of(st.just(1.0), _finite(1e-3, 1.0))) for _ in range(n)],
        "x": x,
        "P": P,
        "age": [draw(_finite(0.0, 300.0)) for _ in range(n)],
        "reports": [draw(_finite(0.0, 20.0)) for _ in range(n)],
        "z": z,
        "dt": draw(_log_uniform(-2, 2)),
        "p_d": draw(_finite(0.3, 1.0)),
        "lam": draw(_log_uniform(-9, -3)),
        "u": draw(_log_uniform(-8, -3)),
        "interval": draw(_log_uniform(0, 2.5)),
    }


@settings(max_examples=30, deadline=None)
@given(sc=async_scene())
def test_async_pmb_posterior_equals_the_exact_enumeration(sc):
    """P_D,i = 1 − (β₀/β₁)^(p_d(1 + reports)) per Bernoulli, e_j = (P_D of an undetected
    target)/Δt · u, ρ_j = λ + e_j: every event's weight from the model's definition,
    the posterior existences and the new Bernoullis' existences from the exact sum."""
    n, dt, p_d, T = len(sc["r"]), sc["dt"], sc["p_d"], sc["interval"]
    t0 = 100.0
    cfg = PMBMConfig(
        reporting="async", p_survive_per="second", p_survive=1.0, p_d=p_d, p_g=1.0,
        clutter_density=sc["lam"], report_interval=T, birth_density=0.0,
        prior_density=sc["u"], measurement_noise=9.0, process_noise=0.3, r_prune=0.0,
        r_recycle=0.0, keep_apart=False, duplicate_distance=0.0,  # the textbook update
    )  # fmt: skip
    trk = PMBTracker(cfg)
    born = [t0 - a for a in sc["age"]]
    _set_bernoullis(trk, sc["x"], sc["P"], sc["r"], born, sc["reports"], t0)
    trk.step(t0 + dt, sc["z"])
    # the model, here: a track's miss over (t0, t0 + dt] and its pair factor
    motion = ConstantVelocity(dim=2, q=0.3)
    F, Q = motion.transition(dt), motion.noise(dt)
    missed, pd_ratio = [], []
    for age, k in zip(sc["age"], sc["reports"], strict=True):
        hazard = (1.0 + k) * math.log1p(dt / (T + age))
        missed.append(math.exp(-p_d * hazard))
        pd_ratio.append(-math.expm1(-p_d * hazard) / dt)
    e = -math.expm1(-p_d / T * dt) / dt * sc["u"]
    rho = sc["lam"] + e
    W = np.zeros((n, len(sc["z"])))
    for i in range(n):
        x, P = F @ sc["x"][i], F @ sc["P"][i] @ F.T + Q
        for j, zj in enumerate(sc["z"]):
            g = math.exp(multivariate_normal(x[:2], P[:2, :2] + 9.0 * np.eye(2)).logpdf(zj))
            W[i, j] = sc["r"][i] * pd_ratio[i] * g / rho
    null = [(1.0 - r) + r * mi for r, mi in zip(sc["r"], missed, strict=True)]
    _, beta, beta0 = brute_assignment(W, null=null)
    for i in range(n):
        r = Fraction(sc["r"][i])
        exists_missed = beta0[i] * r * Fraction(missed[i]) / Fraction(null[i])
        want = float(exists_missed + sum(beta[i]))
        assert math.isclose(trk.existence[i], want, rel_tol=1e-9), (i, trk.existence[i], want)
    share = e / rho
    for j, zj in enumerate(sc["z"]):
        free = 1 - sum(beta[i][j] for i in range(n))
        want = float(free) * share
        hit = np.flatnonzero((trk.x[n:, :2] == zj).all(axis=1))
        got = trk.existence[n + hit[0]] if len(hit) else 0.0
        assert abs(got - want) <= 1e-9 * want + 1e-13 * share, (j, got, want)


# ----------------------------------------------------------------------------- labels


def _crossing_reports(seed=0, n=120):
    """Two targets crossing at the origin at t = 60 s (one 5 m/s east, one 5 m/s north),
    each reporting at its own irregular times with 5 m noise: ``(t, z, label, truth)``."""
    rng = np.random.default_rng(seed)
    rows = []
    for label, v in (("A", (5.0, 0.0)), ("B", (0.0, 5.0))):
        t = 0.0
        while t < 120.0:
            t += rng.exponential(2.0)
            truth = np.array(v) * (t - 60.0)
            rows.append((t, truth + rng.normal(0.0, 5.0, 2), label, truth))
    rows.sort(key=lambda row: row[0])
    return rows[:n]


@pytest.mark.parametrize("kind", [PMBTracker, PMBMTracker])
def test_labelled_targets_that_cross_are_never_swapped(kind):
    trk = kind(_async())
    rows = _crossing_reports()
    for t, z, label, truth in rows:
        trk.step(t, z[None], labels=[label])
        # the track carrying this report's label is at this report (it took it)
        k = np.flatnonzero(trk.labelled_labels == label)
        assert len(k) == 1
        assert np.hypot(*(trk.labelled_x[k[0], :2] - truth)) < 30.0
    ids = {lab: int(trk.labelled_ids[trk.labelled_labels == lab][0]) for lab in "AB"}
    assert ids["A"] != ids["B"]
    hist = trk.history()
    # every reported estimate of id A is nearer target A's truth at its time than B's
    # once they are apart (≥ 140 m: 20 s from the crossing), after as before
    velocity = {"A": (5.0, 0.0), "B": (0.0, 5.0)}
    for lab, other in (("A", "B"), ("B", "A")):
        rows_of = (hist.track_id == ids[lab]) & (np.abs(hist.time - 60.0) >= 20.0)
        assert rows_of.sum() > 20
        lag = hist.time[rows_of] - 60.0
        own = np.hypot(*(hist.x[rows_of, :2] - np.outer(lag, velocity[lab])).T)
        theirs = np.hypot(*(hist.x[rows_of, :2] - np.outer(lag, velocity[other])).T)
        assert (own < theirs).all() and own.max() < 70.0, own.max()
    assert set(np.unique(hist.track_id)) == set(ids.values())


@pytest.mark.parametrize("kind", [PMBTracker, PMBMTracker])
def test_a_labelled_report_updates_only_its_own_bernoulli(kind):
    """A labelled report where an unlabelled Bernoulli is: that Bernoulli is missed,
    exactly as by a scan with no report at all, and the report starts its own."""
    trk = kind(_async(p_survive=1.0))
    trk.step(0.0, np.array([[0.0, 0.0]]))  # an unlabelled Bernoulli at the origin
    trk.step(1.0, np.array([[1.0, 0.0]]))
    twin = kind(trk.config)
    twin._restore(trk.state_dict())
    trk.step(2.0, np.array([[2.0, 0.0]]), labels=["X"])
    twin.step(2.0, np.zeros((0, 2)))
    names = ("x", "P", "existence", "ids") if kind is PMBTracker else (
        "sth_x", "sth_P", "sth_r", "hyp", "hyp_logw", "track_ids")  # fmt: skip
    for name in (*names, "poisson_w", "undetected_density"):
        np.testing.assert_array_equal(getattr(trk, name), getattr(twin, name), name)
    assert trk.labelled_labels.tolist() == ["X"]
    np.testing.assert_array_equal(trk.labelled_x[0, :2], [2.0, 0.0])
    assert trk.labelled_r[0] == trk.config.r_labelled


@pytest.mark.parametrize("kind", [PMBTracker, PMBMTracker])
def test_a_label_takes_back_its_id_after_its_bernoulli_is_gone(kind):
    trk = kind(_async(p_survive=0.9, r_prune=1e-3))
    trk.step(0.0, np.array([[0.0, 0.0]]), labels=["M1"])
    first = int(trk.labelled_ids[0])
    trk.step(1.0, np.array([[5000.0, 0.0]]), labels=["M2"])
    trk.step(400.0, np.array([[9000.0, 0.0]]))  # silence: both labelled Bernoullis die
    assert len(trk.labelled_r) == 0
    res = trk.step(401.0, np.array([[0.0, 10.0]]), labels=["M1"])
    assert trk.labelled_ids.tolist() == [first]
    assert first in res.ids.tolist()


# --------------------------------------------------------------------- velocities


@pytest.mark.parametrize("kind", [PMBTracker, PMBMTracker])
@pytest.mark.parametrize("labelled", [False, True])
def test_reported_velocities_seed_new_bernoullis(kind, labelled):
    cfg = _async(velocity_std=0.25, clutter_density=1e-14, prior_density=1e-6)
    trk = kind(cfg)
    z = np.array([[10.0, 20.0], [500.0, -40.0]])
    v = np.array([[3.0, -4.0], [np.nan, np.nan]])
    trk.step(0.0, z, labels=["A", "B"] if labelled else None, velocities=v)
    if labelled:
        x, P = trk.labelled_x, trk.labelled_P
    else:
        x, P = (trk.x, trk.P) if kind is PMBTracker else (trk.sth_x, trk.sth_P)
    assert len(x) == 2
    seeded = int(np.flatnonzero(x[:, 0] == 10.0)[0])
    np.testing.assert_array_equal(x[seeded, 2:], [3.0, -4.0])
    np.testing.assert_array_equal(P[seeded, 2:, 2:], 0.0625 * np.eye(2))
    np.testing.assert_array_equal(P[seeded, :2, 2:], 0.0)
    # unknown velocity: zero mean, σ = max_speed / 2
    np.testing.assert_array_equal(x[1 - seeded, 2:], 0.0)
    np.testing.assert_array_equal(P[1 - seeded, 2:, 2:], 100.0 * np.eye(2))


@pytest.mark.parametrize("kind", [PMBTracker, PMBMTracker])
def test_bad_report_fields_are_named(kind):
    trk = kind(_async())
    with pytest.raises(ValueError, match="labels must have one entry per report"):
        trk.step(0.0, np.zeros((2, 2)) + [[0, 0], [1, 1]], labels=["A"])
    with pytest.raises(TypeError, match="labels must be strings"):
        trk.step(0.0, np.array([[0.0, 0.0]]), labels=[7])
    with pytest.raises(ValueError, match=r"velocities must have shape \(1, 2\)"):
        trk.step(0.0, np.array([[0.0, 0.0]]), velocities=[[1.0, 2.0, 3.0]])
    with pytest.raises(ValueError, match="velocities has complex entries"):
        trk.step(0.0, np.array([[0.0, 0.0]]), velocities=[[1.0 + 2j, 0.0]])
    assert trk.n_scans == 0  # nothing changed


def test_async_needs_survival_per_second():
    with pytest.raises(ValueError, match="p_survive_per"):
        PMBMConfig(reporting="async", p_survive_per="scan")
    with pytest.raises(ValueError, match="reporting"):
        PMBMConfig(reporting="sometimes")


# ----------------------------------------------------------------------- state files


@pytest.mark.parametrize("kind", [PMBTracker, PMBMTracker])
def test_an_async_labelled_run_saved_and_loaded_continues_identically(kind, tmp_path):
    rows = _crossing_reports(seed=3, n=60)
    trk = kind(_async())
    for k, (t, z, label, _) in enumerate(rows[:40]):
        lab = label if k % 3 else ""  # some reports labelled, some not
        trk.step(t, z[None], labels=[lab], velocities=[[np.nan, np.nan]])
    trk.save(tmp_path / "s.npz")
    again = kind.load(tmp_path / "s.npz")
    for k, (t, z, label, _) in enumerate(rows[40:]):
        lab = label if k % 3 else ""
        a = trk.step(t, z[None], labels=[lab])
        b = again.step(t, z[None], labels=[lab])
        np.testing.assert_array_equal(a.ids, b.ids)
        np.testing.assert_array_equal(a.x, b.x)
        np.testing.assert_array_equal(a.existence, b.existence)


@pytest.mark.parametrize("kind", [PMBTracker, PMBMTracker])
def test_a_version_5_state_is_migrated_and_continues_exactly(kind, tmp_path, monkeypatch):
    """A state written before reporting targets (no born/reports, labelled fields or
    reporting settings) loads as a scanning-sensor run and continues as it would have."""
    cfg = PMBMConfig(clutter_density=1e-4, birth_density=1e-6)
    trk = kind(cfg)
    for t in range(6):
        trk.step(float(t), np.array([[10.0 * t, 0.0], [500.0, 3.0 * t]]))
    new = {"born", "report_count", "sth_born", "sth_reports", *kind._LABELLED}
    new |= {p + k for p in ("", "sth_") for k in ("mode_x", "mode_P", "mode_log_prob")}
    arrays = {k: getattr(trk, trk._attr(k)) for k in kind._ARRAYS if k not in new}
    from jointtrack.trackers.pmbm_config import _ADDED_SETTINGS, ISSUE_33_SETTINGS

    # the settings added in version 6: reporting targets and the IMM (not those of
    # issue 33, added later within version 6)
    added = set(_ADDED_SETTINGS) - {"max_ranking_work"} - set(ISSUE_33_SETTINGS)
    assert {"reporting", "r_labelled", "imm_modes"} <= added
    config = {k: v for k, v in cfg.to_dict().items() if k not in added}
    monkeypatch.setattr(state_io, "VERSION", 5)
    state_io.write_state(
        tmp_path / "old.npz", arrays, config, trk._saved_scalars(), trk.rng.bit_generator.state
    )
    monkeypatch.undo()
    with np.load(tmp_path / "old.npz") as npz:
        assert json.loads(npz["__header__"].tobytes())["version"] == 5
        assert "labelled_r" not in npz.files
    old = kind.load(tmp_path / "old.npz")
    assert old.config == cfg
    for t in range(6, 10):
        z = np.array([[10.0 * t, 0.0], [500.0, 3.0 * t]])
        a, b = trk.step(float(t), z), old.step(float(t), z)
        np.testing.assert_array_equal(a.ids, b.ids)
        np.testing.assert_array_equal(a.x, b.x)
        np.testing.assert_array_equal(a.existence, b.existence)


@pytest.mark.parametrize("kind", [PMBTracker, PMBMTracker])
@pytest.mark.parametrize(
    "field, value, message",
    [
        ("labelled_r", 0.0, "labelled_r"),
        ("labelled_labels", "", "labelled_labels"),
        ("labelled_reports", -1.0, "labelled_reports"),
    ],
)
def test_damaged_labelled_fields_are_refused(kind, field, value, message, tmp_path):
    trk = kind(_async())
    trk.step(0.0, np.array([[0.0, 0.0], [900.0, 0.0]]), labels=["A", "B"])
    state = trk.state_dict()
    arrays = {k: state[k] for k in kind._ARRAYS}
    arrays[field] = arrays[field].copy()
    arrays[field][0] = value
    state_io.write_state(
        tmp_path / "bad.npz", arrays, state["config"], trk._saved_scalars(), state["rng"]
    )
    with pytest.raises(StateFileError, match=f"bad.npz.*{message}"):
        kind.load(tmp_path / "bad.npz")


# ------------------------------------------------------------------------------ CLI


def test_a_report_file_through_the_cli_with_pmbm_writes_lat_lon_tracks(tmp_path):
    """``jointtrack run --detections AIS --tracker pmbm``: accepted (it was refused), the
    asynchronous model stated in the notes, lat/lon tracks that invert to x, y, one
    track per vessel by label."""
    import pymap3d
    from typer.testing import CliRunner

    from jointtrack.cli import app
    from test_run_realdata import SHIPS, write_ais

    rows = write_ais(tmp_path / "full.csv")
    lines = (tmp_path / "full.csv").read_text().splitlines()
    # the first 5 minutes of reports keep the test short
    keep = 1 + sum(1 for r in rows if r[0] - rows[0][0] <= 300.0)
    (tmp_path / "ais.csv").write_text("\n".join(lines[:keep]) + "\n")
    out = tmp_path / "out"
    r = CliRunner().invoke(
        app,
        ["run", "--no-progress", "--detections", str(tmp_path / "ais.csv"), "--tracker", "pmbm",
         "--out", str(out)],
    )  # fmt: skip
    assert r.exit_code == 0, r.output
    m = json.loads((out / "metrics.json").read_text())
    header = (out / "tracks.csv").read_text().splitlines()[0].split(",")
    assert header[:6] == ["time", "track_id", "x", "y", "lat", "lon"]
    table = np.loadtxt(out / "tracks.csv", delimiter=",", skiprows=1, ndmin=2)
    geo = m["geo_reference"]
    e, n, _ = pymap3d.geodetic2enu(table[:, 4], table[:, 5], 0.0, geo["lat"], geo["lon"], 0.0)
    np.testing.assert_allclose(e, table[:, 2], atol=1e-6)
    np.testing.assert_allclose(n, table[:, 3], atol=1e-6)
    s = m["self_reports"]
    assert s["labels"] == "associate" and s["n_identities"] == len(SHIPS[1])
    assert s["tracks_per_identity"] == 1.0 and s["n_id_switches"] == 0, s
    assert s["coverage"] >= 0.95 and s["purity"] >= 0.99, s
    assert any("per second" in note for note in m["notes"]), m["notes"]


@pytest.mark.parametrize("kind", [PMBTracker, PMBMTracker])
def test_a_certain_target_always_detected_has_no_nan(kind):
    """r = 1 and P_D = 1 (P_S = 1): "missed" has probability 0; its existence was 0/0 =
    NaN in the Bernoulli update (existence_update) and the missed-Bernoulli rule."""
    trk = kind(PMBMConfig(p_d=1.0, p_survive=1.0, clutter_density=1e-6, birth_density=0.0,
                          prior_density=1e-7, r_recycle=0.0))  # fmt: skip
    trk.step(0.0, np.array([[0.0, 0.0]]))
    if kind is PMBTracker:
        trk.existence[:] = 1.0
    else:
        trk.sth_r[:] = 1.0
    for t in range(1, 4):
        res = trk.step(float(t), np.array([[float(t), 0.0]]))
        assert np.isfinite(res.x).all() and res.existence.tolist() == [1.0]


@pytest.mark.parametrize("key", ["measure_velocity", "max_coast"])
def test_jpda_only_reporting_keys_are_refused_for_pmb_naming_them(key):
    """[tracker] measure_velocity / max_coast with --tracker pmb|pmbm: the Poisson
    trackers have neither, so the key is refused by name, not silently ignored."""
    from jointtrack.experiments.config import RunConfigError, check_kind_keys

    for kind in ("pmb", "pmbm"):
        with pytest.raises(RunConfigError, match=f"{key}.*{kind} tracker does not have"):
            check_kind_keys(kind, {key: True if key == "measure_velocity" else 60.0}, {}, None)
    check_kind_keys("jipda", {key: True if key == "measure_velocity" else 60.0}, {}, None)
