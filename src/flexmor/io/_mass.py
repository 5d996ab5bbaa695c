"""The mass-matrix check shared by the readers of decks with quadratic elements (CalculiX, Abaqus).

Quadratic elements (``C3D20R``, ``C3D20``, ``C3D15``, ``C3D10``, 8-node shells and plane
elements) can give a singular mass matrix (reduced integration) or one with zero or negative
diagonal entries (row-sum lumping of serendipity elements): the readers then warn instead of
refusing the file, and :func:`check_mass` estimates the smallest eigenvalue of ``M``.
"""

from __future__ import annotations

import warnings

import numpy as np

__all__ = ["QUADRATIC_TYPES", "check_mass", "direction_blocks"]

#: Element types whose mass matrix may legitimately be singular or indefinite (quadratic
#: serendipity / reduced-integration / row-sum-lumped): such decks get warnings, not errors.
QUADRATIC_TYPES = ("C3D20", "C3D15", "C3D10", "S8", "CPS8", "CPE8", "CAX8")


def check_mass(model, where, *, max_dof: int = 500_000, iterations: int = 12) -> float | None:
    """Warn (FlexmorWarning) when the mass matrix is singular or indefinite; return an estimate of
    ``lambda_min/lambda_max`` (0 when it is not positive definite).

    One factorization of ``M`` as positive definite (pardiso: Cholesky) and two inverse iterations
    (``iterations`` with another backend) estimate its smallest eigenvalue: a factorization that
    fails (a pivot ``<= 0``) means singular or indefinite, a ratio below 1e-12 singular, a negative
    Rayleigh quotient indefinite. A mass that couples no two directions (a solid's consistent or
    lumped mass) is checked block by block (:func:`direction_blocks`): its eigenvalues are theirs,
    and a block of one direction, a third of the equations, factorizes at a small part of the cost.
    Skipped (None) above ``max_dof`` equations.
    """
    from ..errors import FlexmorWarning
    from ..model import SINGULAR_MASS_NOTE

    M = model.M
    if M.shape[0] > max_dof:
        return None
    lam_max = float(abs(M).sum(axis=1).max())  # Gershgorin bound (the blocks' largest: no other terms)
    kind, ratio = None, np.inf
    for block in direction_blocks(M, getattr(model, "dofs", None)):
        kind, r = _smallest(block, iterations)
        ratio = min(ratio, r / lam_max)
        if kind is not None:
            break
    if kind is None and ratio < 1e-12:  # (its value at round-off level is noise: not shown)
        kind = "indefinite (a negative eigenvalue)" if ratio < -1e-12 else \
            "singular (smallest eigenvalue below 1e-12 of the largest)"
    if kind is not None:
        warnings.warn(f"{where}: the mass matrix is {kind}; {SINGULAR_MASS_NOTE}", FlexmorWarning, stacklevel=3)
    return ratio


def _smallest(M, iterations: int) -> tuple[str | None, float]:
    """``(kind, rayleigh)``: a failed factorization of ``M`` as positive definite (``kind`` says so, 0), else
    the Rayleigh quotient of two inverse iterations (``iterations`` with a backend other than pardiso)."""
    from ..errors import SolverError
    from ..linalg import factorize

    try:
        try:
            F = factorize(M, symmetric=True, positive=True, check=False)
        except SolverError:  # a pivot <= 0 (pardiso's Cholesky), or singular (LU)
            return "singular or indefinite (a pivot <= 0 in its factorization)", 0.0
        x = np.random.default_rng(1).standard_normal(M.shape[0])
        for _ in range(2 if F.backend == "pardiso" else iterations):
            x = F.solve(x)
            nx = np.linalg.norm(x)
            if not np.isfinite(nx) or nx == 0:
                raise SolverError("inverse iteration broke down")
            x /= nx
        return None, float(x @ (M @ x))
    except (SolverError, RuntimeError, ValueError, np.linalg.LinAlgError):
        return None, 0.0


def direction_blocks(M, dofs) -> list:
    """The diagonal blocks of ``M`` whose eigenvalues are all of its eigenvalues.

    When no stored entry of ``M`` couples two directions (``dofs[:, 1]``), ``M`` is block diagonal
    by direction up to a permutation: one block per direction, and one for all of them when the
    blocks are the same matrix on the same nodes (a solid's mass: ``x``, ``y`` and ``z`` alike).
    Otherwise (or without ``dofs``) ``[M]``.
    """
    import scipy.sparse as sp

    if dofs is None or len(dofs) != M.shape[0]:
        return [M]
    coo = M.tocoo()
    d = np.asarray(dofs)[:, 1]
    if np.any((d[coo.row] != d[coo.col]) & (coo.data != 0)):  # (stored zeros: K's pattern, CalculiX)
        return [M]
    blocks, nodes = [], []
    for code in np.unique(d):
        idx = np.flatnonzero(d == code)
        B = sp.csr_matrix(M[idx][:, idx])
        B.eliminate_zeros()
        B.sort_indices()
        n = np.asarray(dofs)[idx, 0]
        if any(np.array_equal(n, n0) and _same(B, B0) for n0, B0 in zip(nodes, blocks)):
            continue
        blocks.append(B)
        nodes.append(n)
    return blocks


def _same(A, B) -> bool:
    return (A.shape == B.shape and np.array_equal(A.indptr, B.indptr) and np.array_equal(A.indices, B.indices)
            and np.array_equal(A.data, B.data))
