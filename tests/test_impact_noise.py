"""One impact's noise (rotorid.impact_noise): measured on the quiet record before the impact,
checked against the H1 errors of many noisy records drawn directly."""

import numpy as np
import pytest

from rotorid import impact_noise, signals

FS, N, PRE = 5000.0, 1000, 50


def _coloured(rng, shape, pole=0.97):
    """AR(1) noise (most of its power below ~25 Hz at 5 kHz), unit-ish variance, along the last axis."""
    e = rng.standard_normal(shape[:-1] + (shape[-1] + 500,))
    out = np.empty_like(e)
    out[..., 0] = e[..., 0]
    for i in range(1, e.shape[-1]):
        out[..., i] = pole * out[..., i - 1] + e[..., i]
    return out[..., 500:] * np.sqrt(1 - pole ** 2)


def _pulse():
    """A 2 ms half-sine hammer pulse starting at PRE, its window, and a 4-channel response to it."""
    t = np.arange(N)
    f = np.where((t >= PRE) & (t < PRE + 10), 800.0 * np.sin(np.pi * (t - PRE) / 10), 0.0)
    fw = signals.force_window(N, 0, PRE + 10 + PRE)
    tt = np.clip(t - PRE, 0, None) / FS
    h = np.stack([np.exp(-a * tt) * np.sin(2 * np.pi * f0 * tt) * 1e-9 for a, f0 in
                  ((20, 40), (30, 65), (25, 90), (40, 120))])
    y = np.stack([np.convolve(f, hc)[:N] for hc in h])
    return f, fw, y


@pytest.mark.parametrize("weighted", [False, True])
def test_the_measured_noise_is_the_mean_square_h1_error_of_noisy_records(weighted):
    """E|dH_c|² from 15 quiet segments of coloured noise (low-frequency, on the probes and on the
    force, with a force offset the resting level takes off), averaged over 20 quiet stretches,
    agrees with the mean |H1 - H|² of 600 records drawn with the same noise, frequency by
    frequency (median ratio 0.9-1.1, 90 % of the frequencies within 0.7-1.4); with an exponential
    window too. One stretch's estimate scatters more where the force noise dominates: at low
    frequencies a short force window's noise spectrum is nearly real, one degree of freedom per
    segment rather than two (ratios 0.4-1.8 over 30 stretches at 5-30 Hz)."""
    f, fw, y = _pulse()
    w = impact_noise.record_window(N, FS, PRE, 0.05 if weighted else None)
    rng = np.random.default_rng(3)
    levels, force_level, offset = np.array([2e-8, 1e-8, 3e-8, 2e-8])[:, None], 20.0, 50.0
    F = np.fft.rfft(f * w)
    with np.errstate(divide="ignore", invalid="ignore"):
        H = np.fft.rfft(y * w, axis=-1).T / F[:, None]
    L = 9 * N
    var = 0.0
    for _ in range(20):
        quiet = (levels * _coloured(rng, (4, L)), offset + force_level * _coloured(rng, (L,)))
        noise = impact_noise.impact_noise(f, y, PRE, fw, quiet)
        assert noise.measured and noise.segments.shape == (15, 4, N)
        var = var + noise.var(H, f * w, w, N) / 20

    draws = 600
    yn = levels[None] * _coloured(rng, (draws, 4, N))
    fn = offset + force_level * _coloured(rng, (draws, N + 64))
    err = np.zeros_like(var)
    for k in range(draws):
        fk = fn[k, 64:]
        rest = np.median(fn[k, PRE:PRE + 64])       # the resting level from the 64 samples before the pulse
        fm = (f + fk - rest) * fw * w
        ym = (y + yn[k]) * w
        H1 = np.fft.rfft(ym, axis=-1).T / np.fft.rfft(fm)[:, None]
        err += np.abs(H1 - H) ** 2
    err /= draws
    freq = np.fft.rfftfreq(N, 1 / FS)
    band = (freq > 5) & (freq < 400)
    ratio = var[band] / err[band]
    assert 0.9 < np.median(ratio) < 1.1, np.median(ratio)
    assert np.mean((ratio > 0.7) & (ratio < 1.4)) > 0.9, np.percentile(ratio, [5, 50, 95])
    # the white model from the samples before the pulse misses the low-frequency excess
    white = impact_noise.impact_noise(f + quiet[1][-N:] - offset, y + quiet[0][:, -N:], PRE, fw)
    assert not white.measured
    low = (freq > 5) & (freq < 30)
    assert np.median(white.var(H, f * w, w, N)[low] / err[low]) < 0.5


def test_quiet_segments_skip_missing_samples_and_events_and_take_the_forces_resting_level():
    """Segments lie on a grid of half a record ending at the stretch's end, at most
    ``QUIET_SEGMENTS``; those holding a missing sample (or whose force's resting-level samples do)
    are skipped, on both sides of it; a force spike (a tap) leaves out the segments it lies in or a
    record before (it rings into them), a burst of response noise the segments it lies in; a
    constant force offset leaves force segments of zero; fewer than two segments give the white
    model (saying why), or None without enough samples before the impact."""
    f, fw, y = _pulse()
    rng = np.random.default_rng(0)
    L = 5 * N
    yq = rng.standard_normal((4, L))
    fq = np.full(L, 7.0) + 0.01 * rng.standard_normal(L)
    yq[2, 2200] = np.nan
    noise = impact_noise.impact_noise(f, y, PRE, fw, (yq, fq))
    assert noise.hop == N // 2 and noise.left_out == 0
    starts = [500, 1000, 2500, 3000, 3500, 4000]      # 1500 and 2000 hold sample 2200
    np.testing.assert_array_equal(noise.segments, np.stack([yq[:, s:s + N] for s in starts]))
    assert np.abs(noise.force_segments).max() < 0.1   # the resting level (7 N) taken off
    long = impact_noise.impact_noise(f, y, PRE, fw, (rng.standard_normal((4, 40 * N)), rng.standard_normal(40 * N)))
    assert long.segments.shape[0] == impact_noise.QUIET_SEGMENTS
    # a tap at sample 3200 of the force: out go the segments from 2500 (it lies in them or a record
    # before them); a burst on one probe at 600-700: out go 500 (and 0, off the grid's start)
    tapped = fq.copy()
    tapped[3200:3205] += 50.0
    burst = np.nan_to_num(yq.copy())
    burst[1, 600:700] *= 20.0
    noise = impact_noise.impact_noise(f, y, PRE, fw, (burst, tapped))
    kept = [1000, 1500, 2000]
    np.testing.assert_array_equal(noise.segments, np.stack([burst[:, s:s + N] for s in kept]))
    assert noise.left_out == 5
    # not events: a quantized force of little noise (its MAD 0, a step now and then), or spikes
    # that recur in every segment (each left every segment out before, review)
    steps = np.round(0.15 * rng.standard_normal(L))
    assert impact_noise.impact_noise(f, y, PRE, fw, (burst, steps)).left_out == 1      # (the burst)
    spikes = 0.01 * rng.standard_normal(L) + 30.0 * (np.arange(L) % 200 == 0)
    assert impact_noise.impact_noise(f, y, PRE, fw, (burst, spikes)).left_out == 1
    # demeaned like records without the run-out filter: each segment less its first PRE samples' mean
    dm = impact_noise.impact_noise(f, y, PRE, fw, (yq + 5.0, fq), demean=True)
    np.testing.assert_allclose(dm.segments[-1][:, :PRE].mean(axis=1), 0.0, atol=1e-12)
    # too little: white from the PRE samples, or nothing below MIN_NOISE_SAMPLES
    short = impact_noise.impact_noise(f, y + rng.standard_normal((4, N)), PRE, fw, (yq[:, -N - 100:], fq[-N - 100:]))
    assert not short.measured and short.dof(np.ones(N)) == PRE - 1 and "less than 1.5 records" in short.why_white
    np.testing.assert_allclose(short.white[1], np.var(f[:PRE], ddof=1))
    spiky = impact_noise.impact_noise(f, y, PRE, fw, (yq[:, -2 * N:], tapped[-2 * N:] + np.r_[50.0, np.zeros(2 * N - 1)]))
    assert not spiky.measured and "an event" in spiky.why_white
    assert impact_noise.impact_noise(f, y, 8, fw, None) is None


def test_the_measured_noises_degrees_of_freedom_follow_the_segments_overlap():
    """Welch's 2K / (1 + 2 (1 - 1/K) rho): unweighted records half overlapping have rho = 1/4; a
    short exponential window leaves neighbouring segments nearly independent (2K)."""
    f, fw, y = _pulse()
    rng = np.random.default_rng(1)
    noise = impact_noise.impact_noise(f, y, PRE, fw, (rng.standard_normal((4, 9 * N)), rng.standard_normal(9 * N)))
    k = noise.segments.shape[0]
    assert noise.dof(np.ones(N)) == pytest.approx(2 * k / (1 + 2 * (1 - 1 / k) * 0.25))
    w = impact_noise.record_window(N, FS, PRE, 0.005)
    assert noise.dof(w) == pytest.approx(2 * k, rel=1e-3)


def _three_hits(rng, gains=(1.0, 1.0, 1.0)):
    """H1 (signals.FRF) of three noisy records of the pulse, its response scaled by ``gains`` per
    hit (a hit that lands elsewhere), their forces, and each hit's :class:`ImpactNoise` measured on a
    quiet stretch of the same noise (coloured on the probes, white on the force)."""
    f, fw, y = _pulse()
    levels = np.array([2e-8, 1e-8, 3e-8, 2e-8])[:, None]
    forces, responses, noises = [], [], []
    for g in gains:
        fk = (f + 5.0 * rng.standard_normal(N)) * fw
        yk = g * y + levels * _coloured(rng, (4, N)) + 1e-8 * rng.standard_normal((4, N))
        quiet = (levels * _coloured(rng, (4, 6 * N)) + 1e-8 * rng.standard_normal((4, 6 * N)),
                 5.0 * rng.standard_normal(6 * N))
        forces.append(fk)
        responses.append(yk)
        noises.append(impact_noise.impact_noise(fk, yk, PRE, fw, quiet))
    return signals.frf_h1(forces, responses, FS), forces, noises


def test_pooled_covariance_is_the_h1_error_of_three_hits_and_scatter_beyond_the_noise_stands_alone():
    """Three hits' scatter (2 dof) pooled with their measured noise: over 60 draws, the pooled
    covariance's power agrees with the mean |H1 - H|² frequency by frequency (median ratio within
    0.85-1.15), the two agreed in at least 90 % of the draws, on 2 + the noise's dof. Hits whose
    responses differ by 20 % (rms) scatter far more than the noise: the scatter stands alone."""
    f, fw, y = _pulse()
    with np.errstate(divide="ignore", invalid="ignore"):
        H = np.fft.rfft(y, axis=-1).T / np.fft.rfft(f * fw)[:, None]
    freq = np.fft.rfftfreq(N, 1 / FS)
    sel = (freq > 10) & (freq < 300)
    re = impact_noise.real_rows(4)
    rng = np.random.default_rng(11)
    stated, err, sources = 0.0, 0.0, []
    for _ in range(60):
        frf, forces, noises = _three_hits(rng)
        pooled, info = impact_noise.pooled_frf(frf, forces, noises, FS, None, None, sel)
        sources.append(info.source)
        err = err + np.abs(frf.h - H)[sel] ** 2 / 60
        if info.pooled:
            assert pooled.dof == pytest.approx(2.0 + info.dof_noise) and info.dof_noise > 10
            stated = stated + (pooled.cov[:, re, re] + pooled.cov[:, re + 4, re + 4])[sel]
    stated = stated / sources.count("pooled")
    assert np.mean([s == "pooled" for s in sources]) >= 0.9, sources
    ratio = np.median(stated / err, axis=0)
    assert np.all((ratio > 0.85) & (ratio < 1.15)), ratio
    for _ in range(5):
        frf, forces, noises = _three_hits(rng, gains=1.0 + 0.2 * rng.standard_normal(3))
        pooled, info = impact_noise.pooled_frf(frf, forces, noises, FS, None, None, sel)
        assert info.source == "scatter" and info.excess > 5 and pooled.cov is frf.cov and pooled.dof == 2
    # no measured noise (the white model only): the scatter alone, nothing compared
    frf, forces, _ = _three_hits(rng)
    white = [impact_noise.impact_noise(fk, np.zeros((4, N)), PRE, fw) for fk in forces]
    pooled, info = impact_noise.pooled_frf(frf, forces, white, FS, None, None, sel)
    assert info.source == "scatter" and info.measured == 0 and pooled is frf


def test_h1_scatter_covariance_counts_each_impacts_leverage_when_the_forces_differ():
    """The scatter of n impacts estimated H1's covariance as n / (n - 1) times the residuals'; each
    impact pulls H1 towards itself by its share w_i = |F_i|² / Σ|F|², so with unequal forces (a
    hammer tip changed after the first hit: a 3 ms pulse, then two of 0.7 ms) the residuals are
    smaller and it under-counted (the chain's intervals covered 0.89, review). Here a 3 ms pulse
    and two of 0.6 ms carry 0.93, 0.035 and 0.035 of the force below 150 Hz: divided by
    1 - Σ w_i², the covariance's mean over 300 draws is the mean |H1 - H|² (median ratio within
    0.9-1.1), where the n / (n - 1) factor gives under 0.5."""
    rng = np.random.default_rng(5)
    t = np.arange(N)
    h = np.exp(-30 * t / FS) * np.sin(2 * np.pi * 80 * t / FS) * 1e-9
    forces = [np.where((t >= PRE) & (t < PRE + d), a * np.sin(np.pi * (t - PRE) / d), 0.0)
              for a, d in ((1000.0, 15), (1000.0, 3), (1000.0, 3))]
    H = np.fft.rfft(h)[:, None]
    # (circular: the records hold exactly H F, so that |H1 - H|² is the noise's alone)
    clean = [np.fft.irfft(np.fft.rfft(f) * H[:, 0], N)[None, :].repeat(4, axis=0) for f in forces]
    freq = np.fft.rfftfreq(N, 1 / FS)
    band = (freq > 10) & (freq < 150)           # where the 3 ms pulse carries most of the force
    re = impact_noise.real_rows(4)
    stated, err = 0.0, 0.0
    for _ in range(300):
        frf = signals.frf_h1(forces, [x + 1e-8 * rng.standard_normal((4, N)) for x in clean], FS)
        stated = stated + (frf.cov[:, re, re] + frf.cov[:, re + 4, re + 4])[band] / 300
        err = err + np.abs(frf.h - H)[band] ** 2 / 300
    F2 = np.array([np.abs(np.fft.rfft(f)) ** 2 for f in forces])[:, band]
    w = F2 / F2.sum(axis=0)
    assert np.median((w ** 2).sum(axis=0)) > 0.7            # one hit carries most of the force there
    ratio = np.median(stated / err, axis=0)
    assert np.all((ratio > 0.9) & (ratio < 1.1)), ratio
    old = np.median(stated * ((1 - (w ** 2).sum(axis=0)) * 3 / 2)[:, None] / err, axis=0)
    assert np.all(old < 0.5), old


def test_the_truncation_terms_share_lowers_a_frequencys_degrees_of_freedom():
    """The truncation term (one extrapolation of the records' last quarter) is credited
    ``TRUNCATION_DOF``: where it dominates, a frequency's dof fall towards it (pooled few hits of
    0.1 s records with a 30 ms window covered 0.915 at 100 Hz on 26 dof, 0.949 now; review);
    where the noise dominates they stay the covariance's; in between, Satterthwaite's."""
    cov = np.zeros((3, 8, 8))
    re = impact_noise.real_rows(4)
    cov[:, re, re] = cov[:, re + 4, re + 4] = 0.5
    extra = np.array([0.0, 1.0, 1e4])[:, None] * np.ones((3, 4))
    dof = impact_noise.with_truncation_dof(cov, extra, 26.0)
    assert dof[0] == pytest.approx(26.0)
    assert dof[1] == pytest.approx(4.0 / (1.0 / 26.0 + 1.0 / impact_noise.TRUNCATION_DOF))
    assert dof[2] == pytest.approx(impact_noise.TRUNCATION_DOF, rel=1e-3)


def test_h1_scatter_covariance_is_nan_not_inf_where_one_impact_carries_all_the_force():
    """Where every other impact's force spectrum is exactly zero (noise-free boxcar pulses), the
    scatter shows nothing: 1 - Σ w_i² = 0, the covariance NaN (the point "uncertainty unknown"),
    not inf, which made the chain fail (review)."""
    rng = np.random.default_rng(2)
    f1 = np.zeros(N)
    f1[PRE:PRE + 10] = 500.0                    # spectral zeros at multiples of FS / 10
    f2 = np.zeros(N)
    f2[PRE:PRE + 7] = 700.0
    frf = signals.frf_h1([f1, f2], [1e-8 * rng.standard_normal((4, N)) for _ in range(2)], FS)
    k = N // 10                                 # FS / 10 Hz: f1 has no force there, f2 all of it
    assert np.all(np.isnan(frf.cov[k])) and not np.isinf(frf.cov).any()
    assert np.isfinite(frf.cov[k - 1]).all()
