"""K-C-M fit of impact identifications."""

import dataclasses
import warnings

import numpy as np
import pytest

import rotorid
from rotorid import RotoridError, pipeline, rawsim

RIG = rotorid.nsf_rig()


def test_exact_frequency_dependent_support_gives_back_k_c_and_m():
    f = np.arange(5.0, 150.0, 1.0)
    w = 2 * np.pi * f
    m = np.array([[[0.8, 0.1], [0.0, 1.5]], [[0.5, 0.0], [-0.2, 1.2]]])  # kg: a support with inertia
    k = RIG.bearings.k[None] - w[:, None, None, None] ** 2 * m[None]
    c = np.broadcast_to(RIG.bearings.c, k.shape)
    brg = rotorid.BearingCoefficients(k, c, freq_hz=f)
    tests = [rotorid.impact_frf(RIG.rotor, brg, speed_rpm=1000, freq_hz=f, direction=d) for d in "xy"]
    fit = rotorid.fit_kcm(rotorid.identify_impact(RIG.rotor, tests), rotor=RIG.rotor)
    np.testing.assert_allclose(fit.K, RIG.bearings.k, rtol=1e-8, atol=1e-3)
    np.testing.assert_allclose(fit.M, m, atol=1e-8)
    np.testing.assert_allclose(fit.C, RIG.bearings.c, rtol=1e-8)
    assert fit.n_points == f.size and not fit.weighted
    # direct masses summing to 2.7 kg in y (6 % of the rotor): reported
    assert "direct y masses add up to 2.7" in fit.mass_check


def test_chain_fit_recovers_the_example_rig_with_intervals():
    rotor, brg, remnant = rawsim.example_rig()
    recs = [rawsim.impact_recording(rotor, brg, speed_rpm=2000, plane=0.0, direction=d, remnant=remnant, seed=j,
                                    record_s=4.0) for j, d in enumerate("xy")]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ident = pipeline.impact_chain(rotor, recs, band_hz=(20, 120)).identification
    fit = rotorid.fit_kcm(ident, rotor=rotor)
    assert fit.weighted and fit.mass_check == ""
    np.testing.assert_allclose(fit.K, brg.k, rtol=2e-3, atol=2e3)
    np.testing.assert_allclose(fit.C, brg.c, rtol=5e-3, atol=5.0)
    lo, hi = fit.interval(0.95)["K"]
    assert np.mean((lo <= brg.k) & (brg.k <= hi)) >= 0.75
    df = fit.to_dataframe()
    assert list(df.coefficient) == ["xx1", "xy1", "yx1", "yy1", "xx2", "xy2", "yx2", "yy2"]


def test_a_wrong_rotor_mass_shows_up_as_apparent_mass():
    f = np.arange(5.0, 150.0, 1.0)
    tests = [rotorid.impact_frf(RIG.rotor, RIG.bearings, speed_rpm=1000, freq_hz=f, direction=d) for d in "xy"]
    wrong = dataclasses.replace(RIG.rotor, mass_kg=RIG.rotor.mass_kg * 1.1)  # the model is 4.5 kg too heavy
    fit = rotorid.fit_kcm(rotorid.identify_impact(wrong, tests), rotor=wrong)
    assert "rotor model" in fit.mass_check and abs(fit.M[:, 0, 0].sum() + 4.53) < 0.1


def test_bad_bands_and_inputs_are_errors():
    f = np.arange(5.0, 150.0, 1.0)
    tests = [rotorid.impact_frf(RIG.rotor, RIG.bearings, speed_rpm=1000, freq_hz=f, direction=d) for d in "xy"]
    ident = rotorid.identify_impact(RIG.rotor, tests)
    with pytest.raises(RotoridError, match="at least 3"):
        rotorid.fit_kcm(ident, band_hz=(10.0, 11.5))
    with pytest.raises(RotoridError, match="band_hz"):
        rotorid.fit_kcm(ident, band_hz=(50.0, 10.0))
    runs = [rotorid.imbalance_response(RIG.rotor, RIG.bearings, RIG.imbalances[s], speed_rpm=[4000.0, 5000.0])
            for s in "AB"]
    with pytest.raises(RotoridError, match="freq_hz"):
        rotorid.fit_kcm(rotorid.identify_synchronous(RIG.rotor, runs))


@pytest.mark.parametrize("kw", [{}, {"exp_window_tau_s": 0.05}], ids=["plain", "exp-window"])
def test_chain_kcm_intervals_from_a_jackknife_over_impacts_cover(kw):
    # fitted as independent points, windowed spectra covered 52-60 % (neighbouring frequencies share
    # their errors); the jackknife over whole impacts carries that correlation: measured 0.96-0.99
    rotor, brg, remnant = rawsim.example_rig()
    hk, hc = [], []
    for s in range(12):
        recs = [rawsim.impact_recording(rotor, brg, speed_rpm=2000, plane=0.0, direction=d, remnant=remnant,
                                        seed=100 * s + j, record_s=4.0) for j, d in enumerate("xy")]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            fit = pipeline.impact_chain(rotor, recs, band_hz=(20, 120), kcm_band_hz=(20, 120), **kw).kcm
        assert fit.std_method.startswith("delete-one jackknife") and fit.dof == 4
        iv = fit.interval(0.95)
        hk.append(((iv["K"][0] <= brg.k) & (brg.k <= iv["K"][1])).ravel())
        hc.append(((iv["C"][0] <= brg.c) & (brg.c <= iv["C"][1])).ravel())
    assert np.mean(hk) >= 0.9 and np.mean(hc) >= 0.9, (np.mean(hk), np.mean(hc))
