import threading

import numpy as np
import pytest
from hypothesis import assume, given
from hypothesis import strategies as st

import rotorid
from rotorid import IdentifiabilityError, Imbalance, RotoridError, SyncResponse

import oracle
from strategies import bearing_pair, imbalance_sets, rotors

WELL = 1e3  # condition number below which a point counts as well conditioned


def _speeds(rotor, brg, n=12):
    kx = brg.k[:, 0, 0].sum()
    wn = np.sqrt(kx / rotor.mass_kg) * 30 / np.pi
    return np.linspace(0.8 * wn, 2.5 * wn, n)


def _rel_err(res, brg, rpm):
    """Coefficient errors relative to each bearing's impedance scale max(|K|, w|C|)."""
    w = rpm * np.pi / 30
    scale = np.maximum(np.abs(brg.k).max(axis=(1, 2))[None, :], np.abs(brg.c).max(axis=(1, 2))[None, :] * w[:, None])
    ek = np.abs(res.k - brg.k[None]).max(axis=(2, 3)) / scale
    ec = np.abs(res.c - brg.c[None]).max(axis=(2, 3)) * w[:, None] / scale
    return np.maximum(ek, ec)  # (n, 2)


@given(rotors(), bearing_pair(), st.integers(2, 5).flatmap(imbalance_sets), st.booleans())
def test_roundtrip_synchronous(rotor, brg, imbs, at_probes):
    rpm = _speeds(rotor, brg)
    at = "probes" if at_probes else "bearings"
    runs = [rotorid.imbalance_response(rotor, brg, imb, speed_rpm=rpm, at=at) for imb in imbs]
    res = rotorid.identify_synchronous(rotor, runs)
    well = res.cond.max(axis=1) < WELL
    assume(well.sum() >= 3)  # Hypothesis fails the test if this filters out too many examples
    err = _rel_err(res, brg, rpm)
    assert np.all(err[well] < 1e-8 * np.maximum(1.0, res.cond[well] / 100)), (err[well].max(), res.cond[well].max())
    assert np.all(res.residual[well] < 1e-8)


@given(rotors(probes_at_bearings=True), bearing_pair(), imbalance_sets(2))
def test_fast_solver_equals_report_formulation_for_two_runs(rotor, brg, imbs):
    rpm = _speeds(rotor, brg, 6)
    runs = [rotorid.imbalance_response(rotor, brg, imb, speed_rpm=rpm) for imb in imbs]
    a = rotorid.identify_synchronous(rotor, runs, method="forces", cond_max=np.inf)
    b = rotorid.identify_synchronous(rotor, runs, method="report", cond_max=np.inf)
    well = a.cond.max(axis=1) < WELL
    assume(well.any())
    for i in np.nonzero(well)[0]:
        sc = max(np.abs(b.k[i]).max(), 1.0)
        np.testing.assert_allclose(a.k[i], b.k[i], atol=1e-7 * sc)
        np.testing.assert_allclose(a.c[i], b.c[i], atol=1e-7 * max(np.abs(b.c[i]).max(), 1.0))


def test_report_method_matches_numpy_oracle_with_redundant_noisy_runs():
    rig = rotorid.nsf_rig()
    rpm = np.array([3000.0, 4500.0, 6000.0])
    rng = np.random.default_rng(1)
    runs = []
    for name in "ABCD":
        r = rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances[name], speed_rpm=rpm)
        noisy = r.q * (1 + 0.01 * (rng.standard_normal(r.q.shape) + 1j * rng.standard_normal(r.q.shape)))
        runs.append(SyncResponse(rpm, noisy, rig.imbalances[name]))
    res = rotorid.identify_synchronous(rig.rotor, runs, method="report")
    M, G = rig.rotor.matrices()[:2]
    for i, s in enumerate(rpm * oracle.RPM):
        qs = [r.q[i] for r in runs]
        Fs = [rig.imbalances[n].generalized(rig.rotor) * s ** 2 for n in "ABCD"]
        P = oracle.report_identify(qs, Fs, M, G, rig.rotor.l1, rig.rotor.l2, s, s)
        np.testing.assert_allclose(res.report_vector()[i, :8], P[:8], rtol=1e-7, atol=1e-6 * np.abs(P[:8]).max())
        np.testing.assert_allclose(res.report_vector()[i, 8:], P[8:] / s, rtol=1e-7, atol=1e-6 * np.abs(P[8:] / s).max())
    assert np.all(res.residual > 0)


def test_refinement_step_only_from_cond_1e3_and_everywhere_on_request():
    """Redundant runs are solved by the semi-normal equations, refined (one step with the true
    residual) from cond = 1e3 on; ``refine_all=True`` (how the uncertainty propagation's central
    differences solve) refines every point. Below 1e3 the two differ by the normal equations'
    rounding, a small multiple of cond^2 eps of the bearing's impedance; from 1e3 on they are the
    same bits."""
    from rotorid import _core

    rig = rotorid.nsf_rig()
    rpm = np.linspace(300.0, 20000.0, 400)
    rng = np.random.default_rng(5)
    # nearly circular orbits, y = -j x (1 + d) with d from 1 to 1e-5 over the speeds: the x and y
    # columns of each bearing's system grow nearly parallel and cond spans ~10 to ~1e5
    d = 10.0 ** -np.linspace(0.0, 5.0, rpm.size)
    qs = []
    for name in "ABC":
        r = rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances[name], speed_rpm=rpm)
        q = r.q * (1 + 0.02 * (rng.standard_normal(r.q.shape) + 1j * rng.standard_normal(r.q.shape)))
        wobble = d[:, None] * (rng.standard_normal((rpm.size, 2)) + 1j * rng.standard_normal((rpm.size, 2)))
        q[:, 2:] = -1j * q[:, :2] * (1 + wobble)
        qs.append(q)
    om = rpm * oracle.RPM
    e = np.array([rig.imbalances[x].generalized(rig.rotor) for x in "ABC"], dtype=complex)[None]
    args = (rig.rotor.core_params(), om, om, np.array(qs)[None], e, om ** 2)
    k, c, cond = (a[0] for a in _core.identify(*args, with_std=False)[:3])
    kr, cr, condr = (a[0] for a in _core.identify(*args, with_std=False, refine_all=True)[:3])
    np.testing.assert_array_equal(cond, condr)
    assert (cond < 1e3).any() and (cond >= 1e3).any()
    z = k + 1j * om[:, None, None, None] * c        # (n, bearing, 2, 2)
    zr = kr + 1j * om[:, None, None, None] * cr
    err = np.abs(z - zr).max(axis=(2, 3))
    scale = np.abs(zr).max(axis=(2, 3))
    low = cond < 1e3
    assert (err[low] <= 64 * cond[low] ** 2 * np.finfo(float).eps * scale[low]).all()
    assert (err[low] > 0).any()                    # the step is skipped there
    np.testing.assert_array_equal(z[~low], zr[~low])
    with pytest.raises(TypeError):
        _core.identify(*args, refine_all="yes")


def test_least_squares_uses_all_runs_and_reports_standard_errors():
    rig = rotorid.nsf_rig()
    rpm = np.linspace(3000, 6000, 7)
    rng = np.random.default_rng(7)
    truth = [rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances[n], speed_rpm=rpm) for n in "ABCD"]
    noise = 0.2e-6

    def noisy(r):
        return SyncResponse(rpm, r.q + noise * (rng.standard_normal(r.q.shape) + 1j * rng.standard_normal(r.q.shape)),
                            r.imbalance)

    errs2, errs4 = [], []
    for _ in range(40):
        runs = [noisy(r) for r in truth]
        r2 = rotorid.identify_synchronous(rig.rotor, runs[:2])
        r4 = rotorid.identify_synchronous(rig.rotor, runs)
        errs2.append(r2.k - rig.bearings.k)
        errs4.append(r4.k - rig.bearings.k)
    assert np.all(np.isnan(r2.k_std)) and np.all(np.isfinite(r4.k_std))
    rms2 = np.sqrt(np.mean(np.square(errs2)))
    rms4 = np.sqrt(np.mean(np.square(errs4)))
    assert rms4 < rms2  # redundant runs reduce the scatter
    # standard errors are of the right size: actual rms error vs mean predicted std within a factor 2
    pred = np.sqrt(np.mean(np.square(r4.k_std)))
    assert 0.5 < rms4 / pred < 2.0


def test_identical_bearings_from_one_run():
    rig = rotorid.nsf_rig()
    rpm = np.linspace(3000, 6000, 5)
    run = rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances["B"], speed_rpm=rpm)
    for method in ("forces", "report"):
        res = rotorid.identify_synchronous(rig.rotor, [run], identical=True, method=method)
        np.testing.assert_allclose(res.k, np.broadcast_to(rig.bearings.k, res.k.shape), rtol=1e-7, atol=1e-3)
        np.testing.assert_allclose(res.c, np.broadcast_to(rig.bearings.c, res.c.shape), rtol=1e-6, atol=1e-5)


def test_single_plane_runs_are_rejected_with_names():
    rig = rotorid.nsf_rig()
    rpm = [3000.0, 4000.0]
    runs = [rotorid.imbalance_response(rig.rotor, rig.bearings, Imbalance((3e-3, 0.0), (a, 0.0), name=n),
                                       speed_rpm=rpm) for n, a in [("P", 0.0), ("Q", 90.0)]]
    with pytest.raises(IdentifiabilityError, match=r"plane 1 only.*|'P'.*'Q'") as ei:
        rotorid.identify_synchronous(rig.rotor, runs)
    assert "'P'" in str(ei.value) and "'Q'" in str(ei.value)


def test_complex_multiple_run_is_rejected():
    rig = rotorid.nsf_rig()
    rpm = [3000.0, 4000.0]
    a = Imbalance((3e-3, 4e-3), (10.0, 50.0), name="A")
    b = Imbalance((6e-3, 8e-3), (40.0, 80.0), name="twiceA")  # 2 e^{-j30} x A
    runs = [rotorid.imbalance_response(rig.rotor, rig.bearings, i, speed_rpm=rpm) for i in (a, b)]
    with pytest.raises(IdentifiabilityError, match=r"complex multiples.*'twiceA'.*= 2·exp\(j-30.0°\)"):
        rotorid.identify_synchronous(rig.rotor, runs)


def test_isotropic_bearings_are_rejected():
    rig = rotorid.nsf_rig()
    iso = rotorid.BearingCoefficients.identical([[3e6, 0], [0, 3e6]], [[2000, 0], [0, 2000]])
    rpm = np.linspace(2000, 8000, 7)
    runs = [rotorid.imbalance_response(rig.rotor, iso, rig.imbalances[n], speed_rpm=rpm) for n in "AB"]
    with pytest.raises(IdentifiabilityError, match="isotropic"):
        rotorid.identify_synchronous(rig.rotor, runs)


def test_ill_conditioned_speeds_are_flagged_not_silent():
    rig = rotorid.nsf_rig()
    rpm = np.array([100.0, 300.0, 4000.0, 5000.0])
    runs = [rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances[n], speed_rpm=rpm) for n in "AB"]
    res = rotorid.identify_synchronous(rig.rotor, runs)
    assert list(res.ok) == [False, False, True, True]
    assert set(res.flag[0].split("; ")) == {"ill-conditioned", "low amplitude"}  # every reason, not the first
    df = res.to_dataframe()
    assert list(df.columns[:3]) == ["speed_rpm", "Kxx1", "Kxx2"] and "ok" in df and "cond1" in df
    assert res.bearings().axis.tolist() == [4000.0, 5000.0]


def test_bad_inputs_name_the_argument():
    rig = rotorid.nsf_rig()
    r1 = rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances["A"], speed_rpm=[3000.0, 4000.0])
    r2 = rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances["B"], speed_rpm=[3000.0, 4500.0])
    with pytest.raises(RotoridError, match="speed_rpm of run 1 .* differs"):
        rotorid.identify_synchronous(rig.rotor, [r1, r2])
    with pytest.raises(RotoridError, match="has no imbalance"):
        rotorid.identify_synchronous(rig.rotor, [r1, SyncResponse([3000.0, 4000.0], r1.q)])
    with pytest.raises(IdentifiabilityError, match="at least 2"):
        rotorid.identify_synchronous(rig.rotor, [r1])
    with pytest.raises(RotoridError, match="method must be"):
        rotorid.identify_synchronous(rig.rotor, [r1, r1], method="magic")
    with pytest.raises(RotoridError, match="run 1 must be a rotorid.SyncResponse"):
        rotorid.identify_synchronous(rig.rotor, [r1, np.zeros((2, 4))])
    with pytest.raises(RotoridError, match="runs must be a list"):
        rotorid.identify_synchronous(rig.rotor, r1)


def test_core_rejects_bad_shapes_without_panicking():
    from rotorid import _core

    p = rotorid.nsf_rig().rotor.core_params()
    w = np.ones(3)
    with pytest.raises(ValueError, match="q has shape"):
        _core.identify(p, w, w, np.zeros((1, 2, 3, 3), complex), np.zeros((1, 2, 4), complex), w)
    with pytest.raises(ValueError, match="e has shape"):
        _core.identify(p, w, w, np.zeros((1, 2, 3, 4), complex), np.zeros((1, 3, 4), complex), w)
    with pytest.raises(ValueError, match="w .* non-zero"):
        _core.identify(p, np.zeros(3), w, np.zeros((1, 2, 3, 4), complex), np.zeros((1, 2, 4), complex), w)
    with pytest.raises(ValueError, match="rotor"):
        _core.identify(p[:3], w, w, np.zeros((1, 2, 3, 4), complex), np.zeros((1, 2, 4), complex), w)
    with pytest.raises(ValueError, match="C-contiguous"):
        _core.identify(p, w, w, np.zeros((1, 2, 3, 8), complex)[..., ::2], np.zeros((1, 2, 4), complex), w)
    with pytest.raises(TypeError):
        _core.identify(p, w, w, np.zeros((1, 2, 3, 4)), np.zeros((1, 2, 4), complex), w)
    # runs handed over as a list of (n, 4) arrays, used where they are
    with pytest.raises(ValueError, match=r"q\[1\] has shape"):
        _core.identify(p, w, w, [np.zeros((3, 4), complex), np.zeros((2, 4), complex)], np.zeros((1, 2, 4), complex), w)
    with pytest.raises(TypeError, match=r"q\[0\] must be a complex128"):
        _core.identify(p, w, w, [np.zeros((3, 4)), np.zeros((3, 4), complex)], np.zeros((1, 2, 4), complex), w)
    with pytest.raises(ValueError, match="C-contiguous"):
        _core.identify(p, w, w, [np.zeros((3, 8), complex)[:, ::2]] * 2, np.zeros((1, 2, 4), complex), w)
    rig = rotorid.nsf_rig()
    rpm = np.array([3000.0, 4000.0, 5000.0])
    om = rpm * np.pi / 30
    q = np.stack([rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances[n], speed_rpm=rpm).q
                  for n in "AB"])[None]
    e = np.stack([rig.imbalances[n].generalized(rig.rotor) for n in "AB"])[None]
    q[0, 1, 2, 3] = np.nan
    k, c, cond, *_, nbad = _core.identify(p, om, om, q, e, om ** 2)
    assert nbad == 1 and np.all(np.isnan(k[0, 2])) and np.all(np.isnan(cond[0, 2]))
    np.testing.assert_allclose(k[0, :2], np.broadcast_to(rig.bearings.k, (2, 2, 2, 2)), rtol=1e-8, atol=1e-3)


def test_batch_axis_equals_individual_calls_and_threads_are_safe():
    rig = rotorid.nsf_rig()
    rpm = np.linspace(2500, 7000, 50)
    truth = np.stack([rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances[n], speed_rpm=rpm).q
                      for n in "ABCD"])
    rng = np.random.default_rng(3)
    trials = truth[None] + 1e-7 * (rng.standard_normal((64,) + truth.shape) + 1j * rng.standard_normal((64,) + truth.shape))
    imbs = [rig.imbalances[n] for n in "ABCD"]
    batch = rotorid.identify_synchronous_batch(rig.rotor, rpm, trials, imbs, with_std=True)
    for t in (0, 17, 63):
        runs = [SyncResponse(rpm, trials[t, r], imbs[r]) for r in range(4)]
        one = rotorid.identify_synchronous(rig.rotor, runs)
        np.testing.assert_array_equal(batch["k"][t], one.k)
        np.testing.assert_array_equal(batch["c_std"][t], one.c_std)
    results = [None] * 6

    def work(i):
        results[i] = rotorid.identify_synchronous_batch(rig.rotor, rpm, trials, imbs)["k"]

    th = [threading.Thread(target=work, args=(i,)) for i in range(6)]
    for t in th:
        t.start()
    for t in th:
        t.join()
    for r in results:
        np.testing.assert_array_equal(r, batch["k"])
    # the batch is used as it is (no copy); a NaN in one trial marks that trial's point only
    trials[5, 2, 7, 1] = np.nan
    out = rotorid.identify_synchronous_batch(rig.rotor, rpm, trials, imbs)
    assert np.isnan(out["k"][5, 7]).all() and np.isnan(out["cond"][5, 7]).all()
    assert np.isfinite(out["k"][5, 8]).all() and np.isfinite(out["k"][4, 7]).all()
    np.testing.assert_array_equal(out["k"][6], batch["k"][6])


@given(rotors(), bearing_pair(), imbalance_sets(4), st.sampled_from(["forces", "report"]), st.booleans())
def test_runs_at_the_probes_identify_as_the_same_runs_moved_to_the_bearings(rotor, brg, imbs, method, identical):
    """Runs recorded at the probe planes go to the core as they are, with eq. 19 applied as each
    point is loaded; the result must be that of moving them to the bearings first, bit for bit,
    standard errors and flags included, except the residual-based errors of identical bearings,
    which take the noise as white where the runs were measured (tests/test_identical_std.py)."""
    rpm = _speeds(rotor, brg, 7)
    at_b = [rotorid.imbalance_response(rotor, brg, imb, speed_rpm=rpm) for imb in imbs]
    at_p = [r.at_probes(rotor) for r in at_b]
    moved = [r.at_bearings(rotor) for r in at_p]
    try:
        a = rotorid.identify_synchronous(rotor, moved, method=method, identical=identical)
    except rotorid.RotoridError as exc:
        with pytest.raises(type(exc)):
            rotorid.identify_synchronous(rotor, at_p, method=method, identical=identical)
        return
    b = rotorid.identify_synchronous(rotor, at_p, method=method, identical=identical)
    noise_where_measured = identical and method == "forces"
    for field in ("k", "c", "cond", "residual", "rel_amplitude") + (() if noise_where_measured else ("k_std", "c_std")):
        np.testing.assert_array_equal(getattr(a, field), getattr(b, field), err_msg=field)
    if not noise_where_measured:
        assert list(a.flag) == list(b.flag)


def test_runs_at_the_probes_with_covariances_take_the_moved_path():
    """With measurement covariances (moved to the bearings in Python) the result is still the
    moved runs' result."""
    rig = rotorid.nsf_rig()
    rpm = np.linspace(2000, 6000, 5)
    at_p = []
    for name in "ABC":
        r = rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances[name], speed_rpm=rpm, at="probes")
        at_p.append(SyncResponse(rpm, r.q, r.imbalance, "probes", cov=np.broadcast_to(np.eye(8) * 1e-16, (5, 8, 8))))
    a = rotorid.identify_synchronous(rig.rotor, at_p)
    b = rotorid.identify_synchronous(rig.rotor, [r.at_bearings(rig.rotor) for r in at_p])
    np.testing.assert_array_equal(a.k, b.k)
    np.testing.assert_array_equal(a.k_std, b.k_std)
    assert a.std_source == "measurement covariance"


def test_core_refuses_a_bad_plane_transform():
    from rotorid import _core

    rig = rotorid.nsf_rig()
    w = np.array([300.0, 400.0])
    q = [np.ones((2, 4), complex) * (1 + 1j) * 1e-5, np.ones((2, 4), complex) * (1 - 2j) * 1e-5]
    e = np.ones((1, 2, 4), complex)
    with pytest.raises(ValueError, match="planes has shape"):
        _core.identify(rig.rotor.core_params(), w, w, q, e, None, planes=np.eye(3))
    with pytest.raises(ValueError, match="planes"):
        _core.identify(rig.rotor.core_params(), w, w, q, e, None, planes=np.full((2, 2), np.nan))


def test_report_method_with_redundant_runs_says_its_standard_errors_are_unknown():
    """method="report" computes no residual-based standard errors: without a covariance its
    std_source is "none" (it said "residual" while k_std was NaN), and no point is "uncertain"."""
    rig = rotorid.nsf_rig()
    rpm = np.arange(2000, 6001, 500.0)
    runs = [rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances[s], speed_rpm=rpm) for s in "ABC"]
    rep = rotorid.identify_synchronous(rig.rotor, runs, method="report")
    assert rep.std_source == "none" and rep.dof is None
    assert np.isnan(rep.k_std).all() and np.isnan(rep.c_std).all()
    assert not np.char.find(rep.flag.astype(str), "uncertain").max() >= 0
    fast = rotorid.identify_synchronous(rig.rotor, runs)
    assert fast.std_source == "residual" and np.isfinite(fast.k_std).all() and fast.dof.shape == rpm.shape


@pytest.mark.parametrize("with_std", [True, False])
def test_core_flags_in_the_identify_call_equal_the_separate_flag_pass(with_std):
    # the API takes the flags from the identify call itself; they must be those flag_codes gives
    # on that call's outputs, per batch row (its own peak amplitude), NaN points and all
    from rotorid import _core

    rig = rotorid.nsf_rig()
    rpm = np.linspace(1500, 9000, 700)  # low amplitude at the low speeds, ill-conditioned near some
    om = rpm * np.pi / 30
    truth = np.stack([rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances[n], speed_rpm=rpm).q
                      for n in "ABC"])
    rng = np.random.default_rng(5)
    q = truth[None] * (1 + 0.05 * rng.standard_normal((3,) + truth.shape))
    q[1] *= 7.0  # another peak amplitude in the second row
    q[2, 1, 40, 2] = np.nan
    q[0, :, 90] = 0.0  # a singular point
    e = np.stack([rig.imbalances[n].generalized(rig.rotor) for n in "ABC"])[None]
    limits = (50.0, 0.2, 0.05, 2.0)  # thresholds, and the residual dof of 3 runs
    *_, rel_std, code, rel_amp, ok, nbad = _core.identify(rig.rotor.core_params(), om, om, q, e, om ** 2,
                                                           with_std=with_std, flag_limits=limits)
    k, c, cond, resid, amp, ks, cs, *_ = _core.identify(rig.rotor.core_params(), om, om, q, e, om ** 2,
                                                        with_std=with_std)
    assert nbad == 1 and code.dtype == np.uint8 and code.shape == rel_amp.shape == ok.shape == (3, rpm.size)
    assert ok.dtype == bool
    np.testing.assert_array_equal(ok, code == 0)
    for b in range(3):
        want_code, want_rel, want_ok = _core.flag_codes(cond[b], amp[b], rel_std[b] if with_std else None, *limits[:3],
                                                        c[b], cs[b] if with_std else None, np.array([2.0]))
        np.testing.assert_array_equal(code[b], want_code)
        np.testing.assert_array_equal(rel_amp[b], want_rel)
        assert want_ok.dtype == bool
        np.testing.assert_array_equal(want_ok, want_code == 0)
    # every reason occurs somewhere, so the comparison covers each bit
    for bit in (1, 2, 8, 16) + ((4,) if with_std else ()):
        assert (code & bit).any(), bit
    assert code[0, 90] & 1 and not code[1, 90] & 1
    # a row with a NaN point has no peak amplitude: relative amplitude 0 (the API refuses NaN input)
    assert (rel_amp[2] == 0).all() and (rel_amp[1] > 0).all()
    no_flags = _core.identify(rig.rotor.core_params(), om, om, q, e, om ** 2, with_std=with_std)
    assert no_flags[8] is None and no_flags[9] is None and no_flags[10] is None
    from rotorid._corecall import core

    for bad in ((50.0, 0.2), "abc", (50.0, None, 0.1, 2.0), (50.0, 0.2, 0.1)):
        with pytest.raises(RotoridError, match="flag_limits"):
            core.identify(rig.rotor.core_params(), om, om, q, e, om ** 2, flag_limits=bad)


def test_wake_pool_refuses_bad_waits_and_leaves_results_alone():
    from rotorid import _corecall

    for bad in (-1.0, float("nan"), float("inf"), 50_001.0, 2e6):
        with pytest.raises(RotoridError, match="max_wait_us"):
            _corecall.core.wake_pool(bad)
    rig = rotorid.nsf_rig()
    f = np.linspace(2, 300, 9000)
    tests = [rotorid.impact_frf(rig.rotor, rig.bearings, speed_rpm=1000.0, freq_hz=f, plane=0.0, direction=d)
             for d in "xy"]
    ref = rotorid.identify_impact(rig.rotor, tests)
    for wait in (0.0, 50.0, 2000.0):
        _corecall.core.wake_pool(wait)  # a wake with no call after it ends by itself
    _corecall.core.wake_pool()
    _corecall.core.wake_pool()  # a second wake while the first holds the helpers is a no-op
    again = rotorid.identify_impact(rig.rotor, tests)
    np.testing.assert_array_equal(again.k, ref.k)
    np.testing.assert_array_equal(again.flag_code, ref.flag_code)


@given(st.integers(2, 6), st.integers(0, 2 ** 32 - 1), st.floats(-250, 250), st.booleans())
def test_second_singular_ratio_is_the_svd_one(rows, seed, log_scale, dependent):
    from rotorid.identify import _second_singular_ratio

    rng = np.random.default_rng(seed)
    U = rng.standard_normal((rows, 2)) + 1j * rng.standard_normal((rows, 2))
    if dependent:
        U[:, 1] = U[:, 0] * (0.3 - 2j) + 1e-10 * rng.standard_normal(rows)
    U *= 10.0 ** log_scale
    sv = np.linalg.svd(U, compute_uv=False)
    ratio = _second_singular_ratio([tuple(r) for r in U.tolist()])
    # both are exact to rounding: an absolute error of a few eps relative to the largest value
    assert abs(ratio - sv[-1] / sv[0]) <= 1e-13 + 1e-9 * sv[-1] / sv[0]


def test_imbalance_forcing_is_the_numpy_formula_to_the_bit():
    rig = rotorid.nsf_rig()
    rng = np.random.default_rng(2)
    for _ in range(200):
        imb = Imbalance(tuple(rng.uniform(0, 0.05, 2)), tuple(rng.uniform(-720, 720, 2)))
        f = np.asarray(imb.mass_kg) * np.asarray(rig.rotor.r) * np.exp(-1j * np.deg2rad(imb.angle_deg))
        np.testing.assert_array_equal(imb.forcing(rig.rotor), f)
        f1, f2 = f
        d1, d2 = rig.rotor.d
        g = np.array([f1 + f2, -1j * (f1 + f2), -f1 * d1 + f2 * d2, -1j * (f1 * d1 - f2 * d2)])
        np.testing.assert_array_equal(imb.generalized(rig.rotor), g)


def test_a_probe_reversed_in_every_run_is_flagged_by_its_negative_direct_damping():
    """x1 reversed in every run (and its baseline) leaves no residual: the runs still span the
    same two imbalance patterns. An independent lab's recordings gave K off by 136-440 % and
    Cxx1 = -2560, Cxx2 = -12900 N·s/m with every point ok; a passive support dissipates, so
    significantly negative direct damping flags the point."""
    import rotorid

    rig = rotorid.nsf_rig()
    rpm = np.array([3000.0, 4000.0, 5000.0, 6000.0])
    runs = [rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances[s], speed_rpm=rpm, at="probes")
            for s in "ABCD"]
    for r in runs:
        r.cov = np.broadcast_to(np.eye(8) * (0.05e-6) ** 2, (rpm.size, 8, 8)).copy()
    clean = rotorid.identify_synchronous(rig.rotor, runs)
    assert not any(rotorid.identify.NEGATIVE_DAMPING in f for f in clean.flag)
    for r in runs:
        r.q = r.q * np.array([-1.0, 1.0, 1.0, 1.0])
    flipped = rotorid.identify_synchronous(rig.rotor, runs)
    negative = (flipped.c[:, :, [0, 1], [0, 1]] + 2 * flipped.c_std[:, :, [0, 1], [0, 1]] < 0).any(axis=(1, 2))
    assert negative.any()
    assert np.array_equal(np.array(["negative direct damping" in f for f in flipped.flag]), negative)
    assert not flipped.ok[negative].any()


@pytest.mark.parametrize("sets, phase_std", [("ABC", 0.0), ("ABCD", 0.0), ("ABC", 1e-4), ("ABC", 1.0)])
def test_negative_damping_flags_zero_damping_at_the_same_rate_whatever_the_runs_dof(sets, phase_std):
    """A bearing with zero direct damping Cxx1 (the other coefficients as the NSF rig), runs with
    random noise, residual-based standard errors (3 runs: 2 dof; 4 runs: 4 dof): the flag is a
    one-sided test at Phi(-2) = 2.3 %, so zero damping is flagged at that rate whatever the dof.
    Two standard errors regardless of the dof flagged 9.2 % (2 dof) and 6.0 % (4 dof). With a
    phase-reference uncertainty (negligible, and 1 degree random per speed) the flags come from the
    separate pass with each damping's own (Welch-Satterthwaite) dof: the point's smallest over its
    16 coefficients flagged 0.5-0.8 % (review)."""
    import warnings

    from rotorid import BearingCoefficients
    from rotorid.identify import NEGATIVE_DAMPING

    rig = rotorid.nsf_rig()
    rpm = np.arange(2000.0, 9001.0, 250.0)
    c = np.array(rig.bearings.c, dtype=float)
    c[0, 0, 0] = 0.0
    bearings = BearingCoefficients(k=np.array(rig.bearings.k), c=c)
    clean = {s: rotorid.imbalance_response(rig.rotor, bearings, rig.imbalances[s], speed_rpm=rpm) for s in sets}
    rng = np.random.default_rng(3)
    bits, z = [], []
    for _ in range(400):
        runs = []
        turn = np.exp(1j * np.deg2rad(phase_std) * rng.standard_normal(rpm.size))[:, None]  # the phase reference
        for s in sets:
            r = rotorid.imbalance_response(rig.rotor, bearings, rig.imbalances[s], speed_rpm=rpm)
            r.q = (clean[s].q + 0.05e-6 * (rng.standard_normal(r.q.shape) + 1j * rng.standard_normal(r.q.shape))) * turn
            runs.append(r)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            ident = rotorid.identify_synchronous(rig.rotor, runs, keyphasor_angle_std_deg=phase_std)
        assert ident.std_source == "residual" + (" + phase reference" if phase_std else "")
        bit = ident.flag_reasons.index(NEGATIVE_DAMPING)
        bits.append((ident.flag_code.astype(int) >> bit) & 1)
        z.append(ident.c[:, 0, 0, 0] / ident.c_std[:, 0, 0, 0])
    bits, z = np.concatenate(bits), np.concatenate(z)
    if phase_std < 0.5:
        assert np.allclose(ident.dof, 2.0 * (len(sets) - 2), rtol=1e-3)
        assert np.mean(z < -2) > 0.055  # what a fixed 2 standard errors would flag
    assert 0.015 < bits.mean() < 0.035, bits.mean()


def test_negative_damping_threshold_is_students_t_at_each_points_dof():
    """The core's test F_t(c / std; dof) < Phi(-2) against scipy's t distribution: dampings 1e-9
    on either side of scipy's threshold, for real dof from 0.3 to 1e7 (one value for every point
    and one per point), +inf and NaN (the normal: -2 standard errors), NaN standard errors (below
    zero is enough)."""
    from scipy import stats

    from rotorid import _core

    dofs = np.concatenate([np.geomspace(0.3, 1e7, 57), [2.0, 4.0, 99_999.0, 100_001.0]])
    level = stats.norm.cdf(-2.0)
    x = stats.t.ppf(level, dofs)  # the threshold in standard errors
    n = dofs.size
    cond, amp = np.ones((n, 2)), np.ones(n)
    for side, flagged in ((1 - 1e-9, False), (1 + 1e-9, True)):
        c = np.full((n, 2, 2, 2), 100.0)
        c[:, 1, 1, 1] = x * side * 3.0  # Cyy of bearing 2, standard error 3
        std = np.full((n, 2, 2, 2), 3.0)
        code, _, ok = _core.flag_codes(cond, amp, None, 1e9, 0.0, 1e9, c, std, dofs)
        assert (code == 16).tolist() == [flagged] * n, side
        # one dof per coefficient: Cyy2's own, the others' (which stay at 100) far off
        per_coef = np.full((n, 2, 2, 2), 0.5)
        per_coef[:, 1, 1, 1] = dofs
        code, _, ok = _core.flag_codes(cond, amp, None, 1e9, 0.0, 1e9, c, std, per_coef)
        assert (code == 16).tolist() == [flagged] * n, side
        for i in (0, 17, n - 1):  # one dof for every point
            code1, *_ = _core.flag_codes(cond[i:i + 1], amp[i:i + 1], None, 1e9, 0.0, 1e9, c[i:i + 1], std[i:i + 1],
                                         dofs[i:i + 1])
            assert code1[0] == (16 if flagged else 0)
    c = np.full((3, 2, 2, 2), 100.0)
    c[:, 0, 0, 0] = [-1.99, -2.01, -0.01]
    std = np.ones((3, 2, 2, 2))
    std[2] = np.nan
    for dof in (np.array([np.inf]), np.array([np.nan]), None):
        code, *_ = _core.flag_codes(np.ones((3, 2)), np.ones(3), None, 1e9, 0.0, 1e9, c, std, dof)
        assert code.tolist() == [0, 16, 16]
    from rotorid._corecall import core

    with pytest.raises(RotoridError, match="dof has shape"):
        core.flag_codes(np.ones((3, 2)), np.ones(3), None, 1e9, 0.0, 1e9, c, std, np.ones(2))


def test_accelerometer_calibration_raises_the_dof_of_residual_errors():
    """Pedestal runs whose housing accelerometers carry a stated calibration error (2 % gain, 1
    degree phase, drawn per trial), 3 runs (residual dof 2), zero true Cxx1: the calibration's
    variance has infinite dof, so the dof grow (Welch-Satterthwaite). Kept at 2 they flagged none
    of the zero dampings and gave intervals far too wide; now the flag rate is near 2.3 % and the
    95 % intervals cover near 95 %."""
    import warnings

    from rotorid import BearingCoefficients
    from rotorid.identify import NEGATIVE_DAMPING

    rig = rotorid.nsf_rig()
    ped = rotorid.example_pedestals()
    rpm = np.arange(3000.0, 7001.0, 250.0)
    c = np.array(rig.bearings.c, dtype=float)
    c[0, 0, 0] = 0.0
    bearings = BearingCoefficients(k=np.array(rig.bearings.k), c=c)
    clean = {s: rotorid.imbalance_response(rig.rotor, bearings, rig.imbalances[s], speed_rpm=rpm, at="probes",
                                           pedestals=ped) for s in "ABC"}
    rng = np.random.default_rng(2)
    bits, cover = [], []
    for _ in range(150):
        gain = 1 + 0.02 * rng.standard_normal(4)
        phase = np.deg2rad(1.0) * rng.standard_normal(4)
        runs = []
        for s, r in clean.items():
            q = r.q + 2e-9 * (rng.standard_normal(r.q.shape) + 1j * rng.standard_normal(r.q.shape)) / np.sqrt(2)
            runs.append(rotorid.SyncResponse(rpm, q, r.imbalance, "probes", s, None, None,
                                             r.pedestal * gain * np.exp(1j * phase), None))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            ident = rotorid.identify_synchronous(rig.rotor, runs, accel_gain_std=0.02, accel_phase_std_deg=1.0)
        bit = ident.flag_reasons.index(NEGATIVE_DAMPING)
        bits.append((ident.flag_code.astype(int) >> bit) & 1)
        iv = ident.interval(0.95)
        cover.append((iv.c_lower[:, 0, 0, 0] <= 0.0) & (0.0 <= iv.c_upper[:, 0, 0, 0]))
    assert ident.std_source == "residual + accelerometer calibration"
    assert np.all(ident.dof > 50)
    assert 0.012 < np.concatenate(bits).mean() < 0.04, np.concatenate(bits).mean()
    assert 0.92 < np.concatenate(cover).mean() < 0.975, np.concatenate(cover).mean()
