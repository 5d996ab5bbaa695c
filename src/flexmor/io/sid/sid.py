"""SID (Standard Input Data, Wallrapp 1994) flexible-body files, ``.SID_FEM`` ASCII.

The file read by Neweul-M2, the Modelica EMBS library and others describes an elastic body of
the floating frame of reference: ``part / new modal / refmod / frame / new node … /
mdCM / J / Ct / Cr / Me / Gr / Ge / Oe / ksigma / Ke / De / end modal / end part``. Every
matrix is a *Taylor object* ``A(q) = m0 + Σ_k m1[:, :, k] q_k`` with the header
``order, nrow, ncol, nq, nqn, structure`` (structure 0 zero, 1 diagonal, 2 symmetric,
3 full, 4 identity) and the entries ``m0(i,j)``, ``m1(i,j,k)``; zero entries are omitted.

The index order of ``m1``
    Tools disagree. The two sample files (PY_SID, read by the Modelica EMBS library) write
    ``m1(row, q, col)``: the middle index is the modal coordinate; welib's SID writer uses
    ``m1(row, col, q)``. flexmor writes ``m1_order="row-q-col"`` by default (the sample
    files' order) and ``"row-col-q"`` on request. The reader detects the order from the index
    ranges (an index above ``ncol`` or ``nq`` tells) and falls back to the default when every
    object is ambiguous (``nq == ncol``).

Layouts written: ``J`` as 6 x 1 ``(xx, yy, zz, xy, xz, yz)`` of the tensor
``∫(rᵀr I − r rᵀ) dm``; ``Gr = [Gr_1 … Gr_r]`` and ``Ge = [Ge_1 … Ge_r]`` in blocks of three
columns per mode; ``Oe`` columns ``ωx² ωy² ωz² ωxωy ωyωz ωxωz``. Numbers are written with 17
significant digits and a Fortran ``D`` exponent, so a write → read round trip is exact;
``D``, ``d``, ``E`` exponents are all read.

Moving loads
    A body reduced with moving loads (:mod:`flexmor.moving`) has every node of each path as a frame node,
    after the others, in path order (a contiguous block per path, named ``SET#NODE``; the header says which
    indices), so that a multibody code applies the moving force itself by interpolating between them.

Units
    SI by default; ``units="mm-t-s"`` (any system of :data:`flexmor.units.SYSTEMS`) writes each
    object in that system (:data:`SID_DIMENSIONS`: the mass in t, ``J`` in t mm^2, ``Ke`` in
    N mm, ...; the modal coordinates unchanged, so a mode shape ``phi`` is in mm per unit of its
    coordinate). SID has no field for units: the first line (header comment) states them.

References
----------
O. Wallrapp, Standardization of flexible body modeling in multibody system codes, Part I:
Definition of standard input data, *Mechanics of Structures and Machines* 22(3):283-304, 1994.

R. Schwertassek, O. Wallrapp, *Dynamik flexibler Mehrkörpersysteme*, Vieweg, 1999, ch. 6.
"""

from __future__ import annotations

import logging
import re
from pathlib import Path

import numpy as np

from ..._version import __version__
from ...errors import OptionError
from ...units import export_units, unit_system
from .._open import stem
from .._registry import EXPORT_FORMATS, MODEL_FORMATS
from ..atomic import atomic_write
from .sid_reader import read_sid
from .sid_types import BODY_OBJECTS, M1_ORDERS, NODE_OBJECTS, SIDFile, SIDNode, Taylor

__all__ = ["M1_ORDERS", "SID_DIMENSIONS", "SIDFile", "SIDNode", "Taylor", "read_sid", "sid_from_reduced",
           "sid_in_units", "write_sid"]

log = logging.getLogger(__name__)


def _taylor(m0, m1=None, nq=0, *, sym=False):
    m0 = np.atleast_2d(np.asarray(m0, dtype=float))
    structure = 3
    if m1 is None:
        if not np.any(m0):
            structure = 0
        elif m0.shape[0] == m0.shape[1] and np.array_equal(m0, np.eye(m0.shape[0])):
            structure = 4
        elif m0.shape[0] == m0.shape[1] and np.array_equal(m0, np.diag(np.diag(m0))):
            structure = 1
        elif sym and np.array_equal(m0, m0.T):
            structure = 2
    elif not np.any(m0) and not np.any(m1):
        structure = 0
    return Taylor(m0, None if m1 is None else np.asarray(m1, dtype=float), nq, structure)


#: The dimension ``(length, mass, time)`` exponents of each SID object (body objects, the node objects and
#: ``mass``); the modal coordinates count as numbers without unit.
SID_DIMENSIONS = {
    "mass": (0, 1, 0), "mdCM": (1, 1, 0), "J": (2, 1, 0), "Ct": (1, 1, 0), "Cr": (2, 1, 0), "Me": (2, 1, 0),
    "Gr": (2, 1, 0), "Ge": (2, 1, 0), "Oe": (2, 1, 0), "ksigma": (2, 1, -2), "Ke": (2, 1, -2), "De": (2, 1, -1),
    "origin": (1, 0, 0), "phi": (1, 0, 0), "psi": (0, 0, 0), "AP": (0, 0, 0), "sigma": (-1, 1, -2),
}


def sid_in_units(sid: SIDFile, units) -> SIDFile:
    """The SI contents ``sid`` in the unit system ``units``: every object scaled by its dimension
    (:data:`SID_DIMENSIONS`)."""
    system = unit_system(units)

    def scaled(t: Taylor, name: str) -> Taylor:
        dims = SID_DIMENSIONS[name]
        return Taylor(system.from_si(t.m0, *dims), None if t.m1 is None else system.from_si(t.m1, *dims), t.nq,
                      t.structure, t.nqn)

    nodes = [SIDNode(n.id, *(scaled(getattr(n, k), k) for k in NODE_OBJECTS), rframe=n.rframe,
                     sigma=None if n.sigma is None else scaled(n.sigma, "sigma")) for n in sid.nodes]
    return SIDFile(mass=float(system.from_si(sid.mass, *SID_DIMENSIONS["mass"])), ielastq=list(sid.ielastq),
                   nodes=nodes, objects={k: scaled(t, k) for k, t in sid.objects.items()}, header=sid.header)


def _skew(v):
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def sid_from_reduced(body, model, *, nodes=None, remove_rigid: bool = False, units: str = "SI",
                     stiffening: bool = True, progress=None) -> SIDFile:
    """Build the SID contents of a reduced body.

    Parameters
    ----------
    body : ReducedModel
        Must hold its basis ``V``.
    model : FEModel
        The full model it was reduced from, as read (mass matrix, coordinates): the body applies
        its own couplings and its basis is expanded to their slave nodes
        (:func:`flexmor.expansion.expand_body`); each coupling master is a frame node with its
        translations (``phi``) and rotations (``psi``).
    nodes : sequence of str, optional
        Frame nodes (node ids, node sets, coupling masters); default the body's port and
        interface nodes and every coupling master. A body with moving loads (:mod:`flexmor.moving`)
        gets every node of their paths after these, in path order (the header says which).
    remove_rigid : bool
        Allow the basis of a body that holds rigid-body motion to be made mass-orthogonal to
        it (another body than the one judged); refused by default.
    units : str
        The unit system written (:data:`flexmor.units.SYSTEMS`); the header states it. Other
        than SI only for a body whose model was read with its unit system named
        (``body.units``).
    stiffening : bool
        Write the load stiffening (:func:`flexmor.stiffening.load_stiffening`): the geometric stiffness of
        unit frame accelerations in the ``m1`` of ``Ct`` and ``Cr``, of the centrifugal products in ``Oe``
        (added to its mass terms, the spin softening), of unit forces and moments at each frame node in the
        ``m1`` of its ``phi`` and ``psi`` (as a generalized force ``phi(q)ᵀ F``: minus the stiffness). A
        model without solid elements, or a free body without interface, gets none; the header says why.
    progress : callable, optional
        Progress of the load stiffening (:func:`flexmor.linalg.context.track`).

    Returns
    -------
    SIDFile

    Raises
    ------
    ModelError, PortError
        Basis missing or not matching the model; no frame nodes; a body whose model's units are
        not known written in other units than SI.
    OptionError
        An unknown ``units``.
    """
    system = export_units(body, units)
    from ...expansion import expand_body
    from ..invariants import compute_invariants, frame_nodes

    xb = expand_body(model, body, remove_rigid=remove_rigid)  # the floating frame carries the rigid motion
    body, model, V = xb.body, xb.model, xb.V
    fn = frame_nodes(model, V, nodes, body, masters=xb.masters)
    fn, path_said = _path_nodes(model, V, body, fn)
    inv = compute_invariants(model, V, K=body.K, D=body.D, nodes=fn)
    r = V.shape[1]
    stressed = {} if body.stress_modes is None or body.stress_nodes is None else \
        {int(n): i for i, n in enumerate(body.stress_nodes)}
    sid_nodes = []
    for nd in fn:
        ap1 = np.stack([_skew(nd.psi[:, a]) for a in range(r)], axis=2)
        sigma = None
        if nd.id in stressed:  # the node's modal stresses (reduce --stress)
            sigma = _taylor(np.zeros((6, 1)), np.asarray(body.stress_modes)[:, stressed[nd.id], :].T[:, None, :], r)
        sid_nodes.append(SIDNode(nd.id, _taylor(nd.origin[:, None], nd.phi[:, None, :], r),
                                 _taylor(nd.phi, nq=r), _taylor(nd.psi, nq=r), _taylor(np.eye(3), ap1, r),
                                 sigma=sigma))

    def jv(J):
        return np.array([J[0, 0], J[1, 1], J[2, 2], J[0, 1], J[0, 2], J[1, 2]])

    J1 = np.stack([jv(inv.J1[a]) for a in range(r)], axis=1)[:, None, :]
    De = inv.De if inv.De is not None else np.zeros((r, r))
    stiff, stiff_said = None, "no load stiffening"
    if stiffening:
        stiff, stiff_said = _stiffening(xb, fn, body, progress)
    if stiff is not None:  # [node][d, a, b]: phi(q)^T F is a generalized force, minus the stiffness of F
        for nd, sn in zip(fn, sid_nodes):
            G = stiff.nodes[int(nd.id)]
            sn.phi = _taylor(nd.phi, -G[:3], r)
            sn.psi = _taylor(nd.psi, -G[3:], r)
    Ct1 = None if stiff is None else stiff.acceleration.transpose(1, 0, 2)
    Cr1 = inv.Cr1.transpose(0, 2, 1) + (0 if stiff is None else stiff.angular.transpose(1, 0, 2))
    Oe1 = inv.Oe1.transpose(0, 2, 1) + (0 if stiff is None else stiff.centrifugal.transpose(1, 0, 2))
    objects = {
        "mdCM": _taylor(inv.mdCM0[:, None], inv.mdCM1[:, None, :], r),
        "J": _taylor(jv(inv.J0)[:, None], J1, r),
        "Ct": _taylor(inv.Ct, Ct1, nq=r),
        "Cr": _taylor(inv.Cr0, Cr1, r),
        "Me": _taylor(inv.Me, nq=r, sym=True),
        "Gr": _taylor(inv.Gr, nq=r),
        "Ge": _taylor(inv.Ge, nq=r),
        "Oe": _taylor(inv.Oe0, Oe1, r),
        "ksigma": _taylor(np.zeros((r, 1)), nq=r),
        "Ke": _taylor(inv.Ke, nq=r, sym=True),
        "De": _taylor(De, nq=r, sym=True),
    }

    def off(A):
        return np.max(np.abs(A - np.diag(np.diag(A))), initial=0.0) <= 1e-9 * np.max(np.abs(A))

    if off(inv.Ke) and off(inv.Me):
        f = np.sqrt(np.clip(np.diag(inv.Ke) / np.diag(inv.Me), 0, None)) / (2 * np.pi)
        names = [f"Eigen Mode {a + 1:4d} : {f[a]:12.3f} Hz" for a in range(r)]
    else:
        names = [f"{body.method or 'basis'} vector {a + 1:4d}" for a in range(r)]
    said = system.describe() if body.units is not None or not system.is_si else "as given by the FE file"
    header = (f"{len(fn):5d}{r:4d}    :No. nodes, No. modes:File created using flexmor {__version__}! "
              f"units {said}; method {body.method}, model {model.name}; consistent mass; "
              + (f"Ke with the geometric stiffness of preload {' '.join(body.info['preload'].get('specs', []))}; "
                 if isinstance(body.info.get("preload"), dict) else "no geometric stiffness in Ke; ")
              + stiff_said + "; "
              + "".join(f"{s}; " for s in path_said)
              + "frame nodes: " + ", ".join(f"{n.id}={n.name}" for n in fn))
    sid = SIDFile(mass=inv.mass, ielastq=names, nodes=sid_nodes, objects=objects, header=header)
    return sid if system.is_si else sid_in_units(sid, system)


def _path_nodes(model, V, body, fn):
    """``(frame nodes, what the header says of the paths)``: ``fn`` and after it every node of the body's moving
    loads' paths (:mod:`flexmor.moving`), a contiguous block per path in path order, at the node's position with
    its translations as ``phi`` and its rotations as ``psi`` (zero without rotational DOFs), so that a multibody
    code applies the moving force itself, interpolating between them. A single-node frame node of ``fn`` on a
    path leaves ``fn`` (the path holds it); loads over the same nodes share their block."""
    from ..invariants import node_frames

    loads = body.info.get("moving_loads") if isinstance(body.info, dict) else None
    if not loads:
        return fn, []
    on_path = {int(k) for rec in loads for k in rec["nodes"]}
    out = [nd for nd in fn if nd.id not in on_path or nd.load is None or nd.load[0] != "read"]
    blocks: dict = {}
    said = []
    for rec in loads:
        ids = tuple(int(k) for k in rec["nodes"])
        if ids not in blocks:
            first = len(out) + 1
            out += node_frames(model, V, ids, [f"{rec['set']}#{k}" for k in ids])
            blocks[ids] = (first, len(out))
        a, b = blocks[ids]
        said.append(f"moving load {rec['spec']}: frame nodes {a} to {b} (1-based) are the nodes {ids[0]} to "
                    f"{ids[-1]} of its path, set {rec['set']}, in path order")
    return out, said


def _stiffening(xb, fn, body, progress=None):
    """``(LoadStiffening or None, what the header says)``."""
    from ...errors import FlexmorError
    from ...preload import recorded_material
    from ...stiffening import load_stiffening

    try:
        st = load_stiffening(xb, fn, material=recorded_material(body.info.get("preload")), progress=progress)
    except FlexmorError as exc:
        log.info("SID without load stiffening: %s", exc)
        return None, "no load stiffening (" + str(exc).split(";")[0].strip() + ")"
    return st, f"load stiffening in the m1 of Ct Cr Oe phi psi (stresses {st.support})"


# -- writing -----------------------------------------------------------------------------------
def _num(v: float) -> str:
    return f"{v: .16E}".replace("E", "D")


def _kv(indent: int, key: str, value: str) -> str:
    return (" " * indent + key).ljust(48) + "=" + value


def _write_taylor(lines, name, t: Taylor, indent, m1_order):
    ind = 26
    lines.append(" " * indent + name)
    nrow, ncol = t.m0.shape
    for key, val in (("order", t.order), ("nrow", nrow), ("ncol", ncol), ("nq", t.nq), ("nqn", t.nqn),
                     ("structure", t.structure)):
        lines.append(_kv(ind, key, f"{val:5d}"))
    if t.structure not in (0, 4):
        for i in range(nrow):
            for j in range(ncol):
                if (t.structure == 1 and i != j) or (t.structure == 2 and j < i) or t.m0[i, j] == 0:
                    continue
                lines.append(_kv(ind, f"m0({i + 1:2d},{j + 1:2d})", _num(t.m0[i, j])))
        if t.m1 is not None:
            for j in range(ncol):
                for i in range(nrow):
                    for k in range(t.nq):
                        v = t.m1[i, j, k]
                        if v != 0:
                            a, b = (k, j) if m1_order == "row-q-col" else (j, k)
                            lines.append(_kv(ind, f"m1({i + 1:2d},{a + 1:2d},{b + 1:2d})", _num(v)))
    lines.append(" " * indent + "end " + name)


def sid_text(sid: SIDFile, *, m1_order: str = "row-q-col") -> str:
    """The ``.SID_FEM`` text of ``sid``."""
    if m1_order not in M1_ORDERS:
        raise OptionError(f"m1_order={m1_order!r} is not allowed; choose one of: {', '.join(M1_ORDERS)}")
    L = [sid.header or f"{len(sid.nodes):5d}{sid.nq:4d}    :No. nodes, No. modes", " part ",
         _kv(6, "new modal", ""), " " * 11 + "refmod ", _kv(16, "mass", _num(sid.mass)),
         _kv(16, "nelastq", f"{sid.nq:6d}")]
    L += [_kv(16, f"ielastq ({a + 1:4d})", " " + s) for a, s in enumerate(sid.ielastq)]
    L += [" " * 11 + "end refmod ", " " * 11 + "frame "]
    for nd in sid.nodes:
        L.append(_kv(16, "new node", f"{nd.id:5d}"))
        L.append(_kv(21, "rframe", f"    {nd.rframe}"))
        for name in NODE_OBJECTS:
            _write_taylor(L, name, getattr(nd, name), 21, m1_order)
        if nd.sigma is not None:
            _write_taylor(L, "sigma", nd.sigma, 21, m1_order)
        L.append(" " * 16 + "end node")
    L.append(" " * 11 + "end frame ")
    for name in BODY_OBJECTS:
        _write_taylor(L, name, sid.objects[name], 11, m1_order)
    L += ["      end modal ", " end part ", ""]
    return "\n".join(L)


def write_sid(body, path, *, model=None, nodes=None, m1_order: str = "row-q-col",
              allow_clamped: bool = False, remove_rigid: bool = False, units: str = "SI",
              stiffening: bool = True, progress=None) -> None:
    """Write a reduced body as a ``.SID_FEM`` file, atomically.

    Parameters
    ----------
    body : ReducedModel or SIDFile
    path : str or path-like
    model : FEModel
        The full model as read (required unless ``body`` is a SIDFile): the invariants need
        its mass matrix and node coordinates (see :func:`sid_from_reduced`).
    nodes : sequence of str, optional
        Frame nodes (node ids, node sets, coupling masters); default the body's port/interface
        nodes and its coupling masters; a moving load's path nodes follow (see :func:`sid_from_reduced`).
    m1_order : {'row-q-col', 'row-col-q'}
        Index order of the ``m1(i, j, k)`` entries.
    allow_clamped : bool
        Export a body of a supported (clamped) model, whose mass properties miss the supported
        nodes (:func:`flexmor.io.invariants.check_free_model`); refused by default.
    remove_rigid : bool
        See :func:`sid_from_reduced`.
    units : str
        The unit system written (see :func:`sid_from_reduced`; ignored for a SIDFile).
    stiffening : bool
        Write the load stiffening (see :func:`sid_from_reduced`).
    progress : callable, optional
        Its progress (:func:`flexmor.linalg.context.track`).

    Raises
    ------
    ModelError, PortError, OptionError
    """
    from ...errors import ModelError

    if m1_order not in M1_ORDERS:
        raise OptionError(f"m1_order={m1_order!r} is not allowed; choose one of: {', '.join(M1_ORDERS)}")
    if isinstance(body, SIDFile):
        sid = body
    else:
        if model is None:
            raise ModelError("SID export needs the FE data the body was reduced from, given as model: "
                             "the inertia invariants are integrals over its mass matrix", params=("model",))
        from ..invariants import check_free_model

        check_free_model(model, allow_clamped=allow_clamped)
        sid = sid_from_reduced(body, model, nodes=nodes, remove_rigid=remove_rigid, units=units,
                               stiffening=stiffening, progress=progress)
    text = sid_text(sid, m1_order=m1_order)
    atomic_write(path, lambda tmp: Path(tmp).write_text(text))


def _read_as_model(path, **options):
    """A SID file as an FE model with ``M = Me``, ``K = Ke``, ``D = De`` (for ``flexmor info``)."""
    from ...model import FEModel

    sid = read_sid(path, **options)
    De = sid.objects["De"].m0
    stated = re.search(r"\bunits ([A-Za-z0-9-]+) \(", sid.header or "")  # flexmor's own header names them
    return FEModel(M=sid.objects["Me"].m0, K=sid.objects["Ke"].m0, D=De if np.any(De) else None,
                   name=stem(path), source=str(path),
                   damping={"type": "given"} if np.any(De) else {"type": "none"},
                   stated_units=stated.group(1) if stated else None)


MODEL_FORMATS.register("sid", [".sid_fem", ".sid"], _read_as_model, gzip=True,
                       description="SID flexible body (Standard Input Data, Wallrapp 1994) as M = Me, K = Ke")
EXPORT_FORMATS.register("sid", [".sid_fem", ".sid"], write_sid, aliases=["sid_fem"],
                        description="SID flexible body (Standard Input Data, Wallrapp 1994), .SID_FEM ASCII, "
                                    "with all inertia invariants (needs the FE model)")
