"""docs/guide.md runs as written.

Every ```python block is executed in order in one namespace, every ```bash block line by line as a
``rotorid`` command line (in-process, through ``rotorid.cli.main``), and every ```toml block
preceded by ``<!-- guide-test: write NAME -->`` is written to NAME first; all of it in one empty
temporary working folder. A command's expected exit code is its comment's "exit code N" (0
otherwise). Python blocks whose first line is ``# needs ROSS`` are skipped when ROSS is not
installed (CI installs it). ```console blocks (installation) are not run. Then a few outcomes are
checked: the identified coefficients against the example's truth, the files the guide promises.
"""

import contextlib
import importlib.util
import io
import os
import re
import shlex
import time
from pathlib import Path

import numpy as np
import pytest

GUIDE = Path(__file__).resolve().parent.parent / "docs" / "guide.md"
FENCE = re.compile(r"(?:<!-- guide-test: write (?P<target>\S+) -->\n)?```(?P<lang>[a-z]*)\n(?P<body>.*?)```", re.S)
HAVE_ROSS = importlib.util.find_spec("ross") is not None


def _blocks(text):
    """(language, body, file to write or None, line number) of every fenced block, in order."""
    return [(m["lang"], m["body"], m["target"], text.count("\n", 0, m.start()) + 1) for m in FENCE.finditer(text)]


def _commands(body):
    """(argv, expected exit code, source line) of each command line of a bash block."""
    out = []
    for line in body.splitlines():
        if not line.strip():
            continue
        command, _, comment = line.partition("#")
        argv = shlex.split(command)
        code = re.search(r"exit code (\d+)", comment)
        out.append((argv, int(code.group(1)) if code else 0, line.strip()))
    return out


def _run_cli(argv):
    from rotorid import cli

    try:
        return cli.main(argv)
    except SystemExit as exc:   # argparse: --help, --version (0) and usage errors (2)
        return exc.code


def test_guide_structure():
    """The guide's blocks are what the runner expects, and its links point at files that exist."""
    text = GUIDE.read_text(encoding="utf-8")
    blocks = _blocks(text)
    langs = {lang for lang, *_ in blocks}
    assert langs <= {"python", "bash", "toml", "console"}, langs
    assert sum(lang == "python" for lang, *_ in blocks) >= 15
    for lang, body, target, line in blocks:
        if lang == "bash":
            for argv, _, src in _commands(body):
                assert argv[0] == "rotorid", f"guide.md:{line}: a bash block may hold rotorid commands only: {src}"
        if lang == "toml":
            assert target, f"guide.md:{line}: a toml block needs a <!-- guide-test: write NAME --> marker"
    # exactly the ten sections, in order
    heads = re.findall(r"^## (\d+)\. ", text, re.M)
    assert heads == [str(i) for i in range(1, 11)], heads
    for link in re.findall(r"\]\(([^)#]+)(?:#[^)]*)?\)", text):
        if not link.startswith("http"):
            assert (GUIDE.parent / link).exists(), f"broken link {link}"


def test_guide_runs(tmp_path, monkeypatch):
    """Every block of docs/guide.md, in order, in an empty folder; then the outcomes it promises."""
    text = GUIDE.read_text(encoding="utf-8")
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("MPLBACKEND", "Agg")
    namespace = {"__name__": "guide"}
    skipped = []
    timings = []
    stderr = {}   # command line -> what it printed on stderr
    for lang, body, target, line in _blocks(text):
        t0 = time.perf_counter()
        if target:
            Path(target).write_text(body, encoding="utf-8")
        elif lang == "python":
            if body.startswith("# needs ROSS") and not HAVE_ROSS:
                skipped.append(line)
                continue
            exec(compile(body, f"docs/guide.md:{line}", "exec"), namespace)
        elif lang == "bash":
            for argv, expected, src in _commands(body):
                err = io.StringIO()
                with contextlib.redirect_stderr(err):
                    code = _run_cli(argv[1:])
                assert code == expected, (f"guide.md:{line}: `{src}` exited with {code}, expected {expected}; "
                                          f"stderr: {err.getvalue()[-2000:]}")
                stderr[" ".join(argv)] = err.getvalue()
                if expected == 1:   # an error is one line on stderr (after the traceback with --debug)
                    assert err.getvalue().strip().splitlines()[-1].startswith("rotorid: error: ")
        timings.append((time.perf_counter() - t0, line))
    print("slowest blocks (s, guide line):", sorted(timings, reverse=True)[:5])

    # section 10: the typo is named in one line, with the suggestion; --debug adds the traceback
    assert stderr["rotorid check typo.toml"].strip() == ("rotorid: error: typo.toml: [imbalance.runs][0] unknown key "
                                                        "'angle_degs' (did you mean 'angle_deg'?)")
    assert "Traceback" in stderr["rotorid check typo.toml --debug"]

    from rotorid.example import truth

    true = truth()
    # section 2: the example's files and reports
    for path in ["nsf_demo/table5_critical_speeds.csv", "ex/out_imbalance/coefficients_imbalance.csv",
                 "ex/out_imbalance/result_imbalance.json", "ex/report_imbalance.html", "ex/out_impact/kcm_fit.csv",
                 "out_my_rig/coefficients_imbalance.xlsx",
                 "out_my_rig/coefficients_imbalance.json", "ex/out_imbalance_1x/coefficients_imbalance.csv",
                 "study_my_rig/study_errors.csv", "strict_impact/coefficients_impact.csv",
                 "my_rig.xlsx", "my_rig.json", "my_rig.nc"]:
        assert os.path.exists(path), path
    assert "Against the known coefficients" in Path("ex/report_imbalance.html").read_text(encoding="utf-8")
    # section 4: the CSV chain identifies the example's bearings (direct K within 1 %, C within 5 %)
    ident = namespace["ident"]
    # the example's speeds are whole numbers of samples per revolution at 5 kHz: its keyphasor pulses
    # fall at one position within a sample, where the edge shapes their samples allow leave the
    # interpolated times uncertain by 0.005-0.017 sample, in the error bars as a phase reference;
    # at the fastest speed that makes the damping "uncertain" (the guide says so), and only that
    assert ident.std_source == "measurement covariance + phase reference"
    assert ident.ok[:-1].all() and (ident.ok[-1] or ident.flag[-1] == "uncertain"), ident.flag
    iv = ident.interval(0.95)
    for b in range(2):
        for i in range(2):
            assert np.all((iv.c_lower[:, b, i, i] <= true.c[b, i, i]) & (true.c[b, i, i] <= iv.c_upper[:, b, i, i]))
    for b in range(2):
        for i in range(2):
            assert np.abs(ident.k[:, b, i, i] / true.k[b, i, i] - 1).max() < 0.01
            assert np.abs(ident.c[:, b, i, i] / true.c[b, i, i] - 1).max() < 0.05
    # ... and so do the DAQ tables
    tab = namespace["from_tables"].identification
    sel = (tab.speed_rpm >= 3500) & (tab.speed_rpm <= 5500)
    assert np.abs(tab.k[sel, 0, 0, 0] / true.k[0, 0, 0] - 1).max() < 0.01
    # section 3: the measured peak is near the predicted first forward critical speed
    assert abs(namespace["measured_peak_rpm"] - namespace["predicted_rpm"]) < 250
    # section 6: impacts, and the K-C-M fit of the direct stiffnesses
    kcm = namespace["impacts"].kcm
    assert np.abs(kcm.K[:, [0, 1], [0, 1]] / true.k[:, [0, 1], [0, 1]] - 1).max() < 0.02
    # section 7: two exact runs carry no uncertainty; with a covariance they do
    assert namespace["exact"].std_source == "none" and np.isnan(namespace["exact"].k_std).all()
    assert namespace["with_cov"].std_source == "measurement covariance"
    assert np.isfinite(namespace["with_cov"].k_std).all()
    # section 10: low speeds are ill-conditioned; ignored pedestals are wrong, which only the
    # negative direct damping they give away flags
    assert namespace["check"].cond[0].max() > 10 * namespace["check"].cond[-1].max()
    measured, ignored = namespace["measured"], namespace["ignored"]
    assert np.abs(measured.k[:, 0, 0, 0] / 3e6 - 1).max() < 1e-6
    assert np.abs(ignored.k[:, 0, 0, 0] / 3e6 - 1).max() > 0.5
    assert set(ignored.flag) == {"negative direct damping"} and measured.ok.all()
    if HAVE_ROSS:   # section 9: the identified bearings as ROSS elements, over rad/s
        assert np.allclose(namespace["brg1"].frequency, ident.speed_rpm[ident.ok] * np.pi / 30)
    if skipped:
        print(f"ROSS not installed: skipped the guide's ROSS blocks at lines {skipped}")
