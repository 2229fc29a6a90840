"""Predicted series-support coefficients next to identified ones (issue 13, item 4)."""

import os

import numpy as np
import pandas as pd
import pytest

import rotorid
from rotorid import RotoridError, cli, plot
from rotorid.model import REPORT_ORDER, _REPORT_TO_BIJ
from rotorid.support.compare import SeriesSupport, compare, compare_tables, predict_coefficients

W50 = 2 * np.pi * 50.0


def _supports():
    film = [np.diag([1.2e7, 1.5e7]) + 1j * W50 * np.diag([800.0, 900.0]),
            np.diag([1.0e7, 1.3e7]) + 1j * W50 * np.diag([700.0, 750.0])]
    damper = [np.diag([3.0e6, 3.5e6]), np.diag([3.2e6, 3.6e6])]

    class Damper:
        """A damper whose impedance depends on frequency (viscous film): K + j w C."""

        def __init__(self, k, c):
            self.k, self.c = k, c

        def impedance(self, freq_hz):
            w = 2 * np.pi * np.asarray(freq_hz)
            return self.k[None] + 1j * w[:, None, None] * self.c[None]

    return [SeriesSupport(film[b], Damper(damper[b], np.diag([2000.0, 2200.0])), 1.5, f"bearing {b + 1}")
            for b in range(2)]


def test_predicted_coefficients_are_the_series_impedance():
    sup = _supports()
    rpm = np.array([2000.0, 4000.0, 6000.0])
    k, c = predict_coefficients(sup, speed_rpm=rpm)
    w = 2 * np.pi * rpm / 60
    for b in range(2):
        zb = np.broadcast_to(sup[b].bearing, (3, 2, 2))
        zd = sup[b].damper.impedance(rpm / 60)
        d = zd - (w ** 2 * 1.5)[:, None, None] * np.eye(2)
        z = d @ np.linalg.solve(zb + d, zb)
        np.testing.assert_allclose(k[:, b] + 1j * w[:, None, None] * c[:, b], z, rtol=1e-12)
    # impacts: one running speed, the frequencies of the FRFs; the same w gives the same Z here
    # (nothing in these supports depends on speed), a different w a different one
    ki, ci = predict_coefficients(sup, speed_rpm=3000.0, freq_hz=rpm / 60)
    np.testing.assert_allclose(ki, k, rtol=1e-12)
    assert np.abs(k[0] - k[2]).max() > 1e-3 * np.abs(k).max()


def test_identified_from_series_supports_agree_with_the_prediction():
    """The NSF rotor on series supports: the synchronous identification of exact responses agrees
    with the prediction at every speed (z ~ 0, all inside)."""
    rig = rotorid.nsf_rig()
    sup = _supports()
    rpm = np.arange(2500.0, 7001.0, 250.0)
    k, c = predict_coefficients(sup, speed_rpm=rpm)
    brg = rotorid.BearingCoefficients(k, c, speed_rpm=rpm)
    runs = [rotorid.imbalance_response(rig.rotor, brg, rig.imbalances[s], speed_rpm=rpm) for s in "ABCD"]
    for r in runs:
        r.cov = np.broadcast_to(np.eye(8) * (0.05e-6) ** 2, (rpm.size, 8, 8))
    ident = rotorid.identify_synchronous(rig.rotor, runs)
    cmp = compare(ident, k, c)
    assert np.all(np.abs(cmp.z[np.isfinite(cmp.z)]) < 1e-4)
    assert cmp.inside[np.isfinite(cmp.std)].all()
    # a prediction 20 % off in Kxx1 shows up in units of the identified uncertainty
    k_off = k.copy()
    k_off[:, 0, 0, 0] *= 1.2
    bad = compare(ident, k_off, c)
    j = REPORT_ORDER.index("Kxx1")
    assert np.median(np.abs(bad.z[:, j])) > 3 and np.all(bad.z[:, j] > 0)
    s = bad.summary().set_index("coefficient")
    assert s.loc["Kxx1", "median_rel_difference"] == pytest.approx(0.2, rel=1e-6)
    assert s.loc["Kxx2", "median_abs_z"] < 1e-4
    plot.comparison(bad, path=None)


def _tables(tmp_path, ident, k, c, us=False):
    df = ident.to_dataframe()
    pred = {"speed_rpm": ident.axis}
    rv_k, rv_c = k.reshape(-1, 8)[:, _REPORT_TO_BIJ], c.reshape(-1, 8)[:, _REPORT_TO_BIJ]
    for j, n in enumerate(REPORT_ORDER):
        pred[n] = (rv_k if j < 8 else rv_c)[:, j % 8]
    pred = pd.DataFrame(pred)
    if us:
        from rotorid.units import from_si

        def to_us(d):
            ren = {}
            for col in list(d.columns):
                if col[:1] in "KC" and col[1:3] in ("xx", "xy", "yx", "yy"):
                    unit, tag = ("lbf/in", "_lbf_per_in") if col[0] == "K" else ("lbf*s/in", "_lbf_s_per_in")
                    d[col] = from_si(d[col], unit)
                    ren[col] = col + tag
            return d.rename(columns=ren)

        df, pred = to_us(df), to_us(pred)
    ip, pp = tmp_path / f"ident{'_us' if us else ''}.csv", tmp_path / f"pred{'_us' if us else ''}.csv"
    df.to_csv(ip, index=False)
    pred.to_csv(pp, index=False)
    return ip, pp


@pytest.fixture(scope="module")
def identified():
    from noisy import noisy_nsf_runs

    rpm = np.arange(3000.0, 6001.0, 500.0)
    rig, runs = noisy_nsf_runs(rpm, "ABCD", seed=3)
    ident = rotorid.identify_synchronous(rig.rotor, runs)
    k, c = rig.bearings.at()
    return ident, np.repeat(k, rpm.size, 0) * 1.05, np.repeat(c, rpm.size, 0)


@pytest.mark.parametrize("us", [False, True])
def test_tables_in_si_and_us_give_the_comparison_of_the_objects(tmp_path, identified, us):
    ident, k, c = identified
    ip, pp = _tables(tmp_path, ident, k, c, us=us)
    a, b = compare(ident, k, c), compare_tables(ip, pp)
    np.testing.assert_allclose(b.identified, a.identified, rtol=1e-5)
    np.testing.assert_allclose(b.predicted, a.predicted, rtol=1e-5)
    np.testing.assert_allclose(b.z, a.z, rtol=1e-3, atol=1e-3)
    np.testing.assert_array_equal(b.ok, a.ok)


def test_cli_compare(tmp_path, identified, capsys):
    ident, k, c = identified
    ip, pp = _tables(tmp_path, ident, k, c)
    out = tmp_path / "cmp"
    assert cli.main(["compare", str(ip), str(pp), "--out", str(out)]) == 0
    assert {"comparison.csv", "comparison_summary.csv", "comparison.png"} <= set(os.listdir(out))
    assert "compared 7 points" in capsys.readouterr().out
    assert cli.main(["compare", str(ip), str(pp), "--out", str(out)]) == 1          # no overwrite unasked
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--overwrite" in err
    assert cli.main(["compare", str(ip), str(pp), "--out", str(out), "--overwrite"]) == 0


@pytest.mark.parametrize("edit, match", [
    (lambda d: d.drop(columns=["Kxy2"]), "no column 'Kxy2'"),
    (lambda d: d.rename(columns={"speed_rpm": "freq_hz"}), "no speed_rpm column"),
    (lambda d: d.iloc[2:], "extend the predicted table"),
    (lambda d: d.iloc[::-1], "strictly increasing"),
    (lambda d: d.assign(Cxx1=np.nan), "NaN"),
])
def test_bad_predicted_tables(tmp_path, identified, capsys, edit, match):
    ident, k, c = identified
    ip, pp = _tables(tmp_path, ident, k, c)
    edit(pd.read_csv(pp)).to_csv(pp, index=False)
    with pytest.raises(RotoridError, match=match):
        compare_tables(ip, pp)
    assert cli.main(["compare", str(ip), str(pp), "--out", str(tmp_path / "o")]) == 1
    assert capsys.readouterr().err.count("\n") == 1
    assert not (tmp_path / "o").exists()          # nothing written before the inputs are checked


def test_bad_arguments():
    sup = _supports()
    with pytest.raises(RotoridError, match="two SeriesSupport"):
        predict_coefficients(sup[:1], speed_rpm=[3000.0])
    with pytest.raises(RotoridError, match="one running speed"):
        predict_coefficients(sup, speed_rpm=[3000.0, 4000.0], freq_hz=[10.0, 20.0])
    with pytest.raises(RotoridError, match="impedance"):
        SeriesSupport("film", np.eye(2), 1.0)
    with pytest.raises(RotoridError, match="journal_mass_kg"):
        SeriesSupport(np.eye(2), np.eye(2), -1.0)
    with pytest.raises(RotoridError, match="shape"):
        SeriesSupport(np.eye(3), np.eye(2), 1.0)
    with pytest.raises(RotoridError, match="Identification"):
        compare("ident", np.zeros((1, 2, 2, 2)), np.zeros((1, 2, 2, 2)))
    with pytest.raises(RotoridError, match="missing.csv"):
        compare_tables("missing.csv", "missing.csv")


def test_impact_identification_compared_over_frequency():
    """Impacts at one speed measure the support over frequency: predicting at that speed over the
    FRF frequencies agrees; predicting synchronously (w = Omega) at the same speed does not."""
    rig = rotorid.nsf_rig()
    sup = _supports()
    f = np.arange(20.0, 120.0, 5.0)
    k, c = predict_coefficients(sup, speed_rpm=3000.0, freq_hz=f)
    brg = rotorid.BearingCoefficients(k, c, freq_hz=f)
    tests = [rotorid.impact_frf(rig.rotor, brg, speed_rpm=3000.0, freq_hz=f, direction=d) for d in "xy"]
    for t in tests:
        t.cov = np.broadcast_to(np.eye(8) * (1e-3 * np.abs(t.q).max()) ** 2, (f.size, 8, 8))
    ident = rotorid.identify_impact(rig.rotor, tests)
    cmp = compare(ident, k, c)
    assert cmp.axis_name == "freq_hz"
    assert np.all(np.abs(cmp.z[np.isfinite(cmp.z)]) < 1e-4)
    ks, cs = predict_coefficients(sup, speed_rpm=np.full(1, 3000.0))       # the synchronous point only
    wrong = compare(ident, np.repeat(ks, f.size, 0), np.repeat(cs, f.size, 0))
    j = REPORT_ORDER.index("Kxx1")
    assert np.nanmax(np.abs(wrong.z[:, j])) > 10 * np.nanmax(np.abs(cmp.z[:, j])) + 1.0


def test_tables_without_uncertainty_non_numeric_cells_and_empty_tables(tmp_path, identified, capsys):
    ident, k, c = identified
    ip, pp = _tables(tmp_path, ident, k, c)
    df = pd.read_csv(ip)
    # no uncertainty at all: the columns are absent; the comparison is made, no point counts
    df.drop(columns=[col for col in df.columns if col.endswith(("_std", "_lo95", "_hi95"))]).to_csv(
        tmp_path / "nostd.csv", index=False)
    cmp = compare_tables(tmp_path / "nostd.csv", pp)
    assert np.all(np.isnan(cmp.z)) and (cmp.summary().points == 0).all()
    bad = df.copy()
    bad["Kxx1"] = bad["Kxx1"].astype(object)
    bad.loc[2, "Kxx1"] = "1.2e6x"
    bad.to_csv(tmp_path / "text.csv", index=False)
    with pytest.raises(RotoridError, match="column 'Kxx1' row 3 holds '1.2e6x'"):
        compare_tables(tmp_path / "text.csv", pp)
    df.iloc[:0].to_csv(tmp_path / "empty.csv", index=False)
    with pytest.raises(RotoridError, match="has no rows"):
        compare_tables(tmp_path / "empty.csv", pp)
    odd = df.copy()
    odd["ok"] = ["yes"] * len(odd)
    odd.to_csv(tmp_path / "ok.csv", index=False)
    with pytest.raises(RotoridError, match="'ok' must hold True/False"):
        compare_tables(tmp_path / "ok.csv", pp)
    for name in ("text.csv", "empty.csv", "ok.csv"):
        assert cli.main(["compare", str(tmp_path / name), str(pp), "--out", str(tmp_path / "o")]) == 1
        assert capsys.readouterr().err.count("\n") == 1


def test_impact_tables_must_be_at_the_same_running_speed(tmp_path):
    ident = pd.DataFrame({"freq_hz": [20.0, 40.0], "speed_rpm": [2000.0, 2000.0], "ok": [True, True],
                          **{n: [1e6, 1e6] for n in REPORT_ORDER}})
    pred = pd.DataFrame({"freq_hz": [10.0, 50.0], "speed_rpm": [4000.0, 4000.0], **{n: [1e6, 1e6] for n in REPORT_ORDER}})
    ident.to_csv(tmp_path / "i.csv", index=False)
    pred.to_csv(tmp_path / "p.csv", index=False)
    with pytest.raises(RotoridError, match="impacts ran at 2000 rpm but the prediction is for 4000 rpm"):
        compare_tables(tmp_path / "i.csv", tmp_path / "p.csv")
    pred.assign(speed_rpm=2000.0).to_csv(tmp_path / "p.csv", index=False)
    assert compare_tables(tmp_path / "i.csv", tmp_path / "p.csv").axis_name == "freq_hz"
    pred.drop(columns="speed_rpm").to_csv(tmp_path / "p.csv", index=False)
    with pytest.warns(UserWarning, match="only the identified table states its running speed"):
        compare_tables(tmp_path / "i.csv", tmp_path / "p.csv")


def test_series_support_reports_misused_objects():
    from rotorid.support import nsf_damper
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        damper = nsf_damper(spring_stiffness_n_m=4e6)
    swapped = SeriesSupport(bearing=damper, damper=np.eye(2) * 1e7, journal_mass_kg=1.0)
    with pytest.raises(RotoridError, match="bearing.impedance"):
        swapped.impedance([3000.0], [50.0])
    with pytest.raises(RotoridError, match="name must be a string"):
        SeriesSupport(np.eye(2), np.eye(2), 1.0, name=3)
