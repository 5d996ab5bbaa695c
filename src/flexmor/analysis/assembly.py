"""Assemblies of full and reduced bodies coupled by springs, dampers and point masses.

An :class:`Assembly` holds bodies (a full :class:`~flexmor.model.FEModel` with its ports, or a
reduced :class:`~flexmor.body.ReducedModel`) and discrete elements between *points*. A
point is ``(body, SPEC)``: a port SPEC of that body (``NODE:DIR`` or ``SET:DIR``, see
:mod:`flexmor.ports`), or ``None`` for the ground. Every point is one vector ``g`` in the
coordinates of its body: for a full body the port vector ``b`` (the column of ``B`` that the
SPEC gives), for a reduced body ``V^T b``, i.e. the column of ``Br`` (or, equivalently for the
same SPEC, the row of ``Cr``) that was declared at reduction time. A reduced body can therefore
only be coupled at ports declared as inputs or outputs when it was reduced; the body's basis
``V`` is reused as it is.

Elements add to the block-diagonal matrices of the bodies::

    spring k  between points a, b:   K += k (g_a - g_b)(g_a - g_b)^T     (g_b = 0 for ground)
    damper c  between points a, b:   D += c (g_a - g_b)(g_a - g_b)^T
    point mass m at point a:         M += m g_a g_a^T

For a Galerkin-reduced body this is exactly the projection of the coupled full body with
the same basis (``V^T (K + k b b^T) V = Kr + k Br Br^T``), so "reduce, then couple" and
"couple, then reduce with the same basis" give the same reduced assembly.

What survives the coupling depends on the method. A Krylov basis that spans
``(s0^2 M + s0 D + K)^{-1} B`` and its higher moments for all the inputs keeps matching the
moments at ``s0`` after any coupling through those inputs (the input Krylov space is invariant
under feedback ``K -> K + B F B^T``); error bounds of truncation methods (balanced truncation,
modal truncation, POD ...) hold for the uncoupled body only. Adding such a body to an
assembly issues a :class:`~flexmor.errors.FlexmorWarning` naming the method
(``flexmor.reduction.methods()[name].survives_coupling``).

References
----------
Fehr, J., Eberhard, P. (2010). Error-controlled model reduction in flexible multibody
dynamics. J. Comput. Nonlinear Dyn. 5(3), 031005.

Holzwarth, P., Eberhard, P. (2015). Interface reduction for CMS methods and alternative model
order reduction. IFAC-PapersOnLine 48(1), 254-259.

Lohmann, B., Eid, R. (2009). Efficient order reduction of parametric and nonlinear models by
superposition of locally reduced models. In: Methoden und Anwendungen der Regelungstechnik,
Shaker, 27-36.
"""

from __future__ import annotations

import logging
import warnings
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from ..body import ReducedModel
from ..errors import FlexmorWarning, ModelError, OptionError, PortError
from ..linalg import factorize
from ..linalg.context import SolverContext, as_solver
from ..model import FEModel
from ..ports import Ports, make_ports
from ..reduction import methods

__all__ = ["Assembly", "Body", "coupling_warning"]

log = logging.getLogger(__name__)


def coupling_warning(method: str, info: dict | None = None) -> str | None:
    """The warning text for a body reduced by ``method`` (``info``: its record), or None if its guarantee
    survives coupling. A krylov body compressed by balanced truncation (``info['compressed']['body']`` other
    than 'greedy', :mod:`flexmor.reduction.greedy_compress`) keeps no moments."""
    m = methods().get(method)
    if ((info or {}).get("compressed") or {}).get("body", "greedy") != "greedy":
        return (f"body reduced with method {method!r} is the balanced truncation of its greedy basis (the default "
                "points' compression): it keeps no moments, and its error guarantee holds for the uncoupled body "
                "only; reduce with compress='off' (--compress off) or directions='all' for a body that keeps them")
    if m is None or m.survives_coupling:
        return None
    return (f"body reduced with method {method!r}: its error guarantee holds for the uncoupled body only and "
            "does not survive coupling; check the assembly against the full model (interpolation methods such "
            "as 'krylov' keep their moment matching when coupled through their inputs)")


@dataclass
class Body:
    """One body of an :class:`Assembly`: a full model with ports, or a reduced body.

    Attributes
    ----------
    name : str
    model : FEModel or ReducedModel
    ports : Ports or None
        Inputs/outputs of a full body (None for a reduced body, which carries ``B``, ``C``).
    offset : int
        First coordinate of the body in the assembly.
    """

    name: str
    model: object
    ports: Ports | None
    offset: int

    @property
    def reduced(self) -> bool:
        """Whether the body is a reduced one (a :class:`~flexmor.body.ReducedModel`)."""
        return isinstance(self.model, ReducedModel)

    @property
    def size(self) -> int:
        """Coordinates the body brings into the assembly: its order, or the DOF of a full body."""
        return self.model.order if self.reduced else self.model.n_dof

    def vector(self, spec: str, *, role: str = "input") -> np.ndarray:
        """Local coordinate vector of a port SPEC (``role`` prefers the input or output form)."""
        spec = str(spec)
        if not self.reduced:
            return make_ports(self.model, inputs=[spec]).B.toarray()[:, 0]
        red = self.model
        ins, outs = list(red.input_names), list(red.output_names)
        order = (("in", ins), ("out", outs)) if role == "input" else (("out", outs), ("in", ins))
        def key(name):  # SPECs as make_ports reads them: case and blanks do not matter (tip@rbe2:Y = TIP@RBE2:y)
            return str(name).replace(" ", "").upper()

        for kind, names in order:
            keys = [key(n) for n in names]
            if key(spec) in keys:
                j = keys.index(key(spec))
                return np.asarray(red.B[:, j] if kind == "in" else red.C[j, :], dtype=float)
        raise PortError(
            f"port {spec!r} of reduced body {self.name!r} was not declared at reduction time (inputs: "
            f"{', '.join(ins) or 'none'}; outputs: {', '.join(outs) or 'none'}); reduce again with it as an input")

    def matrices(self):
        """``(M, D or None, K)`` of the body (sparse for a full body, dense for a reduced one)."""
        return self.model.M, self.model.D, self.model.K


class Assembly:
    """Bodies coupled by springs, dampers and point masses, with its frequency response.

    Examples
    --------
    >>> asm = Assembly()
    >>> asm.add_body("beam", reduced)                       # doctest: +SKIP
    >>> asm.spring(("beam", "MID:y"), None, 1e8)            # to ground  # doctest: +SKIP
    >>> H = asm.frf(f, inputs=[("beam", "TIP:y")], outputs=[("beam", "TIP:y")])  # doctest: +SKIP

    References
    ----------
    Holzwarth, P., Eberhard, P. (2015). Interface reduction for CMS methods and alternative
    model order reduction. IFAC-PapersOnLine 48(1), 254-259.
    """

    def __init__(self):
        self.bodies: dict[str, Body] = {}
        self.elements: list[tuple] = []  # (kind, value, point_a, point_b)
        self._size = 0

    # -- building -----------------------------------------------------------------------
    def add_body(self, name: str, body, ports: Ports | None = None) -> Body:
        """Add a full body (``FEModel`` with ``ports``, or its own ``B``/``C``) or a reduced body.

        Parameters
        ----------
        name : str
            Unique name used in points ``(name, SPEC)``.
        body : FEModel or ReducedModel
        ports : Ports, optional
            Inputs/outputs of a full body (the default assembly inputs/outputs); ignored for
            a reduced body.

        Warns
        -----
        FlexmorWarning
            If ``body`` was reduced by a method whose guarantee does not survive coupling, or is a
            free body whose basis excludes its rigid-body modes (the floating frame's body: it cannot
            move rigidly in an assembly; on two soft springs the free CalculiX beam lost its 8.0 and
            13.8 Hz suspension modes).
        """
        name = str(name)
        if name in self.bodies:
            raise OptionError(f"body {name!r} is already in the assembly")
        if isinstance(body, ReducedModel):
            msg = coupling_warning(body.method, body.info)
            if msg:
                log.info(msg)
                warnings.warn(msg, FlexmorWarning, stacklevel=2)
            n_rb = int((body.info or {}).get("n_rigid_excluded") or 0)
            if n_rb:  # the floating frame's body: its rigid motion is the frame's, which an assembly does not have
                warnings.warn(FlexmorWarning(
                    f"body {name!r} ({body.method}, order {body.order}) excludes the {n_rb} rigid-body modes of its "
                    "free model (the floating frame carries them): in this assembly it cannot move rigidly, so its "
                    "suspension modes and low-frequency response are missing; reduce it with rigid='include' to "
                    "couple it here", params=("rigid",)), stacklevel=2)
            ports = None
        elif not isinstance(body, FEModel):
            raise ModelError(f"body {name!r} must be an FEModel or a ReducedModel, got {type(body).__name__}")
        b = Body(name, body, ports, self._size)
        self.bodies[name] = b
        self._size += b.size
        return b

    def _point(self, point):
        if point is None:
            return None
        try:
            name, spec = point
        except (TypeError, ValueError):
            raise OptionError(f"a point is (body name, port SPEC) or None for the ground, got {point!r}") from None
        if name not in self.bodies:
            raise OptionError(f"unknown body {name!r}; bodies: {', '.join(self.bodies) or 'none'}")
        return (str(name), str(spec))

    def _element(self, kind: str, value: float, a, b) -> None:
        value = float(value)
        if not np.isfinite(value) or value < 0:
            raise OptionError(f"{kind} value must be finite and >= 0, got {value}")
        a, b = self._point(a), self._point(b)
        if a is None and b is None:
            raise OptionError(f"a {kind} needs at least one point on a body")
        g = [None if p is None else self.bodies[p[0]].vector(p[1]) for p in (a, b)]  # undeclared ports fail here
        if a is not None and b is not None and a[0] == b[0] and np.array_equal(g[0], g[1]):
            raise OptionError(f"a {kind} between {a[0]}:{a[1]} and the same point {b[0]}:{b[1]} does nothing "
                              "(its ends move together); give two points, or None for the ground")
        self.elements.append((kind, value, a, b))

    def spring(self, a, b, k: float) -> None:
        """Spring of stiffness ``k`` between points ``a`` and ``b`` (``b=None``: to the ground)."""
        self._element("spring", k, a, b)

    def damper(self, a, b, c: float) -> None:
        """Viscous damper ``c`` between points ``a`` and ``b`` (``b=None``: to the ground)."""
        self._element("damper", c, a, b)

    def mass(self, a, m: float) -> None:
        """Point mass ``m`` attached at point ``a`` (moves with the port's displacement)."""
        self._element("mass", m, a, None)

    # -- matrices -----------------------------------------------------------------------
    @property
    def size(self) -> int:
        """Number of coordinates of the assembly."""
        return self._size

    @property
    def sparse(self) -> bool:
        """True when a full body is present (sparse assembly and solves)."""
        return any(not b.reduced for b in self.bodies.values())

    def global_vector(self, point, role: str = "input") -> np.ndarray:
        """Assembly-wide vector (size,) of a point ``(body, SPEC)``."""
        name, spec = self._point(point)
        body = self.bodies[name]
        g = np.zeros(self._size)
        g[body.offset:body.offset + body.size] = body.vector(spec, role=role)
        return g

    def matrices(self):
        """``(M, D or None, K)`` of the coupled assembly (sparse if a full body is present)."""
        if not self.bodies:
            raise ModelError("the assembly has no bodies")
        sparse = self.sparse
        mats = []
        for i in range(3):
            blocks = [b.matrices()[i] for b in self.bodies.values()]
            if i == 1 and all(x is None for x in blocks) and not any(e[0] == "damper" for e in self.elements):
                mats.append(None)
                continue
            blocks = [np.zeros((b.size, b.size)) if x is None else x for x, b in zip(blocks, self.bodies.values())]
            if sparse:
                mats.append(sp.block_diag([sp.csr_matrix(x) for x in blocks], format="csr"))
            else:
                mats.append(sla.block_diag(*[np.asarray(x, dtype=float) for x in blocks]))
        target = {"mass": 0, "damper": 1, "spring": 2}
        for kind, value, a, b in self.elements:
            g = self.global_vector(a)
            if b is not None:
                g = g - self.global_vector(b)
            i = target[kind]
            if sparse:
                nz = np.flatnonzero(g)
                rows, cols = np.meshgrid(nz, nz, indexing="ij")
                add = sp.csr_matrix((value * np.outer(g[nz], g[nz]).ravel(), (rows.ravel(), cols.ravel())),
                                    shape=mats[i].shape)
                mats[i] = (mats[i] + add).tocsr()
            else:
                mats[i] = mats[i] + value * np.outer(g, g)
        return tuple(mats)

    def _io(self, inputs, outputs):
        if inputs is None:
            inputs = [(b.name, s) for b in self.bodies.values() for s in self._names(b, "input")]
        if outputs is None:
            outputs = [(b.name, s) for b in self.bodies.values() for s in self._names(b, "output")]
        if not inputs or not outputs:
            raise PortError("the assembly has no inputs or no outputs; give inputs=[(body, SPEC)] and outputs=[...]")
        B = np.column_stack([self.global_vector(p, "input") for p in inputs])
        C = np.vstack([self.global_vector(p, "output") for p in outputs])
        return B, C

    @staticmethod
    def _names(body: Body, role: str) -> list:
        if body.reduced:
            return list(body.model.input_names if role == "input" else body.model.output_names)
        if body.ports is None:
            raise PortError(f"full body {body.name!r} has no ports; give inputs/outputs explicitly")
        return list(body.ports.input_names if role == "input" else body.ports.output_names)

    # -- responses ----------------------------------------------------------------------
    def transfer(self, s, *, inputs=None, outputs=None, solver: SolverContext | None = None) -> np.ndarray:
        """``H(s) = C (s^2 M + s D + K)^{-1} B`` at complex points ``s`` (rad/s).

        Parameters
        ----------
        s : array_like of complex
            Laplace variable values.
        inputs, outputs : list of (body, SPEC), optional
            Default: every body's own inputs / outputs.
        solver : SolverContext, optional
            Solver (backend, statistics) of :func:`flexmor.linalg.factorize` (sparse assemblies only).

        Returns
        -------
        ndarray, shape (n_s, n_outputs, n_inputs), complex
        """
        solver = as_solver(solver)
        s = np.atleast_1d(np.asarray(s, dtype=complex))
        M, D, K = self.matrices()
        B, C = self._io(inputs, outputs)
        H = np.empty((s.size, C.shape[0], B.shape[1]), dtype=complex)
        for k, sk in enumerate(s):
            if self.sparse:
                A = (sk * sk) * M + K if D is None else (sk * sk) * M + sk * D + K
                F = factorize(sp.csr_matrix(A), solver=solver, symmetric=True, check=False)
                H[k] = C @ F.solve(B.astype(complex))
                del F
            else:
                A = (sk * sk) * M + K if D is None else (sk * sk) * M + sk * D + K
                H[k] = C @ np.linalg.solve(A, B.astype(complex))
        return H

    def frf(self, freqs, *, inputs=None, outputs=None, solver: SolverContext | None = None) -> np.ndarray:
        """Frequency response at ``freqs`` (Hz), shape (n_freq, n_outputs, n_inputs).

        Full assemblies are solved sparse, one :func:`flexmor.linalg.factorize` per
        frequency; all-reduced assemblies dense.
        """
        solver = as_solver(solver)
        f = np.atleast_1d(np.asarray(freqs, dtype=float))
        if not np.all(np.isfinite(f)) or np.any(f < 0):
            raise OptionError("frequencies must be finite and >= 0 Hz")
        return self.transfer(2j * np.pi * f, inputs=inputs, outputs=outputs, solver=solver)
