"""rotorid.config: the TOML config schema, its one-line errors and the helpers the pipeline uses."""

import copy
import doctest
import math
import pickle
import re
import tempfile
from pathlib import Path

import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from pydantic import BaseModel

import rotorid
from rotorid import config as C
from rotorid.config import ConfigError, load_config, parse_config
from rotorid.errors import RotoridError
from rotorid.recording import KNOWN

REPO = Path(__file__).resolve().parent.parent
EXAMPLE = Path(rotorid.__file__).parent / "data" / "example"
DOCS = REPO / "docs"
NOT_CONFIGS = {"truth.toml"}  # the example's simulation truth (bearing coefficients), not a config


# ---------------------------------------------------------------------------------------------
# helpers

def imbalance_cfg(**imb):
    sec = {"steady": True, "runs": [
        {"file": "run_S0.tdms", "name": "S0", "mass_g": [5.0, 5.0], "angle_deg": [0.0, 0.0]},
        {"file": "run_C0.tdms", "name": "C0", "mass_g": [5.0, 5.0], "angle_deg": [0.0, 180.0]},
        {"file": "run_S90.tdms", "name": "S90", "mass_kg": [0.005, 0.005], "angle_deg": [90.0, 90.0]},
    ], "baseline": "baseline.tdms"}
    sec.update(imb)
    return {"rig": {"builtin": "nsf"},
            "channels": {"Prox DE X": {"to": "x1", "unit": "mil"}, "Keyphasor": {"to": "kp", "unit": "V"}},
            "imbalance": sec, "output": {"dir": "out", "units": "SI"}}


def impact_cfg(**imp):
    sec = {"band_hz": [5.0, 150.0], "record_s": 0.25, "tests": [
        {"file": "impact_x.tdms", "plane_m": 0.0, "direction": "x"},
        {"file": "impact_y.tdms", "plane_m": 0.0, "direction": "y"}]}
    sec.update(imp)
    return {"rig": {"builtin": "nsf"}, "channels": {"Hammer": {"to": "force", "unit": "lbf"}}, "impact": sec}


ROTOR = {"mass_kg": 45.3, "it_kgm2": 0.704, "ip_kgm2": 0.299, "l1": 0.189, "l2": 0.217,
         "d": [0.067, 0.102], "r": [0.114, 0.095], "s": [0.119, 0.146]}

COLUMNS = {k: {"amplitude": f"{k} amp", "phase": f"{k} phase"} for k in ("x1", "x2", "y1", "y2")}


def rich_cfg():
    """A config that uses every kind of table (for the property tests)."""
    cfg = imbalance_cfg()
    cfg["files"] = {"fs_hz": 10000, "format": "auto", "sep": ";", "decimal": ",", "time_column": False}
    cfg["keyphasor"] = {"level": 2.5, "hysteresis": "auto", "edge": "rising", "tolerance": 0.3}
    cfg["imbalance"]["runs"][0]["keyphasor"] = {"level": 1.0, "fill_missing": False}
    cfg["imbalance"]["runs"][1]["channels"] = {"DE X": {"to": "x1", "unit": "um", "scale": 2.0, "delay_s": 1e-4}}
    cfg["imbalance"]["slow_roll"] = {"files": ["sr1.tdms", "sr2.tdms"], "group": "DAQ"}
    cfg["impact"] = impact_cfg()["impact"]
    cfg["impact"]["tests"][0]["groups"] = ["hit 1", "hit 2"]
    return cfg


def table_cfg():
    cfg = imbalance_cfg()
    cfg["imbalance"]["table"] = {"columns": copy.deepcopy(COLUMNS), "amplitude": "pk-pk", "unit": "mil",
                                 "phase": "lag", "slow_roll_max_rpm": 400.0}
    return cfg


def error_of(data, **kw) -> str:
    kw.setdefault("source", "rig.toml")
    with pytest.raises(ConfigError) as info:
        parse_config(data, **kw)
    return check_message(info.value)


def check_message(exc) -> str:
    msg = str(exc)
    assert isinstance(exc, RotoridError) and isinstance(exc, ValueError)
    assert len(msg.splitlines()) == 1 and "\n" not in msg, msg
    assert "pydantic" not in msg.lower() and "input should" not in msg.lower() and "validation error" not in msg
    assert exc.__cause__ is None and (exc.__context__ is None or exc.__suppress_context__)
    return msg


def load_error(path, **kw) -> str:
    with pytest.raises(ConfigError) as info:
        load_config(path, **kw)
    return check_message(info.value)


# ---------------------------------------------------------------------------------------------
# the bundled configs and the documented examples

BUNDLED = sorted(p for p in EXAMPLE.glob("*.toml") if p.name not in NOT_CONFIGS and not p.name.startswith("study_"))
DOC_EXAMPLES = sorted(p for p in (DOCS / "examples").glob("*.toml") if not p.name.startswith("study_"))  # study configs: test_study_cli


def test_bundled_and_doc_examples_exist():
    assert {p.name for p in BUNDLED} >= {"imbalance.toml", "impact.toml"}
    assert {p.name for p in DOC_EXAMPLES} >= {"imbalance_waveforms.toml", "impact.toml", "imbalance_1x_table.toml"}


@pytest.mark.parametrize("path", BUNDLED, ids=lambda p: p.name)
def test_bundled_configs_validate_as_they_are(path):
    cfg = load_config(path)
    assert cfg.rotor() == rotorid.nsf_rig().rotor
    for loc, entry in cfg.entries():
        assert all(p.is_file() for p in entry.paths(cfg)), loc
    if cfg.imbalance is not None and cfg.imbalance.table is not None:
        assert cfg.channels_for() == {}  # 1X tables name their columns in [imbalance.table]
    else:
        assert cfg.channels_for()["Prox DE X"] == {"to": "x1", "unit": "mil", "scale": 1.0, "offset": 0.0,
                                                    "delay_s": 0.0}


def test_bundled_imbalance_config_content():
    cfg = load_config(EXAMPLE / "imbalance.toml")
    imb = cfg.section("imbalance")
    assert [r.name for r in imb.runs] == ["S0", "C0", "S90", "C90"]
    assert [r.mass_kg() for r in imb.runs] == [(0.005, 0.005)] * 4
    assert imb.runs[3].angle_deg == (90.0, 270.0)
    assert imb.baseline.paths(cfg) == [EXAMPLE / "imbalance" / "baseline.tdms"]
    assert imb.steady is True and imb.speeds_rpm is None and imb.orders == (1, 2, 3)
    assert cfg.output_dir("imbalance") == EXAMPLE / "out_imbalance"
    assert cfg.output.units == "SI"


@pytest.mark.parametrize("path", DOC_EXAMPLES, ids=lambda p: p.name)
def test_doc_examples_validate(path):
    files_there = True
    if "1x_table" in path.name:  # its tables are generated by rotorid.tables; validate without them if absent
        files_there = (EXAMPLE / "daq_1x" / "run_S0.csv").is_file()
    cfg = load_config(path, check_files=files_there)
    cfg.rotor()
    assert cfg.imbalance is not None or cfg.impact is not None


def test_doc_examples_say_what_the_docs_say():
    doc = (DOCS / "config.md").read_text(encoding="utf-8")
    for path in DOC_EXAMPLES:
        assert path.read_text(encoding="utf-8") in doc, f"{path.name} is not reproduced verbatim in docs/config.md"


def all_models():
    return [m for m in vars(C).values() if isinstance(m, type) and issubclass(m, BaseModel) and m is not C._Model
            and m.__module__ == C.__name__]


def all_keys():
    return {(f.alias or n) for m in all_models() for n, f in m.model_fields.items()}


def test_every_key_is_documented():
    doc = (DOCS / "config.md").read_text(encoding="utf-8")
    missing = sorted(k for k in all_keys() if f"`{k}`" not in doc and f"[{k}]" not in doc)
    assert not missing, f"keys missing from docs/config.md: {missing}"


def test_docstring_examples_run():
    res = doctest.testmod(C, optionflags=doctest.ELLIPSIS)
    assert res.attempted >= 8 and res.failed == 0


def test_canonical_channels_match_the_recording_model():
    assert set(C.CANONICAL) == set(KNOWN)
    assert C.QUANTITY["x1"] == "length" and C.QUANTITY["kp"] == "voltage" and C.QUANTITY["px2"] == "acceleration"


# ---------------------------------------------------------------------------------------------
# unknown keys

def test_unknown_top_level_key_with_suggestion():
    cfg = imbalance_cfg()
    cfg["imbalnce"] = cfg.pop("imbalance")
    msg = error_of(cfg)
    assert "rig.toml: unknown top-level key 'imbalnce' (did you mean 'imbalance'?)" in msg


@pytest.mark.parametrize("key, good", [("stedy", "steady"), ("baselin", "baseline"), ("speed_rpm", "speeds_rpm")])
def test_unknown_key_in_section(key, good):
    cfg = imbalance_cfg()
    cfg["imbalance"][key] = cfg["imbalance"].pop(good, False)
    msg = error_of(cfg)
    assert f"[imbalance] unknown key '{key}' (did you mean '{good}'?)" in msg


def test_unknown_key_in_run_exact_message():
    cfg = imbalance_cfg()
    cfg["imbalance"]["runs"][2]["angle_degs"] = cfg["imbalance"]["runs"][2].pop("angle_deg")
    assert error_of(cfg) == "rig.toml: [imbalance.runs][2] unknown key 'angle_degs' (did you mean 'angle_deg'?)"


def test_unknown_key_in_inline_keyphasor_table():
    cfg = impact_cfg()
    cfg["impact"]["tests"][1]["keyphasor"] = {"levle": 2.0}
    assert error_of(cfg) == "rig.toml: [impact.tests][1].keyphasor unknown key 'levle' (did you mean 'level'?)"


def test_unknown_key_in_channel_spec_and_quoted_location():
    cfg = imbalance_cfg()
    cfg["channels"]["Prox DE X"]["units"] = "mil"
    msg = error_of(cfg)
    assert "[channels.\"Prox DE X\"] unknown key 'units' (did you mean 'unit'?)" in msg


def test_unknown_key_without_close_match_has_no_suggestion():
    cfg = impact_cfg()
    cfg["output"] = {"zzzzzz": 1}
    assert error_of(cfg) == "rig.toml: [output] unknown key 'zzzzzz'"


# ---------------------------------------------------------------------------------------------
# strict types

@pytest.mark.parametrize("key", ["steady", "identical"])
def test_string_booleans_are_refused(key):
    msg = error_of(imbalance_cfg(**{key: "false"}))
    assert msg == f"rig.toml: [imbalance] {key} must be true or false, got the string 'false'"


def test_string_boolean_in_keyphasor_override():
    cfg = imbalance_cfg()
    cfg["imbalance"]["runs"][0]["keyphasor"] = {"fill_missing": "no"}
    assert "[imbalance.runs][0].keyphasor fill_missing must be true or false, got the string 'no'" in error_of(cfg)


@pytest.mark.parametrize("where, value, fragment", [
    ("min_revs", 8.0, "[imbalance] min_revs must be an integer >= 2, got 8.0"),
    ("min_revs", True, "[imbalance] min_revs must be an integer >= 2, got true"),
    ("settle_revs", "2", "[imbalance] settle_revs must be an integer >= 0, got the string '2'"),
    ("speed_tolerance", True, "[imbalance] speed_tolerance must be a number > 0 and < 0.5, got true"),
    ("speed_tolerance", 0.7, "[imbalance] speed_tolerance must be a number > 0 and < 0.5, got 0.7"),
    ("cond_max", math.nan, "[imbalance] cond_max must be a number > 1, got nan"),
    ("speeds_rpm", [3000, "4000"], "[imbalance] speeds_rpm[1] must be a number > 0, got the string '4000'"),
    ("speeds_rpm", 3000, "[imbalance] speeds_rpm must be a non-empty array of numbers > 0, got 3000"),
    ("orders", [2, 3], "[imbalance] orders must contain 1, got [2, 3]"),
    ("orders", [1, 1.5], "[imbalance] orders[1] must be an integer >= 1, got 1.5"),
    ("points_per_rev", 8, "[imbalance] points_per_rev must be 'auto' or an integer >= 16 and <= 65536, got 8"),
    ("points_per_rev", "Auto", "got the string 'Auto' (did you mean 'auto'?)"),
    ("method", "Forces", "[imbalance] method must be one of 'forces', 'report', got 'Forces' (did you mean 'forces'?)"),
    ("runs", "run.tdms", "[imbalance] runs must be an array of tables ([[imbalance.runs]]), got the string"),
    ("runs", [], "[imbalance] runs must have at least 1 entry, got 0"),
    ("keyphasor_delay_std_s", -1e-6, "[imbalance] keyphasor_delay_std_s must be a number >= 0"),
    ("keyphasor_angle_std_deg", 45.0, "[imbalance] keyphasor_angle_std_deg must be a number >= 0 and < 45, got 45"),
    ("keyphasor_angle_std_deg", "1 deg", "[imbalance] keyphasor_angle_std_deg must be a number >= 0 and < 45, got the string"),
])
def test_wrong_types_and_ranges_in_imbalance(where, value, fragment):
    msg = error_of(imbalance_cfg(**{where: value}))
    assert fragment in msg
    assert where in msg


def test_integers_accepted_where_numbers_expected():
    cfg = parse_config(impact_cfg(record_s=1, band_hz=[5, 150], pre_s=0))
    assert cfg.impact.record_s == 1.0 and isinstance(cfg.impact.record_s, float)
    assert cfg.impact.band_hz == (5.0, 150.0)


def test_wrong_types_in_rotor_and_sections():
    cfg = {"rotor": dict(ROTOR, mass_kg="45.3", r=[0.1, -0.1], d=[0.1]), "impact": {"tests": [
        {"file": "a.tdms", "plane_m": "0", "direction": "x"}]}}
    with pytest.raises(ConfigError) as info:
        parse_config(cfg, source="rig.toml")
    check_message(info.value)
    probs = info.value.problems
    assert "[rotor] mass_kg must be a number > 0, got the string '45.3'" in probs
    assert "[rotor] d must be an array of 2 numbers [d1, d2], got the array [0.1] (numbers in m or strings with a unit, e.g. '12.5 in')" in probs
    assert "[rotor] r[1] must be > 0, got -0.1" in probs
    assert "[impact.tests][0] plane_m must be a number, got the string '0'" in probs
    assert str(info.value).endswith("and 1 more")


@pytest.mark.parametrize("section, value", [("imbalance", 3), ("channels", "x1"), ("output", [1])])
def test_sections_must_be_tables(section, value):
    cfg = imbalance_cfg()
    cfg[section] = value
    msg = error_of(cfg)
    assert msg.startswith(f"rig.toml: {section} must be a table, got")


def test_channel_value_must_be_a_table():
    cfg = imbalance_cfg()
    cfg["channels"]["DE Y"] = "y1"
    msg = error_of(cfg)
    assert "[channels] \"DE Y\" must be a table like {to = \"x1\", unit = \"mil\"}, got the string 'y1'" in msg


def test_run_entry_of_the_wrong_type():
    cfg = imbalance_cfg()
    cfg["imbalance"]["runs"][1] = 5
    assert '[imbalance] runs[1] must be a file path or a table with file = "...", got 5' in error_of(cfg)


# ---------------------------------------------------------------------------------------------
# imbalance runs

def test_mass_g_with_mass_kg():
    cfg = imbalance_cfg()
    cfg["imbalance"]["runs"][0]["mass_kg"] = [0.005, 0.005]
    assert error_of(cfg) == "rig.toml: [imbalance.runs][0] give mass_g or mass_kg, not both"


def test_missing_angle_deg():
    cfg = imbalance_cfg()
    del cfg["imbalance"]["runs"][1]["angle_deg"]
    msg = error_of(cfg)
    assert msg.startswith("rig.toml: [imbalance.runs][1] missing key 'angle_deg'") and "mass_g" in msg


def test_angle_deg_without_mass():
    cfg = imbalance_cfg()
    del cfg["imbalance"]["runs"][2]["mass_kg"]
    assert "[imbalance.runs][2] angle_deg without a mass" in error_of(cfg)


def test_negative_mass():
    cfg = imbalance_cfg()
    cfg["imbalance"]["runs"][0]["mass_g"] = [5.0, -1.0]
    assert error_of(cfg) == "rig.toml: [imbalance.runs][0] mass_g[1] must be >= 0, got -1.0"


def test_run_needs_file_or_files_not_both():
    cfg = imbalance_cfg()
    del cfg["imbalance"]["runs"][0]["file"]
    assert "[imbalance.runs][0] needs file = " in error_of(cfg)
    cfg = imbalance_cfg()
    cfg["imbalance"]["runs"][0]["files"] = ["a.tdms"]
    assert "[imbalance.runs][0] give file or files, not both" in error_of(cfg)


def test_groups_rules():
    cfg = imbalance_cfg()
    cfg["imbalance"]["runs"][0].update(groups=["a"], group="b")
    assert "[imbalance.runs][0] give group or groups, not both" in error_of(cfg)
    cfg = imbalance_cfg()
    cfg["imbalance"]["runs"][0].update(file="run.csv", groups="*")
    assert "[imbalance.runs][0] groups needs a TDMS file, but 'run.csv' is read as" in error_of(cfg)
    cfg = imbalance_cfg()
    cfg["imbalance"]["runs"][0].update(groups=["*", "a"])
    assert "[imbalance.runs][0] groups" in error_of(cfg)
    cfg = imbalance_cfg()
    cfg["imbalance"]["runs"][0].update(file="run.dat", format="tdms", groups="*")
    assert parse_config(cfg).imbalance.runs[0].groups == "*"
    cfg["imbalance"]["runs"][0]["groups"] = ["*"]
    assert parse_config(cfg).imbalance.runs[0].groups == "*"
    cfg["imbalance"]["runs"][0]["groups"] = ["3000 rpm", "4000 rpm"]
    cfg["files"] = {"group": "DAQ"}
    c = parse_config(cfg)
    assert c.imbalance.runs[0].groups == ("3000 rpm", "4000 rpm")
    assert c.files_for(c.imbalance.runs[0])["group"] is None and c.files_for(c.imbalance.runs[1])["group"] == "DAQ"
    cfg["imbalance"]["runs"][0]["groups"] = ["a", "a"]
    assert "[imbalance.runs][0] groups must not name a group twice" in error_of(cfg)


# ---------------------------------------------------------------------------------------------
# rotor

def test_rotor_missing_d():
    cfg = impact_cfg()
    del cfg["rig"]
    cfg["rotor"] = {k: v for k, v in ROTOR.items() if k != "d"}
    assert error_of(cfg) == "rig.toml: [rotor] missing required key 'd' (imbalance planes [d1, d2] from the CG, m)"


def test_rotor_missing_several_keys_in_one_message():
    cfg = impact_cfg()
    del cfg["rig"]
    cfg["rotor"] = {"mass_kg": 45.3}
    msg = error_of(cfg)
    assert msg == ("rig.toml: [rotor] missing required keys 'it_kgm2', 'ip_kgm2', 'l1', 'l2', 'd', 'r', 's'")


def test_rig_and_rotor_both():
    cfg = impact_cfg()
    cfg["rotor"] = dict(ROTOR)
    msg = error_of(cfg)
    assert "[rig] and [rotor] are both given" in msg


def test_no_rotor_at_all():
    cfg = impact_cfg()
    del cfg["rig"]
    assert error_of(cfg) == ('rig.toml: the config names no rotor: give [rig] builtin = "nsf" or a [rotor] table')


def test_no_rotor_is_reported_with_other_problems():
    cfg = impact_cfg(record_s=-1)
    del cfg["rig"]
    msg = error_of(cfg)
    assert "record_s must be a number > 0" in msg and "names no rotor" in msg


def test_unknown_builtin_rig():
    cfg = impact_cfg()
    cfg["rig"] = {"builtin": "NSF2"}
    assert "[rig] builtin names an unknown builtin rig 'NSF2' (did you mean 'nsf'?)" in error_of(cfg)


def test_rotor_physics():
    cfg = impact_cfg()
    del cfg["rig"]
    cfg["rotor"] = dict(ROTOR, l1=-0.3)
    assert "[rotor] bearing span l1 + l2 must be > 0" in error_of(cfg)
    cfg["rotor"] = dict(ROTOR, s=[0.1, -0.1])
    assert "[rotor] s (probe positions): the two probe planes coincide" in error_of(cfg)
    cfg["rotor"] = dict(ROTOR, it_kgm2=0)
    assert "[rotor] it_kgm2 must be a number > 0, got 0" in error_of(cfg)


def test_rotor_table_gives_a_rigid_rotor():
    cfg = impact_cfg()
    del cfg["rig"]
    cfg["rotor"] = dict(ROTOR, s=[0.1, 0.12])
    rotor = parse_config(cfg).rotor()
    assert isinstance(rotor, rotorid.RigidRotor)
    assert rotor.mass_kg == 45.3 and rotor.d == (0.067, 0.102) and rotor.s == (0.1, 0.12)


def test_neither_imbalance_nor_impact():
    msg = error_of({"rig": {"builtin": "nsf"}})
    assert msg == "rig.toml: the config has no [imbalance] section and no [impact] section: give at least one"


# ---------------------------------------------------------------------------------------------
# units and channels

def test_unit_of_the_wrong_quantity_exact_message():
    cfg = imbalance_cfg()
    cfg["channels"]["Prox DE X"]["unit"] = "lbf"
    assert error_of(cfg) == "rig.toml: [channels.\"Prox DE X\"] unit 'lbf' is a force, but x1 is a length"


def test_unknown_unit():
    cfg = impact_cfg()
    cfg["channels"]["Hammer"]["unit"] = "lbs"
    msg = error_of(cfg)
    assert msg.startswith("rig.toml: [channels.Hammer] unknown unit 'lbs' (did you mean 'lbf'?)")
    assert "known force units" in msg


def test_unit_in_a_run_channel_map():
    cfg = imbalance_cfg()
    cfg["imbalance"]["runs"][0]["channels"] = {"kp": {"to": "kp", "unit": "mil"}}
    assert "[imbalance.runs][0].channels.kp unit 'mil' is a length, but kp is a voltage" in error_of(cfg)


def test_channel_to_and_calibration():
    cfg = imbalance_cfg()
    cfg["channels"]["Prox DE X"]["to"] = "X1"
    assert "to must be one of 'x1', 'x2', 'y1', 'y2', 'kp', 'force'" in error_of(cfg)
    assert "(did you mean 'x1'?)" in error_of(cfg)
    cfg = imbalance_cfg()
    cfg["channels"]["Prox DE X"]["scale"] = 0
    assert "[channels.\"Prox DE X\"] scale must be a non-zero number, got 0" in error_of(cfg)
    cfg = imbalance_cfg()
    cfg["channels"]["Keyphasor"]["delay_s"] = 1.5
    assert "delay_s must be a number between -1 and 1 (exclusive), got 1.5" in error_of(cfg)


def test_two_channels_to_one_target():
    cfg = imbalance_cfg()
    cfg["channels"]["Other"] = {"to": "x1", "unit": "um"}
    assert error_of(cfg) == "rig.toml: [channels] 'Prox DE X' and 'Other' both map to x1"


def test_table_unit_must_be_a_length():
    cfg = table_cfg()
    cfg["imbalance"]["table"]["unit"] = "V"
    assert "[imbalance.table] unit 'V' is a voltage, but the 1X amplitudes are lengths" in error_of(cfg)


def test_output_units():
    cfg = impact_cfg()
    cfg["output"] = {"units": "imperial"}
    assert error_of(cfg) == "rig.toml: [output] units must be one of 'SI', 'US' (any case), got 'imperial'"
    cfg["output"] = {"units": "us"}
    assert parse_config(cfg).output.units == "US"


def test_legacy_fs_hz_in_channels_moves_to_files():
    cfg = imbalance_cfg()
    cfg["channels"]["fs_hz"] = 10000
    c = parse_config(cfg)
    assert c.files.fs_hz == 10000.0 and "fs_hz" not in c.channels
    assert c.files_for(c.imbalance.runs[0])["fs_hz"] == 10000.0
    cfg["files"] = {"fs_hz": 5000}
    assert "fs_hz is given both in [channels]" in error_of(cfg)
    cfg = imbalance_cfg()
    cfg["channels"]["fs_hz"] = -1
    assert "[channels] fs_hz must be a number > 0" in error_of(cfg)


# ---------------------------------------------------------------------------------------------
# impact

def test_direction_exact_message():
    cfg = impact_cfg()
    cfg["impact"]["tests"][0]["direction"] = "Y"
    assert error_of(cfg) == "rig.toml: [impact.tests][0] direction must be one of 'x', 'y', got 'Y' (did you mean 'y'?)"


def test_band_hz_reversed():
    msg = error_of(impact_cfg(band_hz=[150.0, 5.0]))
    assert msg == "rig.toml: [impact] band_hz must be [lo, hi] in Hz with 0 < lo < hi, got [150.0, 5.0]"
    assert "band_hz" in error_of(impact_cfg(band_hz=[0, 100]))
    assert "band_hz" in error_of(impact_cfg(band_hz="5-150"))


def test_pre_s_not_below_record_s():
    assert error_of(impact_cfg(pre_s=0.25)) == "rig.toml: [impact] pre_s must be < record_s (0.25 s), got 0.25"
    assert "[impact] zero_pad_s must be >= record_s" in error_of(impact_cfg(zero_pad_s=0.1))


def test_test_needs_plane_and_direction():
    cfg = impact_cfg()
    del cfg["impact"]["tests"][0]["plane_m"]
    assert "[impact.tests][0] missing required key 'plane_m'" in error_of(cfg)


def test_impact_ranges():
    assert "coherence_min must be a number >= 0 and <= 1, got 1.5" in error_of(impact_cfg(coherence_min=1.5))
    assert "revs_before must be an integer >= 1, got 0" in error_of(impact_cfg(revs_before=0))
    assert "threshold_N must be a number > 0, got -3" in error_of(impact_cfg(threshold_N=-3))


# ---------------------------------------------------------------------------------------------
# 1X tables

def test_table_mode_valid_and_reader_kwargs():
    cfg = parse_config(table_cfg())
    kw = cfg.imbalance.table.reader_kwargs()
    assert kw["columns"] == COLUMNS
    assert (kw["amplitude"], kw["unit"], kw["phase"], kw["phase_unit"], kw["speed_column"]) == \
        ("pk-pk", "mil", "lag", "deg", "auto")
    assert cfg.imbalance.table.slow_roll_max_rpm == 400.0


def test_table_mode_needs_all_columns():
    cfg = table_cfg()
    del cfg["imbalance"]["table"]["columns"]["y2"]
    assert "[imbalance.table.columns] missing required key 'y2'" in error_of(cfg)


def test_table_mode_refuses_waveform_keys():
    cfg = table_cfg()
    cfg["imbalance"]["runs"][1]["keyphasor"] = {"level": 1.0}
    assert "[imbalance.runs][1] keyphasor has no meaning for a DAQ 1X table" in error_of(cfg)


def test_table_choices():
    cfg = table_cfg()
    cfg["imbalance"]["table"]["amplitude"] = "pp"
    assert "[imbalance.table] amplitude must be one of 'pk-pk', '0-pk', got 'pp'" in error_of(cfg)


# ---------------------------------------------------------------------------------------------
# files on disk

def write(path: Path, text: str) -> Path:
    path.write_text(text, encoding="utf-8")
    return path


RIG_TOML = '''[rig]
builtin = "nsf"

[imbalance]
baseline = "baseline.tdms"

[[imbalance.runs]]
file = "run_S0.tdms"
mass_g = [5.0, 5.0]
angle_deg = [0.0, 0.0]
'''


def test_missing_file_names_the_directory(tmp_path):
    cfg = write(tmp_path / "rig.toml", RIG_TOML)
    (tmp_path / "baseline.tdms").write_bytes(b"")
    msg = load_error(cfg)
    assert msg == f"{cfg}: [imbalance.runs][0] file 'run_S0.tdms' not found (looked in {tmp_path})"


def test_missing_plain_entry_and_blocks_and_times_file(tmp_path):
    cfg = write(tmp_path / "rig.toml", RIG_TOML.replace('file = "run_S0.tdms"', 'files = ["a.tdms", "sub/b.tdms"]')
                + '\n[keyphasor]\ntimes_file = "kp.npy"\n')
    (tmp_path / "a.tdms").write_bytes(b"")
    with pytest.raises(ConfigError) as info:
        load_config(cfg)
    check_message(info.value)
    probs = info.value.problems
    assert f"[keyphasor] times_file 'kp.npy' not found (looked in {tmp_path})" in probs
    assert f"[imbalance] baseline 'baseline.tdms' not found (looked in {tmp_path})" in probs
    assert f"[imbalance.runs][0] files[1] 'sub/b.tdms' not found (looked in {tmp_path / 'sub'}, which does not exist)" \
        in probs
    assert load_config(cfg, check_files=False).imbalance.runs[0].files == ("a.tdms", "sub/b.tdms")


def test_referenced_directory_is_not_a_file(tmp_path):
    cfg = write(tmp_path / "rig.toml", RIG_TOML)
    (tmp_path / "baseline.tdms").mkdir()
    (tmp_path / "run_S0.tdms").write_bytes(b"")
    assert "[imbalance] baseline 'baseline.tdms' is a directory, not a file" in load_error(cfg)


def test_paths_are_relative_to_the_config(tmp_path, monkeypatch):
    sub = tmp_path / "cfgs"
    sub.mkdir()
    cfg = write(sub / "rig.toml", RIG_TOML.replace('"run_S0.tdms"', '"../data/run_S0.tdms"'))
    (tmp_path / "data").mkdir()
    (tmp_path / "data" / "run_S0.tdms").write_bytes(b"")
    (sub / "baseline.tdms").write_bytes(b"")
    monkeypatch.chdir(tmp_path)
    c = load_config("cfgs/rig.toml")
    assert c.base_dir == sub and c.source == "cfgs/rig.toml"
    assert c.imbalance.runs[0].paths(c) == [tmp_path / "data" / "run_S0.tdms"]
    assert c.resolve(tmp_path / "x.csv") == tmp_path / "x.csv"


def test_config_is_a_directory(tmp_path):
    assert load_error(tmp_path) == f"{tmp_path}: is a directory, not a config file"


def test_config_not_found(tmp_path):
    p = tmp_path / "nope.toml"
    assert load_error(p) == f"{p}: config file not found (looked in {tmp_path})"


def test_config_not_utf8(tmp_path):
    p = tmp_path / "rig.toml"
    p.write_bytes(b'[rig]\nbuiltin = "nsf"\n# r\xe9glage\n')
    assert load_error(p) == f"{p}: not UTF-8 text (byte 0xe9 at line 3, column 4); save the config as UTF-8"


def test_invalid_toml_names_the_line(tmp_path):
    p = write(tmp_path / "rig.toml", '[rig]\nbuiltin = "nsf"\nsteady = \n')
    msg = load_error(p)
    assert msg.startswith(f"{p}: not valid TOML:") and "line 3" in msg


def test_old_config_doc_example_is_refused_with_a_line(tmp_path):
    # the old CONFIG_DOC example used ';' between keys, which TOML does not allow
    p = write(tmp_path / "rig.toml", "[rotor]\nmass_kg = 45.3; it_kgm2 = 0.704\n")
    assert "line 2" in load_error(p)


def test_windows_path_hint(tmp_path):
    p = write(tmp_path / "rig.toml", '[imbalance]\nbaseline = "C:\\data\\b.tdms"\n')
    assert "single quotes" in load_error(p)


def test_utf8_bom_is_accepted(tmp_path):
    p = tmp_path / "rig.toml"
    p.write_bytes(b"\xef\xbb\xbf" + RIG_TOML.encode())
    assert load_config(p, check_files=False).imbalance.runs[0].file == "run_S0.tdms"


# ---------------------------------------------------------------------------------------------
# several problems, the error type

def test_several_problems_in_one_line():
    cfg = imbalance_cfg(steady="false", min_revs=1, method="x", orders=[2])
    with pytest.raises(ConfigError) as info:
        parse_config(cfg, source="rig.toml")
    msg = check_message(info.value)
    assert len(info.value.problems) == 4 and msg.endswith("; and 1 more") and msg.count("; ") == 3
    assert info.value.source == "rig.toml"


def test_config_error_pickles():
    with pytest.raises(ConfigError) as info:
        parse_config({"rig": {"builtin": "nsf"}})
    back = pickle.loads(pickle.dumps(info.value))
    assert str(back) == str(info.value)


def test_not_a_table():
    assert error_of([1, 2]) == "rig.toml: a config must be a table of sections, got the array [1, 2]"


def test_section_missing():
    cfg = parse_config(impact_cfg(), source="rig.toml")
    with pytest.raises(ConfigError, match=r"rig.toml: no \[imbalance\] section \(the config has \[impact\]\)"):
        cfg.section("imbalance")
    assert cfg.section("impact") is cfg.impact


def test_weird_keys_stay_on_one_line():
    cfg = imbalance_cfg()
    cfg["imbalance"]["runs"][0]["bad\nkey\u2028"] = 1
    cfg["channels"]["a\nb"] = {"to": "x2", "unit": "furlong\r"}
    msg = error_of(cfg)
    assert "'bad\\nkey\\u2028'" in msg and '[channels."a\\nb"]' in msg


# ---------------------------------------------------------------------------------------------
# the helpers the pipeline uses

def test_channels_for():
    cfg = parse_config(rich_cfg())
    runs = cfg.imbalance.runs
    assert cfg.channels_for(runs[0]) == cfg.channels_for() == {
        "Prox DE X": {"to": "x1", "unit": "mil", "scale": 1.0, "offset": 0.0, "delay_s": 0.0},
        "Keyphasor": {"to": "kp", "unit": "V", "scale": 1.0, "offset": 0.0, "delay_s": 0.0}}
    assert cfg.channels_for(runs[1]) == {"DE X": {"to": "x1", "unit": "um", "scale": 2.0, "offset": 0.0,
                                                  "delay_s": 1e-4}}
    assert list(cfg.channels_for(runs[0], only={"kp"})) == ["Keyphasor"]


def test_files_for():
    cfg = parse_config(rich_cfg())
    assert cfg.files_for() == {"fs_hz": 10000.0, "fmt": None, "group": None, "skip_rows": None, "sep": ";",
                               "decimal": ",", "time_column": False}
    sr = cfg.imbalance.slow_roll
    assert cfg.files_for(sr)["group"] == "DAQ"
    assert [p.name for p in sr.paths(cfg)] == ["sr1.tdms", "sr2.tdms"]
    c2 = imbalance_cfg()
    c2["imbalance"]["runs"][0].update(format="tdms", skip_rows=3, time_column="Time", sep="\t")
    c2 = parse_config(c2)
    kw = c2.files_for(c2.imbalance.runs[0])
    assert (kw["fmt"], kw["skip_rows"], kw["time_column"], kw["sep"], kw["fs_hz"]) == ("tdms", 3, "Time", "\t", None)


def test_sep_equal_decimal_refused():
    cfg = imbalance_cfg()
    cfg["files"] = {"sep": ",", "decimal": ","}
    assert "[files] sep and decimal are both ','" in error_of(cfg)


def test_keyphasor_for():
    cfg = parse_config(rich_cfg())
    runs = cfg.imbalance.runs
    assert cfg.keyphasor_for(runs[0]) == {"level": 1.0, "hysteresis": None, "edge": "rising", "mark_angle_deg": 0.0,
                                          "tolerance": 0.3, "fill_missing": False, "refine": True,
                                          "max_speed_step": None, "times_file": None}
    assert cfg.keyphasor_for(runs[1])["level"] == 2.5
    assert cfg.keyphasor_for()["fill_missing"] is True
    c2 = imbalance_cfg()
    c2["imbalance"]["runs"][0]["keyphasor"] = {"times_file": "kp/S0.npy", "level": "auto"}
    c2["keyphasor"] = {"level": 3.0}
    c2 = parse_config(c2, base_dir="/lab")
    kw = c2.keyphasor_for(c2.imbalance.runs[0])
    assert kw["level"] is None and kw["times_file"] == Path("/lab/kp/S0.npy")


def test_keyphasor_ranges():
    cfg = imbalance_cfg()
    cfg["keyphasor"] = {"tolerance": 1.0, "edge": "up", "hysteresis": -1}
    with pytest.raises(ConfigError) as info:
        parse_config(cfg)
    probs = info.value.problems
    assert "[keyphasor] tolerance must be a number > 0 and < 1, got 1.0" in probs
    assert "[keyphasor] edge must be one of 'auto', 'rising', 'falling', got 'up'" in probs
    assert "[keyphasor] hysteresis must be 'auto' or a number >= 0, got -1" in probs


def test_run_meta_and_masses():
    cfg = parse_config(imbalance_cfg())
    r0, r1, r2 = cfg.imbalance.runs
    assert r0.mass_kg() == (0.005, 0.005) and r2.mass_kg() == (0.005, 0.005)
    assert r0.imbalance_meta() == {"mass_kg": [0.005, 0.005], "angle_deg": [0.0, 0.0], "name": "S0"}
    assert r1.meta() == {"name": "C0", "imbalance": {"mass_kg": [0.005, 0.005], "angle_deg": [0.0, 180.0],
                                                     "name": "C0"}}
    plain = parse_config(imbalance_cfg(runs=["only.tdms"])).imbalance.runs[0]
    assert plain.mass_kg() is None and plain.imbalance_meta() is None and plain.meta() == {}
    assert plain.groups is None


def test_test_meta():
    cfg = impact_cfg()
    cfg["impact"]["tests"][1].update(probes_at="bearings", name="B")
    t = parse_config(cfg).impact.tests[1]
    assert t.meta() == {"probes_at": "bearings", "plane": 0.0, "direction": "y", "name": "B"}


def test_defaults():
    cfg = parse_config(impact_cfg())
    imp = cfg.impact
    assert (imp.record_s, imp.pre_s, imp.runout, imp.revs_before, imp.points_per_rev, imp.coherence_min,
            imp.cond_max, imp.min_rel_amplitude, imp.identical, imp.method) == \
        (0.25, 0.01, True, 8, 256, 0.9, 1e4, 0.01, False, "forces")
    imb = parse_config(imbalance_cfg()).imbalance
    assert (imb.min_revs, imb.settle_revs, imb.speed_tolerance, imb.revs_per_block, imb.speed_match_rpm,
            imb.cond_max, imb.min_rel_amplitude, imb.points_per_rev) == (8, 2, 0.005, 4, None, 1e4, 0.08, "auto")
    assert cfg.output_dir("impact") == Path.cwd() / "rotorid_impact"


def test_config_is_immutable():
    cfg = parse_config(impact_cfg())
    with pytest.raises(Exception):
        cfg.impact.record_s = 1.0


def test_entries():
    cfg = parse_config(rich_cfg())
    locs = [loc for loc, _ in cfg.entries()]
    assert locs[:3] == [("imbalance", "runs", 0), ("imbalance", "runs", 1), ("imbalance", "runs", 2)]
    assert ("imbalance", "slow_roll") in locs and ("impact", "tests", 1) in locs


# ---------------------------------------------------------------------------------------------
# property tests: nothing but a one-line ConfigError, ever

KEYS = all_keys()
BASES = [imbalance_cfg, impact_cfg, rich_cfg, table_cfg]

toml_scalars = st.one_of(
    st.booleans(), st.integers(min_value=-2**63, max_value=2**63 - 1),
    st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=12),
    st.dates(), st.datetimes(), st.times())
toml_values = st.recursive(toml_scalars, lambda inner: st.one_of(
    st.lists(inner, max_size=4), st.dictionaries(st.text(max_size=6), inner, max_size=3)), max_leaves=8)


def schema_tables(node, loc=()):
    """Locations of every dict that is a schema table (channel maps are name -> spec, not schema)."""
    out = []
    if isinstance(node, dict):
        if not (loc and loc[-1] == "channels"):
            out.append(loc)
        for k, v in node.items():
            out += schema_tables(v, loc + (k,))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            out += schema_tables(v, loc + (i,))
    return out


def nodes(node, loc=()):
    """Every location below the root (tables, arrays and leaves)."""
    out = [loc] if loc else []
    if isinstance(node, dict):
        out += [x for k, v in node.items() for x in nodes(v, loc + (k,))]
    elif isinstance(node, list):
        out += [x for i, v in enumerate(node) for x in nodes(v, loc + (i,))]
    return out


def at(node, loc):
    for k in loc:
        node = node[k]
    return node


@pytest.mark.parametrize("base", BASES, ids=lambda f: f.__name__)
def test_bases_are_valid(base):
    parse_config(base())


@settings(suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data(), key=st.text(max_size=15), value=toml_values)
def test_random_extra_keys_anywhere_are_rejected(data, key, value):
    assume(key not in KEYS)
    cfg = data.draw(st.sampled_from(BASES))()
    loc = data.draw(st.sampled_from(schema_tables(cfg)))
    table = at(cfg, loc)
    assume(key not in table)
    table[key] = value
    with pytest.raises(ConfigError) as info:
        parse_config(cfg, source="rig.toml")
    msg = check_message(info.value)
    assert repr(key) in msg
    assert "unknown" in msg


def toml_key(key: str) -> str:
    esc = "".join(f"\\u{ord(c):04x}" if ord(c) < 0x20 or c in '"\\\x7f' else c for c in key)
    return f'"{esc}"'


@settings(suppress_health_check=[HealthCheck.too_slow])
@given(key=st.text(min_size=1, max_size=15), section=st.sampled_from(["imbalance", "[imbalance.runs]", "output",
                                                                         "keyphasor", "files", "rig", ""]))
def test_random_extra_keys_in_a_toml_file(key, section):
    assume(key not in KEYS)
    text = RIG_TOML + "\n[keyphasor]\n[files]\n[output]\n"
    if section:  # right after the table's header; "" is the top level
        head = f"[{section}]\n"
        assert head in text
        text = text.replace(head, head + f"{toml_key(key)} = 1\n", 1)
    else:
        text = f"{toml_key(key)} = 1\n" + text
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "rig.toml"
        path.write_text(text, encoding="utf-8")
        with pytest.raises(ConfigError) as info:
            load_config(path, check_files=False)
    msg = check_message(info.value)
    assert repr(key) in msg and msg.startswith(f"{path}: ")


@settings(suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data(), value=toml_values)
def test_random_values_anywhere_give_a_config_or_a_one_line_error(data, value):
    cfg = data.draw(st.sampled_from(BASES))()
    loc = data.draw(st.sampled_from(nodes(cfg)))
    parent = at(cfg, loc[:-1])
    parent[loc[-1]] = value
    try:
        parse_config(cfg, source="rig.toml")
    except ConfigError as exc:
        check_message(exc)


@settings(suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_random_deletions_give_a_config_or_a_one_line_error(data):
    cfg = data.draw(st.sampled_from(BASES))()
    loc = data.draw(st.sampled_from(nodes(cfg)))
    del at(cfg, loc[:-1])[loc[-1]]
    try:
        parse_config(cfg, source="rig.toml")
    except ConfigError as exc:
        msg = check_message(exc)
        assert re.match(r"rig\.toml: ", msg)


def test_override_file_unit_in_a_channel_map():
    cfg = imbalance_cfg()
    cfg["channels"] = {"Prox DE X": {"to": "x1", "unit": "um", "override_file_unit": True}}
    assert parse_config(cfg).channels_for()["Prox DE X"]["override_file_unit"] is True
    cfg["channels"] = {"Prox DE X": {"to": "x1", "override_file_unit": True}}
    assert "override_file_unit = true needs the unit that replaces the file's" in error_of(cfg)
    cfg["channels"] = {"Prox DE X": {"to": "x1", "unit": "um", "override_file_unit": "yes"}}
    assert "override_file_unit must be true or false, got the string 'yes'" in error_of(cfg)


def test_angle_deg_of_probes_in_a_channel_map():
    cfg = imbalance_cfg()
    cfg["channels"] = {"DE L": {"to": "x1", "unit": "um", "angle_deg": 45.0},
                       "DE R": {"to": "y1", "unit": "um", "angle_deg": 135}}
    chans = parse_config(cfg).channels_for()
    assert chans["DE L"]["angle_deg"] == 45.0 and chans["DE R"]["angle_deg"] == 135.0
    cfg["channels"] = {"Prox DE X": {"to": "x1", "unit": "mil"}}
    assert "angle_deg" not in parse_config(cfg).channels_for()["Prox DE X"]
    cfg["channels"] = {"KP": {"to": "kp", "angle_deg": 10.0}}
    assert "angle_deg is the measuring direction of a probe or housing accelerometer" in error_of(cfg)
    cfg["channels"] = {"DE L": {"to": "x1", "angle_deg": "45"}}
    assert "angle_deg" in error_of(cfg)
    cfg["channels"] = {"DE L": {"to": "x1", "angle_deg": float("nan")}}
    assert "angle_deg" in error_of(cfg)


def test_angle_deg_of_probes_in_1x_table_columns():
    cfg = table_cfg()
    cfg["imbalance"]["table"]["columns"]["x1"]["angle_deg"] = 45
    cfg["imbalance"]["table"]["columns"]["y1"]["angle_deg"] = 135.0
    kw = parse_config(cfg).imbalance.table.reader_kwargs()
    assert kw["columns"]["x1"] == {"amplitude": "x1 amp", "phase": "x1 phase", "angle_deg": 45.0}
    assert "angle_deg" not in kw["columns"]["x2"]
    cfg["imbalance"]["table"]["columns"]["y1"]["angle_deg"] = "135"
    assert "angle_deg must be a number" in error_of(cfg)


def test_probe_angles_that_cannot_be_resolved_are_refused_by_the_config_check():
    """``rotorid check`` said "valid" for probes within 20° of parallel, which only failed when
    the files were read (review); angles beyond one turn and out-of-range integers are refused."""
    cfg = imbalance_cfg()
    cfg["channels"] = {"DE A": {"to": "x1", "angle_deg": 45}, "DE B": {"to": "y1", "angle_deg": 55}}
    assert "[channels] x1 (angle_deg 45) and y1 (angle_deg 55) are within 20° of parallel" in error_of(cfg)
    cfg["channels"] = {"DE A": {"to": "x1", "angle_deg": 80}, "y1": {"to": "y1"}}   # y1 at its default 90°
    assert "x1 (angle_deg 80) and y1 (angle_deg 90) are within 20° of parallel" in error_of(cfg)
    cfg["channels"] = {"DE A": {"to": "x1", "angle_deg": 45}}                        # no partner here: the files say
    parse_config(cfg)
    for bad in (400, -361, 10 ** 400):
        cfg["channels"] = {"DE A": {"to": "x1", "angle_deg": bad}}
        assert "angle_deg must be a number >= -360 and <= 360" in error_of(cfg)
    tab = table_cfg()
    tab["imbalance"]["table"]["columns"]["x2"]["angle_deg"] = 100.0
    tab["imbalance"]["table"]["columns"]["y2"]["angle_deg"] = 270.0
    assert "[imbalance.table.columns] x2 (angle_deg 100) and y2 (angle_deg 270) are within 20° of parallel" in \
        error_of(tab)
