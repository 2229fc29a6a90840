"""Interoperability with ROSS (``ross-rotordynamics``, import name ``ross``), a finite-element
rotordynamics library.

* :func:`to_ross`: identified bearing coefficients -> two ROSS ``BearingElement`` (or, with
  ``stochastic=True``, two ``ross.stochastic.ST_BearingElement`` sampled from the standard errors).
* :func:`rigid_rotor_from_ross`: a ROSS ``Rotor`` -> :class:`rotorid.RigidRotor` (mass, inertias,
  bearing, probe and imbalance-plane positions from the CG).
* :func:`imbalance_to_ross` / :func:`imbalance_from_ross`: :class:`rotorid.Imbalance` <-> ROSS
  ``unbalance_magnitude`` (kg·m) and ``unbalance_phase`` (rad) at nodes.
* :func:`sync_response_from_ross`: a ROSS unbalance response -> :class:`rotorid.SyncResponse`.

Conventions (checked by simulation in tests/test_ross.py, see docs/ross.md): ROSS and rotorid use
the same axes (x horizontal, y vertical, rotation from x toward y, ROSS's z axis from bearing 1 to
bearing 2) and the same complex amplitudes x(t) = Re(X e^{jΩt}); rotorid's imbalance angle
``angle_deg`` = φ is measured opposite to the rotation, ROSS's ``unbalance_phase`` along it, so
``unbalance_phase = -φ`` (in rad). ROSS speaks rad/s everywhere, rotorid rpm and Hz at its API.

ROSS is an optional dependency (``pip install 'rotorid[ross]'``): it is imported inside the
functions, never by ``import rotorid``.
"""

from __future__ import annotations

import warnings

import numpy as np

from .errors import RotoridError

#: the message of the error raised when ROSS cannot be imported
ROSS_MISSING = "ROSS is not installed: pip install 'rotorid[ross]'"

_RPM = np.pi / 30.0  # rpm -> rad/s
#: coefficient names as ROSS's BearingElement takes them, with their [i, j] index (x = 0, y = 1)
_ROSS_NAMES = (("kxx", 0, 0), ("kxy", 0, 1), ("kyx", 1, 0), ("kyy", 1, 1))


def _ross():
    """The ``ross`` module, or a RotoridError saying how to install it."""
    try:
        import ross
    except ImportError as exc:
        raise RotoridError(ROSS_MISSING) from exc
    except Exception as exc:  # installed, but its own import fails (e.g. an incompatible plotly)
        raise RotoridError(f"ROSS is installed but cannot be imported ({type(exc).__name__}: "
                           f"{str(exc).splitlines()[0] if str(exc) else ''}); reinstall it with the pins of the "
                           "extra: pip install 'rotorid[ross]'") from exc
    return ross


def _ross_stochastic():
    _ross()
    try:
        import ross.stochastic as srs
    except ImportError as exc:
        raise RotoridError(f"{ROSS_MISSING} (ross.stochastic is missing from the installed ROSS)") from exc
    return srs


# -- checks ---------------------------------------------------------------------------------------
def _node(name, value):
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)) or value < 0:
        raise RotoridError(f"{name} must be a ROSS node number (a whole number >= 0), got {value!r}")
    return int(value)


def _node_pair(name, value, what="bearing"):
    if isinstance(value, (str, bytes)) or not hasattr(value, "__len__") or len(value) != 2:
        raise RotoridError(f"{name} must be a pair of ROSS node numbers ({what} 1, {what} 2), got {value!r}")
    a, b = _node(f"{name}[0]", value[0]), _node(f"{name}[1]", value[1])
    if a == b:
        raise RotoridError(f"{name} gives the same node twice ({a}): the two {what}s must be at different nodes")
    return a, b


def _check_ross_rotor(rotor, name="rotor"):
    ross = _ross()
    if not isinstance(rotor, ross.Rotor):
        raise RotoridError(f"{name} must be a ross.Rotor, got {type(rotor).__name__}")
    return rotor


def _rotor_node(rotor, name, node):
    node = _node(name, node)
    if node not in rotor.nodes:
        raise RotoridError(f"{name} = {node} is not a node of the ROSS rotor (its shaft nodes are "
                           f"{rotor.nodes[0]}..{rotor.nodes[-1]})")
    return node


def _z(rotor, node):
    return float(rotor.nodes_pos[rotor.nodes.index(node)])


def _rotor_dofs(rotor):
    """{(letter, node): global dof index} of the rotor's own nodes (from its shaft elements)."""
    out = {}
    for el in rotor.shaft_elements:
        for key, idx in el.dof_global_index.items():
            letter, n = key.rsplit("_", 1)
            out[(letter, int(n))] = int(idx)
    return out


def _pair(name, value, *, positive=False):
    from ._validate import real_array

    return tuple(map(float, real_array(name, value, shape=(2,), positive=positive)))


def mass_properties(rotor) -> dict:
    """Rigid-body mass properties of a ROSS rotor, from its finite-element mass matrix.

    Parameters
    ----------
    rotor : ross.Rotor
        The rotor. Bearing, seal and support masses (``mxx`` of bearing elements, point masses on
        nodes of their own) are not part of it; point masses on shaft nodes are.

    Returns
    -------
    dict
        ``mass_kg``; ``cg_m``, the CG's axial position in ROSS's frame (``rotor.nodes_pos``);
        ``it_kgm2``, the transverse inertia about the CG (from rigid tilting in the x-z plane);
        ``it_yz_kgm2`` the same from the y-z plane (equal for axisymmetric elements); ``ip_kgm2``,
        the polar inertia from the gyroscopic matrix moved as a rigid body (ROSS's ``rotor.Ip``, shaft
        elements and disks, unless shaft elements are built with ``gyroscopic=False``: as ROSS
        simulates them, like the transverse inertia follows ``rotary_inertia=False``).

    Examples
    --------
    >>> import ross as rs
    >>> from rotorid.ross import mass_properties
    >>> shaft = [rs.ShaftElement(0.2, 0.0, 0.05, material=rs.materials.steel) for _ in range(2)]
    >>> rotor = rs.Rotor(shaft, [rs.DiskElement(n=2, m=10.0, Id=0.02, Ip=0.04)], [])
    >>> p = mass_properties(rotor)
    >>> round(float(p["mass_kg"] - rotor.m), 9), round(float(p["cg_m"] - rotor.CG), 9)
    (0.0, 0.0)
    """
    ross = _ross()
    _check_ross_rotor(rotor)
    if isinstance(rotor, getattr(ross, "MultiRotor", ())):
        raise RotoridError("rotor is a ross.MultiRotor (geared shafts turning at different speeds), not one rigid "
                           "body: use one of its shafts, rotor.rotors['driving'] or rotor.rotors['driven']")
    dofs = _rotor_dofs(rotor)
    M0 = np.asarray(rotor.M0, dtype=float)
    pos = {n: _z(rotor, n) for n in rotor.nodes}

    def rigid(trans, rot, z0=None, sign=1.0):
        """Rigid-body motion: translation of ``trans`` (z0 None), or a unit rotation ``rot`` about
        z0, moving ``trans`` by sign * (z - z0)."""
        v = np.zeros(M0.shape[0])
        for (letter, n), i in dofs.items():
            if letter == trans:
                v[i] = 1.0 if z0 is None else sign * (pos[n] - z0)
            elif letter == rot and z0 is not None:
                v[i] = 1.0
        return v

    # translation x; rotation beta about y (x = z beta); rotation alpha about x (y = -z alpha)
    ux = rigid("x", "beta")
    m = float(ux @ M0 @ ux)
    if not m > 0:
        raise RotoridError(f"the ROSS rotor has no mass (mass matrix gives {m:g} kg)")
    cg = float(ux @ M0 @ rigid("x", "beta", 0.0)) / m
    tx = rigid("x", "beta", cg)
    ty = rigid("y", "alpha", cg, sign=-1.0)
    # the gyroscopic coupling of the two rigid tilts: G0 is skew, ty' G0 tx = Ip (rotor.Ip for the default
    # elements; without the gyroscopic terms of elements built with gyroscopic=False, as ROSS simulates them)
    G0 = np.asarray(rotor.G0, dtype=float)
    return dict(mass_kg=m, cg_m=cg, it_kgm2=float(tx @ M0 @ tx), it_yz_kgm2=float(ty @ M0 @ ty),
                ip_kgm2=float(ty @ G0 @ tx))


# -- rotor ----------------------------------------------------------------------------------------
def rigid_rotor_from_ross(rotor, bearing_nodes, probe_positions=None, *, imbalance_nodes=None,
                          imbalance_radii=(1.0, 1.0)):
    """A :class:`rotorid.RigidRotor` with the rigid-body mass properties of a ROSS rotor.

    Parameters
    ----------
    rotor : ross.Rotor
        The rotor; its flexibility is ignored (rotorid's model is rigid).
    bearing_nodes : (int, int)
        ROSS nodes of bearing 1 and bearing 2. ROSS's axial coordinate must increase from bearing 1
        to bearing 2 (rotorid's axis points from bearing 1 to bearing 2; reversing it would mirror
        the rotation): number the bearings accordingly.
    probe_positions : (float, float), optional
        Axial positions (m) of the probe planes in ROSS's frame (``rotor.nodes_pos``; for a probe
        at node n use ``rotor.nodes_pos[n]``), for probe 1 and probe 2. Default: at the bearings.
    imbalance_nodes : (int, int), optional
        ROSS nodes of imbalance planes 1 and 2 (default: none, d = (0, 0)).
    imbalance_radii : (float, float)
        Radii (m) of the imbalance masses in the two planes (``RigidRotor.r``).

    Returns
    -------
    rotorid.RigidRotor
        mass, transverse inertia about the CG and polar inertia (see :func:`mass_properties`),
        l1, l2, d and s measured from the CG (bearing 1 at -l1, probe 1 at -s1, plane 1 at -d1).

    Examples
    --------
    >>> import ross as rs
    >>> from rotorid.ross import rigid_rotor_from_ross
    >>> shaft = [rs.ShaftElement(0.1, 0.0, 0.05, material=rs.materials.steel) for _ in range(4)]
    >>> disks = [rs.DiskElement(n=1, m=5.0, Id=0.01, Ip=0.02), rs.DiskElement(n=3, m=5.0, Id=0.01, Ip=0.02)]
    >>> bearings = [rs.BearingElement(n=0, kxx=1e6, cxx=500.0), rs.BearingElement(n=4, kxx=1e6, cxx=500.0)]
    >>> rotor = rs.Rotor(shaft, disks, bearings)
    >>> rr = rigid_rotor_from_ross(rotor, (0, 4), imbalance_nodes=(1, 3), imbalance_radii=(0.05, 0.05))
    >>> round(rr.l1, 6), round(rr.l2, 6), round(rr.d1, 6), rr.s == (rr.l1, rr.l2)
    (0.2, 0.2, 0.1, True)
    """
    from .model import RigidRotor

    _check_ross_rotor(rotor)
    n1, n2 = _node_pair("bearing_nodes", bearing_nodes)
    n1 = _rotor_node(rotor, "bearing_nodes[0]", n1)
    n2 = _rotor_node(rotor, "bearing_nodes[1]", n2)
    z1, z2 = _z(rotor, n1), _z(rotor, n2)
    if not z2 > z1:
        raise RotoridError(f"bearing_nodes: bearing 1 (node {n1}, z = {z1:g} m) must come before bearing 2 (node {n2}, "
                           f"z = {z2:g} m) along ROSS's axis: rotorid's axis runs from bearing 1 to bearing 2; "
                           "give the nodes as ({n2}, {n1}) and swap the bearings' names".format(n2=n2, n1=n1))
    p = mass_properties(rotor)
    cg = p["cg_m"]
    zmin, zmax = float(min(rotor.nodes_pos)), float(max(rotor.nodes_pos))
    tol = 1e-9 * (zmax - zmin)
    if probe_positions is None:
        s = (cg - z1, z2 - cg)
    else:
        zp = _pair("probe_positions (axial positions of the probes in ROSS's frame, m)", probe_positions)
        for i, z in enumerate(zp):
            if not zmin - tol <= z <= zmax + tol:
                raise RotoridError(f"probe_positions[{i}] = {z:g} m is off the rotor (ROSS nodes span "
                                   f"{zmin:g}..{zmax:g} m)")
        if abs(zp[1] - zp[0]) <= tol:
            raise RotoridError(f"probe_positions: both probes at z = {zp[0]:g} m: the rotor's tilt cannot be measured "
                               "from one plane; give two different planes")
        if zp[1] < zp[0]:
            raise RotoridError(f"probe_positions: probe 1 (z = {zp[0]:g} m) must come before probe 2 (z = {zp[1]:g} m) "
                               "along ROSS's axis, as bearing 1 comes before bearing 2")
        s = (cg - zp[0], zp[1] - cg)
    if imbalance_nodes is None:
        d = (0.0, 0.0)
    else:
        a, b = _node_pair("imbalance_nodes", imbalance_nodes, "imbalance plane")
        za = _z(rotor, _rotor_node(rotor, "imbalance_nodes[0]", a))
        zb = _z(rotor, _rotor_node(rotor, "imbalance_nodes[1]", b))
        d = (cg - za, zb - cg)
    r = _pair("imbalance_radii (m)", imbalance_radii, positive=True)
    return RigidRotor(mass_kg=p["mass_kg"], it_kgm2=p["it_kgm2"], ip_kgm2=p["ip_kgm2"], l1=cg - z1, l2=z2 - cg,
                      d=d, r=r, s=s)


def _check_rigid(name, value):
    from .model import RigidRotor

    if not isinstance(value, RigidRotor):
        raise RotoridError(f"{name} must be a rotorid.RigidRotor (e.g. from rigid_rotor_from_ross), got "
                           f"{type(value).__name__}")
    return value


def _plane_of(rotor, ross_rotor, z_rel, what, tol):
    """Index (0, 1) of the imbalance plane of ``rotor`` at axial position z_rel from the CG."""
    planes = (-rotor.d1, rotor.d2)
    for i, zp in enumerate(planes):
        if abs(z_rel - zp) <= tol:
            return i
    raise RotoridError(f"{what} is {z_rel:+g} m from the CG, at neither imbalance plane of the rotorid rotor (-d1 = "
                       f"{planes[0]:+g} m, +d2 = {planes[1]:+g} m): the two rotors do not match")


def _node_at(ross_rotor, cg, z_rel, what, tol):
    for n, z in zip(ross_rotor.nodes, ross_rotor.nodes_pos):
        if abs(z - cg - z_rel) <= tol:
            return int(n)
    raise RotoridError(f"no node of the ROSS rotor at {what} ({z_rel:+g} m from the CG, z = {cg + z_rel:g} m); "
                       "add a node there or give nodes=")


def _nodes_at(ross_rotor, cg, planes, nodes, what, tol):
    """The two ROSS nodes at the rotorid rotor's planes ``planes`` (m from the CG): found when
    ``nodes`` is None, else checked to sit there (``what``: "probe", "bearing", "imbalance plane")."""
    if nodes is None:
        return [_node_at(ross_rotor, cg, planes[i], f"{what} {i + 1}", tol) for i in range(2)]
    a, b = _node_pair("nodes", nodes, what)
    nodes = [_rotor_node(ross_rotor, "nodes[0]", a), _rotor_node(ross_rotor, "nodes[1]", b)]
    for i, n in enumerate(nodes):
        zr = _z(ross_rotor, n) - cg
        if abs(zr - planes[i]) > tol:
            raise RotoridError(f"nodes[{i}] = {n} is {zr:+g} m from the CG, but {what} {i + 1} of the rotorid rotor "
                               f"is at {planes[i]:+g} m: the nodes do not match the rotor's {what} positions")
    return nodes


def _tol(ross_rotor):
    return 1e-6 * max(float(max(ross_rotor.nodes_pos) - min(ross_rotor.nodes_pos)), 1e-3)


# -- imbalance ------------------------------------------------------------------------------------
def imbalance_to_ross(imbalance, *, rotor, ross_rotor, nodes=None) -> dict:
    """ROSS unbalance arguments of a :class:`rotorid.Imbalance`.

    The forcing of plane i is m_i r_i exp(-j φ_i) in rotorid (φ = ``angle_deg``, measured opposite
    to the rotation) and ``unbalance_magnitude`` exp(j ``unbalance_phase``) in ROSS (phase along the
    rotation), so magnitude = m_i r_i (kg·m) and phase = -φ_i (rad).

    Parameters
    ----------
    imbalance : rotorid.Imbalance
    rotor : rotorid.RigidRotor
        The rigid rotor (its radii r and planes d), e.g. from :func:`rigid_rotor_from_ross`.
    ross_rotor : ross.Rotor
        The ROSS rotor it came from.
    nodes : (int, int), optional
        ROSS nodes of planes 1 and 2; checked against the planes' positions. Default: the nodes at
        the planes (-d1 and +d2 from the CG).

    Returns
    -------
    dict
        ``node``, ``unbalance_magnitude``, ``unbalance_phase`` (lists of two), to pass on as
        ``ross_rotor.run_unbalance_response(**kw, frequency=speeds_rad_s)``.

    Examples
    --------
    >>> import numpy as np, ross as rs, rotorid
    >>> from rotorid.ross import imbalance_to_ross, rigid_rotor_from_ross
    >>> shaft = [rs.ShaftElement(0.1, 0.0, 0.05, material=rs.materials.steel) for _ in range(4)]
    >>> rotor = rs.Rotor(shaft, [], [])
    >>> rr = rigid_rotor_from_ross(rotor, (0, 4), imbalance_nodes=(1, 3), imbalance_radii=(0.05, 0.05))
    >>> kw = imbalance_to_ross(rotorid.Imbalance((2e-3, 1e-3), (90.0, 0.0)), rotor=rr, ross_rotor=rotor)
    >>> kw["node"], [round(m, 9) for m in kw["unbalance_magnitude"]], np.rad2deg(kw["unbalance_phase"]).tolist()
    ([1, 3], [0.0001, 5e-05], [-90.0, -0.0])
    """
    from .model import Imbalance

    if not isinstance(imbalance, Imbalance):
        raise RotoridError(f"imbalance must be a rotorid.Imbalance, got {type(imbalance).__name__}")
    rotor = _check_rigid("rotor", rotor)
    _check_ross_rotor(ross_rotor, "ross_rotor")
    cg = mass_properties(ross_rotor)["cg_m"]
    tol = _tol(ross_rotor)
    planes = (-rotor.d1, rotor.d2)
    nodes = _nodes_at(ross_rotor, cg, planes, nodes, "imbalance plane", tol)
    f = imbalance.forcing(rotor)  # m r exp(-j phi), kg·m
    return dict(node=[int(n) for n in nodes], unbalance_magnitude=[float(abs(x)) for x in f],
                unbalance_phase=[float(-np.deg2rad(a)) for a in imbalance.angle_deg])


def imbalance_from_ross(node, unbalance_magnitude, unbalance_phase, *, rotor, ross_rotor, name=None):
    """A :class:`rotorid.Imbalance` from ROSS unbalances (kg·m, rad) at nodes.

    Each node must lie in one of the rotor's two imbalance planes; unbalances in the same plane
    add up as vectors. mass = magnitude / r of its plane, ``angle_deg`` = -phase (in degrees; see
    :func:`imbalance_to_ross`). A negative magnitude counts as a positive one turned by 180°.

    Parameters
    ----------
    node, unbalance_magnitude, unbalance_phase : int or sequence
        As given to ROSS's ``run_unbalance_response`` (phase in rad).
    rotor : rotorid.RigidRotor
        The rigid rotor (planes d and radii r), e.g. from :func:`rigid_rotor_from_ross`.
    ross_rotor : ross.Rotor
        The ROSS rotor the nodes belong to.
    name : str, optional
        Name of the imbalance set.

    Returns
    -------
    rotorid.Imbalance

    Examples
    --------
    >>> import ross as rs
    >>> from rotorid.ross import imbalance_from_ross, rigid_rotor_from_ross
    >>> shaft = [rs.ShaftElement(0.1, 0.0, 0.05, material=rs.materials.steel) for _ in range(4)]
    >>> rotor = rs.Rotor(shaft, [], [])
    >>> rr = rigid_rotor_from_ross(rotor, (0, 4), imbalance_nodes=(1, 3), imbalance_radii=(0.05, 0.05))
    >>> imb = imbalance_from_ross([1], [1e-4], [-1.5707963267948966], rotor=rr, ross_rotor=rotor)
    >>> [round(m, 9) for m in imb.mass_kg], [round(a, 9) for a in imb.angle_deg]
    ([0.002, 0.0], [90.0, 0.0])
    """
    from .model import Imbalance

    rotor = _check_rigid("rotor", rotor)
    _check_ross_rotor(ross_rotor, "ross_rotor")
    nodes = np.atleast_1d(np.asarray(node, dtype=object))
    from ._validate import real_array

    mags = np.atleast_1d(real_array("unbalance_magnitude (kg·m)", unbalance_magnitude, finite=False))
    phases = np.atleast_1d(real_array("unbalance_phase (rad)", unbalance_phase, finite=False))
    if nodes.ndim != 1 or not (nodes.size == mags.size == phases.size) or nodes.size == 0:
        raise RotoridError(f"node, unbalance_magnitude and unbalance_phase must have the same length (one unbalance "
                           f"per node), got {nodes.size}, {mags.size} and {phases.size}")
    if not (np.isfinite(mags).all() and np.isfinite(phases).all()):
        raise RotoridError("unbalance_magnitude and unbalance_phase must be finite numbers (kg·m, rad)")
    cg = mass_properties(ross_rotor)["cg_m"]
    tol = _tol(ross_rotor)
    b = np.zeros(2, dtype=complex)  # ROSS's complex unbalance per plane, magnitude exp(j phase)
    for i, (n, mg, ph) in enumerate(zip(nodes, mags, phases)):
        n = _rotor_node(ross_rotor, f"node[{i}]", n)
        b[_plane_of(rotor, ross_rotor, _z(ross_rotor, n) - cg, f"node {n}", tol)] += mg * np.exp(1j * ph)
    mass = np.abs(b) / np.asarray(rotor.r)
    angle = np.where(np.abs(b) > 0, -np.angle(b, deg=True), 0.0)
    return Imbalance(tuple(mass), tuple(angle + 0.0), name=name)


# -- responses ------------------------------------------------------------------------------------
def sync_response_from_ross(response, *, rotor, at="probes", nodes=None, imbalance=None, name=None):
    """A :class:`rotorid.SyncResponse` from a ROSS unbalance (forced) response.

    Parameters
    ----------
    response : ross.ForcedResponseResults
        From ``ross_rotor.run_unbalance_response(..., frequency=speeds_rad_s)``; all speeds > 0.
    rotor : rotorid.RigidRotor
        The rigid rotor, from :func:`rigid_rotor_from_ross` of the same ROSS rotor.
    at : {"probes", "bearings"}
        Read the responses at the rotor's probe planes (-s1, +s2) or its bearings (-l1, +l2).
    nodes : (int, int), optional
        ROSS nodes to read, checked against those planes. Default: the nodes at the planes.
    imbalance : rotorid.Imbalance, optional
        Default: from the response's own unbalance (:func:`imbalance_from_ross`).
    name : str, optional

    Returns
    -------
    rotorid.SyncResponse
        q = [x1, x2, y1, y2] at the two planes, over ``speed_rpm`` = ROSS's speeds × 30/π.

    Examples
    --------
    >>> import numpy as np, ross as rs
    >>> from rotorid.ross import rigid_rotor_from_ross, sync_response_from_ross
    >>> shaft = [rs.ShaftElement(0.1, 0.0, 0.05, material=rs.materials.steel) for _ in range(4)]
    >>> bearings = [rs.BearingElement(n=0, kxx=1e6, cxx=500.0), rs.BearingElement(n=4, kxx=1e6, cxx=500.0)]
    >>> rotor = rs.Rotor(shaft, [], bearings)
    >>> rr = rigid_rotor_from_ross(rotor, (0, 4), imbalance_nodes=(1, 3), imbalance_radii=(0.05, 0.05))
    >>> resp = rotor.run_unbalance_response(node=[1], unbalance_magnitude=[1e-4], unbalance_phase=[0.0],
    ...                                     frequency=np.array([100.0, 200.0]))
    >>> run = sync_response_from_ross(resp, rotor=rr, at="bearings")
    >>> run.q.shape, run.imbalance.mass_kg
    ((2, 4), (0.002, 0.0))
    """
    from ._validate import choice
    from .model import Imbalance
    from .simulate import SyncResponse

    rotor = _check_rigid("rotor", rotor)
    choice("at", at, {"probes", "bearings"})
    ross_rotor = getattr(response, "rotor", None)
    fr = getattr(response, "forced_resp", None)
    if fr is None or ross_rotor is None:
        raise RotoridError(f"response must be a ROSS forced response (ForcedResponseResults from "
                           f"run_unbalance_response), got {type(response).__name__}")
    _check_ross_rotor(ross_rotor, "response.rotor")
    w = np.asarray(response.speed_range, dtype=float)
    if w.ndim != 1 or not np.all(w > 0):
        raise RotoridError("the ROSS response's speeds must all be > 0 rad/s (rotorid has no synchronous response at "
                           "zero speed): leave 0 out of frequency=")
    cg = mass_properties(ross_rotor)["cg_m"]
    tol = _tol(ross_rotor)
    planes = (-rotor.s1, rotor.s2) if at == "probes" else (-rotor.l1, rotor.l2)
    what = "probe" if at == "probes" else "bearing"
    nodes = _nodes_at(ross_rotor, cg, planes, nodes, what, tol)
    dofs = _rotor_dofs(ross_rotor)
    idx = [dofs[("x", nodes[0])], dofs[("x", nodes[1])], dofs[("y", nodes[0])], dofs[("y", nodes[1])]]
    q = np.asarray(fr)[idx].T
    if imbalance is None and getattr(response, "unbalance", None) is not None:
        ub = np.asarray(response.unbalance, dtype=float)
        imbalance = imbalance_from_ross([int(n) for n in ub[0]], ub[1], ub[2], rotor=rotor, ross_rotor=ross_rotor,
                                        name=name)
    elif imbalance is not None and not isinstance(imbalance, Imbalance):
        raise RotoridError(f"imbalance must be a rotorid.Imbalance, got {type(imbalance).__name__}")
    return SyncResponse(w / _RPM, q, imbalance=imbalance, at=at, name=name)


# -- bearings -------------------------------------------------------------------------------------
def _select(ident, drop_flagged):
    """Indices of the points to export (sorted along the axis), warning about dropped ones."""
    n = ident.axis.size
    if n == 0:
        raise RotoridError("the identification has no points: nothing to export to ROSS")
    finite = np.isfinite(ident.k.reshape(n, -1)).all(1) & np.isfinite(ident.c.reshape(n, -1)).all(1)
    keep = finite & (np.asarray(ident.ok, dtype=bool) if drop_flagged else True)
    dropped = np.nonzero(~keep)[0]
    if dropped.size:
        reasons = {}
        for i in dropped:
            why = str(ident.flag[i]) or ("not finite" if not finite[i] else "flagged")
            reasons[why] = reasons.get(why, 0) + 1
        detail = ", ".join(f"{why}: {cnt}" for why, cnt in sorted(reasons.items()))
        if keep.any():
            warnings.warn(f"to_ross: dropped {dropped.size} of {n} points ({detail}); "
                          "pass drop_flagged=False to keep the flagged (finite) ones", stacklevel=3)
    if not keep.any():
        raise RotoridError(f"no point of the identification is left to export to ROSS: all {n} are flagged or not "
                           f"finite ({detail}); ROSS needs at least one point (drop_flagged=False keeps the flagged "
                           "finite ones)")
    sel = np.nonzero(keep)[0]
    sel = sel[np.argsort(ident.axis[sel], kind="stable")]
    ax = ident.axis[sel]
    if np.any(np.diff(ax) <= 0):
        raise RotoridError(f"the identification repeats {ident.axis_name} values: ROSS needs strictly increasing "
                           "frequencies")
    return sel


def _samples(ident, sel, n_samples, seed, common=False):
    """(points, samples, 2, 2, 2) normal samples of k and c with the identified uncertainty: the
    full 16 x 16 covariance of each point where the identification carries it, else independent
    coefficients with the standard errors. Independent between points, or with ``common`` drawn
    from the same standard normals at every point (so that a sample interpolated between two
    points has the interpolated standard error, not one shrunk by averaging two independent draws)."""
    from ._validate import index
    from ._validate import seed as check_seed
    from .model import _REPORT_TO_BIJ

    n_samples = index("n_samples", n_samples, lo=2)
    rng = np.random.default_rng(None if seed is None else check_seed("seed", seed))
    ks, cs = ident.k_std[sel], ident.c_std[sel]
    bad = ~(np.isfinite(ks).reshape(sel.size, -1).all(1) & np.isfinite(cs).reshape(sel.size, -1).all(1))
    if bad.any():
        raise RotoridError(f"stochastic=True needs standard errors, unknown at {int(bad.sum())} of the {sel.size} points "
                           f"exported (std_source {ident.std_source!r}): identify from redundant runs or give the "
                           "runs a measurement covariance (SyncResponse.cov)")
    k = np.empty((sel.size, n_samples, 2, 2, 2))
    c = np.empty_like(k)
    cov = ident.cov
    z0 = rng.standard_normal((n_samples, 16)) if common else None
    for j, i in enumerate(sel):
        z = z0 if common else rng.standard_normal((n_samples, 16))
        if cov is not None and np.isfinite(cov[i]).all():
            mean = np.concatenate([ident.k[i].reshape(8)[_REPORT_TO_BIJ], ident.c[i].reshape(8)[_REPORT_TO_BIJ]])
            lam, vec = np.linalg.eigh(cov[i])
            s = mean + z @ (vec * np.sqrt(np.clip(lam, 0.0, None))).T
            kk = np.empty((n_samples, 8))
            cc = np.empty((n_samples, 8))
            kk[:, _REPORT_TO_BIJ] = s[:, :8]
            cc[:, _REPORT_TO_BIJ] = s[:, 8:]
            k[j], c[j] = kk.reshape(-1, 2, 2, 2), cc.reshape(-1, 2, 2, 2)
        else:
            k[j] = ident.k[i] + ks[j] * z[:, :8].reshape(-1, 2, 2, 2)
            c[j] = ident.c[i] + cs[j] * z[:, 8:].reshape(-1, 2, 2, 2)
    return k, c


def _interp_at(x, axis, values):
    """Linear interpolation of values (points, ...) at x on axis (points,)."""
    if axis.size == 1:
        return values[0]
    j = int(np.clip(np.searchsorted(axis, x), 1, axis.size - 1))
    t = (x - axis[j - 1]) / (axis[j] - axis[j - 1])
    return (1 - t) * values[j - 1] + t * values[j]


def to_ross(ident, *, nodes, drop_flagged=True, impact_as="synchronous", speed_rpm=None, stochastic=False,
            n_samples=100, seed=None, tags=None, rotor=None, **element_kwargs):
    """Two ROSS bearing elements from a :class:`rotorid.Identification`.

    ROSS's ``BearingElement`` tabulates its coefficients over ``frequency`` (rad/s) and evaluates
    them at the rotor's running speed (``Rotor.transfer_matrix`` takes K(speed), C(speed) whatever
    the excitation frequency): ROSS's frequency is the running speed.

    * Synchronous identification (over ``speed_rpm``): the table over frequency = speed × π/30.
      Exactly what ROSS uses in an unbalance response.
    * Impact identification (over excitation ``freq_hz`` at one running speed): with
      ``impact_as="synchronous"`` (default) each bearing gets constant coefficients, those at the
      excitation frequency equal to the running speed ``speed_rpm`` of the tests (linearly
      interpolated between the identified frequencies): right for anything ROSS computes at that
      speed for a synchronous (1X) excitation, e.g. the unbalance response, and an approximation
      for the free whirl (ROSS has no coefficients that depend on the whirl frequency).
      ``impact_as="table"`` puts the table over 2π·freq_hz onto ROSS's axis instead, i.e. it
      treats K(ω) as K(speed = ω): right for supports whose coefficients depend on the vibration
      frequency but not on the running speed.

    With one point the elements are constant; with 2-3 ROSS interpolates linearly or
    quadratically, with 4 or more by a cubic smoothing spline, and extrapolates outside the table
    (rotorid refuses to): keep the analyses inside the exported range.

    Parameters
    ----------
    ident : rotorid.Identification
    nodes : (int, int)
        ROSS nodes of bearing 1 and bearing 2.
    drop_flagged : bool
        Leave out the points not flagged ok (warning how many, and why). Points whose
        coefficients are not finite are always left out. Raises when none is left.
    impact_as : {"synchronous", "table"}
        How to map an impact identification (see above); ignored for synchronous ones.
    speed_rpm : float
        Running speed of the impact tests (the Identification does not record it); needed with
        ``impact_as="synchronous"``.
    stochastic : bool
        Return ``ross.stochastic.ST_BearingElement``s of ``n_samples`` normal samples of the
        coefficients: with the 16 x 16 covariance of each point where the identification carries
        one (measurement covariance), else independent with the standard errors (residual
        based). Samples are independent between points; an impact identification exported at
        ``speed_rpm`` between two identified frequencies interpolates the samples of the two
        with the same normal draws, i.e. the standard errors linearly as well.
    n_samples : int
    seed : int, optional
        Random seed of the samples.
    tags : (str, str), optional
        ROSS tags of the two elements (default: ROSS names them).
    rotor : ross.Rotor, optional
        When given, ``nodes`` are checked against its nodes.
    **element_kwargs
        Passed on to both elements (e.g. ``n_link``, ``scale_factor``).

    Returns
    -------
    tuple
        (bearing 1, bearing 2): ``ross.BearingElement`` or ``ross.stochastic.ST_BearingElement``.

    Examples
    --------
    >>> import numpy as np, ross as rs, rotorid
    >>> from rotorid.ross import to_ross
    >>> rig = rotorid.nsf_rig()
    >>> rpm = np.array([3000.0, 3500.0, 4000.0])
    >>> runs = [rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances[s], speed_rpm=rpm) for s in "AB"]
    >>> ident = rotorid.identify_synchronous(rig.rotor, runs)
    >>> b1, b2 = to_ross(ident, nodes=(1, 5))
    >>> round(float(b1.K(3500.0 * np.pi / 30)[0, 0]) / 1e6, 3)
    3.0
    """
    from ._validate import choice
    from .identify import Identification

    ross = _ross()
    if not isinstance(ident, Identification):
        raise RotoridError(f"ident must be a rotorid.Identification, got {type(ident).__name__}")
    n1, n2 = _node_pair("nodes", nodes)
    if rotor is not None:
        _check_ross_rotor(rotor)
        n1 = _rotor_node(rotor, "nodes[0]", n1)
        n2 = _rotor_node(rotor, "nodes[1]", n2)
    if not isinstance(drop_flagged, (bool, np.bool_)) or not isinstance(stochastic, (bool, np.bool_)):
        raise RotoridError("drop_flagged and stochastic must be True or False")
    choice("impact_as", impact_as, {"synchronous", "table"})
    if tags is not None and (isinstance(tags, (str, bytes)) or not hasattr(tags, "__len__") or len(tags) != 2):
        raise RotoridError(f"tags must be a pair of names (bearing 1, bearing 2), got {tags!r}")
    _check_element_kwargs(_ross_stochastic().ST_BearingElement if stochastic else ross.BearingElement,
                          element_kwargs)
    sel = _select(ident, bool(drop_flagged))
    axis = ident.axis[sel]
    at_speed = None
    if ident.axis_name == "speed_rpm":
        if speed_rpm is not None:
            raise RotoridError("speed_rpm= is for impact identifications (over freq_hz); this one is over speed_rpm "
                               "and carries its speeds")
        w = axis * _RPM
    else:
        w = 2 * np.pi * axis
        if impact_as == "synchronous":
            if speed_rpm is None:
                raise RotoridError("an impact identification is over the excitation frequency at one running speed: give "
                                   "speed_rpm= (the tests' running speed) to export the coefficients at 1X, or "
                                   "impact_as='table' to use the frequency table as ROSS's speed axis")
            from ._validate import number

            at_speed = number("speed_rpm", speed_rpm, positive=True) / 60.0  # Hz
            lo, hi = axis[0], axis[-1]
            if not (lo * (1 - 1e-9) <= at_speed <= hi * (1 + 1e-9)):
                raise RotoridError(f"speed_rpm = {speed_rpm:g} ({at_speed:g} Hz) is outside the identified (and kept) "
                                   f"frequencies {lo:g}..{hi:g} Hz: the 1X coefficients cannot be interpolated")
    if stochastic:
        # (points, samples, 2, 2, 2); one set of normals for all points when interpolated at 1X below
        k, c = _samples(ident, sel, n_samples, seed, common=at_speed is not None)
    else:
        k, c = ident.k[sel], ident.c[sel]              # (points, 2, 2, 2)
    if at_speed is not None:
        k, c = _interp_at(at_speed, axis, k)[None], _interp_at(at_speed, axis, c)[None]
        w = None
    elif w.size == 1:
        w = None
    out = []
    for b, n in enumerate((n1, n2)):
        kw = dict(element_kwargs)
        if tags is not None:
            kw["tag"] = tags[b]
        for letter, arr in (("k", k), ("c", c)):
            for nm, i, j in _ROSS_NAMES:
                v = arr[..., b, i, j]          # (points,) or (points, samples)
                if w is None:
                    kw[letter + nm[1:]] = v[0].copy() if stochastic else float(v[0])
                else:
                    kw[letter + nm[1:]] = v.copy()
        if w is not None:
            kw["frequency"] = w
        if stochastic:
            srs = _ross_stochastic()
            out.append(srs.ST_BearingElement(n=n, is_random=[f"{a}{nm[1:]}" for a in "kc" for nm, _, _ in _ROSS_NAMES],
                                             **kw))
        else:
            el = ross.BearingElement(n=n, **kw)
            if w is not None:
                _check_table(el, w, k[:, b], c[:, b], b)
            out.append(el)
    return tuple(out)


def _check_element_kwargs(cls, kwargs):
    """Refuse extra keywords that to_ross sets itself or that the ROSS element does not take
    (ROSS's BearingElement swallows unknown keywords silently)."""
    import inspect

    own = {"n", "frequency", "tag", "is_random"} | {a + nm[1:] for a in "kc" for nm, _, _ in _ROSS_NAMES}
    clash = sorted(set(kwargs) & own)
    if clash:
        raise RotoridError(f"to_ross sets {', '.join(clash)} itself (from the identification, nodes= and tags=): "
                           "leave them out of the extra keywords")
    params = inspect.signature(cls.__init__).parameters.values()
    allowed = {p.name for p in params if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)} - own - {"self"}
    unknown = sorted(set(kwargs) - allowed)
    if unknown:
        raise RotoridError(f"unknown keyword(s) {', '.join(unknown)} for ROSS's {cls.__name__}: to_ross passes on "
                           f"only {', '.join(sorted(allowed))}")
    if kwargs.get("n_link") is not None:
        _node("n_link", kwargs["n_link"])


def _check_table(el, w, k, c, b):
    """Warn when ROSS's interpolation of a table (a smoothing spline from 4 points on, with an
    absolute tolerance of about 1 N/m or N·s/m per point) misses the exported values by more
    than 0.1 % of the bearing's largest direct coefficient."""
    got_k = np.array([el.K(x)[:2, :2] for x in w])
    got_c = np.array([el.C(x)[:2, :2] for x in w])
    for what, got, want in (("stiffness", got_k, k), ("damping", got_c, c)):
        scale = np.abs(want[:, [0, 1], [0, 1]]).max()
        dev = np.abs(got - want).max()
        if dev > 1e-3 * scale:
            warnings.warn(f"to_ross: ROSS's interpolation of bearing {b + 1}'s {what} table misses the identified values "
                          f"by up to {dev:.3g} ({dev / scale:.2%} of its largest direct coefficient): ROSS fits a "
                          "smoothing spline with an absolute tolerance; small coefficients (or SI units far from 1) "
                          "suffer most", stacklevel=3)
