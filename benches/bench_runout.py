"""Run-out filter throughput and effective bandwidth: a 10-million-sample, 4-channel record.

    python benches/bench_runout.py [--samples 10000000] [--repeat 5] [--quick] [--threads 2]

Work: subtract the revolution signature (the run-out template, 256 points per revolution) from
every sample of every channel at the sample's rotor angle from the keyphasor pulses (each
revolution stretched to its own pulse interval; 4-point cubic Lagrange interpolation of the
template; NaN outside the pulses). The template itself is built first from 20 revolutions
(resampled at 256 angles, averaged) and timed separately: it is small work.

Timed in the same process, best of ``repeat`` interleaved rounds of two back-to-back calls (the
two whole-record NumPy variants, seconds each at 10 M samples and never the fastest: one round):
  rotorid._core.runout_subtract   the raw core call
  rotorid.signals.runout_filter   the public API (checks, core call)
  NumPy (benches/baselines.py):   numpy_runout_simple (the original baseline: per-sample searchsorted,
                                  4-point stencils by fancy indexing, whole record) and numpy_runout
                                  (per-interval cubic polynomial tables, revolution runs from the
                                  pulse positions, one gather per coefficient for all channels)
                                  unblocked, blocked on 1 thread and on --threads threads.

The filter reads each input sample once and writes each output sample once, so its effective
bandwidth (bytes read + written / time) is compared with this machine's copy bandwidth, measured
here: best-of-N np.copyto between two arrays of the signal's size (read + write bytes), on one
thread and split over --threads threads, the faster taken. Target: >= 30 % of copy bandwidth.
"""

import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from baselines import numpy_runout, numpy_runout_simple, numpy_signature  # noqa: E402
from common import (Blocks, best_of, best_of_each, check_api, numpy_variants, print_header,  # noqa: E402
                    quick_args, quiet_blas, report)

from rotorid import _core, signals  # noqa: E402

TARGET_PCT = 30.0
# the filter's kernel keeps ~15 arrays of a block's samples live (4 channels at a time for the
# gathers and the polynomial): larger blocks than the identification pay off
RUNOUT_BLOCKS = (8192, 16384, 32768, 65536)
TUNE_SAMPLES = 2_000_000     # the block size is tuned on this many samples (same work per sample)


def make_record(n, fs):
    t = np.arange(n) / fs
    om = (3000 + 30 * np.sin(2 * np.pi * t / t[-1])) * np.pi / 30  # slow speed wander
    theta = np.cumsum(om) / fs
    rng = np.random.default_rng(0)
    x = np.stack([8e-6 * np.cos(theta + c) + 3e-6 * np.cos(2 * theta - c) + 1e-6 * np.sin(3 * theta)
                  + 0.5e-6 * rng.standard_normal(n) for c in range(4)])
    kp = np.interp(2 * np.pi * np.arange(1, int(theta[-1] / (2 * np.pi)) + 1), theta, t)
    return x, kp


def copy_bandwidth(x, repeat, blocks, threads):
    """Bytes read + written per second by np.copyto of an array like x, on 1 and on ``threads``
    threads (each copying a contiguous share). Returns {label: bytes/s}."""
    src = x.reshape(-1)
    dst = np.empty_like(src)
    dst[:] = 0.0                                  # touch the pages before timing
    n = src.size
    t1 = best_of(lambda: np.copyto(dst, src), repeat, warmup=1)
    out = {"np.copyto, 1 thread": 2 * src.nbytes / t1}
    if threads > 1:
        def part(s, e):
            np.copyto(dst[s:e], src[s:e])
        share = -(-n // threads)
        t2 = best_of(lambda: blocks.run(part, n, share, threads), repeat, warmup=1)
        out[f"np.copyto, {threads} threads"] = 2 * src.nbytes / t2
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=None, help="default 10,000,000 (1,000,000 with --quick)")
    ap.add_argument("--repeat", type=int, default=None, help="default 5 (3 with --quick)")
    quick_args(ap)
    args = ap.parse_args()
    n = args.samples or (1_000_000 if args.quick else 10_000_000)
    repeat = args.repeat or (3 if args.quick else 5)
    _blas = quiet_blas()  # noqa: F841
    fs = 20000.0
    x, kp = make_record(n, fs)
    C = x.shape[0]
    print_header("run-out filter", f"{n:,} samples x {C} channels at {fs:g} Hz, {kp.size} revolutions; "
                 "template 256 points/rev from 20 revolutions", args.threads)
    blocks = Blocks(args.threads)
    k0, k1, p = 5, 25, 256

    # -- the template (small work, reported for completeness)
    def sig_core():
        return _core.angle_resample(x, fs, 0.0, kp, k0, k1, p).mean(axis=1)

    def sig_api():
        return signals.revolution_signature(x, fs, kp, kp[k0], kp[k1], points_per_rev=p)

    def sig_numpy():
        return numpy_signature(x, fs, kp, k0, k1, p)

    tmpl = sig_api()
    ts = best_of_each({"core": sig_core, "api": sig_api, "numpy": sig_numpy}, repeat)
    print(f"template: core {1e3 * ts['core']:.3f} ms, public API {1e3 * ts['api']:.3f} ms, NumPy "
          f"{1e3 * ts['numpy']:.3f} ms (NumPy / core {ts['numpy'] / ts['core']:.1f}x); max |difference| "
          f"core vs NumPy {np.abs(sig_core() - sig_numpy()).max():.1e} m")

    # -- the filter
    def core():
        return _core.runout_subtract(x, fs, 0.0, kp, tmpl, 0, n)[0]

    def api():
        return signals.runout_filter(x, fs, kp, tmpl, 0, n)

    n_tune = min(n, TUNE_SAMPLES)
    variants, tuning = numpy_variants(
        blocks, "numpy poly",
        lambda: numpy_runout(x, fs, 0.0, kp, tmpl, 0, n),
        lambda b, t: numpy_runout(x, fs, 0.0, kp, tmpl, 0, n, blocks, b, t),
        RUNOUT_BLOCKS, 2, args.threads,
        tune_fn=lambda b, t: numpy_runout(x, fs, 0.0, kp, tmpl, 0, n_tune, blocks, b, t))
    tuning += f"\n(block sizes tuned on the first {n_tune:,} samples)"
    variants = {"numpy_runout_simple (original), unblocked": lambda: numpy_runout_simple(x, fs, kp, tmpl),
                **variants}
    slow = [k for k in variants if k.endswith("unblocked")]   # whole-record variants: seconds each at 10 M

    ref = core()
    nan_ref = np.isnan(ref)
    print("agreement with rotorid's core (max |difference| in m over the filtered samples; same NaN samples?):")
    out = check_api("public API", api)
    api_ok = out is not None
    for label, fn in [("public API", None), *variants.items()]:
        if fn is not None:
            out = fn()                # one output at a time: each is as large as the record
        elif out is None:
            continue
        same = np.array_equal(np.isnan(out), nan_ref)
        print(f"  {label:44s} {np.nanmax(np.abs(out - ref)):.1e}   {'yes' if same else 'NO'}")
        del out
    ok = ~nan_ref
    print(f"residual rms after filtering {np.sqrt(np.mean(ref[ok] ** 2)) * 1e6:.3f} µm (noise 0.5 µm); "
          f"{int(nan_ref[0].sum())} samples per channel outside the pulses (NaN)")
    print(tuning)

    bw = copy_bandwidth(x, max(5, repeat), blocks, args.threads)
    bw_label = max(bw, key=bw.get)
    bw_ref = bw[bw_label]
    print("copy bandwidth (read + write): " + ", ".join(f"{k} {v / 1e9:.1f} GB/s" for k, v in bw.items())
          + f"; reference: {bw_label}")
    print()

    t = best_of_each({"core": core, **({"api": api} if api_ok else {}),
                      **{k: v for k, v in variants.items() if k not in slow}}, repeat)
    t.update(best_of_each({k: variants[k] for k in slow}, 1, warmup=0))   # 2 calls each (inner)
    moved = 2 * ref.nbytes      # each input sample read once, each output sample written once
    best = min(variants, key=lambda k: t[k])
    print("effective bandwidth (bytes read + written by the filter / time), % of copy bandwidth:")
    for label, sec in (("rotorid._core.runout_subtract", t["core"]),
                       *([("rotorid.signals.runout_filter", t["api"])] if api_ok else []),
                       (f"best NumPy ({best})", t[best])):
        print(f"  {label:60s} {moved / sec / 1e9:6.2f} GB/s  {100 * moved / sec / bw_ref:5.1f} %")
    pct = 100 * moved / t["core"] / bw_ref
    met = pct >= TARGET_PCT
    print(f"core: {pct:.1f} % of copy bandwidth   target >= {TARGET_PCT:g} %: {'met' if met else 'NOT met'}")
    print()
    report(work=f"run-out filter, {n / 1e6:g} M samples x {C} channels", n=C * n, unit="samples",
           core=("rotorid._core.runout_subtract", t["core"]),
           api=("rotorid.signals.runout_filter (public API)", t["api"], None, None) if api_ok else None,
           numpy={k: t[k] for k in variants},
           target_override=("bandwidth", f"{pct:.0f} % of copy", f">= {TARGET_PCT:g} % of copy bandwidth", met),
           extra_summary=dict(core_bandwidth_gbs=moved / t["core"] / 1e9, copy_bandwidth_gbs=bw_ref / 1e9))
    blocks.close()


if __name__ == "__main__":
    main()
