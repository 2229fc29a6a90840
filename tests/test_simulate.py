import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import rotorid
from rotorid import RotoridError, SyncResponse, simulate

import oracle
from strategies import bearing_pair, imbalance_sets, rotors


@given(rotors(), bearing_pair(), imbalance_sets(1), st.lists(st.floats(100, 30000), min_size=1, max_size=20))
def test_imbalance_response_matches_oracle(rotor, brg, imbs, rpm):
    imb = imbs[0]
    rpm = np.array(rpm)
    resp = rotorid.imbalance_response(rotor, brg, imb, speed_rpm=rpm)
    M, G, K, C = oracle.matrices(rotor.mass_kg, rotor.it_kgm2, rotor.ip_kgm2, rotor.l1, rotor.l2, brg.k, brg.c)
    F0 = oracle.imbalance_vector(imb.mass_kg, imb.angle_deg, rotor.r, rotor.d)
    for i, s in enumerate(rpm * oracle.RPM):
        q = oracle.response(M, G, K, C, s, s, F0 * s ** 2)
        np.testing.assert_allclose(resp.q[i], q, rtol=1e-9, atol=1e-12 * np.abs(q).max())


@given(rotors(), st.lists(st.complex_numbers(max_magnitude=1e-3, allow_nan=False, allow_infinity=False),
                          min_size=4, max_size=4))
def test_probe_transform_roundtrip(rotor, q):
    q = np.array(q)
    qp = rotorid.bearings_to_probes(rotor, q)
    back = rotorid.probes_to_bearings(rotor, qp)
    np.testing.assert_allclose(back, q, atol=1e-12 * (np.abs(q).max() + 1e-30) * 1e3)
    # eq. 19 literally
    T = oracle.eq19(rotor.l1, rotor.l2, rotor.s1, rotor.s2)
    np.testing.assert_allclose(rotorid.probes_to_bearings(rotor, qp)[[0, 1]], T @ qp[[0, 1]], rtol=1e-10, atol=1e-18)


def test_probe_transform_is_rigid_body_geometry():
    rotor = rotorid.nsf_rig().rotor
    # pure translation: every plane moves the same
    q = np.array([1e-5, 1e-5, 2e-5j, 2e-5j])
    np.testing.assert_allclose(rotorid.bearings_to_probes(rotor, q), q)
    # pure tilt a about the CG: x(z) = a z
    a = 1e-4
    qb = np.array([-a * rotor.l1, a * rotor.l2, 0, 0])
    np.testing.assert_allclose(rotorid.bearings_to_probes(rotor, qb)[:2], [-a * rotor.s1, a * rotor.s2])


def test_response_at_probes_on_request():
    rig = rotorid.nsf_rig()
    rpm = np.array([2000.0, 4000.0])
    rb = rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances["B"], speed_rpm=rpm)
    rp = rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances["B"], speed_rpm=rpm, at="probes")
    assert rp.at == "probes"
    np.testing.assert_allclose(rp.at_bearings(rig.rotor).q, rb.q, rtol=1e-12)
    assert not np.allclose(rp.q, rb.q)


def test_figure3_shape_set_A_peaks_near_first_critical():
    rig = rotorid.nsf_rig()
    rpm = np.arange(500, 10001, 10.0)
    r = rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances["A"], speed_rpm=rpm)
    peak = rpm[np.argmax(np.abs(r.q[:, 0]))]
    assert 3300 < peak < 3700
    # report: motions at the first critical of the order of 60-80 µm 0-pk
    assert 40e-6 < np.abs(r.q).max() < 100e-6


def test_bad_inputs():
    rig = rotorid.nsf_rig()
    with pytest.raises(RotoridError, match="speed_rpm must be > 0"):
        rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances["A"], speed_rpm=[0.0, 1000])
    with pytest.raises(RotoridError, match="speed_rpm contains NaN"):
        rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances["A"], speed_rpm=[np.nan])
    with pytest.raises(RotoridError, match="at must be one of"):
        rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances["A"], speed_rpm=[1000], at="disk")
    with pytest.raises(RotoridError, match="imbalance must be"):
        rotorid.imbalance_response(rig.rotor, rig.bearings, "A", speed_rpm=[1000])
    with pytest.raises(RotoridError, match="q has shape"):
        SyncResponse(speed_rpm=[1000, 2000], q=np.zeros((2, 3)))
    with pytest.raises(RotoridError, match="q contains NaN"):
        SyncResponse(speed_rpm=[1000], q=np.array([[np.nan, 0, 0, 0]]))


@given(rotors(), st.integers(0, 70_000), st.sampled_from(["C", "F", "strided"]))
def test_probe_transform_of_arrays_matches_eq19(rotor, n, layout):
    """The core's one-pass plane transform on (n, 4) arrays of any length (past its parallel
    threshold of 16,384 points too) and any memory layout, against eq. 19 written out."""
    rng = np.random.default_rng(n)
    q = (rng.standard_normal((n, 4)) + 1j * rng.standard_normal((n, 4))) * 1e-5
    if layout == "F":
        q = np.asfortranarray(q)
    elif layout == "strided":
        q = np.repeat(q, 2, axis=0)[::2]
    T = oracle.eq19(rotor.l1, rotor.l2, rotor.s1, rotor.s2)
    want = np.empty_like(q)
    want[:, [0, 1]] = q[:, [0, 1]] @ T.T
    want[:, [2, 3]] = q[:, [2, 3]] @ T.T
    got = rotorid.probes_to_bearings(rotor, q)
    assert got.shape == (n, 4)
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12 * 1e-5)


@given(rotors())
def test_plane_matrices_are_computed_once_per_rotor_and_handed_out_as_copies(rotor):
    """The batch transforms use the rotor's own read-only copy of each matrix; the public functions
    return writable copies, so a caller's edit cannot reach the transforms."""
    import copy
    import pickle

    T = oracle.eq19(rotor.l1, rotor.l2, rotor.s1, rotor.s2)
    pb = simulate.probes_to_bearings_matrix(rotor)
    np.testing.assert_allclose(pb, T, rtol=1e-13, atol=1e-15)
    np.testing.assert_allclose(simulate.bearings_to_probes_matrix(rotor) @ pb, np.eye(2), atol=1e-9 * np.abs(pb).max())
    pb[:] = 7.0                                     # the caller's copy
    assert simulate.probes_to_bearings_matrix(rotor)[0, 0] != 7.0
    q = np.array([[1.0, 2.0, 3.0, 4.0]], dtype=complex)
    np.testing.assert_allclose(rotorid.probes_to_bearings(rotor, q)[0, :2], T @ q[0, :2], rtol=1e-12)
    with pytest.raises(ValueError):
        rotor._plane_matrix("bearings")[0, 0] = 1.0
    assert rotor._plane_matrix("probes") is rotor._plane_matrix("probes")
    # the cache is not a field: equality, replace, copies and pickles are the rotor's
    import dataclasses

    moved = dataclasses.replace(rotor, s=(rotor.s1 * 0.5, rotor.s2 * 0.5 + 0.01))
    assert not np.allclose(moved._plane_matrix("bearings"), rotor._plane_matrix("bearings"))
    for other in (copy.deepcopy(rotor), pickle.loads(pickle.dumps(rotor)), copy.copy(rotor)):
        assert other == rotor
        np.testing.assert_array_equal(other._plane_matrix("bearings"), rotor._plane_matrix("bearings"))
        assert not other._plane_matrix("probes").flags.writeable
    with pytest.raises(RotoridError, match="rotor must be a rotorid.RigidRotor"):
        rotorid.probes_to_bearings("rotor", q)


def test_a_validated_run_moved_to_the_bearings_is_the_transform_and_stays_checked():
    rig = rotorid.nsf_rig()
    rpm = np.linspace(1000, 5000, 9)
    run = rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances["A"], speed_rpm=rpm, at="probes")
    moved = run.at_bearings(rig.rotor)
    np.testing.assert_array_equal(moved.q, rotorid.probes_to_bearings(rig.rotor, run.q))
    assert moved.at == "bearings" and moved.imbalance is run.imbalance and moved.speed_rpm is run.speed_rpm
    # NaN put into a run after it was built still stops the identification with a clear error
    runs = [rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances[s], speed_rpm=rpm, at="probes")
            for s in "AB"]
    runs[1].q[3, 2] = np.nan
    with pytest.raises(RotoridError, match="NaN or inf"):
        rotorid.identify_synchronous(rig.rotor, runs)


@pytest.mark.parametrize("n, fs", [(2, 1.0), (17, 3.0), (70_001, 20_000.0), (200_000, 44_100.0)])
def test_time_response_axis_is_arange_times_dt_to_the_bit(n, fs):
    # the time axis comes from the core (memory it reuses); the values are np.arange(n) * (1 / fs)'s
    rig = rotorid.nsf_rig()
    force = np.zeros(n)
    force[: min(n, 8)] = 10.0
    tr = rotorid.impact_time_response(rig.rotor, rig.bearings, speed_rpm=3000.0, force_N=force, fs_hz=fs)
    want = np.arange(n, dtype=float) * (1.0 / fs)
    assert tr.t.dtype == np.float64 and tr.t.shape == (n,)
    np.testing.assert_array_equal(tr.t.view(np.uint64), want.view(np.uint64))


@pytest.mark.parametrize("value, kw, match", [
    ([1.0, -0.5], dict(positive=True), "must be > 0 \\(got min -0.5\\)"),
    ([1.0, 0.0], dict(positive=True), "must be > 0 \\(got min 0\\)"),
    ([np.nan, -2.0, 3.0], dict(positive=True, finite=False), "must be > 0 \\(got min -2\\)"),
    ([np.nan, -2.0], dict(nonneg=True, finite=False), "must be >= 0 \\(got min -2\\)"),
    ([1.0, np.inf], dict(), "contains NaN or inf \\(first at index \\(1,\\)\\)"),
    ([[1.0, 2.0], [-np.inf, 0.0]], dict(), "contains NaN or inf \\(first at index \\(1, 0\\)\\)"),
])
def test_array_bounds_are_checked_by_reductions_with_the_same_messages(value, kw, match):
    from rotorid._validate import real_array

    with pytest.raises(RotoridError, match=match):
        real_array("x", value, **kw)


def test_nan_passes_the_bounds_where_nan_is_allowed():
    from rotorid._validate import real_array

    a = real_array("x", [np.nan, 1.0, 2.0], positive=True, nonneg=True, finite=False)
    assert np.isnan(a[0]) and a[2] == 2.0
    assert np.isnan(real_array("x", [np.nan, np.nan], positive=True, finite=False)).all()


@given(st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.sampled_from([0.0, -0.0, 1.0, -1.0])),
       st.booleans(), st.booleans(), st.booleans(), st.booleans(), st.sampled_from([None, 0, 1]),
       st.sampled_from([None, (), (1,)]))
def test_a_plain_float_takes_the_short_path_with_the_same_result_or_message(v, positive, nonneg, nonzero, finite, ndim,
                                                                            shape):
    """real_array's shortcut for Python floats (speeds, planes) gives what the full checks give: the
    same 0-d array, or the same error message."""
    from rotorid import _validate

    kw = dict(positive=positive, nonneg=nonneg, nonzero=nonzero, finite=finite, ndim=ndim, shape=shape)

    def outcome(value):
        try:
            a = _validate.real_array("x", value, **kw)
        except RotoridError as exc:
            return "error", str(exc)
        return "ok", (a.dtype, a.shape, a.tobytes())

    # the full checks see the same number as a NumPy scalar (not a plain float)
    assert outcome(v) == outcome(np.float64(v))


@given(st.lists(st.one_of(st.floats(1e-3, 1e6), st.sampled_from([0.0, -1.0, np.nan, np.inf, -np.inf])), max_size=200),
       st.integers(0, 300), st.sampled_from([1, 2, 3]))
def test_the_core_bounds_check_finds_the_first_value_outside(vals, prefix, step):
    """``_core.first_outside`` (the one-pass check of frequencies and speeds) against a scan, on
    contiguous and strided arrays."""
    from rotorid import _core

    a = np.concatenate([np.ones(prefix), np.repeat(np.asarray(vals, dtype=float), step)])[::step]
    bad = np.flatnonzero(~((a > 0.0) & (a < np.inf)))
    assert _core.first_outside(a, 0.0, np.inf) == (int(bad[0]) if bad.size else None)
    with pytest.raises(ValueError, match=r"a has shape \[1, 2\], expected \(n,\)"):
        _core.first_outside(np.ones((1, 2)), 0.0, 1.0)


@pytest.mark.parametrize("freq", [[1.0, np.inf], [np.nan, 1.0], [2.0, -1.0], [0.0], [], [[1.0, 2.0]]])
def test_impact_frf_names_what_is_wrong_with_the_frequencies(freq):
    rig = rotorid.nsf_rig()
    with pytest.raises(RotoridError, match="freq_hz (contains NaN or inf \\(first at index|must be a non-empty 1-D array "
                                           "of frequencies > 0)"):
        rotorid.impact_frf(rig.rotor, rig.bearings, speed_rpm=2000.0, freq_hz=freq)


@pytest.mark.parametrize("bad", [complex(1.0, np.nan), complex(np.inf, 0.0), complex(0.0, -np.inf)])
def test_complex_arrays_refuse_non_finite_parts_either_way(bad):
    from rotorid._validate import complex_array

    with pytest.raises(RotoridError, match="q contains NaN or inf \\(first at index \\(1, 2\\)\\)"):
        complex_array("q", [[1 + 1j, 2j, 3.0], [4.0, 5 - 1j, bad]])


@pytest.mark.parametrize("bad", [0.0, -3.0, np.nan, -np.inf])
@pytest.mark.parametrize("where", [0, 4])
def test_dof_must_be_numbers_above_zero_in_the_constructor_and_after(bad, where):
    """dof (n,) of a covariance: > 0, inf allowed (known exactly); refused by name when built and
    when set after construction (the identification checks the runs' dofs again)."""
    rig = rotorid.nsf_rig()
    rpm = np.linspace(2000.0, 6000.0, 5)
    cov = np.broadcast_to(np.eye(8) * 1e-14, (5, 8, 8))
    runs = [rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances[s], speed_rpm=rpm) for s in "ABC"]
    dof = np.full(5, 12.0)
    dof[where] = bad
    with pytest.raises(RotoridError, match=r"dof \(degrees of freedom of cov\) must be > 0"):
        SyncResponse(rpm, runs[0].q, runs[0].imbalance, cov=cov, dof=dof)
    ok = [SyncResponse(rpm, r.q, r.imbalance, cov=cov, dof=np.where(np.arange(5) == where, np.inf, 12.0)) for r in runs]
    assert np.isinf(ok[0].dof[where])
    ident = rotorid.identify_synchronous(rig.rotor, ok)
    assert np.isfinite(ident.k).all()
    ok[1].dof = dof
    with pytest.raises(RotoridError, match=r"dof \(degrees of freedom of cov\) must be > 0"):
        rotorid.identify_synchronous(rig.rotor, ok)
    ok[1].dof = dof[:3]
    with pytest.raises(RotoridError, match=r"dof must be a number or 5 numbers > 0"):
        rotorid.identify_synchronous(rig.rotor, ok)
