"""A literal NumPy oracle of docs/studies.md (Monte Carlo identification studies), used only by the tests.

Written from the spec directly, step by step, with dense matrices and np.linalg; independent of
rotorid's internals (only the rotor matrices of ``tests/oracle.py`` are reused). Readability over
speed: every array keeps its named axes, (T trials, R runs or tests, n points, 4 channels).

Random numbers (spec "Random numbers"): ``mix``, ``stream_key``, ``uniforms``, ``normals`` on
np.uint64 arrays with wrapping arithmetic. Every constant is an np.uint64 so that no Python int
promotes an operand to float or object.

Measurement models: ``sync_measured`` (synchronous table) and ``impact_measured`` (impact table)
return the measured 1X vectors / FRFs at the channels x1, x2, y1, y2 (before any probe-to-bearing
transform). The identification of the measured data as rotorid does it (nominal probe positions,
eq. 19; bearing-force method) is ``probes_to_bearings`` + ``identify_forces``, the whole study
``sync_errors`` / ``impact_errors``; statistics ``relative_errors``, ``histogram``,
``percentiles_from_histogram``.
"""

import numpy as np

from oracle import matrices

U64 = np.uint64
MASK = (1 << 64) - 1
GOLDEN = U64(0x9E3779B97F4A7C15)
SEED_SALT = U64(0x5EED5EED5EED5EED)
STREAM_MUL = U64(0xD1B54A32D192ED03)
M1 = U64(0xBF58476D1CE4E5B9)
M2 = U64(0x94D049BB133111EB)

#: report (eq. 9) order -> flat [bearing][i][j] index, for each of K and C
REPORT_TO_BIJ = np.array([0, 4, 1, 5, 2, 6, 3, 7])
REPORT_NAMES = ("Kxx1", "Kxx2", "Kxy1", "Kxy2", "Kyx1", "Kyx2", "Kyy1", "Kyy2",
                "Cxx1", "Cxx2", "Cxy1", "Cxy2", "Cyx1", "Cyx2", "Cyy1", "Cyy2")

SYNC_KEYS = ("amplitude_rel", "phase_deg", "noise_m", "keyphasor_deg", "channel_delay_s", "probe_position_m",
             "trial_mass_rel", "trial_angle_deg", "speed_rel")
IMPACT_KEYS = ("coherence", "impacts", "force_calibration_rel", "impact_position_m", "channel_delay_s",
               "probe_position_m")

# histogram of the statistics
HIST_BINS = 1024
HIST_E0 = 2.0 ** -20      # errors below E0 are binned linearly, above by octaves
HIST_SUB = 16             # bins per octave (and linear bins below E0)


# ---------------------------------------------------------------------------------------------
# random numbers

def _u64(x):
    """Python int(s) or integer array -> np.uint64 array (Python ints taken modulo 2^64)."""
    if isinstance(x, (int, np.integer)):
        return np.array(int(x) & MASK, dtype=U64)
    a = np.asarray(x)
    if a.dtype == U64:
        return a
    if a.dtype == object:
        return np.array([int(v) & MASK for v in a.ravel()], dtype=U64).reshape(a.shape)
    return a.astype(np.int64).astype(U64)


def mix(z):
    """SplitMix64 finalizer, elementwise on uint64 (wrapping)."""
    z = _u64(z).copy()
    with np.errstate(over="ignore"):
        z ^= z >> U64(30)
        z *= M1
        z ^= z >> U64(27)
        z *= M2
        z ^= z >> U64(31)
    return z


def mix_py(z):
    """The same in pure Python integers (reference for ``mix``)."""
    z &= MASK
    z ^= z >> 30
    z = (z * 0xBF58476D1CE4E5B9) & MASK
    z ^= z >> 27
    z = (z * 0x94D049BB133111EB) & MASK
    z ^= z >> 31
    return z


def stream_key(seed, trial, stream):
    """Key of stream ``stream`` of trial ``trial`` (each may be an array; broadcast)."""
    seed, trial, stream = _u64(seed), _u64(trial), _u64(stream)
    with np.errstate(over="ignore"):
        key = mix(mix(seed ^ SEED_SALT) ^ (trial * GOLDEN + U64(1)))
        key = mix(key ^ (stream * STREAM_MUL + U64(1)))
    return key


def stream_key_py(seed, trial, stream):
    key = mix_py(mix_py(seed ^ 0x5EED5EED5EED5EED) ^ ((trial * 0x9E3779B97F4A7C15 + 1) & MASK))
    return mix_py(key ^ ((stream * 0xD1B54A32D192ED03 + 1) & MASK))


def uniforms(key, count):
    """Uniforms 0..count-1 of the stream(s) ``key`` (...): array (..., count) strictly in (0, 1)."""
    key = _u64(key)
    i = np.arange(count, dtype=U64)
    with np.errstate(over="ignore"):
        z = mix(key[..., None] + (i + U64(1)) * GOLDEN)
    return ((z >> U64(12)).astype(np.float64) + 0.5) * 2.0 ** -52


def normals(key, count):
    """Standard normals 0..count-1 of the stream(s) ``key`` (...): (..., count), Box-Muller pairs
    (normal 2j = r cos(2 pi u_{2j+1}), 2j+1 = r sin(2 pi u_{2j+1}), r = sqrt(-2 ln u_{2j}))."""
    pairs = (count + 1) // 2
    u = uniforms(key, 2 * pairs)
    r = np.sqrt(-2.0 * np.log(u[..., 0::2]))
    t = 2.0 * np.pi * u[..., 1::2]
    out = np.empty(u.shape)
    out[..., 0::2] = r * np.cos(t)
    out[..., 1::2] = r * np.sin(t)
    return out[..., :count]


def _trial_normals(seed, trials, count):
    """(T, count) normals of the trial streams (stream 0)."""
    return normals(stream_key(seed, np.asarray(trials), 0), count)


def _point_normals(seed, trials, n, count):
    """(T, n, count) normals of the point streams (stream 1 + p)."""
    keys = stream_key(seed, np.asarray(trials)[:, None], 1 + np.arange(n)[None, :])
    return normals(keys, count)


# ---------------------------------------------------------------------------------------------
# rotor model

def system_matrices(rotor_params, kb8, cb8):
    """M, G (4, 4) and K, C (n, 4, 4) of eq. 3 from per-point coefficients (n, 8) [bearing][i][j]."""
    m, it, ip, l1, l2 = (float(v) for v in rotor_params)
    kb8 = np.atleast_2d(np.asarray(kb8, float))
    cb8 = np.atleast_2d(np.asarray(cb8, float))
    Ks, Cs = [], []
    for k8, c8 in zip(kb8, cb8):
        M, G, K, C = matrices(m, it, ip, l1, l2, k8.reshape(2, 2, 2), c8.reshape(2, 2, 2))
        Ks.append(K)
        Cs.append(C)
    return M, G, np.array(Ks), np.array(Cs)


def dynamic_stiffness(M, G, K, C, spin, w):
    """H = K - w^2 M + j w (C + spin G), (n, 4, 4) for arrays spin, w (n,)."""
    spin = np.asarray(spin, float)[:, None, None]
    w = np.asarray(w, float)[:, None, None]
    return K - w ** 2 * M + 1j * w * (C + spin * G)


def imbalance_force(u, planes_z):
    """Generalized force e = [S, -jS, Mo, jMo] (eq. 4) of imbalances u (..., 2) at planes_z (2,)."""
    u = np.asarray(u, complex)
    S = u[..., 0] + u[..., 1]
    Mo = planes_z[0] * u[..., 0] + planes_z[1] * u[..., 1]
    return np.stack([S, -1j * S, Mo, 1j * Mo], axis=-1)


def impact_force(plane_z, direction):
    """Generalized force of a unit impact: x -> [1, 0, z, 0], y -> [0, 1, 0, -z]."""
    if direction == "x":
        return np.array([1.0, 0.0, plane_z, 0.0], complex)
    if direction == "y":
        return np.array([0.0, 1.0, 0.0, -plane_z], complex)
    raise ValueError(direction)


def at_positions(qb, z4, l1, l2):
    """Rigid-body readings of channels x1, x2, y1, y2 at axial positions z4 (..., 4) from bearing
    responses qb (..., 4): x(z) = ((l2 - z) x1 + (l1 + z) x2) / L, the same for y."""
    L = l1 + l2
    x1, x2, y1, y2 = qb[..., 0], qb[..., 1], qb[..., 2], qb[..., 3]
    z = np.asarray(z4, float)
    return np.stack([((l2 - z[..., 0]) * x1 + (l1 + z[..., 0]) * x2) / L,
                     ((l2 - z[..., 1]) * x1 + (l1 + z[..., 1]) * x2) / L,
                     ((l2 - z[..., 2]) * y1 + (l1 + z[..., 2]) * y2) / L,
                     ((l2 - z[..., 3]) * y1 + (l1 + z[..., 3]) * y2) / L], axis=-1)


def probes_to_bearings(qc, rotor_params, probes_z):
    """Eq. 19 generalized: bearing responses from channels at the nominal positions probes_z (4,)."""
    l1, l2 = float(rotor_params[3]), float(rotor_params[4])
    L = l1 + l2
    z = np.asarray(probes_z, float)
    out = np.empty(np.shape(qc), complex)
    for a, (ca, cb) in enumerate(((0, 1), (2, 3))):
        # [reading a, reading b] = A [bearing 1, bearing 2]
        A = np.array([[l2 - z[ca], l1 + z[ca]], [l2 - z[cb], l1 + z[cb]]]) / L
        Ti = np.linalg.inv(A)
        out[..., 2 * a] = Ti[0, 0] * qc[..., ca] + Ti[0, 1] * qc[..., cb]
        out[..., 2 * a + 1] = Ti[1, 0] * qc[..., ca] + Ti[1, 1] * qc[..., cb]
    return out


def _errs(errors, keys, defaults=None):
    errors = dict(errors or {})
    unknown = set(errors) - set(keys)
    if unknown:
        raise KeyError(f"unknown error keys {sorted(unknown)}")
    d = dict.fromkeys(keys, 0.0) | dict(defaults or {})
    d.update(errors)
    return {k: float(v) for k, v in d.items()}


# ---------------------------------------------------------------------------------------------
# synchronous study: measured vectors

def sync_measured(rotor_params, kb, cb, speed_rad, u, planes_z, probes_z, errors, seed, trials):
    """Measured 1X vectors of the synchronous study (spec "Synchronous (imbalance) study", steps 1-4).

    rotor_params [m, I_T, I_p, l1, l2]; kb, cb (n, 8) true coefficients per speed; speed_rad (n,);
    u (R, 2) nominal m r e^{-j phi} per run and plane; planes_z (2,) = (-d1, +d2); probes_z (4,)
    nominal channel positions (x1, x2, y1, y2); errors: dict of the table's standard deviations.
    Returns q (T, R, n, 4) complex at the channels and speed_told (T, n) rad/s."""
    er = _errs(errors, SYNC_KEYS)
    trials = np.atleast_1d(np.asarray(trials, np.int64))
    om = np.asarray(speed_rad, float)
    u = np.asarray(u, complex)
    planes_z = np.asarray(planes_z, float)
    probes_z = np.asarray(probes_z, float)
    T, R, n = trials.size, u.shape[0], om.size
    l1, l2 = float(rotor_params[3]), float(rotor_params[4])

    # trial stream: n[0] keyphasor, n[1+c] delay, n[5+c] position, n[9+4r+p] mass, n[11+4r+p] angle
    nt = _trial_normals(seed, trials, 9 + 4 * R)                     # (T, 9 + 4R)
    keyphasor = np.deg2rad(er["keyphasor_deg"]) * nt[:, 0]           # (T,)
    tau = er["channel_delay_s"] * nt[:, 1:5]                         # (T, 4)
    dz = er["probe_position_m"] * nt[:, 5:9]                         # (T, 4)
    mass_n = np.stack([nt[:, 9 + 4 * r:11 + 4 * r] for r in range(R)], axis=1)    # (T, R, 2)
    angle_n = np.stack([nt[:, 11 + 4 * r:13 + 4 * r] for r in range(R)], axis=1)  # (T, R, 2)

    # point stream (1 + speed index): n[0] speed; run r, channel c at b = 2 + 4(4r + c):
    # amplitude, phase, noise re, noise im
    npnt = _point_normals(seed, trials, n, 2 + 16 * R)               # (T, n, 2 + 16R)
    speed_told = om[None, :] * (1.0 + er["speed_rel"] * npnt[:, :, 0])
    per_rc = npnt[:, :, 2:].reshape(T, n, R, 4, 4)                    # (T, n, run, channel, 4 normals)
    per_rc = per_rc.transpose(0, 2, 1, 3, 4)                          # (T, R, n, channel, 4)
    n_amp, n_ph, n_re, n_im = (per_rc[..., i] for i in range(4))

    # 1. true imbalances and generalized forces
    u_true = u[None] * (1.0 + er["trial_mass_rel"] * mass_n) * np.exp(-1j * np.deg2rad(er["trial_angle_deg"]) * angle_n)
    e_true = imbalance_force(u_true, planes_z)                        # (T, R, 4)

    # 3. true bearing response at the true speed: q = Om^2 H(Om)^-1 e
    M, G, K, C = system_matrices(rotor_params, kb, cb)
    H = dynamic_stiffness(M, G, K, C, om, om)                         # (n, 4, 4)
    rhs = (om ** 2)[None, None, :, None] * e_true[:, :, None, :]      # (T, R, n, 4)
    qb = np.linalg.solve(H[None, None], rhs[..., None])[..., 0]       # (T, R, n, 4)
    # true probe readings at the true positions z_c + delta_c
    z_true = probes_z[None, :] + dz                                   # (T, 4)
    X = at_positions(qb, z_true[:, None, None, :], l1, l2)            # (T, R, n, 4)

    # 4. measured vectors
    phase = (np.deg2rad(er["phase_deg"]) * n_ph + keyphasor[:, None, None, None]
             - om[None, None, :, None] * tau[:, None, None, :])
    q = X * (1.0 + er["amplitude_rel"] * n_amp) * np.exp(1j * phase) \
        + er["noise_m"] * (n_re + 1j * n_im) / np.sqrt(2.0)
    return q, speed_told


# ---------------------------------------------------------------------------------------------
# impact study: measured FRFs

def impact_epsilon(coherence, impacts):
    """Normalized random error of an H1 FRF (Bendat & Piersol eq. 9.73 / 9.90)."""
    return np.sqrt((1.0 - coherence) / (2.0 * impacts * coherence))


def impact_measured(rotor_params, kb, cb, spin_rad, w_rad, tests, probes_z, errors, seed, trials):
    """Measured FRFs of the impact study (spec "Impact study").

    kb, cb (n, 8) true coefficients at each frequency; spin_rad the running speed; w_rad (n,);
    tests: list of (plane_z, "x" | "y"); probes_z (4,) nominal channel positions; errors: dict
    (coherence default 1, impacts default 1, force_calibration_rel, impact_position_m,
    channel_delay_s, probe_position_m). Returns H (T, R, n, 4) complex at the channels, per unit
    nominal force."""
    er = _errs(errors, IMPACT_KEYS, {"coherence": 1.0, "impacts": 1.0})
    trials = np.atleast_1d(np.asarray(trials, np.int64))
    w = np.asarray(w_rad, float)
    probes_z = np.asarray(probes_z, float)
    T, R, n = trials.size, len(tests), w.size
    l1, l2 = float(rotor_params[3]), float(rotor_params[4])
    eps = impact_epsilon(er["coherence"], er["impacts"])

    # trial stream: n[1+c] delay, n[5+c] position, n[9+2t] calibration, n[10+2t] impact position
    nt = _trial_normals(seed, trials, 9 + 2 * R)
    tau = er["channel_delay_s"] * nt[:, 1:5]                          # (T, 4)
    dz = er["probe_position_m"] * nt[:, 5:9]                          # (T, 4)
    cal = er["force_calibration_rel"] * nt[:, 9::2][:, :R]            # (T, R)
    dzi = er["impact_position_m"] * nt[:, 10::2][:, :R]               # (T, R)

    # point stream: test t, channel c at b = 2 + 2(4t + c): re, im of the FRF error
    npnt = _point_normals(seed, trials, n, 2 + 8 * R)[:, :, 2:].reshape(T, n, R, 4, 2)
    npnt = npnt.transpose(0, 2, 1, 3, 4)                              # (T, R, n, 4, 2)
    n_re, n_im = npnt[..., 0], npnt[..., 1]

    # true forces (impacts land at z_t + delta_t), true response at the channels' true positions
    e_true = np.empty((T, R, 4), complex)
    for t, (plane, direction) in enumerate(tests):
        for i in range(T):
            e_true[i, t] = impact_force(plane + dzi[i, t], direction)
    M, G, K, C = system_matrices(rotor_params, kb, cb)
    H = dynamic_stiffness(M, G, K, C, np.full(n, float(spin_rad)), w)  # (n, 4, 4)
    qb = np.linalg.solve(H[None, None], np.broadcast_to(e_true[:, :, None, :], (T, R, n, 4))[..., None])[..., 0]
    X = at_positions(qb, (probes_z[None, :] + dz)[:, None, None, :], l1, l2)

    delay = np.exp(-1j * w[None, None, :, None] * tau[:, None, None, :])
    return X * (1.0 + eps * (n_re + 1j * n_im)) * delay / (1.0 + cal)[:, :, None, None]


# ---------------------------------------------------------------------------------------------
# identification as rotorid does it (method "forces"), literally

def identify_forces(rotor_params, w, spin, gain, qb, e, cond_max=1e14):
    """Bearing-force identification. qb (..., R, n, 4) bearing responses, e (..., R, 4) excitation
    vectors (scaled by gain (n,) at each point), w, spin (..., n) or (n,) rad/s.

    Rotor equations: (K + jwC) q = gain e + w^2 M q - j w spin G q = r; the bearing forces from
    r = [f1x + f2x, f1y + f2y, -l1 f1x + l2 f2x, l1 f1y - l2 f2y]; per bearing b and direction i
    the least-squares fit over the runs of [x_b y_b] [Z_ix Z_iy]^T = f_bi (pseudo-inverse).
    Returns k, c (..., n, 8) [bearing][i][j]; NaN where cond([x_b y_b]) > cond_max."""
    m, it, ip, l1, l2 = (float(v) for v in rotor_params)
    M, G, _, _ = matrices(m, it, ip, l1, l2, np.zeros((2, 2, 2)), np.zeros((2, 2, 2)))
    qb = np.asarray(qb, complex)
    n = qb.shape[-2]
    w = np.broadcast_to(np.asarray(w, float), qb.shape[:-3] + (n,))[..., None, :, None]
    spin = np.broadcast_to(np.asarray(spin, float), qb.shape[:-3] + (n,))[..., None, :, None]
    gain = np.broadcast_to(np.asarray(gain, float), qb.shape[:-3] + (n,))[..., None, :, None]
    e = np.asarray(e, complex)[..., :, None, :]
    r = gain * e + w ** 2 * (qb @ M.T) - 1j * w * spin * (qb @ G.T)     # (..., R, n, 4)
    # bearing forces: solve [[1, 1], [-l1, l2]] [f1x, f2x] = [r1, r3], [[1, 1], [l1, -l2]] [f1y, f2y] = [r2, r4]
    Ax = np.linalg.inv(np.array([[1.0, 1.0], [-l1, l2]]))
    Ay = np.linalg.inv(np.array([[1.0, 1.0], [l1, -l2]]))
    f = np.empty(r.shape[:-1] + (2, 2), complex)                         # (..., R, n, bearing, direction)
    f[..., 0, 0] = Ax[0, 0] * r[..., 0] + Ax[0, 1] * r[..., 2]
    f[..., 1, 0] = Ax[1, 0] * r[..., 0] + Ax[1, 1] * r[..., 2]
    f[..., 0, 1] = Ay[0, 0] * r[..., 1] + Ay[0, 1] * r[..., 3]
    f[..., 1, 1] = Ay[1, 0] * r[..., 1] + Ay[1, 1] * r[..., 3]
    out_k = np.empty(qb.shape[:-3] + (n, 8))
    out_c = np.empty_like(out_k)
    wn = w[..., 0, :, 0]
    for b in range(2):
        A = np.stack([qb[..., b], qb[..., 2 + b]], axis=-1)             # (..., R, n, 2)
        A = np.moveaxis(A, -3, -2)                                       # (..., n, R, 2)
        cond = np.linalg.cond(A)
        Ap = np.linalg.pinv(A)                                           # (..., n, 2, R)
        for i in range(2):
            fb = np.moveaxis(f[..., b, i], -2, -1)                       # (..., n, R)
            Z = (Ap @ fb[..., None])[..., 0]                             # (..., n, 2): Z_ix, Z_iy
            Z = np.where((cond <= cond_max)[..., None], Z, complex(np.nan, np.nan))
            for j in range(2):
                out_k[..., 4 * b + 2 * i + j] = Z[..., j].real
                out_c[..., 4 * b + 2 * i + j] = Z[..., j].imag / wn
    return out_k, out_c


def sync_errors(rotor_params, kb, cb, speed_rad, u, planes_z, probes_z, errors, seed, trials):
    """The whole synchronous study of the spec: errors (T, n, 16) in report order."""
    q, told = sync_measured(rotor_params, kb, cb, speed_rad, u, planes_z, probes_z, errors, seed, trials)
    qb = probes_to_bearings(q, rotor_params, probes_z)
    e = imbalance_force(u, planes_z)                                     # nominal
    kh, ch = identify_forces(rotor_params, told, told, told ** 2, qb, e)
    return relative_errors(kh, ch, kb, cb)


def impact_errors(rotor_params, kb, cb, spin_rad, w_rad, tests, probes_z, errors, seed, trials):
    """The whole impact study: errors (T, n, 16) in report order (identification at s = jw, gain 1)."""
    Hm = impact_measured(rotor_params, kb, cb, spin_rad, w_rad, tests, probes_z, errors, seed, trials)
    qb = probes_to_bearings(Hm, rotor_params, probes_z)
    e = np.array([impact_force(z, d) for z, d in tests])
    w = np.asarray(w_rad, float)
    kh, ch = identify_forces(rotor_params, w, np.full(w.size, float(spin_rad)), np.ones(w.size), qb, e)
    return relative_errors(kh, ch, kb, cb)


# ---------------------------------------------------------------------------------------------
# statistics

def reference_values(kb, cb):
    """ref (n, 16) in report order: |p|, or where p = 0 the mean |direct| of the same kind and
    bearing (direct = xx and yy: flat indices 4b and 4b + 3)."""
    refs = []
    for p in (np.asarray(kb, float), np.asarray(cb, float)):
        p = np.atleast_2d(p)
        ref = np.abs(p).copy()
        for b in range(2):
            direct = 0.5 * (np.abs(p[:, 4 * b]) + np.abs(p[:, 4 * b + 3]))
            for j in range(4 * b, 4 * b + 4):
                ref[:, j] = np.where(p[:, j] == 0, direct, ref[:, j])
        refs.append(ref[:, REPORT_TO_BIJ])
    return np.concatenate(refs, axis=-1)


def relative_errors(p_hat_k, p_hat_c, kb, cb):
    """(p_hat - p) / ref in report order: p_hat_k, p_hat_c (..., n, 8) [bearing][i][j], kb, cb (n, 8)."""
    p_hat = np.concatenate([np.asarray(p_hat_k)[..., REPORT_TO_BIJ], np.asarray(p_hat_c)[..., REPORT_TO_BIJ]], -1)
    p = np.concatenate([np.atleast_2d(kb)[:, REPORT_TO_BIJ], np.atleast_2d(cb)[:, REPORT_TO_BIJ]], -1)
    return (p_hat - p) / reference_values(kb, cb)


def _magnitude_bins(x):
    """Magnitude index of x = |e| / E0: floor(16 x) below 1, else 16 + 16 E + t with x = 2^E (1 + t/16 + ...)."""
    m, e = np.frexp(x)              # x = m 2^e, m in [0.5, 1): octave E = e - 1, x / 2^E = 2m in [1, 2)
    top = np.floor((2 * m - 1) * HIST_SUB)
    log = HIST_SUB + HIST_SUB * (e - 1) + top
    lin = np.floor(np.minimum(x, 1.0) * HIST_SUB)
    return np.minimum(np.where(x < 1, lin, log), HIST_BINS // 2 - 1).astype(np.int64)


def hist_bin(errors):
    """Bin of finite errors (docs/studies.md): 512 + magnitude index for e >= 0, 511 - it below."""
    e = np.asarray(errors, float)
    mag = _magnitude_bins(np.abs(e) / HIST_E0)
    return np.where(e < 0, HIST_BINS // 2 - 1 - mag, HIST_BINS // 2 + mag)


def hist_edges():
    """Edges (1025,) of the bins, -inf and +inf at the ends."""
    mags = np.arange(HIST_BINS // 2 + 1, dtype=float)
    lo = np.where(mags < HIST_SUB, mags / HIST_SUB, 2.0 ** ((mags - HIST_SUB) // HIST_SUB)
                  * (1 + ((mags - HIST_SUB) % HIST_SUB) / HIST_SUB)) * HIST_E0
    pos = lo[:-1]  # lower edges of the magnitude bins 0..511 (pos[0] = 0)
    return np.concatenate([[-np.inf], -pos[:0:-1], [0.0], pos[1:], [np.inf]])


def histogram(errors):
    """Streaming statistics of errors (T, n, 16) over the trials: a dict with
    counts (n, 16, 1024) int64, finite (n, 16), nonfinite (n, 16), sum (n, 16), sumsq (n, 16)."""
    e = np.asarray(errors, float)
    _, n, k = e.shape
    ok = np.isfinite(e)
    counts = np.zeros((n, k, HIST_BINS), np.int64)
    idx = hist_bin(np.where(ok, e, 0.0))
    _, p, j = np.nonzero(ok)                                   # every finite error, once
    np.add.at(counts, (p, j, idx[ok]), 1)
    ez = np.where(ok, e, 0.0)
    return {"counts": counts, "finite": ok.sum(0), "nonfinite": (~ok).sum(0),
            "sum": ez.sum(0), "sumsq": (ez * ez).sum(0)}


def percentiles_from_histogram(counts, q):
    """Percentiles q (in percent, sequence) from histogram counts (..., 1024): shape (len(q), ...).

    Rank target = q/100 * N (N = total count); the first bin b whose cumulative count reaches the
    target (and that holds values); linear inside it; the open end bins give their finite edge.
    NaN where the histogram is empty."""
    counts = np.asarray(counts)
    edges = hist_edges()
    lo, hi = edges[:-1].copy(), edges[1:].copy()
    lo[0], hi[-1] = hi[0], lo[-1]
    q = np.atleast_1d(np.asarray(q, float))
    flat = counts.reshape(-1, counts.shape[-1])
    out = np.full((q.size, flat.shape[0]), np.nan)
    for s in range(flat.shape[0]):
        c = flat[s]
        N = c.sum()
        if N == 0:
            continue
        cum = np.cumsum(c)
        for i, qq in enumerate(q):
            target = qq / 100.0 * N
            b = int(np.argmax((cum >= target) & (c > 0)))
            below = cum[b] - c[b]
            out[i, s] = lo[b] + min(max((target - below) / c[b], 0.0), 1.0) * (hi[b] - lo[b])
    return out.reshape((q.size,) + counts.shape[:-1])


def summary(errors, q=(5.0, 50.0, 95.0)):
    """Percentiles (len(q), n, 16), mean and rms (n, 16) of errors (T, n, 16) via the histogram."""
    h = histogram(errors)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = h["sum"] / h["finite"]
        rms = np.sqrt(h["sumsq"] / h["finite"])
    return percentiles_from_histogram(h["counts"], q), mean, rms, h
