"""Parametric 3D linear-elastic solids (box meshes) assembled with scikit-fem.

The models are boxes meshed with a structured grid of hexahedra (or tetrahedra), isotropic
linear elasticity and a consistent mass matrix. Their size is set by one resolution
parameter ``n`` so that the same geometry can be built with a few hundred or a million
degrees of freedom, which makes them the test bodies of the demo and the benchmarks.

Equation numbering follows scikit-fem's vector elements: equation ``3 s + d`` is direction
``d`` (0, 1, 2 = x, y, z) of scalar degree of freedom ``s``; for the 8-node hexahedron and
the 4-node tetrahedron ``s`` is the mesh point index and the node id is ``s + 1``. Clamped
degrees of freedom are removed from the matrices (as CalculiX does when it writes them), so
``FEModel.dofs`` lists the free equations only.

The stiffness matrix is assembled from the six scalar matrices
``G_ab[p, q] = int d_a phi_p d_b phi_q dV`` of the scalar element,

    K[(p, i), (q, j)] = lambda G_ij + mu (delta_ij tr G + G_ji),

which equals scikit-fem's ``linear_elasticity`` form on the vector element (the tests check
this) but needs a ninth of the quadrature work and memory.

References
----------
T. J. R. Hughes, *The Finite Element Method: Linear Static and Dynamic Finite Element
Analysis*, Dover, 2000, ch. 2-4.

T. Gustafsson and G. D. McBain, scikit-fem: A Python package for finite element assembly,
*Journal of Open Source Software* 5(52), 2369, 2020.
"""

from __future__ import annotations

import logging
import time

import numpy as np
import scipy.sparse as sp

from ..errors import ModelError, OptionError
from ..mesh import CellBlock, Mesh
from ..model import FEModel

__all__ = ["ELEMENTS", "KINDS", "cantilever", "plate", "size_for_dofs"]

log = logging.getLogger(__name__)

#: Element choices: name -> (scikit-fem mesh class, element class, quadrature order, description).
ELEMENTS = {
    "hex": ("MeshHex", "ElementHex1", 2, "8-node trilinear hexahedron, 2x2x2 Gauss (like C3D8)"),
    "hex27": ("MeshHex", "ElementHex2", 4, "27-node triquadratic hexahedron, 3x3x3 Gauss"),
    "tet": ("MeshTet", "ElementTetP1", 2, "4-node linear tetrahedron (constant strain)"),
}

#: Model kinds known to :func:`size_for_dofs`.
KINDS = ("cantilever", "plate")

#: Relative tolerance for locating nodes on the faces of the box.
_GEOM_RTOL = 1e-9


# -- helpers -----------------------------------------------------------------------------------
def _check_choice(name: str, value: str, allowed) -> str:
    if value not in allowed:
        raise OptionError(f"{name}={value!r} is not allowed; choose one of: {', '.join(allowed)}")
    return value


def _positive(**kw) -> None:
    for k, v in kw.items():
        if not (np.isfinite(v) and v > 0):
            raise OptionError(f"{k} must be a finite positive number, got {v!r}")


def _material(E: float, nu: float, rho: float) -> tuple[float, float]:
    _positive(E=E, rho=rho)
    if not (-1.0 < nu < 0.5):
        raise OptionError(f"Poisson's ratio nu must lie in (-1, 0.5), got {nu!r}")
    lam = E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))
    mu = E / (2.0 * (1.0 + nu))
    return lam, mu


def _count(n, value: float, unit: float) -> int:
    """Number of elements over ``value`` when ``n`` elements span ``unit``."""
    return max(1, round(n * value / unit))


def _box_mesh(element: str, nx: int, ny: int, nz: int, lx: float, ly: float, lz: float):
    import skfem

    x = np.linspace(0.0, lx, nx + 1)
    y = np.linspace(0.0, ly, ny + 1)
    z = np.linspace(0.0, lz, nz + 1)
    return getattr(skfem, ELEMENTS[element][0]).init_tensor(x, y, z)


def _assemble(mesh, element: str, lam: float, mu: float, rho: float):
    """Stiffness and consistent mass on the vector element; returns ``K, M, node_xyz``."""
    import skfem

    _, ename, intorder, _ = ELEMENTS[element]
    t0 = time.perf_counter()
    basis = skfem.Basis(mesh, getattr(skfem, ename)(), intorder=intorder)
    ns = basis.N
    # scikit-fem's assemble() drops exact zeros, which would give the forms different
    # sparsity patterns; build the CSR matrices from the COO data on common indices instead.
    rows = cols = None

    def csr(form):
        nonlocal rows, cols
        coo = form.coo_data(basis)
        if rows is None:
            rows, cols = coo.indices[0], coo.indices[1]
        A = sp.coo_matrix((coo.data, (rows, cols)), shape=(ns, ns)).tocsr()
        A.sum_duplicates()
        return A

    forms = {}
    for a in range(3):
        for b in range(a, 3):
            # G_ab[p, q] = int d_a phi_p d_b phi_q ; p = test (row), q = trial (column)
            forms[a, b] = csr(skfem.BilinearForm(lambda u, v, w, a=a, b=b: v.grad[a] * u.grad[b]))
    mass = csr(skfem.BilinearForm(lambda u, v, w: u * v))
    rows = cols = None  # free the index arrays
    t1 = time.perf_counter()

    pattern = forms[0, 0]
    for G in [*forms.values(), mass]:
        if not (np.array_equal(G.indptr, pattern.indptr) and np.array_equal(G.indices, pattern.indices)):
            raise ModelError("scalar element matrices do not share one sparsity pattern")  # pragma: no cover
    # G_ba = G_ab^T: re-sort the transposes into the same (symmetric) pattern
    gT = {key: G.data for key, G in forms.items()}
    for a in range(3):
        for b in range(a + 1, 3):
            Gt = forms[a, b].transpose().tocsr()
            Gt.sort_indices()
            if not (np.array_equal(Gt.indptr, pattern.indptr) and np.array_equal(Gt.indices, pattern.indices)):
                raise ModelError("the scalar sparsity pattern is not symmetric")  # pragma: no cover
            gT[b, a] = Gt.data
    trace = gT[0, 0] + gT[1, 1] + gT[2, 2]
    blocks = {}
    for i in range(3):
        for j in range(3):
            blk = lam * gT[i, j] + mu * gT[j, i]
            if i == j:
                blk = blk + mu * trace
            blocks[i, j] = blk
    K = _interleave(pattern.indptr, pattern.indices, ns, blocks)
    mblocks = {(i, j): (rho * mass.data if i == j else None) for i in range(3) for j in range(3)}
    M = _interleave(pattern.indptr, pattern.indices, ns, mblocks)
    t2 = time.perf_counter()
    log.info("assembled %d equations (%d elements, %s) in %.2f s (quadrature %.2f s)",
             3 * ns, mesh.t.shape[1], element, t2 - t0, t1 - t0)
    xyz = np.ascontiguousarray(basis.doflocs.T)
    return K, M, xyz


#: meshio node k of a hexahedron is scikit-fem's local node HEX_TO_MESHIO[k] (as skfem.io.meshio).
HEX_TO_MESHIO = [0, 3, 6, 2, 1, 5, 7, 4]


def cell_mesh(mesh) -> Mesh:
    """The connectivity of a scikit-fem hexahedral or tetrahedral mesh as a :class:`Mesh`.

    The cells are the mesh's (corner) cells in meshio's node order; node ids are the point
    indices + 1 (the numbering of the built-in models; corners come first also for ``hex27``).
    """
    t = np.asarray(mesh.t, dtype=np.int64) + 1
    if t.shape[0] == 8:
        return Mesh([CellBlock("hexahedron", t[HEX_TO_MESHIO].T)])
    return Mesh([CellBlock("tetra", t.T)])


def _interleave(indptr, indices, ns: int, blocks) -> sp.csr_matrix:
    """Vector CSR matrix with rows/columns ``3 s + d`` from 3x3 blocks on one scalar pattern.

    ``blocks[i, j]`` is the data array of block (i, j) on the pattern (``indptr``,
    ``indices``), or None for a zero block (then the columns are left out).
    """
    dirs = [[j for j in range(3) if blocks[i, j] is not None] for i in range(3)]
    nnz_s = indices.size
    k = np.diff(indptr)  # entries per scalar row
    row_of = np.repeat(np.arange(ns, dtype=np.int64), k)
    e_local = np.arange(nnz_s, dtype=np.int64) - indptr[:-1].astype(np.int64)[row_of]
    widths = [len(d) for d in dirs]
    # vector row 3p+i holds widths[i] * k[p] entries
    row_len = np.stack([w * k for w in widths], axis=1).reshape(-1)
    indptr_v = np.zeros(3 * ns + 1, dtype=np.int64)
    np.cumsum(row_len, out=indptr_v[1:])
    nnz = int(indptr_v[-1])
    itype = np.int32 if max(nnz, 3 * ns) < np.iinfo(np.int32).max else np.int64
    data = np.empty(nnz, dtype=np.float64)
    ind = np.empty(nnz, dtype=itype)
    col3 = 3 * indices.astype(itype)
    for i in range(3):
        start = indptr_v[3 * row_of + i]
        w = widths[i]
        for slot, j in enumerate(dirs[i]):
            pos = start + w * e_local + slot
            data[pos] = blocks[i, j]
            ind[pos] = col3 + j
    return sp.csr_matrix((data, ind, indptr_v.astype(itype)), shape=(3 * ns, 3 * ns))


def _on(coord: np.ndarray, value: float, scale: float) -> np.ndarray:
    return np.abs(coord - value) <= _GEOM_RTOL * scale


def _build(name: str, element: str, divisions, extent, E, nu, rho, fixed_set: str | None,
           set_defs) -> FEModel:
    lam, mu = _material(E, nu, rho)
    _check_choice("element", element, ELEMENTS)
    nx, ny, nz = (int(v) for v in divisions)
    if min(nx, ny, nz) < 1:
        raise OptionError(f"element divisions must be >= 1, got {(nx, ny, nz)}")
    mesh = _box_mesh(element, nx, ny, nz, *extent)
    K, M, xyz = _assemble(mesh, element, lam, mu, rho)
    node_ids = np.arange(1, xyz.shape[0] + 1, dtype=np.int64)
    scale = max(extent)
    sets = {set_name: node_ids[_on(xyz[:, axis], value, scale)] for set_name, (axis, value) in set_defs.items()}
    return _finish(name, K, M, xyz, sets, fixed_set, cells=cell_mesh(mesh))


def _finish(name: str, K, M, xyz: np.ndarray, sets: dict, fixed_set: str | None, cells: Mesh | None = None) -> FEModel:
    """The FEModel of assembled matrices: node ids ``s + 1``, set ``ALL`` added, ``fixed_set`` removed,
    element connectivity ``cells``."""
    ns = xyz.shape[0]
    node_ids = np.arange(1, ns + 1, dtype=np.int64)
    sets = {"ALL": node_ids, **sets}
    dofs = np.column_stack([np.repeat(node_ids, 3), np.tile(np.arange(1, 4, dtype=np.int64), ns)])
    if fixed_set is not None:
        fixed_nodes = np.zeros(ns, dtype=bool)
        fixed_nodes[sets[fixed_set] - 1] = True
        free = ~np.repeat(fixed_nodes, 3)
        K = K[free][:, free]
        M = M[free][:, free]
        dofs = dofs[free]
    model = FEModel(M=M, K=K, node_ids=node_ids, xyz=xyz, dofs=dofs, node_sets=sets,
                    name=name, source="built-in", mesh=cells)
    return model


# -- public models -----------------------------------------------------------------------------
def cantilever(n: int = 4, *, length: float = 1.0, width: float = 0.1, height: float = 0.1,
               E: float = 2.1e11, nu: float = 0.3, rho: float = 7850.0, element: str = "hex",
               clamped: bool = True, divisions: tuple[int, int, int] | None = None) -> FEModel:
    """A solid beam along x, clamped at ``x = 0`` or free-free.

    The box ``[0, length] x [0, width] x [0, height]`` is meshed with ``n`` elements through
    the height and elements of about the same size along the other edges
    (``round(n * length / height)`` along x, ``round(n * width / height)`` along y).
    With 8-node hexahedra, ``nx x ny x nz`` elements and the clamped end removed the model
    has ``3 nx (ny + 1) (nz + 1)`` DOF (``n=4``: 40 x 4 x 4 elements, 3,000 DOF;
    ``n=14``: 94,500 DOF); :func:`size_for_dofs` inverts this.

    Parameters
    ----------
    n : int
        Number of elements through the height (the one resolution parameter).
    length, width, height : float
        Edge lengths along x, y, z in m.
    E : float
        Young's modulus in Pa (default steel).
    nu : float
        Poisson's ratio.
    rho : float
        Density in kg/m³.
    element : {'hex', 'hex27', 'tet'}
        ``hex``: 8-node trilinear hexahedron with full 2x2x2 Gauss integration (the
        CalculiX/Abaqus C3D8; stiff in bending, shear locking); ``hex27``: 27-node
        triquadratic hexahedron; ``tet``: 4-node tetrahedron, six per grid cell
        (very stiff in bending, for tests only).
    clamped : bool
        Remove all DOF of the nodes at ``x = 0`` (node set ``FIX``). ``False`` gives a
        free-free body with six rigid-body modes.
    divisions : tuple of int, optional
        Element counts ``(nx, ny, nz)``; overrides ``n``.

    Returns
    -------
    FEModel
        Translational DOF (directions 1..3) only, SI units; node sets ``ALL``, ``FIX``
        (x = 0), ``TIP`` (x = length) and ``TIP_CENTER`` (the node nearest the centre of
        the tip face).

    Raises
    ------
    OptionError
        On a bad element name, non-positive sizes or material constants.

    Examples
    --------
    >>> from flexmor.models import cantilever
    >>> m = cantilever(2, divisions=(10, 2, 2))      # the CalculiX C3D8 10x2x2 test beam
    >>> m.n_dof
    270
    """
    _positive(length=length, width=width, height=height)
    if divisions is None:
        if int(n) < 1:
            raise OptionError(f"n must be an integer >= 1, got {n!r}")
        n = int(n)
        divisions = (_count(n, length, height), _count(n, width, height), n)
        tag = f"n{n}"
    else:
        tag = "x".join(str(int(v)) for v in divisions)
    name = f"cantilever-{element}-{tag}" + ("" if clamped else "-free")
    model = _build(name, element, divisions, (length, width, height), E, nu, rho,
                   "FIX" if clamped else None, {"FIX": (0, 0.0), "TIP": (0, length)})
    tip = model.node_sets["TIP"]
    centre = np.array([length, width / 2, height / 2])
    k = int(np.argmin(np.linalg.norm(model.xyz[tip - 1] - centre, axis=1)))
    model.node_sets["TIP_CENTER"] = tip[k:k + 1]
    return model


def plate(n: int = 8, *, a: float = 1.0, b: float = 0.6, t: float = 0.01, E: float = 2.1e11,
          nu: float = 0.3, rho: float = 7850.0, element: str = "hex", layers: int | None = None,
          clamped: bool = False, divisions: tuple[int, int, int] | None = None) -> FEModel:
    """A thin rectangular plate ``[0, a] x [0, b] x [0, t]`` meshed as a 3D solid.

    Parameters
    ----------
    n : int
        Number of elements along the short edge ``b`` (the resolution parameter); the edge
        ``a`` gets ``round(n * a / b)`` elements.
    a, b : float
        In-plane edge lengths along x and y in m.
    t : float
        Thickness (along z) in m.
    E, nu, rho : float
        Young's modulus (Pa), Poisson's ratio and density (kg/m³).
    element : {'hex', 'hex27', 'tet'}
        See :func:`cantilever`. Thin plates of 8-node hexahedra lock in bending unless the
        in-plane element size approaches the thickness; ``hex27`` is far less sensitive.
    layers : int, optional
        Elements through the thickness; default 2 for ``hex`` and ``tet``, 1 for ``hex27``.
    clamped : bool
        Remove the DOF of the edge ``x = 0`` (node set ``EDGE_X0``); default free-free.
    divisions : tuple of int, optional
        Element counts ``(nx, ny, nz)``; overrides ``n`` and ``layers``.

    Returns
    -------
    FEModel
        Node sets ``ALL``, ``EDGE_X0``, ``EDGE_X1``, ``EDGE_Y0``, ``EDGE_Y1`` (the faces of
        the plate's edges, all through-thickness nodes), ``CORNER`` (the node at
        ``(a, b, t)``).

    Raises
    ------
    OptionError
        On a bad element name, non-positive sizes or material constants.
    """
    _positive(a=a, b=b, t=t)
    _check_choice("element", element, ELEMENTS)
    if divisions is None:
        if int(n) < 1:
            raise OptionError(f"n must be an integer >= 1, got {n!r}")
        n = int(n)
        if layers is None:
            layers = 1 if element == "hex27" else 2
        if int(layers) < 1:
            raise OptionError(f"layers must be >= 1, got {layers!r}")
        divisions = (_count(n, a, b), n, int(layers))
        tag = f"n{n}"
    else:
        tag = "x".join(str(int(v)) for v in divisions)
    name = f"plate-{element}-{tag}" + ("-clamped" if clamped else "")
    sets = {"EDGE_X0": (0, 0.0), "EDGE_X1": (0, a), "EDGE_Y0": (1, 0.0), "EDGE_Y1": (1, b)}
    model = _build(name, element, divisions, (a, b, t), E, nu, rho,
                   "EDGE_X0" if clamped else None, sets)
    k = int(np.argmin(np.linalg.norm(model.xyz - np.array([a, b, t]), axis=1)))
    model.node_sets["CORNER"] = model.node_ids[k:k + 1]
    return model


# -- sizes -------------------------------------------------------------------------------------
def _n_dofs(kind: str, n: int, element: str, clamped: bool, geom: dict) -> int:
    if kind == "cantilever":
        L, w, h = geom.get("length", 1.0), geom.get("width", 0.1), geom.get("height", 0.1)
        nx, ny, nz = _count(n, L, h), _count(n, w, h), n
    else:
        a, b = geom.get("a", 1.0), geom.get("b", 0.6)
        layers = geom.get("layers") or (1 if element == "hex27" else 2)
        nx, ny, nz = _count(n, a, b), n, int(layers)
    p = 2 if element == "hex27" else 1
    px, py, pz = p * nx + 1, p * ny + 1, p * nz + 1
    nodes = px * py * pz
    if clamped:
        nodes -= py * pz  # the face x = 0
    return 3 * nodes


def size_for_dofs(target_dofs: int, kind: str = "cantilever", *, element: str = "hex",
                  clamped: bool | None = None, **geometry) -> int:
    """The resolution ``n`` whose model has the number of DOF closest to ``target_dofs``.

    Parameters
    ----------
    target_dofs : int
        Wanted number of (free) degrees of freedom.
    kind : {'cantilever', 'plate'}
        The model function whose ``n`` is sought.
    element : {'hex', 'hex27', 'tet'}
        Element type, as passed to the model function.
    clamped : bool, optional
        As passed to the model function; default its default (cantilever clamped, plate free).
    **geometry
        Geometry keywords of the model function (``length``, ``width``, ``height`` or
        ``a``, ``b``, ``layers``) when they differ from the defaults.

    Returns
    -------
    int
        ``n`` for :func:`cantilever` or :func:`plate`.

    Examples
    --------
    >>> from flexmor.models import size_for_dofs
    >>> size_for_dofs(100_000)
    14
    """
    _check_choice("kind", kind, KINDS)
    _check_choice("element", element, ELEMENTS)
    if not (np.isfinite(target_dofs) and target_dofs > 0):
        raise OptionError(f"target_dofs must be positive, got {target_dofs!r}")
    if clamped is None:
        clamped = kind == "cantilever"
    best, best_err, n = 1, np.inf, 1
    while True:
        d = _n_dofs(kind, n, element, clamped, geometry)
        err = abs(np.log(max(d, 1) / target_dofs))
        if err < best_err:
            best, best_err = n, err
        if d > target_dofs:
            return best
        n += 1
