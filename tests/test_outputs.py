"""Users' files: no silent overwrite, stale results removed, a manifest, one-line errors."""

import json
import os

import pytest

from rotorid import cli
from rotorid.outputs import MANIFEST


@pytest.fixture(scope="module")
def example(tmp_path_factory):
    d = tmp_path_factory.mktemp("ex") / "ex"
    assert cli.main(["example", "--out", str(d)]) == 0
    return d


def test_example_refuses_to_overwrite_without_the_flag(example, capsys):
    assert cli.main(["example", "--out", str(example)]) == 1
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "--overwrite" in err
    assert cli.main(["example", "--out", str(example), "--overwrite"]) == 0


def test_identify_refuses_earlier_results_and_removes_stale_ones_with_overwrite(example, tmp_path, capsys):
    cfg4 = example / "imbalance.toml"
    out = tmp_path / "res"
    assert cli.main(["identify", "imbalance", str(cfg4), "--out", str(out)]) == 0
    manifest = json.loads((out / MANIFEST).read_text())
    assert "sync_vectors_3_C90.csv" in manifest["files"] and "coefficients_imbalance.png" in manifest["files"]
    before = (out / "coefficients_imbalance.csv").read_bytes()
    capsys.readouterr()
    assert cli.main(["identify", "imbalance", str(cfg4), "--out", str(out)]) == 1
    assert "already holds results of an earlier run" in capsys.readouterr().err
    assert (out / "coefficients_imbalance.csv").read_bytes() == before
    # a 3-run analysis into the same folder: the 4th run's vectors are stale and go
    text = cfg4.read_text()
    last = text.rindex("[[imbalance.runs]]")
    cfg3 = example / "imbalance3.toml"
    cfg3.write_text(text[:last] + text[text.index("[output]"):])
    (out / "my_notes.txt").write_text("mine")
    assert cli.main(["identify", "imbalance", str(cfg3), "--out", str(out), "--overwrite"]) == 0
    assert "removed 1 stale file" in capsys.readouterr().out
    assert not (out / "sync_vectors_3_C90.csv").exists() and (out / "my_notes.txt").read_text() == "mine"
    assert not [f for f in os.listdir(out) if f.endswith(".tmp") or ".tmp." in f]


def test_an_output_path_that_is_a_file_is_one_clear_error(example, tmp_path, capsys):
    f = tmp_path / "afile"
    f.write_text("x")
    assert cli.main(["identify", "impact", str(example / "impact.toml"), "--out", str(f)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "is a file" in err


def test_demo_refuses_a_folder_with_its_figures_and_checks_its_numbers(tmp_path, capsys):
    d = tmp_path / "demo"
    d.mkdir()
    (d / "campbell.png").write_bytes(b"not ours")
    assert cli.main(["demo", "--out", str(d)]) == 1
    assert (d / "campbell.png").read_bytes() == b"not ours"
    assert "--overwrite" in capsys.readouterr().err
    for bad in (["--noise-um", "-1"], ["--step-rpm", "0"]):
        assert cli.main(["demo", "--out", str(tmp_path / "d2")] + bad) == 1
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and bad[0] in err
