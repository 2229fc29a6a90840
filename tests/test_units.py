"""The unit table at the edges: case where it means something, the spellings labs use."""

import pytest

from rotorid import RotoridError, units


@pytest.mark.parametrize("unit, quantity, value", [
    ("MN/m", "stiffness", 1e6), ("mN/m", "stiffness", 1e-3), ("kN/m", "stiffness", 1e3),
    ("klbf/in", "stiffness", 4448.2216152605 / 0.0254), ("lbf/in", "stiffness", 4.4482216152605 / 0.0254),
    ("N·s/m", "damping", 1.0), ("N-s/m", "damping", 1.0), ("lbf-s/in", "damping", 4.4482216152605 / 0.0254),
    ("lbf·s/in", "damping", 4.4482216152605 / 0.0254), ("kN*s/m", "damping", 1e3),
    ("μm", "length", 1e-6), ("µm", "length", 1e-6), ("MIL", "length", 25.4e-6), ("mV", "voltage", 1e-3),
    ("V", "voltage", 1.0), ("G", "acceleration", 9.80665), ("klbf", "force", 4448.2216152605),
])
def test_factors(unit, quantity, value):
    assert units.factor(unit, quantity) == pytest.approx(value, rel=1e-15)
    assert units.quantity_of(unit) == quantity


@pytest.mark.parametrize("unit", ["mn/m", "MV", "Mn/m"])
def test_case_that_means_milli_or_mega_is_not_guessed(unit):
    with pytest.raises(RotoridError, match="letter case matters"):
        units.factor(unit)


def test_a_unit_of_another_quantity_is_named():
    with pytest.raises(RotoridError, match="unit 'mil' is a length, expected an acceleration"):
        units.factor("mil", "acceleration")
    with pytest.raises(RotoridError, match="unknown unit 'furlong'"):
        units.to_si(1.0, "furlong")


# ---------------------------------------------------------------------------------------------
# quantity strings (pint): parsing, dimensions, case, mil

import doctest  # noqa: E402
import shutil  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402

import numpy as np  # noqa: E402

import rotorid  # noqa: E402
from rotorid.units import OutputUnits, quantity  # noqa: E402

LBF, INCH, LB = 4.4482216152605, 0.0254, 0.45359237


@pytest.mark.parametrize("text, dimension, si", [
    ("68 lb", "mass", 68 * LB), ("68 lbm", "mass", 68 * LB), ("500 g", "mass", 0.5), ("12.5 in", "length", 0.3175),
    ("0.45 lb*in**2", "inertia", 0.45 * LB * INCH ** 2), ("0.45 lb in^2", "inertia", 0.45 * LB * INCH ** 2),
    ("0.45 lb·in²", "inertia", 0.45 * LB * INCH ** 2), ("0.7 kg*m^2", "inertia", 0.7),
    ("3000 rpm", "speed", 100 * np.pi), ("50 Hz", "speed", 100 * np.pi), ("3000 1/min", "speed", 100 * np.pi),
    ("314.159 rad/s", "speed", 314.159), ("3000 rpm", "frequency", 50.0), ("2.1 klbf/in", "stiffness", 2100 * LBF / INCH),
    ("2 lbf", "force", 2 * LBF), ("3 klbf", "force", 3000 * LBF), ("12 lbf*s/in", "damping", 12 * LBF / INCH),
    ("12 lbf·s/in", "damping", 12 * LBF / INCH), ("5 N·s/m", "damping", 5.0), ("5 N s/m", "damping", 5.0),
    ("2 mN/m", "stiffness", 2e-3), ("2 MN/m", "stiffness", 2e6), ("5 µm", "length", 5e-6), ("5 μm", "length", 5e-6),
    ("5 um", "length", 5e-6), ("2 mil", "length", 2 * 25.4e-6), ("2 mils", "length", 2 * 25.4e-6),
    ("2mil", "length", 2 * 25.4e-6), ("2 thou", "length", 2 * 25.4e-6), ("1 g0", "acceleration", 9.80665),
    ("2.5 oz*in", "imbalance", 2.5 * 0.028349523125 * INCH), ("-3 in", "length", -3 * INCH),
])
def test_quantity_strings_in_si(text, dimension, si):
    assert quantity(text, dimension, "f") == pytest.approx(si, rel=1e-12)


def test_numbers_are_taken_as_si_and_pint_quantities_are_read():
    assert quantity(45.3, "mass") == 45.3 and quantity(np.float64(0.2), "length") == 0.2
    q = rotorid.units.registry().Quantity(3.0, "inch")
    assert quantity(q, "length") == pytest.approx(3 * INCH)
    assert quantity(rotorid.units.registry().Quantity(2.0, "mil"), "length") == pytest.approx(2 * 25.4e-6)


@pytest.mark.parametrize("value, dimension, message", [
    ("3 in", "mass", "rotor.mass: '3 in' is a length, expected a mass (kg)"),
    ("68 lbf", "mass", "rotor.mass: '68 lbf' is a force, expected a mass (kg) (lb is the pound mass, lbf the pound "
                       "force)"),
    ("2 klbf", "stiffness", "rotor.mass: '2 klbf' is a force, expected a stiffness (N/m)"),
    ("3000 rpm", "length", "rotor.mass: '3000 rpm' is a speed or a frequency, expected a length (m)"),
    ("1 g", "acceleration", "rotor.mass: '1 g' is a mass, expected an acceleration (m/s**2) (g is the gram here; "
                            "standard gravity is g0)"),
    ("5 parsecz", "length", "rotor.mass: has an unknown unit 'parsecz' in '5 parsecz'"),
    ("68", "mass", "rotor.mass: '68' has no unit (write e.g. '68 lb', or give a plain number, taken as kg)"),
    ("", "mass", "rotor.mass: is an empty string"),
    ("(3 m", "length", "rotor.mass: cannot be read as a quantity: '(3 m'"),
    ("3 kg + 2 m", "mass", "rotor.mass: cannot be read: '3 kg + 2 m' adds quantities of different dimensions"),
    ("nan kg", "mass", "rotor.mass: 'nan kg' is not a finite mass"),
    ("9**9**9 m", "length", "rotor.mass: cannot be read as a quantity: '9**9**9 m' (too long, or a power too large"),
    (True, "mass", "rotor.mass: must be a number (in kg) or a string with a unit, got True"),
    ([1.0], "mass", "rotor.mass: must be a number (in kg) or a string with a unit"),
    (float("inf"), "mass", "rotor.mass: must be finite, got inf"),
])
def test_bad_quantities_are_one_line_naming_field_and_dimension(value, dimension, message):
    with pytest.raises(RotoridError) as info:
        quantity(value, dimension, "rotor.mass")
    msg = str(info.value)
    assert msg.startswith(message) and "\n" not in msg


def test_quantity_case_matters_milli_mega():
    assert quantity("1 mN/m", "stiffness") == pytest.approx(1e-3)
    assert quantity("1 MN/m", "stiffness") == pytest.approx(1e6)
    with pytest.raises(RotoridError, match=r"unknown unit 'mn'.*case-sensitive: did you mean 'MN' or 'mN'"):
        quantity("1 mn/m", "stiffness")
    with pytest.raises(RotoridError, match=r"unknown unit 'Kg'.*did you mean 'kg'\?"):
        quantity("68 Kg", "mass")
    # MV is a megavolt to pint: a voltage, never a mass; the lab-file table still refuses it
    with pytest.raises(RotoridError, match="'1 MV' is a voltage, expected a mass"):
        quantity("1 MV", "mass")
    with pytest.raises(RotoridError, match="unknown dimension|dimension must be one of"):
        quantity("1 kg", "weight")


def test_mil_is_a_length_not_pints_angle():
    assert quantity("1 mil", "length") == pytest.approx(25.4e-6, rel=1e-12)
    assert units.factor("mil", "length") == pytest.approx(quantity("1 mil", "length"), rel=1e-12)
    assert rotorid.units.registry().parse_expression("1 mil").to("um").magnitude == pytest.approx(25.4)


def test_import_rotorid_does_not_import_pint():
    code = "import sys, rotorid, rotorid.units, rotorid.config; print('pint' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0 and out.stdout.strip() == "False", out.stderr


def test_docstring_examples_of_units_and_from_quantities():
    res = doctest.testmod(units, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    assert res.failed == 0 and res.attempted >= 15
    finder = doctest.DocTestFinder()
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS)
    for t in finder.find(rotorid.RigidRotor.from_quantities, "from_quantities", globs={}):
        runner.run(t)
    assert runner.failures == 0 and runner.tries >= 3


def test_rigid_rotor_from_quantities_equals_si():
    si = rotorid.nsf_rig().rotor
    us = rotorid.RigidRotor.from_quantities(
        mass=f"{si.mass_kg / LB!r} lb", it=f"{si.it_kgm2 / (LB * INCH ** 2)!r} lb*in**2",
        ip=f"{si.ip_kgm2 / (LB * INCH ** 2)!r} lb in^2", l1=f"{si.l1 / INCH!r} in", l2=f"{si.l2 * 1000!r} mm",
        d=[f"{si.d[0] / INCH!r} in", si.d[1]], r=[f"{si.r[0] * 100!r} cm", si.r[1]], s=list(si.s))
    np.testing.assert_allclose(us.core_params(), si.core_params(), rtol=1e-12)
    np.testing.assert_allclose(us.d + us.r + us.s, si.d + si.r + si.s, rtol=1e-12)
    with pytest.raises(RotoridError, match=r"^d\[1\]: '2 lbf' is a force, expected a length"):
        rotorid.RigidRotor.from_quantities(mass=45.3, it=0.7, ip=0.3, l1=0.19, l2=0.22, d=(0.1, "2 lbf"))


# ---------------------------------------------------------------------------------------------
# output conventions

def test_pk_pk_is_twice_0_pk_and_lag_is_minus_arg_mod_360():
    rig = rotorid.nsf_rig()
    resp = rotorid.imbalance_response(rig.rotor, rig.bearings, rotorid.Imbalance((1e-3, 5e-4), (0.0, 120.0)),
                                      speed_rpm=np.arange(1000.0, 8001.0, 500.0))
    a = OutputUnits("SI", "0-pk", "arg").sync_table(resp)
    b = OutputUnits("SI", "pk-pk", "lag").sync_table(resp)
    c = OutputUnits("us", "pk-pk", "lag").sync_table(resp)
    for nm in ("x1", "x2", "y1", "y2"):
        np.testing.assert_allclose(b[f"{nm}_amp_um_pkpk"], 2 * a[f"{nm}_amp_um_0pk"], rtol=1e-14)
        np.testing.assert_allclose(c[f"{nm}_amp_mil_pkpk"], b[f"{nm}_amp_um_pkpk"] / 25.4, rtol=1e-12)
        np.testing.assert_allclose(b[f"{nm}_phase_deg_lag"], np.mod(-a[f"{nm}_phase_deg_arg"], 360), atol=1e-9)
        assert ((b[f"{nm}_phase_deg_lag"] >= 0) & (b[f"{nm}_phase_deg_lag"] < 360)).all()
        assert ((a[f"{nm}_phase_deg_arg"] > -180) & (a[f"{nm}_phase_deg_arg"] <= 180)).all()
        # the same amplitudes and phases as the response's own table (µm 0-pk, arg)
        np.testing.assert_allclose(a[f"{nm}_amp_um_0pk"], resp.to_dataframe()[f"{nm}_amp_um"], rtol=1e-14)


def test_frf_table_units():
    rig = rotorid.nsf_rig()
    h = rotorid.impact_frf(rig.rotor, rig.bearings, speed_rpm=3000.0, freq_hz=np.arange(10.0, 100.0, 10.0))
    si = OutputUnits("SI", phase="arg").frf_table(h)
    us = OutputUnits("US").frf_table(h)
    np.testing.assert_allclose(si.x1_amp_um_per_N, h.to_dataframe().x1_amp_um_per_N, rtol=1e-14)
    np.testing.assert_allclose(us.x1_amp_mil_per_lbf, si.x1_amp_um_per_N / 25.4 * LBF, rtol=1e-12)
    np.testing.assert_allclose(us.x1_phase_deg_lag, np.mod(-si.x1_phase_deg_arg, 360), atol=1e-9)


@pytest.mark.parametrize("kw, message", [
    (dict(units="imperial"), "units must be 'SI' or 'US'"), (dict(amplitude="rms"), "amplitude must be '0-pk' or "
                                                                                     "'pk-pk'"),
    (dict(phase="lead"), "phase must be 'lag'"),
])
def test_output_conventions_refuse_the_unknown(kw, message):
    with pytest.raises(RotoridError, match=message):
        OutputUnits(**kw)


# ---------------------------------------------------------------------------------------------
# configs in US quantities, outputs in the chosen conventions, bad input through the CLI

NSF_US = """[rotor]
mass = "{mass} lb"
it = "{it} lb*in**2"
ip = "{ip} lb in^2"
l1 = "{l1} in"
l2 = "{l2} in"
d = ["{d1} in", "{d2} in"]
r = ["{r1} in", "{r2} in"]
s = ["{s1} in", {s2}]
"""


def _us_rotor_table():
    r = rotorid.nsf_rig().rotor
    f = dict(mass=r.mass_kg / LB, it=r.it_kgm2 / (LB * INCH ** 2), ip=r.ip_kgm2 / (LB * INCH ** 2), l1=r.l1 / INCH,
             l2=r.l2 / INCH, d1=r.d[0] / INCH, d2=r.d[1] / INCH, r1=r.r[0] / INCH, r2=r.r[1] / INCH, s1=r.s[0] / INCH,
             s2=r.s[1])
    return NSF_US.format(**{k: repr(v) for k, v in f.items()})


@pytest.fixture(scope="module")
def example_dir(tmp_path_factory):
    from rotorid import example as ex

    d = tmp_path_factory.mktemp("units") / "ex"
    shutil.copytree(ex.path(), d)
    return d


def test_config_in_us_quantities_identifies_as_the_si_one(example_dir):
    import warnings

    from rotorid import pipeline

    d = example_dir
    si_text = (d / "imbalance.toml").read_text()
    us_text = si_text.replace('[rig]\nbuiltin = "nsf"\n', _us_rotor_table()).replace('dir = "out_imbalance"',
                                                                                    'dir = "out_us"')
    us_text = us_text.replace('units = "SI"', 'units = "US"\namplitude = "pk-pk"\nphase = "lag"')
    assert "[rig]" not in us_text and 'mass = "' in us_text
    (d / "imbalance_us.toml").write_text(us_text)
    lines = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        si, _ = pipeline.run_config(d / "imbalance.toml", "imbalance", log=lambda m: None, plots=False)
        us, files = pipeline.run_config(d / "imbalance_us.toml", "imbalance", log=lines.append, plots=False)
    np.testing.assert_allclose(us.k, si.k, rtol=1e-7)
    np.testing.assert_allclose(us.c, si.c, rtol=1e-7)
    import pandas as pd

    # written 1X vectors: mils pk-pk, phase lag, named in the headers
    sv_si = pd.read_csv(d / "out_imbalance" / "sync_vectors_0_S0.csv")
    sv_us = pd.read_csv(d / "out_us" / "sync_vectors_0_S0.csv")
    assert "x1_amp_um_0pk" in sv_si.columns and "x1_phase_deg_lag" in sv_si.columns  # the defaults
    assert {"x1_amp_mil_pkpk", "x1_phase_deg_lag", "x1_amp_std_mil_pkpk", "x1_phase_std_deg"} <= set(sv_us.columns)
    np.testing.assert_allclose(sv_us.x1_amp_mil_pkpk, 2 * sv_si.x1_amp_um_0pk / 25.4, rtol=1e-5)
    # console medians and the slow-roll note in US units
    med = next(m for m in lines if "median over ok points" in m)
    assert "(lbf/in, lbf*s/in)" in med
    kxx1 = float(med.split("Kxx1 ")[1].split(",")[0])
    assert kxx1 == pytest.approx(np.median(us.k[us.ok, 0, 0, 0]) * INCH / LBF, rel=1e-3)
    assert any(m.startswith("  slow-roll run-out 1X (pk-pk, phase lag deg): x1 ") and " mil @ " in m for m in lines)


def test_us_impact_frfs_and_kcm_in_us_units(example_dir):
    import warnings

    import pandas as pd

    from rotorid import pipeline

    d = example_dir
    text = (d / "impact.toml").read_text()
    assert "[output]" in text
    text = text.replace("[output]", '[output]\nunits = "US"\nphase = "arg"', 1).replace('units = "SI"\n', "")
    (d / "impact_us.toml").write_text(text)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ident, files = pipeline.run_config(d / "impact_us.toml", "impact", log=lambda m: None, plots=False,
                                           out_dir=str(d / "out_impact_us"))
    frf = pd.read_csv(next((d / "out_impact_us").glob("frf_*.csv")))
    assert {"x1_amp_mil_per_lbf", "x1_phase_deg_arg", "x1_coherence"} <= set(frf.columns)
    assert (frf.x1_phase_deg_arg.abs() <= 180).all()


def test_check_refuses_bad_unit_strings_in_one_line(example_dir, tmp_path, capsys):
    from rotorid import cli

    d = example_dir
    good = (d / "imbalance.toml").read_text().replace('[rig]\nbuiltin = "nsf"\n', _us_rotor_table())
    (d / "check_ok.toml").write_text(good)
    assert cli.main(["check", str(d / "check_ok.toml")]) == 0
    capsys.readouterr()
    for wrong, fragment in ((lambda t: t.replace(' lb"', ' in"', 1), "[rotor] mass '"),
                            (lambda t: t.replace(' lb*in**2"', ' Kg*m**2"', 1), "[rotor] it has an unknown unit 'Kg'"),
                            (lambda t: t.replace(' in"', ' lbf"', 1), "[rotor] l1 '")):
        (d / "check_bad.toml").write_text(wrong(good))
        assert cli.main(["check", str(d / "check_bad.toml")]) == 1
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and fragment in err, err
    # identify with a bad unit writes nothing
    out = tmp_path / "never"
    assert cli.main(["identify", "imbalance", str(d / "check_bad.toml"), "--out", str(out)]) == 1
    assert not out.exists()


def test_output_imperial_is_refused_by_check(example_dir, capsys):
    from rotorid import cli

    d = example_dir
    (d / "imperial.toml").write_text((d / "imbalance.toml").read_text().replace('units = "SI"', 'units = "imperial"'))
    assert cli.main(["check", str(d / "imperial.toml")]) == 1
    err = capsys.readouterr().err
    assert "[output] units must be one of 'SI', 'US' (any case), got 'imperial'" in err


def test_units_doc_python_blocks_run():
    from docblocks import read, run_python_blocks

    run_python_blocks(read("docs/units.md"), "docs/units.md", min_blocks=3)



# ---------------------------------------------------------------------------------------------
# regressions found by adversarial testing

@pytest.mark.parametrize("text", ["1,5 in", "1, 5 in", "1,500 in", "2 in, 3 in"])
def test_a_comma_in_a_quantity_is_refused_not_misread(text):
    """pint drops the comma: "1,5 in" read as 15 in, "1, 5 in" as 5 in (a decimal comma, 10x off)."""
    with pytest.raises(RotoridError, match="has a comma"):
        quantity(text, "length", "rotor.l1")


def test_a_decimal_comma_in_a_config_is_refused():
    from rotorid.config import ConfigError, parse_config

    impact = {"tests": [{"file": "hits.tdms", "plane_m": 0.0, "direction": "x"}]}
    rotor = {"mass": "1,5 lb", "it": 0.7, "ip": 0.3, "l1": 0.19, "l2": 0.22, "d": [0.06, 0.1], "r": [0.11, 0.09],
             "s": [0.12, 0.15]}
    with pytest.raises(ConfigError, match=r"\[rotor\] mass .*comma"):
        parse_config({"rotor": rotor, "impact": impact}, source="rig.toml")


def test_pint_quantities_with_numpy_or_decimal_magnitudes_are_read():
    """A pint Quantity's magnitude is often a numpy scalar (array element * unit); its repr,
    np.float64(2.0), was passed to pint and refused as the unit 'np'."""
    import decimal
    import fractions

    import pint

    ureg = pint.UnitRegistry()
    assert quantity(ureg.Quantity(np.float64(2.0), "inch"), "length") == pytest.approx(0.0508, rel=1e-15)
    assert quantity(np.arange(3.0)[2] * ureg.inch, "length") == pytest.approx(0.0508, rel=1e-15)
    assert quantity(ureg.Quantity(np.int64(2), "lb"), "mass") == pytest.approx(2 * 0.45359237, rel=1e-15)
    assert quantity(ureg.Quantity(decimal.Decimal("2.5"), "inch"), "length") == pytest.approx(0.0635, rel=1e-15)
    assert quantity(ureg.Quantity(fractions.Fraction(1, 4), "inch"), "length") == pytest.approx(0.00635, rel=1e-15)
    for bad in (ureg.Quantity(np.array([1.0, 2.0]), "inch"), ureg.Quantity(2 + 1j, "inch")):
        with pytest.raises(RotoridError, match="single real value"):
            quantity(bad, "length", "l1")


@pytest.mark.parametrize("value", [10 ** 400, -10 ** 400], ids=["1e400", "-1e400"])
def test_an_integer_beyond_the_float_range_is_a_rotorid_error(value):
    with pytest.raises(RotoridError, match="must be finite"):
        quantity(value, "length", "l1")
    with pytest.raises(RotoridError, match="mass: must be finite"):
        rotorid.RigidRotor.from_quantities(mass=value, it=0.7, ip=0.3, l1=0.19, l2=0.22)


@pytest.mark.parametrize("pair", [b"ab", {0.1, 0.2}, {"a": 0.1, "b": 0.2}, bytearray(b"ab")])
def test_from_quantities_pairs_are_sequences(pair):
    """b"ab" was read as (97 m, 98 m), a set in no order, a dict by its keys ('a' as a year)."""
    with pytest.raises(RotoridError, match="d must be a pair of lengths"):
        rotorid.RigidRotor.from_quantities(mass=30.0, it=0.7, ip=0.3, l1=0.19, l2=0.22, d=pair)


def test_phases_stay_in_their_documented_ranges():
    """lag in [0, 360) and arg in (-180, 180]: the mod of a tiny negative angle rounded up to 360,
    and a -0.0 imaginary part gave arg -180."""
    z = np.array([complex(1.0, 1e-300), complex(1.0, 1e-14 * np.pi / 180), complex(-1.0, -0.0), complex(-1.0, 0.0),
                  1j, -1j, 1.0])
    lag = OutputUnits(phase="lag").phase_of(z)
    arg = OutputUnits(phase="arg").phase_of(z)
    assert np.all((lag >= 0) & (lag < 360)), lag
    assert np.all((arg > -180) & (arg <= 180)), arg
    np.testing.assert_allclose(np.exp(1j * np.deg2rad(lag)), np.exp(-1j * np.angle(z)), atol=1e-12)
    np.testing.assert_allclose(np.exp(1j * np.deg2rad(arg)), np.exp(1j * np.angle(z)), atol=1e-12)
    assert OutputUnits(phase="arg").phase_of(complex(-1.0, -0.0)) == 180.0
    assert isinstance(OutputUnits().phase_of(np.complex128(1j)), np.floating)   # a scalar stays a scalar


@pytest.mark.parametrize("kw", [dict(amplitude=np.zeros(0)), dict(phase=np.zeros(0)), dict(amplitude=np.array(["0-pk"] * 2)),
                                dict(phase=np.ones((2, 2)))])
def test_output_conventions_refuse_arrays_in_one_line(kw):
    """An array compared elementwise: 'the truth value of an array is ambiguous' (ValueError)."""
    with pytest.raises(RotoridError, match="must be"):
        OutputUnits("SI", **kw)
