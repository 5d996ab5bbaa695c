"""Geometric (stress) stiffening of a preloaded body: the model's stiffness about a static equilibrium.

A body that carries a static load (a tensioned bolt, a blade spinning on its hub) vibrates about
that equilibrium with the linearized stiffness ``K + K_G``: ``K_G`` is the **geometric stiffness**
of the element stresses ``S`` of the static solution,

.. math:: K_G = \\sum_e \\int_{V_e} G^T S\\, G \\, dV

(``G`` the derivatives ``dN_a / dx_k`` of the shape functions, the same for the three
displacement directions), evaluated at the integration points of CalculiX's stiffness
(:mod:`flexmor.stress`; ``C3D8R`` with its mean gradient and mean stress over the element).
A spinning body also gets the **spin softening** ``-P^T M P`` (``P`` the angular velocity's skew
matrix on the translations of each node): in the frame that turns with it, the centrifugal force
grows with the displacement.

Preload SPECs (:func:`parse_preload`):

``NODE:DIR=F`` or ``SET:DIR=F``
    a total force ``F`` in direction ``x``, ``y`` or ``z``, spread over the set's nodes with
    equal weights as for ports (:mod:`flexmor.ports`);
``gravity:GX,GY,GZ``
    the load ``M g`` of the acceleration of gravity ``g`` on the translations;
``spin:WX,WY,WZ``
    rotation with angular velocity ``w`` (rad/s) about an axis through the origin: the
    centrifugal load ``P^T M P x`` (``x`` the node coordinates) and the spin softening.

:func:`preload_stiffness` solves the static problem ``K u = F`` (the model must be supported:
a free body under load has no static equilibrium), recovers the stresses and returns
``K + K_G`` (with the spin softening). Linear prestress: the stresses of the linear static
solution on the undeformed geometry, which agrees with a geometrically nonlinear static step
followed by a perturbation frequency step while the strains are small.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .errors import ModelError
from .stress import integration_points

__all__ = ["Preload", "Preloaded", "geometric_stiffness", "material_record", "parse_preload", "preload_load",
           "preload_stiffness", "recorded_material", "spin_operator", "spin_softening", "with_preload"]


@dataclass(frozen=True)
class Preload:
    """One static load case of a preload SPEC.

    Attributes
    ----------
    kind : str
        ``"force"``, ``"gravity"`` or ``"spin"``.
    spec : str
        The SPEC as given.
    target : str
        ``NODE:DIR`` of a force (empty otherwise).
    value : ndarray
        The force (shape (1,)), the acceleration of gravity or the angular velocity (shape (3,)).
    """

    kind: str
    spec: str
    target: str
    value: np.ndarray


@dataclass(frozen=True)
class Preloaded:
    """The stiffness about a preloaded equilibrium, and what made it.

    Attributes
    ----------
    K : sparse matrix
        ``K + K_G`` (and the spin softening), over the model's equations.
    K_G : sparse matrix
        The geometric stiffness alone.
    softening : sparse matrix or None
        The spin softening ``-P^T M P`` (None without spin).
    u : ndarray, shape (n_dof,)
        The static displacement.
    load : ndarray, shape (n_dof,)
        The static load.
    specs : list of str
        The preload SPECs.
    material : dict or None
        The material of the stresses when it was given in place of the deck's (:func:`material_record`).
    """

    K: sp.csr_matrix
    K_G: sp.csr_matrix
    softening: sp.csr_matrix | None
    u: np.ndarray
    load: np.ndarray
    specs: list
    material: dict | None = None

    def record(self) -> dict:
        """A JSON-ready description: the SPECs, the largest displacement, the norms of the load and the material
        given in place of the deck's (``material``, only when one was: the same preload with the deck's materials
        is another stiffness)."""
        out = {"specs": list(self.specs), "max_displacement": float(np.abs(self.u).max(initial=0.0)),
               "load_norm": float(np.linalg.norm(self.load)), "spin_softening": self.softening is not None}
        if self.material is not None:
            out["material"] = self.material
        return out


def material_record(material) -> dict:
    """``material`` (a :class:`~flexmor.elements.Material` or ``(E, nu[, rho])``) as JSON: its elasticity matrix
    ``D`` (6 x 6, Voigt order) and density ``rho`` (None when not given)."""
    from .stress import as_material

    m = as_material(material)
    return {"D": np.asarray(m.D).tolist(), "rho": None if m.rho is None else float(m.rho)}


def recorded_material(record, source=None):
    """The material of a preload record (:meth:`Preloaded.record`) given in place of the deck's, or None;
    ``source`` (the body's file) names a malformed record in the error."""
    from .elements import Material

    rec = (record or {}).get("material") if isinstance(record, dict) else None
    if not rec:
        return None
    try:
        return Material("material", np.asarray(rec["D"], dtype=np.float64), rec.get("rho"))
    except (KeyError, TypeError, ValueError, ModelError) as exc:
        raise ModelError(f"{source or 'the body'}: its preload record has a malformed material ({exc})",
                         params=("material",)) from None


_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eEdD][-+]?\d+)?"


def _vector(text: str, spec: str, what: str) -> np.ndarray:
    parts = [p.strip() for p in text.split(",")]
    if len(parts) != 3 or not all(re.fullmatch(_NUMBER, p) for p in parts):
        raise ModelError(f"spec {spec!r}: {what} needs three numbers X,Y,Z, got {text!r}", params=("spec",))
    v = np.array([float(p.replace("d", "e").replace("D", "e")) for p in parts])
    if not np.all(np.isfinite(v)):
        raise ModelError(f"spec {spec!r}: {what} must be finite", params=("spec",))
    return v


def parse_preload(spec: str) -> Preload:
    """A preload SPEC (``NODE|SET:DIR=F``, ``gravity:GX,GY,GZ``, ``spin:WX,WY,WZ``) as a :class:`Preload`.

    Raises
    ------
    ModelError
        A SPEC of none of these forms, naming ``preloads``.
    """
    text = str(spec).strip()
    head, sep, rest = text.partition(":")
    key = head.strip().lower()
    if sep and key in ("gravity", "spin") and "=" not in rest:
        return Preload(key, text, "", _vector(rest, text, "gravity" if key == "gravity" else "the angular velocity"))
    target, eq, value = text.rpartition("=")
    if not eq or ":" not in target:
        raise ModelError(f"spec {text!r}: give NODE:DIR=F or SET:DIR=F (a total force), gravity:GX,GY,GZ or "
                         "spin:WX,WY,WZ", params=("spec",))
    d = target.rpartition(":")[2].strip().lower()
    if d not in ("x", "y", "z"):
        raise ModelError(f"spec {text!r}: a force needs the direction x, y or z, got {d!r}", params=("spec",))
    if not re.fullmatch(_NUMBER, value.strip()):
        raise ModelError(f"spec {text!r}: the force {value.strip()!r} is not a number", params=("spec",))
    return Preload("force", text, target.strip(), np.array([float(value.strip().replace("d", "e").replace("D", "e"))]))


def spin_operator(model, w: np.ndarray) -> tuple[sp.csr_matrix, np.ndarray]:
    """``P`` (n_dof, n_dof): the skew matrix of ``w`` on the translations of each node, and ``P x``."""
    W = np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])
    n = model.n_dof
    d = model.dofs[:, 1]
    trans = np.flatnonzero(d <= 3)
    key = model.dofs[trans, 0] * 8 + d[trans]  # (node, direction) of each translational equation
    order = np.argsort(key)
    rows, cols, vals = [], [], []
    for i in range(3):  # P[(a, i), (a, j)] = W[i, j] where both are equations
        for j in range(3):
            if W[i, j] == 0.0:
                continue
            src = trans[d[trans] == j + 1]
            want = model.dofs[src, 0] * 8 + i + 1
            pos = np.minimum(np.searchsorted(key[order], want), max(trans.size - 1, 0))
            hit = key[order][pos] == want
            rows.append(trans[order][pos][hit])
            cols.append(src[hit])
            vals.append(np.full(int(hit.sum()), W[i, j]))
    empty = [np.zeros(0)]
    P = sp.csr_matrix((np.concatenate(vals or empty), (np.concatenate(rows or empty).astype(np.int64),
                                                       np.concatenate(cols or empty).astype(np.int64))), shape=(n, n))
    v = np.zeros(n)
    v[trans] = (model.node_xyz(model.dofs[trans, 0]) @ W.T)[np.arange(trans.size), d[trans] - 1]
    return P, v


def spin_softening(model, w) -> sp.csr_matrix:
    """The spin softening ``-P^T M P`` of angular velocity ``w`` (rad/s) on the model's translations."""
    P, _ = spin_operator(model, np.asarray(w, dtype=np.float64))
    return sp.csr_matrix(-(P.T @ model.M @ P))


def preload_load(model, spec) -> tuple[np.ndarray, list]:
    """The static load vector of preload SPECs (one string or several) and their parsed forms.

    Returns
    -------
    load : ndarray, shape (n_dof,)
    preloads : list of Preload

    Raises
    ------
    ModelError
        A malformed SPEC, a model without equation map or geometry, or a port error of a force.
    """
    from .ports import make_ports

    specs = [spec] if isinstance(spec, str) else list(spec)
    preloads = [parse_preload(s) for s in specs]
    if not preloads:
        raise ModelError("spec names no preload", params=("spec",))
    if model.dofs is None or model.n_nodes == 0:
        raise ModelError(f"{_name(model)}: a preload needs the model's nodes and equation map", params=("model",))
    if model.node_frames:
        raise ModelError(f"{_name(model)}: nodes with local displacement directions (Nastran CD systems) are not "
                         "preloaded; read the model with directions='basic'", params=("model",))
    F = np.zeros(model.n_dof)
    d = model.dofs[:, 1]
    for p in preloads:
        if p.kind == "force":
            F += p.value[0] * make_ports(model, [p.target]).B.toarray()[:, 0]
        elif p.kind == "gravity":
            g = np.zeros(model.n_dof)
            g[d <= 3] = p.value[d[d <= 3] - 1]
            F += model.M @ g
        else:
            P, v = spin_operator(model, p.value)
            F += P.T @ (model.M @ v)
    return F, preloads


def geometric_stiffness(model, u, *, material=None) -> sp.csr_matrix:
    """The geometric stiffness ``K_G`` of the stresses of the displacement ``u``.

    Parameters
    ----------
    model : FEModel
        With :attr:`~flexmor.model.FEModel.elements` (solid elements, :data:`flexmor.stress.SOLID_TYPES`).
    u : array_like, shape (n_dof,)
        The static displacement over the model's equations.
    material : Material or tuple, optional
        ``(E, nu[, rho])`` or a :class:`~flexmor.elements.Material` for every element, in place of
        the deck's materials.

    Returns
    -------
    scipy.sparse.csr_matrix, shape (n_dof, n_dof)
        Symmetric; the rows and columns of constrained directions are left out, as in ``K``.

    Raises
    ------
    ModelError
        As :func:`flexmor.stress.element_stresses`.
    """
    nn, n = model.n_nodes, model.n_dof
    A = sp.csr_matrix((nn, nn))  # the node-to-node factor, the same in x, y and z
    eq = np.full((nn, 3), -1, np.int64)
    parts: list = []

    def flush():
        nonlocal A
        if parts:
            r, c, v = (np.concatenate(x) for x in zip(*parts))
            A = A + sp.csr_matrix((v, (r, c)), shape=(nn, nn))
            parts.clear()

    size = 0
    for ch in integration_points(model, u, material=material):
        c = ch.ids.size
        S = ch.stress[..., [0, 3, 5, 3, 1, 4, 5, 4, 2]].reshape(c, -1, 3, 3)
        G = ch.gradients
        Ke = np.einsum("cpia,cpij,cpjb,cp->cab", G, S, G, ch.volumes, optimize=True)  # (c, k, k)
        eq[ch.rows] = ch.equations
        k = ch.rows.shape[1]
        parts.append((np.repeat(ch.rows, k, axis=1).ravel(), np.tile(ch.rows, (1, k)).ravel(), Ke.ravel()))
        size += Ke.size
        if size > 1 << 23:
            flush()
            size = 0
    flush()
    KG = sp.csr_matrix((n, n))
    for i in range(3):  # K_G[(a, i), (b, i)] = A[a, b] on the equations
        has = np.flatnonzero(eq[:, i] >= 0)
        E = sp.csr_matrix((np.ones(has.size), (eq[has, i], has)), shape=(n, nn))
        KG = KG + E @ A @ E.T
    KG = sp.csr_matrix(KG)
    KG.sum_duplicates()
    return KG


def _name(model) -> str:
    return model.source or model.name


def _check_supported(model, what: str) -> None:
    """Refuse a model that moves rigidly without straining (its static problem has no solution)."""
    from .rigid import rigid_motions

    R = rigid_motions(model)
    norms = np.linalg.norm(R, axis=0)
    used = norms > 0
    if not used.any():
        return
    KR = model.K @ (R[:, used] / norms[used])
    scale = float(abs(model.K).max()) * np.sqrt(max(1, model.n_dof / max(1, model.n_nodes)))
    free = np.linalg.norm(KR, axis=0) <= 1e-8 * scale * np.sqrt(model.n_dof)
    if free.any():
        names = np.array(["x", "y", "z", "rx", "ry", "rz"])[used][free]
        raise ModelError(f"{_name(model)}: {what} needs a supported model, but it moves freely ({', '.join(names)}"
                         " without strain): constrain it (a *BOUNDARY at the hub or a clamp) before preloading",
                         params=("spec",))


def preload_stiffness(model, spec, *, material=None, solver=None) -> Preloaded:
    """The stiffness of ``model`` about its equilibrium under the preloads ``spec``.

    Solves ``K u = F`` (:func:`flexmor.linalg.factorize`), recovers the element stresses of ``u``
    and returns ``K + K_G`` (plus the spin softening of a ``spin:`` preload).

    Parameters
    ----------
    model : FEModel
        Supported (constrained against rigid motion), with the elements and materials of its deck.
    spec : str or sequence of str
        Preload SPECs (module docstring); their loads add up.
    material : Material or tuple, optional
        ``(E, nu[, rho])`` or a :class:`~flexmor.elements.Material` for every element, in place of
        the deck's materials.
    solver : SolverContext, optional
        The backend of the static solve.

    Returns
    -------
    Preloaded
        ``K`` (the preloaded stiffness), ``K_G``, the softening, the static displacement and load.

    Raises
    ------
    ModelError
        A malformed SPEC, a free (unsupported) model, no elements or materials, or elements
        whose stresses are not recovered (:mod:`flexmor.stress`).
    """
    from .linalg import factorize

    specs = [spec] if isinstance(spec, str) else list(spec)
    F, preloads = preload_load(model, specs)
    next(integration_points(model, np.zeros(model.n_dof), material=material), None)  # elements checked
    _check_supported(model, "spec " + ", ".join(repr(p.spec) for p in preloads))
    u = factorize(model.K, solver=solver, positive=True).solve(F)
    u = np.asarray(u, dtype=np.float64).reshape(-1)
    KG = geometric_stiffness(model, u, material=material)
    K = model.K + KG
    soft = None
    for p in preloads:
        if p.kind == "spin":
            s = spin_softening(model, p.value)
            soft = s if soft is None else soft + s
    if soft is not None:
        K = K + soft
    K = sp.csr_matrix(K)
    K = (K + K.T) * 0.5
    return Preloaded(sp.csr_matrix(K), KG, soft, u, F, specs,
                     None if material is None else material_record(material))


def with_preload(model, spec, *, material=None, solver=None):
    """``model`` with its stiffness about the equilibrium under the preloads ``spec``.

    Parameters
    ----------
    model : FEModel
        Supported, with the elements and materials of its deck (as read: before couplings).
    spec : str or sequence of str
        Preload SPECs (:func:`preload_stiffness`), in the model's units (SI when it was read in
        a named unit system).
    material : Material or tuple, optional
        ``(E, nu[, rho])`` for every element, in place of the deck's materials.
    solver : SolverContext, optional
        The backend of the static solve.

    Returns
    -------
    FEModel
        A copy whose ``K`` is ``K + K_G`` (with the spin softening of a ``spin:`` preload) and whose
        ``preload`` is the record of :meth:`Preloaded.record` (bodies reduced from it carry it in
        their ``info``).

    Raises
    ------
    ModelError
        As :func:`preload_stiffness`; also a model that is preloaded already.
    """
    import dataclasses

    if model.preload:
        raise ModelError(f"{_name(model)} is preloaded already ({', '.join(model.preload.get('specs', []))}); give "
                         "all its preloads in one spec", params=("spec",))
    pre = preload_stiffness(model, spec, material=material, solver=solver)
    return dataclasses.replace(model, K=pre.K, preload=pre.record())
