"""Monte Carlo study throughput: rotorid's one-pass study (Rust core) vs the best NumPy for the same
work, memory, 1-to-2-core scaling, and identify_synchronous_batch on a user's array.

    python benches/bench_study.py [--trials 10000] [--speeds 1000] [--quick] [--threads 2]

Work (docs/studies.md), per trial and point: simulate the R = 4 exact responses (imbalance runs A-D
of the NSF rig, or 4 impact tests), perturb every 1X vector (amplitude 1 %, phase 0.5 deg) or FRF
(coherence 0.95, 5 impacts), move probes to bearings, identify the 16 coefficients (bearing-force
method), and accumulate the relative errors into streaming histograms, sums and counts;
percentiles 5/50/95 at the end.
  rotorid.studies.synchronous_study / impact_study   the public API (threads over trial blocks,
                                   the core over point blocks, merged in order)
  NumPy (benches/study_baseline.py) blocked over (speeds x trials), 1 and --threads threads, the
                                   block size tuned here; the fastest is "best NumPy". With the full
                                   size NumPy runs --numpy-trials trials and its time is scaled to the
                                   rotorid trial count (linear: every trial is the same work).
Memory: each study in a fresh process, peak RSS above the process after its imports, for 1/10 and
all of the trials (the whole footprint of the study: extension pages, thread pools, histograms). Scaling: the rotorid study in fresh processes pinned to 1 CPU
(sched_setaffinity, which limits the core's threads and the task threads alike) and to 2.
Targets (issue 11): >= 20x the best NumPy on 2 cores, < 500 MB whatever the trial count, 1-to-2-core
scaling > 1.8x; identify_synchronous_batch on a user's complex128 array without a copy, >= 85 % of
the bare core's throughput.
"""

import argparse
import json
import os
import subprocess
import sys
import time
import tracemalloc
from concurrent.futures import ThreadPoolExecutor

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from common import best_of, print_header, quick_args, quiet_blas  # noqa: E402
from study_baseline import _nsf, numpy_impact_study, numpy_sync_study  # noqa: E402

import rotorid  # noqa: E402
from rotorid import _core  # noqa: E402

TARGET = 20.0

_CHILD = r"""
import json, os, resource, sys, time
import numpy as np, rotorid
from rotorid.studies import ImpactErrors, SyncErrors, impact_study, synchronous_study
cpus = json.loads(sys.argv[1]); kind = sys.argv[2]; trials = int(sys.argv[3]); n = int(sys.argv[4])
if cpus:
    os.sched_setaffinity(0, cpus)
rig = rotorid.nsf_rig()
def run(t):
    if kind == "sync":
        return synchronous_study(rig.rotor, rig.bearings, [rig.imbalances[s] for s in "ABCD"],
                                 np.linspace(1000, 7000, n), SyncErrors(amplitude_rel=0.01, phase_deg=0.5), trials=t,
                                 seed=1)
    tests = [(0.0, "x"), (0.0, "y"), (0.05, "x"), (-0.08, "y")]
    return impact_study(rig.rotor, rig.bearings, tests, np.linspace(10.0, 300.0, n),
                        ImpactErrors(coherence=0.95, impacts=5), speed_rpm=3000, trials=t, seed=1)
base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss  # after the imports and the rig
t0 = time.perf_counter()
run(trials)
dt = time.perf_counter() - t0
print(json.dumps(dict(seconds=dt, peak_mb=(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - base) / 1024)))
"""


def child(cpus, kind, trials, n):
    p = subprocess.run([sys.executable, "-c", _CHILD, json.dumps(cpus), kind, str(trials), str(n)],
                       capture_output=True, text=True, timeout=3600)
    if p.returncode != 0:
        raise RuntimeError(p.stderr[-2000:])
    return json.loads(p.stdout.strip().splitlines()[-1])


def numpy_best(fn, trials, blocks, threads, repeat):
    """Fastest (seconds, label) over 1 and ``threads`` threads and the block sizes."""
    best = (np.inf, "")
    for thr in sorted({1, threads}):
        for blk in blocks:
            t = best_of(lambda: fn(blk, thr), repeat, warmup=0)
            if t < best[0]:
                best = (t, f"{thr} thread(s), block {blk}")
    return best


def batch_no_copy(n_trials, n):
    """identify_synchronous_batch on a user's (trials, runs, n, 4) complex128 array vs the bare core
    call: time ratio and the largest allocation during the call (a copy of q would show)."""
    rig = rotorid.nsf_rig()
    rpm = np.linspace(2000, 8000, n)
    imbs = [rig.imbalances[s] for s in "ABCD"]
    q1 = np.stack([rotorid.imbalance_response(rig.rotor, rig.bearings, i, speed_rpm=rpm).q for i in imbs])
    rng = np.random.default_rng(0)
    q = np.ascontiguousarray(q1[None] * (1 + 0.01 * rng.standard_normal((n_trials, 4, n, 4))))
    e = np.stack([i.generalized(rig.rotor) for i in imbs])[None]
    om = rpm * np.pi / 30
    p = rig.rotor.core_params()

    def core():
        return _core.identify(p, om, om, q, e, om ** 2, with_std=False)

    def api():
        return rotorid.identify_synchronous_batch(rig.rotor, rpm, q, imbs)

    t_core = best_of(core, 5)
    t_api = best_of(api, 5)
    tracemalloc.start()
    api()
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return t_core, t_api, peak, q.nbytes


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=None, help="default 10,000 (1,000 with --quick)")
    ap.add_argument("--speeds", type=int, default=None, help="default 1,000 (200 with --quick)")
    ap.add_argument("--numpy-trials", type=int, default=None, help="trials NumPy runs (default: 1,000 or --trials)")
    quick_args(ap)
    args = ap.parse_args()
    T = args.trials or (1000 if args.quick else 10_000)
    n = args.speeds or (200 if args.quick else 1000)
    Tn = min(T, args.numpy_trials or 1000)
    repeat = 1 if args.quick else 2
    _blas = quiet_blas()  # noqa: F841
    print_header("Monte Carlo study", f"{T:,} trials x {n:,} points x 4 runs, simulate + perturb + identify + "
                 "summarize", args.threads)
    from rotorid.studies import ImpactErrors, SyncErrors, impact_study, synchronous_study

    rig = rotorid.nsf_rig()
    p, kb, cb, om, u, planes, probes, _ = _nsf(n, 4)
    pool = ThreadPoolExecutor(args.threads) if args.threads > 1 else None
    blocks = (8000, 16000)
    summary = {}
    for kind in ("sync", "impact"):
        if kind == "sync":
            def ours():
                return synchronous_study(rig.rotor, rig.bearings, [rig.imbalances[s] for s in "ABCD"],
                                         np.linspace(1000, 7000, n), SyncErrors(amplitude_rel=0.01, phase_deg=0.5),
                                         trials=T, seed=1)

            def theirs(blk, thr):
                return numpy_sync_study(p, kb, cb, om, u, planes, probes, 0.01, 0.5, Tn, blk, thr, 1, pool=pool)
        else:
            tests = [(0.0, "x"), (0.0, "y"), (0.05, "x"), (-0.08, "y")]
            w = 2 * np.pi * np.linspace(10.0, 300.0, n)

            def ours():
                return impact_study(rig.rotor, rig.bearings, tests, np.linspace(10.0, 300.0, n),
                                    ImpactErrors(coherence=0.95, impacts=5), speed_rpm=3000, trials=T, seed=1)

            def theirs(blk, thr):
                return numpy_impact_study(p, kb, cb, 3000 * np.pi / 30, w, tests, probes, 0.95, 5, Tn, blk, thr, 1,
                                          pool=pool)
        t_ours = best_of(ours, repeat, warmup=1)
        t_np, label = numpy_best(theirs, Tn, blocks, args.threads, repeat)
        t_np_scaled = t_np * T / Tn
        ratio = t_np_scaled / t_ours
        name = "synchronous" if kind == "sync" else "impact"
        print(f"{name} study: rotorid {t_ours:.3f} s ({1e9 * t_ours / (T * n):.0f} ns per trial-point); best NumPy "
              f"{t_np:.3f} s for {Tn:,} trials ({label})" + (f" -> {t_np_scaled:.3f} s for {T:,}" if Tn != T else "")
              + f"; NumPy / rotorid {ratio:.2f}x   target >= {TARGET:g}x: {'met' if ratio >= TARGET else 'NOT met'}",
              flush=True)
        summary[f"{kind}_s"] = t_ours
        summary[f"{kind}_ratio"] = ratio
    if pool is not None:
        pool.shutdown()

    # memory and scaling, each in a fresh process
    mem = {t: child([], "sync", t, n) for t in (max(T // 10, 1), T)}
    for t, r in mem.items():
        print(f"memory, synchronous study of {t:,} trials x {n:,} speeds: peak {r['peak_mb']:.0f} MB above the "
              f"imported process   target < 500 MB: {'met' if r['peak_mb'] < 500 else 'NOT met'}")
    cpus = sorted(os.sched_getaffinity(0))
    if len(cpus) >= 2:
        t1 = child(cpus[:1], "sync", T // 2, n)["seconds"]
        t2 = child(cpus[:2], "sync", T // 2, n)["seconds"]
        print(f"scaling, synchronous study of {T // 2:,} trials: 1 CPU {t1:.3f} s, 2 CPUs {t2:.3f} s: {t1 / t2:.2f}x   "
              f"target > 1.8x: {'met' if t1 / t2 > 1.8 else 'NOT met'}")
        summary["scaling"] = t1 / t2
    t_core, t_api, peak, qbytes = batch_no_copy(200 if args.quick else 1000, n)
    print(f"identify_synchronous_batch on a user's {qbytes / 1e6:.0f} MB complex128 array: core {1e3 * t_core:.1f} ms, "
          f"API {1e3 * t_api:.1f} ms: {100 * t_core / t_api:.0f} % of the core's throughput (target >= 85 %: "
          f"{'met' if t_core / t_api >= 0.85 else 'NOT met'}); largest Python allocation during the call "
          f"{peak / 1e6:.1f} MB (a copy of q would be {qbytes / 1e6:.0f} MB)")
    summary.update(batch_pct=100 * t_core / t_api, peak_mb=max(r["peak_mb"] for r in mem.values()))
    print("SUMMARY " + json.dumps(dict(work=f"study {T:,} trials x {n:,} points x 4 runs", core_ms=1e3 * summary["sync_s"],
                                       api_ms=1e3 * summary["sync_s"], numpy_ms=1e3 * summary["sync_s"] * summary["sync_ratio"],
                                       numpy_which="study_baseline (scaled)", np_over_core=summary["sync_ratio"],
                                       np_over_api=summary["sync_ratio"], api_pct=100.0, target=f">= {TARGET:g}x",
                                       value=f"{summary['sync_ratio']:.1f}x", met=summary["sync_ratio"] >= TARGET,
                                       **{k: v for k, v in summary.items()})))


if __name__ == "__main__":
    main()
