"""The body in 3D for the HTML report and ``flexmor ui``: surface, ports, couplings, modes, deformations.

:func:`body_scene` describes what the viewer draws of a model (outer surface from the element
connectivity, or the nodes as points where there is none; ports, interface nodes, RBE2/RBE3
spiders to their master nodes); :func:`build_scene` adds the mode shapes of the full model
and of each reduced body (expanded with its basis ``V``) with their MAC pairs, and the
deformation of the full and the reduced bodies under each input at a few frequencies of the
band. :func:`render_section` gives the report's HTML section; the viewer itself is the
small self-written WebGL program ``view3d.js`` (no library, nothing downloaded), shared with
the web application.

Shapes are stored per displayed vertex as 16-bit integers scaled by their largest component
(base64), so a report of a 35k-DOF model stays a few MB; surfaces with more than
``max_nodes`` vertices are decimated for display (:func:`flexmor.report.surface.decimate`)
and the report says so.
"""

from __future__ import annotations

import base64
import html
import json
import logging
from importlib import resources

import numpy as np
import scipy.sparse as sp

from ..couplings import coupling_masters, parse_coupling
from ..damping import ModalDamping
from ..dynamics.frf import ShiftedMatrices, angular_frequency
from ..linalg import factorize
from ..linalg.context import as_solver
from .surface import decimate, outer_surface

__all__ = ["MAX_NODES", "N_FREQS", "body_scene", "build_scene", "render_section", "viewer_js"]

log = logging.getLogger(__name__)

#: Largest number of displayed vertices before the surface is decimated.
MAX_NODES = 4000
#: Frequencies (log-spaced over the band) of the full vs reduced deformation.
N_FREQS = 6
#: Largest number of inputs whose deformation is shown.
MAX_INPUTS = 6


def viewer_js() -> str:
    """The source of the WebGL viewer (``view3d.js``)."""
    return resources.files(__package__).joinpath("view3d.js").read_text(encoding="utf-8")


def _b64(a: np.ndarray) -> str:
    return base64.b64encode(np.ascontiguousarray(a).tobytes()).decode("ascii")


def _ids_of(model, spec_nodes) -> np.ndarray:
    return np.asarray([n for n in np.atleast_1d(spec_nodes) if model.has_node(int(n))], dtype=np.int64)


def _port_spiders(model, specs) -> list:
    """``[(target, master xyz, node ids)]`` of RBE3 ports on the unchanged model (``SET@rbe3:DIR``)."""
    out = {}
    for spec in specs:
        target = str(spec).rsplit(":", 1)[0].strip()
        if "@" not in target or target.upper() in model.node_sets or target.upper() in out:
            continue
        name, _, pt = parse_coupling(target)
        nodes = _ids_of(model, model.node_sets.get(name.upper(), []))
        if nodes.size:
            xm = model.node_xyz(nodes).mean(axis=0) if pt is None else np.asarray(pt, float)
            out[target.upper()] = (target.upper(), xm, nodes)
    return list(out.values())


def _spiders(model) -> list:
    """``[(set name, master id, node ids)]`` of the couplings applied to ``model`` (sets ``NAME@RBE2`` ...)."""
    return [(m["name"], m["id"], m["slaves"]) for m in coupling_masters(model)]


def display_map(model, ids: np.ndarray, spiders=()) -> sp.csr_matrix:
    """Sparse ``S`` (3 k, n_dof): ``S @ q`` are the x y z displacements of the nodes ``ids``.

    Nodes whose translations are no equations of the model (RBE2 dependent nodes of a coupled
    model) follow their master node rigidly, ``u = t + theta x r``; clamped ones stay put.
    """
    rows, cols, vals = [], [], []
    master_of = {}
    for _, master, nodes in spiders:
        for n in nodes.tolist():
            master_of[n] = master
    for v, node in enumerate(ids.tolist()):
        for d in (1, 2, 3):
            try:
                cols.append(model.dof_index(node, d))
                rows.append(3 * v + d - 1), vals.append(1.0)
                continue
            except KeyError:
                pass
            m = master_of.get(node)
            if m is None:
                continue
            r = model.node_xyz(node)[0] - model.node_xyz(m)[0]
            terms = [(d, 1.0)]  # (theta x r)_x = ty rz - tz ry, cyclic
            a, b = d % 3 + 1, (d + 1) % 3 + 1
            terms += [(3 + a, r[b - 1]), (3 + b, -r[a - 1])]
            for dd, c in terms:
                try:
                    cols.append(model.dof_index(m, dd))
                except KeyError:
                    continue
                rows.append(3 * v + d - 1), vals.append(c)
    return sp.csr_matrix((vals, (rows, cols)), shape=(3 * ids.size, model.n_dof))


def port_nodes(model, specs) -> np.ndarray:
    """Node ids addressed by port SPECs (``NODE:DIR``, ``SET:DIR``, ``SET@rbe3:DIR``)."""
    nodes = []
    for spec in specs:
        target = str(spec).rsplit(":", 1)[0].strip()
        if target.upper() not in model.node_sets:  # a coupled port is its master node (set NAME@RBE2)
            target = target.split("@")[0].strip()
        if target.upper() in model.node_sets:
            nodes.extend(model.node_sets[target.upper()].tolist())
        elif target.lstrip("-").isdigit() and model.has_node(int(target)):
            nodes.append(int(target))
    return np.unique(np.asarray(nodes, dtype=np.int64))


def interface_nodes(model, body) -> np.ndarray:
    """Interface nodes of a Guyan/Craig-Bampton body: its physical DOFs are the unit rows of ``V``."""
    if "interface" in body.info:
        return port_nodes(model, body.info["interface"])
    nb = body.info.get("n_interface_dofs")
    if not nb or body.V is None or model.dofs is None:
        return np.zeros(0, dtype=np.int64)
    A = np.abs(body.V)
    unit = (np.abs(A.max(axis=1) - 1) < 1e-9) & (np.abs(A.sum(axis=1) - 1) < 1e-9)
    return np.unique(model.dofs[unit, 0])


class _Shapes:
    """Shapes at the displayed vertices, stored once each: int16 scaled by the largest component."""

    def __init__(self, S):
        self.S, self.items = S, []

    def add(self, q) -> int:
        u = self.S @ np.asarray(q)
        if np.iscomplexobj(u):
            parts = [u.real, u.imag]
        else:
            parts = [u]
        amp = float(max(np.max(np.abs(p)) for p in parts)) if u.size else 0.0
        enc = [_b64(np.round(p / (amp or 1.0) * 32767).astype("<i2")) for p in parts]
        self.items.append({"amp": amp, "re": enc[0], "im": enc[1] if len(enc) > 1 else None})
        return len(self.items) - 1


def body_scene(model, *, inputs=(), outputs=(), interface=(), ports=(), max_nodes: int = MAX_NODES):
    """What the viewer draws of ``model`` and the display map of its vertices.

    Parameters
    ----------
    model : FEModel
    inputs, outputs, interface : array_like of int
        Node ids to mark.
    ports : list of str
        Port SPECs; those of RBE3 couplings on the unchanged model (``SET@rbe3:DIR``) are drawn
        as spiders to their master point.
    max_nodes : int
        Surfaces (and point clouds) with more vertices are decimated for display.

    Returns
    -------
    scene : dict
        JSON-ready: ``xyz`` (float64, base64; exact coordinates for selections), ``tris``/``lines``
        (uint32 vertex indices, base64), ``node_ids``, ``marks`` (name -> vertex coordinates),
        ``spiders`` (segments master-node), ``notes``.
    S : sparse matrix
        :func:`display_map` of the vertices.
    """
    notes, spiders = [], _spiders(model)
    if model.mesh is not None and model.mesh.n_cells:
        surf = outer_surface(model.mesh)
        surf = decimate(surf, model.node_xyz(surf.node_ids()), max_nodes)
        ids = surf.node_ids()
        tris, lines = np.searchsorted(ids, surf.triangles), np.searchsorted(ids, surf.lines)
        if surf.decimated:
            notes.append(surf.decimated)
        kind = f"outer surface: {surf.n_faces} faces of {model.mesh.n_cells} cells"
    else:
        ids = np.sort(model.node_ids)
        if ids.size > max_nodes:
            ids = ids[:: int(np.ceil(ids.size / max_nodes))]
            notes.append(f"every {int(np.ceil(model.n_nodes / max_nodes))}th node shown ({ids.size} of "
                         f"{model.n_nodes})")
        tris, lines = np.zeros((0, 3), np.int64), np.zeros((0, 2), np.int64)
        kind = f"{ids.size} nodes (the file has no elements)"
    xyz = model.node_xyz(ids) if ids.size else np.zeros((0, 3))
    marks = {k: model.node_xyz(_ids_of(model, v)).tolist() for k, v in
             (("inputs", inputs), ("outputs", outputs), ("interface", interface)) if len(_ids_of(model, v))}
    segs = []
    virtual = _port_spiders(model, ports)
    for _, master, nodes in spiders + virtual:
        xm = (model.node_xyz(master)[0] if np.isscalar(master) else master).tolist()
        segs += [[xm, p] for p in model.node_xyz(nodes).tolist()]
        marks.setdefault("masters", []).append(xm)
    couplings = [f"{k}: master node {m}, {n.size} nodes" for k, m, n in spiders]
    couplings += [f"{k} (port): master point {np.round(m, 6).tolist()}, {n.size} nodes" for k, m, n in virtual]
    scene = {"xyz": _b64(xyz.astype("<f8")), "n_vertices": int(ids.size), "tris": _b64(tris.astype("<u4")),
             "lines": _b64(lines.astype("<u4")), "points_only": not tris.size and not lines.size, "kind": kind,
             "marks": marks, "spiders": segs, "couplings": couplings, "notes": notes, "node_ids": ids.tolist()}
    return scene, display_map(model, ids, spiders)


def _deform_freqs(band, f_modes) -> np.ndarray:
    """``N_FREQS`` log-spaced frequencies of ``band``, moved 2 % off any eigenfrequency."""
    fs = np.geomspace(band[0], band[1], N_FREQS)
    for f in np.asarray(f_modes, float):
        near = np.abs(fs / f - 1) < 0.02
        fs[near] = f * 1.02
    return fs


def build_scene(model, ports, bodies, labels, *, band, modal, full_modes, nodes=None, solver=None,
                max_nodes: int = MAX_NODES) -> dict:
    """The report's 3D scene: body, modes with MAC pairs, full vs reduced deformation.

    Parameters
    ----------
    model, ports : FEModel, Ports
        The full model and the ports the bodies share.
    bodies, labels : list
        Reduced bodies and their names.
    band : (float, float)
        Band in Hz; the deformations are shown at :data:`N_FREQS` frequencies over it.
    modal : dict
        label -> :func:`flexmor.analysis.modal_check.modal_check` result.
    full_modes : tuple
        ``(f_hz, phi, n_rigid)`` of :func:`flexmor.analysis.modal_check.full_modes`.
    nodes : dict, optional
        Node ids to mark: ``inputs``, ``outputs``, ``interface`` (the port SPECs of ``ports``
        draw their RBE3 spiders).
    solver : SolverContext, optional
    max_nodes : int

    Returns
    -------
    dict
        JSON-ready scene (:func:`body_scene` plus ``shapes``, ``full``, ``bodies``, ``deform``).
    """
    solver = as_solver(solver)
    scene, S = body_scene(model, **(nodes or {}), ports=[*ports.input_names, *ports.output_names],
                          max_nodes=max_nodes)
    shapes = _Shapes(S)
    f, phi, _ = full_modes
    scene["full"] = [{"hz": float(fi), "shape": shapes.add(phi[:, i])} for i, fi in enumerate(f)]
    scene["bodies"] = {}
    for lb, red in zip(labels, bodies):
        c = modal.get(lb)
        if c is None or red.V is None:
            scene["notes"].append(f"{lb}: no basis V, its modes cannot be shown on the body")
            continue
        A = np.asarray(c["mac"])
        n_red = min(c["reduced_hz"].size, max(f.size, int(np.max(c["pair"], initial=-1)) + 1))
        full_idx = []
        for i in range(f.size):  # the full modes as this body's MAC compared them (aligned in clusters)
            same = np.allclose(c["full_shapes"][:, i], phi[:, i], rtol=0, atol=1e-9 * np.max(np.abs(phi[:, i])))
            full_idx.append(scene["full"][i]["shape"] if same else shapes.add(c["full_shapes"][:, i]))
        modes = [{"hz": float(c["reduced_hz"][j]), "shape": shapes.add(c["reduced_shapes"][:, j]),
                  "pair": int(np.argmax(A[:, j])) if A.shape[0] else -1,
                  "mac": float(np.max(A[:, j])) if A.shape[0] else 0.0} for j in range(n_red)]
        pairs = [{"pair": int(c["pair"][i]) if c["pair"][i] < n_red else -1, "mac": float(c["pair_mac"][i])}
                 for i in range(f.size)]
        scene["bodies"][lb] = {"modes": modes, "full_shapes": full_idx, "pairs": pairs}
    scene["deform"] = _deformations(model, ports, bodies, labels, band, f, shapes, solver)
    if isinstance(model.damping, ModalDamping):
        scene["notes"].append("deformation of the full model with the sparse Rayleigh realization of the modal "
                              f"damping (ratio {model.damping.zeta:g} exact at the band ends only); the reduced "
                              "bodies carry the ratio in each of their modes")
    scene["shapes"] = shapes.items
    return scene


def modes_scene(model, ports, bodies, labels, *, band, n_modes: int = 12, solver=None,
                max_nodes: int = MAX_NODES):
    """:func:`build_scene` with the full modes and the MAC checks computed here (``flexmor ui``).

    Returns ``(scene, modal)``, ``modal`` mapping each label to its
    :func:`flexmor.analysis.modal_check.modal_check` result.
    """
    from ..analysis.modal_check import full_modes, modal_check

    full = full_modes(model, n_modes, solver=solver)
    modal = {lb: modal_check(model, red, full=full, solver=solver) for lb, red in zip(labels, bodies)}
    iface = np.unique(np.concatenate([interface_nodes(model, r) for r in bodies]))
    nodes = {"inputs": port_nodes(model, ports.input_names), "outputs": port_nodes(model, ports.output_names),
             "interface": iface}
    scene = build_scene(model, ports, bodies, labels, band=band, modal=modal, full_modes=full, nodes=nodes,
                        solver=solver, max_nodes=max_nodes)
    return scene, modal


def _deformations(model, ports, bodies, labels, band, f_modes, shapes, solver) -> dict:
    """Full and reduced displacement fields per frequency and input, with their relative difference."""
    fs = _deform_freqs(band, f_modes)
    m = min(ports.n_inputs, MAX_INPUTS)
    B = ports.B[:, :m].toarray()
    A = ShiftedMatrices(model.K, model.M, model.D)
    out = {"freqs": fs.tolist(), "inputs": list(ports.input_names[:m]), "full": [],
           "bodies": {lb: [] for lb, red in zip(labels, bodies) if red.V is not None}}
    for w in angular_frequency(fs):
        Q = factorize(A(w), solver=solver, symmetric=True, check=False).solve(B.astype(complex))
        Q = Q.reshape(model.n_dof, m)
        out["full"].append([shapes.add(Q[:, j]) for j in range(m)])
        U = shapes.S @ Q
        for lb, red in zip(labels, bodies):
            if red.V is None:
                continue
            Ar = red.K - w ** 2 * red.M + (1j * w * red.D if red.D is not None else 0)
            Qr = np.asarray(red.V) @ np.linalg.solve(Ar.astype(complex), np.asarray(red.B[:, :m], complex))
            Ur = shapes.S @ Qr
            diff = [float(np.linalg.norm(U[:, j] - Ur[:, j]) / (np.linalg.norm(U[:, j]) or 1.0)) for j in range(m)]
            out["bodies"][lb].append([{"shape": shapes.add(Qr[:, j]), "rel_diff": diff[j]} for j in range(m)])
    return out


_CSS = """.v3d{display:flex;gap:8px;flex-wrap:wrap}.v3d figure{margin:0;flex:1 1 420px;position:relative}
.v3d canvas{width:100%;height:380px;border:1px solid #bbb;background:#fff;touch-action:none;display:block}
.v3d figcaption{font-size:0.85em;color:#333;min-height:1.3em}.v3dctl{display:flex;gap:12px;flex-wrap:wrap;
align-items:center;margin:0.5em 0;font-size:0.9em}.v3dlegend span{display:inline-block;width:10px;height:10px;
margin:0 3px 0 8px;border-radius:5px}"""


def render_section(scene: dict) -> str:
    """The report's "The body in 3D" section: controls, two canvases, the scene JSON and the viewer."""
    e = html.escape
    data = json.dumps(scene, separators=(",", ":")).replace("</", "<\\/")
    notes = "".join(f"<p class=note>{e(n)}</p>" for n in scene["notes"])
    coupl = f"<p class=note>Couplings: {e('; '.join(scene['couplings']))}.</p>" if scene["couplings"] else ""
    return (f'<h2 id="view3d">The body in 3D</h2><style>{_CSS}</style>'
            f"<p>{e(scene['kind'])}; drag to rotate, wheel to zoom, right-drag to pan. Left: the full model, "
            "right: the reduced body. Modes: the paired mode (largest MAC) is shown beside the chosen one. "
            "Deformation: real part of the response to a unit input, animated over one period.</p>"
            f"{coupl}{notes}"
            '<div class=v3dctl id=v3dctl></div><div class=v3d><figure><canvas id=v3d-left></canvas>'
            '<figcaption id=v3d-left-cap></figcaption></figure><figure><canvas id=v3d-right></canvas>'
            '<figcaption id=v3d-right-cap></figcaption></figure></div><div class=v3dlegend id=v3dlegend></div>'
            f'<script type="application/json" id="v3d-data">{data}</script>'
            f"<script>{viewer_js()}\nFlexmorView.report(document.getElementById('v3d-data'));</script>")
