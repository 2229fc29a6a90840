"""The README's table of identification accuracy on the NSF rig (sets A-D), three error levels.

    python docs/examples/study_accuracy_table.py      # about 5 s on 2 cores
"""

import numpy as np
import pandas as pd

import rotorid
from rotorid.studies import SyncErrors, synchronous_study

rig = rotorid.nsf_rig()
runs = [rig.imbalances[s] for s in "ABCD"]
rpm = np.arange(1000, 10001, 250.0)
bands = [(1000, 2000), (2000, 3400), (3500, 7300), (7400, 10000)]
cases = {
    "careful lab, random errors only (0.2 %, 0.05 deg, 0.01 um)":
        SyncErrors(amplitude_rel=0.002, phase_deg=0.05, noise_m=1e-8),
    "careful lab + systematic (the example config)":
        SyncErrors(amplitude_rel=0.002, phase_deg=0.05, noise_m=1e-8, keyphasor_deg=0.02, channel_delay_s=1e-6,
                   trial_mass_rel=0.002, trial_angle_deg=0.1),
    "DAQ 1X table, 1 % and 1 deg": SyncErrors(amplitude_rel=0.01, phase_deg=1.0),
}
pd.set_option("display.width", 200)
for name, errors in cases.items():
    res = synchronous_study(rig.rotor, rig.bearings, runs, rpm, errors, trials=10_000, seed=1, coverage_trials=100)
    print(name)
    print(res.band_summary(bands).to_string(index=False))
