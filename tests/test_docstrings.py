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
           "rotorid.exports", "rotorid.report", "rotorid.plot"]


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples(name):
    mod = importlib.import_module(name)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = doctest.testmod(mod, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    assert res.failed == 0, f"{res.failed} of {res.attempted} examples failed in {name}"


def test_readme_quick_start_runs():
    """The README's quick-start code blocks run as written (no undefined names)."""
    import os
    import re

    text = open(os.path.join(os.path.dirname(__file__), "..", "README.md"), encoding="utf-8").read()
    section = text[text.index("### Quick start"):text.index("### Conventions")]
    blocks = re.findall(r"```python\n(.*?)```", section, re.S)
    assert len(blocks) >= 2
    namespace = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for block in blocks:
            exec(compile(block, "README quick start", "exec"), namespace)
