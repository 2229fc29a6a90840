"""rotorid predict CONFIG: series supports from a bearing table and a damper, as rotorid compare reads."""

import os

import numpy as np
import pandas as pd
import pytest
from pydantic import BaseModel

import rotorid.demo as demo
from rotorid import cli
from rotorid.config import ConfigError
from rotorid.model import REPORT_ORDER
from rotorid.support import config as PC
from rotorid.support.compare import predict_coefficients
import rotorid.errors as rotorid_errors
import rotorid.support as rotorid_support

DOCS = os.path.join(os.path.dirname(__file__), "..", "docs")


def _write_table(path):
    t = demo.illustrative_tpjb()
    rows = []
    for i, s in enumerate(t.speed_rpm):
        for j, r in enumerate(t.freq):
            row = dict(speed_rpm=s, freq_ratio=r)
            for a, (p, q) in zip(("xx", "xy", "yx", "yy"), ((0, 0), (0, 1), (1, 0), (1, 1))):
                row[f"K{a}"], row[f"C{a}"] = t.k[i, j, p, q], t.c[i, j, p, q]
            rows.append(row)
    pd.DataFrame(rows).to_csv(path, index=False)
    return t


CONFIG = """
[[supports]]
journal_mass_kg = 1.5
bearing = {{ file = "fpjb.csv", freq_axis = "ratio" }}
damper = {{ builtin = "nsf", spring_stiffness_n_m = 3.75e6 }}

[[supports]]
journal_mass_kg = 2.0
bearing = {{ file = "fpjb.csv", freq_axis = "ratio" }}
damper = {{ radius_m = 0.048, clearance_m = 2.3e-4, length_m = 0.023, n_lands = 4, land_extent_deg = 52.0, viscosity_pa_s = 0.0158, spring_stiffness_n_m = [[4.0e6, 0.0], [0.0, 4.4e6]] }}

[predict]
{predict}

[output]
units = "{units}"
"""


def _config(tmp_path, predict='kind = "synchronous"\nspeeds_rpm = { start = 1000, stop = 6000, step = 500 }',
            units="SI", name="predict.toml"):
    _write_table(tmp_path / "fpjb.csv")
    p = tmp_path / name
    p.write_text(CONFIG.format(predict=predict, units=units))
    return p


@pytest.mark.parametrize("units", ["SI", "US"])
def test_predicted_table_is_predict_coefficients(tmp_path, units, recwarn):
    path = _config(tmp_path, units=units)
    cfg = PC.load_predict_config(path)
    k, c = predict_coefficients(cfg.build_supports(), speed_rpm=np.arange(1000.0, 6001.0, 500.0))
    assert cli.main(["predict", str(path)]) == 0
    df = pd.read_csv(tmp_path / "rotorid_predict_synchronous" / "predicted_synchronous.csv")
    col = "Kxx1" if units == "SI" else "Kxx1_lbf_per_in"
    scale = 1.0 if units == "SI" else 0.0254 / 4.4482216152605
    np.testing.assert_allclose(df[col], k[:, 0, 0, 0] * scale, rtol=1e-5)
    np.testing.assert_allclose(df["speed_rpm"], np.arange(1000.0, 6001.0, 500.0))
    # the two supports differ (other spring, mass, damper geometry)
    assert np.abs(k[:, 0] - k[:, 1]).max() > 1e-3 * np.abs(k).max()


def test_frequency_kind_and_compare(tmp_path, recwarn):
    path = _config(tmp_path, predict='kind = "frequency"\nspeed_rpm = 3000\nfreq_hz = [10.0, 50.0, 100.0, 140.0]')
    assert cli.main(["predict", str(path), "--out", str(tmp_path / "p")]) == 0
    df = pd.read_csv(tmp_path / "p" / "predicted_frequency.csv")
    assert list(df.columns) == ["freq_hz", "speed_rpm"] + list(REPORT_ORDER)
    assert np.all(df.speed_rpm == 3000.0)
    assert cli.main(["predict", str(path), "--out", str(tmp_path / "p")]) == 1     # no overwrite unasked
    assert cli.main(["check", str(path)]) == 0


@pytest.mark.parametrize("edit, match", [
    (lambda t: t.replace("spring_stiffness_n_m = 3.75e6", "radius_m = 0.05"), "spring_stiffness_n_m"),
    (lambda t: t.replace('builtin = "nsf", ', 'builtin = "nsf", radius_m = 0.05, '), "fixes the geometry"),
    (lambda t: t.replace("n_lands = 4, ", ""), "needs n_lands"),
    (lambda t: t.replace("clearance_m = 2.3e-4", "clearance_m = -2.3e-4"), "clearance_m"),
    (lambda t: t.replace("journal_mass_kg = 1.5", "journal_mass_kg = -1.5"), "journal_mass_kg"),
    (lambda t: t.replace('kind = "synchronous"', 'kind = "frequency"'), "needs speed_rpm"),
    (lambda t: t.replace('kind = "synchronous"', 'kind = "synchronous"\nfreq_hz = [10.0]'), "speeds_rpm only"),
    (lambda t: t.replace('{ file = "fpjb.csv", freq_axis = "ratio" }', '{ file = "missing.csv" }', 1),
     "does not exist"),
    (lambda t: t.replace("[[supports]]\njournal_mass_kg = 2.0", "[[other]]\njournal_mass_kg = 2.0"), "supports"),
    (lambda t: t.replace("land_extent_deg = 52.0", "land_extent_deg = 400.0"), "land_extent_deg"),
    (lambda t: t + "\n[extra]\nx = 1\n", "extra"),
])
def test_bad_configs_are_one_line_errors(tmp_path, capsys, edit, match):
    path = _config(tmp_path)
    text = path.read_text()
    edited = edit(text)
    assert edited != text, "the edit did not apply"
    path.write_text(edited)
    with pytest.raises(ConfigError, match=match):
        PC.load_predict_config(path)
    assert cli.main(["predict", str(path)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "error" in err


def test_every_key_is_documented():
    models = [m for m in vars(PC).values() if isinstance(m, type) and issubclass(m, BaseModel)
              and m.__module__ == PC.__name__]
    keys = {(f.alias or n) for m in models for n, f in m.model_fields.items()}
    doc = open(os.path.join(DOCS, "config.md"), encoding="utf-8").read()
    section = doc[doc.index("## Prediction configs"):]
    missing = sorted(k for k in keys if f"`{k}`" not in section and f"[{k}]" not in section and f"[[{k}]]" not in section)
    assert not missing, f"keys missing from docs/config.md 'Prediction configs': {missing}"


@pytest.mark.parametrize("edit, match", [
    (lambda t: t.replace("n_lands = 4, land_extent_deg = 52.0", "n_lands = 8, land_extent_deg = 52.0"),
     r"\[\[supports\]\] 2 damper:.*360"),
    (lambda t: t.replace('{ file = "fpjb.csv", freq_axis = "ratio" }',
                         '{ file = "fpjb.csv", freq_axis = "ratio", stiffness_unit = "kg" }', 1),
     r"\[\[supports\]\] 1 bearing 'fpjb.csv':.*stiffness"),
    (lambda t: t.replace('{ file = "fpjb.csv", freq_axis = "ratio" }', '{ file = "fpjb.csv" }', 1),
     r"\[\[supports\]\] 1 bearing"),
    (lambda t: t.replace("stop = 6000", "stop = 20000"), r"\[\[supports\]\] 1 at the \[predict\] points"),
    (lambda t: t.replace("[[4.0e6, 0.0], [0.0, 4.4e6]]", "[[4.0e6, 0.0], [0.0, -4.4e6]]"), "direct stiffnesses"),
])
def test_check_finds_what_predict_would(tmp_path, capsys, edit, match):
    """Problems inside the models and tables are found by rotorid check too, each naming its support."""
    path = _config(tmp_path)
    text = path.read_text()
    edited = edit(text)
    assert edited != text
    path.write_text(edited)
    with pytest.raises(ConfigError, match=match):
        PC.load_predict_config(path)
    assert cli.main(["check", str(path)]) == 1
    assert capsys.readouterr().err.count("\n") == 1


def test_impacts_at_standstill_can_be_predicted(tmp_path, recwarn):
    t = demo.illustrative_tpjb()
    from rotorid.support.tpjb import BearingTable

    hz = BearingTable(np.array([0.0, 3000.0]), np.array([5.0, 150.0]), t.k[[0, 3]][:, [2, 5]], t.c[[0, 3]][:, [2, 5]])
    cfg = PC.parse_predict_config({"supports": [{"bearing": {"file": "x.csv"}, "journal_mass_kg": 1.0,
                                                 "damper": {"builtin": "nsf", "spring_stiffness_n_m": 4e6}}] * 2,
                                   "predict": {"kind": "frequency", "speed_rpm": 0, "freq_hz": [10.0, 20.0]}})
    sup = [rotorid_support.SeriesSupport(hz, cfg.supports[0].damper.build(), 1.0)] * 2
    k, c = predict_coefficients(sup, speed_rpm=0.0, freq_hz=[10.0, 20.0])
    assert np.all(np.isfinite(k)) and np.all(np.isfinite(c))
    with pytest.raises(rotorid_errors.RotoridError, match="speeds > 0"):
        predict_coefficients(sup, speed_rpm=[0.0, 100.0])
