"""DAQ 1X tables with the bearing-housing accelerometers px1, px2, py1, py2 (issue 12, flexible pedestals)."""

import warnings

import numpy as np
import pytest

import rotorid
from rotorid import RotoridError, rawsim
from rotorid import example as ex
from rotorid import tables as tb
from rotorid.recording import ACCELEROMETERS

MIL = 25.4e-6
G = 9.80665
RPM = np.pi / 30
SPEEDS = np.arange(3000.0, 6001.0, 250.0)
# the DAQ's column order: DE X, DE Y, FE X, FE Y probes, then the housings' accelerometers
FILE_ORDER = ("x1", "y1", "x2", "y2", "px1", "py1", "px2", "py2")
PLAIN = {ch: {"amplitude": f"A {ch}", "phase": f"P {ch}"} for ch in FILE_ORDER}
Q_ORDER = ("x1", "x2", "y1", "y2")


def rig():
    rotor, brg, remnant = rawsim.example_rig()
    return rotor, brg, remnant


def response(speeds=SPEEDS, imbalance=None):
    rotor, brg, remnant = rig()
    return rotorid.imbalance_response(rotor, brg, remnant if imbalance is None else imbalance, speed_rpm=speeds,
                                      at="probes", pedestals=rotorid.example_pedestals())


def raises(match, fn, *a, **kw):
    with pytest.raises(RotoridError) as exc:
        fn(*a, **kw)
    msg = str(exc.value)
    for m in match:
        assert m in msg, f"{m!r} not in {msg!r}"
    return msg


def cells_of(speeds, q, p, *, unit_m=MIL, pk=2.0, accel_si=G, accel_pk=2.0, sign=-1.0):
    """Rows [speed, (amplitude, phase) per FILE_ORDER channel] of a table in full precision: probe
    amplitudes in ``unit_m`` (pk factor ``pk``), accelerations A = -Ω² P in ``accel_si`` m/s² per
    unit (pk factor ``accel_pk``), phases in degrees (sign -1: lag, +1: lead)."""
    om = np.asarray(speeds, float) * RPM
    a = -(om ** 2)[:, None] * p                                # the accelerometers read -Ω² P
    vals = {ch: (q[:, Q_ORDER.index(ch)], unit_m / pk) for ch in Q_ORDER}
    vals.update({ch: (a[:, ACCELEROMETERS.index(ch)], accel_si / accel_pk) for ch in ACCELEROMETERS})
    rows = []
    for r, s in enumerate(speeds):
        row = [repr(float(s))]
        for ch in FILE_ORDER:
            z, f = vals[ch]
            row += [repr(float(np.abs(z[r]) / f)), repr(float(sign * np.angle(z[r], deg=True)))]
        rows.append(row)
    return rows


def write(path, rows, cols=PLAIN, speed="RPM", order=FILE_ORDER, sep=","):
    head = [speed] + [cols[ch][k] for ch in order for k in ("amplitude", "phase")]
    path.write_text("\n".join([sep.join(head)] + [sep.join(r) for r in rows]) + "\n", encoding="utf-8")
    return path


def table_track(speeds, q, p, name="run"):
    s = np.asarray(speeds, float)
    n = s.size
    return tb.TableTrack(s, np.asarray(q)[:, None, :], (1,), np.full(n, np.nan), np.full((n, 4), np.nan),
                         np.full(n, np.nan), pedestal=np.asarray(p)[:, None, :], name=name)


# ---------------------------------------------------------------------------------------------
# reading: units, amplitude and phase conventions


@pytest.mark.parametrize("accel_unit, accel_si", [("g", G), ("m/s^2", 1.0), ("m/s2", 1.0), ("G", G)])
@pytest.mark.parametrize("amplitude, accel_amplitude", [("pk-pk", None), ("0-pk", None), ("pk-pk", "0-pk"),
                                                        ("0-pk", "pp")])
@pytest.mark.parametrize("phase", ["lag", "lead"])
def test_round_trip_from_a_known_response(tmp_path, accel_unit, accel_si, amplitude, accel_amplitude, phase):
    r = response()
    pk = 2.0 if amplitude == "pk-pk" else 1.0
    apk = pk if accel_amplitude is None else (1.0 if accel_amplitude == "0-pk" else 2.0)
    rows = cells_of(SPEEDS, r.q, r.pedestal, pk=pk, accel_si=accel_si, accel_pk=apk,
                    sign=-1.0 if phase == "lag" else 1.0)
    p = write(tmp_path / "ped.csv", rows)
    t = tb.load_1x_table(p, columns=PLAIN, amplitude=amplitude, phase=phase, accel_unit=accel_unit,
                         accel_amplitude=accel_amplitude)
    assert t.has_pedestal and t.pedestal.shape == (SPEEDS.size, 1, 4)
    # written with 17 significant digits: equal to ~1e-15; 1e-9 relative of the largest
    scale = np.abs(r.pedestal).max()
    assert np.abs(t.pedestal[:, 0, :] - r.pedestal).max() <= 1e-9 * scale
    np.testing.assert_allclose(t.pedestal[:, 0, :], r.pedestal, rtol=1e-9)
    np.testing.assert_allclose(t.order(1), r.q, rtol=1e-9)
    assert np.isnan(t.pedestal_cov).all() and np.isnan(t.pedestal_cross).all()
    info = t.meta["table"]
    assert info["accel_unit"] == accel_unit and set(info["columns"]) == set(FILE_ORDER)


def test_acceleration_to_displacement_sign_and_scale(tmp_path):
    # one g 0-pk with lead 0 at 3000 rpm: a(t) = g cos(Ωt) = -Ω² x(t), x = -g/Ω² cos(Ωt)
    om = 3000.0 * RPM
    one = ["1.0", "0.0"] * 4
    acc = [["1.0", "0.0"], ["2.0", "90.0"], ["0.5", "-90.0"], ["1.0", "180.0"]]   # px1, py1, px2, py2 (file order)
    rows = [[s] + one + [c for pair in acc for c in pair] for s in ("3000", "3600")]
    t = tb.load_1x_table(write(tmp_path / "one.csv", rows), columns=PLAIN, amplitude="0-pk", phase="lead")
    # P = -A/Ω²: px1 1∠0 -> -1, px2 0.5∠-90 = -0.5j -> +0.5j, py1 2∠90 = 2j -> -2j, py2 1∠180 -> +1
    want = np.array([-1.0, 0.5j, -2.0j, 1.0]) * G / om ** 2                     # [xp1, xp2, yp1, yp2]
    np.testing.assert_allclose(t.pedestal[0, 0], want, rtol=1e-14, atol=1e-20)
    np.testing.assert_allclose(t.pedestal[1, 0], want * (3000 / 3600) ** 2, rtol=1e-14, atol=1e-20)
    # the lag convention flips every phase: 90 deg lag is -90 deg lead
    t = tb.load_1x_table(write(tmp_path / "one.csv", rows), columns=PLAIN, amplitude="0-pk", phase="lag")
    np.testing.assert_allclose(t.pedestal[0, 0], np.conj(want), rtol=1e-14, atol=1e-20)


def test_header_units_and_conventions_agreeing_pass(tmp_path):
    r = response()
    cols = {ch: {"amplitude": f"{ch} Amp (mil pp)", "phase": f"{ch} Phase (deg lag)"} for ch in Q_ORDER}
    cols.update({ch: {"amplitude": f"{ch} Accel [m/s^2 0-pk]", "phase": f"{ch} Phase (deg lag)"}
                 for ch in ACCELEROMETERS})
    rows = cells_of(SPEEDS, r.q, r.pedestal, accel_si=1.0, accel_pk=1.0)
    p = write(tmp_path / "h.csv", rows, cols=cols, speed="Speed (rpm)", sep=";")
    t = tb.load_1x_table(p, columns=cols, accel_unit="m/s^2", accel_amplitude="0-pk")
    np.testing.assert_allclose(t.pedestal[:, 0], r.pedestal, rtol=1e-9)
    # "m/s2" and "g" in brackets are acceleration units, not metres
    for head, unit, si in (("[m/s2 0-pk]", "m/s2", 1.0), ("(g pk)", "g", G), ("(m/s² peak)", "m/s^2", 1.0)):
        c2 = {**cols, **{ch: {"amplitude": f"{ch} Accel {head}", "phase": cols[ch]["phase"]} for ch in ACCELEROMETERS}}
        p = write(tmp_path / "h2.csv", cells_of(SPEEDS, r.q, r.pedestal, accel_si=si, accel_pk=1.0), cols=c2,
                  speed="Speed (rpm)")
        t = tb.load_1x_table(p, columns=c2, accel_unit=unit, accel_amplitude="0-pk")
        np.testing.assert_allclose(t.pedestal[:, 0], r.pedestal, rtol=1e-9)


def test_without_accelerometers_nothing_changes(tmp_path):
    r = response()
    rows = [row[:9] for row in cells_of(SPEEDS, r.q, r.pedestal)]
    probes = {ch: PLAIN[ch] for ch in Q_ORDER}
    t = tb.load_1x_table(write(tmp_path / "p.csv", rows, cols=probes, order=FILE_ORDER[:4]), columns=probes,
                         accel_unit="m/s^2", accel_amplitude="0-pk")
    assert not t.has_pedestal and t.pedestal is None and t.pedestal_cov is None
    assert "accel_unit" not in t.meta["table"]
    np.testing.assert_allclose(t.order(1), r.q, rtol=1e-9)
    # accelerometer columns in the file but not mapped: ignored, as any other column
    t = tb.load_1x_table(write(tmp_path / "all.csv", cells_of(SPEEDS, r.q, r.pedestal)), columns=probes)
    assert not t.has_pedestal


# ---------------------------------------------------------------------------------------------
# writing: the accelerometer columns round-trip


@pytest.mark.parametrize("kw", [dict(),
                                dict(unit="um", amplitude="0-pk", phase="lead", accel_unit="m/s^2"),
                                dict(accel_unit="m/s2", accel_amplitude="0-pk"),
                                dict(amplitude="0-pk", accel_amplitude="pk-pk", phase="lead")])
def test_save_round_trip_to_printed_resolution(tmp_path, kw):
    rng = np.random.default_rng(5)
    sp = SPEEDS + rng.uniform(-0.5, 0.5, SPEEDS.size)
    r = response(sp)
    t = table_track(sp, r.q, r.pedestal)
    p = tmp_path / "rt.csv"
    cols = tb.save_1x_table(t, p, **kw)
    assert set(cols) == set(FILE_ORDER)
    unit = kw.get("accel_unit", "g")
    apk = 1.0 if kw.get("accel_amplitude", kw.get("amplitude", "pk-pk")) == "0-pk" else 2.0
    assert f"DE HSG X 1X Amp ({unit} {'pp' if apk == 2 else '0-pk'})" in p.read_text()
    back = tb.load_1x_table(p, columns=cols, **kw)
    assert back.has_pedestal
    step = {"g": 1e-5 * G, "m/s^2": 1e-4, "m/s2": 1e-4}[unit] / apk        # printed resolution, m/s² 0-pk
    om_b = back.speed_rpm * RPM
    # amplitude: half a printed step (divided by Ω²) plus the speed printed to 0.1 rpm (Ω² relative)
    da = np.abs(np.abs(back.pedestal[:, 0]) - np.abs(r.pedestal))
    bound = step / 2 / om_b[:, None] ** 2 + np.abs(r.pedestal) * 2 * 0.05 / sp[:, None] * 1.01
    assert np.all(da <= bound * (1 + 1e-6) + 1e-18)
    assert np.abs(np.angle(back.pedestal[:, 0] / r.pedestal, deg=True)).max() <= 0.05 + 1e-6
    assert np.abs(back.pedestal[:, 0] - r.pedestal).max() <= 0.02 * np.abs(r.pedestal).max()
    # what was printed reads back exactly: saving it again writes the same rows
    p2 = tmp_path / "rt2.csv"
    tb.save_1x_table(back, p2, **kw)
    assert p.read_text().splitlines()[-13:] == p2.read_text().splitlines()[-13:]


def test_save_without_pedestal_unchanged_and_bad_accel_unit(tmp_path):
    r = response()
    plain = tb.TableTrack(SPEEDS, r.q[:, None, :], (1,), np.full(13, np.nan), np.full((13, 4), np.nan),
                          np.full(13, np.nan), name="run")
    cols = tb.save_1x_table(plain, tmp_path / "a.csv")
    assert cols == tb.EXAMPLE_COLUMNS and "HSG" not in (tmp_path / "a.csv").read_text()
    raises(["accel_unit", "length", "px1"], tb.save_1x_table, table_track(SPEEDS, r.q, r.pedestal), tmp_path / "b.csv",
           accel_unit="mil")


# ---------------------------------------------------------------------------------------------
# bad input


def good_file(tmp_path, cols=PLAIN, name="t.csv", edit=None, accel_si=G):
    r = response()
    rows = cells_of(SPEEDS[:4], r.q[:4], r.pedestal[:4], accel_si=accel_si)
    if edit is not None:
        edit(rows)
    return write(tmp_path / name, rows, cols=cols)


def test_partial_accelerometer_set_raises(tmp_path):
    p = good_file(tmp_path)
    no_py2 = {k: v for k, v in PLAIN.items() if k != "py2"}
    raises(["px1", "but not ['py2']", "all four"], tb.load_1x_table, p, columns=no_py2)
    two = {k: v for k, v in PLAIN.items() if k not in ("px2", "py1")}
    raises(["['px2', 'py1']", "all four"], tb.load_1x_table, p, columns=two)
    raises(["unknown ['pz1']"], tb.load_1x_table, p, columns={**PLAIN, "pz1": {"amplitude": "a", "phase": "b"}})


def test_accelerometer_column_missing_from_the_file(tmp_path):
    r = response()
    rows = [row[:-2] for row in cells_of(SPEEDS[:4], r.q[:4], r.pedestal[:4])]
    p = write(tmp_path / "m.csv", rows, order=FILE_ORDER[:-1])
    raises([str(p), "'A py2'", "'P py2'"], tb.load_1x_table, p, columns=PLAIN)


@pytest.mark.parametrize("ch, head, words", [
    ("px1", "PX1 Amp (mil pp)", ["'PX1 Amp (mil pp)'", "px1", "length unit 'mil'", "acceleration"]),
    ("py2", "PY2 Amp [um]", ["'PY2 Amp [um]'", "py2", "length unit 'um'"]),
    ("px2", "PX2 Amp (mm/s pk)", ["'PX2 Amp (mm/s pk)'", "px2", "velocity unit 'mm/s'"]),
    ("py1", "PY1 Amp (in/s^2 pk)", ["'PY1 Amp (in/s^2 pk)'", "py1", "'in/s^2'", "does not convert"]),
    ("x1", "X1 Amp (g pp)", ["'X1 Amp (g pp)'", "x1", "acceleration unit 'g'", "probe"]),
    ("y2", "Y2 Amp (m/s^2)", ["'Y2 Amp (m/s^2)'", "y2", "acceleration unit 'm/s^2'"]),
])
def test_wrong_unit_on_a_column_raises_naming_column_and_channel(tmp_path, ch, head, words):
    cols = {**PLAIN, ch: {"amplitude": head, "phase": PLAIN[ch]["phase"]}}
    p = good_file(tmp_path, cols=cols)
    raises([str(p)] + words, tb.load_1x_table, p, columns=cols)


def test_header_contradicting_accel_arguments(tmp_path):
    cols = {**PLAIN, **{ch: {"amplitude": f"{ch} Amp (g 0-pk)", "phase": f"{ch} Phase (deg lag)"}
                        for ch in ACCELEROMETERS}}
    p = good_file(tmp_path, cols=cols)
    raises(["'px1 Amp (g 0-pk)'", "px1", "accel_unit='m/s^2'", "accel_unit='g'"], tb.load_1x_table, p, columns=cols,
           accel_unit="m/s^2", accel_amplitude="0-pk")
    raises(["'px1 Amp (g 0-pk)'", "factor 2", "accel_amplitude='0-pk'"], tb.load_1x_table, p, columns=cols)
    raises(["'px1 Phase (deg lag)'", "phase='lag'"], tb.load_1x_table, p, columns=cols, accel_amplitude="0-pk",
           phase="lead")
    rms = {**PLAIN, "px2": {"amplitude": "px2 Amp (g rms)", "phase": "P px2"}}
    raises(["'px2 Amp (g rms)'", "rms"], tb.load_1x_table, good_file(tmp_path, cols=rms, name="r.csv"), columns=rms)


def test_wrong_unit_arguments(tmp_path):
    p = good_file(tmp_path)
    raises(["accel_unit='mil'", "length", "px1, px2, py1, py2", "unit="], tb.load_1x_table, p, columns=PLAIN,
           accel_unit="mil")
    raises(["unit='g'", "acceleration", "x1, x2, y1, y2", "accel_unit="], tb.load_1x_table, p, columns=PLAIN,
           unit="g")
    raises(["accel_unit", "lbf"], tb.load_1x_table, p, columns=PLAIN, accel_unit="lbf")
    raises(["accel_amplitude must be"], tb.load_1x_table, p, columns=PLAIN, accel_amplitude="rms")


@pytest.mark.parametrize("cell", ["NaN", "nan", ""])
def test_nan_or_blank_accelerometer_cells_raise(tmp_path, cell):
    # as for the probes: nothing is dropped silently (row 3 of the file is data row 2)
    def edit(rows):
        rows[1][FILE_ORDER.index("py1") * 2 + 1] = cell          # py1 amplitude
        rows[2][FILE_ORDER.index("px2") * 2 + 2] = cell          # px2 phase
    p = good_file(tmp_path, edit=edit)
    raises([str(p), "rows 3, 4", "'A py1'", "'P px2'", "blank"], tb.load_1x_table, p, columns=PLAIN)


def test_bad_accelerometer_values(tmp_path):
    def neg(rows):
        rows[0][FILE_ORDER.index("px1") * 2 + 1] = "-0.01"
    p = good_file(tmp_path, edit=neg)
    raises([str(p), "'A px1'", "px1 amplitude", "negative", "row 2"], tb.load_1x_table, p, columns=PLAIN)

    def wrap(rows):
        rows[3][FILE_ORDER.index("py2") * 2 + 2] = "400.0"
    p = good_file(tmp_path, edit=wrap, name="w.csv")
    raises([str(p), "'P py2'", "±360", "row 5"], tb.load_1x_table, p, columns=PLAIN)

    def text(rows):
        rows[1][FILE_ORDER.index("px2") * 2 + 1] = "ovl"
    p = good_file(tmp_path, edit=text, name="o.csv")
    raises([str(p), "'A px2'", "non-numeric", "'ovl'"], tb.load_1x_table, p, columns=PLAIN)


# ---------------------------------------------------------------------------------------------
# covariance from the DAQ's stated accuracy


def test_pedestal_covariance_from_stated_accuracy(tmp_path):
    r = response()
    p = write(tmp_path / "c.csv", cells_of(SPEEDS, r.q, r.pedestal))
    t = tb.load_1x_table(p, columns=PLAIN, amplitude_std=0.002, phase_std_deg=0.5, accel_amplitude_std=0.001)
    om = SPEEDS * RPM
    a = -(om ** 2)[:, None] * r.pedestal
    want = tb.polar_covariance(a, 0.001 * G / 2, np.deg2rad(0.5)) / (om ** 4)[:, None, None]
    np.testing.assert_allclose(t.pedestal_cov, want, rtol=1e-9, atol=0)
    np.testing.assert_array_equal(t.pedestal_cross, 0.0)
    np.testing.assert_allclose(t.cov, tb.polar_covariance(r.q, 0.002 * MIL / 2, np.deg2rad(0.5)), rtol=1e-9)
    # along the vector: the amplitude's variance (0.0005 g 0-pk)² / Ω⁴
    j, k = 0, 5
    u = r.pedestal[k, j] / abs(r.pedestal[k, j])
    e = np.array([u.real, u.imag])
    c = t.pedestal_cov[k][np.ix_([j, j + 4], [j, j + 4])]
    assert e @ c @ e == pytest.approx((0.0005 * G) ** 2 / om[k] ** 4, rel=1e-9)
    raises(["accel_amplitude_std", "px1, px2, py1, py2"], tb.load_1x_table, p, columns=PLAIN, amplitude_std=0.002)
    probes = {ch: PLAIN[ch] for ch in Q_ORDER}
    raises(["accel_amplitude_std", "no housing accelerometer"], tb.load_1x_table, p, columns=probes,
           amplitude_std=0.002, accel_amplitude_std=0.001)


# ---------------------------------------------------------------------------------------------
# compensation, common speed grid, identification


def test_minus_carries_pedestal(tmp_path):
    r = response()
    t = table_track(SPEEDS, r.q, r.pedestal, "run")
    base = table_track(SPEEDS + 0.2, 0.5 * r.q, 0.25 * r.pedestal, "base")
    comp = t.minus(base)
    assert isinstance(comp, tb.TableTrack) and comp.has_pedestal and comp.name == "run"
    np.testing.assert_allclose(comp.pedestal[:, 0], r.pedestal - base.pedestal_at_speeds(SPEEDS)[:, 0], rtol=1e-12)
    # a slow-roll run-out vector is the probes' own: the housings' motion keeps its value
    sr = tb.slow_roll_vector(t)
    assert sr.shape == (1, 4)
    comp = t.minus(sr)
    np.testing.assert_array_equal(comp.pedestal, t.pedestal)
    np.testing.assert_allclose(comp.order(1), r.q - sr, rtol=1e-12)
    plain = tb.TableTrack(SPEEDS, r.q[:, None, :], (1,), np.full(13, np.nan), np.full((13, 4), np.nan),
                          np.full(13, np.nan))
    raises(["pedestal"], t.minus, plain)


def test_match_speeds_with_pedestal():
    r = response()
    a = table_track(SPEEDS, r.q, r.pedestal, "A")
    b = table_track(SPEEDS + 0.3, r.q, 2 * r.pedestal, "B")
    grid, qs, ps = tb.match_speeds([a, b], pedestal=True)
    np.testing.assert_array_equal(grid, SPEEDS)
    np.testing.assert_allclose(ps[0], r.pedestal, rtol=1e-12)
    # inside b's range: its pedestal interpolated as the vectors are (the first grid speed, 0.3 rpm
    # below b's first, extends b's end segment, within the tolerance)
    np.testing.assert_allclose(ps[1][1:], b.pedestal_at_speeds(SPEEDS[1:])[:, 0], rtol=1e-12)
    same = table_track(SPEEDS + 0.3, 2 * r.pedestal, 2 * r.pedestal, "same")
    _, (_, qv), (_, pv) = tb.match_speeds([a, same], pedestal=True)
    np.testing.assert_array_equal(pv, qv)                            # the same interpolation, the ends too
    assert len(tb.match_speeds([a, b])) == 2                          # default: as before
    plain = tb.TableTrack(SPEEDS, r.q[:, None, :], (1,), np.full(13, np.nan), np.full((13, 4), np.nan),
                          np.full(13, np.nan), name="C")
    raises(["pedestal=True", "['C']"], tb.match_speeds, [a, plain], pedestal=True)
    raises(["pedestal must be True or False"], tb.match_speeds, [a, b], pedestal="yes")


def test_tables_with_accelerometers_identify_the_bearings(tmp_path):
    rotor, truth, remnant = rig()
    ped = rotorid.example_pedestals()
    imbs = {k: rotorid.Imbalance(tuple(m * 1e-3 for m in mass), ang, name=k) for k, (mass, ang) in ex.SETS.items()}
    rng = np.random.default_rng(9)
    tracks = {}
    for k, imb in imbs.items():
        sp = SPEEDS + rng.uniform(-0.3, 0.3, SPEEDS.size)
        r = rotorid.imbalance_response(rotor, truth, imb, speed_rpm=sp, at="probes", pedestals=ped)
        p = write(tmp_path / f"{k}.csv", cells_of(sp, r.q, r.pedestal, accel_si=1.0, accel_pk=1.0))
        tracks[k] = tb.load_1x_table(p, columns=PLAIN, accel_unit="m/s^2", accel_amplitude="0-pk")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        grid, qs, ps = tb.match_speeds(tracks, pedestal=True)
    resp = [rotorid.SyncResponse(grid, q, imbalance=imbs[k], at="probes", pedestal=p)
            for k, q, p in zip(tracks, qs, ps)]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ident = rotorid.identify_synchronous(rotor, resp)
    sel = ident.ok
    assert sel.sum() >= 8
    ek = np.abs(ident.k[sel] - truth.k) / np.abs(truth.k)
    dk = max(ek[:, b, i, i].max() for b in range(2) for i in range(2))
    # exact tables, only the ±0.3 rpm speed offsets interpolated away: well under 1 %
    assert dk < 0.01, dk


def test_housing_accelerometers_mounted_at_angles(tmp_path):
    """Accelerometers at 45° and 135° on housing 1 (probes x and y): with ``angle_deg`` in their
    ``columns`` entries the housing's x and y displacement comes back (full-precision cells), and
    the stated accuracy's pedestal covariance is the readings' moved to x and y."""
    r = response()
    c, s = np.cos(np.radians(45.0)), np.sin(np.radians(45.0))
    p_read = r.pedestal.copy()                                  # [xp1, xp2, yp1, yp2]
    p_read[:, 0] = c * r.pedestal[:, 0] + s * r.pedestal[:, 2]
    p_read[:, 2] = -c * r.pedestal[:, 0] + s * r.pedestal[:, 2]
    path = write(tmp_path / "acc.csv", cells_of(SPEEDS, r.q, p_read))
    cols = {**PLAIN, "px1": {**PLAIN["px1"], "angle_deg": 45.0}, "py1": {**PLAIN["py1"], "angle_deg": 135}}
    got = tb.load_1x_table(path, columns=cols, amplitude_std=0.01, phase_std_deg=0.5, accel_amplitude_std=1e-4)
    np.testing.assert_allclose(got.pedestal[:, 0], r.pedestal, rtol=0, atol=1e-12 * np.abs(r.pedestal).max())
    np.testing.assert_allclose(got.order(1), r.q, rtol=0, atol=1e-12 * np.abs(r.q).max())
    plain = tb.load_1x_table(path, columns=PLAIN, amplitude_std=0.01, phase_std_deg=0.5, accel_amplitude_std=1e-4)
    t = np.eye(4)
    t[np.ix_([0, 2], [0, 2])] = np.linalg.inv(np.array([[c, s], [-c, s]]))
    t8 = np.kron(np.eye(2), t)
    np.testing.assert_allclose(got.pedestal_cov, t8 @ plain.pedestal_cov @ t8.T, rtol=1e-9,
                               atol=1e-12 * np.abs(plain.pedestal_cov).max())
    np.testing.assert_array_equal(got.cov, plain.cov)
