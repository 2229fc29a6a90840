"""The HTML report of an identification (issue 14, item 4): content, escaping, self-containedness,
the reloadable result file, the CLI, and a render in headless Chromium."""

import base64
import hashlib
import json
import os
import re
import shutil
import subprocess
import warnings
from html.parser import HTMLParser

import numpy as np
import pytest

import rotorid
from rotorid import RotoridError, cli
from rotorid.report import file_checksums, load_result, render_report, write_report

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


class Page(HTMLParser):
    """Tags, attributes and text of a page (and whether it parses as nested HTML)."""

    def __init__(self, text):
        super().__init__()
        self.tags, self.text = [], []
        self.feed(text)

    def handle_starttag(self, tag, attrs):
        self.tags.append((tag, dict(attrs)))

    def handle_data(self, data):
        self.text.append(data)

    def all(self, tag, **attrs):
        return [a for t, a in self.tags if t == tag and all(a.get(k) == v for k, v in attrs.items())]


@pytest.fixture(scope="module")
def ident():
    from noisy import noisy_nsf_runs

    rig, runs = noisy_nsf_runs(np.arange(1500.0, 6001.0, 500.0), "ABC", seed=4)
    out = rotorid.identify_synchronous(rig.rotor, runs)
    assert out.ok.any() and (~out.ok).any()   # the page must show both kinds of points
    return out


@pytest.fixture(scope="module")
def page(ident):
    rig = rotorid.nsf_rig()
    return render_report(ident, truth=rig.bearings, warnings=["speed 1500 rpm: <low> & 'odd'"],
                         log=["  baseline subtracted"], settings={"imbalance": {"cond_max": 1e4}, "note": "<script>"},
                         command="rotorid identify imbalance lab.toml", kind="imbalance", date="2024-05-01T10:00:00")


def test_tables_hold_the_coefficients_and_intervals(ident, page):
    doc = Page(page)
    iv = ident.interval(0.95)
    cells = doc.all("td")
    coef_cells = [a for a in cells if "data-coef" in a and "data-lo" in a]
    assert len(coef_cells) == ident.axis.size * 16
    seen = {}
    for a in coef_cells:
        seen.setdefault(a["data-coef"], []).append(a)
    for name, rows in seen.items():
        sym, i, j, b = name[0], "xy".index(name[1]), "xy".index(name[2]), int(name[3]) - 1
        val, lo, hi = (ident.k, iv.k_lower, iv.k_upper) if sym == "K" else (ident.c, iv.c_lower, iv.c_upper)
        np.testing.assert_array_equal([float(r["data-value"]) for r in rows], val[:, b, i, j])
        np.testing.assert_array_equal([float(r["data-lo"]) for r in rows], lo[:, b, i, j])
        np.testing.assert_array_equal([float(r["data-hi"]) for r in rows], hi[:, b, i, j])
    # the printed value (MN/m, 5 significant digits) is the number
    m = re.search(r'data-coef="Kxx1" data-value="([^"]+)"[^>]*>([^<]+)<', page)
    assert float(m.group(2)) == pytest.approx(float(m.group(1)) * 1e-6, rel=1e-4)
    # four coefficient tables, one per quantity and bearing, and the diagnostics
    assert len(doc.all("table", **{"class": "coef"})) == 4
    assert len(doc.all("table", **{"class": "diagnostics"})) == 1
    assert "Against the known coefficients" in page and "measurement covariance" in page


def test_us_units(ident):
    page = render_report(ident, units="US")
    m = re.search(r'data-coef="Kyy2" data-value="([^"]+)"[^>]*>([^<]+)<', page)
    assert float(m.group(2)) == pytest.approx(float(m.group(1)) * 0.0254 / 4.4482216152605, rel=1e-4)
    assert "lbf/in" in page and "MN/m)</h3>" not in page
    with pytest.raises(RotoridError, match="units must be 'SI' or 'US'"):
        render_report(ident, units="imperial")


def test_flagged_points_are_listed_with_their_reasons(ident, page):
    doc = Page(page)
    rows = doc.all("tr", **{"class": "flagged-point"})
    assert [int(r["data-index"]) for r in rows] == list(np.flatnonzero(~ident.ok))
    for p in np.flatnonzero(~ident.ok):
        block = page[page.index(f'id="flag-{p}"'):]
        block = block[:block.index("</tr>")]
        for reason in str(ident.flag[p]).split("; "):
            assert f"<b>{reason}</b>" in block
        assert f'href="#flag-{p}"' in page      # linked from the tables
    assert f"{(~ident.ok).sum()} of {ident.axis.size} points are flagged" in page


def test_user_strings_are_escaped(page):
    assert "<script>" not in page and "&lt;script&gt;" in page
    assert "&lt;low&gt; &amp; &#x27;odd&#x27;" in page
    assert Page(page).all("script") == []


def test_page_is_self_contained_and_images_are_png(page):
    assert "http://" not in page and "https://" not in page
    doc = Page(page)
    for tag, attrs in doc.tags:
        for key in ("src", "href"):
            v = attrs.get(key)
            if v is not None:
                assert v.startswith(("data:image/png;base64,", "#")), (tag, key, v[:40])
    assert doc.all("link") == [] and doc.all("script") == []
    imgs = doc.all("img")
    assert len(imgs) >= 2
    for im in imgs:
        png = base64.b64decode(im["src"].split(",", 1)[1], validate=True)
        assert png.startswith(PNG_MAGIC) and len(png) > 10_000


def test_input_files_with_checksums(tmp_path, ident):
    a, b = tmp_path / "run A.csv", tmp_path / "base<line>.csv"
    a.write_bytes(b"speed,x\n1,2\n")
    b.write_bytes(os.urandom(3000))
    page = render_report(ident, input_files=[a, b])
    for f in (a, b):
        digest = hashlib.sha256(f.read_bytes()).hexdigest()
        assert digest in page
    assert "base&lt;line&gt;.csv" in page and f"{b.stat().st_size:,}" in page
    with pytest.raises(RotoridError, match="cannot read input file"):
        file_checksums([tmp_path / "missing.csv"])
    with pytest.raises(RotoridError, match="input_files must be"):
        render_report(ident, input_files=[{"name": "x"}])


def test_write_report_is_atomic_and_refuses_to_overwrite(tmp_path, ident):
    p = tmp_path / "page.html"
    write_report(p, ident)
    first = p.read_text(encoding="utf-8")
    with pytest.raises(RotoridError, match="page.html' exists; pass overwrite=True"):
        write_report(p, ident)
    assert p.read_text(encoding="utf-8") == first
    write_report(p, ident, overwrite=True, title="second")
    assert "<title>second</title>" in p.read_text(encoding="utf-8")
    assert sorted(os.listdir(tmp_path)) == ["page.html"]          # no temporary file left
    with pytest.raises(RotoridError, match="must end in .html"):
        write_report(tmp_path / "page.txt", ident)
    with pytest.raises(RotoridError, match="rotorid Identification"):
        render_report("not an identification")


def test_json_result_round_trip_reproduces_the_page(tmp_path, ident):
    p = rotorid.exports.to_json(ident, tmp_path / "r.json", units="US",
                                context={"kind": "imbalance", "warnings": ["w1"], "date": "2024-05-01T10:00:00"})
    back, ctx = load_result(p)
    np.testing.assert_allclose(back.k, ident.k, rtol=1e-12)
    np.testing.assert_allclose(back.interval().c_upper, ident.interval().c_upper, rtol=1e-12)
    assert list(back.flag) == list(ident.flag) and list(back.ok) == list(ident.ok)
    np.testing.assert_array_equal(back.cond, ident.cond)
    assert ctx["warnings"] == ["w1"] and ctx["kind"] == "imbalance"
    page = render_report(back, **ctx)
    assert "w1" in page and "2024-05-01T10:00:00" in page
    # a document of the first version (no codes, bias or amplitudes) still loads
    doc = json.loads(ident.to_json())
    for key in ("rel_amplitude", "rel_std", "K_bias", "C_bias", "flag_code", "flag_reasons", "runs", "dof_infinite",
                "K_std_residual", "C_std_residual"):
        doc.pop(key)
    old, _ = load_result(_write(tmp_path / "old.json", json.dumps(doc)))
    assert list(old.flag) == list(ident.flag)
    np.testing.assert_allclose(old.interval().k_lower, ident.interval().k_lower, rtol=1e-9)


def _write(path, text):
    path.write_text(text, encoding="utf-8")
    return path


@pytest.mark.parametrize("content, match", [
    ("{not json", "is not valid JSON"),
    ('{"format": "something-else"}', "not a rotorid identification"),
    ('{"format": "rotorid-identification", "version": 7}', "newer rotorid"),
    ('{"format": "rotorid-identification", "version": 1, "axis_name": "speed_rpm"}', "missing"),
])
def test_bad_result_files(tmp_path, content, match):
    with pytest.raises(RotoridError, match=match):
        load_result(_write(tmp_path / "r.json", content))


# --- the command line -----------------------------------------------------------------------

@pytest.fixture(scope="module")
def example(tmp_path_factory):
    from rotorid.example import copy_example

    return copy_example(str(tmp_path_factory.mktemp("ex") / "ex"))


@pytest.fixture(scope="module")
def identified(example, tmp_path_factory):
    """rotorid identify impact with --report (this example warns about coherence)."""
    out = tmp_path_factory.mktemp("id") / "out"
    page = out.parent / "page.html"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        code = cli.main(["identify", "impact", f"{example}/impact.toml", "--out", str(out), "-q", "--no-plot",
                         "--report", str(page)])
    assert code == 0
    return out, page


def test_identify_report_writes_page_and_result(identified, example):
    out, page = identified
    text = page.read_text(encoding="utf-8")
    assert (out / "result_impact.json").is_file()
    manifest = json.loads((out / "rotorid-manifest.json").read_text())
    assert "result_impact.json" in manifest["files"]
    doc = Page(text)
    assert len(doc.all("table", **{"class": "coef"})) == 4 and len(doc.all("img")) >= 2
    # the settings and the input files, with checksums that match the files
    assert "&quot;band_hz&quot;" in text and "impact.toml" in text
    for name in ("impact.toml", "impact/impact_x.tdms", "impact/impact_y.tdms"):
        assert os.path.exists(os.path.join(example, name)), name
        path = os.path.join(example, name)
        if os.path.exists(path):
            assert hashlib.sha256(open(path, "rb").read()).hexdigest() in text, name
    result = json.loads((out / "result_impact.json").read_text())
    files = result["context"]["input_files"]
    assert files[0]["role"] == "config" and len(files) >= 3
    for f in files:
        assert hashlib.sha256(open(f["path"], "rb").read()).hexdigest() == f["sha256"]
        assert f["sha256"] in text
    # the warnings of the run are on the page
    assert result["context"]["warnings"] and all(w.split(";")[0] in text for w in result["context"]["warnings"])
    assert "coherence" in text


def test_report_subcommand_from_folder_and_file(identified, tmp_path, capsys):
    out, _ = identified
    p = tmp_path / "again.html"
    assert cli.main(["report", str(out), "--out", str(p), "--units", "us"]) == 0
    assert "flagged" in capsys.readouterr().out
    text = p.read_text(encoding="utf-8")
    assert "lbf/in" in text and "Flagged points and why" in text
    # refused without --overwrite, then replaced with it; the result file itself also works
    assert cli.main(["report", str(out / "result_impact.json"), "--out", str(p)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "exists" in err and "--overwrite" in err
    assert cli.main(["report", str(out / "result_impact.json"), "--out", str(p), "--overwrite"]) == 0
    assert "MN/m" in p.read_text(encoding="utf-8")


def test_report_subcommand_default_name_and_truth(example, tmp_path, capsys):
    out = tmp_path / "o"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert cli.main(["identify", "imbalance", f"{example}/imbalance_1x_table.toml", "--out", str(out), "-q",
                         "--no-plot"]) == 0
    assert not any(f.endswith(".html") for f in os.listdir(out))   # no report unless asked
    assert cli.main(["report", str(out), "--truth", f"{example}/truth.toml"]) == 0
    text = (out / "report_imbalance.html").read_text(encoding="utf-8")
    assert "Against the known coefficients" in text and "Compensated 1X response" in text
    capsys.readouterr()
    bad = _write(tmp_path / "t.toml", "k = 1\n")
    assert cli.main(["report", str(out), "--out", str(tmp_path / "x.html"), "--truth", str(bad)]) == 1
    assert "--truth" in capsys.readouterr().err


@pytest.mark.parametrize("setup, match", [
    (lambda d: d / "missing.json", "not found"),
    (lambda d: _write(d / "garbled.json", '{"format": "rotorid-identification", "version": 1, "K": [1,'),
     "not valid JSON"),
    (lambda d: _write(d / "other.json", "[1, 2, 3]"), "not a rotorid identification"),
    (lambda d: d, "holds no rotorid result"),
])
def test_report_subcommand_bad_result(tmp_path, capsys, setup, match):
    target = setup(tmp_path)
    assert cli.main(["report", str(target), "--out", str(tmp_path / "p.html")]) == 1
    err = capsys.readouterr().err
    assert err.startswith("rotorid: error:") and err.count("\n") == 1 and match in err
    assert not (tmp_path / "p.html").exists()


def test_config_output_report_key(example, tmp_path):
    from rotorid import pipeline
    from rotorid.config import ConfigError, parse_config

    cfg = os.path.join(example, "imbalance_1x_table.toml")
    text = open(cfg, encoding="utf-8").read().replace('units = "SI"', 'units = "SI"\nreport = "day1.html"')
    cfg2 = _write(tmp_path / "c.toml", text.replace('"daq_1x/', f'"{example}/daq_1x/'))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        _, files = pipeline.run_config(cfg2, "imbalance", out_dir=str(tmp_path / "o"), log=lambda m: None,
                                       plots=False)
    assert (tmp_path / "o" / "day1.html").is_file() and str(tmp_path / "o" / "day1.html") in files
    # an earlier run's report is refused like its other results
    with pytest.raises(RotoridError, match="already holds"):
        pipeline.run_config(cfg2, "imbalance", out_dir=str(tmp_path / "o"), log=lambda m: None, plots=False)
    base = {"rig": {"builtin": "nsf"}, "impact": {"tests": [{"file": "h.tdms", "plane_m": 0.0, "direction": "x"}]}}
    assert parse_config({**base, "output": {"report": True}}).output.report is True
    for bad in ("sub/page.html", "page.pdf", 3):
        with pytest.raises(ConfigError, match="report"):
            parse_config({**base, "output": {"report": bad}})


def test_identify_report_refused_before_computing(example, tmp_path, capsys):
    page = _write(tmp_path / "page.html", "mine")
    assert cli.main(["identify", "imbalance", f"{example}/imbalance_1x_table.toml", "--out", str(tmp_path / "o"),
                     "-q", "--report", str(page)]) == 1
    assert "exists" in capsys.readouterr().err and page.read_text() == "mine"
    assert not (tmp_path / "o" / "coefficients_imbalance.csv").exists()


# --- headless Chromium --------------------------------------------------------------------------

def _chromium():
    for name in ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable"):
        found = shutil.which(name)
        if found:
            return found
    return None


@pytest.mark.skipif(_chromium() is None, reason="no chromium binary on PATH (apt-get install chromium)")
def test_renders_in_headless_chromium(tmp_path, ident):
    p = write_report(tmp_path / "page.html", ident, truth=rotorid.nsf_rig().bearings, warnings=["a warning"])
    base = [_chromium(), "--headless", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
            "--no-first-run", "--disable-extensions", "--disable-background-networking", f"--user-data-dir={tmp_path / 'u'}"]
    url = "file://" + os.path.abspath(p)
    dom = subprocess.run(base + ["--dump-dom", url], capture_output=True, text=True, timeout=120)
    assert dom.returncode == 0, dom.stderr[-2000:]
    parsed = Page(dom.stdout)
    assert len(parsed.all("table", **{"class": "coef"})) == 4
    assert len(parsed.all("tr", **{"class": "flagged-point"})) == int((~ident.ok).sum())
    assert len(parsed.all("img")) >= 2 and "Flagged points and why" in dom.stdout
    shot = tmp_path / "shot.png"
    r = subprocess.run(base + ["--hide-scrollbars", "--window-size=1280,2000", f"--screenshot={shot}", url],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and shot.is_file(), r.stderr[-2000:]
    from PIL import Image

    im = np.asarray(Image.open(shot).convert("L"), dtype=float)
    assert im.shape == (2000, 1280)
    # not blank: dark text and figures on a light page, in every band down the page
    assert im.std() > 20
    for band in np.array_split(im, 4):
        assert (band < 100).mean() > 0.002 and (band > 200).mean() > 0.3


def test_docs_report_md_python_blocks_run():
    """The ```python blocks of docs/report.md run as written, in order, in one namespace."""
    from docblocks import read, run_python_blocks

    namespace = run_python_blocks(read("docs/report.md"), "docs/report.md", min_blocks=2)
    assert "html" in namespace


def test_docstring_examples():
    import doctest

    import rotorid.report

    res = doctest.testmod(rotorid.report, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    assert res.attempted >= 4 and res.failed == 0


# --- regressions (review of the report feature) -------------------------------------------------

import rotorid.exports  # noqa: E402  (the lazy package does not load it by attribute)


def _zero_point_ident():
    """Two runs with no response at the second speed: a singular point (cond = inf)."""
    rig = rotorid.nsf_rig()
    rpm = np.arange(2000.0, 4001.0, 500.0)
    runs = [rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances[s], speed_rpm=rpm) for s in "AB"]
    for r in runs:
        r.q[1] = 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return rotorid.identify_synchronous(rig.rotor, runs)


def test_json_round_trip_keeps_infinite_cond_of_singular_points():
    ident = _zero_point_ident()
    assert np.isinf(ident.cond[1]).all() and ident.flag[1] == "singular"
    for units in ("SI", "US"):
        back = rotorid.exports.from_json(ident.to_json(units=units))
        np.testing.assert_array_equal(back.cond, ident.cond)      # inf, not NaN (null in "cond")
    assert "cond ∞ (bearing 1), ∞ (bearing 2)" in render_report(back)


def test_json_round_trip_adds_no_bias_where_there_was_none():
    # noise-free impacts, 3 tests (redundant): no estimator bias; the reader must not rebuild one
    # from the rounding of the stored intervals (that is for documents without the "K_bias" key)
    rig = rotorid.nsf_rig()
    f = np.arange(5.0, 150.01, 5.0)
    tests = [rotorid.impact_frf(rig.rotor, rig.bearings, speed_rpm=1000, freq_hz=f, plane=p, direction=d)
             for p, d in ((0.0, "x"), (0.0, "y"), (0.05, "x"))]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ident = rotorid.identify_impact(rig.rotor, tests)
    assert ident.k_bias is None
    for units in ("SI", "US"):
        back = rotorid.exports.from_json(ident.to_json(units=units))
        assert back.k_bias is None and back.c_bias is None
        np.testing.assert_allclose(back.interval().k_upper, ident.interval().k_upper, rtol=1e-12)


@pytest.mark.parametrize("key, value", [("flag_code", ["a", "b", "c", "d", "e"]), ("flag_code", [2 ** 70] * 5),
                                        ("flag_code", [0.5] * 5), ("flag_reasons", 5), ("flag_reasons", "abc")])
def test_from_json_rebuilds_garbled_flag_codes(key, value):
    ident = _zero_point_ident()
    doc = json.loads(ident.to_json())
    doc[key] = value
    back = rotorid.exports.from_json(json.dumps(doc))
    assert list(back.flag) == list(ident.flag) and list(back.ok) == list(ident.ok)


def test_from_json_refuses_runs_that_are_not_a_list():
    doc = json.loads(_zero_point_ident().to_json())
    doc["runs"] = "S0"
    with pytest.raises(RotoridError, match="'runs' must be a list"):
        rotorid.exports.from_json(json.dumps(doc))


@pytest.mark.parametrize("key, value, match", [
    ("input_files", [{"name": "a.csv", "size": "x", "sha256": "00"}], "input_files must be"),
    ("responses", [{"name": "S0", "axis": [1.0, 2.0], "re": [[1, 2, 3, 4], [1]], "im": [[1, 2, 3, 4], [1]]}],
     "lists of numbers"),
])
def test_garbled_context_is_a_one_line_error(tmp_path, capsys, ident, key, value, match):
    p = rotorid.exports.to_json(ident, tmp_path / "r.json", context={key: value})
    assert cli.main(["report", str(p), "--out", str(tmp_path / "p.html")]) == 1
    err = capsys.readouterr().err
    assert err.startswith("rotorid: error:") and match in err and "internal error" not in err
    assert not (tmp_path / "p.html").exists()


def test_report_truth_with_ragged_lists_is_a_one_line_error(tmp_path, capsys, ident):
    p = rotorid.exports.to_json(ident, tmp_path / "r.json")
    bad = _write(tmp_path / "t.toml", "k = [[[1, 2], [3]], [[1, 2], [3, 4]]]\nc = 1\n")
    assert cli.main(["report", str(p), "--out", str(tmp_path / "p.html"), "--truth", str(bad)]) == 1
    err = capsys.readouterr().err
    assert err.startswith("rotorid: error: --truth") and "internal error" not in err


def test_dollar_signs_in_names_do_not_break_the_figures(ident):
    rig = rotorid.nsf_rig()
    runs = [rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances[s], speed_rpm=[3000.0, 4000.0])
            for s in "AB"]
    runs[0].name = "mass $^$ 5 g"                     # mathtext that matplotlib cannot parse
    page = render_report(ident, responses=runs, title="rig $\\frac$ day 1")
    assert "mass $^$ 5 g" in page and "rig $\\frac$ day 1" in page


def test_coefficients_json_without_context_keeps_its_units(tmp_path, ident):
    ident.to_json(tmp_path / "coefficients_imbalance.json", units="US")
    _, ctx = load_result(tmp_path)
    assert ctx["units"] == "US"


def _table_config(example, tmp_path, extra=""):
    cfg = os.path.join(example, "imbalance_1x_table.toml")
    text = open(cfg, encoding="utf-8").read().replace('units = "SI"', 'units = "SI"' + extra)
    return _write(tmp_path / "c.toml", text.replace('"daq_1x/', f'"{example}/daq_1x/'))


def test_report_option_named_like_the_config_key_goes_where_it_says(example, tmp_path, monkeypatch):
    # [output] report = "day1.html" and --report day1.html: the option's file is in the working folder
    cfg = _table_config(example, tmp_path, '\nreport = "day1.html"')
    cwd = tmp_path / "cwd"
    cwd.mkdir()
    monkeypatch.chdir(cwd)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert cli.main(["identify", "imbalance", str(cfg), "--out", str(tmp_path / "o"), "-q", "--no-plot",
                         "--report", "day1.html"]) == 0
    assert (cwd / "day1.html").is_file() and not (tmp_path / "o" / "day1.html").exists()


def test_report_outside_the_folder_that_cannot_be_written(example, tmp_path, monkeypatch):
    from rotorid import pipeline, report

    cfg = _table_config(example, tmp_path)
    elsewhere = tmp_path / "share"
    elsewhere.mkdir()
    real_access = os.access
    # a folder without write permission is refused before anything is computed
    monkeypatch.setattr(os, "access", lambda p, mode: False if str(p) == str(elsewhere) else real_access(p, mode))
    with pytest.raises(RotoridError, match="not writable"):
        pipeline.run_config(cfg, "imbalance", out_dir=str(tmp_path / "o"), log=lambda m: None, plots=False,
                            report=str(elsewhere / "p.html"))
    assert not (tmp_path / "o").exists()
    monkeypatch.setattr(os, "access", real_access)

    # a page that fails to be written all the same leaves complete results with their manifest
    def fail(*a, **k):
        raise RotoridError("cannot write the page: disk full")

    monkeypatch.setattr(report, "write_report", fail)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with pytest.raises(RotoridError, match="disk full"):
            pipeline.run_config(cfg, "imbalance", out_dir=str(tmp_path / "o"), log=lambda m: None, plots=False,
                                report=str(elsewhere / "p.html"))
    manifest = json.loads((tmp_path / "o" / "rotorid-manifest.json").read_text())
    assert "result_imbalance.json" in manifest["files"] and not (elsewhere / "p.html").exists()
