"""End-to-end: simulated raw recordings at realistic levels -> coefficients (issue: raw waveforms)."""

import os
import shutil
import warnings

import numpy as np
import pytest

import rotorid
from rotorid import RotoridError, impact_noise, pipeline, rawsim, signals
from rotorid import example as ex
from rotorid.recording import Recording

DIRECT = [(0, 0, 0), (0, 1, 1), (1, 0, 0), (1, 1, 1)]


def direct_errors(ident, truth, sel=None):
    sel = np.ones(ident.axis.size, bool) if sel is None else sel
    ek = np.abs(ident.k[sel] - truth.k) / np.abs(truth.k)
    ec = np.abs(ident.c[sel] - truth.c) / np.abs(truth.c)
    return max(ek[:, b, i, j].max() for b, i, j in DIRECT), max(ec[:, b, i, j].max() for b, i, j in DIRECT)


@pytest.fixture(scope="module")
def imbalance_records():
    """Four 5 g static/couple runs and a baseline; dwells of 6 s at 3000-6000 rpm, 10 kHz; probe
    noise 0.5 µm rms; run-out 8/3/1 µm (1X/2X/3X); remnant 1.0 g + 0.6 g; probes off the bearings;
    bearings 1 and 2 different and cross-coupled."""
    rotor, brg, remnant = rawsim.example_rig()
    rpm = np.arange(3000.0, 6001.0, 500.0)
    runs = []
    for i, (name, (mass_g, ang)) in enumerate(ex.SETS.items()):
        imb = rotorid.Imbalance(tuple(m * 1e-3 for m in mass_g), ang, name=name)
        runs.append(rawsim.imbalance_recording(rotor, brg, speeds_rpm=rpm, added=imb, remnant=remnant, seed=11 + i))
    base = rawsim.imbalance_recording(rotor, brg, speeds_rpm=rpm, added=None, remnant=remnant, seed=19, kind="baseline")
    slow = rawsim.imbalance_recording(rotor, brg, speeds_rpm=[400.0], added=None, remnant=remnant, seed=20,
                                      kind="slow_roll", dwell_s=3.0)
    return rotor, brg, runs, base, slow


def test_imbalance_chain_recovers_direct_coefficients_within_3_percent(imbalance_records):
    rotor, brg, runs, base, slow = imbalance_records
    res = pipeline.imbalance_chain(rotor, runs, baseline=base, slow_roll=slow)
    ident = res.identification
    assert ident.axis.min() > 2990 and ident.axis.max() < 6010 and ident.axis.size == 7
    ek, ec = direct_errors(ident, brg)
    assert ek < 0.03 and ec < 0.03, (ek, ec)
    assert ident.ok.all()


def test_skipping_baseline_subtraction_visibly_degrades(imbalance_records):
    rotor, brg, runs, base, slow = imbalance_records
    good = direct_errors(pipeline.imbalance_chain(rotor, runs, baseline=base).identification, brg)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        raw = direct_errors(pipeline.imbalance_chain(rotor, runs).identification, brg)
    slow_only = direct_errors(pipeline.imbalance_chain(rotor, runs, slow_roll=slow).identification, brg)
    # remnant imbalance (and run-out) left in the vectors: errors of tens of percent
    assert min(raw) > 5 * max(good) and max(raw) > 0.2
    assert max(slow_only) > 0.2


@pytest.fixture(scope="module")
def impact_records():
    """Five 4 kN, 2 ms impacts per direction at the CG at 2000 rpm, with run-out, remnant imbalance
    and 0.5 µm probe noise."""
    rotor, brg, remnant = rawsim.example_rig()
    recs = [rawsim.impact_recording(rotor, brg, speed_rpm=2000.0, plane=0.0, direction=d, remnant=remnant, seed=31 + i)
            for i, d in enumerate("xy")]
    return rotor, brg, recs


def test_impact_chain_recovers_direct_coefficients_within_5_percent(impact_records):
    rotor, brg, recs = impact_records
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # coherence notes in the crossed directions
        res = pipeline.impact_chain(rotor, recs, band_hz=(5.0, 150.0))
    f = res.identification.freq_hz
    sel = (f >= 20) & (f <= 120)
    ek, ec = direct_errors(res.identification, brg, sel)
    assert ek < 0.05 and ec < 0.05, (ek, ec)
    assert [len(u) for u in res.used] == [5, 5] and not res.dropped


def test_skipping_the_runout_filter_visibly_degrades(impact_records):
    rotor, brg, recs = impact_records
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        good = pipeline.impact_chain(rotor, recs).identification
        bad = pipeline.impact_chain(rotor, recs, runout=False).identification
    sel = (good.freq_hz >= 20) & (good.freq_hz <= 120)
    assert max(direct_errors(bad, brg, sel)) > 5 * max(direct_errors(good, brg, sel))


def _with_force(recs, fn):
    import dataclasses

    return [dataclasses.replace(r, channels=dict(r.channels, force=fn(r.channels["force"]))) for r in recs]


def test_a_force_transducer_offset_is_removed_and_an_inverted_one_refused(impact_records):
    """A charge amplifier's offset of 1.5 % of the peak (60 N) cost 10-18 % in K and C with every
    point ok (found by an independent simulator); it is now the resting level subtracted before
    the window. A force channel of inverted polarity (impacts peaking negative) is refused."""
    rotor, brg, recs = impact_records
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        clean = pipeline.impact_chain(rotor, recs, band_hz=(20.0, 120.0)).identification
        offset = pipeline.impact_chain(rotor, _with_force(recs, lambda f: f + 60.0), band_hz=(20.0, 120.0)).identification
    ek, ec = direct_errors(offset, brg)
    assert ek < 0.05 and ec < 0.05, (ek, ec)
    assert np.allclose(offset.k, clean.k, rtol=2e-3) and np.allclose(offset.c, clean.c, rtol=5e-3)
    with pytest.raises(RotoridError, match=r"peaks at -\d.* polarity is inverted \(give it scale = -1"):
        pipeline.impact_chain(rotor, _with_force(recs, lambda f: -f))


def test_double_hit_is_dropped_with_a_warning():
    rotor, brg, remnant = rawsim.example_rig()
    recs = [rawsim.impact_recording(rotor, brg, speed_rpm=2000.0, plane=0.0, direction=d, remnant=remnant, seed=41 + i,
                                    double_hit_at=1 if d == "x" else None) for i, d in enumerate("xy")]
    with pytest.warns(UserWarning, match="dropped: double hit"):
        res = pipeline.impact_chain(rotor, recs)
    assert [len(u) for u in res.used] == [4, 5] and len(res.dropped) == 1


def test_missing_keyphasor_and_bad_configs_are_errors(tmp_path):
    rotor, brg, remnant = rawsim.example_rig()
    rec = rawsim.imbalance_recording(rotor, brg, speeds_rpm=[3000.0], added=None, remnant=remnant, dwell_s=0.5)
    nokp = Recording(rec.fs_hz, {k: v for k, v in rec.channels.items() if k != "kp"}, rec.meta)
    with pytest.raises(RotoridError, match=r"lacks channel\(s\) \['kp'\]"):
        pipeline.imbalance_chain(rotor, [nokp])
    with pytest.raises(RotoridError, match="has no added imbalance"):
        pipeline.imbalance_chain(rotor, [rec, rec])
    cfg = tmp_path / "c.toml"
    cfg.write_text("[rig]\nbuiltin = 'nsf'\n")
    with pytest.raises(RotoridError, match=r"no \[impact\] section"):
        pipeline.run_config(cfg, "impact")
    cfg.write_text("[rig\n")
    with pytest.raises(RotoridError, match="not valid TOML"):
        pipeline.run_config(cfg, "imbalance")
    cfg.write_text("[rig]\nbuiltin = 'other'\n[imbalance]\n")
    with pytest.raises(RotoridError, match="unknown builtin rig"):
        pipeline.run_config(cfg, "imbalance")


def test_cli_on_the_bundled_example(tmp_path):
    from rotorid import cli

    d = tmp_path / "ex"
    assert cli.main(["example", "--out", str(d)]) == 0
    truth = ex.truth()
    assert cli.main(["identify", "imbalance", str(d / "imbalance.toml")]) == 0
    import pandas as pd

    df = pd.read_csv(d / "out_imbalance" / "coefficients_imbalance.csv")
    for name, (b, i, j) in {"Kxx1": (0, 0, 0), "Kyy2": (1, 1, 1), "Cxx2": (1, 0, 0), "Cyy1": (0, 1, 1)}.items():
        ref = (truth.k if name[0] == "K" else truth.c)[b, i, j]
        np.testing.assert_allclose(df[name], ref, rtol=0.05)
    assert (d / "out_imbalance" / "coefficients_imbalance.png").stat().st_size > 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert cli.main(["identify", "impact", str(d / "impact.toml")]) == 0
    df = pd.read_csv(d / "out_impact" / "coefficients_impact.csv")
    sel = (df.freq_hz >= 20) & (df.freq_hz <= 120)
    np.testing.assert_allclose(df.Kxx1[sel], truth.k[0, 0, 0], rtol=0.05)
    np.testing.assert_allclose(df.Cyy2[sel], truth.c[1, 1, 1], rtol=0.05)
    frfs = sorted(p.name for p in (d / "out_impact").glob("frf_*.csv"))
    assert len(frfs) == 2 and "x1_coherence" in pd.read_csv(d / "out_impact" / frfs[0]).columns
    # a config pointing at a missing file is a clean error, not a traceback
    (d / "bad.toml").write_text((d / "imbalance.toml").read_text().replace("run_S0.tdms", "nope.tdms"))
    assert cli.main(["identify", "imbalance", str(d / "bad.toml")]) == 1


def test_us_customary_report_units(tmp_path):
    from rotorid import cli

    d = tmp_path / "ex"
    shutil.copytree(ex.path(), d)
    cfg = (d / "imbalance.toml").read_text().replace('units = "SI"', 'units = "US"')
    (d / "imbalance.toml").write_text(cfg)
    assert cli.main(["identify", "imbalance", str(d / "imbalance.toml")]) == 0
    import pandas as pd

    df = pd.read_csv(d / "out_imbalance" / "coefficients_imbalance.csv")
    np.testing.assert_allclose(df["Kxx1_lbf_per_in"], 2.4e6 * 0.0254 / 4.4482216152605, rtol=0.05)
    assert os.path.exists(d / "out_imbalance")


def test_exponential_window_on_short_records_is_accounted_for(impact_records):
    """Records cut at 0.06 s, before the response has decayed: an exponential window (tau = 20 ms)
    with its decay passed to the identification does much better than the bare truncated records."""
    rotor, brg, recs = impact_records
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        bare = pipeline.impact_chain(rotor, recs, record_s=0.06, band_hz=(15, 150)).identification
        win = pipeline.impact_chain(rotor, recs, record_s=0.06, band_hz=(15, 150), exp_window_tau_s=0.02).identification
    sel = (win.freq_hz >= 30) & (win.freq_hz <= 120)
    e_bare = max(direct_errors(bare, brg, sel))
    e_win = max(direct_errors(win, brg, sel))
    assert e_win < 0.1 and e_bare > 2 * e_win, (e_bare, e_win)


def test_a_window_that_passes_the_decay_check_leaves_its_truncation_in_the_error_bars(monkeypatch):
    """0.08 s impact records with a 20 ms exponential window pass the decay check, but what they cut
    off still biases the FRFs: the direct damping's 95 % intervals covered the truth 6 % of the
    time at 0.05 µm probe noise (43 % at 0.5 µm), every point ok (found by an independent
    simulator, 25 % there). The last quarter of the records, scaled by the decay per quarter,
    now stands for what was cut off (``impact_noise.truncation_var``)."""
    rotor, brg, remnant = rawsim.example_rig()
    meta = [dict(plane=0.0, direction="x"), dict(plane=0.0, direction="y")]

    def cover(seeds):
        hits, ok = [], []
        for s in seeds:
            recs = [rawsim.impact_recording(rotor, brg, speed_rpm=2000, plane=0.0, direction=d, remnant=remnant,
                                            noise_m=0.05e-6, force_noise_N=0.2, seed=10 * s + i)
                    for i, d in enumerate("xy")]
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                ident = pipeline.impact_chain(rotor, recs, record_s=0.08, band_hz=(10, 160), exp_window_tau_s=0.02,
                                              tests_meta=meta).identification
            iv = ident.interval(0.95)
            hits.append(((iv.c_lower <= brg.c) & (brg.c <= iv.c_upper))[:, :, [0, 1], [0, 1]][ident.ok].ravel())
            ok.append(ident.ok.mean())
        return np.concatenate(hits).mean(), np.mean(ok)

    now, ok = cover(range(2))
    monkeypatch.setattr(impact_noise, "truncation_var", lambda *a: None)
    before, ok_before = cover(range(2))
    assert before < 0.3 and ok_before == 1.0, (before, ok_before)
    assert now >= 0.95 and ok >= 0.8, (now, ok)      # (measured 1.0 and 1.0 over 4 seeds)


def _single_hit_draws(seeds, *, extra=None, impact_s=1.0, **kw):
    """(coverage of the 95 % intervals of every K and C, median |z|) of the impact chain on the
    example rig's x and y tests with one impact each at ``impact_s``; ``extra``: (kind, level) of
    noise added to the recordings: "probe lf" (2nd-order low-pass at 50 Hz on each probe, level m
    rms), "force lf" (the same on the force, N rms) or "hum" (a 50 Hz sine of amplitude level m of
    random phase on each probe)."""
    from scipy import signal as sps

    rotor, brg, remnant = rawsim.example_rig()
    meta = [dict(plane=0.0, direction="x"), dict(plane=0.0, direction="y")]
    hits, z = [], []
    for s in seeds:
        recs = []
        for i, d in enumerate("xy"):
            r = rawsim.impact_recording(rotor, brg, speed_rpm=2000, plane=0.0, direction=d, remnant=remnant,
                                        impact_times_s=(impact_s,), seed=10 * s + i)
            if extra is not None:
                kind, level = extra
                rng = np.random.default_rng(1000 + 10 * s + i)
                n = r.n_samples
                b, a = sps.butter(2, 50.0 / (r.fs_hz / 2))
                for c in ("force",) if kind == "force lf" else ("x1", "x2", "y1", "y2"):
                    if kind == "hum":
                        e = np.sin(2 * np.pi * 50.0 * np.arange(n) / r.fs_hz + rng.uniform(0, 2 * np.pi))
                    else:
                        e = sps.lfilter(b, a, rng.standard_normal(n + 2000))[2000:]
                        e /= e.std()
                    r.channels[c] = r.channels[c] + level * e
            recs.append(r)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            ident = pipeline.impact_chain(rotor, recs, band_hz=(20, 120), tests_meta=meta, **kw).identification
        assert ident.std_source == "measurement covariance" and np.all(np.isfinite(ident.c_std))
        iv = ident.interval(0.95)
        hits.append(np.r_[((iv.k_lower <= brg.k) & (brg.k <= iv.k_upper)).ravel(),
                          ((iv.c_lower <= brg.c) & (brg.c <= iv.c_upper)).ravel()])
        z.append(np.abs(np.r_[((ident.k - brg.k) / ident.k_std).ravel(), ((ident.c - brg.c) / ident.c_std).ravel()]))
    return np.mean(hits), np.median(np.concatenate(z))


def test_a_single_impact_per_test_gets_error_bars_from_the_noise_before_it():
    """One impact per test left no scatter to estimate the FRFs' error from: every coefficient had a
    NaN standard error and every point was ok (review). The quiet record before the impact, cut into
    record-long segments processed as the impact's record is, now gives H1's covariance
    (``impact_noise.ImpactNoise``): over 20 draws the 95 % intervals covered 0.972 with median |z|
    0.69 (a normal's 0.67; 0.958 and 0.72 over 30 draws with the covariance across the channels,
    2026-11-29's eighth part); an independent simulator's single hits 0.987 (with a window 0.985,
    with 3 times the noise 0.986)."""
    cover, z = _single_hit_draws(range(8))
    assert cover >= 0.9 and 0.5 < z < 0.85, (cover, z)
    # with a window (0.1 s records, tau = 30 ms): its weights, not the record's length, count the
    # noise (measured 0.975, median |z| 0.48 with the truncation term)
    cover, z = _single_hit_draws(range(8), record_s=0.1, exp_window_tau_s=0.03)
    assert cover >= 0.9 and 0.35 < z < 0.85, (cover, z)


def test_a_single_impacts_error_bars_follow_noise_that_is_not_white(monkeypatch):
    """The white-noise model from the samples before a single impact under-counted noise
    concentrated in the band (review, 20 draws each: probe noise low-passed at 50 Hz of 0.3 µm rms
    beside the 0.5 µm white, coverage 0.72; force noise low-passed at 50 Hz of 10 N, 0.6-0.8; a 50
    Hz hum of 0.3 µm, 0.89). Measured on the quiet record before the impact, the noise's share at
    each frequency is what its segments show: 0.969, 0.978 and 0.976 over 20 draws (0.958 over 30,
    0.968 over 30 with median |z| 0.65 rather than 0.47, and 0.968 over 20, with the covariance
    across the channels). Without a run-out filter (the synchronous response left in the records
    and in the segments alike), 0.84 -> 0.985 (0.989)."""
    seeds = range(10)
    for extra, floor in ((("probe lf", 3e-7), 0.9), (("force lf", 10.0), 0.9), (("hum", 3e-7), 0.9)):
        cover, z = _single_hit_draws(seeds, extra=extra)
        assert cover >= floor and 0.4 < z < 0.85, (extra, cover, z)
    cover, _ = _single_hit_draws(seeds, runout=False)
    assert cover >= 0.93, cover
    # the white model (no quiet segments) under-counts the low-passed probe noise
    monkeypatch.setattr(impact_noise, "_quiet_segments", lambda *a: "no quiet record (test)")
    cover, z = _single_hit_draws(seeds, extra=("probe lf", 3e-7))
    assert cover < 0.85 and z > 1.0, (cover, z)


def test_a_single_impact_without_quiet_record_before_it_falls_back_to_white_noise():
    """An impact 0.35 s into its recording leaves less than 1.5 records of quiet record before the
    run-out filter's revolutions: its noise is modelled white from the samples before it, with a
    warning (20 draws: coverage 0.953); with too few of those (1 ms at 10 kHz) the uncertainty is
    unknown, every point flagged so, with a warning (it was NaN with every point ok, review). A
    dropout in the quiet record leaves the part after it."""
    cover, z = _single_hit_draws(range(6), impact_s=0.35)
    assert cover >= 0.9 and 0.5 < z < 0.85, (cover, z)
    rotor, brg, remnant = rawsim.example_rig()
    meta = [dict(plane=0.0, direction="x"), dict(plane=0.0, direction="y")]
    recs = [rawsim.impact_recording(rotor, brg, speed_rpm=2000, plane=0.0, direction=d, remnant=remnant,
                                    impact_times_s=(0.35,), seed=i) for i, d in enumerate("xy")]
    with pytest.warns(UserWarning, match="less than 1.5 records of quiet record before it: its FRF's error bars come "
                                         "from the 100 samples"):
        pipeline.impact_chain(rotor, recs, band_hz=(20, 120), tests_meta=meta)
    with pytest.warns(UserWarning, match="no usable quiet record before it and 10 sample.* too few to estimate its noise"):
        ident = pipeline.impact_chain(rotor, recs, band_hz=(20, 120), tests_meta=meta, pre_s=0.001).identification
    assert not ident.ok.any() and set(ident.flag) == {"uncertainty unknown"}, set(ident.flag)
    # a dropout in the quiet record: the segments come from after it (fewer of them, fewer dof)
    recs = [rawsim.impact_recording(rotor, brg, speed_rpm=2000, plane=0.0, direction=d, remnant=remnant,
                                    impact_times_s=(1.0,), seed=i) for i, d in enumerate("xy")]
    full = pipeline.impact_chain(rotor, recs, band_hz=(20, 120), tests_meta=meta)
    for r in recs:
        r.channels["x1"][3000] = np.nan
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        cut = pipeline.impact_chain(rotor, recs, band_hz=(20, 120), tests_meta=meta)
    assert 2 < cut.frfs[0].dof < full.frfs[0].dof and np.isfinite(cut.identification.c_std).all()


def _tapped(rec, rotor, brg, t_s, peak_N, **kw):
    """``rec`` with the response to a light tap of ``peak_N`` at ``t_s`` added (the rig is linear)."""
    tap = rawsim.impact_recording(rotor, brg, speed_rpm=2000, plane=0.0, direction="x", impact_times_s=(t_s,),
                                  peak_N=peak_N, runout=None, noise_m=0.0, force_noise_N=0.0, **kw)
    for c in ("x1", "x2", "y1", "y2", "force"):
        rec.channels[c] = rec.channels[c] + tap.channels[c]
    return rec


def test_a_single_impacts_noise_follows_a_rise_before_it_and_leaves_out_events_in_the_quiet_record(monkeypatch):
    """The quiet record's noise stands for the impact's only if it is as large. Probe noise a
    quarter of the impact's power until 0.1 s before it: coverage 0.62 with the quiet record taken
    as it is (review), 0.955 with the segments scaled up where the noise of the samples before the
    impact exceeds 99 % of the quiet windows' (`impact_noise._noise_growth`), with a warning. A
    light tap (300 N, under the detector's 10 % of the 4000 N hits) in the quiet record made the
    error bars 9-12 times wider and flagged 80-100 % of the points (review): the segments it rings
    into are left out, with a warning, or with fewer than two left the white model is used. A
    group of hits merged as "closer than min_separation_s" rings from its last hit: the quiet
    record starts a record after that one (k_std 22 times too wide before, review)."""
    rotor, brg, remnant = rawsim.example_rig()
    meta = [dict(plane=0.0, direction="x"), dict(plane=0.0, direction="y")]

    def draws(edit, seeds=range(8)):
        hits, ks = [], []
        for s in seeds:
            recs = [edit(rawsim.impact_recording(rotor, brg, speed_rpm=2000, plane=0.0, direction=d, remnant=remnant,
                                                 impact_times_s=(1.0,), seed=10 * s + i, noise_m=0.25e-6), s, i)
                    for i, d in enumerate("xy")]
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                ident = pipeline.impact_chain(rotor, recs, band_hz=(20, 120), tests_meta=meta).identification
            iv = ident.interval(0.95)
            hits.append(np.r_[((iv.k_lower <= brg.k) & (brg.k <= iv.k_upper)).ravel(),
                              ((iv.c_lower <= brg.c) & (brg.c <= iv.c_upper)).ravel()])
            ks.append(np.median(ident.k_std[..., [0, 1], [0, 1]]))
        return np.mean(hits), np.median(ks)

    def risen(rec, s, i):
        rng = np.random.default_rng(500 + 10 * s + i)
        late = np.arange(rec.n_samples) / rec.fs_hz >= 0.9
        for c in ("x1", "x2", "y1", "y2"):
            rec.channels[c] = rec.channels[c] + np.where(late, np.sqrt(0.5e-6 ** 2 - 0.25e-6 ** 2), 0.0) * \
                rng.standard_normal(rec.n_samples)
        return rec

    cover, _ = draws(risen)
    assert cover >= 0.9, cover
    recs = [risen(rawsim.impact_recording(rotor, brg, speed_rpm=2000, plane=0.0, direction=d, remnant=remnant,
                                          impact_times_s=(1.0,), seed=i, noise_m=0.25e-6), 0, i)
            for i, d in enumerate("xy")]
    with pytest.warns(UserWarning, match=r"noise just before its impact is [0-9.]+ times \([xy][12], in power\)"):
        pipeline.impact_chain(rotor, recs, band_hz=(20, 120), tests_meta=meta)
    clean, k_clean = draws(lambda r, s, i: r)
    tapped, k_tapped = draws(lambda r, s, i: _tapped(r, rotor, brg, 0.65, 300.0))
    assert tapped >= 0.9 and k_tapped < 1.3 * k_clean, (tapped, k_tapped, k_clean)
    with monkeypatch.context() as m:
        m.setattr(impact_noise, "_noise_growth", lambda response, force, ys, *a: np.ones(ys.shape[1] + 1))
        cover_flat, _ = draws(risen)
        assert cover_flat < 0.85, cover_flat
    with monkeypatch.context() as m:
        m.setattr(impact_noise, "EVENT_RATIO", np.inf)
        _, k_kept = draws(lambda r, s, i: _tapped(r, rotor, brg, 0.65, 300.0))
        assert k_kept > 2 * k_clean, (k_kept, k_clean)
    recs = [_tapped(rawsim.impact_recording(rotor, brg, speed_rpm=2000, plane=0.0, direction=d, remnant=remnant,
                                            impact_times_s=(1.0,), seed=i), rotor, brg, 0.65, 300.0)
            for i, d in enumerate("xy")]
    with pytest.warns(UserWarning, match="segment.* of the quiet record before its impact left out"):
        pipeline.impact_chain(rotor, recs, band_hz=(20, 120), tests_meta=meta)
    # hits at 0.4 and 0.58 s, merged and dropped, before the one at 1.4 s: with the events' test off,
    # the quiet record must start a record after the second (from the first, k_std 22 times too
    # wide, review)
    def group(rec, s, i):
        return _tapped(_tapped(rec, rotor, brg, 0.4, 4000.0), rotor, brg, 0.58, 3000.0)

    def at_14(edit):
        ks = []
        for s in range(4):
            recs = [edit(rawsim.impact_recording(rotor, brg, speed_rpm=2000, plane=0.0, direction=d, remnant=remnant,
                                                 impact_times_s=(1.4,), seed=10 * s + i), s, i)
                    for i, d in enumerate("xy")]
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                ident = pipeline.impact_chain(rotor, recs, band_hz=(20, 120), tests_meta=meta,
                                              record_s=0.15).identification
            assert ident.std_source == "measurement covariance"
            ks.append(np.median(ident.k_std[..., [0, 1], [0, 1]]))
        return np.median(ks)

    with monkeypatch.context() as m:
        m.setattr(impact_noise, "EVENT_RATIO", np.inf)
        k_group, k_alone = at_14(group), at_14(lambda r, s, i: r)
    assert k_group < 1.3 * k_alone, (k_group, k_alone)


def test_the_truncation_estimate_takes_out_the_impacts_noise_and_follows_the_decay():
    """``impact_noise.truncation_var``: where the records' last quarter holds noise alone (0.1 of
    a unit response, above 400 Hz) the impacts' scatter is taken out, leaving 0.38-0.46 of that
    noise's share (the positive part of a difference of estimates; 0.92-1.06 without it); a record
    whose third quarter does not stand clear of its noise gives 0; on a clean decaying oscillation
    the estimate is the part beyond the record within a factor of 3 (conservative in the median:
    the quarters' shares are summed without their phases)."""
    fs, n, pre = 5000.0, 400, 20
    t = (np.arange(n) - pre) / fs
    forces = [np.where(np.arange(n) == pre, 1.0 + 0.1 * k, 0.0) for k in range(5)]
    sel = np.ones(n // 2 + 1, bool)
    freq = np.fft.rfftfreq(n, 1 / fs)
    high = (freq > 400) & (freq < 2000)
    h = np.where(t >= 0, np.exp(-30.0 * t) * np.sin(2 * np.pi * 60.0 * t), 0.0)
    last = (np.arange(n) >= pre + 3 * (n - pre) // 4).astype(float)
    shares = []
    for seed in range(20):
        rng = np.random.default_rng(seed)
        noise = [0.1 * rng.standard_normal((4, n)) for _ in forces]
        v = impact_noise.truncation_var(forces, [f[pre] * h + e for f, e in zip(forces, noise)], pre, fs, None, sel, None)
        own = np.abs(impact_noise.h1(forces, [e * last for e in noise], fs, None).h[high]) ** 2
        shares.append(v[high].mean() / own.mean())
    assert np.median(shares) < 0.6, np.median(shares)
    rng = np.random.default_rng(1)
    alone = impact_noise.truncation_var(forces, [rng.standard_normal((4, n)) for _ in forces], pre, fs, None, sel, None)
    assert not alone.any()
    # a decaying 60 Hz oscillation per unit force, cut at 0.076 s: what the record misses, exactly
    alpha, f0 = 15.0, 60.0
    h = np.where(t >= 0, np.exp(-alpha * t) * np.sin(2 * np.pi * f0 * t), 0.0)
    resp = [np.tile(f[pre] * h, (4, 1)) + 1e-9 * rng.standard_normal((4, n)) for f in forces]
    v = impact_noise.truncation_var(forces, resp, pre, fs, None, sel, None)
    long_t = np.arange(40 * n) / fs
    full = np.fft.rfft(np.exp(-alpha * long_t) * np.sin(2 * np.pi * f0 * long_t))[::40][: sel.size]
    cut = np.fft.rfft(h[pre:], n=40 * n)[::40][: sel.size]
    missed = np.abs(full - cut)        # the spectrum of what lies beyond the record, at the FRF's bins
    band = (np.fft.rfftfreq(n, 1 / fs) > 20) & (np.fft.rfftfreq(n, 1 / fs) < 200)
    ratio = np.sqrt(v[band, 0]) / missed[band]
    assert 1.0 < np.median(ratio) < 3.0 and ratio.min() > 0.3, ratio    # (measured 1.86, 0.42-2.54)


def test_1x_tables_without_stated_accuracy_use_the_residual_of_redundant_runs(tmp_path):
    """A DAQ table without amplitude_std / phase_std_deg carries no covariance: with 4 runs the
    standard errors come from the residual (they were NaN covariances, every point 'uncertainty
    unknown'), and their 95 % intervals hold the example's true coefficients."""
    import tomllib

    from rotorid import example
    from rotorid.pipeline import run_config

    ex = example.copy_example(str(tmp_path / "ex"))
    ident, _ = run_config(f"{ex}/imbalance_1x_table.toml", "imbalance", out_dir=str(tmp_path / "o"),
                          log=lambda m: None, plots=False)
    assert ident.std_source.startswith("residual")
    assert ident.ok.all() and np.isfinite(ident.k_std).all()
    with open(f"{ex}/truth.toml", "rb") as fh:
        t = tomllib.load(fh)
    iv = ident.interval(0.95)
    k, c = np.array(t["k"]), np.array(t["c"])
    hits = np.concatenate([((iv.k_lower <= k) & (k <= iv.k_upper)).ravel(),
                           ((iv.c_lower <= c) & (c <= iv.c_upper)).ravel()])
    assert hits.mean() > 0.85, hits.mean()


def test_accuracy_lost_in_compensation_is_said_not_silent(tmp_path):
    """Runs with a stated accuracy, compensated by a baseline without one: the compensated vectors'
    accuracy is unknown, which a warning says (the covariance was dropped silently, every point ok)."""
    import warnings as _w

    from rotorid import example, tables
    from rotorid.config import load_config
    from rotorid.pipeline import imbalance_chain

    ex = example.copy_example(str(tmp_path / "ex"))
    cfg = load_config(f"{ex}/imbalance_1x_table.toml")
    kw = cfg.imbalance.table.reader_kwargs()
    runs = [tables.load_1x_table(f"{ex}/daq_1x/run_{n}.csv", **{**kw, "amplitude_std": 0.001, "phase_std_deg": 0.1})
            for n in ("S0", "C0")]
    base = tables.load_1x_table(f"{ex}/daq_1x/baseline.csv", **kw)
    imbalances = [rotorid.Imbalance(r.mass_kg(), tuple(r.angle_deg), r.name) for r in cfg.imbalance.runs[:2]]
    with _w.catch_warnings(record=True) as seen:
        _w.simplefilter("always")
        res = imbalance_chain(cfg.rotor(), runs, baseline=base, imbalances=imbalances, speed_match_rpm=2.0)
    assert any("accuracy is lost in the compensation" in str(w.message) for w in seen)
    assert not res.identification.ok.any()   # "uncertainty unknown": not passed off as trustworthy


def test_tracks_without_their_imbalance_are_an_error_naming_the_run(imbalance_records):
    """SyncTracks made in Python carry no added imbalance and no source file: the error names the
    run (an AttributeError before)."""
    rotor, brg, runs, base, slow = imbalance_records
    tracks = [rotorid.signals.track(r) for r in runs[:2]]
    assert not hasattr(tracks[0], "source")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with pytest.raises(RotoridError, match=r"run 0 \(SyncTrack\) has no added imbalance.*imbalances="):
            pipeline.imbalance_chain(rotor, tracks)
        # given as imbalances=, the same tracks are identified
        imbs = [rotorid.Imbalance(tuple(m * 1e-3 for m in mass_g), ang) for mass_g, ang in list(ex.SETS.values())[:2]]
        res = pipeline.imbalance_chain(rotor, tracks, imbalances=imbs)
    assert res.identification.axis.size == 7


@pytest.mark.parametrize("dead", ["flat", "gap and noise"])
def test_a_dead_probe_is_refused_not_fitted(imbalance_records, dead):
    """A probe that reads nothing (a flat channel, or its gap voltage with noise only) in every run:
    its 1X is noise, which the identification fitted as a response (an independent simulator:
    K off by 170-320 %, C by 350-450 %, most points ok, no warning). Now an error naming it."""
    import dataclasses

    rotor, brg, runs, base, slow = imbalance_records
    rng = np.random.default_rng(3)

    def kill(r):
        x = r.channels["y2"]
        x = np.zeros_like(x) if dead == "flat" else -2e-3 + 0.5e-6 * rng.standard_normal(x.size)
        return dataclasses.replace(r, channels=dict(r.channels, y2=x))

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with pytest.raises(RotoridError, match=r"probe channel\(s\) y2 show no 1X response above their noise"):
            pipeline.imbalance_chain(rotor, [kill(r) for r in runs], baseline=kill(base))


def test_hits_whose_previous_response_is_in_the_runout_window_are_dropped():
    """The run-out filter takes the 8 revolutions before a hit as run-out; with hits 0.3 s apart at
    1000 rpm the previous hit's response is in them (an independent simulator: K off by 153 %, C by
    261 %, 10 of 21 such frequencies ok). Such hits are dropped, saying why and how far apart hits
    must be; the first hit of each test is still used."""
    rotor, brg, remnant = rawsim.example_rig()
    times = (0.6, 0.9, 1.2, 1.5)
    recs = [rawsim.impact_recording(rotor, brg, speed_rpm=1000.0, plane=0.0, direction=d, remnant=remnant, seed=61 + i,
                                    impact_times_s=times, record_s=2.2) for i, d in enumerate("xy")]
    with pytest.warns(UserWarning, match=r"dropped: the response to the previous hit .* space the hits at least 0\.(6|7)\d s"):
        res = pipeline.impact_chain(rotor, recs, band_hz=(20.0, 120.0))
    assert [len(u) for u in res.used] == [1, 1] and len(res.dropped) == 6
    assert all("the response to the previous hit" in why for _, _, why in res.dropped)
    ek, ec = direct_errors(res.identification, brg)
    assert ek < 0.1 and ec < 0.15, (ek, ec)


def test_records_that_end_before_the_response_died_out_are_flagged(impact_records):
    """0.1 s records of the rig's impacts leave 16 % of the response at their end: the FRFs leak
    (K off by 18 %, C by 16 %, every point ok before; an independent simulator's finding). Every
    point is now flagged, with a warning; a 30 ms exponential window, or 0.25 s records, are
    clean and unflagged."""
    rotor, brg, recs = impact_records
    with pytest.warns(UserWarning, match=r"not died out by the end of the 0\.1 s records"):
        short = pipeline.impact_chain(rotor, recs, band_hz=(20.0, 120.0), record_s=0.1).identification
    assert not short.ok.any() and all("response not decayed in the record" in f for f in short.flag)
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)
        warnings.filterwarnings("ignore", message=".*coherence.*")
        windowed = pipeline.impact_chain(rotor, recs, band_hz=(20.0, 120.0), record_s=0.1,
                                         exp_window_tau_s=0.03).identification
    assert windowed.ok.all()
    ek, ec = direct_errors(windowed, brg)
    assert ek < 0.03 and ec < 0.03, (ek, ec)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        full = pipeline.impact_chain(rotor, recs, band_hz=(20.0, 120.0)).identification  # 0.25 s records
    assert not any("response not decayed" in f for f in full.flag)


def test_a_probe_that_hardly_responds_does_not_flag_a_decayed_record():
    """A probe in the direction not hit, whose response is a few noise widths (isotropic bearings,
    no cross-coupling): the scatter of its noise estimate against its own small peak must not read
    as a response left at the end of the record (found in review)."""
    rng = np.random.default_rng(2)
    n, pre = 2500, 100
    t = np.arange(n) / 10000.0
    y = np.zeros((6, 4, n))
    for i in range(6):
        y[i] = 1e-7 * rng.standard_normal((4, n))                   # 0.1 µm noise on every probe
        y[i, 0, pre:] += 5e-5 * np.exp(-t[: n - pre] / 0.02) * np.sin(2 * np.pi * 60 * t[: n - pre])
        y[i, 1, pre:] += 5e-7 * np.exp(-t[: n - pre] / 0.02) * np.sin(2 * np.pi * 60 * t[: n - pre])
    assert pipeline._undecayed(list(y), pre) < 0.01
    # the same strong probe cut off before it died out is seen
    slow = y.copy()
    slow[:, 0, pre:] += 5e-5 * np.exp(-t[: n - pre] / 0.5) * np.sin(2 * np.pi * 40 * t[: n - pre])
    assert pipeline._undecayed(list(slow), pre) > 2 * pipeline.DECAYED


def _with_hump_keyphasor(rec, sigma_samples=1.4):
    """The recording with its keyphasor replaced by Gaussian pulses (no flat top) whose half peak
    on the leading flank falls where the original pulses' edges do."""
    fs = rec.fs_hz
    ev = signals.keyphasor_times(rec.channels["kp"], fs).times
    t = np.arange(rec.channels["kp"].size) / fs
    sig = sigma_samples / fs
    v = np.zeros_like(t)
    for e in ev:
        a, b = np.searchsorted(t, [e - 8 * sig, e + 10 * sig])
        v[a:b] += 5.0 * np.exp(-0.5 * ((t[a:b] - e - sig * np.sqrt(2 * np.log(2))) / sig) ** 2)
    return Recording(fs, {**rec.channels, "kp": v}, dict(rec.meta), source=rec.source)


def test_a_keyphasor_timing_the_pulse_shape_leaves_ambiguous_widens_the_error_bars(imbalance_records):
    """Pulses without a flat top: where angle zero lies on them depends on the level chosen by
    0.1-0.15 samples, and 0.023 samples moved the damping by 7 % in an independent simulator's runs
    while every point stayed ok with the truth outside its 95 % interval. That timing uncertainty
    is now a delay of the phase reference in the coefficients' error bars."""
    rotor, brg, runs, base, slow = imbalance_records
    plain_res = pipeline.imbalance_chain(rotor, runs, baseline=base)
    plain = plain_res.identification
    humps = [_with_hump_keyphasor(r) for r in runs]
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        res = pipeline.imbalance_chain(rotor, humps, baseline=_with_hump_keyphasor(base))
    ident = res.identification
    kps = [k for t in res.tracks for k in t.keyphasors]
    shape_std = max(k.timing_std_s for k in kps)
    assert 0.05 / runs[0].fs_hz < shape_std < 0.3 / runs[0].fs_hz
    assert any("no flat top" in str(w.message) for w in seen)
    assert any("depends on the pulse shape" in n and "counted in the uncertainty" in n for n in res.notes)
    # (the flat-topped pulses have a phase reference too at these round speeds, whose pulses fall at
    # 1-3 positions within a sample at 10 kHz: the uncertainty their edges' samples leave, 0.005-0.025
    # sample)
    assert ident.std_source.endswith("+ phase reference")
    assert max(k.timing_std_s for t in plain_res.tracks for k in t.keyphasors) < 0.03 / runs[0].fs_hz < shape_std
    # the same data otherwise: wider error bars that cover the truth of the direct coefficients
    assert np.all(ident.c_std >= plain.c_std) and np.any(ident.c_std > 2 * plain.c_std)
    iv = ident.interval(0.95)
    for b, i, j in DIRECT:
        truth_c, truth_k = brg.c[b, i, j], brg.k[b, i, j]
        assert np.all((iv.c_lower[:, b, i, j] <= truth_c) & (truth_c <= iv.c_upper[:, b, i, j]))
        assert np.all((iv.k_lower[:, b, i, j] <= truth_k) & (truth_k <= iv.k_upper[:, b, i, j]))
    # at each speed: Omega times the pulses' own timing uncertainty there (not one delay for all),
    # their mean (systematic errors: the 1X's is at most the mean of theirs)
    shape_deg = pipeline._keyphasor_phase_std(kps, ident.axis, 2.0)
    expect = np.rad2deg(ident.axis * np.pi / 30 * np.array([
        max(np.mean(0.5 * (k.timing_std_each_s[1:] + k.timing_std_each_s[:-1])[np.abs(k.speed_rpm - g) <= 0.005 * g])
            for k in kps) for g in ident.axis]))
    np.testing.assert_allclose(shape_deg, expect, rtol=1e-12)
    # an angle the user states adds to it (root sum of squares), and the sum is what is propagated
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        more = pipeline.imbalance_chain(rotor, humps, baseline=_with_hump_keyphasor(base),
                                        keyphasor_angle_std_deg=0.1).identification
    # (with the baseline's keyphasors, as the chain takes them: the largest over the keyphasors)
    hump_base = _with_hump_keyphasor(base)
    blocks = getattr(hump_base, "blocks", [hump_base])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        kps_all = kps + [signals.keyphasor_times(b.channels["kp"], b.fs_hz) for b in blocks]
    grid_deg = pipeline._keyphasor_phase_std(kps_all, ident.axis, 2.0)
    direct = rotorid.identify_synchronous(rotor, res.responses, shared_cov=res.shared_cov,
                                         keyphasor_angle_std_deg=np.hypot(0.1, grid_deg))
    np.testing.assert_allclose(more.c_std, direct.c_std, rtol=1e-9)


def test_cli_states_a_phase_reference_uncertainty_in_the_error_bars(tmp_path):
    """``keyphasor_angle_std_deg`` in the [imbalance] section: the coefficients' standard errors
    grow by it (the damping most), the coefficients stay as they are."""
    import pandas as pd

    from rotorid import cli

    d = tmp_path / "ex"
    assert cli.main(["example", "--out", str(d)]) == 0
    text = (d / "imbalance.toml").read_text()
    (d / "stated.toml").write_text(text.replace("[imbalance]\n", "[imbalance]\nkeyphasor_angle_std_deg = 0.5\n", 1))
    assert "keyphasor_angle_std_deg" in (d / "stated.toml").read_text()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert cli.main(["identify", "imbalance", str(d / "imbalance.toml")]) == 0
        assert cli.main(["identify", "imbalance", str(d / "stated.toml"), "--out", str(d / "out_stated")]) == 0
    a = pd.read_csv(d / "out_imbalance" / "coefficients_imbalance.csv")
    b = pd.read_csv(d / "out_stated" / "coefficients_imbalance.csv")
    np.testing.assert_allclose(b.Cxx1, a.Cxx1, rtol=1e-12)
    assert np.all(b.Cxx1_std >= a.Cxx1_std) and np.all(b.Cxx1_std > 1.5 * a.Cxx1_std)
    (d / "bad.toml").write_text(text.replace("[imbalance]\n", "[imbalance]\nkeyphasor_delay_std_s = -1\n", 1))
    assert cli.main(["identify", "imbalance", str(d / "bad.toml")]) == 1


def test_a_sample_rate_in_the_wrong_unit_is_refused_not_fitted(imbalance_records):
    """fs given in kHz (10 instead of 10,000): the keyphasor then gives 3-6 rpm, and the runs
    describe a similar rotor with coefficients a million times too small, every point ok (found
    by an independent simulator). Such runs are refused, naming the run, its file and the fix."""
    rotor, brg, runs, base, slow = imbalance_records
    khz = [Recording(r.fs_hz / 1000.0, r.channels, r.meta, source="run_S0.csv") for r in runs]
    with pytest.raises(RotoridError, match=r"run 0 \(run_S0.csv\): its fastest speed is 6 rpm at a sample rate of "
                                           r"10 Hz: is the sample rate in Hz\?"):
        pipeline.imbalance_chain(rotor, khz, baseline=base)
    with pytest.raises(RotoridError, match=r"baseline.*fastest speed is 6 rpm"):
        pipeline.imbalance_chain(rotor, runs, baseline=Recording(base.fs_hz / 1000.0, base.channels, base.meta))
    # a 1X table whose speeds are all below 60 rpm (speeds of 25-50 here)
    tracks = [signals.track(r) for r in runs[:2]]
    slow = [signals.SyncTrack(t.speed_rpm / 120.0, t.vectors, t.orders, t.n_revs, t.scatter, t.t_mid) for t in tracks]
    with pytest.raises(RotoridError, match=r"run 0: its fastest speed is 50 rpm in its speed column: are the speeds "
                                           r"in rpm\?"):
        pipeline.imbalance_chain(rotor, slow)


def test_keyphasor_phase_uncertainty_of_a_coast_down_speed_no_revolution_is_near():
    """A coast-down 6000 -> 1000 rpm in 8 s whose per-pulse timing uncertainty grows as the speed
    falls (a mark of fixed angular width: 10 µs at 6000 rpm, 60 µs at 1000 rpm, 0.36 degrees at
    every speed). Near 1000 rpm the revolutions are 10-40 rpm apart, beyond the 5 rpm tolerance:
    those grid speeds take the angle of the revolutions nearest in speed (the median over all
    pulses in seconds gave 1000 rpm 0.23 of its uncertainty, the nearest in seconds 0.87), and a
    grid speed beyond the record the angle at its end."""
    from rotorid.signals.keyphasor import Keyphasor

    t = np.linspace(0.0, 8.0, 200_001)
    rpm_t = 6000.0 - 5000.0 * t / 8.0
    rev = np.cumsum(rpm_t / 60.0) * (t[1] - t[0])
    times = np.interp(np.arange(1, int(rev[-1])), rev, t)
    kp = Keyphasor.from_times(times)
    kp.timing_std_each_s = 1e-5 * 6000.0 / np.interp(times, t, rpm_t)
    kp.timing_std_s = float(np.median(kp.timing_std_each_s))
    grid = np.arange(1000.0, 6001.0, 50.0)
    reached = np.array([np.any(np.abs(kp.speed_rpm - g) <= max(2.0, 0.005 * g)) for g in grid])
    assert 3 <= (~reached).sum() <= 20 and not reached[0]
    got = pipeline._keyphasor_phase_std([kp], grid, 2.0)
    want = np.rad2deg(grid * np.pi / 30.0 * 1e-5 * 6000.0 / grid)  # 0.36 degrees at every speed
    np.testing.assert_allclose(got, want, rtol=0.02)
    # beyond either end of the record: the angle of the revolutions at that end
    beyond = pipeline._keyphasor_phase_std([kp], np.array([800.0, 7000.0]), 2.0)
    np.testing.assert_allclose(beyond, [0.36, 0.36], rtol=0.02)
    # pulses whose timing uncertainty is unknown (NaN) are left out, not spread as NaN
    kp.timing_std_each_s[-3:] = np.nan
    np.testing.assert_allclose(pipeline._keyphasor_phase_std([kp], grid[:3], 2.0), want[:3], rtol=0.02)


ANGLES = {"x1": 45.0, "y1": 135.0, "x2": 30.0, "y2": 120.0}
ANGLED_NAMES = {"x1": "DE A", "y1": "DE B", "x2": "FE A", "y2": "FE B", "kp": "KP"}
ANGLED_MAP = {ANGLED_NAMES[c]: {"to": c, "angle_deg": ANGLES[c]} for c in ANGLES} | {"KP": {"to": "kp"}}


def _angled_lab_file(rec, path, dead=None, rng=None):
    """``rec`` as probes at ``ANGLES`` would have recorded it, saved as a lab TDMS file in µm; the
    probe mapped to ``dead`` reads a 2 mm gap and 0.5 µm noise only (a dead probe). Returns the
    recording loaded with ``angle_deg`` and without it (as if the probes were x and y)."""
    from rotorid import io as rio
    from rotorid.recording import Recording

    ch = {"kp": rec.channels["kp"]}
    for xn, yn in (("x1", "y1"), ("x2", "y2")):
        for c in (xn, yn):
            a = np.radians(ANGLES[c])
            ch[c] = np.cos(a) * rec.channels[xn] + np.sin(a) * rec.channels[yn]  # SI: saved in µm
    if dead is not None:
        ch[dead] = -2e-3 + 0.5e-6 * rng.standard_normal(ch[dead].size)
    rio.save_tdms(Recording(rec.fs_hz, ch, {}), path, names=ANGLED_NAMES,
                  units={c: "um" for c in ANGLES} | {"kp": "V"})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return rio.load_recording(path, channel_map=ANGLED_MAP), rio.load_recording(
            path, channel_map={k: {kk: vv for kk, vv in v.items() if kk != "angle_deg"} for k, v in ANGLED_MAP.items()})


def _example_imbalances():
    """The runs' added imbalances as a config gives them (lab files carry no such metadata)."""
    return [rotorid.Imbalance(tuple(m * 1e-3 for m in mass_g), ang, name=name) for name, (mass_g, ang) in ex.SETS.items()]


def test_imbalance_chain_on_probes_mounted_at_angles(imbalance_records, tmp_path):
    """The same runs recorded by probes at 45° either side of vertical (45° and 135° from +x) at
    plane 1 and at 30° and 120° at plane 2, saved as lab TDMS files in µm: with ``angle_deg`` in
    the channel map the chain identifies what it identifies from x and y probes (to 2e-12);
    without it, as if the probes were x and y, the coefficients are those of a rotated frame."""
    rotor, brg, runs, base, slow = imbalance_records

    def angled(rec, i):
        return _angled_lab_file(rec, tmp_path / f"run{i}.tdms")

    loaded = [angled(r, i) for i, r in enumerate(runs + [base])]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        want = pipeline.imbalance_chain(rotor, runs, baseline=base).identification
        imbs = _example_imbalances()
        got = pipeline.imbalance_chain(rotor, [a for a, _ in loaded[:-1]], baseline=loaded[-1][0],
                                       imbalances=imbs).identification
        rotated = pipeline.imbalance_chain(rotor, [b for _, b in loaded[:-1]], baseline=loaded[-1][1],
                                           imbalances=imbs).identification
    np.testing.assert_allclose(got.k, want.k, rtol=1e-10, atol=1e-10 * np.abs(want.k).max())
    np.testing.assert_allclose(got.c, want.c, rtol=1e-10, atol=1e-10 * np.abs(want.c).max())
    assert got.ok.all() == want.ok.all()
    ek, _ = direct_errors(rotated, brg)
    assert ek > 1.0, ek  # 26 (2,600 %)


@pytest.mark.parametrize("dead", ["x1", "y2"])
def test_a_dead_probe_mounted_at_an_angle_is_refused(imbalance_records, tmp_path, dead):
    """A dead probe (gap voltage and noise) among probes mounted at angles: its partner fills both
    the x and the y resolved from them, so the x/y vectors alone looked alive (an independent
    review: K and C off 40-240 % with the run accepted). The check now looks at what each probe
    reads."""
    rotor, brg, runs, base, slow = imbalance_records
    rng = np.random.default_rng(4)
    loaded = [_angled_lab_file(r, tmp_path / f"run{i}.tdms", dead, rng)[0] for i, r in enumerate(runs + [base])]
    with pytest.raises(RotoridError, match=rf"probe channel\(s\) {dead} \(the probe at {ANGLES[dead]:g}°\) show no 1X "
                                           "response above their noise"):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            pipeline.imbalance_chain(rotor, loaded[:-1], baseline=loaded[-1], imbalances=_example_imbalances())


def test_a_dwell_partly_uncorrected_states_the_mean_of_its_pulses_timing_uncertainty():
    """RC edges of 0.45 sample at 100.503 samples per revolution: the first two thirds of the dwell
    are corrected (stated 0.0004 sample, though 0.004-0.006 off: README Known limits), its last
    third creeps too slowly to correct (0.12 sample), and the dwell's mean timing is 0.027 sample
    off. Its phase reference took the median over the pulses
    (0.0004 sample); the errors being common to the pulses of a stretch, the 1X's is at most their
    mean, which is what it takes now."""
    fs, rpm = 10000.0, 60.0 * 10000.0 / 100.503
    ev = rawsim.event_times(rpm, 600.5 * 60.0 / rpm + 0.01373917, mark_time_s=0.01373917)
    v = rawsim.pulse_train(np.arange(int((600.5 * 60.0 / rpm + 0.01373917) * fs)) / fs, ev, fs,
                           rawsim.PulseShape("rc", 0.45))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        kp = signals.keyphasor_times(v, fs)
    near = np.abs(ev[:, None] - kp.times[None, :]).argmin(axis=0)
    err_deg = abs(np.mean(kp.times - ev[near])) * rpm * 6.0          # s -> degrees at rpm
    stated = pipeline._keyphasor_phase_std([kp], [rpm], 2.0)[0]
    assert err_deg > 0.05                                               # (0.10 degrees)
    assert stated >= 0.5 * err_deg, (stated, err_deg)                   # (the median: 0.0015)


def test_a_dwell_whose_pulses_time_exactly_states_no_phase_uncertainty_of_another():
    """Segmented dwells, one keyphasor each: a keyphasor whose pulses all time exactly (no timing
    uncertainty) was left out, so its speed took the nearest revolutions of another dwell, and a
    test whose 6000 rpm dwell had 0.12 sample stated 0.42 degrees at every clean speed (found in
    review: 9 of 13 speeds of an RC-edge test). It counts as 0 at the speeds it reaches; a speed no
    keyphasor reaches still takes the nearest revolutions (as an angle)."""
    from rotorid.signals.keyphasor import Keyphasor

    def kp(rpm, std_samples):
        t = np.arange(200) * 60.0 / rpm
        each = None if std_samples is None else np.full(t.size, std_samples / 10240.0)
        return Keyphasor(t, timing_std_s=0.0 if each is None else float(each[0]), timing_std_each_s=each)

    deg = pipeline._keyphasor_phase_std([kp(3000.0, None), kp(6000.0, 0.12)], [3000.0, 6000.0], 2.0)
    np.testing.assert_allclose(deg, [0.0, 6000.0 * 6.0 * 0.12 / 10240.0])
    assert pipeline._keyphasor_phase_std([kp(3000.0, None)], [3000.0, 6000.0], 2.0) is None
    carried = pipeline._keyphasor_phase_std([kp(6000.0, 0.12)], [3000.0, 6000.0], 2.0)
    np.testing.assert_allclose(carried, [6000.0 * 6.0 * 0.12 / 10240.0] * 2)


def test_a_recordings_local_keyphasor_uncertainty_turns_its_own_vectors():
    """The part of a keyphasor's timing uncertainty local to its dwells (where the pulses fall
    between samples) is a phase error of that recording's 1X vectors alone: the covariance the
    chain adds to them (probes and pedestal motion turned together) against the spread of the
    vectors under random draws of that turn."""
    from rotorid.signals.keyphasor import Keyphasor

    fs = 10240.0
    t = np.r_[np.arange(200) * 60.0 / 3000.0, 200 * 60.0 / 3000.0 + np.arange(1, 201) * 60.0 / 4000.0]
    local = np.where(t < 200 * 60.0 / 3000.0, 0.05, 0.12) / fs       # samples -> s
    kp = Keyphasor(t, timing_std_s=float(np.median(local)), timing_std_each_s=1.5 * local, local_std_each_s=local)
    rng = np.random.default_rng(3)
    q = (rng.standard_normal((2, 1, 4)) + 1j * rng.standard_normal((2, 1, 4))) * 1e-5
    p = (rng.standard_normal((2, 1, 4)) + 1j * rng.standard_normal((2, 1, 4))) * 1e-6
    track = signals.SyncTrack(np.array([3000.0, 4000.0]), q, (1,), np.array([200, 200]), np.zeros((2, 4)),
                              np.array([2.0, 5.0]), keyphasors=[kp], pedestal=p)
    grid = np.array([3000.0, 4000.0])
    add = pipeline._local_phase_cov(track, grid, 2.0, True)
    sd = np.deg2rad(grid * 6.0 * np.array([0.05, 0.12]) / fs)          # the angle of the local timing
    for i in range(2):
        e = rng.standard_normal(400_000) * sd[i]
        dq, dp = q[i, 0] * np.exp(1j * e[:, None]), p[i, 0] * np.exp(1j * e[:, None])
        x = np.concatenate([dq.real, dq.imag, dp.real, dp.imag], axis=1)
        c = np.cov(x, rowvar=False)
        for got, want in ((add["cov"][i], c[:8, :8]), (add["pedestal_cov"][i], c[8:, 8:]),
                          (add["pedestal_cross"][i], c[:8, 8:])):
            np.testing.assert_allclose(got, want, atol=0.01 * np.abs(want).max())
    # a keyphasor whose pulses time exactly adds nothing
    import dataclasses

    assert pipeline._local_phase_cov(dataclasses.replace(track, keyphasors=[Keyphasor(t)]), grid, 2.0, True) is None


def test_the_chains_phase_calibration_reports_applies_and_keeps_the_local_part():
    """imbalance_chain(phase_calibration=...) through its helper: "report" leaves the vectors and,
    given no stated phase uncertainty to weigh its finding against (``used_kw`` None), the
    identification as they are (the chain's own path is tested below), "apply" corrects them and states the calibration's uncertainty with
    the keyphasor's local part beside it as a phase common to the runs at its speed (a phase error
    of one speed alone, which theta - Omega tau cannot follow) where too few speeds carry the phase
    scatter between speeds (5 speeds: 2 degrees of freedom); with 8 (5 degrees of freedom) the
    scatter stands in for that copy (the chain keeps the local part in each recording's covariance);
    too few speeds for a calibration leave a note, not an error."""
    from noisy import turned_nsf_runs

    rpm = np.arange(3200.0, 6001.0, 400.0)
    rig, runs = turned_nsf_runs(rpm, 0.4, rel_noise=0.002, seed=5)
    ident = rotorid.identify_synchronous(rig.rotor, runs)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        notes = []
        same, kept, cal, _ = pipeline._phase_calibrated(rig.rotor, runs, ident, "forces", {}, None, False, notes)
        assert same is runs and kept is ident and notes == [cal.message]
        assert abs(cal.offset_deg - 0.4) < 3 * cal.offset_std_deg   # (0.28 +- 0.19 deg at this noise)
        _, bare, cal0, _ = pipeline._phase_calibrated(rig.rotor, runs, ident, "forces", {}, None, True, [])
        local = np.zeros(rpm.size)
        local[3] = 0.3
        notes = []
        fixed, wide, cal8, _ = pipeline._phase_calibrated(rig.rotor, runs, ident, "forces", {}, local, True, notes)
        # 5 speeds: the scatter rests on 2 degrees of freedom, the local part's common copy stays
        five = [_at_speed_indices(r, [0, 2, 3, 5, 7]) for r in runs]
        ident5 = rotorid.identify_synchronous(rig.rotor, five)
        _, bare5, _, _ = pipeline._phase_calibrated(rig.rotor, five, ident5, "forces", {}, None, True, [])
        notes5 = []
        _, wide5, cal5, _ = pipeline._phase_calibrated(rig.rotor, five, ident5, "forces", {}, local[[0, 2, 3, 5, 7]], True,
                                                    notes5)
    assert "applied" in notes[-1] and not np.allclose(fixed[0].q, runs[0].q)
    def z(i):
        return np.abs((i.c - rig.bearings.c) / i.c_std)[:, :, [0, 1], [0, 1]].max()

    assert z(ident) > 5 and z(bare) < 3.5, (z(ident), z(bare))   # (measured 9.1 and 2.2)
    # 8 speeds: the calibration's scatter stands in for the common copy (the same calibration as
    # without the local part, whose own copy is in each recording's covariance in the chain)
    assert cal8.scatter_dof == 5 and "in each recording's covariance" in notes[-1], (cal8, notes[-1])
    np.testing.assert_allclose(wide.c_std, bare.c_std, rtol=1e-9)
    # 5 speeds: the speed with a local part is stated wider; the others keep the calibration's own
    assert cal5.scatter_dof == 2 and "common to the runs" in notes5[-1], (cal5, notes5[-1])
    assert np.all(wide5.c_std[2] > 1.5 * bare5.c_std[2])
    np.testing.assert_allclose(np.delete(wide5.c_std, 2, axis=0), np.delete(bare5.c_std, 2, axis=0), rtol=0.05)
    notes = []
    two = [_at_speed_indices(r, [0, 1]) for r in runs]
    # asked to apply it, a calibration that cannot be made is a warning, not only a note
    with pytest.warns(UserWarning, match="could not be calibrated"):
        out = pipeline._phase_calibrated(rig.rotor, two, ident, "forces", {}, None, True, notes)
    assert out[1] is ident and out[2] is None and notes[0].startswith("phase reference not calibrated")
    with pytest.raises(RotoridError, match="phase_calibration"):
        pipeline.imbalance_chain(rig.rotor, [runs[0]], phase_calibration="yes")


def test_a_reported_calibration_lets_its_scatter_stand_in_for_the_local_parts_common_copy():
    """"report" (the CLI's default): where the calibration's phase scatter rests on enough degrees of
    freedom (8 speeds: 5) it stands in for the keyphasor's local part counted as common to the runs,
    which leaves the phase uncertainty the chain stated (the user's and the pulse shape's stay); with
    5 speeds (2 degrees of freedom) that copy stays beside the scatter. (The chain over 20 trials,
    RC keyphasor edges of 0.5 sample: 59 % of the points ok before, README "Uncertainty".)"""
    from noisy import turned_nsf_runs

    rpm = np.arange(3200.0, 6001.0, 400.0)
    rig, runs = turned_nsf_runs(rpm, 0.0, rel_noise=0.002, seed=5)
    local = np.zeros(rpm.size)
    local[3] = 0.3
    user, shape = 0.05, np.hypot(0.1, local)      # the shape's part holds the local part
    used = dict(keyphasor_angle_std_deg=np.hypot(user, shape))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ident = rotorid.identify_synchronous(rig.rotor, runs, **used)
        notes = []
        same, kept, cal, _ = pipeline._phase_calibrated(rig.rotor, runs, ident, "forces", {}, local, False, notes, used)
        alone = rotorid.calibrate_phase(rig.rotor, runs)      # not weighted by the local part
        found = np.sqrt(np.clip(cal.error_deg(rpm) ** 2 - cal.line_std_deg(rpm) ** 2, 0, None))
        want = rotorid.identify_synchronous(rig.rotor, runs, keyphasor_angle_std_deg=np.hypot(
            np.fmax(np.hypot(user, 0.1), found), cal.scatter_std_deg(rpm)))
        five_idx = [0, 2, 3, 5, 7]
        five = [_at_speed_indices(r, five_idx) for r in runs]
        used5 = dict(keyphasor_angle_std_deg=used["keyphasor_angle_std_deg"][five_idx])
        ident5 = rotorid.identify_synchronous(rig.rotor, five, **used5)
        notes5 = []
        _, kept5, cal5, _ = pipeline._phase_calibrated(rig.rotor, five, ident5, "forces", {}, local[five_idx], False,
                                                    notes5, used5)
        found5 = np.sqrt(np.clip(cal5.error_deg(rpm[five_idx]) ** 2 - cal5.line_std_deg(rpm[five_idx]) ** 2, 0, None))
        want5 = rotorid.identify_synchronous(rig.rotor, five, keyphasor_angle_std_deg=np.sqrt(
            np.fmax(np.hypot(user, 0.1), found5) ** 2 + local[five_idx] ** 2 + cal5.scatter_std_deg(rpm[five_idx]) ** 2))
    assert same is runs and cal.scatter_dof == 5 and "standing in for the keyphasor's local" in notes[-1], notes
    assert cal.offset_deg == alone.offset_deg and cal.scatter_deg == alone.scatter_deg
    assert np.all(found < 0.1), found     # (no phase error: the stated part stays the larger)
    np.testing.assert_allclose(kept.c_std, want.c_std, rtol=1e-9)
    assert np.all(kept.c_std[3] < 0.8 * ident.c_std[3]), (kept.c_std[3], ident.c_std[3])
    assert cal5.scatter_dof == 2 and "standing in" not in notes5[-1], notes5
    np.testing.assert_allclose(kept5.c_std, want5.c_std, rtol=1e-9)


def test_a_reported_calibration_keeps_the_phase_error_it_found_in_the_error_bars():
    """"report" leaves the vectors as measured, so a phase reference error the calibration finds
    stays in the coefficients: its estimate theta - Omega tau (with its uncertainty) enters their
    error bars where larger than what was stated. A mark 0.4 degree off at 0.03 % noise: the direct
    damping's intervals covered the truth 7 % of the time with every point ok, now all but 1 in 240
    and every point "uncertain" (``apply`` takes the error out; the chain with a 0.3 degree mark over
    20 trials: 61 % of the points ok, none of them covered, README)."""
    from noisy import turned_nsf_runs

    rpm = np.arange(3200.0, 6001.0, 200.0)
    rig, exact = turned_nsf_runs(rpm, 0.0, rel_noise=0.0, seed=0)
    b = rig.bearings
    before, after, ok = [], [], []
    for seed in range(8):
        _, runs = turned_nsf_runs(rpm, 0.4, rel_noise=3e-4, seed=seed, exact=exact)
        used = dict(keyphasor_angle_std_deg=0.02)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            ident = rotorid.identify_synchronous(rig.rotor, runs, **used)
            notes = []
            _, kept, cal, _ = pipeline._phase_calibrated(rig.rotor, runs, ident, "forces", {}, None, False, notes, used)
        assert cal.significant and "phase reference error the calibration found" in notes[-1], notes

        def hits(i):
            iv = i.interval(0.95)
            return ((iv.c_lower <= b.c) & (b.c <= iv.c_upper))[:, :, [0, 1], [0, 1]].mean()

        before.append(hits(ident))
        after.append(hits(kept))
        ok.append(kept.ok.mean())
    assert np.mean(before) < 0.5 and np.mean(after) >= 0.95, (before, after, ok)


def test_a_reported_calibration_that_finds_nothing_adds_nothing():
    """The phase error a reported calibration puts in the error bars is its moment estimate
    sqrt(max(e² - s_line², 0)) where that exceeds what was stated: an offset within its own
    uncertainty adds nothing (sqrt(e² + s_line²), tried first, added the calibration's uncertainty
    to vectors it never corrects: 10,000 Hz recordings went from 39 to 21 % of the points ok, found
    in review), one well beyond it adds itself, and beyond 44 degrees it is counted as 44 (the
    identification takes less than 45: a mark 60 degrees off refused the whole chain)."""
    from rotorid.phasecal import PhaseCalibration

    rpm = np.array([3000.0, 4500.0, 6000.0])
    stated = np.full(3, 0.02)
    quiet = PhaseCalibration(0.05, 0.1, 0.0, 0.0, 1.0, 8, False, "")
    phase, why = pipeline._reported_phase_std(quiet, rpm, stated, None, stand_in=False)
    np.testing.assert_allclose(phase, stated, rtol=1e-12)
    assert why == []
    off = PhaseCalibration(0.5, 0.1, 0.0, 0.0, 1.0, 8, True, "")
    phase, why = pipeline._reported_phase_std(off, rpm, stated, None, stand_in=False)
    np.testing.assert_allclose(phase, np.sqrt(0.5 ** 2 - 0.1 ** 2), rtol=1e-12)
    assert "calibration found (up to 0.49 deg" in why[0], why
    far = PhaseCalibration(60.0, 0.1, 0.0, 0.0, 1.0, 8, True, "")
    phase, why = pipeline._reported_phase_std(far, rpm, stated, None, stand_in=False)
    assert np.all(phase == pipeline.MAX_REPORTED_PHASE_DEG) and "counted as 44 deg" in why[0], why
    # the stated delay counts in what the finding is compared with (Omega sigma_tau, here 0.54
    # degree at 6000 rpm for 15 µs): used_kw's delay then leaves the re-identification
    from noisy import turned_nsf_runs

    rig, runs = turned_nsf_runs(rpm, 0.3, rel_noise=0.002, seed=3)
    used = dict(keyphasor_delay_std_s=15e-6)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ident = rotorid.identify_synchronous(rig.rotor, runs, **used)
        _, kept, cal, _ = pipeline._phase_calibrated(rig.rotor, runs, ident, "forces", {}, None, False, [], used)
        stated = np.rad2deg(rpm * np.pi / 30 * 15e-6)
        found = np.sqrt(np.clip(cal.error_deg(rpm) ** 2 - cal.line_std_deg(rpm) ** 2, 0, None))
        want = rotorid.identify_synchronous(rig.rotor, runs, keyphasor_angle_std_deg=np.hypot(
            np.fmax(stated, found), cal.scatter_std_deg(rpm)))
    assert np.any(found > stated) and np.any(found < stated), (found, stated)
    np.testing.assert_allclose(kept.c_std, want.c_std, rtol=1e-9)


def test_a_reported_calibration_keeps_a_speed_off_the_line_in_the_error_bars():
    """"report" (the CLI's default) leaves the vectors uncorrected but keeps the phase errors of each
    speed alone that the calibration finds: with one speed 0.4 degree off among 15 (no offset), only
    the common scatter was added and that speed's coefficients were covered 5 % of the time, flagged
    ok in 87 % (found in review); its own error is added now."""
    from noisy import turned_nsf_runs

    rpm = np.arange(3200.0, 6001.0, 200.0)
    rig, exact = turned_nsf_runs(rpm, 0.0, rel_noise=0.0, seed=0)
    turn = np.where(np.arange(rpm.size) == 5, 0.4, 0.0)
    hits = []
    for seed in range(6):
        _, runs = turned_nsf_runs(rpm, turn, rel_noise=3e-4, seed=seed, exact=exact)
        ident = rotorid.identify_synchronous(rig.rotor, runs)
        notes = []
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            _, kept, cal, _ = pipeline._phase_calibrated(rig.rotor, runs, ident, "forces", {}, None, False, notes, {})
        assert cal.outlier_speeds_rpm == (rpm[5],) and f"off the line with their own: {rpm[5]:g} rpm" in notes[-1], \
            (cal, notes)
        if seed == 0:   # applied, the note names them too
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                _, _, cal_a, _ = pipeline._phase_calibrated(rig.rotor, runs, ident, "forces", {}, None, True, notes, {})
            assert cal_a.outlier_speeds_rpm == (rpm[5],) and f"speeds off its line ({rpm[5]:g} rpm)" in notes[-1], notes
        iv = kept.interval(0.95)
        b = rig.bearings
        hits.append(np.r_[((iv.k_lower[5] <= b.k) & (b.k <= iv.k_upper[5])).ravel(),
                          ((iv.c_lower[5] <= b.c) & (b.c <= iv.c_upper[5])).ravel()])
    assert np.mean(hits) >= 0.9, np.mean(hits)


def _at_speed_indices(r, idx):
    """The run at the speeds ``idx`` only."""
    return rotorid.SyncResponse(r.speed_rpm[idx], r.q[idx], r.imbalance, r.at, r.name, r.cov[idx])


def test_the_chain_adds_each_recordings_local_keyphasor_uncertainty_to_its_covariance(monkeypatch):
    """Every run's 1X covariance grows by its own keyphasor's local part and the baseline's (which
    every run has subtracted), the shared covariance by the baseline's, each turned about the
    recording's own (uncompensated) vectors: the chain against the same chain without it."""
    rotor, brg, remnant = rawsim.example_rig()
    speeds = [3000.0, 3500.0, 4000.0]
    kw = dict(speeds_rpm=speeds, remnant=remnant, kp_shape=rawsim.PulseShape("rc", 0.5, duty=0.03), dwell_s=1.0)
    runs = [rawsim.lab_imbalance_recording(rotor, brg, added=imb, seed=i, **kw) for i, imb in enumerate(_example_imbalances())]
    base = rawsim.lab_imbalance_recording(rotor, brg, added=None, seed=9, **kw)
    turn = pipeline._local_phase_cov
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = pipeline.imbalance_chain(rotor, runs, baseline=base)
        bt = signals.track(base, orders=(1, 2, 3))
        monkeypatch.setattr(pipeline, "_local_phase_cov", lambda *a: None)
        bare = pipeline.imbalance_chain(rotor, runs, baseline=base)
    grid = res.responses[0].speed_rpm
    assert np.all(res.keyphasor_local_std_deg[[0, 2]] > 0.05)      # 5 positions within a sample there
    b = turn(bt, grid, 2.0, False)["cov"]
    np.testing.assert_allclose(res.shared_cov - bare.shared_cov, b, rtol=1e-9, atol=1e-12 * np.abs(b).max())
    for r, r0, t in zip(res.responses, bare.responses, res.tracks):
        want = turn(t, grid, 2.0, False)["cov"] + b
        np.testing.assert_allclose(r.cov - r0.cov, want, rtol=1e-9, atol=1e-12 * np.abs(want).max())


def _few_hit_draws(seeds, *, n_hits=2, spread_m=0.0, hum_m=0.0, first_s=1.0, burst=0.0, **kw):
    """(coverage of the 95 % intervals of every K and C, median width of the direct K's intervals
    relative to K, the tests' :class:`rotorid.impact_noise.Pooling`, the warnings) of the impact
    chain on the example rig's x and y tests with ``n_hits`` impacts 0.7 s apart from ``first_s``
    on; ``spread_m``: the hits after the first land that far (rms) from the plane the chain is told;
    ``hum_m``: a 50 Hz hum on every probe, in step with the hits (35 periods apart); ``burst``: a
    50 ms burst of white probe noise that many times the recording's, 0.45 s before the first hit;
    ``kw``: rawsim.impact_recording's options."""
    rotor, brg, remnant = rawsim.example_rig()
    meta = [dict(plane=0.0, direction="x"), dict(plane=0.0, direction="y")]
    hits, widths, pools, warned = [], [], [], set()
    times = tuple(first_s + 0.7 * k for k in range(n_hits))
    for s in seeds:
        recs = []
        for i, d in enumerate("xy"):
            rng = np.random.default_rng(1000 + 10 * s + i)
            r = rawsim.impact_recording(rotor, brg, speed_rpm=2000, plane=0.0, direction=d, remnant=remnant,
                                        impact_times_s=times[:1] if spread_m else times, seed=10 * s + i, **kw)
            if burst:
                a = int((first_s - 0.45) * r.fs_hz)
                for c in ("x1", "x2", "y1", "y2"):
                    r.channels[c][a:a + int(0.05 * r.fs_hz)] += burst * 0.5e-6 * rng.standard_normal(int(0.05 * r.fs_hz))
            for t in times[1:] if spread_m else ():
                e = rawsim.impact_recording(rotor, brg, speed_rpm=2000, plane=spread_m * rng.standard_normal(),
                                            direction=d, runout=None, noise_m=0.0, force_noise_N=0.0,
                                            impact_times_s=(t,))
                for c in ("x1", "x2", "y1", "y2", "force"):
                    r.channels[c] = r.channels[c] + e.channels[c]
            if hum_m:
                t = np.arange(r.n_samples) / r.fs_hz
                for c in ("x1", "x2", "y1", "y2"):
                    r.channels[c] = r.channels[c] + hum_m * np.sin(2 * np.pi * 50.0 * t + rng.uniform(0, 2 * np.pi))
            recs.append(r)
        with warnings.catch_warnings(record=True) as w:
            warnings.simplefilter("always")
            res = pipeline.impact_chain(rotor, recs, band_hz=(20, 120), tests_meta=meta)
        warned |= {str(x.message) for x in w}
        ident = res.identification
        iv = ident.interval(0.95)
        hits.append(np.r_[((iv.k_lower <= brg.k) & (brg.k <= iv.k_upper)).ravel(),
                          ((iv.c_lower <= brg.c) & (brg.c <= iv.c_upper)).ravel()])
        d = (Ellipsis, [0, 1], [0, 1])
        widths.append(((iv.k_upper - iv.k_lower)[d] / np.abs(brg.k[d])).ravel())
        pools += res.poolings
    return np.mean(hits), np.median(np.concatenate(widths)), pools, warned


def test_few_impacts_pool_their_scatter_with_the_noise_measured_before_them(monkeypatch):
    """Two impacts per test gave H1's covariance from their scatter on 1 degree of freedom: 95 %
    intervals of K 2.5 % wide (Student's t of 12.7), three times as wide as one impact's with its
    noise measured (0.8-1.0 %). Pooled with the noise measured on the quiet record before them,
    where the scatter agrees with it (``impact_noise.pooled_frf``): 0.64 % wide, coverage 0.959
    over 20 draws (3 impacts 0.79 -> 0.49 %, 0.957; 5 impacts 0.43 -> 0.36 %, 0.952)."""
    cover, width, pools, _ = _few_hit_draws(range(8))
    assert all(p.n_impacts == 2 and p.measured == 1 for p in pools)
    assert np.mean([p.pooled for p in pools]) >= 0.8, [p.source for p in pools]
    assert all(p.dof_scatter == 1 and p.dof_noise > 4 for p in pools)
    assert "the scatter of its 2 impacts pooled with the noise measured before them (1 + 5.82 dof)" in \
        {p.summary() for p in pools}
    assert cover >= 0.9, cover
    monkeypatch.setattr(impact_noise, "pooled_frf", lambda frf, *a: (frf, impact_noise.Pooling(2, 0, frf.dof)))
    cover_alone, width_alone, _, _ = _few_hit_draws(range(8))
    assert width < width_alone / 2.5 and cover_alone >= 0.9, (width, width_alone)


def test_impacts_that_differ_from_hit_to_hit_keep_the_scatter_alone_and_a_hum_in_step_counts_whole():
    """Hits that land 1-2 mm from where the chain is told differ by more than their noise (the
    scatter's power 2-20 times the noise's over the band): the scatter stands alone, with a warning
    (coverage 0.974-0.978 over 30 draws; hits 0.5 mm apart, half of them pooled, 0.967). A 50 Hz
    hum in step with hits 0.7 s apart is the same in every record and does not average out: the
    impacts scatter a tenth as much as the noise before them, which then counts as coherent over
    them (coverage 0.997; pooled it was 0.931, the scatter alone 0.947 with median |z| 1.08)."""
    cover, _, pools, warned = _few_hit_draws(range(4), n_hits=3, spread_m=0.002)
    assert np.mean([p.source == "scatter" for p in pools]) >= 0.75, [p.source for p in pools]
    assert any("times as much (in power) as the noise measured before them explains" in w for w in warned), warned
    assert any(p.summary().startswith("the scatter of its 3 impacts alone (2 dof; they scatter ") for p in pools)
    assert cover >= 0.9, cover
    cover, _, pools, warned = _few_hit_draws(range(4), n_hits=3, hum_m=3e-7)
    assert all(p.source == "noise in step" and p.shortfall < 0.5 for p in pools), [p.source for p in pools]
    assert any("does not average out" in w for w in warned), warned
    assert all(p.summary().startswith("the scatter of its 3 impacts pooled with the noise measured before them, that "
                                      "noise as the same in every record at ") for p in pools)
    assert all(p.in_step_hz[0] <= 50.0 <= p.in_step_hz[1] for p in pools), [p.in_step_hz for p in pools]
    assert cover >= 0.95, cover


def test_few_impacts_without_the_noise_before_them_say_so_and_a_dropped_first_hit_leaves_its_quiet_record():
    """Two hits 0.5 s into the recordings leave no quiet record before the first to measure the
    noise on: the scatter alone, on 1 dof, with a warning that says how much lead-in would narrow
    the intervals. A first hit followed by a rebound is dropped, and the quiet record before it
    stands for the remaining hits' (the stretch after it holds its ringing): pooled (K's intervals
    2.48 -> 0.61 % wide, coverage 0.953 over 40 draws, review's generator). A burst of noise in the
    lead-in that the event test lets through (segments that only partly hold it) made the
    measured noise larger than the hits': the scatter, short of it over the band, stands alone,
    with a warning ("noise changed"; taken for noise in step with the hits at first, review)."""
    _, _, pools, warned = _few_hit_draws(range(2), first_s=0.5)
    assert all(p.source == "scatter" and p.measured == 0 for p in pools), [p.source for p in pools]
    assert any("rest on their scatter's 1 degree(s) of freedom (95 % intervals 12.7 standard errors wide each way): "
               "too little quiet record before the first hit" in w and "record at least 0.70 s before it" in w
               for w in warned), warned
    cover, width, pools, _ = _few_hit_draws(range(4), n_hits=3, double_hit_at=0)
    assert all(p.n_impacts == 2 and p.measured == 1 and p.pooled for p in pools), [p.summary() for p in pools]
    assert cover >= 0.9 and width < 0.012, (cover, width)
    cover, _, pools, warned = _few_hit_draws(range(4), n_hits=3, burst=10.0)
    assert np.mean([p.source == "noise changed" for p in pools]) >= 0.5, [p.source for p in pools]
    assert any("over the band: that noise is not theirs" in w for w in warned), warned
    assert cover >= 0.9, cover
