"""Identification results as xarray / NetCDF, Excel and JSON (issue 14, item 2)."""

import json

import numpy as np
import pandas as pd
import pytest

import rotorid
from rotorid import RotoridError
from rotorid.model import REPORT_ORDER
from rotorid.units import from_si

LBF_IN = 4.4482216152605 / 0.0254


@pytest.fixture(scope="module")
def ident():
    from noisy import noisy_nsf_runs

    rig, runs = noisy_nsf_runs([3000.0, 3500.0, 4000.0, 4500.0], "ABC", seed=2)
    return rotorid.identify_synchronous(rig.rotor, runs)


def test_xarray_holds_the_coefficients_with_their_uncertainty(ident):
    ds = ident.to_xarray()
    np.testing.assert_array_equal(ds.K.values, ident.k)
    np.testing.assert_array_equal(ds.C_std.values, ident.c_std)
    iv = ident.interval(0.95)
    np.testing.assert_array_equal(ds.K_lower.values, iv.k_lower)
    assert ds.K.attrs["units"] == "N/m" and ds.C.attrs["units"] == "N*s/m"
    assert ds.speed_rpm.attrs["units"] == "rpm" and ds.attrs["std_source"] == ident.std_source
    # labels select what [bearing, i, j] indexes
    assert float(ds.K.sel(speed_rpm=3500.0, bearing=2, i="y", j="x")) == ident.k[1, 1, 1, 0]
    us = ident.to_xarray(units="US")
    np.testing.assert_allclose(us.K.values * LBF_IN, ident.k, rtol=1e-12)
    assert us.K.attrs["units"] == "lbf/in"
    np.testing.assert_array_equal(ident.to_xarray(level=0.68).K_upper.values, ident.interval(0.68).k_upper)


def test_netcdf_round_trip(tmp_path, ident):
    import xarray as xr

    p = ident.to_netcdf(tmp_path / "k.nc")
    with xr.open_dataset(p, engine="scipy") as ds:
        np.testing.assert_allclose(ds.K.values, ident.k, rtol=1e-15)
        np.testing.assert_allclose(ds.C_upper.values, ident.interval(0.95).c_upper, rtol=1e-15)
        assert [bool(v) for v in ds.ok.values] == list(ident.ok)
        assert ds.K.attrs["units"] == "N/m"
    with pytest.raises(RotoridError, match="exists; pass overwrite=True"):
        ident.to_netcdf(tmp_path / "k.nc")
    ident.to_netcdf(tmp_path / "k.nc", overwrite=True)


@pytest.mark.parametrize("units", ["SI", "US"])
def test_excel_round_trip_with_units_row(tmp_path, ident, units):
    p = ident.to_excel(tmp_path / "k.xlsx", units=units)
    head = pd.read_excel(p, sheet_name="coefficients", nrows=1)
    assert head["Kxy2"][0] == ("N/m" if units == "SI" else "lbf/in")
    assert head["speed_rpm"][0] == "rpm"
    sheet = pd.read_excel(p, sheet_name="coefficients", skiprows=[1])
    ref = ident.to_dataframe()
    for name in REPORT_ORDER:
        unit = "lbf/in" if name[0] == "K" else "lbf*s/in"
        for col in (name, f"{name}_std", f"{name}_lo95"):
            want = ref[col].to_numpy(float) if units == "SI" else from_si(ref[col].to_numpy(float), unit)
            np.testing.assert_allclose(sheet[col].to_numpy(float), want, rtol=1e-12, err_msg=col)
    assert list(sheet["ok"]) == list(ident.ok)
    about = pd.read_excel(p, sheet_name="about")
    assert dict(zip(about["item"], about["value"]))["unit_system"] == units
    with pytest.raises(RotoridError, match="exists"):
        ident.to_excel(p, units=units)


def test_json_round_trip(tmp_path, ident):
    doc = json.loads(ident.to_json())
    np.testing.assert_allclose(np.array(doc["K"], float), ident.k, rtol=1e-15)
    np.testing.assert_allclose(np.array(doc["C_std"], float), ident.c_std, rtol=1e-15)
    assert doc["ok"] == [bool(v) for v in ident.ok] and doc["axis_name"] == "speed_rpm"
    p = ident.to_json(tmp_path / "k.json", units="US")
    us = json.loads(open(p, encoding="utf-8").read())
    np.testing.assert_allclose(np.array(us["K"], float) * LBF_IN, ident.k, rtol=1e-12)
    assert us["units"]["C"] == "lbf*s/in"


def test_unknown_uncertainty_is_null_in_json_and_nan_elsewhere():
    rig = rotorid.nsf_rig()
    runs = [rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances[s], speed_rpm=[3000.0]) for s in "AB"]
    ident = rotorid.identify_synchronous(rig.rotor, runs)            # two runs, no covariance: std unknown
    doc = json.loads(ident.to_json())
    assert doc["K_std"][0][0][0][0] is None
    assert np.isnan(ident.to_xarray().K_std.values).all()


@pytest.mark.parametrize("call, match", [
    (lambda i, t: i.to_excel(t / "k.csv"), "must end in .xlsx"),
    (lambda i, t: i.to_json(t / "missing" / "k.json"), "folder of"),
    (lambda i, t: i.to_json(t / "k.json", units="imperial"), "units must be 'SI' or 'US'"),
    (lambda i, t: i.to_xarray(level=1.5), "level"),
    (lambda i, t: i.to_netcdf(3.0), "path"),
    (lambda i, t: i.to_excel(t / "k.xlsx", overwrite="yes"), "overwrite"),
])
def test_bad_arguments(tmp_path, ident, call, match):
    with pytest.raises(RotoridError, match=match):
        call(ident, tmp_path)


def test_a_folder_is_not_overwritten(tmp_path, ident):
    (tmp_path / "d.json").mkdir()
    with pytest.raises(RotoridError, match="folder"):
        ident.to_json(tmp_path / "d.json", overwrite=True)


def test_impact_results_export_over_frequency(tmp_path):
    rig = rotorid.nsf_rig()
    f = np.arange(20.0, 60.0, 10.0)
    tests = [rotorid.impact_frf(rig.rotor, rig.bearings, speed_rpm=1000, freq_hz=f, direction=d) for d in "xy"]
    ident = rotorid.identify_impact(rig.rotor, tests)
    ds = ident.to_xarray()
    assert ds.K.dims[0] == "freq_hz" and ds.freq_hz.attrs["units"] == "Hz"
    assert json.loads(ident.to_json())["units"]["freq_hz"] == "Hz"
    sheet = pd.read_excel(ident.to_excel(tmp_path / "i.xlsx"), sheet_name="coefficients", skiprows=[1])
    np.testing.assert_allclose(sheet["freq_hz"], f)


def test_config_output_formats(tmp_path):
    import os
    import warnings

    from rotorid import pipeline
    from rotorid.config import ConfigError, parse_config

    from rotorid import example

    ex = example.copy_example(str(tmp_path / "ex"))
    cfg = os.path.join(ex, "imbalance.toml")
    text = open(cfg, encoding="utf-8").read().replace('units = "SI"', 'units = "US"\nformats = ["xlsx", "json", "nc"]')
    open(cfg, "w", encoding="utf-8").write(text)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ident, files = pipeline.run_config(cfg, "imbalance", out_dir=str(tmp_path / "out"), log=lambda m: None)
    names = {os.path.basename(f) for f in files}
    assert {"coefficients_imbalance.xlsx", "coefficients_imbalance.json", "coefficients_imbalance.nc"} <= names
    doc = json.loads(open(tmp_path / "out" / "coefficients_imbalance.json", encoding="utf-8").read())
    assert doc["units"]["K"] == "lbf/in"
    np.testing.assert_allclose(np.array(doc["K"], float) * LBF_IN, ident.k, rtol=1e-12)
    base = {"rig": {"builtin": "nsf"}, "imbalance": {"runs": ["a.tdms"]}}
    for bad, match in ((["xlsx", "xlsx"], "twice"), (["pdf"], "formats")):
        with pytest.raises(ConfigError, match=match):
            parse_config({**base, "output": {"formats": bad}})
