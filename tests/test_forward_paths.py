"""The forward-model entry points hand the core's output over as it is (no re-check of values the
core computed, no second array for the motion relative to the pedestals) and the plane transform
finds NaN/inf on its way through: these tests hold those paths to the definitions they replace
(moving a checked response, subtracting the pedestal motion in NumPy, scanning q first)."""

import dataclasses

import numpy as np
import pytest

import rotorid
from rotorid import RotoridError
from rotorid.simulate import ImpactResponse, SyncResponse, _pedestal_transform, bearings_to_probes_matrix


@pytest.fixture(scope="module")
def rig():
    return rotorid.nsf_rig()


def _same_fields(a, b, rtol=0.0):
    assert type(a) is type(b)
    for f in dataclasses.fields(a):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if isinstance(x, np.ndarray) or isinstance(y, np.ndarray):
            assert np.asarray(x).dtype == np.asarray(y).dtype, f.name
            if rtol:
                np.testing.assert_allclose(x, y, rtol=rtol, atol=0, err_msg=f.name)
            else:
                np.testing.assert_array_equal(x, y, err_msg=f.name)
        else:
            assert x == y and type(x) is type(y), f.name


def _checked_copy(resp):
    """The same response through the validating constructor."""
    return type(resp)(**{f.name: getattr(resp, f.name) for f in dataclasses.fields(resp)})


def _moved_by_definition(resp, rotor):
    """A pedestal-carrying response at the bearings moved to the probe planes with the transform
    of the relative motion: q_p = A q + B p (A = T, B = T - I)."""
    A, B = _pedestal_transform(bearings_to_probes_matrix(rotor))
    move = lambda M, v: np.concatenate([v[:, :2] @ M.T, v[:, 2:] @ M.T], axis=1)  # noqa: E731
    return move(A, resp.q) + move(B, resp.pedestal)


@pytest.mark.parametrize("kind", ["imbalance", "impact"])
def test_pedestal_responses_relative_motion_as_defined(rig, kind):
    ped = rotorid.example_pedestals()
    if kind == "imbalance":
        axis = np.linspace(500.0, 9000.0, 2001)
        make = lambda at: rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances["A"],  # noqa: E731
                                                     speed_rpm=axis, pedestals=ped, at=at)
    else:
        axis = np.linspace(2.0, 400.0, 2001)
        make = lambda at: rotorid.impact_frf(rig.rotor, rig.bearings, speed_rpm=2000.0, freq_hz=axis,  # noqa: E731
                                             direction="y", plane=0.05, pedestals=ped, at=at)
    at_b, at_p = make("bearings"), make("probes")
    # the relative motion formed in the core: the absolute motion less the pedestal motion
    assert at_b.at == "bearings" and at_p.at == "probes"
    np.testing.assert_array_equal(at_p.pedestal, at_b.pedestal)
    # at the probes: T q_abs - p, the same as moving q - p with the pedestal transform
    want = _moved_by_definition(at_b, rig.rotor)
    np.testing.assert_allclose(at_p.q, want, rtol=0, atol=1e-13 * np.abs(want).max())
    np.testing.assert_allclose(at_p.q, at_b.at_probes(rig.rotor).q, rtol=0, atol=1e-13 * np.abs(want).max())
    # the unchecked responses are what the validating constructor makes of the same fields
    _same_fields(at_b, _checked_copy(at_b))
    _same_fields(at_p, _checked_copy(at_p))
    # and they identify like responses built by hand (the pedestal chain reads every field)
    assert np.isfinite(at_p.q).all() and np.abs(at_p.pedestal).max() > 0


def test_the_core_forms_the_relative_motion_and_the_imbalance_gain_as_defined(rig):
    from rotorid import _core

    ped = rotorid.example_pedestals().core_params()
    p = rig.rotor.core_params()
    k = np.ascontiguousarray(rig.bearings.k.reshape(1, 8))
    c = np.ascontiguousarray(rig.bearings.c.reshape(1, 8))
    om = np.linspace(50.0, 1000.0, 3001)
    e = np.ascontiguousarray(rig.imbalances["A"].generalized(rig.rotor), dtype=complex).reshape(1, 1, 4)
    qa, pa, _ = _core.forced_response_pedestal(p, k, c, ped, om, om, e, gain=om ** 2)
    qi, pi, _ = _core.forced_response_pedestal(p, k, c, ped, om, om, e, imbalance=True)
    qr, pr, _ = _core.forced_response_pedestal(p, k, c, ped, om, om, e, imbalance=True, relative=True)
    np.testing.assert_array_equal(qi, qa)
    np.testing.assert_array_equal(pi, pa)
    np.testing.assert_array_equal(pr, pa)
    np.testing.assert_array_equal(qr, qa - pa)
    # at the probe planes: the absolute motion moved by the plane transform, less p, bit for bit
    T = np.ascontiguousarray(bearings_to_probes_matrix(rig.rotor))
    qt, pt, _ = _core.forced_response_pedestal(p, k, c, ped, om, om, e, imbalance=True, relative=True, planes=T)
    np.testing.assert_array_equal(pt, pa)
    np.testing.assert_array_equal(qt, _core.apply_planes(T, qa)[0] - pa)
    with pytest.raises(ValueError, match="gain and imbalance=True exclude each other"):
        _core.forced_response_pedestal(p, k, c, ped, om, om, e, gain=om ** 2, imbalance=True)
    with pytest.raises(ValueError, match="planes needs relative=True"):
        _core.forced_response_pedestal(p, k, c, ped, om, om, e, imbalance=True, planes=T)
    for bad in (np.eye(3), np.ones(4)):
        with pytest.raises(ValueError, match="planes"):
            _core.forced_response_pedestal(p, k, c, ped, om, om, e, imbalance=True, relative=True, planes=bad)


def test_impact_frf_and_its_move_keep_every_field(rig):
    f = np.linspace(2.0, 300.0, 997)
    for at in ("bearings", "probes"):
        t = rotorid.impact_frf(rig.rotor, rig.bearings, speed_rpm=1500, freq_hz=f, plane=-0.02, direction="x",
                               at=at, name="hit 3")
        _same_fields(t, _checked_copy(t))
        assert isinstance(t.speed_rpm, float) and t.sigma == 0.0 and t.force is None
        other = "probes" if at == "bearings" else "bearings"
        moved = t._moved(rig.rotor, other)
        _same_fields(moved, _checked_copy(moved))
        # the unchecked move equals the validating one bit for bit
        slow = ImpactResponse(t.speed_rpm, t.freq_hz, list(t.q), t.force, t.plane, t.direction, t.at, t.name, t.sigma)
        _same_fields(moved, slow._moved(rig.rotor, other))
    # a windowed force-and-response test keeps its force and sigma through the move
    F = np.full(f.size, 50.0 + 5j)
    h = rotorid.impact_frf(rig.rotor, rig.bearings, speed_rpm=1500, freq_hz=f, at="probes")
    t = ImpactResponse(1500.0, f, h.q * F[:, None], F, 0.0, "x", "probes", sigma=2.5)
    b = t.at_bearings(rig.rotor)
    assert b.sigma == 2.5 and b.force is F and b.at == "bearings"
    np.testing.assert_allclose(b.frf(), h.at_bearings(rig.rotor).q, rtol=1e-13)


def test_a_test_whose_q_was_replaced_takes_the_validating_path(rig):
    f = np.linspace(5.0, 50.0, 10)
    t = rotorid.impact_frf(rig.rotor, rig.bearings, speed_rpm=1000, freq_hz=f, at="probes")
    t.q = [[np.nan] * 4] * 10
    with pytest.raises(RotoridError, match=r"q contains NaN or inf \(first at index \(0, 0\)\)"):
        t.at_bearings(rig.rotor)


@pytest.mark.parametrize("where, bad", [((0, 0), np.nan), ((7, 3), complex(0, np.inf)), ((2, 1), -np.inf),
                                        ((99_999, 2), complex(np.nan, 1.0))])
def test_plane_transforms_name_the_first_non_finite_value(rig, where, bad):
    q = np.ones((100_000, 4), dtype=complex)
    q[where] = bad
    q[-1, -1] = np.nan  # a later one does not hide the first
    if where == (99_999, 2):
        q[-1, -1] = 1.0
    for fn in (rotorid.probes_to_bearings, rotorid.bearings_to_probes):
        with pytest.raises(RotoridError, match=rf"q contains NaN or inf \(first at index \({where[0]}, {where[1]}\)\)"):
            fn(rig.rotor, q)
    # batches of responses: the index is over the caller's shape
    qb = np.ones((3, 5, 4), dtype=complex)
    qb[2, 1, 3] = np.nan
    with pytest.raises(RotoridError, match=r"first at index \(2, 1, 3\)"):
        rotorid.probes_to_bearings(rig.rotor, qb)


def test_plane_transforms_of_finite_data_are_unchanged(rig):
    rng = np.random.default_rng(4)
    q = rng.standard_normal((1000, 4)) + 1j * rng.standard_normal((1000, 4))
    T = bearings_to_probes_matrix(rig.rotor)
    want = np.concatenate([q[:, :2] @ T.T, q[:, 2:] @ T.T], axis=1)
    np.testing.assert_allclose(rotorid.bearings_to_probes(rig.rotor, q), want, rtol=1e-14, atol=1e-15)
    back = rotorid.probes_to_bearings(rig.rotor, rotorid.bearings_to_probes(rig.rotor, q))
    np.testing.assert_allclose(back, q, rtol=1e-12, atol=1e-13)
    # a list and a real array are accepted as before; booleans and text are not
    np.testing.assert_array_equal(rotorid.probes_to_bearings(rig.rotor, [[1, 2, 3, 4]]),
                                  rotorid.probes_to_bearings(rig.rotor, np.array([[1, 2, 3, 4]], dtype=complex)))
    with pytest.raises(RotoridError, match="q must be"):
        rotorid.probes_to_bearings(rig.rotor, [[True, False, True, True]])
    with pytest.raises(RotoridError, match="q must be numeric"):
        rotorid.probes_to_bearings(rig.rotor, [["a", "b", "c", "d"]])


def test_sync_responses_unchecked_construction_matches_the_constructor(rig):
    r = rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances["B"], speed_rpm=[1000.0, 2000.0, 3500.0])
    _same_fields(r, _checked_copy(r))
    p = r.at_probes(rig.rotor)
    _same_fields(p, _checked_copy(p))
    assert isinstance(p, SyncResponse) and p.name == rig.imbalances["B"].name


def test_axes_formed_by_the_core_give_the_same_bits(rig):
    """w = 2 pi f, one running speed and one window decay, formed by the core from the axis in Hz
    and (1,) arrays, are the (n,) arrays NumPy would have built, bit for bit; a spin, w or sigma
    of another length is refused naming it."""
    from rotorid import _core

    f = np.linspace(2.0, 300.0, 4099)
    speed = 1730.0
    p = rig.rotor.core_params()
    k = np.ascontiguousarray(rig.bearings.k.reshape(1, 8))
    c = np.ascontiguousarray(rig.bearings.c.reshape(1, 8))
    force = np.array([[[1.0, 0.0, 0.03, 0.0]]], dtype=complex)
    spin_n = np.full(f.size, speed * np.pi / 30)
    want, _ = _core.forced_response(p, k, c, spin_n, 2 * np.pi * f, force)
    got, _ = _core.forced_response(p, k, c, spin_n[:1], f, force, w_scale=2 * np.pi)
    np.testing.assert_array_equal(got, want)
    t = rotorid.impact_frf(rig.rotor, rig.bearings, speed_rpm=speed, freq_hz=f, plane=0.03)
    np.testing.assert_array_equal(t.q, want[:, 0, :])
    ped = rotorid.example_pedestals()
    want_p = _core.forced_response_pedestal(p, k, c, ped.core_params(), spin_n, 2 * np.pi * f, force, relative=True)
    got_p = _core.forced_response_pedestal(p, k, c, ped.core_params(), spin_n[:1], f, force, relative=True,
                                           w_scale=2 * np.pi)
    for a, b in zip(got_p[:2], want_p[:2]):
        np.testing.assert_array_equal(a, b)
    # windowed impacts: identification with w, spin and sigma formed by the core
    tests = [rotorid.ImpactResponse(speed, f, rotorid.impact_frf(rig.rotor, rig.bearings, speed_rpm=speed, freq_hz=f,
                                                                   direction=d).q, sigma=4.0, direction=d)
             for d in "xy"]
    ident = rotorid.identify_impact(rig.rotor, tests)
    e = np.stack([tt.excitation() for tt in tests]).astype(complex)[None]
    kk, cc, cond, *_ = _core.identify(p, 2 * np.pi * f, spin_n, [tt.q for tt in tests], e, np.ones(f.size),
                                      with_std=False, sigma=np.full(f.size, 4.0))
    np.testing.assert_array_equal(ident.k, kk[0])
    np.testing.assert_array_equal(ident.c, cc[0])
    np.testing.assert_array_equal(ident.cond, cond[0])
    with pytest.raises(ValueError, match=r"spin has shape \[2\], expected \(4099,\) or \(1,\)"):
        _core.forced_response(p, k, c, spin_n[:2], f, force)
    with pytest.raises(ValueError, match=r"sigma has shape \[3\]"):
        _core.identify(p, f, spin_n[:1], [tt.q for tt in tests], e, np.ones(1), sigma=np.ones(3), w_scale=2 * np.pi)
    with pytest.raises(ValueError, match=r"w has shape"):
        _core.identify(p, f[:-1], spin_n[:1], [tt.q for tt in tests], e, np.ones(1), w_scale=2 * np.pi)


def test_synchronous_speed_axis_formed_by_the_core_gives_the_same_bits(rig):
    """identify_synchronous hands the core the speeds in rpm (w_scale) with no spin array (spin =
    w, formed once) and no gain (Omega^2): the result is the core call on the (n,) arrays NumPy
    would have built, bit for bit, with and without standard errors, for both solvers; a spin of
    another length is still refused naming it."""
    from rotorid import _core
    from rotorid.simulate import RPM

    rpm = np.linspace(1500.0, 9800.0, 1031)
    runs = [rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances[x], speed_rpm=rpm) for x in "ABC"]
    ident = rotorid.identify_synchronous(rig.rotor, runs)
    p = rig.rotor.core_params()
    e = np.stack([r.imbalance.generalized(rig.rotor) for r in runs]).astype(complex)[None]
    om = rpm * RPM
    qs = [r.q for r in runs]
    want = _core.identify(p, om, om, qs, e, om ** 2, with_std=True)
    np.testing.assert_array_equal(ident.k, want[0][0])
    np.testing.assert_array_equal(ident.c, want[1][0])
    np.testing.assert_array_equal(ident.k_std, want[5][0])
    for method in ("forces", "report"):
        for with_std in (False, True):
            a = _core.identify(p, om, om, qs, e, None, method=method, with_std=with_std)
            b = _core.identify(p, rpm, None, qs, e, None, method=method, with_std=with_std, w_scale=RPM)
            for x, y in zip(a[:7], b[:7]):
                if x is None:
                    assert y is None
                else:
                    np.testing.assert_array_equal(x, y)
    with pytest.raises(ValueError, match=r"spin has shape \[5\], expected \(1031,\) or \(1,\)"):
        _core.identify(p, om, om[:5], qs, e, None)


def _time_response_from_states(rig, u, fs, speed, at, pedestals):
    """impact_time_response as it was computed before the core formed its outputs: the (N, n)
    states read back, then q, p and the pedestals' acceleration in NumPy (the reference)."""
    from rotorid import _core
    from rotorid.pedestal import dof_matrix
    from rotorid.simulate import RPM, _expm, bearings_to_probes, impact_vector

    k, c = rig.bearings.at()
    M, G, K, C = rig.rotor.matrices(k[0], c[0])
    f = impact_vector(0.0, "x")
    if pedestals is None:
        Mt, Ct, Kt, ft = M, C + speed * RPM * G, K, f
    else:
        Mp, Kp, Cp = pedestals.matrices()
        Kb, Cb = dof_matrix(k[0]), dof_matrix(c[0])
        Z = np.zeros((4, 4))
        Mt = np.block([[M, Z], [Z, Mp]])
        Ct = np.block([[C + speed * RPM * G, -C], [-Cb, Cb + Cp]])
        Kt = np.block([[K, -K], [-Kb, Kb + Kp]])
        ft = np.concatenate([f, np.zeros(4)])
    nd = Mt.shape[0]
    Mi = np.linalg.inv(Mt)
    A = np.block([[np.zeros((nd, nd)), np.eye(nd)], [-Mi @ Kt, -Mi @ Ct]])
    B = np.concatenate([np.zeros(nd), Mi @ ft])[:, None]
    ns, dt = 2 * nd, 1.0 / fs
    aug = np.zeros((ns + 2, ns + 2))
    aug[:ns, :ns], aug[:ns, ns:ns + 1], aug[ns, ns + 1] = A, B, 1.0
    E = _expm(aug * dt)
    (x,), bad = _core.lti_run(np.ascontiguousarray(E[:ns, :ns]), np.ascontiguousarray(E[:ns, ns:ns + 1]),
                              np.ascontiguousarray(E[:ns, ns + 1:ns + 2] / dt), np.ascontiguousarray(u[:, None]),
                              np.zeros(ns))
    assert bad is None
    if pedestals is None:
        q = x[:, :4]
        return (bearings_to_probes(rig.rotor, q).real if at == "probes" else q), None, None
    qa, p = x[:, :4], x[:, 4:8]
    acc = (x @ A[nd + 4:nd + 8].T) + u[:, None] * B[nd + 4:nd + 8, 0][None, :]
    return (bearings_to_probes(rig.rotor, qa).real if at == "probes" else qa) - p, p, acc


@pytest.mark.parametrize("at", ["bearings", "probes"])
@pytest.mark.parametrize("with_pedestals", [False, True])
def test_time_response_outputs_formed_by_the_core_match_the_states(rig, at, with_pedestals):
    fs, speed = 20_000.0, 2500.0
    u = rotorid.half_sine_pulse(300.0, 8e-4, fs, 6000, t0_s=1e-3)
    ped = rotorid.example_pedestals() if with_pedestals else None
    r = rotorid.impact_time_response(rig.rotor, rig.bearings, speed_rpm=speed, force_N=u, fs_hz=fs, at=at, pedestals=ped)
    q, p, acc = _time_response_from_states(rig, u, fs, speed, at, ped)
    scale = np.abs(q).max()
    assert scale > 0 and r.q.shape == (u.size, 4) and r.q.flags.c_contiguous
    np.testing.assert_allclose(r.q, q, rtol=0, atol=1e-12 * scale)
    np.testing.assert_array_equal(r.t, np.arange(u.size) * (1.0 / fs))
    if ped is None:
        assert r.pedestal is None and r.pedestal_accel is None
    else:
        np.testing.assert_allclose(r.pedestal, p, rtol=0, atol=1e-12 * np.abs(p).max())
        np.testing.assert_allclose(r.pedestal_accel, acc, rtol=0, atol=1e-12 * np.abs(acc).max())
        assert r.pedestal.flags.c_contiguous and r.pedestal_accel.flags.c_contiguous


def test_time_response_overflow_names_the_sample(rig):
    """An unstable model (negative damping) grows until it overflows: refused, naming the first
    sample whose state is not finite (the states are never read back to scan them)."""
    unstable = rotorid.BearingCoefficients(k=rig.bearings.k, c=-20 * rig.bearings.c)
    u = np.zeros(20_000)
    u[5] = 100.0
    with pytest.raises(RotoridError, match=r"overflowed \(at sample (\d+)\)") as err:
        rotorid.impact_time_response(rig.rotor, unstable, speed_rpm=1000.0, force_N=u, fs_hz=10_000.0)
    at = int(err.value.args[0].split("at sample ")[1].split(")")[0])
    # the samples before are finite and growing: the last of them is huge
    r = rotorid.impact_time_response(rig.rotor, unstable, speed_rpm=1000.0, force_N=u[:at], fs_hz=10_000.0)
    assert np.isfinite(r.q).all() and np.abs(r.q).max() > 1e250


def test_lti_run_outputs_are_checked_by_the_core():
    from rotorid import _core

    phi, g = np.eye(2) * 0.5, np.ones((2, 1))
    u, x0 = np.ones((5, 1)), np.zeros(2)
    with pytest.raises(ValueError, match=r"an output's c has shape \[3, 3\], expected \(p, 2\)"):
        _core.lti_run(phi, g, g, u, x0, [(np.ones((3, 3)), np.ones((3, 1)))])
    with pytest.raises(ValueError, match=r"an output's d has shape"):
        _core.lti_run(phi, g, g, u, x0, [(np.ones((3, 2)), np.ones((2, 1)))])
    (y,), bad = _core.lti_run(phi, g, g, u, x0, [(np.array([[1.0, -1.0]]), np.array([[2.0]]))])
    (x,), _ = _core.lti_run(phi, g, g, u, x0)
    np.testing.assert_array_equal(y[:, 0], x[:, 0] - x[:, 1] + 2.0 * u[:, 0])
    assert bad is None


def test_imbalance_response_speeds_converted_by_the_core_give_the_same_bits(rig):
    from rotorid import _core

    rpm = np.linspace(300.0, 12_000.0, 5003)
    p = rig.rotor.core_params()
    k = np.ascontiguousarray(rig.bearings.k.reshape(1, 8))
    c = np.ascontiguousarray(rig.bearings.c.reshape(1, 8))
    e = np.ascontiguousarray(rig.imbalances["C"].generalized(rig.rotor), dtype=complex).reshape(1, 1, 4)
    want, _ = _core.imbalance_response(p, k, c, rpm * (np.pi / 30.0), e)
    got, _ = _core.imbalance_response(p, k, c, rpm, e, spin_scale=np.pi / 30.0)
    np.testing.assert_array_equal(got, want)
    np.testing.assert_array_equal(rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances["C"],
                                                             speed_rpm=rpm).q, want[:, 0, :])


@pytest.mark.parametrize("kind", ["imbalance", "impact"])
@pytest.mark.parametrize("n", [1, 15, 17, 2048, 5003])
def test_responses_at_the_probes_are_moved_in_the_core_call_as_defined(rig, kind, n, monkeypatch):
    """at="probes" without pedestals: the core moves each solution in the pass that computes it.
    The result is the response at the bearings moved by apply_planes, bit for bit (same
    real-times-complex products, after the gain), for group tails and parallel chunks alike, and
    it costs one core call."""
    from rotorid import _corecall

    if kind == "imbalance":
        axis = np.linspace(300.0, 12_000.0, n)
        make = lambda at: rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances["B"],  # noqa: E731
                                                     speed_rpm=axis, at=at)
    else:
        axis = np.linspace(1.0, 450.0, n)
        make = lambda at: rotorid.impact_frf(rig.rotor, rig.bearings, speed_rpm=2500.0, freq_hz=axis,  # noqa: E731
                                             plane=0.03, direction="y", at=at)
    at_b = make("bearings")
    calls = []
    for name in ("forced_response", "imbalance_response", "apply_planes"):
        real = getattr(_corecall.core, name)
        monkeypatch.setattr(_corecall.core, name, lambda *a, _f=real, _n=name, **k: calls.append(_n) or _f(*a, **k))
    at_p = make("probes")
    assert calls == ["imbalance_response" if kind == "imbalance" else "forced_response"]
    assert at_p.at == "probes"
    want, _ = rotorid._core.apply_planes(bearings_to_probes_matrix(rig.rotor), at_b.q)
    np.testing.assert_array_equal(at_p.q, want)
    _same_fields(at_p, _checked_copy(at_p))
    _same_fields(at_p.at_bearings(rig.rotor), at_b._moved(rig.rotor, "probes").at_bearings(rig.rotor))


def test_the_core_moves_singular_points_as_nan_and_refuses_a_bad_transform(rig):
    from rotorid import _core

    # undamped, isotropic, symmetric, not spinning: H is singular at the bounce frequency sqrt(2 k / m)
    rotor = rotorid.RigidRotor(20.0, 0.5, 0.1, 0.2, 0.2, s=(0.1, 0.12))
    p = rotor.core_params()
    k = np.array([[1e6, 0.0, 0.0, 1e6, 1e6, 0.0, 0.0, 1e6]])
    c = np.zeros((1, 8))
    wn = np.sqrt(2 * 1e6 / 20.0)
    w = np.array([0.5 * wn, wn, 2.0 * wn] * 7)
    e = np.ones((1, 1, 4), complex)
    T = bearings_to_probes_matrix(rotor)
    spin = np.zeros(1)
    q_b, ns_b = _core.forced_response(p, k, c, spin, w, e)
    q_p, ns_p = _core.forced_response(p, k, c, spin, w, e, planes=T)
    assert ns_p == ns_b == 7 and np.isnan(q_p[1::3]).all()
    want, _ = _core.apply_planes(T, q_b[:, 0, :])
    np.testing.assert_array_equal(q_p[:, 0, :], want)
    for bad, msg in [(np.eye(3), r"planes has shape \[3, 3\]"), (np.ones(4), r"planes has shape \[4\]")]:
        for call in (lambda t: _core.forced_response(p, k, c, spin, w, e, planes=t),
                     lambda t: _core.imbalance_response(p, k, c, w, e, planes=t)):
            with pytest.raises(ValueError, match=msg):
                call(bad)
    with pytest.raises(TypeError):
        _core.imbalance_response(p, k, c, w, e, planes=np.eye(2, dtype=complex))
