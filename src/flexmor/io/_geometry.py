"""The stiffness matrix and the node coordinates of a model cross-check each other.

An elastic structure stores no strain energy in a rigid motion: ``K u = 0`` for every rigid
translation and every rigid rotation ``u = ω × (x - x_o)`` built from its node coordinates
(on rotational DOF: ``ω``). Equation by equation this holds wherever the matrix has all the
columns of the equation, i.e. away from DOF removed by supports. The translations need no
coordinates: an equation whose terms do not sum to zero in a direction has lost columns (a
support or a spring to ground is beside its node), and its node is not checked. At every other
node the rotations must give zero too, to the rounding of the written values, with the lever
arms ``x_j - x_i`` of the equation's own terms:

    r_i = Σ_j K_ij c_j,   c_j = (e_a × (x_j - x_i))_(dir j) on translations, [dir j = a + 3] on rotations,

measured against ``s_i = Σ_j |K_ij c_j|``. A node coordinate changed into another valid number
or a node table of another mesh (renumbered, other units on an axis) shows as ``|r_i| / s_i``
far above the rounding level of the rest of the model (its median), at that node and its
neighbours; no reader can see it otherwise (a coordinate has no second copy). What does not
follow a rigid rotation shows the same way and is named by the warning as the other cause: a
directional spring between two nodes apart (CalculiX ``SPRING2``), a constraint equation between
DOF of nodes apart (``*EQUATION`` tying ``u_x`` of two nodes; rigid-body constraints such as
``*RIGID BODY`` follow it). For a free body this is worth knowing in any case: a rigid motion
built from the coordinates strains the body there. A median ratio
above :data:`GEOMETRY_GLOBAL` gives one warning for the whole node table (another mesh, or a
stiffness with stress stiffening). A changed off-diagonal stiffness value makes its two equations
no longer sum to zero, which alone would look like a support; but it does so by the same amount in
each, in the direction of the other, and at no other equation of their nodes: such a pair is named
with the value the file held (:func:`changed_entries`). What the check cannot see: a changed
diagonal value (it looks like a spring to ground), a value changed beside a support, the
coordinates of nodes at supports or without equations, and a changed mass value (which
:func:`flexmor.io._mass.check_mass_directions` compares across directions).

Not checked: matrices whose equations mostly do not sum to zero beyond rounding
(:data:`TRANSLATION_ROUNDING`: an axisymmetric model, whose radial translation strains the hoop, a
random test matrix, values written with fewer than about six digits); nodes whose DOF are in a local frame
(``node_frames``) and DOF that are neither translations nor rotations (scalar points), with the
equations that reach them. The cost is two sparse products with a few columns (0.05 s at 35,000
DOF) and a term-by-term pass over the equations above :data:`GEOMETRY_FLOOR`.
"""

from __future__ import annotations

import warnings

import numpy as np
import scipy.sparse as sp

from ..errors import FlexmorWarning
from ..rigid import rigid_motions
from ._sparse import row_blocks

__all__ = ["geometry_residual", "geometry_check", "changed_entries", "describe_geometry_check",
           "check_stiffness_geometry", "cell_corners", "inverted_cells", "check_cells", "FLAT_CELL", "GEOMETRY_FLOOR",
           "GEOMETRY_FACTOR", "GEOMETRY_GLOBAL", "TRANSLATION_ROUNDING"]

#: Ratio |r_i| / s_i below which an equation follows a rigid rotation whatever the model's rounding.
GEOMETRY_FLOOR = 1e-9
#: An equation is named when its ratio exceeds this multiple of the model's median ratio (its rounding level).
GEOMETRY_FACTOR = 1e4
#: Median translation ratio above which the matrix is taken as one that no rigid translation leaves
#: free (an axisymmetric model: a radial translation strains the hoop; a random test matrix; a model
#: mostly beside supports; values written with fewer than ~6 digits): the check is skipped.
TRANSLATION_ROUNDING = 1e-6
#: A median ratio above this is no rounding of written coordinates (8-character fields give ~1e-4 at worst):
#: the whole node table disagrees with the matrix.
GEOMETRY_GLOBAL = 1e-2


def geometry_residual(model, *, sums: bool = False) -> tuple:
    """Per equation: the translation ratio, the rotation ratio, the offset (``(n_dof,)`` each, NaN: not defined).

    ``translation[i] = max_b |Σ_j K_ij [dir j = b]| / max_b Σ_j |K_ij| [dir j = b]`` (no coordinates);
    ``rotation[i] = max_a |r_ia| / s_i`` with ``r`` as in the module text and the scale
    ``s_i = max(h max_b Σ_j |K_ij| [dir j = b], max_a Σ_j |K_ij| [dir j = a + 3])``, ``h`` the median
    distance between the nodes that share a term. NaN on equations without terms or that reach a DOF
    that is no translation or rotation or belongs to a node with a local frame. ``offset[i] = max_a |r_ia| / K_ii``
    (a length, or an angle on a rotational equation): the displacement that would balance the residual, largest
    at a node whose coordinate is off (``r = K_pp (ω × δ)`` there, ``K_qp (ω × δ)`` beside it). Two sparse products
    with a few columns: ``r`` is formed from rotations about the centroid, ``K (ω × (x - x_o))``,
    less the translation sums times ``ω × (x_i - x_o)`` (rounding ``ε |x - x_o| / h`` of the scale).
    ``sums=True`` adds ``(T, S)``: per equation and direction the translation sum ``Σ_j K_ij [dir j = b]`` and
    its scale ``Σ_j |K_ij| [dir j = b]``, shape ``(n_dof, 3)`` each.
    """
    n = model.n_dof
    K = sp.csr_matrix(model.K)
    d = np.asarray(model.dofs[:, 1], dtype=np.int64)
    at = model.node_xyz(model.dofs[:, 0])
    xyz = at - at.mean(axis=0)
    bad = (d < 1) | (d > 6)
    if model.node_frames:
        bad |= np.isin(model.dofs[:, 0], np.fromiter(model.node_frames, dtype=np.int64))
    X = rigid_motions(model)  # translations, rotations e_a × (x - x_o) about the same centroid x_o
    E = np.zeros((n, 7))  # which terms count: the direction of each column, and the left-out DOF
    E[:, :3] = X[:, :3]
    E[:, 3:6] = d[:, None] == np.arange(4, 7)
    E[:, 6] = bad
    KX = K @ X
    S = np.empty((n, 7))
    for start, stop in row_blocks(K):  # |K| @ E by row blocks: no second copy of K's values at any size
        block = K[start:stop]
        block.data = np.abs(block.data)
        S[start:stop] = block @ E
    T = KX[:, :3]
    R = KX[:, 3:] - np.stack([T[:, 2] * xyz[:, 1] - T[:, 1] * xyz[:, 2],   # Σ_b T_ib (e_a × x_i)_b
                              T[:, 0] * xyz[:, 2] - T[:, 2] * xyz[:, 0],
                              T[:, 1] * xyz[:, 0] - T[:, 0] * xyz[:, 1]], axis=1)
    # the typical distance between nodes that share a term (a sample of the terms)
    pick = np.random.default_rng(0).integers(0, K.nnz, min(K.nnz, 200_000)) if K.nnz else np.zeros(0, int)
    rows = np.searchsorted(K.indptr, pick, side="right") - 1
    dist = np.linalg.norm(xyz[K.indices[pick]] - xyz[rows], axis=1)
    h = float(np.median(dist[dist > 0])) if np.any(dist > 0) else 1.0
    with np.errstate(divide="ignore", invalid="ignore"):
        translation = np.abs(T).max(axis=1) / S[:, :3].max(axis=1)
        rotation = np.abs(R).max(axis=1) / np.maximum(h * S[:, :3].max(axis=1), S[:, 3:6].max(axis=1))
    skip = bad | (S[:, 6] > 0)
    translation[skip] = np.nan
    rotation[skip] = np.nan
    # equations above the floor again with their own lever arms (a node far off spoils the centroid's rounding)
    again = np.flatnonzero(rotation > GEOMETRY_FLOOR)
    offset = np.full(n, np.nan)
    if again.size:
        diag = np.abs(K.diagonal())
        for start, stop in row_blocks(K):  # term by term within row blocks: bounded work arrays at any size
            rows = again[(again >= start) & (again < stop)]
            if rows.size:
                rotation[rows], r = _local_rotation(K[rows], rows, d, at)
                with np.errstate(divide="ignore", invalid="ignore"):
                    offset[rows] = r / diag[rows]
    if sums:
        return translation, rotation, offset, T, S[:, :3]
    return translation, rotation, offset


def _local_rotation(Kr, rows, d, xyz) -> tuple[np.ndarray, np.ndarray]:
    """``max_a |r_ia| / max_a s_ia`` and ``max_a |r_ia|`` of the equations ``rows`` (``Kr = K[rows]``), term by
    term with ``x_j - x_i``."""
    n = rows.size
    r = np.repeat(np.arange(n), np.diff(Kr.indptr))
    dj = d[Kr.indices]
    L = xyz[Kr.indices] - xyz[rows[r]]
    ex, ey, ez = (dj == 1), (dj == 2), (dj == 3)
    lever = (np.where(ey, -L[:, 2], 0.0) + np.where(ez, L[:, 1], 0.0),   # (e_x × L) on y, z
             np.where(ex, L[:, 2], 0.0) + np.where(ez, -L[:, 0], 0.0),   # (e_y × L) on x, z
             np.where(ex, -L[:, 1], 0.0) + np.where(ey, L[:, 0], 0.0))   # (e_z × L) on x, y
    R = np.zeros((n, 3))
    S = np.zeros((n, 3))
    for a in range(3):
        t = Kr.data * (lever[a] + (dj == a + 4))
        R[:, a] = np.bincount(r, t, n)
        S[:, a] = np.bincount(r, np.abs(t), n)
    r = np.abs(R).max(axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        return r / S.max(axis=1), r


def geometry_check(model) -> dict:
    """The outcome of the check without a warning (module text).

    Returns
    -------
    dict
        ``checked`` (nodes checked), ``nodes`` (total with equations), ``level`` (median rotation ratio
        of the checked nodes), ``named`` (node ids where ``K`` does not follow the rotation, the one
        that would have to move most first), ``worst`` (the ratio at the first), ``whole`` (True when
        most nodes disagree), ``skipped`` (why nothing was checked, or ``""``), ``changed``
        (:func:`changed_entries`: stiffness entries whose two equations no longer sum to zero by the same amount).
    """
    out = {"checked": 0, "nodes": 0, "level": None, "named": [], "worst": None, "whole": False, "skipped": "",
           "changed": []}
    if model.dofs is None or model.n_nodes == 0 or model.n_dof == 0 or model.K.nnz == 0:
        return dict(out, skipped="no node coordinates or no stiffness")
    translation, rotation, offset, T, S = geometry_residual(model, sums=True)
    node = np.asarray(model.dofs[:, 0])
    out["nodes"] = int(np.unique(node).size)
    known = np.isfinite(translation)
    if not known.any():
        return dict(out, skipped="no equation of translations and rotations in the global frame")
    level = float(np.median(translation[known]))
    if level > TRANSLATION_ROUNDING:  # most equations do not sum to zero beyond rounding: nothing to compare with
        return dict(out, skipped=f"the equations do not sum to zero in a translation (median {level:.0e}: "
                                 "axisymmetric, mostly supported, or values written with few digits)")
    supported = np.unique(node[known & (translation > max(GEOMETRY_FLOOR, GEOMETRY_FACTOR * level))])
    out["changed"] = changed_entries(model.K, model.dofs, T, S, known, max(GEOMETRY_FLOOR, GEOMETRY_FACTOR * level))
    # every equation of a checked node must be complete (a node beside a support has some that are not)
    checked = known & np.isfinite(rotation) & ~np.isin(node, supported)
    if not checked.any():
        return dict(out, skipped="every node is beside a support or a spring to ground")
    level = float(np.median(rotation[checked]))
    out.update(checked=int(np.unique(node[checked]).size), level=level)
    if level > GEOMETRY_GLOBAL:
        named = [int(k) for k in np.unique(node[checked & (rotation > GEOMETRY_GLOBAL)])]
        return dict(out, named=named, worst=level, whole=True)
    off = checked & (rotation > max(GEOMETRY_FLOOR, GEOMETRY_FACTOR * level))
    if off.any():
        # the node with the largest offset first: a changed coordinate shows most at its own node
        order = np.argsort(-np.nan_to_num(offset[off], nan=0.0), kind="stable")
        out.update(named=list(dict.fromkeys(int(k) for k in node[off][order])), worst=float(rotation[off][order[0]]))
    return out


def changed_entries(K, dofs, T, S, known, threshold: float) -> list[tuple[int, int, float, float]]:
    """Stiffness entries changed after they were written, as ``(i, j, K_ij, excess)`` (``i < j``).

    An entry ``K_ij`` (``i != j``) stored once and changed by ``δ`` changes two translation sums by
    exactly ``δ``: that of equation ``i`` in the direction of ``j`` and that of equation ``j`` in the
    direction of ``i``. Beside a support or a spring to ground an equation's sums do not vanish either,
    but there they rarely do so in one direction of one equation of a node alone, and never pair up so:
    an entry is named when equations ``i`` and ``j`` are the only ones of their nodes (or of their one
    node) whose sum exceeds ``threshold`` of its scale ``S``, each in the direction of the other, by the
    same amount (to 1e-6),
    and no other such lone equation has that amount (a row of equal springs to ground, or of nodes
    beside a support of one direction in a regular mesh, gives many). A changed diagonal entry looks
    like a spring to ground and is not named.
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        hot = known[:, None] & (np.abs(T) > threshold * S)
    rows = np.flatnonzero(hot.any(axis=1))
    if rows.size < 2:
        return []
    node = np.asarray(dofs[:, 0])
    d = np.asarray(dofs[:, 1], dtype=np.int64)
    nodes, count = np.unique(node[rows], return_counts=True)
    per_node = count[np.searchsorted(nodes, node[rows])]
    # equations off in one direction, the only one of their node or one of two (an entry within a node)
    lone = rows[(per_node <= 2) & (hot[rows].sum(axis=1) == 1)]
    if lone.size < 2:
        return []
    per_node = dict(zip(nodes.tolist(), count.tolist()))
    a = np.argmax(hot[lone], axis=1) + 1  # the direction of each lone equation's sum
    t = T[lone, a - 1]
    order = np.argsort(t, kind="stable")
    lone, a, t = lone[order], a[order], t[order]
    close = np.abs(np.diff(t)) <= 1e-6 * np.abs(t[1:])  # neighbours in value with the same amount
    K = sp.csr_matrix(K)
    out = []
    for k in np.flatnonzero(close):
        if (k > 0 and close[k - 1]) or (k + 1 < close.size and close[k + 1]):
            continue  # three or more alike: springs or a support, not one value
        i, j = int(lone[k]), int(lone[k + 1])
        alone = per_node[node[i]] == per_node[node[j]] == (2 if node[i] == node[j] else 1)
        if alone and d[j] == a[k] and a[k + 1] == d[i] and j in K.indices[K.indptr[i]:K.indptr[i + 1]]:
            i, j = min(i, j), max(i, j)
            out.append((i, j, float(K[i, j]), float(t[k])))
    return out


def describe_geometry_check(c: dict) -> str:
    """One line for ``flexmor info``: what the check compared, and its outcome."""
    if c["skipped"]:
        return f"K vs node coordinates not checked: {c['skipped']}"
    rest = " (the others beside supports or springs)" if c["checked"] < c["nodes"] else ""
    head = f"K vs node coordinates: a rigid rotation at {c['checked']} of {c['nodes']} nodes{rest}"
    if c.get("changed"):
        i, j = c["changed"][0][:2]
        head = f"K entry ({i + 1}, {j + 1}) changed? (see the warning); {head}"
    if c["whole"]:
        return f"{head}: disagrees at {len(c['named'])} (median {c['level']:.1e} of the terms), see the warning"
    if c["named"]:
        return (f"{head}: median {c['level']:.0e} of the terms, but {c['worst']:.1e} at node {c['named'][0]} "
                f"(and {len(c['named']) - 1} beside it), see the warning")
    return f"{head}: median {c['level']:.0e} of the terms (rounding)"


def check_stiffness_geometry(model, where: str = "") -> list[int]:
    """Warn (FlexmorWarning) where ``K`` does not follow a rigid rotation about the node coordinates.

    Checks the equations of nodes whose equations all sum to zero in every direction (no support
    or spring to ground beside them; module text). Returns the ids of the nodes named (empty: the
    check passed or could not be made: no node table, no equation to check).
    """
    c = geometry_check(model)
    nodes, where = c["named"], where or model.source or model.name
    for i, j, v, excess in c["changed"]:
        warnings.warn(FlexmorWarning(
            f"{where}: stiffness entry ({i + 1}, {j + 1}) = {v:.10g} ({model.describe_dof(i)}, "
            f"{model.describe_dof(j)}): its two equations are the only ones of their nodes whose terms do not sum "
            f"to zero, each by {excess:.6g} in the direction of the other; a changed value (written as "
            f"{v - excess:.10g}?), or two springs to ground of the same stiffness there"), stacklevel=3)
    if not nodes:
        return []
    if c["whole"]:
        warnings.warn(FlexmorWarning(
            f"{where}: the stiffness matrix and the node coordinates disagree at {len(nodes)} of {c['checked']} "
            f"checked nodes: K times a rigid rotation about these coordinates is {c['level']:.1e} of its terms "
            f"(median); the coordinates belong to another mesh (other node numbers, or other units on an axis), or "
            f"the stiffness holds a stress stiffness (a perturbation step); rigid-body modes, couplings and exports "
            f"use these coordinates"), stacklevel=3)
        return nodes
    more = ""
    if len(nodes) > 1:
        more = (f" and {len(nodes) - 1} node(s) beside it ({', '.join(str(k) for k in nodes[1:9])}"
                f"{', ...' if len(nodes) > 9 else ''})")
    warnings.warn(FlexmorWarning(
        f"{where}: the stiffness matrix and the node coordinates disagree at node "
        f"{nodes[0]}{more}: K times a rigid rotation about these coordinates is {c['worst']:.1e} of its "
        f"terms there, {c['level']:.0e} at the other {c['checked'] - len(nodes)} checked nodes. Either something "
        f"there does not follow a rigid rotation (a constraint equation or a directional spring between nodes "
        f"apart: then a rigid motion built from these coordinates strains the body there), or a node coordinate "
        f"or stiffness value was changed, or the coordinates belong to another mesh"), stacklevel=3)
    return nodes


#: Corner triples of solid cells in VTK's node order, each right-handed in a cell of positive volume:
#: ``det[x_a - x_c, x_b - x_c, x_t - x_c] > 0`` at corner ``c`` (hexahedra: the three edges at each corner;
#: tetrahedra: one, their corners span the cell). Quadratic cells: their corners.
_CORNERS = {
    "hexahedron": ((0, 1, 3, 4), (1, 2, 0, 5), (2, 3, 1, 6), (3, 0, 2, 7),
                   (4, 7, 5, 0), (5, 4, 6, 1), (6, 5, 7, 2), (7, 6, 4, 3)),
    "tetra": ((0, 1, 2, 3),),
}
_CORNERS["hexahedron20"] = _CORNERS["hexahedron27"] = _CORNERS["hexahedron"]
_CORNERS["tetra10"] = _CORNERS["tetra"]


#: Scaled corner Jacobian ``det[e1, e2, e3] / (|e1| |e2| |e3|)`` below which a cell counts as nearly flat there
#: (a corner angle below about half a degree; 1 for a right-angled corner, 0.14 or more in the shared meshes).
FLAT_CELL = 1e-2


def cell_corners(model) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Per block of hexahedra or tetrahedra of ``model.mesh``: ``(cell nodes, worst, corner node)``, per
    cell its smallest scaled corner Jacobian ``det[e1, e2, e3] / (|e1| |e2| |e3|)`` over the corners' edge
    triples (:data:`_CORNERS`; 1 at a right-angled corner, negative where the cell is inside out) and the
    corner where it is. Other cell types are not checked, nor a block whose cells are mostly left-handed (a
    mesh written in the other orientation: damage turns a few cells, not most), nor a corner with an edge of
    length 0 (a collapsed hexahedron)."""
    mesh = getattr(model, "mesh", None)
    out = []
    for block in (mesh.blocks if mesh is not None and model.node_ids.size else ()):
        triples = _CORNERS.get(block.type)
        if triples is None or not len(block.nodes):
            continue
        x = model.node_xyz(block.nodes[:, :8 if block.type.startswith("hexa") else 4].ravel()).reshape(
            len(block.nodes), -1, 3)
        low = np.full(len(block.nodes), np.inf)
        at = np.zeros(len(block.nodes), dtype=np.int64)
        for c, a, b, t in triples:
            e1, e2, e3 = x[:, a] - x[:, c], x[:, b] - x[:, c], x[:, t] - x[:, c]
            det = np.einsum("ij,ij->i", np.cross(e1, e2), e3)
            scale = np.linalg.norm(e1, axis=1) * np.linalg.norm(e2, axis=1) * np.linalg.norm(e3, axis=1)
            with np.errstate(divide="ignore", invalid="ignore"):
                sj = np.where(scale > 0, det / scale, np.inf)
            lower = sj < low
            low[lower], at[lower] = sj[lower], block.nodes[lower, c]
        if 2 * np.count_nonzero(low < -1e-8) <= len(low):  # else the other orientation convention, not damage
            out.append((block.nodes, low, at))
    return out


def _select(parts, keep) -> tuple[list, np.ndarray]:
    """``(cell nodes, corner node)`` of the cells of ``parts`` (:func:`cell_corners`) whose worst corner ``keep``
    selects."""
    cells, corners = [], []
    for nodes, worst, at in parts:
        bad = keep(worst)
        cells += list(nodes[bad])
        corners.append(at[bad])
    return cells, np.concatenate(corners) if corners else np.zeros(0, np.int64)


def inverted_cells(model) -> tuple[list, np.ndarray]:
    """``(cell nodes, corner node)`` of the cells of :func:`cell_corners` turned inside out at a corner (its
    edge triple left-handed beyond rounding, scaled Jacobian below -1e-8): the worst corner of each."""
    return _select(cell_corners(model), lambda worst: worst < -1e-8)


def check_cells(model, where: str = "") -> list[int]:
    """Warn (FlexmorWarning) about hexahedra and tetrahedra that the node coordinates turn inside out or
    leave nearly flat at a corner (:data:`FLAT_CELL`).

    FE programs refuse an inverted element (a trilinear hexahedron distorted enough to be inside out
    at a corner only is flagged by them as distorted), so the deck's coordinates are probably not
    those it meshed: a changed coordinate (also of a node without equations, which the stiffness
    cannot check) or the nodes of another mesh. A nearly flat corner (an angle below about half a
    degree) is a node moved far without turning its cell inside out, or a degenerate element. Returns
    the corner nodes named (empty: none, or no such cells).
    """
    where = where or model.source or model.name
    parts = cell_corners(model)  # the corners once, for both warnings
    named: list[int] = []
    for keep, what, why in (
            (lambda w: (w >= -1e-8) & (w < FLAT_CELL), "nearly flat at a corner",
             f"at node {{}}: an angle there below about half a degree, scaled Jacobian < {FLAT_CELL:g}): a node "
             "coordinate changed (also one of a node without equations, which the stiffness cannot check), or a "
             "degenerate element of the mesh"),
            (lambda w: w < -1e-8, "turned inside out by the node coordinates",
             "inverted at node {}): FE programs refuse an inverted element (or flag a corner this distorted), so "
             "a node coordinate was probably changed or the nodes belong to another mesh")):
        cells, corners = _select(parts, keep)
        if not cells:
            continue
        first = ", ".join(str(int(k)) for k in cells[0][:8])
        warnings.warn(FlexmorWarning(
            f"{where}: {len(cells)} element(s) {what} (the first with corner nodes {first}, "
            f"{why.format(int(corners[0]))}; the mesh shown and node sets use these coordinates"), stacklevel=3)
        named += [int(k) for k in corners]
    return list(dict.fromkeys(named))
