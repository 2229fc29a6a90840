"""Run every NumPy-comparison bench in sequence (each in its own process) and print a summary
table for the README.

    python benches/run_all.py [--quick] [--threads 2] [--only identify,modal] [--quiet] [--simd avx2]

``--simd avx2`` measures the AVX2 versions on an AVX-512 machine: rotorid's kernels capped with
``ROTORID_SIMD=avx2``, NumPy's AVX-512 dispatch targets disabled (``NPY_DISABLE_CPU_FEATURES``)
and OpenBLAS run as on Haswell (``OPENBLAS_CORETYPE``), in every bench process. The cores, caches
and memory stay this machine's, so it compares the code paths, not another CPU.

Each bench ends with a ``SUMMARY {json}`` line (common.report; bench_study.py prints one per row:
the two studies, memory, scaling and identify_synchronous_batch); this script collects them. The
CSV-loading bench (bench_csv.py, against pandas) is not part of the set: run it on its own.
"""

import argparse
import json
import os
import subprocess
import sys
import time

sys.path.insert(0, os.path.dirname(__file__))
from common import cpu_info, rotorid_threads  # noqa: E402

BENCHES = ("identify", "impact", "forward", "modal", "runout", "study")


def _ms(v):
    if v is None:
        return ""
    if v >= 100:
        return f"{v:.0f} ms"
    if v >= 10:
        return f"{v:.1f} ms"
    return f"{v:.2f} ms"


def _x(v):
    if v is None:
        return ""
    return f"{v:.1f}x" if v >= 1 else f"{v:.2f}x"


def avx2_env():
    """The environment that runs rotorid, NumPy and OpenBLAS at AVX2 on an AVX-512 CPU."""
    from numpy._core._multiarray_umath import __cpu_dispatch__

    above = [t for t in __cpu_dispatch__ if t.startswith(("AVX512", "X86_V4"))]
    return {"ROTORID_SIMD": "avx2", "NPY_DISABLE_CPU_FEATURES": " ".join(above), "OPENBLAS_CORETYPE": "Haswell"}


def run(name, passthrough, quiet, env=None):
    path = os.path.join(os.path.dirname(os.path.abspath(__file__)), f"bench_{name}.py")
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, path, *passthrough], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            text=True, bufsize=1, env=env)
    summaries = []
    for line in proc.stdout:
        if line.startswith("SUMMARY "):
            summaries.append(json.loads(line[len("SUMMARY "):]))
        elif not quiet:
            print(line, end="", flush=True)
    rc = proc.wait()
    if not quiet:
        print(f"[bench_{name}.py: exit {rc}, {time.perf_counter() - t0:.1f} s]\n", flush=True)
    if rc != 0 or not summaries:
        return [dict(work=f"bench_{name}.py", failed=f"exit {rc}" if rc else "no SUMMARY line")]
    return summaries


def table(rows):
    head = ("work", "rotorid core", "public API", "best NumPy (which)", "NumPy / core", "NumPy / API",
            "API / core", "target", "met?")
    out = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        if "failed" in r:
            out.append(f"| {r['work']} | failed ({r['failed']}) |" + " |" * (len(head) - 2))
            continue
        api_target = r.get("api_target", ">= 90 %")  # a bench may name its own (or none: "")
        api_pct = "" if r.get("api_pct") is None else \
            f"{r['api_pct']:.0f} %" + (f" ({api_target})" if api_target else "")
        target = f"{r['value']} ({r['target']})" if r.get("target") else ""
        met = "" if r.get("met") is None else ("yes" if r["met"] else "**no**")
        api = "failed" if r.get("api_failed") and r.get("api_ms") is None else _ms(r.get("api_ms"))
        out.append("| " + " | ".join([
            r["work"], _ms(r.get("core_ms")), api,
            "" if r.get("numpy_ms") is None else f"{_ms(r['numpy_ms'])} ({r['numpy_which']})",
            _x(r.get("np_over_core")), _x(r.get("np_over_api")), api_pct, target, met]) + " |")
    return "\n".join(out)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="pass --quick to every bench")
    ap.add_argument("--threads", type=int, default=None, help="threads of the threaded NumPy variants")
    ap.add_argument("--only", default="", help=f"comma-separated subset of {','.join(BENCHES)}")
    ap.add_argument("--quiet", action="store_true", help="print only the summary table")
    ap.add_argument("--simd", choices=("native", "avx2"), default="native",
                    help="avx2: rotorid, NumPy and OpenBLAS at AVX2 on an AVX-512 machine")
    args = ap.parse_args()
    names = [b.strip() for b in args.only.split(",") if b.strip()] or list(BENCHES)
    bad = [b for b in names if b not in BENCHES]
    if bad:
        ap.error(f"unknown bench(es) {bad}; choose from {', '.join(BENCHES)}")
    passthrough = (["--quick"] if args.quick else []) + (["--threads", str(args.threads)] if args.threads else [])
    env = {**os.environ, **avx2_env()} if args.simd == "avx2" else None
    rows = [row for name in names for row in run(name, passthrough, args.quiet, env)]
    ci = cpu_info()
    import numpy as np

    print(f"Machine: {ci['model']}, {ci['usable_cpus']} usable CPUs, SIMD {' '.join(ci['simd'])}; NumPy "
          f"{np.__version__}; rotorid core threads {rotorid_threads()}; NumPy baselines on 1 or "
          f"{args.threads or 2} threads{'; --quick sizes' if args.quick else ''}"
          f"{'; rotorid, NumPy and OpenBLAS capped at AVX2 (--simd avx2)' if env else ''}.\n")
    print(table(rows))
    for r in rows:
        if r.get("api_failed"):
            print(f"\n{r['work']}: public API failed ({r['api_failed']})")
    print("\nNumPy / core and NumPy / API: best NumPy time / rotorid time (higher is better for rotorid). "
          "API / core: public API throughput as % of the core call's. Modal target is per core; "
          "run-out target is effective bandwidth as % of this machine's copy bandwidth.")
    return 0 if all("failed" not in r for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
