import subprocess
import sys

import numpy as np
import pandas as pd

import rotorid
from rotorid import cli


def test_demo_writes_figures_and_tables(tmp_path, capsys):
    out = tmp_path / "demo"
    assert cli.main(["demo", "--out", str(out), "--step-rpm", "100"]) == 0
    printed = capsys.readouterr().out
    assert "Table 5" in printed and "3467 cpm" in printed
    for name in ["table5_critical_speeds.csv", "campbell.png", "figure3a_bode_set_A.png", "figure3b_bode_set_B.png",
                 "figure4_identified.png", "figure4_identified_measured.csv", "figure4_band_errors.csv"]:
        assert (out / name).stat().st_size > 0, name
    t5 = pd.read_csv(out / "table5_critical_speeds.csv")
    np.testing.assert_allclose(t5.speed_rpm[:2], [3467, 3676], atol=1)
    ident = pd.read_csv(out / "figure4_identified_exact.csv")
    assert {"speed_rpm", "Kxx1", "Cyy2", "cond1", "ok"} <= set(ident.columns)
    mid = ident[(ident.speed_rpm >= 3000) & (ident.speed_rpm <= 6000)]
    np.testing.assert_allclose(mid.Kxx1, 3.0e6, rtol=1e-8)
    bands = pd.read_csv(out / "figure4_band_errors.csv")
    # the measurement model spoils low speeds far more than the band between the critical speeds
    assert bands.K_direct.iloc[0] > 10 * bands.K_direct.iloc[2]


def test_console_script_help():
    r = subprocess.run([sys.executable, "-m", "rotorid.cli", "--help"], capture_output=True, text=True)
    assert r.returncode == 0 and "demo" in r.stdout


def test_check_validates_a_config_in_one_line(tmp_path, capsys):
    from rotorid.example import copy_example

    ex = copy_example(str(tmp_path / "ex"))
    assert cli.main(["check", f"{ex}/imbalance_1x_table.toml"]) == 0
    assert "valid" in capsys.readouterr().out
    bad = tmp_path / "bad.toml"
    bad.write_text('[rig]\nbuiltin = "nsf"\n[imbalance]\nstedy = false\n[[imbalance.runs]]\nfile = "x.tdms"\n'
                   'mass_g = [1, 1]\nangle_degs = [0, 0]\n')
    assert cli.main(["check", str(bad)]) == 1
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "did you mean 'steady'" in err and "did you mean 'angle_deg'" in err


def test_version(capsys):
    import pytest as _pytest

    from rotorid import __version__

    with _pytest.raises(SystemExit) as exc:
        cli.main(["--version"])
    assert exc.value.code == 0 and capsys.readouterr().out.strip() == f"rotorid {__version__}"


def test_identify_quiet_no_plot_and_strict(tmp_path, capsys):
    import os

    from rotorid import example

    ex = example.copy_example(str(tmp_path / "ex"))
    cfg = os.path.join(ex, "pedestal_imbalance.toml")
    # with the accelerometers' calibration in the error bars some points turn "uncertain"
    text = open(cfg, encoding="utf-8").read().replace("measured = true\n", "measured = true\naccel_gain_std = 0.02\n")
    open(cfg, "w", encoding="utf-8").write(text)
    out = tmp_path / "o"
    assert cli.main(["identify", "imbalance", cfg, "--out", str(out), "-q", "--no-plot"]) == 0
    captured = capsys.readouterr()
    assert captured.out == ""                                     # quiet: no progress lines
    assert not any(f.endswith(".png") for f in os.listdir(out))   # tables only
    assert "coefficients_imbalance.csv" in os.listdir(out)
    # strict: the same results, but flagged points (this example has some) exit with 3
    code = cli.main(["identify", "imbalance", cfg, "--out", str(out), "--overwrite", "-q", "--strict"])
    err = capsys.readouterr().err
    import pandas as pd

    flagged = (~pd.read_csv(out / "coefficients_imbalance.csv").ok).sum()
    assert flagged > 0
    assert code == 3 and "strict:" in err.splitlines()[-1]
    assert cli.main(["identify", "imbalance", cfg, "--out", str(out), "--overwrite", "-q"]) == 0
    # -v lists every flagged point with its reasons, one line each
    assert cli.main(["identify", "imbalance", cfg, "--out", str(out), "--overwrite", "-q", "-v", "--no-plot"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0] == f"{flagged} of {len(pd.read_csv(out / 'coefficients_imbalance.csv'))} points flagged:"
    assert len(lines) == 1 + flagged and all(" rpm: " in x for x in lines[1:])


def test_exit_codes_and_debug(tmp_path, capsys):
    """0 done, 1 a rotorid error (one line), 2 usage (argparse), --debug adds the traceback."""
    import pytest as _pytest

    missing = str(tmp_path / "none.toml")
    assert cli.main(["check", missing]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("rotorid: error:") and "none.toml" in err
    assert cli.main(["check", missing, "--debug"]) == 1
    err = capsys.readouterr().err
    assert "Traceback" in err and err.splitlines()[-1].startswith("rotorid: error:")
    for argv in (["bogus"], ["identify", "sideways", missing], ["demo", "--step-rpm", "fast"]):
        with _pytest.raises(SystemExit) as exc:
            cli.main(argv)
        assert exc.value.code == 2
        capsys.readouterr()


def test_an_unwritable_output_folder_is_one_line(tmp_path, capsys):
    import os

    if os.geteuid() == 0:
        # root writes anywhere: a file where the folder should be is refused by the system all the same
        blocker = tmp_path / "file"
        blocker.write_text("x")
        out = blocker / "sub"
    else:
        ro = tmp_path / "ro"
        ro.mkdir(mode=0o500)
        out = ro / "sub"
    assert cli.main(["example", "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("rotorid: error:") and "Traceback" not in err, err


def test_an_internal_error_is_one_line_with_a_hint(monkeypatch, capsys):
    from rotorid import example

    def broken(*a, **k):
        raise ZeroDivisionError("float division by zero")

    monkeypatch.setattr(example, "copy_example", broken)
    assert cli.main(["example", "--out", "x"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "internal error: ZeroDivisionError" in err and "--debug" in err


def test_every_command_help_shows_defaults(capsys):
    import pytest as _pytest

    with _pytest.raises(SystemExit):
        cli.main(["demo", "--help"])
    out = capsys.readouterr().out
    assert "(default: rotorid_demo)" in out and "(default: 50.0)" in out and "(default: 0.0)" in out
    assert "--debug" in out


def _table_example(tmp_path, run_name="S0", config_name="c.toml"):
    """The DAQ 1X table example config (fast), with its first run renamed, as ``config_name``."""
    import os
    import re

    from rotorid import example

    ex = example.path()
    text = open(os.path.join(ex, "imbalance_1x_table.toml"), encoding="utf-8").read()
    text = re.sub(r'"(daq_1x/[^"]+)"', lambda m: '"' + os.path.join(ex, m.group(1)).replace("\\", "/") + '"', text)
    text = text.replace('name = "S0"', f'name = "{run_name}"')
    p = tmp_path / config_name
    p.write_text(text, encoding="utf-8")
    return p


def test_identify_with_a_dollar_in_names_writes_every_figure(tmp_path, capsys):
    """A run named "S0 $x^$" (or a config named a$$.toml) made the figures raise a mathtext
    ValueError: 'internal error' and a folder with only the first run's table."""
    import os

    cfg = _table_example(tmp_path, run_name="S0 $x^$", config_name="a$$.toml")
    out = tmp_path / "o"
    assert cli.main(["identify", "imbalance", str(cfg), "--out", str(out), "-q"]) == 0
    err = capsys.readouterr().err
    assert "internal error" not in err, err
    files = os.listdir(out)
    assert "rotorid-manifest.json" in files and "coefficients_imbalance.png" in files
    assert sum(f.endswith("_polar.png") for f in files) == 4


def test_an_internal_error_message_stays_on_one_line(monkeypatch, capsys):
    def boom(args):
        raise ValueError("first\n  second\n   ^")

    monkeypatch.setattr(cli, "_run", boom)
    assert cli.main(["check", "x.toml"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "internal error: ValueError: first second ^" in err, err


def test_a_reader_that_goes_away_does_not_stop_identify(tmp_path):
    """rotorid identify ... | head: the BrokenPipeError of a progress line stopped the run half-way
    (exit 1, 'cannot use: Broken pipe', a folder without its coefficients)."""
    import os

    cfg = _table_example(tmp_path)
    out = tmp_path / "o"
    p = subprocess.Popen([sys.executable, "-m", "rotorid.cli", "identify", "imbalance", str(cfg), "--out", str(out),
                          "-v"], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    p.stdout.close()                     # the reader is gone before the first line
    err = p.stderr.read().decode()
    assert p.wait(timeout=300) == 0, err
    assert "Broken pipe" not in err and "Exception ignored" not in err, err
    assert {"rotorid-manifest.json", "coefficients_imbalance.csv"} <= set(os.listdir(out))


def test_identify_imbalance_applies_the_phase_calibration(tmp_path, capsys):
    """``phase_calibration = "apply"`` in [imbalance]: the chain calibrates (the same code as
    ``imbalance_chain(..., phase_calibration="apply")``), says so, and writes coefficients of the
    corrected vectors; "off" says nothing of it; a value outside the three is one line, exit 1."""
    import os

    from rotorid import example

    ex = example.copy_example(str(tmp_path / "ex"))
    cfg = os.path.join(ex, "imbalance.toml")
    text = open(cfg, encoding="utf-8").read()
    out = {}
    for mode in ("off", "apply"):
        open(cfg, "w", encoding="utf-8").write(text.replace("steady = true\n", f'steady = true\nphase_calibration = "{mode}"\n'))
        assert cli.main(["identify", "imbalance", cfg, "--out", str(tmp_path / mode), "--no-plot"]) == 0
        log = capsys.readouterr().out
        assert ("phase calibration applied" in log) == (mode == "apply")
        assert ("phase reference: offset" in log) == (mode == "apply")
        out[mode] = pd.read_csv(tmp_path / mode / "coefficients_imbalance.csv")
    assert not np.allclose(out["off"].filter(like="Cxx").to_numpy(), out["apply"].filter(like="Cxx").to_numpy())
    # the same numbers as the API's chain on the same files
    import warnings

    from rotorid import io, pipeline

    cmap = {"Prox DE X": {"to": "x1", "unit": "mil"}, "Prox DE Y": {"to": "y1", "unit": "mil"},
            "Prox FE X": {"to": "x2", "unit": "mil"}, "Prox FE Y": {"to": "y2", "unit": "mil"},
            "Keyphasor": {"to": "kp", "unit": "V"}}

    def rec(name):
        return io.load_recording(os.path.join(ex, "imbalance", name), channel_map=cmap)

    imbs = [rotorid.Imbalance(tuple(m * 1e-3 for m in mass_g), ang, name=n) for n, (mass_g, ang) in example.SETS.items()]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = pipeline.imbalance_chain(rotorid.nsf_rig().rotor, [rec(f"run_{n}.tdms") for n in example.SETS],
                                       baseline=rec("baseline.tdms"), slow_roll=rec("slow_roll.tdms"), imbalances=imbs,
                                       phase_calibration="apply")
    api = res.identification.to_dataframe()
    for col in ("Kxx1", "Cxx1", "Cyy2", "Cxx1_std"):
        np.testing.assert_allclose(out["apply"][col], api[col], rtol=1e-5)   # (the file holds 6 figures)
    open(cfg, "w", encoding="utf-8").write(text.replace("steady = true\n", 'steady = true\nphase_calibration = "yes"\n'))
    assert cli.main(["identify", "imbalance", cfg, "--out", str(tmp_path / "bad"), "--no-plot"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "phase_calibration" in err[0]


def test_an_applied_phase_calibration_of_1x_tables_reports_and_keeps_their_phase_scatter(tmp_path, capsys):
    """The example's 1X tables (no keyphasor, no stated accuracy) with ``phase_calibration =
    "apply"``: the calibration estimates the phase scatter between speeds from its misfit, says so
    on screen and in the result file, and keeps it in the coefficients' error bars (the same
    numbers as the API's chain with that calibration)."""
    import json
    import os

    from rotorid import example

    ex = example.copy_example(str(tmp_path / "ex"))
    cfg = os.path.join(ex, "imbalance_1x_table.toml")
    text = open(cfg, encoding="utf-8").read()
    assert "[imbalance]\n" in text
    open(cfg, "w", encoding="utf-8").write(text.replace("[imbalance]\n", '[imbalance]\nphase_calibration = "apply"\n'))
    assert cli.main(["identify", "imbalance", cfg, "--out", str(tmp_path / "o"), "--no-plot"]) == 0
    log = capsys.readouterr().out
    assert "a phase scatter of" in log and "the phase scatter between speeds it estimated in the error bars" in log, log
    result = json.load(open(tmp_path / "o" / "result_imbalance.json", encoding="utf-8"))
    assert any("a phase scatter of" in line for line in result["context"]["log"]), result["context"]["log"]


def test_impact_tests_of_one_name_write_an_frf_file_each(tmp_path, capsys):
    """Tests are named by direction and plane to 6 significant figures: two groups whose planes
    agree that far (a plane converted from inches, say) wrote one frf file over the other; the
    second now gets _2."""
    import os

    from rotorid import example

    ex = example.copy_example(str(tmp_path / "ex"))
    cfg = os.path.join(ex, "impact.toml")
    text = open(cfg, encoding="utf-8").read()
    # (the example's x impacts said to be 0.1 m and 0.1000001 m along the rotor: the coefficients
    # are off, the files are the point)
    text = text.replace('plane_m = 0.0\ndirection = "x"', 'plane_m = 0.1\ndirection = "x"')
    text += '\n[[impact.tests]]\nfile = "impact/impact_x.tdms"\nplane_m = 0.1000001\ndirection = "x"\n'
    open(cfg, "w", encoding="utf-8").write(text)
    out = tmp_path / "o"
    assert cli.main(["identify", "impact", cfg, "--out", str(out), "-q"]) == 0
    files = sorted(f for f in os.listdir(out) if f.startswith("frf_"))
    assert len(files) == 6 and "frf_x_0.1m_x5_2.csv" in files and "frf_x_0.1m_x5_2.png" in files, files


def test_distinct_file_stems():
    from rotorid.pipeline import _distinct

    assert _distinct(["a", "b", "A", "a", "a_2"]) == ["a", "b", "A_2", "a_3", "a_2_2"]


def test_identify_prints_each_warning_once(monkeypatch, capsys, tmp_path):
    """The chain's inner identifications (phase calibration, its reported path) repeat their
    warnings: "pedestal motion is up to 2.42 times ..." came 5-6 times per run (an independent
    simulator's log). The CLI prints each once."""
    import warnings

    from rotorid import pipeline

    def fake(*a, **k):
        for _ in range(3):
            with warnings.catch_warnings():      # (inner contexts reset Python's once-registry)
                warnings.warn("pedestal motion is up to 2.42 times the motion relative to the pedestals")
        warnings.warn("another")
        return None, None

    monkeypatch.setattr(pipeline, "run_config", fake)
    assert cli.main(["identify", "imbalance", str(tmp_path / "x.toml"), "-q"]) == 0
    err = capsys.readouterr().err
    assert err.count("pedestal motion is up to 2.42") == 1 and err.count("another") == 1, err


def test_the_impact_log_says_where_each_tests_error_bars_come_from(tmp_path, capsys):
    """The example's impact tests say, on screen and in the result file, where their error bars
    come from and on how many degrees of freedom: their 5 hits' scatter alone, for their first
    hits come 0.5 s into the recordings, too soon for a quiet record before them (the other
    sources' lines: ``test_few_impacts...`` in test_pipeline.py)."""
    import json
    import os

    from rotorid import example

    ex = example.copy_example(str(tmp_path / "ex"))
    assert cli.main(["identify", "impact", os.path.join(ex, "impact.toml"), "--out", str(tmp_path / "o"),
                     "--no-plot"]) == 0
    log = capsys.readouterr().out
    lines = [ln for ln in log.splitlines() if "error bars from" in ln]
    assert len(lines) == 2 and all("the scatter of its 5 impacts alone (4 dof; too little quiet record before the first hit"
                                   in ln for ln in lines), log
    result = json.load(open(tmp_path / "o" / "result_impact.json", encoding="utf-8"))
    assert sum("error bars from" in ln for ln in result["context"]["log"]) == 2, result["context"]["log"]


def test_the_imbalance_log_says_how_far_the_dwells_were_carried(tmp_path, capsys):
    """The bundled DAQ 1X tables' speeds are jittered by ±0.5 rpm: the log (screen and result
    file) says how far the rows were from the common speeds and that they were carried there."""
    import json
    import os
    import re

    from rotorid import example

    ex = example.copy_example(str(tmp_path / "ex"))
    assert cli.main(["identify", "imbalance", os.path.join(ex, "imbalance_1x_table.toml"), "--out",
                     str(tmp_path / "o"), "--no-plot"]) == 0
    log = capsys.readouterr().out
    line = next(ln for ln in log.splitlines() if "carried to them through the rotor" in ln)
    far = float(re.search(r"dwell speeds up to ([\d.]+) rpm", line).group(1))
    assert 0.1 <= far <= 1.0 and "and the baseline" in line and re.search(r"\(\d+ passes\)", line), line
    result = json.load(open(tmp_path / "o" / "result_imbalance.json", encoding="utf-8"))
    assert any("carried to them through the rotor" in ln for ln in result["context"]["log"])
