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


def turned_nsf_runs(rpm, turn_deg, *, rel_noise, seed, bearings=None, exact=None):
    """(rig, runs): the NSF rig's responses to imbalances A-D at ``rpm`` (on ``bearings``, default
    the rig's), turned by ``turn_deg`` (a phase-reference error: a number or one per speed), with
    complex Gaussian noise of ``rel_noise`` times each speed's rms response and the matching
    covariance. ``exact``: the noise-free responses, when already computed (``bearings`` is then
    not used)."""
    rig = rotorid.nsf_rig()
    rpm = np.asarray(rpm, float)
    if exact is None:
        brg = rig.bearings if bearings is None else bearings
        exact = [rotorid.imbalance_response(rig.rotor, brg, rig.imbalances[s], speed_rpm=rpm) for s in "ABCD"]
    rng = np.random.default_rng(seed)
    runs = []
    for r in exact:
        sig = rel_noise * np.sqrt(np.mean(np.abs(r.q) ** 2, axis=1))
        q = r.q * np.exp(1j * np.deg2rad(turn_deg))[..., None] + (sig / np.sqrt(2))[:, None] * (
            rng.standard_normal(r.q.shape) + 1j * rng.standard_normal(r.q.shape))
        runs.append(rotorid.SyncResponse(rpm, q, r.imbalance, r.at, r.name, np.eye(8)[None] * (sig ** 2 / 2)[:, None, None]))
    return rig, runs
