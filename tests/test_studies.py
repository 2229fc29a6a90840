"""Monte Carlo studies (rotorid.studies): the core's one-pass statistics against the same trials
identified one by one through the public API, reproducibility (seeds, threads, task sizes),
statistical calibration against the first-order uncertainty, interval coverage, test design, and
bad input. No timing here (benches/bench_study.py measures speed)."""

import subprocess
import sys

import numpy as np
import pytest

import rotorid
from rotorid import RotoridError
from rotorid.identify import identify_impact, identify_synchronous
from rotorid.model import _REPORT_TO_BIJ
from rotorid.simulate import RPM, ImpactResponse, SyncResponse
from rotorid.studies import (ImpactErrors, SyncErrors, TrialMassRig, bin_edges, design_impact_plan,
                             design_trial_masses, expected_error, frf_random_error, impact_study,
                             percentiles_from_counts, synchronous_study)
from rotorid.studies import monte_carlo as mc

RIG = rotorid.nsf_rig()
RUNS = [RIG.imbalances[s] for s in "ABCD"]
RPM_GOOD = np.linspace(3800.0, 5600.0, 7)  # between the critical speeds: well conditioned
ALL_SYNC = SyncErrors(amplitude_rel=0.01, phase_deg=0.5, noise_m=0.05e-6, keyphasor_deg=0.2, channel_delay_s=5e-6,
                      probe_position_m=0.5e-3, trial_mass_rel=0.02, trial_angle_deg=1.0, speed_rel=0.002)


def _truth(bearings, n):
    k = np.broadcast_to(bearings.k.reshape(1, 8), (n, 8))
    c = np.broadcast_to(bearings.c.reshape(1, 8), (n, 8))
    return np.concatenate([k[:, _REPORT_TO_BIJ], c[:, _REPORT_TO_BIJ]], 1)


def _spec(errors, rpm=RPM_GOOD, seed=3, at="probes", runs=RUNS):
    from rotorid.simulate import _core_coeffs

    r = RIG.rotor
    kb, cb = _core_coeffs(RIG.bearings, rpm.size, speed_rpm=rpm)
    return mc._Spec(kind="imbalance", rotor_params=r.core_params(), w=rpm * RPM, kb=kb, cb=cb,
                    probes_z=mc._probes_z(r, at), planes_z=np.array([-r.d[0], r.d[1]]), errors=errors.core_array(),
                    u=np.array([i.forcing(r) for i in runs]), dirs=None, spin=0.0, method="forces", seed=seed)


def _public_errors(spec, trials, runs=RUNS, at="probes"):
    """The same trials identified one at a time through identify_synchronous: (trials, n, 16)."""
    out = []
    for t in range(trials):
        q, w_told = spec.realize(t, t + 1)
        rs = [SyncResponse(w_told[0] / RPM, q[0, i], imbalance=imb, at=at) for i, imb in enumerate(runs)]
        out.append(identify_synchronous(RIG.rotor, rs).report_vector())
    truth = _truth(RIG.bearings, spec.w.size)
    return (np.array(out) - truth) / np.abs(truth)


def test_exact_data_give_rounding_level_errors():
    res = synchronous_study(RIG.rotor, RIG.bearings, RUNS, RPM_GOOD, trials=64)
    assert np.all(np.abs(res.pct) < 1e-7) and np.all(np.abs(res.mean) < 1e-7)
    assert np.all(res.singular == 0)
    imp = impact_study(RIG.rotor, RIG.bearings, [(0.0, "x"), (0.0, "y")], np.linspace(10, 150, 8), speed_rpm=1000,
                       trials=64)
    assert np.all(np.abs(imp.pct) < 1e-7)


def test_realized_measurements_are_the_exact_responses_without_errors():
    spec = _spec(SyncErrors())
    q, w = spec.realize(0, 2)
    for r, imb in enumerate(RUNS):
        ref = rotorid.imbalance_response(RIG.rotor, RIG.bearings, imb, speed_rpm=RPM_GOOD, at="probes").q
        np.testing.assert_allclose(q[1, r], ref, rtol=0, atol=1e-13 * np.abs(ref).max())
    np.testing.assert_array_equal(w[1], RPM_GOOD * RPM)


def test_one_pass_statistics_equal_the_public_identification_of_the_same_trials():
    errors = ALL_SYNC
    trials = 300
    res = synchronous_study(RIG.rotor, RIG.bearings, RUNS, RPM_GOOD, errors, trials=trials, seed=3,
                            keep_histograms=True)
    e = _public_errors(_spec(errors, seed=3), trials)  # (trials, n, 16)
    np.testing.assert_allclose(res.mean, e.mean(0), rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(res.rms, np.sqrt((e ** 2).mean(0)), rtol=1e-9)
    # histograms: every trial's error in the bin whose edges hold it
    edges = bin_edges()
    counts = np.stack([np.stack([np.histogram(e[:, i, o], bins=edges)[0] for o in range(16)])
                       for i in range(RPM_GOOD.size)])
    assert np.abs(counts.astype(int) - res.counts.astype(int)).sum() <= 2  # a value on a bin edge at most
    # percentiles in the bin of the exact sample quantile (inverted CDF) or its neighbour
    exact = np.percentile(e, [5, 50, 95], axis=0, method="inverted_cdf")
    b_exact = np.searchsorted(edges, exact, side="right") - 1
    b_ours = np.searchsorted(edges, res.pct, side="right") - 1
    assert np.abs(b_exact - b_ours).max() <= 1


def test_measurements_follow_the_specification_bit_for_bit():
    """docs/studies.md written out literally in NumPy (tests/study_oracle.py) draws the same numbers
    and builds the same measured vectors and FRFs as the core, every error on."""
    import dataclasses

    import study_oracle as O

    spec = _spec(ALL_SYNC, seed=77)
    q, w = spec.realize(5, 9)
    qo, wo = O.sync_measured(spec.rotor_params, spec.kb, spec.cb, spec.w, spec.u, spec.planes_z, spec.probes_z,
                             dataclasses.asdict(ALL_SYNC), 77, range(5, 9))
    np.testing.assert_allclose(q, qo, rtol=1e-12, atol=1e-12 * np.abs(qo).max())
    np.testing.assert_allclose(w, wo, rtol=1e-14)
    f = np.linspace(20, 150, 9)
    ie = ImpactErrors(coherence=0.9, impacts=4, force_calibration_rel=0.02, impact_position_m=1e-3,
                      channel_delay_s=3e-6, probe_position_m=0.4e-3)
    tests = [(0.0, "x"), (0.05, "y"), (-0.1, "x")]
    ispec = mc._Spec(kind="impact", rotor_params=RIG.rotor.core_params(), w=2 * np.pi * f,
                     kb=np.tile(RIG.bearings.k.reshape(1, 8), (f.size, 1)),
                     cb=np.tile(RIG.bearings.c.reshape(1, 8), (f.size, 1)), probes_z=mc._probes_z(RIG.rotor, "probes"),
                     planes_z=np.array([t[0] for t in tests]), errors=ie.core_array(), u=None,
                     dirs=np.array([0, 1, 0], np.uint8), spin=2000 * RPM, method="forces", seed=78)
    h, _ = ispec.realize(0, 3)
    ho = O.impact_measured(ispec.rotor_params, ispec.kb, ispec.cb, ispec.spin, ispec.w, tests, ispec.probes_z,
                           dict(coherence=0.9, impacts=4, force_calibration_rel=0.02, impact_position_m=1e-3,
                                channel_delay_s=3e-6, probe_position_m=0.4e-3), 78, range(3))
    np.testing.assert_allclose(h, ho, rtol=1e-12, atol=1e-12 * np.abs(ho).max())
    # the core's bins are the specification's
    np.testing.assert_array_equal(bin_edges(), O.hist_edges())


def test_percentiles_from_histograms():
    edges = bin_edges()
    x = np.random.default_rng(0).normal(0.02, 0.01, 20000)
    counts = np.histogram(x, bins=edges)[0][None]
    p = percentiles_from_counts(counts, [5, 50, 95])[:, 0]
    np.testing.assert_allclose(p, np.percentile(x, [5, 50, 95]), rtol=0.01)
    assert np.all(np.isnan(percentiles_from_counts(np.zeros((2, edges.size - 1), np.uint32), [50])))


def test_percentiles_from_counts_equal_the_oracle_bit_for_bit():
    """The core's percentiles (one pass per histogram) are docs/studies.md's rule as
    tests/study_oracle.py writes it, bit for bit: sparse and dense histograms, empty ones, counts
    in the open end bins only, a single count, percentiles 0 and 100, every integer type, leading
    axes of any shape."""
    import study_oracle as O

    rng = np.random.default_rng(5)
    nb = bin_edges().size - 1
    dense = rng.integers(0, 50, (6, 3, nb)).astype(np.uint32)
    sparse = np.zeros((7, nb), np.uint32)
    for r in range(7):
        sparse[r, rng.integers(0, nb, r)] = rng.integers(1, 9, r)  # row 0 empty, row 1 one bin
    ends = np.zeros((3, nb), np.uint32)
    ends[0, 0] = 5
    ends[1, -1] = 2
    ends[2, [0, -1]] = [1, 4]
    q = [0, 0.1, 5, 50, 95, 99.9, 100]
    for counts in (dense, sparse, ends, sparse.astype(np.int64), dense.astype(np.uint16), dense.astype(np.uint64),
                   dense[0, 0]):
        got = percentiles_from_counts(counts, q)
        want = O.percentiles_from_histogram(counts, q)
        assert got.shape == want.shape
        np.testing.assert_array_equal(got, want)


def test_percentiles_from_counts_refuses_bad_histograms():
    nb = bin_edges().size - 1
    for bad in (np.zeros((2, nb - 1), np.uint32), np.zeros((2, nb)), -np.ones((1, nb), np.int64), np.zeros(()),
                [["a"] * nb]):
        with pytest.raises(RotoridError):
            percentiles_from_counts(bad, [50])
    for q in ([], [101], [-1], [np.nan], "50"):
        with pytest.raises(RotoridError):
            percentiles_from_counts(np.zeros((1, nb), np.uint32), q)


def test_same_seed_same_result_different_seed_different_result():
    errors = SyncErrors(amplitude_rel=0.01, phase_deg=0.3)
    a = synchronous_study(RIG.rotor, RIG.bearings, RUNS, RPM_GOOD, errors, trials=200, seed=11)
    b = synchronous_study(RIG.rotor, RIG.bearings, RUNS, RPM_GOOD, errors, trials=200, seed=11)
    c = synchronous_study(RIG.rotor, RIG.bearings, RUNS, RPM_GOOD, errors, trials=200, seed=12)
    assert np.array_equal(a.pct, b.pct) and np.array_equal(a.mean, b.mean)
    assert not np.array_equal(a.pct, c.pct)


def test_task_sizes_change_nothing_but_the_order_of_float_sums(monkeypatch):
    errors = SyncErrors(amplitude_rel=0.01, phase_deg=0.3, noise_m=1e-8)
    rpm = np.linspace(3000, 7000, 45)
    a = synchronous_study(RIG.rotor, RIG.bearings, RUNS, rpm, errors, trials=300, seed=5, keep_histograms=True)
    monkeypatch.setattr(mc, "TRIAL_BLOCK", 64)
    monkeypatch.setattr(mc, "POINT_BLOCK", 16)
    b = synchronous_study(RIG.rotor, RIG.bearings, RUNS, rpm, errors, trials=300, seed=5, keep_histograms=True)
    assert np.array_equal(a.counts, b.counts) and np.array_equal(a.pct, b.pct)
    np.testing.assert_allclose(a.mean, b.mean, rtol=1e-12, atol=1e-18)


_THREADS = """
import sys, numpy as np, rotorid
from rotorid.studies import SyncErrors, synchronous_study
rig = rotorid.nsf_rig()
r = synchronous_study(rig.rotor, rig.bearings, [rig.imbalances[s] for s in "ABCD"], np.linspace(3000, 7000, 70),
                      SyncErrors(amplitude_rel=0.01, phase_deg=0.3), trials=200, seed=9)
np.save(sys.argv[1], np.concatenate([r.pct.ravel(), r.mean.ravel(), r.rms.ravel()]))
"""


def test_results_do_not_depend_on_the_number_of_threads():
    from thread_runs import outputs_on_threads

    outs = outputs_on_threads(_THREADS)
    np.testing.assert_array_equal(outs[0], outs[1])


def test_spread_matches_first_order_uncertainty_and_intervals_cover():
    """Random errors only, well-conditioned speeds: the Monte Carlo spread of each coefficient
    equals the standard error the identification propagates from the measurement covariance, and
    its 95 % intervals hold the truth 95 % of the time."""
    errors = SyncErrors(amplitude_rel=0.002, phase_deg=0.1, noise_m=0.02e-6)
    res = synchronous_study(RIG.rotor, RIG.bearings, RUNS, RPM_GOOD, errors, trials=4000, seed=2,
                            coverage_trials=60)
    q, w = _spec(errors, seed=2).realize(0, 1)
    e = errors.core_array()
    rs = [SyncResponse(RPM_GOOD, q[0, i], imbalance=imb, at="probes", cov=mc._vector_cov(q[0, i], e[0], e[1], e[2]))
          for i, imb in enumerate(RUNS)]
    ident = identify_synchronous(RIG.rotor, rs)
    n = RPM_GOOD.size
    sd = np.concatenate([ident.k_std.reshape(n, 8)[:, _REPORT_TO_BIJ], ident.c_std.reshape(n, 8)[:, _REPORT_TO_BIJ]], 1)
    sd_rel = sd / np.abs(_truth(RIG.bearings, n))
    spread = (res.percentile(95) - res.percentile(5)) / (2 * 1.6449)
    ratio = spread / sd_rel
    assert 0.85 < np.median(ratio) < 1.15, np.median(ratio)
    assert np.all((ratio > 0.6) & (ratio < 1.6)), ratio
    cov = np.nanmean(res.coverage)
    assert 0.92 <= cov <= 0.98, cov


def test_systematic_errors_are_not_in_the_intervals():
    """A keyphasor error common to a test is invisible to the per-vector covariance: the coverage
    falls well below the nominal level (what the README warns about)."""
    rand = SyncErrors(amplitude_rel=0.002, phase_deg=0.1)
    sysm = SyncErrors(amplitude_rel=0.002, phase_deg=0.1, keyphasor_deg=2.0)
    a = synchronous_study(RIG.rotor, RIG.bearings, RUNS, RPM_GOOD, rand, trials=50, coverage_trials=40, seed=4)
    b = synchronous_study(RIG.rotor, RIG.bearings, RUNS, RPM_GOOD, sysm, trials=50, coverage_trials=40, seed=4)
    assert np.nanmean(b.coverage) < np.nanmean(a.coverage) - 0.2


def test_impact_study_matches_the_public_identification_and_its_error_model():
    f = np.linspace(20, 120, 6)
    errors = ImpactErrors(coherence=0.97, impacts=5, force_calibration_rel=0.01, impact_position_m=2e-3,
                          channel_delay_s=2e-6, probe_position_m=0.3e-3)
    tests = [(0.0, "x"), (0.0, "y")]
    res = impact_study(RIG.rotor, RIG.bearings, tests, f, errors, speed_rpm=1000, trials=150, seed=8)
    spec = mc._Spec(kind="impact", rotor_params=RIG.rotor.core_params(), w=2 * np.pi * f,
                    kb=np.tile(RIG.bearings.k.reshape(1, 8), (f.size, 1)), cb=np.tile(RIG.bearings.c.reshape(1, 8),
                                                                                       (f.size, 1)),
                    probes_z=mc._probes_z(RIG.rotor, "probes"), planes_z=np.zeros(2), errors=errors.core_array(),
                    u=None, dirs=np.array([0, 1], np.uint8), spin=1000 * RPM, method="forces", seed=8)
    errs = []
    truth = _truth(RIG.bearings, f.size)
    for t in range(150):
        h, _ = spec.realize(t, t + 1)
        ts = [ImpactResponse(speed_rpm=1000, freq_hz=f, q=h[0, i], plane=0.0, direction=d, at="probes")
              for i, (_, d) in enumerate(tests)]
        errs.append((identify_impact(RIG.rotor, ts).report_vector() - truth) / np.abs(truth))
    np.testing.assert_allclose(res.mean, np.mean(errs, 0), rtol=1e-9, atol=1e-15)
    # without errors the FRFs are exact
    h, _ = mc._Spec(**{**spec.__dict__, "errors": np.zeros(5)}).realize(0, 1)
    ref = rotorid.impact_frf(RIG.rotor, RIG.bearings, speed_rpm=1000, freq_hz=f, plane=0.0, direction="y").at_probes(
        RIG.rotor).q
    np.testing.assert_allclose(h[0, 1], ref, rtol=1e-12, atol=1e-12 * np.abs(ref).max())


def test_frf_random_error_formula():
    assert frf_random_error(1.0, 3) == 0.0
    assert abs(frf_random_error(0.9, 10) - np.sqrt(0.1 / (2 * 10 * 0.9))) < 1e-15


def test_memory_does_not_grow_with_the_trial_count():
    code = """
import resource, numpy as np, rotorid
from rotorid.studies import SyncErrors, synchronous_study
rig = rotorid.nsf_rig()
runs = [rig.imbalances[s] for s in "ABCD"]
synchronous_study(rig.rotor, rig.bearings, runs, np.linspace(3000, 7000, 40), SyncErrors(phase_deg=0.1), trials=10)
base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
synchronous_study(rig.rotor, rig.bearings, runs, np.linspace(3000, 7000, 40), SyncErrors(phase_deg=0.1), trials=TRIALS)
print((resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - base) / 1024)
"""
    grow = []
    for trials in (2000, 20000):
        p = subprocess.run([sys.executable, "-c", code.replace("TRIALS", str(trials))], capture_output=True, text=True,
                           timeout=300)
        assert p.returncode == 0, p.stderr
        grow.append(float(p.stdout.strip().splitlines()[-1]))
    assert grow[1] < grow[0] + 20, grow  # MB: ten times the trials, not more memory


def test_design_recommends_sets_that_beat_the_reports():
    rpm = np.linspace(2500, 7500, 21)
    compare = {"A-D": RUNS, "BD": [RIG.imbalances["B"], RIG.imbalances["D"]],
               "AB": [RIG.imbalances["A"], RIG.imbalances["B"]], "ABD": [RIG.imbalances[s] for s in "ABD"]}
    d = design_trial_masses(RIG.rotor, RIG.bearings, TrialMassRig(holes=8, masses_kg=(0.0033, 0.0051)), rpm,
                            errors=SyncErrors(amplitude_rel=0.002, phase_deg=0.05), trials=200, screen_keep=6,
                            compare=compare, seed=1)
    comp = d.comparison.set_index("design")["expected_error"]
    assert comp["recommended (2 runs)"] < min(comp["BD"], comp["AB"])
    assert comp["recommended (3 runs)"] < comp["ABD"]
    assert len(d.best[2]) == 2 and len(d.best[3]) == 3
    # the recommendation holds with fresh random numbers
    fresh = [expected_error(synchronous_study(RIG.rotor, RIG.bearings, runs, rpm,
                                              SyncErrors(amplitude_rel=0.002, phase_deg=0.05,
                                                         noise_m=d.noise_m), trials=300, seed=99),
                            RIG.bearings)["all"] for runs in (d.best[2], compare["BD"])]
    assert fresh[0] < fresh[1]


def test_impact_plan_design():
    d = design_impact_plan(RIG.rotor, RIG.bearings, [-0.15, 0.0, 0.15], np.linspace(20, 120, 6), speed_rpm=1000,
                           impacts_total=10, coherence=0.95, tests=(2,), trials=100,
                           compare={"report (CG x, CG y)": [(0.0, "x"), (0.0, "y")]})
    comp = d.comparison.set_index("design")["expected_error"]
    assert comp["recommended (2 tests)"] <= comp["report (CG x, CG y)"]
    assert len(d.ranking) > 5


@pytest.mark.parametrize("kwargs, match", [
    (dict(trials=0), "trials"), (dict(trials=1.5), "trials"), (dict(seed=-1), "seed"),
    (dict(percentiles=[5, 120]), "percentiles"), (dict(percentiles=[]), "percentiles"),
    (dict(percentiles=[np.nan]), "percentiles"), (dict(level=1.0), "level"), (dict(method="ols"), "method"),
    (dict(at="shaft"), "at"), (dict(errors="1%"), "errors"), (dict(coverage_trials=-2), "coverage_trials"),
    (dict(client=42), "client"), (dict(progress="yes"), "progress"),
])
def test_bad_study_arguments(kwargs, match):
    args = dict(trials=10)
    args.update(kwargs)
    with pytest.raises(RotoridError, match=match):
        synchronous_study(RIG.rotor, RIG.bearings, RUNS, RPM_GOOD, **args)


def test_bad_models_and_runs():
    with pytest.raises(RotoridError, match="standard deviation|>= 0"):
        SyncErrors(phase_deg=-1)
    with pytest.raises(RotoridError, match="finite"):
        SyncErrors(noise_m=np.nan)
    with pytest.raises(RotoridError, match="plausible"):
        SyncErrors(amplitude_rel=50)
    with pytest.raises(RotoridError, match="coherence"):
        ImpactErrors(coherence=1.5)
    with pytest.raises(RotoridError, match="impacts"):
        ImpactErrors(impacts=0)
    with pytest.raises(RotoridError, match="two or more"):
        synchronous_study(RIG.rotor, RIG.bearings, RUNS[:1], RPM_GOOD, trials=10)
    with pytest.raises(rotorid.IdentifiabilityError):
        a = RIG.imbalances["A"]
        synchronous_study(RIG.rotor, RIG.bearings, [a, rotorid.Imbalance(tuple(2 * m for m in a.mass_kg),
                                                                          a.angle_deg)], RPM_GOOD, trials=10)
    with pytest.raises(RotoridError, match="speed_rpm"):
        synchronous_study(RIG.rotor, RIG.bearings, RUNS, [3000.0, -1.0], trials=10)
    with pytest.raises(RotoridError, match="tests"):
        impact_study(RIG.rotor, RIG.bearings, [(0.0, "x")], [50.0], speed_rpm=1000, trials=10)
    with pytest.raises(RotoridError, match="direction"):
        impact_study(RIG.rotor, RIG.bearings, [(0.0, "x"), (0.0, "z")], [50.0], speed_rpm=1000, trials=10)
    with pytest.raises(rotorid.IdentifiabilityError):
        impact_study(RIG.rotor, RIG.bearings, [(0.0, "x"), (0.0, "x")], [50.0], speed_rpm=1000, trials=10)
    with pytest.raises(RotoridError, match="masses_kg"):
        TrialMassRig(masses_kg=())
    with pytest.raises(RotoridError, match="max_response_m"):
        design_trial_masses(RIG.rotor, RIG.bearings, TrialMassRig(masses_kg=(0.005,), max_response_m=1e-12),
                            RPM_GOOD, trials=10)


def test_a_huge_trial_count_is_chunked_not_refused(monkeypatch):
    """10^9 trials is accepted and cut into tasks (here only the plan is checked, not run)."""
    tasks = mc._tasks(10 ** 9, 100)
    assert len(tasks) == 10 ** 9 // mc.TRIAL_BLOCK + (10 ** 9 % mc.TRIAL_BLOCK > 0)
    assert max(t1 - t0 for t0, t1, _, _ in tasks) == mc.TRIAL_BLOCK
