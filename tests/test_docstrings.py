"""The examples in the docstrings of the public functions run and give what they say."""

import doctest
import importlib
import warnings

import pytest

MODULES = ["rotorid.signals.keyphasor", "rotorid.signals.order", "rotorid.identify", "rotorid.kcm",
           "rotorid.phasecal", "rotorid.config", "rotorid.tables", "rotorid.io", "rotorid.studies.errors",
           "rotorid.studies.monte_carlo", "rotorid.studies.sensitivity", "rotorid.studies.design",
           "rotorid.studies.config", "rotorid.studies.run", "rotorid.studies.report", "rotorid.pedestal",
           "rotorid.support.series", "rotorid.support.sfd", "rotorid.support.tpjb", "rotorid.support.compare",
           "rotorid.exports", "rotorid.report", "rotorid.plot", "rotorid.speed_offsets"]


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples(name):
    mod = importlib.import_module(name)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = doctest.testmod(mod, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    assert res.failed == 0, f"{res.failed} of {res.attempted} examples failed in {name}"


def test_readme_quick_start_runs():
    """The README's quick-start code blocks run as written (no undefined names)."""
    from docblocks import read, run_python_blocks

    text = read("README.md")
    run_python_blocks(text[text.index("### Quick start"):text.index("### Conventions")], "README quick start",
                      min_blocks=2)
