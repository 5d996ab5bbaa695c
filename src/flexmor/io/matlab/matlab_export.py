"""Export of a reduced body to a MATLAB ``.mat`` file (``scipy.io.savemat``, format v5).

Variables (MATLAB names; all present, empty where not available):

==================  ==========  ====================================================
``Mr Kr Dr``        r x r       reduced mass, stiffness, damping (``Dr`` zeros if none)
``Br``, ``Cr``      r x m, p x r  reduced input and output matrices
``V``               n x r       basis at the equations of the full model (as read: a
                                coupling's slaves included, :mod:`flexmor.expansion`)
``node_ids``        n_nodes x 1 node numbers; ``xyz`` n_nodes x 3 coordinates
``dofs``            n x 2       equation map: node id, direction 1..6 (x y z rx ry rz)
``frequencies_hz``  r x 1       undamped eigenfrequencies of the reduced body
``input_names``,    cell        port SPECs
``output_names``
``method``,         char        method, full model name, flexmor version
``model_name``,
``version``
``stress_nodes``    k x 1       nodes of the stress modes (``reduce --stress``); empty without
``stress_modes``    r x k x 6   nodal stress (xx yy zz xy yz zx) of each basis vector; empty
                                without stress modes
``inv``             struct      inertia invariants when the FE model is given
                                (``mass mdCM J Ct Cr Cr1 Gr Ge Oe Oe1 Me Ke``, frame
                                nodes ``node_id origin phi psi``; see
                                :mod:`flexmor.io.invariants`); otherwise ``[]``
``units``           char        the unit system of the numbers, e.g. ``mm-t-s (length
                                mm, mass t, time s, ...)``
``spin``            struct      a body reduced over a speed range (``reduce --spin-range``,
                                :mod:`flexmor.spin`): ``axis`` (3 x 1), ``range`` (rad/s),
                                ``K2`` and ``G1`` (r x r): at the speed w the body's stiffness
                                is ``Kr + w^2 K2`` and its gyroscopic matrix ``w G1`` (in the
                                frame turning with it); otherwise ``[]``
``moving_loads``    struct      a body reduced with moving loads (``reduce --moving-load``,
                    array       :mod:`flexmor.moving`), one element per path: ``spec``
                    (1 x P)     (``SET:DIR@AXIS``), ``direction`` (``x``, ``y`` or ``z``: the
                                force's axis in the body's frame), ``nodes`` (N x 1 node ids in
                                path order), ``s`` (N x 1 arc length of each node from the
                                first), ``length``, ``B_path`` (r x N: the reduced input of a
                                unit force at each path node, ``V^T B_path``) and
                                ``interpolation`` (text). A force ``F`` at ``s0`` enters as
                                ``B_path * w(s0) * F``, ``w`` the linear interpolation weights
                                between the two path nodes around ``s0`` (N x 1, zero off the
                                path); the deflection under it is ``w' * B_path' * qr``;
                                otherwise ``[]``
==================  ==========  ====================================================

Units: SI by default; ``units="mm-t-s"`` (a system of :data:`flexmor.units.SYSTEMS`) writes
every quantity in that system (:data:`MAT_DIMENSIONS`), the modal coordinates unchanged:
``Br`` per input (a force input ``NODE:x`` in mm per unit of ``qr`` and N, a moment input
unchanged), ``Cr`` per output, ``V`` per equation (mm at translations, rad at rotations).
``frequencies_hz`` stays in Hz; ``moving_loads``: ``B_path`` as a force input, ``s`` and ``length`` as lengths.

References
----------
R. Schwertassek, O. Wallrapp, *Dynamik flexibler Mehrkörpersysteme*, Vieweg, 1999, ch. 6.
"""

from __future__ import annotations

import numpy as np
import scipy.io

from ...errors import OptionError, PortError
from ...units import dof_lengths, export_units, port_kind
from .._registry import EXPORT_FORMATS
from ..atomic import atomic_write
from ..sid.sid import SID_DIMENSIONS

__all__ = ["MAT_DIMENSIONS", "MAT_FIELDS", "write_mat"]

#: Variables every exported ``.mat`` file holds.
MAT_FIELDS = ("Mr", "Kr", "Dr", "Br", "Cr", "V", "node_ids", "xyz", "dofs", "frequencies_hz", "input_names",
              "output_names", "method", "model_name", "version", "stress_nodes", "stress_modes", "inv", "units", "spin",
              "moving_loads")

#: The dimension ``(length, mass, time)`` exponents of the variables of one dimension (``Br``, ``Cr`` and
#: ``V`` have one per input, output and equation); the fields of ``inv`` as their SID objects.
MAT_DIMENSIONS = {"Mr": (2, 1, 0), "Kr": (2, 1, -2), "Dr": (2, 1, -1), "xyz": (1, 0, 0),
                  "inv": {k: SID_DIMENSIONS[v] for k, v in (
                      ("mass", "mass"), ("mdCM", "mdCM"), ("mdCM1", "mdCM"), ("J", "J"), ("J1", "J"), ("Ct", "Ct"),
                      ("Cr", "Cr"), ("Cr1", "Cr"), ("Gr", "Gr"), ("Ge", "Ge"), ("Oe", "Oe"), ("Oe1", "Oe"),
                      ("Me", "Me"), ("Ke", "Ke"), ("origin", "origin"), ("phi", "phi"), ("psi", "psi"))},
                  "spin": {"K2": (2, 1, 0), "G1": (2, 1, 0)}}


def _cell(names):
    arr = np.empty((len(names), 1), dtype=object)
    for i, s in enumerate(names):
        arr[i, 0] = str(s)
    return arr


def _empty(a, shape=(0, 0)):
    return np.zeros(shape) if a is None else np.asarray(a)


def mat_variables(body, model=None, *, nodes=None, units: str = "SI") -> dict:
    """The variables of the ``.mat`` file as a dict (see the module docstring). With ``model`` (as
    read) a body with couplings is written at the model's equations, its basis expanded to the
    slave nodes, and its masters are frame nodes (:func:`flexmor.expansion.expand_body`)."""
    system = export_units(body, units)
    masters = ()
    if model is not None and body.V is not None:
        from ...expansion import expand_body, expanded_reduced

        xb = expand_body(model, body, elastic=False)
        body, model, masters = expanded_reduced(xb), xb.model, xb.masters
    r = body.order
    out = {
        "Mr": body.M, "Kr": body.K, "Dr": _empty(body.D, (r, r)) if body.D is not None else np.zeros((r, r)),
        "Br": body.B, "Cr": body.C, "V": _empty(body.V),
        "node_ids": _empty(body.node_ids, (0,)).reshape(-1, 1).astype(float),
        "xyz": _empty(body.xyz, (0, 3)), "dofs": _empty(body.dofs, (0, 2)).astype(float),
        "frequencies_hz": body.frequencies_hz().reshape(-1, 1),
        "input_names": _cell(body.input_names), "output_names": _cell(body.output_names),
        "method": body.method, "model_name": body.model_name, "version": body.version,
        "stress_nodes": _empty(body.stress_nodes, (0,)).reshape(-1, 1).astype(float),
        "stress_modes": _empty(body.stress_modes, (r, 0, 6)),
        "inv": np.zeros((0, 0)),
        "spin": np.zeros((0, 0)),
    }
    spin = body.info.get("spin") if isinstance(body.info, dict) else None
    if spin:
        out["spin"] = {"axis": np.asarray(spin["axis"], dtype=float).reshape(3, 1),
                       "range": np.asarray(spin["range"], dtype=float).reshape(2, 1),
                       "K2": np.asarray(spin["K2"], dtype=float), "G1": np.asarray(spin["G1"], dtype=float)}
    out["moving_loads"] = _moving_loads(body)
    if model is not None and body.V is not None:
        from ..invariants import compute_invariants, frame_nodes

        try:
            fn = frame_nodes(model, body.V, nodes, body, masters=masters)
        except PortError:  # no port or interface nodes: frame nodes are optional in the .mat file
            fn = []
        inv = compute_invariants(model, body.V, K=body.K, D=body.D, nodes=fn)
        out["inv"] = {
            "mass": inv.mass, "mdCM": inv.mdCM0.reshape(3, 1), "mdCM1": inv.mdCM1, "J": inv.J0,
            "J1": inv.J1.transpose(1, 2, 0), "Ct": inv.Ct, "Cr": inv.Cr0, "Cr1": inv.Cr1, "Gr": inv.Gr,
            "Ge": inv.Ge, "Oe": inv.Oe0, "Oe1": inv.Oe1, "Me": inv.Me, "Ke": inv.Ke,
            "node_id": np.array([n.id for n in fn], dtype=float).reshape(-1, 1),
            "origin": np.array([n.origin for n in fn]).reshape(-1, 3),
            "phi": np.array([n.phi for n in fn]).reshape(-1, 3, r),
            "psi": np.array([n.psi for n in fn]).reshape(-1, 3, r),
        }
    out["units"] = system.describe() if body.units is not None or not system.is_si else "as given by the FE file"
    return out if system.is_si else _in_units(out, body, system)


#: Fields of each element of the ``moving_loads`` struct array.
MOVING_FIELDS = ("spec", "direction", "nodes", "s", "length", "B_path", "interpolation")


def _moving_loads(body):
    """The ``moving_loads`` struct array (1, P) of a body reduced with moving loads, else ``[]``."""
    loads = body.info.get("moving_loads") if isinstance(body.info, dict) else None
    if not loads:
        return np.zeros((0, 0))
    out = np.zeros((1, len(loads)), dtype=[(k, object) for k in MOVING_FIELDS])
    for j, ml in enumerate(loads):
        out[0, j] = (str(ml["spec"]), str(ml["direction"]), np.asarray(ml["nodes"], float).reshape(-1, 1),
                     np.asarray(ml["s"], float).reshape(-1, 1), float(ml["length"]),
                     np.asarray(ml["B_path"], float).reshape(body.order, -1), str(ml["interpolation"]))
    return out


def _in_units(out: dict, body, system) -> dict:
    """The SI variables ``out`` of ``body`` in ``system`` (see the module docstring)."""
    def port_dims(names, what):
        kinds = [port_kind(n) for n in names]
        if None in kinds:
            bad = names[kinds.index(None)]
            raise OptionError(f"{what} {bad!r} names no direction, so whether it is a "
                              f"{'force or a moment' if what == 'input' else 'displacement or a rotation'} is not "
                              f"known: the .mat file of this body is written in SI only", params=("units",))
        return np.array([system.length if k == "translation" else 1.0 for k in kinds])

    out = dict(out)
    for k in ("Mr", "Kr", "Dr", "xyz"):
        out[k] = system.from_si(out[k], *MAT_DIMENSIONS[k])
    out["Br"] = np.asarray(out["Br"]) / port_dims(body.input_names, "input")[None, :]
    out["Cr"] = np.asarray(out["Cr"]) / port_dims(body.output_names, "output")[:, None]
    if np.size(out["V"]):
        if out["dofs"].shape[0] != out["V"].shape[0]:
            raise OptionError("the body has no equation map, so which rows of its basis are rotations is not "
                              "known: the .mat file of this body is written in SI only", params=("units",))
        out["V"] = np.asarray(out["V"]) / dof_lengths(out["dofs"].astype(np.int64), system)[:, None]
    if np.size(out["stress_modes"]):  # stress per reduced coordinate (the coordinates keep their scale, as V shows)
        out["stress_modes"] = np.asarray(out["stress_modes"]) / system.stress
    if np.size(out["moving_loads"]):  # unit forces at the path nodes, positions along it
        ml = np.array(out["moving_loads"], copy=True)
        for j in range(ml.shape[1]):
            ml["B_path"][0, j] = ml["B_path"][0, j] / system.length
            ml["s"][0, j] = system.from_si(ml["s"][0, j], 1, 0, 0)
            ml["length"][0, j] = float(system.from_si(ml["length"][0, j], 1, 0, 0))
        out["moving_loads"] = ml
    for name in ("inv", "spin"):
        if isinstance(out[name], dict):
            dims = MAT_DIMENSIONS[name]
            out[name] = {k: system.from_si(v, *dims[k]) if k in dims else v for k, v in out[name].items()}
    return out


def write_mat(body, path, *, model=None, nodes=None, units: str = "SI") -> None:
    """Write a reduced body to a MATLAB ``.mat`` file (v5), atomically.

    Parameters
    ----------
    body : ReducedModel
    path : str or path-like
    model : FEModel, optional
        The full model; when given, the inertia invariants are added as struct ``inv``.
    nodes : sequence of str, optional
        Frame nodes for ``inv`` (default: the body's port/interface nodes).
    units : str
        The unit system of the numbers (:data:`flexmor.units.SYSTEMS`), stated in the variable
        ``units``; other than SI only for a body whose model's units are known (``body.units``).

    Raises
    ------
    OptionError
        An unknown ``units``, or ports without a direction written in other units than SI.
    ModelError
        Other units than SI for a body whose model was read as given.
    """
    data = mat_variables(body, model, nodes=nodes, units=units)
    atomic_write(path, lambda tmp: scipy.io.savemat(tmp, data, do_compression=True, oned_as="column"))


EXPORT_FORMATS.register("mat", [".mat"], write_mat, aliases=["matlab"],
                        description="reduced body as MATLAB .mat (Mr Kr Dr Br Cr V ...; inertia invariants "
                                    "with the FE model)")
