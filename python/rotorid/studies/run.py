"""``rotorid study CONFIG``: run the study a config describes and write its files."""

from __future__ import annotations

import os

from ..errors import RotoridError


def run_study_config(path, *, out_dir=None, overwrite=False, trials=None, seed=None, progress=True, scheduler=None,
                     log=print):
    """Run the Monte Carlo study (and the test design, with ``[design]``) of the study config at
    ``path`` and write its tables, figures and summary to ``out_dir`` (default: ``[output] dir``,
    else ``study_<kind>`` beside the config). ``trials`` and ``seed`` override the config;
    ``scheduler`` (a Dask scheduler address, or ``[study] scheduler``) runs the study on that
    cluster, with the same results as on this machine. Returns
    (StudyResult, DesignResult or None, list of file names).

    Examples
    --------
    >>> import os, tempfile, rotorid.example as ex
    >>> from rotorid.studies.run import run_study_config
    >>> res, design, files = run_study_config(os.path.join(ex.path(), "study_impact.toml"),
    ...     out_dir=tempfile.mkdtemp(), trials=50, progress=False, log=lambda *a: None)
    >>> "study_errors.csv" in files
    True
    """
    from .._validate import flag, index
    from ..outputs import ResultsFolder
    from .config import load_study_config
    from .report import PATTERNS, write_study

    overwrite = flag("overwrite", overwrite)
    progress = flag("progress", progress)
    if not callable(log):
        raise RotoridError("log must be a function taking a message (e.g. print)")
    cfg = load_study_config(path)
    st = cfg.study
    trials = st.trials if trials is None else index("--trials", trials, 1, 10 ** 9)
    seed = st.seed if seed is None else index("--seed", seed, 0, 2 ** 63 - 1)
    if out_dir is None:
        out_dir = cfg.output.dir or f"study_{st.kind}"
        if not os.path.isabs(out_dir):
            out_dir = os.path.join(os.path.dirname(os.path.abspath(os.fspath(path))), out_dir)
    folder = ResultsFolder(out_dir, patterns=PATTERNS, overwrite=overwrite, command="rotorid study")
    rotor, bearings, rig = cfg.system()
    if scheduler is None:
        scheduler = st.scheduler
    elif not isinstance(scheduler, str) or not scheduler.strip():
        raise RotoridError(f"--scheduler must be a Dask scheduler address (e.g. tcp://host:8786), got {scheduler!r}")
    common = dict(trials=trials, seed=seed, at=st.at, method=st.method, percentiles=st.percentiles,
                  coverage_trials=min(st.coverage_trials, trials), level=st.level, progress=progress,
                  client=scheduler)
    design = None
    if st.kind == "imbalance":
        from .monte_carlo import synchronous_study

        sec = cfg.imbalance
        runs = ([rig.imbalances[n] for n in sec.sets] if sec.sets is not None
                else [r.build(i) for i, r in enumerate(sec.runs)])
        errors = sec.errors.build()
        res = synchronous_study(rotor, bearings, runs, sec.speeds(), errors, **common)
        if cfg.design is not None:
            from dataclasses import replace

            from .design import TrialMassRig, design_trial_masses

            d = cfg.design
            tmr = TrialMassRig(holes=d.holes, masses_kg=tuple(m * 1e-3 for m in d.masses_g),
                               max_response_m=None if d.max_response_um is None else d.max_response_um * 1e-6)
            log(f"test design: ranking trial-mass sets ({d.holes} holes, masses {', '.join(f'{m:g}' for m in d.masses_g)} g)")
            design = design_trial_masses(rotor, bearings, tmr, sec.speeds(), dwell_s=d.dwell_s,
                                         probe_noise_m=d.probe_noise_um * 1e-6, fs_hz=d.fs_hz,
                                         errors=replace(errors, noise_m=errors.noise_m), runs=d.runs,
                                         screen_keep=d.screen_keep, trials=d.trials, seed=seed, at=st.at,
                                         compare={"this study's runs": runs} if d.compare_sets else None)
    else:
        from .monte_carlo import impact_study

        sec = cfg.impact
        tests = [(t.plane_mm * 1e-3, t.direction) for t in sec.tests]
        res = impact_study(rotor, bearings, tests, sec.freqs(), sec.errors.build(), speed_rpm=sec.speed_rpm, **common)
    files = write_study(res, folder, design=design, settings={"config": os.fspath(path)})
    folder.finish()
    med = res.band_summary()
    log(f"{res.kind} study: {res.trials} trials x {res.axis.size} points; median half-width of the errors "
        f"(direct K, cross K, direct C, cross C) over the axis: " + ", ".join(
            f"{100 * float(med[g].median()):.3g} %" for g in ("K_direct", "K_cross", "C_direct", "C_cross")))
    if res.coverage is not None:
        import numpy as np

        log(f"interval coverage ({res.level:g}) over {res.coverage_trials} trials: {np.nanmean(res.coverage):.3f}")
    if design is not None:
        for size, runs in design.best.items():
            log(f"recommended {size} runs: {' + '.join(r.name for r in runs)}")
    log(f"wrote {len(files)} files to {folder.path}/")
    return res, design, files
