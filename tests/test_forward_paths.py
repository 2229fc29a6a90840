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
    with pytest.raises(ValueError, match="gain and imbalance=True exclude each other"):
        _core.forced_response_pedestal(p, k, c, ped, om, om, e, gain=om ** 2, imbalance=True)


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
