"""Command line: ``rotorid demo --out DIR`` runs the report's numerical experiments on the NSF rig;
``identify``, ``check``, ``study`` and ``example`` work from TOML configs (docs/config.md)."""

from __future__ import annotations

import argparse
import os
import sys


def _one_line_warning(message, category, filename, lineno, file=None, line=None):
    return f"rotorid: warning: {message}\n"


#: exit codes (README, "From raw recordings to coefficients")
EXIT_OK, EXIT_ERROR, EXIT_USAGE, EXIT_STRICT = 0, 1, 2, 3


class _Formatter(argparse.HelpFormatter):
    """Help that shows every option's default (``--help`` of each command), unless the help already
    says it or there is none to show (flags, options that are off by default)."""

    def _get_help_string(self, action):
        text = action.help or ""
        default = action.default
        if (not (default is None or default is False or default is argparse.SUPPRESS) and "default" not in text
                and action.option_strings):
            text += " (default: %(default)s)"
        return text


def _parser() -> argparse.ArgumentParser:
    from . import __version__

    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--debug", action="store_true", help="on an error, print the full traceback too")
    ap = argparse.ArgumentParser(prog="rotorid", description="Bearing coefficient identification for rigid rotors",
                                 epilog="exit codes: 0 done, 1 error (one line on stderr), 2 usage error, "
                                        "3 identify --strict: done but with flagged points or warnings",
                                 formatter_class=_Formatter)
    ap.add_argument("--version", action="version", version=f"rotorid {__version__}")
    sub = ap.add_subparsers(dest="cmd", required=True, metavar="COMMAND")
    _add = sub.add_parser

    def add_parser(name, **kw):
        return _add(name, parents=[common], formatter_class=_Formatter, **kw)

    sub.add_parser = add_parser
    d = sub.add_parser("demo", help="run the report's numerical experiments on the built-in NSF rig")
    d.add_argument("--out", default="rotorid_demo", help="output directory for PNG figures and CSV tables")
    d.add_argument("--step-rpm", type=float, default=50.0,
                   help="speed step of the imbalance sweep to 10000 rpm (rpm, 1 to 10000)")
    d.add_argument("--amplitude-resolution-um", type=float, default=None,
                   help="1X amplitude resolution of the measurement model (µm; default 0.0254 = 0.001 mil)")
    d.add_argument("--phase-resolution-deg", type=float, default=None, help="1X phase resolution (deg)")
    d.add_argument("--noise-um", type=float, default=0.0, help="added complex Gaussian noise (µm rms)")
    d.add_argument("--overwrite", action="store_true", help="replace the results of an earlier demo in the folder")
    d.add_argument("--quiet", "-q", action="store_true", help="no progress lines")
    i = sub.add_parser("identify", help="identify bearing coefficients from raw recordings described by a TOML config")
    i.add_argument("kind", choices=["imbalance", "impact"])
    i.add_argument("config", help="TOML config file (every key: docs/config.md)")
    i.add_argument("--out", default=None, help="output directory (default: [output] dir of the config)")
    i.add_argument("--overwrite", action="store_true", help="replace the results of an earlier run in the folder "
                   "(stale ones are removed); without it such a folder is refused")
    i.add_argument("--no-plot", action="store_true", help="write the tables only (no PNG figures)")
    i.add_argument("--quiet", "-q", action="store_true", help="no progress lines (errors and warnings still print)")
    i.add_argument("--verbose", "-v", action="store_true", help="also list every flagged point and why")
    i.add_argument("--strict", action="store_true", help="exit with 3 when points are flagged or warnings fired "
                   "(the results are written all the same)")
    i.add_argument("--report", default=None, metavar="PAGE.html",
                   help="also write a self-contained HTML report of the run there (default: the config's [output] "
                        "report, none unless set; docs/report.md)")
    rp = sub.add_parser("report", help="a self-contained HTML report of an identification written by rotorid identify")
    rp.add_argument("result", help="the output folder of rotorid identify, or its result_<kind>.json")
    rp.add_argument("--out", default=None, metavar="PAGE.html",
                    help="the HTML file to write (default: report_<kind>.html beside the result)")
    rp.add_argument("--overwrite", action="store_true", help="replace an existing report file")
    rp.add_argument("--units", default=None, type=str.upper, choices=["SI", "US"],
                    help="units of the tables (default: those of the run's config, else SI)")
    rp.add_argument("--truth", default=None, metavar="TRUTH.toml",
                    help="known coefficients to compare with: a TOML file with k and c as [bearing][i][j] in N/m and "
                         "N*s/m (as the example data set's truth.toml)")
    c = sub.add_parser("check", help="validate a TOML config (keys, types, units, files) without processing anything")
    c.add_argument("config", help="TOML config file (every key: docs/config.md)")
    s = sub.add_parser("study", help="Monte Carlo study of a test's accuracy (and trial-mass design) from a TOML config")
    s.add_argument("config", help="study config (TOML; every key: docs/config.md, examples: rotorid example)")
    s.add_argument("--out", default=None, help="output directory (default: [output] dir of the config)")
    s.add_argument("--overwrite", action="store_true", help="replace the results of an earlier study in the folder")
    s.add_argument("--trials", type=int, default=None, help="number of simulated tests (overrides the config)")
    s.add_argument("--seed", type=int, default=None, help="seed of the random numbers (overrides the config)")
    s.add_argument("--quiet", "-q", action="store_true", help="no progress bar")
    s.add_argument("--scheduler", default=None, help="run on a Dask cluster: its scheduler address, e.g. "
                   "tcp://10.0.0.5:8786 (needs rotorid[dask]; default: this machine's cores)")
    pr = sub.add_parser("predict", help="predicted coefficients of series supports (bearing table + squeeze film "
                        "damper) from a TOML config, as a table rotorid compare reads")
    pr.add_argument("config", help="prediction config (TOML; every key: docs/config.md, 'Prediction configs')")
    pr.add_argument("--out", default=None, help="output directory (default: [output] dir of the config)")
    pr.add_argument("--overwrite", action="store_true", help="replace the results of an earlier prediction")
    cp = sub.add_parser("compare", help="put predicted support coefficients next to identified ones (tables and a plot)")
    cp.add_argument("identified", help="coefficient table written by rotorid identify (coefficients_*.csv)")
    cp.add_argument("predicted", help="predicted coefficients: the same axis column (speed_rpm or freq_hz) and "
                    "Kxx1 ... Cyy2 (SI, or with rotorid's US suffixes)")
    cp.add_argument("--out", default="rotorid_compare", help="output directory")
    cp.add_argument("--overwrite", action="store_true", help="replace the results of an earlier comparison")
    e = sub.add_parser("example", help="write the bundled example data set (raw recordings + configs) to a directory")
    e.add_argument("--out", default="rotorid_example", help="output directory")
    e.add_argument("--overwrite", action="store_true", help="replace files of the example already in the folder")
    return ap


def main(argv=None) -> int:
    """Run the command line; returns the exit code (0 done, 1 rotorid error, 2 usage, 3 --strict).

    Errors print as one line on stderr (``rotorid: error: ...``); ``--debug`` adds the traceback.
    """
    import warnings

    warnings.formatwarning = _one_line_warning
    args = _parser().parse_args(argv)   # usage errors: argparse prints them and exits with 2
    from .errors import RotoridError

    stdout, sys.stdout = sys.stdout, _Stdout(sys.stdout)
    try:
        return _run(args)
    except RotoridError as exc:
        return _fail(args, f"rotorid: error: {exc}")
    except OSError as exc:   # a file or folder the system refused (permissions, full disk, ...)
        where = f" {exc.filename!r}" if getattr(exc, "filename", None) else ""
        return _fail(args, f"rotorid: error: cannot use{where}: {exc.strerror or exc}")
    except KeyboardInterrupt:
        print("rotorid: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:  # noqa: BLE001 - a bug: still one line, the traceback on request
        return _fail(args, f"rotorid: internal error: {type(exc).__name__}: {' '.join(str(exc).split())} (run with "
                           "--debug for the traceback, and please report it)")
    finally:
        sys.stdout.flush()
        sys.stdout = stdout


class _Stdout:
    """``sys.stdout`` while a command runs: when its reader goes away (``rotorid identify ... | head``)
    the rest of the output is dropped, instead of a BrokenPipeError stopping the work half-way."""

    def __init__(self, stream):
        self._stream, self._gone = stream, False

    def write(self, text):
        if not self._gone:
            try:
                return self._stream.write(text)
            except BrokenPipeError:
                self._drop()
        return len(text)

    def flush(self):
        if not self._gone:
            try:
                self._stream.flush()
            except BrokenPipeError:
                self._drop()

    def _drop(self):
        self._gone = True
        try:   # what is still buffered goes nowhere, also when Python flushes stdout at exit
            fd = os.open(os.devnull, os.O_WRONLY)
            os.dup2(fd, self._stream.fileno())
            os.close(fd)
        except (OSError, ValueError, AttributeError):   # no file descriptor (a captured stream)
            pass

    def __getattr__(self, name):
        return getattr(self._stream, name)


def _fail(args, line: str) -> int:
    if getattr(args, "debug", False):
        import traceback

        traceback.print_exc()
    print(line, file=sys.stderr)
    return EXIT_ERROR


def _run(args) -> int:
    import warnings

    if args.cmd == "identify":
        from .pipeline import run_config

        shown = []
        seen = set()

        def show(message, category, filename, lineno, file=None, line=None):
            # once each: the chain's inner identifications (calibration, jackknife) repeat theirs
            if str(message) in seen:
                return
            seen.add(str(message))
            shown.append(message)
            print(_one_line_warning(message, category, filename, lineno), end="", file=sys.stderr)

        with warnings.catch_warnings():
            warnings.simplefilter("default")
            warnings.showwarning = show
            ident, _ = run_config(args.config, args.kind, out_dir=args.out, overwrite=args.overwrite,
                                  log=(lambda m: None) if args.quiet else print, plots=not args.no_plot,
                                  report=args.report)
        if args.verbose:
            _list_flagged(ident)
        if args.strict and (shown or not ident.ok.all()):
            print(f"rotorid: strict: {int((~ident.ok).sum())} of {ident.ok.size} points flagged, {len(shown)} "
                  "warning(s): exit 3", file=sys.stderr)
            return EXIT_STRICT
        return EXIT_OK
    if args.cmd == "study":
        from .studies.run import run_study_config

        run_study_config(args.config, out_dir=args.out, overwrite=args.overwrite, trials=args.trials,
                         seed=args.seed, progress=not args.quiet, scheduler=args.scheduler)
        return EXIT_OK
    if args.cmd == "check":
        from .config import load_config, read_toml
        from .studies.config import is_study_config, parse_study_config
        from .support.config import is_predict_config, parse_predict_config

        data, src, where = read_toml(args.config)
        if is_predict_config(data):
            pcfg = parse_predict_config(data, source=src, base_dir=where, check_files=True)
            print(f"{args.config}: valid (prediction, {pcfg.predict.kind}; 2 supports, bearing tables present)")
            return EXIT_OK
        if is_study_config(data):
            scfg = parse_study_config(data, source=src)
            print(f"{args.config}: valid ({scfg.study.kind} study{' with a test design' if scfg.design else ''})")
            return EXIT_OK
        cfg = load_config(args.config)
        kinds = [k for k in ("imbalance", "impact") if getattr(cfg, k) is not None]
        n = len(cfg.entries())
        print(f"{args.config}: valid ({', '.join(kinds)}; {n} recording(s) or table(s), all files present)")
        return EXIT_OK
    if args.cmd == "example":
        from .example import copy_example

        path = copy_example(args.out, overwrite=args.overwrite)
        print(f"example data set written to {path}/ (try: rotorid identify imbalance {path}/imbalance.toml)")
        return EXIT_OK
    if args.cmd == "demo":
        return _demo(args)
    if args.cmd == "compare":
        return _compare(args)
    if args.cmd == "report":
        return _report(args)
    if args.cmd == "predict":
        from .support.config import run_predict_config

        with warnings.catch_warnings():
            warnings.simplefilter("default")   # validity warnings: one line each (formatwarning above)
            run_predict_config(args.config, out_dir=args.out, overwrite=args.overwrite)
        return EXIT_OK
    raise AssertionError(f"unhandled command {args.cmd!r}")  # argparse only lets the commands above through


def _list_flagged(ident) -> None:
    """``identify -v``: every flagged point and why, one line each."""
    axis = "rpm" if ident.axis_name == "speed_rpm" else "Hz"
    flagged = [(float(x), str(f)) for x, f, ok in zip(ident.axis, ident.flag, ident.ok) if not ok]
    print(f"{len(flagged)} of {ident.axis.size} points flagged" + (":" if flagged else ""))
    for x, why in flagged:
        print(f"  {x:10.5g} {axis}: {why}")


def _read_truth(path):
    """Known coefficients from a TOML file: k and c as [bearing][i][j] (N/m, N*s/m)."""
    import tomllib

    from .errors import RotoridError
    from .model import BearingCoefficients

    try:
        with open(path, "rb") as fh:
            t = tomllib.load(fh)
    except OSError as exc:
        raise RotoridError(f"cannot read --truth {path!r}: {exc.strerror or exc}") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise RotoridError(f"--truth {path!r} is not valid TOML: {exc}") from None
    if "k" not in t or "c" not in t:
        raise RotoridError(f"--truth {path!r} must hold k and c as [bearing][i][j] (N/m, N*s/m)")
    try:
        return BearingCoefficients(t["k"], t["c"])
    except RotoridError as exc:
        raise RotoridError(f"--truth {path!r}: {exc}") from None
    except (TypeError, ValueError):   # ragged or mixed lists that numpy refuses
        raise RotoridError(f"--truth {path!r}: k and c must be 2 x 2 x 2 lists of numbers "
                           "([bearing][i][j], N/m and N*s/m)") from None


def _report(args):
    from .report import find_result, load_result, write_report

    result = find_result(args.result)
    ident, context = load_result(result)
    if args.units:
        context["units"] = args.units
    truth = _read_truth(args.truth) if args.truth else None
    kind = context.get("kind") or ("imbalance" if ident.axis_name == "speed_rpm" else "impact")
    out = args.out or os.path.join(os.path.dirname(os.path.abspath(result)), f"report_{kind}.html")
    path = write_report(out, ident, overwrite=args.overwrite, truth=truth, **context)
    flagged = int((~ident.ok).sum())
    print(f"wrote {path} ({ident.axis.size} points, {flagged} flagged)")
    return 0


def _compare(args):
    from . import plot
    from .outputs import ResultsFolder
    import numpy as np

    from .support.compare import compare_tables

    cmp = compare_tables(args.identified, args.predicted)     # read and checked before anything is written
    folder = ResultsFolder(args.out, patterns=["comparison*"], overwrite=args.overwrite,
                           command=f"rotorid compare {args.identified} {args.predicted}")
    with folder.atomic("comparison.csv") as tmp:
        cmp.to_dataframe().to_csv(tmp, index=False, float_format="%.6g")
    summary = cmp.summary()
    with folder.atomic("comparison_summary.csv") as tmp:
        summary.to_csv(tmp, index=False, float_format="%.4g")
    with folder.atomic("comparison.png") as tmp:
        plot.comparison(cmp, path=tmp, title=f"Predicted vs identified: {os.path.basename(args.identified)}")
    folder.finish()
    ok = summary[summary.points > 0]
    if ok.empty:
        print(f"compared {cmp.axis.size} points: none is ok with a known uncertainty (see comparison.csv)")
    else:
        worst = ok.loc[ok.median_abs_z.idxmax()]
        print(f"compared {cmp.axis.size} points ({int(cmp.ok.sum())} ok): prediction inside the 95 % interval at "
              f"{100 * float(np.nanmean(ok.inside_fraction)):.0f} % of ok points; largest median |z| "
              f"{worst.median_abs_z:.2g} ({worst.coefficient}); wrote 3 files to {args.out}/")
    return 0


def _demo(args):
    from . import demo
    from .errors import RotoridError
    from .outputs import ResultsFolder
    from .simulate import ProbeResolution

    demo.check_step_rpm("--step-rpm", args.step_rpm)  # before anything is computed or written
    for name, v, ok in (("--noise-um", args.noise_um, args.noise_um >= 0),
                        ("--amplitude-resolution-um", args.amplitude_resolution_um,
                         args.amplitude_resolution_um is None or args.amplitude_resolution_um >= 0),
                        ("--phase-resolution-deg", args.phase_resolution_deg,
                         args.phase_resolution_deg is None or args.phase_resolution_deg >= 0)):
        if not ok or (v is not None and v != v):
            raise RotoridError(f"{name} must be >= 0, got {v:g}")
    folder = ResultsFolder(args.out, patterns=["table5_*", "campbell.*", "figure*", "pedestal_*", "impact_time_*",
                                                 "series_support*"],
                           overwrite=args.overwrite,
                           command="rotorid demo")
    base = ProbeResolution()
    res = ProbeResolution(
        amplitude_m=base.amplitude_m if args.amplitude_resolution_um is None else args.amplitude_resolution_um * 1e-6,
        phase_deg=base.phase_deg if args.phase_resolution_deg is None else args.phase_resolution_deg,
        noise_m=args.noise_um * 1e-6)
    import time

    files = []
    log = (lambda m: None) if args.quiet else print
    steps = [("Table 5, Campbell diagram, imbalance identification (Figures 3-5)",
              lambda: demo.synchronous(args.out, step_rpm=args.step_rpm, resolution=res, log=log)),
             ("impact identification (Figures 6-7)", lambda: demo.impact(args.out, log=log)),
             ("flexible pedestals", lambda: demo.pedestal(args.out, log=log)),
             ("series support prediction", lambda: demo.series_support(args.out, log=log))]
    for i, (what, step) in enumerate(steps, 1):
        t0 = time.perf_counter()
        log(f"[{i}/{len(steps)}] {what}")
        files += step()["files"]
        log(f"[{i}/{len(steps)}] done in {time.perf_counter() - t0:.0f} s")
    for f in files:
        folder.record(os.path.basename(f))
    folder.finish()
    print(f"wrote {len(files)} files to {args.out}/")
    return 0


if __name__ == "__main__":
    sys.exit(main())
