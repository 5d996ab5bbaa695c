"""The elements of a model and their materials, as the FE file defines them: what stress recovery needs.

:class:`Elements` holds blocks of elements of one type each (:class:`ElementBlock`: the type
as CalculiX names it, ``C3D8R`` ..., the element numbers and the node ids in CalculiX's node
order) and the material of each element (:class:`Material`, its elasticity matrix in the
component order :data:`VOIGT` and its density). The readers fill it from the decks'
``*MATERIAL``/``*ELASTIC``/``*DENSITY`` and section keywords, Nastran ``MAT1``/``PSOLID``/``PSHELL``
and Ansys ``MP`` commands; :attr:`flexmor.model.FEModel.elements` carries it.

A material the deck gives in a form flexmor does not evaluate (temperature tables, fully
anisotropic elasticity, orthotropy in a local orientation) is kept with the reason
(:attr:`Material.unsupported`): reading the model for a reduction still works, and stress
recovery refuses such elements with that reason.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import ModelError

__all__ = ["VOIGT", "ElementBlock", "Elements", "Material"]

#: Order of the stress and strain components: xx yy zz xy yz zx (CalculiX's frd order).
VOIGT = ("xx", "yy", "zz", "xy", "yz", "zx")


@dataclass(frozen=True)
class Material:
    """A linear elastic material.

    Parameters
    ----------
    name : str
        The name in the FE file (upper case for decks).
    D : ndarray, shape (6, 6), optional
        Elasticity matrix, stress = D strain, components :data:`VOIGT` with engineering shear
        strains (``gamma_xy = 2 eps_xy``); None when ``unsupported``.
    rho : float, optional
        Density, None when the file gives none.
    unsupported : str
        Empty, or why ``D`` could not be formed (named in the error when stresses are asked for).
    """

    name: str = ""
    D: np.ndarray | None = None
    rho: float | None = None
    unsupported: str = ""

    def __post_init__(self):
        if self.D is not None:
            D = np.asarray(self.D, dtype=np.float64)
            if D.shape != (6, 6) or not np.all(np.isfinite(D)):
                raise ModelError(f"{self.name or 'elasticity'}: the elasticity matrix must be 6 x 6 and finite")
            object.__setattr__(self, "D", D)
        if self.rho is not None:
            rho = float(self.rho)
            if not np.isfinite(rho) or rho <= 0:
                raise ModelError(f"{self.name or 'density'}: the density must be > 0, got {self.rho}")
            object.__setattr__(self, "rho", rho)

    @classmethod
    def isotropic(cls, E: float, nu: float, rho: float | None = None, name: str = "") -> Material:
        """An isotropic material of Young's modulus ``E`` and Poisson's ratio ``nu``.

        Raises
        ------
        ModelError
            ``E <= 0`` or ``nu`` outside (-1, 0.5).
        """
        E, nu = float(E), float(nu)
        if not (np.isfinite(E) and E > 0):
            raise ModelError(f"{name or 'E, nu'}: Young's modulus must be > 0, got {E}")
        if not (np.isfinite(nu) and -1.0 < nu < 0.5):
            raise ModelError(f"{name or 'E, nu'}: Poisson's ratio must lie in (-1, 0.5), got {nu}")
        lam = E * nu / ((1 + nu) * (1 - 2 * nu))
        mu = E / (2 * (1 + nu))
        D = np.zeros((6, 6))
        D[:3, :3] = lam
        D[np.arange(3), np.arange(3)] = lam + 2 * mu
        D[np.arange(3, 6), np.arange(3, 6)] = mu
        return cls(name, D, rho)

    @classmethod
    def orthotropic(cls, d1111, d1122, d2222, d1133, d2233, d3333, d1212, d1313, d2323,
                    rho: float | None = None, name: str = "") -> Material:
        """An orthotropic material in the global axes from its nine elasticity constants (CalculiX's
        ``*ELASTIC, TYPE=ORTHO`` order; ``d1212`` ... are the shear moduli)."""
        D = np.zeros((6, 6))
        D[0, 0], D[1, 1], D[2, 2] = d1111, d2222, d3333
        D[0, 1] = D[1, 0] = d1122
        D[0, 2] = D[2, 0] = d1133
        D[1, 2] = D[2, 1] = d2233
        D[3, 3], D[4, 4], D[5, 5] = d1212, d2323, d1313
        return cls(name, D, rho)

    @classmethod
    def engineering_constants(cls, E1, E2, E3, nu12, nu13, nu23, G12, G13, G23, rho: float | None = None,
                              name: str = "") -> Material:
        """An orthotropic material in the global axes from its engineering constants (CalculiX's
        ``*ELASTIC, TYPE=ENGINEERING CONSTANTS`` order).

        Raises
        ------
        ModelError
            A compliance matrix that is not positive definite.
        """
        C = np.zeros((6, 6))
        C[0, 0], C[1, 1], C[2, 2] = 1 / E1, 1 / E2, 1 / E3
        C[0, 1] = C[1, 0] = -nu12 / E1
        C[0, 2] = C[2, 0] = -nu13 / E1
        C[1, 2] = C[2, 1] = -nu23 / E2
        C[3, 3], C[4, 4], C[5, 5] = 1 / G12, 1 / G23, 1 / G13
        if not np.all(np.isfinite(C)) or np.linalg.eigvalsh(C).min() <= 0:
            raise ModelError(f"{name or 'engineering constants'}: the engineering constants give no positive definite "
                             "compliance")
        return cls(name, np.linalg.inv(C), rho)


@dataclass(frozen=True)
class ElementBlock:
    """Elements of one type.

    Parameters
    ----------
    type : str
        The element type as CalculiX names it (``C3D4 C3D10 C3D8 C3D8R C3D20 C3D20R C3D6 C3D15``
        for the solids; shells and others keep their deck name). Nastran and Ansys solids are
        named by the CalculiX element of the same shape and integration.
    ids : ndarray of int, shape (n,)
        Element numbers.
    nodes : ndarray of int, shape (n, k)
        Node ids of each element in CalculiX's node order.
    material : ndarray of int, shape (n,)
        Index into :attr:`Elements.materials` of each element's material, -1 for none.
    """

    type: str
    ids: np.ndarray
    nodes: np.ndarray
    material: np.ndarray | None = None

    def __post_init__(self):
        ids = np.asarray(self.ids, dtype=np.int64).reshape(-1)
        nodes = np.asarray(self.nodes, dtype=np.int64)
        if nodes.ndim != 2 or nodes.shape[0] != ids.size:
            raise ModelError(f"{self.type} elements: {ids.size} numbers but node array of shape {nodes.shape}")
        mat = np.full(ids.size, -1, np.int64) if self.material is None else np.asarray(self.material, np.int64)
        if mat.shape != ids.shape:
            raise ModelError(f"{self.type} elements: {mat.size} material indices for {ids.size} elements")
        object.__setattr__(self, "type", str(self.type).upper())
        object.__setattr__(self, "ids", ids)
        object.__setattr__(self, "nodes", nodes)
        object.__setattr__(self, "material", mat)


@dataclass(frozen=True)
class Elements:
    """The elements of a model by type, with the materials they refer to.

    Parameters
    ----------
    blocks : tuple of ElementBlock
    materials : tuple of Material
        Indexed by :attr:`ElementBlock.material`.
    source : str
        The file that defines them (named in errors).
    """

    blocks: tuple = ()
    materials: tuple = ()
    source: str = ""

    def __post_init__(self):
        object.__setattr__(self, "blocks", tuple(self.blocks))
        object.__setattr__(self, "materials", tuple(self.materials))
        n = len(self.materials)
        for b in self.blocks:
            if b.material.size and (b.material.max() >= n or b.material.min() < -1):
                raise ModelError(f"{b.type} elements refer to material {int(b.material.max())}, "
                                 f"but there are {n} materials")

    @property
    def n_elements(self) -> int:
        """Number of elements over all blocks."""
        return sum(b.ids.size for b in self.blocks)

    def node_ids(self) -> np.ndarray:
        """Sorted unique node ids the elements use."""
        if not self.blocks:
            return np.zeros(0, np.int64)
        return np.unique(np.concatenate([b.nodes.ravel() for b in self.blocks]))

    def converted(self, stress: float, density: float) -> Elements:
        """These elements with every material's elasticity multiplied by ``stress`` and its density by
        ``density`` (the factors of a unit system to SI; the node coordinates are the model's)."""
        mats = tuple(Material(m.name, None if m.D is None else m.D * stress, None if m.rho is None else m.rho * density,
                              m.unsupported) for m in self.materials)
        return Elements(self.blocks, mats, self.source)

    def with_material(self, material: Material) -> Elements:
        """These elements, all of the one ``material``."""
        blocks = [ElementBlock(b.type, b.ids, b.nodes, np.zeros(b.ids.size, np.int64)) for b in self.blocks]
        return Elements(tuple(blocks), (material,), self.source)
