"""Shared helpers for the benchmark scripts: machine description, timing, blocked and threaded
execution of the NumPy baselines, NSF-rig test data and the result report.

Every bench prints the same header (CPU model and SIMD features, cache sizes, NumPy version, its
SIMD dispatch and BLAS, the threads rotorid's core uses and the threads the NumPy baselines use),
times rotorid's raw core function, its public API and every NumPy variant in the same process,
and ends with one ``SUMMARY {json}`` line that ``run_all.py`` collects.
"""

import json
import math
import os
import platform
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np

import rotorid

# SIMD features worth knowing for this work, in the order printed (names as in /proc/cpuinfo).
SIMD_FLAGS = ("sse4_2", "avx", "avx2", "fma", "avx512f", "avx512dq", "avx512cd", "avx512bw", "avx512vl",
              "avx512ifma", "avx512vbmi", "avx512_vnni", "avx512_bf16", "avx512_fp16")


# ---------------------------------------------------------------------------------------------
# machine description

def _read(path):
    try:
        with open(path) as fh:
            return fh.read().strip()
    except OSError:
        return None


def _cache_sizes():
    """{"L1d": "32K", "L2": "512K", "L3": "32768K"} of cpu0 from sysfs (Linux), {} elsewhere."""
    out = {}
    base = "/sys/devices/system/cpu/cpu0/cache"
    try:
        entries = sorted(os.listdir(base))
    except OSError:
        return out
    for ent in entries:
        if not ent.startswith("index"):
            continue
        level, kind, size = (_read(f"{base}/{ent}/{f}") for f in ("level", "type", "size"))
        if level is None or size is None or kind == "Instruction":
            continue
        out[f"L{level}" + ("d" if kind == "Data" else "")] = size
    return out


def _kib(size):
    """'512K' -> 512 (KiB); None if unparsable."""
    if not size:
        return None
    mult = {"K": 1, "M": 1024, "G": 1024 * 1024}
    try:
        return int(size[:-1]) * mult[size[-1].upper()] if size[-1].upper() in mult else int(size) // 1024
    except ValueError:
        return None


def usable_cpus():
    """Logical CPUs this process may run on (affinity mask, then a cgroup CPU quota if lower)."""
    try:
        n = len(os.sched_getaffinity(0))
    except AttributeError:
        n = os.cpu_count() or 1
    quota = _read("/sys/fs/cgroup/cpu.max")  # cgroup v2: "max 100000" or "200000 100000"
    parts = quota.split() if quota else [_read("/sys/fs/cgroup/cpu/cpu.cfs_quota_us"),   # cgroup v1
                                         _read("/sys/fs/cgroup/cpu/cpu.cfs_period_us")]
    try:
        q, period = int(parts[0]), int(parts[1])
        if q > 0 and period > 0:
            n = min(n, max(1, math.ceil(q / period)))
    except (TypeError, ValueError, IndexError):
        pass                                     # "max", -1 or unreadable: no quota
    return n


def cpu_info():
    """CPU model, SIMD flags present/absent (from /proc/cpuinfo), caches and usable CPUs."""
    model, flags = None, set()
    text = _read("/proc/cpuinfo") or ""
    for line in text.splitlines():
        key, _, val = line.partition(":")
        key = key.strip()
        if key == "model name" and model is None:
            model = val.strip()
        elif key in ("flags", "Features") and not flags:
            flags = set(val.split())
        if model and flags:
            break
    caches = _cache_sizes()
    return {
        "model": model or platform.processor() or platform.machine(),
        "simd": [f for f in SIMD_FLAGS if f in flags],
        "simd_absent": [f for f in SIMD_FLAGS if flags and f not in flags],
        "caches": caches,
        "l2_kib": _kib(caches.get("L2")),
        "logical_cpus": os.cpu_count(),
        "usable_cpus": usable_cpus(),
    }


def rotorid_threads():
    """Threads of the core's rayon pool: RAYON_NUM_THREADS when set to a positive number, else
    the available parallelism (affinity mask and cgroup quota), as rayon itself decides."""
    env = os.environ.get("RAYON_NUM_THREADS", "")
    try:
        if int(env) > 0:
            return int(env)
    except ValueError:
        pass
    return usable_cpus()


def numpy_simd():
    """NumPy's SIMD dispatch targets available on this CPU (private attributes; best effort)."""
    try:
        from numpy._core._multiarray_umath import __cpu_dispatch__, __cpu_features__

        on = [t for t in __cpu_dispatch__ if __cpu_features__.get(t)]
        return ", ".join(on) if on else "baseline only"
    except Exception:  # noqa: BLE001  (older or newer NumPy: not essential)
        return "unknown"


def blas_info():
    try:
        from threadpoolctl import threadpool_info

        return "; ".join(f"{i.get('internal_api')} {i.get('version')} ({i.get('architecture')}, "
                         f"{i.get('num_threads')} thread(s))" for i in threadpool_info()) or "none found"
    except ImportError:
        return "threadpoolctl not installed (pip install threadpoolctl)"


def quiet_blas():
    """Limit OpenBLAS to one thread for the whole benchmark. The NumPy baselines only call BLAS and
    LAPACK on tiny matrices (or with one tiny dimension), which run single-threaded anyway, but idle
    OpenBLAS worker threads keep spinning after each call and steal the second core from whatever
    is timed next. The threaded NumPy variants get their parallelism from Python threads instead."""
    try:
        from threadpoolctl import threadpool_limits

        return threadpool_limits(1)
    except ImportError:
        return None


def print_header(title, work, numpy_threads):
    """The machine and software description every bench starts with."""
    ci = cpu_info()
    caches = ", ".join(f"{k} {v}" for k, v in ci["caches"].items()) or "cache sizes unknown"
    print(f"== {title} ==")
    print(f"work        {work}")
    print(f"CPU         {ci['model']} ({ci['usable_cpus']} of {ci['logical_cpus']} logical CPUs usable; {caches})")
    absent = f"; absent: {' '.join(ci['simd_absent'])}" if ci["simd_absent"] else ""
    print(f"SIMD        {' '.join(ci['simd']) or 'none reported'}{absent}")
    cap = os.environ.get("ROTORID_SIMD")
    print(f"rotorid SIMD {rotorid._core.SIMD} kernels (CPU's widest: {rotorid._core.SIMD_CPU}"
          f"{'; capped by ROTORID_SIMD=' + cap if cap else ''})")
    print(f"NumPy       {np.__version__} (SIMD dispatch on this CPU: {numpy_simd()})")
    print(f"BLAS        {blas_info()}")
    env = os.environ.get("RAYON_NUM_THREADS")
    print(f"threads     rotorid core: {rotorid_threads()} (rayon pool; RAYON_NUM_THREADS "
          f"{'= ' + env if env else 'unset'}); NumPy baselines: 1, and {numpy_threads} via a thread pool")
    print(f"rotorid     {rotorid.__version__ if hasattr(rotorid, '__version__') else '?'} "
          f"(core {rotorid._core.__version__})")
    print()


# ---------------------------------------------------------------------------------------------
# timing

def best_of(fn, repeat=5, warmup=1):
    for _ in range(warmup):
        fn()
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def best_of_each(fns, repeat=5, warmup=1, inner=2):
    """Best time of each callable in ``fns`` (name -> fn) over ``repeat`` interleaved rounds, so
    that a load from elsewhere on the machine affects all of them alike. In each round every
    callable runs ``inner`` times back to back (each timed): the first call after another
    callable finds cold caches and, for the core, a sleeping thread pool, which would otherwise
    penalize whichever callable a round starts with."""
    for fn in fns.values():
        for _ in range(warmup):
            fn()
    best = {name: float("inf") for name in fns}
    for _ in range(repeat):
        for name, fn in fns.items():
            for _ in range(max(1, inner)):
                t0 = time.perf_counter()
                fn()
                best[name] = min(best[name], time.perf_counter() - t0)
    return best


# ---------------------------------------------------------------------------------------------
# blocked and threaded execution of the NumPy baselines

class Blocks:
    """Runs ``kernel(start, stop)`` over [0, n) in blocks of ``block`` points, on one thread or on
    ``threads`` Python threads, each taking a contiguous share of whole blocks. NumPy's ufuncs,
    BLAS and LAPACK calls release the GIL, so the threads overlap everything but the Python-level
    dispatch between calls. The pool is created once (like the core's rayon pool) and reused."""

    def __init__(self, threads=2):
        self.threads = max(1, int(threads))
        self.pool = ThreadPoolExecutor(self.threads) if self.threads > 1 else None

    @staticmethod
    def _serial(kernel, lo, hi, block):
        for s in range(lo, hi, block):
            kernel(s, min(s + block, hi))

    def run(self, kernel, n, block=None, threads=1):
        block = n if not block else int(block)
        if threads <= 1 or self.pool is None or n <= block:
            self._serial(kernel, 0, n, block)
            return
        t = min(threads, self.threads)
        nblocks = -(-n // block)
        cuts = [min(n, (nblocks * j // t) * block) for j in range(t + 1)]
        futs = [self.pool.submit(self._serial, kernel, cuts[j], cuts[j + 1], block) for j in range(t)
                if cuts[j] < cuts[j + 1]]
        for f in futs:
            f.result()

    def close(self):
        if self.pool is not None:
            self.pool.shutdown()


def tune_block(make, candidates, repeat=3):
    """Time ``make(block)`` (a callable doing the whole work in blocks of that size) for each
    candidate block size; returns (best block, {block: seconds})."""
    times = best_of_each({b: make(b) for b in candidates}, repeat=repeat)
    return min(times, key=times.get), times


def numpy_variants(blocks, name, unblocked, blocked_fn, candidates, repeat, threads, tune_fn=None):
    """The three standard NumPy variants of one formulation, block sizes tuned on this machine:

    unblocked:            ``unblocked()`` (all points at once);
    blocked, 1 thread:    ``blocked_fn(block, 1)`` with the fastest of ``candidates``;
    blocked, N threads:   ``blocked_fn(block, threads)`` with its own fastest block.

    ``tune_fn(block, threads)`` (default ``blocked_fn``) is what the tuning times: the same work on
    a part of the data, for large inputs. Returns ({label: callable} ready to time, a text line on
    the tuning). The thread count of a variant is in its label (``variant_threads``)."""
    tune_fn = tune_fn or blocked_fn
    b1, t1 = tune_block(lambda b: (lambda: tune_fn(b, 1)), candidates, repeat)
    out = {f"{name}, unblocked": unblocked, f"{name}, blocked {b1}, 1 thread": lambda: blocked_fn(b1, 1)}
    note = f"{name} block tuning, 1 thread: " + ", ".join(f"{b}: {1e3 * t:.2f} ms" for b, t in t1.items())
    if threads > 1:
        b2, t2 = tune_block(lambda b: (lambda: tune_fn(b, threads)), candidates, repeat)
        out[f"{name}, blocked {b2}, {threads} threads"] = lambda: blocked_fn(b2, threads)
        note += (f"\n{name} block tuning, {threads} threads: "
                 + ", ".join(f"{b}: {1e3 * t:.2f} ms" for b, t in t2.items()))
    return out, note


def variant_threads(label):
    """Threads a NumPy variant runs on, from its label (", N threads" at the end; else 1)."""
    tail = label.rsplit(",", 1)[-1].strip()
    if tail.endswith(" threads"):
        try:
            return int(tail.split()[0])
        except ValueError:
            pass
    return 1


# Block sizes tried for every blocked NumPy variant. One (4 runs x 2048 points) complex temporary
# is 128 KiB and the kernels keep a handful live, so 2048-4096 keep the working set in a 512 KiB
# L2; larger blocks trade cache misses for fewer Python-level calls. The fastest is kept per bench
# and per thread count (``numpy_variants``), and printed.
BLOCK_CANDIDATES = (1024, 2048, 4096, 8192, 16384)


# ---------------------------------------------------------------------------------------------
# checks and report

API_FAILURES = []


def record_core_calls(api):
    """The core calls (function, args, kwargs) ``api`` makes, recorded as it runs once (every
    function of ``rotorid._core`` is seen through ``rotorid._corecall.core``)."""
    from rotorid import _corecall

    core = _corecall.core
    calls = []
    names = [n for n in dir(_corecall._raw) if callable(getattr(_corecall._raw, n)) and not n.startswith("_")]
    saved = {n: core.__dict__.get(n) for n in names}
    try:
        for n in names:
            fn = getattr(core, n)
            setattr(core, n, lambda *a, _fn=fn, **k: (calls.append((_fn, a, k)), _fn(*a, **k))[1])
        api()
    finally:
        for n, fn in saved.items():
            if fn is None:
                core.__dict__.pop(n, None)
            else:
                setattr(core, n, fn)
    return calls


def replay(calls):
    """A callable making exactly the recorded core calls again, with the same argument objects:
    the core's share of a public call, to time against it."""
    def run():
        for fn, a, k in calls:
            fn(*a, **k)
    return run


def check_api(label, fn):
    """Call the public API once: its result, or None after printing why it failed (the benches
    then time the core and NumPy only, so a broken API does not hide the core's numbers; the
    failure goes into the SUMMARY line)."""
    try:
        return fn()
    except Exception as exc:  # noqa: BLE001  (reported, and the API is left out of the timing)
        print(f"  {label}: FAILED ({type(exc).__name__}: {exc}); not timed")
        API_FAILURES.append(f"{label}: {type(exc).__name__}: {exc}")
        return None


def rel_diff(a, b):
    """max |a - b| / max |b| over the finite entries of both (NaN where they differ in finiteness)."""
    a = np.asarray(a)
    b = np.asarray(b)
    fa, fb = np.isfinite(a), np.isfinite(b)
    if not np.array_equal(fa, fb):
        return float("nan")
    if not fb.any():
        return 0.0
    return float(np.abs(a[fb] - b[fb]).max() / np.abs(b[fb]).max())


def nsf_runs(n_speeds, names="ABCD", lo=2000.0, hi=10000.0):
    rig = rotorid.nsf_rig()
    rpm = np.linspace(lo, hi, n_speeds)
    runs = [rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances[n], speed_rpm=rpm) for n in names]
    return rig, rpm, runs


def _fmt_ratio(x):
    return f"{x:.1f}x" if x >= 1 else f"{x:.2f}x"


def report(*, work, n, unit, core, api, numpy, target_ratio=None,
           extra_rows=(), per_core=None, extra_summary=None, target_override=None):
    """Print the timing table and the ratios, then the SUMMARY line.

    core:   (label, seconds) of the raw core function (the call closest to the NumPy work);
    api:    (label, seconds, core seconds with the API's own options, note) or None;
    numpy:  {label: seconds} of every NumPy variant (best one chosen here);
    extra_rows: further (label, seconds) lines (shown, not ranked);
    per_core: rotorid's thread count, to report the per-core ratio (NumPy threads from the label);
    target_override: (label, value text, target text, met) replacing the ratio target."""
    best_label = min(numpy, key=numpy.get)
    t_np = numpy[best_label]
    rows = [(core[0], core[1])]
    if api is not None:
        if api[2] is not None and api[2] != core[1]:
            rows.append((api[3], api[2]))
        rows.append((api[0], api[1]))
    rows += list(extra_rows) + list(numpy.items())
    w = max(len(r[0]) for r in rows) + 2
    print(f"{'implementation':{w}s} {'time (ms)':>10s} {unit + '/s':>14s}")
    for label, t in rows:
        mark = "  <- best NumPy" if label == best_label else ""
        print(f"{label:{w}s} {1e3 * t:10.3f} {n / t:14.3e}{mark}")
    print()
    r_core = t_np / core[1]
    print(f"best NumPy: {best_label} ({1e3 * t_np:.3f} ms)")
    line = f"best NumPy / core        {_fmt_ratio(r_core):>8s}"
    met = None
    if target_ratio is not None and per_core is None and target_override is None:
        met = r_core >= target_ratio
        line += f"   target >= {target_ratio:g}x: {'met' if met else 'NOT met'}"
    print(line)
    r_api = api_pct = None
    if api is not None:
        r_api = t_np / api[1]
        print(f"best NumPy / public API {_fmt_ratio(r_api):>8s}")
        ref = api[2] if api[2] is not None else core[1]
        api_pct = 100.0 * ref / api[1]
        which = "core called with the API's options" if api[2] is not None and api[2] != core[1] else "core"
        print(f"public API throughput / core throughput: {api_pct:5.1f} %   target >= 90 %: "
              f"{'met' if api_pct >= 90 else 'NOT met'}   ({which})")
        if api[2] is not None and api[2] != core[1]:
            print(f"public API throughput / minimal core call throughput: {100.0 * core[1] / api[1]:5.1f} %")
    target_text, value_text = None, None
    if per_core is not None:
        thr_core, thr_np = per_core, variant_threads(best_label)
        pc = r_core * thr_np / thr_core
        print(f"per core (NumPy core-seconds / rotorid core-seconds = ratio x {thr_np} / {thr_core}): "
              f"{_fmt_ratio(pc)}", end="")
        if thr_np == 1:
            print(f"   (= ratio / {thr_core} rotorid threads)", end="")
        if target_ratio is not None:
            met = pc >= target_ratio
            print(f"   target >= {target_ratio:g}x per core: {'met' if met else 'NOT met'}")
        else:
            print()
        target_text, value_text = f">= {target_ratio:g}x per core", f"{_fmt_ratio(pc)} per core"
    elif target_override is not None:
        label, value_text, target_text, met = target_override
    elif target_ratio is not None:
        target_text, value_text = f">= {target_ratio:g}x", _fmt_ratio(r_core)
    summary = dict(work=work, core_ms=1e3 * core[1], api_ms=None if api is None else 1e3 * api[1],
                   numpy_ms=1e3 * t_np, numpy_which=best_label, np_over_core=r_core, np_over_api=r_api,
                   api_pct=api_pct, target=target_text, value=value_text, met=met)
    if API_FAILURES:
        summary["api_failed"] = "; ".join(API_FAILURES)
    summary.update(extra_summary or {})
    print("SUMMARY " + json.dumps(summary))
    return summary


def quick_args(ap):
    ap.add_argument("--quick", action="store_true", help="small sizes and few repeats (a few seconds)")
    ap.add_argument("--threads", type=int, default=2, help="threads of the threaded NumPy variant (default 2)")
