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
    # the table and its two figures (Bode, polar)
    assert "removed 3 stale file(s)" in capsys.readouterr().out
    assert not [f for f in os.listdir(out) if f.startswith("sync_vectors_3_C90")]
    assert (out / "my_notes.txt").read_text() == "mine"
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


def test_measured_data_figures_beside_their_tables(tmp_path):
    """identify writes the measured 1X vectors (Bode and polar) and the FRFs with their coherence as PNG
    next to their CSV tables; --no-plot writes none of them."""
    import os

    from rotorid import example

    ex = example.copy_example(str(tmp_path / "ex"))
    assert cli.main(["identify", "imbalance", os.path.join(ex, "imbalance_1x_table.toml"), "--out",
                     str(tmp_path / "i"), "-q"]) == 0
    names = os.listdir(tmp_path / "i")
    tables = [n for n in names if n.startswith("sync_vectors_") and n.endswith(".csv")]
    assert tables
    for t in tables:
        for kind in ("bode", "polar"):
            png = tmp_path / "i" / t.replace(".csv", f"_{kind}.png")
            assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert cli.main(["identify", "impact", os.path.join(ex, "impact.toml"), "--out", str(tmp_path / "m"), "-q"]) == 0
    frfs = [n for n in os.listdir(tmp_path / "m") if n.startswith("frf_") and n.endswith(".csv")]
    assert frfs and all((tmp_path / "m" / f.replace(".csv", ".png")).is_file() for f in frfs)
    assert cli.main(["identify", "impact", os.path.join(ex, "impact.toml"), "--out", str(tmp_path / "n"), "-q",
                     "--no-plot"]) == 0
    assert not any(n.endswith(".png") for n in os.listdir(tmp_path / "n"))
