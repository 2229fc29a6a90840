"""Monte Carlo study throughput: rotorid's one-pass study (Rust core) vs the best NumPy for the same
work, memory, 1-to-2-core scaling, and identify_synchronous_batch on a user's array.

    python benches/bench_study.py [--trials 10000] [--speeds 1000] [--numpy-trials 1000] [--quick] [--threads 2]

Work (docs/studies.md), per trial and point: simulate the R = 4 exact responses (imbalance runs A-D
of the NSF rig at 1000-7000 rpm, or 4 impact tests at 10-300 Hz with the rotor at 3000 rpm),
perturb every 1X vector (amplitude 1 %, phase 0.5 deg) or FRF (coherence 0.95, 5 impacts), move
probes to bearings, identify the 16 coefficients (bearing-force method), and add the relative
errors to streaming histograms, sums and counts; percentiles 5/50/95 at the end. Timed in this
process (best of --repeat interleaved rounds after a warm-up):
  rotorid.studies.synchronous_study / impact_study   the public API: Python threads over blocks of
                                   1024 trials, the core's rayon pool over blocks of 32 points,
                                   counts merged per point range, percentiles read from them
  rotorid core (one call)          the core kernel over every trial and point in one call
                                   (_core.study_accumulate, the API's own arguments): API / core is
                                   the cost of the Python orchestration
  NumPy (benches/study_baseline.py) blocked over (speeds x trials), 1 and --threads threads, two
                                   block sizes; the fastest is "best NumPy". It runs --numpy-trials
                                   trials (default 1,000) and its time is scaled linearly to the
                                   rotorid trial count (every trial is the same work; said so in the
                                   output).
Memory: each study in a fresh process, its peak RSS above the RSS of the process after its imports
(and the rig), for 1/10, 1/2 and all of the trials: the whole footprint of the study (extension
pages, thread pools, histograms), which must not grow with the trials (it grows until every worker
thread has a block of trials, and its own count array: 2 blocks of 1024 on 2 CPUs). The peak is the kernel's high-water
mark VmHWM (/proc/self/status), reset to the current RSS after the imports (/proc/self/clear_refs):
ru_maxrss is the same mark, but in a process started from Python it also holds the parent's
high-water mark from before the exec (vfork), so it would show this bench's own footprint.
Scaling: the rotorid study in fresh processes on 1 CPU (RAYON_NUM_THREADS=1, the Python task pool
at 1 worker (monte_carlo.LOCAL_WORKERS) and the process pinned to one CPU with sched_setaffinity)
and on 2 CPUs (RAYON_NUM_THREADS=2, 2 workers, 2 CPUs), best of --repeat each after a warm-up.
identify_synchronous_batch: a C-contiguous complex128 (trials, runs, n, 4) array of the user's,
the public call vs the bare _core.identify on the same array; the core call is intercepted to see
that it receives the user's buffer itself, and tracemalloc gives the largest allocation.
Targets (the issue): >= 20x the best NumPy on 2 cores, < 500 MB whatever the trial count, 1-to-2-core
scaling > 1.8x; identify_synchronous_batch without a copy of q, >= 85 % of the bare core's speed.
"""

import argparse
import json
import os
import subprocess
import sys
import tracemalloc
from concurrent.futures import ThreadPoolExecutor

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from common import best_of, best_of_each, print_header, quick_args, quiet_blas  # noqa: E402
from study_baseline import _nsf, numpy_impact_study, numpy_sync_study  # noqa: E402

import rotorid  # noqa: E402
from rotorid import _core  # noqa: E402

TARGET = 20.0
MEM_TARGET_MB = 500.0
SCALING_TARGET = 1.8
BATCH_TARGET = 0.85
TESTS = [(0.0, "x"), (0.0, "y"), (0.05, "x"), (-0.08, "y")]

# one study in a fresh process: argv = cpus (json list, [] = all), kind, trials, points, workers
# (0 = default), repeat (0: one cold run for the memory; else a warm-up and the best of repeat)
_CHILD = r"""
import json, os, resource, sys, time
cpus = json.loads(sys.argv[1]); kind = sys.argv[2]; trials = int(sys.argv[3]); n = int(sys.argv[4])
workers = int(sys.argv[5]); repeat = int(sys.argv[6])
if cpus:
    os.sched_setaffinity(0, cpus)   # before the imports: every thread pool is created inside the mask
import numpy as np, rotorid
from rotorid.studies import ImpactErrors, SyncErrors, impact_study, synchronous_study
from rotorid.studies import monte_carlo
knob = hasattr(monte_carlo, "LOCAL_WORKERS")
if workers and knob:
    monte_carlo.LOCAL_WORKERS = workers
rig = rotorid.nsf_rig()
def run(t):
    if kind == "sync":
        return synchronous_study(rig.rotor, rig.bearings, [rig.imbalances[s] for s in "ABCD"],
                                 np.linspace(1000, 7000, n), SyncErrors(amplitude_rel=0.01, phase_deg=0.5), trials=t,
                                 seed=1)
    tests = [(0.0, "x"), (0.0, "y"), (0.05, "x"), (-0.08, "y")]
    return impact_study(rig.rotor, rig.bearings, tests, np.linspace(10.0, 300.0, n),
                        ImpactErrors(coherence=0.95, impacts=5), speed_rpm=3000, trials=t, seed=1)
def status():
    d = dict(line.split(":", 1) for line in open("/proc/self/status"))
    return int(d["VmHWM"].split()[0]), int(d["VmRSS"].split()[0])   # KiB
try:   # the high-water mark back to the current RSS (Linux >= 4.0), so that the import peak does not hide the study's
    with open("/proc/self/clear_refs", "w") as fh:
        fh.write("5")
    reset = True
except OSError:
    reset = False
hwm0, rss0 = status()   # after the imports and the rig
maxrss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
times = []
if repeat:
    run(min(trials, 1024))
for _ in range(max(repeat, 1)):
    t0 = time.perf_counter()
    run(trials)
    times.append(time.perf_counter() - t0)
hwm1, _ = status()
maxrss1 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
core_s = None
if repeat and hasattr(monte_carlo, "_execute"):   # the bare core over the same work: one call, every trial and point
    seen, orig = {}, monte_carlo._execute
    def grab(spec, *a, **k):
        seen["spec"] = spec
        return orig(spec, *a, **k)
    monte_carlo._execute = grab
    run(4)
    monte_carlo._execute = orig
    spec = seen.get("spec")
    if spec is not None and hasattr(spec, "accumulate"):
        core_times = []
        for _ in range(repeat):
            t0 = time.perf_counter()
            spec.accumulate(0, trials, 0, n)
            core_times.append(time.perf_counter() - t0)
        core_s = min(core_times)
print(json.dumps(dict(seconds=min(times), core_seconds=core_s, peak_mb=(hwm1 - (rss0 if reset else hwm0)) / 1024,
                      base_mb=rss0 / 1024,
                      reset=reset, maxrss_mb=(maxrss1 - maxrss0) / 1024, knob=knob,
                      cpus=len(os.sched_getaffinity(0)), rayon=os.environ.get("RAYON_NUM_THREADS"))))
"""


def child(kind, trials, n, cpus=(), workers=0, rayon=None, repeat=0):
    env = dict(os.environ)
    if rayon is not None:
        env["RAYON_NUM_THREADS"] = str(rayon)
    p = subprocess.run([sys.executable, "-c", _CHILD, json.dumps(list(cpus)), kind, str(trials), str(n), str(workers),
                        str(repeat)], capture_output=True, text=True, timeout=3600, env=env)
    if p.returncode != 0:
        raise RuntimeError(f"child ({kind}, {trials} trials) failed:\n{p.stderr[-2000:]}")
    return json.loads(p.stdout.strip().splitlines()[-1])


def numpy_best(fn, blocks, threads, repeat):
    """Fastest (seconds, label) of ``fn(block, threads)`` over 1 and ``threads`` threads and the block
    sizes (each the best of ``repeat``), and every time measured."""
    times = {}
    for thr in sorted({1, threads}):
        for blk in blocks:
            times[(thr, blk)] = best_of(lambda: fn(blk, thr), repeat, warmup=0)
    thr, blk = min(times, key=times.get)
    return times[(thr, blk)], f"{thr} thread{'s' if thr > 1 else ''}, block {blk}", times


def capture_spec(run_small):
    """The core arguments the public study builds (its _Spec), captured from a small run; None if the
    study module no longer works that way (then the core line is left out)."""
    from rotorid.studies import monte_carlo as mc

    seen = {}
    orig = getattr(mc, "_execute", None)
    if orig is None:
        return None

    def grab(spec, *a, **k):
        seen["spec"] = spec
        return orig(spec, *a, **k)

    mc._execute = grab
    try:
        run_small()
    finally:
        mc._execute = orig
    spec = seen.get("spec")
    return spec if spec is not None and hasattr(spec, "accumulate") else None


def batch_no_copy(n_trials, n, repeat):
    """identify_synchronous_batch on a user's (trials, runs, n, 4) complex128 array vs the bare core
    call on the same array: the best times, whether the core received the user's buffer, and the
    largest allocation tracemalloc saw during the public call (NumPy reports its buffers to it)."""
    rig = rotorid.nsf_rig()
    rpm = np.linspace(2000, 8000, n)
    imbs = [rig.imbalances[s] for s in "ABCD"]
    q1 = np.stack([rotorid.imbalance_response(rig.rotor, rig.bearings, i, speed_rpm=rpm).q for i in imbs])
    rng = np.random.default_rng(0)
    q = np.empty((n_trials, 4, n, 4), complex)
    for t in range(n_trials):             # the user's array, built without a trials-sized temporary
        q[t] = q1 * (1 + 0.01 * rng.standard_normal((4, n, 4)))
    assert q.flags.c_contiguous and q.dtype == np.complex128
    e = np.stack([i.generalized(rig.rotor) for i in imbs])[None]
    om = rpm * (np.pi / 30)                # as the API converts (the same rounding)
    p = rig.rotor.core_params()

    def core():
        return _core.identify(p, om, om, q, e, om ** 2, with_std=False)

    def api():
        return rotorid.identify_synchronous_batch(rig.rotor, rpm, q, imbs)

    r_core, r_api = core(), api()
    same = max(float(np.max(np.abs(r_core[i] - r_api[k]) / np.max(np.abs(r_api[k])))) for i, k in ((0, "k"), (1, "c")))
    # the core call the API makes: is its q the user's buffer? (the API reaches the core through
    # rotorid._corecall.core, which keeps each function once: the spy goes there)
    from rotorid import _corecall

    raw = _corecall.core.identify
    got = {}

    def spy(*args, **kwargs):
        got["q"] = args[3]
        return raw(*args, **kwargs)

    _corecall.core.identify = spy
    try:
        api()
    finally:
        _corecall.core.identify = raw
    qa = got.get("q")
    shares = qa is not None and isinstance(qa, np.ndarray) and np.shares_memory(qa, q) and \
        qa.__array_interface__["data"][0] == q.__array_interface__["data"][0]
    times = best_of_each({"core": core, "api": api}, repeat=repeat, warmup=1, inner=2)
    tracemalloc.start()
    api()
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return times["core"], times["api"], peak, q.nbytes, shares, same


def summary_line(**kw):
    print("SUMMARY " + json.dumps(kw), flush=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=None, help="default 10,000 (1,000 with --quick)")
    ap.add_argument("--speeds", type=int, default=None, help="points per study, default 1,000 (200 with --quick)")
    ap.add_argument("--numpy-trials", type=int, default=None,
                    help="trials NumPy runs, its time scaled to --trials (default 1,000, at most --trials)")
    ap.add_argument("--repeat", type=int, default=None, help="timed rounds, default 2 (1 with --quick)")
    quick_args(ap)
    args = ap.parse_args()
    T = args.trials or (1000 if args.quick else 10_000)
    n = args.speeds or (200 if args.quick else 1000)
    Tn = min(T, args.numpy_trials or 1000)
    repeat = args.repeat or (1 if args.quick else 2)
    _blas = quiet_blas()  # noqa: F841  (kept alive: idle OpenBLAS threads would steal a core)
    print_header("Monte Carlo study", f"{T:,} trials x {n:,} points x 4 runs (sync) / 4 tests (impact): simulate + "
                 "perturb + identify + summarize", args.threads)
    from rotorid.studies import ImpactErrors, SyncErrors, impact_study, synchronous_study

    rig = rotorid.nsf_rig()
    imbs = [rig.imbalances[s] for s in "ABCD"]
    rpm = np.linspace(1000, 7000, n)
    f_hz = np.linspace(10.0, 300.0, n)
    p, kb, cb, om, u, planes, probes, _ = _nsf(n, 4)
    pool = ThreadPoolExecutor(args.threads) if args.threads > 1 else None
    blocks = (8000, 16000)
    rows = {}
    for kind in ("sync", "impact"):
        if kind == "sync":
            name = "synchronous"

            def ours(t=T):
                return synchronous_study(rig.rotor, rig.bearings, imbs, rpm,
                                         SyncErrors(amplitude_rel=0.01, phase_deg=0.5), trials=t, seed=1)

            def theirs(blk, thr):
                return numpy_sync_study(p, kb, cb, om, u, planes, probes, 0.01, 0.5, Tn, blk, thr, 1, pool=pool)
        else:
            name = "impact"

            def ours(t=T):
                return impact_study(rig.rotor, rig.bearings, TESTS, f_hz, ImpactErrors(coherence=0.95, impacts=5),
                                    speed_rpm=3000, trials=t, seed=1)

            def theirs(blk, thr):
                return numpy_impact_study(p, kb, cb, 3000 * np.pi / 30, 2 * np.pi * f_hz, TESTS, probes, 0.95, 5, Tn,
                                          blk, thr, 1, pool=pool)
        spec = capture_spec(lambda: ours(8))
        fns = {"api": ours}
        if spec is not None:
            fns["core"] = lambda: spec.accumulate(0, T, 0, n)
        t = best_of_each(fns, repeat=repeat, warmup=1, inner=1)
        t_api, t_core = t["api"], t.get("core")
        t_np, label, np_times = numpy_best(theirs, blocks, args.threads, repeat)
        t_np_scaled = t_np * T / Tn
        r_api = t_np_scaled / t_api
        per_tp = 1e9 / (T * n)
        print(f"{name} study, {T:,} trials x {n:,} points:")
        lab_api = f"rotorid.studies.{name}_study (public API)"
        lab_core = "rotorid core, one _core.study_accumulate call"
        lab_np = f"best NumPy ({label})" + (f", {Tn:,} trials x {T / Tn:g}" if Tn != T else "")
        w = max(len(lab_api), len(lab_core), len(lab_np)) + 2
        print(f"  {lab_api:{w}s} {t_api:8.3f} s  {per_tp * t_api:6.0f} ns per trial-point")
        if t_core is not None:
            print(f"  {lab_core:{w}s} {t_core:8.3f} s  {per_tp * t_core:6.0f} ns per trial-point   "
                  f"(API throughput {100 * t_core / t_api:.0f} % of the core's)")
        print(f"  {lab_np:{w}s} {t_np_scaled:8.3f} s  {per_tp * t_np_scaled:6.0f} ns per trial-point")
        tune = ", ".join(f"{thr} thread{'s' if thr > 1 else ''} block {blk}: {v:.3f} s"
                         for (thr, blk), v in np_times.items())
        print(f"  NumPy on {Tn:,} trials: {tune}")
        if Tn != T:
            print(f"  (NumPy ran {Tn:,} of the {T:,} trials; its time is scaled linearly: every trial is the "
                  "same work)")
        met = r_api >= TARGET
        line = f"  best NumPy / rotorid API {r_api:.2f}x"
        if t_core is not None:
            line += f", / rotorid core {t_np_scaled / t_core:.2f}x"
        print(line + f"   target >= {TARGET:g}x on {args.threads} cores: {'met' if met else 'NOT met'}", flush=True)
        rows[kind] = dict(work=f"{name} study, {T:,} trials x {n:,} points x 4",
                          core_ms=None if t_core is None else 1e3 * t_core,
                          api_ms=1e3 * t_api, numpy_ms=1e3 * t_np_scaled,
                          numpy_which=f"study_baseline, {label}" + (f", {Tn:,} trials scaled" if Tn != T else ""),
                          np_over_core=None if t_core is None else t_np_scaled / t_core, np_over_api=r_api,
                          api_pct=None if t_core is None else 100 * t_core / t_api, api_target="",
                          target=f">= {TARGET:g}x",
                          value=f"{r_api:.1f}x", met=met)
    if pool is not None:
        pool.shutdown()
    print()

    # memory, each study in a fresh process. The API runs blocks of TRIAL_BLOCK trials on up to one
    # worker thread per CPU, each with its own count array, so the footprint grows until every
    # worker has a block (2 blocks on 2 CPUs) and not after: T/10 (1 block at 10,000), T/2 and T.
    from rotorid.studies import monte_carlo as mc

    tb = getattr(mc, "TRIAL_BLOCK", 1024)
    nw = getattr(mc, "LOCAL_WORKERS", None) or os.cpu_count() or 1
    counts = sorted({max(T // 10, 1), max(T // 2, 1), T})
    mem = {}
    for kind in ("sync", "impact"):
        for t in counts:
            r = child(kind, t, n)
            mem[(kind, t)] = r["peak_mb"]
            blocks = -(-t // tb)
            how = "" if r["reset"] else " (no high-water reset: above the import peak)"
            print(f"memory, {'synchronous' if kind == 'sync' else 'impact'} study of {t:,} trials x {n:,} points "
                  f"({blocks} block{'s' if blocks > 1 else ''} of {tb} trials on {min(blocks, nw)} worker"
                  f"{'s' if min(blocks, nw) > 1 else ''}): peak {r['peak_mb']:.0f} MB above the imported process "
                  f"({r['base_mb']:.0f} MB){how}   target < {MEM_TARGET_MB:g} MB: "
                  f"{'met' if r['peak_mb'] < MEM_TARGET_MB else 'NOT met'}", flush=True)
    peak_mb = max(mem.values())
    growth = {t: max(mem[(k, T)] - mem[(k, t)] for k in ("sync", "impact")) for t in counts[:-1]}
    grow_text = ", ".join(f"{round(g):+d} MB from {t:,}" for t, g in growth.items())
    print(f"memory growth to {T:,} trials: {grow_text} (at most, over both studies)")

    # 1-to-2-core scaling, fresh processes
    cpus = sorted(os.sched_getaffinity(0))
    scaling = {}
    if len(cpus) >= 2:
        for kind in ("sync", "impact"):
            one = child(kind, T, n, cpus=cpus[:1], workers=1, rayon=1, repeat=repeat)
            two = child(kind, T, n, cpus=cpus[:2], workers=2, rayon=2, repeat=repeat)
            s = one["seconds"] / two["seconds"]
            scaling[kind] = s
            how = "RAYON_NUM_THREADS=1, " + ("LOCAL_WORKERS=1, " if one["knob"] else "no worker knob, ") + "1 CPU"
            print(f"scaling, {'synchronous' if kind == 'sync' else 'impact'} study of {T:,} trials: 1 core "
                  f"{one['seconds']:.3f} s ({how}), 2 cores {two['seconds']:.3f} s: {s:.2f}x   "
                  f"target > {SCALING_TARGET:g}x: {'met' if s > SCALING_TARGET else 'NOT met'}", flush=True)
            if one.get("core_seconds") and two.get("core_seconds"):
                print(f"  the bare core (one call) in the same processes: 1 core {one['core_seconds']:.3f} s, 2 cores "
                      f"{two['core_seconds']:.3f} s: {one['core_seconds'] / two['core_seconds']:.2f}x")
    else:
        print("scaling: only one usable CPU, not measured")

    # identify_synchronous_batch on a user's array
    nb_trials = 250
    t_core, t_api, alloc, qbytes, shares, same = batch_no_copy(nb_trials, n, 3 if args.quick else 5)
    pct = t_core / t_api
    no_copy = shares and alloc < 0.5 * qbytes
    print(f"\nidentify_synchronous_batch on a user's C-contiguous complex128 q ({nb_trials} trials x 4 runs x {n:,} "
          f"speeds, {qbytes / 1e6:.0f} MB): bare core {1e3 * t_core:.1f} ms, public API {1e3 * t_api:.1f} ms: "
          f"{100 * pct:.0f} % of the core's speed   target >= {100 * BATCH_TARGET:.0f} %: "
          f"{'met' if pct >= BATCH_TARGET else 'NOT met'}")
    print(f"  the core received the user's buffer itself: {'yes' if shares else 'NO (a copy)'}; largest Python-side "
          f"allocation during the call {alloc / 1e6:.2f} MB (a copy of q would be {qbytes / 1e6:.0f} MB); k and c "
          + ("identical to the bare core call's" if same == 0
             else f"differ from the bare core call's by {same:.1e} (relative)"))

    for kind in ("sync", "impact"):
        summary_line(**rows[kind], scaling=scaling.get(kind),
                     peak_mb=max(v for (k, _), v in mem.items() if k == kind))
    summary_line(work=f"study memory, {T:,} trials x {n:,} points (fresh process)", core_ms=None, api_ms=None,
                 numpy_ms=None, numpy_which="-", np_over_core=None, np_over_api=None, api_pct=None,
                 target=f"< {MEM_TARGET_MB:g} MB", value=f"{peak_mb:.0f} MB (to {T:,} trials: {grow_text})",
                 met=peak_mb < MEM_TARGET_MB)
    if scaling:
        s = min(scaling.values())
        summary_line(work=f"study 1-to-2-core scaling, {T:,} trials", core_ms=None, api_ms=None, numpy_ms=None,
                     numpy_which="-", np_over_core=None, np_over_api=None, api_pct=None,
                     target=f"> {SCALING_TARGET:g}x",
                     value=f"sync {scaling['sync']:.2f}x, impact {scaling['impact']:.2f}x",
                     met=s > SCALING_TARGET)
    summary_line(work=f"identify_synchronous_batch, user's array {nb_trials} x 4 x {n:,}", core_ms=1e3 * t_core,
                 api_ms=1e3 * t_api, numpy_ms=None, numpy_which="-", np_over_core=None, np_over_api=None,
                 api_pct=100 * pct, api_target=f">= {100 * BATCH_TARGET:.0f} %",
                 target=f">= {100 * BATCH_TARGET:.0f} %, no copy",
                 value=f"{100 * pct:.0f} %, {'no copy' if no_copy else 'COPY'}", met=pct >= BATCH_TARGET and no_copy)


if __name__ == "__main__":
    main()
