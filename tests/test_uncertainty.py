"""Uncertainty that covers the truth: Monte Carlo coverage of the 95 % intervals.

Vector level (known covariance, many trials, fast) and chain level (recordings from the second
simulator and impact recordings, covariance estimated from the data themselves)."""

import warnings

import numpy as np
import pytest

import rotorid
from rotorid import RotoridError, pipeline, rawsim
from rotorid.rawsim import PulseShape

RIG = rotorid.nsf_rig()


def _hits_and_z(ident, k, c):
    """Per coefficient and point: whether the 95 % interval holds the truth, and error / std."""
    iv = ident.interval(0.95)
    hits = np.r_[((iv.k_lower <= k) & (k <= iv.k_upper)).ravel(), ((iv.c_lower <= c) & (c <= iv.c_upper)).ravel()]
    z = np.r_[((ident.k - k) / ident.k_std).ravel(), ((ident.c - c) / ident.c_std).ravel()]
    return hits, z


def _vector_mc(rpm, noise_rel, runs, trials=300, seed=0, estimator="ls"):
    rng = np.random.default_rng(seed)
    exact = [rotorid.imbalance_response(RIG.rotor, RIG.bearings, RIG.imbalances[s], speed_rpm=rpm, at="probes")
             for s in runs]
    hits, zs, oks = [], [], []
    for _ in range(trials):
        rs = []
        for r in exact:
            sig = noise_rel * np.sqrt(np.mean(np.abs(r.q) ** 2, axis=1))
            cov = np.eye(8)[None] * (sig ** 2 / 2)[:, None, None]
            q = r.q + (sig / np.sqrt(2))[:, None] * (rng.standard_normal(r.q.shape) + 1j * rng.standard_normal(r.q.shape))
            rs.append(rotorid.SyncResponse(rpm, q, r.imbalance, "probes", r.name, cov))
        i = rotorid.identify_synchronous(RIG.rotor, rs, estimator=estimator)
        iv = i.interval(0.95)
        k, c = RIG.bearings.k, RIG.bearings.c
        hits.append(np.r_[((iv.k_lower <= k) & (k <= iv.k_upper)).ravel(), ((iv.c_lower <= c) & (c <= iv.c_upper)).ravel()])
        zs.append(np.r_[((i.k - k) / i.k_std).ravel(), ((i.c - c) / i.c_std).ravel()])
        oks.append(i.ok)
    return np.mean(hits), np.median(np.abs(zs)), np.mean(zs), np.array(oks)


@pytest.mark.parametrize("runs", ["AB", "ABCD"])
@pytest.mark.parametrize("noise_rel", [0.001, 0.005])
def test_intervals_cover_the_truth_between_the_critical_speeds(runs, noise_rel):
    cover, med, _, _ = _vector_mc(np.array([3800.0, 4200.0, 4600.0, 5000.0]), noise_rel, runs)
    assert 0.93 <= cover <= 0.97, cover
    assert 0.6 <= med <= 0.75, med  # |z| of a standard normal has median 0.674


def test_poorly_conditioned_speeds_are_flagged_where_the_intervals_undercover():
    # below the first critical the runs' responses are nearly parallel (cond ~1e3) and least squares
    # with noisy regressors is biased toward zero: coverage drops to 0.87 with 4 runs (README);
    # such points must not be reported as ok
    cover, _, meanz, oks = _vector_mc(np.array([1000.0, 1500.0, 2000.0]), 0.005, "ABCD", trials=100)
    assert not oks.any()
    assert cover < 0.93 and meanz < -0.2


_LAB_SETS = {"S0": ((5, 5), (0, 0)), "C0": ((5, 5), (0, 180)), "S90": ((5, 5), (90, 90)), "C90": ((5, 5), (90, 270))}


def _lab_recordings(seed, rotor, brg, remnant, speeds, **kw):
    """(runs, baseline, imbalances): 4 imbalance runs and a baseline of the second simulator (2 s
    dwells)."""
    imbalances = [rotorid.Imbalance(tuple(m * 1e-3 for m in v[0]), v[1], name=k) for k, v in _LAB_SETS.items()]
    runs = [rawsim.lab_imbalance_recording(rotor, brg, speeds_rpm=speeds, added=imb, remnant=remnant,
                                           seed=100 * seed + i, dwell_s=2.0, **kw) for i, imb in enumerate(imbalances)]
    base = rawsim.lab_imbalance_recording(rotor, brg, speeds_rpm=speeds, added=None, remnant=remnant,
                                          seed=100 * seed + 9, dwell_s=2.0, **kw)
    return runs, base, imbalances


def _lab_chain(seed, rotor, brg, remnant, speeds, chain_kw=None, **kw):
    """The imbalance chain's result on 4 runs and a baseline of the second simulator (2 s dwells)."""
    runs, base, _ = _lab_recordings(seed, rotor, brg, remnant, speeds, **kw)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return pipeline.imbalance_chain(rotor, runs, baseline=base, **(chain_kw or {}))


def _table_chain(seed, rotor, brg, remnant, speeds, chain_kw, with_cov, **kw):
    """The imbalance chain on the 1X tables of :func:`_lab_recordings`: each recording tracked, its
    keyphasor dropped (a DAQ's 1X export), with or without the tracking's covariance."""
    import dataclasses

    from rotorid import signals

    runs, base, imbalances = _lab_recordings(seed, rotor, brg, remnant, speeds, **kw)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        tables = [dataclasses.replace(signals.track(r), keyphasors=[], **({} if with_cov else dict(cov=None, dof=None)))
                  for r in runs + [base]]
        return pipeline.imbalance_chain(rotor, tables[:-1], baseline=tables[-1], imbalances=imbalances,
                                        **(chain_kw or {}))


def _lab_trial(seed, rotor, brg, remnant, speeds, chain_kw=None, **kw):
    return _lab_chain(seed, rotor, brg, remnant, speeds, chain_kw, **kw).identification


def _lab_coverage(trials, chain_kw=None, **kw):
    """(coverage of the 95 % intervals, median |z|, share of the points ok) over ``trials`` chains
    at 3000-6000 rpm."""
    rotor, brg, remnant = rawsim.example_rig()
    speeds = np.arange(3000, 6001, 500.0)
    hits, zs, ok = [], [], []
    for seed in range(trials):
        ident = _lab_trial(seed, rotor, brg, remnant, speeds, chain_kw, **kw)
        h, z = _hits_and_z(ident, brg.k, brg.c)
        hits.append(h)
        zs.append(z)
        ok.append(ident.ok)
    return np.mean(hits), np.median(np.abs(zs)), np.mean(ok)


def test_imbalance_chain_intervals_from_the_data_cover_the_truth():
    rotor, brg, remnant = rawsim.example_rig()
    speeds = np.arange(3000, 6001, 500.0)
    hits, zs = [], []
    for seed in range(12):
        i = _lab_trial(seed, rotor, brg, remnant, speeds)
        assert i.std_source == "measurement covariance" and np.all(i.dof == 15)
        h, z = _hits_and_z(i, brg.k, brg.c)
        hits.append(h)
        zs.append(z)
    cover, med = np.mean(hits), np.median(np.abs(zs))
    # measured 0.967 and 0.68 (1344 coefficient-speed pairs)
    assert 0.93 <= cover <= 0.975 and 0.6 <= med <= 0.78, (cover, med)


@pytest.mark.parametrize("kp_shape", [PulseShape("rc", 0.7, duty=0.03), PulseShape("rc", 2.0, duty=0.03)],
                         ids=lambda s: f"rc-{s.edge_samples}")
def test_imbalance_chain_intervals_cover_the_truth_with_rc_keyphasor_edges(kp_shape):
    """The same chain with RC-conditioned keyphasor pulses (time constant 0.7 and 2 samples) at
    10,240 Hz, where 3000, 4000 and 6000 rpm put the pulses at 5 positions within a sample. Before
    2026-11-29 (third part) the damping's intervals covered 89 % and 92-93 % (30 trials; 55 % at
    6000 rpm with tau = 0.7, 83 % at 5000 rpm with tau = 2, every point ok): the edge times were
    0.002-0.007 sample off, from the template's linear crossing at 5 positions and a pulse level
    read where an RC top has not settled. Measured now over 30 trials (C / K): 0.965 / 0.964 with tau =
    0.7, 0.965 / 0.963 with tau = 2."""
    cover, med, _ = _lab_coverage(12, kp_shape=kp_shape)
    assert 0.93 <= cover <= 0.98 and 0.6 <= med <= 0.78, (cover, med)


def test_an_applied_phase_calibration_keeps_the_keyphasors_local_timing_uncertainty():
    """RC keyphasor edges of 0.5 sample at 10,240 Hz and a mark 0.3 degree off, the phase
    calibration applied (the CLI's ``phase_calibration = "apply"``). At 3000, 4000 and 6000 rpm the
    pulses fall at 5 positions within a sample and their edges' interpolation error turns the
    vectors by 0.02-0.13 degree, speed by speed and run by run, which theta - Omega tau cannot
    follow. Until 2026-11-29 (fourth part) the calibration was not weighted by that uncertainty (it
    came out 3-8 of its standard errors off, pulled by 3000 rpm) and dropped it once applied: the
    95 % intervals covered 42-48 % of the truth (20 trials). Measured over 20 trials (K / C): 0.988 /
    0.988, median |z| 0.45, 61 % of the points ok, with the local part counted both as common to
    the runs at a speed and as each recording's own; since the calibration's phase scatter between
    speeds stands in for the common copy (fifth part) 0.988 / 0.988, median |z| 0.61, 91 % ok."""
    cover, med, ok = _lab_coverage(12, dict(phase_calibration="apply"), kp_shape=PulseShape("rc", 0.5, duty=0.03),
                                   mark_angle_deg=0.3)
    assert 0.95 <= cover <= 0.999 and 0.3 <= med <= 0.72 and ok >= 0.8, (cover, med, ok)


def test_the_chains_phase_calibration_holds_where_the_keyphasor_is_uncertain_at_most_speeds():
    """The same at 10,000 Hz, where the keyphasor's local timing uncertainty turns 5 of the 7
    speeds "uncertain". Those speeds were left out of the calibration, which then could not be
    made (fewer than 3 speeds, in 20 of 20 trials, with only a note): the mark's 0.3 degree stayed
    in the coefficients (coverage 0.78, 0 at 5500 rpm; found in review). Weighted by their
    standard errors: the calibration is made every time, within 1.1-1.6 of its standard errors
    (2.2-3 when not weighted by the keyphasor's local part), and the intervals cover 0.997."""
    rotor, brg, remnant = rawsim.example_rig()
    speeds = np.arange(3000, 6001, 500.0)
    hits, zcal = [], []
    for seed in range(8):
        res = _lab_chain(seed, rotor, brg, remnant, speeds, dict(phase_calibration="apply"),
                         kp_shape=PulseShape("rc", 0.5, duty=0.03), mark_angle_deg=0.3, fs_hz=10000.0)
        cal = res.phase_calibration
        assert cal is not None, res.notes
        # (the premise: the keyphasor's local part is large at most speeds, 0.2-0.5 degree, which
        # flagged them "uncertain" while it was also counted as common to the runs; every speed takes
        # part in the calibration)
        assert np.sum(res.keyphasor_local_std_deg > 0.15) >= 4 and cal.n_speeds == 7, res.keyphasor_local_std_deg
        om = res.identification.axis * np.pi / 30
        zcal.append(np.max(np.abs(cal.offset_deg - 0.3 - np.rad2deg(om * cal.delay_s)) / cal.phase_std_deg(om * 30 / np.pi)))
        hits.append(_hits_and_z(res.identification, brg.k, brg.c)[0])
    assert np.median(zcal) < 2.0 and np.mean(hits) >= 0.95, (zcal, np.mean(hits))


@pytest.mark.parametrize("with_cov", [True, False], ids=["covariance", "no-covariance"])
def test_an_applied_phase_calibration_of_1x_tables_keeps_their_phase_scatter(with_cov):
    """The runs of the test above as 1X tables (tracked, keyphasor dropped: a DAQ's export), with and
    without the tracking's covariance, the calibration applied. The tables carry the keyphasor's
    timing errors of 3000, 4000 and 6000 rpm but nothing says so; theta - Omega tau cannot follow
    them. Before 2026-11-29 (fifth part) the intervals covered 63 % (77 % of the points flagged ok)
    and 52 % without the covariance (every point ok), 20 trials. The calibration now estimates the
    phase scatter between speeds from its misfit and keeps it: measured over 20 trials 0.89 (0.99 of
    the points ok, 75 % ok) and 0.99 without the covariance (91 % ok)."""
    rotor, brg, remnant = rawsim.example_rig()
    speeds = np.arange(3000, 6001, 500.0)
    hits, hits_ok = [], []
    for seed in range(10):
        res = _table_chain(seed, rotor, brg, remnant, speeds, dict(phase_calibration="apply"), with_cov,
                           kp_shape=PulseShape("rc", 0.5, duty=0.03), mark_angle_deg=0.3)
        ident, cal = res.identification, res.phase_calibration
        assert cal is not None and cal.scatter_deg > 0.01, res.notes
        h = _hits_and_z(ident, brg.k, brg.c)[0].reshape(2, ident.axis.size, -1)
        hits.append(h)
        hits_ok.append(h[:, ident.ok])
    cover, cover_ok = np.mean(hits), np.mean(np.concatenate([h.ravel() for h in hits_ok]))
    assert cover >= (0.8 if with_cov else 0.93) and cover_ok >= 0.93, (cover, cover_ok)


def test_a_reported_phase_calibration_of_1x_tables_keeps_their_phase_scatter_in_the_error_bars():
    """The same 1X tables without a covariance and without a mark offset, the calibration only
    reported (the CLI's default): the phase scatter between speeds it estimates is an uncertainty
    of the vectors as measured, so it enters the error bars while the vectors stay uncorrected.
    Measured over 10 trials: coverage 0.83 with the calibration off, 0.94 reported (the tables'
    common keyphasor delay, which only an applied calibration takes out, is the rest); over these
    6, 0.81 off."""
    rotor, brg, remnant = rawsim.example_rig()
    speeds = np.arange(3000, 6001, 500.0)
    cover = {}
    for mode in ("off", "report"):
        hits = []
        for seed in range(6):
            res = _table_chain(seed, rotor, brg, remnant, speeds, dict(phase_calibration=mode), False,
                               kp_shape=PulseShape("rc", 0.5, duty=0.03))
            hits.append(_hits_and_z(res.identification, brg.k, brg.c)[0])
            if mode == "report":
                assert any("phase scatter between speeds" in n and "reported, not applied" in n for n in res.notes)
        cover[mode] = np.mean(hits)
    assert cover["report"] >= 0.9 and cover["report"] >= cover["off"] + 0.05, cover


def test_impact_chain_intervals_from_single_impact_scatter_cover_the_truth():
    rotor, brg, remnant = rawsim.example_rig()
    hits, zs = [], []
    for seed in range(8):
        recs = [rawsim.impact_recording(rotor, brg, speed_rpm=2000, plane=0.0, direction=d, remnant=remnant,
                                        seed=10 * seed + j, record_s=4.0) for j, d in enumerate("xy")]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            i = pipeline.impact_chain(rotor, recs, band_hz=(20, 120)).identification
        # 5 impacts per test: their scatter's 4 dof, with the truncation term's (also 4) a little more
        # where it counts (Satterthwaite's over two parts of 4 dof lies in 4-8; measured 4.0-4.3)
        assert i.std_source == "measurement covariance" and np.all((i.dof >= 4) & (i.dof <= 8)), i.dof
        h, z = _hits_and_z(i, brg.k, brg.c)
        hits.append(h)
        zs.append(z)
    cover, med = np.mean(hits), np.median(np.abs(zs))
    # measured 0.955 and 0.74 (the median |t| with 4 dof is 0.741)
    assert 0.93 <= cover <= 0.97 and 0.62 <= med <= 0.86, (cover, med)


def test_standard_errors_reach_the_dataframe_and_two_runs_have_them():
    rpm = np.array([4000.0, 4500.0])
    runs = [rotorid.imbalance_response(RIG.rotor, RIG.bearings, RIG.imbalances[s], speed_rpm=rpm) for s in "AB"]
    for r in runs:
        r.cov = np.broadcast_to(np.eye(8) * 1e-14, (2, 8, 8))
    i = rotorid.identify_synchronous(RIG.rotor, runs)
    df = i.to_dataframe()
    assert {"Kxx1_std", "Cyy2_std", "dof", "std_source", "rel_std"} <= set(df.columns)
    assert np.all(df.Kxx1_std > 0) and set(df.std_source) == {"measurement covariance"}


# ---------------------------------------------------------------------------------------------
# bad input


def test_bad_covariances_levels_and_estimators_are_errors():
    rpm = np.array([4000.0, 4500.0])
    r = rotorid.imbalance_response(RIG.rotor, RIG.bearings, RIG.imbalances["A"], speed_rpm=rpm)
    bad = np.broadcast_to(-np.eye(8), (2, 8, 8))
    with pytest.raises(RotoridError, match="positive semi-definite"):
        rotorid.SyncResponse(rpm, r.q, r.imbalance, cov=bad)
    asym = np.broadcast_to(np.eye(8), (2, 8, 8)).copy()
    asym[:, 0, 1] = 1.0
    with pytest.raises(RotoridError, match="symmetric"):
        rotorid.SyncResponse(rpm, r.q, r.imbalance, cov=asym)
    runs = [rotorid.imbalance_response(RIG.rotor, RIG.bearings, RIG.imbalances[s], speed_rpm=rpm) for s in "AB"]
    i = rotorid.identify_synchronous(RIG.rotor, runs)
    for level in (0.0, 1.0, 1.5, "x"):
        with pytest.raises(RotoridError, match="level"):
            i.interval(level)
    with pytest.raises(RotoridError, match="covariance"):
        rotorid.identify_synchronous(RIG.rotor, runs, estimator="bias-corrected")
    with pytest.raises(RotoridError, match="max_rel_std"):
        rotorid.identify_synchronous(RIG.rotor, runs, max_rel_std=np.nan)


def test_unknown_uncertainty_is_nan_with_a_flag_never_zero():
    rpm = np.array([4000.0, 4500.0])
    runs = [rotorid.imbalance_response(RIG.rotor, RIG.bearings, RIG.imbalances[s], speed_rpm=rpm) for s in "AB"]
    # two exact runs without covariance: exactly determined, nothing to estimate an error from
    i = rotorid.identify_synchronous(RIG.rotor, runs)
    assert i.std_source == "none" and np.all(np.isnan(i.k_std)) and np.all(np.isnan(i.interval().k_lower))
    # covariance known at one speed only
    cov = np.stack([np.eye(8) * 1e-17, np.full((8, 8), np.nan)])
    for r in runs:
        r.cov = cov
    i = rotorid.identify_synchronous(RIG.rotor, runs)
    assert np.all(np.isfinite(i.k_std[0])) and np.all(np.isnan(i.k_std[1]))
    assert i.ok[0] and not i.ok[1] and "uncertainty unknown" in i.flag[1]


def test_grid_speeds_between_dwells_are_dropped_not_interpolated():
    rotor, brg, remnant = rawsim.example_rig()
    speeds = np.arange(3000, 6001, 500.0)
    sets = {"S0": ((5, 5), (0, 0)), "C0": ((5, 5), (0, 180)), "S90": ((5, 5), (90, 90)), "C90": ((5, 5), (90, 270))}
    runs = [rawsim.lab_imbalance_recording(rotor, brg, speeds_rpm=speeds, added=rotorid.Imbalance(
        tuple(m * 1e-3 for m in v[0]), v[1], name=k), remnant=remnant, seed=i, dwell_s=1.0)
        for i, (k, v) in enumerate(sets.items())]
    with pytest.warns(UserWarning, match="dropped 2 of 3 grid speed"):
        res = pipeline.imbalance_chain(rotor, runs, speeds_rpm=[3250.0, 4000.0, 4750.0], baseline=None)
    assert res.identification.speed_rpm.tolist() == [4000.0]


def test_covariances_set_after_construction_are_checked_too():
    rpm = np.array([4000.0, 4500.0])
    runs = [rotorid.imbalance_response(RIG.rotor, RIG.bearings, RIG.imbalances[s], speed_rpm=rpm) for s in "AB"]
    for bad, msg in ((np.broadcast_to(-np.eye(8), (2, 8, 8)), "positive semi-definite"), (np.eye(8), "shape"),
                     ("abc", "real array"), (np.broadcast_to(np.eye(8) * np.inf, (2, 8, 8)), "inf"),
                     (np.broadcast_to(np.eye(8) * 1j, (2, 8, 8)), "real array")):
        runs[0].cov = bad
        runs[1].cov = np.broadcast_to(np.eye(8) * 1e-16, (2, 8, 8))
        with pytest.raises(RotoridError, match=msg):
            rotorid.identify_synchronous(RIG.rotor, runs)
    with pytest.raises(RotoridError, match="level"):
        rotorid.identify_synchronous(RIG.rotor, [rotorid.imbalance_response(
            RIG.rotor, RIG.bearings, RIG.imbalances[s], speed_rpm=rpm) for s in "AB"]).interval("0.95")


def test_a_shared_baseline_is_accounted_for():
    # every run minus the same baseline: its error is common to all runs. Treated as independent,
    # the intervals were too wide (median |z| 0.4-0.56); with shared_cov they are calibrated
    rpm = np.array([3800.0, 4200.0, 4600.0, 5000.0])
    imbs = [rotorid.Imbalance((5e-3, 5e-3), (0, 0)), rotorid.Imbalance((5e-3, 5e-3), (0, 180))]
    exact = [rotorid.imbalance_response(RIG.rotor, RIG.bearings, imb, speed_rpm=rpm, at="probes") for imb in imbs]
    rng = np.random.default_rng(1)
    sig = 0.3e-6
    shared = np.broadcast_to(np.eye(8) * sig ** 2 / 2, (4, 8, 8))
    hits, zs = [], []
    for _ in range(150):
        nb = sig / np.sqrt(2) * (rng.standard_normal((4, 4)) + 1j * rng.standard_normal((4, 4)))
        rs = []
        for r in exact:
            nr = 0.1 * sig / np.sqrt(2) * (rng.standard_normal((4, 4)) + 1j * rng.standard_normal((4, 4)))
            rs.append(rotorid.SyncResponse(rpm, r.q + nr - nb, r.imbalance, "probes", None, shared * 1.01))
        i = rotorid.identify_synchronous(RIG.rotor, rs, shared_cov=shared)
        iv = i.interval(0.95)
        k, c = RIG.bearings.k, RIG.bearings.c
        hits.append(np.r_[((iv.k_lower <= k) & (k <= iv.k_upper)).ravel(), ((iv.c_lower <= c) & (c <= iv.c_upper)).ravel()])
        zs.append(np.r_[((i.k - k) / i.k_std).ravel(), ((i.c - c) / i.c_std).ravel()])
    assert 0.93 <= np.mean(hits) <= 0.97 and 0.6 <= np.median(np.abs(zs)) <= 0.75


def test_slow_probe_drift_does_not_pass_for_1x():
    # a ramp plus a 0.3 Hz wander of 2 µm on every probe (thermal growth, a settling probe): it does
    # not close on itself over a revolution and used to leak into 1X as a near-steady error the
    # batch means could not see (coverage 0.81, median |z| 1.05); each revolution's drift ramp is now
    # removed from the revolution means
    rotor, brg, remnant = rawsim.example_rig()
    speeds = np.arange(3000, 6001, 500.0)
    hits, zs = [], []
    for seed in range(8):
        rng = np.random.default_rng(1000 + seed)
        sets = {"S0": ((5, 5), (0, 0)), "C0": ((5, 5), (0, 180)), "S90": ((5, 5), (90, 90)), "C90": ((5, 5), (90, 270))}
        runs = [rawsim.lab_imbalance_recording(rotor, brg, speeds_rpm=speeds, added=rotorid.Imbalance(
            tuple(m * 1e-3 for m in v[0]), v[1], name=k), remnant=remnant, seed=100 * seed + i, dwell_s=2.0)
            for i, (k, v) in enumerate(sets.items())]
        base = rawsim.lab_imbalance_recording(rotor, brg, speeds_rpm=speeds, added=None, remnant=remnant,
                                              seed=100 * seed + 9, dwell_s=2.0)
        for r in runs + [base]:
            for b in r.blocks:
                t = np.arange(b.n_samples) / b.fs_hz
                for ch in ("x1", "x2", "y1", "y2"):
                    b.channels[ch] = b.channels[ch] + 2e-6 * (rng.uniform(-1, 1) * t / t[-1]
                                                              + np.sin(2 * np.pi * 0.3 * t + rng.uniform(0, 6.3)))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            i = pipeline.imbalance_chain(rotor, runs, baseline=base).identification
        h, z = _hits_and_z(i, brg.k, brg.c)
        hits.append(h)
        zs.append(z)
    cover, med = np.mean(hits), np.median(np.abs(zs))
    assert 0.92 <= cover and med <= 0.8, (cover, med)  # measured 0.96 and 0.66 over 12 trials


def _runs_disagree(ident):
    return np.array(["runs disagree beyond their measurement errors" in f for f in ident.flag])


def test_runs_that_disagree_beyond_their_errors_are_flagged_and_consistent_ones_are_not():
    """Four runs with their covariance (0.1 % noise), one of them with a unit mix-up on one channel
    (y2 read in mil as µm: x25.4) or a 10 % gain error there. Found by an independent simulator: K
    off by 150-230 % and C by 100 % with every point ok. The residual-based standard errors are then
    6-30x the propagated ones, and every point is flagged; with consistent noisy runs (2,000 points
    over 200 trials) the flag is (nearly) never raised."""
    rng = np.random.default_rng(5)
    rpm = np.array([3800.0, 4200.0, 4600.0, 5000.0, 6000.0, 7000.0, 8000.0, 9000.0, 10000.0, 11000.0])
    exact = [rotorid.imbalance_response(RIG.rotor, RIG.bearings, RIG.imbalances[s], speed_rpm=rpm, at="probes")
             for s in "ABCD"]

    def noisy():
        out = []
        for r in exact:
            sig = 0.001 * np.sqrt(np.mean(np.abs(r.q) ** 2, axis=1))
            cov = np.eye(8)[None] * (sig ** 2 / 2)[:, None, None]
            q = r.q + (sig / np.sqrt(2))[:, None] * (rng.standard_normal(r.q.shape) + 1j * rng.standard_normal(r.q.shape))
            out.append(rotorid.SyncResponse(rpm, q, r.imbalance, "probes", r.name, cov))
        return out

    flagged = 0
    for _ in range(200):
        flagged += _runs_disagree(rotorid.identify_synchronous(RIG.rotor, noisy())).sum()
    assert flagged <= 1, flagged  # chance exceedances: below 3e-7 per point at 4 runs
    for gain in (25.4, 1.1):
        rs = noisy()
        mixed = rs[1].q.copy()
        mixed[:, 3] *= gain
        rs[1] = rotorid.SyncResponse(rpm, mixed, rs[1].imbalance, "probes", rs[1].name, rs[1].cov)
        i = rotorid.identify_synchronous(RIG.rotor, rs)
        assert _runs_disagree(i).all() and not i.ok.any(), gain


def _nsf_runs(rpm, noise=1e-9):
    rig = rotorid.nsf_rig()
    runs = [rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances[s], speed_rpm=rpm) for s in "ABCD"]
    for r in runs:
        r.cov = np.broadcast_to(np.eye(8) * noise ** 2, (rpm.size, 8, 8)).copy()
    return rig, runs


def test_phase_reference_uncertainty_matches_monte_carlo_of_a_common_delay():
    """A keyphasor timing error is a phase error Omega tau common to every run and channel: it
    leaves no residual, yet on the NSF rig 2 µs moves the damping by percents. Its propagated
    standard error (central differences of the estimator) must match the spread of identifications
    from vectors turned by random delays; and an angle of Omega tau per speed must be the same."""
    rpm = np.array([3000.0, 4000.0, 5000.0, 6000.0])
    rig, runs = _nsf_runs(rpm)
    tau = 2e-6
    plain = rotorid.identify_synchronous(rig.rotor, runs)
    ident = rotorid.identify_synchronous(rig.rotor, runs, keyphasor_delay_std_s=tau)
    assert ident.std_source == "measurement covariance + phase reference" and plain.std_source == \
        "measurement covariance"
    np.testing.assert_array_equal(ident.k, plain.k)
    # the phase reference's part alone
    part_k = np.sqrt(ident.k_std ** 2 - plain.k_std ** 2)
    part_c = np.sqrt(ident.c_std ** 2 - plain.c_std ** 2)
    assert part_c[-1, 0, 0, 0] > 0.02 * 2000.0  # damping: over 2 % at 6,000 rpm
    rng = np.random.default_rng(3)
    d = rng.standard_normal(300) * tau
    ks, cs = [], []
    for dt in d:
        turned = [rotorid.SyncResponse(r.speed_rpm, r.q * np.exp(-1j * r.speed_rpm * np.pi / 30 * dt)[:, None],
                                       r.imbalance) for r in runs]
        one = rotorid.identify_synchronous(rig.rotor, turned)
        ks.append(one.k)
        cs.append(one.c)
    # linear in the delay: the spread is the delays' spread times |g| exactly, to second order
    scale = d.std() / tau
    np.testing.assert_allclose(np.std(ks, axis=0), scale * part_k, rtol=0.02)
    np.testing.assert_allclose(np.std(cs, axis=0), scale * part_c, rtol=0.02)
    # the covariance carries it too, and the per-speed angle form is the same uncertainty
    from rotorid.uncertainty import report_vector

    np.testing.assert_allclose(np.sqrt(np.diagonal(ident.cov, axis1=1, axis2=2)), report_vector(ident.k_std, ident.c_std),
                               rtol=1e-12)
    angle = rotorid.identify_synchronous(rig.rotor, runs, keyphasor_angle_std_deg=np.rad2deg(rpm * np.pi / 30 * tau))
    np.testing.assert_allclose(angle.c_std, ident.c_std, rtol=1e-12)


def test_phase_reference_uncertainty_flags_damping_it_leaves_unknown():
    """A mark angle known to 1 degree: the damping is then uncertain beyond max_rel_std at speeds
    where it hangs on the phase, and those points are flagged, not ok."""
    rpm = np.array([3000.0, 6000.0])
    rig, runs = _nsf_runs(rpm)
    ident = rotorid.identify_synchronous(rig.rotor, runs, keyphasor_angle_std_deg=1.0)
    assert not ident.ok.all() and all("uncertain" in f for f in ident.flag[~ident.ok])
    assert rotorid.identify_synchronous(rig.rotor, runs).ok.all()


@pytest.mark.parametrize("kw, match", [
    (dict(keyphasor_delay_std_s=-1e-6), "keyphasor_delay_std_s"),
    (dict(keyphasor_delay_std_s="2 us"), "keyphasor_delay_std_s"),
    (dict(keyphasor_delay_std_s=2.0), "45 degrees or more.*unit error"),
    (dict(keyphasor_angle_std_deg=[1.0, 2.0, 3.0]), "one per speed"),
    (dict(keyphasor_angle_std_deg=float("nan")), "keyphasor_angle_std_deg"),
    (dict(keyphasor_angle_std_deg=50.0), "below 45"),
])
def test_phase_reference_uncertainty_bad_inputs(kw, match):
    rig, runs = _nsf_runs(np.array([3000.0, 6000.0]))
    with pytest.raises(RotoridError, match=match):
        rotorid.identify_synchronous(rig.rotor, runs, **kw)


def test_phase_reference_uncertainty_holds_where_a_coefficient_hardly_moves_to_first_order():
    """Near 6,500 rpm on the NSF rig dK/dalpha nearly vanishes: first-order propagation gave half
    the spread of K at 2 degrees and a 10th-24th of it at 20 (found in review). Sigma points at
    +-sigma with their second difference follow the Monte Carlo of random common turns."""
    rpm = np.array([3500.0, 6500.0])
    rig, runs = _nsf_runs(rpm)
    plain = rotorid.identify_synchronous(rig.rotor, runs)
    rng = np.random.default_rng(5)
    for deg in (2.0, 20.0):
        ident = rotorid.identify_synchronous(rig.rotor, runs, keyphasor_angle_std_deg=deg)
        part = np.sqrt(ident.k_std ** 2 - plain.k_std ** 2)
        ks = [rotorid.identify_synchronous(rig.rotor, [rotorid.SyncResponse(
            r.speed_rpm, r.q * np.exp(1j * a)[:, None], r.imbalance) for r in runs]).k
            for a in np.deg2rad(deg) * rng.standard_normal((400, rpm.size))]
        ratio = np.std(ks, axis=0)[:, :, [0, 1], [0, 1]] / part[:, :, [0, 1], [0, 1]]
        assert np.all((ratio > 0.8) & (ratio < 1.25)), (deg, ratio)


def test_a_stated_phase_uncertainty_raises_the_degrees_of_freedom_of_estimated_errors():
    """Residual-based errors of 3 runs have 2 degrees of freedom (t = 4.3 at 95 %); the stated
    phase uncertainty is known, so by Welch-Satterthwaite the total's degrees of freedom grow by
    (total / estimated variance)², the smallest over the point's coefficients."""
    rig = rotorid.nsf_rig()
    rpm = np.array([3000.0, 4500.0, 6000.0])
    runs = [rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances[s], speed_rpm=rpm) for s in "ABC"]
    rng = np.random.default_rng(2)
    for r in runs:
        r.q = r.q + 1e-8 * (rng.standard_normal(r.q.shape) + 1j * rng.standard_normal(r.q.shape))
    plain = rotorid.identify_synchronous(rig.rotor, runs)
    ident = rotorid.identify_synchronous(rig.rotor, runs, keyphasor_angle_std_deg=0.5)
    assert plain.std_source == "residual" and np.all(plain.dof == 2.0)
    grow = np.concatenate([(ident.k_std ** 2 / plain.k_std ** 2).reshape(3, -1),
                           (ident.c_std ** 2 / plain.c_std ** 2).reshape(3, -1)], axis=1) ** 2
    np.testing.assert_allclose(ident.dof, 2.0 * grow.min(axis=1), rtol=1e-12)
    assert np.all(ident.dof > 2.0)
