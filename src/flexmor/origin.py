"""Where a reduced body came from: the fingerprint of its full model, and the checks against it.

A reduced body is only meaningful together with the model it was projected from: its error
measures, its export (the inertia invariants integrate over the full mass matrix) and the
expansion ``q ≈ V qr`` all assume that model. :func:`fingerprint` records what identifies
it, cheaply (O(nnz)): the number of DOF and nodes, hashes of the equation map and of ``K``,
``M`` (and ``D`` when given with the model), and the damping. :func:`check_origin` compares a
body's fingerprint with a model and raises a :class:`~flexmor.errors.ModelError` that names
the body file and what differs. Bodies written before fingerprints existed cannot be
checked; reading such a file warns with a :class:`~flexmor.errors.FlexmorWarning`.

:func:`reference_model` gives the model a body is judged against: its couplings applied
and **the body's own damping** (a damping asked for on the command line that differs from
the body's is refused, not silently used).
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
import weakref
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from .damping import Damping, GivenDamping, ModalDamping, NoDamping, Rayleigh, describe_damping
from .errors import ModelError, OptionError
from .linalg.distributed import is_partitioned

__all__ = ["applied_to", "with_body_damping", "fingerprint", "matrix_hash", "check_origin", "origin_differences",
           "reference_model", "same_damping", "describe_damping"]

#: Version of the fingerprint record (bumped when what it hashes changes).
FINGERPRINT_VERSION = 1

_HASHES: dict[int, str] = {}  # id(matrix) -> hash, dropped when the matrix is collected


def _digest(*arrays) -> str:
    h = hashlib.sha256()
    for a in arrays:
        a = np.ascontiguousarray(a)
        h.update(str(a.dtype.str).encode() + str(a.shape).encode())
        h.update(a.view(np.uint8).reshape(-1) if a.size else b"")
    return h.hexdigest()[:16]


def matrix_hash(A) -> str | None:
    """Hash of a sparse matrix: its CSR arrays (indices sorted, duplicates summed, float64 values).

    Remembered per matrix object while it lives; None for a matrix whose rows are spread over
    MPI ranks.
    """
    if A is None or is_partitioned(A):
        return None
    key = id(A)
    if key in _HASHES:
        return _HASHES[key]
    B = A
    if not (sp.issparse(B) and B.format == "csr" and B.dtype == np.float64 and B.has_canonical_format):
        B = sp.csr_matrix(A, dtype=np.float64, copy=True)  # a model's matrices are canonical CSR: no copy
        B.sum_duplicates()
        B.sort_indices()
    value = _digest(np.asarray(B.shape, np.int64), B.indptr.astype(np.int64), B.indices.astype(np.int64), B.data)
    try:
        weakref.finalize(A, _HASHES.pop, key, None)
        _HASHES[key] = value
    except TypeError:  # not weak-referenceable: not remembered
        pass
    return value


def fingerprint(model) -> dict:
    """The fingerprint of ``model`` (as a reduced body records it): JSON-ready dict.

    Keys: ``version``, ``name``, ``source`` (file read), ``n_dof``, ``n_nodes``, ``dof_map``
    (hash of the equation map, None without one), ``K``, ``M``, ``D`` (hashes; ``D`` only when
    the damping matrix came with the model), ``damping`` (stored form). ``flexmor reduce``
    adds the ``couplings``, ``interfaces`` and ``selections`` it applied (their effect on the
    model is in the hashes already).
    """
    dofs = getattr(model, "dofs", None)
    given = isinstance(model.damping, GivenDamping)
    return {"version": FINGERPRINT_VERSION, "name": model.name, "source": str(model.source or ""),
            "n_dof": int(model.n_dof), "n_nodes": int(model.n_nodes),
            "dof_map": None if dofs is None else _digest(np.asarray(dofs, np.int64)),
            "K": matrix_hash(model.K), "M": matrix_hash(model.M), "D": matrix_hash(model.D) if given else None,
            "damping": model.damping.to_dict()}


_MATRIX_WORDS = {"K": "stiffness matrix K", "M": "mass matrix M", "D": "damping matrix D"}


def origin_differences(recorded: dict, model) -> list[str]:
    """What differs between a body's recorded fingerprint and ``model`` (an FEModel, or its
    :func:`fingerprint`): phrases completing "the body was reduced from a model with ..." (empty
    if nothing differs). The damping is not compared here (see :func:`reference_model`)."""
    now = model if isinstance(model, dict) else fingerprint(model)
    if recorded.get("n_dof") != now["n_dof"]:
        n = recorded.get("n_dof")
        return [f"{n:,} DOF, this model has {now['n_dof']:,}" if isinstance(n, int)
                else f"an unknown number of DOF ({n!r}), this model has {now['n_dof']:,}"]
    out = []
    if recorded.get("dof_map") and now["dof_map"] and recorded["dof_map"] != now["dof_map"]:
        out.append("a different equation map (node and direction of each DOF)")
    diff = [k for k in ("K", "M", "D") if recorded.get(k) and now[k] and recorded[k] != now[k]]
    if recorded.get("D") and now["D"] is None:
        diff.append("D")
    if diff:
        out.append("a different " + " and ".join(_MATRIX_WORDS[k] for k in diff))
    return out


def check_origin(body, model, path=None, *, couplings=(), label: str | None = None,
                 advice: str = "give the model the body was reduced from") -> None:
    """Refuse ``model`` when it is not the one ``body`` was reduced from.

    Parameters
    ----------
    body : ReducedModel
    model : FEModel or dict
        The model, or its :func:`fingerprint` (then ``label`` names it).
    path : str or path-like, optional
        The body's file, naming the body in the message (else its method and order do).
    couplings : sequence of str
        Those applied to ``model`` for the body (named in the message).
    label : str, optional
        The model in the message (default: its file, with the couplings).
    advice : str
        The message's last words: what to do.

    Raises
    ------
    ModelError
        Naming the body, the model it came from and what differs (DOF count, equation map, K, M,
        D). A body without a fingerprint (made by hand or by another program) cannot be checked;
        reading a flexmor body file without one warns (:mod:`flexmor.io.hdf5`).
    """
    recorded = getattr(body, "origin", None) or {}
    diffs = origin_differences(recorded, model) if recorded else []
    if not diffs:
        return
    name = (f"body {Path(str(path)).name}" if path is not None
            else f"body ({body.method or 'reduced'}, order {body.order})")
    where = label if label is not None else (model.source or model.name) + (
        f" with {', '.join(couplings)}" if couplings else "")
    came = recorded.get("source") or recorded.get("name") or "unknown"
    read_in = _units_advice(body, model)
    preload = _preload_advice(body, model)
    raise ModelError(f"{name} was reduced from a model with {'; '.join(diffs)} (the body's model: {came}; "
                     f"this model: {where}); {read_in or preload or advice}",
                     params=("units",) if read_in else ("preload",) if preload else ())


def _preload_advice(body, model) -> str:
    """What to do when ``body`` was reduced with another preload than ``model`` has (or "")."""
    if isinstance(model, dict):
        return ""

    def specs(record):
        return ", ".join(map(str, (record or {}).get("specs", []))) or None

    body_rec, model_rec = (getattr(body, "info", None) or {}).get("preload"), getattr(model, "preload", None)
    theirs, ours = specs(body_rec), specs(model_rec)
    if theirs == ours:
        mine, yours = ((r or {}).get("material") if isinstance(r, dict) else None for r in (body_rec, model_rec))
        if theirs and mine != yours:
            return (f"the body's preload {theirs} was stressed with "
                    + ("a material given in place of the deck's" if mine else "the deck's materials")
                    + ", this model's with " + ("another material" if yours and mine else
                                                "a material given in place of the deck's" if yours
                                                else "the deck's materials")
                    + ": give the body's --material (or none) with the model")
        return ""
    return (f"the body was reduced with {'the preload ' + theirs if theirs else 'no preload'} (its K holds the "
            f"geometric stiffness), this model has {'the preload ' + ours if ours else 'none'}: give the body's "
            "preload (or none) with the model")


def _units_advice(body, model) -> str:
    """What to do when ``body``'s model was read in another unit system than ``model`` (or "")."""
    if isinstance(model, dict):
        return ""
    theirs, ours = getattr(body, "units", None), getattr(model, "units", None)
    if theirs == ours:
        return ""
    if theirs is None:
        return f"the body's model was read as given, this one in {ours}: read the model as given (no units)"
    return (f"the body's model was read in {theirs}, this one {'in ' + ours if ours else 'as given'}: give units "
            f"{theirs} with the model")


def same_damping(a: Damping, b: Damping, rtol: float = 1e-9) -> bool:
    """Whether two dampings are the same: of one kind, with Rayleigh coefficients (modal damping: the
    ratio) within ``rtol``."""
    if type(a).kind != type(b).kind:
        return False
    if isinstance(a, ModalDamping):  # the ratio in every mode; the band only places its sparse realization
        return math.isclose(a.zeta, b.zeta, rel_tol=rtol, abs_tol=0.0)
    if isinstance(a, Rayleigh):
        return all(math.isclose(x, y, rel_tol=rtol, abs_tol=0.0) for x, y in ((a.alpha, b.alpha), (a.beta, b.beta)))
    return True


def reference_model(model, body, path, *, damping: Damping | None = None):
    """The full model ``body`` is judged against: its selections and couplings, the body's damping.

    Parameters
    ----------
    model : FEModel
        The model as read (without damping asked for on the command line).
    body : ReducedModel
        The reduced body, read from ``path`` (named in errors).
    damping : Damping, optional
        Damping asked for by the user (``rayleigh``, ``modal_damping`` or ``band_rayleigh`` of
        :func:`flexmor.workflow.damping_of`); must be the body's own, else an :class:`OptionError`.

    Returns
    -------
    FEModel
        ``model`` with the body's node selections (``body.selections``) and couplings
        (``body.couplings``) applied, checked against the body's fingerprint
        (:func:`check_origin`), with the body's damping: its Rayleigh or modal damping, none for
        an undamped body, the model's own ``D`` for a body reduced with it.
    """
    name = Path(str(path)).name
    if damping is not None and not isinstance(damping, NoDamping) and not same_damping(damping, body.damping):
        raise OptionError(f"body {name} was reduced with damping {describe_damping(body.damping)}; the damping "
                          f"asked for here ({describe_damping(damping)}) differs. A body is compared against the "
                          "full model with its own damping: drop rayleigh / modal_damping / band_rayleigh, or "
                          "reduce again with it", params=("rayleigh", "modal_damping", "band_rayleigh"))
    selected, coupled = applied_to(model, body)
    ref = selected if coupled is None else coupled.model
    check_origin(body, ref, path, couplings=tuple(body.couplings))
    return with_body_damping(ref, body, path)


def applied_to(model, body):
    """``(selected, coupled)``: ``model`` (as read) with the body's node selections
    (``body.selections``), and the :class:`flexmor.couplings.Coupled` of its couplings
    (``body.couplings``) on that model, None without couplings. A selection whose set the model
    has already (a model the selections were applied to) is not made again. Not checked against the
    body's fingerprint (:func:`check_origin` does that)."""
    selected = model
    selections = body.selections
    if selections:
        from .selection import parse_selection, with_selections

        selected = with_selections(selected, [s for s in selections
                                              if parse_selection(s)[0].upper() not in model.node_sets])
    couplings = list(body.couplings)
    if not couplings:
        return selected, None
    from .couplings import couple

    return selected, couple(selected, couplings)


def with_body_damping(ref, body, path):
    """``ref`` (the model ``body`` was reduced on) with the body's damping: its Rayleigh or modal
    damping, none for an undamped body, the model's own ``D`` for a body reduced with it.

    Raises
    ------
    ModelError
        The body was reduced with a damping matrix of the model that ``ref`` lacks, or without
        damping from a model that has one of its own.
    """
    name = Path(str(path)).name
    bd = body.damping
    if isinstance(bd, Rayleigh):
        return ref.with_damping(bd)
    if isinstance(bd, NoDamping) and ref.D is not None:
        if isinstance(ref.damping, GivenDamping):
            raise ModelError(f"body {name} was reduced without damping, but {ref.source or ref.name} has a damping "
                             "matrix of its own", params=("model",))
        return dataclasses.replace(ref, D=None, damping=NoDamping())
    if isinstance(bd, GivenDamping) and ref.D is None:
        raise ModelError(f"body {name} was reduced with the damping matrix given with its model, but "
                         f"{ref.source or ref.name} has none", params=("model",))
    return ref
