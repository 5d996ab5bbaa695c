#!/usr/bin/env python
"""The public benchmark of docs/benchmark.md: every reduction method on a stated set of models.

    .venv/bin/python bench/benchmark.py                    # full sizes; writes docs/benchmark.md's tables
    .venv/bin/python bench/benchmark.py --quick            # tiny sizes (< 60 s), same cases and code
    .venv/bin/python bench/benchmark.py --page /tmp/b.md --json /tmp/b.json

Every method of :func:`flexmor.reduction.methods` reduces every model of :data:`CASES` at the model's fixed
order (``guyan``: the order of its interface) through :class:`flexmor.System` (one full FRF per model, shared
by its bodies) and is measured by

* ``band_error`` and ``hinf_error`` over the model's band (:class:`flexmor.analysis.compare.FullResponse`);
* the mounted error: the body clamped at its interface (the six DOF of the coupling master held) against the
  full model clamped the same way, ``max |f_red / f_full - 1|`` of the six lowest elastic modes that lie in the
  band (:func:`flexmor.analysis.mounted.mounted_record`, one :class:`~flexmor.analysis.mounted.FullMounted`
  per model);
* the static error: the static compliance between the ports at 0 Hz, ``G = C K⁻¹ B`` (a free body: its
  elastic part, inertia relief, :func:`flexmor.reduction.free_body.inertia_relief_modes`) against the body's
  ``Cr Kr⁻¹ Br``, ``‖G - Gr‖_F / ‖G‖_F``;
* the frame error: the body's static deflection under each of the frame's six unit accelerations against the
  full model's (the largest relative field error; a free body held clamped at its interface,
  :func:`flexmor.analysis.mounted.static_record`): what gravity and the moving support do to the body;
* the time: wall seconds of building the basis and projecting (``seconds`` of ``flexmor reduce --json``).

The tables are written between ``<!-- benchmark:begin -->`` and ``<!-- benchmark:end -->`` of ``--page``
(default docs/benchmark.md), with the machine the run took place on; ``--json`` keeps the records.
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import subprocess
import sys
import time
from dataclasses import dataclass, field

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "src"))
sys.path.insert(0, str(ROOT / "bench"))

BEGIN, END = "<!-- benchmark:begin -->", "<!-- benchmark:end -->"
PAGE = ROOT / "docs" / "benchmark.md"
#: the columns of every model's table, after the method's name
COLUMNS = ("order", "band_error", "hinf_error", "mounted error", "static error", "frame error", "seconds")
#: the methods in the order of the families of DESIGN.md (condensation, modal, CMS, interpolation, Gramian,
#: hybrid); a method registered later comes after them
ORDER = ("modal", "guyan", "craig-bampton", "craig-chang", "herting", "krylov", "irka", "adaptive", "sobt", "fw-sobt",
         "pod", "two-step", "cms-krylov", "cms-gramian", "svdmor")
ZETA = 0.01
SIX = ("x", "y", "z", "rx", "ry", "rz")


@dataclass(frozen=True)
class Case:
    """One model of the benchmark: how it is built (full and quick size), its ports, interface, band, order."""

    key: str
    what: str
    build: object  # (quick: bool) -> (FEModel, size text)
    inputs: tuple
    interface: str
    band: tuple
    order: int
    notes: dict = field(default_factory=dict)


def _cantilever(quick):
    from flexmor.models import cantilever

    if quick:
        return cantilever(divisions=(10, 2, 2)), "10 x 2 x 2 hexahedra"
    return cantilever(8), "80 x 8 x 8 hexahedra (n = 8)"


def _plate_structure(lower):
    def build(quick):
        from flexmor.models import plate_structure

        n = 4 if quick else 40
        return plate_structure(n, lower=lower), f"n = {n}"
    return build


def _calculix(name):
    def build(quick):
        from flexmor.io import read

        return read(ROOT / "tests" / "data" / "calculix" / f"{name}.sti"), "10 x 2 x 2 C3D8 (the file's mesh)"
    return build


CASES = (
    Case("cantilever", "built-in `cantilever`, steel beam 1 x 0.1 x 0.1 m, clamped at x = 0, solid (hexahedra)",
         _cantilever, ("TIP@rbe2:y",), "TIP@rbe2", (10.0, 3000.0), 10),
    Case("plate-structure", "built-in `plate_structure`: plate 0.5 x 0.5 x 0.02 m with a 0.1 m hole on four rods, "
         "rods clamped at their lower ends", _plate_structure("clamped"), tuple(f"HOLE@rbe2:{d}" for d in SIX),
         "HOLE@rbe2", (1.0, 2000.0), 30),
    Case("plate-structure-free", "built-in `plate_structure(lower='free')`: the same structure free-free",
         _plate_structure("free"), tuple(f"HOLE@rbe2:{d}" for d in SIX), "HOLE@rbe2", (1.0, 2000.0), 30),
    Case("ccx-beam-clamped", "CalculiX export `tests/data/calculix/beam8_clamped_mat.sti`: steel beam "
         "1 x 0.1 x 0.1 m, face x = 0 clamped", _calculix("beam8_clamped_mat"), ("TIP@rbe2:y",), "TIP@rbe2",
         (10.0, 5000.0), 10),
    Case("ccx-beam-free", "CalculiX export `tests/data/calculix/beam8_free_mat.sti`: the same beam free-free",
         _calculix("beam8_free_mat"), tuple(f"FIX@rbe2:{d}" for d in SIX), "FIX@rbe2", (10.0, 5000.0), 24),
)


def method_names() -> list[str]:
    """Every registered method, in :data:`ORDER` first."""
    from flexmor.reduction import methods

    names = list(methods())
    return [m for m in ORDER if m in names] + sorted(m for m in names if m not in ORDER)


# --------------------------------------------------------------------------- measures beyond the FRF
def static_compliance(model, ports, mounted, solver=None) -> np.ndarray:
    """``G = C K⁻¹ B`` between the ports at 0 Hz. A free model: the elastic part ``C K⁺ (I - M Φ Φᵀ) B``
    (inertia relief), exact from the body clamped at its interface (``mounted``, a
    :class:`~flexmor.analysis.mounted.FullMounted`; the six held DOF of one master node fix the rigid motion
    without redundancy, so a balanced load leaves no reaction there) and made M-orthogonal to the rigid modes."""
    from flexmor.analysis.mounted import supports
    from flexmor.linalg import factorize
    from flexmor.rigid import elastic_loads, m_project

    B = ports.B.toarray()
    phi = mounted.phi
    if not phi.shape[1]:
        X = factorize(model.K.tocsr(), solver=solver, positive=True).solve(B)
    else:
        sup = supports(model, held=("clamped",))[0]
        Be = elastic_loads(model, phi, B)
        X = m_project(model, phi, np.column_stack([mounted.deflection(sup, f"static:{j}", Be[:, j])
                                                   for j in range(B.shape[1])]))
    return np.asarray(ports.C @ X)


def static_error(G, body) -> float:
    Gr = body.C @ np.linalg.solve(body.K, body.B)
    return float(np.linalg.norm(G - Gr) / np.linalg.norm(G))


def frame_error(rec) -> float | None:
    """The largest field error of the body's static deflection under the frame's six accelerations
    (``rec``: :func:`flexmor.analysis.mounted.static_record`), None when there is none."""
    from flexmor.rigid import ACCELERATIONS

    errs = [x["field_error"] for x in (rec or {}).get("loads", ())
            if x["load"] in ACCELERATIONS and x["field_error"] is not None]
    return max(errs) if errs else None


def mounted_error(rec) -> tuple[float | None, str | None]:
    """The largest frequency error of the clamped case (modes in the band), or why there is none."""
    if rec is None:
        return None, "no interface"
    (case,) = [c for c in rec["cases"] if c["held"] == "clamped"]
    if case["max_frequency_error"] is not None:
        return case["max_frequency_error"], None
    if not case["frequencies_reduced_hz"]:
        return None, "held, the body has no elastic DOF left"
    return None, "no mounted mode in the band"


# --------------------------------------------------------------------------- the run
def run_case(case: Case, quick: bool, names, log=print) -> dict:
    import flexmor
    from flexmor.analysis.mounted import FullMounted, mounted_record, static_record

    t0 = time.perf_counter()
    model, size = case.build(quick)
    system = flexmor.System(model, inputs=list(case.inputs), interfaces=[case.interface], band=case.band,
                            damping={"band_rayleigh": ZETA}, cache=False)
    full_mounted = FullMounted(system.model, modes=6, solver=system.solver)
    G = static_compliance(system.model, system.ports, full_mounted, solver=system.solver)
    out = {"key": case.key, "what": case.what, "size": size, "n_dof": int(system.model.n_dof),
           "n_dof_as_read": int(model.n_dof), "free": bool(full_mounted.phi.shape[1]),
           "inputs": list(case.inputs), "interface": case.interface, "band_hz": list(case.band),
           "order": case.order, "rows": {}}
    for method in names:
        order = None if method == "guyan" else case.order
        try:
            body, rec = system.reduce_and_judge(method, order, mounted=False)
            mrec = mounted_record(system.model, body, ports=system.ports, band=system.band, full=full_mounted,
                                  held=("clamped",), solver=system.solver)
            merr, mwhy = mounted_error(mrec)
            srec = static_record(system.model, body, ports=system.ports, full=full_mounted, mounted=mrec,
                                 solver=system.solver)
            row = {"order": int(rec["order"]), "band_error": rec["band_error"], "hinf_error": rec["hinf_error"],
                   "mounted_error": merr, "mounted_note": mwhy, "static_error": static_error(G, body),
                   "frame_error": frame_error(srec), "seconds": rec["seconds"], "order_note": rec.get("order_note")}
        except Exception as exc:  # noqa: BLE001 - a method that cannot run on a case says why in its cell
            row = {"error": f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}"}
        out["rows"][method] = row
        log(f"{case.key:>22} {method:>14} " + (row["error"] if "error" in row else
            f"r={row['order']:3d} band {row['band_error']:.2e} hinf {row['hinf_error']:.2e} "
            f"mounted {_cell(row['mounted_error'])} static {row['static_error']:.2e} frame {_cell(row['frame_error'])} "
            f"{row['seconds']:.2f} s"))
    out["full_frf_seconds"] = system.full.seconds
    out["resonances_in_band"] = int(np.size(system.full.resonances))
    out["wall_seconds"] = time.perf_counter() - t0
    return out


# --------------------------------------------------------------------------- the page
def machine() -> dict:
    """CPU, cores, memory, versions, git commit and date of this run (:func:`solvers._machine` and more)."""
    from solvers import _machine

    import flexmor

    info = _machine()
    info["flexmor"] = flexmor.__version__
    try:
        commit = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"], capture_output=True,
                                text=True, check=True).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(ROOT), "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True, check=True).stdout.strip()
        info["commit"] = commit + (" (with uncommitted changes)" if dirty else "")
    except (OSError, subprocess.CalledProcessError):
        info["commit"] = "unknown"
    info["date"] = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())
    return info


def machine_line(m: dict, wall: float, quick: bool, load: tuple) -> str:
    """The line under the marker: the machine, the versions, the date, the run's wall time and the load
    average (1 min) at its start and end (other jobs on the machine inflate the seconds)."""
    return (f"Machine: {m.get('cpu', 'unknown CPU')}, {m['cores']} cores, {m.get('mem_gb', '?')} GB memory; "
            f"flexmor {m['flexmor']}, git {m['commit']}, Python {m['python']}, NumPy {m['numpy']}, "
            f"SciPy {m['scipy']}; {m['date']}; whole run {wall:.0f} s" + (" (--quick sizes)" if quick else "")
            + f", load average {load[0]:.1f} at its start, {load[1]:.1f} at its end.")


def _cell(x) -> str:
    return "-" if x is None else f"{x:.2e}"


def cells(row: dict) -> list[str]:
    """The cells of one method's row after its name, :data:`COLUMNS`."""
    if "error" in row:
        return ["-", f"not run: {row['error']}".replace("|", "/"), "-", "-", "-", "-", "-"]
    mounted = _cell(row["mounted_error"]) if row["mounted_error"] is not None else f"- ({row['mounted_note']})"
    return [str(row["order"]), _cell(row["band_error"]), _cell(row["hinf_error"]), mounted,
            _cell(row["static_error"]), _cell(row["frame_error"]), f"{row['seconds']:.2f}"]


def heading(case_key: str) -> str:
    return f"### `{case_key}`"


def table(res: dict) -> str:
    kind = "free-free, judged on its elastic part" if res["free"] else "supported"
    lines = [heading(res["key"]), "",
             f"{res['what']}; {res['size']}: {res['n_dof']} DOF ({kind}). Inputs = outputs: "
             f"{', '.join('`' + s + '`' for s in res['inputs'])}; interface `{res['interface']}`; band "
             f"{res['band_hz'][0]:g}-{res['band_hz'][1]:g} Hz ({res['resonances_in_band']} resonances); "
             f"Rayleigh damping, ratio {ZETA:g} at the band ends; order {res['order']}. Full FRF "
             f"{res['full_frf_seconds']:.1f} s; the model's whole row of methods {res['wall_seconds']:.0f} s.", "",
             "| method | " + " | ".join(COLUMNS) + " |", "|---" * (len(COLUMNS) + 1) + "|"]
    for method, row in res["rows"].items():
        lines.append(f"| {method} | " + " | ".join(cells(row)) + " |")
    return "\n".join(lines)


def block(results: list, m: dict, wall: float, quick: bool, load: tuple) -> str:
    return "\n\n".join([BEGIN, machine_line(m, wall, quick, load), *(table(r) for r in results), END])


def write_page(path: pathlib.Path, text: str) -> None:
    """Replace the block between the markers of ``path`` by ``text`` (the markers included)."""
    page = path.read_text()
    i, j = page.find(BEGIN), page.find(END)
    if i < 0 or j < i:
        raise SystemExit(f"{path}: no {BEGIN} ... {END} block to write the tables into")
    path.write_text(page[:i] + text + page[j + len(END):])


def structure(text: str) -> list[tuple[str, list[str], list[str]]]:
    """``(model key, header cells, method names)`` of every table in the marker block of ``text``."""
    i, j = text.find(BEGIN), text.find(END)
    if i < 0 or j < i:
        return []
    out, key = [], None
    for line in text[i:j].splitlines():
        if line.startswith("### `"):
            key = line.split("`")[1]
            out.append((key, [], []))
        elif line.startswith("|") and key is not None and not line.startswith("|---"):
            cells_ = [c.strip() for c in line.strip().strip("|").split("|")]
            if not out[-1][1]:
                out[-1][1].extend(cells_)
            else:
                out[-1][2].append(cells_[0])
    return out


def expected_structure() -> list[tuple[str, list[str], list[str]]]:
    """What :func:`structure` reads from a page this script wrote."""
    return [(c.key, ["method", *COLUMNS], method_names()) for c in CASES]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="tiny sizes (< 60 s), for the test")
    ap.add_argument("--page", default=str(PAGE), help="the Markdown page whose marker block is written")
    ap.add_argument("--json", default=None, help="write the records here too")
    ap.add_argument("--models", default=None, help="comma-separated keys of CASES (default all)")
    a = ap.parse_args(argv)
    import logging
    import warnings

    logging.basicConfig(level=logging.WARNING)
    warnings.simplefilter("ignore")
    t0, load0 = time.perf_counter(), os.getloadavg()[0]
    names = method_names()
    keys = None if a.models is None else a.models.split(",")
    results = [run_case(c, a.quick, names) for c in CASES if keys is None or c.key in keys]
    wall = time.perf_counter() - t0
    m = machine()
    write_page(pathlib.Path(a.page), block(results, m, wall, a.quick, (load0, os.getloadavg()[0])))
    if a.json:
        record = {"machine": m, "wall_seconds": wall, "quick": a.quick, "load_start": load0, "models": results}
        pathlib.Path(a.json).write_text(json.dumps(record, indent=1, default=float))
    print(f"wrote {a.page}; whole run {wall:.1f} s", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
