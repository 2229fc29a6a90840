"""Forward simulation: synchronous imbalance response (report eq. 13-14), probe transforms (eq. 19)
and a measurement-error model for numerical experiments."""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass, field

import numpy as np

from ._corecall import core as _core
from ._validate import choice, complex_array, index, instance, number, real_array, speeds_rpm
from .errors import RotoridError
from .model import BearingCoefficients, Imbalance, RigidRotor

RPM = np.pi / 30.0
DOFS = ("x1", "x2", "y1", "y2")


def bearings_to_probes_matrix(rotor: RigidRotor) -> np.ndarray:
    """2x2 matrix T with [x_p1, x_p2] = T [x_1, x_2] (rigid body; same for y)."""
    return _plane_matrix(rotor, "probes").copy()


def probes_to_bearings_matrix(rotor: RigidRotor) -> np.ndarray:
    """2x2 matrix of report eq. 19: [x_1, x_2] = T [x_p1, x_p2]."""
    return _plane_matrix(rotor, "bearings").copy()


def _plane_matrix(rotor, to: str) -> np.ndarray:
    """The rotor's plane transform to ``"bearings"`` (eq. 19) or ``"probes"``, read-only, from the
    rotor's own copy (``RigidRotor._plane_matrix``: computed once per rotor)."""
    instance("rotor", rotor, RigidRotor, what="rotorid.RigidRotor")
    return rotor._plane_matrix(to)


def _planes_to(rotor, at):
    """The transform a forward model's core call applies to its responses at the bearings to
    report them at ``at``: None at the bearings, the (2, 2) bearings-to-probes matrix at the probes."""
    return _plane_matrix(rotor, "probes") if at == "probes" else None


def _apply_planes(T, q, checked=False):
    """T applied to (x1, x2) and to (y1, y2) of q (..., 4). NaN or inf in q is refused, found by
    the core on its way through (no separate scan); ``checked``: q is the array of a validated
    response, passed through as it is."""
    q = q if isinstance(q, np.ndarray) and q.dtype == complex else complex_array("q", q, finite=False)
    if q.ndim < 1 or q.shape[-1] != 4:
        raise RotoridError(f"q must have the four responses [x1, x2, y1, y2] on its last axis, got shape {q.shape}")
    # one pass in the core: NumPy's complex-by-real matmul on the strided halves took 4 ms per
    # 100,000 points, more than the whole identification of a run
    out, first_bad = _core.apply_planes(np.ascontiguousarray(T, dtype=float), np.ascontiguousarray(q))
    if first_bad is not None and not checked:
        at = tuple(int(i) for i in np.unravel_index(first_bad, q.shape))
        raise RotoridError(f"q contains NaN or inf (first at index {at})")
    return out


def _unchecked(cls, **fields):
    """A response of class ``cls`` from values rotorid computed itself (axis already validated,
    q from the core): the checks of ``__post_init__`` are skipped, the other fields take their
    defaults. Not for user data."""
    obj = cls.__new__(cls)
    obj.__dict__.update(_defaults(cls) | fields)
    return obj


@functools.cache
def _defaults(cls) -> dict:
    """The plain defaults of a dataclass's fields (read once per class)."""
    if any(f.default_factory is not dataclasses.MISSING for f in dataclasses.fields(cls)):
        raise TypeError(f"{cls.__name__}: _unchecked supports plain defaults only")
    return {f.name: f.default for f in dataclasses.fields(cls) if f.default is not dataclasses.MISSING}


def _q_as_checked(resp) -> bool:
    """True when a response's ``q`` (and ``force``, for an impact) are still what its constructor
    checked: complex arrays of (n, 4) (and (n,)) on its own axis, not replaced after construction
    by a list or another shape (those take the validating paths)."""
    q, axis = resp.q, resp.speed_rpm if isinstance(resp, SyncResponse) else resp.freq_hz
    force = getattr(resp, "force", None)
    return isinstance(q, np.ndarray) and q.dtype == complex and isinstance(axis, np.ndarray) and \
        q.shape == (axis.size, 4) and (force is None or isinstance(force, np.ndarray) and force.shape == (axis.size,))


def _cov_transform(T, cov):
    """Covariance (n, 8, 8) of [Re q, Im q] after the plane transform T applied to (x1, x2) and
    (y1, y2) of q: A C Aᵀ in the core (exactly symmetric; a point with a NaN all NaN)."""
    if cov is None:
        return None
    return _core.move_covariances(_plane_matrix8(T), None, np.ascontiguousarray(cov, dtype=float))[0]


def check_cov(name, cov, n, size: int = 8):
    """A measurement covariance (n, size, size), by default (n, 8, 8): real, finite (NaN where
    unknown), symmetric, positive semi-definite (see :func:`check_covs`). Returns a checked copy,
    every entry of an unknown point NaN; None for None."""
    if cov is None:
        return None
    return check_covs([name], [cov], n, size)[0]


def check_covs(names, covs, n, size: int = 8):
    """The covariances ``covs`` (each (n, size, size), named ``names`` in messages), checked in one
    core call (``rotorid_core::covariance``) and stacked into a new (len(covs), n, size, size) array:
    real and finite where known (a point with a NaN is unknown: all of it NaN in the result),
    symmetric to 1e-9 of the largest entry, and positive semi-definite to 1e-9 of each matrix's
    scale (S + 1e-9 ‖S‖_F I has a Cholesky factor, S the symmetric part)."""
    what = "one 8 x 8 covariance of [Re q, Im q] per point" if size == 8 else \
        f"one {size} x {size} covariance of [Re q, Im q, Re p, Im p] per point"
    arrays = []
    for name, cov in zip(names, covs):
        if isinstance(cov, (str, bytes)) or np.iscomplexobj(cov):
            raise RotoridError(f"{name} must be a real array (n, {size}, {size}) of covariances, got {type(cov).__name__}")
        try:
            raw = np.asarray(cov, dtype=float)
        except (TypeError, ValueError):
            raise RotoridError(f"{name} must be a real array (n, {size}, {size}) of covariances") from None
        if raw.shape != (n, size, size):
            raise RotoridError(f"{name} has shape {raw.shape}, expected ({n}, {size}, {size}): {what}")
        arrays.append(np.ascontiguousarray(raw))
    out, fault = _core.check_covariances(arrays, size)
    if fault is not None:
        kind, r, point = fault
        name = names[r]
        if kind == "inf":
            raise RotoridError(f"{name} contains inf (use NaN for a point whose covariance is unknown)")
        if kind == "asymmetric":
            raise RotoridError(f"{name} must be symmetric (a covariance matrix per point)")
        c = arrays[r][point]
        ev = np.linalg.eigvalsh(0.5 * (c + c.T))
        raise RotoridError(f"{name} is not positive semi-definite at point {point} (smallest eigenvalue "
                           f"{ev.min():.3g}): not a covariance")
    return out


def polar_std(x, cov, j):
    """Standard deviations of the amplitude (m) and phase (rad) of channel j's vectors x (n,) from
    the (n, 8, 8) covariance of [Re q, Im q]: along and across each vector."""
    u = x / np.where(np.abs(x) > 0, np.abs(x), 1.0)
    c = np.asarray(cov)
    crr, cii, cri = c[:, j, j], c[:, j + 4, j + 4], c[:, j, j + 4]
    along = crr * u.real ** 2 + cii * u.imag ** 2 + 2 * cri * u.real * u.imag
    across = crr * u.imag ** 2 + cii * u.real ** 2 - 2 * cri * u.real * u.imag
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.sqrt(np.clip(along, 0, None)), np.sqrt(np.clip(across, 0, None)) / np.abs(x)


def check_dof(name, dof, n, *, copy=True):
    """Degrees of freedom (n,) of a covariance: numbers > 0 (inf: known exactly). A checked copy;
    ``copy=False``: the caller's own array when it is already a valid float (n,) one."""
    if dof is None:
        return None
    if isinstance(dof, np.ndarray) and dof.dtype == float and dof.shape == (n,) and \
            _core.first_outside(np.ascontiguousarray(dof), 0.0, np.inf) is None:
        return dof.copy() if copy else dof  # finite and > 0 in one pass (inf and the rest: below)
    if isinstance(dof, (str, bytes)) or np.iscomplexobj(dof):
        raise RotoridError(f"{name} must be numbers > 0, got {dof!r}")
    try:
        d = np.broadcast_to(np.asarray(dof, dtype=float), (n,)).copy()
    except (TypeError, ValueError):
        raise RotoridError(f"{name} must be a number or {n} numbers > 0, got shape {np.shape(dof)}") from None
    if np.any(~(d > 0)):
        raise RotoridError(f"{name} (degrees of freedom of cov) must be > 0")
    return d


def probes_to_bearings(rotor: RigidRotor, q_probes):
    """Report eq. 19 applied to [x_p1, x_p2, y_p1, y_p2] (last axis)."""
    return _apply_planes(_plane_matrix(rotor, "bearings"), q_probes)


def bearings_to_probes(rotor: RigidRotor, q_bearings):
    """Inverse of eq. 19: responses at the probe planes from responses at the bearings."""
    return _apply_planes(_plane_matrix(rotor, "probes"), q_bearings)


def _pedestal_transform(T):
    """Probe readings relative to the pedestals -> relative motion at the bearings:
    q_rel_b = T (q_probe + p) - p = T q_probe + (T - I) p (each probe rides on its pedestal)."""
    return T, T - np.eye(2)


def _polar_columns(data, names, vectors, cov):
    """Amplitude (µm) and phase (deg) columns of 1X vectors (n, 4), with their standard errors
    from the (n, 8, 8) covariance when given, into the dict ``data``."""
    for j, nm in enumerate(names):
        data[f"{nm}_amp_um"] = 1e6 * np.abs(vectors[:, j])
        data[f"{nm}_phase_deg"] = np.rad2deg(np.angle(vectors[:, j]))
        if cov is not None:
            sa, sp = polar_std(vectors[:, j], cov, j)
            data[f"{nm}_amp_std_um"] = 1e6 * sa
            data[f"{nm}_phase_std_deg"] = np.rad2deg(sp)


def pedestal_ratio(p, q) -> np.ndarray:
    """(n,) pedestal motion ``p`` relative to the motion relative to the pedestals ``q`` (both
    (n, 4)): rms over the four coordinates of |p| / |q| (inf or NaN where q is zero)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.sqrt(_sum_sq_rows(p) / _sum_sq_rows(q))


def _sum_sq_rows(a):
    """sum_j |a_ij|^2 of a complex (n, m): one pass over the real view (``np.abs(a) ** 2`` took a
    square root, a square and two temporaries per entry)."""
    a = np.ascontiguousarray(a, dtype=complex)
    v = a.view(float).reshape(a.shape[0], -1)
    return np.einsum("ij,ij->i", v, v)


def _check_pedestal(obj, n, *, finite=True):
    """Validate the pedestal motion fields of a response (q shape (n, 4)); ``finite=False`` leaves
    NaN and inf in the pedestal motion to the caller."""
    if obj.pedestal is None:
        for name in ("pedestal_cov", "pedestal_cross"):
            if getattr(obj, name) is not None:
                raise RotoridError(f"{name} given without pedestal (the pedestal motion it is the covariance of)")
        return
    obj.pedestal = complex_array("pedestal (pedestal motion [xp1, xp2, yp1, yp2])", obj.pedestal, shape=(n, 4),
                                 finite=finite)
    obj.pedestal_cov = check_cov("pedestal_cov", obj.pedestal_cov, n)
    if obj.pedestal_cross is not None:
        if obj.cov is None or obj.pedestal_cov is None:
            raise RotoridError("pedestal_cross (the covariance between q and pedestal) needs both cov and pedestal_cov")
        obj.pedestal_cross = real_array("pedestal_cross", obj.pedestal_cross, shape=(n, 8, 8), finite=False)
        # the three blocks must make one covariance: the joint 16 x 16 matrix is checked too
        check_cov("the joint covariance of q and pedestal (cov, pedestal_cov, pedestal_cross)", joint_cov(obj), n,
                  16)


def _with_pedestal_at(resp, rotor, where, cov=None):
    """(q, cov, pedestal_cross) of a pedestal-carrying response moved to ``where``; the pedestal
    motion itself is measured at the bearings and does not move. ``cov``: the response's
    covariance as checked by the caller (default ``resp.cov``)."""
    A, B = _pedestal_transform(_plane_matrix(rotor, where))
    p = resp.pedestal
    q = resp.q
    if not _q_as_checked(resp):  # replaced after construction: checked here, before the sum below
        n = (resp.speed_rpm if isinstance(resp, SyncResponse) else resp.freq_hz).size
        q = complex_array("q", q, shape=(n, 4))
        p = complex_array("pedestal", p, shape=(n, 4))
    q = _apply_planes(A, q) + _apply_planes(B, p)
    cov = resp.cov if cov is None else cov
    if cov is None or resp.pedestal_cov is None:
        return q, None, None
    # the joint covariance's congruence M Σ Mᵀ block by block in the core (no (n, 16, 16) array)
    cross = resp.pedestal_cross
    cov, cross = _core.move_covariances(_plane_matrix8(A), _plane_matrix8(B), np.ascontiguousarray(cov, dtype=float),
                                        np.ascontiguousarray(resp.pedestal_cov, dtype=float),
                                        None if cross is None else np.ascontiguousarray(cross, dtype=float))
    return q, cov, cross


def _pedestal_moved(resp, rotor, where):
    """The fields (q, at, cov, dof, pedestal, pedestal_cov, pedestal_cross) of a pedestal-carrying
    response moved to ``where``, for an unchecked constructor; None when its q is not as its
    constructor checked it (the caller takes the checked constructor then). The response's own
    fields are checked again (set after construction, they skipped ``__post_init__``); the moved
    covariances of valid ones are valid (M Σ Mᵀ, exactly symmetric), so the moved response is not
    checked again: its three covariance checks and the joint (n, 16, 16) one took half of an
    identification of pedestal runs at the probes."""
    if not _q_as_checked(resp):
        return None
    n = resp.q.shape[0]
    cov = check_cov("cov", resp.cov, n)
    dof = check_dof("dof", resp.dof, n)
    _check_pedestal(resp, n)
    q, cov, cross = _with_pedestal_at(resp, rotor, where, cov=cov)
    return dict(q=q, at=where, cov=cov, dof=dof, pedestal=resp.pedestal, pedestal_cov=resp.pedestal_cov,
                pedestal_cross=cross)


def _joint_moved(rotor, joint, where):
    """A joint covariance (n, 16, 16) of [Re q, Im q, Re p, Im p], q relative to the pedestals,
    moved to ``where`` (from the other place; p stays at the bearings)."""
    A, B = _pedestal_transform(_plane_matrix(rotor, where))
    M = np.zeros((16, 16))
    M[:8, :8] = _plane_matrix8(A)
    M[:8, 8:] = _plane_matrix8(B)
    M[8:, 8:] = np.eye(8)
    out = M @ np.nan_to_num(joint) @ M.T
    out[np.isnan(joint).any(axis=(1, 2))] = np.nan
    return out


def _plane_matrix4(T):
    """The 2x2 plane transform T as a 4x4 matrix over [x1, x2, y1, y2] (T on x, T on y)."""
    A4 = np.zeros((4, 4))
    A4[0:2, 0:2] = T
    A4[2:4, 2:4] = T
    return A4


def _plane_matrix8(T):
    A4 = _plane_matrix4(T)
    A8 = np.zeros((8, 8))
    A8[:4, :4] = A4
    A8[4:, 4:] = A4
    return A8


def joint_cov(resp):
    """Covariance (n, 16, 16) of [Re q, Im q, Re p, Im p] of a response with pedestal motion (the
    probe and accelerometer errors are independent unless the response was moved between planes,
    which correlates them); None when either covariance is missing."""
    if resp.pedestal is None or resp.cov is None or resp.pedestal_cov is None:
        return None
    n = resp.q.shape[0]
    out = np.zeros((n, 16, 16))
    out[:, :8, :8] = resp.cov
    out[:, 8:, 8:] = resp.pedestal_cov
    cross = resp.pedestal_cross
    if cross is not None:
        out[:, :8, 8:] = cross
        out[:, 8:, :8] = np.swapaxes(cross, 1, 2)
    return out


@dataclass
class SyncResponse:
    """Synchronous (1X) response of one imbalance run.

    ``q``: complex (n, 4), order [x1, x2, y1, y2], 0-peak amplitude, x(t) = Re(q e^{jΩt}) in metres.
    ``imbalance``: the (added) imbalance that produced it. ``at``: where q was measured,
    "bearings" or "probes" (the rotor's s1, s2). ``cov`` (n, 8, 8), optional: the measurement
    covariance of each point's [Re q, Im q] (m², NaN where unknown), ``dof`` (n,) its degrees of
    freedom (inf when known exactly): the identification propagates them to the coefficients.

    Flexible pedestals: ``pedestal`` (n, 4) complex, the pedestal (bearing housing) displacement
    [xp1, xp2, yp1, yp2] in m at the bearings (from the accelerometers, see
    :func:`rotorid.pedestal.displacement_from_acceleration`), with ``pedestal_cov`` (n, 8, 8) its
    covariance and ``pedestal_cross`` (n, 8, 8), optional, the covariance between [Re q, Im q]
    and [Re p, Im p] (None: probe and accelerometer errors independent). Then ``q`` is what
    probes mounted on the pedestals read: the rotor's motion relative to them, and
    :attr:`absolute` is the rotor's motion in space.
    """

    speed_rpm: np.ndarray
    q: np.ndarray
    imbalance: Imbalance | None = None
    at: str = "bearings"
    name: str | None = field(default=None)
    cov: np.ndarray | None = None
    dof: np.ndarray | None = None
    pedestal: np.ndarray | None = None
    pedestal_cov: np.ndarray | None = None
    pedestal_cross: np.ndarray | None = None

    @classmethod
    def _unchecked(cls, **fields) -> "SyncResponse":
        """A response from values rotorid computed itself, unchecked (see :func:`_unchecked`)."""
        return _unchecked(cls, **fields)

    def __post_init__(self):
        self.speed_rpm = speeds_rpm("speed_rpm", self.speed_rpm)
        self.q = complex_array("q", self.q)
        if self.q.ndim == 1 and self.q.shape == (4,) and self.speed_rpm.size == 1:
            self.q = self.q[None, :]
        if self.q.shape != (self.speed_rpm.size, 4):
            raise RotoridError(f"q has shape {self.q.shape}, expected ({self.speed_rpm.size}, 4) "
                               "= (len(speed_rpm), [x1, x2, y1, y2])")
        choice("at", self.at, {"bearings", "probes"})
        if self.imbalance is not None and not isinstance(self.imbalance, Imbalance):
            raise RotoridError(f"imbalance must be a rotorid.Imbalance, got {type(self.imbalance).__name__}")
        if self.name is None and self.imbalance is not None:
            self.name = self.imbalance.name
        n = self.speed_rpm.size
        self.cov = check_cov("cov", self.cov, n)
        self.dof = check_dof("dof", self.dof, n)
        _check_pedestal(self, n)

    def _moved(self, rotor, where):
        if self.at == where:
            return self
        if self.pedestal is not None:
            fields = _pedestal_moved(self, rotor, where)
            if fields is not None:
                return SyncResponse._unchecked(speed_rpm=self.speed_rpm, imbalance=self.imbalance, name=self.name,
                                               **fields)
            q, cov, cross = _with_pedestal_at(self, rotor, where)
            return SyncResponse(self.speed_rpm, q, self.imbalance, where, self.name, cov, self.dof, self.pedestal,
                                self.pedestal_cov, cross)
        T = _plane_matrix(rotor, where)
        if self.cov is None and self.dof is None and _q_as_checked(self):
            # this response was validated: its move is not checked again (0.4 ms per 100,000 speeds)
            return SyncResponse._unchecked(speed_rpm=self.speed_rpm, q=_apply_planes(T, self.q, checked=True),
                                           imbalance=self.imbalance, at=where, name=self.name)
        return SyncResponse(self.speed_rpm, _apply_planes(T, self.q), self.imbalance, where, self.name,
                            _cov_transform(T, self.cov), self.dof)

    def at_bearings(self, rotor: RigidRotor) -> "SyncResponse":
        """This response at the bearings (report eq. 19; with pedestal motion, the relative motion
        at the bearings, the probes riding on the pedestals)."""
        return self._moved(rotor, "bearings")

    def at_probes(self, rotor: RigidRotor) -> "SyncResponse":
        """This response at the probe planes (inverse of eq. 19)."""
        return self._moved(rotor, "probes")

    @property
    def absolute(self):
        """The rotor's motion in space at the same planes as ``q``: q + pedestal (q itself without
        pedestal motion)."""
        return self.q if self.pedestal is None else self.q + self.pedestal

    @property
    def pedestal_ratio(self):
        """Pedestal motion relative to the journal's motion in its housing, (n,): rms over the four
        coordinates of |pedestal| / |q| (None without pedestal motion)."""
        return None if self.pedestal is None else pedestal_ratio(self.pedestal, self.q)

    @property
    def amplitude(self):
        """0-peak amplitude |q| (m), shape (n, 4)."""
        return np.abs(self.q)

    @property
    def phase_deg(self):
        """Phase angle arg(q) in degrees (instrument phase lag is its negative)."""
        return np.rad2deg(np.angle(self.q))

    def to_dataframe(self):
        import pandas as pd

        data = {"speed_rpm": self.speed_rpm}
        _polar_columns(data, DOFS, self.q, self.cov)
        if self.pedestal is not None:
            from .pedestal import PEDESTAL_DOFS

            _polar_columns(data, PEDESTAL_DOFS, self.pedestal, self.pedestal_cov)
        return pd.DataFrame(data)


def _check_model(rotor, bearings):
    if not isinstance(rotor, RigidRotor):
        raise RotoridError(f"rotor must be a rotorid.RigidRotor, got {type(rotor).__name__}")
    if not isinstance(bearings, BearingCoefficients):
        raise RotoridError(f"bearings must be a rotorid.BearingCoefficients, got {type(bearings).__name__}")


def _core_coeffs(bearings: BearingCoefficients, n, speed_rpm=None, freq_hz=None, broadcast=False):
    """Bearing coefficients as the core wants them: (n, 8), or (1, 8) for constant coefficients when
    the core function broadcasts (``broadcast=True``)."""
    if broadcast and bearings.is_constant:
        return bearings.k.reshape(1, 8).copy(), bearings.c.reshape(1, 8).copy()
    k, c = bearings.at(speed_rpm=speed_rpm, freq_hz=freq_hz)
    k = np.ascontiguousarray(np.broadcast_to(k, (n, 2, 2, 2)).reshape(n, 8))
    c = np.ascontiguousarray(np.broadcast_to(c, (n, 2, 2, 2)).reshape(n, 8))
    return k, c


def _check_pedestals(pedestals):
    from .pedestal import Pedestals

    if pedestals is not None and not isinstance(pedestals, Pedestals):
        raise RotoridError(f"pedestals must be a rotorid.Pedestals or None, got {type(pedestals).__name__}")
    return pedestals


def imbalance_response(rotor: RigidRotor, bearings: BearingCoefficients, imbalance: Imbalance, *,
                       speed_rpm, at: str = "bearings", pedestals=None) -> SyncResponse:
    """Synchronous response to an imbalance set over speeds (eq. 13-14), batched in the core.

    With ``pedestals`` (a :class:`rotorid.Pedestals`) the bearings sit in flexible housings: the
    response's ``q`` is then the rotor's motion relative to the pedestals (what probes mounted on
    them read), ``pedestal`` the housings' motion, ``absolute`` the rotor's motion in space.

    Examples
    --------
    >>> import numpy as np, rotorid
    >>> rig = rotorid.nsf_rig()
    >>> r = rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances["A"], speed_rpm=[3000.0],
    ...                                pedestals=rotorid.example_pedestals())
    >>> r.pedestal.shape
    (1, 4)
    """
    _check_model(rotor, bearings)
    if not isinstance(imbalance, Imbalance):
        raise RotoridError(f"imbalance must be a rotorid.Imbalance, got {type(imbalance).__name__}")
    choice("at", at, {"bearings", "probes"})
    pedestals = _check_pedestals(pedestals)
    rpm = speeds_rpm("speed_rpm", speed_rpm)
    n = rpm.size
    k, c = _core_coeffs(bearings, n, speed_rpm=rpm, broadcast=True)
    # F_i = e Omega_i^2: the core scales each point's solution, no (n, 4) force array is built
    e = np.ascontiguousarray(imbalance.generalized(rotor), dtype=complex).reshape(1, 1, 4)
    if pedestals is not None:
        om = rpm * RPM
        q, qp = _with_pedestals(rotor, k, c, pedestals, om, om, e, at, imbalance=True,
                                singular=lambda bad: "the rotor-bearing-pedestal system is singular (undamped "
                                                     f"resonance) at speed_rpm = {rpm[bad][:5]}")
        return SyncResponse._unchecked(speed_rpm=rpm, q=q, imbalance=imbalance, at=at, name=imbalance.name,
                                       pedestal=qp)
    # Omega from rpm, w = Omega and the gains Omega^2 are formed in the core: (n,) temporaries
    # here made glibc hand memory back to the system after every call and fault it in again on
    # the next (360 page faults, +1.2 ms per 100,000 speeds)
    # at the probe planes: moved by the core in the same pass (no second array, no second call)
    q, nsing = _core.imbalance_response(rotor.core_params(), k, c, rpm, e, spin_scale=RPM, planes=_planes_to(rotor, at))
    if nsing:
        bad = rpm[~np.all(np.isfinite(q[:, 0, :]), axis=1)]
        raise RotoridError(f"the rotor-bearing system is singular (undamped resonance) at speed_rpm = {bad[:5]}")
    # the core's own output at validated speeds: built without re-checking 100,000s of values
    return SyncResponse._unchecked(speed_rpm=rpm, q=q[:, 0, :], imbalance=imbalance, at=at, name=imbalance.name)


@dataclass(frozen=True)
class ProbeResolution:
    """Measurement-error model of 1X vectors: the amplitude is rounded to a fixed resolution and
    the phase to a fixed resolution, optionally after adding complex Gaussian noise (rms, metres).

    The defaults, 0.001 mil (0.0254 µm) 0-pk and 0.01 degree, are the precision to which the demo
    tabulates its simulated responses before identifying; with them the NSF experiment shows the
    report's Figure 4 pattern (poor below ~2000 rpm, good between the critical speeds, cross-coupled
    stiffness distorted above ~6000 rpm). A DAQ reporting 0.01 mil and 1 degree is far coarser and
    ruins the cross-coupled coefficients everywhere (README, "Figure 4").
    """

    amplitude_m: float = 0.0254e-6
    phase_deg: float = 0.01
    noise_m: float = 0.0

    def __post_init__(self):
        from ._validate import number

        for nm in ("amplitude_m", "phase_deg", "noise_m"):
            object.__setattr__(self, nm, number(nm, getattr(self, nm), nonneg=True))

    def apply(self, q, rng=None):
        q = np.asarray(q, complex)
        if self.noise_m > 0:
            rng = np.random.default_rng(rng)
            q = q + self.noise_m / np.sqrt(2) * (rng.standard_normal(q.shape) + 1j * rng.standard_normal(q.shape))
        amp = np.abs(q)
        ph = np.angle(q, deg=True)
        if self.amplitude_m > 0:
            amp = np.round(amp / self.amplitude_m) * self.amplitude_m
        if self.phase_deg > 0:
            ph = np.round(ph / self.phase_deg) * self.phase_deg
        return amp * np.exp(1j * np.deg2rad(ph))

    def measure(self, response: SyncResponse, rng=None) -> SyncResponse:
        """The response as this instrument reports it (the pedestal motion, if any, unchanged)."""
        return SyncResponse(response.speed_rpm, self.apply(response.q, rng), response.imbalance, response.at,
                            response.name, pedestal=response.pedestal)


# ---------------------------------------------------------------------------------------------
# Impacts (report section 5)


def impact_vector(plane: float, direction: str) -> np.ndarray:
    """Generalized force of a unit impact at axial position ``plane`` (m from the CG, positive
    toward bearing 2) in ``direction`` "x" or "y".

    Rows follow eq. 3-4: [sum Fx, sum Fy, sum z Fx, -sum z Fy]. (Eq. 24 of the report prints the
    fourth row as +sum d Fy; that sign disagrees with the imbalance moments of eq. 4 and with the
    rotor equations, and only vanishes for the report's impacts at the CG.)
    """
    choice("direction", direction, {"x", "y"})
    z = number("plane", plane)
    return np.array([1.0, 0.0, z, 0.0]) if direction == "x" else np.array([0.0, 1.0, 0.0, -z])


@dataclass
class ImpactResponse:
    """Response of the rotor to an impact at one running speed, in the frequency domain.

    ``q``: complex (n, 4) [x1, x2, y1, y2]: the response spectrum when ``force`` (the force spectrum,
    complex (n,)) is given, else already per unit force (an FRF, m/N). ``plane``: axial position of
    the impact from the CG (m, positive toward bearing 2); ``direction``: "x" or "y".
    ``sigma`` (1/s): when force and response were both multiplied by an exponential window
    exp(-sigma t), the spectra are those of s = sigma + j w, and the identification accounts for it.
    ``cov`` (n, 8, 8), optional: covariance of the FRF's [Re, Im] per frequency ((m/N)², e.g.
    from the scatter of single impacts), ``dof`` (n,) its degrees of freedom.

    Flexible pedestals: ``pedestal`` (n, 4), the pedestal displacement [xp1, xp2, yp1, yp2] per
    unit force (m/N, the accelerometer FRFs divided by -w²), ``pedestal_cov`` its covariance,
    ``pedestal_cross`` the covariance between q and pedestal (see :class:`SyncResponse`); ``q`` is then the motion relative to the pedestals (FRFs only: ``force=None``).
    """

    speed_rpm: float
    freq_hz: np.ndarray
    q: np.ndarray
    force: np.ndarray | None = None
    plane: float = 0.0
    direction: str = "x"
    at: str = "bearings"
    name: str | None = None
    sigma: float = 0.0
    cov: np.ndarray | None = None
    dof: np.ndarray | None = None
    pedestal: np.ndarray | None = None
    pedestal_cov: np.ndarray | None = None
    pedestal_cross: np.ndarray | None = None

    def __post_init__(self):
        self.sigma = float(real_array("sigma", self.sigma, ndim=0, nonneg=True))
        self.speed_rpm = float(real_array("speed_rpm", self.speed_rpm, ndim=0, nonneg=True))
        self.freq_hz = np.atleast_1d(real_array("freq_hz", self.freq_hz, ndim=None))
        if self.freq_hz.ndim != 1 or self.freq_hz.size == 0:
            raise RotoridError(f"freq_hz must be a non-empty 1-D array, got shape {self.freq_hz.shape}")
        if np.any(self.freq_hz <= 0):
            raise RotoridError("freq_hz must be > 0 (a zero frequency has no dynamic stiffness to identify; "
                               "drop the DC bin)")
        n = self.freq_hz.size
        self.q = complex_array("q", self.q, shape=(n, 4))
        if self.force is not None:
            self.force = complex_array("force", self.force, shape=(n,))
            small = np.abs(self.force) <= 1e-12 * np.abs(self.force).max()
            if np.any(small):
                raise RotoridError(f"force spectrum is zero at freq_hz = {self.freq_hz[small][:5]}: "
                                   "no excitation there (restrict freq_hz to the band the impact excites)")
        self.plane = float(real_array("plane", self.plane, ndim=0))
        choice("direction", self.direction, {"x", "y"})
        choice("at", self.at, {"bearings", "probes"})
        if self.cov is not None and self.force is not None:
            raise RotoridError("cov is the covariance of an FRF (response per unit force): give q as the FRF "
                               "(force=None) together with cov")
        self.cov = check_cov("cov", self.cov, n)
        self.dof = check_dof("dof", self.dof, n)
        if self.pedestal is not None and self.force is not None:
            raise RotoridError("pedestal motion is taken per unit force: give q and pedestal as FRFs (force=None)")
        _check_pedestal(self, n)

    @classmethod
    def _unchecked(cls, **fields) -> "ImpactResponse":
        """A test from values rotorid computed itself, unchecked (see :func:`_unchecked`)."""
        return _unchecked(cls, **fields)

    @property
    def absolute(self):
        """The rotor's FRF in space at the planes of ``q``: q + pedestal (q without pedestal motion)."""
        h = self.frf()
        return h if self.pedestal is None else h + self.pedestal

    @property
    def pedestal_ratio(self):
        """(n,) pedestal motion relative to the motion relative to the pedestals: rms over the four
        coordinates of |pedestal| / |q| (None without pedestal motion)."""
        return None if self.pedestal is None else pedestal_ratio(self.pedestal, self.frf())

    def frf(self) -> np.ndarray:
        """Response per unit force (m/N), (n, 4)."""
        return self.q if self.force is None else self.q / self.force[:, None]

    def excitation(self) -> np.ndarray:
        return impact_vector(self.plane, self.direction)

    def _moved(self, rotor, where):
        if self.at == where:
            return self
        if self.pedestal is not None:
            fields = _pedestal_moved(self, rotor, where) if self.force is None else None
            if fields is not None:
                return ImpactResponse._unchecked(speed_rpm=self.speed_rpm, freq_hz=self.freq_hz, force=None,
                                                 plane=self.plane, direction=self.direction, name=self.name,
                                                 sigma=self.sigma, **fields)
            q, cov, cross = _with_pedestal_at(self, rotor, where)
            return ImpactResponse(self.speed_rpm, self.freq_hz, q, None, self.plane, self.direction, where,
                                  self.name, self.sigma, cov, self.dof, self.pedestal, self.pedestal_cov, cross)
        T = _plane_matrix(rotor, where)
        if self.cov is None and self.dof is None and _q_as_checked(self):
            # this test was validated: its move is not checked again (as SyncResponse._moved)
            return ImpactResponse._unchecked(speed_rpm=self.speed_rpm, freq_hz=self.freq_hz,
                                             q=_apply_planes(T, self.q, checked=True), force=self.force,
                                             plane=self.plane, direction=self.direction, at=where, name=self.name,
                                             sigma=self.sigma)
        return ImpactResponse(self.speed_rpm, self.freq_hz, _apply_planes(T, self.q), self.force, self.plane,
                              self.direction, where, self.name, self.sigma, _cov_transform(T, self.cov), self.dof)

    def at_bearings(self, rotor: RigidRotor) -> "ImpactResponse":
        """This test at the bearings (eq. 19; with pedestal motion, relative to the pedestals)."""
        return self._moved(rotor, "bearings")

    def at_probes(self, rotor: RigidRotor) -> "ImpactResponse":
        """This test at the probe planes."""
        return self._moved(rotor, "probes")

    def to_dataframe(self):
        import pandas as pd

        h = self.frf()
        data = {"freq_hz": self.freq_hz}
        for j, nm in enumerate(DOFS):
            data[f"{nm}_amp_um_per_N"] = 1e6 * np.abs(h[:, j])
            data[f"{nm}_phase_deg"] = np.rad2deg(np.angle(h[:, j]))
        if self.pedestal is not None:
            from .pedestal import PEDESTAL_DOFS

            for j, nm in enumerate(PEDESTAL_DOFS):
                data[f"{nm}_amp_um_per_N"] = 1e6 * np.abs(self.pedestal[:, j])
                data[f"{nm}_phase_deg"] = np.rad2deg(np.angle(self.pedestal[:, j]))
        return pd.DataFrame(data)


def _impact_coeffs(bearings, speed_rpm, freq_hz):
    n = freq_hz.size
    if bearings.axis_name == "freq_hz":
        return _core_coeffs(bearings, n, freq_hz=freq_hz)
    if bearings.axis_name == "speed_rpm":
        k, c = bearings.at(speed_rpm=[speed_rpm])
        return k.reshape(1, 8).copy(), c.reshape(1, 8).copy()
    return _core_coeffs(bearings, n, broadcast=True)


def impact_frf(rotor: RigidRotor, bearings: BearingCoefficients, *, speed_rpm: float, freq_hz, plane: float = 0.0,
               direction: str = "x", at: str = "bearings", name: str | None = None,
               pedestals=None) -> ImpactResponse:
    """Response per unit impact force (m/N) over frequency at one running speed (eq. 26-28).

    Bearing coefficients may be constant, tabulated over freq_hz (frequency-dependent), or over
    speed_rpm (taken at ``speed_rpm``). With ``pedestals`` the FRFs are relative to the pedestals
    and ``pedestal`` holds the pedestals' FRFs (see :func:`imbalance_response`).

    Examples
    --------
    >>> import numpy as np, rotorid
    >>> rig = rotorid.nsf_rig()
    >>> h = rotorid.impact_frf(rig.rotor, rig.bearings, speed_rpm=3000.0, freq_hz=np.arange(10.0, 100.0, 10.0))
    >>> h.q.shape
    (9, 4)
    """
    _check_model(rotor, bearings)
    pedestals = _check_pedestals(pedestals)
    choice("at", at, {"bearings", "probes"})
    speed = float(real_array("speed_rpm", speed_rpm, ndim=0, nonneg=True))
    f = np.atleast_1d(real_array("freq_hz", freq_hz, finite=False))
    if not (f.ndim == 1 and f.size and _core.first_outside(f, 0.0, math.inf) is None):  # one pass
        real_array("freq_hz", freq_hz)  # NaN or inf, named with its index
        raise RotoridError("freq_hz must be a non-empty 1-D array of frequencies > 0")
    e = impact_vector(real_array("plane", plane, ndim=0), direction)
    k, c = _impact_coeffs(bearings, speed, f)
    # one running speed, and w = 2 pi f formed by the core: no (n,) temporaries
    spin = np.array([speed * RPM])
    fields = dict(speed_rpm=speed, freq_hz=f, plane=float(plane), direction=direction, name=name)
    force = e.astype(complex)[None, None, :]
    if pedestals is not None:
        q, qp = _with_pedestals(rotor, k, c, pedestals, spin, f, force, at, w_scale=2 * np.pi,
                                singular=lambda bad: f"the rotor-bearing-pedestal system is singular at freq_hz = "
                                                     f"{f[bad][:5]}")
        return ImpactResponse._unchecked(q=q, at=at, pedestal=qp, **fields)
    q, nsing = _core.forced_response(rotor.core_params(), k, c, spin, f, force, w_scale=2 * np.pi,
                                     planes=_planes_to(rotor, at))
    if nsing:
        raise RotoridError(f"the rotor-bearing system is singular at freq_hz = {f[~np.isfinite(q[:, 0, 0])][:5]}")
    # the core's own output at validated frequencies: built without re-checking it
    return ImpactResponse._unchecked(q=q[:, 0, :], at=at, **fields)


def _with_pedestals(rotor, k, c, pedestals, spin, w, force, at, *, singular, imbalance=False, w_scale=None):
    """(q relative to the pedestals at ``at``, pedestal motion at the bearings), both (n, 4), of
    one force vector with flexible pedestals. The core forms the relative motion in the pass that
    forms p: q - p at the bearings; at the probe planes (probes riding on the pedestals) the
    relative reading T q - p with T from the bearings to the probes (the same as moving q - p
    there with :func:`_pedestal_transform`), with the bits of moving q first and subtracting p
    after. ``singular(mask)``: the message when points are singular."""
    q, qp, nsing = _core.forced_response_pedestal(rotor.core_params(), k, c, pedestals.core_params(), spin, w,
                                                  force, imbalance=imbalance, relative=True, w_scale=w_scale,
                                                  planes=_planes_to(rotor, at))
    if nsing:
        raise RotoridError(singular(~np.all(np.isfinite(q[:, 0, :]), axis=1)))
    return q[:, 0, :], qp[:, 0, :]


def _expm(a: np.ndarray) -> np.ndarray:
    """Matrix exponential by scaling and squaring with a degree-18 Taylor series (error < 1e-20
    before squaring; the matrices here are small and well scaled)."""
    nrm = np.abs(a).sum(axis=1).max()
    s = max(0, int(np.ceil(np.log2(nrm / 0.5))) if nrm > 0.5 else 0)
    x = a / 2.0 ** s
    term = np.eye(a.shape[0])
    out = term.copy()
    for k in range(1, 19):
        term = term @ x / k
        out = out + term
    for _ in range(s):
        out = out @ out
    return out


@dataclass
class TimeResponse:
    """Sampled time response: ``t`` (N,) s, ``q`` (N, 4) m real [x1, x2, y1, y2], ``force`` (N,) N.

    With pedestals, ``q`` is the rotor's motion relative to the pedestals (what probes on them
    read), ``pedestal`` (N, 4) the housings' displacement [xp1, xp2, yp1, yp2] (m) and
    ``pedestal_accel`` (N, 4) their acceleration (m/s², what accelerometers on them read)."""

    t: np.ndarray
    q: np.ndarray
    force: np.ndarray
    fs_hz: float
    speed_rpm: float
    plane: float
    direction: str
    at: str = "bearings"
    pedestal: np.ndarray | None = None
    pedestal_accel: np.ndarray | None = None


def impact_time_response(rotor: RigidRotor, bearings: BearingCoefficients, *, speed_rpm: float, force_N, fs_hz: float,
                         plane: float = 0.0, direction: str = "x", at: str = "bearings",
                         pedestals=None) -> TimeResponse:
    """Displacements caused by a sampled force pulse, exact for the linear model.

    The force is taken as piecewise linear between samples; the state-space model
    [q, dq/dt]' = A [q, dq/dt] + B F is discretized exactly with the matrix exponential of the
    augmented system (first-order hold) and stepped in the Rust core. The rotor starts at rest.
    Bearing coefficients must not depend on frequency (that has no time-domain ODE form).

    With ``pedestals`` (a :class:`rotorid.Pedestals` with masses > 0) the state holds the rotor's
    absolute motion q_a and the pedestals' motion p (8 + 8 states):

        M q_a'' + Omega G q_a' + C (q_a' - p') + K (q_a - p) = F
        M_p p'' + C_p p' + K_p p = C_b (q_a' - p') + K_b (q_a - p)

(C = E C_b, K = E K_b: the rotor's rows balance forces and moments, the pedestals' rows are
the bearing forces C_b, K_b over [x1, x2, y1, y2])

    and the result carries ``q`` = q_a - p (relative), ``pedestal`` and ``pedestal_accel``.

    Examples
    --------
    >>> import rotorid
    >>> rig = rotorid.nsf_rig()
    >>> u = rotorid.half_sine_pulse(1000.0, 1e-3, 10000.0, 2000)
    >>> r = rotorid.impact_time_response(rig.rotor, rig.bearings, speed_rpm=3000, force_N=u, fs_hz=10000.0,
    ...                                  pedestals=rotorid.example_pedestals())
    >>> r.q.shape, r.pedestal_accel.shape
    ((2000, 4), (2000, 4))
    """
    _check_model(rotor, bearings)
    choice("at", at, {"bearings", "probes"})
    pedestals = _check_pedestals(pedestals)
    if bearings.axis_name == "freq_hz":
        raise RotoridError("impact_time_response needs frequency-independent bearing coefficients")
    speed = float(real_array("speed_rpm", speed_rpm, ndim=0, nonneg=True))
    fs = float(real_array("fs_hz", fs_hz, ndim=0, positive=True))
    u = real_array("force_N", force_N, ndim=1)
    if u.size < 2:
        raise RotoridError("force_N needs at least 2 samples")
    k, c = bearings.at(speed_rpm=[speed]) if bearings.axis_name == "speed_rpm" else bearings.at()
    M, G, K, C = rotor.matrices(k[0], c[0])
    f = impact_vector(plane, direction)
    if pedestals is None:
        Mt, Ct, Kt, ft = M, C + speed * RPM * G, K, f
    else:
        if np.any(pedestals.mass_kg <= 0):
            raise RotoridError(f"impact_time_response with pedestals needs pedestal masses > 0 (the state-space "
                               f"form inverts the mass matrix), got mass_kg = {pedestals.mass_kg.tolist()}")
        from .pedestal import dof_matrix

        Mp, Kp, Cp = pedestals.matrices()
        # the rotor's rows are force and moment balances (K = E K_b with K_b the bearing
        # coefficients over [x1, x2, y1, y2]); the pedestals' rows are the bearing forces
        Kb, Cb = dof_matrix(k[0]), dof_matrix(c[0])
        Z = np.zeros((4, 4))
        Mt = np.block([[M, Z], [Z, Mp]])
        Ct = np.block([[C + speed * RPM * G, -C], [-Cb, Cb + Cp]])
        Kt = np.block([[K, -K], [-Kb, Kb + Kp]])
        ft = np.concatenate([f, np.zeros(4)])
    nd = Mt.shape[0]
    Mi = np.linalg.inv(Mt)
    A = np.block([[np.zeros((nd, nd)), np.eye(nd)], [-Mi @ Kt, -Mi @ Ct]])
    B = np.concatenate([np.zeros(nd), Mi @ ft])[:, None]
    dt = 1.0 / fs
    ns = 2 * nd
    aug = np.zeros((ns + 2, ns + 2))
    aug[:ns, :ns] = A
    aug[:ns, ns:ns + 1] = B
    aug[ns, ns + 1] = 1.0
    E = _expm(aug * dt)
    phi, g0, g1 = E[:ns, :ns], E[:ns, ns:ns + 1], E[:ns, ns + 1:ns + 2] / dt
    # what is read out at every step, formed by the core from the state x = [q_a, (p), q_a', (p')]:
    # q at the bearings or the probes (relative to the pedestals), and with pedestals p and the
    # pedestals' acceleration from the equations of motion (rows 4..7 of x'' = A x + B u: exact,
    # no differencing); no array of states is read back
    plane4 = _plane_matrix4(_plane_matrix(rotor, "probes") if at == "probes" else np.eye(2))
    Z4 = np.zeros((4, 4))
    if pedestals is None:
        outputs = [(np.hstack([plane4, Z4]), np.zeros((4, 1)))]
    else:
        I4 = np.eye(4)
        outputs = [(np.hstack([plane4, -I4, Z4, Z4]), np.zeros((4, 1))),   # q = T q_a - p
                   (np.hstack([Z4, I4, Z4, Z4]), np.zeros((4, 1))),        # p
                   (A[nd + 4:nd + 8], B[nd + 4:nd + 8])]                   # p''
    ys, first_bad = _core.lti_run(np.ascontiguousarray(phi), np.ascontiguousarray(g0), np.ascontiguousarray(g1),
                                  np.ascontiguousarray(u[:, None]), np.zeros(ns),
                                  [(np.ascontiguousarray(c), np.ascontiguousarray(d)) for c, d in outputs])
    if first_bad is not None:
        raise RotoridError(f"impact_time_response overflowed (at sample {first_bad}): the model's fastest mode is too "
                           f"fast or unstable for fs_hz = {fs:g} Hz (stiff, light pedestals?); raise fs_hz or check "
                           "the coefficients")
    q, p, acc = (ys[0], None, None) if pedestals is None else ys
    # i dt (np.arange(n) * dt's bits) from the core, in memory its allocator reuses (np.arange took
    # ~2.4 ms per call at 2 million samples inside this function, the core 0.5 ms)
    t = _core.sample_times(u.size, dt)
    return TimeResponse(t, q, u, fs, speed, float(plane), direction, at, p, acc)


def half_sine_pulse(peak_N: float, duration_s: float, fs_hz: float, n_samples: int, t0_s: float = 0.0) -> np.ndarray:
    """A half-sine force pulse (a typical hammer or impactor load) sampled at fs_hz."""
    peak_N = float(real_array("peak_N", peak_N, ndim=0))
    duration_s = float(real_array("duration_s", duration_s, ndim=0, positive=True))
    fs_hz = float(real_array("fs_hz", fs_hz, ndim=0, positive=True))
    t0_s = float(real_array("t0_s", t0_s, ndim=0))
    n_samples = index("n_samples", n_samples, 1, 1 << 26)  # 0.5 GB: the longest window rotorid accepts (signals.MAX_WINDOW)
    t = np.arange(n_samples) / fs_hz - t0_s
    return np.where((t >= 0) & (t <= duration_s), peak_N * np.sin(np.pi * np.clip(t, 0, duration_s) / duration_s), 0.0)
