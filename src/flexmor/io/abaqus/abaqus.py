"""Reader of Abaqus matrix exports (``*MATRIX GENERATE`` + ``*MATRIX OUTPUT``).

For the job ``<job>.inp`` with ::

    *STEP
    *MATRIX GENERATE, STIFFNESS, MASS
    *MATRIX OUTPUT, STIFFNESS, MASS, FORMAT=COORDINATE   (or FORMAT=LABELS, the default)
    *END STEP

Abaqus writes ``<job>_STIF1.mtx`` and ``<job>_MASS1.mtx`` (``1``: the step; ``_DMPV1.mtx``
with viscous damping when requested). The main file is the ``.inp``; pass it (or one of the
``.mtx`` files) and the rest is found beside it. Two matrix forms are read, told apart by the
number of columns of the first data line:

COORDINATE, ``row, col, value``
    Global equation numbers, 1-based. Abaqus numbers the equations node by node in its
    internal node order (instances in deck order, labels ascending within an instance, see
    :mod:`flexmor.io.abaqus.abaqus_inp`) with the same number of DOFs per node, ``d``: equation
    ``(k - 1) * d + j`` is direction ``j`` of the ``k``-th node. ``d`` is 3 for continuum
    elements (``C3D*``), 2 for plane ones (``CPS* CPE* CAX*``), 6 for shells and beams; for
    mixed meshes pass ``dof_per_node=`` or use the LABELS form. Equation numbers beyond what the
    nodes of the deck carry are refused naming the deck (cut off in its node block?) and the ``.mtx``.
LABELS, ``node, dof, node, dof, value``
    Node labels (``instance.label`` in assemblies) and directions 1..6.

Either triangle or both may be stored; one triangle is mirrored. An entry given twice is
refused (a damaged file), never summed; so is a matrix stored with both triangles whose
triangles differ in their entry counts (a cut between an entry and its mirror image), and an
equation with mass but no stiffness entry (lines lost from the stiffness file). When exactly the
last equations of the stiffness have no mass, a FlexmorWarning says that the mass file may be
cut off (its format cannot tell that from massless directions). Equations that have neither stiffness nor mass (a
direction no element uses) are removed and logged. Units are those of the deck.

The deck is checked for a cut (:mod:`flexmor.io.abaqus.abaqus_inp`); a deck with elements but
without the ``*STEP`` that a ``*MATRIX GENERATE`` job has is read with a FlexmorWarning, as the
CalculiX reader does: it may be a mesh written for the matrices, or cut off after its element
blocks (what followed, such as sets and materials, is then missing).

Decks with quadratic elements (``C3D20R``, ``C3D10`` ...) may have a singular or
indefinite mass matrix: that is a FlexmorWarning (see :func:`flexmor.io._mass.check_mass`),
not an error.

``.inp`` is shared with CalculiX: if ``<job>.sti`` lies beside the deck and no ``_STIF``
file does, the CalculiX reader is used.
"""

from __future__ import annotations

import io
import logging
import re
import warnings
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from ...elements import ElementBlock, Elements, Material
from ...errors import FlexmorWarning, ModelError, ReadError
from ...model import FEModel
from .._build import build_model
from .._cells import abaqus_cell, mesh_of_elements
from .._mass import QUADRATIC_TYPES, check_mass
from .._open import beside, is_gzip, open_binary, plain_name, stem, suffix
from .._registry import MODEL_FORMATS
from .._sparse import assemble, rows_in_use
from .._text import check_text, entry_line, parse_triplets, read_text
from .abaqus_inp import AbaqusDeck, read_deck

__all__ = ["read_abaqus", "read_deck", "AbaqusDeck", "MATRIX_FILE"]

log = logging.getLogger(__name__)

#: ``<job>_<KIND><step>.mtx`` as written by ``*MATRIX OUTPUT``.
MATRIX_FILE = re.compile(r"^(?P<job>.+)_(?P<kind>STIF|MASS|DMPV|DMPS|LOAD)(?P<step>\d+)$", re.I)
_ROLE = {"STIF": "K", "MASS": "M", "DMPV": "D"}


def _is_matrix_file(path) -> bool:
    return suffix(path) == ".mtx" and MATRIX_FILE.match(stem(path)) is not None


def _files(path: Path) -> tuple[Path, dict]:
    """The deck and the matrix files ``{'K': .., 'M': .., 'D': ..}`` of the job of ``path``; each
    plain or ``.gz`` (the compression of ``path`` preferred when both lie there)."""
    m = MATRIX_FILE.match(stem(path)) if suffix(path) == ".mtx" else None
    job = m.group("job") if m else stem(path)
    step = m.group("step") if m else None
    files = sorted((p for p in path.parent.iterdir() if p.is_file()), key=lambda p: is_gzip(p) != is_gzip(path))
    listing = {}
    for p in files:
        listing.setdefault(plain_name(p).lower(), p)
    deck = listing.get(f"{job}.inp".lower())
    if deck is None:
        raise ReadError(path.parent / f"{job}.inp", "not found; the input deck with the nodes must lie beside "
                                                    "the .mtx files")
    if step is None:
        steps = sorted({int(MATRIX_FILE.match(Path(n).stem).group("step")) for n in listing
                        if n.endswith(".mtx") and n.startswith(job.lower() + "_stif")
                        and MATRIX_FILE.match(Path(n).stem)})
        if not steps:
            return deck, {}
        if len(steps) > 1:
            log.info("%s: matrices of steps %s; reading step %d", deck, steps, steps[0])
        step = str(steps[0])
    files = {}
    for kind, role in _ROLE.items():
        p = listing.get(f"{job}_{kind}{step}.mtx".lower())
        if p is not None:
            files[role] = p
    for role, kind in (("K", "STIF"), ("M", "MASS")):
        if role not in files:
            raise ReadError(path.parent / f"{job}_{kind}{step}.mtx",
                            f"not found; request it with *MATRIX GENERATE, STIFFNESS, MASS in {job}.inp")
    return deck, files


def _first_data_columns(path: Path) -> int:
    check_text(path)
    with open_binary(path) as f:
        for line in f:
            s = line.decode("latin-1").strip()
            if s and not s.startswith("*"):
                return len(s.replace(",", " ").split())
    raise ReadError(path, "no matrix entries found")


def _parse_labels(path: Path, text: str):
    """``(row node tokens, row dofs, col node tokens, col dofs, values)`` of a LABELS file."""
    if "*" not in text:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                a = np.loadtxt(io.StringIO(text.replace("D", "E").replace("d", "e")), delimiter=",",
                               dtype=np.float64, ndmin=2)
            ok = a.shape[1] == 5 and np.all(a[:, :4] == np.floor(a[:, :4])) and np.all(np.isfinite(a[:, 4]))
        except ValueError:
            ok = False
        if ok:
            ints = a[:, :4].astype(np.int64)
            if ints[:, [1, 3]].min() >= 1 and ints[:, [1, 3]].max() <= 6 and ints[:, [0, 2]].min() >= 1:
                return ints[:, 0].astype(str), ints[:, 1], ints[:, 2].astype(str), ints[:, 3], a[:, 4]
    rows = []
    for lineno, line in enumerate(text.splitlines(), 1):
        s = line.strip()
        if not s or s.startswith("*"):
            continue
        t = [x.strip() for x in s.split(",")]
        if t and t[-1] == "":
            t.pop()
        if len(t) != 5:
            raise ReadError(path, f"expected 5 columns 'node, dof, node, dof, value' (LABELS form), found {len(t)} "
                                  f"in {s[:60]!r}; is the file truncated or damaged?", lineno)
        try:
            d1, d2 = int(t[1]), int(t[3])
            v = float(t[4].replace("D", "E").replace("d", "e"))
        except ValueError:
            raise ReadError(path, f"non-numeric direction or value in {s[:60]!r}", lineno) from None
        for node, d in ((t[0], d1), (t[2], d2)):
            lab = node.rsplit(".", 1)[-1]
            if not (lab.isascii() and lab.lstrip("-").isdigit()):
                raise ReadError(path, f"node label {node!r} is not a number (or instance.number)", lineno)
            if int(lab) <= 0:
                raise ReadError(path, f"node label {node} <= 0 is an internal DOF (Lagrange multiplier or hybrid "
                                      "element); flexmor needs matrices on nodes only", lineno)
            if not 1 <= d <= 6:
                raise ReadError(path, f"direction {d} is not one of 1..6 (displacements and rotations); "
                                      "flexmor needs a purely mechanical model", lineno)
        if not np.isfinite(v):
            raise ReadError(path, f"non-finite value {t[4]}", lineno)
        rows.append((t[0], d1, t[2], d2, v))
    if not rows:
        raise ReadError(path, "no matrix entries found")
    r1, d1, r2, d2, v = zip(*rows)
    return np.array(r1), np.array(d1), np.array(r2), np.array(d2), np.array(v, dtype=np.float64)


def _labels_to_equations(path, text, deck: AbaqusDeck):
    """Node tokens of a LABELS file → equation indices and the equation map."""
    n1, d1, n2, d2, v = _parse_labels(path, text)
    lut = deck.lookup()
    tokens, inv = np.unique(np.concatenate([n1, n2]), return_inverse=True)
    ids = np.empty(tokens.size, dtype=np.int64)
    for k, tok in enumerate(tokens):
        inst, _, lab = tok.rpartition(".")
        key = (inst.upper(), int(lab))
        if key not in lut:
            rows = np.flatnonzero((inv[: n1.size] == k) | (inv[n1.size:] == k))
            raise ReadError(path, f"node {tok} is not defined in the input deck", entry_line(path, int(rows[0])))
        ids[k] = lut[key]
    return ids[inv[: n1.size]], d1, ids[inv[n1.size:]], d2, v


def _element_dofs(deck: AbaqusDeck, path: Path) -> int | None:
    """DOFs per node told by the element types of the deck; None when no element tells it."""
    kinds = set()
    for etype, _ in deck.elements:
        if etype.startswith(("C3D", "SC8", "SC6")):
            kinds.add(3)
        elif etype.startswith(("CPS", "CPE", "CAX")):
            kinds.add(2)
        elif etype.startswith(("S", "B3", "B2", "PIPE")):
            kinds.add(6)
    if len(kinds) > 1:
        raise ReadError(path, f"elements with {sorted(kinds)} DOFs per node: the COORDINATE form is ambiguous; "
                              "write the matrices with *MATRIX OUTPUT, FORMAT=LABELS, which names the node and "
                              "direction of every entry")
    return kinds.pop() if kinds else None


def _deck_too_short(path: Path, deck: AbaqusDeck, r, c, d: int | None) -> ReadError | None:
    """The error naming the deck when the matrix of ``path`` has more equations than the deck's nodes carry
    (``d`` DOFs each; none of 2, 3 or 6 fits when None) yet is whole: every equation up to the largest has its
    diagonal entry, as Abaqus writes them. Then the deck seems cut off in its node block; None when the
    matrix itself looks damaged (an index changed), which its own line names."""
    n_max = int(max(r.max(), c.max())) + 1
    if np.unique(r[r == c]).size != n_max:  # (no array of n_max: a damaged index may be huge)
        return None
    n_nodes, where = deck.node_ids.size, deck.path or path
    if d is not None:
        return ReadError(where, f"its {n_nodes} nodes carry {n_nodes * d} equations ({d} DOFs per node), but "
                                f"{path.name} has {n_max}, each with its diagonal entry: the deck seems cut off in "
                                "its node block, or the files are from different jobs")
    return ReadError(where, f"{path.name} has {n_max} equations, each with its diagonal entry, which fit no count "
                            f"of 2, 3 or 6 DOFs per node of the {n_nodes} nodes of the deck (no element type tells "
                            "the count): the deck seems cut off in its node block, or the files are from different "
                            "jobs")


def _dof_per_node(deck: AbaqusDeck, r, c, path: Path) -> int:
    d = _element_dofs(deck, path)
    if d is not None:
        return d
    n_max = int(max(r.max(), c.max())) + 1
    n_nodes = deck.node_ids.size
    for d in (3, 6, 2):
        if n_max <= d * n_nodes and n_max > d * (n_nodes - 1):
            # no element says it: a deck cut inside its node block can fit another count (88 nodes x 6 = 176 x 3)
            warnings.warn(FlexmorWarning(
                f"{path.name}: {deck.path.name if deck.path else 'the input deck'} has no elements, so the "
                f"COORDINATE form's equations were taken as {d} DOFs per node of its {n_nodes} nodes (the count "
                f"that fits {n_max} equations); a deck cut off in its node block fits another count: check that "
                "the deck is complete, or write the matrices with *MATRIX OUTPUT, FORMAT=LABELS"), stacklevel=2)
            return d
    exc = _deck_too_short(path, deck, r, c, None)
    if exc is not None:
        raise exc
    k = int(np.argmax(np.maximum(r, c)))
    raise ReadError(path, f"equation {n_max} fits no count of 2, 3 or 6 DOFs per node of the {n_nodes} nodes of "
                          "the input deck, and not every equation up to it has its diagonal entry: is an index "
                          "damaged, or are the .mtx and .inp from different jobs?", entry_line(path, k))


def _read_matrix(path: Path, deck: AbaqusDeck, dpn):
    """One matrix as ``(node, dof, node, dof, value, "labels")`` arrays in model node ids (LABELS form)
    or ``(row, col, value, dofs per node)`` with 0-based equations (COORDINATE form)."""
    ncol = _first_data_columns(path)
    if ncol == 5:
        return _labels_to_equations(path, read_text(path), deck) + ("labels",)
    if ncol != 3:
        raise ReadError(path, f"first entry has {ncol} columns; expected 3 (COORDINATE: row, col, value) or "
                              "5 (LABELS: node, dof, node, dof, value)")
    n_cap = deck.node_ids.size * (dpn or 6)
    try:
        r, c, v = parse_triplets(path, one_based=True, n=n_cap,
                                 index_dtype=np.int32 if 8 * n_cap < 2**31 else np.int64)
    except ReadError as exc:  # an index beyond the nodes: a damaged line, or a deck cut off in its node block
        try:
            r, c, _ = parse_triplets(path, one_based=True)
        except ReadError:
            raise exc from None
        raise (_deck_too_short(path, deck, r, c, dpn or _element_dofs(deck, path)) or exc) from None
    d = dpn or _dof_per_node(deck, r, c, path)
    big = np.flatnonzero(np.maximum(r, c) >= d * deck.node_ids.size)
    if big.size:
        exc = _deck_too_short(path, deck, r, c, d)
        if exc is not None:
            raise exc
        k = int(big[0])
        raise ReadError(path, f"equation {max(r[k], c[k]) + 1} is beyond {deck.node_ids.size} nodes x {d} DOFs of "
                              "the input deck; are the .mtx and .inp from the same job?", entry_line(path, k))
    return r, c, v, d


def _assemble(path, parts, size, again):
    """The matrix of ``parts = [row codes, col codes, values]`` over all codes (node position * 8 + direction).

    ``parts`` is emptied so that the parsed arrays are freed as soon as they are used;
    ``again()`` parses the file anew to name a duplicate entry.
    """
    r, c, _ = parts
    n_lower, n_upper = int(np.count_nonzero(r > c)), int(np.count_nonzero(r < c))
    lower, upper = n_lower > 0, n_upper > 0
    del r, c
    A = assemble(parts, (size, size), mirror=lower != upper)  # one triangle: mirror it
    if A is None:
        cr, cc, _ = again()
        key = cr.astype(np.int64) * size + cc
        order = np.argsort(key, kind="stable")
        dup = np.flatnonzero(key[order][1:] == key[order][:-1])
        k, first = int(order[dup[0] + 1]), int(order[dup[0]])
        raise ReadError(path, f"entry ({again.node(cr[k])}, {again.node(cc[k])}) appears twice (also on line "
                              f"{entry_line(path, first)}); duplicates are refused, not summed",
                        entry_line(path, k))
    if lower and upper and n_lower != n_upper:
        raise ReadError(path, f"{n_upper} entries above the diagonal but {n_lower} below: Abaqus writes both "
                              "triangles of the symmetric matrix, so the file is cut off or lines are missing")
    return A


def _check_complete(files: dict, mats: dict, deck: AbaqusDeck) -> None:
    """Refuse equations with mass but no stiffness entry; warn when the last equations have no mass.

    Every equation with mass belongs to an element, which gives it stiffness: one without an
    entry in the stiffness file means that file lost lines. A mass matrix may leave equations
    out (massless directions), but when exactly the last ones of the stiffness (in the order
    Abaqus writes them) have none, the mass file may have been cut off at a line end.
    """
    def label(k):
        return f"node {deck.node_ids[k // 8]} direction {k % 8}"

    in_k = np.diff(mats["K"].indptr) > 0
    in_m = np.diff(mats["M"].indptr) > 0
    bad = np.flatnonzero(in_m & ~in_k)
    if bad.size:
        raise ReadError(files["K"], f"no entry for {label(int(bad[0]))}"
                                    f"{f' and {bad.size - 1} more equations' if bad.size > 1 else ''}, which "
                                    f"have mass in {files['M'].name}: the file is cut off or lines are missing")
    k_rows = np.flatnonzero(in_k)
    no_mass = ~in_m[k_rows]
    if in_m.any() and no_mass[-1]:
        first = int(np.flatnonzero(~no_mass)[-1]) + 1  # the tail of equations without mass starts here
        if np.count_nonzero(no_mass) == k_rows.size - first:
            warnings.warn(f"{files['M']}: the last {k_rows.size - first} equations (from {label(int(k_rows[first]))}) "
                          "have no mass entry: the file may be cut off at a line end, which its format cannot "
                          "tell from massless directions", FlexmorWarning, stacklevel=3)


def _check_step(deck: AbaqusDeck, deck_path: Path) -> None:
    """Warn when a deck with elements lacks the ``*STEP`` of the job that wrote the matrices.

    Abaqus writes matrices only in a step (``*MATRIX GENERATE``): a deck with ``*ELEMENT`` but
    without ``*STEP`` was cut off after a block (a cut inside one is refused by
    :func:`~flexmor.io.abaqus.abaqus_inp.read_deck`) and lost what followed (sets, sections,
    materials), or it is a mesh written for the matrices. The matrices and the nodes read are
    complete, so the model is read, as by the CalculiX reader. (A deck of nodes only is taken for
    a geometry deck.)
    """
    if "STEP" in deck.keywords or "ELEMENT" not in deck.keywords:
        return
    where, line = deck.end if deck.end is not None else (deck_path, None)
    warnings.warn(f"{where}{f':{line}' if line else ''}: the deck ends without *STEP, which the job that wrote the "
                  "matrices had (*MATRIX GENERATE): it seems cut off after its element blocks; elements, node sets "
                  "and materials after the cut are missing from the model", FlexmorWarning, stacklevel=3)


def _compress(A: sp.csr_matrix, code: np.ndarray, number: np.ndarray) -> sp.csr_matrix:
    """``A[code][:, code]`` in place for a matrix whose rows and columns outside ``code`` are empty
    (``number`` maps a code to its position in ``code``)."""
    np.take(number.astype(A.indices.dtype, copy=False), A.indices, out=A.indices)
    indptr = np.append(A.indptr[code], A.indptr[-1]).astype(A.indptr.dtype)
    return sp.csr_matrix((A.data, A.indices, indptr), shape=(code.size, code.size))


def deck_elements(deck: AbaqusDeck, path) -> Elements | None:
    """The :class:`~flexmor.elements.Elements` of an Abaqus deck: elements of a type, numbered by their labels
    (which may repeat across instances), and the isotropic materials of their sections."""
    if not deck.elements:
        return None
    names = sorted({m for m in deck.element_materials if m is not None})
    materials = []
    for name in names:
        data = deck.materials.get(name)
        rho = (data or {}).get("DENSITY") or None
        if data is None or "E" not in data:
            materials.append(Material(name, rho=rho, unsupported=f"*MATERIAL {name} has no *ELASTIC in {path.name}"
                                      if data is not None else f"{name} is not defined by a *MATERIAL in {path.name}"))
        elif data.get("UNSUPPORTED"):
            materials.append(Material(name, rho=rho, unsupported=data["UNSUPPORTED"]))
        else:
            try:
                materials.append(Material.isotropic(data["E"], data["NU"], rho, name))
            except ModelError as exc:
                materials.append(Material(name, rho=rho, unsupported=str(exc)))
    groups: dict = {}
    for (etype, nodes), label, mat in zip(deck.elements, deck.element_labels, deck.element_materials):
        groups.setdefault((etype.upper(), nodes.size), []).append((label, nodes, names.index(mat) if mat else -1))
    blocks = [ElementBlock(etype, [r[0] for r in rows], np.array([r[1] for r in rows]), [r[2] for r in rows])
              for (etype, _), rows in groups.items()]
    return Elements(tuple(blocks), tuple(materials), str(path))


def read_abaqus(path, *, dof_per_node: int | None = None) -> FEModel:
    """Read an Abaqus ``*MATRIX GENERATE`` export with its input deck.

    Parameters
    ----------
    path : str or path-like
        The deck ``<job>.inp`` or one of ``<job>_STIF1.mtx``, ``<job>_MASS1.mtx``.
    dof_per_node : int, optional
        DOFs per node of the COORDINATE form; by default told by the element types.

    Returns
    -------
    FEModel
        ``K``, ``M`` (and ``D`` from ``_DMPV``), node table and sets from the deck, the
        equation map, the elements with their materials (``*MATERIAL``, ``*ELASTIC``,
        ``*DENSITY``, ``*SOLID SECTION``, ``*SHELL SECTION``, isotropic elasticity); ``name``
        is the job name.

    Raises
    ------
    ReadError
        Missing files, malformed lines (with line number), entries given twice, equations
        beyond the deck's nodes, nodes the deck does not define.
    """
    path = Path(path)
    deck_path, files = _files(path)
    if not files:
        sti = beside(deck_path, ".sti")
        if sti is not None:
            log.info("%s: no Abaqus _STIF .mtx but %s beside it; reading as CalculiX", deck_path, sti.name)
            return MODEL_FORMATS.by_name("calculix").function(sti)
        raise ReadError(deck_path.parent / f"{stem(deck_path)}_STIF1.mtx",
                        f"not found; Abaqus writes it for *MATRIX GENERATE, STIFFNESS, MASS in {deck_path.name} "
                        f"(a CalculiX job would have {stem(deck_path)}.sti)")
    deck = read_deck(deck_path)
    _check_step(deck, deck_path)
    sorter = np.argsort(deck.node_ids)
    ids_sorted = deck.node_ids[sorter]

    def codes(nodes, dirs):  # (position in the deck's node order) * 8 + direction
        return sorter[np.searchsorted(ids_sorted, nodes)].astype(np.int64) * 8 + np.asarray(dirs, dtype=np.int64)

    def parse(path):
        """``[row codes, col codes, values]`` of one matrix file and its form."""
        got = _read_matrix(path, deck, dof_per_node)
        if got[-1] == "labels":
            n1, d1, n2, d2, v, form = got
            return [codes(n1, d1), codes(n2, d2), v], form
        r, c, v, d = got
        for x in (r, c):  # in place: equation -> node position * 8 + direction
            dof = x % d
            x //= d
            x *= 8
            x += dof + 1
        return [r, c, v], "coordinate"

    size = deck.node_ids.size * 8
    used = np.zeros(size, dtype=bool)  # every (node, dof) that occurs
    mats, forms = {}, set()
    for role, p in files.items():  # one file at a time: only one parsed file in memory
        parts, form = parse(p)
        forms.add(form)
        used[parts[0]] = True
        used[parts[1]] = True

        def again(p=p):
            return parse(p)[0]
        again.node = lambda k: f"{deck.node_ids[k // 8]}.{k % 8}"
        mats[role] = _assemble(p, parts, size, again)
    _check_complete(files, mats, deck)
    # equation map: in internal node order, then direction
    code = np.flatnonzero(used)
    number = (np.cumsum(used) - 1).astype(np.int32 if size < 2**31 else np.int64)
    del used
    mats = {role: _compress(A, code, number) for role, A in mats.items()}
    n = code.size
    dofs = np.stack([deck.node_ids[code // 8], code % 8], axis=1)
    used = rows_in_use(mats["K"]) | rows_in_use(mats["M"])
    if not np.all(used):
        keep = np.flatnonzero(used)
        log.info("%s: removed %d equations without stiffness and mass", deck_path, n - keep.size)
        mats = {k: A[keep][:, keep] for k, A in mats.items()}
        dofs = dofs[keep]
    log.info("%s: %d equations, %d nodes, %s form", deck_path, dofs.shape[0], deck.node_ids.size, "/".join(forms))
    quadratic = sorted({etype for etype, _ in deck.elements if etype.startswith(QUADRATIC_TYPES)})
    model = build_model(
        deck_path,
        roles=files,
        M=mats["M"], K=mats["K"], D=mats.get("D"),
        damping={"type": "given"} if "D" in mats else {"type": "none"},
        node_ids=deck.node_ids, xyz=deck.xyz, dofs=dofs, node_sets=deck.node_sets,
        mesh=mesh_of_elements(deck.elements, lambda etype, _: abaqus_cell(etype), "abaqus"),
        elements=deck_elements(deck, deck_path), name=stem(deck_path), source=str(deck_path),
        singular_mass_ok=bool(quadratic),
    )
    if quadratic and np.all(model.M.diagonal() > 0):
        check_mass(model, f"{files['M']} ({', '.join(quadratic)} elements)")
    return model


MODEL_FORMATS.register("abaqus", [".inp"], read_abaqus, claims=_is_matrix_file, gzip=True,
                       claims_doc="<job>_{STIF,MASS,DMPV}<n>.mtx",
                       description="Abaqus *MATRIX GENERATE export (.inp + <job>_STIF1.mtx + <job>_MASS1.mtx)")
