"""Hypothesis strategies: random rigid rotors, anisotropic cross-coupled bearings (1 != 2), imbalance sets."""

import numpy as np
from hypothesis import assume
from hypothesis import strategies as st

import rotorid

f = st.floats


@st.composite
def rotors(draw, probes_at_bearings=False):
    m = draw(f(5.0, 500.0))
    rg = draw(f(0.05, 0.4))  # radius of gyration
    it = m * rg ** 2
    ip = it * draw(f(0.05, 1.5))
    l1 = draw(f(0.05, 0.6))
    l2 = draw(f(0.05, 0.6))
    d = (draw(f(0.25, 0.9)) * l1, draw(f(0.25, 0.9)) * l2)  # planes on both sides of the CG
    r = (draw(f(0.03, 0.3)), draw(f(0.03, 0.3)))
    if probes_at_bearings:
        s = (l1, l2)
    else:
        s = (draw(f(0.3, 1.2)) * l1, draw(f(0.3, 1.2)) * l2)
    return rotorid.RigidRotor(mass_kg=m, it_kgm2=it, ip_kgm2=ip, l1=l1, l2=l2, d=d, r=r, s=s)


@st.composite
def bearing_pair(draw, scale=1e6):
    out_k, out_c = [], []
    for _ in range(2):
        kxx = draw(f(0.3, 30.0)) * scale
        kyy = kxx * draw(f(1.15, 3.0)) * draw(st.sampled_from([1.0, 1.0]))
        kxy = kxx * draw(f(0.01, 0.4)) * draw(st.sampled_from([-1, 1]))
        kyx = kxx * draw(f(0.01, 0.4)) * draw(st.sampled_from([-1, 1]))
        zeta = draw(f(0.02, 0.3))
        cxx = zeta * 2 * np.sqrt(kxx * 50.0)
        cyy = cxx * draw(f(0.5, 2.0))
        cxy = cxx * draw(f(-0.3, 0.3))
        cyx = cxx * draw(f(-0.3, 0.3))
        out_k.append([[kxx, kxy], [kyx, kyy]])
        out_c.append([[cxx, cxy], [cyx, cyy]])
    return rotorid.BearingCoefficients(np.array(out_k), np.array(out_c))


@st.composite
def imbalance_sets(draw, n):
    sets = []
    for i in range(n):
        m = (draw(f(1e-3, 20e-3)), draw(f(1e-3, 20e-3)))
        a = (draw(f(-180.0, 180.0)), draw(f(-180.0, 180.0)))
        sets.append(rotorid.Imbalance(m, a, name=f"set{i}"))
    if n >= 2:  # keep the sets clearly independent (the dependent case has its own tests)
        U = np.array([np.asarray(s.mass_kg) * np.exp(-1j * np.deg2rad(s.angle_deg)) for s in sets])
        sv = np.linalg.svd(U, compute_uv=False)
        assume(sv[-1] > 0.05 * sv[0])
    return sets


# ---------------------------------------------------------------------------------------------
# bad arguments for the fuzz runs over the public API (tests/test_fuzz.py)

#: values that are wrong for most arguments: non-finite, signed zero, sub-normal, huge (every size
#: they set must be refused, never allocated), strings, None, booleans, complex numbers, sequences
#: and arrays where scalars belong, mappings, bytes, an arbitrary object. Ordinary numbers stay
#: small (|x| <= 20), so that a size they give is legal and cheap rather than slow.
bad_values = st.one_of(
    st.sampled_from([np.nan, np.inf, -np.inf, -1.0, 0.0, -0.0, 5e-324, 1e-300, 1e12, 1e300, 2.0 ** 40, 10 ** 30,
                     -(10 ** 9), 2 ** 63, 1.5]),
    st.floats(-20.0, 20.0), st.integers(-5, 20),
    st.sampled_from(["x", "", "nan", "1e3", None, True, False, b"x", 1 + 1j, [1.0, 2.0], (1.0,), [], {"a": 1},
                     {"x1": 3}, np.zeros(0), np.ones((2, 2)), np.array([np.nan]), np.float64(np.nan), object()]))


def bad_kwargs(names, values=bad_values, max_size=2):
    """One or two of the keyword arguments ``names`` set to bad values."""
    return st.dictionaries(st.sampled_from(list(names)), values, min_size=1, max_size=max_size)
