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
==================  ==========  ====================================================

References
----------
R. Schwertassek, O. Wallrapp, *Dynamik flexibler Mehrkörpersysteme*, Vieweg, 1999, ch. 6.
"""

from __future__ import annotations

import numpy as np
import scipy.io

from ...errors import PortError
from .._registry import EXPORT_FORMATS
from ..atomic import atomic_write

__all__ = ["MAT_FIELDS", "write_mat"]

#: Variables every exported ``.mat`` file holds.
MAT_FIELDS = ("Mr", "Kr", "Dr", "Br", "Cr", "V", "node_ids", "xyz", "dofs", "frequencies_hz", "input_names",
              "output_names", "method", "model_name", "version", "stress_nodes", "stress_modes", "inv")


def _cell(names):
    arr = np.empty((len(names), 1), dtype=object)
    for i, s in enumerate(names):
        arr[i, 0] = str(s)
    return arr


def _empty(a, shape=(0, 0)):
    return np.zeros(shape) if a is None else np.asarray(a)


def mat_variables(body, model=None, *, nodes=None) -> dict:
    """The variables of the ``.mat`` file as a dict (see the module docstring). With ``model`` (as
    read) a body with couplings is written at the model's equations, its basis expanded to the
    slave nodes, and its masters are frame nodes (:func:`flexmor.expansion.expand_body`)."""
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
    }
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
    return out


def write_mat(body, path, *, model=None, nodes=None) -> None:
    """Write a reduced body to a MATLAB ``.mat`` file (v5), atomically.

    Parameters
    ----------
    body : ReducedModel
    path : str or path-like
    model : FEModel, optional
        The full model; when given, the inertia invariants are added as struct ``inv``.
    nodes : sequence of str, optional
        Frame nodes for ``inv`` (default: the body's port/interface nodes).
    """
    data = mat_variables(body, model, nodes=nodes)
    atomic_write(path, lambda tmp: scipy.io.savemat(tmp, data, do_compression=True, oned_as="column"))


EXPORT_FORMATS.register("mat", [".mat"], write_mat, aliases=["matlab"],
                        description="reduced body as MATLAB .mat (Mr Kr Dr Br Cr V ...; inertia invariants "
                                    "with the FE model)")
