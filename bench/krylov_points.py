#!/usr/bin/env python
"""Krylov's default expansion points against fixed choices and the other methods, and its estimate.

For each case (model, ports, band, damping, order) every body is judged by the same full FRF
(:class:`flexmor.System`), and the table gives its order, band_error, its frame error (the static deflection
under the frame's six unit accelerations against the full model's, ``frame_error`` of ``bench/benchmark.py``:
krylov's bodies are built for those loads and spend part of the order on them), the seconds of its basis and
projection, and for ``krylov`` (default points) its own estimate (``points_check``) and the ratio
estimate / band_error. The rows:

* ``krylov``: the default points (the static point, then points on the frequency axis where the body's
  residual is largest, with the load combinations the body misses there:
  :mod:`flexmor.reduction.greedy_points`), built to 1.5-3 times the order and compressed where the balanced
  truncation of that body is better (:mod:`flexmor.reduction.greedy_compress`); ``krylov greedy``: the greedy
  basis of the order (``compress='off'``); ``krylov band``: ``compress='band'``, chosen on the band alone (the
  static responses not kept, the balanced truncation of the reference body among the candidates); ``krylov
  all``: the greedy basis with ``directions='all'`` (every port's blocks at each point);
* ``krylov 1 real``, ``krylov 3 real``: the earlier defaults, one real point at the band's geometric mean,
  and the three real points of :func:`flexmor.reduction.krylov.default_points`;
* ``krylov 0,f/2 j,f j``: the fixed choice that did well on the C3D10 structure (0, the band's middle and
  its top on the frequency axis);
* ``fw-sobt``, ``irka``, ``craig-bampton`` (where the case has an interface), ``adaptive``.

Cases: the plate structure (``flexmor.models.plate_structure``) clamped with one port at a top corner (z)
and free with its hole's RBE2 (six directions) plus the corner; the plate structure with the hole's six
ports, clamped and free; the cantilever with the tip's RBE2 (y) and undamped with two tip ports; the
CalculiX beams of ``tests/data/calculix`` (the clamped one damped and undamped: the estimate's second
reference); the Abaqus C3D10 block of ``tests/data/abaqus`` undamped (where one check of the estimate fell 67x
short); the Ansys files of ``tests/data/ansys``: the clamped SOLID186 beam of the ``.full`` file with its ``.cdb``
mesh (two ports at a tip corner) and the free rotor over its lowest eight modes.

Usage::

    .venv/bin/python bench/krylov_points.py                 # n = 20 (6-7k DOF), all cases
    .venv/bin/python bench/krylov_points.py --n 40 --cases corner-clamped,corner-free
    .venv/bin/python bench/krylov_points.py --json /tmp/kp.json

Writes a Markdown table per case to stdout.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import sys
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "src"))
sys.path.insert(0, str(ROOT / "bench"))

SIX = ("x", "y", "z", "rx", "ry", "rz")


def _corner(model) -> int:
    return int(model.node_ids[np.argmin(np.linalg.norm(model.xyz - [0.25, 0.25, 0.02], axis=1))])


def _plate(n, lower):
    from flexmor.models import plate_structure

    return plate_structure(n, lower=lower)


def _block():
    from flexmor.io import read

    m = read(ROOT / "tests" / "data" / "abaqus" / "blockC3D10.inp")
    return m, [f"{int(m.node_ids[np.argmin(np.linalg.norm(m.xyz - [4.0, 1.0, 1.0], axis=1))])}:z"], []


def _hexbeam():
    from flexmor.io import read

    a = ROOT / "tests" / "data" / "ansys"
    m = read(a / "ansys_file.full", coordinates=a / "ansys_HexBeam.cdb")
    tip = int(m.node_ids[np.argmax(m.xyz @ [1.0, 1.0, 10.0])])
    return m, [f"{tip}:x", f"{tip}:z"], []


def _rotor():
    from flexmor.io import read

    m = read(ROOT / "tests" / "data" / "ansys" / "rotorAnsysStiffnessMatrixSparse.txt")
    top = int(m.node_ids[np.argmax(m.xyz[:, 2] + 1e-3 * m.xyz[:, 0])])
    return m, [f"{top}:x", f"{top}:y"], []


def cases(n: int) -> dict:
    """``key: (build() -> (model, inputs, interfaces), band, damping, order, text)``."""
    from flexmor.io import read
    from flexmor.models import cantilever

    ccx = ROOT / "tests" / "data" / "calculix"

    def corner(lower, hole):
        def build():
            m = _plate(n, lower)
            return m, ([f"HOLE@rbe2:{d}" for d in SIX] if hole else []) + [f"{_corner(m)}:z"], (
                ["HOLE@rbe2"] if hole else [])
        return build

    def hole(lower):
        def build():
            return _plate(n, lower), [f"HOLE@rbe2:{d}" for d in SIX], ["HOLE@rbe2"]
        return build

    modal, rayleigh = {"modal_damping": 0.01}, {"band_rayleigh": 0.01}
    return {
        "corner-clamped": (corner("clamped", False), (1.0, 2000.0), modal, 20,
                           f"plate_structure({n}) clamped, top corner z, modal damping 1 %"),
        "corner-free": (corner("free", True), (1.0, 2000.0), modal, 45,
                        f"plate_structure({n}, lower='free'), HOLE@rbe2 x..rz + corner z, modal damping 1 %"),
        "hole-clamped": (hole("clamped"), (1.0, 2000.0), rayleigh, 30,
                         f"plate_structure({n}) clamped, HOLE@rbe2 x..rz, Rayleigh 1 % at the band ends"),
        "hole-free": (hole("free"), (1.0, 2000.0), rayleigh, 30,
                      f"plate_structure({n}, lower='free'), HOLE@rbe2 x..rz, Rayleigh 1 %"),
        "cantilever": (lambda: (cantilever(4), ["TIP@rbe2:y"], ["TIP@rbe2"]), (10.0, 3000.0), rayleigh, 10,
                       "cantilever(4), TIP@rbe2:y, Rayleigh 1 %"),
        "cantilever-undamped": (lambda: (cantilever(4), ["TIP:y", "TIP:z"], []), (10.0, 3000.0), None, 12,
                                "cantilever(4), TIP:y and TIP:z, undamped"),
        "ccx-clamped": (lambda: (read(ccx / "beam8_clamped_mat.sti"), ["TIP@rbe2:y"], ["TIP@rbe2"]),
                        (10.0, 5000.0), rayleigh, 10, "CalculiX beam8 clamped, TIP@rbe2:y, Rayleigh 1 %"),
        "ccx-clamped-undamped": (lambda: (read(ccx / "beam8_clamped_mat.sti"), ["TIP@rbe2:y"], ["TIP@rbe2"]),
                                 (10.0, 5000.0), None, 10,
                                 "CalculiX beam8 clamped, TIP@rbe2:y, undamped (the estimate's second reference)"),
        "ccx-free": (lambda: (read(ccx / "beam8_free_mat.sti"), [f"FIX@rbe2:{d}" for d in SIX], ["FIX@rbe2"]),
                     (10.0, 5000.0), rayleigh, 24, "CalculiX beam8 free, FIX@rbe2 x..rz, Rayleigh 1 %"),
        "c3d10-block": (_block, (10.0, 2000.0), None, 12,
                        "Abaqus C3D10 block (free), corner node z, undamped: ten modes in the band, three at 1030 Hz"),
        "ansys-hexbeam": (_hexbeam, (100.0, 20000.0), rayleigh, 12,
                          "Ansys .full (SOLID186 beam, clamped, .cdb mesh), tip corner x and z, Rayleigh 1 %"),
        "ansys-rotor": (_rotor, (10.0, 300.0), None, 12,
                        "Ansys rotor (free, HBMAT/MMF), top node x and y, undamped: eight modes in the band"),
    }


def rows(band, interfaces) -> list[tuple[str, str, dict]]:
    from flexmor.reduction.krylov import default_points

    f1, f2 = band
    three = ",".join(f"{p.real:.6g}" for p in default_points(band))
    out = [("krylov", "krylov", {}), ("krylov greedy", "krylov", {"compress": "off"}),
           ("krylov band", "krylov", {"compress": "band"}),
           ("krylov all", "krylov", {"directions": "all"}),
           ("krylov 1 real", "krylov", {"points": f"{np.sqrt(f1 * f2):.6g}"}),
           ("krylov 3 real", "krylov", {"points": three}),
           ("krylov 0,f/2 j,f j", "krylov", {"points": f"0,{f2 / 2:.6g}j,{f2:.6g}j"}),
           ("fw-sobt", "fw-sobt", {}), ("irka", "irka", {}), ("adaptive", "adaptive", {}),
           ("fw-sobt rv", "fw-sobt", {"residual_vectors": True}), ("irka rv", "irka", {"residual_vectors": True}),
           ("fw-sobt + static", "fw-sobt", {})]
    if interfaces:
        out.append(("craig-bampton", "craig-bampton", {"interface": interfaces}))
    return out


def _with_static(S, order: int):
    """The static responses krylov's default holds (the inputs and the frame's six inertia loads, its point 0),
    then fw-sobt's leading directions, ``order`` columns in all: fw-sobt's band error at equal order where it
    keeps the same static responses (``residual_vectors`` adds the masters' unit loads too, more columns than the
    one-port beams' order). A supported body only."""
    import flexmor
    from flexmor.rigid import rigid_body_modes

    if rigid_body_modes(S.model).shape[1]:
        raise ValueError("the static block of a supported body only (a free body: fw-sobt rv)")
    Vs = S.reduce("krylov", order, points="0", moments=1, compress="off").V
    s = Vs.shape[1]
    if s >= order:
        raise ValueError(f"the static block has {s} columns, the order {order}")
    Vf = S.reduce("fw-sobt", order - s).V
    Q, _ = np.linalg.qr(np.hstack([Vs, Vf]))  # Vs's span first, then what Vf adds to it
    return flexmor.project(S.model, Q[:, :order], S.ports)


def run_case(key, spec, log=print, only=None) -> dict:
    from benchmark import _cell, frame_error

    import flexmor

    build, band, damping, order, text = spec
    model, inputs, interfaces = build()
    S = flexmor.System(model, inputs=inputs, interfaces=interfaces, band=band, damping=damping, cache=False)
    t0 = time.perf_counter()
    path = S.full.grid.get("path")
    out = {"key": key, "what": text, "n_dof": int(S.model.n_dof), "order": order, "full_path": path,
           "full_seconds": time.perf_counter() - t0, "rows": {}}
    for label, method, opts in rows(band, interfaces):
        if only is not None and label not in only:
            continue
        try:
            t = time.perf_counter()
            body = _with_static(S, order) if label == "fw-sobt + static" else S.reduce(method, order, **opts)
            sec = time.perf_counter() - t
            e = S.judge(body).band_error
            row = {"order": int(body.order), "band_error": float(e), "seconds": sec,
                   "frame_error": frame_error(S.static(body))}
            check = body.info.get("points_check")
            if check and label.startswith("krylov") and "points" not in opts:
                row["estimate"] = float(check["estimate"])
                row["n_points"] = len(body.info["points_hz"])
        except Exception as exc:  # noqa: BLE001 - a method that cannot run says why in its row
            row = {"error": f"{type(exc).__name__}: {str(exc).splitlines()[0]}"}
        out["rows"][label] = row
        log(f"{key:>20} {label:>20} " + (row["error"] if "error" in row else
            f"r={row['order']:3d} band {row['band_error']:.2e} frame {_cell(row['frame_error'])} {row['seconds']:.2f} s"
            + (f" est {row['estimate']:.2e} ({row['n_points']} points)" if "estimate" in row else "")),
            file=sys.stderr)
    return out


def table(res: dict) -> str:
    from benchmark import _cell

    lines = [f"### {res['key']}: {res['what']}, {res['n_dof']} DOF, order {res['order']} (full FRF: "
             f"{res['full_path']})", "",
             "| body | order | band_error | frame error | estimate | estimate / band_error | seconds |",
             "|---|---|---|---|---|---|---|"]
    for label, row in res["rows"].items():
        if "error" in row:
            lines.append(f"| {label} | - | {row['error']} | | | | |")
            continue
        est = row.get("estimate")
        ratio = f"{est / row['band_error']:.2f}" if est is not None and row["band_error"] > 0 else ""
        lines.append(f"| {label} | {row['order']} | {row['band_error']:.2e} | {_cell(row['frame_error'])} | "
                     f"{'' if est is None else f'{est:.2e}'} | {ratio} | {row['seconds']:.2f} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[1])
    p.add_argument("--n", type=int, default=20, help="plate structure size parameter (20: ~6.5k DOF, 40: ~18k)")
    p.add_argument("--cases", default=None, help="comma-separated keys (default all)")
    p.add_argument("--json", default=None, help="write the records here")
    p.add_argument("--rows", default=None, help="comma-separated row labels (default all)")
    a = p.parse_args(argv)
    all_cases = cases(a.n)
    keys = a.cases.split(",") if a.cases else list(all_cases)
    only = a.rows.split(",") if a.rows else None
    results = [run_case(k, all_cases[k], only=only) for k in keys]
    for r in results:
        print(table(r))
    if a.json:
        pathlib.Path(a.json).write_text(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
