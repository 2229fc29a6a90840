"""Runs measured at slightly different speeds: carried to common speeds through the rotor model
(rotorid.speed_offsets), in the API (identify_synchronous) and in the imbalance chain."""
import warnings

import numpy as np
import pytest

import rotorid
from rotorid import example as ex
from rotorid import pipeline, rawsim
from rotorid.errors import RotoridError
from rotorid.signals import SyncTrack
from rotorid.speed_offsets import carry_matrix

ROTOR, BRG, REMNANT = rawsim.example_rig()
RPM = np.arange(3000.0, 6001.0, 250.0)
SETS = [rotorid.Imbalance(tuple(m * 1e-3 for m in mg), ang, name=n) for n, (mg, ang) in ex.SETS.items()]
DIRECT = [(b, i, i) for b in range(2) for i in range(2)]


def _offset_speeds(rng, spread, n=RPM.size):
    return RPM[:n] * (1.0 + rng.uniform(-spread, spread, n))


def _runs(rng, spread, noise=0.0, n_runs=4, own=True):
    """Imbalance runs, each at its own speeds within ±spread of RPM, with white noise of ``noise``
    m per component and that covariance (None when noise-free)."""
    out = []
    for imb in SETS[:n_runs]:
        sp = _offset_speeds(rng, spread)
        q = rotorid.imbalance_response(ROTOR, BRG, imb, speed_rpm=sp, at="probes").q
        cov = dof = None
        if noise:
            q = q + noise * (rng.standard_normal(q.shape) + 1j * rng.standard_normal(q.shape))
            cov = np.broadcast_to(np.eye(8) * noise ** 2, (RPM.size, 8, 8)).copy()
            dof = np.full(RPM.size, 100.0)
        out.append(rotorid.SyncResponse(sp if own else RPM, q, imb, "probes", cov=cov, dof=dof))
    return out


@pytest.mark.parametrize("at", ["bearings", "probes"])
def test_carry_matrix_moves_an_imbalance_response_to_another_speed_exactly(at):
    """T = (Ω/Ω_r)² H(Ω) H(Ω_r)⁻¹ carries any imbalance response (added or remnant, any planes)
    from Ω_r to Ω: against the forward model at both speeds."""
    src = RPM * 1.004
    T, bad = carry_matrix(ROTOR, BRG.k[None], BRG.c[None], src, RPM, at=at)
    assert not bad.any()
    for imb in SETS + [REMNANT]:
        q_src = rotorid.imbalance_response(ROTOR, BRG, imb, speed_rpm=src, at=at).q
        q_dst = rotorid.imbalance_response(ROTOR, BRG, imb, speed_rpm=RPM, at=at).q
        np.testing.assert_allclose(np.einsum("nij,nj->ni", T, q_src), q_dst, rtol=1e-10, atol=1e-9 * np.abs(q_dst).max())
    # a point whose coefficients are unknown is not carried (T = I) and says so
    k = np.broadcast_to(BRG.k, (RPM.size, 2, 2, 2)).copy()
    k[3, 0, 0, 0] = np.nan
    T, bad = carry_matrix(ROTOR, k, BRG.c[None], src, RPM, at=at)
    assert bad.tolist() == [i == 3 for i in range(RPM.size)]
    np.testing.assert_array_equal(T[3], np.eye(4))


def test_runs_at_their_own_speeds_are_identified_exactly():
    """Noise-free runs ±0.25 % apart: identified as if at one speed the direct damping is up to
    tens of percent off near the critical speeds (21 % in this set); given at their own speeds they
    are carried to the mean and the truth comes out."""
    rng = np.random.default_rng(3)
    own = _runs(rng, 0.0025)
    as_one = [rotorid.SyncResponse(RPM, r.q, r.imbalance, "probes") for r in own]
    naive = rotorid.identify_synchronous(ROTOR, as_one)
    err = max(np.abs(naive.c[:, b, i, j] / BRG.c[b, i, j] - 1).max() for b, i, j in DIRECT)
    assert err > 0.05, err
    ident = rotorid.identify_synchronous(ROTOR, own)
    np.testing.assert_allclose(ident.axis, np.mean([r.speed_rpm for r in own], axis=0))
    np.testing.assert_allclose(ident.k, np.broadcast_to(BRG.k, ident.k.shape), rtol=1e-7)
    np.testing.assert_allclose(ident.c, np.broadcast_to(BRG.c, ident.c.shape), rtol=1e-6)
    assert ident.ok.all(), ident.flag


@pytest.mark.parametrize("n_runs,spread", [(2, 0.0025), (4, 0.0025)])
def test_carried_runs_error_bars_cover_as_runs_at_one_speed(n_runs, spread):
    """Monte Carlo: 95 % intervals of runs at their own speeds (carried) cover the truth as often
    as those of runs all taken at one speed (measured 0.956 / 0.957, the same draws at one speed
    0.955 / 0.957); identified as if at one speed they covered 0.878 / 0.698."""
    hits, hits_same = [], []
    for t in range(30):
        for spread_t, out in ((spread, hits), (0.0, hits_same)):
            runs = _runs(np.random.default_rng(1000 + t), spread_t, noise=0.07e-6, n_runs=n_runs)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                ident = rotorid.identify_synchronous(ROTOR, runs)
            iv = ident.interval(0.95)
            k0, c0 = BRG.k[None], BRG.c[None]
            out.append(np.concatenate([((iv.k_lower <= k0) & (k0 <= iv.k_upper)).ravel(),
                                       ((iv.c_lower <= c0) & (c0 <= iv.c_upper)).ravel()]))
    cover, same = np.concatenate(hits).mean(), np.concatenate(hits_same).mean()
    assert 0.93 <= cover <= 0.98 and abs(cover - same) < 0.01, (cover, same)


def test_speed_offsets_that_do_not_settle_are_flagged(monkeypatch):
    """A carry stopped before it settles (here after one pass) flags its points and warns, naming
    the speeds."""
    from rotorid import speed_offsets

    monkeypatch.setattr(speed_offsets, "MAX_PASSES", 1)
    runs = _runs(np.random.default_rng(3), 0.0025)
    with pytest.warns(UserWarning, match=r"did not settle at 2998, 3252, .* rpm \(flagged \"speed offsets not resolved\"\)"):
        ident = rotorid.identify_synchronous(ROTOR, runs)
    assert not ident.ok.any()
    assert all("speed offsets not resolved" in f for f in ident.flag)


def test_runs_at_different_speeds_are_refused_with_what_to_do():
    rng = np.random.default_rng(1)
    runs = _runs(rng, 0.0, n_runs=2)
    far = rotorid.SyncResponse(RPM * 1.03, runs[1].q, runs[1].imbalance, "probes")
    with pytest.raises(RotoridError, match=r"speed_rpm of run 1 \('C0'\) differs from that of run 0 \('S0'\): 3090.00 "
                                           r"against 3000.00 rpm, 1.48 % .*max_speed_offset = 0.5 %"):
        rotorid.identify_synchronous(ROTOR, [runs[0], far])
    # allowed farther when asked, to 5 %
    rotorid.identify_synchronous(ROTOR, [runs[0], far], max_speed_offset=0.02)
    with pytest.raises(RotoridError, match=r"max_speed_offset must be at most 5 % .* got 0.2"):
        rotorid.identify_synchronous(ROTOR, [runs[0], far], max_speed_offset=0.2)
    short = rotorid.SyncResponse(RPM[:-1] * 1.001, runs[1].q[:-1], runs[1].imbalance, "probes")
    with pytest.raises(RotoridError, match="has 12 speeds, run 0 .* 13"):
        rotorid.identify_synchronous(ROTOR, [runs[0], short])
    for bad in (-0.01, np.nan, "1%"):
        with pytest.raises(RotoridError, match="max_speed_offset"):
            rotorid.identify_synchronous(ROTOR, [runs[0], _runs(rng, 0.001, n_runs=2)[1]], max_speed_offset=bad)


def test_what_cannot_be_carried_is_refused():
    """Pedestal motion and a shared (baseline) covariance need the runs at one speed."""
    rng = np.random.default_rng(2)
    runs = _runs(rng, 0.002, noise=0.05e-6, n_runs=2)
    with pytest.raises(RotoridError, match="shared_cov is given but the runs' speeds differ"):
        rotorid.identify_synchronous(ROTOR, runs, shared_cov=runs[0].cov)
    ped = rotorid.example_pedestals()
    pr = [rotorid.imbalance_response(ROTOR, BRG, imb, speed_rpm=RPM * f, at="probes", pedestals=ped)
          for imb, f in zip(SETS[:2], (1.0, 1.001))]
    with pytest.raises(RotoridError, match="pedestal motion must be given at the same speeds"):
        rotorid.identify_synchronous(ROTOR, pr)


def _table(imbs, speeds, rng, noise, runout=0.0):
    q = sum(rotorid.imbalance_response(ROTOR, BRG, imb, speed_rpm=speeds, at="probes").q for imb in imbs) + runout
    q = q + noise * (rng.standard_normal(q.shape) + 1j * rng.standard_normal(q.shape))
    n = speeds.size
    return SyncTrack(speeds, q[:, None, :], (1,), np.full(n, 100), np.full((n, 4), np.nan), np.arange(n) * 10.0,
                     cov=np.broadcast_to(np.eye(8) * noise ** 2, (n, 8, 8)).copy(), dof=np.full(n, 100.0))


def _chain_draw(seed, spread, noise=0.035e-6, runout=0.0, **kw):
    rng = np.random.default_rng(seed)
    rpm = np.arange(3000.0, 6001.0, 500.0)
    runs = [_table([imb, REMNANT], rpm * (1 + rng.uniform(-spread, spread, rpm.size)), rng, noise, runout)
            for imb in SETS]
    base = _table([REMNANT], rpm * (1 + rng.uniform(-spread, spread, rpm.size)), rng, noise, runout)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return pipeline.imbalance_chain(ROTOR, runs, baseline=base, imbalances=SETS, **kw)


def test_chain_carries_runs_and_baseline_measured_at_their_own_dwell_speeds():
    """Dwells ±0.25 % apart (±15 rpm at 6000 rpm) in every run and the baseline: with the default
    matching every speed is kept (2 rpm dropped them, and a baseline that missed a run's end speed
    stopped the chain), the baseline is carried with the runs, and the coefficients are those of
    the same draw's runs all taken at the nominal speeds to within their error bars."""
    res = _chain_draw(7, 0.0025)
    ident = res.identification
    assert ident.axis.size == 7
    assert any("carried to them through the rotor" in n for n in res.notes), res.notes
    same = _chain_draw(7, 0.0).identification
    assert not any("carried" in n for n in _chain_draw(7, 0.0).notes)
    for b, i, j in DIRECT:
        dk = np.abs(ident.k[:, b, i, j] - same.k[:, b, i, j]) / ident.k_std[:, b, i, j]
        assert dk.max() < 1.0, dk
    # the 95 % intervals hold the truth over draws (measured 0.958 over 20 draws, as the same
    # draws at the nominal speeds)
    hits = []
    for seed in range(20):
        iv = _chain_draw(100 + seed, 0.0025).identification.interval(0.95)
        hits.append(np.concatenate([((iv.k_lower <= BRG.k) & (BRG.k <= iv.k_upper)).ravel(),
                                    ((iv.c_lower <= BRG.c) & (BRG.c <= iv.c_upper)).ravel()]))
    assert np.concatenate(hits).mean() > 0.92


def test_chain_with_a_tolerance_of_the_users_drops_what_lies_beyond_it():
    """speed_match_rpm given: dwells farther than it from every dwell of another run are dropped
    with a warning, as before."""
    rng = np.random.default_rng(5)
    rpm = np.arange(3000.0, 6001.0, 500.0)
    runs = [_table([imb], rpm * np.where(np.arange(rpm.size) == 3, 1.004, 1.0), rng, 0.03e-6) for imb in SETS[:2]]
    runs[0] = _table([SETS[0]], rpm, rng, 0.03e-6)
    with pytest.warns(UserWarning, match="dropped"):
        res = pipeline.imbalance_chain(ROTOR, runs, imbalances=SETS[:2], speed_match_rpm=2.0)
    assert res.identification.axis.size == 6


def test_chain_default_tolerance_is_relative_to_each_speed():
    """The default matching tolerance is 0.5 % of each grid speed: a run 25 rpm off at 6000 rpm (0.4 %)
    is carried, where a fixed 2 rpm dropped it, and a slow dwell in the runs (600 rpm) does not
    shrink the tolerance of the others."""
    rng = np.random.default_rng(11)
    rpm = np.array([600.0, 3000.0, 4500.0, 6000.0])
    runs = [_table([imb], rpm + np.array([0.0, 5.0, -10.0, 25.0]) * (k % 2), rng, 0.02e-6)
            for k, imb in enumerate(SETS)]
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        res = pipeline.imbalance_chain(ROTOR, runs, imbalances=SETS)
    assert not any("dropped" in str(w.message) for w in seen), [str(w.message) for w in seen]
    assert res.identification.axis.size == 4
    np.testing.assert_allclose(res.identification.axis, rpm + np.array([0.0, 2.5, -5.0, 12.5]))
    with pytest.warns(UserWarning, match="dropped"):
        fixed = pipeline.imbalance_chain(ROTOR, runs, imbalances=SETS, speed_match_rpm=2.0)
    assert fixed.identification.axis.size == 1


RUNOUT = 3 * np.array([4e-6 * np.exp(0.5j), 3e-6 * np.exp(2.0j), 4e-6 * np.exp(-1.0j), 2e-6 * np.exp(1.2j)])


def _coverage(draws):
    hits = []
    for res in draws:
        iv = res.identification.interval(0.95)
        hits.append(np.concatenate([((iv.k_lower <= BRG.k) & (BRG.k <= iv.k_upper)).ravel(),
                                    ((iv.c_lower <= BRG.c) & (BRG.c <= iv.c_upper)).ravel()]))
    return np.concatenate(hits).mean()


def test_run_out_without_a_slow_roll_is_estimated_from_the_baseline_before_carrying(monkeypatch):
    """Run-out (6-12 µm, the same at every speed) in runs and baseline, no slow roll: subtracting
    the baseline cancels it only at one speed; carried with the response, (T_r - T_b) R stayed (an
    independent simulator's ±0.25 % offsets with 4 µm: 0.845 coverage on ok points, 55 % of points
    ok). It is now estimated from the baseline's dwells (q_b = Ω² H u + R over the speeds) and
    taken out first: the estimate within 1 % of the truth, coverage as without run-out (runs ±0.25
    % apart, 20 draws: 0.943, as with no run-out; without the estimate 0.875)."""
    from rotorid import speed_offsets

    res = _chain_draw(3, 0.0025, runout=RUNOUT)
    note = next(n for n in res.notes if n.startswith("1X run-out estimated from the baseline"))
    est = np.array([float(x.split()[1]) for x in note.split(": ")[1].split(", ")]) * 1e-6
    np.testing.assert_allclose(est, np.abs(RUNOUT), rtol=0.01)
    assert _coverage(_chain_draw(200 + s, 0.0025, runout=RUNOUT) for s in range(20)) > 0.92
    # without the estimate (too few speeds, here forced): warned, and the run-out spoils the bars
    monkeypatch.setattr(speed_offsets, "RUNOUT_MIN_SPEEDS", 100)
    rng = np.random.default_rng(3)
    rpm = np.arange(3000.0, 6001.0, 500.0)
    runs = [_table([imb, REMNANT], rpm * (1 + rng.uniform(-0.0025, 0.0025, rpm.size)), rng, 0.035e-6, RUNOUT)
            for imb in SETS]
    base = _table([REMNANT], rpm * 1.002, rng, 0.035e-6, RUNOUT)
    with pytest.warns(UserWarning, match="too few speeds .* to estimate the run-out from the baseline"):
        pipeline.imbalance_chain(ROTOR, runs, baseline=base, imbalances=SETS)
    assert _coverage(_chain_draw(200 + s, 0.0025, runout=RUNOUT) for s in range(20)) < 0.9


def test_a_dwell_split_by_its_wandering_speed_is_one_grid_speed():
    """A dwell whose speed moved beyond speed_tolerance within it comes out of the tracker as two
    blocks a few rpm apart: each became a grid speed of its own, reusing the other runs' one dwell
    (the same data counted twice, both points ok; review, 1 of 12 trials). Now one grid speed, the
    longest block of each run, and a warning that names the split."""
    rpm_of = [[3000.0, 3012.0, 4000.0, 5000.0], [3010.0, 4010.0, 5010.0], [2995.0, 3995.0, 4995.0]]
    runs = [rawsim.imbalance_recording(ROTOR, BRG, speeds_rpm=sp, added=imb, remnant=REMNANT, seed=30 + i,
                                       dwell_s=1.5 if i else 1.0)
            for i, (sp, imb) in enumerate(zip(rpm_of, SETS))]
    base = rawsim.imbalance_recording(ROTOR, BRG, speeds_rpm=[3005.0, 4005.0, 5005.0], added=None, remnant=REMNANT,
                                      seed=39, kind="baseline", dwell_s=1.5)
    with pytest.warns(UserWarning, match=r"run 0: dwells split by a speed change within them, the longest block "
                                         r"used: \d+ rpm \(2 blocks"):
        # (a tracker tolerance of ±0.3 % splits the 0.4 % step; the runs match within 0.5 %)
        res = pipeline.imbalance_chain(ROTOR, runs, baseline=base, speed_tolerance=0.003)
    ident = res.identification
    assert ident.axis.size == 3 and np.all(np.abs(ident.axis - [3005, 4005, 5005]) < 8), ident.axis
    for b, i, j in DIRECT:
        assert np.all(np.abs(ident.k[:, b, i, j] / BRG.k[b, i, j] - 1) < 0.05)


def test_points_where_the_carry_runs_away_do_not_spoil_the_others():
    """Far below the critical speeds the identification is so ill-conditioned that the carry's own
    error grows from pass to pass (review: runs ±0.99 % apart, a 2000 rpm vector went from 16 µm to
    9 cm, and every other point became "low amplitude" beside it). Such points are carried by
    (Ω/Ω_r)² alone and flagged; the others are exact."""
    grid = np.array([1000.0, 2000.0, 3000.0, 3300.0, 3600.0, 4000.0, 5000.0, 6000.0, 7000.0, 8000.0])
    runs = []
    for i, imb in enumerate(SETS):
        s = grid * (1 + (0.0099 if i % 2 == 0 else -0.0099))
        runs.append(rotorid.SyncResponse(s, rotorid.imbalance_response(ROTOR, BRG, imb, speed_rpm=s).q, imb))
    with pytest.warns(UserWarning, match="did not settle at 1000, 2000 rpm"):
        ident = rotorid.identify_synchronous(ROTOR, runs, max_speed_offset=0.01)
    assert ["speed offsets not resolved" in f for f in ident.flag] == [True, True] + [False] * 8
    assert ident.ok[2:].all(), ident.flag
    np.testing.assert_allclose(ident.c[2:], np.broadcast_to(BRG.c, ident.c[2:].shape), rtol=1e-5)
