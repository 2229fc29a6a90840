"""Lab file layouts as labs really have them: DAQ text exports (preamble, separators, decimal
comma, units in names, time columns), TDMS test days (group per run, time channels), UFF node and
direction addressing, channel delays and segmented recordings."""

import re
import warnings

import numpy as np
import pytest
from nptdms import ChannelObject, TdmsWriter
from pyuff import UFF

from rotorid import io as rio
from rotorid.errors import RotoridError
from rotorid.recording import Recording, SegmentedRecording

FS = 1000.0
N = 40
MIL = 25.4e-6
RNG = np.random.default_rng(11)
X_MIL = np.round(RNG.uniform(-2, 2, N), 6)     # probe readings as a DAQ writes them (6 decimals)
Y_MIL = np.round(RNG.uniform(-2, 2, N), 6)
T = np.arange(N) / FS


def quiet(fn, *args, **kw):
    """Call with every warning turned into an error."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        return fn(*args, **kw)


def table(sep, decimal, cols, fmt="{:.6f}"):
    """Data lines of the columns, with the given separator and decimal mark."""
    def cell(v):
        text = fmt.format(v)
        return text.replace(".", ",") if decimal == "," else text
    return "".join(sep.join(cell(v) for v in row) + "\n" for row in zip(*cols))


def check_xy(rec, fs=FS, t0=0.0):
    assert rec.fs_hz == pytest.approx(fs, rel=1e-9)
    assert rec.t0_s == pytest.approx(t0, abs=1e-12)
    np.testing.assert_allclose(rec.channels["x1"], X_MIL * MIL, rtol=1e-12)
    np.testing.assert_allclose(rec.channels["y1"], Y_MIL * MIL, rtol=1e-12)
    assert rec.units["x1"] == "m"


XY_MAP = {"DE X": {"to": "x1"}, "DE Y": {"to": "y1"}}


# ------------------------------------------------------------------------------ delimited text


def test_preamble_with_rate_semicolon_decimal_comma(tmp_path):
    path = tmp_path / "daq.csv"
    path.write_text("MyDAQ 3000 export\nDate: 05.01.2024 14:03\nComment: run 3; 1800 rpm\n"
                    "Sample rate: 1000 Hz\n\nDE X (mil);DE Y (mil)\n" + table(";", ",", [X_MIL, Y_MIL]))
    rec = quiet(rio.load_recording, path, channel_map=XY_MAP)
    check_xy(rec)
    assert rec.meta["preamble"][0] == "MyDAQ 3000 export" and len(rec.meta["preamble"]) == 4
    assert rec.meta["channel_sources"]["x1"]["unit_from"] == "file"


@pytest.mark.parametrize("line", ["Sampling rate = 1 kHz", "fs: 1000", "Rate\t1000 S/s", "# Sample rate [Hz]: 1000.0"])
def test_stated_rate_spellings(tmp_path, line):
    path = tmp_path / "daq.csv"
    path.write_text(f"DAQ\n{line}\nx1 [mil],y1 [mil]\n" + table(",", ".", [X_MIL, Y_MIL]))
    check_xy(quiet(rio.load_recording, path))


def test_preamble_without_rate_and_time_column_in_seconds(tmp_path):
    path = tmp_path / "daq.csv"
    path.write_text("Acquired with DAQ 9\nOperator: AB\nTime (s),DE X (mil),DE Y (mil)\n"
                    + table(",", ".", [T + 2.5, X_MIL, Y_MIL], "{:.9f}"))
    check_xy(quiet(rio.load_recording, path, channel_map=XY_MAP), t0=2.5)


def test_preamble_rate_agreeing_with_time_column(tmp_path):
    path = tmp_path / "daq.csv"
    path.write_text("Sample rate: 1000 Hz\nTime [ms],x1 (mil),y1 (mil)\n"
                    + table(",", ".", [T * 1e3, X_MIL, Y_MIL], "{:.9f}"))
    check_xy(quiet(rio.load_recording, path))


def test_time_column_in_milliseconds_by_name(tmp_path):
    path = tmp_path / "run.csv"
    path.write_text("time_ms,x1 [mil],y1 [mil]\n" + table(",", ".", [T * 1e3 + 100, X_MIL, Y_MIL], "{:.9f}"))
    check_xy(quiet(rio.load_recording, path), t0=0.1)


def test_tab_separated_with_decimal_comma(tmp_path):
    path = tmp_path / "export.txt"
    path.write_text("Zeit [s]\tDE X [mil]\tDE Y [mil]\n" + table("\t", ",", [T, X_MIL, Y_MIL], "{:.9f}"))
    check_xy(quiet(rio.load_recording, path, channel_map=XY_MAP))


def test_whitespace_separated_txt_with_units_line(tmp_path):
    path = tmp_path / "run.txt"
    body = "".join(f"  {t:.6f}   {x: .6f}   {y: .6f}\n" for t, x, y in zip(T, X_MIL, Y_MIL))
    path.write_text("Test rig export\n\n   time     x1      y1\n   s        mil     mil\n" + body)
    check_xy(quiet(rio.load_recording, path))


@pytest.mark.parametrize("ext", [".dat", ".asc"])
def test_other_text_extensions(tmp_path, ext):
    path = tmp_path / f"run{ext}"
    path.write_text("t x1 [mil] y1 [mil]\n" + table(" ", ".", [T, X_MIL, Y_MIL], "{:.9f}"))
    # .dat is also a binary extension: it is read as text only when asked to
    rec = quiet(rio.load_recording, path, fmt="csv") if ext == ".dat" else quiet(rio.load_recording, path)
    check_xy(rec)


def test_overrides_skip_rows_sep_decimal_time_column(tmp_path):
    path = tmp_path / "odd.csv"
    # a preamble with a numeric block of its own (a calibration table) fools the detection
    path.write_text("cal\n1;2\n3;4\n5;6\nclock;x1 [mil];y1 [mil]\n" + table(";", ",", [T, X_MIL, Y_MIL], "{:.9f}"))
    rec = quiet(rio.load_recording, path, skip_rows=4, time_column="clock")
    check_xy(rec)
    assert rec.meta["preamble"] == ["cal", "1;2", "3;4", "5;6"]
    rec = quiet(rio.load_recording, path, skip_rows=4, sep=";", decimal=",", time_column="clock")
    check_xy(rec)
    # time_column=False: no time axis; the rate must then come from elsewhere
    with pytest.warns(UserWarning, match=r"dropped 1 channel.*\['clock'\]"):
        rec = rio.load_recording(path, skip_rows=4, time_column=False, fs_hz=FS)
    check_xy(rec)


def test_separator_ending_every_line(tmp_path):
    # e.g. LabVIEW's spreadsheet export: a tab after the last value, a 'Comment' column that stays empty
    path = tmp_path / "lv.txt"
    body = "".join(f"{t:.6f}\t{x:.6f}\t{y:.6f}\t\n" for t, x, y in zip(T, X_MIL, Y_MIL))
    path.write_text("X_Value\tDE X (mil)\tDE Y (mil)\tComment\n" + body)
    with pytest.warns(UserWarning, match=r"dropped 1 channel.*\['Comment'\]"):
        check_xy(rio.load_recording(path, channel_map=XY_MAP, time_column="X_Value"))
    path.write_text("X_Value\tDE X (mil)\tDE Y (mil)\n" + body)
    check_xy(quiet(rio.load_recording, path, channel_map=XY_MAP, time_column="X_Value"))


def test_headerless_file_names_columns(tmp_path):
    path = tmp_path / "raw.csv"
    path.write_text(table(",", ".", [X_MIL, Y_MIL]))
    rec = quiet(rio.load_recording, path, fs_hz=FS, channel_map={"column 1": {"to": "x1", "unit": "mil"},
                                                                  "column 2": {"to": "y1", "unit": "mil"}})
    check_xy(rec)


# ------------------------------------------------------------------------------ bad text files


def test_non_numeric_cell_names_line_and_column(tmp_path):
    path = tmp_path / "bad.csv"
    lines = ("Sample rate: 1000 Hz\nx1 [mil],y1 [mil]\n" + table(",", ".", [X_MIL, Y_MIL])).splitlines()
    lines[12] = lines[12].split(",")[0] + ",overload"
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(RotoridError, match=rf"{re.escape(str(path))}: channel 'y1' .*cell 'overload' on line 13 "
                                           r"is not a number"):
        rio.load_recording(path)


def test_decimal_comma_read_with_the_wrong_decimal_says_so(tmp_path):
    path = tmp_path / "de.csv"
    path.write_text("x1 [mil];y1 [mil]\n" + table(";", ",", [X_MIL, Y_MIL]))
    with pytest.raises(RotoridError, match=r"de\.csv: channel 'x1' .*cell '-?\d+,\d+' on line 2 is not a number "
                                           r"\(decimal ','\? pass decimal=','\)"):
        rio.load_recording(path, decimal=".", fs_hz=FS)


def test_ambiguous_decimal_comma_raises(tmp_path):
    path = tmp_path / "amb.csv"
    path.write_text("0,5\n1,5\n2,5\n3,5\n")  # two integer columns, or one with decimal commas?
    with pytest.raises(RotoridError, match=r"amb\.csv.*ambiguous.*2 column\(s\) separated by ','.*1 column\(s\).*"
                                           r"decimal ','.*pass sep= and decimal="):
        rio.load_recording(path, fs_hz=FS)
    rec = quiet(rio.load_recording, path, fs_hz=FS, sep=";", decimal=",",
                channel_map={"column 1": {"to": "kp"}})
    np.testing.assert_array_equal(rec.channels["kp"], [0.5, 1.5, 2.5, 3.5])


def test_header_that_does_not_fit_the_data_raises(tmp_path):
    path = tmp_path / "hdr.csv"
    path.write_text("Sample rate: 1000 Hz\nx1 and y1 in mil\n" + table(",", ".", [X_MIL, Y_MIL]))
    with pytest.raises(RotoridError, match=r"cannot read .*hdr\.csv .*cannot find the header line: the data from line 3 "
                                           r"have 2 fields .*line 2 before them has 1.*pass skip_rows="):
        rio.load_recording(path)


def test_short_line_raises(tmp_path):
    path = tmp_path / "short.csv"
    lines = ("time [s],x1 [mil],y1 [mil]\n" + table(",", ".", [T, X_MIL, Y_MIL], "{:.9f}")).splitlines()
    lines[20] = lines[20].rsplit(",", 1)[0]
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(RotoridError, match=r"cannot read .*short\.csv .*line 21 has 2 field\(s\), the header has 3"):
        rio.load_recording(path)


def test_preamble_rate_disagreeing_with_time_column_raises(tmp_path):
    path = tmp_path / "rates.csv"
    path.write_text("Sample rate: 2000 Hz\ntime [s],x1 [mil]\n" + table(",", ".", [T, X_MIL], "{:.9f}"))
    with pytest.raises(RotoridError, match=r"rates\.csv: the preamble states a sample rate of 2000 Hz \(line 1.*"
                                           r"the time column 'time' gives 1000 Hz"):
        rio.load_recording(path)


@pytest.mark.parametrize("kw, match", [
    (dict(group="Run 1"), r"group= does not apply to .*run\.csv"),
    (dict(skip_rows=-1), r"skip_rows must be an integer >= 0"),
    (dict(sep="ab"), r"sep must be one of"),
    (dict(decimal=";"), r"decimal must be '\.' or ','"),
    (dict(sep=",", decimal=","), r"sep and decimal must differ"),
])
def test_options_are_checked(tmp_path, kw, match):
    path = tmp_path / "run.csv"
    rio.save_csv(Recording(FS, {"x1": X_MIL * MIL}), path)
    with pytest.raises(RotoridError, match=match):
        rio.load_recording(path, **kw)


def test_options_of_other_formats_raise(tmp_path):
    path = tmp_path / "run.tdms"
    rio.save_tdms(Recording(FS, {"x1": X_MIL * MIL}), path)
    with pytest.raises(RotoridError, match=r"sep= does not apply to .*run\.tdms"):
        rio.load_recording(path, sep=";")
    path = tmp_path / "run.npz"
    rio.save_recording(Recording(FS, {"x1": X_MIL * MIL}), path)
    with pytest.raises(RotoridError, match=r"time_column= does not apply to .*run\.npz"):
        rio.load_recording(path, time_column="t")


# ----------------------------------------------------------------------------------------- TDMS


def write_tdms(path, channels):
    """channels: [(group, name, data, properties)]"""
    with TdmsWriter(str(path)) as w:
        w.write_segment([ChannelObject(g, c, np.asarray(d), properties=p) for g, c, d, p in channels])


def test_day_file_one_group_per_run(tmp_path):
    path = tmp_path / "day.tdms"
    runs = ["Run 1", "Run 2", "Run 3"]
    props = {"wf_increment": 1 / FS, "unit_string": "mil"}
    write_tdms(path, [(r, c, d * (i + 1), dict(props, wf_start_offset=10.0 * i))
                      for i, r in enumerate(runs) for c, d in (("DE X", X_MIL), ("DE Y", Y_MIL))])
    assert rio.list_groups(path) == runs
    rec = quiet(rio.load_recording, path, group="Run 3", channel_map=XY_MAP)
    np.testing.assert_allclose(rec.channels["x1"], 3 * X_MIL * MIL, rtol=1e-12)
    assert rec.t0_s == 20.0 and rec.meta["group"] == "Run 3"
    assert rec.meta["channel_sources"]["y1"]["file_channel"] == "Run 3/DE Y"
    with pytest.raises(RotoridError, match=r"day\.tdms has no group 'Run 4'; its groups: \['Run 1', 'Run 2', 'Run 3'\]"):
        rio.load_recording(path, group="Run 4", channel_map=XY_MAP)
    with pytest.raises(RotoridError, match=r"day\.tdms: the file holds 3 groups with the same channels "
                                           r"\(\['DE X', 'DE Y'\]\); choose one with group="):
        rio.load_recording(path, channel_map=XY_MAP)


def test_day_file_with_a_settings_group(tmp_path):
    path = tmp_path / "day.tdms"
    props = {"wf_increment": 1 / FS, "unit_string": "mil"}
    write_tdms(path, [("Settings", "Temperature", np.full(3, 21.0), {})]
               + [(r, c, d, props) for r in ("Run 1", "Run 2") for c, d in (("DE X", X_MIL), ("DE Y", Y_MIL))])
    with pytest.raises(RotoridError, match=r"'DE X' named in channel_map is ambiguous in .*day\.tdms.*the file holds 2 "
                                           r"groups with the same channels \(\['DE X', 'DE Y'\]\); choose one with "
                                           r"group= \(one of \['Run 1', 'Run 2'\]\)"):
        rio.load_recording(path, channel_map=XY_MAP)
    check_xy(quiet(rio.load_recording, path, group="Run 2", channel_map=XY_MAP))


def test_tdms_time_channel_is_the_time_base(tmp_path):
    path = tmp_path / "timed.tdms"
    write_tdms(path, [("DAQ", "Time (s)", T + 4.0, {}), ("DAQ", "x1", X_MIL, {"unit_string": "mil"}),
                      ("DAQ", "y1", Y_MIL, {"unit_string": "mil", "wf_increment": 1 / FS})])
    check_xy(quiet(rio.load_recording, path), t0=4.0)
    with pytest.raises(RotoridError, match=r"timed\.tdms states no sample rate for channel 'DAQ/x1'"), \
            pytest.warns(UserWarning, match=r"dropped 1 channel.*\['DAQ/Time \(s\)'\]"):
        rio.load_recording(path, time_column=False)


def test_tdms_time_channel_by_unit(tmp_path):
    path = tmp_path / "timed.tdms"
    write_tdms(path, [("DAQ", "Clock", (T + 1.0) * 1e3, {"unit_string": "ms"}),
                      ("DAQ", "x1", X_MIL, {"unit_string": "mil"}), ("DAQ", "y1", Y_MIL, {"unit_string": "mil"})])
    check_xy(quiet(rio.load_recording, path), t0=1.0)


def test_tdms_timestamp_channel(tmp_path):
    path = tmp_path / "stamped.tdms"
    start = np.datetime64("2024-05-01T10:00:00.250000")
    stamps = start + (np.arange(N) * 1000).astype("timedelta64[us]")
    write_tdms(path, [("DAQ", "Timestamp", stamps, {}), ("DAQ", "x1", X_MIL, {"unit_string": "mil"}),
                      ("DAQ", "y1", Y_MIL, {"unit_string": "mil"})])
    rec = quiet(rio.load_recording, path)
    check_xy(rec, t0=0.0)
    assert rec.meta["start_time"] == "2024-05-01T10:00:00.250000Z"


def test_tdms_time_channel_and_wf_increment_disagree(tmp_path):
    path = tmp_path / "clash.tdms"
    write_tdms(path, [("DAQ", "time", T, {}), ("DAQ", "x1", X_MIL, {"unit_string": "mil", "wf_increment": 1 / 2048})])
    with pytest.raises(RotoridError, match=r"clash\.tdms: channel 'DAQ/x1' .*wf_increment gives 2048 Hz, the time "
                                           r"channel 'DAQ/time' gives 1000 Hz"):
        rio.load_recording(path)


def test_tdms_non_uniform_time_channel(tmp_path):
    path = tmp_path / "jitter.tdms"
    t = T.copy()
    t[7] += 2e-4
    write_tdms(path, [("DAQ", "t", t, {}), ("DAQ", "x1", X_MIL, {"unit_string": "mil"})])
    with pytest.raises(RotoridError, match=r"jitter\.tdms: .*'DAQ/t': non-uniform time channel: sample 7"):
        rio.load_recording(path)


def test_list_groups_of_a_missing_or_bad_file(tmp_path):
    with pytest.raises(RotoridError, match=r"absent\.tdms: no such file"):
        rio.list_groups(tmp_path / "absent.tdms")
    bad = tmp_path / "bad.tdms"
    bad.write_bytes(b"not a tdms file at all" * 10)
    with pytest.raises(RotoridError, match=r"cannot read .*bad\.tdms as TDMS"):
        rio.list_groups(bad)


# ------------------------------------------------------------------------------------------ UFF


def uff_set(node, direction, data, id1="Response"):
    return {"type": 58, "binary": 0, "id1": id1, "id2": "NONE", "id3": "NONE", "id4": "NONE", "id5": "NONE",
            "func_type": 1, "func_id": 0, "ver_num": 0, "load_case_id": 0, "rsp_ent_name": "rig",
            "rsp_node": node, "rsp_dir": direction, "ref_ent_name": "NONE", "ref_node": 0, "ref_dir": 0,
            "ord_data_type": 4, "abscissa_spacing": 1, "abscissa_min": 0.0, "abscissa_inc": 1 / FS,
            "z_axis_value": 0.0, "abscissa_spec_data_type": 17, "abscissa_len_unit_exp": 0,
            "abscissa_force_unit_exp": 0, "abscissa_temp_unit_exp": 0, "abscissa_axis_lab": "Time",
            "abscissa_axis_units_lab": "s", "ordinate_spec_data_type": 8, "ordinate_len_unit_exp": 0,
            "ordinate_force_unit_exp": 0, "ordinate_temp_unit_exp": 0, "ordinate_axis_lab": "NONE",
            "ordinate_axis_units_lab": "mil", "orddenom_spec_data_type": 0, "orddenom_len_unit_exp": 0,
            "orddenom_force_unit_exp": 0, "orddenom_temp_unit_exp": 0, "orddenom_axis_lab": "NONE",
            "orddenom_axis_units_lab": "NONE", "z_axis_spec_data_type": 0, "z_axis_len_unit_exp": 0,
            "z_axis_force_unit_exp": 0, "z_axis_temp_unit_exp": 0, "z_axis_axis_lab": "NONE",
            "z_axis_axis_units_lab": "NONE", "data": np.asarray(data, dtype=float), "x": T}


def test_uff_sets_sharing_id1_by_node_and_direction(tmp_path):
    path = tmp_path / "modal.uff"
    UFF(str(path)).write_sets([uff_set(3, 1, X_MIL), uff_set(3, 2, Y_MIL), uff_set(4, -1, 2 * X_MIL),
                               uff_set(4, -2, 2 * Y_MIL)], mode="overwrite")
    cmap = {"3:+X": {"to": "x1"}, "3:+Y": {"to": "y1", "delay_s": 1e-4},
            "4:-X": {"to": "x2"}, "4:-Y": {"to": "y2", "scale": -1}}
    rec = quiet(rio.load_recording, path, channel_map=cmap)
    check_xy(rec)
    np.testing.assert_allclose(rec.channels["x2"], 2 * X_MIL * MIL, rtol=1e-9)   # -X: not negated
    np.testing.assert_allclose(rec.channels["y2"], -2 * Y_MIL * MIL, rtol=1e-9)  # unless scale=-1 says so
    assert rec.meta["channel_sources"]["x2"]["file_channel"] == "4:-X"
    assert rec.meta["channel_delays_s"] == {"y1": 1e-4}
    with pytest.raises(RotoridError, match=r"'Response' named in channel_map is ambiguous in .*modal\.uff.*"
                                           r"\['3:\+X', '3:\+Y', '4:-X', '4:-Y'\]; name it as '<node>:<dir>'"):
        rio.load_recording(path, channel_map={"Response": {"to": "x1"}})
    with pytest.raises(RotoridError, match=r"'5:\+X' named in channel_map is not in .*modal\.uff"):
        rio.load_recording(path, channel_map={"5:+X": {"to": "x1"}})


def test_uff_node_direction_alongside_unique_names(tmp_path):
    path = tmp_path / "run.uff"
    UFF(str(path)).write_sets([uff_set(1, 1, X_MIL, "Prox DE X"), uff_set(1, 2, Y_MIL, "Prox DE Y")], mode="overwrite")
    check_xy(quiet(rio.load_recording, path, channel_map={"1:+X": {"to": "x1"}, "Prox DE Y": {"to": "y1"}}))


# ------------------------------------------------------------------------------------- delay_s


def test_delay_s_is_stored_in_meta(tmp_path):
    path = tmp_path / "run.csv"
    path.write_text("time [s],DE X [mil],DE Y [mil]\n" + table(",", ".", [T, X_MIL, Y_MIL], "{:.9f}"))
    cmap = {"DE X": {"to": "x1", "delay_s": 2.5e-4}, "DE Y": {"to": "y1", "delay_s": 0.0}}
    rec = quiet(rio.load_recording, path, channel_map=cmap)
    check_xy(rec)  # the data are not shifted
    assert rec.meta["channel_delays_s"] == {"x1": 2.5e-4}
    rec = quiet(rio.load_recording, path, channel_map=XY_MAP)
    assert "channel_delays_s" not in rec.meta


@pytest.mark.parametrize("delay", [float("nan"), 5.0, -1.0, "1ms", True])
def test_bad_delay_s_raises(tmp_path, delay):
    path = tmp_path / "run.csv"
    path.write_text("time [s],DE X [mil]\n" + table(",", ".", [T, X_MIL], "{:.9f}"))
    with pytest.raises(RotoridError, match=r"channel_map\['DE X'\] \(for .*run\.csv\): 'delay_s' must be a finite "
                                           r"number of seconds with \|delay_s\| < 1"):
        rio.load_recording(path, channel_map={"DE X": {"to": "x1", "delay_s": delay}})


# ---------------------------------------------------------------------------------- segmented


def test_load_segmented_from_files_with_time_columns(tmp_path):
    paths = []
    for i, start in enumerate([0.0, 3.0, 7.5]):
        p = tmp_path / f"step{i}.csv"
        p.write_text("Time (s);DE X (mil);DE Y (mil)\n" + table(";", ",", [T + start, X_MIL * (i + 1), Y_MIL],
                                                                  "{:.9f}"))
        paths.append(p)
    seg = quiet(rio.load_segmented, paths, channel_map=XY_MAP, meta={"kind": "imbalance"})
    assert isinstance(seg, SegmentedRecording) and len(seg.blocks) == 3
    assert [b.t0_s for b in seg.blocks] == pytest.approx([0.0, 3.0, 7.5])
    np.testing.assert_allclose(seg.blocks[2].channels["x1"], 3 * X_MIL * MIL, rtol=1e-12)
    assert seg.fs_hz == pytest.approx(FS) and seg.meta["kind"] == "imbalance"
    assert seg.meta["source_format"] == "csv" and seg.meta["block_sources"] == [str(p) for p in paths]


def test_load_segmented_lays_blocks_without_start_back_to_back(tmp_path):
    paths = []
    for i in range(2):
        p = tmp_path / f"block{i}.txt"
        p.write_text("Sample rate: 1000 Hz\nx1 [mil]\ty1 [mil]\n" + table("\t", ".", [X_MIL, Y_MIL]))
        paths.append(p)
    with pytest.warns(UserWarning, match=r"2 block\(s\) state no start time.*laid back to back"):
        seg = rio.load_segmented(paths)
    assert [b.t0_s for b in seg.blocks] == pytest.approx([0.0, N / FS])


def test_load_segmented_from_tdms_groups(tmp_path):
    blocks = [Recording(FS, {"x1": X_MIL * MIL * (i + 1), "y1": Y_MIL * MIL}, t0_s=t0)
              for i, t0 in enumerate([0.0, 2.0, 5.0])]
    path = tmp_path / "steps.tdms"
    names = ["600 rpm", "900 rpm", "1200 rpm"]
    rio.save_tdms_segmented(SegmentedRecording(blocks), path, groups=names, units={"x1": "mil", "y1": "mil"})
    assert rio.list_groups(path) == names
    seg = quiet(rio.load_segmented, path, groups="*")
    assert [b.t0_s for b in seg.blocks] == [0.0, 2.0, 5.0]
    for got, want in zip(seg.blocks, blocks):
        np.testing.assert_allclose(got.channels["x1"], want.channels["x1"], rtol=1e-12)
    assert seg.blocks[1].meta["group"] == "900 rpm" and "group" not in seg.meta
    seg = quiet(rio.load_segmented, path, groups=["1200 rpm", "600 rpm"])
    assert [b.t0_s for b in seg.blocks] == [5.0, 0.0]
    with pytest.raises(RotoridError, match=r"steps\.tdms has no group\(s\) \['Run 9'\]; its groups: "):
        rio.load_segmented(path, groups=["Run 9"])
    with pytest.raises(RotoridError, match=r"groups= needs a TDMS file"):
        rio.load_segmented(tmp_path / "x.csv", groups="*")
    with pytest.raises(RotoridError, match=r"not group="):
        rio.load_segmented([path], group="600 rpm")


def test_load_segmented_tdms_timestamps_share_one_clock(tmp_path):
    path = tmp_path / "stamped_steps.tdms"
    start = np.datetime64("2024-05-01T10:00:00")
    chans = []
    for group, offset_s in (("step 1", 0), ("step 2", 4), ("step 3", 9)):
        stamps = start + np.timedelta64(offset_s, "s") + (np.arange(N) * 1000).astype("timedelta64[us]")
        chans += [(group, "Time", stamps, {}), (group, "x1", X_MIL, {"unit_string": "mil"}),
                  (group, "y1", Y_MIL, {"unit_string": "mil"})]
    write_tdms(path, chans)
    seg = quiet(rio.load_segmented, path, groups="*")
    assert [b.t0_s for b in seg.blocks] == pytest.approx([0.0, 4.0, 9.0], abs=1e-9)
    assert seg.meta["start_time"] == "2024-05-01T10:00:00.000000Z"
    check_xy(seg.blocks[2], t0=9.0)
