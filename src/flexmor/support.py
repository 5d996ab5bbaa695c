"""The ways a body is held at its interfaces: the equations a clamp or a pin holds.

An interface is the master node of a coupling (``SET@rbe2``/``SET@rbe3``) or a Craig-Bampton
``interface`` node or set; holding it ``clamped`` holds all six directions of its nodes, ``pinned`` the
three translations (:data:`HELD`). The body held in its joints (:mod:`flexmor.analysis.mounted`) and the
stresses of its load stiffening (:mod:`flexmor.stiffening`) use these support cases.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .couplings import coupling_masters
from .errors import ModelError, check_choice

__all__ = ["AS_SUPPORTED", "HELD", "Support", "supports"]

#: Ways of holding an interface: the directions held at each of its nodes.
HELD = {"clamped": (1, 2, 3, 4, 5, 6), "pinned": (1, 2, 3)}

#: The support of a model without rigid-body motion, held as it is (:func:`static_record`).
AS_SUPPORTED = "supported"


@dataclass(frozen=True)
class Support:
    """One interface held one way: ``interface`` (set or SPEC), its ``node`` (the master node, None
    for a set of several nodes), ``held`` (a key of :data:`HELD`) and the held equations ``eqs``."""

    interface: str
    node: int | None
    held: str
    eqs: tuple


def _interface_nodes(model, target: str) -> np.ndarray:
    key = str(target).replace(" ", "").upper()
    if key in model.node_sets:
        return np.asarray(model.node_sets[key], dtype=np.int64)
    if key.lstrip("-").isdigit() and model.has_node(int(key)):
        return np.array([int(key)], dtype=np.int64)
    raise ModelError(f"interface {target!r} is neither a node set nor a node of {model.name}",
                     params=("interfaces",))


def supports(model, body=None, *, interfaces=None, held=("clamped", "pinned")) -> list[Support]:
    """The support cases of a body: each interface, held each way of ``held``.

    Parameters
    ----------
    model : FEModel
        The coupled model (its node sets hold the couplings' master nodes, e.g. ``HOLE@RBE2``).
    body : ReducedModel, optional
        Its couplings (``body.couplings``; without them the model's coupling masters,
        :func:`flexmor.couplings.coupling_masters`) and its interface nodes or sets
        without coupling (``info['options']['interface']``, not ``SET:DIR``) are the interfaces.
    interfaces : sequence of str, optional
        Node sets, nodes or coupling SPECs given explicitly (overrides the body's).
    held : sequence of str
        Keys of :data:`HELD`.
    """
    for h in held:
        check_choice("held", h, HELD)
    if model.dofs is None:
        return []
    if interfaces is None:
        info = {} if body is None else body.info
        names = ([str(c).split(":")[0] for c in (() if body is None else body.couplings)]
                 or [m["name"] for m in coupling_masters(model)])
        interfaces = names + [str(s) for s in (info.get("options") or {}).get("interface") or ()
                              if not set("@:") & set(str(s))]
    out, seen = [], set()
    for name in interfaces:
        key = str(name).replace(" ", "").upper()
        if key in seen:
            continue
        seen.add(key)
        nodes = _interface_nodes(model, key)
        done = []
        for h in held:
            eqs = np.flatnonzero(np.isin(model.dofs[:, 0], nodes) & np.isin(model.dofs[:, 1], HELD[h]))
            if eqs.size and not any(np.array_equal(eqs, d) for d in done):  # a solid node: pinned is clamped
                done.append(eqs)
                out.append(Support(key, int(nodes[0]) if nodes.size == 1 else None, h, tuple(int(e) for e in eqs)))
    return out
