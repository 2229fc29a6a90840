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
