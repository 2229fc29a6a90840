"""Start-up stays light: ``import rotorid`` and the CLI's help load none of the heavy optional
dependencies (they are imported inside the functions that need them), and the lazily imported
public API is complete. Each check runs in a fresh interpreter, as the test session itself has
imported everything long before. No timing here (speed is measured by benches only)."""

import json
import subprocess
import sys

import pytest

import rotorid

HEAVY = ("pandas", "matplotlib", "scipy", "pydantic", "nptdms", "pyuff", "openpyxl", "pint")
REQUIRED_ABSENT = ("pandas", "matplotlib")  # the must; the rest are checked as well while they hold

_REPORT = f"""
import json, sys
print(json.dumps([m for m in {HEAVY!r} if m in sys.modules]))
"""


def _loaded_after(code):
    """The heavy modules in sys.modules of a fresh interpreter after running ``code``."""
    out = subprocess.run([sys.executable, "-c", code + _REPORT], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout.strip().splitlines()[-1])


def _assert_light(loaded):
    assert not [m for m in REQUIRED_ABSENT if m in loaded], loaded
    assert loaded == [], f"heavy modules imported at start-up: {loaded}"


def test_import_rotorid_loads_no_heavy_dependency():
    _assert_light(_loaded_after("import rotorid"))


@pytest.mark.parametrize("argv", [["--help"], ["demo", "--help"], ["identify", "--help"], ["check", "--help"],
                                  ["example", "--help"], ["study", "--help"], ["report", "--help"]])
def test_cli_help_loads_no_heavy_dependency(argv):
    code = f"""
import contextlib, io
from rotorid.cli import main
with contextlib.redirect_stdout(io.StringIO()) as buf:
    try:
        main({argv!r})
    except SystemExit as exc:
        assert exc.code in (0, None), exc.code
    else:
        raise AssertionError("--help did not exit")
assert "usage: rotorid" in buf.getvalue(), buf.getvalue()
"""
    _assert_light(_loaded_after(code))


def test_every_public_name_imports_in_a_fresh_interpreter():
    names = ", ".join(rotorid.__all__)
    code = f"""
import rotorid
from rotorid import {names}
for n in rotorid.__all__:
    assert getattr(rotorid, n) is not None, n
    assert n in dir(rotorid), n
ns = {{}}
exec("from rotorid import *", ns)
missing = set(rotorid.__all__) - set(ns)
assert not missing, missing
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr


def test_public_names_come_from_their_modules():
    for name in rotorid.__all__:
        obj = getattr(rotorid, name)
        assert obj is not None
    # the submodules are the real modules, reachable as attributes as before the lazy import
    assert rotorid.io is sys.modules["rotorid.io"]
    assert rotorid.simulate is sys.modules["rotorid.simulate"]
    assert rotorid.load_recording is rotorid.io.load_recording
    assert rotorid.ProbeResolution is rotorid.simulate.ProbeResolution
    with pytest.raises(AttributeError):
        rotorid.no_such_name  # noqa: B018
