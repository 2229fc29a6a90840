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
