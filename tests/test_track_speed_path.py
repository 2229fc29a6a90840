"""The order-tracking fast path of ``signals.track`` against a straightforward reference.

``track`` takes each revolution's order vectors by one matrix product with a table of cosines
and sines and removes the drift ramp from the bins (the DFT is linear) instead of transforming
the whole detrended revolution with ``np.fft.rfft``. These tests compute the reference the plain
way (one resampling call over all revolutions, mean, ``np.gradient``, ramp subtraction, full
``rfft``, bins kept, 2/P) and require the same numbers to 1e-12 of the largest vector (and to the
rounding of a large offset), across
grids (odd and even P, small and large), orders, channel counts, drifting speeds,
slow non-synchronous drifts and offsets; and the same NaN where the samples are NaN.
"""

import numpy as np
import pytest

from rotorid import RotoridError, _core, signals
from rotorid.recording import Recording
from rotorid.signals import order

TOL = 1e-12


def _reference_per_rev(x, fs, t0, kpt, k0, k1, p, orders):
    """(revs, n_orders, C): the plain computation, all revolutions in one resampling call."""
    res = _core.angle_resample(np.ascontiguousarray(x), fs, t0, np.ascontiguousarray(kpt), k0, k1, p)
    m = res.mean(axis=2)
    step = np.gradient(m, axis=1) if m.shape[1] > 1 else np.zeros_like(m)
    ramp = np.arange(p) / p - 0.5
    det = res - step[:, :, None] * ramp[None, None, :]
    spec = np.fft.rfft(det, axis=2)[:, :, list(orders)] * (2.0 / p)
    return spec.transpose(1, 2, 0)


def _signals(n_ch, fs, duration_s, rpm0, rpm1, *, dc=0.0, drift=0.0, noise=0.0, seed=0):
    """(C, N) synchronous vibration (orders 1-4) at a speed going linearly rpm0 -> rpm1, with an
    offset ``dc``, a slow non-synchronous drift (``drift`` m over the record) and noise; the
    keyphasor times (theta = 2 pi k)."""
    rng = np.random.default_rng(seed)
    n = int(duration_s * fs)
    t = np.arange(n) / fs
    om = (rpm0 + (rpm1 - rpm0) * t / duration_s) * np.pi / 30
    theta = 0.3 + np.cumsum(om) / fs
    x = np.empty((n_ch, n))
    for c in range(n_ch):
        amp = rng.uniform(2e-6, 10e-6, 4) * rng.choice([-1, 1], 4)
        ph = rng.uniform(0, 2 * np.pi, 4)
        x[c] = sum(amp[k] * np.cos((k + 1) * theta + ph[k]) for k in range(4))
        x[c] += dc * (c + 1) + drift * (t / duration_s) ** 2 + noise * rng.standard_normal(n)
    kpt = np.interp(2 * np.pi * np.arange(1, int(theta[-1] / (2 * np.pi)) + 1), theta, t)
    return x, kpt


def _mean_covariance_reference(v, max_batches=16):
    """The covariance of the mean of the per-revolution vectors v (revs, k) by batch means, with
    np.cov: (cov (2k, 2k) of [Re, Im] per group of 4 channels, dof)."""
    n, k = v.shape
    nb = min(n, max_batches)
    if nb < 2:
        return np.full((2 * k, 2 * k), np.nan), np.nan
    b = v[: nb * (n // nb)].reshape(nb, n // nb, k).mean(axis=1)
    r = np.concatenate([part for g in range(0, k, 4) for part in (b[:, g:g + 4].real, b[:, g:g + 4].imag)], axis=1)
    return np.cov(r, rowvar=False, ddof=1) / nb, float(nb - 1)


def _close(new, ref, offset=0.0):
    """Equal to TOL of the largest vector (and, for a channel with an ``offset``, to the rounding
    of the offset in its revolution means: 1e-15 of it); NaN at the same places."""
    scale = np.nanmax(np.abs(ref))
    assert np.array_equal(np.isnan(new), np.isnan(ref))
    err = np.nanmax(np.abs(new - ref)) if np.isfinite(ref).any() else 0.0
    assert err <= TOL * scale + 1e-15 * offset, (err, scale, offset)


@pytest.mark.parametrize("p, orders", [(16, (1, 2, 3)), (17, (1, 7)), (64, (1,)), (100, (2, 5, 1)),
                                       (127, (1, 2, 3, 4)), (512, (1, 2, 3)), (4096, (1, 3, 1000)),
                                       (512, (1, 1, 2))])
@pytest.mark.parametrize("n_ch", [1, 4, 8])
def test_order_vectors_match_the_full_rfft(p, orders, n_ch):
    fs = 20000.0
    x, kpt = _signals(n_ch, fs, 1.5, 3000.0, 3400.0, dc=1e-4, drift=3e-6, noise=2e-7, seed=p + n_ch)
    k0, k1 = 1, kpt.size - 2
    ref = _reference_per_rev(x, fs, 0.0, kpt, k0, k1, p, orders)
    new = order._order_vectors(np.ascontiguousarray(x), fs, 0.0, kpt, k0, k1, p, orders)
    assert new.shape == ref.shape == (k1 - k0, len(orders), n_ch)
    _close(new, ref)


@pytest.mark.parametrize("dc", [0.0, 3e-5, 1e-3, 5e-2])
@pytest.mark.parametrize("p", [64, 512, 4096])
def test_large_offsets_keep_the_accuracy_of_the_fft(dc, p):
    """Probes recorded with their gap (an offset up to thousands of times the vibration): the
    channels whose offset dwarfs their orders are summed about their revolution means."""
    fs = 20000.0
    x, kpt = _signals(4, fs, 0.6, 3000.0, 3300.0, dc=dc, drift=1e-6, noise=1e-7, seed=int(1e6 * dc) + p)
    k0, k1 = 1, kpt.size - 2
    ref = _reference_per_rev(x, fs, 0.0, kpt, k0, k1, p, (1, 2, 3))
    new = order._order_vectors(np.ascontiguousarray(x), fs, 0.0, kpt, k0, k1, p, (1, 2, 3))
    for c in range(4):                     # each channel to 1e-12 of its own largest vector
        _close(new[:, :, c], ref[:, :, c], offset=dc * (c + 1))


@pytest.mark.parametrize("k0, k1", [(0, 1), (0, 2), (3, 4), (2, 5)])
def test_one_or_few_revolutions_and_record_ends(k0, k1):
    fs = 5000.0
    x, kpt = _signals(4, fs, 0.8, 2000.0, 2000.0, dc=-3e-5, drift=1e-6, seed=k0 + 3 * k1)
    kpt = kpt - 0.001                      # the first pulse inside the record
    for p in (16, 33, 64):
        ref = _reference_per_rev(x, fs, 0.0, kpt, k0, k1, p, (1, 2))
        _close(order._order_vectors(np.ascontiguousarray(x), fs, 0.0, kpt, k0, k1, p, (1, 2)), ref)


def test_nan_samples_give_nan_where_the_full_rfft_does():
    fs = 10000.0
    x, kpt = _signals(4, fs, 1.0, 3000.0, 3100.0, dc=2e-5, seed=3)
    i = int(0.5 * fs)
    x[2, i] = np.nan                       # one revolution of channel 2 (and its drift neighbours)
    k0, k1 = 1, kpt.size - 2
    for p in (64, 65):
        ref = _reference_per_rev(x, fs, 0.0, kpt, k0, k1, p, (1, 2, 3))
        assert np.isnan(ref).any() and not np.isnan(ref).all()
        new = order._order_vectors(np.ascontiguousarray(x), fs, 0.0, kpt, k0, k1, p, (1, 2, 3))
        _close(new, ref)


def _recording(x, fs, kpt, *, rows=True, t0=0.0, pedestal=None):
    names = ("x1", "x2", "y1", "y2")
    chans = {nm: (x[i] if rows else x[i].copy()) for i, nm in enumerate(names)}
    if pedestal is not None:
        chans.update({nm: pedestal[i] for i, nm in enumerate(("px1", "px2", "py1", "py2"))})
    chans["kp"] = np.zeros(x.shape[1])
    return Recording(fs, chans, t0_s=t0), signals.Keyphasor.from_times(kpt)


def _track_range(rec, kp):
    t_first, t_last = rec.t0_s + 1 / rec.fs_hz, rec.t0_s + (rec.n_samples - 2) / rec.fs_hz
    ok = np.nonzero((kp.times >= t_first) & (kp.times <= t_last))[0]
    return int(ok[0]), int(ok[-1])


@pytest.mark.parametrize("p", [None, 64, 101])
def test_track_vectors_per_revolution_match_the_reference(p):
    fs = 8000.0
    x, kpt = _signals(4, fs, 2.0, 2400.0, 2900.0, dc=5e-5, drift=2e-6, noise=1e-7, seed=11)
    t0 = 0.25
    rec, kp = _recording(x, fs, kpt + t0, t0=t0)
    tr = signals.track(rec, kp=kp, steady=False, revs_per_block=1, orders=(1, 2, 3), points_per_rev=p)
    pp = p or int(max(64, 2 ** int(np.ceil(np.log2(fs * np.max(kp.period_s))))))
    k0, k1 = _track_range(rec, kp)
    ref = _reference_per_rev(x, fs, t0, kp.times, k0, k1, pp, (1, 2, 3))
    assert tr.vectors.shape == ref.shape
    _close(tr.vectors, ref)


def test_track_steady_blocks_cov_scatter_and_pedestal_match_the_reference():
    fs = 10000.0
    x, kpt = _signals(8, fs, 3.0, 3000.0, 3000.0, dc=2e-5, drift=1e-6, noise=3e-7, seed=5)
    rec, kp = _recording(x[:4], fs, kpt, pedestal=x[4:] * 1e3)
    orders = (1, 2)
    tr = signals.track(rec, kp=kp, orders=orders, pedestal=True, points_per_rev=128)
    k0, k1 = _track_range(rec, kp)
    per = _reference_per_rev(np.concatenate([x[:4], x[4:] * 1e3]), fs, 0.0, kp.times, k0, k1, 128, orders)
    rpm = kp.speed_rpm[k0:k1]
    nom = np.asarray(orders)[None, :, None] * (rpm * np.pi / 30)[:, None, None]
    per[:, :, 4:] = per[:, :, 4:] / -(nom ** 2)
    (a, b), = signals.steady_segments(signals.Keyphasor(kp.times[k0:k1 + 1]))
    v = per[a:b]
    _close(tr.vectors[0], v.mean(axis=0)[:, :4])
    _close(tr.pedestal[0], v.mean(axis=0)[:, 4:])
    cov, dof = _mean_covariance_reference(v[:, 0, :])
    # the covariance of batch means is a difference of nearly equal vectors: it carries the
    # vectors' rounding (1e-16 of the offsets) magnified by |vector| / spread of the batch means:
    # 5e-13 measured here
    for got, want in ((tr.cov[0], cov[:8, :8]), (tr.pedestal_cov[0], cov[8:, 8:]), (tr.pedestal_cross[0], cov[:8, 8:])):
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-11 * np.abs(want).max())
    assert tr.dof[0] == dof
    scat = np.sqrt(np.mean(np.abs(v[:, 0, :4] - v[:, 0, :4].mean(axis=0)) ** 2, axis=0))
    np.testing.assert_allclose(tr.scatter[0], scat, rtol=1e-12)


def test_rows_and_separate_channel_arrays_track_identically():
    fs = 6000.0
    x, kpt = _signals(4, fs, 1.5, 1800.0, 2100.0, dc=1e-5, noise=1e-7, seed=2)
    r1, kp = _recording(x, fs, kpt, rows=True)
    r2, _ = _recording(x, fs, kpt, rows=False)
    a = signals.track(r1, kp=kp, steady=False, revs_per_block=3)
    b = signals.track(r2, kp=kp, steady=False, revs_per_block=3)
    for name in ("vectors", "speed_rpm", "scatter", "cov", "dof", "n_revs", "t_mid"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))


@pytest.mark.parametrize("t0", [0.0, 7.25])
def test_separate_channel_arrays_go_to_the_core_as_they_are(t0):
    """Channels stored apart are resampled by the core where they are (a list of arrays): the same
    numbers as one (C, N) array."""
    fs = 7000.0
    x, kpt = _signals(4, fs, 2.0, 2000.0, 2600.0, dc=1e-4, drift=1e-6, noise=1e-7, seed=9)
    kpt = kpt + t0
    k0, k1 = 0, kpt.size - 1
    sources = [row.copy() for row in x]
    for p in (64, 129, 256):
        stacked = order._order_vectors(np.ascontiguousarray(x), fs, t0, kpt, k0, k1, p, (1, 2))
        apart = order._order_vectors(sources, fs, t0, kpt, k0, k1, p, (1, 2))
        np.testing.assert_array_equal(apart, stacked)
        _close(apart, _reference_per_rev(x, fs, t0, kpt, k0, k1, p, (1, 2)), offset=4e-4)


def test_the_core_refuses_channels_of_different_lengths():
    from rotorid import _core

    kp = np.linspace(0.0, 1.0, 11)
    with pytest.raises(ValueError, match=r"x has 99 elements, expected 100 samples in every channel \(channel 1 differs\)"):
        _core.angle_resample([np.zeros(100), np.zeros(99)], 100.0, 0.0, kp, 0, 5, 8)
    with pytest.raises(ValueError, match=r"a channel of x has shape"):
        _core.angle_resample([np.zeros((2, 50))], 100.0, 0.0, kp, 0, 5, 8)
    with pytest.raises(ValueError, match=r"x has shape"):
        _core.angle_resample(np.zeros(100), 100.0, 0.0, kp, 0, 5, 8)
    with pytest.raises(ValueError, match="at least one channel"):
        _core.angle_resample([], 100.0, 0.0, kp, 0, 5, 8)


def _span_reference(times):
    """Speed over the 4 revolutions centred on each (revolutions i-1 .. i+2, fewer at the ends)."""
    n = times.size - 1
    out = np.empty(n)
    for i in range(n):
        lo, hi = max(i - 1, 0), min(i + 3, n)
        out[i] = 60.0 * (hi - lo) / (times[hi] - times[lo])
    return out


def _steady_segments_reference(times, tolerance, min_revs, settle_revs):
    rpm = 60.0 / np.diff(times)
    span = _span_reference(times)
    segs, start = [], 0
    ref = rpm[0] if rpm.size else 0.0
    for i in range(1, rpm.size + 1):
        if i == rpm.size or (abs(rpm[i] - ref) > tolerance * ref and abs(span[i] - ref) > tolerance * ref):
            b, lead = i, start
            while b > max(start, i - 2) and abs(rpm[b - 1] - ref) > tolerance * ref:
                b -= 1
            while lead < min(b, start + 2) and abs(rpm[lead] - ref) > tolerance * ref:
                lead += 1
            a = lead + settle_revs if start > 0 else lead
            if b - a >= min_revs:
                segs.append((a, b))
            start = i
            if i < rpm.size:
                ref = rpm[i]
        elif i - start < 16:
            ref = float(np.median(span[start + 1:i + 1]))
    return segs


def test_steady_segments_match_the_revolution_by_revolution_scan():
    rng = np.random.default_rng(7)
    for _ in range(300):
        n = int(rng.integers(1, 3000))
        levels = rng.choice([2990.0, 3000.0, 3012.0, 3500.0], size=int(rng.integers(1, 6)))
        rpm = np.repeat(levels, -(-n // levels.size))[:n]
        rpm = rpm * (1 + rng.choice([1e-5, 1e-3, 4e-3, 8e-3]) * rng.standard_normal(n))
        if rng.random() < 0.2:
            rpm = np.linspace(3000, 2000, n)
        kp = signals.Keyphasor(np.concatenate([[0.0], np.cumsum(60 / rpm)]))
        for tol, mr, sr in ((0.005, 8, 2), (0.002, 2, 0), (0.01, 1, 5)):
            assert signals.steady_segments(kp, tolerance=tol, min_revs=mr, settle_revs=sr) == \
                _steady_segments_reference(kp.times, tol, mr, sr)


def test_bad_input_still_raises_the_same_errors():
    fs = 5000.0
    x, kpt = _signals(4, fs, 1.0, 3000.0, 3000.0, seed=1)
    rec, kp = _recording(x, fs, kpt)
    with pytest.raises(RotoridError, match="orders must be whole numbers >= 1"):
        signals.track(rec, kp=kp, orders=(0,))
    with pytest.raises(RotoridError, match="orders must be below points_per_rev/2"):
        signals.track(rec, kp=kp, orders=(1, 32), points_per_rev=64)
    with pytest.raises(RotoridError, match="points_per_rev"):
        signals.track(rec, kp=kp, points_per_rev=8)
    with pytest.raises(RotoridError, match="shorter than one revolution"):
        signals.track(rec, kp=signals.Keyphasor.from_times([1.5, 1.52]))
    with pytest.raises(RotoridError, match="NaN"):
        Recording(fs, {"x1": np.r_[np.nan, x[0, 1:]], "x2": x[1], "y1": x[2], "y2": x[3]})


def test_the_core_order_vectors_refuse_bad_arguments_by_name():
    kp = np.linspace(0.0, 1.0, 11)
    x = [np.zeros(100), np.zeros(100)]
    assert _core.order_vectors(x, 100.0, 0.0, kp, 0, 5, 8, [1, 3]).shape == (5, 2, 2)
    with pytest.raises(ValueError, match=r"orders must be from 1 to below p/2 = 4 \(p = 8 points per revolution\), got 4"):
        _core.order_vectors(x, 100.0, 0.0, kp, 0, 5, 8, [1, 4])
    with pytest.raises(ValueError, match="orders must be from 1 to below p/2.*got 0"):
        _core.order_vectors(x, 100.0, 0.0, kp, 0, 5, 8, [0])
    with pytest.raises(ValueError, match="orders needs at least one order"):
        _core.order_vectors(x, 100.0, 0.0, kp, 0, 5, 8, [])
    with pytest.raises(ValueError, match=r"x has 99 elements, expected 100 samples in every channel \(channel 1 differs\)"):
        _core.order_vectors([np.zeros(100), np.zeros(99)], 100.0, 0.0, kp, 0, 5, 8, [1])
    with pytest.raises(ValueError, match=r"x has shape \[100\], expected \(channels, samples\)"):
        _core.order_vectors(np.zeros(100), 100.0, 0.0, kp, 0, 5, 8, [1])
    with pytest.raises(ValueError, match=r"k0, k1 need k0 < k1 < len\(kp\) = 11, got k0 = 5, k1 = 5"):
        _core.order_vectors(x, 100.0, 0.0, kp, 5, 5, 8, [1])
    with pytest.raises(ValueError, match="kp"):
        _core.order_vectors(x, 100.0, 0.0, kp[::-1].copy(), 0, 5, 8, [1])
    with pytest.raises(ValueError, match="fs"):
        _core.order_vectors(x, np.nan, 0.0, kp, 0, 5, 8, [1])
    with pytest.raises(ValueError, match="p .points per revolution. must be at least 4"):
        _core.order_vectors(x, 100.0, 0.0, kp, 0, 5, 3, [1])
    with pytest.raises(OverflowError):
        _core.order_vectors(x, 100.0, 0.0, kp, 0, 5, 8, [-1])


def test_the_core_block_statistics_refuse_bad_arguments_by_name():
    per = np.zeros((10, 2, 4), complex)
    t = np.zeros(10)
    i64 = lambda *v: np.array(v, np.int64)  # noqa: E731
    out = _core.block_statistics(per, t, t, i64(0, 5), i64(5, 5), 1)
    assert [a.shape for a in out] == [(2, 2, 4), (2, 8, 8), (2,), (2,), (2,), (2, 4)]
    with pytest.raises(ValueError, match="block 0 .3 revolutions from 8. is empty or ends past the 10 revolutions"):
        _core.block_statistics(per, t, t, i64(8), i64(3))
    with pytest.raises(ValueError, match="is empty"):
        _core.block_statistics(per, t, t, i64(0), i64(0))
    with pytest.raises(ValueError, match="starts must be >= 0, got -1"):
        _core.block_statistics(per, t, t, i64(-1), i64(2))
    with pytest.raises(ValueError, match=r"lengths has shape \[1\], expected \[2\]"):
        _core.block_statistics(per, t, t, i64(0, 1), i64(2))
    with pytest.raises(ValueError, match="cov_order must be an order index below 2, got 2"):
        _core.block_statistics(per, t, t, i64(0), i64(2), 2)
    with pytest.raises(ValueError, match="max_batches must be at least 2"):
        _core.block_statistics(per, t, t, i64(0), i64(2), 0, 1)
    with pytest.raises(ValueError, match="channels must be at least 4"):
        _core.block_statistics(per[:, :, :3].copy(), t, t, i64(0), i64(2))
    with pytest.raises(ValueError, match=r"rpm has shape \[9\], expected \[10\]"):
        _core.block_statistics(per, t[:9], t, i64(0), i64(2))
    with pytest.raises(ValueError, match=r"per_rev has shape \[10, 8\], expected \(revolutions, orders, channels\)"):
        _core.block_statistics(per.reshape(10, 8), t, t, i64(0), i64(2))
    with pytest.raises(ValueError, match="per_rev must be a C-contiguous array"):
        _core.block_statistics(np.zeros((10, 4, 2), complex).transpose(0, 2, 1), t, t, i64(0), i64(2))
    with pytest.raises(RotoridError, match=r"v must be per-revolution vectors of shape \(revolutions, 4 or 8\)"):
        order.mean_covariance(np.zeros((5, 3), complex))


def test_order_vectors_do_not_depend_on_the_thread_count():
    """Revolutions are summed in tasks of a few revolutions each; the drift slopes join them after
    the tasks. One thread (RAYON_NUM_THREADS=1) gives the same bits as the pool."""
    from thread_runs import outputs_on_threads

    code = ("import numpy as np, sys; sys.path.insert(0, 'tests'); from test_track_speed_path import _signals; "
            "from rotorid.signals import order; x, kpt = _signals(4, 20000.0, 2.0, 3000.0, 3600.0, dc=1e-3, "
            "drift=1e-6, noise=1e-7, seed=4); v = order._order_vectors(list(x), 20000.0, 0.0, kpt, 0, kpt.size - 2, "
            "256, (1, 2, 3)); np.save(sys.argv[1], v)")
    outs = outputs_on_threads(code, timeout=120)
    assert outs[0].shape[0] > 64          # more revolutions than two tasks hold
    np.testing.assert_array_equal(outs[0], outs[1])


@pytest.mark.parametrize("n_ch, i1", [(4, 0), (8, 1), (4, None)])
def test_block_statistics_equal_the_block_by_block_loop(n_ch, i1):
    """Blocks of one length are reduced together; each block's numbers are those of the plain loop
    (mean, np.cov of the 1X vectors' batch means, speed, mid time, scatter of the first order), for
    blocks of mixed lengths (1 revolution: no covariance), steady segments and coast-down blocks."""
    rng = np.random.default_rng(n_ch + (i1 or 7))
    revs, nord = 400, 3
    per_rev = (rng.standard_normal((revs, nord, n_ch)) + 1j * rng.standard_normal((revs, nord, n_ch))) * 1e-6
    per_rev += 3e-5 * np.exp(1j * np.arange(n_ch))        # a common vector, as a real 1X
    rpm = 3000.0 + rng.standard_normal(revs)
    tmid = np.cumsum(60.0 / rpm)
    # lengths 4 and 40 apart (gathered), 7 back to back (views), 1 (no covariance), 37, 250
    blocks = [(0, 1), (1, 41), (41, 45), (45, 49), (60, 60 + 37), (100, 140), (150, 400), (300, 304), (310, 314)] + \
        [(a, a + 7) for a in range(200, 221, 7)]
    starts, lengths = np.array([a for a, _ in blocks]), np.array([b - a for a, b in blocks])
    mean, cov, dof, sp, scat, tm = order._block_statistics(per_rev, rpm, tmid, starts, lengths, i1)
    m = 2 * n_ch
    for j, (a, b) in enumerate(blocks):
        v = per_rev[a:b]
        np.testing.assert_allclose(mean[j], v.mean(axis=0), rtol=1e-14, atol=0)
        if i1 is None:
            assert np.isnan(cov[j]).all() and np.isnan(dof[j])
        else:
            c, d = _mean_covariance_reference(v[:, i1, :])
            assert c.shape == (m, m) and (np.isnan(dof[j]) and np.isnan(d) or dof[j] == d)
            if np.isfinite(c).all():
                np.testing.assert_allclose(cov[j], c, rtol=1e-10, atol=1e-12 * np.abs(c).max())
            else:
                assert np.isnan(cov[j]).all() and b - a == 1
        assert sp[j] == pytest.approx(rpm[a:b].mean(), rel=1e-15) and tm[j] == pytest.approx(tmid[a:b].mean(), rel=1e-15)
        want = np.sqrt(np.mean(np.abs(v[:, 0, :4] - v[:, 0, :4].mean(axis=0)) ** 2, axis=0))
        np.testing.assert_allclose(scat[j], want, rtol=1e-12)


def test_a_coast_down_tracks_every_block_of_revolutions():
    """steady=False: thousands of equal blocks, reduced together, against the per-revolution
    reference averaged block by block."""
    fs = 10000.0
    x, kpt = _signals(4, fs, 6.0, 6000.0, 1500.0, dc=2e-5, drift=1e-6, noise=2e-7, seed=21)
    rec, kp = _recording(x, fs, kpt)
    for rb in (1, 3):
        tr = signals.track(rec, kp=kp, steady=False, revs_per_block=rb, orders=(1, 2), points_per_rev=128)
        k0, k1 = _track_range(rec, kp)
        per = _reference_per_rev(x, fs, 0.0, kp.times, k0, k1, 128, (1, 2))
        nb = (k1 - k0) // rb
        assert tr.vectors.shape == (nb, 2, 4) and nb > 100
        _close(tr.vectors, per[: nb * rb].reshape(nb, rb, 2, 4).mean(axis=1))
        np.testing.assert_allclose(tr.speed_rpm, kp.speed_rpm[k0:k0 + nb * rb].reshape(nb, rb).mean(axis=1), rtol=1e-14)
        assert (np.isnan(tr.cov).all() if rb == 1 else np.isfinite(tr.cov).all())


@pytest.mark.parametrize("revs, k", [(1, 4), (2, 4), (5, 8), (16, 4), (17, 4), (100, 8)])
def test_mean_covariance_is_the_batch_means_covariance(revs, k):
    rng = np.random.default_rng(revs + k)
    v = rng.standard_normal((revs, k)) + 1j * rng.standard_normal((revs, k)) + 5.0
    cov, dof = order.mean_covariance(v)
    want, wdof = _mean_covariance_reference(v)
    assert cov.shape == (2 * k, 2 * k) and (np.isnan(dof) and np.isnan(wdof) or dof == wdof)
    np.testing.assert_allclose(cov, want, rtol=1e-12, atol=1e-14 * np.nanmax(np.abs(want)) if revs > 1 else 0)
