"""Moving loads: a force whose point moves along a path of nodes, one reduced body for every position.

A moving load ``SET:DIR`` (``SET:DIR@x`` to order the path by a coordinate) is a force in direction ``DIR``
whose point ``s`` (arc length along the path, in the model's length unit) moves over the nodes of the node set
``SET``. Its input matrix is

``B(s) = B_path w(s)``

with ``B_path`` (n_dof, N) the unit forces at the path's ``N`` nodes and ``w(s)`` the **linear interpolation
between consecutive path nodes** (hat functions of the arc length: the force is shared by the two nodes of the
segment it stands on, in proportion to its distance from each); its output, the **deflection under the load**, is
``y(s) = w(s)^T B_path^T q``.

The path is ordered by the coordinate given (``@x``), else as a **nearest-neighbour chain** that starts at the
node farthest along the set's principal axis (the record says which).

**Compression.** Every path node an input would give a method ``N`` inputs. The path's inputs are compressed by
sampling its transfer matrix ``[C; B_path^T] (s^2 M + s D + K)^{-1} B_path`` at ``0`` and at points over the band
(each sample scaled to unit norm, so that the quasi-static response does not hide the resonant ones), and keeping
the right singular vectors ``W`` (N, k) whose singular values exceed ``tol`` times the largest
(:func:`flexmor.reduction.svdmor.port_directions`). The ``k`` compressed loads ``B_path W`` (real combinations of
path-node forces) become inputs, and their collocated outputs outputs, of the study's ports
(:func:`with_moving_loads`): every method that takes inputs builds its basis for them, and a method that does not
(Craig-Bampton, modal, Guyan) gets their static responses as residual vectors. The body itself keeps the exact
path: ``V^T B_path`` (r, N) (:func:`path_record`), so that ``B_r(s) = (V^T B_path) w(s)``.

**Judged over the path** (:func:`judge_path`): the band error of the body's response to a load at ``s`` (at the
ports' outputs and under the load) against the full model's, at every path node and midpoint, refined within the
worst segments; the path maximum and its position. :func:`crossing` integrates a force crossing the path at a
speed in time (Newmark, :func:`flexmor.dynamics.time.simulate`) for both.
"""

from __future__ import annotations

import dataclasses
import logging
import time
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .errors import OptionError, PortError, did_you_mean
from .linalg.context import as_solver
from .model import DIRECTIONS, FEModel, direction_code, direction_name
from .ports import path_matrix, with_path_loads
from .reduction.residual import static_solve
from .rigid import rigid_body_modes

__all__ = ["MovingLoad", "parse_moving_load", "moving_path", "hat_weights", "Compression", "compress",
           "with_moving_loads", "path_record", "judge_path", "judge_paths", "moving_key", "crossing", "DEFAULT_TOL",
           "SAMPLE_POINTS"]

log = logging.getLogger(__name__)

#: Default relative singular value below which a compressed direction of the path's inputs is dropped.
DEFAULT_TOL = 3e-3
#: Number of points over the band (besides 0) at which the path's transfer matrix is sampled.
SAMPLE_POINTS = 12
#: Relative damping of the sampling points ``s = 2 pi f (ZETA + i)``: off the frequency axis, so that an
#: undamped model is regular at every point.
SAMPLE_ZETA = 0.05
#: Positions per segment tried when the worst segments are refined.
REFINE = 16
#: Segments refined (those around the worst node or midpoint).
REFINE_SEGMENTS = 4


@dataclass(frozen=True)
class MovingLoad:
    """A path of nodes over which a unit force in one direction moves.

    Attributes
    ----------
    spec : str
        ``SET:DIR`` or ``SET:DIR@AXIS`` as given.
    set_name : str
    direction : int
        Direction code (``flexmor.model.DIRECTIONS``).
    nodes : ndarray of int, shape (N,)
        The path's node ids in path order.
    s : ndarray, shape (N,)
        Arc length of each node from the first (model length unit), increasing.
    ordering : str
        How the nodes were ordered (``by x`` or the nearest-neighbour chain from node ...).
    B : scipy.sparse.csc_matrix, shape (n_dof, N)
        Unit force at each path node (a column of zeros where the direction is constrained).
    """

    spec: str
    set_name: str
    direction: int
    nodes: np.ndarray
    s: np.ndarray
    ordering: str
    B: sp.csc_matrix

    @property
    def length(self) -> float:
        """Length of the path (model length unit)."""
        return float(self.s[-1])

    @property
    def name(self) -> str:
        """``SET:DIR`` (the name of the path's ports)."""
        return f"{self.set_name}:{direction_name(self.direction)}"

    @property
    def node_names(self) -> list[str]:
        """One port name per path node: ``SET#NODE:DIR``."""
        d = direction_name(self.direction)
        return [f"{self.set_name}#{int(k)}:{d}" for k in self.nodes]

    def weights(self, s) -> np.ndarray:
        """``w(s)``, shape (len(s), N): :func:`hat_weights` of this path."""
        return hat_weights(self.s, s)

    def record(self) -> dict:
        """The path as JSON values (nodes, arc lengths, ordering, interpolation)."""
        return {"spec": self.spec, "set": self.set_name, "direction": direction_name(self.direction),
                "nodes": [int(k) for k in self.nodes], "s": [float(v) for v in self.s], "length": self.length,
                "ordering": self.ordering, "interpolation": "linear between consecutive path nodes (arc length)"}


def parse_moving_load(text) -> tuple[str, int, int | None]:
    """``SET:DIR`` or ``SET:DIR@AXIS`` -> ``(set name, direction code, axis 0-2 or None)``."""
    spec = str(text).strip()
    body, _, axis = spec.partition("@")
    target, sep, d = body.rpartition(":")
    if not sep or not target.strip():
        raise OptionError(f"moving load {spec!r}: give SET:DIR (a node set of the path and the force's direction, "
                          "e.g. TOP:z), optionally @x, @y or @z to order the path by that coordinate",
                          params=("moving_load",))
    if d.strip().lower() not in DIRECTIONS or direction_code(d) > 3:
        raise OptionError(f"moving load {spec!r}: the force's direction must be x, y or z, got {d!r}",
                          params=("moving_load",))
    ax = None
    if axis:
        if axis.strip().lower() not in ("x", "y", "z"):
            raise OptionError(f"moving load {spec!r}: order the path by x, y or z, got @{axis}",
                              params=("moving_load",))
        ax = "xyz".index(axis.strip().lower())
    return target.strip().upper(), direction_code(d), ax


def moving_path(model: FEModel, spec) -> MovingLoad:
    """The path of the moving load ``spec`` (:func:`parse_moving_load`) on ``model``: its nodes ordered, their
    arc lengths and the unit forces ``B_path``.

    Raises
    ------
    OptionError, PortError
        A SPEC that does not parse, an unknown or too small set (fewer than 2 nodes), a model without node
        coordinates or equations, two path nodes at the same point, or a path none of whose nodes has a free
        equation in the direction.
    """
    set_name, d, axis = parse_moving_load(spec)
    if model.n_nodes == 0 or model.dofs is None:
        raise PortError(f"moving load {spec!r}: the model has no node coordinates or no equation map, so a path of "
                        "nodes cannot be laid out", params=("moving_load",))
    if set_name not in model.node_sets:
        raise PortError(f"moving load {spec!r}: no node set {set_name!r}; {did_you_mean(set_name, model.node_sets)}"
                        f"(sets: {', '.join(sorted(model.node_sets)) or 'none'})", params=("moving_load",))
    nodes = np.unique(np.asarray(model.node_sets[set_name], dtype=np.int64))
    if nodes.size < 2:
        raise PortError(f"moving load {spec!r}: set {set_name!r} has {nodes.size} node(s); a path needs two or more",
                        params=("moving_load",))
    xyz = model.node_xyz(nodes)
    scale = max(float(np.ptp(xyz, axis=0).max()), 1e-300)
    if axis is not None:
        order = np.argsort(xyz[:, axis], kind="stable")
        ordering = f"by {'xyz'[axis]}"
        tie = np.flatnonzero(np.diff(xyz[order, axis]) <= 1e-9 * scale)
        if tie.size:
            a, b = nodes[order][tie[0]], nodes[order][tie[0] + 1]
            raise PortError(f"moving load {spec!r}: path nodes {int(a)} and {int(b)} share {'xyz'[axis]} = "
                            f"{xyz[order][tie[0], axis]:.6g}, so ordering by {'xyz'[axis]} is ambiguous: give a set of "
                            "one line of nodes, or leave out @AXIS for a nearest-neighbour chain",
                            params=("moving_load",))
    else:
        order, start = _chain(xyz)
        ordering = f"nearest-neighbour chain from node {int(nodes[start])} (the end of the set's principal axis)"
    nodes, xyz = nodes[order], xyz[order]
    step = np.linalg.norm(np.diff(xyz, axis=0), axis=1)
    if np.any(step <= 1e-12 * scale):
        k = int(np.argmin(step))
        raise PortError(f"moving load {spec!r}: path nodes {int(nodes[k])} and {int(nodes[k + 1])} lie at the same "
                        "point; a path visits each point once", params=("moving_load",))
    s = np.concatenate([[0.0], np.cumsum(step)])
    B = path_matrix(model, nodes, d)
    if B.nnz == 0:
        raise PortError(f"moving load {spec!r}: no node of {set_name!r} has a free equation in direction "
                        f"{direction_name(d)} (constrained?)", params=("moving_load",))
    return MovingLoad(str(spec).strip(), set_name, d, nodes, s, ordering, B)


def _chain(xyz: np.ndarray) -> tuple[np.ndarray, int]:
    """A nearest-neighbour chain through the points, from the one farthest along their principal axis."""
    c = xyz - xyz.mean(axis=0)
    axis = np.linalg.svd(c, full_matrices=False)[2][0]
    start = int(np.argmin(c @ axis))
    left = np.ones(len(xyz), bool)
    order = [start]
    left[start] = False
    for _ in range(len(xyz) - 1):
        d = np.linalg.norm(xyz - xyz[order[-1]], axis=1)
        d[~left] = np.inf
        nxt = int(np.argmin(d))
        order.append(nxt)
        left[nxt] = False
    return np.asarray(order), start


def hat_weights(nodes_s, s) -> np.ndarray:
    """Linear interpolation weights of positions ``s`` between path nodes at arc lengths ``nodes_s``:
    shape (len(s), N), each row two neighbours' shares summing to 1 (zero for a position off the path)."""
    nodes_s = np.asarray(nodes_s, float)
    s = np.atleast_1d(np.asarray(s, float))
    W = np.zeros((s.size, nodes_s.size))
    on = (s >= nodes_s[0]) & (s <= nodes_s[-1])
    j = np.clip(np.searchsorted(nodes_s, s, side="right") - 1, 0, nodes_s.size - 2)
    t = (s - nodes_s[j]) / (nodes_s[j + 1] - nodes_s[j])
    i = np.flatnonzero(on)
    W[i, j[i]] = 1.0 - t[i]
    W[i, j[i] + 1] += t[i]
    return W


@dataclass(frozen=True)
class Compression:
    """The compressed inputs of a path: ``B_path W``.

    Attributes
    ----------
    W : ndarray, shape (N, k)
        Orthonormal input directions in path-node space.
    singular_values : ndarray
        All singular values of the stacked (normalized) samples, descending.
    tol : float
        Relative singular value below which directions were dropped.
    points_hz : list of complex
        The sampling points (Hz; ``s = 2 pi p``).
    seconds : float
    """

    W: np.ndarray
    singular_values: np.ndarray
    tol: float
    points_hz: list
    seconds: float

    @property
    def k(self) -> int:
        """Number of compressed loads (directions kept)."""
        return self.W.shape[1]

    def record(self) -> dict:
        """As JSON values: ``directions``, ``tol``, ``W``, ``singular_values``, ``first_dropped`` (relative), the
        points."""
        sv = self.singular_values
        return {"directions": self.k, "tol": self.tol, "W": self.W.tolist(), "singular_values": [float(v) for v in sv],
                "first_dropped": float(sv[self.k] / sv[0]) if self.k < sv.size else None,
                "points_hz": [[float(p.real), float(p.imag)] for p in self.points_hz], "seconds": self.seconds}


def sample_points(band) -> list[complex]:
    """The points (Hz, complex) at which a path's transfer matrix is sampled: 0 and :data:`SAMPLE_POINTS` over
    ``band`` off the frequency axis by :data:`SAMPLE_ZETA`."""
    from .options import Band

    fmin, fmax = Band.of(band)
    return [0j, *(complex(SAMPLE_ZETA * f, f) for f in np.linspace(fmin, fmax, SAMPLE_POINTS))]


def compress(model, path: MovingLoad, band, *, tol: float = DEFAULT_TOL, outputs=None, solver=None) -> Compression:
    """The dominant input directions of ``path`` over ``band`` (module docstring).

    The path's transfer matrix ``H(s) = [C; B_path^T] (s^2 M + s D + K)^{-1} B_path`` is sampled at
    :func:`sample_points`; the column of each path node is divided by its largest norm over the samples (every
    position weighs alike: near a support, where the structure hardly moves, the local deformation under the load
    is the whole response), each sample is scaled to unit norm (the quasi-static sample does not hide the resonant
    ones), and the right singular vectors of the stacked samples with singular values above ``tol`` times the
    largest are kept. ``outputs`` (a sparse (p, n_dof) matrix: the study's outputs) join the path's deflections
    in ``C``. A node whose direction is held (no response) gets no direction.
    """
    from .ports import Ports
    from .reduction.svdmor import real_parts, sampled_transfer

    tol = float(tol)
    if not 0 < tol < 1:
        raise OptionError(f"the moving load's compression tolerance must lie in (0, 1), got {tol:g}",
                          params=("moving_load_tol",))
    t0 = time.perf_counter()
    C = path.B.T.tocsr() if outputs is None else sp.vstack([sp.csr_matrix(outputs), path.B.T]).tocsr()
    ports = Ports(B=path.B.tocsr(), C=C, input_names=path.node_names,
                  output_names=[f"y{i}" for i in range(C.shape[0])])
    Hs, used = sampled_transfer(model, ports, sample_points(band), solver=solver)
    col = np.max([np.linalg.norm(H, axis=0) for H in Hs], axis=0)
    scale = np.divide(1.0, col, out=np.zeros_like(col), where=col > 0)
    parts = []
    for H in Hs:
        H = H * scale
        parts += real_parts(H / max(float(np.linalg.norm(H)), np.finfo(float).tiny))
    _, sv, Wt = np.linalg.svd(np.vstack(parts), full_matrices=False)
    k = max(1, int(np.count_nonzero(sv > tol * sv[0])))
    W = np.linalg.qr(scale[:, None] * Wt[:k].T)[0]  # back to unit forces: the span of the scaled directions
    return Compression(W, sv, tol, [complex(u) / (2 * np.pi) for u in used], time.perf_counter() - t0)


def with_moving_loads(ports, paths, compressions):
    """``ports`` with each path's compressed loads ``B_path W`` appended as inputs and their collocated
    deflections ``W^T B_path^T`` as outputs (named ``SET:DIR~1`` ...), or those alone when ``ports`` is None
    (:func:`flexmor.ports.with_path_loads`)."""
    return with_path_loads(ports, [(p.name, p.B, c.W) for p, c in zip(paths, compressions)])


def path_record(body, path: MovingLoad, comp: Compression | None) -> dict:
    """What the body keeps of a moving load (``body.info['moving_loads']``): the path, ``B_path`` projected
    (``V^T B_path``, (r, N): the reduced input of a unit force at each path node; ``B_r(s) = B_path_r w(s)``,
    and the deflection under the load ``w(s)^T B_path_r^T q_r``) and the compression."""
    Bp = np.asarray((path.B.T @ np.asarray(body.V)).T)
    return {**path.record(), "B_path": Bp.tolist(), "compression": None if comp is None else comp.record()}


def reduced_path(body, k: int = 0) -> np.ndarray:
    """``V^T B_path`` (r, N) of the body's ``k``-th moving load."""
    try:
        return np.asarray(body.info["moving_loads"][k]["B_path"], float)
    except (KeyError, IndexError, TypeError):
        raise OptionError("the body was not reduced with a moving load (reduce --moving-load SET:DIR)",
                          params=("moving_load",)) from None


def _path_body(body, Bp, n_out: int, names_in, names_out):
    """The body with the path's node loads as its inputs and the first ``n_out`` outputs plus the path's
    deflections as outputs."""
    return dataclasses.replace(body, B=Bp, C=np.vstack([np.asarray(body.C)[:n_out], Bp.T]),
                               input_names=list(names_in), output_names=list(names_out))


def _position_errors(freqs, H, Hr, Wpos, n_out):
    """Band errors per position (rows of ``Wpos``): ``(both, under_load)``, of the response at the outputs and
    under the load together, and under the load alone."""
    from .dynamics.grid import band_error

    def at(X):
        y = np.einsum("fpn,sn->sfp", X[:, :n_out, :], Wpos)
        u = np.einsum("sn,fnm,sm->sf", Wpos, X[:, n_out:, :], Wpos)[..., None]
        return np.concatenate([u, y], axis=2), u

    both, under = at(H)
    both_r, under_r = at(Hr)
    return (np.asarray([band_error(freqs, a[:, :, None], b[:, :, None]) for a, b in zip(both, both_r)]),
            np.asarray([band_error(freqs, a[:, :, None], b[:, :, None]) for a, b in zip(under, under_r)]))


def judge_path(model, body, load: MovingLoad, *, k: int = 0, outputs=None, output_names=(), band, full=None,
               solver=None, **grid) -> tuple[dict, object]:
    """The body's band error over the positions of its ``k``-th moving load ``load``.

    For a unit force at position ``s``: the band error (``∫||H - Hr||^2 df / ∫||H||^2 df``) of the response
    under the load and at the study's ``outputs`` (sparse (p, n_dof), the body's first ``p`` outputs, named
    ``output_names``; None: under the load only), against the full model's
    (:class:`~flexmor.analysis.compare.FullResponse` with the path's node loads as inputs: its grid, path and
    judge). Positions: every path node and segment midpoint, then :data:`REFINE` positions in each of the
    :data:`REFINE_SEGMENTS` segments around the worst. ``full``: that FullResponse when computed before (else
    made here with ``grid`` options).

    Returns
    -------
    (dict, FullResponse)
        ``path_max_band_error`` (the maximum over the positions, of the load's response at the outputs and
        under it), ``worst_s`` and ``worst_node`` (nearest node), ``under_load_max`` (under the load alone),
        ``held_positions`` (where the full model does not move: a held node; left out), ``outputs`` (their names),
        ``overall`` (the error measures of the whole path transfer matrix: its ``judge_check`` where the
        reference is a surrogate), ``positions`` (s, band_error, under_load), ``seconds``.
    """
    from .analysis.compare import FullResponse
    from .dynamics.frf import frf_reduced
    from .ports import Ports

    t0 = time.perf_counter()
    path = load
    Bp = reduced_path(body, k)
    n_out = 0 if outputs is None else outputs.shape[0]
    names_out = [*list(output_names)[:n_out], *path.node_names]
    if full is None:
        C = path.B.T.tocsr() if outputs is None else sp.vstack([sp.csr_matrix(outputs), path.B.T]).tocsr()
        ports = Ports(B=path.B.tocsr(), C=C, input_names=path.node_names, output_names=names_out)
        full = FullResponse(model, ports, band, solver=solver, **grid)
    pb = _path_body(body, Bp, n_out, path.node_names, names_out)
    overall = full.evaluate(pb)
    H, _ = full.reference(pb)
    Hr = frf_reduced(pb, full.freqs)
    f = full.freqs
    mid = 0.5 * (path.s[:-1] + path.s[1:])
    s = np.sort(np.concatenate([path.s, mid]))
    both, under = _position_errors(f, H, Hr, path.weights(s), n_out)
    worst = int(np.nanargmax(both))  # NaN: a position where the full model does not move (a held node)
    j = int(np.clip(np.searchsorted(path.s, s[worst], side="right") - 1, 0, path.s.size - 2))
    seg = range(max(0, j - REFINE_SEGMENTS // 2), min(path.s.size - 1, j + REFINE_SEGMENTS // 2 + 1))
    extra = np.concatenate([np.linspace(path.s[i], path.s[i + 1], REFINE + 2)[1:-1] for i in seg])
    b2, u2 = _position_errors(f, H, Hr, path.weights(extra), n_out)
    s, both, under = (np.concatenate(a) for a in ((s, extra), (both, b2), (under, u2)))
    order = np.argsort(s, kind="stable")
    s, both, under = s[order], both[order], under[order]
    if np.all(np.isnan(both)):
        raise OptionError(f"moving load {path.spec!r}: the full model does not respond to the load anywhere on the "
                          "path (every path node constrained in its direction?)", params=("moving_load",))
    worst = int(np.nanargmax(both))
    rec = {"path": path.name, "n_positions": int(s.size), "path_max_band_error": float(both[worst]),
           "held_positions": int(np.count_nonzero(np.isnan(both))),
           "worst_s": float(s[worst]), "worst_node": int(path.nodes[int(np.argmin(abs(path.s - s[worst])))]),
           "under_load_max": float(np.nanmax(under)), "outputs": list(output_names)[:n_out],
           "path_mean_band_error": float(np.nanmean(both)),
           "overall": {k2: v for k2, v in overall.to_dict().items() if k2 in ("band_error", "judged", "judge_check")},
           "grid": {"n_freq": int(f.size), "path": full.grid.get("path")},
           "positions": {"s": s.tolist(), "band_error": _json_list(both), "under_load": _json_list(under)},
           "seconds": time.perf_counter() - t0}
    return rec, full


def judge_paths(model, body, band, *, fulls: dict | None = None, solver=None, **grid) -> list[dict]:
    """:func:`judge_path` of each of ``body``'s moving loads on ``model`` (the paths laid out again from their
    SPECs, the study's outputs from the body's output SPECs: :func:`flexmor.ports.body_ports`). ``fulls`` keeps the
    full path FRFs between calls (keyed by the path, the outputs and the band), e.g. for several bodies."""
    from .ports import body_ports

    moving = body.info.get("moving_loads") or []
    if not moving:
        return []
    fulls = {} if fulls is None else fulls
    n_out = sum("~" not in n for n in body.output_names)
    names = list(body.output_names[:n_out])
    outputs = body_ports(model, body).C[:n_out] if n_out else None
    out = []
    for k, rec in enumerate(moving):
        key = (rec["spec"], tuple(names), tuple(band))
        r, fulls[key] = judge_path(model, body, moving_path(model, rec["spec"]), k=k, outputs=outputs,
                                   output_names=names, band=band, full=fulls.get(key), solver=solver, **grid)
        out.append(r)
    return out


def moving_key(body) -> tuple:
    """What tells the moving loads of two bodies apart (their SPECs and compressed directions): bodies with equal
    keys and port names share their ports."""
    import hashlib

    return tuple((r["spec"], hashlib.sha256(np.asarray(r["compression"]["W"], float).tobytes()).hexdigest())
                 for r in body.info.get("moving_loads") or ())


def _json_list(x) -> list:
    return [None if np.isnan(v) else float(v) for v in x]


def crossing(model, body, path: MovingLoad, *, speed: float, force: float = 1.0, k: int = 0, dt: float | None = None,
             steps: int = 2000, scheme: str = "newmark", start: str = "static", outputs=None, output_names=(),
             solver=None) -> dict:
    """A force ``force`` (N) crossing the ``k``-th path of ``body`` at ``speed`` (model length unit per s), from
    its first node to its last, integrated for the full model (sparse, one factorization) and the body
    (:func:`flexmor.dynamics.time.simulate`, the same scheme and step).

    ``start``: ``static`` (default), both at rest in the static deflection under the force standing at the path's
    first node (the load was there before; one more factorization of ``K``), or ``rest``: undeformed, the force
    appearing at ``t = 0`` (a step load, whose response above the band no reduced body holds). A free body starts
    in its inertia-relief deflection (the force accelerates it), and its elastic part is compared: the rigid motion
    ``phi phi^T M q`` is taken out of the full model's deflection. ``outputs`` (sparse (p, n_dof): the study's
    outputs, the body's first ``p`` rows of ``C``, named ``output_names``) are compared too.

    Returns a dict: ``path`` (its name), ``speed``, ``force``, ``start``, ``duration``, ``dt``, ``steps``, the
    deflection under the load's ``time_mean_error`` (``mean_t |y - yr| / mean_t |y|``) and ``time_max_error``
    (``max_t |y - yr| / max_t |y|``), ``peak_deflection`` of the full model, ``seconds_full``, ``seconds_body``
    and ``speedup``; ``outputs`` (with ``outputs``: their ``names`` and the same two errors over them, Frobenius
    norms at each time); and the curves ``t``, ``under_load`` and ``under_load_body`` (for plots).
    """
    from .dynamics.time import simulate
    from .ports import Ports

    speed, force = float(speed), float(force)
    if not (np.isfinite(speed) and speed > 0):
        raise OptionError(f"the crossing speed must be a positive number, got {speed!r}", params=("speed",))
    if not np.isfinite(force):
        raise OptionError(f"the crossing force must be a finite number, got {force!r}", params=("force",))
    duration = path.length / speed
    dt = duration / int(steps) if dt is None else float(dt)

    def u(t):
        return force * path.weights(speed * np.asarray(t))

    if start not in ("static", "rest"):
        raise OptionError(f"start must be 'static' or 'rest', got {start!r}", params=("start",))
    phi = rigid_body_modes(model)
    p = 0 if outputs is None else outputs.shape[0]
    C = path.B.T.tocsr() if not p else sp.vstack([path.B.T, sp.csr_matrix(outputs)]).tocsr()
    if phi.shape[1]:  # a free body: its rigid coordinates phi^T M q too, to take the rigid motion out
        C = sp.vstack([C, sp.csr_matrix((model.M @ phi).T)]).tocsr()
    ports = Ports(B=path.B.tocsr(), C=C, input_names=path.node_names,
                  output_names=[f"y{i}" for i in range(C.shape[0])])
    Bp = reduced_path(body, k)
    w0 = path.weights([0.0])[0]
    b0 = path.B @ w0
    t0 = time.perf_counter()
    q0 = q0r = None
    if start == "static" and np.any(b0):  # a free body: its inertia-relief deflection (the load accelerates it)
        q0 = force * static_solve(model, b0[:, None], phi, as_solver(solver))[:, 0]
        q0r = force * np.linalg.solve(body.K, Bp @ w0)
    full = simulate(model, u, dt=dt, t_end=duration, ports=ports, scheme=scheme, q0=q0, solver=solver)
    t1 = time.perf_counter()
    Cr = np.vstack([Bp.T, np.asarray(body.C)[:p]])
    red = simulate((body.M, body.D, body.K, Bp, Cr), u, dt=dt, t_end=duration, scheme=scheme, q0=q0r)
    t2 = time.perf_counter()
    Wt = path.weights(speed * full.t)
    Y = full.output()[:, :, 0]
    n = path.nodes.size
    if phi.shape[1]:  # the elastic part: the path's deflections and outputs less those of the rigid motion
        Y = Y[:, :n + p] - Y[:, n + p:] @ np.asarray(C[:n + p] @ phi).T
    Yr = red.output()[:, :, 0]
    y = np.einsum("tn,tn->t", Wt, Y[:, :n])
    yr = np.einsum("tn,tn->t", Wt, Yr[:, :n])
    out = None
    if p:
        e_o = np.linalg.norm(Y[:, n:] - Yr[:, n:], axis=1)
        y_o = np.linalg.norm(Y[:, n:], axis=1)
        out = {"names": list(output_names)[:p], "time_mean_error": float(e_o.mean() / max(y_o.mean(), 1e-300)),
               "time_max_error": float(e_o.max() / max(y_o.max(), 1e-300))}
    e = np.abs(y - yr)
    return {"path": path.name, "speed": speed, "force": force, "start": start, "duration": duration, "dt": dt,
            "steps": int(full.t.size - 1),
            "time_mean_error": float(e.mean() / max(np.abs(y).mean(), 1e-300)),
            "time_max_error": float(e.max() / max(np.abs(y).max(), 1e-300)), "outputs": out,
            "peak_deflection": float(np.abs(y).max()), "seconds_full": t1 - t0, "seconds_body": t2 - t1,
            "speedup": (t1 - t0) / max(t2 - t1, 1e-9),
            "t": full.t.tolist(), "under_load": y.tolist(), "under_load_body": yr.tolist()}
