"""The SIMD dispatch: ``ROTORID_SIMD`` caps the level the kernels run at (how the benches measure
the AVX2 kernels on an AVX-512 machine), and every level gives the same bits. The kernels are
written lane by lane, so AVX-512, AVX2 and the baseline build do the same IEEE operations in the
same order (the identification kernel's fused multiply-adds are fused at every level, the other
kernels fuse none); a difference here means a kernel's result depends on the
CPU it runs on. Each level runs in a fresh interpreter (the level is read once per process)."""

import os
import subprocess
import sys

import numpy as np
import pytest

import rotorid
from rotorid import _core

# every dispatched kernel through the public API: time stepping (8 and 16 states with output
# equations), forward response (SIMD-lane LU), synchronous
# identification at the probes with redundant runs (forces kernel, eq. 19 on load, standard
# errors, flags), impact identification with an exponential window, modal analysis (rigid and on
# pedestals, eigenvalues and shapes, an odd number of speeds: pairs and a last one alone), the run-out
# filter, the order vectors of signals.track (fused resampling and order sums), a Monte Carlo study (counter-based normals, rotations, histograms), and the pedestal fit
# (streamed QR and HC3 passes over 2500 speeds: three tasks of points)
_WORK = r"""
import sys
import numpy as np
import rotorid
from rotorid import _core, signals, studies

rig = rotorid.nsf_rig()
rpm = np.linspace(1500.0, 10000.0, 203)
rng = np.random.default_rng(7)
runs = []
for s in "ABCD":
    r = rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances[s], speed_rpm=rpm, at="probes")
    q = r.q * (1 + 0.01 * rng.standard_normal(r.q.shape)) + 1e-7 * rng.standard_normal(r.q.shape)
    runs.append(rotorid.SyncResponse(speed_rpm=rpm, q=q, at="probes", imbalance=rig.imbalances[s]))
ident = rotorid.identify_synchronous(rig.rotor, runs)
f = np.linspace(2.0, 300.0, 157)
tests = []
for d in "xyx":
    t = rotorid.impact_frf(rig.rotor, rig.bearings, speed_rpm=1000.0, freq_hz=f, plane=0.0, direction=d)
    tests.append(rotorid.ImpactResponse(speed_rpm=1000.0, freq_hz=f, q=t.q * (1 + 0.02 * rng.standard_normal(t.q.shape)),
                                        plane=0.0, direction=d, sigma=3.0))
kw = rotorid.identify_impact(rig.rotor, tests)
modal = rotorid.modal_analysis(rig.rotor, rig.bearings, speed_rpm=rpm[:37])
x = rng.standard_normal((3, 20011))
kp = np.arange(0.001, 2.0, 0.0173)
filt = signals.runout_filter(x, 10000.0, kp, rng.standard_normal((3, 64)), 100, 19900)
xo = 1e-3 + 1e-6 * x + 1e-5 * np.cos(2 * np.pi * np.arange(20011) / 173.0)   # an offset, vibration, noise
xo[1, 7000:7010] = np.nan
orders_v = signals.order._order_vectors(list(xo), 10000.0, 0.0, kp, 0, kp.size - 1, 100, [1, 2, 7])
study = studies.synchronous_study(rig.rotor, rig.bearings, [rig.imbalances[s] for s in "ABC"], rpm[::20],
                                  studies.SyncErrors(amplitude_rel=0.01, phase_deg=0.5), trials=64, seed=3)
pulse = rotorid.half_sine_pulse(200.0, 1e-3, 10000.0, 3000, t0_s=1e-3)
tr = rotorid.impact_time_response(rig.rotor, rig.bearings, speed_rpm=2000.0, force_N=pulse, fs_hz=10000.0, at="probes")
trp = rotorid.impact_time_response(rig.rotor, rig.bearings, speed_rpm=2000.0, force_N=pulse, fs_hz=10000.0,
                                   pedestals=rotorid.example_pedestals())
ped = rotorid.example_pedestals()
pruns = [rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances[s], speed_rpm=np.linspace(800.0, 9000.0, 2500),
                                    pedestals=ped) for s in "AB"]
pruns = [rotorid.SyncResponse(r.speed_rpm, r.q * (1 + 0.01 * rng.standard_normal(r.q.shape)), r.imbalance,
                              pedestal=r.pedestal * (1 + 0.01 * rng.standard_normal(r.q.shape))) for r in pruns]
pfit = rotorid.identify_pedestals(rig.rotor, pruns, cross_coupled=True)
pmodal = rotorid.modal_analysis(rig.rotor, rig.bearings, speed_rpm=rpm[:23], pedestals=ped)
out = dict(pk=pfit.k, pm=pfit.mass_kg, pks=pfit.k_std, pcs=pfit.c_std, tq=tr.q, tpq=trp.q, tpp=trp.pedestal, tpa=trp.pedestal_accel, resp=runs[0].q, k=ident.k, c=ident.c, k_std=ident.k_std, cond=ident.cond, code=ident.flag_code,
           kk=kw.k, kc=kw.c, kstd=kw.k_std, eig=modal.eigenvalues, shapes=modal.shapes, peig=pmodal.eigenvalues,
           pshapes=pmodal.shapes, filt=filt, orders_v=orders_v,
           study=study.pct, study_rms=study.rms)
np.savez(sys.argv[1], level=_core.SIMD, **out)
"""


def _levels():
    """The cap values this CPU can run: its own level and every one below it."""
    order = ["baseline", "avx2", "avx512"]
    return order[: order.index(_core.SIMD_CPU) + 1]


def _run(tmp_path, level):
    path = tmp_path / f"{level or 'default'}.npz"
    env = dict(os.environ)
    env.pop("ROTORID_SIMD", None)
    if level is not None:
        env["ROTORID_SIMD"] = level
    out = subprocess.run([sys.executable, "-c", _WORK, str(path)], capture_output=True, text=True, env=env, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    return dict(np.load(path))


def test_the_default_level_is_the_cpus_and_the_cap_lowers_it(tmp_path):
    assert _core.SIMD_CPU in ("avx512", "avx2", "baseline")
    levels = _levels()
    for level in levels:
        got = subprocess.run([sys.executable, "-c", "from rotorid import _core; print(_core.SIMD, _core.SIMD_CPU)"],
                             capture_output=True, text=True, env={**os.environ, "ROTORID_SIMD": level}, timeout=60)
        assert got.stdout.split() == [level, _core.SIMD_CPU]
    # a cap above the CPU's level does not raise it
    if _core.SIMD_CPU != "avx512":
        got = subprocess.run([sys.executable, "-c", "from rotorid import _core; print(_core.SIMD)"],
                             capture_output=True, text=True, env={**os.environ, "ROTORID_SIMD": "avx512"}, timeout=60)
        assert got.stdout.strip() == _core.SIMD_CPU


@pytest.mark.skipif(os.environ.get("ROTORID_SIMD") not in (None, ""), reason="the session itself runs with a cap")
def test_every_simd_level_gives_the_same_bits(tmp_path):
    levels = _levels()
    ref = _run(tmp_path, None)
    assert str(ref.pop("level")) == _core.SIMD_CPU
    assert np.isfinite(ref["k"]).mean() > 0.9 and (ref["code"] == 0).any() and np.isfinite(ref["study"]).all()
    for level in levels:
        got = _run(tmp_path, level)
        assert str(got.pop("level")) == level
        for name, want in ref.items():
            np.testing.assert_array_equal(got[name], want, err_msg=f"{name} at ROTORID_SIMD={level}")


@pytest.mark.parametrize("value", ["sse", "AVX-512", "2"])
def test_an_unknown_cap_is_refused_in_one_line(value, tmp_path):
    env = {**os.environ, "ROTORID_SIMD": value}
    code = "import numpy as np, rotorid; rig = rotorid.nsf_rig(); rotorid.modal_analysis(rig.rotor, rig.bearings, speed_rpm=[1000.0])"
    got = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=60)
    assert got.returncode != 0
    assert "RotoridError" in got.stderr and "ROTORID_SIMD must be avx512, avx2 or baseline" in got.stderr
    assert repr(value).strip("'") in got.stderr
    cli = subprocess.run([sys.executable, "-m", "rotorid.cli", "demo", "--out", str(tmp_path / "d")], capture_output=True,
                         text=True, env=env, timeout=120)
    assert cli.returncode == 1
    assert cli.stderr.strip().splitlines() == [f"rotorid: error: cannot load rotorid's compiled core: ROTORID_SIMD must be "
                                               f"avx512, avx2 or baseline (or unset), got \"{value}\""]
    assert not (tmp_path / "d").exists()


def test_the_level_in_use_is_reported():
    assert rotorid._core.SIMD in _levels()
