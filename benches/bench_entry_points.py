"""Public API throughput as a share of its core calls, for every batch entry point on large inputs
(forward models, plane transforms, time stepping, series supports, pedestals, order tracking, and
the two identifications, which bench_identify.py and bench_impact.py also time at their own sizes).

    python benches/bench_entry_points.py [--rounds 15] [--only NAME ...] [--quick] [--points N[,N...]]

For each entry point the core calls it makes are recorded while it runs once (every function of
``rotorid._core`` is seen through ``rotorid._corecall.core``), then the public call and a replay of
exactly those core calls with the same argument objects are timed in interleaved rounds of two back-to-back
calls each (best of ``--rounds``, ``common.best_of_each``). API / core = core time / API time,
target >= 90 % (issue 10). "API - core" is what the public call adds, in µs. Large inputs:
100,000 speeds or frequencies (the identifications with covariances a tenth of that), 2 M samples
for time stepping, 10 M samples x 4 channels for order tracking (one core call for the
per-revolution order vectors; then the block statistics: one steady segment, or a coast-down's
~6,000 blocks of 4 revolutions).

``--points 100000,1000000`` times every size and then the API's throughput on the points added
from one size to the next: the core's extra time over the API's. A fixed cost per call (Python's
checks and the result object, several times slower right after a core call has streamed its
arrays through the caches) drops out of it; a cost per point (a copy, a scan, a temporary) does
not. Time stepping and order tracking stop growing at 100,000 points (2 M and 10 M samples: the
recording of the next size would take gigabytes), so they have no added points above that size.
"""

import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from common import best_of_each, print_header, record_core_calls, replay  # noqa: E402

import rotorid  # noqa: E402
from rotorid.simulate import SyncResponse  # noqa: E402

TARGET = 90.0


def entries(n, n_time):
    rig = rotorid.nsf_rig()
    rpm = np.linspace(500.0, 10_000.0, n)
    f = np.linspace(2.0, 400.0, n)
    ped = rotorid.example_pedestals()
    imb = rig.imbalances["A"]
    run = rotorid.imbalance_response(rig.rotor, rig.bearings, imb, speed_rpm=rpm, at="probes")
    test = rotorid.impact_frf(rig.rotor, rig.bearings, speed_rpm=2000.0, freq_hz=f, at="probes")
    pulse = np.zeros(n_time)
    for s0 in range(0, n_time, 40_000):
        pulse[s0:s0 + 16] = 120.0 * np.sin(np.pi * np.arange(16) / 16)
    zb = rig.bearings.k[0][None] + 1j * (2 * np.pi * f)[:, None, None] * rig.bearings.c[0][None]
    zd = ped.k[0][None] + 1j * (2 * np.pi * f)[:, None, None] * ped.c[0][None]
    runs_ped = [rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances[s], speed_rpm=rpm, pedestals=ped)
                for s in "AB"]
    ident = rotorid.identify_synchronous(rig.rotor, [rotorid.imbalance_response(rig.rotor, rig.bearings,
                                                                                rig.imbalances[s], speed_rpm=rpm)
                                                     for s in "ABC"])
    # the same runs with measurement covariances (the imbalance chain's), at a tenth of the speeds
    # (the propagation identifies 129 perturbed copies of every point)
    m = n // 10
    runs_cov = [rotorid.SyncResponse(rpm[:m], r.q[:m], r.imbalance, cov=np.broadcast_to(np.eye(8) * 1e-14, (m, 8, 8)).copy(),
                                     dof=np.full(m, 30.0))
                for r in (rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances[s], speed_rpm=rpm)
                          for s in "ABCD")]
    # pedestal runs with the covariances of probes and accelerometers (weighted fit: dof >= GLS_MIN_DOF)
    runs_ped_cov = [rotorid.SyncResponse(rpm[:m], r.q[:m], r.imbalance, pedestal=r.pedestal[:m],
                                         cov=np.broadcast_to(np.eye(8) * 1e-14, (m, 8, 8)).copy(),
                                         pedestal_cov=np.broadcast_to(np.eye(8) * 1e-15, (m, 8, 8)).copy(),
                                         dof=np.full(m, 30.0))
                    for r in runs_ped]
    # the same at the probe planes, as a rig records them (each run is moved to the bearings with
    # its covariance, which correlates the probes' and the accelerometers' errors)
    runs_ped_probes_cov = [rotorid.SyncResponse(rpm[:m], r.q, r.imbalance, "probes", pedestal=r.pedestal,
                                                cov=np.broadcast_to(np.eye(8) * 1e-14, (m, 8, 8)).copy(),
                                                pedestal_cov=np.broadcast_to(np.eye(8) * 1e-15, (m, 8, 8)).copy(),
                                                dof=np.full(m, 30.0))
                           for r in (rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances[s],
                                                                speed_rpm=rpm[:m], pedestals=ped, at="probes")
                                     for s in "AB")]
    tests_cov = [rotorid.ImpactResponse(2000.0, f[:m], t.q[:m], None, 0.0, d,
                                        cov=np.broadcast_to(np.eye(8) * 1e-16, (m, 8, 8)).copy(), dof=np.full(m, 10.0))
                 for d, t in ((d, rotorid.impact_frf(rig.rotor, rig.bearings, speed_rpm=2000.0, freq_hz=f[:m],
                                                     direction=d)) for d in "xy")]
    # the identifications at the same large size (bench_impact.py times 10,000 frequencies, where
    # the API's fixed ~0.1 ms of Python is a third to a half of the call)
    runs4 = [rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances[s], speed_rpm=rpm) for s in "ABCD"]
    tests2 = [rotorid.impact_frf(rig.rotor, rig.bearings, speed_rpm=2000.0, freq_hz=f, direction=d) for d in "xy"]
    from rotorid import signals, uncertainty
    from rotorid.recording import Recording

    # a 4-channel recording of n_time * 5 samples at 20 kHz, 3000 rpm with a slow speed wobble
    ns, fs = 5 * n_time, 20_000.0
    t = np.arange(ns) / fs
    theta = np.cumsum((3000.0 + 5.0 * np.sin(2 * np.pi * t / t[-1])) * np.pi / 30) / fs
    rng = np.random.default_rng(0)
    chans = {nm: 8e-6 * np.cos(theta + c) + 3e-6 * np.cos(2 * theta - c) + 0.5e-6 * rng.standard_normal(ns)
             for c, nm in enumerate(("x1", "x2", "y1", "y2"))}
    rec = Recording(fs, {**chans, "kp": np.zeros(ns)})
    kp = signals.Keyphasor.from_times(np.interp(2 * np.pi * np.arange(1, int(theta[-1] / (2 * np.pi)) + 1), theta, t))
    del t, theta

    return {
        "imbalance_response, pedestals": lambda: rotorid.imbalance_response(rig.rotor, rig.bearings, imb,
                                                                            speed_rpm=rpm, pedestals=ped),
        "imbalance_response, pedestals, at probes": lambda: rotorid.imbalance_response(
            rig.rotor, rig.bearings, imb, speed_rpm=rpm, pedestals=ped, at="probes"),
        "impact_frf": lambda: rotorid.impact_frf(rig.rotor, rig.bearings, speed_rpm=2000.0, freq_hz=f),
        "impact_frf, at probes": lambda: rotorid.impact_frf(rig.rotor, rig.bearings, speed_rpm=2000.0, freq_hz=f,
                                                            at="probes"),
        "impact_frf, pedestals": lambda: rotorid.impact_frf(rig.rotor, rig.bearings, speed_rpm=2000.0, freq_hz=f,
                                                            pedestals=ped),
        "impact_time_response": lambda: rotorid.impact_time_response(rig.rotor, rig.bearings, speed_rpm=3000.0,
                                                                     force_N=pulse, fs_hz=20_000.0),
        "impact_time_response, pedestals": lambda: rotorid.impact_time_response(
            rig.rotor, rig.bearings, speed_rpm=3000.0, force_N=pulse, fs_hz=20_000.0, pedestals=ped),
        "probes_to_bearings": lambda: rotorid.probes_to_bearings(rig.rotor, run.q),
        "SyncResponse.at_bearings": lambda: run.at_bearings(rig.rotor),
        "ImpactResponse.at_bearings": lambda: test.at_bearings(rig.rotor),
        "series_impedance": lambda: rotorid.series_impedance(zb, zd, 12.0, f),
        "identify_synchronous (4 runs)": lambda: rotorid.identify_synchronous(rig.rotor, runs4),
        "identify_impact (2 tests)": lambda: rotorid.identify_impact(rig.rotor, tests2),
        "identify_pedestals (2 runs)": lambda: rotorid.identify_pedestals(rig.rotor, runs_ped),
        "identify_pedestals (2 runs, cross-coupled)": lambda: rotorid.identify_pedestals(rig.rotor, runs_ped,
                                                                                         cross_coupled=True),
        "identify_pedestals (2 runs with cov, n/10 speeds)": lambda: rotorid.identify_pedestals(rig.rotor,
                                                                                                  runs_ped_cov),
        "identify_synchronous, 4 runs with cov (n/10 speeds)": lambda: rotorid.identify_synchronous(rig.rotor,
                                                                                                      runs_cov),
        "identify_impact, 2 tests with cov (n/10 freqs)": lambda: rotorid.identify_impact(rig.rotor, tests_cov),
        "identify_synchronous, 2 pedestal runs with cov + accel calibration (n/10 speeds)":
            lambda: rotorid.identify_synchronous(rig.rotor, runs_ped_cov, accel_gain_std=0.02, accel_phase_std_deg=1.0),
        "identify_synchronous, 2 pedestal runs at the probes with cov (n/10 speeds)":
            lambda: rotorid.identify_synchronous(rig.rotor, runs_ped_probes_cov),
        "identify_synchronous, 2 pedestal runs at the probes with cov + accel calibration (n/10 speeds)":
            lambda: rotorid.identify_synchronous(rig.rotor, runs_ped_probes_cov, accel_gain_std=0.02,
                                                 accel_phase_std_deg=1.0),
        "identify_pedestals (2 runs at the probes with cov, n/10 speeds)":
            lambda: rotorid.identify_pedestals(rig.rotor, runs_ped_probes_cov),
        "uncertainty.relative_std": lambda: uncertainty.relative_std(ident.k, ident.c, ident.k_std, ident.c_std),
        "SyncResponse (constructor, user data)": lambda: SyncResponse(rpm, run.q, imb, "probes"),
        "signals.track (steady, 4 channels)": lambda: signals.track(rec, kp=kp,
                                                                                          points_per_rev=512),
        "signals.track, coast-down blocks of 4 revs": lambda: signals.track(rec, kp=kp, points_per_rev=512,
                                                                           steady=False),
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=15)
    ap.add_argument("--only", nargs="*")
    ap.add_argument("--quick", action="store_true", help="10,000 points, 200,000 samples, 5 rounds")
    ap.add_argument("--points", default=None,
                    help="speeds or frequencies per entry point, or several sizes separated by commas "
                         "(default 100000; 10000 with --quick); time stepping and order tracking take 20 and "
                         "100 samples per point up to 100,000 points. With two sizes or more the API's "
                         "throughput on the points added from one size to the next is printed too")
    args = ap.parse_args()
    sizes = [10_000 if args.quick else 100_000]
    if args.points is not None:
        try:
            sizes = sorted({int(v) for v in args.points.split(",")})
        except ValueError:
            ap.error(f"--points must be whole numbers separated by commas, got {args.points!r}")
        if sizes[0] < 100:
            ap.error(f"--points must be >= 100, got {sizes[0]}")
    rounds = 5 if args.quick else args.rounds
    times = {}
    for n in sizes:
        n_time = 20 * min(n, 100_000)
        print_header("public entry points against their core calls", f"{n:,} points or {n_time:,} samples each", 1)
        times[n] = run_size(entries(n, n_time), args.only, rounds)
        print()
    if len(sizes) > 1:
        added(times, sizes)


def run_size(ents, only, rounds):
    """Time every entry point (or those named in ``only``) against its replayed core calls:
    {name: (API s, core s)}."""
    names = only or list(ents)
    unknown = [nm for nm in names if nm not in ents]
    if unknown:
        raise SystemExit(f"unknown entry point(s): {unknown}; known: {list(ents)}")
    print(f"{'entry point':42s} {'API ms':>9s} {'core ms':>9s} {'API - core':>11s} {'API / core':>10s}  core calls")
    below, out = [], {}
    for name in names:
        api = ents[name]
        calls = record_core_calls(api)
        if not calls:
            print(f"{name:42s} {'':>9s} {'':>9s} {'':>11s} {'':>10s}  none (pure Python/NumPy)")
            continue

        t = best_of_each({"api": api, "core": replay(calls)}, rounds)
        out[name] = (t["api"], t["core"])
        pct = 100.0 * t["core"] / t["api"]
        kinds = sorted({fn.__name__ for fn, _, _ in calls})
        print(f"{name:42s} {1e3 * t['api']:9.3f} {1e3 * t['core']:9.3f} {1e6 * (t['api'] - t['core']):8.0f} µs "
              f"{pct:9.1f} %  {', '.join(kinds)} "
              f"({len(calls)} call{'s' if len(calls) > 1 else ''})", flush=True)
        if pct < TARGET:
            below.append(f"{name} ({pct:.0f} %)")
    print(f"\nbelow {TARGET:.0f} %: {', '.join(below) or 'none'}")
    return out


def added(times, sizes):
    """Throughput on the added points: from each size to the next, the core's extra time over the
    API's extra time. A fixed cost per call (Python's checks, the result object) drops out; what
    is left is what the API costs per point beyond its core calls (a copy, a scan, a temporary)."""
    print("API throughput on the points added between sizes (core's extra time / API's extra time)")
    pairs = list(zip(sizes, sizes[1:]))
    print(f"{'entry point':42s} " + " ".join(f"{f'{a:,} -> {b:,}':>22s}" for a, b in pairs))
    below = []
    for name in times[sizes[0]]:
        cells = []
        for a, b in pairs:
            if name not in times[a] or name not in times[b]:
                cells.append(f"{'':>22s}")
                continue
            (api_a, core_a), (api_b, core_b) = times[a][name], times[b][name]
            if core_b < 1.5 * core_a:
                cells.append(f"{'(input not grown)':>22s}")
                continue
            pct = 100.0 * (core_b - core_a) / (api_b - api_a)
            cells.append(f"{pct:20.1f} %")
            if pct < TARGET:
                below.append(f"{name} ({a:,} -> {b:,}: {pct:.0f} %)")
        print(f"{name:42s} " + " ".join(cells))
    print(f"\nbelow {TARGET:.0f} %: {', '.join(below) or 'none'}")

if __name__ == "__main__":
    main()
