"""The mass-matrix check shared by the readers of decks with quadratic elements (CalculiX, Abaqus).

Quadratic elements (``C3D20R``, ``C3D20``, ``C3D15``, ``C3D10``, 8-node shells and plane
elements) can give a singular mass matrix (reduced integration) or one with zero or negative
diagonal entries (row-sum lumping of serendipity elements): the readers then warn instead of
refusing the file, and :func:`check_mass` estimates the smallest eigenvalue of ``M``.

Every reader's mass is also compared across directions (:func:`check_mass_directions`): a
continuum's mass holds each value three times, once for ``x``, ``y`` and ``z``, so a value changed in
one of them is named.
"""

from __future__ import annotations

import warnings

import numpy as np
import scipy.sparse as sp

from ..errors import FlexmorWarning, note

__all__ = ["QUADRATIC_TYPES", "check_mass", "check_mass_directions", "direction_blocks", "direction_mismatches"]

#: Element types whose mass matrix may legitimately be singular or indefinite (quadratic
#: serendipity / reduced-integration / row-sum-lumped): such decks get warnings, not errors.
QUADRATIC_TYPES = ("C3D20", "C3D15", "C3D10", "S8", "CPS8", "CPE8", "CAX8")


def check_mass(model, where, *, max_dof: int = 500_000, iterations: int = 12) -> float | None:
    """Note (``singular-mass``, :func:`flexmor.errors.note`) a mass matrix that is singular or indefinite;
    return an estimate of ``lambda_min/lambda_max`` (0 when it is not positive definite).

    One factorization of ``M`` as positive definite (pardiso: Cholesky) and two inverse iterations
    (``iterations`` with another backend) estimate its smallest eigenvalue: a factorization that
    fails (a pivot ``<= 0``) means singular or indefinite, a ratio below 1e-12 singular, a negative
    Rayleigh quotient indefinite. A mass that couples no two directions (a solid's consistent or
    lumped mass) is checked block by block (:func:`direction_blocks`): its eigenvalues are theirs,
    and a block of one direction, a third of the equations, factorizes at a small part of the cost.
    Skipped (None) where a block has more than ``max_dof`` equations (a solid's mass: 1.5 M equations).
    """
    M = model.M
    if M.shape[0] > 3 * max_dof:
        return None
    blocks = direction_blocks(M, getattr(model, "dofs", None))
    if max(B.shape[0] for B in blocks) > max_dof:
        return None
    lam_max = float(abs(M).sum(axis=1).max())  # Gershgorin bound (the blocks' largest: no other terms)
    kind, ratio = None, np.inf
    for block in blocks:
        kind, r = _smallest(block, iterations)
        ratio = min(ratio, r / lam_max)
        if kind is not None:
            break
    if kind is None and ratio < 1e-12:  # (its value at round-off level is noise: not shown)
        kind = "indefinite (a negative eigenvalue)" if ratio < -1e-12 else \
            "singular (smallest eigenvalue below 1e-12 of the largest)"
    if kind is not None:
        note("singular-mass", f"{where}: the mass matrix is {kind}; every method still works", stacklevel=3)
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
    if dofs is None or len(dofs) != M.shape[0]:
        return [M]
    coo = M.tocoo()
    d = np.asarray(dofs)[:, 1]
    if np.any((d[coo.row] != d[coo.col]) & (coo.data != 0)):  # (stored zeros: K's pattern, CalculiX)
        return [M]
    parts: list = []
    for part in _parts(M, dofs, np.unique(d), np.ones(d.size, dtype=bool)):
        if not any(_same(part, other) for other in parts):
            parts.append(part)
    return [B for _, B in parts]


def _parts(M, dofs, codes, rows) -> list:
    """``(nodes, block)`` of ``M`` over the equations ``rows`` of each direction code in ``codes`` (canonical
    CSR without stored zeros, so that two blocks holding one matrix compare equal array by array)."""
    d = np.asarray(dofs)[:, 1]
    out = []
    for code in codes:
        idx = np.flatnonzero(rows & (d == code))
        B = sp.csr_matrix(M[idx][:, idx])
        B.eliminate_zeros()
        B.sort_indices()
        out.append((np.asarray(dofs)[idx, 0], B))
    return out


def _same(a, b) -> bool:
    """Whether two ``(nodes, block)`` parts are one matrix on the same nodes."""
    (na, A), (nb, B) = a, b
    return (np.array_equal(na, nb) and A.shape == B.shape and np.array_equal(A.indptr, B.indptr)
            and np.array_equal(A.indices, B.indices) and np.array_equal(A.data, B.data))


#: Relative difference below which the x, y and z entries of one pair of nodes count as the same value.
DIRECTION_RTOL = 1e-9

#: Share of node pairs whose x, y and z entries may differ for the rest to count as one isotropic mass.
DIRECTION_ODD_SHARE = 1e-2


def direction_mismatches(M, dofs) -> list[tuple[int, int, float, float]] | None:
    """Entries of a mass whose x, y and z values for one pair of nodes differ, as ``(i, j, M_ij, usual)``.

    A continuum's mass (consistent or lumped) and an isotropic point mass hold the same value for
    ``u_x``, ``u_y`` and ``u_z`` of every pair of nodes and couple no two translations: every value is
    written three times, so a value changed in one direction (a digit, an exponent) stands out
    against the other two. ``usual`` is the value the other directions hold (the most common one;
    0 where the entry is missing in this direction). Pairs are compared where both nodes have the
    direction and neither has rotational DOF (a beam's consistent axial and transverse masses differ); an
    entry coupling two translations is odd too (``usual`` 0). None when more than
    :data:`DIRECTION_ODD_SHARE` of the entries couple two translations or of the pairs differ (not an
    isotropic mass: beams' and shells' rotations are not compared, nodes in local frames couple
    translations). The entries listed are the odd ones out, upper triangle.
    """
    if dofs is None or len(dofs) != M.shape[0]:
        return None
    d = np.asarray(dofs)[:, 1]
    trans = (d >= 1) & (d <= 3)
    rotating = np.isin(np.asarray(dofs)[:, 0], np.asarray(dofs)[d >= 4, 0])
    trans &= ~rotating  # a beam's axial and transverse masses differ: nodes with rotations are not compared
    coo = M.tocoo()
    keep = trans[coo.row] & trans[coo.col] & (coo.data != 0)
    r, c, v = coo.row[keep], coo.col[keep], coo.data[keep]
    across = d[r] != d[c]
    if r.size == 0 or np.count_nonzero(across) > DIRECTION_ODD_SHARE * r.size:
        return None
    if not across.any() and _alike(M, dofs, trans):
        return []
    upper = r <= c
    out = [(int(i), int(j), float(x), 0.0) for i, j, x in zip(r[upper & across], c[upper & across], v[upper & across])]
    r, c, v = r[upper & ~across], c[upper & ~across], v[upper & ~across]
    nodes, node = np.unique(np.asarray(dofs)[:, 0], return_inverse=True)
    has = np.zeros((nodes.size, 3), dtype=bool)
    has[node[trans], d[trans] - 1] = True
    key = node[r].astype(np.int64) * nodes.size + node[c]
    order = np.lexsort((v, key))
    key, r, c, v = key[order], r[order], c[order], v[order]
    start = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
    count = np.diff(np.r_[start, key.size])
    expected = (has[node[r[start]]] & has[node[c[start]]]).sum(axis=1)
    scale = np.maximum.reduceat(np.abs(v), start)
    spread = np.maximum.reduceat(v, start) - np.minimum.reduceat(v, start)
    odd = (count != expected) | (spread > DIRECTION_RTOL * scale)
    if np.count_nonzero(expected >= 2) == 0:
        return out
    if np.count_nonzero(odd) > DIRECTION_ODD_SHARE * np.count_nonzero(expected >= 2):
        return None
    for g in np.flatnonzero(odd):
        lo, hi = start[g], start[g] + count[g]
        vals = v[lo:hi]
        same = np.abs(vals[:, None] - vals[None, :]) <= DIRECTION_RTOL * scale[g]
        votes = same.sum(axis=1)
        if count[g] < expected[g] and votes.max() == 1:  # present in fewer directions, and they disagree:
            usual = 0.0  # the missing one(s) may be the damage; name the first given
        else:
            usual = float(vals[int(np.argmax(votes))])
        if count[g] < expected[g] and votes.max() == count[g]:  # the given ones agree: the entry lost
            missing = sorted(set(np.flatnonzero(has[node[r[lo]]] & has[node[c[lo]]]) + 1) - set(d[r[lo:hi]]))
            i = _equation(dofs, nodes[node[r[lo]]], missing[0])
            j = _equation(dofs, nodes[node[c[lo]]], missing[0])
            out.append((i, j, 0.0, usual))
            continue
        for k in range(lo, hi):
            if abs(v[k] - usual) > DIRECTION_RTOL * scale[g]:
                out.append((int(r[k]), int(c[k]), float(v[k]), usual))
    return out


def _alike(M, dofs, trans) -> bool:
    """Whether the x, y and z blocks of ``M`` over the equations ``trans`` are one matrix on the same nodes (a
    sound solid's mass: no sort)."""
    first, *rest = _parts(M, dofs, (1, 2, 3), trans)
    return all(_same(first, part) for part in rest)


def _equation(dofs, node, direction) -> int:
    return int(np.flatnonzero((np.asarray(dofs)[:, 0] == node) & (np.asarray(dofs)[:, 1] == direction))[0])


def check_mass_directions(model) -> None:
    """Warn (``FlexmorWarning`` naming ``model.source``) where the x, y and z values of the mass of one pair of
    nodes differ in a mass that is otherwise the same in every direction (:func:`direction_mismatches`)."""
    found = direction_mismatches(model.M, model.dofs)
    if not found:
        return
    i, j, v, usual = found[0]
    more = f" (and {len(found) - 1} more)" if len(found) > 1 else ""
    entry = f"entry ({i + 1}, {j + 1}) = {v:.6g} ({model.describe_dof(i)}, {model.describe_dof(j)})"
    if model.dofs[i, 1] != model.dofs[j, 1]:
        what = (f"couples no two directions of motion except at {entry}{more}: a changed value (a digit, or an "
                "explicit zero turned into a number)")
    else:
        what = (f"holds the same value for x, y and z of each pair of nodes except at {entry}, where the other "
                f"directions hold {usual:.6g}{more}: a changed value (a digit or an exponent), or a point mass that "
                "differs by direction")
    warnings.warn(FlexmorWarning(f"{model.source or model.name}: the mass matrix {what}"), stacklevel=3)
