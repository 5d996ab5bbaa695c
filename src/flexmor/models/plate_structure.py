"""A plate-and-rods steel structure meshed with hexahedra: upper plate with a central hole on rods.

The structure of a reference table comparing four reductions, Krylov, Krylov + Gramian, POD and
modal, reproduced by ``examples/slide3_table.py`` (a 35,000-DOF solid whose interface is the
wall of a hole in its upper plate), built parametrically:

* **upper plate** ``[-a/2, a/2]^2 x [0, t]`` with a central hole of diameter ``hole``; the hole
  is the set of grid cells whose centre lies inside the circle (a staircase polygon that is
  symmetric about both axes);
* **rods**: four solid square rods (side ``rod``, length ``rod_length``) below the plate, their
  axes at ``(±c, ±c)`` with ``c = a/2 - rod_inset``, meshed conformingly with the plate;
* **lower plate**: rigid. ``lower='clamped'`` (default) fixes the rods' lower end faces (node
  set ``BOTTOM``): the lower plate is bolted to a rigid foundation. ``lower='mass'`` ties the
  lower end faces by an RBE2 (:func:`flexmor.couplings.couple`) to a master node (set
  ``LOWER``) at the centre of a steel plate ``a x a x lower_thickness`` hanging below the rods,
  carrying that plate's mass and rotary inertia; the structure is then free-free (six
  rigid-body modes). ``lower='free'`` leaves the lower end faces free (the solid alone, free-free,
  translational DOFs only): tied to a rigid body by the same RBE2 it is the ``mass`` variant, the
  form an MBS code with 3-DOF FE nodes (Exudyn's ``ObjectFFRF``) takes the structure in.

All cells live on one rectilinear grid whose lines include the rods' faces and the hole's
bounding square, so plate and rods share their nodes (no tie constraints). The matrices are
assembled by :mod:`flexmor.models.solid` (8-node hexahedra, 2x2x2 Gauss, consistent mass).
Units: m, kg, N, s (frequencies in Hz).

References
----------
Fehr, J. (2011). Automated and error-controlled model reduction in elastic multibody systems.
Dissertation, Universität Stuttgart, Shaker Verlag (the plate-and-rods test structure).
"""

from __future__ import annotations

import dataclasses
import itertools
import logging

import numpy as np
import scipy.sparse as sp

from ..errors import OptionError
from ..model import FEModel
from .solid import _assemble, _check_choice, _finish, _material, _positive, cell_mesh

__all__ = ["LOWER", "plate_structure"]

log = logging.getLogger(__name__)

#: Choices of the lower plate.
LOWER = ("clamped", "mass", "free")


def _lines(breaks, h: float, minimum) -> np.ndarray:
    """Grid coordinates: each interval between sorted ``breaks`` cut into ``max(m, round(len/h))`` cells."""
    out = [np.array([breaks[0]])]
    for (lo, hi), m in zip(itertools.pairwise(breaks), minimum):
        k = max(int(m), round((hi - lo) / h))
        out.append(np.linspace(lo, hi, k + 1)[1:])
    return np.concatenate(out)


def _mesh(n, a, t, hole, rod, rod_length, rod_inset, layers):
    """The hexahedral mesh and its node sets (point indices): returns ``(mesh, sets)``."""
    import skfem

    h = a / n
    c, w, r = a / 2 - rod_inset, rod / 2, hole / 2
    xb = np.array([-a / 2, -c - w, -c + w, -r, r, c - w, c + w, a / 2])
    if not np.all(np.diff(xb) > 0):
        raise OptionError("the rods must lie inside the plate, outside the hole and apart: need "
                          "hole/2 < a/2 - rod_inset - rod/2 and rod/2 < rod_inset")
    xy = _lines(xb, h, [1, 2, 1, 1, 1, 2, 1])  # at least two elements across a rod
    z = np.concatenate([_lines(np.array([-rod_length, 0.0]), h, [1])[:-1],
                        np.linspace(0.0, t, int(layers) + 1)])
    grid = skfem.MeshHex.init_tensor(xy, xy, z)
    centre = grid.p[:, grid.t].mean(axis=1)  # (3, n_cells)
    cx, cy, cz = centre
    in_plate = cz > 0
    in_hole = in_plate & (cx ** 2 + cy ** 2 < r ** 2)
    in_rod = (cz < 0) & (np.abs(np.abs(cx) - c) < w) & (np.abs(np.abs(cy) - c) < w)
    keep = (in_plate & ~in_hole) | in_rod
    used = np.unique(grid.t[:, keep])
    new = -np.ones(grid.p.shape[1], np.int64)
    new[used] = np.arange(used.size)
    mesh = skfem.MeshHex(np.ascontiguousarray(grid.p[:, used]), np.ascontiguousarray(new[grid.t[:, keep]]))
    wall = np.intersect1d(grid.t[:, in_hole], grid.t[:, keep])  # on a kept and on a hole cell
    p = mesh.p
    tol = 1e-9 * a
    sets = {
        "HOLE": new[wall],
        "TOP": np.flatnonzero(np.abs(p[2] - t) <= tol),
        "BOTTOM": np.flatnonzero(np.abs(p[2] + rod_length) <= tol),
        "RODS": np.flatnonzero(p[2] <= tol),
    }
    return mesh, sets, int(keep.sum())


def plate_structure(n: int = 56, *, a: float = 0.5, t: float = 0.02, hole: float = 0.1, rod: float = 0.03,
                    rod_length: float = 0.4, rod_inset: float = 0.06, layers: int = 2, lower: str = "clamped",
                    lower_thickness: float = 0.02, E: float = 2.1e11, nu: float = 0.3,
                    rho: float = 7850.0) -> FEModel:
    """Upper plate with a central hole, on four solid rods, with a rigid lower plate.

    Parameters
    ----------
    n : int
        Resolution: the element edge length is about ``a / n`` in the plate plane and along the
        rods (at least 2 elements across a rod). Default 56: 35,988 DOF with the clamped lower
        plate (``n=20``: 6,336 DOF; ``n=30``: 10,944; ``n=40``: 18,144; ``n=70``: 60,708).
    a : float
        Edge length of the square upper plate in m.
    t : float
        Thickness of the upper plate in m.
    hole : float
        Diameter of the central hole in m.
    rod : float
        Side of the rods' square cross-section in m.
    rod_length : float
        Length of the rods in m (from the plate's lower face down).
    rod_inset : float
        Distance of the rods' axes from the plate's edges in m.
    layers : int
        Elements through the plate thickness.
    lower : {'clamped', 'mass', 'free'}
        The rigid lower plate fixed to the ground (rods' lower faces clamped), or a free rigid
        steel plate ``a x a x lower_thickness`` (mass and rotary inertia at its centre, node set
        ``LOWER``) tied to the rods' lower faces by an RBE2, or no lower plate (the rods' lower
        faces free).
    lower_thickness : float
        Thickness of the lower plate in m (``lower='mass'`` only).
    E, nu, rho : float
        Young's modulus (Pa), Poisson's ratio and density (kg/m³); default steel.

    Returns
    -------
    FEModel
        Translational DOF of the solid (plus the 6 DOF of the ``LOWER`` master for
        ``lower='mass'``), SI units. Node sets: ``ALL``; ``HOLE`` (the nodes on the hole's wall,
        all through-thickness levels: the interface); ``TOP`` (upper face of the plate);
        ``RODS`` (the rods' nodes, including those on the plate's lower face); ``BOTTOM`` (the
        rods' lower end faces; clamped by default); ``LOWER`` (``lower='mass'``).

    Raises
    ------
    OptionError
        On non-positive sizes, inconsistent geometry (rods overlapping the hole or the edges),
        a bad ``lower`` choice or material constants.

    Examples
    --------
    >>> from flexmor.models import plate_structure
    >>> plate_structure(20).n_dof
    6336
    """
    _check_choice("lower", lower, LOWER)
    _positive(a=a, t=t, hole=hole, rod=rod, rod_length=rod_length, rod_inset=rod_inset,
              lower_thickness=lower_thickness)
    if int(n) != n or n < 2:
        raise OptionError(f"n must be an integer >= 2, got {n!r}")
    if int(layers) != layers or layers < 1:
        raise OptionError(f"layers must be an integer >= 1, got {layers!r}")
    lam, mu = _material(E, nu, rho)
    mesh, sets, n_cells = _mesh(int(n), a, t, hole, rod, rod_length, rod_inset, layers)
    K, M, xyz = _assemble(mesh, "hex", lam, mu, rho)
    sets = {name: idx.astype(np.int64) + 1 for name, idx in sets.items()}
    name = f"plate-structure-n{int(n)}" + ("" if lower == "clamped" else f"-{lower}")
    model = _finish(name, K, M, xyz, sets, "BOTTOM" if lower == "clamped" else None, cells=cell_mesh(mesh))
    if lower == "mass":
        model = _hang_lower_plate(model, a, lower_thickness, rod_length, rho)
    log.info("%s: %d hexahedra, %d nodes, %d DOF, hole wall %d nodes", name, n_cells, model.n_nodes,
             model.n_dof, model.node_sets["HOLE"].size)
    return model


def _hang_lower_plate(model: FEModel, a: float, thickness: float, rod_length: float, rho: float) -> FEModel:
    """RBE2 from the rods' lower faces to a master carrying the rigid lower plate's inertia."""
    from ..couplings import couple

    zc = -rod_length - thickness / 2
    coupled = couple(model, [f"BOTTOM@rbe2[0,0,{zc!r}]"])
    (key, master), = coupled.masters.items()
    m = rho * a * a * thickness
    inertia = [m * (a * a + thickness ** 2) / 12] * 2 + [m * a * a / 6]
    cm = coupled.model
    eqs = [cm.dof_index(master, d) for d in range(1, 7)]
    extra = sp.csr_matrix((np.array([m, m, m, *inertia]), (eqs, eqs)), shape=cm.M.shape)
    sets = {k: v for k, v in cm.node_sets.items() if k != key}
    sets["LOWER"] = np.array([master], dtype=np.int64)
    return dataclasses.replace(cm, M=(cm.M + extra).tocsr(), node_sets=sets, name=model.name)
