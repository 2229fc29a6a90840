"""The report's numerical experiments on the NSF rig, as figures, CSV tables and a printed summary."""

from __future__ import annotations

import os

import numpy as np

from . import _validate, plot
from .errors import RotoridError
from .identify import identify_synchronous
from .modal import critical_speeds, modal_analysis
from .model import nsf_rig
from .simulate import ProbeResolution, imbalance_response

#: report Table 5 (critical speed in cpm, damping ratio)
TABLE5 = [(3467, 0.114), (3676, 0.131), (4997, 0.201), (7360, 0.199)]
BANDS = [(0, 2000), (2000, 3000), (3000, 6000), (6000, 10001)]
#: the imbalance sweep of the synchronous demo runs up to this speed (rpm) ...
TOP_RPM = 10000.0
#: ... in at most this many speeds (so step_rpm >= TOP_RPM / MAX_SPEEDS = 1 rpm)
MAX_SPEEDS = 10000


def check_step_rpm(name, step_rpm):
    """The speed step of the demo's imbalance sweep: from TOP_RPM / MAX_SPEEDS (1 rpm) to TOP_RPM."""
    step = _validate.number(name, step_rpm, positive=True)
    lo = TOP_RPM / MAX_SPEEDS
    if not lo <= step <= TOP_RPM:
        raise RotoridError(f"{name} must be between {lo:g} and {TOP_RPM:g} rpm (the sweep to {TOP_RPM:g} rpm has at "
                           f"most {MAX_SPEEDS} speeds), got {step:g}")
    return step


def _out_dir(out):
    """The output folder ``out``, created when missing."""
    p = _validate.path("out", out)
    if p.exists() and not p.is_dir():
        raise RotoridError(f"out: {str(p)!r} is a file, not a folder")
    try:
        os.makedirs(p, exist_ok=True)
    except OSError as exc:
        raise RotoridError(f"cannot create the output folder {str(p)!r}: {exc}") from None
    return str(p)


def _log(log):
    if not callable(log):
        raise RotoridError(f"log must be a function taking a message (e.g. print), got {type(log).__name__}")
    return log


def _band_errors(ident, truth):
    """Median |relative error| of direct and cross-coupled K and C per speed band."""
    P0 = truth.to_report_vector()
    err = np.abs(ident.report_vector() - P0) / np.abs(P0)
    rows = []
    for lo, hi in BANDS:
        s = (ident.axis >= lo) & (ident.axis < hi)
        if not s.any():
            continue
        e = err[s]
        rows.append(dict(band_rpm=f"{lo}-{min(hi, 10000)}", points=int(s.sum()), flagged=int((~ident.ok[s]).sum()),
                         K_direct=np.nanmedian(e[:, [0, 1, 6, 7]]), K_cross=np.nanmedian(e[:, [2, 3, 4, 5]]),
                         C_direct=np.nanmedian(e[:, [8, 9, 14, 15]]), C_cross=np.nanmedian(e[:, [10, 11, 12, 13]])))
    return rows


def synchronous(out: str, *, step_rpm: float = 50.0, resolution: ProbeResolution | None = None, log=print):
    """Report section 4: Table 5, Figure 3 (Bode, sets A and B), Figure 4 (identification from A-D).

    ``step_rpm``: speed step of the imbalance sweep up to 10000 rpm, from 1 rpm (10000 speeds) up."""
    import pandas as pd

    step_rpm = check_step_rpm("step_rpm", step_rpm)
    _validate.instance("resolution", resolution, ProbeResolution, allow_none=True, what="rotorid.ProbeResolution")
    log = _log(log)
    out = _out_dir(out)
    rig = nsf_rig()
    rotor, brg = rig.rotor, rig.bearings
    files = []

    # Table 5 and Campbell diagram
    cs = critical_speeds(rotor, brg, max_rpm=12000)
    cs["report_cpm"] = [t[0] for t in TABLE5][: len(cs)]
    cs["report_damping"] = [t[1] for t in TABLE5][: len(cs)]
    cs["diff_percent"] = 100 * (cs.speed_rpm - cs.report_cpm) / cs.report_cpm
    path = os.path.join(out, "table5_critical_speeds.csv")
    cs.to_csv(path, index=False, float_format="%.6g")
    files.append(path)
    camp = modal_analysis(rotor, brg, speed_rpm=np.linspace(0, 10000, 201))
    camp.to_dataframe().to_csv(os.path.join(out, "campbell.csv"), index=False, float_format="%.6g")
    plot.campbell(camp, crit=cs, path=os.path.join(out, "campbell.png"), title="NSF rig: Campbell diagram (Table 5)")
    files += [os.path.join(out, "campbell.csv"), os.path.join(out, "campbell.png")]

    # Figure 3: imbalance responses of sets A and B at the bearings
    rpm = np.arange(step_rpm, TOP_RPM + step_rpm / 2, step_rpm)
    runs = {n: imbalance_response(rotor, brg, rig.imbalances[n], speed_rpm=rpm) for n in "ABCD"}
    for tag, n in (("a", "A"), ("b", "B")):
        p = os.path.join(out, f"figure3{tag}_bode_set_{n}.png")
        plot.bode(runs[n], title=f"Figure 3{tag}: imbalance response to set {n} at the bearings", path=p)
        c = os.path.join(out, f"figure3{tag}_response_set_{n}.csv")
        runs[n].to_dataframe().to_csv(c, index=False, float_format="%.6g")
        files += [p, c]

    # Figure 4: identification from sets A-D, exact and through the measurement-error model
    exact = identify_synchronous(rotor, list(runs.values()))
    res = resolution if resolution is not None else ProbeResolution()
    rng = np.random.default_rng(2001)
    measured = [res.measure(r, rng) for r in runs.values()]
    ident = identify_synchronous(rotor, measured)
    for name, idn in (("exact", exact), ("measured", ident)):
        p = os.path.join(out, f"figure4_identified_{name}.csv")
        idn.to_dataframe().to_csv(p, index=False, float_format="%.6g")
        files.append(p)
    ttl = (f"Figure 4: coefficients identified from sets A-D; 1X vectors rounded to "
           f"{res.amplitude_m * 1e6:.4g} µm and {res.phase_deg:g}°" + (f", noise {res.noise_m * 1e6:g} µm" if res.noise_m else ""))
    p = os.path.join(out, "figure4_identified.png")
    plot.coefficients(ident, brg, title=ttl, path=p)
    files.append(p)
    p = os.path.join(out, "figure4_identified_exact.png")
    plot.coefficients(exact, brg, title="Figure 4 (exact responses): coefficients identified from sets A-D", path=p)
    files.append(p)
    bands = pd.DataFrame(_band_errors(ident, brg))
    bands_exact = pd.DataFrame(_band_errors(exact, brg))
    bands.to_csv(os.path.join(out, "figure4_band_errors.csv"), index=False, float_format="%.4g")
    files.append(os.path.join(out, "figure4_band_errors.csv"))

    fig5 = cross_coupling(out, speed_rpm=rpm, resolution=res, log=log)
    files += fig5["files"]

    log("Table 5 - critical speeds of the NSF rig (damping ratio = -Re/Im = log decrement / 2 pi):")
    for _, r in cs.iterrows():
        log(f"  {r.speed_rpm:7.0f} cpm ({r.freq_hz:6.1f} Hz, {r.whirl:8s})  zeta {r.damping_ratio_wd:.3f}   "
            f"report {r.report_cpm:5.0f} cpm, zeta {r.report_damping:.3f}   ({r.diff_percent:+.2f} %)")
    log("Figure 4 - median |relative error| of identified coefficients by speed band")
    log(f"  measurement model: amplitude rounded to {res.amplitude_m * 1e6:.4g} µm, phase to {res.phase_deg:g} deg")
    with pd.option_context("display.float_format", "{:.2%}".format, "display.width", 120):
        log("  exact responses:")
        log("    " + bands_exact.to_string(index=False).replace("\n", "\n    "))
        log("  measured responses:")
        log("    " + bands.to_string(index=False).replace("\n", "\n    "))
    log(fig5["summary"])
    return dict(critical_speeds=cs, exact=exact, measured=ident, band_errors=bands,
                cross_coupling=fig5["sensitivity"], speed_bands=fig5["speed_bands"], files=files)


#: trials of the Figure 5 study when the measurement model adds noise (rounding alone is deterministic)
FIG5_NOISE_TRIALS = 5
_FIG5_LINES = (("xy1", "Kxy, bearing 1", "tab:blue", "o"), ("xy2", "Kxy, bearing 2", "tab:orange", "s"),
               ("yx1", "Kyx, bearing 1", "tab:green", "^"), ("yx2", "Kyx, bearing 2", "tab:red", "v"))


def cross_coupling(out: str, *, speed_rpm, resolution: ProbeResolution | None = None, log=print):
    """Report Figure 5: error of the identified cross-coupled stiffnesses vs the ratio a (eq. 20-22),
    and the median errors in speed bands scaled by the first critical speed.

    Writes ``figure5_cross_coupling.png``/``.csv`` and ``figure5_speed_bands.csv`` to ``out``; the
    study itself is :mod:`rotorid.studies.sensitivity`. Returns dict(sensitivity, speed_bands,
    files, summary)."""
    from .studies.sensitivity import cross_coupling_sensitivity, speed_range_errors

    _validate.instance("resolution", resolution, ProbeResolution, allow_none=True, what="rotorid.ProbeResolution")
    log = _log(log)
    out = _out_dir(out)
    res = resolution if resolution is not None else ProbeResolution()
    trials = FIG5_NOISE_TRIALS if res.noise_m > 0 else 1
    sens = cross_coupling_sensitivity(speed_rpm=speed_rpm, resolution=res, trials=trials, seed=2001)
    bands = speed_range_errors(speed_rpm=speed_rpm, resolution=res, trials=trials, seed=2001)
    files = []
    p = os.path.join(out, "figure5_cross_coupling.csv")
    sens.to_csv(p, index=False, float_format="%.6g")
    files.append(p)
    p = os.path.join(out, "figure5_speed_bands.csv")
    bands.to_csv(p, index=False, float_format="%.6g")
    files.append(p)

    plt = plot._plt()
    fig, ax = plt.subplots(figsize=(8, 5.5))
    n, n_hi, cut = int(sens.n.iloc[0]), int(sens.n_above.iloc[0]), sens.attrs["cutoff_rpm"]
    for key, label, color, marker in _FIG5_LINES:
        ax.plot(100 * sens.a, 100 * sens[f"E_{key}"], color=color, marker=marker,
                label=f"{label}: all speeds (n = {n})")
        ax.plot(100 * sens.a, 100 * sens[f"E_{key}_above"], color=color, marker=marker, ls="--", mfc="none",
                label=f"{label}: speeds ≥ {cut:.0f} rpm (n = {n_hi})")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("Cross-coupled to direct stiffness ratio a (%), eq. 20")
    ax.set_ylabel("Total relative error E (%), eq. 21-22")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    ax.set_title(f"Figure 5: identification of the cross-coupled stiffnesses vs a (sets A-D; 1X vectors rounded to "
                 f"{res.amplitude_m * 1e6:.4g} µm and {res.phase_deg:g}°"
                 + (f", noise {res.noise_m * 1e6:g} µm, {trials} trials" if res.noise_m else "") + ")", fontsize=9)
    p = os.path.join(out, "figure5_cross_coupling.png")
    plot.finish(fig, p)
    files.append(p)

    def worst(row, suffix):
        return 100 * max(row[f"E_{k[0]}{suffix}"] for k in _FIG5_LINES)

    parts = ", ".join(f"{100 * r.a:g} %: {worst(r, ''):.3g} % ({worst(r, '_above'):.3g} %)" for _, r in sens.iterrows())
    summary = (f"Figure 5 - largest E of Kxy1, Kxy2, Kyx1, Kyx2 (eq. 21-22) over {n} speeds (over the {n_hi} at or "
               f"above 0.6 of the first critical, {cut:.0f} rpm) by ratio a: {parts}")
    return dict(sensitivity=sens, speed_bands=bands, files=files, summary=summary)


def impact(out: str, *, speed_rpm: float = 1000.0, log=print):
    """Report section 5: Figure 6 (FRFs for the Table 6 impacts at 1000 rpm) and Figure 7 (coefficients
    identified over 2-200 Hz), plus the same identification from simulated time records of
    half-sine impacts (force and response spectra by FFT)."""
    import pandas as pd

    from .identify import identify_impact
    from .simulate import ImpactResponse, half_sine_pulse, impact_frf, impact_time_response

    speed_rpm = _validate.number("speed_rpm", speed_rpm, nonneg=True)
    log = _log(log)
    out = _out_dir(out)
    rig = nsf_rig()
    rotor, brg = rig.rotor, rig.bearings
    files = []
    f = np.arange(2.0, 200.0 + 1e-9, 0.5)
    tests = {}
    for tag, (name, (plane, d, load)) in zip("ab", rig.impacts.items()):
        h = impact_frf(rotor, brg, speed_rpm=speed_rpm, freq_hz=f, plane=plane, direction=d, name=name)
        tests[name] = h
        p = os.path.join(out, f"figure6{tag}_frf_test_{name}.png")
        plot.bode(h.q * load, axis=f, x_label="Frequency (Hz)", path=p,
                  title=f"Figure 6{tag}: response to a {load:g} N impact (flat spectrum) at the CG in {d}, "
                        f"{speed_rpm:g} rpm")
        c = os.path.join(out, f"figure6{tag}_frf_test_{name}.csv")
        h.to_dataframe().to_csv(c, index=False, float_format="%.6g")
        files += [p, c]
    ident = identify_impact(rotor, list(tests.values()))
    p = os.path.join(out, "figure7_identified.csv")
    ident.to_dataframe().to_csv(p, index=False, float_format="%.6g")
    files.append(p)
    p = os.path.join(out, "figure7_identified.png")
    plot.coefficients(ident, brg, path=p,
                      title=f"Figure 7: coefficients identified from impacts A (x) and B (y), {speed_rpm:g} rpm")
    files.append(p)
    P0 = brg.to_report_vector()
    err_frf = np.nanmax(np.abs(ident.report_vector() - P0) / np.abs(P0))

    # the same from sampled impacts: half-sine pulses of 2 ms, spectra by FFT of the full decay
    fs, n = 5000.0, 2 ** 14
    spectra = []
    freqs = np.fft.rfftfreq(n, 1 / fs)
    band = (freqs >= 2) & (freqs <= 200)
    for name, (plane, d, load) in rig.impacts.items():
        peak = 4500.0 if d == "x" else 3750.0  # ~ report: ~4,500 N over ~3.5 ms soft tip; 2 ms here
        u = half_sine_pulse(peak, 2e-3, fs, n, t0_s=0.02)
        tr = impact_time_response(rotor, brg, speed_rpm=speed_rpm, force_N=u, fs_hz=fs, plane=plane, direction=d)
        X = np.fft.rfft(tr.q, axis=0)[band]
        F = np.fft.rfft(u)[band] * np.sinc(freqs[band] / fs) ** 2  # force spectrum of the piecewise-linear pulse
        spectra.append(ImpactResponse(speed_rpm=speed_rpm, freq_hz=freqs[band], q=X, force=F, plane=plane,
                                      direction=d, name=name))
        if d == "x":
            plt = plot._plt()
            fig, ax = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
            ax[0].plot(tr.t * 1e3, u)
            ax[0].set_ylabel("Force (N)")
            for j, lab in enumerate(plot.DOF_TITLES):
                ax[1].plot(tr.t * 1e3, tr.q[:, j] * 1e6, label=lab)
            ax[1].set_xlabel("Time (ms)")
            ax[1].set_ylabel("Displacement (µm)")
            ax[1].set_xlim(0, 300)
            ax[1].legend(fontsize=8)
            fig.suptitle(f"Time response to a 2 ms, {peak:g} N half-sine impact in x at the CG ({speed_rpm:g} rpm)")
            p = os.path.join(out, "impact_time_response.png")
            plot.finish(fig, p)
            files.append(p)
    ident_t = identify_impact(rotor, spectra)
    err_time = np.nanmax(np.abs(ident_t.report_vector() - P0) / np.abs(P0))
    p = os.path.join(out, "figure7_identified_from_time_records.csv")
    ident_t.to_dataframe().to_csv(p, index=False, float_format="%.6g")
    files.append(p)

    log(f"Figure 7 - impact identification at {speed_rpm:g} rpm over {f[0]:g}-{f[-1]:g} Hz "
        f"({f.size} frequencies, tests A (x, 120 N) and B (y, 100 N) at the CG):")
    log(f"  from exact FRFs:          max relative error of the 16 coefficients {err_frf:.1e}; "
        f"cond {ident.cond.min():.0f}-{ident.cond.max():.0f}")
    log(f"  from sampled 2 ms pulses: max relative error {err_time:.1e} ({ident_t.axis.size} FFT lines, fs {fs:g} Hz)")
    return dict(frf=ident, time=ident_t, files=files, err_frf=err_frf, err_time=err_time,
                summary=pd.DataFrame(dict(source=["frf", "time records"], max_rel_error=[err_frf, err_time])))


def pedestal(out: str, *, step_rpm: float = 100.0, probe_noise_um: float = 0.025, accel_noise_ms2: float = 0.002,
             seed: int = 12, log=print):
    """Flexible pedestals (the report's remedy for "bearing parameters varying with no defined
    trend"): the NSF rig on :func:`rotorid.example_pedestals`, imbalance sets A and B over
    500-8000 rpm, probes on the housings with complex 1X noise ``probe_noise_um`` (µm rms; the
    default is the report's amplitude resolution, 0.001 mil) and housing accelerometers with
    ``accel_noise_ms2`` (m/s² rms, 1X after averaging).

    The same noisy runs are identified twice: ignoring the housings' motion (what the report's
    first tests did) and with it (the accelerometers' 1X divided by -Ω²). Writes
    ``pedestal_compensation.png`` (direct K and C, without and with compensation, 95 % intervals),
    ``pedestal_identified.csv``, ``pedestal_ignored.csv``, ``pedestal_parameters.csv`` (the
    pedestals identified from the same runs, with truth) and ``pedestal_critical_speeds.csv``
    (rigid vs flexible supports).

    Examples
    --------
    >>> import tempfile, rotorid.demo as demo
    >>> r = demo.pedestal(tempfile.mkdtemp(), step_rpm=500.0, log=lambda m: None)
    >>> bool(r["err_with"] < 0.1 < r["err_without"])
    True
    """
    import warnings

    import pandas as pd

    from .pedestal import example_pedestals, identify_pedestals
    from .simulate import SyncResponse

    step = _validate.number("step_rpm", step_rpm, positive=True)
    if not 1.0 <= step <= 1000.0:
        raise RotoridError(f"step_rpm must be between 1 and 1000 rpm, got {step:g}")
    probe_noise_um = _validate.number("probe_noise_um", probe_noise_um, nonneg=True)
    accel_noise_ms2 = _validate.number("accel_noise_ms2", accel_noise_ms2, nonneg=True)
    seed = _validate.seed("seed", seed)
    log = _log(log)
    out = _out_dir(out)
    rig = nsf_rig()
    rotor, brg, ped = rig.rotor, rig.bearings, example_pedestals()
    rpm = np.arange(500.0, 8000.0 + 1e-9, step)
    om = rpm * np.pi / 30.0
    rng = np.random.default_rng(seed)
    sq = probe_noise_um * 1e-6 / np.sqrt(2.0)                  # per real component
    sp = accel_noise_ms2 / np.sqrt(2.0) / om ** 2                # displacement, per real component
    cov = np.broadcast_to(np.eye(8) * sq ** 2, (rpm.size, 8, 8)).copy()
    pcov = np.eye(8)[None] * (sp ** 2)[:, None, None]
    runs, naive, ratios = [], [], []
    for name in ("A", "B"):
        r = imbalance_response(rotor, brg, rig.imbalances[name], speed_rpm=rpm, at="probes", pedestals=ped)
        ratios.append(r.pedestal_ratio)
        q = r.q + sq * (rng.standard_normal(r.q.shape) + 1j * rng.standard_normal(r.q.shape))
        p = r.pedestal + sp[:, None] * (rng.standard_normal(r.q.shape) + 1j * rng.standard_normal(r.q.shape))
        runs.append(SyncResponse(rpm, q, r.imbalance, "probes", name, cov, None, p, pcov))
        naive.append(SyncResponse(rpm, q, r.imbalance, "probes", name, cov))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the naive fit is meant to be poor; its flags say so per point
        with_ped = identify_synchronous(rotor, runs)
        without = identify_synchronous(rotor, naive)
    files = []
    for ident, tag in ((with_ped, "identified"), (without, "ignored")):
        p = os.path.join(out, f"pedestal_{tag}.csv")
        ident.to_dataframe().to_csv(p, index=False, float_format="%.6g")
        files.append(p)
    p = os.path.join(out, "pedestal_compensation.png")
    plot.pedestal_compensation(without, with_ped, brg, path=p,
                               title="NSF rig on flexible pedestals (example_pedestals): identified direct "
                                     "coefficients, same noisy runs A and B")
    files.append(p)
    fit = identify_pedestals(rotor, runs)
    df = fit.to_dataframe()
    df["mass_true"] = [ped.mass_kg[b, i] for b in range(2) for i in range(2)]
    df["k_true"] = [ped.k[b, i, i] for b in range(2) for i in range(2)]
    df["c_true"] = [ped.c[b, i, i] for b in range(2) for i in range(2)]
    p = os.path.join(out, "pedestal_parameters.csv")
    df.to_csv(p, index=False, float_format="%.6g")
    files.append(p)
    cs_rigid = critical_speeds(rotor, brg, max_rpm=12000.0)
    cs_ped = critical_speeds(rotor, brg, max_rpm=12000.0, pedestals=ped)
    p = os.path.join(out, "pedestal_critical_speeds.csv")
    pd.concat([cs_rigid.assign(supports="rigid"), cs_ped.assign(supports="flexible pedestals")]).to_csv(
        p, index=False, float_format="%.6g")
    files.append(p)
    k0, c0 = brg.at()

    # compared where the compensated identification is trustworthy (the naive one cannot know)
    sel = with_ped.ok if with_ped.ok.any() else np.ones(rpm.size, bool)

    def direct_err(ident):
        d = [(b, i, i) for b in range(2) for i in range(2)]
        ek = [np.abs(ident.k[sel, b, i, j] / k0[0, b, i, j] - 1) for b, i, j in d]
        ec = [np.abs(ident.c[sel, b, i, j] / c0[0, b, i, j] - 1) for b, i, j in d]
        return float(np.median(np.concatenate(ek + ec)))

    err_with, err_without = direct_err(with_ped), direct_err(without)
    ratio = np.stack(ratios)
    log(f"Flexible pedestals - NSF rig on example_pedestals(), sets A and B at {rpm[0]:g}-{rpm[-1]:g} rpm "
        f"(the housings move {ratio.min():.2f}-{ratio.max():.2f} x the journal in them):")
    log(f"  ignoring the housings' motion: median error of the direct K, C {100 * err_without:.0f} % at the "
        f"{int(sel.sum())} speeds below ({int((without.ok & sel).sum())} of them flagged ok: the model error is "
        "invisible without the accelerometers)")
    log(f"  with the accelerometers:       median error {100 * err_with:.1f} % ({int(sel.sum())} of {rpm.size} "
        "speeds ok)")
    log("  " + fit.summary())
    return dict(with_pedestal=with_ped, without=without, pedestals=fit, files=files, err_with=err_with,
                err_without=err_without)


def illustrative_tpjb():
    """An *illustrative* flexure-pivot tilting-pad bearing table for the NSF rig: not from the
    report (which gives no bearing coefficients), built only to show the series support. Direct
    stiffness 1.2e7 + 1000 N/m per rpm (4 times a 3.75e6 N/m damper spring at 3000 rpm, the
    report's "3.5 to 4.5 times at the first critical speed"), direct damping 3000 N s/m at
    3000 rpm falling as speed^-0.3, a preloaded bearing's weak frequency dependence (stiffness
    +2.25 % to -7.5 %, damping the opposite, over frequency ratios 0.1-4), no cross-coupling."""
    from .support.tpjb import BearingTable

    rpm = np.array([500.0, 1000.0, 2000.0, 3000.0, 4000.0, 6000.0, 8000.0, 10000.0])
    ratio = np.array([0.1, 0.25, 0.5, 1.0, 1.5, 2.0, 3.0, 4.0])
    kd = 1.2e7 + 1000.0 * rpm[:, None] * np.ones(ratio.size)
    cd = 3000.0 * (rpm[:, None] / 3000.0) ** -0.3 * np.ones(ratio.size)
    kd = kd * (1.0 - 0.05 * (ratio - 1.0) / 2.0)[None, :]
    cd = cd * (1.0 + 0.05 * (ratio - 1.0) / 2.0)[None, :]
    k = np.zeros((rpm.size, ratio.size, 2, 2))
    c = np.zeros_like(k)
    k[..., 0, 0], k[..., 1, 1] = kd, 1.1 * kd
    c[..., 0, 0], c[..., 1, 1] = cd, 1.1 * cd
    return BearingTable(rpm, ratio, k, c, freq_axis="ratio", name="illustrative FPJB")


def series_support(out: str, *, spring_stiffness_n_m: float = 3.75e6, journal_mass_kg: float = 1.5, log=print):
    """Predicted coefficients of the report's series support (issue 13): the NSF integral squeeze
    film damper of Table 1 (``nsf_damper``, full film, fluid inertia) in series with an
    *illustrative* tilting-pad table (:func:`illustrative_tpjb`) through the damper journal's mass.

    Writes ``series_support.png``: direct K and C of film, damper and series support against
    speed at w = Omega (what an imbalance identification measures) and against frequency at
    3000 rpm (what impacts at 3000 rpm measure), and ``series_support.csv``.

    Examples
    --------
    >>> import tempfile, rotorid.demo as demo
    >>> r = demo.series_support(tempfile.mkdtemp(), log=lambda m: None)
    >>> sorted(r)
    ['files', 'frequency', 'synchronous']
    """
    import warnings

    import pandas as pd

    from .support.series import coefficients_of
    from .support.compare import SeriesSupport
    from .support.sfd import SFDValidityWarning, nsf_damper

    log = _log(log)
    out = _out_dir(out)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SFDValidityWarning)  # the NSF lands are short: docs/sfd.md
        damper = nsf_damper(spring_stiffness_n_m=spring_stiffness_n_m)
    film = illustrative_tpjb()
    support = SeriesSupport(film, damper, journal_mass_kg, "NSF series support")
    rpm = np.arange(500.0, 10000.0 + 1e-9, 100.0)
    f_sync = rpm / 60.0
    f_imp = np.arange(5.0, 150.0 + 1e-9, 1.0)
    rows = {}
    for tag, s, f in (("synchronous", rpm, f_sync), ("frequency", np.full(f_imp.size, 3000.0), f_imp)):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", SFDValidityWarning)
            zb = film.impedance(s, f)
            zd = damper.impedance(f)
            ze = support.impedance(s, f)
        rows[tag] = {name: coefficients_of(z, f) for name, z in (("film", zb), ("damper", zd), ("series", ze))}
    plt = plot._plt()
    fig, axes = plt.subplots(2, 2, figsize=(13, 8), sharex="col")
    for col, (tag, x, xlabel) in enumerate((("synchronous", rpm, "Rotor speed (rpm), w = Omega"),
                                            ("frequency", f_imp, "Frequency (Hz), 3000 rpm"))):
        for name, style in (("film", ":"), ("damper", "--"), ("series", "-")):
            k, c = rows[tag][name]
            axes[0, col].plot(x, k[:, 0, 0] * 1e-6, style, label=f"{name} Kxx")
            axes[1, col].plot(x, c[:, 0, 0] * 1e-3, style, label=f"{name} Cxx")
        axes[1, col].set_xlabel(xlabel)
    axes[0, 0].set_ylabel("Direct stiffness (MN/m)")
    axes[1, 0].set_ylabel("Direct damping (kN·s/m)")
    for ax in axes.flat:
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)
    spring = np.asarray(damper.stiffness_matrix())
    spring_text = f"{spring[0, 0]:.3g}" if np.allclose(spring, spring[0, 0] * np.eye(2)) else \
        f"[{spring[0, 0]:.3g}, {spring[1, 1]:.3g}] (xx, yy)"
    fig.suptitle("NSF series support: Table 1 squeeze film damper (full film, fluid inertia) in series with an "
                 f"ILLUSTRATIVE tilting-pad table\n(not from the report; spring {spring_text} N/m and journal mass "
                 f"{support.journal_mass_kg:g} kg assumed)")
    p = os.path.join(out, "series_support.png")
    plot.finish(fig, p)
    data = {"speed_rpm": rpm}
    for name in ("film", "damper", "series"):
        k, c = rows["synchronous"][name]
        data[f"{name}_Kxx"], data[f"{name}_Cxx"] = k[:, 0, 0], c[:, 0, 0]
    csv = os.path.join(out, "series_support.csv")
    pd.DataFrame(data).to_csv(csv, index=False, float_format="%.6g")
    ks, cs = rows["synchronous"]["series"]
    kf, cf = rows["frequency"]["series"]
    i3 = int(np.argmin(np.abs(rpm - 3000.0)))
    log(f"Series support (NSF damper + illustrative FPJB table): at 3000 rpm synchronous Kxx "
        f"{ks[i3, 0, 0]:.3g} N/m, Cxx {cs[i3, 0, 0]:.3g} N s/m; at 3000 rpm and 100 Hz Kxx "
        f"{kf[np.argmin(np.abs(f_imp - 100.0)), 0, 0]:.3g} N/m: impacts and imbalance measure different coefficients")
    return dict(synchronous=rows["synchronous"], frequency=rows["frequency"], files=[p, csv])
