"""``rotorid study CONFIG``: the example configs run end to end, results are reproducible, an
earlier study is not overwritten without --overwrite, and every bad config is one line, exit 2."""

import os

import numpy as np
import pandas as pd
import pytest

import rotorid.example as ex
from rotorid.cli import main
from rotorid.studies.config import load_study_config, parse_study_config

EXAMPLES = {k: os.path.join(ex.path(), f"study_{k}.toml") for k in ("imbalance", "impact")}


def _run(capsys, *argv):
    code = main(["study", *argv])
    out = capsys.readouterr()
    return code, out.out, out.err


@pytest.mark.parametrize("kind", ["imbalance", "impact"])
def test_example_configs_run_and_write_their_files(tmp_path, capsys, kind):
    code, out, err = _run(capsys, EXAMPLES[kind], "--out", str(tmp_path / "r"), "--trials", "200", "-q")
    assert code == 0, err
    files = set(os.listdir(tmp_path / "r"))
    want = {"study_errors.csv", "study_bands.csv", "study_percentiles.png", "study_coverage.png", "study_summary.txt",
            "rotorid-manifest.json"}
    if kind == "imbalance":
        want |= {"design_ranking.csv", "design_comparison.csv"}
    assert want <= files, files
    df = pd.read_csv(tmp_path / "r" / "study_errors.csv")
    cfg = load_study_config(EXAMPLES[kind])
    n = cfg.imbalance.speeds().size if kind == "imbalance" else cfg.impact.freqs().size
    assert len(df) == 16 * n
    assert set(df.coefficient) == set(rotorid_names()) and np.isfinite(df.p50).all()
    assert "wrote" in out and err == ""


def rotorid_names():
    from rotorid.model import REPORT_ORDER

    return REPORT_ORDER


def test_same_seed_same_tables_and_no_overwrite(tmp_path, capsys):
    a, b = tmp_path / "a", tmp_path / "b"
    for d in (a, b):
        assert _run(capsys, EXAMPLES["impact"], "--out", str(d), "--trials", "100", "--seed", "3", "-q")[0] == 0
    assert (a / "study_errors.csv").read_bytes() == (b / "study_errors.csv").read_bytes()
    before = (a / "study_errors.csv").read_bytes()
    code, out, err = _run(capsys, EXAMPLES["impact"], "--out", str(a), "--trials", "100", "--seed", "4", "-q")
    assert code == 1 and err.count("\n") == 1 and "--overwrite" in err
    assert (a / "study_errors.csv").read_bytes() == before
    code, _, _ = _run(capsys, EXAMPLES["impact"], "--out", str(a), "--trials", "100", "--seed", "4", "-q", "--overwrite")
    assert code == 0 and (a / "study_errors.csv").read_bytes() != before


BASE = {"rig": {"builtin": "nsf"}, "study": {"kind": "imbalance", "trials": 10},
        "imbalance": {"sets": ["A", "B"], "speeds_rpm": [3000, 4000]}}


IMPACT = """[rig]
builtin = "nsf"
[study]
kind = "impact"
trials = 10
[impact]
speed_rpm = 1000
freq_hz = [10, 20]
tests = [{ plane_mm = 0, direction = "x" }, { plane_mm = 0, direction = "y" }]
[impact.errors]
coherence = 0.9
"""


def _toml(d):
    from rotorid.config import _toml as dump

    lines = []
    for sec, tab in d.items():
        simple = {k: v for k, v in tab.items() if not isinstance(v, dict)}
        lines.append(f"[{sec}]")
        lines += [f"{k} = {dump(v)}" for k, v in simple.items()]
        for k, v in tab.items():
            if isinstance(v, dict):
                lines.append(f"[{sec}.{k}]")
                lines += [f"{kk} = {dump(vv)}" for kk, vv in v.items()]
    return "\n".join(lines) + "\n"


def _edit(**changes):
    import copy

    d = copy.deepcopy(BASE)
    for path, v in changes.items():
        sec, _, key = path.partition("__")
        if key:
            d.setdefault(sec, {})[key] = v
        else:
            d[sec] = v
    return d


@pytest.mark.parametrize("cfg, key", [
    (_edit(study__trails=5), "trails"),
    (_edit(study__trials=0), "trials"),
    (_edit(study__percentiles=[5, 120]), "percentiles"),
    (_edit(study__level=1.0), "level"),
    (_edit(imbalance__sets=["A", "Q"]), "'Q'"),
    (_edit(imbalance__sets=["A"]), "two or more"),
    (_edit(imbalance__speeds_rpm=[3000, -1]), "speeds_rpm"),
    (_edit(imbalance__errors={"phase_deg": -1}), "phase_deg"),
    (_edit(imbalance__errors={"noise_um": "0.1 um"}), "units are in the key names"),
    (_edit(imbalance__errors={"noise": 0.1}), "'noise_um'"),
    (_edit(study__percentiles=[50]), "percentiles"),
    (_edit(study__kind="impact"), "[impact]"),
    (IMPACT.replace("coherence = 0.9", "coherence = 1.5"), "[impact.errors] coherence"),
    (IMPACT.replace('direction = "y"', 'direction = "z"'), "[impact.tests][1] direction"),
    ({k: v for k, v in _edit().items() if k != "rig"}, "no rotor"),
])
def test_bad_study_configs_are_one_line(tmp_path, capsys, cfg, key):
    p = tmp_path / "s.toml"
    p.write_text(cfg if isinstance(cfg, str) else _toml(cfg), encoding="utf-8")
    code, out, err = _run(capsys, str(p), "--out", str(tmp_path / "o"), "-q")
    assert code == 1 and err.startswith("rotorid: error: ") and err.count("\n") == 1, err
    assert key in err, err
    assert not (tmp_path / "o").exists()


def test_missing_config_and_bad_overrides(tmp_path, capsys):
    code, _, err = _run(capsys, str(tmp_path / "none.toml"))
    assert code == 1 and "not found" in err and "none.toml" in err and err.count("\n") == 1
    code, _, err = _run(capsys, EXAMPLES["impact"], "--out", str(tmp_path / "o"), "--trials", "0")
    assert code == 1 and "--trials" in err


def test_example_configs_parse_and_document_every_key():
    text = open(os.path.join(os.path.dirname(__file__), "..", "docs", "config.md"), encoding="utf-8").read()
    from rotorid.studies import config as sc

    for model in (sc.StudySection, sc.ImbalanceStudySection, sc.SyncErrorsSection, sc.ImpactStudySection,
                  sc.ImpactErrorsSection, sc.DesignSection, sc.BearingsSection, sc.TrialRun, sc.ImpactPlan):
        for name, f in model.model_fields.items():
            if isinstance(f.annotation, type) and issubclass(f.annotation, sc._Model):
                assert f".{name}]`" in text, f"{model.__name__}.{name} (a table) is not documented"
                continue
            assert f"`{f.alias or name}`" in text, f"{model.__name__}.{name} is not documented in docs/config.md"
    cfg = parse_study_config(BASE)
    assert cfg.imbalance.speeds().tolist() == [3000.0, 4000.0]


def test_check_recognises_study_configs(capsys, tmp_path):
    assert main(["check", EXAMPLES["imbalance"]]) == 0
    assert "imbalance study with a test design" in capsys.readouterr().out
    p = tmp_path / "s.toml"
    p.write_text(_toml(_edit(study__trials=-1)), encoding="utf-8")
    assert main(["check", str(p)]) == 1
    assert "trials" in capsys.readouterr().err


def test_documented_examples_are_the_bundled_ones():
    docs = os.path.join(os.path.dirname(__file__), "..", "docs", "examples")
    for kind, path in EXAMPLES.items():
        assert open(os.path.join(docs, f"study_{kind}.toml"), "rb").read() == open(path, "rb").read()


def test_progress_bar_unless_quiet_and_a_band_without_the_median(tmp_path, capsys):
    cfg = _edit(study__percentiles=[10, 90], study__coverage_trials=0)
    p = tmp_path / "s.toml"
    p.write_text(_toml(cfg), encoding="utf-8")
    code, out, err = _run(capsys, str(p), "--out", str(tmp_path / "o"))
    assert code == 0 and "synchronous study [" in err and "100.0 %" in err, err
    files = set(os.listdir(tmp_path / "o"))
    assert {"study_errors.csv", "study_percentiles.png", "study_summary.txt"} <= files
    assert "study_coverage.png" not in files
    assert list(pd.read_csv(tmp_path / "o" / "study_errors.csv").columns[2:4]) == ["p10", "p90"]
    summary = (tmp_path / "o" / "study_summary.txt").read_text(encoding="utf-8")
    assert "percentiles: 10, 90" in summary and "speeds: 2 from 3000 to 4000 rpm" in summary
    assert len(pd.read_csv(tmp_path / "o" / "study_bands.csv")) == 2  # one band per point, none repeated
    code, out, err = _run(capsys, str(p), "--out", str(tmp_path / "o"), "--overwrite", "--quiet")
    assert code == 0 and err == ""


def test_unreachable_scheduler_is_one_line_within_seconds(tmp_path, capsys):
    import time

    t = time.monotonic()
    code, _, err = _run(capsys, EXAMPLES["impact"], "--out", str(tmp_path / "o"), "--trials", "20", "-q",
                        "--scheduler", "tcp://127.0.0.1:1")
    assert code == 1 and err.count("\n") == 1 and "scheduler" in err, err
    assert time.monotonic() - t < 30
    assert not any((tmp_path / "o").glob("study_*"))  # no results of a study that did not run
