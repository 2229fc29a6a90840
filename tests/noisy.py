"""Noisy NSF-rig imbalance runs with their measurement covariance: the shared input of the tests
that need identifications with intervals and some flagged points."""

import numpy as np

import rotorid


def noisy_nsf_runs(rpm, sets="ABC", *, noise_m=0.05e-6, seed=0):
    """(rig, runs): the NSF rig's responses to imbalance ``sets`` at ``rpm``, each with complex
    Gaussian noise of ``noise_m`` per part (m) and the matching covariance."""
    rig = rotorid.nsf_rig()
    rpm = np.asarray(rpm, float)
    runs = [rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances[s], speed_rpm=rpm) for s in sets]
    rng = np.random.default_rng(seed)
    for r in runs:
        r.q = r.q + noise_m * (rng.standard_normal(r.q.shape) + 1j * rng.standard_normal(r.q.shape))
        r.cov = np.broadcast_to(np.eye(8) * noise_m ** 2, (rpm.size, 8, 8))
    return rig, runs
