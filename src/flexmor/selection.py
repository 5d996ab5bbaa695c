"""Node selection: by set name, box, plane, cylinder (a hole), sphere and nearest node.

Each function returns the sorted node ids it selects from ``model.node_ids``/``model.xyz``
(length unit of the model). A selection can become a named node set with
:func:`add_node_set`, so that ports, interfaces and couplings can name it (``HOLE:y``,
``--interface HOLE@rbe2``). On the command line, ``--select NAME=KIND:NUMBERS`` does the same:

=================================================  ==========================================
``set:OTHER``                                      the nodes of an existing set
``box:x0,y0,z0,x1,y1,z1``                          ``x0 <= x <= x1`` ... (+- tol)
``plane:x0,y0,z0,nx,ny,nz[,tol]``                  distance from the plane ``<= tol``
``cylinder:x0,y0,z0,dx,dy,dz,r[,tol[,s0,s1]]``     distance from the axis within ``r +- tol``
                                                   (axial position ``s0 <= s <= s1``, measured
                                                   from the point along the unit direction)
``sphere:x0,y0,z0,r[,tol]``                        distance from the centre within ``r +- tol``
``nearest:x,y,z``                                  the one node nearest to the point
=================================================  ==========================================

The default tolerance is ``1e-6`` times the diagonal of the model's bounding box (nodes of a
mesh lie on the surfaces they model up to round-off); give a larger one for curved surfaces
meshed with straight-edged elements.
"""

from __future__ import annotations

import dataclasses
import re

import numpy as np

from .errors import PortError, did_you_mean
from .model import FEModel

__all__ = ["add_node_set", "box", "cylinder", "nearest", "nearest_report", "parse_selection", "plane", "select",
           "sphere", "with_selections"]

_REL_TOL = 1e-6


def _xyz(model: FEModel) -> np.ndarray:
    if model.n_nodes == 0:
        raise PortError("the model has no node table, so nodes cannot be selected by position")
    return model.xyz


def _tol(model: FEModel, tol) -> float:
    if tol is not None:
        tol = float(tol)
        if not np.isfinite(tol) or tol < 0:
            raise PortError(f"selection tolerance must be >= 0, got {tol}")
        return tol
    x = _xyz(model)
    return _REL_TOL * max(float(np.linalg.norm(x.max(axis=0) - x.min(axis=0))), 1e-300)


def _vec(v, what: str) -> np.ndarray:
    a = np.asarray(v, dtype=np.float64).reshape(-1)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise PortError(f"{what} must be three finite numbers, got {v!r}")
    return a


def _unit(v, what: str) -> np.ndarray:
    a = _vec(v, what)
    n = np.linalg.norm(a)
    if n == 0:
        raise PortError(f"{what} must not be zero")
    return a / n


def _ids(model: FEModel, mask, what: str) -> np.ndarray:
    ids = np.sort(model.node_ids[mask])
    if ids.size == 0:
        raise PortError(f"{what} selects no node")
    return ids


def box(model: FEModel, lo, hi, *, tol=None) -> np.ndarray:
    """Nodes with ``lo - tol <= xyz <= hi + tol`` in every coordinate."""
    lo, hi, t = _vec(lo, "box corner"), _vec(hi, "box corner"), _tol(model, tol)
    lo, hi = np.minimum(lo, hi), np.maximum(lo, hi)
    x = _xyz(model)
    return _ids(model, np.all((x >= lo - t) & (x <= hi + t), axis=1), f"box {lo.tolist()}..{hi.tolist()}")


def plane(model: FEModel, point, normal, *, tol=None) -> np.ndarray:
    """Nodes within ``tol`` of the plane through ``point`` with normal ``normal``."""
    p, nrm, t = _vec(point, "plane point"), _unit(normal, "plane normal"), _tol(model, tol)
    d = np.abs((_xyz(model) - p) @ nrm)
    return _ids(model, d <= t, f"plane through {p.tolist()} (closest node at {d.min():.3g})")


def cylinder(model: FEModel, point, direction, radius, *, tol=None, span=None) -> np.ndarray:
    """Nodes at distance ``radius +- tol`` from the axis (e.g. the surface of a hole).

    ``span=(s0, s1)`` limits the axial position ``s = (x - point) . direction/|direction|``.
    """
    p, a, t = _vec(point, "axis point"), _unit(direction, "axis direction"), _tol(model, tol)
    r = float(radius)
    if not np.isfinite(r) or r < 0:
        raise PortError(f"cylinder radius must be >= 0, got {radius}")
    rel = _xyz(model) - p
    s = rel @ a
    dist = np.linalg.norm(rel - np.outer(s, a), axis=1)
    mask = np.abs(dist - r) <= t
    if span is not None:
        s0, s1 = sorted(float(v) for v in span)
        mask &= (s >= s0 - t) & (s <= s1 + t)
    return _ids(model, mask, f"cylinder r={r:g} about {p.tolist()} + s {a.round(6).tolist()} (closest radius "
                             f"{dist[np.argmin(np.abs(dist - r))]:.6g})")


def sphere(model: FEModel, center, radius, *, tol=None) -> np.ndarray:
    """Nodes at distance ``radius +- tol`` from ``center``."""
    c, t = _vec(center, "sphere centre"), _tol(model, tol)
    d = np.linalg.norm(_xyz(model) - c, axis=1)
    return _ids(model, np.abs(d - float(radius)) <= t, f"sphere r={radius:g} about {c.tolist()}")


def nearest(model: FEModel, point) -> int:
    """The node nearest to ``point`` (the lowest id among equally near ones)."""
    p = _vec(point, "point")
    d = np.linalg.norm(_xyz(model) - p, axis=1)
    cand = np.flatnonzero(d <= d.min() * (1 + 1e-12))
    return int(np.min(model.node_ids[cand]))


_NUMS = {"box": (6, 6), "plane": (6, 7), "cylinder": (7, 10), "sphere": (4, 5), "nearest": (3, 3)}


def select(model: FEModel, spec: str) -> np.ndarray:
    """Node ids selected by ``KIND:NUMBERS`` (or ``set:NAME``); see the module docstring."""
    kind, _, rest = str(spec).partition(":")
    kind = kind.strip().lower()
    if kind == "set":
        name = rest.strip().upper()
        if name not in model.node_sets:
            known = ", ".join(sorted(model.node_sets)) or "none"
            raise PortError(f"selection {spec!r}: no node set {name!r}; {did_you_mean(name, model.node_sets)}"
                            f"(sets: {known})")
        return np.sort(model.node_sets[name])
    if kind not in _NUMS:
        raise PortError(f"selection {spec!r}: unknown kind {kind!r}; use one of: set, {', '.join(_NUMS)}")
    try:
        v = [float(x) for x in rest.split(",")] if rest.strip() else []
    except ValueError:
        raise PortError(f"selection {spec!r}: expected comma-separated numbers after '{kind}:'") from None
    lo, hi = _NUMS[kind]
    if not lo <= len(v) <= hi or kind == "cylinder" and len(v) == 9:
        want = str(lo) if lo == hi else f"{lo} to {hi}" + (" (not 9)" if kind == "cylinder" else "")
        raise PortError(f"selection {spec!r}: {kind} takes {want} numbers, got {len(v)}")
    if kind == "box":
        return box(model, v[:3], v[3:])
    if kind == "plane":
        return plane(model, v[:3], v[3:6], tol=v[6] if len(v) > 6 else None)
    if kind == "cylinder":
        return cylinder(model, v[:3], v[3:6], v[6], tol=v[7] if len(v) > 7 else None,
                        span=v[8:10] if len(v) == 10 else None)
    if kind == "sphere":
        return sphere(model, v[:3], v[3], tol=v[4] if len(v) > 4 else None)
    return np.array([nearest(model, v)], dtype=np.int64)


def parse_selection(text: str) -> tuple[str, str]:
    """Split ``NAME=KIND:NUMBERS`` into ``(NAME, 'KIND:NUMBERS')``."""
    m = re.match(r"^\s*([A-Za-z_][\w\-.]*)\s*=\s*(\S.*)$", str(text))
    if not m:
        raise PortError(f"selections {text!r}: expected NAME=KIND:NUMBERS, e.g. HOLE=cylinder:0,0,0,0,0,1,0.01",
                        params=("selections",))
    return m.group(1).upper(), m.group(2).strip()


def add_node_set(model: FEModel, name: str, nodes) -> FEModel:
    """A copy of ``model`` with the node set ``name`` (upper-cased); an existing set is refused."""
    key = str(name).upper()
    if key in model.node_sets:
        raise PortError(f"node set {key!r} exists already; choose another name")
    sets = dict(model.node_sets)
    sets[key] = np.unique(np.asarray(nodes, dtype=np.int64))
    return dataclasses.replace(model, node_sets=sets)


def nearest_report(model: FEModel, selections) -> list[dict]:
    """For each ``NAME=nearest:x,y,z`` of ``selections`` (applied to ``model``): ``name``,
    ``point``, the ``node`` chosen, its ``xyz``, the ``distance`` (model length units) and
    ``outside``: the point lies farther from its node than a tenth of the model's largest extent
    (a point outside the body, or given in other units)."""
    out = []
    xyz = _xyz(model)
    size = float(np.max(np.ptp(xyz, axis=0))) if len(xyz) else 0.0
    for text in selections or ():
        name, spec = parse_selection(text)
        kind, _, rest = spec.partition(":")
        if kind.strip().lower() != "nearest":
            continue
        point = np.array([float(v) for v in rest.split(",")])
        node = int(model.node_sets[name][0])
        at = xyz[np.flatnonzero(model.node_ids == node)[0]]
        dist = float(np.linalg.norm(at - point))
        out.append({"name": name, "point": point.tolist(), "node": node, "xyz": at.tolist(), "distance": dist,
                    "outside": bool(dist > 0.1 * size)})
    return out


def with_selections(model: FEModel, selections) -> FEModel:
    """Apply ``NAME=KIND:NUMBERS`` selections in order (later ones may use ``set:`` of earlier ones)."""
    for text in selections or ():
        name, spec = parse_selection(text)
        model = add_node_set(model, name, select(model, spec))
    return model
