"""Shared helpers for the benchmark scripts: timing and NSF-rig test data."""

import time

import numpy as np

import rotorid


def best_of(fn, repeat=5, warmup=1):
    for _ in range(warmup):
        fn()
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def nsf_runs(n_speeds, names="ABCD", lo=2000.0, hi=10000.0):
    rig = rotorid.nsf_rig()
    rpm = np.linspace(lo, hi, n_speeds)
    runs = [rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances[n], speed_rpm=rpm) for n in names]
    return rig, rpm, runs


def blas_info():
    try:
        from threadpoolctl import threadpool_info

        return "; ".join(f"{i.get('internal_api')} {i.get('version')} ({i.get('architecture')}, {i.get('num_threads')} threads)"
                         for i in threadpool_info())
    except ImportError:
        return "threadpoolctl not installed"


def quiet_blas():
    """Limit OpenBLAS to one thread for the whole benchmark. The NumPy baselines only call LAPACK
    on tiny (16 x 16) matrices, which run single-threaded anyway, but idle OpenBLAS worker threads
    keep spinning after each call and steal the second core from whatever is timed next."""
    try:
        from threadpoolctl import threadpool_limits

        return threadpool_limits(1)
    except ImportError:
        return None
