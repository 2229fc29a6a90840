"""Tilting-pad bearing coefficients from tables (issue 13 item 3): BearingTable, load_bearing_table."""

import dataclasses
import re

import numpy as np
import pytest

from rotorid import RotoridError
from rotorid.support.tpjb import RANGE_TOLERANCE, BearingTable, load_bearing_table

LBF_IN = 4.4482216152605 / 0.0254          # N/m per lbf/in (and N s/m per lbf s/in)
IJ = ("xx", "xy", "yx", "yy")


def _random_table(rng, ns=3, nf=4, *, axis="hz", mass=True, name="t"):
    s = np.sort(rng.choice(np.arange(0, 12001, 500), ns, replace=False)).astype(float)
    f = (np.sort(rng.choice(np.arange(1, 40), nf, replace=False)) * (0.1 if axis == "ratio" else 5.0)).astype(float)
    k = rng.uniform(-3e6, 3e7, (ns, nf, 2, 2))
    c = rng.uniform(-1e3, 3e4, (ns, nf, 2, 2))
    m = rng.uniform(-2.0, 5.0, (ns, nf, 2, 2)) if mass else None
    return BearingTable(s, f, k, c, m, freq_axis=axis, name=name)


def _linear(a, b, c, d):
    """A coefficient a + b s + c x + d s x, bilinear in speed s and frequency-axis value x."""
    return lambda s, x: a + b * s + c * x + d * s * x


def _linear_table(s, x, axis="hz"):
    """A table whose K, C, M (each of the four entries a different bilinear function) are exactly
    representable by bilinear interpolation; returns the table and the functions."""
    rng = np.random.default_rng(7)
    funcs = {p: [[_linear(*rng.uniform(-1, 1, 4) * sc) for _ in range(2)] for _ in range(2)]
             for p, sc in (("k", 1e6), ("c", 1e3), ("m", 1.0))}
    S, X = np.meshgrid(s, x, indexing="ij")
    arr = {p: np.stack([np.stack([funcs[p][i][j](S, X) for j in range(2)], -1) for i in range(2)], -2)
           for p in funcs}
    return BearingTable(s, x, arr["k"], arr["c"], arr["m"], freq_axis=axis), funcs


def _eval(funcs, s, x):
    return np.stack([np.stack([funcs[i][j](s, x) for j in range(2)], -1) for i in range(2)], -2)


# ---------------------------------------------------------------------------------------------
# interpolation


@pytest.mark.parametrize("seed", range(5))
def test_exact_at_grid_nodes(seed):
    rng = np.random.default_rng(seed)
    t = _random_table(rng, 3 + seed % 2, 4 + seed % 3)
    S, F = np.meshgrid(t.speed_rpm, t.freq, indexing="ij")
    k, c = t.coefficients(S.ravel(), F.ravel())
    np.testing.assert_array_equal(k, t.k.reshape(-1, 2, 2))
    np.testing.assert_array_equal(c, t.c.reshape(-1, 2, 2))
    w = 2 * np.pi * F.ravel()[:, None, None]
    z = t.impedance(S.ravel(), F.ravel())
    np.testing.assert_array_equal(z.real, t.k.reshape(-1, 2, 2) - w**2 * t.m.reshape(-1, 2, 2))
    np.testing.assert_array_equal(z.imag, w * t.c.reshape(-1, 2, 2))


def test_bilinear_by_hand():
    k = np.zeros((3, 3, 2, 2))
    # the cell [1000, 3000] x [10, 50] carries 1, 2 / 3, 5 (x 1e6) at its corners in Kxy
    k[:, :, 0, 1] = [[9e6, 9e6, 9e6], [9e6, 1e6, 2e6], [9e6, 3e6, 5e6]]
    c = np.zeros((3, 3, 2, 2))
    c[:, :, 1, 0] = [[0, 0, 0], [0, 100.0, 300.0], [0, 200.0, 800.0]]
    t = BearingTable([0.0, 1000.0, 3000.0], [0.0, 10.0, 50.0], k, c)
    # (1500 rpm, 20 Hz): t_s = 500 / 2000 = 0.25, t_f = 10 / 40 = 0.25
    K, C = t.coefficients(1500.0, 20.0)
    # 0.75*0.75*1 + 0.75*0.25*2 + 0.25*0.75*3 + 0.25*0.25*5 = 1.8125
    assert K[0, 0, 1] == pytest.approx(1.8125e6, rel=1e-14)
    # 0.5625*100 + 0.1875*300 + 0.1875*200 + 0.0625*800 = 200
    assert C[0, 1, 0] == pytest.approx(200.0, rel=1e-14)
    assert K[0, 0, 0] == K[0, 1, 0] == K[0, 1, 1] == 0.0
    # on an edge of the cell only that edge counts: (3000 rpm, 30 Hz) -> (3 + 5) / 2
    K, _ = t.coefficients(3000.0, 30.0)
    assert K[0, 0, 1] == pytest.approx(4e6, rel=1e-14)
    # along speed at a node frequency: (2000 rpm, 50 Hz) -> (2 + 5) / 2
    K, _ = t.coefficients(2000.0, 50.0)
    assert K[0, 0, 1] == pytest.approx(3.5e6, rel=1e-14)


@pytest.mark.parametrize("seed", range(3))
def test_bilinear_function_interpolated_exactly(seed):
    rng = np.random.default_rng(100 + seed)
    s = np.sort(rng.choice(np.arange(0, 10001, 250), 5, replace=False)).astype(float)
    f = np.sort(rng.choice(np.arange(0, 301, 5), 6, replace=False)).astype(float)
    t, funcs = _linear_table(s, f)
    sp = rng.uniform(s[0], s[-1], 200)
    fp = rng.uniform(f[0], f[-1], 200)
    K, C = t.coefficients(sp, fp)
    np.testing.assert_allclose(K, _eval(funcs["k"], sp, fp), rtol=1e-11, atol=1e-6)
    np.testing.assert_allclose(C, _eval(funcs["c"], sp, fp), rtol=1e-11, atol=1e-9)
    # impedance = K + j w C - w^2 M with K, C, M the interpolated ones
    w = 2 * np.pi * fp[:, None, None]
    z_ref = _eval(funcs["k"], sp, fp) + 1j * w * _eval(funcs["c"], sp, fp) - w**2 * _eval(funcs["m"], sp, fp)
    np.testing.assert_allclose(t.impedance(sp, fp), z_ref, rtol=1e-10, atol=1e-4)


def test_impedance_is_k_plus_jwc_minus_w2m():
    one = np.ones((2, 2, 2, 2))
    k = one * np.array([[2e7, 1e6], [-1e6, 3e7]])
    c = one * np.array([[4e3, 50.0], [60.0, 5e3]])
    m = one * np.array([[0.7, 0.0], [0.1, 0.9]])
    t = BearingTable([500.0, 8000.0], [0.0, 200.0], k, c, m)
    f = np.array([0.0, 33.0, 150.0, 200.0])
    z = t.impedance(4000.0, f)
    w = 2 * np.pi * f[:, None, None]
    np.testing.assert_allclose(z, k[0, 0] + 1j * w * c[0, 0] - w**2 * m[0, 0], rtol=1e-14)
    # the mass is not in the coefficients
    K, C = t.coefficients(4000.0, f)
    np.testing.assert_allclose(K, np.broadcast_to(k[0, 0], K.shape), rtol=1e-14)
    np.testing.assert_allclose(C, np.broadcast_to(c[0, 0], C.shape), rtol=1e-14)
    # no mass given: zeros
    t0 = BearingTable([500.0, 8000.0], [0.0, 200.0], k, c)
    assert not np.any(t0.m)
    np.testing.assert_allclose(t0.impedance(4000.0, f), k[0, 0] + 1j * w * c[0, 0], rtol=1e-14)


def test_broadcasting_of_points():
    t = _random_table(np.random.default_rng(3), 3, 3)
    s, f = t.speed_rpm.mean(), np.linspace(t.freq[0], t.freq[-1], 7)
    z1 = t.impedance(s, f)
    z2 = t.impedance(np.full(7, s), f)
    assert z1.shape == (7, 2, 2)
    np.testing.assert_array_equal(z1, z2)
    assert t.impedance(s, f[3]).shape == (1, 2, 2)
    k, c = t.coefficients([t.speed_rpm[0], t.speed_rpm[-1]], t.freq[1])
    np.testing.assert_array_equal(k, t.k[[0, -1], 1])
    np.testing.assert_array_equal(c, t.c[[0, -1], 1])


def test_synchronous_is_the_table_at_speed_over_60():
    s = np.array([600.0, 3000.0, 6000.0, 12000.0])
    f = np.array([0.0, 20.0, 60.0, 120.0, 200.0])
    t, funcs = _linear_table(s, f)
    sp = np.array([600.0, 1200.0, 3000.0, 4321.0, 12000.0])
    K, C = t.synchronous(sp)
    K2, C2 = t.coefficients(sp, sp / 60.0)
    np.testing.assert_array_equal(K, K2)
    np.testing.assert_array_equal(C, C2)
    np.testing.assert_allclose(K, _eval(funcs["k"], sp, sp / 60.0), rtol=1e-11, atol=1e-6)


# ---------------------------------------------------------------------------------------------
# ratio axis


def test_ratio_axis_frequency_is_ratio_times_running_frequency():
    s = np.array([1000.0, 2000.0, 4000.0])
    r = np.array([0.25, 0.5, 1.0, 2.0])
    rng = np.random.default_rng(11)
    k = rng.uniform(1e6, 1e7, (3, 4, 2, 2))
    c = rng.uniform(1e2, 1e4, (3, 4, 2, 2))
    m = rng.uniform(0.0, 2.0, (3, 4, 2, 2))
    t = BearingTable(s, r, k, c, m, freq_axis="ratio", name="ratio")
    assert t.freq_axis == "ratio" and t.freq_hz is None
    np.testing.assert_array_equal(t.freq_ratio, r)
    S, R = np.meshgrid(s, r, indexing="ij")
    f = R.ravel() * S.ravel() / 60.0                     # the frequency at ratio r
    K, C = t.coefficients(S.ravel(), f)
    np.testing.assert_allclose(K, k.reshape(-1, 2, 2), rtol=1e-13)
    np.testing.assert_allclose(C, c.reshape(-1, 2, 2), rtol=1e-13)
    w = 2 * np.pi * f[:, None, None]
    np.testing.assert_allclose(t.impedance(S.ravel(), f),
                               (k + 0j).reshape(-1, 2, 2) + 1j * w * c.reshape(-1, 2, 2)
                               - w**2 * m.reshape(-1, 2, 2), rtol=1e-12)
    # synchronous = ratio 1 (column 2)
    Ks, Cs = t.synchronous(s)
    np.testing.assert_array_equal(Ks, k[:, 2])
    np.testing.assert_array_equal(Cs, c[:, 2])


def test_ratio_axis_interpolates_in_ratio_not_in_hz():
    # K linear in the ratio: at 3000 rpm (50 Hz running) and 30 Hz the ratio is 0.6
    s, r = np.array([1000.0, 5000.0]), np.array([0.0, 1.0, 3.0])
    k = np.zeros((2, 3, 2, 2))
    k[:, :, 0, 0] = 1e6 + 2e6 * r
    t = BearingTable(s, r, k, np.zeros_like(k), freq_axis="ratio")
    K, _ = t.coefficients(3000.0, 30.0)
    assert K[0, 0, 0] == pytest.approx(1e6 + 2e6 * 0.6, rel=1e-13)
    t2, funcs = _linear_table(np.array([1000.0, 3000.0, 9000.0]), np.array([0.2, 0.5, 1.0, 1.5]), axis="ratio")
    sp = np.array([1500.0, 2000.0, 7000.0])
    fp = np.array([0.3, 1.2, 0.9]) * sp / 60.0
    np.testing.assert_allclose(t2.coefficients(sp, fp)[0], _eval(funcs["k"], sp, fp * 60.0 / sp), rtol=1e-11,
                               atol=1e-6)


def test_ratio_table_refuses_speed_zero():
    t = BearingTable([0.0, 3000.0], [0.5, 1.0], np.ones((2, 2, 2, 2)), np.ones((2, 2, 2, 2)), freq_axis="ratio",
                     name="r")
    with pytest.raises(RotoridError, match=r"freq_ratio.*undefined at speed 0 rpm: point\(s\) 1"):
        t.impedance([3000.0, 0.0], [25.0, 0.0])
    with pytest.raises(RotoridError, match="speed 0"):
        t.coefficients(0.0, 10.0)
    with pytest.raises(RotoridError, match="speed 0"):
        t.synchronous([0.0, 1000.0])
    # a Hz table takes speed 0
    th = BearingTable([0.0, 3000.0], [0.0, 50.0], np.ones((2, 2, 2, 2)), np.ones((2, 2, 2, 2)))
    assert th.synchronous(0.0)[0].shape == (1, 2, 2)


# ---------------------------------------------------------------------------------------------
# single speed / single frequency


def test_single_speed_table_is_constant_in_speed():
    rng = np.random.default_rng(5)
    k, c = rng.uniform(1e6, 1e7, (1, 3, 2, 2)), rng.uniform(1e2, 1e3, (1, 3, 2, 2))
    t = BearingTable([4000.0], [10.0, 50.0, 90.0], k, c)
    for sp in (0.0, 4000.0, 25000.0):
        K, C = t.coefficients(sp, [10.0, 30.0, 90.0])
        np.testing.assert_array_equal(K[[0, 2]], k[0, [0, 2]])
        np.testing.assert_allclose(K[1], 0.5 * (k[0, 0] + k[0, 1]), rtol=1e-14)
        np.testing.assert_allclose(C[1], 0.5 * (c[0, 0] + c[0, 1]), rtol=1e-14)
    with pytest.raises(RotoridError, match=r"point 0 \(speed 4000 rpm, freq 95 Hz\).*freq_hz 10\.\.90 Hz"):
        t.coefficients(4000.0, 95.0)


def test_single_frequency_table_is_constant_in_frequency():
    rng = np.random.default_rng(6)
    k, c = rng.uniform(1e6, 1e7, (2, 1, 2, 2)), rng.uniform(1e2, 1e3, (2, 1, 2, 2))
    t = BearingTable([1000.0, 3000.0], [50.0], k, c)
    K, C = t.coefficients([1000.0, 2000.0, 3000.0], [0.0, 500.0, 1e4])
    np.testing.assert_array_equal(K[0], k[0, 0])
    np.testing.assert_allclose(K[1], 0.5 * (k[0, 0] + k[1, 0]), rtol=1e-14)
    np.testing.assert_array_equal(C[2], c[1, 0])
    with pytest.raises(RotoridError, match=r"speed_rpm 1000\.\.3000 rpm"):
        t.coefficients(999.0, 50.0)
    # one node: constant everywhere; the synchronous coefficients then are that node
    t1 = BearingTable([3000.0], [50.0], k[:1], c[:1], name="one")
    K1, C1 = t1.synchronous([0.0, 1e5])
    np.testing.assert_array_equal(K1, np.broadcast_to(k[0, 0], (2, 2, 2)))
    t1r = BearingTable(3000.0, 1.0, k[:1], c[:1], freq_axis="ratio")
    np.testing.assert_array_equal(t1r.coefficients(10.0, 123.0)[1][0], c[0, 0])


# ---------------------------------------------------------------------------------------------
# range


def test_points_outside_the_table_are_named():
    t = BearingTable([1000.0, 2000.0, 5000.0], [0.0, 100.0], np.ones((3, 2, 2, 2)), np.ones((3, 2, 2, 2)),
                     name="FPJB")
    msg = ("BearingTable 'FPJB': 2 point(s) outside the table (no extrapolation): point 1 (speed 6000 rpm, freq "
           "50 Hz), point 3 (speed 2000 rpm, freq 120 Hz); the table covers speed_rpm 1000..5000 rpm and freq_hz "
           "0..100 Hz")
    with pytest.raises(RotoridError, match=re.escape(msg)):
        t.impedance([1500.0, 6000.0, 5000.0, 2000.0], [50.0, 50.0, 100.0, 120.0])
    with pytest.raises(RotoridError, match=r"point 0 \(speed 500 rpm"):
        t.coefficients(500.0, 10.0)
    with pytest.raises(RotoridError, match=r"point 0 \(speed 6000 rpm, freq 100 Hz\)"):
        t.synchronous(6000.0)
    tr = BearingTable([1000.0, 2000.0], [0.5, 1.0], np.ones((2, 2, 2, 2)), np.ones((2, 2, 2, 2)),
                      freq_axis="ratio", name="R")
    with pytest.raises(RotoridError, match=re.escape("point 0 (speed 1200 rpm, freq 30 Hz = ratio 1.5); the "
                                                     "table covers speed_rpm 1000..2000 rpm and freq_ratio 0.5..1")):
        tr.impedance(1200.0, 30.0)


def test_range_tolerance_at_the_ends():
    k = np.zeros((2, 2, 2, 2))
    k[:, :, 0, 0] = [[1.0, 2.0], [3.0, 4.0]]
    t = BearingTable([1000.0, 2000.0], [10.0, 50.0], k, np.zeros_like(k))
    inside = 1 + 0.5 * RANGE_TOLERANCE
    K, _ = t.coefficients([2000.0 * inside, 1000.0 / inside], [50.0 * inside, 10.0 / inside])
    assert K[:, 0, 0].tolist() == [4.0, 1.0]      # taken at the end nodes, no extrapolation
    outside = 1 + 10 * RANGE_TOLERANCE
    with pytest.raises(RotoridError, match="outside the table"):
        t.coefficients(2000.0 * outside, 20.0)
    with pytest.raises(RotoridError, match="outside the table"):
        t.coefficients(1500.0, 10.0 / outside)


# ---------------------------------------------------------------------------------------------
# the dataclass and its validation


def test_frozen_read_only_and_copied():
    k = np.ones((2, 2, 2, 2))
    s = np.array([0.0, 1000.0])
    t = BearingTable(s, [0, 10], k, k)
    with pytest.raises(dataclasses.FrozenInstanceError):
        t.k = k
    with pytest.raises(ValueError):
        t.k[0, 0, 0, 0] = 5.0
    s[1] = 99.0
    k[:] = 7.0
    assert t.speed_rpm[1] == 1000.0 and t.c[0, 0, 0, 0] == 1.0
    assert t.freq.dtype == float and t.freq_hz is t.freq and t.freq_ratio is None
    assert repr(t) == "BearingTable('': 2 speeds 0..1000 rpm x 2 freq_hz 0..10 Hz)"
    assert "with added mass" in repr(BearingTable([1.0], [1.0], k[:1, :1], k[:1, :1], k[:1, :1]))
    assert BearingTable([1.0], [1.0], k[:1, :1], k[:1, :1], freq_axis="Ratio").freq_axis == "ratio"


GOOD = dict(speed_rpm=[1000.0, 2000.0], freq=[0.0, 50.0, 100.0], k=np.ones((2, 3, 2, 2)), c=np.ones((2, 3, 2, 2)))


def _nan_at(key, where):
    a = np.array(GOOD[key], dtype=float)
    a[where] = np.nan
    return a


@pytest.mark.parametrize("change, match", [
    (dict(k=np.ones((3, 2, 2, 2))), r"k has shape \(3, 2, 2, 2\), expected \(2, 3, 2, 2\)"),
    (dict(c=np.ones((2, 3, 2))), r"c has shape \(2, 3, 2\), expected \(2, 3, 2, 2\)"),
    (dict(m=np.ones((2, 3, 2, 3))), r"m has shape"),
    (dict(k=np.ones((2, 2))), r"k has shape"),
    (dict(k=_nan_at("k", (1, 2, 0, 1))), r"k contains NaN or inf \(first at index \(1, 2, 0, 1\)\)"),
    (dict(c=np.full((2, 3, 2, 2), np.inf)), r"c contains NaN or inf"),
    (dict(m=np.full((2, 3, 2, 2), np.nan)), r"m contains NaN or inf"),
    (dict(speed_rpm=[1000.0, np.nan]), r"speed_rpm contains NaN or inf"),
    (dict(freq=[0.0, np.inf, 100.0]), r"freq_hz contains NaN or inf"),
    (dict(speed_rpm=[2000.0, 1000.0]), r"speed_rpm must be ascending: speed_rpm\[0\] = 2000 > speed_rpm\[1\] = 1000"),
    (dict(freq=[0.0, 50.0, 50.0]), r"freq_hz has the value 50 twice"),
    (dict(speed_rpm=[-1000.0, 2000.0]), r"speed_rpm must be >= 0"),
    (dict(freq=[-5.0, 50.0, 100.0]), r"freq_hz must be >= 0"),
    (dict(freq=[-0.5, 1.0, 2.0], freq_axis="ratio"), r"freq_ratio must be >= 0"),
    (dict(speed_rpm=[]), r"speed_rpm must be a non-empty 1-D array"),
    (dict(speed_rpm=[[1000.0, 2000.0]]), r"speed_rpm must be a non-empty 1-D array"),
    (dict(speed_rpm="fast"), r"speed_rpm must be numeric"),
    (dict(freq=[0.0, "50", 100.0]), r"freq_hz must be numeric"),
    (dict(k=[[["a"]]]), r"k must be numeric"),
    (dict(c=np.ones((2, 3, 2, 2)) * (1 + 1j)), r"c must be real"),
    (dict(speed_rpm=[True, False]), r"speed_rpm must be numbers"),
    (dict(freq_axis="rpm"), r"freq_axis must be one of \['hz', 'ratio'\], got 'rpm'"),
    (dict(freq_axis=1), r"freq_axis must be one of"),
    (dict(name=3), r"name must be a string"),
])
def test_bad_tables(change, match):
    with pytest.raises(RotoridError, match=match):
        BearingTable(**{**GOOD, **change})


@pytest.mark.parametrize("args, match", [
    ((-100.0, 10.0), r"speed_rpm must be >= 0"),
    ((1500.0, -1.0), r"freq_hz must be >= 0"),
    ((np.nan, 10.0), r"speed_rpm contains NaN"),
    ((1500.0, [10.0, np.inf]), r"freq_hz contains NaN"),
    (("1500", 10.0), r"speed_rpm must be numeric"),
    ((1500.0, None), r"freq_hz must be numeric"),
    ((1500.0, 10.0 + 1j), r"freq_hz must be real"),
    (([1500.0, 1600.0], [10.0, 20.0, 30.0]), r"do not broadcast"),
    (([[1500.0], [1600.0]], [10.0, 20.0]), r"scalars or 1-D arrays"),
    (([], 10.0), r"scalars or 1-D arrays"),
])
def test_bad_points(args, match):
    t = BearingTable(**GOOD)
    for fn in (t.impedance, t.coefficients):
        with pytest.raises(RotoridError, match=match):
            fn(*args)


def test_bad_synchronous_speeds():
    t = BearingTable(**GOOD)
    for bad, match in ((-1.0, ">= 0"), ([[1200.0]], "1-D"), ([], "empty"), ("x", "numeric"), ([np.nan], "NaN")):
        with pytest.raises(RotoridError, match=match):
            t.synchronous(bad)


# ---------------------------------------------------------------------------------------------
# files


def _frame(t, *, kunit=None, cunit=None, k_factor=1.0, c_factor=1.0, shuffle=0, axis="hz", mass=False):
    import pandas as pd

    rows = []
    for i, s in enumerate(t.speed_rpm):
        for j, f in enumerate(t.freq):
            row = {"speed_rpm": s, ("freq_hz" if axis == "hz" else "freq_ratio"): f}
            for n, ij in enumerate(IJ):
                a, b = divmod(n, 2)
                row["Kxx Kxy Kyx Kyy".split()[n] + (f" {kunit}" if kunit else "")] = t.k[i, j, a, b] / k_factor
                row["Cxx Cxy Cyx Cyy".split()[n] + (f" {cunit}" if cunit else "")] = t.c[i, j, a, b] / c_factor
                if mass:
                    row["M" + ij] = t.m[i, j, a, b]
            rows.append(row)
    df = pd.DataFrame(rows)
    if shuffle:
        df = df.sample(frac=1.0, random_state=shuffle).reset_index(drop=True)
    return df


def _same(a, b, rtol=0.0):
    np.testing.assert_array_equal(a.speed_rpm, b.speed_rpm)
    np.testing.assert_array_equal(a.freq, b.freq)
    assert a.freq_axis == b.freq_axis
    for key in "kcm":
        np.testing.assert_allclose(getattr(a, key), getattr(b, key), rtol=rtol, atol=0)


def test_csv_round_trip_si(tmp_path):
    t = _random_table(np.random.default_rng(21), 4, 5, mass=False)
    p = tmp_path / "fpjb_si.csv"
    _frame(t, kunit="(N/m)", cunit="[N*s/m]", shuffle=3).to_csv(p, index=False)
    got = load_bearing_table(p)
    _same(got, t)
    assert got.name == "fpjb_si"
    # a leading index column, extra columns and lower-case names do no harm
    df = _frame(t, shuffle=4)
    df.columns = [c.lower() for c in df.columns]
    df["eccentricity"] = 0.3
    df.to_csv(p, index=True)
    _same(load_bearing_table(p, name="again"), t)


def test_csv_round_trip_us_units(tmp_path):
    t = _random_table(np.random.default_rng(22), 3, 4, mass=False)
    p = tmp_path / "fpjb_us.csv"
    _frame(t, kunit="[lbf/in]", cunit="(lbf*s/in)", k_factor=LBF_IN, c_factor=LBF_IN, shuffle=5).to_csv(p,
                                                                                                      index=False)
    got = load_bearing_table(p, stiffness_unit="lbf/in", damping_unit="lbf*s/in")
    _same(got, t, rtol=1e-13)
    # without the units in the header: the arguments alone decide
    _frame(t, k_factor=LBF_IN, c_factor=LBF_IN).to_csv(p, index=False)
    _same(load_bearing_table(p, stiffness_unit="lbf/in", damping_unit="lbf*s/in"), t, rtol=1e-13)
    # read as N/m the numbers are off by the factor: the conversion is applied
    got_si = load_bearing_table(p)
    np.testing.assert_allclose(got_si.k * LBF_IN, t.k, rtol=1e-13)


def test_csv_round_trip_ratio_axis_with_mass_semicolons_and_comments(tmp_path):
    t = _random_table(np.random.default_rng(23), 3, 4, axis="ratio", mass=True)
    p = tmp_path / "ratio.txt"
    body = _frame(t, axis="ratio", mass=True, shuffle=6).to_csv(index=False, sep=";")
    p.write_text("# reduced coefficients from a bearing code\n\n" + body)
    got = load_bearing_table(p, freq_axis="ratio")
    _same(got, t)
    np.testing.assert_allclose(got.synchronous(t.speed_rpm[1])[0], t.coefficients(t.speed_rpm[1],
                                                                                   t.speed_rpm[1] / 60)[0])


def test_excel_round_trip(tmp_path):
    pytest.importorskip("openpyxl")
    import pandas as pd

    t = _random_table(np.random.default_rng(24), 2, 3, mass=True)
    p = tmp_path / "fpjb.xlsx"
    with pd.ExcelWriter(p, engine="openpyxl") as w:
        pd.DataFrame({"note": ["other"]}).to_excel(w, sheet_name="notes", index=False)
        _frame(t, mass=True, shuffle=7).to_excel(w, sheet_name="coefs", index=False)
    # (Excel keeps 15 significant digits)
    _same(load_bearing_table(p, sheet="coefs"), t, rtol=1e-14)
    _same(load_bearing_table(p, sheet=1), t, rtol=1e-14)
    with pytest.raises(RotoridError, match=r"no column\(s\)"):
        load_bearing_table(p)                     # the first sheet has no table
    with pytest.raises(RotoridError, match="no sheet 'x'"):
        load_bearing_table(p, sheet="x")
    with pytest.raises(RotoridError, match="sheet index 5 out of range"):
        load_bearing_table(p, sheet=5)


HEAD = "speed_rpm,freq_hz,Kxx,Kxy,Kyx,Kyy,Cxx,Cxy,Cyx,Cyy"
ROWS = ["1000,0,1,0,0,1,5,0,0,5", "1000,50,2,0,0,2,5,0,0,5", "2000,0,3,0,0,3,5,0,0,5", "2000,50,4,0,0,4,5,0,0,5"]


def _write(tmp_path, head=HEAD, rows=ROWS, name="t.csv"):
    p = tmp_path / name
    p.write_text("\n".join([head] + list(rows)) + "\n")
    return p


def test_the_small_file_reads(tmp_path):
    t = load_bearing_table(_write(tmp_path))
    assert t.k[:, :, 0, 0].tolist() == [[1.0, 2.0], [3.0, 4.0]]
    assert t.c[:, :, 1, 1].tolist() == [[5.0, 5.0], [5.0, 5.0]]


@pytest.mark.parametrize("head, rows, kwargs, match", [
    (HEAD.replace(",Cyx", ""), [r.rsplit(",", 2)[0] + "," + r.rsplit(",", 1)[1] for r in ROWS], {},
     r"no column\(s\) \['Cyx'\]"),
    (HEAD, ROWS[:3], {}, r"missing: \(speed 2000 rpm, freq_hz 50 Hz\)"),
    (HEAD, ROWS + [ROWS[1]], {}, r"more than once: speed 1000 rpm, freq_hz 50 Hz on lines 3, 6"),
    (HEAD, ROWS + ["3000,50,4,0,0,4,5,0,0,5"], {}, r"missing: \(speed 3000 rpm, freq_hz 0 Hz\)"),
    (HEAD, ROWS, dict(stiffness_unit="furlong/s"), r"unknown unit 'furlong/s'"),
    (HEAD, ROWS, dict(stiffness_unit="N*s/m"), r"unit 'N\*s/m' is a damping, expected a stiffness"),
    (HEAD, ROWS, dict(damping_unit="lbf/in"), r"is a stiffness, expected a damping"),
    (HEAD, ROWS, dict(mass_unit="N"), r"is a force, expected a mass"),
    (HEAD, ROWS, dict(stiffness_unit=None), r"stiffness_unit must be a string"),
    (HEAD, ROWS, dict(freq_axis="Hertz"), r"freq_axis must be one of"),
    (HEAD, ROWS, dict(freq_axis="ratio"), r"has a freq_hz column, not freq_ratio: pass freq_axis='hz'"),
    (HEAD.replace("freq_hz", "freq_ratio"), ROWS, {}, r"has a freq_ratio column, not freq_hz: pass freq_axis='ratio'"),
    (HEAD.replace("Kxx", "Kxx [lbf/in]"), ROWS, {}, r"column 'Kxx \[lbf/in\]' is in lbf/in but stiffness_unit='N/m'"),
    (HEAD.replace("Cyy", "Cyy (lbf*s/in)"), ROWS, dict(damping_unit="N*s/m"), r"pass damping_unit='lbf\*s/in'"),
    (HEAD.replace("Kxx", "Kxx (parsec)"), ROWS, {}, r"column 'Kxx \(parsec\)': unknown unit 'parsec'"),
    (HEAD.replace("Kxx", "Kxx (N*s/m)"), ROWS, {}, r"is a damping, expected a stiffness"),
    (HEAD.replace("speed_rpm", "speed_rpm (rad/s)"), ROWS, {}, r"must be in rpm \(its name says so\), not rad/s"),
    (HEAD.replace("freq_hz", "freq_hz [mm]"), ROWS, {}, r"is a length, expected a frequency"),
    (HEAD.replace("freq_hz", "freq_ratio (Hz)"), ROWS, dict(freq_axis="ratio"), r"a frequency ratio has no unit"),
    (HEAD + ",kxx (N/m)", [r + ",1" for r in ROWS], {}, r"column Kxx twice, 'Kxx' and 'kxx \(N/m\)'"),
    (HEAD + ",Mxx,Myy", [r + ",1,1" for r in ROWS], {},
     r"added mass columns \['Mxx', 'Myy'\] without \['Mxy', 'Myx'\]"),
    (HEAD, ROWS[:2] + ["2000,0,abc,0,0,3,5,0,0,5"] + ROWS[3:], {}, r"column 'Kxx', line 4 has 'abc'"),
    (HEAD, ROWS[:2] + ["2000,0,,0,0,3,5,0,0,5"] + ROWS[3:], {}, r"column 'Kxx', line 4 has a blank cell"),
    (HEAD, ROWS[:2] + ["2000,0,nan,0,0,3,5,0,0,5"] + ROWS[3:], {}, r"column 'Kxx', line 4 has 'nan'"),
    (HEAD, ROWS[:2] + ["2000,0,1,0,0,3,inf,0,0,5"] + ROWS[3:], {}, r"column 'Cxx', line 4 has 'inf'"),
    (HEAD, ROWS[:2] + ["-2000,0,1,0,0,3,5,0,0,5"] + ROWS[3:], {}, r"column 'speed_rpm' must be >= 0: line\(s\) 4"),
    (HEAD, ROWS[:2] + ["2000,-5,1,0,0,3,5,0,0,5"] + ROWS[3:], {}, r"column 'freq_hz' must be >= 0"),
    (HEAD, ROWS[:2] + ["2000,0,1,0,0,3,5,0,0"] + ROWS[3:], {}, r"line 4 has 9 fields, the header \(line 1\) 10"),
    (HEAD, ROWS[:2] + ["2000,0,1,0,0,3,5,0,0,5,7"] + ROWS[3:], {}, r"line 4 has 11 fields"),
    (HEAD, [], {}, r"no data rows after the header \(line 1\)"),
    (HEAD, ROWS, dict(sheet="Sheet1"), r"sheet='Sheet1' applies to Excel workbooks only"),
    ("Speed,Freq,Kxx", ["1,2,3"], {}, r"no column\(s\) \['speed_rpm', 'freq_hz', 'Kxy'.*accepted: speed_rpm"),
])
def test_bad_files(tmp_path, head, rows, kwargs, match):
    with pytest.raises(RotoridError, match=match):
        load_bearing_table(_write(tmp_path, head, rows), **kwargs)


def test_bad_paths(tmp_path):
    with pytest.raises(RotoridError, match="no such file"):
        load_bearing_table(tmp_path / "absent.csv")
    with pytest.raises(RotoridError, match="unknown file type '.json'"):
        load_bearing_table(_write(tmp_path, name="t.json"))
    with pytest.raises(RotoridError, match="path must be a file path"):
        load_bearing_table(3)
    (tmp_path / "empty.csv").write_text("# only a comment\n\n")
    with pytest.raises(RotoridError, match="the file is empty"):
        load_bearing_table(tmp_path / "empty.csv")
    (tmp_path / "bad.xlsx").write_text("not a workbook")
    with pytest.raises(RotoridError, match="cannot read .* as an Excel workbook"):
        load_bearing_table(tmp_path / "bad.xlsx")
