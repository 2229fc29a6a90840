"""Lab-file I/O: native .npz, CSV, TDMS and UFF 58 round trips, channel maps, units and bad input."""

import ast
import re
import warnings

import numpy as np
import pytest
from nptdms import ChannelObject, TdmsWriter

from rotorid import io as rio
from rotorid.errors import RotoridError
from rotorid.recording import Recording

FS = 2000.0
N = 2000
MIL = 25.4e-6
LBF = 4.4482216152605

LAB_NAMES = {"x1": "Prox DE X", "x2": "Prox FE X", "y1": "Prox DE Y", "y2": "Prox FE Y", "force": "Hammer"}
LAB_UNITS = {"x1": "mil", "x2": "mil", "y1": "mil", "y2": "mil", "force": "lbf"}
LAB_MAP = {LAB_NAMES[c]: {"to": c, "unit": LAB_UNITS[c]} for c in LAB_NAMES}

WRITERS = {"csv": (rio.save_csv, ".csv"), "tdms": (rio.save_tdms, ".tdms"), "uff58": (rio.save_uff58, ".uff")}
# data precision of each lab format: CSV (17 digits) and TDMS (float64) are exact, UFF ASCII has 12 digits
RTOL = {"csv": 0.0, "tdms": 0.0, "uff58": 1e-9}


def make_rec(fs=FS, n=N, t0=0.0, extra=None, meta=None):
    """x1..y2 orbits in m with noise, a once-per-rev keyphasor in V, one hammer impact in N."""
    rng = np.random.default_rng(7)
    t = t0 + np.arange(n) / fs
    ch = {}
    for i, c in enumerate(["x1", "x2", "y1", "y2"]):
        ch[c] = 40e-6 * np.sin(2 * np.pi * 30 * t + i) + 3e-6 + 2e-7 * rng.standard_normal(n)
    ch["kp"] = np.where(np.arange(n) % 67 < 3, 5.0, 0.0)
    force = np.zeros(n)
    force[400:408] = 300.0 * np.sin(np.pi * np.arange(1, 9) / 9)
    ch["force"] = force
    ch.update(extra or {})
    return Recording(fs, ch, dict(meta or {}), t0_s=t0, source="test rig")


def quiet_load(path, **kw):
    """load_recording with every warning turned into an error."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        return rio.load_recording(path, **kw)


def assert_channels(got, want, rtol, names=None):
    names = list(want.channels) if names is None else names
    assert list(got.channels) == names
    for c in names:
        np.testing.assert_allclose(got.channels[c], want.channels[c], rtol=rtol, atol=0, err_msg=c)


def dropped_list(message):
    """The list of dropped channels a drop warning gives."""
    m = re.search(r"named canonically: (\[.*?\])", message)
    assert m, message
    return ast.literal_eval(m.group(1))


# ----------------------------------------------------------------------------------------- native


def test_native_round_trip_is_exact(tmp_path):
    meta = {"kind": "imbalance", "speed_rpm": 1800.0, "imbalance": {"mass_kg": [1e-3, 0.0], "angle_deg": [0, 90]},
            "rig": "NSF", "count": np.int64(3)}
    rec = make_rec(t0=0.125, extra={"temp": np.linspace(20, 21, N)}, meta=meta)
    rec.units["temp"] = "degC"
    path = tmp_path / "run.npz"
    rio.save_recording(rec, path)
    got = quiet_load(path)
    assert got.fs_hz == rec.fs_hz and got.t0_s == rec.t0_s
    assert list(got.channels) == list(rec.channels)
    for c in rec.channels:
        np.testing.assert_array_equal(got.channels[c], rec.channels[c])
    assert got.meta == {**meta, "count": 3}
    assert got.units == rec.units
    assert got.source == "test rig"

    with np.load(path, allow_pickle=False) as z:
        assert str(z["format"]) == "rotorid-recording" and int(z["format_version"]) == 1
        assert z["ch_x1"].dtype == np.float64 and float(z["fs_hz"]) == FS


def test_native_keeps_path_without_extension_and_merges_meta(tmp_path):
    rec = make_rec(meta={"kind": "baseline", "rig": "A"})
    path = tmp_path / "run.bin"
    rio.save_recording(rec, path)
    assert path.is_file() and not (tmp_path / "run.bin.npz").exists()
    got = quiet_load(path, fmt="native", meta={"rig": "B", "speed_rpm": 900.0})
    assert got.meta == {"kind": "baseline", "rig": "B", "speed_rpm": 900.0}


@pytest.mark.parametrize("entries, match", [
    ({"format": "something-else", "format_version": 1}, "format is 'something-else'"),
    ({"format": "rotorid-recording", "format_version": 2}, "format_version .* not supported"),
    ({"format_version": 1}, "no 'format' entry"),
])
def test_native_refuses_other_formats_and_versions(tmp_path, entries, match):
    path = tmp_path / "run.npz"
    base = dict(fs_hz=FS, t0_s=0.0, meta_json="{}", units_json="{}", source='""', ch_x1=np.zeros(10))
    np.savez(path, **base, **entries)
    with pytest.raises(RotoridError, match=match):
        rio.load_recording(path)


def test_native_refuses_meta_that_is_not_json(tmp_path):
    rec = make_rec(meta={"when": object()})
    with pytest.raises(RotoridError, match="not JSON"):
        rio.save_recording(rec, tmp_path / "run.npz")


# -------------------------------------------------------------------------------- lab round trips


@pytest.mark.parametrize("fmt", list(WRITERS))
def test_lab_round_trip_in_si(tmp_path, fmt):
    save, ext = WRITERS[fmt]
    rec = make_rec(t0=0.5)
    path = tmp_path / f"run{ext}"
    save(rec, path)
    got = quiet_load(path)
    assert_channels(got, rec, RTOL[fmt])
    assert got.fs_hz == pytest.approx(FS, rel=1e-12)
    assert got.t0_s == pytest.approx(0.5, rel=1e-9)
    assert got.units["x1"] == "m" and got.units["force"] == "N"
    assert got.meta["source_format"] == fmt
    assert got.meta["channel_sources"]["x1"]["unit_from"] == "file"


@pytest.mark.parametrize("fmt", list(WRITERS))
def test_lab_units_and_names_through_channel_map(tmp_path, fmt):
    save, ext = WRITERS[fmt]
    rec = make_rec()
    path = tmp_path / f"lab{ext}"
    save(rec, path, names=LAB_NAMES, units=LAB_UNITS)
    # the file really holds mils and lbf under the lab names
    with pytest.warns(UserWarning, match="dropped 3 channel"):
        raw = rio.load_recording(path, channel_map={"Prox DE X": {"to": "x1", "unit": "um", "override_file_unit": True},
                                                    "Hammer": {"to": "force", "unit": "N", "override_file_unit": True}})
    np.testing.assert_allclose(raw.channels["x1"], rec.channels["x1"] / MIL * 1e-6, rtol=1e-9)
    np.testing.assert_allclose(raw.channels["force"], rec.channels["force"] / LBF, rtol=1e-9)

    got = quiet_load(path, channel_map=LAB_MAP)
    assert_channels(got, rec, 1e-9)
    assert got.units == {"x1": "m", "x2": "m", "y1": "m", "y2": "m", "kp": "V", "force": "N"}
    assert got.meta["channel_sources"]["x2"] == {"file_channel": "rotorid/Prox FE X" if fmt == "tdms" else "Prox FE X",
                                                 "unit": "mil", "unit_from": "channel_map", "scale": 1.0,
                                                 "offset": 0.0}


def test_tdms_float32_storage(tmp_path):
    rec = make_rec()
    path = tmp_path / "daq.tdms"
    rio.save_tdms(rec, path, group="DAQ", names=LAB_NAMES, units=LAB_UNITS, dtype="float32")
    with pytest.raises(RotoridError, match="dtype must be"):
        rio.save_tdms(rec, path, dtype="int16")
    got = quiet_load(path, channel_map={f"DAQ/{k}": v for k, v in LAB_MAP.items()})
    assert_channels(got, rec, 1e-6)
    assert got.channels["x1"].dtype == np.float64
    # float32 really was stored: the values are not the float64 ones
    assert not np.array_equal(got.channels["x1"], rec.channels["x1"])


@pytest.mark.parametrize("fmt", list(WRITERS))
def test_units_stated_in_the_file_are_applied_without_a_map(tmp_path, fmt):
    save, ext = WRITERS[fmt]
    rec = make_rec()
    path = tmp_path / f"lab{ext}"
    save(rec, path, units={"x1": "um", "y2": "mil", "force": "kN"})
    got = quiet_load(path)
    assert_channels(got, rec, 1e-9)
    assert got.meta["channel_sources"]["y2"]["unit"] == "mil"


def test_scale_and_offset_of_a_sensor(tmp_path):
    rec = make_rec()
    x_mil = rec.channels["x1"] / MIL
    volts = (x_mil + 1.0) / 5.0                       # probe: 200 mV/mil around a 0.2 V gap voltage
    hammer_mv = rec.channels["force"] / LBF / 0.01    # hammer: 10 mV/lbf
    path = tmp_path / "daq.csv"
    with open(path, "w") as fh:
        fh.write("time [s],Prox [V],Hammer [mV]\n")
        np.savetxt(fh, np.column_stack([rec.t, volts, hammer_mv]), fmt="%.17g", delimiter=",")
    cmap = {"Prox": {"to": "x1", "unit": "mil", "scale": 5.0, "offset": -1.0},
            "Hammer": {"to": "force", "unit": "lbf", "scale": 0.01}}
    got = quiet_load(path, channel_map=cmap)
    np.testing.assert_allclose(got.channels["x1"], rec.channels["x1"], rtol=1e-9, atol=1e-20)
    np.testing.assert_allclose(got.channels["force"], rec.channels["force"], rtol=1e-9)


# ------------------------------------------------------------------------------ channel selection


@pytest.mark.parametrize("fmt", list(WRITERS))
def test_dropped_channels_are_listed_in_a_warning(tmp_path, fmt):
    save, ext = WRITERS[fmt]
    rec = make_rec(extra={"Temp": np.full(N, 21.5), "Tacho 2": np.zeros(N)})
    path = tmp_path / f"extra{ext}"
    save(rec, path)
    with pytest.warns(UserWarning, match="dropped 2 channel") as record:
        got = rio.load_recording(path)
    prefix = "rotorid/" if fmt == "tdms" else ""
    messages = [str(w.message) for w in record if "dropped" in str(w.message)]
    assert len(messages) == 1
    assert dropped_list(messages[0]) == [prefix + "Temp", prefix + "Tacho 2"]
    assert list(got.channels) == ["x1", "x2", "y1", "y2", "kp", "force"]


def test_a_mapped_channel_shadows_a_canonical_one(tmp_path):
    rec = make_rec(extra={"Prox": np.zeros(N)})
    path = tmp_path / "run.csv"
    rio.save_csv(rec, path, units={"Prox": ""})
    with pytest.warns(UserWarning, match=r"because channel_map maps another channel onto that name: \['x1'\]"):
        got = rio.load_recording(path, channel_map={"Prox": {"to": "x1", "unit": "m"}})
    np.testing.assert_array_equal(got.channels["x1"], 0.0)


@pytest.mark.parametrize("fmt", list(WRITERS))
def test_missing_mapped_channel_names_it_and_what_the_file_has(tmp_path, fmt):
    save, ext = WRITERS[fmt]
    path = tmp_path / f"lab{ext}"
    save(make_rec(), path, names=LAB_NAMES, units=LAB_UNITS)
    cmap = dict(LAB_MAP, **{"Prox NDE X": {"to": "x2", "unit": "mil"}})
    del cmap["Prox FE X"]
    with pytest.raises(RotoridError, match=r"'Prox NDE X' named in channel_map is not in .*Prox FE X"):
        rio.load_recording(path, channel_map=cmap)


def test_wrong_quantity_units_raise(tmp_path):
    path = tmp_path / "lab.csv"
    rio.save_csv(make_rec(), path, names=LAB_NAMES, units=LAB_UNITS)
    bad = dict(LAB_MAP, **{"Prox DE X": {"to": "x1", "unit": "lbf"}})
    with pytest.raises(RotoridError, match=r"Prox DE X.*'lbf' is a force, expected a length.*x1"):
        rio.load_recording(path, channel_map=bad)
    # a wrong unit stated by the file itself
    path2 = tmp_path / "wrong.csv"
    path2.write_text("time [s],x1 [lbf]\n0,1\n0.001,2\n")
    with pytest.raises(RotoridError, match=r"channel 'x1'.*'lbf' is a force, expected a length"):
        rio.load_recording(path2)


@pytest.mark.parametrize("cmap, match", [
    ({"Prox DE X": {"to": "x3", "unit": "mil"}}, r"'to' must be one of"),
    ({"Prox DE X": {"to": "x1", "unit": "mil", "scal": 2.0}}, r"unknown key\(s\) \['scal'\]"),
    ({"Prox DE X": {"to": "x1"}, "Prox FE X": {"to": "x1"}}, r"maps both 'Prox DE X' and 'Prox FE X' to 'x1'"),
    ({"Prox DE X": {"to": "x1", "scale": float("nan")}}, r"'scale' must be a finite number"),
    ({"Prox DE X": "x1"}, r"must be a dict"),
])
def test_channel_map_is_checked(tmp_path, cmap, match):
    path = tmp_path / "lab.csv"
    rio.save_csv(make_rec(), path, names=LAB_NAMES, units=LAB_UNITS)
    with pytest.raises(RotoridError, match=match):
        rio.load_recording(path, channel_map=cmap)


def test_non_numeric_column_is_fine_unless_used(tmp_path):
    path = tmp_path / "notes.csv"
    path.write_text("time,x1,note\n0,1e-6,ok\n0.0005,2e-6,bump\n0.001,3e-6,ok\n")
    with pytest.warns(UserWarning, match=r"\['note'\]"):
        got = rio.load_recording(path)
    assert got.fs_hz == pytest.approx(2000.0) and list(got.channels) == ["x1"]
    with pytest.raises(RotoridError, match=r"'note'.*cell 'ok' on line 2 is not a number"):
        rio.load_recording(path, channel_map={"note": {"to": "kp", "unit": "V"}})


# ------------------------------------------------------------------------------- time base: CSV


def test_csv_non_uniform_time_column_raises(tmp_path):
    path = tmp_path / "run.csv"
    rio.save_csv(make_rec(), path)
    lines = path.read_text().splitlines()
    cells = lines[501].split(",")
    cells[0] = repr(float(cells[0]) + 5e-5)  # sample 500 late by 10 % of a step (a clock jump)
    lines[501] = ",".join(cells)
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(RotoridError, match="non-uniform time column.*sample 500"):
        rio.load_recording(path)


def test_csv_time_column_rounded_as_daqs_print_it(tmp_path):
    # times printed to 9 significant digits (and in ms with 6 decimals) deviate from the grid by up to
    # 0.3 % of a step: rounding, not a non-uniform axis
    rec = make_rec()
    for fmt, unit, scale in (("%.9g", "s", 1.0), ("%.6f", "ms", 1e3)):
        path = tmp_path / f"rounded_{unit}.csv"
        t = 12.3456 + np.arange(rec.n_samples) / rec.fs_hz
        body = "\n".join(f"{fmt % (ti * scale)},{v:.17g}" for ti, v in zip(t, rec.channels["x1"]))
        path.write_text(f"time [{unit}],x1 [m]\n{body}\n")
        got = rio.load_recording(path)
        assert abs(got.fs_hz / rec.fs_hz - 1) < 1e-6 and abs(got.t0_s - 12.3456) < 1e-6


def test_csv_without_time_column_needs_fs(tmp_path):
    rec = make_rec()
    path = tmp_path / "notime.csv"
    with open(path, "w") as fh:
        fh.write("x1 [mil];y1 [mil]\n")  # semicolon-separated, as some DAQ software writes
        np.savetxt(fh, np.column_stack([rec.channels["x1"], rec.channels["y1"]]) / MIL, fmt="%.17g", delimiter=";")
    with pytest.raises(RotoridError, match=r"no sample rate for channel 'x1'.*pass fs_hz"):
        rio.load_recording(path)
    got = quiet_load(path, fs_hz=FS)
    assert got.fs_hz == FS and got.t0_s == 0.0
    np.testing.assert_allclose(got.channels["y1"], rec.channels["y1"], rtol=1e-9)


def test_fs_hz_does_not_override_the_file(tmp_path):
    path = tmp_path / "run.csv"
    rio.save_csv(make_rec(), path)
    with pytest.warns(UserWarning, match=r"fs_hz=1000 ignored: the file states 2000 Hz"):
        got = rio.load_recording(path, fs_hz=1000.0)
    assert got.fs_hz == pytest.approx(FS, rel=1e-12)


# ------------------------------------------------------------------------------ time base: TDMS


def write_tdms(path, channels):
    """channels: [(group, name, data, properties)]"""
    with TdmsWriter(str(path)) as w:
        w.write_segment([ChannelObject(g, c, np.asarray(d, dtype=np.float64), properties=p) for g, c, d, p in channels])


def test_tdms_sample_rates_disagree(tmp_path):
    path = tmp_path / "rates.tdms"
    x = np.linspace(0, 1e-5, 100)
    write_tdms(path, [("DAQ", "x1", x, {"wf_increment": 1 / 2000}),
                      ("DAQ", "x2", x, {"wf_increment": 1 / 1000}),
                      ("DAQ", "Temp", x[:10], {"wf_increment": 1.0})])
    with pytest.raises(RotoridError, match=r"sample rates disagree: DAQ/x1 2000 Hz, DAQ/x2 1000 Hz"), \
            pytest.warns(UserWarning, match=r"\['DAQ/Temp'\]"):
        rio.load_recording(path)
    # only the channels used must agree: channels that are dropped do not matter
    with pytest.warns(UserWarning, match=r"\['DAQ/Temp'\].*\['DAQ/x1'\]"):
        got = rio.load_recording(path, channel_map={"x2": {"to": "x1", "unit": "m"}})
    assert got.fs_hz == 1000.0 and list(got.channels) == ["x1"]


def test_tdms_channel_addressing(tmp_path):
    path = tmp_path / "groups.tdms"
    rec = make_rec()
    props = {"wf_increment": 1 / FS, "unit_string": "um"}
    chans = [("DE", "X", rec.channels["x1"] / 1e-6, props), ("DE", "Y", rec.channels["y1"] / 1e-6, props),
             ("FE", "X", rec.channels["x2"] / 1e-6, props), ("FE", "Y", rec.channels["y2"] / 1e-6, props),
             ("Impact", "Hammer", rec.channels["force"], {"wf_increment": 1 / FS})]
    write_tdms(path, chans)
    cmap = {"DE/X": {"to": "x1"}, "DE/Y": {"to": "y1"}, "FE/X": {"to": "x2"}, "FE/Y": {"to": "y2"},
            "Hammer": {"to": "force", "unit": "N"}}
    got = quiet_load(path, channel_map=cmap)
    assert_channels(got, rec, 1e-9, names=["x1", "x2", "y1", "y2", "force"])
    assert got.meta["channel_sources"]["x1"]["unit_from"] == "file"
    with pytest.raises(RotoridError, match=r"'X' named in channel_map is ambiguous.*\['DE/X', 'FE/X'\]"):
        rio.load_recording(path, channel_map={"X": {"to": "x1", "unit": "um"}})


def test_tdms_rate_from_fs_hz_only_without_wf_increment(tmp_path):
    path = tmp_path / "norate.tdms"
    write_tdms(path, [("g", "x1", np.zeros(50), {}), ("g", "y1", np.ones(50) * 1e-6, {})])
    with pytest.raises(RotoridError, match=r"states no sample rate for channel 'g/x1': pass fs_hz"):
        rio.load_recording(path)
    assert quiet_load(path, fs_hz=512.0).fs_hz == 512.0


# ------------------------------------------------------------------------------- time base: UFF


def test_uff_whole_hertz_rate_survives_the_e13_abscissa(tmp_path):
    # 1/2048 s is written as 4.88281e-04, i.e. 2048.001 Hz; the reader snaps it back
    rec = make_rec(fs=2048.0)
    path = tmp_path / "run.uff"
    rio.save_uff58(rec, path)
    assert "4.88281e-04" in path.read_text()
    got = quiet_load(path)
    assert got.fs_hz == 2048.0
    assert_channels(got, rec, 1e-9)


def test_uff_sample_rates_disagree(tmp_path):
    a = tmp_path / "a.uff"
    b = tmp_path / "b.uff"
    rio.save_uff58(Recording(2000.0, {"x1": np.zeros(64)}), a)
    rio.save_uff58(Recording(1000.0, {"x2": np.zeros(64)}), b)
    both = tmp_path / "both.unv"
    both.write_text(a.read_text() + b.read_text())
    with pytest.raises(RotoridError, match=r"sample rates disagree: x1 2000 Hz, x2 1000 Hz"):
        rio.load_recording(both)


# ------------------------------------------------------------------------------------ bad files

GARBAGE = bytes(range(256)) * 4 + b"\x00garbage\xff" * 50


@pytest.mark.parametrize("ext", [".npz", ".csv", ".tdms", ".uff", ".unv"])
def test_garbage_file_raises(tmp_path, ext):
    path = tmp_path / f"garbage{ext}"
    path.write_bytes(GARBAGE)
    with pytest.raises(RotoridError, match=r"cannot read .*garbage.* as "):
        rio.load_recording(path, fs_hz=FS)


@pytest.mark.parametrize("fmt", ["native", *WRITERS])
def test_truncated_file_raises(tmp_path, fmt):
    save, ext = (rio.save_recording, ".npz") if fmt == "native" else WRITERS[fmt]
    path = tmp_path / f"cut{ext}"
    save(make_rec(), path)
    data = path.read_bytes()
    path.write_bytes(data[: int(len(data) * 0.6)])
    with pytest.raises(RotoridError, match=r"cannot read .*cut.* as "):
        rio.load_recording(path)


def test_uff_without_time_series_raises(tmp_path):
    path = tmp_path / "empty.uff"
    path.write_text("    -1\n  2411\n    -1\n")
    with pytest.raises(RotoridError, match=r"no type-58"):
        rio.load_recording(path)


def test_format_selection(tmp_path):
    path = tmp_path / "run.dat"
    rio.save_csv(make_rec(), path)
    with pytest.raises(RotoridError, match=r"cannot tell the format .*'\.dat'"):
        rio.load_recording(path)
    assert quiet_load(path, fmt="csv").n_samples == N
    with pytest.raises(RotoridError, match=r"fmt must be one of"):
        rio.load_recording(path, fmt="xlsx")
    with pytest.raises(RotoridError, match=r"no such file"):
        rio.load_recording(tmp_path / "absent.csv")


def test_writers_check_their_arguments(tmp_path):
    rec = make_rec()
    with pytest.raises(RotoridError, match=r"names names channel\(s\) \['x9'\]"):
        rio.save_csv(rec, tmp_path / "a.csv", names={"x9": "Prox"})
    # a table for the lab's whole channel set may name canonical channels this recording lacks
    small = Recording(FS, {"x1": rec.channels["x1"]})
    rio.save_csv(small, tmp_path / "small.csv", names=LAB_NAMES, units=LAB_UNITS)
    assert (tmp_path / "small.csv").read_text().startswith("time [s],Prox DE X [mil]\n")
    (tmp_path / "small.csv").unlink()
    with pytest.raises(RotoridError, match=r"channel 'x1' from 'm' to 'lbf'"):
        rio.save_tdms(rec, tmp_path / "a.tdms", units={"x1": "lbf"})
    with pytest.raises(RotoridError, match=r"two channels would be written as 'Prox'"):
        rio.save_uff58(rec, tmp_path / "a.uff", names={"x1": "Prox", "x2": "Prox"})
    assert not list(tmp_path.iterdir())  # nothing half-written left behind


# -------------------------------------------------------------------------------------- clipping


def test_clipping_is_reported():
    rec = make_rec()
    x = rec.channels["x1"]
    rail = 0.8 * x.max()
    x = np.minimum(x, rail)
    rec = Recording(FS, dict(rec.channels, x1=x))
    first = int(np.flatnonzero(x == rail)[0])
    with pytest.warns(UserWarning, match=rf"'x1' possibly clipped: it sits at its maximum {rail:.6g} m .* from "
                                         rf"sample {first} "):
        found = rio.check_clipping(rec)
    assert [(f["channel"], f["side"], f["first_index"]) for f in found] == [("x1", "maximum", first)]
    assert found[0]["runs"] == 30  # every peak of the 30 Hz orbit over 1 s
    assert found[0]["run_length"] >= 5


def test_clipping_needs_five_samples_at_the_extreme():
    base = np.sin(np.linspace(0, 6 * np.pi, 400))
    four, five = base.copy(), base.copy()
    four[100:104] = 2.0
    five[100:105] = -2.0
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert rio.check_clipping(Recording(FS, {"y2": four, "kp": five})) == []  # kp is not checked
        # a quiet baseline at the minimum (a hammer between impacts) is not a rail
        assert rio.check_clipping(Recording(FS, {"force": np.maximum(base, 0.0)})) == []
    with pytest.warns(UserWarning, match=r"'force' possibly clipped: it sits at its minimum -2 N for 5 .*sample 100"):
        assert len(rio.check_clipping(Recording(FS, {"force": five}))) == 1


def test_load_checks_clipping(tmp_path):
    rec = make_rec()
    f = rec.channels["force"].copy()
    f[402:410] = f[402:410].max()
    path = tmp_path / "clipped.tdms"
    rio.save_tdms(Recording(FS, dict(rec.channels, force=f)), path)
    with pytest.warns(UserWarning, match=r"'force' possibly clipped.*from sample 402"):
        rio.load_recording(path)


@pytest.mark.parametrize("fmt", list(WRITERS))
def test_a_channel_map_unit_that_contradicts_the_file_is_an_error(tmp_path, fmt):
    """The file states mil, the channel map says um (or the other way): the map used to win
    silently, and an independent lab's probes stated in um but mapped as mil came out 25.4 times
    too large, K off by hundreds of percent, every point ok. Same-size synonyms, another quantity
    converted by scale, and an explicit override_file_unit pass."""
    save, ext = WRITERS[fmt]
    rec = make_rec()
    path = tmp_path / f"lab{ext}"
    save(rec, path, names=LAB_NAMES, units=LAB_UNITS)
    # (also for a reversed sensor, scale = -1)
    with pytest.raises(RotoridError, match="is stated in the file as 'mil'"):
        quiet_load(path, channel_map={"Prox DE X": {"to": "x1", "unit": "um", "scale": -1.0}})
    with pytest.raises(RotoridError, match=r"Prox DE X' \(-> x1\) is stated in the file as 'mil', but channel_map gives "
                                           r"unit = 'um'.*override_file_unit = true"):
        quiet_load(path, channel_map={"Prox DE X": {"to": "x1", "unit": "um"}})
    got = quiet_load(path, channel_map={**LAB_MAP, "Prox DE X": {"to": "x1", "unit": "MILS"}})
    assert_channels(got, rec, max(RTOL[fmt], 1e-9))
    # the label is wrong and the user says so: the map's unit is used
    over = quiet_load(path, channel_map={**LAB_MAP, "Prox DE X": {"to": "x1", "unit": "mm", "override_file_unit": True}})
    np.testing.assert_allclose(over.channels["x1"], rec.channels["x1"] / MIL * 1e-3, rtol=1e-9)
    with pytest.raises(RotoridError, match="override_file_unit' needs the 'unit'"):
        quiet_load(path, channel_map={"Prox DE X": {"to": "x1", "override_file_unit": True}})


def test_ni_unit_names_and_probe_values_without_a_unit(tmp_path):
    """NI DAQmx writes unit_string "Volts" (refused as unknown before); a file that states no
    unit for probes holding µm is read as metres, 1e6 times too large: refused, saying how."""
    rec = make_rec()
    path = tmp_path / "ni.tdms"
    with TdmsWriter(path) as w:
        w.write_segment([ChannelObject("Measured Data", "kp", rec.channels["kp"],
                                       properties={"unit_string": "Volts", "wf_increment": 1 / FS}),
                         ChannelObject("Measured Data", "x1", rec.channels["x1"] * 1e6,
                                       properties={"unit_string": "", "wf_increment": 1 / FS})])
    with pytest.raises(RotoridError, match=r"'Measured Data/x1' \(-> x1\) spans 81.1 m peak to peak as read in 'm' "
                                           r"\(unit from assumed SI\).*unit = \"um\""):
        quiet_load(path)
    got = quiet_load(path, channel_map={"x1": {"to": "x1", "unit": "um"}, "kp": {"to": "kp"}})
    np.testing.assert_allclose(got.channels["kp"], rec.channels["kp"])
    np.testing.assert_allclose(got.channels["x1"], rec.channels["x1"], rtol=1e-12)


def test_uff_abscissa_in_milliseconds_and_a_rate_that_e13_5_rounds(tmp_path):
    """A UFF 58 abscissa labelled ms was read as seconds (a sample rate 1000 times too low, the
    keyphasor at 3 rpm instead of 3013); 51.2 kHz, stored as 1.95313e-05 s, was not snapped to
    whole hertz (51199.87 Hz). A label that is no time unit is refused."""
    rec = make_rec(fs=51200.0)
    path = tmp_path / "s.uff"
    rio.save_uff58(rec, path)
    assert quiet_load(path).fs_hz == 51200.0
    text = path.read_text()
    assert "1.95313e-05" in text
    ms = tmp_path / "ms.uff"
    ms.write_text(text.replace("1.95313e-05", "1.95313e-02").replace("Time                 s   ",
                                                                      "Time                 ms  "))
    got = quiet_load(ms)
    assert got.fs_hz == 51200.0
    assert_channels(got, rec, 1e-9)
    # labels as other software writes them (all loaded before the ms conversion; review)
    for label in ("Seconds", "sec.", "[s]", "t"):
        other = tmp_path / "other.uff"
        other.write_text(text.replace("Time                 s   ", "Time                 " + label.ljust(4)))
        assert quiet_load(other).fs_hz == 51200.0, label
    # a label that is no time unit, on a data set whose abscissa is time (type 17): seconds, said
    hz = tmp_path / "hz.uff"
    hz.write_text(text.replace("Time                 s   ", "Time                 Hz  "))
    with pytest.warns(UserWarning, match="abscissa units label 'Hz' is no time unit rotorid knows; its abscissa is "
                                         "time"):
        assert rio.load_recording(hz).fs_hz == 51200.0


def _angled(rec, angles):
    """The probes of ``rec`` as if mounted at ``angles`` {channel: deg from +x toward +y}: each
    reads the plane's motion along its direction."""
    ch = dict(rec.channels)
    for xn, yn in (("x1", "y1"), ("x2", "y2")):
        x, y = rec.channels[xn], rec.channels[yn]
        for name in (xn, yn):
            a = np.radians(angles.get(name, 0.0 if name == xn else 90.0))
            ch[name] = np.cos(a) * x + np.sin(a) * y
    return Recording(rec.fs_hz, ch, dict(rec.meta), t0_s=rec.t0_s, source=rec.source)


@pytest.mark.parametrize("fmt", list(WRITERS))
def test_probes_mounted_at_angles_are_resolved_into_x_and_y(tmp_path, fmt):
    """Probes at 45° either side of vertical (API 670; 45° and 135° from +x) at plane 1 and a
    horizontal probe with one at 60° at plane 2: ``angle_deg`` in the channel map gives back the
    x and y motion of each plane. Before, such probes could only be mapped as if they were x and
    y (the coefficients in a rotated frame, with the imbalance angles off by the rotation)."""
    save, ext = WRITERS[fmt]
    rec = make_rec()
    angles = {"x1": 45.0, "y1": 135.0, "y2": 60.0}
    path = tmp_path / f"angled{ext}"
    save(_angled(rec, angles), path, names=LAB_NAMES, units=LAB_UNITS)
    cmap = {**LAB_MAP}
    for c, a in angles.items():
        cmap[LAB_NAMES[c]] = {**cmap[LAB_NAMES[c]], "angle_deg": a}
    got = quiet_load(path, channel_map=cmap)
    for c in ("x1", "x2", "y1", "y2"):
        np.testing.assert_allclose(got.channels[c], rec.channels[c], rtol=0, atol=1e-15 + RTOL[fmt] * 4e-5, err_msg=c)
    np.testing.assert_array_equal(got.channels["force"], quiet_load(path, channel_map=LAB_MAP).channels["force"])
    src = got.meta["channel_sources"]
    assert (src["x1"]["angle_deg"], src["y1"]["angle_deg"], src["x2"]["angle_deg"], src["y2"]["angle_deg"]) == (
        45.0, 135.0, 0.0, 60.0)
    assert "angle_deg" not in quiet_load(path, channel_map=LAB_MAP).meta["channel_sources"]["x1"]
    # without the angles the same file reads as if the probes were x and y: not the plane's motion
    plain = quiet_load(path, channel_map=LAB_MAP)
    assert np.abs(plain.channels["x1"] - rec.channels["x1"]).max() > 1e-5


def test_angled_probes_that_cannot_be_resolved_are_refused(tmp_path):
    rec = make_rec()
    path = tmp_path / "angled.csv"
    rio.save_csv(rec, path, names=LAB_NAMES, units=LAB_UNITS)

    def load(**changes):
        cmap = {k: dict(v) for k, v in LAB_MAP.items()}
        for lab, extra in changes.items():
            cmap[LAB_NAMES[lab]].update(extra)
        return quiet_load(path, channel_map=cmap)

    with pytest.raises(RotoridError, match=r"Prox DE X' \(-> x1, angle_deg 45\) and 'Prox DE Y' \(-> y1, angle_deg 215\) are within 20° of parallel"):
        load(x1={"angle_deg": 45.0}, y1={"angle_deg": 225.0 - 10.0})
    with pytest.raises(RotoridError, match="have different delay_s"):
        load(x1={"angle_deg": 45.0, "delay_s": 1e-4})
    with pytest.raises(RotoridError, match=r"'angle_deg' must be a finite number, got nan"):
        load(x1={"angle_deg": float("nan")})
    with pytest.raises(RotoridError, match=r"'angle_deg' must be a finite number, got '45'"):
        load(x1={"angle_deg": "45"})
    with pytest.raises(RotoridError, match=r"'angle_deg' is the measuring direction of a probe.*not of 'force'"):
        load(force={"angle_deg": 10.0})
    # a probe at an angle whose partner is missing
    only = {LAB_NAMES["x1"]: {"to": "x1", "unit": "mil", "angle_deg": 45.0}}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with pytest.raises(RotoridError, match=r"has angle_deg = 45, but there is no y1 channel.*map that probe to 'y1'"):
            rio.load_recording(path, channel_map=only)
    # resolved motion beyond any probe's range (a unit or angle mistake)
    big = Recording(rec.fs_hz, {**rec.channels, "x1": rec.channels["x1"] * 100, "y1": -rec.channels["x1"] * 100})
    path2 = tmp_path / "big.csv"
    rio.save_csv(big, path2, names=LAB_NAMES, units={**LAB_UNITS, "x1": "m", "y1": "m"})
    cmap = {**LAB_MAP, "Prox DE X": {"to": "x1", "unit": "m", "angle_deg": 0.0},
            "Prox DE Y": {"to": "y1", "unit": "m", "angle_deg": 25.0}}
    with pytest.raises(RotoridError, match="resolved from the angled probes spans"):
        quiet_load(path2, channel_map=cmap)


def test_an_angled_probe_with_a_partner_at_its_default_and_angled_housing_accelerometers(tmp_path):
    """x1 at 45° whose partner is the file's canonically named y1 (no map entry: vertical, 90°);
    x2 canonical (0°) with y2 at 120°; housing accelerometers px1/py1 at 30° and 150° (g): each
    plane's x and y come back, and the defaults are recorded."""
    rng = np.random.default_rng(2)
    t = np.arange(N) / FS
    acc = {c: 0.3 * 9.80665 * np.sin(2 * np.pi * 30 * t + i) + 0.01 * rng.standard_normal(N)
           for i, c in enumerate(("px1", "px2", "py1", "py2"))}
    rec = make_rec(extra=acc)
    angles = {"x1": 45.0, "y2": 120.0}
    read = _angled(rec, angles)
    ch = dict(read.channels)
    for c, a in (("px1", 30.0), ("py1", 150.0)):
        ch[c] = np.cos(np.radians(a)) * rec.channels["px1"] + np.sin(np.radians(a)) * rec.channels["py1"]
    path = tmp_path / "partners.tdms"
    rio.save_tdms(Recording(FS, ch), path, names={"x1": "Prox DE A"}, units={c: "g" for c in acc})
    cmap = {"Prox DE A": {"to": "x1", "angle_deg": 45.0}, "y2": {"to": "y2", "angle_deg": 120.0},
            "px1": {"to": "px1", "angle_deg": 30.0}, "py1": {"to": "py1", "angle_deg": 150.0}}
    got = quiet_load(path, channel_map=cmap)
    for c in ("x1", "x2", "y1", "y2", "px1", "px2", "py1", "py2"):
        np.testing.assert_allclose(got.channels[c], rec.channels[c], rtol=0, atol=1e-12 * np.abs(rec.channels[c]).max(),
                                   err_msg=c)
    src = got.meta["channel_sources"]
    assert (src["y1"]["angle_deg"], src["x2"]["angle_deg"], src["py1"]["angle_deg"]) == (90.0, 0.0, 150.0)


def test_a_clipped_probe_mounted_at_an_angle_is_reported_as_read(tmp_path):
    """A probe at its rail mixes into both the x and the y resolved from it, neither flat: the
    clipping check looks at what each angled probe reads (a review found 0 warnings and the
    coefficients 13-66 % off, every point ok)."""
    rec = make_rec()
    read = _angled(rec, {"x1": 45.0, "y1": 135.0})
    x1 = read.channels["x1"]
    rail = 0.7 * x1.max()
    path = tmp_path / "clipped.csv"
    rio.save_csv(Recording(FS, {**read.channels, "x1": np.minimum(x1, rail)}), path, names=LAB_NAMES, units=LAB_UNITS)
    cmap = {**LAB_MAP, "Prox DE X": {**LAB_MAP["Prox DE X"], "angle_deg": 45.0},
            "Prox DE Y": {**LAB_MAP["Prox DE Y"], "angle_deg": 135.0}}
    with pytest.warns(UserWarning, match=r"the probes 'Prox DE X' at 45° -> x1 and 'Prox DE Y' at 135° -> y1, as "
                                         r"read\): channel 'x1' possibly clipped: it sits at its maximum"):
        rio.load_recording(path, channel_map=cmap)


def test_the_groups_of_a_tdms_file_warn_once_of_channels_they_drop(tmp_path):
    """A TDMS file with one group per dwell and housing accelerometers left unmapped warned once
    per group, naming each group's channels (40 lines for 4 files of 10 dwells, an independent
    simulator's): the groups now name them bare, so the warning is one (Python's default filter,
    the CLI) per file."""
    rec = make_rec()
    path = tmp_path / "dwells.tdms"
    with TdmsWriter(path) as w:
        for g in ("Dwell 01", "Dwell 02", "Dwell 03"):
            w.write_segment([ChannelObject(g, c, rec.channels[c], properties={"wf_increment": 1 / FS,
                                                                             "unit_string": "m" if c != "kp" else "V"})
                             for c in ("x1", "x2", "y1", "y2", "kp")] +
                            [ChannelObject(g, "Acc DE X", np.zeros(rec.n_samples), properties={"wf_increment": 1 / FS})])
    with warnings.catch_warnings(record=True) as got:
        warnings.simplefilter("always")
        seg = rio.load_segmented(path, groups="*")
    assert len(seg.blocks) == 3
    msgs = {str(w.message) for w in got if "dropped" in str(w.message)}
    assert len(msgs) == 1 and "['Acc DE X']" in msgs.pop(), got
    # one group read alone names it in full, as before
    with warnings.catch_warnings(record=True) as got:
        warnings.simplefilter("always")
        rio.load_recording(path, group="Dwell 02")
    assert any("'Dwell 02/Acc DE X'" in str(w.message) for w in got), [str(w.message) for w in got]
