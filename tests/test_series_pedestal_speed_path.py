"""The faster paths of ``series_impedance`` and ``identify_pedestals`` give what the straightforward
computations give.

``series_impedance`` leaves the finite scan of the impedances to the core (a non-finite impedance
makes its point singular there) and names the argument after the call: here every argument's NaN
and inf are still named, in the words of the finite check, and the results match a NumPy solve.

``identify_pedestals`` fits in the core (``_core.pedestal_fit``): the equations are formed point
by point and folded into a Householder QR factor, the rank from the factor's singular values, the
HC3 meat from a second pass (with covariances, the weighted or sandwich fit in the same core
call). The reference below is the first implementation's arithmetic, kept here:
C-order designs stacked from complex columns, ``lstsq``, ``matrix_rank``, ``einsum`` and BLAS
products; with covariances it continues with the NumPy fit of ``pedestal_cov_oracle``. Estimates agree to 1e-12; standard errors
to 1e-12 or the rounding of (X^T X)^-1 (cond(X)² eps: both differ from the exact HC3 value by that
much); on noise-free runs the standard errors and residuals are rounding noise and are compared
with a bound relative to the estimates.
"""

import re
import warnings

import numpy as np
import pytest

import rotorid
from rotorid import IdentifiabilityError, ImpactResponse, Pedestals, RotoridError, SyncResponse
from rotorid._corecall import core
from rotorid.pedestal import GLS_MIN_DOF
from rotorid.rawsim import example_rig
from rotorid.simulate import RPM

from pedestal_cov_oracle import covariance_fit, force_jacobian

EPS = np.finfo(float).eps

# ---------------------------------------------------------------------------------------------
# series_impedance


def _series_reference(zb, zd, m, f):
    """Z_eq = Z_b - Z_b (Z_b + Z_d - w² m I)⁻¹ Z_b by a NumPy solve per point."""
    w = 2 * np.pi * np.atleast_1d(np.asarray(f, float))
    zb = np.broadcast_to(np.asarray(zb, complex), (w.size, 2, 2))
    zd = np.broadcast_to(np.asarray(zd, complex), (w.size, 2, 2))
    m = np.broadcast_to(np.asarray(m, float), w.shape)
    a = zb + zd - (w ** 2 * m)[:, None, None] * np.eye(2)
    return zb - zb @ np.linalg.solve(a, zb), np.linalg.cond(a)


def _z(rng, n, scale):
    k = rng.uniform(0.2, 1.0, (n, 2, 2)) * scale * np.array([[1.0, 0.15], [-0.1, 1.0]])
    c = rng.uniform(0.2, 1.0, (n, 2, 2)) * scale * 1e-3
    return k + 1j * 2 * np.pi * 60.0 * c


@pytest.mark.parametrize("n, per_point, masses", [(1, False, False), (7, True, False), (500, True, True),
                                                  (20000, False, True), (20000, True, False)])
def test_series_matches_the_solve(n, per_point, masses):
    rng = np.random.default_rng(n + 3 * per_point + 7 * masses)
    zb = _z(rng, n, 3e7) if per_point else _z(rng, 1, 3e7)[0]
    zd = _z(rng, n, 2e6)
    m = rng.uniform(0.0, 20.0, n) if masses else 4.0
    f = rng.uniform(0.0, 400.0, n)
    got = rotorid.series_impedance(zb, zd, m, f)
    ref, cond = _series_reference(zb, zd, m, f)
    assert got.shape == (n, 2, 2) and got.dtype == complex
    scale = np.abs(ref).max(axis=(1, 2), keepdims=True)
    assert np.all(np.abs(got - ref) <= 1e-10 * np.maximum(cond, 1.0)[:, None, None] * scale)
    # and exactly the core's own result: the wrapper neither copies wrongly nor reorders
    zb3 = np.ascontiguousarray(np.broadcast_to(zb, (n, 2, 2)) if per_point else np.asarray(zb)[None])
    direct, nbad = core.series_impedance(zb3, np.ascontiguousarray(zd), np.atleast_1d(np.asarray(m, float)),
                                         2 * np.pi * f)
    assert nbad == 0
    np.testing.assert_array_equal(got, direct)


def _args(n=6):
    rng = np.random.default_rng(0)
    return dict(z_bearing=_z(rng, n, 3e7), z_damper=_z(rng, n, 2e6), journal_mass_kg=np.full(n, 2.0),
                freq_hz=np.linspace(10.0, 200.0, n))


@pytest.mark.parametrize("name", ["z_bearing", "z_damper", "journal_mass_kg", "freq_hz"])
@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf, complex(1.0, np.nan)])
@pytest.mark.parametrize("where", [0, 3, 5])
def test_series_names_every_non_finite_argument(name, bad, where):
    args = _args()
    a = args[name].copy()
    if np.iscomplexobj(bad) and not np.iscomplexobj(a):
        bad = complex(bad).imag                                  # a real argument: its NaN
    if a.ndim == 3:
        a[where, 1, 0] = bad
        index = f"({where}, 1, 0)"
    else:
        a[where] = bad
        index = f"({where},)"
    args[name] = a
    with pytest.raises(RotoridError, match=re.escape(f"{name} contains NaN or inf (first at index {index})")):
        rotorid.series_impedance(**args)


@pytest.mark.parametrize("name", ["z_bearing", "z_damper"])
def test_series_names_a_non_finite_single_matrix(name):
    """One (2, 2) matrix for every point: its index as given, not as broadcast."""
    args = _args()
    z = np.eye(2, dtype=complex) * 1e6
    z[1, 1] = np.nan
    args[name] = z
    with pytest.raises(RotoridError, match=re.escape(f"{name} contains NaN or inf (first at index (1, 1))")):
        rotorid.series_impedance(**args)
    args[name] = [[1e6, 0.0], [0.0, float("inf")]]                # nested lists alike
    with pytest.raises(RotoridError, match=re.escape(f"{name} contains NaN or inf (first at index (1, 1))")):
        rotorid.series_impedance(**args)


def test_series_scalar_frequency_and_mass_errors():
    args = _args(1)
    for name, value, msg in [("freq_hz", float("nan"), "freq_hz contains NaN or inf (first at index ())"),
                             ("freq_hz", -1.0, "freq_hz must be >= 0"),
                             ("freq_hz", 2e6, "freq_hz up to 2e+06 Hz: beyond 1e6 Hz"),
                             ("freq_hz", [10.0, 3e6], "freq_hz up to 3e+06 Hz: beyond 1e6 Hz"),
                             ("journal_mass_kg", float("nan"), "journal_mass_kg contains NaN or inf"),
                             ("journal_mass_kg", -1.0, "journal_mass_kg must be >= 0")]:
        kw = dict(args, **{name: value})
        if name == "freq_hz" and np.ndim(value):
            kw.update(z_bearing=np.eye(2) * 1e7, z_damper=np.eye(2) * 1e6, journal_mass_kg=1.0)
        with pytest.raises(RotoridError, match=re.escape(msg)):
            rotorid.series_impedance(**kw)


def test_series_frequency_bounds_are_closed_at_0_and_1e6_hz():
    """The one-pass bounds check keeps [0, 1e6] Hz closed: -0, 0 and 1e6 pass; the nearest values
    outside are refused by name."""
    args = _args(4)
    for edge in (0.0, -0.0, 1e6):
        f = np.array([edge, 10.0, 20.0, 30.0])
        z = rotorid.series_impedance(**{**args, "freq_hz": f})
        direct, _ = core.series_impedance(args["z_bearing"], args["z_damper"], args["journal_mass_kg"], 2 * np.pi * f)
        np.testing.assert_array_equal(z, direct)
    for bad, msg in [(-np.finfo(float).smallest_subnormal, "freq_hz must be >= 0"),
                     (float(np.nextafter(1e6, np.inf)), "beyond 1e6 Hz")]:
        with pytest.raises(RotoridError, match=msg):
            rotorid.series_impedance(**{**args, "freq_hz": np.array([10.0, bad, 20.0, 30.0])})


@pytest.mark.parametrize("w_scale", [0.0, -1.0, np.nan, np.inf])
def test_series_core_refuses_a_bad_w_scale(w_scale):
    args = _args(3)
    with pytest.raises(ValueError, match="w_scale"):
        core.series_impedance(args["z_bearing"], args["z_damper"], args["journal_mass_kg"], args["freq_hz"], w_scale)
    with pytest.raises(ValueError, match="times w_scale must be finite"):
        core.series_impedance(args["z_bearing"], args["z_damper"], args["journal_mass_kg"],
                              np.array([1.0, 1e308, 2.0]), 1e10)


def test_series_a_true_resonance_is_still_named_singular():
    """Finite impedances with a singular point: the frequency is named, not an argument."""
    kb, kd, m = 3e6, 1e6, 10.0
    f0 = np.sqrt((kb + kd) / m) / (2 * np.pi)
    zb = np.broadcast_to(np.eye(2) * kb, (3, 2, 2)).astype(complex)
    with pytest.raises(RotoridError, match=r"singular at freq_hz = \[.*\]: an undamped resonance"):
        rotorid.series_impedance(zb, np.eye(2) * kd, m, [10.0, f0, 30.0])


def test_series_error_precedence_of_non_finite_and_shape():
    """A wrong shape is named before the core runs, even with a NaN elsewhere."""
    args = _args()
    args["z_damper"] = args["z_damper"].copy()
    args["z_damper"][0, 0, 0] = np.nan
    with pytest.raises(RotoridError, match=r"z_bearing has shape \(3, 2\)"):
        rotorid.series_impedance(**dict(args, z_bearing=np.ones((3, 2))))


# ---------------------------------------------------------------------------------------------
# identify_pedestals: the earlier implementation's arithmetic, as the reference


def _old_design(s, p, b, i, cross):
    own = p[..., 2 * i + b]
    cols = [own, s ** 2 * own, s * own]
    if cross:
        other = p[..., 2 * (1 - i) + b]
        cols += [other, s * other]
    X = np.stack([c.ravel() for c in cols], -1)
    return np.concatenate([X.real, X.imag], 0)


def _old_hc3(X, r):
    XtXi = np.linalg.inv(X.T @ X)
    h = np.einsum("ij,jk,ik->i", X, XtXi, X)
    meat = (X * (r / np.clip(1 - h, 1e-12, None))[:, None] ** 2).T @ X
    return XtXi @ meat @ XtXi


def _reference(rotor, runs, *, cross_coupled=False, freq_range_hz=None, shared_cov=None):
    """identify_pedestals as it was computed before (arguments assumed valid), and the condition
    number of each fit's scaled design (2, 2)."""
    from rotorid.identify import _pedestal_frame, _shared

    cross = cross_coupled
    labels = [f"run {i}" for i in range(len(runs))]
    impact = isinstance(runs[0], ImpactResponse)
    if impact:
        f = runs[0].freq_hz
        w = 2 * np.pi * f
        spin = np.array([runs[0].speed_rpm * RPM])
        gain = np.ones(1)
        e = np.stack([r.excitation() for r in runs]).astype(complex)
        sigma = runs[0].sigma
    else:
        rpm = runs[0].speed_rpm
        f = rpm / 60.0
        w = spin = rpm * RPM
        gain = w ** 2
        sigma = 0.0
        e = np.stack([r.imbalance.generalized(rotor) for r in runs])
    frames = [_pedestal_frame(rotor, r, lab) for r, lab in zip(runs, labels)]
    shared = _shared(rotor, runs, shared_cov, size=16)
    q = np.stack([fr[0] for fr in frames])
    p = np.stack([fr[1] for fr in frames])
    covs = [fr[2] for fr in frames]
    have_cov = all(c is not None for c in covs)
    dofs = [np.asarray(r.dof, float) if r.dof is not None else np.full(w.size, np.inf) for r in runs]
    min_dof = float(np.nanmin(np.concatenate(dofs))) if have_cov else np.inf
    weighted = have_cov and min_dof >= GLS_MIN_DOF
    sel = np.ones(w.size, bool)
    if freq_range_hz is not None:
        sel = (f >= freq_range_hz[0]) & (f <= freq_range_hz[1])
    s_lap = sigma + 1j * w
    sig_arr = np.full(w.size, sigma) if sigma else None

    def forces(qq, pp):
        return core.bearing_forces(rotor.core_params(), w, spin, np.ascontiguousarray(qq[None]),
                                   np.ascontiguousarray(e[None], dtype=complex), gain, sigma=sig_arr,
                                   q_ped=np.ascontiguousarray(pp[None]))[0]

    F = forces(q, p)
    R = q.shape[0]
    nu = 5 if cross else 3
    if have_cov:
        J = force_jacobian(forces, q, p)
        S = np.stack(covs)
        unknown = np.isnan(S).any(axis=(0, 2, 3))
        if unknown[sel].all():
            have_cov = False
        else:
            sel = sel & ~unknown
            S = np.nan_to_num(S)
            Sh = None if shared is None else np.nan_to_num(shared)
    out = {k: np.zeros((2, 2)) for k in ("mass_kg", "mass_std", "dof", "residual")}
    out.update({k: np.zeros((2, 2, 2)) for k in ("k", "c", "k_std", "c_std")})
    conds = np.zeros((2, 2))
    for b in range(2):
        for i in range(2):
            col = 2 * i + b
            X = _old_design(s_lap[None].repeat(R, 0)[:, sel], p[:, sel], b, i, cross)
            y = np.concatenate([F[:, sel, col].ravel().real, F[:, sel, col].ravel().imag])
            if not np.all(np.isfinite(X)) or not np.all(np.isfinite(y)):
                raise RotoridError("runs contain NaN or inf")
            scale = np.maximum(np.abs(X).max(axis=0), 1e-300)
            Xs = X / scale
            theta, *_ = np.linalg.lstsq(Xs, y, rcond=None)
            if np.linalg.matrix_rank(Xs) < nu:
                raise IdentifiabilityError(f"pedestal {b + 1} {'xy'[i]}: the equations are rank deficient (too few "
                                           "distinct frequencies, or no pedestal motion in that direction)")
            conds[b, i] = np.linalg.cond(Xs)
            m_rows = y.size
            if have_cov:
                # the weighted fit or the sandwich as the pedestal-covariance oracle computes them
                th_c, cov_c, _, src = covariance_fit(theta / scale, b, i, cross, R, sel, s_lap, w, F, p, J, S, Sh,
                                                     weighted)
                theta, covt = th_c * scale, cov_c * np.outer(scale, scale)
                if not weighted:
                    # unweighted: the larger of the sandwich and the residual (HC3) variances
                    c3 = _old_hc3(Xs, y - Xs @ theta)
                    big = np.diag(c3) > np.diag(covt)
                    covt = np.where(big[:, None] & big[None, :], c3, covt)
            else:
                covt = _old_hc3(Xs, y - Xs @ theta)
                src = "residual"
            sd = np.sqrt(np.clip(np.diag(covt), 0, None)) / scale
            th = theta / scale
            out["k"][b, i, i], out["mass_kg"][b, i], out["c"][b, i, i] = th[0], th[1], th[2]
            out["k_std"][b, i, i], out["mass_std"][b, i], out["c_std"][b, i, i] = sd[0], sd[1], sd[2]
            if cross:
                out["k"][b, i, 1 - i], out["c"][b, i, 1 - i] = th[3], th[4]
                out["k_std"][b, i, 1 - i], out["c_std"][b, i, 1 - i] = sd[3], sd[4]
            out["dof"][b, i] = m_rows - nu
            fit = X @ th
            out["residual"][b, i] = np.sqrt(np.sum((y - fit) ** 2) / max(np.sum(y ** 2), 1e-300))
    out.update(std_source=src, points=R * int(sel.sum()), cross_coupled=cross)
    return out, conds


def _compare(fit, ref, conds, *, exact):
    """Every field of ``fit`` against the reference (see the module docstring for the bounds)."""
    assert fit.std_source == ref["std_source"] and fit.points == ref["points"]
    assert fit.cross_coupled is ref["cross_coupled"]
    np.testing.assert_array_equal(fit.dof, ref["dof"])
    for nm in ("mass_kg", "k", "c"):
        got, want = getattr(fit, nm), ref[nm]
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12 * np.abs(want).max(), err_msg=nm)
    # (X^T X)^-1 rounds to about cond² eps relative; the HC3 meat weighs each row by its residual
    # r_i = y_i - x_i theta, which an estimate rounded by cond eps moves by cond eps |y| (first
    # order: unlike sum r², the row weights are not stationary at the least-squares solution),
    # relative to |r|: cond eps / (|r| / |y|). Measured on the noisy case rel=1e-4 (|r|/|y| ~
    # 1e-4, cond 19-69) against long-double HC3 from the same equations: the reference 1.4e-13 to
    # 2.8e-12 off, the core 3e-14 to 9e-13 (test_hc3_standard_errors_match_long_double below).
    # Per fit (b, i), broadcast over [b, i, j].
    rtol = np.maximum(1e-12, 20 * EPS * conds ** 2 + EPS * conds / np.maximum(ref["residual"], 1e-300))
    for nm, est in (("mass_std", "mass_kg"), ("k_std", "k"), ("c_std", "c")):
        got, want = getattr(fit, nm), ref[nm]
        tol = rtol if got.ndim == 2 else rtol[..., None]
        floor = 1e-12 * np.abs(ref[est]).max()                     # noise-free: rounding noise
        bound = tol * np.abs(want) + (floor if exact else 0.0)
        assert np.all(np.abs(got - want) <= bound), (nm, np.abs(got - want) / np.abs(want))
    np.testing.assert_allclose(fit.residual, ref["residual"], rtol=1e-12, atol=1e-12 if exact else 0.0)


RIG = rotorid.nsf_rig()
ROTOR, BRG, _ = example_rig()
PEDX = Pedestals(mass_kg=[[15.0, 22.0], [25.0, 18.0]],
                 k=[[[2.0e7, 3.0e6], [-2.0e6, 2.6e7]], [[2.2e7, -1.0e6], [4.0e6, 2.8e7]]],
                 c=[[[2500.0, 300.0], [100.0, 2000.0]], [[3000.0, -200.0], [0.0, 2800.0]]])
RPM_GRID = np.linspace(1000.0, 8000.0, 40)


def _sync(ped=PEDX, rpm=RPM_GRID, sets="AB", at="bearings"):
    return [rotorid.imbalance_response(ROTOR, BRG, RIG.imbalances[s], speed_rpm=rpm, pedestals=ped, at=at)
            for s in sets]


def _noisy(runs, rel, rng, *, cov=False, dof=None):
    """Complex Gaussian noise of ``rel`` times each point's rms reading on q and on the pedestal
    motion; with ``cov`` its covariance given (and ``dof``)."""
    out = []
    for r in runs:
        sq = rel * np.sqrt(np.mean(np.abs(r.q) ** 2, axis=1))
        sp = rel * np.sqrt(np.mean(np.abs(r.pedestal) ** 2, axis=1))

        def noise(sig):
            return (sig / np.sqrt(2))[:, None] * (rng.standard_normal(r.q.shape) + 1j * rng.standard_normal(r.q.shape))

        kw = {}
        if cov:
            kw = dict(cov=np.eye(8)[None] * (sq ** 2 / 2)[:, None, None], dof=dof,
                      pedestal_cov=np.eye(8)[None] * (sp ** 2 / 2)[:, None, None])
        out.append(SyncResponse(r.speed_rpm, r.q + noise(sq), r.imbalance, r.at, r.name,
                                pedestal=r.pedestal + noise(sp), **kw))
    return out


def _check(runs, exact=False, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")   # pedestal-dominated points, as the reference would warn
        fit = rotorid.identify_pedestals(ROTOR, runs, **kw)
        ref, conds = _reference(ROTOR, runs, **kw)
    _compare(fit, ref, conds, exact=exact)
    return fit


@pytest.mark.parametrize("cross", [False, True])
@pytest.mark.parametrize("at", ["bearings", "probes"])
def test_exact_runs_match_the_reference(cross, at):
    fit = _check(_sync(at=at), exact=True, cross_coupled=cross)
    if cross:
        np.testing.assert_allclose(fit.k, PEDX.k, rtol=1e-6, atol=1.0)


@pytest.mark.parametrize("rel", [1e-4, 1e-2, 0.2])
@pytest.mark.parametrize("cross", [False, True])
@pytest.mark.parametrize("freq_range_hz", [None, (30.0, 110.0)])
def test_noisy_runs_match_the_reference(rel, cross, freq_range_hz):
    rng = np.random.default_rng(int(rel * 1e4) + 10 * cross)
    _check(_noisy(_sync(), rel, rng), cross_coupled=cross, freq_range_hz=freq_range_hz)


def test_one_run_and_three_runs_match_the_reference():
    rng = np.random.default_rng(3)
    _check(_noisy(_sync(sets="B"), 1e-3, rng), cross_coupled=True)
    _check(_noisy(_sync(sets="ABC"), 1e-3, rng), cross_coupled=False)


@pytest.mark.parametrize("dof", [None, 4.0], ids=["weighted", "sandwich"])
@pytest.mark.parametrize("cross", [False, True])
def test_runs_with_covariances_match_the_reference(dof, cross):
    rng = np.random.default_rng(11)
    runs = _noisy(_sync(rpm=np.linspace(1000.0, 8000.0, 16)), 5e-3, rng, cov=True,
                  dof=None if dof is None else np.full(16, dof))
    fit = _check(runs, cross_coupled=cross)
    assert fit.std_source.startswith("measurement" if dof is None else "residual or measurement")


def test_shared_covariance_matches_the_reference():
    rng = np.random.default_rng(12)
    rpm = np.linspace(3000.0, 6000.0, 12)
    runs = _noisy(_sync(rpm=rpm, at="probes"), 5e-3, rng, cov=True)
    shared = np.zeros((rpm.size, 16, 16))
    shared[:, :8, :8] = runs[0].cov / 2
    shared[:, 8:, 8:] = runs[0].pedestal_cov / 2
    _check(runs, shared_cov=shared)


@pytest.mark.parametrize("sigma", [0.0, 15.0])
def test_noisy_impacts_match_the_reference(sigma):
    rng = np.random.default_rng(int(sigma) + 1)
    f = np.linspace(5.0, 150.0, 40)
    tests = []
    for d in "xy":
        t = rotorid.impact_frf(ROTOR, BRG, speed_rpm=3000.0, freq_hz=f, direction=d, pedestals=PEDX)
        noise = 1e-3 * np.abs(t.q).max() * (rng.standard_normal(t.q.shape) + 1j * rng.standard_normal(t.q.shape))
        tests.append(ImpactResponse(3000.0, f, t.q + noise, direction=d, sigma=sigma,
                                    pedestal=t.pedestal * (1 + 1e-3 * rng.standard_normal(t.q.shape))))
    _check(tests, cross_coupled=True)


def test_a_large_problem_matches_the_reference():
    """20,000 speeds: the sums over many rows (pairwise here, BLAS there) still agree."""
    rng = np.random.default_rng(21)
    _check(_noisy(_sync(rpm=np.linspace(1000.0, 8000.0, 20000)), 1e-3, rng), cross_coupled=True)


# ---------------------------------------------------------------------------------------------
# identify_pedestals: the same errors


def _same_error(runs, exc_type, **kw):
    with pytest.raises(exc_type) as new:
        rotorid.identify_pedestals(ROTOR, runs, **kw)
    with pytest.raises(exc_type) as old:
        _reference(ROTOR, runs, **kw)
    assert str(new.value) == str(old.value)
    return str(new.value)


def _with_pedestal(runs, edit):
    out = []
    for r in runs:
        p = r.pedestal.copy()
        edit(p)
        out.append(SyncResponse(r.speed_rpm, r.q, r.imbalance, r.at, r.name, pedestal=p))
    return out


@pytest.mark.parametrize("cross", [False, True])
@pytest.mark.parametrize("dof", [0, 1, 2, 3])
def test_no_pedestal_motion_in_a_direction_is_rank_deficient(cross, dof):
    def drop(p):
        p[:, dof] = 0.0

    msg = _same_error(_with_pedestal(_sync(), drop), IdentifiabilityError, cross_coupled=cross)
    assert "rank deficient" in msg


def test_one_distinct_speed_is_rank_deficient():
    msg = _same_error(_sync(rpm=np.full(5, 3000.0)), IdentifiabilityError)
    assert msg.startswith("pedestal 1 x: the equations are rank deficient")


def test_proportional_cross_motion_is_rank_deficient():
    """The other direction moving in proportion (real factor) to the own one: k_ij and k_ii are
    one unknown, and c_ij and c_ii."""
    def tie(p):
        p[:, 2] = 0.7 * p[:, 0]

    msg = _same_error(_with_pedestal(_sync(), tie), IdentifiabilityError, cross_coupled=True)
    assert "rank deficient" in msg
    _check(_with_pedestal(_sync(), tie), exact=True, cross_coupled=False)   # fine without cross terms


def test_a_design_that_overflows_is_refused_alike():
    def huge(p):
        p /= np.abs(p).max()
        p *= 1e304

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        assert _same_error(_with_pedestal(_sync(), huge), RotoridError) == "runs contain NaN or inf"


@pytest.mark.parametrize("field, pattern", [
    ("pedestal", r"run 1 \('B'\): pedestal .*contains NaN or inf \(first at index \(2, 1\)\)"),
    ("q", r"run 1 \('B'\): q contains NaN or inf \(first at index \(2, 1\)\)"),
])
def test_nan_set_in_a_run_after_construction_is_named(field, pattern):
    runs = _sync(rpm=np.linspace(2000.0, 6000.0, 8))
    arr = getattr(runs[1], field).copy()
    arr[2, 1] = np.nan
    setattr(runs[1], field, arr)
    with pytest.raises(RotoridError, match=pattern):
        rotorid.identify_pedestals(ROTOR, runs)


@pytest.mark.parametrize("kw, pattern", [
    (dict(freq_range_hz=[np.nan, 100.0]), r"freq_range_hz contains NaN or inf"),
    (dict(freq_range_hz=[10.0, np.inf]), r"freq_range_hz contains NaN or inf"),
    (dict(accel_gain_std=np.nan), r"accel_gain_std"),
    (dict(accel_phase_std_deg=np.nan), r"accel_phase_std_deg"),
    (dict(cross_coupled=np.nan), r"cross_coupled must be True or False"),
])
def test_nan_arguments_are_named(kw, pattern):
    with pytest.raises(RotoridError, match=pattern):
        rotorid.identify_pedestals(ROTOR, _sync(rpm=np.linspace(2000.0, 6000.0, 8)), **kw)


# ---------------------------------------------------------------------------------------------
# the core's pedestal fit: its own argument checks


def _core_args(runs):
    w = runs[0].speed_rpm * RPM
    e = np.stack([r.imbalance.generalized(ROTOR) for r in runs])[None].astype(complex)
    return ROTOR.core_params(), w, w, [r.q for r in runs], e, None, [r.pedestal for r in runs]


def test_core_pedestal_fit_refuses_bad_arguments():
    runs = _sync(rpm=np.linspace(2000.0, 6000.0, 12))
    params, w, spin, qs, e, gain, ps = _core_args(runs)
    n = w.size
    with pytest.raises(ValueError, match=r"select has shape \[5\], expected \[12\]"):
        core.pedestal_fit(params, w, spin, qs, e, gain, ps, select=np.ones(5, bool))
    with pytest.raises(ValueError, match=r"select must be a bool array of shape \(12,\)"):
        core.pedestal_fit(params, w, spin, qs, e, gain, ps, select=np.ones(n))  # not bool
    with pytest.raises(ValueError, match="q_ped is needed"):
        core.pedestal_fit(params, w, spin, qs, e, gain, None)
    with pytest.raises(ValueError, match="q_ped"):
        core.pedestal_fit(params, w, spin, qs, e, gain, ps[:1])
    with pytest.raises(ValueError, match="C-contiguous"):
        core.pedestal_fit(params, w, spin, qs, e, gain, [np.asfortranarray(p) for p in ps])
    one = np.zeros(n, bool)
    one[3] = True
    with pytest.raises(ValueError, match="4 equations for 5 unknowns"):
        core.pedestal_fit(params, w, spin, qs, e, gain, ps, select=one, cross=True)
    two = np.concatenate([qs[0][None, None], qs[0][None, None]])           # batch of 2
    with pytest.raises(ValueError, match="batch must be 1"):
        core.pedestal_fit(params, w, spin, two, np.concatenate([e[:, :1]] * 2), gain,
                          np.concatenate([ps[0][None, None]] * 2))


def test_core_pedestal_fit_of_a_selection_equals_the_fit_of_the_selected_points():
    """``select`` leaves points out exactly as slicing the runs would (bit-identical for one task
    of points: the same equations in the same order)."""
    rng = np.random.default_rng(5)
    runs = _noisy(_sync(rpm=np.linspace(1000.0, 8000.0, 40)), 1e-3, rng)
    params, w, spin, qs, e, gain, ps = _core_args(runs)
    sel = (np.arange(w.size) % 3) != 0
    got = core.pedestal_fit(params, w, spin, qs, e, gain, ps, select=sel, cross=True)
    cut = core.pedestal_fit(params, w[sel], spin[sel], [np.ascontiguousarray(q[sel]) for q in qs], e, gain,
                            [np.ascontiguousarray(p[sel]) for p in ps], cross=True)
    for a, b in zip(got, cut):
        np.testing.assert_array_equal(a, b)


def _long_double_hc3(runs, cross, sel):
    """HC3 standard errors of the four fits in long double (64-bit mantissa on x86-64) from the
    same equations (forces from the core in double): Gaussian elimination with partial pivoting on
    the scaled normal equations, whose rounding (cond² 2^-64, about 5e-16 for cond ~ 70) is far
    below the double-precision errors compared against. Returns (2, 2, u) standard errors."""
    rpm = runs[0].speed_rpm
    w = rpm * RPM
    e = np.stack([r.imbalance.generalized(ROTOR) for r in runs])[None].astype(complex)
    F = core.bearing_forces(ROTOR.core_params(), w, w, [r.q for r in runs], e, None,
                            q_ped=[r.pedestal for r in runs])[0]
    L = np.longdouble

    def solve(A, B):
        A, B = A.copy(), B.copy()
        n = A.shape[0]
        for k in range(n):
            piv = int(np.argmax(np.abs(A[k:, k]))) + k
            A[[k, piv]], B[[k, piv]] = A[[piv, k]], B[[piv, k]]
            for i in range(k + 1, n):
                f = A[i, k] / A[k, k]
                A[i] -= f * A[k]
                B[i] -= f * B[k]
        x = np.zeros_like(B)
        for k in range(n - 1, -1, -1):
            x[k] = (B[k] - A[k, k + 1:] @ x[k + 1:]) / A[k, k]
        return x

    u = 5 if cross else 3
    out = np.zeros((2, 2, u))
    s = 1j * w[sel]
    for b in range(2):
        for i in range(2):
            col, oc = 2 * i + b, 2 * (1 - i) + b
            rows, ys = [], []
            for r in range(len(runs)):
                p = runs[r].pedestal[sel]
                cols = [p[:, col], s ** 2 * p[:, col], s * p[:, col]] + ([p[:, oc], s * p[:, oc]] if cross else [])
                for part in (np.real, np.imag):
                    rows.append(np.stack([part(c) for c in cols], 1))
                    ys.append(part(F[r, sel, col]))
            X, y = np.concatenate(rows).astype(L), np.concatenate(ys).astype(L)
            scale = np.abs(X).max(0)
            Xs = X / scale
            G = Xs.T @ Xs
            Gi = solve(G, np.eye(u, dtype=L))
            r_ = y - Xs @ solve(G, Xs.T @ y)
            h = np.einsum("ij,jk,ik->i", Xs, Gi, Xs)
            meat = (Xs * ((r_ / (1 - h)) ** 2)[:, None]).T @ Xs
            out[b, i] = (np.sqrt(np.diag(Gi @ meat @ Gi)) / scale).astype(float)
    return out


@pytest.mark.parametrize("rel, cross", [(1e-4, True), (1e-4, False), (1e-2, True)])
def test_hc3_standard_errors_match_long_double(rel, cross):
    """The core's HC3 standard errors against long-double arithmetic on the same equations, within
    the first-order rounding of the residuals (cond eps |y| / |r|, see _compare) plus that of
    (X^T X)^-1 (cond² eps)."""
    rng = np.random.default_rng(int(rel * 1e4) + 10 * cross)
    runs = _noisy(_sync(), rel, rng)
    sel = np.ones(RPM_GRID.size, bool)
    fit = rotorid.identify_pedestals(ROTOR, runs, cross_coupled=cross)
    truth = _long_double_hc3(runs, cross, sel)
    for b in range(2):
        for i in range(2):
            got = [fit.k_std[b, i, i], fit.mass_std[b, i], fit.c_std[b, i, i]]
            if cross:
                got += [fit.k_std[b, i, 1 - i], fit.c_std[b, i, 1 - i]]
            # cond of the scaled design
            rows = []
            for r in runs:
                p = r.pedestal
                s = 1j * r.speed_rpm * RPM
                c = [p[:, 2 * i + b], s ** 2 * p[:, 2 * i + b], s * p[:, 2 * i + b]]
                if cross:
                    c += [p[:, 2 * (1 - i) + b], s * p[:, 2 * (1 - i) + b]]
                rows += [np.stack([z.real for z in c], 1), np.stack([z.imag for z in c], 1)]
            X = np.concatenate(rows)
            cond = np.linalg.cond(X / np.abs(X).max(0))
            rtol = 20 * EPS * cond ** 2 + EPS * cond / fit.residual[b, i]
            np.testing.assert_allclose(got, truth[b, i], rtol=rtol, atol=0, err_msg=f"pedestal {b + 1} {'xy'[i]}")


def test_axes_that_are_views_are_taken():
    """A reversed run-down or a column of a table (strided views the responses keep as they are)
    give the fit of the same data stored contiguously (found by review: the core refused them)."""
    runs = _sync(rpm=np.linspace(2000.0, 6000.0, 12))
    rev = [SyncResponse(r.speed_rpm[::-1], r.q[::-1], r.imbalance, pedestal=r.pedestal[::-1]) for r in runs]
    assert not rev[0].speed_rpm.flags.c_contiguous
    a = rotorid.identify_pedestals(ROTOR, runs, cross_coupled=True)
    b = rotorid.identify_pedestals(ROTOR, rev, cross_coupled=True)
    np.testing.assert_allclose(b.k, a.k, rtol=1e-12)
    np.testing.assert_allclose(b.k_std, a.k_std, rtol=1e-9)
    tab = np.stack([np.linspace(5.0, 150.0, 30), np.zeros(30)], 1)             # freq_hz as a table column
    tests = [rotorid.impact_frf(ROTOR, BRG, speed_rpm=3000.0, freq_hz=tab[:, 0], direction=d, pedestals=PEDX)
             for d in "xy"]
    assert not tests[0].freq_hz.flags.c_contiguous
    fit = rotorid.identify_pedestals(ROTOR, tests, cross_coupled=True)
    np.testing.assert_allclose(fit.k, PEDX.k, rtol=1e-6, atol=1.0)
    col = np.stack([RPM_GRID, RPM_GRID], 1)[:, 0]                              # speed_rpm as a table column
    for ped in (None, PEDX):
        got = rotorid.imbalance_response(ROTOR, BRG, RIG.imbalances["A"], speed_rpm=col, pedestals=ped)
        want = rotorid.imbalance_response(ROTOR, BRG, RIG.imbalances["A"], speed_rpm=RPM_GRID, pedestals=ped)
        np.testing.assert_array_equal(got.q, want.q)
    bare = [rotorid.impact_frf(ROTOR, BRG, speed_rpm=3000.0, freq_hz=tab[:, 0], direction=d) for d in "xy"]
    ident = rotorid.identify_impact(ROTOR, bare)
    np.testing.assert_allclose(ident.k[:, 0, 0, 0], BRG.k[0][0, 0], rtol=1e-6)


def test_nan_in_the_pedestal_motion_of_a_probe_run_is_named():
    """Runs at the probes are moved to the bearings with their pedestal motion: a NaN set in it
    after construction is named with the run and the field (review: it was blamed on q)."""
    for run, field, index, bad, name in [(1, "pedestal", (2, 1), np.nan, "B"), (0, "q", (3, 0), np.inf, "A")]:
        runs = _sync(rpm=np.linspace(2000.0, 6000.0, 8), at="probes")
        arr = getattr(runs[run], field).copy()
        arr[index] = bad
        setattr(runs[run], field, arr)
        with pytest.raises(RotoridError, match=rf"run {run} \('{name}'\): {field} .*contains NaN or inf "
                                               rf"\(first at index \({index[0]}, {index[1]}\)\)"):
            rotorid.identify_pedestals(ROTOR, runs)


def test_covariances_unknown_everywhere_warn_that_the_fit_is_unweighted():
    rng = np.random.default_rng(3)
    runs = _noisy(_sync(rpm=np.linspace(2000.0, 6000.0, 10)), 1e-3, rng, cov=True, dof=50)
    for r in runs:
        r.cov = np.full_like(r.cov, np.nan)
    shared = np.zeros((10, 16, 16))
    with pytest.warns(UserWarning, match="no point has a known measurement covariance.*shared_cov is not used"):
        fit = rotorid.identify_pedestals(ROTOR, runs, shared_cov=shared)
    assert fit.std_source == "residual"
