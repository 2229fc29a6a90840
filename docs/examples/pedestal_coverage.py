"""Monte Carlo check of the pedestal-motion chain: are the 95 % intervals rotorid prints honest?

Each trial simulates raw recordings of the example rig on flexible pedestals (rawsim: probes on
the housings, housing accelerometers, run-out, keyphasor, noise) with its own noise seed, runs the
whole chain (order tracking or impact H1, compensation, identification with pedestal motion,
pedestal fit) and records, for every coefficient at every point flagged ok, whether the 95 %
interval covers the truth. Prints the coverage and the median relative error.

    python docs/examples/pedestal_coverage.py [trials]     # 100 trials: about 25 s on 2 cores

The numbers are in docs/pedestals.md ("Accuracy and coverage").
"""

import sys
import warnings

import numpy as np

import rotorid
from rotorid import pipeline, rawsim

trials = int(sys.argv[1]) if len(sys.argv) > 1 else 100
rotor, brg, rem = rawsim.example_rig()
ped = rotorid.example_pedestals()
k0, c0 = brg.at()
speeds = [3000.0, 4000.0, 5000.0, 6000.0]
imbs = [rotorid.Imbalance((5e-3, 5e-3), (0.0, 0.0), name="S0"), rotorid.Imbalance((5e-3, 5e-3), (0.0, 180.0), name="C0")]


def covered(ident):
    iv = ident.interval(0.95)
    ok = ident.ok
    inside = np.concatenate([((iv.k_lower <= k0) & (k0 <= iv.k_upper))[ok].ravel(),
                             ((iv.c_lower <= c0) & (c0 <= iv.c_upper))[ok].ravel()])
    err = np.concatenate([np.abs(ident.k[ok] / k0[0] - 1)[..., [0, 1], [0, 1]].ravel(),
                          np.abs(ident.c[ok] / c0[0] - 1)[..., [0, 1], [0, 1]].ravel()])
    return inside, err


def pedestal_covered(fit):
    iv = fit.interval(0.95)
    d = np.arange(2)
    return np.concatenate([((iv["mass_kg"][0] <= ped.mass_kg) & (ped.mass_kg <= iv["mass_kg"][1])).ravel(),
                           ((iv["k"][0] <= ped.k) & (ped.k <= iv["k"][1]))[:, d, d].ravel(),
                           ((iv["c"][0] <= ped.c) & (ped.c <= iv["c"][1]))[:, d, d].ravel()])


res = {"imbalance": ([], [], []), "impact": ([], [], [])}
for t in range(trials):
    s = 1000 + 10 * t
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        runs = [rawsim.imbalance_recording(rotor, brg, speeds_rpm=speeds, added=im, remnant=rem, dwell_s=2.0,
                                           fs_hz=5000.0, pedestals=ped, seed=s + i) for i, im in enumerate(imbs)]
        base = rawsim.imbalance_recording(rotor, brg, speeds_rpm=speeds, added=None, remnant=rem, dwell_s=2.0,
                                          fs_hz=5000.0, pedestals=ped, seed=s + 5)
        chain = pipeline.imbalance_chain(rotor, runs, baseline=base, pedestal_motion=True)
        fit = rotorid.identify_pedestals(rotor, chain.responses, shared_cov=chain.shared_cov)
        recs = [rawsim.impact_recording(rotor, brg, speed_rpm=2000.0, plane=0.0, direction=d, remnant=rem,
                                        fs_hz=5000.0, pedestals=ped, seed=s + 7 + i) for i, d in enumerate("xy")]
        ichain = pipeline.impact_chain(rotor, recs, pedestal_motion=True)
        ifit = rotorid.identify_pedestals(rotor, ichain.tests)
    for kind, ident, f in (("imbalance", chain.identification, fit), ("impact", ichain.identification, ifit)):
        inside, err = covered(ident)
        res[kind][0].append(inside)
        res[kind][1].append(err)
        res[kind][2].append(pedestal_covered(f))
    if (t + 1) % 10 == 0:
        print(f"{t + 1} trials", flush=True)

print(f"\n{trials} trials, example rig on example_pedestals(), rawsim recordings through the chain")
print("| test | bearing K, C: 95 % coverage (ok points) | median rel. error, direct K, C | pedestal m, k, c: 95 % coverage |")
print("|---|---|---|---|")
for kind, (ins, errs, pins) in res.items():
    ins, errs, pins = np.concatenate(ins), np.concatenate(errs), np.concatenate(pins)
    print(f"| {kind} | {ins.mean():.3f} ({ins.size} intervals) | {100 * np.median(errs):.2f} % | "
          f"{pins.mean():.3f} ({pins.size} intervals) |")
