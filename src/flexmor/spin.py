"""Spinning bodies: the stiffness and the gyroscopic matrix of a body turning at a constant angular velocity,
one reduced body over a speed range, and Campbell diagrams.

In the frame that turns with the body at the angular velocity ``ω a`` (``a`` a unit axis through the origin),
a supported body (a rotor in its bearings, a blade at its hub) vibrates about its centrifugally loaded
equilibrium as

.. math:: M \\ddot u + (D + ω G_1) \\dot u + (K + ω^2 K_2) u = f

with ``K_2 = K_G(σ_1) - P_1^T M P_1`` (the geometric stiffness of the centrifugal stresses of the unit speed,
:mod:`flexmor.preload`, minus the spin softening) and the Coriolis (gyroscopic) matrix
``G_1 = M P_1 + P_1 M`` (skew-symmetric; ``P_1`` the skew matrix of ``a`` on the translations of each node,
so ``G_1 = 2 M P_1`` for a mass matrix that treats x, y and z alike). Both scale with the speed, so one reduced
body carries them for every speed: ``K_r(ω) = Vᵀ K V + ω² Vᵀ K_2 V``, ``G_r = Vᵀ G_1 V``.

:func:`campbell` gives the damped eigenvalues over a speed range (the full model by shift-invert Arnoldi on
the first-order form at each speed, one factorization of ``K + ω² K_2`` per speed; a reduced body densely),
each mode's **whirl** (forward when it turns about the axis in the sense of the spin, in the turning frame) and
the **critical speeds** where a frequency crosses a multiple of the speed.

References
----------
M. Géradin, D. J. Rixen, *Mechanical Vibrations*, 3rd ed., Wiley 2015, ch. 8 (rotating structures:
centrifugal stiffening, spin softening, Coriolis forces).

R. Schwertassek, O. Wallrapp, *Dynamik flexibler Mehrkörpersysteme*, Vieweg, 1999, ch. 6.
"""

from __future__ import annotations

import logging
import re
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .errors import FlexmorError, ModelError, OptionError

__all__ = ["Campbell", "SpinOperators", "SpinRange", "campbell", "check_stable", "critical_speeds", "merged_basis",
           "parse_axis_speeds", "parse_spin_range", "spin_check", "spin_operators"]

log = logging.getLogger(__name__)

_AXES = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}
#: Speeds at which a body over a speed range is built (the ends and the middle).
BUILD_SPEEDS = 3
#: Speeds at which it is checked against the full model (equally spaced, the ends included).
CHECK_SPEEDS = 5
#: |normalized whirl| below which a mode does not whirl (axial, torsional or in-plane modes).
WHIRL_TOL = 0.1


@dataclass(frozen=True)
class SpinRange:
    """A speed range about an axis: ``axis`` (unit (3,)), ``w0``, ``w1`` (rad/s) and the SPEC as given."""

    axis: np.ndarray
    w0: float
    w1: float
    spec: str = ""

    def speeds(self, n: int) -> np.ndarray:
        """``n`` equally spaced speeds from ``w0`` to ``w1``."""
        return np.linspace(self.w0, self.w1, max(int(n), 1)) if n > 1 else np.array([self.w1])

    def record(self) -> dict:
        """JSON: ``spec``, ``axis``, ``range`` (rad/s)."""
        return {"spec": self.spec, "axis": self.axis.tolist(), "range": [self.w0, self.w1]}


def parse_spin_range(spec) -> SpinRange:
    """``AXIS:W0:W1`` (``AXIS`` ``x``, ``y``, ``z`` or ``AX,AY,AZ``; speeds in rad/s, ``0 <= W0 < W1``).

    Raises
    ------
    OptionError
        Naming ``spin_range``.
    """
    if isinstance(spec, SpinRange):
        return spec
    text = str(spec).strip()
    parts = text.split(":")
    if len(parts) != 3:
        raise OptionError(f"spin range {text!r}: give AXIS:W0:W1 (AXIS x, y, z or AX,AY,AZ; rad/s), e.g. z:0:500",
                          params=("spin_range",))
    axis_text = parts[0].strip().lower()
    try:
        axis = np.array(_AXES[axis_text] if axis_text in _AXES else [float(v) for v in axis_text.split(",")])
        w0, w1 = float(parts[1]), float(parts[2])
    except ValueError:
        raise OptionError(f"spin range {text!r}: the axis and the speeds must be numbers (AXIS:W0:W1)",
                          params=("spin_range",)) from None
    if axis.shape != (3,) or not np.all(np.isfinite(axis)) or np.linalg.norm(axis) == 0:
        raise OptionError(f"spin range {text!r}: the axis needs three finite numbers, not all zero",
                          params=("spin_range",))
    if not (np.isfinite(w0) and np.isfinite(w1) and 0 <= w0 < w1):
        raise OptionError(f"spin range {text!r}: the speeds need 0 <= W0 < W1 (rad/s)", params=("spin_range",))
    return SpinRange(axis / np.linalg.norm(axis), w0, w1, text)


@dataclass
class SpinOperators:
    """``K_2`` and ``G_1`` of a model about ``axis`` (see the module docstring), sparse, over its equations."""

    axis: np.ndarray
    K2: sp.csr_matrix
    G1: sp.csr_matrix

    def stiffness(self, K, w: float):
        """``K + ω² K_2``."""
        return (K + (w * w) * self.K2).tocsr()


def spin_operators(model, axis, *, material=None, solver=None, param: str = "spin_range") -> SpinOperators:
    """The spin operators of a supported ``model`` (with solid elements) about the unit ``axis``.

    Raises
    ------
    ModelError
        A free model (naming ``param``, the option that asked for the spin), no elements or materials (as
        :func:`flexmor.preload.preload_stiffness`).
    """
    from .preload import preload_stiffness, spin_operator
    from .rigid import rigid_body_modes

    if rigid_body_modes(model).shape[1]:
        raise ModelError(f"{model.source or model.name}: a spinning body is held at its hub or bearings, but this "
                         "model moves freely: constrain it (a *BOUNDARY at the hub) for --spin-range or --campbell",
                         params=(param,))
    a = np.asarray(axis, dtype=float)
    pre = preload_stiffness(model, "spin:" + ",".join(repr(float(v)) for v in a), material=material, solver=solver)
    P, _ = spin_operator(model, a)
    G1 = sp.csr_matrix(model.M @ P + P @ model.M)
    return SpinOperators(a, sp.csr_matrix(pre.K_G + pre.softening), G1)


def check_stable(model, ops: SpinOperators, w: float, *, solver=None, param: str = "spin_range") -> None:
    """Refuse a speed at which the spinning stiffness ``K + w^2 K2`` has a negative eigenvalue (a mode the spin
    softens below zero in the turning frame), whatever the solver backend (an LU factorization does not tell
    an indefinite matrix): the lowest eigenvalues of ``(K + w^2 K2, M)``."""
    import dataclasses

    from .checks import stable_lowest_eigenvalues
    from .linalg.context import as_solver

    try:
        stable_lowest_eigenvalues(dataclasses.replace(model, K=ops.stiffness(model.K, w), preload=None),
                                  as_solver(solver), 1)
    except ModelError:
        raise ModelError(f"{model.source or model.name}: at {w:g} rad/s the spinning stiffness K + w^2 K2 is not "
                         "positive definite (a speed above the first frequency of a mode the spin softens, in the "
                         "turning frame): give a lower speed", params=(param,)) from None


@dataclass
class Campbell:
    """Eigenvalues over speeds.

    Attributes
    ----------
    speeds : ndarray (s,)
        rad/s.
    frequencies_hz : ndarray (s, k)
        Damped frequencies ``Im λ / 2π``, ascending at each speed.
    damping : ndarray (s, k)
        Damping ratios ``-Re λ / |λ|``.
    whirl : ndarray (s, k)
        Normalized whirl ``Im(uᴴ M P_1 u) / uᴴ M u`` in [-1, 1]: > 0 forward, < 0 backward.
    critical : list of dict
        ``{"mode", "multiple", "speed", "frequency_hz"}`` where mode ``mode`` (by order at each speed)
        crosses ``multiple`` times the speed.
    """

    speeds: np.ndarray
    frequencies_hz: np.ndarray
    damping: np.ndarray
    whirl: np.ndarray
    critical: list = field(default_factory=list)

    def labels(self) -> np.ndarray:
        """``FW``, ``BW`` or ``-`` per entry of :attr:`whirl` (``-`` at rest: a whirl needs a spin, and the
        modes of a pair that the spin splits are any combination of the two there)."""
        lab = np.where(self.whirl > WHIRL_TOL, "FW", np.where(self.whirl < -WHIRL_TOL, "BW", "-"))
        lab[self.speeds == 0] = "-"
        return lab

    def record(self) -> dict:
        """JSON values."""
        return {"speeds": self.speeds.tolist(), "frequencies_hz": self.frequencies_hz.tolist(),
                "damping": self.damping.tolist(), "whirl": self.whirl.tolist(), "labels": self.labels().tolist(),
                "critical": self.critical}


def _first_order_dense(M, K, C) -> tuple[np.ndarray, np.ndarray]:
    n = M.shape[0]
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-K, -C]])
    B = np.block([[np.eye(n), np.zeros((n, n))], [np.zeros((n, n)), M]])
    return A, B


def _pairs(lam: np.ndarray, U: np.ndarray, k: int):
    """The ``k`` eigenvalues of positive imaginary part with the smallest modulus, and their vectors."""
    keep = np.flatnonzero(lam.imag > 1e-9 * np.abs(lam).max(initial=1.0))
    keep = keep[np.argsort(lam[keep].imag)][:k]
    return lam[keep], U[:, keep]


def _whirl(M, P1M, u: np.ndarray) -> np.ndarray:
    num = np.einsum("ij,ij->j", u.conj(), P1M @ u)
    den = np.einsum("ij,ij->j", u.conj(), M @ u).real
    return num.imag / np.where(den > 0, den, 1.0)


def campbell(M, K, K2, G1, speeds, k: int, *, D=None, P1M=None, solver=None) -> Campbell:
    """The lowest ``k`` damped eigenvalues of ``λ² M + λ (D + ω G_1) + K + ω² K_2`` at each speed ω.

    Parameters
    ----------
    M, K, K2, G1 : sparse or dense (n, n)
        Dense (a reduced body): ``scipy.linalg.eig`` of the first-order form. Sparse (the full model):
        shift-invert Arnoldi about 0 with one factorization of ``K + ω² K_2`` per speed.
    speeds : array_like
        rad/s.
    D : matrix, optional
        Damping.
    P1M : matrix, optional
        ``M P_1`` (default ``G_1 / 2``) for the whirl of each mode.

    Raises
    ------
    ModelError
        A speed with a mode that grows (``K + ω² K_2`` indefinite and not stabilized by the Coriolis forces), or
        with a singular ``K + ω² K_2``.
    """
    from .linalg import factorize

    speeds = np.asarray(speeds, dtype=float)
    sparse = sp.issparse(K)
    n = K.shape[0]
    P1M = 0.5 * G1 if P1M is None else P1M
    F, Z, W = (np.full((speeds.size, k), np.nan) for _ in range(3))
    for i, w in enumerate(speeds):
        Kw = K + (w * w) * K2
        C = w * G1 if D is None else D + w * G1
        if sparse:
            try:
                fac = factorize(sp.csr_matrix(Kw), solver=solver, symmetric=True)  # spin may stabilize it
            except FlexmorError as exc:  # a singular stiffness at that speed
                raise ModelError(f"at {w:g} rad/s the spinning stiffness K + w^2 K2 is singular ({exc})",
                                 params=("campbell",)) from None
            Cs = sp.csr_matrix(C)

            def op(x, fac=fac, Cs=Cs):
                u, v = x[:n], x[n:]
                return np.concatenate([-fac.solve(M @ v + Cs @ u), u])

            m = min(2 * k + 2, 2 * n - 2)
            mu, X = spla.eigs(spla.LinearOperator((2 * n, 2 * n), matvec=op, dtype=complex), k=m, which="LM",
                              ncv=min(2 * n - 1, max(2 * m + 1, 20)), v0=np.ones(2 * n))
            lam, U = 1.0 / mu, X[:n]
        else:
            A, B = _first_order_dense(np.asarray(M), np.asarray(Kw), np.asarray(C))
            lam, X = sla.eig(A, B)
            U = X[:n]
        if np.any(lam.real > 1e-6 * np.abs(lam).max(initial=0.0)):  # a mode that grows: K + w^2 K2 indefinite
            raise ModelError(f"at {w:g} rad/s the spinning body has a mode that grows (its stiffness K + w^2 K2 is "
                             "indefinite there and the Coriolis forces do not stabilize it): give a lower speed",
                             params=("campbell",))
        lam, U = _pairs(lam, U, k)
        j = lam.size
        F[i, :j] = lam.imag / (2 * np.pi)
        Z[i, :j] = -lam.real / np.abs(lam)
        W[i, :j] = _whirl(M, P1M, U)
    return Campbell(speeds, F, Z, W, critical_speeds(speeds, F))


def critical_speeds(speeds, F, multiples=(1, 2, 3, 4)) -> list:
    """Crossings of each frequency curve (by order) with ``k`` times the speed (Hz), linear between speeds."""
    out = []
    for j in range(F.shape[1]):
        for k in multiples:
            g = F[:, j] - k * speeds / (2 * np.pi)
            for i in np.flatnonzero(np.sign(g[:-1]) * np.sign(g[1:]) < 0):
                t = g[i] / (g[i] - g[i + 1])
                s = speeds[i] + t * (speeds[i + 1] - speeds[i])
                out.append({"mode": j + 1, "multiple": k, "speed": float(s),
                            "frequency_hz": float(k * s / (2 * np.pi))})
    return out


def parse_axis_speeds(text: str) -> tuple[SpinRange, int]:
    """``AXIS:W0:W1[:N]`` of ``--campbell``: the range and the number of speeds (default 11)."""
    m = re.fullmatch(r"(.*):(\d+)", str(text).strip())
    if m and str(text).count(":") == 3:
        return parse_spin_range(m.group(1)), int(m.group(2))
    return parse_spin_range(text), 11


def merged_basis(model, bases: list) -> np.ndarray:
    """One basis for every speed: the union of the bases built at each speed, M-orthonormal (directions of
    relative mass below 1e-12 of the largest, numerically dependent, left out). Its order is up to the sum of
    theirs: the bases at neighbouring speeds share most directions, and what differs (the static responses
    to the inputs at each speed's stiffness, the modes as they shift) is what keeps the body exact at each
    build speed (a Galerkin body on a larger space)."""
    from .linalg.threads import sparse_dense

    Y = np.hstack([np.asarray(V, dtype=float) for V in bases])
    G = Y.T @ sparse_dense(model.M, Y)
    d = 1.0 / np.sqrt(np.clip(np.diag(G), np.finfo(float).tiny, None))
    w, X = np.linalg.eigh((G * d[:, None]) * d[None, :])
    keep = w > 1e-12 * w.max()
    return Y @ (d[:, None] * X[:, keep] / np.sqrt(w[keep]))


def reduced_spin(model, V, ops: SpinOperators) -> dict:
    """``K2`` and ``G1`` of the basis ``V`` (dense, as lists)."""
    from .linalg.threads import sparse_dense

    K2 = V.T @ sparse_dense(ops.K2, V)
    G1 = V.T @ sparse_dense(ops.G1, V)
    return {"K2": (0.5 * (K2 + K2.T)).tolist(), "G1": (0.5 * (G1 - G1.T)).tolist()}


def spin_check(model, Mr, Kr, K2r, ops: SpinOperators, speeds, modes: int, *, solver=None) -> dict:
    """The reduced body's lowest ``modes`` frequencies (without Coriolis) against the full model's at each speed:
    ``speeds``, ``full_hz``, ``reduced_hz``, ``max_rel_error`` per speed and ``max_rel_error`` over all."""
    from .linalg.eigen import eigenmodes, frequencies_hz

    full, red, err = [], [], []
    for w in speeds:
        lam = eigenmodes(ops.stiffness(model.K, w), model.M, modes, solver=solver)[0]
        f = frequencies_hz(np.sort(lam))
        lr = sla.eigh(Kr + w * w * K2r, Mr, eigvals_only=True)[:modes]
        g = frequencies_hz(lr)
        full.append(f.tolist())
        red.append(g.tolist())
        err.append(float(np.max(np.abs(g / f - 1))))
    return {"speeds": [float(w) for w in speeds], "full_hz": full, "reduced_hz": red, "max_rel_error_by_speed": err,
            "max_rel_error": max(err)}
